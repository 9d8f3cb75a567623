#!/usr/bin/env python3
"""Read a 3D VTU with meshio and with pyvista (VTK's own reader) and print what each saw as one
JSON object (tests/mesh3.rs, issue 38):
{"meshio": {"points": [[x, y, z], ...], "cells": [[type, [corners]], ...] (file order),
            "point_data": {name: nested list}, "cell_data": {name: nested list over all cells}},
 "pyvista": {"points": ..., "celltypes": [VTK type per cell], "cells": [[corners], ...],
             "point_data": {name: nested list}, "cell_data": {name: nested list}}}"""
import json
import sys

import meshio
import numpy as np
import pyvista as pv

path = sys.argv[1]
m = meshio.read(path)
mo = {"points": m.points.tolist(), "cells": [], "point_data": {}, "cell_data": {}}
for block in m.cells:
    mo["cells"].extend([block.type, [int(i) for i in c]] for c in block.data)
for k, v in m.point_data.items():
    mo["point_data"][k] = np.asarray(v).tolist()
for k, blocks in m.cell_data.items():
    mo["cell_data"][k] = np.concatenate([np.asarray(b) for b in blocks]).tolist()

g = pv.read(path)
conn = np.asarray(g.cell_connectivity)
off = np.asarray(g.offset)
po = {
    "points": np.asarray(g.points).tolist(),
    "celltypes": [int(t) for t in g.celltypes],
    "cells": [conn[off[i]:off[i + 1]].tolist() for i in range(g.n_cells)],
    "point_data": {k: np.asarray(g.point_data[k]).tolist() for k in g.point_data.keys()},
    "cell_data": {k: np.asarray(g.cell_data[k]).tolist() for k in g.cell_data.keys()},
}
print(json.dumps({"meshio": mo, "pyvista": po}))
