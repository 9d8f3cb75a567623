//! Stress intensity factors at a crack tip from a linear elastic solution (issue 34, "Must
//! show 1"): the interaction integral in its domain form, with the maximum tangential stress
//! kink angle from the two factors. A post-processing of a displacement field (the implicit check
//! solve: `flem sif`, `tools/src/sif.rs`); nothing here runs in the explicit step.
//!
//! **Tips.** A crack face is an interior element edge whose two elements' copies are in different
//! clusters at one end at least (`Topology::is_separated_at`). A crack *tip* is the end `q` of a
//! crack face that is still joined at `q` while separated at its other end `p`: the last node of
//! a pre-cut edge set ending inside the body, or the far ends of the edges a split cut. The crack
//! runs from `p` to `q`; its direction at the tip is `e1 = (q - p) / |q - p|` ([`crack_tips`]).
//!
//! **Interaction integral** (Yau, Wang & Corten 1980, J. Appl. Mech. 47, 335; domain form as in
//! Moës, Dolbow & Belytschko 1999, IJNME 46, 131, eqs. 12-19). In the tip's frame (`x1 = e1`,
//! `x2` counter-clockwise from it, crack faces along `theta = +-pi`), with the FE field (1) and an
//! auxiliary Williams field (2) of unit `K_I` or `K_II`,
//!
//! ```text
//! I(1,2) = int_A [ s1_ij du2_i/dx1 + s2_ij du1_i/dx1 - W(1,2) delta_1j ] dq/dx_j dA,
//! W(1,2) = s1_ij e2_ij,
//! K_I = E* I(1, mode I) / 2,   K_II = E* I(1, mode II) / 2,
//! E* = E (plane stress),  E / (1 - nu^2) (plane strain),
//! J = int_A [ s_ij du_i/dx1 - W delta_1j ] dq/dx_j dA,   W = s_ij e_ij / 2  (the check: J = G),
//! G = (K_I^2 + K_II^2) / E*.
//! ```
//!
//! The weight `q` is 1 inside `r_in`, falls linearly to 0 at `r_out` (distance from the tip) and
//! is interpolated from its corner values by the element's shape functions; only elements with a
//! non-zero `grad q` contribute. Auxiliary fields (Williams 1957; Anderson, Fracture Mechanics,
//! table 2.1/2.2), `mu` the shear modulus, `kappa = 3 - 4 nu` (plane strain) or
//! `(3 - nu) / (1 + nu)` (plane stress), `c = cos(theta/2)`, `s = sin(theta/2)`:
//!
//! ```text
//! mode I :  u1 = sqrt(r/2pi)/(2mu) c (kappa - 1 + 2 s^2),   u2 = sqrt(r/2pi)/(2mu) s (kappa + 1 - 2 c^2)
//!           s11 = c (1 - s sin(3theta/2)) / sqrt(2 pi r),   s22 = c (1 + s sin(3theta/2)) / sqrt(2 pi r),
//!           s12 = s c cos(3theta/2) / sqrt(2 pi r)
//! mode II:  u1 = sqrt(r/2pi)/(2mu) s (kappa + 1 + 2 c^2),   u2 = -sqrt(r/2pi)/(2mu) c (kappa - 1 - 2 s^2)
//!           s11 = -s (2 + c cos(3theta/2)) / sqrt(2 pi r),  s22 = s c cos(3theta/2) / sqrt(2 pi r),
//!           s12 = c (1 - s sin(3theta/2)) / sqrt(2 pi r)
//! ```
//!
//! The displacement gradients are the exact derivatives of these (`aux_field`; the unit test
//! checks that `D` times their symmetric part is the stress above). Quadrature: 3 x 3 Gauss
//! points on `q4`, the 6-point degree-4 rule on `t3` (Strang & Fix), more than the elements'
//! own rules because the auxiliary field is not polynomial. `qm6` (and any kind with condensed
//! internal fields) is refused by name: its strain is not the gradient of the corner
//! interpolation. So are material laws with history and co-rotational blocks (not linear).
//!
//! **Kink angle** (maximum tangential stress, Erdogan & Sih 1963; rationalised form, e.g. MOOSE
//! after its issue 29921): `theta = 2 atan(-2 r / (1 + sqrt(1 + 8 r^2)))`, `r = K_II / K_I`,
//! measured from the crack's own direction `e1`, positive counter-clockwise. Pure mode I: 0;
//! `r -> +inf`: -70.53 deg. Defined for `K_I > 0` (and for `K_I = 0`, the limit); a closed crack
//! (`K_I < 0`) has none.
//!
//! **Domain checks** (each a named [`SifError`]): the disc of radius `r_out` must not reach the
//! body's outer boundary, must hold no support and no applied nodal force (gravity included:
//! no body-force or crack-face-traction term is integrated), must see the crack only as straight
//! faces behind the tip along `-e1` (no kink, no other crack, no other tip), and every element
//! in it must be a linear elastic `q4` (or `q4_closed`, the same element) or `t3` of one material.
use flem_core::element::model::Model;
use flem_core::element::{self, Material, Plane, Shape};
use flem_core::ids::EdgeId;
use serde::Serialize;

use crate::elements::{Q4, T3};

/// A crack tip: its point, position and the crack's direction there.
#[derive(Clone, Debug, Serialize)]
pub struct CrackTip {
    /// Index of the mesh point (0-based).
    pub point: usize,
    pub x: [f64; 2],
    /// Unit vector from the crack into the body ahead of the tip.
    pub dir: [f64; 2],
    /// Index of the crack face ending at the tip.
    pub edge: usize,
    /// Mean length of the element edges through the tip (the element size there).
    pub h: f64,
    /// Crack faces ending at the tip: more than one (two cracks meeting, a branch) leaves the
    /// direction undefined and [`domain_sif`] refuses the tip ([`SifError::AmbiguousTip`]);
    /// `dir` is then the first face's.
    pub faces: usize,
}

impl CrackTip {
    /// `p` in the tip's frame: origin at the tip, x' along `dir` (ahead of the crack), y' to its
    /// left.
    pub fn local(&self, p: [f64; 2]) -> [f64; 2] {
        self.rotate([p[0] - self.x[0], p[1] - self.x[1]])
    }

