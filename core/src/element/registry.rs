//! The registry of element kinds: `[[material]] element = "name"` picks one per region.
//!
//! An element kind is a type implementing [`Blocked`] (the element trait, `element/kernel.rs`)
//! and one registration line,
//! `inventory::submit! { ElementKind::new::<MyElem, 4>("summary") }`, in the crate that defines
//! it (built-ins: `q4` and `t3` here in core, `qm6` in `flem-plugins`; docs/elements.md). The
//! registration carries a monomorphised constructor of its block, so the element loop stays
//! generic per block (no dispatch per element). A name registers only if the final binary links
//! its crate (`flem_plugins::link()`), as with typetag.
//!
//! Default by cell type: a region's quadrilaterals use `q4` and its triangles `t3` unless its
//! material names an element of that cell type; an element name applies to the cells of its
//! own type only (`element = "qm6"` on a mixed mesh leaves the triangles `t3`).
use crate::element::block::{Block, ElementBlock};
use crate::element::corot::CorotBlock;
use crate::element::kernel::Blocked;
use crate::element::{Material, Q4, T3};
use crate::ids::ElemId;
use crate::mesh::CellKind;

/// Collects the elements of one block while the model is built.
pub trait BlockBuilder {
    /// Adds an element: its global id, reference corner coordinates and clusters (`N` each).
    fn push(&mut self, e: ElemId, x: &[[f64; 2]], conn: &[u32]);
    fn is_empty(&self) -> bool;
    /// The finished block (linear, or co-rotational: `element::corot`).
    fn finish(self: Box<Self>, corotational: bool) -> Box<dyn Block>;
}

impl<S: Blocked<N>, const N: usize> BlockBuilder for ElementBlock<S, N> {
    fn push(&mut self, e: ElemId, x: &[[f64; 2]], conn: &[u32]) {
        ElementBlock::push(self, e, std::array::from_fn(|a| x[a]), std::array::from_fn(|a| conn[a]))
    }
    fn is_empty(&self) -> bool {
        self.elems.is_empty()
    }
    fn finish(self: Box<Self>, corotational: bool) -> Box<dyn Block> {
        if corotational {
            Box::new(CorotBlock(*self))
        } else {
            self
        }
    }
}

/// One registered element kind.
pub struct ElementKind {
    /// Name in `[[material]] element = "..."` (`Blocked::NAME`).
    pub name: &'static str,
    /// The mesh cell type it is built on.
    pub cell: CellKind,
    /// One line for `flem plugins`.
    pub summary: &'static str,
    /// Bytes of blocked kernel data per element (`Blocked::BYTES_PER_ELEM`).
    pub bytes_per_elem: usize,
    builder: fn(String, Material) -> Box<dyn BlockBuilder>,
}

fn build<S: Blocked<N>, const N: usize>(region: String, mat: Material) -> Box<dyn BlockBuilder> {
    Box::new(ElementBlock::<S, N>::new(region, mat))
}

impl ElementKind {
    /// The registration of element type `S` with `N` corners.
    pub const fn new<S: Blocked<N>, const N: usize>(summary: &'static str) -> ElementKind {
        ElementKind { name: S::NAME, cell: S::KIND, summary, bytes_per_elem: S::BYTES_PER_ELEM, builder: build::<S, N> }
    }
    /// An empty block of this kind for `region`.
    pub fn builder(&self, region: String, mat: Material) -> Box<dyn BlockBuilder> {
        (self.builder)(region, mat)
    }
}

inventory::collect!(ElementKind);

inventory::submit! { ElementKind::new::<Q4, 4>("bilinear quadrilateral, 2 x 2 Gauss points (the paper's element; locks in bending)") }
inventory::submit! { ElementKind::new::<T3, 3>("constant-strain triangle") }

/// Every linked element kind, sorted by name.
pub fn kinds() -> Vec<&'static ElementKind> {
    let mut v: Vec<&'static ElementKind> = inventory::iter::<ElementKind>.into_iter().collect();
    v.sort_by_key(|k| k.name);
    v
}

/// The element kind named `name`, if linked.
pub fn find(name: &str) -> Option<&'static ElementKind> {
    inventory::iter::<ElementKind>.into_iter().find(|k| k.name == name)
}

/// The default element of a cell type.
pub fn default_for(cell: CellKind) -> &'static str {
    match cell {
        CellKind::Q4 => Q4::NAME,
        CellKind::T3 => T3::NAME,
    }
}
