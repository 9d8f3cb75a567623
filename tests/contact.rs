//! Contact and co-rotational kinematics (issue 4). Every test names its reference and
//! tolerance.
use flem_core::contact::Master;
use flem_core::plugin::damping::Damping;
use flem_core::solver::{NoOutput, Simulation};
use flem_plugins::snippets::toml_blocks;

use crate::common::sim;

/// Switches the solver's damping off (for the dynamic part of a test).
fn undamped(s: &mut Simulation) {
    let d: Box<dyn Damping> = toml::from_str(r#"type = "none""#).unwrap();
    s.scene.file.solver.damping = Some(d);
}

/// Clusters of a node set (before any split cluster id == point id).
fn clusters(s: &Simulation, set: &str) -> Vec<usize> {
    s.model.node_set(set, "test", "test").unwrap().iter().flat_map(|p| s.model.topo.point_clusters[p.idx()].iter().map(|c| c.idx())).collect()
}

/// Gives the clusters `cs` the velocity `v` and credits the kinetic energy to the ledger as
/// work done on the body (the divergence guard compares against it).
fn launch(s: &mut Simulation, cs: &[usize], v: [f64; 2]) {
    for &c in cs {
        s.ledger.external_work += 0.5 * s.state.mass[c] * (v[0] * v[0] + v[1] * v[1] - s.state.v[c][0].powi(2) - s.state.v[c][1].powi(2));
        s.state.v[c] = v;
    }
}

/// Mass-weighted mean of a per-cluster vector over `cs`.
fn mean(s: &Simulation, cs: &[usize], f: &[[f64; 2]]) -> [f64; 2] {
    let (mut m, mut acc) = (0.0, [0.0; 2]);
    for &c in cs {
        m += s.state.mass[c];
        acc[0] += s.state.mass[c] * f[c][0];
        acc[1] += s.state.mass[c] * f[c][1];
    }
    [acc[0] / m, acc[1] / m]
}

/// Steps for a duration `t`.
fn run_for(s: &mut Simulation, t: f64) {
    steps(s, (t / s.dt).round() as usize);
}

fn steps(s: &mut Simulation, n: usize) {
    for _ in 0..n {
        s.step().unwrap_or_else(|e| panic!("{e}"));
    }
}

/// Runs the scene's stages and asserts that the first one converged.
fn run_converged(s: &mut Simulation) {
    s.run(&mut NoOutput).unwrap();
    assert!(s.stages_done[0].converged, "{:?}", s.stages_done);
}

/// Current position x0 + u of cluster `c`.
fn pos(s: &Simulation, c: usize) -> [f64; 2] {
    [s.x0[c][0] + s.state.u[c][0], s.x0[c][1] + s.state.u[c][1]]
}

/// Kinetic + strain + contact-spring energy (what a free, undamped system conserves).
fn energy(s: &Simulation) -> f64 {
    let l = &s.ledger;
    l.kinetic + l.strain + l.contact_energy
}

/// (index in its block, mean stress) of every element, block after block.
fn element_stresses(s: &Simulation) -> impl Iterator<Item = (usize, [f64; 3])> + '_ {
    s.model.blocks.iter().flat_map(move |b| (0..b.len()).map(move |i| (i, b.mean_stress(i, &s.state.u))))
}

/// The 1 x 2 bar of 4 x 8 elements (E = 1000, nu = 0.25) whose mid-height grid line is the
/// cut `cut`, on rollers at the bottom and pinned at the bottom-left corner; `rest` adds the
/// contact law, the solver settings, the load and the stage.
fn cut_bar(rest: &str) -> Simulation {
    sim(&format!(
        r#"
[mesh]
type = "rectangle"
width = 1.0
height = 2.0
nx = 4
ny = 8
cuts = [1.0]

[[material]]
young_modulus = 1000.0
poisson_ratio = 0.25
density = 1.0

[[support]]
nodes = "bottom"
fix = "y"

[[support]]
nodes = "bottom_left"
fix = "xy"
{rest}"#
    ))
}

/// Two free 1-wide blocks `a` (at the origin) and `b` (at `b_origin`) of `height` with 4 x `ny`
/// elements (E = 1e4, nu = 0.25), with the contact settings `contact`, no gravity and no damping.
/// Runs the single one-step dynamic stage (the tests then step by hand) and returns the
/// simulation with the clusters of a and of b.
fn free_blocks(height: f64, ny: usize, b_origin: [f64; 2], corotational: bool, contact: &str) -> (Simulation, Vec<usize>, Vec<usize>) {
    let mut s = sim(&format!(
        r#"
[mesh]
type = "rectangles"
parts = [
  {{ name = "a", origin = [0.0, 0.0], width = 1.0, height = {height}, nx = 4, ny = {ny} }},
  {{ name = "b", origin = {b_origin:?}, width = 1.0, height = {height}, nx = 4, ny = {ny} }},
]

[[material]]
young_modulus = 1e4
poisson_ratio = 0.25
density = 1.0
corotational = {corotational}

[contact]
{contact}

[solver]
dt_safety = 0.5

[solver.damping]
type = "none"

[[stage]]
dynamic = true
max_steps = 1
"#
    ));
    s.run_stage(0, &mut NoOutput).unwrap();
    let (a, b) = (clusters(&s, "a_all"), clusters(&s, "b_all"));
    (s, a, b)
}

