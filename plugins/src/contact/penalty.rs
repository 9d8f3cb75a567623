//! `penalty`: a total-gap penalty law with regularised Coulomb friction (METHOD section 6,
//! an alternative to the paper's incremental eq. 10-14).
//!
//! - normal (total gap, no tension): `f_n = k_n A max(-gap, 0) - eta_n A v_n`, clamped >= 0;
//!   the pair is active only while `gap < 0`. Without the dashpot the normal force is the
//!   gradient of `1/2 k_n A gap^2`: no energy is created or lost by contact.
//! - tangential (regularised Coulomb, no history): `f_t = -mu f_n v_s / sqrt(v_s^2 + v_reg^2)`;
//!   a body at rest creeps at about `v_reg` times its demand ratio, so use `spring_dashpot`
//!   when sticking must be exact.
//!
//! Energy: stored `1/2 k_n A gap^2`; dissipated `(eta_n A v_n^2 + |f_t v_s|) dt`.
//! Units: `normal_stiffness` stress/length, `normal_damping` stress x time / length,
//! `slip_velocity` length/time, `friction` dimensionless.
//!
//! ```toml
//! [contact]
//! law = { type = "penalty", normal_stiffness = 1e5, friction = 0.3, slip_velocity = 1e-4 }
//! ```
use flem_core::contact::contact3::{PairForce3, PairKinematics3, PairState3};
use flem_core::contact::{ContactLaw, PairForce, PairKinematics, PairState};
use flem_core::plugin::traits::ParamError;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Penalty {
    pub normal_stiffness: f64,
    #[serde(default)]
    pub normal_damping: f64,
    #[serde(default)]
    pub friction: f64,
    #[serde(default = "default_vreg")]
    pub slip_velocity: f64,
}

fn default_vreg() -> f64 {
    1e-6
}

#[typetag::serde(name = "penalty")]
impl ContactLaw for Penalty {
    fn validate(&self) -> Result<(), ParamError> {
        ParamError::range("normal_stiffness", self.normal_stiffness, 0.0, false, f64::INFINITY, false)?;
        ParamError::range("normal_damping", self.normal_damping, 0.0, true, f64::INFINITY, false)?;
        ParamError::range("friction", self.friction, 0.0, true, f64::INFINITY, false)?;
        ParamError::range("slip_velocity", self.slip_velocity, 0.0, false, f64::INFINITY, false)
    }
    fn stiffness(&self) -> f64 {
        self.normal_stiffness
    }
    fn evaluate(&self, kin: &[PairKinematics], hist: &mut [PairState], out: &mut [PairForce]) {
        for ((k, h), o) in kin.iter().zip(hist.iter_mut()).zip(out.iter_mut()) {
            if k.gap >= 0.0 {
                *o = PairForce::default();
                continue;
            }
            let kn = self.normal_stiffness * k.area;
            let el = -kn * k.gap;
            let normal = (el - self.normal_damping * k.area * k.vn).max(0.0);
            let ft = -self.friction * normal * k.vs / (k.vs * k.vs + self.slip_velocity * self.slip_velocity).sqrt();
            h.en = el;
            h.es = ft;
            let diss = (-(normal - el) * k.vn - ft * k.vs) * k.dt;
            *o = PairForce { normal, tangential: ft, active: true, stored: 0.5 * el * el / kn, dissipated: diss, fracture: 0.0 };
        }
    }
    /// The 3D form (issue 38, docs/3d.md "Contact (3D)"): the same total-gap normal force;
    /// friction `f_t = -mu f_n v_s / sqrt(|v_s|^2 + v_reg^2)` with `v_s` the tangential
    /// relative velocity vector in the face's plane.
    fn evaluate_3d(&self, kin: &[PairKinematics3], hist: &mut [PairState3], out: &mut [PairForce3]) -> Result<(), String> {
        for ((k, h), o) in kin.iter().zip(hist.iter_mut()).zip(out.iter_mut()) {
            if k.gap >= 0.0 {
                *o = PairForce3::default();
                continue;
            }
            let kn = self.normal_stiffness * k.area;
            let el = -kn * k.gap;
            let normal = (el - self.normal_damping * k.area * k.vn).max(0.0);
            let v2 = k.vs[0] * k.vs[0] + k.vs[1] * k.vs[1] + k.vs[2] * k.vs[2];
            let c = -self.friction * normal / (v2 + self.slip_velocity * self.slip_velocity).sqrt();
            let ft = k.vs.map(|v| c * v);
            h.en = el;
            h.es = ft;
            let diss = (-(normal - el) * k.vn - c * v2) * k.dt;
            *o = PairForce3 { normal, tangential: ft, active: true, stored: 0.5 * el * el / kn, dissipated: diss };
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The normal force is k A pen whatever the path; friction opposes the slip and tends to
    /// mu f_n for |v_s| >> v_reg. Reference: the law's formula; 1e-12 and 1e-6.
    #[test]
    fn total_gap_force_and_regularised_friction() {
        let l = Penalty { normal_stiffness: 100.0, normal_damping: 0.0, friction: 0.4, slip_velocity: 1e-6 };
        let mut h = [PairState::default()];
        let mut o = [PairForce::default()];
        l.evaluate(&[PairKinematics { gap: -0.01, vs: 1.0, area: 3.0, dt: 1.0, ..Default::default() }], &mut h, &mut o);
        assert!((o[0].normal - 3.0).abs() < 1e-12);
        assert!((o[0].tangential + 1.2).abs() < 1e-6);
        l.evaluate(&[PairKinematics { gap: 0.01, area: 3.0, dt: 1.0, ..Default::default() }], &mut h, &mut o);
        assert!(!o[0].active);
    }
}
