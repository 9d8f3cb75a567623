//! Reading a run folder back: the VTU snapshots listed in `results.pvd` (through vtkio),
//! `history.csv` and `summary.json`, as written by `flem_core::output`.
use std::path::{Path, PathBuf};

use flem_core::{FlemError, Result};
use vtkio::model::{Attribute, CellType, DataSet, IOBuffer, Piece};

/// One snapshot: clusters (points), elements on clusters, crack faces, stresses.
#[derive(Clone, Debug, Default)]
pub struct Snapshot {
    /// The VTU file name.
    pub name: String,
    /// Reference coordinates of every cluster.
    pub x0: Vec<[f64; 2]>,
    /// Displacement of every cluster.
    pub u: Vec<[f64; 2]>,
    /// Mesh point of every cluster (clusters of one point share it).
    pub point: Vec<i64>,
    /// Elements as cluster lists (3 or 4).
    pub elems: Vec<Vec<usize>>,
    /// Mean stress of every element, tension positive `[sxx, syy, sxy]`.
    pub stress: Vec<[f64; 3]>,
    /// Crack faces: (clusters of the face on one side, 1 = separated at one end, 2 = both).
    pub cracks: Vec<([usize; 2], u8)>,
}

impl Snapshot {
    /// Reads one VTU written by `flem_core::output::snapshot_vtk`.
    pub fn read(path: &Path) -> Result<Snapshot> {
        let shown = path.display().to_string();
        let bad = |m: String| FlemError::Other(format!("{shown}: {m}"));
        let vtk = vtkio::Vtk::import(path).map_err(|e| bad(format!("cannot be read as VTU: {e}")))?;
        let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else { return Err(bad("is not an unstructured grid".into())) };
        let Some(Piece::Inline(p)) = pieces.into_iter().next() else { return Err(bad("has no inline piece".into())) };
        let coords: Vec<f64> = p.points.cast_into().ok_or_else(|| bad("points are not numeric".into()))?;
        let n = coords.len() / 3;
        let x0 = coords.chunks_exact(3).map(|c| [c[0], c[1]]).collect();
        let find = |arrs: &[Attribute], name: &str| -> Option<IOBuffer> {
            arrs.iter().find_map(|a| match a {
                Attribute::DataArray(d) if d.name == name => Some(d.data.clone()),
                _ => None,
            })
        };
        let num = |arrs: &[Attribute], name: &str| -> Result<Vec<f64>> {
            find(arrs, name).and_then(|b| b.cast_into::<f64>()).ok_or_else(|| bad(format!("has no numeric array \"{name}\"")))
        };
        let disp = num(&p.data.point, "displacement")?;
        if disp.len() != 3 * n {
            return Err(bad(format!("\"displacement\" has {} values for {n} points", disp.len())));
        }
        let u = disp.chunks_exact(3).map(|c| [c[0], c[1]]).collect();
        let point = num(&p.data.point, "point_id")?.into_iter().map(|v| v as i64).collect();
        let stress_c = num(&p.data.cell, "stress")?;
        let crack_c = num(&p.data.cell, "crack")?;
        let types = p.cells.types.clone();
        let (conn, offs) = p.cells.cell_verts.into_xml();
        if offs.len() != types.len() || stress_c.len() != 3 * types.len() || crack_c.len() != types.len() {
            return Err(bad("cell arrays do not match the cells".into()));
        }
        let mut s = Snapshot { name: path.file_name().map(|f| f.to_string_lossy().to_string()).unwrap_or_default(), x0, u, point, ..Default::default() };
        let mut start = 0usize;
        for (c, (&t, &end)) in types.iter().zip(&offs).enumerate() {
            let end = end as usize;
            let v: Vec<usize> = conn.get(start..end).ok_or_else(|| bad(format!("cell {c} has bad offsets")))?.iter().map(|&k| k as usize).collect();
            start = end;
            if v.iter().any(|&k| k >= n) {
                return Err(bad(format!("cell {c} refers to a point beyond {n}")));
            }
            match t {
                CellType::Quad | CellType::Triangle => {
                    s.elems.push(v);
                    s.stress.push([stress_c[3 * c], stress_c[3 * c + 1], stress_c[3 * c + 2]]);
                }
                CellType::Line if v.len() == 2 => s.cracks.push(([v[0], v[1]], crack_c[c] as u8)),
                _ => {}
            }
        }
        Ok(s)
    }

