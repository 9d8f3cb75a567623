//! The events solver's kept factorisation (issue 19, ours): `ImplicitSolver::events_factor`.
//!
//! A fresh factorisation (the check solver's assembly, faer's symbolic and numeric Cholesky) is
//! made at the first call and again every `refactor_every` updates; in between, each call
//! corrects the kept factor of `K_0` by a low-rank (Woodbury / capacitance) update, as measured
//! by `flem bench events --woodbury` (`woodbury.rs`, where the algebra is written out):
//!
//! ```text
//! K = A_0 + W L W^T,  A_0 = diag(K_0, I),   K^{-1} b = y - Z (L^{-1} + W^T Z)^{-1} W^T y,
//! y = A_0^{-1} b,  Z = A_0^{-1} W.
//! ```
//!
//! Here each call's new terms come from the elements whose connectivity changed since the last
//! call: `D = sum_e (K_e at its new clusters - K_e at its old clusters) - I (new dofs)`, a dense
//! block on a few dofs, eigen-decomposed (pairs with `|l| > 1e-12 max |l|` kept). New clusters
//! are numbered last by the check solver's dof numbering, so the free dofs of `K_0` keep their
//! numbers. Every updated solution is checked by its residual (internal forces of the solution
//! against the external force on free dofs, 1e-9 of their scale); a failed check, a change of
//! fixities, or a capacitance above 2000 columns falls back to a fresh factorisation, whose
//! failure (a fragment without support, a hinge) is named by the check solver's own messages.
use crate::elements::{Q4, T3};
use faer::Mat;
use flem_core::element::model::Model;
use flem_core::mesh::CellKind;
use flem_core::plugin::check::EventsFactor;
use flem_core::FlemError;

use super::{assemble, dof_coords, factor, number_dofs, refined_solve, ImplicitSolver, Timings};

struct Base {
    /// Free dofs and clusters of `K_0`.
    n0: usize,
    llt: factor::Factor,
    /// Fixities and connectivity (per block, flattened) at the last call.
    fix: Vec<u8>,
    conn: Vec<Vec<u32>>,
    w: Vec<Vec<(usize, f64)>>,
    z: Vec<Vec<f64>>,
    lam: Vec<f64>,
    updates: usize,
}

/// See the module docs.
pub struct KeptFactor {
    refactor_every: usize,
    base: Option<Base>,
    fresh: u64,
    updates: u64,
    /// The fill-reducing ordering of the last fresh factorisation and the fixities it was made
    /// for: the next fresh factorisation extends it (`factor::extend_ordering`) instead of
    /// computing a new one while the fixities of the old clusters are unchanged.
    order: Option<(Vec<u8>, Vec<usize>)>,
    orderings: u64,
}

impl KeptFactor {
    pub fn new(refactor_every: usize) -> Self {
        KeptFactor { refactor_every, base: None, fresh: 0, updates: 0, order: None, orderings: 0 }
    }

    /// Fresh factorisations whose ordering was computed from scratch (the others extended the
    /// previous ordering).
    pub fn orderings(&self) -> u64 {
        self.orderings
    }

    /// The ordering for the free dofs numbered by `eq` (`n` of them).
    fn ordering(&mut self, model: &Model, fix: &[u8], eq: &[usize], n: usize, a: &faer::sparse::SparseColMat<usize, f64>) -> Vec<usize> {
        if let Some((ofix, old)) = &self.order {
            let n_old = old.len();
            if fix.len() >= ofix.len() && fix[..ofix.len()] == ofix[..] && n >= n_old {
                // New clusters are numbered last, so the old free dofs keep their numbers; each
                // new dof goes after the same-direction dof of its point's original cluster.
                let topo = &model.topo;
                let mut parent = vec![usize::MAX; n - n_old];
                for c in ofix.len()..fix.len() {
                    let c0 = topo.point_clusters[topo.cluster_point[c].idx()][0].idx();
                    for d in 0..2 {
                        let k = eq[2 * c + d];
                        if k != usize::MAX && k >= n_old {
                            parent[k - n_old] = eq[2 * c0 + d];
                        }
                    }
                }
                let order = factor::extend_ordering(old, n, &parent);
                self.order = Some((fix.to_vec(), order.clone()));
                return order;
            }
        }
        let order = factor::nested_dissection(a.symbolic(), &dof_coords(model, eq, n));
        self.orderings += 1;
        self.order = Some((fix.to_vec(), order.clone()));
        order
    }
}

