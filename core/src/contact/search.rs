//! Contact surfaces, the Verlet-list broad phase on a uniform grid, the narrow phase and the
//! force scatter (see the module docs of [`crate::contact`]).
//!
//! Why a hand-written grid rather than kiddo/rstar: the faces of a FLEM mesh have similar
//! sizes, the grid is rebuilt rarely (skin) and a counting sort into fixed cells gives a
//! deterministic candidate order (by face index) with no dependency; a tree would need a
//! sort of its query results to be deterministic anyway.
use super::{Bond, ContactCfg, ContactHistory, ContactLaw, Master, Pair, PairForce, PairKinematics, PairState};
use crate::element::model::Model;
use crate::element::registry;
use crate::error::Result;
use crate::ids::{EdgeId, ElemId, PointId};
use crate::mesh::topology::{SplitRecord, Topology};
use serde::{Deserialize, Serialize};

const NONE: u32 = u32::MAX;
/// A new node-to-edge contact is accepted for `-XI_NEW <= xi <= 1 + XI_NEW` (faces ending at
/// the same point, e.g. the two sides of a cut, must not lose their end nodes to round-off);
/// an existing pair is kept up to `XI_KEEP` beyond its face when no neighbouring face takes
/// it (hysteresis: no chatter at face ends). Forces use `xi` clamped to [0, 1].
const XI_NEW: f64 = 2e-2;
const XI_KEEP: f64 = 5e-2;

/// A master face: element `id / 4`, local edge `id % 4`, from cluster `a` to cluster `b`
/// (counter-clockwise, outward normal `(dy, -dx) / L`).
#[derive(Copy, Clone, Debug)]
struct Face {
    id: u32,
    a: u32,
    b: u32,
    /// Clusters of the face's element (a slave of the same element is never its contact).
    elem: [u32; 4],
    /// Mesh points of the ends `a`, `b`, and the cluster across the face's edge at each end
    /// (the other side's node there when the edge is separated at that end, else `NONE`).
    pts: [u32; 2],
    across: [u32; 2],
}

impl Face {
    /// The slave `s` (at mesh point `sp`) sits at a vertex of this face without being the
    /// node across the face's edge there: a third body meeting at that point (the V of a
    /// crack branch, a junction of cracks). It touches the face only at the face's own end,
    /// where the normal gap is a round-off of the rotation of the face about that point, not
    /// a penetration: no pair (the contact of those bodies is carried by their other nodes).
    #[inline]
    fn vertex_only(&self, s: u32, sp: u32) -> bool {
        (sp == self.pts[0] && s != self.across[0]) || (sp == self.pts[1] && s != self.across[1])
    }
}

/// Geometry of one pair in this step.
#[derive(Copy, Clone, Debug)]
struct Geo {
    slave: u32,
    master: Master,
    i: u32,
    j: u32,
    xi: f64,
    n: [f64; 2],
    t: [f64; 2],
}

/// Where the cohesion of crack faces went without its law opening them (issue 36: the
/// fracture-energy account of docs/dynamic.md). Each term is the energy the pairs concerned
/// had still to release (`A x ContactLaw::unreleased`) when their cohesion left, cumulative
/// over the run; it was never dissipated (the faces came free without paying it). Since
/// session 17 a law with cohesion carries it per face end ([`Bond`]) and these counters stay 0
/// (the per-node pairs they watch are then contact only); `summary.json` keeps them so that
/// a run's account shows it. Not
/// checkpointed (a resumed run counts from the resume). Zero for laws without cohesion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct CohesionAccount {
    /// Cohesive pairs lost by geometry (the slave slid off its face, no neighbour took it).
    pub lost_geometry: f64,
    /// Cohesive pairs whose slave passed to another master (they go on as contact only:
    /// cohesion belongs to the faces of the split edge).
    pub lost_master: f64,
    /// Pairs of a split slave merged into one (one pair per slave): the dropped ones.
    pub lost_merged: f64,
    /// A cohesive pair's area that shrank (a split gave part of the slave's faces to another
    /// node): the part given away (`(A_old - A) x unreleased`).
    pub lost_shrunk: f64,
    /// Cut edge ends that got no fresh pair (their slave had a pair already, or the faces
    /// meet at one node): `G_f x` half the edge's area each (an upper bound: the slave's own
    /// pair may cover the face when it faces the same master).
    pub unpaired: f64,
    /// Cut edge ends whose slave kept a pair without cohesion (contact only: a face pair that
    /// opened past `delta_f` and closed again, or a pair of faces that were never cohesive):
    /// `G_f x` half the edge's area each; the new face gets no cohesion.
    pub unpaired_contact: f64,
}

impl CohesionAccount {
    pub fn total(&self) -> f64 {
        self.lost_geometry + self.lost_master + self.lost_merged + self.lost_shrunk + self.unpaired + self.unpaired_contact
    }
}

/// Contact state of a simulation: surfaces, Verlet list, pair history and scratch buffers.
#[derive(Debug)]
pub struct Contact {
    declared: Vec<bool>,
    fresh_edge: Vec<bool>,
    crack_faces: bool,
    boundary: bool,
    max_depth: f64,
    skin_cfg: Option<f64>,
    /// Verlet skin in use (length).
    pub skin: f64,
    faces: Vec<Face>,
    face_of_id: Vec<u32>,
    /// Slave clusters, ascending, with their tributary area (length x thickness).
    slaves: Vec<u32>,
    /// Mesh point of every slave.
    slave_pt: Vec<u32>,
    /// Mesh point of every cluster (as `Topology::cluster_point`).
    cluster_pt: Vec<u32>,
    /// Faces of every slave (`side[side_off[i]..side_off[i + 1]]`): reference outward normal
    /// and half the face area.
    side_off: Vec<u32>,
    side: Vec<([f64; 2], f64)>,
    area: Vec<f64>,
    cand_off: Vec<u32>,
    cand: Vec<u32>,
    /// The displacement of every surface node at the build of its Verlet list (by cluster): the
    /// list's build configuration is `x0 + ub`. A full build sets it for every slave; a local
    /// update after a split (cohesive laws, [`Contact::patch_verlet`]) keeps it for the slaves
    /// it does not touch and gives new ones their parent's (or their displacement now).
    ub: Vec<[f64; 2]>,
    /// The list holds, for every slave, every face within `margin_list` of it in the build
    /// configuration; `lmax_list` is the longest face it was built for and `skin_list` what is
    /// left of the margin beyond `max_depth x lmax_list`: the list stays valid while no surface
    /// node moved more than `skin_list / 2` from its build position.
    margin_list: f64,
    lmax_list: f64,
    skin_list: f64,
    /// The grid of the last full build (origin, cell size, cells), its items' face ids (by the
    /// build's face index), and the faces made since (not in the grid).
    grid_lo: [f64; 2],
    grid_h: f64,
    grid_n: [usize; 2],
    grid_ids: Vec<u32>,
    /// Faces made since the last full build, by grid cell (face ids).
    grid_extra: Vec<Vec<u32>>,
    /// Local updates of the Verlet list at splits so far (cohesive laws).
    pub patches: u64,
    dirty: bool,
    /// The open pairs (checkpoint this).
    pub history: ContactHistory,
    next: Vec<Pair>,
    geo: Vec<Geo>,
    /// The faces' current end positions `[x_a, y_a, x_b, y_b]` (parallel to `faces`), filled
    /// once per step by the narrow phase: a face is met by several slaves' candidate lists, and
    /// its ends' gathers from `x0` and `u` were the search's cost (session 36).
    fpos: Vec<[f64; 4]>,
    kin: Vec<PairKinematics>,
    st: Vec<PairState>,
    out: Vec<PairForce>,
    reports: Vec<PairReport>,
    cell_count: Vec<u32>,
    cell_items: Vec<u32>,
    /// Energy of the springs of the pairs lost in this step's narrow phase.
    released: f64,
    /// The surfaces changed since the last narrow phase: pairs' areas are recomputed.
    areas_stale: bool,
    /// Number of Verlet-list builds so far.
    pub rebuilds: u64,
    /// Pairs in contact after the last step.
    pub n_active: usize,
    /// Fracture energy dissipated in the last step (the laws' [`PairForce::fracture`]).
    pub fracture_step: f64,
    /// Cohesion that left crack faces without dissipation (issue 36; [`CohesionAccount`]).
    pub cohesion: CohesionAccount,
    /// The law has cohesion: crack faces carry it per face end ([`Bond`], module doc).
    per_face: bool,
    /// The cohesive faces still holding (checkpoint section `contact_bonds`).
    pub bonds: Vec<Bond>,
    /// The faces held by bonds, by face index (parallel to `faces`): bit `k` set when a live
    /// bond's edge has this face on one of its sides and the bond's end is the face's end `k`
    /// (`pts[k]`). The contact search leaves such a face to the bonds at that point (review
    /// r17: a node's search met the face its neighbour's bond holds, and a node pair carried
    /// 3 k A in compression). Per face, so that the narrow phase asks it in O(1) (session 36:
    /// before, a binary search of a sorted (face, point) list per candidate). Refreshed when
    /// the bonds or the faces change.
    held: Vec<u8>,
    /// (slave face, mesh point) of each bond (parallel to `bonds`).
    bond_meta: Vec<(u32, u32)>,
    /// The bond of each batch entry from `n_pairs` on.
    bond_at: Vec<u32>,
    n_pairs: usize,
}

