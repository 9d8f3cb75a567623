//! `flem fos SCENE --out DIR`: factor of safety by strength reduction (ours, issue 21). The
//! search and its criterion are `flem_core::solver::fos` (docs/materials.md); this file writes
//! DIR/fos.json and the mechanism picture DIR/mechanism.png/.svg (plastic shear strain of the
//! lowest F that flowed, on the deformed mesh).
//!
//! `--warm` (ours, off by default): the warm start of `flem_core::solver::fos` (a trial above
//! the highest F that stood starts from that trial's final state). `--implicit` (ours): every
//! trial by Newton (`flem_plugins::check::newton`, the implicit plastic check) instead of the
//! explicit march, Griffiths & Lane's criterion: the trial stands when the last stage's loads,
//! applied in `--increments` load increments (halved when an increment does not converge), reach
//! equilibrium within the Newton budget ([`implicit_trial`]), and flows when they do not; the same
//! bisection. No mechanism picture then (fos.json says so). `--early` (ours, off by default):
//! the early verdicts of `flem_core::solver::fos` (a trial's last stage stopped once its largest
//! displacement clearly accelerates or comes to rest; fos.json marks those trials `early`).
//! `--trend` (ours, off by default): the trend search of `flem_core::solver::fos` (the next
//! trial where the flowing trials' unbalanced-force ratios, extrapolated in 1 / F, vanish).
use std::path::PathBuf;

use anyhow::{Context, Result};
use flem_core::solver::fos::{factor_of_safety, FosOptions, Trial};

#[derive(clap::Args)]
pub struct Args {
    pub scene: PathBuf,
    /// Output folder (default: out/<scene name>_fos).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Initial bracket (widened when lo flows or hi stands).
    #[arg(long, default_value_t = 0.5)]
    pub lo: f64,
    #[arg(long, default_value_t = 3.0)]
    pub hi: f64,
    /// Bisect until hi - lo <= rel_tol * lo.
    #[arg(long, default_value_t = 0.01)]
    pub rel_tol: f64,
    #[arg(long, default_value_t = 16)]
    pub max_trials: usize,
    /// A stage short of its tolerance at its step limit flows when its largest displacement grew
    /// by more than this fraction over the second half of its steps.
    #[arg(long, default_value_t = 0.1)]
    pub growth: f64,
    /// Warm start (ours): a trial above the highest F that stood starts its last stage from that
    /// trial's final state instead of the initial state (fewer steps; it changes the path).
    #[arg(long)]
    pub warm: bool,
    /// Every trial by Newton (the implicit plastic check's solver) instead of the explicit
    /// march (ours; docs/materials.md).
    #[arg(long, conflicts_with_all = ["warm", "early", "trend"])]
    pub implicit: bool,
    /// Early verdicts (ours): a trial's last stage is stopped as soon as its largest
    /// displacement clearly accelerates (flows) or comes to rest (stands), judged at its history
    /// rows (fewer steps; a verdict may differ from the one at the step limit).
    #[arg(long)]
    pub early: bool,
    /// Trend search (ours): the next trial where the unbalanced-force ratios of the trials that
    /// flowed, extrapolated linearly in 1 / F, vanish, instead of the bracket's mid-point
    /// (fewer trials far from the answer; another bracket of the same width).
    #[arg(long)]
    pub trend: bool,
    /// With --implicit: nominal load increments of the last stage's loads.
    #[arg(long, default_value_t = 10)]
    pub increments: usize,
}

/// Newton's budget in a strength-reduction trial (docs/materials.md): relative residual
/// 1e-6 (the explicit slope stage stops at an unbalanced ratio of 1e-5), 15 iterations per
/// increment, 20 tries per nominal increment (halvings included).
pub const IMPLICIT_TOL: f64 = 1e-6;
pub const IMPLICIT_ITER: usize = 15;
pub const IMPLICIT_TRIES: usize = 20;

