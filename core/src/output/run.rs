//! Running a scene into a folder: the part of `flem run` that `flem sweep` and the Python
//! package (`python/`, issue 22) share, so that they write the same files and stop the same way.
//!
//! [`run_in_folder`] runs a [`Simulation`] through an [`OutputWriter`] (plus the scene's
//! `[check]` comparer when it has one, plus any `extra` observer: the Python package's stage
//! callbacks and signal checks, the sweep's first-split recorder), then writes `summary.json`
//! as `flem run` always did: also after an interruption (best effort) or a divergence, not after
//! an output error (the disk is the problem). The caller holds the folder's lock
//! (`lock::lock_dir`) and prints what it wants.
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::cracking::SplitEvent;
use crate::error::{FlemError, Result};
use crate::mesh::topology::SplitRecord;
use crate::output::compare::{Comparer, StageComparison};
use crate::output::OutputWriter;
use crate::solver::{Observer, Progress, Simulation, StagePos};

/// Two observers as one: every event goes to both; `should_stop` is asked of both (either may
/// stop the run); `checkpoint_due` and `checkpoint` go to the first only (the writer).
pub struct Tee<'a> {
    pub first: &'a mut dyn Observer,
    pub second: &'a mut dyn Observer,
}

impl Observer for Tee<'_> {
    fn history(&mut self, sim: &Simulation, stage: usize) -> Result<()> {
        self.first.history(sim, stage)?;
        self.second.history(sim, stage)
    }
    fn snapshot(&mut self, sim: &Simulation, stage: usize, label: &str) -> Result<()> {
        self.first.snapshot(sim, stage, label)?;
        self.second.snapshot(sim, stage, label)
    }
    fn splits(&mut self, sim: &Simulation, rec: &SplitRecord, events: &[SplitEvent]) -> Result<()> {
        self.first.splits(sim, rec, events)?;
        self.second.splits(sim, rec, events)
    }
    fn progress(&mut self, p: &Progress) {
        self.first.progress(p);
        self.second.progress(p);
    }
    fn stage_end(&mut self, sim: &Simulation, stage: usize) -> Result<()> {
        self.first.stage_end(sim, stage)?;
        self.second.stage_end(sim, stage)
    }
    fn should_stop(&mut self, sim: &Simulation) -> bool {
        let a = self.first.should_stop(sim);
        let b = self.second.should_stop(sim);
        a || b
    }
    fn checkpoint_due(&mut self, sim: &Simulation) -> bool {
        self.first.checkpoint_due(sim)
    }
    fn checkpoint(&mut self, sim: &Simulation, pos: &StagePos) -> Result<()> {
        self.first.checkpoint(sim, pos)
    }
}

/// Restores `sim` and `w` from the newest valid checkpoint of `dir` (`checkpoint::load_newest`):
/// returns where to continue, the checkpoint's file, and the refusals of newer ones (warnings).
pub fn resume(sim: &mut Simulation, w: &mut OutputWriter, dir: &Path) -> Result<(StagePos, PathBuf, Vec<String>)> {
    let (ck, path, refused) = crate::output::checkpoint::load_newest(dir, sim)?;
    ck.restore(sim).map_err(|e| FlemError::Other(format!("restoring {}: {e}", path.display())))?;
    w.resume(&ck, &path)?;
    Ok((ck.pos.clone(), path, refused))
}

/// What [`run_in_folder`] gives back.
pub struct RunEnd {
    /// The run's own outcome (`FlemError::Interrupted` when `should_stop` stopped it).
    pub result: Result<()>,
    /// The `[check]` comparison rows (empty without `[check]`).
    pub compare_rows: Vec<StageComparison>,
}

/// Runs `sim` from `pos` into `w`'s folder (see the module doc). `t0` is the run's start, for
/// `summary.json`'s wall time. An error writing the summary after a successful run is the
/// result.
pub fn run_in_folder(sim: &mut Simulation, w: &mut OutputWriter, pos: StagePos, extra: &mut dyn Observer, t0: Instant) -> RunEnd {
    let mut compare_rows = Vec::new();
    let dir = w.dir.clone();
    let result = {
        let mut tee = Tee { first: w, second: extra };
        if sim.scene.file.check.is_some() {
            match Comparer::new(&mut tee, &dir) {
                Ok(mut c) => {
                    let r = sim.run_from(pos, &mut c);
                    compare_rows = std::mem::take(&mut c.rows);
                    r
                }
                Err(e) => Err(e),
            }
        } else {
            sim.run_from(pos, &mut tee)
        }
    };
    let wall = t0.elapsed().as_secs_f64();
    let result = match result {
        Err(e @ FlemError::Interrupted { .. }) => {
            let _ = w.write_summary(sim, wall);
            Err(e)
        }
        Err(e @ FlemError::Output { .. }) => Err(e),
        Err(e) => {
            let _ = w.write_summary(sim, wall);
            Err(e)
        }
        Ok(()) => w.write_summary(sim, wall),
    };
    RunEnd { result, compare_rows }
}

/// The comparison tolerance of `flem compare` on a scene without `[check]` (ours): 1000 times
/// the loosest equilibrium tolerance of its stages, within [1e-6, 0.1].
pub fn default_compare_tolerance(scene: &crate::scene::Scene) -> f64 {
    let f = &scene.file;
    let loosest = f.stages.iter().map(|s| s.tolerance.unwrap_or(f.solver.tolerance)).fold(f.solver.tolerance, f64::max);
    (1000.0 * loosest).clamp(1e-6, 0.1)
}

/// `flem compare` (and the Python package's `flem.compare`): runs every stage of `scene` to
/// equilibrium with the implicit comparison after each (the scene's `[check]`, or its defaults
/// when it has none), writing `compare.json` and the comparison VTUs into `out` (no snapshots
/// or history). The caller holds `out`'s lock. Returns the run's outcome, the rows and the
/// warnings of the model.
pub fn compare_in_folder(mut scene: crate::scene::Scene, out: &Path, on_row: Option<Box<dyn FnMut(&StageComparison) + '_>>) -> Result<(Result<()>, Vec<StageComparison>, Vec<String>)> {
    crate::output::prepare_dir(out)?;
    if scene.file.check.is_none() {
        // Without [check] (ours): the tolerance follows the scene's equilibrium tolerance, since
        // FLEM at an unbalanced-force ratio r agrees with the implicit solve to a few r up to
        // ~100 r (measured: opening.toml 3.5 r, cantilever 40 r, notched_crack 120 r).
        let mut c = crate::plugin::check::CheckCfg::with_defaults(&scene.path.display().to_string())?;
        c.tolerance = default_compare_tolerance(&scene);
        scene.file.check = Some(c);
    }
    let mut sim = Simulation::new(scene)?;
    let mut quiet = crate::solver::NoOutput;
    let mut c = Comparer::new(&mut quiet, out)?;
    c.on_row = on_row;
    let r = sim.run(&mut c);
    Ok((r, std::mem::take(&mut c.rows), sim.warnings.clone()))
}
