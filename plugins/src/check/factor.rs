//! The sparse Cholesky factor of `K_ff` with a geometric nested-dissection ordering (ours),
//! faer's supernodal symbolic analysis, and our tree-parallel supernodal numeric factorisation
//! on faer's dense kernels.
//!
//! faer's high-level `SymbolicLlt::try_new` orders the matrix by approximate minimum degree
//! (AMD): on a 2D finite-element mesh of 5e5 dofs that ordering costs a quarter of the whole
//! solve, and its fill is larger than nested dissection's (George 1973: for a 2D mesh of `n`
//! nodes nested dissection gives `O(n log n)` fill and `O(n^1.5)` flops, the optimum). The
//! dofs here have coordinates (their cluster's reference position), so the dissection is
//! geometric: split the vertices (a node's dofs, kept together) at the median of the longer side
//! of their bounding box, take as separator the vertices of the first half that are coupled (a
//! non-zero of `K`) to the second, order first half, second half, separator; recurse down to
//! `LEAF` vertices. The cut is at the
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
//! Numeric factorisation (ours, `Factor::new`): left-looking supernodal Cholesky as in CHOLMOD
//! (Chen, Davis, Hager, Rajamanickam 2008) and faer, on faer's supernodal structure, with
//! faer's dense `triangular::matmul`/`matmul`, `cholesky_in_place` and triangular solve for
//! each supernode. A supernode reads only its descendants in the supernodal elimination tree,
//! so disjoint subtrees are independent: subtrees with at least 1/(16 t) of the work run as
//! rayon tasks of their own, the supernodes above them after their tasks join. faer 0.24's own
//! supernodal numeric walks the supernodes one after the other and parallelises only inside the
//! dense kernels, which gained 0.98 -> 0.88 s on two threads at 5e5 dofs; the subtree tasks
//! give 0.95 -> 0.55 s (docs/perf/implicit.md).
//!
//! Threads: from [`PAR_MIN_DOFS`] dofs on, the numeric factorisation runs its subtree tasks on
//! the calling pool (`rayon::current_num_threads`) and the triangular solves with several
//! right-hand sides take `Par::rayon(n)`. Every supernode's arithmetic (its gather, its updates
//! in increasing order of the updating supernode, its dense kernels, all on `Par::Seq`) is the
//! same whichever thread runs it, and a single right-hand side is solved on one thread, because
//! faer's matrix-vector product with `Par::Rayon` sums per-thread partial products: the factor
//! and the solutions are bit-identical whatever `n` (the unit tests below check 1, 2 and 4
//! threads at 2.4e5 dofs, where that product takes its parallel path).
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::sparse::linalg::cholesky::supernodal::{SupernodalLltRef, SymbolicSupernodalCholesky};
use faer::sparse::linalg::LltError;
use faer::sparse::{SparseColMat, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{Accum, Conj, MatMut, MatRef, Par};

/// Dissection stops at this many vertices (the leaf keeps its coordinate order). Measured on
/// `flem bench implicit`'s 5e5-dof mesh: dof leaves of 8 gave 56.0 M entries in `L` (AMD: 59.5 M),
/// leaves of 24, 48 and 128 gave more; ordering the leaves by AMD (as METIS orders its leaves by
/// minimum degree) gave no less fill at leaves of 48 (56.4 M) and cost a quarter of a second.
/// Vertex leaves of 4 (8 dofs): 56.1 M, with the ordering 0.14 -> 0.07 s.
const LEAF: usize = 4;

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
    if n == 0 {
        return Vec::new();
    }
    // Vertices: runs of consecutive dofs at the same point (a node's x and y dofs). The
    // dissection runs on the vertex graph (half the items and a quarter of the couplings of the
    // dof graph for 2-dof nodes) and each vertex's dofs stay together in the ordering.
    let mut first = vec![0usize];
    for k in 1..n {
        if xy[k] != xy[k - 1] {
            first.push(k);
        }
    }
    first.push(n);
    let nv = first.len() - 1;
    let mut vert = vec![0u32; n];
    for v in 0..nv {
        vert[first[v]..first[v + 1]].fill(v as u32);
    }
    let vxy: Vec<[f64; 2]> = (0..nv).map(|v| xy[first[v]]).collect();
    let order = dissect(pattern, &vert, &vxy);
    let mut out = Vec::with_capacity(n);
    for v in order {
        out.extend(first[v]..first[v + 1]);
    }
    out
}