fn conn_of(model: &Model) -> Vec<Vec<u32>> {
    model.blocks.iter().map(|b| (0..b.len()).flat_map(|i| b.conn(i).iter().copied()).collect()).collect()
}

/// Displacement of every cluster from the free-dof solution `x` and the prescribed values.
fn to_clusters(x: &[f64], eq: &[usize], fix: &[u8], up: &[[f64; 2]]) -> Vec<[f64; 2]> {
    (0..fix.len()).map(|c| std::array::from_fn(|d| if eq[2 * c + d] == usize::MAX { up[c][d] } else { x[eq[2 * c + d]] })).collect()
}

/// `max |f - F_int(u)|` over free dofs within 1e-9 of their scale.
fn residual_ok(model: &Model, u: &[[f64; 2]], f: &[[f64; 2]], fix: &[u8]) -> bool {
    let mut fi = vec![[0.0; 2]; u.len()];
    model.internal_forces(u, &mut fi);
    let (mut r, mut s) = (0.0f64, 0.0f64);
    for c in 0..u.len() {
        for d in 0..2 {
            if fix[c] & (1 << d) == 0 {
                r = r.max((f[c][d] - fi[c][d]).abs());
                s = s.max(f[c][d].abs()).max(fi[c][d].abs());
            }
        }
    }
    r.is_finite() && r <= 1e-9 * s.max(f64::MIN_POSITIVE) || s == 0.0 && r == 0.0
}

impl KeptFactor {
    /// A fresh factorisation; errors through the check solver's own solve (named fragments).
    fn fresh(&mut self, model: &Model, fix: &[u8], rhs: &[(Vec<[f64; 2]>, Vec<[f64; 2]>)]) -> Result<Vec<Vec<[f64; 2]>>, FlemError> {
        self.base = None;
        let named =
            |i: usize| ImplicitSolver::new().solve(model, fix, &rhs[i].0, &rhs[i].1).err().unwrap_or_else(|| FlemError::Solve("the kept factorisation failed where the check solver did not".into()));
        let (eq, n) = number_dofs(fix);
        if n == 0 {
            return rhs.iter().map(|(f, up)| ImplicitSolver::new().solve(model, fix, f, up)).collect();
        }
        let (a, _) = ImplicitSolver::assembled(model, fix, &rhs[0].0, &rhs[0].1);
        let order = self.ordering(model, fix, &eq, n, &a);
        let Ok(sym) = factor::symbolic(a.symbolic(), &order) else { return Err(named(0)) };
        let Ok(llt) = factor::Factor::new(sym, &a, factor::par(n)) else { return Err(named(0)) };
        let mut out = Vec::new();
        for (i, (f, up)) in rhs.iter().enumerate() {
            let b = assemble::rhs_by_forces(model, &eq, n, fix, f, up);
            let Some(x) = refined_solve(&llt, &a, &b, true, &mut Timings::default()) else { return Err(named(i)) };
            out.push(to_clusters(&x, &eq, fix, up));
        }
        self.fresh += 1;
        self.base = Some(Base { n0: n, llt, fix: fix.to_vec(), conn: conn_of(model), w: Vec::new(), z: Vec::new(), lam: Vec::new(), updates: 0 });
        Ok(out)
    }

