//! The implicit check solver (METHOD.md section 10): the [`CheckSolver`] trait that plugins
//! implement (the built-in one is faer's sparse Cholesky, `type = "faer_cholesky"`) and the
//! `[check]` scene section. The comparison itself, run after every stage, is an observer of the
//! solver: `crate::output::compare`.
//!
//! ```toml
//! [check]                                # every key optional
//! solver = { type = "faer_cholesky" }    # the check solver plugin (default)
//! tolerance = 1e-6                       # bound on both relative L2 differences
//! vtu = true                             # write compare_NNNN_<stage>.vtu per stage
//! increments = 20                        # load increments per plastic stage (ours)
//! ```
//!
//! The trait (typetag): `solve(&self, model, fix, f_ext, u_p)`; reusable data lives behind
//! interior mutability so one configured solver serves every stage. The built-in
//! `faer_cholesky` and `flem bench implicit` live in `plugins/src/check/`.
use std::fmt::Debug;

use serde::{Deserialize, Serialize};

use crate::element::model::Model;
use crate::error::{FlemError, Result};
use crate::plugin::traits::ParamError;

/// A direct solver of the linear static problem of a model (METHOD section 10).
///
/// `solve` takes `&self`: an implementation keeps what it can reuse between calls (a symbolic
/// factorisation, a sparsity pattern) behind interior mutability, so one configured solver in a
/// scene serves every stage.
#[typetag::serde(tag = "type")]
pub trait CheckSolver: Debug + Send + Sync {
    /// Checks the parameters; the error names the key and the allowed range.
    fn validate(&self) -> Result<(), ParamError> {
        Ok(())
    }
    /// Solves `K u = f_ext` with the dofs flagged in `fix` (bit 1 = x, bit 2 = y) prescribed to
    /// `u_prescribed`; returns the displacement of every cluster. A singular system (a fragment
    /// without enough support) is an error naming the fragment, never a NaN solution.
    fn solve(&self, model: &Model, fix: &[u8], f_ext: &[[f64; 2]], u_prescribed: &[[f64; 2]]) -> Result<Vec<[f64; 2]>>;
    /// A factorisation kept across crack events (the events solver, ours, issue 19):
    /// `refactor_every` events are solved by an update of the kept factor before a fresh one
    /// (0: a fresh factorisation at every call). `None` (the default): the events solver calls
    /// [`Self::solve`] per right-hand side.
    fn events_factor(&self, _refactor_every: usize) -> Option<Box<dyn EventsFactor>> {
        None
    }
    /// The implicit plastic check (Newton with the laws' consistent tangents; the built-in:
    /// `flem-plugins/src/check/newton.rs`), one per run, kept from stage to stage. `None`
    /// (the default): the solver has none, and the comparison of a plastic stage says so.
    fn plastic(&self) -> Option<Box<dyn PlasticCheck>> {
        None
    }
    /// The linear static problem of a 3D model (issue 38, docs/3d.md "Implicit check"): the
    /// displacement and nodal stress of every cluster. The default refuses: a check solver
    /// without a 3D form is named in a 3D scene's error.
    fn solve_3d(&self, _problem: &Linear3) -> Result<Linear3Solution> {
        Err(FlemError::Solve("this check solver has no 3D form (the built-in \"faer_cholesky\" has one)".into()))
    }
}

/// The linear static problem of a 3D body as the implicit check sees it (issue 38): `mesh`
/// has one point per *cluster* (at its point's reference position; the cells name clusters,
/// so a separated face is open), and per cell its material and element kind.
#[derive(Clone, Debug)]
pub struct Linear3<'a> {
    pub mesh: &'a crate::mesh::RawMesh3,
    /// Per cell: Young's modulus, Poisson's ratio and the element kind's name (`t4`, `h8`,
    /// `h8_full`).
    pub cells: Vec<(f64, f64, &'static str)>,
    /// Prescribed dofs per cluster: bit 1 = x, 2 = y, 4 = z.
    pub fix: &'a [u8],
    /// Values of the prescribed dofs (others ignored).
    pub u_prescribed: &'a [[f64; 3]],
    /// External force per cluster.
    pub f_ext: &'a [[f64; 3]],
}

/// The solution of a [`Linear3`].
#[derive(Clone, Debug)]
pub struct Linear3Solution {
    pub u: Vec<[f64; 3]>,
    /// Voigt `xx, yy, zz, xy, yz, zx`, tension positive: the 0.9999 corner stresses averaged
    /// over the cells of each cluster.
    pub nodal_stress: Vec<[f64; 6]>,
    /// Free dofs.
    pub n_dofs: usize,
}

/// One Newton iteration of the implicit plastic check: the residual norm, relative to the
/// external force (reactions included), after `iteration` corrections of load increment
/// `increment` (ending at the fraction `level` of the stage's load path).
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct NewtonRow {
    pub increment: usize,
    pub level: f64,
    pub iteration: usize,
    pub residual: f64,
}

/// What the implicit plastic check did in a stage.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct PlasticStage {
    /// Accepted load increments and Newton iterations over all of them.
    pub increments: usize,
    pub iterations: usize,
    /// Bisections of an increment that did not converge.
    pub bisections: usize,
    /// "consistent", or the laws that fell back to the elastic tangent, named.
    pub tangent: String,
    /// How the tangent systems were solved (our Cholesky, faer's LU for a non-symmetric
    /// tangent or one that was not positive definite), with counts.
    pub factorisation: String,
    pub table: Vec<NewtonRow>,
}

