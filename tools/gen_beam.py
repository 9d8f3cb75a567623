"""Meshes and scenes of Bittencourt's asymmetrically notched beam with three holes (issue 34
must-show 3, the curved benchmark; docs/paths.md, section "Bittencourt's beam with holes").

    /work/venvs/b38/bin/python tools/gen_beam.py      # gmsh 4.15.2 (python module gmsh)

Writes configs/beam/beam_{t3,quad,q4}_{1,2,3}.msh and .toml (refinement 1 coarsest).

Geometry (inches; Bittencourt, Wawrzynek, Ingraffea & Sousa 1996, Eng. Fract. Mech. 55,
321-334, as given in the public meshes cited in HEADER): the beam [0, 20] x [0, 8], thickness
0.5; pin at (1, 0), roller at (19, 0); the load, a downward displacement, on the top patch
9.9 <= x <= 10.1 (ours: a patch of 0.2 instead of the point, against the singularity); the
notch from the bottom at x = 4, 1 deep, here a slit (the experiment's is 0.1 wide): the mesh's
line x = 4, 0 <= y <= 1, pre-cut by the scene; three holes of diameter 0.5 centred at x = 6,
y = 2.75, 4.75, 6.75. Mesh kinds:
- t3: unstructured gmsh triangles, size h in the band 3 <= x <= 7.5 (where the crack runs) and
  on the load patch, 3 h elsewhere;
- quad: the same, recombined into quads by gmsh (Blossom);
- q4: block-structured quads: a tensor grid of transfinite rectangles (x lines 0, 1, 3, 4, 5.5,
  6.5, 7.5, 9.9, 10.1, 19, 20; y lines 0, 1, 2.25, 3.25, 4.25, 5.25, 6.25, 7.25, 8), cells of
  h in the band and 3 h across outside it (cells up to 3:1 there), and around each hole an
  O-grid of four transfinite patches between the 1 x 1 square and the circle.
"""
import math
import os
import sys

import gmsh

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "configs", "beam")

L, H = 20.0, 8.0
HOLES = [(6.0, 2.75), (6.0, 4.75), (6.0, 6.75)]
R = 0.25
NOTCH_X, NOTCH_A = 4.0, 1.0
PATCH = (9.9, 10.1)
BAND = (3.0, 7.5)
# Element size in the band per refinement (in).
SIZES = {1: 0.1, 2: 0.07, 3: 0.05}


def unstructured(h, quads):
    g = gmsh.model.geo
    far = 3 * h
    outer = [(0, 0), (1, 0), (NOTCH_X, 0), (19, 0), (L, 0), (L, H), (PATCH[1], H), (PATCH[0], H), (0, H)]
    tags = [g.addPoint(x, y, 0, far) for x, y in outer]
    lines = [g.addLine(tags[i], tags[(i + 1) % len(tags)]) for i in range(len(tags))]
    loops = [g.addCurveLoop(lines)]
    for cx, cy in HOLES:
        c = g.addPoint(cx, cy, 0, h)
        p = [g.addPoint(cx + R * math.cos(a), cy + R * math.sin(a), 0, h) for a in (0, math.pi / 2, math.pi, 3 * math.pi / 2)]
        arcs = [g.addCircleArc(p[i], c, p[(i + 1) % 4]) for i in range(4)]
        loops.append(g.addCurveLoop(arcs))
    s = g.addPlaneSurface(loops)
    tip = g.addPoint(NOTCH_X, NOTCH_A, 0, h)
    slit = g.addLine(tags[2], tip)
    g.synchronize()
    gmsh.model.mesh.embed(1, [slit], 2, s)
    gmsh.model.addPhysicalGroup(1, [slit], name="crack")
    gmsh.model.addPhysicalGroup(2, [s], name="beam")
    f = gmsh.model.mesh.field
    band = f.add("Box")
    for k, v in {"VIn": h, "VOut": far, "XMin": BAND[0], "XMax": BAND[1], "YMin": -1, "YMax": H + 1, "Thickness": 1.0}.items():
        f.setNumber(band, k, v)
    patch = f.add("Box")
    for k, v in {"VIn": h, "VOut": far, "XMin": PATCH[0] - 0.1, "XMax": PATCH[1] + 0.1, "YMin": H - 0.2, "YMax": H + 1, "Thickness": 0.5}.items():
        f.setNumber(patch, k, v)
    mn = f.add("Min")
    f.setNumbers(mn, "FieldsList", [band, patch])
    f.setAsBackgroundMesh(mn)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    if quads:
        gmsh.option.setNumber("Mesh.Algorithm", 8)
        gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 1)
        gmsh.option.setNumber("Mesh.RecombineAll", 1)


