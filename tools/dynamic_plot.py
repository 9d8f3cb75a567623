"""Pictures of docs/dynamic.md: split points coloured by time, and the crack front's distance
from the notch tip and its speed against time (needs matplotlib).
python3 tools/dynamic_plot.py RUN_DIR OUT.png [aspect]"""
import csv, math, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt

d, out = sys.argv[1], sys.argv[2]
aspect = float(sys.argv[3]) if len(sys.argv) > 3 else 1.0
rows = list(csv.DictReader(open(d + "/splits.csv")))
tips = list(csv.DictReader(open(d + "/crack_tips.csv")))
tip0 = (0.05, 0.025) if aspect == 1.0 else (0.05, 0.02)
fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.6))
sc = a.scatter([float(r["x"]) * 1e3 for r in rows], [float(r["y"]) * 1e3 for r in rows], c=[float(r["time"]) * 1e6 for r in rows], s=4, cmap="viridis")
fig.colorbar(sc, ax=a, label="split time (us)")
a.set_aspect("equal"); a.set_xlabel("x (mm)"); a.set_ylabel("y (mm)"); a.set_title("split points")
by = {}
for r in tips:
    if r["branch"] == "":
        continue
    t = float(r["time"]); dd = math.hypot(float(r["x"]) - tip0[0], float(r["y"]) - tip0[1])
    by[t] = max(by.get(t, 0.0), dd)
ts = sorted(by)
b.plot([t * 1e6 for t in ts], [by[t] * 1e3 for t in ts], "k-", label="front distance from notch tip (mm)")
W, sp = 2e-6, []
for k, t in enumerate(ts):
    js = [j for j in range(k) if ts[j] <= t - W]
    if js:
        sp.append((t, (by[t] - by[ts[js[-1]]]) / (t - ts[js[-1]])))
b2 = b.twinx()
b2.plot([t * 1e6 for t, _ in sp], [v for _, v in sp], "C1-", label="front speed, 2 us window (m/s)")
cr = 2803.0 if aspect == 1.0 else 2125.0
b2.axhline(cr, color="C3", ls="--", label="Rayleigh speed")
b.set_xlabel("t (us)"); b.set_ylabel("distance (mm)"); b2.set_ylabel("speed (m/s)")
b.legend(loc="upper left", fontsize=8); b2.legend(loc="lower right", fontsize=8)
fig.tight_layout(); fig.savefig(out, dpi=80)
