//! Every scene in configs/ validates and builds; every bad scene gives its expected message.
use std::path::Path;

use flem_core::scene::Scene;
use flem_core::solver::Simulation;

use crate::common::root;

fn toml_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    let Ok(rd) = std::fs::read_dir(dir) else { return };
    let mut entries: Vec<_> = rd.flatten().map(|e| e.path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            toml_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "toml") {
            out.push(p);
        }
    }
}

/// `flem check` accepts every scene in configs/ (one process, every file named on its line).
#[test]
fn every_config_scene_passes_check() {
    let mut files = Vec::new();
    toml_files(&root().join("configs"), &mut files);
    assert!(files.len() >= 4);
    let out = std::process::Command::new(crate::common::flem_exe()).arg("check").args(&files).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for f in &files {
        assert!(stdout.contains(&format!("{}: ok", f.display())), "{} not reported ok:\n{stdout}", f.display());
    }
}

/// Every verification scene carries a `[check]` section, so that `flem run` compares each of its
/// equilibria with the implicit solve by default (issue 23), except the scenes of plastic flow
/// and large strain (issue 21), which the linear implicit check cannot judge (it refuses them).
#[test]
fn every_verification_scene_has_a_check_section() {
    flem_plugins::link();
    let mut files = Vec::new();
    toml_files(&root().join("configs/verification"), &mut files);
    assert!(files.len() >= 4, "configs/verification lost files");
    for f in files {
        let scene = Scene::from_file(&f).unwrap();
        let nonlinear = scene.file.solver.large_strain || scene.file.materials.iter().any(|m| m.law.as_ref().is_some_and(|l| !l.is_linear_elastic()));
        assert!(nonlinear || scene.file.check.is_some(), "{} has no [check] section", f.display());
    }
}

/// Node and edge sets chosen by geometry (issue 23, `[[set]]`): configs/meshes/gmsh_bar_sets.toml
/// names by segment, box and nearest point what gmsh_bar.toml names by the .msh file's groups.
/// Reference: the file's physical groups (gmsh). The sets hold the same points and edges as
/// the groups, the corner is the point at (0, 0), and the two runs agree to 1e-12.
#[test]
fn sets_by_geometry_select_what_the_mesh_groups_hold() {
    flem_plugins::link();
    let run = |name: &str| {
        let mut s = Simulation::new(Scene::from_file(&root().join("configs/meshes").join(name)).unwrap()).unwrap();
        s.run(&mut flem_core::solver::NoOutput).unwrap();
        s
    };
    let (groups, sets) = (run("gmsh_bar.toml"), run("gmsh_bar_sets.toml"));
    let m = &sets.model.mesh;
    let sorted = |v: &Vec<u32>| {
        let mut v = v.clone();
        v.sort_unstable();
        v
    };
    assert_eq!(sorted(&m.node_sets["left_line"]), sorted(&m.node_sets["left"]));
    assert_eq!(sorted(&m.node_sets["foot"]), sorted(&m.node_sets["bottom"]));
    let mut right: Vec<[u32; 2]> = m.edge_sets["right"].iter().map(|e| [e[0].min(e[1]), e[0].max(e[1])]).collect();
    right.sort_unstable();
    assert_eq!(m.edge_sets["pulled_end"], right);
    assert_eq!(m.points[m.node_sets["corner"][0] as usize], [0.0, 0.0]);
    let scale = groups.state.u.iter().map(|u| u[0].abs().max(u[1].abs())).fold(0.0, f64::max);
    assert!(scale > 0.0);
    for (a, b) in groups.state.u.iter().zip(&sets.state.u) {
        assert!((a[0] - b[0]).abs() < 1e-12 * scale && (a[1] - b[1]).abs() < 1e-12 * scale, "{a:?} vs {b:?}");
    }
}

/// Each file in tests/bad_scenes starts with `# expect: <text>`; loading it must fail with a
/// message containing that text (and the file name).
#[test]
fn bad_scenes_give_their_messages() {
    flem_plugins::link();
    let mut files = Vec::new();
    toml_files(&root().join("tests/bad_scenes"), &mut files);
    assert!(files.len() >= 5, "the bad-scene folder lost files");
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        let expect = text.lines().next().and_then(|l| l.strip_prefix("# expect: ")).unwrap_or_else(|| panic!("{}: first line must be '# expect: ...'", f.display()));
        let err = match Scene::from_file(&f) {
            Err(e) => e.to_string(),
            Ok(s) => match Simulation::new(s) {
                Err(e) => e.to_string(),
                Ok(_) => panic!("{}: expected an error containing {expect:?}, but the scene loaded", f.display()),
            },
        };
        assert!(err.contains(expect), "{}: message {err:?} does not contain {expect:?}", f.display());
        assert!(err.contains(f.file_name().unwrap().to_str().unwrap()), "{}: message {err:?} does not name the file", f.display());
    }
}

