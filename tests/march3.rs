//! The 3D explicit march (issue 38: `flem_core::solver::march3`, scenes with `[model] dim = 3`)
//! against independent references: its equilibrium against the 3D implicit solve
//! (`flem_plugins::check::solid3`, a sparse Cholesky on the assembled stiffness), and its
//! cracking against the 2D plane-strain model of the same section. References and tolerances
//! at each test.
use std::path::Path;

use flem_core::mesh::AnyMesh;
use flem_core::scene3::Scene3;
use flem_core::solver::march3::{March3, Observer3};
use flem_plugins::check::solid3::{self, FaceLoad, FaceLoadKind, Problem3};
use flem_plugins::elements3d::Kind3;

struct Quiet;
impl Observer3 for Quiet {}

fn scene(text: &str) -> Scene3 {
    flem_plugins::link();
    Scene3::from_str(text, Path::new("tests/march3.rs scene"), &crate::common::root()).unwrap()
}

/// A beam 4 x 1 x 1 clamped at x = 0 under a pressure on its top face, on bricks (h8, h8_full)
/// and tetrahedra (t4): the explicit march at rest (unbalanced-force ratio 1e-11, the paper's
/// damping replaced by the default adaptive relaxation) equals the implicit solve of the same
/// mesh, kind and loads. Reference: the implicit solve; tolerance 1e-6 of the largest
/// displacement (issue 38 must-show 2), on every displacement component of every point.
#[test]
fn explicit_3d_equilibrium_equals_the_implicit_solve() {
    // `hex`: the implicit solve's kind for bricks (tetrahedra are always t4).
    for (cell, kind, hex) in [("h8", "h8", Kind3::H8), ("h8", "h8_full", Kind3::H8Full), ("t4", "t4", Kind3::H8)] {
        let text = format!(
            r#"
[model]
dim = 3
[mesh]
type = "box"
size = [4.0, 1.0, 1.0]
nx = 8
ny = 2
nz = 2
element = "{cell}"
[[material]]
young_modulus = 1000.0
poisson_ratio = 0.25
density = 1.0
element = "{kind}"
[solver]
tolerance = 1e-11
max_steps = 400000
[[support]]
nodes = "xmin"
fix = "xyz"
[[load]]
name = "p"
type = "pressure"
faces = "ymax"
value = 0.5
[[stage]]
levels = {{ p = 1.0 }}
"#
        );
        let mut sc = scene(&text);
        let mut m = March3::from_scene(&mut sc).unwrap();
        let r = m.run_scene(&sc, &mut Quiet).unwrap();
        assert!(r[0].at_rest, "{kind}: not at rest after {} steps (ratio {})", r[0].steps, r[0].ratio);
        let AnyMesh::Three(mesh) = sc.file.mesh.load_any(&crate::common::root()).unwrap() else { panic!() };
        let mut p = Problem3::new(&mesh, 1000.0, 0.25);
        p.hex = hex;
        for &q in &mesh.node_sets["xmin"] {
            p.fix[q as usize] = 7;
        }
        p.face_loads.push(FaceLoad { faces: mesh.face_sets["ymax"].clone(), load: FaceLoadKind::Pressure(0.5) });
        let imp = solid3::solve(&p).unwrap();
        let umax = imp.u.iter().flat_map(|u| u.iter().map(|x| x.abs())).fold(0.0, f64::max);
        assert!(umax > 1e-3, "{kind}: the beam bends ({umax})");
        // No split: cluster i is point i.
        let err = (0..mesh.points.len()).flat_map(|i| (0..3).map(move |d| (i, d))).map(|(i, d)| (m.state.u[i][d] - imp.u[i][d]).abs()).fold(0.0, f64::max);
        eprintln!("{kind}: {} steps, max |u_flem - u_implicit| / max |u| = {:.2e}", r[0].steps, err / umax);
        assert!(err <= 1e-6 * umax, "{kind}: {:.3e} of the largest displacement", err / umax);
    }
}

