//! `cohesive`: linear-softening cohesion on freshly split faces, then pure contact
//! (METHOD section 6; our extension of the paper's no-tension law, eq. 10-14).
//!
//! A pair joining the two faces of an edge split during the run (`fresh`) carries tension:
//! with opening `delta = gap > 0`, `delta_0 = sigma_t / k_n` and
//! `delta_f = 2 G_f / sigma_t` (needs `delta_f > delta_0`),
//!
//! ```text
//! T(delta) = k_n delta                                         delta <= delta_0
//!          = sigma_t (delta_f - delta) / (delta_f - delta_0)   delta_0 < delta < delta_f
//!          = 0                                                 delta >= delta_f
//! ```
//!
//! Unloading goes back to the origin along the secant `T(delta_max) / delta_max`; the area
//! under the envelope up to `delta_f` is `G_f`. The tangential spring
//! (`e_s += -k_s A dslip`) is capped by `mu N + sigma_t A (1 - delta_max / delta_f)`.
//! Once `delta_max >= delta_f` (or for faces that were never cohesive) the pair is pure
//! contact: normal `k_n A max(-gap, 0)` (total gap), Coulomb `|e_s| <= mu N`.
//!
//! Energy: stored `1/2 T delta A` in tension, `1/2 k_n A gap^2` in compression, plus
//! `e_s^2 / (2 k_s A)`; dissipated: the fracture energy released as `delta_max` grows,
//! `A (W(delta_max) - 1/2 T(delta_max) delta_max)` with `W` the area under the envelope,
//! and the Coulomb slip.
//!
//! Units: stiffnesses stress/length, `tensile_strength` stress, `fracture_energy`
//! energy/area, `friction` dimensionless.
//!
//! ```toml
//! [contact]
//! law = { type = "cohesive", normal_stiffness = 1e6, shear_stiffness = 4e5, tensile_strength = 1.0, fracture_energy = 0.01, friction = 0.577 }
//! ```
use flem_core::contact::{ContactLaw, PairForce, PairKinematics, PairState};
use flem_core::traits::ParamError;
use serde::{Deserialize, Serialize};

use super::coulomb_cap;

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Cohesive {
    pub normal_stiffness: f64,
    pub shear_stiffness: f64,
    pub tensile_strength: f64,
    pub fracture_energy: f64,
    #[serde(default)]
    pub friction: f64,
}

impl Cohesive {
    fn d0(&self) -> f64 {
        self.tensile_strength / self.normal_stiffness
    }
    fn df(&self) -> f64 {
        2.0 * self.fracture_energy / self.tensile_strength
    }
    /// Envelope traction at opening `d`.
    pub fn envelope(&self, d: f64) -> f64 {
        let (d0, df) = (self.d0(), self.df());
        if d <= d0 {
            self.normal_stiffness * d
        } else if d < df {
            self.tensile_strength * (df - d) / (df - d0)
        } else {
            0.0
        }
    }
    /// Area under the envelope from 0 to `d`.
    fn work(&self, d: f64) -> f64 {
        let (d0, df) = (self.d0(), self.df());
        if d <= d0 {
            0.5 * self.normal_stiffness * d * d
        } else {
            let e = d.min(df);
            0.5 * self.tensile_strength * d0 + 0.5 * (self.tensile_strength + self.envelope(e)) * (e - d0)
        }
    }
    /// Energy released (per area) once the opening has reached `d`.
    fn released(&self, d: f64) -> f64 {
        if d <= 0.0 {
            0.0
        } else {
            self.work(d) - 0.5 * self.envelope(d) * d
        }
    }
}

