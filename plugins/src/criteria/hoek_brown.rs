//! `hoek_brown`: the generalised Hoek-Brown criterion for rock masses (Hoek, Carranza-Torres
//! and Corkum 2002); an alternative to the paper's Mohr-Coulomb (METHOD section 4; paper
//! section 2.2 uses eqs. (1)-(2), this is our extension).
//!
//! Compression positive, `s1 >= s3`, stresses in any consistent unit. With `sigma_ci` the
//! uniaxial compressive strength of the intact rock (stress; `scale` multiplies it), `m_b`,
//! `s`, `a` dimensionless:
//!
//! `s1_f(s3) = s3 + sigma_ci (m_b s3 / sigma_ci + s)^a`
//!
//! - **Tension**: fails when `s3 <= -sigma_t` with `sigma_t = s sigma_ci / m_b`, the apex of
//!   the envelope (where the bracket vanishes; the biaxial tensile strength of Hoek et al.
//!   2002). One plane, the sigma1 direction. Index `-s3 / sigma_t`.
//! - **Shear**: for `s3 > -sigma_t`, fails when `s1 >= s1_f(s3)`. Index
//!   `(s1 - s3) / (sigma_ci (m_b s3 / sigma_ci + s)^a)`. Planes at `theta1 +- (pi/4 - phi_i/2)`
//!   with the instantaneous friction angle at `s3`: `k = ds1_f/ds3 = 1 + a m_b
//!   (m_b s3 / sigma_ci + s)^(a - 1)`, `sin(phi_i) = (k - 1) / (k + 1)`.
//! - The index is the max of the two, clamped to [0, 1e6]; the modes never overlap (tension
//!   covers `s3 <= -sigma_t`, where the envelope is undefined).
//!
//! With `a = 0.5`, `s = 1` this is the classic intact-rock formula
//! `s1 = s3 + sqrt(m_i sigma_ci s3 + sigma_ci^2)`: UCS = `sigma_ci`.
//!
//! Keys: `sigma_ci` > 0, `m_b` > 0, `s` in (0, 1] (use a small positive `s` for a fully
//! broken mass), `a` in (0, 1] (0.5 to 0.67 in practice).
//!
//! ```toml
//! [cracking.criterion]
//! type = "hoek_brown"
//! sigma_ci = 50.0e6   # Pa
//! m_b = 10.0
//! s = 1.0
//! a = 0.5
//! ```
use serde::{Deserialize, Serialize};

use flem_core::plugin::traits::{FailureCheck, FailureCriterion, ParamError, Principal};

use super::{holds, ratio_index, shear_check, tension_check};

/// Generalised Hoek-Brown (see the module docs).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HoekBrown {
    /// Uniaxial compressive strength of the intact rock (stress), > 0.
    pub sigma_ci: f64,
    /// Rock-mass constant m_b (dimensionless), > 0.
    pub m_b: f64,
    /// Rock-mass constant s (dimensionless), in (0, 1].
    pub s: f64,
    /// Exponent a (dimensionless), in (0, 1].
    pub a: f64,
}

impl HoekBrown {
    /// The tensile strength `s sigma_ci / m_b` at strength scale `scale`.
    pub fn tensile_strength(&self, scale: f64) -> f64 {
        self.s * self.sigma_ci * scale / self.m_b
    }

    /// The strength `s1_f(s3)` on the envelope (NaN below the apex).
    pub fn envelope(&self, s3: f64, scale: f64) -> f64 {
        let sci = self.sigma_ci * scale;
        s3 + sci * (self.m_b * s3 / sci + self.s).powf(self.a)
    }

    /// The instantaneous friction angle (radians) at `s3` (pi/2 at the apex).
    pub fn instantaneous_phi(&self, s3: f64, scale: f64) -> f64 {
        let base = self.m_b * s3 / (self.sigma_ci * scale) + self.s;
        let k = 1.0 + self.a * self.m_b * base.powf(self.a - 1.0);
        let sin = 1.0 - 2.0 / (k + 1.0);
        sin.clamp(0.0, 1.0).asin()
    }
}

#[typetag::serde(name = "hoek_brown")]
impl FailureCriterion for HoekBrown {
    fn validate(&self) -> Result<(), ParamError> {
        ParamError::range("sigma_ci", self.sigma_ci, 0.0, false, f64::INFINITY, false)?;
        ParamError::range("m_b", self.m_b, 0.0, false, f64::INFINITY, false)?;
        ParamError::range("s", self.s, 0.0, false, 1.0, true)?;
        ParamError::range("a", self.a, 0.0, false, 1.0, true)
    }

    /// Failure and index use the principal values only; `theta1` gives the planes.
    fn isotropic(&self) -> bool {
        true
    }

