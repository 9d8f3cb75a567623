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
//! plus, when slipping (spring trial `e_s* = e_s,old - k_s A dslip` capped to `e_s`), the
//! tangential work over the step as the ledger credits it (trapezoid, `1/2 (e_s,old + e_s)
//! dslip`) less the change of stored energy: `(e_s,old + e_s)(e_s* - e_s) / (2 k_s A)`, exact
//! without dashpots (unit test `work_of_the_forces_equals_stored_plus_dissipated`). Session 5;
//! the former `|e_s* - e_s| |e_s| / (k_s A)` (a rectangle) missed the work done while the cap
//! moved with the normal force: the direct shear residual fell from 1.3e-3 to 1.6e-4.
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
use flem_core::contact::contact3::{PairForce3, PairKinematics3, PairState3};
use flem_core::contact::{ContactLaw, PairForce, PairKinematics, PairState};
use flem_core::plugin::traits::ParamError;
use serde::{Deserialize, Serialize};

use super::{coulomb_cap, slip_dissipation};

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
            let es_old = if k.new { 0.0 } else { h.es };
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
                diss += slip_dissipation(es_old, h.es, capped, ks);
                h.es = capped;
                ds = 0.0;
            }
            diss += -((normal - h.en) * k.vn + ds * k.vs) * k.dt;
            *o = PairForce { normal, tangential: h.es + ds, active: true, stored: 0.5 * h.en * h.en / kn + 0.5 * h.es * h.es / ks, dissipated: diss, fracture: 0.0 };
        }
    }
    /// The 3D form (issue 38, docs/3d.md "Contact (3D)"): eqs. 10-14 with the shear spring
    /// `e_s` a vector in the face's plane, `e_s -= k_s A dslip` (vector), the Coulomb cap on
    /// its length `|e_s + d_s| <= mu (e_n + d_n)` (eq. 13: the trial scaled back along
    /// itself), slip dissipation `(e_s,old + e_s) . (e_s* - e_s) / (2 k_s A)` (the 1D
    /// trapezoid rule with dot products). In 1D-like motion (slip along one direction) it is
    /// the 2D law exactly.
    fn evaluate_3d(&self, kin: &[PairKinematics3], hist: &mut [PairState3], out: &mut [PairForce3]) -> Result<(), String> {
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        for ((k, h), o) in kin.iter().zip(hist.iter_mut()).zip(out.iter_mut()) {
            let (kn, ks) = (self.normal_stiffness * k.area, self.shear_stiffness * k.area);
            let es_old = if k.new { [0.0; 3] } else { h.es };
            if k.new {
                h.en = kn * (-k.gap).max(0.0);
                h.es = [0.0; 3];
            } else {
                h.en -= kn * k.dgap;
                for d in 0..3 {
                    h.es[d] -= ks * k.dslip[d];
                }
            }
            if h.en <= 0.0 {
                *o = PairForce3::default();
                continue;
            }
            let dn = -self.normal_damping * k.area * k.vn;
            let mut ds = k.vs.map(|v| -self.shear_damping * k.area * v);
            let normal = (h.en + dn).max(0.0);
            let trial: [f64; 3] = std::array::from_fn(|d| h.es[d] + ds[d]);
            let (lt, lim) = (dot(trial, trial).sqrt(), self.friction * normal);
            let mut diss = 0.0;
            if lt > lim {
                let capped = trial.map(|t| t * lim.max(0.0) / lt);
                let sum: [f64; 3] = std::array::from_fn(|d| es_old[d] + capped[d]);
                let dif: [f64; 3] = std::array::from_fn(|d| h.es[d] - capped[d]);
                diss += 0.5 * dot(sum, dif) / ks;
                h.es = capped;
                ds = [0.0; 3];
            }
            diss += -((normal - h.en) * k.vn + dot(ds, k.vs)) * k.dt;
            let tangential: [f64; 3] = std::array::from_fn(|d| h.es[d] + ds[d]);
            *o = PairForce3 { normal, tangential, active: true, stored: 0.5 * h.en * h.en / kn + 0.5 * dot(h.es, h.es) / ks, dissipated: diss };
        }
        Ok(())
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

    /// The 3D form on a slip along a fixed direction equals the 2D law on the same path, and a
    /// slip that turns keeps the cap on the length of the shear force. Reference: the 2D law
    /// (eqs. 10-14) and Coulomb's law |e_s| <= mu e_n; 1e-12.
    #[test]
    fn three_d_form_matches_the_2d_law_and_caps_the_length() {
        let l = law();
        let dir = [0.6, 0.0, 0.8];
        let (mut h2, mut h3) = ([PairState::default()], [PairState3::default()]);
        let (mut o2, mut o3) = ([PairForce::default()], [PairForce3::default()]);
        for i in 0..40 {
            let t = i as f64;
            let (g, ds) = (-0.01 - 0.004 * (t * 0.3).sin(), 0.004 * (t * 0.2).cos());
            let dg = if i == 0 { 0.0 } else { -0.004 * ((t * 0.3).sin() - ((t - 1.0) * 0.3).sin()) };
            let k2 = PairKinematics { gap: g, dgap: dg, dslip: ds, area: 2.0, dt: 1.0, new: i == 0, ..Default::default() };
            let k3 = PairKinematics3 { gap: g, dgap: dg, dslip: dir.map(|c| c * ds), area: 2.0, dt: 1.0, new: i == 0, ..Default::default() };
            l.evaluate(&[k2], &mut h2, &mut o2);
            l.evaluate_3d(&[k3], &mut h3, &mut o3).unwrap();
            assert!((o2[0].normal - o3[0].normal).abs() < 1e-12);
            for d in 0..3 {
                assert!((o2[0].tangential * dir[d] - o3[0].tangential[d]).abs() < 1e-12, "step {i}");
            }
            assert!((o2[0].stored - o3[0].stored).abs() < 1e-12 && (o2[0].dissipated - o3[0].dissipated).abs() < 1e-12);
        }
        // A slip turning in the plane: the force's length stays at the cap mu e_n.
        let mut h = [PairState3 { en: 10.0, ..Default::default() }];
        let mut o = [PairForce3::default()];
        for i in 0..20 {
            let a = 0.3 * i as f64;
            l.evaluate_3d(&[PairKinematics3 { gap: -0.05, dslip: [a.cos(), a.sin(), 0.0], area: 1.0, dt: 1.0, ..Default::default() }], &mut h, &mut o).unwrap();
            let t = o[0].tangential;
            assert!(((t[0] * t[0] + t[1] * t[1]).sqrt() - 5.0).abs() < 1e-12 && o[0].dissipated > 0.0);
        }
    }

    /// Energy of the law against the ledger's quadrature, without dashpots: a pair held in
    /// compression (the normal force varying with the gap, so the Coulomb cap moves) slides
    /// back and forth, sticking and slipping. Reference: the work of the returned forces summed
    /// independently as the ledger sums it (trapezoid of force x increment, normal and
    /// tangential, on the slave) equals minus (stored + accumulated dissipated): `W + E + D = 0`
    /// to 1e-9 of the sum of |work increments|. The former rectangle slip dissipation
    /// (`|e_s* - e_s| |e_s| / k_s`) misses the work done while the cap falls and fails it.
    #[test]
    fn work_of_the_forces_equals_stored_plus_dissipated() {
        let l = law();
        let area = 2.0;
        let mut h = [PairState::default()];
        let mut o = [PairForce::default()];
        let (mut g0, mut s0, mut f0) = (-0.01, 0.0, [0.0; 2]);
        let (mut w, mut w_abs, mut d, mut e, mut slipping) = (0.0, 0.0, 0.0, 0.0, 0);
        for i in 0..=600 {
            let t = i as f64;
            let (g, s) = (-0.01 - 0.006 * (t * 0.05).sin(), 0.03 * (t * 0.021).sin());
            let k = PairKinematics { gap: g, dgap: g - g0, dslip: s - s0, area, dt: 1.0, new: i == 0, ..Default::default() };
            l.evaluate(&[k], &mut h, &mut o);
            assert!(o[0].active);
            let f = [o[0].normal, o[0].tangential];
            if i > 0 {
                let dw = 0.5 * (f0[0] + f[0]) * (g - g0) + 0.5 * (f0[1] + f[1]) * (s - s0);
                (w, w_abs) = (w + dw, w_abs + dw.abs());
            } else {
                // the pair is born at the overlap: its spring energy is the scene's (no work)
                w -= o[0].stored;
            }
            (d, e, f0, g0, s0) = (d + o[0].dissipated, o[0].stored, f, g, s);
            slipping += (o[0].tangential.abs() >= 0.5 * o[0].normal - 1e-12) as usize;
        }
        assert!(slipping > 100 && slipping < 500, "the path must both stick and slip: {slipping} of 601 steps at the cap");
        assert!(d > 0.0 && (w + e + d).abs() < 1e-9 * w_abs, "W + E + D = {:.3e} of {w_abs:.3e} (D = {d:.3e})", w + e + d);
    }
}
