//! Contact between faces (METHOD section 6; the paper's section 3.2, eqs. 6-17).
//!
//! What: faces that can touch are the free faces created by splits (both sides of every
//! separated element edge) plus the edge sets a scene declares (`[contact] surfaces`, or
//! every mesh-boundary face with `boundary = true`). Every node of a surface is a *slave*
//! and every face a *master* (two-pass, symmetric: no body is privileged).
//!
//! How:
//! - Broad phase ([`search`]): a uniform grid over the master faces gives, for every slave,
//!   the faces within `skin + max_depth` (a Verlet list). The list is rebuilt only when some
//!   surface node has moved more than `skin / 2` since the last build, or the topology
//!   changed (a split), so a quiet step costs one pass over the list. With a law that has
//!   cohesion (bonds, below) a split updates the list locally instead (session 18,
//!   `Contact::patch_verlet`: the split's nodes and faces; the same list as a full rebuild
//!   within the contact distance, see its doc for the concave-corner rule beyond it).
//! - Narrow phase: node-to-edge in the edge's local frame (paper eq. 6-7): the slave touches
//!   face i->j when `0 <= xi <= 1` along it and it lies inside the element side by less than
//!   `max_depth` x the face length. Node-to-node (corner): a slave inside a concave master
//!   corner (behind both faces meeting there, inside neither strip) is pushed out towards the
//!   corner node. One pair per slave (the shallowest face; ties: lowest face id).
//! - History: [`ContactHistory`], pairs sorted by slave cluster and keyed by
//!   (slave cluster, master face id = 4 x element + local edge, or master node): stable
//!   across rebuilds and splits, plain serde (checkpoints). When a slave slides past the end
//!   of its face onto the neighbouring face (sharing that end node), the pair's history
//!   carries over.
//! - No energy from nothing (a split under compression makes all of these happen; test
//!   `contact_between_faces_split_in_compression_creates_no_energy`): a pair born with its
//!   slave already behind the face takes as spring compression only the approach of its first
//!   step (what the trapezoidal work sum credits); the rest of the overlap is its zero
//!   (`PairState::offset`). Only the run's first contact step takes overlaps whole: they are
//!   the scene's (parts placed pressed into each other). A slave that passes to another master (not a neighbouring face)
//!   keeps its history, and the new master's gap is shifted to continue the old one's. When a
//!   pair's area changes (a split gives part of the slave's faces to another node) its springs
//!   are scaled by `sqrt(A_new / A_old)`, which keeps their energy; a law whose energy is the
//!   area times a value per unit area (total-gap, cohesive) gets the old area
//!   ([`PairKinematics::area_old`]) and accounts for the change itself. A pair lost by geometry
//!   (its slave slid off the end of its face, no neighbour took it) releases its springs'
//!   energy, counted as dissipated.
//! - The law ([`ContactLaw`], a plugin chosen by `law = { type = "..." }`) is called once per
//!   step on the whole batch of pairs; forces go to the slave and, with the opposite sign, to
//!   the face ends by the division ratio (eq. 16-17), so momentum is conserved exactly.
//!
//! Determinism: every loop runs in slave order, then face order; no hash map anywhere.
//!
//! ```toml
//! [contact]
//! law = { type = "penalty", normal_stiffness = 1e5, friction = 0.3 }
//! surfaces = ["block_bottom", "base_top"]
//! boundary = false      # true: every mesh-boundary face is a contact surface
//! crack_faces = true    # faces created by splits and pre-separated edges
//! max_depth = 0.5       # deepest penetration counted, x face length
//! # skin = 0.01         # Verlet skin (length); default 0.2 x mean face length
//! ```
//!
//! # In the solver (issue 4)
//! Only when the scene has `[contact]`: `Simulation::contact` is `None` otherwise and the step
//! skips it. The surfaces' separated edges are those of splits and of `model.separated`. The
//! broad phase's grid is filled by counting sort (deterministic order); the narrow phase covers
//! the paper's eqs. 6-9, faces extended by 2 % at their ends against chatter. Built-in laws
//! (`plugins/src/contact/`): `spring_dashpot` (the paper's eqs. 10-14), `penalty`, `cohesive`.
//! Forces go to `State::f_con`.
//!
//! # Contact across splits (`Contact::on_split`, `search.rs`)
//! A fresh (cohesive) pair is created only at the end where an edge is cut in this split (gap
//! 0); pairs of a split slave are re-keyed to the part across their master face; a node at a
//! vertex of a face without being the node across that face's edge (the V of a crack branch) is
//! never paired with it; a pair's area is half the slave's faces whose reference normal faces
//! the master (a branch adding faces at a node does not change the area of its open pairs).
//! Each of these created energy on the notched plate with cohesive contact
//! (`configs/bench/notch_q4_h0.25_contact.toml`, test
//! `contact::dynamic_crack_with_cohesive_contact_keeps_the_energy_balance`).
//!
//! # Splits under compression (session 4)
//! The "no energy from nothing" rules above come from the paper's direct shear box (copy in
//! `tests/data/direct_shear_contact.toml`): a pair born with its slave already behind the face
//! (the overlap grew while the slave was held by another face or kept off this one, e.g. by the
//! vertex rule after a split at a junction) counts only the approach of its first step; a
//! spring born at the full overlap stored `1/2 k A d^2` from nothing (0.23 of the work at
//! p = 180). A split halving a loaded pair's area doubled its springs' energy before the
//! `sqrt(A_new / A_old)` scaling. `cohesive`, whose energy is A x a value per unit area, counts
//! the normal energy of a shrinking area as dissipated. A lost pair's released energy is
//! `PairState::stored`. Checkpoint section `contact` is version 2 (the new `PairState` fields;
//! the Verlet list's build state is section `contact_verlet`, `Contact::restore_verlet`). Test
//! `contact::contact_between_faces_split_in_compression_creates_no_energy`: worst stage
//! 0.98 -> 1.3e-3; 1.6e-4 with spring_dashpot's trapezoid slip dissipation.
//!
//! # Stable step and energy accounting
//! Stable step: `omega^2 = omega_elements^2 + 4 k A_max / m_min` (`StableStep::dt_contact`,
//! `crate::solver`). Ledger: `contact_work` (trapezoidal), `contact_energy` (stored in the
//! springs now), `contact_dissipated` (friction, dashpots, fracture); the residual counts the
//! last two. `cohesive` (session 5) makes stored + dissipated change by exactly the trapezoidal
//! work of its forces: slip dissipation `(e_s,old + e_s)(e_s* - e_s) / (2 k_s A)` (was a
//! rectangle), the trapezoid's error at the kinks of its traction (contact born from an open
//! gap, release, peak, delta_f, reloading past delta_max) counted in `contact_dissipated` (of
//! either sign; the explicit scheme's impact loss at contact), the area change above; the
//! notched plate's residual went from 3.6e-2..4.8e-2 (lost) to 1e-5..8e-5 (breakdown in the
//! test's comment).
//!
//! # Cohesion per crack face (issue 36, session 17)
//! With a law that has cohesion (`cohesive`: [`ContactLaw::unreleased`] of a fresh state > 0)
//! the cohesion of crack faces is not carried by the one pair per slave node: every end of an
//! edge cut in the run gets its own [`Bond`] (slave: the node of the lower face there; master:
//! the other face; area: half the edge's, fixed), evaluated by the law in the same batch as the
//! contact pairs until it opens past `delta_f` (then it is dropped: the face is free). A node
//! with several cut faces (a straight crack: two; a junction or a branch: more) has one bond per
//! face, each with its own opening and damage, and one that splits again keeps them all (the
//! bond's slave is re-read from the topology at each split). Before (sessions 5-16) a node
//! had one pair whose area was its faces facing the master: at a junction the second face got
//! no cohesion, a split gave part of a pair's faces to the new node without a pair, and a pair
//! carried both faces of a straight crack against one master (tests
//! `one_cohesive_face_opened_releases_gc_times_its_area`,
//! `a_node_with_two_cohesive_faces_releases_both`; the branching plate released 0.38 of
//! `G_c` x its free crack). A bond carries its face in compression too (the law's penalty): the
//! contact search leaves out, for every node at a bond's point (either side), both faces of
//! that bond's edge (no second spring on the same faces; review r17: before, only the slave's
//! own bonds' masters, so a node pair could carry 3 k A against the 2 k A of `omega2`) and
//! goes on for every other face (the notch's, another crack's); the two-pass contact of the
//! other side's nodes goes on as before. Laws without cohesion (`spring_dashpot`, `penalty`, plugin laws)
//! never make bonds: their runs are unchanged. Checkpoint section `contact_bonds` (version 1).
//!
//! Fracture energy (issue 36): the part of a law's dissipation that is fracture
//! ([`PairForce::fracture`]) is summed by [`Contact::compute`] into `Contact::fracture_step`
//! and by the solver into the ledger's `fracture` (a part of `contact_dissipated`, not a
//! separate term of the balance). A split itself dissipates nothing: the node's copies keep
//! their displacement, the strain energy is unchanged and goes to the faces' motion; without a
//! cohesive law the energy a crack releases leaves as waves and kinetic energy.
pub mod contact3;
pub mod dynlaw;
pub mod search;

