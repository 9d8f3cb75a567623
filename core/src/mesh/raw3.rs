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

use super::raw::{FileIds, ValidationOptions, MAX_COORD};
use crate::error::{FlemError, Result};

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

    /// Elements as the user's file names them, `more` after the list ([`FileIds::cells`]).
    pub fn cells_name(&self, es: &[usize], more: &str) -> String {
        FileIds::cells(self.ids.as_ref(), es, more)
    }

    /// Checks the mesh, the 3D twin of [`RawMesh::validate`](super::RawMesh::validate):
    /// returns warnings (reoriented cells) or the first error, naming the file and the element
    /// and points by the ids of the file ([`FileIds`]; 0-based indices without them).
    ///
    /// Refused: no cells; non-finite coordinates or coordinates beyond [`MAX_COORD`]; a cell
    /// naming a missing point or a point twice; a zero-volume cell; a hexahedron whose corner
    /// Jacobians change sign (twisted, non-convex or numbered out of order); a face shared by
    /// more than two cells, or by two cells on the same side of it (overlapping cells);
    /// duplicate points (at the same place within 1e-10 of the mesh size); points used by no
    /// cell (importers drop them before, as in 2D); node and face sets naming missing points;
    /// face-set faces that are not faces of a cell. Inverted cells (negative volume) are
    /// reoriented, T4 by swapping corners 1 and 2, H8 by swapping its bottom and top faces, each
    /// reported in a warning (the first five, then a count); [`ValidationOptions::Refuse`]
    /// refuses them instead.
    pub fn validate(&mut self, opt: ValidationOptions) -> Result<Vec<String>> {
        let src = self.source.clone();
        let np = self.points.len();
        let mut warnings = Vec::new();
        if self.cells.is_empty() {
            return Err(FlemError::mesh(&src, "the mesh has no 3D elements (tetrahedra or hexahedra)"));
        }
        if self.cell_region.len() != self.cells.len() {
            self.cell_region = vec!["all".to_string(); self.cells.len()];
        }
        for (i, p) in self.points.iter().enumerate() {
            if !p.iter().all(|v| v.is_finite()) {
                return Err(FlemError::mesh(&src, format!("{} has a non-finite coordinate {p:?}", self.point_name(i))));
            }
        }
        let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
        for p in &self.points {
            for d in 0..3 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        let diam = (0..3).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt().max(f64::MIN_POSITIVE);
        // Volumes and stiffnesses cube and square lengths: beyond this they overflow f64.
        let far = lo.iter().chain(&hi).fold(0.0f64, |m, x| m.max(x.abs()));
        if !(far <= MAX_COORD && diam <= MAX_COORD) {
            return Err(FlemError::mesh(&src, format!("coordinates reach {far:e} (the mesh is {diam:e} across); they must stay below {MAX_COORD:e} in magnitude: rescale the units")));
        }
        let ids = self.ids.as_ref();
        let name = |e: usize| FileIds::cell(ids, e);
        let pname = |p: usize| FileIds::point(ids, p);
        let pnames = |ps: &[u32]| FileIds::points(ids, ps);
        let mut flipped = 0usize;
        for (e, c) in self.cells.iter_mut().enumerate() {
            let k = c.kind.nodes();
            for a in 0..k {
                let n = c.nodes[a] as usize;
                if n >= np {
                    return Err(FlemError::mesh(&src, format!("{} refers to point index {n}, but there are only {np} points", name(e))));
                }
                if c.nodes[..a].contains(&c.nodes[a]) {
                    return Err(FlemError::mesh(&src, format!("{} uses {} twice", name(e), pname(n))));
                }
            }
            let x: Vec<[f64; 3]> = c.corners().iter().map(|&n| self.points[n as usize]).collect();
            // The longest edge: the length scale of the zero-volume test.
            let h = cell_edges(c.kind).iter().map(|&[a, b]| dist(x[a], x[b])).fold(0.0, f64::max);
            let tol = 1e-12 * h * h * h.max(diam * 1e-9);
            let sign = match c.kind {
                CellKind3::T4 => {
                    let v = tet_volume6(x[0], x[1], x[2], x[3]);
                    if v.abs() <= tol || h == 0.0 {
                        0
                    } else {
                        v.signum() as i32
                    }
                }
                CellKind3::H8 => {
                    let j: Vec<f64> = H8_CORNER_EDGES.iter().enumerate().map(|(i, &[a, b, cc])| tet_volume6(x[i], x[a], x[b], x[cc])).collect();
                    if h == 0.0 || j.iter().all(|v| v.abs() <= tol) {
                        0
                    } else if j.iter().all(|&v| v > tol) {
                        1
                    } else if j.iter().all(|&v| v < -tol) {
                        -1
                    } else {
                        return Err(FlemError::mesh(
                            &src,
                            format!(
                                "{} is not a valid hexahedron ({}): its corners do not all turn the same way (a twisted or non-convex brick, or corners out of the VTK/gmsh order)",
                                name(e),
                                pnames(c.corners())
                            ),
                        ));
                    }
                }
            };
            if sign == 0 {
                return Err(FlemError::mesh(&src, format!("{} has zero volume ({})", name(e), pnames(c.corners()))));
            }
            if sign < 0 {
                if opt == ValidationOptions::Refuse {
                    return Err(FlemError::mesh(&src, format!("{} is inverted (negative volume; {}); reorient it or set model.orientation = \"reorient\"", name(e), pnames(c.corners()))));
                }
                match c.kind {
                    CellKind3::T4 => c.nodes.swap(1, 2),
                    CellKind3::H8 => c.nodes.rotate_left(4),
                }
                flipped += 1;
                if flipped <= 5 {
                    warnings.push(format!("{src}: {} was inverted (negative volume) and has been reoriented", name(e)));
                }
            }
        }
        if flipped > 5 {
            warnings.push(format!("{src}: {flipped} elements in all were inverted and have been reoriented"));
        }
        // Faces shared by more than two cells, or by two cells on the same side of it.
        let mut faces: Vec<([u32; 4], u32, u8)> = Vec::new();
        for (e, c) in self.cells.iter().enumerate() {
            for (f, lf) in c.kind.faces().iter().enumerate() {
                faces.push((cell_face(c, lf).key(), e as u32, f as u8));
            }
        }
        faces.sort_unstable();
        let mut i = 0;
        while i < faces.len() {
            let mut j = i + 1;
            while j < faces.len() && faces[j].0 == faces[i].0 {
                j += 1;
            }
            let corners = |(key, _, _): ([u32; 4], u32, u8)| -> Vec<u32> { key.into_iter().filter(|&p| p != NO_CORNER).collect() };
            if j - i > 2 {
                let es: Vec<usize> = faces[i..j].iter().map(|f| f.1 as usize).collect();
                return Err(FlemError::mesh(&src, format!("the face through {} is shared by more than two elements: {}", self.points_name(&corners(faces[i])), self.cells_name(&es, ""))));
            }
            if j - i == 2 {
                let side = |(_, e, f): ([u32; 4], u32, u8)| cell_face(&self.cells[e as usize], &self.cells[e as usize].kind.faces()[f as usize]);
                if !opposite(side(faces[i]).corners(), side(faces[i + 1]).corners()) {
                    let es = [faces[i].1 as usize, faces[i + 1].1 as usize];
                    return Err(FlemError::mesh(
                        &src,
                        format!("{} overlap: they lie on the same side of their common face through {}", self.cells_name(&es, ""), self.points_name(&corners(faces[i]))),
                    ));
                }
            }
            i = j;
        }
        // Duplicate points (used ones only; tolerance relative to the mesh size).
        let mut used = vec![false; np];
        for c in &self.cells {
            for &n in c.corners() {
                used[n as usize] = true;
            }
        }
        let mut order: Vec<usize> = (0..np).filter(|&i| used[i]).collect();
        let pts = &self.points;
        order.sort_by(|&a, &b| pts[a][0].total_cmp(&pts[b][0]).then(pts[a][1].total_cmp(&pts[b][1])).then(pts[a][2].total_cmp(&pts[b][2])));
        let tol = 1e-10 * diam;
        for i in 0..order.len() {
            let a = order[i];
            for &b in &order[i + 1..] {
                if pts[b][0] - pts[a][0] > tol {
                    break;
                }
                if (pts[b][1] - pts[a][1]).abs() <= tol && (pts[b][2] - pts[a][2]).abs() <= tol {
                    return Err(FlemError::mesh(
                        &src,
                        format!(
                            "duplicate points: {} and {} are both at ({}, {}, {}): merge them or declare the faces between them separated",
                            self.point_name(a.min(b)),
                            self.point_name(a.max(b)),
                            pts[a][0],
                            pts[a][1],
                            pts[a][2]
                        ),
                    ));
                }
            }
        }
        if let Some(i) = (0..np).find(|&i| !used[i]) {
            let n = used.iter().filter(|u| !**u).count();
            return Err(FlemError::mesh(&src, format!("{} is not used by any element ({n} unreferenced points in all); remove them from the mesh", self.point_name(i))));
        }
        // Groups must refer to existing points, face sets to faces of cells.
        for (name, set) in &self.node_sets {
            if let Some(&n) = set.iter().find(|&&n| n as usize >= np) {
                return Err(FlemError::mesh(&src, format!("node set \"{name}\" refers to point {n}, but there are only {np} points")));
            }
        }
        let keys: std::collections::BTreeSet<[u32; 4]> = faces.iter().map(|f| f.0).collect();
        for (name, set) in &self.face_sets {
            for f in set {
                if let Some(&n) = f.corners().iter().find(|&&n| n as usize >= np) {
                    return Err(FlemError::mesh(&src, format!("face set \"{name}\" refers to point {n}, but there are only {np} points")));
                }
                if !keys.contains(&f.key()) {
                    return Err(FlemError::mesh(&src, format!("face set \"{name}\" holds a face that is not a face of any element: {}", self.points_name(f.corners()))));
                }
            }
        }
        Ok(warnings)
    }

    /// Adds a node set for every face set that has no node set of the same name (its faces'
    /// corners; the 3D twin of [`RawMesh::derive_node_sets`](super::RawMesh::derive_node_sets)).
    pub fn derive_node_sets(&mut self) {
        for (name, set) in &self.face_sets {
            if !self.node_sets.contains_key(name) {
                let mut v: Vec<u32> = set.iter().flat_map(|f| f.corners().to_vec()).collect();
                v.sort_unstable();
                v.dedup();
                self.node_sets.insert(name.clone(), v);
            }
        }
    }
}

