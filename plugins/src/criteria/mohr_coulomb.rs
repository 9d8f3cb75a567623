//! `mohr_coulomb`: Mohr-Coulomb with a tension cut-off, the paper's criterion
//! (paper section 2.2, eqs. (1) and (2); METHOD section 4).
//!
//! Compression positive, `s1 >= s3` in-plane principal stresses (stress units), `c` the
//! cohesion (stress), `phi` the friction angle, `sigma_t > 0` the tensile strength (stress).
//! `scale` multiplies `c` and `sigma_t`.
//!
//! - **Tension** (eq. (1), with the sign fixed by METHOD 4): fails when `s3 <= -sigma_t`.
//!   One failure plane, parallel to the sigma1 direction (`theta1`; its normal is the sigma3
//!   direction). Index `-s3 / sigma_t`.
//! - **Shear** (eq. (2)): fails when
//!   `f_s = (2 c cos(phi) + (s1 + s3) sin(phi)) / (s1 - s3) <= 1`.
//!   We test the equivalent `2 c cos(phi) + (s1 + s3) sin(phi) <= s1 - s3`, which never divides
//!   by zero: at `s1 == s3` the state fails only when the numerator is `<= 0` (mean stress in
//!   tension beyond the apex `c / tan(phi)`). Two failure planes at
//!   `theta1 +- (pi/4 - phi/2)` (mod pi, ascending). Direction convention at `s1 == s3`:
//!   `theta1` as supplied, i.e. 0 (+x) from `principal()`, so the planes are then at
//!   `+-(pi/4 - phi/2)` from +x. Index `((s1 - s3)/2) / (c cos(phi) + (s1 + s3)/2 sin(phi))`
//!   when that denominator is > 0, otherwise 1e6 (beyond the apex).
//! - The index is the max over the enabled branches, clamped to [0, 1e6]. When both branches
//!   fail, the mode is the branch with the larger index; on an exact tie, tension.
//!   With the paper's Table 1 values (c = 0.1, phi = 30 deg, sigma_t = 1) the cut-off lies
//!   beyond the apex (c / tan(phi) = 0.173), so in tension the shear branch wins when it is on.
//!
//! Keys: `cohesion` >= 0, `friction_angle_deg` in [0, 90), `tensile_strength` > 0,
//! `tension` (default true), `shear` (default true); at least one branch must be on.
//! The paper's shear model switches `tension` off, its opening model `shear`.
//!
//! ```toml
//! [cracking.criterion]
//! type = "mohr_coulomb"
//! cohesion = 0.1            # kgf/cm^2 (paper Table 1)
//! friction_angle_deg = 30.0
//! tensile_strength = 1.0    # kgf/cm^2
//! tension = false           # the paper's shear model
//! ```
//!
//! ```toml
//! [cracking.criterion]
//! type = "mohr_coulomb"
//! cohesion = 0.1
//! friction_angle_deg = 30.0
//! tensile_strength = 1.0
//! shear = false             # the paper's opening model
//! ```
use serde::{Deserialize, Serialize};

use flem_core::plugin::traits::{affine_crossing, FailureCheck, FailureCriterion, ParamError, Principal};

use super::{holds, ratio_index, shear_check, tension_check};

fn yes() -> bool {
    true
}

/// Mohr-Coulomb with a tension cut-off (see the module docs).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MohrCoulomb {
    /// Cohesion c (stress), >= 0.
    pub cohesion: f64,
    /// Friction angle phi (degrees), in [0, 90).
    pub friction_angle_deg: f64,
    /// Tensile strength sigma_t (stress), > 0.
    pub tensile_strength: f64,
    /// Tension cut-off on (eq. (1)).
    #[serde(default = "yes")]
    pub tension: bool,
    /// Shear branch on (eq. (2)).
    #[serde(default = "yes")]
    pub shear: bool,
}

/// The branch indices of Mohr-Coulomb: `(tension, shear)` (unclamped).
pub fn mc_indices(p: &Principal, c: f64, phi: f64, sigma_t: f64) -> (f64, f64) {
    let tension = -p.s3 / sigma_t;
    let cap = c * phi.cos() + 0.5 * (p.s1 + p.s3) * phi.sin();
    (tension, ratio_index(0.5 * (p.s1 - p.s3), cap))
}