    /// Current position of cluster `c` with displacements magnified by `mag`.
    pub fn x(&self, c: usize, mag: f64) -> (f64, f64) {
        (self.x0[c][0] + mag * self.u[c][0], self.x0[c][1] + mag * self.u[c][1])
    }

    /// Largest displacement magnitude.
    pub fn max_disp(&self) -> f64 {
        self.u.iter().map(|u| u[0].hypot(u[1])).fold(0.0, f64::max)
    }

    /// Number of crack faces separated at both ends (each face counted once, not per side).
    pub fn open_faces(&self) -> usize {
        self.cracks.iter().filter(|c| c.1 >= 2).count() / 2
    }

    /// Number of crack faces separated at one end or more (per face).
    pub fn crack_faces(&self) -> usize {
        self.cracks.len() / 2
    }
}

/// The snapshot files listed in `results.pvd`, in order, with their times.
pub fn snapshot_list(dir: &Path) -> Result<Vec<(f64, PathBuf)>> {
    let pvd = dir.join("results.pvd");
    let text = std::fs::read_to_string(&pvd).map_err(|e| FlemError::Other(format!("{}: cannot be read ({e}); is {} a run folder?", pvd.display(), dir.display())))?;
    let mut out = Vec::new();
    for line in text.lines().filter(|l| l.contains("<DataSet")) {
        let attr = |key: &str| line.split(&format!("{key}=\"")).nth(1).and_then(|r| r.split('"').next());
        let (Some(t), Some(f)) = (attr("timestep"), attr("file")) else { continue };
        out.push((t.parse().unwrap_or(f64::NAN), dir.join(f)));
    }
    Ok(out)
}

/// `history.csv` as columns.
#[derive(Clone, Debug, Default)]
pub struct History {
    pub header: Vec<String>,
    pub rows: Vec<Vec<f64>>,
}

impl History {
    pub fn read(dir: &Path) -> Result<History> {
        let path = dir.join("history.csv");
        let text = std::fs::read_to_string(&path).map_err(|e| FlemError::Other(format!("{}: cannot be read ({e})", path.display())))?;
        // The log is appended row by row: a run killed by SIGKILL may leave its last row cut
        // (no newline; flem_core::output::csvlog). Only whole lines are read.
        let text = &text[..text.rfind('\n').map_or(0, |i| i + 1)];
        let mut lines = text.lines();
        let header: Vec<String> = lines.next().unwrap_or_default().split(',').map(str::to_string).collect();
        let rows = lines.filter(|l| !l.is_empty()).map(|l| l.split(',').map(|v| v.parse().unwrap_or(f64::NAN)).collect()).collect();
        Ok(History { header, rows })
    }

    pub fn col(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h == name)
    }

    /// Names of the load levels (`level_NAME` columns).
    pub fn loads(&self) -> Vec<String> {
        self.header.iter().filter_map(|h| h.strip_prefix("level_").map(str::to_string)).collect()
    }

    /// The row nearest in time to `t` (`None` without rows).
    pub fn at_time(&self, t: f64) -> Option<&Vec<f64>> {
        let c = self.col("time")?;
        self.rows.iter().min_by(|a, b| (a[c] - t).abs().total_cmp(&(b[c] - t).abs()))
    }
}

/// Per-stage results from `summary.json`: (name, converged, splits).
pub fn stages(dir: &Path) -> Vec<(String, bool, u64)> {
    let Ok(text) = std::fs::read_to_string(dir.join("summary.json")) else { return Vec::new() };
    let Ok(v) = serde_json::from_str::<serde_json::Value>(&text) else { return Vec::new() };
    v["stages"]
        .as_array()
        .map(|a| a.iter().map(|s| (s["name"].as_str().unwrap_or("").to_string(), s["converged"].as_bool().unwrap_or(false), s["splits"].as_u64().unwrap_or(0))).collect())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    /// A history whose last row was cut by a kill (no newline): only the whole rows are read.
    #[test]
    fn history_ignores_a_cut_last_row() {
        let dir = std::env::temp_dir().join(format!("flem-plot-cut-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("history.csv"), "step,time\n1,1e-1\n2,2e-1\n3,3e").unwrap();
        let h = super::History::read(&dir).unwrap();
        assert_eq!(h.header, ["step", "time"]);
        assert_eq!(h.rows, vec![vec![1.0, 0.1], vec![2.0, 0.2]]);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
