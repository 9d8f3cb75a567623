//! Ours (issue 34, the path method; docs/paths.md): the core's side of a separation rule that
//! grows crack tips (`SeparationRule::grows_tips`, e.g. `tip_mts` in flem-plugins). It finds
//! the crack tips of the topology, routes a failed point near a tip to that tip, checks and
//! applies the relocation of the node ahead of the tip (`Model::move_point`), and keeps what a
//! checkpoint needs to replay it (the moves, in cut order, and each tip's planned line).
//!
//! A *tip* is a point with one cluster (never split) at which exactly one interior crack face
//! ends: an edge separated at its other end and joined at the tip (as `check::sif::crack_tips`).
//!
//! A move of point `p` to `x` is accepted when `p` carries no boundary condition (ours, session
//! 18: the fixity mask `Cracking::path_held`, [`check_move_held`]), is an interior point (or, ours since session
//! 17, a boundary point sliding along a straight stretch of the boundary:
//! [`slides_along_boundary`]) that never split, lies on no crack face, and every element with a corner at `p` keeps its orientation and a corner
//! angle of at least [`MIN_ANGLE_DEG`] (or half its smallest angle before the move, whichever
//! is smaller): no element is inverted or flattened.
use serde::{Deserialize, Serialize};

use crate::element::model::Model;
use crate::ids::{EdgeId, PointId};
use crate::mesh::topology::Topology;

/// The smallest corner angle (degrees) a move may leave in an element.
pub const MIN_ANGLE_DEG: f64 = 15.0;

/// One relocation: applied before cut number `cut` (an index into `Cracking::cuts`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PathMove {
    pub cut: u32,
    pub point: u32,
    pub from: [f64; 2],
    pub to: [f64; 2],
}

/// The line a tip was grown along: origin and direction (radians from +x), keyed by the tip's
/// point (the far end of the last cut link).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TipLine {
    pub point: u32,
    pub origin: [f64; 2],
    pub dir: f64,
}

/// What a checkpoint keeps of the path method (section "path", version 1).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PathState {
    pub moves: Vec<PathMove>,
    pub lines: Vec<TipLine>,
    pub refused: u64,
}

/// A crack tip: its point, the crack face ending there and the element size (mean length of
/// the edges through the point, reference coordinates).
#[derive(Clone, Copy, Debug)]
pub struct Tip {
    pub point: PointId,
    pub face: EdgeId,
    pub h: f64,
}

/// The crack face ending at `p` when `p` is a tip (see the module doc).
pub fn tip_face(topo: &Topology, p: PointId) -> Option<EdgeId> {
    if topo.point_clusters[p.idx()].len() != 1 {
        return None;
    }
    let mut face = None;
    for &e in topo.point_edges.row(p.idx()) {
        if topo.edges[e.idx()].sides[1].is_none() {
            continue;
        }
        let q = topo.other_end(e, p);
        if topo.is_separated_at(e, q) && !topo.is_separated_at(e, p) {
            if face.is_some() {
                return None;
            }
            face = Some(e);
        }
    }
    face
}

/// Whether `p` has split, or an edge joins it to a point that has (a crack passes at or beside
/// it).
pub fn on_or_beside_crack(topo: &Topology, p: PointId) -> bool {
    topo.point_clusters[p.idx()].len() > 1 || topo.point_edges.row(p.idx()).iter().any(|&e| topo.point_clusters[topo.other_end(e, p).idx()].len() > 1)
}

/// The crack's edges as segments (reference coordinates of their ends): every interior edge
/// separated at one end or both (`Topology::crack_state` >= 1), in edge order. What
/// [`near_crack`] measures against (the shield of a rule that grows tips, ours, session 27).
pub fn crack_segments(topo: &Topology, x: &[[f64; 2]]) -> Vec<[[f64; 2]; 2]> {
    (0..topo.edges.len())
        .filter(|&e| topo.edges[e].sides[1].is_some() && topo.crack_state(EdgeId::new(e)) > 0)
        .map(|e| {
            let [a, b] = topo.edges[e].points;
            [x[a.idx()], x[b.idx()]]
        })
        .collect()
}

