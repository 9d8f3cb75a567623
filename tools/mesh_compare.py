#!/usr/bin/env python3
"""Summarise gmsh .msh files as meshio reads them, as JSON, to check FLEM's importer against.

Usage:
    python3 tools/mesh_compare.py FILE.msh [FILE.msh ...] [--indent N]

Needs meshio (5.3.5 tested) and numpy. Prints ONE JSON object on stdout and exits 0 whenever
the arguments were usable, even if some files fail to read (those get "ok": false); it exits 2
on a usage error and 3 if meshio cannot be imported (the reason goes to stderr). meshio's own
warnings go to stderr, never to stdout.

Output format (keys are always present; lists are sorted; counts are integers):

    {
      "meshio_version": "5.3.5",
      "files": [
        {
          "file": "configs/meshes/rect_quad_v41.msh",   # the path exactly as given
          "ok": true,
          "points_total": 45,               # len(mesh.points), every node in the file
          "nodes_2d": 45,                   # distinct nodes used by cells of topological
                                            # dimension 2 (what FLEM keeps)
          "cells": {"line": 24, "quad": 32},  # cells per meshio type, summed over blocks,
                                              # types with zero cells omitted
          "cells_2d": {"quad": 32, "triangle": 0},  # always both keys: first-order 2D cells
          "physical_groups": {              # names per dimension "0".."3" (always 4 keys)
            "0": [],
            "1": ["bottom", "left", "right", "top"],
            "2": ["domain"],
            "3": []
          }
        },
        {"file": "missing.msh", "ok": false, "error": "FileNotFoundError: ..."}
      ]
    }

Physical group names: every entry of meshio's field_data (name -> [tag, dim]) whose dimension
is 0-3, plus, for physical tags that appear in cell_data["gmsh:physical"] on cells of
dimension d but have no name, the tag as a decimal string ("7"), as FLEM names unnamed groups.
A failed file has exactly the keys "file", "ok" (false) and "error" (exception type and text).
"""
import json
import sys


def summarise(path, meshio, np):
    """The JSON summary of one file (see the module docstring)."""
    from meshio._mesh import topological_dimension

    m = meshio.read(path, file_format="gmsh")
    cells = {}
    used = []
    named = {str(d): set() for d in range(4)}
    tags_by_dim = {str(d): set() for d in range(4)}
    phys = m.cell_data.get("gmsh:physical")
    for k, block in enumerate(m.cells):
        n = int(len(block.data))
        cells[block.type] = cells.get(block.type, 0) + n
        dim = topological_dimension.get(block.type)
        if dim == 2 and n > 0:
            used.append(np.asarray(block.data).reshape(-1))
        if phys is not None and dim in (0, 1, 2, 3) and k < len(phys):
            tags_by_dim[str(dim)].update(int(t) for t in np.asarray(phys[k]).reshape(-1) if int(t) != 0)
    tag_named = {str(d): set() for d in range(4)}
    for name, value in m.field_data.items():
        v = np.asarray(value).reshape(-1)
        if len(v) >= 2 and int(v[1]) in (0, 1, 2, 3):
            named[str(int(v[1]))].add(str(name))
            tag_named[str(int(v[1]))].add(int(v[0]))
    for d in named:
        named[d] |= {str(t) for t in tags_by_dim[d] - tag_named[d]}
    nodes_2d = int(len(np.unique(np.concatenate(used)))) if used else 0
    return {
        "file": path,
        "ok": True,
        "points_total": int(len(m.points)),
        "nodes_2d": nodes_2d,
        "cells": {t: c for t, c in sorted(cells.items()) if c > 0},
        "cells_2d": {"quad": cells.get("quad", 0), "triangle": cells.get("triangle", 0)},
        "physical_groups": {d: sorted(v) for d, v in sorted(named.items())},
    }


def main(argv):
    args = list(argv[1:])
    indent = None
    if "--indent" in args:
        i = args.index("--indent")
        try:
            indent = int(args[i + 1])
        except (IndexError, ValueError):
            print("--indent needs an integer", file=sys.stderr)
            return 2
        del args[i : i + 2]
    if not args or any(a.startswith("-") for a in args):
        print(__doc__.split("\n\n")[1], file=sys.stderr)
        return 2
    try:
        import meshio
        import numpy as np
    except Exception as e:  # noqa: BLE001 - report any import problem
        print(f"cannot import meshio/numpy: {e}", file=sys.stderr)
        return 3
    out = {"meshio_version": getattr(meshio, "__version__", "unknown"), "files": []}
    real_stdout = sys.stdout
    for path in args:
        sys.stdout = sys.stderr  # meshio prints warnings; keep stdout pure JSON
        try:
            out["files"].append(summarise(path, meshio, np))
        except KeyboardInterrupt:
            raise
        except BaseException as e:  # noqa: BLE001 - one bad file must not stop the others
            # (meshio's gmsh reader can even raise SystemExit on some corrupt files)
            out["files"].append({"file": path, "ok": False, "error": f"{type(e).__name__}: {e}"})
        finally:
            sys.stdout = real_stdout
    json.dump(out, sys.stdout, indent=indent, sort_keys=False)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