/// The 2D notched plate of `notched_plate_cracks_like_its_plane_strain_section` (plane strain,
/// a notch from the left edge at mid-height, bottom on rollers, traction pulling the top).
fn plate_2d(element: &str) -> String {
    format!(
        r#"
[mesh]
type = "rectangle"
width = 2.0
height = 2.0
nx = 8
ny = 8
notch = {{ side = "left", y = 1.0, depth = 0.5 }}
[model]
plane = "strain"
separated = ["notch"]
[[material]]
young_modulus = 100.0
poisson_ratio = 0.2
density = 1.0
element = "{element}"
[[support]]
nodes = "bottom"
fix = "y"
[[support]]
nodes = "bottom_left"
fix = "xy"
[[load]]
name = "pull"
type = "traction"
edges = "top"
value = [0.0, 1.0]
[cracking.criterion]
type = "rankine"
tensile_strength = 1.0
[cracking.separation]
type = "sigma1_nearest"
[[stage]]
levels = {{ pull = 1.0 }}
"#
    )
}

/// The 2D mesh extruded by `t` along z (one layer of bricks: Q4 `a b c d` -> H8 `a b c d a' b'
/// c' d'`), its node sets extruded (both layers), edge sets as face sets of the extruded quads,
/// and the node set `all`.
fn extrude(m: &flem_core::mesh::RawMesh, t: f64) -> flem_core::mesh::RawMesh3 {
    use flem_core::mesh::{CellKind3, RawCell3, RawFace, RawMesh3};
    let np = m.points.len() as u32;
    let mut points: Vec<[f64; 3]> = m.points.iter().map(|p| [p[0], p[1], 0.0]).collect();
    points.extend(m.points.iter().map(|p| [p[0], p[1], t]));
    let cells = m.cells.iter().map(|c| {
        let n = c.corners();
        assert_eq!(n.len(), 4, "quadrilaterals only");
        RawCell3 { kind: CellKind3::H8, nodes: [n[0], n[1], n[2], n[3], n[0] + np, n[1] + np, n[2] + np, n[3] + np] }
    });
    let mut node_sets: std::collections::BTreeMap<String, Vec<u32>> = m.node_sets.iter().map(|(k, v)| (k.clone(), v.iter().flat_map(|&p| [p, p + np]).collect())).collect();
    node_sets.insert("all".into(), (0..2 * np).collect());
    let face_sets = m.edge_sets.iter().map(|(k, v)| (k.clone(), v.iter().map(|e| RawFace([e[0], e[1], e[1] + np, e[0] + np])).collect())).collect();
    RawMesh3 { source: "tests/march3.rs extruded plate".into(), points, cells: cells.collect(), cell_region: Vec::new(), node_sets, face_sets, ids: None }
}

/// The smallest load factor at which the criterion fails at some cluster of the 3D body (its
/// nodal stress at level 1 scaled: the body is linear before it splits), by bisection to 1e-12.
fn factor_3d(m: &March3, crit: &dyn flem_core::plugin::traits::FailureCriterion) -> f64 {
    use flem_core::plugin::traits::principal3;
    let fails = |s: &[f64; 6], l: f64| crit.check(&principal3(s.map(|x| x * l)).p, 1.0).failed();
    let mut best = f64::INFINITY;
    for s in m.nodal_stress() {
        let (mut lo, mut hi) = (0.0, 1.0);
        while !fails(&s, hi) {
            hi *= 2.0;
            if hi > 1e12 {
                break;
            }
        }
        if hi > 1e12 {
            continue;
        }
        while hi - lo > 1e-12 * hi {
            let mid = 0.5 * (lo + hi);
            if fails(&s, mid) {
                hi = mid
            } else {
                lo = mid
            }
        }
        best = best.min(hi);
    }
    best
}

/// The 2D run's splits, in order.
struct Splits2(Vec<flem_core::cracking::SplitEvent>);
impl flem_core::solver::Observer for Splits2 {
    fn splits(&mut self, _s: &flem_core::solver::Simulation, _r: &flem_core::mesh::topology::SplitRecord, ev: &[flem_core::cracking::SplitEvent]) -> flem_core::Result<()> {
        self.0.extend(ev.iter().cloned());
        Ok(())
    }
}

