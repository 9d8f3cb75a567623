//! `example_mohr_coulomb` (material law): a copy of the built-in `mohr_coulomb`
//! (`plugins/src/material/mohr_coulomb.rs`) loaded at run time, a UMAT of FLEM: elastic-perfectly
//! plastic Mohr-Coulomb with non-associated flow and a tension cut-off, exact return mapping in
//! principal stresses (plane strain; de Souza Neto, Peric & Owen 2008, section 8.2.1; Clausen,
//! Damkilde & Andersen 2006). The same arithmetic in the same order as the built-in, so that
//! tests/dynkinds.rs compares the two bit for bit on the strip footing (docs/materials.md has
//! the equations and the verification of the built-in).
//!
//! Tension positive, principal stresses `s1 >= s2 >= s3` (with the out-of-plane `szz`);
//! shear planes `F_ij = (s_i - s_j) + (s_i + s_j) sin(phi) - 2 c cos(phi) <= 0`, flow along
//! `G_ij = (s_i - s_j) + (s_i + s_j) sin(psi)`; tension planes `s_i - sigma_t <= 0`. History per
//! point (2 f64, kept by the core): `[plastic shear strain, state]` (state 1 plastic in the last
//! update, 2 in the past). Units: `cohesion`, `tension_cutoff` stress; angles in degrees.
//!
//! Also `example_nan_law` (material law): linear elastic until a point's `nan_after`-th update,
//! which returns NaN, to show that a plugin returning NaN stops the run with its name.
//!
//! ```toml
//! [[material]]
//! young_modulus = 1.0e5    # kPa
//! poisson_ratio = 0.3
//! density = 2.0            # t/m3
//! law = { type = "example_mohr_coulomb", cohesion = 10.0, friction_angle_deg = 20.0, dilation_angle_deg = 0.0 }
//! ```
//!
//! ```toml
//! [[material]]
//! young_modulus = 1.0e5
//! poisson_ratio = 0.3
//! density = 2.0
//! law = { type = "example_nan_law", nan_after = 10 }
//! ```
use flem_plugin_sdk::{BoundLaw, Dmat, Law, Material, ParamError, Plane};
use serde::Deserialize;

/// `law = { type = "example_mohr_coulomb", ... }`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExampleMohrCoulomb {
    /// Cohesion c (stress), >= 0.
    pub cohesion: f64,
    /// Friction angle (degrees), in [0, 90).
    pub friction_angle_deg: f64,
    /// Dilation angle (degrees), in [0, friction_angle_deg]; default 0.
    #[serde(default)]
    pub dilation_angle_deg: f64,
    /// Tension cut-off (stress), in [0, c / tan(phi)]; default the apex (none when phi = 0).
    #[serde(default)]
    pub tension_cutoff: Option<f64>,
}

fn range(key: &str, v: f64, lo: f64, hi: f64, hi_incl: bool) -> Result<(), ParamError> {
    let ok = v.is_finite() && v >= lo && (if hi_incl { v <= hi } else { v < hi });
    if ok {
        Ok(())
    } else {
        Err(ParamError::new(key, format!("= {v} is incorrect; it must be in [{lo}, {hi}{}", if hi_incl { "]" } else { ")" })))
    }
}

impl ExampleMohrCoulomb {
    fn tension(&self) -> f64 {
        let phi = self.friction_angle_deg.to_radians();
        match self.tension_cutoff {
            Some(t) => t,
            None if phi > 0.0 => self.cohesion / phi.tan(),
            None => f64::INFINITY,
        }
    }
}

impl Law for ExampleMohrCoulomb {
    /// `[plastic shear strain, state]`.
    const STATE: usize = 2;
    type Bound = MohrCoulomb;

