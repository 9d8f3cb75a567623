//! Contact in 3D (issue 38, docs/3d.md "Contact (3D)"): node-to-face penalty contact with
//! Coulomb friction between the faces of a 3D body, the paper's section 3.2 (eqs. 6-17) read in
//! 3D.
//!
//! What: the contact surfaces are element faces (a triangle of a T4, a quadrilateral of an H8):
//! both sides of every face separated at one corner at least (splits, `[model] separated`)
//! with `crack_faces`, the faces of the face sets in `surfaces` (a boundary face, or both
//! sides of an interior one), every boundary face with `boundary = true`. Every cluster at a
//! corner of a surface face is a *slave*, every (face, side) a *master* (two-pass, symmetric).
//!
//! How (the 2D design of [`super::search`], in 3D):
//! - Master geometry: a triangle is flat; a quadrilateral is the **bilinear** surface of its
//!   four corners (the trace of the H8's trilinear map, so the contact surface is the
//!   element's own surface; ours: no diagonal to choose, which would depend on the corner
//!   order and put a fold in a warped face). Closest-point projection: the triangle's plane and
//!   barycentric coordinates in closed form; the bilinear face by Newton on `(s, t)` in
//!   `[-1, 1]^2` (at most 12 iterations; exact in one for a parallelogram).
//! - Normal gap `g = (x_s - x(s, t)) . n`, `n` the outward unit normal of the master element
//!   at the projection (> 0 open, < 0 penetrated); tangential slip the relative displacement
//!   increment less its normal part, a 3-vector in the face's plane (eq. 8-9 in 3D).
//! - A slave touches a face when it projects inside it (a new pair: up to `XI_NEW` of the
//!   face's size outside; an existing pair is kept up to `XI_KEEP` outside unless a face it
//!   slid onto takes it) and lies behind it by less than `max_depth` x the face size
//!   (`sqrt(area)`), and the slave *faces* it (one of its own faces has its current outward
//!   normal within 60 degrees of opposite the master's: a node of a flat surface is not pushed
//!   sideways through the side face of a block landing on it). One pair per slave: its old master while it holds it, else the
//!   shallowest penetrated face (ties: lowest face id). A slave never pairs with a face of an
//!   element it belongs to.
//! - Forces (eq. 15-17 in 3D): the law's normal force along `n` plus its tangential vector on
//!   the slave, the opposite on the face's corners by the projection's shape functions (3
//!   barycentric or 4 bilinear weights summing to 1): momentum is exact.
//! - Broad phase: a uniform grid over the faces' bounding boxes, filled by counting sort (each
//!   cell's faces ascending), gives every slave the faces within `max_depth x h_max + skin`
//!   (a Verlet list), rebuilt when a surface node has moved more than `skin / 2` since the
//!   last build and after every split.
//! - History ([`Pair3`], sorted by slave cluster; the master is `2 x face + side`): the
//!   normal spring `e_n` and the tangential spring `e_s` (a 3-vector kept in the face's plane:
//!   turned with the face each step, its length kept).
//! - No energy from nothing (the 2D rules, [`super`]): only the run's first contact step takes
//!   overlaps whole; a pair born later with its slave already behind the face counts only the
//!   approach of its first step (the rest is its zero, [`PairState3::offset`]); a slave that
//!   passes to another face keeps its springs and the new gap continues the old one; a change
//!   of the pair's area scales its springs by `sqrt(A_new / A_old)` (energy kept); a pair lost
//!   by geometry releases its springs' energy as dissipated. A split keeps the pairs of the
//!   split cluster's first part (its id); the other parts pair afresh.
//! - Determinism: every loop runs in slave order, then face order; no hash map.
//!
//! The law is the scene's `[contact] law`, through [`ContactLaw::evaluate_3d`]: `spring_dashpot`
//! (the paper's eqs. 10-14: incremental springs, Coulomb cap on `|e_s|`) and `penalty` (ours)
//! have a 3D form; a law without one is refused by name. Stable step: `omega^2 = 4 k A_max /
//! m_min` over the slaves and, with `crack_faces`, over every element corner as if it were split
//! (its faces' share of area, its copy's mass), as in 2D.
//!
//! Limits: node-to-face only (no edge-to-edge or node-to-node contact: a slave at a concave
//! edge of the master surface is held by the faces on either side, but an edge crossing an
//! edge is not seen); small sliding per step (the pair moves to the face it slid onto, found
//! in its Verlet list); no cohesive law in 3D. Checkpoints: [`Contact3::pairs`] (plain serde)
//! and [`Contact3::verlet_state`], restored by [`Contact3::restore`] (no 3D checkpoint writes
//! them yet).
//!
//! ```toml
//! [contact]
//! law = { type = "spring_dashpot", normal_stiffness = 1e5, shear_stiffness = 1e5, friction = 0.5 }
//! surfaces = ["block_bottom", "base_top"]   # face sets of the mesh
//! boundary = false      # true: every boundary face is a contact surface
//! crack_faces = true    # faces of splits and of [model] separated
//! max_depth = 0.5       # deepest penetration counted, x the face size sqrt(area)
//! # skin = 0.05         # Verlet skin (length); default 0.2 x the mean face size
//! ```
use serde::{Deserialize, Serialize};

