//! The explicit solver: central difference with damping treated implicitly in velocity
//! (METHOD section 7), stages marched to equilibrium (section 8), an energy ledger and the
//! stable time step.
//!
//! Beside it: [`loads`] (supports and loads resolved on the model). The damping trait is a plugin
//! trait (`crate::plugin::damping`).
//!
//! # State
//! `State`: one `Vec` per field (u, v, f_int, f_ext, f_con, mass, fixity, ...) indexed by
//! cluster; a split's `SplitRecord` is applied to every one of them.
//!
//! # The step (`Simulation::step`)
//! 1. `f_int` from every block (no allocation, no per-element dispatch; `element/kernel.rs`).
//! 2. `f_ext` = constant loads (recomputed only when levels change or a split happens) + follower
//!    pressures (only if the scene has any).
//! 3. Contact forces `f_con` (only with `[contact]`: Verlet list, narrow phase, law batch;
//!    `crate::contact`).
//! 4. Damping coefficients from the `Damping` plugin (one call per step); central-difference update
//!    with damping implicit in velocity, in fixed node chunks
//!    (`NodeCtx::update::<CONTACT, LOCAL, FULL, STATS>`: contact and local damping compiled out
//!    when absent; on a CPU with AVX2 the same update two nodes per register, `node_simd.rs`,
//!    bit for bit the same). The stage loop asks for a *full* step (`step_as(true)`: the whole energy
//!    ledger plus the unbalanced-force ratio, fused) only when something reads them after it
//!    (ratio checks every `ratio_every` steps, history rows, snapshots, the last step); other
//!    steps sum only what accumulates (work, damping, contact work; and the kinetic energy,
//!    `u.F`, `u.Mu` if the damping `uses_rayleigh_stats`). The divergence guard runs on full
//!    steps (before any output), on steps that sum the kinetic energy, and before every
//!    checkpoint (`guard_now`). `Simulation::step()` is always full.
//! 5. Failure checks (`crate::cracking`), only if `[cracking]` exists: by default when the stage
//!    reaches equilibrium (`at_equilibrium`; again after each split until a check splits
//!    nothing; `stall_steps` also checks a stage that never comes to rest), or every
//!    `check_every` steps. Nodal stress (corner stress at 0.9999, averaged over each cluster's
//!    copies), criterion (one batch call), separation rule per failed cluster, `Topology::cut`
//!    in order (index desc, cluster id), arrays follow the record, and the stable step is
//!    re-estimated (warm-started power iteration; dt follows it down) unless dt is below the
//!    element bound (safe for any splitting; `iterations = 0` marks the deferred estimate, made
//!    at the stage's end). Corner-stress gradients are computed once per block; with an
//!    `isotropic` criterion (the built-ins) the sigma1 direction (atan2) is computed only at
//!    failing points. Points still beyond the criterion that the rule did not cut (an open
//!    fan's edges all more than 45 deg from sigma1) stay elastic above their strength: the
//!    method has no plasticity; `Cracking::beyond_criterion` counts them (summary.json,
//!    `flem run`).
//! 6. Every `ratio_every` steps: unbalanced-force ratio; a stage ends at its tolerance or step
//!    limit.
//!
//! # Invariants kept here
//! - Stable step: `Simulation::estimate_stable_step` (power iteration on `M^-1/2 K M^-1/2`, times
//!   the damping scheme's `stability_factor`); a `dt` above it is refused unless
//!   `allow_unstable_dt`. With `[contact]` it includes the contact term
//!   `omega^2 = omega_el^2 + 4 k A_max / m_min` (`StableStep::dt_contact`). `flem stability`
//!   measures both (`tools/src/stability.rs`).
//! - Divergence: `step()` stops with `FlemError::Diverged` (step, dt, dt_crit) before anything
//!   non-finite is written; output writers clamp nothing silently (`state_is_finite` in
//!   `output/mod.rs` only guards a diverged state that is never written).
//! - Energy ledger: `Ledger` (trapezoidal work, KE as `1/2 m v- . v+`): exact for linear
//!   elasticity; the contact terms are described in `crate::contact`.
//! - Bit-identical results for any `solver.threads`: the node update sums per fixed node chunk
//!   (`NODE_CHUNK`), the element loop by regions of chunks (`element/kernel.rs`).
//!
//! The stage loop is re-entrant (`run_from(StagePos)`) for checkpoints: `output/checkpoint.rs`.
//! Results leave through the [`Observer`] trait, which the output writer and the comparer
//! (`crate::output`) implement: the solver never depends on them.
pub mod events;
pub mod fos;
pub mod loads;
pub mod march3;
mod node_simd;

use crate::cracking::Cracking;
use crate::element::block::Simd;
use crate::element::model::Model;
use crate::error::{FlemError, Result};
use crate::mesh::topology::SplitRecord;
use crate::plugin::damping::{DampingCoeffs, StepStats};
use crate::scene::Scene;
use crate::solver::loads::Loads;

/// Nodal state, one array per field, indexed by cluster; `D` components per node (2: every
/// scene so far; 3: a 3D model, issue 38, docs/3d.md).
#[derive(Clone, Debug, Default)]
pub struct State<const D: usize = 2> {
    pub u: Vec<[f64; D]>,
    pub v: Vec<[f64; D]>,
    pub f_int: Vec<[f64; D]>,
    pub f_ext: Vec<[f64; D]>,
    /// Contact forces (all zero without `[contact]`).
    pub f_con: Vec<[f64; D]>,
    pub mass: Vec<f64>,
    /// Prescribed-dof bits (1: x, 2: y, 4: z).
    pub fix: Vec<u8>,
    /// Velocity of prescribed dofs.
    pub v_pres: Vec<[f64; D]>,
    pub time: f64,
    pub step: u64,
}

/// Energy ledger (METHOD section 7). With the trapezoidal work sums and the kinetic energy
/// taken as `1/2 m v(n-1/2) . v(n+1/2)`, the balance of the central-difference scheme is exact
/// for linear elasticity, so the residual measures round-off, damping bookkeeping and events
/// (splits, contact) only.
#[derive(Copy, Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Ledger {
    pub external_work: f64,
    pub kinetic: f64,
    pub strain: f64,
    pub damping: f64,
    /// Work of the last half step, not yet part of the balance.
    pub pending_ext: f64,
    pub pending_damp: f64,
    /// Work done by contact forces on the nodes (trapezoidal, like `external_work`).
    #[serde(default)]
    pub contact_work: f64,
    #[serde(default)]
    pub pending_contact: f64,
    /// Elastic energy stored in the contact springs now.
    #[serde(default)]
    pub contact_energy: f64,
    /// Energy dissipated by contacts (friction slip, dashpots, fracture), cumulative.
    #[serde(default)]
    pub contact_dissipated: f64,
    /// The fracture energy in `contact_dissipated` (issue 36: a cohesive law's softening,
    /// `crate::contact::PairForce::fracture`), cumulative; not a separate term of the
    /// residual. Per unit crack length: `crate::output::tips`.
    #[serde(default)]
    pub fracture: f64,
    /// Ours (issue 36): energy put into the discrete system by the path method's node moves
    /// (`cracking::path`): the change of strain energy of the moved node's elements (displacement
    /// kept) and of kinetic energy (masses relumped, velocities kept), cumulative. A move is not
    /// physics: this term keeps it out of the residual and says how large it is. 0 for every
    /// rule that moves no node. Not in the checkpoint's ledger (postcard layout): section
    /// `ledger_relocation`.
    #[serde(skip)]
    pub relocation: f64,
}

impl Ledger {
    pub fn external(&self) -> f64 {
        self.external_work - self.pending_ext
    }
    pub fn dissipated(&self) -> f64 {
        self.damping - self.pending_damp
    }
    /// `W_ext + W_relocation - (KE + U + D + E_contact + D_contact)`.
    pub fn residual(&self) -> f64 {
        self.external() + self.relocation - (self.kinetic + self.strain + self.dissipated() + self.contact_energy + self.contact_dissipated)
    }
    /// The ledger as `summary.json` writes it (2D and 3D runs): the terms of the balance, the
    /// fracture part of `contact_dissipated`, the work contact forces did on the nodes, and the
    /// residual, absolute and relative.
    pub fn summary_json(&self) -> serde_json::Value {
        let mut j = serde_json::json!({"external_work": self.external(), "kinetic": self.kinetic, "strain": self.strain, "damping": self.dissipated(), "contact_energy": self.contact_energy, "contact_dissipated": self.contact_dissipated, "fracture": self.fracture, "residual": self.residual(), "relative_residual": self.relative_residual()});
        if self.relocation != 0.0 {
            // Only runs that moved a node (the path method) have the key: every other summary
            // is as before.
            j["relocation"] = serde_json::json!(self.relocation);
        }
        j
    }
    /// Residual relative to the largest term.
    pub fn relative_residual(&self) -> f64 {
        let scale = self.external().abs().max(self.kinetic.abs() + self.strain.abs() + self.dissipated().abs() + self.contact_energy.abs() + self.contact_dissipated.abs());
        if scale > 0.0 {
            self.residual().abs() / scale
        } else {
            0.0
        }
    }
}

/// The stable step estimate.
#[derive(Copy, Clone, Debug, Default, serde::Serialize)]
pub struct StableStep {
    /// 2 / omega_max with omega_max from power iteration on M^-1 K (free dofs), times the
    /// damping scheme's stability factor.
    pub dt_crit: f64,
    /// 2 / max element omega (Gershgorin bound: always <= the true limit).
    pub dt_element_bound: f64,
    pub omega_max: f64,
    /// Power iterations of the estimate; 0 when the estimate after the last splits was
    /// deferred (see `Simulation::update_stable_step`): `dt_crit` and `omega_max` are then
    /// those before the splits until `Simulation::refresh_stable_step`.
    pub iterations: usize,
    /// 2 / omega_contact (infinite without contact); `dt_crit` uses
    /// `omega = sqrt(omega_max^2 + omega_contact^2)`.
    pub dt_contact: f64,
}

