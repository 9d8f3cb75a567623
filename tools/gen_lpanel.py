"""Meshes and scenes of Winkler's L-shaped panel (issue 34 must-show 3; docs/paths.md,
section "Winkler's L-panel").

    /work/venvs/b38/bin/python tools/gen_lpanel.py      # gmsh 4.15.2 (python module gmsh)
    python3 tools/gen_lpanel.py --scenes               # the .toml files only, from the .msh files here (no gmsh)

Writes configs/lpanel/lpanel_{t3,quad,q4}_{1,2,3}.msh and .toml (refinement 1 coarsest) and
the small mesh of the test (lpanel_t3_test.msh, tests/lpanel.rs).

Geometry (metres; Winkler 2001, Winkler, Hofstetter & Niederwanger 2001): the square
[0, 0.5]^2 less the cut-out [0.25, 0.5] x [0, 0.25]; the leg is [0, 0.25] x [0, 0.25] (its
bottom y = 0 fixed), the arm [0, 0.5] x [0.25, 0.5]; the load (an upward displacement) acts on
the arm's underside y = 0.25 for 0.47 <= x <= 0.5. The re-entrant corner is (0.25, 0.25).
Mesh kinds:
- t3: unstructured gmsh triangles, size h in the band [0, 0.30] x [0.22, 0.45] where the crack
  runs, 2 h elsewhere;
- quad: the same, recombined into quads by gmsh (Blossom, then all-quad subdivision off);
- q4: a structured grid, three transfinite patches (leg, arm left of x = 0.25, arm right),
  uniform h.
"""
import os
import sys

gmsh = None  # imported by write() only: `--scenes` writes the scenes without it

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "configs", "lpanel")

# The shield of `tip_mts` (m; session 27, `shield_length`): no new crack within this distance of
# a crack, on every mesh and in every region. The parallel cracks it keeps off started 16-19 mm
# beside the main one on q4_2, q4_4 and quad_4 (docs/paths.md).
SHIELD = 0.040

# Element size in the crack band (m) per refinement; q4: cells per 0.25 m.
SIZES = {1: 0.0125, 2: 0.009, 3: 0.0065}
Q4_N = {1: 20, 2: 28, 3: 38}


def geometry(h_band, h_far):
    occ = gmsh.model.geo
    pts = [(0, 0), (0.25, 0), (0.25, 0.25), (0.47, 0.25), (0.5, 0.25), (0.5, 0.5), (0, 0.5), (0, 0.25)]
    tags = [occ.addPoint(x, y, 0, h_far) for x, y in pts]
    lines = [occ.addLine(tags[i], tags[(i + 1) % len(tags)]) for i in range(len(tags))]
    loop = occ.addCurveLoop(lines)
    s = occ.addPlaneSurface([loop])
    occ.synchronize()
    gmsh.model.addPhysicalGroup(1, [lines[0]], name="bottom")
    gmsh.model.addPhysicalGroup(1, [lines[3]], name="load")
    gmsh.model.addPhysicalGroup(2, [s], name="panel")
    f = gmsh.model.mesh.field.add("Box")
    gmsh.model.mesh.field.setNumber(f, "VIn", h_band)
    gmsh.model.mesh.field.setNumber(f, "VOut", h_far)
    gmsh.model.mesh.field.setNumber(f, "XMin", -0.01)
    gmsh.model.mesh.field.setNumber(f, "XMax", 0.30)
    gmsh.model.mesh.field.setNumber(f, "YMin", 0.22)
    gmsh.model.mesh.field.setNumber(f, "YMax", 0.45)
    gmsh.model.mesh.field.setNumber(f, "Thickness", 0.03)
    gmsh.model.mesh.field.setAsBackgroundMesh(f)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    return s


def structured(n):
    """Three transfinite patches, n cells per 0.25 m."""
    g = gmsh.model.geo
    P = {}
    for x, y in [(0, 0), (0.25, 0), (0.25, 0.25), (0, 0.25), (0.5, 0.25), (0.5, 0.5), (0.25, 0.5), (0, 0.5)]:
        P[(x, y)] = g.addPoint(x, y, 0)
    L = {}

    def line(a, b):
        if (b, a) in L:
            return -L[(b, a)]
        L[(a, b)] = g.addLine(P[a], P[b])
        return L[(a, b)]

    patches = [
        [(0, 0), (0.25, 0), (0.25, 0.25), (0, 0.25)],
        [(0, 0.25), (0.25, 0.25), (0.25, 0.5), (0, 0.5)],
        [(0.25, 0.25), (0.5, 0.25), (0.5, 0.5), (0.25, 0.5)],
    ]
    surfs = []
    for c in patches:
        ls = [line(c[i], c[(i + 1) % 4]) for i in range(4)]
        s = g.addPlaneSurface([g.addCurveLoop(ls)])
        surfs.append((s, [abs(t) for t in ls], c))
    g.synchronize()
    for s, ls, c in surfs:
        for t in ls:
            gmsh.model.mesh.setTransfiniteCurve(t, n + 1)
        gmsh.model.mesh.setTransfiniteSurface(s, "Left", [P[p] for p in c])
        gmsh.model.mesh.setRecombine(2, s)
    gmsh.model.addPhysicalGroup(1, [L[((0, 0), (0.25, 0))]], name="bottom")
    gmsh.model.addPhysicalGroup(2, [s for s, _, _ in surfs], name="panel")


