//! Blocked internal-force kernels (issue 9) and their deterministic parallel schedule.
//!
//! **Layout.** A block's elements are grouped in packs of [`LANES`] consecutive elements. A pack
//! stores, per field, one array of `LANES` values (structure of arrays inside the pack), so the
//! force computation is one loop over the lanes that the compiler vectorises. Per element it
//! holds only what the geometry fixes (the element kind's `Blocked::Pack`; the built-in layouts
//! are documented with their kinds in `flem-plugins/src/elements/`, e.g. 32 bytes per element
//! for `q4` of parallelograms, 80 for other quadrilaterals, 32 for `t3`). Geometry that only some
//! packs need is a kind's `Blocked::Extra`, kept beside the packs for those packs only (issue
//! 24). The thickness and the Gauss weights are folded into the D matrix
//! (`Blocked::scaled_d`). Each kind's blocked force equals its one-element reference
//! (`Blocked::force_ref`, by default `element::internal_force`) to round-off; the kinds' unit
//! tests check 1e-12 relative.
//!
//! **Schedule.** Packs are grouped in chunks of consecutive packs (the chunk size depends on
//! the block size only, never on the thread count). Chunks are coloured greedily so that two
//! chunks of one colour share no cluster. A step runs the colours in order; the chunks of one
//! colour may run on different threads because they write disjoint clusters, and inside a
//! chunk elements are scattered in their local order. Every cluster therefore receives its
//! contributions in the same order (colour, then element) whatever the number of threads: the
//! result is bit-identical to one thread. The colours need not run one after the other: one
//! thread runs the chunks in a local order, and several threads run the same order as a
//! dataflow (`Schedule::local_order`, `Schedule::run_dataflow`), each chunk waiting for the
//! chunks sharing a cluster with it that come before it in (colour, index) order; the sums
//! are the same, and the clusters of nearby chunks are still in cache (issue 24). A split only re-points corners at new clusters whose
//! elements shared the parent cluster before, so the colouring stays valid after `remap`.
//!
//! **Threads, node update, measurement.** A step gathers `u` for a pack, computes its 8
//! elements as one vectorised loop and scatters. The chunks of one colour run on the rayon pool
//! of `solver.threads` (`Model::pool`; 0 = all cores, 1 = no pool). The node update
//! (`solver/mod.rs`) adds its ledger sums per fixed 4096-node chunk (`NODE_CHUNK`), so whole
//! runs, not only the forces, are bit-identical to one thread (tests/parallel.rs).
//! `element::internal_force` stays the reference. `flem bench step` (`tools/src/bench.rs`)
//! measures it all (JSON); figures of one session against Akantu are in `docs/perf/README.md`.
use crate::element::{Dmat, Shape};

/// Elements per pack (the width of the vectorised loop: two AVX2 or one AVX-512 register).
pub const LANES: usize = 8;

