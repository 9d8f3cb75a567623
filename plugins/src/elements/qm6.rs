//! `qm6` (ours): the bilinear quadrilateral with incompatible modes (Wilson-Taylor QM6), which
//! does not lock in bending.
//!
//! **What.** Q4's displacement field plus two internal "bubble" modes per direction that vanish
//! at the corners (Wilson, Taylor, Doherty & Ghaboussi 1973, "Incompatible displacement models";
//! Taylor, Beresford & Wilson 1976, "A non-conforming element for stress analysis"):
//!
//!     u(xi) = sum_a N_a(xi) u_a + P_1(xi) alpha_1 + P_2(xi) alpha_2,
//!     P_1 = 1 - xi^2,   P_2 = 1 - eta^2   (alpha_k = [alpha_kx, alpha_ky]).
//!
//! A Q4 bent by a moment needs a curved edge; the bubbles supply it, so the spurious shear
//! strain that makes Q4 too stiff in bending (shear locking) vanishes on rectangles.
//!
//! **Taylor's correction (passes the patch test on any convex quadrilateral).** The bubbles'
//! Cartesian derivatives use the Jacobian at the element centre, `J0`, and the factor
//! `det J0 / det J(xi)`:
//!
//!     [dP/dx, dP/dy]^T = (det J0 / det J(xi)) J0^-1 [dP/dxi, dP/deta]^T,
//!
//! so that `integral G dA = det J0 J0^-1 sum_gp w [dP/dxi, dP/deta] = 0` with 2 x 2 Gauss
//! points: a constant strain does no work on the modes, their parameters stay 0 and the element
//! reproduces any constant strain exactly. This is the same element as Simo & Rifai's (1990)
//! enhanced assumed strain Q1/E4 for linear elasticity.
//!
//! **Condensation (per element, once).** With `B` (3 x 8) Q4's strain-displacement matrix,
//! `G` (3 x 4) the corrected bubble strains and `c = w det J t` at each of the 2 x 2 Gauss points,
//!
//!     K_uu = sum c B^T D B,  K_ua = sum c B^T D G,  K_aa = sum c G^T D G,
//!     alpha = H u,  H = -K_aa^-1 K_au,   K = K_uu + K_ua H  (= K_uu - K_ua K_aa^-1 K_au).
//!
//! `K` (8 x 8, symmetric: stored as its 36 upper-triangle values, symmetrised) and `H` (4 x 8,
//! the stress recovery) depend on the geometry and the material only. For linear elasticity the
//! condensed element is exactly linear, so the explicit step computes `f = K u` from the
//! precomputed `K` (the blocked kernel below: 64 multiply-adds per element on 288 bytes) rather
//! than re-solving the 4 internal parameters each step (Q4's 4-point integrand twice, plus a
//! 4 x 8 product: about 3 x the flops for 80 + 256 bytes). `flem bench step --kinds` measures
//! the choice (docs/elements.md). The implicit check uses the same `K` (`stiffness`), the
//! stable step bounds the same `K` with Q4's lumped mass.
//!
//! **Stress.** At natural point `xi`: `sigma = D (B(xi) u + G(xi) H u)`: with the enhanced
//! field, at the 0.9999 corners for the nodal stress (paper 2.1), at the Gauss points for the
//! nonlocal check. Mass, corners, edges, fans and splits are Q4's: only the element's interior
//! differs, and the modes are internal to each element, so a split changes nothing of them.
//!
//! Units: those of the scene (consistent); plane strain or plane stress through `D`
//! (`[model] plane`). Co-rotational blocks work on it unchanged.
//!
//! ```toml
//! [[material]]
//! young_modulus = 1000.0
//! poisson_ratio = 0.25
//! density = 1.0
//! element = "qm6"
//! ```
use flem_core::element::block::Block;
use flem_core::element::kernel::{Blocked, LANES};
use flem_core::element::law::{LinearElastic, MaterialLaw, RegionElems, StatefulOpts};
use flem_core::element::registry::ElementKind;
use flem_core::element::stateful::{Enhanced, StatefulBlock};
use flem_core::element::{gradients, Dmat, Material, Shape};

