//! `q4_closed` (ours, issue 42): the paper's bilinear quadrilateral `q4`, whose 2 x 2 Gauss sum
//! of a parallelogram is written in closed form: the centre point plus the exact hourglass
//! terms. The same element (shape functions, Gauss points, mass, stress, stiffness) and, in
//! exact arithmetic, the same internal force as `q4`; in floating point it differs by round-off
//! (other operations, other bits: 1.1e-15 of the largest force against `q4` on random
//! parallelograms, tested to 1e-12), which is why it is an option and `q4` stays the default.
//!
//! **Why it is exact.** On a parallelogram the Jacobian `J` is constant, and the parent
//! derivatives of `u` are linear in the natural coordinates: `u_,xi = a + eta h`,
//! `u_,eta = b + xi h` (`a, b, h` the corner combinations of [`super::q4`]). The integrand of a
//! Gauss point, `P = adj J^T D (adj J grad_xi u) / det J` (`super::parent_stress`), is linear in
//! them: `P(xi, eta) = P(c) + eta P(k1) + xi P(k2)` with `c = (a_x, b_x, a_y, b_y)`,
//! `k1 = (h_x, 0, h_y, 0)`, `k2 = (0, h_x, 0, h_y)`. Over the 4 points `(+-g, +-g)`,
//! `g = 1 / sqrt 3`: `sum xi = sum eta = sum xi eta = 0` and `sum xi^2 = sum eta^2 = 4 / 3`, so
//! the four sums the corner forces need (`q4`'s `assemble`) are
//!
//! ```text
//! sum P_s = 4 P(c)_s,   sum eta P_s = 4/3 P(k1)_s,   sum P_e = 4 P(c)_e,   sum xi P_e = 4/3 P(k2)_e
//! ```
//!
//! (`s`, `e`: the parent axes). The corner forces are then, per direction,
//! `f = [-(A - B) - (C - E), (A - B) - (C + E), (A + B) + (C + E), -(A + B) + (C - E)]` with
//! `A = P(c)_s`, `C = P(c)_e`, `B = P(k1)_s / 3`, `E = P(k2)_e / 3`: one full point and two
//! half points instead of four full points (59 multiplications and 51 additions or subtractions
//! per element, counted in the source with `abh_u` and the corner rows, against 142 and 122 in
//! `q4`'s lean `forces` counted the same way, negations not counted). This is the one-point
//! element with its exact hourglass stiffness (Belytschko & Bachrach 1986; Flanagan & Belytschko 1981 for the centre gradients),
//! not an hourglass *control*: no coefficient, nothing tuned. Packs holding a
//! non-parallelogram (`h` of the geometry not zero, where `J` varies over the element) keep
//! `q4`'s Gauss form.
//!
//! Everything but the elastic force kernel is `q4`'s, bit for bit: the mass, the stress, the
//! element stiffness (implicit check) and the stateful blocks (plastic laws, large strain: they
//! are `q4`'s blocks, and report their element as `q4`). The stable step's power iteration runs
//! on the forces, so it differs from `q4`'s in the last bits.
//!
//! Where it runs: packs of parallelograms in floating point (`h` exactly zero, as on the
//! generated rectangles and graded rectangles, and on any grid whose corner sums are exact);
//! a rotated or imported grid with decimal coordinates usually has `h` of round-off size and
//! takes `q4`'s form, with no gain.
//!
//! ```toml
//! [[material]]
//! young_modulus = 1000.0
//! poisson_ratio = 0.25
//! density = 1.0
//! element = "q4_closed"
//! ```
use flem_core::element::kernel::{Blocked, LANES};
use flem_core::element::law::LinearElastic;
use flem_core::element::registry::{stateful_block, ElementKind};
use flem_core::element::{Dmat, Shape};
use flem_core::mesh::CellKind;

use super::parent_stress;
use super::q4::{abh_u, Q4Extra, Q4Pack, Q4};

/// `q4` with the 2 x 2 Gauss sum of a parallelogram in closed form (ours).
#[derive(Copy, Clone, Default, Debug)]
pub struct Q4Closed;

// The stateful blocks (plastic laws, large strain) have no elastic force kernel: they are q4's,
// compiled once (a region of a plastic law reports its element as `q4`).
inventory::submit! { ElementKind::new::<Q4Closed, 4>("bilinear quadrilateral, q4's 2 x 2 Gauss forces in closed form on parallelograms (ours; q4 to round-off, faster)").with_stateful_elastic(stateful_block::<Q4, LinearElastic, 4>) }

