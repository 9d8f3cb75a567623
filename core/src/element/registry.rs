//! The registry of element kinds: `[[material]] element = "name"` picks one per region.
//!
//! An element kind is a type implementing [`Blocked`] (the element trait, `element/kernel.rs`)
//! and one registration line,
//! `inventory::submit! { ElementKind::new::<MyElem, 4>("summary") }`, in the crate that defines
//! it. Core defines no kind: the built-ins `q4`, `t3` (the paper's elements), `qm6` and `q4_closed` are in
//! `flem-plugins/src/elements/` (docs/elements.md). The registration carries the monomorphised
//! constructors of the kind's blocks (the linear block, the co-rotational one, the stateful block
//! with the linear elastic law) and its per-element geometry (Gauss points, lumped mass), so
//! core builds blocks of a kind it cannot name and the element loop stays generic per block (no
//! dispatch per element). A name registers only if the final binary links its crate
//! (`flem_plugins::link()`), as with typetag.
//!
//! Default by cell type: a region's quadrilaterals use `q4` and its triangles `t3`
//! (`element::default_kind`) unless its material names an element of that cell type; an element
//! name applies to the cells of its own type only (`element = "qm6"` on a mixed mesh leaves the
//! triangles `t3`).
use crate::element::block::{Block, ElementBlock};
use crate::element::corot::CorotBlock;
use crate::element::kernel::Blocked;
use crate::element::law::{LinearElastic, MaterialLaw, RegionElems, StatefulOpts};
use crate::element::stateful::StatefulBlock;
use crate::element::{self, Material, Shape};
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

/// Builds the stateful block of one element kind and law from a region's elements.
pub type StatefulCtor<L> = fn(L, &str, Material, StatefulOpts, &RegionElems) -> Option<Box<dyn Block>>;

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
    /// The kind's stateful block with the linear elastic law (`[solver] large_strain`, or
    /// `law = { type = "linear_elastic" }`); `None` when the kind has none.
    pub stateful_elastic: Option<StatefulCtor<LinearElastic>>,
    gauss: fn(&[[f64; 2]], &mut Vec<([f64; 2], f64)>),
    mass: fn(&[[f64; 2]], f64, f64, &mut [f64]),
}

fn build<S: Blocked<N>, const N: usize>(region: String, mat: Material) -> Box<dyn BlockBuilder> {
    Box::new(ElementBlock::<S, N>::new(region, mat))
}

/// The stateful block (`element::stateful::StatefulBlock<S, L, N>`) of the plain isoparametric
/// element of shape `S` and law `L` over the region's cells of `S::KIND` (`None` if it has none).
/// A kind's registration monomorphises it for the linear elastic law; a law plugin calls it
/// for its own law.
pub fn stateful_block<S: Shape<N>, L: MaterialLaw, const N: usize>(law: L, region: &str, mat: Material, opts: StatefulOpts, elems: &RegionElems) -> Option<Box<dyn Block>> {
    let mut b = StatefulBlock::<S, L, N>::new(region.to_string(), mat, law, opts);
    let mut any = false;
    elems.for_cell(S::KIND, |e, x, c| {
        b.push(e, std::array::from_fn(|a| x[a]), std::array::from_fn(|a| c[a]));
        any = true;
    });
    any.then(|| Box::new(b) as Box<dyn Block>)
}

fn gauss<S: Shape<N>, const N: usize>(x: &[[f64; 2]], out: &mut Vec<([f64; 2], f64)>) {
    let xa: [[f64; 2]; N] = std::array::from_fn(|a| x[a]);
    for &(xi, w) in S::GAUSS {
        let n = S::n(xi);
        let (_, det) = element::gradients::<S, N>(&xa, xi);
        let mut p = [0.0; 2];
        for a in 0..N {
            p[0] += n[a] * xa[a][0];
            p[1] += n[a] * xa[a][1];
        }
        out.push((p, w * det));
    }
}

fn mass<S: Shape<N>, const N: usize>(x: &[[f64; 2]], rho: f64, t: f64, out: &mut [f64]) {
    let m = element::lumped_mass::<S, N>(&std::array::from_fn(|a| x[a]), rho, t);
    out[..N].copy_from_slice(&m);
}

impl ElementKind {
    /// The registration of element type `S` with `N` corners. An isoparametric kind
    /// (`RECOVERY_LEN == 0`) gets the plain isoparametric stateful block; a kind with internal
    /// fields gives its own with [`ElementKind::with_stateful_elastic`] or has none.
    pub const fn new<S: Blocked<N>, const N: usize>(summary: &'static str) -> ElementKind {
        let stateful_elastic: Option<StatefulCtor<LinearElastic>> = if S::RECOVERY_LEN == 0 { Some(stateful_block::<S, LinearElastic, N>) } else { None };
        ElementKind { name: S::NAME, cell: S::KIND, summary, bytes_per_elem: S::BYTES_PER_ELEM, builder: build::<S, N>, stateful_elastic, gauss: gauss::<S, N>, mass: mass::<S, N> }
    }
    /// The kind's own stateful block with the linear elastic law.
    pub const fn with_stateful_elastic(mut self, f: StatefulCtor<LinearElastic>) -> ElementKind {
        self.stateful_elastic = Some(f);
        self
    }
    /// An empty block of this kind for `region`.
    pub fn builder(&self, region: String, mat: Material) -> Box<dyn BlockBuilder> {
        (self.builder)(region, mat)
    }
    /// Appends the Gauss points of an element with corners `x`: (position, weight x det J).
    pub fn gauss_points(&self, x: &[[f64; 2]], out: &mut Vec<([f64; 2], f64)>) {
        (self.gauss)(x, out)
    }
    /// Row-sum lumped mass of each corner of an element with corners `x` into `out[..N]`.
    pub fn lumped_mass(&self, x: &[[f64; 2]], rho: f64, t: f64, out: &mut [f64]) {
        (self.mass)(x, rho, t, out)
    }
}

inventory::collect!(ElementKind);

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

/// The default element kind of a cell type (`element::default_kind`), if linked.
pub fn default_for(cell: CellKind) -> Option<&'static ElementKind> {
    find(element::default_kind(cell))
}