/// Per-stage results.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct StageResult {
    pub name: String,
    pub steps: u64,
    pub converged: bool,
    pub final_ratio: f64,
    pub wall_seconds: f64,
    pub time: f64,
    pub splits: usize,
    pub energy_residual: f64,
    /// Failure checks made in this stage (0 without `[cracking]`).
    #[serde(default)]
    pub checks: u64,
}

/// What a progress callback sees.
#[derive(Copy, Clone, Debug, Default)]
pub struct Progress {
    pub stage: usize,
    pub n_stages: usize,
    pub step: u64,
    pub stage_step: u64,
    pub max_steps: u64,
    pub dt: f64,
    pub ratio: f64,
    pub tolerance: f64,
}

/// Receives what a run produces (the output writer implements it; tests may collect).
pub trait Observer {
    fn history(&mut self, _sim: &Simulation, _stage: usize) -> Result<()> {
        Ok(())
    }
    fn snapshot(&mut self, _sim: &Simulation, _stage: usize, _label: &str) -> Result<()> {
        Ok(())
    }
    fn splits(&mut self, _sim: &Simulation, _rec: &SplitRecord, _events: &[crate::cracking::SplitEvent]) -> Result<()> {
        Ok(())
    }
    fn progress(&mut self, _p: &Progress) {}
    /// After a stage has ended (its result is `sim.stages_done.last()`), after its snapshot.
    fn stage_end(&mut self, _sim: &Simulation, _stage: usize) -> Result<()> {
        Ok(())
    }
    /// Polled once per step: `true` stops the run after this step (a checkpoint, a snapshot
    /// labelled "interrupted", then `FlemError::Interrupted`).
    fn should_stop(&mut self, _sim: &Simulation) -> bool {
        false
    }
    /// Polled once per step: `true` asks for a checkpoint now (e.g. a wall-clock interval).
    fn checkpoint_due(&mut self, _sim: &Simulation) -> bool {
        false
    }
    /// Saves a checkpoint (see `checkpoint.rs`): every `output.checkpoint_every` steps, when
    /// `checkpoint_due`, at the end of every stage and on interruption.
    fn checkpoint(&mut self, _sim: &Simulation, _pos: &StagePos) -> Result<()> {
        Ok(())
    }
}

/// Where the stage loop is: enough to re-enter [`Simulation::run_from`] at step `stage_step`
/// of stage `stage` with the loop's own counters.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StagePos {
    pub stage: usize,
    /// Steps done in this stage.
    pub stage_step: u64,
    /// Whether `begin_stage` (levels, constraints, damping reset) has been applied.
    pub begun: bool,
    /// Splits in this stage so far.
    pub splits: usize,
    /// The loop's last unbalanced ratio.
    pub ratio: f64,
    /// Wall time already spent in this stage (before an interruption).
    pub wall_seconds: f64,
    /// Stall detection: the best ratio so far and the stage step it was reached at.
    pub best_ratio: f64,
    pub best_step: u64,
    /// Failure checks made in this stage so far.
    #[serde(default)]
    pub checks: u64,
}

impl StagePos {
    /// The start of stage `i`.
    pub fn start(i: usize) -> Self {
        StagePos { stage: i, stage_step: 0, begun: false, splits: 0, ratio: f64::INFINITY, wall_seconds: 0.0, best_ratio: f64::INFINITY, best_step: 0, checks: 0 }
    }
}

/// A do-nothing observer.
pub struct NoOutput;
impl Observer for NoOutput {}

pub struct Simulation {
    pub scene: Scene,
    pub model: Model,
    pub loads: Loads,
    pub state: State,
    pub ledger: Ledger,
    pub levels: Vec<f64>,
    pub dt: f64,
    pub stable: StableStep,
    pub warnings: Vec<String>,
    pub cracking: Option<Cracking>,
    /// Contact state, only when the scene has `[contact]`.
    pub contact: Option<crate::contact::Contact>,
    pub stages_done: Vec<StageResult>,
    pub last_ratio: f64,
    /// x0 of every cluster.
    pub x0: Vec<[f64; 2]>,
    pub(crate) f_const: Vec<[f64; 2]>,
    /// Eigenvector of the last stable-step estimate (warm start after splits).
    pub(crate) stable_vec: Vec<[f64; 2]>,
    pub(crate) stats: StepStats,
    pub(crate) coeffs: DampingCoeffs,
    /// Ledger sums of each node chunk of the last step.
    partials: Vec<[f64; NSUM]>,
    /// When `Some`, each step adds the seconds of its parts here: (force pass, node update,
    /// whole step) (`flem bench step`'s task graph, issue 42; `None`: no clock is read).
    #[doc(hidden)]
    pub part_seconds: Option<[f64; 3]>,
    /// The unbalanced-force ratio of the last step when it was a full one.
    step_ratio: Option<f64>,
    scratch: Vec<[f64; 2]>,
    /// The events solver's current event (`[solver] type = "events"`, `events.rs`); `None`
    /// for the explicit solver.
    pub events: Option<events::EventsInfo>,
    /// The events solver's hand-over to the explicit march, when a stage had one
    /// (`events::HandOver`; not kept in checkpoints).
    pub hand_over: Option<events::HandOver>,
}

/// An error of a generated mesh (`[mesh] type = "rectangle"`...), which has no file of its own,
/// renamed to the scene file that describes it.
fn generated_in_scene(e: FlemError, scene: &str) -> FlemError {
    match e {
        FlemError::Config { file, key, msg } if file.starts_with("mesh (") => FlemError::config(scene, key, msg),
        FlemError::Mesh { file, msg } if file.starts_with("mesh (") => FlemError::mesh(format!("{scene}: {file}"), msg),
        e => e,
    }
}

/// Sums of the node update: the ledger's eleven, then (full steps) the unbalanced-force ratio's
/// largest squared residual of a node, the sum of the nodes' applied-force magnitudes and
/// their count (see [`Simulation::unbalanced_ratio`]).
const NSUM: usize = 14;

/// Nodes per chunk of the node update (fixed: the ledger sums must not depend on threads).
pub const NODE_CHUNK: usize = 4096;

/// What the node update reads (`D` components per node).
struct NodeCtx<'a, const D: usize = 2> {
    mass: &'a [f64],
    fix: &'a [u8],
    f_int: &'a [[f64; D]],
    f_ext: &'a [[f64; D]],
    f_con: &'a [[f64; D]],
    v_pres: &'a [[f64; D]],
    dt: f64,
    inv_dt: f64,
    c1: f64,
    c2: f64,
    beta: f64,
    /// The constant-eta term `eta dt / 2` (only read when `DAMP == 3`).
    eta_hdt: f64,
    /// The mass-proportional `a dt / 2` (only read when `DAMP == 3`).
    a_hdt: f64,
}

/// `max |F_unbal| / mean |F_applied|` from the largest residual, the sum of the applied-force
/// magnitudes and their count.
fn ratio_of(num: f64, sum: f64, cnt: f64) -> f64 {
    if cnt == 0.0 || sum == 0.0 {
        return if num == 0.0 { 0.0 } else { f64::INFINITY };
    }
    num / (sum / cnt)
}

/// The node update of a step (see [`NodeCtx::update`]).
type UpdateFn<const D: usize = 2> = fn(&NodeCtx<D>, usize, &mut [[f64; D]], &mut [[f64; D]]) -> [f64; NSUM];

/// [`pick_update`] for a scene's contact flag and damping mode (0 none, 1 viscous, 2 with the
/// local term, 3 with a constant eta) known at run time.
fn pick_variant<const D: usize>(contact: bool, damp: u8, full: bool, stats: bool, simd: Simd) -> UpdateFn<D> {
    match (contact, damp) {
        (false, 0) => pick_update::<D, false, 0>(full, stats, simd),
        (false, 1) => pick_update::<D, false, 1>(full, stats, simd),
        (false, 2) => pick_update::<D, false, 2>(full, stats, simd),
        (false, _) => pick_update::<D, false, 3>(full, stats, simd),
        (true, 0) => pick_update::<D, true, 0>(full, stats, simd),
        (true, 1) => pick_update::<D, true, 1>(full, stats, simd),
        (true, 2) => pick_update::<D, true, 2>(full, stats, simd),
        (true, _) => pick_update::<D, true, 3>(full, stats, simd),
    }
}

/// The node update of a step: the variant of the scene (contact `C`, damping mode `L`) and of
/// the step (`full`, `stats`), vectorised for `simd` when this CPU has it (`node_simd.rs`: the
/// same results bit for bit; 2D only), else the scalar [`NodeCtx::update`].
fn pick_update<const D: usize, const C: bool, const L: u8>(full: bool, stats: bool, simd: Simd) -> UpdateFn<D> {
    let vector = match (full, stats) {
        (true, _) => node_simd::vector_update::<D, C, L, true, true>(simd),
        (false, true) => node_simd::vector_update::<D, C, L, false, true>(simd),
        (false, false) => node_simd::vector_update::<D, C, L, false, false>(simd),
    };
    vector.unwrap_or(match (full, stats) {
        (true, _) => |x, k, u, v| x.update::<C, L, true, true>(k, u, v),
        (false, true) => |x, k, u, v| x.update::<C, L, false, true>(k, u, v),
        (false, false) => |x, k, u, v| x.update::<C, L, false, false>(k, u, v),
    })
}

