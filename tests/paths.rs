//! Crack paths (issue 34, must-show 2, 4, 7; docs/paths.md): the kink of the new crack over its
//! first five element sizes with the path method (`tip_mts`, ours) against the maximum
//! tangential stress angle (Erdogan & Sih 1963), the default edge rule untouched, the node
//! relocation's bookkeeping (masses, refusals, checkpoints).
use flem_core::ids::PointId;
use flem_core::solver::{NoOutput, Simulation};
use flem_plugins::check::paths::{crack_faces, edge_cut_order, fragment_sizes, kinks, kinks_in_order, Kink};
use flem_plugins::check::sif::crack_tips;

use crate::common::{root, sim};

/// The scene `configs/paths/NAME.toml` as text for `common::scene` (paths against configs/),
/// with the separation rule `rule`.
fn text(name: &str, rule: &str) -> String {
    let t = std::fs::read_to_string(root().join(format!("configs/paths/{name}.toml"))).unwrap().replace("../meshes/", "meshes/");
    assert!(t.contains("type = \"sigma1_nearest\""), "{name}: the scene's rule changed: update the test");
    t.replace("type = \"sigma1_nearest\"", &format!("type = \"{rule}\""))
}

/// Runs the scene and measures the kink at every initial tip over 5 element sizes.
fn kink_run(name: &str, rule: &str) -> (Vec<Kink>, Simulation) {
    let mut s = sim(&text(name, rule));
    let tips = crack_tips(&s.model);
    let initial = crack_faces(&s.model);
    s.run(&mut NoOutput).unwrap_or_else(|e| panic!("{name}: {e}"));
    (kinks(&s.model, &tips, &initial, 5.0), s)
}

/// MTS kink (deg) of the closed forms: the centre crack at beta to uniaxial tension,
/// r = K_II / K_I = cot(beta); the shear test's pure mode II (K_I = 0): -2 atan(1/sqrt 2).
fn mts_deg(r: f64) -> f64 {
    (2.0 * (-2.0 * r / (1.0 + (1.0 + 8.0 * r * r).sqrt())).atan()).to_degrees()
}

/// Reference: Erdogan & Sih's maximum tangential stress angle from the closed-form K_I, K_II
/// (infinite plate; the implicit solution's factors on these meshes give the same angles within
/// 0.2 deg, docs/paths.md). Tolerance: 5 deg on the chord over five element sizes at every tip
/// (issue 34 must-show 2), on one mesh of each kind; no fragment below 3 elements, and every path
/// reaches the outer boundary (must-show 4; a centre crack stopped by `max_events = 80` before
/// session 34 ended inside the plate on `centre_60_quad_2`: the test fails with it).
/// The paper's edge rule misses by 17 to 49 deg on these meshes (docs/paths.md), so a method
/// that fell back to it would fail here.
#[test]
fn tip_mts_kinks_within_five_degrees() {
    let cases =
        [("centre_45_t3_1", mts_deg(1.0)), ("centre_60_quad_2", mts_deg(1.0 / 3f64.sqrt())), ("centre_30_q4_1", mts_deg(3f64.sqrt())), ("sen_q4_1", -2.0 * (1.0 / 2f64.sqrt()).atan().to_degrees())];
    for (name, mts) in cases {
        let (ks, s) = kink_run(name, "tip_mts");
        assert!(!ks.is_empty(), "{name}: no tip");
        for k in &ks {
            let c = k.chord_deg.unwrap_or(f64::NAN);
            assert!(k.reached && (c - mts).abs() <= 5.0, "{name}, tip {}: chord {c:.2} deg against MTS {mts:.2} (path {:.2} h)", k.tip_point, k.length / k.h);
            // Must-show 4: the events solver runs the path to the boundary (the plate's edge).
            assert!(k.boundary_at.is_some(), "{name}, tip {}: the path ends inside the body ({:.2} h long)", k.tip_point, k.length / k.h);
        }
        let small: Vec<usize> = fragment_sizes(&s.model).into_iter().filter(|&n| n < 3).collect();
        assert!(small.is_empty(), "{name}: fragments of {small:?} elements");
        assert!(!s.cracking.as_ref().unwrap().path.moves.is_empty(), "{name}: no node moved");
    }
}

/// The one setting of session 25 (`every = 1.25`, `piece = 0.05`, `shrink = 1.5`; ours) on the
/// coarse recombined quads: `centre_30_quad_1`, whose tips missed with the defaults (-6.9 and
/// -7.3 deg before session 25's finer move fractions, -5.2 and -5.6 after; -4.7 and -0.6 with
/// the setting), and `centre_60_quad_1`, the other angle on the same mesh (4.2 and 1.1 deg with
/// the defaults and with the setting; 3.0 and 2.2 before the finer fractions). Reference: Erdogan
/// & Sih's angle from the closed-form factors, as above; tolerance 5 deg on the chord over five
/// element sizes (must-show 2); no fragment below 3 elements. The margins are thin (4.7 and 4.2
/// against 5): the setting's first re-evaluation falls at 5 h, the edge of the window measured,
/// and the path turns there by a further 8-12.5 deg (docs/paths.md, "Session 25"); a failure here
/// after a change of the path method is read with that in mind.
#[test]
fn tip_mts_setting_kinks_on_the_coarse_quads() {
    let opts = "type = \"tip_mts\"\nevery = 1.25\npiece = 0.05\nshrink = 1.5";
    for (name, mts) in [("centre_30_quad_1", mts_deg(3f64.sqrt())), ("centre_60_quad_1", mts_deg(1.0 / 3f64.sqrt()))] {
        let mut s = sim(&text(name, "tip_mts").replace("type = \"tip_mts\"", opts));
        let tips = crack_tips(&s.model);
        let initial = crack_faces(&s.model);
        s.run(&mut NoOutput).unwrap_or_else(|e| panic!("{name}: {e}"));
        let ks = kinks(&s.model, &tips, &initial, 5.0);
        assert_eq!(ks.len(), 2, "{name}: tips");
        for k in &ks {
            let c = k.chord_deg.unwrap_or(f64::NAN);
            assert!(k.reached && (c - mts).abs() <= 5.0, "{name}, tip {}: chord {c:.2} deg against MTS {mts:.2}", k.tip_point);
        }
        assert!(fragment_sizes(&s.model).iter().all(|&n| n >= 3), "{name}: debris");
    }
}

/// x of the path's first crossing of the height `y` (linear along the segment).
fn x_at(path: &[[f64; 2]], y: f64) -> Option<f64> {
    path.windows(2).find(|w| (w[0][1] - y) * (w[1][1] - y) <= 0.0 && w[0][1] != w[1][1]).map(|w| w[0][0] + (y - w[0][1]) / (w[1][1] - w[0][1]) * (w[1][0] - w[0][0]))
}

