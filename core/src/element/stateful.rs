//! Stateful element blocks: a material law with history (plasticity) or large strain.
//!
//! What: a block of one element kind `S` and one law `L` (monomorphised per pair, no dynamic
//! dispatch per element). Every step, [`Block::update_internal_forces`] takes the displacement
//! increment of each element since the last step, forms the strain increment at each Gauss
//! point, lets the law update the stress `[sxx, syy, sxy, szz]` and its history in place, and
//! adds `f_a = sum_gp Bbar_a^T sigma w det J t` to the nodal forces. Stress, history, the last
//! displacements and the internal work are core-owned arrays of the block (`state_len`,
//! `save_state`, `load_state` carry them through checkpoints).
//!
//! B-bar (selective volumetric strain, mean dilatation; Hughes 1980, Nagtegaal, Parks & Rice
//! 1974): for Q4 the in-plane volumetric strain of every Gauss point is replaced by its mean
//! over the element, `eps_bar = eps + 1/2 (ev_mean - ev) [1, 1, 0]` with
//! `ev_mean = (1/A) integral (exx + eyy) dA`, and `ezz = 0` is kept exactly (plane strain). An
//! incompressible plastic flow then imposes one constraint per element instead of four, which
//! is what keeps a Q4 mesh from locking at the limit load (docs/materials.md shows the
//! footing's limit load with and without). `[[material]] bbar = false` turns it off. A T3
//! has one point: B-bar changes nothing (and a T3 mesh locks: use Q4 for plastic flow).
//!
//! Incompatible modes (`with_enhanced`, an element kind that has them: `qm6`): the strain of a
//! point adds the modes' `G alpha` with `alpha = H u` condensed once with the elastic moduli,
//! and the force is `(B + G H)^T sigma` ([`Enhanced`]; docs/elements.md says why the elastic
//! condensation). Exactly the stateless element while the law is elastic; small strain only.
//!
//! Large strain (`[solver] large_strain = true`): updated Lagrangian. The strain increment and
//! the spin are taken on the mid-step configuration `x0 + (u_n + u_{n+1}) / 2`, the stress is
//! first rotated by the Hughes-Winget (1980) increment `Q = (I - W/2)^-1 (I + W/2)` of the
//! Jaumann rate, then updated by the law, and the forces are integrated on the current
//! configuration `x0 + u_{n+1}`. A rigid rotation increment gives `deps = 0` exactly (the
//! mid-point gradient of a rotation increment is skew, the Cayley transform) and rotates the
//! stress exactly, so a body turned rigidly carries its stress along and gains none.
//!
//! Never-yielded shortcut (ours, `StatefulOpts::elastic_shortcut`, default on; small strain,
//! no modes, a law with `MaterialLaw::elastic_start`): a pack of `LANES` elements none of
//! whose points ever failed the law's initial elastic test gives its points the stress of the
//! total strain (`MaterialLaw::initial_lanes`) and reads nothing stored (`update_pack_total`;
//! it writes the last displacements, non-temporal stores). Its geometry is the element kind's
//! own form when the kind has one (`Shape::TOTAL_ROWS`, `total_strains`, `total_forces`; `q4`:
//! its parent coordinates, session 11), else the generic isoparametric one from the corners
//! (`total_generic`). When a point first fails,
//! the pack is seeded from the last step (`seed_pack`: stress of the total strain there, the
//! elastic energy as work), flagged `yielded` for good, and takes the stored path. The stored
//! path (small strain, no modes) uses the kind's own form too when there is one
//! (`stored_total`, session 30: 72 bytes of geometry and weights read per element instead of
//! the 352 of the stored gradients; strains and forces equal to round-off, not bit for bit),
//! else the stored gradients. A chunk
//! runs its never-yielded packs first, then the stored ones (one order of the force sums,
//! whatever the threads or instruction set). Round-off differs from storing every point.
//! Outputs compute a never-yielded point from the displacements of the last element pass
//! (`u_prev`), the time level of the stored points. docs/materials.md.
//!
//! Outside the step (stable step, implicit check, `add_internal_forces`): the block answers
//! with the elastic law on the reference configuration (with B-bar), i.e. the initial
//! tangent; `strain_energy` is the internal work done so far (stored plus dissipated: the
//! energy ledger's "strain" term then balances with plastic dissipation in it).
//!
//! Determinism: elements are processed in the chunks and colours of `kernel::Schedule`; each
//! element writes only its own points' history; the forces of a node are summed in a fixed
//! order, whatever the number of threads.
use crate::element::block::Block;
use crate::element::kernel::{Schedule, SharedForces, LANES};
use crate::element::law::{MaterialLaw, StatefulOpts};
use crate::element::{self, Dmat, Material, Shape};
use crate::ids::ElemId;
use crate::mesh::CellKind;

/// Blocks smaller than this run on the calling thread.
const PAR_MIN_ELEMS: usize = 512;

