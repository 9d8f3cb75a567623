"""Winkler's L-panel runs (docs/paths.md, section "Winkler's L-panel"): tables and figures.

    python3 tools/lpanel.py OUT.json RUN_DIR... [--png-paths FILE] [--png-load FILE] [--png-faces FILE] [--title T]

(/work/main/.venv: numpy, meshio, matplotlib). For each `flem run` folder of a
configs/lpanel/ scene:
- the load-displacement curve: `level_lift` (mm, the scene's unit level is 1 mm) against the
  force of the experiment, `|reaction_lift_y|` x 0.1 m (thickness) in kN, at the last
  history row of each level (the stage's end, at rest); the peak and its displacement;
- the crack path: the crack faces (VTU line cells with `crack` > 0, reference coordinates) of
  the last snapshot, as a graph; the path is the shortest path along the faces from the
  re-entrant corner (0.25, 0.25), or the face point nearest it, to the face point farthest from
  it (the crack's end); `reached` when that point lies on the outer boundary;
- the fragments of fewer than 3 elements (elements joined through a shared cluster, the run's
  own definition in check::paths::fragment_sizes).
Then the Hausdorff distance between every two runs' paths (points every 1e-4 of the specimen
size, 0.5 m, along both polylines), in % of 0.5 m. Writes OUT.json and prints markdown tables.
"""
import csv
import glob
import heapq
import json
import math
import os
import sys

import numpy as np

SIZE = 0.5
CORNER = (0.25, 0.25)
T = 0.1  # thickness, m
BAND = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "configs", "lpanel", "winkler_band.csv")


def load_curve(d):
    rows = list(csv.DictReader(open(os.path.join(d, "history.csv"))))
    last = {}
    order = []
    for r in rows:
        u = float(r["level_lift"])
        if u not in last:
            order.append(u)
        last[u] = abs(float(r["reaction_lift_y"])) * T / 1e3
    return [(0.0, 0.0)] + [(u, last[u]) for u in order if u > 0]


def on_boundary(x, y, tol=1e-7):
    return bool(x < tol) or y < tol or x > SIZE - tol or y > SIZE - tol or (abs(x - 0.25) < tol and y < 0.25 + tol) or (abs(y - 0.25) < tol and x > 0.25 - tol)


def crack(d):
    import meshio

    snaps = sorted(glob.glob(os.path.join(d, "snapshot_*.vtu")))
    if not snaps:
        return None
    m = meshio.read(snaps[-1])
    pts = m.points[:, :2]
    segs, cells_elem = [], []
    for blk, data in zip(m.cells, m.cell_data["crack"]):
        if blk.type == "line":
            for c, s in zip(blk.data.astype(int), data):
                if s > 0:
                    segs.append((tuple(np.round(pts[c[0]], 9)), tuple(np.round(pts[c[1]], 9))))
        else:
            cells_elem.extend(blk.data.astype(int).tolist())
    # fragments: union-find over clusters (a VTU point is a cluster)
    parent = list(range(len(cells_elem)))

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    owner = {}
    for e, cl in enumerate(cells_elem):
        for c in cl:
            if c in owner:
                ra, rb = find(owner[c]), find(e)
                if ra != rb:
                    parent[ra] = rb
            else:
                owner[c] = e
    sizes = {}
    for e in range(len(cells_elem)):
        r = find(e)
        sizes[r] = sizes.get(r, 0) + 1
    small = sorted(s for s in sizes.values() if s < 3)
    # crack graph
    adj = {}
    for a, b in segs:
        if a == b:
            continue
        w = math.dist(a, b)
        adj.setdefault(a, []).append((b, w))
        adj.setdefault(b, []).append((a, w))
    if not adj:
        return {"path": [], "segments": 0, "small_fragments": small, "fragments": len(sizes), "reached": False, "branch_points": 0}
    start = min(adj, key=lambda p: math.dist(p, CORNER))
    dist, prev = {start: 0.0}, {}
    h = [(0.0, start)]
    while h:
        dd, p = heapq.heappop(h)
        if dd > dist[p]:
            continue
        for q, w in adj[p]:
            if dd + w < dist.get(q, math.inf):
                dist[q], prev[q] = dd + w, p
                heapq.heappush(h, (dd + w, q))
    end = max(dist, key=lambda p: (math.dist(p, start), p))
    path = [end]
    while path[-1] != start:
        path.append(prev[path[-1]])
    path.reverse()
    unreached = len(adj) - len(dist)
    return {
        "path": [list(p) for p in path],
        "segments": len(segs),
        "unconnected_face_points": unreached,
        "branch_points": sum(1 for p in dist if len(adj[p]) > 2),
        "reached": bool(on_boundary(*end)),
        "small_fragments": small,
        "fragments": len(sizes),
        "start": list(start),
        "end": list(end),
    }


