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
//! (log-log, Pareto front marked; `flem_plot::charts::speed_accuracy`: colour = method, marker
//! shape = tolerance). An error that is the same for every run gets `<scene>_<error>.md`, a
//! table, instead of a chart (issue 40: on the scenes of docs/events.md every run follows the
//! same path).
//!
//! `--paths` (issue 34, must-show 5): over one benchmark's scenes on several meshes (e.g.
//! configs/paths/sen_*.toml), each scene run with the paper's edge rule (`sigma1_nearest`) and
//! with `tip_mts` (ours) as `flem paths` runs it (`--separation TOML`: with the keys given, e.g.
//! session 25's setting, instead of the defaults). Error: the Hausdorff distance of the path
//! from the first initial tip up to the outer boundary (`Kink::through`) to the same rule's path
//! on the finest mesh given (smallest element size at the tip), as a percentage of the
//! specimen's size; against the run's wall time. The finest run (error 0) is the reference and
//! is left out of the chart. Output: `path_error.csv`, `path_error.png/svg`.
use anyhow::{Context, Result};
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
    /// "events (ours)" or "explicit" (the colour of the chart).
    method: String,
    /// The setting that varies ("tolerance 1e-4"; "" for the events run): the marker shape.
    setting: String,
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

/// The sweep's settings: load steps and tolerances of the explicit runs (`--quick`: two steps,
/// one tolerance; the reference path is then the finest of them).
struct Plan {
    steps: Vec<f64>,
    tolerances: Vec<f64>,
}

/// One scene's sweep.
fn sweep(path: &Path, n_max: usize, out: &Path, csv: &mut String, plan: &Plan) -> Result<()> {
    // A file name without dots (the pictures' names get an extension).
    let stem = path.file_stem().map(|s| s.to_string_lossy().replace('.', "_")).unwrap_or_default();
    let scene = Scene::from_file(path)?;
    let f = &scene.file;
    if f.solver.kind != flem_core::scene::SolverKind::Events || f.stages.len() != 1 || f.cracking.is_none() {
        return Err(crate::unsuited(
            path,
            "chart-crack",
            format!(
                "it compares the events solver with explicit load steps on a one-stage events scene with [cracking] (configs/events/); this one has solver.type = \"{}\", {} stage(s){}",
                if f.solver.kind == flem_core::scene::SolverKind::Events { "events" } else { "explicit" },
                f.stages.len(),
                if f.cracking.is_none() { ", no [cracking]" } else { "" }
            ),
        ));
    }
    // The exact initiation load.
    let mut sim = Simulation::new(scene)?;
    let target = sim.scene.file.stages[0].levels.values().copied().fold(0.0f64, |a, v| a.max(v.abs()));
    sim.set_stage_levels(0);
    let u1 = flem_plugins::check::static_solve(&sim)?;
    let crit = &sim.scene.file.cracking.as_ref().context("no [cracking]")?.criterion;
    let cr = sim.cracking.as_mut().context("no [cracking]")?;
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
    let mut runs =
        vec![Run { method: "events (ours)".into(), setting: String::new(), step: 0.0, tolerance: 0.0, wall, first: level(&log.splits[0]), edges: edges(&log.splits), splits: log.splits.len().min(n) }];
    let t_init = exact / target;
    for &tol in &plan.tolerances {
        for &step in &plan.steps {
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
            runs.push(Run { method: "explicit".into(), setting: format!("tolerance {tol:e}"), step, tolerance: tol, wall, first, edges: edges(&l.splits), splits: l.splits.len() });
        }
    }
    // The reference path: the finest step at the tighter tolerance.
    let (fine, tight) = (plan.steps.iter().copied().fold(f64::INFINITY, f64::min), plan.tolerances.iter().copied().fold(f64::INFINITY, f64::min));
    let reference = runs.iter().find(|r| r.step == fine && r.tolerance == tight).map(|r| r.edges.clone()).unwrap_or_default();
    let init_err: Vec<f64> = runs.iter().map(|r| ((r.first - exact) / exact).abs()).collect();
    let path_err: Vec<f64> = runs.iter().map(|r| r.edges.symmetric_difference(&reference).count() as f64 / reference.len().max(1) as f64).collect();
    let p_init = pareto(&runs.iter().zip(&init_err).map(|(r, &e)| (r.wall, e)).collect::<Vec<_>>());
    let p_path = pareto(&runs.iter().zip(&path_err).map(|(r, &e)| (r.wall, e)).collect::<Vec<_>>());
    for (k, r) in runs.iter().enumerate() {
        let _ = writeln!(csv, "{stem},{},{},{},{},{},{},{},{},{},{},{}", r.method, r.step, r.tolerance, r.wall, r.splits, r.first, exact, init_err[k], path_err[k], p_init[k], p_path[k]);
    }
    for (name, err, par, label) in [
        ("initiation", &init_err, &p_init, "relative error of the initiation load (dimensionless)"),
        ("path", &path_err, &p_path, "share of split edges differing from the reference path (dimensionless)"),
    ] {
        let stem_n = out.join(format!("{stem}_{name}"));
        if err.iter().all(|e| *e == err[0]) {
            // Every run has the same error: a chart would show one line of points and say no
            // more than this table (issue 40).
            let mut t = format!("# {name} of {stem}: every run has error {} (first {n} splits)\n\n", err[0]);
            t += &format!("{label}: the same for every run, so a table rather than a chart.\n\n| method | load step | tolerance | wall (s) | error |\n|---|---|---|---|---|\n");
            for (k, r) in runs.iter().enumerate() {
                let (step, tol) = if r.method == "explicit" { (format!("{} %", r.step * 100.0), format!("{:e}", r.tolerance)) } else { ("-".into(), "-".into()) };
                t += &format!("| {} | {step} | {tol} | {:.3} | {} |\n", r.method, r.wall, err[k]);
            }
            flem_core::output::atomic_write(&stem_n.with_extension("md"), t.as_bytes())?;
            eprintln!("{stem}: every run has {name} error {}: {}.md (a table) instead of a chart", err[0], stem_n.display());
            continue;
        }
        let pts: Vec<flem_plot::charts::ChartPoint> = runs
            .iter()
            .enumerate()
            .map(|(k, r)| flem_plot::charts::ChartPoint { method: r.method.clone(), element: String::new(), mesh: r.setting.clone(), wall_seconds: r.wall, error: err[k], pareto: par[k] })
            .collect();
        flem_plot::charts::speed_accuracy(&stem_n, &format!("cracking, {name}: {stem} (first {n} splits)"), label, &pts)?;
    }
    Ok(())
}

