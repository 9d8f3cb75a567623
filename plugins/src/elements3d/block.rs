//! The 3D kinds as blocks of the explicit march (`flem_core::element::model3::Block3`,
//! registered by name: `t4`, `h8`, `h8_full`): one monomorphised element loop per kind, no
//! allocation and no dynamic dispatch inside it (one dynamic call per block and step).
//!
//! **Storage** (what the force pass streams per element, besides its `N` corner clusters as
//! `u32`): packs of [`LANES`] elements, structure of arrays inside a pack (as 2D's blocked
//! kernels, `flem_core::element::kernel`), so that one loop over the lanes computes the pack and
//! the compiler vectorises it.
//! - `t4`: 9 f64, the gradients of corners 0, 1, 2 scaled by `sqrt(V)` (`h_a = sqrt(V) g_a`;
//!   corner 3's is `-(h_0 + h_1 + h_2)`): `f_a = V B_a^T D B u = H_a^T D (sum_b H_b u_b)`. The
//!   strain is formed from `u_a - u_3`, and `f_3 = -(f_0 + f_1 + f_2)`, so the forces balance
//!   exactly. (`t4::T4Geo` holds 13 f64: 4 gradients and the volume.)
//! - `h8`: the condensed stiffness `K` (24 x 24, 9 incompatible modes condensed out,
//!   `h8::matrices`), its upper triangle row by row (300 f64); `f = K u` by the triangle (each
//!   stored value used twice).
//! - `h8_full`: the 24 corner coordinates (the trilinear brick's forces are computed from them
//!   each step, `shape3::internal_force3`).
//!
//! The corner coordinates are also kept (not streamed by the force pass) for the nodal stress,
//! the masses and the stable-step bound.
//!
//! **Threads, bit for bit** (ours; issue 38 must-show 3 and 6). Packs are grouped in chunks of
//! consecutive packs (about 32 chunks a block, at least `Kernel3::CHUNK_PACKS` packs each: a
//! size from the block alone, never from the thread count). The chunks are coloured once, greedily in chunk order, so that two chunks of one
//! colour share no cluster. A pass runs the colours one after the other; the chunks of a colour
//! run on the pool in any order, since none of them adds to a cluster that another adds to; a
//! chunk adds its elements in element order. So every cluster receives its contributions in
//! one order fixed by the mesh (colour, then chunk, then element), on one thread or many: the
//! forces are the same bits (tests/march3.rs, `flem bench step3`). One thread runs the same
//! colour order. A split only re-points corners at new clusters whose elements all shared the
//! parent cluster, so two chunks of one colour still share no cluster after `reconnect`: the
//! colouring is built once.
//! Why colours rather than 2D's dataflow of regions (`kernel::Schedule`): a 3D mesh in its
//! file's order touches far more chunks per cluster than a banded 2D one, and the colouring
//! needs no waits; the price is one barrier per colour and step (a handful of colours; `flem
//! bench step3` prints them). Why not per-chunk force buffers summed in a fixed order: that
//! writes and reads the element forces again (96 B per tetrahedron, more than its geometry).
//!
//! **Instruction sets**: the chunk loop is compiled for the baseline, AVX2 and AVX-512 (as
//! 2D's, `element::block::Simd`) and the widest the CPU runs is picked when the block is built;
//! Rust never contracts a multiply and an add, so each lane does the same IEEE operations
//! whichever runs.
use flem_core::element::block::Simd;
use flem_core::element::kernel::LANES;
use flem_core::element::model3::{corner_clusters, Block3, BlockInput3, Kind3Registration};
use flem_core::element::shape3::{internal_force3, lumped_mass3, Dmat3, Hex8, Tet4};
use flem_core::ids::ElemId;
use flem_core::mesh::topology3::Topology3;
use flem_core::mesh::CellKind3;

use super::{corner_stresses, h8, stiffness, t4, Kind3};

type Lanes = [f64; LANES];

