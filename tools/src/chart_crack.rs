//! `flem chart-crack SCENE...` (issue 19): speed against accuracy for cracking, per one-stage
//! events scene (configs/events/): the explicit solver in load steps of 5, 2, 1 and 0.5 % of the
//! stage's levels at two equilibrium tolerances, and the events solver (ours).
//!
//! Errors, per run:
//! - initiation load: `|L_first - L_exact| / L_exact`, with `L_exact` the exact linear
//!   initiation load (`cracking::initiation`: bisection on the criterion, independent of both
//!   solvers);
//! - crack path: the share of split edges differing from the reference path, `|E Δ E_ref| /
//!   |E_ref|` over the edges cut by the first `n` splits (`n`: `--splits`, at most the events
//!   run's count), with the reference the explicit run of the finest step (0.5 %) and the tighter
//!   tolerance (independent of the events solver).
//!
//! Every explicit run stops after `n` splits (its wall time is that of the path compared).
//! Output per scene: `chart_crack.csv`, `<scene>_initiation.png/svg`, `<scene>_path.png/svg`
//! (log-log, Pareto front marked; `flem_plot::charts::speed_accuracy`).
use anyhow::Result;
use flem_core::cracking::initiation::initiation;
use flem_core::scene::Scene;
use flem_core::solver::events::{explicit_twin, LoggedSplit, SplitLog};
use flem_core::solver::Simulation;
use flem_core::FlemError;
use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

struct Run {
    series: String,
    step: f64,
    tolerance: f64,
    wall: f64,
    first: f64,
    edges: BTreeSet<u32>,
    splits: usize,
}

fn level(s: &LoggedSplit) -> f64 {
    s.levels.iter().copied().fold(0.0f64, |a, v| a.max(v.abs()))
}

fn pareto(pts: &[(f64, f64)]) -> Vec<bool> {
    pts.iter().enumerate().map(|(i, &(t, e))| !pts.iter().enumerate().any(|(j, &(tj, ej))| j != i && tj <= t && ej <= e && (tj < t || ej < e))).collect()
}

