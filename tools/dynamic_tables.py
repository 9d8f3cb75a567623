#!/usr/bin/env python3
"""The tables of docs/dynamic.md (issue 36) from run folders of configs/dynamic/ scenes:
    python3 tools/dynamic_tables.py kalthoff out/kalthoff_h1 ...
    python3 tools/dynamic_tables.py branching out/branching_h0.5 ...
    python3 tools/dynamic_tables.py front-diff [--kalthoff] out/base out/other ...   (the front's history against a base run;
        distances from the branching plate's notch tip (0.05, 0.02), or Kalthoff's (0.05, 0.025) with --kalthoff)
Reads crack_tips.csv, splits.csv and summary.json (standard library only). Definitions: the
front is the tip (with a branch) farthest from the notch tip at each record; its speed is the
advance of that distance over a 2 us window; vmean_10_40mm 30 mm over the time the front took
from 10 to 40 mm, vfit_10_40mm the least-squares slope of the distance against time over that
window's records (vfit_bands_10mm the same over 10 mm bands from 10 to 60 mm: the speed
history); vfit_free_10_40mm the same slope for the free crack, fracture_energy / G_c of each
record while 10-40 mm long (session 36); the Kalthoff angle is the mean angle (from the notch line) of the front while it is 10-20 mm from the notch tip; frac_gc_* is the ledger's
fracture energy over G_c x the front's chord, its arc along the crack, or the crack-face length;
symmetry: each split point's distance to the nearest split point mirrored about y = 0.02."""
import csv, json, math, sys

def load(d):
    tips = list(csv.DictReader(open(d + "/crack_tips.csv")))
    splits = list(csv.DictReader(open(d + "/splits.csv")))
    summ = json.load(open(d + "/summary.json"))
    return tips, splits, summ

def f(x):
    return float(x) if x not in ("", None) else float("nan")

def front(tips, tip0):
    """Per record time: the tip (with a branch) farthest from the notch tip."""
    by = {}
    for r in tips:
        if r["branch"] == "":
            continue
        t = f(r["time"]); x, y = f(r["x"]), f(r["y"])
        dd = math.hypot(x - tip0[0], y - tip0[1])
        if t not in by or dd > by[t][0]:
            by[t] = (dd, x, y, f(r["arc"]), f(r["speed"]))
    return sorted(by.items())

