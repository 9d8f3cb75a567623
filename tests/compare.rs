//! FLEM equilibrium vs the implicit check solver (issue 5), through the `[check]` path
//! (`flem_core::output::compare::Comparer`) and the `flem compare` command.
use flem_core::output::compare::{Comparer, StageComparison};
use flem_core::solver::NoOutput;

use crate::common::{root, scene};
use flem_core::solver::Simulation;

const MAT: &str = "[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.25\ndensity = 1.0\n";
const SOLVER: &str = "[solver]\ntolerance = 1e-8\nmax_steps = 2000000\n";

/// Runs a scene with `[check]` and returns the comparison rows (compare.json in a temp folder).
fn run_checked(text: &str, tag: &str) -> Vec<StageComparison> {
    let dir = std::env::temp_dir().join(format!("flem-test-compare-{tag}-{}", std::process::id()));
    let mut sim = Simulation::new(scene(text)).unwrap_or_else(|e| panic!("{tag}: {e}"));
    let mut quiet = NoOutput;
    let mut c = Comparer::new(&mut quiet, &dir).unwrap();
    sim.run(&mut c).unwrap_or_else(|e| panic!("{tag}: {e}"));
    let rows = c.rows.clone();
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("compare.json")).unwrap()).unwrap();
    assert_eq!(json["stages"].as_array().unwrap().len(), rows.len(), "{tag}: compare.json rows");
    for r in &rows {
        if r.implicit_error.is_none() {
            assert!(dir.join(r.vtu.as_ref().unwrap()).is_file(), "{tag}: VTU of stage {} missing", r.stage);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    rows
}

/// FLEM at an unbalanced-force ratio of 1e-8 agrees with the implicit solve of the same model
/// (same clusters, fixities, prescribed displacements and loads). Reference: the implicit
/// (faer Cholesky) solution. Tolerance: relative L2 difference of displacements and of nodal
/// stresses below 1e-6 at every stage. Scenes: (1) a clamped Q4 bar under an end traction
/// (bending + tension); (2) a plate with a traction-free pre-separated side notch, two stages
/// (configs/verification/notch_compare.toml); (3) distorted plane-stress T3 mesh under gravity
/// with a prescribed displacement of its top that changes between two stages.
#[test]
fn flem_matches_implicit_on_three_scenes() {
    let bar = format!(
        "[mesh]\ntype = \"rectangle\"\nwidth = 4.0\nheight = 1.0\nnx = 16\nny = 4\n{MAT}{SOLVER}[[support]]\nnodes = \"left\"\nfix = \"xy\"\n[[load]]\nname = \"tip\"\ntype = \"traction\"\nedges = \"right\"\nvalue = [0.5, -0.2]\n[[stage]]\nlevels = {{ tip = 1.0 }}\n[check]\n"
    );
    let notch = std::fs::read_to_string(root().join("configs/verification/notch_compare.toml")).unwrap();
    let t3 = format!(
        "[mesh]\ntype = \"rectangle\"\nwidth = 2.0\nheight = 1.0\nnx = 8\nny = 4\nelement = \"t3\"\ndistort = 0.2\n[model]\nplane = \"stress\"\ngravity = [0.0, -1.0]\n{MAT}{SOLVER}[[support]]\nnodes = \"bottom\"\nfix = \"xy\"\n[[load]]\nname = \"lift\"\ntype = \"displacement\"\nnodes = \"top\"\nx = 0.002\ny = 0.001\n[[stage]]\nlevels = {{ lift = 1.0 }}\n[[stage]]\nlevels = {{ lift = -0.5 }}\n[check]\ntolerance = 1e-6\n"
    );
    for (tag, text, stages) in [("bar", bar, 1), ("notch", notch, 2), ("t3", t3, 2)] {
        let rows = run_checked(&text, tag);
        assert_eq!(rows.len(), stages, "{tag}");
        for r in &rows {
            eprintln!("{tag}: {}: ratio {:?}, rel_l2 u {:?}, s {:?}, max|du| {:?}", r.name, r.unbalanced_ratio, r.rel_l2_displacement, r.rel_l2_nodal_stress, r.max_abs_displacement_error);
            assert!(r.flem_converged && r.unbalanced_ratio.unwrap() < 1e-8, "{tag}: {r:?}");
            assert!(r.implicit_error.is_none(), "{tag}: {r:?}");
            assert!(r.rel_l2_displacement.unwrap() < 1e-6 && r.rel_l2_nodal_stress.unwrap() < 1e-6, "{tag}: {r:?}");
            assert!(r.within_tolerance && r.max_abs_displacement.unwrap() > 0.0, "{tag}: {r:?}");
        }
    }
}

/// The uniaxial tension crack (configs/verification/tension_crack.toml) under a prescribed
/// displacement of the top (y only, sigma_yy = E d / H = sigma_t at d = 0.04) with `[check]`:
/// above sigma_t the crack runs across the plate at successive equilibria and separates the
/// upper part, whose only support is the prescribed y of its top edge (x free): the implicit
/// solve of that stage fails with a message naming that fragment (reference: the topology;
/// fragment 1 = the 20 elements above the crack line). The stage below sigma_t, uncracked,
/// compares within 1e-6 (FLEM ratio 1e-7).
#[test]
fn crack_separating_an_unsupported_fragment_is_named() {
    let base = std::fs::read_to_string(root().join("configs/verification/tension_crack.toml")).unwrap();
    // The scene carries its own [check] (every verification scene does).
    let text = base.replace("type = \"traction\"\nedges = \"top\"\nvalue = [0.0, 1.0]", "type = \"displacement\"\nnodes = \"top\"\ny = 0.04");
    assert!(text.contains("\n[check]"), "tension_crack.toml lost its [check] section");
    assert!(text.contains("type = \"displacement\""), "the base scene changed");
    let rows = run_checked(&text, "crack");
    assert_eq!(rows.len(), 2);
    assert!(rows[0].splits == 0 && rows[0].implicit_error.is_none() && rows[0].rel_l2_displacement.unwrap() < 1e-6, "{:?}", rows[0]);
    assert!(rows[1].splits >= 5, "{:?}", rows[1]);
    let e = rows[1].implicit_error.as_deref().unwrap_or_else(|| panic!("no implicit error after the crack: {:?}", rows[1]));
    eprintln!("{e}");
    assert!(e.contains("fragment 1 (elements 12, 13, 14, ... (0-based, in file order); 20 elements") && e.contains("leave a translation or rotation free"), "{e}");
    assert!(rows[1].rel_l2_displacement.is_none() && !rows[1].within_tolerance && rows[1].vtu.is_none());
}

/// `flem compare` on the notched plate writes compare.json with finite numbers below the
/// scene's tolerance 1e-6 for both stages, and one VTU per stage whose point data holds both
/// fields and the differences (reference: the implicit solution; tolerance 1e-6).
#[test]
fn flem_compare_cli_writes_compare_json() {
    let dir = std::env::temp_dir().join(format!("flem-test-compare-cli-{}", std::process::id()));
    let out = std::process::Command::new(crate::common::flem_exe())
        .args(["compare", root().join("configs/verification/notch_compare.toml").to_str().unwrap(), "--out", dir.to_str().unwrap()])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}\n{stdout}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("rel_l2_u") && stdout.contains("pull_shear"), "{stdout}");
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("compare.json")).unwrap()).unwrap();
    let stages = json["stages"].as_array().unwrap();
    assert_eq!(stages.len(), 2);
    for s in stages {
        for key in ["rel_l2_displacement", "max_abs_displacement_error", "rel_l2_nodal_stress", "wall_seconds_flem", "wall_seconds_implicit", "unbalanced_ratio"] {
            let v = s[key].as_f64().unwrap_or_else(|| panic!("{key} is not a number: {s}"));
            assert!(v.is_finite() && v >= 0.0, "{key} = {v}");
        }
        assert!(s["rel_l2_displacement"].as_f64().unwrap() < 1e-6 && s["rel_l2_nodal_stress"].as_f64().unwrap() < 1e-6, "{s}");
        assert!(s["unbalanced_ratio"].as_f64().unwrap() < 1e-8 && s["dofs"].as_u64().unwrap() > 100, "{s}");
        let vtu = std::fs::read_to_string(dir.join(s["vtu"].as_str().unwrap())).unwrap();
        for name in ["\"displacement\"", "displacement_implicit", "nodal_stress_implicit", "displacement_difference", "nodal_stress_difference"] {
            assert!(vtu.contains(name), "{name} missing from the VTU");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `flem compare` on every scene of configs/ with a `[check]` section (issue 39): exit 0, and
/// every stage either compared within the scene's tolerance (reference: the implicit solve of
/// the same model; tolerance: the scene's `[check] tolerance`) or reported not comparable with
/// its reason, in compare.json. The uniaxial tension crack's stage "above" (the bar cracked
/// through, FLEM at its step limit, the freed part moving) is not comparable because FLEM is not
/// at rest, and its stage "below" is compared.
#[test]
fn flem_compare_on_every_check_scene() {
    let mut found = 0;
    for dir in ["configs/verification", "configs/paper", "configs/events", "configs/converge", "configs/bench", "configs/meshes", "configs/plugins", "configs"] {
        let mut files: Vec<_> = std::fs::read_dir(root().join(dir)).unwrap().map(|e| e.unwrap().path()).filter(|p| p.extension().is_some_and(|x| x == "toml")).collect();
        files.sort();
        for p in files {
            let text = std::fs::read_to_string(&p).unwrap();
            if !text.contains("\n[check]") {
                continue;
            }
            found += 1;
            let out_dir = std::env::temp_dir().join(format!("flem-test-compare-all-{}-{}", std::process::id(), p.file_stem().unwrap().to_string_lossy()));
            let out = std::process::Command::new(crate::common::flem_exe()).args(["compare", p.to_str().unwrap(), "--out", out_dir.to_str().unwrap()]).output().unwrap();
            let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
            eprintln!("{}:\n{stdout}", p.display());
            assert!(out.status.success(), "flem compare {} exits {:?}:\n{stdout}\n{stderr}", p.display(), out.status.code());
            let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out_dir.join("compare.json")).unwrap()).unwrap();
            let tol = json["tolerance"].as_f64().unwrap();
            for s in json["stages"].as_array().unwrap() {
                let comparable = s["comparable"].as_bool().unwrap_or_else(|| panic!("{}: no comparable: {s}", p.display()));
                if comparable {
                    assert!(s["implicit_error"].is_null() && s["within_tolerance"].as_bool() == Some(true), "{}: {s}", p.display());
                    assert!(s["rel_l2_displacement"].as_f64().unwrap() <= tol && s["rel_l2_nodal_stress"].as_f64().unwrap() <= tol, "{}: {s}", p.display());
                } else {
                    let why = s["reason"].as_str().unwrap_or_else(|| panic!("{}: not comparable without a reason: {s}", p.display()));
                    assert!(why.len() > 20, "{why}");
                }
            }
            if p.ends_with("tension_crack.toml") {
                let st = json["stages"].as_array().unwrap();
                assert_eq!(st[0]["comparable"], true, "{}", st[0]);
                assert_eq!(st[1]["comparable"], false, "{}", st[1]);
                assert!(st[1]["reason"].as_str().unwrap().contains("FLEM is not at rest"), "{}", st[1]);
                assert!(stdout.contains("n/c") && stdout.contains("not comparable: FLEM is not at rest"), "{stdout}");
            }
            let _ = std::fs::remove_dir_all(&out_dir);
        }
    }
    assert!(found >= 6, "{found} scenes with [check]");
}

