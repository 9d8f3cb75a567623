//! The state of a run as plain arrays: what a VTU snapshot holds (`super::snapshot_vtk` is
//! built from [`ResultArrays`]) and what the Python package hands out as numpy arrays
//! (`python/`, issue 22). One function builds both, so the two cannot drift apart: the Python
//! arrays equal the VTU's bit for bit (tests in `python/tests/test_run.py`).
//!
//! Points are clusters (reference coordinates; `displacement` moves them). Elements are on their
//! clusters, in element order; a crack face is one side of a separated edge, a line on the two
//! clusters of that side (state 1: separated at one end, 2: at both).
use crate::ids::{EdgeId, ElemId};
use crate::mesh::CellKind;
use crate::solver::Simulation;

/// A run's state as arrays (see the module doc).
#[derive(Clone, Debug, Default)]
pub struct ResultArrays {
    /// Reference coordinates of each cluster.
    pub points: Vec<[f64; 2]>,
    /// The mesh point each cluster was split from (VTU `point_id`).
    pub point_id: Vec<u32>,
    /// Kind of each element.
    pub kinds: Vec<CellKind>,
    /// The cluster of each element copy (corner), element after element (`copy_offsets`).
    pub clusters: Vec<u32>,
    /// Start of each element's corners in `clusters` (length `n_elems + 1`).
    pub copy_offsets: Vec<u32>,
    /// Region index of each element (in the order regions first appear among the blocks).
    pub region: Vec<i32>,
    /// Mean element stress `[sxx, syy, sxy]`.
    pub elem_stress: Vec<[f64; 3]>,
    /// The two clusters of each crack face.
    pub crack_faces: Vec<[u32; 2]>,
    /// 1: separated at one end, 2: at both ends.
    pub crack_state: Vec<u8>,
    pub displacement: Vec<[f64; 2]>,
    pub velocity: Vec<[f64; 2]>,
    pub mass: Vec<f64>,
    /// Nodal stress (the paper's corner mean) `[sxx, syy, sxy]`.
    pub nodal_stress: Vec<[f64; 3]>,
    /// Failure index of each cluster at the last check (with `[cracking]`).
    pub failure_index: Option<Vec<f64>>,
    /// Per element: plastic shear strain and plastic state (0 never, 1 now, 2 in the past;
    /// issue 21), when some block has a plastic law.
    pub plastic: Option<(Vec<f64>, Vec<i32>)>,
}

/// The arrays of the current state of `sim`.
pub fn result_arrays(sim: &Simulation) -> ResultArrays {
    let m = &sim.model;
    let topo = &m.topo;
    let nc = topo.n_clusters();
    let mut r = ResultArrays { points: sim.x0.clone(), point_id: topo.cluster_point.iter().map(|p| p.0).collect(), ..Default::default() };
    let mut regions: Vec<&str> = m.blocks.iter().map(|b| b.region()).collect();
    regions.dedup();
    r.copy_offsets.push(0);
    for e in 0..topo.n_elems() {
        for k in topo.elem_copies(ElemId::new(e)) {
            r.clusters.push(topo.copy_cluster[k].0);
        }
        r.copy_offsets.push(r.clusters.len() as u32);
        let (b, i) = m.elem_slot[e];
        let blk = &m.blocks[b as usize];
        r.kinds.push(blk.kind());
        r.region.push(regions.iter().position(|x| *x == blk.region()).unwrap_or(0) as i32);
        r.elem_stress.push(blk.mean_stress(i as usize, &sim.state.u));
    }
    if m.blocks.iter().any(|b| !b.is_empty() && b.plastic(0).is_some()) {
        let (mut g, mut f) = (Vec::with_capacity(topo.n_elems()), Vec::with_capacity(topo.n_elems()));
        for e in 0..topo.n_elems() {
            let (b, i) = m.elem_slot[e];
            let (pg, pf) = m.blocks[b as usize].plastic(i as usize).unwrap_or((0.0, 0));
            g.push(pg);
            f.push(pf as i32);
        }
        r.plastic = Some((g, f));
    }
    for ei in 0..topo.edges.len() {
        let st = topo.crack_state(EdgeId::new(ei));
        if st == 0 {
            continue;
        }
        let ed = &topo.edges[ei];
        for side in ed.sides.iter().flatten() {
            let c = ed.points.map(|p| topo.copy_cluster[topo.copy_at(side.0, p).expect("an edge's side holds both of its points").idx()].0);
            r.crack_faces.push(c);
            r.crack_state.push(st);
        }
    }
    r.displacement = sim.state.u.clone();
    r.velocity = sim.state.v.clone();
    r.mass = sim.state.mass.clone();
    let mut corner = Vec::new();
    m.nodal_stress(&sim.state.u, &mut corner, &mut r.nodal_stress);
    if let Some(cr) = &sim.cracking {
        let cfg = sim.scene.file.cracking.as_ref().expect("cracking config");
        let mut idx = cr.failure_index(cfg, &sim.model, &sim.state.u).into_owned();
        idx.resize(nc, 0.0);
        r.failure_index = Some(idx);
    }
    r
}