use super::{ContactCfg, ContactLaw};
use crate::error::{FlemError, Result};
use crate::ids::{ElemId, FaceId};
use crate::mesh::topology3::Topology3;
use crate::mesh::{face_integration, RawMesh3};

const NONE: u32 = u32::MAX;
/// A new pair is accepted for a projection up to `XI_NEW` (in units of the face's parametric
/// size) outside the face (faces meeting at an edge must not lose the slaves on that edge to
/// round-off); an existing pair is kept up to `XI_KEEP` outside when no other face takes it.
/// Forces use the projection clamped to the face.
const XI_NEW: f64 = 2e-2;
const XI_KEEP: f64 = 5e-2;

/// What a 3D law sees of one pair (the 3D twin of [`super::PairKinematics`]): vectors in the
/// global frame, tangential ones in the master face's plane at the projection.
#[derive(Copy, Clone, Debug, Default)]
pub struct PairKinematics3 {
    /// Signed gap along the master's outward normal (length; < 0 penetrated), less the pair's
    /// [`PairState3::offset`].
    pub gap: f64,
    /// Increment of the gap over the last step.
    pub dgap: f64,
    /// Increment of the tangential relative displacement of the slave (in the face's plane).
    pub dslip: [f64; 3],
    /// Relative velocity: normal component and tangential vector.
    pub vn: f64,
    pub vs: [f64; 3],
    /// Tributary area of the slave: springs are per unit area.
    pub area: f64,
    /// The pair's area in its previous step (0: first step); see [`super::PairKinematics`].
    pub area_old: f64,
    pub dt: f64,
    /// First step of this pair (no history yet).
    pub new: bool,
}

/// The force a 3D law returns for one pair (on the slave; the face gets the opposite).
#[derive(Copy, Clone, Debug, Default)]
pub struct PairForce3 {
    /// Normal force along the master's outward normal (> 0 pushes apart).
    pub normal: f64,
    /// Tangential force vector (in the face's plane).
    pub tangential: [f64; 3],
    /// The pair stays in contact (false: it opened and is dropped).
    pub active: bool,
    /// Elastic energy stored in the pair's springs now.
    pub stored: f64,
    /// Energy dissipated in this step (slip, dashpots).
    pub dissipated: f64,
}

/// Per-pair history in 3D (plain data).
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PairState3 {
    /// Normal spring force (compression positive).
    pub en: f64,
    /// Tangential spring force on the slave (a vector in the face's plane).
    pub es: [f64; 3],
    /// Gap offset (length): the law sees `gap - offset` (see [`super::PairState::offset`]).
    pub offset: f64,
    /// The pair's area in its last step (0: not yet known).
    pub area: f64,
    /// Energy stored in the springs after the last step (released as dissipated when the pair
    /// is lost by geometry).
    pub stored: f64,
}

/// One 3D contact pair: slave cluster, master `2 x face + side`, history.
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pair3 {
    pub slave: u32,
    pub master: u32,
    pub state: PairState3,
}

/// The force of one active pair after a step (for tests and output).
#[derive(Copy, Clone, Debug)]
pub struct PairReport3 {
    pub slave: u32,
    pub master: u32,
    /// Force on the slave (global frame).
    pub force: [f64; 3],
    /// Normal gap (length; < 0 penetrated), before the pair's offset.
    pub gap: f64,
    /// Outward unit normal of the master at the projection.
    pub normal: [f64; 3],
}

/// What [`Contact3::restore`] needs to rebuild the Verlet list of a checkpoint.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct VerletState3 {
    pub u_build: Vec<[f64; 3]>,
    pub dirty: bool,
    pub rebuilds: u64,
}

/// A master: face `id / 2` seen from side `id % 2` (its element's outward orientation).
#[derive(Copy, Clone, Debug)]
struct MFace {
    id: u32,
    /// 3 or 4 corners.
    n: u8,
    /// Clusters at the corners, anticlockwise seen from outside the element.
    c: [u32; 4],
    /// Clusters of the element (a slave among them is never paired with this face).
    elem: [u32; 8],
}

/// Geometry of one pair in this step.
#[derive(Copy, Clone, Debug)]
struct Geo3 {
    slave: u32,
    master: u32,
    c: [u32; 4],
    w: [f64; 4],
    n: [f64; 3],
    gap: f64,
}

/// A projection onto a face: gap, outward unit normal, corner weights (of the clamped point),
/// how far outside the face (parametric, 0 inside) and the face size `sqrt(area)`.
#[derive(Copy, Clone, Debug)]
struct Proj {
    gap: f64,
    n: [f64; 3],
    w: [f64; 4],
    out: f64,
    h: f64,
}

#[inline]
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline]
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

const S4: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];