/// The dissection of the vertex graph (`vert[dof]` = vertex; `xy` per vertex).
fn dissect(pattern: SymbolicSparseColMatRef<'_, usize>, vert: &[u32], xy: &[[f64; 2]]) -> Vec<usize> {
    let n = xy.len();
    // Symmetric adjacency (both triangles) of the vertices, without self-loops, deduplicated.
    let (cp, ri) = (pattern.col_ptr(), pattern.row_idx());
    let mut deg = vec![0usize; n + 1];
    for j in 0..pattern.ncols() {
        for &i in &ri[cp[j]..cp[j + 1]] {
            let (vi, vj) = (vert[i] as usize, vert[j] as usize);
            if vi != vj {
                deg[vi] += 1;
                deg[vj] += 1;
            }
        }
    }
    let mut start = vec![0usize; n + 1];
    for k in 0..n {
        start[k + 1] = start[k] + deg[k];
    }
    let mut fill = start.clone();
    let mut raw = vec![0u32; start[n]];
    for j in 0..pattern.ncols() {
        for &i in &ri[cp[j]..cp[j + 1]] {
            let (vi, vj) = (vert[i] as usize, vert[j] as usize);
            if vi != vj {
                raw[fill[vi]] = vj as u32;
                fill[vi] += 1;
                raw[fill[vj]] = vi as u32;
                fill[vj] += 1;
            }
        }
    }
    let mut seen = vec![u32::MAX; n];
    let mut adj = Vec::with_capacity(raw.len());
    let mut s0 = 0;
    for k in 0..n {
        for &m in &raw[start[k]..start[k + 1]] {
            if seen[m as usize] != k as u32 {
                seen[m as usize] = k as u32;
                adj.push(m);
            }
        }
        start[k] = s0;
        s0 = adj.len();
    }
    start[n] = s0;
    drop(raw);
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
            if mid == 0 || mid == part.len() {
                // All on one line across the long side (or coordinates that do not compare,
                // NaN): a rank split.
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

/// The symbolic analysis: the ordering, the permuted lower pattern of `K` (and where each
/// stored entry of the unpermuted one goes in it), faer's supernodal structure of `L`, and the
/// plan of our numeric factorisation on it.
pub struct Symbolic {
    /// `fwd[new] = old`.
    fwd: Vec<usize>,
    /// `inv[old] = new` (`Factor::forward_sparse`).
    inv: Vec<usize>,
    /// FNV-1a hash of the unpermuted pattern's row indices, column by column (a matrix handed
    /// to `Factor::new` must have this pattern).
    rows_hash: u64,
    /// Each stored entry of the unpermuted lower pattern (column by column): its position in the
    /// permuted lower pattern `(lcp, lri)` (rows unsorted within a column).
    to_perm: Vec<u32>,
    lcp: Vec<usize>,
    lri: Vec<u32>,
    sn: SymbolicSupernodalCholesky<usize>,
    plan: Plan,
}

/// Symbolic Cholesky of the lower triangle `pattern` with the ordering `order` (`order[new] = old`).
///
/// The pattern is permuted once here (both triangles' patterns, and the map that later puts a
/// matrix's values in place with one pass); the elimination tree and column counts are ours
/// (`elimination_tree`, `column_counts`: near-linear, where faer's `prefactorize_symbolic_cholesky`
/// walks every entry of `L`), the supernodes from faer's
/// `factorize_supernodal_symbolic_cholesky` (its default relaxed amalgamation). faer's
/// high-level `factorize_symbolic_cholesky` does the same but permutes the pattern through a
/// general routine, and its numeric factorisation permutes every matrix again.
pub fn symbolic(pattern: SymbolicSparseColMatRef<'_, usize>, order: &[usize]) -> Result<Arc<Symbolic>, String> {
    use faer::sparse::linalg::cholesky::{simplicial, supernodal};
    let n = order.len();
    if pattern.nrows() != n || pattern.ncols() != n {
        return Err(format!("pattern {}x{} for an ordering of {n}", pattern.nrows(), pattern.ncols()));
    }
    let mut inv = vec![usize::MAX; n];
    for (new, &old) in order.iter().enumerate() {
        if old >= n || inv[old] != usize::MAX {
            return Err(format!("the ordering is not a permutation of 0..{n}"));
        }
        inv[old] = new;
    }
    // Permuted lower (numeric) and upper (faer's symbolic analyses read the upper triangle)
    // patterns, by counting sort.
    let mut acp = vec![0usize; n + 1];
    let (mut lcnt, mut ucnt) = (vec![0usize; n + 1], vec![0usize; n + 1]);
    for j in 0..n {
        let rows = pattern.row_idx_of_col_raw(j);
        acp[j + 1] = acp[j] + rows.len();
        for &i in rows {
            if i < j {
                return Err(format!("entry ({i}, {j}) above the diagonal of a lower-triangle pattern"));
            }
            let (a, b) = (inv[i], inv[j]);
            lcnt[a.min(b) + 1] += 1;
            ucnt[a.max(b) + 1] += 1;
        }
    }
    for k in 0..n {
        lcnt[k + 1] += lcnt[k];
        ucnt[k + 1] += ucnt[k];
    }
    let nnz = acp[n];
    if nnz > u32::MAX as usize {
        return Err(format!("{nnz} stored entries in the lower triangle: more than this solver indexes (2^32)"));
    }
    let (lcp, ucp) = (lcnt.clone(), ucnt.clone());
    // 32-bit where only we read (the map and our numeric's rows): less memory to touch.
    let (mut lri, mut uri, mut to_perm) = (vec![0u32; nnz], vec![0usize; nnz], vec![0u32; nnz]);
    let mut p = 0;
    for j in 0..n {
        for &i in pattern.row_idx_of_col_raw(j) {
            let (a, b) = (inv[i], inv[j]);
            let (lo, hi) = (a.min(b), a.max(b));
            to_perm[p] = lcnt[lo] as u32;
            lri[lcnt[lo]] = hi as u32;
            lcnt[lo] += 1;
            uri[ucnt[hi]] = lo;
            ucnt[hi] += 1;
            p += 1;
        }
    }
    let upper = SymbolicSparseColMat::new_unsorted_checked(n, n, ucp, None, uri);
    let etree = elimination_tree(upper.col_ptr(), upper.row_idx());
    let counts = column_counts(&lcp, &lri, &etree);
    let mut mem = MemBuffer::try_new(supernodal::factorize_supernodal_symbolic_cholesky_scratch::<usize>(n)).map_err(|_| "out of memory".to_string())?;
    let stack = MemStack::new(&mut mem);
    // SAFETY: `etree` is the elimination tree of `upper` (Liu's algorithm), the array faer's
    // `prefactorize_symbolic_cholesky` fills for the same pattern (the tree is unique; the unit
    // test `own_etree_and_counts_are_faers` compares the two, and the column counts).
    let et = unsafe { simplicial::EliminationTreeRef::<usize>::from_inner(&etree) };
    let sn = supernodal::factorize_supernodal_symbolic_cholesky(upper.as_ref(), et, &counts, stack, Default::default()).map_err(|e| format!("{e:?}"))?;
    let plan = Plan::new(&sn);
    Ok(Arc::new(Symbolic { fwd: order.to_vec(), inv, rows_hash: rows_hash(pattern), to_perm, lcp, lri, sn, plan }))
}

/// FNV-1a hash of a pattern's row indices, column by column (with each column's length).
fn rows_hash(pattern: SymbolicSparseColMatRef<'_, usize>) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut mix = |x: usize| {
        h ^= x as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    };
    for j in 0..pattern.ncols() {
        let rows = pattern.row_idx_of_col_raw(j);
        mix(rows.len());
        for &i in rows {
            mix(i);
        }
    }
    h
}

/// The elimination tree of the upper-triangle pattern `(cp, ri)` (Liu 1986, with path
/// compression, as CSparse's `cs_etree`): `parent[k]` or -1 for a root.
fn elimination_tree(cp: &[usize], ri: &[usize]) -> Vec<isize> {
    let n = cp.len() - 1;
    let mut parent = vec![-1isize; n];
    let mut ancestor = vec![usize::MAX; n];
    for k in 0..n {
        for &r in &ri[cp[k]..cp[k + 1]] {
            let mut i = r;
            while i != usize::MAX && i < k {
                let next = ancestor[i];
                ancestor[i] = k;
                if next == usize::MAX {
                    parent[i] = k as isize;
                }
                i = next;
            }
        }
    }
    parent
}

/// Column counts of `L` (diagonal included) from the lower-triangle pattern `(cp, ri)` and its
/// elimination tree, in near-linear time (Gilbert, Ng and Peyton 1994, as CSparse's `cs_counts`:
/// row subtrees through their leaves and least common ancestors) instead of walking every
/// entry of `L` (faer's `prefactorize_symbolic_cholesky`, 56 M steps at 5e5 dofs).
fn column_counts(cp: &[usize], ri: &[u32], parent: &[isize]) -> Vec<usize> {
    let n = parent.len();
    const NONE: isize = -1;
    // Post-order of the tree (children in increasing order, as cs_post).
    let (mut head, mut next) = (vec![NONE; n], vec![NONE; n]);
    for j in (0..n).rev() {
        if parent[j] != NONE {
            let p = parent[j] as usize;
            next[j] = head[p];
            head[p] = j as isize;
        }
    }
    let mut post = Vec::with_capacity(n);
    let mut stack = Vec::new();
    for r in 0..n {
        if parent[r] != NONE {
            continue;
        }
        stack.push(r);
        while let Some(&p) = stack.last() {
            let c = head[p];
            if c == NONE {
                stack.pop();
                post.push(p);
            } else {
                head[p] = next[c as usize];
                stack.push(c as usize);
            }
        }
    }
    let mut first = vec![NONE; n];
    let mut delta = vec![0isize; n];
    for (k, &j0) in post.iter().enumerate() {
        delta[j0] = if first[j0] == NONE { 1 } else { 0 };
        let mut j = j0 as isize;
        while j != NONE && first[j as usize] == NONE {
            first[j as usize] = k as isize;
            j = parent[j as usize];
        }
    }
    let (mut maxfirst, mut prevleaf) = (vec![NONE; n], vec![NONE; n]);
    let mut ancestor: Vec<usize> = (0..n).collect();
    for &j in &post {
        if parent[j] != NONE {
            delta[parent[j] as usize] -= 1;
        }
        for &r in &ri[cp[j]..cp[j + 1]] {
            let i = r as usize;
            // cs_leaf: is j a leaf of the row subtree of i, and if a later one, where it meets
            // the previous leaf's path.
            if i <= j || first[j] <= maxfirst[i] {
                continue;
            }
            maxfirst[i] = first[j];
            let jprev = prevleaf[i];
            prevleaf[i] = j as isize;
            delta[j] += 1;
            if jprev != NONE {
                let jprev = jprev as usize;
                let mut q = jprev;
                while q != ancestor[q] {
                    q = ancestor[q];
                }
                let mut s = jprev;
                while s != q {
                    let up = ancestor[s];
                    ancestor[s] = q;
                    s = up;
                }
                delta[q] -= 1;
            }
        }
        if parent[j] != NONE {
            ancestor[j] = parent[j] as usize;
        }
    }
    for j in 0..n {
        if parent[j] != NONE {
            let d = delta[j];
            delta[parent[j] as usize] += d;
        }
    }
    delta.into_iter().map(|c| c as usize).collect()
}

/// What the numeric factorisation needs beyond faer's supernodal structure.
///
/// Left-looking supernodal Cholesky (as CHOLMOD and faer): supernode `s` gathers its columns of
/// `A`, subtracts the update `L_d,mid_bot L_d,mid^T` of every earlier supernode `d` whose row
/// pattern meets `s`'s columns (`updaters`, in increasing `d`), then factors its diagonal block
/// and solves its off-diagonal block. A supernode reads only supernodes of its own subtree in the
/// supernodal elimination tree, so disjoint subtrees run in parallel (ours: faer 0.24's
/// supernodal numeric walks the supernodes in sequence and parallelises only inside each dense
/// kernel, which gains little on small fronts). Every supernode's arithmetic is the same whatever
/// the thread that runs it and whatever the thread count: the factor is bit-identical.
struct Plan {
    /// Updaters of each supernode (CSR over supernodes; increasing within a row).
    upd_ptr: Vec<usize>,
    upd: Vec<usize>,
    /// Children of each supernode in the supernodal elimination tree (CSR), and the roots.
    child_ptr: Vec<usize>,
    child: Vec<usize>,
    roots: Vec<usize>,
    /// Work estimate (flops) of each subtree, and the whole.
    work: Vec<f64>,
    total: f64,
    /// Largest update block (rows x columns) and widest supernode: scratch sizes.
    max_update: usize,
    max_width: usize,
    /// Longest row pattern below a supernode's diagonal block.
    max_rows: usize,
}

impl Plan {
    fn new(s: &SymbolicSupernodalCholesky<usize>) -> Plan {
        let ns = s.n_supernodes();
        let (sb, se, cpr, ri) = (s.supernode_begin(), s.supernode_end(), s.col_ptr_for_row_idx(), s.row_idx());
        let n = se.last().copied().unwrap_or(0);
        let mut col2s = vec![0usize; n];
        for k in 0..ns {
            col2s[sb[k]..se[k]].fill(k);
        }
        // Updaters: d updates every supernode its (sorted) row pattern meets.
        let mut pairs: Vec<(usize, usize)> = Vec::new();
        let mut parent = vec![usize::MAX; ns];
        let mut work = vec![0.0f64; ns];
        let (mut max_update, mut max_width, mut max_rows) = (0usize, 0usize, 0usize);
        for d in 0..ns {
            let pat = &ri[cpr[d]..cpr[d + 1]];
            let (w, h) = ((se[d] - sb[d]) as f64, pat.len() as f64);
            work[d] = w * w * w / 3.0 + h * w * w + h * h * w;
            max_width = max_width.max(se[d] - sb[d]);
            max_rows = max_rows.max(pat.len());
            if let Some(&r) = pat.first() {
                parent[d] = col2s[r];
            }
            let mut i = 0;
            while i < pat.len() {
                let t = col2s[pat[i]];
                let mut j = i;
                while j < pat.len() && pat[j] < se[t] {
                    j += 1;
                }
                max_update = max_update.max((pat.len() - i) * (j - i));
                pairs.push((t, d));
                i = j;
            }
        }
        let (upd_ptr, upd) = csr(ns, pairs.iter().copied());
        let (child_ptr, child) = csr(ns, (0..ns).filter(|&k| parent[k] != usize::MAX).map(|k| (parent[k], k)));
        let roots: Vec<usize> = (0..ns).filter(|&k| parent[k] == usize::MAX).collect();
        for k in 0..ns {
            if parent[k] != usize::MAX {
                debug_assert!(parent[k] > k);
                let w = work[k];
                work[parent[k]] += w;
            }
        }
        let total = roots.iter().map(|&r| work[r]).sum();
        Plan { upd_ptr, upd, child_ptr, child, roots, work, total, max_update, max_width, max_rows }
    }

    fn children(&self, k: usize) -> &[usize] {
        &self.child[self.child_ptr[k]..self.child_ptr[k + 1]]
    }
}

/// Rows `(row, value)` grouped by row into CSR, stable (values keep their order within a row).
fn csr(n: usize, pairs: impl Iterator<Item = (usize, usize)> + Clone) -> (Vec<usize>, Vec<usize>) {
    let mut ptr = vec![0usize; n + 1];
    for (r, _) in pairs.clone() {
        ptr[r + 1] += 1;
    }
    for k in 0..n {
        ptr[k + 1] += ptr[k];
    }
    let mut fill = ptr.clone();
    let mut val = vec![0usize; ptr[n]];
    for (r, v) in pairs {
        val[fill[r]] = v;
        fill[r] += 1;
    }
    (ptr, val)
}

/// Scratch of one task: the global-to-local row map of the supernode in hand (all `usize::MAX`
/// between supernodes), the update block, and the dense Cholesky's workspace.
struct Work {
    map: Vec<usize>,
    /// Rows of the supernode in hand that an update's rows go to.
    rel: Vec<usize>,
    w: Vec<f64>,
    mem: MemBuffer,
}

/// The numeric factorisation's shared state. `L` is written through a raw pointer: each
/// supernode writes only its own block of `values`, and reads only blocks of supernodes in its
/// subtree, which are complete before it starts (the subtree's tasks have joined).
struct Numeric<'a> {
    s: &'a SymbolicSupernodalCholesky<usize>,
    plan: &'a Plan,
    /// `A` permuted, lower triangle (column pointers, rows, values).
    acp: &'a [usize],
    ari: &'a [u32],
    av: &'a [f64],
    values: *mut f64,
    /// Subtrees with at least this much work run as tasks of their own.
    cut: f64,
    pool: Mutex<Vec<Work>>,
    failed: Mutex<Option<usize>>,
    stop: AtomicBool,
}

