#!/usr/bin/env bash
# Session 3 (issue 9): FLEM kernel 1/2 threads at the Akantu mesh sizes, then Akantu on the same
# meshes, then the notched plate (without and with contact) beside Akantu's cohesive run.
# Paths: /work/peer-meshes (../shared/peers/gen_meshes.py), /work/venv-akantu (peers/setup.sh).
set -x
OUT=${OUT:-/work/perf-out/s3}
mkdir -p $OUT
date -u; uptime
./target/release/flem bench step --sizes 2048,32768,524288,1000000 --kinds q4,t3 --threads 1,2 --step-sizes 32768 --min-time 0.5 > $OUT/bench_step.json 2> $OUT/bench_step.err
date -u; uptime
/work/venv-akantu/bin/python ../shared/peers/akantu_explicit_throughput.py --meshdir /work/peer-meshes --sizes 64,256,1024 --cells q4,t3 > $OUT/akantu_tp.log 2> $OUT/akantu_tp.err
date -u; uptime
/work/venv-akantu/bin/python ../shared/peers/akantu_cohesive_notch.py --mesh /work/peer-meshes/notch_q4_h0.25_v22.msh --out $OUT/akantu_notch_crack.json > $OUT/akantu_notch.log 2> $OUT/akantu_notch.err
(cd configs && for s in notch_q4_h0.25 notch_q4_h0.25_contact; do for i in 1 2 3; do ../target/release/flem run bench/$s.toml --out $OUT/$s.$i --quiet; done; done) > $OUT/flem_notch.log 2>&1
date -u; uptime