pub struct StatefulBlock<S: Shape<N>, L: MaterialLaw, const N: usize> {
    pub region: String,
    pub mat: Material,
    pub law: L,
    pub d: Dmat,
    pub opts: StatefulOpts,
    pub elems: Vec<ElemId>,
    pub x: Vec<[[f64; 2]; N]>,
    pub conn: Vec<[u32; N]>,
    /// Element displacements at the last update, by pack of `LANES` elements
    /// (`u_prev[p][a][dim][lane]`, structure of arrays; the lanes past the block's end stay
    /// zero).
    u_prev: Vec<[[[f64; LANES]; 2]; N]>,
    /// Stress `[sxx, syy, sxy, szz]` of each Gauss point, by pack and point
    /// (`stress[p * ng + k][component][lane]`, structure of arrays: the stored path reads and
    /// writes a point of a whole pack without a gather; ours, issue 37). Checkpoints keep the
    /// element-major order (`save_state`).
    stress: Vec<[[f64; LANES]; 4]>,
    /// `law.n_state()` f64 per Gauss point.
    hist: Vec<f64>,
    /// Internal work of each element so far.
    work: Vec<f64>,
    /// Reference gradients `gp[p * ng + k][a][dim][lane]` and `w det J t` (`gw`, same index)
    /// of each Gauss point `k`, and the mean gradient (B-bar) of each element (`gbar[p]`), in
    /// packs `p` of `LANES` consecutive elements (structure of arrays, like the blocked
    /// kernel; the last pack padded with zeros), built by `prepare`.
    gp: Vec<[[[f64; LANES]; 2]; N]>,
    gw: Vec<[f64; LANES]>,
    gbar: Vec<[[[f64; LANES]; 2]; N]>,
    /// The Gauss point nearest each corner (corner stress).
    corner_gp: [usize; N],
    sched: Schedule,
    omega_bound: std::sync::OnceLock<f64>,
    /// Incompatible modes of the element kind, if it has them (`with_enhanced`).
    enh_fn: Option<(&'static str, EnhancedFn<N>)>,
    /// Per pack: true once a point of the pack failed the law's initial elastic test (the
    /// pack then keeps its points' stress, history and last displacements); false while every
    /// point of the pack never yielded (nothing of it stored: the stress of the total strain).
    /// Only read when `shortcut`.
    yielded: Vec<bool>,
    /// The never-yielded shortcut is on (set by `prepare`: the law's `elastic_start`,
    /// `opts.elastic_shortcut`, small strain, no incompatible modes).
    shortcut: bool,
    /// The element kind's own form (`Shape::TOTAL_ROWS`): of the never-yielded pass (session
    /// 11) and of the stored path (session 30): `S::TOTAL_ROWS` rows per pack (`tg`), and for
    /// a pack that asks for them `S::TOTAL_EXTRA_ROWS` more at `tx[tx_at[p]..]` (`u32::MAX`:
    /// none). Built by `prepare` when the kind has the form (`kind_total`; a test turns it off
    /// with `generic_total` to compare), small strain, no modes (`stored_total`).
    tg: Vec<[f64; LANES]>,
    tx: Vec<[f64; LANES]>,
    tx_at: Vec<u32>,
    kind_total: bool,
    /// The stored path (small strain, no modes) takes its strain increments, its forces and
    /// the seed of a pack leaving the shortcut in the kind's own form (`tg`/`tx`, ours,
    /// session 30): with the work's weights `gw`, 72 bytes per element read (152 in a pack
    /// of non-parallelograms) instead of the 352 of the stored gradients, weights and B-bar
    /// means. Set by `prepare`.
    stored_total: bool,
    enh: Vec<Enhanced<N>>,
    _s: std::marker::PhantomData<S>,
}

/// Incompatible (enhanced) modes of one element for the stateful block, from an element kind
/// that has them (`qm6`, flem-plugins/src/elements/qm6.rs). Two modes ("bubbles") per element,
/// seen as two extra nodes: `h` row `m` gives the parameter `alpha[m / 2][m % 2] = sum_a
/// h[m][a] . u_a` of the element displacements (condensed once with the elastic moduli), `g[k]`
/// the two modes' Cartesian gradients at Gauss point `k`. The strain of a point is then
/// `B u + G alpha` and the force `f = sum_gp w det J t (B + G H)^T sigma`.
#[derive(Clone, Copy, Debug)]
pub struct Enhanced<const N: usize> {
    pub h: [[[f64; 2]; N]; 4],
    pub g: [[[f64; 2]; 2]; 4],
}

/// Builds the [`Enhanced`] data of an element from its corners, the elastic D and thickness.
pub type EnhancedFn<const N: usize> = fn(&[[f64; 2]; N], &Dmat, f64) -> Enhanced<N>;

const NO_MEAN: [[f64; 2]; 2] = [[0.0; 2]; 2];

/// The modes' parameters `alpha = H u`.
#[inline(always)]
fn modes<const N: usize>(h: &[[[f64; 2]; N]; 4], u: &[[f64; 2]; N]) -> [[f64; 2]; 2] {
    let mut al = [[0.0; 2]; 2];
    for m in 0..4 {
        let mut s = 0.0;
        for a in 0..N {
            s += h[m][a][0] * u[a][0] + h[m][a][1] * u[a][1];
        }
        al[m / 2][m % 2] = s;
    }
    al
}

/// `f += H^T fa`: the modes' forces carried to the nodes.
#[inline(always)]
fn add_modes_force<const N: usize>(h: &[[[f64; 2]; N]; 4], fa: &[[f64; 2]; 2], f: &mut [[f64; 2]; N]) {
    for m in 0..4 {
        let v = fa[m / 2][m % 2];
        for a in 0..N {
            f[a][0] += h[m][a][0] * v;
            f[a][1] += h[m][a][1] * v;
        }
    }
}

#[inline(always)]
fn add3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// A raw view of a per-element array written by disjoint element ranges (chunks) at once.
#[derive(Copy, Clone)]
struct Raw<T> {
    ptr: *mut T,
    len: usize,
}
unsafe impl<T> Send for Raw<T> {}
unsafe impl<T> Sync for Raw<T> {}
impl<T> Raw<T> {
    fn new(v: &mut [T]) -> Self {
        Raw { ptr: v.as_mut_ptr(), len: v.len() }
    }
    /// # Safety
    /// No other thread touches `[a, b)` during the borrow (chunks are disjoint element ranges).
    #[allow(clippy::mut_from_ref)]
    unsafe fn range(&self, a: usize, b: usize) -> &mut [T] {
        assert!(a <= b && b <= self.len);
        // SAFETY: in bounds (checked); exclusive by the caller's contract.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(a), b - a) }
    }
}

/// Gradients and `w det J` of every Gauss point of an element at coordinates `x`, and the
/// element's mean gradient.
#[inline(always)]
fn geometry<S: Shape<N>, const N: usize>(x: &[[f64; 2]; N], g: &mut [[[f64; 2]; N]], w: &mut [f64]) -> [[f64; 2]; N] {
    let mut gb = [[0.0; 2]; N];
    let mut a = 0.0;
    for (k, &(xi, wk)) in S::GAUSS.iter().enumerate() {
        let (gk, det) = element::gradients::<S, N>(x, xi);
        g[k] = gk;
        w[k] = wk * det;
        a += w[k];
        for n in 0..N {
            gb[n][0] += w[k] * gk[n][0];
            gb[n][1] += w[k] * gk[n][1];
        }
    }
    let inv = 1.0 / a;
    for v in gb.iter_mut() {
        v[0] *= inv;
        v[1] *= inv;
    }
    gb
}

/// Which packs `StatefulBlock::packs` runs: those that never yielded (the shortcut), or the
/// stored ones. A chunk runs the first pass, then the second, with every instruction set
/// (so the forces' sums have one order: the same bits on any x86-64, any thread count).
const PASS_TOTAL: u8 = 1;
const PASS_STORED: u8 = 2;

/// Gauss points of an element kind at most (Q4).
const MAXG: usize = 4;

/// The B-bar mean volumetric strain increment of the pack's lanes: `sum_a gb_a . du_a`.
#[inline(always)]
fn volumetric_lanes<const N: usize>(gb: &[[[f64; LANES]; 2]; N], du: &[[[f64; LANES]; 2]; N]) -> [f64; LANES] {
    let mut ev = [0.0; LANES];
    for l in 0..LANES {
        for a in 0..N {
            ev[l] += gb[a][0][l] * du[a][0][l] + gb[a][1][l] * du[a][1][l];
        }
    }
    ev
}

/// The strain increment `(exx, eyy, gxy)` of lane `l` from the gradients `g`, with the
/// B-bar correction towards the mean volumetric increment `ev` when `BBAR`.
#[inline(always)]
fn strain_lane<const N: usize, const BBAR: bool>(g: &[[[f64; LANES]; 2]; N], du: &[[[f64; LANES]; 2]; N], ev: f64, l: usize) -> (f64, f64, f64) {
    let (mut e0, mut e1, mut e2) = (0.0, 0.0, 0.0);
    for a in 0..N {
        e0 += g[a][0][l] * du[a][0][l];
        e1 += g[a][1][l] * du[a][1][l];
        e2 += g[a][1][l] * du[a][0][l] + g[a][0][l] * du[a][1][l];
    }
    if BBAR {
        let cc = 0.5 * (ev - (e0 + e1));
        e0 += cc;
        e1 += cc;
    }
    (e0, e1, e2)
}

/// `fe += c B_bar^T s` of lane `l` at one point: the nodal forces of the stress `(s0, s1, s2)`
/// with the gradients `g` (and the B-bar correction with the mean gradients `gb` when `BBAR`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn force_lane<const N: usize, const BBAR: bool>(fe: &mut [[[f64; LANES]; 2]; N], g: &[[[f64; LANES]; 2]; N], gb: &[[[f64; LANES]; 2]; N], s0: f64, s1: f64, s2: f64, c: f64, l: usize) {
    let hp = 0.5 * (s0 + s1);
    for a in 0..N {
        let (g0, g1) = (g[a][0][l], g[a][1][l]);
        let (mut fx, mut fy) = (g0 * s0 + g1 * s2, g0 * s2 + g1 * s1);
        if BBAR {
            fx += (gb[a][0][l] - g0) * hp;
            fy += (gb[a][1][l] - g1) * hp;
        }
        fe[a][0][l] += c * fx;
        fe[a][1][l] += c * fy;
    }
}

