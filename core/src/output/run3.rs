//! A 3D scene's run in a folder (issue 38, `flem run` on a scene with `[model] dim = 3`):
//! one VTU per stage (`snapshot_NNNN_stageK.vtu`, `Vtu3`: one point per cluster, so an open
//! crack shows as a gap; the displacement, the nodal stress' largest principal value and the
//! cluster's point id as point arrays; the region, the mean corner stress and the fragment as
//! cell arrays), `history.csv` (one row per stage), `splits3.csv` (every split: stage, point,
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
    Vtu3::new(&points, &cells)
        .displacement(&m.state.u)
        .point_scalar("max_principal_stress", &s1)
        .point_scalar("point", &point_id)
        .region(&region)
        .stress(&stress, StressLayout::Symmetric6)
        .cell_scalar("fragment", &frag.iter().map(|&f| f as f64).collect::<Vec<_>>())
}

impl Observer3 for Writer3<'_> {
    fn stage_done(&mut self, m: &March3, stage: usize, r: &Stage3Result) -> Result<()> {
        let path = self.dir.join(format!("snapshot_{:04}_stage{stage}.vtu", self.snapshots));
        snapshot3(m).write(&path, true)?;
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
    let (stages, compare) = if scene.file.check.is_some() {
        let mut c = crate::output::compare3::Comparer3::new(&mut w, scene, dir)?;
        let stages = m.run_scene(scene, &mut c)?;
        (stages, Some(c.rows))
    } else {
        (m.run_scene(scene, &mut w)?, None)
    };
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
