//! A 3D body's arrays as written and returned (issue 38): the VTU snapshot of a run
//! (`snapshot3`: one point per cluster), the crack faces' VTU (`crack_faces3`), the cells on
//! clusters (`cluster_cells`, also the 3D implicit check's body) and the arrays of a 3D run for
//! Python (`arrays3`). Used by the run's writer (`run3.rs`) and the check (`compare3.rs`).
use crate::mesh::RawCell3;
use crate::output::vtu3::{StressLayout, Vtu3};
use crate::solver::march3::March3;

/// The cells of the body with their corners' clusters (one point per cluster: a separated
/// face is open).
pub fn cluster_cells(m: &March3) -> Vec<RawCell3> {
    let t = &m.topo;
    (0..t.n_elems())
        .map(|e| {
            let mut nodes = [0u32; 8];
            for (a, k) in t.elem_copies(crate::ids::ElemId::new(e)).enumerate() {
                nodes[a] = t.copy_cluster[k].0;
            }
            RawCell3 { kind: m.mesh.cells[e].kind, nodes }
        })
        .collect()
}

/// The mean of every element's corner stresses (Voigt `xx, yy, zz, xy, yz, zx`).
fn elem_mean_stress(m: &March3) -> Vec<[f64; 6]> {
    let t = &m.topo;
    let mut corner = vec![[0.0; 6]; t.copy_point.len()];
    for b in &m.blocks {
        b.corner_stresses(&m.state.u, &t.elem_first_copy, &mut corner);
    }
    (0..t.n_elems())
        .map(|e| {
            let r = t.elem_copies(crate::ids::ElemId::new(e));
            let n = r.len() as f64;
            let mut s = [0.0; 6];
            for k in r {
                for d in 0..6 {
                    s[d] += corner[k][d] / n;
                }
            }
            s
        })
        .collect()
}

/// Every element's region as a number (regions numbered in order of first appearance).
fn region_ids(m: &March3) -> Vec<i32> {
    let mut regions: Vec<&str> = Vec::new();
    (0..m.topo.n_elems())
        .map(|e| {
            let r = m.mesh.cell_region.get(e).map_or("all", |s| s.as_str());
            match regions.iter().position(|x| *x == r) {
                Some(i) => i as i32,
                None => {
                    regions.push(r);
                    regions.len() as i32 - 1
                }
            }
        })
        .collect()
}

/// The body as VTU: one point per cluster at its point's reference position.
pub fn snapshot3(m: &March3) -> Vtu3 {
    let t = &m.topo;
    let points: Vec<[f64; 3]> = t.cluster_point.iter().map(|p| m.mesh.points[p.idx()]).collect();
    let cells = cluster_cells(m);
    let nodal = m.nodal_stress();
    let s1: Vec<f64> = nodal.iter().map(|&s| -crate::plugin::traits::principal3(s).p.s3).collect();
    let stress: Vec<[[f64; 3]; 3]> = elem_mean_stress(m).iter().map(|s| [[s[0], s[3], s[5]], [s[3], s[1], s[4]], [s[5], s[4], s[2]]]).collect();
    let region = region_ids(m);
    let (frag, _) = t.fragments();
    let point_id: Vec<f64> = t.cluster_point.iter().map(|p| p.0 as f64).collect();
    let mut cracked = vec![0.0; t.n_elems()];
    for (f, face) in t.faces.iter().enumerate() {
        if t.crack_state(crate::ids::FaceId::new(f)) > 0 {
            for (e, _) in face.sides.iter().flatten() {
                cracked[e.idx()] += 1.0;
            }
        }
    }
    Vtu3::new(&points, &cells)
        .displacement(&m.state.u)
        .point_scalar("max_principal_stress", &s1)
        .point_scalar("point", &point_id)
        .region(&region)
        .stress(&stress, StressLayout::Symmetric6)
        .cell_scalar("fragment", &frag.iter().map(|&f| f as f64).collect::<Vec<_>>())
        .cell_scalar("cracked_faces", &cracked)
}

