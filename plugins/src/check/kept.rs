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
//! Here each call's new terms come from the elements whose connectivity (or, after a node moved
//! by the path method, ours, their corner coordinates) changed since the last call:
//! `D = sum_e (K_e at its new clusters - K_e at its old clusters) - I (new dofs)`, a dense
//! block on a few dofs, eigen-decomposed (pairs with `|l| > 1e-12 max |l|` kept). New clusters
//! are numbered last by the check solver's dof numbering, so the free dofs of `K_0` keep their
//! numbers.
//!
//! What a call costs (issue 19's profile of the notched plate h = 0.125, 18k dofs): one
//! multi-column solve with `K_0` for the `k` new columns `Z_new = A_0^{-1} W_new` (k about 6
//! per split), and one for the solutions, written as `x = A_0^{-1} (b - W c)` with
//! `c = C^{-1} W^T y`; no dense `Z` (n x r) is kept or multiplied. `C^{-1}` itself is kept and
//! grown by bordering (`S = C_new,new - B^T C_old^{-1} B` of size `k`), `O(r^2 k)` per call
//! instead of a new `O(r^3)` factorisation; `y = A_0^{-1} b` is kept per right-hand side while
//! `b` does not change on the dofs of `K_0`, and a zero right-hand side is not solved.
//!
//! Every updated solution is checked by its residual (internal forces of the solution
//! against the external force on free dofs, 1e-9 of their scale); a failed check, a change of
//! fixities, or a capacitance above 2000 columns falls back to a fresh factorisation, whose
//! failure (a fragment without support, a hinge) is named by the check solver's own messages.
//! Checkpoints (`EventsFactor::save_state`): the ordering of the last fresh factorisation, so
//! that a resumed run's fresh factorisation extends the same ordering.
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
    /// Corner coordinates (per block, flattened) at the last call: a node moved by the path
    /// method (ours, issue 34: `Model::move_point`) changes its elements' stiffness in place.
    coords: Vec<Vec<[f64; 2]>>,
    /// The low-rank terms `W` (sparse columns) and `L` (diagonal).
    w: Vec<Vec<(usize, f64)>>,
    lam: Vec<f64>,
    /// The inverse of the capacitance matrix `C = L^{-1} + W^T A_0^{-1} W` (`r x r`, row
    /// major), grown by bordering at each update (no dense `Z = A_0^{-1} W` is kept).
    cinv: Vec<f64>,
    /// `C` itself (`r x r`, row major): each capacitance solve `c = C^{-1} W^T y` is refined
    /// against it (the bordered inverse gathers round-off as it grows).
    cmat: Vec<f64>,
    /// Per right-hand side: the last `b` on the dofs of `K_0` and `y = K_0^{-1} b` there (a
    /// load that did not change is not solved again).
    ycache: Vec<(Vec<f64>, Vec<f64>)>,
    updates: usize,
    /// Ours (issue 34, session 18): once a node moved by the path method changed `K` since this
    /// factorisation, the forward halves `V = L^{-1} P W` of the low-rank columns (on `K_0`'s
    /// dofs, the factor's order, non-zero rows only): the capacitance's new entries are then
    /// `W_a^T K_0^{-1} W_q = V_a . V_q` (plus the new dofs' rows, where `A_0 = I`), from one
    /// sparse forward solve of the new columns (`Factor::forward_sparse`) instead of a full
    /// solve. `None`: no move yet (the paper's rules never move a node: their updates, and so
    /// their results, are those of before, bit for bit).
    v: Option<Vec<(Vec<u32>, Vec<f64>)>>,
}

/// The non-zero rows of column `q` of `y`.
fn sparse_col(y: &Mat<f64>, q: usize) -> (Vec<u32>, Vec<f64>) {
    let (mut rows, mut vals) = (Vec::new(), Vec::new());
    for i in 0..y.nrows() {
        let v = y[(i, q)];
        if v != 0.0 {
            rows.push(i as u32);
            vals.push(v);
        }
    }
    (rows, vals)
}

