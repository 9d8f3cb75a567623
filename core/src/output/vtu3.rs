//! 3D results as VTU (issue 38): points, T4 and H8 cells (VTK types 10 and 12, corners in
//! VTK order as in [`RawMesh3`](crate::mesh::RawMesh3)), point arrays (the displacement
//! 3-vector and any named scalars and vectors) and cell arrays (the region id, the stress, any
//! named scalars), written with vtkio like the 2D snapshots ([`super::vtu_bytes`]) and on disk
//! through [`super::atomic_write`].
//!
//! The stress is given per cell as a symmetric 3x3 tensor and written either as 6 components in
//! VTK's order for symmetric tensors, `xx, yy, zz, xy, yz, xz` (ParaView shows them as a
//! symmetric tensor; meshio hands back an `(n, 6)` array), or as the 9 components of the full
//! tensor, row by row (meshio: `(n, 9)`; `reshape(-1, 3, 3)` gives the tensors)
//! ([`StressLayout`]). A VTU of surface polygons ([`Vtu3::polygons`]: triangles, quads, VTK
//! types 5 and 9) takes the same arrays: the crack faces of a 3D run (`cracks_NNNN_stageK.vtu`,
//! [`super::run3`]). Nothing non-finite is written: an array holding NaN or infinity, or of
//! the wrong length, is refused by name before any byte reaches the disk.
use std::path::Path;

use vtkio::model::{Attribute, Attributes, ByteOrder, CellType, Cells, DataSet, UnstructuredGridPiece, Version, VertexNumbers, Vtk};

use crate::error::{FlemError, Result};
use crate::mesh::{CellKind3, RawCell3};

/// How [`Vtu3::stress`] writes the tensor.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub enum StressLayout {
    /// 6 components `xx, yy, zz, xy, yz, xz` (VTK's symmetric tensor; default).
    #[default]
    Symmetric6,
    /// 9 components, the full tensor row by row.
    Full9,
}

/// One named array: its number of components and its values (component-fastest).
#[derive(Clone, Debug)]
enum Values {
    F64(Vec<f64>),
    I32(Vec<i32>),
}

#[derive(Clone, Debug)]
struct Array {
    name: String,
    components: usize,
    values: Values,
}

/// A 3D VTU being assembled: the mesh, then its arrays (see the module doc).
#[derive(Clone, Debug)]
pub struct Vtu3 {
    points: Vec<[f64; 3]>,
    cells: Vec<RawCell3>,
    /// Surface polygons (3 or more points each), written after `cells`.
    polys: Vec<Vec<u32>>,
    point: Vec<Array>,
    cell: Vec<Array>,
    title: String,
}

impl Vtu3 {
    /// The points and cells; no array yet.
    pub fn new(points: &[[f64; 3]], cells: &[RawCell3]) -> Self {
        Vtu3 { points: points.to_vec(), cells: cells.to_vec(), polys: Vec::new(), point: Vec::new(), cell: Vec::new(), title: "FLEM 3D snapshot".into() }
    }

    /// The points and surface polygons (each 3 or more point indices: VTK triangles, quads,
    /// polygons); no array yet. Cell arrays have one entry per polygon.
    pub fn polygons(points: &[[f64; 3]], polys: &[Vec<u32>]) -> Self {
        Vtu3 { points: points.to_vec(), cells: Vec::new(), polys: polys.to_vec(), point: Vec::new(), cell: Vec::new(), title: "FLEM 3D crack faces".into() }
    }

    /// The point array "displacement" (3 components).
    pub fn displacement(self, u: &[[f64; 3]]) -> Self {
        self.point_vector("displacement", u)
    }

    /// A named point scalar.
    pub fn point_scalar(mut self, name: &str, v: &[f64]) -> Self {
        self.point.push(Array { name: name.into(), components: 1, values: Values::F64(v.to_vec()) });
        self
    }

    /// A named point 3-vector.
    pub fn point_vector(mut self, name: &str, v: &[[f64; 3]]) -> Self {
        self.point.push(Array { name: name.into(), components: 3, values: Values::F64(v.iter().flatten().copied().collect()) });
        self
    }

    /// The cell array "region" (an integer id per cell).
    pub fn region(mut self, ids: &[i32]) -> Self {
        self.cell.push(Array { name: "region".into(), components: 1, values: Values::I32(ids.to_vec()) });
        self
    }

    /// The cell array "stress" from one symmetric tensor per cell, in `layout`.
    pub fn stress(mut self, s: &[[[f64; 3]; 3]], layout: StressLayout) -> Self {
        let (components, values): (usize, Vec<f64>) = match layout {
            StressLayout::Symmetric6 => (6, s.iter().flat_map(|t| [t[0][0], t[1][1], t[2][2], t[0][1], t[1][2], t[0][2]]).collect()),
            StressLayout::Full9 => (9, s.iter().flat_map(|t| t.iter().flatten().copied()).collect()),
        };
        self.cell.push(Array { name: "stress".into(), components, values: Values::F64(values) });
        self
    }

    /// A named cell scalar.
    pub fn cell_scalar(mut self, name: &str, v: &[f64]) -> Self {
        self.cell.push(Array { name: name.into(), components: 1, values: Values::F64(v.to_vec()) });
        self
    }

