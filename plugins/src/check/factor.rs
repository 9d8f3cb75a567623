//! The sparse Cholesky factor of `K_ff` with a geometric nested-dissection ordering (ours), on
//! faer's low-level symbolic and numeric Cholesky.
//!
//! faer's high-level `SymbolicLlt::try_new` orders the matrix by approximate minimum degree
//! (AMD): on a 2D finite-element mesh of 5e5 dofs that ordering costs a quarter of the whole
//! solve, and its fill is larger than nested dissection's (George 1973: for a 2D mesh of `n`
//! nodes nested dissection gives `O(n log n)` fill and `O(n^1.5)` flops, the optimum). The
//! dofs here have coordinates (their cluster's reference position), so the dissection is
//! geometric: split the dofs at the median of the longer side of their bounding box, take as
//! separator the dofs of the first half that are coupled (a non-zero of `K`) to the second,
//! order first half, second half, separator; recurse down to `LEAF` dofs. The cut is at the
//! median coordinate by value, so that a grid line is never cut in two. Any permutation is
//! valid (the factor is exact whatever the ordering; only fill and time change), so cracks,
//! holes and duplicated points at split nodes cost at most fill, never correctness.
//!
//! Why not METIS: the `metis` crate binds the C library through bindgen, which needs libclang at
//! build time on every machine that builds FLEM; the geometric dissection is 100 lines, needs
//! nothing, and on the benchmark meshes gives less fill than AMD (`flem bench implicit` prints
//! `nnz_factor` for both). The ordering is cached with the symbolic analysis (`mod.rs`), and the
//! events solver's fresh factorisations reuse it (`extend_ordering`: dofs added by splits go
//! next to the dof they were split from), so a refactorisation after splits skips the ordering.
//!
//! Threads: from [`PAR_MIN_DOFS`] dofs on, the numeric factorisation and the triangular solves
//! take `Par::rayon(n)` with the calling pool's thread count (`rayon::current_num_threads`);
//! faer's supernodal kernels split work by blocks of the output, so the factor is bit-identical
//! whatever `n` (the unit test below checks it on 1 and 2 threads).
use std::sync::Arc;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::Perm;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering};
use faer::sparse::linalg::LltError;
use faer::sparse::{SparseColMat, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

/// Dissection stops at this many dofs (the leaf keeps its coordinate order). Measured on
/// `flem bench implicit`'s 5e5-dof mesh: leaves of 8 give 56.0 M entries in `L` (AMD: 59.5 M),
/// leaves of 24, 48 and 128 give more; ordering the leaves by AMD (as METIS orders its leaves by
/// minimum degree) gave no less fill at leaves of 48 (56.4 M) and cost a quarter of a second.
const LEAF: usize = 8;

/// Below this many dofs the factorisation and the solves run on one thread: faer's parallel
/// supernodal tasks cost more than they save on small fronts (the events solver's 2e4-dof plate
/// ran 25 % slower on two busy cores with them).
pub const PAR_MIN_DOFS: usize = 100_000;

/// The parallelism for a system of `n` dofs: the calling thread pool's threads from
/// [`PAR_MIN_DOFS`] on.
pub fn par(n: usize) -> Par {
    let t = rayon::current_num_threads();
    if t <= 1 || n < PAR_MIN_DOFS {
        Par::Seq
    } else {
        Par::rayon(t)
    }
}

/// Geometric nested dissection of the dofs `0..n` with coordinates `xy` and the coupling graph of
/// the lower triangle `pattern` (compressed columns). Returns `order` with `order[new] = old`.
pub fn nested_dissection(pattern: SymbolicSparseColMatRef<'_, usize>, xy: &[[f64; 2]]) -> Vec<usize> {
    let n = pattern.nrows();
    assert_eq!(xy.len(), n);
    // Symmetric adjacency (both triangles), without the diagonal.
    let (cp, ri) = (pattern.col_ptr(), pattern.row_idx());
    let mut deg = vec![0usize; n + 1];
    for j in 0..n {
        for &i in &ri[cp[j]..cp[j + 1]] {
            if i != j {
                deg[i] += 1;
                deg[j] += 1;
            }
        }
    }
    let mut start = vec![0usize; n + 1];
    for k in 0..n {
        start[k + 1] = start[k] + deg[k];
    }
    let mut fill = start.clone();
    let mut adj = vec![0u32; start[n]];
    for j in 0..n {
        for &i in &ri[cp[j]..cp[j + 1]] {
            if i != j {
                adj[fill[i]] = j as u32;
                fill[i] += 1;
                adj[fill[j]] = i as u32;
                fill[j] += 1;
            }
        }
    }
    // Reach of each dof: the largest coordinate difference to a coupled dof, per axis. A dof
    // below the cut value `v` can be coupled to one at or above it only if `x + reach >= v`, so
    // the separator search looks at the dofs near the cut only.
    let mut reach = vec![[0.0f64; 2]; n];
    for k in 0..n {
        for &m in &adj[start[k]..start[k + 1]] {
            for d in 0..2 {
                reach[k][d] = reach[k][d].max(xy[m as usize][d] - xy[k][d]);
            }
        }
    }
    let mut ids: Vec<u32> = (0..n as u32).collect();
    let mut stamp = vec![0u32; n];
    let mut gen = 0u32;
    let mut order = Vec::with_capacity(n);
    // Explicit stack of (range in `ids`, separator to emit after the range's children).
    enum Job {
        Split(usize, usize),
        Emit(usize, usize),
    }
    let mut jobs = vec![Job::Split(0, n)];
    while let Some(job) = jobs.pop() {
        let (lo, hi) = match job {
            Job::Emit(lo, hi) => {
                order.extend(ids[lo..hi].iter().map(|&k| k as usize));
                continue;
            }
            Job::Split(lo, hi) => (lo, hi),
        };
        let part = &mut ids[lo..hi];
        if part.len() <= LEAF {
            order.extend(part.iter().map(|&k| k as usize));
            continue;
        }
        let (mut min, mut max) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for &k in part.iter() {
            for d in 0..2 {
                min[d] = min[d].min(xy[k as usize][d]);
                max[d] = max[d].max(xy[k as usize][d]);
            }
        }
        let axis = if max[0] - min[0] >= max[1] - min[1] { 0 } else { 1 };
        // Split at the median coordinate by value, not by rank: dofs on one grid line stay on
        // one side, so the separator is one line of nodes (a rank split cuts a line in two and
        // leaves a ragged separator two lines thick).
        let half = part.len() / 2;
        part.select_nth_unstable_by(half, |&a, &b| xy[a as usize][axis].total_cmp(&xy[b as usize][axis]).then(a.cmp(&b)));
        let v = xy[part[half] as usize][axis];
        let mut mid = 0;
        for i in 0..part.len() {
            if xy[part[i] as usize][axis] < v {
                part.swap(i, mid);
                mid += 1;
            }
        }
        if mid == 0 {
            // Every dof at or above the median value: the line at the median goes first.
            for i in 0..part.len() {
                if xy[part[i] as usize][axis] <= v {
                    part.swap(i, mid);
                    mid += 1;
                }
            }
            if mid == part.len() {
                // All on one line across the long side: a rank split.
                mid = half;
            }
        }
        gen = gen.wrapping_add(1);
        for &k in &part[mid..] {
            stamp[k as usize] = gen;
        }
        // Separator: first-half dofs coupled to the second half; moved to the end of the first half.
        let mut s = mid;
        let mut i = 0;
        while i < s {
            let k = part[i] as usize;
            if xy[k][axis] + reach[k][axis] >= v && adj[start[k]..start[k + 1]].iter().any(|&m| stamp[m as usize] == gen) {
                s -= 1;
                part.swap(i, s);
            } else {
                i += 1;
            }
        }
        // Order: first half's interior, second half, then the separator (pushed in reverse).
        // The second half is emitted before the separator, so the separator goes last.
        let (a, b, c) = (lo, lo + s, lo + mid);
        // Move the separator [b, c) behind the second half: rotate [b, hi).
        ids[b..hi].rotate_left(c - b);
        let sep_lo = hi - (c - b);
        jobs.push(Job::Emit(sep_lo, hi));
        jobs.push(Job::Split(b, sep_lo));
        jobs.push(Job::Split(a, b));
    }
    debug_assert_eq!(order.len(), n);
    order
}

/// Extends an ordering of `old.len()` dofs to `n >= old.len()` dofs: each new dof `k` goes right
/// after `parent[k - old.len()]` (the dof it was split from), in order.
pub fn extend_ordering(old: &[usize], n: usize, parent: &[usize]) -> Vec<usize> {
    let n0 = old.len();
    assert_eq!(parent.len(), n - n0);
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); n0];
    let mut orphans = Vec::new();
    for (j, &p) in parent.iter().enumerate() {
        if p < n0 {
            children[p].push(n0 + j);
        } else {
            orphans.push(n0 + j);
        }
    }
    let mut out = Vec::with_capacity(n);
    for &k in old {
        out.push(k);
        out.extend(children[k].iter().copied());
    }
    out.extend(orphans);
    out
}

