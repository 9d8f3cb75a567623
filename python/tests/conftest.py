"""Shared fixtures of the Python package's tests (run by `bash .ci/run` after the Rust tests)."""
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def flem_bin() -> Path:
    """The `flem` command line of this checkout (built if missing; `cargo test` builds it)."""
    exe = Path(os.environ.get("FLEM_BIN", ROOT / "target" / "release" / "flem"))
    if not exe.exists():
        subprocess.run(["cargo", "build", "--release", "--bin", "flem"], cwd=ROOT, check=True)
    return exe


@pytest.fixture(scope="session")
def dask_client():
    """One 2-worker LocalCluster (one thread per worker process) for the sweep tests."""
    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    client = Client(cluster)
    yield client
    client.close()
    cluster.close()