use super::Q4;
use flem_core::mesh::CellKind;

/// The incompatible-mode quadrilateral (see the module doc).
#[derive(Copy, Clone, Default, Debug)]
pub struct Qm6;

inventory::submit! { ElementKind::new::<Qm6, 4>("ours: Q4 with incompatible modes (Wilson-Taylor QM6), condensed per element; no bending locking").with_stateful_elastic(stateful::<LinearElastic>) }

impl Shape<4> for Qm6 {
    const KIND: CellKind = CellKind::Q4;
    const CORNERS: [[f64; 2]; 4] = <Q4 as Shape<4>>::CORNERS;
    const GAUSS: &'static [([f64; 2], f64)] = <Q4 as Shape<4>>::GAUSS;
    #[inline(always)]
    fn n(xi: [f64; 2]) -> [f64; 4] {
        <Q4 as Shape<4>>::n(xi)
    }
    #[inline(always)]
    fn dn(xi: [f64; 2]) -> [[f64; 2]; 4] {
        <Q4 as Shape<4>>::dn(xi)
    }
}

/// Index of `K[i][j]` in the 36 stored upper-triangle values (row-major upper triangle).
const SYM: [[usize; 8]; 8] = {
    let mut m = [[0usize; 8]; 8];
    let mut k = 0;
    let mut i = 0;
    while i < 8 {
        let mut j = i;
        while j < 8 {
            m[i][j] = k;
            m[j][i] = k;
            k += 1;
            j += 1;
        }
        i += 1;
    }
    m
};

/// The condensed stiffness of `Qm6`'s pack: `k[SYM[i][j]][lane]`.
#[derive(Copy, Clone, Debug)]
#[repr(C, align(64))]
pub struct Qm6Pack {
    k: [[f64; LANES]; 36],
}

/// Strain rows of a gradient: `eps = sum_a B_a u_a`, `B_a = [[gx, 0], [0, gy], [gy, gx]]`.
type Bmat<const M: usize> = [[[f64; 2]; 3]; M];

fn bmat<const M: usize>(g: &[[f64; 2]; M]) -> Bmat<M> {
    std::array::from_fn(|a| [[g[a][0], 0.0], [0.0, g[a][1]], [g[a][1], g[a][0]]])
}

/// Q4's `B` and the corrected bubble `G` (as two "nodes") at `xi`, and `det J(xi)`.
fn b_and_g(x: &[[f64; 2]; 4], xi: [f64; 2]) -> (Bmat<4>, Bmat<2>, f64) {
    let (g, det) = gradients::<Q4, 4>(x, xi);
    let gb = bubble_gradients(x, xi, det);
    (bmat(&g), bmat(&gb), det)
}

/// The two bubbles' Cartesian gradients at `xi` with Taylor's correction (`det` = det J(xi)).
fn bubble_gradients(x: &[[f64; 2]; 4], xi: [f64; 2], det: f64) -> [[f64; 2]; 2] {
    // J0 at the centre: rows d/dxi, d/deta of (x, y).
    let dn0 = <Q4 as Shape<4>>::dn([0.0, 0.0]);
    let (mut j11, mut j12, mut j21, mut j22) = (0.0, 0.0, 0.0, 0.0);
    for a in 0..4 {
        j11 += dn0[a][0] * x[a][0];
        j12 += dn0[a][0] * x[a][1];
        j21 += dn0[a][1] * x[a][0];
        j22 += dn0[a][1] * x[a][1];
    }
    // (det J0 / det J) J0^-1 = adj J0 / det J (Taylor's correction).
    let s = 1.0 / det;
    let nat = [[-2.0 * xi[0], 0.0], [0.0, -2.0 * xi[1]]];
    std::array::from_fn(|k| {
        let [dxi, deta] = nat[k];
        [s * (j22 * dxi - j12 * deta), s * (-j21 * dxi + j11 * deta)]
    })
}

