//! Strain softening (or hardening) of `mohr_coulomb`: FLAC's strain-softening model (Itasca,
//! "Constitutive Models", the strain-softening/hardening Mohr-Coulomb model): cohesion,
//! friction and dilation angles are piecewise-linear functions of a hardening parameter, the
//! plastic shear strain `e_ps`, given as tables in the law's `softening` key. Yield planes,
//! potentials, tension cut-off and the return are those of `mohr_coulomb` (the parent module)
//! with `c`, `phi`, `psi` taken at the point's current `e_ps`.
//!
//! The hardening parameter (FLAC's shear hardening increment) from the principal plastic
//! strain increments of the shear planes `de_i` (the tension planes do not count):
//!
//! `d e_ps = sqrt( 1/2 sum_i (de_i - de_m)^2 )`,  `de_m = (de_1 + de_2 + de_3) / 3`.
//!
//! On the face of the yield surface `de_2 = 0` and this is FLAC's formula exactly,
//! `d e_ps = (1/sqrt 2) sqrt((de_1 - de_m)^2 + de_m^2 + (de_3 - de_m)^2)`, `de_m = (de_1 +
//! de_3) / 3`; at the edges (two shear planes active) it counts the middle flow too. For
//! `psi = 0` on the face, `de_1 = -de_3 = dl` and `d e_ps = dl`: half the engineering plastic
//! shear strain `de_1 - de_3` that the VTU's `plastic_shear_strain` accumulates.
//!
//! The tables are linear between their entries and constant beyond the last (FLAC's). Our
//! update is implicit in `e_ps` (FLAC's is explicit: it takes the properties of the step's
//! start): the return is made on the surface of `e_ps_{n+1} = e_ps_n + d e_ps(return at
//! e_ps_{n+1})`, a scalar equation solved by a bracketed secant (Illinois) iteration to a
//! relative 1e-14; so after every update the stress lies on the surface of the point's stored
//! parameter. The tension cut-off stays constant, capped at the current apex `c cot(phi)`
//! (default: the apex). History per point: `[plastic shear strain (as mohr_coulomb), state,
//! e_ps]`.
//!
//! ```toml
//! [[material]]
//! young_modulus = 1.0e5    # kPa
//! poisson_ratio = 0.3
//! density = 2.0
//! law = { type = "mohr_coulomb", cohesion = 10.0, friction_angle_deg = 35.0, dilation_angle_deg = 5.0, softening = { eps_ps = [0.0, 0.01, 0.05], cohesion = [10.0, 5.0, 1.0], friction_angle_deg = [35.0, 32.0, 30.0], dilation_angle_deg = [5.0, 2.0, 0.0] } }
//! ```
use serde::{Deserialize, Serialize};

use super::{MohrCoulomb, MohrCoulombCfg};
use flem_core::element::law::MaterialLaw;
use flem_core::element::{Dmat, Material};

/// `softening = { eps_ps = [...], cohesion = [...], friction_angle_deg = [...],
/// dilation_angle_deg = [...] }`: tables against the plastic shear strain `eps_ps` (starting
/// at 0, increasing). A table left out keeps the law's constant value; a given one starts at
/// the law's value (the strength at zero plastic strain).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SofteningCfg {
    pub eps_ps: Vec<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cohesion: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_angle_deg: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dilation_angle_deg: Option<Vec<f64>>,
}

fn err(key: String, msg: String) -> Result<(), (String, String)> {
    Err((key, msg))
}

impl SofteningCfg {
    /// The three tables, a constant one where the config gives none.
    fn tables(&self, law: &MohrCoulombCfg) -> [Vec<f64>; 3] {
        let n = self.eps_ps.len();
        let t = |v: &Option<Vec<f64>>, c: f64| v.clone().unwrap_or_else(|| vec![c; n]);
        [t(&self.cohesion, law.cohesion), t(&self.friction_angle_deg, law.friction_angle_deg), t(&self.dilation_angle_deg, law.dilation_angle_deg)]
    }