    /// A vector (a displacement, a jump) in the tip's frame's axes.
    pub fn rotate(&self, v: [f64; 2]) -> [f64; 2] {
        let (e1, e2) = (self.dir, [-self.dir[1], self.dir[0]]);
        [v[0] * e1[0] + v[1] * e1[1], v[0] * e2[0] + v[1] * e2[1]]
    }
}

/// Why the factors cannot be computed (every message names the tip or the element).
#[derive(Debug, thiserror::Error)]
pub enum SifError {
    #[error("no crack tip found: no crack face (a pre-cut or separated edge) ends inside the body")]
    NoTip,
    #[error("the point ({x}, {y}) is not on a crack tip: the nearest tip is point {point} at ({tx}, {ty}), {dist:.3e} away (more than half the element size there, {tol:.3e})")]
    NotATip { x: f64, y: f64, point: usize, tx: f64, ty: f64, dist: f64, tol: f64 },
    #[error("crack tip at point {point}: {n} crack faces end there; the crack direction is ambiguous")]
    AmbiguousTip { point: usize, n: usize },
    #[error("crack tip at point {point}: radii r_in = {r_in:e}, r_out = {r_out:e} are incorrect; they must be finite with 0 <= r_in < r_out")]
    BadRadius { point: usize, r_in: f64, r_out: f64 },
    #[error("crack tip at point {point}: the domain of radius {r_out:e} leaves the body (it reaches the boundary edge of points {a} and {b}); use a smaller radius")]
    DomainLeavesBody { point: usize, r_out: f64, a: usize, b: usize },
    #[error("crack tip at point {point}: the crack is not straight inside the domain of radius {r_out:e} (crack face of points {a} and {b} is off the line behind the tip by {off:.3e}, or ahead of it); use a smaller radius")]
    CrackNotStraight { point: usize, r_out: f64, a: usize, b: usize, off: f64 },
    #[error("crack tip at point {point}: another crack tip (point {other}) lies inside the domain of radius {r_out:e}; use a smaller radius")]
    OtherTip { point: usize, r_out: f64, other: usize },
    #[error("crack tip at point {point}: a support acts inside the domain of radius {r_out:e} (point {at}); use a smaller radius")]
    SupportInDomain { point: usize, r_out: f64, at: usize },
    #[error("crack tip at point {point}: an applied force (a point load, gravity or a crack-face traction) acts inside the domain of radius {r_out:e} (point {at}); the integral has no such term; use a smaller radius or no body force")]
    LoadInDomain { point: usize, r_out: f64, at: usize },
    #[error("crack tip at point {point}: element {elem} is of kind \"{kind}\"; the interaction integral supports the isoparametric kinds \"q4\", \"q4_closed\" (as q4) and \"t3\" (\"qm6\" has condensed internal modes)")]
    UnsupportedElement { point: usize, elem: usize, kind: String },
    #[error(
        "crack tip at point {point}: element {elem} is not linear elastic (a material law with history, large strain or co-rotational kinematics); the interaction integral needs linear elasticity"
    )]
    NotLinear { point: usize, elem: usize },
    #[error("crack tip at point {point}: the material changes inside the domain (element {elem}); the interaction integral needs one homogeneous material there")]
    MaterialChanges { point: usize, elem: usize },
    #[error("crack tip at point {point}: no element has a weight gradient in the ring {r_in:e} < r < {r_out:e}; use a larger radius")]
    EmptyDomain { point: usize, r_in: f64, r_out: f64 },
    #[error("crack tip at point {point}: the integral is not finite (a displacement or a coordinate is not finite)")]
    NotFinite { point: usize },
}

/// The integrals on one domain.
#[derive(Clone, Debug, Serialize)]
pub struct DomainSif {
    pub r_in: f64,
    pub r_out: f64,
    /// Elements with a weight gradient (the ring).
    pub elements: usize,
    pub k1: f64,
    pub k2: f64,
    /// The J integral (domain form).
    pub j: f64,
    /// `(K_I^2 + K_II^2) / E*`.
    pub g: f64,
    /// `E*` of the material in the domain.
    pub e_star: f64,
}

/// Everything needed at one tip besides the field: `E*` and the material.
fn e_star(m: &Material) -> f64 {
    match m.plane {
        Plane::Strain => m.young / (1.0 - m.poisson * m.poisson),
        Plane::Stress => m.young,
    }
}

/// The maximum tangential stress kink angle (radians, from the crack's direction, positive
/// counter-clockwise): `2 atan(-2 r / (1 + sqrt(1 + 8 r^2)))`, `r = K_II / K_I`. `None` for a
/// closed crack (`K_I < 0`) or no loading at all.
pub fn mts_angle(k1: f64, k2: f64) -> Option<f64> {
    if !(k1.is_finite() && k2.is_finite()) || k1 < 0.0 || (k1 == 0.0 && k2 == 0.0) {
        return None;
    }
    if k1 == 0.0 {
        // r -> +-inf: theta -> -+2 atan(1/sqrt 2) = -+70.53 deg.
        return Some(-k2.signum() * 2.0 * (1.0 / 2f64.sqrt()).atan());
    }
    let r = k2 / k1;
    Some(2.0 * (-2.0 * r / (1.0 + (1.0 + 8.0 * r * r).sqrt())).atan())
}

/// Every crack tip of the model's current topology, in point order (see the module doc).
pub fn crack_tips(model: &Model) -> Vec<CrackTip> {
    let topo = &model.topo;
    let pts = &model.mesh.points;
    // (tip point, crack face) pairs.
    let ends = topo.joined_crack_ends();
    let mut tips = Vec::new();
    let mut i = 0;
    while i < ends.len() {
        let p = ends[i].0;
        let n = ends[i..].iter().take_while(|(q, _)| *q == p).count();
        let e = ends[i].1;
        let other = topo.other_end(e, p);
        let (x, o) = (pts[p.idx()], pts[other.idx()]);
        let d = [x[0] - o[0], x[1] - o[1]];
        let len = d[0].hypot(d[1]);
        let h = flem_core::cracking::path::size_at(topo, pts, p);
        tips.push(CrackTip { point: p.idx(), x, dir: [d[0] / len, d[1] / len], edge: e.idx(), h, faces: n });
        i += n;
    }
    tips
}

