//! The 3D kinds as blocks of the explicit march (`flem_core::element::model3::Block3`,
//! registered by name: `t4`, `h8`, `h8_full`): one monomorphised element loop per kind, the
//! per-element geometry computed once (`t4::geometry`, `h8::geometry`), no allocation and no
//! dynamic dispatch inside the loop. The loop is serial and sums in element order, so results
//! do not depend on the thread count (a threaded 3D loop is a later step: docs/3d.md).
use flem_core::element::model3::{corner_clusters, Block3, BlockInput3, Kind3Registration};
use flem_core::element::shape3::{internal_force3, lumped_mass3, Dmat3, Hex8, Tet4};
use flem_core::ids::ElemId;
use flem_core::mesh::topology3::Topology3;
use flem_core::mesh::CellKind3;

use super::{corner_stresses, h8, stiffness, t4, Kind3};

/// What the element loop of one kind needs.
trait Kernel3: Send + Sync + 'static {
    const N: usize;
    const KIND: Kind3;
    type Geo: Send + Sync + std::fmt::Debug;
    /// What the element keeps between steps (computed once from its corners and material).
    fn geometry(x: &[[f64; 3]; 8], d: &Dmat3) -> Self::Geo;
    fn forces(geo: &Self::Geo, x: &[[f64; 3]; 8], u: &[[f64; 3]; 8], d: &Dmat3, f: &mut [[f64; 3]; 8]);
    fn masses(x: &[[f64; 3]; 8], rho: f64, m: &mut [f64]);
}

fn first<const N: usize>(a: &[[f64; 3]; 8]) -> [[f64; 3]; N] {
    std::array::from_fn(|i| a[i])
}

struct T4K;
impl Kernel3 for T4K {
    const N: usize = 4;
    const KIND: Kind3 = Kind3::T4;
    type Geo = t4::T4Geo;
    fn geometry(x: &[[f64; 3]; 8], _d: &Dmat3) -> t4::T4Geo {
        t4::geometry(&first::<4>(x))
    }
    #[inline(always)]
    fn forces(geo: &t4::T4Geo, _x: &[[f64; 3]; 8], u: &[[f64; 3]; 8], d: &Dmat3, f: &mut [[f64; 3]; 8]) {
        f[..4].copy_from_slice(&t4::forces(geo, &first::<4>(u), d));
    }
    fn masses(x: &[[f64; 3]; 8], rho: f64, m: &mut [f64]) {
        m[..4].copy_from_slice(&lumped_mass3::<Tet4, 4>(&first::<4>(x), rho));
    }
}

struct H8K;
impl Kernel3 for H8K {
    const N: usize = 8;
    const KIND: Kind3 = Kind3::H8;
    /// The condensed element stiffness, packed (`h8::packed_k`, 300 f64): the forces are
    /// `K u` (linear elasticity), five times faster than the modes' forces from the stored
    /// geometry (e38's timing, session 15), as `qm6` does in 2D.
    type Geo = Box<[f64; 300]>;
    fn geometry(x: &[[f64; 3]; 8], d: &Dmat3) -> Box<[f64; 300]> {
        Box::new(h8::packed_k(x, d))
    }
    #[inline(always)]
    fn forces(k: &Box<[f64; 300]>, _x: &[[f64; 3]; 8], u: &[[f64; 3]; 8], _d: &Dmat3, f: &mut [[f64; 3]; 8]) {
        *f = h8::forces_packed(k, u);
    }
    fn masses(x: &[[f64; 3]; 8], rho: f64, m: &mut [f64]) {
        m[..8].copy_from_slice(&lumped_mass3::<Hex8, 8>(x, rho));
    }
}

struct H8FullK;
impl Kernel3 for H8FullK {
    const N: usize = 8;
    const KIND: Kind3 = Kind3::H8Full;
    type Geo = ();
    fn geometry(_x: &[[f64; 3]; 8], _d: &Dmat3) {}
    #[inline(always)]
    fn forces(_geo: &(), x: &[[f64; 3]; 8], u: &[[f64; 3]; 8], d: &Dmat3, f: &mut [[f64; 3]; 8]) {
        *f = internal_force3::<Hex8, 8>(x, u, d);
    }
    fn masses(x: &[[f64; 3]; 8], rho: f64, m: &mut [f64]) {
        m[..8].copy_from_slice(&lumped_mass3::<Hex8, 8>(x, rho));
    }
}

