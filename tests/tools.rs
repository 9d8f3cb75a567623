//! Every tool on every shipped scene (issue 41): each scene-taking subcommand of `flem` runs in a
//! quick mode on every scene of configs/ and either succeeds or refuses with a message saying why
//! the scene does not suit it. A refusal is recognised by its words: "does not suit `flem TOOL`"
//! (`tools/src/main.rs: unsuited`), or, for the scenes of configs/plugins/ (native libraries),
//! the consent refusal that names `--allow-plugins` (these tests give no consent). Anything else
//! fails the test: a panic (exit 101), another error, a signal.
//!
//! Quick modes (CI has 2 cores; the whole suite stays well under 10 min):
//! - `check`: as is; `run` and `compare`: `--max-steps 60` (every stage's step limit; the
//!   events solver's event limit); `plot`: the folder of that run;
//! - `chart`: `--quick --max-steps 30` (2 dampings x 1 safety x 2 tolerances x 2 refinements of a
//!   rectangle, plus the implicit points and the x4 reference), on every scene but the plastic
//!   footings and the biaxial softening test, whose rectangles refined x2 and x4 make each run
//!   seconds long (measured: strip_footing 55 s, strip_footing_phi30 20 s, its _fine 80 s,
//!   biaxial_softening 12 s; the whole chart of the others: 22 s);
//! - `converge`: `--levels 2 --no-explicit` (two meshes, the exact initiation load only);
//! - `chart-crack`: `--quick --splits 2`;
//! - `fos`: `--max-trials 2` on every scene but the plastic ones in [`FOS_LEFT_OUT`]: the scenes
//!   without a law with a strength are refused at once, and configs/verification/slope.toml
//!   (0.6 s) gives a factor; the footings and softening tests are loaded by a prescribed velocity
//!   (no factor of safety: "no bracket within 2 trials", 0.1 to 94 s measured) and the cavity and
//!   the fine footing take over 2 min per trial; fos itself is verified by tests/slope.rs.
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::root;