use std::fmt::Debug;

use serde::{Deserialize, Serialize};

use crate::error::{FlemError, Result};
use crate::plugin::traits::ParamError;

pub use search::Contact;

/// `[contact]` in a scene.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactCfg {
    /// A built-in, or a loaded plugin's law (`dynlaw::de_contact`).
    #[serde(deserialize_with = "dynlaw::de_contact")]
    pub law: Box<dyn ContactLaw>,
    /// Edge sets that are contact surfaces (boundary faces; an interior edge gives both faces).
    #[serde(default)]
    pub surfaces: Vec<String>,
    /// Every mesh-boundary face is a contact surface.
    #[serde(default)]
    pub boundary: bool,
    /// Faces of separated element edges (splits and `model.separated`) are contact surfaces.
    #[serde(default = "yes")]
    pub crack_faces: bool,
    /// Deepest penetration still counted, as a fraction of the master face length, in (0, 1].
    #[serde(default = "half")]
    pub max_depth: f64,
    /// Verlet skin (length, > 0); default 0.2 x the mean surface face length.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skin: Option<f64>,
}

fn yes() -> bool {
    true
}
fn half() -> f64 {
    0.5
}

impl ContactCfg {
    /// Checks the parameters; errors name `contact.<key>`.
    pub fn validate(&self, file: &str) -> Result<()> {
        self.law.validate().map_err(|e| FlemError::config(file, format!("contact.law.{}", e.key), e.msg))?;
        ParamError::range("contact.max_depth", self.max_depth, 0.0, false, 1.0, true).map_err(|e| FlemError::config(file, e.key, e.msg))?;
        if let Some(s) = self.skin {
            ParamError::range("contact.skin", s, 0.0, false, f64::INFINITY, false).map_err(|e| FlemError::config(file, e.key, e.msg))?;
        }
        if self.surfaces.is_empty() && !self.boundary && !self.crack_faces {
            return Err(FlemError::config(file, "contact", "has no surface: give surfaces = [edge sets], boundary = true or crack_faces = true"));
        }
        Ok(())
    }
}

