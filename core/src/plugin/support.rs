//! Supports of the implicit check (METHOD.md section 10; issue 41, ours): which fragments the
//! check solver can solve, and a statically determinate support for a body whose loads are
//! self-equilibrated and that has no support at all (the paper's opening model, pulled at both
//! ends, configs/paper/opening.toml).
//!
//! Per fragment (elements joined through shared clusters, `Topology::fragments`):
//! - with prescribed dofs: they must stop its three rigid motions (rank 3 of the rigid modes
//!   restricted to them), else it is refused, named ("has no support that stops its rigid
//!   motion");
//! - with no prescribed dof: its loads must be self-equilibrated. With `f_c` the external force
//!   of its clusters, `x_c` their reference positions, `S = sum_c |f_c|` and `L` the diagonal of
//!   its bounding box,
//!
//!   ```text
//!   |sum_c f_c| <= EQ_TOL S   and   |sum_c (x_c - x_A) x f_c| <= EQ_TOL S L,   EQ_TOL = 1e-10
//!   ```
//!
//!   (round-off of the load integration; a fragment without load passes). Otherwise it is
//!   refused, named ("has no prescribed dof at all ... its loads are not in equilibrium"). When
//!   they are, three dofs are pinned (u = 0): both dofs of node A, the cluster with the smallest
//!   x (then y, then index), and at node B, the cluster farthest from A (ties: smallest index),
//!   the dof closest to the normal of AB (y when |x_B - x_A| >= |y_B - y_A|, else x). The support
//!   is statically determinate: its reactions are fixed by the loads alone, and vanish when the
//!   loads are self-equilibrated; after the solve [`check_reactions`] measures them
//!   (`R = f_int(u) - f` at the three dofs) and refuses a solve whose largest reaction exceeds
//!   [`REACTION_TOL`] S (a solve that is not round-off close to the free body's).
//!
//! The displacement of such a body is defined up to a rigid motion (the pin chose one). To
//! compare another solution `u` of the same body with it, [`align_rigid`] adds to the implicit
//! solution the rigid motion `r(x) = (a - theta (y - y_c), b + theta (x - x_c))` that fits
//! `u - u_implicit` best in the least-squares sense over the fragment's clusters (the member of
//! the family of solutions closest to `u`); stresses do not depend on it.
//!
//! [`solve_supported`] runs any [`CheckSolver`] through this: the callers of the check solver
//! (`flem compare`, `flem run` with `[check]`, `flem converge`, `flem chart`, the events solver)
//! use it, so the note ([`AddedSupport::note`]) reaches their output. A plugin called directly
//! (`CheckSolver::solve`) still refuses a fragment without prescribed dofs.
use serde::{Deserialize, Serialize};

use crate::element::model::Model;
use crate::error::{FlemError, Result};
use crate::plugin::check::CheckSolver;

/// Bound on the resultant force and moment of an unsupported fragment's loads, relative to the
/// sum of their magnitudes (and times the fragment's size for the moment).
pub const EQ_TOL: f64 = 1e-10;
/// Bound on the largest reaction at the pinned dofs after the solve, relative to the sum of the
/// magnitudes of the fragment's loads.
pub const REACTION_TOL: f64 = 1e-8;

/// The prefix of every refusal (the check solver's own).
pub const PREFIX: &str = "the implicit check solver cannot solve";

/// A statically determinate support added to a fragment without prescribed dofs.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct AddedSupport {
    pub fragment: u32,
    /// "fragment 0 (elements 0, 1, 2, ...; 36 elements, around point (x, y))".
    pub description: String,
    /// The pinned dofs: (cluster, 0 = x or 1 = y).
    pub dofs: [(usize, u8); 3],
    /// Reference positions of nodes A and B.
    pub at: [[f64; 2]; 2],
    /// Sum of the magnitudes of the fragment's loads (S).
    pub load: f64,
    /// |resultant force| / S and |resultant moment| / (S L) of its loads.
    pub resultant: [f64; 2],
    /// Largest |reaction| at the pinned dofs / S after the solve (None before it, or S = 0).
    pub reaction: Option<f64>,
}

