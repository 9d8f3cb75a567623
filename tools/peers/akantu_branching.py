#!/usr/bin/env python3
"""Akantu (extrinsic cohesive insertion) on FLEM's dynamic branching plate (issue 36, must-show 4).

Usage (from the repository root, with the peers' venv: VENV=/work/venvs/peers bash
../shared/peers/setup.sh):
    $VENV/bin/python tools/peers/akantu_branching.py configs/dynamic/branching_h0.5.msh \
        [--sigma-c 3e6] [--G-c 3] [--factor 0.5] [--t-end 80e-6] [--out out/akantu_b05.json]

The plate of configs/dynamic/branching_h0.5.toml (Borden et al. 2012, sec. 6.1): 0.1 x 0.04 m,
notch (0, 0.02)-(0.05, 0.02), E = 32 GPa, nu = 0.2, rho = 2450 kg/m^3, G_c = 3 J/m^2, plane
strain, traction 1 MPa on "top" (+y) and "bottom" (-y) from t = 0, 80 us, no support.
The mesh is FLEM's gmsh file, the same triangles; the notch (physical curve "notch", which FLEM
pre-cuts with [model] separated) is cut here by doubling its nodes (all but the notch tip) for
the triangles above it, and the mesh is written as msh 2.2 for Akantu. Bulk "elastic", facets
"cohesive_linear" (linear softening, delta_c = 2 G_c / sigma_c, beta = 1: Camacho-Ortiz
effective stress) inserted where the facet stress reaches sigma_c (checkCohesiveStress()
before every solveStep()); explicit central difference, lumped mass, dt = factor x Akantu's
stable step of the bulk. Tractions by a Python NeumannFunctor (the wheel's FromTraction
segfaults with numpy 2, see ../shared/peers/setup.sh).

Prints one JSON object (last line): inserted facets, their length, the dissipated energy
(Akantu's "dissipated") over G_c x that length, the crack extent, the branch point by
tools/peers/crack_metrics.py (the same function is applied to FLEM's split points), the wall
time of the loop. The facet midpoints go to --out (JSON).
"""
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import meshio  # noqa: E402
import numpy as np  # noqa: E402
import akantu as aka  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from crack_metrics import branch_point  # noqa: E402

MATERIAL = """model solid_mechanics_model_cohesive [
  cohesive_inserter [
    bounding_box = [[-1, 1], [-1, 1]]
  ]
  material elastic [
    name = bulk
    rho = {rho}
    E = {E}
    nu = {nu}
    Plane_Stress = false
  ]
  material cohesive_linear [
    name = cohesive
    sigma_c = {sigma_c}
    G_c = {G_c}
    beta = {beta}
    penalty = {penalty}
  ]
]
"""


class UniformTraction(aka.NeumannFunctor):
    """Constant traction on a boundary group (as ../shared/peers/akantu_explicit_throughput.py)."""

    def __init__(self, traction):
        super().__init__()
        self.t = [float(x) for x in traction]

    def __call__(self, quad_point, dual, coord, normals):
        dual[0] = self.t[0]
        dual[1] = self.t[1]