// SAFETY: the raw pointer is written by disjoint supernode blocks only (see `Numeric`).
unsafe impl Sync for Numeric<'_> {}

impl Numeric<'_> {
    fn work(&self) -> Work {
        if let Some(w) = self.pool.lock().unwrap_or_else(|e| e.into_inner()).pop() {
            return w;
        }
        let n = self.s.nrows();
        let req = faer::linalg::cholesky::llt::factor::cholesky_in_place_scratch::<f64>(self.plan.max_width, Par::Seq, Default::default());
        Work { map: vec![usize::MAX; n], rel: vec![0; self.plan.max_rows], w: vec![0.0; self.plan.max_update], mem: MemBuffer::new(req) }
    }

    fn give_back(&self, w: Work) {
        self.pool.lock().unwrap_or_else(|e| e.into_inner()).push(w);
    }

    /// Factors the subtree rooted at `k`: children with enough work as parallel tasks, the rest
    /// in this task, then `k` itself.
    fn subtree(&self, k: usize) {
        if self.plan.work[k] < self.cut {
            let mut w = self.work();
            self.sequential(k, &mut w);
            self.give_back(w);
            return;
        }
        let kids = self.plan.children(k);
        rayon::scope(|sc| {
            for &c in kids.iter().filter(|&&c| self.plan.work[c] >= self.cut) {
                sc.spawn(move |_| self.subtree(c));
            }
            let small: Vec<usize> = kids.iter().copied().filter(|&c| self.plan.work[c] < self.cut).collect();
            if !small.is_empty() {
                let mut w = self.work();
                for c in small {
                    self.sequential(c, &mut w);
                }
                self.give_back(w);
            }
        });
        let mut w = self.work();
        self.node(k, &mut w);
        self.give_back(w);
    }

    /// The subtree rooted at `k`, children before parents, in this thread.
    fn sequential(&self, k: usize, w: &mut Work) {
        // Post-order walk with an explicit stack of (node, next child).
        let mut stack = vec![(k, 0usize)];
        while let Some(&mut (v, ref mut next)) = stack.last_mut() {
            let kids = self.plan.children(v);
            if *next < kids.len() {
                let c = kids[*next];
                *next += 1;
                stack.push((c, 0));
            } else {
                stack.pop();
                self.node(v, w);
            }
        }
    }

    /// Supernode `k`: gather `A`, subtract the updates, factor the diagonal block, solve the rest.
    /// The dense kernels run on one thread (`Par::Seq`) whatever the pool: the parallelism is
    /// the subtrees', and no kernel's arithmetic can depend on the thread count (faer's matrix-
    /// vector product with `Par::Rayon` splits the inner dimension into per-thread partial sums).
    fn node(&self, k: usize, wk: &mut Work) {
        let par = Par::Seq;
        if self.stop.load(Ordering::Relaxed) {
            return;
        }
        let s = self.s;
        let (sb, se, cpr, cpv, ri) = (s.supernode_begin(), s.supernode_end(), s.col_ptr_for_row_idx(), s.col_ptr_for_val(), s.row_idx());
        let (s0, s1) = (sb[k], se[k]);
        let pat = &ri[cpr[k]..cpr[k + 1]];
        let ncols = s1 - s0;
        let nrows = ncols + pat.len();
        // SAFETY: block `k` of `values` is this supernode's own (no other task writes it), and
        // the blocks read below belong to finished supernodes of this subtree.
        // Zeroed before any reference to it exists (the buffer is allocated uninitialised), and
        // written before it is read: a fresh page's first access is then a write (one fault),
        // not a read of the shared zero page followed by a copy-on-write fault, whose TLB
        // shootdown interrupts the other threads.
        let ls = unsafe {
            let p = self.values.add(cpv[k]);
            std::ptr::write_bytes(p, 0, cpv[k + 1] - cpv[k]);
            std::slice::from_raw_parts_mut(p, cpv[k + 1] - cpv[k])
        };
        let map = &mut wk.map;
        for (i, &r) in pat.iter().enumerate() {
            map[r] = ncols + i;
        }
        let local = |r: usize, map: &[usize]| if r < s1 { r - s0 } else { map[r] };
        for j in s0..s1 {
            let col = (j - s0) * nrows;
            for p in self.acp[j]..self.acp[j + 1] {
                ls[local(self.ari[p] as usize, map) + col] += self.av[p];
            }
        }
        for &d in &self.plan.upd[self.plan.upd_ptr[k]..self.plan.upd_ptr[k + 1]] {
            let dpat = &ri[cpr[d]..cpr[d + 1]];
            let dc = se[d] - sb[d];
            let dr = dc + dpat.len();
            let p0 = dpat.partition_point(|&r| r < s0);
            let q = dpat[p0..].partition_point(|&r| r < s1);
            let m = dpat.len() - p0;
            // SAFETY: `d` is a finished descendant of `k` (see above).
            let ld = unsafe { std::slice::from_raw_parts(self.values.add(cpv[d]) as *const f64, cpv[d + 1] - cpv[d]) };
            let ld = MatRef::from_column_major_slice(ld, dr, dc);
            let (_, bot) = ld.split_at_row(dc + p0);
            let (mid, low) = bot.split_at_row(q);
            let wbuf = &mut wk.w[..m * q];
            let mut wm = MatMut::from_column_major_slice_mut(wbuf, m, q);
            {
                let (wt, wb) = wm.rb_mut().split_at_row_mut(q);
                triangular::matmul(wt, BlockStructure::TriangularLower, Accum::Replace, mid, BlockStructure::Rectangular, mid.transpose(), BlockStructure::Rectangular, 1.0, par);
                if m > q {
                    faer::linalg::matmul::matmul(wb, Accum::Replace, low, mid.transpose(), 1.0, par);
                }
            }
            // Where each row of the update goes, once per update (not once per entry).
            let rel = &mut wk.rel[..m];
            for (r, &g) in rel.iter_mut().zip(&dpat[p0..]) {
                *r = local(g, map);
            }
            let wbuf = &wk.w[..m * q];
            for jj in 0..q {
                let col = rel[jj] * nrows;
                let wcol = &wbuf[jj * m..(jj + 1) * m];
                for ii in jj..m {
                    ls[rel[ii] + col] -= wcol[ii];
                }
            }
        }
        for &r in pat {
            map[r] = usize::MAX;
        }
        let lm = MatMut::from_column_major_slice_mut(ls, nrows, ncols);
        let (mut top, bot) = lm.split_at_row_mut(ncols);
        match faer::linalg::cholesky::llt::factor::cholesky_in_place(top.rb_mut(), Default::default(), par, MemStack::new(&mut wk.mem), Default::default()) {
            Ok(_) => faer::linalg::triangular_solve::solve_lower_triangular_in_place(top.rb(), bot.transpose_mut(), par),
            Err(faer::linalg::cholesky::llt::factor::LltError::NonPositivePivot { index }) => {
                let mut f = self.failed.lock().unwrap_or_else(|e| e.into_inner());
                *f = Some(f.map_or(s0 + index, |g: usize| g.min(s0 + index)));
                self.stop.store(true, Ordering::Relaxed);
            }
        }
    }
}