impl AddedSupport {
    /// One line for the tools' output.
    pub fn note(&self) -> String {
        let d = |k: usize| format!("cluster {} {}", self.dofs[k].0, if self.dofs[k].1 == 0 { "x" } else { "y" });
        format!(
            "{} has no prescribed dof and self-equilibrated loads (resultant {:.1e}, moment {:.1e} of the load): a statically determinate support was added ({}, {} at ({}, {}); {} at ({}, {})){}",
            self.description,
            self.resultant[0],
            self.resultant[1],
            d(0),
            d(1),
            self.at[0][0],
            self.at[0][1],
            d(2),
            self.at[1][0],
            self.at[1][1],
            match self.reaction {
                Some(r) => format!(", reactions {r:.1e} of the load"),
                None => String::from(", reactions zero"),
            }
        )
    }
}

/// Fragment membership of elements and clusters.
pub struct Fragments {
    pub elem_frag: Vec<u32>,
    pub n: usize,
    /// `u32::MAX` for a cluster of no element.
    pub cluster_frag: Vec<u32>,
}

impl Fragments {
    pub fn new(model: &Model) -> Self {
        let topo = &model.topo;
        let (elem_frag, n) = topo.fragments();
        let mut cluster_frag = vec![u32::MAX; topo.n_clusters()];
        for (k, c) in topo.copy_cluster.iter().enumerate() {
            cluster_frag[c.idx()] = elem_frag[topo.copy_elem[k].idx()];
        }
        Fragments { elem_frag, n, cluster_frag }
    }

    /// "fragment 2 (element tags 14, 15, 16, ...; 40 elements, around point (x, y))" (the ids of
    /// the mesh file; "elements 14, ... (0-based, in file order)" for a generated mesh).
    pub fn describe(&self, model: &Model, f: u32) -> String {
        let elems: Vec<usize> = (0..self.elem_frag.len()).filter(|&e| self.elem_frag[e] == f).collect();
        let more = if elems.len() > 3 { ", ..." } else { "" };
        let list = model.mesh.cells_name(&elems[..elems.len().min(3)], more);
        let (mut sx, mut sy, mut m) = (0.0, 0.0, 0.0);
        for &e in &elems {
            for &p in model.mesh.cells[e].corners() {
                let x = model.mesh.points[p as usize];
                sx += x[0];
                sy += x[1];
                m += 1.0;
            }
        }
        format!("fragment {f} ({list}; {} elements, around point ({:.6}, {:.6}))", elems.len(), sx / m, sy / m)
    }
}

/// How every refusal of a fragment ends ([`singular`]): a property of the model (a fragment
/// without enough support, a mechanism), not a failure of the solver.
pub const SINGULAR: &str = ": its stiffness is singular";

/// The refusal of a fragment, as the check solver words it.
pub fn singular(model: &Model, fr: &Fragments, f: u32, why: &str) -> FlemError {
    FlemError::Solve(format!("{PREFIX}: {} {why}{SINGULAR}", fr.describe(model, f)))
}

/// What [`plan`] found: the fixities to solve with (the scene's, plus the added pins) and the
/// added supports.
#[derive(Clone, Debug)]
pub struct Plan {
    pub fix: Vec<u8>,
    pub added: Vec<AddedSupport>,
}

