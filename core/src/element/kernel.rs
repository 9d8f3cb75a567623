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
//! the block size only, never on the thread count). Inside a chunk elements are scattered in
//! their local order. The chunk range is cut into regions (their number too depends on the
//! block only, `Schedule::regions_for`), and the chunks are put in one *sequence*: first the
//! *lead* chunks (those sharing a cluster with an earlier region), then region by region the
//! others (`Schedule::build`). Two chunks sharing a cluster add to it in sequence order,
//! whatever thread runs them: every cluster receives its contributions in the same order
//! (sequence, then element) whatever the number of threads, so the result is bit-identical
//! to one thread. One thread runs any order that keeps this (`Schedule::order`, the one
//! nearest to index order); several threads run the lead chunks first, then one region each
//! at a time, each chunk waiting for the chunks sharing a cluster with it that come before it
//! in the sequence (`Schedule::run_dataflow`; issue 24, session 10: the threads seldom wait,
//! because a region's chunks wait only for lead chunks, run long before, and for their own
//! region's). A block larger than the last-level cache runs them region by region instead
//! (`Schedule::run_dataflow_local`, ours, session 29: each thread takes a region and runs its
//! lead chunks, its interior, the next region's lead chunks and its trailing chunks, so the
//! clusters a lead chunk shares are still in cache; with the lead chunks first they were read
//! from memory twice: without the prefetch, 1.17-1.25x faster on two threads at 1e6 elements;
//! with the prefetch of `ElementBlock::prefetch_ahead`, 0.9-1.07x, within the noise). Either
//! way the waits fix every cluster's order, so the forces are the same bits (`Dataflow`
//! chooses; `Model::set_dataflow`). The greedy colouring of the chunks (two chunks of one colour share no cluster)
//! is kept for the stateful blocks, which run the colours one after the other. A split only
//! re-points corners at new clusters whose elements shared the parent cluster before, so the
//! colouring, the lead chunks and the waits stay valid after `remap`.
//!
//! **Parallelism** (issue 42). The waits make the pass a task graph (`Schedule::task_graph`,
//! `element::dag`): a region's chunks share clusters one with the next on a banded mesh, so
//! they are a chain, and the critical path is about one region (its lead chunks, then its
//! others); the parallelism, work over critical path, is about the number of regions. Their
//! cap (`Schedule::regions_for`) was 64, which held it below 64 at any size; it is 4096, so a
//! block of 1e6 elements has 122 regions and a parallelism above 100 (`flem bench step`'s
//! `task_graph` measures it; docs/perf/README.md). `Schedule::simulate_dataflow` and
//! `Schedule::simulate_dataflow_local` model the two dataflows on any number of threads.
//!
//! **Zero-free pass** (issue 24, session 11). Since the sequence fixes each cluster's order of
//! contributions from the mesh alone, the first contribution of every cluster is known before
//! any pass. A model of one stateless block (`Model::internal_forces`,
//! `Model::update_internal_forces`) lets the pack of that first writer zero the cluster just
//! before it computes (`SharedForces::zero`; per pack, the list of the clusters it writes
//! first, built with the schedule by `ElementBlock`, rebuilt after a split by
//! `Model::apply_record`), so the force array is not zeroed before the pass: the same
//! bits (tests/zero_free.rs), one sweep of 16 bytes per cluster less. Every other caller (several blocks, stateful or co-rotational blocks, the `add_*`
//! methods) zeroes and adds.
//!
//! **Threads, node update, measurement.** A step gathers `u` for a pack, computes its 8
//! elements as one vectorised loop and scatters. The chunks run on the rayon pool
//! of `solver.threads` (`Model::pool`; 0 = all cores, 1 = no pool). The node update
//! (`solver/mod.rs`) adds its ledger sums per fixed 4096-node chunk (`NODE_CHUNK`), so whole
//! runs, not only the forces, are bit-identical to one thread (tests/parallel.rs).
//! `element::internal_force` stays the reference. `flem bench step` (`tools/src/bench.rs`)
//! measures it all (JSON); figures of one session against Akantu are in `docs/perf/README.md`.
use crate::element::dag::TaskGraph;
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

/// Which of the two dataflows the threads run (issue 42, session 29; the forces are the same
/// bits with either, and with one thread): `Phases` is [`Schedule::run_dataflow`] (the lead
/// chunks of every region first, then the regions), `Local` is
/// [`Schedule::run_dataflow_local`] (ours: region by region, each lead chunk beside the chunks
/// that share its clusters), `Auto` (the default) takes `Local` for a block whose streamed
/// bytes exceed the last-level cache ([`last_level_cache_bytes`]) and `Phases` otherwise.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Dataflow {
    #[default]
    Auto,
    Phases,
    Local,
}

impl Dataflow {
    pub fn name(self) -> &'static str {
        match self {
            Dataflow::Auto => "auto",
            Dataflow::Phases => "phases",
            Dataflow::Local => "local",
        }
    }
    /// Whether a block that streams `bytes` per force pass runs the local dataflow.
    pub fn local_for(self, bytes: usize) -> bool {
        match self {
            Dataflow::Auto => bytes > last_level_cache_bytes(),
            Dataflow::Phases => false,
            Dataflow::Local => true,
        }
    }
}

impl std::str::FromStr for Dataflow {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(Dataflow::Auto),
            "phases" => Ok(Dataflow::Phases),
            "local" => Ok(Dataflow::Local),
            _ => Err(format!("unknown dataflow `{s}` (auto, phases or local)")),
        }
    }
}

/// The size of the largest cache of the first CPU (Linux sysfs,
/// `/sys/devices/system/cpu/cpu0/cache/index*/size`), read once; 32 MiB where it cannot be read.
pub fn last_level_cache_bytes() -> usize {
    static LLC: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *LLC.get_or_init(|| {
        let parse = |t: &str| {
            let t = t.trim();
            let (num, mult) = match t.as_bytes().last() {
                Some(b'K') => (&t[..t.len() - 1], 1usize << 10),
                Some(b'M') => (&t[..t.len() - 1], 1 << 20),
                Some(b'G') => (&t[..t.len() - 1], 1 << 30),
                _ => (t, 1),
            };
            num.parse::<usize>().ok().map(|n| n * mult)
        };
        let dir = std::path::Path::new("/sys/devices/system/cpu/cpu0/cache");
        (0..8).filter_map(|i| parse(&std::fs::read_to_string(dir.join(format!("index{i}/size"))).ok()?)).max().unwrap_or(32 << 20)
    })
}

