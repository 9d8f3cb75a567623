//! Results on disk: VTU snapshots with a PVD series, a history CSV, a split log, and
//! `summary.json`. Every file is written to a temporary name and renamed into place, so a
//! reader never sees half a file, except the two CSV logs, which are appended to row by row
//! ([`csvlog`]: at most a last row cut by SIGKILL, which readers ignore and resume removes).
//!
//! # Atomicity
//! `atomic_write` (temp file `.NAME.tmpPID` + fsync + rename + fsync of the folder; the temp
//! file is removed on any error) writes every result file: VTU, PVD, JSON, checkpoints, PNGs,
//! and the headers of the CSV logs (no `fs::write`/`File::create` elsewhere in the library);
//! only the rows of the two CSV logs are appended (`csvlog.rs`). `prepare_dir` probes the
//! folder (before any step) and removes temp files left by killed runs. Nothing non-finite is
//! written and nothing is clamped silently: a diverged run stops before any snapshot, and
//! `state_is_finite` guards the state whatever the caller does.
//!
//! Beside the writer: `checkpoint.rs` (checkpoints and resume) and `compare.rs` (the
//! FLEM-vs-implicit comparison). Both the writer and the comparer are `crate::solver::Observer`s.
pub mod arrays;
pub mod body3;
pub mod checkpoint;
pub mod checkpoint3;
pub mod compare;
pub mod compare3;
pub mod csvlog;
pub mod lock;
pub mod run;
pub mod run3;
pub mod sweep;
pub mod tips;
pub mod vtu3;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use vtkio::model::{Attribute, Attributes, ByteOrder, CellType, Cells, DataSet, UnstructuredGridPiece, Version, VertexNumbers, Vtk};

use crate::cracking::SplitEvent;
use crate::error::{FlemError, Result};
use crate::mesh::topology::SplitRecord;
use crate::mesh::CellKind;
use crate::output::checkpoint::Checkpoint;
use crate::solver::{Observer, Progress, Simulation, StagePos};

/// Writes `bytes` to `path` atomically and durably: a temporary file in the same folder
/// (`.NAME.tmpPID`), fsync, rename over `path`, fsync of the folder. A reader, or a run killed
/// at any moment, sees the old file or the new one, never a part. On any error the temporary
/// file is removed and `path` is left as it was; the error names `path`. Every result file
/// (VTU, PVD, JSON, PNG, checkpoints, the CSV logs' headers) goes through here; the CSV logs'
/// rows are appended by [`csvlog::CsvLog`].
pub fn atomic_write(path: &Path, bytes: &[u8]) -> Result<()> {
    atomic_write_with(path, bytes, true)
}

/// [`atomic_write`], with the two fsyncs only when `durable`. Without them the file is still
/// whole for readers and after a killed process (rename is atomic), but a power cut may lose
/// it. fsync costs about 9 ms per file (+7 ms for the folder) on this machine's disk; used for
/// the folder probe of [`prepare_dir`].
pub fn atomic_write_with(path: &Path, bytes: &[u8], durable: bool) -> Result<()> {
    use std::io::Write;
    let err = |e: std::io::Error| FlemError::Output { path: path.display().to_string(), msg: e.to_string() };
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name = path.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    let write = || -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        if durable {
            f.sync_all()?;
        }
        drop(f);
        std::fs::rename(&tmp, path)
    };
    if let Err(e) = write() {
        let _ = std::fs::remove_file(&tmp);
        return Err(err(e));
    }
    // The rename itself survives a power cut only once the folder is synced (Unix; elsewhere
    // opening a folder fails and this is skipped).
    if durable {
        if let Ok(d) = std::fs::File::open(dir) {
            let _ = d.sync_all();
        }
    }
    Ok(())
}

/// The mesh point nearest `at` (a probe's point; its first cluster carries its displacement).
pub fn nearest_point(sim: &Simulation, at: [f64; 2]) -> usize {
    let pts = &sim.model.mesh.points;
    let d = |i: usize| (pts[i][0] - at[0]).powi(2) + (pts[i][1] - at[1]).powi(2);
    (0..pts.len()).min_by(|&a, &b| d(a).total_cmp(&d(b))).unwrap_or(0)
}

