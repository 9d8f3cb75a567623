"""Writes the mapped quad meshes of the plastic-flow verification scenes (issue 21) as gmsh
msh 2.2 ASCII files, with plain Python (no gmsh needed: the meshes are structured):

- slope.msh, slope_fine.msh: the 2:1 slope of slope.toml (height 10, crest 15 m wide behind
  the crest edge, base at toe level): the trapezoid (0,0) (35,0) (15,10) (0,10), mapped with
  columns that run from the base to the crest/face. Curves: left, bottom, crest, face; surface soil.
- cavity.msh: the quarter annulus a = 1 <= r <= b = 10 of cavity.toml, 40 rings of 0.05 from
  r = 1 to 3, then 16 rings growing geometrically to 10; 24 sectors. Curves: hole, outer,
  xaxis (y = 0), yaxis (x = 0); surface ground.
Run: python3 configs/verification/gen_meshes.py
"""
import math
import os

here = os.path.dirname(os.path.abspath(__file__))


def write(name, nodes, quads, curves, surface):
    """nodes: list of (x, y); quads: counter-clockwise node index quadruples; curves: name ->
    list of (i, j) node pairs."""
    names = list(curves) + [surface]
    lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", str(len(names))]
    for k, n in enumerate(curves):
        lines.append(f'1 {k + 1} "{n}"')
    lines.append(f'2 {len(names)} "{surface}"')
    lines += ["$EndPhysicalNames", "$Nodes", str(len(nodes))]
    lines += [f"{i + 1} {x:.15g} {y:.15g} 0" for i, (x, y) in enumerate(nodes)]
    lines += ["$EndNodes", "$Elements"]
    els = []
    for k, n in enumerate(curves):
        for a, b in curves[n]:
            els.append(f"1 2 {k + 1} {k + 1} {a + 1} {b + 1}")
    for q in quads:
        els.append(f"3 2 {len(names)} {len(names)} " + " ".join(str(v + 1) for v in q))
    lines.append(str(len(els)))
    lines += [f"{i + 1} {e}" for i, e in enumerate(els)]
    lines.append("$EndElements")
    with open(os.path.join(here, name), "w") as f:
        f.write("\n".join(lines) + "\n")
    print(name, len(nodes), "nodes", len(quads), "quads")


def grid(nx, ny, xy):
    """A mapped nx x ny grid: xy(i, j) gives node (i, j); returns nodes, quads, id."""
    nid = lambda i, j: j * (nx + 1) + i
    nodes = [xy(i, j) for j in range(ny + 1) for i in range(nx + 1)]
    quads = [(nid(i, j), nid(i + 1, j), nid(i + 1, j + 1), nid(i, j + 1)) for j in range(ny) for i in range(nx)]
    return nodes, quads, nid


def slope(name, nx, ny):
    h, crest, toe = 10.0, 15.0, 35.0
    def xy(i, j):
        y = h * j / ny
        right = toe - (toe - crest) * y / h
        return (right * i / nx, y)
    nodes, quads, nid = grid(nx, ny, xy)
    curves = {
        "left": [(nid(0, j), nid(0, j + 1)) for j in range(ny)],
        "bottom": [(nid(i, 0), nid(i + 1, 0)) for i in range(nx)],
        # The top row: crest (x <= 15) and the face from the crest edge down to the toe are
        # the right column and the top row; the face is the right column (i = nx).
        "face": [(nid(nx, j), nid(nx, j + 1)) for j in range(ny)],
        "crest": [(nid(i, ny), nid(i + 1, ny)) for i in range(nx)],
    }
    write(name, nodes, quads, curves, "soil")


def cavity(name, nth):
    a, b = 1.0, 10.0
    radii = [a + 0.05 * k for k in range(41)]
    n_out = 16
    # Geometric growth from 3 to b whose first ring is about 0.06.
    q = 1.0
    lo, hi = 1.0, 2.0
    for _ in range(200):
        q = 0.5 * (lo + hi)
        s = 0.06 * (q ** n_out - 1) / (q - 1)
        lo, hi = (q, hi) if s < b - 3.0 else (lo, q)
    r, d = 3.0, 0.06
    for _ in range(n_out):
        r += d
        d *= q
        radii.append(r)
    radii[-1] = b
    nr = len(radii) - 1
    def xy(i, j):
        t = 0.5 * math.pi * j / nth
        return (radii[i] * math.cos(t), radii[i] * math.sin(t))
    nodes, quads, nid = grid(nr, nth, xy)
    nodes[nid(0, nth)] = (0.0, a)
    nodes[nid(nr, nth)] = (0.0, b)
    for i in range(nr + 1):
        nodes[nid(i, nth)] = (0.0, radii[i])
    curves = {
        "hole": [(nid(0, j + 1), nid(0, j)) for j in range(nth)],
        "outer": [(nid(nr, j), nid(nr, j + 1)) for j in range(nth)],
        "xaxis": [(nid(i, 0), nid(i + 1, 0)) for i in range(nr)],
        "yaxis": [(nid(i, nth), nid(i + 1, nth)) for i in range(nr)],
    }
    write(name, nodes, quads, curves, "ground")


slope("slope.msh", 30, 10)
slope("slope_fine.msh", 60, 20)
cavity("cavity.msh", 24)