/// The supports of every fragment (module doc): the fixities with a statically determinate
/// support added to each fragment without prescribed dofs whose loads (every entry of `loads`,
/// one force per cluster) are self-equilibrated; a refusal naming the first fragment that cannot
/// be solved. `fix` is returned unchanged when nothing is added.
pub fn plan(model: &Model, fix: &[u8], loads: &[&[[f64; 2]]]) -> Result<Plan> {
    let fr = Fragments::new(model);
    let x0 = model.cluster_x0();
    let nf = fr.n;
    let mut lo = vec![[f64::INFINITY; 2]; nf];
    let mut hi = vec![[f64::NEG_INFINITY; 2]; nf];
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); nf];
    for (c, &f) in fr.cluster_frag.iter().enumerate() {
        if f == u32::MAX {
            continue;
        }
        members[f as usize].push(c);
        for d in 0..2 {
            lo[f as usize][d] = lo[f as usize][d].min(x0[c][d]);
            hi[f as usize][d] = hi[f as usize][d].max(x0[c][d]);
        }
    }
    let mut out = Plan { fix: fix.to_vec(), added: Vec::new() };
    for f in 0..nf {
        let l = ((hi[f][0] - lo[f][0]).powi(2) + (hi[f][1] - lo[f][1]).powi(2)).sqrt().max(f64::MIN_POSITIVE);
        let ctr = [0.5 * (lo[f][0] + hi[f][0]), 0.5 * (lo[f][1] + hi[f][1])];
        // Rank of the rigid modes restricted to the prescribed dofs.
        let mut g = [[0.0f64; 3]; 3];
        let mut count = 0usize;
        for &c in &members[f] {
            let (dx, dy) = ((x0[c][0] - ctr[0]) / l, (x0[c][1] - ctr[1]) / l);
            for d in 0..2 {
                if fix[c] & (1 << d) == 0 {
                    continue;
                }
                count += 1;
                let r = if d == 0 { [1.0, 0.0, -dy] } else { [0.0, 1.0, dx] };
                for i in 0..3 {
                    for j in 0..3 {
                        g[i][j] += r[i] * r[j];
                    }
                }
            }
        }
        if count > 0 {
            let ev = nalgebra::Matrix3::from_fn(|i, j| g[i][j]).symmetric_eigenvalues();
            if ev.min() <= 1e-10 * ev.max() {
                return Err(singular(model, &fr, f as u32, &format!("has no support that stops its rigid motion (its {count} prescribed dof(s) leave a translation or rotation free)")));
            }
            continue;
        }
        // No prescribed dof: node A (smallest x, then y, then index), node B (farthest).
        let ms = &members[f];
        let Some(&a) = ms.iter().min_by(|&&p, &&q| x0[p][0].total_cmp(&x0[q][0]).then(x0[p][1].total_cmp(&x0[q][1])).then(p.cmp(&q))) else { continue };
        let dist = |c: usize| (x0[c][0] - x0[a][0]).powi(2) + (x0[c][1] - x0[a][1]).powi(2);
        let b = ms.iter().copied().fold(a, |best, c| if dist(c) > dist(best) { c } else { best });
        let mut s = 0.0f64;
        let mut worst = [0.0f64; 2];
        for ld in loads {
            let (mut sx, mut sy, mut sm, mut ss) = (0.0, 0.0, 0.0, 0.0);
            for &c in ms {
                let v = ld[c];
                sx += v[0];
                sy += v[1];
                sm += (x0[c][0] - x0[a][0]) * v[1] - (x0[c][1] - x0[a][1]) * v[0];
                ss += v[0].hypot(v[1]);
            }
            let rf = if ss > 0.0 { sx.hypot(sy) / ss } else { 0.0 };
            let rm = if ss > 0.0 { sm.abs() / (ss * l) } else { 0.0 };
            if !(rf <= EQ_TOL && rm <= EQ_TOL) {
                return Err(singular(
                    model,
                    &fr,
                    f as u32,
                    &format!("has no prescribed dof at all, so nothing stops its rigid motion, and its loads are not in equilibrium (resultant force ({sx:.6e}, {sy:.6e}), moment {sm:.6e} about ({}, {}); {rf:.2e} and {rm:.2e} of the load, above {EQ_TOL:.0e}): no statically determinate support can carry it", x0[a][0], x0[a][1]),
                ));
            }
            s = s.max(ss);
            worst = [worst[0].max(rf), worst[1].max(rm)];
        }
        let (dx, dy) = (x0[b][0] - x0[a][0], x0[b][1] - x0[a][1]);
        let db: u8 = if dx.abs() >= dy.abs() { 1 } else { 0 };
        if b == a || (if db == 1 { dx } else { dy }).abs() <= 1e-12 * l {
            return Err(singular(model, &fr, f as u32, "has no prescribed dof at all and no two distinct points to pin"));
        }
        out.fix[a] |= 3;
        out.fix[b] |= 1 << db;
        out.added.push(AddedSupport { fragment: f as u32, description: fr.describe(model, f as u32), dofs: [(a, 0), (a, 1), (b, db)], at: [x0[a], x0[b]], load: s, resultant: worst, reaction: None });
    }
    Ok(out)
}

