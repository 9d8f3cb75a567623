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
use crate::mesh::RawCell3;
use crate::output::checkpoint::{file_name, prune};
use crate::output::checkpoint3::{load_newest3, scene_hash3, Checkpoint3};
use crate::output::csvlog::{CsvLog, LogMark};
use crate::output::vtu3::{StressLayout, Vtu3};
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

/// The cells of the body with their corners' clusters (one point per cluster: a separated
/// face is open).
pub fn cluster_cells(m: &March3) -> Vec<RawCell3> {
    let t = &m.topo;
    (0..t.n_elems())
        .map(|e| {
            let mut nodes = [0u32; 8];
            for (a, k) in t.elem_copies(crate::ids::ElemId::new(e)).enumerate() {
                nodes[a] = t.copy_cluster[k].0;
            }
            RawCell3 { kind: m.mesh.cells[e].kind, nodes }
        })
        .collect()
}

/// The mean of every element's corner stresses (Voigt `xx, yy, zz, xy, yz, zx`).
fn elem_mean_stress(m: &March3) -> Vec<[f64; 6]> {
    let t = &m.topo;
    let mut corner = vec![[0.0; 6]; t.copy_point.len()];
    for b in &m.blocks {
        b.corner_stresses(&m.state.u, &t.elem_first_copy, &mut corner);
    }
    (0..t.n_elems())
        .map(|e| {
            let r = t.elem_copies(crate::ids::ElemId::new(e));
            let n = r.len() as f64;
            let mut s = [0.0; 6];
            for k in r {
                for d in 0..6 {
                    s[d] += corner[k][d] / n;
                }
            }
            s
        })
        .collect()
}

/// Every element's region as a number (regions numbered in order of first appearance).
fn region_ids(m: &March3) -> Vec<i32> {
    let mut regions: Vec<&str> = Vec::new();
    (0..m.topo.n_elems())
        .map(|e| {
            let r = m.mesh.cell_region.get(e).map_or("all", |s| s.as_str());
            match regions.iter().position(|x| *x == r) {
                Some(i) => i as i32,
                None => {
                    regions.push(r);
                    regions.len() as i32 - 1
                }
            }
        })
        .collect()
}

/// The body as VTU: one point per cluster at its point's reference position.
pub fn snapshot3(m: &March3) -> Vtu3 {
    let t = &m.topo;
    let points: Vec<[f64; 3]> = t.cluster_point.iter().map(|p| m.mesh.points[p.idx()]).collect();
    let cells = cluster_cells(m);
    let nodal = m.nodal_stress();
    let s1: Vec<f64> = nodal.iter().map(|&s| -crate::plugin::traits::principal3(s).p.s3).collect();
    let stress: Vec<[[f64; 3]; 3]> = elem_mean_stress(m).iter().map(|s| [[s[0], s[3], s[5]], [s[3], s[1], s[4]], [s[5], s[4], s[2]]]).collect();
    let region = region_ids(m);
    let (frag, _) = t.fragments();
    let point_id: Vec<f64> = t.cluster_point.iter().map(|p| p.0 as f64).collect();
    let mut cracked = vec![0.0; t.n_elems()];
    for (f, face) in t.faces.iter().enumerate() {
        if t.crack_state(crate::ids::FaceId::new(f)) > 0 {
            for (e, _) in face.sides.iter().flatten() {
                cracked[e.idx()] += 1.0;
            }
        }
    }
    Vtu3::new(&points, &cells)
        .displacement(&m.state.u)
        .point_scalar("max_principal_stress", &s1)
        .point_scalar("point", &point_id)
        .region(&region)
        .stress(&stress, StressLayout::Symmetric6)
        .cell_scalar("fragment", &frag.iter().map(|&f| f as f64).collect::<Vec<_>>())
        .cell_scalar("cracked_faces", &cracked)
}