/// Closest-point projection of `p` onto the face with corners `x` (3: flat triangle; 4:
/// bilinear quadrilateral), corners anticlockwise seen from outside. `None` for a degenerate
/// face or a Newton iteration that does not converge.
fn project(p: [f64; 3], x: &[[f64; 3]]) -> Option<Proj> {
    if x.len() == 3 {
        let (e1, e2, r) = (sub(x[1], x[0]), sub(x[2], x[0]), sub(p, x[0]));
        let nv = cross(e1, e2);
        let a2 = dot(nv, nv).sqrt();
        if !(a2 > 0.0) {
            return None;
        }
        let n = nv.map(|v| v / a2);
        let (g11, g12, g22, b1, b2) = (dot(e1, e1), dot(e1, e2), dot(e2, e2), dot(r, e1), dot(r, e2));
        let det = g11 * g22 - g12 * g12;
        let l1 = (g22 * b1 - g12 * b2) / det;
        let l2 = (g11 * b2 - g12 * b1) / det;
        let l0 = 1.0 - l1 - l2;
        let out = (-l0).max(-l1).max(-l2).max(0.0);
        // Clamped weights: the nearest point of the triangle in barycentric terms (clip and
        // renormalise: forces stay on the face's corners and sum to the force).
        let (c0, c1, c2) = (l0.max(0.0), l1.max(0.0), l2.max(0.0));
        let s = c0 + c1 + c2;
        return Some(Proj { gap: dot(r, n), n, w: [c0 / s, c1 / s, c2 / s, 0.0], out, h: (0.5 * a2).sqrt() });
    }
    let at = |s: f64, t: f64| {
        let (mut xp, mut xs, mut xt) = ([0.0; 3], [0.0; 3], [0.0; 3]);
        for a in 0..4 {
            let (sa, ta) = (S4[a][0], S4[a][1]);
            let na = 0.25 * (1.0 + sa * s) * (1.0 + ta * t);
            for d in 0..3 {
                xp[d] += na * x[a][d];
                xs[d] += 0.25 * sa * (1.0 + ta * t) * x[a][d];
                xt[d] += 0.25 * ta * (1.0 + sa * s) * x[a][d];
            }
        }
        (xp, xs, xt)
    };
    let mut xst = [0.0; 3];
    for a in 0..4 {
        for d in 0..3 {
            xst[d] += 0.25 * S4[a][0] * S4[a][1] * x[a][d];
        }
    }
    let (mut s, mut t) = (0.0f64, 0.0f64);
    let mut ok = false;
    for _ in 0..12 {
        let (xp, xs, xt) = at(s, t);
        let r = sub(xp, p);
        let (g1, g2) = (dot(r, xs), dot(r, xt));
        let (h11, h12, h22) = (dot(xs, xs), dot(xs, xt) + dot(r, xst), dot(xt, xt));
        let det = h11 * h22 - h12 * h12;
        if !(det > 0.0) {
            return None;
        }
        let ds = -(h22 * g1 - h12 * g2) / det;
        let dtt = -(h11 * g2 - h12 * g1) / det;
        // Far outside the face the bilinear extension is meaningless: stop there (the pair
        // is rejected by its `out`).
        s = (s + ds).clamp(-3.0, 3.0);
        t = (t + dtt).clamp(-3.0, 3.0);
        if ds.abs() + dtt.abs() < 1e-12 {
            ok = true;
            break;
        }
    }
    if !ok {
        return None;
    }
    let (xp, xs, xt) = at(s, t);
    let nv = cross(xs, xt);
    let l = dot(nv, nv).sqrt();
    if !(l > 0.0) {
        return None;
    }
    let n = nv.map(|v| v / l);
    let out = 0.5 * ((s.abs() - 1.0).max(t.abs() - 1.0)).max(0.0);
    let (sc, tc) = (s.clamp(-1.0, 1.0), t.clamp(-1.0, 1.0));
    let w: [f64; 4] = std::array::from_fn(|a| 0.25 * (1.0 + S4[a][0] * sc) * (1.0 + S4[a][1] * tc));
    let area = dot(cross(sub(x[2], x[0]), sub(x[3], x[1])), cross(sub(x[2], x[0]), sub(x[3], x[1]))).sqrt() * 0.5;
    Some(Proj { gap: dot(sub(p, xp), n), n, w, out, h: area.sqrt() })
}

/// Contact state of a 3D body (see the module doc).
#[derive(Debug)]
pub struct Contact3 {
    law: Box<dyn ContactLaw>,
    declared: Vec<bool>,
    crack_faces: bool,
    boundary: bool,
    max_depth: f64,
    skin_cfg: Option<f64>,
    /// Verlet skin in use (length).
    pub skin: f64,
    faces: Vec<MFace>,
    face_of_id: Vec<u32>,
    /// Slave clusters, ascending, their mesh points and tributary areas.
    slaves: Vec<u32>,
    area: Vec<f64>,
    /// Per slave, its faces (index in `faces`), their reference outward normals and area
    /// shares.
    side_off: Vec<u32>,
    side: Vec<(u32, [f64; 3], f64)>,
    /// Reference outward normal of every master face (by index in `faces`).
    ref_normal: Vec<[f64; 3]>,
    cluster_pt: Vec<u32>,
    cand_off: Vec<u32>,
    cand: Vec<u32>,
    u_build: Vec<[f64; 3]>,
    dirty: bool,
    /// The open pairs, sorted by slave.
    pub pairs: Vec<Pair3>,
    next: Vec<Pair3>,
    geo: Vec<Geo3>,
    kin: Vec<PairKinematics3>,
    st: Vec<PairState3>,
    out: Vec<PairForce3>,
    reports: Vec<PairReport3>,
    cell_count: Vec<u32>,
    cell_items: Vec<u32>,
    released: f64,
    areas_stale: bool,
    /// Verlet-list builds so far.
    pub rebuilds: u64,
    /// Squared contact frequency bound (see [`Contact3::update_omega2`]).
    pub omega2: f64,
}

