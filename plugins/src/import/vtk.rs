//! `[mesh] type = "vtk"`: unstructured grids from `.vtu` (XML) or legacy `.vtk` files, read
//! through vtkio.
//!
//! VTK_TRIANGLE (5) and VTK_QUAD (9) cells become T3/Q4 cells. VTK_LINE (3) and VTK_VERTEX (1)
//! cells are ignored unless the region array gives them a group: lines then form an edge set
//! and a node set, vertices a node set, named by their value. Any other cell type is refused.
//!
//! Regions come from a cell-data array: `region_array` if given (it must exist), else "region",
//! else "gmsh:physical" (as meshio writes it); integer values become names ("1"). Without such
//! an array every cell is in region "all". Only points used by 2D cells are kept.
//!
//! ```toml
//! [mesh]
//! type = "vtk"
//! file = "meshes/rect_quad.vtu"
//! region_array = "region"   # optional
//! ```
use std::path::Path;

use flem_core::mesh::{CellKind, MeshSource, RawCell, RawMesh};
use flem_core::{FlemError, Result};
use serde::{Deserialize, Serialize};
use vtkio::model::{Attribute, CellType, DataSet, Piece, UnstructuredGridPiece, VertexNumbers};

use super::{no_panic, read_input, Gathered};

/// A VTK unstructured grid file; `file` is relative to the scene file's folder.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Vtk {
    pub file: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub region_array: Option<String>,
}

#[typetag::serde(name = "vtk")]
impl MeshSource for Vtk {
    fn load(&self, base_dir: &Path) -> Result<RawMesh> {
        let (src, path, bytes) = read_input(base_dir, &self.file)?;
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
        read_vtk_bytes(&src, &ext, &bytes, self.region_array.as_deref())
    }

    /// The 2D mesh, or the 3D one when the file has volume cells (`vtk3.rs`).
    fn load_any(&self, base_dir: &Path) -> Result<flem_core::mesh::AnyMesh> {
        let (src, path, bytes) = read_input(base_dir, &self.file)?;
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
        super::vtk3::read_vtk_any(&src, &ext, &bytes, self.region_array.as_deref())
    }
}

/// Reads a VTK file held in memory: `ext` is "vtu" (XML) or "vtk" (legacy); `src` names it in
/// errors; `region_array` as in [`Vtk`].
pub fn read_vtk_bytes(src: &str, ext: &str, bytes: &[u8], region_array: Option<&str>) -> Result<RawMesh> {
    let src = src.to_string();
    let pieces = parse_vtk(&src, ext, bytes)?;
    let mut g = Gathered { words: ("VTK point", "VTK cell"), zero_based: true, ..Default::default() };
    for piece in pieces {
        match piece {
            Piece::Inline(p) => add_piece(&src, *p, region_array, &mut g)?,
            _ => return Err(FlemError::mesh(&src, "pieces stored in other files (parallel VTK) are not supported")),
        }
    }
    let mut mesh = g.finish(&src)?;
    mesh.node_sets.retain(|_, s| !s.is_empty());
    mesh.edge_sets.retain(|_, s| !s.is_empty());
    Ok(mesh)
}

/// The pieces of the unstructured grid of a VTK file held in memory (see [`read_vtk_bytes`]).
pub(crate) fn parse_vtk(src: &str, ext: &str, bytes: &[u8]) -> Result<Vec<Piece<UnstructuredGridPiece>>> {
    let src = src.to_string();
    let parsed = no_panic("the VTK reader (vtkio)", || match ext {
        "vtu" => Some(vtkio::Vtk::parse_xml(std::io::Cursor::new(bytes))),
        "vtk" => Some(vtkio::Vtk::parse_legacy_be(bytes)),
        _ => None,
    });
    // vtkio's errors give no position: on failure (only) our scanner looks for the line, the
    // section, the piece and the data array.
    let hint = || {
        let h = if ext == "vtu" { super::vtk_locate::locate_xml(bytes) } else { super::vtk_locate::locate_legacy(bytes) };
        h.map_or_else(String::new, |h| format!("; {h}"))
    };
    let vtk = match parsed {
        Ok(Some(Ok(v))) => v,
        Ok(Some(Err(e))) => return Err(FlemError::mesh(&src, format!("cannot parse the VTK file: {e}{}", hint()))),
        Ok(None) => return Err(FlemError::mesh(&src, format!("unknown VTK file extension \"{ext}\"; use .vtu (XML unstructured grid) or .vtk (legacy)"))),
        Err(e) => return Err(FlemError::mesh(&src, format!("{e}{}", hint()))),
    };
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        return Err(FlemError::mesh(&src, "the VTK file holds no unstructured grid"));
    };
    Ok(pieces)
}

/// The cells of a piece as (type, point indices), whatever the connectivity layout.
pub(crate) fn cell_list(src: &str, p: &UnstructuredGridPiece) -> Result<Vec<(CellType, Vec<u64>)>> {
    let types = &p.cells.types;
    let bad = |m: String| FlemError::mesh(src, format!("bad cell connectivity: {m}"));
    let mut out = Vec::new();
    match &p.cells.cell_verts {
        VertexNumbers::Legacy { vertices, .. } => {
            let mut i = 0usize;
            for (c, &t) in types.iter().enumerate() {
                let n = *vertices.get(i).ok_or_else(|| bad(format!("cell {c} is missing")))? as usize;
                let v = vertices.get(i + 1..i + 1 + n).ok_or_else(|| bad(format!("cell {c} is cut short")))?;
                out.push((t, v.iter().map(|&x| x as u64).collect()));
                i += 1 + n;
            }
        }
        VertexNumbers::XML { connectivity, offsets } => {
            let offs = if offsets.len() == types.len() + 1 && offsets.first() == Some(&0) { &offsets[1..] } else { &offsets[..] };
            if offs.len() != types.len() {
                return Err(bad(format!("{} offsets for {} cells", offs.len(), types.len())));
            }
            let mut start = 0u64;
            for (c, (&t, &end)) in types.iter().zip(offs).enumerate() {
                let v = usize::try_from(start).ok().zip(usize::try_from(end).ok()).and_then(|(a, b)| connectivity.get(a..b));
                let v = v.ok_or_else(|| bad(format!("cell {c} has offsets {start}..{end} outside the {} connectivity entries", connectivity.len())))?;
                out.push((t, v.to_vec()));
                start = end;
            }
        }
    }
    Ok(out)
}