/// A numeric Cholesky factor on a shared symbolic analysis.
#[derive(Clone)]
pub struct Factor {
    sym: Arc<Symbolic>,
    values: Vec<f64>,
}

/// The values buffer of the last factor dropped, kept for the next factorisation (ours). `L`'s
/// values are a solve's largest allocation (56 M entries, 450 MB, at 5e5 dofs), and on this
/// project's machines (virtual machines that hand freed memory back to the host) the first
/// touch of fresh pages costs about 0.5 ms per MB: ~0.2 s of a 1 s factorisation at 5e5 dofs. A
/// later factorisation (a new topology between stages, the events solver's refactorisations,
/// the benchmark's repeats) reuses the kept pages. At most one buffer, the largest, is kept;
/// [`release_spare`] frees it.
static SPARE: Mutex<Vec<f64>> = Mutex::new(Vec::new());

/// Frees the buffer kept for the next factorisation (see `SPARE`).
pub fn release_spare() {
    drop(std::mem::take(&mut *SPARE.lock().unwrap_or_else(|e| e.into_inner())));
}

impl Drop for Factor {
    fn drop(&mut self) {
        let v = std::mem::take(&mut self.values);
        let mut spare = SPARE.lock().unwrap_or_else(|e| e.into_inner());
        if v.capacity() > spare.capacity() {
            *spare = v;
        }
    }
}