/// A pre-cut specimen (the paper's shear model has a pre-cut plane): a rectangle whose
/// mid-height grid line is separated over the whole width, pressed on top. The cut closes
/// (the gap is the contact-spring compression only) and transmits the pressure: every
/// element above and below the cut carries s_yy = -p, s_xx = 0.
/// Paper's contact law (spring_dashpot, mu = 0.577 of Table 1; friction also holds the upper
/// half, which is otherwise free to slide sideways).
/// Reference: uniaxial compression, s_yy = -p exactly for linear Q4 with the two halves in
/// conforming contact; tolerance 0.5 % of p (equilibrium tolerance 1e-6 and the springs).
#[test]
fn precut_specimen_closes_and_transmits_compression() {
    let mut s = cut_bar(
        r#"
[model]
separated = ["cut"]

[contact]
law = { type = "spring_dashpot", normal_stiffness = 1e5, shear_stiffness = 4e4, friction = 0.577 }

[solver]
tolerance = 1e-6
max_steps = 200000

[[load]]
name = "p"
type = "pressure"
edges = "top"
value = 2.0

[[stage]]
levels = { p = 1.0 }
"#,
    );
    assert_eq!(s.model.topo.n_clusters(), 45 + 5, "the cut line must be split into two rows of clusters");
    run_converged(&mut s);
    let p = 2.0;
    for (i, st) in element_stresses(&s) {
        assert!((st[1] + p).abs() < 5e-3 * p, "element {i}: s_yy = {} (want {})", st[1], -p);
        assert!(st[0].abs() < 5e-3 * p && st[2].abs() < 5e-3 * p, "element {i}: {st:?}");
    }
    // The two faces of the cut overlap by the spring compression only: p / (2 k_n) (two
    // passes), i.e. 1e-5 here; nothing passes through.
    let ymid: Vec<f64> = (0..s.x0.len()).filter(|&c| (s.x0[c][1] - 1.0).abs() < 1e-12).map(|c| pos(&s, c)[1]).collect();
    let (lo, hi) = ymid.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &y| (a.min(y), b.max(y)));
    assert!(hi - lo < 2.0 * p / 1e5, "overlap {}", hi - lo);
    assert!(s.contact.as_ref().unwrap().n_active >= 10);
}

/// Blocks on the fixed block `base` (`parts`: the lines of the `rectangles` mesh) under
/// gravity 10, E = 1e5, nu = 0.25, local damping; `solver` adds to `[solver]`, `rest` gives
/// the contact and stage tables.
fn on_fixed_base(parts: &str, solver: &str, rest: &str) -> Simulation {
    sim(&format!(
        r#"
[mesh]
type = "rectangles"
parts = [
{parts}
]

[model]
gravity = [0.0, -10.0]

[[material]]
young_modulus = 1e5
poisson_ratio = 0.25
density = 1.0

[solver]
{solver}

[solver.damping]
type = "local"

[[support]]
nodes = "base_all"
fix = "xy"
{rest}"#
    ))
}

/// A block on a fixed base, for the friction tests.
fn block_on_base(law: &str, base_width: f64, block_x: f64) -> Simulation {
    let nb = (base_width * 4.0).round() as usize;
    let parts = format!(
        r#"  {{ name = "base", origin = [0.0, 0.0], width = {base_width}, height = 0.5, nx = {nb}, ny = 2 }},
  {{ name = "block", origin = [{block_x}, 0.5000001], width = 1.0, height = 0.5, nx = 4, ny = 2 }},"#
    );
    let rest = format!(
        r#"
[contact]
law = {law}
surfaces = ["block_bottom", "base_top"]

[[stage]]
name = "settle"

[[stage]]
name = "go"
dynamic = true
max_steps = 1
"#
    );
    on_fixed_base(&parts, "tolerance = 1e-5\nmax_steps = 40000", &rest)
}

const FRICTION_LAW: &str = r#"{ type = "spring_dashpot", normal_stiffness = 1e6, shear_stiffness = 4e5, normal_damping = 300.0, shear_damping = 300.0, friction = 0.5 }"#;

/// Settles the block under vertical gravity, then tilts gravity by `theta` and switches damping
/// off; returns the simulation at the start of the motion.
fn incline(theta_deg: f64) -> Simulation {
    let mut s = block_on_base(FRICTION_LAW, 6.0, 0.5);
    s.run_stage(0, &mut NoOutput).unwrap();
    assert!(s.stages_done[0].converged, "{:?}", s.stages_done);
    let th = theta_deg.to_radians();
    s.loads.gravity = [10.0 * th.sin(), -10.0 * th.cos()];
    undamped(&mut s);
    s.run_stage(1, &mut NoOutput).unwrap();
    s
}

