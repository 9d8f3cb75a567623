//! Element blocks: one element kind and one material per block, the kernel monomorphised
//! inside. The solver calls each block once per step through `dyn Block`; there is no dynamic
//! dispatch per element and no allocation inside a step.
//!
//! Kinds: any element kind implementing `kernel::Blocked` (the built-ins `q4`, `t3`, `qm6` are
//! plugins, `flem-plugins/src/elements/`); a block is generic over it and monomorphised per kind. Connectivity is by cluster index (`Block::conn`), so an unsplit
//! node costs what a plain FEM node costs. The force kernel and its parallel schedule live in
//! `element/kernel.rs`, the co-rotational block in `element/corot.rs`; `element/model.rs`
//! builds the blocks of a `Model`.
use std::marker::PhantomData;

use crate::element::kernel::{Blocked, Dataflow, Schedule, SharedForces, LANES};
use crate::element::{self, Dmat, Material};
use crate::ids::ElemId;
use crate::mesh::CellKind;

/// How far ahead the force pass prefetches, in packs (`ElementBlock::prefetch_ahead`; 4 to 16
/// measured alike at 1e6 Q4 elements, session 29).
const PREFETCH_PACKS: usize = 8;

/// A batch of elements of one kind and one material, seen by the solver.
pub trait Block: Send + Sync {
    fn kind(&self) -> CellKind;
    fn nodes_per_elem(&self) -> usize;
    fn len(&self) -> usize;
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    fn material(&self) -> &Material;
    fn region(&self) -> &str;
    /// Global element id of each local element.
    fn elems(&self) -> &[ElemId];
    /// Cluster index of each corner of local element `i`.
    fn conn(&self, i: usize) -> &[u32];
    /// Re-points corner `a` of local element `i` at `cluster` (after a split).
    fn remap(&mut self, i: usize, a: usize, cluster: u32);
    /// `f[c] += F_int` of every element, with `u` the cluster displacements.
    fn add_internal_forces(&self, u: &[[f64; 2]], f: &mut [[f64; 2]]);
    /// `f[c] += F_int` of every element with the blocked kernel, the chunks spread over `pool`
    /// when given; the result does not depend on the pool (see `kernel`).
    fn add_internal_forces_pool(&self, u: &[[f64; 2]], f: &mut [[f64; 2]], pool: Option<&rayon::ThreadPool>);
    /// Builds the blocked kernel data and the parallel schedule (after the last `push`).
    fn prepare(&mut self, n_clusters: usize);
    /// `f = F_int` of every element, every entry of `f` written (no zeroing sweep before:
    /// the zero-free force pass, issue 24 session 11), on `pool` when given; the same bits as
    /// zeroing `f` then `add_internal_forces_pool`. False, `f` untouched, when the block cannot
    /// (default; no [`Self::enable_zero_free`], or `f` is not as long as the clusters it
    /// planned for). Only a stateless block may return true: the model's step calls this
    /// instead of `update_internal_forces` (`Model::update_internal_forces`).
    fn set_internal_forces_pool(&self, _u: &[[f64; 2]], _f: &mut [[f64; 2]], _pool: Option<&rayon::ThreadPool>) -> bool {
        false
    }
    /// Plans the zero-free pass ([`Self::set_internal_forces_pool`]) over `n_clusters`
    /// clusters (after `prepare`; `Model::new` asks the block of a one-block model, and asks
    /// again after a split, `Model::apply_record`); false when the block has no zero-free pass
    /// (default).
    fn enable_zero_free(&mut self, _n_clusters: usize) -> bool {
        false
    }
    /// Whether [`Self::enable_zero_free`] planned the zero-free pass.
    fn zero_free(&self) -> bool {
        false
    }
    /// Bytes held by the block (geometry, connectivity, kernel data, schedule).
    fn memory_bytes(&self) -> usize;
    /// Bytes of the block's own data that one force pass streams (kernel packs and their
    /// extra parts, connectivity, schedule; `flem bench step`'s byte count). Default: all of
    /// `memory_bytes`.
    fn kernel_bytes(&self) -> usize {
        self.memory_bytes()
    }
    /// `f[c] += F_int` for the local elements in `range` only: for a linear block element by
    /// element with the reference kernel `Blocked::force_ref` (tests compare the blocked kernel
    /// with it); a co-rotational block runs its blocked pass here (`element::corot`).
    fn add_internal_forces_range(&self, range: std::ops::Range<usize>, u: &[[f64; 2]], f: &mut [[f64; 2]]);
    /// `m[c] += ` lumped mass of every element.
    fn add_mass(&self, m: &mut [f64]);
    /// Stress of every copy at its corner (0.9999-scaled natural coordinates), written at the
    /// copy's index `elem_first_copy[elem] + corner`.
    fn corner_stress(&self, u: &[[f64; 2]], elem_first_copy: &[u32], out: &mut [[f64; 3]]);
    /// `max_row sum_j |(A_k)_rj|` of every copy `k` of the block's elements, written at
    /// `elem_first_copy[elem] + corner`, where `A_k` (3 x 2N) maps the element's corner
    /// displacements to `corner_stress` at that corner (the certified skip's Lipschitz constant,
    /// `cracking::skip`). False when the block cannot say (the caller then probes
    /// `corner_stress` with unit displacements); the default.
    fn corner_lipschitz(&self, _elem_first_copy: &[u32], _out: &mut [f64]) -> bool {
        false
    }
    /// Stress at every Gauss point of every element (in `Shape::GAUSS` order), written at
    /// `first_gp[elem] + g`: the nonlocal failure check's input (`cracking::nonlocal`).
    fn gauss_stress(&self, u: &[[f64; 2]], first_gp: &[u32], out: &mut [[f64; 3]]);
    /// Stress at natural coordinate `xi` of local element `i`.
    fn stress_at(&self, i: usize, u: &[[f64; 2]], xi: [f64; 2]) -> [f64; 3];
    /// Average stress of local element `i` (over its Gauss points).
    fn mean_stress(&self, i: usize, u: &[[f64; 2]]) -> [f64; 3];
    /// Element stiffness of local element `i`, row-major (2N)^2.
    fn stiffness(&self, i: usize, k: &mut [f64]);
    /// Reference (initial) corner coordinates of local element `i`.
    fn coords(&self, i: usize) -> &[[f64; 2]];
    /// Upper bound of the highest natural frequency of each element (Gershgorin on M^-1/2 K M^-1/2).
    fn max_omega_bound(&self) -> f64;
    /// Strain energy of blocks whose forces are not linear in `u` (co-rotational,
    /// `crate::element::corot`); `None` for linear blocks, where the solver uses `1/2 u . F_int`.
    fn strain_energy(&self, _u: &[[f64; 2]]) -> Option<f64> {
        None
    }
    /// Gives local element `i` the corner coordinates `x` in place (a node moved by the path
    /// method, `Model::move_point`): its kernel pack, its cached gradients and recovery data
    /// are recomputed, nothing else (the connectivity and so the schedule are unchanged). The
    /// block is then bit for bit the one a rebuild from the mesh would give. False: the block
    /// cannot (the caller rebuilds it).
    fn move_elem(&mut self, _i: usize, _x: &[[f64; 2]]) -> bool {
        false
    }
    /// Registered name of the element kind (`element::registry`; default: the cell type's
    /// default kind).
    fn element(&self) -> &'static str {
        element::default_kind(self.kind())
    }
    /// True when the element stiffness is the plain isoparametric `sum_gp B^T D B w det J t` of
    /// the shape gradients (a solver may then assemble it itself); false for an element with
    /// internal fields, whose stiffness only `stiffness` gives.
    fn isoparametric(&self) -> bool {
        true
    }
    /// Which dataflow the block's force pass runs on several threads
    /// (`element::kernel::Dataflow`; the same bits with either; `Local` also turns on the
    /// pass's prefetch, which is otherwise on beyond the last-level cache only). Ignored by a
    /// block that does not run the dataflow (the default).
    fn set_dataflow(&mut self, _d: Dataflow) {}
    /// Whether the force pass on several threads runs the local dataflow with `n_clusters`
    /// clusters (false for a block too small to run any dataflow; `None` for a block that runs
    /// no dataflow, the default).
    fn dataflow_local(&self, _n_clusters: usize) -> Option<bool> {
        None
    }
    /// The force pass's schedule and the cost of each of its chunks on one thread (seconds,
    /// the least of `passes` passes in the one-thread order: on a shared machine the least
    /// disturbed; `flem bench step`'s task graph, issue 42). `None` for a block that does not
    /// run the dataflow (the default).
    fn chunk_costs(&self, _u: &[[f64; 2]], _passes: usize) -> Option<(crate::element::kernel::Schedule, Vec<f64>)> {
        None
    }
    /// Stress update + internal forces for the step (stateful laws commit their
    /// integration-point state here). Default: the stateless linear path.
    fn update_internal_forces(&mut self, u: &[[f64; 2]], f: &mut [[f64; 2]], pool: Option<&rayon::ThreadPool>) {
        self.add_internal_forces_pool(u, f, pool)
    }
    /// f64 of history the block keeps (stateful blocks, `element::stateful`); 0 when stateless.
    fn state_len(&self) -> usize {
        0
    }
    /// Appends the block's history (`state_len` values) for a checkpoint.
    fn save_state(&self, _out: &mut Vec<f64>) {}
    /// Restores the history written by `save_state`; false when the length does not match.
    fn load_state(&mut self, s: &[f64]) -> bool {
        s.is_empty()
    }
    /// `(plastic shear strain, plastic state)` of local element `i` (mean over its points;
    /// state 0 never, 1 now, 2 in the past), `None` for blocks without a plastic law.
    fn plastic(&self, _i: usize) -> Option<(f64, u8)> {
        None
    }
    /// The stress `[sxx, syy, sxy, szz]` of every Gauss point at displacements `u`, for
    /// stateful blocks (a point never yielded is computed from `u`, `element::stateful`).
    fn point_stress(&self, _u: &[[f64; 2]]) -> Option<Vec<[f64; 4]>> {
        None
    }
    /// The block as the implicit plastic check's Newton solver sees it
    /// (`element::implicit`): `None` for a stateless block (its stiffness is the whole story:
    /// [`crate::element::implicit::Linear`]), `Some(Err(why))` for a block the check cannot
    /// follow (large strain, incompatible modes).
    fn implicit(&self) -> Option<Result<Box<dyn crate::element::implicit::ImplicitBlock>, String>> {
        None
    }
    /// An error of the block's material law (a dynamic law that failed or returned a
    /// non-finite stress; issue 25): the solver reports it instead of a bare divergence.
    fn fault(&self) -> Option<String> {
        None
    }
}

