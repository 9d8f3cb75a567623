//! `t3`: the constant-strain triangle (one Gauss point), the default for triangle cells.
//!
//! **Shape functions** (corners `(0,0) (1,0) (0,1)`): `N = [1 - xi - eta, xi, eta]`; the strain
//! is constant, so the nodal stress is taken at the centroid (`element::corner_xi`). Internal
//! force `f_a = B_a^T D B u A t`; row-sum lumped mass (`A t rho / 3` per corner). Units: the
//! scene's (consistent).
//!
//! **Blocked layout** (`flem_core::element::kernel`): the constant Jacobian (4 values) and
//! `1 / det J`: 5 f64 = 40 bytes per element; the force is Q4's Gauss-point integrand
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

#[derive(Copy, Clone, Debug)]
#[repr(C, align(64))]
pub struct T3Pack {
    j11: [f64; LANES],
    j12: [f64; LANES],
    j21: [f64; LANES],
    j22: [f64; LANES],
    inv: [f64; LANES],
}

impl Blocked<3> for T3 {
    const NAME: &'static str = "t3";
    type Pack = T3Pack;
    fn pack(x: &[[[f64; 2]; 3]], _d: &Dmat, _t: f64) -> T3Pack {
        let z = [0.0; LANES];
        let mut p = T3Pack { j11: z, j12: z, j21: z, j22: z, inv: z };
        for (l, e) in x.iter().enumerate().take(LANES) {
            let (j11, j12, j21, j22) = (e[1][0] - e[0][0], e[1][1] - e[0][1], e[2][0] - e[0][0], e[2][1] - e[0][1]);
            (p.j11[l], p.j12[l], p.j21[l], p.j22[l]) = (j11, j12, j21, j22);
            p.inv[l] = 1.0 / (j11 * j22 - j12 * j21);
        }
        p
    }
    fn scaled_d(d: &Dmat, t: f64) -> [f64; 3] {
        // One Gauss point of weight 1/2.
        [d.d11 * t * 0.5, d.d12 * t * 0.5, d.d33 * t * 0.5]
    }
    #[inline(always)]
    fn forces(p: &T3Pack, d: &[f64; 3], u: &[[[f64; LANES]; 2]; 3], f: &mut [[[f64; LANES]; 2]; 3]) {
        for l in 0..LANES {
            let (uxs, uxe) = (u[1][0][l] - u[0][0][l], u[2][0][l] - u[0][0][l]);
            let (uys, uye) = (u[1][1][l] - u[0][1][l], u[2][1][l] - u[0][1][l]);
            let (pxs, pxe, pys, pye) = parent_stress([p.j11[l], p.j12[l], p.j21[l], p.j22[l]], p.inv[l], [uxs, uxe, uys, uye], d);
            f[0][0][l] = -pxs - pxe;
            f[1][0][l] = pxs;
            f[2][0][l] = pxe;
            f[0][1][l] = -pys - pye;
            f[1][1][l] = pys;
            f[2][1][l] = pye;
        }
    }
}