/// `flem check` exits 0 on a good scene and 1 with the message on a bad one; `flem plugins`
/// lists kinds and names.
#[test]
fn cli_check_and_plugins() {
    let exe = crate::common::flem_exe();
    let ok = std::process::Command::new(exe).arg("check").arg(root().join("configs/default.toml")).output().unwrap();
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let bad = std::process::Command::new(exe).arg("check").arg(root().join("tests/bad_scenes/unknown_key.toml")).output().unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown field"));
    let pl = std::process::Command::new(exe).arg("plugins").output().unwrap();
    let s = String::from_utf8_lossy(&pl.stdout);
    assert!(s.lines().any(|l| l.split_whitespace().collect::<Vec<_>>() == ["damping", "adaptive"]), "{s}");
}

/// Every registry entry really deserialises through typetag (the list and the registrations agree).
#[test]
fn registry_names_deserialise() {
    flem_plugins::link();
    for (kind, name) in flem_plugins::registry() {
        if kind == "damping" {
            let r: Result<Box<dyn flem_core::plugin::damping::Damping>, _> = toml::from_str(&format!("type = \"{name}\""));
            // A missing parameter is fine here; an unknown name is not.
            if let Err(e) = r {
                assert!(!e.to_string().contains("unknown variant"), "{kind} {name}: {e}");
            }
        }
    }
}

/// Each bad-mesh case of `RawMesh::validate` gives its message naming the file and element; a mesh
/// without file ids (built here by hand) names them by 0-based index and says so.
#[test]
fn bad_meshes_give_their_messages() {
    use flem_core::mesh::{CellKind, RawCell, RawMesh, ValidationOptions};
    let q = |n: [u32; 4]| RawCell { kind: CellKind::Q4, nodes: n };
    let t = |n: [u32; 3]| RawCell { kind: CellKind::T3, nodes: [n[0], n[1], n[2], 0] };
    let mesh = |points: Vec<[f64; 2]>, cells: Vec<RawCell>| RawMesh { source: "bad.msh".into(), points, cells, ..Default::default() };
    let sq = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    // Clockwise: reoriented with a warning, or refused.
    let mut m = mesh(sq.clone(), vec![q([0, 3, 2, 1])]);
    let w = m.validate(ValidationOptions::Reorient).unwrap();
    assert!(w[0].contains("bad.msh: element 0 (0-based, in file order) was clockwise"), "{w:?}");
    assert_eq!(m.cells[0].nodes, [1, 2, 3, 0]);
    let e = mesh(sq.clone(), vec![q([0, 3, 2, 1])]).validate(ValidationOptions::Refuse).unwrap_err().to_string();
    assert!(e.contains("bad.msh: element 0 (0-based, in file order) is clockwise (points [0, 3, 2, 1] (0-based, in file order))"), "{e}");
    // Zero area.
    let e = mesh(vec![[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]], vec![t([0, 1, 2])]).validate(ValidationOptions::Reorient).unwrap_err().to_string();
    assert!(e.contains("element 0 (0-based, in file order) has zero area"), "{e}");
    // Duplicate points.
    let mut pts = sq.clone();
    pts.push([1.0, 1.0]);
    let e = mesh(pts, vec![t([0, 1, 2]), t([0, 4, 3])]).validate(ValidationOptions::Reorient).unwrap_err().to_string();
    assert!(e.contains("duplicate points: point 2 (0-based, in file order) and point 4 (0-based, in file order) are both at (1, 1)"), "{e}");
    // Unreferenced point.
    let mut pts = sq.clone();
    pts.push([5.0, 5.0]);
    let e = mesh(pts, vec![q([0, 1, 2, 3])]).validate(ValidationOptions::Reorient).unwrap_err().to_string();
    assert!(e.contains("point 4 (0-based, in file order) is not used by any element"), "{e}");
    // An edge shared by three elements.
    let pts = vec![[0.0, 0.0], [1.0, 0.0], [0.5, 1.0], [0.5, -1.0], [0.5, 2.0]];
    let e = mesh(pts, vec![t([0, 1, 2]), t([1, 0, 3]), t([0, 1, 4])]).validate(ValidationOptions::Reorient).unwrap_err().to_string();
    assert!(e.contains("shared by more than two elements: element 0 (0-based, in file order), element 1 (0-based, in file order), element 2 (0-based, in file order)"), "{e}");
}

