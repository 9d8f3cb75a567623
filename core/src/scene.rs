//! Scenes: TOML files parsed into raw structs that reject unknown keys, then validated into a
//! [`Scene`] whose errors name the file, the key and the allowed range.
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

pub use crate::element::model::MaterialCfg;
use crate::element::Plane;
use crate::error::{nearest, FlemError, Result};
pub use crate::expr::LoadValue;
use crate::mesh::{MeshSource, SetCfg, ValidationOptions};
use crate::plugin::check::CheckCfg;
use crate::plugin::damping::Damping;
use crate::plugin::traits::{FailureCriterion, ParamError, SeparationRule};

/// The scene file as written (after defaults).
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    #[serde(default)]
    pub title: String,
    pub mesh: Box<dyn MeshSource>,
    /// `[[set]]`: node and edge sets chosen by geometry (crate::mesh::SetCfg).
    #[serde(default, rename = "set", skip_serializing_if = "Vec::is_empty")]
    pub sets: Vec<SetCfg>,
    #[serde(default)]
    pub model: ModelCfg,
    #[serde(rename = "material")]
    pub materials: Vec<MaterialCfg>,
    #[serde(default)]
    pub solver: SolverCfg,
    #[serde(default, rename = "support")]
    pub supports: Vec<SupportCfg>,
    #[serde(default, rename = "load")]
    pub loads: Vec<LoadCfg>,
    #[serde(rename = "stage")]
    pub stages: Vec<StageCfg>,
    #[serde(default)]
    pub output: OutputCfg,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cracking: Option<CrackingCfg>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plugins: Option<PluginsCfg>,
    /// `[check]`: compare each stage with the implicit solve (crate::plugin::check).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub check: Option<CheckCfg>,
    /// `[contact]`: contact between faces (crate::contact).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact: Option<crate::contact::ContactCfg>,
}

/// `[plugins] load = ["path/to/libfoo.so"]`: dynamic plugin libraries loaded before the rest
/// of the scene is read.
#[derive(Debug, Clone, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct PluginsCfg {
    #[serde(default)]
    pub load: Vec<String>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelCfg {
    /// "strain" (default) or "stress".
    #[serde(default)]
    pub plane: Plane,
    /// Gravity acceleration vector, e.g. [0, -9.81].
    #[serde(default)]
    pub gravity: [f64; 2],
    /// Edge sets separated from the start (a notch, a pre-cut plane).
    #[serde(default)]
    pub separated: Vec<String>,
    /// "reorient" clockwise elements with a warning (default) or "refuse" them.
    #[serde(default)]
    pub orientation: ValidationOptions,
}

