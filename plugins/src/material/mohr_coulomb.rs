//! `mohr_coulomb`: elastic-perfectly plastic Mohr-Coulomb with non-associated flow and a
//! tension cut-off, return mapping in principal stresses (plane strain).
//!
//! Tension positive here (the element convention), principal stresses sorted
//! `s1 >= s2 >= s3` over the two in-plane ones and the out-of-plane `szz` of plane strain.
//! `c` cohesion (stress), `phi` friction angle, `psi` dilation angle, `sigma_t` tension
//! cut-off (stress, `<= c / tan(phi)`; default: the apex `c / tan(phi)`, i.e. no cut-off
//! below the apex; none when `phi = 0`). Yield planes and potentials:
//!
//! - shear `F_ij = (s_i - s_j) + (s_i + s_j) sin(phi) - 2 c cos(phi) <= 0` for
//!   `(i, j) = (1, 3)` (the face), `(2, 3)` and `(1, 2)` (the faces met at the edges
//!   `s1 = s2` and `s2 = s3`), flow along `G_ij = (s_i - s_j) + (s_i + s_j) sin(psi)`;
//! - tension `T_i = s_i - sigma_t <= 0`, `i = 1, 2, 3`, associated flow.
//!
//! With isotropic elasticity the principal directions of the trial stress are kept, and
//! because every surface is a plane in principal space and the law is perfectly plastic,
//! the return is exact: for an active set `A`, `sigma = sigma_tr - sum_{j in A} dl_j D m_j`
//! with `sum_j (n_k . D m_j) dl_j = f_k(sigma_tr)`, `k in A` (`D = lambda 1 1^T + 2 G I`,
//! `n_k`, `m_k` the gradients of the yield plane and of the potential). The active set is the
//! first, in the order face (1 plane), edges and corners (2), apex points (3), whose
//! multipliers are all `>= 0` and whose stress violates no plane: the main face, the two
//! edges `s1 = s2` / `s2 = s3`, the apex (for `phi > 0`, where the tension planes at
//! `sigma_t = c cot(phi)` meet) and the tension cut-off regions come out of this one rule.
//! For associated flow these are the KKT conditions of the closest-point projection in the
//! energy norm, which has one solution. This is the algorithm of de Souza Neto, Peric & Owen
//! (2008, Computational Methods for Plasticity, section 8.2.1: one-vector, two-vector
//! (edge) and apex returns) and of Clausen, Damkilde & Andersen (2006, Comput. Struct. 84:
//! 1922), with the tension planes of FLAC's Mohr-Coulomb model (Itasca, "Constitutive Models").
//!
//! History per point: `[plastic shear strain, state]`; the plastic shear strain accumulates
//! `de1p - de3p` (largest minus smallest principal plastic strain increment, an engineering
//! shear strain), the state is 1 when the last update was plastic, 2 when a past one was.
//! Plane strain only (the out-of-plane stress is a principal stress of the return); angles
//! in degrees in the config. Optional strain softening of c, phi, psi against FLAC's plastic
//! shear strain (`softening = { eps_ps = [...], ... }`): the submodule [`softening`]; without
//! it this law is perfectly plastic.
//!
//! ```toml
//! [[material]]
//! young_modulus = 1.0e5    # kPa
//! poisson_ratio = 0.3
//! density = 2.0            # t/m3
//! law = { type = "mohr_coulomb", cohesion = 10.0, friction_angle_deg = 20.0, dilation_angle_deg = 0.0 }
//! ```
//!
//! ```toml
//! [[material]]
//! young_modulus = 1.0e5
//! poisson_ratio = 0.3
//! density = 2.0
//! law = { type = "mohr_coulomb", cohesion = 10.0, friction_angle_deg = 30.0, dilation_angle_deg = 30.0, tension_cutoff = 5.0 }
//! ```
use serde::{Deserialize, Serialize};

use crate::elements::build_stateful;
use flem_core::element::block::Block;
use flem_core::element::block::Simd;
use flem_core::element::kernel::LANES;
use flem_core::element::law::{LawCfg, MaterialLaw, RegionElems, StatefulOpts};
use flem_core::element::{Dmat, Material, Plane};

#[path = "mohr_coulomb_tangent.rs"]
mod tangent;

#[cfg(target_arch = "x86_64")]
#[path = "mohr_coulomb_avx512.rs"]
mod avx512;

#[path = "mohr_coulomb_softening.rs"]
pub mod softening;
pub use softening::{MohrCoulombSoftening, SofteningCfg};

/// `law = { type = "mohr_coulomb", ... }` (see the module docs).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MohrCoulombCfg {
    /// Cohesion c (stress), >= 0.
    pub cohesion: f64,
    /// Friction angle (degrees), in [0, 90).
    pub friction_angle_deg: f64,
    /// Dilation angle (degrees), in [0, friction_angle_deg]; default 0 (no dilation).
    #[serde(default)]
    pub dilation_angle_deg: f64,
    /// Tension cut-off (stress), in [0, c / tan(phi)]; default the apex (none when phi = 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tension_cutoff: Option<f64>,
    /// Optional strain softening (or hardening) of c, phi, psi against FLAC's plastic shear
    /// strain parameter (`softening::SofteningCfg`); absent: perfectly plastic.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub softening: Option<SofteningCfg>,
}