/// A block on an incline (gravity tilted by theta, mu = 0.5) sticks when tan(theta) < mu:
/// at 20 degrees (tan = 0.364) it moves less than 1e-4 (the tangential springs' elastic
/// deflection) in 0.5 s, where sliding at g (sin - mu cos) would cover 0.5 x 0.4 x 0.25.
/// Reference: Coulomb's law; tolerance 1e-4 (length).
#[test]
fn block_on_incline_sticks_below_the_friction_angle() {
    let mut s = incline(20.0);
    let blk = clusters(&s, "block_all");
    let u0 = mean(&s, &blk, &s.state.u);
    run_for(&mut s, 0.5);
    let u1 = mean(&s, &blk, &s.state.u);
    assert!((u1[0] - u0[0]).abs() < 1e-4, "the block moved {} along the incline", u1[0] - u0[0]);
}

/// A block on an incline slides when tan(theta) > mu, with a = g (sin(theta) - mu cos(theta))
/// = 1.640 at 35 degrees, mu = 0.5. Measured from the mass-weighted mean velocity between
/// 0.1 s and 0.6 s of sliding. Reference: rigid-block dynamics with Coulomb friction;
/// tolerance 2 %.
#[test]
fn block_on_incline_slides_with_the_coulomb_acceleration() {
    let mut s = incline(35.0);
    let blk = clusters(&s, "block_all");
    run_for(&mut s, 0.1);
    let (t1, v1) = (s.state.time, mean(&s, &blk, &s.state.v)[0]);
    run_for(&mut s, 0.5);
    let (t2, v2) = (s.state.time, mean(&s, &blk, &s.state.v)[0]);
    let th = 35f64.to_radians();
    let want = 10.0 * (th.sin() - 0.5 * th.cos());
    let a = (v2 - v1) / (t2 - t1);
    eprintln!("incline: a = {a:.5}, want {want:.5} (error {:.2} %)", 100.0 * (a - want).abs() / want);
    assert!((a - want).abs() < 0.02 * want, "a = {a}, want {want}");
}

/// A block launched at v0 = 2 on a base with mu = 0.5, g = 10 stops after
/// v0^2 / (2 mu g) = 0.4, without toppling (its top corners stay level) and without jitter
/// (0.2 s later it has not moved by more than 1e-4 and its speed is below 1e-3).
/// Reference: rigid-block dynamics with Coulomb friction; tolerance 3 % of the distance.
#[test]
fn sliding_block_stops_at_the_coulomb_distance() {
    let mut s = block_on_base(FRICTION_LAW, 3.0, 0.25);
    s.run_stage(0, &mut NoOutput).unwrap();
    undamped(&mut s);
    s.run_stage(1, &mut NoOutput).unwrap();
    let blk = clusters(&s, "block_all");
    launch(&mut s, &blk, [2.0, 0.0]);
    let u0 = mean(&s, &blk, &s.state.u);
    run_for(&mut s, 0.6);
    let u1 = mean(&s, &blk, &s.state.u);
    let d = u1[0] - u0[0];
    eprintln!("sliding block: stopped after {d:.5}, want 0.4 (error {:.2} %)", 100.0 * (d - 0.4).abs() / 0.4);
    assert!((d - 0.4).abs() < 0.03 * 0.4, "stopped after {d}, want 0.4");
    let (tl, tr) = (clusters(&s, "block_top_left")[0], clusters(&s, "block_top_right")[0]);
    assert!((s.state.u[tl][1] - s.state.u[tr][1]).abs() < 1e-3, "the block tilted: {} vs {}", s.state.u[tl][1], s.state.u[tr][1]);
    run_for(&mut s, 0.2);
    let u2 = mean(&s, &blk, &s.state.u);
    let v2 = mean(&s, &blk, &s.state.v);
    assert!((u2[0] - u1[0]).abs() < 1e-4 && v2[0].abs() < 1e-3, "jitter after stopping: moved {}, v {}", u2[0] - u1[0], v2[0]);
}

/// Two free blocks, A moving at v0 = 1 towards B at rest, penalty contact without friction or
/// dashpots, no damping, no gravity: total energy (kinetic + strain + contact springs) stays
/// within 1 % of 1/2 M v0^2 through and after the impact, and momentum is conserved to
/// round-off (1e-12 relative); afterwards B moves away.
/// Reference: conservation laws; tolerances 1 % and 1e-12.
#[test]
fn collision_conserves_energy_and_momentum() {
    let law = "law = { type = \"penalty\", normal_stiffness = 1e5 }\nsurfaces = [\"a_right\", \"b_left\"]";
    let (mut s, a, b) = free_blocks(0.5, 2, [1.05, 0.0], false, law);
    launch(&mut s, &a, [1.0, 0.0]);
    let mtot: f64 = s.state.mass.iter().sum();
    let ma: f64 = a.iter().map(|&c| s.state.mass[c]).sum();
    let e0 = 0.5 * ma;
    let p0 = ma;
    let n = (0.5 / s.dt) as usize;
    let mut emax: f64 = 0.0;
    for k in 0..n {
        s.step().unwrap();
        if k > 2 {
            let e = energy(&s);
            emax = emax.max((e - e0).abs() / e0);
            let p: f64 = s.state.v.iter().zip(&s.state.mass).map(|(v, m)| m * v[0]).sum();
            assert!((p - p0).abs() < 1e-12 * p0, "momentum {p} vs {p0}");
        }
    }
    eprintln!("collision: largest energy drift {:.3} %", 100.0 * emax);
    assert!(emax < 0.01, "energy drift {emax}");
    let vb = mean(&s, &b, &s.state.v)[0];
    assert!(vb > 0.8 && s.contact.as_ref().unwrap().n_active == 0, "B moves at {vb} after the impact (mass {mtot})");
}

