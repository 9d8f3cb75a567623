#!/bin/bash
# docs/perf/s16/3d_step.md: one measurement, from the repository root after
# `cargo build --release`: flem bench step3 (T4 and H8 boxes of 1e5 and 1e6 elements, 1 and 2
# threads, 5 rounds), then Akantu's 3D explicit step on the same T4 meshes (written by flem),
# the load average before and after each.
# Usage: VENV=/work/venvs/peers bash docs/perf/s16/3d_step.sh TAG
set -e
tag=${1:-A}
out=out/3d_step_$tag
mkdir -p $out
uptime > $out/load.txt
./target/release/flem bench step3 --sizes 100000,1000000 --write-msh $out/meshes > $out/meshes.json
./target/release/flem bench step3 --sizes 100000,1000000 --kinds t4,h8 --threads 1,2 --rounds 5 --min-time 1.0 > $out/flem.json 2> $out/flem.err
uptime >> $out/load.txt
${VENV:-/work/venvs/peers}/bin/python tools/peers/akantu_3d_throughput.py --meshdir $out/meshes --sizes 100000,1000000 --steps 200 > $out/akantu.out 2> $out/akantu.err
uptime >> $out/load.txt
rm -rf $out/meshes
python3 docs/perf/s16/3d_step_table.py $out/flem.json $out/akantu.out
