#!/usr/bin/env python3
"""The kink table of docs/paths.md (issue 34, must-show 2) from two `flem paths --out` files.

    python3 tools/kink_table.py SETTING.json [DEFAULTS.json] > table.md

One row per initial tip of SETTING.json: scene, tip, element size, the MTS angle of the
implicit solution's factors, the chord over five element sizes and its error (deg; the same run
in DEFAULTS.json beside it when given, matched by scene and tip), the least-squares angle, node
moves (refused) and fragments below 3 elements. A summary (tips within 5 deg, largest and median
error) goes to stderr. Standard library only.
"""
import json
import statistics
import sys


def main(argv):
    if len(argv) not in (2, 3):
        print(__doc__, file=sys.stderr)
        return 2
    rows = json.load(open(argv[1]))
    base = {}
    if len(argv) == 3:
        base = {(r["scene"], r["kink"]["tip_point"]): r for r in json.load(open(argv[2]))}
    head = ["scene", "tip", "h", "MTS (implicit)"]
    if base:
        head.append("defaults: chord (error)")
    head += ["chord (error)", "lsq", "moves (refused)", "frag < 3"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    errs, berrs = [], []
    for r in rows:
        k = r["kink"]
        if k.get("chord_deg") is None:
            print("note: %s tip %s has no chord (path shorter than 5 h)" % (r["scene"], k["tip_point"]), file=sys.stderr)
            continue
        name = r["scene"].split("/")[-1].removesuffix(".toml")
        cells = [name, str(k["tip_point"]), "%.4f" % k["h"], "%.1f" % r["mts_deg"]]
        if base:
            b = base.get((r["scene"], k["tip_point"]))
            if b is None or b["kink"].get("chord_deg") is None:
                cells.append("-")
            else:
                cells.append("%.1f (%.1f)" % (b["kink"]["chord_deg"], b["error_deg"]))
                berrs.append(abs(b["error_deg"]))
        cells += ["%.1f (%.1f)" % (k["chord_deg"], r["error_deg"]), "%.1f" % k["lsq_deg"], "%d (%d)" % (r["moves"], r["refused_moves"]), str(r["small_fragments"])]
        errs.append(abs(r["error_deg"]))
        print("| " + " | ".join(cells) + " |")
    runs = len({r["scene"] for r in rows})
    summary = lambda e: "%d of %d within 5 deg, largest %.1f, median %.1f" % (sum(x <= 5.0 for x in e), len(e), max(e), statistics.median(e))
    print("%d tips in %d runs: %s" % (len(errs), runs, summary(errs)), file=sys.stderr)
    if berrs:
        print("defaults: %s" % summary(berrs), file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