/// One implicit trial at strength factor `f`: the stages' loads and supports up to the last
/// (`Simulation::set_stage_levels`) applied by Newton from the unloaded state in `increments`
/// nominal increments. `Ok(true)`: no equilibrium within the budget (flows); `Ok(false)`: it
/// stands. Other failures (a law Newton cannot follow, a singular model) are errors.
pub fn implicit_trial(text: &str, scene: &std::path::Path, base: &std::path::Path, f: f64, increments: usize) -> Result<(bool, flem_core::plugin::check::PlasticStage)> {
    use flem_core::plugin::check::PlasticCheck;
    let sc = flem_core::solver::fos::reduced_scene(text, scene, base, f)?;
    let last = sc.file.stages.len().saturating_sub(1);
    let mut s = flem_core::solver::Simulation::new(sc)?;
    s.set_stage_levels(last);
    let fe = s.external_force()?;
    let zero = vec![[0.0; 2]; fe.len()];
    let mut newton = flem_plugins::check::newton::NewtonCheck::new();
    (newton.tol, newton.max_iter, newton.max_tries) = (IMPLICIT_TOL, IMPLICIT_ITER, IMPLICIT_TRIES);
    match newton.advance(&s.model, &s.state.fix.clone(), &fe, &zero, increments) {
        Ok(st) => Ok((false, st)),
        // The two ways Newton gives a load path up (`check/newton.rs`): no equilibrium.
        Err(flem_core::FlemError::Solve(m)) if m.contains("load increments tried") || m.contains("did not converge after") => Ok((true, Default::default())),
        Err(e) => Err(e.into()),
    }
}

fn run_implicit(a: &Args, text: &str, base: &std::path::Path, out: &std::path::Path) -> Result<()> {
    let o = FosOptions { lo: a.lo, hi: a.hi, rel_tol: a.rel_tol, max_trials: a.max_trials, growth: a.growth, warm: false, early: false, trend: false };
    let mut trials = Vec::new();
    let name = a.scene.display().to_string();
    let (fos, bracket, _, _) = flem_core::solver::fos::bisect(&name, &o, |f| {
        let t0 = std::time::Instant::now();
        let (flows, st) = implicit_trial(text, &a.scene, base, f, a.increments).map_err(|e| flem_core::FlemError::Other(format!("{e:#}")))?;
        let secs = t0.elapsed().as_secs_f64();
        eprintln!(
            "F = {f:.4}: {} (Newton: {} increments, {} iterations, {} halvings) {secs:.1} s",
            if flows { "no equilibrium (flows)" } else { "equilibrium" },
            st.increments,
            st.iterations,
            st.bisections
        );
        trials.push(serde_json::json!({"f": f, "flows": flows, "increments": st.increments, "iterations": st.iterations, "halvings": st.bisections, "seconds": secs}));
        Ok((flows, ()))
    })?;
    let json = serde_json::json!({
        "fos": fos,
        "bracket": bracket,
        "scene": name,
        "solver": "implicit (Newton, consistent tangent; flem fos --implicit)",
        "criterion": {
            "equilibrium": "Newton reaches the last stage's loads (relative residual 1e-6, 15 iterations per increment, 20 tries per nominal increment, halvings included)",
            "flows": "it does not within that budget",
            "increments": a.increments,
            "rel_tol": a.rel_tol,
        },
        "reduction": "c / F and tan(phi) / F for every law with a strength (dilation angle capped at the reduced friction angle)",
        "pictures": "none (the implicit trials keep no mechanism; run without --implicit for it)",
        "trials": trials,
    });
    flem_core::output::atomic_write(&out.join("fos.json"), serde_json::to_string_pretty(&json)?.as_bytes())?;
    println!("factor of safety {fos:.4} (implicit; bracket [{:.4}, {:.4}], {} trials); {}", bracket[0], bracket[1], trials.len(), out.join("fos.json").display());
    Ok(())
}