/// The tip nearest `x`; an error when none is within half the element size there.
pub fn tip_near(tips: &[CrackTip], x: [f64; 2]) -> Result<&CrackTip, SifError> {
    let d = |t: &CrackTip| (t.x[0] - x[0]).hypot(t.x[1] - x[1]);
    let t = tips.iter().min_by(|a, b| d(a).total_cmp(&d(b))).ok_or(SifError::NoTip)?;
    if d(t) > 0.5 * t.h {
        return Err(SifError::NotATip { x: x[0], y: x[1], point: t.point, tx: t.x[0], ty: t.x[1], dist: d(t), tol: 0.5 * t.h });
    }
    Ok(t)
}

/// Distance from `p` to the segment `a`-`b`.
fn seg_dist(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 { (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0) } else { 0.0 };
    (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
}

/// The elements that come within `r_out` of the tip (as `(block, local index)`, in the order of
/// a pass over the blocks) and the edges at their corners (in id order): a breadth-first
/// search from the elements at the tip point through shared mesh points, going on from an
/// element only when one of its sides comes within `r_out` (ours, issue 34 must-show 5: the
/// integral's cost is that of the tip's neighbourhood, not of the model). When the disc lies
/// inside the body (every accepted domain) these are all of the model's elements and edges
/// that the disc reaches, so the sums run over the same elements in the same order as a pass
/// over the whole model: the factors are bit for bit the same. A disc that reaches the outer
/// boundary meets a boundary edge among these, and is refused as before.
fn near_tip(model: &Model, tip: &CrackTip, r_out: f64) -> (Vec<(u32, u32)>, Vec<EdgeId>) {
    let topo = &model.topo;
    let pts = &model.mesh.points;
    // The visited elements and corners as sorted vectors (a binary search and an insert each:
    // the sets hold a few hundred ids; cheaper than a tree's nodes, same members).
    let insert = |set: &mut Vec<usize>, x: usize| match set.binary_search(&x) {
        Ok(_) => false,
        Err(at) => {
            set.insert(at, x);
            true
        }
    };
    let mut stack: Vec<usize> = topo.point_copies.row(tip.point).iter().map(|&k| topo.copy_elem[k.idx()].idx()).collect();
    let mut seen: Vec<usize> = stack.clone();
    seen.sort_unstable();
    seen.dedup();
    let mut inside: Vec<usize> = Vec::new();
    let mut corners: Vec<usize> = Vec::new();
    while let Some(e) = stack.pop() {
        let cs = model.mesh.cells[e].corners();
        let n = cs.len();
        let at_tip = cs.iter().any(|&c| c as usize == tip.point);
        let near = at_tip || (0..n).any(|a| seg_dist(tip.x, pts[cs[a] as usize], pts[cs[(a + 1) % n] as usize]) < r_out);
        if !near {
            continue;
        }
        inside.push(e);
        for &c in cs {
            if insert(&mut corners, c as usize) {
                for &k in topo.point_copies.row(c as usize) {
                    let f = topo.copy_elem[k.idx()].idx();
                    if insert(&mut seen, f) {
                        stack.push(f);
                    }
                }
            }
        }
    }
    let mut slots: Vec<(u32, u32)> = inside.iter().map(|&e| model.elem_slot[e]).collect();
    slots.sort_unstable();
    let mut edges: Vec<EdgeId> = corners.iter().flat_map(|&c| topo.point_edges.row(c).iter().copied()).collect();
    edges.sort_unstable();
    edges.dedup();
    (slots, edges)
}

/// Checks the domain's geometry: the outer boundary and the crack faces.
fn check_geometry(model: &Model, tip: &CrackTip, r_out: f64, tol: f64, edges: &[EdgeId]) -> Result<(), SifError> {
    let topo = &model.topo;
    let pts = &model.mesh.points;
    let local = |p: [f64; 2]| tip.local(p);
    for &e in edges {
        let (e, ed) = (e.idx(), &topo.edges[e.idx()]);
        let [a, b] = ed.points;
        let (pa, pb) = (pts[a.idx()], pts[b.idx()]);
        if seg_dist(tip.x, pa, pb) >= r_out {
            continue;
        }
        if ed.sides[1].is_none() {
            return Err(SifError::DomainLeavesBody { point: tip.point, r_out, a: a.idx(), b: b.idx() });
        }
        let e = EdgeId::new(e);
        let (sa, sb) = (topo.is_separated_at(e, a), topo.is_separated_at(e, b));
        if sa != sb {
            let q = if sa { b } else { a };
            let pq = pts[q.idx()];
            if q.idx() != tip.point && (pq[0] - tip.x[0]).hypot(pq[1] - tip.x[1]) < r_out {
                return Err(SifError::OtherTip { point: tip.point, r_out, other: q.idx() });
            }
        }
        if sa || sb {
            let (la, lb) = (local(pa), local(pb));
            let off = la[1].abs().max(lb[1].abs());
            if off > tol || la[0] > tol || lb[0] > tol {
                return Err(SifError::CrackNotStraight { point: tip.point, r_out, a: a.idx(), b: b.idx(), off });
            }
        }
    }
    Ok(())
}

/// The Williams field of unit `K` (mode I when `mode2` is false) at local polar `(r, theta)`:
/// the displacement gradient `[[du1/dx1, du1/dx2], [du2/dx1, du2/dx2]]` and the stress
/// `[s11, s22, s12]`, both in the tip's frame.
pub fn aux_field(mode2: bool, r: f64, th: f64, mu: f64, kappa: f64) -> ([[f64; 2]; 2], [f64; 3]) {
    let (s, c) = (0.5 * th).sin_cos();
    let (s3, c3) = (1.5 * th).sin_cos();
    let (f, df) = if !mode2 {
        ([c * (kappa - 1.0 + 2.0 * s * s), s * (kappa + 1.0 - 2.0 * c * c)], [-0.5 * s * (kappa - 1.0) - s * s * s + 2.0 * s * c * c, 0.5 * c * (kappa + 1.0) - c * c * c + 2.0 * s * s * c])
    } else {
        ([s * (kappa + 1.0 + 2.0 * c * c), -c * (kappa - 1.0) + 2.0 * c * s * s], [0.5 * c * (kappa + 1.0) + c * c * c - 2.0 * s * s * c, 0.5 * s * (kappa - 1.0) - s * s * s + 2.0 * s * c * c])
    };
    let k = 1.0 / (2.0 * mu * (2.0 * std::f64::consts::PI * r).sqrt());
    let (st, ct) = th.sin_cos();
    let g = std::array::from_fn(|i| [k * (ct * 0.5 * f[i] - st * df[i]), k * (st * 0.5 * f[i] + ct * df[i])]);
    let a = 1.0 / (2.0 * std::f64::consts::PI * r).sqrt();
    let sig = if !mode2 { [a * c * (1.0 - s * s3), a * c * (1.0 + s * s3), a * s * c * c3] } else { [-a * s * (2.0 + c * c3), a * s * c * c3, a * c * (1.0 - s * s3)] };
    (g, sig)
}

/// 3 x 3 Gauss points of the square [-1, 1]^2.
fn gauss_q4() -> [([f64; 2], f64); 9] {
    let (p, w) = ([-(0.6f64).sqrt(), 0.0, (0.6f64).sqrt()], [5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0]);
    std::array::from_fn(|k| ([p[k % 3], p[k / 3]], w[k % 3] * w[k / 3]))
}

/// The 6-point degree-4 rule of the reference triangle (area 1/2; Strang & Fix).
fn gauss_t3() -> [([f64; 2], f64); 6] {
    let (a1, b1, w1) = (0.445_948_490_915_965, 0.108_103_018_168_070, 0.5 * 0.223_381_589_678_011);
    let (a2, b2, w2) = (0.091_576_213_509_771, 0.816_847_572_980_459, 0.5 * 0.109_951_743_655_322);
    [([a1, a1], w1), ([b1, a1], w1), ([a1, b1], w1), ([a2, a2], w2), ([b2, a2], w2), ([a2, b2], w2)]
}

/// Running sums of one domain.
#[derive(Default)]
struct Sums {
    i1: f64,
    i2: f64,
    j: f64,
    elements: usize,
}

/// Frame and material constants of one domain.
struct Frame {
    tip: [f64; 2],
    e1: [f64; 2],
    e2: [f64; 2],
    mu: f64,
    kappa: f64,
    r_in: f64,
    r_out: f64,
}

impl Frame {
    fn q(&self, x: [f64; 2]) -> f64 {
        let r = (x[0] - self.tip[0]).hypot(x[1] - self.tip[1]);
        if r <= self.r_in {
            1.0
        } else if r >= self.r_out {
            0.0
        } else {
            (self.r_out - r) / (self.r_out - self.r_in)
        }
    }
    /// Global 2-vector to the tip's frame.
    fn vec(&self, v: [f64; 2]) -> [f64; 2] {
        [v[0] * self.e1[0] + v[1] * self.e1[1], v[0] * self.e2[0] + v[1] * self.e2[1]]
    }
    /// `R A R^T` of a global 2 x 2 tensor.
    fn tensor(&self, a: [[f64; 2]; 2]) -> [[f64; 2]; 2] {
        let r = [self.e1, self.e2];
        std::array::from_fn(|i| std::array::from_fn(|j| (0..2).map(|k| (0..2).map(|l| r[i][k] * a[k][l] * r[j][l]).sum::<f64>()).sum()))
    }
}

/// Adds one element's contribution (corners `x`, displacements `u`, weights `q`).
fn element_sums<S: Shape<N>, const N: usize>(fr: &Frame, m: &Material, x: &[[f64; 2]; N], u: &[[f64; 2]; N], q: &[f64; N], rule: &[([f64; 2], f64)], s: &mut Sums) {
    let d = m.dmat();
    for &(xi, w) in rule {
        let (g, det) = element::gradients::<S, N>(x, xi);
        let nn = S::n(xi);
        let mut h = [[0.0; 2]; 2];
        let (mut gq, mut xg) = ([0.0; 2], [0.0; 2]);
        for a in 0..N {
            for i in 0..2 {
                for j in 0..2 {
                    h[i][j] += u[a][i] * g[a][j];
                }
                gq[i] += q[a] * g[a][i];
                xg[i] += nn[a] * x[a][i];
            }
        }
        let sg = d.stress([h[0][0], h[1][1], h[0][1] + h[1][0]]);
        let sig = fr.tensor([[sg[0], sg[2]], [sg[2], sg[1]]]);
        let h = fr.tensor(h);
        let gq = fr.vec(gq);
        let xl = fr.vec([xg[0] - fr.tip[0], xg[1] - fr.tip[1]]);
        let (r, th) = (xl[0].hypot(xl[1]), xl[1].atan2(xl[0]));
        let dw = w * det;
        let eps = [h[0][0], h[1][1], 0.5 * (h[0][1] + h[1][0])];
        // J: s_ij u_i,1 q,j - W q,1.
        let wfe = 0.5 * (sig[0][0] * eps[0] + sig[1][1] * eps[1] + 2.0 * sig[0][1] * eps[2]);
        s.j += dw * ((0..2).map(|j| (sig[0][j] * h[0][0] + sig[1][j] * h[1][0]) * gq[j]).sum::<f64>() - wfe * gq[0]);
        for (mode2, acc) in [(false, &mut s.i1), (true, &mut s.i2)] {
            let (ga, sa) = aux_field(mode2, r, th, fr.mu, fr.kappa);
            let sa = [[sa[0], sa[2]], [sa[2], sa[1]]];
            let ea = [ga[0][0], ga[1][1], 0.5 * (ga[0][1] + ga[1][0])];
            let w12 = sig[0][0] * ea[0] + sig[1][1] * ea[1] + 2.0 * sig[0][1] * ea[2];
            let t: f64 = (0..2).map(|j| (sig[0][j] * ga[0][0] + sig[1][j] * ga[1][0] + sa[0][j] * h[0][0] + sa[1][j] * h[1][0]) * gq[j]).sum();
            *acc += dw * (t - w12 * gq[0]);
        }
    }
}

/// The interaction and J integrals on the domain `r_in < r < r_out` (weight ramp) around `tip`,
/// from the cluster displacements `u`. `fix` (fixity bits per cluster) and `f_ext` (applied
/// nodal force per cluster) are checked to be zero inside the domain.
pub fn domain_sif(model: &Model, u: &[[f64; 2]], fix: &[u8], f_ext: &[[f64; 2]], tip: &CrackTip, r_in: f64, r_out: f64) -> Result<DomainSif, SifError> {
    domain_sif_tol(model, u, fix, f_ext, tip, r_in, r_out, 1e-6 * r_out)
}

/// [`domain_sif`] with the crack faces inside the disc allowed `face_tol` off the tip's line
/// (`domain_sif`: `1e-6 r_out`). Ours (issue 34, `tip_mts`'s staircase tips): a crack drawn as
/// a staircase about a line (partial node moves on quads) is integrated as if it were straight
/// along `tip.dir`; the auxiliary field's faces are then off the real faces by up to
/// `face_tol`, an error of the order of `face_tol / r` in the angle (docs/paths.md).
#[allow(clippy::too_many_arguments)]
pub fn domain_sif_tol(model: &Model, u: &[[f64; 2]], fix: &[u8], f_ext: &[[f64; 2]], tip: &CrackTip, r_in: f64, r_out: f64, face_tol: f64) -> Result<DomainSif, SifError> {
    let point = tip.point;
    if tip.faces > 1 {
        return Err(SifError::AmbiguousTip { point, n: tip.faces });
    }
    if !(r_in.is_finite() && r_out.is_finite() && 0.0 <= r_in && r_in < r_out) {
        return Err(SifError::BadRadius { point, r_in, r_out });
    }
    let (near, edges) = near_tip(model, tip, r_out);
    check_geometry(model, tip, r_out, face_tol, &edges)?;
    let mut fr = Frame { tip: tip.x, e1: tip.dir, e2: [-tip.dir[1], tip.dir[0]], mu: 0.0, kappa: 0.0, r_in, r_out };
    let mut mat: Option<Material> = None;
    let mut s = Sums::default();
    let (q4, t3) = (gauss_q4(), gauss_t3());
    // The blocks' linearity is checked at their first element with a non-zero weight.
    let mut linear_checked: Option<u32> = None;
    // One buffer each for the element's weights and displacements (not one allocation per element).
    let (mut q, mut ue): (Vec<f64>, Vec<[f64; 2]>) = (Vec::new(), Vec::new());
    for &(b, i) in &near {
        let (blk, i) = (&model.blocks[b as usize], i as usize);
        {
            let x = blk.coords(i);
            q.clear();
            q.extend(x.iter().map(|&p| fr.q(p)));
            if q.iter().all(|&v| v == 0.0) {
                continue;
            }
            let elem = blk.elems()[i].idx();
            let conn = blk.conn(i);
            for &c in conn {
                let c = c as usize;
                let at = model.topo.cluster_point[c].idx();
                if fix.get(c).is_some_and(|&b| b != 0) {
                    return Err(SifError::SupportInDomain { point, r_out, at });
                }
                if f_ext.get(c).is_some_and(|f| f[0] != 0.0 || f[1] != 0.0) {
                    return Err(SifError::LoadInDomain { point, r_out, at });
                }
            }
            let m = *blk.material();
            match &mat {
                None => {
                    let ks = match m.plane {
                        Plane::Strain => 3.0 - 4.0 * m.poisson,
                        Plane::Stress => (3.0 - m.poisson) / (1.0 + m.poisson),
                    };
                    (fr.mu, fr.kappa) = (m.young / (2.0 * (1.0 + m.poisson)), ks);
                    mat = Some(m);
                }
                Some(m0) if (m0.young, m0.poisson, m0.plane) != (m.young, m.poisson, m.plane) => return Err(SifError::MaterialChanges { point, elem }),
                _ => {}
            }
            if linear_checked != Some(b) {
                if blk.strain_energy(u).is_some() {
                    return Err(SifError::NotLinear { point, elem });
                }
                linear_checked = Some(b);
            }
            if q.iter().all(|&v| v == q[0]) {
                continue;
            }
            ue.clear();
            ue.extend(conn.iter().map(|&c| u[c as usize]));
            match blk.element() {
                // `q4_closed` is `q4` (its closed form changes the force kernel's sums only).
                "q4" | "q4_closed" => element_sums::<Q4, 4>(&fr, &m, &arr(x), &arr(&ue), &arr(&q), &q4, &mut s),
                "t3" => element_sums::<T3, 3>(&fr, &m, &arr(x), &arr(&ue), &arr(&q), &t3, &mut s),
                kind => return Err(SifError::UnsupportedElement { point, elem, kind: kind.to_string() }),
            }
            s.elements += 1;
        }
    }
    let Some(m) = mat.filter(|_| s.elements > 0) else {
        return Err(SifError::EmptyDomain { point, r_in, r_out });
    };
    let es = e_star(&m);
    let (k1, k2) = (0.5 * es * s.i1, 0.5 * es * s.i2);
    let g = (k1 * k1 + k2 * k2) / es;
    if ![k1, k2, s.j].iter().all(|v| v.is_finite()) {
        return Err(SifError::NotFinite { point });
    }
    Ok(DomainSif { r_in, r_out, elements: s.elements, k1, k2, j: s.j, g, e_star: es })
}

fn arr<T: Copy + Default, const N: usize>(v: &[T]) -> [T; N] {
    std::array::from_fn(|a| v[a])
}

/// Displacement correlation (the cross-check): at every crack-face point behind the tip with
/// `r_max / 2 <= r <= r_max`, the faces' relative displacement in the tip's frame (upper face,
/// `x2 > 0`, minus lower) gives `K(r) = mu / (kappa + 1) sqrt(2 pi / r) [du1, du2]` (the
/// Williams field on `theta = +-pi`); `K = K(0)` by a least-squares line in `r`. The points
/// nearer the tip are left out: linear elements underestimate the opening there (on the edge
/// crack, `K(r)` rose from -10 % at `r = 2 h` to -4 % at `r = 14 h`). Less accurate than the
/// integral (docs/paths.md: 3-10 % low on the test meshes). `None` with fewer than two points.
/// Call after [`domain_sif`] on `r_max` has accepted the geometry (straight faces behind the
/// tip, one material).
pub fn displacement_correlation(model: &Model, u: &[[f64; 2]], tip: &CrackTip, r_max: f64) -> Option<(f64, f64, usize)> {
    let topo = &model.topo;
    let pts = &model.mesh.points;
    let local = |p: [f64; 2]| tip.local(p);
    let mut mat = *model.material_of(flem_core::ids::ElemId::new(0));
    let mut samples: Vec<(f64, f64, f64)> = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    for (e, ed) in topo.edges.iter().enumerate() {
        let e = EdgeId::new(e);
        for p in ed.points {
            if p.idx() == tip.point || !topo.is_separated_at(e, p) || !seen.insert(p.idx()) {
                continue;
            }
            let x = local(pts[p.idx()]);
            let r = -x[0];
            if r < 0.5 * r_max || r > r_max || topo.point_clusters[p.idx()].len() != 2 {
                continue;
            }
            // The side of each cluster: the centroid of an element holding one of its copies.
            let mut side = [None, None];
            for (k, &c) in topo.point_clusters[p.idx()].iter().enumerate() {
                let copy = topo.point_copies.row(p.idx()).iter().find(|k| topo.copy_cluster[k.idx()] == c)?;
                let el = topo.copy_elem[copy.idx()];
                mat = *model.material_of(el);
                let cs = topo.elem_copies(el);
                let n = cs.len() as f64;
                let cen = cs.fold([0.0; 2], |a, k| {
                    let q = pts[topo.copy_point[k].idx()];
                    [a[0] + q[0] / n, a[1] + q[1] / n]
                });
                side[k] = Some((local(cen)[1] > 0.0, c.idx()));
            }
            let (Some((up0, c0)), Some((up1, c1))) = (side[0], side[1]) else { continue };
            if up0 == up1 {
                continue;
            }
            let (cu, cl) = if up0 { (c0, c1) } else { (c1, c0) };
            let du = [u[cu][0] - u[cl][0], u[cu][1] - u[cl][1]];
            let dl = tip.rotate(du);
            samples.push((r, dl[0], dl[1]));
        }
    }
    if samples.len() < 2 {
        return None;
    }
    let mu = mat.young / (2.0 * (1.0 + mat.poisson));
    let kappa = match mat.plane {
        Plane::Strain => 3.0 - 4.0 * mat.poisson,
        Plane::Stress => (3.0 - mat.poisson) / (1.0 + mat.poisson),
    };
    let f = |r: f64| mu / (kappa + 1.0) * (2.0 * std::f64::consts::PI / r).sqrt();
    let fit = |k: &dyn Fn(&(f64, f64, f64)) -> f64| {
        let n = samples.len() as f64;
        let (sr, sk) = samples.iter().fold((0.0, 0.0), |a, s| (a.0 + s.0, a.1 + k(s)));
        let (mr, mk) = (sr / n, sk / n);
        let (sxy, sxx) = samples.iter().fold((0.0, 0.0), |a, s| (a.0 + (s.0 - mr) * (k(s) - mk), a.1 + (s.0 - mr).powi(2)));
        if sxx > 0.0 {
            mk - sxy / sxx * mr
        } else {
            mk
        }
    };
    let k1 = fit(&|s| f(s.0) * s.2);
    let k2 = fit(&|s| f(s.0) * s.1);
    (k1.is_finite() && k2.is_finite()).then_some((k1, k2, samples.len()))
}

/// The factors at one tip on several domains, with their mean and the MTS kink angle.
#[derive(Clone, Debug, Serialize)]
pub struct TipSif {
    pub tip: CrackTip,
    /// `E*` of the material at the tip.
    pub e_star: f64,
    pub domains: Vec<DomainSif>,
    /// Means over the domains.
    pub k1: f64,
    pub k2: f64,
    pub j: f64,
    pub g: f64,
    /// Largest difference between two domains' K_I (and K_II) over `sqrt(K_I^2 + K_II^2)`.
    pub spread: f64,
    /// MTS kink angle (degrees, from the crack's direction, counter-clockwise positive);
    /// `None` for a closed crack.
    pub mts_deg: Option<f64>,
    /// The kinked crack's direction, degrees from +x.
    pub kink_direction_deg: Option<f64>,
    /// The cross-check by displacement correlation over the faces within the largest `r_out`:
    /// `[K_I, K_II, points]` ([`displacement_correlation`]; less accurate than the integral).
    pub displacement_correlation: Option<[f64; 3]>,
}

/// [`domain_sif`] on each `(r_in, r_out)`, with the means and the MTS angle.
pub fn tip_sif(model: &Model, u: &[[f64; 2]], fix: &[u8], f_ext: &[[f64; 2]], tip: &CrackTip, radii: &[(f64, f64)]) -> Result<TipSif, SifError> {
    let domains: Vec<DomainSif> = radii.iter().map(|&(a, b)| domain_sif(model, u, fix, f_ext, tip, a, b)).collect::<Result<_, _>>()?;
    let n = domains.len() as f64;
    let mean = |f: fn(&DomainSif) -> f64| domains.iter().map(f).sum::<f64>() / n;
    let (k1, k2, j, g) = (mean(|d| d.k1), mean(|d| d.k2), mean(|d| d.j), mean(|d| d.g));
    let span = |f: fn(&DomainSif) -> f64| domains.iter().map(f).fold(f64::NEG_INFINITY, f64::max) - domains.iter().map(f).fold(f64::INFINITY, f64::min);
    let norm = k1.hypot(k2);
    let spread = if norm > 0.0 { span(|d| d.k1).max(span(|d| d.k2)) / norm } else { 0.0 };
    let mts = mts_angle(k1, k2);
    let dir = tip.dir[1].atan2(tip.dir[0]);
    let e_star = domains[0].e_star;
    let r_max = radii.iter().map(|r| r.1).fold(0.0, f64::max);
    let dc = displacement_correlation(model, u, tip, r_max).map(|(a, b, n)| [a, b, n as f64]);
    Ok(TipSif { tip: tip.clone(), e_star, domains, k1, k2, j, g, spread, mts_deg: mts.map(f64::to_degrees), kink_direction_deg: mts.map(|t| (dir + t).to_degrees()), displacement_correlation: dc })
}

/// The default domains at a tip: `r_out = f h` for each factor `f`, `r_in = r_out / 2`, `h` the
/// element size at the tip.
pub fn default_radii(tip: &CrackTip, factors: &[f64]) -> Vec<(f64, f64)> {
    factors.iter().map(|&f| (0.5 * f * tip.h, f * tip.h)).collect()
}

/// The domains of a call: outer radii as multiples of the element size at the tip, or absolute;
/// `r_in = r_out / 2` in both.
#[derive(Clone, Debug, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Radii {
    ElementSizes(Vec<f64>),
    Absolute(Vec<f64>),
}

