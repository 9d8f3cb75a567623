//! Assembly of `K_ff` (lower triangle, compressed sparse columns) on a pattern built once from
//! the cluster graph.
//!
//! Why not `SparseColMat::try_new_from_triplets`: it sorts every triplet (about 36 per Q4
//! element for the lower triangle), which cost as much as faer's whole numeric factorisation on
//! 5e5 dofs. Here the pattern comes from the cluster adjacency (a counting pass, then a short
//! sort per cluster), and values are scattered straight into place: each column's rows are found
//! by one forward walk over the column (at most 18 rows in a structured Q4 mesh), the element's
//! free dofs sorted by equation number. The pattern is kept by the solver and
//! reused while the fingerprint (clusters, fixities, connectivity, geometry, materials) is
//! unchanged, like the symbolic and numeric factorisations.
//!
//! Element stiffness: `K_e = sum_gp B^T D B w det J t` written out per Gauss point from the
//! shape gradients (`element::gradients`), one generic kernel per block (monomorphised for Q4
//! and T3). A block that is not isoparametric (`Block::isoparametric`: an element with condensed
//! internal fields such as `qm6`) gives its own `Block::stiffness`. `Block::stiffness` of Q4/T3 builds the same matrix column by column from the force kernel
//! (eight force evaluations for a Q4), about four times slower; the unit test below checks that
//! both agree to round-off.
use std::hash::{DefaultHasher, Hash, Hasher};

use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use flem_core::element::block::Block;
use flem_core::element::model::Model;
use flem_core::element::{self, Dmat, Plane, Shape};

use crate::elements::{Q4, T3};
use flem_core::mesh::CellKind;

/// Hash of everything the pattern and the matrix values depend on: number of clusters, fixity
/// bits, connectivity, reference coordinates and materials.
pub(crate) fn fingerprint(model: &Model, fix: &[u8]) -> u64 {
    let mut h = DefaultHasher::new();
    fix.len().hash(&mut h);
    fix.hash(&mut h);
    for blk in &model.blocks {
        blk.len().hash(&mut h);
        blk.element().hash(&mut h);
        let m = blk.material();
        [m.young, m.poisson, m.thickness].map(f64::to_bits).hash(&mut h);
        (m.plane == Plane::Strain).hash(&mut h);
        for i in 0..blk.len() {
            blk.conn(i).hash(&mut h);
            for x in blk.coords(i) {
                x.map(f64::to_bits).hash(&mut h);
            }
        }
    }
    h.finish()
}

/// Element stiffness (row-major 2N x 2N, dofs x0 y0 x1 y1 ...) of an isotropic element.
pub(crate) fn elem_stiffness<S: Shape<N>, const N: usize>(x: &[[f64; 2]], d: &Dmat, t: f64, k: &mut [f64]) {
    let x: [[f64; 2]; N] = std::array::from_fn(|a| x[a]);
    let n2 = 2 * N;
    k[..n2 * n2].fill(0.0);
    for &(xi, w) in S::GAUSS {
        let (g, det) = element::gradients::<S, N>(&x, xi);
        let c = w * det * t;
        for a in 0..N {
            let (a0, a1) = (c * g[a][0], c * g[a][1]);
            for b in 0..N {
                let (b0, b1) = (g[b][0], g[b][1]);
                let (r0, r1) = (2 * a * n2 + 2 * b, (2 * a + 1) * n2 + 2 * b);
                k[r0] += a0 * d.d11 * b0 + a1 * d.d33 * b1;
                k[r0 + 1] += a0 * d.d12 * b1 + a1 * d.d33 * b0;
                k[r1] += a1 * d.d12 * b0 + a0 * d.d33 * b1;
                k[r1 + 1] += a1 * d.d11 * b1 + a0 * d.d33 * b0;
            }
        }
    }
}

/// The right-hand side `f_f - K_fp u_p` without the matrix: `K_fp u_p` is the internal force of
/// the displacement that is `u_p` on prescribed dofs and 0 on free ones (linear elasticity).
pub(crate) fn rhs_by_forces(model: &Model, eq: &[usize], n: usize, fix: &[u8], f_ext: &[[f64; 2]], u_p: &[[f64; 2]]) -> Vec<f64> {
    let nc = fix.len();
    let up: Vec<[f64; 2]> = (0..nc).map(|c| std::array::from_fn(|d| if fix[c] & (1 << d) != 0 { u_p[c][d] } else { 0.0 })).collect();
    let mut fi = vec![[0.0; 2]; nc];
    if up.iter().any(|v| v[0] != 0.0 || v[1] != 0.0) {
        model.internal_forces(&up, &mut fi);
    }
    let mut rhs = vec![0.0; n];
    for c in 0..nc {
        for d in 0..2 {
            if eq[2 * c + d] != usize::MAX {
                rhs[eq[2 * c + d]] = f_ext[c][d] - fi[c][d];
            }
        }
    }
    rhs
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
    for blk in &model.blocks {
        let b: &dyn Block = blk.as_ref();
        match b.kind() {
            CellKind::Q4 => scatter::<Q4, 4>(b, eq, cp, ri, u_p, &mut vals, &mut rhs),
            CellKind::T3 => scatter::<T3, 3>(b, eq, cp, ri, u_p, &mut vals, &mut rhs),
        }
    }
    (SparseColMat::new(pat.clone(), vals), rhs)
}

