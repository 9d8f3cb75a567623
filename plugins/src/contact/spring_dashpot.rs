//! `spring_dashpot`: the paper's incremental linear spring-dashpot with Coulomb slip and no
//! tension (eqs. 10-14; METHOD section 6).
//!
//! Per pair (area `A`, history `e_n`, `e_s` kept by the core, keyed by the pair):
//! - springs, incremental (eq. 10-11): `e_n += -k_n A dgap` (approach compresses),
//!   `e_s += -k_s A dslip`; on the first step of a pair `e_n = k_n A max(-gap, 0)` (the
//!   overlap reached when the pair is found; the paper starts from the touching instant);
//! - dashpots (eq. 12): `d_n = -eta_n A v_n`, `d_s = -eta_s A v_s`;
//! - no tension: `e_n <= 0` opens the pair (forces zero, history dropped); the normal force
//!   `e_n + d_n` is clamped at 0 (a dashpot does not pull);
//! - Coulomb slip (eq. 13-14): `|e_s + d_s| > mu N` with `N = max(e_n + d_n, 0)` the normal
//!   force gives `e_s = mu N sign(e_s + d_s)`, `d_s = 0`. (The paper tests `|e_s| > mu e_n`;
//!   including the dashpots keeps the tangential force within Coulomb's limit of the force
//!   really transmitted, also on the first step of a pair, when `e_s` is still 0 but the
//!   dashpot already sees the full sliding velocity.)
//! - force on the slave `(e_n + d_n) n + (e_s + d_s) t` (eq. 15), the opposite on the face.
//!
//! Energy: stored `e_n^2 / (2 k_n A) + e_s^2 / (2 k_s A)`; dissipated: dashpot power x dt
//! plus, when slipping, the slip `|e_s,trial - e_s| / (k_s A)` times `|e_s|`.
//!
//! Units: `normal_stiffness`, `shear_stiffness` stress/length; `normal_damping`,
//! `shear_damping` stress x time / length; `friction` dimensionless.
//!
//! ```toml
//! [contact]
//! law = { type = "spring_dashpot", normal_stiffness = 1e6, shear_stiffness = 2.5e5, friction = 0.577 }
//! ```
//!
//! ```toml
//! [contact.law]
//! type = "spring_dashpot"
//! # paper Table 1: k_n = 6210 rho g = 1.61e7 dyn/cm and k_s = 1552 rho g = 4.03e6 dyn/cm per
//! # node (rho = 2.65 g/cm^3, g = 980 cm/s^2); per unit area for a node of 1 cm^2:
//! normal_stiffness = 1.61e7
//! shear_stiffness = 4.03e6
//! normal_damping = 10.0
//! shear_damping = 10.0
//! friction = 0.577            # paper Table 1
//! ```
use flem_core::contact::{ContactLaw, PairForce, PairKinematics, PairState};
use flem_core::traits::ParamError;
use serde::{Deserialize, Serialize};

use super::coulomb_cap;

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringDashpot {
    pub normal_stiffness: f64,
    pub shear_stiffness: f64,
    #[serde(default)]
    pub normal_damping: f64,
    #[serde(default)]
    pub shear_damping: f64,
    #[serde(default)]
    pub friction: f64,
}

#[typetag::serde(name = "spring_dashpot")]
impl ContactLaw for SpringDashpot {
    fn validate(&self) -> Result<(), ParamError> {
        ParamError::range("normal_stiffness", self.normal_stiffness, 0.0, false, f64::INFINITY, false)?;
        ParamError::range("shear_stiffness", self.shear_stiffness, 0.0, false, f64::INFINITY, false)?;
        ParamError::range("normal_damping", self.normal_damping, 0.0, true, f64::INFINITY, false)?;
        ParamError::range("shear_damping", self.shear_damping, 0.0, true, f64::INFINITY, false)?;
        ParamError::range("friction", self.friction, 0.0, true, f64::INFINITY, false)
    }
    fn stiffness(&self) -> f64 {
        self.normal_stiffness.max(self.shear_stiffness)
    }
    fn evaluate(&self, kin: &[PairKinematics], hist: &mut [PairState], out: &mut [PairForce]) {
        for ((k, h), o) in kin.iter().zip(hist.iter_mut()).zip(out.iter_mut()) {
            let (kn, ks) = (self.normal_stiffness * k.area, self.shear_stiffness * k.area);
            if k.new {
                h.en = kn * (-k.gap).max(0.0);
                h.es = 0.0;
            } else {
                h.en -= kn * k.dgap;
                h.es -= ks * k.dslip;
            }
            if h.en <= 0.0 {
                *o = PairForce::default();
                continue;
            }
            let dn = -self.normal_damping * k.area * k.vn;
            let mut ds = -self.shear_damping * k.area * k.vs;
            let normal = (h.en + dn).max(0.0);
            let trial = h.es + ds;
            let (capped, slipped) = coulomb_cap(trial, self.friction * normal);
            let mut diss = 0.0;
            if slipped {
                diss += (h.es - capped).abs() / ks * capped.abs();
                h.es = capped;
                ds = 0.0;
            }
            diss += -((normal - h.en) * k.vn + ds * k.vs) * k.dt;
            *o = PairForce { normal, tangential: h.es + ds, active: true, stored: 0.5 * h.en * h.en / kn + 0.5 * h.es * h.es / ks, dissipated: diss };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn law() -> SpringDashpot {
        SpringDashpot { normal_stiffness: 100.0, shear_stiffness: 50.0, normal_damping: 0.0, shear_damping: 0.0, friction: 0.5 }
    }

    /// Loading then unloading along the normal is elastic and the pair opens at e_n <= 0
    /// (eq. 10, no tension). Reference: hand values; exact.
    #[test]
    fn normal_spring_is_incremental_and_opens_without_tension() {
        let l = law();
        let mut h = [PairState::default()];
        let mut o = [PairForce::default()];
        let k = PairKinematics { gap: -0.01, area: 2.0, dt: 1.0, new: true, ..Default::default() };
        l.evaluate(&[k], &mut h, &mut o);
        assert!((o[0].normal - 2.0).abs() < 1e-12 && o[0].active);
        let k = PairKinematics { gap: -0.005, dgap: 0.005, area: 2.0, dt: 1.0, ..Default::default() };
        l.evaluate(&[k], &mut h, &mut o);
        assert!((o[0].normal - 1.0).abs() < 1e-12);
        let k = PairKinematics { gap: 0.001, dgap: 0.006, area: 2.0, dt: 1.0, ..Default::default() };
        l.evaluate(&[k], &mut h, &mut o);
        assert!(!o[0].active && o[0].normal == 0.0);
    }

    /// Tangential force is capped at mu e_n (eq. 13) and the slip dissipates energy.
    /// Reference: Coulomb's law; exact.
    #[test]
    fn coulomb_cap_and_slip_dissipation() {
        let l = law();
        let mut h = [PairState { en: 10.0, ..Default::default() }];
        let mut o = [PairForce::default()];
        let k = PairKinematics { gap: -0.05, dslip: 1.0, area: 1.0, dt: 1.0, ..Default::default() };
        l.evaluate(&[k], &mut h, &mut o);
        assert!((o[0].tangential + 5.0).abs() < 1e-12, "{}", o[0].tangential);
        assert!(o[0].dissipated > 0.0);
    }
}
