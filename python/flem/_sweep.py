"""Parameter sweeps on Dask distributed (issue 22; docs/python.md).

Each task runs one scene, with its parameters set by key path, in a worker process, through the
same Rust task function as ``flem sweep`` (``flem_core::output::sweep::run_task``), into its
own folder ``out/task_NNNN``. A task that fails (a bad parameter, a refused scene, a divergence,
a worker that died) is a row with its ``error``; the others go on.
"""
from __future__ import annotations

import itertools
import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any, Dict, Iterable, List, Mapping, Optional, Sequence, Union

RESULT_COLUMNS = ["initiation_load", "initiation_loadname", "initiation_stage", "splits", "energy_residual", "steps", "converged", "wall_seconds", "out", "error"]


def grid(params: Mapping[str, Sequence[Any]]) -> List[Dict[str, Any]]:
    """Every combination of the values of a dict of lists (the first key varies slowest):
    ``grid({"a": [1, 2], "b": [3]})`` is ``[{"a": 1, "b": 3}, {"a": 2, "b": 3}]``."""
    keys = list(params)
    for k in keys:
        if isinstance(params[k], (str, bytes)) or not hasattr(params[k], "__iter__"):
            raise TypeError(f"grid: the values of {k!r} must be a list")
    return [dict(zip(keys, combo)) for combo in itertools.product(*(list(params[k]) for k in keys))]


def _task(i: int, text: str, path: str, base: str, params: Dict[str, Any], out: str, threads: Optional[int]) -> Dict[str, Any]:
    """One task, in a worker: the row as a dict (never raises for the run's own failure)."""
    from flem import _native, _jsonable  # imported in the worker process

    try:
        pj = json.dumps(params, default=_jsonable)
    except TypeError as e:
        return _error_row(i, params, out, f"{path}: the parameters have no TOML value: {e}")
    return json.loads(_native.run_task(i, text, path, base, pj, out, threads))


def _error_row(i: int, params: Dict[str, Any], out: str, error: str) -> Dict[str, Any]:
    row: Dict[str, Any] = {"task": i, **params}
    row.update({k: None for k in RESULT_COLUMNS})
    row.update({"splits": 0, "steps": 0, "converged": False, "wall_seconds": 0.0, "out": out, "error": error})
    return row


def sweep(
    scene: Any,
    params: Union[Mapping[str, Sequence[Any]], Iterable[Mapping[str, Any]]],
    client: Any = None,
    out: Optional[Union[str, "os.PathLike[str]"]] = None,
    threads: Optional[int] = 1,
    workers: Optional[int] = None,
    results: Optional[str] = "sweep.csv",
) -> Any:
    """Runs ``scene`` once per parameter set on a Dask cluster and returns one row per task.

    - ``params``: a grid (dict of lists: every combination, see :func:`grid`) or a list of
      dicts (e.g. ``[{"cracking.weibull.seed": s} for s in range(100)]``); keys are key paths
      as :meth:`flem.Scene.set` takes them.
    - ``client``: a ``distributed.Client`` for any cluster (``LocalCluster``, dask-jobqueue's
      ``SLURMCluster`` on an HPC machine, ...). None: a ``LocalCluster`` of ``workers`` worker
      processes (default: one per core) with one thread each, closed at the end.
    - ``out``: the sweep's folder (default: a new temporary folder, kept); task ``i`` runs in
      ``out/task_NNNN`` (on a cluster, a folder every worker can write).
    - ``threads``: ``solver.threads`` of each task (default 1: parallel over tasks).
    - ``results``: file name in ``out`` for the table: ``.csv``, or ``.parquet`` (needs pyarrow),
      or None.

    Returns a pandas DataFrame (a dict of lists without pandas) in task order: ``task``, one
    column per parameter, ``initiation_load`` (the highest load level at the first split; NaN:
    no split), ``initiation_loadname``, ``initiation_stage``, ``splits``, ``energy_residual``
    (relative to the work done), ``steps``, ``converged``, ``wall_seconds``, ``out``, ``error``
    (None, or why the task failed).
    """
    from distributed import Client, LocalCluster, as_completed

    from flem import Scene, _as_scene

    sc: Scene = _as_scene(scene)
    tasks: List[Dict[str, Any]] = grid(params) if isinstance(params, Mapping) else [dict(p) for p in params]
    if not tasks:
        raise ValueError("sweep: no parameter set given")
    folder = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="flem-sweep-"))
    folder = folder.resolve()
    folder.mkdir(parents=True, exist_ok=True)
    own = None
    if client is None:
        n = workers or os.cpu_count() or 1
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
        client = own = Client(cluster)
    try:
        t0 = time.perf_counter()
        dirs = [str(folder / f"task_{i:04d}") for i in range(len(tasks))]
        futures = client.map(_task, range(len(tasks)), [sc._text] * len(tasks), [sc._path] * len(tasks), [sc._base] * len(tasks), tasks, dirs, [threads] * len(tasks), pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        rows: List[Optional[Dict[str, Any]]] = [None] * len(tasks)
        for f in as_completed(futures):
            i = index[f.key]
            if f.status == "finished":
                rows[i] = f.result()
            else:
                # The task itself never raises for a failed run: this is the worker or Dask.
                rows[i] = _error_row(i, tasks[i], dirs[i], f"the task failed in Dask: {f.exception()!r}")
        wall = time.perf_counter() - t0
    finally:
        if own is not None:
            cluster = own.cluster
            own.close()
            cluster.close()
    table = _to_table([r for r in rows if r is not None], tasks)
    if results:
        _write(table, folder / results)
    try:
        table.attrs["wall_seconds"] = wall  # type: ignore[union-attr]
        table.attrs["out"] = str(folder)  # type: ignore[union-attr]
    except AttributeError:
        pass
    return table


def _to_table(rows: List[Dict[str, Any]], tasks: List[Dict[str, Any]]) -> Any:
    keys: List[str] = []
    for t in tasks:
        keys += [k for k in t if k not in keys]
    cols = ["task"] + keys + RESULT_COLUMNS
    data = {c: [r.get(c) for r in rows] for c in cols}
    try:
        import pandas as pd
    except ImportError:
        return data
    return pd.DataFrame(data)


def _write(table: Any, path: Path) -> None:
    """The table as CSV or Parquet (written to a temporary name, then renamed)."""
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    if path.suffix == ".parquet":
        table.to_parquet(tmp)
    elif hasattr(table, "to_csv"):
        table.to_csv(tmp, index=False)
    else:
        import csv

        with open(tmp, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(list(table))
            w.writerows(zip(*table.values()))
    os.replace(tmp, path)
