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
//! plus `1 / det J` at the 4 Gauss points: 10 f64 = 80 bytes per element. A pack whose
//! elements are all parallelograms (`h = 0`: every structured mesh) keeps only `a, b` and its
//! one `1 / det J` (5 f64 = 40 bytes per element, `Q4Pack`; issue 24 computed `1 / det J` in the
//! kernel from 32 bytes, issue 42 stores it: no division per pack); the others keep the other
//! 6 f64 in a `Q4Extra` beside it. Both forms give the same forces bit for bit on a
//! parallelogram (`full_pack` says when; tested). With
//! `adj J = det J * J^-1`, the force of a Gauss point is
//! `f_a = w t (adj J^T dN_a)^T sigma`, `sigma = D (adj J grad_xi u) / det J`, which is exactly
//! `element::internal_force` rearranged (equal to round-off, tested to 1e-12 relative). The
//! thickness and the Gauss weight are folded into the D matrix.
//!
//! **Never-yielded pass of a stateful block** (ours, session 11; `Shape::total_strains`,
//! `total_forces`, see [`total_geometry`]): the same parent form with the law's stress in
//! place of `D eps`, B-bar as `B^T (sigma - p I + p_bar I)` (`p_bar` the `det J`-weighted mean
//! of the points' in-plane mean stress); 40 bytes per element for a pack of parallelograms,
//! 120 for others; equal to the generic isoparametric pass to round-off (tested 1e-12).
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

use super::{parent_strain, parent_stress, pull_back};

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
    /// `ax, bx, ay, by, 1 / det J` (the parallelogram form, 40 bytes per element); see
    /// [`total_geometry`].
    const TOTAL_ROWS: usize = 5;
    /// `hx, hy`, `1 / det J` and `det J / sum det J` at the 4 Gauss points.
    const TOTAL_EXTRA_ROWS: usize = 10;
    fn total_geometry(x: &[[[f64; 2]; 4]; LANES], geo: &mut [[f64; LANES]], extra: &mut [[f64; LANES]]) -> bool {
        total_geometry(x, geo, extra)
    }
    #[inline(always)]
    fn total_strains<const BBAR: bool>(geo: &[[f64; LANES]], extra: Option<&[[f64; LANES]]>, u: &[[[f64; LANES]; 2]; 4], e: &mut [[[f64; LANES]; 4]; 4]) {
        let g: &[[f64; LANES]; 5] = geo.try_into().expect("q4: 5 rows per pack");
        match extra {
            None => total_strains_lean::<BBAR>(g, u, e),
            Some(x) => total_strains_full::<BBAR>(g, x.try_into().expect("q4: 10 extra rows"), u, e),
        }
    }
    #[inline(always)]
    fn total_forces<const BBAR: bool>(geo: &[[f64; LANES]], extra: Option<&[[f64; LANES]]>, s: &[[[f64; LANES]; 4]; 4], t: f64, f: &mut [[[f64; LANES]; 2]; 4]) {
        let g: &[[f64; LANES]; 5] = geo.try_into().expect("q4: 5 rows per pack");
        match extra {
            None => total_forces_lean::<BBAR>(g, s, t, f),
            Some(x) => total_forces_full::<BBAR>(g, x.try_into().expect("q4: 10 extra rows"), s, t, f),
        }
    }
}