#[typetag::serde(name = "cohesive")]
impl ContactLaw for Cohesive {
    fn validate(&self) -> Result<(), ParamError> {
        ParamError::range("normal_stiffness", self.normal_stiffness, 0.0, false, f64::INFINITY, false)?;
        ParamError::range("shear_stiffness", self.shear_stiffness, 0.0, false, f64::INFINITY, false)?;
        ParamError::range("tensile_strength", self.tensile_strength, 0.0, false, f64::INFINITY, false)?;
        ParamError::range("fracture_energy", self.fracture_energy, 0.0, false, f64::INFINITY, false)?;
        ParamError::range("friction", self.friction, 0.0, true, f64::INFINITY, false)?;
        if self.df() <= self.d0() {
            return Err(ParamError::new(
                "fracture_energy",
                format!("= {} is incorrect; it must be > tensile_strength^2 / (2 normal_stiffness) = {} (otherwise the softening branch would snap back)", self.fracture_energy, self.tensile_strength.powi(2) / (2.0 * self.normal_stiffness)),
            ));
        }
        Ok(())
    }
    fn stiffness(&self) -> f64 {
        self.normal_stiffness.max(self.shear_stiffness)
    }
    fn evaluate(&self, kin: &[PairKinematics], hist: &mut [PairState], out: &mut [PairForce]) {
        let df = self.df();
        for ((k, h), o) in kin.iter().zip(hist.iter_mut()).zip(out.iter_mut()) {
            let (kn, ks) = (self.normal_stiffness * k.area, self.shear_stiffness * k.area);
            let cohesive = h.fresh && h.max_open < df;
            if k.gap >= 0.0 && !cohesive {
                *o = PairForce::default();
                continue;
            }
            let mut diss = 0.0;
            let (normal, stored_n, cap_extra) = if k.gap > 0.0 {
                let old = h.max_open;
                h.max_open = h.max_open.max(k.gap);
                diss += k.area * (self.released(h.max_open) - self.released(old));
                let t = if k.gap >= h.max_open { self.envelope(k.gap) } else { self.envelope(h.max_open) / h.max_open * k.gap };
                (-t * k.area, 0.5 * t * k.gap * k.area, self.tensile_strength * k.area * (1.0 - h.max_open / df).max(0.0))
            } else {
                let n = -kn * k.gap;
                let extra = if cohesive { self.tensile_strength * k.area * (1.0 - h.max_open / df) } else { 0.0 };
                (n, 0.5 * n * n / kn, extra)
            };
            h.en = normal;
            if k.new {
                h.es = 0.0;
            } else {
                h.es -= ks * k.dslip;
            }
            let trial = h.es;
            let (es, slipped) = coulomb_cap(trial, self.friction * normal.max(0.0) + cap_extra);
            h.es = es;
            if slipped {
                diss += (trial - es).abs() / ks * es.abs();
            }
            let active = k.gap < 0.0 || (h.fresh && h.max_open < df);
            *o = PairForce { normal, tangential: es, active, stored: stored_n + 0.5 * es * es / ks, dissipated: diss };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn law() -> Cohesive {
        Cohesive { normal_stiffness: 1000.0, shear_stiffness: 1000.0, tensile_strength: 1.0, fracture_energy: 0.01, friction: 0.5 }
    }

    /// Opening a fresh pair monotonically: the traction follows the bilinear envelope (peak
    /// sigma_t at delta_0), the dissipated energy totals G_f x area when the pair fails, and
    /// it then no longer carries tension. Reference: the closed-form envelope; 1e-9 and 1 %.
    #[test]
    fn monotonic_opening_releases_the_fracture_energy() {
        let l = law();
        let area = 2.0;
        let mut h = [PairState { fresh: true, ..Default::default() }];
        let mut o = [PairForce::default()];
        let mut diss = 0.0;
        let n = 20000;
        let df = 2.0 * 0.01 / 1.0;
        let mut peak: f64 = 0.0;
        for i in 1..=n {
            let gap = 1.1 * df * i as f64 / n as f64;
            l.evaluate(&[PairKinematics { gap, area, dt: 1.0, ..Default::default() }], &mut h, &mut o);
            diss += o[0].dissipated;
            peak = peak.max(-o[0].normal);
            if gap < df {
                assert!(o[0].active);
                assert!((-o[0].normal - area * l.envelope(gap)).abs() < 1e-9);
            }
        }
        assert!(!o[0].active);
        assert!((peak - area * 1.0).abs() < 1e-2 * area, "peak {peak}");
        assert!((diss - 0.01 * area).abs() < 0.01 * 0.01 * area, "dissipated {diss}");
    }

    /// A pair that is not fresh never pulls; compression is a total-gap penalty.
    /// Reference: the law; exact.
    #[test]
    fn old_faces_are_pure_contact() {
        let l = law();
        let mut h = [PairState::default()];
        let mut o = [PairForce::default()];
        l.evaluate(&[PairKinematics { gap: 1e-4, area: 1.0, dt: 1.0, ..Default::default() }], &mut h, &mut o);
        assert!(!o[0].active);
        l.evaluate(&[PairKinematics { gap: -1e-3, area: 1.0, dt: 1.0, new: true, ..Default::default() }], &mut h, &mut o);
        assert!((o[0].normal - 1.0).abs() < 1e-12);
    }

    /// fracture_energy below sigma_t^2 / (2 k_n) is refused with the key and the bound.
    #[test]
    fn snap_back_is_refused() {
        let l = Cohesive { fracture_energy: 1e-4, ..law() };
        let e = l.validate().unwrap_err();
        assert_eq!(e.key, "fracture_energy");
    }
}