/// What the element loop of one kind needs.
trait Kernel3<const N: usize>: Send + Sync + 'static {
    const KIND: Kind3;
    /// The fewest packs in a chunk of the threaded pass.
    const CHUNK_PACKS: usize;
    /// The force pass's data of `LANES` elements.
    type Pack: Copy + Send + Sync + 'static;
    /// The pack of up to `LANES` elements (missing lanes: zero).
    fn pack(x: &[[[f64; 3]; N]], d: &Dmat3) -> Self::Pack;
    /// Forces of the pack's first `live` lanes from gathered `u[a][dim][lane]`.
    fn forces(p: &Self::Pack, d: &Dmat3, live: usize, u: &[[Lanes; 3]; N], f: &mut [[Lanes; 3]; N]);
    fn masses(x: &[[f64; 3]; N], rho: f64) -> [f64; N];
    /// `max_i sum_j |K(3a + i, j)|` of every corner `a` (the stable-step bound).
    fn row_sums(_p: &Self::Pack, _lane: usize, x: &[[f64; 3]; N], d: &Dmat3) -> [f64; N] {
        let n = 3 * N;
        let mut ke = vec![0.0; n * n];
        stiffness(Self::KIND, x, d, &mut ke);
        std::array::from_fn(|a| (0..3).map(|i| ke[(3 * a + i) * n..(3 * a + i + 1) * n].iter().map(|v| v.abs()).sum::<f64>()).fold(0.0, f64::max))
    }
}

/// `t4`'s pack: `h[a][dim][lane] = sqrt(V) g_a` of corners 0, 1, 2.
#[derive(Copy, Clone, Debug)]
#[repr(C, align(64))]
struct T4Pack {
    h: [[Lanes; 3]; 3],
}

struct T4K;
impl Kernel3<4> for T4K {
    const KIND: Kind3 = Kind3::T4;
    const CHUNK_PACKS: usize = 32;
    type Pack = T4Pack;
    fn pack(x: &[[[f64; 3]; 4]], _d: &Dmat3) -> T4Pack {
        let mut p = T4Pack { h: [[[0.0; LANES]; 3]; 3] };
        for (l, x) in x.iter().enumerate().take(LANES) {
            let g = t4::geometry(x);
            // Cells are validated (positive volume) before a block is built.
            let s = g.vol.max(0.0).sqrt();
            for a in 0..3 {
                for d in 0..3 {
                    p.h[a][d][l] = s * g.g[a][d];
                }
            }
        }
        p
    }
    #[inline(always)]
    fn forces(p: &T4Pack, d: &Dmat3, _live: usize, u: &[[Lanes; 3]; 4], f: &mut [[Lanes; 3]; 4]) {
        let (lam, mu) = (d.lambda, d.mu);
        let m2 = 2.0 * mu;
        let h = &p.h;
        for l in 0..LANES {
            let du = |a: usize, i: usize| u[a][i][l] - u[3][i][l];
            // sqrt(V) x the strain: e_ij = sum_a h_a[j] (u_a - u_3)[i].
            let g = |i: usize, j: usize| h[0][j][l] * du(0, i) + h[1][j][l] * du(1, i) + h[2][j][l] * du(2, i);
            let (exx, eyy, ezz) = (g(0, 0), g(1, 1), g(2, 2));
            let gxy = g(0, 1) + g(1, 0);
            let gyz = g(1, 2) + g(2, 1);
            let gzx = g(2, 0) + g(0, 2);
            let tr = lam * (exx + eyy + ezz);
            let (sxx, syy, szz) = (tr + m2 * exx, tr + m2 * eyy, tr + m2 * ezz);
            let (sxy, syz, szx) = (mu * gxy, mu * gyz, mu * gzx);
            for a in 0..3 {
                let (hx, hy, hz) = (h[a][0][l], h[a][1][l], h[a][2][l]);
                f[a][0][l] = hx * sxx + hy * sxy + hz * szx;
                f[a][1][l] = hy * syy + hx * sxy + hz * syz;
                f[a][2][l] = hz * szz + hy * syz + hx * szx;
            }
            for i in 0..3 {
                f[3][i][l] = -(f[0][i][l] + f[1][i][l] + f[2][i][l]);
            }
        }
    }
    fn masses(x: &[[f64; 3]; 4], rho: f64) -> [f64; 4] {
        lumped_mass3::<Tet4, 4>(x, rho)
    }
}