/// For each corner of an H8, its three edge neighbours in right-hand order: the corner's
/// Jacobian `(x_a - x_i) . ((x_b - x_i) x (x_c - x_i))` is positive at every corner of a
/// well-shaped brick in VTK/gmsh order (tested on the unit cube).
const H8_CORNER_EDGES: [[usize; 3]; 8] = [[1, 3, 4], [2, 0, 5], [3, 1, 6], [0, 2, 7], [7, 5, 0], [4, 6, 1], [5, 7, 2], [6, 4, 3]];

const T4_EDGES: [[usize; 2]; 6] = [[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]];
const H8_EDGES: [[usize; 2]; 12] = [[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4], [0, 4], [1, 5], [2, 6], [3, 7]];

/// The local edges of a cell (corner pairs).
pub fn cell_edges(kind: CellKind3) -> &'static [[usize; 2]] {
    match kind {
        CellKind3::T4 => &T4_EDGES,
        CellKind3::H8 => &H8_EDGES,
    }
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// The face `local` (a row of [`CellKind3::faces`]) of cell `c` by its points, anticlockwise
/// seen from outside the cell.
pub fn cell_face(c: &RawCell3, local: &[u32; 4]) -> RawFace {
    RawFace(local.map(|l| if l == NO_CORNER { NO_CORNER } else { c.nodes[l as usize] }))
}

