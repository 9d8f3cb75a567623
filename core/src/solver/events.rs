//! The events stage solver (ours, issue 19; `[solver] type = "events"`, docs/events.md): a
//! quasi-static crack path at one linear solve per crack event, for scenes with cracking, linear
//! elements and no contact. The explicit solver stays the default (the paper's method).
//!
//! A stage takes the load levels from those held by the earlier stages, `L0`, to its own, `L1`,
//! along `L(t) = L0 + t (L1 - L0)`, `t` in `[0, 1]`. The body is linear between two splits, so
//!
//! ```text
//! u(t) = u0 + t (u1 - u0),   K u0 = f(L0),   K u1 = f(L1)     (prescribed displacements too)
//! s_c(t) = s0_c + t (s1_c - s0_c)                              (nodal stress of every cluster)
//! ```
//!
//! with the nodal stress exactly as the explicit run computes it (the paper's corner mean, or the
//! nonlocal average: `Cracking::nodal_stress_of`). One stage:
//! 1. solve `u0` and `u1` (the scene's check solver, `[check] solver`, faer's sparse Cholesky
//!    by default: its kept factor with low-rank updates, `CheckSolver::events_factor`; a check
//!    solver without one is called through `CheckSolver::solve`, two fresh solves per event);
//! 2. set the state to `u(t)` and run the explicit solver's own failure check
//!    (`Cracking::check`: criterion, most critical first, `max_splits_per_check`, the scene's
//!    separation rule): a split is an event (a history row, its splits.csv rows); re-solve on the
//!    new topology at the same `t` and repeat (the crack runs under load control, as in the
//!    explicit run);
//! 3. when the check splits nothing, find per cluster the smallest `t' > t` at which the
//!    criterion fails (`cracking::events`: closed forms for the built-ins, bisection for any
//!    other criterion) and advance to the smallest; none up to 1: the stage ends at `t = 1`.
//!
//! Per event the *critical factor of the current configuration* is recorded too: the smallest
//! `t >= 0` at which a cluster of the configuration that the event splits fails on the stage's
//! path (the sequentially linear analysis of Rots et al. 2008: the saw-tooth curve;
//! history.csv columns `critical_factor`, `critical_level_<load>`, `<probe>_ux_critical`,
//! `<probe>_uy_critical`). It lies below the current `t` where the crack runs at a load the
//! cracked body could not carry (a snap-back that load control jumps over).
//!
//! A fragment left without support (the solve is singular): by default (ours, issue 35,
//! `[solver] on_loose_fragment = "hand_over"`) the stage goes on in the explicit march from the
//! last solved state until the fragment comes to rest or leaves ([`Simulation::hand_over`]);
//! with `"stop"` the run ends there with the check solver's message naming the fragment (as
//! `flem compare` does). Contact (allowed only with the hand-over, where it acts), dynamic
//! stages and co-rotational materials are refused when the scene is read (scene.rs);
//! prescribed velocities other than zero, loads of `t` and following pressures are refused when
//! the simulation is built ([`Simulation::check_events_scene`]). Clusters the rule cannot cut
//! (`Cracking::beyond_criterion`) are left out of the search while they fail.
//!
//! In events mode `state.step` counts events, `state.time` is the stage's load factor `t` plus
//! the stage index (`time` of history.csv and splits.csv), velocities are zero, the energy
//! ledger holds the strain energy only (external work is set equal to it: dissipation by
//! cracking is not booked), the unbalanced-force ratio is that of the linear solve
//! (round-off), and `output.snapshot_every` and `output.checkpoint_every` count events.
//!
//! Checkpoints and interrupts, between two events (docs/events.md): every
//! `output.checkpoint_every` events a checkpoint (section `"events"`: [`EventsInfo`], with the
//! stage's path, factor, left-out clusters and the kept factor's ordering) and a restart of the
//! kept factor, as in a run resumed there, so that the resumed run is bit for bit the
//! uninterrupted one; a checkpoint due by `output.checkpoint_seconds` waits for the next fresh
//! factorisation of the schedule (no change to the arithmetic); the interrupt flag
//! (`Observer::should_stop`) stops the run at once with a checkpoint (resumed: the same path to
//! round-off, the next solve being fresh).
use std::time::Instant;

use crate::cracking::events::{smallest_failure, FactorStats, Path};
use crate::error::{FlemError, Result};
use crate::plugin::check::{CheckCfg, CheckSolver, EventsFactor};
use crate::plugin::damping::{DampingCoeffs, StepStats};
use crate::scene::{LooseFragment, SolverCfg};
use crate::solver::{Ledger, Observer, Progress, Simulation, StagePos, StageResult};

