//! The explicit march of a 3D model (issue 38, docs/3d.md): the same central-difference node
//! update as 2D (`NodeCtx<3>`: damping implicit in velocity, the damping plugin's coefficients,
//! the energy ledger's sums), element forces from the model's `Block3`s, dynamic relaxation to
//! the unbalanced-force ratio, and the failure check that splits points along element faces
//! (`Topology3::cut`, the separation rule's `propose_3d`).
//!
//! Contact (`[contact]`): `crate::contact::contact3`, one call in the step (`contact_forces`).
//! Checkpoints: `run_scene_from` resumes at a `Pos3` (`output::checkpoint3` stores the body and
//! replays `cuts`). docs/3d.md says what is left.
//! Every per-node quantity is a flat array indexed by cluster (`State<3>`), every per-copy one
//! by copy: a partition of the mesh later slices them.
use super::{pick_variant, ratio_of, Ledger, NodeCtx, State, NODE_CHUNK, NSUM};
use crate::element::block::Simd;
use crate::element::model3::{build_blocks3, Block3};
use crate::error::{FlemError, Result};
use crate::ids::{ClusterId, ElemId, FaceId};
use crate::mesh::topology3::{SplitRecord3, Topology3};
use crate::mesh::RawMesh3;
use crate::plugin::damping::{Damping, StepStats};
use crate::plugin::traits::{principal3, FailureCheck, FailureCriterion, FanView3, SeparationRule};

/// A support: the points of a node set, the fixed dofs (bits 1: x, 2: y, 4: z) and the velocity
/// of those dofs (0: held).
#[derive(Clone, Debug)]
pub struct Support3 {
    pub points: Vec<u32>,
    pub fix: u8,
    pub velocity: [f64; 3],
}

/// One load of a 3D body at level 1, and its level.
#[derive(Clone, Debug, Default)]
pub struct Load3 {
    pub name: String,
    pub level: f64,
    pub on_copies: Vec<(u32, [f64; 3])>,
    pub on_points: Vec<(u32, [f64; 3])>,
    /// Prescribed velocity: the points, the dof bits and the velocity at level 1.
    pub velocity: Option<(Vec<u32>, u8, [f64; 3])>,
}

/// A 3D body marching in time.
pub struct March3 {
    pub mesh: RawMesh3,
    pub topo: Topology3,
    pub blocks: Vec<Box<dyn Block3>>,
    pub state: State<3>,
    /// The lumped mass of every copy (a cluster's mass is the sum over its copies).
    pub copy_mass: Vec<f64>,
    /// The loads at level 1: each a list of (copy, force) (a pressure's share of a face
    /// belongs to the copy of the element that owns the face, so it follows the right part
    /// when the point splits) and of (point, force) (a point load, on the point's first
    /// cluster).
    pub loads: Vec<Load3>,
    /// Body force per unit mass (gravity), not scaled by the levels.
    pub gravity: [f64; 3],
    /// The external force in force now, per cluster (`rebuild_forces`).
    pub f_const: Vec<[f64; 3]>,
    pub dt: f64,
    pub damping: Box<dyn Damping>,
    pub ledger: Ledger,
    pub(crate) stats: StepStats,
    pub(crate) omega_max: f64,
    partials: Vec<[f64; NSUM]>,
    /// Ratio of the last step.
    pub ratio: f64,
    /// What building the body warned about (reoriented cells).
    pub warnings: Vec<String>,
    /// Every cut of the failure check, in order: (cluster, faces). A checkpoint replays them
    /// (`output::checkpoint3`); the pre-separated face sets are cut again by `from_scene`.
    pub cuts: Vec<(u32, Vec<u32>)>,
    /// Node-to-face contact, only with `[contact]` (`March3::attach_contact`).
    pub contact: Option<crate::contact::contact3::Contact3>,
    /// The threads of the element loop and the node update (`None`: this thread only;
    /// `set_threads`). Results are the same bits whatever it is.
    pub pool: Option<std::sync::Arc<rayon::ThreadPool>>,
}

