//! `flem bench events --woodbury` (issue 19): what a crack event costs the events solver's
//! linear algebra, a fresh factorisation against a kept factor corrected by a low-rank
//! (Woodbury / capacitance) update, measured on the same matrices.
//!
//! A split gives the parent cluster's copies in one part of its fan a new cluster (two new
//! dofs). With the dofs numbered as the check solver numbers them (new clusters last, old dofs
//! keep their numbers), the stiffness after event `j` is
//!
//! ```text
//! K_j = A_0 + sum_{i <= j} D_i,   A_0 = diag(K_0, I),   D_i = K_i - diag(K_{i-1}, I_new_i)
//! ```
//!
//! (telescoping; `I` on the dofs added since the factorisation of `K_0`). Each `D_i` is nonzero
//! on the few dofs of the elements around the split point only; its eigen-decomposition keeps
//! `r_i` (typically 4-8) pairs, `D_i = W_i L_i W_i^T`. With `W = [W_1 ...]`, `L = diag(L_i)` and
//! `Z = A_0^{-1} W` (`r_i` new solves with the kept factor per event, earlier columns kept):
//!
//! ```text
//! K_j^{-1} b = y - Z (L^{-1} + W^T Z)^{-1} W^T y,   y = A_0^{-1} b.
//! ```
//!
//! The bench cuts a horizontal crack into a clamped Q4 cantilever (the `flem bench implicit`
//! problem) edge by edge from its free end and, per event, times (a) the check solver's cold path
//! (pattern, symbolic, numeric, solve) and (b) the update (eigen-decomposition of `D_j`, `r_j`
//! solves, the capacitance LU, one solve and the correction), and checks that both give the same
//! displacement. `D_j` is found here by a full assembly and a difference (reported apart, as
//! `delta_seconds`): an events solver would form it from the moved elements' matrices alone.
use std::time::Instant;

use faer::prelude::*;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::SparseColMat;
use faer::{Mat, Side};
use flem_core::element::model::Model;
use flem_core::element::Plane;
use flem_core::mesh::{CellKind, Rectangle, ValidationOptions};
use flem_core::scene::MaterialCfg;
use flem_core::FlemError;
use serde::Serialize;

use super::ImplicitSolver;

/// One event of the measurement.
#[derive(Debug, Serialize)]
pub struct WoodburyRow {
    pub event: usize,
    pub dofs: usize,
    /// Rank kept from this event's `D_j`, and the total `R` of the capacitance matrix.
    pub rank: usize,
    pub total_rank: usize,
    /// The check solver's cold path on `K_j` (assembly, symbolic, numeric, solve).
    pub fresh_seconds: f64,
    /// The update: eigen-decomposition, new solves, capacitance, one solve and the correction.
    pub update_seconds: f64,
    /// Forming `D_j` by this bench's shortcut (full assembly and difference); not in the above.
    pub delta_seconds: f64,
    /// `|u_update - u_fresh| / |u_fresh|`.
    pub rel_difference: f64,
}

/// The whole measurement.
#[derive(Debug, Serialize)]
pub struct WoodburyBench {
    pub what: &'static str,
    pub elements: usize,
    pub dofs0: usize,
    /// Kept factor of `K_0`: symbolic + numeric seconds.
    pub factor_seconds: f64,
    pub rows: Vec<WoodburyRow>,
    pub mean_fresh_seconds: f64,
    pub mean_update_seconds: f64,
}

fn err(e: impl std::fmt::Debug) -> FlemError {
    FlemError::Solve(format!("bench woodbury: {e:?}"))
}

/// Dense copy of the entries of the lower-triangle matrix `a` in rows and columns `s` (sorted).
fn dense_sub(a: &SparseColMat<usize, f64>, s: &[usize]) -> nalgebra::DMatrix<f64> {
    let sa = a.as_ref();
    let (cp, ri, v) = (sa.col_ptr(), sa.row_idx(), sa.val());
    let m = s.len();
    let mut d = nalgebra::DMatrix::zeros(m, m);
    for (jj, &j) in s.iter().enumerate() {
        if j >= a.ncols() {
            continue;
        }
        for p in cp[j]..cp[j + 1] {
            if let Ok(ii) = s.binary_search(&ri[p]) {
                d[(ii, jj)] = v[p];
                d[(jj, ii)] = v[p];
            }
        }
    }
    d
}

