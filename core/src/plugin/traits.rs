//! The plugin traits of FLEM. Plugins implement them; scenes select them by `type = "name"`
//! (typetag). The core calls them once per event or batch (a check, a split candidate, a step),
//! never once per element in the hot loop.
use std::fmt::Debug;

use serde::{Deserialize, Serialize};

use crate::ids::{ClusterId, EdgeId, PointId};

// ---------------------------------------------------------------------------------------------
// Stress in the geomechanics convention
// ---------------------------------------------------------------------------------------------

/// In-plane principal stresses in the geomechanics convention (compression positive,
/// `s1 >= s3`), the out-of-plane stress `s2` (same convention) and the direction of `s1`.
#[derive(Copy, Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct Principal {
    pub s1: f64,
    pub s3: f64,
    pub s2: f64,
    /// Angle of the sigma1 direction from +x, radians in [0, pi).
    pub theta1: f64,
}

/// Converts a tension-positive stress `[sxx, syy, sxy]` (and out-of-plane `szz`) into
/// compression-positive principal values. When s1 == s3 the direction is undefined; by
/// convention it is then 0 (the +x axis).
pub fn principal(s: [f64; 3], szz: f64) -> Principal {
    let p = principal_values(s, szz);
    let (a, b, t) = (-s[0], -s[1], -s[2]);
    let r = (0.25 * (a - b) * (a - b) + t * t).sqrt();
    let mut theta = if r > 0.0 { 0.5 * (2.0 * t).atan2(a - b) } else { 0.0 };
    if theta < 0.0 {
        theta += std::f64::consts::PI;
    }
    if theta >= std::f64::consts::PI {
        theta -= std::f64::consts::PI;
    }
    Principal { theta1: theta, ..p }
}

/// [`principal`] without the direction (`theta1 = 0`): the same `s1`, `s3`, `s2` bit for bit,
/// without the `atan2` (for criteria that are [`FailureCriterion::isotropic`]).
pub fn principal_values(s: [f64; 3], szz: f64) -> Principal {
    // compression positive
    let (a, b, t) = (-s[0], -s[1], -s[2]);
    let c = 0.5 * (a + b);
    let r = (0.25 * (a - b) * (a - b) + t * t).sqrt();
    Principal { s1: c + r, s3: c - r, s2: -szz, theta1: 0.0 }
}

/// Principal stresses of a 3D stress (issue 38): `p.s1 >= p.s2 >= p.s3` compression positive
/// (so every criterion's `check` reads them as it reads the 2D ones, `s2` now the true
/// intermediate stress; `theta1 = 0`), and the unit directions of sigma1 and sigma3. The
/// failure plane of the paper's rule read in 3D contains the sigma1 and sigma2 directions: its
/// normal is `d3` (the most tensile direction; docs/3d.md).
#[derive(Copy, Clone, Debug, PartialEq, Default)]
pub struct Principal3 {
    pub p: Principal,
    pub d1: [f64; 3],
    pub d3: [f64; 3],
}

/// [`Principal3`] of a tension-positive stress `[sxx, syy, szz, sxy, syz, szx]` (Voigt order of
/// the 3D elements). Eigenvectors by nalgebra's symmetric eigen-decomposition (Jacobi-free QL;
/// the same input gives the same output); each direction's sign is fixed so that its largest
/// component is positive (ties: the first). Where two principal values are equal the direction
/// within their plane is nalgebra's choice, deterministic but arbitrary (as theta1 = 0 is in 2D).
pub fn principal3(s: [f64; 6]) -> Principal3 {
    let m = nalgebra::Matrix3::new(-s[0], -s[3], -s[5], -s[3], -s[1], -s[4], -s[5], -s[4], -s[2]);
    let e = nalgebra::SymmetricEigen::new(m);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| e.eigenvalues[b].total_cmp(&e.eigenvalues[a]).then(a.cmp(&b)));
    let dir = |k: usize| {
        let v = e.eigenvectors.column(k);
        let mut d = [v[0], v[1], v[2]];
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let big = (0..3).fold(0, |b, i| if d[i].abs() > d[b].abs() { i } else { b });
        let sg = if d[big] < 0.0 { -1.0 } else { 1.0 } / n;
        for x in &mut d {
            *x *= sg;
        }
        d
    };
    let (a, b, c) = (e.eigenvalues[order[0]], e.eigenvalues[order[1]], e.eigenvalues[order[2]]);
    Principal3 { p: Principal { s1: a, s3: c, s2: b, theta1: 0.0 }, d1: dir(order[0]), d3: dir(order[2]) }
}