/// What the events solver shows of the current event (read by the output writer), and what a
/// checkpoint keeps of the stage loop (section `"events"`, `output/checkpoint.rs`).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct EventsInfo {
    /// The stage's load factor `t` now.
    pub factor: f64,
    /// Critical factor of the configuration the last event split (NaN before the first).
    pub critical_factor: f64,
    /// Load levels at `critical_factor`.
    pub critical_levels: Vec<f64>,
    /// Displacement of every cluster at `critical_factor` (before that split).
    pub critical_u: Vec<[f64; 2]>,
    /// Events (checks that split) so far in the run.
    pub events: u64,
    /// Linear solves so far.
    pub solves: u64,
    /// Seconds in the linear solves.
    pub solve_seconds: f64,
    /// Fresh factorisations and low-rank updates of the kept factor (`solver.refactor_every`).
    pub fresh_factorisations: u64,
    pub updates: u64,
    pub factors: FactorStats,
    /// The message that ended the run (a fragment without support): later stages are skipped.
    pub stopped: Option<String>,
    /// The stage's path: levels at `t = 0` and `t = 1` (kept for a resume within the stage).
    pub stage_l0: Vec<f64>,
    pub stage_l1: Vec<f64>,
    /// Clusters left out of the searches (failing, not cut by the rule at the last check
    /// that split nothing).
    pub stuck: Vec<bool>,
    /// The kept factor's [`EventsFactor::save_state`] at the last checkpoint.
    pub kept_state: Vec<u64>,
}

/// How a hand-over to the explicit march ended (`[solver] on_loose_fragment = "hand_over"`).
#[derive(Copy, Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub enum HandOverEnd {
    /// At rest: kinetic energy below `solver.hand_over_rest` of the largest energy moved in the
    /// explicit part and the unbalanced ratio below the stage's tolerance.
    Rest,
    /// A cluster moved more than `solver.hand_over_distance` (of the mesh's diagonal) from
    /// where the hand-over found it: a fragment has left.
    Left,
    /// `solver.hand_over_max_steps` explicit steps without either.
    StepLimit,
}

impl HandOverEnd {
    fn describe(self, s: &SolverCfg) -> String {
        match self {
            HandOverEnd::Rest => format!("at rest (kinetic energy below {:e} of the energy moved, unbalanced ratio below the tolerance)", s.hand_over_rest),
            HandOverEnd::Left => format!("a fragment left (moved more than solver.hand_over_distance = {} of the mesh's diagonal)", s.hand_over_distance),
            HandOverEnd::StepLimit => format!("neither at rest nor gone at solver.hand_over_max_steps = {}", s.hand_over_max_steps),
        }
    }
}

/// What the hand-over of an events stage to the explicit march did (`Simulation::hand_over`,
/// not kept in checkpoints: a run resumed after the stage has only its warning and stage result).
#[derive(Clone, Debug, serde::Serialize)]
pub struct HandOver {
    pub stage: usize,
    /// The stage's load factor of the last solved event (the loads are held there).
    pub factor: f64,
    pub end: HandOverEnd,
    /// Explicit steps.
    pub steps: u64,
    /// Splits in the march (failure checked every `cracking.check_every` steps).
    pub splits: usize,
    /// Time marched (sum of the steps' dt).
    pub time: f64,
    pub dt: f64,
    /// The ledger at the hand-over (external work = strain energy, as in the events part).
    pub start: Ledger,
    /// The ledger at the end.
    pub end_ledger: Ledger,
    /// The largest displacement of a cluster from the hand-over's state, and that cluster.
    pub moved: f64,
    pub moved_cluster: usize,
}

impl HandOver {
    /// Work done on the body in the explicit part (external work since the hand-over).
    pub fn work(&self) -> f64 {
        self.end_ledger.external() - self.start.external()
    }
    /// The largest energy moved in the explicit part: the work, the change of strain energy,
    /// the kinetic energy, the dissipation, the contact terms.
    pub fn energy_scale(&self) -> f64 {
        energy_scale(&self.start, &self.end_ledger)
    }
    /// The ledger's residual at the end (it is zero at the hand-over) over the work done in
    /// the explicit part (over [`Self::energy_scale`] when no work is done, e.g. prescribed
    /// displacements only).
    pub fn relative_residual(&self) -> f64 {
        let w = self.work().abs();
        let s = if w > 0.0 { w } else { self.energy_scale() };
        if s > 0.0 {
            self.end_ledger.residual().abs() / s
        } else {
            0.0
        }
    }
}

fn energy_scale(a: &Ledger, b: &Ledger) -> f64 {
    let w = (b.external() - a.external()).abs();
    let du = (b.strain - a.strain).abs();
    w.max(du).max(b.kinetic).max(b.dissipated()).max(b.contact_energy).max(b.contact_dissipated)
}

/// The largest stage factor the critical-factor search looks at (beyond it: infinite).
const CRIT_MAX: f64 = 1e3;