/// The chunk loop of an element block (`ElementBlock::chunk_fn`).
pub type ChunkFn<B> = fn(&B, usize, &[[f64; 2]], SharedForces);

/// The first writers of the zero-free force pass (issue 24, session 11).
///
/// The schedule fixes, from the mesh only, the order in which each cluster receives its
/// contributions: chunks in the schedule's sequence (`lead` then `rest`), inside a chunk the
/// packs and their elements in local order (`kernel`). So the pack holding the first
/// contribution of each cluster is known before any pass. That pack zeroes the cluster's
/// entry just before it computes (the cache line is then fetched while the pack computes, and
/// the scatter's add finds it in cache), every contribution adds as before: exactly zeroing
/// then adding, bit for bit, with no sweep over the whole array before the pass (at 1e6 Q4
/// elements the sweep wrote 16 MB per pass, about 0.9 ns of the 8-12 ns an element-update
/// takes; docs/perf/README.md). The clusters no corner names (a point of no element of the
/// block; usually none) are zeroed from a list before the pass. (A first design let the first
/// writer store through a per-lane bit mask: branch-free, but about 20 more instructions per
/// element, and the one-thread kernel lost 7 %; docs/perf/README.md, session 11.)
#[derive(Clone, Debug, Default)]
struct FirstWriters {
    /// Planned (`enable_zero_free`).
    on: bool,
    /// A corner was re-pointed (`remap`) and the first writers not yet rebuilt
    /// (`enable_zero_free`): the pass falls back to zeroing then adding.
    stale: bool,
    /// Per cluster, the pack of its first writer; `u32::MAX` when no corner names it.
    pack_of: Vec<u32>,
    /// The clusters pack `p` writes first: `ids[start[p]..start[p + 1]]`.
    start: Vec<u32>,
    ids: Vec<u32>,
    /// The clusters no corner of the block names.
    untouched: Vec<u32>,
}

impl FirstWriters {
    /// The per-pack lists and the untouched list from `pack_of` (a counting sort).
    fn from_pack_of(pack_of: Vec<u32>, n_packs: usize) -> Self {
        let mut start = vec![0u32; n_packs + 1];
        for &p in pack_of.iter().filter(|&&p| p != u32::MAX) {
            start[p as usize + 1] += 1;
        }
        for p in 0..n_packs {
            start[p + 1] += start[p];
        }
        let mut fill = start.clone();
        let mut ids = vec![0u32; start[n_packs] as usize];
        let mut untouched = Vec::new();
        for (c, &p) in pack_of.iter().enumerate() {
            if p == u32::MAX {
                untouched.push(c as u32);
            } else {
                ids[fill[p as usize] as usize] = c as u32;
                fill[p as usize] += 1;
            }
        }
        FirstWriters { on: true, stale: false, pack_of, start, ids, untouched }
    }
}

/// The instruction sets the chunk loop is compiled for (`ElementBlock::chunk_fn`), narrowest
/// first.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Simd {
    Plain,
    Avx2,
    Avx512,
}