/// A block of one 3D kind.
struct Block<K: Kernel3> {
    elems: Vec<ElemId>,
    x: Vec<[[f64; 3]; 8]>,
    geo: Vec<K::Geo>,
    conn: Vec<[u32; 8]>,
    d: Dmat3,
    rho: f64,
}

impl<K: Kernel3> std::fmt::Debug for Block<K> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Block3({}, {} elements)", K::KIND.name(), self.elems.len())
    }
}

fn build<K: Kernel3>(inp: &BlockInput3) -> Box<dyn Block3> {
    let d = Dmat3::new(inp.young, inp.poisson);
    Box::new(Block::<K> { elems: inp.elems.to_vec(), x: inp.x.to_vec(), geo: inp.x.iter().map(|x| K::geometry(x, &d)).collect(), conn: inp.conn.to_vec(), d, rho: inp.density })
}

impl<K: Kernel3> Block3 for Block<K> {
    fn kind(&self) -> &'static str {
        K::KIND.name()
    }
    fn elems(&self) -> &[ElemId] {
        &self.elems
    }
    fn add_internal_forces(&self, u: &[[f64; 3]], f: &mut [[f64; 3]]) {
        let mut ue = [[0.0; 3]; 8];
        let mut fe = [[0.0; 3]; 8];
        for k in 0..self.elems.len() {
            let c = &self.conn[k];
            for a in 0..K::N {
                ue[a] = u[c[a] as usize];
            }
            K::forces(&self.geo[k], &self.x[k], &ue, &self.d, &mut fe);
            for a in 0..K::N {
                let t = &mut f[c[a] as usize];
                t[0] += fe[a][0];
                t[1] += fe[a][1];
                t[2] += fe[a][2];
            }
        }
    }
    fn corner_stresses(&self, u: &[[f64; 3]], first_copy: &[u32], out: &mut [[f64; 6]]) {
        let mut ue = [[0.0; 3]; 8];
        for (k, e) in self.elems.iter().enumerate() {
            let c = &self.conn[k];
            for a in 0..K::N {
                ue[a] = u[c[a] as usize];
            }
            let o = first_copy[e.idx()] as usize;
            corner_stresses(K::KIND, &self.x[k][..K::N], &ue[..K::N], &self.d, &mut out[o..o + K::N]);
        }
    }
    fn corner_masses(&self, first_copy: &[u32], out: &mut [f64]) {
        for (k, e) in self.elems.iter().enumerate() {
            let o = first_copy[e.idx()] as usize;
            K::masses(&self.x[k], self.rho, &mut out[o..o + K::N]);
        }
    }
    fn add_row_sums(&self, rows: &mut [f64]) {
        let n = 3 * K::N;
        let mut ke = vec![0.0; n * n];
        for k in 0..self.elems.len() {
            stiffness(K::KIND, &self.x[k][..K::N], &self.d, &mut ke);
            for a in 0..K::N {
                let r = (0..3).map(|i| ke[(3 * a + i) * n..(3 * a + i + 1) * n].iter().map(|v| v.abs()).sum::<f64>()).fold(0.0, f64::max);
                rows[self.conn[k][a] as usize] += r;
            }
        }
    }
    fn reconnect(&mut self, topo: &Topology3) {
        for (k, &e) in self.elems.iter().enumerate() {
            self.conn[k] = corner_clusters(topo, e);
        }
    }
}

inventory::submit! { Kind3Registration { name: "t4", cell: CellKind3::T4, default: true, build: build::<T4K> } }
inventory::submit! { Kind3Registration { name: "h8", cell: CellKind3::H8, default: true, build: build::<H8K> } }
inventory::submit! { Kind3Registration { name: "h8_full", cell: CellKind3::H8, default: false, build: build::<H8FullK> } }