/// Issue 41, item 2: a body without any support under self-equilibrated loads gets a statically
/// determinate support in the implicit check (`flem_core::plugin::support`). Reference: the
/// exact solution of a plane-stress plate W x H pulled by a uniform traction p on its top and
/// bottom sides, sigma_yy = p, sigma_xx = sigma_xy = 0, u = (-nu p / E (x - x0), p / E (y - y0))
/// up to a rigid motion (Q4 reproduces it exactly). Tolerance: 1e-9 relative on the nodal stress
/// and, after the best-fit rigid motion is removed (`align_rigid`), on the displacement; the
/// reactions at the three pinned dofs below 1e-8 of the load (measured about 1e-15). The same
/// plate pulled on its top only (loads not in equilibrium) is refused, naming fragment 0.
#[test]
fn unsupported_self_equilibrated_body_gets_a_determinate_support() {
    let (e, nu, p, w, h) = (1000.0, 0.25, 2.0, 3.0, 2.0);
    let text = |bottom: f64| {
        format!(
            "[mesh]\ntype = \"rectangle\"\nwidth = {w}\nheight = {h}\nnx = 6\nny = 4\ndistort = 0.2\n[model]\nplane = \"stress\"\n[[material]]\nyoung_modulus = {e}\npoisson_ratio = {nu}\ndensity = 1.0\n[[load]]\nname = \"top\"\ntype = \"traction\"\nedges = \"top\"\nvalue = [0.0, {p}]\n[[load]]\nname = \"bottom\"\ntype = \"traction\"\nedges = \"bottom\"\nvalue = [0.0, {}]\n[[stage]]\nlevels = {{ top = 1.0, bottom = 1.0 }}\n",
            -p * bottom
        )
    };
    let mut sim = crate::common::sim(&text(1.0));
    sim.set_stage_levels(0);
    let sol = flem_plugins::check::static_solve_supported(&sim).unwrap();
    assert_eq!(sol.added.len(), 1, "{:?}", sol.added);
    let a = &sol.added[0];
    eprintln!("{}", a.note());
    assert!(a.note().contains("statically determinate support") && a.note().contains("fragment 0"));
    assert!(a.reaction.unwrap() < 1e-8 && a.resultant[0] < 1e-10 && a.resultant[1] < 1e-10, "{a:?}");
    // Pinned: both dofs of one node and one of another.
    assert_eq!(a.dofs[0].0, a.dofs[1].0);
    assert_ne!(a.dofs[0].0, a.dofs[2].0);
    let (mut corner, mut s) = (Vec::new(), Vec::new());
    sim.model.nodal_stress(&sol.u, &mut corner, &mut s);
    for v in &s {
        assert!((v[0]).abs() < 1e-9 * p && (v[1] - p).abs() < 1e-9 * p && v[2].abs() < 1e-9 * p, "{v:?}");
    }
    let x0 = sim.model.cluster_x0();
    let exact: Vec<[f64; 2]> = x0.iter().map(|x| [-nu * p / e * x[0], p / e * x[1]]).collect();
    let mut u = sol.u.clone();
    flem_core::plugin::support::align_rigid(&sim.model, &sol.added, &exact, &mut u);
    let err = flem_core::output::compare::rel_l2(&u, &exact).unwrap();
    assert!(err < 1e-9, "displacement after the rigid fit: rel L2 {err:e}");
    // The pinned solution itself is not the exact one (a rigid motion apart): the fit matters.
    assert!(flem_core::output::compare::rel_l2(&sol.u, &exact).unwrap() > 1e-3);
    // Not in equilibrium: refused, named.
    let mut sim = crate::common::sim(&text(0.0));
    sim.set_stage_levels(0);
    let e = flem_plugins::check::static_solve_supported(&sim).unwrap_err().to_string();
    assert!(e.contains("fragment 0") && e.contains("loads are not in equilibrium"), "{e}");
}