impl March3 {
    /// A body from a validated 3D mesh: blocks by region (`material_of(region)`: `[young,
    /// poisson, density]` and an element kind name), supports, the damping scheme, and the time
    /// step as a fraction `safety` of the stable step (Gershgorin bound of the lumped system).
    pub fn new(mesh: RawMesh3, material_of: &dyn Fn(&str) -> Result<([f64; 3], Option<String>)>, supports: &[Support3], damping: Box<dyn Damping>, safety: f64) -> Result<March3> {
        let topo = Topology3::new(&mesh);
        let blocks = build_blocks3(&mesh, &topo, material_of)?;
        let nc = topo.n_clusters();
        let mut copy_mass = vec![0.0; topo.copy_point.len()];
        for b in &blocks {
            b.corner_masses(&topo.elem_first_copy, &mut copy_mass);
        }
        let mut state = State::<3> {
            u: vec![[0.0; 3]; nc],
            v: vec![[0.0; 3]; nc],
            f_int: vec![[0.0; 3]; nc],
            f_ext: vec![[0.0; 3]; nc],
            f_con: vec![[0.0; 3]; nc],
            mass: vec![0.0; nc],
            fix: vec![0; nc],
            v_pres: vec![[0.0; 3]; nc],
            time: 0.0,
            step: 0,
        };
        for (k, &c) in topo.copy_cluster.iter().enumerate() {
            state.mass[c.idx()] += copy_mass[k];
        }
        if let Some(c) = state.mass.iter().position(|&m| !(m > 0.0 && m.is_finite())) {
            return Err(FlemError::mesh(&mesh.source, format!("{} has no positive lumped mass (is it in a cell, with a positive density?)", mesh.point_name(c))));
        }
        for s in supports {
            for &p in &s.points {
                let c = p as usize;
                state.fix[c] |= s.fix;
                for d in 0..3 {
                    if s.fix & (1 << d) != 0 {
                        state.v_pres[c][d] = s.velocity[d];
                    }
                }
            }
        }
        let mut m = March3 {
            loads: Vec::new(),
            gravity: [0.0; 3],
            f_const: vec![[0.0; 3]; nc],
            dt: 0.0,
            damping,
            ledger: Ledger::default(),
            stats: StepStats::default(),
            omega_max: 0.0,
            partials: Vec::new(),
            ratio: f64::INFINITY,
            warnings: Vec::new(),
            cuts: Vec::new(),
            contact: None,
            pool: None,
            mesh,
            topo,
            blocks,
            state,
            copy_mass,
        };
        m.omega_max = m.omega_bound();
        if !(m.omega_max > 0.0 && m.omega_max.is_finite()) {
            return Err(FlemError::mesh(&m.mesh.source, "the stiffness bound of the mesh is not a positive number (degenerate cells or material?)"));
        }
        m.dt = safety * m.damping.stability_factor() * 2.0 / m.omega_max;
        Ok(m)
    }

    /// Upper bound of the highest natural frequency: `max_c sqrt(rows_c / m_c)` (Gershgorin on
    /// `M^-1 K` with the lumped mass).
    pub fn omega_bound(&self) -> f64 {
        let mut rows = vec![0.0; self.topo.n_clusters()];
        for b in &self.blocks {
            b.add_row_sums(&mut rows);
        }
        let w = rows.iter().zip(&self.state.mass).map(|(r, m)| (r / m).sqrt()).fold(0.0, f64::max);
        // With contact, its springs' term: omega^2 = omega_el^2 + omega_contact^2 (as 2D).
        self.contact.as_ref().map_or(w, |c| (w * w + c.omega2).sqrt())
    }

    /// A new load (level 0) named `name`; returns its index.
    pub fn add_load(&mut self, name: &str) -> usize {
        self.loads.push(Load3 { name: name.to_string(), ..Default::default() });
        self.loads.len() - 1
    }

    /// Adds a uniform pressure `p` (force per area, positive pushing into the body) on the faces
    /// of a face set to load `k`, along each face's initial inward normal: consistent nodal
    /// forces (`mesh::face_integration`, as the 3D implicit solve's), each on the copy of the
    /// element that owns the face. Faces are oriented
    /// by that element (outward), whatever their order in the file.
    pub fn add_face_pressure(&mut self, k: usize, set: &str, p: f64) -> Result<()> {
        let Some(faces) = self.mesh.face_sets.get(set) else {
            let names: Vec<&String> = self.mesh.face_sets.keys().collect();
            return Err(FlemError::mesh(&self.mesh.source, format!("no face set \"{set}\" (face sets: {names:?})")));
        };
        let mut out = Vec::new();
        for f in faces {
            let Some(fid) = self.topo.face_with(f.corners()) else {
                return Err(FlemError::mesh(&self.mesh.source, format!("face set \"{set}\": the face of {} is not a face of a cell", self.mesh.points_name(f.corners()))));
            };
            let face = self.topo.faces[fid.idx()];
            if face.sides[1].is_some() {
                return Err(FlemError::mesh(&self.mesh.source, format!("face set \"{set}\": the face of {} is inside the body (a pressure acts on the boundary)", self.mesh.points_name(f.corners()))));
            }
            let e = face.sides[0].unwrap().0;
            let c: Vec<u32> = face.corners().iter().map(|p| p.0).collect();
            let x: Vec<[f64; 3]> = c.iter().map(|&q| self.mesh.points[q as usize]).collect();
            crate::mesh::face_integration(&x, |nw, area| {
                for (a, &q) in c.iter().enumerate() {
                    let copy = self.topo.copy_at(e, crate::ids::PointId(q)).unwrap();
                    out.push((copy.0, [-p * nw[a] * area[0], -p * nw[a] * area[1], -p * nw[a] * area[2]]));
                }
            });
        }
        self.loads[k].on_copies.extend(out);
        Ok(())
    }

