//! A 3D scene's run in a folder (issue 38, `flem run` on a scene with `[model] dim = 3`):
//! one VTU per stage (`snapshot_NNNN_stageK.vtu`, `Vtu3`: one point per cluster, so an open
//! crack shows as a gap; the displacement, the nodal stress' largest principal value and the
//! cluster's point id as point arrays; the region, the mean corner stress, the fragment and
//! `cracked_faces`, the number of the cell's faces separated at one corner at least, as cell
//! arrays), the crack faces once there are any (`cracks_NNNN_stageK.vtu`, [`crack_faces3`]:
//! both sides of every separated face as a polygon with its opening), `history.csv` (one row per stage), `splits3.csv` (every split: stage, point,
//! its coordinates, the new cluster) and `summary.json`, all written atomically or appended by
//! whole rows (`csvlog::CsvLog`). Checkpoints (`checkpoint3.rs`): every
//! `output.checkpoint_every` steps or `checkpoint_seconds`, after every stage and when the run
//! is interrupted; `resume3_in_folder` continues the newest valid one bit for bit. What the 2D
//! writer has and this one has not yet: probes, reactions, plots (docs/3d.md).
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::error::{FlemError, Result};
pub use crate::output::body3::{arrays3, cluster_cells, crack_faces3, snapshot3, Arrays3};
use crate::output::checkpoint::{file_name, prune};
use crate::output::checkpoint3::{load_newest3, scene_hash3, Checkpoint3};
use crate::output::csvlog::{CsvLog, LogMark};
use crate::scene3::Scene3;
use crate::solver::march3::{March3, Observer3, Pos3, Stage3Result};

struct Writer3<'a> {
    dir: &'a Path,
    snapshots: usize,
    splits_seen: usize,
    history: CsvLog,
    splits: CsvLog,
    /// Checkpoints: steps and seconds between them, files kept, the last one's number and
    /// time, the scene hash.
    ck_every: u64,
    ck_seconds: f64,
    ck_keep: usize,
    seq: u64,
    last_ck: Instant,
    hash: u64,
    stop: Option<Arc<AtomicBool>>,
}

/// What the writer keeps in a checkpoint (section "output3", version 1).
#[derive(Serialize, Deserialize)]
struct Writer3State {
    snapshots: usize,
    splits_seen: usize,
    history: Option<LogMark>,
    splits: Option<LogMark>,
}

impl<'a> Writer3<'a> {
    fn new(dir: &'a Path, scene: &Scene3, hash: u64, stop: Option<Arc<AtomicBool>>) -> Self {
        let o = &scene.file.output;
        Writer3 {
            dir,
            snapshots: 0,
            splits_seen: 0,
            history: CsvLog::new(dir.join("history.csv"), "stage,name,steps,ratio,at_rest,time,splits,fragments\n".into()),
            splits: CsvLog::new(dir.join("splits3.csv"), "stage,point,x,y,z,new_cluster\n".into()),
            ck_every: o.checkpoint_every,
            ck_seconds: o.checkpoint_seconds,
            ck_keep: o.checkpoint_keep,
            seq: 0,
            last_ck: Instant::now(),
            hash,
            stop,
        }
    }
}

impl Observer3 for Writer3<'_> {
    fn stage_done(&mut self, m: &March3, stage: usize, r: &Stage3Result) -> Result<()> {
        let path = self.dir.join(format!("snapshot_{:04}_stage{stage}.vtu", self.snapshots));
        snapshot3(m).write(&path, true)?;
        if let Some(v) = crack_faces3(m) {
            v.write(&self.dir.join(format!("cracks_{:04}_stage{stage}.vtu", self.snapshots)), true)?;
        }
        self.snapshots += 1;
        let row = format!("{stage},{},{},{:e},{},{:e},{},{}\n", r.name, r.steps, r.ratio, r.at_rest, r.time, r.splits, r.fragments);
        self.history.append(row.as_bytes())?;
        // New clusters since the last stage: the split log.
        let t = &m.topo;
        let mut rows = String::new();
        for c in (t.n_points + self.splits_seen)..t.n_clusters() {
            let p = t.cluster_point[c];
            let x = m.mesh.points[p.idx()];
            rows.push_str(&format!("{stage},{},{:e},{:e},{:e},{c}\n", p.0, x[0], x[1], x[2]));
        }
        self.splits_seen = t.n_clusters() - t.n_points;
        if !rows.is_empty() {
            self.splits.append(rows.as_bytes())?;
        }
        Ok(())
    }
    fn checkpoint_due(&mut self, m: &March3) -> bool {
        (self.ck_every > 0 && m.state.step % self.ck_every == 0) || (self.ck_seconds > 0.0 && self.last_ck.elapsed().as_secs_f64() >= self.ck_seconds)
    }
    fn checkpoint(&mut self, m: &March3, pos: &Pos3) -> Result<()> {
        self.history.sync()?;
        self.splits.sync()?;
        let mut ck = Checkpoint3::capture(m, pos)?;
        ck.put_section("output3", 1, &Writer3State { snapshots: self.snapshots, splits_seen: self.splits_seen, history: self.history.mark(), splits: self.splits.mark() })?;
        self.seq += 1;
        ck.seq = self.seq;
        crate::output::atomic_write(&self.dir.join(file_name(self.seq)), &ck.encode(self.hash)?)?;
        prune(self.dir, self.seq, self.ck_keep)?;
        self.last_ck = Instant::now();
        Ok(())
    }
    fn should_stop(&mut self) -> bool {
        self.stop.as_ref().is_some_and(|s| s.load(Ordering::Relaxed))
    }
}