/// Three blocks stacked on a fixed base under gravity come to rest with the analytic contact
/// forces: the upward contact force on the bottom face of block k is the weight of the blocks
/// from k up (0.5 x 10 per block), shared between its interior nodes by tributary length.
/// (At the ends of a contact zone the two-pass node-to-edge split differs from the tributary
/// share: under a block corner the base node has a full tributary length but only half of it
/// is covered; the end nodes are therefore checked through the total only.)
/// Reference: statics; tolerance 0.5 % on the totals, 5 % per interior node.
#[test]
fn stack_of_blocks_rests_with_the_static_contact_forces() {
    let parts = r#"  { name = "base", origin = [-0.5, 0.0], width = 2.0, height = 0.5, nx = 8, ny = 2 },
  { name = "b1", origin = [0.0, 0.5000001], width = 1.0, height = 0.5, nx = 4, ny = 2 },
  { name = "b2", origin = [0.0, 1.0000002], width = 1.0, height = 0.5, nx = 4, ny = 2 },
  { name = "b3", origin = [0.0, 1.5000003], width = 1.0, height = 0.5, nx = 4, ny = 2 },"#;
    let rest = r#"
[contact]
law = { type = "spring_dashpot", normal_stiffness = 1e6, shear_stiffness = 4e5, friction = 0.5 }
surfaces = ["base_top", "b1_bottom", "b1_top", "b2_bottom", "b2_top", "b3_bottom"]

[[stage]]
"#;
    let mut s = on_fixed_base(parts, "tolerance = 1e-7", rest);
    run_converged(&mut s);
    for (k, name) in ["b1", "b2", "b3"].iter().enumerate() {
        let bottom = clusters(&s, &format!("{name}_bottom"));
        let total: f64 = bottom.iter().map(|&c| s.state.f_con[c][1]).sum();
        let want = (3 - k) as f64 * 0.5 * 10.0;
        assert!((total - want).abs() < 5e-3 * want, "{name}: contact force {total}, want {want}");
        for &c in &bottom {
            let x = s.x0[c][0];
            if x.abs() < 1e-9 || (x - 1.0).abs() < 1e-9 {
                continue;
            }
            let share = 0.25;
            let f = s.state.f_con[c][1];
            assert!((f - want * share).abs() < 0.05 * want * share, "{name} node at x = {x}: {f}, want {}", want * share);
        }
    }
}

/// Corner-to-corner contact: block A moves diagonally at (1, 1) so that its top-right corner
/// meets the bottom-left corner of block B exactly (co-rotational blocks: the impact spins
/// them). No node of one block ends inside the other by more than 2 % of the element size, nothing blows up (energy stays within 2 % of the
/// initial kinetic energy, penalty without friction) and the blocks separate.
/// Reference: impenetrability and energy conservation; tolerances 2 % (corner impacts are
/// the least smooth events of a penalty method).
#[test]
fn corner_to_corner_contact_neither_penetrates_nor_blows_up() {
    let law = "law = { type = \"penalty\", normal_stiffness = 1e6 }\nboundary = true";
    let (mut s, a, b) = free_blocks(1.0, 4, [1.05, 1.05], true, law);
    launch(&mut s, &a, [1.0, 1.0]);
    let e0: f64 = a.iter().map(|&c| s.state.mass[c]).sum::<f64>();
    let corner = |s: &Simulation, p: &str| ["bottom_left", "bottom_right", "top_right", "top_left"].map(|k| clusters(s, &format!("{p}_{k}"))[0]);
    let (corners_a, corners_b) = (corner(&s, "a"), corner(&s, "b"));
    let mut worst: f64 = 0.0;
    let mut touched = false;
    for _ in 0..(0.4 / s.dt) as usize {
        s.step().unwrap();
        touched |= s.contact.as_ref().unwrap().n_active > 0;
        // Penetration of a's nodes into b's box and of b's into a's (both rigid-ish squares).
        // Depth of every node of one block inside the other (its current corners as a convex
        // quadrilateral, counter-clockwise: the blocks rotate after an off-centre impact).
        for (p, q) in [(&a, &corners_b), (&b, &corners_a)] {
            let poly: Vec<[f64; 2]> = q.iter().map(|&c| pos(&s, c)).collect();
            for &c in p.iter() {
                let y = pos(&s, c);
                let mut depth = f64::INFINITY;
                for k in 0..4 {
                    let (e0, e1) = (poly[k], poly[(k + 1) % 4]);
                    let (dx, dy) = (e1[0] - e0[0], e1[1] - e0[1]);
                    let len = (dx * dx + dy * dy).sqrt();
                    depth = depth.min(((y[0] - e0[0]) * -dy + (y[1] - e0[1]) * dx) / len);
                }
                worst = worst.max(depth);
            }
        }
        let e = energy(&s);
        assert!(e.is_finite() && e < 1.02 * e0, "energy {e} vs {e0}");
    }
    assert!(touched, "the corners never met");
    eprintln!("corner to corner: worst penetration {worst:.3e} (element size 0.25)");
    assert!(worst < 0.02 * 0.25, "penetration {worst}");
    assert!(s.contact.as_ref().unwrap().forces().iter().all(|p| matches!(p.master, Master::Face(_) | Master::Node(_))));
}