    fn bind(&self, mat: &Material) -> Result<MohrCoulomb, ParamError> {
        range("cohesion", self.cohesion, 0.0, 1e100, true)?;
        range("friction_angle_deg", self.friction_angle_deg, 0.0, 90.0, false)?;
        range("dilation_angle_deg", self.dilation_angle_deg, 0.0, self.friction_angle_deg, true)?;
        if self.cohesion == 0.0 && self.friction_angle_deg == 0.0 {
            return Err(ParamError::new("cohesion", "= 0 with friction_angle_deg = 0 gives no strength at all; give a cohesion or a friction angle"));
        }
        if let Some(t) = self.tension_cutoff {
            let phi = self.friction_angle_deg.to_radians();
            let apex = if phi > 0.0 { self.cohesion / phi.tan() } else { 1e100 };
            range("tension_cutoff", t, 0.0, apex, true)?;
        }
        if mat.plane != Plane::Strain {
            return Err(ParamError::new("type", "= \"example_mohr_coulomb\" needs plane strain (model.plane = \"strain\"): its return uses the out-of-plane stress"));
        }
        Ok(MohrCoulomb::new(mat, self.cohesion, self.friction_angle_deg.to_radians(), self.dilation_angle_deg.to_radians(), self.tension()))
    }
}

/// The law with its constants in the form the return uses.
#[derive(Clone, Copy, Debug)]
pub struct MohrCoulomb {
    pub d: Dmat,
    pub lambda: f64,
    pub g: f64,
    /// Yield planes `n_k . s <= r_k` and flow directions `m_k` (principal space, sorted).
    n: [[f64; 3]; 6],
    m: [[f64; 3]; 6],
    r: [f64; 6],
    /// `n_k . D m_j`.
    a: [[f64; 6]; 6],
    /// `D m_j`.
    dm: [[f64; 3]; 6],
    /// Planes in use (tension planes are off when the cut-off is infinite).
    used: u8,
    /// Stress scale for tolerances.
    scale: f64,
}

impl MohrCoulomb {
    /// `c`, angles in radians, `sigma_t` (infinite: no tension planes).
    pub fn new(mat: &Material, c: f64, phi: f64, psi: f64, sigma_t: f64) -> Self {
        let (e, nu) = (mat.young, mat.poisson);
        let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        let g = e / (2.0 * (1.0 + nu));
        let (sp, cp, ss) = (phi.sin(), phi.cos(), psi.sin());
        let shear = |i: usize, j: usize, s: f64| {
            let mut v = [0.0; 3];
            v[i] = 1.0 + s;
            v[j] = -(1.0 - s);
            v
        };
        let unit = |i: usize| {
            let mut v = [0.0; 3];
            v[i] = 1.0;
            v
        };
        let n = [shear(0, 2, sp), shear(1, 2, sp), shear(0, 1, sp), unit(0), unit(1), unit(2)];
        let m = [shear(0, 2, ss), shear(1, 2, ss), shear(0, 1, ss), unit(0), unit(1), unit(2)];
        let r = [2.0 * c * cp, 2.0 * c * cp, 2.0 * c * cp, sigma_t, sigma_t, sigma_t];
        let dm: [[f64; 3]; 6] = std::array::from_fn(|j| {
            let tr = m[j][0] + m[j][1] + m[j][2];
            std::array::from_fn(|d| lambda * tr + 2.0 * g * m[j][d])
        });
        let a = std::array::from_fn(|k| std::array::from_fn(|j| n[k][0] * dm[j][0] + n[k][1] * dm[j][1] + n[k][2] * dm[j][2]));
        let used = if sigma_t.is_finite() { 0b11_1111 } else { 0b00_0111 };
        let d = Material { plane: Plane::Strain, ..*mat }.dmat();
        MohrCoulomb { d, lambda, g, n, m, r, a, dm, used, scale: c.max(if sigma_t.is_finite() { sigma_t.abs() } else { 0.0 }) }
    }

    /// `f_k(s)` of plane `k`.
    #[inline(always)]
    fn f(&self, k: usize, s: &[f64; 3]) -> f64 {
        self.n[k][0] * s[0] + self.n[k][1] * s[1] + self.n[k][2] * s[2] - self.r[k]
    }