/// True when the shear branch fails: `2 c cos(phi) + (s1 + s3) sin(phi) <= s1 - s3`
/// (eq. (2) multiplied by `s1 - s3 >= 0`, so no division).
pub fn mc_shear_fails(p: &Principal, c: f64, phi: f64) -> bool {
    2.0 * c * phi.cos() + (p.s1 + p.s3) * phi.sin() <= p.s1 - p.s3
}

/// The paper's `f_s` (eq. (2)) for output and tests; `None` when `s1 == s3`.
pub fn f_s(p: &Principal, c: f64, phi: f64) -> Option<f64> {
    let den = p.s1 - p.s3;
    (den != 0.0).then(|| (2.0 * c * phi.cos() + (p.s1 + p.s3) * phi.sin()) / den)
}

impl MohrCoulomb {
    fn phi(&self) -> f64 {
        self.friction_angle_deg.to_radians()
    }
}

#[typetag::serde(name = "mohr_coulomb")]
impl FailureCriterion for MohrCoulomb {
    fn validate(&self) -> Result<(), ParamError> {
        ParamError::range("cohesion", self.cohesion, 0.0, true, f64::INFINITY, false)?;
        ParamError::range("friction_angle_deg", self.friction_angle_deg, 0.0, true, 90.0, false)?;
        ParamError::range("tensile_strength", self.tensile_strength, 0.0, false, f64::INFINITY, false)?;
        if !self.tension && !self.shear {
            return Err(ParamError::new("shear", "= false is incorrect while tension = false; at least one branch must be on"));
        }
        Ok(())
    }

    /// Failure and index use the principal values only; `theta1` gives the planes.
    fn isotropic(&self) -> bool {
        true
    }

    fn check(&self, p: &Principal, scale: f64) -> FailureCheck {
        let (c, phi, st) = (self.cohesion * scale, self.phi(), self.tensile_strength * scale);
        let (it, is) = mc_indices(p, c, phi, st);
        let it = if self.tension { it } else { f64::NEG_INFINITY };
        let is = if self.shear { is } else { f64::NEG_INFINITY };
        let t_fail = self.tension && p.s3 <= -st;
        let s_fail = self.shear && mc_shear_fails(p, c, phi);
        let index = it.max(is);
        match (t_fail, s_fail) {
            (true, true) if is > it => shear_check(index, p.theta1, phi),
            (true, _) => tension_check(index, p.theta1),
            (false, true) => shear_check(index, p.theta1, phi),
            (false, false) => holds(index),
        }
    }

