//! `q4`: the bilinear quadrilateral with 2 x 2 Gauss points, the paper's element and the
//! default for quadrilateral cells.
//!
//! **Shape functions** (corners `(-1,-1) (1,-1) (1,1) (-1,1)`): `N_a = (1 + xi_a xi)(1 + eta_a eta) / 4`.
//! Internal force `f_a = sum_gp B_a^T D B u w det J t` (2 x 2 Gauss points at `+-1/sqrt 3`,
//! weights 1); stress `sigma = D B(xi) u`, at the corners scaled by 0.9999 for the nodal stress
//! (paper 2.1, `element::corner_xi`); row-sum lumped mass. Units: the scene's (consistent).
//! Locks in bending (Cook's membrane, docs/elements.md): `qm6` is the remedy.
//!
//! **Blocked layout** (`flem_core::element::kernel`: packs of `LANES` elements, structure of
//! arrays). The Jacobian is linear in the natural coordinates, `dx/dxi = a + eta h`,
//! `dx/deta = b + xi h` (with `a, b, h` the three corner combinations of x and y: 6 values),
//! plus `1 / det J` at the 4 Gauss points: 10 f64 = 80 bytes per element. With
//! `adj J = det J * J^-1`, the force of a Gauss point is
//! `f_a = w t (adj J^T dN_a)^T sigma`, `sigma = D (adj J grad_xi u) / det J`, which is exactly
//! `element::internal_force` rearranged (equal to round-off, tested to 1e-12 relative). The
//! thickness and the Gauss weight are folded into the D matrix.
//!
//! ```toml
//! [[material]]
//! young_modulus = 1000.0
//! poisson_ratio = 0.25
//! density = 1.0
//! element = "q4"
//! ```
use flem_core::element::kernel::{Blocked, LANES};
use flem_core::element::registry::ElementKind;
use flem_core::element::{Dmat, Shape};
use flem_core::mesh::CellKind;

use super::parent_stress;

/// Bilinear quadrilateral, 2 x 2 Gauss points.
#[derive(Copy, Clone, Default, Debug)]
pub struct Q4;

inventory::submit! { ElementKind::new::<Q4, 4>("bilinear quadrilateral, 2 x 2 Gauss points (the paper's element; locks in bending)") }

impl Shape<4> for Q4 {
    const KIND: CellKind = CellKind::Q4;
    const CORNERS: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    const GAUSS: &'static [([f64; 2], f64)] = &[([-G, -G], 1.0), ([G, -G], 1.0), ([G, G], 1.0), ([-G, G], 1.0)];
    #[inline(always)]
    fn n(xi: [f64; 2]) -> [f64; 4] {
        let c = Self::CORNERS;
        std::array::from_fn(|a| 0.25 * (1.0 + c[a][0] * xi[0]) * (1.0 + c[a][1] * xi[1]))
    }
    #[inline(always)]
    fn dn(xi: [f64; 2]) -> [[f64; 2]; 4] {
        let c = Self::CORNERS;
        std::array::from_fn(|a| [0.25 * c[a][0] * (1.0 + c[a][1] * xi[1]), 0.25 * c[a][1] * (1.0 + c[a][0] * xi[0])])
    }
}

#[derive(Copy, Clone, Debug)]
#[repr(C, align(64))]
pub struct Q4Pack {
    ax: [f64; LANES],
    bx: [f64; LANES],
    hx: [f64; LANES],
    ay: [f64; LANES],
    by: [f64; LANES],
    hy: [f64; LANES],
    inv: [[f64; LANES]; 4],
}

const G: f64 = 0.577_350_269_189_625_8;
/// Gauss points of Q4 in the order of `Q4::GAUSS`.
const Q4_GP: [[f64; 2]; 4] = [[-G, -G], [G, -G], [G, G], [-G, G]];

/// The three corner combinations of a bilinear field: `d/dxi = a + eta h`, `d/deta = b + xi h`.
#[inline(always)]
fn abh(v0: f64, v1: f64, v2: f64, v3: f64) -> (f64, f64, f64) {
    (0.25 * ((v1 - v0) + (v2 - v3)), 0.25 * ((v3 - v0) + (v2 - v1)), 0.25 * ((v0 - v1) + (v2 - v3)))
}

