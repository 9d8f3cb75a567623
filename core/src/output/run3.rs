//! A 3D scene's run in a folder (issue 38, `flem run` on a scene with `[model] dim = 3`):
//! one VTU per stage (`snapshot_NNNN_stageK.vtu`, `Vtu3`: one point per cluster, so an open
//! crack shows as a gap; the displacement, the nodal stress' largest principal value and the
//! cluster's point id as point arrays; the region, the mean corner stress, the fragment and
//! `cracked_faces`, the number of the cell's faces separated at one corner at least, as cell
//! arrays), the crack faces once there are any (`cracks_NNNN_stageK.vtu`, [`crack_faces3`]:
//! both sides of every separated face as a polygon with its opening), `history.csv` (one row per stage), `splits3.csv` (every split: stage, point,
//! its coordinates, the new cluster) and `summary.json`, all written atomically or appended by
//! whole rows. What the 2D writer has and this one has not yet: probes, reactions, plots,
//! checkpoints (docs/3d.md).
use std::io::Write;
use std::path::Path;

use crate::error::{FlemError, Result};
use crate::mesh::RawCell3;
use crate::output::vtu3::{StressLayout, Vtu3};
use crate::scene3::Scene3;
use crate::solver::march3::{March3, Observer3, Stage3Result};

struct Writer3<'a> {
    dir: &'a Path,
    snapshots: usize,
    splits_seen: usize,
}

fn io(path: &Path, e: std::io::Error) -> FlemError {
    FlemError::Output { path: path.display().to_string(), msg: e.to_string() }
}

fn append(path: &Path, header: &str, rows: &str) -> Result<()> {
    let new = !path.exists();
    let mut f = std::fs::OpenOptions::new().create(true).append(true).open(path).map_err(|e| io(path, e))?;
    let mut s = String::new();
    if new {
        s.push_str(header);
        s.push('\n');
    }
    s.push_str(rows);
    f.write_all(s.as_bytes()).map_err(|e| io(path, e))
}

/// The body as VTU: one point per cluster at its point's reference position.
pub fn snapshot3(m: &March3) -> Vtu3 {
    let t = &m.topo;
    let points: Vec<[f64; 3]> = t.cluster_point.iter().map(|p| m.mesh.points[p.idx()]).collect();
    let cells: Vec<RawCell3> = (0..t.n_elems())
        .map(|e| {
            let mut nodes = [0u32; 8];
            for (a, k) in t.elem_copies(crate::ids::ElemId::new(e)).enumerate() {
                nodes[a] = t.copy_cluster[k].0;
            }
            RawCell3 { kind: m.mesh.cells[e].kind, nodes }
        })
        .collect();
    let nodal = m.nodal_stress();
    let s1: Vec<f64> = nodal.iter().map(|&s| -crate::plugin::traits::principal3(s).p.s3).collect();
    let mut corner = vec![[0.0; 6]; t.copy_point.len()];
    for b in &m.blocks {
        b.corner_stresses(&m.state.u, &t.elem_first_copy, &mut corner);
    }
    let stress: Vec<[[f64; 3]; 3]> = (0..t.n_elems())
        .map(|e| {
            let r = t.elem_copies(crate::ids::ElemId::new(e));
            let n = r.len() as f64;
            let mut s = [0.0; 6];
            for k in r {
                for d in 0..6 {
                    s[d] += corner[k][d] / n;
                }
            }
            [[s[0], s[3], s[5]], [s[3], s[1], s[4]], [s[5], s[4], s[2]]]
        })
        .collect();
    let mut regions: Vec<&str> = Vec::new();
    let region: Vec<i32> = (0..t.n_elems())
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
        .collect();
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
        append(&self.dir.join("history.csv"), "stage,name,steps,ratio,at_rest,time,splits,fragments", &row)?;
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
            append(&self.dir.join("splits3.csv"), "stage,point,x,y,z,new_cluster", &rows)?;
        }
        Ok(())
    }
}

/// Builds the body of a 3D scene and runs it in `dir` (created empty or emptied of a previous
/// run's files by the caller): the stage results, also in `summary.json`.
pub fn run3_in_folder(scene: &mut Scene3, dir: &Path) -> Result<(March3, Vec<Stage3Result>)> {
    let t0 = std::time::Instant::now();
    let mut m = March3::from_scene(scene)?;
    // The pre-separated faces' splits are in the first stage's rows of splits3.csv.
    let mut w = Writer3 { dir, snapshots: 0, splits_seen: 0 };
    let stages = m.run_scene(scene, &mut w)?;
    let summary = serde_json::json!({
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
    let cells: Vec<RawCell3> = (0..t.n_elems())
        .map(|e| {
            let mut nodes = [0u32; 8];
            for (a, k) in t.elem_copies(crate::ids::ElemId::new(e)).enumerate() {
                nodes[a] = t.copy_cluster[k].0;
            }
            RawCell3 { kind: m.mesh.cells[e].kind, nodes }
        })
        .collect();
    let mut corner = vec![[0.0; 6]; t.copy_point.len()];
    for b in &m.blocks {
        b.corner_stresses(&m.state.u, &t.elem_first_copy, &mut corner);
    }
    let elem_stress = (0..t.n_elems())
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
        .collect();
    let mut regions: Vec<&str> = Vec::new();
    let region = (0..t.n_elems())
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
        .collect();
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