    /// The update; `None` when it cannot be used (then a fresh factorisation follows).
    fn update(&mut self, model: &Model, fix: &[u8], rhs: &[(Vec<[f64; 2]>, Vec<[f64; 2]>)]) -> Option<Vec<Vec<[f64; 2]>>> {
        let base = self.base.as_mut()?;
        let nc_last = base.fix.len();
        if fix.len() < nc_last || fix[..nc_last] != base.fix[..] || base.updates >= self.refactor_every || base.conn.len() != model.blocks.len() {
            return None;
        }
        let (eq, n) = number_dofs(fix);
        // The dofs touched: the changed elements' old and new dofs, the new clusters' dofs.
        let mut touched: Vec<(usize, usize, Vec<u32>)> = Vec::new();
        for (bi, blk) in model.blocks.iter().enumerate() {
            let nn = blk.conn(0).len();
            for i in 0..blk.len() {
                let old = &base.conn[bi][i * nn..(i + 1) * nn];
                if old != blk.conn(i) {
                    touched.push((bi, i, old.to_vec()));
                }
            }
        }
        let mut s: Vec<usize> = Vec::new();
        let dof = |c: u32, d: usize| eq[2 * c as usize + d];
        for (bi, i, old) in &touched {
            for &c in old.iter().chain(model.blocks[*bi].conn(*i)) {
                s.extend((0..2).map(|d| dof(c, d)).filter(|&k| k != usize::MAX));
            }
        }
        for c in nc_last..fix.len() {
            s.extend((0..2).map(|d| dof(c as u32, d)).filter(|&k| k != usize::MAX));
        }
        s.sort_unstable();
        s.dedup();
        if !s.is_empty() {
            let m = s.len();
            let mut dm = nalgebra::DMatrix::<f64>::zeros(m, m);
            let pos = |k: usize| s.binary_search(&k).expect("in s");
            let mut ke = [0.0; 64];
            for (bi, i, old) in &touched {
                let blk = &model.blocks[*bi];
                let mat = blk.material();
                let nn = old.len();
                if !blk.isoparametric() {
                    // An element with condensed internal fields (`qm6`): its own stiffness, as
                    // the full assembly takes it (assemble.rs).
                    blk.stiffness(*i, &mut ke[..4 * nn * nn]);
                } else {
                    match blk.kind() {
                        CellKind::Q4 => assemble::elem_stiffness::<Q4, 4>(blk.coords(*i), &mat.dmat(), mat.thickness, &mut ke),
                        CellKind::T3 => assemble::elem_stiffness::<T3, 3>(blk.coords(*i), &mat.dmat(), mat.thickness, &mut ke),
                    }
                }
                for (sign, conn) in [(1.0, blk.conn(*i)), (-1.0, &old[..])] {
                    for r in 0..2 * nn {
                        let kr = dof(conn[r / 2], r % 2);
                        if kr == usize::MAX {
                            continue;
                        }
                        for q in 0..2 * nn {
                            let kq = dof(conn[q / 2], q % 2);
                            if kq != usize::MAX {
                                dm[(pos(kr), pos(kq))] += sign * ke[r * 2 * nn + q];
                            }
                        }
                    }
                }
            }
            for c in nc_last..fix.len() {
                for d in 0..2 {
                    if dof(c as u32, d) != usize::MAX {
                        let p = pos(dof(c as u32, d));
                        dm[(p, p)] -= 1.0;
                    }
                }
            }
            let eig = dm.symmetric_eigen();
            let big = eig.eigenvalues.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let first = base.w.len();
            for (q, &l) in eig.eigenvalues.iter().enumerate() {
                if l.abs() > 1e-12 * big {
                    base.w.push(s.iter().enumerate().map(|(ii, &k)| (k, eig.eigenvectors[(ii, q)])).filter(|x| x.1 != 0.0).collect());
                    base.lam.push(l);
                }
            }
            if base.w.len() > 2000 {
                return None;
            }
            for z in base.z.iter_mut() {
                z.resize(n, 0.0);
            }
            let r_new = base.w.len() - first;
            let mut zn = Mat::<f64>::zeros(n, r_new);
            for q in 0..r_new {
                for &(k, v) in &base.w[first + q] {
                    zn[(k, q)] = v;
                }
            }
            base.llt.solve_in_place(zn.as_mut().subrows_mut(0, base.n0), factor::par(base.n0));
            for q in 0..r_new {
                base.z.push((0..n).map(|k| zn[(k, q)]).collect());
            }
        }
        let r = base.w.len();
        let lu = nalgebra::DMatrix::from_fn(r, r, |a, b| base.w[a].iter().map(|&(k, x)| x * base.z[b][k]).sum::<f64>() + if a == b { 1.0 / base.lam[a] } else { 0.0 }).lu();
        let mut out = Vec::new();
        for (f, up) in rhs {
            let b = assemble::rhs_by_forces(model, &eq, n, fix, f, up);
            let mut y = Mat::<f64>::from_fn(n, 1, |k, _| b[k]);
            base.llt.solve_in_place(y.as_mut().subrows_mut(0, base.n0), factor::par(base.n0));
            let x: Vec<f64> = if r > 0 {
                let wy = nalgebra::DVector::from_fn(r, |a, _| base.w[a].iter().map(|&(k, x)| x * y[(k, 0)]).sum());
                let c = lu.solve(&wy)?;
                (0..n).map(|k| y[(k, 0)] - (0..r).map(|a| base.z[a][k] * c[a]).sum::<f64>()).collect()
            } else {
                (0..n).map(|k| y[(k, 0)]).collect()
            };
            let u = to_clusters(&x, &eq, fix, up);
            if !residual_ok(model, &u, f, fix) {
                return None;
            }
            out.push(u);
        }
        base.fix = fix.to_vec();
        base.conn = conn_of(model);
        base.updates += 1;
        self.updates += 1;
        Some(out)
    }
}