impl Shape<4> for Q4Closed {
    const KIND: CellKind = CellKind::Q4;
    const CORNERS: [[f64; 2]; 4] = <Q4 as Shape<4>>::CORNERS;
    const GAUSS: &'static [([f64; 2], f64)] = <Q4 as Shape<4>>::GAUSS;
    #[inline(always)]
    fn n(xi: [f64; 2]) -> [f64; 4] {
        Q4::n(xi)
    }
    #[inline(always)]
    fn dn(xi: [f64; 2]) -> [[f64; 2]; 4] {
        Q4::dn(xi)
    }
    // No `total_*` form: the stateful blocks of this kind are `q4`'s (the registration and
    // `build_stateful`), so a stateful block of `Q4Closed` itself is never built.
}

const THIRD: f64 = 1.0 / 3.0;

/// The closed form of one lane of a parallelogram pack (module doc): the sums `[A, B, C, E]` of
/// the corner forces along x and along y.
#[inline(always)]
fn closed_sums(j: [f64; 4], inv: f64, d: &[f64; 3], a: [f64; 2], b: [f64; 2], h: [f64; 2]) -> [[f64; 4]; 2] {
    let [j11, j12, j21, j22] = j;
    let [d11, d12, d33] = *d;
    let (pxs, pxe, pys, pye) = parent_stress(j, inv, [a[0], b[0], a[1], b[1]], d);
    // The hourglass parts, `h inv / 3` (the strain's 1 / det J and the 1 / 3 of the sums).
    let k = inv * THIRD;
    let (hx, hy) = (h[0] * k, h[1] * k);
    // P(k1)_s: strain of the derivative (hx, 0, hy, 0) along xi-parent axes.
    let (exx, eyy, gxy) = (j22 * hx, -(j21 * hy), j22 * hy - j21 * hx);
    let (sxx, syy, sxy) = (d11 * exx + d12 * eyy, d12 * exx + d11 * eyy, d33 * gxy);
    let (bx, by) = (j22 * sxx - j21 * sxy, j22 * sxy - j21 * syy);
    // P(k2)_e: strain of (0, hx, 0, hy).
    let (exx, eyy, gxy) = (-(j12 * hx), j11 * hy, j11 * hx - j12 * hy);
    let (sxx, syy, sxy) = (d11 * exx + d12 * eyy, d12 * exx + d11 * eyy, d33 * gxy);
    let (ex, ey) = (j11 * sxy - j12 * sxx, j11 * syy - j12 * sxy);
    [[pxs, bx, pxe, ex], [pys, by, pye, ey]]
}

impl Blocked<4> for Q4Closed {
    const NAME: &'static str = "q4_closed";
    type Pack = Q4Pack;
    type Extra = Q4Extra;
    fn pack(x: &[[[f64; 2]; 4]], d: &Dmat, t: f64) -> Q4Pack {
        <Q4 as Blocked<4>>::pack(x, d, t)
    }
    fn extra(x: &[[[f64; 2]; 4]], d: &Dmat, t: f64) -> Option<Q4Extra> {
        <Q4 as Blocked<4>>::extra(x, d, t)
    }
    fn scaled_d(d: &Dmat, t: f64) -> [f64; 3] {
        <Q4 as Blocked<4>>::scaled_d(d, t)
    }
    /// A pack of parallelograms: the closed form (module doc).
    #[inline(always)]
    fn forces(p: &Q4Pack, d: &[f64; 3], u: &[[[f64; LANES]; 2]; 4], f: &mut [[[f64; LANES]; 2]; 4]) {
        for l in 0..LANES {
            let (aux, bux, hux) = abh_u(u[0][0][l], u[1][0][l], u[2][0][l], u[3][0][l]);
            let (auy, buy, huy) = abh_u(u[0][1][l], u[1][1][l], u[2][1][l], u[3][1][l]);
            let s = closed_sums([p.ax[l], p.ay[l], p.bx[l], p.by[l]], p.inv[l], d, [aux, auy], [bux, buy], [hux, huy]);
            for (k, [a, b, c, e]) in s.into_iter().enumerate() {
                let (amb, apb, cme, cpe) = (a - b, a + b, c - e, c + e);
                f[0][k][l] = -amb - cme;
                f[1][k][l] = amb - cpe;
                f[2][k][l] = apb + cpe;
                f[3][k][l] = cme - apb;
            }
        }
    }
    /// A pack holding a non-parallelogram: `q4`'s Gauss form.
    #[inline(always)]
    fn forces_extra(p: &Q4Pack, e: &Q4Extra, d: &[f64; 3], u: &[[[f64; LANES]; 2]; 4], f: &mut [[[f64; LANES]; 2]; 4]) {
        <Q4 as Blocked<4>>::forces_extra(p, e, d, u, f)
    }
}