    /// The return of sorted principal trial stresses `s` (`s[0] >= s[1] >= s[2]`): the
    /// returned stresses and the plastic strain increment (principal), or `None` when the
    /// trial is elastic.
    pub fn return_principal(&self, s: [f64; 3]) -> Option<([f64; 3], [f64; 3])> {
        let tol = 1e-12 * (self.scale + s[0].abs().max(s[2].abs()));
        let viol = (0..6).filter(|&k| self.used & (1 << k) != 0).any(|k| self.f(k, &s) > tol);
        if !viol {
            return None;
        }
        // The planes in use (no allocation: this runs in the element loop).
        let mut planes = [0usize; 6];
        let mut np = 0;
        for k in 0..6 {
            if self.used & (1 << k) != 0 {
                planes[np] = k;
                np += 1;
            }
        }
        let planes = &planes[..np];
        let check = 1e-9 * (self.scale + s[0].abs().max(s[2].abs()));
        // Active sets of 1, 2, 3 planes in a fixed order; the first consistent one is the return.
        let mut best: Option<([f64; 3], [f64; 3])> = None;
        'size: for size in 1..=3usize {
            let mut idx = [0usize; 3];
            // Combinations of `size` planes in lexicographic order.
            for (t, v) in idx.iter_mut().enumerate().take(size) {
                *v = t;
            }
            loop {
                let act: [usize; 3] = std::array::from_fn(|t| if t < size { planes[idx[t]] } else { usize::MAX });
                if let Some(dl) = self.solve(&act[..size], &s) {
                    if dl[..size].iter().all(|&x| x >= -1e-14 * (1.0 + x.abs())) {
                        let mut out = s;
                        let mut dep = [0.0; 3];
                        for t in 0..size {
                            let j = act[t];
                            for d in 0..3 {
                                out[d] -= dl[t] * self.dm[j][d];
                                dep[d] += dl[t] * self.m[j][d];
                            }
                        }
                        if planes.iter().all(|&k| self.f(k, &out) <= check) {
                            best = Some((out, dep));
                            break 'size;
                        }
                    }
                }
                // Next combination.
                let mut t = size;
                loop {
                    if t == 0 {
                        continue 'size;
                    }
                    t -= 1;
                    if idx[t] < np - size + t {
                        idx[t] += 1;
                        for u in t + 1..size {
                            idx[u] = idx[u - 1] + 1;
                        }
                        break;
                    }
                }
            }
        }
        // Every admissible point is reached by some set; this guards round-off at the apex.
        Some(best.unwrap_or_else(|| {
            let p = if self.r[3].is_finite() { self.r[3] } else { (s[0] + s[1] + s[2]) / 3.0 };
            ([p; 3], [0.0; 3])
        }))
    }

    /// Multipliers of the active planes `act` (Cramer's rule; `None` when singular).
    fn solve(&self, act: &[usize], s: &[f64; 3]) -> Option<[f64; 3]> {
        let k = act.len();
        let a = |i: usize, j: usize| self.a[act[i]][act[j]];
        let b: [f64; 3] = std::array::from_fn(|i| if i < k { self.f(act[i], s) } else { 0.0 });
        let big = self.a[0][0].abs().max(self.a[3][3].abs());
        match k {
            1 => {
                let d = a(0, 0);
                (d.abs() > 1e-12 * big).then(|| [b[0] * (1.0 / d), 0.0, 0.0])
            }
            2 => {
                let d = a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0);
                (d.abs() > 1e-10 * big * big).then(|| [(b[0] * a(1, 1) - a(0, 1) * b[1]) / d, (a(0, 0) * b[1] - b[0] * a(1, 0)) / d, 0.0])
            }
            _ => {
                let m = [[a(0, 0), a(0, 1), a(0, 2)], [a(1, 0), a(1, 1), a(1, 2)], [a(2, 0), a(2, 1), a(2, 2)]];
                let det3 =
                    |m: &[[f64; 3]; 3]| m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
                let d = det3(&m);
                if d.abs() <= 1e-9 * big * big * big {
                    return None;
                }
                Some(std::array::from_fn(|c| {
                    let mut mc = m;
                    for r in 0..3 {
                        mc[r][c] = b[r];
                    }
                    det3(&mc) / d
                }))
            }
        }
    }
}