impl Simd {
    /// Whether this CPU runs `self`.
    pub fn detected(self) -> bool {
        match self {
            Simd::Plain => true,
            #[cfg(target_arch = "x86_64")]
            Simd::Avx2 => std::arch::is_x86_feature_detected!("avx2"),
            #[cfg(target_arch = "x86_64")]
            Simd::Avx512 => std::arch::is_x86_feature_detected!("avx512f") && std::arch::is_x86_feature_detected!("avx512vl") && std::arch::is_x86_feature_detected!("avx512dq"),
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }
    /// The widest set this CPU runs, at most the cap of `FLEM_SIMD` (`plain`, `avx2`;
    /// default: none; for measurements); decided once per process.
    pub fn best() -> Simd {
        static BEST: std::sync::OnceLock<Simd> = std::sync::OnceLock::new();
        *BEST.get_or_init(|| {
            let cap = match std::env::var("FLEM_SIMD").as_deref() {
                Ok("plain") => 1,
                Ok("avx2") => 2,
                _ => 3,
            };
            [Simd::Plain, Simd::Avx2, Simd::Avx512][..cap].iter().rev().copied().find(|s| s.detected()).unwrap_or(Simd::Plain)
        })
    }
}

/// Blocks smaller than this run on the calling thread (waking the pool costs more than it
/// saves; the result is the same either way).
const PAR_MIN_ELEMS: usize = 4096;

pub struct ElementBlock<S: Blocked<N>, const N: usize> {
    pub region: String,
    pub mat: Material,
    pub d: Dmat,
    pub elems: Vec<ElemId>,
    pub x: Vec<[[f64; 2]; N]>,
    pub conn: Vec<[u32; N]>,
    /// Blocked kernel data, one pack per `LANES` elements (built by `prepare`).
    packs: Vec<S::Pack>,
    /// The extra parts of the packs that need one (`Blocked::extra`), in pack order.
    extra: Vec<S::Extra>,
    /// Per pack, the index of its extra part in `extra`, `u32::MAX` for none.
    extra_of: Vec<u32>,
    /// The last epoch and the threads' chunk flags: done (`Schedule::run_dataflow` and
    /// `run_dataflow_local`) and taken (`run_dataflow_local`'s lead chunks); a call that finds
    /// them in use (another thread in the same block) runs on its own thread instead.
    dataflow: std::sync::Mutex<(u32, Vec<std::sync::atomic::AtomicU32>, Vec<std::sync::atomic::AtomicU32>)>,
    /// Which dataflow the threads run (`Block::set_dataflow`; the same bits with either).
    dataflow_mode: Dataflow,
    /// D with thickness and Gauss weight folded in.
    dk: [f64; 3],
    sched: Schedule,
    /// The zero-free pass's first writers (`set_internal_forces_pool`; empty until
    /// `enable_zero_free`).
    fw: FirstWriters,
    /// Shape-function gradients at each corner's stress point, built at the first failure
    /// check (a scene that never checks does not pay its 8 N^2 doubles per element).
    corner_g: std::sync::OnceLock<Vec<[[[f64; 2]; N]; N]>>,
    /// Shape-function gradients at each Gauss point, built at the first nonlocal check.
    gauss_g: std::sync::OnceLock<Vec<[[f64; 2]; N]>>,
    /// `max_omega_bound` (asked again at every new stable-step estimate, after splits).
    omega_bound: std::sync::OnceLock<f64>,
    /// Each element's largest Gershgorin row sum (`omega_bound` is the square root of their
    /// maximum): kept so that a moved element (`move_elem`) costs one element, not the block.
    omega_elem: std::sync::OnceLock<Vec<f64>>,
    /// `Blocked::recovery` of every element (`S::RECOVERY_LEN` f64 each; empty for an
    /// isoparametric kind), built at the first stress request.
    recovery: std::sync::OnceLock<Vec<f64>>,
    _s: PhantomData<S>,
}

/// The displacements of a full pack's corners into its lanes (`ug[a][dim][lane]`), for AVX-512:
/// each corner's 8 `[ux, uy]` pairs loaded whole (16 bytes) into two registers, then split into
/// x and y by two permutes, instead of 16 scalar loads and 16 inserts per corner (issue 42: in
/// the Q4 kernel those inserts took a fifth of the FP ports' work). A copy of the same values
/// (no arithmetic): the forces are the same bit for bit.
///
/// # Safety
/// The CPU has AVX-512 F and DQ; `conn` holds `LANES` elements whose clusters index `u`. Call it
/// only from a function compiled for AVX-512 (`run_chunk_avx512`), into which it is inlined
/// (a function with `target_feature` cannot be `inline(always)`).
// `gather_pack_avx512` fills 8 lanes with one 512-bit store per corner and coordinate.
const _: () = assert!(LANES == 8);

#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn gather_pack_avx512<const N: usize>(u: &[[f64; 2]], conn: &[[u32; N]], ug: &mut [[[f64; LANES]; 2]; N]) {
    use std::arch::x86_64::*;
    debug_assert_eq!(conn.len(), LANES);
    let base = u.as_ptr() as *const f64;
    let ix = _mm512_setr_epi64(0, 2, 4, 6, 8, 10, 12, 14);
    let iy = _mm512_setr_epi64(1, 3, 5, 7, 9, 11, 13, 15);
    for a in 0..N {
        // SAFETY (all loads): the caller's contract, clusters in bounds of `u`.
        let (c0, c1, c2, c3) = (conn[0][a], conn[1][a], conn[2][a], conn[3][a]);
        let (c4, c5, c6, c7) = (conn[4][a], conn[5][a], conn[6][a], conn[7][a]);
        let lo = unsafe {
            let v = _mm512_castpd128_pd512(_mm_loadu_pd(base.add(2 * c0 as usize)));
            let v = _mm512_insertf64x2::<1>(v, _mm_loadu_pd(base.add(2 * c1 as usize)));
            let v = _mm512_insertf64x2::<2>(v, _mm_loadu_pd(base.add(2 * c2 as usize)));
            _mm512_insertf64x2::<3>(v, _mm_loadu_pd(base.add(2 * c3 as usize)))
        };
        let hi = unsafe {
            let v = _mm512_castpd128_pd512(_mm_loadu_pd(base.add(2 * c4 as usize)));
            let v = _mm512_insertf64x2::<1>(v, _mm_loadu_pd(base.add(2 * c5 as usize)));
            let v = _mm512_insertf64x2::<2>(v, _mm_loadu_pd(base.add(2 * c6 as usize)));
            _mm512_insertf64x2::<3>(v, _mm_loadu_pd(base.add(2 * c7 as usize)))
        };
        // SAFETY: `ug[a][d]` is 8 f64.
        unsafe {
            _mm512_storeu_pd(ug[a][0].as_mut_ptr(), _mm512_permutex2var_pd(lo, ix, hi));
            _mm512_storeu_pd(ug[a][1].as_mut_ptr(), _mm512_permutex2var_pd(lo, iy, hi));
        }
    }
}

