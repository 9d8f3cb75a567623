#!/usr/bin/env python3
"""Overlays the crack paths of `flem paths --out` files on one figure per benchmark (issue 34,
must-show 6; docs/paths.md). Each file holds the rows of one or more runs; every tip's path
(`kink.path`) is drawn, coloured by mesh kind, with line style by refinement; the MTS line from
the initial tip is dashed black.

    python3 tools/plot_paths.py OUT.png ROWS.json [ROWS.json ...] [--zoom R] [--title TEXT]

A path is drawn up to where it first reaches the outer boundary (`kink.boundary_at`, what
`flem paths` compares by the Hausdorff distance), all of it when it does not.

Needs matplotlib (e.g. the repo's .venv)."""
import json
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main(argv):
    zoom = None
    if "--zoom" in argv:
        i = argv.index("--zoom")
        zoom = float(argv[i + 1])
        argv = argv[:i] + argv[i + 2:]
    title = "crack paths (tip_mts); dashed: MTS line from the initial tip"
    if "--title" in argv:
        i = argv.index("--title")
        title = argv[i + 1]
        argv = argv[:i] + argv[i + 2:]
    out, files = argv[0], argv[1:]
    colours = {"t3": "tab:blue", "quad": "tab:orange", "q4": "tab:green", "uquad": "tab:red"}
    styles = {"1": ":", "2": "--", "3": "-"}
    fig, ax = plt.subplots(figsize=(6, 6))
    seen = set()
    tips = []
    for f in files:
        for r in json.load(open(f)):
            name = r["scene"].rsplit("/", 1)[-1].replace(".toml", "")
            parts = name.split("_")
            kind, ref = parts[-2], parts[-1]
            k = r["kink"]
            b = k.get("boundary_at")
            path = k["path"][: b + 1] if b is not None else k["path"]
            xs = [p[0] for p in path]
            ys = [p[1] for p in path]
            label = "%s %s" % (kind, ref) if (kind, ref) not in seen else None
            seen.add((kind, ref))
            ax.plot(xs, ys, styles.get(ref, "-"), color=colours.get(kind, "k"), lw=1.2, label=label)
            if r["mts_deg"] is not None:
                tips.append((k["tip"], math.radians(k["crack_deg"] + r["mts_deg"])))
    for (x, y), a in tips[:4]:
        L = zoom or 0.5
        ax.plot([x, x + L * math.cos(a)], [y, y + L * math.sin(a)], "k--", lw=0.8)
    if zoom and tips:
        (x, y), _ = tips[0]
        ax.set_xlim(x - zoom, x + zoom)
        ax.set_ylim(y - zoom, y + zoom)
    ax.set_aspect("equal")
    ax.legend(fontsize=8, title="mesh kind, refinement")
    ax.set_title(title, fontsize=10)
    fig.savefig(out, dpi=120, bbox_inches="tight")


if __name__ == "__main__":
    main(sys.argv[1:])