def write(kind, name, h=None, n=None):
    global gmsh
    import gmsh as g

    gmsh = g
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add(name)
    if kind == "q4":
        structured(n)
    else:
        geometry(h, 2 * h)
        if kind == "quad":
            gmsh.option.setNumber("Mesh.Algorithm", 8)
            gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 1)
            gmsh.option.setNumber("Mesh.RecombineAll", 1)
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.write(os.path.join(HERE, name + ".msh"))
    ne = sum(len(t) for t in gmsh.model.mesh.getElements(2)[1])
    gmsh.finalize()
    return ne


HEADER = """# Winkler's L-shaped panel (issue 34 must-show 3, second half; docs/paths.md, "Winkler's L-panel").
# Source: B. Winkler, G. Hofstetter, G. Niederwanger (2001), "Experimental verification of a
# constitutive model for concrete cracking", Proc. IMechE L 215, 75-86; B. Winkler (2001), PhD
# thesis, Innsbruck. Panel 500 x 500 mm less a 250 x 250 mm cut-out, thickness t = 100 mm (plane
# stress); bottom of the leg fixed; upward displacement u on 470-500 mm of the arm's underside;
# E = 25.85 GPa, nu = 0.18, G_c 89-95 N/m, f_t 2.65-2.7 MPa (../shared/BENCHMARKS.md).
# Experiments: peak 6.7-7.6 kN at u ~ 0.20 mm (band: fpled/MYCODE
# examples/phasefield/dataLshapedPanelWinkler/force_displacement_Win04_fig10_Win01_fig5.csv;
# series A 7.22 kN at 0.208 mm: PSAAPGroupLinder/lShapedPanelBenchmark
# experimental/Winkler_Abb-7.12_Versuchsreihe-A.csv). Copies in configs/lpanel/winkler_band.csv.
# FLEM (units m, Pa, N per metre of thickness: the force of the experiment is t = 0.1 times the
# reaction): nodes split by Rankine at f_t = 2.7 MPa; the new faces carry the `cohesive` contact
# law (ours) with the exponential softening of concrete of Cornelissen, Hordijk & Reinhardt (1986,
# Heron 31(2); `softening = "cornelissen"`, since session 33), G_f = G_c = 90 N/m, frictionless;
# k_n = k_s = 10 E / h (ours). Petersson's bilinear law (`"petersson"`, sessions 26-32) gave peaks
# of 7.4-8.0 kN, the linear softening (the key removed) 8.5-12.5 kN (docs/paths.md, "Winkler's
# L-panel"); points within 30 mm of the load strip's end and of the clamped edge's end never split
# (`intact`, ours, session 33: the idealised rigid strip and clamp make the elastic stress singular
# there and crack the panel where the experiments' plates did not);
# explicit march with local damping (FLAC's, ratio 0.8; session 27: the default adaptive
# relaxation did not come to rest within 300 000 steps per stage on the fine unstructured meshes,
# their reaction 5-16 % high, docs/paths.md), displacement in stages (the ramp below), cracking
# checked at rest (at_equilibrium, FLEM's default, ours) and when the relaxation stalls
# (stall_steps, below).
# Separation rule: `tip_mts` (ours, issue 34) with `shield_length` (ours, session 27: no new
# crack within 40 mm of a crack) and `every = 2` (ours, session 33: the crack's direction is
# evaluated again once it is straight over two domain radii, not one; the interaction integral
# does not see the cohesive faces' tractions); the same scene with
# type = "sigma1_nearest" and without the shield_length and every lines is the paper's edge rule (the `lpe_` runs
# of docs/paths.md). Density
# 2400 kg/m^3 (only the explicit march's time scale; quasi-static).
# Mesh: {mesh_doc}. Written by tools/gen_lpanel.py.
"""