def structured(h):
    """Block-structured quads (module doc)."""
    g = gmsh.model.geo
    xs = [0.0, 1.0, 3.0, NOTCH_X, 5.5, 6.5, BAND[1], PATCH[0], PATCH[1], 19.0, L]
    ys = [0.0, NOTCH_A, 2.25, 3.25, 4.25, 5.25, 6.25, 7.25, H]
    fine = lambda a, b: (a >= BAND[0] - 1e-9 and b <= BAND[1] + 1e-9) or (a, b) == PATCH

    def cells(a, b):
        return max(1, round((b - a) / (h if fine(a, b) else 3 * h)))

    nx = [cells(xs[i], xs[i + 1]) for i in range(len(xs) - 1)]
    ny = [max(1, round((ys[j + 1] - ys[j]) / h)) for j in range(len(ys) - 1)]
    P, Ln = {}, {}

    def pt(x, y):
        k = (round(x, 9), round(y, 9))
        if k not in P:
            P[k] = g.addPoint(x, y, 0)
        return P[k]

    def line(a, b, n, arc_centre=None):
        key = (a, b)
        if key in Ln:
            return Ln[key][0]
        if (b, a) in Ln:
            return -Ln[(b, a)][0]
        t = g.addLine(a, b) if arc_centre is None else g.addCircleArc(a, arc_centre, b)
        Ln[key] = (t, n)
        return t

    patches = []  # (surface, corner points)
    holes = {(5.5, cy - 0.5): (cx, cy) for cx, cy in HOLES}
    crack = None
    for i in range(len(xs) - 1):
        for j in range(len(ys) - 1):
            x0, x1, y0, y1 = xs[i], xs[i + 1], ys[j], ys[j + 1]
            c = [pt(x0, y0), pt(x1, y0), pt(x1, y1), pt(x0, y1)]
            if (x0, y0) in holes:
                cx, cy = holes[(x0, y0)]
                ctr = g.addPoint(cx, cy, 0)
                d = R / math.sqrt(2)
                q = [pt(cx - d, cy - d), pt(cx + d, cy - d), pt(cx + d, cy + d), pt(cx - d, cy + d)]
                n = nx[i]
                k = max(1, round((0.5 * math.sqrt(2) - R) / h))
                for s in range(4):
                    a, b = s, (s + 1) % 4
                    ls = [line(c[a], c[b], n), line(c[b], q[b], k), line(q[b], q[a], n, ctr), line(q[a], c[a], k)]
                    surf = g.addPlaneSurface([g.addCurveLoop(ls)])
                    patches.append((surf, [c[a], c[b], q[b], q[a]]))
                continue
            ls = [line(c[0], c[1], nx[i]), line(c[1], c[2], ny[j]), line(c[2], c[3], nx[i]), line(c[3], c[0], ny[j])]
            surf = g.addPlaneSurface([g.addCurveLoop(ls)])
            patches.append((surf, c))
            if x1 == NOTCH_X and y0 == 0.0:
                crack = abs(ls[1])
    g.synchronize()
    for t, n in Ln.values():
        gmsh.model.mesh.setTransfiniteCurve(t, n + 1)
    for s, c in patches:
        gmsh.model.mesh.setTransfiniteSurface(s, "Left", c)
        gmsh.model.mesh.setRecombine(2, s)
    gmsh.model.addPhysicalGroup(1, [crack], name="crack")
    gmsh.model.addPhysicalGroup(2, [s for s, _ in patches], name="beam")


def write(kind, name, h):
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add(name)
    if kind == "q4":
        structured(h)
    else:
        unstructured(h, kind == "quad")
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.write(os.path.join(HERE, name + ".msh"))
    types, tags, _ = gmsh.model.mesh.getElements(2)
    ne = sum(len(t) for t in tags)
    gmsh.finalize()
    return ne