/// Chunks of packs, their colours, and the order in which threads run them (see the module doc).
#[derive(Clone, Debug, Default)]
pub struct Schedule {
    /// Packs per chunk.
    pub chunk_packs: usize,
    /// Chunk indices of each colour, in increasing order (two chunks of one colour share no
    /// cluster): the stateful blocks (`element::stateful`) run the colours one after the other.
    pub colours: Vec<Vec<u32>>,
    /// Every chunk once, in the order one thread runs them (see [`Schedule::build`]).
    pub order: Vec<u32>,
    /// The lead chunks (those sharing a cluster with an earlier region), the regions taken in
    /// turn (the first lead chunk of every region, then the second, ...): the first phase of
    /// [`Schedule::run_dataflow`].
    pub lead: Vec<u32>,
    /// The other chunks of region `r`, interior ones then trailing ones, each in index order:
    /// `rest[region_start[r]..region_start[r + 1]]`.
    pub region_start: Vec<u32>,
    pub rest: Vec<u32>,
    /// The chunks each chunk waits for (CSR: those of chunk `k` are
    /// `wait_on[wait_start[k]..wait_start[k + 1]]`): the chunks sharing a cluster with it that
    /// come before it in the schedule's sequence, `lead` then `rest`.
    pub wait_start: Vec<u32>,
    pub wait_on: Vec<u32>,
    /// The lead chunks of region `r` in index order: `lead_local[lead_local_start[r]..
    /// lead_local_start[r + 1]]` (the same chunks as `lead`, by region).
    pub lead_local: Vec<u32>,
    pub lead_local_start: Vec<u32>,
    /// Where region `r`'s trailing chunks start in `rest` (its interior ones are
    /// `rest[region_start[r]..trail_start[r]]`).
    pub trail_start: Vec<u32>,
    /// The longest chain of waits, in chunks (`run_dataflow_local` helps along such a chain,
    /// at most [`Schedule::LOCAL_CHAIN`] deep).
    pub chain: u32,
}

/// Sets the dataflow's poison flag when dropped during a panic (held around each chunk's run):
/// the threads waiting for that chunk then give up instead of spinning for ever.
struct OnPanic<'a>(&'a std::sync::atomic::AtomicBool);
impl Drop for OnPanic<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.store(true, std::sync::atomic::Ordering::Relaxed);
        }
    }
}

/// Runs `work` once on each thread of `pool` (as far as the pool lends them: a half that no
/// other thread steals runs after the first), started with `rayon::join` inside `install`
/// (no allocation per call, unlike `broadcast`).
fn run_on_every_thread(pool: &rayon::ThreadPool, work: &(impl Fn() + Sync)) {
    fn fan(n: usize, work: &(impl Fn() + Sync)) {
        if n <= 1 {
            work()
        } else {
            rayon::join(|| fan(n / 2, work), || fan(n - n / 2, work));
        }
    }
    pool.install(|| fan(pool.current_num_threads(), work));
}

impl Schedule {
    /// Chunk size from the block size only: about 64 chunks per block, 4 to 64 packs each.
    pub fn chunk_packs_for(n_packs: usize) -> usize {
        (n_packs / 64).clamp(4, 64)
    }

    /// Regions of a block of `n_chunks` chunks: about 16 chunks each, from the chunk count
    /// only (never from the thread count: the regions fix the sums). At most 4096 (issue 42;
    /// before it 64, which held the force pass's parallelism below 64 for any block of more
    /// than 1024 chunks, about 5e5 elements: with a region's chunks a chain, the critical path
    /// is about one region, so the parallelism about the number of regions). Only blocks of
    /// more than 1024 chunks changed.
    pub fn regions_for(n_chunks: usize) -> usize {
        (n_chunks / 16).clamp(1, 4096)
    }

    /// Chunks, colours and the sequence of the chunks (`conn` of every element, in local
    /// order; issue 24, session 10).
    ///
    /// The chunk range is cut into [`Schedule::regions_for`] regions of consecutive chunks. A
    /// chunk of region `r` is *lead* when it shares a cluster with a chunk of an earlier
    /// region, else *trailing* when it shares one with a later region, else *interior*. The
    /// sequence is every lead chunk (regions taken in turn), then region by region its
    /// interior then its trailing chunks, each in index order. Two chunks sharing a cluster
    /// add their forces to it in sequence order, whoever runs them: a cluster's sum, and so
    /// the forces bit for bit, depend on the sequence only, which depends on the mesh only.
    /// Only a lead chunk shares clusters with another region (of two chunks sharing a
    /// cluster across regions, the later one is lead), so a region's other chunks wait only
    /// for lead chunks and for their own region's earlier chunks.
    pub fn build<const N: usize>(conn: &[[u32; N]], n_clusters: usize) -> Schedule {
        let n_packs = conn.len().div_ceil(LANES);
        let chunk_packs = Self::chunk_packs_for(n_packs);
        let chunk_elems = chunk_packs * LANES;
        let n_chunks = conn.len().div_ceil(chunk_elems);
        // Chunks touching each cluster (CSR, increasing chunk order), then the colour of each chunk.
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
        let mut s = Schedule { chunk_packs, colours, ..Default::default() };
        s.sequence(conn, chunk_elems, &count, &items);
        s
    }

