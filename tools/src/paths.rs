//! `flem paths SCENE... [--separation NAME] [--sizes N] [--out FILE]` (issue 34, must-show 2
//! and 4; docs/paths.md): runs each scene and measures the new crack's direction over its first
//! `N` element sizes at every initial crack tip (`flem_plugins::check::paths::kinks`), beside the
//! maximum tangential stress angle predicted from the implicit solution's `K_I`, `K_II` at that
//! tip (`check::sif::stage_sif`, first stage, domains of 4, 6 and 8 element sizes). Also the
//! fragments of fewer than 3 elements, the events and the path method's moves. Prints a table;
//! `--out` writes the rows as JSON (atomically).
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use flem_core::plugin::traits::SeparationRule;
use flem_core::scene::Scene;
use flem_core::solver::{NoOutput, Simulation};
use flem_plugins::check::paths::{crack_faces, fragment_sizes, kinks, Kink};
use flem_plugins::check::sif::{crack_tips, stage_sif, Radii};
use flem_plugins::separation::tip_mts::kink_angle;
use serde::Serialize;

#[derive(clap::Args)]
pub struct Args {
    #[arg(required = true)]
    pub scenes: Vec<PathBuf>,
    /// Replace the scene's separation rule by this one, as TOML of `[cracking.separation]`
    /// (e.g. `type = "tip_mts"`, or just `tip_mts`).
    #[arg(long)]
    pub separation: Option<String>,
    /// Element sizes over which the kink is measured.
    #[arg(long, default_value_t = 5.0)]
    pub sizes: f64,
    /// Write the rows as JSON to this file.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// One initial tip of one run.
#[derive(Serialize)]
pub struct Row {
    pub scene: String,
    pub separation: String,
    /// The MTS angle from the implicit solution at the tip (deg; `None`: not available).
    pub mts_deg: Option<f64>,
    pub k1: Option<f64>,
    pub k2: Option<f64>,
    pub kink: Kink,
    /// Chord angle minus the MTS angle (deg).
    pub error_deg: Option<f64>,
    pub small_fragments: usize,
    pub events: u64,
    pub splits: usize,
    pub moves: usize,
    pub refused_moves: u64,
    pub wall_s: f64,
    /// The run's error, when it stopped early (the path is still measured).
    pub run_error: Option<String>,
}

/// Parses `--separation`: a bare name or TOML.
pub fn parse_rule(s: &str) -> Result<Box<dyn SeparationRule>> {
    let text = if s.contains('=') { s.to_string() } else { format!("type = \"{s}\"") };
    let r: Box<dyn SeparationRule> = toml::from_str(&text).with_context(|| format!("--separation {s}"))?;
    r.validate().map_err(|e| anyhow::anyhow!("--separation {s}: {} {}", e.key, e.msg))?;
    Ok(r)
}

fn load(path: &PathBuf, rule: Option<&str>) -> Result<Scene> {
    let mut scene = Scene::from_file(path)?;
    if let Some(r) = rule {
        let cr = scene.file.cracking.as_mut().with_context(|| format!("{}: the scene has no [cracking]", path.display()))?;
        cr.separation = parse_rule(r)?;
    }
    Ok(scene)
}

/// Runs one scene and measures it (see the module doc).
pub fn measure(path: &PathBuf, rule: Option<&str>, sizes: f64) -> Result<Vec<Row>> {
    let name = path.display().to_string();
    // The prediction: K_I, K_II of the implicit solution at the initial tips, first stage.
    let mut pre = Simulation::new(load(path, rule)?)?;
    let st = stage_sif(&mut pre, 0, None, &Radii::default()).with_context(|| format!("{name}: stress intensity factors"))?;
    let mut sim = Simulation::new(load(path, rule)?)?;
    let separation = sim.scene.file.cracking.as_ref().map(|c| format!("{:?}", c.separation)).unwrap_or_default();
    let tips = crack_tips(&sim.model);
    let initial = crack_faces(&sim.model);
    let t0 = Instant::now();
    let run_error = sim.run(&mut NoOutput).err().map(|e| e.to_string());
    let wall_s = t0.elapsed().as_secs_f64();
    let ks = kinks(&sim.model, &tips, &initial, sizes);
    let small = fragment_sizes(&sim.model).iter().filter(|&&s| s < 3).count();
    let cr = sim.cracking.as_ref();
    let (splits, moves, refused) = cr.map_or((0, 0, 0), |c| (c.n_splits, c.path.moves.len(), c.path.refused));
    Ok(ks
        .into_iter()
        .map(|k| {
            let t = st.tips.iter().find(|t| t.point == k.tip_point).and_then(|t| t.sif.as_ref());
            let (k1, k2) = (t.map(|s| s.k1), t.map(|s| s.k2));
            // A K_I at or below zero by at most 5 % of |K_II| is zero (the shear test's tip:
            // pure mode II, its faces pressed together by round-off or slightly): `kink_angle`.
            let mts = t.and_then(|s| kink_angle(s.k1, s.k2)).map(f64::to_degrees);
            let error_deg = match (k.chord_deg, mts) {
                (Some(c), Some(m)) if k.reached => Some(c - m),
                _ => None,
            };
            Row {
                scene: name.clone(),
                separation: separation.clone(),
                mts_deg: mts,
                k1,
                k2,
                kink: k,
                error_deg,
                small_fragments: small,
                events: sim.state.step,
                splits,
                moves,
                refused_moves: refused,
                wall_s,
                run_error: run_error.clone(),
            }
        })
        .collect())
}

pub fn table(rows: &[Row]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "{:<44} {:>6} {:>8} {:>8} {:>8} {:>8} {:>7} {:>5} {:>5} {:>6} {:>6} {:>7}", "scene", "tip", "h", "MTS", "chord", "lsq", "error", "frag", "br", "moves", "refus", "wall s");
    let f = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
    for r in rows {
        let k = &r.kink;
        let err = if k.reached { f(r.error_deg) } else { format!("short {:.2}", k.length / k.h) };
        let _ = writeln!(
            s,
            "{:<44} {:>6} {:>8.4} {:>8} {:>8} {:>8} {:>7} {:>5} {:>5} {:>6} {:>6} {:>7.2}{}",
            r.scene,
            k.tip_point,
            k.h,
            f(r.mts_deg),
            f(k.chord_deg),
            f(k.lsq_deg),
            err,
            r.small_fragments,
            k.branches,
            r.moves,
            r.refused_moves,
            r.wall_s,
            r.run_error.as_ref().map_or(String::new(), |e| format!("  [stopped: {}]", e.lines().next().unwrap_or("")))
        );
    }
    s
}

pub fn run(a: Args) -> Result<()> {
    anyhow::ensure!(a.sizes.is_finite() && a.sizes > 0.0, "--sizes must be finite and > 0");
    if let Some(r) = &a.separation {
        parse_rule(r)?;
    }
    let mut rows = Vec::new();
    for p in &a.scenes {
        let r = measure(p, a.separation.as_deref(), a.sizes)?;
        print!("{}", table(&r));
        rows.extend(r);
    }
    if let Some(out) = &a.out {
        let text = serde_json::to_string_pretty(&rows)?;
        flem_core::output::atomic_write(out, text.as_bytes()).with_context(|| format!("writing {}", out.display()))?;
        println!("rows in {}", out.display());
    }
    Ok(())
}