impl Default for ModelCfg {
    fn default() -> Self {
        ModelCfg { plane: Plane::Strain, gravity: [0.0; 2], separated: Vec::new(), orientation: ValidationOptions::Reorient }
    }
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverCfg {
    /// Time step; default: `dt_safety` x the computed critical step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dt: Option<f64>,
    #[serde(default = "default_safety")]
    pub dt_safety: f64,
    /// Accept a `dt` above the critical step with a warning instead of an error.
    #[serde(default)]
    pub allow_unstable_dt: bool,
    /// Filled in by [`Scene::from_str`] with "adaptive" when the scene names none. A built-in
    /// or a loaded plugin's scheme (`plugin::dynload::de_damping`).
    #[serde(default, skip_serializing_if = "Option::is_none", deserialize_with = "crate::plugin::dynload::de_damping")]
    pub damping: Option<Box<dyn Damping>>,
    /// Unbalanced-force ratio at which a stage is in equilibrium.
    #[serde(default = "default_tol")]
    pub tolerance: f64,
    /// Step limit of a stage.
    #[serde(default = "default_max_steps")]
    pub max_steps: u64,
    /// Steps between evaluations of the unbalanced-force ratio.
    #[serde(default = "default_ratio_every")]
    pub ratio_every: u64,
    /// Worker threads of the element loop and the node update (0: one per available core).
    /// Results are bit-identical whatever the number (deterministic scatter, see `kernel`).
    #[serde(default = "one_usize")]
    pub threads: usize,
    /// Updated Lagrangian kinematics with the Jaumann rate for every law
    /// (`crate::element::stateful`); default false: small strain.
    #[serde(default)]
    pub large_strain: bool,
    /// Mass scaling to a common stable step (ours, issue 37; off by default: it changes the
    /// dynamics, so it is for stages that march to rest or push slowly, whose answer is the
    /// state at rest): every node's lumped mass lowered to `G_i / max_j (G_j / m_j)`, `G_i` its
    /// Gershgorin row sum of the elastic stiffness, so that every node has the highest node's
    /// `G / m` (`Simulation::new`, docs/materials.md). The stable step is estimated on the scaled
    /// masses. Refused with gravity (the body force would scale with the masses) and with
    /// cracking or contact (splits recompute the masses).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub mass_scaling: bool,
    /// The stage solver: `"explicit"` (the paper's damped relaxation, the default) or
    /// `"events"` (ours, issue 19: one linear solve per crack event, `solver::events`,
    /// docs/events.md; scenes with cracking and linear elements; contact only for the
    /// hand-over of a loose fragment to the explicit march).
    #[serde(default, rename = "type")]
    pub kind: SolverKind,
    /// With `type = "events"`: at most this many events per stage (a guard; default 100000).
    #[serde(default = "default_max_events")]
    pub max_events: u64,
    /// With `type = "events"`: events solved by a low-rank update of the kept factorisation
    /// before a fresh one (0: a fresh factorisation at every event; docs/events.md).
    #[serde(default = "default_refactor_every")]
    pub refactor_every: usize,
    /// With `type = "events"` (ours, issue 35): what a stage does when a split leaves a fragment
    /// without support (the linear solve is singular): `"hand_over"` (the default) continues
    /// the stage in the explicit march from the last solved state until the fragment comes to
    /// rest or leaves (`solver::events::hand_over`, docs/events.md); `"stop"` ends the run there.
    #[serde(default)]
    pub on_loose_fragment: LooseFragment,
    /// Hand-over: a cluster that moved this far from where the hand-over found it (a fraction
    /// of the mesh's bounding-box diagonal) has left: the stage ends (default 0.1).
    #[serde(default = "default_hand_over_distance")]
    pub hand_over_distance: f64,
    /// Hand-over: explicit steps at most (default 100000; reached: the stage ends with a warning).
    #[serde(default = "default_hand_over_max_steps")]
    pub hand_over_max_steps: u64,
    /// Hand-over: at rest when the kinetic energy is below this fraction of the largest energy
    /// moved in the explicit part and the unbalanced ratio below the stage's tolerance
    /// (default 1e-6).
    #[serde(default = "default_hand_over_rest")]
    pub hand_over_rest: f64,
}

/// `[solver] on_loose_fragment` (events solver, ours).
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LooseFragment {
    /// Continue the stage in the explicit march (ours, issue 35).
    #[default]
    HandOver,
    /// End the run at the singular solve, naming the fragment (the events solver before issue 35).
    Stop,
}

fn default_hand_over_distance() -> f64 {
    0.1
}
fn default_hand_over_max_steps() -> u64 {
    100_000
}
fn default_hand_over_rest() -> f64 {
    1e-6
}

fn default_refactor_every() -> usize {
    50
}

/// The stage solver (`[solver] type`).
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SolverKind {
    /// Damped explicit relaxation (the paper's method).
    #[default]
    Explicit,
    /// Ours: sequentially linear events (`solver::events`).
    Events,
}

fn default_max_events() -> u64 {
    100_000
}

fn default_safety() -> f64 {
    0.8
}
fn default_tol() -> f64 {
    1e-6
}
fn default_max_steps() -> u64 {
    1_000_000
}
fn default_ratio_every() -> u64 {
    10
}
fn one_usize() -> usize {
    1
}

impl SolverCfg {
    /// The damping scheme (always present once the scene is validated).
    pub fn damping(&mut self) -> &mut dyn Damping {
        self.damping.as_deref_mut().expect("Scene::from_str fills in the default damping")
    }
}

impl Default for SolverCfg {
    fn default() -> Self {
        SolverCfg {
            dt: None,
            dt_safety: default_safety(),
            allow_unstable_dt: false,
            damping: None,
            tolerance: default_tol(),
            max_steps: default_max_steps(),
            ratio_every: default_ratio_every(),
            threads: 1,
            large_strain: false,
            mass_scaling: false,
            kind: SolverKind::Explicit,
            max_events: default_max_events(),
            refactor_every: default_refactor_every(),
            on_loose_fragment: LooseFragment::HandOver,
            hand_over_distance: default_hand_over_distance(),
            hand_over_max_steps: default_hand_over_max_steps(),
            hand_over_rest: default_hand_over_rest(),
        }
    }
}

/// Fixed directions on a node set.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SupportCfg {
    pub nodes: String,
    /// "x", "y" or "xy".
    pub fix: String,
}