/// An elastic trial (`MohrCoulomb::trial`).
#[derive(Clone, Copy, Debug)]
struct Trial {
    /// Trial stress `[sxx, syy, sxy, szz]`.
    s: [f64; 4],
    /// Half the in-plane stress difference `(sxx - syy) / 2` and Mohr's radius.
    half: f64,
    rad: f64,
    /// In-plane principal stresses (`pa >= pb`) and the out-of-plane one.
    pa: f64,
    pb: f64,
    pz: f64,
    /// True when the trial passes the quick test (the trial is the answer).
    inside: bool,
}

/// A return in principal stresses: the returned stresses, the plastic strain increment, its
/// part on the shear planes, and the active planes `act[..size]` (`size = 0`: the round-off
/// guard at the apex).
#[derive(Clone, Copy, Debug)]
struct Return {
    out: [f64; 3],
    dep: [f64; 3],
    dep_shear: [f64; 3],
    act: [usize; 3],
    size: usize,
}

/// A pack's elastic trial at one point (`MohrCoulomb::elastic_lanes`): the trial stress, half
/// the in-plane difference, the centre and the squared radius of Mohr's circle, by lane.
#[derive(Clone, Copy, Debug)]
struct LaneTrial {
    ts: [[f64; LANES]; 4],
    half: [f64; LANES],
    mid: [f64; LANES],
    rr: [f64; LANES],
}

/// The most points of a pack that `update_points_lanes` handles together (Q4's four; a kind
/// with more takes `update_lanes` point by point).
const MAX_POINTS: usize = 4;

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
    /// The bounds of the pre-test (`slack_lanes`): `(r / ka, kb / ka, r / kb, ka / kb)` (constants of the law).
    pre: [f64; 4],
    /// `1 / a_kk`: a single plane's multiplier is `f_k * inv_diag[k]` (one multiply, not a
    /// division, in every single-plane return; pairs and triples still divide; ours, session 30).
    inv_diag: [f64; 6],
}

