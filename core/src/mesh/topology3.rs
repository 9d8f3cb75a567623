//! The topology of a 3D mesh (issue 38): element-owned node copies grouped into clusters, as in
//! 2D ([`super::topology`], METHOD section 2), with element *faces* where 2D has edges.
//!
//! Around a point, the copies of its elements form a *fan* linked across the element faces
//! through the point that are still joined there (in 3D a fan is connected through faces: two
//! elements that share only an edge or the point are linked through the faces of the elements
//! between them). A face is cut at one of its corners; a cluster splits when the faces cut at
//! its point divide its fan into pieces ([`Topology3::cut`]). Before any separation every
//! point is one cluster (cluster id == point id), so the step sees plain FEM connectivity.
//!
//! Everything is a flat array indexed by a `u32` id (points, copies, clusters, faces), built
//! from the mesh alone: no global state, which is what a partition of the mesh needs later
//! (docs/3d.md, "Design").
//!
//! The paper's rule read in 3D (ours, docs/3d.md): [`Topology3::plane_cut`] gives the faces
//! through a point that divide its fan into the elements on either side of a plane through the
//! point (the plane normal to the direction of failure): the element faces closest to that
//! plane.
use super::topology::{fragments_of, parts_of, root, Copies, Csr, NewCluster};
use super::{CellKind3, RawCell3, RawMesh3, NO_CORNER};
use crate::ids::{ClusterId, CopyId, ElemId, FaceId, PointId};

/// An element face: its points (a triangle's 4th is `PointId(NO_CORNER)`), in the order of
/// `sides[0]`'s local face (anticlockwise seen from outside that element), and the (element,
/// local face) on each side; `sides[1]` is `None` on the mesh boundary.
#[derive(Copy, Clone, Debug)]
pub struct Face3 {
    pub points: [PointId; 4],
    pub sides: [Option<(ElemId, u8)>; 2],
}

impl Face3 {
    /// The face's 3 or 4 points.
    pub fn corners(&self) -> &[PointId] {
        if self.points[3].0 == NO_CORNER {
            &self.points[..3]
        } else {
            &self.points[..]
        }
    }
    /// Which corner (0..4) point `p` is, if any.
    pub fn corner_of(&self, p: PointId) -> Option<usize> {
        self.corners().iter().position(|&q| q == p)
    }
}

/// A link of a 3D fan: two copies at the point, joined across `face`.
#[derive(Copy, Clone, Debug)]
pub struct FaceLink {
    pub face: FaceId,
    pub a: CopyId,
    pub b: CopyId,
}

/// The copies of one cluster around its point, with the links still joined there.
#[derive(Clone, Debug, Default)]
pub struct Fan3 {
    pub point: PointId,
    pub cluster: ClusterId,
    pub copies: Vec<CopyId>,
    pub links: Vec<FaceLink>,
}

/// What a call to [`Topology3::cut`] changed; every per-cluster array follows it.
#[derive(Clone, Debug, Default)]
pub struct SplitRecord3 {
    /// Faces whose cut flag was set, with the corner (0..4) at which they were cut.
    pub cut_faces: Vec<(FaceId, u8)>,
    pub new_clusters: Vec<NewCluster>,
}

impl SplitRecord3 {
    pub fn is_empty(&self) -> bool {
        self.new_clusters.is_empty()
    }
    pub fn extend(&mut self, other: SplitRecord3) {
        self.cut_faces.extend(other.cut_faces);
        self.new_clusters.extend(other.new_clusters);
    }
}

/// Copies, clusters and faces of a 3D mesh (see the module doc).
#[derive(Clone, Debug)]
pub struct Topology3 {
    pub n_points: usize,
    pub elem_nodes: Vec<u8>,
    pub elem_first_copy: Vec<u32>,
    pub copy_point: Vec<PointId>,
    pub copy_elem: Vec<ElemId>,
    pub copy_cluster: Vec<ClusterId>,
    pub cluster_point: Vec<PointId>,
    /// Copies around each point, in increasing copy id.
    pub point_copies: Csr<CopyId>,
    /// Faces through each point, in increasing face id.
    pub point_faces: Csr<FaceId>,
    /// Faces in the order of their sorted corner keys (deterministic from the mesh).
    pub faces: Vec<Face3>,
    /// Per face, whether it has been cut at each corner.
    pub face_cut: Vec<[bool; 4]>,
    /// The clusters of each point, in creation order (the first is the original).
    pub point_clusters: Vec<Vec<ClusterId>>,
}