/// Checks that results can be written into `dir` (creating it), before any step is computed:
/// a probe file is written through [`atomic_write`] and removed. Leftover temporary files of
/// killed runs (`.NAME.tmpPID`, never a result) are removed.
pub fn prepare_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| FlemError::Output { path: dir.display().to_string(), msg: format!("the output folder cannot be created: {e}") })?;
    let probe = dir.join(".flem-write-test");
    atomic_write_with(&probe, b"ok", false).map_err(|e| FlemError::Output { path: dir.display().to_string(), msg: format!("the output folder is not writable ({e})") })?;
    let _ = std::fs::remove_file(probe);
    let me = format!(".tmp{}", std::process::id());
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd.flatten() {
            let n = e.file_name().to_string_lossy().to_string();
            if n.starts_with('.') && n.contains(".tmp") && !n.ends_with(&me) {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
    Ok(())
}

/// Version of the checkpoint section [`OUTPUT_SECTION`].
pub const OUTPUT_SECTION_VERSION: u32 = 2;
/// The checkpoint section holding [`WriterState`].
pub const OUTPUT_SECTION: &str = "output";

/// What the output writer keeps in a checkpoint (section "output", version 2): the snapshot
/// series, and the length and CRC-32 of each CSV log (`None`: not created yet). Version 1
/// carried the logs' whole contents.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct WriterState {
    pub snapshots: Vec<(f64, String)>,
    pub history: Option<csvlog::LogMark>,
    pub splits: Option<csvlog::LogMark>,
}

/// Appends a CSV field: the number, or nothing when it is not finite (not yet computed), never
/// NaN.
fn push_num(s: &mut String, v: f64) {
    if v.is_finite() {
        let _ = write!(s, "{v:e}");
    }
}

/// Whether the state may be written (a diverged run stops before any snapshot; this is the
/// guard that keeps NaN out of results whatever the caller does).
fn state_is_finite(sim: &Simulation) -> bool {
    sim.state.u.iter().chain(&sim.state.v).all(|a| a[0].is_finite() && a[1].is_finite())
}

/// The VTU of the current state: points are clusters (reference coordinates; `displacement`
/// moves them), cells are the elements on their clusters, then one line cell per crack face
/// (cell array `crack`: 1 separated at one end, 2 at both ends; 0 on elements). Built from
/// [`arrays::result_arrays`] (the arrays the Python package hands out).
pub fn snapshot_vtk(sim: &Simulation) -> Vtk {
    vtk_of(&arrays::result_arrays(sim))
}

/// The VTU model of a run's arrays (see [`snapshot_vtk`]).
pub fn vtk_of(r: &arrays::ResultArrays) -> Vtk {
    let mut pts = Vec::with_capacity(3 * r.points.len());
    for x in &r.points {
        pts.extend_from_slice(&[x[0], x[1], 0.0]);
    }
    let mut conn: Vec<u64> = r.clusters.iter().map(|&c| c as u64).collect();
    let mut offs: Vec<u64> = r.copy_offsets[1..].iter().map(|&o| o as u64).collect();
    let mut types: Vec<CellType> = r
        .kinds
        .iter()
        .map(|k| match k {
            CellKind::Q4 => CellType::Quad,
            CellKind::T3 => CellType::Triangle,
        })
        .collect();
    let mut region = r.region.clone();
    let mut crack = vec![0i32; r.kinds.len()];
    let mut stress: Vec<f64> = r.elem_stress.iter().flat_map(|s| *s).collect();
    for (f, &st) in r.crack_faces.iter().zip(&r.crack_state) {
        conn.extend(f.iter().map(|&c| c as u64));
        offs.push(conn.len() as u64);
        types.push(CellType::Line);
        region.push(-1);
        crack.push(st as i32);
        stress.extend_from_slice(&[0.0; 3]);
    }
    let vec2 = |v: &[[f64; 2]]| -> Vec<f64> { v.iter().flat_map(|a| [a[0], a[1], 0.0]).collect() };
    let mut point = vec![
        Attribute::generic("displacement", 3).with_data(vec2(&r.displacement)),
        Attribute::generic("velocity", 3).with_data(vec2(&r.velocity)),
        Attribute::generic("point_id", 1).with_data(r.point_id.iter().map(|&p| p as i64).collect::<Vec<i64>>()),
        Attribute::generic("mass", 1).with_data(r.mass.clone()),
        Attribute::generic("nodal_stress", 3).with_data(r.nodal_stress.iter().flat_map(|s| *s).collect::<Vec<f64>>()),
    ];
    if let Some(idx) = &r.failure_index {
        point.push(Attribute::generic("failure_index", 1).with_data(idx.clone()));
    }
    let mut cell = vec![Attribute::generic("region", 1).with_data(region), Attribute::generic("crack", 1).with_data(crack), Attribute::generic("stress", 3).with_data(stress)];
    if let Some((g, f)) = &r.plastic {
        // Plastic shear strain and state per element (-1 on crack cells; issue 21).
        let n_faces = r.crack_faces.len();
        let pg: Vec<f64> = g.iter().copied().chain(std::iter::repeat_n(0.0, n_faces)).collect();
        let pf: Vec<i32> = f.iter().copied().chain(std::iter::repeat_n(-1, n_faces)).collect();
        cell.push(Attribute::generic("plastic_shear_strain", 1).with_data(pg));
        cell.push(Attribute::generic("plastic_state", 1).with_data(pf));
    }
    Vtk {
        version: Version::new_xml(1, 0),
        title: String::from("FLEM snapshot"),
        byte_order: ByteOrder::LittleEndian,
        file_path: None,
        data: DataSet::inline(UnstructuredGridPiece {
            points: pts.into(),
            cells: Cells { cell_verts: VertexNumbers::XML { connectivity: conn, offsets: offs }, types },
            data: Attributes { point, cell },
        }),
    }
}

