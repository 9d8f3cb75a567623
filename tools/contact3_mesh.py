#!/usr/bin/env python3
"""The mesh of configs/3d/contact_drop.toml (docs/3d.md "Contact (3D)"): a base 1 x 1 x 0.25 of
4 x 4 x 1 bricks and a block 0.5 x 0.5 x 0.25 of 2 x 2 x 2 bricks 0.05 above its middle, written
as gmsh msh 2.2 ASCII (the format FLEM reads with `[mesh] type = "gmsh"`). Two structured boxes
need no mesher: this script writes them directly (no gmsh dependency), deterministically.

Physical volumes: "base", "block" (regions). Physical surfaces (quadrangles: face sets and node
sets): "base_bottom" (the support), "base_top", "block_bottom" (the contact surfaces).

    python3 tools/contact3_mesh.py configs/3d/contact_drop.msh
"""
import sys


def box(origin, size, n, first):
    """Points (id -> xyz) and bricks (gmsh/VTK corner order) of a box, ids from `first`."""
    (ox, oy, oz), (sx, sy, sz), (nx, ny, nz) = origin, size, n
    pid = lambda i, j, k: first + i + (nx + 1) * (j + (ny + 1) * k)
    pts = {}
    for k in range(nz + 1):
        for j in range(ny + 1):
            for i in range(nx + 1):
                pts[pid(i, j, k)] = (ox + sx * i / nx, oy + sy * j / ny, oz + sz * k / nz)
    cells = []
    for k in range(nz):
        for j in range(ny):
            for i in range(nx):
                cells.append([pid(i, j, k), pid(i + 1, j, k), pid(i + 1, j + 1, k), pid(i, j + 1, k), pid(i, j, k + 1), pid(i + 1, j, k + 1), pid(i + 1, j + 1, k + 1), pid(i, j + 1, k + 1)])
    # bottom (outward -z: 0 3 2 1) and top (outward +z: 4 5 6 7) faces
    bottom = [[c[0], c[3], c[2], c[1]] for c in cells[: nx * ny]]
    top = [[c[4], c[5], c[6], c[7]] for c in cells[nx * ny * (nz - 1):]]
    return pts, cells, bottom, top


def main(out):
    bp, bc, bb, bt = box((0.0, 0.0, 0.0), (1.0, 1.0, 0.25), (4, 4, 1), 1)
    kp, kc, kb, _ = box((0.25, 0.25, 0.3), (0.5, 0.5, 0.25), (2, 2, 2), len(bp) + 1)
    pts = {**bp, **kp}
    names = [(2, 3, "base_bottom"), (2, 4, "base_top"), (2, 5, "block_bottom"), (3, 1, "base"), (3, 2, "block")]
    elems = [(3, 3, f) for f in bb] + [(3, 4, f) for f in bt] + [(3, 5, f) for f in kb] + [(5, 1, c) for c in bc] + [(5, 2, c) for c in kc]
    lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", str(len(names))]
    lines += [f'{d} {t} "{n}"' for d, t, n in names]
    lines += ["$EndPhysicalNames", "$Nodes", str(len(pts))]
    lines += [f"{i} {x:.17g} {y:.17g} {z:.17g}" for i, (x, y, z) in sorted(pts.items())]
    lines += ["$EndNodes", "$Elements", str(len(elems))]
    lines += [f"{k + 1} {t} 2 {tag} {tag} " + " ".join(map(str, nodes)) for k, (t, tag, nodes) in enumerate(elems)]
    lines += ["$EndElements"]
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "configs/3d/contact_drop.msh")
