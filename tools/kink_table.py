#!/usr/bin/env python3
"""The kink table of docs/paths.md (issue 34, must-show 2) from two `flem paths --out` files.

    python3 tools/kink_table.py SETTING.json [DEFAULTS.json] [--label TEXT] > table.md

One row per initial tip of SETTING.json: scene, tip, element size, the MTS angle of the
implicit solution's factors, the chord over five element sizes and its error (deg; the same run
in DEFAULTS.json beside it when given, matched by scene and tip), the least-squares angle, node
moves (refused) and fragments below 3 elements; a tip not measured over five element sizes is
printed `short` and counted as a miss. A summary (tips within 5 deg, largest and median error)
goes to stderr. `--label TEXT` names the second file's column and summary (default
"defaults"). Standard library only.
"""
import json
import statistics
import sys


def main(argv):
    label = "defaults"
    if "--label" in argv:
        i = argv.index("--label")
        if i + 1 >= len(argv):
            print(__doc__, file=sys.stderr)
            return 2
        label = argv[i + 1]
        argv = argv[:i] + argv[i + 2:]
    if len(argv) not in (2, 3):
        print(__doc__, file=sys.stderr)
        return 2
    rows = json.load(open(argv[1]))
    base = {}
    if len(argv) == 3:
        base = {(r["scene"], r["kink"]["tip_point"]): r for r in json.load(open(argv[2]))}
    head = ["scene", "tip", "h", "MTS (implicit)"]
    if base:
        head.append("%s: chord (error)" % label)
    head += ["chord (error)", "lsq", "moves (refused)", "frag < 3"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    errs, berrs = [], []
    short = 0

    def cell(r):
        """'chord (error)' of a row, or None when the tip was not measured over 5 h."""
        k = r["kink"]
        if k.get("chord_deg") is None or r.get("error_deg") is None:
            return None
        return "%.1f (%.1f)" % (k["chord_deg"], r["error_deg"])

    for r in rows:
        try:
            k = r["kink"]
            name = r["scene"].split("/")[-1].removesuffix(".toml")
        except (KeyError, TypeError):
            sys.exit("error: %s is not `flem paths --out` JSON (a row without scene / kink)" % argv[1])
        mts = "-" if r.get("mts_deg") is None else "%.1f" % r["mts_deg"]
        cells = [name, str(k["tip_point"]), "%.4f" % k["h"], mts]
        if base:
            b = base.get((r["scene"], k["tip_point"]))
            c = None if b is None else cell(b)
            cells.append(c or "short")
            berrs.append(abs(b["error_deg"]) if c else float("inf"))
        c = cell(r)
        if c is None:
            short += 1
        lsq = "-" if k.get("lsq_deg") is None else "%.1f" % k["lsq_deg"]
        cells += [c or "short", lsq, "%d (%d)" % (r["moves"], r["refused_moves"]), str(r["small_fragments"])]
        # An unmeasured tip (its path shorter than 5 h, or no MTS angle) counts as a miss.
        errs.append(abs(r["error_deg"]) if c else float("inf"))
        print("| " + " | ".join(cells) + " |")
    runs = len({r["scene"] for r in rows})
    summary = lambda e: "%d of %d within 5 deg (%d not measured), largest measured %.1f, median %.1f" % (
        sum(x <= 5.0 for x in e), len(e), sum(x == float("inf") for x in e), max([x for x in e if x != float("inf")] or [float("nan")]), statistics.median(e))
    print("%d tips in %d runs: %s" % (len(errs), runs, summary(errs)), file=sys.stderr)
    if berrs:
        print("%s: %s" % (label, summary(berrs)), file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
