"""Pictures of the strip-footing scenes (configs/verification/strip_footing*.toml, issue 21):
the plastic shear strain and the mechanism (the soil's speed over the footing's) of the last
snapshot of the first run, and the load-settlement curves of every run against the closed form.

Usage: python plot_footing.py OUT.png N_C RUN_DIR[=LABEL] [RUN_DIR[=LABEL] ...]
  N_C: the closed form of |reaction_footing_y| / (b c): 5.142 (Prandtl, phi = 0) or 30.14
  (Prandtl-Reissner, phi = 30 deg). Settlement = time x the footing's velocity, both read from
  the run (history.csv, scene.resolved.toml); the footing half-width b = 1, c = 1.
Needs meshio and matplotlib (the README's .venv has both)."""
import csv
import glob
import sys
import tomllib

import matplotlib
import meshio
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402


def footing_velocity(run):
    scene = tomllib.load(open(run + "/scene.resolved.toml", "rb"))
    for load in scene.get("load", []):
        if load.get("name") == "footing":
            return abs(float(load["y"]))
    sys.exit(f"{run}/scene.resolved.toml: no [[load]] named 'footing'")


def curve(run):
    rows = list(csv.DictReader(open(run + "/history.csv")))
    if not rows:
        sys.exit(f"{run}/history.csv: no rows")
    t = np.array([float(r["time"]) for r in rows])
    q = np.array([abs(float(r["reaction_footing_y"])) for r in rows])
    return t * footing_velocity(run), q


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    out, nc = sys.argv[1], float(sys.argv[2])
    runs = [a.split("=", 1) if "=" in a else (a, a) for a in sys.argv[3:]]
    fig, (a, w, b) = plt.subplots(1, 3, figsize=(16, 4.6), gridspec_kw={"width_ratios": [1.2, 1.2, 1]})
    snaps = sorted(glob.glob(runs[0][0] + "/snapshot_*.vtu"))
    if not snaps:
        sys.exit(f"{runs[0][0]}: no snapshot_*.vtu")
    m = meshio.read(snaps[-1])
    pts = m.points[:, :2]
    cells = m.cells[0].data.astype(int)
    g = m.cell_data["plastic_shear_strain"][0]
    top = pts[:, 1].max()
    # The strain is singular at the footing's edge: the colour scale stops at the 97th
    # percentile of the yielded cells so that the fan and the wedges show.
    vmax = float(np.percentile(g[g > 0], 97)) if (g > 0).any() else 1.0
    pc = PolyCollection(pts[cells], array=g, cmap="inferno_r", edgecolors="none", clim=(0.0, vmax))
    a.add_collection(pc)
    fig.colorbar(pc, ax=a, shrink=0.75, extend="max")
    a.set_title(f"plastic shear strain\n({runs[0][1]}, last snapshot)", fontsize=9)
    # The mechanism: the speed of the soil at the end of the push, over the footing's speed
    # (rigid wedge under the footing ~1, the fan, the passive wedge: more than 1 when the flow
    # dilates, exp(theta tan(phi)) along the fan of an associated law; the rest at rest).
    vel = np.linalg.norm(m.point_data["velocity"][:, :2], axis=1) / footing_velocity(runs[0][0])
    pv = PolyCollection(pts[cells], array=vel[cells].mean(axis=1), cmap="viridis", edgecolors="none", clim=(0.0, float(np.percentile(vel, 99))))
    w.add_collection(pv)
    fig.colorbar(pv, ax=w, shrink=0.75)
    w.set_title("mechanism: |velocity| / footing velocity\n(last snapshot)", fontsize=9)
    for ax in (a, w):
        ax.set_xlim(0, min(pts[:, 0].max(), 11.0))
        ax.set_ylim(max(top - 4.5, pts[:, 1].min()), top)
        ax.set_aspect("equal")
        ax.plot([0, 1], [top, top], "r-", lw=4, label="footing (b = 1)")
        ax.legend(loc="lower right", fontsize=8)
    for run, label in runs:
        s, q = curve(run)
        b.plot(s * 1000, q, "-", lw=1.5, label=f"{label}: peak {q.max():.2f} ({100 * (q.max() / nc - 1):+.1f} %)")
    b.axhline(nc, color="k", lw=1, label=f"closed form {nc}")
    b.axhspan(nc * 0.95, nc * 1.05, color="0.85", zorder=0, label="+/- 5 %")
    b.set_xlabel("settlement / b (x 1e-3)")
    b.set_ylabel("|reaction_footing_y| / (b c)")
    b.set_ylim(0, nc * 1.25)
    b.grid(alpha=0.3)
    b.legend(fontsize=7, loc="lower right")
    b.set_title("load - settlement", fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    for run, label in runs:
        s, q = curve(run)
        print(f"{label}: peak {q.max():.4f} ({100 * (q.max() / nc - 1):+.2f} %), last {q[-1]:.4f}, settlement {s[-1]:.5f}")


main()
