//! `t3`: the constant-strain triangle (one Gauss point), the default for triangle cells.
//!
//! **Shape functions** (corners `(0,0) (1,0) (0,1)`): `N = [1 - xi - eta, xi, eta]`; the strain
//! is constant, so the nodal stress is taken at the centroid (`element::corner_xi`). Internal
//! force `f_a = B_a^T D B u A t`; row-sum lumped mass (`A t rho / 3` per corner). Units: the
//! scene's (consistent).
//!
//! **Blocked layout** (`flem_core::element::kernel`): the constant Jacobian (4 values: 32 bytes
//! per element; `1 / det J` is computed in the kernel, issue 24: it was a fifth stored value,
//! still kept for a pack with a degenerate element); the force is Q4's Gauss-point integrand
//! (`parent_stress`) at the one point, weight 1/2 folded into the D matrix.
//!
//! ```toml
//! [[material]]
//! young_modulus = 1000.0
//! poisson_ratio = 0.25
//! density = 1.0
//! element = "t3"
//! ```
use flem_core::element::kernel::{Blocked, LANES};
use flem_core::element::registry::ElementKind;
use flem_core::element::{Dmat, Shape};
use flem_core::mesh::CellKind;

use super::parent_stress;

/// Constant-strain triangle, one point.
#[derive(Copy, Clone, Default, Debug)]
pub struct T3;

inventory::submit! { ElementKind::new::<T3, 3>("constant-strain triangle") }

impl Shape<3> for T3 {
    const KIND: CellKind = CellKind::T3;
    const CORNERS: [[f64; 2]; 3] = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
    const GAUSS: &'static [([f64; 2], f64)] = &[([1.0 / 3.0, 1.0 / 3.0], 0.5)];
    #[inline(always)]
    fn n(xi: [f64; 2]) -> [f64; 3] {
        [1.0 - xi[0] - xi[1], xi[0], xi[1]]
    }
    #[inline(always)]
    fn dn(_xi: [f64; 2]) -> [[f64; 2]; 3] {
        [[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]]
    }
}

/// The Jacobian of `LANES` elements (32 bytes each); `1 / det J` is computed in `forces` from
/// the same expression as `pack`'s, so that it is the same number (issue 24: it was stored).
#[derive(Copy, Clone, Debug)]
#[repr(C, align(64))]
pub struct T3Pack {
    j11: [f64; LANES],
    j12: [f64; LANES],
    j21: [f64; LANES],
    j22: [f64; LANES],
}

/// `1 / det J`, kept only for a pack with a degenerate element (`det J` zero or not finite),
/// whose stored inverse `forces` must use as before (the run then stops on non-finite forces).
#[derive(Copy, Clone, Debug)]
#[repr(C, align(64))]
pub struct T3Extra {
    inv: [f64; LANES],
}

/// The pack of `x`, its inverse determinants, and whether every one is finite.
fn full_pack(x: &[[[f64; 2]; 3]]) -> (T3Pack, T3Extra, bool) {
    let z = [0.0; LANES];
    let (mut p, mut e) = (T3Pack { j11: z, j12: z, j21: z, j22: z }, T3Extra { inv: z });
    for (l, el) in x.iter().enumerate().take(LANES) {
        let (j11, j12, j21, j22) = (el[1][0] - el[0][0], el[1][1] - el[0][1], el[2][0] - el[0][0], el[2][1] - el[0][1]);
        (p.j11[l], p.j12[l], p.j21[l], p.j22[l]) = (j11, j12, j21, j22);
        e.inv[l] = 1.0 / (j11 * j22 - j12 * j21);
    }
    let finite = e.inv[..x.len().min(LANES)].iter().all(|v| v.is_finite());
    (p, e, finite)
}

impl T3 {
    #[inline(always)]
    fn lanes(p: &T3Pack, inv: impl Fn(usize) -> f64, d: &[f64; 3], u: &[[[f64; LANES]; 2]; 3], f: &mut [[[f64; LANES]; 2]; 3]) {
        for l in 0..LANES {
            let (uxs, uxe) = (u[1][0][l] - u[0][0][l], u[2][0][l] - u[0][0][l]);
            let (uys, uye) = (u[1][1][l] - u[0][1][l], u[2][1][l] - u[0][1][l]);
            let (pxs, pxe, pys, pye) = parent_stress([p.j11[l], p.j12[l], p.j21[l], p.j22[l]], inv(l), [uxs, uxe, uys, uye], d);
            f[0][0][l] = -pxs - pxe;
            f[1][0][l] = pxs;
            f[2][0][l] = pxe;
            f[0][1][l] = -pys - pye;
            f[1][1][l] = pys;
            f[2][1][l] = pye;
        }
    }
}

impl Blocked<3> for T3 {
    const NAME: &'static str = "t3";
    type Pack = T3Pack;
    type Extra = T3Extra;
    fn pack(x: &[[[f64; 2]; 3]], _d: &Dmat, _t: f64) -> T3Pack {
        full_pack(x).0
    }
    fn extra(x: &[[[f64; 2]; 3]], _d: &Dmat, _t: f64) -> Option<T3Extra> {
        let (_, e, finite) = full_pack(x);
        (!finite).then_some(e)
    }
    fn scaled_d(d: &Dmat, t: f64) -> [f64; 3] {
        // One Gauss point of weight 1/2.
        [d.d11 * t * 0.5, d.d12 * t * 0.5, d.d33 * t * 0.5]
    }
    #[inline(always)]
    fn forces(p: &T3Pack, d: &[f64; 3], u: &[[[f64; LANES]; 2]; 3], f: &mut [[[f64; LANES]; 2]; 3]) {
        // An empty lane (all zero) gives zero force.
        let inv = |l: usize| {
            let det = p.j11[l] * p.j22[l] - p.j12[l] * p.j21[l];
            if det == 0.0 {
                0.0
            } else {
                1.0 / det
            }
        };
        Self::lanes(p, inv, d, u, f)
    }
    #[inline(always)]
    fn forces_extra(p: &T3Pack, e: &T3Extra, d: &[f64; 3], u: &[[[f64; LANES]; 2]; 3], f: &mut [[[f64; LANES]; 2]; 3]) {
        Self::lanes(p, |l| e.inv[l], d, u, f)
    }
}