// ---------------------------------------------------------------------------------------------
// Failure criteria
// ---------------------------------------------------------------------------------------------

/// How a point failed.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FailureMode {
    Tension,
    Shear,
}

/// The answer of a criterion at one point.
#[derive(Copy, Clone, Debug, PartialEq, Default)]
pub struct FailureCheck {
    /// How close to failure: >= 1 failed. Finite, clamped to [0, 1e6].
    pub index: f64,
    /// `Some` when the point fails.
    pub mode: Option<FailureMode>,
    /// Directions of the failure plane(s), radians in [0, pi): tension one plane (the sigma1
    /// direction), shear two (+-(pi/4 - phi/2) from sigma1).
    pub planes: [f64; 2],
    pub n_planes: u8,
}

impl FailureCheck {
    pub fn failed(&self) -> bool {
        self.mode.is_some()
    }
}

/// A failure criterion (METHOD section 4). Inputs are compression positive.
/// `scale` multiplies the criterion's strengths at this point (1 without scatter).
#[typetag::serde(tag = "type")]
pub trait FailureCriterion: Debug + Send + Sync {
    /// Checks the parameters; the error names the key and the allowed range.
    fn validate(&self) -> Result<(), ParamError>;
    fn check(&self, p: &Principal, scale: f64) -> FailureCheck;
    /// `true` when whether a point fails, and its index, depend on the principal values only,
    /// not on `theta1` (only the failure planes do). The core then computes the sigma1
    /// direction only at the points that fail and asks again there. Default `false`: an
    /// anisotropic criterion (a weak bedding plane, say) sees `theta1` at every point.
    fn isotropic(&self) -> bool {
        false
    }
    /// Batch form (one dynamic call per check, not per point). Default: loops over `check`.
    fn check_batch(&self, p: &[Principal], scale: &[f64], out: &mut [FailureCheck]) {
        for i in 0..p.len() {
            out[i] = self.check(&p[i], scale[i]);
        }
    }
    /// Fallible batch form: what the core calls. Built-ins keep this default; a dynamic plugin
    /// (`dynload`) turns a plugin error or a caught panic into `Err` (a message).
    fn try_check_batch(&self, p: &[Principal], scale: &[f64], out: &mut [FailureCheck]) -> Result<(), String> {
        self.check_batch(p, scale, out);
        Ok(())
    }
    /// Closed form for the events solver (ours, issue 19): the smallest `t` in `[t0, t1]` at
    /// which the criterion fails for the stress `s0 + t ds` (tension positive; out-of-plane
    /// `szz0 + t dszz`), strength factor `scale`; `Some(f64::INFINITY)` when it holds on the
    /// whole interval. `None` (the default): no closed form, the core searches by bisection
    /// (`cracking::events`). The core checks every answer against [`Self::check`].
    #[allow(clippy::too_many_arguments)]
    fn affine_failure(&self, _s0: [f64; 3], _ds: [f64; 3], _szz0: f64, _dszz: f64, _scale: f64, _t0: f64, _t1: f64) -> Option<f64> {
        None
    }
    /// The certified skip of the failure check (ours, issue 24, `cracking::skip`): a distance
    /// `rho >= 0` in stress units such that no principal triple `p'` with `|p'.s1 - p.s1|`,
    /// `|p'.s3 - p.s3|`, `|p'.s2 - p.s2|` all below `rho` fails (any `theta1`, same `scale`),
    /// in exact arithmetic (the core allows for round-off). `None` (the default; dynamic
    /// plugins): no bound, the point is evaluated at every check. A wrong (too large) margin
    /// would skip a failure: `tests/skip.rs` checks each built-in's against its `check`.
    fn margin(&self, _p: &Principal, _scale: f64) -> Option<f64> {
        None
    }
    /// Batch form of [`Self::margin`] (one dynamic call per check); `false` as soon as a point
    /// has no margin (then `out` is partly written and the check is not skipped).
    fn margin_batch(&self, p: &[Principal], scale: &[f64], out: &mut [f64]) -> bool {
        for i in 0..p.len() {
            match self.margin(&p[i], scale[i]) {
                Some(m) => out[i] = m,
                None => return false,
            }
        }
        true
    }
}

