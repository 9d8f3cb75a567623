//! Meshes as they come in: points, cells and named groups, before any topology is built.
//!
//! Importers (gmsh, VTK) and the built-in rectangle generator all produce a [`RawMesh`];
//! [`RawMesh::validate`] checks it and reorients clockwise cells before a model is built.
mod raw;
mod rect;
mod rects;
pub mod topology;

pub use raw::{CellKind, FileIds, RawCell, RawMesh, ValidationOptions, MAX_COORD};
pub use rect::{Notch, Rectangle};
pub use rects::{Part, Rectangles};

use crate::error::Result;

/// Where a scene's mesh comes from: `[mesh] type = "rectangle" | "gmsh" | "vtk" | ...`.
///
/// Implementations live in plugins (file importers) and in core (the generator).
/// `base_dir` is the folder of the scene file (relative mesh paths resolve against it).
#[typetag::serde(tag = "type")]
pub trait MeshSource: std::fmt::Debug + Send + Sync {
    fn load(&self, base_dir: &std::path::Path) -> Result<RawMesh>;
}
