//! Damping plugins (METHOD section 7). Each returns, once per step, the coefficients of the
//! combined law `f_damp = (a m + eta) v + beta |F| sign(v)` that the core integrates implicitly
//! in velocity: `v+ = ((1 - a' dt/2) v- + dt (F - beta |F| sign(v-)) / m) / (1 + a' dt/2)` with
//! `a' = a + eta / m` per node.
//!
//! Names: `viscous_eta` (the paper's eq. 5), `viscous`, `local`, `adaptive`, `none`.
//!
//! `viscous_eta`: the paper's eq. (5), `m_a u''_a + eta u'_a + F_a = f_a`, with one constant
//! `eta` for every node (no node index in eq. 5): a node's damping force is `eta v` whatever its
//! mass, so light nodes (corners, boundary) are damped more per unit mass than interior ones.
//! Units: force per velocity per unit thickness, i.e. g/(cm s) in the paper's cm-g-s units
//! (mass per node is per unit thickness in 2D). The paper gives no value for eta: a scene
//! must choose one (configs/paper/*.toml derive theirs from the lowest mode, ours).
//!
//! ```toml
//! [solver.damping]
//! type = "viscous_eta"
//! eta = 12000.0    # g/(cm s): 2 w0 m_mean with w0 = 3060 rad/s, m_mean = 1.95 g/cm
//! ```
//!
//! `viscous` (ours, not the paper's eq. 5): mass-proportional, `eta_a = alpha m_a`.
//!
//! ```toml
//! [solver.damping]
//! type = "viscous"
//! alpha = 20.0
//! ```
//!
//! ```toml
//! [solver.damping]
//! type = "local"
//! ratio = 0.8
//! ```
//!
//! ```toml
//! [solver.damping]
//! type = "adaptive"
//! ```

use flem_core::plugin::damping::{Damping, DampingCoeffs, StepStats};
use flem_core::plugin::traits::ParamError;
use serde::{Deserialize, Serialize};

/// The paper's viscous damping as eq. (5) writes it: one constant `eta` for every node, a
/// node's damping force `eta v` (METHOD 7). `eta` in force per velocity (per unit thickness),
/// >= 0. A node of mass m sees the mass-proportional rate `eta / m`: critical damping of a
/// mode of angular frequency w in a region of nodal mass m is eta = 2 w m.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViscousEta {
    pub eta: f64,
}

#[typetag::serde(name = "viscous_eta")]
impl Damping for ViscousEta {
    fn validate(&self) -> Result<(), ParamError> {
        ParamError::range("eta", self.eta, 0.0, true, f64::INFINITY, false)
    }
    fn uses_rayleigh_stats(&self) -> bool {
        false
    }
    fn coeffs(&mut self, _s: &StepStats) -> DampingCoeffs {
        DampingCoeffs { eta: self.eta, ..Default::default() }
    }
}

/// Mass-proportional viscous damping, eta_a = alpha m_a (ours: the paper's eq. 5 has one
/// constant eta, [`ViscousEta`]; METHOD 7). `alpha` in 1/time. Critical damping of a mode of
/// angular frequency w is alpha = 2 w.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Viscous {
    pub alpha: f64,
}

#[typetag::serde(name = "viscous")]
impl Damping for Viscous {
    fn validate(&self) -> Result<(), ParamError> {
        ParamError::range("alpha", self.alpha, 0.0, true, f64::INFINITY, false)
    }
    fn uses_rayleigh_stats(&self) -> bool {
        false
    }
    fn coeffs(&mut self, _s: &StepStats) -> DampingCoeffs {
        DampingCoeffs { viscous: self.alpha, ..Default::default() }
    }
}

/// Local (non-viscous) damping as in FLAC/UDEC: a force `ratio |F| sign(v)` opposing the
/// motion, dimensionless `ratio` in [0, 1) (0.8 is FLAC's default for statics).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Local {
    #[serde(default = "default_local")]
    pub ratio: f64,
}

fn default_local() -> f64 {
    0.8
}

#[typetag::serde(name = "local")]
impl Damping for Local {
    fn validate(&self) -> Result<(), ParamError> {
        ParamError::range("ratio", self.ratio, 0.0, true, 1.0, false)
    }
    fn uses_rayleigh_stats(&self) -> bool {
        false
    }
    fn coeffs(&mut self, _s: &StepStats) -> DampingCoeffs {
        DampingCoeffs { local: self.ratio, ..Default::default() }
    }
    /// Opposing the previous half-step velocity, the local force acts along F for the highest
    /// mode (whose velocity flips every step): it stiffens it by (1 + ratio).
    fn stability_factor(&self) -> f64 {
        1.0 / (1.0 + self.ratio).sqrt()
    }
}

/// Adaptive dynamic relaxation (Underwood 1983): critical viscous damping of the current
/// lowest mode, `alpha = 2 w0` with `w0^2 = (u . F_int) / (u . M u)` (the Rayleigh quotient of the
/// current displacement, free dofs). Needs no parameter. Before the body has moved it uses
/// `w_max / 100`.
#[derive(Debug, Clone, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct Adaptive {
    #[serde(skip)]
    alpha: f64,
}

#[typetag::serde(name = "adaptive")]
impl Damping for Adaptive {
    fn validate(&self) -> Result<(), ParamError> {
        Ok(())
    }
    fn reset(&mut self) {
        self.alpha = 0.0;
    }
    fn coeffs(&mut self, s: &StepStats) -> DampingCoeffs {
        let w2 = if s.u_m_u > 0.0 { s.u_f_int / s.u_m_u } else { 0.0 };
        let w0 = if w2 > 0.0 && w2.is_finite() { w2.sqrt().min(s.omega_max) } else { 0.01 * s.omega_max };
        self.alpha = 2.0 * w0;
        DampingCoeffs { viscous: self.alpha, ..Default::default() }
    }
    fn state(&self) -> Vec<f64> {
        vec![self.alpha]
    }
    fn set_state(&mut self, s: &[f64]) {
        self.alpha = s.first().copied().unwrap_or(0.0);
    }
}

/// No damping (dynamics, wave propagation).
#[derive(Debug, Clone, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct NoDamping {}

#[typetag::serde(name = "none")]
impl Damping for NoDamping {
    fn validate(&self) -> Result<(), ParamError> {
        Ok(())
    }
    fn uses_rayleigh_stats(&self) -> bool {
        false
    }
    fn coeffs(&mut self, _s: &StepStats) -> DampingCoeffs {
        DampingCoeffs::default()
    }
}

pub const NAMES: &[&str] = &["viscous_eta", "viscous", "local", "adaptive", "none"];

#[cfg(test)]
mod tests {
    use super::*;

    /// Every ```toml block of this module's docs deserialises into a `Box<dyn Damping>` and
    /// validates; every name has a snippet. Reference: the docs; exact.
    #[test]
    fn doc_toml_snippets_parse_and_validate() {
        for (file, d) in crate::snippets::doc_snippets::<Box<dyn Damping>>(&[("damping/mod.rs", include_str!("mod.rs"))], &["solver", "damping"], &["viscous_eta", "viscous", "local", "adaptive"]) {
            d.validate().unwrap_or_else(|e| panic!("{file}: {e}"));
        }
    }
}