impl Contact3 {
    /// The contact of a 3D body from its `[contact]` (after the pre-separated faces were cut);
    /// `file` names the scene in errors. Refuses a law with no 3D form by name.
    pub fn new(cfg: ContactCfg, mesh: &RawMesh3, topo: &Topology3, file: &str) -> Result<Contact3> {
        cfg.validate(file)?;
        if let Err(e) = cfg.law.evaluate_3d(&[], &mut [], &mut []) {
            return Err(FlemError::config(file, "contact.law", format!("{e}: a 3D scene takes \"spring_dashpot\" or \"penalty\"")));
        }
        let mut declared = vec![false; topo.faces.len()];
        for (k, name) in cfg.surfaces.iter().enumerate() {
            let Some(set) = mesh.face_sets.get(name) else {
                return Err(FlemError::config(
                    file,
                    format!("contact.surfaces[{k}]"),
                    format!("= \"{name}\" names no face set of the mesh (face sets: {:?})", mesh.face_sets.keys().collect::<Vec<_>>()),
                ));
            };
            for f in set {
                match topo.face_with(f.corners()) {
                    Some(fid) => declared[fid.idx()] = true,
                    None => return Err(FlemError::config(file, format!("contact.surfaces[{k}]"), format!("face set \"{name}\": the face of {} is no cell's face", mesh.points_name(f.corners())))),
                }
            }
        }
        let mut c = Contact3 {
            law: cfg.law,
            declared,
            crack_faces: cfg.crack_faces,
            boundary: cfg.boundary,
            max_depth: cfg.max_depth,
            skin_cfg: cfg.skin,
            skin: 0.0,
            faces: Vec::new(),
            face_of_id: Vec::new(),
            slaves: Vec::new(),
            area: Vec::new(),
            side_off: Vec::new(),
            side: Vec::new(),
            ref_normal: Vec::new(),
            cluster_pt: Vec::new(),
            cand_off: Vec::new(),
            cand: Vec::new(),
            u_build: Vec::new(),
            dirty: true,
            pairs: Vec::new(),
            next: Vec::new(),
            geo: Vec::new(),
            kin: Vec::new(),
            st: Vec::new(),
            out: Vec::new(),
            reports: Vec::new(),
            cell_count: Vec::new(),
            cell_items: Vec::new(),
            released: 0.0,
            areas_stale: true,
            rebuilds: 0,
            omega2: 0.0,
        };
        c.rebuild_surfaces(mesh, topo);
        Ok(c)
    }

    /// The law in use.
    pub fn law(&self) -> &dyn ContactLaw {
        self.law.as_ref()
    }
    /// Number of slave nodes and of master faces.
    pub fn n_surface_nodes(&self) -> usize {
        self.slaves.len()
    }
    pub fn n_faces(&self) -> usize {
        self.faces.len()
    }
    /// The force of every active pair in the last step, in slave order.
    pub fn forces(&self) -> &[PairReport3] {
        &self.reports
    }

    fn rebuild_surfaces(&mut self, mesh: &RawMesh3, topo: &Topology3) {
        self.faces.clear();
        self.ref_normal.clear();
        let mut per: Vec<(u32, f64, [f64; 3], u32)> = Vec::new();
        let mut total_h = 0.0;
        for (fi, f) in topo.faces.iter().enumerate() {
            let on = match f.sides {
                [Some(_), None] => self.boundary || self.declared[fi],
                _ => self.declared[fi] || (self.crack_faces && topo.crack_state(FaceId::new(fi)) >= 1),
            };
            if !on {
                continue;
            }
            for (side, &(e, k)) in f.sides.iter().enumerate().filter_map(|(s, x)| x.as_ref().map(|x| (s, x))) {
                let cell = &mesh.cells[e.idx()];
                let local = cell.kind.faces()[k as usize];
                let nc = if local[3] == crate::mesh::NO_CORNER { 3 } else { 4 };
                let r = topo.elem_copies(e);
                let mut elem = [NONE; 8];
                for (a, x) in elem.iter_mut().enumerate().take(r.len()) {
                    *x = topo.copy_cluster[r.start + a].0;
                }
                let mut c = [NONE; 4];
                let mut x = [[0.0; 3]; 4];
                for a in 0..nc {
                    let li = local[a] as usize;
                    c[a] = topo.copy_cluster[r.start + li].0;
                    x[a] = mesh.points[cell.nodes[li] as usize];
                }
                let mut nsum = [0.0; 3];
                let mut share = [0.0; 4];
                face_integration(&x[..nc], |w, av| {
                    let a = dot(av, av).sqrt();
                    for d in 0..3 {
                        nsum[d] += av[d];
                    }
                    for (s, &wa) in share.iter_mut().zip(w) {
                        *s += wa * a;
                    }
                });
                let la = dot(nsum, nsum).sqrt();
                let n = if la > 0.0 { nsum.map(|v| v / la) } else { [0.0; 3] };
                total_h += la.sqrt();
                for a in 0..nc {
                    per.push((c[a], share[a], n, self.faces.len() as u32));
                }
                self.faces.push(MFace { id: 2 * fi as u32 + side as u32, n: nc as u8, c, elem });
                self.ref_normal.push(n);
            }
        }
        // `topo.faces` order and then side: ids ascending already.
        self.face_of_id.clear();
        self.face_of_id.resize(2 * topo.faces.len(), NONE);
        for (i, f) in self.faces.iter().enumerate() {
            self.face_of_id[f.id as usize] = i as u32;
        }
        per.sort_by_key(|a| a.0);
        self.side.clear();
        self.side_off.clear();
        self.side_off.push(0);
        self.slaves.clear();
        self.area.clear();
        for (k, &(c, a, n, fi)) in per.iter().enumerate() {
            self.side.push((fi, n, a));
            if self.slaves.last() == Some(&c) {
                *self.area.last_mut().unwrap() += a;
            } else {
                self.slaves.push(c);
                self.area.push(a);
            }
            if per.get(k + 1).is_none_or(|x| x.0 != c) {
                self.side_off.push(self.side.len() as u32);
            }
        }
        let mean = if self.faces.is_empty() { 1.0 } else { total_h / self.faces.len() as f64 };
        self.skin = self.skin_cfg.unwrap_or(0.2 * mean);
        self.dirty = true;
        self.areas_stale = true;
        self.cluster_pt.clear();
        self.cluster_pt.extend(topo.cluster_point.iter().map(|p| p.0));
    }