impl Simulation {
    /// Refuses what the events solver cannot do, naming the key (called by `Simulation::new`).
    pub(crate) fn check_events_scene(&self) -> Result<()> {
        let file = self.scene.path.display().to_string();
        if self.model.stateful {
            // A material law with state (plasticity) or large strain (element::stateful): the
            // stress is not linear in the load.
            let key = if self.scene.file.solver.large_strain {
                "solver.large_strain".to_string()
            } else {
                format!("material[{}].law", self.scene.file.materials.iter().position(|m| m.law.is_some()).unwrap_or(0))
            };
            return Err(FlemError::config(&file, key, "makes the stress not linear in the load, which solver.type = \"events\" needs (a linear elastic law on small strain)"));
        }
        for (i, l) in self.loads.loads.iter().enumerate() {
            if l.uses_t() {
                return Err(FlemError::config(&file, format!("load[{i}].value"), "is an expression of t, which solver.type = \"events\" cannot follow (its states have no time)"));
            }
        }
        if self.loads.has_follower {
            return Err(FlemError::config(&file, "load", "a pressure with follow = true is not possible with solver.type = \"events\" (its solve is linear, on the reference configuration)"));
        }
        for lv in self.scene.file.stages.iter().map(|s| &s.levels) {
            let mut levels = vec![0.0; self.loads.loads.len()];
            for (name, &v) in lv {
                if let Some(k) = self.loads.loads.iter().position(|l| &l.name == name) {
                    levels[k] = v;
                }
            }
            let (_, vp, _) = self.loads.constraints(&self.model, &levels, 0.0);
            if let Some(c) = vp.iter().position(|v| v[0] != 0.0 || v[1] != 0.0) {
                let p = self.model.topo.cluster_point[c];
                return Err(FlemError::config(
                    &file,
                    "load",
                    format!(
                        "a prescribed velocity (at point {} of the mesh) is not possible with solver.type = \"events\" (its states have no time); prescribe a displacement (displacement = true)",
                        p.0
                    ),
                ));
            }
        }
        Ok(())
    }

    /// External force, fixities and prescribed displacements at the given levels.
    fn events_rhs(&self, levels: &[f64]) -> Result<(Vec<u8>, Vec<[f64; 2]>, Vec<[f64; 2]>)> {
        let mut probe = self.levels.clone();
        probe.copy_from_slice(levels);
        let mut f = Vec::new();
        self.loads.constant_force(&self.model, &probe, &self.state.mass, &mut f);
        let (fix, _, up) = self.loads.constraints(&self.model, &probe, 0.0);
        let mut u_p = vec![[0.0; 2]; fix.len()];
        for (c, d, v) in up {
            u_p[c][d] = v;
        }
        Ok((fix, f, u_p))
    }

    /// Solves the current model at the levels `l0` and `l1` (the kept factor when there is one).
    fn events_solve_pair(&mut self, solver: &dyn CheckSolver, kept: &mut Option<Box<dyn EventsFactor>>, l0: &[f64], l1: &[f64]) -> Result<(Vec<[f64; 2]>, Vec<[f64; 2]>)> {
        let t = Instant::now();
        let (fix, f0, p0) = self.events_rhs(l0)?;
        let (_, f1, p1) = self.events_rhs(l1)?;
        // A fragment without support under self-equilibrated loads gets a statically
        // determinate one (plugin::support; issue 41), said once in the warnings; any other
        // fragment without support is refused here, named.
        let crate::plugin::support::Plan { fix, mut added } = crate::plugin::support::plan(&self.model, &fix, &[f0.as_slice(), f1.as_slice()])?;
        let check = (!added.is_empty()).then(|| (f0.clone(), f1.clone()));
        let before = kept.as_ref().map_or((0, 0), |k| k.counts());
        let (a, b) = match kept.as_mut() {
            Some(k) => {
                let mut v = k.solve_many(&self.model, &fix, &[(f0, p0), (f1, p1)])?;
                let b = v.pop().expect("two solutions");
                (v.pop().expect("two solutions"), b)
            }
            None => (solver.solve(&self.model, &fix, &f0, &p0)?, solver.solve(&self.model, &fix, &f1, &p1)?),
        };
        if let Some((f0, f1)) = check {
            crate::plugin::support::check_reactions(&self.model, &mut added, &f0, &a)?;
            crate::plugin::support::check_reactions(&self.model, &mut added, &f1, &b)?;
            for s in &added {
                let w = format!("the events solver's linear solves: {}", s.note().split(", reactions").next().unwrap_or_default());
                if !self.warnings.contains(&w) {
                    self.warnings.push(w);
                }
            }
        }
        if let Some(ev) = self.events.as_mut() {
            ev.solves += 2;
            ev.solve_seconds += t.elapsed().as_secs_f64();
            if let Some(k) = kept.as_ref() {
                // Deltas: a kept factor restarted at a checkpoint (or in a resumed run) counts
                // from zero.
                let (f, u) = k.counts();
                ev.fresh_factorisations += f - before.0;
                ev.updates += u - before.1;
            }
        }
        Ok((a, b))
    }

