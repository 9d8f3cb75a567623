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
        let num = |arrs: &[Attribute], name: &str| -> Result<Vec<f64>> { find(arrs, name).and_then(|b| b.cast_into::<f64>()).ok_or_else(|| bad(format!("has no numeric array \"{name}\""))) };
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

/// `path:line: msg` (1-based line), the form of every refusal of a file read here.
fn at(path: &Path, line: usize, msg: impl std::fmt::Display) -> FlemError {
    FlemError::Other(format!("{}:{line}: {msg}", path.display()))
}

/// The snapshot files listed in `results.pvd`, in order, with their times. A `<DataSet>` line
/// without `timestep` and `file`, or with a time that is not a finite number, is refused as
/// `results.pvd:LINE: ...` (the file is written whole by the run, so this is damage).
pub fn snapshot_list(dir: &Path) -> Result<Vec<(f64, PathBuf)>> {
    let pvd = dir.join("results.pvd");
    let text = std::fs::read_to_string(&pvd).map_err(|e| FlemError::Other(format!("{}: cannot be read ({e}); is {} a run folder?", pvd.display(), dir.display())))?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate().filter(|(_, l)| l.contains("<DataSet")) {
        let attr = |key: &str| line.split(&format!("{key}=\"")).nth(1).and_then(|r| r.split('"').next());
        let (Some(t), Some(f)) = (attr("timestep"), attr("file")) else { return Err(at(&pvd, i + 1, "a <DataSet> without its timestep=\"...\" and file=\"...\" attributes")) };
        let t: f64 = t.parse().ok().filter(|t: &f64| t.is_finite()).ok_or_else(|| at(&pvd, i + 1, format!("timestep=\"{t}\" is not a finite number")))?;
        out.push((t, dir.join(f)));
    }
    if !text.contains("</Collection>") {
        return Err(FlemError::Other(format!("{}: cut short (no </Collection>)", pvd.display())));
    }
    Ok(out)
}

/// `history.csv` as columns.
#[derive(Clone, Debug, Default)]
pub struct History {
    pub header: Vec<String>,
    /// One row per whole line; an empty field (a value not yet computed, e.g. the unbalanced
    /// ratio before its first check: the writer never writes NaN) is NaN here.
    pub rows: Vec<Vec<f64>>,
    /// The 1-based line number of a last line that was cut (no newline: the run was killed
    /// while writing it) and left out.
    pub cut_line: Option<usize>,
}

