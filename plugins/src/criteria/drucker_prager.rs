//! `drucker_prager`: the Drucker-Prager cone, a smooth alternative to Mohr-Coulomb that also
//! sees the out-of-plane stress `s2` (METHOD section 4; the paper uses Mohr-Coulomb, eq. (2);
//! Drucker-Prager is our extension).
//!
//! Compression positive throughout. With `I1 = s1 + s2 + s3` (three times the mean pressure) and
//! `J2 = ((s1 - s2)^2 + (s2 - s3)^2 + (s3 - s1)^2) / 6`, a point fails (mode shear) when
//!
//! `sqrt(J2) >= alpha I1 + k`
//!
//! so strength grows with pressure for `alpha > 0` (`alpha` dimensionless, `k` a stress;
//! `scale` multiplies `k`). Failure index `sqrt(J2) / (alpha I1 + k)` when the denominator is
//! > 0, else 1e6 (beyond the apex: mean tension `k / (3 alpha)` fails even without deviator).
//!
//! Give either `alpha` and `k`, or `match_mohr_coulomb` with `cohesion` (stress) and
//! `friction_angle_deg` (in [0, 90)):
//! - `"outer"`: the cone through the compression meridian of Mohr-Coulomb (`s1 > s2 = s3`):
//!   `alpha = 2 sin(phi) / (sqrt(3) (3 - sin(phi)))`, `k = 6 c cos(phi) / (sqrt(3) (3 - sin(phi)))`;
//! - `"inner"`: through the extension meridian (`s1 = s2 > s3`):
//!   `alpha = 2 sin(phi) / (sqrt(3) (3 + sin(phi)))`, `k = 6 c cos(phi) / (sqrt(3) (3 + sin(phi)))`;
//! - `"plane_strain"`: the same collapse load as Mohr-Coulomb in plane strain with associated
//!   flow: `alpha = tan(phi) / sqrt(9 + 12 tan^2(phi))`, `k = 3 c / sqrt(9 + 12 tan^2(phi))`.
//!
//! Failure planes: as for Mohr-Coulomb, `theta1 +- (pi/4 - phi/2)` (mod pi, ascending), with
//! the matched `phi`; with explicit `alpha`, `k`, `phi` is the inverse of the plane-strain
//! match, `tan(phi) = 3 alpha / sqrt(1 - 12 alpha^2)` (phi = 90 deg when `12 alpha^2 >= 1`).
//! At `s1 == s3` the direction follows `theta1` as supplied (0 from `principal()`).
//! There is no separate tension cut-off: combine with care, or use `mohr_coulomb`.
//!
//! ```toml
//! [cracking.criterion]
//! type = "drucker_prager"
//! match_mohr_coulomb = "plane_strain"   # or "outer", "inner"
//! cohesion = 0.1                        # stress
//! friction_angle_deg = 30.0
//! ```
//!
//! ```toml
//! [cracking.criterion]
//! type = "drucker_prager"
//! alpha = 0.2       # dimensionless
//! k = 0.1           # stress
//! ```
use serde::{Deserialize, Serialize};

use flem_core::plugin::traits::{FailureCheck, FailureCriterion, ParamError, Principal};

use super::{holds, ratio_index, shear_check};

/// Which Mohr-Coulomb surface the cone is matched to.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DpMatch {
    Outer,
    Inner,
    PlaneStrain,
}

/// Drucker-Prager (see the module docs). All keys optional in serde; `validate` checks the
/// combination.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DruckerPrager {
    /// Pressure coefficient (dimensionless), >= 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha: Option<f64>,
    /// Shear strength at zero pressure (stress), >= 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub match_mohr_coulomb: Option<DpMatch>,
    /// Mohr-Coulomb cohesion (stress), >= 0; only with `match_mohr_coulomb`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cohesion: Option<f64>,
    /// Mohr-Coulomb friction angle (degrees) in [0, 90); only with `match_mohr_coulomb`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_angle_deg: Option<f64>,
}

