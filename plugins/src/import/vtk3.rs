//! VTK files with volume cells (issue 38): the 3D path of `[mesh] type = "vtk"`.
//!
//! A file is 3D when it holds a VTK volume cell (types 10-14, the quadratic and higher ones);
//! `Vtk::load_any` then gives [`AnyMesh::Three`], while the 2D `load` refuses it saying that
//! it is 3D. VTK_TETRA (10) cells become T4 and VTK_HEXAHEDRON (12) H8 cells (VTK's corner
//! order is ours); every other volume cell (voxel, wedge, pyramid, quadratic cells) is refused
//! by name with its cell index. Regions come from the cell array as in 2D (`region_array`,
//! else "region", else "gmsh:physical"; "all" without one); triangles (5) and quadrilaterals (9)
//! with a region value form a face set and a node set named by it, lines (3) and vertices (1)
//! a node set; without a region array they are ignored. Only points used by volume cells are
//! kept; messages name VTK cells and points by their 0-based index in the file. A VTU written
//! by [`flem_core::output::vtu3::Vtu3`] reads back as the mesh it was written from.
//!
//! ```toml
//! [mesh]
//! type = "vtk"
//! file = "3d/cube_hex.vtu"
//! region_array = "gmsh:physical"   # optional ("region", else "gmsh:physical")
//! ```
use flem_core::mesh::{AnyMesh, CellKind3, RawCell3, RawFace, NO_CORNER};
use flem_core::{FlemError, Result};
use vtkio::model::{CellType, Piece, UnstructuredGridPiece};

use super::gmsh3::Gathered3;
use super::vtk::{cell_list, parse_vtk, regions};

/// Whether VTK cell type `t` is a volume cell.
pub(crate) fn is_volume_cell(t: CellType) -> bool {
    matches!(t as u8, 10..=14 | 24..=27 | 29 | 31..=33 | 42)
}

/// Reads a VTK file held in memory in its own dimension: [`AnyMesh::Three`] when it has
/// volume cells, else the mesh of [`super::read_vtk_bytes`].
pub fn read_vtk_any(src: &str, ext: &str, bytes: &[u8], region_array: Option<&str>) -> Result<AnyMesh> {
    let pieces = parse_vtk(src, ext, bytes)?;
    let three = pieces.iter().any(|p| matches!(p, Piece::Inline(p) if p.cells.types.iter().any(|&t| is_volume_cell(t))));
    if !three {
        return Ok(AnyMesh::Two(super::read_vtk_bytes(src, ext, bytes, region_array)?));
    }
    let mut g = Gathered3 {
        points: Vec::new(),
        labels: Vec::new(),
        words: ("VTK point", "VTK cell"),
        zero_based: true,
        cells: Vec::new(),
        cell_labels: Vec::new(),
        cell_region: Vec::new(),
        node_sets: Default::default(),
        face_sets: Default::default(),
    };
    for piece in pieces {
        match piece {
            Piece::Inline(p) => add_piece3(src, *p, region_array, &mut g)?,
            _ => return Err(FlemError::mesh(src, "pieces stored in other files (parallel VTK) are not supported")),
        }
    }
    let mut mesh = g.finish(src)?;
    mesh.node_sets.retain(|_, s| !s.is_empty());
    mesh.face_sets.retain(|_, s| !s.is_empty());
    Ok(AnyMesh::Three(mesh))
}