/// Index of `K(i, j)`, `i <= j`, in the upper triangle stored row by row (row `i` starts at
/// `sum_{r < i} (24 - r) = 24 i - i (i - 1) / 2`).
const fn tri(i: usize, j: usize) -> usize {
    24 * i - i * i.saturating_sub(1) / 2 + (j - i)
}

/// `h8`'s pack: the condensed stiffness of 8 elements, upper triangle (`tri`), lane innermost.
#[derive(Copy, Clone, Debug)]
#[repr(C, align(64))]
struct H8Pack {
    k: [Lanes; 300],
}

struct H8K;
impl Kernel3<8> for H8K {
    const KIND: Kind3 = Kind3::H8;
    const CHUNK_PACKS: usize = 4;
    type Pack = H8Pack;
    fn pack(x: &[[[f64; 3]; 8]], d: &Dmat3) -> H8Pack {
        let mut p = H8Pack { k: [[0.0; LANES]; 300] };
        for (l, x) in x.iter().enumerate().take(LANES) {
            let (k, _) = h8::matrices(x, d);
            for i in 0..24 {
                for j in i..24 {
                    p.k[tri(i, j)][l] = k[i][j];
                }
            }
        }
        p
    }
    #[inline(always)]
    fn forces(p: &H8Pack, _d: &Dmat3, _live: usize, u: &[[Lanes; 3]; 8], f: &mut [[Lanes; 3]; 8]) {
        let mut uf = [[0.0; LANES]; 24];
        for (a, ua) in u.iter().enumerate() {
            for i in 0..3 {
                uf[3 * a + i] = ua[i];
            }
        }
        let mut ff = [[0.0; LANES]; 24];
        let mut rest: &[Lanes] = &p.k;
        for i in 0..24 {
            // Row i of the triangle: K(i, i..24).
            let (row, next) = rest.split_at(24 - i);
            rest = next;
            let ui = uf[i];
            let mut acc = [0.0; LANES];
            for l in 0..LANES {
                acc[l] = row[0][l] * ui[l];
            }
            let (lo, hi) = ff.split_at_mut(i + 1);
            for ((k, uj), fj) in row[1..].iter().zip(&uf[i + 1..]).zip(hi.iter_mut()) {
                for l in 0..LANES {
                    acc[l] += k[l] * uj[l];
                    fj[l] += k[l] * ui[l];
                }
            }
            for l in 0..LANES {
                lo[i][l] += acc[l];
            }
        }
        for (a, fa) in f.iter_mut().enumerate() {
            for i in 0..3 {
                fa[i] = ff[3 * a + i];
            }
        }
    }
    fn masses(x: &[[f64; 3]; 8], rho: f64) -> [f64; 8] {
        lumped_mass3::<Hex8, 8>(x, rho)
    }
    fn row_sums(p: &H8Pack, lane: usize, _x: &[[f64; 3]; 8], _d: &Dmat3) -> [f64; 8] {
        let k = |i: usize, j: usize| p.k[if i <= j { tri(i, j) } else { tri(j, i) }][lane].abs();
        std::array::from_fn(|a| (0..3).map(|i| (0..24).map(|j| k(3 * a + i, j)).sum::<f64>()).fold(0.0, f64::max))
    }
}

/// `h8_full`'s pack: the corner coordinates `x[a][dim][lane]`.
#[derive(Copy, Clone, Debug)]
#[repr(C, align(64))]
struct H8FullPack {
    x: [[Lanes; 3]; 8],
}

struct H8FullK;
impl Kernel3<8> for H8FullK {
    const KIND: Kind3 = Kind3::H8Full;
    const CHUNK_PACKS: usize = 8;
    type Pack = H8FullPack;
    fn pack(x: &[[[f64; 3]; 8]], _d: &Dmat3) -> H8FullPack {
        let mut p = H8FullPack { x: [[[0.0; LANES]; 3]; 8] };
        for (l, x) in x.iter().enumerate().take(LANES) {
            for a in 0..8 {
                for d in 0..3 {
                    p.x[a][d][l] = x[a][d];
                }
            }
        }
        p
    }
    #[inline(always)]
    fn forces(p: &H8FullPack, d: &Dmat3, live: usize, u: &[[Lanes; 3]; 8], f: &mut [[Lanes; 3]; 8]) {
        for l in 0..live {
            let x: [[f64; 3]; 8] = std::array::from_fn(|a| std::array::from_fn(|i| p.x[a][i][l]));
            let ue: [[f64; 3]; 8] = std::array::from_fn(|a| std::array::from_fn(|i| u[a][i][l]));
            let fe = internal_force3::<Hex8, 8>(&x, &ue, d);
            for a in 0..8 {
                for i in 0..3 {
                    f[a][i][l] = fe[a][i];
                }
            }
        }
    }
    fn masses(x: &[[f64; 3]; 8], rho: f64) -> [f64; 8] {
        lumped_mass3::<Hex8, 8>(x, rho)
    }
}