/// Must-show 3 (in part): a staircase path is evaluated again. The shear test on the 40 x 40
/// grid (`sen_q4_2`, h = 0.025), whose moves are partial (no link near -70.5 deg). Reference:
/// the crack of the shear test curves away from its first kink line towards the clamped corner
/// (principle of local symmetry: a mode II crack kinks, then the new crack runs in mode I of the
/// new field); the straight MTS line from the tip (0.5, 0.5) crosses y = 0.1 at
/// x = 0.5 + 0.4 / tan 70.53 deg = 0.642. The finest T3 path crosses it at about 0.70
/// (docs/paths.md). With the staircase rule the path must cross more than 1.5 h (0.0375) right of
/// the line; with `staircase = 0` (the first version: a staircase tip never counts as on its line)
/// it stays on the line within 1 h (a staircase), which is what this test tells apart.
#[test]
fn tip_mts_staircase_path_turns() {
    let line = 0.5 + 0.4 / (2.0 * (1.0 / 2f64.sqrt()).atan()).tan();
    let x = |rule: &str| {
        let (ks, _) = kink_run("sen_q4_2", rule);
        let k = &ks[0];
        x_at(k.through(), 0.1).unwrap_or_else(|| panic!("{rule}: the path does not reach y = 0.1: {:?}", k.path))
    };
    let (on, off) = (x("tip_mts"), x("tip_mts\"\nstaircase = 0.0\n#\""));
    assert!(on - line > 1.5 * 0.025, "staircase rule: x = {on:.4} at y = 0.1, the straight line {line:.4}");
    assert!((off - line).abs() < 0.025, "staircase = 0: x = {off:.4} at y = 0.1, the straight line {line:.4}");
}

/// Must-show 7: the default rule (the paper's) leaves the path method's state empty and moves
/// no node (exact). Its kink on the T3 centre crack is the edge rule's, far from the MTS angle
/// (more than 10 deg off at one tip at least), which is what issue 34 is about.
#[test]
fn default_rule_moves_nothing() {
    let before = sim(&text("centre_45_t3_1", "sigma1_nearest")).model.mesh.points.clone();
    let (ks, s) = kink_run("centre_45_t3_1", "sigma1_nearest");
    let cr = s.cracking.as_ref().unwrap();
    assert!(cr.n_splits > 10, "{} splits", cr.n_splits);
    assert_eq!(cr.path, flem_core::cracking::path::PathState::default());
    assert!(s.model.mesh.points == before, "a point moved");
    assert!(ks.iter().any(|k| (k.chord_deg.unwrap() - mts_deg(1.0)).abs() > 10.0), "{ks:?}");
}

/// `Model::move_point` and the move check (`cracking::path::check_move`) on the 4 x 4 Q4
/// rectangle: an interior node moved by a quarter element keeps the total mass (rho times the
/// area, 16 x 1: the boundary did not move; 1e-12) and changes its neighbours' lumped masses; a move
/// past the neighbour (inverting elements), a boundary point and a non-finite target are
/// refused by name, and nothing changes.
#[test]
fn move_point_rebuilds_geometry_and_refuses_bad_moves() {
    let mut s =
        sim("[mesh]\ntype = \"rectangle\"\nwidth = 4.0\nheight = 4.0\nnx = 4\nny = 4\n\n[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\n\n[[stage]]\nname = \"none\"\n");
    let m = &mut s.model;
    let p = (0..m.mesh.points.len()).find(|&i| m.mesh.points[i] == [2.0, 2.0]).map(PointId::new).unwrap();
    let m0 = m.masses();
    use flem_core::cracking::path::check_move;
    assert_eq!(check_move(m, p, [3.5, 2.0]), Err("an element would be inverted or flattened"));
    assert_eq!(check_move(m, p, [f64::NAN, 2.0]), Err("not finite"));
    let b = (0..m.mesh.points.len()).find(|&i| m.mesh.points[i] == [0.0, 2.0]).map(PointId::new).unwrap();
    assert_eq!(check_move(m, b, [0.1, 2.0]), Err("a boundary point"));
    // Ours (session 17, `slide`): a boundary point may slide along a straight stretch of the
    // boundary (exact geometry: the outline is unchanged), not off it, and a corner never moves.
    assert_eq!(check_move(m, b, [0.0, 2.3]), Ok(()));
    assert_eq!(check_move(m, b, [1e-6, 2.3]), Err("a boundary point"));
    let corner = (0..m.mesh.points.len()).find(|&i| m.mesh.points[i] == [0.0, 0.0]).map(PointId::new).unwrap();
    assert_eq!(check_move(m, corner, [0.0, 0.2]), Err("a boundary point"));
    assert_eq!(check_move(m, p, [2.25, 1.8]), Ok(()));
    m.move_point(p, [2.25, 1.8]).unwrap();
    let m1 = m.masses();
    assert!((m1.iter().sum::<f64>() - 16.0).abs() < 1e-12 && (m0.iter().sum::<f64>() - 16.0).abs() < 1e-12, "{} {}", m0.iter().sum::<f64>(), m1.iter().sum::<f64>());
    let q = (0..m.mesh.points.len()).find(|&i| m.mesh.points[i] == [3.0, 2.0]).unwrap();
    assert!((m1[q] - m0[q]).abs() > 1e-3, "a neighbour's lumped mass did not follow the move");
    assert_eq!(m.mesh.points[p.idx()], [2.25, 1.8]);
}

/// A 4 x 4 grid of `element` (4 x 4 in size) in `plane`, a non-trivial displacement of every
/// node, and the interior point at (2, 2).
fn strained_grid(element: &str, plane: &str) -> (Simulation, Vec<[f64; 2]>, PointId) {
    let s = sim(&format!("[mesh]\ntype = \"rectangle\"\nwidth = 4.0\nheight = 4.0\nnx = 4\nny = 4\nelement = \"{element}\"\n[model]\nplane = \"{plane}\"\n\n[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\n\n[[stage]]\nname = \"none\"\n"));
    let n = s.model.cluster_x0().len();
    let u: Vec<[f64; 2]> = (0..n).map(|i| [1e-3 * (i as f64).sin(), 1e-3 * (2.0 * i as f64).cos()]).collect();
    let p = (0..s.model.mesh.points.len()).find(|&i| s.model.mesh.points[i] == [2.0, 2.0]).map(PointId::new).unwrap();
    (s, u, p)
}

