//! Factor of safety by strength reduction (ours, issue 21; `flem fos`, docs/materials.md).
//!
//! What: the factor `F` by which the strength of every law that has one must be divided for
//! the body to stop being in equilibrium under its loads (gravity, usually). Each law
//! reduces itself ([`crate::element::law::LawCfg::strength_reduced`]; `mohr_coulomb`: `c / F`,
//! `tan(phi) / F`, `psi <= phi`), as in FLAC's `solve fos` and Griffiths & Lane (1999,
//! Geotechnique 49(3):387) and Dawson, Roth & Drescher (1999, Geotechnique 49(6):835).
//!
//! How: each trial `F` runs the scene from its start with the reduced laws (every stage, as
//! written; the stages' own `tolerance` and `max_steps` apply) and is judged by a stated
//! criterion on its **last stage**:
//! - *equilibrium* when the stage reached its unbalanced-force ratio tolerance (`converged`), or
//!   when it did not but the largest displacement grew by at most `growth` (default 10 %) of its
//!   final value over the second half of the stage's steps (a slow approach to rest);
//! - *flow* when the ratio is still above the tolerance at the step limit and the largest
//!   displacement grew by more than `growth` over the second half (a mechanism moving at a
//!   steady rate grows by about 50 %).
//!
//! The bracket `[lo, hi]` starts from the options (checked: `lo` in equilibrium, `hi` flowing;
//! else it is widened, `lo / 2` or `2 hi`, a few times) and is bisected until
//! `hi - lo <= rel_tol * lo` or `max_trials` trials. The answer is the mid-point with the bracket;
//! the simulation of the lowest `F` that flowed is kept (its plastic shear strain is the
//! mechanism). By default trials are independent runs from the initial state (no continuation
//! from the previous `F`): slower, but each trial is the scene at that strength, whatever the
//! order.
//!
//! Warm start (ours, `FosOptions::warm`, `flem fos --warm`, off by default: it changes the
//! path to each trial's state, so a verdict near the factor may change): a trial above the
//! highest `F` that stood so far starts its last stage from that trial's final state (its
//! displacements, velocities, stresses and histories: a [`Checkpoint`] taken in memory)
//! instead of from the initial state; the earlier stages are not run again. The stress of the
//! stronger soil is in equilibrium with the loads; the weaker soil's laws return what no longer
//! fits, and the stage either comes back to rest (in fewer steps than from the start) or flows.
//! Strength reduction then follows one loading path, as a continuation in `F` (Dawson, Roth &
//! Drescher 1999 restart each trial; FLAC's `solve fos` too).
use std::path::Path;

use crate::error::{FlemError, Result};
use crate::scene::Scene;
use crate::solver::{Ledger, Observer, Simulation, StagePos, State};

/// Options of the search (`flem fos --lo --hi --rel-tol --max-trials --growth`).
#[derive(Clone, Debug)]
pub struct FosOptions {
    /// Initial bracket.
    pub lo: f64,
    pub hi: f64,
    /// Stop when `hi - lo <= rel_tol * lo`.
    pub rel_tol: f64,
    /// At most this many trials (widening included).
    pub max_trials: usize,
    /// Displacement growth over the second half of a non-converged stage above which it flows.
    pub growth: f64,
    /// Warm start (ours, off by default; module docs): a trial above the highest `F` that
    /// stood starts its last stage from that trial's final state.
    pub warm: bool,
}

impl Default for FosOptions {
    fn default() -> Self {
        FosOptions { lo: 0.5, hi: 3.0, rel_tol: 0.01, max_trials: 16, growth: 0.1, warm: false }
    }
}

/// One trial strength factor and what its last stage did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Trial {
    pub f: f64,
    /// The verdict: true = the body flows at this `F`.
    pub flows: bool,
    /// The last stage reached its tolerance.
    pub converged: bool,
    /// Its unbalanced-force ratio at the end.
    pub ratio: f64,
    /// Its steps.
    pub steps: u64,
    /// Largest displacement at the end, and at the middle of the stage's steps.
    pub u_max: f64,
    pub u_max_half: f64,
    /// `(u_max - u_max_half) / u_max`.
    pub growth: f64,
    /// Wall-clock seconds of the trial.
    pub seconds: f64,
    /// The `F` of the stable trial whose final state this one started from (warm start).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub from: Option<f64>,
}

/// The answer.
pub struct FosResult {
    pub fos: f64,
    pub bracket: [f64; 2],
    pub trials: Vec<Trial>,
    /// The run at `bracket[1]` (the lowest `F` that flowed).
    pub flow: Simulation,
}