/// The force array shared by the chunks of one colour (they write disjoint clusters).
#[derive(Clone, Copy)]
struct Shared3 {
    ptr: *mut [f64; 3],
    len: usize,
}
// SAFETY: the chunks running at once write disjoint entries (the colouring, module doc).
unsafe impl Send for Shared3 {}
unsafe impl Sync for Shared3 {}

type ChunkFn<B> = fn(&B, usize, &[[f64; 3]], Shared3);

/// A block of one 3D kind.
struct Block<K: Kernel3<N>, const N: usize> {
    elems: Vec<ElemId>,
    x: Vec<[[f64; 3]; N]>,
    conn: Vec<[u32; N]>,
    packs: Vec<K::Pack>,
    /// Packs per chunk (`chunk_packs`).
    chunk_packs: usize,
    /// The chunks of each colour, ascending.
    colours: Vec<Vec<u32>>,
    /// The largest cluster any element touches.
    top: usize,
    d: Dmat3,
    rho: f64,
    run: ChunkFn<Self>,
}

impl<K: Kernel3<N>, const N: usize> std::fmt::Debug for Block<K, N> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Block3({}, {} elements, {} colours)", K::KIND.name(), self.elems.len(), self.colours.len())
    }
}

/// Greedy colouring of the chunks of `chunk` consecutive elements: two chunks of one colour
/// share no cluster. Chunks in ascending order each take the smallest colour that no earlier
/// chunk sharing a cluster with it has.
fn colour_chunks<const N: usize>(conn: &[[u32; N]], chunk: usize) -> Vec<Vec<u32>> {
    let n_chunks = conn.len().div_ceil(chunk);
    let nc = conn.iter().flatten().fold(0u32, |m, &c| m.max(c)) as usize + 1;
    // The chunks touching each cluster (CSR, each chunk once, ascending).
    let mut last = vec![u32::MAX; nc];
    let mut count = vec![0u32; nc + 1];
    for (e, c) in conn.iter().enumerate() {
        let ch = (e / chunk) as u32;
        for &c in c {
            if last[c as usize] != ch {
                last[c as usize] = ch;
                count[c as usize + 1] += 1;
            }
        }
    }
    for i in 0..nc {
        count[i + 1] += count[i];
    }
    let mut fill = count.clone();
    let mut touch = vec![0u32; count[nc] as usize];
    last.fill(u32::MAX);
    for (e, c) in conn.iter().enumerate() {
        let ch = (e / chunk) as u32;
        for &c in c {
            if last[c as usize] != ch {
                last[c as usize] = ch;
                touch[fill[c as usize] as usize] = ch;
                fill[c as usize] += 1;
            }
        }
    }
    let mut colour = vec![u32::MAX; n_chunks];
    let mut stamp = vec![u32::MAX; 0];
    let mut colours: Vec<Vec<u32>> = Vec::new();
    for ch in 0..n_chunks {
        for c in &conn[ch * chunk..((ch + 1) * chunk).min(conn.len())] {
            for &c in c {
                for &o in &touch[count[c as usize] as usize..count[c as usize + 1] as usize] {
                    let k = colour[o as usize];
                    if k != u32::MAX {
                        stamp[k as usize] = ch as u32;
                    }
                }
            }
        }
        let k = (0..stamp.len()).find(|&k| stamp[k] != ch as u32).unwrap_or(stamp.len());
        if k == stamp.len() {
            stamp.push(u32::MAX);
            colours.push(Vec::new());
        }
        colour[ch] = k as u32;
        colours[k].push(ch as u32);
    }
    colours
}