impl Topology3 {
    /// Builds the topology of a validated 3D mesh (a face shared by at most two cells): one
    /// cluster per point.
    pub fn new(mesh: &RawMesh3) -> Self {
        let np = mesh.points.len();
        let Copies { elem_nodes, elem_first_copy, copy_point, copy_elem, copy_cluster, point_copies } = Copies::new(np, mesh.cells.iter().map(|c| c.corners()));
        // Faces: sort (sorted corners, elem, local face) and pair equal keys.
        let mut half: Vec<([u32; 4], u32, u8)> = Vec::new();
        for (e, c) in mesh.cells.iter().enumerate() {
            for (k, f) in c.kind.faces().iter().enumerate() {
                let mut key = f.map(|i| if i == NO_CORNER { NO_CORNER } else { c.nodes[i as usize] });
                key.sort_unstable();
                half.push((key, e as u32, k as u8));
            }
        }
        half.sort_unstable();
        let mut faces = Vec::new();
        let mut i = 0;
        while i < half.len() {
            let (key, e, l) = half[i];
            let mut sides = [Some((ElemId(e), l)), None];
            if i + 1 < half.len() && half[i + 1].0 == key {
                sides[1] = Some((ElemId(half[i + 1].1), half[i + 1].2));
                i += 1;
            }
            let cell = &mesh.cells[e as usize];
            let local = cell.kind.faces()[l as usize];
            let points = local.map(|k| PointId(if k == NO_CORNER { NO_CORNER } else { cell.nodes[k as usize] }));
            faces.push(Face3 { points, sides });
            i += 1;
        }
        let pairs: Vec<(u32, FaceId)> = faces.iter().enumerate().flat_map(|(k, f)| f.corners().iter().map(move |p| (p.0, FaceId::new(k))).collect::<Vec<_>>()).collect();
        let point_faces = Csr::from_pairs(np, &pairs);
        let face_cut = vec![[false; 4]; faces.len()];
        Topology3 {
            n_points: np,
            elem_nodes,
            elem_first_copy,
            copy_point,
            copy_elem,
            copy_cluster,
            cluster_point: (0..np as u32).map(PointId).collect(),
            point_copies,
            point_faces,
            faces,
            face_cut,
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
    /// The face with these corner points (any order), if any.
    pub fn face_with(&self, points: &[u32]) -> Option<FaceId> {
        let mut key: Vec<u32> = points.to_vec();
        key.sort_unstable();
        let p = PointId(*key.first()?);
        self.point_faces.row(p.idx()).iter().copied().find(|f| {
            let mut k: Vec<u32> = self.faces[f.idx()].corners().iter().map(|q| q.0).collect();
            k.sort_unstable();
            k == key
        })
    }

    /// Whether the two sides of an interior face are in different clusters at point `p`.
    pub fn is_separated_at(&self, f: FaceId, p: PointId) -> bool {
        match self.faces[f.idx()].sides {
            [Some((a, _)), Some((b, _))] => match (self.copy_at(a, p), self.copy_at(b, p)) {
                (Some(ca), Some(cb)) => self.copy_cluster[ca.idx()] != self.copy_cluster[cb.idx()],
                _ => false,
            },
            _ => false,
        }
    }

    /// Crack state of an interior face: at how many of its corners it is separated (0: joined;
    /// all of them: fully open).
    pub fn crack_state(&self, f: FaceId) -> u8 {
        self.faces[f.idx()].corners().iter().filter(|&&p| self.is_separated_at(f, p)).count() as u8
    }

    /// Interior faces separated at one corner at least and fully open, in that order.
    pub fn crack_counts(&self) -> (usize, usize) {
        let (mut some, mut open) = (0, 0);
        for (k, f) in self.faces.iter().enumerate() {
            let s = self.crack_state(FaceId::new(k)) as usize;
            if s > 0 {
                some += 1;
                if s == f.corners().len() {
                    open += 1;
                }
            }
        }
        (some, open)
    }

    /// The fan of cluster `c` around its point.
    pub fn fan(&self, c: ClusterId) -> Fan3 {
        let p = self.cluster_point[c.idx()];
        let copies: Vec<CopyId> = self.point_copies.row(p.idx()).iter().copied().filter(|k| self.copy_cluster[k.idx()] == c).collect();
        let mut links = Vec::new();
        for &f in self.point_faces.row(p.idx()) {
            let fc = &self.faces[f.idx()];
            let corner = fc.corner_of(p).expect("point_faces lists faces through the point");
            if self.face_cut[f.idx()][corner] {
                continue;
            }
            if let [Some((ea, _)), Some((eb, _))] = fc.sides {
                let (a, b) = (self.copy_at(ea, p).unwrap(), self.copy_at(eb, p).unwrap());
                if self.copy_cluster[a.idx()] == c && self.copy_cluster[b.idx()] == c {
                    links.push(FaceLink { face: f, a, b });
                }
            }
        }
        Fan3 { point: p, cluster: c, copies, links }
    }

    /// Connected parts of the fan's copies once the given faces are removed from its links;
    /// each part sorted, parts ordered by their smallest copy.
    pub fn fan_parts(fan: &Fan3, removed: &[FaceId]) -> Vec<Vec<CopyId>> {
        parts_of(&fan.copies, fan.links.iter().filter(|l| !removed.contains(&l.face)).map(|l| (l.a, l.b)))
    }

    /// The faces of the fan to cut so that it falls into the copies on either side of a plane
    /// through its point (the paper's rule read in 3D, ours): `side[i]` is the signed distance
    /// of copy `fan.copies[i]`'s element (its centroid, say) from the plane. The copies with
    /// `side > 0` connected (through the fan's links among them) to the one of largest `side`
    /// form one part; every link between that part and the rest is returned, in face order.
    /// Empty when either side would be empty (the plane does not divide the fan).
    pub fn plane_cut(fan: &Fan3, side: &[f64]) -> Vec<FaceId> {
        let n = fan.copies.len();
        assert_eq!(side.len(), n, "one signed distance per copy of the fan");
        let Some(top) = (0..n).filter(|&i| side[i] > 0.0).max_by(|&a, &b| side[a].total_cmp(&side[b]).then(b.cmp(&a))) else {
            return Vec::new();
        };
        let pos = |c: CopyId| fan.copies.iter().position(|&k| k == c).unwrap();
        let mut parent: Vec<u32> = (0..n as u32).collect();
        for l in &fan.links {
            let (a, b) = (pos(l.a), pos(l.b));
            if side[a] > 0.0 && side[b] > 0.0 {
                let (ra, rb) = (root(&mut parent, a as u32), root(&mut parent, b as u32));
                if ra != rb {
                    parent[ra.max(rb) as usize] = ra.min(rb);
                }
            }
        }
        let rt = root(&mut parent, top as u32);
        let mut in_part = vec![false; n];
        for (i, slot) in in_part.iter_mut().enumerate() {
            *slot = side[i] > 0.0 && root(&mut parent, i as u32) == rt;
        }
        if in_part.iter().all(|&b| b) {
            return Vec::new();
        }
        let mut faces: Vec<FaceId> = fan.links.iter().filter(|l| in_part[pos(l.a)] != in_part[pos(l.b)]).map(|l| l.face).collect();
        faces.sort_unstable();
        faces
    }

    /// Cuts `faces` at the point of cluster `c` and splits the cluster into its connected parts.
    /// The part holding the smallest copy keeps the cluster id; the others get new ids, in order.
    /// With `require_split`, a cut that would not divide the fan changes nothing (a proposal
    /// from a separation rule); without it the cut flags are set anyway (pre-separated faces
    /// ending inside the body).
    pub fn cut(&mut self, c: ClusterId, faces: &[FaceId], require_split: bool) -> SplitRecord3 {
        let fan = self.fan(c);
        let p = fan.point;
        let valid: Vec<FaceId> = faces.iter().copied().filter(|f| fan.links.iter().any(|l| l.face == *f)).collect();
        let parts = Self::fan_parts(&fan, &valid);
        let mut rec = SplitRecord3::default();
        if require_split && parts.len() < 2 {
            return rec;
        }
        for &f in &valid {
            let corner = self.faces[f.idx()].corner_of(p).unwrap();
            self.face_cut[f.idx()][corner] = true;
            rec.cut_faces.push((f, corner as u8));
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

    /// Separates a set of faces from the start (a notch, a pre-cut plane): cuts them at every
    /// corner in every cluster there, splitting wherever the fan falls apart.
    pub fn separate_faces(&mut self, faces: &[FaceId]) -> SplitRecord3 {
        let mut rec = SplitRecord3::default();
        let mut pts: Vec<PointId> = faces.iter().flat_map(|f| self.faces[f.idx()].corners().to_vec()).collect();
        pts.sort_unstable();
        pts.dedup();
        for p in pts {
            let at_p: Vec<FaceId> = faces.iter().copied().filter(|f| self.faces[f.idx()].corner_of(p).is_some()).collect();
            let clusters = self.point_clusters[p.idx()].clone();
            for c in clusters {
                rec.extend(self.cut(c, &at_p, false));
            }
        }
        rec
    }

    /// Connected fragments: elements joined through shared clusters (as 2D
    /// [`super::topology::Topology::fragments`]).
    pub fn fragments(&self) -> (Vec<u32>, usize) {
        fragments_of(self.n_elems(), self.n_clusters(), &self.copy_cluster, &self.copy_elem)
    }
}

/// A structured n x n x n box of unit H8 cells, or each cube split into six T4 around its
/// main diagonal (0-6), conforming across cubes (every cube uses the same split). For tests
/// (the scenes' generator is the `box` mesh source).
#[doc(hidden)]
pub fn unit_cubes(n: usize, tets: bool) -> RawMesh3 {
    let m = n + 1;
    let id = |i: usize, j: usize, k: usize| (i + m * (j + m * k)) as u32;
    let mut points = Vec::new();
    for k in 0..m {
        for j in 0..m {
            for i in 0..m {
                points.push([i as f64, j as f64, k as f64]);
            }
        }
    }
    let mut cells = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let h = [id(i, j, k), id(i + 1, j, k), id(i + 1, j + 1, k), id(i, j + 1, k), id(i, j, k + 1), id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)];
                if tets {
                    // The six tetrahedra of the Kuhn split around the diagonal 0-6, each
                    // positive (checked below).
                    for t in [[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6], [0, 5, 1, 6]] {
                        let mut nodes = [0u32; 8];
                        for (a, &b) in t.iter().enumerate() {
                            nodes[a] = h[b];
                        }
                        cells.push(RawCell3 { kind: CellKind3::T4, nodes });
                    }
                } else {
                    cells.push(RawCell3 { kind: CellKind3::H8, nodes: h });
                }
            }
        }
    }
    RawMesh3 { source: "cube".into(), points, cells, ..Default::default() }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn centroid(m: &RawMesh3, e: ElemId) -> [f64; 3] {
        let c = m.cells[e.idx()];
        let k = c.corners();
        std::array::from_fn(|d| k.iter().map(|&p| m.points[p as usize][d]).sum::<f64>() / k.len() as f64)
    }

