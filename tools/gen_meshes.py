#!/usr/bin/env python3
"""Regenerate the small test meshes in configs/meshes from their .geo sources.

Needs the gmsh and meshio Python packages (e.g. a venv with gmsh==4.15.2 meshio==5.3.5 numpy).
Run from anywhere: python3 tools/gen_meshes.py (or `python3 tools/gen_meshes.py sif`: only the
stress-intensity meshes; `paths`: the kink-angle meshes; `3d`: the 3D meshes of configs/3d)
"""
import os
import sys

import gmsh

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "configs", "meshes")


def mesh(geo, outputs):
    """Mesh `geo` in 2D and write each (file name, msh version, binary) in `outputs`."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.open(os.path.join(HERE, geo))
    gmsh.model.mesh.generate(2)
    for name, version, binary in outputs:
        gmsh.option.setNumber("Mesh.MshFileVersion", version)
        gmsh.option.setNumber("Mesh.Binary", 1 if binary else 0)
        gmsh.write(os.path.join(HERE, name))
    gmsh.finalize()


def cook():
    """Cook's membrane (cook.geo) at n = 4, 8, 16 quads per side (cook_N.msh) and the same with
    every quad split in two triangles (cook_N_t3.msh: the transfinite surface without Recombine)."""
    src = open(os.path.join(HERE, "cook.geo")).read()
    for n in (4, 8, 16):
        for tag, recombine in (("", True), ("_t3", False)):
            text = src.replace("n = 4;", "n = %d;" % n)
            if not recombine:
                text = text.replace("Recombine Surface{1};", "")
            write_msh41(text, "cook_%d%s.msh" % (n, tag))


def write_msh41(geo_text, out):
    """Meshes the .geo text in 2D with gmsh and writes `out` (beside this file) as ASCII msh 4.1."""
    import tempfile
    with tempfile.NamedTemporaryFile("w", suffix=".geo", delete=False) as f:
        f.write(geo_text)
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.open(f.name)
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.write(os.path.join(HERE, out))
    gmsh.finalize()
    os.unlink(f.name)


def sif():
    """The stress-intensity meshes (issue 34, tests/sif.rs, configs/sif/): the inclined centre
    crack (sif_inclined.geo) at beta = 30, 45, 60 deg in triangles and at 45 deg in quads, the
    edge crack (sif_edge.geo) at a/W = 0.3 in triangles and 0.5 in quads. Each .geo's first
    lines are its parameters; they are replaced here."""
    import re
    cases = [
        ("sif_inclined.geo", {"beta": b, "quads": 0}, "sif_inclined_%d_t3.msh" % b) for b in (30, 45, 60)
    ] + [
        ("sif_inclined.geo", {"beta": 45, "quads": 1}, "sif_inclined_45_q4.msh"),
        ("sif_edge.geo", {"aw": 0.3, "quads": 0}, "sif_edge_0.3_t3.msh"),
        ("sif_edge.geo", {"aw": 0.5, "quads": 1}, "sif_edge_0.5_q4.msh"),
    ]
    for geo, subs, out in cases:
        src = open(os.path.join(HERE, geo)).read()
        for k, v in subs.items():
            src, n = re.subn(r"^%s = [^;]*;" % k, "%s = %s;" % (k, v), src, flags=re.M)
            assert n == 1, (geo, k)
        write_msh41(src, out)


PATHS_H = {"centre": (0.1, 0.05, 0.025), "sen": (0.05, 0.025, 0.0125)}
# The shear test's whole path (must-show 3, ours, session 17): the same square (paths_sen.geo) at
# h = 1/30, 1/40, 1/60, written as paths_shear_KIND_N.msh.
PATHS_H["shear"] = (1.0 / 30, 1.0 / 40, 1.0 / 60)


def paths():
    """The kink-angle meshes (issue 34 must-show 2, configs/paths/, `flem paths`): the centre
    crack (paths_centre.geo) and the single-edge-notched square (paths_sen.geo), unstructured
    triangles and gmsh-recombined quads at three sizes each (PATHS_H; refinement 1 coarsest).
    The structured Q4 grids of the same runs are the scenes' own `rectangle` meshes."""
    import re
    for fam in ("centre", "sen", "shear"):
        geo = "sen" if fam == "shear" else fam
        for k, h in enumerate(PATHS_H[fam], start=1):
            # `uquad` (session 34): unstructured quads, for the shear test only ("quad" is a regular
            # grid on its square at h = 1/40 and 1/60: docs/paths.md, "Cost", session 34).
            for kind, quads in (("t3", 0), ("quad", 1)) + ((("uquad", 2),) if fam == "shear" else ()):
                src = open(os.path.join(HERE, "paths_%s.geo" % geo)).read()
                for key, v in (("h", h), ("quads", quads)):
                    src, n = re.subn(r"^%s = [^;]*;" % key, "%s = %s;" % (key, v), src, flags=re.M)
                    assert n == 1, (geo, key)
                write_msh41(src, "paths_%s_%s_%d.msh" % (fam, kind, k))