/// The smallest `t` in `[t0, t1]` with `g(t) = r(t) + k m(t) - big_k >= 0`, where, for the
/// in-plane tension-positive stress `s0 + t ds`, `m = (sxx + syy) / 2` and
/// `r = sqrt(((sxx - syy) / 2)^2 + sxy^2)`; infinite if none. With `k = 1`, `big_k = sigma_t`
/// this is the tension cut-off (most tensile principal stress `m + r` reaches `sigma_t`); with
/// `k = sin(phi)`, `big_k = c cos(phi)` the Mohr-Coulomb shear line. `g` is convex in `t` (a
/// norm of an affine map plus an affine term), so its first root after a negative `g(t0)` is the
/// smaller root of `r^2 = (big_k - k m)^2` with `big_k - k m >= 0` (a quadratic in `t`).
pub fn affine_crossing(s0: [f64; 3], ds: [f64; 3], k: f64, big_k: f64, t0: f64, t1: f64) -> f64 {
    let (m0, dm) = (0.5 * (s0[0] + s0[1]), 0.5 * (ds[0] + ds[1]));
    let (a0, da) = (0.5 * (s0[0] - s0[1]), 0.5 * (ds[0] - ds[1]));
    let (b0, db) = (s0[2], ds[2]);
    let g = |t: f64| ((a0 + t * da).powi(2) + (b0 + t * db).powi(2)).sqrt() + k * (m0 + t * dm) - big_k;
    if g(t0) >= 0.0 {
        return t0;
    }
    // (a0 + t da)^2 + (b0 + t db)^2 = (w0 - t dw)^2, w = big_k - k m.
    let (w0, dw) = (big_k - k * m0, k * dm);
    let qa = da * da + db * db - dw * dw;
    let qb = 2.0 * (a0 * da + b0 * db + w0 * dw);
    let qc = a0 * a0 + b0 * b0 - w0 * w0;
    let mut roots = [f64::INFINITY; 2];
    if qa.abs() <= 1e-14 * (da * da + db * db + dw * dw) {
        if qb != 0.0 {
            roots[0] = -qc / qb;
        }
    } else {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc >= 0.0 {
            // The numerically stable pair of roots.
            let q = -0.5 * (qb + qb.signum() * disc.sqrt());
            roots = [q / qa, if q != 0.0 { qc / q } else { f64::INFINITY }];
        }
    }
    roots.sort_by(f64::total_cmp);
    for t in roots {
        if t.is_finite() && t > t0 && t <= t1 && w0 - t * dw >= -1e-12 * big_k.abs().max(w0.abs()) {
            return t;
        }
    }
    f64::INFINITY
}

/// A parameter error: `key = value is incorrect; it must be ...`.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamError {
    pub key: String,
    pub msg: String,
}

impl ParamError {
    pub fn new(key: impl Into<String>, msg: impl Into<String>) -> Self {
        ParamError { key: key.into(), msg: msg.into() }
    }
    /// Checks `lo <= v <= hi` (inclusive flags per side).
    pub fn range(key: &str, v: f64, lo: f64, lo_incl: bool, hi: f64, hi_incl: bool) -> Result<(), ParamError> {
        let ok = v.is_finite() && (if lo_incl { v >= lo } else { v > lo }) && (if hi_incl { v <= hi } else { v < hi });
        if ok {
            Ok(())
        } else {
            let l = if lo_incl { "[" } else { "(" };
            let h = if hi_incl { "]" } else { ")" };
            // Very large or small magnitudes in exponent form (1e300 would print 301 digits).
            let fmt = |x: f64| match x {
                x if x.is_infinite() => {
                    if x > 0.0 {
                        "inf".to_string()
                    } else {
                        "-inf".to_string()
                    }
                }
                x if x != 0.0 && (x.abs() >= 1e9 || x.abs() < 1e-6) => format!("{x:e}"),
                x => format!("{x}"),
            };
            Err(ParamError::new(key, format!("= {} is incorrect; it must be in {l}{}, {}{h}", fmt(v), fmt(lo), fmt(hi))))
        }
    }
}

impl std::fmt::Display for ParamError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {}", self.key, self.msg)
    }
}

// ---------------------------------------------------------------------------------------------
// Separation rules
// ---------------------------------------------------------------------------------------------

/// One joined edge of a fan, as a separation rule sees it.
#[derive(Copy, Clone, Debug)]
pub struct LinkGeom {
    pub edge: EdgeId,
    /// Direction of the edge leaving the point (current configuration), radians in [0, 2 pi).
    pub angle: f64,
    /// Outward normals (current configuration) of the two elements' faces on this edge are
    /// +-normal; `normal` is the unit normal (angle + pi/2).
    pub normal: [f64; 2],
}

