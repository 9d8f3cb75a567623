//! Supports and loads resolved against the model (METHOD section 8).
//!
//! Edge loads belong to the copies of the element that owns the edge, so after a split they
//! follow the right part by themselves. A point load acts on the point's first cluster; a
//! support holds every cluster of its point.
use crate::element::model::Model;
use crate::error::{FlemError, Result};
use crate::ids::{ElemId, PointId};
use crate::scene::{LoadCfg, SceneFile};

#[derive(Clone, Debug)]
enum Kind {
    /// Pressure (`vector = None`) or traction on (element, local edge) faces.
    Edge {
        faces: Vec<(ElemId, u8)>,
        pressure: f64,
        traction: [f64; 2],
        follow: bool,
    },
    Point {
        points: Vec<PointId>,
        value: [f64; 2],
    },
    /// Prescribed velocity (`displacement = false`) or displacement of the given components.
    Prescribed {
        points: Vec<PointId>,
        value: [Option<f64>; 2],
        displacement: bool,
    },
}

#[derive(Clone, Debug)]
pub struct Load {
    pub name: String,
    kind: Kind,
}

/// Resolved supports and loads of a scene.
#[derive(Clone, Debug)]
pub struct Loads {
    pub loads: Vec<Load>,
    /// Fixity bits per point from the supports (1: x, 2: y).
    pub point_fix: Vec<u8>,
    pub gravity: [f64; 2],
    /// True when some pressure follows the deformed edge (recomputed every step).
    pub has_follower: bool,
}

impl Loads {
    pub fn new(model: &Model, scene: &SceneFile, file: &str) -> Result<Loads> {
        let mut point_fix = vec![0u8; model.topo.n_points];
        for (i, s) in scene.supports.iter().enumerate() {
            let bits = match s.fix.as_str() {
                "x" => 1,
                "y" => 2,
                _ => 3,
            };
            for p in model.node_set(&s.nodes, &format!("support[{i}].nodes"), file)? {
                point_fix[p.idx()] |= bits;
            }
        }
        let mut loads = Vec::new();
        let mut has_follower = false;
        for (i, l) in scene.loads.iter().enumerate() {
            let key = |k: &str| format!("load[{i}].{k}");
            let faces = |edges: &str| -> Result<Vec<(ElemId, u8)>> {
                let ids = model.edge_set(edges, &key("edges"), file)?;
                ids.iter()
                    .map(|e| {
                        let ed = &model.topo.edges[e.idx()];
                        match ed.sides {
                            [Some(s), None] => Ok(s),
                            _ => Err(FlemError::config(
                                file,
                                key("edges"),
                                format!("= \"{edges}\": the edge between {} lies inside the body; loads go on boundary edges", model.mesh.points_name(&[ed.points[0].0, ed.points[1].0])),
                            )),
                        }
                    })
                    .collect()
            };
            let kind = match l {
                LoadCfg::Pressure { edges, value, follow, .. } => {
                    has_follower |= *follow;
                    Kind::Edge { faces: faces(edges)?, pressure: *value, traction: [0.0; 2], follow: *follow }
                }
                LoadCfg::Traction { edges, value, .. } => Kind::Edge { faces: faces(edges)?, pressure: 0.0, traction: *value, follow: false },
                LoadCfg::Point { nodes, value, .. } => Kind::Point { points: model.node_set(nodes, &key("nodes"), file)?, value: *value },
                LoadCfg::Velocity { nodes, x, y, .. } => Kind::Prescribed { points: model.node_set(nodes, &key("nodes"), file)?, value: [*x, *y], displacement: false },
                LoadCfg::Displacement { nodes, x, y, .. } => Kind::Prescribed { points: model.node_set(nodes, &key("nodes"), file)?, value: [*x, *y], displacement: true },
            };
            loads.push(Load { name: l.name().to_string(), kind });
        }
        Ok(Loads { loads, point_fix, gravity: scene.model.gravity, has_follower })
    }