/// Issue 38 must-show 3 (first half): a notched slab with both faces held in z (plane strain)
/// starts to crack at the load of the 2D plane-strain model of the same section, and cracks
/// through the ligament. The slab is the 2D mesh extruded by one layer of bricks: `h8_full`
/// against `q4` (the same trilinear field with u_z = 0: the same nodal stress to the march's
/// tolerance) and `h8` against `qm6` (incompatible modes in both). Reference: the 2D model's
/// exact initiation factor (`cracking::initiation`, from the 2D implicit solve); tolerance 2 %
/// (the issue's), measured far below it. Then, loaded 5 % above its initiation load with the
/// 2D scene's protocol (a check when the body is at rest, one split per check; Rankine,
/// `sigma1_nearest`, read in 3D for the slab), the slab cracks where its section does: each
/// split of the 2D run is two splits of the slab at the same (x, y), z = 0 and z = t, in the
/// same order, across the ligament from the notch tip to the last point before the far edge
/// (where both runs stop: the hinge left there is a mechanism under load control and never
/// comes to rest); every face that opened lies in the plane y = 1. Reference: the 2D run;
/// exact positions.
#[test]
fn notched_plate_cracks_like_its_plane_strain_section() {
    use flem_core::cracking::initiation::initiation;
    use flem_core::scene::Scene;
    use flem_core::solver::march3::Support3;
    use flem_core::solver::Simulation;
    flem_plugins::link();
    for (k2, k3) in [("q4", "h8_full"), ("qm6", "h8")] {
        let sc = Scene::from_str(&plate_2d(k2), Path::new("tests/march3.rs plate"), &crate::common::root()).unwrap();
        let mesh2 = sc.file.mesh.load(&crate::common::root()).unwrap();
        let mut sim = Simulation::new(sc).unwrap();
        sim.set_stage_levels(0);
        let u1 = flem_plugins::check::static_solve(&sim).unwrap();
        let crit = &sim.scene.file.cracking.as_ref().unwrap().criterion;
        let cr = sim.cracking.as_mut().unwrap();
        let scale = cr.scale.clone();
        let f2 = initiation(crit.as_ref(), &scale, &sim.model, &u1, cr.nonlocal.as_mut()).unwrap().factor;

        let t = 0.25;
        let mut mesh3 = extrude(&mesh2, t);
        mesh3.validate(flem_core::mesh::ValidationOptions::Refuse).unwrap();
        let damping: Box<dyn flem_core::plugin::damping::Damping> = toml::from_str("type = \"adaptive\"").unwrap();
        let kind = k3.to_string();
        let material_of = |_: &str| Ok(([100.0, 0.2, 1.0], Some(kind.clone())));
        let ns = |s: &str| mesh3.node_sets[s].clone();
        let supports = [
            Support3 { points: ns("all"), fix: 4, velocity: [0.0; 3] },
            Support3 { points: ns("bottom"), fix: 2, velocity: [0.0; 3] },
            Support3 { points: ns("bottom_left"), fix: 1, velocity: [0.0; 3] },
        ];
        let mut m = March3::new(mesh3, &material_of, &supports, damping, 0.9).unwrap();
        m.separate_face_set("notch").unwrap();
        let pull = m.add_load("pull");
        // A traction of 1 on the top edge per unit thickness: a pressure of -1 on the top face.
        m.add_face_pressure(pull, "top", -1.0).unwrap();
        m.set_levels(&[("pull".to_string(), 1.0)].into());
        let steps = m.run_to_rest(1e-10, 10, 400_000).unwrap();
        assert!(m.ratio <= 1e-10, "{k3}: not at rest after {steps} steps");
        let rankine: Box<dyn flem_core::plugin::traits::FailureCriterion> = toml::from_str("type = \"rankine\"\ntensile_strength = 1.0").unwrap();
        let f3 = factor_3d(&m, rankine.as_ref());
        eprintln!("{k2} / {k3}: initiation factor 2D {f2:.9}, 3D {f3:.9}, relative difference {:.2e}", (f3 - f2).abs() / f2);
        assert!((f3 - f2).abs() <= 0.02 * f2, "{k3} vs {k2}: {f3} vs {f2}");

        // The crack, 5 % above initiation, with the 2D scene's protocol (check at rest, one
        // split per check, until a check splits nothing or the stage does not come to rest).
        let mut sc2 = Scene::from_str(&plate_2d(k2), Path::new("tests/march3.rs plate"), &crate::common::root()).unwrap();
        sc2.file.solver.tolerance = 1e-8;
        sc2.file.solver.max_steps = 30_000;
        sc2.file.cracking.as_mut().unwrap().max_splits_per_check = 1;
        sc2.file.stages[0].levels.insert("pull".into(), 1.05 * f2);
        let mut sim2 = Simulation::new(sc2).unwrap();
        let mut log = Splits2(Vec::new());
        sim2.run(&mut log).unwrap();
        let path2: Vec<[f64; 2]> = log.0.iter().map(|e| mesh2.points[e.point.idx()]).collect();
        let rule: Box<dyn flem_core::plugin::traits::SeparationRule> = toml::from_str("type = \"sigma1_nearest\"").unwrap();
        m.set_levels(&[("pull".to_string(), 1.05 * f3)].into());
        let mut path3: Vec<[f64; 3]> = Vec::new();
        loop {
            m.run_to_rest(1e-8, 10, 8_000).unwrap();
            if m.ratio > 1e-8 {
                break;
            }
            let rec = m.check_failure(rankine.as_ref(), rule.as_ref(), 1).unwrap();
            if rec.is_empty() {
                break;
            }
            path3.extend(rec.new_clusters.iter().map(|c| m.mesh.points[c.point.idx()]));
        }
        eprintln!("{k2}: 2D splits at {path2:?}");
        eprintln!("{k3}: 3D splits at {path3:?}");
        assert!(path2.len() >= 6, "{k2}: the 2D crack crosses the 6 cells of the ligament but the hinge point ({path2:?})");
        assert_eq!(path3.len(), 2 * path2.len(), "{k3}: each 2D split is two 3D splits (z = 0 and z = t)");
        for (k, p2) in path2.iter().enumerate() {
            let pair = &path3[2 * k..2 * k + 2];
            assert!(pair.iter().all(|p| p[0] == p2[0] && p[1] == p2[1]) && pair[0][2] != pair[1][2], "{k3}: split {k} at {pair:?}, 2D at {p2:?}");
        }
        for (f, face) in m.topo.faces.iter().enumerate() {
            if m.topo.crack_state(flem_core::ids::FaceId::new(f)) > 0 {
                assert!(face.corners().iter().all(|p| m.mesh.points[p.idx()][1] == 1.0), "{k3}: a face off the ligament opened");
            }
        }
    }
}

