#!/usr/bin/env python3
"""Writes the kink-angle scenes of configs/paths/ (issue 34 must-show 2; `flem paths`;
docs/paths.md): the centre crack under uniaxial tension at beta = 30, 45, 60 deg to the crack
and the single-edge-notched shear test, each on unstructured triangles, gmsh-recombined quads
(configs/meshes/paths_*.msh, `python3 tools/gen_meshes.py paths`) and a structured Q4 grid (the
scene's own `rectangle` mesh), three refinements each. Standard library only."""
import math
import os

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "configs", "paths")
H = {"centre": (0.1, 0.05, 0.025), "sen": (0.05, 0.025, 0.0125)}
# The shear test's whole path (must-show 3; ours, session 17): h = 1/30, 1/40, 1/60, the
# scenes shear_KIND_N.toml (h = 1/20 cannot resolve the path's end at the clamped edge:
# docs/paths.md). N even, so that the grid has a line at the slit, y = 0.5.
H["shear"] = (1.0 / 30, 1.0 / 40, 1.0 / 60)

MATERIAL = """[model]
plane = "strain"
separated = ["crack"]

[[material]]
young_modulus = 1000.0
poisson_ratio = 0.3
density = 1.0

[solver]
type = "events"
max_events = %d
on_loose_fragment = "stop"   # the measurement ends when a crack reaches the boundary

[cracking]
max_splits_per_check = 1

[cracking.criterion]
type = "rankine"
tensile_strength = 1.0

[cracking.separation]
type = "sigma1_nearest"
"""


def graded_zone(length, h, q=1.15):
    """Cells and last/first ratio of a zone of `length` whose first cell is about h."""
    n = math.ceil(math.log(1.0 + length * (q - 1.0) / h) / math.log(q))
    return n, q ** (n - 1)


def centre(beta, kind, k):
    h = H["centre"][k - 1]
    b = math.radians(beta)
    sxx, syy, sxy = math.cos(b) ** 2, math.sin(b) ** 2, math.sin(b) * math.cos(b)
    r = math.tan(b) ** -1
    mts = math.degrees(2 * math.atan(-2 * r / (1 + math.sqrt(1 + 8 * r * r))))
    head = """# Centre crack (half-length a = 1, horizontal, y = 0) in a 20 a x 20 a plate under uniaxial
# tension s = 1 at beta = %d deg to the crack: the stress s n n (n = (cos beta, sin beta)) as
# tractions on the four sides, held by a pin and a roller (self-equilibrated). Reference (infinite
# plate): K_I = s sqrt(pi a) sin^2 beta, K_II = s sqrt(pi a) sin beta cos beta, maximum
# tangential stress kink (Erdogan & Sih 1963) %.1f deg from the crack's direction at each tip.
# Plane strain, E = 1000, nu = 0.3, Rankine sigma_t = 1, events solver; %s, element size
# %g at the tips. `flem paths` measures the kink (issue 34 must-show 2; docs/paths.md).
# Written by tools/gen_paths.py.
title = "kink: centre crack, beta = %d deg, %s %d"
""" % (beta, mts, {"t3": "unstructured triangles", "quad": "unstructured quads (gmsh recombined)", "q4": "structured Q4 grid (graded away from the tips)"}[kind], h, beta, kind, k)
    if kind == "q4":
        nxo, gx = graded_zone(8.5, h)
        nyo, gy = graded_zone(9.5, h)
        nxi, nyi = round(3.0 / h), round(0.5 / h)
        mesh = """
[mesh]
type = "rectangle"
width = 20.0
height = 20.0
origin = [-10.0, -10.0]
nx = %d
ny = %d
grading_x = [[8.5, %d, %.6f], [3.0, %d, 1.0], [8.5, %d, %.6f]]
grading_y = [[9.5, %d, %.6f], [0.5, %d, 1.0], [0.5, %d, 1.0], [9.5, %d, %.6f]]

[[set]]
name = "crack"
segment = [[-1.0, 0.0], [1.0, 0.0]]
boundary = false
tolerance = 1e-9

[[set]]
name = "pin"
nearest = [-10.0, -10.0]

[[set]]
name = "roller"
nearest = [10.0, -10.0]
""" % (2 * nxo + nxi, 2 * nyo + 2 * nyi, nxo, 1 / gx, nxi, nxo, gx, nyo, 1 / gy, nyi, nyi, nyo, gy)
    else:
        mesh = """
[mesh]
type = "gmsh"
file = "../meshes/paths_centre_%s_%d.msh"
""" % (kind, k)
    loads = """
[[support]]
nodes = "pin"
fix = "xy"

[[support]]
nodes = "roller"
fix = "y"

[[load]]
name = "top"
type = "traction"
edges = "top"
value = [%.15g, %.15g]

[[load]]
name = "bottom"
type = "traction"
edges = "bottom"
value = [%.15g, %.15g]

[[load]]
name = "right"
type = "traction"
edges = "right"
value = [%.15g, %.15g]

[[load]]
name = "left"
type = "traction"
edges = "left"
value = [%.15g, %.15g]

[[stage]]
name = "tension"
levels = { top = 10.0, bottom = 10.0, right = 10.0, left = 10.0 }
""" % (sxy, syy, -sxy, -syy, sxx, sxy, -sxx, -sxy)
    return head + mesh + "\n" + MATERIAL % 500 + loads