/// `(alpha, k)` of the cone matched to Mohr-Coulomb `(c, phi)` (phi in radians).
pub fn dp_from_mc(m: DpMatch, c: f64, phi: f64) -> (f64, f64) {
    let (s, co) = (phi.sin(), phi.cos());
    let r3 = 3f64.sqrt();
    match m {
        DpMatch::Outer => (2.0 * s / (r3 * (3.0 - s)), 6.0 * c * co / (r3 * (3.0 - s))),
        DpMatch::Inner => (2.0 * s / (r3 * (3.0 + s)), 6.0 * c * co / (r3 * (3.0 + s))),
        DpMatch::PlaneStrain => {
            let t = phi.tan();
            let d = (9.0 + 12.0 * t * t).sqrt();
            (t / d, 3.0 * c / d)
        }
    }
}

/// The friction angle whose plane-strain match gives `alpha` (radians, in [0, pi/2]).
pub fn phi_from_alpha(alpha: f64) -> f64 {
    let q = 1.0 - 12.0 * alpha * alpha;
    if q > 0.0 {
        (3.0 * alpha / q.sqrt()).atan()
    } else {
        0.5 * std::f64::consts::PI
    }
}

/// `(I1, sqrt(J2))`, compression positive.
pub fn invariants(p: &Principal) -> (f64, f64) {
    let (a, b, c) = (p.s1, p.s2, p.s3);
    let j2 = ((a - b).powi(2) + (b - c).powi(2) + (c - a).powi(2)) / 6.0;
    (a + b + c, j2.sqrt())
}

fn missing(key: &str) -> ParamError {
    ParamError::new(key, "is missing; give either alpha and k, or match_mohr_coulomb with cohesion and friction_angle_deg")
}

fn unexpected(key: &str, v: f64, with: &str) -> ParamError {
    ParamError::new(key, format!("= {v} is incorrect; it is not used {with}"))
}

impl DruckerPrager {
    /// `(alpha, k, phi)`; `None` when the combination of keys is incomplete.
    pub fn params(&self) -> Option<(f64, f64, f64)> {
        match (self.match_mohr_coulomb, self.alpha, self.k) {
            (Some(m), _, _) => {
                let phi = self.friction_angle_deg?.to_radians();
                let (a, k) = dp_from_mc(m, self.cohesion?, phi);
                Some((a, k, phi))
            }
            (None, Some(a), Some(k)) => Some((a, k, phi_from_alpha(a))),
            _ => None,
        }
    }

    fn validate_matched(&self) -> Result<(), ParamError> {
        if let Some(a) = self.alpha {
            return Err(unexpected("alpha", a, "with match_mohr_coulomb"));
        }
        if let Some(k) = self.k {
            return Err(unexpected("k", k, "with match_mohr_coulomb"));
        }
        let c = self.cohesion.ok_or_else(|| missing("cohesion"))?;
        let phi = self.friction_angle_deg.ok_or_else(|| missing("friction_angle_deg"))?;
        ParamError::range("cohesion", c, 0.0, true, f64::INFINITY, false)?;
        ParamError::range("friction_angle_deg", phi, 0.0, true, 90.0, false)
    }

    fn validate_explicit(&self) -> Result<(), ParamError> {
        if let Some(c) = self.cohesion {
            return Err(unexpected("cohesion", c, "without match_mohr_coulomb"));
        }
        if let Some(f) = self.friction_angle_deg {
            return Err(unexpected("friction_angle_deg", f, "without match_mohr_coulomb"));
        }
        let a = self.alpha.ok_or_else(|| missing("alpha"))?;
        let k = self.k.ok_or_else(|| missing("k"))?;
        ParamError::range("alpha", a, 0.0, true, f64::INFINITY, false)?;
        ParamError::range("k", k, 0.0, true, f64::INFINITY, false)
    }
}

#[typetag::serde(name = "drucker_prager")]
impl FailureCriterion for DruckerPrager {
    fn validate(&self) -> Result<(), ParamError> {
        match self.match_mohr_coulomb {
            Some(_) => self.validate_matched(),
            None => self.validate_explicit(),
        }
    }

    /// Failure and index use the principal values only; `theta1` gives the planes.
    fn isotropic(&self) -> bool {
        true
    }