/// `flem chart-crack`; `quick`: load steps of 5 and 2 % at the tolerance 1e-4 only.
pub fn run(scenes: &[PathBuf], out: Option<PathBuf>, splits: usize, quick: bool) -> Result<()> {
    let plan = if quick { Plan { steps: vec![0.05, 0.02], tolerances: vec![1e-4] } } else { Plan { steps: vec![0.05, 0.02, 0.01, 0.005], tolerances: vec![1e-4, 1e-5] } };
    let out = out.unwrap_or_else(|| PathBuf::from("out/chart_crack"));
    let _lock = crate::lock_out(&out)?;
    flem_core::output::prepare_dir(&out)?;
    let mut csv = String::from("scene,method,load_step,tolerance,wall_seconds,splits,first_split_level,exact_initiation_level,initiation_error,path_error,pareto_initiation,pareto_path\n");
    for s in scenes {
        sweep(s, splits, &out, &mut csv, &plan)?;
    }
    flem_core::output::atomic_write(&out.join("chart_crack.csv"), csv.as_bytes())?;
    eprintln!("chart_crack.csv and <scene>_initiation/_path .png/.svg (or .md tables) in {}", out.display());
    Ok(())
}

/// The path method's name on the chart (`NAME (ours)`) and its keys (`every = 1.25; piece =
/// 0.05`, empty for a bare name; no comma: they go into a CSV field and the chart's title).
fn method_label(method: &str) -> (String, String) {
    let (name, keys) = match method.parse::<toml::Table>() {
        Ok(t) => (
            t.get("type").and_then(|v| v.as_str()).unwrap_or("?").to_string(),
            t.iter().filter(|(k, _)| *k != "type").map(|(k, v)| format!("{k} = {v}")).collect::<Vec<_>>().join("; ").replace(',', ";"),
        ),
        Err(_) => (method.trim().to_string(), String::new()),
    };
    // Every rule but the paper's edge rule (`sigma1_nearest`) is ours.
    let whose = if name == "sigma1_nearest" { "paper" } else { "ours" };
    (format!("{name} ({whose})"), keys)
}