    /// Adds the force `f` (at level 1) on every point of a node set to load `k`.
    pub fn add_point_force(&mut self, k: usize, set: &str, f: [f64; 3]) -> Result<()> {
        let pts = self.node_set(set)?;
        self.loads[k].on_points.extend(pts.into_iter().map(|p| (p, f)));
        Ok(())
    }

    /// Makes load `k` a prescribed velocity (`v[d]` at level 1 on the dofs of `bits`) of a node
    /// set.
    pub fn set_velocity(&mut self, k: usize, set: &str, bits: u8, v: [f64; 3]) -> Result<()> {
        let pts = self.node_set(set)?;
        self.loads[k].velocity = Some((pts, bits, v));
        Ok(())
    }

    /// The points of a node set of the mesh, or an error that names the sets.
    pub fn node_set(&self, set: &str) -> Result<Vec<u32>> {
        self.mesh.node_sets.get(set).cloned().ok_or_else(|| {
            let names: Vec<&String> = self.mesh.node_sets.keys().collect();
            FlemError::mesh(&self.mesh.source, format!("no node set \"{set}\" (node sets: {names:?})"))
        })
    }

    /// Sets the level of every load by name (absent: unchanged) and rebuilds the forces.
    pub fn set_levels(&mut self, levels: &std::collections::BTreeMap<String, f64>) {
        for l in &mut self.loads {
            if let Some(&v) = levels.get(&l.name) {
                l.level = v;
            }
        }
        self.rebuild_forces();
    }

    /// A prescribed velocity is imposed at once at the start of a stage (as 2D's
    /// `begin_stage`): the kinetic energy it adds is work done on the body (without it the
    /// ledger, and the divergence guard built on it, see energy appear from nothing: a scene
    /// driven by a velocity load stopped at its first step).
    pub fn impose_velocities(&mut self) {
        let st = &mut self.state;
        for c in 0..st.v.len() {
            for d in 0..3 {
                if st.fix[c] & (1 << d) != 0 && st.v[c][d] != st.v_pres[c][d] {
                    self.ledger.external_work += 0.5 * st.mass[c] * (st.v_pres[c][d].powi(2) - st.v[c][d].powi(2));
                    st.v[c][d] = st.v_pres[c][d];
                }
            }
        }
    }

    /// The external force in force (gravity plus every load times its level, on the current
    /// clusters) and the prescribed velocities.
    pub fn rebuild_forces(&mut self) {
        let nc = self.topo.n_clusters();
        self.f_const.clear();
        self.f_const.extend(self.state.mass.iter().map(|&m| [m * self.gravity[0], m * self.gravity[1], m * self.gravity[2]]));
        for l in &self.loads {
            for &(k, f) in &l.on_copies {
                let c = self.topo.copy_cluster[k as usize].idx();
                for d in 0..3 {
                    self.f_const[c][d] += l.level * f[d];
                }
            }
            for &(p, f) in &l.on_points {
                let c = self.topo.point_clusters[p as usize][0].idx();
                for d in 0..3 {
                    self.f_const[c][d] += l.level * f[d];
                }
            }
            if let Some((pts, bits, v)) = &l.velocity {
                for &p in pts {
                    for &c in &self.topo.point_clusters[p as usize] {
                        self.state.fix[c.idx()] |= bits;
                        for d in 0..3 {
                            if bits & (1 << d) != 0 {
                                self.state.v_pres[c.idx()][d] = l.level * v[d];
                            }
                        }
                    }
                }
            }
        }
        debug_assert_eq!(self.f_const.len(), nc);
    }

    /// Runs the element loop and the node update on `threads` threads (0: one per core; 1: no
    /// pool). The results do not depend on it (tests/threads3.rs).
    pub fn set_threads(&mut self, threads: usize) -> std::result::Result<(), rayon::ThreadPoolBuildError> {
        let n = if threads == 0 { std::thread::available_parallelism().map_or(1, |n| n.get()) } else { threads };
        self.pool = if n <= 1 { None } else { Some(std::sync::Arc::new(rayon::ThreadPoolBuilder::new().num_threads(n).build()?)) };
        Ok(())
    }

    /// Threads in use (1 without a pool).
    pub fn threads(&self) -> usize {
        self.pool.as_ref().map_or(1, |p| p.current_num_threads())
    }

    /// `f_int` of every block at the current displacement (zeroed, then each block adds, on
    /// the pool's threads: the same bits on any number).
    pub fn internal_forces(&mut self) {
        for f in &mut self.state.f_int {
            *f = [0.0; 3];
        }
        for b in &self.blocks {
            b.add_internal_forces_pool(&self.state.u, &mut self.state.f_int, self.pool.as_deref());
        }
    }