/// `up = ul`: the last displacements of a never-yielded pack, written with non-temporal
/// stores on x86-64 (`movnti`, SSE2: the line goes to memory without being read first, half
/// the traffic of a plain store; nothing reads it before the pack leaves the shortcut or an
/// output asks). The chunk ends its never-yielded pass with [`fence`].
#[inline(always)]
fn store_streaming<const N: usize>(up: &mut [[[f64; LANES]; 2]; N], ul: &[[[f64; LANES]; 2]; N]) {
    #[cfg(target_arch = "x86_64")]
    for a in 0..N {
        for d in 0..2 {
            for l in 0..LANES {
                // SAFETY: a valid, 8-byte aligned f64 slot (`movnti` needs natural alignment
                // only); SSE2 is part of x86-64.
                unsafe { std::arch::x86_64::_mm_stream_si64(&mut up[a][d][l] as *mut f64 as *mut i64, ul[a][d][l].to_bits() as i64) };
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        *up = *ul;
    }
}

/// Orders the non-temporal stores of [`store_streaming`] before anything after it (another
/// thread reading `u_prev` after the pass: `sfence`).
#[inline(always)]
fn fence() {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE is part of x86-64.
    unsafe {
        std::arch::x86_64::_mm_sfence()
    };
}

/// Adds the pack's internal work to `wk` and scatters the forces of its elements (`conn`).
#[inline(always)]
fn scatter_lanes<const N: usize>(conn: &[[u32; N]], fe: &[[[f64; LANES]; 2]; N], w_acc: &[f64; LANES], wk: &mut [f64], f: SharedForces) {
    for (l, c) in conn.iter().enumerate() {
        wk[l] += w_acc[l];
        for a in 0..N {
            // SAFETY: chunks of one colour write disjoint clusters (Schedule::build).
            unsafe { f.add(c[a] as usize, [fe[a][0][l], fe[a][1][l]]) };
        }
    }
}

/// `geometry` of the `LANES` elements of a pack at once (`x[a][dim][lane]`): the same
/// operations lane by lane (`element::gradients`, then the mean), so the same bits.
#[inline(always)]
fn geometry_lanes<S: Shape<N>, const N: usize>(x: &[[[f64; LANES]; 2]; N], g: &mut [[[[f64; LANES]; 2]; N]; MAXG], w: &mut [[f64; LANES]; MAXG]) -> [[[f64; LANES]; 2]; N] {
    let mut gb = [[[0.0; LANES]; 2]; N];
    let mut area = [0.0; LANES];
    for (k, &(xi, wk)) in S::GAUSS.iter().enumerate() {
        let dn = S::dn(xi);
        for l in 0..LANES {
            let (mut j11, mut j12, mut j21, mut j22) = (0.0, 0.0, 0.0, 0.0);
            for a in 0..N {
                j11 += dn[a][0] * x[a][0][l];
                j12 += dn[a][0] * x[a][1][l];
                j21 += dn[a][1] * x[a][0][l];
                j22 += dn[a][1] * x[a][1][l];
            }
            let det = j11 * j22 - j12 * j21;
            let inv = 1.0 / det;
            let wl = wk * det;
            w[k][l] = wl;
            area[l] += wl;
            for a in 0..N {
                let (gx, gy) = (inv * (j22 * dn[a][0] - j12 * dn[a][1]), inv * (-j21 * dn[a][0] + j11 * dn[a][1]));
                g[k][a][0][l] = gx;
                g[k][a][1][l] = gy;
                gb[a][0][l] += wl * gx;
                gb[a][1][l] += wl * gy;
            }
        }
    }
    for l in 0..LANES {
        let inv = 1.0 / area[l];
        for a in 0..N {
            gb[a][0][l] *= inv;
            gb[a][1][l] *= inv;
        }
    }
    gb
}

/// `[exx, eyy, gxy]` of `u` with the B-bar correction when `gb` is given.
#[inline(always)]
fn strain_bar<const N: usize>(g: &[[f64; 2]; N], gb: Option<&[[f64; 2]; N]>, u: &[[f64; 2]; N]) -> [f64; 3] {
    let mut e = element::strain(g, u);
    if let Some(gb) = gb {
        let mut ev = 0.0;
        for a in 0..N {
            ev += gb[a][0] * u[a][0] + gb[a][1] * u[a][1];
        }
        let c = 0.5 * (ev - (e[0] + e[1]));
        e[0] += c;
        e[1] += c;
    }
    e
}

/// `f_a += c Bbar_a^T s`.
#[inline(always)]
fn add_force<const N: usize>(g: &[[f64; 2]; N], gb: Option<&[[f64; 2]; N]>, s: [f64; 3], c: f64, f: &mut [[f64; 2]; N]) {
    let hp = 0.5 * (s[0] + s[1]);
    for a in 0..N {
        let (mut fx, mut fy) = (g[a][0] * s[0] + g[a][1] * s[2], g[a][0] * s[2] + g[a][1] * s[1]);
        if let Some(gb) = gb {
            fx += (gb[a][0] - g[a][0]) * hp;
            fy += (gb[a][1] - g[a][1]) * hp;
        }
        f[a][0] += c * fx;
        f[a][1] += c * fy;
    }
}

impl<S: Shape<N>, L: MaterialLaw, const N: usize> StatefulBlock<S, L, N> {
    pub fn new(region: String, mat: Material, law: L, opts: StatefulOpts) -> Self {
        let corner_gp = std::array::from_fn(|a| {
            let c = S::CORNERS[a];
            let d = |k: usize| (S::GAUSS[k].0[0] - c[0]).powi(2) + (S::GAUSS[k].0[1] - c[1]).powi(2);
            (0..S::GAUSS.len()).fold(0, |best, k| if d(k) < d(best) { k } else { best })
        });
        StatefulBlock {
            region,
            d: law.elastic(),
            mat,
            law,
            opts,
            elems: Vec::new(),
            x: Vec::new(),
            conn: Vec::new(),
            u_prev: Vec::new(),
            stress: Vec::new(),
            hist: Vec::new(),
            work: Vec::new(),
            gp: Vec::new(),
            gw: Vec::new(),
            gbar: Vec::new(),
            corner_gp,
            sched: Schedule::default(),
            omega_bound: std::sync::OnceLock::new(),
            enh_fn: None,
            enh: Vec::new(),
            yielded: Vec::new(),
            shortcut: false,
            tg: Vec::new(),
            tx: Vec::new(),
            tx_at: Vec::new(),
            kind_total: S::TOTAL_ROWS > 0,
            stored_total: false,
            _s: std::marker::PhantomData,
        }
    }

    /// The block of an element kind with incompatible modes (see [`Enhanced`]): `name` is the
    /// kind's registered name, `f` builds each element's modes when the block is prepared. The
    /// modes are condensed with the elastic moduli (a fixed `alpha = H u` per element; why:
    /// docs/elements.md). Small strain only (the large-strain path has no modes).
    pub fn with_enhanced(mut self, name: &'static str, f: EnhancedFn<N>) -> Self {
        self.enh_fn = Some((name, f));
        self
    }

    /// The never-yielded pass and the stored path on the generic isoparametric geometry (the
    /// stored gradients) even for a kind that has its own form (`Shape::TOTAL_ROWS`): the
    /// reference the kind's form is tested against.
    #[doc(hidden)]
    pub fn generic_total(mut self) -> Self {
        self.kind_total = false;
        self
    }

    pub fn push(&mut self, e: ElemId, x: [[f64; 2]; N], conn: [u32; N]) {
        let ng = S::GAUSS.len();
        if self.elems.len() % LANES == 0 {
            self.yielded.push(false);
            self.u_prev.push([[[0.0; LANES]; 2]; N]);
            self.stress.extend(std::iter::repeat_n([[0.0; LANES]; 4], ng));
        }
        self.elems.push(e);
        self.x.push(x);
        self.conn.push(conn);
        self.hist.extend(std::iter::repeat_n(0.0, ng * self.law.n_state()));
        self.work.push(0.0);
        self.omega_bound = std::sync::OnceLock::new();
    }

    fn bbar(&self) -> bool {
        self.opts.bbar && S::GAUSS.len() > 1
    }

    /// Element `i`'s points are stored (not the never-yielded shortcut).
    #[inline(always)]
    fn stored(&self, i: usize) -> bool {
        !self.shortcut || self.yielded[i / LANES]
    }

    /// Stress `[sxx, syy, sxy, szz]` of point `k` of element `i` at the last element pass:
    /// stored, or for a pack that never yielded the stress of the total strain of the
    /// displacements of that pass (`u_prev`, `MaterialLaw::initial_lanes`), so that every point
    /// of a block is read at the same time level whatever `u` the caller holds (a failure check
    /// runs after the node update). `_u`: kept for the callers' symmetry.
    fn stress4(&self, i: usize, k: usize, _u: &[[f64; 2]]) -> [f64; 4] {
        if self.stored(i) {
            return self.stored4(i, k);
        }
        let ue = self.up_at(i);
        let gbi = self.gbar_at(i);
        let e = strain_bar(&self.g_at(i, k), self.bbar().then_some(&gbi), &ue);
        let mut el = [[0.0; LANES]; 4];
        (el[0][0], el[1][0], el[2][0]) = (e[0], e[1], e[2]);
        let mut s = [[0.0; LANES]; 4];
        self.law.initial_lanes(&el, &mut s);
        [s[0][0], s[1][0], s[2][0], s[3][0]]
    }

    /// The stored stress of point `k` of element `i` (the raw array: zero for a pack that
    /// never yielded).
    #[inline(always)]
    fn stored4(&self, i: usize, k: usize) -> [f64; 4] {
        let (s, l) = (&self.stress[(i / LANES) * S::GAUSS.len() + k], i % LANES);
        [s[0][l], s[1][l], s[2][l], s[3][l]]
    }

    /// The displacements of element `i` at the last element pass.
    #[inline(always)]
    fn up_at(&self, i: usize) -> [[f64; 2]; N] {
        let (v, l) = (&self.u_prev[i / LANES], i % LANES);
        std::array::from_fn(|a| [v[a][0][l], v[a][1][l]])
    }

    #[inline(always)]
    fn gather(&self, i: usize, u: &[[f64; 2]]) -> [[f64; 2]; N] {
        let c = &self.conn[i];
        std::array::from_fn(|a| u[c[a] as usize])
    }

    /// Reference gradients of point `k` of element `i`.
    #[inline(always)]
    fn g_at(&self, i: usize, k: usize) -> [[f64; 2]; N] {
        let (p, l) = (i / LANES, i % LANES);
        let g = &self.gp[p * S::GAUSS.len() + k];
        std::array::from_fn(|a| [g[a][0][l], g[a][1][l]])
    }
    /// `w det J t` of point `k` of element `i`.
    #[inline(always)]
    fn w_at(&self, i: usize, k: usize) -> f64 {
        self.gw[(i / LANES) * S::GAUSS.len() + k][i % LANES]
    }
    /// Mean gradient (B-bar) of element `i`.
    #[inline(always)]
    fn gbar_at(&self, i: usize) -> [[f64; 2]; N] {
        let (g, l) = (&self.gbar[i / LANES], i % LANES);
        std::array::from_fn(|a| [g[a][0][l], g[a][1][l]])
    }

    /// Linear elastic forces of element `i` on the reference configuration (the initial tangent).
    fn elastic_force(&self, i: usize, ue: &[[f64; 2]; N]) -> [[f64; 2]; N] {
        let ng = S::GAUSS.len();
        let gbi = self.gbar_at(i);
        let gb = self.bbar().then_some(&gbi);
        let mut f = [[0.0; 2]; N];
        let enh = self.enh.get(i);
        let al = enh.map(|en| modes(&en.h, ue));
        let mut fa = [[0.0; 2]; 2];
        for k in 0..ng {
            let g = &self.g_at(i, k);
            let mut e = strain_bar(g, gb, ue);
            if let (Some(en), Some(al)) = (enh, &al) {
                e = add3(e, strain_bar(&en.g[k], self.bbar().then_some(&NO_MEAN), al));
            }
            let s = self.d.stress(e);
            add_force(g, gb, s, self.w_at(i, k), &mut f);
            if let Some(en) = enh {
                add_force(&en.g[k], self.bbar().then_some(&NO_MEAN), s, self.w_at(i, k), &mut fa);
            }
        }
        if let Some(en) = enh {
            add_modes_force(&en.h, &fa, &mut f);
        }
        f
    }

    /// `elastic_force` of lanes `l0..l1` of pack `p` at once (no incompatible modes): the same
    /// operations in the same order lane by lane (`strain_lane`, the moduli, `force_lane`), so
    /// the same bits; the other lanes see zero displacements. The power iteration of the
    /// stable step calls this through `add_internal_forces_range` (ours, issue 37: it was the
    /// scalar per-element path, a tenth of a plastic footing's run).
    #[inline(always)]
    fn elastic_pack<const BBAR: bool>(&self, p: usize, l0: usize, l1: usize, u: &[[f64; 2]]) -> [[[f64; LANES]; 2]; N] {
        let ng = S::GAUSS.len();
        let mut ul = [[[0.0; LANES]; 2]; N];
        for l in l0..l1 {
            let c = &self.conn[p * LANES + l];
            for a in 0..N {
                let v = u[c[a] as usize];
                ul[a][0][l] = v[0];
                ul[a][1][l] = v[1];
            }
        }
        let gb = &self.gbar[p];
        let ev = if BBAR { volumetric_lanes(gb, &ul) } else { [0.0; LANES] };
        let d = &self.d;
        let mut fe = [[[0.0; LANES]; 2]; N];
        for k in 0..ng {
            let (g, c) = (&self.gp[p * ng + k], &self.gw[p * ng + k]);
            for l in 0..LANES {
                let (e0, e1, e2) = strain_lane::<N, BBAR>(g, &ul, ev[l], l);
                let (s0, s1, s2) = (d.d11 * e0 + d.d12 * e1, d.d12 * e0 + d.d11 * e1, d.d33 * e2);
                force_lane::<N, BBAR>(&mut fe, g, gb, s0, s1, s2, c[l], l);
            }
        }
        fe
    }

    /// The step of element `i`: stress update of its points from the displacement increment,
    /// then its forces. `st`, `hs` are its points' stress and history, `up` its last displacements.
    #[inline(always)]
    fn update_elem(&self, i: usize, ue: &[[f64; 2]; N], st: &mut [[f64; 4]], hs: &mut [f64], up: &mut [[f64; 2]; N], work: &mut f64) -> [[f64; 2]; N] {
        let ng = S::GAUSS.len();
        let ns = self.law.n_state();
        debug_assert!(ng <= MAXG);
        let du: [[f64; 2]; N] = std::array::from_fn(|a| [ue[a][0] - up[a][0], ue[a][1] - up[a][1]]);
        let bbar = self.bbar();
        let t = self.mat.thickness;
        let mut f = [[0.0; 2]; N];
        let mut w_acc = 0.0;
        if self.opts.large_strain {
            let x0 = &self.x[i];
            let xm: [[f64; 2]; N] = std::array::from_fn(|a| [x0[a][0] + 0.5 * (up[a][0] + ue[a][0]), x0[a][1] + 0.5 * (up[a][1] + ue[a][1])]);
            let xe: [[f64; 2]; N] = std::array::from_fn(|a| [x0[a][0] + ue[a][0], x0[a][1] + ue[a][1]]);
            let (mut gm, mut wm) = ([[[0.0; 2]; N]; MAXG], [0.0; MAXG]);
            let (mut ge, mut we) = ([[[0.0; 2]; N]; MAXG], [0.0; MAXG]);
            let gbm = geometry::<S, N>(&xm, &mut gm[..ng], &mut wm[..ng]);
            let gbe = geometry::<S, N>(&xe, &mut ge[..ng], &mut we[..ng]);
            for k in 0..ng {
                let e = strain_bar(&gm[k], bbar.then_some(&gbm), &du);
                // Spin of the increment at the mid-step configuration, Hughes-Winget rotation.
                let mut om = 0.0;
                for a in 0..N {
                    om += 0.5 * (gm[k][a][0] * du[a][1] - gm[k][a][1] * du[a][0]);
                }
                let s = &mut st[k];
                let (c2, s2) = {
                    // Q = rotation by theta with tan(theta / 2) = om / 2: cos, sin of 2 theta.
                    let h = 0.5 * om;
                    let (ct, sn) = ((1.0 - h * h) / (1.0 + h * h), 2.0 * h / (1.0 + h * h));
                    (ct * ct - sn * sn, 2.0 * sn * ct)
                };
                let (m, dd, xy) = (0.5 * (s[0] + s[1]), 0.5 * (s[0] - s[1]), s[2]);
                let (dd2, xy2) = (c2 * dd - s2 * xy, s2 * dd + c2 * xy);
                s[0] = m + dd2;
                s[1] = m - dd2;
                s[2] = xy2;
                let old = *s;
                let de = [e[0], e[1], e[2], 0.0];
                self.law.update(s, de, &mut hs[k * ns..(k + 1) * ns]);
                w_acc += wm[k] * t * 0.5 * ((old[0] + s[0]) * de[0] + (old[1] + s[1]) * de[1] + (old[2] + s[2]) * de[2]);
                add_force(&ge[k], bbar.then_some(&gbe), [s[0], s[1], s[2]], we[k] * t, &mut f);
            }
        } else {
            let gbi = self.gbar_at(i);
            let gb = bbar.then_some(&gbi);
            let enh = self.enh.get(i);
            let dal = enh.map(|en| modes(&en.h, &du));
            let mut fa = [[0.0; 2]; 2];
            for k in 0..ng {
                let g = &self.g_at(i, k);
                let mut e = strain_bar(g, gb, &du);
                if let (Some(en), Some(dal)) = (enh, &dal) {
                    e = add3(e, strain_bar(&en.g[k], bbar.then_some(&NO_MEAN), dal));
                }
                let s = &mut st[k];
                let old = *s;
                let de = [e[0], e[1], e[2], 0.0];
                self.law.update(s, de, &mut hs[k * ns..(k + 1) * ns]);
                let c = self.w_at(i, k);
                w_acc += c * 0.5 * ((old[0] + s[0]) * de[0] + (old[1] + s[1]) * de[1] + (old[2] + s[2]) * de[2]);
                add_force(g, gb, [s[0], s[1], s[2]], c, &mut f);
                if let Some(en) = enh {
                    add_force(&en.g[k], bbar.then_some(&NO_MEAN), [s[0], s[1], s[2]], c, &mut fa);
                }
            }
            if let Some(en) = enh {
                add_modes_force(&en.h, &fa, &mut f);
            }
        }
        *work += w_acc;
        *up = *ue;
        f
    }

    /// Pack `p`'s geometry in the kind's own form: its `S::TOTAL_ROWS` rows, and the extra
    /// rows of a pack that has them (`tg`, `tx`; built by `prepare` when `stored_total`).
    #[inline(always)]
    fn kind_geometry(&self, p: usize) -> (&[[f64; LANES]], Option<&[[f64; LANES]]>) {
        let r = S::TOTAL_ROWS;
        let xa = self.tx_at[p];
        (&self.tg[p * r..(p + 1) * r], (xa != u32::MAX).then(|| &self.tx[xa as usize..xa as usize + S::TOTAL_EXTRA_ROWS]))
    }

    /// The step of the `n` elements of pack `p` (small strain, no modes) at once, as loops
    /// over the lanes that the compiler vectorises, with the law called for the whole pack: in
    /// the kind's own form when it has one (`stored_total`; the same strains and forces as
    /// `update_elem` to round-off), once for all its points (`MaterialLaw::update_points_lanes`,
    /// session 37), else once per Gauss point (`MaterialLaw::update_lanes`) on the stored
    /// gradients with `update_elem`'s arithmetic lane by lane (the same bits).
    /// `st`, `hs`, `up`, `wk` start at the pack's first element.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn update_pack<const BBAR: bool>(&self, p: usize, n: usize, u: &[[f64; 2]], st: &mut [[[f64; LANES]; 4]], hs: &mut [f64], up: &mut [[[f64; LANES]; 2]; N], wk: &mut [f64], f: SharedForces) {
        let ng = S::GAUSS.len();
        let ns = self.law.n_state();
        let i0 = p * LANES;
        let conn = &self.conn[i0..i0 + n];
        let (st, wk) = (&mut st[..ng], &mut wk[..n]);
        // Displacement increments since the last update, by lane (the lanes past the block's
        // end: zero displacements, zero increments).
        let mut ul = [[[0.0; LANES]; 2]; N];
        for (l, c) in conn.iter().enumerate() {
            for a in 0..N {
                let v = u[c[a] as usize];
                ul[a][0][l] = v[0];
                ul[a][1][l] = v[1];
            }
        }
        let mut du = [[[0.0; LANES]; 2]; N];
        for a in 0..N {
            for d in 0..2 {
                for l in 0..LANES {
                    du[a][d][l] = ul[a][d][l] - up[a][d][l];
                }
            }
        }
        *up = ul;
        let mut fe = [[[0.0; LANES]; 2]; N];
        let mut w_acc = [0.0; LANES];
        if S::TOTAL_ROWS > 0 && self.stored_total {
            // The kind's own form (`Shape::total_strains` of the increments, `total_forces` of
            // the new stresses; `q4`: the parent coordinates of its elastic kernel): the same
            // strains and forces as the stored gradients to round-off
            // (`q4_total_form_matches_the_generic_shortcut`, shortcut off), 72 bytes of
            // geometry and weights per element read instead of 352.
            let (geo, extra) = self.kind_geometry(p);
            let mut e = [[[0.0; LANES]; 4]; MAXG];
            S::total_strains::<BBAR>(geo, extra, &du, &mut e);
            let mut old = [[[0.0; LANES]; 4]; MAXG];
            old[..ng].copy_from_slice(&st[..ng]);
            // The law updates the stored stresses of the pack's points in place, all at once.
            self.law.update_points_lanes(&mut st[..ng], &e[..ng], hs, ng * ns, n);
            for k in 0..ng {
                let c = &self.gw[p * ng + k];
                let (s, de, old) = (&st[k], &e[k], &old[k]);
                for l in 0..LANES {
                    w_acc[l] += c[l] * 0.5 * ((old[0][l] + s[0][l]) * de[0][l] + (old[1][l] + s[1][l]) * de[1][l] + (old[2][l] + s[2][l]) * de[2][l]);
                }
            }
            // `Shape::total_forces` takes `MAXG` points: the stored ones themselves when the
            // kind has that many (q4), else a copy padded with zeros.
            if let Ok(sn) = <&[[[f64; LANES]; 4]; MAXG]>::try_from(&st[..]) {
                S::total_forces::<BBAR>(geo, extra, sn, self.mat.thickness, &mut fe);
            } else {
                let mut sn = [[[0.0; LANES]; 4]; MAXG];
                sn[..ng].copy_from_slice(st);
                S::total_forces::<BBAR>(geo, extra, &sn, self.mat.thickness, &mut fe);
            }
            scatter_lanes(conn, &fe, &w_acc, wk, f);
            return;
        }
        let gb = &self.gbar[p];
        // B-bar: the element's mean volumetric strain increment (the same at every point).
        let ev = if BBAR { volumetric_lanes(gb, &du) } else { [0.0; LANES] };
        for k in 0..ng {
            let g = &self.gp[p * ng + k];
            let c = &self.gw[p * ng + k];
            let mut de = [[0.0; LANES]; 4];
            for l in 0..LANES {
                (de[0][l], de[1][l], de[2][l]) = strain_lane::<N, BBAR>(g, &du, ev[l], l);
            }
            let mut s = st[k];
            let old = s;
            self.law.update_lanes(&mut s, &de, &mut hs[k * ns..], ng * ns, n);
            st[k] = s;
            for l in 0..LANES {
                let (s0, s1, s2) = (s[0][l], s[1][l], s[2][l]);
                w_acc[l] += c[l] * 0.5 * ((old[0][l] + s0) * de[0][l] + (old[1][l] + s1) * de[1][l] + (old[2][l] + s2) * de[2][l]);
                force_lane::<N, BBAR>(&mut fe, g, gb, s0, s1, s2, c[l], l);
            }
        }
        scatter_lanes(conn, &fe, &w_acc, wk, f);
    }

    /// The never-yielded shortcut of pack `p` (small strain, no modes): the strain of every
    /// point from the total displacements, on the kind's own geometry (`Shape::total_strains`,
    /// `tg`/`tx`) or the generic one from the corners (`total_generic`), the law's stress from
    /// the initial state and its elastic test (`MaterialLaw::initial_lanes`), the forces.
    /// Nothing stored is read; only the last displacements are written (`store_streaming`). When
    /// every point of the pack's `n` elements is elastic it scatters the forces, sets `up`
    /// and returns true; otherwise it changes nothing and returns false (the caller then
    /// seeds the pack's stored state from the last displacements, `seed_pack`, marks it
    /// yielded and runs the stored path: the increment from the last step on, as if the pack
    /// had been stored from the start).
    #[inline(always)]
    fn update_pack_total<const BBAR: bool>(&self, p: usize, n: usize, u: &[[f64; 2]], f: SharedForces, up: &mut [[[f64; LANES]; 2]; N]) -> bool {
        let ng = S::GAUSS.len();
        let t = self.mat.thickness;
        let i0 = p * LANES;
        let conn = &self.conn[i0..i0 + n];
        let mut ul = [[[0.0; LANES]; 2]; N];
        for (l, c) in conn.iter().enumerate() {
            for a in 0..N {
                let v = u[c[a] as usize];
                ul[a][0][l] = v[0];
                ul[a][1][l] = v[1];
            }
        }
        let mut fe = [[[0.0; LANES]; 2]; N];
        let mut ok = [true; LANES];
        if S::TOTAL_ROWS > 0 && self.kind_total {
            // The kind's own form (`Shape::total_strains`, `total_forces`; `q4`: the parent
            // coordinates, as its elastic kernel).
            let (geo, extra) = self.kind_geometry(p);
            let mut e = [[[0.0; LANES]; 4]; MAXG];
            S::total_strains::<BBAR>(geo, extra, &ul, &mut e);
            let mut s = [[[0.0; LANES]; 4]; MAXG];
            for k in 0..ng {
                let inside = self.law.initial_lanes(&e[k], &mut s[k]);
                for l in 0..LANES {
                    ok[l] &= inside[l];
                }
            }
            S::total_forces::<BBAR>(geo, extra, &s, t, &mut fe);
        } else {
            self.total_generic::<BBAR>(p, n, &ul, &mut fe, &mut ok);
        }
        if !ok[..n].iter().all(|&b| b) {
            return false;
        }
        for (l, c) in conn.iter().enumerate() {
            for a in 0..N {
                // SAFETY: chunks of one colour write disjoint clusters (Schedule::build).
                unsafe { f.add(c[a] as usize, [fe[a][0][l], fe[a][1][l]]) };
            }
        }
        store_streaming(up, &ul);
        true
    }

    /// The never-yielded pass of `update_pack_total` on the generic isoparametric geometry
    /// (a kind without its own form): forces into `fe`, the elastic test into `ok`.
    #[inline(always)]
    fn total_generic<const BBAR: bool>(&self, p: usize, n: usize, ul: &[[[f64; LANES]; 2]; N], fe: &mut [[[f64; LANES]; 2]; N], ok: &mut [bool; LANES]) {
        let ng = S::GAUSS.len();
        let t = self.mat.thickness;
        let i0 = p * LANES;
        let (mut g, mut w) = ([[[[0.0; LANES]; 2]; N]; MAXG], [[0.0; LANES]; MAXG]);
        // The geometry from the corners (cheaper than reading the stored gradients: this path
        // is bound by arithmetic, and 64 bytes per element are read instead of 352).
        let mut xl = [[[0.0; LANES]; 2]; N];
        for l in 0..LANES {
            // Lanes past the block's end repeat its first element (finite geometry, zero u).
            let x0 = &self.x[i0 + if l < n { l } else { 0 }];
            for a in 0..N {
                xl[a][0][l] = x0[a][0];
                xl[a][1][l] = x0[a][1];
            }
        }
        let gb = geometry_lanes::<S, N>(&xl, &mut g, &mut w);
        for wk in w.iter_mut() {
            for v in wk.iter_mut() {
                *v *= t;
            }
        }
        let ev = if BBAR { volumetric_lanes(&gb, ul) } else { [0.0; LANES] };
        for k in 0..ng {
            let gk = &g[k];
            let mut e = [[0.0; LANES]; 4];
            for l in 0..LANES {
                (e[0][l], e[1][l], e[2][l]) = strain_lane::<N, BBAR>(gk, ul, ev[l], l);
            }
            let mut s = [[0.0; LANES]; 4];
            let inside = self.law.initial_lanes(&e, &mut s);
            for l in 0..LANES {
                ok[l] &= inside[l];
                force_lane::<N, BBAR>(fe, gk, &gb, s[0][l], s[1][l], s[2][l], w[k][l], l);
            }
        }
    }

    /// The stored state of pack `p` when it leaves the shortcut: each point's stress of the
    /// total strain at the last displacements `up` (the law's `initial_lanes`, in the form the
    /// stored path uses: the kind's own when `stored_total`, the same strains as the shortcut's
    /// own at that step, else the stored gradients), and each element's work so far, the
    /// elastic energy `1/2 sigma : eps` of its points (what the increments' work adds up to).
    /// History stays initial. `st`, `up`, `wk` start at the pack's first element. Runs once
    /// per pack.
    #[inline(never)]
    fn seed_pack<const BBAR: bool>(&self, p: usize, n: usize, st: &mut [[[f64; LANES]; 4]], up: &[[[f64; LANES]; 2]; N], wk: &mut [f64]) {
        let ng = S::GAUSS.len();
        // The lanes past the block's end hold zero displacements.
        let ul = *up;
        // Every point's total strain, in the form the stored path uses.
        let mut e = [[[0.0; LANES]; 4]; MAXG];
        if S::TOTAL_ROWS > 0 && self.stored_total {
            let (geo, extra) = self.kind_geometry(p);
            S::total_strains::<BBAR>(geo, extra, &ul, &mut e);
        } else {
            let ev = if BBAR { volumetric_lanes(&self.gbar[p], &ul) } else { [0.0; LANES] };
            for (k, ek) in e.iter_mut().enumerate().take(ng) {
                let g = &self.gp[p * ng + k];
                for l in 0..LANES {
                    (ek[0][l], ek[1][l], ek[2][l]) = strain_lane::<N, BBAR>(g, &ul, ev[l], l);
                }
            }
        }
        let mut w_acc = [0.0; LANES];
        for k in 0..ng {
            let (c, e) = (&self.gw[p * ng + k], &e[k]);
            let mut s = [[0.0; LANES]; 4];
            self.law.initial_lanes(e, &mut s);
            st[k] = s;
            for l in 0..LANES {
                w_acc[l] += c[l] * 0.5 * (s[0][l] * e[0][l] + s[1][l] * e[1][l] + s[2][l] * e[2][l]);
            }
        }
        wk[..n].copy_from_slice(&w_acc[..n]);
    }

    /// The packs of elements `e0..e1` (`e0` a multiple of `LANES`; `st`, `hs`, `up`, `wk`
    /// start at `e0`, `yl` at pack `e0 / LANES`) that `PASS` selects. A pack whose shortcut
    /// fails in `PASS_TOTAL` is marked yielded and left to `PASS_STORED`.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn packs<const PASS: u8>(
        &self,
        e0: usize,
        e1: usize,
        u: &[[f64; 2]],
        f: SharedForces,
        st: &mut [[[f64; LANES]; 4]],
        hs: &mut [f64],
        up: &mut [[[[f64; LANES]; 2]; N]],
        wk: &mut [f64],
        yl: &mut [bool],
    ) {
        let (ng, ns) = (S::GAUSS.len(), self.law.n_state());
        let bbar = self.bbar();
        let p0 = e0 / LANES;
        for p in p0..e1.div_ceil(LANES) {
            let (j, n) = (p * LANES - e0, (e1 - p * LANES).min(LANES));
            if self.shortcut && !yl[p - p0] {
                if PASS == PASS_STORED {
                    continue;
                }
                let (st, up, wk) = (&mut st[(p - p0) * ng..], &mut up[p - p0], &mut wk[j..]);
                let done = if bbar { self.update_pack_total::<true>(p, n, u, f, up) } else { self.update_pack_total::<false>(p, n, u, f, up) };
                if done {
                    continue;
                }
                if bbar {
                    self.seed_pack::<true>(p, n, st, up, wk);
                } else {
                    self.seed_pack::<false>(p, n, st, up, wk);
                }
                yl[p - p0] = true;
            }
            if PASS == PASS_TOTAL {
                continue;
            }
            let (st, hs, up, wk) = (&mut st[(p - p0) * ng..], &mut hs[j * ng * ns..], &mut up[p - p0], &mut wk[j..]);
            match (self.opts.large_strain, bbar) {
                (false, true) => self.update_pack::<true>(p, n, u, st, hs, up, wk, f),
                (false, false) => self.update_pack::<false>(p, n, u, st, hs, up, wk, f),
                (true, true) => self.update_pack_large::<true>(p, n, u, st, hs, up, wk, f),
                (true, false) => self.update_pack_large::<false>(p, n, u, st, hs, up, wk, f),
            }
        }
    }

    /// `update_pack` with large strain: `update_elem`'s large-strain branch lane by lane (the
    /// same bits), the geometry of the mid-step and current configurations of the pack's
    /// elements computed together (`geometry_lanes`).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn update_pack_large<const BBAR: bool>(&self, p: usize, n: usize, u: &[[f64; 2]], st: &mut [[[f64; LANES]; 4]], hs: &mut [f64], up: &mut [[[f64; LANES]; 2]; N], wk: &mut [f64], f: SharedForces) {
        let ng = S::GAUSS.len();
        let ns = self.law.n_state();
        let t = self.mat.thickness;
        let i0 = p * LANES;
        let conn = &self.conn[i0..i0 + n];
        let (st, wk) = (&mut st[..ng], &mut wk[..n]);
        let mut du = [[[0.0; LANES]; 2]; N];
        let (mut xm, mut xe) = ([[[0.0; LANES]; 2]; N], [[[0.0; LANES]; 2]; N]);
        for l in 0..LANES {
            // Lanes past the block's end repeat its first element (finite geometry, unused).
            let (x0, lu) = (&self.x[i0 + if l < n { l } else { 0 }], if l < n { l } else { 0 });
            for a in 0..N {
                let v = u[conn[lu][a] as usize];
                let o = [up[a][0][lu], up[a][1][lu]];
                for d in 0..2 {
                    du[a][d][l] = if l < n { v[d] - o[d] } else { 0.0 };
                    xm[a][d][l] = x0[a][d] + 0.5 * (o[d] + v[d]);
                    xe[a][d][l] = x0[a][d] + v[d];
                }
            }
        }
        for l in 0..n {
            for a in 0..N {
                let v = u[conn[l][a] as usize];
                (up[a][0][l], up[a][1][l]) = (v[0], v[1]);
            }
        }
        let (mut gm, mut wm) = ([[[[0.0; LANES]; 2]; N]; MAXG], [[0.0; LANES]; MAXG]);
        let (mut ge, mut we) = ([[[[0.0; LANES]; 2]; N]; MAXG], [[0.0; LANES]; MAXG]);
        let gbm = geometry_lanes::<S, N>(&xm, &mut gm, &mut wm);
        let gbe = geometry_lanes::<S, N>(&xe, &mut ge, &mut we);
        let ev = if BBAR { volumetric_lanes(&gbm, &du) } else { [0.0; LANES] };
        let mut fe = [[[0.0; LANES]; 2]; N];
        let mut w_acc = [0.0; LANES];
        for k in 0..ng {
            let (g, h) = (&gm[k], &ge[k]);
            let mut de = [[0.0; LANES]; 4];
            let mut s = st[k];
            for l in 0..LANES {
                (de[0][l], de[1][l], de[2][l]) = strain_lane::<N, BBAR>(g, &du, ev[l], l);
                let mut om = 0.0;
                // Spin of the increment at the mid-step configuration, Hughes-Winget rotation.
                for a in 0..N {
                    om += 0.5 * (g[a][0][l] * du[a][1][l] - g[a][1][l] * du[a][0][l]);
                }
                let hh = 0.5 * om;
                let (ct, sn) = ((1.0 - hh * hh) / (1.0 + hh * hh), 2.0 * hh / (1.0 + hh * hh));
                let (c2, s2) = (ct * ct - sn * sn, 2.0 * sn * ct);
                let (m, dd, xy) = (0.5 * (s[0][l] + s[1][l]), 0.5 * (s[0][l] - s[1][l]), s[2][l]);
                let (dd2, xy2) = (c2 * dd - s2 * xy, s2 * dd + c2 * xy);
                (s[0][l], s[1][l], s[2][l]) = (m + dd2, m - dd2, xy2);
            }
            let old = s;
            self.law.update_lanes(&mut s, &de, &mut hs[k * ns..], ng * ns, n);
            st[k] = s;
            for l in 0..LANES {
                let (s0, s1, s2) = (s[0][l], s[1][l], s[2][l]);
                w_acc[l] += wm[k][l] * t * 0.5 * ((old[0][l] + s0) * de[0][l] + (old[1][l] + s1) * de[1][l] + (old[2][l] + s2) * de[2][l]);
                force_lane::<N, BBAR>(&mut fe, &h, &gbe, s0, s1, s2, we[k][l] * t, l);
            }
        }
        scatter_lanes(conn, &fe, &w_acc, wk, f);
    }

    /// The never-yielded packs (`PASS_TOTAL`) compiled for AVX-512 (8 f64 per instruction:
    /// one pack per register, 32 registers; the same bits as `packs`, see `packs_avx2`): it
    /// runs about 1.5 times faster than with AVX2. The stored pass: `packs_stored_avx512`.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq")]
    #[allow(clippy::too_many_arguments)]
    fn packs_total_avx512(
        &self,
        e0: usize,
        e1: usize,
        u: &[[f64; 2]],
        f: SharedForces,
        st: &mut [[[f64; LANES]; 4]],
        hs: &mut [f64],
        up: &mut [[[[f64; LANES]; 2]; N]],
        wk: &mut [f64],
        yl: &mut [bool],
    ) {
        self.packs::<PASS_TOTAL>(e0, e1, u, f, st, hs, up, wk, yl)
    }

    /// The stored packs (`PASS_STORED`) compiled for AVX-512 (the same bits, as
    /// `packs_total_avx512`). Session 10 found this pass slower with AVX-512 than with AVX2;
    /// since the stored stress and last displacements are kept by pack (session 17: whole
    /// registers loaded and stored instead of a lane-by-lane gather), it is as fast in the
    /// never-yielding stored case and 5-10 % faster in the yielding ones (`flem bench laws`,
    /// docs/materials.md).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq")]
    #[allow(clippy::too_many_arguments)]
    fn packs_stored_avx512(
        &self,
        e0: usize,
        e1: usize,
        u: &[[f64; 2]],
        f: SharedForces,
        st: &mut [[[f64; LANES]; 4]],
        hs: &mut [f64],
        up: &mut [[[[f64; LANES]; 2]; N]],
        wk: &mut [f64],
        yl: &mut [bool],
    ) {
        self.packs::<PASS_STORED>(e0, e1, u, f, st, hs, up, wk, yl)
    }

    /// `packs` compiled for AVX2 (4 f64 per instruction instead of SSE2's 2), chosen at run
    /// time. The same operations in the same order (Rust never fuses a multiply and an add,
    /// and the lanes are independent), so the same bits as `packs` on any x86-64.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    fn packs_avx2<const PASS: u8>(
        &self,
        e0: usize,
        e1: usize,
        u: &[[f64; 2]],
        f: SharedForces,
        st: &mut [[[f64; LANES]; 4]],
        hs: &mut [f64],
        up: &mut [[[[f64; LANES]; 2]; N]],
        wk: &mut [f64],
        yl: &mut [bool],
    ) {
        self.packs::<PASS>(e0, e1, u, f, st, hs, up, wk, yl)
    }

    #[allow(clippy::too_many_arguments)]
    fn run_chunk(&self, k: usize, u: &[[f64; 2]], f: SharedForces, st: Raw<[[f64; LANES]; 4]>, hs: Raw<f64>, up: Raw<[[[f64; LANES]; 2]; N]>, wk: Raw<f64>, yl: Raw<bool>) {
        let ce = self.sched.chunk_packs * LANES;
        let (e0, e1) = (k * ce, ((k + 1) * ce).min(self.len()));
        let (ng, ns) = (S::GAUSS.len(), self.law.n_state());
        // SAFETY: chunks are disjoint element ranges (and so disjoint pack ranges: a chunk is
        // whole packs); one chunk runs on one thread.
        let (p0, p1) = (e0 / LANES, e1.div_ceil(LANES));
        let (st, hs, up, wk, yl) = unsafe { (st.range(p0 * ng, p1 * ng), hs.range(e0 * ng * ns, e1 * ng * ns), up.range(p0, p1), wk.range(e0, e1), yl.range(p0, p1)) };
        if self.enh.is_empty() {
            #[cfg(target_arch = "x86_64")]
            if crate::element::block::Simd::best() == crate::element::block::Simd::Avx512 && crate::element::block::Simd::Avx2.detected() {
                // The never-yielded packs first, then the stored ones (a fixed order per chunk,
                // whatever the thread count: the forces' sums stay bit-identical).
                // SAFETY: `Simd::best` answers Avx512 only when the CPU has those features,
                // and AVX2 is checked on the line above (a VM may hide it).
                unsafe {
                    if self.shortcut {
                        self.packs_total_avx512(e0, e1, u, f, st, hs, up, wk, yl);
                        fence();
                    }
                    self.packs_stored_avx512(e0, e1, u, f, st, hs, up, wk, yl);
                }
                return;
            }
            #[cfg(target_arch = "x86_64")]
            if crate::element::block::Simd::best() != crate::element::block::Simd::Plain && crate::element::block::Simd::Avx2.detected() {
                // SAFETY: the CPU has AVX2 (detected just above; `FLEM_SIMD=plain` turns it off
                // as for the elastic kernel).
                unsafe {
                    self.packs_avx2::<PASS_TOTAL>(e0, e1, u, f, st, hs, up, wk, yl);
                    fence();
                    self.packs_avx2::<PASS_STORED>(e0, e1, u, f, st, hs, up, wk, yl);
                }
                return;
            }
            self.packs::<PASS_TOTAL>(e0, e1, u, f, st, hs, up, wk, yl);
            fence();
            self.packs::<PASS_STORED>(e0, e1, u, f, st, hs, up, wk, yl);
            return;
        }
        for i in e0..e1 {
            let (j, q, l) = (i - e0, i / LANES - p0, i % LANES);
            let ue = self.gather(i, u);
            // The element's points and last displacements out of the packs and back.
            let mut se = [[0.0; 4]; MAXG];
            for kk in 0..ng {
                let v = &st[q * ng + kk];
                se[kk] = [v[0][l], v[1][l], v[2][l], v[3][l]];
            }
            let mut upe: [[f64; 2]; N] = std::array::from_fn(|a| [up[q][a][0][l], up[q][a][1][l]]);
            let fe = self.update_elem(i, &ue, &mut se[..ng], &mut hs[j * ng * ns..(j + 1) * ng * ns], &mut upe, &mut wk[j]);
            for kk in 0..ng {
                let v = &mut st[q * ng + kk];
                (v[0][l], v[1][l], v[2][l], v[3][l]) = (se[kk][0], se[kk][1], se[kk][2], se[kk][3]);
            }
            for a in 0..N {
                (up[q][a][0][l], up[q][a][1][l]) = (upe[a][0], upe[a][1]);
            }
            let c = &self.conn[i];
            for a in 0..N {
                // SAFETY: chunks of one colour write disjoint clusters (Schedule::build).
                unsafe { f.add(c[a] as usize, fe[a]) };
            }
        }
    }

    /// The elastic forces of elements `range` by packs (`elastic_pack`: `elastic_force`'s
    /// arithmetic lane by lane, the same bits), the elements scattered in order.
    #[inline(always)]
    fn elastic_range(&self, range: std::ops::Range<usize>, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        let mut i = range.start;
        while i < range.end {
            let p = i / LANES;
            let (l0, l1) = (i - p * LANES, (range.end - p * LANES).min(LANES));
            let fe = if self.bbar() { self.elastic_pack::<true>(p, l0, l1, u) } else { self.elastic_pack::<false>(p, l0, l1, u) };
            for l in l0..l1 {
                let c = &self.conn[p * LANES + l];
                for a in 0..N {
                    f[c[a] as usize][0] += fe[a][0][l];
                    f[c[a] as usize][1] += fe[a][1][l];
                }
            }
            i = p * LANES + l1;
        }
    }

    /// `elastic_range` compiled for AVX2 (ours, issue 37: the power iteration of the stable
    /// step, a fifth of a short plastic run, ran on the baseline instruction set). The same
    /// operations in the same order (no fused multiply-add: the `fma` feature is not enabled),
    /// so the same bits, as `packs_avx2`.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn elastic_range_avx2(&self, range: std::ops::Range<usize>, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        self.elastic_range(range, u, f)
    }

    /// `elastic_range` compiled for AVX-512 (one pack per register, as `packs_total_avx512`;
    /// the same bits: Rust does not contract a multiply and an add into an FMA).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq")]
    fn elastic_range_avx512(&self, range: std::ops::Range<usize>, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        self.elastic_range(range, u, f)
    }

    fn stress3(&self, i: usize, k: usize, u: &[[f64; 2]]) -> [f64; 3] {
        let s = self.stress4(i, k, u);
        [s[0], s[1], s[2]]
    }
}