/// Serialises a VTK model to VTU bytes (little endian, raw or zlib).
pub fn vtu_bytes(vtk: Vtk, compress: bool) -> Result<Vec<u8>> {
    use vtkio::xml::Compressor;
    let (c, level) = if compress { (Compressor::ZLib, 5) } else { (Compressor::None, 0) };
    let file = vtk.try_into_xml_format(c, level).map_err(|e| FlemError::Other(format!("VTU encoding failed: {e}")))?;
    let mut out = Vec::new();
    file.write(&mut out).map_err(|e| FlemError::Other(format!("VTU encoding failed: {e}")))?;
    Ok(out)
}

/// Writes a run's results into a folder.
pub struct OutputWriter {
    pub dir: PathBuf,
    snapshots: Vec<(f64, String)>,
    history: csvlog::CsvLog,
    splits: csvlog::CsvLog,
    /// The row being written (kept to reuse its allocation).
    row: String,
    compress: bool,
    probes: Vec<(String, usize)>,
    /// `[output] reactions`: the points of each set.
    reactions: Vec<Vec<crate::ids::PointId>>,
    pub quiet: bool,
    pub on_progress: Option<Box<dyn FnMut(&Progress)>>,
    /// Set (e.g. by a SIGINT handler) to stop the run after the current step.
    pub stop: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
    /// The last checkpoint written or resumed from.
    pub last_checkpoint: Option<PathBuf>,
    ck_seq: u64,
    ck_keep: usize,
    ck_seconds: f64,
    ck_time: std::time::Instant,
    scene_hash: u64,
    /// `crack_tips.csv` (scenes with `[cracking]`; `tips.rs`).
    pub tips: Option<tips::TipTracker>,
}

