//! Assembly of `K_ff` (lower triangle, compressed sparse columns) on a pattern built once from
//! the cluster graph.
//!
//! Why not `SparseColMat::try_new_from_triplets`: it sorts every triplet (about 36 per Q4
//! element for the lower triangle), which cost as much as faer's whole numeric factorisation on
//! 5e5 dofs. Here the pattern comes from the cluster adjacency (a counting pass, then a short
//! sort per cluster), and values are scattered straight into place by a binary search in the
//! column (at most 18 rows in a structured Q4 mesh). The pattern is kept by the solver and
//! reused while the fingerprint (clusters, fixities, connectivity) is unchanged, like the
//! symbolic factorisation.
use std::hash::{DefaultHasher, Hash, Hasher};

use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use flem_core::model::Model;

/// Hash of everything the pattern depends on: number of clusters, fixity bits, connectivity.
pub(crate) fn fingerprint(model: &Model, fix: &[u8]) -> u64 {
    let mut h = DefaultHasher::new();
    fix.len().hash(&mut h);
    fix.hash(&mut h);
    for blk in &model.blocks {
        blk.len().hash(&mut h);
        for i in 0..blk.len() {
            blk.conn(i).hash(&mut h);
        }
    }
    h.finish()
}

/// Lower-triangle pattern of `K_ff`; `eq[2 c + d]` is the free-dof number (increasing with
/// `(c, d)`) or `usize::MAX`. Every free dof has its diagonal entry (a cluster without element
/// stays visible to the factorisation, which then reports it).
pub(crate) fn pattern(model: &Model, eq: &[usize], n: usize) -> SymbolicSparseColMat<usize> {
    let nc = eq.len() / 2;
    // Cluster adjacency, upper half: for cluster a, the clusters b >= a sharing an element.
    let mut ptr = vec![1usize; nc + 1];
    let each_pair = |f: &mut dyn FnMut(usize, u32)| {
        for blk in &model.blocks {
            for i in 0..blk.len() {
                let c = blk.conn(i);
                for &a in c {
                    for &b in c {
                        if b > a {
                            f(a as usize, b);
                        }
                    }
                }
            }
        }
    };
    each_pair(&mut |a, _| ptr[a] += 1);
    let mut acc = 0;
    for p in ptr.iter_mut() {
        let k = *p;
        *p = acc;
        acc += k;
    }
    let mut adj = vec![0u32; acc];
    let mut fill: Vec<usize> = ptr[..nc].to_vec();
    for a in 0..nc {
        adj[fill[a]] = a as u32;
        fill[a] += 1;
    }
    each_pair(&mut |a, b| {
        adj[fill[a]] = b;
        fill[a] += 1;
    });
    let mut col_ptr = Vec::with_capacity(n + 1);
    col_ptr.push(0usize);
    let mut row_idx = Vec::with_capacity(9 * n);
    for a in 0..nc {
        let nb = &mut adj[ptr[a]..ptr[a + 1]];
        nb.sort_unstable();
        for d in 0..2 {
            let j = eq[2 * a + d];
            if j == usize::MAX {
                continue;
            }
            let mut last = u32::MAX;
            for &b in nb.iter() {
                if b == last {
                    continue;
                }
                last = b;
                for d2 in 0..2 {
                    let i = eq[2 * b as usize + d2];
                    if i != usize::MAX && i >= j {
                        row_idx.push(i);
                    }
                }
            }
            col_ptr.push(row_idx.len());
        }
    }
    SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx)
}

/// Values of `K_ff` on `pat` and the right-hand side `f_f - K_fp u_p`.
pub(crate) fn values(model: &Model, eq: &[usize], pat: &SymbolicSparseColMat<usize>, f_ext: &[[f64; 2]], u_p: &[[f64; 2]]) -> (SparseColMat<usize, f64>, Vec<f64>) {
    let n = pat.ncols();
    let (cp, ri) = (pat.col_ptr(), pat.row_idx());
    let mut vals = vec![0.0; ri.len()];
    let mut rhs = vec![0.0; n];
    for (c, f) in f_ext.iter().enumerate() {
        for d in 0..2 {
            if eq[2 * c + d] != usize::MAX {
                rhs[eq[2 * c + d]] += f[d];
            }
        }
    }
    let mut k = Vec::new();
    let mut g = Vec::new();
    for blk in &model.blocks {
        let nd = 2 * blk.nodes_per_elem();
        k.resize(nd * nd, 0.0);
        g.resize(nd, 0usize);
        for i in 0..blk.len() {
            blk.stiffness(i, &mut k);
            let conn = blk.conn(i);
            for r in 0..nd {
                g[r] = 2 * conn[r / 2] as usize + r % 2;
            }
            for r in 0..nd {
                let er = eq[g[r]];
                if er == usize::MAX {
                    continue;
                }
                for s in 0..nd {
                    let es = eq[g[s]];
                    let v = k[r * nd + s];
                    if es == usize::MAX {
                        rhs[er] -= v * u_p[g[s] / 2][g[s] % 2];
                    } else if er >= es {
                        let col = &ri[cp[es]..cp[es + 1]];
                        vals[cp[es] + col.partition_point(|&x| x < er)] += v;
                    }
                }
            }
        }
    }
    (SparseColMat::new(pat.clone(), vals), rhs)
}
