//! The implicit plastic check (ours, issue 37): Newton-Raphson on the same model as the
//! explicit run (mesh, element kinds, B-bar, law and Gauss-point history, supports, loads),
//! with the consistent tangent of each law, so that a plastic stage has an independent
//! equilibrium beside FLEM's. docs/materials.md, "Implicit plastic check".
//!
//! Each block is seen through `Block::implicit` (`flem_core::element::implicit`): at trial
//! displacements `u` every Gauss point is updated from its last converged state with the
//! strain increment since then (the law's own `update`, the return map), giving the internal
//! force `f_int(u)` and the tangent `K_t = sum_e sum_gp Bbar^T D_alg Bbar w det J t` with
//! `D_alg = d sigma_{n+1} / d deps` the law's consistent tangent (`MaterialLaw::tangent`).
//! A load increment from the converged state `(u_n, lambda_n)` to `lambda_{n+1}`:
//!
//! ```text
//! u^0 = u_n with the prescribed dofs at u_p(lambda_{n+1})
//! r^i = f_ext(lambda_{n+1}) - f_int(u^i)             (free dofs)
//! K_t,ff(u^i) du = r^i,   u^{i+1} = u^i + du,        until |r^i|_2 <= tol |F|_2
//! ```
//!
//! with `|F|_2` the norm of the external force including the reactions (free dofs:
//! `f_ext`; prescribed dofs: `f_int - f_ext`), so that a displacement-driven stage (no
//! applied force) has a scale too. The load path of a stage is the straight one from the last
//! converged state to the stage's end (`f_ext` and the prescribed displacements), in
//! `increments` equal steps; an increment that does not converge in `MAX_ITER` iterations (or
//! whose solve fails) is halved, up to `MAX_BISECT` successive times, and after each converged
//! one the step doubles back towards the nominal one; at most `MAX_TRIES` tries per nominal
//! increment (a path that needs more crawls along its limit load: the stage is given up, said). Each iteration's relative residual
//! is recorded (the residual table of docs/materials.md: quadratic convergence with the
//! consistent tangent).
//!
//! Linear solves: a symmetric tangent (associated flow, elastic blocks) by our supernodal
//! Cholesky (`factor.rs`, nested-dissection ordering and symbolic analysis made once per
//! stage's fixities); a non-symmetric one (`psi < phi`), or one that is not positive definite
//! (a softening branch; at the limit load), by faer's sparse LU (`sp_lu`). Both are counted
//! in the stage's report. Ours, off by default (`NewtonCheck::shift`, session 17): at a
//! non-positive pivot, a Cholesky of `K + shift |diag K|` first (the Tresca footing's edge
//! points make the tangent singular but for round-off; docs/materials.md, "Speed of plastic
//! scenes").
use std::sync::Arc;

use faer::prelude::*;
use faer::sparse::{SparseColMat, SymbolicSparseColMat, Triplet};
use flem_core::element::implicit::{ImplicitBlock, Linear, TangentKind};
use flem_core::element::model::Model;
use flem_core::plugin::check::{NewtonRow, PlasticCheck, PlasticStage};
use flem_core::FlemError;

use super::{assemble, dof_coords, factor, number_dofs};

/// Relative residual at which an increment has converged.
pub const TOL: f64 = 1e-10;
/// Newton iterations per increment before it is halved.
pub const MAX_ITER: usize = 25;
/// Successive halvings of an increment before the stage is given up.
pub const MAX_BISECT: usize = 12;
/// Load increments tried per nominal increment (halvings included) before the stage is given
/// up: a path that needs more crawls along a limit load.
pub const MAX_TRIES: usize = 20;

const PREFIX: &str = "the implicit plastic check";