    /// Checks what would be written: cells naming existing points, arrays of the right length,
    /// with distinct non-empty names and finite values. The error names the array and the
    /// first bad entry.
    pub fn check(&self) -> std::result::Result<(), String> {
        let np = self.points.len();
        if let Some(i) = self.points.iter().position(|p| !p.iter().all(|x| x.is_finite())) {
            return Err(format!("point {i} has a non-finite coordinate {:?}", self.points[i]));
        }
        for (e, c) in self.cells.iter().map(|c| c.corners()).chain(self.polys.iter().map(|p| p.as_slice())).enumerate() {
            if let Some(&p) = c.iter().find(|&&p| p as usize >= np) {
                return Err(format!("cell {e} refers to point {p}, but there are {np} points"));
            }
            if c.len() < 3 {
                return Err(format!("cell {e} has {} points (a polygon needs 3 at least)", c.len()));
            }
        }
        for (arrays, n, what) in [(&self.point, np, "point"), (&self.cell, self.cells.len() + self.polys.len(), "cell")] {
            for (k, a) in arrays.iter().enumerate() {
                if a.name.is_empty() || arrays[..k].iter().any(|b| b.name == a.name) {
                    return Err(format!("the {what} array \"{}\" is unnamed or named twice", a.name));
                }
                let len = match &a.values {
                    Values::F64(v) => v.len(),
                    Values::I32(v) => v.len(),
                };
                if len != n * a.components {
                    return Err(format!("the {what} array \"{}\" has {} entries of {} components; it must have one per {what} ({n})", a.name, len as f64 / a.components as f64, a.components));
                }
                if let Values::F64(v) = &a.values {
                    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                        return Err(format!("the {what} array \"{}\" is not finite at {what} {} (component {}): {}", a.name, i / a.components, i % a.components, v[i]));
                    }
                }
            }
        }
        Ok(())
    }

    /// The vtkio model (unchecked; [`Self::bytes`] and [`Self::write`] check first).
    pub fn vtk(&self) -> Vtk {
        let mut conn = Vec::new();
        let mut offs = Vec::with_capacity(self.cells.len());
        for c in self.cells.iter().map(|c| c.corners()).chain(self.polys.iter().map(|p| p.as_slice())) {
            conn.extend(c.iter().map(|&p| p as u64));
            offs.push(conn.len() as u64);
        }
        let types = self
            .cells
            .iter()
            .map(|c| match c.kind {
                CellKind3::T4 => CellType::Tetra,
                CellKind3::H8 => CellType::Hexahedron,
            })
            .chain(self.polys.iter().map(|p| match p.len() {
                3 => CellType::Triangle,
                4 => CellType::Quad,
                _ => CellType::Polygon,
            }))
            .collect();
        let attr = |a: &Array| {
            let at = Attribute::generic(&a.name, a.components as u32);
            match &a.values {
                Values::F64(v) => at.with_data(v.clone()),
                Values::I32(v) => at.with_data(v.clone()),
            }
        };
        Vtk {
            version: Version::new_xml(1, 0),
            title: self.title.clone(),
            byte_order: ByteOrder::LittleEndian,
            file_path: None,
            data: DataSet::inline(UnstructuredGridPiece {
                points: self.points.iter().flatten().copied().collect::<Vec<f64>>().into(),
                cells: Cells { cell_verts: VertexNumbers::XML { connectivity: conn, offsets: offs }, types },
                data: Attributes { point: self.point.iter().map(attr).collect(), cell: self.cell.iter().map(attr).collect() },
            }),
        }
    }

    /// The VTU bytes (raw or zlib-compressed), after [`Self::check`].
    pub fn bytes(&self, compress: bool) -> Result<Vec<u8>> {
        self.check().map_err(|m| FlemError::Other(format!("3D VTU not written: {m}")))?;
        super::vtu_bytes(self.vtk(), compress)
    }

    /// Writes the VTU to `path` atomically ([`super::atomic_write`]); on a refused array
    /// nothing is written and the error names `path` and the array.
    pub fn write(&self, path: &Path, compress: bool) -> Result<()> {
        self.check().map_err(|msg| FlemError::Output { path: path.display().to_string(), msg })?;
        super::atomic_write(path, &super::vtu_bytes(self.vtk(), compress)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{Box3, CellKind3};

    /// Bad arrays are refused by name and nothing is written. Reference: the contract of
    /// `check` (module doc).
    #[test]
    fn bad_arrays_are_refused_by_name_and_nothing_is_written() {
        let m = Box3::new([1.0; 3], [1, 1, 1], CellKind3::T4).build().unwrap();
        let ok = Vtu3::new(&m.points, &m.cells).displacement(&vec![[0.0; 3]; 8]).region(&[1; 6]);
        assert!(ok.check().is_ok());
        let e = ok.clone().point_scalar("damage", &[0.0; 7]).check().unwrap_err();
        assert!(e.contains("point array \"damage\" has 7 entries of 1 components; it must have one per point (8)"), "{e}");
        let mut s = vec![[[0.0; 3]; 3]; 6];
        s[4][1][2] = f64::NAN;
        let e = ok.clone().stress(&s, StressLayout::Symmetric6).check().unwrap_err();
        assert!(e.contains("cell array \"stress\" is not finite at cell 4 (component 4): NaN"), "{e}");
        let e = ok.clone().point_scalar("displacement", &[0.0; 8]).check().unwrap_err();
        assert!(e.contains("\"displacement\" is unnamed or named twice"), "{e}");
        let dir = std::env::temp_dir().join(format!("flem-vtu3-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bad.vtu");
        let e = ok.stress(&s, StressLayout::Full9).write(&path, false).unwrap_err().to_string();
        assert!(e.contains("bad.vtu") && e.contains("not finite at cell 4 (component 5)"), "{e}");
        assert!(!path.exists());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