/// `Model::move_point` updates the moved node's elements in place (`Block::move_elem`: the
/// tip's neighbourhood, not the block; issue 34 must-show 5). Reference: a model built afresh
/// from the moved mesh (`Model::new`, the whole-block path). Internal forces for a non-trivial
/// displacement, lumped masses, corner stresses and the stable-step bound must be equal bit for
/// bit, with the block's caches (corner gradients, bound) built before the move and after it.
#[test]
fn move_point_in_place_equals_a_fresh_model() {
    let (mut s, u, p) = strained_grid("q4", "stress");
    let n = u.len();
    let mut cs = Vec::new();
    s.model.corner_stresses(&u, &mut cs);
    let _ = s.model.blocks.iter().map(|b| b.max_omega_bound()).fold(0.0, f64::max);
    s.model.move_point(p, [2.25, 1.8]).unwrap();
    let fresh = flem_core::element::model::Model::new(s.model.mesh.clone(), &s.scene.file.materials, s.scene.file.model.plane, "fresh").unwrap();
    let (mut f1, mut f2) = (vec![[0.0; 2]; n], vec![[0.0; 2]; n]);
    s.model.internal_forces(&u, &mut f1);
    fresh.internal_forces(&u, &mut f2);
    assert!(f1 == f2, "internal forces differ");
    assert!(f1.iter().any(|f| f[0] != 0.0));
    assert!(s.model.masses() == fresh.masses(), "masses differ");
    let (mut c1, mut c2) = (Vec::new(), Vec::new());
    s.model.corner_stresses(&u, &mut c1);
    fresh.corner_stresses(&u, &mut c2);
    assert!(c1 == c2 && c1 != cs, "corner stresses");
    let w = |m: &flem_core::element::model::Model| m.blocks.iter().map(|b| b.max_omega_bound()).fold(0.0, f64::max);
    assert_eq!(w(&s.model).to_bits(), w(&fresh).to_bits());
}

/// What the ledger books for a node move of the path method (`Model::strain_energy_at`, the
/// `relocation` term; docs/dynamic.md "Session 22"). Reference: the whole model's strain energy
/// (`Model::strain_energy`: 1/2 u . F_int of the blocked force kernel, another route than the
/// element stiffness matrices of `strain_energy_at`) before and after moving one node with the
/// displacements kept: the change of the moved node's elements must equal the change of the
/// whole to 1e-12 of the energy, and be far from zero (a strained neighbourhood moved by a
/// quarter of an element changes its energy by per cents).
#[test]
fn strain_energy_at_a_node_measures_what_a_move_changes() {
    // Q4 in plane stress and T3 in plane strain (the element stiffness of either kind and plane).
    for (element, plane) in [("q4", "stress"), ("t3", "strain")] {
        let (mut s, u, p) = strained_grid(element, plane);
        let mut scratch = Vec::new();
        let (whole0, local0) = (s.model.strain_energy(&u, &mut scratch), s.model.strain_energy_at(p, &u));
        s.model.move_point(p, [2.25, 1.8]).unwrap();
        let (whole1, local1) = (s.model.strain_energy(&u, &mut scratch), s.model.strain_energy_at(p, &u));
        eprintln!("{element} {plane}: whole {whole0:e} -> {whole1:e}; the node's elements {local0:e} -> {local1:e}");
        assert!(((local1 - local0) - (whole1 - whole0)).abs() < 1e-12 * whole0, "{element}: local change {} against the whole's {}", local1 - local0, whole1 - whole0);
        assert!((whole1 - whole0).abs() > 1e-3 * whole0, "{element}: the move changed the energy by {:e} only", whole1 - whole0);
        assert!(local0 < whole0 && local0 > 0.0);
    }
}

/// Checkpoints carry the moved coordinates: the shear test with `tip_mts` (nodes moved), stopped
/// after events 10 and 20 and resumed from the folder, ends bit for bit as the uninterrupted
/// run (tests/ckpt.rs's check: displacements, splits, history, snapshots). Also with `piece`
/// (session 19; it adds no state of its own: a resumed tip reads its line from the checkpoint).
#[test]
fn tip_mts_checkpoint_resumes_bit_for_bit() {
    for (k, rule) in ["tip_mts", "tip_mts\"\npiece = 0.05\nshrink = 1.5\n#\""].into_iter().enumerate() {
        let t = text("sen_q4_1", rule) + "\n[output]\ncheckpoint_every = 5\ncheckpoint_seconds = 0\n";
        let ref_dir = crate::ckpt::tmp(&format!("paths-ref-{k}"));
        let mut reference = sim(&t);
        let mut w = flem_core::output::OutputWriter::new(&ref_dir, &reference).unwrap();
        reference.run(&mut w).unwrap();
        let cr = reference.cracking.as_ref().unwrap();
        assert!(reference.state.step > 20 && cr.path.moves.len() > 10, "{rule}: {} events, {} moves", reference.state.step, cr.path.moves.len());
        for at in [10, 20] {
            crate::ckpt::interrupt_and_resume(&t, at, &reference, &ref_dir, &format!("paths-{k}-{at}"));
        }
        let _ = std::fs::remove_dir_all(&ref_dir);
    }
}

/// The shear test (`sen_q4_1`) with `tip_mts` in the explicit march, four stages of displacement.
fn explicit_shear_text() -> String {
    explicit_text("sen_q4_1", "tip_mts")
}

/// The scene `configs/paths/NAME.toml` in the explicit march as `tools/paths_cost_explicit.sh`
/// writes it (tolerance 1e-4, a check every 10 steps, the shear raised in four stages of at most
/// 20000 steps), with the separation rule's table opening `rule` (a name, or a name and keys).
fn explicit_text(name: &str, rule: &str) -> String {
    let t = text(name, rule);
    let solver = "[solver]\ntype = \"events\"\nmax_events = 90\non_loose_fragment = \"stop\"   # the measurement ends when a crack reaches the boundary\n";
    assert!(t.contains(solver), "the scene's [solver] changed: update the test");
    let mut t = t.replace(solver, "[solver]\ntolerance = 1e-4\n").replace("[cracking]\n", "[cracking]\ncheck_every = 10\n");
    t.truncate(t.find("[[stage]]").unwrap());
    for (k, v) in [0.01, 0.02, 0.025, 0.03].iter().enumerate() {
        t += &format!("[[stage]]\nname = \"s{k}\"\nlevels = {{ shear = {v} }}\nmax_steps = 20000\n\n");
    }
    t
}

/// The explicit march (the paper's solver, checks every 10 steps at equilibrium) with `tip_mts`
/// on the shear test, displacement raised in four stages: the kink over five element sizes is
/// within 5 deg of the pure mode II MTS angle (-70.53 deg, Erdogan & Sih 1963), nodes moved,
/// no debris; the stable step followed the moves (the run did not diverge).
#[test]
fn tip_mts_in_the_explicit_march() {
    let mut s = sim(&explicit_shear_text());
    let tips = crack_tips(&s.model);
    let initial = crack_faces(&s.model);
    s.run(&mut NoOutput).unwrap();
    let ks = kinks(&s.model, &tips, &initial, 5.0);
    let mts = -2.0 * (1.0 / 2f64.sqrt()).atan().to_degrees();
    let c = ks[0].chord_deg.unwrap();
    assert!(ks[0].reached && (c - mts).abs() <= 5.0, "chord {c:.2} deg against {mts:.2}");
    assert!(!s.cracking.as_ref().unwrap().path.moves.is_empty());
    assert!(fragment_sizes(&s.model).iter().all(|&n| n >= 3));
    // The ledger (docs/dynamic.md "Session 22"): the node moves' energy booked as
    // `relocation` closes it to 1e-5 of the work (measured 4.7e-7); without that term the
    // residual would be the moves' 4e-4 of the work.
    let l = &s.ledger;
    let without = (l.residual() - l.relocation).abs() / l.external();
    eprintln!("ledger: relocation {:e}, work {:e}, relative residual {:e}, without the relocation term {without:e}", l.relocation, l.external(), l.relative_residual());
    assert!(l.relative_residual() < 1e-5 && without > 1e-4, "residual {:e}, without the relocation term {without:e}", l.relative_residual());
}