/// Whether `b` runs through the corners of `a` the other way round (the same face seen from
/// its other side).
fn opposite(a: &[u32], b: &[u32]) -> bool {
    let n = a.len();
    n == b.len() && (0..n).any(|s| (0..n).all(|k| a[k] == b[(s + n - k) % n]))
}

/// Six times the signed volume of the tetrahedron `a, b, c, d` (positive when `a, b, c` turn
/// anticlockwise seen from `d`).
pub fn tet_volume6(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> f64 {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
    u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) + u[2] * (v[0] * w[1] - v[1] * w[0])
}

/// The integration of a load over a flat or bilinear face with corners `x` (3 or 4, anticlockwise
/// seen from outside): `at(weights, area)` at each integration point, `weights[a]` the shape
/// function of corner `a` there and `area` the outward area vector the point stands for (a
/// triangle: one point, weights 1/3, area `(x1 - x0) x (x2 - x0) / 2`; a quadrilateral: 2 x 2
/// Gauss points on its bilinear map, area `dx/ds x dx/dt`). A uniform pressure `p` gives the
/// consistent corner forces `-p sum weights[a] area`. Shared by the 3D march's face loads and
/// the 3D implicit solve's.
pub fn face_integration(x: &[[f64; 3]], mut at: impl FnMut(&[f64], [f64; 3])) {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross = |a: [f64; 3], b: [f64; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    if x.len() == 3 {
        at(&[1.0 / 3.0; 3], cross(sub(x[1], x[0]), sub(x[2], x[0])).map(|v| 0.5 * v));
        return;
    }
    const G: f64 = 0.577_350_269_189_625_8;
    const S: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    for &(s, t) in &[(-G, -G), (G, -G), (G, G), (-G, G)] {
        let n: [f64; 4] = std::array::from_fn(|a| 0.25 * (1.0 + S[a][0] * s) * (1.0 + S[a][1] * t));
        let (mut xs, mut xt) = ([0.0; 3], [0.0; 3]);
        for a in 0..4 {
            for d in 0..3 {
                xs[d] += 0.25 * S[a][0] * (1.0 + S[a][1] * t) * x[a][d];
                xt[d] += 0.25 * S[a][1] * (1.0 + S[a][0] * s) * x[a][d];
            }
        }
        at(&n, cross(xs, xt));
    }
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

#[cfg(test)]
mod validate_tests {
    use super::*;

    const CUBE: [[f64; 3]; 8] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0]];

    fn h8(nodes: [u32; 8]) -> RawCell3 {
        RawCell3 { kind: CellKind3::H8, nodes }
    }

    fn t4(n: [u32; 4]) -> RawCell3 {
        RawCell3 { kind: CellKind3::T4, nodes: [n[0], n[1], n[2], n[3], 0, 0, 0, 0] }
    }

    fn mesh(points: &[[f64; 3]], cells: Vec<RawCell3>) -> RawMesh3 {
        RawMesh3 { source: "m.msh".into(), points: points.to_vec(), cells, ..Default::default() }
    }

    fn err(mut m: RawMesh3, opt: ValidationOptions) -> String {
        m.validate(opt).unwrap_err().to_string()
    }

    /// Reference: the unit cube in VTK order has the corner Jacobian +1 at every corner
    /// (H8_CORNER_EDGES), the mirrored cube -1.
    #[test]
    fn corner_jacobians_of_the_unit_cube() {
        for (i, &[a, b, c]) in H8_CORNER_EDGES.iter().enumerate() {
            assert_eq!(tet_volume6(CUBE[i], CUBE[a], CUBE[b], CUBE[c]), 1.0, "corner {i}");
        }
    }

    /// Inverted cells are reoriented (T4: corners 1 and 2 swapped; H8: bottom and top swapped)
    /// with a warning naming the file and the element, or refused by name; the reoriented
    /// cells have positive volume. Reference: the signed volumes of the unit cells.
    #[test]
    fn inverted_cells_are_reoriented_or_refused() {
        let mut m = mesh(&CUBE, vec![h8([4, 5, 6, 7, 0, 1, 2, 3])]);
        assert!(err(m.clone(), ValidationOptions::Refuse).contains("m.msh: element 0 (0-based, in file order) is inverted (negative volume; points [4, 5, 6, 7, 0, 1, 2, 3]"));
        let w = m.validate(ValidationOptions::Reorient).unwrap();
        assert_eq!(w, ["m.msh: element 0 (0-based, in file order) was inverted (negative volume) and has been reoriented"]);
        assert_eq!(m.cells[0].nodes, [0, 1, 2, 3, 4, 5, 6, 7]);
        let p = [CUBE[0], CUBE[1], CUBE[3], CUBE[4]];
        let mut m = mesh(&p, vec![t4([0, 2, 1, 3])]);
        m.ids = Some(FileIds { point_word: "node tag", cell_word: "element tag", zero_based: false, points: vec![10, 11, 12, 13], cells: vec![77] });
        assert!(err(m.clone(), ValidationOptions::Refuse).contains("m.msh: element tag 77 is inverted (negative volume; points [node tags 10, 12, 11, 13])"));
        m.validate(ValidationOptions::Reorient).unwrap();
        let c = m.cells[0].nodes;
        assert!(tet_volume6(p[c[0] as usize], p[c[1] as usize], p[c[2] as usize], p[c[3] as usize]) > 0.0);
    }

    /// Each refusal names the file and what is wrong. Reference: the contract of `validate`.
    #[test]
    fn refusals_are_named() {
        let r = ValidationOptions::Reorient;
        assert!(err(mesh(&CUBE, vec![]), r).contains("m.msh: the mesh has no 3D elements"));
        let mut p = CUBE;
        p[6][2] = f64::NAN;
        assert!(err(mesh(&p, vec![h8([0, 1, 2, 3, 4, 5, 6, 7])]), r).contains("point 6 (0-based, in file order) has a non-finite coordinate"));
        let mut p = CUBE;
        p[6][0] = 1e120;
        assert!(err(mesh(&p, vec![h8([0, 1, 2, 3, 4, 5, 6, 7])]), r).contains("must stay below 1e100"));
        // A flat tetrahedron, a flat brick.
        let flat = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
        assert!(err(mesh(&flat, vec![t4([0, 1, 2, 3])]), r).contains("element 0 (0-based, in file order) has zero volume (points [0, 1, 2, 3]"));
        let mut p = CUBE;
        for q in &mut p[4..] {
            q[2] = 0.0;
        }
        assert!(err(mesh(&p, vec![h8([0, 1, 2, 3, 4, 5, 6, 7])]), r).contains("has zero volume"));
        // A twisted brick: top face numbered the other way round.
        assert!(err(mesh(&CUBE, vec![h8([0, 1, 2, 3, 4, 7, 6, 5])]), r).contains("is not a valid hexahedron"));
        assert!(err(mesh(&CUBE, vec![h8([0, 1, 2, 3, 4, 5, 6, 6])]), r).contains("uses point 6 (0-based, in file order) twice"));
        assert!(err(mesh(&CUBE, vec![h8([0, 1, 2, 3, 4, 5, 6, 9])]), r).contains("refers to point index 9, but there are only 8 points"));
        // Three tetrahedra on one face (two of them on the same side), two overlapping.
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [0.2, 0.2, 1.0]];
        let e = err(mesh(&p, vec![t4([0, 1, 2, 3]), t4([0, 2, 1, 4]), t4([0, 1, 2, 5])]), r);
        assert!(e.contains("the face through points [0, 1, 2] (0-based, in file order) is shared by more than two elements: elements 0, 1, 2"), "{e}");
        assert!(err(mesh(&p[..], vec![t4([0, 1, 2, 3]), t4([0, 1, 2, 5]), t4([0, 2, 1, 4])]), r).contains("more than two"));
        let q = [p[0], p[1], p[2], p[3], p[5]];
        assert!(err(mesh(&q, vec![t4([0, 1, 2, 3]), t4([0, 1, 2, 4])]), r)
            .contains("elements 0, 1 (0-based, in file order) overlap: they lie on the same side of their common face through points [0, 1, 2]"));
        // Duplicate and unreferenced points.
        let mut p = CUBE.to_vec();
        p.push(CUBE[6]);
        assert!(err(mesh(&p, vec![h8([0, 1, 2, 3, 4, 5, 8, 7])]), r).contains("point 6 (0-based, in file order) is not used by any element"));
        p.push([2.0, 0.0, 0.0]);
        let two = mesh(&p, vec![h8([0, 1, 2, 3, 4, 5, 6, 7]), t4([1, 2, 8, 9])]);
        assert!(err(two, r).contains("duplicate points: point 6 (0-based, in file order) and point 8 (0-based, in file order) are both at (1, 1, 1)"));
        // Face sets: a face of the cell (either orientation, any first corner) is accepted;
        // a face across the brick is not.
        let mut m = mesh(&CUBE, vec![h8([0, 1, 2, 3, 4, 5, 6, 7])]);
        m.face_sets.insert("bottom".into(), vec![RawFace([1, 2, 3, 0]), RawFace([0, 1, 2, 3])]);
        m.clone().validate(r).unwrap();
        m.face_sets.insert("diag".into(), vec![RawFace([0, 2, 6, 4])]);
        assert!(err(m.clone(), r).contains("face set \"diag\" holds a face that is not a face of any element: points [0, 2, 6, 4]"));
        m.face_sets.remove("diag");
        m.face_sets.insert("tri".into(), vec![RawFace([0, 1, 2, NO_CORNER])]);
        assert!(err(m.clone(), r).contains("face set \"tri\" holds a face that is not a face of any element: points [0, 1, 2]"));
        m.face_sets.remove("tri");
        m.node_sets.insert("far".into(), vec![3, 12]);
        assert!(err(m, r).contains("node set \"far\" refers to point 12, but there are only 8 points"));
    }
}
