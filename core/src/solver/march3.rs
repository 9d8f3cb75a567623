//! The explicit march of a 3D model (issue 38, docs/3d.md): the same central-difference node
//! update as 2D (`NodeCtx<3>`: damping implicit in velocity, the damping plugin's coefficients,
//! the energy ledger's sums), element forces from the model's `Block3`s, dynamic relaxation to
//! the unbalanced-force ratio, and the failure check that splits points along element faces
//! (`Topology3::cut`, the separation rule's `propose_3d`).
//!
//! What it is not yet: the scene's stage loop, contact, checkpoints and output in 3D (the
//! builder below takes its supports and loads from the caller); docs/3d.md says what is left.
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

/// A 3D body marching in time.
pub struct March3 {
    pub mesh: RawMesh3,
    pub topo: Topology3,
    pub blocks: Vec<Box<dyn Block3>>,
    pub state: State<3>,
    /// The lumped mass of every copy (a cluster's mass is the sum over its copies).
    pub copy_mass: Vec<f64>,
    /// Constant external forces at load level 1 (per cluster; a load on a point stays on the
    /// point's first cluster).
    pub f_load: Vec<[f64; 3]>,
    pub level: f64,
    pub dt: f64,
    pub damping: Box<dyn Damping>,
    pub ledger: Ledger,
    stats: StepStats,
    omega_max: f64,
    partials: Vec<[f64; NSUM]>,
    /// Ratio of the last step.
    pub ratio: f64,
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
            f_load: vec![[0.0; 3]; nc],
            level: 1.0,
            dt: 0.0,
            damping,
            ledger: Ledger::default(),
            stats: StepStats::default(),
            omega_max: 0.0,
            partials: Vec::new(),
            ratio: f64::INFINITY,
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
        rows.iter().zip(&self.state.mass).map(|(r, m)| (r / m).sqrt()).fold(0.0, f64::max)
    }

    /// Adds a force (at load level 1) to a point's first cluster.
    pub fn add_point_force(&mut self, p: u32, f: [f64; 3]) {
        for d in 0..3 {
            self.f_load[p as usize][d] += f[d];
        }
    }

    /// Adds a uniform pressure `p` (force per area, positive pushing into the body) on the faces
    /// of a face set, along each face's initial inward normal: consistent nodal forces (a
    /// triangle's corners a third each; a quadrilateral by 2 x 2 Gauss points on its bilinear
    /// map). Faces given anticlockwise seen from outside (the mesh convention).
    pub fn add_face_pressure(&mut self, set: &str, p: f64) -> Result<()> {
        let Some(faces) = self.mesh.face_sets.get(set) else {
            let names: Vec<&String> = self.mesh.face_sets.keys().collect();
            return Err(FlemError::mesh(&self.mesh.source, format!("no face set \"{set}\" (face sets: {names:?})")));
        };
        let faces = faces.clone();
        for f in faces {
            let c = f.corners();
            let x: Vec<[f64; 3]> = c.iter().map(|&q| self.mesh.points[q as usize]).collect();
            let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
            let cross = |a: [f64; 3], b: [f64; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
            if c.len() == 3 {
                // n A = (x1 - x0) x (x2 - x0) / 2, outward; the force is -p n A.
                let na = cross(sub(x[1], x[0]), sub(x[2], x[0]));
                for &q in c {
                    self.add_point_force(q, [-p * na[0] / 6.0, -p * na[1] / 6.0, -p * na[2] / 6.0]);
                }
            } else {
                let g = 1.0 / 3f64.sqrt();
                for (xi, eta) in [(-g, -g), (g, -g), (g, g), (-g, g)] {
                    let n = [0.25 * (1.0 - xi) * (1.0 - eta), 0.25 * (1.0 + xi) * (1.0 - eta), 0.25 * (1.0 + xi) * (1.0 + eta), 0.25 * (1.0 - xi) * (1.0 + eta)];
                    let dxi = [-0.25 * (1.0 - eta), 0.25 * (1.0 - eta), 0.25 * (1.0 + eta), -0.25 * (1.0 + eta)];
                    let deta = [-0.25 * (1.0 - xi), -0.25 * (1.0 + xi), 0.25 * (1.0 + xi), 0.25 * (1.0 - xi)];
                    let t1: [f64; 3] = std::array::from_fn(|d| (0..4).map(|a| dxi[a] * x[a][d]).sum());
                    let t2: [f64; 3] = std::array::from_fn(|d| (0..4).map(|a| deta[a] * x[a][d]).sum());
                    let na = cross(t1, t2);
                    for a in 0..4 {
                        self.add_point_force(c[a], [-p * n[a] * na[0], -p * n[a] * na[1], -p * n[a] * na[2]]);
                    }
                }
            }
        }
        Ok(())
    }

    /// One step: element forces, the node update (the scene's damping), the ratio.
    pub fn step(&mut self) -> Result<()> {
        let nc = self.topo.n_clusters();
        for f in &mut self.state.f_int {
            *f = [0.0; 3];
        }
        for b in &self.blocks {
            b.add_internal_forces(&self.state.u, &mut self.state.f_int);
        }
        for c in 0..nc {
            for d in 0..3 {
                self.state.f_ext[c][d] = self.level * self.f_load[c][d];
            }
        }
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
        let update = pick_variant::<3>(false, damp, true, true, Simd::best());
        let State { u, v, f_int, f_ext, f_con, mass, fix, v_pres, .. } = &mut self.state;
        let ctx = NodeCtx::<3> { mass, fix, f_int, f_ext, f_con, v_pres, dt, inv_dt: 1.0 / dt, c1, c2, beta, eta_hdt: 0.5 * eta * dt, a_hdt: 0.5 * a * dt };
        let n_chunks = u.len().div_ceil(NODE_CHUNK);
        self.partials.resize(n_chunks, [0.0; NSUM]);
        for (k, ((u, v), s)) in u.chunks_mut(NODE_CHUNK).zip(v.chunks_mut(NODE_CHUNK)).zip(self.partials.iter_mut()).enumerate() {
            *s = update(&ctx, k * NODE_CHUNK, u, v);
        }
        let mut sum = [0.0; NSUM];
        for p in &self.partials {
            for (k, (s, x)) in sum.iter_mut().zip(p).enumerate() {
                *s = if k == 11 { f64::max(*s, *x) } else { *s + x };
            }
        }
        let [w, dmp, pw, pd, ke, keh, ufi, umu, uf, _, _, num, asum, cnt] = sum;
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
            return Err(FlemError::Diverged { step: self.state.step, time: self.state.time, dt, dt_crit: 2.0 / self.omega_max, ratio: self.ratio, why: why.into() });
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
    pub fn check_failure(&mut self, criterion: &dyn FailureCriterion, rule: &dyn SeparationRule) -> Result<SplitRecord3> {
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
        for c in 0..ps.len() {
            if !checks[c].failed() {
                continue;
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
            self.follow(&r);
            rec.extend(r);
        }
        if !rec.is_empty() {
            for b in &mut self.blocks {
                b.reconnect(&self.topo);
            }
            self.omega_max = self.omega_bound();
        }
        Ok(rec)
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
            self.f_load.push([0.0; 3]);
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
