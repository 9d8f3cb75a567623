#!/usr/bin/env python3
"""Read a FLEM run directory as a ParaView user would: results.pvd, each VTU it lists (meshio),
and, where pyvista installs, the PVD through pyvista/VTK itself. Prints one JSON object:
{"datasets": [{"file", "timestep", "points", "cells": {type: n}, "point_data": {name: list}}],
 "pyvista": null | {"version", "blocks": [{"points", "cells", "arrays": [...], "displacement": list}]},
 "pyvista_error": str | null}"""
import json
import os
import sys
import xml.etree.ElementTree as ET

import meshio

run = sys.argv[1]
pvd = os.path.join(run, "results.pvd")
root = ET.parse(pvd).getroot()
out = {"datasets": [], "pyvista": None, "pyvista_error": None}
for ds in root.iter("DataSet"):
    f = ds.get("file")
    m = meshio.read(os.path.join(run, f))
    out["datasets"].append({
        "file": f,
        "timestep": float(ds.get("timestep")),
        "points": m.points.tolist(),
        "cells": {b.type: int(len(b.data)) for b in m.cells},
        "point_data": {k: v.tolist() for k, v in m.point_data.items()},
    })
try:
    import pyvista as pv
except Exception as e:  # pyvista is optional: it needs the vtk wheel
    out["pyvista_error"] = f"pyvista not importable: {e}"
else:
    reader = pv.get_reader(pvd)
    blocks = []
    for i, t in enumerate(reader.time_values):
        reader.set_active_time_value(t)
        mesh = reader.read()
        b = mesh[0] if isinstance(mesh, pv.MultiBlock) else mesh
        blocks.append({
            "time": float(t),
            "points": int(b.n_points),
            "cells": int(b.n_cells),
            "arrays": sorted(b.point_data.keys()),
            "displacement": b.point_data["displacement"].tolist(),
        })
    out["pyvista"] = {"version": pv.__version__, "blocks": blocks}
print(json.dumps(out))