impl EventsFactor for KeptFactor {
    fn solve_many(&mut self, model: &Model, fix: &[u8], rhs: &[(Vec<[f64; 2]>, Vec<[f64; 2]>)]) -> Result<Vec<Vec<[f64; 2]>>, FlemError> {
        if let Some(u) = self.update(model, fix, rhs) {
            return Ok(u);
        }
        self.fresh(model, fix, rhs)
    }

    fn counts(&self) -> (u64, u64) {
        (self.fresh, self.updates)
    }
}

#[cfg(test)]
mod tests {
    use flem_core::element::model::Model;
    use flem_core::element::Plane;
    use flem_core::mesh::{CellKind, Rectangle, ValidationOptions};
    use flem_core::plugin::check::EventsFactor;
    use flem_core::scene::MaterialCfg;

    use super::*;

    /// Fresh factorisations after splits (refactor_every = 0: every call is fresh) reuse the
    /// first nested-dissection ordering, extended with the new dofs; each solution equals the
    /// check solver's own fresh solve (reference; 1e-10 relative). A 12 x 8 bar clamped on the
    /// left, pulled on the right, cut one edge at a time along y = 4 from the left end.
    #[test]
    fn fresh_factorisations_after_splits_extend_the_first_ordering() {
        crate::link();
        let (nx, ny) = (12usize, 8usize);
        let mut mesh = Rectangle::new(3.0, 2.0, nx, ny, CellKind::Q4).build().unwrap();
        mesh.validate(ValidationOptions::Reorient).unwrap();
        mesh.derive_node_sets();
        let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
        for k in 0..4 {
            mesh.edge_sets.insert(format!("cut{k}"), vec![[id(k, 4), id(k + 1, 4)]]);
        }
        let mut m = Model::new(mesh, &[MaterialCfg::elastic(1000.0, 0.3, 1.0)], Plane::Strain, "<test>").unwrap();
        let mut kept = KeptFactor::new(0);
        for k in 0..=4 {
            if k > 0 {
                let e = m.edge_set(&format!("cut{}", k - 1), "cut", "<test>").unwrap();
                let rec = m.topo.separate_edges(&e);
                m.apply_record(&rec);
            }
            let nc = m.topo.n_clusters();
            let x0 = m.cluster_x0();
            let fix: Vec<u8> = x0.iter().map(|x| if x[0] == 0.0 { 3 } else { 0 }).collect();
            let f: Vec<[f64; 2]> = x0.iter().map(|x| if x[0] == 3.0 { [1.0, 0.3] } else { [0.0; 2] }).collect();
            let zero = vec![[0.0; 2]; nc];
            let u = kept.solve_many(&m, &fix, &[(f.clone(), zero.clone())]).unwrap().remove(0);
            let want = ImplicitSolver::new().solve(&m, &fix, &f, &zero).unwrap();
            let scale = want.iter().map(|v| v[0].abs().max(v[1].abs())).fold(0.0, f64::max);
            for c in 0..nc {
                for d in 0..2 {
                    assert!((u[c][d] - want[c][d]).abs() <= 1e-10 * scale, "split {k}: cluster {c}: {:?} vs {:?}", u[c], want[c]);
                }
            }
            if k > 0 {
                assert!(nc > (nx + 1) * (ny + 1), "split {k} made no new cluster");
            }
        }
        assert_eq!(kept.counts().0, 5, "every call should have been a fresh factorisation");
        assert_eq!(kept.orderings(), 1, "the ordering was recomputed after splits");
    }
}