    /// Splits every point of the plane `x[axis] = at` by `plane_cut` with the plane's normal;
    /// returns the topology.
    fn split_plane(m: &RawMesh3, axis: usize, at: f64) -> Topology3 {
        let mut t = Topology3::new(m);
        for p in 0..m.points.len() {
            if m.points[p][axis] != at {
                continue;
            }
            let c = t.point_clusters[p][0];
            let fan = t.fan(c);
            let side: Vec<f64> = fan.copies.iter().map(|&k| centroid(m, t.copy_elem[k.idx()])[axis] - at).collect();
            let faces = Topology3::plane_cut(&fan, &side);
            t.cut(c, &faces, true);
        }
        t
    }

    /// Reference: construction. A 2 x 2 x 2 box: H8 has 8 cells and 3 * 2 * 2 * 3 = 36 faces,
    /// 12 interior; the Kuhn split has 48 positive tetrahedra; a closed interior fan (the
    /// centre point) links 8 hexes through 12 faces, 24 tetrahedra through 36 faces.
    #[test]
    fn faces_and_fans_of_structured_boxes() {
        let h = unit_cubes(2, false);
        let t = Topology3::new(&h);
        assert_eq!(t.faces.len(), 36);
        assert_eq!(t.faces.iter().filter(|f| f.sides[1].is_some()).count(), 12);
        let centre = 13; // (1, 1, 1)
        let fan = t.fan(ClusterId(centre));
        assert_eq!((fan.copies.len(), fan.links.len()), (8, 12));
        let tm = unit_cubes(2, true);
        for c in &tm.cells {
            let x = c.corners().iter().map(|&p| tm.points[p as usize]).collect::<Vec<_>>();
            assert!(crate::mesh::tet_volume6(x[0], x[1], x[2], x[3]) > 0.0);
        }
        let t = Topology3::new(&tm);
        assert_eq!(t.n_elems(), 48);
        let fan = t.fan(ClusterId(centre));
        assert_eq!((fan.copies.len(), fan.links.len()), (24, 36));
        // Face lookup by points, in any order.
        let f = t.faces[5];
        let mut q: Vec<u32> = f.corners().iter().map(|p| p.0).collect();
        q.reverse();
        assert_eq!(t.face_with(&q), Some(FaceId(5)));
    }