    /// `cap - q` over its largest rate (ours, issue 24): `I1` moves at most `3 rho`, so `cap`
    /// at most `3 |alpha| rho`; `sqrt(J2)` at most `sqrt(2) rho` (each difference of principal
    /// values at most `2 rho`).
    fn margin(&self, p: &Principal, scale: f64) -> Option<f64> {
        let Some((alpha, k, _)) = self.params() else { return Some(f64::INFINITY) };
        let (i1, q) = invariants(p);
        Some((alpha * i1 + k * scale - q) / (3.0 * alpha.abs() + std::f64::consts::SQRT_2))
    }
    fn check(&self, p: &Principal, scale: f64) -> FailureCheck {
        let Some((alpha, k, phi)) = self.params() else { return holds(0.0) };
        let (i1, q) = invariants(p);
        let cap = alpha * i1 + k * scale;
        let index = ratio_index(q, cap);
        if q >= cap {
            shear_check(index, p.theta1, phi)
        } else {
            holds(index)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::criteria::mohr_coulomb::mc_shear_fails;
    use flem_core::plugin::traits::FailureMode;

    const C: f64 = 0.1;
    const PHI_DEG: f64 = 30.0;

    fn matched(m: DpMatch) -> DruckerPrager {
        DruckerPrager { match_mohr_coulomb: Some(m), cohesion: Some(C), friction_angle_deg: Some(PHI_DEG), ..Default::default() }
    }

    /// Mohr-Coulomb's major principal stress at failure for a given minor one:
    /// `s1 = s3 (1 + sin phi)/(1 - sin phi) + 2 c cos phi / (1 - sin phi)`.
    fn mc_s1(s3: f64) -> f64 {
        let phi = PHI_DEG.to_radians();
        (s3 * (1.0 + phi.sin()) + 2.0 * C * phi.cos()) / (1.0 - phi.sin())
    }

    fn pr(s1: f64, s2: f64, s3: f64) -> Principal {
        Principal { s1, s2, s3, theta1: 0.0 }
    }

    /// The outer cone equals Mohr-Coulomb on the compression meridian (s2 = s3) and the inner
    /// cone on the extension meridian (s2 = s1). Reference: the analytic MC envelope;
    /// tolerance: index 1 to 1e-12 on the envelope, fails/holds at 1 +- 1e-9 of the deviator.
    #[test]
    fn inner_outer_match_mc_on_meridians() {
        let (outer, inner) = (matched(DpMatch::Outer), matched(DpMatch::Inner));
        for s3 in [-0.05, 0.0, 0.5, 2.0, 10.0] {
            let s1 = mc_s1(s3);
            let dev = s1 - s3;
            assert!((outer.check(&pr(s1, s3, s3), 1.0).index - 1.0).abs() < 1e-12, "outer s3 = {s3}");
            assert!((inner.check(&pr(s1, s1, s3), 1.0).index - 1.0).abs() < 1e-12, "inner s3 = {s3}");
            let (up, down) = (s3 + dev * (1.0 + 1e-9), s3 + dev * (1.0 - 1e-9));
            assert!(outer.check(&pr(up, s3, s3), 1.0).failed() && !outer.check(&pr(down, s3, s3), 1.0).failed());
            assert!(inner.check(&pr(up, up, s3), 1.0).failed() && !inner.check(&pr(down, down, s3), 1.0).failed());
            // consistent with our Mohr-Coulomb branch on the same states
            assert!(mc_shear_fails(&pr(up, 0.0, s3), C, PHI_DEG.to_radians()));
        }
    }

    /// The plane-strain cone: for (s1, s3) on the MC envelope, the minimum over s2 of
    /// F = sqrt(J2) - alpha I1 - k is 0 (the stationary s2 is the plane-strain state of
    /// associated flow). Reference: the analytic MC envelope; tolerance 1e-10 (ternary search).
    #[test]
    fn plane_strain_match() {
        let (alpha, k, _) = matched(DpMatch::PlaneStrain).params().unwrap();
        for s3 in [0.0, 0.3, 1.0, 5.0] {
            let s1 = mc_s1(s3);
            let f = |s2: f64| {
                let (i1, q) = invariants(&pr(s1, s2, s3));
                q - alpha * i1 - k
            };
            let (mut lo, mut hi) = (s3 - 10.0 * s1, s1 + 10.0 * s1 + 10.0);
            for _ in 0..300 {
                let (a, b) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
                if f(a) < f(b) {
                    hi = b
                } else {
                    lo = a
                }
            }
            assert!(f(0.5 * (lo + hi)).abs() < 1e-10, "s3 = {s3}: min F = {}", f(0.5 * (lo + hi)));
        }
    }

    /// Explicit alpha, k reproduce the matched cone; the phi used for the planes inverts the
    /// plane-strain match. Tolerance 1e-12.
    #[test]
    fn explicit_params_and_planes() {
        let (alpha, k, phi) = matched(DpMatch::PlaneStrain).params().unwrap();
        assert!((phi_from_alpha(alpha) - phi).abs() < 1e-12);
        let ex = DruckerPrager { alpha: Some(alpha), k: Some(k), ..Default::default() };
        ex.validate().unwrap();
        let p = Principal { s1: 1.0, s2: 0.2, s3: -0.2, theta1: 1.0 };
        let (a, b) = (ex.check(&p, 1.0), matched(DpMatch::PlaneStrain).check(&p, 1.0));
        assert_eq!(a.mode, Some(FailureMode::Shear));
        assert!((a.index - b.index).abs() < 1e-12);
        assert!((a.planes[0] - (1.0 - (std::f64::consts::FRAC_PI_4 - 0.5 * phi))).abs() < 1e-12);
        // beyond the apex (mean tension) fails with index 1e6; scale multiplies k
        let t = ex.check(&pr(-1.0, -1.0, -1.0), 1.0);
        assert!(t.failed() && t.index == 1e6);
        assert!(!ex.check(&pr(0.0, 0.0, 0.0), 1.0).failed());
        let at = |sc: f64| ex.check(&p, sc);
        assert!(at(1.0).failed() && !at(10.0).failed());
        assert!((at(2.0).index - ratio_index(invariants(&p).1, alpha * 1.0 + 2.0 * k)).abs() < 1e-12);
    }

    /// Bad combinations and ranges name the key.
    #[test]
    fn bad_input_names_the_key() {
        let e = DruckerPrager { friction_angle_deg: Some(95.0), ..matched(DpMatch::Outer) }.validate().unwrap_err();
        assert_eq!(e.to_string(), "friction_angle_deg = 95 is incorrect; it must be in [0, 90)");
        let e = DruckerPrager { alpha: Some(0.1), ..matched(DpMatch::Outer) }.validate().unwrap_err();
        assert!(e.to_string().starts_with("alpha = 0.1 is incorrect"), "{e}");
        let e = DruckerPrager { alpha: Some(0.1), ..Default::default() }.validate().unwrap_err();
        assert!(e.to_string().starts_with("k is missing"), "{e}");
        let e = DruckerPrager { alpha: Some(-0.1), k: Some(1.0), ..Default::default() }.validate().unwrap_err();
        assert!(e.to_string().starts_with("alpha = -0.1 is incorrect; it must be in [0, inf)"), "{e}");
        let src = "type = \"drucker_prager\"\nalpha = 0.1\nk = 1\nbeta = 2\n";
        let err = toml::from_str::<Box<dyn FailureCriterion>>(src).unwrap_err().to_string();
        assert!(err.contains("unknown field `beta`"), "{err}");
        let src = "type = \"drucker_prager\"\nmatch_mohr_coulomb = \"middle\"\ncohesion = 1\nfriction_angle_deg = 3\n";
        let err = toml::from_str::<Box<dyn FailureCriterion>>(src).unwrap_err().to_string();
        assert!(err.contains("unknown variant `middle`"), "{err}");
        // an incomplete config never panics in check
        assert!(!DruckerPrager::default().check(&pr(1.0, 0.0, -1.0), 1.0).failed());
    }
}
