//! Crack paths of a finished run (issue 34, must-show 2 and 4; `flem paths`, docs/paths.md):
//! the kink of the new crack at each initial crack tip, and the fragments a run cut loose.
//!
//! **Kink.** From each tip of the initial model (`sif::crack_tips` before the run) the new crack
//! faces (interior edges separated at one end at least that were not crack faces at the start)
//! are followed as a tree from the tip and from the initial crack-face points within 1.5 h of it
//! (the edge rule often starts the new crack there); the path is the tree's branch to the point farthest from the tip
//! (reference coordinates of the final mesh: a node moved by the path method counts where it
//! was moved to). Its direction over `n` element sizes `h` (the tip's, `CrackTip::h`):
//! - `chord_deg`: the direction of the chord from the tip to where the path first leaves the
//!   circle of radius `n h` around it (linear along the path's segment that crosses it);
//! - `lsq_deg`: the least-squares line through the tip of the path's points inside that circle
//!   (with the crossing point), `0.5 atan2(2 Sxy, Sxx - Syy)` in the tip's frame, oriented along
//!   the chord;
//!
//! both measured from the pre-crack's direction at the tip, positive counter-clockwise, in
//! (-180, 180] deg. A path that never leaves the circle is reported `reached = false` with the
//! chord to its farthest point.
//!
//! **Fragments.** Elements joined through a shared cluster form a fragment; `small_fragments`
//! counts the fragments of fewer than 3 elements (debris).
use serde::Serialize;

use flem_core::element::model::Model;
use flem_core::ids::{EdgeId, PointId};

use super::sif::CrackTip;

/// The new crack at one initial tip.
#[derive(Clone, Debug, Serialize)]
pub struct Kink {
    pub tip_point: usize,
    pub tip: [f64; 2],
    /// Pre-crack direction at the tip (deg from +x).
    pub crack_deg: f64,
    pub h: f64,
    /// Radius of the measurement, `n h`.
    pub radius: f64,
    /// The path reached the radius.
    pub reached: bool,
    /// Length of the followed path (along it) and its number of segments.
    pub length: f64,
    pub segments: usize,
    /// Branch points of the new crack's tree (0: one path).
    pub branches: usize,
    pub chord_deg: Option<f64>,
    pub lsq_deg: Option<f64>,
    /// The path's points (reference coordinates), from the tip.
    pub path: Vec<[f64; 2]>,
    /// Index in `path` of its first point on the outer boundary (the crack has run through
    /// there); `None`: it has not reached the boundary.
    pub boundary_at: Option<usize>,
}

impl Kink {
    /// The path up to where it first reaches the outer boundary (all of it when it does not):
    /// what two runs' paths are compared on (`hausdorff`), whatever a run cut after that.
    pub fn through(&self) -> &[[f64; 2]] {
        &self.path[..self.boundary_at.map_or(self.path.len(), |i| i + 1)]
    }
}

/// Which edges are crack faces (separated at one end at least).
pub fn crack_faces(model: &Model) -> Vec<bool> {
    let topo = &model.topo;
    (0..topo.edges.len())
        .map(|e| {
            let ed = &topo.edges[e];
            let id = EdgeId::new(e);
            ed.sides[1].is_some() && topo.crack_state(id) > 0
        })
        .collect()
}

fn wrap_deg(a: f64) -> f64 {
    let mut a = a % 360.0;
    if a <= -180.0 {
        a += 360.0;
    } else if a > 180.0 {
        a -= 360.0;
    }
    a
}

/// The kink at every tip of `tips` (the initial model's), in the final `model`; `initial`:
/// [`crack_faces`] of the initial model; `n`: element sizes of the measurement.
pub fn kinks(model: &Model, tips: &[CrackTip], initial: &[bool], n: f64) -> Vec<Kink> {
    kinks_in_order(model, tips, initial, n, &[])
}

/// The cut at which each edge first became a crack face: the index into `cuts` (the run's
/// `Cracking::cuts`, in cut order: cluster and cut edges) of the first cut that holds it;
/// `u32::MAX` for an edge never cut.
pub fn edge_cut_order(n_edges: usize, cuts: &[(u32, Vec<u32>)]) -> Vec<u32> {
    let mut t = vec![u32::MAX; n_edges];
    for (i, (_, edges)) in cuts.iter().enumerate() {
        for &e in edges {
            if let Some(slot) = t.get_mut(e as usize) {
                *slot = (*slot).min(i as u32);
            }
        }
    }
    t
}