/// The geometry of the never-yielded pass of a stateful block (`Shape::total_geometry`, ours,
/// session 11): rows `ax, bx, ay, by, 1 / det J` (`det J` of the centre, the one of a
/// parallelogram), and for a pack holding a non-parallelogram (some `h` not zero) the extra
/// rows `hx, hy`, `1 / det J_k` and the B-bar weights `det J_k / sum_j det J_j` of the 4 Gauss
/// points. The strain of point `(xi, eta)` is then `(adj J grad_xi u) / det J` with
/// `J = [[ax + eta hx, ay + eta hy], [bx + xi hx, by + xi hy]]` and the force
/// `f_a = t sum_k dN_a(k) . (adj J_k^T sigma_k)` (the Gauss weights are 1): the elastic
/// kernel's parent form (`parent_stress`), with the law's stress in place of `D eps`.
pub(crate) fn total_geometry(x: &[[[f64; 2]; 4]; LANES], geo: &mut [[f64; LANES]], extra: &mut [[f64; LANES]]) -> bool {
    let mut full = false;
    for (l, el) in x.iter().enumerate() {
        let (ax, bx, hx) = abh(el[0][0], el[1][0], el[2][0], el[3][0]);
        let (ay, by, hy) = abh(el[0][1], el[1][1], el[2][1], el[3][1]);
        (geo[0][l], geo[1][l], geo[2][l], geo[3][l], geo[4][l]) = (ax, bx, ay, by, 1.0 / (ax * by - ay * bx));
        (extra[0][l], extra[1][l]) = (hx, hy);
        let det: [f64; 4] = std::array::from_fn(|g| {
            let [xi, eta] = Q4_GP[g];
            (ax + eta * hx) * (by + xi * hy) - (ay + eta * hy) * (bx + xi * hx)
        });
        let sum = (det[0] + det[1]) + (det[2] + det[3]);
        for g in 0..4 {
            extra[2 + g][l] = 1.0 / det[g];
            extra[6 + g][l] = det[g] / sum;
        }
        full |= hx != 0.0 || hy != 0.0;
    }
    full
}

/// The parent derivatives `a, b, h` of the pack's displacements, lane `l`.
#[inline(always)]
fn u_abh(u: &[[[f64; LANES]; 2]; 4], l: usize) -> [(f64, f64, f64); 2] {
    [abh(u[0][0][l], u[1][0][l], u[2][0][l], u[3][0][l]), abh(u[0][1][l], u[1][1][l], u[2][1][l], u[3][1][l])]
}

/// [`Q4::total_strains`] of a pack of parallelograms (one Jacobian per element; the B-bar
/// mean is the mean of the 4 points, whose `det J` are equal).
#[inline(always)]
fn total_strains_lean<const BBAR: bool>(g: &[[f64; LANES]; 5], u: &[[[f64; LANES]; 2]; 4], e: &mut [[[f64; LANES]; 4]; 4]) {
    for l in 0..LANES {
        let [(aux, bux, hux), (auy, buy, huy)] = u_abh(u, l);
        let j = [g[0][l], g[2][l], g[1][l], g[3][l]];
        let inv = g[4][l];
        let mut ev = 0.0;
        for (k, &[xi, eta]) in Q4_GP.iter().enumerate() {
            let p = parent_strain(j, inv, [aux + eta * hux, bux + xi * hux, auy + eta * huy, buy + xi * huy]);
            (e[k][0][l], e[k][1][l], e[k][2][l]) = (p[0], p[1], p[2]);
            ev += p[0] + p[1];
        }
        if BBAR {
            ev *= 0.25;
            for ek in e.iter_mut() {
                let c = 0.5 * (ev - (ek[0][l] + ek[1][l]));
                ek[0][l] += c;
                ek[1][l] += c;
            }
        }
    }
}

/// [`Q4::total_strains`] of a pack holding a non-parallelogram (a Jacobian per point; the
/// B-bar mean weighted by `det J`).
#[inline(always)]
fn total_strains_full<const BBAR: bool>(g: &[[f64; LANES]; 5], x: &[[f64; LANES]; 10], u: &[[[f64; LANES]; 2]; 4], e: &mut [[[f64; LANES]; 4]; 4]) {
    for l in 0..LANES {
        let [(aux, bux, hux), (auy, buy, huy)] = u_abh(u, l);
        let (ax, bx, ay, by, hx, hy) = (g[0][l], g[1][l], g[2][l], g[3][l], x[0][l], x[1][l]);
        let mut ev = 0.0;
        for (k, &[xi, eta]) in Q4_GP.iter().enumerate() {
            let j = [ax + eta * hx, ay + eta * hy, bx + xi * hx, by + xi * hy];
            let p = parent_strain(j, x[2 + k][l], [aux + eta * hux, bux + xi * hux, auy + eta * huy, buy + xi * huy]);
            (e[k][0][l], e[k][1][l], e[k][2][l]) = (p[0], p[1], p[2]);
            ev += x[6 + k][l] * (p[0] + p[1]);
        }
        if BBAR {
            for ek in e.iter_mut() {
                let c = 0.5 * (ev - (ek[0][l] + ek[1][l]));
                ek[0][l] += c;
                ek[1][l] += c;
            }
        }
    }
}

