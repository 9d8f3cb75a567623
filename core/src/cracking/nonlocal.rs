//! The nonlocal failure check (ours, not the paper's: issue 18, docs/nonlocal.md).
//!
//! With `[cracking] nonlocal = { radius = R }` the stress handed to the failure criterion at a
//! cluster is not the paper's corner mean (METHOD section 3) but the area-weighted mean of the
//! Gauss-point stresses within distance `R` of its point:
//!
//! `sigma_bar(c) = sum_g w_g sigma_g / sum_g w_g`, over the Gauss points `g` with
//! `|x_g - x_p| <= R` that `c` sees, `w_g = (quadrature weight) x det J` (the area the point
//! stands for), distances in the reference configuration. Q4: 2 x 2 points, T3: 1 point. The
//! sigma1 direction (separation rule) comes from the averaged tensor. Every criterion, built-in
//! or from a plugin library, receives it like the local stress.
//!
//! **Visibility** (Belytschko, Lu and Gu's visibility criterion, 1994): a crack is opaque. A
//! Gauss point is seen by cluster `c` at point `p` when
//! 1. it lies in one of `c`'s own elements (an element is convex: the segment stays inside it), or
//! 2. the straight segment from `p` to it leaves `p` into the wedge of one of `c`'s own elements
//!    (this only matters at a point that has split: the copies on the other side of the crack
//!    through `p` belong to other clusters), and crosses no crack edge in its interior.
//!
//! A *crack edge* is an element edge separated at one end or both (`Topology::crack_state > 0`):
//! the whole edge is opaque, from the split point to the next (still joined) crack tip. Passing
//! exactly through an edge's end point is not a crossing (the segment touches the tip).
//!
//! Cost: the Gauss points within `R` of every point are found once per mesh (kiddo k-d tree,
//! sorted by index, so sums do not depend on the tree). After splits, only the points within
//! `R + L/2` of the midpoint of a new crack edge (length `L`) are re-filtered, and only against
//! the crack edges within reach (a bounding-box test over the crack edges: they are few, a
//! linear scan with a box test costs less than keeping a second tree up to date). A check does
//! no allocation: Gauss stresses into a kept buffer, one weighted sum per cluster.
use kiddo::{ImmutableKdTree, SquaredEuclidean};

use crate::element::model::Model;
use crate::element::registry;
use crate::error::{FlemError, Result};
use crate::ids::{ClusterId, EdgeId, PointId};
use crate::mesh::topology::{Csr, Topology};
use crate::mesh::{CellKind, RawMesh};
use crate::scene::NonlocalWeight;

/// Gauss points of one element: (position, quadrature weight x det J), those of its cell
/// type's default element kind (`element::registry`; `Model::new` refuses a mesh whose cell
/// type has none linked).
fn elem_gauss(kind: CellKind, x: &[[f64; 2]], out: &mut Vec<([f64; 2], f64)>) {
    if let Some(k) = registry::default_for(kind) {
        k.gauss_points(x, out);
    }
}

/// Squared distance from `x` to the segment `a`-`b` (also `path::near_crack`'s).
pub(crate) fn segment_distance2(x: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (d, w) = ([b[0] - a[0], b[1] - a[1]], [x[0] - a[0], x[1] - a[1]]);
    let l2 = d[0] * d[0] + d[1] * d[1];
    let t = if l2 > 0.0 { ((w[0] * d[0] + w[1] * d[1]) / l2).clamp(0.0, 1.0) } else { 0.0 };
    (w[0] - t * d[0]).powi(2) + (w[1] - t * d[1]).powi(2)
}

