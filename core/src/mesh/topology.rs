//! The topology of element-owned node copies grouped into clusters (METHOD section 2).
//!
//! Every element owns one *copy* of each of its corners (`copy = first_copy[elem] + corner`).
//! A *cluster* is a set of copies at one point that move as one node; before any separation
//! every point is exactly one cluster (cluster id == point id), so the hot loop sees plain
//! FEM connectivity. Around a point, the copies form a *fan* linked across the element edges
//! through the point that are still joined there. This module is the only owner of that
//! topology: criteria and separation rules only propose cuts, [`Topology::cut`] applies them and
//! returns a [`SplitRecord`] that every per-cluster array consumes.
use crate::ids::{ClusterId, CopyId, EdgeId, ElemId, PointId};
use crate::mesh::RawMesh;

/// An element edge: its two points and the (element, local edge) on each side.
#[derive(Copy, Clone, Debug)]
pub struct Edge {
    pub points: [PointId; 2],
    /// The element on each side with the local edge index (edge k joins corners k and k+1).
    /// `sides[1]` is `None` on the mesh boundary.
    pub sides: [Option<(ElemId, u8)>; 2],
}

/// A link of a fan: two copies at the point, joined across `edge`.
#[derive(Copy, Clone, Debug)]
pub struct FanLink {
    pub edge: EdgeId,
    pub a: CopyId,
    pub b: CopyId,
}

/// The copies of one cluster around its point, with the links still joined there.
#[derive(Clone, Debug, Default)]
pub struct Fan {
    pub point: PointId,
    pub cluster: ClusterId,
    pub copies: Vec<CopyId>,
    pub links: Vec<FanLink>,
}

impl Fan {
    /// Closed: the links form a cycle (an interior point never split).
    pub fn is_closed(&self) -> bool {
        self.copies.len() >= 2 && self.links.len() == self.copies.len()
    }
}

/// One new cluster made by a split.
#[derive(Clone, Debug)]
pub struct NewCluster {
    pub id: ClusterId,
    pub parent: ClusterId,
    pub point: PointId,
    pub copies: Vec<CopyId>,
}

/// What a call to [`Topology::cut`] changed; every per-cluster array follows it.
#[derive(Clone, Debug, Default)]
pub struct SplitRecord {
    /// Edges whose cut flag was set, with the end index (0 or 1) at which they were cut.
    pub cut_edges: Vec<(EdgeId, u8)>,
    pub new_clusters: Vec<NewCluster>,
    /// Points moved before the cut (ours: the crack-tip node relocation of a separation rule
    /// that grows tips, `cracking::path`), with their new reference coordinates. Empty for
    /// every other rule; `Topology::cut` never fills it.
    pub moved: Vec<(PointId, [f64; 2])>,
}

impl SplitRecord {
    pub fn is_empty(&self) -> bool {
        self.new_clusters.is_empty()
    }
    pub fn extend(&mut self, other: SplitRecord) {
        self.cut_edges.extend(other.cut_edges);
        self.new_clusters.extend(other.new_clusters);
        self.moved.extend(other.moved);
    }
}

/// Compressed rows: `items[offsets[i]..offsets[i+1]]` belong to row i.
#[derive(Clone, Debug, Default)]
pub struct Csr<T> {
    pub offsets: Vec<u32>,
    pub items: Vec<T>,
}