/// Builds the body of a 3D scene and runs it in `dir` (created by the caller; the logs are
/// replaced at their first row): the stage results, also in `summary.json`.
pub fn run3_in_folder(scene: &mut Scene3, dir: &Path) -> Result<(March3, Vec<Stage3Result>)> {
    run3_with(scene, dir, false, None)
}

/// [`run3_in_folder`], or (`resume`) its continuation from the newest valid checkpoint of `dir`
/// (`checkpoint3.rs`; the logs are cut back to what they were then); `stop` (a SIGINT flag)
/// ends the run after a checkpoint with `FlemError::Interrupted`.
pub fn run3_with(scene: &mut Scene3, dir: &Path, resume: bool, stop: Option<Arc<AtomicBool>>) -> Result<(March3, Vec<Stage3Result>)> {
    let t0 = Instant::now();
    // The scene's hash leaves out `solver.threads`: the results are the same bits on any number
    // of threads, so a run may resume on another.
    let mut scene_value = serde_json::to_value(&scene.file).map_err(|e| FlemError::Other(format!("the scene cannot be written as JSON for its hash: {e}")))?;
    if let Some(s) = scene_value.get_mut("solver").and_then(|s| s.as_object_mut()) {
        s.remove("threads");
    }
    let scene_json = scene_value.to_string();
    let mut m = March3::from_scene(scene)?;
    let hash = scene_hash3(&scene_json, &m);
    // The pre-separated faces' splits are in the first stage's rows of splits3.csv.
    let mut w = Writer3::new(dir, scene, hash, stop);
    let mut from = None;
    if resume {
        let (ck, path, refused) = load_newest3(dir, hash)?;
        m.warnings.extend(refused);
        // Errors of the restore name the checkpoint file.
        let named = |e: FlemError| match e {
            e @ FlemError::Checkpoint { .. } => e,
            e => FlemError::Checkpoint { path: path.display().to_string(), msg: e.to_string() },
        };
        ck.restore(&mut m).map_err(named)?;
        let st: Writer3State = ck.section("output3", 1).map_err(named)?.ok_or_else(|| FlemError::Checkpoint { path: path.display().to_string(), msg: "has no output section".into() })?;
        w.history.resume(&dir.join("history.csv"), st.history, &path)?;
        w.splits.resume(&dir.join("splits3.csv"), st.splits, &path)?;
        w.snapshots = st.snapshots;
        w.splits_seen = st.splits_seen;
        w.seq = ck.seq;
        m.warnings.push(format!("resumed from {} (step {}, stage {} step {})", path.display(), ck.step, ck.pos.stage + 1, ck.pos.steps));
        from = Some(ck.pos);
    } else {
        // A new run in a folder with an older run's checkpoints numbers after them (as 2D), so
        // that its own are the newest.
        w.seq = crate::output::checkpoint::list(dir)?.first().map_or(0, |(s, _)| *s);
    }
    let (stages, compare) = if scene.file.check.is_some() {
        let mut c = crate::output::compare3::Comparer3::new(&mut w, scene, dir)?;
        if let Some(p) = &from {
            c.keep_rows_before(p.stage)?;
        }
        let stages = m.run_scene_from(scene, &mut c, from)?;
        (stages, Some(c.rows))
    } else {
        (m.run_scene_from(scene, &mut w, from)?, None)
    };
    // Logs that got no row are written with their header (and an older run's are replaced).
    w.history.append(b"")?;
    w.splits.append(b"")?;
    w.history.sync()?;
    w.splits.sync()?;
    let mut summary = serde_json::json!({
        "scene": scene.path.display().to_string(),
        "dim": 3,
        "elements": m.topo.n_elems(),
        "points": m.topo.n_points,
        "clusters": m.topo.n_clusters(),
        "dt": m.dt,
        "warnings": m.warnings,
        "stages": stages,
        "energy": m.ledger.summary_json(),
        "wall_seconds": t0.elapsed().as_secs_f64(),
    });
    // The work contact forces did on the nodes (beside what the law says it stored and
    // dissipated: docs/3d.md, "3D scenes").
    summary["energy"]["contact_work"] = serde_json::json!(m.ledger.contact_work - m.ledger.pending_contact);
    if let Some(rows) = compare {
        // The implicit check's verdict per stage (the figures are in compare.json).
        summary["compare"] = rows
            .iter()
            .map(|r| serde_json::json!({"stage": r.stage, "comparable": r.comparable, "within_tolerance": r.within_tolerance, "rel_l2_displacement": r.rel_l2_displacement, "rel_l2_nodal_stress": r.rel_l2_nodal_stress}))
            .collect();
    }
    let text = serde_json::to_string_pretty(&summary).map_err(|e| FlemError::Output { path: dir.join("summary.json").display().to_string(), msg: e.to_string() })?;
    crate::output::atomic_write(&dir.join("summary.json"), text.as_bytes())?;
    Ok((m, stages))
}
