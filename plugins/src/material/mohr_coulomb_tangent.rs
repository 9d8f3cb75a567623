//! The consistent (algorithmic) tangent of `mohr_coulomb`'s return (the implicit plastic
//! check, `check/newton.rs`): the derivative of the updated stress with respect to the strain
//! increment, `D_alg = d sigma_{n+1} / d deps = C D`, with `D` the elastic moduli of the trial
//! (`d sigma_tr / d deps`) and `C = d sigma_{n+1} / d sigma_tr` the Jacobian of the return.
//!
//! In principal stresses (sorted `s1 >= s2 >= s3`), for the active planes `A` the return is
//! `s = s_tr - sum_{j in A} dl_j D m_j` with `sum_j (n_k . D m_j) dl_j = f_k(s_tr)`, linear in
//! `s_tr` (the law is perfectly plastic and its surfaces are planes), so its Jacobian is the
//! constant
//!
//! ```text
//! P = I - sum_{j, k in A} (D m_j) (A^-1)_jk n_k^T,    A_kj = n_k . D m_j
//! ```
//!
//! (face: one plane, edge: two, apex and tension corners: three; `P = I` elastic). The stress
//! is rebuilt on the trial's principal axes, `sigma = m + h (c2, -c2, s2)` in-plane with
//! `m = (s_a + s_b) / 2`, `h = (s_a - s_b) / 2`, `c2 = (sxx - syy) / (2 R)`, `s2 = sxy / R`,
//! `R` Mohr's radius of the trial, and `szz = s_z`; its derivative adds to the principal
//! part `P` the rotation of the axes, whose weight is `h / R = (s_a - s_b) / (s_a,tr -
//! s_b,tr)` (de Souza Neto, Peric & Owen 2008, Computational Methods for Plasticity, section
//! 8.1 and appendix A: the derivative of an isotropic tensor function of a symmetric tensor;
//! in the limit `R -> 0` the derivative of that ratio, `(P_aa - P_ab - P_ba + P_bb) / 2`).
//! The tangent is symmetric for associated flow (`psi = phi`, the tension planes are always
//! associated). Checked against central finite differences of `update` on every branch
//! (`mohr_coulomb_tests.rs`, `tangent_*`).
use super::{MohrCoulomb, Trial};

type M4 = [[f64; 4]; 4];

/// `inv(a)` of the leading `k x k` block (Gauss-Jordan with partial pivoting; `k <= 3`).
fn inverse(a: [[f64; 3]; 3], k: usize) -> [[f64; 3]; 3] {
    let mut m = a;
    let mut inv = [[0.0; 3]; 3];
    for (i, row) in inv.iter_mut().enumerate().take(k) {
        row[i] = 1.0;
    }
    for c in 0..k {
        let p = (c..k).fold(c, |b, r| if m[r][c].abs() > m[b][c].abs() { r } else { b });
        m.swap(c, p);
        inv.swap(c, p);
        let d = m[c][c];
        for j in 0..k {
            m[c][j] /= d;
            inv[c][j] /= d;
        }
        for r in 0..k {
            if r != c {
                let f = m[r][c];
                for j in 0..k {
                    m[r][j] -= f * m[c][j];
                    inv[r][j] -= f * inv[c][j];
                }
            }
        }
    }
    inv
}

impl MohrCoulomb {
    /// `d sigma / d sigma_tr` of the trial's component order `[sxx, syy, sxy, szz]`; `None`
    /// when the update is elastic.
    fn return_jacobian(&self, t: &Trial) -> Option<M4> {
        let Trial { s, half, rad, pa, pb, pz, inside } = *t;
        if inside {
            return None;
        }
        let (sorted, pos) = super::sort_principal(pa, pb, pz);
        let r = self.return_active(sorted)?;
        // P = d(returned sorted) / d(sorted trial).
        let mut p = [[0.0; 3]; 3];
        if r.size == 0 {
            // The round-off guard at the apex: a constant point, or the mean stress.
            let v = if self.r[3].is_finite() { 0.0 } else { 1.0 / 3.0 };
            p = [[v; 3]; 3];
        } else {
            let k = r.size;
            let a: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| if i < k && j < k { self.a[r.act[i]][r.act[j]] } else { 0.0 }));
            let ai = inverse(a, k);
            for (i, row) in p.iter_mut().enumerate() {
                row[i] = 1.0;
            }
            for t in 0..k {
                let w: [f64; 3] = std::array::from_fn(|j| (0..k).map(|u| ai[t][u] * self.n[r.act[u]][j]).sum());
                for i in 0..3 {
                    for j in 0..3 {
                        p[i][j] -= self.dm[r.act[t]][i] * w[j];
                    }
                }
            }
        }
        // The same in the unsorted order (a, b, z).
        let q: [[f64; 3]; 3] = std::array::from_fn(|u| std::array::from_fn(|v| p[pos[u]][pos[v]]));
        let (c2, s2) = crate::material::mohr_coulomb::rotation(half, s[2], rad);
        // d(pa, pb, pz) / d(sxx, syy, sxy, szz).
        let dp = [[0.5 * (1.0 + c2), 0.5 * (1.0 - c2), s2, 0.0], [0.5 * (1.0 - c2), 0.5 * (1.0 + c2), -s2, 0.0], [0.0, 0.0, 0.0, 1.0]];
        let dn: [[f64; 4]; 3] = std::array::from_fn(|u| std::array::from_fn(|c| (0..3).map(|v| q[u][v] * dp[v][c]).sum()));
        let (na, nb) = (r.out[pos[0]], r.out[pos[1]]);
        let h = 0.5 * (na - nb);
        let scale = self.scale + sorted[0].abs().max(sorted[2].abs());
        let w = if rad > 1e-13 * scale { h / rad } else { 0.5 * (q[0][0] - q[0][1] - q[1][0] + q[1][1]) };
        let rot_c = [0.5 * s2 * s2, -0.5 * s2 * s2, -c2 * s2, 0.0];
        let rot_s = [-0.5 * s2 * c2, 0.5 * s2 * c2, c2 * c2, 0.0];
        Some(std::array::from_fn(|i| {
            std::array::from_fn(|c| {
                let (dm, dh) = (0.5 * (dn[0][c] + dn[1][c]), 0.5 * (dn[0][c] - dn[1][c]));
                match i {
                    0 => dm + c2 * dh + w * rot_c[c],
                    1 => dm - c2 * dh - w * rot_c[c],
                    2 => s2 * dh + w * rot_s[c],
                    _ => dn[2][c],
                }
            })
        }))
    }

    /// The consistent tangent `d sigma_{n+1} / d deps` of `update(st, de, _)` (module docs).
    pub fn consistent_tangent(&self, st: &[f64; 4], de: [f64; 4], out: &mut M4) {
        let (l, g) = (self.lambda, self.g);
        let l2g = l + 2.0 * g;
        let del = [[l2g, l, 0.0, l], [l, l2g, 0.0, l], [0.0, 0.0, g, 0.0], [l, l, 0.0, l2g]];
        match self.return_jacobian(&self.trial(st, de)) {
            None => *out = del,
            Some(c) => *out = std::array::from_fn(|i| std::array::from_fn(|j| (0..4).map(|k| c[i][k] * del[k][j]).sum())),
        }
    }

    /// Associated flow on every plane in use (the tangent is then symmetric).
    pub fn associated(&self) -> bool {
        self.n == self.m
    }
}

#[cfg(test)]
#[path = "mohr_coulomb_tangent_tests.rs"]
mod tests;
