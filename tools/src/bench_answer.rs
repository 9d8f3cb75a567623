//! `flem bench answer`: time to answer of the plastic verification scenes (issue 37), explicit
//! beside implicit, and the chart of wall time against error (ours).
//!
//! Three scenes of `configs/verification/`, each answered by:
//! - **explicit**: the scene as written (`flem run`): the strip footings pushed at constant
//!   velocity with local damping, their plateau the footing pressure `|R_y| / b` (b = 1) at the
//!   last history row; the slope's factor of safety by `flem fos` (default options: bracket
//!   [0.5, 3], 1 %), with `--warm` (ours: trials from the last stable trial's state) and with
//!   `--early` (ours: a trial stopped once it clearly flows or stands, `FosOptions::early`);
//! - **implicit**: Newton with the consistent tangent (`flem_plugins::check::newton`, the
//!   implicit plastic check) on the same mesh and law: the footing's settlement of the explicit
//!   run's end (`|v| * max_steps * dt`) prescribed in `n` load increments from rest, the plateau
//!   the footing's reaction there; the slope by `flem fos --implicit` (`crate::fos`).
//!
//! Wall time is the whole answer: model build, solve, nothing written. Each variant runs
//! `--repeat` times, the variants interleaved within a round (before/after in one run on the
//! same, possibly shared, machine); the table keeps the best time. Errors are against the
//! closed forms and the limit-equilibrium reference: Prandtl's `(2 + pi) c` = 5.1416 (Tresca),
//! Prandtl-Reissner's `N_c` = 30.14 (phi = 30 deg), Bishop's simplified method 1.3762 (circles
//! searched by tests/slope.rs, Bishop & Morgenstern's charts: 1.38); and against the explicit
//! answer of the scene as written (`vs_explicit`, the "unchanged within 0.5 %" of the issue).
//! Written: answer.json and the chart (answer.png/.svg, `flem_plot::charts::speed_accuracy`).
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use flem_core::plugin::check::PlasticCheck;
use flem_core::scene::Scene;
use flem_core::solver::fos::{factor_of_safety, FosOptions};
use flem_core::solver::{Observer, Simulation};
use serde_json::json;

#[derive(clap::Args)]
pub struct Args {
    /// Rounds of every variant (the best time is kept).
    #[arg(long, default_value_t = 1)]
    pub repeat: usize,
    /// Newton's nominal load increments for the footings (one point of the chart each).
    #[arg(long, value_delimiter = ',', default_values_t = vec![5usize, 20])]
    pub increments: Vec<usize>,
    /// Speed-ups of the footings' push to try explicit (1: the scene as written; k: the
    /// velocity times k for 1 / k of the steps, the same final settlement).
    #[arg(long, value_delimiter = ',', default_values_t = vec![1.0f64, 2.0, 3.0])]
    pub faster: Vec<f64>,
    /// Leave out the slow variants (the phi = 30 footing explicit, the implicit slope).
    #[arg(long)]
    pub quick: bool,
    /// The folder of the scenes (strip_footing.toml, strip_footing_phi30.toml, slope.toml).
    #[arg(long, default_value = "configs/verification")]
    pub dir: PathBuf,
    /// Ours (issue 37): also the Tresca footing by Newton with `NewtonCheck::shift` = 1e-8
    /// (a shifted Cholesky instead of LU at non-positive pivots) and 16 iterations per
    /// increment before a halving (instead of 25).
    #[arg(long)]
    pub newton_shift: bool,
    /// Ours (issue 37): also the footings pushed at every `--faster` speed with
    /// `[solver] mass_scaling = true` (every node's mass lowered to a common stable step).
    #[arg(long)]
    pub mass_scaling: bool,
    /// Output folder for answer.json and the chart.
    #[arg(long, default_value = "out/bench_answer")]
    pub out: PathBuf,
}

const PRANDTL: f64 = 2.0 + std::f64::consts::PI;
/// `N_c = (exp(pi tan phi) tan^2(45 + phi / 2) - 1) cot(phi)` at phi = 30 deg.
fn prandtl_reissner(phi_deg: f64) -> f64 {
    let t = phi_deg.to_radians().tan();
    ((std::f64::consts::PI * t).exp() * (std::f64::consts::FRAC_PI_4 + 0.5 * phi_deg.to_radians()).tan().powi(2) - 1.0) / t
}
/// Bishop's simplified method on the slope (tests/slope.rs: circles searched, 1.3762).
const BISHOP: f64 = 1.3762;

