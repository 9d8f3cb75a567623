//! Supports and loads resolved against the model (METHOD section 8).
//!
//! Edge loads belong to the copies of the element that owns the edge, so after a split they
//! follow the right part by themselves. A point load acts on the point's first cluster; a
//! support holds every cluster of its point.
use crate::element::model::Model;
use crate::error::{FlemError, Result};
use crate::expr::Field;
use crate::ids::{ElemId, PointId};
use crate::scene::{LoadCfg, SceneFile, MAX_MAGNITUDE};

/// The two Gauss points of a face, as the fraction `s` of the way from its first end.
const GAUSS_S: [f64; 2] = [0.5 - 0.288_675_134_594_812_9, 0.5 + 0.288_675_134_594_812_9];

#[derive(Clone, Debug)]
enum Kind {
    /// Pressure or traction on (element, local edge) faces. `ends`: for values given by
    /// expressions without `t`, per face the consistent end values `[p_a, p_b, tx_a, tx_b, ty_a,
    /// ty_b]` (2-point Gauss along the face, computed once); `None` when every value is a
    /// number (the constant path) or when an expression uses `t` (evaluated at each step).
    Edge { faces: Vec<(ElemId, u8)>, pressure: Field, traction: [Field; 2], follow: bool, ends: Option<Vec<[f64; 6]>> },
    /// `at`: per point, the value of expressions without `t` (None: numbers, or `t` used).
    Point { points: Vec<PointId>, value: [Field; 2], at: Option<Vec<[f64; 2]>> },
    /// Prescribed velocity (`displacement = false`; each component a number or an expression
    /// of x, y, t) or displacement (numbers) of the given components.
    Prescribed { points: Vec<PointId>, value: [Option<Field>; 2], displacement: bool },
}

#[derive(Clone, Debug)]
pub struct Load {
    pub name: String,
    /// `load[i]`, for messages.
    key: String,
    /// The largest |level| any stage gives this load, at least 1 (bounds evaluated values).
    level: f64,
    kind: Kind,
}

impl Load {
    /// Whether the load is an expression of time (evaluated at every step).
    pub fn uses_t(&self) -> bool {
        match &self.kind {
            Kind::Edge { pressure, traction, .. } => pressure.uses_t() || traction.iter().any(Field::uses_t),
            Kind::Point { value, .. } => value.iter().any(Field::uses_t),
            Kind::Prescribed { value, .. } => value.iter().flatten().any(Field::uses_t),
        }
    }
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
    /// True when some force load is an expression of time (recomputed every step, that load only).
    pub has_time: bool,
    /// True when some prescribed velocity is an expression of time (issue 36: a ramp; set at
    /// every step by [`Self::ramp_velocities`]).
    pub velocity_of_t: bool,
    /// The scene file, for messages of expressions evaluated during the run.
    file: String,
}

/// Checks an evaluated load value: finite, and within the magnitude bound once multiplied by
/// the largest level a stage gives the load (`level`, at least 1), as numbers are checked
/// against the levels when the scene is read.
fn checked(v: f64, f: &Field, key: &str, file: &str, x: [f64; 2], t: f64, level: f64) -> Result<f64> {
    if v.is_finite() && v.abs() * level <= MAX_MAGNITUDE {
        Ok(v)
    } else {
        Err(FlemError::config(
            file,
            format!("{key}.value"),
            format!("= \"{}\" gives {v} at (x, y) = ({}, {}), t = {t}; a load value must be finite and at most 1e100 in magnitude once scaled by its largest level ({level})", f.text(), x[0], x[1]),
        ))
    }
}