/// Loads. Each has a `name`; a stage's `levels` scale it (levels start at 0 and keep their
/// value from stage to stage until a stage changes them).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum LoadCfg {
    /// Pressure on an edge set, positive pushing into the body. `follow = false` (the paper's):
    /// direction fixed at the initial edge normal; `true`: follows the deformed edge.
    Pressure {
        name: String,
        edges: String,
        /// A number, or an expression of x, y, t (`crate::expr`).
        value: LoadValue,
        #[serde(default)]
        follow: bool,
    },
    /// Traction vector (force per length per thickness) on an edge set, fixed direction. Each
    /// component a number or an expression of x, y, t.
    Traction { name: String, edges: String, value: [LoadValue; 2] },
    /// Force on every point of a node set (each component a number or an expression).
    Point { name: String, nodes: String, value: [LoadValue; 2] },
    /// Prescribed velocity of a node set (components not given are free). Each component a
    /// number or an expression of x, y, t (`crate::expr`; issue 36: a ramp such as
    /// `"16.5 * min(t / 1e-6, 1)"`), evaluated at the middle of every step (the velocity of the
    /// central-difference half step); the kinetic energy the prescribed nodes gain is work done
    /// on the body (`solver::loads::Loads::ramp_velocities`).
    Velocity {
        name: String,
        nodes: String,
        #[serde(default)]
        x: Option<LoadValue>,
        #[serde(default)]
        y: Option<LoadValue>,
    },
    /// Prescribed displacement of a node set, applied at the start of each stage.
    Displacement {
        name: String,
        nodes: String,
        #[serde(default)]
        x: Option<f64>,
        #[serde(default)]
        y: Option<f64>,
    },
}