impl<const D: usize> NodeCtx<'_, D> {
    /// Central-difference update of the clusters `c0..c0 + u.len()`; returns the ledger sums
    /// `[w, dmp, pw, pd, ke, keh, ufi, umu, uf, wc, pc]` of the chunk. `CONTACT = false`
    /// compiles the contact force out (a scene without contact pays nothing for it), `DAMP`
    /// (0 none, 1 viscous, 2 viscous and local, 3 viscous with a constant eta: per-node
    /// coefficients `a = a_mass + eta / m`) the damping terms. `FULL = false` (a step whose ledger nobody reads) sums
    /// only what accumulates over steps (work, damping, contact work), plus the half-step
    /// kinetic energy, `u . F_int` and `u . M u` when `STATS` (a damping that reads them);
    /// `FULL` sums everything. The sums run in four independent lanes (node parity x
    /// dof), so that eleven running sums do not chain one add latency per dof; the lanes are
    /// fixed by position, so the sums do not depend on the number of threads.
    #[inline]
    fn update<const CONTACT: bool, const DAMP: u8, const FULL: bool, const STATS: bool>(&self, c0: usize, u: &mut [[f64; D]], v: &mut [[f64; D]]) -> [f64; NSUM] {
        let mut acc = [[0.0f64; NSUM]; 4];
        let n = u.len();
        let mut i = 0;
        while i + 1 < n {
            let [a0, a1, a2, a3] = &mut acc;
            self.node::<CONTACT, DAMP, FULL, STATS>(c0 + i, &mut u[i], &mut v[i], a0, a1);
            // The same lanes in full and lean steps: the accumulated sums do not depend on
            // which steps were full.
            self.node::<CONTACT, DAMP, FULL, STATS>(c0 + i + 1, &mut u[i + 1], &mut v[i + 1], a2, a3);
            i += 2;
        }
        if i < n {
            let [a0, a1, ..] = &mut acc;
            self.node::<CONTACT, DAMP, FULL, STATS>(c0 + i, &mut u[i], &mut v[i], a0, a1);
        }
        self.reduce(&acc)
    }

    /// The chunk's sums from its four lanes (in a fixed order), with the common factors.
    fn reduce(&self, acc: &[[f64; NSUM]; 4]) -> [f64; NSUM] {
        let (h, hdt) = (0.5, 0.5 * self.dt);
        let mut out = [0.0; NSUM];
        for (k, o) in out.iter_mut().enumerate() {
            // Factors common to every term are applied once, here.
            let f = match k {
                0..=3 | 9 | 10 => hdt,
                4 | 5 => h,
                _ => 1.0,
            };
            *o = if k == 11 { acc[0][k].max(acc[1][k]).max(acc[2][k]).max(acc[3][k]) } else { f * ((acc[0][k] + acc[1][k]) + (acc[2][k] + acc[3][k])) };
        }
        out
    }

    /// One node of [`Self::update`]: its dofs into the lanes `a` (x, and z in 3D) and `b` (y).
    #[inline(always)]
    fn node<const CONTACT: bool, const DAMP: u8, const FULL: bool, const STATS: bool>(&self, c: usize, uc: &mut [f64; D], vc: &mut [f64; D], a: &mut [f64; NSUM], b: &mut [f64; NSUM]) {
        const { assert!(D == 2 || D == 3, "the node update is for 2 or 3 components") };
        let m = self.mass[c];
        // One division per node instead of two per dof (the ledger stays exact to round-off).
        let dt_m = self.dt / m;
        let fix = self.fix[c];
        // A constant eta (the paper's eq. 5) is a different `a` per node: `a = a_mass + eta / m`.
        let (c1, c2) = if DAMP == 3 {
            let h = self.a_hdt + self.eta_hdt / m;
            (1.0 - h, 1.0 / (1.0 + h))
        } else {
            (self.c1, self.c2)
        };
        let (ux, ax) = self.dof::<CONTACT, DAMP, FULL, STATS>(c, 0, fix & 1 == 0, m, dt_m, c1, c2, uc, vc, a);
        let (uy, ay) = self.dof::<CONTACT, DAMP, FULL, STATS>(c, 1, fix & 2 == 0, m, dt_m, c1, c2, uc, vc, b);
        let (mut un, mut ap) = (ux + uy, ax + ay);
        if D == 3 {
            let (uz, az) = self.dof::<CONTACT, DAMP, FULL, STATS>(c, 2, fix & 4 == 0, m, dt_m, c1, c2, uc, vc, a);
            (un, ap) = (un + uz, ap + az);
        }
        if FULL {
            // The unbalanced-force ratio of this step, fused (the same terms, in the same
            // order per node, as `Simulation::unbalanced_ratio`).
            a[11] = a[11].max(un);
            if ap > 0.0 {
                a[12] += ap.sqrt();
                a[13] += 1.0;
            }
        }
    }

    /// One dof: the damped central-difference update and its terms of the ledger (without the
    /// common factors dt/2 and 1/2, see [`Self::update`]); returns (full steps) its squared
    /// unbalanced force and squared applied force.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn dof<const CONTACT: bool, const DAMP: u8, const FULL: bool, const STATS: bool>(
        &self,
        c: usize,
        d: usize,
        free: bool,
        m: f64,
        dt_m: f64,
        c1: f64,
        c2: f64,
        uc: &mut [f64; D],
        vc: &mut [f64; D],
        s: &mut [f64; NSUM],
    ) -> (f64, f64) {
        let dt = self.dt;
        let (fe, fi, vm) = (self.f_ext[c][d], self.f_int[c][d], vc[d]);
        let fc = if CONTACT { self.f_con[c][d] } else { 0.0 };
        let ud = uc[d];
        if FULL {
            s[8] += ud * fi;
        }
        let vp;
        let (un, ap);
        if free {
            let f = if CONTACT { fe + fc - fi } else { fe - fi };
            let fa = if CONTACT { fe + fc } else { fe };
            (un, ap) = (f * f, fa * fa);
            // Local damping only when the scheme asks for it, and branch-free: the sign of a
            // velocity that oscillates would mispredict half the time.
            let fl = if DAMP == 2 { f - self.beta * f.abs() * (((vm > 0.0) as i8 - (vm < 0.0) as i8) as f64) } else { f };
            vp = if DAMP == 0 { vm + dt_m * fl } else { (c1 * vm + dt_m * fl) * c2 };
            // Undamped: the damping force is zero (to round-off) and not summed.
            let fd = if DAMP == 0 { 0.0 } else { f - m * (vp - vm) * self.inv_dt };
            let va = vm + vp;
            // Loads act on few dofs (a boundary): undamped, a predictable branch skips the
            // rest (the same sum: the skipped terms are zeros); damped, the branch-free loop
            // measured faster.
            if DAMP != 0 || fe != 0.0 {
                s[0] += fe * va;
            }
            if DAMP != 0 {
                s[1] += fd * va;
            }
            if CONTACT {
                s[9] += fc * va;
            }
            if FULL {
                s[2] += fe * vp;
                if DAMP != 0 {
                    s[3] += fd * vp;
                }
                if CONTACT {
                    s[10] += fc * vp;
                }
            }
            if FULL || STATS {
                s[6] += ud * fi;
                s[7] += m * ud * ud;
            }
        } else {
            vp = self.v_pres[c][d];
            (un, ap) = (0.0, (fi - fc) * (fi - fc));
            let va = vm + vp;
            s[0] += (fi - fc) * va;
            if CONTACT {
                s[9] += fc * va;
            }
            if FULL {
                s[2] += (fi - fc) * vp;
                if CONTACT {
                    s[10] += fc * vp;
                }
            }
        }
        if FULL {
            s[4] += m * vm * vp;
        }
        if FULL || STATS {
            s[5] += m * vp * vp;
        }
        vc[d] = vp;
        uc[d] = ud + dt * vp;
        (un, ap)
    }
}

/// Issue 35: T3 cells under a material law other than linear elastic (plasticity). A constant
/// strain triangle has one point: B-bar changes nothing, and under (nearly) incompressible
/// plastic flow a triangle mesh locks (too stiff, limit loads too high; docs/materials.md).
/// One warning per material, naming the key and the cure: quadrilaterals (Q4 with B-bar, the
/// default `bbar = true`; `qm6` where the registry has a stateful kernel for it).
fn t3_plastic_warnings(model: &Model, materials: &[crate::element::model::MaterialCfg], file: &str, warnings: &mut Vec<String>) {
    let mesh = &model.mesh;
    let cfg_of = |region: &str| materials.iter().position(|m| m.region == region).or_else(|| materials.iter().position(|m| m.region == "all"));
    let mut count = vec![0usize; materials.len()];
    for (c, r) in mesh.cells.iter().zip(&mesh.cell_region) {
        if c.kind == crate::mesh::CellKind::T3 {
            if let Some(i) = cfg_of(r) {
                count[i] += 1;
            }
        }
    }
    let quads: Vec<&str> = crate::element::registry::kinds().iter().filter(|k| k.cell == crate::mesh::CellKind::Q4 && k.stateful_elastic.is_some()).map(|k| k.name).collect();
    let qm6 = if quads.contains(&"qm6") { "element = \"qm6\", or " } else { "" };
    for (i, m) in materials.iter().enumerate() {
        if count[i] > 0 && m.law.as_ref().is_some_and(|l| !l.is_linear_elastic()) {
            warnings.push(format!(
                "{file}: material[{i}].law: {} T3 (constant-strain triangle) elements under a plastic law lock under plastic flow (one integration point: B-bar changes nothing; collapse loads come out too high): mesh the region with quadrilaterals and use {qm6}Q4 with B-bar (material[{i}].bbar = true, the default){}",
                count[i],
                if qm6.is_empty() { "; qm6 has no kernel for plastic laws" } else { "" }
            ));
        }
    }
}

/// A stage as warnings name it: `"name"`, or `stage[i]` when it has none.
fn stage_label(i: usize, s: &crate::scene::StageCfg) -> String {
    if s.name.is_empty() {
        format!("stage[{i}]")
    } else {
        format!("\"{}\"", s.name)
    }
}