/// The scene text with every law's strength divided by `f`; an error when no law has one.
pub fn reduced_scene(text: &str, path: &Path, base: &Path, f: f64) -> Result<Scene> {
    let mut sc = Scene::from_str(text, path, base)?;
    let mut any = false;
    for m in sc.file.materials.iter_mut() {
        if let Some(r) = m.law.as_ref().and_then(|l| l.strength_reduced(f)) {
            m.law = Some(r);
            any = true;
        }
    }
    if !any {
        return Err(FlemError::config(path.display().to_string(), "material", "has no law with a strength to reduce (e.g. law = { type = \"mohr_coulomb\", ... }): no factor of safety"));
    }
    Ok(sc)
}

/// Largest displacement of the last stage at each of its history rows.
struct Watch {
    last_stage: usize,
    rows: Vec<(u64, f64)>,
}

impl Observer for Watch {
    fn history(&mut self, s: &Simulation, stage: usize) -> Result<()> {
        if stage == self.last_stage {
            let u = s.state.u.iter().map(|u| u[0].hypot(u[1])).fold(0.0, f64::max);
            self.rows.push((s.state.step, u));
        }
        Ok(())
    }
}

/// Runs one trial: the scene at strength factor `f`, judged as the module docs say.
pub fn trial(text: &str, path: &Path, base: &Path, f: f64, growth: f64) -> Result<(Trial, Simulation)> {
    trial_from(text, path, base, f, growth, None)
}

/// [`trial`], its last stage started from `warm` when given (the warm start: the final state
/// of a stable trial at the strength factor `warm.0`, captured by [`warm_state`]).
pub fn trial_from(text: &str, path: &Path, base: &Path, f: f64, growth: f64, warm: Option<(f64, &WarmState)>) -> Result<(Trial, Simulation)> {
    let t0 = std::time::Instant::now();
    let mut sc = reduced_scene(text, path, base, f)?;
    let last = sc.file.stages.len() - 1;
    let st = &sc.file.stages[last];
    let max_steps = st.max_steps.unwrap_or(sc.file.solver.max_steps);
    if max_steps >= 1_000_000_000 || max_steps < 20 {
        return Err(FlemError::config(
            path.display().to_string(),
            "solver.max_steps",
            format!("= {max_steps}: a factor of safety needs a step limit (in [20, 1e9)) at which a stage that does not come to rest counts as flowing"),
        ));
    }
    // Twenty rows over the stage: the middle and the end are among them.
    sc.file.output.history_every = (max_steps / 20).max(1);
    let mut sim = Simulation::new(sc)?;
    let mut w = Watch { last_stage: last, rows: Vec::new() };
    match warm {
        Some((_, ws)) => {
            ws.restore(&mut sim, last)?;
            sim.run_from(StagePos::start(last), &mut w)?;
        }
        None => sim.run(&mut w)?,
    }
    let res = sim.stages_done.last().expect("a stage ran");
    let u_end = sim.state.u.iter().map(|u| u[0].hypot(u[1])).fold(0.0, f64::max);
    let start = w.rows.first().map(|r| r.0).unwrap_or(0).saturating_sub(sim.scene.file.output.history_every);
    let mid = start + res.steps / 2;
    let u_half = w.rows.iter().rev().find(|r| r.0 <= mid).map(|r| r.1).unwrap_or(0.0);
    let g = if u_end > 0.0 { (u_end - u_half) / u_end } else { 0.0 };
    let flows = !res.converged && g > growth;
    let t = Trial {
        f,
        flows,
        converged: res.converged,
        ratio: res.final_ratio,
        steps: res.steps,
        u_max: u_end,
        u_max_half: u_half,
        growth: g,
        seconds: t0.elapsed().as_secs_f64(),
        from: warm.map(|s| s.0),
    };
    Ok((t, sim))
}

/// The final state of a trial that stood, kept as the warm start of the next one (its last
/// stage run again from there; `flem fos --warm`).
pub struct WarmState {
    state: State,
    blocks: Vec<Vec<f64>>,
    levels: Vec<f64>,
    ledger: Ledger,
}

impl WarmState {
    /// Puts the state into `sim`, a simulation freshly built from the same scene with other
    /// strengths (the same mesh, blocks and loads), before its stage `last`.
    fn restore(&self, sim: &mut Simulation, last: usize) -> Result<()> {
        if self.state.u.len() != sim.state.u.len() || self.blocks.len() != sim.model.blocks.len() || self.levels.len() != sim.levels.len() {
            return Err(FlemError::Other("fos warm start: the trial's model differs from the one it starts from".into()));
        }
        for (b, v) in sim.model.blocks.iter_mut().zip(&self.blocks) {
            if !b.load_state(v) {
                return Err(FlemError::Other(format!("fos warm start: block of region \"{}\" does not take the state of the last stable trial", b.region())));
            }
        }
        sim.state.clone_from(&self.state);
        sim.levels.clone_from(&self.levels);
        sim.ledger = self.ledger;
        sim.stages_done.truncate(last);
        Ok(())
    }
}