fn add_piece3(src: &str, p: UnstructuredGridPiece, wanted: Option<&str>, g: &mut Gathered3) -> Result<()> {
    let coords: Vec<f64> = p.points.cast_into().ok_or_else(|| FlemError::mesh(src, "the points are not numeric"))?;
    if coords.len() % 3 != 0 {
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
        let k = match t {
            CellType::Tetra => 4,
            CellType::Hexahedron => 8,
            CellType::Triangle => 3,
            CellType::Quad => 4,
            CellType::Line => 2,
            CellType::Vertex => 1,
            other => {
                return Err(FlemError::mesh(
                    src,
                    format!("VTK cell {c} (0-based, as in the file): VTK cell type {} ({other:?}) is not supported in a 3D mesh: FLEM uses tetrahedra (10) and hexahedra (12); triangles (5), quadrilaterals (9), lines (3) and vertices (1) may carry groups", *other as u8),
                ))
            }
        };
        if v.len() != k {
            return Err(FlemError::mesh(src, format!("VTK cell {c} (0-based, as in the file) ({t:?}) has {} points; it must have {k}", v.len())));
        }
        let mut nodes = [0u32; 8];
        for (a, &x) in v.iter().enumerate() {
            if x >= np {
                return Err(FlemError::mesh(src, format!("VTK cell {c} (0-based, as in the file) refers to point {x}, but there are only {np} points")));
            }
            nodes[a] = (base + x) as u32;
        }
        let name = region.as_ref().map(|r| r[c].clone());
        match (t, name) {
            (CellType::Tetra | CellType::Hexahedron, name) => {
                let kind = if k == 4 { CellKind3::T4 } else { CellKind3::H8 };
                g.cells.push(RawCell3 { kind, nodes });
                g.cell_labels.push(c as u64);
                g.cell_region.push(name.unwrap_or_else(|| "all".into()));
            }
            (CellType::Triangle | CellType::Quad, Some(name)) => {
                let f = RawFace([nodes[0], nodes[1], nodes[2], if k == 4 { nodes[3] } else { NO_CORNER }]);
                g.face_sets.entry(name.clone()).or_default().push(f);
                g.node_sets.entry(name).or_default().extend_from_slice(f.corners());
            }
            (_, Some(name)) => g.node_sets.entry(name).or_default().extend_from_slice(&nodes[..k]),
            (_, None) => {}
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use flem_core::mesh::{AnyMesh, Box3, CellKind3, MeshSource, RawMesh3, ValidationOptions};
    use flem_core::output::vtu3::Vtu3;

    use super::read_vtk_any;

    /// A 3D VTU written by `Vtu3` (a distorted H8 box, a T4 box, regions 1 and 2) reads back as
    /// the mesh it was written from: the same points bit for bit, cells, regions; raw and
    /// compressed. The 2D reader refuses it saying it is 3D. Reference: the written mesh.
    #[test]
    fn our_3d_vtu_reads_back_as_the_mesh_written() {
        for (kind, compress) in [(CellKind3::H8, false), (CellKind3::T4, true)] {
            let mut b = Box3::new([1.0, 2.0, 0.5], [2, 3, 2], kind);
            b.distort = 0.1;
            let m: RawMesh3 = b.build().unwrap();
            let region: Vec<i32> = (0..m.cells.len()).map(|e| 1 + (e % 2) as i32).collect();
            let bytes = Vtu3::new(&m.points, &m.cells).region(&region).bytes(compress).unwrap();
            let AnyMesh::Three(mut r) = read_vtk_any("b.vtu", "vtu", &bytes, None).unwrap() else { panic!("read as 2D") };
            assert_eq!(r.points, m.points);
            assert_eq!(r.cells, m.cells);
            assert_eq!(r.cell_region, region.iter().map(|x| x.to_string()).collect::<Vec<_>>());
            assert!(r.validate(ValidationOptions::Refuse).unwrap().is_empty());
            let e = super::super::read_vtk_bytes("b.vtu", "vtu", &bytes, None).unwrap_err().to_string();
            assert!(e.contains("b.vtu: cell 0: VTK cell type") && e.contains("is not supported in a 2D mesh: this file has volume cells, it is a 3D mesh"), "{e}");
        }
    }

    /// The ```toml snippet of this module's doc loads its file (relative to configs/) as a 3D
    /// mesh. Reference: the docs and the shipped file.
    #[test]
    fn doc_toml_snippet_loads_a_3d_mesh() {
        let configs = crate::snippets::configs_dir();
        for (file, src) in crate::snippets::doc_snippets::<Box<dyn MeshSource>>(&[("import/vtk3.rs", include_str!("vtk3.rs"))], &["mesh"], &["vtk"]) {
            let AnyMesh::Three(mut m) = src.load_any(&configs).unwrap_or_else(|e| panic!("{file}: {e}")) else { panic!("{file}: not 3D") };
            m.validate(ValidationOptions::Refuse).unwrap_or_else(|e| panic!("{file}: {e}"));
            assert_eq!(m.cells.len(), 16);
            // meshio wrote gmsh's physical tags: volumes 1, 2; surfaces 3-6 (cube.geo).
            assert_eq!(m.cell_region.iter().filter(|r| *r == "1").count(), 8);
            assert_eq!(m.face_sets.keys().collect::<Vec<_>>(), ["3", "4", "5", "6"]);
            assert_eq!(m.face_sets["5"].len(), 8);
        }
    }
}
