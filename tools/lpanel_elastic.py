"""Independent elastic stiffness of Winkler's L-panel (docs/paths.md, "Winkler's L-panel"):
plane-stress linear triangles (T3) or bilinear quads (Q4, 2 x 2 Gauss) assembled here with
numpy/scipy, not with FLEM, on a configs/lpanel mesh; bottom (y = 0) fixed, u_y = 1 mm on the
points y = 250 mm, 470 <= x <= 500 mm (u_x free there). Prints the force (kN on t = 100 mm)
per mm.

    /work/venvs/peers/bin/python tools/lpanel_elastic.py configs/lpanel/lpanel_t3_3.msh [...]
"""
import sys

import meshio
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl

E, NU, T = 25.85e9, 0.18, 0.1
D = E / (1 - NU**2) * np.array([[1, NU, 0], [NU, 1, 0], [0, 0, (1 - NU) / 2]])


def ke_quad(x):
    k = np.zeros((8, 8))
    g = 1 / np.sqrt(3)
    for xi, eta in [(-g, -g), (g, -g), (g, g), (-g, g)]:
        dn = 0.25 * np.array([[-(1 - eta), (1 - eta), (1 + eta), -(1 + eta)], [-(1 - xi), -(1 + xi), (1 + xi), (1 - xi)]])
        J = dn @ x
        dx = np.linalg.solve(J, dn)
        B = np.zeros((3, 8))
        B[0, 0::2], B[1, 1::2], B[2, 0::2], B[2, 1::2] = dx[0], dx[1], dx[1], dx[0]
        k += B.T @ D @ B * np.linalg.det(J)
    return k


def ke_tri(x):
    a = 0.5 * ((x[1, 0] - x[0, 0]) * (x[2, 1] - x[0, 1]) - (x[2, 0] - x[0, 0]) * (x[1, 1] - x[0, 1]))
    b = np.array([x[1, 1] - x[2, 1], x[2, 1] - x[0, 1], x[0, 1] - x[1, 1]]) / (2 * a)
    c = np.array([x[2, 0] - x[1, 0], x[0, 0] - x[2, 0], x[1, 0] - x[0, 0]]) / (2 * a)
    B = np.zeros((3, 6))
    B[0, 0::2], B[1, 1::2], B[2, 0::2], B[2, 1::2] = b, c, c, b
    return B.T @ D @ B * abs(a)


def stiffness(path):
    m = meshio.read(path)
    P = m.points[:, :2]
    n = len(P)
    rows, cols, vals = [], [], []
    for blk in m.cells:
        if blk.type not in ("triangle", "quad"):
            continue
        for c in blk.data:
            x = P[c]
            if blk.type == "quad":
                k = ke_quad(x)
            else:
                k = ke_tri(x)
            dof = np.ravel([[2 * i, 2 * i + 1] for i in c])
            rows.append(np.repeat(dof, len(dof)))
            cols.append(np.tile(dof, len(dof)))
            vals.append(k.ravel())
    K = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(2 * n, 2 * n))
    used = np.unique(np.concatenate([b.data.ravel() for b in m.cells if b.type in ("triangle", "quad")]))
    fixed = np.zeros(2 * n, bool)
    u = np.zeros(2 * n)
    bottom = used[np.abs(P[used, 1]) < 1e-9]
    fixed[2 * bottom], fixed[2 * bottom + 1] = True, True
    lift = used[(np.abs(P[used, 1] - 0.25) < 1e-9) & (P[used, 0] >= 0.47 - 1e-9)]
    fixed[2 * lift + 1] = True
    u[2 * lift + 1] = 1e-3
    unused = np.setdiff1d(np.arange(n), used)
    fixed[2 * unused], fixed[2 * unused + 1] = True, True
    free = ~fixed
    u[free] = spl.spsolve(K[free][:, free].tocsc(), -K[free][:, fixed] @ u[fixed])
    f = K @ u
    return f[2 * lift + 1].sum() * T / 1e3, len(lift)


for p in sys.argv[1:]:
    F, nl = stiffness(p)
    print(f"{p}: {F:.2f} kN/mm ({nl} loaded points)")
