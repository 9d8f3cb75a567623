//! Element math: shape functions, the linear elastic material and the per-element kernels.
//!
//! Elements are small-strain, linear elastic, in plane strain or plane stress, with lumped
//! (row-sum) mass. Stress is tension-positive here, `[sxx, syy, sxy]`; failure criteria convert
//! to the geomechanics convention (compression positive) at their boundary, once.
//!
//! The folder holds the element math and what is built from it: [`kernel`] (the element trait
//! `Blocked` and the blocked schedule), [`registry`] (element kinds by name), [`block`] (one
//! element kind and material per block, monomorphised), [`corot`] (co-rotational blocks),
//! [`stateful`] (material laws with history) and [`model`] (topology + blocks: the model the
//! solver steps). The element kinds themselves (`q4`, `t3`, `qm6`, ...) are plugins
//! (`flem-plugins/src/elements/`, docs/elements.md): core names none of them.
pub mod block;
pub mod corot;
pub mod dag;
pub mod implicit;
pub mod implicit_law;
pub mod kernel;
pub mod law;
pub mod model;
pub mod model3;
pub mod registry;
pub mod shape3;
pub mod stateful;
#[cfg(test)]
pub mod testkinds;

use serde::{Deserialize, Serialize};

use crate::mesh::CellKind;

/// 2D idealisation.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Plane {
    #[default]
    Strain,
    Stress,
}

/// Isotropic linear elastic material of one element block.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Material {
    pub young: f64,
    pub poisson: f64,
    pub density: f64,
    pub thickness: f64,
    pub plane: Plane,
}

/// The isotropic elasticity matrix `[[d11, d12, 0], [d12, d11, 0], [0, 0, d33]]`.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Dmat {
    pub d11: f64,
    pub d12: f64,
    pub d33: f64,
}

impl Material {
    pub fn dmat(&self) -> Dmat {
        let (e, nu) = (self.young, self.poisson);
        match self.plane {
            Plane::Strain => {
                let f = e / ((1.0 + nu) * (1.0 - 2.0 * nu));
                Dmat { d11: f * (1.0 - nu), d12: f * nu, d33: f * (1.0 - 2.0 * nu) / 2.0 }
            }
            Plane::Stress => {
                let f = e / (1.0 - nu * nu);
                Dmat { d11: f, d12: f * nu, d33: f * (1.0 - nu) / 2.0 }
            }
        }
    }
    /// Out-of-plane stress szz for a given in-plane stress (plane strain: nu (sxx + syy)).
    pub fn szz(&self, s: [f64; 3]) -> f64 {
        match self.plane {
            Plane::Strain => self.poisson * (s[0] + s[1]),
            Plane::Stress => 0.0,
        }
    }
}

impl Dmat {
    #[inline(always)]
    pub fn stress(&self, eps: [f64; 3]) -> [f64; 3] {
        [self.d11 * eps[0] + self.d12 * eps[1], self.d12 * eps[0] + self.d11 * eps[1], self.d33 * eps[2]]
    }
}

/// An element shape with `N` corners. Kernels are generic over it and monomorphised per block.
pub trait Shape<const N: usize>: Copy + Default + Send + Sync + 'static {
    const KIND: CellKind;
    /// Natural coordinates of the corners.
    const CORNERS: [[f64; 2]; N];
    /// Gauss points (natural coordinates) and weights.
    const GAUSS: &'static [([f64; 2], f64)];
    fn n(xi: [f64; 2]) -> [f64; N];
    fn dn(xi: [f64; 2]) -> [[f64; 2]; N];

    /// The never-yielded pass of a stateful block in the kind's own form (ours, issue 21,
    /// session 11; `element::stateful`, docs/materials.md "Storage"), and since session 30 its
    /// stored path too (strain increments, forces, the seed). `TOTAL_ROWS` rows of
    /// `LANES` f64 per pack of geometry, `TOTAL_EXTRA_ROWS` more for a pack whose `total_geometry`
    /// asks for them (`q4`: a pack holding a non-parallelogram). 0 (the default): the kind has
    /// no such form, and the block computes the generic isoparametric geometry (`t3`, `qm6`,
    /// a plugin's kind).
    const TOTAL_ROWS: usize = 0;
    const TOTAL_EXTRA_ROWS: usize = 0;
    /// Fills `geo` (`TOTAL_ROWS` rows) and `extra` (`TOTAL_EXTRA_ROWS` rows) from the corners of
    /// the pack's `LANES` elements (`x[lane]`, every lane a valid element); true when the pack
    /// needs `extra`.
    fn total_geometry(_x: &[[[f64; 2]; N]; kernel::LANES], _geo: &mut [[f64; kernel::LANES]], _extra: &mut [[f64; kernel::LANES]]) -> bool {
        false
    }
    /// `e[k] = [exx, eyy, gxy, 0]` of Gauss point `k` of every lane from the displacements
    /// `u[a][dim][lane]` (with B-bar when `BBAR`: the in-plane volumetric part replaced by its
    /// mean over the element weighted by `w det J`). Equal to the generic
    /// `B(x) u` to round-off.
    #[inline(always)]
    fn total_strains<const BBAR: bool>(_geo: &[[f64; kernel::LANES]], _extra: Option<&[[f64; kernel::LANES]]>, _u: &[[[f64; kernel::LANES]; 2]; N], _e: &mut [[[f64; kernel::LANES]; 4]; 4]) {}
    /// `f[a][dim][lane] = sum_k w_k det J_k t Bbar_a(k)^T s[k]` (B-bar when `BBAR`): the
    /// corner forces of the point stresses `s[k] = [sxx, syy, sxy, szz]`.
    #[inline(always)]
    fn total_forces<const BBAR: bool>(_geo: &[[f64; kernel::LANES]], _extra: Option<&[[f64; kernel::LANES]]>, _s: &[[[f64; kernel::LANES]; 4]; 4], _t: f64, _f: &mut [[[f64; kernel::LANES]; 2]; N]) {}
}

