//! Cracking (METHOD sections 3-5): nodal stress recovery, failure checks, separation proposals
//! and the one place where splits are applied, in a deterministic order (score, then id).
//!
//! The nodal stress handed to the criterion is the paper's corner mean (METHOD section 3) unless
//! the scene asks for ours, the nonlocal average over a radius (`nonlocal.rs`, docs/nonlocal.md):
//!
//! ```toml
//! [cracking]
//! criterion = { type = "rankine", tensile_strength = 1.0 }
//! separation = { type = "sigma1_nearest" }
//! nonlocal = { radius = 0.5 }
//! ```
pub mod events;
pub mod initiation;
pub mod nonlocal;
pub mod path;
pub mod skip;
pub mod weibull;

use crate::cracking::weibull::weibull_scale;
use crate::element::model::Model;
use crate::ids::{ClusterId, EdgeId, PointId};
use crate::mesh::topology::{SplitRecord, Topology};
use crate::plugin::traits::{principal, principal_values, FailureCheck, FailureMode, FanView, LinkGeom, Principal};
use crate::scene::CrackingCfg;

/// One applied split, for the split log.
#[derive(Clone, Debug)]
pub struct SplitEvent {
    pub time: f64,
    pub step: u64,
    pub point: PointId,
    pub cluster: ClusterId,
    pub new_cluster: ClusterId,
    pub mode: FailureMode,
    pub index: f64,
    /// sigma1 direction, degrees in [0, 180).
    pub sigma1_deg: f64,
    pub edges: Vec<EdgeId>,
    /// Nodal stress at the split, tension positive.
    pub stress: [f64; 3],
}

/// The fractions of a planned tip move tried in turn (the path method, `propose_tip`): the
/// largest the element check admits is made.
const MOVE_FRACTIONS: [f64; 7] = [1.0, 0.875, 0.75, 0.625, 0.5, 0.375, 0.25];

/// Cracking state: strength scatter, buffers and the last failure index per cluster.
pub struct Cracking {
    /// Strength factor per point (1 without scatter).
    pub scale: Vec<f64>,
    corner: Vec<[f64; 3]>,
    /// Copies per cluster (scratch of the nodal average).
    counts: Vec<u32>,
    /// The material of each point (of its first copy's element).
    point_mat: Vec<crate::element::Material>,
    pub nodal: Vec<[f64; 3]>,
    principal: Vec<Principal>,
    scales: Vec<f64>,
    checks: Vec<FailureCheck>,
    /// Failure index of every cluster at the last check.
    pub index: Vec<f64>,
    pub n_splits: usize,
    /// Every cut applied, in order: (cluster, proposed edges). A checkpoint stores it and a
    /// resumed run replays it through `Topology::cut` (checkpoint.rs).
    pub cuts: Vec<(u32, Vec<u32>)>,
    /// The path method's moves and tip lines (ours, issue 34, `path.rs`): empty unless the
    /// separation rule grows tips. A checkpoint keeps it (section "path").
    pub path: path::PathState,
    /// Ours (session 18): the fixity mask, per point: whether it carries a boundary condition (a
    /// support, a point load, a prescribed motion, an end of a loaded face:
    /// `Loads::held_points`), built once at set-up when the rule grows tips; the path method
    /// never moves such a point, except a supported one along its supported straight boundary
    /// (`path::check_move_held`). Empty: no point is held.
    pub path_held: Vec<u8>,
    /// Of `path.refused`, the moves refused because the point is held (`path_held`). A
    /// checkpoint keeps it (section "path_held", written when not zero).
    pub held_refused: u64,
    /// Ours (issue 36): the change of strain energy made by the path method's node moves at
    /// the last check (`Model::strain_energy_at` of the moved node's elements after the move
    /// less before, the displacement kept); the solver takes it into the ledger's
    /// `relocation` term. 0 unless a node moved.
    pub move_strain: f64,
    /// The nonlocal average (`[cracking] nonlocal`, ours); `None`: the paper's corner mean.
    pub nonlocal: Option<nonlocal::Nonlocal>,
    /// The certified skip (ours, issue 24, `skip.rs`): on by default (it changes no result);
    /// `false` evaluates every point at every check.
    pub certified_skip: bool,
    /// Multiplies the skip's margins: 1. Tests only (above 1 the bound is unsafe, and
    /// `tests/skip.rs` shows that its splits then differ).
    pub skip_margin_factor: f64,
    /// Checks evaluated in full and checks skipped (certified).
    pub n_full: u64,
    pub n_skipped: u64,
    skip: skip::Skip,
    margins: Vec<f64>,
    /// The displacement of the last check when it was skipped and a step came after it (its
    /// failure index is computed from it on demand: [`Self::failure_index`]); saved by
    /// [`Self::before_step`] only, so that a check every step copies nothing.
    u_skipped: Vec<[f64; 2]>,
    index_stale: bool,
    u_saved: bool,
    /// Ours (session 33, `[cracking] intact`): per point, whether it may never split (empty:
    /// every point may).
    pub intact: Vec<bool>,
}