/// The warm start of `sim` after a trial that stood; `None` for a scene whose model the run
/// changes (splits, contact, the events solver): its next trial starts cold.
pub fn warm_state(sim: &Simulation) -> Option<WarmState> {
    if sim.cracking.as_ref().is_some_and(|c| !c.cuts.is_empty()) || sim.contact.is_some() || sim.events.is_some() {
        return None;
    }
    let blocks = sim.model.block_states();
    Some(WarmState { state: sim.state.clone(), blocks, levels: sim.levels.clone(), ledger: sim.ledger })
}

/// The search of the module docs over a trial `run(F) -> (flows, what the trial keeps)`: widen
/// the bracket `[o.lo, o.hi]` until `lo` stands and `hi` flows, then bisect. Answers `(F,
/// bracket, what the lowest `F` that flowed kept, trials run)`. Shared by the explicit trials
/// and the implicit ones (`flem fos --implicit`).
pub fn bisect<T>(name: &str, o: &FosOptions, mut run: impl FnMut(f64) -> Result<(bool, T)>) -> Result<(f64, [f64; 2], T, usize)> {
    check_options(name, o)?;
    let mut seen: Vec<(f64, bool)> = Vec::new();
    let mut go = |f: f64, seen: &mut Vec<(f64, bool)>| -> Result<(bool, T)> {
        let (flows, keep) = run(f)?;
        seen.push((f, flows));
        Ok((flows, keep))
    };
    let (mut lo, mut hi) = (o.lo, o.hi);
    // Widen until lo stands and hi flows.
    let mut flow_keep: T;
    loop {
        if seen.len() >= o.max_trials {
            return Err(FlemError::Other(format!("{name}: no bracket within {} trials (last [{lo}, {hi}])", o.max_trials)));
        }
        let (f, keep) = go(hi, &mut seen)?;
        if f {
            flow_keep = keep;
            break;
        }
        (lo, hi) = (hi, 2.0 * hi);
    }
    loop {
        if seen.len() >= o.max_trials {
            return Err(FlemError::Other(format!("{name}: no bracket within {} trials (last [{lo}, {hi}])", o.max_trials)));
        }
        if seen.iter().any(|t| t.0 == lo && !t.1) {
            break;
        }
        let (f, keep) = go(lo, &mut seen)?;
        if !f {
            break;
        }
        (hi, lo) = (lo, 0.5 * lo);
        flow_keep = keep;
    }
    while hi - lo > o.rel_tol * lo && seen.len() < o.max_trials {
        let mid = 0.5 * (lo + hi);
        let (f, keep) = go(mid, &mut seen)?;
        if f {
            hi = mid;
            flow_keep = keep;
        } else {
            lo = mid;
        }
    }
    Ok((0.5 * (lo + hi), [lo, hi], flow_keep, seen.len()))
}

fn check_options(name: &str, o: &FosOptions) -> Result<()> {
    if !(o.lo > 0.0 && o.hi > o.lo && o.hi.is_finite()) {
        return Err(FlemError::config(name, "fos bracket", format!("[{}, {}] is incorrect; it must satisfy 0 < lo < hi", o.lo, o.hi)));
    }
    if !(o.rel_tol > 0.0 && o.rel_tol < 1.0 && o.growth > 0.0 && o.growth < 1.0) {
        return Err(FlemError::config(name, "fos options", format!("rel_tol = {} and growth = {} must lie in (0, 1)", o.rel_tol, o.growth)));
    }
    Ok(())
}

/// The factor of safety of the scene `text` (read from `path`, relative paths from `base`);
/// `each` sees every trial as it ends (progress).
pub fn factor_of_safety(text: &str, path: &Path, base: &Path, o: &FosOptions, each: &mut dyn FnMut(&Trial)) -> Result<FosResult> {
    let name = path.display().to_string();
    let mut trials = Vec::new();
    // The highest F that stood so far and its final state (warm start only).
    let mut stood: Option<(f64, WarmState)> = None;
    let (fos, bracket, flow, _) = bisect(&name, o, |f| {
        let start = stood.as_ref().filter(|s| o.warm && s.0 < f).map(|s| (s.0, &s.1));
        let (t, sim) = trial_from(text, path, base, f, o.growth, start)?;
        each(&t);
        let flows = t.flows;
        trials.push(t);
        if o.warm && !flows && stood.as_ref().is_none_or(|s| s.0 < f) {
            stood = warm_state(&sim).map(|w| (f, w));
        }
        Ok((flows, sim))
    })?;
    Ok(FosResult { fos, bracket, trials, flow })
}