/// Neighbour lists, visibility filter and buffers of the nonlocal check.
pub struct Nonlocal {
    pub radius: f64,
    /// The distance weight (`uniform` or `bell`).
    pub weight: NonlocalWeight,
    /// Crack tracking (`exclusion`): near a crack only its tips may split.
    pub exclusion: Option<f64>,
    /// First Gauss point of each element (Gauss points are numbered element by element).
    pub first_gp: Vec<u32>,
    /// Reference position, weight (w det J) and element of every Gauss point.
    pub gp_x: Vec<[f64; 2]>,
    pub gp_w: Vec<f64>,
    pub gp_elem: Vec<u32>,
    /// Stress at every Gauss point at the last check (tension positive).
    pub gp_s: Vec<[f64; 3]>,
    /// Gauss points within the radius of each point, increasing index (before any crack).
    near: Csr<u32>,
    /// The weight of each entry of `near` divided by its row's total (one multiply-add per
    /// entry in a check, no indirection for the weight).
    near_w: Vec<f64>,
    /// Mesh points, for the patch after splits.
    point_tree: ImmutableKdTree<f64, 2>,
    /// The visible list of a cluster when a crack hides some of its point's list, with its
    /// weights normalised over that list.
    own: Vec<Option<(Vec<u32>, Vec<f64>)>>,
    /// Reference positions of the mesh points (the distance weights of the visible lists).
    points: Vec<[f64; 2]>,
    /// Edges known to be crack edges, and their segments (reference configuration).
    is_crack: Vec<bool>,
    cracks: Vec<(EdgeId, [[f64; 2]; 2])>,
    /// Clusters already looked at for new crack edges.
    seen_clusters: usize,
    /// Largest element edge (the warning for a radius below it).
    pub largest_edge: f64,
}