/// The force of one pair after a step, for tests and output.
#[derive(Copy, Clone, Debug)]
pub struct PairReport {
    pub slave: u32,
    pub master: Master,
    /// Force on the slave (global frame).
    pub force: [f64; 2],
    pub gap: f64,
}

/// What [`Contact::restore_verlet`] needs to rebuild the Verlet list of a checkpoint: the
/// surface displacements at the last build (slave order), whether a rebuild was pending, and
/// the rebuild count.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct VerletState {
    pub u_build: Vec<[f64; 2]>,
    pub dirty: bool,
    pub rebuilds: u64,
}

/// The margin of a Verlet list that splits updated locally (cohesive laws, session 18):
/// `(margin_list, lmax_list, skin_list)`, checkpoint section `contact_verlet_margin`, so that a
/// resumed run rebuilds the same list (every face within that margin of each slave's build
/// position) and rebuilds it again at the same step.
pub type VerletMargin = (f64, f64, f64);

impl Contact {
    /// Builds the surfaces of a model (after pre-separated edges were cut).
    pub fn new(cfg: &ContactCfg, model: &Model, file: &str) -> Result<Contact> {
        let ne = model.topo.edges.len();
        let mut declared = vec![false; ne];
        for (k, name) in cfg.surfaces.iter().enumerate() {
            for e in model.edge_set(name, &format!("contact.surfaces[{k}]"), file)? {
                declared[e.idx()] = true;
            }
        }
        let mut c = Contact {
            declared,
            fresh_edge: vec![false; ne],
            crack_faces: cfg.crack_faces,
            boundary: cfg.boundary,
            max_depth: cfg.max_depth,
            skin_cfg: cfg.skin,
            skin: 0.0,
            faces: Vec::new(),
            face_of_id: Vec::new(),
            slaves: Vec::new(),
            slave_pt: Vec::new(),
            cluster_pt: Vec::new(),
            side_off: Vec::new(),
            side: Vec::new(),
            area: Vec::new(),
            cand_off: Vec::new(),
            cand: Vec::new(),
            ub: Vec::new(),
            margin_list: 0.0,
            lmax_list: 0.0,
            skin_list: 0.0,
            grid_lo: [0.0; 2],
            grid_h: 1.0,
            grid_n: [0; 2],
            grid_ids: Vec::new(),
            grid_extra: Vec::new(),
            patches: 0,
            dirty: true,
            history: ContactHistory::default(),
            next: Vec::new(),
            geo: Vec::new(),
            fpos: Vec::new(),
            kin: Vec::new(),
            st: Vec::new(),
            out: Vec::new(),
            reports: Vec::new(),
            cell_count: Vec::new(),
            cell_items: Vec::new(),
            released: 0.0,
            areas_stale: true,
            rebuilds: 0,
            n_active: 0,
            fracture_step: 0.0,
            cohesion: CohesionAccount::default(),
            per_face: cfg.law.unreleased(&PairState { fresh: true, ..Default::default() }) > 0.0,
            bonds: Vec::new(),
            held: Vec::new(),
            bond_meta: Vec::new(),
            bond_at: Vec::new(),
            n_pairs: 0,
        };
        c.rebuild_surfaces(model);
        Ok(c)
    }

    /// Number of slave nodes (surface nodes).
    pub fn n_surface_nodes(&self) -> usize {
        self.slaves.len()
    }
    pub fn n_faces(&self) -> usize {
        self.faces.len()
    }

    fn rebuild_surfaces(&mut self, model: &Model) {
        let topo = &model.topo;
        self.faces.clear();
        let push = |e: ElemId, k: u8, faces: &mut Vec<Face>| {
            let r = topo.elem_copies(e);
            let n = r.len();
            let cl = |a: usize| topo.copy_cluster[r.start + a].0;
            let mut elem = [NONE; 4];
            for (a, x) in elem.iter_mut().enumerate().take(n) {
                *x = cl(a);
            }
            let (pa, pb) = (topo.copy_point[r.start + k as usize], topo.copy_point[r.start + (k as usize + 1) % n]);
            let (a, b) = (cl(k as usize), cl((k as usize + 1) % n));
            let mut across = [NONE; 2];
            for (x, (p, own)) in across.iter_mut().zip([(pa, a), (pb, b)]) {
                if let Some(c) = cluster_across(topo, e, pa, pb, p, own) {
                    *x = c;
                }
            }
            faces.push(Face { id: 4 * e.0 + k as u32, a, b, elem, pts: [pa.0, pb.0], across });
        };
        for (ei, ed) in topo.edges.iter().enumerate() {
            let on = match ed.sides {
                [Some(_), None] => self.boundary || self.declared[ei],
                _ => self.declared[ei] || (self.crack_faces && topo.crack_state(EdgeId::new(ei)) >= 1),
            };
            if on {
                for (e, k) in ed.sides.iter().flatten() {
                    push(*e, *k, &mut self.faces);
                }
            }
        }
        self.faces.sort_by_key(|f| f.id);
        self.face_of_id.clear();
        self.face_of_id.resize(4 * topo.n_elems(), NONE);
        for (i, f) in self.faces.iter().enumerate() {
            self.face_of_id[f.id as usize] = i as u32;
        }
        self.refresh_held();
        let x0 = |c: u32| model.mesh.points[topo.cluster_point[c as usize].idx()];
        let mut per: Vec<(u32, f64, [f64; 2])> = Vec::with_capacity(2 * self.faces.len());
        let mut total_len = 0.0;
        for f in &self.faces {
            let (p, q) = (x0(f.a), x0(f.b));
            let len = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt();
            total_len += len;
            let half = 0.5 * len * model.material_of(ElemId(f.id / 4)).thickness;
            let n = if len > 0.0 { [(q[1] - p[1]) / len, -(q[0] - p[0]) / len] } else { [0.0; 2] };
            per.push((f.a, half, n));
            per.push((f.b, half, n));
        }
        per.sort_by_key(|a| a.0);
        self.side.clear();
        self.side_off.clear();
        self.side_off.push(0);
        for (k, &(c, half, n)) in per.iter().enumerate() {
            self.side.push((n, half));
            if per.get(k + 1).is_none_or(|x| x.0 != c) {
                self.side_off.push(self.side.len() as u32);
            }
        }
        let per: Vec<(u32, f64)> = per.into_iter().map(|(c, h, _)| (c, h)).collect();
        self.slaves.clear();
        self.slave_pt.clear();
        self.area.clear();
        for (c, a) in per {
            if self.slaves.last() == Some(&c) {
                *self.area.last_mut().unwrap() += a;
            } else {
                self.slaves.push(c);
                self.slave_pt.push(topo.cluster_point[c as usize].0);
                self.area.push(a);
            }
        }
        let mean = if self.faces.is_empty() { 1.0 } else { total_len / self.faces.len() as f64 };
        self.skin = self.skin_cfg.unwrap_or(0.2 * mean);
        self.dirty = true;
        self.areas_stale = true;
        self.cluster_pt.clear();
        self.cluster_pt.extend(topo.cluster_point.iter().map(|p| p.0));
    }