impl Simulation {
    /// Builds the model, resolves loads, separates the declared edges and computes the step.
    pub fn new(scene: Scene) -> Result<Simulation> {
        let file = scene.path.display().to_string();
        let mut mesh = scene.file.mesh.load(&scene.base_dir).map_err(|e| generated_in_scene(e, &file))?;
        if mesh.source.starts_with("mesh (") {
            // A generated mesh has no file of its own: its messages name the scene.
            mesh.source = format!("{file}: {}", mesh.source);
        }
        let mut warnings = mesh.validate(scene.file.model.orientation)?;
        mesh.derive_node_sets();
        for (i, set) in scene.file.sets.iter().enumerate() {
            mesh.add_selection(set, &format!("set[{i}]"), &file)?;
        }
        let opts = crate::element::model::ModelOpts { large_strain: scene.file.solver.large_strain };
        let mut model = Model::new_with(mesh, &scene.file.materials, scene.file.model.plane, opts, &file)?;
        let loads = Loads::new(&model, &scene.file, &file)?;
        // Pre-separated edges.
        for (i, g) in scene.file.model.separated.iter().enumerate() {
            let edges = model.edge_set(g, &format!("model.separated[{i}]"), &file)?;
            let rec = model.topo.separate_edges(&edges);
            model.apply_record(&rec);
        }
        let cracking = match &scene.file.cracking {
            Some(c) => {
                let mut cr = Cracking::new(c, &model, &file, &mut warnings)?;
                if !c.intact.is_empty() {
                    cr.intact = vec![false; model.topo.n_points];
                    for (i, name) in c.intact.iter().enumerate() {
                        for p in model.node_set(name, &format!("cracking.intact[{i}]"), &file)? {
                            cr.intact[p.idx()] = true;
                        }
                    }
                }
                // The path method (ours) never moves a point that carries a boundary condition.
                if c.separation.grows_tips() {
                    cr.path_held = loads.held_points(&model);
                }
                Some(cr)
            }
            None => None,
        };
        if scene.file.cracking.as_ref().is_some_and(|c| c.at_equilibrium) {
            // A dynamic stage never comes to rest, so checks at equilibrium never run in it.
            let dynamic: Vec<String> = scene.file.stages.iter().enumerate().filter(|(_, s)| s.dynamic).map(|(i, s)| stage_label(i, s)).collect();
            if !dynamic.is_empty() {
                warnings.push(format!("{file}: cracking.at_equilibrium = true: failure is never checked in the dynamic stage(s) {} (they do not come to rest); set cracking.at_equilibrium = false and cracking.check_every to crack during them", dynamic.join(", ")));
            }
        }
        t3_plastic_warnings(&model, &scene.file.materials, &file, &mut warnings);
        if loads.has_time || loads.velocity_of_t {
            // A load of t in a stage marched to equilibrium follows the relaxation's pseudo-time.
            let quasi: Vec<String> = scene.file.stages.iter().enumerate().filter(|(_, s)| !s.dynamic).map(|(i, s)| stage_label(i, s)).collect();
            let which: Vec<String> = loads.loads.iter().filter(|l| l.uses_t()).map(|l| format!("\"{}\"", l.name)).collect();
            if !quasi.is_empty() {
                warnings.push(format!(
                    "{file}: load(s) {} are expressions of t, but stage(s) {} march to equilibrium: there t is the relaxation's pseudo-time (it depends on the damping and dt), and a stage may come to rest before the load stops changing; use dynamic = true stages for loads of time",
                    which.join(", "),
                    quasi.join(", ")
                ));
            }
        }
        // The implicit checks are small strain: the linear solve for elastic stages, Newton
        // with the laws' tangents for plastic ones (`output::compare`, issue 37). Large strain
        // has none.
        if scene.file.check.is_some() && scene.file.solver.large_strain {
            return Err(FlemError::config(
                &file,
                "check",
                "compares with a small-strain implicit solve (linear, or Newton for plastic laws); it cannot check [solver] large_strain = true: remove [check]",
            ));
        }
        // `[output] reactions` name node sets: refused here, so that `flem check` sees it.
        for (i, n) in scene.file.output.reactions.iter().enumerate() {
            model.node_set(n, &format!("output.reactions[{i}]"), &file)?;
        }
        let contact = match &scene.file.contact {
            Some(c) => Some(crate::contact::Contact::new(c, &model, &file)?),
            None => None,
        };
        let nc = model.topo.n_clusters();
        let mut mass = model.masses();
        if scene.file.solver.mass_scaling {
            if scene.file.model.gravity != [0.0; 2] || cracking.is_some() || contact.is_some() {
                return Err(FlemError::config(
                    &file,
                    "solver.mass_scaling",
                    "= true needs a scene without gravity (the body force would scale with the masses), cracking and contact (splits recompute the masses)",
                ));
            }
            scale_masses(&model, &mut mass);
        }
        let x0 = model.cluster_x0();
        let mut sim = Simulation {
            levels: vec![0.0; loads.loads.len()],
            loads,
            state: State {
                u: vec![[0.0; 2]; nc],
                v: vec![[0.0; 2]; nc],
                f_int: vec![[0.0; 2]; nc],
                f_ext: vec![[0.0; 2]; nc],
                f_con: vec![[0.0; 2]; nc],
                mass,
                fix: vec![0; nc],
                v_pres: vec![[0.0; 2]; nc],
                time: 0.0,
                step: 0,
            },
            ledger: Ledger::default(),
            dt: 0.0,
            stable: StableStep::default(),
            warnings: Vec::new(),
            cracking,
            contact,
            stages_done: Vec::new(),
            last_ratio: f64::NAN,
            x0,
            f_const: Vec::new(),
            stable_vec: Vec::new(),
            stats: StepStats::default(),
            coeffs: DampingCoeffs::default(),
            partials: Vec::new(),
            part_seconds: None,
            step_ratio: None,
            scratch: Vec::new(),
            events: None,
            hand_over: None,
            scene,
            model,
        };
        sim.warnings.append(&mut warnings);
        sim.model
            .set_threads(sim.scene.file.solver.threads)
            .map_err(|e| FlemError::config(&file, "solver.threads", format!("= {}: the thread pool could not be started: {e}", sim.scene.file.solver.threads)))?;
        sim.apply_constraints_bits();
        if sim.scene.file.solver.kind == crate::scene::SolverKind::Events {
            sim.check_events_scene()?;
        }
        if sim.scene.file.solver.kind == crate::scene::SolverKind::Events {
            // The events solver takes no time step: the element bound stands in for the power
            // iteration (which cost the events runs more than their events: docs/events.md).
            let bound = sim.model.blocks.iter().map(|b| b.max_omega_bound()).fold(0.0, f64::max);
            let k = sim.scene.file.solver.damping.as_ref().map_or(1.0, |d| d.stability_factor());
            let dt = k * 2.0 / bound;
            sim.stable = StableStep { dt_crit: dt, dt_element_bound: dt, omega_max: bound, iterations: 0, dt_contact: f64::INFINITY };
        } else {
            (sim.stable, sim.stable_vec) = sim.power_iteration(None);
        }
        sim.dt = sim.choose_dt(&file)?;
        Ok(sim)
    }

    fn apply_constraints_bits(&mut self) {
        let (fix, vp, _) = self.loads.constraints(&self.model, &self.levels, self.state.time);
        self.state.fix = fix;
        self.state.v_pres = vp;
    }

    fn choose_dt(&mut self, file: &str) -> Result<f64> {
        let s = &self.scene.file.solver;
        let crit = self.stable.dt_crit;
        if !(crit.is_finite() && crit > 0.0) {
            // Extreme (finite) moduli or densities: dt = inf or 0 would write NaN or never move.
            let ratio: Vec<String> = self.scene.file.materials.iter().map(|m| format!("{:e}", m.young_modulus / m.density)).collect();
            return Err(FlemError::config(
                file,
                "material",
                format!("gives a critical time step dt_crit = {crit:e}, which cannot be run (young_modulus / density = {}): rescale the units", ratio.join(", ")),
            ));
        }
        match s.dt {
            None => Ok(s.dt_safety * crit),
            Some(dt) if dt <= crit => Ok(dt),
            Some(dt) if s.allow_unstable_dt => {
                self.warnings.push(format!("{file}: solver.dt = {dt:e} is above the critical step {crit:e} (dt/dt_crit = {:.3}); running anyway because solver.allow_unstable_dt = true", dt / crit));
                Ok(dt)
            }
            Some(dt) => {
                // Say what sets the step: the contact springs when their term dominates.
                let dc = self.stable.dt_contact;
                let by = if dc.is_finite() && dc < self.stable.dt_element_bound {
                    format!(" (set by the contact springs, contact.law normal_stiffness / shear_stiffness: their bound alone is {dc:e})")
                } else {
                    String::new()
                };
                Err(FlemError::config(
                    file,
                    "solver.dt",
                    format!(
                        "= {dt:e} is incorrect; it must be <= the critical step {crit:e} of this mesh{by} (dt/dt_crit = {:.3}); remove it to use {} x dt_crit, or set solver.allow_unstable_dt = true",
                        dt / crit,
                        s.dt_safety
                    ),
                ))
            }
        }
    }

    /// Highest natural frequency by power iteration on `M^-1/2 K M^-1/2` over free dofs.
    pub fn estimate_stable_step(&self) -> StableStep {
        self.power_iteration(None).0
    }