impl Factor {
    /// Numeric `L L^T` of `a` (lower triangle, the pattern the symbolic analysis was made for).
    /// `Err(LltError::Numeric(_))`: a non-positive pivot (the first one met; its index is
    /// the permuted column).
    pub fn new(sym: Arc<Symbolic>, a: &SparseColMat<usize, f64>, par: Par) -> Result<Self, LltError> {
        let s = &sym.sn;
        let n = sym.fwd.len();
        let sa = a.symbolic();
        // The values are placed by the analysis's map: `a` must have the analysed pattern (an
        // internal invariant of the callers, which keep the pattern with the analysis).
        if sa.nrows() != n || sa.ncols() != n || rows_hash(sa) != sym.rows_hash {
            return Err(LltError::Generic(faer::sparse::FaerError::IndexOverflow));
        }
        // A's values in the permuted lower pattern: one pass.
        let mut av = vec![0.0f64; sym.to_perm.len()];
        let mut p = 0;
        for j in 0..n {
            for &v in a.val_of_col(j) {
                av[sym.to_perm[p] as usize] = v;
                p += 1;
            }
        }
        // Not zeroed here: each supernode zeroes its own block, in the thread that factors it.
        let len = s.len_val();
        let mut values = {
            let mut spare = SPARE.lock().unwrap_or_else(|e| e.into_inner());
            // Not a buffer much larger than needed: a small factor would hold it.
            if spare.capacity() >= len && spare.capacity() <= 2 * len.max(1 << 16) {
                std::mem::take(&mut *spare)
            } else {
                Vec::new()
            }
        };
        values.clear();
        values.try_reserve_exact(len).map_err(|_| LltError::Generic(faer::sparse::FaerError::OutOfMemory))?;
        let threads = match par {
            Par::Seq => 1,
            Par::Rayon(t) => t.get(),
        };
        let num = Numeric {
            s,
            plan: &sym.plan,
            acp: &sym.lcp,
            ari: &sym.lri,
            av: &av,
            values: values.as_mut_ptr(),
            cut: if threads > 1 { sym.plan.total / (16 * threads) as f64 } else { f64::INFINITY },
            pool: Mutex::new(Vec::new()),
            failed: Mutex::new(None),
            stop: AtomicBool::new(false),
        };
        if threads > 1 {
            rayon::scope(|sc| {
                for &r in &sym.plan.roots {
                    let num = &num;
                    sc.spawn(move |_| num.subtree(r));
                }
            });
        } else {
            let mut w = num.work();
            for &r in &sym.plan.roots {
                num.sequential(r, &mut w);
            }
        }
        if let Some(index) = num.failed.into_inner().unwrap_or_else(|e| e.into_inner()) {
            // Blocks of supernodes skipped after the failure were never written; the buffer
            // (length 0) goes back to the spare.
            let mut spare = SPARE.lock().unwrap_or_else(|e| e.into_inner());
            if values.capacity() > spare.capacity() {
                *spare = values;
            }
            return Err(LltError::Numeric(faer::linalg::cholesky::llt::factor::LltError::NonPositivePivot { index }));
        }
        // SAFETY: every supernode ran (no failure) and wrote its whole block: the blocks tile
        // `0..len` (faer's `col_ptr_for_val`).
        unsafe { values.set_len(len) };
        Ok(Factor { sym, values })
    }