/// Adds one block's element stiffnesses into `vals` (free-free) and `-K_fp u_p` into `rhs`.
///
/// The element's free dofs are sorted by equation number (at most 8, insertion sort); each
/// column's rows are then found by one forward walk along the column's ascending row list
/// instead of a binary search per entry (assembly 1.27 x faster at 1e4 dofs, 1.34 x at 1e5: best
/// of three interleaved `flem bench implicit` runs of both binaries, docs/perf/README.md; the
/// values are added in the same order, so the matrix is bit-identical: `flem compare` output
/// unchanged).
fn scatter<S: Shape<N>, const N: usize>(blk: &dyn Block, eq: &[usize], cp: &[usize], ri: &[usize], u_p: &[[f64; 2]], vals: &mut [f64], rhs: &mut [f64]) {
    let mat = blk.material();
    let (d, t) = (mat.dmat(), mat.thickness);
    let nd = 2 * N;
    let mut k = [0.0; 64];
    let mut g = [0usize; 8];
    let mut e = [0usize; 8];
    let mut free = [0usize; 8];
    let iso = blk.isoparametric();
    for i in 0..blk.len() {
        if iso {
            elem_stiffness::<S, N>(blk.coords(i), &d, t, &mut k);
        } else {
            // An element with condensed internal fields (e.g. `qm6`): its own stiffness, the
            // Jacobian of the explicit step's force.
            blk.stiffness(i, &mut k[..nd * nd]);
        }
        let conn = blk.conn(i);
        let (mut nf, mut prescribed) = (0, false);
        for r in 0..nd {
            g[r] = 2 * conn[r / 2] as usize + r % 2;
            e[r] = eq[g[r]];
            if e[r] == usize::MAX {
                prescribed = true;
            } else {
                // insertion into `free`, ascending by equation number
                let mut j = nf;
                while j > 0 && e[free[j - 1]] > e[r] {
                    free[j] = free[j - 1];
                    j -= 1;
                }
                free[j] = r;
                nf += 1;
            }
        }
        if prescribed {
            for r in 0..nd {
                if e[r] == usize::MAX {
                    continue;
                }
                for s in 0..nd {
                    if e[s] == usize::MAX {
                        rhs[e[r]] -= k[r * nd + s] * u_p[g[s] / 2][g[s] % 2];
                    }
                }
            }
        }
        for c in 0..nf {
            let s = free[c];
            let (base, col) = (cp[e[s]], &ri[cp[e[s]]..cp[e[s] + 1]]);
            let mut p = 0;
            for &r in &free[c..nf] {
                while col[p] < e[r] {
                    p += 1;
                }
                vals[base + p] += k[r * nd + s];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::elements::{Q4, T3};
    use flem_core::element::{Material, Plane};

    /// The written-out `B^T D B` stiffness equals the column-by-column one of the core
    /// (`element::stiffness`, built from the force kernel). Reference: that function;
    /// tolerance 1e-13 of the largest entry. Distorted Q4 and T3, plane strain and stress.
    #[test]
    fn stiffness_matches_core_force_kernel() {
        let q = [[0.0, 0.0], [1.2, 0.1], [1.0, 0.9], [-0.1, 1.1]];
        for plane in [Plane::Strain, Plane::Stress] {
            let d = Material { young: 210.0, poisson: 0.3, density: 1.0, thickness: 0.7, plane }.dmat();
            let (mut a, mut b) = ([0.0; 64], [0.0; 64]);
            super::elem_stiffness::<Q4, 4>(&q, &d, 0.7, &mut a);
            flem_core::element::stiffness::<Q4, 4>(&q, &d, 0.7, &mut b);
            let m = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= 1e-13 * m), "Q4 {plane:?}");
            let t = [q[0], q[1], q[2]];
            let (mut a, mut b) = ([0.0; 36], [0.0; 36]);
            super::elem_stiffness::<T3, 3>(&t, &d, 0.7, &mut a);
            flem_core::element::stiffness::<T3, 3>(&t, &d, 0.7, &mut b);
            let m = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= 1e-13 * m), "T3 {plane:?}");
        }
    }
}