fn load(path: &Path) -> Result<(String, PathBuf)> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot be read", path.display()))?;
    Ok((text, path.parent().map(Path::to_path_buf).unwrap_or_default()))
}

/// The footing's pressure at every history row.
struct Pressure {
    pts: Vec<flem_core::ids::PointId>,
    last: f64,
}
impl Observer for Pressure {
    fn history(&mut self, s: &Simulation, _stage: usize) -> flem_core::Result<()> {
        self.last = s.reaction(&self.pts)[1].abs();
        Ok(())
    }
}

/// The scene pushed `k` times faster for `1 / k` of the steps (the same final settlement): the
/// footing's velocity and the step limits scaled, as a user would edit them.
fn faster(text: &str, k: f64) -> Result<String> {
    let mut v: toml::Value = toml::from_str(text)?;
    let scale_steps = |t: &mut toml::Value| {
        if let Some(n) = t.get_mut("max_steps").and_then(|x| x.as_integer()) {
            t["max_steps"] = toml::Value::Integer((n as f64 / k).round() as i64);
        }
    };
    if let Some(s) = v.get_mut("solver") {
        scale_steps(s);
    }
    for st in v.get_mut("stage").and_then(|s| s.as_array_mut()).context("no [[stage]]")? {
        scale_steps(st);
    }
    for l in v.get_mut("load").and_then(|s| s.as_array_mut()).context("no [[load]]")? {
        if l.get("name").and_then(|n| n.as_str()) == Some("footing") {
            let y = l.get("y").and_then(|y| y.as_float()).context("the footing load has no y")?;
            l["y"] = toml::Value::Float(y * k);
        }
    }
    if let Some(o) = v.get_mut("output") {
        if let Some(h) = o.get("history_every").and_then(|x| x.as_integer()) {
            o["history_every"] = toml::Value::Integer(((h as f64 / k).round() as i64).max(1));
        }
    }
    Ok(toml::to_string(&v)?)
}

/// The scene with `[solver] mass_scaling = true` (ours).
fn mass_scaled(text: &str) -> Result<String> {
    let mut v: toml::Value = toml::from_str(text)?;
    let t = v.as_table_mut().context("scene is not a table")?;
    let s = t.entry("solver").or_insert_with(|| toml::Value::Table(Default::default()));
    s.as_table_mut().context("[solver] is not a table")?.insert("mass_scaling".into(), toml::Value::Boolean(true));
    Ok(toml::to_string(&v)?)
}

/// The footing explicit, pushed `k` times as fast as written (1: as written): (plateau, wall
/// seconds).
fn footing_explicit(path: &Path, k: f64, scaled: bool) -> Result<(f64, f64)> {
    let (text, base) = load(path)?;
    let text = if k == 1.0 { text } else { faster(&text, k)? };
    let text = if scaled { mass_scaled(&text)? } else { text };
    let t0 = Instant::now();
    let mut s = Simulation::new(Scene::from_str(&text, path, &base)?)?;
    let pts = s.model.node_set("footing", "set", &path.display().to_string())?;
    let mut w = Pressure { pts, last: f64::NAN };
    s.run(&mut w)?;
    Ok((w.last, t0.elapsed().as_secs_f64()))
}

/// The footing by Newton: the explicit run's final settlement in `inc` increments from rest.
fn footing_implicit(path: &Path, inc: usize, shifted: bool) -> Result<(f64, f64)> {
    let (text, base) = load(path)?;
    let t0 = Instant::now();
    let mut s = Simulation::new(Scene::from_str(&text, path, &base)?)?;
    s.set_stage_levels(0);
    let st = &s.scene.file.stages[0];
    let steps = st.max_steps.unwrap_or(s.scene.file.solver.max_steps) as f64;
    let pts = s.model.node_set("footing", "set", &path.display().to_string())?;
    let foot: Vec<usize> = pts.iter().map(|p| s.model.topo.point_clusters[p.idx()][0].idx()).collect();
    let nc = s.model.topo.n_clusters();
    let mut up = vec![[0.0; 2]; nc];
    for &c in &foot {
        up[c][1] = s.state.v_pres[c][1] * steps * s.dt;
    }
    let zero = vec![[0.0; 2]; nc];
    let mut newton = flem_plugins::check::newton::NewtonCheck::new();
    if shifted {
        (newton.shift, newton.max_iter) = (1e-8, 16);
    }
    let st = newton.advance(&s.model, &s.state.fix.clone(), &zero, &up, inc)?;
    eprintln!("bench answer: {}: Newton {} increments, {} iterations, {} halvings, {}", path.display(), st.increments, st.iterations, st.bisections, st.factorisation);
    let q = foot.iter().map(|&c| newton.internal_force()[c][1]).sum::<f64>().abs();
    Ok((q, t0.elapsed().as_secs_f64()))
}