pub fn run(a: Args) -> Result<()> {
    let text = std::fs::read_to_string(&a.scene).with_context(|| format!("{}: cannot be read", a.scene.display()))?;
    let base = a.scene.parent().map(|p| p.to_path_buf()).unwrap_or_default();
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join(format!("{}_fos", a.scene.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default())));
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot be created", out.display()))?;
    // A scene whose laws have no strength to reduce has no factor of safety: said before any trial.
    if let Err(e) = flem_core::solver::fos::reduced_scene(&text, &a.scene, &base, 1.0) {
        if matches!(&e, flem_core::FlemError::Config { key, .. } if key == "material") {
            return Err(crate::unsuited(&a.scene, "fos", format!("it reduces the strength of the material laws, and {e}")));
        }
        return Err(e.into());
    }
    if a.implicit {
        return run_implicit(&a, &text, &base, &out);
    }
    let o = FosOptions { lo: a.lo, hi: a.hi, rel_tol: a.rel_tol, max_trials: a.max_trials, growth: a.growth, warm: a.warm, early: a.early, trend: a.trend };
    let mut show = |t: &Trial| {
        eprintln!(
            "F = {:.4}: {} (ratio {:.2e} after {} steps, {}; largest displacement {:.4e}, grew {:.1} % over the second half){} {:.1} s",
            t.f,
            if t.flows { "flows" } else { "equilibrium" },
            t.ratio,
            t.steps,
            if t.converged {
                "converged"
            } else if t.early {
                "early verdict"
            } else {
                "step limit"
            },
            t.u_max,
            100.0 * t.growth,
            t.from.map(|f| format!(" from F = {f:.4}")).unwrap_or_default(),
            t.seconds
        );
    };
    let r = factor_of_safety(&text, &a.scene, &base, &o, &mut show)?;
    // The mechanism: plastic shear strain of the lowest F that flowed, on the deformed mesh
    // (true scale: the mechanism's own displacement).
    let arr = flem_core::output::arrays::result_arrays(&r.flow);
    let (g, _) = arr.plastic.clone().context("the scene has no plastic law: no mechanism to draw")?;
    let cells: Vec<Vec<[f64; 2]>> = (0..arr.kinds.len())
        .map(|e| {
            let (s, t) = (arr.copy_offsets[e] as usize, arr.copy_offsets[e + 1] as usize);
            arr.clusters[s..t].iter().map(|&c| [arr.points[c as usize][0] + arr.displacement[c as usize][0], arr.points[c as usize][1] + arr.displacement[c as usize][1]]).collect()
        })
        .collect();
    let title = format!("{}: plastic shear strain at F = {:.4} (flows); factor of safety {:.4} in [{:.4}, {:.4}]", a.scene.display(), r.bracket[1], r.fos, r.bracket[0], r.bracket[1]);
    let files =
        flem_plot::field::element_field(&out.join("mechanism"), &flem_plot::field::Field { title: &title, label: "plastic shear strain (deformed mesh, true scale)", cells: &cells, values: &g })?;
    let mut json = serde_json::json!({
        "fos": r.fos,
        "bracket": r.bracket,
        "scene": a.scene.display().to_string(),
        "criterion": {
            "equilibrium": "the last stage reaches its unbalanced-force ratio tolerance, or its largest displacement grows by at most `growth` of its final value over the second half of its steps",
            "flows": "the ratio is above the tolerance at the step limit and the largest displacement grew by more than `growth` over the second half",
            "growth": a.growth,
            "rel_tol": a.rel_tol,
            "warm": a.warm,
        },
        "reduction": "c / F and tan(phi) / F for every law with a strength (dilation angle capped at the reduced friction angle)",
        "mechanism_f": r.bracket[1],
        "pictures": files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
        "trials": r.trials,
    });
    if a.early {
        // Only when on: the default fos.json keeps its keys.
        json["criterion"]["early"] = serde_json::json!("ours: the last stage stopped at a history row once it flows (growth over the second half so far above 3 growth with the last 3 increments of the largest displacement increasing, or from 2/5 of the step limit above growth with the last 5 increasing) or stands (from half the step limit, growth at most `growth` with the last 4 increments decreasing)");
    }
    if a.trend {
        json["criterion"]["trend"] = serde_json::json!("ours: the next F where the ratios of the two lowest F that flowed, linear in 1 / F, vanish (a trial at that estimate times 1 + rel_tol / 2, or the closing trial hi / (1 + rel_tol)); the mid-point without an estimate inside the bracket");
    }
    flem_core::output::atomic_write(&out.join("fos.json"), serde_json::to_string_pretty(&json)?.as_bytes())?;
    println!("factor of safety {:.4} (bracket [{:.4}, {:.4}], {} trials); {}", r.fos, r.bracket[0], r.bracket[1], r.trials.len(), out.join("fos.json").display());
    Ok(())
}