/// Dofs whose column differs between `k` (new) and `diag(prev, I)`.
fn changed_dofs(k: &SparseColMat<usize, f64>, prev: &SparseColMat<usize, f64>) -> Vec<usize> {
    let (a, b) = (k.as_ref(), prev.as_ref());
    let mut s = Vec::new();
    let n0 = prev.ncols();
    for j in 0..k.ncols() {
        let col_a: Vec<(usize, f64)> = (a.col_ptr()[j]..a.col_ptr()[j + 1]).map(|p| (a.row_idx()[p], a.val()[p])).collect();
        let col_b: Vec<(usize, f64)> = if j < n0 { (b.col_ptr()[j]..b.col_ptr()[j + 1]).map(|p| (b.row_idx()[p], b.val()[p])).collect() } else { vec![(j, 1.0)] };
        let scale = col_a.iter().chain(&col_b).fold(0.0f64, |m, x| m.max(x.1.abs()));
        let get = |c: &[(usize, f64)], i: usize| c.iter().find(|x| x.0 == i).map_or(0.0, |x| x.1);
        let rows: std::collections::BTreeSet<usize> = col_a.iter().chain(&col_b).map(|x| x.0).collect();
        for i in rows {
            if (get(&col_a, i) - get(&col_b, i)).abs() > 1e-13 * scale {
                s.push(i);
                s.push(j);
            }
        }
    }
    s.sort_unstable();
    s.dedup();
    s
}