impl Nonlocal {
    /// Builds the neighbour lists of `model`'s mesh. A point whose radius catches no Gauss
    /// point is refused, naming the key and the node. Returns the warnings to show.
    pub fn new(radius: f64, weight: NonlocalWeight, model: &Model, file: &str) -> Result<(Nonlocal, Vec<String>)> {
        let key = "cracking.nonlocal.radius";
        if !(radius.is_finite() && radius > 0.0) {
            return Err(FlemError::config(file, key, format!("= {radius} is incorrect; it must be finite and > 0")));
        }
        let mesh: &RawMesh = &model.mesh;
        let topo = &model.topo;
        let ne = topo.n_elems();
        let (mut gp_x, mut gp_w, mut gp_elem, mut first_gp) = (Vec::new(), Vec::new(), Vec::new(), Vec::with_capacity(ne));
        let mut buf = Vec::with_capacity(4);
        let mut largest_edge: f64 = 0.0;
        for (e, c) in mesh.cells.iter().enumerate() {
            let n = c.kind.nodes();
            let xs: Vec<[f64; 2]> = c.nodes[..n].iter().map(|&p| mesh.points[p as usize]).collect();
            for a in 0..n {
                let (p, q) = (xs[a], xs[(a + 1) % n]);
                largest_edge = largest_edge.max(((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt());
            }
            buf.clear();
            elem_gauss(c.kind, &xs, &mut buf);
            first_gp.push(gp_x.len() as u32);
            for &(x, w) in &buf {
                gp_x.push(x);
                gp_w.push(w);
                gp_elem.push(e as u32);
            }
        }
        let tree: ImmutableKdTree<f64, 2> = ImmutableKdTree::new_from_slice(&gp_x).map_err(|e| FlemError::config(file, key, format!("the Gauss points could not be indexed: {e:?}")))?;
        let r2 = radius * radius;
        let mut offsets = Vec::with_capacity(mesh.points.len() + 1);
        let mut items: Vec<u32> = Vec::new();
        offsets.push(0u32);
        for p in 0..mesh.points.len() {
            let start = items.len();
            if !topo.point_copies.row(p).is_empty() {
                let found = tree.query(&mesh.points[p]).within::<SquaredEuclidean<f64>>(r2).unsorted().execute();
                items.extend(found.iter().map(|f| f.item));
                items[start..].sort_unstable();
                if items.len() == start {
                    return Err(FlemError::config(
                        file,
                        key,
                        format!("= {radius} catches no Gauss point within that distance of {}; it must be at least the distance from every node to the nearest Gauss point", mesh.point_name(p)),
                    ));
                }
            }
            offsets.push(items.len() as u32);
        }
        let point_tree: ImmutableKdTree<f64, 2> = ImmutableKdTree::new_from_slice(&mesh.points).map_err(|e| FlemError::config(file, key, format!("the mesh points could not be indexed: {e:?}")))?;
        let mut warnings = Vec::new();
        if radius < largest_edge {
            warnings.push(format!(
                "{file}: {key} = {radius} is below the largest element size ({largest_edge:.4e}): where elements are that large the average catches only the Gauss points next to the node and degenerates to the local stress there"
            ));
        }
        let n_gp = gp_x.len();
        let mut nl = Nonlocal {
            radius,
            weight,
            exclusion: None,
            first_gp,
            gp_x,
            gp_w,
            gp_elem,
            gp_s: vec![[0.0; 3]; n_gp],
            near: Csr { offsets, items },
            near_w: Vec::new(),
            point_tree,
            own: Vec::new(),
            points: mesh.points.clone(),
            is_crack: vec![false; topo.edges.len()],
            cracks: Vec::new(),
            seen_clusters: topo.n_points,
            largest_edge,
        };
        nl.near_w = vec![0.0; nl.near.items.len()];
        for p in 0..mesh.points.len() {
            let (a, b) = (nl.near.offsets[p] as usize, nl.near.offsets[p + 1] as usize);
            for i in a..b {
                nl.near_w[i] = nl.raw_weight(p, nl.near.items[i] as usize);
            }
            let total: f64 = nl.near_w[a..b].iter().sum();
            if a < b && !(total > 0.0) {
                // The bell weighs a point at exactly the radius by zero.
                return Err(FlemError::config(
                    file,
                    key,
                    format!("= {radius} gives every Gauss point it catches at {} a zero weight (they all lie at the radius); take a larger radius", mesh.point_name(p)),
                ));
            }
            for w in &mut nl.near_w[a..b] {
                *w /= total;
            }
        }
        nl.sync(topo, &mesh.points);
        Ok((nl, warnings))
    }

    /// The un-normalised weight of Gauss point `g` at point `p`: its area times the distance
    /// factor of `weight`.
    #[inline]
    fn raw_weight(&self, p: usize, g: usize) -> f64 {
        let (xp, xg) = (self.points[p], self.gp_x[g]);
        let r2 = (xg[0] - xp[0]).powi(2) + (xg[1] - xp[1]).powi(2);
        self.gp_w[g] * self.weight.factor(r2, self.radius)
    }

    /// Where the failure of cluster `c` splits under crack tracking (`exclusion`, ours after
    /// Cervera and Chiumenti's exclusion radius; docs/nonlocal.md). Without it, or before any
    /// crack, or when `c`'s point lies farther than the exclusion distance from every crack
    /// edge: at `c` itself. Otherwise at the crack tip nearest to `c`'s point (the joined end
    /// of an edge separated at its other end; `c` itself when it is one) if that tip lies
    /// within the exclusion distance: a crack grows from its tip when its process zone fails.
    /// `None`: no tip within reach (a point beside a crack face, shielded by it): no split.
    /// Reads the crack edges of the last `sync`.
    pub fn route(&self, topo: &Topology, c: ClusterId) -> Option<ClusterId> {
        let Some(ex) = self.exclusion else { return Some(c) };
        if self.cracks.is_empty() {
            return Some(c);
        }
        let p = topo.cluster_point[c.idx()];
        let xp = self.points[p.idx()];
        let ex2 = ex * ex;
        if !self.cracks.iter().any(|(_, s)| segment_distance2(xp, s[0], s[1]) <= ex2) {
            return Some(c);
        }
        let mut best: Option<(f64, ClusterId)> = None;
        for (e, _) in &self.cracks {
            if topo.crack_state(*e) != 1 {
                continue;
            }
            let ed = &topo.edges[e.idx()];
            for q in ed.points {
                if topo.is_separated_at(*e, q) {
                    continue;
                }
                let Some((ea, _)) = ed.sides[0].or(ed.sides[1]) else { continue };
                let Some(k) = topo.copy_at(ea, q) else { continue };
                let tc = topo.copy_cluster[k.idx()];
                let xq = self.points[q.idx()];
                let d2 = (xq[0] - xp[0]).powi(2) + (xq[1] - xp[1]).powi(2);
                if d2 <= ex2 && best.is_none_or(|(bd, bc)| d2 < bd || (d2 == bd && tc < bc)) {
                    best = Some((d2, tc));
                }
            }
        }
        best.map(|(_, t)| t)
    }

    /// The Gauss points cluster `c` averages over (increasing index).
    pub fn caught(&self, topo: &Topology, c: ClusterId) -> &[u32] {
        match self.own.get(c.idx()) {
            Some(Some((v, _))) => v,
            _ => self.near.row(topo.cluster_point[c.idx()].idx()),
        }
    }

    /// Weighted mean of `field` (one value per Gauss point) over what cluster `c` sees.
    #[inline]
    pub fn average(&self, topo: &Topology, c: ClusterId, field: &[[f64; 3]]) -> [f64; 3] {
        let (items, weights) = match self.own.get(c.idx()) {
            Some(Some((v, w))) => (&v[..], &w[..]),
            _ => {
                // The point's full list with its normalised weights.
                let p = topo.cluster_point[c.idx()].idx();
                let (a, b) = (self.near.offsets[p] as usize, self.near.offsets[p + 1] as usize);
                (&self.near.items[a..b], &self.near_w[a..b])
            }
        };
        let mut acc = [0.0; 3];
        for (&g, &w) in items.iter().zip(weights) {
            let s = field[g as usize];
            acc[0] += w * s[0];
            acc[1] += w * s[1];
            acc[2] += w * s[2];
        }
        acc
    }

    /// Nonlocal stress of every cluster at displacement `u` into `out`.
    pub fn nodal_stress(&mut self, model: &Model, u: &[[f64; 2]], out: &mut Vec<[f64; 3]>) {
        self.sync(&model.topo, &model.mesh.points);
        for b in &model.blocks {
            b.gauss_stress(u, &self.first_gp, &mut self.gp_s);
        }
        let nc = model.topo.n_clusters();
        out.clear();
        out.extend((0..nc).map(|c| self.average(&model.topo, ClusterId(c as u32), &self.gp_s)));
    }

    /// Looks for crack edges at the points of the clusters created since the last call and
    /// re-filters the lists of the points within reach of them. Nothing to do (and no cost
    /// beyond one comparison) when nothing split.
    pub fn sync(&mut self, topo: &Topology, points: &[[f64; 2]]) {
        let nc = topo.n_clusters();
        if nc == self.seen_clusters {
            return;
        }
        self.own.resize(nc, None);
        let mut new_edges: Vec<EdgeId> = Vec::new();
        let mut split_points: Vec<PointId> = (self.seen_clusters..nc).map(|c| topo.cluster_point[c]).collect();
        split_points.sort_unstable();
        split_points.dedup();
        for &p in &split_points {
            for &e in topo.point_edges.row(p.idx()) {
                if !self.is_crack[e.idx()] && topo.crack_state(e) > 0 {
                    self.is_crack[e.idx()] = true;
                    new_edges.push(e);
                }
            }
        }
        self.seen_clusters = nc;
        let mut affected: Vec<u32> = split_points.iter().map(|p| p.0).collect();
        for &e in &new_edges {
            let [p, q] = topo.edges[e.idx()].points;
            let (a, b) = (points[p.idx()], points[q.idx()]);
            self.cracks.push((e, [a, b]));
            let mid = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
            let half = 0.5 * ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
            let reach = (self.radius + half) * (1.0 + 1e-12);
            let found = self.point_tree.query(&mid).within::<SquaredEuclidean<f64>>(reach * reach).unsorted().execute();
            affected.extend(found.iter().map(|f| f.item));
        }
        affected.sort_unstable();
        affected.dedup();
        let mut local_cracks: Vec<usize> = Vec::new();
        for &p in &affected {
            let p = p as usize;
            let xp = points[p];
            local_cracks.clear();
            let r = self.radius;
            for (i, (_, s)) in self.cracks.iter().enumerate() {
                let lo = [s[0][0].min(s[1][0]), s[0][1].min(s[1][1])];
                let hi = [s[0][0].max(s[1][0]), s[0][1].max(s[1][1])];
                if lo[0] <= xp[0] + r && hi[0] >= xp[0] - r && lo[1] <= xp[1] + r && hi[1] >= xp[1] - r {
                    local_cracks.push(i);
                }
            }
            let split = topo.point_clusters[p].len() > 1;
            for &c in &topo.point_clusters[p] {
                let base = self.near.row(p);
                let vis: Vec<u32> = base.iter().copied().filter(|&g| self.visible(topo, points, c, PointId(p as u32), g as usize, split, &local_cracks)).collect();
                self.own[c.idx()] = if vis.len() == base.len() {
                    None
                } else {
                    let mut w: Vec<f64> = vis.iter().map(|&g| self.raw_weight(p, g as usize)).collect();
                    let mut total: f64 = w.iter().sum();
                    if !(total > 0.0) {
                        // Only points at the radius are left (bell weight): the cluster's own
                        // elements' points, by area (a cluster always sees them).
                        w = vis.iter().map(|&g| self.gp_w[g as usize]).collect();
                        total = w.iter().sum();
                    }
                    w.iter_mut().for_each(|x| *x /= total);
                    Some((vis, w))
                };
            }
        }
    }

    /// Whether cluster `c` at point `p` sees Gauss point `g` (module doc).
    fn visible(&self, topo: &Topology, points: &[[f64; 2]], c: ClusterId, p: PointId, g: usize, split: bool, local_cracks: &[usize]) -> bool {
        let e = self.gp_elem[g];
        let own = |e: u32| topo.point_copies.row(p.idx()).iter().any(|k| topo.copy_cluster[k.idx()] == c && topo.copy_elem[k.idx()].0 == e);
        if own(e) {
            return true;
        }
        let (xp, xg) = (points[p.idx()], self.gp_x[g]);
        let d = [xg[0] - xp[0], xg[1] - xp[1]];
        let cross = |a: [f64; 2], b: [f64; 2]| a[0] * b[1] - a[1] * b[0];
        if split {
            // The segment must leave p into one of c's own elements (corners counter-clockwise).
            let in_wedge = topo.point_copies.row(p.idx()).iter().filter(|k| topo.copy_cluster[k.idx()] == c).any(|&k| {
                let el = topo.copy_elem[k.idx()];
                let first = topo.elem_first_copy[el.idx()] as usize;
                let n = topo.elem_nodes[el.idx()] as usize;
                let a = k.idx() - first;
                let next = points[topo.copy_point[first + (a + 1) % n].idx()];
                let prev = points[topo.copy_point[first + (a + n - 1) % n].idx()];
                cross([next[0] - xp[0], next[1] - xp[1]], d) >= 0.0 && cross(d, [prev[0] - xp[0], prev[1] - xp[1]]) >= 0.0
            });
            if !in_wedge {
                return false;
            }
        }
        let orient = |a: [f64; 2], b: [f64; 2], q: [f64; 2]| cross([b[0] - a[0], b[1] - a[1]], [q[0] - a[0], q[1] - a[1]]);
        for &i in local_cracks {
            let (edge, s) = self.cracks[i];
            if topo.edges[edge.idx()].points.contains(&p) {
                continue;
            }
            let (o1, o2) = (orient(xp, xg, s[0]), orient(xp, xg, s[1]));
            let (o3, o4) = (orient(s[0], s[1], xp), orient(s[0], s[1], xg));
            if o1 * o2 < 0.0 && o3 * o4 < 0.0 {
                return false;
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::model::MaterialCfg;
    use crate::element::Plane;
    use crate::mesh::Rectangle;

    fn model(w: f64, h: f64, nx: usize, ny: usize, kind: CellKind, distort: f64) -> Model {
        let mut r = Rectangle::new(w, h, nx, ny, kind);
        r.distort = distort;
        let mut mesh = r.build().unwrap();
        mesh.validate(Default::default()).unwrap();
        let mat = MaterialCfg::elastic(1000.0, 0.2, 1.0);
        Model::new(mesh, &[mat], Plane::Strain, "test").unwrap()
    }

    /// Reference: the weighted mean of a constant is that constant. A uniform strain gives the
    /// same stress at every Gauss point, so every node gets D eps whatever the radius, on
    /// distorted Q4 and T3 meshes; tolerance 1e-12 relative (rounding only).
    #[test]
    fn uniform_stress_is_returned_at_every_node_for_any_radius() {
        for kind in [CellKind::Q4, CellKind::T3] {
            let m = model(3.0, 2.0, 6, 4, kind, 0.2);
            let eps = [1e-3, -4e-4, 6e-4];
            let u: Vec<[f64; 2]> = m.cluster_x0().iter().map(|x| [eps[0] * x[0] + 0.5 * eps[2] * x[1], eps[1] * x[1] + 0.5 * eps[2] * x[0]]).collect();
            let d = m.blocks[0].material().dmat();
            let want = d.stress(eps);
            for (r, w) in [0.45, 0.8, 1.7, 10.0].into_iter().flat_map(|r| [(r, NonlocalWeight::Uniform), (r, NonlocalWeight::Bell)]) {
                let (mut nl, _) = Nonlocal::new(r, w, &m, "test").unwrap();
                let mut out = Vec::new();
                nl.nodal_stress(&m, &u, &mut out);
                assert_eq!(out.len(), m.topo.n_clusters());
                for s in &out {
                    for k in 0..3 {
                        assert!((s[k] - want[k]).abs() <= 1e-12 * want[0].abs(), "{kind:?} R = {r}: {s:?} vs {want:?}");
                    }
                }
            }
        }
    }

    /// Reference: a weighted mean of a linear field is the field at the weighted centroid of
    /// the points averaged. At an interior node of a uniform grid the points caught are
    /// symmetric about the node, so the centroid is the node itself (an independent value);
    /// at a boundary node the centroid is computed from the positions and weights. 1e-12.
    #[test]
    fn linear_field_gives_the_value_at_the_weighted_centroid() {
        let m = model(4.0, 4.0, 8, 8, CellKind::Q4, 0.0);
        let (nl, _) = Nonlocal::new(0.81, NonlocalWeight::Uniform, &m, "test").unwrap();
        let f = |x: [f64; 2]| [2.0 + 3.0 * x[0] - x[1], -1.0 + 0.5 * x[1], 0.25 * x[0]];
        let field: Vec<[f64; 3]> = nl.gp_x.iter().map(|&x| f(x)).collect();
        // Interior point (2, 2): index 4 * 9 + 4.
        let p = 4 * 9 + 4;
        assert_eq!(m.mesh.points[p], [2.0, 2.0]);
        let got = nl.average(&m.topo, ClusterId(p as u32), &field);
        let want = f([2.0, 2.0]);
        assert!(nl.caught(&m.topo, ClusterId(p as u32)).len() > 4, "the radius reaches beyond the node's own elements");
        for k in 0..3 {
            assert!((got[k] - want[k]).abs() < 1e-12, "{got:?} vs {want:?}");
        }
        // Corner point (0, 0): the centroid of what it catches.
        let caught = nl.caught(&m.topo, ClusterId(0));
        let wsum: f64 = caught.iter().map(|&g| nl.gp_w[g as usize]).sum();
        let cx = [0, 1].map(|d| caught.iter().map(|&g| nl.gp_w[g as usize] * nl.gp_x[g as usize][d]).sum::<f64>() / wsum);
        let (got, want) = (nl.average(&m.topo, ClusterId(0), &field), f(cx));
        for k in 0..3 {
            assert!((got[k] - want[k]).abs() < 1e-12, "{got:?} vs {want:?}");
        }
    }

    /// A constructed crack: the grid line y = 2 separated from x = 0 to x = 4 on an 8 x 4 grid
    /// (h = 1). The field is +1 above the line and -1 below it. Reference (the visibility rule):
    /// a node above the crack sees only +1 (exactly 1); the two clusters of a split point on the
    /// crack see +1 and -1; a node beyond the tip sees both sides symmetrically (0). Without the
    /// rule the node above the crack would average both sides (checked: it differs).
    #[test]
    fn points_across_a_crack_are_left_out() {
        let mut m = model(8.0, 4.0, 8, 4, CellKind::Q4, 0.0);
        let id = |i: u32, j: u32| j * 9 + i;
        let edges: Vec<EdgeId> = (0..4).map(|i| m.topo.edge_between(PointId(id(i, 2)), PointId(id(i + 1, 2))).unwrap()).collect();
        let r = 1.6;
        let (mut nl, _) = Nonlocal::new(r, NonlocalWeight::Uniform, &m, "test").unwrap();
        let field: Vec<[f64; 3]> = nl.gp_x.iter().map(|x| if x[1] > 2.0 { [1.0; 3] } else { [-1.0; 3] }).collect();
        let above = ClusterId(id(2, 3));
        let before = nl.average(&m.topo, above, &field);
        assert!(before[0] < 0.9, "before the cut the node above sees both sides: {before:?}");
        let rec = m.topo.separate_edges(&edges);
        m.apply_record(&rec);
        nl.sync(&m.topo, &m.mesh.points);
        // (Normalised weights: the sum is 1 to round-off.)
        let close = |a: [f64; 3], b: f64| a.iter().all(|x| (x - b).abs() < 1e-14);
        assert!(close(nl.average(&m.topo, above, &field), 1.0));
        let below = ClusterId(id(2, 1));
        assert!(close(nl.average(&m.topo, below, &field), -1.0));
        // The split point (2, 2): two clusters, one per side.
        let cs = &m.topo.point_clusters[id(2, 2) as usize];
        assert_eq!(cs.len(), 2);
        let mut got: Vec<f64> = cs.iter().map(|&c| nl.average(&m.topo, c, &field)[0]).collect();
        got.sort_by(f64::total_cmp);
        assert!((got[0] + 1.0).abs() < 1e-14 && (got[1] - 1.0).abs() < 1e-14, "{got:?}");
        // Beyond the tip (6, 2): both sides, symmetric.
        let beyond = nl.average(&m.topo, ClusterId(id(6, 2)), &field);
        assert!(beyond[0].abs() < 1e-12, "{beyond:?}");
    }

    /// Bad radii are refused naming the key; a radius that catches no Gauss point names the node.
    #[test]
    fn bad_radius_is_refused_naming_key_and_node() {
        let m = model(2.0, 2.0, 2, 2, CellKind::Q4, 0.0);
        for r in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = Nonlocal::new(r, NonlocalWeight::Uniform, &m, "scene.toml").err().expect("refused").to_string();
            assert!(e.contains("scene.toml") && e.contains("cracking.nonlocal.radius"), "{e}");
        }
        // Gauss points lie 0.211 h from the corners in each direction (0.30 h away).
        let e = Nonlocal::new(0.2, NonlocalWeight::Uniform, &m, "scene.toml").err().expect("refused").to_string();
        assert!(e.contains("cracking.nonlocal.radius") && e.contains("point 0"), "{e}");
        let (_, w) = Nonlocal::new(0.5, NonlocalWeight::Uniform, &m, "scene.toml").unwrap();
        assert!(w.len() == 1 && w[0].contains("degenerates to the local stress"), "{w:?}");
        let (_, w) = Nonlocal::new(1.5, NonlocalWeight::Uniform, &m, "scene.toml").unwrap();
        assert!(w.is_empty(), "{w:?}");
    }
}