impl Cracking {
    /// Builds the cracking state; with `nonlocal` also its neighbour lists (a radius that
    /// catches no Gauss point at some node is refused, naming the key and the node). The
    /// warnings (a radius below the largest element size) are appended to `warnings`.
    pub fn new(cfg: &CrackingCfg, model: &Model, file: &str, warnings: &mut Vec<String>) -> crate::Result<Self> {
        let np = model.topo.n_points;
        let nonlocal = match &cfg.nonlocal {
            Some(nl) => {
                let (mut n, mut w) = nonlocal::Nonlocal::new(nl.radius, nl.weight, model, file)?;
                n.exclusion = nl.exclusion;
                warnings.append(&mut w);
                Some(n)
            }
            None => None,
        };
        let scale = match &cfg.weibull {
            Some(w) => (0..np as u64).map(|p| weibull_scale(w.modulus, w.seed, p)).collect(),
            None => vec![1.0; np],
        };
        Ok(Cracking {
            scale,
            corner: Vec::new(),
            counts: Vec::new(),
            point_mat: Vec::new(),
            nodal: Vec::new(),
            principal: Vec::new(),
            scales: Vec::new(),
            checks: Vec::new(),
            index: vec![0.0; model.topo.n_clusters()],
            n_splits: 0,
            cuts: Vec::new(),
            path: path::PathState::default(),
            path_held: Vec::new(),
            held_refused: 0,
            move_strain: 0.0,
            nonlocal,
            certified_skip: true,
            skip_margin_factor: 1.0,
            n_full: 0,
            n_skipped: 0,
            skip: skip::Skip::default(),
            margins: Vec::new(),
            u_skipped: Vec::new(),
            index_stale: false,
            u_saved: false,
            intact: Vec::new(),
        })
    }

    /// The nodal stress of `u` as [`Self::check`] computes it (the paper's corner mean, or the
    /// nonlocal average), into `out` (the events solver, `solver::events`).
    pub fn nodal_stress_of(&mut self, model: &Model, u: &[[f64; 2]], out: &mut Vec<[f64; 3]>) {
        match &mut self.nonlocal {
            None => model.nodal_stress_with(u, &mut self.corner, out, &mut self.counts),
            Some(nl) => nl.nodal_stress(model, u, out),
        }
    }

