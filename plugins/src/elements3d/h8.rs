//! `h8` (ours as a default: the paper has no 3D): the 8-node brick with incompatible modes
//! (Wilson-Taylor, the 3D form of `qm6`), which does not lock in bending; and `h8_full`, the
//! plain trilinear brick with 2 x 2 x 2 Gauss points (the 3D twin of `q4`, which locks).
//!
//! **What.** The trilinear field plus three internal "bubble" modes per direction that vanish
//! at the corners (Wilson, Taylor, Doherty & Ghaboussi 1973, "Incompatible displacement
//! models", in *Numerical and Computer Methods in Structural Mechanics*, pp. 43-57; Taylor,
//! Beresford & Wilson 1976, "A non-conforming element for stress analysis", IJNME 10,
//! 1211-1219):
//!
//!     u(xi) = sum_a N_a(xi) u_a + sum_m P_m(xi) alpha_m,
//!     P_1 = 1 - xi^2,   P_2 = 1 - eta^2,   P_3 = 1 - zeta^2   (alpha_m = [alpha_mx, _my, _mz]),
//!
//! nine internal parameters. A brick bent by a moment needs curved edges; the bubbles supply
//! them, so the parasitic shear strain that makes `h8_full` too stiff in bending (shear locking)
//! vanishes on rectangular bricks (a pure-bending state is reproduced exactly).
//!
//! **Taylor's correction (the patch test on any convex brick).** The bubbles' Cartesian
//! gradients use the Jacobian at the element centre, `J0`, and `det J0 / det J(xi)`:
//!
//!     grad_x P_m = (det J0 / det J(xi)) J0^-1 grad_xi P_m = adj(J0) grad_xi P_m / det J(xi),
//!
//! so that `integral grad_x P_m dV = adj(J0) sum_gp w grad_xi P_m(xi_gp) = 0` with 2 x 2 x 2
//! Gauss points (`sum_gp w (-2 xi_gp) = 0`): a constant stress does no work on the modes, their
//! parameters stay 0 under a linear displacement field and the element passes the patch test on
//! distorted meshes (tests/solid3.rs, to 1e-12). For linear elasticity this is the same element
//! as Simo & Rifai's (1990) enhanced assumed strain brick with 9 modes.
//!
//! **Condensation (per element).** With `B` (6 x 24) the trilinear strain-displacement matrix,
//! `G` (6 x 9) the corrected bubble strains and `c = w det J` at each Gauss point,
//!
//!     K_uu = sum c B^T D B,  K_ua = sum c B^T D G,  K_aa = sum c G^T D G,
//!     alpha = H u,  H = -K_aa^-1 K_au,   K = K_uu + K_ua H  (= K_uu - K_ua K_aa^-1 K_au).
//!
//! The stress at a natural point is `sigma = D (B(xi) u + G(xi) alpha)`: at the 0.9999 corners
//! for the nodal stress (paper 2.1, read in 3D, as `qm6`), at the Gauss points for a nonlocal
//! check. Units: the scene's (consistent). The modes are internal to an element: corners, faces,
//! mass (trilinear, lumped by row sums) and a split are the brick's.
//!
//! **Fast form** (for an explicit kernel, no allocation): [`internal_force`] computes the
//! corner forces from the 24 coordinates and the displacements: at the 8 Gauss points the
//! Jacobian, the gradients and the trilinear strain `B u`, then `r = sum c G^T D B u`, the 9
//! parameters `alpha = -K_aa^-1 r` (a 9 x 9 Cholesky on the stack, `K_aa` from the same Gauss
//! loop) and `f = sum c B^T D (B u + G alpha)`. Or, storing 300 values per element, the
//! condensed `K` of [`matrices`] (`f = K u`, 576 multiply-adds), as `qm6` does in 2D.
//!
//! ```toml
//! [[material]]
//! young_modulus = 210e3
//! poisson_ratio = 0.3
//! density = 7.85e-9
//! element = "h8"
//! ```
use flem_core::element::shape3::{bt_stress, det_adj, gradients3, jacobian, mul3, strain3, Dmat3, Hex8, Shape3};
use nalgebra::{SMatrix, SVector};