impl Blocked<4> for Q4 {
    const NAME: &'static str = "q4";
    type Pack = Q4Pack;
    fn pack(x: &[[[f64; 2]; 4]], _d: &Dmat, _t: f64) -> Q4Pack {
        let z = [0.0; LANES];
        let mut p = Q4Pack { ax: z, bx: z, hx: z, ay: z, by: z, hy: z, inv: [z; 4] };
        for (l, e) in x.iter().enumerate().take(LANES) {
            let (ax, bx, hx) = abh(e[0][0], e[1][0], e[2][0], e[3][0]);
            let (ay, by, hy) = abh(e[0][1], e[1][1], e[2][1], e[3][1]);
            (p.ax[l], p.bx[l], p.hx[l], p.ay[l], p.by[l], p.hy[l]) = (ax, bx, hx, ay, by, hy);
            for (g, &[xi, eta]) in Q4_GP.iter().enumerate() {
                let (j11, j12, j21, j22) = (ax + eta * hx, ay + eta * hy, bx + xi * hx, by + xi * hy);
                p.inv[g][l] = 1.0 / (j11 * j22 - j12 * j21);
            }
        }
        p
    }
    fn scaled_d(d: &Dmat, t: f64) -> [f64; 3] {
        [d.d11 * t, d.d12 * t, d.d33 * t]
    }
    #[inline(always)]
    fn forces(p: &Q4Pack, d: &[f64; 3], u: &[[[f64; LANES]; 2]; 4], f: &mut [[[f64; LANES]; 2]; 4]) {
        for l in 0..LANES {
            let (aux, bux, hux) = abh(u[0][0][l], u[1][0][l], u[2][0][l], u[3][0][l]);
            let (auy, buy, huy) = abh(u[0][1][l], u[1][1][l], u[2][1][l], u[3][1][l]);
            let (ax, bx, hx, ay, by, hy) = (p.ax[l], p.bx[l], p.hx[l], p.ay[l], p.by[l], p.hy[l]);
            // Sums over Gauss points of P (S) and of P times the other coordinate (T).
            let (mut sxs, mut txs, mut sxe, mut txe) = (0.0, 0.0, 0.0, 0.0);
            let (mut sys, mut tys, mut sye, mut tye) = (0.0, 0.0, 0.0, 0.0);
            for (g, &[xi, eta]) in Q4_GP.iter().enumerate() {
                let (j11, j12, j21, j22) = (ax + eta * hx, ay + eta * hy, bx + xi * hx, by + xi * hy);
                let (uxs, uxe, uys, uye) = (aux + eta * hux, bux + xi * hux, auy + eta * huy, buy + xi * huy);
                let (pxs, pxe, pys, pye) = parent_stress([j11, j12, j21, j22], p.inv[g][l], [uxs, uxe, uys, uye], d);
                sxs += pxs;
                txs += eta * pxs;
                sxe += pxe;
                txe += xi * pxe;
                sys += pys;
                tys += eta * pys;
                sye += pye;
                tye += xi * pye;
            }
            // f_a = 1/4 [xi_a (S_s + eta_a T_s) + eta_a (S_e + xi_a T_e)], corners (-,-) (+,-) (+,+) (-,+).
            f[0][0][l] = 0.25 * (-(sxs - txs) - (sxe - txe));
            f[1][0][l] = 0.25 * ((sxs - txs) - (sxe + txe));
            f[2][0][l] = 0.25 * ((sxs + txs) + (sxe + txe));
            f[3][0][l] = 0.25 * (-(sxs + txs) + (sxe - txe));
            f[0][1][l] = 0.25 * (-(sys - tys) - (sye - tye));
            f[1][1][l] = 0.25 * ((sys - tys) - (sye + tye));
            f[2][1][l] = 0.25 * ((sys + tys) + (sye + tye));
            f[3][1][l] = 0.25 * (-(sys + tys) + (sye - tye));
        }
    }
}
