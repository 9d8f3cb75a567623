//! The blocks of a 3D model (issue 38, docs/3d.md): one element kind and one material each,
//! connectivity by cluster index, as 2D's `Block` (`element::block`).
//!
//! Core names no 3D kind: a kind is a type implementing [`Block3`] in flem-plugins
//! (`elements3d`) and one registration line, `inventory::submit! { Kind3Registration { .. } }`;
//! core builds the blocks of a region by name ([`build_block3`]). A block's element loop is
//! generic per kind (one dynamic call per block and step, none per element); it may run on a
//! thread pool (`Block3::add_internal_forces_pool`) and gives the same bits on any number of
//! threads (plugins/src/elements3d/block.rs: chunks coloured so that no two of a colour share a
//! cluster).
use crate::error::{FlemError, Result};
use crate::ids::ElemId;
use crate::mesh::topology3::Topology3;
use crate::mesh::{CellKind3, RawMesh3};

/// A block of 3D elements of one kind and material.
pub trait Block3: Send + Sync + std::fmt::Debug {
    /// The kind's name (`t4`, `h8`, ...).
    fn kind(&self) -> &'static str;
    /// The block's elements, in the order of its arrays.
    fn elems(&self) -> &[ElemId];
    /// `f[c] += F_int` of every element from the displacements `u` (both indexed by cluster).
    fn add_internal_forces(&self, u: &[[f64; 3]], f: &mut [[f64; 3]]);
    /// As `add_internal_forces`, on the threads of `pool` (`None`: this thread). The forces
    /// are the same bits whatever the pool (a kind that cannot share its loop runs it on this
    /// thread).
    fn add_internal_forces_pool(&self, u: &[[f64; 3]], f: &mut [[f64; 3]], pool: Option<&rayon::ThreadPool>) {
        let _ = pool;
        self.add_internal_forces(u, f)
    }
    /// Bytes the force pass streams (the kernel's per-element data and connectivity).
    fn kernel_bytes(&self) -> usize {
        0
    }
    /// Colours of the threaded pass (the barriers of a step; 1 for a serial loop).
    fn colours(&self) -> usize {
        1
    }
    /// The stress (tension positive, `[sxx, syy, szz, sxy, syz, szx]`) of every element at
    /// each corner (the paper's nodal stress: natural coordinates scaled by 0.9999; a
    /// tetrahedron's constant stress), written to `out[first_copy[e] + a]`.
    fn corner_stresses(&self, u: &[[f64; 3]], first_copy: &[u32], out: &mut [[f64; 6]]);
    /// The lumped mass of every element's corners, written to `out[first_copy[e] + a]`.
    fn corner_masses(&self, first_copy: &[u32], out: &mut [f64]);
    /// `rows[c] += sum_j |K_e(i, j)|` over the dofs `i` of cluster `c` (the largest of its
    /// three rows): a Gershgorin bound of the stiffness for the stable step.
    fn add_row_sums(&self, rows: &mut [f64]);
    /// Re-reads the corner clusters of every element after a split.
    fn reconnect(&mut self, topo: &Topology3);
}

/// The input of a 3D block: its elements with their reference corners and corner clusters
/// (only the first `cell.nodes()` entries of each are used).
pub struct BlockInput3<'a> {
    /// Young's modulus, Poisson's ratio, density (the region's `[[material]]`).
    pub young: f64,
    pub poisson: f64,
    pub density: f64,
    pub elems: &'a [ElemId],
    pub x: &'a [[[f64; 3]; 8]],
    pub conn: &'a [[u32; 8]],
}

/// One registered 3D element kind.
pub struct Kind3Registration {
    /// Name in `[[material]] element = "..."`.
    pub name: &'static str,
    /// The cell type it is built on.
    pub cell: CellKind3,
    /// Whether it is the default kind of its cell type.
    pub default: bool,
    pub build: fn(&BlockInput3) -> Box<dyn Block3>,
}

inventory::collect!(Kind3Registration);

/// The registered 3D kinds, sorted by name.
pub fn kinds3() -> Vec<&'static Kind3Registration> {
    let mut v: Vec<&'static Kind3Registration> = inventory::iter::<Kind3Registration>.into_iter().collect();
    v.sort_by_key(|k| k.name);
    v
}

/// The blocks of a 3D mesh: the cells of each region, split by cell type, each on the kind
/// `material_of(region)` names (`None`, or a kind of another cell type: the cell type's default
/// kind) with the region's `[young, poisson, density]`. Blocks in order of region (first appearance), then cell type (T4, H8).
pub fn build_blocks3(mesh: &RawMesh3, topo: &Topology3, material_of: &dyn Fn(&str) -> Result<([f64; 3], Option<String>)>) -> Result<Vec<Box<dyn Block3>>> {
    let mut regions: Vec<&str> = Vec::new();
    let region = |e: usize| if mesh.cell_region.is_empty() { "all" } else { mesh.cell_region[e].as_str() };
    for e in 0..mesh.cells.len() {
        if !regions.contains(&region(e)) {
            regions.push(region(e));
        }
    }
    let mut blocks = Vec::new();
    for r in regions {
        let ([young, poisson, density], element) = material_of(r)?;
        for cell in [CellKind3::T4, CellKind3::H8] {
            let elems: Vec<ElemId> = (0..mesh.cells.len()).filter(|&e| region(e) == r && mesh.cells[e].kind == cell).map(ElemId::new).collect();
            if elems.is_empty() {
                continue;
            }
            let kinds = kinds3();
            let kind = match element.as_deref() {
                Some(name) => kinds.iter().find(|k| k.name == name && k.cell == cell).or_else(|| kinds.iter().find(|k| k.default && k.cell == cell)),
                None => kinds.iter().find(|k| k.default && k.cell == cell),
            };
            let Some(kind) = kind else {
                let names: Vec<&str> = kinds.iter().map(|k| k.name).collect();
                return Err(FlemError::mesh(&mesh.source, format!("region \"{r}\": no 3D element kind for {cell:?} cells is linked into this program (registered: {names:?})")));
            };
            let x: Vec<[[f64; 3]; 8]> = elems.iter().map(|e| std::array::from_fn(|a| if a < cell.nodes() { mesh.points[mesh.cells[e.idx()].nodes[a] as usize] } else { [0.0; 3] })).collect();
            let conn: Vec<[u32; 8]> = elems.iter().map(|&e| corner_clusters(topo, e)).collect();
            blocks.push((kind.build)(&BlockInput3 { young, poisson, density, elems: &elems, x: &x, conn: &conn }));
        }
    }
    Ok(blocks)
}

/// The clusters of element `e`'s corners (unused entries 0).
pub fn corner_clusters(topo: &Topology3, e: ElemId) -> [u32; 8] {
    let r = topo.elem_copies(e);
    let mut c = [0u32; 8];
    for (a, k) in r.enumerate() {
        c[a] = topo.copy_cluster[k].0;
    }
    c
}