    /// The state at factor `t`: displacement, levels, forces and the linear solve's ratio.
    fn events_set_state(&mut self, u0: &[[f64; 2]], u1: &[[f64; 2]], t: f64, l0: &[f64], l1: &[f64], stage: usize) {
        for (k, l) in self.levels.iter_mut().enumerate() {
            *l = l0[k] + t * (l1[k] - l0[k]);
        }
        let st = &mut self.state;
        st.u.clear();
        st.u.extend(u0.iter().zip(u1).map(|(a, b)| [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]));
        st.v.iter_mut().for_each(|v| *v = [0.0; 2]);
        st.time = stage as f64 + t;
        self.refresh_constant_force();
        if self.loads.has_follower || self.loads.has_time {
            // Refused for events scenes (check_events_scene); kept whole for safety.
            if let Ok(f) = self.external_force() {
                self.state.f_ext = f;
            }
        }
        let mut fi = std::mem::take(&mut self.state.f_int);
        self.model.internal_forces(&self.state.u, &mut fi);
        self.state.f_int = fi;
        let strain = self.strain_energy();
        self.ledger = Ledger { external_work: strain, strain, ..Ledger::default() };
        self.last_ratio = self.unbalanced_ratio();
        if let Some(ev) = self.events.as_mut() {
            ev.factor = t;
        }
    }

    /// The paths the events search follows: those of clusters not `stuck` (failed at the last
    /// check and not cut) and whose point may split. Points of `[cracking] intact` (ours) are left
    /// out from the start, so the solver does not stop at each of their failures to check a state
    /// that cannot split (their failure index is still computed at every check).
    fn live_paths(&self, paths: &[Path], stuck: &[bool]) -> Vec<Path> {
        let intact = self.cracking.as_ref().map(|cr| cr.intact.as_slice()).filter(|i| !i.is_empty());
        let topo = &self.model.topo;
        paths.iter().enumerate().filter(|(c, _)| !stuck.get(*c).copied().unwrap_or(false) && !intact.is_some_and(|i| i[topo.cluster_point[*c].idx()])).map(|(_, p)| *p).collect()
    }

    /// The stress paths of every cluster between `u0` (t = 0) and `u1` (t = 1).
    fn events_paths(&mut self, u0: &[[f64; 2]], u1: &[[f64; 2]]) -> Vec<Path> {
        let cr = self.cracking.as_mut().expect("events scenes have [cracking]");
        let (mut s0, mut s1) = (Vec::new(), Vec::new());
        cr.nodal_stress_of(&self.model, u0, &mut s0);
        cr.nodal_stress_of(&self.model, u1, &mut s1);
        let topo = &self.model.topo;
        (0..s0.len())
            .map(|c| {
                let p = topo.cluster_point[c];
                let mat = self.model.material_of(topo.copy_elem[topo.point_copies.row(p.idx())[0].idx()]);
                let ds = std::array::from_fn(|k| s1[c][k] - s0[c][k]);
                let (z0, z1) = (mat.szz(s0[c]), mat.szz(s1[c]));
                Path { s0: s0[c], ds, szz0: z0, dszz: z1 - z0, scale: cr.scale[p.idx()] }
            })
            .collect()
    }