impl Default for Radii {
    /// `r_out` = 4, 6 and 8 element sizes at the tip.
    fn default() -> Self {
        Radii::ElementSizes(vec![4.0, 6.0, 8.0])
    }
}

impl Radii {
    pub fn at(&self, tip: &CrackTip) -> Vec<(f64, f64)> {
        match self {
            Radii::ElementSizes(f) => default_radii(tip, f),
            Radii::Absolute(r) => r.iter().map(|&r| (0.5 * r, r)).collect(),
        }
    }
}

/// One tip of one stage: the factors, or why not.
#[derive(Clone, Debug, Serialize)]
pub struct TipResult {
    pub point: usize,
    pub x: [f64; 2],
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub sif: Option<TipSif>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// The factors of one stage.
#[derive(Clone, Debug, Serialize)]
pub struct StageSif {
    /// 0-based stage index.
    pub stage: usize,
    pub name: String,
    pub tips: Vec<TipResult>,
}

/// Solves stage `stage` (0-based; the load levels of stages `0..=stage`) of `sim`'s model
/// implicitly with the scene's check solver (`[check]`, default `faer_cholesky`) and computes
/// the factors at every crack tip, or at the one at `at`. A tip's own failure (e.g. its domain
/// leaves the body) is recorded in its entry; no tip at all, or `at` on no tip, is an error.
pub fn stage_sif(sim: &mut flem_core::solver::Simulation, stage: usize, at: Option<[f64; 2]>, radii: &Radii) -> Result<StageSif, flem_core::FlemError> {
    use flem_core::plugin::check::CheckCfg;
    let file = sim.scene.path.display().to_string();
    let n = sim.scene.file.stages.len();
    if stage >= n {
        return Err(flem_core::FlemError::Other(format!("{file}: stage {} does not exist (the scene has {n})", stage + 1)));
    }
    let all = crack_tips(&sim.model);
    if all.is_empty() {
        return Err(flem_core::FlemError::Other(format!("{file}: {}", SifError::NoTip)));
    }
    let tips: Vec<CrackTip> = match at {
        Some(x) => vec![tip_near(&all, x).map_err(|e| flem_core::FlemError::Other(format!("{file}: {e}")))?.clone()],
        None => all,
    };
    sim.set_stage_levels(stage);
    let f = sim.external_force()?;
    let default;
    let solver = match &sim.scene.file.check {
        Some(c) => c.solver(),
        None => {
            default = CheckCfg::with_defaults(&file)?;
            default.solver()
        }
    };
    let u = solver.solve(&sim.model, &sim.state.fix, &f, &sim.state.u)?;
    let tips = tips
        .iter()
        .map(|t| {
            let r = tip_sif(&sim.model, &u, &sim.state.fix, &f, t, &radii.at(t));
            let (sif, error) = match r {
                Ok(s) => (Some(s), None),
                Err(e) => (None, Some(e.to_string())),
            };
            TipResult { point: t.point, x: t.x, sif, error }
        })
        .collect();
    Ok(StageSif { stage, name: sim.scene.file.stages[stage].name.clone(), tips })
}

/// Ours (session 31, `tip_mts`'s `fork_ratio`): the hoop stress around a tip, `sigma_thetatheta` of
/// the linear elastic stress at the centroid of every element whose centroid lies in the ring
/// `r_in <= r <= r_out` about the tip and ahead of it (`|theta| < 90 deg` from `tip.dir`), averaged in 18 bins
/// of 10 deg from -90 to 90 deg: `(sum, count)` per bin. The stress of a `t3` is its constant
/// one, of a `q4` (`q4_closed`) the one at its centre, both by the block's own `Block::stress_at`. `None`: an element of another kind or a
/// block that is not linear elastic within `r_out`.
pub fn hoop_profile(model: &Model, u: &[[f64; 2]], tip: &CrackTip, r_in: f64, r_out: f64) -> Option<[(f64, u32); 18]> {
    // (An element whose centroid lies within `r_out` has a side within it: `near_tip` has it.)
    let (near, _) = near_tip(model, tip, r_out);
    let mut bins = [(0.0, 0u32); 18];
    // Each block's linearity is checked once, at its first element in the ring (as `domain_sif`).
    let mut linear_checked: Option<u32> = None;
    for &(b, i) in &near {
        let (blk, i) = (&model.blocks[b as usize], i as usize);
        let x = blk.coords(i);
        let n = x.len() as f64;
        let c = x.iter().fold([0.0; 2], |a, p| [a[0] + p[0] / n, a[1] + p[1] / n]);
        let l = tip.local(c);
        let r = l[0].hypot(l[1]);
        let th = l[1].atan2(l[0]);
        if r < r_in || r > r_out || th.abs() >= std::f64::consts::FRAC_PI_2 {
            continue;
        }
        if linear_checked != Some(b) {
            if blk.strain_energy(u).is_some() {
                return None;
            }
            linear_checked = Some(b);
        }
        // The block's own stress at the element's centre (`Block::stress_at`, parent coordinates).
        let s = match (blk.element(), x.len()) {
            ("t3", 3) => blk.stress_at(i, u, [1.0 / 3.0, 1.0 / 3.0]),
            ("q4" | "q4_closed", 4) => blk.stress_at(i, u, [0.0, 0.0]),
            _ => return None,
        };
        // The hoop direction at the centroid, in the global frame.
        let ph = (c[1] - tip.x[1]).atan2(c[0] - tip.x[0]);
        let (tx, ty) = (-ph.sin(), ph.cos());
        let stt = s[0] * tx * tx + 2.0 * s[2] * tx * ty + s[1] * ty * ty;
        let k = (((th + std::f64::consts::FRAC_PI_2) / std::f64::consts::PI * 18.0) as usize).min(17);
        bins[k].0 += stt;
        bins[k].1 += 1;
    }
    Some(bins)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The auxiliary displacement gradients are consistent with the auxiliary stresses: `D`
    /// times the symmetric gradient is the Williams stress (plane strain and plane stress), and
    /// the gradient matches central differences of the Williams displacement.
    #[test]
    fn aux_field_is_consistent() {
        for plane in [Plane::Strain, Plane::Stress] {
            let m = Material { young: 210.0, poisson: 0.3, density: 1.0, thickness: 1.0, plane };
            let d = m.dmat();
            let mu = m.young / 2.6;
            let kappa = if plane == Plane::Strain { 3.0 - 1.2 } else { 2.7 / 1.3 };
            for mode2 in [false, true] {
                for k in 0..12 {
                    let th = -3.0 + 0.5 * k as f64;
                    let r = 0.3 + 0.1 * k as f64;
                    let (g, s) = aux_field(mode2, r, th, mu, kappa);
                    let sd = d.stress([g[0][0], g[1][1], g[0][1] + g[1][0]]);
                    for c in 0..3 {
                        assert!((sd[c] - s[c]).abs() < 1e-12 * (1.0 + s[c].abs()), "{plane:?} mode2 {mode2} th {th}: {sd:?} vs {s:?}");
                    }
                    // Displacement by integration of the gradient along r: u = 2 r du/dr.
                    let disp = |x: f64, y: f64| {
                        let (r, t) = (x.hypot(y), y.atan2(x));
                        let (g, _) = aux_field(mode2, r, t, mu, kappa);
                        let (st, ct) = t.sin_cos();
                        // du/dr = ct du/dx + st du/dy; u = 2 r du/dr for u ~ sqrt(r).
                        [2.0 * r * (ct * g[0][0] + st * g[0][1]), 2.0 * r * (ct * g[1][0] + st * g[1][1])]
                    };
                    let (x, y, e) = (r * th.cos(), r * th.sin(), 1e-6);
                    for i in 0..2 {
                        let dx = (disp(x + e, y)[i] - disp(x - e, y)[i]) / (2.0 * e);
                        let dy = (disp(x, y + e)[i] - disp(x, y - e)[i]) / (2.0 * e);
                        assert!((dx - g[i][0]).abs() < 1e-6 && (dy - g[i][1]).abs() < 1e-6, "mode2 {mode2} th {th} i {i}: ({dx}, {dy}) vs {:?}", g[i]);
                    }
                }
            }
        }
    }

    /// The auxiliary displacement of mode I with K_I = 1 at r, theta = pi (upper face) is
    /// Anderson's crack opening: u2 = (kappa + 1)/(2 mu) sqrt(r / 2 pi).
    #[test]
    fn aux_mode_one_opening() {
        let (mu, kappa, r) = (80.0, 1.8, 0.04);
        let disp = |th: f64| {
            let (g, _) = aux_field(false, r, th, mu, kappa);
            let (st, ct) = th.sin_cos();
            2.0 * r * (ct * g[1][0] + st * g[1][1])
        };
        let want = (kappa + 1.0) / (2.0 * mu) * (r / (2.0 * std::f64::consts::PI)).sqrt();
        assert!((disp(std::f64::consts::PI - 1e-12) - want).abs() < 1e-12 * want.max(1.0));
    }

    /// The MTS angles of the benchmark table (../shared/BENCHMARKS.md): r = 0.25/0.5/1/2/inf
    /// give -25.33/-40.21/-53.13/-61.34/-70.53 deg; pure mode I 0; closed cracks none.
    #[test]
    fn mts_angles() {
        for (r, want) in [(0.25, -25.33), (0.5, -40.21), (1.0, -53.13), (2.0, -61.34)] {
            let got = mts_angle(1.0, r).unwrap().to_degrees();
            assert!((got - want).abs() < 0.01, "r = {r}: {got} vs {want}");
            let neg = mts_angle(1.0, -r).unwrap().to_degrees();
            assert!((neg + want).abs() < 0.01);
        }
        assert!((mts_angle(0.0, 1.0).unwrap().to_degrees() + 70.53).abs() < 0.01);
        assert!((mts_angle(1e-12, 1.0).unwrap().to_degrees() + 70.53).abs() < 0.01);
        assert_eq!(mts_angle(1.0, 0.0), Some(0.0));
        assert!(mts_angle(-1.0, 0.5).is_none());
    }

    /// The quadrature rules integrate polynomials of their degree exactly.
    #[test]
    fn rules_are_exact() {
        let q: f64 = gauss_q4().iter().map(|(x, w)| w * x[0].powi(4) * x[1].powi(4)).sum();
        assert!((q - 4.0 / 25.0).abs() < 1e-14);
        // int over the unit triangle of x^2 y^2 = 2! 2! / 6! = 1/180; of x^4 = 4!/6! = 1/30.
        let t: f64 = gauss_t3().iter().map(|(x, w)| w * x[0] * x[0] * x[1] * x[1]).sum();
        assert!((t - 1.0 / 180.0).abs() < 1e-12, "{t}");
        let t4: f64 = gauss_t3().iter().map(|(x, w)| w * x[0].powi(4)).sum();
        assert!((t4 - 1.0 / 30.0).abs() < 1e-12, "{t4}");
    }
}
