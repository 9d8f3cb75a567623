#!/usr/bin/env python3
"""Overlays the crack paths of Bittencourt's beam with holes (issue 34 must-show 3 and 6;
docs/paths.md, "Bittencourt's beam with holes") from `flem paths --out` files: one panel per
file (e.g. tip_mts beside the edge rule), the beam, its three holes, the notch, supports and
load patch drawn, every run's path coloured by mesh kind, line style by refinement, each up to
where it first meets a boundary (`kink.boundary_at`: what `flem paths` compares).

    python3 tools/plot_beam.py OUT.png ROWS.json[:TITLE] [ROWS.json[:TITLE] ...] [--full]

`--full` draws the whole beam (default: 2.5 <= x <= 10.5). Needs matplotlib (the repo's .venv).
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Circle, Polygon, Rectangle  # noqa: E402

HOLES = [(6.0, 2.75), (6.0, 4.75), (6.0, 6.75)]


def specimen(ax):
    ax.add_patch(Rectangle((0, 0), 20, 8, fill=False, lw=1.0, color="k"))
    for c in HOLES:
        ax.add_patch(Circle(c, 0.25, fill=True, facecolor="0.85", edgecolor="k", lw=0.8))
    ax.plot([4, 4], [0, 1], color="k", lw=2.0)
    for x in (1, 19):
        ax.add_patch(Polygon([[x, 0], [x - 0.25, -0.4], [x + 0.25, -0.4]], closed=True, color="0.4"))
    ax.add_patch(Rectangle((9.9, 8.0), 0.2, 0.12, color="tab:red"))
    ax.annotate("", xy=(10, 8.1), xytext=(10, 8.9), arrowprops=dict(arrowstyle="->", color="tab:red"))


def main(argv):
    full = "--full" in argv
    argv = [a for a in argv if a != "--full"]
    out, files = argv[0], argv[1:]
    colours = {"t3": "tab:blue", "quad": "tab:orange", "q4": "tab:green"}
    styles = {"1": ":", "2": "--", "3": "-"}
    fig, axs = plt.subplots(1, len(files), figsize=(5.2 * len(files) * (2.3 if full else 1.0), 5.6), squeeze=False)
    for ax, spec in zip(axs[0], files):
        f, _, title = spec.partition(":")
        specimen(ax)
        seen = set()
        for r in json.load(open(f)):
            name = r["scene"].rsplit("/", 1)[-1].replace(".toml", "")
            kind, ref = name.split("_")[-2:]
            k = r["kink"]
            b = k.get("boundary_at")
            path = k["path"][: b + 1] if b is not None else k["path"]
            label = "%s %s" % (kind, ref) if (kind, ref) not in seen else None
            seen.add((kind, ref))
            ax.plot([p[0] for p in path], [p[1] for p in path], styles.get(ref, "-"), color=colours.get(kind, "k"), lw=1.3, label=label)
        ax.set_xlim((-0.5, 20.5) if full else (2.5, 10.5))
        ax.set_ylim(-0.6, 9.0)
        ax.set_aspect("equal")
        ax.legend(fontsize=7, title="mesh kind, refinement", title_fontsize=7, loc="upper right")
        ax.set_title(title or f, fontsize=9)
        ax.set_xlabel("x (in)")
        ax.set_ylabel("y (in)")
    fig.savefig(out, dpi=120, bbox_inches="tight")


if __name__ == "__main__":
    main(sys.argv[1:])