/// The element's modes for the stateful block (`StatefulBlock::with_enhanced`): `H` of the
/// elastic condensation (`matrices`) and the corrected bubble gradients at the 2 x 2 points.
pub fn enhanced(x: &[[f64; 2]; 4], d: &Dmat, t: f64) -> Enhanced<4> {
    let (_, h) = matrices(x, d, t);
    Enhanced {
        h: std::array::from_fn(|m| std::array::from_fn(|a| [h[m][2 * a], h[m][2 * a + 1]])),
        g: std::array::from_fn(|k| {
            let xi = <Q4 as Shape<4>>::GAUSS[k].0;
            bubble_gradients(x, xi, gradients::<Q4, 4>(x, xi).1)
        }),
    }
}

/// The stateful qm6 block of law `L` over the region's quadrilaterals (`None` without any, or
/// with `[solver] large_strain`, which has no modes: `Model::new` then refuses naming
/// `material[i].element`).
pub fn stateful<L: MaterialLaw>(law: L, region: &str, mat: Material, opts: StatefulOpts, elems: &RegionElems) -> Option<Box<dyn Block>> {
    if opts.large_strain || elems.q4.is_empty() {
        return None;
    }
    let mut b = StatefulBlock::<Qm6, L, 4>::new(region.to_string(), mat, law, opts).with_enhanced(<Qm6 as Blocked<4>>::NAME, enhanced);
    for &(e, x, c) in &elems.q4 {
        b.push(e, x, c);
    }
    Some(Box::new(b))
}

fn dfull(d: &Dmat) -> [[f64; 3]; 3] {
    [[d.d11, d.d12, 0.0], [d.d12, d.d11, 0.0], [0.0, 0.0, d.d33]]
}

/// `K` (8 x 8, symmetric) and `H` (4 x 8) of one element.
pub fn matrices(x: &[[f64; 2]; 4], d: &Dmat, t: f64) -> ([[f64; 8]; 8], [[f64; 8]; 4]) {
    let dm = dfull(d);
    let (mut kuu, mut kua, mut kaa) = ([[0.0; 8]; 8], [[0.0; 4]; 8], [[0.0; 4]; 4]);
    for &(xi, w) in <Q4 as Shape<4>>::GAUSS {
        let (b, g, det) = b_and_g(x, xi);
        let c = w * det * t;
        // Columns of B (8) and G (4) as strain vectors.
        let bc: [[f64; 3]; 8] = std::array::from_fn(|j| std::array::from_fn(|r| b[j / 2][r][j % 2]));
        let gc: [[f64; 3]; 4] = std::array::from_fn(|j| std::array::from_fn(|r| g[j / 2][r][j % 2]));
        let db: [[f64; 3]; 8] = std::array::from_fn(|j| std::array::from_fn(|r| (0..3).map(|q| dm[r][q] * bc[j][q]).sum()));
        let dg: [[f64; 3]; 4] = std::array::from_fn(|j| std::array::from_fn(|r| (0..3).map(|q| dm[r][q] * gc[j][q]).sum()));
        let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        for i in 0..8 {
            for j in 0..8 {
                kuu[i][j] += c * dot(&bc[i], &db[j]);
            }
            for j in 0..4 {
                kua[i][j] += c * dot(&bc[i], &dg[j]);
            }
        }
        for i in 0..4 {
            for j in 0..4 {
                kaa[i][j] += c * dot(&gc[i], &dg[j]);
            }
        }
    }
    let kaa = nalgebra::Matrix4::from_fn(|i, j| 0.5 * (kaa[i][j] + kaa[j][i]));
    let kau = nalgebra::SMatrix::<f64, 4, 8>::from_fn(|i, j| kua[j][i]);
    // K_aa is positive definite for a convex element (the modes carry strain energy).
    let h = match kaa.cholesky() {
        Some(ch) => -ch.solve(&kau),
        None => nalgebra::SMatrix::<f64, 4, 8>::zeros(),
    };
    let mut k = [[0.0; 8]; 8];
    for i in 0..8 {
        for j in 0..8 {
            k[i][j] = kuu[i][j] + (0..4).map(|m| kua[i][m] * h[(m, j)]).sum::<f64>();
        }
    }
    for i in 0..8 {
        for j in i + 1..8 {
            let s = 0.5 * (k[i][j] + k[j][i]);
            k[i][j] = s;
            k[j][i] = s;
        }
    }
    (k, std::array::from_fn(|m| std::array::from_fn(|j| h[(m, j)])))
}