/// `[check]` in a 3D scene (`output::compare3`): every stage's FLEM equilibrium against the
/// implicit solve of the same body (`CheckSolver::solve_3d`: the clusters, so pre-separated
/// faces are open; each region's own material). Reference: the implicit solve (sparse
/// Cholesky on the assembled stiffness, an independent path from the explicit element loop);
/// tolerance 1e-6 on both relative L2 differences (issue 38 must-show 2), with FLEM relaxed to
/// an unbalanced-force ratio of 1e-11. A stage stopped at its step limit is reported as not
/// comparable, with the reason.
#[test]
fn implicit_check_of_3d_scenes() {
    flem_plugins::link();
    let dir = std::env::temp_dir().join(format!("flem_check3_{}", std::process::id()));
    // Two regions of different stiffness (tetrahedra), and the notched bar (bricks) whose notch
    // is separated from the start.
    let cube = r#"
[model]
dim = 3
[mesh]
type = "gmsh"
file = "configs/3d/cube_tet_v41.msh"
[[material]]
region = "left"
young_modulus = 1000.0
poisson_ratio = 0.25
density = 1.0
[[material]]
region = "right"
young_modulus = 3000.0
poisson_ratio = 0.3
density = 2.0
[solver]
tolerance = 1e-11
max_steps = 400000
[[support]]
nodes = "xmin"
fix = "xyz"
[[load]]
name = "p"
type = "pressure"
faces = "zmax"
value = 0.5
[[load]]
name = "pull"
type = "pressure"
faces = "xmax"
value = -1.0
[check]
tolerance = 1e-6
[[stage]]
name = "loaded"
levels = { p = 1.0, pull = 1.0 }
[[stage]]
name = "cut short"
levels = { p = 2.0 }
max_steps = 50
"#;
    let bar = std::fs::read_to_string(crate::common::root().join("configs/3d/notched_bar.toml"))
        .unwrap()
        .replace("file = \"notched_bar_hex_v41.msh\"", "file = \"configs/3d/notched_bar_hex_v41.msh\"")
        .replace("tolerance = 1e-6\nmax_steps = 20000", "tolerance = 1e-11\nmax_steps = 400000")
        .replace("[cracking]\n", "[check]\n\n[cracking]\n");
    let bar: String = bar.split("[[stage]]\nname = \"cracking\"").next().unwrap().to_string();
    for (name, text, stages) in [("cube", cube.to_string(), 2), ("notched bar", bar, 1)] {
        let mut sc = Scene3::from_str(&text, Path::new(name), &crate::common::root()).unwrap();
        let out = dir.join(name.replace(' ', "_"));
        flem_core::output::prepare_dir(&out).unwrap();
        let (m, _) = flem_core::output::run3::run3_in_folder(&mut sc, &out).unwrap();
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("compare.json")).unwrap()).unwrap();
        let rows = v["stages"].as_array().unwrap();
        assert_eq!(rows.len(), stages, "{name}: one row per stage");
        let r = &rows[0];
        let (du, ds) = (r["rel_l2_displacement"].as_f64().unwrap(), r["rel_l2_nodal_stress"].as_f64().unwrap());
        eprintln!("{name}: {} clusters of {} points, {} dofs, rel_l2 u {du:.2e}, s {ds:.2e}", m.topo.n_clusters(), m.topo.n_points, r["dofs"]);
        assert!(r["comparable"].as_bool().unwrap() && r["within_tolerance"].as_bool().unwrap(), "{name}: {r}");
        assert!(du <= 1e-6 && ds <= 1e-6, "{name}: {du:e} {ds:e}");
        assert!(r["max_abs_displacement"].as_f64().unwrap() > 1e-3, "{name}: the body deforms");
        if name == "notched bar" {
            assert!(m.topo.n_clusters() > m.topo.n_points, "the notch is open in the compared body");
        } else {
            // The check's body takes the march's own supports and loads; against a reference
            // that assembles neither: `solid3` with its own face pressures, supports and each
            // region's material, FLEM's first stage at rest within 1e-6 of the largest
            // displacement.
            let first = text.split("[[stage]]\nname = \"cut short\"").next().unwrap().to_string();
            let mut sc1 = Scene3::from_str(&first, Path::new(name), &crate::common::root()).unwrap();
            let mut m1 = March3::from_scene(&mut sc1).unwrap();
            assert!(m1.run_scene(&sc1, &mut Quiet).unwrap()[0].at_rest);
            let AnyMesh::Three(mesh) = sc1.file.mesh.load_any(&crate::common::root()).unwrap() else { panic!() };
            let mut p = Problem3::new(&mesh, 1000.0, 0.25);
            p.cells = mesh.cell_region.iter().map(|r| if r == "left" { (1000.0, 0.25, Kind3::T4) } else { (3000.0, 0.3, Kind3::T4) }).collect();
            for &q in &mesh.node_sets["xmin"] {
                p.fix[q as usize] = 7;
            }
            p.face_loads.push(FaceLoad { faces: mesh.face_sets["zmax"].clone(), load: FaceLoadKind::Pressure(0.5) });
            p.face_loads.push(FaceLoad { faces: mesh.face_sets["xmax"].clone(), load: FaceLoadKind::Pressure(-1.0) });
            let imp = solid3::solve(&p).unwrap();
            let umax = imp.u.iter().flat_map(|u| u.iter().map(|x| x.abs())).fold(0.0, f64::max);
            let err = (0..mesh.points.len()).flat_map(|i| (0..3).map(move |d| (i, d))).map(|(i, d)| (m1.state.u[i][d] - imp.u[i][d]).abs()).fold(0.0, f64::max);
            eprintln!("{name}: against solid3's own loads and supports {:.2e} of the largest displacement", err / umax);
            assert!(err <= 1e-6 * umax, "{name}: {:.3e}", err / umax);
            let r = &rows[1];
            assert!(!r["comparable"].as_bool().unwrap(), "a stage at its step limit is not comparable: {r}");
            assert!(r["reason"].as_str().unwrap().contains("not at rest"), "{r}");
        }
        assert!(out.join("compare_0000_stage0.vtu").exists());
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Every file of a run folder except checkpoints, with the wall times of summary.json and
/// compare.json and the warnings (a resumed run says so) left out.
fn run_files(dir: &Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        if name.starts_with("checkpoint_") || name.starts_with('.') {
            continue;
        }
        let mut bytes = std::fs::read(e.path()).unwrap();
        if name == "summary.json" || name == "compare.json" {
            let mut v: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
            v.as_object_mut().unwrap().remove("wall_seconds");
            v.as_object_mut().unwrap().remove("warnings");
            for r in v.get_mut("stages").and_then(|s| s.as_array_mut()).into_iter().flatten() {
                r.as_object_mut().unwrap().remove("wall_seconds_flem");
                r.as_object_mut().unwrap().remove("wall_seconds_implicit");
            }
            bytes = serde_json::to_vec(&v).unwrap();
        }
        out.insert(name, bytes);
    }
    out
}

