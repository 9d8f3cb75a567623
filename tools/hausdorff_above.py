#!/usr/bin/env python3
"""The largest Hausdorff distance between the crack paths of `flem paths --out` files, over the
whole path and over its part above a height (issue 34; docs/paths.md "Session 35"). Ours: a
check of where two paths differ (in the body, or where they meet an edge), not `flem paths`'
own measure. Each path (`kink.path`, up to where it first reaches the outer boundary as
`flem paths` writes it) is resampled at 50 points per segment; the part above is the set of
those points with y >= Y; the distance is the point-set Hausdorff distance between two such
sets. With Y at the path's lowest point it agrees with `flem paths`' figure to about 1e-3 of
a percent on the shear series.

    python3 tools/hausdorff_above.py Y ROWS.json [ROWS.json ...] [--only TEXT]

prints, per file, the largest distance in % of the size (`size` of the rows) over the whole
paths and over their parts above Y, with the pair. `--only TEXT` keeps the rows whose scene
contains TEXT. Needs numpy."""
import itertools
import json
import sys

import numpy as np


def dense(path, ymin):
    p = np.array(path, dtype=float)
    t = np.linspace(0.0, 1.0, 50)
    q = np.concatenate([a + (b - a) * t[:, None] for a, b in zip(p[:-1], p[1:])])
    return q[q[:, 1] >= ymin]


def hausdorff(a, b):
    d = np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(-1))
    return max(d.min(1).max(), d.min(0).max())


def main(argv):
    only = None
    if "--only" in argv:
        i = argv.index("--only")
        only = argv[i + 1]
        argv = argv[:i] + argv[i + 2:]
    if len(argv) < 3:
        sys.exit(__doc__)
    y = float(argv[1])
    for f in argv[2:]:
        rows = [r for r in json.load(open(f)) if only is None or only in r["scene"]]
        size = rows[0]["size"]
        out = []
        for ymin in (-np.inf, y):
            sets = [(r["scene"].split("/")[-1].removesuffix(".toml"), dense(r["kink"]["path"], ymin)) for r in rows]
            d, a, b = max((hausdorff(pa, pb), a, b) for (a, pa), (b, pb) in itertools.combinations(sets, 2))
            out.append("%.2f %% (%s / %s)" % (100.0 * d / size, a, b))
        print("%s: whole %s; above y = %g: %s" % (f, out[0], y, out[1]))


if __name__ == "__main__":
    main(sys.argv)