/// The consistent end values of a face's fields at time `t` (reference coordinates `xa`, `xb`):
/// `F_a = sum_g (1 - s_g) F(x_g)`, `F_b = sum_g s_g F(x_g)` (2-point Gauss, weight 1/2 each on
/// the unit interval, times 2 so that a constant F gives F_a = F_b = F).
fn face_ends(fields: [&Field; 3], xa: [f64; 2], xb: [f64; 2], t: f64, key: &str, file: &str, level: f64) -> Result<[f64; 6]> {
    let mut out = [0.0; 6];
    for (k, f) in fields.iter().enumerate() {
        for s in GAUSS_S {
            let x = [xa[0] + s * (xb[0] - xa[0]), xa[1] + s * (xb[1] - xa[1])];
            let v = checked(f.at(x[0], x[1], t), f, key, file, x, t, level)?;
            out[2 * k] += (1.0 - s) * v;
            out[2 * k + 1] += s * v;
        }
    }
    Ok(out)
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
            // Values were checked to compile by Scene::validate.
            let field = |v: &crate::scene::LoadValue| v.compile().map_err(|e| FlemError::config(file, key("value"), e));
            let kind = match l {
                LoadCfg::Pressure { edges, value, follow, .. } => {
                    has_follower |= *follow;
                    Kind::Edge { faces: faces(edges)?, pressure: field(value)?, traction: [Field::Const(0.0), Field::Const(0.0)], follow: *follow, ends: None }
                }
                LoadCfg::Traction { edges, value, .. } => Kind::Edge { faces: faces(edges)?, pressure: Field::Const(0.0), traction: [field(&value[0])?, field(&value[1])?], follow: false, ends: None },
                LoadCfg::Point { nodes, value, .. } => Kind::Point { points: model.node_set(nodes, &key("nodes"), file)?, value: [field(&value[0])?, field(&value[1])?], at: None },
                LoadCfg::Velocity { nodes, x, y, .. } => {
                    let comp = |v: &Option<crate::scene::LoadValue>| v.as_ref().map(&field).transpose();
                    Kind::Prescribed { points: model.node_set(nodes, &key("nodes"), file)?, value: [comp(x)?, comp(y)?], displacement: false }
                }
                LoadCfg::Displacement { nodes, x, y, .. } => {
                    Kind::Prescribed { points: model.node_set(nodes, &key("nodes"), file)?, value: [x.map(Field::Const), y.map(Field::Const)], displacement: true }
                }
            };
            let level = scene.stages.iter().filter_map(|st| st.levels.get(l.name())).fold(1.0f64, |m, v| m.max(v.abs()));
            let mut load = Load { name: l.name().to_string(), key: format!("load[{i}]"), level, kind };
            // Expressions without t: evaluated here, once per face or point (and checked).
            let uses_t = load.uses_t();
            let x0 = |p: PointId| model.mesh.points[p.idx()];
            match &mut load.kind {
                Kind::Edge { faces, pressure, traction, ends, .. } if !uses_t && (pressure.constant().is_none() || traction.iter().any(|t| t.constant().is_none())) => {
                    let mut v = Vec::with_capacity(faces.len());
                    for &f in faces.iter() {
                        let (pa, pb) = Self::face_points(model, f);
                        v.push(face_ends([pressure, &traction[0], &traction[1]], x0(pa), x0(pb), 0.0, &load.key, file, load.level)?);
                    }
                    *ends = Some(v);
                }
                Kind::Point { points, value, at } if !uses_t && value.iter().any(|f| f.constant().is_none()) => {
                    let mut v = Vec::with_capacity(points.len());
                    for &p in points.iter() {
                        let x = x0(p);
                        let at = |f: &Field| checked(f.at(x[0], x[1], 0.0), f, &load.key, file, x, 0.0, load.level);
                        v.push([at(&value[0])?, at(&value[1])?]);
                    }
                    *at = Some(v);
                }
                _ => {}
            }
            loads.push(load);
        }
        let is_prescribed = |l: &&Load| matches!(l.kind, Kind::Prescribed { .. });
        let has_time = loads.iter().filter(|l| !is_prescribed(l)).any(Load::uses_t);
        let velocity_of_t = loads.iter().filter(is_prescribed).any(Load::uses_t);
        Ok(Loads { loads, point_fix, gravity: scene.model.gravity, has_follower, has_time, velocity_of_t, file: file.to_string() })
    }

    /// Ours (issue 34, session 18): the fixity mask of the path method
    /// (`cracking::path::check_move_held`), per point, built once at set-up:
    /// - [`HELD`]: the point carries a point load, a prescribed velocity or displacement, or is an
    ///   end of a face with a pressure or traction (whatever the stage's level), or a support that
    ///   ends at it (a boundary neighbour lacks one of its fixed directions). It never moves: the
    ///   move would change the problem (where the load acts or the support ends, what was
    ///   integrated on the face).
    /// - [`SLIDES`]: held by supports only, with both of its boundary neighbours fixed in (at
    ///   least) the same directions: the support covers both boundary edges at the point. It may
    ///   slide along a straight boundary (`slide`), never off it: the fixed directions stay zero
    ///   along the same two edges, which is the same problem (the outline and the supported
    ///   stretch unchanged).
    /// - 0: free.
    pub fn held_points(&self, model: &Model) -> Vec<u8> {
        use crate::cracking::path::{HELD, SLIDES};
        let topo = &model.topo;
        let mut held: Vec<u8> = (0..self.point_fix.len())
            .map(|p| {
                let bits = self.point_fix[p];
                if bits == 0 {
                    return 0;
                }
                let mut n = 0;
                let mut covered = true;
                for &e in topo.point_edges.row(p) {
                    if topo.edges[e.idx()].sides[1].is_none() {
                        n += 1;
                        let q = topo.other_end(e, PointId::new(p));
                        covered &= self.point_fix[q.idx()] & bits == bits;
                    }
                }
                if n == 2 && covered {
                    SLIDES
                } else {
                    HELD
                }
            })
            .collect();
        for l in &self.loads {
            match &l.kind {
                Kind::Point { points, .. } | Kind::Prescribed { points, .. } => points.iter().for_each(|p| held[p.idx()] = HELD),
                Kind::Edge { faces, .. } => {
                    for &f in faces {
                        let (a, b) = Self::face_points(model, f);
                        held[a.idx()] = HELD;
                        held[b.idx()] = HELD;
                    }
                }
            }
        }
        held
    }

    /// The two points of a face (element, local edge), in the element's order.
    fn face_points(model: &Model, face: (ElemId, u8)) -> (PointId, PointId) {
        let (e, k) = face;
        let r = model.topo.elem_copies(e);
        let n = r.len();
        let (ca, cb) = (r.start + k as usize, r.start + (k as usize + 1) % n);
        (model.topo.cluster_point[model.topo.copy_cluster[ca].idx()], model.topo.cluster_point[model.topo.copy_cluster[cb].idx()])
    }

    /// A face's two clusters (a, b), its edge vector `(dx, dy)` from a to b, length and
    /// element thickness, on the configuration `x`.
    fn face_geometry(model: &Model, face: (ElemId, u8), x: &dyn Fn(usize) -> [f64; 2]) -> ([usize; 2], f64, f64, f64, f64) {
        let (e, k) = face;
        let r = model.topo.elem_copies(e);
        let n = r.len();
        let (ca, cb) = (r.start + k as usize, r.start + (k as usize + 1) % n);
        let (a, b) = (model.topo.copy_cluster[ca].idx(), model.topo.copy_cluster[cb].idx());
        let (xa, xb) = (x(a), x(b));
        let (dx, dy) = (xb[0] - xa[0], xb[1] - xa[1]);
        ([a, b], dx, dy, (dx * dx + dy * dy).sqrt(), model.material_of(e).thickness)
    }

    fn edge_force(model: &Model, face: (ElemId, u8), x: &dyn Fn(usize) -> [f64; 2], pressure: f64, traction: [f64; 2], out: &mut [[f64; 2]]) {
        // Outward normal times length of a counter-clockwise face: (dy, -dx).
        let (ab, dx, dy, len, t) = Self::face_geometry(model, face, x);
        let f = [0.5 * t * (-pressure * dy + traction[0] * len), 0.5 * t * (pressure * dx + traction[1] * len)];
        for c in ab {
            out[c][0] += f[0];
            out[c][1] += f[1];
        }
    }

    /// [`Self::edge_force`] with values that vary along the face: `ends` = the consistent end
    /// values `[p_a, p_b, tx_a, tx_b, ty_a, ty_b]`, times `lev`.
    fn edge_force_ends(model: &Model, face: (ElemId, u8), x: &dyn Fn(usize) -> [f64; 2], lev: f64, ends: &[f64; 6], out: &mut [[f64; 2]]) {
        let (ab, dx, dy, len, t) = Self::face_geometry(model, face, x);
        for (end, c) in ab.into_iter().enumerate() {
            let (p, tx, ty) = (lev * ends[end], lev * ends[2 + end], lev * ends[4 + end]);
            out[c][0] += 0.5 * t * (-p * dy + tx * len);
            out[c][1] += 0.5 * t * (p * dx + ty * len);
        }
    }

    /// The constant part of the external force at the given levels: gravity, fixed-direction
    /// edge loads and point loads, per cluster (loads that are expressions of time are left to
    /// [`Self::add_step_force`]).
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
            if lev == 0.0 || l.uses_t() {
                continue;
            }
            match &l.kind {
                Kind::Edge { faces, ends: Some(ends), follow: false, .. } => {
                    for (&f, e) in faces.iter().zip(ends) {
                        Self::edge_force_ends(model, f, &x0, lev, e, out);
                    }
                }
                Kind::Edge { faces, pressure, traction, follow: false, ends: None } => {
                    let (p, tx, ty) = (pressure.constant().unwrap_or(0.0), traction[0].constant().unwrap_or(0.0), traction[1].constant().unwrap_or(0.0));
                    for &f in faces {
                        Self::edge_force(model, f, &x0, lev * p, [lev * tx, lev * ty], out);
                    }
                }
                Kind::Point { points, value, at } => {
                    for (k, p) in points.iter().enumerate() {
                        let v = at.as_ref().map_or_else(|| [value[0].constant().unwrap_or(0.0), value[1].constant().unwrap_or(0.0)], |a| a[k]);
                        let c = model.topo.point_clusters[p.idx()][0].idx();
                        out[c][0] += lev * v[0];
                        out[c][1] += lev * v[1];
                    }
                }
                _ => {}
            }
        }
    }

    /// Adds what changes within a stage, on the current configuration (`x0 + u`) at `time`:
    /// following pressures, and the loads that are expressions of time (fixed-direction ones on
    /// the reference configuration). Called every step when the scene has either; an expression
    /// that gives a non-finite value is an error naming the load.
    pub fn add_step_force(&self, model: &Model, levels: &[f64], x0: &[[f64; 2]], u: &[[f64; 2]], time: f64, out: &mut [[f64; 2]]) -> Result<()> {
        let x = |c: usize| [x0[c][0] + u[c][0], x0[c][1] + u[c][1]];
        let xr = |c: usize| x0[c];
        let pref = |p: PointId| model.mesh.points[p.idx()];
        for (l, &lev) in self.loads.iter().zip(levels) {
            let uses_t = l.uses_t();
            match &l.kind {
                Kind::Edge { faces, pressure, follow: true, ends, .. } => {
                    for (k, &f) in faces.iter().enumerate() {
                        match (ends, pressure.constant()) {
                            (None, Some(p)) => Self::edge_force(model, f, &x, lev * p, [0.0; 2], out),
                            (Some(e), _) => Self::edge_force_ends(model, f, &x, lev, &e[k], out),
                            (None, None) if lev == 0.0 => {}
                            (None, None) => {
                                let (pa, pb) = Self::face_points(model, f);
                                let e = face_ends([pressure, &Field::Const(0.0), &Field::Const(0.0)], pref(pa), pref(pb), time, &l.key, &self.file, l.level)?;
                                Self::edge_force_ends(model, f, &x, lev, &e, out);
                            }
                        }
                    }
                }
                Kind::Edge { faces, pressure, traction, follow: false, .. } if uses_t && lev != 0.0 => {
                    for &f in faces {
                        let (pa, pb) = Self::face_points(model, f);
                        let e = face_ends([pressure, &traction[0], &traction[1]], pref(pa), pref(pb), time, &l.key, &self.file, l.level)?;
                        Self::edge_force_ends(model, f, &xr, lev, &e, out);
                    }
                }
                Kind::Point { points, value, .. } if uses_t && lev != 0.0 => {
                    for p in points {
                        let xp = pref(*p);
                        let at = |f: &Field| checked(f.at(xp[0], xp[1], time), f, &l.key, &self.file, xp, time, l.level);
                        let (v0, v1) = (at(&value[0])?, at(&value[1])?);
                        let c = model.topo.point_clusters[p.idx()][0].idx();
                        out[c][0] += lev * v0;
                        out[c][1] += lev * v1;
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Constraints at the given levels: fixity bits, prescribed velocity per cluster (an
    /// expression at time `time`; a value that is not finite counts as 0 here and stops the run
    /// at the next step, [`Self::ramp_velocities`]), and the prescribed displacements
    /// `(cluster, dof, value)` to impose at the stage start.
    pub fn constraints(&self, model: &Model, levels: &[f64], time: f64) -> (Vec<u8>, Vec<[f64; 2]>, Vec<(usize, usize, f64)>) {
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
                        let val = match val.constant() {
                            Some(v) => v,
                            None => {
                                let x = model.mesh.points[p.idx()];
                                let v = val.at(x[0], x[1], time);
                                if v.is_finite() {
                                    v
                                } else {
                                    0.0
                                }
                            }
                        };
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

    /// Prescribed velocities that are expressions of time (issue 36): sets `v_pres` of their
    /// dofs to the value at `time` (the caller passes the middle of the coming step, where the
    /// central-difference velocity lives) and returns the work this takes, as the energy ledger
    /// counts a free dof's: a prescribed dof going from `v-` (`v`, the last half step's velocity)
    /// to `v+` is pushed by the inertial force `m (v+ - v-) / dt` besides the element forces,
    /// whose trapezoidal work over the step is `1/2 m (v+^2 - v-^2)` (first value), of which
    /// `1/2 m (v+^2 - v- v+)` belongs to the step's second half (second value: the ledger's
    /// pending work). The element and contact forces' work on these dofs is summed by the node
    /// update as for any prescribed dof, so the ledger stays exact for linear elasticity. A value
    /// that is not finite, or beyond 1e100, stops the run naming the load.
    pub fn ramp_velocities(&self, model: &Model, levels: &[f64], time: f64, v: &[[f64; 2]], mass: &[f64], v_pres: &mut [[f64; 2]]) -> Result<(f64, f64)> {
        let (mut work, mut pending) = (0.0, 0.0);
        for (l, &lev) in self.loads.iter().zip(levels) {
            let Kind::Prescribed { points, value, displacement: false } = &l.kind else { continue };
            for (d, f) in value.iter().enumerate() {
                let Some(f) = f.as_ref().filter(|f| f.uses_t()) else { continue };
                for p in points {
                    let x = model.mesh.points[p.idx()];
                    let val = lev * checked(f.at(x[0], x[1], time), f, &l.key, &self.file, x, time, l.level)?;
                    for &c in &model.topo.point_clusters[p.idx()] {
                        let (c, m, vm) = (c.idx(), mass[c.idx()], v[c.idx()][d]);
                        work += 0.5 * m * (val * val - vm * vm);
                        pending += 0.5 * m * (val * val - vm * val);
                        v_pres[c][d] = val;
                    }
                }
            }
        }
        Ok((work, pending))
    }
}