def dynamic():
    """The dynamic-fracture meshes (issue 36, configs/dynamic/, docs/dynamic.md): Kalthoff-Winkler
    (kalthoff.geo) at h = 1 and 0.6 mm in the crack band, the branching plate (branching.geo) at
    h = 0.5 and 0.35 mm; triangles. Written beside their .geo in configs/dynamic/."""
    import re
    dyn = os.path.join(HERE, "..", "dynamic")
    for geo, hs in (("kalthoff.geo", (("1", 0.001), ("0.6", 0.0006))), ("branching.geo", (("0.5", 0.0005), ("0.35", 0.00035)))):
        src = open(os.path.join(dyn, geo)).read()
        for tag, h in hs:
            text, n = re.subn(r"^h = [^;]*;", "h = %r;" % h, src, flags=re.M)
            assert n == 1, geo
            write_msh41(text, os.path.join(dyn, "%s_h%s.msh" % (geo[:-4], tag)))


THREE_D = os.path.join(HERE, "..", "3d")


def mesh3(geo, params, outputs):
    """Mesh configs/3d/`geo` in 3D with its parameters (`name = value;` lines at the top of the
    .geo) replaced by `params`, and write each (file name, msh version, binary) in `outputs`
    beside it. Only first-order tetrahedra and hexahedra are accepted (a prism or pyramid left
    by the mesher would make FLEM refuse the file)."""
    import re
    import tempfile
    src = open(os.path.join(THREE_D, geo)).read()
    for k, v in params.items():
        src, n = re.subn(r"^%s = [^;]*;" % k, "%s = %r;" % (k, v), src, flags=re.M)
        assert n == 1, (geo, k)
    with tempfile.NamedTemporaryFile("w", suffix=".geo", delete=False) as f:
        f.write(src)
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.open(f.name)
    gmsh.model.mesh.generate(3)
    types = set(int(t) for t in gmsh.model.mesh.getElementTypes(3))
    assert types and types <= {4, 5}, (geo, params, types)
    for name, version, binary in outputs:
        gmsh.option.setNumber("Mesh.MshFileVersion", version)
        gmsh.option.setNumber("Mesh.Binary", 1 if binary else 0)
        gmsh.write(os.path.join(THREE_D, name))
    gmsh.finalize()
    os.unlink(f.name)


