//! `[mesh] type = "box"`: the built-in structured 3D mesh (issue 38), a box of `nx` x `ny` x
//! `nz` bricks (H8) or of tetrahedra (T4, six per brick), so that a 3D scene needs no mesh file.
//!
//! Groups: face sets and node sets `xmin`, `xmax`, `ymin`, `ymax`, `zmin`, `zmax` (the six
//! sides; faces with their corners anticlockwise seen from outside), the node set `all`, the
//! region `all`. T4 cells split every brick into six tetrahedra around its diagonal from the
//! corner nearest `origin` to the opposite one (Kuhn's split): every brick is split the same
//! way, so that the split faces of neighbours match (a conforming mesh; the five-tetrahedron
//! split needs alternating bricks and is not used). `distort` moves interior points by up to
//! `distort` x the cell size along each axis (deterministic; for patch tests on distorted
//! meshes; below 0.15 so that no cell inverts).
//!
//! The 2D `load` refuses a box by name; a 3D scene reads it through `load_any`.
//!
//! ```toml
//! [mesh]
//! type = "box"
//! origin = [0.0, 0.0, 0.0]   # m (default)
//! size = [2.0, 1.0, 0.5]     # m, along x, y, z
//! nx = 8
//! ny = 4
//! nz = 2
//! element = "h8"             # "h8" (bricks, default) or "t4" (six tetrahedra per brick)
//! ```
use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::raw3::{cell_face, tet_volume6, AnyMesh, CellKind3, RawCell3, RawFace, RawMesh3};
use super::{MeshSource, RawMesh, MAX_COORD};
use crate::error::{FlemError, Result};

const SRC: &str = "mesh (box)";

/// `[mesh] element` of the box: a 3D cell type, with an error that names the key.
fn de_element3<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<CellKind3, D::Error> {
    let s = String::deserialize(d)?;
    match s.as_str() {
        "h8" => Ok(CellKind3::H8),
        "t4" => Ok(CellKind3::T4),
        _ => Err(serde::de::Error::custom(format!("mesh.element = \"{s}\" is not a 3D cell type of the box: give \"h8\" (bricks) or \"t4\" (six tetrahedra per brick)"))),
    }
}

fn default_h8() -> CellKind3 {
    CellKind3::H8
}

/// `[mesh] type = "box"`: `nx` x `ny` x `nz` cells on `origin + [0, size]` (see the module doc).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Box3 {
    #[serde(default)]
    pub origin: [f64; 3],
    pub size: [f64; 3],
    pub nx: usize,
    pub ny: usize,
    pub nz: usize,
    #[serde(default = "default_h8", deserialize_with = "de_element3")]
    pub element: CellKind3,
    #[serde(default)]
    pub distort: f64,
}

/// Most cells a box may have (memory: a 1e8-cell mesh is some 10 GB of model).
pub const MAX_BOX_CELLS: usize = 100_000_000;

/// Corner `(bx, by, bz)` of the unit brick -> its H8 local index (VTK/gmsh order).
const H8_OF_BITS: [[[usize; 2]; 2]; 2] = [[[0, 4], [3, 7]], [[1, 5], [2, 6]]];

/// The six tetrahedra of Kuhn's split of a brick, as H8 local corners, each positively
/// oriented on the unit cube: for every order (a, b, c) of the axes, the path 000 -> e_a ->
/// e_a + e_b -> 111.
fn kuhn_tets() -> [[usize; 4]; 6] {
    let unit = |l: usize| -> [f64; 3] {
        let mut out = [0.0; 3];
        for (bx, plane) in H8_OF_BITS.iter().enumerate() {
            for (by, row) in plane.iter().enumerate() {
                for (bz, &k) in row.iter().enumerate() {
                    if k == l {
                        out = [bx as f64, by as f64, bz as f64];
                    }
                }
            }
        }
        out
    };
    let mut tets = [[0usize; 4]; 6];
    for (t, [a, b]) in [[0, 1], [0, 2], [1, 0], [1, 2], [2, 0], [2, 1]].into_iter().enumerate() {
        let mut bits = [0usize; 3];
        let mut path = [H8_OF_BITS[0][0][0], 0, 0, H8_OF_BITS[1][1][1]];
        bits[a] = 1;
        path[1] = H8_OF_BITS[bits[0]][bits[1]][bits[2]];
        bits[b] = 1;
        path[2] = H8_OF_BITS[bits[0]][bits[1]][bits[2]];
        if tet_volume6(unit(path[0]), unit(path[1]), unit(path[2]), unit(path[3])) < 0.0 {
            path.swap(1, 2);
        }
        tets[t] = path;
    }
    tets
}