def sample(path, step):
    out = []
    for a, b in zip(path, path[1:]):
        n = max(1, int(math.ceil(math.dist(a, b) / step)))
        for k in range(n):
            t = k / n
            out.append((a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])))
    out.append(tuple(path[-1]))
    return np.array(out)


def hausdorff(p, q):
    a, b = sample(p, 1e-4 * SIZE), sample(q, 1e-4 * SIZE)
    d = np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(-1)) if len(a) * len(b) < 4e7 else None
    if d is None:
        from scipy.spatial import cKDTree  # noqa

        return max(cKDTree(b).query(a)[0].max(), cKDTree(a).query(b)[0].max())
    return max(d.min(1).max(), d.min(0).max())


def band():
    rows = [r for r in open(BAND) if r.strip() and not r.startswith("#")]
    rd = list(csv.DictReader(rows))
    return np.array([[float(r["U_mm"]), float(r["F_lb_kN"]), float(r["F_ub_kN"])] for r in rd])


def faces_figure(dirs, png, title):
    """Every run's crack faces (red: separated at both ends, orange: at one end) on the panel,
    one panel per run, three per row."""
    import meshio
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(dirs)
    cols = min(3, n)
    rows = (n + cols - 1) // cols
    fig, axs = plt.subplots(rows, cols, figsize=(3.2 * cols, 3.2 * rows), squeeze=False)
    L = np.array([[0, 0], [250, 0], [250, 250], [500, 250], [500, 500], [0, 500], [0, 0]])
    for ax in axs.flat:
        ax.set_axis_off()
    for ax, d in zip(axs.flat, dirs):
        snaps = sorted(glob.glob(os.path.join(d, "snapshot_*.vtu")))
        ax.plot(L[:, 0], L[:, 1], "k-", lw=0.5)
        ax.plot([470, 500], [250, 250], "b-", lw=2)
        if snaps:
            m = meshio.read(snaps[-1])
            P = m.points[:, :2] * 1e3
            for blk, c in zip(m.cells, m.cell_data["crack"]):
                if blk.type == "line":
                    for e, st in zip(blk.data.astype(int), c):
                        if st > 0:
                            ax.plot(P[e, 0], P[e, 1], color="red" if st == 2 else "orange", lw=1)
        ax.set_aspect("equal")
        ax.set_title(os.path.basename(os.path.normpath(d)), fontsize=8)
    fig.suptitle(title, fontsize=9)
    fig.savefig(png, dpi=110, bbox_inches="tight")