    /// The hand-over (ours, issue 35; docs/events.md): the solve after the last event was
    /// singular (a fragment without support). The stage goes on in the explicit march from the
    /// last solved state: the same clusters, `u` as the last solve put it (the split's new
    /// clusters where their parents were), `v = 0`, the loads held at the stage's factor `t`,
    /// contact on where the scene has `[contact]`, the scene's damping (reset), `dt` from a
    /// fresh stable-step estimate (`dt_safety` of it, or `solver.dt`; estimated again after
    /// splits as the explicit loop does). Failure is checked every `cracking.check_every`
    /// steps (the paper's checks during the march: a fragment held by one node, a hinge,
    /// tears off there). It ends when the fragment comes to rest or leaves, or at the step limit
    /// ([`HandOverEnd`]). The ledger starts with the external work equal to the strain energy
    /// (the events part's convention), so that its residual at the end is that of the
    /// explicit part alone. History rows every `output.history_every` steps; the interrupt is
    /// polled every step (it stops without a checkpoint: a resumed run starts again from the
    /// last checkpoint, which is before the hand-over).
    fn hand_over(&mut self, i: usize, t: f64, obs: &mut dyn Observer) -> Result<HandOver> {
        let file = self.scene.path.display().to_string();
        let sc = &self.scene.file.solver;
        let st = &self.scene.file.stages[i];
        let (max_steps, tol, every) = (sc.hand_over_max_steps, st.tolerance.unwrap_or(sc.tolerance), sc.ratio_every);
        let rest = sc.hand_over_rest;
        let hist_every = self.scene.file.output.history_every;
        let check_every = self.scene.file.cracking.as_ref().map_or(0, |c| c.check_every);
        let uses_omega = sc.damping.as_deref().is_none_or(|d| d.uses_rayleigh_stats());
        let distance = sc.hand_over_distance * {
            let (lo, hi) = self.model.mesh.bounding_box();
            ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2)).sqrt()
        };
        let n_stages = self.scene.file.stages.len();
        // The state: u of the last solve (events_set_state before the split; the new clusters
        // took their parents' u), at rest, the constraints and loads of the held levels.
        self.state.v.iter_mut().for_each(|v| *v = [0.0; 2]);
        let (fix, vp, _) = self.loads.constraints(&self.model, &self.levels, self.state.time);
        self.state.fix = fix;
        self.state.v_pres = vp;
        self.refresh_constant_force();
        let mut fi = std::mem::take(&mut self.state.f_int);
        self.model.internal_forces(&self.state.u, &mut fi);
        self.state.f_int = fi;
        // Contact starts here: pairs found anew from the current faces (the events part kept
        // pairs of its splits without ever computing them: their history would see the whole
        // opening since each split as one step's increment and create energy).
        if let Some(cfg) = self.scene.file.contact.as_ref() {
            self.contact = Some(crate::contact::Contact::new(cfg, &self.model, &file)?);
        }
        // The stable step of the cracked body (the events part estimated none).
        (self.stable, self.stable_vec) = self.power_iteration(None);
        self.dt = self.choose_dt(&file)?;
        self.scene.file.solver.damping().reset();
        self.stats = StepStats { step: self.state.step, dt: self.dt, omega_max: self.stable.omega_max, ..StepStats::default() };
        self.coeffs = DampingCoeffs::default();
        let strain = self.strain_energy();
        self.ledger = Ledger { external_work: strain, strain, ..Ledger::default() };
        let start = self.ledger;
        let u_h = self.state.u.clone();
        let t0 = self.state.time;
        let moved = |u: &[[f64; 2]]| {
            u.iter().zip(&u_h).enumerate().fold((0.0f64, 0usize), |(m, c), (k, (a, b))| {
                let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
                if d > m {
                    (d, k)
                } else {
                    (m, c)
                }
            })
        };
        let mut end = HandOverEnd::StepLimit;
        let mut k = 0u64;
        let mut splits = 0usize;
        while k < max_steps {
            if k > 0 && obs.should_stop(self) {
                obs.snapshot(self, i, "interrupted")?;
                let stage_step = self.events.as_ref().map_or(0, |e| e.events);
                return Err(FlemError::Interrupted { step: self.state.step, stage: i, stage_step });
            }
            let kn = k + 1;
            let full = kn % every == 0 || kn == max_steps || (hist_every > 0 && kn % hist_every == 0);
            self.step_checked(full, check_every == 1)?;
            k = kn;
            let n = if check_every > 0 && k % check_every == 0 { self.check_failure(obs)? } else { 0 };
            if n > 0 {
                // The explicit loop's rule after splits (`update_stable_step`, whose estimate the
                // events solver skips; it keeps its warm start's update): a new estimate when dt
                // is not provably stable for any splitting, or when the damping reads omega_max;
                // dt follows it down.
                if uses_omega || self.dt > self.safe_step_bound() {
                    self.estimate_again();
                }
                splits += n;
            }
            if k % every == 0 {
                let ratio = self.step_unbalanced_ratio();
                self.last_ratio = ratio;
                if moved(&self.state.u).0 > distance {
                    end = HandOverEnd::Left;
                    break;
                }
                let scale = energy_scale(&start, &self.ledger);
                if ratio < tol && self.ledger.kinetic <= rest * scale {
                    end = HandOverEnd::Rest;
                    break;
                }
            }
            if k % 256 == 0 {
                obs.progress(&Progress { stage: i, n_stages, step: self.state.step, stage_step: k, max_steps, dt: self.dt, ratio: self.last_ratio, tolerance: tol });
            }
            if hist_every > 0 && k % hist_every == 0 {
                obs.history(self, i)?;
            }
        }
        if k % every != 0 {
            // The last step was full (kn == max_steps).
            self.last_ratio = self.step_unbalanced_ratio();
        }
        self.guard_now()?;
        let (m, c) = moved(&self.state.u);
        Ok(HandOver { stage: i, factor: t, end, steps: k, splits, time: self.state.time - t0, dt: self.dt, start, end_ledger: self.ledger, moved: m, moved_cluster: c })
    }

    /// Runs stage `pos.stage` by events (see the module docs).
    pub(crate) fn run_stage_events(&mut self, pos: StagePos, obs: &mut dyn Observer) -> Result<()> {
        let t_start = Instant::now();
        let i = pos.stage;
        if self.events.is_none() {
            self.events = Some(EventsInfo { critical_factor: f64::NAN, ..EventsInfo::default() });
        }
        let file = self.scene.path.display().to_string();
        // A resume within the stage (a checkpoint after an event) takes the stage's path, its
        // factor and its left-out clusters from the checkpoint's section "events".
        let resumed = pos.begun && pos.stage_step > 0;
        let (l0, l1) = if resumed {
            let ev = self.events.as_ref().expect("set above");
            if ev.stage_l0.len() != self.levels.len() || ev.stage_l1.len() != self.levels.len() {
                return Err(FlemError::Other(format!("{file}: the checkpoint's events section has no load path for stage {i}: it cannot be resumed by events")));
            }
            (ev.stage_l0.clone(), ev.stage_l1.clone())
        } else {
            let l0 = self.levels.clone();
            if !pos.begun {
                self.begin_stage(i);
            }
            (l0, self.levels.clone())
        };
        {
            let ev = self.events.as_mut().expect("set above");
            ev.stage_l0.clone_from(&l0);
            ev.stage_l1.clone_from(&l1);
        }
        // The scene's check solver ([check] solver, faer's sparse Cholesky by default), a copy
        // owned by the stage. Only a solver with `CheckSolver::events_factor` (faer_cholesky:
        // the kept factor with low-rank updates) keeps anything between events; any other is
        // called through `CheckSolver::solve`, two fresh solves per event.
        let own = match &self.scene.file.check {
            Some(c) => {
                let text = toml::to_string(c).map_err(|e| FlemError::config(&file, "check.solver", format!("cannot be copied for the events solver: {e}")))?;
                let mut c: CheckCfg = toml::from_str(&text).map_err(|e| FlemError::config(&file, "check.solver", format!("cannot be copied for the events solver: {e}")))?;
                c.fill_default(&file)?;
                c
            }
            None => CheckCfg::with_defaults(&file)?,
        };
        let st = self.scene.file.stages[i].clone();
        let max_events = self.scene.file.solver.max_events;
        let snap_every = self.scene.file.output.snapshot_every;
        let ck_every = self.scene.file.output.checkpoint_every;
        let name = if st.name.is_empty() { format!("stage{i}") } else { st.name.clone() };
        let (mut splits, mut checks, mut stage_events) = if resumed { (pos.splits, pos.checks, pos.stage_step) } else { (0usize, 0u64, 0u64) };
        let mut t = if resumed { self.events.as_ref().map_or(0.0, |e| e.factor) } else { 0.0f64 };
        // Clusters failing at the last check that split nothing (the rule found no edge): left
        // out of the searches while they fail.
        let mut stuck: Vec<bool> = if resumed { self.events.as_ref().map(|e| e.stuck.clone()).unwrap_or_default() } else { Vec::new() };
        // Consecutive advances after which the check split nothing (round-off at the factor).
        let mut misses = 0u32;
        let mut advanced = false;
        let solver = own.solver();
        if let Some(m) = self.events.as_ref().and_then(|e| e.stopped.clone()) {
            self.warnings.push(format!("{file}: stage \"{name}\" skipped: the events solver stopped in an earlier stage ({m})"));
            return Ok(());
        }
        // A singular solve (a fragment without support) ends the run here, named.
        let mut stop: Option<String> = None;
        let refactor_every = self.scene.file.solver.refactor_every;
        let mut kept = solver.events_factor(refactor_every);
        if resumed {
            if let Some(k) = kept.as_mut() {
                let state = self.events.as_ref().map(|e| e.kept_state.clone()).unwrap_or_default();
                if !k.load_state(&state) {
                    return Err(FlemError::Other(format!("{file}: the checkpoint's events section holds a kept factor state that does not fit this scene")));
                }
            }
        }
        let pair = |sim: &mut Self, kept: &mut Option<Box<dyn EventsFactor>>, stop: &mut Option<String>| -> Result<Option<(Vec<[f64; 2]>, Vec<[f64; 2]>)>> {
            match sim.events_solve_pair(solver, kept, &l0, &l1) {
                Ok(p) => Ok(Some(p)),
                Err(FlemError::Solve(m)) => {
                    *stop = Some(m);
                    Ok(None)
                }
                Err(e) => Err(e),
            }
        };
        let Some((mut u0, mut u1)) = pair(self, &mut kept, &mut stop)? else {
            let m = stop.unwrap_or_default();
            return Err(FlemError::Solve(format!("{file}: stage \"{name}\" cannot start by events: {m}")));
        };
        loop {
            self.events_set_state(&u0, &u1, t, &l0, &l1, i);
            // The critical factor of this configuration (before the check's split, if any).
            let paths = self.events_paths(&u0, &u1);
            let criterion = || self.scene.file.cracking.as_ref().expect("events scenes have [cracking]").criterion.as_ref();
            let mut fs = FactorStats::default();
            let live = self.live_paths(&paths, &stuck);
            let (crit, _) = smallest_failure(criterion(), &live, 0.0, CRIT_MAX, &mut fs)?;
            let n = self.check_failure_with(obs, false)?;
            checks += 1;
            if n > 0 {
                splits += n;
                stage_events += 1;
                misses = 0;
                advanced = false;
                {
                    let ev = self.events.as_mut().expect("set above");
                    ev.events += 1;
                    ev.critical_factor = crit;
                    ev.critical_levels = l0.iter().zip(&l1).map(|(a, b)| a + crit * (b - a)).collect();
                    ev.critical_u = u0.iter().zip(&u1).map(|(a, b)| [a[0] + crit * (b[0] - a[0]), a[1] + crit * (b[1] - a[1])]).collect();
                    ev.factors.closed += fs.closed;
                    ev.factors.fallback += fs.fallback;
                    ev.factors.searched += fs.searched;
                }
                self.state.step += 1;
                obs.history(self, i)?;
                if snap_every > 0 && self.state.step % snap_every == 0 {
                    obs.snapshot(self, i, &format!("{}_event{}", i, self.state.step))?;
                }
                if stage_events >= max_events {
                    self.warnings.push(format!("{file}: stage \"{name}\" stopped at solver.max_events = {max_events} events (load factor {t:.6e} of the stage)"));
                    break;
                }
                // Between two events (the state is whole here): checkpoints and the interrupt.
                // Every `output.checkpoint_every` events (global count) the kept factor restarts
                // (the next solve is a fresh factorisation, as in a run resumed here), so that
                // a resumed run continues bit for bit. A checkpoint due by `checkpoint_seconds`
                // waits for the next fresh factorisation of the schedule (it changes nothing of
                // the arithmetic there). An interrupt stops at once with a checkpoint; resumed,
                // its next solve is a fresh factorisation where the uninterrupted run would
                // have updated (the same to round-off, docs/events.md).
                let stop_now = obs.should_stop(self);
                let by_count = ck_every > 0 && self.state.step % ck_every == 0;
                let natural = kept.as_ref().is_none_or(|k| k.fresh_next());
                if stop_now || by_count || (natural && obs.checkpoint_due(self)) {
                    if let Some(k) = kept.as_mut() {
                        k.restart();
                    }
                    {
                        let ev = self.events.as_mut().expect("set above");
                        ev.factor = t;
                        ev.stuck.clone_from(&stuck);
                        ev.kept_state = kept.as_ref().map(|k| k.save_state()).unwrap_or_default();
                    }
                    let here = StagePos {
                        stage: i,
                        stage_step: stage_events,
                        begun: true,
                        splits,
                        ratio: self.last_ratio,
                        wall_seconds: pos.wall_seconds + t_start.elapsed().as_secs_f64(),
                        best_ratio: f64::INFINITY,
                        best_step: 0,
                        checks,
                    };
                    obs.checkpoint(self, &here)?;
                }
                if stop_now {
                    obs.snapshot(self, i, "interrupted")?;
                    return Err(FlemError::Interrupted { step: self.state.step, stage: i, stage_step: stage_events });
                }
                match pair(self, &mut kept, &mut stop)? {
                    Some((a, b)) => (u0, u1) = (a, b),
                    None => break,
                }
                continue;
            }
            let cr = self.cracking.as_ref().expect("events scenes have [cracking]");
            let now: Vec<bool> = cr.index.iter().map(|&x| x >= 1.0).collect();
            // A point the check found failed and did not cut (no edge to cut, or shielded: intact
            // points are out of the search already): the failure is confirmed, so it is not a
            // miss; that point leaves the search below.
            let refused = now.iter().enumerate().any(|(c, &f)| f && !stuck.get(c).copied().unwrap_or(false));
            stuck = now;
            if advanced && refused {
                misses = 0;
            } else if advanced {
                // The factor was found on the paths; the check's own stress of u(t) held by
                // round-off: nudge up.
                misses += 1;
                if misses > 60 {
                    return Err(FlemError::Other(format!(
                        "{file}: stage \"{name}\": the events solver found a failure at load factor {t:e} that the failure check does not confirm (the criterion's closed form disagrees with its check)"
                    )));
                }
            }
            let live = self.live_paths(&paths, &stuck);
            let mut fs2 = FactorStats::default();
            let criterion = self.scene.file.cracking.as_ref().expect("events scenes have [cracking]").criterion.as_ref();
            let (next, _) = smallest_failure(criterion, &live, t, 1.0, &mut fs2)?;
            if let Some(ev) = self.events.as_mut() {
                ev.factors.closed += fs2.closed;
                ev.factors.fallback += fs2.fallback;
                ev.factors.searched += fs2.searched;
            }
            if !next.is_finite() {
                if t < 1.0 {
                    t = 1.0;
                    self.events_set_state(&u0, &u1, t, &l0, &l1, i);
                }
                break;
            }
            let floor = if advanced { t + (1u64 << misses.min(40)) as f64 * f64::EPSILON * t.abs().max(1e-300) } else { t };
            t = next.max(floor).min(1.0);
            advanced = true;
        }
        let mut converged = stop.is_none();
        let mut energy_residual = 0.0;
        if let Some(m) = &stop {
            let event = self.state.step;
            let msg = match self.scene.file.solver.on_loose_fragment {
                LooseFragment::Stop => {
                    format!("{file}: stage \"{name}\" stopped after event {event} at load factor {t:.9e} of the stage: {m}; the events solver ends the run here (solver.on_loose_fragment = \"stop\")")
                }
                LooseFragment::HandOver => {
                    let h = self.hand_over(i, t, obs)?;
                    converged = h.end != HandOverEnd::StepLimit;
                    splits += h.splits;
                    energy_residual = h.relative_residual();
                    let msg = format!(
                        "{file}: stage \"{name}\": after event {event} at load factor {t:.9e} of the stage a fragment came loose ({m}); the stage went on in the explicit march (ours, solver.on_loose_fragment = \"hand_over\"): {} after {} steps and {} splits (time {:.6e} since the hand-over), energy residual {:.2e} of the work done in the explicit part; the events solver ends the run here",
                        h.end.describe(&self.scene.file.solver),
                        h.steps,
                        h.splits,
                        h.time,
                        energy_residual
                    );
                    self.hand_over = Some(h);
                    msg
                }
            };
            self.warnings.push(msg);
            if let Some(ev) = self.events.as_mut() {
                ev.stopped = Some(m.clone());
            }
        }
        let result = StageResult {
            name,
            steps: stage_events,
            converged,
            final_ratio: self.last_ratio,
            wall_seconds: pos.wall_seconds + t_start.elapsed().as_secs_f64(),
            time: self.state.time,
            splits,
            energy_residual,
            checks,
        };
        self.stages_done.push(result);
        obs.history(self, i)?;
        if st.snapshot {
            obs.snapshot(self, i, &format!("stage{i}"))?;
        }
        obs.stage_end(self, i)?;
        obs.checkpoint(self, &StagePos::start(i + 1))?;
        // As the explicit stage loop: the interrupt is polled at the stage's end too.
        if i + 1 < self.scene.file.stages.len() && obs.should_stop(self) {
            obs.snapshot(self, i, "interrupted")?;
            return Err(FlemError::Interrupted { step: self.state.step, stage: i + 1, stage_step: 0 });
        }
        Ok(())
    }
}

