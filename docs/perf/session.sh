#!/usr/bin/env bash
# One session: FLEM bench, then Akantu on the same meshes, then the notch runs.
set -x
cd /work/wt-perf
date -u; uptime
/usr/bin/time -v /work/tgt-perf/release/flem bench step --sizes 1000,2048,10000,32768,100000,524288,1000000 --step-sizes 10000,32768 --min-time 0.5 > /work/perf-out/bench.json 2> /work/perf-out/bench.err
date -u; uptime
/usr/bin/time -v /work/venv-akantu/bin/python /work/shared/peers/akantu_explicit_throughput.py --meshdir /work/peer-meshes --sizes 64,256,1024 --cells q4,t3 > /work/perf-out/akantu_tp.log 2> /work/perf-out/akantu_tp.err
date -u; uptime
cd configs && /usr/bin/time -v /work/tgt-perf/release/flem run bench/notch_q4_h0.25.toml --out /work/perf-out/notch --quiet > /work/perf-out/notch.log 2>&1
cd /work/perf-out && /usr/bin/time -v /work/venv-akantu/bin/python /work/shared/peers/akantu_cohesive_notch.py --mesh /work/peer-meshes/notch_q4_h0.25_v22.msh --out /work/perf-out/peer-out/akantu_notch_crack.json > /work/perf-out/akantu_notch.log 2> /work/perf-out/akantu_notch.err
date -u; uptime
