//! `rectangles`: several separate rectangles in one mesh (blocks on a base, stacks,
//! collisions): each part is a [`Rectangle`] whose points are its own (parts never share a
//! point even where they touch), so the parts are separate bodies that meet through contact.
//! Parts must not have coincident points (the mesh validation refuses duplicates, which in an
//! imported mesh are a meshing error): leave a small gap (1e-7 of the size is enough) where
//! parts rest on each other; gravity or the loads close it.
//!
//! Groups of part `p`: node and edge sets `p_left`, `p_right`, `p_bottom`, `p_top`, node sets
//! `p_bottom_left`, ..., `p_all`, and the element region `p` (so `[[material]] region = "p"`
//! can differ per part); node set `all` holds every point.
//!
//! ```toml
//! [mesh]
//! type = "rectangles"
//! parts = [
//!   { name = "base", origin = [0.0, 0.0], width = 4.0, height = 0.5, nx = 16, ny = 2 },
//!   { name = "block", origin = [1.0, 0.5000001], width = 1.0, height = 1.0, nx = 4, ny = 4 },
//! ]
//! ```
//!
//! One body cut in parts instead: `[mesh] type = "rectangle"` has `cuts = [y, ...]`
//! (`rect.rs`): interior grid lines whose edges form the edge set `cut` (declare it in
//! `model.separated`), a pre-cut specimen.
use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::{CellKind, MeshSource, RawMesh, Rectangle};
use crate::error::{FlemError, Result};

/// One part of a [`Rectangles`] mesh.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Part {
    pub name: String,
    #[serde(default)]
    pub origin: [f64; 2],
    pub width: f64,
    pub height: f64,
    pub nx: usize,
    pub ny: usize,
    #[serde(default = "q4", deserialize_with = "crate::mesh::raw::de_mesh_element")]
    pub element: CellKind,
}

fn q4() -> CellKind {
    CellKind::Q4
}

/// `[mesh] type = "rectangles"` (see the module docs).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rectangles {
    pub parts: Vec<Part>,
}

const SRC: &str = "mesh (rectangles)";

impl Rectangles {
    pub fn build(&self) -> Result<RawMesh> {
        if self.parts.is_empty() {
            return Err(FlemError::config(SRC, "mesh.parts", "is empty; give at least one part"));
        }
        let mut out = RawMesh { source: SRC.into(), points: Vec::new(), cells: Vec::new(), cell_region: Vec::new(), node_sets: BTreeMap::new(), edge_sets: BTreeMap::new(), ids: None };
        for (k, p) in self.parts.iter().enumerate() {
            if p.name.is_empty() || p.name == "all" || self.parts[..k].iter().any(|q| q.name == p.name) {
                return Err(FlemError::config(SRC, format!("mesh.parts[{k}].name"), format!("= \"{}\" is incorrect; part names must be non-empty, unique and not \"all\"", p.name)));
            }
            let r = Rectangle {
                width: p.width,
                height: p.height,
                nx: p.nx,
                ny: p.ny,
                element: p.element,
                origin: p.origin,
                notch: None,
                distort: 0.0,
                cuts: Vec::new(),
                grading_x: Vec::new(),
                grading_y: Vec::new(),
            };
            let m = r.build().map_err(|e| FlemError::config(SRC, format!("mesh.parts[{k}]"), format!("(\"{}\"): {e}", p.name)))?;
            let off = out.points.len() as u32;
            out.points.extend(m.points);
            for mut c in m.cells {
                for n in c.nodes.iter_mut().take(c.kind.nodes()) {
                    *n += off;
                }
                out.cells.push(c);
                out.cell_region.push(p.name.clone());
            }
            for (name, v) in m.node_sets {
                out.node_sets.insert(format!("{}_{name}", p.name), v.iter().map(|x| x + off).collect());
            }
            for (name, v) in m.edge_sets {
                out.edge_sets.insert(format!("{}_{name}", p.name), v.iter().map(|e| [e[0] + off, e[1] + off]).collect());
            }
        }
        out.node_sets.insert("all".into(), (0..out.points.len() as u32).collect());
        Ok(out)
    }
}

#[typetag::serde(name = "rectangles")]
impl MeshSource for Rectangles {
    fn load(&self, _base: &std::path::Path) -> Result<RawMesh> {
        self.build()
    }
}
