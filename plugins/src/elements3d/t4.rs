//! `t4`: the 4-node linear tetrahedron (constant strain), the 3D twin of `t3`.
//!
//! **What.** Linear shape functions in volume coordinates (`flem_core::element::shape3::Tet4`):
//! `u(xi) = sum_a N_a(xi) u_a`, `N = [1 - xi - eta - zeta, xi, eta, zeta]`. Their Cartesian
//! gradients `g_a` are constant over the element, so are the strain and the stress:
//!
//!     eps = sum_a B_a u_a,   sigma = D eps,   f_a = V B_a^T sigma,   K_ab = V B_a^T D B_b,
//!
//! with `V = det J / 6` the volume (one Gauss point at the centroid, weight 1/6, integrates the
//! constant integrand exactly), `B_a` and `D` as in `shape3`'s module doc (Voigt order
//! `xx, yy, zz, xy, yz, zx`, engineering shear strains). The nodal stress is the element's
//! constant stress (taken at the centroid, as 2D's `t3`: `shape3::corner_xi3`). References:
//! Zienkiewicz, Taylor & Zhu, *The Finite Element Method: its Basis and Fundamentals*, 7th ed.,
//! sec. 6.3 (the linear tetrahedron); Hughes, *The Finite Element Method*, sec. 3.6.
//!
//! Units: the scene's (consistent). Reproduces any linear displacement field exactly (the
//! patch test: tests/solid3.rs), stiff in bending (a coarse tetrahedral cantilever locks).
//!
//! **Fast form** (for an explicit kernel): [`T4Geo`] (12 gradients and the volume, 13 f64 per
//! element, computed once by [`geometry`]) and [`forces`] (about 110 flops, no allocation).
//!
//! ```toml
//! [[material]]
//! young_modulus = 210e3
//! poisson_ratio = 0.3
//! density = 7.85e-9
//! element = "t4"
//! ```
use flem_core::element::shape3::{bt_stress, gradients3, strain3, Dmat3, Tet4};

/// The geometry of one tetrahedron that its forces need: Cartesian gradients and volume.
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct T4Geo {
    pub g: [[f64; 3]; 4],
    pub vol: f64,
}

/// Gradients and volume of the tetrahedron `x` (volume negative for a tangled cell).
#[inline(always)]
pub fn geometry(x: &[[f64; 3]; 4]) -> T4Geo {
    let (g, det) = gradients3::<Tet4, 4>(x, [0.25; 3]);
    T4Geo { g, vol: det / 6.0 }
}

/// Internal corner forces `f_a = V B_a^T D B u` (no allocation).
#[inline(always)]
pub fn forces(geo: &T4Geo, u: &[[f64; 3]; 4], d: &Dmat3) -> [[f64; 3]; 4] {
    let s = d.stress(strain3(&geo.g, u));
    std::array::from_fn(|a| bt_stress(geo.g[a], &s).map(|v| geo.vol * v))
}

/// Internal corner forces from the coordinates.
#[inline(always)]
pub fn internal_force(x: &[[f64; 3]; 4], u: &[[f64; 3]; 4], d: &Dmat3) -> [[f64; 3]; 4] {
    forces(&geometry(x), u, d)
}

/// The (constant) stress of the element.
pub fn stress(x: &[[f64; 3]; 4], u: &[[f64; 3]; 4], d: &Dmat3) -> [f64; 6] {
    d.stress(strain3(&geometry(x).g, u))
}
