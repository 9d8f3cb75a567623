//! Mesh importers: `[mesh] type = "gmsh"` (msh 2.2 and 4.1, ASCII and binary) and
//! `[mesh] type = "vtk"` (`.vtu` XML and legacy `.vtk`).
//!
//! What: each importer turns a file into a [`RawMesh`] (points, first-order T3/Q4 cells, a
//! region name per cell, named node and edge sets); [`RawMesh::validate`] checks it afterwards.
//! Why here: reading files is plugin work; core only knows the [`MeshSource`] trait.
//! How: a format reader gathers candidate points (in a deterministic order), cells and groups
//! ([`Gathered`]); [`Gathered::finish`] keeps only the points used by 2D cells, renumbers them
//! densely in that order, remaps the sets (dropping points that are not in the mesh) and refuses
//! meshes that are not planar. gmsh files with volume elements are read as 3D meshes by
//! `gmsh3.rs`, VTK files with volume cells by `vtk3.rs` (through `MeshSource::load_any`).
//!
//! Corrupt input never panics: every count and index is checked, errors name the file and,
//! where possible, the line or element. Third-party parsers (mshio, vtkio) are called inside
//! `catch_unwind` as a last line of defence.
//!
//! ```toml
//! [mesh]
//! type = "gmsh"
//! file = "meshes/plate_hole_v41.msh"   # relative to the scene file
//! ```
//!
//! [`MeshSource`]: flem_core::mesh::MeshSource
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use flem_core::mesh::{FileIds, RawCell, RawMesh};
use flem_core::{FlemError, Result};

mod cursor;
mod gmsh;
mod gmsh3;
mod msh2;
mod msh4;
mod vtk;
mod vtk3;
mod vtk_locate;

#[cfg(test)]
mod tests;

pub use gmsh::{read_msh_any, read_msh_bytes, Gmsh};
pub use vtk::{read_vtk_bytes, Vtk};
pub use vtk3::read_vtk_any;

/// Resolves `file` against `base_dir` and reads it whole. A file that cannot be read is the
/// scene's error, key `mesh.file` (the file "mesh (file)" is replaced by the scene's name where
/// the scene is known, as for generated meshes); the message names the full path.
pub(crate) fn read_input(base_dir: &Path, file: &str) -> Result<(String, PathBuf, Vec<u8>)> {
    let path = base_dir.join(file);
    let shown = path.display().to_string();
    match std::fs::read(&path) {
        Ok(b) => Ok((shown, path, b)),
        Err(e) => Err(FlemError::config("mesh (file)", "mesh.file", format!("= \"{file}\": cannot read the mesh file {shown}: {e}"))),
    }
}

/// Runs a third-party parser, turning a panic inside it into an error message.
pub(crate) fn no_panic<T>(what: &str, f: impl FnOnce() -> T) -> std::result::Result<T, String> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).map_err(|p| {
        let msg = p.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| p.downcast_ref::<String>().cloned()).unwrap_or_else(|| "unknown panic".into());
        format!("{what} failed on this (corrupt?) file: {msg}")
    })
}

/// What a reader collects before the points are compacted.
///
/// Point indices in `cells` and the sets refer to `points`; `labels` gives each point's name
/// in the file (gmsh node tag, VTK point index) and `cell_labels` each cell's (gmsh element
/// tag, VTK cell index), kept in the mesh ([`FileIds`]) for error messages; `words` says what
/// they are called (point, cell) and `zero_based` whether they count from 0.
#[derive(Default, Debug)]
pub(crate) struct Gathered {
    pub points: Vec<[f64; 3]>,
    pub labels: Vec<u64>,
    pub words: (&'static str, &'static str),
    pub zero_based: bool,
    pub cells: Vec<RawCell>,
    pub cell_labels: Vec<u64>,
    pub cell_region: Vec<String>,
    pub node_sets: BTreeMap<String, Vec<u32>>,
    pub edge_sets: BTreeMap<String, Vec<[u32; 2]>>,
}

impl Gathered {
    /// Keeps the points used by cells (in their order), remaps cells and sets, checks planarity.
    pub fn finish(self, src: &str) -> Result<RawMesh> {
        if self.cells.is_empty() {
            return Err(FlemError::mesh(src, "the file has no triangles or quadrilaterals (first-order 2D cells)"));
        }
        let n = self.points.len();
        let based = if self.zero_based { " (0-based, as in the file)" } else { "" };
        let mut new_id = vec![u32::MAX; n];
        for c in &self.cells {
            for &p in c.corners() {
                let p = p as usize;
                if p >= n {
                    return Err(FlemError::mesh(src, format!("a cell refers to point index {p}, but there are only {n} points")));
                }
                new_id[p] = 0;
            }
        }
        let mut points = Vec::new();
        let mut point_ids = Vec::new();
        let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
        for (i, id) in new_id.iter_mut().enumerate() {
            if *id == 0 {
                let p = self.points[i];
                if !p.iter().all(|v| v.is_finite()) {
                    return Err(FlemError::mesh(src, format!("{} {}{based} has a non-finite coordinate {p:?}", self.words.0, self.labels[i])));
                }
                *id = points.len() as u32;
                points.push([p[0], p[1]]);
                point_ids.push(self.labels[i]);
                for d in 0..2 {
                    lo[d] = lo[d].min(p[d]);
                    hi[d] = hi[d].max(p[d]);
                }
            }
        }
        let size = ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2)).sqrt();
        for (i, &id) in new_id.iter().enumerate() {
            let z = self.points[i][2];
            if id != u32::MAX && z.abs() > 1e-9 * size {
                return Err(FlemError::mesh(
                    src,
                    format!("not a 2D mesh: {} {}{based} has z = {z} (the mesh is {size:.6e} across); FLEM reads planar meshes in the plane z = 0", self.words.0, self.labels[i]),
                ));
            }
        }
        let map = |p: u32| new_id.get(p as usize).copied().filter(|&q| q != u32::MAX);
        let cells = self
            .cells
            .iter()
            .map(|c| {
                let mut nodes = [0u32; 4];
                for (k, &p) in c.corners().iter().enumerate() {
                    nodes[k] = new_id[p as usize];
                }
                RawCell { kind: c.kind, nodes }
            })
            .collect();
        let node_sets = self
            .node_sets
            .into_iter()
            .map(|(name, set)| {
                let mut v: Vec<u32> = set.into_iter().filter_map(map).collect();
                v.sort_unstable();
                v.dedup();
                (name, v)
            })
            .collect();
        let edge_sets = self
            .edge_sets
            .into_iter()
            .map(|(name, set)| {
                let v = set.into_iter().filter_map(|[a, b]| Some([map(a)?, map(b)?])).collect();
                (name, v)
            })
            .collect();
        let ids = (self.cell_labels.len() == self.cells.len()).then(|| FileIds {
            point_word: self.words.0,
            cell_word: self.words.1,
            zero_based: self.zero_based,
            points: point_ids,
            cells: self.cell_labels,
        });
        Ok(RawMesh { source: src.to_string(), points, cells, cell_region: self.cell_region, node_sets, edge_sets, ids })
    }
}