fn fos_explicit(path: &Path, warm: bool, early: bool, trend: bool) -> Result<(f64, f64)> {
    let (text, base) = load(path)?;
    let t0 = Instant::now();
    let o = FosOptions { warm, early, trend, ..FosOptions::default() };
    let r = factor_of_safety(&text, path, &base, &o, &mut |_| {})?;
    Ok((r.fos, t0.elapsed().as_secs_f64()))
}

fn fos_implicit(path: &Path) -> Result<(f64, f64)> {
    let (text, base) = load(path)?;
    let t0 = Instant::now();
    let name = path.display().to_string();
    let (fos, ..) = flem_core::solver::fos::bisect(&name, &FosOptions::default(), |f| {
        let (flows, _) = crate::fos::implicit_trial(&text, path, &base, f, 10).map_err(|e| flem_core::FlemError::Other(format!("{e:#}")))?;
        Ok((flows, ()))
    })?;
    Ok((fos, t0.elapsed().as_secs_f64()))
}

fn explicit_name(k: f64) -> String {
    if k == 1.0 {
        "explicit".into()
    } else {
        format!("explicit, pushed {k}x faster")
    }
}

struct Variant {
    scene: &'static str,
    method: String,
    reference: f64,
    run: Box<dyn Fn() -> Result<(f64, f64)>>,
}

