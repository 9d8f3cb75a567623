#!/usr/bin/env bash
# Ours (issue 34, must-show 5, per step; docs/paths.md "Cost"): CPU time per step of the explicit
# march with the edge rule and with `tip_mts` on shear-test scenes of configs/paths/ (as
# tests/paths.rs `tip_mts_in_the_explicit_march`: the events solver replaced by the explicit
# march to equilibrium, tolerance 1e-4, a failure check every 10 steps, the displacement raised
# in four stages 0.01, 0.02, 0.025, 0.03, at most 20000 steps each). Least CPU (task clock,
# `perf stat`) of REPEATS runs.
# Usage: tools/paths_cost_explicit.sh FLEM OUT_DIR REPEATS SCENE...
# TIP_OPTS="piece = 0.05; shrink = 1.5" adds keys to tip_mts's table (separated by "; ").
set -euo pipefail
flem=$(realpath "$1"); out=$(realpath -m "$2"); reps=$3; shift 3
root=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$out/scenes"
printf "%-18s %8s %8s %10s %10s %6s\n" scene st_edge st_tip us_st_edge us_st_tip ratio
for f in "$@"; do
  n=$(basename "$f" .toml)
  declare -A us st
  for rule in sigma1_nearest tip_mts; do
    s="$out/scenes/${n}_$rule.toml"
    python3 - "$f" "$s" "$rule" "$root" <<'PY'
import sys, re
src, dst, rule, root = sys.argv[1:]
import os
extra = "".join("\n" + kv.strip() for kv in os.environ.get("TIP_OPTS", "").split(";") if kv.strip()) if rule == "tip_mts" else ""
t = open(src).read().replace("../meshes/", root + "/configs/meshes/").replace('type = "sigma1_nearest"', f'type = "{rule}"{extra}')
t = re.sub(r'\[solver\]\n(.*\n)*?\n', '[solver]\ntolerance = 1e-4\n\n', t, count=1)
t = t.replace("[cracking]\n", "[cracking]\ncheck_every = 10\n", 1)
t = t[: t.index("[[stage]]")]
for k, v in enumerate([0.01, 0.02, 0.025, 0.03]):
    t += f'[[stage]]\nname = "s{k}"\nlevels = {{ shear = {v} }}\nmax_steps = 20000\n\n'
open(dst, "w").write(t)
PY
    best=""
    for r in $(seq "$reps"); do
      rm -rf "$out/run"
      perf stat -x, -e task-clock -o "$out/t.txt" "$flem" run "$s" --out "$out/run" > /dev/null 2>&1 || true
      c=$(awk -F, '/task-clock/ {print $1 / 1000}' "$out/t.txt")
      if [ -z "$best" ] || awk "BEGIN{exit !($c < $best)}"; then best=$c; fi
    done
    e=$(python3 -c "import json;print(json.load(open('$out/run/summary.json'))['steps'])")
    st[$rule]=$e; us[$rule]=$(awk "BEGIN{printf \"%.1f\", 1e6*$best/$e}")
  done
  printf "%-18s %8s %8s %10s %10s %6s\n" "$n" "${st[sigma1_nearest]}" "${st[tip_mts]}" "${us[sigma1_nearest]}" "${us[tip_mts]}" "$(awk "BEGIN{printf \"%.2f\", ${us[tip_mts]}/${us[sigma1_nearest]}}")"
done