    /// Regions, lead chunks, the waits and the one-thread order (see [`Schedule::build`]).
    fn sequence<const N: usize>(&mut self, conn: &[[u32; N]], chunk_elems: usize, count: &[u32], items: &[u32]) {
        use std::cmp::Reverse;
        let n_chunks = self.colours.iter().map(Vec::len).sum::<usize>();
        let n_regions = Self::regions_for(n_chunks);
        let rstart: Vec<usize> = (0..=n_regions).map(|r| r * n_chunks / n_regions).collect();
        let chunks = || conn.chunks(chunk_elems).enumerate();
        // Lead, interior and trailing chunks of each region, in index order.
        let (mut lead_of, mut inner_of, mut trail_of) = (vec![Vec::new(); n_regions], vec![Vec::new(); n_regions], vec![Vec::new(); n_regions]);
        let mut region = vec![0u32; n_chunks];
        for r in 0..n_regions {
            for k in rstart[r]..rstart[r + 1] {
                region[k] = r as u32;
            }
        }
        for (k, ch) in chunks() {
            let r = region[k] as usize;
            let touch = |c: &u32| &items[count[*c as usize] as usize..count[*c as usize + 1] as usize];
            // `items` of a cluster are in increasing chunk order: first and last toucher.
            if ch.iter().flatten().any(|c| (touch(c)[0] as usize) < rstart[r]) {
                lead_of[r].push(k as u32);
            } else if ch.iter().flatten().any(|c| *touch(c).last().unwrap() as usize >= rstart[r + 1]) {
                trail_of[r].push(k as u32);
            } else {
                inner_of[r].push(k as u32);
            }
        }
        let deepest = lead_of.iter().map(Vec::len).max().unwrap_or(0);
        self.lead = (0..deepest).flat_map(|j| lead_of.iter().filter_map(move |l| l.get(j).copied())).collect();
        self.region_start = vec![0];
        self.rest = Vec::with_capacity(n_chunks - self.lead.len());
        self.lead_local = lead_of.concat();
        self.lead_local_start = std::iter::once(0)
            .chain(lead_of.iter().scan(0u32, |a, l| {
                *a += l.len() as u32;
                Some(*a)
            }))
            .collect();
        self.trail_start = Vec::with_capacity(n_regions);
        for r in 0..n_regions {
            self.rest.extend_from_slice(&inner_of[r]);
            self.trail_start.push(self.rest.len() as u32);
            self.rest.extend_from_slice(&trail_of[r]);
            self.region_start.push(self.rest.len() as u32);
        }
        // Position of each chunk in the sequence, and the waits: the chunks sharing a cluster
        // that come before it.
        let mut pos = vec![0u32; n_chunks];
        for (i, &k) in self.lead.iter().chain(&self.rest).enumerate() {
            pos[k as usize] = i as u32;
        }
        self.wait_start = Vec::with_capacity(n_chunks + 1);
        self.wait_start.push(0);
        self.wait_on.clear();
        let mut near = Vec::new();
        for (k, ch) in chunks() {
            near.clear();
            for c in ch.iter().flatten() {
                let c = *c as usize;
                near.extend(items[count[c] as usize..count[c + 1] as usize].iter().filter(|&&o| pos[o as usize] < pos[k]));
            }
            near.sort_unstable();
            near.dedup();
            self.wait_on.extend_from_slice(&near);
            self.wait_start.push(self.wait_on.len() as u32);
        }
        // The one-thread order: any order that keeps the waits gives the same sums. Of those,
        // the one nearest to region by region, interior, then the next region's lead chunks,
        // then the trailing ones (Kahn's algorithm, the nearest first): the clusters a lead
        // chunk shares are still in cache from the chunks before it.
        let mut depth = vec![0u32; n_chunks];
        for &k in self.lead.iter().chain(&self.rest) {
            let k = k as usize;
            depth[k] = 1 + self.wait_on[self.wait_start[k] as usize..self.wait_start[k + 1] as usize].iter().map(|&w| depth[w as usize]).max().unwrap_or(0);
        }
        self.chain = depth.iter().copied().max().unwrap_or(0);
        let mut near_rank = vec![0u32; n_chunks];
        let mut i = 0u32;
        // (Region 0 has no lead chunk: the lead chunks of region r + 1 come after region r's interior.)
        for r in 0..n_regions {
            let next_lead = lead_of.get(r + 1).map(Vec::as_slice).unwrap_or(&[]);
            for &k in inner_of[r].iter().chain(next_lead).chain(&trail_of[r]) {
                near_rank[k as usize] = i;
                i += 1;
            }
        }
        let mut after_start = vec![0u32; n_chunks + 1];
        for &w in &self.wait_on {
            after_start[w as usize + 1] += 1;
        }
        for k in 0..n_chunks {
            after_start[k + 1] += after_start[k];
        }
        let mut after = vec![0u32; self.wait_on.len()];
        let mut fill = after_start.clone();
        for k in 0..n_chunks {
            for &w in &self.wait_on[self.wait_start[k] as usize..self.wait_start[k + 1] as usize] {
                after[fill[w as usize] as usize] = k as u32;
                fill[w as usize] += 1;
            }
        }
        let mut waits: Vec<u32> = (0..n_chunks).map(|k| self.wait_start[k + 1] - self.wait_start[k]).collect();
        let mut ready: std::collections::BinaryHeap<Reverse<(u32, u32)>> = (0..n_chunks as u32).filter(|&k| waits[k as usize] == 0).map(|k| Reverse((near_rank[k as usize], k))).collect();
        self.order = Vec::with_capacity(n_chunks);
        while let Some(Reverse((_, k))) = ready.pop() {
            self.order.push(k);
            for &o in &after[after_start[k as usize] as usize..after_start[k as usize + 1] as usize] {
                waits[o as usize] -= 1;
                if waits[o as usize] == 0 {
                    ready.push(Reverse((near_rank[o as usize], o)));
                }
            }
        }
        debug_assert_eq!(self.order.len(), n_chunks, "the waits follow one sequence: no cycle");
    }

    /// Runs every chunk once with `run` on the threads of `pool` (issue 24, session 10). First
    /// the lead chunks, taken one at a time by whichever thread is free, in `lead` order;
    /// then the regions, each taken whole by one thread, which runs its interior then its
    /// trailing chunks. A chunk starts when the chunks it waits for are done. `done` holds
    /// one flag per chunk, set to `epoch` when it is done; `epoch` must differ from every flag
    /// at the call (a new value per call).
    ///
    /// The same sums as one thread: two chunks sharing a cluster never run at the same time
    /// and run in sequence order (the waits). Why threads seldom wait: consecutive lead chunks
    /// belong to different regions, so they share no cluster unless the regions are thin;
    /// a region's interior waits only for its own lead chunks and the trailing chunks for
    /// the next region's, all run in the first phase. No deadlock, even when some threads of
    /// the pool never come: a lead chunk waits only for lead chunks earlier in `lead`, all
    /// taken by running threads (by induction, done); a thread starts on the regions only
    /// once every lead chunk is taken, and a region's chunk waits only for lead chunks and
    /// for the chunks its own thread ran before it. The threads are started with
    /// `rayon::join` inside `install` (no allocation per call, unlike `broadcast`); a half
    /// that no other thread steals runs after the first and finds nothing left.
    pub fn run_dataflow(&self, pool: &rayon::ThreadPool, done: &[std::sync::atomic::AtomicU32], epoch: u32, run: impl Fn(usize) + Sync) {
        use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
        let (next_lead, next_region) = (AtomicUsize::new(0), AtomicUsize::new(0));
        // Set when a chunk panics (a bug, or a plugin kind's panic): the chunks waiting for it
        // would otherwise spin for ever; they give up instead, and `rayon::join` hands the
        // panic to the caller once every thread has returned.
        let poisoned = AtomicBool::new(false);
        let one = |k: u32| {
            let k = k as usize;
            for &w in &self.wait_on[self.wait_start[k] as usize..self.wait_start[k + 1] as usize] {
                let mut spins = 0u32;
                // Acquire: the forces the waited-for chunk wrote are visible here.
                while done[w as usize].load(Ordering::Acquire) != epoch {
                    spins += 1;
                    if spins < 256 {
                        std::hint::spin_loop();
                    } else {
                        if poisoned.load(Ordering::Relaxed) {
                            return;
                        }
                        std::thread::yield_now();
                    }
                }
            }
            let guard = OnPanic(&poisoned);
            run(k);
            drop(guard);
            // Release: every write of chunk k happens before a waiting chunk's reads.
            done[k].store(epoch, Ordering::Release);
        };
        let work = || {
            while let Some(&k) = self.lead.get(next_lead.fetch_add(1, Ordering::Relaxed)) {
                one(k);
            }
            loop {
                let r = next_region.fetch_add(1, Ordering::Relaxed);
                if r + 1 >= self.region_start.len() {
                    break;
                }
                self.rest[self.region_start[r] as usize..self.region_start[r + 1] as usize].iter().for_each(|&k| one(k));
            }
        };
        run_on_every_thread(pool, &work);
    }

    /// Region `r`'s lead chunks in index order (none past the last region).
    fn lead_of_region(&self, r: usize) -> &[u32] {
        if r + 1 < self.lead_local_start.len() {
            &self.lead_local[self.lead_local_start[r] as usize..self.lead_local_start[r + 1] as usize]
        } else {
            &[]
        }
    }
    /// Region `r`'s interior chunks (sharing no cluster with another region).
    fn interior_of(&self, r: usize) -> &[u32] {
        &self.rest[self.region_start[r] as usize..self.trail_start[r] as usize]
    }
    /// Region `r`'s trailing chunks (sharing a cluster with a later region's lead chunks).
    fn trailing_of(&self, r: usize) -> &[u32] {
        &self.rest[self.trail_start[r] as usize..self.region_start[r + 1] as usize]
    }

