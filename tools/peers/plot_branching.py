#!/usr/bin/env python3
"""FLEM's split points beside Akantu's inserted facets on the branching plate (issue 36,
docs/dynamic.md "Akantu side by side"), coloured by time:
    python tools/peers/plot_branching.py out/branching_h0.5 out/ak/akantu_b05.json docs/dynamic/branching_flem_akantu.png
Needs matplotlib (the peers' venv has it)."""
import csv
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

run, ak, png = sys.argv[1:4]
fl = list(csv.DictReader(open(run + "/splits.csv")))
af = json.load(open(ak))["facets"]
fig, axs = plt.subplots(2, 1, figsize=(8, 7.2), sharex=True)
for ax, (name, xs, ys, ts) in zip(axs, [
        ("FLEM: split points", [float(r["x"]) for r in fl], [float(r["y"]) for r in fl], [float(r["time"]) for r in fl]),
        ("Akantu: inserted cohesive facets", [f["x"] for f in af], [f["y"] for f in af], [f["t"] for f in af])]):
    ax.plot([0, 0.1, 0.1, 0, 0], [0, 0, 0.04, 0.04, 0], "k-", lw=0.8)
    ax.plot([0, 0.05], [0.02, 0.02], "k-", lw=2)
    sc = ax.scatter(xs, ys, c=[1e6 * t for t in ts], s=2, cmap="viridis", vmin=0, vmax=80)
    ax.set_aspect("equal")
    ax.set_title(f"{name} ({len(xs)}), 80 us, h = 0.5 mm mesh")
    ax.set_ylabel("y (m)")
axs[1].set_xlabel("x (m)")
fig.colorbar(sc, ax=axs, label="time (us)", shrink=0.8)
fig.savefig(png, dpi=110)
print(png)
