#!/usr/bin/env bash
# The implicit solve against CHOLMOD (sksparse-minimal, OpenBLAS preloaded) and MKL Pardiso
# (pypardiso) on the same problem (../shared/peers/implicit_peer.py: the structured plane-strain
# Q4 mesh of `flem bench implicit`), interleaved so that a change of load on a shared machine falls
# on both sides: for each round and thread count, FLEM's bench then the peers'.
#
#   VENV=/path/to/peer-venv bash tools/peers/implicit_vs_peers.sh OUTDIR [DOFS] [THREADS] [ROUNDS]
#
# Needs the peer venv (bash ../shared/peers/setup.sh) and libopenblas0-pthread. Writes one JSON
# per run into OUTDIR (flem_t<threads>_r<round>.json, peer_t<threads>_r<round>.jsonl).
set -euo pipefail
OUT=${1:?usage: implicit_vs_peers.sh OUTDIR [DOFS] [THREADS] [ROUNDS]}
DOFS=${2:-100000,500000}
THREADS=${3:-1,2}
ROUNDS=${4:-2}
VENV=${VENV:?set VENV to the peer venv}
HERE=$(cd "$(dirname "$0")/../.." && pwd)
PEER=${PEER:-$HERE/../shared/peers/implicit_peer.py}
FLEM=${FLEM:-$HERE/target/release/flem}
BLAS=$(ldconfig -p | awk '/libopenblas.so.0 /{print $NF; exit}')
[ -n "$BLAS" ] || { echo "implicit_vs_peers: no libopenblas.so.0 (apt-get install libopenblas0-pthread)" >&2; exit 2; }
mkdir -p "$OUT"
for r in $(seq 1 "$ROUNDS"); do
  for t in ${THREADS//,/ }; do
    "$FLEM" bench implicit --dofs "$DOFS" --repeats 2 --threads "$t" > "$OUT/flem_t${t}_r${r}.json"
    OPENBLAS_NUM_THREADS=$t MKL_NUM_THREADS=$t OMP_NUM_THREADS=$t LD_PRELOAD="$BLAS" \
      "$VENV/bin/python" "$PEER" "$DOFS" > "$OUT/peer_t${t}_r${r}.jsonl"
  done
done
"$VENV/bin/python" - "$OUT" <<'PY'
import json, sys, glob, os
out = sys.argv[1]
best = {}
for f in glob.glob(os.path.join(out, "flem_t*_r*.json")):
    t = int(os.path.basename(f).split("_")[1][1:])
    for r in json.load(open(f))["rows"]:
        k = (r["dofs"], t)
        b = best.setdefault(k, {})
        b["flem_whole"] = min(b.get("flem_whole", 1e99), r["ours_cold"]["total"])
        b["flem_first"] = min(b.get("flem_first", 1e99), r["ours_cold_first"]["total"])
        b["flem_factor_solve"] = min(b.get("flem_factor_solve", 1e99), r["ours_cold"]["symbolic"] + r["ours_cold"]["numeric"] + r["ours_cold"]["solve"])
        b["faer_bare_amd"] = min(b.get("faer_bare_amd", 1e99), r["bare"]["total"])
for f in glob.glob(os.path.join(out, "peer_t*_r*.jsonl")):
    t = int(os.path.basename(f).split("_")[1][1:])
    for line in open(f):
        r = json.loads(line)
        b = best.setdefault((r["dofs"], t), {})
        for key in ("cholmod_factor_solve", "pardiso_factor_solve"):
            if key in r:
                b[key] = min(b.get(key, 1e99), r[key])
rows = []
for (dofs, t), b in sorted(best.items()):
    row = {"dofs": dofs, "threads": t, **b}
    for peer in ("cholmod_factor_solve", "pardiso_factor_solve"):
        if peer in b and "flem_whole" in b:
            row["flem_whole_over_" + peer.split("_")[0]] = b["flem_whole"] / b[peer]
            row["flem_first_over_" + peer.split("_")[0]] = b["flem_first"] / b[peer]
    rows.append(row)
json.dump({"what": "best of all rounds; flem_whole = checks + assembly + ordering + factorisation + solve (best repeat: the factor's pages reused); flem_first = the same for the first solve of a row, no pages kept; peers: factorisation + solve of the assembled matrix", "rows": rows}, open(os.path.join(out, "summary.json"), "w"), indent=1)
for row in rows:
    print(json.dumps(row))
PY
