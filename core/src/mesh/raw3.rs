//! 3D meshes as they come in (issue 38): points, tetrahedra and hexahedra, named node and face
//! sets, regions. The 3D twin of [`RawMesh`](super::RawMesh), kept a type of its own so that a
//! 2D scene's mesh, model and step are exactly what they were (docs/3d.md, "Design").
//!
//! # Conventions (ours, written down in docs/3d.md)
//! - Corner order of a cell is VTK's and gmsh's (they agree for first-order cells):
//!   T4 (VTK_TETRA 10, gmsh type 4): 0, 1, 2 anticlockwise seen from corner 3, so that the
//!   signed volume `(x1 - x0) . ((x2 - x0) x (x3 - x0)) / 6` is positive.
//!   H8 (VTK_HEXAHEDRON 12, gmsh type 5): 0-1-2-3 the bottom face anticlockwise seen from the
//!   top, 4-5-6-7 the top face above them.
//! - Local faces ([`CellKind3::faces`]) list their corners anticlockwise seen from outside the
//!   cell (outward normal by the right-hand rule), triangles with a 4th entry `u32::MAX`.
//! - A face set holds boundary faces by their corner points ([`RawFace`]); faces of cells
//!   only, like the edge sets of 2D.
//! - Point indices are `u32`, 0-based in the order of `points`; every per-point array of the
//!   model follows that order (a partition of the mesh later keeps a global id per point:
//!   `FileIds::points`).
use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::raw::FileIds;

/// First-order 3D cells.
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CellKind3 {
    /// 4-node linear tetrahedron.
    T4,
    /// 8-node brick.
    H8,
}

/// Marks the missing 4th corner of a triangular face.
pub const NO_CORNER: u32 = u32::MAX;

const T4_FACES: [[u32; 4]; 4] = [[0, 2, 1, NO_CORNER], [0, 1, 3, NO_CORNER], [1, 2, 3, NO_CORNER], [0, 3, 2, NO_CORNER]];
const H8_FACES: [[u32; 4]; 6] = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]];

impl CellKind3 {
    pub fn nodes(self) -> usize {
        match self {
            CellKind3::T4 => 4,
            CellKind3::H8 => 8,
        }
    }

    /// Local faces, corners anticlockwise seen from outside (see the module doc); a triangle
    /// ends with [`NO_CORNER`].
    pub fn faces(self) -> &'static [[u32; 4]] {
        match self {
            CellKind3::T4 => &T4_FACES,
            CellKind3::H8 => &H8_FACES,
        }
    }

    /// The VTK cell type (10, 12).
    pub fn vtk_type(self) -> u8 {
        match self {
            CellKind3::T4 => 10,
            CellKind3::H8 => 12,
        }
    }
}

/// One 3D cell: its kind and corner points (only the first `kind.nodes()` are used).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct RawCell3 {
    pub kind: CellKind3,
    pub nodes: [u32; 8],
}

impl RawCell3 {
    pub fn corners(&self) -> &[u32] {
        &self.nodes[..self.kind.nodes()]
    }
}

/// A face by its corner points (3 or 4; a triangle's 4th is [`NO_CORNER`]).
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct RawFace(pub [u32; 4]);

impl RawFace {
    pub fn corners(&self) -> &[u32] {
        if self.0[3] == NO_CORNER {
            &self.0[..3]
        } else {
            &self.0[..]
        }
    }

    /// The corners sorted: the key that finds the same face whatever its first corner and
    /// orientation.
    pub fn key(&self) -> [u32; 4] {
        let mut k = self.0;
        k.sort_unstable();
        k
    }
}

/// A 3D mesh with its named groups, as read or generated.
#[derive(Clone, Debug, Default)]
pub struct RawMesh3 {
    /// Name of the file (or generator) it came from, for error messages.
    pub source: String,
    pub points: Vec<[f64; 3]>,
    pub cells: Vec<RawCell3>,
    /// Region (material) name per cell; empty means one region "all".
    pub cell_region: Vec<String>,
    /// Named sets of points (supports, point loads, probes).
    pub node_sets: BTreeMap<String, Vec<u32>>,
    /// Named sets of faces (pressure loads, pre-separated faces, contact surfaces): gmsh's
    /// physical surfaces.
    pub face_sets: BTreeMap<String, Vec<RawFace>>,
    /// The ids the file gives its points and cells, for error messages.
    pub ids: Option<FileIds>,
}

impl RawMesh3 {
    /// Cell `e` as the user's file names it (see [`super::RawMesh::cell_name`]).
    pub fn cell_name(&self, e: usize) -> String {
        FileIds::cell(self.ids.as_ref(), e)
    }

    /// Point `p` as the user's file names it.
    pub fn point_name(&self, p: usize) -> String {
        FileIds::point(self.ids.as_ref(), p)
    }

    /// Points as the user's file names them.
    pub fn points_name(&self, ps: &[u32]) -> String {
        FileIds::points(self.ids.as_ref(), ps)
    }
}

/// Six times the signed volume of the tetrahedron `a, b, c, d` (positive when `a, b, c` turn
/// anticlockwise seen from `d`).
pub fn tet_volume6(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> f64 {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
    u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) + u[2] * (v[0] * w[1] - v[1] * w[0])
}

/// A mesh of either dimension, as a [`MeshSource`](super::MeshSource) gives it
/// ([`MeshSource::load_any`](super::MeshSource::load_any)).
#[derive(Clone, Debug)]
pub enum AnyMesh {
    Two(super::RawMesh),
    Three(RawMesh3),
}

impl AnyMesh {
    pub fn dim(&self) -> usize {
        match self {
            AnyMesh::Two(_) => 2,
            AnyMesh::Three(_) => 3,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: the unit corner tetrahedron has volume 1/6; every local face's corners,
    /// taken anticlockwise, give a normal pointing away from the cell's centroid (module doc).
    #[test]
    fn local_faces_point_outward() {
        let t4 = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!((tet_volume6(t4[0], t4[1], t4[2], t4[3]) - 1.0).abs() < 1e-15);
        let h8 = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0]];
        for (kind, x) in [(CellKind3::T4, &t4[..]), (CellKind3::H8, &h8[..])] {
            let n = x.len() as f64;
            let c: [f64; 3] = std::array::from_fn(|d| x.iter().map(|p| p[d]).sum::<f64>() / n);
            for f in kind.faces() {
                let f = RawFace(*f);
                let p: Vec<[f64; 3]> = f.corners().iter().map(|&i| x[i as usize]).collect();
                // The face's centre and the cell's centre: the face turns anticlockwise seen
                // from outside iff the tetrahedron (p0, p1, p2, centroid) has negative volume.
                assert!(tet_volume6(p[0], p[1], p[2], c) < 0.0, "{kind:?} face {:?}", f.0);
            }
        }
    }
}