def cut_notch(src, dst, y0=0.02, x_tip=0.05):
    """FLEM's mesh with the notch cut: its nodes (not the tip) doubled for the triangles above."""
    m = meshio.read(src)
    pts = m.points[:, :2].copy()
    tri = m.cells_dict["triangle"].copy()
    lines = {}
    for cb, tags in zip(m.cells, m.cell_data["gmsh:physical"]):
        if cb.type == "line":
            for c, t in zip(cb.data, tags):
                lines.setdefault(int(t), []).append(c)
    names = {int(v[0]): k for k, v in m.field_data.items()}
    notch_tag = [t for t, n in names.items() if n == "notch"][0]
    notch_nodes = sorted({int(i) for c in lines[notch_tag] for i in c})
    notch_nodes = [i for i in notch_nodes if pts[i, 0] < x_tip - 1e-12]
    new_id = {}
    for i in notch_nodes:
        new_id[i] = len(pts) + len(new_id)
    pts = np.vstack([pts, pts[notch_nodes]])
    cy = pts[tri].mean(axis=1)[:, 1]
    for k in np.where(cy > y0)[0]:
        tri[k] = [new_id.get(int(i), int(i)) for i in tri[k]]
    cells, phys, geo = [], [], []
    for t, n in names.items():
        if n in ("top", "bottom", "right", "left_up", "left_low"):
            cells.append(("line", np.array(lines[t])))
            phys.append(np.full(len(lines[t]), t))
            geo.append(np.full(len(lines[t]), t))
    plate = [t for t, n in names.items() if n == "plate"][0]
    cells.append(("triangle", tri))
    phys.append(np.full(len(tri), plate))
    geo.append(np.full(len(tri), plate))
    out = meshio.Mesh(np.c_[pts, np.zeros(len(pts))], cells,
                      cell_data={"gmsh:physical": phys, "gmsh:geometrical": geo},
                      field_data={n: np.array([t, 2 if n == "plate" else 1]) for t, n in names.items() if n != "notch"})
    meshio.write(dst, out, file_format="gmsh22", binary=False)
    return len(tri), len(notch_nodes)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mesh")
    ap.add_argument("--E", type=float, default=32e9)
    ap.add_argument("--nu", type=float, default=0.2)
    ap.add_argument("--rho", type=float, default=2450.0)
    ap.add_argument("--sigma-c", type=float, default=3e6)
    ap.add_argument("--G-c", type=float, default=3.0)
    ap.add_argument("--beta", type=float, default=1.0)
    ap.add_argument("--penalty", type=float, default=1e14, help="compression penalty (Pa/m)")
    ap.add_argument("--traction", type=float, default=1e6)
    ap.add_argument("--t-end", type=float, default=80e-6)
    ap.add_argument("--factor", type=float, default=0.5, help="dt / Akantu's stable dt")
    ap.add_argument("--out", default=os.path.join(os.getcwd(), "out", "akantu_branching.json"))
    args = ap.parse_args()

    tmpd = tempfile.mkdtemp()
    msh = os.path.join(tmpd, "plate_cut.msh")
    nel, ndup = cut_notch(args.mesh, msh)
    mat = os.path.join(tmpd, "material.dat")
    with open(mat, "w") as fh:
        fh.write(MATERIAL.format(rho=args.rho, E=args.E, nu=args.nu, sigma_c=args.sigma_c,
                                 G_c=args.G_c, beta=args.beta, penalty=args.penalty))
    aka.parseInput(mat)
    t0 = time.perf_counter()
    mesh = aka.Mesh(2)
    mesh.read(msh)
    model = aka.SolidMechanicsModelCohesive(mesh)
    model.initFull(_analysis_method=aka._explicit_lumped_mass, _is_extrinsic=True)
    model.applyBC(UniformTraction([0.0, args.traction]), "top")
    model.applyBC(UniformTraction([0.0, -args.traction]), "bottom")
    dt_stable = model.getStableTimeStep()
    dt = args.factor * dt_stable
    model.setTimeStep(dt)
    t_setup = time.perf_counter() - t0
    steps = int(np.ceil(args.t_end / dt))
    facets, hist = [], []
    ncoh = 0
    w0 = time.perf_counter()
    for s in range(steps):
        nins = model.checkCohesiveStress()
        model.solveStep()
        if nins:
            conn = mesh.getConnectivity(aka._cohesive_2d_4)
            X = mesh.getNodes()
            for k in range(ncoh, conn.shape[0]):
                a, b = X[conn[k, 0]], X[conn[k, 1]]
                facets.append(dict(x=float(0.5 * (a[0] + b[0])), y=float(0.5 * (a[1] + b[1])),
                                   length=float(np.hypot(*(b - a))), t=(s + 1) * dt))
            ncoh = conn.shape[0]
        if s % 200 == 0 or s == steps - 1:
            hist.append(dict(step=s, t=(s + 1) * dt, n_cohesive=ncoh,
                             E_kin=float(model.getEnergy("kinetic")),
                             E_pot=float(model.getEnergy("potential")),
                             E_diss=float(model.getEnergy("dissipated"))))
    wall = time.perf_counter() - w0
    E_diss = float(model.getEnergy("dissipated"))
    length = sum(f["length"] for f in facets)
    xs = np.array([f["x"] for f in facets]) if facets else np.zeros(0)
    ys = np.array([f["y"] for f in facets]) if facets else np.zeros(0)
    summary = dict(
        script="tools/peers/akantu_branching.py", akantu=aka.__version__, mesh=args.mesh,
        n_bulk_elements=int(nel), notch_nodes_doubled=int(ndup),
        params=dict(E=args.E, nu=args.nu, rho=args.rho, sigma_c=args.sigma_c, G_c=args.G_c,
                    beta=args.beta, penalty=args.penalty, traction=args.traction, t_end=args.t_end,
                    factor=args.factor, delta_c=2 * args.G_c / args.sigma_c, plane="strain"),
        dt_stable=dt_stable, dt=dt, steps=steps, n_cohesive=int(ncoh), facet_length=length,
        E_dissipated=E_diss, E_diss_over_Gc_length=E_diss / (args.G_c * length) if length else None,
        E_diss_over_Gc=E_diss / args.G_c,
        crack_extent=dict(x_min=float(xs.min()), x_max=float(xs.max()), y_min=float(ys.min()),
                          y_max=float(ys.max())) if facets else None,
        branch_point=branch_point(list(zip(xs, ys))),
        timing=dict(setup_s=round(t_setup, 3), loop_s=round(wall, 3), ms_per_step=round(1e3 * wall / steps, 4)),
        out=args.out)
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w") as fh:
        json.dump(dict(summary=summary, facets=facets, history=hist), fh)
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
