"""Independent LE10 (NAFEMS R0015; docs/3d.md) with scikit-fem 12.0.2: quadratic tetrahedra (P2) on the same mapped
geometry as tests/solid3.rs (bricks split into 6 tetrahedra), sigma_yy at D from the
element-wise linear P2 stress at D averaged over the tetrahedra at D.

    /work/venvs/e38/bin/python tools/le10_skfem.py 3x6x4 6x12x8 9x18x12
    /work/venvs/e38/bin/python tools/le10_skfem.py --p1 3x6x4 6x12x8   # = FLEM's t4, the same discrete problem

(a venv with scikit-fem 12.0.2, numpy, scipy; nr x nt x nz bricks as in tests/solid3.rs)."""
import sys, time
import numpy as np
from skfem import MeshTet, Basis, FacetBasis, ElementVector, ElementTetP2, ElementTetDG, ElementTetP1, BilinearForm, LinearForm, asm, condense, solve
from skfem.models.elasticity import linear_elasticity, lame_parameters
from skfem.helpers import dot

def mesh(nr, nt, nz):
    pts = []
    for k in range(nz + 1):
        for j in range(nt + 1):
            for i in range(nr + 1):
                q = (i / nr, j / nt, k / nz)
                th = np.pi / 2 * q[1]
                c, s = np.cos(th), np.sin(th)
                xi, yi, xo, yo = 2 * c, s, 3.25 * c, 2.75 * s
                pts.append((xi + q[0] * (xo - xi), yi + q[0] * (yo - yi), 0.6 * q[2]))
    pts = np.array(pts)
    idx = lambda i, j, k: i + (nr + 1) * (j + (nt + 1) * k)
    tets = []
    for k in range(nz):
        for j in range(nt):
            for i in range(nr):
                h = [idx(i, j, k), idx(i + 1, j, k), idx(i + 1, j + 1, k), idx(i, j + 1, k), idx(i, j, k + 1), idx(i + 1, j, k + 1), idx(i + 1, j + 1, k + 1), idx(i, j + 1, k + 1)]
                for a, b in [(1, 2), (1, 5), (3, 2), (3, 7), (4, 5), (4, 7)]:
                    t = [h[0], h[a], h[b], h[6]]
                    x = pts[t]
                    if np.linalg.det(np.array([x[1] - x[0], x[2] - x[0], x[3] - x[0]])) < 0:
                        t[1], t[2] = t[2], t[1]
                    tets.append(t)
    return MeshTet(pts.T, np.array(tets).T), idx(0, 0, nz)

def run(nr, nt, nz, p1=False):
    t0 = time.time()
    m, d = mesh(nr, nt, nz)
    e = ElementVector(ElementTetP1() if p1 else ElementTetP2())
    ib = Basis(m, e, intorder=4)
    lam, mu = lame_parameters(210e3, 0.3)
    K = asm(linear_elasticity(lam, mu), ib)
    top = m.facets_satisfying(lambda x: np.isclose(x[2], 0.6))
    fb = FacetBasis(m, e, facets=top, intorder=4)
    @LinearForm
    def load(v, w):
        return -1.0 * dot(w.n, v)
    f = asm(load, fb)
    # Dof locations and components: nodal dofs at points, edge dofs at edge midpoints.
    P = m.p
    em = 0.5 * (P[:, m.edges[0]] + P[:, m.edges[1]])
    fixed = []
    for dofs, (x, y, z) in [(ib.nodal_dofs, P)] + ([] if p1 else [(ib.edge_dofs, em)]):
        fixed += list(dofs[1][np.isclose(y, 0.0)])  # DCD'C': u_y = 0
        fixed += list(dofs[0][np.isclose(x, 0.0)])  # ABA'B': u_x = 0
    # BCB'C' (the outer face, radial parameter 1): u_x = u_y = 0; its mid-plane line: u_z = 0.
    on_outer_pt = np.arange(m.p.shape[1]) % (nr + 1) == nr
    outer_edges = on_outer_pt[m.edges[0]] & on_outer_pt[m.edges[1]]
    fixed += list(ib.nodal_dofs[0][on_outer_pt]) + list(ib.nodal_dofs[1][on_outer_pt])
    if not p1:
        fixed += list(ib.edge_dofs[0][outer_edges]) + list(ib.edge_dofs[1][outer_edges])
    mid_pt = on_outer_pt & np.isclose(m.p[2], 0.3)
    mid_edges = outer_edges & np.isclose(em[2], 0.3)
    fixed += list(ib.nodal_dofs[2][mid_pt]) + ([] if p1 else list(ib.edge_dofs[2][mid_edges]))
    fixed = np.unique(np.array(fixed, dtype=np.int64))
    u = solve(*condense(K, f, D=fixed))
    # Stress: element-wise linear for P2; projected onto discontinuous P1 (exact).
    uh = ib.interpolate(u)
    g = uh.grad  # (3, 3, nel, nqp)
    eps = 0.5 * (g + np.transpose(g, (1, 0, 2, 3)))
    tr = eps[0, 0] + eps[1, 1] + eps[2, 2]
    syy = lam * tr + 2 * mu * eps[1, 1]
    db = Basis(m, ElementTetDG(ElementTetP1()), intorder=4)
    s = db.project(syy)
    els = np.where((m.t == d).any(axis=0))[0]
    vals = [s[db.element_dofs[list(m.t[:, e_]).index(d), e_]] for e_ in els]
    print(f"skfem {'P1' if p1 else 'P2'} tets {nr}x{nt}x{nz}: {K.shape[0]} dofs, sigma_yy(D) = {np.mean(vals):.8f} (tets at D: {len(vals)}, spread {min(vals):.4f}..{max(vals):.4f}), {time.time() - t0:.1f} s", flush=True)

p1 = "--p1" in sys.argv
for a in sys.argv[1:]:
    if a != "--p1":
        run(*map(int, a.split("x")), p1=p1)