/// Whether some segment of `segs` passes within `d` of `xp` (Euclidean distance to the
/// segment, its ends included), with a relative margin of 1e-9: a point exactly `d` away (a
/// structured grid's row `shield` element sizes from a crack along a grid line) counts as within,
/// whatever the round-off of its coordinates.
pub fn near_crack(segs: &[[[f64; 2]; 2]], xp: [f64; 2], d: f64) -> bool {
    let d2 = (d * (1.0 + 1e-9)).powi(2);
    segs.iter().any(|&[xa, xb]| super::nonlocal::segment_distance2(xp, xa, xb) <= d2)
}

/// Mean length of the edges through `p`.
pub fn size_at(topo: &Topology, x: &[[f64; 2]], p: PointId) -> f64 {
    let row = topo.point_edges.row(p.idx());
    let s: f64 = row
        .iter()
        .map(|&e| {
            let [a, b] = topo.edges[e.idx()].points;
            let (pa, pb) = (x[a.idx()], x[b.idx()]);
            (pa[0] - pb[0]).hypot(pa[1] - pb[1])
        })
        .sum();
    s / row.len().max(1) as f64
}

/// Every tip of the topology, in point order.
pub fn tips(topo: &Topology, x: &[[f64; 2]]) -> Vec<Tip> {
    let mut pts: Vec<PointId> = topo.joined_crack_ends().into_iter().map(|(p, _)| p).collect();
    pts.dedup();
    pts.into_iter().filter_map(|p| tip_face(topo, p).map(|face| Tip { point: p, face, h: size_at(topo, x, p) })).collect()
}

/// The tip a failed point at `p` grows: `p` itself when it is a tip, else the nearest tip
/// within `radius` of that tip's element size; `None`: no tip near.
pub fn route(tips: &[Tip], x: &[[f64; 2]], p: PointId, radius: f64) -> Option<Tip> {
    if let Some(t) = tips.iter().find(|t| t.point == p) {
        return Some(*t);
    }
    let xp = x[p.idx()];
    let d = |t: &Tip| (x[t.point.idx()][0] - xp[0]).hypot(x[t.point.idx()][1] - xp[1]);
    tips.iter().filter(|t| d(t) <= radius * t.h).min_by(|a, b| d(a).total_cmp(&d(b)).then(a.point.cmp(&b.point))).copied()
}

/// Smallest corner sine of a polygon `x` (orientation sign `s0`), and its signed area.
fn shape(x: &[[f64; 2]], s0: f64) -> (f64, f64) {
    let n = x.len();
    let mut area = 0.0;
    let mut smin = f64::INFINITY;
    for i in 0..n {
        let (a, b, c) = (x[(i + n - 1) % n], x[i], x[(i + 1) % n]);
        area += 0.5 * (b[0] * c[1] - c[0] * b[1]);
        let (v1, v2) = ([c[0] - b[0], c[1] - b[1]], [a[0] - b[0], a[1] - b[1]]);
        let cr = s0 * (v1[0] * v2[1] - v1[1] * v2[0]);
        smin = smin.min(cr / (v1[0].hypot(v1[1]) * v2[0].hypot(v2[1])).max(f64::MIN_POSITIVE));
    }
    (smin, area)
}

/// Ours (session 17): whether a move of `p` to `to` is an interior point's (`Ok(true)`), or a
/// boundary point's slide along a straight stretch of the outer boundary (`Ok(true)`: exactly two
/// boundary edges at `p`, collinear to 1e-9, and `to` on their line to 1e-9 of their length; the
/// body's outline is unchanged). `Ok(false)`: a boundary point otherwise (a corner, or a move off
/// the boundary's line). A slide lets the crack leave the body where its line meets the boundary
/// rather than at the nearest boundary node (docs/paths.md, "The shear test's whole path"). What
/// was integrated on the boundary edges at the start (a traction's nodal forces) is not
/// integrated again: the rule proposes a slide only with `slide = true`.
pub fn slides_along_boundary(model: &Model, p: PointId, to: [f64; 2]) -> Result<bool, &'static str> {
    let topo = &model.topo;
    let x = &model.mesh.points;
    let xp = x[p.idx()];
    let mut ends: Vec<[f64; 2]> = Vec::new();
    for &e in topo.point_edges.row(p.idx()) {
        if topo.edges[e.idx()].sides[1].is_none() {
            ends.push(x[topo.other_end(e, p).idx()]);
        }
    }
    if ends.is_empty() {
        return Ok(true);
    }
    if ends.len() != 2 {
        return Ok(false);
    }
    let (a, b) = ([ends[0][0] - xp[0], ends[0][1] - xp[1]], [ends[1][0] - xp[0], ends[1][1] - xp[1]]);
    let (la, lb) = (a[0].hypot(a[1]), b[0].hypot(b[1]));
    let straight = (a[0] * b[1] - a[1] * b[0]).abs() <= 1e-9 * la * lb && a[0] * b[0] + a[1] * b[1] < 0.0;
    let d = [to[0] - xp[0], to[1] - xp[1]];
    let on_line = (a[0] * d[1] - a[1] * d[0]).abs() <= 1e-9 * la * la.min(lb);
    Ok(straight && on_line)
}

