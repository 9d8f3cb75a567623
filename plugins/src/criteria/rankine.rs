//! `rankine`: maximum tensile stress (Rankine), tension only (METHOD section 4; the tension
//! cut-off of the paper's eq. (1) on its own).
//!
//! Compression positive: fails when the most tensile principal stress reaches the tensile
//! strength, `s3 <= -sigma_t` (`sigma_t > 0`, stress units; `scale` multiplies it).
//! One failure plane, parallel to the sigma1 direction `theta1` (its normal is the sigma3
//! direction). Failure index `-s3 / sigma_t`, clamped to [0, 1e6]. The out-of-plane stress
//! is ignored (plane strain: it is never the most tensile one in a tension crack problem;
//! plane stress: it is 0).
//!
//! ```toml
//! [cracking.criterion]
//! type = "rankine"
//! tensile_strength = 1.0    # kgf/cm^2 (paper Table 1)
//! ```
use serde::{Deserialize, Serialize};

use flem_core::plugin::traits::{affine_crossing, FailureCheck, FailureCriterion, ParamError, Principal};

use super::{holds, tension_check};

/// Rankine tension criterion (see the module docs).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rankine {
    /// Tensile strength sigma_t (stress), > 0.
    pub tensile_strength: f64,
}

#[typetag::serde(name = "rankine")]
impl FailureCriterion for Rankine {
    fn validate(&self) -> Result<(), ParamError> {
        ParamError::range("tensile_strength", self.tensile_strength, 0.0, false, f64::INFINITY, false)
    }

    /// Failure and index use the principal values only; `theta1` gives the planes.
    fn isotropic(&self) -> bool {
        true
    }

    fn check(&self, p: &Principal, scale: f64) -> FailureCheck {
        let st = self.tensile_strength * scale;
        let index = -p.s3 / st;
        if p.s3 <= -st {
            tension_check(index, p.theta1)
        } else {
            holds(index)
        }
    }

    /// Closed form for the events solver: the most tensile principal stress `m + r` reaches
    /// `sigma_t` (`affine_crossing` with `k = 1`).
    /// Fails at `s3 <= -st`: the distance of `s3` from there (ours, issue 24).
    fn margin(&self, p: &Principal, scale: f64) -> Option<f64> {
        Some(self.tensile_strength * scale + p.s3)
    }
    fn affine_failure(&self, s0: [f64; 3], ds: [f64; 3], _szz0: f64, _dszz: f64, scale: f64, t0: f64, t1: f64) -> Option<f64> {
        Some(affine_crossing(s0, ds, 1.0, self.tensile_strength * scale, t0, t1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use flem_core::plugin::traits::{principal, FailureMode};

    /// Uniaxial tension along x (METHOD table rows 1-2): 1.2 fails, 0.8 holds, plane at 90 deg;
    /// index -s3/sigma_t. Reference: the definition; tolerance 1e-12.
    #[test]
    fn uniaxial_tension() {
        let r = Rankine { tensile_strength: 1.0 };
        let f = r.check(&principal([1.2, 0.0, 0.0], 0.0), 1.0);
        assert_eq!(f.mode, Some(FailureMode::Tension));
        assert_eq!(f.n_planes, 1);
        assert!((f.planes[0].to_degrees() - 90.0).abs() < 1e-9 && (f.index - 1.2).abs() < 1e-12);
        let h = r.check(&principal([0.8, 0.0, 0.0], 0.0), 1.0);
        assert!(!h.failed() && (h.index - 0.8).abs() < 1e-12);
        // exactly at the strength fails; compression never fails (index 0)
        assert!(r.check(&principal([1.0, 0.0, 0.0], 0.0), 1.0).failed());
        let c = r.check(&principal([-50.0, -10.0, 3.0], 0.0), 1.0);
        assert!(!c.failed() && c.index == 0.0);
        // scale multiplies the strength
        assert!(!r.check(&principal([1.2, 0.0, 0.0], 0.0), 1.5).failed());
    }

    /// The error names the key (exact message).
    #[test]
    fn bad_input_names_the_key() {
        let e = Rankine { tensile_strength: -1.0 }.validate().unwrap_err();
        assert_eq!(e.to_string(), "tensile_strength = -1 is incorrect; it must be in (0, inf)");
        let src = "type = \"rankine\"\ntensile_strength = 1\ncohesion = 0.1\n";
        let err = toml::from_str::<Box<dyn FailureCriterion>>(src).unwrap_err().to_string();
        assert!(err.contains("unknown field `cohesion`"), "{err}");
    }
}