    /// One step: element forces, the node update (the scene's damping), the ratio.
    pub fn step(&mut self) -> Result<()> {
        self.internal_forces();
        self.state.f_ext.copy_from_slice(&self.f_const);
        let with_contact = self.contact_forces()?;
        let co = self.damping.coeffs(&self.stats);
        let dt = self.dt;
        let (a, beta, eta) = (co.viscous, co.local, co.eta);
        let (c1, c2) = (1.0 - 0.5 * a * dt, 1.0 / (1.0 + 0.5 * a * dt));
        let damp = if eta != 0.0 {
            3
        } else if beta != 0.0 {
            2
        } else if a != 0.0 {
            1
        } else {
            0
        };
        let update = pick_variant::<3>(with_contact, damp, true, true, Simd::best());
        let State { u, v, f_int, f_ext, f_con, mass, fix, v_pres, .. } = &mut self.state;
        let ctx = NodeCtx::<3> { mass, fix, f_int, f_ext, f_con, v_pres, dt, inv_dt: 1.0 / dt, c1, c2, beta, eta_hdt: 0.5 * eta * dt, a_hdt: 0.5 * a * dt };
        let n_chunks = u.len().div_ceil(NODE_CHUNK);
        self.partials.resize(n_chunks, [0.0; NSUM]);
        // Per fixed chunk of nodes, on the pool or not: the sums below do not depend on it.
        match self.pool.as_deref() {
            Some(pool) if n_chunks > 1 => {
                use rayon::prelude::*;
                let par = u.par_chunks_mut(NODE_CHUNK).zip(v.par_chunks_mut(NODE_CHUNK)).zip(self.partials.par_iter_mut()).enumerate();
                pool.install(|| par.for_each(|(k, ((u, v), s))| *s = update(&ctx, k * NODE_CHUNK, u, v)));
            }
            _ => {
                for (k, ((u, v), s)) in u.chunks_mut(NODE_CHUNK).zip(v.chunks_mut(NODE_CHUNK)).zip(self.partials.iter_mut()).enumerate() {
                    *s = update(&ctx, k * NODE_CHUNK, u, v);
                }
            }
        }
        let mut sum = [0.0; NSUM];
        for p in &self.partials {
            for (k, (s, x)) in sum.iter_mut().zip(p).enumerate() {
                *s = if k == 11 { f64::max(*s, *x) } else { *s + x };
            }
        }
        let [w, dmp, pw, pd, ke, keh, ufi, umu, uf, wc, pc, num, asum, cnt] = sum;
        self.ledger.contact_work += wc;
        self.ledger.pending_contact = pc;
        self.ledger.external_work += w;
        self.ledger.damping += dmp;
        self.ledger.pending_ext = pw;
        self.ledger.pending_damp = pd;
        self.ledger.kinetic = ke;
        self.ledger.strain = 0.5 * uf;
        self.ratio = ratio_of(num.sqrt(), asum, cnt);
        self.state.time += dt;
        self.state.step += 1;
        self.stats = StepStats { step: self.state.step, dt, omega_max: self.omega_max, kinetic: keh, u_f_int: ufi, u_m_u: umu };
        if !keh.is_finite() || keh > 1e12 * self.ledger.external_work.abs().max(1e-300) && keh > 1e-200 {
            let why = if keh.is_finite() { "the kinetic energy grew beyond 1e12 times the work done on the body" } else { "velocities became non-finite" };
            return Err(FlemError::Diverged { step: self.state.step, time: self.state.time, dt, dt_crit: 2.0 / self.omega_max, ratio: dt * self.omega_max / 2.0, why: why.into() });
        }
        Ok(())
    }

    /// Marches until the unbalanced-force ratio is at most `tol` (checked every `every` steps)
    /// or `max_steps` have run; returns the steps run.
    pub fn run_to_rest(&mut self, tol: f64, every: u64, max_steps: u64) -> Result<u64> {
        self.damping.reset();
        for k in 1..=max_steps {
            self.step()?;
            if k % every.max(1) == 0 && self.ratio <= tol {
                return Ok(k);
            }
        }
        Ok(max_steps)
    }

    /// The nodal stress of every cluster: the mean of its copies' corner stresses (METHOD 3,
    /// read in 3D), tension positive `[sxx, syy, szz, sxy, syz, szx]`.
    pub fn nodal_stress(&self) -> Vec<[f64; 6]> {
        let mut corner = vec![[0.0; 6]; self.topo.copy_point.len()];
        for b in &self.blocks {
            b.corner_stresses(&self.state.u, &self.topo.elem_first_copy, &mut corner);
        }
        let nc = self.topo.n_clusters();
        let (mut s, mut n) = (vec![[0.0; 6]; nc], vec![0u32; nc]);
        for (k, &c) in self.topo.copy_cluster.iter().enumerate() {
            for d in 0..6 {
                s[c.idx()][d] += corner[k][d];
            }
            n[c.idx()] += 1;
        }
        for (s, &n) in s.iter_mut().zip(&n) {
            for x in s.iter_mut() {
                *x /= n as f64;
            }
        }
        s
    }

