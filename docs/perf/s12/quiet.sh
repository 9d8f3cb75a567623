#!/bin/bash
# Quiet measurements on the final main (lead, session 12).
set -x
F=/work/main/target/release/flem
O=/work/main/docs/perf/s12
cd /work/main
uptime
$F bench step --sizes 32768,100000,1000000 --kinds q4 --threads 1,2 --step-sizes 100000 --min-time 0.3 > $O/quiet_bench_step.json 2> $O/quiet_bench_step.err
uptime
for r in 1 2 3; do $F bench step --sizes 1000000 --kinds q4 --threads 1,2 --step-sizes 8 --min-time 0.3 > $O/quiet_kernel_1e6_run$r.json 2>/dev/null; done
uptime
(cd /work/shared/peers && /work/peersvenv/bin/python akantu_explicit_throughput.py --sizes 256 --cells q4 --meshdir /work/peermeshes) > $O/quiet_akantu.log 2>&1
uptime
