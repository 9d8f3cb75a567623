"""flem.run of a 3D scene (issue 38, docs/python.md "3D runs"): the arrays' shapes, a uniaxial
bar's stress and stretch against the analytic solution, and the arrays equal to the run's last
VTU snapshot read by meshio (the independent reader)."""
from pathlib import Path

import meshio
import numpy as np

import flem

BAR = """
title = "uniaxial bar, 3D"
[model]
dim = 3
[mesh]
type = "box"
size = [4.0, 1.0, 1.0]
nx = 4
ny = 2
nz = 2
element = "h8"
[[material]]
young_modulus = 1000.0
poisson_ratio = 0.25
density = 1.0
element = "h8"
[solver]
tolerance = 1e-12
max_steps = 200000
[[support]]
nodes = "xmin"
fix = "x"
[[support]]
nodes = "ymin"
fix = "y"
[[support]]
nodes = "zmin"
fix = "z"
[[load]]
name = "pull"
type = "pressure"
faces = "xmax"
value = -2.0
[[stage]]
levels = { pull = 1.0 }
"""


def test_uniaxial_bar_3d_arrays(tmp_path: Path):
    # Reference: a bar on rollers at x, y, z = 0 pulled by a traction 2 on x = 4: the uniform
    # stress sxx = 2, all else 0; u_x = sxx x / E, u_y = -nu sxx y / E, u_z = -nu sxx z / E
    # (E = 1000, nu = 0.25). Tolerance 1e-6 relative (the march stops at an unbalanced-force
    # ratio of 1e-12).
    r = flem.run(flem.Scene.from_toml(BAR), out=tmp_path / "bar")
    n = len(r.points)
    assert r.dim == 3
    assert r.points.shape == (n, 3) and r.displacement.shape == (n, 3) and r.velocity.shape == (n, 3)
    assert r.nodal_stress.shape == (n, 6) and r.mass.shape == (n,)
    assert r.cells["hexahedron"].shape == (16, 8) and r.elem_stress.shape == (16, 6)
    assert r.crack_faces.shape == (0, 2)
    assert n == 5 * 3 * 3
    want = np.array([2.0, 0, 0, 0, 0, 0])
    assert np.abs(r.nodal_stress - want).max() <= 1e-6 * 2.0
    assert np.abs(r.elem_stress - want).max() <= 1e-6 * 2.0
    x = r.points
    u = np.c_[2.0 * x[:, 0] / 1000.0, -0.25 * 2.0 * x[:, 1] / 1000.0, -0.25 * 2.0 * x[:, 2] / 1000.0]
    assert np.abs(r.displacement - u).max() <= 1e-6 * np.abs(u).max()
    # The same state as the run's VTU (meshio): points and displacement bit for bit.
    snap = sorted((tmp_path / "bar").glob("snapshot_*.vtu"))[-1]
    m = meshio.read(snap)
    assert np.array_equal(m.points, r.points)
    assert np.array_equal(m.point_data["displacement"], r.displacement)
    assert np.array_equal(m.cells_dict["hexahedron"], r.cells["hexahedron"])


def test_3d_run_resumes_and_compares(tmp_path: Path):
    # A 3D run with [check] in two stages, then flem.run(..., resume=out): the run continues from
    # its last checkpoint (written after the last stage) and returns the same arrays bit for
    # bit, and the implicit check's rows (reference: the implicit solve; tolerance 1e-6, both
    # stages at rest at a ratio of 1e-12).
    text = BAR.replace("[[stage]]\nlevels = { pull = 1.0 }", "[check]\n[[stage]]\nlevels = { pull = 1.0 }\n[[stage]]\nlevels = { pull = 2.0 }")
    out = tmp_path / "bar"
    a = flem.run(flem.Scene.from_toml(text), out=out)
    assert len(sorted(out.glob("checkpoint_*.bin"))) >= 1
    b = flem.run(flem.Scene.from_toml(text), out=out, resume=out)
    for k in ("points", "displacement", "velocity", "nodal_stress", "elem_stress"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    for r in (a, b):
        rows = r.compare
        assert len(rows) == 2
        assert all(x["comparable"] and x["within_tolerance"] and x["rel_l2_displacement"] <= 1e-6 for x in rows)