    /// Reference: construction. Cutting a box of H8 and of T4 at every point of its mid-plane
    /// x = 1 (the plane normal along x through the points) separates it into two fragments; the
    /// faces cut are exactly the mid-plane's (4 quads, 8 triangles), each fully open; the plane
    /// z = 1 does the same for z. A fan cut by a plane that does not divide it changes nothing.
    #[test]
    fn a_plane_of_splits_divides_a_box_in_two() {
        for tets in [false, true] {
            for axis in [0, 2] {
                let m = unit_cubes(2, tets);
                let t = split_plane(&m, axis, 1.0);
                let (_, nfrag) = t.fragments();
                assert_eq!(nfrag, 2, "tets {tets} axis {axis}");
                let (some, open) = t.crack_counts();
                let want = if tets { 8 } else { 4 };
                assert_eq!((some, open), (want, want), "tets {tets} axis {axis}");
                for (k, f) in t.faces.iter().enumerate() {
                    if t.crack_state(FaceId::new(k)) > 0 {
                        assert!(f.corners().iter().all(|p| m.points[p.idx()][axis] == 1.0));
                    }
                }
                // Nine points on the plane, each now two clusters.
                assert_eq!(t.n_clusters(), m.points.len() + 9);
                let (frag, _) = t.fragments();
                for e in 0..t.n_elems() {
                    let below = centroid(&m, ElemId::new(e))[axis] < 1.0;
                    assert_eq!(frag[e] == frag[0], below == (centroid(&m, ElemId(0))[axis] < 1.0));
                }
            }
        }
        let m = unit_cubes(2, false);
        let mut t = Topology3::new(&m);
        let fan = t.fan(ClusterId(13));
        let all_up = vec![1.0; fan.copies.len()];
        assert!(Topology3::plane_cut(&fan, &all_up).is_empty());
        // One face alone never divides a closed fan: nothing changes.
        let f = fan.links[0].face;
        assert!(t.cut(ClusterId(13), &[f], true).is_empty());
        assert!(!t.face_cut[f.idx()].iter().any(|&b| b));
    }