    /// Follows a split: the faces of newly cut edges become surfaces, fresh (cohesive laws
    /// act on them).
    ///
    /// - Pairs are keyed by slave cluster, and a split may hand the copies that face a pair's
    ///   master to the new cluster: a pair whose slave was split and lies at an end of its
    ///   master face is re-keyed to the part (parent or new cluster) across that face's edge at
    ///   that point (the only node there that faces it), so its history (e_n, e_s, largest opening) stays with the
    ///   node that carries it.
    /// - A fresh pair is created only at the end where an edge was cut in this split, where
    ///   both faces are still at the same place (gap 0, no stored energy). The other end of an
    ///   edge cut earlier has opened already: a pair born there with an empty history would
    ///   count the whole opening as if the law had acted over it (stored and released energy
    ///   out of nothing) and pull again across a gap that opened free of traction.
    ///
    /// With a law that has cohesion (bonds, module doc) the Verlet list is then updated locally
    /// ([`Contact::patch_verlet`]: the split's nodes and the faces it made) instead of rebuilt
    /// over every crack face at the next step; `x0`, `u` are the clusters' reference positions
    /// and displacements after the split.
    pub fn on_split(&mut self, law: &dyn ContactLaw, model: &Model, rec: &SplitRecord, x0: &[[f64; 2]], u: &[[f64; 2]]) {
        for &(e, _) in &rec.cut_edges {
            if !self.fresh_edge[e.idx()] {
                self.fresh_edge[e.idx()] = true;
                self.history.fresh_edges.push(e.0);
            }
        }
        let can_patch = self.per_face && !self.dirty && self.rebuilds > 0 && rec.moved.is_empty() && x0.len() == model.topo.n_clusters() && u.len() == x0.len();
        let before = can_patch.then(|| (self.slaves.clone(), self.faces.iter().map(|f| f.id).collect::<Vec<u32>>(), std::mem::take(&mut self.cand_off), std::mem::take(&mut self.cand)));
        self.rebuild_surfaces(model);
        // The points the split touched: those with new clusters and the cut edges' ends.
        let mut points: Vec<u32> = rec.new_clusters.iter().map(|nc| nc.point.0).collect();
        points.extend(rec.cut_edges.iter().map(|&(e, end)| model.topo.edges[e.idx()].points[end as usize].0));
        points.sort_unstable();
        points.dedup();
        if let Some((slaves, ids, off, cand)) = before {
            if self.patch_verlet(rec, &points, x0, u, &slaves, &ids, &off, &cand) {
                self.patches += 1;
                self.dirty = false;
            }
        }
        let topo = &model.topo;
        let mut old = std::mem::take(&mut self.history.pairs);
        for p in old.iter_mut() {
            let Master::Face(id) = p.master else { continue };
            let split = |c: u32| rec.new_clusters.iter().any(|nc| nc.parent.0 == p.slave && (nc.id.0 == c || nc.parent.0 == c));
            if let Some(s) = slave_across(model, id, p.slave).filter(|&c| split(c)) {
                p.slave = s;
            }
        }
        old.sort_by_key(|p| (p.slave, p.master));
        for w in old.windows(2) {
            if w[0].slave == w[1].slave {
                self.cohesion.lost_merged += w[1].state.area * law.unreleased(&w[1].state);
            }
        }
        old.dedup_by_key(|p| p.slave);
        let g_f = law.unreleased(&PairState { fresh: true, ..Default::default() });
        let half_area = |e: &crate::mesh::topology::Edge, se: ElemId| {
            let (a, b) = (model.mesh.points[e.points[0].idx()], model.mesh.points[e.points[1].idx()]);
            0.5 * ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt() * model.material_of(se).thickness
        };
        if self.per_face {
            // Cohesion per face end (module doc): bonds follow their node's splits; every end
            // cut now gets its own. The pairs are contact only.
            // Only the points the split touched have new clusters: the bonds elsewhere keep
            // their slaves, and asking the topology for them was the cost of a split on a crack
            // with many bonds (session 36).
            for b in self.bonds.iter_mut() {
                let Some(pt) = topo.edges.get(b.edge as usize).and_then(|ed| ed.points.get(b.end as usize)) else { continue };
                if points.binary_search(&pt.0).is_err() {
                    continue;
                }
                if let Some((s, _, _, _)) = bond_ends(topo, b.edge, b.end) {
                    b.slave = s;
                }
            }
            for &(e, end) in &rec.cut_edges {
                let Some((s, sf, mf, se)) = bond_ends(topo, e.0, end) else { continue };
                if self.face(sf).is_none() || self.face(mf).is_none() || self.bonds.iter().any(|b| b.edge == e.0 && b.end == end) {
                    continue;
                }
                let area = half_area(&topo.edges[e.idx()], se);
                self.bonds.push(Bond { edge: e.0, end, slave: s, master: mf, area, state: PairState { fresh: true, ..Default::default() } });
                self.bond_meta.push((sf, topo.edges[e.idx()].points[end as usize].0));
            }
            self.history.pairs = old;
            self.refresh_held();
            return;
        }
        let mut added: Vec<Pair> = Vec::new();
        let mut cand: Vec<(u32, u32, f64)> = Vec::new();
        for &(e, end) in &rec.cut_edges {
            let ed = &topo.edges[e.idx()];
            let [Some((ea, ka)), Some((eb, kb))] = ed.sides else { continue };
            let (fa, fb) = (4 * ea.0 + ka as u32, 4 * eb.0 + kb as u32);
            if self.face(fa).is_none() || self.face(fb).is_none() {
                continue;
            }
            // One pass (slave on the face of the lower element id): cohesion counted once.
            let (se, me) = if fa < fb { (ea, eb) } else { (eb, ea) };
            let pt = ed.points[end as usize];
            let (Some(cs), Some(cm)) = (topo.copy_at(se, pt), topo.copy_at(me, pt)) else { continue };
            let (s, m) = (topo.copy_cluster[cs.idx()].0, topo.copy_cluster[cm.idx()].0);
            if s == m {
                self.cohesion.unpaired += g_f * half_area(ed, se);
                continue;
            }
            let (sf, mf) = if fa < fb { (fa, fb) } else { (fb, fa) };
            added.push(Pair { slave: s, master: Master::Face(mf), state: PairState { fresh: true, ..Default::default() } });
            cand.push((s, sf, g_f * half_area(ed, se)));
        }
        added.sort_by_key(|p| (p.slave, p.master));
        added.dedup_by_key(|p| p.slave);
        // The slave's one pair (the old one, else the first added) carries the faces that face
        // its master (`facing_area`); a cut end whose face does not gets no cohesion.
        for &(s, sf, a) in &cand {
            let (keep, cohesive) = match old.binary_search_by_key(&s, |p| p.slave) {
                Ok(i) => (old[i].master, law.unreleased(&old[i].state) > 0.0),
                Err(_) => (added[added.binary_search_by_key(&s, |p| p.slave).unwrap_or(0)].master, true),
            };
            if !cohesive {
                // The slave's pair is contact only (its cohesion spent, or never had one): it
                // is kept, and the new face gets no cohesion.
                self.cohesion.unpaired_contact += a;
            } else if !self.faces_face(model, sf, keep) {
                self.cohesion.unpaired += a;
            }
        }
        let history = &mut self.history;
        let (mut i, mut j) = (0, 0);
        while i < old.len() || j < added.len() {
            if j == added.len() || (i < old.len() && old[i].slave <= added[j].slave) {
                if j < added.len() && old[i].slave == added[j].slave {
                    j += 1;
                }
                history.pairs.push(old[i]);
                i += 1;
            } else {
                history.pairs.push(added[j]);
                j += 1;
            }
        }
    }

    /// Restores a checkpointed history (the model's topology must already be the checkpoint's):
    /// surfaces are rebuilt and the Verlet list is rebuilt at the next step, unless
    /// [`Contact::restore_verlet`] then rebuilds it as it was at the checkpoint.
    pub fn restore(&mut self, model: &Model, history: ContactHistory) {
        self.fresh_edge.iter_mut().for_each(|f| *f = false);
        for &e in &history.fresh_edges {
            if let Some(f) = self.fresh_edge.get_mut(e as usize) {
                *f = true;
            }
        }
        self.rebuild_surfaces(model);
        self.history = history;
    }

    /// `held` from the bonds and the faces (after either changed). A bond's faces exist while
    /// it lives (a bond is made only between existing faces, and a cut edge keeps its faces).
    fn refresh_held(&mut self) {
        self.held.clear();
        self.held.resize(self.faces.len(), 0);
        for (b, &(sf, pt)) in self.bonds.iter().zip(&self.bond_meta) {
            for f in [b.master, sf] {
                if let Some(&i) = self.face_of_id.get(f as usize).filter(|&&i| i != NONE) {
                    let fc = &self.faces[i as usize];
                    self.held[i as usize] |= (fc.pts[0] == pt) as u8 | (((fc.pts[1] == pt) as u8) << 1);
                }
            }
        }
    }

    /// The master face of bond `b` when its end is separated (the slave is not the face's own
    /// node there); `None` before (a cut edge's end can be listed before its node separates:
    /// the bond waits, unevaluated and not counted as a face).
    #[inline]
    fn bond_face(&self, b: &Bond) -> Option<Face> {
        self.bond_face_at(b).map(|i| self.faces[i])
    }

    /// [`Contact::bond_face`]'s index into `faces`.
    #[inline]
    fn bond_face_at(&self, b: &Bond) -> Option<usize> {
        let i = *self.face_of_id.get(b.master as usize).filter(|&&i| i != NONE)? as usize;
        let fc = &self.faces[i];
        (b.slave != fc.a && b.slave != fc.b).then_some(i)
    }

    /// Restores the checkpointed bonds (after [`Contact::restore`]); their slaves are re-read
    /// from the topology. A bond that names no cut edge end with two sides, or no crack face as
    /// its master, or an area that is not finite and positive, is refused (a corrupt or foreign
    /// checkpoint: the message names the bond), and nothing is restored.
    pub fn restore_bonds(&mut self, model: &Model, mut bonds: Vec<Bond>) -> Result<(), String> {
        let mut meta = Vec::with_capacity(bonds.len());
        for (i, b) in bonds.iter_mut().enumerate() {
            let Some((s, sf, _, _)) = bond_ends(&model.topo, b.edge, b.end) else {
                return Err(format!("cohesive bond {i} names edge {} end {}, which is not an edge with two sides in this mesh", b.edge, b.end));
            };
            if self.face(b.master).is_none() || !(b.area.is_finite() && b.area > 0.0) {
                return Err(format!("cohesive bond {i} (edge {} end {}) has master face {} and area {}: not a crack face of this run, or not a positive area", b.edge, b.end, b.master, b.area));
            }
            b.slave = s;
            meta.push((sf, model.topo.edges[b.edge as usize].points[b.end as usize].0));
        }
        self.bonds = bonds;
        self.bond_meta = meta;
        self.refresh_held();
        Ok(())
    }