    /// Keys relative to `law`: `softening.eps_ps[1]`, `softening.cohesion`, ...
    pub fn validate(&self, law: &MohrCoulombCfg) -> Result<(), (String, String)> {
        let e = &self.eps_ps;
        if e.is_empty() {
            return err("softening.eps_ps".into(), "is empty; give the plastic shear strains of the table, starting at 0".into());
        }
        if e[0] != 0.0 {
            return err("softening.eps_ps[0]".into(), format!("= {} is incorrect; the table starts at plastic shear strain 0", e[0]));
        }
        for i in 1..e.len() {
            if !(e[i].is_finite() && e[i] > e[i - 1]) {
                return err(format!("softening.eps_ps[{i}]"), format!("= {} is incorrect; the strains must be finite and strictly increasing (after {})", e[i], e[i - 1]));
            }
        }
        let named = [
            ("cohesion", &self.cohesion, law.cohesion),
            ("friction_angle_deg", &self.friction_angle_deg, law.friction_angle_deg),
            ("dilation_angle_deg", &self.dilation_angle_deg, law.dilation_angle_deg),
        ];
        for (k, t, at0) in named {
            let Some(t) = t else { continue };
            if t.len() != e.len() {
                return err(format!("softening.{k}"), format!("has {} entries; it needs one per entry of softening.eps_ps ({})", t.len(), e.len()));
            }
            if t[0] != at0 {
                return err(format!("softening.{k}[0]"), format!("= {} differs from the law's {k} = {at0}; the table's first entry is the value at zero plastic strain", t[0]));
            }
            for (i, &v) in t.iter().enumerate() {
                if !(v.is_finite() && v >= 0.0) {
                    return err(format!("softening.{k}[{i}]"), format!("= {v} is incorrect; it must be finite and >= 0"));
                }
            }
        }
        let [c, phi, psi] = self.tables(law);
        for i in 0..e.len() {
            if phi[i] >= 90.0 {
                return err(format!("softening.friction_angle_deg[{i}]"), format!("= {} is incorrect; it must be in [0, 90)", phi[i]));
            }
            if psi[i] > phi[i] {
                let k = if self.dilation_angle_deg.is_some() { format!("softening.dilation_angle_deg[{i}]") } else { "dilation_angle_deg".into() };
                return err(k, format!("= {} exceeds the friction angle {} at eps_ps = {}; the dilation angle must be in [0, phi]", psi[i], phi[i], e[i]));
            }
            if c[i] == 0.0 && phi[i] == 0.0 {
                return err(format!("softening.cohesion[{i}]"), format!("= 0 with a friction angle 0 at eps_ps = {} gives no strength at all", e[i]));
            }
        }
        Ok(())
    }

    /// Strength reduction: every entry `c / f`, `tan(phi) / f`, `psi` capped at the reduced
    /// `phi`. `psi0` is the law's constant dilation angle (used when there is no psi table),
    /// `phi0` its reduced constant friction angle (caps a psi table without a phi one).
    pub fn reduced(&self, f: f64, psi0: f64, phi0: f64) -> SofteningCfg {
        let phi: Option<Vec<f64>> = self.friction_angle_deg.as_ref().map(|t| t.iter().map(|p| (p.to_radians().tan() / f).atan().to_degrees()).collect());
        let psi = match (&self.dilation_angle_deg, &phi) {
            (Some(t), Some(p)) => Some(t.iter().zip(p).map(|(a, b)| a.min(*b)).collect()),
            (None, Some(p)) => Some(p.iter().map(|b| psi0.min(*b)).collect()),
            (Some(t), None) => Some(t.iter().map(|a| a.min(phi0)).collect()),
            (None, None) => None,
        };
        SofteningCfg { eps_ps: self.eps_ps.clone(), cohesion: self.cohesion.as_ref().map(|t| t.iter().map(|c| c / f).collect()), friction_angle_deg: phi, dilation_angle_deg: psi }
    }
}