    /// The failure index of every cluster at the last check, as a check of every point gives
    /// it: `index` itself, or (the last check was skipped, `skip.rs`) computed here from that
    /// check's displacement. What the output writes (VTU, Python, checkpoints).
    /// `u`: the current displacement (that of the last check unless a step came after it).
    pub fn failure_index(&self, cfg: &CrackingCfg, model: &Model, u: &[[f64; 2]]) -> std::borrow::Cow<'_, [f64]> {
        if !self.index_stale {
            return std::borrow::Cow::Borrowed(&self.index);
        }
        let (mut corner, mut nodal, mut counts) = (Vec::new(), Vec::new(), Vec::new());
        // A skipped check only happens with the corner mean (no nonlocal average).
        let u = if self.u_saved { &self.u_skipped[..] } else { u };
        model.nodal_stress_with(u, &mut corner, &mut nodal, &mut counts);
        let (mut principal, mut scales, mut checks) = (Vec::new(), Vec::new(), Vec::new());
        let point_mat = &self.point_mat;
        Self::evaluate(cfg, model, &nodal, &self.scale, point_mat, &mut principal, &mut scales, &mut checks).expect("a criterion that gave margins evaluates");
        std::borrow::Cow::Owned(checks.iter().map(|c| c.index).collect())
    }

    /// Checks certified by the skip's node tier and by its element pass (`skip.rs`).
    pub fn skip_tiers(&self) -> (u64, u64) {
        (self.skip.n_node_tier, self.skip.n_element_tier)
    }

    /// Called by the solver before a step changes `u`: after a skipped check whose failure
    /// index may be read before the next check, keeps that check's `u`. `check_follows`: the
    /// next check comes right after this step, before anything reads the index (the stage loop
    /// with a check every step): nothing to keep. (Should the step fail, divergence, the index
    /// of that skipped check is then evaluated at the diverged `u`: a run that stops with
    /// `FlemError::Diverged` writes no state.)
    pub fn before_step(&mut self, u: &[[f64; 2]], check_follows: bool) {
        if self.index_stale && !self.u_saved && !check_follows {
            self.u_skipped.clear();
            self.u_skipped.extend_from_slice(u);
            self.u_saved = true;
        }
    }

    /// Principal stresses and the criterion at every cluster (the first half of a check).
    #[allow(clippy::too_many_arguments)]
    fn evaluate(
        cfg: &CrackingCfg,
        model: &Model,
        nodal: &[[f64; 3]],
        scale: &[f64],
        point_mat: &[crate::element::Material],
        principal_out: &mut Vec<Principal>,
        scales: &mut Vec<f64>,
        checks: &mut Vec<FailureCheck>,
    ) -> crate::Result<()> {
        let nc = model.topo.n_clusters();
        principal_out.clear();
        scales.clear();
        // An isotropic criterion decides on the principal values alone: the sigma1 direction
        // (an atan2 per point) is computed, and the criterion asked again, only where it fails.
        let iso = cfg.criterion.isotropic();
        let szz = |c: usize| point_mat[model.topo.cluster_point[c].idx()].szz(nodal[c]);
        for c in 0..nc {
            let s = nodal[c];
            principal_out.push(if iso { principal_values(s, szz(c)) } else { principal(s, szz(c)) });
            scales.push(scale[model.topo.cluster_point[c].idx()]);
        }
        checks.resize(nc, FailureCheck::default());
        cfg.criterion.try_check_batch(principal_out, scales, checks).map_err(crate::FlemError::Other)?;
        if iso {
            for c in 0..nc {
                if checks[c].failed() {
                    principal_out[c] = principal(nodal[c], szz(c));
                    cfg.criterion.try_check_batch(std::slice::from_ref(&principal_out[c]), std::slice::from_ref(&scales[c]), std::slice::from_mut(&mut checks[c])).map_err(crate::FlemError::Other)?;
                }
            }
        }
        Ok(())
    }

    /// Points (clusters) beyond the criterion at the last check that no split relieved: the
    /// separation rule found no edge to cut (e.g. an open fan whose joined edges lie more than
    /// 45 deg from sigma1). The method has no plasticity: these carry stress above their
    /// strength, so an equilibrium with some of them is not a limit state of the material.
    pub fn beyond_criterion(&self) -> usize {
        self.index.iter().filter(|&&x| x >= 1.0).count()
    }

    /// Direction (radians, [0, 2 pi)) of every joined edge of the fan, in the current configuration.
    pub fn link_geometry(topo: &Topology, fan: &crate::mesh::topology::Fan, x0: &[[f64; 2]], u: &[[f64; 2]], out: &mut Vec<LinkGeom>) {
        out.clear();
        let xc = |c: ClusterId| [x0[c.idx()][0] + u[c.idx()][0], x0[c.idx()][1] + u[c.idx()][1]];
        let xp = xc(fan.cluster);
        for l in &fan.links {
            let q = topo.other_end(l.edge, fan.point);
            let e = topo.copy_elem[l.a.idx()];
            let cq = topo.copy_cluster[topo.copy_at(e, q).expect("edge end in element").idx()];
            let xq = xc(cq);
            let (dx, dy) = (xq[0] - xp[0], xq[1] - xp[1]);
            let angle = dy.atan2(dx).rem_euclid(2.0 * std::f64::consts::PI);
            let len = (dx * dx + dy * dy).sqrt().max(f64::MIN_POSITIVE);
            out.push(LinkGeom { edge: l.edge, angle, normal: [-dy / len, dx / len] });
        }
    }

    /// Evaluates the criterion at every cluster and applies the proposed splits, the most
    /// critical first (index descending, then cluster id), at most `max_splits_per_check`.
    /// A plugin that fails or panics (dynamic plugins) gives an error.
    pub fn check(&mut self, cfg: &CrackingCfg, model: &mut Model, u: &[[f64; 2]], x0: &[[f64; 2]], time: f64, step: u64) -> crate::Result<(SplitRecord, Vec<SplitEvent>)> {
        let skippable = self.certified_skip && self.nonlocal.is_none() && skip::Skip::applies(model);
        if skippable && self.skip.certified(model, u, self.cuts.len(), self.skip_margin_factor) {
            // Every point is certified inside the criterion: no split, and the index of this
            // check is computed only if someone reads it.
            self.index_stale = true;
            self.u_saved = false;
            self.n_skipped += 1;
            return Ok((SplitRecord::default(), Vec::new()));
        }
        self.n_full += 1;
        self.index_stale = false;
        let mut nodal = std::mem::take(&mut self.nodal);
        self.nodal_stress_of(model, u, &mut nodal);
        self.nodal = nodal;
        let nc = model.topo.n_clusters();
        // The material of a point (that of its first copy's element) never changes: its
        // out-of-plane factor is looked up once, not through the blocks at every check.
        if self.point_mat.len() != model.topo.n_points {
            self.point_mat = (0..model.topo.n_points).map(|p| model.material_of(model.topo.copy_elem[model.topo.point_copies.row(p)[0].idx()]).clone()).collect();
        }
        Self::evaluate(cfg, model, &self.nodal, &self.scale, &self.point_mat, &mut self.principal, &mut self.scales, &mut self.checks)?;
        if skippable {
            // The margins of this evaluation become the next checks' reference (a split below
            // invalidates it: the reference records the number of cuts).
            self.margins.resize(nc, 0.0);
            let ok = cfg.criterion.margin_batch(&self.principal, &self.scales, &mut self.margins);
            if ok {
                for (m, p) in self.margins.iter_mut().zip(&self.principal) {
                    *m -= skip::Skip::ROUND * (m.abs() + p.s1.abs() + p.s3.abs() + p.s2.abs());
                }
                self.skip.set_reference(model, u, &self.margins, self.cuts.len());
            } else {
                self.skip.invalidate();
            }
        }
        self.index.resize(nc, 0.0);
        let mut cands: Vec<(f64, u32)> = Vec::new();
        for c in 0..nc {
            self.index[c] = self.checks[c].index;
            if self.checks[c].failed() {
                cands.push((self.checks[c].index, c as u32));
            }
        }
        cands.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut rec = SplitRecord::default();
        let mut events = Vec::new();
        let mut links = Vec::new();
        // After the first cut of this check the fans of later candidates may hold the new
        // clusters, which `u` and `x0` (the solver's arrays, grown after the check) do not
        // have yet: they are carried here as the solver will grow them (the parent's u, the
        // point's x0). Indexing `u` by a new cluster panicked with max_splits_per_check > 1.
        let (mut u_ext, mut x_ext): (Vec<[f64; 2]>, Vec<[f64; 2]>) = (Vec::new(), Vec::new());
        // The path method (ours, `path.rs`): only when the rule grows tips.
        let grows = cfg.separation.grows_tips();
        let mut tips: Option<Vec<path::Tip>> = None;
        // The tips' points for `TipContext::tips`, refilled (in the same buffer) only after the
        // tips themselves are found again.
        let (mut tip_pts, mut tip_pts_fresh): (Vec<PointId>, bool) = (Vec::new(), false);
        // The shield (ours, session 27; `SeparationRule::shield_distance`): the crack's edges,
        // found when a candidate first asks and again after a cut, as the tips are.
        let mut crack_segs: Option<Vec<[[f64; 2]; 2]>> = None;
        for (idx, c) in cands {
            if events.len() >= cfg.max_splits_per_check {
                break;
            }
            let mut cid = ClusterId(c);
            let mut tip: Option<path::Tip> = None;
            if grows {
                let t = tips.get_or_insert_with(|| path::tips(&model.topo, &model.mesh.points));
                tip = path::route(t, &model.mesh.points, model.topo.cluster_point[c as usize], cfg.separation.route_radius());
                match tip {
                    Some(t) => cid = model.topo.point_clusters[t.point.idx()][0],
                    // A point on a crack (split), or joined by an edge to one, away from every
                    // tip: the path method grows cracks at their tips only (no branch, no
                    // sliver cut beside a crack).
                    None if path::on_or_beside_crack(&model.topo, model.topo.cluster_point[c as usize]) => continue,
                    // Within the shield of a crack (and not routed to a tip): not cut either, no
                    // new crack beside one (crack tracking's exclusion radius).
                    None if {
                        let p = model.topo.cluster_point[c as usize];
                        let d = cfg.separation.shield_distance(path::size_at(&model.topo, &model.mesh.points, p));
                        d > 0.0 && path::near_crack(crack_segs.get_or_insert_with(|| path::crack_segments(&model.topo, &model.mesh.points)), model.mesh.points[p.idx()], d)
                    } =>
                    {
                        continue
                    }
                    None => {}
                }
            }
            if let (None, Some(nl)) = (tip, &mut self.nonlocal) {
                // Crack tracking: the crack edges cut earlier in this check count too; the
                // failure of a point near a crack splits the nearest crack tip.
                nl.sync(&model.topo, &model.mesh.points);
                match nl.route(&model.topo, cid) {
                    Some(t) => cid = t,
                    None => continue,
                }
            }
            if !self.intact.is_empty() && self.intact[model.topo.cluster_point[cid.idx()].idx()] {
                continue;
            }
            let fan = model.topo.fan(cid);
            if fan.copies.len() < 2 || fan.links.is_empty() {
                continue;
            }
            let (xg, ug) = if u_ext.is_empty() { (x0, u) } else { (&x_ext[..], &u_ext[..]) };
            Self::link_geometry(&model.topo, &fan, xg, ug, &mut links);
            let view = FanView {
                point: fan.point,
                cluster: cid,
                closed: fan.is_closed(),
                never_split: model.topo.point_clusters[fan.point.idx()].len() == 1,
                links: &links,
                stress: self.nodal[c as usize],
                principal: self.principal[c as usize],
            };
            let chk = self.checks[c as usize];
            // The path method's node moves and tip lines of this cut (two of each when the
            // tip forks, `TipPlan::fork`; ours, session 31).
            let mut moved: Vec<(PointId, [f64; 2], [f64; 2])> = Vec::new();
            let mut lines: Vec<(PointId, [f64; 2], f64)> = Vec::new();
            let prop = match tip {
                Some(t) => {
                    let planned = self.path.lines.iter().rev().find(|l| l.point == t.point.0).map(|l| (l.origin, l.dir));
                    if !tip_pts_fresh {
                        tip_pts.clear();
                        tip_pts.extend(tips.as_deref().unwrap_or(&[]).iter().map(|t| t.point));
                        tip_pts_fresh = true;
                    }
                    let ctx = crate::plugin::traits::TipContext { model, u: ug, fan: &view, face: t.face, h: t.h, planned, tips: &tip_pts };
                    let Some(plan) = cfg.separation.propose_tip(&ctx) else { continue };
                    let far = plan.edges.iter().find(|&&e| e != t.face).map(|&e| model.topo.other_end(e, t.point));
                    if let Some(q) = far {
                        lines.push((q, plan.origin, plan.direction));
                    }
                    let mut edges = plan.edges;
                    let mut relocs = [plan.relocate, None];
                    if let Some(fk) = plan.fork {
                        debug_assert!(!edges.contains(&fk.edge), "a fork's second link is not among the plan's edges");
                        lines.push((model.topo.other_end(fk.edge, t.point), fk.origin, fk.direction));
                        edges.push(fk.edge);
                        relocs[1] = fk.relocate;
                    }
                    for (q, to) in relocs.into_iter().flatten() {
                        // The largest of the fractions 1, 7/8, ..., 1/4 of the move (in eighths)
                        // that the element check admits (session 25; before, 1, 1/2 or 1/4: a
                        // coarse quad whose whole move flattened an element moved half-way and its
                        // node stayed 0.5 h off the line, the kink table's one tip out by 6.9 deg).
                        let from = model.mesh.points[q.idx()];
                        let at = |f: f64| [from[0] + f * (to[0] - from[0]), from[1] + f * (to[1] - from[1])];
                        // (A model whose blocks cannot be rebuilt, stateful or co-rotational,
                        // refuses every move: its tips are cut along the nearest link.)
                        // A point that carries a boundary condition (`path_held`) is refused
                        // at once, counted apart (`held_refused`): the link is cut where it lies.
                        // The strain energy the move changes (displacement kept): booked in
                        // the ledger's `relocation` term by the solver (issue 36).
                        let e0 = model.strain_energy_at(q, ug);
                        match MOVE_FRACTIONS.into_iter().map(at).find(|&x| path::check_move_held(model, &self.path_held, q, x).is_ok()).map(|x| (x, model.move_point(q, x))) {
                            Some((x, Ok(()))) => {
                                moved.push((q, from, x));
                                self.move_strain += model.strain_energy_at(q, ug) - e0;
                            }
                            _ => {
                                self.path.refused += 1;
                                self.held_refused += (path::check_move_held(model, &self.path_held, q, to) == Err(path::HELD_MSG)) as u64;
                            }
                        }
                    }
                    crate::plugin::traits::Proposal { edges }
                }
                None => match cfg.separation.try_propose(&view, &chk).map_err(crate::FlemError::Other)? {
                    Some(p) => p,
                    None => continue,
                },
            };
            let mut r = model.topo.cut(cid, &prop.edges, true);
            if r.is_empty() {
                for &(q, from, _) in moved.iter().rev() {
                    let e1 = model.strain_energy_at(q, ug);
                    model.move_point(q, from).map_err(crate::FlemError::Other)?;
                    self.move_strain += model.strain_energy_at(q, ug) - e1;
                }
                continue;
            }
            model.apply_record(&r);
            if grows {
                tips = None;
                tip_pts_fresh = false;
                crack_segs = None;
            }
            for &(q, from, to) in &moved {
                self.path.moves.push(path::PathMove { cut: self.cuts.len() as u32, point: q.0, from, to });
                r.moved.push((q, to));
            }
            for &(q, origin, dir) in &lines {
                self.path.lines.push(path::TipLine { point: q.0, origin, dir });
            }
            if u_ext.is_empty() {
                (u_ext, x_ext) = (u.to_vec(), x0.to_vec());
            }
            for &(q, _, to) in &moved {
                for &k in &model.topo.point_clusters[q.idx()] {
                    if k.idx() < x_ext.len() {
                        x_ext[k.idx()] = to;
                    }
                }
            }
            for nc in &r.new_clusters {
                debug_assert_eq!(nc.id.idx(), u_ext.len());
                u_ext.push(u_ext[nc.parent.idx()]);
                x_ext.push(model.mesh.points[nc.point.idx()]);
            }
            self.cuts.push((cid.0, prop.edges.iter().map(|e| e.0).collect()));
            for nc in &r.new_clusters {
                self.index.push(idx);
                events.push(SplitEvent {
                    time,
                    step,
                    point: fan.point,
                    cluster: cid,
                    new_cluster: nc.id,
                    mode: chk.mode.unwrap_or(FailureMode::Tension),
                    index: idx,
                    sigma1_deg: self.principal[c as usize].theta1.to_degrees(),
                    edges: prop.edges.clone(),
                    stress: self.nodal[c as usize],
                });
            }
            rec.extend(r);
        }
        self.n_splits += events.len();
        Ok((rec, events))
    }
}