/// The element-kind trait: everything the core needs of an element kind (docs/elements.md).
///
/// From [`Shape`]: nodes (`N`, the cell type `KIND`, whose edges are the fans' and the splits'),
/// shape functions and their natural corners (the nodal-stress rule, `element::corner_xi`), Gauss
/// points (lumped mass, nonlocal input). Here: the internal force in the blocked pack form
/// (`pack`, `forces`; the hot loop, monomorphised per block), and with defaults that are the plain
/// isoparametric element: the reference force, the element stiffness (implicit check, stable-step
/// bound) and the stress at a natural point. An element with internal (condensed) fields, such as
/// the incompatible-mode quadrilateral `qm6` (plugins/src/elements/qm6.rs), overrides the three
/// and keeps `RECOVERY_LEN` f64 per element for its stress recovery.
pub trait Blocked<const N: usize>: Shape<N> {
    /// Registered name (`[[material]] element = "..."`).
    const NAME: &'static str;
    /// Precomputed geometry of `LANES` elements.
    type Pack: Copy + Send + Sync + 'static;
    /// Geometry that only some packs need, kept beside the packs for those packs only (`q4`:
    /// the packs holding a non-parallelogram); `()` for a kind that never needs any.
    type Extra: Copy + Send + Sync + 'static;
    /// Bytes of kernel data per element (the pack; a pack with an extra part adds
    /// `size_of::<Extra>() / LANES`, counted by `Block::kernel_bytes`).
    const BYTES_PER_ELEM: usize = std::mem::size_of::<Self::Pack>() / LANES;
    /// f64 per element that `stress` needs beyond the geometry (built once by `recovery`);
    /// 0 for an isoparametric element, whose stress comes from the shape gradients alone.
    const RECOVERY_LEN: usize = 0;
    /// Packs the data of up to `LANES` elements (missing lanes give zero force). `d` and `t`
    /// are the block's elasticity and thickness (an element may fold them into the pack).
    fn pack(x: &[[[f64; 2]; N]], d: &Dmat, t: f64) -> Self::Pack;
    /// The D matrix with thickness and Gauss weight folded in (passed back to `forces`).
    fn scaled_d(d: &Dmat, t: f64) -> [f64; 3];
    /// The extra part of the pack of `x` (as `pack`), `None` when `forces` needs none.
    fn extra(_x: &[[[f64; 2]; N]], _d: &Dmat, _t: f64) -> Option<Self::Extra> {
        None
    }
    /// Forces of the pack's elements, `f[a][dim][lane]`, from gathered `u[a][dim][lane]`
    /// (a pack whose `extra` is `None`).
    fn forces(p: &Self::Pack, d: &[f64; 3], u: &[[[f64; LANES]; 2]; N], f: &mut [[[f64; LANES]; 2]; N]);
    /// Forces of a pack whose `extra` is `e` (default: `forces`, the extra part unused).
    #[inline(always)]
    fn forces_extra(p: &Self::Pack, _e: &Self::Extra, d: &[f64; 3], u: &[[[f64; LANES]; 2]; N], f: &mut [[[f64; LANES]; 2]; N]) {
        Self::forces(p, d, u, f)
    }
    /// Internal force of one element, the reference the blocked kernel is tested against.
    #[inline(always)]
    fn force_ref(x: &[[f64; 2]; N], u: &[[f64; 2]; N], d: &Dmat, t: f64) -> [[f64; 2]; N] {
        crate::element::internal_force::<Self, N>(x, u, d, t)
    }
    /// Element stiffness, row-major (2N)^2, dofs x0 y0 x1 y1 ... (the implicit check and the
    /// stable-step bound); equal to the Jacobian of `forces`.
    fn stiffness(x: &[[f64; 2]; N], d: &Dmat, t: f64, k: &mut [f64]) {
        crate::element::stiffness::<Self, N>(x, d, t, k)
    }
    /// Fills `out` (`RECOVERY_LEN` values) with the element's stress-recovery data.
    fn recovery(_x: &[[f64; 2]; N], _d: &Dmat, _t: f64, _out: &mut [f64]) {}
    /// Stress `[sxx, syy, sxy]` at natural coordinate `xi`; `rec` is the element's `recovery`.
    fn stress(x: &[[f64; 2]; N], u: &[[f64; 2]; N], d: &Dmat, xi: [f64; 2], _rec: &[f64]) -> [f64; 3] {
        crate::element::stress_at::<Self, N>(x, u, d, xi)
    }
}

/// Chunks of packs and their colours (see the module doc).
#[derive(Clone, Debug, Default)]
pub struct Schedule {
    /// Packs per chunk.
    pub chunk_packs: usize,
    /// Chunk indices of each colour, in increasing order; colours run in this order.
    pub colours: Vec<Vec<u32>>,
    /// Every chunk once, in the order one thread runs them (see [`Schedule::local_order`]).
    pub order: Vec<u32>,
    /// The chunks each chunk waits for when threads run `order` together (CSR: those of chunk
    /// `k` are `wait_on[wait_start[k]..wait_start[k + 1]]`): the chunks sharing a cluster with
    /// it that come before it in (colour, index) order.
    pub wait_start: Vec<u32>,
    pub wait_on: Vec<u32>,
}

impl Schedule {
    /// Chunk size from the block size only: about 64 chunks per block, 4 to 64 packs each.
    pub fn chunk_packs_for(n_packs: usize) -> usize {
        (n_packs / 64).clamp(4, 64)
    }