    /// Whether crack faces carry cohesion per face end ([`Bond`]; the law has cohesion).
    pub fn per_face(&self) -> bool {
        self.per_face
    }

    /// The Verlet list's build state, for checkpoints: a resumed run must rebuild its list at
    /// the same steps and from the same positions as the uninterrupted one, because the
    /// candidate set (all faces within the margin at the build) is a superset that depends on
    /// when it was built, and the concave-corner test counts every penetrated candidate face.
    pub fn verlet_state(&self) -> VerletState {
        let u_build = if self.slaves.iter().all(|&s| (s as usize) < self.ub.len()) { self.slaves.iter().map(|&s| self.ub[s as usize]).collect() } else { Vec::new() };
        VerletState { u_build, dirty: self.dirty, rebuilds: self.rebuilds }
    }

    /// The margin of the list now (checkpoint section `contact_verlet_margin`, cohesive laws).
    pub fn verlet_margin(&self) -> VerletMargin {
        (self.margin_list, self.lmax_list, self.skin_list)
    }

    /// Rebuilds the Verlet list as it was at the checkpoint (after [`Contact::restore`]): from
    /// the saved surface displacements, so the list and its next rebuild step are the
    /// uninterrupted run's. A state that does not fit the surfaces leaves the list dirty.
    pub fn restore_verlet(&mut self, x0: &[[f64; 2]], st: VerletState, margin: Option<VerletMargin>) {
        if !st.dirty && st.u_build.len() == self.slaves.len() && self.slaves.iter().all(|&s| (s as usize) < x0.len()) {
            let mut u = vec![[0.0; 2]; x0.len()];
            for (&s, b) in self.slaves.iter().zip(&st.u_build) {
                u[s as usize] = *b;
            }
            self.build_verlet_with(x0, &u, margin.filter(|_| self.per_face));
        } else {
            self.dirty = true;
        }
        self.rebuilds = st.rebuilds;
    }

    /// For tests (review r18: the local update had no check against a full rebuild): the
    /// Verlet list compared with what a full build at the same build configuration `x0 + ub`
    /// and the same margin gives, found here by brute force over every slave and face (no
    /// grid): for every slave, every face not excluded (its own element's, or met only at a
    /// vertex) within `margin_list` of it, in face order. `None` when they are the same (or
    /// the list is pending a rebuild), else a description of the first slave that differs.
    /// O(slaves x faces): not for production runs.
    #[doc(hidden)]
    pub fn verlet_list_mismatch(&self, x0: &[[f64; 2]]) -> Option<String> {
        if self.dirty || self.cand_off.len() != self.slaves.len() + 1 || self.slaves.iter().any(|&s| s as usize >= self.ub.len() || s as usize >= x0.len()) {
            return None;
        }
        let xb = |c: u32| [x0[c as usize][0] + self.ub[c as usize][0], x0[c as usize][1] + self.ub[c as usize][1]];
        let m2 = self.margin_list * self.margin_list;
        let mut want: Vec<u32> = Vec::new();
        for (i, (&s, &sp)) in self.slaves.iter().zip(&self.slave_pt).enumerate() {
            want.clear();
            let p = xb(s);
            for (fi, f) in self.faces.iter().enumerate() {
                if f.elem.contains(&s) || f.vertex_only(s, sp) {
                    continue;
                }
                if dist2_segment(p, xb(f.a), xb(f.b)) <= m2 {
                    want.push(fi as u32);
                }
            }
            let have = &self.cand[self.cand_off[i] as usize..self.cand_off[i + 1] as usize];
            if have != want.as_slice() {
                let ids = |l: &[u32]| l.iter().map(|&fi| self.faces.get(fi as usize).map_or(u32::MAX, |f| f.id)).collect::<Vec<u32>>();
                return Some(format!(
                    "slave {s} (point {sp}): list has faces {:?}, a full build at the same positions {:?} (margin {:.3e}, {} patches, {} rebuilds)",
                    ids(have),
                    ids(&want),
                    self.margin_list,
                    self.patches,
                    self.rebuilds
                ));
            }
        }
        None
    }

    /// For tests (session 36): the search's caches against what they are made from. `held`
    /// against a search of the bonds for both ends of every face, and every bond's slave
    /// against the topology (`on_split` asks the topology only for the bonds at the points a
    /// split touched). `None` when they agree, else the first difference.
    #[doc(hidden)]
    pub fn cache_mismatch(&self, model: &Model) -> Option<String> {
        if self.held.len() != self.faces.len() {
            return Some(format!("held has {} entries for {} faces", self.held.len(), self.faces.len()));
        }
        for (fi, fc) in self.faces.iter().enumerate() {
            for k in 0..2 {
                let want = self.bonds.iter().zip(&self.bond_meta).any(|(b, &(sf, pt))| pt == fc.pts[k] && (b.master == fc.id || sf == fc.id));
                if (self.held[fi] >> k) & 1 == 1 {
                    if !want {
                        return Some(format!("face {} end {k} (point {}) marked held, no bond there", fc.id, fc.pts[k]));
                    }
                } else if want {
                    return Some(format!("face {} end {k} (point {}) held by a bond, not marked", fc.id, fc.pts[k]));
                }
            }
        }
        for b in &self.bonds {
            if let Some((s, _, _, _)) = bond_ends(&model.topo, b.edge, b.end) {
                if s != b.slave {
                    return Some(format!("bond at edge {} end {}: slave {} kept, the topology says {s}", b.edge, b.end, b.slave));
                }
            }
        }
        None
    }

    fn face(&self, id: u32) -> Option<Face> {
        match self.face_of_id.get(id as usize) {
            Some(&i) if i != NONE => Some(self.faces[i as usize]),
            _ => None,
        }
    }

    /// Squared contact frequency bound for the stable step: `4 k A_max / m_min` over surface
    /// nodes (each node carries its own pair and the pairs of the slaves on its faces; the
    /// relative motion of two nodes doubles the rate), so `dt <= 2 / omega` includes
    /// `2 sqrt(m / k_n)` per contact.
    ///
    /// With `crack_faces`, splits during the run create new surface nodes, lighter than any
    /// node now; the bound then also covers every element corner as if it were a node of its
    /// own with both its element edges as faces (`4 k (L1 + L2) t / 2 / m_corner`), so the step
    /// chosen at the start stays stable after any split.
    pub fn omega2(&self, model: &Model, mass: &[f64], fix: &[u8], k: f64) -> f64 {
        let mut a_max: f64 = 0.0;
        let mut m_min = f64::INFINITY;
        for (&s, &a) in self.slaves.iter().zip(&self.area) {
            a_max = a_max.max(a);
            if fix[s as usize] != 3 && mass[s as usize] > 0.0 {
                m_min = m_min.min(mass[s as usize]);
            }
        }
        let mut w2 = if m_min.is_finite() { 4.0 * k * a_max / m_min } else { 0.0 };
        if self.crack_faces {
            for b in &model.blocks {
                let (rho, t) = (b.material().density, b.material().thickness);
                for i in 0..b.len() {
                    let x = b.coords(i);
                    let mut m4 = [0.0; 4];
                    if let Some(k) = registry::find(b.element()).or_else(|| registry::default_for(b.kind())) {
                        k.lumped_mass(x, rho, t, &mut m4);
                    }
                    let m = &m4[..x.len()];
                    let n = x.len();
                    let len = |a: usize, b: usize| ((x[a][0] - x[b][0]).powi(2) + (x[a][1] - x[b][1]).powi(2)).sqrt();
                    for (a, &ma) in m.iter().enumerate() {
                        let area = 0.5 * (len(a, (a + 1) % n) + len(a, (a + n - 1) % n)) * t;
                        if ma > 0.0 {
                            w2 = w2.max(4.0 * k * area / ma);
                        }
                    }
                }
            }
        }
        w2
    }

    /// Rebuilds the Verlet list: for every slave, the faces (not of its own element) within
    /// `max_depth x L_max + skin` of it, ascending.
    pub fn build_verlet(&mut self, x0: &[[f64; 2]], u: &[[f64; 2]]) {
        self.build_verlet_with(x0, u, None);
    }