/// The law: `mohr_coulomb` with its strength at the point's plastic shear strain.
#[derive(Clone, Debug)]
pub struct MohrCoulombSoftening {
    /// The law at `e_ps = 0` (its elastic constants serve every update).
    pub base: MohrCoulomb,
    mat: Material,
    eps: Vec<f64>,
    c: Vec<f64>,
    /// Angles in radians.
    phi: Vec<f64>,
    psi: Vec<f64>,
    /// The configured cut-off (infinite: the apex).
    sigma_t: f64,
}

impl MohrCoulombSoftening {
    pub fn new(law: &MohrCoulombCfg, sc: &SofteningCfg, mat: &Material) -> Self {
        let [c, phi, psi] = sc.tables(law);
        let rad = |v: Vec<f64>| v.into_iter().map(f64::to_radians).collect::<Vec<_>>();
        // A reduced psi table may exceed a reduced constant phi: cap it entrywise.
        let (phi, psi) = (rad(phi), rad(psi));
        let psi = psi.iter().zip(&phi).map(|(a, b)| a.min(*b)).collect();
        MohrCoulombSoftening { base: law.law(mat), mat: *mat, eps: sc.eps_ps.clone(), c, phi, psi, sigma_t: law.tension_cutoff.unwrap_or(f64::INFINITY) }
    }

    /// `(c, phi, psi)` at plastic shear strain `k` (linear between entries, constant beyond).
    pub fn params(&self, k: f64) -> (f64, f64, f64) {
        let e = &self.eps;
        let n = e.len();
        if k <= e[0] || n == 1 {
            return (self.c[0], self.phi[0], self.psi[0]);
        }
        if k >= e[n - 1] {
            return (self.c[n - 1], self.phi[n - 1], self.psi[n - 1]);
        }
        let i = e.partition_point(|&x| x <= k) - 1;
        let t = (k - e[i]) / (e[i + 1] - e[i]);
        let lin = |v: &[f64]| v[i] + t * (v[i + 1] - v[i]);
        (lin(&self.c), lin(&self.phi), lin(&self.psi))
    }

    /// The perfectly plastic law with the strength at plastic shear strain `k`.
    pub fn at(&self, k: f64) -> MohrCoulomb {
        let (c, phi, psi) = self.params(k);
        let apex = if phi > 0.0 { c / phi.tan() } else { f64::INFINITY };
        MohrCoulomb::new(&self.mat, c, phi, psi, self.sigma_t.min(apex))
    }

    /// The last strain of the tables: beyond it the parameters are constant.
    fn last(&self) -> f64 {
        self.eps[self.eps.len() - 1]
    }
}

/// FLAC's shear hardening increment of principal plastic strain increments (module docs).
pub fn hardening_increment(de: [f64; 3]) -> f64 {
    let m = (de[0] + de[1] + de[2]) / 3.0;
    (0.5 * ((de[0] - m).powi(2) + (de[1] - m).powi(2) + (de[2] - m).powi(2))).sqrt()
}