    /// Greedy colouring of chunks by shared clusters (`conn` of every element, in local order).
    pub fn build<const N: usize>(conn: &[[u32; N]], n_clusters: usize) -> Schedule {
        let n_packs = conn.len().div_ceil(LANES);
        let chunk_packs = Self::chunk_packs_for(n_packs);
        let chunk_elems = chunk_packs * LANES;
        let n_chunks = conn.len().div_ceil(chunk_elems);
        // Chunks touching each cluster (CSR), then the colour of each chunk.
        let mut count = vec![0u32; n_clusters + 1];
        let mut last = vec![u32::MAX; n_clusters];
        for (k, ch) in conn.chunks(chunk_elems).enumerate() {
            for c in ch.iter().flatten() {
                let c = *c as usize;
                if last[c] != k as u32 {
                    last[c] = k as u32;
                    count[c + 1] += 1;
                }
            }
        }
        for i in 0..n_clusters {
            count[i + 1] += count[i];
        }
        let mut items = vec![0u32; count[n_clusters] as usize];
        let mut fill = count.clone();
        last.iter_mut().for_each(|x| *x = u32::MAX);
        for (k, ch) in conn.chunks(chunk_elems).enumerate() {
            for c in ch.iter().flatten() {
                let c = *c as usize;
                if last[c] != k as u32 {
                    last[c] = k as u32;
                    items[fill[c] as usize] = k as u32;
                    fill[c] += 1;
                }
            }
        }
        let mut colour = vec![u32::MAX; n_chunks];
        let mut used: Vec<bool> = Vec::new();
        for (k, ch) in conn.chunks(chunk_elems).enumerate() {
            used.iter_mut().for_each(|u| *u = false);
            for c in ch.iter().flatten() {
                let c = *c as usize;
                for &o in &items[count[c] as usize..count[c + 1] as usize] {
                    let oc = colour[o as usize];
                    if oc != u32::MAX {
                        if used.len() <= oc as usize {
                            used.resize(oc as usize + 1, false);
                        }
                        used[oc as usize] = true;
                    }
                }
            }
            let free = used.iter().position(|u| !u).unwrap_or(used.len());
            colour[k] = free as u32;
        }
        let n_colours = colour.iter().map(|&c| c as usize + 1).max().unwrap_or(0);
        let mut colours = vec![Vec::new(); n_colours];
        for (k, &c) in colour.iter().enumerate() {
            colours[c as usize].push(k as u32);
        }
        let (order, wait_start, wait_on) = Self::local_order(conn, chunk_elems, &count, &items, &colour);
        Schedule { chunk_packs, colours, order, wait_start, wait_on }
    }

    /// The order one thread runs the chunks in (issue 24). A cluster's sum depends only on the
    /// order of the chunks that touch it, (colour, index) when the colours run one after the
    /// other; any order that keeps it for every pair of chunks sharing a cluster gives the same
    /// forces bit for bit. Of those, the one nearest to index order (Kahn's algorithm, smallest
    /// index first): running whole colours one after the other streams the node arrays once per
    /// colour, this order keeps nearby chunks together, so their clusters are still in cache.
    /// Also returns the waits of each chunk (`wait_start`, `wait_on`).
    #[allow(clippy::type_complexity)]
    fn local_order<const N: usize>(conn: &[[u32; N]], chunk_elems: usize, count: &[u32], items: &[u32], colour: &[u32]) -> (Vec<u32>, Vec<u32>, Vec<u32>) {
        use std::cmp::Reverse;
        let n_chunks = colour.len();
        let key = |k: u32| (colour[k as usize], k);
        let mut after: Vec<Vec<u32>> = vec![Vec::new(); n_chunks];
        let mut waits = vec![0u32; n_chunks];
        let mut near = Vec::new();
        for (k, ch) in conn.chunks(chunk_elems).enumerate() {
            near.clear();
            for c in ch.iter().flatten() {
                let c = *c as usize;
                near.extend(items[count[c] as usize..count[c + 1] as usize].iter().filter(|&&o| key(o) > key(k as u32)));
            }
            near.sort_unstable();
            near.dedup();
            for &o in &near {
                waits[o as usize] += 1;
            }
            after[k].extend_from_slice(&near);
        }
        let mut ready: std::collections::BinaryHeap<Reverse<u32>> = (0..n_chunks as u32).filter(|&k| waits[k as usize] == 0).map(Reverse).collect();
        let mut order = Vec::with_capacity(n_chunks);
        while let Some(Reverse(k)) = ready.pop() {
            order.push(k);
            for &o in &after[k as usize] {
                waits[o as usize] -= 1;
                if waits[o as usize] == 0 {
                    ready.push(Reverse(o));
                }
            }
        }
        debug_assert_eq!(order.len(), n_chunks, "the (colour, index) order has no cycle");
        let mut wait_start = vec![0u32; n_chunks + 1];
        for a in after.iter().flatten() {
            wait_start[*a as usize + 1] += 1;
        }
        for k in 0..n_chunks {
            wait_start[k + 1] += wait_start[k];
        }
        let mut fill = wait_start.clone();
        let mut wait_on = vec![0u32; wait_start[n_chunks] as usize];
        for (k, a) in after.iter().enumerate() {
            for &o in a {
                wait_on[fill[o as usize] as usize] = k as u32;
                fill[o as usize] += 1;
            }
        }
        (order, wait_start, wait_on)
    }