    /// [`Contact::build_verlet`], with the margin of a checkpointed list when given.
    fn build_verlet_with(&mut self, x0: &[[f64; 2]], u: &[[f64; 2]], given: Option<VerletMargin>) {
        self.rebuilds += 1;
        self.dirty = false;
        let x = |c: u32| [x0[c as usize][0] + u[c as usize][0], x0[c as usize][1] + u[c as usize][1]];
        self.ub.resize(x0.len().max(self.ub.len()), [0.0; 2]);
        for &s in &self.slaves {
            self.ub[s as usize] = u[s as usize];
        }
        self.grid_extra.iter_mut().for_each(|c| c.clear());
        self.grid_ids.clear();
        self.grid_ids.extend(self.faces.iter().map(|f| f.id));
        self.cand_off.clear();
        self.cand.clear();
        self.cand_off.push(0);
        if self.faces.is_empty() {
            self.cand_off.resize(self.slaves.len() + 1, 0);
            return;
        }
        let (mut lo, mut hi, mut lmax) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2], 0.0f64);
        for f in &self.faces {
            let (p, q) = (x(f.a), x(f.b));
            lmax = lmax.max(((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt());
            for d in 0..2 {
                lo[d] = lo[d].min(p[d].min(q[d]));
                hi[d] = hi[d].max(p[d].max(q[d]));
            }
        }
        let mut margin = self.max_depth * lmax + self.skin;
        (self.margin_list, self.lmax_list, self.skin_list) = (margin, lmax, self.skin);
        if let Some((m, l, s)) = given {
            (margin, self.margin_list, self.lmax_list, self.skin_list) = (m, m, l, s);
        }
        let mut h = lmax + 2.0 * margin;
        let cap = 4 * self.faces.len() + 64;
        for d in 0..2 {
            lo[d] -= margin;
            hi[d] += margin;
        }
        let dims = |h: f64| [((hi[0] - lo[0]) / h).floor() as usize + 1, ((hi[1] - lo[1]) / h).floor() as usize + 1];
        while dims(h)[0] * dims(h)[1] > cap {
            h *= 1.5;
        }
        let [nx, ny] = dims(h);
        (self.grid_lo, self.grid_h, self.grid_n) = (lo, h, [nx, ny]);
        if self.per_face {
            self.grid_extra.resize(nx * ny, Vec::new());
        }
        let cell = |p: [f64; 2]| -> Option<usize> {
            let (i, j) = (((p[0] - lo[0]) / h).floor(), ((p[1] - lo[1]) / h).floor());
            (i >= 0.0 && j >= 0.0 && (i as usize) < nx && (j as usize) < ny).then(|| j as usize * nx + i as usize)
        };
        let range = |f: &Face| {
            let (p, q) = (x(f.a), x(f.b));
            let c = |v: f64, o: f64, n: usize| (((v - o) / h).floor().max(0.0) as usize).min(n - 1);
            (c(p[0].min(q[0]) - margin, lo[0], nx), c(p[0].max(q[0]) + margin, lo[0], nx), c(p[1].min(q[1]) - margin, lo[1], ny), c(p[1].max(q[1]) + margin, lo[1], ny))
        };
        // Counting sort of faces into cells (each cell's list ascending by face index).
        self.cell_count.clear();
        self.cell_count.resize(nx * ny + 1, 0);
        for f in &self.faces {
            let (i0, i1, j0, j1) = range(f);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    self.cell_count[j * nx + i + 1] += 1;
                }
            }
        }
        for k in 0..nx * ny {
            self.cell_count[k + 1] += self.cell_count[k];
        }
        self.cell_items.clear();
        self.cell_items.resize(self.cell_count[nx * ny] as usize, 0);
        let mut cursor: Vec<u32> = self.cell_count[..nx * ny].to_vec();
        for (fi, f) in self.faces.iter().enumerate() {
            let (i0, i1, j0, j1) = range(f);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let k = j * nx + i;
                    self.cell_items[cursor[k] as usize] = fi as u32;
                    cursor[k] += 1;
                }
            }
        }
        let m2 = margin * margin;
        for (&s, &sp) in self.slaves.iter().zip(&self.slave_pt) {
            let p = x(s);
            if let Some(k) = cell(p) {
                for &fi in &self.cell_items[self.cell_count[k] as usize..self.cell_count[k + 1] as usize] {
                    let f = &self.faces[fi as usize];
                    if f.elem.contains(&s) || f.vertex_only(s, sp) {
                        continue;
                    }
                    if dist2_segment(p, x(f.a), x(f.b)) <= m2 {
                        self.cand.push(fi);
                    }
                }
            }
            self.cand_off.push(self.cand.len() as u32);
        }
    }

    /// The grid cells (of the last full build) that a box `[lo, hi]` covers, clamped to the
    /// grid: `(i0, i1, j0, j1)`. A point outside the grid maps to the border cell nearest it,
    /// which every face within the margin of the point covers too (a face's margin box that
    /// holds the point and meets the grid holds the point's projection onto the grid).
    fn cells_of(&self, lo: [f64; 2], hi: [f64; 2]) -> (usize, usize, usize, usize) {
        let [nx, ny] = self.grid_n;
        let c = |v: f64, o: f64, n: usize| (((v - o) / self.grid_h).floor().max(0.0) as usize).min(n - 1);
        (c(lo[0], self.grid_lo[0], nx), c(hi[0], self.grid_lo[0], nx), c(lo[1], self.grid_lo[1], ny), c(hi[1], self.grid_lo[1], ny))
    }

    /// Updates the Verlet list locally after a split (cohesive laws; session 18: the full
    /// rebuild at every check that split took a third of the branching plate's time). The list
    /// keeps its meaning: for every slave, every face (not excluded: its own element's, or met
    /// only at a vertex) within `margin_list` of it in the build configuration `x0 + ub`, in
    /// face order. A new node takes its parent's build displacement (it is a copy of it, at the
    /// same place since the parent's build) or, when the parent was no surface node, its
    /// displacement now; the nodes at the split's points (their exclusions change) and the new
    /// ones are searched again in the grid of the last full build (with the faces added since);
    /// every other slave keeps its list and gains the new faces within the margin. The margin
    /// covers faces as long as the longest one built for (`lmax_list`): a new longer face
    /// shrinks the skin left (`skin_list`), and below half the surfaces' skin the list is
    /// rebuilt in full (returns false, and the next step rebuilds). `slaves`, `ids`, `off`,
    /// `cand`: the list before the split (slaves, face ids by index, candidates).
    ///
    /// The list differs from a full rebuild's only in faces beyond the contact distance (the
    /// superset within the margin depends on where each node was at its build); of the narrow
    /// phase only the concave-corner rule reads those (it counts penetrated faces beyond their
    /// ends), so the pairs found can differ there, rarely. The paper's laws (no cohesion) never
    /// take this path: their lists are rebuilt in full as before.
    #[allow(clippy::too_many_arguments)]
    fn patch_verlet(&mut self, rec: &SplitRecord, points: &[u32], x0: &[[f64; 2]], u: &[[f64; 2]], slaves: &[u32], ids: &[u32], off: &[u32], cand: &[u32]) -> bool {
        if self.grid_n[0] == 0 || self.grid_extra.len() != self.grid_n[0] * self.grid_n[1] || self.faces.is_empty() {
            return false;
        }
        self.ub.resize(x0.len(), [0.0; 2]);
        // Build displacements of the new slaves; which slaves are searched again (the new ones,
        // and those at the split's points, `points`, sorted).
        let root = |mut c: u32| {
            while let Some(nc) = rec.new_clusters.iter().find(|nc| nc.id.0 == c) {
                c = nc.parent.0;
            }
            c
        };
        let n = self.slaves.len();
        let mut touched = vec![false; n];
        let mut k = 0;
        for (i, &s) in self.slaves.iter().enumerate() {
            while k < slaves.len() && slaves[k] < s {
                k += 1;
            }
            if k < slaves.len() && slaves[k] == s {
                touched[i] = points.binary_search(&self.slave_pt[i]).is_ok();
            } else {
                let r = root(s);
                self.ub[s as usize] = if r != s && slaves.binary_search(&r).is_ok() { self.ub[r as usize] } else { u[s as usize] };
                touched[i] = true;
            }
        }
        let xb = |c: u32| [x0[c as usize][0] + self.ub[c as usize][0], x0[c as usize][1] + self.ub[c as usize][1]];
        // The faces made: the longest sets the skin left.
        let mut fresh: Vec<u32> = Vec::new();
        let mut k = 0;
        for (fi, f) in self.faces.iter().enumerate() {
            while k < ids.len() && ids[k] < f.id {
                k += 1;
            }
            if k >= ids.len() || ids[k] != f.id {
                fresh.push(fi as u32);
            }
        }
        let mut lmax = self.lmax_list;
        for &fi in &fresh {
            let f = &self.faces[fi as usize];
            let (p, q) = (xb(f.a), xb(f.b));
            lmax = lmax.max(((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt());
        }
        let skin = self.margin_list - self.max_depth * lmax;
        if skin < 0.5 * self.skin {
            return false;
        }
        let (margin, m2) = (self.margin_list, self.margin_list * self.margin_list);
        // The new faces into the grid (by their build-configuration box and the margin).
        let mut near: Vec<(u32, u32)> = Vec::new();
        for &fi in &fresh {
            let f = self.faces[fi as usize];
            let (p, q) = (xb(f.a), xb(f.b));
            let (i0, i1, j0, j1) = self.cells_of([p[0].min(q[0]) - margin, p[1].min(q[1]) - margin], [p[0].max(q[0]) + margin, p[1].max(q[1]) + margin]);
            let nx = self.grid_n[0];
            for j in j0..=j1 {
                for i in i0..=i1 {
                    self.grid_extra[j * nx + i].push(f.id);
                }
            }
            // The slaves that are not searched again and lie within the margin of the new
            // face: each is an end of a face in the cells the face's margin box covers.
            let mut ends: Vec<u32> = Vec::new();
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let k = j * nx + i;
                    let items = self.cell_items[self.cell_count[k] as usize..self.cell_count[k + 1] as usize].iter().map(|&g| self.grid_ids[g as usize]);
                    for id in items.chain(self.grid_extra[k].iter().copied()) {
                        if let Some(g) = self.face(id) {
                            ends.push(g.a);
                            ends.push(g.b);
                        }
                    }
                }
            }
            ends.sort_unstable();
            ends.dedup();
            for c in ends {
                let Ok(si) = self.slaves.binary_search(&c) else { continue };
                if touched[si] || f.elem.contains(&c) || f.vertex_only(c, self.slave_pt[si]) {
                    continue;
                }
                if dist2_segment(xb(c), p, q) <= m2 {
                    near.push((si as u32, fi));
                }
            }
        }
        near.sort_unstable();
        // The new list, slave by slave.
        let mut new_off = Vec::with_capacity(n + 1);
        let mut new_cand: Vec<u32> = Vec::with_capacity(cand.len() + 16 * fresh.len());
        new_off.push(0u32);
        let (mut k, mut e) = (0, 0);
        for (i, &s) in self.slaves.iter().enumerate() {
            while k < slaves.len() && slaves[k] < s {
                k += 1;
            }
            let start = new_cand.len();
            if touched[i] {
                let (p, sp) = (xb(s), self.slave_pt[i]);
                let (i0, _, j0, _) = self.cells_of(p, p);
                let cell = j0 * self.grid_n[0] + i0;
                let items = self.cell_items[self.cell_count[cell] as usize..self.cell_count[cell + 1] as usize].iter().map(|&g| self.grid_ids[g as usize]);
                for id in items.chain(self.grid_extra[cell].iter().copied()) {
                    let Some(&fi) = self.face_of_id.get(id as usize).filter(|&&fi| fi != NONE) else { continue };
                    let f = &self.faces[fi as usize];
                    if f.elem.contains(&s) || f.vertex_only(s, sp) {
                        continue;
                    }
                    if dist2_segment(p, xb(f.a), xb(f.b)) <= m2 {
                        new_cand.push(fi);
                    }
                }
            } else {
                for &fo in &cand[off[k] as usize..off[k + 1] as usize] {
                    new_cand.push(self.face_of_id[ids[fo as usize] as usize]);
                }
                while e < near.len() && near[e].0 < i as u32 {
                    e += 1;
                }
                while e < near.len() && near[e].0 == i as u32 {
                    new_cand.push(near[e].1);
                    e += 1;
                }
            }
            new_cand[start..].sort_unstable();
            new_off.push(new_cand.len() as u32);
        }
        self.cand_off = new_off;
        self.cand = new_cand;
        (self.lmax_list, self.skin_list) = (lmax, skin);
        true
    }

    fn needs_rebuild(&self, u: &[[f64; 2]]) -> bool {
        if self.dirty || self.slaves.last().is_some_and(|&s| s as usize >= self.ub.len()) {
            return true;
        }
        // A list that splits updated locally (cohesive laws) keeps the skin it was built
        // with (`skin_list`); otherwise the skin of the surfaces now (the paper's scenes).
        let skin = if self.per_face { self.skin_list } else { self.skin };
        let lim = 0.25 * skin * skin;
        self.slaves.iter().any(|&s| {
            let (d, b) = (u[s as usize], self.ub[s as usize]);
            (d[0] - b[0]).powi(2) + (d[1] - b[1]).powi(2) > lim
        })
    }

    /// Geometry of slave at `p` against face `f`: (gap, xi, length, n, t).
    #[inline]
    fn face_geo(p: [f64; 2], xa: [f64; 2], xb: [f64; 2]) -> (f64, f64, f64, [f64; 2], [f64; 2]) {
        let (dx, dy) = (xb[0] - xa[0], xb[1] - xa[1]);
        let len = (dx * dx + dy * dy).sqrt();
        let t = [dx / len, dy / len];
        let n = [t[1], -t[0]];
        let r = [p[0] - xa[0], p[1] - xa[1]];
        (r[0] * n[0] + r[1] * n[1], (r[0] * t[0] + r[1] * t[1]) / len, len, n, t)
    }

    /// One contact step: narrow phase, the law on the batch, forces into `f` (zeroed first).
    /// Returns (stored energy, energy dissipated in this step).
    pub fn compute(&mut self, law: &dyn ContactLaw, x0: &[[f64; 2]], u: &[[f64; 2]], v: &[[f64; 2]], dt: f64, f: &mut [[f64; 2]]) -> (f64, f64) {
        // The first contact step of a run meets the initial overlaps: they are the scene's
        // (parts placed pressed into each other), and the springs take them whole.
        let first = self.rebuilds == 0;
        if self.needs_rebuild(u) {
            self.build_verlet(x0, u);
        }
        self.narrow(law, x0, u, v, dt, first);
        let n = self.geo.len();
        self.out.clear();
        self.out.resize(n, PairForce::default());
        law.evaluate(&self.kin, &mut self.st, &mut self.out);
        f.iter_mut().for_each(|x| *x = [0.0; 2]);
        self.next.clear();
        self.reports.clear();
        let (mut stored, mut diss) = (0.0, self.released);
        self.fracture_step = 0.0;
        for k in 0..n {
            let (g, o) = (&self.geo[k], &self.out[k]);
            diss += o.dissipated;
            self.fracture_step += o.fracture;
            let bond = (k >= self.n_pairs).then(|| self.bond_at[k - self.n_pairs] as usize);
            if !o.active {
                if let Some(bi) = bond {
                    // Opened past delta_f: the face is free (area 0 marks it for removal).
                    self.bonds[bi].area = 0.0;
                }
                continue;
            }
            stored += o.stored;
            let fv = [o.normal * g.n[0] + o.tangential * g.t[0], o.normal * g.n[1] + o.tangential * g.t[1]];
            let s = g.slave as usize;
            f[s][0] += fv[0];
            f[s][1] += fv[1];
            for (c, w) in [(g.i, 1.0 - g.xi), (g.j, g.xi)] {
                f[c as usize][0] -= w * fv[0];
                f[c as usize][1] -= w * fv[1];
            }
            self.st[k].stored = o.stored;
            match bond {
                Some(bi) => self.bonds[bi].state = self.st[k],
                None => self.next.push(Pair { slave: g.slave, master: g.master, state: self.st[k] }),
            }
            self.reports.push(PairReport { slave: g.slave, master: g.master, force: fv, gap: self.kin[k].gap + self.st[k].offset });
        }
        if self.bonds.iter().any(|b| b.area <= 0.0) {
            let mut k = 0;
            self.bond_meta.retain(|_| {
                k += 1;
                self.bonds[k - 1].area > 0.0
            });
            self.bonds.retain(|b| b.area > 0.0);
            self.refresh_held();
        }
        self.n_active = self.reports.len();
        std::mem::swap(&mut self.next, &mut self.history.pairs);
        (stored, diss)
    }

    /// Builds `geo`, `kin`, `st` for this step from the history and the Verlet list.
    fn narrow(&mut self, law: &dyn ContactLaw, x0: &[[f64; 2]], u: &[[f64; 2]], v: &[[f64; 2]], dt: f64, first: bool) {
        self.geo.clear();
        self.kin.clear();
        self.st.clear();
        self.released = 0.0;
        let x = |c: u32| [x0[c as usize][0] + u[c as usize][0], x0[c as usize][1] + u[c as usize][1]];
        self.fpos.clear();
        // Only when some slave has a candidate or a bond holds (a scene whose bodies are apart
        // has neither, and pays nothing per face).
        if !self.cand.is_empty() || !self.bonds.is_empty() {
            self.fpos.extend(self.faces.iter().map(|g| {
                let (a, b) = (x(g.a), x(g.b));
                [a[0], a[1], b[0], b[1]]
            }));
        }
        let mut h = 0usize;
        let pairs = &self.history.pairs;
        for (si, &s) in self.slaves.iter().enumerate() {
            while h < pairs.len() && pairs[h].slave < s {
                h += 1;
            }
            let mut old = (h < pairs.len() && pairs[h].slave == s).then(|| pairs[h]);
            // A face whose edge has a live bond at this slave's point is the bond's (below, in
            // compression too), whichever side's node the bond holds: no contact pair with it;
            // a pair the slave had with it lets its springs go. (Before review r17 only the
            // slave's own bonds' masters were left out: on a crack whose bonds alternate sides,
            // a node pair carried the bonds and both nodes' contact pairs, 3 k A against the
            // 2 k A of `omega2`.)
            let sp = self.slave_pt[si];
            let (held_f, faces, face_of_id) = (&self.held, &self.faces, &self.face_of_id);
            let held = |fi: u32| held_at(held_f, faces, fi as usize, sp);
            let held_id = |f: u32| face_of_id.get(f as usize).is_some_and(|&i| i != NONE && held(i));
            if let Some(o) = old.filter(|o| matches!(o.master, Master::Face(f) if held_id(f))) {
                self.released += o.state.stored;
                old = None;
            }
            let p = x(s);
            let cands = &self.cand[self.cand_off[si] as usize..self.cand_off[si + 1] as usize];
            let mut found: Option<(Geo, f64, PairState, bool)> = None;
            // 1. The pair's own face, or a neighbouring face sharing the end it slid past.
            if let Some(Pair { master: Master::Face(id), state, .. }) = old {
                if let Some(fc) = self.face(id).filter(|fc| !fc.vertex_only(s, self.slave_pt[si])) {
                    let (gap, xi, len, n, t) = Self::face_geo(p, x(fc.a), x(fc.b));
                    if -gap <= self.max_depth * len && (0.0..=1.0).contains(&xi) {
                        found = Some((Geo { slave: s, master: Master::Face(id), i: fc.a, j: fc.b, xi, n, t }, gap, state, false));
                    } else if -gap <= self.max_depth * len {
                        let end = if xi < 0.0 { fc.a } else { fc.b };
                        if (-XI_KEEP..=1.0 + XI_KEEP).contains(&xi) {
                            found = Some((Geo { slave: s, master: Master::Face(id), i: fc.a, j: fc.b, xi: xi.clamp(0.0, 1.0), n, t }, gap, state, false));
                        }
                        for &fi in cands {
                            let g = self.faces[fi as usize];
                            if g.id == id || (g.a != end && g.b != end) || held(fi) {
                                continue;
                            }
                            let (gap, xi, len, n, t) = Self::face_geo(p, x(g.a), x(g.b));
                            if -gap <= self.max_depth * len && (0.0..=1.0).contains(&xi) {
                                found = Some((Geo { slave: s, master: Master::Face(g.id), i: g.a, j: g.b, xi, n, t }, gap, state, false));
                                break;
                            }
                        }
                    }
                }
            }
            // 2. A new contact: the shallowest penetrated face; else a concave corner.
            if found.is_none() {
                let mut best: Option<(f64, Geo)> = None;
                let mut corners: [(u32, u8); 4] = [(NONE, 0); 4];
                for &fi in cands {
                    if held(fi) {
                        continue;
                    }
                    let (g, q) = (self.faces[fi as usize], self.fpos[fi as usize]);
                    let (xa, xb) = ([q[0], q[1]], [q[2], q[3]]);
                    if surely_apart(p, xa, xb, self.max_depth) {
                        continue;
                    }
                    let (gap, xi, len, n, t) = Self::face_geo(p, xa, xb);
                    if gap >= 0.0 || -gap > self.max_depth * len {
                        continue;
                    }
                    if (-XI_NEW..=1.0 + XI_NEW).contains(&xi) {
                        if best.as_ref().is_none_or(|b| -gap < b.0) {
                            best = Some((-gap, Geo { slave: s, master: Master::Face(g.id), i: g.a, j: g.b, xi: xi.clamp(0.0, 1.0), n, t }));
                        }
                    } else {
                        let q = if xi < 0.0 { g.a } else { g.b };
                        if let Some(slot) = corners.iter_mut().find(|c| c.0 == q || c.0 == NONE) {
                            slot.0 = q;
                            slot.1 += 1;
                        }
                    }
                }
                if let Some((pen, g)) = best {
                    let state = match old {
                        Some(o) if o.master == g.master => o.state,
                        _ => PairState::default(),
                    };
                    found = Some((g, -pen, state, !matches!(old, Some(o) if o.master == g.master)));
                } else if let Some(&(q, _)) = corners.iter().find(|c| c.1 >= 2 && c.0 != s && self.cluster_pt[c.0 as usize] != self.slave_pt[si]) {
                    let xq = x(q);
                    let d = ((xq[0] - p[0]).powi(2) + (xq[1] - p[1]).powi(2)).sqrt();
                    if d > 0.0 {
                        let n = [(xq[0] - p[0]) / d, (xq[1] - p[1]) / d];
                        let master = Master::Node(q);
                        let (state, new) = match old {
                            Some(o) if o.master == master => (o.state, false),
                            _ => (PairState::default(), true),
                        };
                        found = Some((Geo { slave: s, master, i: q, j: q, xi: 0.0, n, t: [-n[1], n[0]] }, -d, state, new));
                    }
                }
            }
            let Some((g, gap, mut state, mut new)) = found else {
                // A pair lost by geometry (not opened by its law) lets its springs go: their
                // energy leaves the model, and the ledger counts it as dissipated.
                if let Some(o) = old {
                    self.released += o.state.stored;
                    self.cohesion.lost_geometry += o.state.area * law.unreleased(&o.state);
                }
                continue;
            };
            let (vp, vi, vj) = (v[s as usize], v[g.i as usize], v[g.j as usize]);
            let vr = [vp[0] - (1.0 - g.xi) * vi[0] - g.xi * vj[0], vp[1] - (1.0 - g.xi) * vi[1] - g.xi * vj[1]];
            let vn = vr[0] * g.n[0] + vr[1] * g.n[1];
            let vs = vr[0] * g.t[0] + vr[1] * g.t[1];
            if new {
                if let Some((o, ga)) = old.and_then(|o| self.law_gap(o, p, &x).map(|ga| (o, ga))) {
                    // The slave passed from its master to another (a concave corner, a
                    // junction of cracks): its history carries over as onto a neighbouring
                    // face, and the new master's gap is shifted to continue the old pair's, so
                    // neither an incremental nor a total-gap law sees its springs jump (the
                    // energy of a spring reset to the new face's overlap was made from
                    // nothing, or lost). Cohesion stays with the faces of the split edge.
                    self.cohesion.lost_master += o.state.area * law.unreleased(&o.state);
                    state = PairState { fresh: false, offset: gap - ga, ..o.state };
                    new = false;
                } else if !first {
                    // Born overlapped: the spring counts the approach of this step (the
                    // trapezoidal work sum credits exactly 1/2 f x that approach to a force
                    // that appears in one step); an overlap reached earlier with no pair (the
                    // slave held by another face, or kept off this one by the vertex rule
                    // after a split) is the pair's zero.
                    let depth = (-gap).min((-vn * dt).max(0.0));
                    state.offset = (gap + depth).min(0.0);
                }
            }
            // The facing area depends only on the slave's faces and the master's reference
            // geometry: a pair that keeps its master keeps it until the surfaces change.
            let area = match g.master {
                Master::Face(_) if !self.areas_stale && state.area > 0.0 && old.is_some_and(|o| o.master == g.master) => state.area,
                Master::Face(_) => self.facing_area(si, x0[g.i as usize], x0[g.j as usize]),
                Master::Node(_) => self.area[si],
            };
            if state.area > area {
                self.cohesion.lost_shrunk += (state.area - area) * law.unreleased(&state);
            }
            if state.area > 0.0 && area != state.area {
                // A split gave part of the slave's faces to another node, or the master
                // changed: the springs keep their energy e^2 / (2 k A), not their force (a
                // force kept on half the area would store twice the energy, no work done).
                let r = (area / state.area).sqrt();
                state.en *= r;
                state.es *= r;
            }
            let area_old = state.area;
            state.area = area;
            self.kin.push(PairKinematics { gap: gap - state.offset, dgap: vn * dt, dslip: vs * dt, vn, vs, area, area_old, dt, new });
            self.st.push(state);
            self.geo.push(g);
        }
        self.areas_stale = false;
        // The cohesive faces (bonds), after the pairs: the slave against its master face's
        // line, with the bond's own area and state.
        self.n_pairs = self.geo.len();
        self.bond_at.clear();
        for (bi, b) in self.bonds.iter().enumerate() {
            let Some(fi) = self.bond_face_at(b) else { continue };
            let (fc, q) = (self.faces[fi], self.fpos[fi]);
            let (gap, xi, _, n, t) = Self::face_geo(x(b.slave), [q[0], q[1]], [q[2], q[3]]);
            let g = Geo { slave: b.slave, master: Master::Face(b.master), i: fc.a, j: fc.b, xi: xi.clamp(0.0, 1.0), n, t };
            let (vp, vi, vj) = (v[g.slave as usize], v[g.i as usize], v[g.j as usize]);
            let vr = [vp[0] - (1.0 - g.xi) * vi[0] - g.xi * vj[0], vp[1] - (1.0 - g.xi) * vi[1] - g.xi * vj[1]];
            let vn = vr[0] * g.n[0] + vr[1] * g.n[1];
            let vs = vr[0] * g.t[0] + vr[1] * g.t[1];
            let mut state = b.state;
            let area_old = state.area;
            state.area = b.area;
            self.kin.push(PairKinematics { gap, dgap: vn * dt, dslip: vs * dt, vn, vs, area: b.area, area_old, dt, new: false });
            self.st.push(state);
            self.geo.push(g);
            self.bond_at.push(bi as u32);
        }
    }

    /// The gap the law of pair `o` would see with its slave at `p` now (its master's gap less
    /// its offset); `None` when the master face no longer exists.
    #[inline]
    fn law_gap(&self, o: Pair, p: [f64; 2], x: &impl Fn(u32) -> [f64; 2]) -> Option<f64> {
        let gap = match o.master {
            Master::Face(id) => {
                let f = self.face(id)?;
                Self::face_geo(p, x(f.a), x(f.b)).0
            }
            Master::Node(q) => {
                let xq = x(q);
                -((xq[0] - p[0]).powi(2) + (xq[1] - p[1]).powi(2)).sqrt()
            }
        };
        Some(gap - o.state.offset)
    }

    /// Tributary area of slave `si` against a master face from `xa` to `xb` (reference
    /// positions): half the area of each of the slave's faces that faces the master (reference
    /// normals within 60 degrees of opposite, `n_s . n_m < -1/2`); the whole
    /// tributary area when none does. A node where a crack branches has faces on two cracks:
    /// only those across this master carry this pair, and the area does not change when a
    /// later split adds faces of another crack at the node (a jump of the area of an open
    /// cohesive or penalty pair would change its stored energy with no work done).
    #[inline]
    fn facing_area(&self, si: usize, xa: [f64; 2], xb: [f64; 2]) -> f64 {
        let (dx, dy) = (xb[0] - xa[0], xb[1] - xa[1]);
        let nm = [dy, -dx];
        let lm = (dx * dx + dy * dy).sqrt();
        let mut a = 0.0;
        for &(n, half) in &self.side[self.side_off[si] as usize..self.side_off[si + 1] as usize] {
            if n[0] * nm[0] + n[1] * nm[1] < -0.5 * lm {
                a += half;
            }
        }
        if a > 0.0 {
            a
        } else {
            self.area[si]
        }
    }

    /// The open pairs that hold cohesion (issue 36): `[intact area, softening area, energy
    /// the softening ones have still to release]`. Intact: no energy released yet (the
    /// opening never passed the peak, `delta_0`: an elastic bond, the faces are not a crack
    /// yet); softening: past the peak, short of `delta_f` (the cohesive zone). Laws without
    /// cohesion: zeros. `G_f` is `law.unreleased` of a fresh state.
    pub fn zones(&self, law: &dyn ContactLaw) -> [f64; 3] {
        let g_f = law.unreleased(&PairState { fresh: true, ..Default::default() });
        let mut z = [0.0; 3];
        let bonds = self.bonds.iter().filter(|b| self.bond_face(b).is_some()).map(|b| (b.area, &b.state));
        for (area, st) in self.history.pairs.iter().map(|p| (p.state.area, &p.state)).chain(bonds) {
            let w = law.unreleased(st);
            if w <= 0.0 {
                continue;
            }
            if w >= g_f {
                z[0] += area;
            } else {
                z[1] += area;
                z[2] += area * w;
            }
        }
        z
    }

    /// Whether slave face `sf` faces master `m` in the reference geometry (as `facing_area`:
    /// outward normals within 60 degrees of opposite); a node master: never.
    fn faces_face(&self, model: &Model, sf: u32, m: Master) -> bool {
        let Master::Face(mf) = m else { return false };
        let (Some(a), Some(b)) = (self.face(sf), self.face(mf)) else { return false };
        let n = |f: Face| {
            let (p, q) = (model.mesh.points[f.pts[0] as usize], model.mesh.points[f.pts[1] as usize]);
            let l = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt().max(f64::MIN_POSITIVE);
            [(q[1] - p[1]) / l, -(q[0] - p[0]) / l]
        };
        let (na, nb) = (n(a), n(b));
        na[0] * nb[0] + na[1] * nb[1] < -0.5
    }

    /// The area of the crack faces made during the run (edges split in the run, not the
    /// notch: whole when separated at both ends, half at one; length x thickness), as the
    /// tip tracker's `crack_length` (issue 36).
    pub fn fresh_face_area(&self, model: &Model) -> f64 {
        let topo = &model.topo;
        let mut a = 0.0;
        for &e in &self.history.fresh_edges {
            let ed = &topo.edges[e as usize];
            let (p, q) = (model.mesh.points[ed.points[0].idx()], model.mesh.points[ed.points[1].idx()]);
            let len = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt();
            let th = ed.sides[0].map_or(1.0, |(el, _)| model.material_of(el).thickness);
            a += 0.5 * topo.crack_state(EdgeId(e)) as f64 * len * th;
        }
        a
    }

    /// The force of every active pair in the last step, in slave order.
    pub fn forces(&self) -> &[PairReport] {
        &self.reports
    }
}