/// Symbolic Cholesky of the lower triangle `pattern` with the ordering `order` (`order[new] = old`).
pub fn symbolic(pattern: SymbolicSparseColMatRef<'_, usize>, order: &[usize]) -> Result<Arc<SymbolicCholesky<usize>>, String> {
    let n = order.len();
    let mut inv = vec![0usize; n];
    for (new, &old) in order.iter().enumerate() {
        inv[old] = new;
    }
    let perm = Perm::new_checked(order.to_vec().into_boxed_slice(), inv.into_boxed_slice(), n);
    factorize_symbolic_cholesky(pattern, Side::Lower, SymmetricOrdering::Custom(perm.as_ref()), Default::default()).map(Arc::new).map_err(|e| format!("{e:?}"))
}

/// A numeric Cholesky factor on a shared symbolic analysis.
#[derive(Clone)]
pub struct Factor {
    sym: Arc<SymbolicCholesky<usize>>,
    values: Vec<f64>,
}

impl Factor {
    /// Numeric `L L^T` of `a` (lower triangle, the pattern the symbolic analysis was made for).
    /// `Err(LltError::Numeric(_))`: a non-positive pivot.
    pub fn new(sym: Arc<SymbolicCholesky<usize>>, a: &SparseColMat<usize, f64>, par: Par) -> Result<Self, LltError> {
        let mut values = vec![0.0; sym.len_val()];
        let mut mem = MemBuffer::try_new(sym.factorize_numeric_llt_scratch::<f64>(par, Default::default())).map_err(|_| LltError::Generic(faer::sparse::FaerError::OutOfMemory))?;
        sym.factorize_numeric_llt::<f64>(&mut values, a.as_ref(), Side::Lower, Default::default(), par, MemStack::new(&mut mem), Default::default())?;
        Ok(Factor { sym, values })
    }