def main(argv):
    args, opts = [], {}
    it = iter(argv)
    for a in it:
        if a.startswith("--"):
            opts[a[2:]] = next(it)
        else:
            args.append(a)
    out, dirs = args[0], args[1:]
    runs = []
    for d in dirs:
        name = os.path.basename(os.path.normpath(d))
        curve = load_curve(d)
        if not os.path.exists(os.path.join(d, "summary.json")) and len(curve) > 1:
            curve = curve[:-1]  # a run still going (or stopped): its last level's row is mid-stage
        k = max(range(len(curve)), key=lambda i: curve[i][1])
        c = crack(d) or {}
        sm = os.path.join(d, "summary.json")
        summ = json.load(open(sm)) if os.path.exists(sm) else {}
        extra = {"finished": bool(summ), "splits": summ.get("splits"), "beyond_criterion": summ.get("beyond_criterion"), "wall_seconds": summ.get("wall_seconds"), "u_last_mm": curve[-1][0]}
        runs.append({"run": name, "curve": curve, "peak_kN": curve[k][1], "u_peak_mm": curve[k][0], **c, **extra})
    names = [r["run"] for r in runs]
    H = {}
    for i, a in enumerate(runs):
        for b in runs[i + 1 :]:
            if a.get("path") and b.get("path") and len(a["path"]) > 1 and len(b["path"]) > 1:
                H[f'{a["run"]}|{b["run"]}'] = 100 * hausdorff(a["path"], b["path"]) / SIZE
    json.dump({"runs": runs, "hausdorff_percent": H}, open(out, "w"), indent=1, default=float)
    print("| run | peak (kN) | u at peak (mm) | last stage (mm) | path end (mm) | reached boundary | crack faces | branch points | fragments < 3 el. | splits | failed points left uncut |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in runs:
        e = r.get("end")
        es = f"({1e3 * e[0]:.0f}, {1e3 * e[1]:.0f})" if e else "-"
        last = f'{r["u_last_mm"]:.2f}' + ("" if r["finished"] else " (stopped)")
        print(f'| {r["run"]} | {r["peak_kN"]:.2f} | {r["u_peak_mm"]:.3f} | {last} | {es} | {r.get("reached")} | {r.get("segments")} | {r.get("branch_points")} | {len(r.get("small_fragments", []))} | {r.get("splits")} | {r.get("beyond_criterion")} |')
    print()
    print("| | " + " | ".join(names) + " |")
    print("|---" * (len(names) + 1) + "|")
    for a in names:
        cells = []
        for b in names:
            v = H.get(f"{a}|{b}", H.get(f"{b}|{a}"))
            cells.append("-" if a == b else ("n/a" if v is None else f"{v:.1f}"))
        print(f"| {a} | " + " | ".join(cells) + " |")
    if "png-faces" in opts:
        faces_figure(dirs, opts["png-faces"], opts.get("title", "L-panel crack faces"))
    if "png-paths" in opts or "png-load" in opts:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        colours = {"t3": "tab:blue", "quad": "tab:orange", "q4": "tab:green"}
        styles = {"1": ":", "2": "--", "3": "-"}

        def style(n):
            parts = n.split("_")
            kind = next((p for p in parts if p in colours), "t3")
            ref = next((p for p in parts if p in styles), "3")
            return colours[kind], styles[ref]

        def extra(n):
            # the edge rule's runs (folder names starting "lpe"): thin, crosses
            return {"lw": 0.8, "marker": "x", "ms": 3, "alpha": 0.7} if os.path.basename(n).startswith("lpe") else {"lw": 1.5}

        if "png-paths" in opts:
            fig, ax = plt.subplots(figsize=(6, 6))
            L = np.array([[0, 0], [250, 0], [250, 250], [500, 250], [500, 500], [0, 500], [0, 0]])
            ax.plot(L[:, 0], L[:, 1], "k-", lw=1)
            ax.plot([470, 500], [250, 250], "r-", lw=3, label="load")
            for r in runs:
                if r.get("path"):
                    p = 1e3 * np.array(r["path"])
                    c, s = style(r["run"])
                    kw = extra(r["run"])
                    kw.pop("marker", None), kw.pop("ms", None)
                    ax.plot(p[:, 0], p[:, 1], color=c, ls=s, label=r["run"], **kw)
            ax.set_aspect("equal")
            ax.set_xlabel("x (mm)")
            ax.set_ylabel("y (mm)")
            ax.set_title(opts.get("title", "L-panel crack paths"), fontsize=9)
            ax.legend(fontsize=6, loc="upper right")
            fig.savefig(opts["png-paths"], dpi=120, bbox_inches="tight")
        if "png-load" in opts:
            fig, ax = plt.subplots(figsize=(7, 4.5))
            b = band()
            ax.fill_between(b[:, 0], b[:, 1], b[:, 2], color="0.8", label="experiments (Winkler, band)")
            for r in runs:
                cu = np.array(r["curve"])
                c, s = style(r["run"])
                kw = {"marker": ".", "ms": 3, **extra(r["run"])}
                ax.plot(cu[:, 0], cu[:, 1], color=c, ls=s, label=r["run"], **kw)
            ax.set_xlabel("u (mm)")
            ax.set_ylabel("F (kN)")
            ax.set_xlim(0, 0.75)
            ax.set_title(opts.get("title", "L-panel load-displacement"), fontsize=9)
            ax.legend(fontsize=6)
            fig.savefig(opts["png-load"], dpi=120, bbox_inches="tight")


if __name__ == "__main__":
    main(sys.argv[1:])