/// The region value per cell, from the chosen cell-data array.
pub(crate) fn regions(src: &str, p: &UnstructuredGridPiece, wanted: Option<&str>, n: usize) -> Result<Option<Vec<String>>> {
    let mut arrays = Vec::new();
    for a in &p.data.cell {
        match a {
            Attribute::DataArray(d) => arrays.push((d.name.as_str(), &d.data)),
            Attribute::Field { data_array, .. } => arrays.extend(data_array.iter().map(|f| (f.name.as_str(), &f.data))),
        }
    }
    let find = |name: &str| arrays.iter().find(|a| a.0 == name);
    let chosen = match wanted {
        Some(w) => Some(find(w).ok_or_else(|| {
            let names: Vec<&str> = arrays.iter().map(|a| a.0).collect();
            FlemError::mesh(src, format!("mesh.region_array = \"{w}\" is not a cell array of this file (it has: {names:?})"))
        })?),
        None => find("region").or_else(|| find("gmsh:physical")),
    };
    let Some((name, data)) = chosen else { return Ok(None) };
    let v: Vec<f64> = data.cast_into().ok_or_else(|| FlemError::mesh(src, format!("cell array \"{name}\" is not numeric")))?;
    if v.len() != n {
        return Err(FlemError::mesh(src, format!("cell array \"{name}\" has {} values for {n} cells (it must have one component)", v.len())));
    }
    v.iter()
        .enumerate()
        .map(
            |(c, &x)| {
                if x.fract() == 0.0 && x.abs() < 9e15 {
                    Ok(format!("{}", x as i64))
                } else {
                    Err(FlemError::mesh(src, format!("cell array \"{name}\": cell {c} has the non-integer region {x}")))
                }
            },
        )
        .collect::<Result<Vec<_>>>()
        .map(Some)
}

fn add_piece(src: &str, p: UnstructuredGridPiece, wanted: Option<&str>, g: &mut Gathered) -> Result<()> {
    let coords: Vec<f64> = p.points.cast_into().ok_or_else(|| FlemError::mesh(src, "the points are not numeric"))?;
    if coords.len() / 3 * 3 != coords.len() {
        return Err(FlemError::mesh(src, format!("{} point coordinates is not a multiple of 3", coords.len())));
    }
    let base = g.points.len() as u64;
    let np = (coords.len() / 3) as u64;
    if base + np >= u32::MAX as u64 {
        return Err(FlemError::mesh(src, "too many points"));
    }
    for (k, x) in coords.chunks_exact(3).enumerate() {
        g.points.push([x[0], x[1], x[2]]);
        g.labels.push(k as u64);
    }
    let cells = cell_list(src, &p)?;
    let region = regions(src, &p, wanted, cells.len())?;
    for (c, (t, v)) in cells.iter().enumerate() {
        let (kind, k) = match t {
            CellType::Triangle => (Some(CellKind::T3), 3),
            CellType::Quad => (Some(CellKind::Q4), 4),
            CellType::Line => (None, 2),
            CellType::Vertex => (None, 1),
            other if super::vtk3::is_volume_cell(*other) => {
                return Err(FlemError::mesh(
                    src,
                    format!("cell {c}: VTK cell type {} ({other:?}) is not supported in a 2D mesh: this file has volume cells, it is a 3D mesh; a 3D scene reads it (docs/3d.md)", *other as u8),
                ));
            }
            other => {
                return Err(FlemError::mesh(
                    src,
                    format!(
                        "cell {c}: VTK cell type {} ({other:?}) is not supported: FLEM uses first-order triangles (5) and quadrilaterals (9); lines (3) and vertices (1) may carry groups",
                        *other as u8
                    ),
                ))
            }
        };
        if v.len() != k {
            return Err(FlemError::mesh(src, format!("cell {c} ({t:?}) has {} points; it must have {k}", v.len())));
        }
        let mut nodes = [0u32; 4];
        for (a, &x) in v.iter().enumerate() {
            if x >= np {
                return Err(FlemError::mesh(src, format!("cell {c} refers to point {x}, but there are only {np} points")));
            }
            nodes[a] = (base + x) as u32;
        }
        let name = region.as_ref().map(|r| r[c].clone());
        match (kind, name) {
            (Some(kind), name) => {
                g.cells.push(RawCell { kind, nodes });
                g.cell_labels.push(c as u64);
                g.cell_region.push(name.unwrap_or_else(|| "all".into()));
            }
            (None, Some(name)) => {
                if k == 2 {
                    g.edge_sets.entry(name.clone()).or_default().push([nodes[0], nodes[1]]);
                }
                g.node_sets.entry(name).or_default().extend(&nodes[..k]);
            }
            (None, None) => {}
        }
    }
    Ok(())
}