impl Box3 {
    pub fn new(size: [f64; 3], n: [usize; 3], element: CellKind3) -> Self {
        Box3 { origin: [0.0; 3], size, nx: n[0], ny: n[1], nz: n[2], element, distort: 0.0 }
    }

    pub fn build(&self) -> Result<RawMesh3> {
        let bad = |key: &str, msg: String| FlemError::config(SRC, format!("mesh.{key}"), msg);
        for d in 0..3 {
            let s = self.size[d];
            if !(s > 0.0 && s <= MAX_COORD) {
                return Err(bad(&format!("size[{d}]"), format!("= {s} is incorrect; it must be in (0, {MAX_COORD:e}]")));
            }
            let o = self.origin[d];
            if !(o.abs() <= MAX_COORD) {
                return Err(bad(&format!("origin[{d}]"), format!("= {o} is incorrect; it must be in [-{MAX_COORD:e}, {MAX_COORD:e}]")));
            }
        }
        let n = [self.nx, self.ny, self.nz];
        for (d, key) in ["nx", "ny", "nz"].into_iter().enumerate() {
            if n[d] == 0 || n[d] > 4096 {
                return Err(bad(key, format!("= {} is incorrect; it must be in [1, 4096]", n[d])));
            }
        }
        let per = if self.element == CellKind3::T4 { 6 } else { 1 };
        let n_cells = n[0] * n[1] * n[2] * per;
        if n_cells > MAX_BOX_CELLS {
            return Err(bad("nx", format!("nx * ny * nz = {} gives {n_cells} cells; at most {MAX_BOX_CELLS} are allowed", n[0] * n[1] * n[2])));
        }
        if !(0.0..0.15).contains(&self.distort) {
            return Err(bad("distort", format!("= {} is incorrect; it must be in [0, 0.15)", self.distort)));
        }
        let h: [f64; 3] = std::array::from_fn(|d| self.size[d] / n[d] as f64);
        let (px, py) = (n[0] + 1, n[1] + 1);
        let id = |i: usize, j: usize, k: usize| (i + px * (j + py * k)) as u32;
        let mut points = Vec::with_capacity(px * py * (n[2] + 1));
        let mut seed: u64 = 0x2545_F491_4F6C_DD1D;
        for k in 0..=n[2] {
            for j in 0..=n[1] {
                for i in 0..=n[0] {
                    let g = [i, j, k];
                    // The last line is placed at origin + size exactly.
                    let mut x: [f64; 3] = std::array::from_fn(|d| if g[d] == n[d] { self.origin[d] + self.size[d] } else { self.origin[d] + g[d] as f64 * h[d] });
                    if self.distort > 0.0 && (0..3).all(|d| g[d] > 0 && g[d] < n[d]) {
                        for d in 0..3 {
                            seed ^= seed << 13;
                            seed ^= seed >> 7;
                            seed ^= seed << 17;
                            let r = (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
                            x[d] += r * self.distort * h[d];
                        }
                    }
                    points.push(x);
                }
            }
        }
        let tets = kuhn_tets();
        let mut cells = Vec::with_capacity(n_cells);
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    let b = [id(i, j, k), id(i + 1, j, k), id(i + 1, j + 1, k), id(i, j + 1, k), id(i, j, k + 1), id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)];
                    match self.element {
                        CellKind3::H8 => cells.push(RawCell3 { kind: CellKind3::H8, nodes: b }),
                        CellKind3::T4 => {
                            for t in &tets {
                                cells.push(RawCell3 { kind: CellKind3::T4, nodes: [b[t[0]], b[t[1]], b[t[2]], b[t[3]], 0, 0, 0, 0] });
                            }
                        }
                    }
                }
            }
        }
        // The sides: (name, axis, grid index of the plane).
        let sides = [("xmin", 0, 0), ("xmax", 0, n[0]), ("ymin", 1, 0), ("ymax", 1, n[1]), ("zmin", 2, 0), ("zmax", 2, n[2])];
        let grid = |p: u32| -> [usize; 3] {
            let p = p as usize;
            [p % px, (p / px) % py, p / (px * py)]
        };
        let mut face_sets: BTreeMap<String, Vec<RawFace>> = sides.iter().map(|s| (s.0.to_string(), Vec::new())).collect();
        let mut node_sets: BTreeMap<String, Vec<u32>> = BTreeMap::new();
        for c in &cells {
            for lf in c.kind.faces() {
                let f = cell_face(c, lf);
                for &(name, axis, at) in &sides {
                    if f.corners().iter().all(|&p| grid(p)[axis] == at) {
                        face_sets.get_mut(name).expect("every side has a set").push(f);
                    }
                }
            }
        }
        for &(name, axis, at) in &sides {
            node_sets.insert(name.to_string(), (0..points.len() as u32).filter(|&p| grid(p)[axis] == at).collect());
        }
        node_sets.insert("all".into(), (0..points.len() as u32).collect());
        let m = cells.len();
        Ok(RawMesh3 { source: SRC.into(), points, cells, cell_region: vec!["all".into(); m], node_sets, face_sets, ids: None })
    }
}