    /// The failure check (METHOD 4-5 read in 3D): the nodal stress of every cluster, the
    /// criterion, and at each failed cluster (in cluster order, one split per cluster) the
    /// faces the rule proposes, cut if the fan then falls apart. The state follows every split
    /// (new clusters take their parent's displacement, velocity and supports; masses are the
    /// sums over each part's copies) and the blocks are reconnected.
    pub fn check_failure(&mut self, criterion: &dyn FailureCriterion, rule: &dyn SeparationRule, max_splits: usize) -> Result<SplitRecord3> {
        let stress = self.nodal_stress();
        let p3: Vec<_> = stress.iter().map(|&s| principal3(s)).collect();
        let ps: Vec<_> = p3.iter().map(|p| p.p).collect();
        let mut checks = vec![FailureCheck::default(); ps.len()];
        criterion.try_check_batch(&ps, &vec![1.0; ps.len()], &mut checks).map_err(|e| FlemError::config("scene", "cracking.criterion", e))?;
        let mut rec = SplitRecord3::default();
        let centroid = |mesh: &RawMesh3, e: ElemId| -> [f64; 3] {
            let c = mesh.cells[e.idx()].corners();
            std::array::from_fn(|d| c.iter().map(|&p| mesh.points[p as usize][d]).sum::<f64>() / c.len() as f64)
        };
        // The most critical first (index, then cluster id), at most `max_splits` splits.
        let mut failed: Vec<usize> = (0..ps.len()).filter(|&c| checks[c].failed()).collect();
        failed.sort_by(|&a, &b| checks[b].index.total_cmp(&checks[a].index).then(a.cmp(&b)));
        let mut n_split = 0;
        for c in failed {
            if n_split >= max_splits {
                break;
            }
            let cl = ClusterId::new(c);
            let fan = self.topo.fan(cl);
            let point = fan.point;
            let centroids: Vec<[f64; 3]> = fan.copies.iter().map(|&k| centroid(&self.mesh, self.topo.copy_elem[k.idx()])).collect();
            let normals: Vec<[f64; 3]> = fan.links.iter().map(|l| face_normal(&self.mesh, &self.topo, l.face)).collect();
            let view = FanView3 {
                fan: &fan,
                x: self.mesh.points[point.idx()],
                centroids: &centroids,
                face_normals: &normals,
                never_split: self.topo.point_clusters[point.idx()].len() == 1,
                principal: p3[c],
            };
            let Some(faces) = rule.propose_3d(&view, &checks[c]).map_err(|e| FlemError::config("scene", "cracking.separation", e))? else { continue };
            let r = self.topo.cut(cl, &faces, true);
            if !r.is_empty() {
                n_split += 1;
                self.cuts.push((cl.0, faces.iter().map(|f| f.0).collect()));
            }
            self.follow(&r);
            rec.extend(r);
        }
        if !rec.is_empty() {
            self.rebuild_forces();
            for b in &mut self.blocks {
                b.reconnect(&self.topo);
            }
            self.contact_follow_split();
            self.omega_max = self.omega_bound();
        }
        Ok(rec)
    }

    /// Replays a cut of the failure check (a checkpoint's, `output::checkpoint3`): the same
    /// `Topology3::cut` and the arrays following it, without the blocks' reconnection (call
    /// [`Self::after_cuts`] once after the last).
    pub fn replay_cut(&mut self, cluster: u32, faces: &[u32]) -> Result<()> {
        if cluster as usize >= self.topo.n_clusters() {
            return Err(FlemError::Other(format!("a replayed cut names cluster {cluster}, and the body has {}", self.topo.n_clusters())));
        }
        let faces: Vec<FaceId> = faces.iter().map(|&f| FaceId(f)).collect();
        let r = self.topo.cut(ClusterId(cluster), &faces, true);
        if r.is_empty() {
            return Err(FlemError::Other(format!("a replayed cut at cluster {cluster} splits nothing: the checkpoint does not fit this body")));
        }
        self.follow(&r);
        self.cuts.push((cluster, faces.iter().map(|f| f.0).collect()));
        Ok(())
    }

    /// After replayed cuts: forces, blocks and the stiffness bound follow the topology.
    pub fn after_cuts(&mut self) {
        self.rebuild_forces();
        for b in &mut self.blocks {
            b.reconnect(&self.topo);
        }
        self.contact_follow_split();
        self.omega_max = self.omega_bound();
    }

    /// Every per-cluster array follows a split.
    fn follow(&mut self, r: &SplitRecord3) {
        let st = &mut self.state;
        for nc in &r.new_clusters {
            let p = nc.parent.idx();
            st.u.push(st.u[p]);
            st.v.push(st.v[p]);
            st.f_int.push([0.0; 3]);
            st.f_ext.push([0.0; 3]);
            st.f_con.push([0.0; 3]);
            st.fix.push(st.fix[p]);
            st.v_pres.push(st.v_pres[p]);
            st.mass.push(0.0);
        }
        let mut touched: Vec<usize> = r.new_clusters.iter().flat_map(|nc| [nc.parent.idx(), nc.id.idx()]).collect();
        touched.sort_unstable();
        touched.dedup();
        for &c in &touched {
            st.mass[c] = 0.0;
        }
        for (k, &c) in self.topo.copy_cluster.iter().enumerate() {
            if touched.binary_search(&c.idx()).is_ok() {
                st.mass[c.idx()] += self.copy_mass[k];
            }
        }
    }