/// The crack faces of the body as a VTU of polygons (`None` before any face separates): every
/// interior face separated at one corner at least (`Topology3::crack_state`), once per side,
/// each polygon on the clusters of its side's element (so the two sides of an open face are
/// two polygons on different points), wound outward of that element. Points at the reference
/// position with the point array `displacement` (ParaView's "Warp By Vector" opens the crack);
/// cell arrays `opening` (the mean over the face's corners of the gap `u_side1 - u_side0`
/// along the face's normal out of side 0: positive open, negative overlapping), `slip` (the
/// gap's tangential length), `cut_corners` (at how many corners the face is separated: all of
/// them, fully open), `side` (0, 1) and `fragment` (of the side's element, as in the snapshot).
pub fn crack_faces3(m: &March3) -> Option<Vtu3> {
    let t = &m.topo;
    let (frag, _) = t.fragments();
    let mut local = vec![u32::MAX; t.n_clusters()];
    let (mut clusters, mut polys) = (Vec::<usize>::new(), Vec::<Vec<u32>>::new());
    let (mut opening, mut slip, mut cut, mut side, mut fragment) = (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (f, face) in t.faces.iter().enumerate() {
        let fid = crate::ids::FaceId::new(f);
        let ncut = t.crack_state(fid);
        let [Some((a, _)), Some((b, _))] = face.sides else { continue };
        if ncut == 0 {
            continue;
        }
        let corners = face.corners();
        let side_clusters = |e: crate::ids::ElemId| -> Vec<usize> { corners.iter().map(|&p| t.copy_cluster[t.copy_at(e, p).expect("a face's corner is its element's").idx()].idx()).collect() };
        let (c0, c1) = (side_clusters(a), side_clusters(b));
        let n = crate::solver::march3::face_normal(&m.mesh, t, fid);
        let mut g = [0.0; 3];
        for (&p, &q) in c0.iter().zip(&c1) {
            for d in 0..3 {
                g[d] += (m.state.u[q][d] - m.state.u[p][d]) / corners.len() as f64;
            }
        }
        let gn = g[0] * n[0] + g[1] * n[1] + g[2] * n[2];
        let gt = ((g[0] - gn * n[0]).powi(2) + (g[1] - gn * n[1]).powi(2) + (g[2] - gn * n[2]).powi(2)).sqrt();
        for (k, (cs, e)) in [(c0, a), (c1, b)].into_iter().enumerate() {
            let mut poly: Vec<u32> = cs
                .iter()
                .map(|&c| {
                    if local[c] == u32::MAX {
                        local[c] = clusters.len() as u32;
                        clusters.push(c);
                    }
                    local[c]
                })
                .collect();
            if k == 1 {
                poly.reverse();
            }
            polys.push(poly);
            opening.push(gn);
            slip.push(gt);
            cut.push(ncut as f64);
            side.push(k as f64);
            fragment.push(frag[e.idx()] as f64);
        }
    }
    if polys.is_empty() {
        return None;
    }
    let points: Vec<[f64; 3]> = clusters.iter().map(|&c| m.mesh.points[t.cluster_point[c].idx()]).collect();
    let u: Vec<[f64; 3]> = clusters.iter().map(|&c| m.state.u[c]).collect();
    Some(
        Vtu3::polygons(&points, &polys)
            .displacement(&u)
            .cell_scalar("opening", &opening)
            .cell_scalar("slip", &slip)
            .cell_scalar("cut_corners", &cut)
            .cell_scalar("side", &side)
            .cell_scalar("fragment", &fragment),
    )
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
        let mut ck = Checkpoint3::capture(m, pos);
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
    let scene_json = serde_json::to_string(&scene.file).map_err(|e| FlemError::Other(format!("the scene cannot be written as JSON for its hash: {e}")))?;
    let mut m = March3::from_scene(scene)?;
    let hash = scene_hash3(&scene_json, &m);
    // The pre-separated faces' splits are in the first stage's rows of splits3.csv.
    let mut w = Writer3::new(dir, scene, hash, stop);
    let mut from = None;
    if resume {
        let (ck, path, refused) = load_newest3(dir, hash)?;
        m.warnings.extend(refused);
        ck.restore(&mut m)?;
        let st: Writer3State = ck.section("output3", 1)?.ok_or_else(|| FlemError::Checkpoint { path: path.display().to_string(), msg: "has no output section".into() })?;
        w.history.resume(&dir.join("history.csv"), st.history, &path)?;
        w.splits.resume(&dir.join("splits3.csv"), st.splits, &path)?;
        w.snapshots = st.snapshots;
        w.splits_seen = st.splits_seen;
        w.seq = ck.seq;
        m.warnings.push(format!("resumed from {} (step {}, stage {} step {})", path.display(), ck.step, ck.pos.stage + 1, ck.pos.steps));
        from = Some(ck.pos);
    }
    let (stages, compare) = if scene.file.check.is_some() {
        let mut c = crate::output::compare3::Comparer3::new(&mut w, scene, dir)?;
        if let Some(p) = &from {
            c.keep_rows_before(p.stage);
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
        "energy": { "external_work": m.ledger.external_work, "kinetic": m.ledger.kinetic, "strain": m.ledger.strain, "damping": m.ledger.damping },
        "wall_seconds": t0.elapsed().as_secs_f64(),
    });
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

/// The state of a 3D body as flat arrays (the Python package's `flem.run` of a 3D scene,
/// docs/python.md): per cluster the reference position `points`, the mesh point it was split
/// from, `displacement`, `velocity`, `mass` and the nodal stress (the mean of its copies'
/// corner stresses, `[xx, yy, zz, xy, yz, zx]`, tension positive: the failure check's);
/// per element the cell on clusters, the region index (the snapshot's `region`), the mean
/// corner stress (the snapshot's `stress`, same order as the nodal stress) and the fragment;
/// per separated face (`crack_state` > 0, in face order) its two elements and at how many
/// corners it is separated.
#[derive(Clone, Debug, Default)]
pub struct Arrays3 {
    pub points: Vec<[f64; 3]>,
    pub point_id: Vec<u32>,
    pub cells: Vec<RawCell3>,
    pub region: Vec<i32>,
    pub displacement: Vec<[f64; 3]>,
    pub velocity: Vec<[f64; 3]>,
    pub mass: Vec<f64>,
    pub nodal_stress: Vec<[f64; 6]>,
    pub elem_stress: Vec<[f64; 6]>,
    pub fragment: Vec<u32>,
    pub crack_faces: Vec<[u32; 2]>,
    pub crack_state: Vec<u8>,
}

/// [`Arrays3`] of the body now.
pub fn arrays3(m: &March3) -> Arrays3 {
    let t = &m.topo;
    let cells = cluster_cells(m);
    let elem_stress = elem_mean_stress(m);
    let region = region_ids(m);
    let (mut crack_faces, mut crack_state) = (Vec::new(), Vec::new());
    for (f, face) in t.faces.iter().enumerate() {
        let s = t.crack_state(crate::ids::FaceId::new(f));
        if let ([Some((a, _)), Some((b, _))], true) = (face.sides, s > 0) {
            crack_faces.push([a.0, b.0]);
            crack_state.push(s);
        }
    }
    Arrays3 {
        points: t.cluster_point.iter().map(|p| m.mesh.points[p.idx()]).collect(),
        point_id: t.cluster_point.iter().map(|p| p.0).collect(),
        cells,
        region,
        displacement: m.state.u.clone(),
        velocity: m.state.v.clone(),
        mass: m.state.mass.clone(),
        nodal_stress: m.nodal_stress(),
        elem_stress,
        fragment: t.fragments().0,
        crack_faces,
        crack_state,
    }
}
