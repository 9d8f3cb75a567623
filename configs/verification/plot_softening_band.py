"""Picture of configs/verification/biaxial_softening.toml (docs/img/softening_biaxial.png):
plastic shear strain of the last snapshot on the deformed mesh, and the load-displacement
curve. Usage: python plot_softening_band.py RUN_DIR OUT.png (needs meshio, matplotlib)."""
import sys, glob, meshio, numpy as np, csv
import matplotlib; matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.collections import PolyCollection
d, out = sys.argv[1], sys.argv[2]
m = meshio.read(sorted(glob.glob(d + "/snapshot_*.vtu"))[-1])
u = m.point_data.get("displacement")
pts = m.points[:, :2] + 3 * u[:, :2]
cells = m.cells[0].data.astype(int)
g = m.cell_data["plastic_shear_strain"][0]
rows = list(csv.DictReader(open(d + "/history.csv")))
fig, (a, b) = plt.subplots(1, 2, figsize=(9, 5), gridspec_kw={"width_ratios": [1, 1.3]})
pc = PolyCollection(pts[cells], array=g, cmap="inferno_r", edgecolors="none")
a.add_collection(pc); a.autoscale(); a.set_aspect("equal"); a.set_title("plastic shear strain\n(displacements x3)")
fig.colorbar(pc, ax=a, shrink=0.8)
t = np.array([float(r["time"]) for r in rows]); q = np.array([abs(float(r["reaction_top_y"])) for r in rows])
b.plot(t * 0.002 / 2.0 * 100, q, "-o", ms=3)  # velocity 0.002, height 2
b.set_xlabel("axial strain of the specimen (%)"); b.set_ylabel("|reaction_top_y| / width"); b.set_title("load - displacement"); b.grid(alpha=0.3)
fig.tight_layout(); fig.savefig(out, dpi=110)
print("max g", g.max(), "median", np.median(g), "frac > half max", (g > 0.5 * g.max()).mean())