impl MohrCoulombSoftening {
    /// The return of sorted principal trial stresses `s` from a point at plastic shear strain
    /// `k0`: `(stress, plastic strain increment, new e_ps)`, `None` when elastic at `k0`.
    pub fn return_softening(&self, s: [f64; 3], k0: f64) -> Option<([f64; 3], [f64; 3], f64)> {
        let eval = |k: f64| self.at(k).return_parts(s);
        let (r0, d0, sh0) = eval(k0)?;
        let dk0 = hardening_increment(sh0);
        if dk0 == 0.0 || (k0 >= self.last() && self.eps.len() > 1) || self.eps.len() == 1 {
            return Some((r0, d0, k0 + dk0));
        }
        // g(k) = k0 + dk(k) - k: g(k0) = dk0 > 0; find a k with g <= 0 (doubling), then the root.
        let g = |k: f64| -> (f64, Option<([f64; 3], [f64; 3], f64)>) {
            match eval(k) {
                Some((r, d, sh)) => {
                    let dk = hardening_increment(sh);
                    (k0 + dk - k, Some((r, d, k0 + dk)))
                }
                None => (k0 - k, None),
            }
        };
        let (mut lo, mut glo) = (k0, dk0);
        let mut step = dk0;
        let (mut hi, mut ghi, mut out_hi);
        let mut tries = 0;
        loop {
            hi = k0 + step;
            let (gh, o) = g(hi);
            (ghi, out_hi) = (gh, o);
            if ghi <= 0.0 || tries > 80 {
                break;
            }
            (lo, glo) = (hi, ghi);
            step *= 2.0;
            tries += 1;
        }
        let tol = 1e-14 * hi.abs().max(1e-300);
        let mut best = (hi, ghi, out_hi);
        let mut side = 0i8;
        for _ in 0..200 {
            if best.1.abs() <= tol || (hi - lo) <= tol {
                break;
            }
            // Illinois regula falsi on the bracket [lo, hi] (glo > 0 >= ghi).
            let mut k = hi - ghi * (hi - lo) / (ghi - glo);
            if !(k > lo && k < hi) {
                k = 0.5 * (lo + hi);
            }
            let (gk, o) = g(k);
            if gk.abs() < best.1.abs() {
                best = (k, gk, o);
            }
            if gk > 0.0 {
                (lo, glo) = (k, gk);
                if side == 1 {
                    ghi *= 0.5;
                }
                side = 1;
            } else {
                (hi, ghi) = (k, gk);
                if side == -1 {
                    glo *= 0.5;
                }
                side = -1;
            }
        }
        match best.2 {
            Some(o) => Some(o),
            // The root sits where the trial just touches the surface: no plastic strain.
            None => Some((s, [0.0; 3], k0)),
        }
    }
}

impl MaterialLaw for MohrCoulombSoftening {
    const STATE: usize = 3;
    fn elastic(&self) -> Dmat {
        self.base.d
    }
    /// As `MohrCoulomb::update` (trial, principal stresses, sort, return, back to x-y), with
    /// the return of [`Self::return_softening`] at the point's `e_ps = state[2]`.
    fn update(&self, st: &mut [f64; 4], de: [f64; 4], state: &mut [f64]) {
        let b = &self.base;
        let (l, g2) = (b.lambda, 2.0 * b.g);
        let tr = de[0] + de[1] + de[3];
        let s = [st[0] + l * tr + g2 * de[0], st[1] + l * tr + g2 * de[1], st[2] + b.g * de[2], st[3] + l * tr + g2 * de[3]];
        let (mid, half) = (0.5 * (s[0] + s[1]), 0.5 * (s[0] - s[1]));
        let rad = (half * half + s[2] * s[2]).sqrt();
        let (pa, pb, pz) = (mid + rad, mid - rad, s[3]);
        let (sorted, pos) = super::sort_principal(pa, pb, pz);
        match self.return_softening(sorted, state[2]) {
            None => {
                *st = s;
                if state[1] == 1.0 {
                    state[1] = 2.0;
                }
            }
            Some((r, dep, k)) => {
                let (na, nb, nz) = (r[pos[0]], r[pos[1]], r[pos[2]]);
                let (c2, s2) = crate::material::mohr_coulomb::rotation(half, s[2], rad);
                let (m, h) = (0.5 * (na + nb), 0.5 * (na - nb));
                *st = [m + h * c2, m - h * c2, h * s2, nz];
                let (mx, mn) = (dep[0].max(dep[1]).max(dep[2]), dep[0].min(dep[1]).min(dep[2]));
                state[0] += mx - mn;
                state[2] = k;
                state[1] = 1.0;
            }
        }
    }
    fn output(&self, state: &[f64]) -> (f64, u8) {
        (state[0], state[1] as u8)
    }
}

#[cfg(test)]
#[path = "mohr_coulomb_softening_tests.rs"]
mod tests;