/// What the law sees of one pair, in the master face's local frame (paper eq. 6-9):
/// `n` the master's outward normal, `t` along the face (from its start to its end).
#[derive(Copy, Clone, Debug, Default)]
pub struct PairKinematics {
    /// Signed gap along n (length): > 0 open, < 0 penetrated; less the pair's
    /// [`PairState::offset`] (an overlap that is not its springs', see there).
    pub gap: f64,
    /// Increment of the gap over the last step (relative displacement increment . n, eq. 8-9).
    pub dgap: f64,
    /// Increment of the tangential relative displacement of the slave (. t).
    pub dslip: f64,
    /// Relative velocity, normal and tangential.
    pub vn: f64,
    pub vs: f64,
    /// Tributary area of the slave (length x thickness): springs are per unit area.
    pub area: f64,
    /// The pair's area in its previous step ([`PairState::area`] before this step; 0 when
    /// unknown: the pair's first step). It differs from `area` after a split gave part of the
    /// slave's faces to another node, or a change of master; the core has then scaled `e_n`,
    /// `e_s` by `sqrt(area / area_old)` (which keeps an incremental spring's energy), but a law
    /// whose energy depends on the area directly (a total-gap or cohesive law stores
    /// `A x` energy per unit area) sees its stored energy change by `area / area_old - 1`
    /// times its previous value with no work done, and accounts for it (see `cohesive`).
    pub area_old: f64,
    pub dt: f64,
    /// First step of this pair (no history yet).
    pub new: bool,
}

/// The force a law returns for one pair (acting on the slave; the master gets the opposite).
#[derive(Copy, Clone, Debug, Default)]
pub struct PairForce {
    /// Normal force along n (> 0 pushes the faces apart; < 0 only for cohesion).
    pub normal: f64,
    /// Tangential force along t.
    pub tangential: f64,
    /// The pair stays in contact (false: it opened and is dropped).
    pub active: bool,
    /// Elastic energy stored in the pair's springs now.
    pub stored: f64,
    /// Energy dissipated in this step (slip, dashpots, fracture).
    pub dissipated: f64,
    /// The part of `dissipated` that is fracture energy (issue 36: a cohesive law's softening,
    /// `G_f` x area once a pair has opened past `delta_f`); the ledger's `fracture` sums it.
    /// 0 for laws without cohesion, and for laws from plugin libraries (the ABI has no field
    /// for it: their dissipation is all in `dissipated`).
    pub fracture: f64,
}

