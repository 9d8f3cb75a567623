#!/usr/bin/env python3
"""Regenerate the small test meshes in configs/meshes from their .geo sources.

Needs the gmsh and meshio Python packages (e.g. a venv with gmsh==4.15.2 meshio==5.3.5 numpy).
Run from anywhere: python3 tools/gen_meshes.py
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
    import tempfile
    src = open(os.path.join(HERE, "cook.geo")).read()
    for n in (4, 8, 16):
        for tag, recombine in (("", True), ("_t3", False)):
            text = src.replace("n = 4;", "n = %d;" % n)
            if not recombine:
                text = text.replace("Recombine Surface{1};", "")
            with tempfile.NamedTemporaryFile("w", suffix=".geo", delete=False) as f:
                f.write(text)
            gmsh.initialize()
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.open(f.name)
            gmsh.model.mesh.generate(2)
            gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
            gmsh.option.setNumber("Mesh.Binary", 0)
            gmsh.write(os.path.join(HERE, "cook_%d%s.msh" % (n, tag)))
            gmsh.finalize()
            os.unlink(f.name)


def main():
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