/// Per-Gauss-point geometry of a brick: Cartesian gradients of the 8 shape functions and of
/// the 3 bubbles (Taylor-corrected), and `c = w det J`.
#[derive(Copy, Clone, Debug)]
pub struct H8Geo {
    pub g: [[[f64; 3]; 8]; 8],
    pub gm: [[[f64; 3]; 3]; 8],
    pub c: [f64; 8],
}

/// `adj(J0)`, the adjugate of the Jacobian at the centre.
#[inline(always)]
fn adj_j0(x: &[[f64; 3]; 8]) -> [[f64; 3]; 3] {
    det_adj(&jacobian(x, &Hex8::dn([0.0; 3]))).1
}

/// The bubbles' Cartesian gradients at `xi` with Taylor's correction (`det` = det J(xi)).
#[inline(always)]
fn bubble_gradients(adj0: &[[f64; 3]; 3], xi: [f64; 3], det: f64) -> [[f64; 3]; 3] {
    let s = 1.0 / det;
    std::array::from_fn(|m| {
        let mut nat = [0.0; 3];
        nat[m] = -2.0 * xi[m];
        mul3(adj0, nat).map(|v| s * v)
    })
}

/// The per-Gauss-point geometry of `x`.
#[inline(always)]
pub fn geometry(x: &[[f64; 3]; 8]) -> H8Geo {
    let adj0 = adj_j0(x);
    let mut geo = H8Geo { g: [[[0.0; 3]; 8]; 8], gm: [[[0.0; 3]; 3]; 8], c: [0.0; 8] };
    for (k, &(xi, w)) in Hex8::GAUSS.iter().enumerate() {
        let (g, det) = gradients3::<Hex8, 8>(x, xi);
        geo.g[k] = g;
        geo.gm[k] = bubble_gradients(&adj0, xi, det);
        geo.c[k] = w * det;
    }
    geo
}