    /// Runs every chunk once with `run` on every thread of `pool`, the threads taking the
    /// chunks in `order`; a chunk starts when the chunks it waits for are done (issue 24: the
    /// colours ran one after the other over the whole block, streaming the node arrays once per
    /// colour). `done` holds one flag per chunk, set to `epoch` when it is done; `epoch` must
    /// differ from every flag at the call (a new value per call).
    ///
    /// No deadlock: `order` is a topological order of the waits, so the chunk at the smallest
    /// position not done has every chunk it waits for done. The same sums as the colours: two
    /// chunks sharing a cluster never run at the same time and run in (colour, index) order.
    pub fn run_dataflow(&self, pool: &rayon::ThreadPool, done: &[std::sync::atomic::AtomicU32], epoch: u32, run: impl Fn(usize) + Sync) {
        use std::sync::atomic::{AtomicUsize, Ordering};
        let next = AtomicUsize::new(0);
        pool.broadcast(|_| loop {
            let i = next.fetch_add(1, Ordering::Relaxed);
            let Some(&k) = self.order.get(i) else { break };
            let k = k as usize;
            for &w in &self.wait_on[self.wait_start[k] as usize..self.wait_start[k + 1] as usize] {
                let mut spins = 0u32;
                // Acquire: the forces the waited-for chunk wrote are visible here.
                while done[w as usize].load(Ordering::Acquire) != epoch {
                    spins += 1;
                    if spins < 64 {
                        std::hint::spin_loop();
                    } else {
                        std::thread::yield_now();
                    }
                }
            }
            run(k);
            // Release: every write of chunk k happens before a waiting chunk's reads.
            done[k].store(epoch, Ordering::Release);
        });
    }

    pub fn n_chunks(&self) -> usize {
        self.colours.iter().map(Vec::len).sum()
    }
}

/// A raw view of the force array shared by the chunks of one colour.
///
/// Safety argument (why not a safe split): the clusters written by one chunk are scattered over
/// the whole array, so no slice split separates them. The colouring guarantees that chunks
/// running at the same time (one colour) write disjoint clusters, so no two threads touch the
/// same element of the array; under the dataflow (`Schedule::run_dataflow`) a chunk starts
/// only when every chunk sharing a cluster with it and before it in (colour, index) order is
/// done (its flag stored with Release after its last write, loaded with Acquire before the
/// first read), and the chunks after it wait for it likewise. `f` outlives every use (the
/// colour loop and the broadcast join before returning).
#[derive(Copy, Clone)]
pub struct SharedForces {
    ptr: *mut [f64; 2],
    len: usize,
}
unsafe impl Send for SharedForces {}
unsafe impl Sync for SharedForces {}

impl SharedForces {
    pub fn new(f: &mut [[f64; 2]]) -> Self {
        SharedForces { ptr: f.as_mut_ptr(), len: f.len() }
    }
    /// `f[c] += v`.
    ///
    /// # Safety
    /// No other thread may access `f[c]` during the call (guaranteed by the colouring).
    #[inline(always)]
    pub unsafe fn add(&self, c: usize, v: [f64; 2]) {
        assert!(c < self.len);
        // SAFETY: in bounds (checked), exclusive by the caller's contract.
        let x = unsafe { &mut *self.ptr.add(c) };
        x[0] += v[0];
        x[1] += v[1];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Chunks of one colour share no cluster; every chunk has one colour.
    #[test]
    fn colouring_separates_chunks() {
        // A structured 100 x 60 grid of quads, row by row.
        let nx = 100;
        let conn: Vec<[u32; 4]> = (0..60)
            .flat_map(|j| {
                (0..nx).map(move |i| {
                    let id = |i: u32, j: u32| j * (nx + 1) + i;
                    [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]
                })
            })
            .collect();
        let s = Schedule::build(&conn, 101 * 61);
        let ce = s.chunk_packs * LANES;
        assert_eq!(s.n_chunks(), conn.len().div_ceil(ce));
        // The one-thread order runs every chunk once and, for every cluster, its chunks in
        // (colour, index) order, the order of running the colours one after the other.
        let mut sorted = s.order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..s.n_chunks() as u32).collect::<Vec<_>>());
        let colour_of = |k: u32| s.colours.iter().position(|c| c.contains(&k)).unwrap();
        let mut seen: Vec<Vec<u32>> = vec![Vec::new(); 101 * 61];
        for &k in &s.order {
            for e in conn.chunks(ce).nth(k as usize).unwrap() {
                for &c in e {
                    let v = &mut seen[c as usize];
                    if v.last() != Some(&k) {
                        if let Some(&prev) = v.last() {
                            assert!((colour_of(prev), prev) < (colour_of(k), k), "cluster {c}: chunk {k} runs after {prev} against the colour order");
                        }
                        v.push(k);
                    }
                }
            }
        }
        assert!(s.order.iter().enumerate().any(|(i, &k)| k as usize != i), "a grid this size needs more than one colour");
        for col in &s.colours {
            let mut owner = vec![u32::MAX; 101 * 61];
            for &k in col {
                for e in conn.chunks(ce).nth(k as usize).unwrap() {
                    for &c in e {
                        assert!(owner[c as usize] == u32::MAX || owner[c as usize] == k, "two chunks of one colour share cluster {c}");
                        owner[c as usize] = k;
                    }
                }
            }
        }
    }
}