/// As [`kinks`], with the run's cuts in order (`Cracking::cuts`; ours, session 17): when the new
/// crack reaches the outer boundary, the path is the one along which it reached it **first**,
/// not the branch to the farthest point. Among the paths through the new crack faces from the
/// tip (and its seeds) to a boundary point, the one whose latest cut is earliest (a minimax
/// path over the cut index, fewest segments on a tie) is taken. A crack that another crack,
/// started later elsewhere (by the edge rule, away from every tip), runs into is then still
/// measured along its own faces: with the farthest point, the shear test's `t3_2` run followed
/// such a later crack from where it joined (docs/paths.md). Without cuts (`&[]`), or when the
/// crack has not reached the boundary, it is [`kinks`]'s farthest point.
pub fn kinks_in_order(model: &Model, tips: &[CrackTip], initial: &[bool], n: f64, cuts: &[(u32, Vec<u32>)]) -> Vec<Kink> {
    let order_of = (!cuts.is_empty()).then(|| edge_cut_order(model.topo.edges.len(), cuts));
    let topo = &model.topo;
    let x = &model.mesh.points;
    let now = crack_faces(model);
    let np = x.len();
    tips.iter()
        .map(|t| {
            let p0 = PointId::new(t.point);
            // Breadth-first tree over the new crack faces from the tip.
            let mut parent: Vec<u32> = vec![u32::MAX; np];
            let mut seen = vec![false; np];
            seen[p0.idx()] = true;
            let mut queue = std::collections::VecDeque::from([p0]);
            // The edge rule often starts the new crack at a face point just behind the tip (its
            // corner mean is as high): the points of the initial crack faces within 1.5 h of the
            // tip seed the tree too.
            for (e, &f) in initial.iter().enumerate() {
                if !f {
                    continue;
                }
                for q in topo.edges[e].points {
                    let xq = x[q.idx()];
                    if !seen[q.idx()] && (xq[0] - t.x[0]).hypot(xq[1] - t.x[1]) <= 1.5 * t.h {
                        seen[q.idx()] = true;
                        queue.push_back(q);
                    }
                }
            }
            let sources: Vec<PointId> = queue.iter().copied().collect();
            let mut order = Vec::new();
            let mut branches = 0;
            while let Some(p) = queue.pop_front() {
                order.push(p);
                let mut kids = 0;
                for &e in topo.point_edges.row(p.idx()) {
                    if !now[e.idx()] || initial.get(e.idx()).copied().unwrap_or(false) {
                        continue;
                    }
                    let q = topo.other_end(e, p);
                    if !seen[q.idx()] {
                        seen[q.idx()] = true;
                        parent[q.idx()] = p.0;
                        queue.push_back(q);
                        kids += 1;
                    }
                }
                if kids > 1 {
                    branches += kids - 1;
                }
            }
            let on_boundary = |p: PointId| topo.point_edges.row(p.idx()).iter().any(|&e| topo.edges[e.idx()].sides[1].is_none());
            let first = order_of.as_ref().and_then(|ord| first_through(topo, &now, initial, ord, &sources, &on_boundary));
            let ids = match first {
                Some(ids) => ids,
                None => {
                    let d = |p: PointId| (x[p.idx()][0] - t.x[0]).hypot(x[p.idx()][1] - t.x[1]);
                    let far = order.iter().copied().max_by(|a, b| d(*a).total_cmp(&d(*b)).then(b.cmp(a))).unwrap_or(p0);
                    let mut ids = vec![far];
                    let mut p = far;
                    while parent[p.idx()] != u32::MAX {
                        p = PointId(parent[p.idx()]);
                        ids.push(p);
                    }
                    ids.reverse();
                    ids
                }
            };
            let path: Vec<[f64; 2]> = ids.iter().map(|p| x[p.idx()]).collect();
            let boundary_at = ids.iter().skip(1).position(|&p| on_boundary(p)).map(|i| i + 1);
            let radius = n * t.h;
            let length: f64 = path.windows(2).map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1])).sum();
            let crack = t.dir[1].atan2(t.dir[0]);
            let rel = |v: [f64; 2]| wrap_deg((v[1].atan2(v[0]) - crack).to_degrees());
            // The first crossing of the circle.
            let mut pts: Vec<[f64; 2]> = Vec::new();
            let mut end: Option<[f64; 2]> = None;
            for w in path.windows(2) {
                let (a, b) = ([w[0][0] - t.x[0], w[0][1] - t.x[1]], [w[1][0] - t.x[0], w[1][1] - t.x[1]]);
                pts.push(a);
                let (ra, rb) = (a[0].hypot(a[1]), b[0].hypot(b[1]));
                if rb >= radius && ra < radius {
                    // Solve |a + s (b - a)| = radius for s in [0, 1].
                    let dv = [b[0] - a[0], b[1] - a[1]];
                    let (qa, qb, qc) = (dv[0] * dv[0] + dv[1] * dv[1], 2.0 * (a[0] * dv[0] + a[1] * dv[1]), ra * ra - radius * radius);
                    let s = ((-qb + (qb * qb - 4.0 * qa * qc).max(0.0).sqrt()) / (2.0 * qa)).clamp(0.0, 1.0);
                    end = Some([a[0] + s * dv[0], a[1] + s * dv[1]]);
                    break;
                }
            }
            let reached = end.is_some();
            let end = end.or_else(|| path.last().map(|l| [l[0] - t.x[0], l[1] - t.x[1]])).filter(|e| e[0].hypot(e[1]) > 0.0);
            let chord_deg = end.map(rel);
            let lsq_deg = end.map(|e| {
                pts.push(e);
                let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
                for v in &pts {
                    sxx += v[0] * v[0];
                    syy += v[1] * v[1];
                    sxy += v[0] * v[1];
                }
                let th = 0.5 * (2.0 * sxy).atan2(sxx - syy);
                let dir = [th.cos(), th.sin()];
                let dir = if dir[0] * e[0] + dir[1] * e[1] < 0.0 { [-dir[0], -dir[1]] } else { dir };
                rel(dir)
            });
            Kink {
                tip_point: t.point,
                tip: t.x,
                crack_deg: crack.to_degrees(),
                h: t.h,
                radius,
                reached,
                length,
                segments: path.len().saturating_sub(1),
                branches,
                chord_deg,
                lsq_deg,
                path,
                boundary_at,
            }
        })
        .collect()
}

