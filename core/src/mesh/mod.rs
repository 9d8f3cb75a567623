//! Meshes as they come in: points, cells and named groups, before any topology is built.
//!
//! Importers (gmsh, VTK) and the built-in rectangle generator all produce a [`RawMesh`];
//! [`RawMesh::validate`] checks it and reorients clockwise cells before a model is built.
//!
//! # What a raw mesh holds, and what validation refuses
//! Points, cells, named node and edge sets, and regions. `validate()` reorients clockwise cells
//! and refuses zero-area cells, duplicate points, unreferenced points and edges shared by more
//! than two elements; coordinates are bounded by `MAX_COORD` (1e100), so that an overflow is
//! refused by name instead of surfacing as a divergence. Sources implement [`MeshSource`]
//! (typetag, `[mesh] type = "..."`): `rectangle` and `rectangles` here (`rect.rs`, `rects.rs`),
//! `gmsh` and `vtk` in `plugins/src/import/`. The topology of copies and clusters is built
//! from a validated mesh in `topology.rs`.
//!
//! 3D meshes (issue 38, docs/3d.md) are types of their own beside these: `RawMesh3`
//! (`raw3.rs`, with its `validate`), the `box` generator (`box3.rs`), given by
//! `MeshSource::load_any`.
//!
//! # File ids in messages
//! Importers keep the file's ids (`RawMesh::ids`, `FileIds`: gmsh node and element tags, VTK
//! point and cell indices counting skipped cells), so messages name `"element tag 57"`,
//! `"points [node tags 3, 4, 9]"`, `"VTK cell 12 (0-based, as in the file)"`; without them
//! (generated or handmade meshes) `"element 12 (0-based, in file order)"`. The same names serve
//! edge sets that are not element edges, loads on interior edges and the check solver's
//! unsupported fragments (`FileIds::points`, `FileIds::cells`). vtkio's parse errors carry no
//! position: on that failure path only, `plugins/src/import/vtk_locate.rs` scans the file for
//! the line and the data array, section and piece (a cut file, a bad tag, a non-number, a
//! wrong count).
mod box3;
mod raw;
mod raw3;
mod rect;
mod rects;
mod select;
pub mod topology;
pub mod topology3;

pub use box3::Box3;
pub use raw::{CellKind, FileIds, RawCell, RawMesh, ValidationOptions, MAX_COORD};
pub use raw3::{cell_edges, cell_face, face_integration, tet_volume6, AnyMesh, CellKind3, RawCell3, RawFace, RawMesh3, NO_CORNER};
pub use rect::{Notch, Rectangle};
pub use rects::{Part, Rectangles};
pub use select::SetCfg;

use crate::error::Result;

/// Where a scene's mesh comes from: `[mesh] type = "rectangle" | "gmsh" | "vtk" | ...`.
///
/// Implementations live in plugins (file importers) and in core (the generator).
/// `base_dir` is the folder of the scene file (relative mesh paths resolve against it).
#[typetag::serde(tag = "type")]
pub trait MeshSource: std::fmt::Debug + Send + Sync {
    fn load(&self, base_dir: &std::path::Path) -> Result<RawMesh>;

    /// The mesh in its own dimension (issue 38): a 3D source (a gmsh file with volumes, the
    /// `box` generator) gives [`AnyMesh::Three`]; the default is the 2D mesh of [`Self::load`].
    fn load_any(&self, base_dir: &std::path::Path) -> Result<AnyMesh> {
        Ok(AnyMesh::Two(self.load(base_dir)?))
    }
}