/// A diverging run (`dt` well above dt_crit, opted in) exits 1 with the step, dt and dt_crit,
/// writes no snapshot, and its summary.json holds no NaN (JSON null where a value is not finite).
#[test]
fn diverging_run_stops_and_writes_nothing_non_finite() {
    let dir = std::env::temp_dir().join(format!("flem-diverge-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(root().join("tests/bad_scenes/dt_too_large.toml")).unwrap();
    let scene = dir.join("diverge.toml");
    std::fs::write(
        &scene,
        text.replace("dt = 1.0", "dt = 1.0\nallow_unstable_dt = true\ndamping = { type = \"none\" }")
            .replace("[[stage]]", "[[load]]\nname = \"p\"\ntype = \"point\"\nnodes = \"top_right\"\nvalue = [0.1, 0.0]\n\n[[stage]]")
            + "levels = { p = 1.0 }\ndynamic = true\nmax_steps = 100000\n",
    )
    .unwrap();
    let out = std::process::Command::new(crate::common::flem_exe()).args(["run", "--quiet", "--out"]).arg(dir.join("out")).arg(&scene).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("diverged at step") && err.contains("dt_crit"), "{err}");
    let names: Vec<String> = std::fs::read_dir(dir.join("out")).unwrap().flatten().map(|e| e.file_name().to_string_lossy().to_string()).collect();
    assert!(!names.iter().any(|n| n.ends_with(".vtu")), "{names:?}");
    let summary = std::fs::read_to_string(dir.join("out/summary.json")).unwrap();
    assert!(!summary.contains("NaN") && !summary.contains("inf"), "{summary}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `flem chart --quick` on the cantilever (configs/verification/cantilever.toml) writes the
/// sweep: the explicit runs at tolerance 1e-7 agree with the implicit solve of the same mesh
/// within 1e-4 (the tolerance's order, relative L2); the implicit solution's error against
/// the analytic tip deflection (Timoshenko & Goodier: 4.02625) falls with refinement (Q4
/// locking: about 11 % then 3 %); the Pareto front is not empty. Reference: analytic, and the
/// implicit solve (independent of the explicit solver).
#[test]
fn chart_sweeps_and_marks_the_pareto_front() {
    let dir = std::env::temp_dir().join(format!("flem-chart-{}", std::process::id()));
    let out = std::process::Command::new(crate::common::flem_exe())
        .args(["chart", root().join("configs/verification/cantilever.toml").to_str().unwrap(), "--quick", "--analytic", "tip:y=-4.02625", "--out", dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let csv = std::fs::read_to_string(dir.join("chart.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 10);
    let num = |r: &Vec<&str>, i: usize| r[i].parse::<f64>().unwrap();
    let implicit: Vec<&Vec<&str>> = rows.iter().filter(|r| r[0] == "implicit").collect();
    assert_eq!(implicit.len(), 2);
    let (e1, e2) = (num(implicit[0], 11), num(implicit[1], 11));
    assert!(e1 > 0.05 && e1 < 0.2 && e2 < 0.5 * e1 && e2 > 0.001, "analytic errors {e1} -> {e2}");
    for r in rows.iter().filter(|r| r[0] == "explicit" && r[3] == "1e-7") {
        assert!(num(r, 9) < 1e-4, "explicit vs implicit at tol 1e-7: {r:?}");
    }
    assert!(rows.iter().any(|r| r[12] == "true"));
    let png = std::fs::read(dir.join("chart.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG") && png.len() > 10_000, "chart.png");
    assert!(std::fs::read_to_string(dir.join("chart.svg")).unwrap().contains("Pareto front"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A dynamic stage with `cracking.at_equilibrium = true` (the default) never checks failure:
/// the scene is accepted with a warning naming the stage and the keys to set; with
/// `at_equilibrium = false` there is no warning.
#[test]
fn dynamic_stage_with_checks_at_equilibrium_warns() {
    let text = |eq: bool| {
        format!(
            "[mesh]\ntype = \"rectangle\"\nwidth = 1.0\nheight = 1.0\nnx = 2\nny = 2\n[[material]]\nyoung_modulus = 1.0\npoisson_ratio = 0.2\ndensity = 1.0\n[[support]]\nnodes = \"bottom\"\nfix = \"xy\"\n[cracking]\nat_equilibrium = {eq}\ncheck_every = 10\n[cracking.criterion]\ntype = \"rankine\"\ntensile_strength = 1.0\n[cracking.separation]\ntype = \"sigma1_nearest\"\n[[stage]]\nname = \"settle\"\n[[stage]]\nname = \"impact\"\ndynamic = true\nmax_steps = 10\n"
        )
    };
    let s = crate::common::sim(&text(true));
    let w: Vec<&String> = s.warnings.iter().filter(|w| w.contains("at_equilibrium")).collect();
    assert_eq!(w.len(), 1, "{:?}", s.warnings);
    assert!(w[0].contains("\"impact\"") && !w[0].contains("settle") && w[0].contains("cracking.check_every"), "{}", w[0]);
    let s = crate::common::sim(&text(false));
    assert!(s.warnings.iter().all(|w| !w.contains("at_equilibrium")), "{:?}", s.warnings);
}

/// The pictures say what they show (issue 23): every frame, the crack sequence's panels too,
/// has a key of its line kinds and the stress scale; the load-displacement curve plots the
/// displacement along the load (the tension crack is pulled along +y: (0, 1)) and every stage
/// (the cracking stage, which ends at its step limit, as a hollow marker beside the filled one
/// of the stage in equilibrium). Reference: the scene's load direction and stage list.
#[test]
fn pictures_have_a_key_and_the_curve_follows_the_load_through_every_stage() {
    let dir = std::env::temp_dir().join(format!("flem-pictures-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let text = std::fs::read_to_string(root().join("configs/verification/tension_crack.toml")).unwrap() + "\n[output]\nprobes = [{ name = \"top\", at = [1.0, 4.0] }]\n";
    let scene_path = dir.with_extension("toml");
    std::fs::write(&scene_path, text).unwrap();
    let out = std::process::Command::new(crate::common::flem_exe()).args(["run", scene_path.to_str().unwrap(), "--quiet", "--plot", "--out", dir.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let curve = std::fs::read_to_string(dir.join("plots/load_displacement.svg")).unwrap();
    assert!(curve.contains("along load pull (0, 1)") && curve.contains("every stage"), "the curve's labels: {}", &curve[..curve.len().min(3000)]);
    // Two stage ends plus the key's two sample markers; the cracked stage's end (the upper part
    // flies off) sits at the chart's edge with its value noted.
    assert!(curve.matches("<circle").count() >= 4 && curve.contains("drawn at the edge: stage 2 ends at"), "stage-end markers missing");
    let seq = std::fs::read_to_string(dir.join("plots/crack_sequence.svg")).unwrap();
    for key in ["crack face, open at both ends", "joined edge", "principal stress, tension", "compression", "cross arm"] {
        assert!(seq.contains(key), "the crack sequence has no \"{key}\" in its key");
    }
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_file(&scene_path);
}

/// history.csv has one row per step it reports: a stage that ends at its step limit on a
/// multiple of `history_every` (tension_crack's cracked stage: 20000 steps, rows every 1000)
/// wrote that step's row twice, once in the loop and once at the stage end. Reference: the
/// history's own contract (one row per reported step, steps increasing).
#[test]
fn a_stage_ending_on_a_history_row_writes_it_once() {
    let dir = std::env::temp_dir().join(format!("flem-histrow-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let text = std::fs::read_to_string(root().join("configs/verification/tension_crack.toml")).unwrap().replace("\n[check]\n", "\n[output]\nhistory_every = 1000\n\n[check]\n");
    assert!(text.contains("history_every = 1000") && text.contains("max_steps = 20000"), "tension_crack.toml changed");
    let scene_path = dir.with_extension("toml");
    std::fs::write(&scene_path, text).unwrap();
    let out = std::process::Command::new(crate::common::flem_exe()).args(["run", scene_path.to_str().unwrap(), "--quiet", "--out", dir.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let hist = std::fs::read_to_string(dir.join("history.csv")).unwrap();
    let col = hist.lines().next().unwrap().split(',').position(|h| h == "step").unwrap();
    let steps: Vec<u64> = hist.lines().skip(1).map(|l| l.split(',').nth(col).unwrap().parse().unwrap()).collect();
    assert!(steps.len() > 20, "{} rows", steps.len());
    assert!(steps.windows(2).all(|w| w[0] < w[1]), "a step is reported twice or goes back: {steps:?}");
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_file(&scene_path);
}