impl LoadCfg {
    pub fn name(&self) -> &str {
        match self {
            LoadCfg::Pressure { name, .. } | LoadCfg::Traction { name, .. } | LoadCfg::Point { name, .. } | LoadCfg::Velocity { name, .. } | LoadCfg::Displacement { name, .. } => name,
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StageCfg {
    #[serde(default)]
    pub name: String,
    /// Load levels set by this stage, by load name.
    #[serde(default)]
    pub levels: BTreeMap<String, f64>,
    /// Overrides solver.max_steps for this stage.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_steps: Option<u64>,
    /// Overrides solver.tolerance for this stage.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Run a fixed number of steps (dynamics) instead of marching to equilibrium.
    #[serde(default)]
    pub dynamic: bool,
    /// With `dynamic = true` (issue 36): the stage ends at this run time (the first step that
    /// reaches it to within half a step), or at its step limit if that comes first.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub end_time: Option<f64>,
    /// Write a snapshot at the end of the stage.
    #[serde(default = "yes")]
    pub snapshot: bool,
    /// Compare this stage with the implicit check (`[check]`, `flem compare`); false: reported
    /// as not comparable (e.g. a stage meant to run through a collapse).
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub check: bool,
}

fn is_true(b: &bool) -> bool {
    *b
}

fn yes() -> bool {
    true
}

/// A probe: a named point whose displacement goes into the history.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeCfg {
    pub name: String,
    /// The point nearest to these coordinates.
    pub at: [f64; 2],
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputCfg {
    /// Steps between history rows (0: only at stage ends).
    #[serde(default = "default_hist")]
    pub history_every: u64,
    /// Steps between extra VTU snapshots inside a stage (0: only at stage ends).
    #[serde(default)]
    pub snapshot_every: u64,
    #[serde(default)]
    pub probes: Vec<ProbeCfg>,
    /// Node sets whose reaction (the sum over their prescribed dofs of `f_int - f_ext -
    /// f_con`, the force the supports or prescribed motion apply to the body) goes into
    /// history.csv as `reaction_<set>_x`, `reaction_<set>_y` (the last columns).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub reactions: Vec<String>,
    /// zlib-compress VTU arrays.
    #[serde(default)]
    pub compress: bool,
    /// Steps (global count) between checkpoints (0: none by step count); crack events in
    /// `solver.type = "events"` stages. A checkpoint is also written at the end of every stage
    /// and when the run is interrupted.
    #[serde(default)]
    pub checkpoint_every: u64,
    /// Wall-clock seconds between checkpoints (0: none by time).
    #[serde(default = "default_ck_seconds")]
    pub checkpoint_seconds: f64,
    /// Checkpoints kept (the newest ones; at least 1).
    #[serde(default = "default_ck_keep")]
    pub checkpoint_keep: usize,
    /// Also write a snapshot after every failure check that split something (the frames of a
    /// running crack, as the paper's figure 11).
    #[serde(default)]
    pub snapshot_on_split: bool,
    /// Draw the pictures (PNG and SVG in `plots/`, as `flem plot`) at the end of `flem run`.
    #[serde(default)]
    pub plots: bool,
    /// The time window of the crack-tip speed in `crack_tips.csv` (`crate::output::tips`;
    /// ours, issue 36); default 10 x the mean element edge over the Rayleigh speed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tip_window: Option<f64>,
}

fn default_ck_seconds() -> f64 {
    600.0
}
fn default_ck_keep() -> usize {
    2
}

fn default_hist() -> u64 {
    1000
}

impl Default for OutputCfg {
    fn default() -> Self {
        OutputCfg {
            history_every: default_hist(),
            snapshot_every: 0,
            probes: Vec::new(),
            reactions: Vec::new(),
            compress: false,
            checkpoint_every: 0,
            checkpoint_seconds: default_ck_seconds(),
            checkpoint_keep: default_ck_keep(),
            snapshot_on_split: false,
            plots: false,
            tip_window: None,
        }
    }
}

/// `[cracking]`: failure checks and node splitting.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CrackingCfg {
    /// A built-in (typetag) or a plugin from a `[plugins] load` library (`dynload`).
    #[serde(deserialize_with = "crate::plugin::dynload::de_criterion")]
    pub criterion: Box<dyn FailureCriterion>,
    #[serde(deserialize_with = "crate::plugin::dynload::de_separation")]
    pub separation: Box<dyn SeparationRule>,
    /// Steps between failure checks, when `at_equilibrium = false`.
    #[serde(default = "default_check_every")]
    pub check_every: u64,
    /// Check failure only once the stage has reached equilibrium (default: damped relaxation
    /// overshoots, and its transient stresses are not the static ones); after splits the
    /// stage relaxes again and checks again, until a check splits nothing. A quasi-static
    /// variant of ours: the paper checks during the march (`false` with `check_every`, METHOD
    /// 8). A stage that never comes to rest is then never checked: it ends with a warning
    /// (`Simulation::warnings`, summary.json, `flem run`).
    #[serde(default = "yes")]
    pub at_equilibrium: bool,
    /// With `at_equilibrium`: also check when the stage has not come to rest, i.e. its best
    /// unbalanced-force ratio has not halved within this many steps (default 0: off). A
    /// fragment held by one node (a hinge left by a running crack) is a mechanism under load
    /// control and never reaches equilibrium, so its last node is never checked without this;
    /// with it, the checks see the transient states of that mechanism (not static ones).
    #[serde(default = "default_stall_steps")]
    pub stall_steps: u64,
    /// At most this many splits per check (the most critical first).
    #[serde(default = "default_max_splits")]
    pub max_splits_per_check: usize,
    /// Optional Weibull scatter of strengths.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weibull: Option<WeibullCfg>,
    /// Ours, not the paper's (issue 18): the stress handed to the criterion at a node is the
    /// area-weighted mean of the Gauss-point stresses within `radius` of it, never across an
    /// open crack (`cracking::nonlocal`, docs/nonlocal.md). Absent: the paper's corner mean.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nonlocal: Option<NonlocalCfg>,
    /// Ours (session 33): node sets (`[[set]]` names or the mesh's groups) whose points never
    /// split. For the ends of an idealised boundary condition (the edge of a displaced strip, the
    /// end of a clamped edge), where the elastic stress is singular and the experiment's plates
    /// and bolts spread the load. Their points are still evaluated (failure index, VTU) and a
    /// point beyond the criterion counts in `beyond_criterion`. Empty (default): every point may split.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub intact: Vec<String>,
}

/// `[cracking] nonlocal = { radius = R }` (ours; docs/nonlocal.md).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NonlocalCfg {
    /// Averaging radius, in the mesh's length unit (Euclidean distance in the reference
    /// configuration from the node to each Gauss point).
    pub radius: f64,
    /// How a Gauss point's area weight falls off with its distance `r` from the node:
    /// `uniform` (the default: every point within `radius` counts by its area alone) or `bell`
    /// (ours too: times `(1 - r^2/R^2)^2`, Bazant and Jirasek's truncated quartic).
    #[serde(default, skip_serializing_if = "NonlocalWeight::is_uniform")]
    pub weight: NonlocalWeight,
    /// Crack tracking (ours, after Cervera and Chiumenti's exclusion radius): once a crack
    /// exists, a point within this distance of a crack edge may split only where it is a crack
    /// tip (the joined end of an edge separated at its other end). Absent: every point may split.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exclusion: Option<f64>,
}

/// The distance weight of the nonlocal average (`[cracking] nonlocal.weight`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NonlocalWeight {
    /// Every Gauss point within the radius counts by the area it stands for.
    #[default]
    Uniform,
    /// The area times `(1 - r^2/R^2)^2` (Bazant and Jirasek 2002, eq. 14: the truncated
    /// quartic "bell"): points near the node count most, points at the radius not at all.
    Bell,
}