pub fn run(a: &Args) -> Result<()> {
    anyhow::ensure!(a.repeat >= 1 && a.repeat <= 20, "--repeat: must be in [1, 20]");
    anyhow::ensure!(a.faster.contains(&1.0) && a.faster.iter().all(|&k| (1.0..=100.0).contains(&k)), "--faster: every value must be in [1, 100], and 1 (the scene as written) among them");
    anyhow::ensure!(!a.increments.is_empty() && a.increments.iter().all(|&n| (1..=1000).contains(&n)), "--increments: every value must be in [1, 1000]");
    let (tresca, phi30, slope) = (a.dir.join("strip_footing.toml"), a.dir.join("strip_footing_phi30.toml"), a.dir.join("slope.toml"));
    let nc30 = prandtl_reissner(30.0);
    let mut vs: Vec<Variant> = Vec::new();
    for &k in &a.faster {
        let p = tresca.clone();
        vs.push(Variant { scene: "footing, Tresca", method: explicit_name(k), reference: PRANDTL, run: Box::new(move || footing_explicit(&p, k, false)) });
        if a.mass_scaling {
            let p = tresca.clone();
            vs.push(Variant { scene: "footing, Tresca", method: format!("{}, mass scaling (ours)", explicit_name(k)), reference: PRANDTL, run: Box::new(move || footing_explicit(&p, k, true)) });
        }
    }
    for &n in &a.increments {
        let p = tresca.clone();
        vs.push(Variant { scene: "footing, Tresca", method: format!("implicit, {n} increments"), reference: PRANDTL, run: Box::new(move || footing_implicit(&p, n, false)) });
        if a.newton_shift {
            let p = tresca.clone();
            vs.push(Variant {
                scene: "footing, Tresca",
                method: format!("implicit, {n} increments, shifted pivots, 16 iterations (ours)"),
                reference: PRANDTL,
                run: Box::new(move || footing_implicit(&p, n, true)),
            });
        }
    }
    for &k in &a.faster {
        if !a.quick || k > 2.0 {
            let p = phi30.clone();
            vs.push(Variant { scene: "footing, phi = 30", method: explicit_name(k), reference: nc30, run: Box::new(move || footing_explicit(&p, k, false)) });
        }
        if a.mass_scaling {
            let p = phi30.clone();
            vs.push(Variant { scene: "footing, phi = 30", method: format!("{}, mass scaling (ours)", explicit_name(k)), reference: nc30, run: Box::new(move || footing_explicit(&p, k, true)) });
        }
    }
    for &n in &a.increments {
        let p = phi30.clone();
        vs.push(Variant { scene: "footing, phi = 30", method: format!("implicit, {n} increments"), reference: nc30, run: Box::new(move || footing_implicit(&p, n, false)) });
    }
    let p = slope.clone();
    vs.push(Variant { scene: "slope, fos", method: "explicit".into(), reference: BISHOP, run: Box::new(move || fos_explicit(&p, false, false, false)) });
    let p = slope.clone();
    vs.push(Variant { scene: "slope, fos", method: "explicit, warm start (ours)".into(), reference: BISHOP, run: Box::new(move || fos_explicit(&p, true, false, false)) });
    let p = slope.clone();
    vs.push(Variant { scene: "slope, fos", method: "explicit, early verdicts (ours)".into(), reference: BISHOP, run: Box::new(move || fos_explicit(&p, false, true, false)) });
    let p = slope.clone();
    vs.push(Variant { scene: "slope, fos", method: "explicit, early verdicts and trend search (ours)".into(), reference: BISHOP, run: Box::new(move || fos_explicit(&p, false, true, true)) });
    if !a.quick {
        let p = slope.clone();
        vs.push(Variant { scene: "slope, fos", method: "implicit, 10 increments".into(), reference: BISHOP, run: Box::new(move || fos_implicit(&p)) });
    }
    // Rounds: every variant once per round, interleaved.
    let mut res: Vec<(f64, Vec<f64>, Vec<f64>)> = vec![(f64::NAN, Vec::new(), Vec::new()); vs.len()];
    for round in 0..a.repeat {
        for (v, r) in vs.iter().zip(res.iter_mut()) {
            let c0 = crate::bench::cpu_seconds();
            let (ans, secs) = (v.run)().with_context(|| format!("{} by {}", v.scene, v.method))?;
            let cpu = crate::bench::cpu_seconds() - c0;
            eprintln!("bench answer: round {} {} by {}: {ans:.5} in {secs:.3} s ({cpu:.3} s CPU)", round + 1, v.scene, v.method);
            r.0 = ans;
            r.1.push(secs);
            r.2.push(cpu);
        }
    }
    let explicit_of = |scene: &str| vs.iter().zip(&res).find(|(v, _)| v.scene == scene && v.method == "explicit").map(|(_, r)| r);
    let mut rows = Vec::new();
    let mut pts = Vec::new();
    for (v, (ans, secs, cpus)) in vs.iter().zip(&res) {
        let best = secs.iter().copied().fold(f64::INFINITY, f64::min);
        let best_cpu = cpus.iter().copied().fold(f64::INFINITY, f64::min);
        let err = (ans - v.reference) / v.reference;
        let ex = explicit_of(v.scene);
        let vs_explicit = ex.map(|e| (ans - e.0) / e.0);
        let speedup = ex.map(|e| e.1.iter().copied().fold(f64::INFINITY, f64::min) / best);
        let speedup_cpu = ex.map(|e| e.2.iter().copied().fold(f64::INFINITY, f64::min) / best_cpu);
        rows.push(json!({"scene": v.scene, "method": v.method, "answer": ans, "reference": v.reference, "error": err, "vs_explicit": vs_explicit, "best_seconds": best, "seconds": secs, "explicit_over_this": speedup, "best_cpu_seconds": best_cpu, "cpu_seconds": cpus, "explicit_over_this_cpu": speedup_cpu}));
        // The chart tells at most 8 methods apart: one class per kind of method.
        let class = if v.method.starts_with("implicit") {
            "implicit"
        } else if v.method.contains("(ours)") {
            "explicit, options of ours"
        } else if v.method.contains("pushed") {
            "explicit, pushed faster"
        } else {
            "explicit, as written"
        };
        pts.push(flem_plot::charts::ChartPoint { method: class.to_string(), element: String::new(), mesh: v.scene.to_string(), wall_seconds: best, error: err.abs().max(1e-6), pareto: false });
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}: cannot be created", a.out.display()))?;
    // The table first, so that a chart that fails loses no measurement.
    flem_core::output::atomic_write(&a.out.join("answer.json"), serde_json::to_string_pretty(&json!({"bench": "answer", "repeat": a.repeat, "rows": rows}))?.as_bytes())?;
    let files = flem_plot::charts::speed_accuracy(
        &a.out.join("answer"),
        "plastic scenes: time to answer (explicit beside implicit)",
        "|answer - reference| / reference (Prandtl, Prandtl-Reissner, Bishop)",
        &pts,
    )?;
    let j = json!({"bench": "answer", "repeat": a.repeat, "rows": rows, "pictures": files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
        "note": "wall and CPU time (every thread of the process) of model build and solve, best of the rounds, variants interleaved; the machine may be shared"});
    flem_core::output::atomic_write(&a.out.join("answer.json"), serde_json::to_string_pretty(&j)?.as_bytes())?;
    println!("{}", serde_json::to_string_pretty(&j)?);
    Ok(())
}