    /// The longest chain of waits along which [`Self::run_dataflow_local`] may help (its
    /// recursion depth); a schedule with a longer one runs [`Self::run_dataflow`].
    pub const LOCAL_CHAIN: u32 = 256;

    /// Runs every chunk once with `run` on the threads of `pool`, region by region (ours,
    /// session 29: the lead chunks next to the chunks that share their clusters, so that
    /// those clusters are still in cache). Each thread takes the next region `r` and runs
    /// those of its lead chunks nobody has taken, its interior chunks, the next region's lead
    /// chunks nobody has taken, then its trailing chunks. A chunk is *taken* by the thread
    /// that swaps `epoch` into its `taken` flag first, and runs on that thread only; before
    /// it runs, each chunk it waits for is either done, or taken by another thread (then
    /// this one spins until it is done), or not yet taken (then this one takes it and runs
    /// it first: the helping of work-stealing runtimes' joins, as in Java's ForkJoin or TBB). The
    /// same sums as [`Self::run_dataflow`] and as one thread: two chunks sharing a cluster run
    /// in sequence order (the waits).
    ///
    /// No deadlock: a thread spins only on a taken chunk that is not done. Of all taken chunks
    /// not done, the one earliest in the sequence waits only for chunks earlier still, so for
    /// done ones or ones nobody has taken, which its thread takes and runs (each earlier
    /// again): its thread always progresses. The helping recursion is at most `chain` deep;
    /// a schedule whose `chain` exceeds [`Self::LOCAL_CHAIN`] runs [`Self::run_dataflow`]
    /// instead. A chunk that panics stops every thread at its next wait (`poisoned`): no
    /// chunk starts after one of its waits gave up.
    pub fn run_dataflow_local(&self, pool: &rayon::ThreadPool, done: &[std::sync::atomic::AtomicU32], taken: &[std::sync::atomic::AtomicU32], epoch: u32, run: impl Fn(usize) + Sync) {
        use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
        if self.chain > Self::LOCAL_CHAIN {
            // Helping could recurse as deep as the chain: the phases instead.
            return self.run_dataflow(pool, done, epoch, run);
        }
        struct Flow<'a, F> {
            s: &'a Schedule,
            done: &'a [std::sync::atomic::AtomicU32],
            taken: &'a [std::sync::atomic::AtomicU32],
            epoch: u32,
            poisoned: AtomicBool,
            run: F,
        }
        impl<F: Fn(usize) + Sync> Flow<'_, F> {
            /// Takes chunk `k` if nobody has (the swap orders the takers of one flag).
            fn take(&self, k: usize) -> bool {
                self.taken[k].load(Ordering::Relaxed) != self.epoch && self.taken[k].swap(self.epoch, Ordering::Relaxed) != self.epoch
            }
            /// Runs chunk `k`, taken by this thread, after its waits; false when it gave up
            /// (a chunk panicked: nothing more runs on this thread).
            fn go(&self, k: usize) -> bool {
                let s = self.s;
                for &w in &s.wait_on[s.wait_start[k] as usize..s.wait_start[k + 1] as usize] {
                    let w = w as usize;
                    if self.done[w].load(Ordering::Acquire) == self.epoch {
                        continue;
                    }
                    if self.take(w) {
                        if !self.go(w) {
                            return false;
                        }
                        continue;
                    }
                    let mut spins = 0u32;
                    // Acquire: the forces the waited-for chunk wrote are visible here.
                    while self.done[w].load(Ordering::Acquire) != self.epoch {
                        spins += 1;
                        if spins < 256 {
                            std::hint::spin_loop();
                        } else {
                            if self.poisoned.load(Ordering::Relaxed) {
                                return false;
                            }
                            std::thread::yield_now();
                        }
                    }
                }
                let guard = OnPanic(&self.poisoned);
                (self.run)(k);
                drop(guard);
                // Release: every write of chunk k happens before a waiting chunk's reads.
                self.done[k].store(self.epoch, Ordering::Release);
                true
            }
            fn offer(&self, ks: &[u32]) -> bool {
                ks.iter().all(|&k| !self.take(k as usize) || self.go(k as usize))
            }
        }
        let flow = Flow { s: self, done, taken, epoch, poisoned: AtomicBool::new(false), run };
        let next_region = AtomicUsize::new(0);
        let n_regions = self.region_start.len().saturating_sub(1);
        let work = || loop {
            let r = next_region.fetch_add(1, Ordering::Relaxed);
            if r >= n_regions {
                break;
            }
            // Only this region's own chunks wait for its interior and trailing chunks, and
            // they run on this thread: nobody helps with them, no flag is needed.
            let ok = flow.offer(self.lead_of_region(r))
                && self.interior_of(r).iter().all(|&k| flow.go(k as usize))
                && flow.offer(self.lead_of_region(r + 1))
                && self.trailing_of(r).iter().all(|&k| flow.go(k as usize));
            if !ok {
                break;
            }
        };
        run_on_every_thread(pool, &work);
    }

    /// The makespan of [`Self::run_dataflow_local`] on `threads` threads when chunk `k` takes
    /// `cost[k]` (a model, like [`Self::simulate_dataflow`]): the free thread that comes first
    /// takes the next region and runs its lead chunks not yet taken, its interior ones, the
    /// next region's lead chunks not yet taken and its trailing ones; a chunk starts when its
    /// thread is free and its waits are done, and a wait not yet taken is run first on the
    /// same thread (helping). An approximation: a thread settles all the helping a chunk
    /// needs when it starts that chunk, where the code decides wait by wait.
    pub fn simulate_dataflow_local(&self, cost: &[f64], threads: usize) -> f64 {
        assert_eq!(cost.len(), self.n_chunks(), "one cost per chunk");
        struct Sim<'a> {
            s: &'a Schedule,
            cost: &'a [f64],
            /// Per chunk: NaN not taken, else the time it is done (known when it is taken).
            done: Vec<f64>,
        }
        impl Sim<'_> {
            /// Takes and runs chunk `k` on a thread free at `t`; returns when it is done.
            fn go(&mut self, t: f64, k: usize) -> f64 {
                let s = self.s;
                let mut t = t;
                self.done[k] = f64::INFINITY;
                for &w in &s.wait_on[s.wait_start[k] as usize..s.wait_start[k + 1] as usize] {
                    let w = w as usize;
                    if self.done[w].is_nan() {
                        t = self.go(t, w);
                    }
                    t = t.max(self.done[w]);
                }
                self.done[k] = t + self.cost[k];
                self.done[k]
            }
        }
        let n_regions = self.region_start.len().saturating_sub(1);
        let mut sim = Sim { s: self, cost, done: vec![f64::NAN; cost.len()] };
        // Each thread's time and what is left of its region's chunks; the thread whose time
        // comes first decides next (takes its next chunk, or the next region), so that a
        // chunk is found taken when a thread earlier in time took it.
        let n = threads.max(1);
        let (mut time, mut todo, mut next_region) = (vec![0.0f64; n], vec![std::collections::VecDeque::<u32>::new(); n], 0);
        let mut live = vec![true; n];
        while let Some(th) = (0..n).filter(|&i| live[i]).reduce(|a, b| if time[b] < time[a] { b } else { a }) {
            let Some(k) = todo[th].pop_front() else {
                if next_region == n_regions {
                    live[th] = false;
                } else {
                    let r = next_region;
                    next_region += 1;
                    todo[th].extend(self.lead_of_region(r).iter().chain(self.interior_of(r)).chain(self.lead_of_region(r + 1)).chain(self.trailing_of(r)));
                }
                continue;
            };
            if sim.done[k as usize].is_nan() {
                time[th] = sim.go(time[th], k as usize);
            }
        }
        debug_assert!(!sim.done.iter().any(|d| d.is_nan() || d.is_infinite()), "every chunk ran");
        time.iter().copied().fold(0.0, f64::max)
    }

    pub fn n_chunks(&self) -> usize {
        self.colours.iter().map(Vec::len).sum()
    }

    /// The force pass as a task graph (issue 42): one task per chunk, of cost `cost[k]`,
    /// waiting for `wait_on`'s chunks (the dependency structure of every run, whatever the
    /// threads).
    pub fn task_graph(&self, cost: &[f64]) -> TaskGraph {
        assert_eq!(cost.len(), self.n_chunks(), "one cost per chunk");
        TaskGraph { cost: cost.to_vec(), pred_start: self.wait_start.clone(), pred: self.wait_on.clone() }
    }

    /// Each chunk's position in the sequence (`lead` then `rest`): the priority of the list
    /// schedule that follows the sequence.
    pub fn sequence_rank(&self) -> Vec<u32> {
        let mut rank = vec![0u32; self.n_chunks()];
        for (i, &k) in self.lead.iter().chain(&self.rest).enumerate() {
            rank[k as usize] = i as u32;
        }
        rank
    }

    /// The makespan of [`Self::run_dataflow`] on `threads` threads when chunk `k` takes
    /// `cost[k]` and nothing else costs time (a model, issue 42): the free thread that comes
    /// first takes the next lead chunk, then, once every lead chunk is taken, the next whole
    /// region; a chunk starts when its thread is free and its waits are done.
    pub fn simulate_dataflow(&self, cost: &[f64], threads: usize) -> f64 {
        assert_eq!(cost.len(), self.n_chunks(), "one cost per chunk");
        let mut done = vec![f64::NAN; cost.len()];
        let mut free = vec![0.0f64; threads.max(1)];
        let mut one = |t: f64, k: u32| {
            let k = k as usize;
            let start = self.wait_on[self.wait_start[k] as usize..self.wait_start[k + 1] as usize].iter().map(|&w| done[w as usize]).fold(t, f64::max);
            debug_assert!(!start.is_nan(), "a chunk waits for one not yet taken");
            done[k] = start + cost[k];
            done[k]
        };
        let first_free = |free: &[f64]| (0..free.len()).reduce(|a, b| if free[b] < free[a] { b } else { a }).unwrap_or(0);
        for &k in &self.lead {
            let th = first_free(&free);
            free[th] = one(free[th], k);
        }
        for r in 0..self.region_start.len().saturating_sub(1) {
            let th = first_free(&free);
            for &k in &self.rest[self.region_start[r] as usize..self.region_start[r + 1] as usize] {
                free[th] = one(free[th], k);
            }
        }
        free.iter().copied().fold(0.0, f64::max)
    }
}