/// One scene's sweep.
fn sweep(path: &Path, n_max: usize, out: &Path, csv: &mut String) -> Result<()> {
    // A file name without dots (the pictures' names get an extension).
    let stem = path.file_stem().map(|s| s.to_string_lossy().replace('.', "_")).unwrap_or_default();
    // The exact initiation load.
    let mut sim = Simulation::new(Scene::from_file(path)?)?;
    let target = sim.scene.file.stages[0].levels.values().copied().fold(0.0f64, |a, v| a.max(v.abs()));
    sim.set_stage_levels(0);
    let u1 = flem_plugins::check::static_solve(&sim)?;
    let crit = &sim.scene.file.cracking.as_ref().expect("a cracking scene").criterion;
    let cr = sim.cracking.as_mut().expect("cracking");
    let scale = cr.scale.clone();
    let exact = initiation(crit.as_ref(), &scale, &sim.model, &u1, cr.nonlocal.as_mut())?.factor * target;
    // The events run, stopped after the splits compared (solver.max_events, one split per event
    // with max_splits_per_check = 1) so that both solvers are timed on the same path.
    let mut sc = Scene::from_file(path)?;
    sc.file.solver.max_events = n_max as u64;
    // The events part alone is timed (a loose fragment's explicit march is not the crack path).
    sc.file.solver.on_loose_fragment = flem_core::scene::LooseFragment::Stop;
    let t = Instant::now();
    let mut ev_sim = Simulation::new(sc)?;
    let mut log = SplitLog { splits: Vec::new(), stop_after: usize::MAX };
    ev_sim.run(&mut log)?;
    let wall = t.elapsed().as_secs_f64();
    anyhow::ensure!(!log.splits.is_empty(), "{}: the events run made no split", path.display());
    let n = n_max.min(log.splits.len());
    let edges = |l: &[LoggedSplit]| l.iter().take(n).flat_map(|s| s.edges.iter().copied()).collect::<BTreeSet<u32>>();
    let mut runs = vec![Run { series: "events (ours)".into(), step: 0.0, tolerance: 0.0, wall, first: level(&log.splits[0]), edges: edges(&log.splits), splits: log.splits.len().min(n) }];
    let t_init = exact / target;
    for tol in [1e-4, 1e-5] {
        for step in [0.05, 0.02, 0.01, 0.005] {
            let mut sc = Scene::from_file(path)?;
            explicit_twin(&mut sc, ((t_init / step).floor() as u64).max(1), step, 1.0, 2_000_000, tol)?;
            let t = Instant::now();
            let mut s = Simulation::new(sc)?;
            let mut l = SplitLog { splits: Vec::new(), stop_after: n };
            match s.run(&mut l) {
                Ok(()) | Err(FlemError::Interrupted { .. }) => {}
                Err(e) => return Err(e.into()),
            }
            let wall = t.elapsed().as_secs_f64();
            eprintln!("{stem}: explicit step {step} tol {tol:e}: {} splits, {wall:.2} s", l.splits.len());
            let first = l.splits.first().map_or(f64::NAN, level);
            runs.push(Run { series: format!("explicit, tolerance {tol:e}"), step, tolerance: tol, wall, first, edges: edges(&l.splits), splits: l.splits.len() });
        }
    }
    let reference = runs.iter().find(|r| r.step == 0.005 && r.tolerance == 1e-5).map(|r| r.edges.clone()).unwrap_or_default();
    let init_err: Vec<f64> = runs.iter().map(|r| ((r.first - exact) / exact).abs()).collect();
    let path_err: Vec<f64> = runs.iter().map(|r| r.edges.symmetric_difference(&reference).count() as f64 / reference.len().max(1) as f64).collect();
    let p_init = pareto(&runs.iter().zip(&init_err).map(|(r, &e)| (r.wall, e)).collect::<Vec<_>>());
    let p_path = pareto(&runs.iter().zip(&path_err).map(|(r, &e)| (r.wall, e)).collect::<Vec<_>>());
    for (k, r) in runs.iter().enumerate() {
        let _ = writeln!(csv, "{stem},{},{},{},{},{},{},{},{},{},{},{}", r.series, r.step, r.tolerance, r.wall, r.splits, r.first, exact, init_err[k], path_err[k], p_init[k], p_path[k]);
    }
    for (name, err, par, label) in [("initiation", &init_err, &p_init, "relative error of the initiation load"), ("path", &path_err, &p_path, "share of split edges differing from the reference path")]
    {
        let pts: Vec<flem_plot::charts::ChartPoint> =
            runs.iter().enumerate().map(|(k, r)| flem_plot::charts::ChartPoint { series: r.series.clone(), wall_seconds: r.wall, error: err[k], pareto: par[k] }).collect();
        flem_plot::charts::speed_accuracy(&out.join(format!("{stem}_{name}")), &format!("cracking, {name}: {stem} (first {n} splits)"), label, &pts)?;
    }
    Ok(())
}

/// `flem chart-crack`.
pub fn run(scenes: &[PathBuf], out: Option<PathBuf>, splits: usize) -> Result<()> {
    let out = out.unwrap_or_else(|| PathBuf::from("out/chart_crack"));
    let _lock = crate::lock_out(&out)?;
    flem_core::output::prepare_dir(&out)?;
    let mut csv = String::from("scene,method,load_step,tolerance,wall_seconds,splits,first_split_level,exact_initiation_level,initiation_error,path_error,pareto_initiation,pareto_path\n");
    for s in scenes {
        sweep(s, splits, &out, &mut csv)?;
    }
    flem_core::output::atomic_write(&out.join("chart_crack.csv"), csv.as_bytes())?;
    eprintln!("chart_crack.csv and <scene>_initiation/_path .png/.svg in {}", out.display());
    Ok(())
}