/// Per-pair history (paper eq. 10-14: e_n, e_s accumulate per pair). Plain data so that it
/// can be written to checkpoints.
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PairState {
    /// Normal spring force (compression positive).
    pub en: f64,
    /// Tangential spring force on the slave along t.
    pub es: f64,
    /// Largest opening reached (cohesive laws).
    pub max_open: f64,
    /// The pair joins the two faces of an edge split during the run (eligible for cohesion).
    pub fresh: bool,
    /// Gap offset (length): the law sees `gap - offset`. A pair born with its slave already
    /// behind the face by more than the approach of its first step takes that earlier overlap
    /// as its zero (offset < 0): a spring born at the full overlap would store
    /// `1/2 k A overlap^2` that no force ever worked for. A pair whose slave passed to another
    /// master continues the old pair's law gap (offset of either sign).
    #[serde(default)]
    pub offset: f64,
    /// The pair's area (length x thickness) in its last step (0: not yet known). When a split
    /// or a change of master changes it, the springs `e_n`, `e_s` are scaled by
    /// `sqrt(A_new / A_old)`, which keeps their energy `e^2 / (2 k A)`: a force kept on a
    /// smaller area would store more energy with no work done (on a larger one, less).
    #[serde(default)]
    pub area: f64,
    /// Energy stored in the pair's springs after its last step (written by the core from
    /// [`PairForce::stored`]): released, i.e. counted as dissipated, when the pair is lost
    /// without its law opening it (its slave slid off the end of its face with no neighbouring
    /// face to take it, or a split kept it off its master).
    #[serde(default)]
    pub stored: f64,
}

/// The master of a pair.
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Master {
    /// Face `4 x element + local edge`.
    Face(u32),
    /// A node (cluster) at a concave corner.
    Node(u32),
}

/// One contact pair with its history.
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pair {
    pub slave: u32,
    pub master: Master,
    pub state: PairState,
}

/// The cohesion of one crack face end (issue 36, session 17: cohesion per cut face): the end
/// `end` of edge `edge`, cut during the run, joins the slave node there (the copy of the element
/// whose face has the lower id) to the other element's face `master` (`4 x element + local
/// edge`) with its own cohesive state over its own area, half the edge's (length x thickness),
/// until its law lets it go (`PairForce::active` false: opened past `delta_f`). `slave` follows
/// the splits of the node ([`search::Contact::on_split`]). Used only with a law that has
/// cohesion ([`ContactLaw::unreleased`] of a fresh state > 0); see the module doc.
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Bond {
    pub edge: u32,
    pub end: u8,
    pub slave: u32,
    pub master: u32,
    /// Half the edge's area (length x thickness), fixed.
    pub area: f64,
    pub state: PairState,
}

/// Every open pair, sorted by slave cluster (at most one pair per slave), and the edges split
/// during the run (their faces are fresh: cohesive laws act on them). Restore with
/// [`Contact::restore`].
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ContactHistory {
    pub pairs: Vec<Pair>,
    #[serde(default)]
    pub fresh_edges: Vec<u32>,
}

/// A contact law (METHOD section 6): springs per unit area, called once per step on the batch.
#[typetag::serde(tag = "type")]
pub trait ContactLaw: Debug + Send + Sync {
    /// Checks the parameters; the error names the key and the allowed range.
    fn validate(&self) -> std::result::Result<(), ParamError>;
    /// The largest spring stiffness per unit area (stress / length), for the stable step.
    fn stiffness(&self) -> f64;
    /// Updates the history and returns the force of every pair (same order, same length).
    fn evaluate(&self, kin: &[PairKinematics], hist: &mut [PairState], out: &mut [PairForce]);
    /// Fracture energy per unit area that a pair in state `st` has still to release before
    /// its faces are free of traction (issue 36: a cohesive pair short of `delta_f` holds
    /// `G_f - R(delta_max)`); 0 for laws without cohesion (the default). Used only to account
    /// for the fracture energy ([`search::CohesionAccount`]), never in the march.
    fn unreleased(&self, _st: &PairState) -> f64 {
        0.0
    }
    /// The 3D form of the law (issue 38, [`contact3`]): the same springs with the tangential
    /// quantities as vectors in the master face's plane and the Coulomb cap on their length.
    /// A law without one returns an error (the default); a 3D scene probes it with empty
    /// slices and refuses the law by name.
    fn evaluate_3d(&self, _kin: &[contact3::PairKinematics3], _hist: &mut [contact3::PairState3], _out: &mut [contact3::PairForce3]) -> std::result::Result<(), String> {
        Err("this contact law has no 3D form (docs/3d.md, \"Contact (3D)\")".into())
    }
    /// An error the law met in `evaluate` (a dynamic law that failed or returned a non-finite
    /// force; it then returned NaN forces, which the divergence guard stops on).
    fn fault(&self) -> Option<String> {
        None
    }
}