impl<S: Shape<N>, L: MaterialLaw, const N: usize> Block for StatefulBlock<S, L, N> {
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
    }
    fn add_internal_forces(&self, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        self.add_internal_forces_range(0..self.len(), u, f)
    }
    fn add_internal_forces_pool(&self, u: &[[f64; 2]], f: &mut [[f64; 2]], _pool: Option<&rayon::ThreadPool>) {
        self.add_internal_forces_range(0..self.len(), u, f)
    }
    fn update_internal_forces(&mut self, u: &[[f64; 2]], f: &mut [[f64; 2]], pool: Option<&rayon::ThreadPool>) {
        let shared = SharedForces::new(f);
        let (st, hs, up, wk) = (Raw::new(&mut self.stress), Raw::new(&mut self.hist), Raw::new(&mut self.u_prev), Raw::new(&mut self.work));
        let yl = Raw::new(&mut self.yielded);
        let this = &*self;
        for colour in &this.sched.colours {
            match pool {
                Some(pool) if colour.len() > 1 && this.len() >= PAR_MIN_ELEMS => {
                    use rayon::prelude::*;
                    pool.install(|| colour.par_iter().for_each(|&k| this.run_chunk(k as usize, u, shared, st, hs, up, wk, yl)));
                }
                _ => colour.iter().for_each(|&k| this.run_chunk(k as usize, u, shared, st, hs, up, wk, yl)),
            }
        }
    }
    fn prepare(&mut self, n_clusters: usize) {
        let ng = S::GAUSS.len();
        let np = self.len().div_ceil(LANES);
        self.gp = vec![[[[0.0; LANES]; 2]; N]; np * ng];
        self.gw = vec![[0.0; LANES]; np * ng];
        self.gbar = vec![[[[0.0; LANES]; 2]; N]; np];
        let t = self.mat.thickness;
        let (mut g, mut w) = ([[[0.0; 2]; N]; 4], [0.0; 4]);
        for i in 0..self.len() {
            let (p, l) = (i / LANES, i % LANES);
            let gb = geometry::<S, N>(&self.x[i], &mut g[..ng], &mut w[..ng]);
            for a in 0..N {
                for d in 0..2 {
                    self.gbar[p][a][d][l] = gb[a][d];
                    for k in 0..ng {
                        self.gp[p * ng + k][a][d][l] = g[k][a][d];
                    }
                }
            }
            for k in 0..ng {
                self.gw[p * ng + k][l] = w[k] * t;
            }
        }
        if let Some((_, f)) = self.enh_fn {
            let d = self.d;
            self.enh = self.x.iter().map(|x| f(x, &d, t)).collect();
        }
        self.sched = Schedule::build(&self.conn, n_clusters);
        self.shortcut = self.law.elastic_start() && self.opts.elastic_shortcut && !self.opts.large_strain && self.enh.is_empty();
        (self.tg, self.tx, self.tx_at) = (Vec::new(), Vec::new(), Vec::new());
        self.stored_total = self.kind_total && !self.opts.large_strain && self.enh.is_empty() && ng <= MAXG;
        // (The shortcut implies small strain and no modes: `stored_total` covers it.)
        if self.stored_total {
            let (r, rx) = (S::TOTAL_ROWS, S::TOTAL_EXTRA_ROWS);
            self.tg = vec![[0.0; LANES]; np * r];
            let mut extra = vec![[0.0; LANES]; rx];
            for p in 0..np {
                let i0 = p * LANES;
                // Lanes past the block's end repeat its first element (finite geometry, zero u).
                let xl: [[[f64; 2]; N]; LANES] = std::array::from_fn(|l| self.x[if i0 + l < self.len() { i0 + l } else { 0 }]);
                if S::total_geometry(&xl, &mut self.tg[p * r..(p + 1) * r], &mut extra) {
                    self.tx_at.push(self.tx.len() as u32);
                    self.tx.extend_from_slice(&extra);
                } else {
                    self.tx_at.push(u32::MAX);
                }
            }
        }
    }
    fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        self.elems.capacity() * size_of::<ElemId>()
            + self.x.capacity() * size_of::<[[f64; 2]; N]>()
            + self.u_prev.capacity() * size_of::<[[[f64; LANES]; 2]; N]>()
            + self.conn.capacity() * size_of::<[u32; N]>()
            + self.stress.capacity() * size_of::<[[f64; LANES]; 4]>()
            + (self.hist.capacity() + self.work.capacity()) * 8
            + (self.gp.capacity() + self.gbar.capacity()) * size_of::<[[[f64; LANES]; 2]; N]>()
            + self.gw.capacity() * size_of::<[f64; LANES]>()
            + self.enh.capacity() * size_of::<Enhanced<N>>()
            + (self.tg.capacity() + self.tx.capacity()) * size_of::<[f64; LANES]>()
            + self.tx_at.capacity() * 4
            + self.yielded.capacity()
    }
    fn add_internal_forces_range(&self, range: std::ops::Range<usize>, u: &[[f64; 2]], f: &mut [[f64; 2]]) {
        if self.enh.is_empty() && !self.gp.is_empty() {
            #[cfg(target_arch = "x86_64")]
            if crate::element::block::Simd::best() == crate::element::block::Simd::Avx512 {
                // SAFETY: `Simd::best` answers Avx512 only when the CPU has those features.
                unsafe { self.elastic_range_avx512(range, u, f) };
                return;
            }
            #[cfg(target_arch = "x86_64")]
            if crate::element::block::Simd::best() != crate::element::block::Simd::Plain && crate::element::block::Simd::Avx2.detected() {
                // SAFETY: the CPU has AVX2 (detected just above; `FLEM_SIMD=plain` turns it off).
                unsafe { self.elastic_range_avx2(range, u, f) };
                return;
            }
            self.elastic_range(range, u, f);
            return;
        }
        for i in range {
            let fe = self.elastic_force(i, &self.gather(i, u));
            let c = &self.conn[i];
            for a in 0..N {
                f[c[a] as usize][0] += fe[a][0];
                f[c[a] as usize][1] += fe[a][1];
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
    /// The stress of the Gauss point nearest each corner (the stress lives at the points).
    fn corner_stress(&self, u: &[[f64; 2]], first: &[u32], out: &mut [[f64; 3]]) {
        for i in 0..self.len() {
            let base = first[self.elems[i].idx()] as usize;
            for a in 0..N {
                out[base + a] = self.stress3(i, self.corner_gp[a], u);
            }
        }
    }
    fn gauss_stress(&self, u: &[[f64; 2]], first: &[u32], out: &mut [[f64; 3]]) {
        for i in 0..self.len() {
            let base = first[self.elems[i].idx()] as usize;
            for k in 0..S::GAUSS.len() {
                out[base + k] = self.stress3(i, k, u);
            }
        }
    }
    /// The stress of the Gauss point nearest `xi`.
    fn stress_at(&self, i: usize, u: &[[f64; 2]], xi: [f64; 2]) -> [f64; 3] {
        let d = |k: usize| (S::GAUSS[k].0[0] - xi[0]).powi(2) + (S::GAUSS[k].0[1] - xi[1]).powi(2);
        let k = (0..S::GAUSS.len()).fold(0, |best, k| if d(k) < d(best) { k } else { best });
        self.stress3(i, k, u)
    }
    fn mean_stress(&self, i: usize, u: &[[f64; 2]]) -> [f64; 3] {
        let (mut wsum, mut acc) = (0.0, [0.0; 3]);
        for (k, &(_, w)) in S::GAUSS.iter().enumerate() {
            let s = self.stress3(i, k, u);
            for d in 0..3 {
                acc[d] += w * s[d];
            }
            wsum += w;
        }
        acc.map(|a| a / wsum)
    }
    fn stiffness(&self, i: usize, k: &mut [f64]) {
        let n2 = 2 * N;
        for j in 0..n2 {
            let mut u = [[0.0; 2]; N];
            u[j / 2][j % 2] = 1.0;
            let f = self.elastic_force(i, &u);
            for r in 0..n2 {
                k[r * n2 + j] = f[r / 2][r % 2];
            }
        }
    }
    fn coords(&self, i: usize) -> &[[f64; 2]] {
        &self.x[i]
    }
    fn max_omega_bound(&self) -> f64 {
        *self.omega_bound.get_or_init(|| {
            let mut kbuf = vec![0.0; 4 * N * N];
            let mut best: f64 = 0.0;
            for i in 0..self.len() {
                self.stiffness(i, &mut kbuf);
                let m = element::lumped_mass::<S, N>(&self.x[i], self.mat.density, self.mat.thickness);
                let n2 = 2 * N;
                for r in 0..n2 {
                    let row: f64 = (0..n2).map(|c| kbuf[r * n2 + c].abs() / (m[r / 2] * m[c / 2]).sqrt()).sum();
                    best = best.max(row);
                }
            }
            best.sqrt()
        })
    }
    /// The internal work of the stored points, plus for the packs that never yielded the
    /// elastic energy `1/2 sigma : eps` of their total strain at the last element pass (what
    /// the work of their increments adds up to). One `initial_lanes` per pack and point (not
    /// per element: full steps call this); summed in (pack, point, lane) order.
    fn strain_energy(&self, _u: &[[f64; 2]]) -> Option<f64> {
        let mut e: f64 = self.work.iter().sum();
        if self.shortcut {
            let n = self.len();
            for p in (0..n.div_ceil(LANES)).filter(|&p| !self.yielded[p]) {
                let (i0, i1) = (p * LANES, ((p + 1) * LANES).min(n));
                for k in 0..S::GAUSS.len() {
                    let mut el = [[0.0; LANES]; 4];
                    for i in i0..i1 {
                        let gbi = self.gbar_at(i);
                        let ep = strain_bar(&self.g_at(i, k), self.bbar().then_some(&gbi), &self.up_at(i));
                        (el[0][i - i0], el[1][i - i0], el[2][i - i0]) = (ep[0], ep[1], ep[2]);
                    }
                    let mut s = [[0.0; LANES]; 4];
                    self.law.initial_lanes(&el, &mut s);
                    for i in i0..i1 {
                        let l = i - i0;
                        e += 0.5 * self.w_at(i, k) * (s[0][l] * el[0][l] + s[1][l] * el[1][l] + s[2][l] * el[2][l]);
                    }
                }
            }
        }
        Some(e)
    }
    fn element(&self) -> &'static str {
        self.enh_fn.map_or_else(|| element::default_kind(S::KIND), |(name, _)| name)
    }
    /// A block with modes has a condensed stiffness (`stiffness`), not the plain `B^T D B`.
    fn isoparametric(&self) -> bool {
        self.enh_fn.is_none()
    }
    fn state_len(&self) -> usize {
        self.len() * (2 * N + 4 * S::GAUSS.len()) + self.hist.len() + self.work.len() + self.yielded.len()
    }
    /// Element-major, as before the packs' layout (session 17): the last displacements of each
    /// element, the stress of each point, then history, work and the packs' flags.
    fn save_state(&self, out: &mut Vec<f64>) {
        out.extend((0..self.len()).flat_map(|i| self.up_at(i).into_iter().flatten()));
        out.extend((0..self.len()).flat_map(|i| (0..S::GAUSS.len()).flat_map(move |k| self.stored4(i, k))));
        out.extend_from_slice(&self.hist);
        out.extend_from_slice(&self.work);
        out.extend(self.yielded.iter().map(|&y| if y { 1.0 } else { 0.0 }));
    }
    fn load_state(&mut self, s: &[f64]) -> bool {
        if s.len() != self.state_len() {
            return false;
        }
        let mut it = s.iter().copied();
        for i in 0..self.len() {
            let (p, l) = (i / LANES, i % LANES);
            for a in 0..N {
                for d in 0..2 {
                    self.u_prev[p][a][d][l] = it.next().unwrap_or(0.0);
                }
            }
        }
        let ng = S::GAUSS.len();
        for i in 0..self.len() {
            let (p, l) = (i / LANES, i % LANES);
            for k in 0..ng {
                for c in 0..4 {
                    self.stress[p * ng + k][c][l] = it.next().unwrap_or(0.0);
                }
            }
        }
        for v in self.hist.iter_mut().chain(self.work.iter_mut()) {
            *v = it.next().unwrap_or(0.0);
        }
        for y in self.yielded.iter_mut() {
            *y = it.next().unwrap_or(0.0) != 0.0;
        }
        true
    }
    fn plastic(&self, i: usize) -> Option<(f64, u8)> {
        let ns = self.law.n_state();
        if ns == 0 {
            return None;
        }
        let ng = S::GAUSS.len();
        let (mut gamma, mut wsum, mut flag) = (0.0, 0.0, 0u8);
        for (k, &(_, w)) in S::GAUSS.iter().enumerate() {
            let j = (i * ng + k) * ns;
            let (g, f) = self.law.output(&self.hist[j..j + ns]);
            gamma += w * g;
            wsum += w;
            flag = match (flag, f) {
                (1, _) | (_, 1) => 1,
                (2, _) | (_, 2) => 2,
                _ => 0,
            };
        }
        Some((gamma / wsum, flag))
    }
    /// The stress `[sxx, syy, sxy, szz]` of each Gauss point (element-major; a pack that
    /// never yielded gives the stress of its total strain at the last element pass).
    fn point_stress(&self, u: &[[f64; 2]]) -> Option<Vec<[f64; 4]>> {
        let ng = S::GAUSS.len();
        Some((0..self.len() * ng).map(|j| self.stress4(j / ng, j % ng, u)).collect())
    }
    fn fault(&self) -> Option<String> {
        self.law.fault().map(|f| format!("region \"{}\": {f}", self.region))
    }
    fn implicit(&self) -> Option<Result<Box<dyn crate::element::implicit::ImplicitBlock>, String>> {
        let why = if self.opts.large_strain {
            Some("large strain ([solver] large_strain = true)")
        } else if self.enh_fn.is_some() {
            Some("an element kind with incompatible modes")
        } else {
            None
        };
        Some(match why {
            Some(w) => Err(format!("region \"{}\": the implicit plastic check is small strain on isoparametric elements; this block has {w}", self.region)),
            None => Ok(Box::new(crate::element::implicit_law::LawImplicit::<L, N>::new::<S>(self.law.clone(), &self.x, self.opts.bbar, self.mat.thickness))),
        })
    }
}
