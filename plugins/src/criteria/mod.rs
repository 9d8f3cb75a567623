//! Failure criteria (METHOD section 4; the paper's section 2.2, eqs. (1)-(2)).
//!
//! What: each criterion takes the in-plane principal stresses of a cluster in the
//! geomechanics convention (**compression positive**, `s1 >= s3`, plus the out-of-plane `s2`
//! and the sigma1 direction `theta1`, see [`flem_core::plugin::traits::principal`]) and answers
//! failed or not, the mode (tension or shear), the failure-plane direction(s) and a failure
//! index (>= 1 failed, clamped to [0, 1e6]).
//!
//! Why several: the paper uses Mohr-Coulomb with a tension cut-off; Rankine, Drucker-Prager
//! and Hoek-Brown are the usual alternatives of rock and soil mechanics.
//!
//! How they are selected: `type = "name"` in the scene's `[cracking.criterion]` table (typetag).
//! Units: any consistent stress unit (the paper uses kgf/cm^2); angles in config are degrees
//! (`_deg`), radians inside. `scale` (strength scatter, see [`flem_core::cracking::weibull`]) multiplies every
//! strength of a criterion at a point.
//!
//! Shared conventions:
//! - Failure-plane directions are radians in [0, pi) from +x, in ascending order for shear.
//! - When `s1 == s3` the sigma1 direction is undefined; we use `theta1` as supplied, which
//!   [`flem_core::plugin::traits::principal`] sets to 0 (the +x axis) in that case.
//! - A NaN input never fails (all comparisons are false) and gives index 0.
pub mod drucker_prager;
pub mod hoek_brown;
pub mod mohr_coulomb;
pub mod rankine;

use std::f64::consts::PI;

use flem_core::plugin::traits::{FailureCheck, FailureMode};

/// The registered criterion names (typetag `type = "..."`), in documentation order.
pub const NAMES: &[&str] = &["mohr_coulomb", "rankine", "drucker_prager", "hoek_brown"];

/// The largest failure index reported (also used where the index would be infinite).
pub const INDEX_MAX: f64 = 1e6;

/// Clamps a failure index to [0, INDEX_MAX]; NaN gives 0.
pub(crate) fn clamp_index(x: f64) -> f64 {
    if x.is_nan() {
        0.0
    } else {
        x.clamp(0.0, INDEX_MAX)
    }
}

/// Wraps an angle to [0, pi) (guards the rounding case `rem_euclid` returning pi).
pub(crate) fn wrap_pi(a: f64) -> f64 {
    let r = a.rem_euclid(PI);
    if r >= PI {
        0.0
    } else {
        r
    }
}

/// `ratio / capacity` when the capacity is positive, else INDEX_MAX (beyond the apex).
pub(crate) fn ratio_index(demand: f64, capacity: f64) -> f64 {
    if capacity > 0.0 {
        demand / capacity
    } else if capacity.is_nan() || demand.is_nan() {
        0.0
    } else {
        INDEX_MAX
    }
}

/// A tension failure: one plane, the sigma1 direction (METHOD 4; paper fig. 3).
pub(crate) fn tension_check(index: f64, theta1: f64) -> FailureCheck {
    FailureCheck { index: clamp_index(index), mode: Some(FailureMode::Tension), planes: [wrap_pi(theta1), 0.0], n_planes: 1 }
}

/// A shear failure with planes at `theta1 +- (pi/4 - phi/2)` (mod pi, ascending; paper fig. 4).
pub(crate) fn shear_check(index: f64, theta1: f64, phi: f64) -> FailureCheck {
    FailureCheck { index: clamp_index(index), mode: Some(FailureMode::Shear), planes: shear_planes(theta1, phi), n_planes: 2 }
}

/// No failure: only the index.
pub(crate) fn holds(index: f64) -> FailureCheck {
    FailureCheck { index: clamp_index(index), mode: None, planes: [0.0, 0.0], n_planes: 0 }
}

/// The two Mohr-Coulomb failure planes `theta1 +- (pi/4 - phi/2)`, wrapped to [0, pi), ascending.
pub fn shear_planes(theta1: f64, phi: f64) -> [f64; 2] {
    let h = 0.25 * PI - 0.5 * phi;
    let (a, b) = (wrap_pi(theta1 - h), wrap_pi(theta1 + h));
    if a <= b {
        [a, b]
    } else {
        [b, a]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use flem_core::plugin::traits::FailureCriterion;

    const SOURCES: &[(&str, &str)] = &[
        ("mohr_coulomb.rs", include_str!("mohr_coulomb.rs")),
        ("rankine.rs", include_str!("rankine.rs")),
        ("drucker_prager.rs", include_str!("drucker_prager.rs")),
        ("hoek_brown.rs", include_str!("hoek_brown.rs")),
    ];

    /// Every ```toml block of every criterion's module doc parses as TOML, its
    /// `[cracking.criterion]` table deserializes into a `Box<dyn FailureCriterion>` and
    /// validates. Reference: the docs themselves; exact (no tolerance).
    #[test]
    fn doc_toml_snippets_parse_and_validate() {
        for (file, crit) in crate::snippets::doc_snippets::<Box<dyn FailureCriterion>>(SOURCES, &["cracking", "criterion"], NAMES) {
            crit.validate().unwrap_or_else(|e| panic!("{file}: {e}"));
        }
    }

    /// Wrapping and plane helpers. Reference: hand values; tolerance 1e-12.
    #[test]
    fn wrap_and_planes() {
        assert_eq!(wrap_pi(-1e-300), 0.0);
        assert!((wrap_pi(-0.5) - (PI - 0.5)).abs() < 1e-12);
        let p = shear_planes(0.0, 30f64.to_radians());
        assert!((p[0] - 30f64.to_radians()).abs() < 1e-12 && (p[1] - 150f64.to_radians()).abs() < 1e-12);
        assert_eq!(clamp_index(f64::NAN), 0.0);
        assert_eq!(clamp_index(f64::INFINITY), INDEX_MAX);
        assert_eq!(clamp_index(-3.0), 0.0);
    }
}