    /// Separates the faces of a face set from the start (a notch, a pre-cut plane): cut at every
    /// corner, every point split where its fan falls apart.
    pub fn separate_face_set(&mut self, set: &str) -> Result<()> {
        let Some(faces) = self.mesh.face_sets.get(set) else {
            return Err(FlemError::mesh(&self.mesh.source, format!("no face set \"{set}\" (face sets: {:?})", self.mesh.face_sets.keys().collect::<Vec<_>>())));
        };
        let mut ids = Vec::new();
        for face in faces {
            match self.topo.face_with(face.corners()) {
                Some(fid) => ids.push(fid),
                None => return Err(FlemError::mesh(&self.mesh.source, format!("face set \"{set}\": the face of {} is not a face of a cell", self.mesh.points_name(face.corners())))),
            }
        }
        let rec = self.topo.separate_faces(&ids);
        self.follow(&rec);
        for b in &mut self.blocks {
            b.reconnect(&self.topo);
        }
        self.rebuild_forces();
        Ok(())
    }

    /// Adds node-to-face contact (`[contact]`, after the pre-separated faces were cut) and sets
    /// the time step with the contact springs' term: `dt` when given (refused above the
    /// critical step unless `allow_unstable`), else `safety` of the stable step.
    pub fn attach_contact(&mut self, cfg: crate::contact::ContactCfg, file: &str, dt: Option<f64>, safety: f64, allow_unstable: bool) -> Result<()> {
        let mut c = crate::contact::contact3::Contact3::new(cfg, &self.mesh, &self.topo, file)?;
        c.update_omega2(&self.mesh, &self.topo, &self.copy_mass, &self.state.mass, &self.state.fix);
        self.contact = Some(c);
        self.omega_max = self.omega_bound();
        let crit = 2.0 / self.omega_max;
        match dt {
            Some(dt) if dt > crit && !allow_unstable => Err(FlemError::config(
                file,
                "solver.dt",
                format!("= {dt} is above the critical step {crit:.6e} with the contact springs (contact.law normal_stiffness / shear_stiffness); lower it or set solver.allow_unstable_dt = true"),
            )),
            Some(dt) => {
                self.dt = dt;
                Ok(())
            }
            None => {
                self.dt = safety * self.damping.stability_factor() * crit;
                Ok(())
            }
        }
    }

    /// The contact forces of this step into `f_con` and the contact terms of the ledger;
    /// false (and nothing done) without contact.
    fn contact_forces(&mut self) -> Result<bool> {
        let Some(c) = self.contact.as_mut() else { return Ok(false) };
        let (stored, diss) = c.compute(&self.mesh.points, &self.state.u, &self.state.v, self.dt, &mut self.state.f_con)?;
        self.ledger.contact_energy = stored;
        self.ledger.contact_dissipated += diss;
        Ok(true)
    }

    /// The contact surfaces follow splits (new faces, new slaves, the stable-step term).
    fn contact_follow_split(&mut self) {
        if let Some(c) = self.contact.as_mut() {
            c.on_split(&self.mesh, &self.topo);
            c.update_omega2(&self.mesh, &self.topo, &self.copy_mass, &self.state.mass, &self.state.fix);
        }
    }

    /// Connected fragments of the body.
    pub fn fragments(&self) -> usize {
        self.topo.fragments().1
    }
}

/// The unit normal of a face from its first three corners (outward of its first element).
pub fn face_normal(mesh: &RawMesh3, topo: &Topology3, f: FaceId) -> [f64; 3] {
    let c = topo.faces[f.idx()].corners();
    let x: Vec<[f64; 3]> = c.iter().map(|p| mesh.points[p.idx()]).collect();
    let (a, b) = ([x[1][0] - x[0][0], x[1][1] - x[0][1], x[1][2] - x[0][2]], [x[2][0] - x[0][0], x[2][1] - x[0][1], x[2][2] - x[0][2]]);
    let n = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    [n[0] / l, n[1] / l, n[2] / l]
}

/// What a stage of a 3D scene did.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Stage3Result {
    pub name: String,
    pub steps: u64,
    pub ratio: f64,
    /// The stage ended at its tolerance (not at its step limit or end time).
    pub at_rest: bool,
    /// Clusters created by splits in this stage.
    pub splits: usize,
    pub fragments: usize,
    pub time: f64,
}