/// Lane `l`'s corner forces of the point stresses `s` (`j(xi, eta)`: the Jacobian at a Gauss
/// point; B-bar: each point's in-plane mean stress replaced by `pbar`), shared by both forms.
#[inline(always)]
fn point_forces<const BBAR: bool>(j: impl Fn(f64, f64) -> [f64; 4], s: &[[[f64; LANES]; 4]; 4], pbar: f64, t: f64, l: usize, f: &mut [[[f64; LANES]; 2]; 4]) {
    let mut acc = [[0.0; 4]; 2];
    for (k, &[xi, eta]) in Q4_GP.iter().enumerate() {
        let (mut sxx, mut syy, sxy) = (s[k][0][l], s[k][1][l], s[k][2][l]);
        if BBAR {
            let c = pbar - 0.5 * (sxx + syy);
            sxx += c;
            syy += c;
        }
        add_point(&mut acc, xi, eta, pull_back(j(xi, eta), t * sxx, t * syy, t * sxy));
    }
    assemble(acc, l, f);
}

/// [`Q4::total_forces`] of a pack of parallelograms. B-bar: `Bbar^T sigma = B^T (sigma - p I
/// + p_bar I)` with `p = (sxx + syy) / 2` of the point and `p_bar` its mean over the element
/// weighted by `det J` (`sum_k c_k Bbar_k^T s_k` with the mean gradient `sum_k c_k B_k / sum c`).
#[inline(always)]
fn total_forces_lean<const BBAR: bool>(g: &[[f64; LANES]; 5], s: &[[[f64; LANES]; 4]; 4], t: f64, f: &mut [[[f64; LANES]; 2]; 4]) {
    for l in 0..LANES {
        let j = [g[0][l], g[2][l], g[1][l], g[3][l]];
        let mut pbar = 0.0;
        if BBAR {
            for sk in s.iter() {
                pbar += sk[0][l] + sk[1][l];
            }
            pbar *= 0.125;
        }
        point_forces::<BBAR>(|_, _| j, s, pbar, t, l, f);
    }
}

/// [`Q4::total_forces`] of a pack holding a non-parallelogram.
#[inline(always)]
fn total_forces_full<const BBAR: bool>(g: &[[f64; LANES]; 5], x: &[[f64; LANES]; 10], s: &[[[f64; LANES]; 4]; 4], t: f64, f: &mut [[[f64; LANES]; 2]; 4]) {
    for l in 0..LANES {
        let (ax, bx, ay, by, hx, hy) = (g[0][l], g[1][l], g[2][l], g[3][l], x[0][l], x[1][l]);
        let mut pbar = 0.0;
        if BBAR {
            for (k, sk) in s.iter().enumerate() {
                pbar += x[6 + k][l] * (sk[0][l] + sk[1][l]);
            }
            pbar *= 0.5;
        }
        point_forces::<BBAR>(|xi, eta| [ax + eta * hx, ay + eta * hy, bx + xi * hx, by + xi * hy], s, pbar, t, l, f);
    }
}

/// Geometry of `LANES` elements, all a pack needs when every element of it is a parallelogram
/// (`h = 0`): `dx/dxi = a`, `dx/deta = b`, one Jacobian and its `1 / det J` for the whole element (40 bytes each).
#[derive(Copy, Clone, Debug)]
#[repr(C, align(64))]
pub struct Q4Pack {
    pub(crate) ax: [f64; LANES],
    pub(crate) bx: [f64; LANES],
    pub(crate) ay: [f64; LANES],
    pub(crate) by: [f64; LANES],
    /// `1 / det J` of the (parallelogram) element, `0` for an empty lane.
    pub(crate) inv: [f64; LANES],
}