/// Chunks per block (about; fewer when a block is small): large chunks keep a colour's pass
/// local (a 1e6-tetrahedron box in the mesh's order then has 2 colours, its 256-element chunks
/// had 8, each colour sweeping the whole node range), and 16 chunks a colour keep 2 threads
/// balanced (session 16, docs/perf/s16/3d_step.md).
const CHUNKS: usize = 32;

/// Packs per chunk of a block of `n_packs` packs: at least `min`, and about [`CHUNKS`] chunks
/// (from the block's size only, never from the thread count).
fn chunk_packs(min: usize, n_packs: usize) -> usize {
    min.max(n_packs.div_ceil(CHUNKS))
}

fn build<K: Kernel3<N>, const N: usize>(inp: &BlockInput3) -> Box<dyn Block3> {
    let d = Dmat3::new(inp.young, inp.poisson);
    let x: Vec<[[f64; 3]; N]> = inp.x.iter().map(|x| std::array::from_fn(|a| x[a])).collect();
    let conn: Vec<[u32; N]> = inp.conn.iter().map(|c| std::array::from_fn(|a| c[a])).collect();
    let packs: Vec<K::Pack> = x.chunks(LANES).map(|x| K::pack(x, &d)).collect();
    let chunk_packs = chunk_packs(K::CHUNK_PACKS, packs.len());
    let colours = colour_chunks(&conn, chunk_packs * LANES);
    let top = conn.iter().flatten().fold(0u32, |m, &c| m.max(c)) as usize;
    let run = Block::<K, N>::chunk_fn(Simd::best());
    Box::new(Block::<K, N> { elems: inp.elems.to_vec(), x, conn, packs, chunk_packs, colours, top, d, rho: inp.density, run })
}

