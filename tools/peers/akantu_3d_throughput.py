#!/usr/bin/env python3
"""Akantu's 3D explicit step on FLEM's tetrahedral box meshes (issue 38, must-show 6).

Usage (the meshes first, from FLEM's own box generator, so that both codes step the same
mesh):
    flem bench step3 --sizes 100000,1000000 --write-msh out/peers3d
    $VENV/bin/python tools/peers/akantu_3d_throughput.py --meshdir out/peers3d \
        [--sizes 100000,1000000] [--steps 200] [--factor 0.8]

VENV: the peers' environment (bash ../shared/peers/setup.sh; Akantu 5.0.7.post1 wheel).
For every box_t4_<n>_v22.msh (a unit cube of 6 k^3 linear tetrahedra, gmsh 2.2, physical
surfaces "xmin", "xmax", physical volume "body"): E = 100, nu = 0.3, rho = 1 (as `flem bench
step3`), "xmin" held in x, y and z, a constant traction (1, 0, 0) on "xmax". Akantu's
SolidMechanicsModel with _explicit_lumped_mass (central difference) runs --steps steps at
--factor x getStableTimeStep(). Only the solveStep() loop is timed (mesh reading, model and
material set-up, mass assembly and boundary conditions are not). The numeric libraries are
held to one thread (OMP/OPENBLAS/MKL_NUM_THREADS=1); Akantu's wheel is serial (the JSON says
whether its library links OpenMP or MPI). The last stdout line is one JSON object: per mesh the
elements, nodes, dt, wall and CPU time of the loop, ns per element-update (wall; and the best
and the median of blocks of 50 steps, robust to a shared machine's load), the load average.
This is the 3D twin of ../shared/peers/akantu_explicit_throughput.py (2D).
"""
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import akantu as aka  # noqa: E402

MATERIAL = """material elastic [
  name = body
  rho = {rho}
  E = {E}
  nu = {nu}
]
"""


class UniformTraction(aka.NeumannFunctor):
    """Constant traction on a boundary group (a Python functor: Akantu 5.0.7.post1's
    aka.FromTraction crashes with numpy >= 2, see the 2D script)."""

    def __init__(self, traction):
        super().__init__()
        self.t = [float(x) for x in traction]

    def __call__(self, quad_point, dual, coord, normals):
        dual[0] = self.t[0]
        dual[1] = self.t[1]
        dual[2] = self.t[2]


def run_one(path, steps, factor, block=50):
    t0 = time.perf_counter()
    mesh = aka.Mesh(3)
    mesh.read(path)
    model = aka.SolidMechanicsModel(mesh)
    model.initFull(_analysis_method=aka._explicit_lumped_mass)
    for d in (aka._x, aka._y, aka._z):
        model.applyBC(aka.FixedValue(0.0, d), "xmin")
    model.getExternalForce()[:] = 0
    model.applyBC(UniformTraction((1.0, 0.0, 0.0)), "xmax")
    dt_stable = model.getStableTimeStep()
    dt = factor * dt_stable
    model.setTimeStep(dt)
    t_setup = time.perf_counter() - t0
    etype = aka._tetrahedron_4
    nel = mesh.getNbElement(type=etype)
    nqp = model.getFEEngine().getNbIntegrationPoints(etype)
    c0, w0 = time.process_time(), time.perf_counter()
    rates, tb = [], w0
    for s in range(steps):
        model.solveStep()
        if (s + 1) % block == 0:
            tn = time.perf_counter()
            rates.append((tn - tb) / (nel * block) * 1e9)
            tb = tn
    wall = time.perf_counter() - w0
    cpu = time.process_time() - c0
    u = model.getDisplacement()
    X = mesh.getNodes()
    right = np.isclose(X[:, 0], 1.0)
    return dict(mesh=os.path.basename(path), element_type="_tetrahedron_4", quadrature_points_per_element=int(nqp),
                n_elements=int(nel), n_nodes=int(mesh.getNbNodes()), steps=steps, dt_stable=dt_stable, dt=dt,
                factor=factor, t_setup_s=round(t_setup, 3), wall_loop_s=round(wall, 4), cpu_loop_s=round(cpu, 4),
                cpu_over_wall=round(cpu / wall, 3) if wall > 0 else None,
                ns_per_element_update=1e9 * wall / (nel * steps),
                cpu_ns_per_element_update=1e9 * cpu / (nel * steps),
                best_block_ns_per_element_update=min(rates) if rates else None,
                median_block_ns_per_element_update=float(np.median(rates)) if rates else None,
                block_steps=block, ux_xmax_mean_end=float(u[right, 0].mean()),
                loadavg_after=os.getloadavg())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="100000,1000000")
    ap.add_argument("--meshdir", default="out/peers3d")
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--factor", type=float, default=0.8)
    ap.add_argument("--E", type=float, default=100.0)
    ap.add_argument("--nu", type=float, default=0.3)
    ap.add_argument("--rho", type=float, default=1.0)
    args = ap.parse_args()
    tmp = tempfile.NamedTemporaryFile("w", suffix=".dat", delete=False)
    tmp.write(MATERIAL.format(rho=args.rho, E=args.E, nu=args.nu))
    tmp.close()
    aka.parseInput(tmp.name)
    runs, missing = [], []
    t0 = time.perf_counter()
    for n in [int(x) for x in args.sizes.split(",")]:
        path = os.path.join(args.meshdir, f"box_t4_{n}_v22.msh")
        if not os.path.exists(path):
            missing.append(path)
            continue
        r = run_one(path, args.steps, args.factor)
        runs.append(r)
        print(f"{r['mesh']}: {r['n_elements']} el, {r['ns_per_element_update']:.1f} ns/el-update "
              f"(median block {r['median_block_ns_per_element_update']:.1f}, best {r['best_block_ns_per_element_update']:.1f}), "
              f"cpu/wall {r['cpu_over_wall']}", file=sys.stderr, flush=True)
    os.unlink(tmp.name)
    try:
        import subprocess
        libdir = os.path.join(os.path.dirname(aka.__file__), "..", "akantu.libs")
        lib = [f for f in os.listdir(libdir) if f.startswith("libakantu")]
        ldd = subprocess.run(["ldd", os.path.join(libdir, lib[0])], capture_output=True, text=True).stdout
        openmp, mpi = any(k in ldd for k in ("gomp", "libomp", "iomp")), "mpi" in ldd
    except Exception:  # pragma: no cover
        openmp = mpi = None
    print(json.dumps(dict(script="akantu_3d_throughput", akantu=aka.__version__,
                          scheme="central difference, lumped mass (_explicit_lumped_mass)",
                          material=dict(E=args.E, nu=args.nu, rho=args.rho), steps=args.steps, factor=args.factor,
                          akantu_linked_openmp=openmp, akantu_linked_mpi=mpi,
                          env={k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")},
                          cpu_count=os.cpu_count(), loadavg_at_end=os.getloadavg(),
                          max_rss_MB=round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
                          missing_meshes=missing, wall_total_s=round(time.perf_counter() - t0, 2), runs=runs)))


if __name__ == "__main__":
    main()