    /// The squared contact frequency bound for the stable step: `4 k A / m` over the slaves
    /// (cluster masses `mass`, fully fixed ones left out) and, with `crack_faces`, over every
    /// element corner (copy mass `copy_mass`, the area share of its element's faces through it)
    /// as if a split made it a node of its own, so that the step stays stable after splits.
    pub fn update_omega2(&mut self, mesh: &RawMesh3, topo: &Topology3, copy_mass: &[f64], mass: &[f64], fix: &[u8]) {
        let k = self.law.stiffness();
        let mut w2: f64 = 0.0;
        for (&s, &a) in self.slaves.iter().zip(&self.area) {
            let m = mass[s as usize];
            if fix[s as usize] != 7 && m > 0.0 {
                w2 = w2.max(4.0 * k * a / m);
            }
        }
        if self.crack_faces {
            for (e, cell) in mesh.cells.iter().enumerate() {
                let r = topo.elem_copies(ElemId::new(e));
                let mut share = [0.0; 8];
                for local in cell.kind.faces() {
                    let nc = if local[3] == crate::mesh::NO_CORNER { 3 } else { 4 };
                    let x: Vec<[f64; 3]> = local[..nc].iter().map(|&l| mesh.points[cell.nodes[l as usize] as usize]).collect();
                    face_integration(&x, |w, av| {
                        let a = dot(av, av).sqrt();
                        for (b, &wa) in w.iter().enumerate() {
                            share[local[b] as usize] += wa * a;
                        }
                    });
                }
                for (a, &sh) in share.iter().enumerate().take(r.len()) {
                    let m = copy_mass[r.start + a];
                    if m > 0.0 {
                        w2 = w2.max(4.0 * k * sh / m);
                    }
                }
            }
        }
        self.omega2 = w2;
    }

    /// Follows splits: the faces of newly cut faces become surfaces and the Verlet list is
    /// rebuilt. A pair keeps its slave cluster id (the part of a split cluster holding its
    /// first copy); its area is recomputed at the next step.
    pub fn on_split(&mut self, mesh: &RawMesh3, topo: &Topology3) {
        self.rebuild_surfaces(mesh, topo);
    }

    /// The Verlet list's build state, for checkpoints (as 2D's `Contact::verlet_state`): a
    /// resumed run must rebuild its list at the same steps and from the same positions.
    pub fn verlet_state(&self) -> VerletState3 {
        VerletState3 { u_build: self.u_build.clone(), dirty: self.dirty, rebuilds: self.rebuilds }
    }

    /// Restores a checkpoint's pairs and Verlet list (the topology must already be the
    /// checkpoint's; the surfaces are rebuilt from it): the list is rebuilt from the saved
    /// surface displacements, so that it and its next rebuild are the uninterrupted run's. A
    /// state that does not fit the surfaces leaves the list to be rebuilt at the next step.
    pub fn restore(&mut self, mesh: &RawMesh3, topo: &Topology3, pairs: Vec<Pair3>, st: VerletState3) {
        self.rebuild_surfaces(mesh, topo);
        self.pairs = pairs;
        if !st.dirty && st.u_build.len() == self.slaves.len() {
            let mut u = vec![[0.0; 3]; topo.n_clusters()];
            for (&s, b) in self.slaves.iter().zip(&st.u_build) {
                u[s as usize] = *b;
            }
            self.build_verlet(&mesh.points, &u);
        }
        self.rebuilds = st.rebuilds;
    }