/// The crack faces of the body as a VTU of polygons (`None` before any face separates): every
/// interior face separated at one corner at least (`Topology3::crack_state`), once per side,
/// each polygon on the clusters of its side's element (so the two sides of an open face are
/// two polygons on different points), wound outward of that element. Points at the reference
/// position with the point array `displacement` (ParaView's "Warp By Vector" opens the crack);
/// cell arrays `opening` (the mean over the face's corners of the gap `u_side1 - u_side0`
/// along the face's normal out of side 0: positive open, negative overlapping), `slip` (the
/// gap's tangential length), `cut_corners` (at how many corners the face is separated: all of
/// them, fully open), `side` (0, 1) and `fragment` (of the side's element, as in the snapshot).
pub fn crack_faces3(m: &March3) -> Option<Vtu3> {
    let t = &m.topo;
    let (frag, _) = t.fragments();
    let mut local = vec![u32::MAX; t.n_clusters()];
    let (mut clusters, mut polys) = (Vec::<usize>::new(), Vec::<Vec<u32>>::new());
    let (mut opening, mut slip, mut cut, mut side, mut fragment) = (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (f, face) in t.faces.iter().enumerate() {
        let fid = crate::ids::FaceId::new(f);
        let ncut = t.crack_state(fid);
        let [Some((a, _)), Some((b, _))] = face.sides else { continue };
        if ncut == 0 {
            continue;
        }
        let corners = face.corners();
        let side_clusters = |e: crate::ids::ElemId| -> Vec<usize> { corners.iter().map(|&p| t.copy_cluster[t.copy_at(e, p).expect("a face's corner is its element's").idx()].idx()).collect() };
        let (c0, c1) = (side_clusters(a), side_clusters(b));
        let n = crate::solver::march3::face_normal(&m.mesh, t, fid);
        let mut g = [0.0; 3];
        for (&p, &q) in c0.iter().zip(&c1) {
            for d in 0..3 {
                g[d] += (m.state.u[q][d] - m.state.u[p][d]) / corners.len() as f64;
            }
        }
        let gn = g[0] * n[0] + g[1] * n[1] + g[2] * n[2];
        let gt = ((g[0] - gn * n[0]).powi(2) + (g[1] - gn * n[1]).powi(2) + (g[2] - gn * n[2]).powi(2)).sqrt();
        for (k, (cs, e)) in [(c0, a), (c1, b)].into_iter().enumerate() {
            let mut poly: Vec<u32> = cs
                .iter()
                .map(|&c| {
                    if local[c] == u32::MAX {
                        local[c] = clusters.len() as u32;
                        clusters.push(c);
                    }
                    local[c]
                })
                .collect();
            if k == 1 {
                poly.reverse();
            }
            polys.push(poly);
            opening.push(gn);
            slip.push(gt);
            cut.push(ncut as f64);
            side.push(k as f64);
            fragment.push(frag[e.idx()] as f64);
        }
    }
    if polys.is_empty() {
        return None;
    }
    let points: Vec<[f64; 3]> = clusters.iter().map(|&c| m.mesh.points[t.cluster_point[c].idx()]).collect();
    let u: Vec<[f64; 3]> = clusters.iter().map(|&c| m.state.u[c]).collect();
    Some(
        Vtu3::polygons(&points, &polys)
            .displacement(&u)
            .cell_scalar("opening", &opening)
            .cell_scalar("slip", &slip)
            .cell_scalar("cut_corners", &cut)
            .cell_scalar("side", &side)
            .cell_scalar("fragment", &fragment),
    )
}

/// The state of a 3D body as flat arrays (the Python package's `flem.run` of a 3D scene,
/// docs/python.md): per cluster the reference position `points`, the mesh point it was split
/// from, `displacement`, `velocity`, `mass` and the nodal stress (the mean of its copies'
/// corner stresses, `[xx, yy, zz, xy, yz, zx]`, tension positive: the failure check's);
/// per element the cell on clusters, the region index (the snapshot's `region`), the mean
/// corner stress (the snapshot's `stress`, same order as the nodal stress) and the fragment;
/// per separated face (`crack_state` > 0, in face order) its two elements and at how many
/// corners it is separated.
#[derive(Clone, Debug, Default)]
pub struct Arrays3 {
    pub points: Vec<[f64; 3]>,
    pub point_id: Vec<u32>,
    pub cells: Vec<RawCell3>,
    pub region: Vec<i32>,
    pub displacement: Vec<[f64; 3]>,
    pub velocity: Vec<[f64; 3]>,
    pub mass: Vec<f64>,
    pub nodal_stress: Vec<[f64; 6]>,
    pub elem_stress: Vec<[f64; 6]>,
    pub fragment: Vec<u32>,
    pub crack_faces: Vec<[u32; 2]>,
    pub crack_state: Vec<u8>,
}

/// [`Arrays3`] of the body now.
pub fn arrays3(m: &March3) -> Arrays3 {
    let t = &m.topo;
    let cells = cluster_cells(m);
    let elem_stress = elem_mean_stress(m);
    let region = region_ids(m);
    let (mut crack_faces, mut crack_state) = (Vec::new(), Vec::new());
    for (f, face) in t.faces.iter().enumerate() {
        let s = t.crack_state(crate::ids::FaceId::new(f));
        if let ([Some((a, _)), Some((b, _))], true) = (face.sides, s > 0) {
            crack_faces.push([a.0, b.0]);
            crack_state.push(s);
        }
    }
    Arrays3 {
        points: t.cluster_point.iter().map(|p| m.mesh.points[p.idx()]).collect(),
        point_id: t.cluster_point.iter().map(|p| p.0).collect(),
        cells,
        region,
        displacement: m.state.u.clone(),
        velocity: m.state.v.clone(),
        mass: m.state.mass.clone(),
        nodal_stress: m.nodal_stress(),
        elem_stress,
        fragment: t.fragments().0,
        crack_faces,
        crack_state,
    }
}