/// 3D checkpoints (`output::checkpoint3`, issue 38 must-show 3): the cracking notched bar run
/// whole, then resumed from a checkpoint taken in the middle of its cracking stage (after some
/// splits, with later rows and a cut row in the logs that the resume must drop), and a run
/// interrupted at its first step (the stop flag of SIGINT) then resumed, end with every file
/// (VTU, history.csv, splits3.csv, compare.json, summary.json but its wall time) byte for byte
/// as the uninterrupted run's. Reference: the uninterrupted run; tolerance: none (bits).
#[test]
fn checkpoints_3d_resume_bit_identically() {
    flem_plugins::link();
    let root = std::env::temp_dir().join(format!("flem_ck3_{}", std::process::id()));
    let text = std::fs::read_to_string(crate::common::root().join("configs/3d/notched_bar.toml"))
        .unwrap()
        .replace("file = \"notched_bar_hex_v41.msh\"", "file = \"configs/3d/notched_bar_hex_v41.msh\"")
        .replace("max_steps = 20000", "max_steps = 9000")
        .replace("[cracking]\n", "[output]\ncheckpoint_every = 2000\ncheckpoint_keep = 100\n\n[check]\ntolerance = 1e-3\n\n[cracking]\n");
    let scene = || Scene3::from_str(&text, Path::new("notched bar"), &crate::common::root()).unwrap();
    let run = |dir: &Path, resume: bool, stop: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>| {
        flem_core::output::prepare_dir(dir).unwrap();
        flem_core::output::run3::run3_with(&mut scene(), dir, resume, stop)
    };
    let a = root.join("whole");
    let (m, stages) = run(&a, false, None).unwrap();
    let splits = stages[1].splits;
    assert!(splits >= 2, "the bar cracks in its second stage ({splits} splits)");
    let whole = run_files(&a);
    // The checkpoints of the cracking stage: one after the first split and before the last.
    let cks = flem_core::output::checkpoint::list(&a).unwrap();
    let hash_of = |p: &Path| flem_core::output::checkpoint3::peek3(p).unwrap();
    let same = |a: &std::collections::BTreeMap<String, Vec<u8>>, what: &str| {
        let names = |m: &std::collections::BTreeMap<String, Vec<u8>>| m.keys().cloned().collect::<Vec<_>>();
        assert_eq!(names(a), names(&whole), "{what}: the same files");
        let differ: Vec<&String> = a.iter().filter(|(k, v)| whole[*k] != **v).map(|(k, _)| k).collect();
        assert!(differ.is_empty(), "{what}: {differ:?} differ from the uninterrupted run's");
    };
    // Resumed from a checkpoint in a folder as a killed run leaves it: later checkpoints gone,
    // the later stages' VTU files gone, a later row and a cut row in history.csv.
    let resume_from = |what: &str, pick: &dyn Fn(&flem_core::output::checkpoint3::Checkpoint3) -> bool| {
        let (path, ck) = cks.iter().map(|(_, p)| (p.clone(), hash_of(p))).find(|(_, ck)| pick(ck)).unwrap_or_else(|| panic!("{what}: no such checkpoint"));
        eprintln!("{what}: resuming from {} (stage {} began {} step {}, {} of {} cuts)", path.display(), ck.pos.stage, ck.pos.began, ck.pos.steps, ck.cuts.len(), m.cuts.len());
        let b = root.join(what.replace(' ', "_"));
        std::fs::create_dir_all(&b).unwrap();
        for e in std::fs::read_dir(&a).unwrap().flatten() {
            let name = e.file_name().to_string_lossy().to_string();
            let later_vtu = name.ends_with(".vtu") && name.split('_').nth(1).and_then(|n| n.parse::<usize>().ok()).is_some_and(|n| n >= ck.pos.stage);
            let later_ck = name.starts_with("checkpoint_") && name > path.file_name().unwrap().to_string_lossy().to_string();
            if !later_vtu && !later_ck {
                std::fs::copy(e.path(), b.join(e.file_name())).unwrap();
            }
        }
        let mut h = std::fs::OpenOptions::new().append(true).open(b.join("history.csv")).unwrap();
        std::io::Write::write_all(&mut h, b"9,late,1,1e0,false,1e0,0,1\n9,cu").unwrap();
        run(&b, true, None).unwrap();
        same(&run_files(&b), what);
    };
    // Inside the cracking stage between two splits, and at the end of the first stage (the
    // next stage not begun: its levels are set by the resumed run).
    resume_from("resumed mid-stage", &|ck| ck.pos.stage == 1 && ck.pos.steps > 0 && !ck.cuts.is_empty() && ck.cuts.len() < m.cuts.len());
    resume_from("resumed at a stage end", &|ck| ck.pos.stage == 1 && !ck.pos.began);
    // Interrupted at once, then resumed.
    let c = root.join("interrupted");
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
    match run(&c, false, Some(stop)) {
        Err(flem_core::FlemError::Interrupted { step, .. }) => assert_eq!(step, 0),
        other => panic!("expected an interruption, got {:?}", other.map(|r| r.1)),
    }
    // Resumed on two threads (the results are the same bits on any number of threads, and the
    // scene's hash leaves the count out).
    let mut sc2 = Scene3::from_str(&text.replace("[solver]\n", "[solver]\nthreads = 2\n"), Path::new("notched bar"), &crate::common::root()).unwrap();
    flem_core::output::run3::run3_with(&mut sc2, &c, true, None).unwrap();
    same(&run_files(&c), "interrupted and resumed on two threads");
    // A checkpoint of another scene is refused by name.
    let other = text.replace("tensile_strength = 1.0", "tensile_strength = 1.1");
    let mut sc = Scene3::from_str(&other, Path::new("edited"), &crate::common::root()).unwrap();
    let e = flem_core::output::run3::run3_with(&mut sc, &c, true, None).err().expect("an edited scene is refused").to_string();
    assert!(e.contains("another scene"), "{e}");
    let _ = std::fs::remove_dir_all(&root);
}