/// What a 3D run reports as it goes (the output writer implements it).
pub trait Observer3 {
    /// After the body is built (and its pre-separated faces cut), before the first stage.
    fn start(&mut self, _m: &March3) -> Result<()> {
        Ok(())
    }
    /// Every `every()` steps of a stage (0: never).
    fn every(&self) -> u64 {
        0
    }
    fn step(&mut self, _m: &March3, _stage: usize) -> Result<()> {
        Ok(())
    }
    /// At the end of every stage.
    fn stage_done(&mut self, _m: &March3, _stage: usize, _r: &Stage3Result) -> Result<()> {
        Ok(())
    }
    /// Polled between two steps: a checkpoint is due (e.g. `output.checkpoint_every`).
    fn checkpoint_due(&mut self, _m: &March3) -> bool {
        false
    }
    /// Takes a checkpoint of the body at `pos` (between two steps, or after a stage).
    fn checkpoint(&mut self, _m: &March3, _pos: &Pos3) -> Result<()> {
        Ok(())
    }
    /// Polled once per step: stop the run (after a checkpoint) with `FlemError::Interrupted`.
    fn should_stop(&mut self) -> bool {
        false
    }
}

/// Where the stage loop of a 3D run stands (a checkpoint's position, `output::checkpoint3`):
/// the stage, whether it began (its levels set), the steps run in it, the clusters at its
/// start, and the stages done.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Pos3 {
    pub stage: usize,
    pub began: bool,
    pub steps: u64,
    pub clusters0: usize,
    pub done: Vec<Stage3Result>,
}

impl March3 {
    /// The body of a 3D scene: its mesh (which must be 3D), materials by region, supports,
    /// loads at level 0, gravity, pre-separated faces, the damping (taken from the scene) and
    /// the time step.
    pub fn from_scene(scene: &mut crate::scene3::Scene3) -> Result<March3> {
        let damping = scene.file.solver.damping.take();
        let contact = scene.file.contact.take();
        let f = &scene.file;
        let name = scene.path.display().to_string();
        let mut mesh = match f.mesh.load_any(&scene.base_dir)? {
            crate::mesh::AnyMesh::Three(m) => m,
            crate::mesh::AnyMesh::Two(m) => {
                return Err(FlemError::config(&name, "model.dim", format!("= 3, but the mesh {} is 2D (it has no volume elements); remove model.dim for a 2D scene", m.source)))
            }
        };
        let warnings = mesh.validate(f.model.orientation)?;
        let material_of = |region: &str| -> Result<([f64; 3], Option<String>)> {
            match scene.material_for(region) {
                Some(m) => Ok(([m.young_modulus, m.poisson_ratio, m.density], m.element.clone())),
                None => Err(FlemError::config(&name, "material", format!("no [[material]] for region \"{region}\" of the mesh (and none with region = \"all\")"))),
            }
        };
        let mut supports = Vec::new();
        for (i, s) in f.supports.iter().enumerate() {
            let points = mesh.node_sets.get(&s.nodes).cloned().ok_or_else(|| {
                FlemError::config(&name, format!("support[{i}].nodes"), format!("= \"{}\" names no node set of the mesh (node sets: {:?})", s.nodes, mesh.node_sets.keys().collect::<Vec<_>>()))
            })?;
            supports.push(Support3 { points, fix: s.bits().unwrap_or(0), velocity: [0.0; 3] });
        }
        let damping = damping.ok_or_else(|| FlemError::config(&name, "solver.damping", "is missing (the scene's damping is taken by the body it builds: build one body per scene)"))?;
        let mut m = March3::new(mesh, &material_of, &supports, damping, f.solver.dt_safety)?;
        if let Some(dt) = f.solver.dt {
            let crit = 2.0 / m.omega_max;
            if dt > crit && !f.solver.allow_unstable_dt {
                return Err(FlemError::config(
                    &name,
                    "solver.dt",
                    format!("= {dt} is above the critical step {crit:.6e} of this mesh (a bound: Gershgorin on the lumped system); lower it or set solver.allow_unstable_dt = true"),
                ));
            }
            m.dt = dt;
        }
        m.gravity = f.model.gravity;
        m.warnings = warnings;
        m.set_threads(f.solver.threads).map_err(|e| FlemError::config(&name, "solver.threads", format!("= {}: the thread pool could not be started: {e}", f.solver.threads)))?;
        for (i, l) in f.loads.iter().enumerate() {
            let k = m.add_load(l.name());
            let key = |s: &str| format!("load[{i}].{s}");
            match l {
                crate::scene3::Load3Cfg::Pressure { faces, value, .. } => m.add_face_pressure(k, faces, *value).map_err(|e| FlemError::config(&name, key("faces"), e.to_string()))?,
                crate::scene3::Load3Cfg::Point { nodes, value, .. } => m.add_point_force(k, nodes, *value).map_err(|e| FlemError::config(&name, key("nodes"), e.to_string()))?,
                crate::scene3::Load3Cfg::Velocity { nodes, x, y, z, .. } => {
                    let bits = x.map_or(0, |_| 1) | y.map_or(0, |_| 2) | z.map_or(0, |_| 4);
                    m.set_velocity(k, nodes, bits, [x.unwrap_or(0.0), y.unwrap_or(0.0), z.unwrap_or(0.0)]).map_err(|e| FlemError::config(&name, key("nodes"), e.to_string()))?
                }
            }
        }
        for (i, set) in f.model.separated.iter().enumerate() {
            m.separate_face_set(set).map_err(|e| FlemError::config(&name, format!("model.separated[{i}]"), e.to_string()))?;
        }
        if let Some(c) = contact {
            m.attach_contact(c, &name, f.solver.dt, f.solver.dt_safety, f.solver.allow_unstable_dt)?;
        }
        m.rebuild_forces();
        Ok(m)
    }