    /// Power iteration from `start` (a previous eigenvector, warm start after splits) or from a
    /// fixed pseudo-random vector; returns the estimate and the eigenvector.
    fn power_iteration(&self, start: Option<Vec<[f64; 2]>>) -> (StableStep, Vec<[f64; 2]>) {
        let n = self.state.mass.len();
        let fix = &self.state.fix;
        let sqm: Vec<f64> = self.state.mass.iter().map(|m| m.sqrt()).collect();
        let mut x = vec![[0.0; 2]; n];
        let mut seed: u64 = 0x9E37_79B9_7F4A_7C15;
        for (c, xc) in x.iter_mut().enumerate() {
            for d in 0..2 {
                seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                if fix[c] & (1 << d) == 0 {
                    xc[d] = ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5;
                }
            }
        }
        if let Some(s) = start {
            // Warm start, with a little of the random vector so no mode is missed.
            for (c, xc) in x.iter_mut().enumerate() {
                for d in 0..2 {
                    if fix[c] & (1 << d) == 0 {
                        xc[d] = s[c][d] + 1e-3 * xc[d];
                    }
                }
            }
        }
        let mut u = vec![[0.0; 2]; n];
        let mut f = vec![[0.0; 2]; n];
        let size = {
            let (lo, hi) = self.model.mesh.bounding_box();
            ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2)).sqrt().max(f64::MIN_POSITIVE)
        };
        let (mut lam, mut prev, mut it) = (0.0f64, 0.0f64, 0usize);
        let mut stable_iters = 0;
        while it < 2000 {
            it += 1;
            let nx: f64 = x.iter().map(|v| v[0] * v[0] + v[1] * v[1]).sum::<f64>().sqrt();
            if nx == 0.0 {
                break;
            }
            let mut umax: f64 = 0.0;
            for c in 0..n {
                for d in 0..2 {
                    x[c][d] /= nx;
                    u[c][d] = x[c][d] / sqm[c];
                    umax = umax.max(u[c][d].abs());
                }
            }
            // Probe with displacements of 1e-9 of the mesh size: exact for linear blocks,
            // the tangent for co-rotational ones.
            let sc = if umax > 0.0 { 1e-9 * size / umax } else { 1.0 };
            u.iter_mut().for_each(|v| *v = [v[0] * sc, v[1] * sc]);
            self.model.internal_forces(&u, &mut f);
            let mut dot = 0.0;
            for c in 0..n {
                for d in 0..2 {
                    let y = if fix[c] & (1 << d) == 0 { f[c][d] / (sc * sqm[c]) } else { 0.0 };
                    dot += x[c][d] * y;
                    x[c][d] = y;
                }
            }
            lam = dot;
            if (lam - prev).abs() <= 1e-7 * lam.abs() {
                stable_iters += 1;
                if stable_iters >= 5 {
                    break;
                }
            } else {
                stable_iters = 0;
            }
            prev = lam;
        }
        let omega_el = lam.max(0.0).sqrt();
        let bound = self.model.blocks.iter().map(|b| b.max_omega_bound()).fold(0.0, f64::max);
        let k = self.scene.file.solver.damping.as_ref().map_or(1.0, |d| d.stability_factor());
        let oc2 = match (&self.contact, &self.scene.file.contact) {
            (Some(c), Some(cfg)) => c.omega2(&self.model, &self.state.mass, fix, cfg.law.stiffness()),
            _ => 0.0,
        };
        let omega = (omega_el * omega_el + oc2).sqrt();
        let dt_contact = if oc2 > 0.0 { 2.0 / oc2.sqrt() } else { f64::INFINITY };
        (StableStep { dt_crit: if omega > 0.0 { k * 2.0 / omega } else { f64::INFINITY }, dt_element_bound: k * 2.0 / bound, omega_max: omega, iterations: it, dt_contact }, x)
    }

    /// After splits: the highest frequency can rise (a split node keeps only part of its mass
    /// and of its stiffness), so the stable step is estimated again, warm-started from the last
    /// eigenvector. If it fell below `dt`, `dt` follows (`dt_safety x dt_crit`) with a warning.
    ///
    /// The estimate is deferred (to the stage's end, [`Self::refresh_stable_step`]) when the
    /// step in use is provably stable whatever the splits: below the element-by-element bound
    /// (the highest frequency of an assembly with lumped masses is at most the highest element
    /// frequency, however the elements share nodes; with contact, combined with the contact
    /// term of the new masses), and the damping does not read `omega_max`. A scene that checks
    /// every step then does not pay a power iteration per split.
    ///
    /// After a node move (the path method) the warm start carries the moved points' clusters as
    /// large as the whole vector (ours, session 35; docs/paths.md "Session 35"). The events
    /// solver calls this for the vector only; its own loop decides on an estimate.
    fn update_stable_step(&mut self, rec: &SplitRecord) {
        // New clusters start from their parent's entry of the last eigenvector.
        if !self.stable_vec.is_empty() {
            for nc in &rec.new_clusters {
                let v = self.stable_vec[nc.parent.idx()];
                self.stable_vec.push(v);
            }
            // A moved node (the path method, ours) can make a mode around it stiffer than the
            // last eigenvector's. Warm-started from that vector (plus 1e-3 of noise, absolute:
            // next to a vector of the size of omega_max^2 it is no safeguard), the power
            // iteration sees no change for five iterations and stops before the new mode has
            // grown: measured, the shear test's explicit march on `shear_t3_1` kept dt = 1.004 of
            // the new critical step after a move and diverged 1300 steps later (session 35).
            // The start gets the moved points' clusters as large as the whole vector, so the new
            // mode has a share of the start of the order of one. Only moves: the other rules'
            // runs are unchanged, bit for bit. (Review r35c: a mode polarised against (1, 1), or
            // one on another corner of the moved element, gets a smaller share; a split without
            // a move keeps the old start.) A vector grown by many spikes without an estimate
            // between them is rescaled first, and a non-finite one dropped (a cold start).
            if !rec.moved.is_empty() {
                let mut norm = self.stable_vec.iter().map(|v| v[0] * v[0] + v[1] * v[1]).sum::<f64>().sqrt();
                if norm > 1e150 && norm.is_finite() {
                    self.stable_vec.iter_mut().for_each(|v| *v = [v[0] / norm, v[1] / norm]);
                    norm = 1.0;
                }
                if norm.is_finite() {
                    for (p, _) in &rec.moved {
                        for &c in &self.model.topo.point_clusters[p.idx()] {
                            self.stable_vec[c.idx()] = [norm, norm];
                        }
                    }
                } else {
                    self.stable_vec.clear();
                }
            }
        }
        let uses_omega = self.scene.file.solver.damping.as_deref().is_none_or(|d| d.uses_rayleigh_stats());
        // The events solver (events.rs) takes no time step: no new estimate per event.
        if self.scene.file.solver.kind == crate::scene::SolverKind::Events || !uses_omega && self.dt <= self.safe_step_bound() {
            self.stable.iterations = 0;
            return;
        }
        self.estimate_again();
    }

    /// A step that is stable for any splitting of the current mesh: the element bound, with
    /// the contact term of the current masses (the same combination as `dt_crit`). The element
    /// bound is of the unscaled masses: with `mass_scaling` it is no bound, which is safe only
    /// because scaling is refused with cracking and contact (review r18).
    fn safe_step_bound(&self) -> f64 {
        let k = self.scene.file.solver.damping.as_ref().map_or(1.0, |d| d.stability_factor());
        let w_el = 2.0 * k / self.stable.dt_element_bound;
        let oc2 = match (&self.contact, &self.scene.file.contact) {
            (Some(c), Some(cfg)) => c.omega2(&self.model, &self.state.mass, &self.state.fix, cfg.law.stiffness()),
            _ => 0.0,
        };
        let w = (w_el * w_el + oc2).sqrt();
        if w > 0.0 {
            k * 2.0 / w
        } else {
            f64::INFINITY
        }
    }

    /// Estimates the stable step again if the last splits deferred it (`iterations == 0`).
    pub fn refresh_stable_step(&mut self) {
        if self.stable.iterations == 0 {
            self.estimate_again();
        }
    }

    /// Power iteration warm-started from the last eigenvector (cold without one).
    fn estimate_again(&mut self) {
        let start = std::mem::take(&mut self.stable_vec);
        let (st, x) = self.power_iteration((!start.is_empty()).then_some(start));
        self.stable_vec = x;
        self.stable = st;
        let s = &self.scene.file.solver;
        if self.dt > st.dt_crit && !s.allow_unstable_dt {
            let new = s.dt_safety * st.dt_crit;
            self.warnings.push(format!("step {}: after a split the critical step fell to {:e}; dt lowered from {:e} to {new:e}", self.state.step, st.dt_crit, self.dt));
            self.dt = new;
        }
    }

    /// Sets the load levels of stage `i` and imposes its constraints.
    fn begin_stage(&mut self, i: usize) {
        let st = &self.scene.file.stages[i];
        for (name, &v) in &st.levels {
            if let Some(k) = self.loads.loads.iter().position(|l| &l.name == name) {
                self.levels[k] = v;
            }
        }
        let (fix, vp, up) = self.loads.constraints(&self.model, &self.levels, self.state.time);
        self.state.fix = fix;
        self.state.v_pres = vp;
        // A prescribed velocity is imposed at once: the kinetic energy it adds is work done on
        // the body (without it the ledger, and the divergence guard built on it, see energy
        // appear from nothing).
        let st = &mut self.state;
        for c in 0..st.v.len() {
            for d in 0..2 {
                if st.fix[c] & (1 << d) != 0 && st.v[c][d] != st.v_pres[c][d] {
                    self.ledger.external_work += 0.5 * st.mass[c] * (st.v_pres[c][d].powi(2) - st.v[c][d].powi(2));
                    st.v[c][d] = st.v_pres[c][d];
                }
            }
        }
        if !up.is_empty() {
            // A jump of prescribed displacement injects the change of strain energy at once.
            let before = self.strain_energy();
            for (c, d, val) in up {
                self.state.u[c][d] = val;
                self.state.v[c][d] = 0.0;
            }
            let after = self.strain_energy();
            self.ledger.external_work += after - before;
            self.ledger.strain = after;
        }
        self.refresh_constant_force();
        self.scene.file.solver.damping().reset();
    }

    /// Applies the load levels and constraints of stages `0..=i` without stepping (what a
    /// static solve of stage `i` needs: levels, fixities, prescribed displacements).
    pub fn set_stage_levels(&mut self, i: usize) {
        for k in 0..=i.min(self.scene.file.stages.len().saturating_sub(1)) {
            self.begin_stage(k);
        }
    }

    pub(crate) fn refresh_constant_force(&mut self) {
        let mut f = std::mem::take(&mut self.f_const);
        self.loads.constant_force(&self.model, &self.levels, &self.state.mass, &mut f);
        self.f_const = f;
        if !self.loads.has_follower && !self.loads.has_time {
            // Without following pressures or loads of time the external force is this constant
            // part: set it here (levels changed or a split happened), not in every step.
            self.state.f_ext.copy_from_slice(&self.f_const);
        }
    }

    /// The external force at the current load levels, per cluster: the constant part (gravity,
    /// fixed-direction edge loads, point loads) plus following pressures on the reference
    /// configuration (u = 0), as a linear static solve sees them, and loads of time at the
    /// current time (an error when such an expression is not finite there).
    pub fn external_force(&self) -> Result<Vec<[f64; 2]>> {
        let mut f = Vec::new();
        self.loads.constant_force(&self.model, &self.levels, &self.state.mass, &mut f);
        if self.loads.has_follower || self.loads.has_time {
            let zero = vec![[0.0; 2]; f.len()];
            self.loads.add_step_force(&self.model, &self.levels, &self.x0, &zero, self.state.time, &mut f)?;
        }
        Ok(f)
    }

    /// Strain energy: `1/2 u . F_int` for linear blocks, the local energy of co-rotational ones.
    pub fn strain_energy(&self) -> f64 {
        self.model.strain_energy(&self.state.u, &mut Vec::new())
    }

    /// One central-difference step, with the whole energy ledger.
    pub fn step(&mut self) -> Result<()> {
        self.step_as(true)
    }

    /// One step; `full = false` leaves the ledger's snapshot terms (kinetic, strain and the
    /// pending half-step works) as they were at the last full step and updates only the terms
    /// that accumulate (work, damping, contact work), so that the stage loop pays for the
    /// ledger only on the steps after which it is read (ratio checks, history rows, snapshots,
    /// the stage's last step). Displacements and velocities are the same either way.
    pub fn step_as(&mut self, full: bool) -> Result<()> {
        self.step_checked(full, false)
    }

    /// [`Self::step_as`]; `check_follows`: the caller checks failure right after this step,
    /// before anything reads the failure index (the stage loop with a check every step), so a
    /// skipped check's displacement need not be kept (`Cracking::before_step`).
    fn step_checked(&mut self, full: bool, check_follows: bool) -> Result<()> {
        if let Some(cr) = self.cracking.as_mut() {
            cr.before_step(&self.state.u, check_follows);
        }
        let dt = self.dt;
        let t0 = self.part_seconds.map(|_| std::time::Instant::now());
        self.model.update_internal_forces(&self.state.u, &mut self.state.f_int);
        let t_force = t0.map(|t| t.elapsed().as_secs_f64());
        if self.loads.has_follower || self.loads.has_time {
            self.state.f_ext.copy_from_slice(&self.f_const);
            self.loads.add_step_force(&self.model, &self.levels, &self.x0, &self.state.u, self.state.time, &mut self.state.f_ext)?;
        }
        if let (Some(c), Some(cfg)) = (self.contact.as_mut(), self.scene.file.contact.as_ref()) {
            let (stored, diss) = c.compute(cfg.law.as_ref(), &self.x0, &self.state.u, &self.state.v, dt, &mut self.state.f_con);
            self.ledger.contact_energy = stored;
            self.ledger.contact_dissipated += diss;
            self.ledger.fracture += c.fracture_step;
        }
        self.coeffs = self.scene.file.solver.damping().coeffs(&self.stats);
        let corot_strain = if full && (self.model.corotational || self.model.stateful) { Some(self.model.strain_energy(&self.state.u, &mut self.scratch)) } else { None };
        let stats = self.scene.file.solver.damping.as_deref().is_some_and(|d| d.uses_rayleigh_stats());
        // Prescribed velocities of time (a ramp): their value at the step's middle, and the
        // work of the inertial force that changes them (`Loads::ramp_velocities`).
        let (w_ramp, pw_ramp) = if self.loads.velocity_of_t {
            self.loads.ramp_velocities(&self.model, &self.levels, self.state.time + 0.5 * dt, &self.state.v, &self.state.mass, &mut self.state.v_pres)?
        } else {
            (0.0, 0.0)
        };
        let t1 = self.part_seconds.map(|_| std::time::Instant::now());
        let sum = self.update_nodes(full, stats, Simd::best());
        let t_node = t1.map(|t| t.elapsed().as_secs_f64());
        let [w, dmp, pw, pd, ke, keh, ufi, umu, uf, wc, pc, num, asum, cnt] = sum;
        self.step_ratio = full.then(|| ratio_of(num.sqrt(), asum, cnt));
        self.ledger.external_work += w + w_ramp;
        self.ledger.damping += dmp;
        self.ledger.contact_work += wc;
        if full {
            self.ledger.pending_ext = pw + pw_ramp;
            self.ledger.pending_damp = pd;
            self.ledger.pending_contact = pc;
            self.ledger.kinetic = ke;
            self.ledger.strain = corot_strain.unwrap_or(0.5 * uf);
        }
        self.state.time += dt;
        self.state.step += 1;
        if full || stats {
            self.stats = StepStats { step: self.state.step, dt, omega_max: self.stable.omega_max, kinetic: keh, u_f_int: ufi, u_m_u: umu };
            self.guard(keh)?;
        } else {
            self.stats.step = self.state.step;
        }
        if let (Some(p), Some(t0), Some(tf), Some(tn)) = (self.part_seconds.as_mut(), t0, t_force, t_node) {
            *p = [p[0] + tf, p[1] + tn, p[2] + t0.elapsed().as_secs_f64()];
        }
        Ok(())
    }

    /// The node update of a step (the central-difference update of every cluster with the
    /// current damping coefficients, `NodeCtx::update`) and its ledger sums; `full`: every sum,
    /// `stats`: the damping's Rayleigh sums too; vectorised for `simd` if this CPU has it.
    fn update_nodes(&mut self, full: bool, stats: bool, simd: Simd) -> [f64; NSUM] {
        let dt = self.dt;
        let (a, beta, eta) = (self.coeffs.viscous, self.coeffs.local, self.coeffs.eta);
        let (c1, c2) = (1.0 - 0.5 * a * dt, 1.0 / (1.0 + 0.5 * a * dt));
        // Node update in fixed chunks; the ledger sums are added chunk by chunk in chunk order,
        // so they do not depend on the number of threads.
        let State { u, v, f_int, f_ext, f_con, mass, fix, v_pres, .. } = &mut self.state;
        let ctx = NodeCtx { mass, fix, f_int, f_ext, f_con, v_pres, dt, inv_dt: 1.0 / dt, c1, c2, beta, eta_hdt: 0.5 * eta * dt, a_hdt: 0.5 * a * dt };
        // One monomorphised node update per combination: a step pays only for what the scene
        // has and for what is read after it.
        // Damping: 0 none, 1 viscous only, 2 with the local term, 3 with a constant eta (the
        // paper's; with a local term too, the local term is dropped: no scheme asks for both).
        let damp = if eta != 0.0 {
            3
        } else if beta != 0.0 {
            2
        } else if a != 0.0 {
            1
        } else {
            0
        };
        let update = pick_variant(self.contact.is_some(), damp, full, stats, simd);
        let n_chunks = u.len().div_ceil(NODE_CHUNK);
        if self.partials.len() != n_chunks {
            self.partials.resize(n_chunks, [0.0; NSUM]);
        }
        match self.model.pool.as_deref() {
            Some(pool) if n_chunks > 1 => {
                use rayon::prelude::*;
                let par = u.par_chunks_mut(NODE_CHUNK).zip(v.par_chunks_mut(NODE_CHUNK)).zip(self.partials.par_iter_mut()).enumerate();
                pool.install(|| par.for_each(|(k, ((u, v), s))| *s = update(&ctx, k * NODE_CHUNK, u, v)));
            }
            _ => {
                let seq = u.chunks_mut(NODE_CHUNK).zip(v.chunks_mut(NODE_CHUNK)).zip(self.partials.iter_mut()).enumerate();
                seq.for_each(|(k, ((u, v), s))| *s = update(&ctx, k * NODE_CHUNK, u, v));
            }
        }
        let mut sum = [0.0; NSUM];
        for p in &self.partials {
            for (k, (s, x)) in sum.iter_mut().zip(p).enumerate() {
                *s = if k == 11 { f64::max(*s, *x) } else { *s + x };
            }
        }
        sum
    }

    /// The node update alone, as a lean step of the scene runs it, with the code of `simd`
    /// (`Simd::Plain`: the scalar one; timed by `flem bench step`). It moves the nodes and
    /// keeps no ledger and no time.
    #[doc(hidden)]
    pub fn bench_node_update(&mut self, simd: Simd) {
        let stats = self.scene.file.solver.damping.as_deref().is_some_and(|d| d.uses_rayleigh_stats());
        std::hint::black_box(self.update_nodes(false, stats, simd));
    }

    /// The divergence guard on the half-step kinetic energy `keh`. It runs on every full step
    /// (so before anything is written) and every step whose damping reads the step's sums;
    /// the stage loop also runs [`Self::guard_now`] before a checkpoint.
    fn guard(&self, keh: f64) -> Result<()> {
        if !keh.is_finite() || keh > 1e12 * self.ledger.external_work.abs().max(1e-300) && keh > 1e-200 {
            return Err(self.diverged(if keh.is_finite() { "the kinetic energy grew beyond 1e12 times the work done on the body" } else { "velocities became non-finite" }));
        }
        Ok(())
    }

    /// [`Self::guard`] on the current velocities (one pass over the nodes).
    pub fn guard_now(&self) -> Result<()> {
        let st = &self.state;
        let keh: f64 = st.v.iter().zip(&st.mass).map(|(v, m)| 0.5 * m * (v[0] * v[0] + v[1] * v[1])).sum();
        self.guard(keh)
    }

    fn diverged(&self, why: &str) -> FlemError {
        // A dynamic plugin that failed or returned a non-finite number (it then wrote NaN):
        // its error, naming it, instead of a bare divergence (issue 25).
        let fault = self
            .model
            .blocks
            .iter()
            .find_map(|b| b.fault())
            .or_else(|| self.scene.file.contact.as_ref().and_then(|c| c.law.fault()))
            .or_else(|| self.scene.file.solver.damping.as_ref().and_then(|d| d.fault()));
        if let Some(f) = fault {
            return FlemError::Solve(format!("the run stopped at step {} (t = {:.6e}): {f}", self.state.step, self.state.time));
        }
        FlemError::Diverged { step: self.state.step, time: self.state.time, dt: self.dt, dt_crit: self.stable.dt_crit, ratio: self.dt / self.stable.dt_crit, why: why.to_string() }
    }

    /// Unbalanced-force ratio `max |F_unbal| / mean |F_applied|` of the last step (free dofs;
    /// applied = external force on free dofs and the reaction on prescribed ones).
    pub fn unbalanced_ratio(&self) -> f64 {
        let st = &self.state;
        let (mut num, mut sum, mut cnt) = (0.0f64, 0.0f64, 0usize);
        for c in 0..st.u.len() {
            let (mut un, mut ap) = (0.0, 0.0);
            for d in 0..2 {
                let (fe, fi) = (st.f_ext[c][d] + st.f_con[c][d], st.f_int[c][d]);
                if st.fix[c] & (1 << d) == 0 {
                    un += (fe - fi) * (fe - fi);
                    ap += fe * fe;
                } else {
                    ap += (fi - st.f_con[c][d]).powi(2);
                }
            }
            num = num.max(un);
            if ap > 0.0 {
                sum += ap.sqrt();
                cnt += 1;
            }
        }
        ratio_of(num.sqrt(), sum, cnt as f64)
    }

    /// Reaction on the points `pts` (every cluster of each): the sum over prescribed dofs of
    /// `f_int - f_ext - f_con`, the force the supports or the prescribed motion apply to the
    /// body (`m a = f_ext + f_con - f_int + R`, so `R = f_int - f_ext - f_con` at rest).
    pub fn reaction(&self, pts: &[crate::ids::PointId]) -> [f64; 2] {
        let st = &self.state;
        let mut r = [0.0; 2];
        for p in pts {
            for c in &self.model.topo.point_clusters[p.idx()] {
                let c = c.idx();
                for (d, rd) in r.iter_mut().enumerate() {
                    if st.fix[c] & (1 << d) != 0 {
                        *rd += st.f_int[c][d] - st.f_ext[c][d] - st.f_con[c][d];
                    }
                }
            }
        }
        r
    }

    /// [`Self::unbalanced_ratio`] of the last step: computed with it when that step was full.
    fn step_unbalanced_ratio(&self) -> f64 {
        self.step_ratio.unwrap_or_else(|| self.unbalanced_ratio())
    }

    /// Runs every stage.
    pub fn run(&mut self, obs: &mut dyn Observer) -> Result<()> {
        self.run_from(StagePos::start(0), obs)
    }

    /// Runs from a position (a restored checkpoint's) to the end of the last stage.
    pub fn run_from(&mut self, pos: StagePos, obs: &mut dyn Observer) -> Result<()> {
        for i in pos.stage..self.scene.file.stages.len() {
            self.run_stage_from(if i == pos.stage { pos.clone() } else { StagePos::start(i) }, obs)?;
        }
        Ok(())
    }

    /// Marches stage `i` to equilibrium (or its step limit, or its fixed step count when dynamic).
    pub fn run_stage(&mut self, i: usize, obs: &mut dyn Observer) -> Result<()> {
        self.run_stage_from(StagePos::start(i), obs)
    }

    /// [`Self::run_stage`] entered at `pos` (re-entrant: a resumed run continues with the
    /// loop's counters as they were).
    pub fn run_stage_from(&mut self, pos: StagePos, obs: &mut dyn Observer) -> Result<()> {
        if self.scene.file.solver.kind == crate::scene::SolverKind::Events {
            return self.run_stage_events(pos, obs);
        }
        let t0 = std::time::Instant::now();
        let i = pos.stage;
        if !pos.begun {
            self.begin_stage(i);
        }
        let st = self.scene.file.stages[i].clone();
        let sc = &self.scene.file.solver;
        let (max_steps, tol, every) = (st.max_steps.unwrap_or(sc.max_steps), st.tolerance.unwrap_or(sc.tolerance), sc.ratio_every);
        let hist_every = self.scene.file.output.history_every;
        let snap_every = self.scene.file.output.snapshot_every;
        let split_snap = self.scene.file.output.snapshot_on_split;
        let (check_every, check_at_eq, stall_steps) = match self.scene.file.cracking.as_ref() {
            Some(c) if c.at_equilibrium => (0, true, c.stall_steps),
            Some(c) => (c.check_every, false, 0),
            None => (0, false, 0),
        };
        // Stall detection (at_equilibrium mode): the best ratio and the step it was last halved.
        let (mut best, mut best_step) = (pos.best_ratio, pos.best_step);
        let n_stages = self.scene.file.stages.len();
        let ck_every = self.scene.file.output.checkpoint_every;
        let k0 = pos.stage_step;
        let mut k = k0;
        let mut converged = false;
        let mut splits = pos.splits;
        let mut ratio = pos.ratio;
        let mut checks = pos.checks;
        let here = |k: u64, splits: usize, ratio: f64, best_ratio: f64, best_step: u64, checks: u64| StagePos {
            stage: i,
            stage_step: k,
            begun: true,
            splits,
            ratio,
            wall_seconds: pos.wall_seconds + t0.elapsed().as_secs_f64(),
            best_ratio,
            best_step,
            checks,
        };
        while k < max_steps {
            if k > k0 {
                // Once per step, between two steps (the state is whole here).
                let stop = obs.should_stop(self);
                if stop || (ck_every > 0 && self.state.step % ck_every == 0) || obs.checkpoint_due(self) {
                    // A lean step does not run the divergence guard: nothing diverged is saved.
                    self.guard_now()?;
                    obs.checkpoint(self, &here(k, splits, ratio, best, best_step, checks))?;
                }
                if stop {
                    obs.snapshot(self, i, "interrupted")?;
                    return Err(FlemError::Interrupted { step: self.state.step, stage: i, stage_step: k });
                }
            }
            // The ledger is summed in full only on steps after which it is read.
            let kn = k + 1;
            // `end_time` (dynamic stages): the step that reaches it is the stage's last.
            let last = kn == max_steps || st.end_time.is_some_and(|te| self.state.time + 1.5 * self.dt >= te);
            // A dynamic stage does not stop at equilibrium: its ratio is taken only on steps
            // that are full for another reason (and at its end).
            let full = (!st.dynamic && kn % every == 0)
                || last
                || (hist_every > 0 && kn % hist_every == 0)
                || (snap_every > 0 && kn % snap_every == 0)
                || (split_snap && check_every > 0 && kn % check_every == 0);
            self.step_checked(full, check_every == 1)?;
            k += 1;
            if check_every > 0 && k % check_every == 0 {
                splits += self.check_failure(obs)?;
                checks += 1;
            }
            if (k % every == 0 && (full || !st.dynamic)) || last {
                ratio = self.step_unbalanced_ratio();
                self.last_ratio = ratio;
                if ratio < 0.5 * best {
                    (best, best_step) = (ratio, k);
                }
                if check_at_eq && stall_steps > 0 && !st.dynamic && k - best_step >= stall_steps {
                    // Not coming to rest (a mechanism): check anyway, then watch again.
                    splits += self.check_failure(obs)?;
                    checks += 1;
                    (best, best_step) = (ratio, k);
                }
                if !st.dynamic && ratio < tol && k >= 2 * every {
                    if check_at_eq {
                        let n = self.check_failure(obs)?;
                        checks += 1;
                        splits += n;
                        if n > 0 {
                            continue;
                        }
                    }
                    converged = true;
                    break;
                }
            }
            if k % 256 == 0 {
                obs.progress(&Progress { stage: i, n_stages, step: self.state.step, stage_step: k, max_steps, dt: self.dt, ratio, tolerance: tol });
            }
            // The stage's last step gets its row at the stage end (below), not twice.
            if hist_every > 0 && k % hist_every == 0 && k < max_steps && !last {
                obs.history(self, i)?;
            }
            if snap_every > 0 && k % snap_every == 0 {
                obs.snapshot(self, i, &format!("{}_step{}", i, k))?;
            }
            if last {
                break;
            }
        }
        ratio = self.unbalanced_ratio();
        self.last_ratio = ratio;
        self.refresh_stable_step();
        let name = if st.name.is_empty() { format!("stage{i}") } else { st.name.clone() };
        if !st.dynamic && !converged && checks == 0 && self.cracking.is_some() {
            // Checks at equilibrium never ran: the stage may hold cracks nobody looked for.
            let file = self.scene.path.display();
            self.warnings.push(format!(
                "{file}: stage \"{name}\" ended at its step limit ({k} steps, unbalanced ratio {ratio:.2e}) without equilibrium and failure was never checked in it (cracking.at_equilibrium = true checks only once a stage comes to rest): cracks it would show are hidden; set cracking.at_equilibrium = false with cracking.check_every (the paper's checks during the march), or cracking.stall_steps"
            ));
        }
        if st.dynamic {
            converged = true;
        }
        self.stages_done.push(StageResult {
            name,
            steps: k,
            converged,
            final_ratio: ratio,
            wall_seconds: pos.wall_seconds + t0.elapsed().as_secs_f64(),
            time: self.state.time,
            splits,
            energy_residual: self.ledger.relative_residual(),
            checks,
        });
        obs.history(self, i)?;
        if st.snapshot {
            obs.snapshot(self, i, &format!("stage{i}"))?;
        }
        obs.stage_end(self, i)?;
        obs.checkpoint(self, &StagePos::start(i + 1))?;
        // The last step of a stage is polled here (the run is complete after the last stage).
        if i + 1 < n_stages && obs.should_stop(self) {
            obs.snapshot(self, i, "interrupted")?;
            return Err(FlemError::Interrupted { step: self.state.step, stage: i + 1, stage_step: 0 });
        }
        Ok(())
    }

    /// Failure check: proposes and applies splits, then makes every per-cluster array follow.
    fn check_failure(&mut self, obs: &mut dyn Observer) -> Result<usize> {
        self.check_failure_with(obs, true)
    }

    /// [`Self::check_failure`]; `book_moves`: the path method's node moves go to the ledger's
    /// `relocation` term (a march: explicit steps, the events solver's hand-over). The events
    /// part passes false: its ledger is the event state's strain energy alone (external work =
    /// strain, no balance), which a booked move would turn into a false residual.
    pub(crate) fn check_failure_with(&mut self, obs: &mut dyn Observer, book_moves: bool) -> Result<usize> {
        let Some(cr) = self.cracking.as_mut() else { return Ok(0) };
        let cfg = self.scene.file.cracking.as_ref().expect("cracking config");
        let (rec, events) = cr.check(cfg, &mut self.model, &self.state.u, &self.x0, self.state.time, self.state.step)?;
        let move_strain = std::mem::take(&mut cr.move_strain);
        if rec.is_empty() {
            return Ok(0);
        }
        // Node moves (ours, the path method): the energy they change goes to the ledger's
        // `relocation` term (strain: the moved elements' change at the kept displacement;
        // kinetic: the relumped masses at the kept velocities). Only when a node moved: the
        // other rules' ledgers are untouched, bit for bit.
        let ke = |m: &[f64], v: &[[f64; 2]]| 0.5 * m.iter().zip(v).map(|(m, v)| m * (v[0] * v[0] + v[1] * v[1])).sum::<f64>();
        let ke0 = (book_moves && !rec.moved.is_empty()).then(|| ke(&self.state.mass, &self.state.v));
        self.apply_split_record(&rec);
        if let Some(ke0) = ke0 {
            self.ledger.relocation += move_strain + ke(&self.state.mass, &self.state.v) - ke0;
        }
        obs.splits(self, &rec, &events)?;
        Ok(events.len())
    }

    /// Grows the per-cluster arrays for new clusters (same displacement and velocity as the
    /// parent), recomputes masses, fixities and the constant loads.
    pub fn apply_split_record(&mut self, rec: &SplitRecord) {
        self.apply_split_arrays(rec);
        if !rec.moved.is_empty() {
            // A node moved (ours, the path method): the element bound of the stable step
            // follows the new shapes before the step is judged stable.
            let bound = self.model.blocks.iter().map(|b| b.max_omega_bound()).fold(0.0, f64::max);
            let k = self.scene.file.solver.damping.as_ref().map_or(1.0, |d| d.stability_factor());
            if bound > 0.0 {
                self.stable.dt_element_bound = self.stable.dt_element_bound.min(k * 2.0 / bound);
            }
        }
        self.update_stable_step(rec);
    }

    /// The per-cluster arrays of [`Self::apply_split_record`] without the new stable-step
    /// estimate (a checkpoint restores that itself).
    pub(crate) fn apply_split_arrays(&mut self, rec: &SplitRecord) {
        // The forces changed: the fused ratio of the last step no longer describes them.
        self.step_ratio = None;
        let st = &mut self.state;
        for nc in &rec.new_clusters {
            let p = nc.parent.idx();
            let (u, v, vp) = (st.u[p], st.v[p], st.v_pres[p]);
            st.u.push(u);
            st.v.push(v);
            st.v_pres.push(vp);
            st.f_int.push([0.0; 2]);
            st.f_ext.push([0.0; 2]);
            st.f_con.push([0.0; 2]);
            self.x0.push(self.model.mesh.points[nc.point.idx()]);
        }
        // Points moved before the cut (ours, the path method): every cluster there takes the
        // new reference position (the displacement is kept: the node carries its own).
        for (p, x) in &rec.moved {
            for &c in &self.model.topo.point_clusters[p.idx()] {
                self.x0[c.idx()] = *x;
            }
        }
        st.mass = self.model.masses();
        let (fix, vpres, _) = self.loads.constraints(&self.model, &self.levels, st.time);
        // Keep the velocities of prescribed dofs as they were (no new jump).
        st.fix = fix;
        st.v_pres = vpres;
        self.refresh_constant_force();
        if let (Some(c), Some(cfg)) = (self.contact.as_mut(), self.scene.file.contact.as_ref()) {
            c.on_split(cfg.law.as_ref(), &self.model, rec, &self.x0, &self.state.u);
        }
    }
}