    fn edge_force(model: &Model, face: (ElemId, u8), x: &dyn Fn(usize) -> [f64; 2], pressure: f64, traction: [f64; 2], out: &mut [[f64; 2]]) {
        let (e, k) = face;
        let r = model.topo.elem_copies(e);
        let n = r.len();
        let (ca, cb) = (r.start + k as usize, r.start + (k as usize + 1) % n);
        let (a, b) = (model.topo.copy_cluster[ca].idx(), model.topo.copy_cluster[cb].idx());
        let (xa, xb) = (x(a), x(b));
        let (dx, dy) = (xb[0] - xa[0], xb[1] - xa[1]);
        let t = model.material_of(e).thickness;
        // Outward normal times length of a counter-clockwise face: (dy, -dx).
        let len = (dx * dx + dy * dy).sqrt();
        let f = [0.5 * t * (-pressure * dy + traction[0] * len), 0.5 * t * (pressure * dx + traction[1] * len)];
        for c in [a, b] {
            out[c][0] += f[0];
            out[c][1] += f[1];
        }
    }

    /// The constant part of the external force at the given levels: gravity, fixed-direction
    /// edge loads and point loads, per cluster.
    pub fn constant_force(&self, model: &Model, levels: &[f64], mass: &[f64], out: &mut Vec<[f64; 2]>) {
        let nc = model.topo.n_clusters();
        out.clear();
        out.resize(nc, [0.0; 2]);
        if self.gravity != [0.0; 2] {
            for (c, m) in mass.iter().enumerate() {
                out[c] = [m * self.gravity[0], m * self.gravity[1]];
            }
        }
        let x0 = |c: usize| model.mesh.points[model.topo.cluster_point[c].idx()];
        for (l, &lev) in self.loads.iter().zip(levels) {
            if lev == 0.0 {
                continue;
            }
            match &l.kind {
                Kind::Edge { faces, pressure, traction, follow: false } => {
                    for &f in faces {
                        Self::edge_force(model, f, &x0, lev * pressure, [lev * traction[0], lev * traction[1]], out);
                    }
                }
                Kind::Point { points, value } => {
                    for p in points {
                        let c = model.topo.point_clusters[p.idx()][0].idx();
                        out[c][0] += lev * value[0];
                        out[c][1] += lev * value[1];
                    }
                }
                _ => {}
            }
        }
    }

    /// Adds the following pressures on the current configuration (`x0 + u`).
    pub fn add_follower_force(&self, model: &Model, levels: &[f64], x0: &[[f64; 2]], u: &[[f64; 2]], out: &mut [[f64; 2]]) {
        let x = |c: usize| [x0[c][0] + u[c][0], x0[c][1] + u[c][1]];
        for (l, &lev) in self.loads.iter().zip(levels) {
            if let Kind::Edge { faces, pressure, follow: true, .. } = &l.kind {
                for &f in faces {
                    Self::edge_force(model, f, &x, lev * pressure, [0.0; 2], out);
                }
            }
        }
    }

    /// Constraints at the given levels: fixity bits, prescribed velocity per cluster, and the
    /// prescribed displacements `(cluster, dof, value)` to impose at the stage start.
    pub fn constraints(&self, model: &Model, levels: &[f64]) -> (Vec<u8>, Vec<[f64; 2]>, Vec<(usize, usize, f64)>) {
        let nc = model.topo.n_clusters();
        let mut fix: Vec<u8> = model.topo.cluster_point.iter().map(|p| self.point_fix[p.idx()]).collect();
        let mut vp = vec![[0.0; 2]; nc];
        let mut up = Vec::new();
        for (l, &lev) in self.loads.iter().zip(levels) {
            let Kind::Prescribed { points, value, displacement } = &l.kind else { continue };
            for p in points {
                for &c in &model.topo.point_clusters[p.idx()] {
                    for (d, val) in value.iter().enumerate() {
                        let Some(val) = val else { continue };
                        fix[c.idx()] |= 1 << d;
                        if *displacement {
                            up.push((c.idx(), d, lev * val));
                        } else {
                            vp[c.idx()][d] = lev * val;
                        }
                    }
                }
            }
        }
        (fix, vp, up)
    }
}