/// The fixity mask's classes (`Loads::held_points`, ours, session 18): a point that never moves.
pub const HELD: u8 = 1;
/// A point held by supports that cover both of its boundary edges: it may slide along a straight
/// boundary, never leave it.
pub const SLIDES: u8 = 2;

/// The reason [`check_move_held`] gives for a held point.
pub const HELD_MSG: &str = "the point carries a boundary condition (support, load or prescribed motion)";

/// [`check_move`], and first (ours, session 18) the fixity mask `held` (per point, built once at
/// set-up: `Loads::held_points`): a [`HELD`] point (a point load, a prescribed velocity or
/// displacement, an end of a loaded face, the end of a support) never moves; a [`SLIDES`] point
/// (supported, the support covering both its boundary edges) only slides along a straight
/// boundary ([`slides_along_boundary`]). Otherwise a move would change the problem being solved.
/// `held` shorter than the points (empty): nothing held.
pub fn check_move_held(model: &Model, held: &[u8], p: PointId, to: [f64; 2]) -> Result<(), &'static str> {
    match held.get(p.idx()).copied().unwrap_or(0) {
        0 => {}
        SLIDES if is_on_boundary(model, p) => {}
        _ => return Err(HELD_MSG),
    }
    check_move(model, p, to)
}

/// Whether `p` is an end of an outer boundary edge.
fn is_on_boundary(model: &Model, p: PointId) -> bool {
    let topo = &model.topo;
    topo.point_edges.row(p.idx()).iter().any(|&e| topo.edges[e.idx()].sides[1].is_none())
}

/// Whether `p` may move to `to` (see the module doc); the reason when not. The fixity mask is
/// [`check_move_held`]'s.
pub fn check_move(model: &Model, p: PointId, to: [f64; 2]) -> Result<(), &'static str> {
    let topo = &model.topo;
    if !(to[0].is_finite() && to[1].is_finite()) {
        return Err("not finite");
    }
    if topo.point_clusters[p.idx()].len() != 1 {
        return Err("the point has split");
    }
    if !slides_along_boundary(model, p, to)? {
        return Err("a boundary point");
    }
    for &e in topo.point_edges.row(p.idx()) {
        if topo.is_separated_at(e, p) || topo.is_separated_at(e, topo.other_end(e, p)) {
            return Err("the point lies on a crack face");
        }
    }
    let sin_min = MIN_ANGLE_DEG.to_radians().sin();
    for &k in topo.point_copies.row(p.idx()) {
        let e = topo.copy_elem[k.idx()];
        let corners = model.mesh.cells[e.idx()].corners();
        let old: Vec<[f64; 2]> = corners.iter().map(|&q| model.mesh.points[q as usize]).collect();
        let new: Vec<[f64; 2]> = corners.iter().map(|&q| if q as usize == p.idx() { to } else { model.mesh.points[q as usize] }).collect();
        let (_, a0) = shape(&old, 1.0);
        let s0 = a0.signum();
        let (m0, _) = shape(&old, s0);
        let (m1, a1) = shape(&new, s0);
        if a1 * s0 <= 0.0 || m1 < sin_min.min(0.5 * m0) {
            return Err("an element would be inverted or flattened");
        }
    }
    Ok(())
}
