//! 3D element math (issue 38): shape functions of the 4-node tetrahedron and the 8-node brick,
//! the isotropic elasticity matrix, strain-displacement (B) matrices, element stiffness,
//! internal forces, stresses at points and the nodal stress at the paper's 0.9999 corners.
//! The 3D twin of this folder's 2D math (`element::Shape`, `gradients`, `internal_force`,
//! `stress_at`, `corner_xi`), kept beside it so that 2D stays exactly as it is (docs/3d.md,
//! "Design"). The element kinds built on it (`t4`, `h8` with incompatible modes) are plugins:
//! `flem-plugins/src/elements3d/`.
//!
//! # Conventions
//! - Stress and strain in Voigt order `[xx, yy, zz, xy, yz, zx]`, tension positive, with
//!   *engineering* shear strains `gamma_xy = du/dy + dv/dx` (twice the tensor component), so
//!   that `sigma . eps` is the strain-energy density doubled.
//! - Isotropic linear elasticity (`Dmat3`), with Lame's `lambda = E nu / ((1 + nu)(1 - 2 nu))`,
//!   `mu = G = E / (2 (1 + nu))`:
//!
//! ```text
//!     | sxx |   | l+2m  l     l     0  0  0 | | exx |
//!     | syy |   | l     l+2m  l     0  0  0 | | eyy |
//!     | szz | = | l     l     l+2m  0  0  0 | | ezz |
//!     | sxy |   | 0     0     0     m  0  0 | | gxy |
//!     | syz |   | 0     0     0     0  m  0 | | gyz |
//!     | szx |   | 0     0     0     0  0  m | | gzx |
//! ```
//!
//! - Corner order VTK's and gmsh's (`mesh::raw3`). Natural coordinates: T4 `(xi, eta, zeta)`
//!   with corners `(0,0,0), (1,0,0), (0,1,0), (0,0,1)`, `N = [1 - xi - eta - zeta, xi, eta,
//!   zeta]`; H8 `[-1, 1]^3`, `N_a = (1 + xi xi_a)(1 + eta eta_a)(1 + zeta zeta_a) / 8`.
//! - The Jacobian `J[i][j] = d x_j / d xi_i` (rows: natural directions), so that the Cartesian
//!   gradient of a shape function is `grad_x N = J^-1 grad_xi N`; `det J > 0` for a cell in the
//!   corner order above.
//! - `B_a` (6 x 3) of corner `a` with gradient `g = (gx, gy, gz)`:
//!   `eps = sum_a B_a u_a`, rows `[gx 0 0], [0 gy 0], [0 0 gz], [gy gx 0], [0 gz gy], [gz 0 gx]`.
//! - Element stiffness `K = sum_gp w det J B^T D B`, dofs ordered `x0 y0 z0 x1 y1 z1 ...`;
//!   internal forces `f_a = sum_gp w det J B_a^T sigma`. Units: the scene's (consistent: a
//!   modulus in force / length^2 gives forces in force units, displacements in length).
//! - Nodal stress (paper 2.1, read in 3D): a brick's stress at its corners scaled by 0.9999 in
//!   natural coordinates, a tetrahedron's (constant) stress at its centroid, exactly as 2D's
//!   `corner_xi` does for Q4 and T3.
use crate::mesh::CellKind3;

/// Isotropic linear elastic 3D material (`E`, `nu`; density for the lumped mass).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Material3 {
    pub young: f64,
    pub poisson: f64,
    pub density: f64,
}

/// The isotropic elasticity matrix through Lame's constants (module doc).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Dmat3 {
    pub lambda: f64,
    pub mu: f64,
}

impl Material3 {
    pub fn dmat(&self) -> Dmat3 {
        Dmat3::new(self.young, self.poisson)
    }
}