#[typetag::serde(name = "box")]
impl MeshSource for Box3 {
    fn load(&self, _base: &std::path::Path) -> Result<RawMesh> {
        Err(FlemError::config(SRC, "mesh.type", "= \"box\" is a 3D mesh (tetrahedra or bricks): a 2D scene cannot use it; use \"rectangle\" for a 2D scene, or a 3D scene (docs/3d.md)"))
    }

    fn load_any(&self, _base: &std::path::Path) -> Result<AnyMesh> {
        Ok(AnyMesh::Three(self.build()?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::ValidationOptions;

    fn volume(m: &RawMesh3) -> f64 {
        let x = |p: u32| m.points[p as usize];
        m.cells
            .iter()
            .map(|c| match c.kind {
                CellKind3::T4 => tet_volume6(x(c.nodes[0]), x(c.nodes[1]), x(c.nodes[2]), x(c.nodes[3])) / 6.0,
                // The brick as Kuhn's six tetrahedra (exact for the bricks of the box).
                CellKind3::H8 => kuhn_tets().iter().map(|t| tet_volume6(x(c.nodes[t[0]]), x(c.nodes[t[1]]), x(c.nodes[t[2]]), x(c.nodes[t[3]])) / 6.0).sum(),
            })
            .sum()
    }

    /// Reference: the box's dimensions. Both kinds validate with `Refuse` (no inverted cell,
    /// no face shared by more than two cells, matching faces between bricks, face sets made of
    /// cell faces), fill the box's volume (to 1e-12 relative, undistorted and distorted), have
    /// the counts of a structured grid, and their side sets cover each side's area once.
    #[test]
    fn both_kinds_fill_the_box_and_validate() {
        for element in [CellKind3::H8, CellKind3::T4] {
            for distort in [0.0, 0.14] {
                let mut b = Box3::new([2.0, 1.0, 0.5], [4, 3, 2], element);
                b.origin = [-1.0, 0.5, 3.0];
                b.distort = distort;
                let mut m = b.build().unwrap();
                let w = m.validate(ValidationOptions::Refuse).unwrap();
                assert!(w.is_empty());
                let per = if element == CellKind3::T4 { 6 } else { 1 };
                assert_eq!((m.points.len(), m.cells.len()), (5 * 4 * 3, 24 * per));
                assert!((volume(&m) - 1.0).abs() < 1e-12, "{element:?} {distort}: {}", volume(&m));
                let area = |f: &RawFace| -> f64 {
                    let p: Vec<[f64; 3]> = f.corners().iter().map(|&i| m.points[i as usize]).collect();
                    let tri = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| {
                        let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
                        let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
                        0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
                    };
                    tri(p[0], p[1], p[2]) + if p.len() == 4 { tri(p[0], p[2], p[3]) } else { 0.0 }
                };
                for (name, want, nodes) in [("xmin", 0.5, 12), ("xmax", 0.5, 12), ("ymin", 1.0, 15), ("ymax", 1.0, 15), ("zmin", 2.0, 20), ("zmax", 2.0, 20)] {
                    let a: f64 = m.face_sets[name].iter().map(area).sum();
                    assert!((a - want).abs() < 1e-12, "{element:?} {name}: {a}");
                    assert_eq!(m.node_sets[name].len(), nodes, "{name}");
                }
                // Outward: the xmax faces' normals point along +x (anticlockwise seen from outside).
                for f in &m.face_sets["xmax"] {
                    let p: Vec<[f64; 3]> = f.corners().iter().map(|&i| m.points[i as usize]).collect();
                    let outside = [p[0][0] + 1.0, p[0][1], p[0][2]];
                    assert!(tet_volume6(p[0], p[1], p[2], outside) > 0.0);
                }
            }
        }
    }

    /// The 2D `load` refuses the box by name; `load_any` gives the 3D mesh. Bad keys are
    /// named. Reference: the messages' contract.
    #[test]
    fn box_is_3d_and_bad_keys_are_named() {
        let s: Box<dyn MeshSource> = toml::from_str("type = \"box\"\nsize = [1.0, 1.0, 1.0]\nnx = 1\nny = 1\nnz = 1\nelement = \"t4\"").unwrap();
        let e = s.load(std::path::Path::new(".")).unwrap_err().to_string();
        assert!(e.contains("mesh.type") && e.contains("\"box\" is a 3D mesh"), "{e}");
        match s.load_any(std::path::Path::new(".")).unwrap() {
            AnyMesh::Three(m) => assert_eq!(m.cells.len(), 6),
            AnyMesh::Two(_) => panic!("a box is 3D"),
        }
        let e = toml::from_str::<Box<dyn MeshSource>>("type = \"box\"\nsize = [1.0, 1.0, 1.0]\nnx = 1\nny = 1\nnz = 1\nelement = \"q4\"").unwrap_err().to_string();
        assert!(e.contains("mesh.element = \"q4\" is not a 3D cell type"), "{e}");
        let mut b = Box3::new([1.0, -1.0, 1.0], [1, 1, 1], CellKind3::H8);
        assert!(b.build().unwrap_err().to_string().contains("mesh.size[1]"));
        b.size[1] = 1.0;
        b.nz = 0;
        assert!(b.build().unwrap_err().to_string().contains("mesh.nz"));
        b.nz = 1;
        b.distort = 0.2;
        assert!(b.build().unwrap_err().to_string().contains("mesh.distort"));
    }

    /// The ```toml snippet of this module's doc parses and builds (the docs cannot drift).
    #[test]
    fn doc_snippet_builds() {
        let src = include_str!("box3.rs");
        let mut block = String::new();
        let mut inside = false;
        for l in src.lines() {
            let Some(d) = l.strip_prefix("//!") else { continue };
            let d = d.strip_prefix(' ').unwrap_or(d);
            match (inside, d.trim()) {
                (false, "```toml") => inside = true,
                (true, "```") => break,
                (true, _) => {
                    block.push_str(d);
                    block.push('\n');
                }
                _ => {}
            }
        }
        let t: toml::Table = toml::from_str(&block).unwrap();
        let s: Box<dyn MeshSource> = t["mesh"].clone().try_into().unwrap();
        let AnyMesh::Three(mut m) = s.load_any(std::path::Path::new(".")).unwrap() else { panic!("3D") };
        assert_eq!(m.cells.len(), 64);
        m.validate(ValidationOptions::Refuse).unwrap();
    }
}