/// The Newton solver of a run (`PlasticCheck`): blocks with their own history, the converged
/// state, and the symbolic analysis of the current fixities.
#[derive(Default)]
pub struct NewtonCheck {
    blocks: Vec<Box<dyn ImplicitBlock>>,
    u: Vec<[f64; 2]>,
    f_ext: Vec<[f64; 2]>,
    f_int: Vec<[f64; 2]>,
    fix: Vec<u8>,
    sym: Option<(SymbolicSparseColMat<usize>, Arc<factor::Symbolic>)>,
    /// faer's symbolic LU of the full pattern (the same every iteration: every element
    /// coupling is assembled, zero or not), made at the first LU of the fixities.
    lu_sym: Option<faer::sparse::linalg::solvers::SymbolicLu<usize>>,
    /// Relative residual of convergence ([`TOL`]), Newton iterations per increment
    /// ([`MAX_ITER`]) and tries per nominal increment ([`MAX_TRIES`]).
    pub tol: f64,
    pub max_iter: usize,
    pub max_tries: usize,
    /// Ours (issue 37, default 0: off): when Cholesky meets a non-positive pivot, factorise
    /// `K + shift |diag K|` by Cholesky before falling back to LU. A Tresca point returned
    /// to an edge keeps only the bulk modulus of its principal stiffness (two active planes
    /// fix both principal differences), so a plastic zone of edge points makes the tangent
    /// singular but for round-off; the shift gives that null space a small stiffness. The
    /// step is then no longer the exact Newton step, but the convergence test (the residual)
    /// is the same, so a converged increment meets the same tolerance.
    pub shift: f64,
    /// Solves: Cholesky, LU, shifted Cholesky.
    counts: (usize, usize, usize),
}

/// The free dofs of an element's `2N` dofs (`eq[2 c + d]`).
fn elem_eq(conn: &[u32], eq: &[usize], out: &mut [usize; 8]) -> usize {
    let n2 = 2 * conn.len();
    for r in 0..n2 {
        out[r] = eq[2 * conn[r / 2] as usize + r % 2];
    }
    n2
}

impl NewtonCheck {
    pub fn new() -> Self {
        NewtonCheck { tol: TOL, max_iter: MAX_ITER, max_tries: MAX_TRIES, ..Default::default() }
    }

    fn init(&mut self, model: &Model) -> Result<(), FlemError> {
        let mut blocks: Vec<Box<dyn ImplicitBlock>> = Vec::with_capacity(model.blocks.len());
        for b in &model.blocks {
            blocks.push(match b.implicit() {
                None => {
                    let n2 = 2 * b.nodes_per_elem();
                    let mut k = vec![0.0; b.len() * n2 * n2];
                    for i in 0..b.len() {
                        b.stiffness(i, &mut k[i * n2 * n2..(i + 1) * n2 * n2]);
                    }
                    Box::new(Linear::new(b.nodes_per_elem(), k))
                }
                Some(Ok(ib)) => ib,
                Some(Err(why)) => return Err(FlemError::Solve(format!("{PREFIX} cannot follow {why}"))),
            });
        }
        let nc = model.topo.n_clusters();
        *self = NewtonCheck {
            blocks,
            u: vec![[0.0; 2]; nc],
            f_ext: vec![[0.0; 2]; nc],
            f_int: vec![[0.0; 2]; nc],
            tol: self.tol,
            max_iter: self.max_iter,
            max_tries: self.max_tries,
            shift: self.shift,
            ..Default::default()
        };
        Ok(())
    }