impl Dmat3 {
    /// From Young's modulus and Poisson's ratio (`-1 < nu < 0.5`).
    pub fn new(young: f64, poisson: f64) -> Self {
        let (e, nu) = (young, poisson);
        Dmat3 { lambda: e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), mu: e / (2.0 * (1.0 + nu)) }
    }

    /// `sigma = D eps` (Voigt, engineering shear strains).
    #[inline(always)]
    pub fn stress(&self, e: [f64; 6]) -> [f64; 6] {
        let tr = self.lambda * (e[0] + e[1] + e[2]);
        let m2 = 2.0 * self.mu;
        [tr + m2 * e[0], tr + m2 * e[1], tr + m2 * e[2], self.mu * e[3], self.mu * e[4], self.mu * e[5]]
    }

    /// The full 6 x 6 matrix.
    pub fn full(&self) -> [[f64; 6]; 6] {
        let (l, m) = (self.lambda, self.mu);
        let mut d = [[0.0; 6]; 6];
        for i in 0..3 {
            d[i][..3].fill(l);
            d[i][i] = l + 2.0 * m;
            d[i + 3][i + 3] = m;
        }
        d
    }
}

/// A 3D element shape with `N` corners (the 3D twin of `element::Shape`).
pub trait Shape3<const N: usize>: Copy + Default + Send + Sync + 'static {
    const KIND: CellKind3;
    /// Natural coordinates of the corners.
    const CORNERS: [[f64; 3]; N];
    /// Gauss points (natural coordinates) and weights.
    const GAUSS: &'static [([f64; 3], f64)];
    fn n(xi: [f64; 3]) -> [f64; N];
    fn dn(xi: [f64; 3]) -> [[f64; 3]; N];
}

/// The 4-node linear tetrahedron (constant strain; one Gauss point at the centroid, weight
/// 1/6 = the volume of the natural tetrahedron).
#[derive(Copy, Clone, Default, Debug)]
pub struct Tet4;