def scene(kind, i, ne, h):
    name = f"lpanel_{kind}_{i}"
    mesh_doc = {
        "t3": f"unstructured gmsh triangles, h = {h * 1e3:.1f} mm in the band [0, 0.30] x [0.22, 0.45] m, 2 h elsewhere ({ne} elements)",
        "quad": f"gmsh quads (recombined), h = {h * 1e3:.1f} mm in the band [0, 0.30] x [0.22, 0.45] m, 2 h elsewhere ({ne} elements)",
        "q4": f"structured Q4 grid, three transfinite patches, h = {h * 1e3:.2f} mm ({ne} elements)",
    }[kind]
    kn = 10 * 25.85e9 / h
    t = HEADER.format(mesh_doc=mesh_doc)
    t += f'title = "Winkler L-panel, {kind} {i}"\n\n'
    t += f'[mesh]\ntype = "gmsh"\nfile = "{name}.msh"\n\n'
    t += '[[set]]\nname = "lift"\nbox = [[0.4699, 0.2499], [0.5001, 0.2501]]\n\n'
    t += '[[set]]\nname = "lift_zone"   # the load strip and 30 mm around it: never split (ours, session 33)\nbox = [[0.4399, 0.2499], [0.5001, 0.2801]]\n\n'
    t += '[[set]]\nname = "base_end"   # the clamped edge\'s end, 30 mm: never split (ours, session 33)\nbox = [[0.2199, -0.0001], [0.2501, 0.0301]]\n\n'
    t += '[model]\nplane = "stress"\n\n'
    t += "[[material]]\nyoung_modulus = 25.85e9\npoisson_ratio = 0.18\ndensity = 2400.0\n\n"
    t += "[solver]\ntolerance = 1e-4   # the reaction within about 1 % of the converged one (docs/paths.md)\n"
    t += 'damping = { type = "local", ratio = 0.8 }   # ours for this scene (session 27; see the header)\n\n'
    t += '[[support]]\nnodes = "bottom"\nfix = "xy"\n\n'
    t += '[[load]]\nname = "lift"\ntype = "displacement"\nnodes = "lift"\ny = 1e-3   # m per unit level: level 0.2 = 0.2 mm\n\n'
    t += f'[contact]\nlaw = {{ type = "cohesive", normal_stiffness = {kn:.4e}, shear_stiffness = {kn:.4e}, tensile_strength = 2.7e6, fracture_energy = 90.0, friction = 0.0, softening = "cornelissen" }}\n\n'
    t += "[cracking]\n# Checks at rest (at_equilibrium, the default), and also when the relaxation stalls (its best\n# unbalanced ratio not halved in 30 000 steps): with cohesive faces softening, a stage often never\n# comes to rest to 1e-4, and without stall_steps its checks would never run (docs/paths.md).\nstall_steps = 30000\nmax_splits_per_check = 1\n# Ours (session 33): no split at the ends of the idealised load strip and clamp (header).\nintact = [\"lift_zone\", \"base_end\"]\n\n"
    t += '[cracking.criterion]\ntype = "rankine"\ntensile_strength = 2.7e6\n\n'
    t += f'[cracking.separation]\ntype = "tip_mts"   # ours (issue 34)\nshield_length = {SHIELD}   # ours (session 27): no new crack within 40 mm of a crack\n'
    t += "every = 2.0   # ours (session 33): the direction evaluated again after two domain radii of straight crack (docs/paths.md)\n\n"
    t += '[output]\nhistory_every = 5000\nreactions = ["lift"]\n\n'
    levels = [round(0.025 * k, 3) for k in range(1, 5)] + [round(0.1 + 0.02 * k, 3) for k in range(1, 11)] + [0.35, 0.4]
    for k, v in enumerate(levels):
        t += f'[[stage]]\nname = "u{k + 1}"\nlevels = {{ lift = {v} }}\nmax_steps = 300000\n\n'
    with open(os.path.join(HERE, name + ".toml"), "w") as f:
        f.write(t)


def count(kind, name, h=None, n=None):
    """The number of 2-D elements of the .msh file written before (gmsh 4.1 ASCII)."""
    with open(os.path.join(HERE, name + ".msh")) as f:
        lines = iter(f.read().splitlines())
    for line in lines:
        if line == "$Elements":
            nblocks = int(next(lines).split()[0])
            ne = 0
            for _ in range(nblocks):
                dim, _tag, _typ, k = (int(v) for v in next(lines).split())
                for _ in range(k):
                    next(lines)
                ne += k if dim == 2 else 0
            return ne
    raise SystemExit(f"{name}.msh: no $Elements section")


def main():
    os.makedirs(HERE, exist_ok=True)
    scenes_only = "--scenes" in sys.argv[1:]
    write_or_count = count if scenes_only else write
    for i, h in SIZES.items():
        for kind in ("t3", "quad"):
            ne = write_or_count(kind, f"lpanel_{kind}_{i}", h=h)
            scene(kind, i, ne, h)
            print(kind, i, ne)
        n = Q4_N[i]
        ne = write_or_count("q4", f"lpanel_q4_{i}", n=n)
        scene("q4", i, ne, 0.25 / n)
        print("q4", i, ne)
    if not scenes_only:
        ne = write("t3", "lpanel_t3_test", h=0.025)
        print("test", ne)


if __name__ == "__main__":
    sys.exit(main())