    /// `f_int(u)` and the assembled tangent: the lower triangle on the kept pattern
    /// (`symmetric`) or every free entry as triplets.
    fn assemble(&mut self, model: &Model, u: &[[f64; 2]], eq: &[usize], n: usize, symmetric: bool) -> (Vec<[f64; 2]>, Result<SparseColMat<usize, f64>, FlemError>) {
        let mut fi = vec![[0.0; 2]; u.len()];
        let mut e = [0usize; 8];
        if symmetric {
            let (pat, _) = self.sym.as_ref().expect("made before");
            let (cp, ri) = (pat.col_ptr(), pat.row_idx());
            let mut vals = vec![0.0; ri.len()];
            for (ib, blk) in self.blocks.iter_mut().zip(&model.blocks) {
                ib.evaluate(&conn_of(blk.as_ref()), u, &mut fi, &mut |conn, ke| {
                    let n2 = elem_eq(conn, eq, &mut e);
                    for s in 0..n2 {
                        let col = e[s];
                        if col == usize::MAX {
                            continue;
                        }
                        let rows = &ri[cp[col]..cp[col + 1]];
                        for r in 0..n2 {
                            if e[r] == usize::MAX || e[r] < col {
                                continue;
                            }
                            let p = rows.binary_search(&e[r]).expect("the pattern holds every element coupling");
                            vals[cp[col] + p] += ke[r * n2 + s];
                        }
                    }
                });
            }
            (fi, Ok(SparseColMat::new(pat.clone(), vals)))
        } else {
            let mut trip = Vec::new();
            for (ib, blk) in self.blocks.iter_mut().zip(&model.blocks) {
                ib.evaluate(&conn_of(blk.as_ref()), u, &mut fi, &mut |conn, ke| {
                    let n2 = elem_eq(conn, eq, &mut e);
                    for r in 0..n2 {
                        for s in 0..n2 {
                            if e[r] != usize::MAX && e[s] != usize::MAX {
                                trip.push(Triplet::new(e[r], e[s], ke[r * n2 + s]));
                            }
                        }
                    }
                });
            }
            let k = SparseColMat::try_new_from_triplets(n, n, &trip).map_err(|e| FlemError::Solve(format!("{PREFIX}: assembly failed: {e:?}")));
            (fi, k)
        }
    }

    /// `K du = r`: Cholesky on the kept analysis, else (or when it fails) the shifted
    /// Cholesky when `shift > 0`, else faer's LU.
    fn solve(&mut self, k: &SparseColMat<usize, f64>, r: &[f64], symmetric: bool) -> Option<Vec<f64>> {
        if symmetric {
            let (_, sym) = self.sym.as_ref().expect("made before");
            if let Ok(l) = factor::Factor::new(sym.clone(), k, factor::par(r.len())) {
                let x = l.solve(r, factor::par(r.len()));
                if x.iter().all(|v| v.is_finite()) {
                    self.counts.0 += 1;
                    return Some(x);
                }
            }
            if self.shift > 0.0 {
                let ks = shifted(k, self.shift);
                if let Ok(l) = factor::Factor::new(sym.clone(), &ks, factor::par(r.len())) {
                    let x = l.solve(r, factor::par(r.len()));
                    if x.iter().all(|v| v.is_finite()) {
                        self.counts.2 += 1;
                        return Some(x);
                    }
                }
            }
        }
        let full = if symmetric { full_from_lower(k)? } else { k.clone() };
        if self.lu_sym.is_none() {
            self.lu_sym = Some(faer::sparse::linalg::solvers::SymbolicLu::try_new(full.symbolic()).ok()?);
        }
        let sym = self.lu_sym.clone().expect("set above");
        let lu = faer::sparse::linalg::solvers::Lu::try_new_with_symbolic(sym, full.as_ref()).ok()?;
        let mut x = r.to_vec();
        lu.solve_in_place(faer::MatMut::from_column_major_slice_mut(&mut x, r.len(), 1));
        self.counts.1 += 1;
        x.iter().all(|v| v.is_finite()).then_some(x)
    }