def common(d, tip0, gc, cr):
    tips, splits, s = load(d)
    fr = front(tips, tip0)
    # Front speed: the advance of the front's distance from the notch tip over a window W = 2 us.
    W = 2e-6
    vfront = float("nan")
    for k, (t, v) in enumerate(fr):
        js = [j for j in range(k) if fr[j][0] <= t - W]
        if js:
            tj, vj = fr[js[-1]]
            s_ = (v[0] - vj[0]) / (t - tj)
            vfront = s_ if math.isnan(vfront) else max(vfront, s_)
    last = fr[-1][1] if fr else (0, 0, 0, 0, 0)
    # Mean front speed: the front's distance from the notch tip from 10 to 40 mm over the time
    # it took (robust against the jumps of a window).
    def when(dd):
        return next(((t, v[0]) for t, v in fr if v[0] >= dd), None)
    a, b = when(0.010), when(0.040)
    vmean = (b[1] - a[1]) / (b[0] - a[0]) if a and b and b[0] > a[0] else float("nan")
    # Fitted front speed (session 23): the least-squares slope of the front's distance against
    # time over every record with the distance in [lo, hi] (crack length against time fitted, as
    # experiments and the dynamic-fracture papers read a crack speed). It uses all the records of
    # the window, where the mean speed above uses only the two that first pass 10 and 40 mm.
    def fit(lo, hi):
        pts = [(t, v[0]) for t, v in fr if lo <= v[0] <= hi]
        if len(pts) < 3:
            return float("nan")
        mt = sum(t for t, _ in pts) / len(pts); mx = sum(x for _, x in pts) / len(pts)
        stt = sum((t - mt) ** 2 for t, _ in pts)
        return sum((t - mt) * (x - mx) for t, x in pts) / stt if stt > 0 else float("nan")
    vfit = fit(0.010, 0.040)
    # The free crack (session 36): fracture_energy / G_c, the length of fully opened face that
    # the dissipated energy stands for, one value per record; its fitted speed while it is 10-40
    # mm long (smoother than the split front, which jumps ahead of the open crack).
    free = sorted({f(r["time"]): f(r["fracture_energy"]) / gc for r in tips}.items())
    fpts = [(t, x) for t, x in free if 0.010 <= x <= 0.040]
    if len(fpts) >= 3:
        mt = sum(t for t, _ in fpts) / len(fpts); mx = sum(x for _, x in fpts) / len(fpts)
        stt = sum((t - mt) ** 2 for t, _ in fpts)
        vfree = sum((t - mt) * (x - mx) for t, x in fpts) / stt if stt > 0 else float("nan")
    else:
        vfree = float("nan")
    # The speed history as the fitted speed in 10 mm bands of the front's distance.
    vbands = [round(fit(lo / 1e3, (lo + 10) / 1e3), 1) for lo in (10, 20, 30, 40, 50)]
    en = s["energy"]
    face = f(tips[-1]["crack_length"])
    res = dict(steps=s["steps"], splits=s["splits"], wall=s["stages"][0]["wall_seconds"], dt=s["dt"],
               vfront=vfront, vfront_cr=vfront / cr, chord=last[0], arc=last[3], face=face,
               frac=en["fracture"], frac_gc_chord=en["fracture"] / (gc * last[0]) if last[0] else float("nan"),
               frac_gc_arc=en["fracture"] / (gc * last[3]) if last[3] else float("nan"),
               frac_gc_face=en["fracture"] / (gc * face) if face else float("nan"),
               vmean_10_40mm=vmean, vfit_10_40mm=vfit, vfit_free_10_40mm=vfree, vfit_bands_10mm=vbands, resid=en["relative_residual"], isolated=len({r["time"] for r in tips if r["branch"] == ""}) and sum(1 for r in tips if r["branch"] == "" and r["time"] == tips[-1]["time"]))
    # The fracture account of summary.json (docs/dynamic.md "Energy"; absent in older runs).
    acc = s.get("fracture_account") or {}
    if acc:
        res.update(free_mm=1e3 * acc["free_area"], softening_mm=1e3 * acc["softening_area"], intact_mm=1e3 * acc["intact_area"],
                   frac_gc_free=acc["fracture_over_g_f_free"], identity_error=acc["identity_error"])
    return tips, splits, fr, res

def kalthoff(d):
    tip0 = (0.05, 0.025)
    tips, splits, fr, res = common(d, tip0, 2.213e4, 2803.0)
    # Mean angle of the crack front while it is 10-20 mm from the notch tip (chord from the tip).
    ang = [math.degrees(math.atan2(v[2] - tip0[1], v[1] - tip0[0])) for _, v in fr if 0.010 <= v[0] <= 0.020]
    ang_all = [math.degrees(math.atan2(f(r["y"]) - tip0[1], f(r["x"]) - tip0[0])) for r in splits if 0.010 <= math.hypot(f(r["x"]) - tip0[0], f(r["y"]) - tip0[1]) <= 0.020]
    impact = sum(1 for r in splits if f(r["x"]) < 0.03)
    res.update(angle_front=sum(ang) / len(ang) if ang else float("nan"), angle_splits=sum(ang_all) / len(ang_all) if ang_all else float("nan"), splits_x_lt_30mm=impact)
    return res