/// A raw view of the force array shared by the chunks that run at the same time.
///
/// Safety argument (why not a safe split): the clusters written by one chunk are scattered over
/// the whole array, so no slice split separates them. No two threads touch the same element of
/// the array at the same time: chunks running at the same time write disjoint clusters. With
/// the colours (the stateful blocks), they belong to one colour (`Schedule::build`). Under the
/// dataflow (`Schedule::run_dataflow`) a chunk starts only when every chunk sharing a cluster
/// with it and before it in the schedule's sequence is done (its flag stored with Release
/// after its last write, loaded with Acquire before the first read), and the chunks after it
/// in the sequence wait for it likewise; every pair of chunks sharing a cluster is one of
/// these (`Schedule::wait_on` lists, for each chunk, every earlier chunk sharing a cluster).
/// `f` outlives every use (the colour loop and the dataflow's `install` join before returning).
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
    /// The address of `f[c]` (for a prefetch hint only; never dereferenced here).
    #[inline(always)]
    pub fn ptr_at(&self, c: usize) -> *const [f64; 2] {
        self.ptr.wrapping_add(c.min(self.len.saturating_sub(1)))
    }
    /// `f[c] += v`.
    ///
    /// # Safety
    /// No other thread may access `f[c]` during the call (guaranteed by the colouring or by the
    /// dataflow's waits).
    #[inline(always)]
    pub unsafe fn add(&self, c: usize, v: [f64; 2]) {
        assert!(c < self.len);
        // SAFETY: in bounds (checked), exclusive by the caller's contract.
        let x = unsafe { &mut *self.ptr.add(c) };
        x[0] += v[0];
        x[1] += v[1];
    }
    /// The length of the array.
    pub fn len(&self) -> usize {
        self.len
    }
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// `f[c] += v` without the bounds check (the caller has checked `c < self.len()`, e.g.
    /// once for a whole pack: `ElementBlock`'s chunk loop).
    ///
    /// # Safety
    /// As [`Self::add`], and `c < self.len()`.
    #[inline(always)]
    pub unsafe fn add_unchecked(&self, c: usize, v: [f64; 2]) {
        debug_assert!(c < self.len);
        // SAFETY: in bounds and exclusive by the caller's contract.
        let x = unsafe { &mut *self.ptr.add(c) };
        x[0] += v[0];
        x[1] += v[1];
    }
    /// `f[c] = 0` (the zero-free force pass: the pack of the cluster's first writer zeroes
    /// it, `ElementBlock`'s first writers).
    ///
    /// # Safety
    /// As [`Self::add`].
    #[inline(always)]
    pub unsafe fn zero(&self, c: usize) {
        assert!(c < self.len);
        // SAFETY: in bounds (checked), exclusive by the caller's contract.
        unsafe { *self.ptr.add(c) = [0.0; 2] };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chunk that panics while other threads wait for it: the panic reaches the caller and
    /// nothing hangs (before the poison flag, the waiting thread spun for ever). Two threads on
    /// a grid whose chunks wait on one another; the panicking chunk is a lead chunk that later
    /// chunks wait for. Reference: `catch_unwind` returns `Err` within 60 s (the run is on its
    /// own thread: a hang fails the test instead of stalling the suite).
    #[test]
    fn a_panicking_chunk_does_not_hang_the_others() {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            panicking_chunk_run();
            let _ = tx.send(());
        });
        rx.recv_timeout(std::time::Duration::from_secs(60)).expect("the dataflow hung after a chunk panicked");
    }

    fn panicking_chunk_run() {
        let (conn, n) = grid(300, 150);
        let s = Schedule::build(&conn, n);
        let done: Vec<std::sync::atomic::AtomicU32> = (0..s.n_chunks()).map(|_| std::sync::atomic::AtomicU32::new(0)).collect();
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let bad = s.lead[0] as usize;
        assert!(s.wait_on.contains(&(bad as u32)), "some chunk waits for the panicking one");
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            s.run_dataflow(&pool, &done, 1, |k| {
                if k == bad {
                    panic!("chunk {k} fails");
                }
            })
        }));
        assert!(r.is_err(), "the chunk's panic reaches the caller");
        // The pool still works afterwards.
        s.run_dataflow(&pool, &done, 2, |_| {});
        assert!(done.iter().all(|d| d.load(std::sync::atomic::Ordering::Relaxed) == 2));
        // The same with the local dataflow (its lead chunks are offered region by region).
        let taken: Vec<std::sync::atomic::AtomicU32> = (0..s.n_chunks()).map(|_| std::sync::atomic::AtomicU32::new(0)).collect();
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            s.run_dataflow_local(&pool, &done, &taken, 3, |k| {
                if k == bad {
                    panic!("chunk {k} fails");
                }
            })
        }));
        assert!(r.is_err(), "the chunk's panic reaches the caller (local)");
        s.run_dataflow_local(&pool, &done, &taken, 4, |_| {});
        assert!(done.iter().all(|d| d.load(std::sync::atomic::Ordering::Relaxed) == 4));
    }

    /// A structured `nx` x `ny` grid of quads, row by row.
    fn grid(nx: u32, ny: u32) -> (Vec<[u32; 4]>, usize) {
        let id = move |i: u32, j: u32| j * (nx + 1) + i;
        let conn = (0..ny).flat_map(|j| (0..nx).map(move |i| [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)])).collect();
        (conn, ((nx + 1) * (ny + 1)) as usize)
    }

    /// The grid with its elements shuffled (a fixed pseudo-random permutation): chunks share
    /// clusters with chunks of far regions, many chunks are lead and would also be trailing.
    fn shuffled(nx: u32, ny: u32) -> (Vec<[u32; 4]>, usize) {
        let (mut conn, n) = grid(nx, ny);
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for i in (1..conn.len()).rev() {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            conn.swap(i, (x % (i as u64 + 1)) as usize);
        }
        (conn, n)
    }

    /// For every cluster, the chunks touching it in the order they run in `seq`.
    fn per_cluster(conn: &[[u32; 4]], n: usize, ce: usize, seq: &[u32]) -> Vec<Vec<u32>> {
        let mut seen: Vec<Vec<u32>> = vec![Vec::new(); n];
        for &k in seq {
            for e in conn.chunks(ce).nth(k as usize).unwrap() {
                for &c in e {
                    if seen[c as usize].last() != Some(&k) {
                        seen[c as usize].push(k);
                    }
                }
            }
        }
        seen
    }

    /// Chunks of one colour share no cluster; every chunk has one colour (the stateful
    /// blocks' path).
    #[test]
    fn colouring_separates_chunks() {
        let (conn, n) = grid(100, 60);
        let s = Schedule::build(&conn, n);
        let ce = s.chunk_packs * LANES;
        assert_eq!(s.n_chunks(), conn.len().div_ceil(ce));
        assert!(s.colours.len() > 1, "a grid this size needs more than one colour");
        let mut all: Vec<u32> = s.colours.iter().flatten().copied().collect();
        all.sort_unstable();
        assert_eq!(all, (0..s.n_chunks() as u32).collect::<Vec<_>>());
        for col in &s.colours {
            let mut owner = vec![u32::MAX; n];
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

    /// The sequence (`lead` then `rest`) and the waits: of two chunks sharing a cluster, the
    /// later in the sequence waits for the earlier, and no chunk waits for one it shares
    /// nothing with; a lead chunk waits only for earlier lead chunks, any other chunk only for
    /// lead chunks and its own region's earlier chunks (what `run_dataflow`'s progress
    /// argument needs); the one-thread `order` keeps every wait. On a row-by-row grid (the
    /// lead chunks of a region follow the previous region), a shuffled one (chunks sharing
    /// clusters with far regions), a grid of 4 rows each about a region long (chunks sharing
    /// clusters with both neighbouring regions) and a one-chunk block.
    #[test]
    fn sequence_and_waits_fix_every_shared_cluster() {
        for (name, (conn, n)) in [("grid", grid(300, 150)), ("shuffled", shuffled(120, 90)), ("thin", grid(4000, 4)), ("tiny", grid(5, 3))] {
            let s = Schedule::build(&conn, n);
            let (ce, nc) = (s.chunk_packs * LANES, s.n_chunks());
            let seq: Vec<u32> = s.lead.iter().chain(&s.rest).copied().collect();
            let mut sorted = seq.clone();
            sorted.sort_unstable();
            assert_eq!(sorted, (0..nc as u32).collect::<Vec<_>>(), "{name}: the sequence runs every chunk once");
            let mut sorted = s.order.clone();
            sorted.sort_unstable();
            assert_eq!(sorted, (0..nc as u32).collect::<Vec<_>>(), "{name}: the order runs every chunk once");
            let mut pos = vec![0usize; nc];
            seq.iter().enumerate().for_each(|(i, &k)| pos[k as usize] = i);
            let waits = |k: usize| &s.wait_on[s.wait_start[k] as usize..s.wait_start[k + 1] as usize];
            // Pairs sharing a cluster.
            let mut share = vec![vec![false; nc]; nc];
            for v in per_cluster(&conn, n, ce, &(0..nc as u32).collect::<Vec<_>>()) {
                for &a in &v {
                    for &b in &v {
                        share[a as usize][b as usize] |= a != b;
                    }
                }
            }
            for a in 0..nc {
                for b in 0..nc {
                    let waits_ab = waits(a).contains(&(b as u32));
                    assert_eq!(waits_ab, share[a][b] && pos[b] < pos[a], "{name}: chunk {a} waits for {b}: {waits_ab}");
                }
            }
            let region_of = |k: u32| (0..s.region_start.len() - 1).find(|&r| s.rest[s.region_start[r] as usize..s.region_start[r + 1] as usize].contains(&k));
            for (i, &k) in seq.iter().enumerate() {
                for &w in waits(k as usize) {
                    if i < s.lead.len() {
                        assert!(pos[w as usize] < i, "{name}: lead chunk {k} waits for {w}, not an earlier lead chunk");
                    } else {
                        assert!(pos[w as usize] < s.lead.len() || region_of(w) == region_of(k), "{name}: chunk {k} waits for {w} of another region");
                    }
                }
            }
            let mut at = vec![0usize; nc];
            s.order.iter().enumerate().for_each(|(i, &k)| at[k as usize] = i);
            for k in 0..nc {
                assert!(waits(k).iter().all(|&w| at[w as usize] < at[k]), "{name}: the one-thread order runs {k} before a chunk it waits for");
            }
            // The local dataflow's tables: the lead chunks by region (the same set as `lead`,
            // each in its region's chunk range), the interior chunks before `trail_start`
            // sharing no cluster with another region, and the longest chain of waits.
            let n_regions = s.region_start.len() - 1;
            let mut by_region = s.lead_local.clone();
            by_region.sort_unstable();
            let mut lead = s.lead.clone();
            lead.sort_unstable();
            assert_eq!(by_region, lead, "{name}: lead_local holds the lead chunks");
            assert_eq!((s.lead_local_start.len(), s.trail_start.len()), (n_regions + 1, n_regions));
            let mut next = 0u32;
            for r in 0..n_regions {
                // Region r is a range of consecutive chunks: its lead chunks and its others.
                let mut mine: Vec<u32> = s.lead_of_region(r).to_vec();
                mine.extend_from_slice(&s.rest[s.region_start[r] as usize..s.region_start[r + 1] as usize]);
                mine.sort_unstable();
                assert!(mine.iter().copied().eq(next..next + mine.len() as u32), "{name}: region {r} is chunks {next}.. ({mine:?})");
                next += mine.len() as u32;
                for &k in s.interior_of(r) {
                    let in_r = |o: u32| region_of(o) == Some(r) || s.lead_of_region(r).contains(&o);
                    assert!((0..nc).all(|o| !share[k as usize][o] || in_r(o as u32)), "{name}: interior chunk {k} shares a cluster outside region {r}");
                }
            }
            let mut depth = vec![0u32; nc];
            for &k in &seq {
                depth[k as usize] = 1 + waits(k as usize).iter().map(|&w| depth[w as usize]).max().unwrap_or(0);
            }
            assert_eq!(s.chain, depth.iter().copied().max().unwrap(), "{name}: the longest chain");
            if name == "grid" {
                assert!(s.region_start.len() > 4 && !s.lead.is_empty(), "{name}: several regions with lead chunks");
                assert!(s.lead.len() * 5 < nc, "{name}: few lead chunks on a row-by-row grid ({} of {nc})", s.lead.len());
            }
            if name == "shuffled" {
                assert!(s.lead.len() * 2 > nc, "{name}: most chunks are lead chunks here ({} of {nc})", s.lead.len());
            }
        }
    }

    /// `run_dataflow` on pools of 1 to 4 threads: every cluster receives its chunks in the
    /// same order as with the one-thread `order` (so the same sums bit for bit), and what each
    /// thread ran is in an order that keeps the waits. Two calls per pool (the epochs). On the
    /// grids of `sequence_and_waits_fix_every_shared_cluster` and the 1e6-element bench grid.
    #[test]
    fn dataflow_keeps_the_per_cluster_order_on_every_thread_count() {
        // On its own thread: a dataflow that hangs fails the test instead of stalling the suite.
        let (tx, rx) = std::sync::mpsc::channel();
        let h = std::thread::spawn(move || {
            dataflow_order_runs();
            let _ = tx.send(());
        });
        if rx.recv_timeout(std::time::Duration::from_secs(300)).is_err() {
            // The thread panicked (join re-raises it) or hung.
            if h.is_finished() {
                if let Err(e) = h.join() {
                    std::panic::resume_unwind(e);
                }
            }
            panic!("the dataflow hung");
        }
    }

    fn dataflow_order_runs() {
        use std::sync::atomic::AtomicU32;
        use std::sync::Mutex;
        // "bench": the 1e6-element grid of `flem bench step`, 122 regions (more than 64, the
        // cap before issue 42).
        for (name, (conn, n)) in [("grid", grid(300, 150)), ("shuffled", shuffled(120, 90)), ("thin", grid(4000, 4)), ("bench", grid(1414, 707))] {
            let s = Schedule::build(&conn, n);
            let (ce, nc) = (s.chunk_packs * LANES, s.n_chunks());
            assert!(name != "bench" || s.region_start.len() - 1 > 64, "{name}: more than 64 regions");
            let want = per_cluster(&conn, n, ce, &s.order);
            for threads in 1..=4 {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let done: Vec<AtomicU32> = (0..nc).map(|_| AtomicU32::new(0)).collect();
                let taken: Vec<AtomicU32> = (0..nc).map(|_| AtomicU32::new(0)).collect();
                // Epochs 1 and 2: `run_dataflow`; 3 and 4: `run_dataflow_local`.
                for epoch in 1..=4 {
                    // Chunks sharing a cluster never overlap, so the start order gives each
                    // cluster's order; the thread of each chunk gives each thread's order.
                    // Each chunk logs its start and its end: two chunks sharing a cluster must
                    // not overlap (the earlier one ends before the later one starts).
                    let events = Mutex::new(Vec::new());
                    let log = Mutex::new(Vec::new());
                    let run = |k: usize| {
                        events.lock().unwrap().push((k, false));
                        log.lock().unwrap().push((k as u32, rayon::current_thread_index().unwrap()));
                        std::hint::black_box((0..50).sum::<u64>());
                        events.lock().unwrap().push((k, true));
                    };
                    if epoch <= 2 {
                        s.run_dataflow(&pool, &done, epoch, run);
                    } else {
                        s.run_dataflow_local(&pool, &done, &taken, epoch, run);
                    }
                    let events = events.into_inner().unwrap();
                    let (mut start, mut end) = (vec![usize::MAX; nc], vec![usize::MAX; nc]);
                    for (i, &(k, e)) in events.iter().enumerate() {
                        if e {
                            end[k] = i;
                        } else {
                            start[k] = i;
                        }
                    }
                    for order in &want {
                        for w in order.windows(2) {
                            assert!(end[w[0] as usize] < start[w[1] as usize], "{name}, {threads} threads, epoch {epoch}: chunks {} and {} share a cluster and overlap", w[0], w[1]);
                        }
                    }
                    let log = log.into_inner().unwrap();
                    let mut once = log.iter().map(|x| x.0).collect::<Vec<_>>();
                    once.sort_unstable();
                    assert!(once.iter().copied().eq(0..nc as u32), "{name}, {threads} threads, epoch {epoch}: every chunk once");
                    let ran: Vec<u32> = log.iter().map(|x| x.0).collect();
                    assert_eq!(per_cluster(&conn, n, ce, &ran), want, "{name}, {threads} threads: a cluster receives its chunks in another order");
                    for t in 0..threads {
                        let mine: Vec<u32> = log.iter().filter(|x| x.1 == t).map(|x| x.0).collect();
                        let mut at = vec![usize::MAX; nc];
                        mine.iter().enumerate().for_each(|(i, &k)| at[k as usize] = i);
                        for &k in &mine {
                            for &w in &s.wait_on[s.wait_start[k as usize] as usize..s.wait_start[k as usize + 1] as usize] {
                                assert!(at[w as usize] == usize::MAX || at[w as usize] < at[k as usize], "{name}: thread {t} ran {k} before {w}");
                            }
                        }
                    }
                }
            }
        }
    }

    /// The force pass's task graph on the 1e6-element grid of `flem bench step` (1414 x 707
    /// Q4: 1953 chunks), every chunk of cost 1 (a model, not a timing; issue 42). Regions of
    /// about 16 chunks (122; before issue 42 at most 64, which held the parallelism at 63):
    /// the critical path is the lead chunks of one region (a row of the grid is 2.8 chunks, so
    /// 3 of them, each sharing the column of nodes at its end with the next), then that
    /// region's other chunks in sequence (each shares nodes with the one before it): 3 + 14 =
    /// 17 chunks, all of one region; parallelism 1953 / 17 = 114.9 > 64. The `run_dataflow`
    /// model finishes within 10 % of the list schedule and of the bound max(W / p, D).
    #[test]
    fn bench_grid_parallelism_exceeds_64() {
        let (conn, n) = grid(1414, 707);
        let s = Schedule::build(&conn, n);
        let nc = s.n_chunks();
        assert_eq!((nc, s.region_start.len() - 1), (1953, 122));
        let unit = vec![1.0; nc];
        let g = s.task_graph(&unit);
        let cp = g.critical_path();
        assert_eq!(cp.length, 17.0);
        // With unit costs the critical path is the longest chain of waits (`element::dag`'s
        // own computation): the local dataflow's recursion bound.
        assert_eq!(s.chain, 17, "the longest chain of waits");
        assert_eq!(g.parallelism(), 1953.0 / 17.0);
        let lead_on_path: Vec<u32> = cp.tasks.iter().copied().filter(|k| s.lead.contains(k)).collect();
        assert_eq!(lead_on_path.len(), 3, "{cp:?}");
        assert!(cp.tasks[..3] == lead_on_path[..], "the lead chunks come first on the path: {cp:?}");
        let r = (0..s.region_start.len() - 1).find(|&r| s.rest[s.region_start[r] as usize..s.region_start[r + 1] as usize].contains(&cp.tasks[3])).unwrap();
        let region = &s.rest[s.region_start[r] as usize..s.region_start[r + 1] as usize];
        assert_eq!(&cp.tasks[3..], region, "the rest of the path is one region's other chunks, in sequence");
        let rank = s.sequence_rank();
        for p in [1usize, 2, 4, 16, 64] {
            let bound = (nc as f64 / p as f64).max(17.0);
            let (list, flow, local) = (g.list_schedule(p, &rank), s.simulate_dataflow(&unit, p), s.simulate_dataflow_local(&unit, p));
            assert!(list >= bound && list <= 1.1 * bound, "{p} threads: list schedule {list}, bound {bound}");
            assert!(flow >= bound && flow <= 1.1 * bound, "{p} threads: dataflow model {flow}, bound {bound}");
            assert!(local >= bound && local <= 1.1 * bound, "{p} threads: local dataflow model {local}, bound {bound}");
        }
        assert_eq!(s.simulate_dataflow(&unit, 1), nc as f64, "one thread: the work");
        assert_eq!(s.simulate_dataflow_local(&unit, 1), nc as f64, "one thread: the work (local)");
    }

    /// `simulate_dataflow` by hand, on a schedule written out: chunks 0 and 1 form region 0
    /// (no shared cluster), chunk 2 is lead, chunk 3 (region 1) waits for it; costs 2, 2, 1, 1.
    /// Two threads: thread 0 takes lead chunk 2 (0 to 1), thread 1 region 0 (0 to 2, 2 to 4),
    /// thread 0 region 1 (1 to 2): makespan 4. The list schedule of the same graph (sequence
    /// priority 2, 0, 1, 3) runs 0 and 1 on two threads: 2 (0-1) and 0 (0-2), 1 (1-3), 3 (2-3):
    /// 3. One thread: 6 both.
    #[test]
    fn dataflow_model_by_hand() {
        let s = Schedule {
            chunk_packs: 1,
            colours: vec![vec![0, 1, 2, 3]],
            order: vec![0, 1, 2, 3],
            lead: vec![2],
            region_start: vec![0, 2, 3],
            rest: vec![0, 1, 3],
            wait_start: vec![0, 0, 0, 0, 1],
            wait_on: vec![2],
            lead_local: vec![2],
            lead_local_start: vec![0, 0, 1],
            trail_start: vec![2, 3],
            chain: 2,
        };
        let cost = [2.0, 2.0, 1.0, 1.0];
        assert_eq!(s.sequence_rank(), vec![1, 2, 0, 3]);
        assert_eq!(s.simulate_dataflow(&cost, 2), 4.0);
        assert_eq!(s.simulate_dataflow(&cost, 1), 6.0);
        // The local dataflow: thread 0 takes region 0 and runs chunk 0 (0 to 2); thread 1
        // region 1: its lead chunk 2 (0 to 1), then 3 (1 to 2); thread 0 runs 1 (2 to 4) and
        // finds chunk 2 (region 1's lead, offered after region 0's interior) taken: 4. One
        // thread: 0, 1, then 2 (offered as the next region's lead), then 3: 6.
        assert_eq!(s.simulate_dataflow_local(&cost, 2), 4.0);
        assert_eq!(s.simulate_dataflow_local(&cost, 1), 6.0);
        let g = s.task_graph(&cost);
        assert_eq!(g.list_schedule(2, &s.sequence_rank()), 3.0);
        assert_eq!(g.list_schedule(1, &s.sequence_rank()), 6.0);
        assert_eq!(g.critical_path().length, 2.0);
    }

    /// The schedule lets two threads work without waiting: on the 1e6-element grid of `flem
    /// bench step` (1414 x 707 Q4, 1953 chunks, 64 regions), two threads following
    /// `run_dataflow`'s rules (the lead chunks from one counter, then whole regions, a chunk
    /// starting when its waits are done), with every chunk taking one time unit, finish within
    /// 1 % of half the chunks, also when the second thread starts 10 units late. (Session 9's
    /// rule, both threads taking chunks one at a time from one (colour, index) order: 0.67 of
    /// that; docs/perf/README.md, session 10.) A model of the schedule, not a timing.
    #[test]
    fn two_threads_seldom_wait_on_the_bench_grid() {
        let (conn, n) = grid(1414, 707);
        let s = Schedule::build(&conn, n);
        let nc = s.n_chunks();
        assert!(s.region_start.len() > 32, "many regions");
        let waits = |k: u32| &s.wait_on[s.wait_start[k as usize] as usize..s.wait_start[k as usize + 1] as usize];
        for delay in [0.0, 10.0] {
            let mut done = vec![f64::NAN; nc];
            let mut t = [0.0f64, delay];
            let mut one = |th: usize, k: u32, t: &mut [f64; 2]| {
                let start = waits(k).iter().map(|&w| done[w as usize]).fold(t[th], f64::max);
                assert!(!start.is_nan(), "chunk {k} waits for a chunk not yet taken");
                done[k as usize] = start + 1.0;
                t[th] = start + 1.0;
            };
            for &k in &s.lead {
                let th = (t[1] < t[0]) as usize;
                one(th, k, &mut t);
            }
            for r in 0..s.region_start.len() - 1 {
                let th = (t[1] < t[0]) as usize;
                for &k in &s.rest[s.region_start[r] as usize..s.region_start[r + 1] as usize] {
                    one(th, k, &mut t);
                }
            }
            let ideal = (nc as f64 + delay) / 2.0;
            assert!(t[0].max(t[1]) <= 1.01 * ideal, "delay {delay}: two threads take {t:?} units for {nc} chunks");
        }
    }
}