    /// Newton iterations of one increment to `(f, up)`: the converged `u`, `f_int` and the
    /// residual of every iteration; `Err` when it does not converge.
    #[allow(clippy::type_complexity)]
    fn increment(&mut self, model: &Model, eq: &[usize], n: usize, f: &[[f64; 2]], up: &[[f64; 2]], symmetric: bool) -> Result<(Vec<[f64; 2]>, Vec<[f64; 2]>, Vec<f64>), String> {
        let nc = self.u.len();
        let mut u = self.u.clone();
        for c in 0..nc {
            for d in 0..2 {
                if self.fix[c] & (1 << d) != 0 {
                    u[c][d] = up[c][d];
                }
            }
        }
        let mut res = Vec::new();
        for _ in 0..=self.max_iter {
            let (fi, k) = self.assemble(model, &u, eq, n, symmetric);
            let k = k.map_err(|e| e.to_string())?;
            let (mut r, mut rn, mut fnorm) = (vec![0.0; n], 0.0, 0.0);
            for c in 0..nc {
                for d in 0..2 {
                    let j = eq[2 * c + d];
                    if j == usize::MAX {
                        fnorm += (fi[c][d] - f[c][d]).powi(2);
                    } else {
                        r[j] = f[c][d] - fi[c][d];
                        rn += r[j] * r[j];
                        fnorm += f[c][d] * f[c][d];
                    }
                }
            }
            let rel = if fnorm > 0.0 { (rn / fnorm).sqrt() } else { rn.sqrt() };
            res.push(rel);
            if !rel.is_finite() {
                return Err("the residual is not finite".into());
            }
            if rel <= self.tol {
                return Ok((u, fi, res));
            }
            if res.len() > self.max_iter {
                break;
            }
            let du = self.solve(&k, &r, symmetric).ok_or("the tangent system could not be solved")?;
            for c in 0..nc {
                for d in 0..2 {
                    let j = eq[2 * c + d];
                    if j != usize::MAX {
                        u[c][d] += du[j];
                    }
                }
            }
        }
        Err(format!("no convergence in {} iterations (relative residual {:.2e})", self.max_iter, res.last().copied().unwrap_or(f64::NAN)))
    }
}

/// `K + shift diag(K)` of a matrix stored as its lower triangle (ours).
fn shifted(k: &SparseColMat<usize, f64>, shift: f64) -> SparseColMat<usize, f64> {
    let mut ks = k.clone();
    let (cp, ri) = (k.symbolic().col_ptr().to_vec(), k.symbolic().row_idx().to_vec());
    let v = ks.val_mut();
    for j in 0..k.ncols() {
        for p in cp[j]..cp[j + 1] {
            if ri[p] == j {
                v[p] += shift * v[p].abs();
            }
        }
    }
    ks
}

/// The current connectivity of a block, element after element.
fn conn_of(b: &dyn flem_core::element::block::Block) -> Vec<u32> {
    (0..b.len()).flat_map(|i| b.conn(i).iter().copied()).collect()
}

/// Both triangles of a matrix stored as its lower triangle.
fn full_from_lower(k: &SparseColMat<usize, f64>) -> Option<SparseColMat<usize, f64>> {
    let s = k.as_ref();
    let (cp, ri, v) = (s.col_ptr(), s.row_idx(), s.val());
    let mut trip = Vec::with_capacity(2 * v.len());
    for j in 0..k.ncols() {
        for p in cp[j]..cp[j + 1] {
            trip.push(Triplet::new(ri[p], j, v[p]));
            if ri[p] != j {
                trip.push(Triplet::new(j, ri[p], v[p]));
            }
        }
    }
    SparseColMat::try_new_from_triplets(k.nrows(), k.ncols(), &trip).ok()
}