def three_d():
    """The 3D meshes (issue 38, configs/3d/, tests/mesh3.rs, docs/3d.md): two unit cubes
    (cube.geo: two regions, side and inner face sets, a curve and a point group) in tetrahedra
    and bricks, each in msh 2.2 and 4.1, ASCII and binary; the notched bar (notched_bar.geo) in
    tetrahedra and bricks at h = 0.125 m and the Brazilian cylinder (cylinder.geo) in
    tetrahedra at h = 0.02 m and the strip-loaded Brazilian disc (brazilian.geo) at h = 5 and
    3.5 mm, msh 4.1 ASCII; the brick cubes as .vtu through meshio."""
    for kind, hexa in (("tet", 0), ("hex", 1)):
        mesh3("cube.geo", {"hex": hexa, "n": 2}, [
            ("cube_%s_v22.msh" % kind, 2.2, False),
            ("cube_%s_v22_bin.msh" % kind, 2.2, True),
            ("cube_%s_v41.msh" % kind, 4.1, False),
            ("cube_%s_v41_bin.msh" % kind, 4.1, True),
        ])
        mesh3("notched_bar.geo", {"hex": hexa, "h": 0.125}, [("notched_bar_%s_v41.msh" % kind, 4.1, False)])
    mesh3("cylinder.geo", {"h": 0.02}, [("cylinder_tet_v41.msh", 4.1, False)])
    # The Brazilian disc with its loading strips (brazilian.geo, brazilian.toml,
    # tests/brazilian3.rs): tetrahedra at h = 5 mm (the scene's) and 3.5 mm (the finer mesh of
    # the initiation test), the strips' edges at h / 2.
    for h in (5, 3.5):
        mesh3("brazilian.geo", {"h": h}, [("brazilian_h%s_v41.msh" % h, 4.1, False)])
    # The brick cubes as a .vtu written by meshio (its "gmsh:physical" cell array on every
    # block): the 3D VTK importer's doc file (plugins/src/import/vtk3.rs).
    import meshio
    m = meshio.read(os.path.join(THREE_D, "cube_hex_v41.msh"))
    out = meshio.Mesh(m.points, m.cells, cell_data={"gmsh:physical": m.cell_data["gmsh:physical"]})
    out.write(os.path.join(THREE_D, "cube_hex.vtu"))  # binary, zlib (meshio's default)


def main():
    if sys.argv[1:] == ["3d"]:
        three_d()
        return 0
    if sys.argv[1:] == ["sif"]:
        sif()
        return 0
    if sys.argv[1:] == ["paths"]:
        paths()
        return 0
    if sys.argv[1:] == ["dynamic"]:
        dynamic()
        return 0
    three_d()
    dynamic()
    sif()
    paths()
    cook()
    mesh("rect_quad.geo", [
        ("rect_quad_v41.msh", 4.1, False),
        ("rect_quad_v41_bin.msh", 4.1, True),
        ("rect_quad_v22.msh", 2.2, False),
        ("rect_quad_v22_bin.msh", 2.2, True),
    ])
    mesh("rect_tri.geo", [("rect_tri_v22.msh", 2.2, False)])
    mesh("plate_hole.geo", [("plate_hole_v41.msh", 4.1, False)])
    mesh("plate_hole_fine.geo", [("plate_hole_fine_v41.msh", 4.1, False)])
    # A tiny .vtu from the quad rectangle with a cell array "region" (1 = domain), via meshio.
    import meshio
    import numpy as np
    m = meshio.read(os.path.join(HERE, "rect_quad_v41.msh"))
    quads = np.concatenate([c.data for c in m.cells if c.type == "quad"])
    used = np.unique(quads)
    remap = -np.ones(len(m.points), dtype=np.int64)
    remap[used] = np.arange(len(used))
    out = meshio.Mesh(
        m.points[used],
        [("quad", remap[quads].astype(np.int64))],
        cell_data={"region": [np.ones(len(quads), dtype=np.int32)]},
    )
    out.write(os.path.join(HERE, "rect_quad.vtu"))  # binary, zlib-compressed (meshio's default)
    out.write(os.path.join(HERE, "rect_quad_ascii.vtu"), binary=False)
    # A legacy (4.2) .vtk of the triangle rectangle with meshio's "gmsh:physical" cell array
    # on its triangles and lines (lines 1-4 = bottom/right/top/left, triangles 5 = domain).
    t = meshio.read(os.path.join(HERE, "rect_tri_v22.msh"))
    t.points = t.points.astype(np.float64)
    t.cell_data = {"gmsh:physical": t.cell_data["gmsh:physical"]}
    t.field_data = {}
    meshio.vtk.write(os.path.join(HERE, "rect_tri.vtk"), t, fmt_version="4.2", binary=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