/// `B_a^T D B_b` (3 x 3) of two gradients for the isotropic `D` (engineering shear strains):
/// `lambda a b^T + mu b a^T + mu (a . b) I` (row `i`, column `j`: `lambda a_i b_j + mu a_j b_i
/// + mu delta_ij a . b`).
#[inline(always)]
fn block(a: [f64; 3], b: [f64; 3], d: &Dmat3) -> [[f64; 3]; 3] {
    let ab = d.mu * (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
    std::array::from_fn(|i| std::array::from_fn(|j| d.lambda * a[i] * b[j] + d.mu * a[j] * b[i] + if i == j { ab } else { 0.0 }))
}

/// `K_aa` (9 x 9, modes `3 m + dir`) of a geometry: `sum_gp c G^T D G` block by block.
#[inline(always)]
fn kaa(geo: &H8Geo, d: &Dmat3) -> SMatrix<f64, 9, 9> {
    let mut k = SMatrix::<f64, 9, 9>::zeros();
    for gp in 0..8 {
        let c = geo.c[gp];
        for m in 0..3 {
            for n in m..3 {
                let b = block(geo.gm[gp][m], geo.gm[gp][n], d);
                for p in 0..3 {
                    for q in 0..3 {
                        k[(3 * m + p, 3 * n + q)] += c * b[p][q];
                    }
                }
            }
        }
    }
    // The lower blocks by symmetry (K_nm = K_mn^T).
    for m in 0..3 {
        for n in 0..m {
            for p in 0..3 {
                for q in 0..3 {
                    k[(3 * m + p, 3 * n + q)] = k[(3 * n + q, 3 * m + p)];
                }
            }
        }
    }
    k
}

/// The strain of a unit displacement in direction `q` with gradient `g` (a column of `B`).
#[inline(always)]
fn unit_strain(g: [f64; 3], q: usize, e: &mut [f64; 6]) {
    *e = [0.0; 6];
    let [gx, gy, gz] = g;
    match q {
        0 => {
            e[0] = gx;
            e[3] = gy;
            e[5] = gz;
        }
        1 => {
            e[1] = gy;
            e[3] = gx;
            e[4] = gz;
        }
        _ => {
            e[2] = gz;
            e[4] = gy;
            e[5] = gx;
        }
    }
}

/// The strain of the modes `alpha` with bubble gradients `gm`.
#[inline(always)]
fn mode_strain(gm: &[[f64; 3]; 3], alpha: &[[f64; 3]; 3]) -> [f64; 6] {
    strain3(gm, alpha)
}

/// The 9 internal parameters (`alpha[m] = [a_mx, a_my, a_mz]`) of the trilinear strains `eu`
/// at the Gauss points: the static condensation `alpha = -K_aa^-1 sum_gp c G^T D (B u)`. Zero
/// when `K_aa` is not positive definite (a degenerate cell; the solver refuses those before).
#[inline(always)]
fn alpha_of(geo: &H8Geo, eu: &[[f64; 6]; 8], d: &Dmat3) -> [[f64; 3]; 3] {
    let mut r = SVector::<f64, 9>::zeros();
    for gp in 0..8 {
        let s = d.stress(eu[gp]);
        for m in 0..3 {
            let f = bt_stress(geo.gm[gp][m], &s);
            for p in 0..3 {
                r[3 * m + p] += geo.c[gp] * f[p];
            }
        }
    }
    match kaa(geo, d).cholesky() {
        Some(ch) => {
            let a = ch.solve(&r);
            std::array::from_fn(|m| std::array::from_fn(|p| -a[3 * m + p]))
        }
        None => [[0.0; 3]; 3],
    }
}

/// The 9 internal parameters of the displacement `u` (see `alpha_of`).
#[inline(always)]
pub fn alpha(geo: &H8Geo, u: &[[f64; 3]; 8], d: &Dmat3) -> [[f64; 3]; 3] {
    alpha_of(geo, &std::array::from_fn(|gp| strain3(&geo.g[gp], u)), d)
}

/// Internal corner forces of a precomputed geometry (no allocation; the module doc's fast form).
#[inline(always)]
pub fn forces(geo: &H8Geo, u: &[[f64; 3]; 8], d: &Dmat3) -> [[f64; 3]; 8] {
    let eu: [[f64; 6]; 8] = std::array::from_fn(|gp| strain3(&geo.g[gp], u));
    let al = alpha_of(geo, &eu, d);
    let mut f = [[0.0; 3]; 8];
    for gp in 0..8 {
        let em = mode_strain(&geo.gm[gp], &al);
        let s = d.stress(std::array::from_fn(|r| eu[gp][r] + em[r]));
        let c = geo.c[gp];
        for a in 0..8 {
            let b = bt_stress(geo.g[gp][a], &s);
            for k in 0..3 {
                f[a][k] += c * b[k];
            }
        }
    }
    f
}

/// Internal corner forces from the coordinates (no allocation).
#[inline(always)]
pub fn internal_force(x: &[[f64; 3]; 8], u: &[[f64; 3]; 8], d: &Dmat3) -> [[f64; 3]; 8] {
    forces(&geometry(x), u, d)
}

/// The condensed stiffness `K` (24 x 24, dofs `x0 y0 z0 x1 ...`, symmetric) and the recovery
/// `H` (9 x 24, `alpha = H u`, rows `3 m + dir`).
pub fn matrices(x: &[[f64; 3]; 8], d: &Dmat3) -> ([[f64; 24]; 24], [[f64; 24]; 9]) {
    let geo = geometry(x);
    let mut kuu = [[0.0; 24]; 24];
    let mut kua = [[0.0; 9]; 24];
    for gp in 0..8 {
        let c = geo.c[gp];
        for j in 0..24 {
            let mut e = [0.0; 6];
            unit_strain(geo.g[gp][j / 3], j % 3, &mut e);
            let s = d.stress(e);
            for a in 0..8 {
                let f = bt_stress(geo.g[gp][a], &s);
                for p in 0..3 {
                    kuu[3 * a + p][j] += c * f[p];
                }
            }
            for m in 0..3 {
                let f = bt_stress(geo.gm[gp][m], &s);
                for p in 0..3 {
                    // K_au[3m+p][j] = K_ua[j][3m+p].
                    kua[j][3 * m + p] += c * f[p];
                }
            }
        }
    }
    let ka = kaa(&geo, d);
    let ka = (ka + ka.transpose()) * 0.5;
    let kau = SMatrix::<f64, 9, 24>::from_fn(|i, j| kua[j][i]);
    let h = match ka.cholesky() {
        Some(ch) => -ch.solve(&kau),
        None => SMatrix::<f64, 9, 24>::zeros(),
    };
    let mut k = [[0.0; 24]; 24];
    for i in 0..24 {
        for j in 0..24 {
            k[i][j] = kuu[i][j] + (0..9).map(|m| kua[i][m] * h[(m, j)]).sum::<f64>();
        }
    }
    for i in 0..24 {
        for j in i + 1..24 {
            let s = 0.5 * (k[i][j] + k[j][i]);
            k[i][j] = s;
            k[j][i] = s;
        }
    }
    (k, std::array::from_fn(|m| std::array::from_fn(|j| h[(m, j)])))
}

/// Index of `K[i][j]` in the 300 stored upper-triangle values of a packed 24 x 24 symmetric
/// matrix (row-major upper triangle; `packed_k`).
pub const SYM24: [[u16; 24]; 24] = {
    let mut m = [[0u16; 24]; 24];
    let mut k = 0;
    let mut i = 0;
    while i < 24 {
        let mut j = i;
        while j < 24 {
            m[i][j] = k;
            m[j][i] = k;
            k += 1;
            j += 1;
        }
        i += 1;
    }
    m
};

/// The condensed `K` of [`matrices`] packed as its 300 upper-triangle values (`SYM24`): what an
/// explicit kernel stores per element (2400 bytes) to compute `f = K u` by [`forces_packed`].
pub fn packed_k(x: &[[f64; 3]; 8], d: &Dmat3) -> [f64; 300] {
    let (k, _) = matrices(x, d);
    let mut p = [0.0; 300];
    for i in 0..24 {
        for j in i..24 {
            p[SYM24[i][j] as usize] = k[i][j];
        }
    }
    p
}

/// `f = K u` of a packed condensed stiffness (no allocation; 576 multiply-adds on 2400 bytes).
#[inline(always)]
pub fn forces_packed(k: &[f64; 300], u: &[[f64; 3]; 8]) -> [[f64; 3]; 8] {
    let mut f = [[0.0; 3]; 8];
    for i in 0..24 {
        let mut acc = 0.0;
        for j in 0..24 {
            acc += k[SYM24[i][j] as usize] * u[j / 3][j % 3];
        }
        f[i / 3][i % 3] = acc;
    }
    f
}

/// Stress (Voigt) at natural point `xi` with the enhanced field, for the internal parameters
/// `alpha` of the displacement (`alpha(geometry(x), u, d)`).
pub fn stress_with(x: &[[f64; 3]; 8], u: &[[f64; 3]; 8], al: &[[f64; 3]; 3], d: &Dmat3, xi: [f64; 3]) -> [f64; 6] {
    let (g, det) = gradients3::<Hex8, 8>(x, xi);
    let gm = bubble_gradients(&adj_j0(x), xi, det);
    let eu = strain3(&g, u);
    let em = mode_strain(&gm, al);
    d.stress(std::array::from_fn(|r| eu[r] + em[r]))
}

/// Stress (Voigt) at natural point `xi`.
pub fn stress(x: &[[f64; 3]; 8], u: &[[f64; 3]; 8], d: &Dmat3, xi: [f64; 3]) -> [f64; 6] {
    stress_with(x, u, &alpha(&geometry(x), u, d), d, xi)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn distorted() -> [[f64; 3]; 8] {
        std::array::from_fn(|a| {
            let c = Hex8::CORNERS[a];
            [2.0 * c[0] + 0.3 * c[1] * c[2] + 0.1, 1.5 * c[1] + 0.2 * c[0] - 0.15 * c[0] * c[2], c[2] + 0.25 * c[0] * c[1] + 0.1 * c[1]]
        })
    }

    /// The condensed `K` times `u` equals the coordinate-based force routine (both are the same
    /// condensation: round-off), `K` is symmetric, and `H u` equals `alpha`.
    #[test]
    fn matrices_match_forces() {
        let x = distorted();
        let d = Dmat3::new(1000.0, 0.3);
        let (k, h) = matrices(&x, &d);
        let u: [[f64; 3]; 8] = std::array::from_fn(|a| [0.01 * (a as f64).sin(), 0.02 * (a as f64 * 1.3).cos(), -0.015 * a as f64]);
        let f = internal_force(&x, &u, &d);
        let scale = f.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        for i in 0..24 {
            let ku: f64 = (0..24).map(|j| k[i][j] * u[j / 3][j % 3]).sum();
            assert!((ku - f[i / 3][i % 3]).abs() < 1e-12 * scale, "{i}: {ku} vs {}", f[i / 3][i % 3]);
        }
        let fp = forces_packed(&packed_k(&x, &d), &u);
        for i in 0..24 {
            assert!((fp[i / 3][i % 3] - f[i / 3][i % 3]).abs() < 1e-12 * scale);
        }
        let al = alpha(&geometry(&x), &u, &d);
        for m in 0..9 {
            let hu: f64 = (0..24).map(|j| h[m][j] * u[j / 3][j % 3]).sum();
            assert!((hu - al[m / 3][m % 3]).abs() < 1e-10 * al.iter().flatten().fold(1e-30f64, |a, v| a.max(v.abs())));
        }
    }

    /// `K_aa` by the isotropic block formula equals `sum c G^T D G` from the strains of unit
    /// modes and the full 6 x 6 `D` (to round-off).
    #[test]
    fn kaa_blocks_match_the_full_product() {
        let d = Dmat3::new(1000.0, 0.3);
        let geo = geometry(&distorted());
        let k = kaa(&geo, &d);
        let dm = d.full();
        for i in 0..9 {
            for j in 0..9 {
                let mut v = 0.0;
                for gp in 0..8 {
                    let (mut ei, mut ej) = ([0.0; 6], [0.0; 6]);
                    unit_strain(geo.gm[gp][i / 3], i % 3, &mut ei);
                    unit_strain(geo.gm[gp][j / 3], j % 3, &mut ej);
                    v += geo.c[gp] * (0..6).map(|r| ei[r] * (0..6).map(|q| dm[r][q] * ej[q]).sum::<f64>()).sum::<f64>();
                }
                assert!((k[(i, j)] - v).abs() < 1e-12 * k[(i, i)].abs().max(1.0), "{i} {j}: {} vs {v}", k[(i, j)]);
            }
        }
    }

    /// Reference: pure bending of a rectangular brick, u = k x z, w = -k x^2 / 2 (nu = 0), is
    /// exact in the enhanced field: the condensed element's strain energy equals the exact
    /// E k^2 I L / 2 for the cell, where the plain trilinear brick is too stiff (locking).
    #[test]
    fn pure_bending_exact_on_a_rectangular_brick() {
        let (lx, ly, lz) = (4.0, 1.0, 1.0);
        let x: [[f64; 3]; 8] = std::array::from_fn(|a| {
            let c = Hex8::CORNERS[a];
            [0.5 * lx * c[0], 0.5 * ly * c[1], 0.5 * lz * c[2]]
        });
        let (e, kappa) = (1000.0, 1e-3);
        let d = Dmat3::new(e, 0.0);
        let u: [[f64; 3]; 8] = std::array::from_fn(|a| [kappa * x[a][0] * x[a][2], 0.0, -0.5 * kappa * x[a][0] * x[a][0]]);
        let exact = 0.5 * e * kappa * kappa * (ly * lz.powi(3) / 12.0) * lx;
        let f = internal_force(&x, &u, &d);
        let w: f64 = (0..8).map(|a| (0..3).map(|k| f[a][k] * u[a][k]).sum::<f64>()).sum::<f64>() * 0.5;
        assert!((w / exact - 1.0).abs() < 1e-12, "h8 energy {w} vs {exact}");
        let f0 = flem_core::element::shape3::internal_force3::<Hex8, 8>(&x, &u, &d);
        let w0: f64 = (0..8).map(|a| (0..3).map(|k| f0[a][k] * u[a][k]).sum::<f64>()).sum::<f64>() * 0.5;
        assert!(w0 / exact > 1.5, "h8_full should lock: {}", w0 / exact);
    }
}