/// A body rotated rigidly by 90 degrees carries no stress with `corotational = true`
/// (below 1e-9 E in every element and at every corner) and no internal force, while the linear
/// kernel sees a strain of order 1. Reference: rigid-body motion is stress free; 1e-9 E.
#[test]
fn corotational_body_rotated_by_90_degrees_is_stress_free() {
    let scene = |corot: bool| {
        format!(
            r#"
[mesh]
type = "rectangle"
width = 2.0
height = 1.0
nx = 4
ny = 2
origin = [0.3, -0.2]

[[material]]
young_modulus = 1000.0
poisson_ratio = 0.3
density = 1.0
corotational = {corot}

[[stage]]
"#
        )
    };
    for corot in [true, false] {
        let mut s = sim(&scene(corot));
        let c0 = [1.0, 0.5];
        for c in 0..s.x0.len() {
            let r = [s.x0[c][0] - c0[0], s.x0[c][1] - c0[1]];
            s.state.u[c] = [c0[0] - r[1] - s.x0[c][0] + 0.7, c0[1] + r[0] - s.x0[c][1] - 0.4];
        }
        let mut smax: f64 = 0.0;
        for (_, st) in element_stresses(&s) {
            smax = smax.max(st.iter().fold(0.0, |m: f64, v| m.max(v.abs())));
        }
        let (mut corner, mut nodal) = (Vec::new(), Vec::new());
        s.model.nodal_stress(&s.state.u, &mut corner, &mut nodal);
        smax = corner.iter().flatten().fold(smax, |m, v| m.max(v.abs()));
        let mut f = vec![[0.0; 2]; s.x0.len()];
        s.model.internal_forces(&s.state.u, &mut f);
        let fmax = f.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        if corot {
            assert!(smax < 1e-9 * 1000.0, "stress {smax}");
            assert!(fmax < 1e-9 * 1000.0, "force {fmax}");
            assert!(s.strain_energy().abs() < 1e-12, "energy {}", s.strain_energy());
        } else {
            assert!(smax > 0.1 * 1000.0, "the linear kernel should see the rotation: {smax}");
        }
    }
}