    /// Stored entries of `L`.
    pub fn nnz(&self) -> usize {
        self.values.len()
    }

    /// Solves `A X = B` in place (`B` has the factor's rows, any number of columns).
    /// One right-hand side is solved on one thread: faer's supernodal solve then runs
    /// matrix-vector products, whose `Par::Rayon` form sums per-thread partial products (the
    /// result would depend on the thread count; measured: 323 of 239 700 entries differ between
    /// one and two threads). Several columns go through faer's matrix products, which split the
    /// output only.
    pub fn solve_in_place(&self, mut rhs: MatMut<'_, f64>, par: Par) {
        let (n, k) = (rhs.nrows(), rhs.ncols());
        let par = if k == 1 { Par::Seq } else { par };
        let fwd = &self.sym.fwd;
        let mut x = faer::Mat::<f64>::zeros(n, k);
        for c in 0..k {
            for (new, &old) in fwd.iter().enumerate() {
                x[(new, c)] = rhs[(old, c)];
            }
        }
        let mut mem = MemBuffer::new(self.sym.sn.solve_in_place_scratch::<f64>(k, par));
        SupernodalLltRef::new(&self.sym.sn, &self.values).solve_in_place_with_conj(Conj::No, x.as_mut(), par, MemStack::new(&mut mem));
        for c in 0..k {
            for (new, &old) in fwd.iter().enumerate() {
                rhs[(old, c)] = x[(new, c)];
            }
        }
    }

