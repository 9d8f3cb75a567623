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
//!   rectangle, plus the implicit points and the x4 reference);
//! - `converge`: `--levels 2 --no-explicit` (two meshes, the exact initiation load only);
//! - `chart-crack`: `--quick --splits 2`;
//! - `fos`: `--max-trials 2` on every scene without a law with a strength (refused at once) and
//!   on one scene with one (configs/verification/softening_uniaxial.toml, the smallest); the
//!   other plastic scenes (strip footings, slopes, cavity, biaxial softening) are left out: one
//!   trial of each runs the scene to rest or to flow, tens of seconds to minutes each, and fos
//!   on them is verified by tests/slope.rs and tests/plasticity.rs.
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::root;

/// Every scene of configs/ (TOML files with a `[mesh]` table), sorted.
fn scenes() -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut dirs = vec![root().join("configs")];
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                dirs.push(p);
            } else if p.extension().is_some_and(|x| x == "toml") && std::fs::read_to_string(&p).unwrap().contains("[mesh]") {
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
    let out = Command::new(env!("CARGO_BIN_EXE_flem")).args(args).output().unwrap();
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

/// check, run (and plot its folder), compare on every scene.
#[test]
fn check_run_plot_compare_on_every_scene() {
    let all = scenes();
    assert!(all.len() >= 30, "{} scenes found", all.len());
    for s in &all {
        assert_eq!(tool("check", s, &[]), Outcome::Ok, "{}", s.display());
        let dir = tmp("run", s);
        let d = dir.to_str().unwrap();
        if tool("run", s, &["--out", d, "--quiet", "--max-steps", "60"]) == Outcome::Ok {
            let (code, _, stderr) = flem(&["plot", d]);
            assert!(code == Some(0) && !stderr.contains("panicked"), "flem plot {d} ({}):\n{stderr}", s.display());
        }
        let _ = std::fs::remove_dir_all(&dir);
        let dir = tmp("compare", s);
        tool("compare", s, &["--out", dir.to_str().unwrap(), "--max-steps", "60"]);
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// chart, converge, chart-crack and fos on every scene (fos: see the module doc).
#[test]
fn chart_converge_chart_crack_fos_on_every_scene() {
    let all = scenes();
    let mut ran = std::collections::BTreeMap::<&str, usize>::new();
    for s in &all {
        let dir = tmp("chart", s);
        if tool("chart", s, &["--quick", "--max-steps", "30", "--out", dir.to_str().unwrap()]) == Outcome::Ok {
            *ran.entry("chart").or_default() += 1;
        }
        let _ = std::fs::remove_dir_all(&dir);
        let dir = tmp("converge", s);
        if tool("converge", s, &["--levels", "2", "--no-explicit", "--out", dir.to_str().unwrap()]) == Outcome::Ok {
            *ran.entry("converge").or_default() += 1;
        }
        let _ = std::fs::remove_dir_all(&dir);
        let dir = tmp("crack", s);
        if tool("chart-crack", s, &["--quick", "--splits", "2", "--out", dir.to_str().unwrap()]) == Outcome::Ok {
            *ran.entry("chart-crack").or_default() += 1;
        }
        let _ = std::fs::remove_dir_all(&dir);
        let text = std::fs::read_to_string(s).unwrap();
        let plastic = text.contains("mohr_coulomb\"") && text.contains("law");
        if !plastic || s.ends_with("verification/softening_uniaxial.toml") {
            let dir = tmp("fos", s);
            if tool("fos", s, &["--max-trials", "2", "--out", dir.to_str().unwrap()]) == Outcome::Ok {
                *ran.entry("fos").or_default() += 1;
            }
            let _ = std::fs::remove_dir_all(&dir);
        }
    }
    eprintln!("succeeded: {ran:?}");
    // Each tool did its work on some scene (not only refusals): the default scene among them.
    for t in ["chart", "converge", "chart-crack"] {
        assert!(ran.get(t).copied().unwrap_or(0) >= 1, "flem {t} succeeded on no scene: {ran:?}");
    }
}