/// 3D checkpoints with contact (`[contact]`, section "contact3": the pairs with their history
/// and the Verlet list's build state): the block dropped onto its base (configs/3d/
/// contact_drop.toml), resumed from a checkpoint taken while pairs are open, ends with every
/// file byte for byte as the uninterrupted run's. Reference: the uninterrupted run; tolerance:
/// none (bits).
#[test]
fn checkpoints_3d_with_contact_resume_bit_identically() {
    use flem_core::contact::contact3::{Pair3, VerletState3};
    flem_plugins::link();
    let root = std::env::temp_dir().join(format!("flem_ck3c_{}", std::process::id()));
    let text = std::fs::read_to_string(crate::common::root().join("configs/3d/contact_drop.toml")).unwrap().replace("file = \"contact_drop.msh\"", "file = \"configs/3d/contact_drop.msh\"")
        + "\n[output]\ncheckpoint_every = 150\ncheckpoint_keep = 100\n";
    let run = |dir: &Path, resume: bool| {
        flem_core::output::prepare_dir(dir).unwrap();
        let mut sc = Scene3::from_str(&text, Path::new("contact drop"), &crate::common::root()).unwrap();
        flem_core::output::run3::run3_with(&mut sc, dir, resume, None).unwrap()
    };
    let a = root.join("whole");
    run(&a, false);
    let whole = run_files(&a);
    let cks = flem_core::output::checkpoint::list(&a).unwrap();
    let mid = cks
        .iter()
        .map(|(s, p)| (*s, flem_core::output::checkpoint3::peek3(p).unwrap()))
        .find(|(_, ck)| ck.section::<(Vec<Pair3>, VerletState3)>("contact3", 1).unwrap().is_some_and(|(pairs, _)| !pairs.is_empty()) && ck.pos.steps > 0)
        .expect("a checkpoint with open contact pairs");
    let b = root.join("resumed");
    std::fs::create_dir_all(&b).unwrap();
    for e in std::fs::read_dir(&a).unwrap().flatten() {
        std::fs::copy(e.path(), b.join(e.file_name())).unwrap();
    }
    for (seq, p) in &cks {
        if *seq > mid.0 {
            std::fs::remove_file(b.join(p.file_name().unwrap())).unwrap();
        }
    }
    eprintln!("resuming from checkpoint {} (step {})", mid.0, mid.1.step);
    run(&b, true);
    let got = run_files(&b);
    assert_eq!(got.keys().collect::<Vec<_>>(), whole.keys().collect::<Vec<_>>());
    let differ: Vec<&String> = got.iter().filter(|(k, v)| whole[*k] != **v).map(|(k, _)| k).collect();
    assert!(differ.is_empty(), "{differ:?} differ from the uninterrupted run's");
    let _ = std::fs::remove_dir_all(&root);
}