impl History {
    /// Reads `dir/history.csv`. Every whole line must have as many fields as the header, each a
    /// finite number or empty, `step` and `stage` (when present) whole numbers, `step` never
    /// going back: anything else is refused as `history.csv:LINE: what` (a curve drawn from a
    /// damaged log would be silently wrong). The one exception is a last line without its
    /// newline, which only a kill during the write leaves (`flem_core::output::csvlog`): it is
    /// left out and reported in [`History::cut_line`] (and by `plot_run` in its notes).
    pub fn read(dir: &Path) -> Result<History> {
        let path = dir.join("history.csv");
        let text = std::fs::read_to_string(&path).map_err(|e| FlemError::Other(format!("{}: cannot be read ({e})", path.display())))?;
        let whole = text.rfind('\n').map_or(0, |i| i + 1);
        let mut lines = text[..whole].split_terminator('\n').map(|l| l.strip_suffix('\r').unwrap_or(l));
        let Some(head) = lines.next().filter(|h| !h.trim().is_empty()) else { return Err(at(&path, 1, "no header line (the file is empty or its first line is cut)")) };
        let header: Vec<String> = head.split(',').map(str::to_string).collect();
        let cut_line = (whole < text.len()).then(|| text[..whole].matches('\n').count() + 1);
        if cut_line == Some(1) {
            return Err(at(&path, 1, "no header line (the file is empty or its first line is cut)"));
        }
        let whole_cols: Vec<usize> = ["step", "stage"].iter().filter_map(|n| header.iter().position(|h| h == n)).collect();
        let step_col = header.iter().position(|h| h == "step");
        let mut rows: Vec<Vec<f64>> = Vec::new();
        for (i, l) in lines.enumerate() {
            let ln = i + 2;
            let fields: Vec<&str> = l.split(',').collect();
            if fields.len() != header.len() {
                return Err(at(&path, ln, format!("{} fields, but the header has {} columns", fields.len(), header.len())));
            }
            let mut row = Vec::with_capacity(fields.len());
            for (c, f) in fields.iter().enumerate() {
                let v = if f.is_empty() {
                    if whole_cols.contains(&c) {
                        return Err(at(&path, ln, format!("column \"{}\" is empty", header[c])));
                    }
                    f64::NAN
                } else {
                    match f.parse::<f64>() {
                        Ok(v) if v.is_finite() => v,
                        _ => return Err(at(&path, ln, format!("column \"{}\" = \"{}\" is not a finite number", header[c], f.escape_debug()))),
                    }
                };
                if whole_cols.contains(&c) && (v < 0.0 || v.fract() != 0.0) {
                    return Err(at(&path, ln, format!("column \"{}\" = {f} is not a whole number", header[c])));
                }
                row.push(v);
            }
            if let (Some(sc), Some(prev)) = (step_col, rows.last()) {
                if row[sc] < prev[sc] {
                    return Err(at(&path, ln, format!("step {} comes after step {} (rows out of order: the file was edited or two logs were joined)", row[sc], prev[sc])));
                }
            }
            rows.push(row);
        }
        Ok(History { header, rows, cut_line })
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

/// Per-stage results from `summary.json`: (name, converged, splits); `None` when the folder has
/// no summary.json (a run killed before its end writes none). A summary.json that is not JSON
/// (e.g. cut) is refused as `summary.json:LINE:COLUMN: ...`, one without a well-formed `stages`
/// list as `summary.json: stages[K].KEY ...` (it is written whole by the run, so this is damage;
/// guessing would mark stages wrongly as in equilibrium or not).
pub fn stages(dir: &Path) -> Result<Option<Vec<(String, bool, u64)>>> {
    let path = dir.join("summary.json");
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(FlemError::Other(format!("{}: cannot be read ({e})", path.display()))),
    };
    let v: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| FlemError::Other(format!("{}:{}:{}: not valid JSON ({e}){}", path.display(), e.line(), e.column(), if e.is_eof() { "; the file is cut short" } else { "" })))?;
    let bad = |key: String, what: &str| FlemError::Other(format!("{}: {key} {what}", path.display()));
    let list = v.get("stages").and_then(|s| s.as_array()).ok_or_else(|| bad("stages".into(), "is missing or not a list"))?;
    list.iter()
        .enumerate()
        .map(|(k, s)| {
            let name = s.get("name").and_then(|x| x.as_str()).ok_or_else(|| bad(format!("stages[{k}].name"), "is missing or not a string"))?;
            let conv = s.get("converged").and_then(|x| x.as_bool()).ok_or_else(|| bad(format!("stages[{k}].converged"), "is missing or not true/false"))?;
            let splits = s.get("splits").and_then(|x| x.as_u64()).ok_or_else(|| bad(format!("stages[{k}].splits"), "is missing or not a whole number"))?;
            Ok((name.to_string(), conv, splits))
        })
        .collect::<Result<Vec<_>>>()
        .map(Some)
}

#[cfg(test)]
mod tests {
    /// A history whose last row was cut by a kill (no newline): only the whole rows are read.
    #[test]
    fn history_ignores_a_cut_last_row() {
        let dir = folder("cut");
        std::fs::write(dir.join("history.csv"), "step,time\n1,1e-1\n2,2e-1\n3,3e").unwrap();
        let h = super::History::read(&dir).unwrap();
        assert_eq!(h.header, ["step", "time"]);
        assert_eq!(h.rows, vec![vec![1.0, 0.1], vec![2.0, 0.2]]);
        assert_eq!(h.cut_line, Some(4));
        let _ = std::fs::remove_dir_all(&dir);
    }