/// Mass scaling to a common stable step (ours, `[solver] mass_scaling`, issue 37): `G_i` the
/// larger of node `i`'s two Gershgorin row sums of the assembled elastic stiffness (bounded by
/// the sum over its elements of their row sums `sum_c |K_e(r, c)|`), every node's mass is
/// lowered to `G_i / max_j (G_j / m_j)`. Gershgorin's bound on the highest frequency of the
/// lumped system, `w^2 <= max_i G_i / m_i`, is then the same as before, and every node has it:
/// the nodes of large or soft elements, whose own stable step was longer than the mesh's, get
/// lighter, their waves faster, and a quasi-static stage reaches rest there in fewer steps
/// (FLAC's density scaling for static solutions does the same with a step of 1). A node
/// without stiffness keeps its mass.
pub fn scale_masses(model: &crate::element::model::Model, mass: &mut [f64]) {
    let mut g = vec![[0.0f64; 2]; mass.len()];
    let mut k = Vec::new();
    for b in &model.blocks {
        let n2 = 2 * b.nodes_per_elem();
        k.resize(n2 * n2, 0.0);
        for i in 0..b.len() {
            b.stiffness(i, &mut k);
            let conn = b.conn(i);
            for r in 0..n2 {
                let row: f64 = k[r * n2..(r + 1) * n2].iter().map(|x| x.abs()).sum();
                g[conn[r / 2] as usize][r % 2] += row;
            }
        }
    }
    let gi: Vec<f64> = g.iter().map(|g| g[0].max(g[1])).collect();
    let top = gi.iter().zip(mass.iter()).filter(|(g, m)| **g > 0.0 && **m > 0.0).map(|(g, m)| g / m).fold(0.0, f64::max);
    if top > 0.0 {
        for (m, g) in mass.iter_mut().zip(&gi) {
            if *g > 0.0 {
                *m = m.min(g / top);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The node update in 3D (issue 38) against the central-difference formulas by hand, for
    /// every damping mode: a free node under a force, with viscous damping
    /// `v+ = ((1 - a dt/2) v- + dt F / m) / (1 + a dt/2)`, `u+ = u- + dt v+`; a node with z fixed
    /// takes the prescribed z velocity; a 3D node whose z force is zero and z fixed moves in x
    /// and y exactly as the same 2D node does (the 2D update is the reference). Tolerance 1e-15
    /// relative (the same operations).
    #[test]
    fn node_update_in_three_dimensions() {
        let dt = 0.01;
        let (m, f, v0, u0) = (2.0, [3.0, -1.0, 0.5], [0.1, 0.2, -0.3], [1.0, 2.0, 3.0]);
        for (a, beta) in [(0.0, 0.0), (4.0, 0.0), (0.0, 0.2)] {
            let (c1, c2) = (1.0 - 0.5 * a * dt, 1.0 / (1.0 + 0.5 * a * dt));
            let damp = if beta != 0.0 {
                2
            } else if a != 0.0 {
                1
            } else {
                0
            };
            for fix in [0u8, 4] {
                let (mass, fixv, f_int, f_ext, f_con, v_pres) = (vec![m], vec![fix], vec![[0.0; 3]], vec![f], vec![[0.0; 3]], vec![[0.0, 0.0, 0.7]]);
                let ctx = NodeCtx::<3> { mass: &mass, fix: &fixv, f_int: &f_int, f_ext: &f_ext, f_con: &f_con, v_pres: &v_pres, dt, inv_dt: 1.0 / dt, c1, c2, beta, eta_hdt: 0.0, a_hdt: 0.5 * a * dt };
                let (mut u, mut v) = (vec![u0], vec![v0]);
                let up = pick_variant::<3>(false, damp, true, false, Simd::best());
                let sums = up(&ctx, 0, &mut u, &mut v);
                for d in 0..3 {
                    let want_v = if d == 2 && fix == 4 {
                        0.7
                    } else {
                        let fd = if beta != 0.0 { f[d] - beta * f[d].abs() * v0[d].signum() } else { f[d] };
                        if damp == 0 {
                            v0[d] + dt / m * fd
                        } else {
                            (c1 * v0[d] + dt / m * fd) * c2
                        }
                    };
                    assert!((v[0][d] - want_v).abs() <= 1e-15 * want_v.abs().max(1.0), "a {a} beta {beta} fix {fix} dof {d}: {} vs {want_v}", v[0][d]);
                    assert!((u[0][d] - (u0[d] + dt * want_v)).abs() <= 1e-15 * u0[d].abs().max(1.0));
                }
                // External work of the step: dt/2 F . (v- + v+) over the free dofs.
                let w: f64 = (0..3).filter(|&d| !(d == 2 && fix == 4)).map(|d| 0.5 * dt * f[d] * (v0[d] + v[0][d])).sum();
                assert!(damp != 0 || (sums[0] - w).abs() <= 1e-15 * w.abs().max(1e-12), "{} vs {w}", sums[0]);
                if fix == 4 {
                    // x and y as the 2D update of the same node.
                    let (f2, c2d, p2) = (vec![[f[0], f[1]]], vec![[0.0; 2]], vec![[0.0; 2]]);
                    let ctx2 = NodeCtx::<2> { mass: &mass, fix: &[0], f_int: &c2d, f_ext: &f2, f_con: &c2d, v_pres: &p2, dt, inv_dt: 1.0 / dt, c1, c2, beta, eta_hdt: 0.0, a_hdt: 0.5 * a * dt };
                    let (mut u2, mut v2) = (vec![[u0[0], u0[1]]], vec![[v0[0], v0[1]]]);
                    pick_variant::<2>(false, damp, true, false, Simd::Plain)(&ctx2, 0, &mut u2, &mut v2);
                    assert_eq!((u2[0], v2[0]), ([u[0][0], u[0][1]], [v[0][0], v[0][1]]));
                }
            }
        }
    }
}