def sen(kind, k, fam="sen"):
    h = H[fam][k - 1]
    head = """# Shear test (issue 34's table, first row): a unit square with a slit from the middle of the
# left edge to the centre (0.5, 0.5), bottom clamped, top displaced along x (u_y = 0 there).
# The tip is loaded in mode II with little mode I: the maximum tangential stress kink
# (Erdogan & Sih 1963) tends to -70.5 deg (K_I -> 0). Plane strain, E = 1000, nu = 0.3, Rankine
# sigma_t = 1, events solver; %s, element size %g. `flem paths` measures the kink
# (issue 34 must-show 2; docs/paths.md). Written by tools/gen_paths.py.
title = "kink: shear test, %s %d"
""" % ({"t3": "unstructured triangles", "quad": "gmsh-recombined quads (Frontal-Delaunay for quads: on this square a regular grid but at h = 1/30 of the shear test; docs/paths.md)", "uquad": "unstructured quads (Frontal-Delaunay triangles recombined by Blossom; session 34)", "q4": "structured Q4 grid"}[kind], h, kind, k)
    if kind == "q4":
        n = round(1.0 / h)
        mesh = """
[mesh]
type = "rectangle"
width = 1.0
height = 1.0
nx = %d
ny = %d

[[set]]
name = "crack"
segment = [[0.0, 0.5], [0.5, 0.5]]
boundary = false
tolerance = 1e-9
""" % (n, n)
    else:
        mesh = """
[mesh]
type = "gmsh"
file = "../meshes/paths_%s_%s_%d.msh"
""" % (fam, kind, k)
    loads = """
[[support]]
nodes = "bottom"
fix = "xy"

[[load]]
name = "shear"
type = "displacement"
nodes = "top"
x = 1.0
y = 0.0

[[stage]]
name = "shear"
levels = { shear = 0.05 }
"""
    return head + mesh + "\n" + MATERIAL % 90 + loads


def main():
    os.makedirs(HERE, exist_ok=True)
    for k in (1, 2, 3):
        for kind in ("t3", "quad", "q4"):
            for beta in (30, 45, 60):
                open(os.path.join(HERE, "centre_%d_%s_%d.toml" % (beta, kind, k)), "w").write(centre(beta, kind, k))
            open(os.path.join(HERE, "sen_%s_%d.toml" % (kind, k)), "w").write(sen(kind, k))
            open(os.path.join(HERE, "shear_%s_%d.toml" % (kind, k)), "w").write(sen(kind, k, "shear"))
        # The shear test on unstructured quads (session 34; its "quad" meshes are grids at 1/40, 1/60).
        open(os.path.join(HERE, "shear_uquad_%d.toml" % k), "w").write(sen("uquad", k, "shear"))


if __name__ == "__main__":
    main()