    /// Stored entries of `L`.
    pub fn nnz(&self) -> usize {
        self.values.len()
    }

    /// Solves `A X = B` in place (`B` has the factor's rows, any number of columns).
    pub fn solve_in_place(&self, rhs: MatMut<'_, f64>, par: Par) {
        let mut mem = MemBuffer::new(self.sym.solve_in_place_scratch::<f64>(rhs.ncols(), par));
        LltRef::new(&self.sym, &self.values).solve_in_place_with_conj(Conj::No, rhs, par, MemStack::new(&mut mem));
    }

    /// Solves `A x = b` for one vector.
    pub fn solve(&self, b: &[f64], par: Par) -> Vec<f64> {
        let mut x = b.to_vec();
        self.solve_in_place(MatMut::from_column_major_slice_mut(&mut x, b.len(), 1), par);
        x
    }
}

#[cfg(test)]
mod tests {
    use faer::sparse::{SparseColMat, Triplet};

    use super::*;

    /// The stiffness-like lower triangle of a 5-point Laplacian plus identity on an `nx x ny` grid
    /// of points with two coincident copies of the line `x = nx / 2` (a "crack": same
    /// coordinates, no coupling across), and the point coordinates.
    fn grid(nx: usize, ny: usize) -> (SparseColMat<usize, f64>, Vec<[f64; 2]>) {
        let cut = nx / 2;
        let mut id = vec![vec![0usize; ny]; nx + 1];
        let mut xy = Vec::new();
        let mut copy = vec![0usize; ny];
        for i in 0..nx {
            for j in 0..ny {
                id[i][j] = xy.len();
                xy.push([i as f64, j as f64]);
            }
            if i == cut {
                for j in 0..ny {
                    copy[j] = xy.len();
                    xy.push([i as f64, j as f64]);
                }
            }
        }
        let n = xy.len();
        let mut t = Vec::new();
        let link = |a: usize, b: usize, t: &mut Vec<Triplet<usize, usize, f64>>| {
            let (lo, hi) = (a.min(b), a.max(b));
            t.push(Triplet::new(hi, lo, -1.0));
        };
        for i in 0..nx {
            for j in 0..ny {
                if j + 1 < ny {
                    link(id[i][j], id[i][j + 1], &mut t);
                    if i == cut {
                        link(copy[j], copy[j + 1], &mut t);
                    }
                }
                if i + 1 < nx {
                    // Across the cut, the right side couples to the copy.
                    let left = if i == cut { copy[j] } else { id[i][j] };
                    link(left, id[i + 1][j], &mut t);
                }
            }
        }
        for k in 0..n {
            t.push(Triplet::new(k, k, 5.0));
        }
        (SparseColMat::try_new_from_triplets(n, n, &t).unwrap(), xy)
    }

