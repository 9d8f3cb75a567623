"""Sweep benchmark (issue 22; not a test): wall time of a 16-seed Weibull sweep
(examples/weibull_bar.toml) on 1 and 2 Dask workers, and the per-task overhead of the Dask path
against bare runs of the same task function in this process; also `flem sweep` (local worker
processes) on 1 and 2 workers. Prints JSON. Usage:

    .venv/bin/python python/bench/sweep.py [--tasks 16] [--flem target/release/flem]

Cluster start-up is timed apart (a LocalCluster is started once per worker count, before the
sweep is timed). Figures in docs/python.md.
"""
import argparse
import json
import os
import subprocess
import tempfile
import time
from pathlib import Path

import flem
from flem import _native

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--tasks", type=int, default=16)
    ap.add_argument("--flem", default=str(ROOT / "target" / "release" / "flem"))
    a = ap.parse_args()
    from distributed import Client, LocalCluster

    scene = flem.Scene.from_file(ROOT / "examples" / "weibull_bar.toml")
    seeds = list(range(1, a.tasks + 1))
    out = {"scene": "examples/weibull_bar.toml", "tasks": a.tasks, "cores": os.cpu_count()}
    tmp = Path(tempfile.mkdtemp(prefix="flem-bench-"))
    # Bare: the task function itself, serially in this process (no Dask, no pickling).
    t0 = time.perf_counter()
    bare = []
    for i, s in enumerate(seeds):
        row = json.loads(_native.run_task(i, scene._text, scene._path, scene._base, json.dumps({"cracking.weibull.seed": s}), str(tmp / f"bare_{i}"), 1))
        bare.append(row["wall_seconds"])
    out["bare_serial_wall_seconds"] = time.perf_counter() - t0
    out["bare_task_mean_seconds"] = sum(bare) / len(bare)
    for n in (1, 2):
        t0 = time.perf_counter()
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
        out[f"dask_{n}_startup_seconds"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        table = flem.sweep(scene, {"cracking.weibull.seed": seeds}, client=client, out=tmp / f"dask{n}")
        wall = time.perf_counter() - t0
        client.close()
        cluster.close()
        assert table["error"].isna().all()
        in_tasks = float(table["wall_seconds"].sum())
        out[f"dask_{n}_workers_wall_seconds"] = wall
        # Per task: the sweep's wall time times the workers, less the time spent inside the
        # tasks, over the tasks (scheduling, pickling, result transfer, idle tails).
        out[f"dask_{n}_overhead_per_task_seconds"] = (wall * n - in_tasks) / a.tasks
        out[f"dask_{n}_task_mean_seconds"] = in_tasks / a.tasks
    for n in (1, 2):
        f = tmp / f"cli{n}.toml"
        f.write_text(f'scene = "{ROOT / "examples" / "weibull_bar.toml"}"\nout = "cli{n}"\n[grid]\n"cracking.weibull.seed" = {seeds}\n')
        t0 = time.perf_counter()
        subprocess.run([a.flem, "sweep", str(f), "--workers", str(n)], check=True, capture_output=True)
        out[f"cli_{n}_workers_wall_seconds"] = time.perf_counter() - t0
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