impl OutputWriter {
    pub fn new(dir: &Path, sim: &Simulation) -> Result<Self> {
        prepare_dir(dir)?;
        let mut probes = Vec::new();
        for p in &sim.scene.file.output.probes {
            probes.push((p.name.clone(), nearest_point(sim, p.at)));
        }
        let mut history = String::from("step,time,stage");
        for l in &sim.loads.loads {
            let _ = write!(history, ",level_{}", l.name);
        }
        for (n, _) in &probes {
            let _ = write!(history, ",{n}_ux,{n}_uy");
        }
        history.push_str(",external_work,kinetic,strain,damping,energy_residual,unbalanced_ratio");
        let mut reactions = Vec::new();
        let file = sim.scene.path.display().to_string();
        for (i, n) in sim.scene.file.output.reactions.iter().enumerate() {
            reactions.push(sim.model.node_set(n, &format!("output.reactions[{i}]"), &file)?);
            let _ = write!(history, ",reaction_{n}_x,reaction_{n}_y");
        }
        if sim.scene.file.solver.kind == crate::scene::SolverKind::Events {
            // The events solver's saw-tooth (solver::events): the critical factor of the
            // configuration an event splits, its levels and the probes' displacement there.
            history.push_str(",critical_factor");
            for l in &sim.loads.loads {
                let _ = write!(history, ",critical_level_{}", l.name);
            }
            for (n, _) in &probes {
                let _ = write!(history, ",{n}_ux_critical,{n}_uy_critical");
            }
        }
        history.push('\n');
        // A new run in a folder holding an older run's checkpoints numbers its own after them,
        // so that they are the newest (and the old ones get pruned); `resume` renumbers.
        let ck_seq = crate::output::checkpoint::list(dir)?.first().map_or(0, |(s, _)| s + 1);
        let history = csvlog::CsvLog::new(dir.join("history.csv"), history);
        let mut splits_header = String::from("time,step,point,x,y,cluster,new_cluster,mode,failure_index,sigma1_deg,sxx,syy,sxy,edges");
        for l in &sim.loads.loads {
            let _ = write!(splits_header, ",level_{}", l.name);
        }
        splits_header.push('\n');
        let splits = csvlog::CsvLog::new(dir.join("splits.csv"), splits_header);
        let w = OutputWriter {
            dir: dir.to_path_buf(),
            snapshots: Vec::new(),
            history,
            splits,
            row: String::new(),
            compress: sim.scene.file.output.compress,
            probes,
            reactions,
            quiet: false,
            on_progress: None,
            stop: None,
            last_checkpoint: None,
            ck_seq,
            ck_keep: sim.scene.file.output.checkpoint_keep,
            ck_seconds: sim.scene.file.output.checkpoint_seconds,
            ck_time: std::time::Instant::now(),
            scene_hash: crate::output::checkpoint::scene_hash(sim),
            tips: if sim.scene.file.cracking.is_some() { Some(tips::TipTracker::new(dir, sim, sim.scene.file.output.tip_window)?) } else { None },
        };
        atomic_write(&dir.join("scene.resolved.toml"), sim.scene.resolved_toml().as_bytes())?;
        Ok(w)
    }

    /// Continues from a restored checkpoint (read from `path`): the snapshot series as it was
    /// then, the CSV logs truncated to the lengths it recorded (copied from the checkpoint's
    /// folder when resuming into another one; a shorter or changed log is refused, naming it;
    /// see [`csvlog::CsvLog::resume`]), and the checkpoint numbering after it.
    pub fn resume(&mut self, ck: &Checkpoint, path: &Path) -> Result<()> {
        if let Some(w) = ck.section::<WriterState>(OUTPUT_SECTION, OUTPUT_SECTION_VERSION)? {
            let src = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
            self.history.resume(&src.join("history.csv"), w.history, path)?;
            self.splits.resume(&src.join("splits.csv"), w.splits, path)?;
            self.snapshots = w.snapshots;
        }
        if let (Some(t), Some(st)) = (self.tips.as_mut(), ck.section::<tips::TipState>(tips::TIPS_SECTION, tips::TIPS_SECTION_VERSION)?) {
            t.resume(st, path)?;
        }
        self.ck_seq = ck.seq + 1;
        self.last_checkpoint = Some(path.to_path_buf());
        Ok(())
    }

    fn write_pvd(&self) -> Result<()> {
        let mut s = String::from("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  <Collection>\n");
        for (t, f) in &self.snapshots {
            let _ = writeln!(s, "    <DataSet timestep=\"{t:e}\" group=\"\" part=\"0\" file=\"{f}\"/>");
        }
        s.push_str("  </Collection>\n</VTKFile>\n");
        atomic_write(&self.dir.join("results.pvd"), s.as_bytes())
    }

    /// Writes `summary.json` (the end of a run, also after a divergence or an interruption),
    /// after an fsync of the CSV logs. A log that got no row is written with its header only,
    /// so that the folder never ends with an older run's `splits.csv` beside this run's
    /// summary (a run without splits into a folder that held one with splits).
    pub fn write_summary(&mut self, sim: &Simulation, wall: f64) -> Result<()> {
        self.history.append(&[])?;
        self.splits.append(&[])?;
        self.history.sync()?;
        self.splits.sync()?;
        if let Some(t) = self.tips.as_mut() {
            t.finish()?;
        }
        let l = &sim.ledger;
        let (one, two) = sim.model.topo.crack_counts();
        let v = serde_json::json!({
            "title": sim.scene.file.title,
            "elements": sim.model.n_elems(),
            "points": sim.model.topo.n_points,
            "clusters": sim.model.topo.n_clusters(),
            "steps": sim.state.step,
            "time": sim.state.time,
            "wall_seconds": wall,
            "dt": sim.dt,
            "dt_crit": sim.stable.dt_crit,
            "dt_over_dt_crit": sim.dt / sim.stable.dt_crit,
            "dt_element_bound": sim.stable.dt_element_bound,
            "stages": sim.stages_done,
            "energy": l.summary_json(),
            "splits": sim.cracking.as_ref().map(|c| c.n_splits).unwrap_or(0),
            "beyond_criterion": sim.cracking.as_ref().map(|c| c.beyond_criterion()).unwrap_or(0),
            "crack_faces": {"separated_one_end": one, "separated_both_ends": two},
            // Issue 36: the fracture-energy account (docs/dynamic.md, "Energy").
            "fracture_account": fracture_account(sim),
            "warnings": sim.warnings,
            // The events solver's hand-over of a loose fragment to the explicit march (issue 35).
            "hand_over": sim.hand_over,
        });
        atomic_write(&self.dir.join("summary.json"), serde_json::to_string_pretty(&v).unwrap_or_default().as_bytes())
    }
}