    fn folder(tag: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("flem-plot-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// Damaged history.csv lines are refused as `history.csv:LINE: what` with the column named,
    /// never read as NaN or a short row (reference: the writer's format, `OutputWriter::history`:
    /// every row has the header's columns, numbers or empty for "not computed yet").
    #[test]
    fn history_refuses_damaged_lines_by_line_and_column() {
        let dir = folder("bad-hist");
        let head = "step,time,stage,level_p,external_work,unbalanced_ratio\n";
        let ok = "0,0e0,0,0e0,0e0,\n10,1e-3,0,5e-1,2e-3,4.5e-2\n";
        std::fs::write(dir.join("history.csv"), format!("{head}{ok}")).unwrap();
        let h = super::History::read(&dir).unwrap();
        assert_eq!(h.rows.len(), 2);
        assert!(h.rows[0][5].is_nan() && h.rows[1][5] == 4.5e-2 && h.cut_line.is_none(), "an empty field is a value not computed yet");
        let cases = [
            ("20,2e-3,0,1e0,3e-3\n", ":4: 5 fields, but the header has 6 columns"),
            ("20,2e-3,0,1e0,3e-3,1e-2,7\n", ":4: 7 fields"),
            ("20,2e-3,0,1e0,3x-3,1e-2\n", ":4: column \"external_work\" = \"3x-3\" is not a finite number"),
            ("20,2e-3,0,NaN,3e-3,1e-2\n", ":4: column \"level_p\" = \"NaN\" is not a finite number"),
            ("20,2e-3,0,inf,3e-3,1e-2\n", "column \"level_p\" = \"inf\""),
            (",2e-3,0,1e0,3e-3,1e-2\n", ":4: column \"step\" is empty"),
            ("20,2e-3,1.5,1e0,3e-3,1e-2\n", ":4: column \"stage\" = 1.5 is not a whole number"),
            ("5,2e-3,0,1e0,3e-3,1e-2\n", ":4: step 5 comes after step 10"),
            ("\n20,2e-3,0,1e0,3e-3,1e-2\n", ":4: 1 fields"),
        ];
        for (extra, want) in cases {
            std::fs::write(dir.join("history.csv"), format!("{head}{ok}{extra}")).unwrap();
            let e = super::History::read(&dir).unwrap_err().to_string();
            assert!(e.contains(&format!("{}", dir.join("history.csv").display())) && e.contains(want), "{extra:?}: {e}");
        }
        // Empty, or only a cut header: no header.
        for text in ["", "step,ti"] {
            std::fs::write(dir.join("history.csv"), text).unwrap();
            let e = super::History::read(&dir).unwrap_err().to_string();
            assert!(e.contains("history.csv:1: no header line"), "{text:?}: {e}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// summary.json: absent (a killed run) is `None`; cut, not JSON, or with a damaged `stages`
    /// list it is refused with the line and column or the key (reference: the writer's format,
    /// `OutputWriter::write_summary`).
    #[test]
    fn summary_refuses_damage_by_line_or_key() {
        let dir = folder("bad-summary");
        assert!(super::stages(&dir).unwrap().is_none());
        let good = "{\n  \"title\": \"t\",\n  \"stages\": [\n    {\"name\": \"load\", \"converged\": true, \"splits\": 3}\n  ]\n}\n";
        std::fs::write(dir.join("summary.json"), good).unwrap();
        assert_eq!(super::stages(&dir).unwrap().unwrap(), vec![("load".to_string(), true, 3)]);
        let path = dir.join("summary.json").display().to_string();
        let cases = [
            (good[..good.len() - 9].to_string(), format!("{path}:4:")),
            (good.replace("true", "yes"), format!("{path}:4:")),
            (good.replace("\"converged\": true, ", ""), format!("{path}: stages[0].converged is missing")),
            (good.replace("3}", "\"3\"}"), format!("{path}: stages[0].splits is missing or not a whole number")),
            (good.replace("\"stages\"", "\"stage\""), format!("{path}: stages is missing")),
        ];
        for (text, want) in cases {
            std::fs::write(dir.join("summary.json"), &text).unwrap();
            let e = super::stages(&dir).unwrap_err().to_string();
            assert!(e.contains(&want), "{text:?}: {e}");
        }
        std::fs::write(dir.join("summary.json"), &good[..40]).unwrap();
        assert!(super::stages(&dir).unwrap_err().to_string().contains("cut short"));
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// results.pvd: a `<DataSet>` without its attributes or with a time that is not a number,
    /// or a file cut before `</Collection>`, is refused with the line (reference: the writer's
    /// format, `OutputWriter::write_pvd`).
    #[test]
    fn snapshot_list_refuses_a_damaged_pvd() {
        let dir = folder("bad-pvd");
        let pvd = |sets: &str, end: bool| format!("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\">\n  <Collection>\n{sets}{}", if end { "  </Collection>\n</VTKFile>\n" } else { "" });
        let one = "    <DataSet timestep=\"1e0\" group=\"\" part=\"0\" file=\"a.vtu\"/>\n";
        std::fs::write(dir.join("results.pvd"), pvd(one, true)).unwrap();
        assert_eq!(super::snapshot_list(&dir).unwrap(), vec![(1.0, dir.join("a.vtu"))]);
        for (text, want) in [
            (pvd(&one.replace("1e0", "1x0"), true), "results.pvd:4: timestep=\"1x0\""),
            (pvd(&one.replace(" file=", " fle="), true), "results.pvd:4: a <DataSet> without"),
            (pvd(one, false), "results.pvd: cut short"),
        ] {
            std::fs::write(dir.join("results.pvd"), &text).unwrap();
            let e = super::snapshot_list(&dir).unwrap_err().to_string();
            assert!(e.contains(want), "{text:?}: {e}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