/// What a separation rule sees of a failing cluster.
#[derive(Clone, Debug)]
pub struct FanView<'a> {
    pub point: PointId,
    pub cluster: ClusterId,
    /// A cycle of links (interior point never split) or a path.
    pub closed: bool,
    /// The point has never split: it has one cluster (no failure cut and no pre-separated
    /// edge split it into two). An open fan of such a point is a boundary point or the end
    /// of a pre-cut edge (METHOD 5: the paper's pi/4 cap for open fans is stated only for
    /// points that have already split). Dynamic plugins see it too (`CFan::never_split`, ABI 3).
    pub never_split: bool,
    /// Joined edges at the point, in increasing edge id.
    pub links: &'a [LinkGeom],
    /// Nodal stress, tension positive `[sxx, syy, sxy]`.
    pub stress: [f64; 3],
    pub principal: Principal,
}

/// What a separation rule sees of a failing cluster of a 3D model (issue 38): its fan (copies
/// linked through faces, `mesh::topology3`), the point, the centroid of each copy's element and
/// the unit normal of each link's face (in the order of `fan.links`), whether the point has
/// split before, and the nodal principal stresses.
#[derive(Clone, Debug)]
pub struct FanView3<'a> {
    pub fan: &'a crate::mesh::topology3::Fan3,
    pub x: [f64; 3],
    pub centroids: &'a [[f64; 3]],
    pub face_normals: &'a [[f64; 3]],
    pub never_split: bool,
    pub principal: Principal3,
}

/// The edges a rule proposes to cut at a point. The core cuts them only if the fan then falls
/// into exactly two non-empty parts.
#[derive(Clone, Debug, PartialEq)]
pub struct Proposal {
    pub edges: Vec<EdgeId>,
}

/// Chooses the separation face(s) at a failed point (METHOD section 5).
#[typetag::serde(tag = "type")]
pub trait SeparationRule: Debug + Send + Sync {
    fn validate(&self) -> Result<(), ParamError> {
        Ok(())
    }
    fn propose(&self, fan: &FanView, failure: &FailureCheck) -> Option<Proposal>;
    /// Fallible form: what the core calls (see [`FailureCriterion::try_check_batch`]).
    fn try_propose(&self, fan: &FanView, failure: &FailureCheck) -> Result<Option<Proposal>, String> {
        Ok(self.propose(fan, failure))
    }
    /// Ours (issue 34, the path method, `cracking::path`): whether the rule grows crack tips
    /// itself. When true, a failed point at a crack tip, or within [`Self::route_radius`]
    /// element sizes of one, is handed to [`Self::propose_tip`] at that tip; a failed point on
    /// a crack (it has split), or joined to one by an edge, farther from every tip is not cut
    /// (`cracking::path::on_or_beside_crack`); other points go to
    /// [`Self::propose`] as before. Every rule of the paper answers false (the default), and
    /// the failure check then runs exactly as without this method.
    fn grows_tips(&self) -> bool {
        false
    }
    /// Failed points within this many element sizes (at the tip) of a crack tip grow that tip.
    fn route_radius(&self) -> f64 {
        0.0
    }
    /// Ours (session 27; a rule that grows tips only): the shield's radius, in the mesh's unit, at
    /// a failed point whose element size (mean length of its edges) is `h`. A failed point that
    /// no tip takes (farther than [`Self::route_radius`] from every tip) and that lies within it
    /// of a crack edge is not cut: no new crack starts beside a crack, nor in the ring between
    /// `route` and the shield around a tip (the exclusion radius of crack-tracking schemes,
    /// Cervera & Chiumenti 2006). 0 (the default): no shield (such a point starts a crack of its
    /// own, by [`Self::propose`], as before).
    fn shield_distance(&self, _h: f64) -> f64 {
        0.0
    }
    /// The plan at a crack tip (see [`TipContext`]); `None`: nothing is cut there.
    fn propose_tip(&self, _ctx: &TipContext) -> Option<TipPlan> {
        None
    }
    /// The rule in a 3D model (issue 38): the faces to cut at a failed point (the core cuts
    /// them only if the fan then falls apart). `Err` (the default): the rule has no 3D form,
    /// and a 3D scene that names it is refused with the rule's name.
    fn propose_3d(&self, _fan: &FanView3, _failure: &FailureCheck) -> Result<Option<Vec<crate::ids::FaceId>>, String> {
        Err("this separation rule has no 3D form (docs/3d.md lists the rules that do)".into())
    }
}