/// The fracture energy's account for `summary.json` (issue 36, docs/dynamic.md "Energy").
/// Areas are length x thickness. `face_area`: the crack faces made during the run (an edge
/// separated at both ends whole, at one end half, the notch excluded; the tip tracker's
/// `crack_length`); of it, `intact_area` still bonded by cohesive pairs that never passed the
/// peak (split, not opened: no crack yet), `softening_area` in the cohesive zone (past the
/// peak, short of `delta_f`), holding `softening_pending` of energy still to release, and
/// `free_area` the rest (traction-free: cohesion fully released). Every face releases `G_f`
/// per area once: `fracture = G_f (free + softening) - softening_pending` when the cohesion
/// of no face was lost or counted twice (`identity_error`, relative to the fracture energy).
/// `lost`: [`crate::contact::search::CohesionAccount`], the pairs whose cohesion left without
/// dissipation (a part given to a new fresh pair is counted there too). `null` without contact.
fn fracture_account(sim: &Simulation) -> serde_json::Value {
    let (Some(c), Some(cfg)) = (sim.contact.as_ref(), sim.scene.file.contact.as_ref()) else { return serde_json::Value::Null };
    let law = cfg.law.as_ref();
    let g_f = law.unreleased(&crate::contact::PairState { fresh: true, ..Default::default() });
    let [intact, soft, pending] = c.zones(law);
    let area = c.fresh_face_area(&sim.model);
    let free = area - intact - soft;
    let frac = sim.ledger.fracture;
    let expect = g_f * (free + soft) - pending;
    serde_json::json!({
        "g_f": g_f,
        "face_area": area,
        "intact_area": intact,
        "softening_area": soft,
        "softening_pending": pending,
        "free_area": free,
        "fracture": frac,
        "fracture_over_g_f_free": if free > 0.0 { frac / (g_f * free) } else { f64::NAN },
        "fracture_over_g_f_free_and_softening": if free + soft > 0.0 { frac / (g_f * (free + soft)) } else { f64::NAN },
        "identity_error": if frac > 0.0 { (frac - expect) / frac } else { f64::NAN },
        "lost": c.cohesion,
    })
}

impl Observer for OutputWriter {
    fn history(&mut self, sim: &Simulation, stage: usize) -> Result<()> {
        let l = &sim.ledger;
        let r = &mut self.row;
        r.clear();
        let _ = write!(r, "{},", sim.state.step);
        push_num(r, sim.state.time);
        let _ = write!(r, ",{stage}");
        let probes = self.probes.iter().flat_map(|(_, p)| sim.state.u[sim.model.topo.point_clusters[*p][0].idx()]);
        let reactions = self.reactions.iter().flat_map(|p| sim.reaction(p));
        for v in sim.levels.iter().copied().chain(probes).chain([l.external(), l.kinetic, l.strain, l.dissipated(), l.residual(), sim.last_ratio]).chain(reactions) {
            r.push(',');
            push_num(r, v);
        }
        if sim.scene.file.solver.kind == crate::scene::SolverKind::Events {
            let ev = sim.events.as_ref();
            let nan = f64::NAN;
            let crit = ev.map_or(nan, |e| e.critical_factor);
            let lev = |k: usize| ev.and_then(|e| e.critical_levels.get(k).copied()).unwrap_or(nan);
            let cu = |p: usize, d: usize| ev.and_then(|e| e.critical_u.get(sim.model.topo.point_clusters[p][0].idx())).map_or(nan, |u| u[d]);
            let vals = std::iter::once(crit).chain((0..sim.loads.loads.len()).map(lev)).chain(self.probes.iter().flat_map(|(_, p)| [cu(*p, 0), cu(*p, 1)]));
            for v in vals {
                r.push(',');
                push_num(r, v);
            }
        }
        r.push('\n');
        self.history.append(self.row.as_bytes())
    }