    /// Ours (issue 34, session 18): the forward half of a solve, `L y = P b`, for right-hand
    /// sides with few non-zero rows (the columns of the events solver's low-rank update,
    /// `kept.rs`): `cols` are the columns of `b` as (row, value) in the original order (rows at
    /// or beyond the factor's size are left out), `y` is returned in the factor's (permuted)
    /// order, `n x k`. A supernode whose rows of `y` are all zero is skipped: only the
    /// elimination-tree ancestors of `b`'s rows are visited, and no backward half is run. With
    /// `A^{-1} = P^T L^{-T} L^{-1} P`, `u^T A^{-1} v = (L^{-1} P u) . (L^{-1} P v)`. One thread
    /// (the same result on any thread count).
    pub fn forward_sparse(&self, cols: &[Vec<(usize, f64)>]) -> faer::Mat<f64> {
        let n = self.sym.fwd.len();
        let k = cols.len();
        let inv = &self.sym.inv;
        let mut x = faer::Mat::<f64>::zeros(n, k);
        for (c, col) in cols.iter().enumerate() {
            for &(i, v) in col.iter().filter(|e| e.0 < n) {
                x[(inv[i], c)] = v;
            }
        }
        let l = SupernodalLltRef::new(&self.sym.sn, &self.values);
        let mut tmp = faer::Mat::<f64>::zeros(0, k);
        for s in 0..self.sym.sn.n_supernodes() {
            let sn = l.supernode(s);
            let ls = sn.val();
            let size = ls.ncols();
            let start = sn.start();
            if (0..k).all(|j| x.col(j).subrows(start, size).iter().all(|&v| v == 0.0)) {
                continue;
            }
            let (top, bot) = ls.split_at_row(size);
            faer::linalg::triangular_solve::solve_lower_triangular_in_place(top, x.as_mut().subrows_mut(start, size), Par::Seq);
            let pat = sn.pattern();
            if pat.is_empty() {
                continue;
            }
            tmp.resize_with(pat.len(), k, |_, _| 0.0);
            faer::linalg::matmul::matmul(tmp.as_mut(), Accum::Replace, bot, x.as_ref().subrows(start, size), 1.0, Par::Seq);
            for j in 0..k {
                for (idx, &i) in pat.iter().enumerate() {
                    x[(i, j)] -= tmp[(idx, j)];
                }
            }
        }
        x
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
    /// Ours (session 18): `forward_sparse` gives `u^T A^{-1} v` as the dot of the forward halves
    /// (`A = L L^T` permuted). Reference: the full solve `A^{-1} v` (the factor's own, checked
    /// against faer's AMD factor above), dotted with `u`, for columns with a few non-zero rows
    /// (as the kept factor's low-rank columns), one of them with a row beyond the factor (left
    /// out). Tolerance 1e-12 relative. Also: the forward halves of a column supported in one
    /// corner of the grid leave most rows zero (only the elimination-tree ancestors are visited).
    #[test]
    fn forward_halves_give_the_inverse_products() {
        let (a, xy) = grid(60, 40);
        let n = a.nrows();
        let sym = symbolic(a.symbolic(), &nested_dissection(a.symbolic(), &xy)).unwrap();
        let f = Factor::new(sym, &a, Par::Seq).unwrap();
        let cols: Vec<Vec<(usize, f64)>> = vec![vec![(3, 1.0), (4, -0.5), (61, 0.25)], vec![(n / 2, 2.0), (n / 2 + 1, 1.0), (n + 5, 9.0)], vec![(n - 1, 1.0)]];
        let y = f.forward_sparse(&cols);
        for (p, u) in cols.iter().enumerate() {
            for (q, v) in cols.iter().enumerate() {
                let mut b = vec![0.0; n];
                v.iter().filter(|e| e.0 < n).for_each(|&(i, x)| b[i] = x);
                let z = f.solve(&b, Par::Seq);
                let full: f64 = u.iter().filter(|e| e.0 < n).map(|&(i, x)| x * z[i]).sum();
                let half: f64 = (0..n).map(|i| y[(i, p)] * y[(i, q)]).sum();
                assert!((full - half).abs() <= 1e-12 * full.abs().max(1e-300), "({p}, {q}): {full} against {half}");
            }
        }
        let zeros = (0..n).filter(|&i| y[(i, 0)] == 0.0).count();
        assert!(zeros > n / 2, "{zeros} of {n} rows zero");
    }

    #[test]
    fn dissection_orders_and_solves_bit_identically_on_any_thread_count() {
        let (a, xy) = grid(240, 160);
        let n = a.nrows();
        let order = nested_dissection(a.symbolic(), &xy);
        assert!(is_perm(&order));
        let sym = symbolic(a.symbolic(), &order).unwrap();
        // Several subtrees with enough work to run as tasks of their own on two threads.
        // The crack splits the grid in two components (two roots); each has subtrees with
        // enough work to run as tasks of their own on two threads.
        assert_eq!(sym.plan.roots.len(), 2);
        assert!(sym.plan.work.iter().filter(|&&w| w >= sym.plan.total / 32.0).count() > 4);
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
        let xa = faer::prelude::Solve::solve(&a.sp_cholesky(faer::Side::Lower).unwrap(), faer::ColRef::from_slice(&b));
        let xa: Vec<f64> = xa.iter().copied().collect();
        let d = (0..n).map(|i| (x1[i] - xa[i]).abs()).fold(0.0, f64::max);
        assert!(d < 1e-12, "nested dissection vs AMD: {d}");
    }

    /// At a size where faer's kernels take their parallel paths (2.4e5 dofs: fronts of several
    /// hundred rows, matrix-vector products above faer's 65 536-entry threshold), the factor and
    /// the solves (one and three right-hand sides) are bit-identical on 1, 2 and 4 threads.
    #[test]
    fn large_factor_and_solves_are_bit_identical_on_1_2_4_threads() {
        let (a, xy) = grid(600, 400);
        let n = a.nrows();
        let sym = symbolic(a.symbolic(), &nested_dissection(a.symbolic(), &xy)).unwrap();
        let b: Vec<f64> = (0..3 * n).map(|i| ((i * 7919) % 17) as f64 - 8.0).collect();
        let run = |t: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build().unwrap();
            pool.install(|| {
                let par = if t == 1 { Par::Seq } else { Par::rayon(t) };
                let f = Factor::new(sym.clone(), &a, par).unwrap();
                let x1 = f.solve(&b[..n], par);
                let mut x3 = b.clone();
                f.solve_in_place(MatMut::from_column_major_slice_mut(&mut x3, n, 3), par);
                (f.values.clone(), x1, x3)
            })
        };
        let one = run(1);
        for t in [2, 4] {
            let other = run(t);
            assert!(one.0 == other.0, "factor differs between 1 and {t} threads");
            assert!(one.1 == other.1, "one-column solve differs between 1 and {t} threads");
            assert!(one.2 == other.2, "three-column solve differs between 1 and {t} threads");
        }
        // And it solves (reference: the residual, 1e-12 relative).
        let kx = super::super::sym_mul(&a, &one.1);
        let r = (0..n).map(|i| (b[i] - kx[i]).abs()).fold(0.0, f64::max);
        assert!(r < 1e-12 * 8.0 * 5.0, "residual {r}");
    }

