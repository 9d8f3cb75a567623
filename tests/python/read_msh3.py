#!/usr/bin/env python3
"""Read gmsh files with volume elements through meshio and print what it saw as one JSON object,
to check FLEM's 3D importer against (tests/mesh3.rs, issue 38):
{"meshio_version": "5.3.5", "files": [{
  "file": path,
  "points_3d": number of distinct nodes used by tetrahedra and hexahedra,
  "cells": [[meshio cell type, [[x, y, z] per corner]], ...] (the 3D cells in meshio's order),
  "region": [name of the cell's physical volume ("all" for none), ...],
  "face_sets": {name: [[[x, y, z] per corner] per face]} (triangles and quads of physical
               surfaces, corners in the file's order),
  "node_sets": {name: [[x, y, z], ...]} (distinct corners of the physical points, curves and
               surfaces' elements)}]}
Groups are named as FLEM names them: their $PhysicalNames name, else their tag as a string."""
import json
import sys

import meshio
import numpy as np

DIM = {"vertex": 0, "line": 1, "triangle": 2, "quad": 2, "tetra": 3, "hexahedron": 3}


def summarise(path):
    m = meshio.read(path, file_format="gmsh")
    names = {}
    for name, v in m.field_data.items():
        v = np.asarray(v).reshape(-1)
        names[(int(v[1]), int(v[0]))] = str(name)
    phys = m.cell_data.get("gmsh:physical")
    pts = m.points
    out = {"file": path, "cells": [], "region": [], "face_sets": {}, "node_sets": {}}
    used = set()
    node_sets = {}
    for k, block in enumerate(m.cells):
        dim = DIM.get(block.type)
        if dim is None:
            raise ValueError("unexpected cell type %s" % block.type)
        tags = np.asarray(phys[k]).reshape(-1) if phys is not None else np.zeros(len(block.data), dtype=int)
        for cell, tag in zip(block.data, tags):
            tag = int(tag)
            xs = [pts[i].tolist() for i in cell]
            name = names.get((dim, tag), str(tag)) if tag != 0 else None
            if dim == 3:
                out["cells"].append([block.type, xs])
                out["region"].append(name or "all")
                used.update(int(i) for i in cell)
            elif name is not None:
                if dim == 2:
                    out["face_sets"].setdefault(name, []).append(xs)
                node_sets.setdefault(name, set()).update(tuple(x) for x in xs)
    out["points_3d"] = len(used)
    out["node_sets"] = {n: sorted(list(x) for x in s) for n, s in sorted(node_sets.items())}
    return out


def main(argv):
    res = {"meshio_version": meshio.__version__, "files": []}
    real = sys.stdout
    for path in argv[1:]:
        sys.stdout = sys.stderr  # meshio's warnings must not reach the JSON
        try:
            res["files"].append(summarise(path))
        finally:
            sys.stdout = real
    json.dump(res, sys.stdout)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
