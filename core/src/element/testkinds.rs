//! Test-only element kinds for core's own unit tests. Core defines no element kind (the real
//! ones are plugins, `flem-plugins/src/elements/`), but a few core unit tests build a `Model`
//! (nonlocal averaging, co-rotation). These two plain isoparametric kinds, a bilinear
//! quadrilateral (2 x 2 Gauss points) and a linear triangle, are registered under the default
//! names `q4` and `t3` in core's unit-test binary only (`#[cfg(test)]`); their "blocked" kernel
//! is the one-element reference `element::internal_force` per lane (slow, exact).
use crate::element::kernel::{Blocked, LANES};
use crate::element::registry::ElementKind;
use crate::element::{Dmat, Shape};
use crate::mesh::CellKind;

const G: f64 = 0.577_350_269_189_625_8;

/// Bilinear quadrilateral (test only).
#[derive(Copy, Clone, Default, Debug)]
pub struct TestQuad;
/// Linear triangle (test only).
#[derive(Copy, Clone, Default, Debug)]
pub struct TestTri;

impl Shape<4> for TestQuad {
    const KIND: CellKind = CellKind::Q4;
    const CORNERS: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    const GAUSS: &'static [([f64; 2], f64)] = &[([-G, -G], 1.0), ([G, -G], 1.0), ([G, G], 1.0), ([-G, G], 1.0)];
    fn n(xi: [f64; 2]) -> [f64; 4] {
        let c = Self::CORNERS;
        std::array::from_fn(|a| 0.25 * (1.0 + c[a][0] * xi[0]) * (1.0 + c[a][1] * xi[1]))
    }
    fn dn(xi: [f64; 2]) -> [[f64; 2]; 4] {
        let c = Self::CORNERS;
        std::array::from_fn(|a| [0.25 * c[a][0] * (1.0 + c[a][1] * xi[1]), 0.25 * c[a][1] * (1.0 + c[a][0] * xi[0])])
    }
}

impl Shape<3> for TestTri {
    const KIND: CellKind = CellKind::T3;
    const CORNERS: [[f64; 2]; 3] = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
    const GAUSS: &'static [([f64; 2], f64)] = &[([1.0 / 3.0, 1.0 / 3.0], 0.5)];
    fn n(xi: [f64; 2]) -> [f64; 3] {
        [1.0 - xi[0] - xi[1], xi[0], xi[1]]
    }
    fn dn(_xi: [f64; 2]) -> [[f64; 2]; 3] {
        [[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]]
    }
}

/// The corners of `LANES` elements, `D` and `t` (lanes beyond `n` are empty).
#[derive(Copy, Clone, Debug)]
pub struct RefPack<const N: usize> {
    x: [[[f64; 2]; N]; LANES],
    n: usize,
    d: Dmat,
    t: f64,
}

fn pack<const N: usize>(x: &[[[f64; 2]; N]], d: &Dmat, t: f64) -> RefPack<N> {
    let mut p = RefPack { x: [[[0.0; 2]; N]; LANES], n: x.len().min(LANES), d: *d, t };
    p.x[..p.n].copy_from_slice(&x[..p.n]);
    p
}

fn forces<S: Blocked<N>, const N: usize>(p: &RefPack<N>, u: &[[[f64; LANES]; 2]; N], f: &mut [[[f64; LANES]; 2]; N]) {
    for l in 0..LANES {
        let fe = if l < p.n { S::force_ref(&p.x[l], &std::array::from_fn(|a| [u[a][0][l], u[a][1][l]]), &p.d, p.t) } else { [[0.0; 2]; N] };
        for a in 0..N {
            f[a][0][l] = fe[a][0];
            f[a][1][l] = fe[a][1];
        }
    }
}

impl Blocked<4> for TestQuad {
    const NAME: &'static str = "q4";
    type Pack = RefPack<4>;
    type Extra = ();
    fn pack(x: &[[[f64; 2]; 4]], d: &Dmat, t: f64) -> RefPack<4> {
        pack(x, d, t)
    }
    fn scaled_d(_d: &Dmat, _t: f64) -> [f64; 3] {
        [0.0; 3]
    }
    fn forces(p: &RefPack<4>, _d: &[f64; 3], u: &[[[f64; LANES]; 2]; 4], f: &mut [[[f64; LANES]; 2]; 4]) {
        forces::<Self, 4>(p, u, f)
    }
}

impl Blocked<3> for TestTri {
    const NAME: &'static str = "t3";
    type Pack = RefPack<3>;
    type Extra = ();
    fn pack(x: &[[[f64; 2]; 3]], d: &Dmat, t: f64) -> RefPack<3> {
        pack(x, d, t)
    }
    fn scaled_d(_d: &Dmat, _t: f64) -> [f64; 3] {
        [0.0; 3]
    }
    fn forces(p: &RefPack<3>, _d: &[f64; 3], u: &[[[f64; LANES]; 2]; 3], f: &mut [[[f64; LANES]; 2]; 3]) {
        forces::<Self, 3>(p, u, f)
    }
}

inventory::submit! { ElementKind::new::<TestQuad, 4>("test-only bilinear quadrilateral (core unit tests)") }
inventory::submit! { ElementKind::new::<TestTri, 3>("test-only linear triangle (core unit tests)") }