    /// A matrix that is not positive definite (one negative diagonal entry in the middle of the
    /// grid) is refused with a numeric error on one thread and on two, not factored.
    #[test]
    fn indefinite_matrix_is_refused_on_any_thread_count() {
        let (a, xy) = grid(120, 80);
        let n = a.nrows();
        let order = nested_dissection(a.symbolic(), &xy);
        let sym = symbolic(a.symbolic(), &order).unwrap();
        let mut t = Vec::new();
        let sa = a.as_ref();
        for j in 0..n {
            for (i, &v) in sa.row_idx_of_col(j).zip(sa.val_of_col(j)) {
                t.push(faer::sparse::Triplet::new(i, j, if i == j && i == n / 2 { -5.0 } else { v }));
            }
        }
        let bad = SparseColMat::try_new_from_triplets(n, n, &t).unwrap();
        assert!(matches!(Factor::new(sym.clone(), &bad, Par::Seq), Err(LltError::Numeric(_))));
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        assert!(pool.install(|| matches!(Factor::new(sym.clone(), &bad, Par::rayon(2)), Err(LltError::Numeric(_)))));
        assert!(Factor::new(sym, &a, Par::Seq).is_ok());
    }

    /// Our elimination tree and column counts are faer's (`prefactorize_symbolic_cholesky`, the
    /// reference), on the permuted grid with a crack (two components) and on a random ordering.
    #[test]
    fn own_etree_and_counts_are_faers() {
        use faer::sparse::linalg::cholesky::simplicial;
        let (a, xy) = grid(60, 40);
        let n = a.nrows();
        let nd = nested_dissection(a.symbolic(), &xy);
        let mut rnd: Vec<usize> = (0..n).collect();
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for k in (1..n).rev() {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            rnd.swap(k, (state % (k as u64 + 1)) as usize);
        }
        for order in [nd, rnd] {
            let sym = symbolic(a.symbolic(), &order).unwrap();
            // Upper pattern of the permuted matrix = transpose of our permuted lower pattern.
            let lower = SymbolicSparseColMat::new_unsorted_checked(n, n, sym.lcp.clone(), None, sym.lri.iter().map(|&r| r as usize).collect());
            let upper = lower.as_ref().transpose().to_col_major().unwrap();
            let mut etree = vec![0isize; n];
            let mut counts = vec![0usize; n];
            let mut mem = MemBuffer::new(simplicial::prefactorize_symbolic_cholesky_scratch::<usize>(n, upper.compute_nnz()));
            simplicial::prefactorize_symbolic_cholesky(&mut etree, &mut counts, upper.as_ref(), MemStack::new(&mut mem));
            assert_eq!(elimination_tree(upper.col_ptr(), upper.row_idx()), etree);
            assert_eq!(column_counts(&sym.lcp, &sym.lri, &etree), counts);
        }
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
