"""The open crack of a run (ours, session 36): the split points whose copies have moved apart
by at least `delta_f` at the last snapshot, i.e. the cohesive faces there are traction-free,
against the split points still bonded (split, opened less than `delta_f`). A phase-field
picture shows the first (damage near 1), not the band of bonded faces that a split front leaves.

python3 tools/open_crack.py OUT.png RUN_DIR [RUN_DIR ...] [--delta-f 2e-6] [--mirror 0.02] [--h 5e-4[,3.5e-4...]]
    [--from-x 0.0505]

Needs numpy, meshio and matplotlib (the repository's .venv). `--h`: the element size, one for
all runs or one per run (comma-separated). The measures below take the open points past
`--from-x` (default 0.0505 m: the branching plate's notch, whose pre-separated points are open
from the start and would mirror onto themselves). Per run it prints:
- the open points' count, their x range and y range;
- their distance to the open crack mirrored about y = MIRROR (median / 90th percentile / largest,
  mm; for each open point, the nearest open point to its mirror image), past x = 55 mm and all;
- the branch point: the first 1 mm column from which the next ten columns that hold open points
  (empty columns skipped) all hold points more than 4 h apart in y (two branches), and where the branches
  leave the plate (open points within 2 h of an edge), and each branch's nearest distance to the
  right, top and bottom edges.
The gap of a point is the largest distance between the displacements of its copies (points of
the VTU at the same reference position, to 1 nm). Reference: none; this is a measure.
"""
import sys
from collections import defaultdict

import numpy as np


def gaps(d):
    import meshio

    import glob

    snaps = sorted(glob.glob(d + "/snapshot_*.vtu"))
    if not snaps:
        raise SystemExit(f"{d}: no snapshot_*.vtu")
    m = meshio.read(snaps[-1])  # the last snapshot (names sort by number)
    X = m.points[:, :2]
    U = m.point_data["displacement"][:, :2]
    at = defaultdict(list)
    for i, x in enumerate(np.round(X / 1e-9).astype(np.int64)):
        at[(x[0], x[1])].append(i)
    P, G = [], []
    for ids in at.values():
        if len(ids) < 2:
            continue
        G.append(max(np.linalg.norm(U[a] - U[b]) for a in ids for b in ids if a < b))
        P.append(X[ids[0]])
    return np.array(P).reshape(-1, 2), np.array(G), X[:, 0].max(), X[:, 1].max()


def mirror_distance(free, ym):
    if len(free) == 0:
        return np.array([])
    mir = free.copy()
    mir[:, 1] = 2 * ym - mir[:, 1]
    return np.array([np.min(np.linalg.norm(free - q, axis=1)) for q in mir])


def branch_point(free, h):
    """The first 1 mm column from which the next 10 columns that hold open points (empty columns
    skipped) all split in two (a gap in y larger than 4 h): where the open crack branches."""
    cols = {}
    for x, y in free:
        cols.setdefault(int(x / 1e-3), []).append(y)
    two = {c: bool(np.diff(np.sort(ys)).max(initial=0.0) > 4 * h) for c, ys in cols.items()}
    keys = sorted(two)
    for i, c in enumerate(keys):
        nxt = keys[i : i + 10]
        if len(nxt) == 10 and all(two[k] for k in nxt):
            return c * 1e-3
    return None


def main():
    args = sys.argv[1:]
    opt = {"--delta-f": "2e-6", "--mirror": "0.02", "--h": "5e-4", "--from-x": "0.0505"}
    for k in list(opt):
        if k in args:
            i = args.index(k)
            opt[k] = args[i + 1]
            del args[i : i + 2]
    out, runs = args[0], args[1:]
    hs = [float(v) for v in opt["--h"].split(",")]
    if len(hs) == 1:
        hs = hs * len(runs)
    if len(hs) != len(runs):
        raise SystemExit(f"--h: {len(hs)} sizes for {len(runs)} runs")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    df, ym, x_from = float(opt["--delta-f"]), float(opt["--mirror"]), float(opt["--from-x"])
    fig, axs = plt.subplots(len(runs), 1, figsize=(8, 3.4 * len(runs)), squeeze=False)
    for ax, d, h in zip(axs[:, 0], runs, hs):
        P, G, xmax, ymax = gaps(d)
        for lo, hi, c, s, lab in [(0, 0.1 * df, "0.8", 1, "bonded, gap < 0.1 delta_f"), (0.1 * df, df, "orange", 2, "softening-size gap"), (df, np.inf, "k", 3, "open, gap >= delta_f")]:
            k = (G >= lo) & (G < hi)
            ax.scatter(P[k, 0] * 1e3, P[k, 1] * 1e3, s=s, c=c, label=f"{lab}: {k.sum()}")
        free = P[(G >= df) & (P[:, 0] > x_from)]
        ax.set_aspect("equal")
        ax.set_xlim(0, xmax * 1e3)
        ax.set_ylim(0, ymax * 1e3)
        ax.legend(fontsize=6, loc="lower left")
        ax.set_title(d, fontsize=8)
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        if len(free) == 0:
            print(f"{d}: no open point past x = {x_from}")
            continue
        dist = mirror_distance(free, ym) * 1e3
        bp = branch_point(free, h)
        edge = free[(free[:, 0] > xmax - 2 * h) | (free[:, 1] < 2 * h) | (free[:, 1] > ymax - 2 * h)]
        up, lo = free[free[:, 1] >= ym], free[free[:, 1] < ym]
        near = lambda q: "-" if len(q) == 0 else f"right {1e3*(xmax - q[:, 0].max()):.1f}, top {1e3*(ymax - q[:, 1].max()):.1f}, bottom {1e3*q[:, 1].min():.1f}"
        print(
            f"{d} (h {h*1e3:g} mm): {len(free)} open points past x = {x_from*1e3:g} mm, x {free[:, 0].min()*1e3:.1f}-{free[:, 0].max()*1e3:.1f} mm, "
            f"y {free[:, 1].min()*1e3:.1f}-{free[:, 1].max()*1e3:.1f} mm; mirror distance median/p90/max "
            f"{np.median(dist):.2f}/{np.percentile(dist, 90):.2f}/{dist.max():.2f} mm; "
            f"branch point x {'none' if bp is None else f'{bp*1e3:.0f} mm'}; "
            f"open points within 2 h of an edge: {', '.join(f'({x*1e3:.1f}, {y*1e3:.1f})' for x, y in edge) or 'none'}; "
            f"nearest to the edges (mm), above y = {ym*1e3:g} mm: {near(up)}; below: {near(lo)}"
        )
    plt.tight_layout()
    plt.savefig(out, dpi=150)


if __name__ == "__main__":
    main()