/// The cohesive face at end `end` of edge `e` ([`Bond`]): `(slave cluster, slave face, master
/// face, slave element)`; the slave side is the face of lower id (one pass: each face's
/// cohesion counted once). `None` for an edge with one side.
fn bond_ends(topo: &Topology, e: u32, end: u8) -> Option<(u32, u32, u32, ElemId)> {
    let ed = topo.edges.get(e as usize)?;
    let [Some((ea, ka)), Some((eb, kb))] = ed.sides else { return None };
    let (fa, fb) = (4 * ea.0 + ka as u32, 4 * eb.0 + kb as u32);
    let (se, sf, mf) = if fa < fb { (ea, fa, fb) } else { (eb, fb, fa) };
    let cs = topo.copy_at(se, *ed.points.get(end as usize)?)?;
    Some((topo.copy_cluster[cs.idx()].0, sf, mf, se))
}

/// The cluster across master face `id` (element `id / 4`, local edge `id % 4`) at the point
/// of cluster `slave`, when that point is an end of the face and the edge has a second side
/// separated from the face there; `None` otherwise (the pair is then left as it is).
fn slave_across(model: &Model, id: u32, slave: u32) -> Option<u32> {
    let topo = &model.topo;
    let (e, k) = (ElemId(id / 4), (id % 4) as usize);
    let r = topo.elem_copies(e);
    let n = r.len();
    let (pa, pb) = (topo.copy_point[r.start + k], topo.copy_point[r.start + (k + 1) % n]);
    let ps = *topo.cluster_point.get(slave as usize)?;
    if ps != pa && ps != pb {
        return None;
    }
    let own = topo.copy_cluster[topo.copy_at(e, ps)?.idx()].0;
    cluster_across(topo, e, pa, pb, ps, own)
}