/// The events solver books no node move (review r22): its ledger is the event state's strain
/// energy alone (external work = strain: a residual of exactly 0 at every event), and a move
/// booked there would show as a false residual of the size of the move's energy in the history
/// rows. Reference: the events part's own definition (tolerance: exact). Shear test `sen_q4_1`
/// with `tip_mts`, nodes moved.
#[test]
fn events_solver_books_no_node_move() {
    let dir = crate::ckpt::tmp("paths-events-ledger");
    let mut s = sim(&text("sen_q4_1", "tip_mts"));
    let mut w = flem_core::output::OutputWriter::new(&dir, &s).unwrap();
    s.run(&mut w).unwrap();
    drop(w);
    assert!(!s.cracking.as_ref().unwrap().path.moves.is_empty(), "no node moved");
    assert_eq!(s.ledger.relocation, 0.0);
    // Every history row (written after each event's check): with moves booked, 15 of the 67
    // rows had a non-zero residual (measured on the binary before the fix).
    let hist = std::fs::read_to_string(dir.join("history.csv")).unwrap();
    let col = hist.lines().next().unwrap().split(',').position(|h| h == "energy_residual").unwrap();
    let rows: Vec<f64> = hist.lines().skip(1).map(|l| l.split(',').nth(col).unwrap().parse().unwrap()).collect();
    assert!(rows.len() > 20 && rows.iter().all(|&r| r == 0.0), "residuals {rows:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The explicit march of the test above, interrupted after nodes moved and resumed from its
/// checkpoint: bit for bit the uninterrupted run (tests/ckpt.rs's check), the ledger's
/// `relocation` term included (checkpoint section `ledger_relocation`: lost, the resumed
/// residual differs).
#[test]
fn tip_mts_explicit_checkpoint_keeps_the_relocation() {
    let t = explicit_shear_text() + "\n[output]\ncheckpoint_every = 100\ncheckpoint_seconds = 0\n";
    let ref_dir = crate::ckpt::tmp("paths-explicit-ref");
    let mut reference = sim(&t);
    let mut w = flem_core::output::OutputWriter::new(&ref_dir, &reference).unwrap();
    reference.run(&mut w).unwrap();
    assert!(reference.ledger.relocation != 0.0 && reference.state.step > 400, "{} steps, relocation {}", reference.state.step, reference.ledger.relocation);
    let at = reference.state.step * 3 / 4;
    crate::ckpt::interrupt_and_resume(&t, at, &reference, &ref_dir, "paths-explicit");
    let _ = std::fs::remove_dir_all(&ref_dir);
}

/// Ours (session 17): the path `flem paths` compares (`kinks_in_order`) is the one along which the
/// crack first ran through the body. On the shear test's `t3_2` mesh with `tip_mts` (the
/// settings before session 17: `every = 2`, no `shrink`, no `slide`), cracks that
/// the edge rule starts later away from the tip (at the clamped edge, after the main crack ran
/// through) join the main crack; the branch to the farthest point then leaves the main crack
/// where one of them joined (it used to, 16 % of the specimen from the other meshes' paths).
/// Reference: the run's own cut order, against which the followed path is checked segment by
/// segment: every face on it was cut no later than the cut at which the path reaches the
/// boundary, and that cut is the first that reaches the boundary from the tip (the farthest
/// branch's latest cut is later). Tolerance: exact (integers).
#[test]
fn whole_path_is_the_crack_that_ran_through_first() {
    // The settings before session 17 (with them the run has such a joining crack).
    let old = "type = \"tip_mts\"\nevery = 2.0\nshrink = 0.0\nslide = false";
    let mut s = sim(&text("sen_t3_2", "tip_mts").replace("type = \"tip_mts\"", old));
    let tips = crack_tips(&s.model);
    let initial = crack_faces(&s.model);
    s.run(&mut NoOutput).unwrap();
    let cuts = s.cracking.as_ref().unwrap().cuts.clone();
    let order = edge_cut_order(s.model.topo.edges.len(), &cuts);
    let x = &s.model.mesh.points;
    // The latest cut along a path of points (the faces between consecutive points).
    let latest = |path: &[[f64; 2]]| -> u32 {
        let id = |p: [f64; 2]| (0..x.len()).find(|&i| x[i] == p).map(PointId::new).unwrap();
        path.windows(2)
            .map(|w| {
                let (a, b) = (id(w[0]), id(w[1]));
                let e = *s.model.topo.point_edges.row(a.idx()).iter().find(|&&e| s.model.topo.other_end(e, a) == b).unwrap();
                order[e.idx()]
            })
            .max()
            .unwrap()
    };
    let first = &kinks_in_order(&s.model, &tips, &initial, 5.0, &cuts)[0];
    let far = &kinks(&s.model, &tips, &initial, 5.0)[0];
    let (f, t) = (first.through(), far.through());
    assert!(first.boundary_at.is_some(), "the crack reaches the boundary");
    assert!(far.branches > 0, "the run has a crack that joins the main one (the case measured)");
    assert!(latest(f) < latest(t), "first through at cut {}, the farthest branch at {}", latest(f), latest(t));
    // The main crack leaves at the clamped edge between x = 0.7 and 0.85 (all nine meshes,
    // docs/paths.md); the farthest branch did not follow it.
    let end = f.last().unwrap();
    assert!(end[1].abs() < 1e-9 && (0.7..0.85).contains(&end[0]), "{end:?}");
}

/// Must-show 3 (issue 34, first half; ours, session 17): the shear test's whole path, up to where
/// it first reaches the outer boundary, on the unstructured T3 mesh and the structured 30 x 30
/// Q4 grid at h = 1/30 (configs/paths/shear_t3_1, shear_q4_1) with the default `tip_mts`.
/// Reference: each other (the issue asks for the same path on every mesh; there is no closed
/// form). Tolerance: the issue's 2 % of the specimen's size (1) as the Hausdorff distance
/// (measured 1.61 %; all nine meshes of the series: docs/paths.md). Both paths must reach the
/// clamped edge (y = 0) and leave no fragment below 3 elements.
#[test]
fn shear_whole_path_same_on_t3_and_q4() {
    let run = |name: &str| whole_path_to_clamped_edge(name, &text(name, "tip_mts")).1.through().to_vec();
    let (a, b) = (run("shear_t3_1"), run("shear_q4_1"));
    let d = flem_plugins::check::paths::hausdorff(&a, &b, 1e-4);
    assert!(d <= 0.02, "Hausdorff distance {:.2} % of the size", 100.0 * d);
}

/// Ours (session 18, review r17 (b)): the path method's fixity mask. On the shear test
/// (`shear_t3_1`, h = 1/30) the crack's line meets the clamped edge (y = 0) at x of about 0.78.
/// With the bottom held by a prescribed displacement of zero (the same problem as the support,
/// but a prescribed motion: class `HELD`, never moved), no point of the bottom edge may move,
/// the refusals are counted (`held_refused`) and the crack still reaches the edge (cut where the
/// node lies). The same scene with the mask emptied (`path_held`, as before session 18) slides
/// a bottom node: what the mask is for. With the support itself (class `SLIDES`: the support
/// covers both boundary edges of every bottom node but the corners) the slide along the edge
/// stays allowed (the same problem: u = 0 along the same edges). Tolerance: exact (moves are
/// records, the edge's points have y = 0 exactly).
#[test]
fn path_method_never_moves_a_held_point() {
    let t = text("shear_t3_1", "tip_mts");
    let support = "[[support]]\nnodes = \"bottom\"\nfix = \"xy\"\n";
    assert!(t.contains(support) && t.contains("levels = { shear = 0.05 }"), "the scene changed: update the test");
    let held = t
        .replace(support, "[[load]]\nname = \"clamp\"\ntype = \"displacement\"\nnodes = \"bottom\"\nx = 0.0\ny = 0.0\n")
        .replace("levels = { shear = 0.05 }", "levels = { shear = 0.05, clamp = 1.0 }");
    let bottom_moves = |s: &Simulation| s.cracking.as_ref().unwrap().path.moves.iter().filter(|m| m.from[1] == 0.0).count();
    let run = |text: &str, mask: bool| {
        let mut s = sim(text);
        if !mask {
            s.cracking.as_mut().unwrap().path_held.clear();
        }
        let tips = crack_tips(&s.model);
        let initial = crack_faces(&s.model);
        s.run(&mut NoOutput).unwrap();
        let cuts = s.cracking.as_ref().unwrap().cuts.clone();
        let k = kinks_in_order(&s.model, &tips, &initial, 5.0, &cuts).remove(0);
        let end = *k.through().last().unwrap();
        assert!(k.boundary_at.is_some() && end[1].abs() < 1e-9, "the path ends at {end:?}");
        s
    };
    let s = run(&held, true);
    let cr = s.cracking.as_ref().unwrap();
    assert_eq!(bottom_moves(&s), 0, "a held point moved");
    assert!(cr.held_refused > 0 && cr.path.refused >= cr.held_refused, "{} held refusals", cr.held_refused);
    let free = run(&held, false);
    assert!(bottom_moves(&free) > 0, "without the mask no bottom node moved: the test would not see the defect");
    let sup = run(&t, true);
    assert!(bottom_moves(&sup) > 0, "a supported node no longer slides along its supported edge");
    assert_eq!(sup.cracking.as_ref().unwrap().held_refused, 0);
}

/// The mask's classes (`Loads::held_points`, ours, session 18) on the 4 x 4 Q4 rectangle with
/// the bottom supported in y, the left edge in x, the top displaced and a traction on the right
/// edge: a bottom node inside the edge slides (its support covers both its boundary edges), the
/// corner (0, 0) slides neither (not straight: `check_move` refuses it anyway), the left edge's
/// nodes slide, the top and right edges' nodes (prescribed, loaded face) and the corners where a
/// support ends are held, an interior node is free. Moves: exact classes and refusals by name.
#[test]
fn fixity_mask_classes() {
    let s = sim("[mesh]\ntype = \"rectangle\"\nwidth = 4.0\nheight = 4.0\nnx = 4\nny = 4\n\n[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\n\n[[support]]\nnodes = \"bottom\"\nfix = \"y\"\n\n[[support]]\nnodes = \"left\"\nfix = \"x\"\n\n[[load]]\nname = \"d\"\ntype = \"displacement\"\nnodes = \"top\"\ny = 0.01\n\n[[load]]\nname = \"t\"\ntype = \"traction\"\nedges = \"right\"\nvalue = [1.0, 0.0]\n\n[[stage]]\nname = \"none\"\nlevels = { d = 1.0, t = 1.0 }\n");
    use flem_core::cracking::path::{check_move_held, HELD, HELD_MSG, SLIDES};
    let m = &s.model;
    let id = |x: [f64; 2]| (0..m.mesh.points.len()).find(|&i| m.mesh.points[i] == x).map(PointId::new).unwrap();
    let h = s.loads.held_points(m);
    let c = |x: [f64; 2]| h[id(x).idx()];
    assert_eq!(c([2.0, 0.0]), SLIDES);
    assert_eq!(c([0.0, 2.0]), SLIDES);
    // (0, 0): fixed in x and y, its neighbours each in one direction only: the supports end there.
    assert_eq!(c([0.0, 0.0]), HELD);
    // (4, 0): the bottom's y support ends at the right edge (free in y below the traction), and
    // it is an end of a loaded face.
    assert_eq!(c([4.0, 0.0]), HELD);
    assert_eq!(c([4.0, 2.0]), HELD);
    assert_eq!(c([2.0, 4.0]), HELD);
    assert_eq!(c([2.0, 2.0]), 0);
    assert_eq!(check_move_held(m, &h, id([2.0, 0.0]), [2.3, 0.0]), Ok(()));
    assert_eq!(check_move_held(m, &h, id([2.0, 0.0]), [2.3, 0.1]), Err("a boundary point"));
    assert_eq!(check_move_held(m, &h, id([4.0, 2.0]), [4.0, 2.3]), Err(HELD_MSG));
    assert_eq!(check_move_held(m, &h, id([2.0, 4.0]), [2.3, 4.0]), Err(HELD_MSG));
    assert_eq!(check_move_held(m, &h, id([2.0, 2.0]), [2.25, 1.8]), Ok(()));
    // Empty mask: nothing held (the rule's state before set-up, the paper's rules).
    assert_eq!(check_move_held(m, &[], id([2.0, 4.0]), [2.3, 4.0]), Ok(()));
}

/// Ours (session 19): `tip_mts`'s `piece` option, re-evaluation pieces of one length on every
/// mesh (a fraction of the specimen's size) instead of `every` domain radii (4 h). The shear
/// test on the 30 x 30 grid (`shear_q4_1`, h = 1/30) and the finest T3 mesh (`shear_t3_3`,
/// h = 1/62), the pair farthest apart with the defaults (2.26 %, docs/paths.md).
/// 1. The mechanism: on the coarse grid, the lines the main crack followed (`path.lines`; their
///    origins are the path's vertices where the factors were evaluated) start at most
///    `piece + 1.5 h` apart (a tip is evaluated at the first step past `piece` along its line,
///    a step at most one link, plus the staircase's offset), after the first piece (which runs
///    until the domain has cleared the first kink). With the defaults some piece is longer
///    than that (they are `4 h` = 0.133 and more), which is what the check tells apart.
///    Tolerance: exact geometry.
/// 2. What it is for: the two paths, up to where each first reaches the clamped edge, within the
///    issue's 2 % of the specimen's size (Hausdorff). Reference: each other (must-show 3 asks
///    for the same path on every mesh; there is no closed form). The setting (`piece = 0.05`,
///    `shrink = 1.5`) is the best of those measured on the 9 meshes of the series, and its
///    neighbours are not all within 2 %: a tuned setting, not a convergence proof
///    (docs/paths.md, session 19).
#[test]
fn tip_mts_piece_same_pieces_on_every_mesh() {
    let opts = "type = \"tip_mts\"\npiece = 0.05\nshrink = 1.5";
    let run = |name: &str, opts: &str| {
        let (s, k) = whole_path_to_clamped_edge(name, &text(name, "tip_mts").replace("type = \"tip_mts\"", opts));
        // The line origins on the path, in the path's order, and the largest distance between
        // two consecutive ones after the first.
        let p = k.through().to_vec();
        let mut at: Vec<usize> = s.cracking.as_ref().unwrap().path.lines.iter().filter_map(|l| p.iter().position(|&v| v == l.origin)).collect();
        at.sort_unstable();
        at.dedup();
        let gap = at.windows(2).skip(1).map(|w| (p[w[1]][0] - p[w[0]][0]).hypot(p[w[1]][1] - p[w[0]][1])).fold(0.0, f64::max);
        (p, at.len(), gap, k.h)
    };
    let (coarse, n, gap, h) = run("shear_q4_1", opts);
    assert!(n >= 6, "{n} evaluations along the path");
    assert!(gap <= 0.05 + 1.5 * h, "largest piece {gap:.4} (h = {h:.4})");
    let (_, _, gap0, _) = run("shear_q4_1", "type = \"tip_mts\"");
    assert!(gap0 > 0.05 + 1.5 * h, "the defaults' largest piece {gap0:.4}");
    let (fine, _, _, _) = run("shear_t3_3", opts);
    let d = flem_plugins::check::paths::hausdorff(&coarse, &fine, 1e-4);
    assert!(d <= 0.02, "Hausdorff distance {:.2} % of the size", 100.0 * d);
}

/// The `toml` blocks of `tip_mts`'s module doc and those of docs/paths.md that set
/// `type = "tip_mts"` build the shear test's scene as its `[cracking.separation]` (the docs
/// cannot drift from the code), and `piece` out of range is refused by name.
#[test]
fn tip_mts_doc_snippets_parse() {
    let sep = "[cracking.separation]\ntype = \"sigma1_nearest\"\n";
    let base = text("shear_q4_1", "sigma1_nearest");
    assert!(base.contains(sep), "the scene changed: update the test");
    let src = std::fs::read_to_string(root().join("plugins/src/separation/tip_mts.rs")).unwrap();
    let mut snippets = flem_plugins::snippets::toml_blocks(&src);
    assert!(!snippets.is_empty(), "tip_mts.rs has no toml block");
    let md = std::fs::read_to_string(root().join("docs/paths.md")).unwrap();
    let mut cur: Option<String> = None;
    for line in md.lines() {
        match (&mut cur, line.trim()) {
            (None, "```toml") => cur = Some(String::new()),
            (Some(s), "```") => {
                if s.contains("type = \"tip_mts\"") {
                    snippets.push(s.clone());
                }
                cur = None;
            }
            (Some(s), _) => {
                s.push_str(line);
                s.push('\n');
            }
            _ => {}
        }
    }
    assert!(snippets.len() >= 3, "{} snippets", snippets.len());
    for snip in &snippets {
        let s = crate::common::scene(&base.replace(sep, snip));
        assert!(s.file.cracking.as_ref().unwrap().separation.grows_tips(), "{snip}");
    }
    let bad = base.replace(sep, "[cracking.separation]\ntype = \"tip_mts\"\npiece = 2.0\n");
    let e = flem_core::scene::Scene::from_str(&bad, std::path::Path::new("bad.toml"), &root().join("configs")).map(|_| ()).unwrap_err();
    assert!(e.to_string().contains("cracking.separation.piece"), "{e}");
}

/// Runs a shear-test scene to its end and returns it with the kink record of its first tip's
/// whole path (`kinks_in_order`); asserts no fragment below 3 elements and that the path reaches
/// the clamped edge (y = 0).
fn whole_path_to_clamped_edge(name: &str, scene: &str) -> (Simulation, Kink) {
    let mut s = sim(scene);
    let tips = crack_tips(&s.model);
    let initial = crack_faces(&s.model);
    s.run(&mut NoOutput).unwrap();
    let cuts = s.cracking.as_ref().unwrap().cuts.clone();
    assert!(fragment_sizes(&s.model).iter().all(|&n| n >= 3), "{name}: debris");
    let k = kinks_in_order(&s.model, &tips, &initial, 5.0, &cuts).remove(0);
    let end = *k.through().last().unwrap();
    assert!(k.boundary_at.is_some() && end[1].abs() < 1e-9, "{name}: the path ends at {end:?}");
    (s, k)
}

/// The shear test's scene `sen_q4_1` (a unit square, 20 x 20 Q4, h = 0.05, a slit along y = 0.5
/// from the left edge to its tip at (0.5, 0.5)) with `tip_mts` and the shield's `key` line ("":
/// none), nu = 0 (the failure indices below are computed for it).
fn shield_text(key: &str) -> String {
    let rule = if key.is_empty() { "tip_mts".to_string() } else { format!("tip_mts\"\n{key}\n#\"") };
    let t = text("sen_q4_1", &rule);
    assert!(t.contains("poisson_ratio = 0.3\n") && t.contains("nx = 20\nny = 20\n"), "sen_q4_1 changed: update the test");
    t.replace("poisson_ratio = 0.3\n", "poisson_ratio = 0.0\n")
}

/// Ours (session 27), `tip_mts`'s `shield` (`SeparationRule::shield_distance`): a failed point
/// that no tip takes and that lies within `shield` element sizes of a crack edge is not cut.
/// Reference: the key's definition (exact), on a displacement field made by hand so that the
/// points that fail lie 1 to 3 element sizes above the slit, 5 or more from its tip, and the
/// most critical is (0.2, 0.6): `u_x = e0 (F(x) - F(0.2)) g(y)`, `F' = f` a hat of half-width
/// 2 h at x = 0.2, `g` one at y = 0.6, so that `e_xx = e0 f g` and the shear vanishes on x = 0.2
/// (sigma1 there 0.75 e0 E in the corner mean, 2.0 times the strength; the shear of the rows
/// beyond x = 0.3, where `u_x` no longer changes with x, stays at 0.68 of it). Without the key that
/// point (2 h from the slit, beyond `route` = 3 h of the tip) starts a crack; with `shield = 4`
/// nothing is cut; with `shield = 1.5` the point is outside the shield and is cut again; the same
/// with `shield_length = 0.2` and `0.075` (4 h and 1.5 h as lengths). The
/// same hat centred past the slit's end, at (0.75, 0.55), 1 h from the slit's line but 5.1 h
/// from the slit: cut with `shield = 4` (the distance is to the segment, not to its line). The
/// order of routing before the shield is not pinned here (on a first version of this fixture, a
/// 2 x 1 grid, a hat within `route` of the tip cut nothing with or without the shield: the tip's
/// integral refused the hand-made field), but by the L-panel runs, whose tips grow with
/// `shield = 4`.
#[test]
fn tip_mts_shield_keeps_new_cracks_off_a_crack() {
    let h = 0.05;
    // The first split of one check, with the hat centred on (x0, y0).
    let first_split = |key: &str, x0: f64, y0: f64| -> Option<[f64; 2]> {
        let mut s = sim(&shield_text(key));
        let w = 2.0 * h;
        let fd = |t: f64| if t.abs() <= w { t - t.signum() * t * t / (2.0 * w) } else { t.signum() * w / 2.0 };
        let g = |y: f64| (1.0 - (y - y0).abs() / w).max(0.0);
        let u: Vec<[f64; 2]> = s.x0.iter().map(|x| [0.0027 * fd(x[0] - x0) * g(x[1]), 0.0]).collect();
        let cfg = s.scene.file.cracking.as_ref().unwrap();
        let cr = s.cracking.as_mut().unwrap();
        let (_, ev) = cr.check(cfg, &mut s.model, &u, &s.x0, 0.0, 0).unwrap();
        ev.first().map(|e| s.model.mesh.points[e.point.idx()])
    };
    let at = |x: [f64; 2], t: [f64; 2]| (x[0] - t[0]).abs() < 1e-9 && (x[1] - t[1]).abs() < 1e-9;
    let off = first_split("", 0.2, 0.6).expect("without the shield the check cuts");
    assert!(at(off, [0.2, 0.6]), "without the shield the first cut is at {off:?}, not (0.2, 0.6)");
    // The same radii in element sizes (`shield`) and as lengths (`shield_length`, h = 0.05).
    for (wide, narrow) in [("shield = 4.0", "shield = 1.5"), ("shield_length = 0.2", "shield_length = 0.075")] {
        let shielded = first_split(wide, 0.2, 0.6);
        assert!(shielded.is_none(), "{wide}: a cut at {shielded:?}");
        let cut = first_split(narrow, 0.2, 0.6).unwrap_or_else(|| panic!("{narrow} cuts"));
        assert!(at(cut, [0.2, 0.6]), "{narrow}: the first cut is at {cut:?}");
    }
    // Beyond the slit's end: (0.75, 0.55) is 1 h from the slit's line but 5.1 h from the slit
    // (its end, the tip) and so outside the shield and beyond `route`: cut (a distance to the
    // line instead of the segment would shield it).
    let past = first_split("shield = 4.0", 0.75, 0.55).expect("shield 4 cuts past the slit's end");
    assert!(at(past, [0.75, 0.55]), "shield 4, past the end: the first cut is at {past:?}");
}

/// `flem chart-crack --paths --separation TOML` (issue 34 must-show 5's chart with session 25's
/// setting): the shear test on the coarse Q4 grid and the coarse T3 mesh (the finer of the two,
/// h = 0.0321, is the reference). Reference: must-show 3's bound, the Hausdorff distance between
/// the two meshes' paths at most 2 % of the specimen with the path method (1.09 % measured with
/// the setting), while the paper's edge rule's paths differ by more than 5 % (12.2 % measured: a
/// chart that ran the edge rule twice fails here). The same chart without `--separation` runs
/// `tip_mts`'s defaults (1.68 % here): the two must differ, so a chart that dropped the keys
/// fails. The keys are named in the CSV; a misspelt key is refused before any run, naming it.
#[test]
fn chart_crack_paths_runs_the_setting_given() {
    let out = std::env::temp_dir().join(format!("flem_chart_paths_{}", std::process::id()));
    let scenes: Vec<String> = ["shear_q4_1", "shear_t3_1"].iter().map(|n| root().join(format!("configs/paths/{n}.toml")).to_string_lossy().into_owned()).collect();
    let run = |sep: Option<&str>| {
        let _ = std::fs::remove_dir_all(&out);
        let mut args = vec!["chart-crack", "--paths", &scenes[0], &scenes[1], "--out", out.to_str().unwrap()];
        if let Some(s) = sep {
            args.extend(["--separation", s]);
        }
        let o = std::process::Command::new(crate::common::flem_exe()).args(&args).output().unwrap();
        let csv = std::fs::read_to_string(out.join("path_error.csv")).unwrap_or_default();
        (o, csv)
    };
    // The q4_1 row's distance (% of the specimen) of one rule's label.
    let pct = |csv: &str, rule: &str| -> f64 {
        let row = csv.lines().find(|l| l.contains("shear_q4_1") && l.split(',').nth(1) == Some(rule)).unwrap_or_else(|| panic!("no q4_1 row of {rule} in\n{csv}"));
        row.rsplit(',').next().unwrap().parse().unwrap()
    };
    let (o, csv) = run(Some("type = \"tip_mts\"\nevery = 1.25\npiece = 0.05\nshrink = 1.5"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("path_error.svg").exists());
    let (edge, tip) = (pct(&csv, "edge rule (paper)"), pct(&csv, "tip_mts (ours): every = 1.25; piece = 0.05; shrink = 1.5"));
    assert!(tip <= 2.0 && edge > 5.0, "Hausdorff q4_1 to t3_1: tip_mts {tip:.2} %, edge rule {edge:.2} %");
    let (o, csv) = run(None);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let defaults = pct(&csv, "tip_mts (ours)");
    assert!((defaults - tip).abs() > 0.1, "the setting's path is the defaults' ({tip:.3} % against {defaults:.3} %): the keys were not used");
    let (bad, _) = run(Some("type = \"tip_mts\"\nevry = 1.25"));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success() && err.contains("unknown field `evry`") && !err.contains("edge rule (paper):"), "{err}");
    assert!(!out.exists(), "a refused chart wrote {}", out.display());
    let _ = std::fs::remove_dir_all(&out);
}

/// Follows the first crack's lines from the initial tip `tip0` (`PathState::lines`, one record
/// per cut, keyed by the point the cut made the tip). A new line is planned at the tip of a record
/// of the current line (its point `q`, which no later move touches: it lies on a crack face). With
/// `anchor` its origin must be `q`'s foot on the current line when `q` lies off that line by more
/// than 1e-6 h (a staircase tip), and `q` itself otherwise. Returns the number of new lines
/// followed, how many of them were planned at a staircase tip, and the largest distance of such a
/// line's origin from that foot (the relation's error; without `anchor` it is the tip's offset).
fn anchored_chain(s: &Simulation, tip0: [f64; 2], h: f64) -> (usize, usize, f64) {
    use flem_core::cracking::path::TipLine;
    let lines = &s.cracking.as_ref().unwrap().path.lines;
    let x = &s.model.mesh.points;
    let same = |a: &TipLine, b: &TipLine| a.origin == b.origin && a.dir == b.dir;
    let d = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    let mut cur = lines.iter().position(|l| d(l.origin, tip0) < 1e-12).expect("a line from the initial tip");
    let (mut n, mut stair, mut err) = (0, 0, 0.0f64);
    loop {
        let mut next = None;
        'search: for i in cur + 1..lines.len() {
            if lines[..i].iter().any(|m| same(m, &lines[i])) {
                continue;
            }
            for j in (cur..i).filter(|&j| same(&lines[j], &lines[cur])) {
                let q = x[lines[j].point as usize];
                let (o, t) = (lines[j].origin, [lines[j].dir.cos(), lines[j].dir.sin()]);
                let s_ = (q[0] - o[0]) * t[0] + (q[1] - o[1]) * t[1];
                let foot = [o[0] + s_ * t[0], o[1] + s_ * t[1]];
                let off = d(q, foot);
                let expect = if off > 1e-6 * h { foot } else { q };
                // The line was planned at q: its origin is q's foot or q itself.
                if d(lines[i].origin, foot) <= 1e-6 * h || d(lines[i].origin, q) <= 1e-9 * h {
                    next = Some((i, off > 1e-6 * h, d(lines[i].origin, expect)));
                    break 'search;
                }
            }
        }
        let Some((i, staircase, e)) = next else { break };
        n += 1;
        if staircase {
            stair += 1;
            err = err.max(e);
        }
        cur = i;
    }
    (n, stair, err)
}

/// Ours (session 35): `anchor = true` starts a staircase tip's new line at the tip's foot on its
/// previous line (the moves on quads are partial, so a tip lies up to `staircase h` off its
/// line); the lines then form one continuous polyline. The shear test on the q4 grids, the T3
/// meshes and the three unstructured quad meshes (`shear_uquad_*`, gmsh Frontal-Delaunay +
/// Blossom), h = 1/30 to 1/65.
/// 1. What the key does (`anchored_chain`): along the first crack, every new line planned at a
///    staircase tip starts at that tip's foot on the line before it (tolerance 1e-6 h: the foot
///    is computed from the same numbers), at least 5 new lines are followed (6-9 measured) on every mesh, and
///    the q4 and unstructured quad meshes have staircase tips among them. Without the key
///    (session 25's setting S25) `uquad_2`'s lines start more than 0.05 h off that foot: a key
///    made inert fails here (checked in session 35: `shear_q4_1`, 7.7e-3 off).
/// 2. The target, with session 35's setting (S35: S25 with `anchor = true` and `shrink = 1.0`).
///    Reference: each other (must-show 3 of issue 34: the same path on every mesh; no closed
///    form). Tolerance: the issue's 2 % of the specimen's size, the Hausdorff distance of the
///    paths up to where each first meets the clamped edge, over all nine meshes (measured
///    1.41 %; S25 2.72 %, S25 with `shrink = 1.0` alone 1.92 %: docs/paths.md "Session 35").
#[test]
fn tip_mts_anchor_keeps_the_lines_continuous() {
    let s25 = "type = \"tip_mts\"\nevery = 1.25\npiece = 0.05\nshrink = 1.5";
    let s35 = "type = \"tip_mts\"\nevery = 1.25\npiece = 0.05\nshrink = 1.0\nanchor = true";
    let run = |name: &str, opts: &str| {
        let (s, k) = whole_path_to_clamped_edge(name, &text(name, "tip_mts").replace("type = \"tip_mts\"", opts));
        (k.through().to_vec(), anchored_chain(&s, [0.5, 0.5], k.h), k.h)
    };
    let (_, (_, stair25, err25), h) = run("shear_uquad_2", s25);
    assert!(stair25 > 0 && err25 > 0.05 * h, "S25 on uquad_2: {stair25} staircase tips, largest offset {err25:.2e} (h = {h:.4})");
    let mut paths = Vec::new();
    for kind in ["q4", "t3", "uquad"] {
        for n in 1..=3 {
            let name = format!("shear_{kind}_{n}");
            let (p, (lines, stair, err), h) = run(&name, s35);
            assert!(lines >= 5, "{name}: {lines} new lines followed");
            assert!(kind == "t3" || stair > 0, "{name}: no staircase tip among {lines} new lines");
            assert!(err <= 1e-6 * h, "{name}: a staircase tip's new line starts {err:.2e} off its foot");
            paths.push((name, p));
        }
    }
    let mut worst = (0.0, String::new());
    for (i, (a, pa)) in paths.iter().enumerate() {
        for (b, pb) in &paths[i + 1..] {
            let d = flem_plugins::check::paths::hausdorff(pa, pb, 1e-4);
            if d > worst.0 {
                worst = (d, format!("{a} / {b}"));
            }
        }
    }
    assert!(worst.0 <= 0.02, "S35: Hausdorff distance {:.2} % of the size ({})", 100.0 * worst.0, worst.1);
}

/// Ours (session 35): after a node move the stable step is estimated again with the moved
/// points' clusters in the warm start (`Simulation::update_stable_step`). The explicit march of
/// the shear test on `shear_t3_1` with S35 (as `tools/paths_cost_explicit.sh` writes it): a
/// move at step 3260 near the top-right corner raised the highest frequency, and the power
/// iteration, warm-started from the last eigenvector, stopped after six iterations with the old
/// estimate. dt stayed at 1.004 of the new critical step, and the run diverged at step 4543
/// (kinetic energy beyond 1e12 of the work; the same with S25 since session 33 at least).
/// Reference: the stability limit of the central difference march (dt <= 2 / omega_max) and the
/// energy balance. Tolerance: the run ends without error after its 80000 steps, dt was lowered
/// after a split (the warning), the ledger closes to 1e-5 of the work, and the final dt is at
/// most the critical step of a cold estimate of the final mesh. Fails without the
/// warm start's spike (checked in session 35: the divergence at step 4543).
#[test]
fn tip_mts_explicit_step_follows_a_move() {
    let mut s = sim(&explicit_text("shear_t3_1", "tip_mts\"\nevery = 1.25\npiece = 0.05\nshrink = 1.0\nanchor = true\n#\""));
    let dt0 = s.dt;
    s.run(&mut NoOutput).unwrap_or_else(|e| panic!("the explicit march with tip_mts: {e}"));
    assert!(!s.cracking.as_ref().unwrap().path.moves.is_empty(), "no node moved");
    assert!(s.state.step >= 80000, "{} steps", s.state.step);
    assert!(s.dt < dt0 && s.warnings.iter().any(|w| w.contains("critical step fell")), "dt {:e} (at the start {dt0:e}); warnings {:?}", s.dt, s.warnings);
    assert!(s.ledger.relative_residual() < 1e-5, "residual {:e}", s.ledger.relative_residual());
    // Direct: the step in use at the end is within the critical step of a cold estimate (a
    // power iteration from a pseudo-random start, not the warm-started one) of the final mesh.
    let cold = s.estimate_stable_step();
    assert!(s.dt <= cold.dt_crit, "dt {:e} against the cold estimate's critical step {:e}", s.dt, cold.dt_crit);
}