HEADER = """# Bittencourt's asymmetrically notched beam with three holes (issue 34 must-show 3, the curved
# benchmark; docs/paths.md, "Bittencourt's beam with holes"). Units: inches.
# Source: T. N. Bittencourt, P. A. Wawrzynek, A. R. Ingraffea, J. L. Sousa (1996), "Quasi-automatic
# simulation of crack propagation for 2D LEFM problems", Eng. Fract. Mech. 55, 321-334; the same
# specimen in Miehe, Hofacker & Welschinger (2010) and Ambati, Gerasimov & De Lorenzis (2015).
# Geometry as read in public meshes of it (search tool, code corpus): mohd-afeef-badri/psd
# data/meshes/2D/Geo-Files/asymmetric-three-point-bending.geo (beam 20 x 8, supports at x = 1 and
# 19, load at x = 10 on top, notch at x = 4 from the bottom 1 deep, holes centred at x = 6,
# y = 2.75, 4.75, 6.75; that file gives the holes' diameter as 1.0) and a Victor E. Cardoso
# Nungaray input file "Asymmetric notched three point bending test, unit 1 in" (notch 3.95-4.05
# x 0-1, the first hole's points at radius 0.25 from (6, 2.75): diameter 0.5, the value of
# Bittencourt et al. and of the brief; we use 0.5). The paper itself was not available to us.
# Beam [0, 20] x [0, 8], thickness 0.5 (plane stress); pin at (1, 0), roller at (19, 0);
# downward displacement on the top patch 9.9 <= x <= 10.1 (ours: a patch, not a point); the
# notch is a slit (ours; the experiment's is 0.1 wide) pre-cut along x = 4, 0 <= y <= 1.
# Material: homogeneous linear elastic, E = 1000, nu = 0.3, Rankine sigma_t = 1 (LEFM: the path
# depends on geometry, supports and nu only; E and the strength only scale the load).
# Events solver; separation rule `tip_mts` (ours, issue 34) with session 35's setting (every,
# piece, shrink, anchor; session 25's with shrink 1.0 and anchor; since session 34: with the
# defaults beam_q4_1's crack misses the middle hole); the same scene with
# type = "sigma1_nearest" and without those four lines is the paper's edge rule. `flem paths` measures the path from the
# notch tip to where it first meets a boundary (a hole or the outside).
# Mesh: {mesh_doc}. Written by tools/gen_beam.py.
"""


def scene(kind, i, ne, h):
    name = f"beam_{kind}_{i}"
    mesh_doc = {
        "t3": f"unstructured gmsh triangles, h = {h} in the band 3 <= x <= 7.5 and at the load patch, 3 h elsewhere ({ne} elements)",
        "quad": f"gmsh quads (recombined), h = {h} in the band 3 <= x <= 7.5 and at the load patch, 3 h elsewhere ({ne} elements)",
        "q4": f"block-structured quads (transfinite tensor grid, O-grids at the holes), h = {h} in the band 3 <= x <= 7.5, 3 h across outside it ({ne} elements)",
    }[kind]
    t = HEADER.format(mesh_doc=mesh_doc)
    t += f'title = "Bittencourt beam with holes, {kind} {i}"\n\n'
    t += f'[mesh]\ntype = "gmsh"\nfile = "{name}.msh"\n\n'
    t += '[[set]]\nname = "pin"\nnearest = [1.0, 0.0]\n\n'
    t += '[[set]]\nname = "roller"\nnearest = [19.0, 0.0]\n\n'
    t += '[[set]]\nname = "punch"\nbox = [[9.8999, 7.9999], [10.1001, 8.0001]]\n\n'
    t += '[model]\nplane = "stress"\nseparated = ["crack"]\n\n'
    t += "[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\n\n"
    t += '[solver]\ntype = "events"\nmax_events = 400\non_loose_fragment = "stop"\n\n'
    t += "[cracking]\nmax_splits_per_check = 1\n\n"
    t += '[cracking.criterion]\ntype = "rankine"\ntensile_strength = 1.0\n\n'
    t += '[cracking.separation]\ntype = "tip_mts"   # ours (issue 34)\n'
    t += "every = 1.25   # ours (session 35's setting, docs/paths.md): evaluated again after 1.25 domain radii\n"
    t += "piece = 0.05   # ours (session 19): or after 5 % of the specimen's size of straight crack\n"
    t += "shrink = 1.0   # ours: a smaller domain near the boundary, down to 1 h\n"
    t += "anchor = true  # ours (session 35): a new line starts on the previous line, at the tip's foot\n\n"
    t += '[[support]]\nnodes = "pin"\nfix = "xy"\n\n'
    t += '[[support]]\nnodes = "roller"\nfix = "y"\n\n'
    t += '[[load]]\nname = "punch"\ntype = "displacement"\nnodes = "punch"\ny = -1.0\n\n'
    t += '[[stage]]\nname = "bend"\nlevels = { punch = 1.0 }\n'
    with open(os.path.join(HERE, name + ".toml"), "w") as f:
        f.write(t)


def main():
    os.makedirs(HERE, exist_ok=True)
    only = sys.argv[1:]
    for i, h in SIZES.items():
        for kind in ("t3", "quad", "q4"):
            name = f"beam_{kind}_{i}"
            if only and name not in only:
                continue
            ne = write(kind, name, h)
            scene(kind, i, ne, h)
            print(name, ne)


if __name__ == "__main__":
    sys.exit(main())