/// A 3D bar on rollers (x = 0, y = 0, z = 0) stretched by a prescribed velocity of its end
/// x = L (a `velocity` load over a dynamic stage of N steps), then held and relaxed: the end
/// moved v N dt, and the bar carries the uniaxial stress sxx = E v N dt / L with the other
/// components zero. Reference: that closed form; tolerance 1e-6 of sxx (FLEM relaxed to a
/// ratio of 1e-11). Before the velocity was imposed at the start of the stage (crediting its
/// kinetic energy as work, as 2D does), such a scene stopped at its first step (divergence
/// guard).
#[test]
fn velocity_load_stretches_a_bar_to_the_uniaxial_stress() {
    let text = r#"
[model]
dim = 3
[mesh]
type = "box"
size = [2.0, 1.0, 1.0]
nx = 4
ny = 2
nz = 2
element = "h8"
[[material]]
young_modulus = 1000.0
poisson_ratio = 0.25
density = 1.0
[solver]
tolerance = 1e-11
max_steps = 400000
[[support]]
nodes = "xmin"
fix = "x"
[[support]]
nodes = "ymin"
fix = "y"
[[support]]
nodes = "zmin"
fix = "z"
[[load]]
name = "pull"
type = "velocity"
nodes = "xmax"
x = 0.001
[[stage]]
name = "pull"
levels = { pull = 1.0 }
dynamic = true
max_steps = 500
[[stage]]
name = "hold"
levels = { pull = 0.0 }
"#;
    let mut sc = scene(text);
    let mut m = March3::from_scene(&mut sc).unwrap();
    let r = m.run_scene(&sc, &mut Quiet).unwrap();
    assert!(r[1].at_rest, "held: at rest ({} steps, ratio {})", r[1].steps, r[1].ratio);
    let u_end = 0.001 * 500.0 * m.dt;
    let sxx = 1000.0 * u_end / 2.0;
    let xmax = m.node_set("xmax").unwrap();
    for &p in &xmax {
        let c = m.topo.point_clusters[p as usize][0].idx();
        assert!((m.state.u[c][0] - u_end).abs() <= 1e-12 * u_end, "the end moved v N dt: {} against {u_end}", m.state.u[c][0]);
    }
    let s = m.nodal_stress();
    let err = s.iter().map(|v| (v[0] - sxx).abs().max(v[1].abs()).max(v[2].abs()).max(v[3].abs()).max(v[4].abs()).max(v[5].abs())).fold(0.0, f64::max);
    eprintln!("sxx = {sxx:.6e}; largest deviation {:.2e} of it", err / sxx);
    assert!(err <= 1e-6 * sxx, "uniaxial stress: deviation {err:e} against sxx = {sxx:e}");
}