/// The name of the default element kind of a cell type (the paper's elements: `q4` for
/// quadrilaterals, `t3` for triangles; both are plugins, looked up by name in [`registry`]).
pub fn default_kind(cell: CellKind) -> &'static str {
    match cell {
        CellKind::Q4 => "q4",
        CellKind::T3 => "t3",
    }
}

/// Cartesian shape-function gradients and det J at natural coordinate `xi`.
#[inline(always)]
pub fn gradients<S: Shape<N>, const N: usize>(x: &[[f64; 2]; N], xi: [f64; 2]) -> ([[f64; 2]; N], f64) {
    let dn = S::dn(xi);
    let (mut j11, mut j12, mut j21, mut j22) = (0.0, 0.0, 0.0, 0.0);
    for a in 0..N {
        j11 += dn[a][0] * x[a][0];
        j12 += dn[a][0] * x[a][1];
        j21 += dn[a][1] * x[a][0];
        j22 += dn[a][1] * x[a][1];
    }
    let det = j11 * j22 - j12 * j21;
    let inv = 1.0 / det;
    let g = std::array::from_fn(|a| [inv * (j22 * dn[a][0] - j12 * dn[a][1]), inv * (-j21 * dn[a][0] + j11 * dn[a][1])]);
    (g, det)
}

#[inline(always)]
pub fn strain<const N: usize>(g: &[[f64; 2]; N], u: &[[f64; 2]; N]) -> [f64; 3] {
    let mut e = [0.0; 3];
    for a in 0..N {
        e[0] += g[a][0] * u[a][0];
        e[1] += g[a][1] * u[a][1];
        e[2] += g[a][1] * u[a][0] + g[a][0] * u[a][1];
    }
    e
}

/// Internal nodal forces of one element: `f = sum_gp B^T D B u w det J t`.
#[inline(always)]
pub fn internal_force<S: Shape<N>, const N: usize>(x: &[[f64; 2]; N], u: &[[f64; 2]; N], d: &Dmat, t: f64) -> [[f64; 2]; N] {
    let mut f = [[0.0; 2]; N];
    for &(xi, w) in S::GAUSS {
        let (g, det) = gradients::<S, N>(x, xi);
        let s = d.stress(strain(&g, u));
        let c = w * det * t;
        for a in 0..N {
            f[a][0] += c * (g[a][0] * s[0] + g[a][1] * s[2]);
            f[a][1] += c * (g[a][0] * s[2] + g[a][1] * s[1]);
        }
    }
    f
}

/// Stress `[sxx, syy, sxy]` at natural coordinate `xi`.
pub fn stress_at<S: Shape<N>, const N: usize>(x: &[[f64; 2]; N], u: &[[f64; 2]; N], d: &Dmat, xi: [f64; 2]) -> [f64; 3] {
    let (g, _) = gradients::<S, N>(x, xi);
    d.stress(strain(&g, u))
}

/// Natural coordinate used for the stress of corner `a` (paper 2.1: corners scaled by 0.9999;
/// a triangle's strain is constant, so its centroid is used).
pub fn corner_xi<S: Shape<N>, const N: usize>(a: usize) -> [f64; 2] {
    match S::KIND {
        CellKind::Q4 => [0.9999 * S::CORNERS[a][0], 0.9999 * S::CORNERS[a][1]],
        CellKind::T3 => [1.0 / 3.0, 1.0 / 3.0],
    }
}

/// Row-sum lumped mass of each corner: `rho t integral N_a dA`.
pub fn lumped_mass<S: Shape<N>, const N: usize>(x: &[[f64; 2]; N], rho: f64, t: f64) -> [f64; N] {
    let mut m = [0.0; N];
    for &(xi, w) in S::GAUSS {
        let (_, det) = gradients::<S, N>(x, xi);
        let n = S::n(xi);
        for a in 0..N {
            m[a] += rho * t * w * det * n[a];
        }
    }
    m
}

/// Element stiffness (2N x 2N, row-major, dofs ordered x0 y0 x1 y1 ...), built column by
/// column from the force kernel so it is consistent with the explicit solver by construction.
pub fn stiffness<S: Shape<N>, const N: usize>(x: &[[f64; 2]; N], d: &Dmat, t: f64, k: &mut [f64]) {
    let n2 = 2 * N;
    debug_assert_eq!(k.len(), n2 * n2);
    for j in 0..n2 {
        let mut u = [[0.0; 2]; N];
        u[j / 2][j % 2] = 1.0;
        let f = internal_force::<S, N>(x, &u, d, t);
        for i in 0..n2 {
            k[i * n2 + j] = f[i / 2][i % 2];
        }
    }
}