impl NonlocalWeight {
    pub fn is_uniform(&self) -> bool {
        *self == NonlocalWeight::Uniform
    }
    /// The factor on the area weight of a Gauss point at squared distance `r2` (radius `r`).
    #[inline]
    pub fn factor(&self, r2: f64, radius: f64) -> f64 {
        match self {
            NonlocalWeight::Uniform => 1.0,
            NonlocalWeight::Bell => {
                let q = 1.0 - r2 / (radius * radius);
                if q > 0.0 {
                    q * q
                } else {
                    0.0
                }
            }
        }
    }
}

fn default_check_every() -> u64 {
    10
}
fn default_stall_steps() -> u64 {
    0
}
fn default_max_splits() -> usize {
    1
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WeibullCfg {
    pub modulus: f64,
    #[serde(default)]
    pub seed: u64,
}

/// A validated scene.
#[derive(Debug)]
pub struct Scene {
    pub file: SceneFile,
    /// The scene file's path (for messages) and folder (for relative paths).
    pub path: PathBuf,
    pub base_dir: PathBuf,
}

/// Largest magnitude of a material constant, load value, level, gravity or probe coordinate:
/// products of a few such values must stay finite in f64 (1e300 would overflow in the first
/// step and only show as a divergence).
pub const MAX_MAGNITUDE: f64 = 1e100;

fn range(file: &str, key: &str, v: f64, lo: f64, lo_incl: bool, hi: f64, hi_incl: bool) -> Result<()> {
    ParamError::range(key, v, lo, lo_incl, hi, hi_incl).map_err(|e| FlemError::config(file, e.key, e.msg))
}

impl Scene {
    /// Reads and validates a scene file.
    pub fn from_file(path: &Path) -> Result<Scene> {
        let text = std::fs::read_to_string(path).map_err(|e| FlemError::config(path.display().to_string(), "", format!("cannot be read: {e}")))?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Scene::from_str(&text, path, &base)
    }

    /// Parses and validates scene text; `path` is used in messages, `base_dir` for relative paths.
    pub fn from_str(text: &str, path: &Path, base_dir: &Path) -> Result<Scene> {
        let name = path.display().to_string();
        crate::plugin::dynload::load_scene_plugins(text, &name, base_dir)?;
        let mut file: SceneFile = toml::from_str(text).map_err(|e| parse_error(&name, text, e))?;
        if file.solver.damping.is_none() {
            // The default: adaptive dynamic relaxation (a plugin; an error, not a panic, when the
            // binary does not link the plugin crate).
            let d = toml::from_str("type = \"adaptive\"").map_err(|e| {
                FlemError::config(&name, "solver.damping", format!("is not given and the default \"adaptive\" is not registered in this program ({e}); link flem-plugins or name a damping"))
            })?;
            file.solver.damping = Some(d);
        }
        if let Some(c) = file.check.as_mut() {
            c.fill_default(&name)?;
        }
        let scene = Scene { file, path: path.to_path_buf(), base_dir: base_dir.to_path_buf() };
        scene.validate()?;
        Ok(scene)
    }

    fn validate(&self) -> Result<()> {
        let f = &self.file;
        let n = self.path.display().to_string();
        if f.materials.is_empty() {
            return Err(FlemError::config(&n, "material", "is missing; give at least one [[material]]"));
        }
        for (i, set) in f.sets.iter().enumerate() {
            set.validate(i, &n)?;
            if f.sets[..i].iter().any(|o| o.name == set.name) {
                return Err(FlemError::config(&n, format!("set[{i}].name"), format!("= \"{}\" is used twice; set names must be unique", set.name)));
            }
        }
        for (i, m) in f.materials.iter().enumerate() {
            let k = |s: &str| format!("material[{i}].{s}");
            range(&n, &k("young_modulus"), m.young_modulus, 0.0, false, MAX_MAGNITUDE, true)?;
            range(&n, &k("poisson_ratio"), m.poisson_ratio, -1.0, false, 0.5, false)?;
            range(&n, &k("density"), m.density, 0.0, false, MAX_MAGNITUDE, true)?;
            range(&n, &k("thickness"), m.thickness, 0.0, false, MAX_MAGNITUDE, true)?;
        }
        let s = &f.solver;
        if let Some(dt) = s.dt {
            range(&n, "solver.dt", dt, 0.0, false, f64::INFINITY, false)?;
        }
        range(&n, "solver.dt_safety", s.dt_safety, 0.0, false, 1.0, true)?;
        range(&n, "solver.tolerance", s.tolerance, 0.0, false, 1.0, false)?;
        if s.max_steps == 0 {
            return Err(FlemError::config(&n, "solver.max_steps", "= 0 is incorrect; it must be >= 1"));
        }
        if s.ratio_every == 0 {
            return Err(FlemError::config(&n, "solver.ratio_every", "= 0 is incorrect; it must be >= 1"));
        }
        if s.max_events == 0 {
            return Err(FlemError::config(&n, "solver.max_events", "= 0 is incorrect; it must be >= 1"));
        }
        if s.kind == SolverKind::Events {
            if f.cracking.is_none() {
                return Err(FlemError::config(
                    &n,
                    "solver.type",
                    "= \"events\" needs a [cracking] section (the events solver advances from one crack event to the next); remove solver.type for the explicit solver",
                ));
            }
            if f.contact.is_some() && s.on_loose_fragment == LooseFragment::Stop {
                return Err(FlemError::config(
                    &n,
                    "solver.type",
                    "= \"events\" with solver.on_loose_fragment = \"stop\" does not use [contact] (its solve is linear, with no contact forces; contact acts only in the hand-over to the explicit march); remove [contact], or solver.type to run the explicit solver",
                ));
            }
            range(&n, "solver.hand_over_distance", s.hand_over_distance, 0.0, false, MAX_MAGNITUDE, true)?;
            range(&n, "solver.hand_over_rest", s.hand_over_rest, 0.0, false, 1.0, false)?;
            if s.hand_over_max_steps == 0 {
                return Err(FlemError::config(&n, "solver.hand_over_max_steps", "= 0 is incorrect; it must be >= 1"));
            }
            if let Some((i, _)) = f.stages.iter().enumerate().find(|(_, st)| st.dynamic) {
                return Err(FlemError::config(&n, format!("stage[{i}].dynamic"), "= true is not possible with solver.type = \"events\" (quasi-static: every state is an equilibrium)"));
            }
            if let Some((i, _)) = f.materials.iter().enumerate().find(|(_, m)| m.corotational) {
                return Err(FlemError::config(&n, format!("material[{i}].corotational"), "= true is not possible with solver.type = \"events\" (its stress must be linear in the load)"));
            }
        }
        if s.threads > 1024 {
            return Err(FlemError::config(&n, "solver.threads", format!("= {} is incorrect; it must be in [0, 1024] (0: one per core)", s.threads)));
        }
        s.damping.as_ref().map_or(Ok(()), |d| d.validate()).map_err(|e| FlemError::config(&n, format!("solver.damping.{}", e.key), e.msg))?;
        for d in 0..2 {
            range(&n, &format!("model.gravity[{d}]"), f.model.gravity[d], -MAX_MAGNITUDE, true, MAX_MAGNITUDE, true)?;
        }
        for (i, sup) in f.supports.iter().enumerate() {
            if !["x", "y", "xy"].contains(&sup.fix.as_str()) {
                return Err(FlemError::config(&n, format!("support[{i}].fix"), format!("= \"{}\" is incorrect; it must be \"x\", \"y\" or \"xy\"", sup.fix)));
            }
        }
        let mut names: Vec<&str> = Vec::new();
        // The largest magnitude of each load's values (a level scales them).
        let mut largest: Vec<f64> = Vec::new();
        for (i, l) in f.loads.iter().enumerate() {
            if names.contains(&l.name()) {
                return Err(FlemError::config(&n, format!("load[{i}].name"), format!("= \"{}\" is used twice; load names must be unique", l.name())));
            }
            names.push(l.name());
            let lv: Vec<&LoadValue> = match l {
                LoadCfg::Pressure { value, .. } => vec![value],
                LoadCfg::Traction { value, .. } | LoadCfg::Point { value, .. } => value.iter().collect(),
                LoadCfg::Velocity { x, y, .. } => x.iter().chain(y.iter()).collect(),
                _ => Vec::new(),
            };
            for (d, v) in lv.iter().enumerate() {
                let key = match l {
                    LoadCfg::Velocity { x, .. } => format!("load[{i}].{}", if d == 0 && x.is_some() { "x" } else { "y" }),
                    _ if lv.len() == 1 => format!("load[{i}].value"),
                    _ => format!("load[{i}].value[{d}]"),
                };
                v.compile().map_err(|e| FlemError::config(&n, key, e))?;
            }
            // Expressions are bounded where they are evaluated (solver::loads).
            let numbers = lv.iter().filter_map(|v| if let LoadValue::Number(x) = v { Some(*x) } else { None });
            let vals: Vec<f64> = match l {
                LoadCfg::Pressure { .. } | LoadCfg::Traction { .. } | LoadCfg::Point { .. } => numbers.collect(),
                LoadCfg::Velocity { x, y, .. } => {
                    if x.is_none() && y.is_none() {
                        return Err(FlemError::config(&n, format!("load[{i}]"), "prescribes neither x nor y; give at least one"));
                    }
                    numbers.collect()
                }
                LoadCfg::Displacement { x, y, .. } => {
                    if x.is_none() && y.is_none() {
                        return Err(FlemError::config(&n, format!("load[{i}]"), "prescribes neither x nor y; give at least one"));
                    }
                    x.iter().chain(y.iter()).copied().collect()
                }
            };
            for &v in &vals {
                range(&n, &format!("load[{i}].value"), v, -MAX_MAGNITUDE, true, MAX_MAGNITUDE, true)?;
            }
            largest.push(vals.iter().fold(0.0f64, |m, v| m.max(v.abs())));
        }
        for (i, p) in f.output.probes.iter().enumerate() {
            for d in 0..2 {
                range(&n, &format!("output.probes[{i}].at[{d}]"), p.at[d], -MAX_MAGNITUDE, true, MAX_MAGNITUDE, true)?;
            }
        }
        range(&n, "output.checkpoint_seconds", f.output.checkpoint_seconds, 0.0, true, f64::INFINITY, false)?;
        if let Some(w) = f.output.tip_window {
            range(&n, "output.tip_window", w, 0.0, false, MAX_MAGNITUDE, true)?;
        }
        if f.output.checkpoint_keep == 0 {
            return Err(FlemError::config(&n, "output.checkpoint_keep", "= 0 is incorrect; it must be >= 1"));
        }
        if f.stages.is_empty() {
            return Err(FlemError::config(&n, "stage", "is missing; give at least one [[stage]]"));
        }
        for (i, st) in f.stages.iter().enumerate() {
            for (lname, v) in &st.levels {
                if !names.contains(&lname.as_str()) {
                    let hint = nearest(lname, names.iter().copied()).map(|h| format!(" (did you mean \"{h}\"?)")).unwrap_or_default();
                    return Err(FlemError::config(&n, format!("stage[{i}].levels.{lname}"), format!("names no load{hint}; loads are: {names:?}")));
                }
                range(&n, &format!("stage[{i}].levels.{lname}"), *v, -MAX_MAGNITUDE, true, MAX_MAGNITUDE, true)?;
                let big = largest[names.iter().position(|x| *x == lname.as_str()).unwrap_or(0)];
                if (v * big).abs() > MAX_MAGNITUDE {
                    return Err(FlemError::config(
                        &n,
                        format!("stage[{i}].levels.{lname}"),
                        format!("= {v:e} scales load \"{lname}\" (values up to {big:e}) to {:e}; the product must stay within {MAX_MAGNITUDE:e}", v * big),
                    ));
                }
            }
            if let Some(t) = st.tolerance {
                range(&n, &format!("stage[{i}].tolerance"), t, 0.0, false, 1.0, false)?;
            }
            if st.max_steps == Some(0) {
                return Err(FlemError::config(&n, format!("stage[{i}].max_steps"), "= 0 is incorrect; it must be >= 1"));
            }
            if let Some(t) = st.end_time {
                range(&n, &format!("stage[{i}].end_time"), t, 0.0, false, MAX_MAGNITUDE, true)?;
                if !st.dynamic {
                    return Err(FlemError::config(&n, format!("stage[{i}].end_time"), "is only possible with dynamic = true (a stage marched to equilibrium ends there)"));
                }
            }
        }
        if let Some(c) = &f.contact {
            c.validate(&n)?;
        }
        if let Some(c) = &f.cracking {
            let key = |t: &str, k: &str| if k.is_empty() { t.to_string() } else { format!("{t}.{k}") };
            c.criterion.validate().map_err(|e| FlemError::config(&n, key("cracking.criterion", &e.key), e.msg))?;
            c.separation.validate().map_err(|e| FlemError::config(&n, key("cracking.separation", &e.key), e.msg))?;
            if c.check_every == 0 {
                return Err(FlemError::config(&n, "cracking.check_every", "= 0 is incorrect; it must be >= 1"));
            }
            if c.max_splits_per_check == 0 {
                return Err(FlemError::config(&n, "cracking.max_splits_per_check", "= 0 is incorrect; it must be >= 1"));
            }
            if let Some(w) = &c.weibull {
                range(&n, "cracking.weibull.modulus", w.modulus, 0.5, true, 1000.0, true)?;
            }
            if let Some(nl) = &c.nonlocal {
                range(&n, "cracking.nonlocal.radius", nl.radius, 0.0, false, MAX_MAGNITUDE, true)?;
                if let Some(x) = nl.exclusion {
                    range(&n, "cracking.nonlocal.exclusion", x, 0.0, false, MAX_MAGNITUDE, true)?;
                }
            }
        }
        if let Some(c) = &f.check {
            c.validate(&n)?;
        }
        Ok(())
    }

    /// The resolved scene (every default filled in) as TOML.
    pub fn resolved_toml(&self) -> String {
        toml::to_string_pretty(&self.file).unwrap_or_else(|e| format!("# could not serialise the resolved scene: {e}\n"))
    }
}

/// Turns a TOML/serde error into a message naming the file, with a "did you mean" for an
/// unknown plugin name.
pub(crate) fn parse_error(file: &str, _text: &str, e: toml::de::Error) -> FlemError {
    let msg = e.to_string();
    let mut hint = String::new();
    if let (Some(a), Some(b)) = (msg.find("unknown variant `"), msg.find("expected one of")) {
        let rest = &msg[a + 17..];
        if let Some(end) = rest.find('`') {
            let bad = &rest[..end];
            let opts: Vec<&str> = msg[b..].split('`').skip(1).step_by(2).collect();
            if let Some(h) = nearest(bad, opts.iter().copied()) {
                hint = format!("\n(did you mean \"{h}\"?)");
            }
        }
    }
    FlemError::config(file, "", format!("is not a valid scene: {}{hint}", msg.trim_end()))
}
