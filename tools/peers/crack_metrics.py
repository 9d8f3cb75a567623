#!/usr/bin/env python3
"""One branch-point measure for FLEM and its peers (issue 36, must-show 4; docs/dynamic.md).

    python3 tools/peers/crack_metrics.py out/branching_h0.5      # FLEM run folder (splits.csv)

`branch_point(points)`: points are (x, y) of the crack (FLEM: split points of splits.csv;
Akantu: midpoints of inserted cohesive facets). The plate's crack runs along +x from the notch
tip (0.05, 0.02). In slices 1 mm wide from x = 50 mm on, the crack's width is the y-spread
(max - min) of its points in the slice; the branch point is the left edge of the first slice
whose width is at least `width` (4 mm: 8 coarse elements, about twice the straight crack's
zig-zag) together with the next two slices that hold points (ours: a crack that has split into
two or spread into a band). Returns metres, or None. Standard library only.
"""
import csv
import json
import sys


def branch_point(points, x0=0.05, x1=0.1, dx=1e-3, width=4e-3):
    n = int(round((x1 - x0) / dx))
    ys = [[] for _ in range(n)]
    for x, y in points:
        k = int((x - x0) // dx)
        if 0 <= k < n:
            ys[k].append(y)
    wide = [(max(s) - min(s) >= width) if s else None for s in ys]
    for k in range(n):
        if not wide[k]:
            continue
        nxt = [w for w in wide[k + 1:] if w is not None][:2]
        if len(nxt) == 2 and all(nxt):
            return x0 + k * dx
    return None


def flem_points(run):
    return [(float(r["x"]), float(r["y"])) for r in csv.DictReader(open(run + "/splits.csv"))]


if __name__ == "__main__":
    for run in sys.argv[1:]:
        pts = flem_points(run)
        print(json.dumps(dict(run=run, splits=len(pts), branch_point=branch_point(pts))))