impl<S: Blocked<N>, const N: usize> ElementBlock<S, N> {
    pub fn new(region: String, mat: Material) -> Self {
        let d = mat.dmat();
        ElementBlock {
            region,
            d,
            dk: S::scaled_d(&d, mat.thickness),
            mat,
            elems: Vec::new(),
            x: Vec::new(),
            conn: Vec::new(),
            packs: Vec::new(),
            extra: Vec::new(),
            extra_of: Vec::new(),
            dataflow: std::sync::Mutex::new((0, Vec::new(), Vec::new())),
            dataflow_mode: Dataflow::default(),
            sched: Schedule::default(),
            fw: FirstWriters::default(),
            corner_g: std::sync::OnceLock::new(),
            gauss_g: std::sync::OnceLock::new(),
            omega_bound: std::sync::OnceLock::new(),
            omega_elem: std::sync::OnceLock::new(),
            recovery: std::sync::OnceLock::new(),
            _s: PhantomData,
        }
    }

    /// Forces of the elements of chunk `k`: gather a pack, compute, scatter in element order.
    /// `ZERO`: the zero-free pass (each pack first zeroes the clusters it writes first,
    /// `FirstWriters`).
    /// `PF`: with [`Self::prefetch_ahead`] (a pass beyond the cache, [`Self::prefetches`]).
    #[inline(always)]
    fn run_chunk_body<const ZERO: bool, const WIDE: bool, const PF: bool>(&self, k: usize, u: &[[f64; 2]], f: SharedForces) {
        let cp = self.sched.chunk_packs;
        let (p0, p1) = (k * cp, ((k + 1) * cp).min(self.packs.len()));
        let mut ug = [[[0.0; LANES]; 2]; N];
        let mut fg = [[[0.0; LANES]; 2]; N];
        for p in p0..p1 {
            if PF {
                self.prefetch_ahead::<ZERO>(p, u, f);
            }
            if ZERO {
                let fw = &self.fw;
                for &c in &fw.ids[fw.start[p] as usize..fw.start[p + 1] as usize] {
                    // SAFETY: as the adds below (this pack's chunk is the first to write `c`).
                    unsafe { f.zero(c as usize) };
                }
            }
            let e0 = p * LANES;
            let conn = &self.conn[e0..(e0 + LANES).min(self.conn.len())];
            // One bounds check per pack (a vector max of its clusters) instead of one per
            // corner for `u` and one per corner for `f` (issue 42: 64 compare-and-branch per
            // pack of Q4 in the hot loop).
            let top = conn.iter().flatten().fold(0u32, |m, &c| m.max(c)) as usize;
            assert!(top < u.len() && top < f.len(), "cluster {top} beyond the displacement ({}) or force ({}) array", u.len(), f.len());
            #[cfg(target_arch = "x86_64")]
            let wide = WIDE && conn.len() == LANES;
            #[cfg(not(target_arch = "x86_64"))]
            let wide = false;
            if wide {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: `WIDE` only in `run_chunk_avx512` (the CPU has AVX-512 F and DQ); every
                // corner's cluster <= top < u.len() (asserted above); a full pack.
                unsafe {
                    gather_pack_avx512(u, conn, &mut ug)
                };
            } else {
                for (l, c) in conn.iter().enumerate() {
                    for a in 0..N {
                        // SAFETY: c[a] <= top < u.len() (asserted above).
                        let ua = unsafe { *u.get_unchecked(c[a] as usize) };
                        ug[a][0][l] = ua[0];
                        ug[a][1][l] = ua[1];
                    }
                }
            }
            match self.extra_of[p] {
                u32::MAX => S::forces(&self.packs[p], &self.dk, &ug, &mut fg),
                i => S::forces_extra(&self.packs[p], &self.extra[i as usize], &self.dk, &ug, &mut fg),
            }
            for (l, c) in conn.iter().enumerate() {
                for a in 0..N {
                    // SAFETY: chunks running at the same time write disjoint clusters: under
                    // either dataflow (Schedule::run_dataflow, run_dataflow_local) a chunk starts
                    // only when every earlier chunk sharing a cluster with it is done (its waits
                    // list every such chunk), and the later ones wait for it.
                    // In bounds: c[a] <= top < f.len() (asserted above).
                    unsafe { f.add_unchecked(c[a] as usize, [fg[a][0][l], fg[a][1][l]]) };
                }
            }
        }
    }
    /// The bytes a force pass streams: the block's (`Block::kernel_bytes`), and per cluster
    /// `u` read, `f` read and written.
    fn streamed_bytes(&self, n_clusters: usize) -> usize {
        self.kernel_bytes() + 48 * n_clusters
    }
    /// Whether a force pass streams more than the last-level cache holds.
    fn beyond_cache(&self, n_clusters: usize) -> bool {
        self.streamed_bytes(n_clusters) > crate::element::kernel::last_level_cache_bytes()
    }
    /// Software prefetch (issue 42, session 29; a hint: the forces do not change): the
    /// streams of the pack [`PREFETCH_PACKS`] after `p` (its geometry, its corners, its first
    /// writers) and the clusters of the first and last element of the pack half as far ahead
    /// (whose corners were fetched as many packs ago). The hardware's stream prefetchers stop
    /// at every 4 KiB page; at 1e6 Q4 elements the pass is 1.1-1.3 x faster with it on one
    /// thread and 1.2-1.4 x on two (docs/perf/README.md, session 29). Run only when
    /// [`Self::prefetches`].
    #[inline(always)]
    fn prefetch_ahead<const ZERO: bool>(&self, p: usize, u: &[[f64; 2]], f: SharedForces) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let line = |ptr: *const i8, bytes: usize| {
                let mut off = 0;
                while off < bytes {
                    // SAFETY: a prefetch is a hint that never faults; SSE is baseline on x86_64.
                    unsafe { _mm_prefetch::<_MM_HINT_T0>(ptr.wrapping_add(off)) };
                    off += 64;
                }
            };
            let q = (p + PREFETCH_PACKS).min(self.packs.len() - 1);
            line((&self.packs[q]) as *const S::Pack as *const i8, std::mem::size_of::<S::Pack>());
            let e = (q * LANES).min(self.conn.len() - 1);
            line((&self.conn[e]) as *const [u32; N] as *const i8, LANES * std::mem::size_of::<[u32; N]>());
            if ZERO {
                if let Some(id) = self.fw.ids.get(self.fw.start[q] as usize) {
                    line(id as *const u32 as *const i8, 1);
                }
            }
            let h = ((p + PREFETCH_PACKS / 2) * LANES).min(self.conn.len() - 1);
            for c in [&self.conn[h], &self.conn[(h + LANES - 1).min(self.conn.len() - 1)]] {
                for &cl in c {
                    let cl = (cl as usize).min(u.len().saturating_sub(1));
                    line(u.as_ptr().wrapping_add(cl) as *const i8, 1);
                    line(f.ptr_at(cl) as *const i8, 1);
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = (p, u, f);
    }
    /// [`Self::run_chunk_body`] compiled for the baseline instruction set.
    fn run_chunk_plain<const ZERO: bool, const PF: bool>(&self, k: usize, u: &[[f64; 2]], f: SharedForces) {
        self.run_chunk_body::<ZERO, false, PF>(k, u, f)
    }
    /// [`Self::run_chunk_body`] compiled for AVX2 (4 lanes per vector instruction).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn run_chunk_avx2<const ZERO: bool, const PF: bool>(&self, k: usize, u: &[[f64; 2]], f: SharedForces) {
        self.run_chunk_body::<ZERO, false, PF>(k, u, f)
    }
    /// [`Self::run_chunk_body`] compiled for AVX-512 (8 lanes: one pack per instruction).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq")]
    fn run_chunk_avx512<const ZERO: bool, const PF: bool>(&self, k: usize, u: &[[f64; 2]], f: SharedForces) {
        self.run_chunk_body::<ZERO, true, PF>(k, u, f)
    }
    /// The chunk loop for `simd` (`None` when this CPU lacks it). The three are the same
    /// code compiled for wider registers: each lane does the same IEEE operations in the same
    /// order (Rust never contracts a multiply and an add into an FMA), so the forces are the
    /// same bit for bit whichever runs (tested in flem-plugins' element tests).
    pub fn chunk_fn(simd: Simd) -> Option<ChunkFn<Self>> {
        Self::chunk_fn_of::<false, false>(simd)
    }
    /// [`Self::chunk_fn`], the adding (`ZERO = false`) or the zero-free loop, with or without
    /// the prefetch (`PF`).
    fn chunk_fn_of<const ZERO: bool, const PF: bool>(simd: Simd) -> Option<ChunkFn<Self>> {
        match simd {
            Simd::Plain => Some(Self::run_chunk_plain::<ZERO, PF>),
            #[cfg(target_arch = "x86_64")]
            Simd::Avx2 if simd.detected() => {
                // SAFETY: the CPU has AVX2 (`detected`, on the line above).
                Some(|b, k, u, f| unsafe { b.run_chunk_avx2::<ZERO, PF>(k, u, f) })
            }
            #[cfg(target_arch = "x86_64")]
            Simd::Avx512 if simd.detected() => {
                // SAFETY: the CPU has AVX-512 F, VL and DQ (`detected`, on the line above).
                Some(|b, k, u, f| unsafe { b.run_chunk_avx512::<ZERO, PF>(k, u, f) })
            }
            _ => None,
        }
    }
    /// The chunk loop of [`Simd::best`] for a pass over `n_clusters` clusters (with the
    /// prefetch when [`Self::prefetches`]; decided once per pass).
    fn best_chunk_fn<const ZERO: bool>(&self, n_clusters: usize) -> ChunkFn<Self> {
        if self.prefetches(n_clusters) {
            Self::chunk_fn_of::<ZERO, true>(Simd::best()).unwrap_or(Self::run_chunk_plain::<ZERO, true>)
        } else {
            Self::chunk_fn_of::<ZERO, false>(Simd::best()).unwrap_or(Self::run_chunk_plain::<ZERO, false>)
        }
    }
    /// Whether the force pass prefetches: beyond the cache (in cache there is nothing to
    /// fetch), or with `Dataflow::Local` set (so that tests on small meshes run it too).
    fn prefetches(&self, n_clusters: usize) -> bool {
        self.beyond_cache(n_clusters) || self.dataflow_mode == Dataflow::Local
    }
    /// `f[c] += F_int` of every element, one thread, with the chunk loop of `simd`; false
    /// (nothing added) when this CPU lacks it.
    pub fn add_internal_forces_simd(&self, u: &[[f64; 2]], f: &mut [[f64; 2]], simd: Simd) -> bool {
        let Some(run) = Self::chunk_fn(simd) else { return false };
        let shared = SharedForces::new(f);
        self.sched.order.iter().for_each(|&k| run(self, k as usize, u, shared));
        true
    }
    /// Whether the zero-free pass is planned and fresh for a force array of `len` clusters.
    fn zero_free_fits(&self, len: usize) -> bool {
        let fw = &self.fw;
        fw.on && !fw.stale && len == fw.pack_of.len() && fw.start.len() == self.packs.len() + 1
    }
    /// Zeroes the clusters no corner names (the zero-free pass writes every other one).
    fn zero_untouched(&self, f: &mut [[f64; 2]]) {
        for &c in &self.fw.untouched {
            f[c as usize] = [0.0; 2];
        }
    }
    /// Runs every chunk with `run` (`best_chunk_fn`), on `pool` when given (see `kernel`).
    fn run_chunks(&self, run: ChunkFn<Self>, u: &[[f64; 2]], f: &mut [[f64; 2]], pool: Option<&rayon::ThreadPool>) {
        assert_eq!(self.packs.len(), self.len().div_ceil(LANES), "ElementBlock::prepare was not called after the last push");
        let shared = SharedForces::new(f);
        match pool {
            Some(pool) if self.len() >= PAR_MIN_ELEMS && pool.current_num_threads() > 1 => {
                // A pass that panicked (and was caught by the caller) poisons the lock; its
                // flags hold older epochs only, so the next pass may take it as it is.
                let lock = match self.dataflow.try_lock() {
                    Ok(g) => Some(g),
                    Err(std::sync::TryLockError::Poisoned(e)) => Some(e.into_inner()),
                    Err(std::sync::TryLockError::WouldBlock) => None,
                };
                if let Some(mut g) = lock {
                    let (epoch, done, taken) = &mut *g;
                    if done.len() != self.sched.n_chunks() {
                        let n = self.sched.n_chunks();
                        (*epoch, *done, *taken) = (0, (0..n).map(|_| Default::default()).collect(), (0..n).map(|_| Default::default()).collect());
                    }
                    // A new value, not in any flag (every flag holds an earlier epoch or 0).
                    *epoch = epoch.wrapping_add(1).max(1);
                    if *epoch == 1 {
                        done.iter_mut().chain(taken.iter_mut()).for_each(|d| *d.get_mut() = 0);
                    }
                    if self.dataflow_local(u.len()) == Some(true) {
                        self.sched.run_dataflow_local(pool, done, taken, *epoch, |k| run(self, k, u, shared));
                    } else {
                        self.sched.run_dataflow(pool, done, *epoch, |k| run(self, k, u, shared));
                    }
                    return;
                }
                // Another thread is in this block's dataflow: this call runs on its own thread.
                self.sched.order.iter().for_each(|&k| run(self, k as usize, u, shared));
            }
            // One thread: the chunks in the schedule's local order (the same sums, bit for bit).
            _ => self.sched.order.iter().for_each(|&k| run(self, k as usize, u, shared)),
        }
    }
    /// The first writers from scratch (`FirstWriters`): the chunks in sequence order, their
    /// elements in order; the first to name a cluster writes it first.
    fn build_first_writers(&mut self, n_clusters: usize) {
        let ce = self.sched.chunk_packs * LANES;
        let mut pack_of = vec![u32::MAX; n_clusters];
        for &k in self.sched.lead.iter().chain(&self.sched.rest) {
            let k = k as usize;
            for i in k * ce..((k + 1) * ce).min(self.conn.len()) {
                for &c in &self.conn[i] {
                    let Some(p) = pack_of.get_mut(c as usize) else {
                        // A corner outside the planned range: no zero-free pass.
                        self.fw = FirstWriters::default();
                        return;
                    };
                    if *p == u32::MAX {
                        *p = (i / LANES) as u32;
                    }
                }
            }
        }
        self.fw = FirstWriters::from_pack_of(pack_of, self.packs.len());
    }
    /// The blocked kernel's packs and extra parts of every element (`prepare` without the
    /// chunk schedule; the co-rotational block, `element::corot`, needs these only).
    pub(crate) fn prepare_packs(&mut self) {
        let (d, t) = (self.d, self.mat.thickness);
        self.packs = self.x.chunks(LANES).map(|x| S::pack(x, &d, t)).collect();
        self.build_extra();
    }
    /// The extra parts of the packs that need one, and each pack's index into them.
    fn build_extra(&mut self) {
        let (d, t) = (self.d, self.mat.thickness);
        (self.extra, self.extra_of) = (Vec::new(), Vec::with_capacity(self.packs.len()));
        for x in self.x.chunks(LANES) {
            match S::extra(x, &d, t) {
                Some(e) => {
                    self.extra_of.push(self.extra.len() as u32);
                    self.extra.push(e);
                }
                None => self.extra_of.push(u32::MAX),
            }
        }
    }