/// The measurement on about `dofs` dofs, `events` splits.
pub fn bench_woodbury(dofs: f64, events: usize) -> Result<WoodburyBench, FlemError> {
    let ny = (((dofs / 4.0).sqrt().round() as usize).max(2) / 2) * 2;
    let nx = 2 * ny;
    let mut mesh = Rectangle::new(2.0, 1.0, nx, ny, CellKind::Q4).build()?;
    mesh.validate(ValidationOptions::Reorient)?;
    mesh.derive_node_sets();
    let mat = MaterialCfg::elastic(1000.0, 0.3, 1.0);
    let mut m = Model::new(mesh, &[mat], Plane::Strain, "<bench>")?;
    let left: Vec<u32> = m.mesh.node_sets["left"].clone();
    let right: Vec<u32> = m.mesh.node_sets["right"].clone();
    let cond = |m: &Model| -> (Vec<u8>, Vec<[f64; 2]>) {
        let nc = m.topo.n_clusters();
        let mut fix = vec![0u8; nc];
        let mut f = vec![[0.0; 2]; nc];
        for c in 0..nc {
            let p = m.topo.cluster_point[c].0;
            if left.contains(&p) {
                fix[c] = 3;
            }
            if right.contains(&p) && m.topo.point_clusters[p as usize][0].idx() == c {
                f[c] = [0.0, -1.0 / ny as f64];
            }
        }
        (fix, f)
    };
    // The crack: the mid-height edges, from the free end inwards.
    let mut crack: Vec<(f64, flem_core::ids::EdgeId)> = Vec::new();
    for (k, e) in m.topo.edges.iter().enumerate() {
        let [a, b] = e.points;
        let (pa, pb) = (m.mesh.points[a.idx()], m.mesh.points[b.idx()]);
        if (pa[1] - 0.5).abs() < 1e-9 && (pb[1] - 0.5).abs() < 1e-9 {
            crack.push((-(pa[0] + pb[0]), flem_core::ids::EdgeId(k as u32)));
        }
    }
    crack.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (fix0, f0) = cond(&m);
    let zero = vec![[0.0; 2]; f0.len()];
    let (k0, _) = ImplicitSolver::assembled(&m, &fix0, &f0, &zero);
    let t = Instant::now();
    let sym = SymbolicLlt::try_new(k0.symbolic(), Side::Lower).map_err(err)?;
    let llt0 = Llt::try_new_with_symbolic(sym, k0.as_ref(), Side::Lower).map_err(err)?;
    let factor_seconds = t.elapsed().as_secs_f64();
    let n0 = k0.ncols();
    // A_0^{-1} x: the kept factor on the first n0 rows, identity on the rest.
    let a0_solve = |x: &mut Mat<f64>| {
        let mut top = x.as_mut().subrows_mut(0, n0);
        llt0.solve_in_place(top.as_mut());
    };
    // W by columns, sparse (the dofs of one split's elements); Z = A_0^{-1} W dense.
    let (mut w_cols, mut z_cols): (Vec<Vec<(usize, f64)>>, Vec<Vec<f64>>) = (Vec::new(), Vec::new());
    let mut lam: Vec<f64> = Vec::new();
    let mut prev = k0.clone();
    let mut rows = Vec::new();
    for (ev, &(_, edge)) in crack.iter().take(events).enumerate() {
        let rec = m.topo.separate_edges(&[edge]);
        m.apply_record(&rec);
        let (fix, f) = cond(&m);
        let zero = vec![[0.0; 2]; f.len()];
        // (a) fresh: the check solver's cold path.
        let t = Instant::now();
        let u_fresh = ImplicitSolver::new().solve(&m, &fix, &f, &zero)?;
        let fresh_seconds = t.elapsed().as_secs_f64();
        // D_j by the shortcut.
        let t = Instant::now();
        let (kj, rhs) = ImplicitSolver::assembled(&m, &fix, &f, &zero);
        let s = changed_dofs(&kj, &prev);
        let dk = dense_sub(&kj, &s);
        let mut dprev = dense_sub(&prev, &s);
        for (ii, &i) in s.iter().enumerate() {
            if i >= prev.ncols() {
                dprev[(ii, ii)] = 1.0;
            }
        }
        let delta_seconds = t.elapsed().as_secs_f64();
        // (b) the update.
        let t = Instant::now();
        let n = kj.ncols();
        let eig = (dk - dprev).symmetric_eigen();
        let big = eig.eigenvalues.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let mut rank = 0;
        let first_new = w_cols.len();
        for (q, &l) in eig.eigenvalues.iter().enumerate() {
            if l.abs() > 1e-12 * big {
                w_cols.push(s.iter().enumerate().map(|(ii, &i)| (i, eig.eigenvectors[(ii, q)])).collect());
                lam.push(l);
                rank += 1;
            }
        }
        // Earlier columns of Z grow by the new dofs (zeros: W had none there).
        for c in z_cols.iter_mut() {
            c.resize(n, 0.0);
        }
        let mut znew = Mat::<f64>::zeros(n, rank);
        for q in 0..rank {
            for &(i, v) in &w_cols[first_new + q] {
                znew[(i, q)] = v;
            }
        }
        a0_solve(&mut znew);
        for q in 0..rank {
            z_cols.push((0..n).map(|i| znew[(i, q)]).collect());
        }
        let r = w_cols.len();
        let cap = nalgebra::DMatrix::from_fn(r, r, |a, b| {
            let wz: f64 = w_cols[a].iter().map(|&(i, x)| x * z_cols[b][i]).sum();
            wz + if a == b { 1.0 / lam[a] } else { 0.0 }
        });
        let lu = cap.lu();
        let mut y = Mat::<f64>::from_fn(n, 1, |i, _| rhs[i]);
        a0_solve(&mut y);
        let wy = nalgebra::DVector::from_fn(r, |a, _| w_cols[a].iter().map(|&(i, x)| x * y[(i, 0)]).sum());
        let c = lu.solve(&wy).ok_or_else(|| err("singular capacitance"))?;
        let x: Vec<f64> = (0..n).map(|i| y[(i, 0)] - (0..r).map(|a| z_cols[a][i] * c[a]).sum::<f64>()).collect();
        let update_seconds = t.elapsed().as_secs_f64();
        // Compare on the free dofs.
        let (mut num, mut den, mut k) = (0.0, 0.0, 0);
        for c in 0..fix.len() {
            for d in 0..2 {
                if fix[c] & (1 << d) == 0 {
                    num += (x[k] - u_fresh[c][d]).powi(2);
                    den += u_fresh[c][d].powi(2);
                    k += 1;
                }
            }
        }
        rows.push(WoodburyRow { event: ev + 1, dofs: n, rank, total_rank: r, fresh_seconds, update_seconds, delta_seconds, rel_difference: (num / den).sqrt() });
        prev = kj;
    }
    let mean = |g: &dyn Fn(&WoodburyRow) -> f64| rows.iter().map(g).sum::<f64>() / rows.len().max(1) as f64;
    Ok(WoodburyBench {
        what: "one crack event: fresh faer factorisation (check solver cold path) against the kept factor of K_0 with a Woodbury/capacitance update (flem_plugins::check::woodbury)",
        elements: m.n_elems(),
        dofs0: n0,
        factor_seconds,
        mean_fresh_seconds: mean(&|r| r.fresh_seconds),
        mean_update_seconds: mean(&|r| r.update_seconds),
        rows,
    })
}