/// Issue 41, item 2, in the events solver (ours): the paper's opening model (configs/paper/
/// opening.toml, no support, pulled at both ends) run by `[solver] type = "events"` to 150: its
/// linear solves get the statically determinate support (a warning says so) and its first event
/// is at the elastic initiation load. Reference: docs/paper.md's p_crit / (rho g) = 113.41 of
/// this mesh, from tests/paper.rs's linear solve with another statically determinate support
/// (bottom-left y, bottom-right x and y); tolerance 0.005 (its two decimals).
#[test]
fn events_solver_supports_the_free_opening_model() {
    let text = std::fs::read_to_string(root().join("configs/paper/opening.toml")).unwrap();
    let mut t: toml::Table = toml::from_str(&text).unwrap();
    let solver = t["solver"].as_table_mut().unwrap();
    solver.remove("dt");
    solver.remove("damping");
    solver.insert("type".into(), toml::Value::String("events".into()));
    t["cracking"].as_table_mut().unwrap().remove("at_equilibrium");
    t["output"].as_table_mut().unwrap().insert("plots".into(), toml::Value::Boolean(false));
    let stage: toml::Table = toml::from_str("name = \"p150\"\nlevels = { p = 150.0, p_bottom = 150.0 }").unwrap();
    t.insert("stage".into(), toml::Value::Array(vec![toml::Value::Table(stage)]));
    let mut sim = Simulation::new(scene(&toml::to_string(&t).unwrap())).unwrap_or_else(|e| panic!("{e}"));
    let mut log = flem_core::solver::events::SplitLog { splits: Vec::new(), stop_after: usize::MAX };
    sim.run(&mut log).unwrap_or_else(|e| panic!("{e}"));
    assert!(sim.warnings.iter().any(|w| w.contains("events solver") && w.contains("a statically determinate support was added")), "{:?}", sim.warnings);
    let first = log.splits.first().unwrap_or_else(|| panic!("no event: {:?}", sim.warnings)).levels[0];
    assert!((first - 113.41).abs() < 0.005, "first event at {first}, docs/paper.md 113.41");
}