    fn check(&self, p: &Principal, scale: f64) -> FailureCheck {
        let st = self.tensile_strength(scale);
        let it = -p.s3 / st;
        if p.s3 <= -st {
            return tension_check(it, p.theta1);
        }
        let cap = self.envelope(p.s3, scale) - p.s3;
        let index = it.max(ratio_index(p.s1 - p.s3, cap));
        if p.s1 - p.s3 >= cap {
            shear_check(index, p.theta1, self.instantaneous_phi(p.s3, scale))
        } else {
            holds(index)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use flem_core::plugin::traits::FailureMode;

    fn classic(m: f64) -> HoekBrown {
        HoekBrown { sigma_ci: 100.0, m_b: m, s: 1.0, a: 0.5 }
    }

    fn pr(s1: f64, s3: f64) -> Principal {
        Principal { s1, s3, s2: 0.0, theta1: 0.0 }
    }

    /// a = 0.5, s = 1 reduces to the classic formula s1 = s3 + sqrt(m sigma_ci s3 + sigma_ci^2)
    /// (Hoek and Brown 1980). Reference: that formula; tolerance 1e-9 relative.
    #[test]
    fn reduces_to_classic_formula() {
        let hb = classic(10.0);
        for s3 in [-5.0, 0.0, 1.0, 10.0, 50.0] {
            let want = s3 + (10.0 * 100.0 * s3 + 100.0f64 * 100.0).sqrt();
            assert!((hb.envelope(s3, 1.0) - want).abs() < 1e-9 * want.abs(), "s3 = {s3}");
            assert!((hb.check(&pr(want, s3), 1.0).index - 1.0).abs() < 1e-12);
        }
    }

    /// UCS = sigma_ci and the tension cut-off sits at s3 = -s sigma_ci / m_b.
    /// Reference: the formulas; tolerance 1e-9 relative (fails just beyond, holds just inside).
    #[test]
    fn ucs_and_tensile_strength() {
        let hb = classic(10.0);
        assert!(hb.check(&pr(100.0 * (1.0 + 1e-9), 0.0), 1.0).failed());
        assert!(!hb.check(&pr(100.0 * (1.0 - 1e-9), 0.0), 1.0).failed());
        assert!((hb.tensile_strength(1.0) - 10.0).abs() < 1e-12);
        let t = hb.check(&pr(0.0, -10.0), 1.0);
        assert_eq!(t.mode, Some(FailureMode::Tension));
        assert!((t.index - 1.0).abs() < 1e-12 && t.n_planes == 1);
        // just inside the cut-off with no deviator beyond the envelope: holds
        let s3 = -10.0 * (1.0 - 1e-6);
        assert!(!hb.check(&pr(s3, s3), 1.0).failed());
        // scale multiplies sigma_ci: UCS doubles
        assert!(!hb.check(&pr(190.0, 0.0), 2.0).failed() && hb.check(&pr(210.0, 0.0), 2.0).failed());
    }

    /// Shear planes use the instantaneous friction angle: at s3 = 0 with m = 10, a = 0.5, s = 1,
    /// k = 1 + 0.5 * 10 = 6, sin(phi_i) = 5/7. Tolerance 1e-12.
    #[test]
    fn planes_from_instantaneous_phi() {
        let hb = classic(10.0);
        let phi = (5.0f64 / 7.0).asin();
        assert!((hb.instantaneous_phi(0.0, 1.0) - phi).abs() < 1e-12);
        let f = hb.check(&pr(150.0, 0.0), 1.0);
        assert_eq!(f.mode, Some(FailureMode::Shear));
        let h = std::f64::consts::FRAC_PI_4 - 0.5 * phi;
        assert!((f.planes[0] - h).abs() < 1e-12 && (f.planes[1] - (std::f64::consts::PI - h)).abs() < 1e-12);
        // at the apex the angle is pi/2 and nothing is NaN
        assert!((hb.instantaneous_phi(-10.0, 1.0) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let r = hb.check(&Principal { s1: f64::NAN, s3: f64::NAN, s2: 0.0, theta1: 0.0 }, 1.0);
        assert!(!r.failed() && r.index == 0.0);
    }

    /// The error names the key.
    #[test]
    fn bad_input_names_the_key() {
        let e = HoekBrown { s: 1.5, ..classic(10.0) }.validate().unwrap_err();
        assert_eq!(e.to_string(), "s = 1.5 is incorrect; it must be in (0, 1]");
        let e = HoekBrown { m_b: 0.0, ..classic(10.0) }.validate().unwrap_err();
        assert_eq!(e.to_string(), "m_b = 0 is incorrect; it must be in (0, inf)");
    }
}