/// A crack tip as the path method sees it (ours, issue 34): the model and the displacement of
/// the check, the tip's fan (its links include the crack face that ends there), the crack face
/// and the tip's element size `h` (mean length of the edges through the tip).
pub struct TipContext<'a> {
    pub model: &'a crate::element::model::Model,
    pub u: &'a [[f64; 2]],
    pub fan: &'a FanView<'a>,
    /// The crack face ending at the tip (separated at its other end, joined at the tip).
    pub face: EdgeId,
    pub h: f64,
    /// The line (origin, direction in radians from +x) that this tip was grown along, when the
    /// path method grew it: a rule that cannot evaluate a direction at the tip (a crack not yet
    /// straight over its domain) may keep to it.
    pub planned: Option<([f64; 2], f64)>,
    /// The points of every crack tip of the topology at this candidate (the check's own list).
    pub tips: &'a [PointId],
}

/// What a rule that grows tips proposes: the edges to cut at the tip (the crack face and the
/// link the crack runs along) and, optionally, a point to move first (the far end of that link,
/// onto the predicted line: crack-tip node relocation). The core checks the move (interior
/// point never split, every element around it keeps its orientation and a minimum angle) and
/// cuts without it when it is refused. `origin`, `direction`: the line the crack is to follow
/// (radians from +x), handed back in [`TipContext::planned`] at the new tip.
/// `fork` (ours, session 31): a second link cut at the same tip in the same cut (the crack
/// branches: the tip's point falls in three), with its own move and line.
#[derive(Clone, Debug, PartialEq)]
pub struct TipPlan {
    pub edges: Vec<EdgeId>,
    pub relocate: Option<(PointId, [f64; 2])>,
    pub origin: [f64; 2],
    pub direction: f64,
    pub fork: Option<TipFork>,
}

/// The second branch of a forking tip ([`TipPlan::fork`]): the link it runs along (a link of
/// the tip's fan, not in `TipPlan::edges`), the move of that link's far point, and its line.
#[derive(Clone, Debug, PartialEq)]
pub struct TipFork {
    pub edge: EdgeId,
    pub relocate: Option<(PointId, [f64; 2])>,
    pub origin: [f64; 2],
    pub direction: f64,
}

/// Angular distance between two directions (radians), as undirected lines (mod pi), in [0, pi/2].
pub fn line_angle(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::PI);
    d.min(std::f64::consts::PI - d)
}

/// Angular distance between two directed rays (mod 2 pi), in [0, pi].
pub fn ray_angle(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(2.0 * std::f64::consts::PI);
    d.min(2.0 * std::f64::consts::PI - d)
}

#[cfg(test)]
mod tests3 {
    use super::*;

    /// Reference: construction. The tension-positive stress R diag(3, -1, 2) R^T (R a rotation
    /// about an oblique axis) has compression-positive principal values 1 >= -2 >= -3, sigma3
    /// along R e_x (the tension 3) and sigma1 along R e_y, up to sign; to 1e-12.
    #[test]
    fn principal3_of_a_rotated_diagonal_stress() {
        let r = nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(nalgebra::Vector3::new(1.0, 2.0, -0.5)), 0.7);
        let d = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(3.0, -1.0, 2.0));
        let m = r.matrix() * d * r.matrix().transpose();
        let p = principal3([m[(0, 0)], m[(1, 1)], m[(2, 2)], m[(0, 1)], m[(1, 2)], m[(2, 0)]]);
        assert!((p.p.s1 - 1.0).abs() < 1e-12 && (p.p.s2 + 2.0).abs() < 1e-12 && (p.p.s3 + 3.0).abs() < 1e-12, "{p:?}");
        let ex = r * nalgebra::Vector3::x();
        let ey = r * nalgebra::Vector3::y();
        let dot3 = ex[0] * p.d3[0] + ex[1] * p.d3[1] + ex[2] * p.d3[2];
        let dot1 = ey[0] * p.d1[0] + ey[1] * p.d1[1] + ey[2] * p.d1[2];
        assert!((dot3.abs() - 1.0).abs() < 1e-12 && (dot1.abs() - 1.0).abs() < 1e-12, "{p:?}");
        // An in-plane stress gives the 2D principal values (s2 the out-of-plane 0).
        let q = principal3([1.0, -0.5, 0.0, 0.3, 0.0, 0.0]);
        let q2 = principal([1.0, -0.5, 0.3], 0.0);
        assert!((q.p.s1 - q2.s1).abs() < 1e-14 && (q.p.s3 - q2.s3).abs() < 1e-14 && q.p.s2.abs() < 1e-14);
    }
}