/// The rest of the geometry of a pack holding a non-parallelogram: `h` of x and y and
/// `1 / det J` at the 4 Gauss points (48 bytes each; kept only for such packs).
#[derive(Copy, Clone, Debug)]
#[repr(C, align(64))]
pub struct Q4Extra {
    hx: [f64; LANES],
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

/// [`abh`] of a displacement field in the force kernel, with `h` from the two differences `a`
/// has already formed: `(v0 - v1) + (v2 - v3)` is `(v2 - v3) - (v1 - v0)` but for the sign of a
/// zero (one subtraction per field fewer, issue 42; a zero's sign reaches no node force, see
/// [`first_point`]).
#[inline(always)]
pub(crate) fn abh_u(v0: f64, v1: f64, v2: f64, v3: f64) -> (f64, f64, f64) {
    let (d10, d23) = (v1 - v0, v2 - v3);
    (0.25 * (d10 + d23), 0.25 * ((v3 - v0) + (v2 - v1)), 0.25 * (d23 - d10))
}

/// The whole geometry of a pack (`Q4Pack` and `Q4Extra`), and whether the lean form (the pack
/// alone) gives the same forces bit for bit: every `h` is zero, so that `a + eta h` is `a`
/// exactly (true unless `a` is -0.0, hence that exclusion), and every `det J` is finite and
/// non-zero, so that `forces` recomputes the one `1 / det J` from the same expression.
pub(crate) fn full_pack(x: &[[[f64; 2]; 4]]) -> (Q4Pack, Q4Extra, bool) {
    let z = [0.0; LANES];
    let (mut p, mut e) = (Q4Pack { ax: z, bx: z, ay: z, by: z, inv: z }, Q4Extra { hx: z, hy: z, inv: [z; 4] });
    let mut lean = true;
    for (l, el) in x.iter().enumerate().take(LANES) {
        let (ax, bx, hx) = abh(el[0][0], el[1][0], el[2][0], el[3][0]);
        let (ay, by, hy) = abh(el[0][1], el[1][1], el[2][1], el[3][1]);
        (p.ax[l], p.bx[l], p.ay[l], p.by[l], e.hx[l], e.hy[l]) = (ax, bx, ay, by, hx, hy);
        for (g, &[xi, eta]) in Q4_GP.iter().enumerate() {
            let (j11, j12, j21, j22) = (ax + eta * hx, ay + eta * hy, bx + xi * hx, by + xi * hy);
            e.inv[g][l] = 1.0 / (j11 * j22 - j12 * j21);
        }
        // The lean form's `1 / det J`, as it was computed in the kernel before (issue 42).
        let det = ax * by - ay * bx;
        p.inv[l] = if det == 0.0 { 0.0 } else { 1.0 / det };
        let not_neg_zero = [ax, bx, ay, by].iter().all(|v| v.to_bits() != (-0.0f64).to_bits());
        lean &= hx == 0.0 && hy == 0.0 && not_neg_zero && e.inv[0][l].is_finite();
    }
    (p, e, lean)
}

/// Corner forces from the Gauss-point sums `S` (of P) and `T` (of P times the other
/// coordinate), `[sxs, txs, sxe, txe]` per direction, into lane `l` of `f`:
/// `f_a = 1/4 [xi_a (S_s + eta_a T_s) + eta_a (S_e + xi_a T_e)]`, corners (-,-) (+,-) (+,+) (-,+).
#[inline(always)]
fn assemble(s: [[f64; 4]; 2], l: usize, f: &mut [[[f64; LANES]; 2]; 4]) {
    for (k, [ss, ts, se, te]) in s.into_iter().enumerate() {
        f[0][k][l] = 0.25 * (-(ss - ts) - (se - te));
        f[1][k][l] = 0.25 * ((ss - ts) - (se + te));
        f[2][k][l] = 0.25 * ((ss + ts) + (se + te));
        f[3][k][l] = 0.25 * (-(ss + ts) + (se - te));
    }
}

/// The sums of [`assemble`] of the first Gauss point alone (`0 + x` spelled `x`: 8 additions
/// per element fewer in a kernel bound by its additions, issue 42). The only difference from
/// adding to zeros is the sign of a zero sum (`0.0 + -0.0` is `+0.0`), which no node force can
/// see: a corner force is only ever added to a node's sum, which starts at `+0.0`, and
/// `x + -0.0 == x + 0.0` bit for bit for every `x` but `-0.0`.
#[inline(always)]
fn first_point(xi: f64, eta: f64, p: (f64, f64, f64, f64)) -> [[f64; 4]; 2] {
    let (pxs, pxe, pys, pye) = p;
    [[pxs, eta * pxs, pxe, xi * pxe], [pys, eta * pys, pye, xi * pye]]
}

/// The Gauss-point sums of an element's 4 points, in `Q4_GP`'s order (`point(xi, eta)`: its
/// integrand), as [`add_point`] from zeros gives them up to the sign of a zero (see [`first_point`]).
#[inline(always)]
fn point_sums(mut point: impl FnMut(usize, f64, f64) -> (f64, f64, f64, f64)) -> [[f64; 4]; 2] {
    let [xi0, eta0] = Q4_GP[0];
    let mut s = first_point(xi0, eta0, point(0, xi0, eta0));
    for (g, &[xi, eta]) in Q4_GP.iter().enumerate().skip(1) {
        add_point(&mut s, xi, eta, point(g, xi, eta));
    }
    s
}

/// Adds the integrand of Gauss point `(xi, eta)` to the sums of [`assemble`].
#[inline(always)]
fn add_point(s: &mut [[f64; 4]; 2], xi: f64, eta: f64, p: (f64, f64, f64, f64)) {
    let (pxs, pxe, pys, pye) = p;
    for (sk, (ps, pe)) in s.iter_mut().zip([(pxs, pxe), (pys, pye)]) {
        sk[0] += ps;
        sk[1] += eta * ps;
        sk[2] += pe;
        sk[3] += xi * pe;
    }
}

impl Blocked<4> for Q4 {
    const NAME: &'static str = "q4";
    type Pack = Q4Pack;
    type Extra = Q4Extra;
    fn pack(x: &[[[f64; 2]; 4]], _d: &Dmat, _t: f64) -> Q4Pack {
        full_pack(x).0
    }
    fn extra(x: &[[[f64; 2]; 4]], _d: &Dmat, _t: f64) -> Option<Q4Extra> {
        let (_, e, lean) = full_pack(x);
        (!lean).then_some(e)
    }
    fn scaled_d(d: &Dmat, t: f64) -> [f64; 3] {
        [d.d11 * t, d.d12 * t, d.d33 * t]
    }
    /// The lean form: every element of the pack a parallelogram (see [`full_pack`]).
    #[inline(always)]
    fn forces(p: &Q4Pack, d: &[f64; 3], u: &[[[f64; LANES]; 2]; 4], f: &mut [[[f64; LANES]; 2]; 4]) {
        for l in 0..LANES {
            let (aux, bux, hux) = abh_u(u[0][0][l], u[1][0][l], u[2][0][l], u[3][0][l]);
            let (auy, buy, huy) = abh_u(u[0][1][l], u[1][1][l], u[2][1][l], u[3][1][l]);
            let (j11, j12, j21, j22) = (p.ax[l], p.ay[l], p.bx[l], p.by[l]);
            let inv = p.inv[l];
            let s = point_sums(|_, xi, eta| {
                let (uxs, uxe, uys, uye) = (aux + eta * hux, bux + xi * hux, auy + eta * huy, buy + xi * huy);
                parent_stress([j11, j12, j21, j22], inv, [uxs, uxe, uys, uye], d)
            });
            assemble(s, l, f);
        }
    }
    /// The general form: the Jacobian and `1 / det J` of each Gauss point.
    #[inline(always)]
    fn forces_extra(p: &Q4Pack, e: &Q4Extra, d: &[f64; 3], u: &[[[f64; LANES]; 2]; 4], f: &mut [[[f64; LANES]; 2]; 4]) {
        for l in 0..LANES {
            let (aux, bux, hux) = abh_u(u[0][0][l], u[1][0][l], u[2][0][l], u[3][0][l]);
            let (auy, buy, huy) = abh_u(u[0][1][l], u[1][1][l], u[2][1][l], u[3][1][l]);
            let (ax, bx, hx, ay, by, hy) = (p.ax[l], p.bx[l], e.hx[l], p.ay[l], p.by[l], e.hy[l]);
            let s = point_sums(|g, xi, eta| {
                let (j11, j12, j21, j22) = (ax + eta * hx, ay + eta * hy, bx + xi * hx, by + xi * hy);
                let (uxs, uxe, uys, uye) = (aux + eta * hux, bux + xi * hux, auy + eta * huy, buy + xi * huy);
                parent_stress([j11, j12, j21, j22], e.inv[g][l], [uxs, uxe, uys, uye], d)
            });
            assemble(s, l, f);
        }
    }
}