/// Every scene of configs/ (TOML files with a `[mesh]` table), sorted; of the kink scenes of
/// configs/paths/ (issue 34: 36 runs of three mesh kinds at three sizes, measured by
/// `flem paths` and tests/paths.rs) and of Winkler's L-panel (configs/lpanel/, tests/lpanel.rs)
/// only the coarsest size (`_1`), of the kink scenes only the gmsh meshes (`_quad_`, `_t3_`; the
/// structured `_q4_` files are generated rectangles like many other scenes here, and the
/// costliest: 29 s), and of the centre-crack scenes only beta = 45 deg (the 30 and 60 deg files
/// are the same scene with other load values: 60 s of the three tests' 200 s of CPU, measured); of the events solver's notched plate only h = 0.25 (h = 0.125 is the same scene
/// on the finer mesh: 11.5 s); none of Bittencourt's beam (configs/beam/, tests/beam.rs); none of
/// the Kalthoff scenes on the path method (`kalthoff_*_path.toml`: the edge rule's scenes with
/// `tip_mts`; tests/dynamic.rs runs h = 1 mm to its end, `flem check` reads both). To keep
/// the suite quick (CI time of a fresh clone).
fn scenes() -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut dirs = vec![root().join("configs")];
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                dirs.push(p);
            } else if p.extension().is_some_and(|x| x == "toml") && std::fs::read_to_string(&p).unwrap().contains("[mesh]") {
                if p.parent().is_some_and(|d| d.ends_with("configs/paths") || d.ends_with("configs/lpanel")) && !p.file_stem().is_some_and(|s| s.to_string_lossy().ends_with("_1")) {
                    continue;
                }
                // Bittencourt's beam (configs/beam/): 5 400-12 700 elements even at `_1` (beam_q4_1:
                // about 12 s of CPU over these tools); tests/beam.rs runs it and configs.rs checks
                // all nine.
                if p.parent().is_some_and(|d| d.ends_with("configs/beam")) {
                    continue;
                }
                let name = p.file_name().unwrap().to_string_lossy();
                let paths_q4 = p.parent().is_some_and(|d| d.ends_with("configs/paths")) && name.contains("_q4_");
                // The Kalthoff scenes on the path method (`_path`): the edge rule's scenes with
                // another separation rule; tests/dynamic.rs runs kalthoff_h1_path to its end.
                let kalthoff_path = name.starts_with("kalthoff_") && name.ends_with("_path.toml");
                if name.starts_with("centre_30_") || name.starts_with("centre_60_") || paths_q4 || name == "notch_plate_h0.125.toml" || kalthoff_path {
                    continue;
                }
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// What one subcommand did on one scene.
#[derive(Debug, PartialEq)]
enum Outcome {
    Ok,
    Unsuited,
}

fn flem(args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(crate::common::flem_exe()).args(args).output().unwrap();
    (out.status.code(), String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// Runs `flem TOOL SCENE ARGS...` and classifies it; panics on any other outcome.
fn tool(tool: &str, scene: &Path, args: &[&str]) -> Outcome {
    let s = scene.to_str().unwrap();
    let mut all = vec![tool, s];
    all.extend_from_slice(args);
    let t = std::time::Instant::now();
    let (code, stdout, stderr) = flem(&all);
    let rel = scene.strip_prefix(root()).unwrap_or(scene).display().to_string();
    eprintln!("{tool:<12} {rel:<55} exit {code:?} {:.2} s", t.elapsed().as_secs_f64());
    assert!(!stderr.contains("panicked"), "flem {tool} {rel} panicked:\n{stderr}");
    match code {
        Some(0) => Outcome::Ok,
        Some(1) if stderr.contains(&format!("does not suit `flem {tool}`")) => Outcome::Unsuited,
        Some(1) if rel.starts_with("configs/plugins/") && stderr.contains("--allow-plugins") => Outcome::Unsuited,
        _ => panic!("flem {} failed on {rel} (exit {code:?}) without saying that the scene does not suit it:\nstdout:\n{stdout}\nstderr:\n{stderr}", all.join(" ")),
    }
}

fn tmp(tag: &str, scene: &Path) -> PathBuf {
    let stem = scene.strip_prefix(root().join("configs")).unwrap_or(scene).display().to_string().replace(['/', '.'], "_");
    std::env::temp_dir().join(format!("flem-test-tools-{}-{tag}-{stem}", std::process::id()))
}

/// check, run (and plot its folder), compare on every scene, in three shards (scenes i with
/// i % 3 == shard) so that the suite's two threads share them: unsharded it was 48 s, the last
/// test of the suite to end, alone for its last 15 s (CI time of a fresh clone, session 23).
#[test]
fn check_run_plot_compare_on_every_scene_0() {
    check_run_plot_compare(0);
}

/// The second third of [`check_run_plot_compare_on_every_scene_0`]'s scenes.
#[test]
fn check_run_plot_compare_on_every_scene_1() {
    check_run_plot_compare(1);
}

/// The last third of [`check_run_plot_compare_on_every_scene_0`]'s scenes.
#[test]
fn check_run_plot_compare_on_every_scene_2() {
    check_run_plot_compare(2);
}

fn check_run_plot_compare(shard: usize) {
    let all = scenes();
    assert!(all.len() >= 30, "{} scenes found", all.len());
    for s in all.iter().skip(shard).step_by(3) {
        assert_eq!(tool("check", s, &[]), Outcome::Ok, "{}", s.display());
        let dir = tmp("run", s);
        let d = dir.to_str().unwrap();
        if tool("run", s, &["--out", d, "--quiet", "--max-steps", "60"]) == Outcome::Ok {
            let (code, _, stderr) = flem(&["plot", d]);
            if std::fs::read_to_string(s).unwrap().contains("dim = 3") {
                // A 3D run (issue 38): `flem plot` draws 2D runs only and says so.
                assert!(code == Some(1) && stderr.contains("folder of a 3D run"), "flem plot {d} ({}):\n{stderr}", s.display());
            } else {
                assert!(code == Some(0) && !stderr.contains("panicked"), "flem plot {d} ({}):\n{stderr}", s.display());
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
        let dir = tmp("compare", s);
        tool("compare", s, &["--out", dir.to_str().unwrap(), "--max-steps", "60"]);
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// Left out of `fos` (module doc).
const FOS_LEFT_OUT: [&str; 6] = [
    "verification/biaxial_softening.toml",
    "verification/cavity.toml",
    "verification/softening_uniaxial.toml",
    "verification/strip_footing.toml",
    "verification/strip_footing_phi30.toml",
    "verification/strip_footing_phi30_fine.toml",
];
/// Left out of `chart` (module doc).
const CHART_LEFT_OUT: [&str; 4] = ["verification/strip_footing.toml", "verification/strip_footing_phi30.toml", "verification/strip_footing_phi30_fine.toml", "verification/biaxial_softening.toml"];

/// chart, converge, chart-crack and fos on every scene (fos and chart: see the module doc), in
/// three tests so that the suite's two threads share them (`tools_on_every_scene`): chart and
/// converge on the even-numbered scenes, on the odd ones, and chart-crack and fos on all.
#[test]
fn chart_and_converge_on_every_scene_0() {
    tools_on_every_scene(&["chart", "converge"], 0, 2);
}

/// chart and converge on the odd-numbered scenes.
#[test]
fn chart_and_converge_on_every_scene_1() {
    tools_on_every_scene(&["chart", "converge"], 1, 2);
}

/// The rest of the tools on every scene: chart-crack and fos, on all of them.
#[test]
fn chart_crack_and_fos_on_every_scene() {
    tools_on_every_scene(&["chart-crack", "fos"], 0, 1);
}

/// Runs each of `tools` (of chart, converge, chart-crack, fos) in its quick mode on the scenes i
/// with i % shards == shard and asserts that each did its work on some of them (not only
/// refusals).
fn tools_on_every_scene(tools: &[&str], shard: usize, shards: usize) {
    let all = scenes();
    let mut ran = std::collections::BTreeMap::<&str, usize>::new();
    let on = |t: &str| tools.contains(&t);
    for s in all.iter().skip(shard).step_by(shards) {
        let left_out = |list: &[&str]| list.iter().any(|l| s.ends_with(l));
        if on("chart") && !left_out(&CHART_LEFT_OUT) {
            let dir = tmp("chart", s);
            if tool("chart", s, &["--quick", "--max-steps", "30", "--out", dir.to_str().unwrap()]) == Outcome::Ok {
                *ran.entry("chart").or_default() += 1;
            }
            let _ = std::fs::remove_dir_all(&dir);
        }
        if on("converge") {
            let dir = tmp("converge", s);
            if tool("converge", s, &["--levels", "2", "--no-explicit", "--out", dir.to_str().unwrap()]) == Outcome::Ok {
                *ran.entry("converge").or_default() += 1;
            }
            let _ = std::fs::remove_dir_all(&dir);
        }
        if on("chart-crack") {
            let dir = tmp("crack", s);
            if tool("chart-crack", s, &["--quick", "--splits", "2", "--out", dir.to_str().unwrap()]) == Outcome::Ok {
                *ran.entry("chart-crack").or_default() += 1;
            }
            let _ = std::fs::remove_dir_all(&dir);
        }
        if on("fos") && !left_out(&FOS_LEFT_OUT) {
            let dir = tmp("fos", s);
            if tool("fos", s, &["--max-trials", "2", "--out", dir.to_str().unwrap()]) == Outcome::Ok {
                *ran.entry("fos").or_default() += 1;
            }
            let _ = std::fs::remove_dir_all(&dir);
        }
    }
    eprintln!("succeeded: {ran:?}");
    // Each tool did its work on some scene of the shard (not only refusals); the default scene has
    // a test of its own (below).
    for t in tools {
        assert!(ran.get(t).copied().unwrap_or(0) >= 1, "flem {t} succeeded on no scene: {ran:?}");
    }
}

/// Issue 41 on the default scene (configs/paper/opening.toml: Table 1's fixed dt = 1e-4 s, no
/// support, pulled at both ends). `flem chart` keeps dt/dt_crit on the refined meshes and says
/// so, and writes the chart; `flem converge --levels 2` solves each level with a statically
/// determinate support and says so. Reference for its p_crit: docs/paper.md's 113.41 and 74.29
/// (p/(rho g)) for the 6 x 6 and 12 x 12 meshes, computed by tests/paper.rs with another
/// statically determinate support (bottom-left y, bottom-right x and y): the stresses of a free
/// body do not depend on which; tolerance 5e-5 relative (the table's two decimals).
#[test]
fn chart_and_converge_on_the_default_scene() {
    let scene = root().join("configs/paper/opening.toml");
    let dir = tmp("default-chart", &scene);
    let (code, _, stderr) = flem(&["chart", scene.to_str().unwrap(), "--quick", "--max-steps", "30", "--out", dir.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stderr.contains("refinement x2: solver.dt = 1e-4 of the scene (dt/dt_crit = 0.7207) becomes") && stderr.contains("the same ratio dt/dt_crit"), "{stderr}");
    assert!(stderr.contains("a statically determinate support was added"), "{stderr}");
    assert!(dir.join("chart.csv").is_file() && dir.join("chart.png").is_file());
    let _ = std::fs::remove_dir_all(&dir);
    let dir = tmp("default-converge", &scene);
    let (code, _, stderr) = flem(&["converge", scene.to_str().unwrap(), "--levels", "2", "--no-explicit", "--out", dir.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{stderr}");
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("converge.json")).unwrap()).unwrap();
    for (lv, want) in [(0, 113.41), (1, 74.29)] {
        let l = &json["levels"][lv];
        let p = l["p_crit"].as_f64().unwrap() * 110.0;
        assert!((p - want).abs() < 5e-5 * want + 0.005, "level {lv}: p_crit {p}, docs/paper.md {want}");
        let note = l["supports"][0].as_str().unwrap_or_else(|| panic!("level {lv}: no support note: {l}"));
        assert!(note.contains("statically determinate support") && note.contains("reactions"), "{note}");
    }
    assert!(json["levels"][1]["dt_rule"].as_str().unwrap().contains("the same ratio dt/dt_crit"));
    let _ = std::fs::remove_dir_all(&dir);
}