    fn snapshot(&mut self, sim: &Simulation, _stage: usize, label: &str) -> Result<()> {
        if !state_is_finite(sim) {
            return Err(FlemError::Other(format!("refusing to write snapshot \"{label}\": the state is not finite")));
        }
        let name = format!("snapshot_{:04}_{label}.vtu", self.snapshots.len());
        let bytes = vtu_bytes(snapshot_vtk(sim), self.compress)?;
        atomic_write(&self.dir.join(&name), &bytes)?;
        self.snapshots.push((sim.state.time, name));
        self.write_pvd()
    }

    fn splits(&mut self, sim: &Simulation, _rec: &SplitRecord, events: &[SplitEvent]) -> Result<()> {
        self.row.clear();
        for e in events {
            let x = sim.model.mesh.points[e.point.idx()];
            let edges: Vec<String> = e
                .edges
                .iter()
                .map(|ed| {
                    let p = sim.model.topo.edges[ed.idx()].points;
                    format!("{}-{}", p[0], p[1])
                })
                .collect();
            let _ = write!(
                self.row,
                "{:e},{},{},{:e},{:e},{},{},{:?},{:e},{:.3},{:e},{:e},{:e},{}",
                e.time,
                e.step,
                e.point,
                x[0],
                x[1],
                e.cluster,
                e.new_cluster,
                e.mode,
                e.index,
                e.sigma1_deg,
                e.stress[0],
                e.stress[1],
                e.stress[2],
                edges.join(" ")
            );
            // The load levels at the split (every run; issue 19).
            for &v in &sim.levels {
                self.row.push(',');
                push_num(&mut self.row, v);
            }
            self.row.push('\n');
        }
        self.splits.append(self.row.as_bytes())?;
        if let Some(t) = self.tips.as_mut() {
            t.splits(sim, _rec, events)?;
        }
        if sim.scene.file.output.snapshot_on_split && !events.is_empty() {
            let n = sim.cracking.as_ref().map_or(0, |c| c.n_splits);
            self.snapshot(sim, sim.stages_done.len(), &format!("stage{}_split{n}", sim.stages_done.len()))?;
        }
        Ok(())
    }

    fn stage_end(&mut self, sim: &Simulation, stage: usize) -> Result<()> {
        match self.tips.as_mut() {
            Some(t) => t.stage_end(sim, stage),
            None => Ok(()),
        }
    }

    fn progress(&mut self, p: &Progress) {
        if let Some(f) = self.on_progress.as_mut() {
            f(p);
        }
    }

    fn should_stop(&mut self, _sim: &Simulation) -> bool {
        self.stop.as_ref().is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed))
    }

    fn checkpoint_due(&mut self, _sim: &Simulation) -> bool {
        self.ck_seconds > 0.0 && self.ck_time.elapsed().as_secs_f64() >= self.ck_seconds
    }

    /// Syncs the CSV logs (the checkpoint records their lengths: they must be durable first),
    /// writes `checkpoint_{seq}.bin` atomically, then removes the ones older than the
    /// `output.checkpoint_keep` newest (only after the new one is safely in place).
    fn checkpoint(&mut self, sim: &Simulation, pos: &StagePos) -> Result<()> {
        let mut ck = Checkpoint::capture(sim, pos)?;
        ck.seq = self.ck_seq;
        self.history.sync()?;
        self.splits.sync()?;
        if let Some(t) = &self.tips {
            t.sync()?;
            ck.put_section(tips::TIPS_SECTION, tips::TIPS_SECTION_VERSION, &t.checkpoint_state())?;
        }
        ck.put_section(OUTPUT_SECTION, OUTPUT_SECTION_VERSION, &WriterState { snapshots: self.snapshots.clone(), history: self.history.mark(), splits: self.splits.mark() })?;
        let path = self.dir.join(crate::output::checkpoint::file_name(ck.seq));
        atomic_write(&path, &ck.encode(self.scene_hash)?)?;
        crate::output::checkpoint::prune(&self.dir, ck.seq, self.ck_keep)?;
        self.ck_seq += 1;
        self.ck_time = std::time::Instant::now();
        self.last_checkpoint = Some(path);
        Ok(())
    }
}