    /// Co-rotational forces (`element::corot`, its module doc) of the elements `range`, `f[c]
    /// +=`, pack by pack with the blocked kernel: each lane's rotation and local displacements
    /// (`element::corot::frame`, lane by lane, so that it vectorises), the pack's forces
    /// by `Blocked::forces` on the local displacements, rotated back and added in element
    /// order. One thread; the same bits from every `simd` (each lane does the same IEEE
    /// operations). Needs the packs (`prepare_packs`).
    #[inline(always)]
    fn corot_body(&self, range: std::ops::Range<usize>, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        assert_eq!(self.packs.len(), self.len().div_ceil(LANES), "the co-rotational block's packs were not built (Block::prepare)");
        assert!(range.end <= self.len(), "elements {range:?} beyond the block ({})", self.len());
        if range.is_empty() {
            return;
        }
        for p in range.start / LANES..=(range.end - 1) / LANES {
            let e0 = p * LANES;
            let e1 = (e0 + LANES).min(self.conn.len());
            let (conn, xs) = (&self.conn[e0..e1], &self.x[e0..e1]);
            // Reference and current corners in lanes (missing lanes: zero, so zero rotation and
            // zero local displacement; the kernel gives them zero force).
            let (mut x0, mut xc) = ([[[0.0; LANES]; 2]; N], [[[0.0; LANES]; 2]; N]);
            for (l, (c, xe)) in conn.iter().zip(xs).enumerate() {
                for a in 0..N {
                    let ua = u[c[a] as usize];
                    x0[a][0][l] = xe[a][0];
                    x0[a][1][l] = xe[a][1];
                    xc[a][0][l] = xe[a][0] + ua[0];
                    xc[a][1][l] = xe[a][1] + ua[1];
                }
            }
            let (mut cs, mut sn, mut ul) = ([0.0; LANES], [0.0; LANES], [[[0.0; LANES]; 2]; N]);
            element::corot::frame(&x0, &xc, &mut cs, &mut sn, &mut ul);
            let mut fg = [[[0.0; LANES]; 2]; N];
            match self.extra_of[p] {
                u32::MAX => S::forces(&self.packs[p], &self.dk, &ul, &mut fg),
                i => S::forces_extra(&self.packs[p], &self.extra[i as usize], &self.dk, &ul, &mut fg),
            }
            for l in range.start.max(e0) - e0..range.end.min(e1) - e0 {
                let c = &conn[l];
                for a in 0..N {
                    let (f0, f1) = (fg[a][0][l], fg[a][1][l]);
                    let fa = &mut f[c[a] as usize];
                    fa[0] += cs[l] * f0 - sn[l] * f1;
                    fa[1] += sn[l] * f0 + cs[l] * f1;
                }
            }
        }
    }
    fn corot_plain(&self, range: std::ops::Range<usize>, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        self.corot_body(range, u, f)
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn corot_avx2(&self, range: std::ops::Range<usize>, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        self.corot_body(range, u, f)
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq")]
    fn corot_avx512(&self, range: std::ops::Range<usize>, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        self.corot_body(range, u, f)
    }
    /// [`Self::corot_body`] compiled for `simd`; false (nothing added) when this CPU lacks it.
    pub fn corot_forces_simd(&self, range: std::ops::Range<usize>, u: &[[f64; 2]], f: &mut [[f64; 2]], simd: Simd) -> bool {
        match simd {
            Simd::Plain => self.corot_plain(range, u, f),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the CPU has AVX2 (`detected`).
            Simd::Avx2 if simd.detected() => unsafe { self.corot_avx2(range, u, f) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the CPU has AVX-512 F, VL and DQ (`detected`).
            Simd::Avx512 if simd.detected() => unsafe { self.corot_avx512(range, u, f) },
            _ => return false,
        }
        true
    }

    pub fn push(&mut self, e: ElemId, x: [[f64; 2]; N], conn: [u32; N]) {
        self.elems.push(e);
        self.x.push(x);
        self.corner_g = std::sync::OnceLock::new();
        self.gauss_g = std::sync::OnceLock::new();
        self.omega_bound = std::sync::OnceLock::new();
        self.omega_elem = std::sync::OnceLock::new();
        self.recovery = std::sync::OnceLock::new();
        self.conn.push(conn);
    }
    #[inline(always)]
    fn gather(&self, i: usize, u: &[[f64; 2]]) -> [[f64; 2]; N] {
        let c = &self.conn[i];
        std::array::from_fn(|a| u[c[a] as usize])
    }
    /// The stress-recovery data of local element `i` (`Blocked::recovery`; empty for an
    /// isoparametric kind).
    pub fn recovery(&self, i: usize) -> &[f64] {
        let r = S::RECOVERY_LEN;
        if r == 0 {
            return &[];
        }
        let all = self.recovery.get_or_init(|| {
            let mut v = vec![0.0; r * self.len()];
            for (x, out) in self.x.iter().zip(v.chunks_exact_mut(r)) {
                S::recovery(x, &self.d, self.mat.thickness, out);
            }
            v
        });
        &all[i * r..(i + 1) * r]
    }
    /// Stress of local element `i` at `xi` for element displacements `ue` (`Blocked::stress`).
    #[inline]
    pub fn stress_local(&self, i: usize, ue: &[[f64; 2]; N], xi: [f64; 2]) -> [f64; 3] {
        S::stress(&self.x[i], ue, &self.d, xi, self.recovery(i))
    }
}

impl<S: Blocked<N>, const N: usize> Block for ElementBlock<S, N> {
    fn kind(&self) -> CellKind {
        S::KIND
    }
    fn nodes_per_elem(&self) -> usize {
        N
    }
    fn len(&self) -> usize {
        self.elems.len()
    }
    fn material(&self) -> &Material {
        &self.mat
    }
    fn region(&self) -> &str {
        &self.region
    }
    fn elems(&self) -> &[ElemId] {
        &self.elems
    }
    fn conn(&self, i: usize) -> &[u32] {
        &self.conn[i]
    }
    fn remap(&mut self, i: usize, a: usize, cluster: u32) {
        self.conn[i][a] = cluster;
        // The first writers wait to be rebuilt (the pass zeroes and adds till then).
        self.fw.stale = self.fw.on;
    }
    fn add_internal_forces(&self, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        self.add_internal_forces_pool(u, f, None)
    }
    fn add_internal_forces_pool(&self, u: &[[f64; 2]], f: &mut [[f64; 2]], pool: Option<&rayon::ThreadPool>) {
        self.run_chunks(self.best_chunk_fn::<false>(u.len()), u, f, pool)
    }
    fn set_internal_forces_pool(&self, u: &[[f64; 2]], f: &mut [[f64; 2]], pool: Option<&rayon::ThreadPool>) -> bool {
        if !self.zero_free_fits(f.len()) {
            return false;
        }
        self.zero_untouched(f);
        self.run_chunks(self.best_chunk_fn::<true>(u.len()), u, f, pool);
        true
    }
    fn enable_zero_free(&mut self, n_clusters: usize) -> bool {
        if self.packs.len() != self.len().div_ceil(LANES) {
            return false;
        }
        self.build_first_writers(n_clusters);
        self.fw.on
    }
    fn zero_free(&self) -> bool {
        self.fw.on
    }
    fn move_elem(&mut self, i: usize, x: &[[f64; 2]]) -> bool {
        if x.len() != N || i >= self.len() {
            return false;
        }
        let xi: [[f64; 2]; N] = std::array::from_fn(|a| x[a]);
        self.x[i] = xi;
        let (d, t) = (self.d, self.mat.thickness);
        if !self.packs.is_empty() {
            // The pack of the element's chunk, as `prepare` builds it.
            let k = i / LANES;
            let chunk = &self.x[k * LANES..((k + 1) * LANES).min(self.x.len())];
            self.packs[k] = S::pack(chunk, &d, t);
            match (S::extra(chunk, &d, t), self.extra_of[k]) {
                (Some(e), j) if j != u32::MAX => self.extra[j as usize] = e,
                (None, u32::MAX) => {}
                _ => {
                    // The chunk gains or loses its extra data: the lists as `prepare` builds them.
                    self.build_extra();
                }
            }
        }
        if let Some(cg) = self.corner_g.get_mut() {
            cg[i] = std::array::from_fn(|a| element::gradients::<S, N>(&xi, element::corner_xi::<S, N>(a)).0);
        }
        if let Some(gg) = self.gauss_g.get_mut() {
            let ng = S::GAUSS.len();
            for (k, &(g, _)) in S::GAUSS.iter().enumerate() {
                gg[i * ng + k] = element::gradients::<S, N>(&xi, g).0;
            }
        }
        let r = S::RECOVERY_LEN;
        if r > 0 {
            if let Some(all) = self.recovery.get_mut() {
                S::recovery(&xi, &d, t, &mut all[i * r..(i + 1) * r]);
            }
        }
        // The bound is a maximum over the block: this element's row sum again, the maximum
        // when next asked.
        if self.omega_elem.get().is_some() {
            let wi = self.elem_omega_rows(i);
            if let Some(w) = self.omega_elem.get_mut() {
                w[i] = wi;
            }
        }
        self.omega_bound = std::sync::OnceLock::new();
        true
    }
    fn prepare(&mut self, n_clusters: usize) {
        self.prepare_packs();
        self.sched = Schedule::build(&self.conn, n_clusters);
        if self.fw.on {
            // A new schedule, new first writers.
            self.build_first_writers(n_clusters);
        }
    }
    fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        self.elems.capacity() * size_of::<ElemId>() + self.x.capacity() * size_of::<[[f64; 2]; N]>() + self.fw.pack_of.capacity() * size_of::<u32>() + self.kernel_bytes()
    }
    fn kernel_bytes(&self) -> usize {
        use std::mem::size_of;
        self.conn.capacity() * size_of::<[u32; N]>()
            + self.packs.capacity() * size_of::<S::Pack>()
            + self.extra.capacity() * size_of::<S::Extra>()
            + self.extra_of.capacity() * 4
            + (self.sched.order.capacity() + self.sched.lead.capacity() + self.sched.rest.capacity() + self.sched.region_start.capacity()) * 4
            + (self.sched.wait_start.capacity() + self.sched.wait_on.capacity()) * 4
            + (self.sched.lead_local.capacity() + self.sched.lead_local_start.capacity() + self.sched.trail_start.capacity()) * 4
            + (self.fw.start.capacity() + self.fw.ids.capacity() + self.fw.untouched.capacity()) * 4
    }
    fn set_dataflow(&mut self, d: Dataflow) {
        self.dataflow_mode = d;
    }
    fn dataflow_local(&self, n_clusters: usize) -> Option<bool> {
        Some(self.len() >= PAR_MIN_ELEMS && self.sched.chain <= Schedule::LOCAL_CHAIN && self.dataflow_mode.local_for(self.streamed_bytes(n_clusters)))
    }
    fn chunk_costs(&self, u: &[[f64; 2]], passes: usize) -> Option<(Schedule, Vec<f64>)> {
        let run = self.best_chunk_fn::<false>(u.len());
        let mut f = vec![[0.0; 2]; u.len()];
        let shared = SharedForces::new(&mut f);
        let mut t = vec![Vec::with_capacity(passes); self.sched.n_chunks()];
        for _ in 0..passes.max(1) {
            for &k in &self.sched.order {
                let t0 = std::time::Instant::now();
                run(self, k as usize, u, shared);
                t[k as usize].push(t0.elapsed().as_secs_f64());
            }
        }
        let cost = t.into_iter().map(|v| v.into_iter().fold(f64::INFINITY, f64::min)).collect();
        std::hint::black_box(&f);
        Some((self.sched.clone(), cost))
    }
    fn add_internal_forces_range(&self, range: std::ops::Range<usize>, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        let t = self.mat.thickness;
        for i in range {
            let ue = self.gather(i, u);
            let fe = S::force_ref(&self.x[i], &ue, &self.d, t);
            let c = &self.conn[i];
            for a in 0..N {
                let fa = &mut f[c[a] as usize];
                fa[0] += fe[a][0];
                fa[1] += fe[a][1];
            }
        }
    }
    fn add_mass(&self, m: &mut [f64]) {
        for i in 0..self.len() {
            let me = element::lumped_mass::<S, N>(&self.x[i], self.mat.density, self.mat.thickness);
            for a in 0..N {
                m[self.conn[i][a] as usize] += me[a];
            }
        }
    }
    fn corner_stress(&self, u: &[[f64; 2]], first: &[u32], out: &mut [[f64; 3]]) {
        if S::RECOVERY_LEN > 0 {
            // An element with internal fields: its own stress at the corner points.
            for i in 0..self.len() {
                let ue = self.gather(i, u);
                let base = first[self.elems[i].idx()] as usize;
                for a in 0..N {
                    out[base + a] = self.stress_local(i, &ue, element::corner_xi::<S, N>(a));
                }
            }
            return;
        }
        // The same gradients as `element::stress_at` at `corner_xi` (bit for bit), computed once.
        let cg = self.corner_g.get_or_init(|| self.x.iter().map(|x| std::array::from_fn(|a| element::gradients::<S, N>(x, element::corner_xi::<S, N>(a)).0)).collect());
        for (i, g) in cg.iter().enumerate() {
            let ue = self.gather(i, u);
            let base = first[self.elems[i].idx()] as usize;
            for a in 0..N {
                out[base + a] = self.d.stress(element::strain(&g[a], &ue));
            }
        }
    }
    /// The operator of `corner_stress` is `D B(g_a)` with `g_a` the corner gradients: a unit
    /// `u_x` of corner `b` gives `[d11 g_bx, d12 g_bx, d33 g_by]`, a unit `u_y` gives
    /// `[d12 g_by, d11 g_by, d33 g_bx]` (exactly the products the probing would see), so the
    /// row sums come from the gradients in one pass. Elements with internal fields
    /// (`RECOVERY_LEN > 0`) have another operator: they are probed.
    fn corner_lipschitz(&self, first: &[u32], out: &mut [f64]) -> bool {
        if S::RECOVERY_LEN > 0 {
            return false;
        }
        let cg = self.corner_g.get_or_init(|| self.x.iter().map(|x| std::array::from_fn(|a| element::gradients::<S, N>(x, element::corner_xi::<S, N>(a)).0)).collect());
        let d = &self.d;
        for (i, g) in cg.iter().enumerate() {
            let base = first[self.elems[i].idx()] as usize;
            for a in 0..N {
                let mut r = [0.0f64; 3];
                for gb in &g[a] {
                    r[0] += (d.d11 * gb[0]).abs() + (d.d12 * gb[1]).abs();
                    r[1] += (d.d12 * gb[0]).abs() + (d.d11 * gb[1]).abs();
                    r[2] += (d.d33 * gb[1]).abs() + (d.d33 * gb[0]).abs();
                }
                out[base + a] = r[0].max(r[1]).max(r[2]);
            }
        }
        true
    }
    fn gauss_stress(&self, u: &[[f64; 2]], first: &[u32], out: &mut [[f64; 3]]) {
        // The gradients of `element::stress_at` at the Gauss points (bit for bit), computed once
        // (only scenes with the nonlocal check call this).
        let ng = S::GAUSS.len();
        if S::RECOVERY_LEN > 0 {
            for i in 0..self.len() {
                let ue = self.gather(i, u);
                let base = first[self.elems[i].idx()] as usize;
                for (k, &(xi, _)) in S::GAUSS.iter().enumerate() {
                    out[base + k] = self.stress_local(i, &ue, xi);
                }
            }
            return;
        }
        let gg = self.gauss_g.get_or_init(|| self.x.iter().flat_map(|x| S::GAUSS.iter().map(|&(xi, _)| element::gradients::<S, N>(x, xi).0)).collect());
        for (i, g) in gg.chunks_exact(ng).enumerate() {
            let ue = self.gather(i, u);
            let base = first[self.elems[i].idx()] as usize;
            for (k, gk) in g.iter().enumerate() {
                out[base + k] = self.d.stress(element::strain(gk, &ue));
            }
        }
    }
    fn stress_at(&self, i: usize, u: &[[f64; 2]], xi: [f64; 2]) -> [f64; 3] {
        self.stress_local(i, &self.gather(i, u), xi)
    }
    fn mean_stress(&self, i: usize, u: &[[f64; 2]]) -> [f64; 3] {
        let ue = self.gather(i, u);
        let mut s = [0.0; 3];
        let (mut wsum, mut acc) = (0.0, [0.0; 3]);
        for &(xi, w) in S::GAUSS {
            let si = self.stress_local(i, &ue, xi);
            for k in 0..3 {
                acc[k] += w * si[k];
            }
            wsum += w;
        }
        for k in 0..3 {
            s[k] = acc[k] / wsum;
        }
        s
    }
    fn stiffness(&self, i: usize, k: &mut [f64]) {
        S::stiffness(&self.x[i], &self.d, self.mat.thickness, k)
    }
    fn coords(&self, i: usize) -> &[[f64; 2]] {
        &self.x[i]
    }
    fn max_omega_bound(&self) -> f64 {
        *self.omega_bound.get_or_init(|| self.compute_omega_bound())
    }
    fn element(&self) -> &'static str {
        S::NAME
    }
    fn isoparametric(&self) -> bool {
        S::RECOVERY_LEN == 0
    }
}

impl<S: Blocked<N>, const N: usize> ElementBlock<S, N> {
    fn compute_omega_bound(&self) -> f64 {
        let w = self.omega_elem.get_or_init(|| (0..self.len()).map(|i| self.elem_omega_rows(i)).collect());
        w.iter().fold(0.0f64, |a, &b| a.max(b)).sqrt()
    }
    /// The largest Gershgorin row sum of element `i`'s `M^-1/2 K M^-1/2`.
    fn elem_omega_rows(&self, i: usize) -> f64 {
        // (The stack buffer holds elements of up to 8 corners; larger ones allocate.)
        let mut stack = [0.0; 256];
        let mut heap = Vec::new();
        let kbuf: &mut [f64] = if 4 * N * N <= stack.len() {
            &mut stack[..4 * N * N]
        } else {
            heap.resize(4 * N * N, 0.0);
            &mut heap
        };
        S::stiffness(&self.x[i], &self.d, self.mat.thickness, kbuf);
        let m = element::lumped_mass::<S, N>(&self.x[i], self.mat.density, self.mat.thickness);
        let n2 = 2 * N;
        let mut best: f64 = 0.0;
        for r in 0..n2 {
            let row: f64 = (0..n2).map(|c| kbuf[r * n2 + c].abs() / (m[r / 2] * m[c / 2]).sqrt()).sum();
            best = best.max(row);
        }
        best
    }
}