impl PlasticCheck for NewtonCheck {
    fn advance(&mut self, model: &Model, fix: &[u8], f_ext: &[[f64; 2]], u_p: &[[f64; 2]], increments: usize) -> Result<PlasticStage, FlemError> {
        let nc = model.topo.n_clusters();
        if self.blocks.is_empty() {
            self.init(model)?;
        }
        if self.u.len() != nc || fix.len() != nc || f_ext.len() != nc || u_p.len() != nc {
            return Err(FlemError::Solve(format!("{PREFIX}: the model has {nc} clusters, the check {} (it follows no splits)", self.u.len())));
        }
        let (eq, n) = number_dofs(fix);
        let symmetric = self.blocks.iter().all(|b| b.symmetric());
        if self.fix != fix || self.sym.is_none() {
            self.fix = fix.to_vec();
            let pat = assemble::pattern(model, &eq, n);
            let order = factor::nested_dissection(pat.as_ref(), &dof_coords(model, &eq, n));
            let sym = factor::symbolic(pat.as_ref(), &order).map_err(|e| FlemError::Solve(format!("{PREFIX}: symbolic factorisation failed: {e}")))?;
            self.sym = Some((pat, sym));
            self.lu_sym = None;
        }
        self.counts = (0, 0, 0);
        let (u0, f0) = (self.u.clone(), self.f_ext.clone());
        let at = |lam: f64, a: &[[f64; 2]], b: &[[f64; 2]]| -> Vec<[f64; 2]> { a.iter().zip(b).map(|(x, y)| [x[0] + lam * (y[0] - x[0]), x[1] + lam * (y[1] - x[1])]).collect() };
        let mut st = PlasticStage::default();
        let nominal = 1.0 / increments.max(1) as f64;
        let (mut lam, mut dl, mut halvings, mut tries) = (0.0f64, nominal, 0usize, 0usize);
        while lam < 1.0 - 1e-12 {
            tries += 1;
            if tries > self.max_tries * increments.max(1) {
                return Err(FlemError::Solve(format!("{PREFIX}: {} load increments tried and the stage's path is at {lam:.6} only (the body is near its limit load)", tries - 1)));
            }
            let target = if lam + dl > 1.0 - 1e-12 { 1.0 } else { lam + dl };
            let (f, up) = (at(target, &f0, f_ext), at(target, &u0, u_p));
            match self.increment(model, &eq, n, &f, &up, symmetric) {
                Ok((u, fi, res)) => {
                    for b in self.blocks.iter_mut() {
                        b.commit();
                    }
                    (self.u, self.f_int, self.f_ext) = (u, fi, f);
                    st.increments += 1;
                    st.iterations += res.len() - 1;
                    st.table.extend(res.iter().enumerate().map(|(i, &r)| NewtonRow { increment: st.increments, level: target, iteration: i, residual: r }));
                    lam = target;
                    // Back towards the nominal increment after a halving.
                    dl = (2.0 * dl).min(nominal);
                    halvings = 0;
                }
                Err(why) => {
                    if halvings >= MAX_BISECT {
                        return Err(FlemError::Solve(format!("{PREFIX}: the load increment to {target:.6} of the stage's path did not converge after {halvings} halvings: {why}")));
                    }
                    halvings += 1;
                    st.bisections += 1;
                    dl = 0.5 * (target - lam);
                }
            }
        }
        let elastic: Vec<String> = model.blocks.iter().zip(&self.blocks).filter(|(_, ib)| ib.tangent() == TangentKind::Elastic).map(|(b, _)| format!("region \"{}\"", b.region())).collect();
        st.tangent = if elastic.is_empty() { "consistent".into() } else { format!("elastic (the law has no consistent tangent) in {}; consistent elsewhere", elastic.join(", ")) };
        st.factorisation = match self.counts {
            (c, 0, 0) => format!("{c} Cholesky (factor.rs)"),
            (c, l, 0) => format!("{c} Cholesky (factor.rs), {l} LU (faer; {})", if symmetric { "a non-positive pivot in Cholesky" } else { "non-symmetric tangent" }),
            (c, l, s) => format!("{c} Cholesky (factor.rs), {s} shifted Cholesky, {l} LU (faer)"),
        };
        Ok(st)
    }
    fn displacement(&self) -> &[[f64; 2]] {
        &self.u
    }
    fn internal_force(&self) -> &[[f64; 2]] {
        &self.f_int
    }
    fn point_stress(&self) -> Vec<Vec<[f64; 4]>> {
        self.blocks.iter().map(|b| b.stress().to_vec()).collect()
    }
    fn yielded(&self) -> Vec<Vec<bool>> {
        self.blocks
            .iter()
            .map(|b| {
                let mut v = Vec::new();
                b.yielded(&mut v);
                v
            })
            .collect()
    }
}