impl Shape3<4> for Tet4 {
    const KIND: CellKind3 = CellKind3::T4;
    const CORNERS: [[f64; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    const GAUSS: &'static [([f64; 3], f64)] = &[([0.25, 0.25, 0.25], 1.0 / 6.0)];
    #[inline(always)]
    fn n(xi: [f64; 3]) -> [f64; 4] {
        [1.0 - xi[0] - xi[1] - xi[2], xi[0], xi[1], xi[2]]
    }
    #[inline(always)]
    fn dn(_xi: [f64; 3]) -> [[f64; 3]; 4] {
        [[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    }
}

/// The 8-node trilinear brick (2 x 2 x 2 Gauss points at `+-1/sqrt 3`, weights 1).
#[derive(Copy, Clone, Default, Debug)]
pub struct Hex8;

const G: f64 = 0.577_350_269_189_625_8; // 1 / sqrt(3)

impl Shape3<8> for Hex8 {
    const KIND: CellKind3 = CellKind3::H8;
    const CORNERS: [[f64; 3]; 8] = [[-1.0, -1.0, -1.0], [1.0, -1.0, -1.0], [1.0, 1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]];
    const GAUSS: &'static [([f64; 3], f64)] =
        &[([-G, -G, -G], 1.0), ([G, -G, -G], 1.0), ([G, G, -G], 1.0), ([-G, G, -G], 1.0), ([-G, -G, G], 1.0), ([G, -G, G], 1.0), ([G, G, G], 1.0), ([-G, G, G], 1.0)];
    #[inline(always)]
    fn n(xi: [f64; 3]) -> [f64; 8] {
        std::array::from_fn(|a| {
            let c = Self::CORNERS[a];
            0.125 * (1.0 + c[0] * xi[0]) * (1.0 + c[1] * xi[1]) * (1.0 + c[2] * xi[2])
        })
    }
    #[inline(always)]
    fn dn(xi: [f64; 3]) -> [[f64; 3]; 8] {
        std::array::from_fn(|a| {
            let c = Self::CORNERS[a];
            let (p, q, r) = (1.0 + c[0] * xi[0], 1.0 + c[1] * xi[1], 1.0 + c[2] * xi[2]);
            [0.125 * c[0] * q * r, 0.125 * c[1] * p * r, 0.125 * c[2] * p * q]
        })
    }
}

/// The Jacobian `J[i][j] = d x_j / d xi_i` from the natural derivatives `dn`.
#[inline(always)]
pub fn jacobian<const N: usize>(x: &[[f64; 3]; N], dn: &[[f64; 3]; N]) -> [[f64; 3]; 3] {
    let mut j = [[0.0; 3]; 3];
    for a in 0..N {
        for i in 0..3 {
            for k in 0..3 {
                j[i][k] += dn[a][i] * x[a][k];
            }
        }
    }
    j
}

/// Determinant and adjugate (`adj J = det J * J^-1`) of a 3 x 3 matrix.
#[inline(always)]
pub fn det_adj(j: &[[f64; 3]; 3]) -> (f64, [[f64; 3]; 3]) {
    let adj = [
        [j[1][1] * j[2][2] - j[1][2] * j[2][1], j[0][2] * j[2][1] - j[0][1] * j[2][2], j[0][1] * j[1][2] - j[0][2] * j[1][1]],
        [j[1][2] * j[2][0] - j[1][0] * j[2][2], j[0][0] * j[2][2] - j[0][2] * j[2][0], j[0][2] * j[1][0] - j[0][0] * j[1][2]],
        [j[1][0] * j[2][1] - j[1][1] * j[2][0], j[0][1] * j[2][0] - j[0][0] * j[2][1], j[0][0] * j[1][1] - j[0][1] * j[1][0]],
    ];
    let det = j[0][0] * adj[0][0] + j[0][1] * adj[1][0] + j[0][2] * adj[2][0];
    (det, adj)
}

/// `m v` for a 3 x 3 matrix.
#[inline(always)]
pub fn mul3(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

/// Cartesian shape-function gradients and `det J` at natural coordinate `xi`.
#[inline(always)]
pub fn gradients3<S: Shape3<N>, const N: usize>(x: &[[f64; 3]; N], xi: [f64; 3]) -> ([[f64; 3]; N], f64) {
    let dn = S::dn(xi);
    let (det, adj) = det_adj(&jacobian(x, &dn));
    let inv = 1.0 / det;
    let g = std::array::from_fn(|a| {
        let v = mul3(&adj, dn[a]);
        [inv * v[0], inv * v[1], inv * v[2]]
    });
    (g, det)
}

/// Strain (Voigt, engineering shear) of the gradients `g` and corner displacements `u`.
#[inline(always)]
pub fn strain3<const N: usize>(g: &[[f64; 3]; N], u: &[[f64; 3]; N]) -> [f64; 6] {
    let mut e = [0.0; 6];
    for a in 0..N {
        let ([gx, gy, gz], [ux, uy, uz]) = (g[a], u[a]);
        e[0] += gx * ux;
        e[1] += gy * uy;
        e[2] += gz * uz;
        e[3] += gy * ux + gx * uy;
        e[4] += gz * uy + gy * uz;
        e[5] += gx * uz + gz * ux;
    }
    e
}

/// `B_a^T s` for one gradient `g` (the force on a corner of the stress `s`, per unit volume).
#[inline(always)]
pub fn bt_stress(g: [f64; 3], s: &[f64; 6]) -> [f64; 3] {
    let [gx, gy, gz] = g;
    [gx * s[0] + gy * s[3] + gz * s[5], gy * s[1] + gx * s[3] + gz * s[4], gz * s[2] + gy * s[4] + gx * s[5]]
}

/// The 6 x 3 block `B_a` of a gradient (module doc).
#[inline(always)]
pub fn bmat3(g: [f64; 3]) -> [[f64; 3]; 6] {
    let [gx, gy, gz] = g;
    [[gx, 0.0, 0.0], [0.0, gy, 0.0], [0.0, 0.0, gz], [gy, gx, 0.0], [0.0, gz, gy], [gz, 0.0, gx]]
}

/// Internal corner forces `f = sum_gp w det J B^T D B u` of an isoparametric element (no
/// allocation).
#[inline(always)]
pub fn internal_force3<S: Shape3<N>, const N: usize>(x: &[[f64; 3]; N], u: &[[f64; 3]; N], d: &Dmat3) -> [[f64; 3]; N] {
    let mut f = [[0.0; 3]; N];
    for &(xi, w) in S::GAUSS {
        let (g, det) = gradients3::<S, N>(x, xi);
        let s = d.stress(strain3(&g, u));
        let c = w * det;
        for a in 0..N {
            let b = bt_stress(g[a], &s);
            for k in 0..3 {
                f[a][k] += c * b[k];
            }
        }
    }
    f
}

/// Stress (Voigt) of an isoparametric element at natural coordinate `xi`.
pub fn stress_at3<S: Shape3<N>, const N: usize>(x: &[[f64; 3]; N], u: &[[f64; 3]; N], d: &Dmat3, xi: [f64; 3]) -> [f64; 6] {
    let (g, _) = gradients3::<S, N>(x, xi);
    d.stress(strain3(&g, u))
}

/// Natural coordinate at which the nodal stress of corner `a` is taken (paper 2.1 read in 3D,
/// as 2D's `element::corner_xi`): a brick's corner scaled by 0.9999, a tetrahedron's centroid
/// (its strain is constant).
pub fn corner_xi3<S: Shape3<N>, const N: usize>(a: usize) -> [f64; 3] {
    match S::KIND {
        CellKind3::H8 => S::CORNERS[a].map(|c| 0.9999 * c),
        CellKind3::T4 => [0.25; 3],
    }
}

/// Element stiffness (3N x 3N, row-major into `k`, dofs `x0 y0 z0 x1 ...`) of an isoparametric
/// element: `K = sum_gp w det J B^T D B`.
pub fn stiffness3<S: Shape3<N>, const N: usize>(x: &[[f64; 3]; N], d: &Dmat3, k: &mut [f64]) {
    let n3 = 3 * N;
    assert!(k.len() >= n3 * n3, "stiffness3: k holds {} values, {} needed", k.len(), n3 * n3);
    k[..n3 * n3].fill(0.0);
    let dm = d.full();
    for &(xi, w) in S::GAUSS {
        let (g, det) = gradients3::<S, N>(x, xi);
        let c = w * det;
        for b in 0..N {
            let bb = bmat3(g[b]);
            // D B_b (6 x 3).
            let db: [[f64; 3]; 6] = std::array::from_fn(|r| std::array::from_fn(|q| (0..6).map(|s| dm[r][s] * bb[s][q]).sum()));
            for a in 0..N {
                let ba = bmat3(g[a]);
                for p in 0..3 {
                    for q in 0..3 {
                        let v: f64 = (0..6).map(|r| ba[r][p] * db[r][q]).sum();
                        k[(3 * a + p) * n3 + 3 * b + q] += c * v;
                    }
                }
            }
        }
    }
}

/// Row-sum lumped mass of each corner: `rho integral N_a dV`.
pub fn lumped_mass3<S: Shape3<N>, const N: usize>(x: &[[f64; 3]; N], rho: f64) -> [f64; N] {
    let mut m = [0.0; N];
    for &(xi, w) in S::GAUSS {
        let (_, det) = gradients3::<S, N>(x, xi);
        let n = S::n(xi);
        for a in 0..N {
            m[a] += rho * w * det * n[a];
        }
    }
    m
}

/// Volume `sum_gp w det J` (exact for a tetrahedron and for a brick: det J of a trilinear map is
/// a polynomial of degree 2 per direction, which 2 x 2 x 2 Gauss integrates exactly).
pub fn volume3<S: Shape3<N>, const N: usize>(x: &[[f64; 3]; N]) -> f64 {
    S::GAUSS.iter().map(|&(xi, w)| w * det_adj(&jacobian(x, &S::dn(xi))).0).sum()
}

/// The smallest `det J` over the Gauss points and the 0.9999 corners (`> 0` for a valid,
/// untangled cell; the solver refuses a cell where it is not).
pub fn min_det3<S: Shape3<N>, const N: usize>(x: &[[f64; 3]; N]) -> f64 {
    let mut m = f64::INFINITY;
    for xi in S::GAUSS.iter().map(|g| g.0).chain((0..N).map(corner_xi3::<S, N>)) {
        m = m.min(det_adj(&jacobian(x, &S::dn(xi))).0);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Partition of unity, `N_a(corner_b) = delta_ab`, and the natural derivatives against
    /// central differences (1e-6 step: error O(h^2) of a trilinear function is 0, round-off
    /// ~1e-10).
    fn check_shape<S: Shape3<N>, const N: usize>() {
        for b in 0..N {
            let n = S::n(S::CORNERS[b]);
            for a in 0..N {
                assert!((n[a] - if a == b { 1.0 } else { 0.0 }).abs() < 1e-15);
            }
        }
        let xi = [0.13, -0.21, 0.07];
        assert!((S::n(xi).iter().sum::<f64>() - 1.0).abs() < 1e-15);
        let dn = S::dn(xi);
        for d in 0..3 {
            let (mut p, mut m) = (xi, xi);
            p[d] += 1e-6;
            m[d] -= 1e-6;
            let (np, nm) = (S::n(p), S::n(m));
            for a in 0..N {
                assert!(((np[a] - nm[a]) / 2e-6 - dn[a][d]).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn shapes() {
        check_shape::<Tet4, 4>();
        check_shape::<Hex8, 8>();
    }

    /// Reference: Hooke's law. A uniaxial stress state sigma_xx = E eps with the lateral strains
    /// -nu eps gives exactly (E eps, 0, 0, 0, 0, 0); a pure shear gamma gives G gamma.
    #[test]
    fn dmat_uniaxial_and_shear() {
        let (e, nu) = (210e3, 0.3);
        let d = Dmat3::new(e, nu);
        let s = d.stress([1e-3, -nu * 1e-3, -nu * 1e-3, 0.0, 0.0, 0.0]);
        assert!((s[0] - e * 1e-3).abs() < 1e-12 * e && s[1].abs() < 1e-12 * e && s[2].abs() < 1e-12 * e);
        let s = d.stress([0.0, 0.0, 0.0, 0.0, 2e-3, 0.0]);
        assert!((s[4] - e / (2.0 * (1.0 + nu)) * 2e-3).abs() < 1e-12 * e);
    }

    /// The stiffness by `stiffness3` and the internal force kernel agree (K u = f(u)), and K
    /// annihilates the six rigid motions (the element is free of spurious strain under rigid
    /// translation and infinitesimal rotation).
    #[test]
    fn stiffness_matches_forces_and_rigid_motions() {
        let x: [[f64; 3]; 8] = std::array::from_fn(|a| {
            let c = Hex8::CORNERS[a];
            [c[0] + 0.1 * c[1] * c[2], 0.8 * c[1] + 0.05 * c[0], 1.2 * c[2] - 0.1 * c[0] * c[1]]
        });
        let d = Dmat3::new(100.0, 0.25);
        let mut k = vec![0.0; 576];
        stiffness3::<Hex8, 8>(&x, &d, &mut k);
        let u: [[f64; 3]; 8] = std::array::from_fn(|a| [0.01 * a as f64, -0.02 * (a % 3) as f64, 0.005 * (a * a) as f64]);
        let f = internal_force3::<Hex8, 8>(&x, &u, &d);
        for i in 0..24 {
            let ku: f64 = (0..24).map(|j| k[i * 24 + j] * u[j / 3][j % 3]).sum();
            assert!((ku - f[i / 3][i % 3]).abs() < 1e-12 * 100.0);
        }
        for w in [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.3, -0.2, 0.5]] {
            let rig: [[f64; 3]; 8] = std::array::from_fn(|a| {
                let p = x[a];
                [0.1 + w[1] * p[2] - w[2] * p[1], w[2] * p[0] - w[0] * p[2], w[0] * p[1] - w[1] * p[0]]
            });
            let f = internal_force3::<Hex8, 8>(&x, &rig, &d);
            assert!(f.iter().flatten().all(|v| v.abs() < 1e-12 * 100.0), "{f:?}");
        }
    }
}