/// A spinning co-rotational body (free, no damping) keeps its kinetic + strain energy within
/// 1 % over a quarter turn, where the linear kernel's spurious stress would pump energy.
/// Reference: energy conservation of a free body; 1 %.
#[test]
fn corotational_spinning_body_conserves_energy() {
    let mut s = sim(r#"
[mesh]
type = "rectangle"
width = 1.0
height = 1.0
nx = 4
ny = 4
origin = [-0.5, -0.5]

[[material]]
young_modulus = 1e5
poisson_ratio = 0.3
density = 1.0
corotational = true

[solver.damping]
type = "none"

[[stage]]
dynamic = true
max_steps = 1
"#);
    s.run_stage(0, &mut NoOutput).unwrap();
    let w = 2.0;
    for c in 0..s.x0.len() {
        let v = [-w * s.x0[c][1], w * s.x0[c][0]];
        launch(&mut s, &[c], v);
    }
    let e0: f64 = (0..s.x0.len()).map(|c| 0.5 * s.state.mass[c] * w * w * (s.x0[c][0].powi(2) + s.x0[c][1].powi(2))).sum();
    let n = (std::f64::consts::FRAC_PI_2 / w / s.dt) as usize;
    steps(&mut s, n);
    let e = s.ledger.kinetic + s.ledger.strain;
    assert!((e - e0).abs() < 0.01 * e0, "energy {e} vs {e0}");
    // A quarter turn: the point at (0.5, 0) is near (0, 0.5) (centrifugal stretch aside).
    let c = (0..s.x0.len()).find(|&c| (s.x0[c][0] - 0.5).abs() < 1e-12 && s.x0[c][1].abs() < 1e-12).unwrap();
    let x = pos(&s, c);
    assert!(x[0].abs() < 0.02 && (x[1] - 0.5).abs() < 0.02, "{x:?}");
}

/// The ```toml snippets of the `[contact]` docs (core/src/contact/mod.rs) and of the
/// `rectangles` mesh source parse, validate and build a runnable scene (the docs cannot drift
/// from the code). Reference: the docs; exact.
#[test]
fn contact_and_rectangles_doc_snippets_build_a_scene() {
    let mesh = &toml_blocks(include_str!("../core/src/mesh/rects.rs"))[0];
    let contact = &toml_blocks(include_str!("../core/src/contact/mod.rs"))[0];
    let text = format!("{mesh}\n{contact}\n[[material]]\nyoung_modulus = 1e4\npoisson_ratio = 0.25\ndensity = 1.0\n\n[[stage]]\n");
    let s = sim(&text);
    assert_eq!(s.contact.as_ref().unwrap().n_surface_nodes(), 17 + 5);
}

/// The ```toml snippets of the contact laws' docs (plugins/src/contact/*.rs: the `[contact]`
/// tables of `cohesive` with each softening, `penalty`, `spring_dashpot` in both forms) build a
/// scene with the `rectangles` mesh of the docs, and a law's `softening` key is the one the
/// snippet names in the resolved scene. (The plugins' unit test
/// `doc_toml_snippets_parse_and_validate` parses and validates the laws alone; session 32 adds
/// the scene and the key's round trip.) Reference: the docs; exact.
#[test]
fn contact_law_doc_snippets_build_a_scene() {
    let mesh = &toml_blocks(include_str!("../core/src/mesh/rects.rs"))[0];
    let docs = [
        include_str!("../plugins/src/contact/cohesive.rs"),
        include_str!("../plugins/src/contact/penalty.rs"),
        include_str!("../plugins/src/contact/spring_dashpot.rs"),
        include_str!("../plugins/src/contact/mod.rs"),
    ];
    let mut n = 0;
    for doc in docs {
        for block in toml_blocks(doc).iter().filter(|b| b.contains("[contact")) {
            let text = format!("{mesh}\n{block}\n[[material]]\nyoung_modulus = 1e4\npoisson_ratio = 0.25\ndensity = 1.0\n\n[[stage]]\n");
            let s = sim(&text);
            assert!(s.contact.is_some(), "{block}");
            let resolved = toml::to_string(&s.scene.file).unwrap();
            for soft in ["petersson", "cornelissen"] {
                assert_eq!(block.contains(soft), resolved.contains(&format!("softening = \"{soft}\"")), "{soft} in {block}");
            }
            n += 1;
        }
    }
    assert_eq!(n, 6, "the six [contact] snippets of the three laws");
}

/// A bar cut across at mid-height during the run (the split is applied through the same path
/// as a cracking check) with the cohesive law: the fresh faces carry tension. Below the
/// strength (0.3 sigma_t, so that even the dynamic overshoot of the suddenly applied load stays
/// elastic) the bar reaches equilibrium with s_yy = 0.3 sigma_t on both sides and an opening of
/// 0.3 delta_0 = 0.3 sigma_t / k_n; at 1.5 sigma_t the faces soften, open beyond
/// delta_f = 2 G_f / sigma_t and the pairs are dropped.
/// Reference: statics and the cohesive envelope; tolerance 1 % (equilibrium ratio 1e-9; an
/// earlier version stalled near 4e-6 here).
#[test]
fn cohesive_fresh_faces_carry_tension_then_fail() {
    let rest = |level: f64| {
        format!(
            r#"
[contact]
law = {{ type = "cohesive", normal_stiffness = 1e5, shear_stiffness = 4e4, tensile_strength = 1.0, fracture_energy = 0.01, friction = 0.5 }}

[solver]
tolerance = 1e-9
max_steps = 100000

[[load]]
name = "pull"
type = "traction"
edges = "top"
value = [0.0, {level}]

[[stage]]
levels = {{ pull = 1.0 }}
"#
        )
    };
    for level in [0.3, 1.5] {
        let mut s = cut_bar(&rest(level));
        let edges = s.model.edge_set("cut", "test", "test").unwrap();
        let rec = s.model.topo.separate_edges(&edges);
        s.model.apply_record(&rec);
        s.apply_split_record(&rec);
        // Cohesion per face end (issue 36, session 17): 4 cut edges, both ends separated.
        let c = s.contact.as_ref().unwrap();
        assert_eq!(c.bonds.len(), 8, "one cohesive bond per end of each cut edge");
        assert!(c.history.pairs.iter().all(|p| !p.state.fresh), "no cohesive pair besides the bonds");
        if level < 1.0 {
            run_converged(&mut s);
            for (i, st) in element_stresses(&s) {
                assert!((st[1] - level).abs() < 0.01 * level, "element {i}: s_yy = {}", st[1]);
            }
            let c = s.contact.as_ref().unwrap();
            assert_eq!(c.n_active, 8);
            for p in c.forces() {
                assert!((p.gap - level * 1e-5).abs() < 0.01 * level * 1e-5, "opening {}", p.gap);
            }
        } else {
            undamped(&mut s);
            s.scene.file.stages[0].dynamic = true;
            s.scene.file.stages[0].max_steps = Some(20000);
            s.run(&mut NoOutput).unwrap();
            let top = clusters(&s, "top");
            let uy = mean(&s, &top, &s.state.u)[1];
            assert!(uy > 0.02, "the cut did not open: {uy}");
            assert!(s.contact.as_ref().unwrap().history.pairs.iter().all(|p| !p.state.fresh || p.state.max_open < 0.02), "failed pairs must be dropped");
            assert!(s.contact.as_ref().unwrap().bonds.is_empty(), "failed bonds must be dropped");
            assert_eq!(s.contact.as_ref().unwrap().n_active, 0);
        }
    }
}

/// The peers' side-notched plate (configs/bench/notch_q4_h0.25_contact.toml: 2280 Q4, pulled
/// at the top, undamped, Rankine checked every step) with cohesive contact on the crack faces
/// created by node splitting. Reference: central differences with a conservative contact law
/// keep the energy balance W_ext = KE + U + E_contact + D_contact (METHOD section 6; the run
/// without contact closes it to 1e-14): after 4000 steps no energy created (signed residual
/// above -1e-3 of the work) and relative residual below 5e-4. History of the residual, all energy
/// lost: session 3 measured 3.5e-3 at dt_safety 0.5, but the same code gave 3.6e-2 to 5.0e-2 at
/// dt_safety 0.45, 0.49, 0.51; session 4 (no spring born at a full earlier overlap) 3.6e-2 to
/// 4.8e-2 at 0.45-0.51. Session 5 measured where it came from, per pair and step (the pair's
/// trapezoidal work + change of stored + dissipated, at 0.5, of the 7.9e-4 lost): contacts born
/// from an open gap -7.3e-4 (the step's whole approach is credited 1/2 N |dgap|, the spring
/// stores 1/2 N |gap|), releases +3.5e-4, Coulomb slip counted as a rectangle -3.1e-4, splits
/// shrinking the area of cohesive pairs -1.5e-4, the cohesive peak +4.8e-5 (trapezoid across a
/// concave kink); the `cohesive` law now counts each of these (its doc), and the residual is
/// 8.4e-5, 5.1e-5, 7.9e-5, 1.1e-5 at dt_safety 0.45, 0.49, 0.5, 0.51 (still lost: frames turning
/// over a step, pairs changing master). The cohesive faces release at least G_c x the 9 cm
/// ligament and at most G_c x the faces made, and the fracture account closes (session 17). The crack stays a crack: every new node lies in the band y = 5.75 +- 1.5 of the
/// notch, and there are at most 4 x the splits of the same run without contact (41; the
/// cohesive zone makes the tip branch, 119 splits). Before the fix the run diverged at step
/// 2923 (pairs created at the already-open end of a re-cut edge with an empty history, pairs
/// of a node at a crack-branch vertex against the faces meeting there, history carried to the
/// wrong cluster after a split, cohesive areas jumping when a branch added faces at a node);
/// with dt_safety 0.25 it shattered the plate (2729 splits) with a residual of 1.0.
#[test]
fn dynamic_crack_with_cohesive_contact_keeps_the_energy_balance() {
    let text = std::fs::read_to_string(crate::common::root().join("configs/bench/notch_q4_h0.25_contact.toml")).unwrap().replace("\"../meshes/", "\"meshes/");
    let without: String = text.lines().filter(|l| !l.starts_with("[contact]") && !l.starts_with("law = {")).collect::<Vec<_>>().join("\n");
    let splits = |s: &Simulation| s.model.topo.n_clusters() - s.model.mesh.points.len();
    let mut bare = sim(&without);
    assert!(bare.contact.is_none());
    bare.run(&mut NoOutput).unwrap_or_else(|e| panic!("without contact: {e}"));
    let n_bare = splits(&bare);
    let mut s = sim(&text);
    assert!(s.contact.is_some());
    s.run(&mut NoOutput).unwrap_or_else(|e| panic!("with contact: {e}"));
    let n = splits(&s);
    let res = s.ledger.relative_residual();
    let topo = &s.model.topo;
    let far = (s.model.mesh.points.len()..topo.n_clusters()).map(|c| s.model.mesh.points[topo.cluster_point[c].idx()]).filter(|p| (p[1] - 5.75).abs() > 1.5).count();
    let released = s.ledger.contact_dissipated;
    println!("splits: {n} with contact, {n_bare} without; energy residual {res:.3e} (without contact {:.3e}); new nodes off the crack band: {far}; energy dissipated by the contact law {released:.4e} (G_c x ligament {:.4e})", bare.ledger.relative_residual(), 0.001 * 9.0);
    assert!(n_bare > 10, "the scene no longer cracks without contact ({n_bare} splits)");
    assert!(s.ledger.residual() > -1e-3 * s.ledger.external().abs(), "energy created: residual {:.3e} of work {:.3e}", s.ledger.residual(), s.ledger.external());
    assert!(res < 5e-4, "energy residual {res:.3e} with contact");
    assert!(n <= 4 * n_bare, "{n} splits with contact, {n_bare} without");
    assert!(far <= 1, "{far} new nodes away from the notch's crack band");
    // The contact law really worked the crack faces: separating the plate through its 9 cm
    // ligament releases at least G_c x ligament = 0.009 (Griffith; Akantu's cohesive run of the
    // same plate: 0.0096), and at most G_c x the faces made (each face releases G_c per area
    // once). Since session 17 every cut face end carries its own cohesion (issue 36): the
    // fracture energy is 1.10e-2 (8.8e-3 before, when faces at junctions and at re-split nodes
    // came free without their cohesion: the account's identity error was -0.25), 1.22 x G_c x
    // ligament; the law's whole dissipation (slip, kinks, shear release besides) 1.24e-2. The
    // fracture account must close (fracture = G_c (free + softening) - pending, module doc of
    // `contact`): 1e-9. Caveat (session 5 review): the kink terms are the explicit scheme's
    // O(dt) error at the law's kinks, of both signs, gross 5-6 % of the work, booked as
    // dissipation, so the "no energy created" assert above does not see them; the law itself is
    // held by its unit test (work = stored + dissipated; a 10 % error in the fracture energy
    // fails it and gives a residual of 5e-2 here).
    let fracture = s.ledger.fracture;
    let c = s.contact.as_ref().unwrap();
    let law = s.scene.file.contact.as_ref().unwrap().law.as_ref();
    let (faces, [intact, soft, pending]) = (c.fresh_face_area(&s.model), c.zones(law));
    let free = faces - intact - soft;
    println!("fracture {fracture:.4e}; faces {faces}, free {free}, softening {soft}, intact {intact}, pending {pending:.4e}");
    assert!((0.009..=0.001 * faces).contains(&fracture), "fracture energy {fracture:.4e} against G_c x ligament 9e-3 and G_c x faces made {:.4e}", 0.001 * faces);
    assert!(released >= fracture, "the law's dissipation {released:.4e} holds its fracture energy {fracture:.4e}");
    let expect = 0.001 * (free + soft) - pending;
    assert!((fracture - expect).abs() < 1e-9 * fracture, "fracture account: {fracture:.9e} against G_c (free + softening) - pending = {expect:.9e}");
}

/// The paper's direct shear box (tests/data/direct_shear_contact.toml, a copy of
/// configs/paper/direct_shear_steps.toml: 21 quads + 1 triangle, co-rotational, spring_dashpot on
/// crack faces and on the pre-separated bc, shear-only Mohr-Coulomb, q then p = 20 ... 400
/// rho g, each stage to equilibrium). From p = 180 on, nodes split while their faces are pressed
/// together and sheared: pairs switch masters at the junctions of cracks, and splits halve the
/// area of pairs that carry load. Reference: energy conservation of central differences with a
/// contact law whose dashpots are zero (METHOD section 6: no energy may be created),
/// W_ext = KE + U + D_damping + E_contact + D_contact; relative residual below 1e-3 at the end of
/// every stage (tests/paper.rs allows 1e-2), and no stage may end with more than 1e-3 of
/// energy created (signed residual). Measured before the fix: 0.23 at p = 180 (energy created:
/// a pair born 6.3e-2 deep, behind the face of a column its slave had been sliding under, took
/// the whole overlap as spring compression, 3.2e4 erg from nothing), 0.031 at p = 260 (a split
/// halved a loaded pair's area and kept its force: twice the energy); after: at most 1.3e-3, and
/// 1.6e-4 since spring_dashpot's slip dissipation is the trapezoid (session 5).
#[test]
fn contact_between_faces_split_in_compression_creates_no_energy() {
    flem_plugins::link();
    let dir = crate::common::root().join("tests/data");
    let path = dir.join("direct_shear_contact.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let scene = flem_core::scene::Scene::from_str(&text, &path, &dir).unwrap_or_else(|e| panic!("{e}"));
    let mut s = Simulation::new(scene).unwrap_or_else(|e| panic!("{e}"));
    let n_points = s.model.mesh.points.len();
    let mut worst: f64 = 0.0;
    let mut created: f64 = 0.0;
    for i in 0..s.scene.file.stages.len() {
        s.run_stage(i, &mut NoOutput).unwrap();
        let l = &s.ledger;
        let rel = l.relative_residual();
        // Signed: W_ext - (...) < 0 is energy created.
        let signed = if rel > 0.0 { l.residual().signum() * rel } else { 0.0 };
        let st = s.stages_done.last().unwrap();
        println!(
            "direct shear {}: splits so far {}, in equilibrium {}, energy residual {signed:.2e} (contact stored {:.3e}, dissipated {:.3e})",
            st.name,
            s.model.topo.n_clusters() - n_points,
            st.converged,
            l.contact_energy,
            l.contact_dissipated
        );
        worst = worst.max(rel);
        created = created.max(-signed);
    }
    let splits = s.model.topo.n_clusters() - n_points;
    assert!(splits >= 12, "the scene no longer splits under compression ({splits} new nodes): the test does not test what it says");
    assert!(worst < 1e-3, "energy residual {worst:.3e}");
    assert!(created < 1e-3, "energy created: {created:.3e} of the work");
}