impl<K: Kernel3<N>, const N: usize> Block<K, N> {
    /// Forces of the elements of chunk `k`: gather a pack, compute, scatter in element order.
    #[inline(always)]
    fn chunk_body(&self, k: usize, u: &[[f64; 3]], f: Shared3) {
        let cp = self.chunk_packs;
        let (p0, p1) = (k * cp, ((k + 1) * cp).min(self.packs.len()));
        let mut ug = [[[0.0; LANES]; 3]; N];
        let mut fg = [[[0.0; LANES]; 3]; N];
        for p in p0..p1 {
            let e0 = p * LANES;
            let conn = &self.conn[e0..(e0 + LANES).min(self.conn.len())];
            for (l, c) in conn.iter().enumerate() {
                for a in 0..N {
                    // SAFETY: c[a] <= self.top < u.len() (asserted by the caller of the pass).
                    let ua = unsafe { *u.get_unchecked(c[a] as usize) };
                    ug[a][0][l] = ua[0];
                    ug[a][1][l] = ua[1];
                    ug[a][2][l] = ua[2];
                }
            }
            K::forces(&self.packs[p], &self.d, conn.len(), &ug, &mut fg);
            for (l, c) in conn.iter().enumerate() {
                for a in 0..N {
                    // SAFETY: in bounds (c[a] <= self.top < f.len(), asserted by the caller);
                    // no other thread writes this entry now: the chunks running at once are of
                    // one colour and share no cluster (module doc).
                    let t = unsafe { &mut *f.ptr.add(c[a] as usize) };
                    t[0] += fg[a][0][l];
                    t[1] += fg[a][1][l];
                    t[2] += fg[a][2][l];
                }
            }
        }
    }
    fn chunk_plain(&self, k: usize, u: &[[f64; 3]], f: Shared3) {
        self.chunk_body(k, u, f)
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn chunk_avx2(&self, k: usize, u: &[[f64; 3]], f: Shared3) {
        self.chunk_body(k, u, f)
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq")]
    fn chunk_avx512(&self, k: usize, u: &[[f64; 3]], f: Shared3) {
        self.chunk_body(k, u, f)
    }
    /// The chunk loop compiled for `simd` (the baseline when this CPU lacks it).
    fn chunk_fn(simd: Simd) -> ChunkFn<Self> {
        match simd {
            #[cfg(target_arch = "x86_64")]
            Simd::Avx2 if simd.detected() => |b, k, u, f| {
                // SAFETY: the CPU has AVX2 (`detected`, on the line above).
                unsafe { b.chunk_avx2(k, u, f) }
            },
            #[cfg(target_arch = "x86_64")]
            Simd::Avx512 if simd.detected() => |b, k, u, f| {
                // SAFETY: the CPU has AVX-512 F, VL and DQ (`detected`, on the line above).
                unsafe { b.chunk_avx512(k, u, f) }
            },
            _ => Self::chunk_plain,
        }
    }
}

impl<K: Kernel3<N>, const N: usize> Block3 for Block<K, N> {
    fn kind(&self) -> &'static str {
        K::KIND.name()
    }
    fn elems(&self) -> &[ElemId] {
        &self.elems
    }
    fn add_internal_forces(&self, u: &[[f64; 3]], f: &mut [[f64; 3]]) {
        self.add_internal_forces_pool(u, f, None)
    }
    fn add_internal_forces_pool(&self, u: &[[f64; 3]], f: &mut [[f64; 3]], pool: Option<&rayon::ThreadPool>) {
        if self.elems.is_empty() {
            return;
        }
        assert!(self.top < u.len() && self.top < f.len(), "cluster {} beyond the displacement ({}) or force ({}) array", self.top, u.len(), f.len());
        let shared = Shared3 { ptr: f.as_mut_ptr(), len: f.len() };
        debug_assert!(shared.len > self.top);
        let run = self.run;
        for col in &self.colours {
            match pool {
                Some(pool) if col.len() > 1 && pool.current_num_threads() > 1 => {
                    use rayon::prelude::*;
                    pool.install(|| col.par_iter().for_each(|&k| run(self, k as usize, u, shared)));
                }
                _ => {
                    for &k in col {
                        run(self, k as usize, u, shared);
                    }
                }
            }
        }
    }
    fn kernel_bytes(&self) -> usize {
        std::mem::size_of_val(self.packs.as_slice()) + std::mem::size_of_val(self.conn.as_slice())
    }
    fn colours(&self) -> usize {
        self.colours.len()
    }
    fn corner_stresses(&self, u: &[[f64; 3]], first_copy: &[u32], out: &mut [[f64; 6]]) {
        let mut ue = [[0.0; 3]; N];
        for (k, e) in self.elems.iter().enumerate() {
            let c = &self.conn[k];
            for a in 0..N {
                ue[a] = u[c[a] as usize];
            }
            let o = first_copy[e.idx()] as usize;
            corner_stresses(K::KIND, &self.x[k], &ue, &self.d, &mut out[o..o + N]);
        }
    }
    fn corner_masses(&self, first_copy: &[u32], out: &mut [f64]) {
        for (k, e) in self.elems.iter().enumerate() {
            let o = first_copy[e.idx()] as usize;
            out[o..o + N].copy_from_slice(&K::masses(&self.x[k], self.rho));
        }
    }
    fn add_row_sums(&self, rows: &mut [f64]) {
        for k in 0..self.elems.len() {
            let r = K::row_sums(&self.packs[k / LANES], k % LANES, &self.x[k], &self.d);
            for a in 0..N {
                rows[self.conn[k][a] as usize] += r[a];
            }
        }
    }
    fn reconnect(&mut self, topo: &Topology3) {
        for (k, &e) in self.elems.iter().enumerate() {
            let c = corner_clusters(topo, e);
            self.conn[k] = std::array::from_fn(|a| c[a]);
        }
        self.top = self.conn.iter().flatten().fold(0u32, |m, &c| m.max(c)) as usize;
    }
}

inventory::submit! { Kind3Registration { name: "t4", cell: CellKind3::T4, default: true, build: build::<T4K, 4> } }
inventory::submit! { Kind3Registration { name: "h8", cell: CellKind3::H8, default: true, build: build::<H8K, 8> } }
inventory::submit! { Kind3Registration { name: "h8_full", cell: CellKind3::H8, default: false, build: build::<H8FullK, 8> } }

#[cfg(test)]
mod tests {
    use super::*;

