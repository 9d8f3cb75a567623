#!/usr/bin/env bash
# Ours (issue 34, must-show 5; docs/paths.md "Cost"): CPU time per event (events solver) of the
# edge rule and of `tip_mts` on the scenes of configs/paths/, each scene's rule replaced, the
# edge rule's run right before its tip_mts run, each run REPEATS times (the least CPU kept: the
# machine is shared). CPU = the process's task clock (`perf stat -e task-clock`, 1 us
# resolution; /usr/bin/time's 10 ms is too coarse for the small meshes' 0.1 s runs).
# Usage: tools/paths_cost.sh FLEM OUT_DIR [REPEATS] [SCENE...]   (default: every configs/paths scene)
# TIP_OPTS="piece = 0.05; shrink = 1.5" adds keys to tip_mts's table (separated by "; ").
set -euo pipefail
flem=$(realpath "$1"); out=$(realpath -m "$2"); reps=${3:-2}; shift 3 || shift $#
root=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$out/scenes"
scenes=("$@"); [ ${#scenes[@]} -eq 0 ] && scenes=($(ls "$root"/configs/paths/*.toml))
printf "%-18s %8s %8s %10s %10s %6s\n" scene ev_edge ev_tip ms_ev_edge ms_ev_tip ratio
for f in "${scenes[@]}"; do
  n=$(basename "$f" .toml)
  declare -A ms ev
  for rule in sigma1_nearest tip_mts; do
    s="$out/scenes/${n}_$rule.toml"
    extra=""; [ "$rule" = tip_mts ] && [ -n "${TIP_OPTS:-}" ] && extra="\\n${TIP_OPTS//; /\\n}"
    sed "s#\.\./meshes/#$root/configs/meshes/#; s#type = \"sigma1_nearest\"#type = \"$rule\"$extra#" "$f" > "$s"
    best=""
    for r in $(seq "$reps"); do
      rm -rf "$out/run"
      perf stat -x, -e task-clock -o "$out/t.txt" "$flem" run "$s" --out "$out/run" > /dev/null 2>&1
      c=$(awk -F, '/task-clock/ {print $1 / 1000}' "$out/t.txt")
      if [ -z "$best" ] || awk "BEGIN{exit !($c < $best)}"; then best=$c; fi
    done
    e=$(python3 -c "import json;print(json.load(open('$out/run/summary.json'))['steps'])")
    ev[$rule]=$e; ms[$rule]=$(awk "BEGIN{printf \"%.2f\", 1000*$best/$e}")
  done
  printf "%-18s %8s %8s %10s %10s %6s\n" "$n" "${ev[sigma1_nearest]}" "${ev[tip_mts]}" "${ms[sigma1_nearest]}" "${ms[tip_mts]}" "$(awk "BEGIN{printf \"%.2f\", ${ms[tip_mts]}/${ms[sigma1_nearest]}}")"
done