    /// Reference: construction. A crack that ends inside the body: the faces of the plane
    /// x = 1 with z <= 1 of a 2 x 2 x 2 H8 box, pre-separated. Points with z < 1 split, the
    /// front z = 1 does not (its fans stay connected around the crack's edge), so the body
    /// remains one fragment; the faces are cut at every corner but separated only where the
    /// point split.
    #[test]
    fn a_crack_front_inside_the_body_keeps_one_fragment() {
        let m = unit_cubes(2, false);
        let mut t = Topology3::new(&m);
        let faces: Vec<FaceId> = (0..t.faces.len())
            .map(FaceId::new)
            .filter(|f| {
                let fc = &t.faces[f.idx()];
                fc.sides[1].is_some() && fc.corners().iter().all(|p| m.points[p.idx()][0] == 1.0 && m.points[p.idx()][2] <= 1.0)
            })
            .collect();
        assert_eq!(faces.len(), 2);
        let rec = t.separate_faces(&faces);
        assert_eq!(t.fragments().1, 1);
        // The three points (1, y, 0) are on the boundary z = 0: they split; the front (1, y, 1)
        // does not.
        assert_eq!(rec.new_clusters.len(), 3);
        for nc in &rec.new_clusters {
            assert_eq!(m.points[nc.point.idx()][2], 0.0);
        }
        for &f in &faces {
            assert_eq!(t.crack_state(f), 2, "separated at its two z = 0 corners only");
        }
    }
}