    /// Rebuilds the Verlet list: for every slave, the faces (not of an element it belongs to)
    /// whose bounding box is within `max_depth x h_max + skin` of it, ascending.
    fn build_verlet(&mut self, points: &[[f64; 3]], u: &[[f64; 3]]) {
        self.rebuilds += 1;
        self.dirty = false;
        let cp = &self.cluster_pt;
        let x = |c: u32| {
            let (p, d) = (points[cp[c as usize] as usize], u[c as usize]);
            [p[0] + d[0], p[1] + d[1], p[2] + d[2]]
        };
        self.u_build.clear();
        self.u_build.extend(self.slaves.iter().map(|&s| u[s as usize]));
        self.cand_off.clear();
        self.cand.clear();
        self.cand_off.push(0);
        if self.faces.is_empty() {
            self.cand_off.resize(self.slaves.len() + 1, 0);
            return;
        }
        let bbox = |f: &MFace| {
            let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for &c in &f.c[..f.n as usize] {
                let p = x(c);
                for d in 0..3 {
                    lo[d] = lo[d].min(p[d]);
                    hi[d] = hi[d].max(p[d]);
                }
            }
            (lo, hi)
        };
        let (mut lo, mut hi, mut hmax) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3], 0.0f64);
        for f in &self.faces {
            let (a, b) = bbox(f);
            hmax = hmax.max(dot(sub(b, a), sub(b, a)).sqrt());
            for d in 0..3 {
                lo[d] = lo[d].min(a[d]);
                hi[d] = hi[d].max(b[d]);
            }
        }
        let margin = self.max_depth * hmax + self.skin;
        let mut h = hmax + 2.0 * margin;
        for d in 0..3 {
            lo[d] -= margin;
            hi[d] += margin;
        }
        let cap = 4 * self.faces.len() + 64;
        let dims = |h: f64| -> [usize; 3] { std::array::from_fn(|d| ((hi[d] - lo[d]) / h).floor() as usize + 1) };
        while dims(h).iter().product::<usize>() > cap {
            h *= 1.5;
        }
        let nd = dims(h);
        let ix = |v: f64, d: usize| (((v - lo[d]) / h).floor().max(0.0) as usize).min(nd[d] - 1);
        let range = |f: &MFace| {
            let (a, b) = bbox(f);
            let r: [(usize, usize); 3] = std::array::from_fn(|d| (ix(a[d] - margin, d), ix(b[d] + margin, d)));
            r
        };
        let ncell = nd[0] * nd[1] * nd[2];
        self.cell_count.clear();
        self.cell_count.resize(ncell + 1, 0);
        for f in &self.faces {
            let r = range(f);
            for k in r[2].0..=r[2].1 {
                for j in r[1].0..=r[1].1 {
                    for i in r[0].0..=r[0].1 {
                        self.cell_count[(k * nd[1] + j) * nd[0] + i + 1] += 1;
                    }
                }
            }
        }
        for k in 0..ncell {
            self.cell_count[k + 1] += self.cell_count[k];
        }
        self.cell_items.clear();
        self.cell_items.resize(self.cell_count[ncell] as usize, 0);
        let mut cursor: Vec<u32> = self.cell_count[..ncell].to_vec();
        for (fi, f) in self.faces.iter().enumerate() {
            let r = range(f);
            for k in r[2].0..=r[2].1 {
                for j in r[1].0..=r[1].1 {
                    for i in r[0].0..=r[0].1 {
                        let c = (k * nd[1] + j) * nd[0] + i;
                        self.cell_items[cursor[c] as usize] = fi as u32;
                        cursor[c] += 1;
                    }
                }
            }
        }
        let m2 = margin * margin;
        for &s in &self.slaves {
            let p = x(s);
            if p.iter().enumerate().all(|(d, &v)| v >= lo[d] && v <= hi[d]) {
                let c = (ix(p[2], 2) * nd[1] + ix(p[1], 1)) * nd[0] + ix(p[0], 0);
                for &fi in &self.cell_items[self.cell_count[c] as usize..self.cell_count[c + 1] as usize] {
                    let f = &self.faces[fi as usize];
                    if f.elem.contains(&s) {
                        continue;
                    }
                    let (a, b) = bbox(f);
                    let d2: f64 = (0..3).map(|d| (a[d] - p[d]).max(p[d] - b[d]).max(0.0).powi(2)).sum();
                    if d2 <= m2 {
                        self.cand.push(fi);
                    }
                }
            }
            self.cand_off.push(self.cand.len() as u32);
        }
    }

    fn needs_rebuild(&self, u: &[[f64; 3]]) -> bool {
        if self.dirty || self.u_build.len() != self.slaves.len() {
            return true;
        }
        let lim = 0.25 * self.skin * self.skin;
        self.slaves.iter().zip(&self.u_build).any(|(&s, b)| {
            let d = sub(u[s as usize], *b);
            dot(d, d) > lim
        })
    }

    /// Projection of slave position `p` onto master face (index) `fi` at the current positions.
    #[inline]
    fn proj(&self, fi: usize, p: [f64; 3], x: &impl Fn(u32) -> [f64; 3]) -> Option<Proj> {
        let f = &self.faces[fi];
        let mut xs = [[0.0; 3]; 4];
        for a in 0..f.n as usize {
            xs[a] = x(f.c[a]);
        }
        project(p, &xs[..f.n as usize])
    }

    /// Whether slave `si` faces a master whose outward normal at the projection is `nm`: one
    /// of the slave's faces has its current outward normal within 60 degrees of opposite
    /// (`n_s . n_m < -1/2`). A slave is never pushed through a face it meets edge-on (a node
    /// of a flat surface against the side of a block landing on it: the side face is the
    /// shallowest, but pushing the node sideways out of the block is not contact of these
    /// surfaces).
    fn facing(&self, si: usize, nm: [f64; 3], x: &impl Fn(u32) -> [f64; 3]) -> bool {
        self.side[self.side_off[si] as usize..self.side_off[si + 1] as usize].iter().any(|&(fi, _, _)| {
            let f = &self.faces[fi as usize];
            let nv = if f.n == 3 {
                let x0 = x(f.c[0]);
                cross(sub(x(f.c[1]), x0), sub(x(f.c[2]), x0))
            } else {
                cross(sub(x(f.c[2]), x(f.c[0])), sub(x(f.c[3]), x(f.c[1])))
            };
            let l = dot(nv, nv).sqrt();
            l > 0.0 && dot(nv, nm) < -0.5 * l
        })
    }

    /// Tributary area of slave `si` against master face `fi`: its faces whose reference normals
    /// face the master's (within 60 degrees of opposite); the whole area when none does.
    fn facing_area(&self, si: usize, fi: usize) -> f64 {
        let nm = self.ref_normal[fi];
        let a: f64 = self.side[self.side_off[si] as usize..self.side_off[si + 1] as usize].iter().filter(|(_, n, _)| dot(*n, nm) < -0.5).map(|(_, _, a)| a).sum();
        if a > 0.0 {
            a
        } else {
            self.area[si]
        }
    }

    /// One contact step: the narrow phase, the law on the batch, the forces into `f` (zeroed
    /// first). `points` are the mesh points, `u`, `v` per cluster. Returns (stored energy,
    /// energy dissipated in this step).
    pub fn compute(&mut self, points: &[[f64; 3]], u: &[[f64; 3]], v: &[[f64; 3]], dt: f64, f: &mut [[f64; 3]]) -> Result<(f64, f64)> {
        let first = self.rebuilds == 0;
        if self.needs_rebuild(u) {
            self.build_verlet(points, u);
        }
        self.narrow(points, u, v, dt, first);
        let n = self.geo.len();
        self.out.clear();
        self.out.resize(n, PairForce3::default());
        self.law.evaluate_3d(&self.kin, &mut self.st, &mut self.out).map_err(|e| FlemError::config("scene", "contact.law", e))?;
        f.iter_mut().for_each(|x| *x = [0.0; 3]);
        self.next.clear();
        self.reports.clear();
        let (mut stored, mut diss) = (0.0, self.released);
        for k in 0..n {
            let (g, o) = (&self.geo[k], &self.out[k]);
            diss += o.dissipated;
            if !o.active {
                continue;
            }
            stored += o.stored;
            let fv: [f64; 3] = std::array::from_fn(|d| o.normal * g.n[d] + o.tangential[d]);
            let s = g.slave as usize;
            for d in 0..3 {
                f[s][d] += fv[d];
            }
            for (&c, &w) in g.c.iter().zip(&g.w) {
                if c != NONE && w != 0.0 {
                    for d in 0..3 {
                        f[c as usize][d] -= w * fv[d];
                    }
                }
            }
            self.st[k].stored = o.stored;
            self.next.push(Pair3 { slave: g.slave, master: g.master, state: self.st[k] });
            self.reports.push(PairReport3 { slave: g.slave, master: g.master, force: fv, gap: g.gap, normal: g.n });
        }
        std::mem::swap(&mut self.next, &mut self.pairs);
        Ok((stored, diss))
    }

    fn narrow(&mut self, points: &[[f64; 3]], u: &[[f64; 3]], v: &[[f64; 3]], dt: f64, first: bool) {
        self.geo.clear();
        self.kin.clear();
        self.st.clear();
        self.released = 0.0;
        let cp = &self.cluster_pt;
        let x = |c: u32| {
            let (p, d) = (points[cp[c as usize] as usize], u[c as usize]);
            [p[0] + d[0], p[1] + d[1], p[2] + d[2]]
        };
        let mut h = 0usize;
        for si in 0..self.slaves.len() {
            let s = self.slaves[si];
            while h < self.pairs.len() && self.pairs[h].slave < s {
                h += 1;
            }
            let old = (h < self.pairs.len() && self.pairs[h].slave == s).then(|| self.pairs[h]);
            let p = x(s);
            // The old master, while the slave projects on it (or near it) and is not too deep.
            let mut keep: Option<(usize, Proj)> = None;
            let mut old_law_gap = None;
            if let Some(o) = old {
                let fi = self.face_of_id.get(o.master as usize).copied().unwrap_or(NONE);
                if fi != NONE && !self.faces[fi as usize].elem.contains(&s) {
                    if let Some(pr) = self.proj(fi as usize, p, &x) {
                        old_law_gap = Some(pr.gap - o.state.offset);
                        if -pr.gap <= self.max_depth * pr.h && pr.out <= XI_KEEP {
                            keep = Some((fi as usize, pr));
                        }
                    }
                }
            }
            // A face it projects inside of, penetrated: the shallowest (ties: lowest id).
            let mut best: Option<(usize, Proj)> = None;
            if keep.is_none_or(|(_, pr)| pr.out > 0.0) {
                for &fi in &self.cand[self.cand_off[si] as usize..self.cand_off[si + 1] as usize] {
                    let fi = fi as usize;
                    if keep.is_some_and(|(k, _)| k == fi) {
                        continue;
                    }
                    let Some(pr) = self.proj(fi, p, &x) else { continue };
                    if pr.gap >= 0.0 || -pr.gap > self.max_depth * pr.h || pr.out > XI_NEW || !self.facing(si, pr.n, &x) {
                        continue;
                    }
                    if best.as_ref().is_none_or(|b| -pr.gap < -b.1.gap) {
                        best = Some((fi, pr));
                    }
                }
            }
            let (fi, pr, mut state, mut new) = match (keep, best) {
                (Some((fi, pr)), None) => (fi, pr, old.unwrap().state, false),
                (Some((fi, pr)), Some(_)) if pr.out == 0.0 => (fi, pr, old.unwrap().state, false),
                (_, Some((fi, pr))) => (fi, pr, PairState3::default(), true),
                (None, None) => {
                    // Lost by geometry (not opened by its law): its springs' energy leaves.
                    if let Some(o) = old {
                        self.released += o.state.stored;
                    }
                    continue;
                }
            };
            let mf = &self.faces[fi];
            let vp = v[s as usize];
            let mut vr = vp;
            for a in 0..mf.n as usize {
                let vc = v[mf.c[a] as usize];
                for d in 0..3 {
                    vr[d] -= pr.w[a] * vc[d];
                }
            }
            let vn = dot(vr, pr.n);
            let vs: [f64; 3] = std::array::from_fn(|d| vr[d] - vn * pr.n[d]);
            if new {
                if let (Some(o), Some(lg)) = (old, old_law_gap) {
                    // The slave passed from its master to another face: its springs carry
                    // over and the new gap continues the old pair's law gap.
                    state = PairState3 { offset: pr.gap - lg, ..o.state };
                    new = false;
                } else {
                    if let Some(o) = old {
                        self.released += o.state.stored;
                    }
                    if !first {
                        // Born overlapped: the spring counts the approach of this step only.
                        let depth = (-pr.gap).min((-vn * dt).max(0.0));
                        state.offset = (pr.gap + depth).min(0.0);
                    }
                }
            }
            let master = mf.id;
            let same = old.is_some_and(|o| o.master == master);
            let area = if !self.areas_stale && state.area > 0.0 && same { state.area } else { self.facing_area(si, fi) };
            if state.area > 0.0 && area != state.area {
                let r = (area / state.area).sqrt();
                state.en *= r;
                state.es = state.es.map(|e| e * r);
            }
            // The tangential spring turns with the face: kept in its plane, length kept.
            let en_dot = dot(state.es, pr.n);
            if en_dot != 0.0 {
                let len = dot(state.es, state.es).sqrt();
                let t: [f64; 3] = std::array::from_fn(|d| state.es[d] - en_dot * pr.n[d]);
                let lt = dot(t, t).sqrt();
                state.es = if lt > 0.0 { t.map(|c| c * len / lt) } else { [0.0; 3] };
            }
            let area_old = state.area;
            state.area = area;
            self.kin.push(PairKinematics3 { gap: pr.gap - state.offset, dgap: vn * dt, dslip: vs.map(|c| c * dt), vn, vs, area, area_old, dt, new });
            self.st.push(state);
            self.geo.push(Geo3 { slave: s, master, c: mf.c, w: pr.w, n: pr.n, gap: pr.gap });
        }
        self.areas_stale = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The projection onto a triangle and a bilinear quadrilateral: gap, outward normal and
    /// weights that reproduce the projected point. Reference: hand geometry; 1e-12.
    #[test]
    fn projection_onto_triangle_and_bilinear_quad() {
        let tri = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let p = project([0.25, 0.25, -0.1], &tri).unwrap();
        assert!((p.gap + 0.1).abs() < 1e-12 && (p.n[2] - 1.0).abs() < 1e-12 && p.out == 0.0);
        assert!((p.w[0] - 0.5).abs() < 1e-12 && (p.w[1] - 0.25).abs() < 1e-12 && (p.w[2] - 0.25).abs() < 1e-12);
        // A warped quadrilateral: the projection is where the gap vector is normal to the
        // surface, and the weights rebuild the foot point.
        let q = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.2], [2.0, 1.5, 0.0], [0.0, 1.0, 0.1]];
        let x = [0.7, 0.6, 0.5];
        let p = project(x, &q).unwrap();
        let foot: [f64; 3] = std::array::from_fn(|d| (0..4).map(|a| p.w[a] * q[a][d]).sum());
        let r = sub(x, foot);
        let g = dot(r, r).sqrt();
        assert!((g - p.gap.abs()).abs() < 1e-12 && p.gap > 0.0, "gap {} |r| {g}", p.gap);
        assert!((dot(r, p.n) - p.gap).abs() < 1e-12);
        assert!((p.w.iter().sum::<f64>() - 1.0).abs() < 1e-14 && p.out == 0.0);
    }
}