    fn is_perm(p: &[usize]) -> bool {
        let mut seen = vec![false; p.len()];
        p.iter().all(|&k| k < p.len() && !std::mem::replace(&mut seen[k], true))
    }

    /// The dissection is a permutation, its factor solves the system (reference: the residual
    /// of the solution, 1e-13 relative, and faer's AMD-ordered factor, 1e-12), and the factor is
    /// bit-identical on one thread and on a pool of two.
    #[test]
    fn dissection_orders_and_solves_bit_identically_on_any_thread_count() {
        let (a, xy) = grid(240, 160);
        let n = a.nrows();
        let order = nested_dissection(a.symbolic(), &xy);
        assert!(is_perm(&order));
        let sym = symbolic(a.symbolic(), &order).unwrap();
        // Large enough for faer's supernodal (blocked, parallel) path.
        assert!(matches!(sym.raw(), faer::sparse::linalg::cholesky::SymbolicCholeskyRaw::Supernodal(_)));
        let b: Vec<f64> = (0..n).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
        let f1 = Factor::new(sym.clone(), &a, Par::Seq).unwrap();
        let x1 = f1.solve(&b, Par::Seq);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let (f2, x2) = pool.install(|| {
            let f = Factor::new(sym.clone(), &a, Par::rayon(2)).unwrap();
            let x = f.solve(&b, Par::rayon(2));
            (f, x)
        });
        assert_eq!(f1.values, f2.values, "factor differs between 1 and 2 threads");
        assert_eq!(x1, x2, "solution differs between 1 and 2 threads");
        // Residual and agreement with faer's AMD-ordered factor.
        let kx = super::super::sym_mul(&a, &x1);
        let r = (0..n).map(|i| (b[i] - kx[i]).abs()).fold(0.0, f64::max);
        assert!(r < 1e-13 * 6.0 * 5.0, "residual {r}");
        let amd = factorize_symbolic_cholesky(a.symbolic(), Side::Lower, SymmetricOrdering::Amd, Default::default()).unwrap();
        let fa = Factor::new(Arc::new(amd), &a, Par::Seq).unwrap();
        let xa = fa.solve(&b, Par::Seq);
        let d = (0..n).map(|i| (x1[i] - xa[i]).abs()).fold(0.0, f64::max);
        assert!(d < 1e-12, "nested dissection vs AMD: {d}");
    }

    /// Extending an ordering keeps the old dofs' relative order and puts each new dof right after
    /// its parent; orphans (no parent) go last.
    #[test]
    fn extended_ordering_is_a_permutation_with_children_after_parents() {
        let old = vec![3, 0, 2, 1];
        let ext = extend_ordering(&old, 7, &[0, usize::MAX, 0]);
        assert_eq!(ext, vec![3, 0, 4, 6, 2, 1, 5]);
        assert!(is_perm(&ext));
    }
}