    /// The triangle index runs over 0..300 once, row by row.
    #[test]
    fn triangle_index_is_a_bijection() {
        let mut seen = [false; 300];
        let mut next = 0;
        for i in 0..24 {
            for j in i..24 {
                assert_eq!(tri(i, j), next);
                assert!(!seen[next]);
                seen[next] = true;
                next += 1;
            }
        }
    }

    /// Each kind's pack forces equal the kind's one-element reference (`elements3d::
    /// internal_force`: the same math from the coordinates) to round-off, on distorted cells.
    #[test]
    fn pack_forces_match_the_reference() {
        let d = Dmat3::new(1000.0, 0.3);
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let cube = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0]];
        let hexes: Vec<[[f64; 3]; 8]> = (0..5).map(|_| std::array::from_fn(|a| std::array::from_fn(|i| cube[a][i] + 0.15 * rnd()))).collect();
        let tets: Vec<[[f64; 3]; 4]> = hexes.iter().map(|h| [h[0], h[1], h[3], h[4]]).collect();
        let uh: Vec<[[f64; 3]; 8]> = (0..5).map(|_| std::array::from_fn(|_| std::array::from_fn(|_| rnd()))).collect();
        fn check<K: Kernel3<N>, const N: usize>(x: &[[[f64; 3]; N]], u: &[[[f64; 3]; N]], d: &Dmat3) {
            let p = K::pack(x, d);
            let mut ug = [[[0.0; LANES]; 3]; N];
            for (l, u) in u.iter().enumerate() {
                for a in 0..N {
                    for i in 0..3 {
                        ug[a][i][l] = u[a][i];
                    }
                }
            }
            let mut fg = [[[0.0; LANES]; 3]; N];
            K::forces(&p, d, x.len(), &ug, &mut fg);
            for l in 0..x.len() {
                let mut fr = [[0.0; 3]; N];
                super::super::internal_force(K::KIND, &x[l], &u[l], d, &mut fr);
                let scale = fr.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
                for a in 0..N {
                    for i in 0..3 {
                        assert!((fg[a][i][l] - fr[a][i]).abs() <= 1e-12 * scale, "{}: lane {l} corner {a} dof {i}: {} vs {}", K::KIND.name(), fg[a][i][l], fr[a][i]);
                    }
                }
                let rs = K::row_sums(&p, l, &x[l], d);
                let n = 3 * N;
                let mut ke = vec![0.0; n * n];
                stiffness(K::KIND, &x[l], d, &mut ke);
                for a in 0..N {
                    let r = (0..3).map(|i| ke[(3 * a + i) * n..(3 * a + i + 1) * n].iter().map(|v| v.abs()).sum::<f64>()).fold(0.0, f64::max);
                    assert!((rs[a] - r).abs() <= 1e-12 * r, "{}: row sum of corner {a}", K::KIND.name());
                }
            }
        }
        let ut: Vec<[[f64; 3]; 4]> = uh.iter().map(|u| std::array::from_fn(|a| u[a])).collect();
        check::<T4K, 4>(&tets, &ut, &d);
        check::<H8K, 8>(&hexes, &uh, &d);
        check::<H8FullK, 8>(&hexes, &uh, &d);
    }

    /// Two chunks of one colour share no cluster, and every chunk has one colour.
    #[test]
    fn colours_separate_chunks() {
        let mesh = flem_core::mesh::Box3::new([1.0, 1.0, 1.0], [7, 5, 4], CellKind3::T4).build().unwrap();
        let conn: Vec<[u32; 4]> = mesh.cells.iter().map(|c| std::array::from_fn(|a| c.nodes[a])).collect();
        let chunk = 16;
        let colours = colour_chunks(&conn, chunk);
        let mut n = 0;
        for col in &colours {
            let mut owner = vec![u32::MAX; mesh.points.len()];
            for &ch in col {
                n += 1;
                for c in &conn[ch as usize * chunk..((ch as usize + 1) * chunk).min(conn.len())] {
                    for &p in c {
                        assert!(owner[p as usize] == u32::MAX || owner[p as usize] == ch, "chunks {} and {ch} share point {p}", owner[p as usize]);
                        owner[p as usize] = ch;
                    }
                }
            }
        }
        assert_eq!(n, conn.len().div_ceil(chunk));
        assert!(colours.len() > 1);
    }
}