    /// Runs every stage of the scene (METHOD 8): each sets its levels and marches to its
    /// tolerance (checked every `ratio_every` steps) or its step limit; with `[cracking]`,
    /// failure is checked at rest (after splits the stage relaxes again, until a check splits
    /// nothing) or every `check_every` steps (`at_equilibrium = false`); a `dynamic` stage runs
    /// its steps (or to its `end_time`) without the tolerance.
    pub fn run_scene(&mut self, scene: &crate::scene3::Scene3, obs: &mut dyn Observer3) -> Result<Vec<Stage3Result>> {
        self.run_scene_from(scene, obs, None)
    }

    /// [`Self::run_scene`] from the start (`None`) or from a checkpoint's position (the body
    /// restored by `output::checkpoint3`). Between two steps the observer may take a
    /// checkpoint (`checkpoint_due`); one is taken after every stage; `should_stop` ends the
    /// run after a checkpoint with `FlemError::Interrupted`.
    pub fn run_scene_from(&mut self, scene: &crate::scene3::Scene3, obs: &mut dyn Observer3, from: Option<Pos3>) -> Result<Vec<Stage3Result>> {
        let f = &scene.file;
        let levels = scene.stage_levels();
        let resumed = from.is_some();
        let mut pos = match from {
            Some(p) => p,
            None => {
                obs.start(self)?;
                Pos3 { stage: 0, began: false, steps: 0, clusters0: self.topo.n_clusters(), done: Vec::new() }
            }
        };
        let mut fresh = resumed;
        while pos.stage < f.stages.len() {
            let i = pos.stage;
            let st = &f.stages[i];
            if !pos.began {
                self.set_levels(&levels[i]);
                self.impose_velocities();
                self.damping.reset();
                pos.clusters0 = self.topo.n_clusters();
                pos.began = true;
            }
            let tol = st.tolerance.unwrap_or(f.solver.tolerance);
            let max_steps = st.max_steps.unwrap_or(f.solver.max_steps);
            let every = f.solver.ratio_every;
            let obs_every = obs.every();
            let mut at_rest = false;
            while pos.steps < max_steps {
                // Between two steps: the state is whole here (a resumed run starts here).
                if !fresh {
                    if obs.should_stop() {
                        obs.checkpoint(self, &pos)?;
                        return Err(FlemError::Interrupted { step: self.state.step, stage: i, stage_step: pos.steps });
                    }
                    if obs.checkpoint_due(self) {
                        obs.checkpoint(self, &pos)?;
                    }
                }
                fresh = false;
                self.step()?;
                pos.steps += 1;
                let steps = pos.steps;
                if obs_every > 0 && steps % obs_every == 0 {
                    obs.step(self, i)?;
                }
                if let Some(c) = f.cracking.as_ref().filter(|c| !c.at_equilibrium || st.dynamic) {
                    if steps % c.check_every == 0 {
                        self.check_failure(c.criterion.as_ref(), c.separation.as_ref(), c.max_splits_per_check)?;
                    }
                }
                if st.dynamic {
                    if st.end_time.is_some_and(|t| self.state.time >= t - 0.5 * self.dt) {
                        break;
                    }
                    continue;
                }
                if steps % every == 0 && self.ratio <= tol {
                    if let Some(c) = f.cracking.as_ref().filter(|c| c.at_equilibrium) {
                        if !self.check_failure(c.criterion.as_ref(), c.separation.as_ref(), c.max_splits_per_check)?.is_empty() {
                            self.damping.reset();
                            continue;
                        }
                    }
                    at_rest = true;
                    break;
                }
            }
            fresh = false;
            let r = Stage3Result {
                name: if st.name.is_empty() { format!("stage{i}") } else { st.name.clone() },
                steps: pos.steps,
                ratio: self.ratio,
                at_rest,
                splits: self.topo.n_clusters() - pos.clusters0,
                fragments: self.fragments(),
                time: self.state.time,
            };
            obs.stage_done(self, i, &r)?;
            pos.done.push(r);
            pos.stage += 1;
            pos.steps = 0;
            pos.began = false;
            obs.checkpoint(self, &pos)?;
        }
        Ok(pos.done)
    }
}