/// The path (point ids, from its source) along which the new crack first reached the outer
/// boundary ([`kinks_in_order`]): a minimax search (Dijkstra's, on the key) over the new crack
/// faces from `sources` (the tip and its seeds), the key of a path being (its latest cut, its
/// segments), compared in that order. `None`: no boundary point is reached.
fn first_through(topo: &flem_core::mesh::topology::Topology, now: &[bool], initial: &[bool], ord: &[u32], sources: &[PointId], on_boundary: &dyn Fn(PointId) -> bool) -> Option<Vec<PointId>> {
    use std::cmp::Reverse;
    use std::collections::{BTreeMap, BinaryHeap};
    let mut key: BTreeMap<u32, (u32, u32)> = BTreeMap::new();
    let mut parent: BTreeMap<u32, u32> = BTreeMap::new();
    let mut heap = BinaryHeap::new();
    for &p in sources {
        key.insert(p.0, (0, 0));
        heap.push(Reverse((0u32, 0u32, p.0)));
    }
    while let Some(Reverse((t, hops, p))) = heap.pop() {
        if key.get(&p).is_some_and(|&k| k < (t, hops)) {
            continue;
        }
        let pid = PointId(p);
        if hops > 0 && on_boundary(pid) {
            let mut ids = vec![pid];
            let mut q = p;
            while let Some(&r) = parent.get(&q) {
                ids.push(PointId(r));
                q = r;
            }
            ids.reverse();
            return Some(ids);
        }
        for &e in topo.point_edges.row(p as usize) {
            if !now[e.idx()] || initial.get(e.idx()).copied().unwrap_or(false) {
                continue;
            }
            let q = topo.other_end(e, pid).0;
            let k = (t.max(ord[e.idx()]), hops + 1);
            if key.get(&q).is_none_or(|&old| k < old) {
                key.insert(q, k);
                parent.insert(q, p);
                heap.push(Reverse((k.0, k.1, q)));
            }
        }
    }
    None
}

