"""flem.sweep on Dask distributed and `flem sweep` (issue 22): a Weibull Monte Carlo of 16 seeds on
a 2-worker LocalCluster equals 16 serial runs; a failing task is a row with its error and the
other rows are all there; the CLI's local engine gives the same rows."""
import csv
import subprocess
from pathlib import Path

import meshio
import numpy as np
import pandas as pd

import flem

SCENE = "examples/weibull_bar.toml"
SEEDS = list(range(1, 17))


def first_split_level(scene: flem.Scene, r: flem.Result) -> float:
    """The load level of the first stage that split, from the serial run's per-stage summary and
    the scene's stage levels (derived independently of the sweep's first-split recorder)."""
    k = int(np.argmax(np.asarray(r.summary["splits"]) > 0))
    assert r.summary["splits"][k] > 0
    return scene.get(f"stage[{k}].levels.pull")


def test_16_weibull_seeds_on_2_workers_equal_16_serial_runs(root, tmp_path, dask_client):
    base = flem.Scene.from_file(root / SCENE)
    table = flem.sweep(base, {"cracking.weibull.seed": SEEDS}, client=dask_client, out=tmp_path / "sweep")
    assert list(table["task"]) == list(range(16)) and list(table["cracking.weibull.seed"]) == SEEDS
    assert table["error"].isna().all(), table["error"].tolist()
    assert (tmp_path / "sweep" / "sweep.csv").exists()
    loads = []
    for i, seed in enumerate(SEEDS):
        scene = base.copy().set("cracking.weibull.seed", seed)
        r = flem.run(scene, threads=1)
        row = table.iloc[i]
        # Tolerance: none; the same scene gives the same bits in a worker process.
        assert row["splits"] == r.info["splits"] and row["steps"] == r.info["steps"]
        assert row["energy_residual"] == r.info["energy"]["relative_residual"]
        assert row["initiation_load"] == first_split_level(scene, r)
        snap = sorted(Path(row["out"]).glob("snapshot_*.vtu"))[-1]

        m = meshio.read(snap)
        assert m.point_data["displacement"][:, :2].tobytes() == r.displacement.tobytes()
        loads.append(row["initiation_load"])
    # Weibull scatter: the seeds do not all fail at the same load.
    assert len(set(loads)) > 1


def test_a_failing_task_leaves_the_other_rows(root, tmp_path, dask_client):
    base = flem.Scene.from_file(root / SCENE)
    params = [{"cracking.weibull.seed": s} for s in SEEDS]
    params[5] = {"cracking.weibull.seed": 6, "material[0].poisson_ratio": 0.7}  # refused by validation
    table = flem.sweep(base, params, client=dask_client, out=tmp_path / "sweep", results="rows.csv")
    assert len(table) == 16
    failed = table[table["error"].notna()]
    assert list(failed["task"]) == [5]
    assert "material[0].poisson_ratio = 0.7 is incorrect" in failed["error"].iloc[0]
    ok = table[table["error"].isna()]
    assert len(ok) == 15 and (ok["splits"] > 0).all() and ok["initiation_load"].notna().all()
    written = pd.read_csv(tmp_path / "sweep" / "rows.csv")
    assert len(written) == 16 and written["error"].notna().sum() == 1


def test_cli_sweep_gives_the_same_rows(root, tmp_path, flem_bin, dask_client):
    sweep_file = tmp_path / "seeds.toml"
    sweep_file.write_text(f'scene = "{root / SCENE}"\nout = "cli"\n[grid]\n"cracking.weibull.seed" = [1, 2, 3]\n[[task]]\n"cracking.weibull.seed" = 4\n"cracking.criterion.tensile_strength" = -1.0\n')
    p = subprocess.run([str(flem_bin), "sweep", str(sweep_file), "--workers", "2"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    with open(tmp_path / "cli" / "sweep.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["task"] for r in rows] == ["0", "1", "2", "3"]
    assert rows[3]["error"] and "tensile_strength" in rows[3]["error"]
    py = flem.sweep(root / SCENE, {"cracking.weibull.seed": [1, 2, 3]}, client=dask_client, out=tmp_path / "py")
    for r, (_, q) in zip(rows[:3], py.iterrows()):
        assert float(r["initiation_load"]) == q["initiation_load"] and int(r["splits"]) == q["splits"]
        assert float(r["energy_residual"]) == q["energy_residual"] and int(r["steps"]) == q["steps"]