impl<T: Copy> Csr<T> {
    pub fn row(&self, i: usize) -> &[T] {
        &self.items[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }
    pub(crate) fn from_pairs(n: usize, pairs: &[(u32, T)]) -> Self {
        let mut offsets = vec![0u32; n + 1];
        for &(r, _) in pairs {
            offsets[r as usize + 1] += 1;
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut items: Vec<Option<T>> = vec![None; pairs.len()];
        for &(r, t) in pairs {
            items[fill[r as usize] as usize] = Some(t);
            fill[r as usize] += 1;
        }
        Csr { offsets, items: items.into_iter().map(|t| t.unwrap()).collect() }
    }
}

#[derive(Clone, Debug)]
pub struct Topology {
    pub n_points: usize,
    pub elem_nodes: Vec<u8>,
    pub elem_first_copy: Vec<u32>,
    pub copy_point: Vec<PointId>,
    pub copy_elem: Vec<ElemId>,
    pub copy_cluster: Vec<ClusterId>,
    pub cluster_point: Vec<PointId>,
    /// Copies around each point, in increasing copy id.
    pub point_copies: Csr<CopyId>,
    /// Edges through each point, in increasing edge id.
    pub point_edges: Csr<EdgeId>,
    pub edges: Vec<Edge>,
    /// Per edge, whether it has been cut at its end 0 / end 1.
    pub edge_cut: Vec<[bool; 2]>,
    /// The clusters of each point, in creation order (the first is the original).
    pub point_clusters: Vec<Vec<ClusterId>>,
}

impl Topology {
    /// Builds the topology of a validated mesh: one cluster per point.
    pub fn new(mesh: &RawMesh) -> Self {
        let np = mesh.points.len();
        let Copies { elem_nodes, elem_first_copy, copy_point, copy_elem, copy_cluster, point_copies } = Copies::new(np, mesh.cells.iter().map(|c| c.corners()));
        // Edges: sort (min, max, elem, local) and pair up.
        let mut half: Vec<(u32, u32, u32, u8)> = Vec::new();
        for (e, c) in mesh.cells.iter().enumerate() {
            let k = c.kind.nodes();
            for a in 0..k {
                let (p, q) = (c.nodes[a], c.nodes[(a + 1) % k]);
                half.push((p.min(q), p.max(q), e as u32, a as u8));
            }
        }
        half.sort_unstable();
        let mut edges = Vec::new();
        let mut i = 0;
        while i < half.len() {
            let (p, q, e, l) = half[i];
            let mut sides = [Some((ElemId(e), l)), None];
            if i + 1 < half.len() && half[i + 1].0 == p && half[i + 1].1 == q {
                sides[1] = Some((ElemId(half[i + 1].2), half[i + 1].3));
                i += 1;
            }
            edges.push(Edge { points: [PointId(p), PointId(q)], sides });
            i += 1;
        }
        let pairs: Vec<(u32, EdgeId)> = edges.iter().enumerate().flat_map(|(k, e)| [(e.points[0].0, EdgeId::new(k)), (e.points[1].0, EdgeId::new(k))]).collect();
        let point_edges = Csr::from_pairs(np, &pairs);
        let edge_cut = vec![[false; 2]; edges.len()];
        Topology {
            n_points: np,
            elem_nodes,
            elem_first_copy,
            copy_point,
            copy_elem,
            copy_cluster,
            cluster_point: (0..np as u32).map(PointId).collect(),
            point_copies,
            point_edges,
            edges,
            edge_cut,
            point_clusters: (0..np as u32).map(|p| vec![ClusterId(p)]).collect(),
        }
    }

    pub fn n_elems(&self) -> usize {
        self.elem_nodes.len()
    }
    pub fn n_clusters(&self) -> usize {
        self.cluster_point.len()
    }
    /// The copies of an element, in corner order.
    pub fn elem_copies(&self, e: ElemId) -> std::ops::Range<usize> {
        self.elem_first_copy[e.idx()] as usize..self.elem_first_copy[e.idx() + 1] as usize
    }
    /// The copy of element `e` at point `p`.
    pub fn copy_at(&self, e: ElemId, p: PointId) -> Option<CopyId> {
        self.elem_copies(e).find(|&c| self.copy_point[c] == p).map(CopyId::new)
    }
    /// The edge between two points, if any.
    pub fn edge_between(&self, p: PointId, q: PointId) -> Option<EdgeId> {
        self.point_edges.row(p.idx()).iter().copied().find(|&e| {
            let pts = self.edges[e.idx()].points;
            (pts[0] == p && pts[1] == q) || (pts[0] == q && pts[1] == p)
        })
    }
    /// Which end of edge `e` point `p` is.
    pub fn end_of(&self, e: EdgeId, p: PointId) -> u8 {
        if self.edges[e.idx()].points[0] == p {
            0
        } else {
            1
        }
    }
    /// The other point of edge `e`.
    pub fn other_end(&self, e: EdgeId, p: PointId) -> PointId {
        let pts = self.edges[e.idx()].points;
        if pts[0] == p {
            pts[1]
        } else {
            pts[0]
        }
    }

    /// Whether the two sides of an interior edge are in different clusters at point `p`
    /// (a crack face at that end).
    pub fn is_separated_at(&self, e: EdgeId, p: PointId) -> bool {
        // A point of one cluster has all its copies in it (the common case, and the cheap one).
        if self.point_clusters[p.idx()].len() < 2 {
            return false;
        }
        let ed = &self.edges[e.idx()];
        match ed.sides {
            [Some((a, _)), Some((b, _))] => {
                let (ca, cb) = (self.copy_at(a, p).unwrap(), self.copy_at(b, p).unwrap());
                self.copy_cluster[ca.idx()] != self.copy_cluster[cb.idx()]
            }
            _ => false,
        }
    }

    /// Crack state of an interior edge: 0 joined, 1 separated at one end, 2 at both ends.
    pub fn crack_state(&self, e: EdgeId) -> u8 {
        let pts = self.edges[e.idx()].points;
        self.is_separated_at(e, pts[0]) as u8 + self.is_separated_at(e, pts[1]) as u8
    }

    /// The crack's ends that are still joined: `(q, e)` for every interior edge `e` separated
    /// at its other end and joined at `q`, sorted by point, then edge. Crack tips are among these
    /// points (`cracking::path::tips`, flem-plugins' `check::sif::crack_tips`).
    pub fn joined_crack_ends(&self) -> Vec<(PointId, EdgeId)> {
        let mut ends = Vec::new();
        for (e, ed) in self.edges.iter().enumerate() {
            if ed.sides[1].is_none() {
                continue;
            }
            let e = EdgeId::new(e);
            let [a, b] = ed.points;
            match (self.is_separated_at(e, a), self.is_separated_at(e, b)) {
                (true, false) => ends.push((b, e)),
                (false, true) => ends.push((a, e)),
                _ => {}
            }
        }
        ends.sort_unstable_by_key(|&(p, e)| (p.idx(), e.idx()));
        ends
    }

    /// The fan of cluster `c` around its point.
    pub fn fan(&self, c: ClusterId) -> Fan {
        let p = self.cluster_point[c.idx()];
        let copies: Vec<CopyId> = self.point_copies.row(p.idx()).iter().copied().filter(|k| self.copy_cluster[k.idx()] == c).collect();
        let mut links = Vec::new();
        for &e in self.point_edges.row(p.idx()) {
            let ed = &self.edges[e.idx()];
            let end = self.end_of(e, p) as usize;
            if self.edge_cut[e.idx()][end] {
                continue;
            }
            if let [Some((ea, _)), Some((eb, _))] = ed.sides {
                let (a, b) = (self.copy_at(ea, p).unwrap(), self.copy_at(eb, p).unwrap());
                if self.copy_cluster[a.idx()] == c && self.copy_cluster[b.idx()] == c {
                    links.push(FanLink { edge: e, a, b });
                }
            }
        }
        Fan { point: p, cluster: c, copies, links }
    }

    /// Connected parts of the fan's copies once the given edges are removed from its links;
    /// each part sorted, parts ordered by their smallest copy.
    pub fn fan_parts(fan: &Fan, removed: &[EdgeId]) -> Vec<Vec<CopyId>> {
        parts_of(&fan.copies, fan.links.iter().filter(|l| !removed.contains(&l.edge)).map(|l| (l.a, l.b)))
    }

    /// Cuts `edges` at the point of cluster `c` and splits the cluster into its connected parts.
    /// The part holding the smallest copy keeps the cluster id; the others get new ids, in order.
    /// With `require_split`, a cut that would not divide the fan changes nothing (a proposal
    /// from a separation rule); without it the cut flags are set anyway (pre-separated edges
    /// ending inside the body, e.g. at a notch tip).
    pub fn cut(&mut self, c: ClusterId, edges: &[EdgeId], require_split: bool) -> SplitRecord {
        let fan = self.fan(c);
        let p = fan.point;
        let valid: Vec<EdgeId> = edges.iter().copied().filter(|e| fan.links.iter().any(|l| l.edge == *e)).collect();
        let parts = Self::fan_parts(&fan, &valid);
        let mut rec = SplitRecord::default();
        if require_split && parts.len() < 2 {
            return rec;
        }
        for &e in &valid {
            let end = self.end_of(e, p);
            self.edge_cut[e.idx()][end as usize] = true;
            rec.cut_edges.push((e, end));
        }
        for part in parts.into_iter().skip(1) {
            let id = ClusterId::new(self.cluster_point.len());
            self.cluster_point.push(p);
            self.point_clusters[p.idx()].push(id);
            for &k in &part {
                self.copy_cluster[k.idx()] = id;
            }
            rec.new_clusters.push(NewCluster { id, parent: c, point: p, copies: part });
        }
        rec
    }

    /// Separates a set of edges from the start (a notch, a pre-cut plane): cuts them at both
    /// ends in every cluster there, splitting wherever the fan falls apart.
    pub fn separate_edges(&mut self, edges: &[EdgeId]) -> SplitRecord {
        let mut rec = SplitRecord::default();
        let mut pts: Vec<PointId> = edges.iter().flat_map(|e| self.edges[e.idx()].points).collect();
        pts.sort_unstable();
        pts.dedup();
        for p in pts {
            let at_p: Vec<EdgeId> = edges.iter().copied().filter(|e| self.edges[e.idx()].points.contains(&p)).collect();
            let clusters = self.point_clusters[p.idx()].clone();
            for c in clusters {
                rec.extend(self.cut(c, &at_p, false));
            }
        }
        rec
    }

    /// Number of interior edges separated at one end and at both ends.
    pub fn crack_counts(&self) -> (usize, usize) {
        let (mut one, mut two) = (0, 0);
        for e in 0..self.edges.len() {
            match self.crack_state(EdgeId::new(e)) {
                1 => one += 1,
                2 => two += 1,
                _ => {}
            }
        }
        (one, two)
    }

    /// Connected fragments: elements joined through shared clusters. Returns the fragment
    /// index of every element and the number of fragments (deterministic: by smallest element).
    pub fn fragments(&self) -> (Vec<u32>, usize) {
        fragments_of(self.n_elems(), self.n_clusters(), &self.copy_cluster, &self.copy_elem)
    }
}

/// Every element's own copy of each corner, one cluster per point (2D [`Topology::new`] and 3D
/// `Topology3::new`).
pub(crate) struct Copies {
    pub elem_nodes: Vec<u8>,
    pub elem_first_copy: Vec<u32>,
    pub copy_point: Vec<PointId>,
    pub copy_elem: Vec<ElemId>,
    pub copy_cluster: Vec<ClusterId>,
    pub point_copies: Csr<CopyId>,
}

impl Copies {
    /// The copies of `np` points' elements, given as their corner lists in element order.
    pub(crate) fn new<'a>(np: usize, cells: impl ExactSizeIterator<Item = &'a [u32]>) -> Copies {
        let mut elem_nodes = Vec::with_capacity(cells.len());
        let mut elem_first_copy = Vec::with_capacity(cells.len() + 1);
        let mut copy_point = Vec::new();
        let mut copy_elem = Vec::new();
        for (e, c) in cells.enumerate() {
            elem_nodes.push(c.len() as u8);
            elem_first_copy.push(copy_point.len() as u32);
            for &p in c {
                copy_point.push(PointId(p));
                copy_elem.push(ElemId::new(e));
            }
        }
        elem_first_copy.push(copy_point.len() as u32);
        let copy_cluster: Vec<ClusterId> = copy_point.iter().map(|p| ClusterId(p.0)).collect();
        let pairs: Vec<(u32, CopyId)> = copy_point.iter().enumerate().map(|(c, p)| (p.0, CopyId::new(c))).collect();
        let point_copies = Csr::from_pairs(np, &pairs);
        Copies { elem_nodes, elem_first_copy, copy_point, copy_elem, copy_cluster, point_copies }
    }
}

/// Connected parts of `copies` joined by `links` (pairs of copies among them): each part sorted,
/// parts ordered by their smallest copy, so the answer depends on the links, not their order
/// (2D and 3D fans: [`Topology::fan_parts`], `Topology3::fan_parts`).
pub(crate) fn parts_of(copies: &[CopyId], links: impl Iterator<Item = (CopyId, CopyId)>) -> Vec<Vec<CopyId>> {
    let n = copies.len();
    let pos = |c: CopyId| copies.iter().position(|&k| k == c).unwrap() as u32;
    let mut parent: Vec<u32> = (0..n as u32).collect();
    for (a, b) in links {
        let (ra, rb) = (root(&mut parent, pos(a)), root(&mut parent, pos(b)));
        if ra != rb {
            parent[ra.max(rb) as usize] = ra.min(rb);
        }
    }
    let mut parts: Vec<Vec<CopyId>> = Vec::new();
    let mut part_of_root = vec![usize::MAX; n];
    for i in 0..n {
        let r = root(&mut parent, i as u32) as usize;
        if part_of_root[r] == usize::MAX {
            part_of_root[r] = parts.len();
            parts.push(Vec::new());
        }
        parts[part_of_root[r]].push(copies[i]);
    }
    for p in &mut parts {
        p.sort_unstable();
    }
    parts.sort_by_key(|p| p[0]);
    parts
}

/// Union-find root with path halving (the fans' and fragments' components, 2D and 3D).
pub(crate) fn root(p: &mut [u32], mut i: u32) -> u32 {
    while p[i as usize] != i {
        p[i as usize] = p[p[i as usize] as usize];
        i = p[i as usize];
    }
    i
}

/// Connected fragments of `ne` elements joined through shared clusters, from the cluster and
/// element of every copy (2D [`Topology::fragments`] and 3D `Topology3::fragments`): the
/// fragment index of every element and the number of fragments, numbered by smallest element.
pub(crate) fn fragments_of(ne: usize, n_clusters: usize, copy_cluster: &[ClusterId], copy_elem: &[ElemId]) -> (Vec<u32>, usize) {
    let mut parent: Vec<u32> = (0..ne as u32).collect();
    let mut first_elem_of_cluster = vec![u32::MAX; n_clusters];
    for (k, &c) in copy_cluster.iter().enumerate() {
        let e = copy_elem[k].0;
        let f = &mut first_elem_of_cluster[c.idx()];
        if *f == u32::MAX {
            *f = e;
        } else {
            let (a, b) = (root(&mut parent, *f), root(&mut parent, e));
            if a != b {
                parent[a.max(b) as usize] = a.min(b);
            }
        }
    }
    let mut id = vec![u32::MAX; ne];
    let mut frag = vec![0u32; ne];
    let mut n = 0u32;
    for e in 0..ne as u32 {
        let r = root(&mut parent, e);
        if id[r as usize] == u32::MAX {
            id[r as usize] = n;
            n += 1;
        }
        frag[e as usize] = id[r as usize];
    }
    (frag, n as usize)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::CellKind;
    use crate::mesh::Rectangle;

    /// The point at (1, 1) of a 2 x 2 rectangle of unit cells, its cluster and its edge to `q`.
    fn centre(kind: CellKind) -> (Topology, RawMesh, PointId) {
        let mesh = Rectangle::new(2.0, 2.0, 2, 2, kind).build().unwrap();
        let p = mesh.points.iter().position(|x| x[0] == 1.0 && x[1] == 1.0).unwrap();
        (Topology::new(&mesh), mesh, PointId::new(p))
    }

    fn edge_to(t: &Topology, m: &RawMesh, p: PointId, q: [f64; 2]) -> EdgeId {
        let qi = m.points.iter().position(|x| *x == q).unwrap();
        t.edge_between(p, PointId::new(qi)).unwrap()
    }

    /// A structured interior point of four Q4 ends as four independent copies: the horizontal
    /// line splits it in two (top and bottom pairs), then each half is cut along its vertical
    /// edge. Reference: construction (four elements, four copies, every link cut).
    #[test]
    fn a_point_can_end_as_four_independent_copies() {
        let (mut t, m, p) = centre(CellKind::Q4);
        let c = t.point_clusters[p.idx()][0];
        assert!(t.fan(c).is_closed());
        assert_eq!(t.fan(c).copies.len(), 4);
        let (l, r) = (edge_to(&t, &m, p, [0.0, 1.0]), edge_to(&t, &m, p, [2.0, 1.0]));
        // one link alone does not divide a closed fan: nothing changes
        assert!(t.cut(c, &[l], true).is_empty());
        let rec = t.cut(c, &[l, r], true);
        assert_eq!(rec.new_clusters.len(), 1);
        assert_eq!(rec.cut_edges.len(), 2);
        let (d, u) = (edge_to(&t, &m, p, [1.0, 0.0]), edge_to(&t, &m, p, [1.0, 2.0]));
        for cl in t.point_clusters[p.idx()].clone() {
            let fan = t.fan(cl);
            assert!(!fan.is_closed());
            assert_eq!((fan.copies.len(), fan.links.len()), (2, 1));
            let e = fan.links[0].edge;
            assert!(e == d || e == u);
            assert_eq!(t.cut(cl, &[e], true).new_clusters.len(), 1);
        }
        let cl = &t.point_clusters[p.idx()];
        assert_eq!(cl.len(), 4);
        for &c in cl {
            let fan = t.fan(c);
            assert_eq!((fan.copies.len(), fan.links.len()), (1, 0), "cluster {c:?}");
        }
        // every copy at p in its own cluster, and every edge through p cut at p
        for e in [l, r, d, u] {
            assert!(t.is_separated_at(e, p));
        }
        assert_eq!(t.n_clusters(), t.n_points + 3);
    }

    /// A T3 fan of six elements (the centre of a 2 x 2 diagonal-split square) cut along the
    /// horizontal line splits in two non-empty parts of three copies each; the diagonal line
    /// (45 degrees) splits it 3 + 3 as well, the vertical line 3 + 3. Reference: construction
    /// (each line through the centre has three triangles on each side).
    #[test]
    fn t3_fan_of_six_splits_in_two_non_empty_parts() {
        for line in [[[0.0, 1.0], [2.0, 1.0]], [[0.0, 0.0], [2.0, 2.0]], [[1.0, 0.0], [1.0, 2.0]]] {
            let (mut t, m, p) = centre(CellKind::T3);
            let c = t.point_clusters[p.idx()][0];
            let fan = t.fan(c);
            assert!(fan.is_closed());
            assert_eq!((fan.copies.len(), fan.links.len()), (6, 6));
            let rec = t.cut(c, &[edge_to(&t, &m, p, line[0]), edge_to(&t, &m, p, line[1])], true);
            assert_eq!(rec.new_clusters.len(), 1, "line {line:?}");
            let parts: Vec<usize> = t.point_clusters[p.idx()].iter().map(|&c| t.fan(c).copies.len()).collect();
            assert_eq!(parts, vec![3, 3], "line {line:?}");
            assert_eq!(t.fragments().1, 1, "a split at one point leaves the body whole");
        }
    }
}