    /// Closed form for the events solver: the first of the tension cut-off (`m + r = sigma_t`)
    /// and the shear line (`r + m sin(phi) = c cos(phi)`, tension positive), each a root of a
    /// quadratic (`affine_crossing`), for the branches that are on.
    /// The smaller of the branches' distances (ours, issue 24): tension `s3 + st` (moves
    /// with `s3` only); shear `h = 2 c cos(phi) - (1 - sin(phi)) s1 + (1 + sin(phi)) s3`, which
    /// moves at most `(1 - sin(phi)) + (1 + sin(phi)) = 2` per unit move of each principal value.
    fn margin(&self, p: &Principal, scale: f64) -> Option<f64> {
        let (c, phi, st) = (self.cohesion * scale, self.phi(), self.tensile_strength * scale);
        let t = if self.tension { st + p.s3 } else { f64::INFINITY };
        let h = 2.0 * c * phi.cos() + (p.s1 + p.s3) * phi.sin() - (p.s1 - p.s3);
        let s = if self.shear { 0.5 * h } else { f64::INFINITY };
        Some(t.min(s))
    }
    fn affine_failure(&self, s0: [f64; 3], ds: [f64; 3], _szz0: f64, _dszz: f64, scale: f64, t0: f64, t1: f64) -> Option<f64> {
        let (c, phi, st) = (self.cohesion * scale, self.phi(), self.tensile_strength * scale);
        let t = if self.tension { affine_crossing(s0, ds, 1.0, st, t0, t1) } else { f64::INFINITY };
        let s = if self.shear { affine_crossing(s0, ds, phi.sin(), c * phi.cos(), t0, t1) } else { f64::INFINITY };
        Some(t.min(s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use flem_core::plugin::traits::{principal, FailureMode};

    fn paper() -> MohrCoulomb {
        MohrCoulomb { cohesion: 0.1, friction_angle_deg: 30.0, tensile_strength: 1.0, tension: true, shear: true }
    }

    fn deg(a: f64) -> f64 {
        a.to_degrees()
    }

    /// One table row: input, s1, s3, sigma1 dir, f_s, tension fails, shear planes.
    type Row = ([f64; 3], f64, f64, f64, f64, bool, [f64; 2]);

    /// METHOD.md section 4 worked-numbers table, all six rows and every column.
    /// Tolerances: stresses and angles 1e-9 (exact arithmetic), f_s 1e-4 (table rounding).
    #[test]
    fn method_worked_numbers_table() {
        // input (sxx, syy, sxy), s1, s3, sigma1 dir, f_s, tension fails, shear planes
        let rows: [Row; 6] = [
            ([1.2, 0.0, 0.0], 0.0, -1.2, 90.0, -0.3557, true, [60.0, 120.0]),
            ([0.8, 0.0, 0.0], 0.0, -0.8, 90.0, -0.2835, false, [60.0, 120.0]),
            ([0.0, 0.0, 0.3], 0.3, -0.3, 135.0, 0.2887, false, [105.0, 165.0]),
            ([-2.0, -0.5, 0.0], 2.0, 0.5, 0.0, 0.9488, false, [30.0, 150.0]),
            ([-2.0, -0.6, 0.0], 2.0, 0.6, 0.0, 1.0523, false, [30.0, 150.0]),
            ([-1.0, 0.0, 0.0], 1.0, 0.0, 0.0, 0.6732, false, [30.0, 150.0]),
        ];
        let (c, phi) = (0.1, 30f64.to_radians());
        let tension_only = MohrCoulomb { shear: false, ..paper() };
        let shear_only = MohrCoulomb { tension: false, ..paper() };
        for (s, s1, s3, dir, fs, t_fails, planes) in rows {
            let p = principal(s, 0.0);
            assert!((p.s1 - s1).abs() < 1e-9 && (p.s3 - s3).abs() < 1e-9, "{s:?}: {p:?}");
            assert!((deg(p.theta1) - dir).abs() < 1e-9, "{s:?}: dir {}", deg(p.theta1));
            let f = f_s(&p, c, phi).unwrap();
            assert!((f - fs).abs() < 1e-4, "{s:?}: f_s {f}");
            assert_eq!(tension_only.check(&p, 1.0).failed(), t_fails, "{s:?}");
            let sh = shear_only.check(&p, 1.0);
            assert_eq!(sh.failed(), fs <= 1.0, "{s:?}");
            let got = shear_planes_deg(&p, phi);
            assert!((got[0] - planes[0]).abs() < 1e-9 && (got[1] - planes[1]).abs() < 1e-9, "{s:?}: {got:?}");
            if sh.failed() {
                assert_eq!(sh.n_planes, 2);
                assert!((deg(sh.planes[0]) - planes[0]).abs() < 1e-9 && (deg(sh.planes[1]) - planes[1]).abs() < 1e-9);
            }
        }
    }

    fn shear_planes_deg(p: &Principal, phi: f64) -> [f64; 2] {
        let q = super::super::shear_planes(p.theta1, phi);
        [deg(q[0]), deg(q[1])]
    }

    /// UCS = 2 c cos(phi) / (1 - sin(phi)) = 0.34641 lies exactly on the shear envelope:
    /// f_s = 1 to 1e-12; it fails at UCS (1 + 1e-9) and holds at UCS (1 - 1e-9).
    #[test]
    fn ucs_on_envelope() {
        let phi = 30f64.to_radians();
        let ucs = 2.0 * 0.1 * phi.cos() / (1.0 - phi.sin());
        assert!((ucs - 0.34641).abs() < 1e-5);
        let p = |q: f64| principal([-q, 0.0, 0.0], 0.0);
        assert!((f_s(&p(ucs), 0.1, phi).unwrap() - 1.0).abs() < 1e-12);
        let mc = paper();
        assert!(mc.check(&p(ucs * (1.0 + 1e-9)), 1.0).failed());
        assert!(!mc.check(&p(ucs * (1.0 - 1e-9)), 1.0).failed());
        assert!((mc.check(&p(ucs), 1.0).index - 1.0).abs() < 1e-12);
        // scale doubles the strengths: UCS doubles
        assert!(!mc.check(&p(1.9 * ucs), 2.0).failed());
        assert!(mc.check(&p(2.1 * ucs), 2.0).failed());
    }

    /// Mode choice and indices (hand values, tolerance 1e-12): in uniaxial tension 1.2 with
    /// both branches on, shear wins (index clamped 1e6, beyond the apex); the tension index is
    /// -s3/sigma_t; hydrostatic states follow the no-division rule.
    #[test]
    fn modes_indices_and_apex() {
        let p = principal([1.2, 0.0, 0.0], 0.0);
        let both = paper().check(&p, 1.0);
        assert_eq!(both.mode, Some(FailureMode::Shear));
        assert_eq!(both.index, 1e6);
        let t = MohrCoulomb { shear: false, ..paper() }.check(&p, 1.0);
        assert_eq!(t.mode, Some(FailureMode::Tension));
        assert_eq!(t.n_planes, 1);
        assert!((t.index - 1.2).abs() < 1e-12 && (deg(t.planes[0]) - 90.0).abs() < 1e-9);
        // hydrostatic compression holds (index 0), hydrostatic tension beyond the apex fails
        let hc = paper().check(&principal([-1.0, -1.0, 0.0], 0.0), 1.0);
        assert!(!hc.failed() && hc.index == 0.0);
        let ht = MohrCoulomb { tension: false, ..paper() }.check(&principal([0.2, 0.2, 0.0], 0.0), 1.0);
        assert_eq!(ht.mode, Some(FailureMode::Shear));
        assert!((deg(ht.planes[0]) - 30.0).abs() < 1e-9 && (deg(ht.planes[1]) - 150.0).abs() < 1e-9);
        let inside = paper().check(&principal([0.1, 0.1, 0.0], 0.0), 1.0);
        assert!(!inside.failed());
    }

    /// Non-finite input never panics and never fails; index stays in [0, 1e6].
    #[test]
    fn nan_and_extreme_inputs() {
        let mc = paper();
        let nan = Principal { s1: f64::NAN, s3: f64::NAN, s2: 0.0, theta1: f64::NAN };
        let r = mc.check(&nan, 1.0);
        assert!(!r.failed() && r.index == 0.0);
        for s in [[1e300, -1e300, 1e300], [-1e308, 1e308, 0.0], [0.0, 0.0, 0.0]] {
            let r = mc.check(&principal(s, 0.0), 1.0);
            assert!(r.index.is_finite() && (0.0..=1e6).contains(&r.index));
        }
    }

    /// Bad input names the key: an out-of-range value and an unknown key (exact messages).
    #[test]
    fn bad_input_names_the_key() {
        let bad = MohrCoulomb { friction_angle_deg: 95.0, ..paper() };
        assert_eq!(bad.validate().unwrap_err().to_string(), "friction_angle_deg = 95 is incorrect; it must be in [0, 90)");
        let bad = MohrCoulomb { tensile_strength: 0.0, ..paper() };
        assert_eq!(bad.validate().unwrap_err().to_string(), "tensile_strength = 0 is incorrect; it must be in (0, inf)");
        let bad = MohrCoulomb { cohesion: -1.0, ..paper() };
        assert!(bad.validate().unwrap_err().to_string().starts_with("cohesion = -1 is incorrect"));
        let off = MohrCoulomb { tension: false, shear: false, ..paper() };
        assert!(off.validate().unwrap_err().to_string().starts_with("shear = false"));
        let src = "type = \"mohr_coulomb\"\ncohesion = 0.1\nfriction_angle_deg = 30\ntensile_strength = 1\ncohesoin = 2\n";
        let err = toml::from_str::<Box<dyn FailureCriterion>>(src).unwrap_err().to_string();
        assert!(err.contains("unknown field `cohesoin`"), "{err}");
        let src = "type = \"mohr_coulomb\"\ncohesion = 0.1\ntensile_strength = 1\n";
        let err = toml::from_str::<Box<dyn FailureCriterion>>(src).unwrap_err().to_string();
        assert!(err.contains("missing field `friction_angle_deg`"), "{err}");
    }
}