impl Base {
    /// `c = C^{-1} v` with the kept inverse, refined twice against `C`.
    fn cap_solve(&self, v: &[f64]) -> Vec<f64> {
        let r = self.w.len();
        let mul = |m: &[f64], v: &[f64]| -> Vec<f64> { (0..r).map(|a| m[a * r..(a + 1) * r].iter().zip(v).map(|(p, q)| p * q).sum()).collect() };
        let mut c = mul(&self.cinv, v);
        for _ in 0..2 {
            let cc = mul(&self.cmat, &c);
            let res: Vec<f64> = v.iter().zip(&cc).map(|(a, b)| a - b).collect();
            let dc = mul(&self.cinv, &res);
            c.iter_mut().zip(&dc).for_each(|(a, b)| *a += b);
        }
        c
    }

    /// `K^{-1} b` by the update, nothing kept (`n` dofs): the refinement step of a solution
    /// whose residual check failed.
    fn woodbury(&self, b: &[f64], n: usize) -> Vec<f64> {
        let par = factor::par(self.n0);
        let mut y = b.to_vec();
        self.llt.solve_in_place(faer::MatMut::from_column_major_slice_mut(&mut y[..self.n0], self.n0, 1), par);
        let mut x = b.to_vec();
        if !self.w.is_empty() {
            let wy: Vec<f64> = self.w.iter().map(|col| col.iter().map(|&(k, v)| v * y[k]).sum()).collect();
            let c = self.cap_solve(&wy);
            for (a, col) in self.w.iter().enumerate() {
                for &(k, v) in col {
                    x[k] -= v * c[a];
                }
            }
        }
        self.llt.solve_in_place(faer::MatMut::from_column_major_slice_mut(&mut x[..self.n0], self.n0, 1), par);
        debug_assert_eq!(x.len(), n);
        x
    }
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

fn coords_of(model: &Model) -> Vec<Vec<[f64; 2]>> {
    model.blocks.iter().map(|b| (0..b.len()).flat_map(|i| b.coords(i).iter().copied()).collect()).collect()
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
        self.base = Some(Base {
            n0: n,
            llt,
            fix: fix.to_vec(),
            conn: conn_of(model),
            coords: coords_of(model),
            w: Vec::new(),
            lam: Vec::new(),
            cinv: Vec::new(),
            cmat: Vec::new(),
            ycache: Vec::new(),
            updates: 0,
            v: None,
        });
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
        // (With the old corner coordinates, which differ only where the path method moved a
        // node: then the element's old stiffness is taken from them.)
        let mut touched: Vec<(usize, usize, Vec<u32>, Vec<[f64; 2]>)> = Vec::new();
        let mut moved_any = false;
        for (bi, blk) in model.blocks.iter().enumerate() {
            let nn = blk.conn(0).len();
            for i in 0..blk.len() {
                let old = &base.conn[bi][i * nn..(i + 1) * nn];
                let old_x = &base.coords[bi][i * nn..(i + 1) * nn];
                if old != blk.conn(i) || old_x != blk.coords(i) {
                    if old_x != blk.coords(i) {
                        if !blk.isoparametric() {
                            return None;
                        }
                        moved_any = true;
                    }
                    touched.push((bi, i, old.to_vec(), old_x.to_vec()));
                }
            }
        }
        let mut s: Vec<usize> = Vec::new();
        let dof = |c: u32, d: usize| eq[2 * c as usize + d];
        for (bi, i, old, _) in &touched {
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
            let mut ke_old = [0.0; 64];
            for (bi, i, old, old_x) in &touched {
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
                let moved = old_x[..] != *blk.coords(*i);
                if moved {
                    match blk.kind() {
                        CellKind::Q4 => assemble::elem_stiffness::<Q4, 4>(old_x, &mat.dmat(), mat.thickness, &mut ke_old),
                        CellKind::T3 => assemble::elem_stiffness::<T3, 3>(old_x, &mat.dmat(), mat.thickness, &mut ke_old),
                    }
                } else {
                    ke_old = ke;
                }
                for (sign, conn, k) in [(1.0, blk.conn(*i), &ke), (-1.0, &old[..], &ke_old)] {
                    for r in 0..2 * nn {
                        let kr = dof(conn[r / 2], r % 2);
                        if kr == usize::MAX {
                            continue;
                        }
                        for q in 0..2 * nn {
                            let kq = dof(conn[q / 2], q % 2);
                            if kq != usize::MAX {
                                dm[(pos(kr), pos(kq))] += sign * k[r * 2 * nn + q];
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
            // A node moved by the path method (ours) adds about 20 columns a call instead of a
            // split's 6; the capacitance's O(r^2 k) bordering then outgrows a fresh
            // factorisation sooner: such calls restart at 300 columns (the paper's rules never
            // move a node and keep the 2000 of before).
            let cap = if moved_any { 300 } else { 2000 };
            if base.w.len() > cap {
                return None;
            }
            let k = base.w.len() - first;
            if k > 0 {
                let r = base.w.len();
                let ro = first;
                let n0 = base.n0;
                // The capacitance's new columns `bt[a k + q] = W_a^T A_0^{-1} W_new,q` (all `r`
                // rows a).
                let bt: Vec<f64> = if base.v.is_some() || moved_any {
                    // Ours (session 18): the forward halves (see `Base::v`). The columns before
                    // this call are forward-solved once, at the first move since the fresh
                    // factorisation.
                    if base.v.is_none() {
                        let y = base.llt.forward_sparse(&base.w[..ro]);
                        base.v = Some((0..ro).map(|a| sparse_col(&y, a)).collect());
                    }
                    let yn = base.llt.forward_sparse(&base.w[ro..]);
                    let v = base.v.as_mut().expect("set above");
                    v.extend((0..k).map(|q| sparse_col(&yn, q)));
                    // The rows where some new column is non-zero, row-major (`k` values each).
                    let mut slot = vec![u32::MAX; n0];
                    let mut rows_k: Vec<f64> = Vec::new();
                    for i in 0..n0 {
                        if (0..k).any(|q| yn[(i, q)] != 0.0) {
                            slot[i] = (rows_k.len() / k) as u32;
                            rows_k.extend((0..k).map(|q| yn[(i, q)]));
                        }
                    }
                    // The new dofs' rows of W_new (A_0 = I there).
                    let mut wt = vec![0.0; (n - n0) * k];
                    for q in 0..k {
                        for &(i, x) in base.w[ro + q].iter().filter(|e| e.0 >= n0) {
                            wt[(i - n0) * k + q] = x;
                        }
                    }
                    let mut bt = vec![0.0; r * k];
                    for (a, (rows, vals)) in v.iter().enumerate() {
                        let acc = &mut bt[a * k..(a + 1) * k];
                        for (&i, &x) in rows.iter().zip(vals) {
                            let sl = slot[i as usize];
                            if sl != u32::MAX {
                                let y = &rows_k[sl as usize * k..(sl as usize + 1) * k];
                                acc.iter_mut().zip(y).for_each(|(s, y)| *s += x * y);
                            }
                        }
                        for &(i, x) in base.w[a].iter().filter(|e| e.0 >= n0) {
                            acc.iter_mut().zip(&wt[(i - n0) * k..(i - n0 + 1) * k]).for_each(|(s, y)| *s += x * y);
                        }
                    }
                    bt
                } else {
                    // Z_new = A_0^{-1} W_new (one multi-column solve; the rows of new dofs: A_0 = I).
                    let mut zn = Mat::<f64>::zeros(n, k);
                    for q in 0..k {
                        for &(i, v) in &base.w[first + q] {
                            zn[(i, q)] = v;
                        }
                    }
                    base.llt.solve_in_place(zn.as_mut().subrows_mut(0, base.n0), factor::par(base.n0));
                    (0..r * k).map(|e| base.w[e / k].iter().map(|&(i, x)| x * zn[(i, e % k)]).sum::<f64>()).collect()
                };
                let bm = |a: usize, q: usize| bt[a * k + q];
                // The capacitance's new columns B = W^T Z_new (all rows; the new rows with
                // L^{-1} on the diagonal), then the inverse grown by bordering:
                // E = C_old^{-1} B_old, S = B_new - B_old^T E,
                // C^{-1} = [[C_old^{-1} + E S^{-1} E^T, -E S^{-1}], [-S^{-1} E^T, S^{-1}]].
                let b_old: Vec<f64> = (0..ro * k).map(|e| bm(e / k, e % k)).collect();
                let c22 = nalgebra::DMatrix::<f64>::from_fn(k, k, |p, q| bm(ro + p, q) + if p == q { 1.0 / base.lam[ro + p] } else { 0.0 });
                let c22 = (c22.clone() + c22.transpose()) * 0.5;
                let mut smat = c22.clone();
                // After a move (ours, session 18: `Base::v`), the two products of size `r^2 k` go
                // through faer's matrix product (one thread); the paper's rules keep the loops
                // of before (their bits).
                let gemm = base.v.is_some();
                let mut e = vec![0.0; ro * k];
                if gemm && ro > 0 {
                    let mut em = faer::MatMut::from_row_major_slice_mut(&mut e, ro, k);
                    faer::linalg::matmul::matmul(
                        em.as_mut(),
                        faer::Accum::Replace,
                        faer::MatRef::from_row_major_slice(&base.cinv, ro, ro),
                        faer::MatRef::from_row_major_slice(&b_old, ro, k),
                        1.0,
                        faer::Par::Seq,
                    );
                } else {
                    for i in 0..ro {
                        let row = &base.cinv[i * ro..(i + 1) * ro];
                        for (j, &c) in row.iter().enumerate() {
                            if c != 0.0 {
                                for q in 0..k {
                                    e[i * k + q] += c * b_old[j * k + q];
                                }
                            }
                        }
                    }
                }
                for p in 0..k {
                    for q in 0..k {
                        smat[(p, q)] -= (0..ro).map(|i| b_old[i * k + p] * e[i * k + q]).sum::<f64>();
                    }
                }
                let sym = (smat.clone() + smat.transpose()) * 0.5;
                let sinv = sym.try_inverse()?;
                if sinv.iter().any(|v| !v.is_finite()) {
                    return None;
                }
                // F = E S^{-1} (ro x k).
                let mut f = vec![0.0; ro * k];
                for i in 0..ro {
                    for q in 0..k {
                        f[i * k + q] = (0..k).map(|p| e[i * k + p] * sinv[(p, q)]).sum();
                    }
                }
                let mut cinv = vec![0.0; r * r];
                let mut fe = Vec::new();
                if gemm && ro > 0 {
                    fe = vec![0.0; ro * ro];
                    let mut m = faer::MatMut::from_row_major_slice_mut(&mut fe, ro, ro);
                    faer::linalg::matmul::matmul(
                        m.as_mut(),
                        faer::Accum::Replace,
                        faer::MatRef::from_row_major_slice(&f, ro, k),
                        faer::MatRef::from_row_major_slice(&e, ro, k).transpose(),
                        1.0,
                        faer::Par::Seq,
                    );
                }
                for i in 0..ro {
                    if gemm {
                        for j in 0..ro {
                            cinv[i * r + j] = base.cinv[i * ro + j] + fe[i * ro + j];
                        }
                    } else {
                        for j in 0..ro {
                            cinv[i * r + j] = base.cinv[i * ro + j] + (0..k).map(|q| f[i * k + q] * e[j * k + q]).sum::<f64>();
                        }
                    }
                    for q in 0..k {
                        cinv[i * r + ro + q] = -f[i * k + q];
                        cinv[(ro + q) * r + i] = -f[i * k + q];
                    }
                }
                for p in 0..k {
                    for q in 0..k {
                        cinv[(ro + p) * r + ro + q] = sinv[(p, q)];
                    }
                }
                base.cinv = cinv;
                let mut cmat = vec![0.0; r * r];
                for i in 0..ro {
                    cmat[i * r..i * r + ro].copy_from_slice(&base.cmat[i * ro..(i + 1) * ro]);
                    for q in 0..k {
                        cmat[i * r + ro + q] = b_old[i * k + q];
                        cmat[(ro + q) * r + i] = b_old[i * k + q];
                    }
                }
                for p in 0..k {
                    for q in 0..k {
                        cmat[(ro + p) * r + ro + q] = c22[(p, q)];
                    }
                }
                base.cmat = cmat;
            }
        }
        let r = base.w.len();
        // y = A_0^{-1} b (kept per right-hand side while b does not change on K_0's dofs),
        // c = C^{-1} W^T y, then x = A_0^{-1} (b - W c): one multi-column solve for all.
        let bs: Vec<Vec<f64>> = rhs.iter().map(|(f, up)| assemble::rhs_by_forces(model, &eq, n, fix, f, up)).collect();
        base.ycache.resize(bs.len(), (Vec::new(), Vec::new()));
        let stale: Vec<usize> = (0..bs.len()).filter(|&i| base.ycache[i].0[..] != bs[i][..base.n0]).collect();
        if !stale.is_empty() {
            let mut y = Mat::<f64>::from_fn(base.n0, stale.len(), |k, j| bs[stale[j]][k]);
            base.llt.solve_in_place(y.as_mut(), factor::par(base.n0));
            for (j, &i) in stale.iter().enumerate() {
                base.ycache[i] = (bs[i][..base.n0].to_vec(), (0..base.n0).map(|k| y[(k, j)]).collect());
            }
        }
        let mut xs = Mat::<f64>::zeros(n, bs.len());
        for (j, b) in bs.iter().enumerate() {
            let y0 = &base.ycache[j].1;
            let yk = |k: usize| if k < base.n0 { y0[k] } else { b[k] };
            for k in 0..n {
                xs[(k, j)] = b[k];
            }
            if r > 0 {
                let wy: Vec<f64> = base.w.iter().map(|col| col.iter().map(|&(k, x)| x * yk(k)).sum()).collect();
                let c = base.cap_solve(&wy);
                for a in 0..r {
                    for &(k, x) in &base.w[a] {
                        xs[(k, j)] -= x * c[a];
                    }
                }
            }
        }
        // A zero right-hand side (no held load in a first stage) has the solution zero: only
        // the others are solved (the same bits: the solve of zeros gives +0 everywhere).
        let live: Vec<usize> = (0..bs.len()).filter(|&j| (0..n).any(|k| xs[(k, j)] != 0.0)).collect();
        if live.len() == bs.len() {
            base.llt.solve_in_place(xs.as_mut().subrows_mut(0, base.n0), factor::par(base.n0));
        } else if !live.is_empty() {
            let mut xl = Mat::<f64>::from_fn(base.n0, live.len(), |k, j| xs[(k, live[j])]);
            base.llt.solve_in_place(xl.as_mut(), factor::par(base.n0));
            for (j, &c) in live.iter().enumerate() {
                for k in 0..base.n0 {
                    xs[(k, c)] = xl[(k, j)];
                }
            }
        }
        let mut out = Vec::new();
        for (j, (f, up)) in rhs.iter().enumerate() {
            let mut x: Vec<f64> = (0..n).map(|k| xs[(k, j)]).collect();
            let mut u = to_clusters(&x, &eq, fix, up);
            if !residual_ok(model, &u, f, fix) {
                // One step of iterative refinement by the same update before falling back to
                // a fresh factorisation: r = b - K x on the free dofs, x += K^{-1} r.
                let mut fi = vec![[0.0; 2]; u.len()];
                model.internal_forces(&u, &mut fi);
                let mut r = vec![0.0; n];
                for c in 0..u.len() {
                    for d in 0..2 {
                        if eq[2 * c + d] != usize::MAX {
                            r[eq[2 * c + d]] = f[c][d] - fi[c][d];
                        }
                    }
                }
                let dx = base.woodbury(&r, n);
                x.iter_mut().zip(&dx).for_each(|(a, b)| *a += b);
                u = to_clusters(&x, &eq, fix, up);
                if !residual_ok(model, &u, f, fix) {
                    return None;
                }
            }
            out.push(u);
        }
        base.fix = fix.to_vec();
        base.conn = conn_of(model);
        base.coords = coords_of(model);
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

    fn fresh_next(&self) -> bool {
        self.base.as_ref().is_none_or(|b| b.updates >= self.refactor_every)
    }

    fn restart(&mut self) {
        self.base = None;
    }

    /// The ordering of the last fresh factorisation and the fixities it was made for:
    /// `[n_fix, fix..., order...]`.
    fn save_state(&self) -> Vec<u64> {
        match &self.order {
            Some((fix, order)) => std::iter::once(fix.len() as u64).chain(fix.iter().map(|&f| f as u64)).chain(order.iter().map(|&o| o as u64)).collect(),
            None => Vec::new(),
        }
    }

    fn load_state(&mut self, state: &[u64]) -> bool {
        if state.is_empty() {
            self.order = None;
            return true;
        }
        let nf = state[0] as usize;
        if state.len() < 1 + nf || state[1..1 + nf].iter().any(|&f| f > 3) {
            return false;
        }
        let order: Vec<usize> = state[1 + nf..].iter().map(|&o| o as usize).collect();
        let mut seen = vec![false; order.len()];
        if order.iter().any(|&o| o >= seen.len() || std::mem::replace(&mut seen[o], true)) {
            return false;
        }
        self.order = Some((state[1..1 + nf].iter().map(|&f| f as u8).collect(), order));
        self.base = None;
        true
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