/// The implicit plastic check of a run: its own Gauss-point stress and history, advanced
/// stage by stage from its last converged state (never from the explicit run's).
pub trait PlasticCheck: Send {
    /// Advances the solution from its last converged state to the external force `f_ext`
    /// and the prescribed displacements `u_prescribed` (on the dofs flagged in `fix`) along
    /// the straight load path between them, in `increments` equal load increments (halved on
    /// a Newton iteration that does not converge).
    fn advance(&mut self, model: &Model, fix: &[u8], f_ext: &[[f64; 2]], u_prescribed: &[[f64; 2]], increments: usize) -> Result<PlasticStage>;
    /// Converged displacement of every cluster.
    fn displacement(&self) -> &[[f64; 2]];
    /// Converged internal force of every cluster (at a prescribed dof: the reaction).
    fn internal_force(&self) -> &[[f64; 2]];
    /// Converged stress of every Gauss point `[sxx, syy, sxy, szz]`, block by block (empty for
    /// a block without a law), as `Block::point_stress` orders them.
    fn point_stress(&self) -> Vec<Vec<[f64; 4]>>;
    /// Per block, per element: some point has yielded so far.
    fn yielded(&self) -> Vec<Vec<bool>>;
}

/// The linear algebra of the events solver (`solver::events`): solves the current model for
/// several right-hand sides (`(f_ext, u_prescribed)` pairs), keeping what it can between calls
/// while the model changes by splits. Errors as [`CheckSolver::solve`] (a fragment without
/// support is named).
pub trait EventsFactor: Send {
    fn solve_many(&mut self, model: &Model, fix: &[u8], rhs: &[(Vec<[f64; 2]>, Vec<[f64; 2]>)]) -> Result<Vec<Vec<[f64; 2]>>>;
    /// (fresh factorisations, updates) so far.
    fn counts(&self) -> (u64, u64);
    /// Whether the next call makes a fresh factorisation by the refactorisation schedule
    /// (`refactor_every`): a checkpoint taken there is resumed without changing the arithmetic.
    fn fresh_next(&self) -> bool {
        true
    }
    /// Drops the kept factor: the next call makes a fresh factorisation (what a run resumed
    /// from a checkpoint does), keeping only what [`Self::save_state`] saves.
    fn restart(&mut self) {}
    /// What a checkpoint keeps of this factor (e.g. its fill-reducing ordering), so that the
    /// resumed run's next fresh factorisation is the uninterrupted run's bit for bit.
    fn save_state(&self) -> Vec<u64> {
        Vec::new()
    }
    /// Restores [`Self::save_state`] into a new factor; `false` when the data do not fit.
    fn load_state(&mut self, _state: &[u64]) -> bool {
        true
    }
}

/// `[check]`: compare every stage's equilibrium with the implicit solve.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CheckCfg {
    /// The check solver; filled in with "faer_cholesky" when the scene names none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solver: Option<Box<dyn CheckSolver>>,
    /// A stage is `within_tolerance` when both relative L2 differences are at most this.
    #[serde(default = "default_tol")]
    pub tolerance: f64,
    /// Write one comparison VTU per stage.
    #[serde(default = "yes")]
    pub vtu: bool,
    /// Load increments per stage of the implicit plastic check (ours; halved where Newton
    /// does not converge). Only read when the model has a plastic law.
    #[serde(default = "default_increments")]
    pub increments: usize,
}

pub(crate) fn default_increments() -> usize {
    20
}

pub(crate) fn default_tol() -> f64 {
    1e-6
}
fn yes() -> bool {
    true
}

impl CheckCfg {
    /// `[check]` with every default (the check solver named "faer_cholesky", which must be
    /// linked into the program: `flem-plugins`).
    pub fn with_defaults(file: &str) -> Result<CheckCfg> {
        let mut c = CheckCfg { solver: None, tolerance: default_tol(), vtu: true, increments: default_increments() };
        c.fill_default(file)?;
        Ok(c)
    }

    /// Fills in the default solver.
    pub fn fill_default(&mut self, file: &str) -> Result<()> {
        if self.solver.is_none() {
            let s = toml::from_str("type = \"faer_cholesky\"").map_err(|e| {
                FlemError::config(file, "check.solver", format!("is not given and the default \"faer_cholesky\" is not registered in this program ({e}); link flem-plugins or name a check solver"))
            })?;
            self.solver = Some(s);
        }
        Ok(())
    }

    /// Validates the keys (errors name `check.<key>`).
    pub fn validate(&self, file: &str) -> Result<()> {
        ParamError::range("check.tolerance", self.tolerance, 0.0, false, 1.0, false).map_err(|e| FlemError::config(file, e.key, e.msg))?;
        if self.increments == 0 || self.increments > 100_000 {
            return Err(FlemError::config(file, "check.increments", format!("= {} is incorrect; it must be in [1, 100000]", self.increments)));
        }
        if let Some(s) = &self.solver {
            s.validate().map_err(|e| FlemError::config(file, format!("check.solver.{}", e.key), e.msg))?;
        }
        Ok(())
    }

    pub fn solver(&self) -> &dyn CheckSolver {
        self.solver.as_deref().expect("Scene::from_str fills in the default check solver")
    }
}