/// The cluster of the element across the face of `e` on edge `pa`-`pb`, at its end `p`, when it
/// is not `own` (the face's own cluster there), i.e. when the edge is separated at `p`.
fn cluster_across(topo: &Topology, e: ElemId, pa: PointId, pb: PointId, p: PointId, own: u32) -> Option<u32> {
    let ed = &topo.edges[topo.edge_between(pa, pb)?.idx()];
    let (other, _) = ed.sides.iter().flatten().find(|(x, _)| *x != e).copied()?;
    let c = topo.copy_cluster[topo.copy_at(other, p)?.idx()].0;
    (c != own).then_some(c)
}

/// Whether face `fi` (an index into `faces`) is held by a bond at mesh point `sp` (`held`'s
/// bits against the face's ends).
#[inline]
fn held_at(held: &[u8], faces: &[Face], fi: usize, sp: u32) -> bool {
    let (h, fc) = (held[fi], &faces[fi]);
    (h & 1 != 0 && fc.pts[0] == sp) || (h & 2 != 0 && fc.pts[1] == sp)
}

/// The slave at `p` is surely in front of the face `a`-`b` (gap > 0) or behind it by more than
/// `depth` x its length, decided without a square root or a division: the narrow phase's
/// `gap >= 0 || -gap > depth x len` would reject it too (the margins, 1e-9 relative, are far
/// above the rounding of either form), so skipping it first changes no result; the cases near
/// either bound go on to the exact test.
#[inline]
fn surely_apart(p: [f64; 2], a: [f64; 2], b: [f64; 2], depth: f64) -> bool {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let (u, w) = ((p[0] - a[0]) * dy, (p[1] - a[1]) * dx);
    let gn = u - w;
    let e = 1e-9 * (u.abs() + w.abs());
    gn > e || -gn > depth * (dx * dx + dy * dy) * (1.0 + 1e-9) + e
}

/// Squared distance from `p` to the segment `a`-`b`.
fn dist2_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let s = if l2 > 0.0 { (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0) } else { 0.0 };
    let (qx, qy) = (a[0] + s * dx - p[0], a[1] + s * dy - p[1]);
    qx * qx + qy * qy
}