impl Blocked<4> for Qm6 {
    const NAME: &'static str = "qm6";
    type Pack = Qm6Pack;
    type Extra = ();
    /// 4 x 8 `H` (alpha = H u), row-major.
    const RECOVERY_LEN: usize = 32;
    fn pack(x: &[[[f64; 2]; 4]], d: &Dmat, t: f64) -> Qm6Pack {
        let mut p = Qm6Pack { k: [[0.0; LANES]; 36] };
        for (l, e) in x.iter().enumerate().take(LANES) {
            let (k, _) = matrices(e, d, t);
            for i in 0..8 {
                for j in i..8 {
                    p.k[SYM[i][j]][l] = k[i][j];
                }
            }
        }
        p
    }
    fn scaled_d(d: &Dmat, t: f64) -> [f64; 3] {
        // Unused by `forces` (D and t are inside the packed K).
        [d.d11 * t, d.d12 * t, d.d33 * t]
    }
    #[inline(always)]
    fn forces(p: &Qm6Pack, _d: &[f64; 3], u: &[[[f64; LANES]; 2]; 4], f: &mut [[[f64; LANES]; 2]; 4]) {
        let uu: [[f64; LANES]; 8] = std::array::from_fn(|j| u[j / 2][j % 2]);
        for i in 0..8 {
            let mut acc = [0.0; LANES];
            for j in 0..8 {
                let kk = &p.k[SYM[i][j]];
                for l in 0..LANES {
                    acc[l] += kk[l] * uu[j][l];
                }
            }
            f[i / 2][i % 2] = acc;
        }
    }
    fn force_ref(x: &[[f64; 2]; 4], u: &[[f64; 2]; 4], d: &Dmat, t: f64) -> [[f64; 2]; 4] {
        let (k, _) = matrices(x, d, t);
        let mut f = [[0.0; 2]; 4];
        for i in 0..8 {
            let mut acc = 0.0;
            for j in 0..8 {
                acc += k[i][j] * u[j / 2][j % 2];
            }
            f[i / 2][i % 2] = acc;
        }
        f
    }
    fn stiffness(x: &[[f64; 2]; 4], d: &Dmat, t: f64, out: &mut [f64]) {
        let (k, _) = matrices(x, d, t);
        for i in 0..8 {
            out[i * 8..i * 8 + 8].copy_from_slice(&k[i]);
        }
    }
    fn recovery(x: &[[f64; 2]; 4], d: &Dmat, t: f64, out: &mut [f64]) {
        let (_, h) = matrices(x, d, t);
        for m in 0..4 {
            out[m * 8..m * 8 + 8].copy_from_slice(&h[m]);
        }
    }
    fn stress(x: &[[f64; 2]; 4], u: &[[f64; 2]; 4], d: &Dmat, xi: [f64; 2], rec: &[f64]) -> [f64; 3] {
        let (b, g, _) = b_and_g(x, xi);
        let mut alpha = [[0.0; 2]; 2];
        for m in 0..4 {
            alpha[m / 2][m % 2] = (0..8).map(|j| rec[m * 8 + j] * u[j / 2][j % 2]).sum();
        }
        let mut eps = [0.0; 3];
        for r in 0..3 {
            for a in 0..4 {
                eps[r] += b[a][r][0] * u[a][0] + b[a][r][1] * u[a][1];
            }
            for k in 0..2 {
                eps[r] += g[k][r][0] * alpha[k][0] + g[k][r][1] * alpha[k][1];
            }
        }
        d.stress(eps)
    }
}
