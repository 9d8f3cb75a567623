//! Damping: a trait the solver asks once per step for the coefficients of the combined law
//!
//! `f_damp = (viscous * m + eta) * v_mid + local * |F| * sign(v)`,
//!
//! integrated implicitly in velocity (METHOD section 7):
//! `v+ = ((1 - a dt/2) v- + dt (F - local |F| sign(v-)) / m) / (1 + a dt/2)` with
//! `a = viscous + eta / m` per node (`eta` the paper's eq. 5 coefficient, the same for every
//! node, so `a` differs with the node's mass; `viscous` the mass-proportional part).
use std::fmt::Debug;

use crate::plugin::traits::ParamError;

/// Coefficients for one step.
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct DampingCoeffs {
    /// Mass-proportional viscous coefficient `a` (1/time): eta = a m.
    pub viscous: f64,
    /// Local (non-viscous) damping ratio, dimensionless in [0, 1).
    pub local: f64,
    /// Constant viscous coefficient of every node, force per velocity (the paper's eq. 5
    /// `eta`: a node's damping force is `eta v` whatever its mass). The node update divides it
    /// by each node's mass; a scheme that leaves it 0 pays nothing for it.
    pub eta: f64,
}

/// What the solver measured over the last step (free dofs only).
#[derive(Copy, Clone, Debug, Default)]
pub struct StepStats {
    pub step: u64,
    pub dt: f64,
    /// Highest natural frequency of the mesh (rad/time), from the stable-step estimate.
    pub omega_max: f64,
    /// Kinetic energy at the half step, sum 1/2 m v+^2. Like `u_f_int` and `u_m_u`, summed on
    /// every step only when the scheme `uses_rayleigh_stats`; otherwise on the stage loop's
    /// full steps (the others leave the last value).
    pub kinetic: f64,
    /// Sum u . F_int (for the Rayleigh quotient).
    pub u_f_int: f64,
    /// Sum m u . u.
    pub u_m_u: f64,
}

#[typetag::serde(tag = "type")]
pub trait Damping: Debug + Send + Sync {
    fn validate(&self) -> Result<(), ParamError>;
    /// Called at the start of every stage.
    fn reset(&mut self) {}
    /// Coefficients for the next step, given the stats of the previous one.
    fn coeffs(&mut self, stats: &StepStats) -> DampingCoeffs;
    /// Whether [`Self::coeffs`] reads `u_f_int` and `u_m_u` of [`StepStats`]: when it does not,
    /// the node update does not sum them (they are then 0 between the ledger's full steps).
    fn uses_rayleigh_stats(&self) -> bool {
        true
    }
    /// Factor (<= 1) on the critical time step that this scheme needs.
    fn stability_factor(&self) -> f64 {
        1.0
    }
    /// Internal state, for checkpoints.
    fn state(&self) -> Vec<f64> {
        Vec::new()
    }
    fn set_state(&mut self, _s: &[f64]) {}
    /// An error the scheme met (a dynamic scheme that failed or returned non-finite
    /// coefficients; it then returned NaN, which the divergence guard stops on).
    fn fault(&self) -> Option<String> {
        None
    }
}