impl BoundLaw for MohrCoulomb {
    fn elastic(&self) -> Dmat {
        self.d
    }
    #[inline]
    fn update(&self, st: &mut [f64; 4], de: [f64; 4], state: &mut [f64]) {
        // Elastic trial (3D isotropic law, plane strain).
        let (l, g2) = (self.lambda, 2.0 * self.g);
        let tr = de[0] + de[1] + de[3];
        let s = [st[0] + l * tr + g2 * de[0], st[1] + l * tr + g2 * de[1], st[2] + self.g * de[2], st[3] + l * tr + g2 * de[3]];
        // In-plane principal stresses and direction, then the three sorted.
        let (mid, half) = (0.5 * (s[0] + s[1]), 0.5 * (s[0] - s[1]));
        let rad = (half * half + s[2] * s[2]).sqrt();
        let (pa, pb, pz) = (mid + rad, mid - rad, s[3]);
        // Quick elastic check on the face and the tension plane (most points, most steps).
        let (hi, lo) = (pa.max(pz), pb.min(pz));
        let f13 = self.f(0, &[hi, 0.0, lo]);
        let t1 = if self.used & 8 != 0 { hi - self.r[3] } else { f64::NEG_INFINITY };
        if f13 <= 0.0 && t1 <= 0.0 {
            *st = s;
            if state[1] == 1.0 {
                state[1] = 2.0;
            }
            return;
        }
        // Sort (pa >= pb always): z first, middle or last.
        let (sorted, pos) = if pz >= pa {
            ([pz, pa, pb], [1usize, 2, 0]) // pos[a, b, z] in sorted
        } else if pz >= pb {
            ([pa, pz, pb], [0, 2, 1])
        } else {
            ([pa, pb, pz], [0, 1, 2])
        };
        match self.return_principal(sorted) {
            None => {
                *st = s;
                if state[1] == 1.0 {
                    state[1] = 2.0;
                }
            }
            Some((r, dep)) => {
                let (na, nb, nz) = (r[pos[0]], r[pos[1]], r[pos[2]]);
                // One division and two products, as the built-in's `rotation`.
                let (c2, s2) = if rad > 0.0 {
                    let ir = 1.0 / rad;
                    (half * ir, s[2] * ir)
                } else {
                    (1.0, 0.0)
                };
                let (m, h) = (0.5 * (na + nb), 0.5 * (na - nb));
                *st = [m + h * c2, m - h * c2, h * s2, nz];
                let (mx, mn) = (dep[0].max(dep[1]).max(dep[2]), dep[0].min(dep[1]).min(dep[2]));
                state[0] += mx - mn;
                state[1] = 1.0;
            }
        }
    }
    fn output(&self, state: &[f64]) -> (f64, u8) {
        (state[0], state[1] as u8)
    }
}

/// `law = { type = "example_nan_law", nan_after = n }`: linear elastic (plane strain or
/// stress as the material), NaN at a point's `nan_after`-th update (history: its update count).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExampleNanLaw {
    pub nan_after: u64,
}

pub struct NanLaw {
    d: Dmat,
    after: f64,
}

impl Law for ExampleNanLaw {
    const STATE: usize = 1;
    type Bound = NanLaw;
    fn bind(&self, mat: &Material) -> Result<NanLaw, ParamError> {
        if self.nan_after == 0 {
            return Err(ParamError::new("nan_after", "= 0 is incorrect; it must be at least 1"));
        }
        Ok(NanLaw { d: mat.dmat(), after: self.nan_after as f64 })
    }
}

impl BoundLaw for NanLaw {
    fn elastic(&self) -> Dmat {
        self.d
    }
    fn update(&self, s: &mut [f64; 4], de: [f64; 4], state: &mut [f64]) {
        state[0] += 1.0;
        if state[0] >= self.after {
            s[0] = f64::NAN;
            return;
        }
        let d = &self.d;
        s[0] += d.d11 * de[0] + d.d12 * de[1];
        s[1] += d.d12 * de[0] + d.d11 * de[1];
        s[2] += d.d33 * de[2];
    }
}