/// The reactions at the pinned dofs of `added` for the solution `u` under the load `f`
/// (`R = f_int(u) - f`): records the largest, relative to the fragment's load, and refuses a
/// solve whose reactions are above [`REACTION_TOL`] of it (or, for a fragment without load, not
/// zero to round-off of its internal forces).
pub fn check_reactions(model: &Model, added: &mut [AddedSupport], f: &[[f64; 2]], u: &[[f64; 2]]) -> Result<()> {
    if added.is_empty() {
        return Ok(());
    }
    let mut fi = vec![[0.0; 2]; u.len()];
    model.internal_forces(u, &mut fi);
    for a in added.iter_mut() {
        let r = a.dofs.iter().map(|&(c, d)| (fi[c][d as usize] - f[c][d as usize]).abs()).fold(0.0, f64::max);
        if a.load > 0.0 {
            let rel = r / a.load;
            a.reaction = Some(a.reaction.map_or(rel, |x| x.max(rel)));
            if !(rel <= REACTION_TOL) {
                return Err(FlemError::Solve(format!(
                    "{PREFIX}: {}: the reactions of the statically determinate support added to it are {rel:.2e} of its load, above {REACTION_TOL:.0e}: the solve is not that of the free body",
                    a.description
                )));
            }
        } else if !(r == 0.0 || r <= 1e-12 * fi.iter().map(|v| v[0].abs() + v[1].abs()).fold(0.0, f64::max)) {
            return Err(FlemError::Solve(format!("{PREFIX}: {}: without load, the reactions of the support added to it are {r:.2e}, not zero", a.description)));
        }
    }
    Ok(())
}

/// The solution of [`solve_supported`].
#[derive(Clone, Debug)]
pub struct Supported {
    pub u: Vec<[f64; 2]>,
    /// The statically determinate supports added (empty when every fragment had its own).
    pub added: Vec<AddedSupport>,
}

impl Supported {
    pub fn notes(&self) -> Vec<String> {
        self.added.iter().map(AddedSupport::note).collect()
    }
}

/// `solver.solve` with the supports of [`plan`]: a fragment without prescribed dofs under
/// self-equilibrated loads gets a statically determinate support whose reactions are checked
/// to be zero to round-off; any other fragment that cannot be solved is refused, named.
pub fn solve_supported(solver: &dyn CheckSolver, model: &Model, fix: &[u8], f_ext: &[[f64; 2]], u_prescribed: &[[f64; 2]]) -> Result<Supported> {
    let Plan { fix: fx, mut added } = plan(model, fix, &[f_ext])?;
    let u = solver.solve(model, &fx, f_ext, u_prescribed)?;
    check_reactions(model, &mut added, f_ext, &u)?;
    Ok(Supported { u, added })
}

/// Adds to `u_imp`, on each fragment of `added`, the rigid motion that fits `u - u_imp` best in
/// the least-squares sense over the fragment's clusters (module doc). Clusters of other
/// fragments are untouched.
pub fn align_rigid(model: &Model, added: &[AddedSupport], u: &[[f64; 2]], u_imp: &mut [[f64; 2]]) {
    if added.is_empty() {
        return;
    }
    let fr = Fragments::new(model);
    let x0 = model.cluster_x0();
    for a in added {
        let ms: Vec<usize> = (0..fr.cluster_frag.len()).filter(|&c| fr.cluster_frag[c] == a.fragment).collect();
        if ms.is_empty() {
            continue;
        }
        let n = ms.len() as f64;
        let (mut xc, mut yc, mut dxm, mut dym) = (0.0, 0.0, 0.0, 0.0);
        for &c in &ms {
            xc += x0[c][0] / n;
            yc += x0[c][1] / n;
            dxm += (u[c][0] - u_imp[c][0]) / n;
            dym += (u[c][1] - u_imp[c][1]) / n;
        }
        let (mut num, mut den) = (0.0, 0.0);
        for &c in &ms {
            let (rx, ry) = (x0[c][0] - xc, x0[c][1] - yc);
            let (dx, dy) = (u[c][0] - u_imp[c][0] - dxm, u[c][1] - u_imp[c][1] - dym);
            num += rx * dy - ry * dx;
            den += rx * rx + ry * ry;
        }
        let th = if den > 0.0 { num / den } else { 0.0 };
        for &c in &ms {
            let (rx, ry) = (x0[c][0] - xc, x0[c][1] - yc);
            u_imp[c][0] += dxm - th * ry;
            u_imp[c][1] += dym + th * rx;
        }
    }
}
