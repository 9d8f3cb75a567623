#!/usr/bin/env python3
"""Read a FLEM VTU (or a PVD's files) with meshio and print what it saw as one JSON object:
{"points": [[x, y, z], ...], "cells": {"quad": [[...], ...], ...},
 "point_data": {name: nested list}, "cell_data": {name: [per block nested list]}}.
Used by the integration tests to check that what we write is what others read."""
import json
import sys

import meshio

m = meshio.read(sys.argv[1])
out = {
    "points": m.points.tolist(),
    "cells": {},
    "point_data": {k: v.tolist() for k, v in m.point_data.items()},
    "cell_data": {k: [b.tolist() for b in v] for k, v in m.cell_data.items()},
}
for block in m.cells:
    out["cells"].setdefault(block.type, []).extend(block.data.tolist())
print(json.dumps(out))