/// `(cos 2 theta, sin 2 theta)` of the in-plane principal direction from the trial's `half`,
/// `sxy` and Mohr's radius `rad`: one division (`1 / rad`) and two products (ours, session 30;
/// the two quotients of before differ from these by an ulp at most). Shared by the return in
/// lanes, the scalar return, the softening law and the consistent tangent, so that they agree
/// bit for bit.
#[inline(always)]
pub(crate) fn rotation(half: f64, sxy: f64, rad: f64) -> (f64, f64) {
    let pos = rad > 0.0;
    let ir = 1.0 / if pos { rad } else { 1.0 };
    (if pos { half * ir } else { 1.0 }, if pos { sxy * ir } else { 0.0 })
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
        let (ka, kb) = (n[0][0], -n[0][2]);
        let pre = [r[0] / ka, kb / ka, r[0] / kb, ka / kb];
        let inv_diag = std::array::from_fn(|k| if a[k][k] != 0.0 { 1.0 / a[k][k] } else { 0.0 });
        MohrCoulomb { d, lambda, g, n, m, r, a, dm, used, scale: c.max(if sigma_t.is_finite() { sigma_t.abs() } else { 0.0 }), pre, inv_diag }
    }

    /// The elastic trial of an update (3D isotropic law, plane strain): the trial stress, its
    /// in-plane principal stresses, and the quick test on the main face and the first tension
    /// plane, which most points pass in most steps (then the trial is the answer).
    #[inline(always)]
    fn trial(&self, st: &[f64; 4], de: [f64; 4]) -> Trial {
        let (l, g2) = (self.lambda, 2.0 * self.g);
        let tr = de[0] + de[1] + de[3];
        let s = [st[0] + l * tr + g2 * de[0], st[1] + l * tr + g2 * de[1], st[2] + self.g * de[2], st[3] + l * tr + g2 * de[3]];
        // In-plane principal stresses and direction, then the three sorted.
        let (mid, half) = (0.5 * (s[0] + s[1]), 0.5 * (s[0] - s[1]));
        let rad = (half * half + s[2] * s[2]).sqrt();
        let (pa, pb, pz) = (mid + rad, mid - rad, s[3]);
        let (hi, lo) = (pa.max(pz), pb.min(pz));
        let f13 = self.f(0, &[hi, 0.0, lo]);
        let t1 = if self.used & 8 != 0 { hi - self.r[3] } else { f64::NEG_INFINITY };
        Trial { s, half, rad, pa, pb, pz, inside: f13 <= 0.0 && t1 <= 0.0 }
    }

    /// The pre-test of [`Self::slack_lanes`] as booleans (its tests' form).
    #[cfg(test)]
    fn inside_lanes(&self, mid: &[f64; LANES], rr: &[f64; LANES], pz: &[f64; LANES]) -> [bool; LANES] {
        let slack = self.slack_lanes(mid, rr, pz);
        std::array::from_fn(|l| slack[l] >= 0.0)
    }

    /// The quick test of `trial` without the square root, for a pack, as each lane's slack
    /// (`>= 0`: the lane passes): with `mid`, `rr` the centre and the squared radius of Mohr's
    /// in-plane circle and `pz` the out-of-plane stress, the main face `F_13 <= 0` (over every
    /// order of the three principal stresses: `F_13` of the sorted ones is the largest of
    /// `k_a s_i - k_b s_j - 2 c cos(phi)`, `k_a = 1 + sin(phi)`, `k_b = 1 - sin(phi) > 0`) and
    /// the first tension plane are each a bound `rad <= x` on Mohr's radius, tested as `x >= 0`
    /// and `rr <= x^2`. It may differ from `trial`'s test by round-off at the surface;
    /// `update_lanes` uses it only to route a pack (see there), so no result depends on it.
    ///
    /// The form vectorises (ours, session 37; before, booleans and a bit mask built lane by
    /// lane): the slack is the least of `x`, `x^2 - rr` and `sigma_t - pz`, each `>= 0` exactly
    /// when its test holds (a rounded difference of finite numbers has the sign of the exact
    /// one; `inf - inf`, stresses whose squares overflow, is NaN and routes the lane on), with
    /// the tension plane's bound in a loop of its own rather than a branch in the loop. A NaN
    /// input makes `x` or `x^2 - rr` NaN, and the minimum keeps it because the NaN candidates
    /// (`x3`, `x2`, `x^2 - rr`) are `lo`'s first operands: do not reorder them. A NaN fails
    /// `>= 0`, so a NaN stress is routed on (`pre_test_passes_only_lanes_inside_nan_and_infinities_included`).
    #[inline(always)]
    fn slack_lanes(&self, mid: &[f64; LANES], rr: &[f64; LANES], pz: &[f64; LANES]) -> [f64; LANES] {
        let (ka, kb, r) = (self.n[0][0], -self.n[0][2], self.r[0]);
        let [ra, ba, rb, ab] = self.pre;
        let st = self.r[3];
        // `lo(a, b)`: `b` when it is smaller, else `a` (a NaN `a` is kept). Selects, not
        // `f64::min`, whose NaN rule keeps a loop scalar.
        let lo = |a: f64, b: f64| if b < a { b } else { a };
        let mut x = [0.0; LANES];
        for l in 0..LANES {
            // (pa, pb), (pa, pz), (pz, pb): the largest over the orders, each `rad <= x`.
            let x1 = 0.5 * (r - (ka - kb) * mid[l]);
            let x2 = ra + ba * pz[l] - mid[l];
            let x3 = rb - ab * pz[l] + mid[l];
            x[l] = lo(lo(x3, x2), x1);
        }
        let mut slack = [0.0; LANES];
        if self.used & 8 != 0 {
            for l in 0..LANES {
                let xl = lo(x[l], st - mid[l]);
                slack[l] = lo(lo(xl * xl - rr[l], xl), st - pz[l]);
            }
        } else {
            for l in 0..LANES {
                slack[l] = lo(x[l] * x[l] - rr[l], x[l]);
            }
        }
        slack
    }

    /// The returns of `return_active` after the main face, in lanes, for a law without
    /// tension planes (`used` = the three shear planes; ours, issue 37: the Tresca footing's
    /// points under the footing return to the edges): the active sets that
    /// come next in its order, `{1}`, `{2}` and the two edges `{0, 1}`
    /// (`s1 = s2`) and `{0, 2}` (`s2 = s3`), each with `solve`'s arithmetic and
    /// `return_active`'s tests (multipliers `>= 0`, no plane violated after), computed for
    /// every lane; a lane that the face did not take (`face[l]` false) and whose trial violates
    /// a plane (`vio[l]`) takes the first consistent set of that list, as `return_active`
    /// would, since every set before it in its order was tried and failed (`{0}`: the face).
    /// Such a lane gets `plastic_update`'s rotation back and history (`fs`, `gam`) and is
    /// marked in `face` (a vectorised return); a lane none of these sets fits (corners, the
    /// apex, the tension planes' pairs) is left to `plastic_update`. The same operations in
    /// the same order as the scalar return, so the same bits.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn edge_lanes(
        &self,
        q: &[[f64; LANES]; 3],
        vio: &[bool; LANES],
        za: &[bool; LANES],
        zb: &[bool; LANES],
        rad: &[f64; LANES],
        half: &[f64; LANES],
        sxy: &[f64; LANES],
        face: &mut [bool; LANES],
        fs: &mut [[f64; LANES]; 4],
        gam: &mut [f64; LANES],
    ) {
        debug_assert_eq!(self.used, 0b111);
        let used: [bool; 6] = std::array::from_fn(|k| self.used & (1 << k) != 0);
        let big = self.a[0][0].abs().max(self.a[3][3].abs());
        let ok = |x: f64| x >= -1e-14 * (1.0 + x.abs());
        // The singles' and the pairs' solvability (`solve`'s tests: constants of the law).
        let single: [bool; 6] = std::array::from_fn(|k| used[k] & (self.a[k][k].abs() > 1e-12 * big));
        let det = |a: usize, b: usize| self.a[a][a] * self.a[b][b] - self.a[a][b] * self.a[b][a];
        let pairs = [(0usize, 1usize), (0, 2)];
        let pair_ok: [bool; 2] = std::array::from_fn(|t| det(pairs[t].0, pairs[t].1).abs() > 1e-10 * big * big);
        for l in 0..LANES {
            let ql = [q[0][l], q[1][l], q[2][l]];
            let check = 1e-9 * (self.scale + ql[0].abs().max(ql[2].abs()));
            // (Three planes: the caller calls this for a law without tension planes only.)
            let adm = |out: &[f64; 3]| {
                let mut a = true;
                for k in 0..3 {
                    a &= self.f(k, out) <= check;
                }
                a
            };
            // `found`: a set before the current one fits (the face, or one of this list).
            let mut found = face[l] | !vio[l];
            let (mut o, mut dp, mut take) = ([0.0; 3], [0.0; 3], false);
            for k in 1..3 {
                let dl = self.f(k, &ql) * self.inv_diag[k];
                let mut out = ql;
                let mut dep = [0.0; 3];
                for d in 0..3 {
                    out[d] -= dl * self.dm[k][d];
                    dep[d] += dl * self.m[k][d];
                }
                let fits = single[k] & ok(dl) & adm(&out);
                let t = !found & fits;
                for d in 0..3 {
                    o[d] = if t { out[d] } else { o[d] };
                    dp[d] = if t { dep[d] } else { dp[d] };
                }
                take |= t;
                found |= fits;
            }
            for (t, &(a, b)) in pairs.iter().enumerate() {
                let (b0, b1) = (self.f(a, &ql), self.f(b, &ql));
                let (a00, a01, a10, a11) = (self.a[a][a], self.a[a][b], self.a[b][a], self.a[b][b]);
                let dt = a00 * a11 - a01 * a10;
                let dl = [(b0 * a11 - a01 * b1) / dt, (a00 * b1 - b0 * a10) / dt];
                let mut out = ql;
                let mut dep = [0.0; 3];
                for (u, j) in [a, b].into_iter().enumerate() {
                    for d in 0..3 {
                        out[d] -= dl[u] * self.dm[j][d];
                        dep[d] += dl[u] * self.m[j][d];
                    }
                }
                let fits = pair_ok[t] & ok(dl[0]) & ok(dl[1]) & adm(&out);
                let tk = !found & fits;
                for d in 0..3 {
                    o[d] = if tk { out[d] } else { o[d] };
                    dp[d] = if tk { dep[d] } else { dp[d] };
                }
                take |= tk;
                found |= fits;
            }
            // `plastic_update`'s rotation back, as the face lanes'.
            let na = if za[l] { o[1] } else { o[0] };
            let nb = if zb[l] { o[2] } else { o[1] };
            let nz = if za[l] {
                o[0]
            } else if zb[l] {
                o[1]
            } else {
                o[2]
            };
            let (c2, s2) = rotation(half[l], sxy[l], rad[l]);
            let (m, h) = (0.5 * (na + nb), 0.5 * (na - nb));
            let g = dp[0].max(dp[1]).max(dp[2]) - dp[0].min(dp[1]).min(dp[2]);
            let v = [m + h * c2, m - h * c2, h * s2, nz];
            for c in 0..4 {
                fs[c][l] = if take { v[c] } else { fs[c][l] };
            }
            gam[l] = if take { g } else { gam[l] };
            face[l] |= take;
        }
    }

    /// The elastic part of `update_lanes` for one point of a pack: the trial of every lane
    /// and the pre-test. When every lane of `..n` passes it, the trial is the answer: it is
    /// written to `s`, the history's state 1 becomes 2, and `None` is returned; otherwise
    /// nothing is written and the trial is returned for the return (`yield_lanes`).
    #[inline(always)]
    fn elastic_lanes(&self, s: &mut [[f64; LANES]; 4], de: &[[f64; LANES]; 4], state: &mut [f64], stride: usize, n: usize) -> Option<LaneTrial> {
        let z = [0.0; LANES];
        let (l_, g2, g) = (self.lambda, 2.0 * self.g, self.g);
        let (mut ts, mut half, mut mid, mut rr) = ([z; 4], z, z, z);
        for l in 0..LANES {
            // `trial`'s arithmetic, in its order.
            let tr = de[0][l] + de[1][l] + de[3][l];
            ts[0][l] = s[0][l] + l_ * tr + g2 * de[0][l];
            ts[1][l] = s[1][l] + l_ * tr + g2 * de[1][l];
            ts[2][l] = s[2][l] + g * de[2][l];
            ts[3][l] = s[3][l] + l_ * tr + g2 * de[3][l];
            mid[l] = 0.5 * (ts[0][l] + ts[1][l]);
            half[l] = 0.5 * (ts[0][l] - ts[1][l]);
            rr[l] = half[l] * half[l] + ts[2][l] * ts[2][l];
        }
        let n = n.min(LANES);
        // Whether a lane of `..n` fails the pre-test: one compare of the pack and an OR over
        // its lanes, not a branch per lane (nor a bit mask built lane by lane, which did not
        // vectorise).
        let slack = self.slack_lanes(&mid, &rr, &ts[3]);
        let mut bad = [0u64; LANES];
        for l in 0..LANES {
            bad[l] = u64::from(!(slack[l] >= 0.0) & (l < n));
        }
        if bad.iter().fold(0, |a, &b| a | b) != 0 {
            return Some(LaneTrial { ts, half, mid, rr });
        }
        // Every lane elastic: no branch per lane but the history's.
        *s = ts;
        for l in 0..n {
            let h = &mut state[l * stride + 1];
            if *h == 1.0 {
                *h = 2.0;
            }
        }
        None
    }

    /// `yield_lanes` of the points `k` of a pack that have a trial `tr[k]` (stress `s[k]`,
    /// history at `state[k * STATE..]`), in one out-of-line call chosen at run time as
    /// `yield_lanes` is (ours, session 37).
    #[inline(never)]
    fn yield_points(&self, s: &mut [[[f64; LANES]; 4]], tr: &[Option<LaneTrial>; MAX_POINTS], state: &mut [f64], stride: usize, n: usize) {
        #[cfg(target_arch = "x86_64")]
        {
            match Simd::best() {
                // SAFETY: `Simd::best` answers a set only when the CPU runs it.
                Simd::Avx512 => return unsafe { self.yield_points_avx512(s, tr, state, stride, n) },
                // SAFETY: as above.
                Simd::Avx2 => return unsafe { self.yield_points_avx2(s, tr, state, stride, n) },
                Simd::Plain => {}
            }
        }
        self.yield_points_body(s, tr, state, stride, n)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn yield_points_avx2(&self, s: &mut [[[f64; LANES]; 4]], tr: &[Option<LaneTrial>; MAX_POINTS], state: &mut [f64], stride: usize, n: usize) {
        self.yield_points_body(s, tr, state, stride, n)
    }

    #[inline(always)]
    fn yield_points_body(&self, s: &mut [[[f64; LANES]; 4]], tr: &[Option<LaneTrial>; MAX_POINTS], state: &mut [f64], stride: usize, n: usize) {
        for (k, (sk, t)) in s.iter_mut().zip(tr).enumerate() {
            if let Some(t) = t {
                self.yield_lanes_body(sk, &t.ts, &t.half, &t.mid, &t.rr, &mut state[k * Self::STATE..], stride, n);
            }
        }
    }

    /// The rest of `update_lanes` for a pack some of whose lanes fail the pre-test: the
    /// principal stresses, the main-face return in lanes, the edges (`edge_lanes`) and the
    /// scalar returns. Out of line, so that the elastic path that inlines into the stateful
    /// block's pack loop stays small (its trial arrays stay in registers); compiled for the
    /// instruction sets the block's pack loop is (AVX-512 in intrinsics, AVX2, the baseline)
    /// and chosen at run time by the same `Simd::best` (so `FLEM_SIMD` caps it too), with the
    /// same operations and bits on every path (ours, session 37).
    ///
    /// (`yield_points` does the same for a pack's points at once. Routing `update_lanes`
    /// through it with one point, to keep one dispatch, was tried: the face case went from 46
    /// to 53 ns and large strain from 90 to 121-127 ns, so both stay.)
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    fn yield_lanes(&self, s: &mut [[f64; LANES]; 4], ts: &[[f64; LANES]; 4], half: &[f64; LANES], mid: &[f64; LANES], rr: &[f64; LANES], state: &mut [f64], stride: usize, n: usize) {
        #[cfg(target_arch = "x86_64")]
        {
            match Simd::best() {
                // SAFETY: `Simd::best` answers a set only when the CPU runs it.
                Simd::Avx512 => return unsafe { self.yield_lanes_avx512(s, ts, half, mid, rr, state, stride, n) },
                // SAFETY: as above.
                Simd::Avx2 => return unsafe { self.yield_lanes_avx2(s, ts, half, mid, rr, state, stride, n) },
                Simd::Plain => {}
            }
        }
        self.yield_lanes_body(s, ts, half, mid, rr, state, stride, n)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    fn yield_lanes_avx2(&self, s: &mut [[f64; LANES]; 4], ts: &[[f64; LANES]; 4], half: &[f64; LANES], mid: &[f64; LANES], rr: &[f64; LANES], state: &mut [f64], stride: usize, n: usize) {
        self.yield_lanes_body(s, ts, half, mid, rr, state, stride, n)
    }

    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn yield_lanes_body(&self, s: &mut [[f64; LANES]; 4], ts: &[[f64; LANES]; 4], half: &[f64; LANES], mid: &[f64; LANES], rr: &[f64; LANES], state: &mut [f64], stride: usize, n: usize) {
        let z = [0.0; LANES];
        let (mut rad, mut pa, mut pb, mut inside) = (z, z, z, [false; LANES]);

        let (r3, t_on) = (self.r[3], self.used & 8 != 0);
        for l in 0..LANES {
            rad[l] = rr[l].sqrt();
            pa[l] = mid[l] + rad[l];
            pb[l] = mid[l] - rad[l];
            let pz = ts[3][l];
            // `trial`'s quick test.
            let (hi, lo) = (pa[l].max(pz), pb[l].min(pz));
            let f13 = self.f(0, &[hi, 0.0, lo]);
            let t1 = if t_on { hi - r3 } else { f64::NEG_INFINITY };
            inside[l] = f13 <= 0.0 && t1 <= 0.0;
        }
        let pz = ts[3];
        let (d0, big) = (self.a[0][0], self.a[0][0].abs().max(self.a[3][3].abs()));
        let solvable = d0.abs() > 1e-12 * big;
        let used: [bool; 6] = std::array::from_fn(|k| self.used & (1 << k) != 0);
        // Sorted `s1 >= s2 >= s3` over (pa, pb, pz), as `sort_principal` sorts them.
        // Selects only, no `else if` and no booleans stored in the loop: written this way it
        // vectorises (its branchy form was compiled lane by lane, and the whole-pack loads that
        // followed its scalar stores stalled; ours, session 37). The orders `edge_lanes` needs
        // are a loop of their own.
        let (mut za, mut zb, mut q) = ([false; LANES], [false; LANES], [z; 3]);
        for l in 0..LANES {
            let (a, b, c) = (pa[l], pb[l], pz[l]);
            let (ya, yb) = (c >= a, c >= b);
            let m1 = if yb { c } else { b };
            q[0][l] = if ya { c } else { a };
            q[1][l] = if ya { a } else { m1 };
            q[2][l] = if yb { b } else { c };
        }
        for l in 0..LANES {
            za[l] = pz[l] >= pa[l];
            zb[l] = pz[l] >= pb[l];
        }
        let (mut face, mut fs, mut gam, mut vio) = ([false; LANES], [z; 4], z, [false; LANES]);
        for l in 0..LANES {
            let ql = [q[0][l], q[1][l], q[2][l]];
            let tol = 1e-12 * (self.scale + ql[0].abs().max(ql[2].abs()));
            // `return_active`'s test over the planes in use, on the main face and the first
            // tension plane only: for sorted stresses (`q0 >= q1 >= q2`) every other plane's
            // `f` is at most one of these two, in floating point too (the same products and
            // sums but one, larger or equal, and rounding is monotone: `f1, f2 <= f0`,
            // `f4, f5 <= f3`), so the test has the same answer.
            let viol = (self.f(0, &ql) > tol) | (used[3] & (self.f(3, &ql) > tol));
            vio[l] = viol;
            let dl = self.f(0, &ql) * self.inv_diag[0];
            let ok = dl >= -1e-14 * (1.0 + dl.abs());
            let mut out = ql;
            let mut dep = [0.0; 3];
            for d in 0..3 {
                out[d] -= dl * self.dm[0][d];
                dep[d] += dl * self.m[0][d];
            }
            let check = 1e-9 * (self.scale + ql[0].abs().max(ql[2].abs()));
            let mut adm = true;
            for k in 0..6 {
                adm &= !used[k] | (self.f(k, &out) <= check);
            }
            face[l] = solvable & viol & ok & adm;
            let (ya, yb) = (pz[l] >= pa[l], pz[l] >= pb[l]);
            let na = if ya { out[1] } else { out[0] };
            let nb = if ya | yb { out[2] } else { out[1] };
            let t = if yb { out[1] } else { out[2] };
            let nz = if ya { out[0] } else { t };
            let (c2, s2) = rotation(half[l], ts[2][l], rad[l]);
            let (m, h) = (0.5 * (na + nb), 0.5 * (na - nb));
            fs[0][l] = m + h * c2;
            fs[1][l] = m - h * c2;
            fs[2][l] = h * s2;
            fs[3][l] = nz;
            gam[l] = dep[0].max(dep[1]).max(dep[2]) - dep[0].min(dep[1]).min(dep[2]);
        }
        // The lanes that the face does not take: the next active sets of `return_active`'s
        // order in lanes (`edge_lanes`), when some lane needs them.
        // Only for a law without tension planes (Tresca's case: three planes, the sets in lanes
        // cheaper than the scalar search from two lanes on; with the tension planes, five
        // singles and six planes to check, the scalar search with its early exits is faster),
        // and when two lanes at least need it.
        if !t_on && (0..n).filter(|&l| !inside[l] & !face[l] & vio[l]).count() >= 2 {
            self.edge_lanes(&q, &vio, &za, &zb, &rad, &half, &ts[2], &mut face, &mut fs, &mut gam);
        }
        // The elastic and face lanes without a branch: the stress selected, the history
        // rewritten (a face lane: `h0 + gam`, state 1; an elastic one: state 1 -> 2); then the
        // other lanes' returns, one by one.
        for c in 0..4 {
            for l in 0..LANES {
                s[c][l] = if inside[l] { ts[c][l] } else { fs[c][l] };
            }
        }
        for l in 0..n {
            lane_history(&mut state[l * stride..l * stride + 2], face[l], inside[l], gam[l]);
        }
        for l in 0..n {
            if !inside[l] && !face[l] {
                let h = &mut state[l * stride..l * stride + 2];
                let t = Trial { s: [ts[0][l], ts[1][l], ts[2][l], ts[3][l]], half: half[l], rad: rad[l], pa: pa[l], pb: pb[l], pz: pz[l], inside: false };
                let mut sl = t.s;
                self.plastic_update(&mut sl, &t, h);
                (s[0][l], s[1][l], s[2][l], s[3][l]) = (sl[0], sl[1], sl[2], sl[3]);
            }
        }
    }

    /// The rest of `update` when the trial fails the quick test: the return in principal
    /// stresses (out of line: the elastic path stays small enough to inline and vectorise).
    #[inline(never)]
    fn plastic_update(&self, st: &mut [f64; 4], t: &Trial, state: &mut [f64]) {
        let Trial { s, half, rad, pa, pb, pz, .. } = *t;
        let (sorted, pos) = sort_principal(pa, pb, pz);
        match self.return_principal(sorted) {
            None => {
                *st = s;
                if state[1] == 1.0 {
                    state[1] = 2.0;
                }
            }
            Some((r, dep)) => {
                let (na, nb, nz) = (r[pos[0]], r[pos[1]], r[pos[2]]);
                let (c2, s2) = rotation(half, s[2], rad);
                let (m, h) = (0.5 * (na + nb), 0.5 * (na - nb));
                *st = [m + h * c2, m - h * c2, h * s2, nz];
                let (mx, mn) = (dep[0].max(dep[1]).max(dep[2]), dep[0].min(dep[1]).min(dep[2]));
                state[0] += mx - mn;
                state[1] = 1.0;
            }
        }
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
        self.return_parts(s).map(|(out, dep, _)| (out, dep))
    }

    /// [`Self::return_principal`] with, third, the part of the plastic strain increment that
    /// flows on the shear planes (the strain-softening law's hardening parameter counts it
    /// alone, as FLAC's does); the same arithmetic for the first two.
    #[inline(always)]
    pub fn return_parts(&self, s: [f64; 3]) -> Option<([f64; 3], [f64; 3], [f64; 3])> {
        self.return_active(s).map(|r| (r.out, r.dep, r.dep_shear))
    }

    /// [`Self::return_parts`] with the active set it found (the consistent tangent needs it).
    #[inline(always)]
    fn return_active(&self, s: [f64; 3]) -> Option<Return> {
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
        let mut best: Option<Return> = None;
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
                        let mut dep_shear = [0.0; 3];
                        for t in 0..size {
                            let j = act[t];
                            for d in 0..3 {
                                out[d] -= dl[t] * self.dm[j][d];
                                dep[d] += dl[t] * self.m[j][d];
                                if j < 3 {
                                    dep_shear[d] += dl[t] * self.m[j][d];
                                }
                            }
                        }
                        if planes.iter().all(|&k| self.f(k, &out) <= check) {
                            best = Some(Return { out, dep, dep_shear, act, size });
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
            Return { out: [p; 3], dep: [0.0; 3], dep_shear: [0.0; 3], act: [usize::MAX; 3], size: 0 }
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
                (d.abs() > 1e-12 * big).then(|| [b[0] * self.inv_diag[act[0]], 0.0, 0.0])
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

impl MaterialLaw for MohrCoulomb {
    const STATE: usize = 2;
    fn elastic(&self) -> Dmat {
        self.d
    }
    #[inline(always)]
    fn update(&self, st: &mut [f64; 4], de: [f64; 4], state: &mut [f64]) {
        let t = self.trial(st, de);
        if t.inside {
            *st = t.s;
            if state[1] == 1.0 {
                state[1] = 2.0;
            }
            return;
        }
        self.plastic_update(st, &t, state);
    }
    /// `update` of a pack of points (bit for bit the same, lane by lane), every step written as
    /// a loop over the lanes of plain arithmetic and selects, so that it vectorises:
    /// - the elastic trial, and a pre-test without the square root (`Self::slack_lanes`:
    ///   Mohr's radius squared against the room each yield plane leaves it); a pack whose lanes
    ///   all pass it takes the trial (most packs, most steps). The pre-test only routes: a lane
    ///   it sends on is a lane `update` may still find elastic, and the return then gives it
    ///   the trial stress too (`return_active`'s tolerance), so the bits do not depend on it;
    /// - else, out of line (`Self::yield_lanes`; AVX-512 intrinsics where the CPU has them,
    ///   `mohr_coulomb_avx512.rs`), the principal stresses (one square root per lane) and the
    ///   main-face return of every lane at once: `return_principal`'s first active set (plane 0
    ///   alone, always the first tried) and `plastic_update`'s rotation back, the same
    ///   operations. A lane takes it when the scalar return would (violated, multiplier >= 0,
    ///   no plane violated after); the edges of a law without tension planes in lanes
    ///   (`edge_lanes`); any other lane (corners, apex, tension) through `plastic_update`.
    #[inline(always)]
    fn update_lanes(&self, s: &mut [[f64; LANES]; 4], de: &[[f64; LANES]; 4], state: &mut [f64], stride: usize, n: usize) {
        if let Some(t) = self.elastic_lanes(s, de, state, stride, n) {
            self.yield_lanes(s, &t.ts, &t.half, &t.mid, &t.rr, state, stride, n.min(LANES));
        }
    }
    /// `update_lanes` of a pack's points (ours, session 37): each point's trial and pre-test
    /// as there, then the points some of whose lanes yield in one out-of-line call
    /// (`yield_points`), not one call per point. The same operations per point, so the same
    /// bits.
    #[inline(always)]
    fn update_points_lanes(&self, s: &mut [[[f64; LANES]; 4]], de: &[[[f64; LANES]; 4]], state: &mut [f64], stride: usize, n: usize) {
        let ns = Self::STATE;
        debug_assert_eq!(self.n_state(), ns);
        // More points than a Q4's (not met by the stateful block, whose own form has four):
        // point by point.
        if s.len() > MAX_POINTS {
            for (k, (sk, dk)) in s.iter_mut().zip(de).enumerate() {
                self.update_lanes(sk, dk, &mut state[k * ns..], stride, n);
            }
            return;
        }
        debug_assert_eq!(s.len(), de.len());
        // `None` for a point whose lanes all stayed elastic (a tag written, not the 448 bytes
        // of a trial: the all-elastic path zeroes nothing).
        let mut tr: [Option<LaneTrial>; MAX_POINTS] = [None; MAX_POINTS];
        let mut any = false;
        for (k, (sk, dk)) in s.iter_mut().zip(de).enumerate() {
            tr[k] = self.elastic_lanes(sk, dk, &mut state[k * ns..], stride, n);
            any |= tr[k].is_some();
        }
        if any {
            self.yield_points(s, &tr, state, stride, n.min(LANES));
        }
    }
    /// Elastic from zero stress until the trial first leaves the quick test's region; the
    /// history (`[0, 0]`) does not change on an elastic update from the initial state.
    fn elastic_start(&self) -> bool {
        true
    }
    /// The elastic trial from zero stress and its quick test, lane by lane (`trial`, the same
    /// arithmetic as `update`'s first step from the initial state).
    #[inline(always)]
    fn initial_lanes(&self, e: &[[f64; LANES]; 4], s: &mut [[f64; LANES]; 4]) -> [bool; LANES] {
        let mut inside = [false; LANES];
        for l in 0..LANES {
            let t = self.trial(&[0.0; 4], [e[0][l], e[1][l], e[2][l], e[3][l]]);
            (s[0][l], s[1][l], s[2][l], s[3][l]) = (t.s[0], t.s[1], t.s[2], t.s[3]);
            inside[l] = t.inside;
        }
        inside
    }
    fn output(&self, state: &[f64]) -> (f64, u8) {
        (state[0], state[1] as u8)
    }
    /// The tangent of the return map (`mohr_coulomb_tangent.rs`); perfectly plastic, so the
    /// history does not enter.
    fn tangent(&self, st: &[f64; 4], de: [f64; 4], _state: &[f64], out: &mut [[f64; 4]; 4]) -> bool {
        self.consistent_tangent(st, de, out);
        true
    }
    fn tangent_symmetric(&self) -> bool {
        self.associated()
    }
}

/// The history `[plastic shear strain, state]` of a lane after the lanes' return
/// (`yield_lanes_body`, `yield_lanes_avx512`): a face lane (`face`, not `inside`) adds `gam` and is in state 1; an elastic
/// one (`inside`) goes from state 1 to 2; any other lane is left to `plastic_update`. Shared by
/// the generic body and the AVX-512 one, so that they write the same bits.
#[inline(always)]
pub(crate) fn lane_history(h: &mut [f64], face: bool, inside: bool, gam: f64) {
    let fl = face & !inside;
    let (h0, h1) = (h[0], h[1]);
    h[0] = if fl { h0 + gam } else { h0 };
    h[1] = if fl {
        1.0
    } else if inside & (h1 == 1.0) {
        2.0
    } else {
        h1
    };
}

/// The in-plane principal stresses `pa >= pb` and the out-of-plane `pz`, sorted in decreasing
/// order, and `pos[u]`: the place of (a, b, z) among the sorted (z first, middle or last).
/// Shared by the return map, its consistent tangent and the softening law.
#[inline(always)]
pub(crate) fn sort_principal(pa: f64, pb: f64, pz: f64) -> ([f64; 3], [usize; 3]) {
    if pz >= pa {
        ([pz, pa, pb], [1, 2, 0])
    } else if pz >= pb {
        ([pa, pz, pb], [0, 2, 1])
    } else {
        ([pa, pb, pz], [0, 1, 2])
    }
}

fn range(key: &str, v: f64, lo: f64, hi: f64, hi_incl: bool) -> Result<(), (String, String)> {
    let ok = v.is_finite() && v >= lo && (if hi_incl { v <= hi } else { v < hi });
    if ok {
        Ok(())
    } else {
        Err((key.to_string(), format!("= {v} is incorrect; it must be in [{lo}, {hi}{}", if hi_incl { "]" } else { ")" })))
    }
}

impl MohrCoulombCfg {
    fn tension(&self) -> f64 {
        let phi = self.friction_angle_deg.to_radians();
        match self.tension_cutoff {
            Some(t) => t,
            None if phi > 0.0 => self.cohesion / phi.tan(),
            None => f64::INFINITY,
        }
    }
    pub fn law(&self, mat: &Material) -> MohrCoulomb {
        MohrCoulomb::new(mat, self.cohesion, self.friction_angle_deg.to_radians(), self.dilation_angle_deg.to_radians(), self.tension())
    }
}

#[typetag::serde(name = "mohr_coulomb")]
impl LawCfg for MohrCoulombCfg {
    fn validate(&self, mat: &Material) -> Result<(), (String, String)> {
        range("cohesion", self.cohesion, 0.0, 1e100, true)?;
        range("friction_angle_deg", self.friction_angle_deg, 0.0, 90.0, false)?;
        range("dilation_angle_deg", self.dilation_angle_deg, 0.0, self.friction_angle_deg, true)?;
        if self.cohesion == 0.0 && self.friction_angle_deg == 0.0 {
            return Err(("cohesion".into(), "= 0 with friction_angle_deg = 0 gives no strength at all; give a cohesion or a friction angle".into()));
        }
        if let Some(t) = self.tension_cutoff {
            let phi = self.friction_angle_deg.to_radians();
            let apex = if phi > 0.0 { self.cohesion / phi.tan() } else { 1e100 };
            range("tension_cutoff", t, 0.0, apex, true)?;
        }
        if let Some(sc) = &self.softening {
            sc.validate(self)?;
        }
        if mat.plane != Plane::Strain {
            return Err(("type".into(), "= \"mohr_coulomb\" needs plane strain (model.plane = \"strain\"): its return uses the out-of-plane stress".into()));
        }
        Ok(())
    }
    /// Strength reduction (`flem fos`): `c / f`, `tan(phi) / f`, the dilation angle capped at
    /// the reduced friction angle (`psi <= phi`); the tension cut-off is kept (the apex
    /// `c cot(phi)` does not change). With softening, every entry of the tables is reduced the
    /// same way (the residual strength too), the strains kept.
    fn strength_reduced(&self, f: f64) -> Option<Box<dyn LawCfg>> {
        let phi = (self.friction_angle_deg.to_radians().tan() / f).atan().to_degrees();
        let softening = self.softening.as_ref().map(|sc| sc.reduced(f, self.dilation_angle_deg, phi));
        Some(Box::new(MohrCoulombCfg { cohesion: self.cohesion / f, friction_angle_deg: phi, dilation_angle_deg: self.dilation_angle_deg.min(phi), tension_cutoff: self.tension_cutoff, softening }))
    }
    fn build(&self, region: &str, mat: Material, opts: StatefulOpts, elems: &RegionElems) -> Vec<Box<dyn Block>> {
        match &self.softening {
            None => build_stateful(self.law(&mat), region, mat, opts, elems),
            Some(sc) => build_stateful(MohrCoulombSoftening::new(self, sc, &mat), region, mat, opts, elems),
        }
    }
    fn clone_box(&self) -> Box<dyn LawCfg> {
        Box::new(self.clone())
    }
}

#[cfg(test)]
#[path = "mohr_coulomb_tests.rs"]
mod tests;