/// `flem chart-crack --paths` (see the module doc).
/// `method`: the path method's `[cracking.separation]` as a bare name or TOML (default `tip_mts`
/// with its defaults); its label on the chart names the keys given.
pub fn run_paths(scenes: &[PathBuf], out: Option<PathBuf>, method: Option<&str>) -> Result<()> {
    let method = method.unwrap_or("tip_mts");
    crate::paths::parse_rule(method)?; // a wrong key is refused before any run or output
    let out = out.unwrap_or_else(|| PathBuf::from("out/chart_crack"));
    let _lock = crate::lock_out(&out)?;
    flem_core::output::prepare_dir(&out)?;
    let mut csv = String::from("scene,rule,h,wall_seconds,events,reference,hausdorff,percent_of_size\n");
    let mut pts: Vec<flem_plot::charts::ChartPoint> = Vec::new();
    let (method_name, keys) = method_label(method);
    let method_csv = if keys.is_empty() { method_name.clone() } else { format!("{method_name}: {keys}") };
    for (rule, label, csv_label) in [("sigma1_nearest", "edge rule (paper)", "edge rule (paper)"), (method, method_name.as_str(), method_csv.as_str())] {
        let mut rows = Vec::new();
        for s in scenes {
            let mut r = crate::paths::measure(s, Some(rule), 5.0)?;
            anyhow::ensure!(!r.is_empty(), "{}: no crack tip to follow", s.display());
            eprintln!("{}: {csv_label}: {:.2} s", s.display(), r[0].wall_s);
            rows.push(r.swap_remove(0));
        }
        let fine = rows.iter().enumerate().min_by(|a, b| a.1.kink.h.total_cmp(&b.1.kink.h)).map(|(i, _)| i).context("no scene")?;
        let size = rows[fine].size;
        for (i, r) in rows.iter().enumerate() {
            let d = flem_plugins::check::paths::hausdorff(r.kink.through(), rows[fine].kink.through(), 1e-4 * size);
            let pct = 100.0 * d / size;
            let _ = writeln!(csv, "{},{},{},{},{},{},{d},{pct}", r.scene, csv_label, r.kink.h, r.wall_s, r.events, rows[fine].scene);
            if i != fine {
                let stem = Path::new(&r.scene).file_stem().map_or(String::new(), |s| s.to_string_lossy().into_owned());
                // A `FAMILY_KIND_N` scene (configs/paths/): the mesh kind as the marker shape, the
                // refinement as its fill (the chart tells at most 5 shapes and 3 fills apart).
                let parts: Vec<&str> = stem.rsplitn(3, '_').collect();
                let (mesh, element) = match parts.as_slice() {
                    [n, kind, _] => (kind.to_string(), format!("size {n}")),
                    _ => (stem.clone(), String::new()),
                };
                pts.push(flem_plot::charts::ChartPoint { method: label.into(), element, mesh, wall_seconds: r.wall_s, error: pct.max(1e-3), pareto: false });
            }
        }
    }
    let par = pareto(&pts.iter().map(|p| (p.wall_seconds, p.error)).collect::<Vec<_>>());
    for (p, q) in pts.iter_mut().zip(par) {
        p.pareto = q;
    }
    flem_core::output::atomic_write(&out.join("path_error.csv"), csv.as_bytes())?;
    flem_plot::charts::speed_accuracy(
        &out.join("path_error"),
        &if keys.is_empty() {
            "crack path: Hausdorff distance to the finest mesh's path".to_string()
        } else {
            format!("crack path: Hausdorff distance to the finest mesh's path ({method_name}: {keys})")
        },
        "Hausdorff distance to the finest mesh's path (% of the specimen; 1e-3: equal)",
        &pts,
    )?;
    eprintln!("path_error.csv and path_error.png/.svg in {}", out.display());
    Ok(())
}