/// Sizes (element counts) of the fragments: elements joined through a shared cluster.
pub fn fragment_sizes(model: &Model) -> Vec<usize> {
    let topo = &model.topo;
    let ne = topo.n_elems();
    let mut up: Vec<usize> = (0..ne).collect();
    fn find(up: &mut [usize], mut i: usize) -> usize {
        while up[i] != i {
            up[i] = up[up[i]];
            i = up[i];
        }
        i
    }
    let mut first: Vec<usize> = vec![usize::MAX; topo.n_clusters()];
    for k in 0..topo.copy_cluster.len() {
        let c = topo.copy_cluster[k].idx();
        let e = topo.copy_elem[k].idx();
        if first[c] == usize::MAX {
            first[c] = e;
        } else {
            let (a, b) = (find(&mut up, first[c]), find(&mut up, e));
            if a != b {
                up[a.max(b)] = a.min(b);
            }
        }
    }
    let mut size = vec![0usize; ne];
    for e in 0..ne {
        let r = find(&mut up, e);
        size[r] += 1;
    }
    let mut out: Vec<usize> = size.into_iter().filter(|&s| s > 0).collect();
    out.sort_unstable();
    out
}

/// Distance from `p` to the segment `a`-`b`.
fn seg_dist(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let s = if l2 > 0.0 { (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0) } else { 0.0 };
    (p[0] - a[0] - s * dx).hypot(p[1] - a[1] - s * dy)
}

/// Distance from `p` to the polyline `b` (a single point when it has one vertex).
fn poly_dist(p: [f64; 2], b: &[[f64; 2]]) -> f64 {
    match b {
        [] => f64::INFINITY,
        [q] => (p[0] - q[0]).hypot(p[1] - q[1]),
        _ => b.windows(2).map(|w| seg_dist(p, w[0], w[1])).fold(f64::INFINITY, f64::min),
    }
}

/// Directed Hausdorff distance `sup_{x in a} dist(x, b)` of two polylines, with the points of
/// `a` sampled along each segment at spacing at most `step` (the vertices included): the
/// result is below the exact value by at most `step / 2` (distance to `b` is 1-Lipschitz).
pub fn directed_hausdorff(a: &[[f64; 2]], b: &[[f64; 2]], step: f64) -> f64 {
    let mut d: f64 = a.first().map_or(0.0, |&p| poly_dist(p, b));
    for w in a.windows(2) {
        let len = (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
        let n = ((len / step).ceil() as usize).max(1);
        for i in 1..=n {
            let s = i as f64 / n as f64;
            d = d.max(poly_dist([w[0][0] + s * (w[1][0] - w[0][0]), w[0][1] + s * (w[1][1] - w[0][1])], b));
        }
    }
    d
}

/// Hausdorff distance between two polylines (issue 34, must-show 3: two meshes' crack paths),
/// `max(h(a, b), h(b, a))` by [`directed_hausdorff`] at spacing `step` (accurate to `step / 2`).
pub fn hausdorff(a: &[[f64; 2]], b: &[[f64; 2]], step: f64) -> f64 {
    directed_hausdorff(a, b, step).max(directed_hausdorff(b, a, step))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: distances by hand. A horizontal unit segment against the same segment lifted
    /// by 0.1: 0.1 both ways. Against a V with its apex at (0.5, 0.3): the apex is 0.3 from the
    /// segment; the farthest point of the segment from the V is its middle, at
    /// 0.3 / sqrt(1 + 0.6^2) from each leg (an interior point of the segment, which vertex
    /// sampling alone would miss). A path longer by 0.2 is 0.2 away.
    #[test]
    fn hausdorff_of_simple_polylines() {
        let a = [[0.0, 0.0], [1.0, 0.0]];
        let b = [[0.0, 0.1], [1.0, 0.1]];
        assert!((hausdorff(&a, &b, 1e-3) - 0.1).abs() < 1e-12);
        let v = [[0.0, 0.0], [0.5, 0.3], [1.0, 0.0]];
        assert!((hausdorff(&a, &v, 1e-4) - 0.3).abs() < 1e-12);
        let mid = 0.3 / (1.0f64 + 0.36).sqrt();
        assert!((directed_hausdorff(&a, &v, 1e-5) - mid).abs() < 1e-5, "{}", directed_hausdorff(&a, &v, 1e-5));
        let c = [[0.0, 0.0], [1.2, 0.0]];
        assert!((hausdorff(&a, &c, 1e-3) - 0.2).abs() < 1e-12);
        assert_eq!(hausdorff(&a, &a, 1e-3), 0.0);
    }
}