/// The explicit twin of a one-stage events scene (for comparisons: tests/events.rs,
/// `flem bench events-path`): the explicit solver, checks at equilibrium, and the stage replaced
/// by stages at the load factors `k step`, `k = k0, k0 + 1, ...` up to `k step <= to` (levels of
/// the stage scaled), each with the step limit `max_steps` and the tolerance `tolerance`.
pub fn explicit_twin(scene: &mut crate::scene::Scene, k0: u64, step: f64, to: f64, max_steps: u64, tolerance: f64) -> Result<()> {
    let f = &mut scene.file;
    if f.stages.len() != 1 {
        return Err(FlemError::Other(format!("explicit_twin: the scene has {} stages, not one", f.stages.len())));
    }
    let st = f.stages[0].clone();
    f.solver.kind = crate::scene::SolverKind::Explicit;
    if let Some(c) = f.cracking.as_mut() {
        c.at_equilibrium = true;
    }
    f.output.snapshot_every = 0;
    f.stages.clear();
    let mut k = k0;
    while (k as f64) * step <= to * (1.0 + 1e-12) {
        let t = k as f64 * step;
        let mut s = st.clone();
        s.name = format!("t{t:.6}");
        s.levels.values_mut().for_each(|v| *v *= t);
        s.max_steps = Some(max_steps);
        s.tolerance = Some(tolerance);
        s.snapshot = false;
        f.stages.push(s);
        k += 1;
    }
    Ok(())
}

/// One split as the comparisons see it: point, edges cut, load levels, the stage.
#[derive(Clone, Debug, PartialEq)]
pub struct LoggedSplit {
    pub point: u32,
    pub edges: Vec<u32>,
    pub levels: Vec<f64>,
    pub stage: usize,
}

/// An observer that records the split log and stops the run after `stop_after` splits
/// (`FlemError::Interrupted`).
pub struct SplitLog {
    pub splits: Vec<LoggedSplit>,
    pub stop_after: usize,
}

impl Observer for SplitLog {
    fn splits(&mut self, sim: &Simulation, _rec: &crate::mesh::topology::SplitRecord, events: &[crate::cracking::SplitEvent]) -> Result<()> {
        for e in events {
            self.splits.push(LoggedSplit { point: e.point.0, edges: e.edges.iter().map(|x| x.0).collect(), levels: sim.levels.clone(), stage: sim.stages_done.len() });
        }
        Ok(())
    }
    fn should_stop(&mut self, _sim: &Simulation) -> bool {
        self.splits.len() >= self.stop_after
    }
}