def branching(d):
    tip0 = (0.05, 0.02)
    tips, splits, fr, res = common(d, tip0, 3.0, 2125.0)
    t_end = tips[-1]["time"]
    final = [r for r in tips if r["time"] == t_end and r["branch"] != ""]
    reach = [r for r in final if f(r["x"]) >= 0.095]
    forks = sorted(f(r["fork_x"]) for r in final if r["parent"] != "" and f(r["x"]) >= 0.08)
    # Symmetry about y = 0.02: each split point's distance to the nearest mirrored split point.
    pts = [(f(r["x"]), f(r["y"])) for r in splits]
    mir = [(x, 0.04 - y) for x, y in pts]
    import bisect
    mir.sort()
    xs = [p[0] for p in mir]
    dists = []
    for x, y in pts:
        i = bisect.bisect_left(xs, x - 0.002); best = 1.0
        while i < len(mir) and mir[i][0] <= x + 0.002:
            best = min(best, math.hypot(mir[i][0] - x, mir[i][1] - y)); i += 1
        dists.append(best)
    dists.sort()
    longf = sorted(f(r["fork_x"]) for r in final if r["parent"] != "" and math.hypot(f(r["x"]) - f(r["fork_x"]), f(r["y"]) - f(r["fork_y"])) >= 0.005)
    sys.path.insert(0, __file__.rsplit("/", 1)[0] + "/peers")
    from crack_metrics import branch_point
    bp = branch_point(pts)
    res.update(branch_point_mm=1e3 * bp if bp else float("nan"))
    res.update(first_fork_x_of_branch_ge_5mm=longf[0] if longf else float("nan"), tips_final=len(final), tips_at_right=len(reach), fork_x_of_branches_past_80mm=forks,
               sym_median_mm=1e3 * dists[len(dists) // 2], sym_p90_mm=1e3 * dists[int(0.9 * len(dists))],
               ymin_mm=1e3 * min(p[1] for p in pts), ymax_mm=1e3 * max(p[1] for p in pts))
    return res

def front_diff(base, run, tip0=(0.05, 0.02), t0=10e-6, t1=80e-6, dt=0.5e-6):
    """The front's distance from the notch tip in `run` against `base` at the same times, every
    `dt` from `t0` to `t1` (each run's last record at or before the time; before a run's first
    record, that first record): the largest
    difference (m), its median, and the largest relative one where the base's front is past
    10 mm (session 31, the settings study of docs/dynamic.md)."""
    import bisect
    def series(d):
        fr = front(load(d)[0], tip0)
        return [t for t, _ in fr], [v[0] for _, v in fr]
    (bt, bd), (rt, rd) = series(base), series(run)
    def at(ts, ds, t):
        return ds[max(bisect.bisect_right(ts, t) - 1, 0)]
    grid = [t0 + k * dt for k in range(int(round((t1 - t0) / dt)) + 1)]
    diffs = [abs(at(rt, rd, t) - at(bt, bd, t)) for t in grid]
    rel = [abs(at(rt, rd, t) - at(bt, bd, t)) / at(bt, bd, t) for t in grid if at(bt, bd, t) > 0.010]
    return dict(front_diff_max_mm=1e3 * max(diffs), front_diff_median_mm=1e3 * sorted(diffs)[len(diffs) // 2],
                front_diff_max_rel=max(rel) if rel else float("nan"))

if __name__ == "__main__":
    kind = sys.argv[1]
    if kind == "front-diff":
        # python3 tools/dynamic_tables.py front-diff [--kalthoff] BASE RUN...
        args = sys.argv[2:]
        tip0 = (0.05, 0.02)
        if args and args[0] == "--kalthoff":
            args, tip0 = args[1:], (0.05, 0.025)
        for d in args[1:]:
            print(d.split("/")[-1], {k: round(v, 4) for k, v in front_diff(args[0], d, tip0).items()})
        sys.exit(0)
    for d in sys.argv[2:]:
        r = (kalthoff if kind == "kalthoff" else branching)(d)
        print(d.split("/")[-1], {k: (round(v, 4) if isinstance(v, float) else v) for k, v in r.items()})
