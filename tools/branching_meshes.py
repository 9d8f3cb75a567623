#!/usr/bin/env python3
"""Meshes for the symmetry study of the branching plate (issue 36, docs/dynamic.md "Session 32"):

    python3 tools/branching_meshes.py mirror SRC.msh DST.msh 0.04
        a gmsh 4.1 ASCII mesh mirrored about y = 0.04 / 2 for FLEM's reader (standard library
        only): y -> 0.04 - y, each triangle's (quadrangle's) corners after the first reversed
        (counter-clockwise kept), the physical names "top" and "bottom" swapped so that the scene's
        loads act on the mirrored edges; $Entities and the other names copied as they are.
        tests/dynamic.rs does the same in Rust (`mirrored_msh`).
    PYTHON tools/branching_meshes.py symmetric 0.0005 OUT.msh   (PYTHON: one with gmsh)
        the plate meshed on its lower half and copied onto the upper one by gmsh's periodic
        constraint with the mirror transform (gmsh 4.15.2 Python API, e.g. the peers' venv):
        a mesh symmetric about y = 0.02, with a line of edges along it. Same size field and
        physical groups as configs/dynamic/branching.geo; FLEM reorients the mirrored triangles
        (a warning per element).
"""
import sys


def mirror(src, dst, height):
    lines = open(src).read().split("\n")
    out, i = [], 0
    swap = lambda s: s.replace('"bottom"', '"@"').replace('"top"', '"bottom"').replace('"@"', '"top"')
    while i < len(lines):
        l = lines[i]
        out.append(swap(l))
        i += 1
        if l not in ("$Nodes", "$Elements"):
            continue
        blocks = int(lines[i].split()[0])
        out.append(lines[i])
        i += 1
        for _ in range(blocks):
            head = lines[i].split()
            ty, n = int(head[2]), int(head[3])
            if l == "$Nodes" and ty != 0:
                sys.exit(f"{src}: a node block with parametric coordinates: {lines[i]}")
            out.append(lines[i])
            i += 1
            if l == "$Nodes":
                out.extend(lines[i:i + n])
                i += n
                for c in lines[i:i + n]:
                    x, y, z = (float(t) for t in c.split())
                    out.append(f"{x!r} {height - y!r} {z!r}")
            else:
                for c in lines[i:i + n]:
                    f = c.split()
                    if ty in (2, 3):
                        f = f[:2] + f[2:][::-1]
                    out.append(" ".join(f))
            i += n
    open(dst, "w").write("\n".join(out))


def symmetric(h, out):
    import gmsh
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    g = gmsh.model.geo
    p = [g.addPoint(x, y, 0, 2 * h) for x, y in [(0, 0), (0.1, 0), (0.1, 0.02), (0.1, 0.04), (0, 0.04), (0, 0.02), (0.05, 0.02)]]
    bot, rlo, rup = g.addLine(p[0], p[1]), g.addLine(p[1], p[2]), g.addLine(p[2], p[3])
    top, lup, llo = g.addLine(p[3], p[4]), g.addLine(p[4], p[5]), g.addLine(p[5], p[0])
    notch, lig = g.addLine(p[5], p[6]), g.addLine(p[6], p[2])
    lower = g.addPlaneSurface([g.addCurveLoop([bot, rlo, -lig, -notch, llo])])
    upper = g.addPlaneSurface([g.addCurveLoop([notch, lig, rup, top, lup])])
    g.synchronize()
    f = gmsh.model.mesh.field
    b = f.add("Box")
    for k, v in dict(VIn=h, VOut=2 * h, XMin=0.045, XMax=0.1, YMin=0.008, YMax=0.032, Thickness=0.003).items():
        f.setNumber(b, k, v)
    f.setAsBackgroundMesh(b)
    for k in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints", "MeshSizeFromCurvature"):
        gmsh.option.setNumber("Mesh." + k, 0)
    m = [1, 0, 0, 0, 0, -1, 0, 0.04, 0, 0, 1, 0, 0, 0, 0, 1]
    for a, c in ((rup, rlo), (top, bot), (lup, llo)):
        gmsh.model.mesh.setPeriodic(1, [a], [c], m)
    gmsh.model.mesh.setPeriodic(2, [upper], [lower], m)
    for name, tags, d in (("bottom", [bot], 1), ("right", [rlo, rup], 1), ("top", [top], 1), ("left_up", [lup], 1),
                          ("left_low", [llo], 1), ("notch", [notch], 1), ("plate", [lower, upper], 2)):
        gmsh.model.addPhysicalGroup(d, tags, name=name)
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.write(out)
    gmsh.finalize()


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "mirror":
        mirror(sys.argv[2], sys.argv[3], float(sys.argv[4]))
    elif len(sys.argv) == 4 and sys.argv[1] == "symmetric":
        symmetric(float(sys.argv[2]), sys.argv[3])
    else:
        sys.exit(__doc__)
