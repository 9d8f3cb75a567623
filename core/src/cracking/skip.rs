//! The certified skip of the failure check (ours, issue 24): a check whose every point is
//! provably inside the criterion is skipped, so that the splits, their order and the output are
//! exactly those of evaluating every point, at a fraction of the cost.
//!
//! # The bound
//! The paper's nodal stress (corner mean, METHOD section 3) of a cluster `c` is linear in the
//! displacement: `sigma_c(u) = 1/n_c sum_{k in c} A_k u_e(k)`, where `A_k` (3 x 2N) maps the
//! corner displacements of the element `e(k)` of copy `k` to its stress at the copy's corner.
//! A rigid translation gives no stress (`A_k t = 0`), so with `du = u - u_ref`,
//!
//! `|sigma_c(u) - sigma_c(u_ref)|_inf <= max_{k in c} L_k delta_e(k)`,
//!
//! `L_k = max_row sum_j |(A_k)_rj|` (the infinity operator norm, computed once per model: from
//! the corner gradients when every block can (`Block::corner_lipschitz`: isoparametric kinds,
//! one pass), else by probing the blocks' own `corner_stress` with unit displacements on a
//! distance-2 colouring of the clusters (2 x colours passes: ~80 ms at 1e5 Q4, the one-time
//! cost of the first check that session 10 saw in `flem bench step`); it depends on the element
//! geometry only, so splits do not change it) and
//! `delta_e = max_d (max_i du_id - min_i du_id) / 2` (the half range of the corner
//! displacement changes, i.e. `du` less its best translation). The in-plane principal values
//! move at most `(1 + sqrt 2)` times the component bound (`|d(sxx + syy)/2| <= eps`,
//! `|d r| <= sqrt 2 eps`), and the out-of-plane `szz = nu (sxx + syy)` at most `2 nu <= 1`
//! times it: so every principal value moves by at most `rho = (1 + sqrt 2) max_k L_k delta_e`.
//!
//! The criterion supplies the margin (`FailureCriterion::margin`): a `rho_c` such that no
//! principal triple within `rho_c` (max norm) of the point's fails. A check is skipped when
//! `rho < rho_c` at every copy; otherwise it is evaluated in full, which also becomes the new
//! reference (`u_ref`, margins). A criterion without a margin (the default; dynamic plugins),
//! a failed point, a split, the nonlocal average (ours; its average spans a radius, not the
//! element patch), co-rotational or stateful blocks (stress not linear in `u`): no skip.
//!
//! Round-off: the margin is cut by `1e-9 (|m| + |s1| + |s3| + |s2|)`, `L_k` raised by `1e-9`
//! relative, and `delta_e` raised by `1e-9 max |u|` over the element's corners (both states):
//! this covers the rounding of the nodal stress (`~1e-15 L |u|`), of the translation the
//! gradients do not annihilate exactly, and of the principal values (`~1e-15 |sigma|`).
//!
//! Two tiers test `rho < rho_c` ([`Skip::certified`]): a streaming pass over the clusters
//! (`max |u - b|` against one allowance, where the base `b` is `u_ref` or the `u` of the last
//! element pass that certified: no gather, a few bytes per cluster) and, when it fails, the
//! element pass (each element's half range against its own allowance).
//!
//! The failure index of a skipped check (VTU output, checkpoints) is computed on demand from the
//! displacement of that check ([`super::Cracking::failure_index`]), so the output is the same.
use crate::element::model::Model;

/// Lipschitz constants per copy and the reference of the last full evaluation.
#[derive(Default)]
pub struct Skip {
    /// `(1 + 1e-9) L_k` per copy (empty until first needed).
    lip: Vec<f64>,
    /// Allowed `delta` per element: `min_k m_c(k) / ((1 + sqrt 2) L_k)` at the reference.
    allowed: Vec<f64>,
    /// Cluster displacements at the reference.
    u_ref: Vec<[f64; 2]>,
    /// Whether `allowed` and `u_ref` hold a reference.
    valid: bool,
    /// Number of clusters and of cuts at the reference (a split elsewhere invalidates it).
    at: (usize, usize),
    /// Corners of every element when all have as many (4, 3), else 0.
    uniform: u8,
    /// `min_e allowed[e]`: the node tier's allowance against `u_ref` (see [`Skip::certified`]).
    allowed_min: f64,
    /// The node tier's base when it is not `u_ref`: the `u` of the last element pass that
    /// certified, and the smallest slack it left (`slack`, margin factor included).
    u_base: Vec<[f64; 2]>,
    base_is_ref: bool,
    slack: f64,
    /// The margin factor `slack` was computed with.
    slack_factor: f64,
    /// Back-off of the node tier after it fails: checks to wait, and the exponent.
    wait: u32,
    backoff: u32,
    /// Checks certified by the node tier and by the element pass (diagnostics, tests).
    pub n_node_tier: u64,
    pub n_element_tier: u64,
}

/// `1 + sqrt 2`: the bound of a principal value's move per unit of the stress components'.
const PRINCIPAL_FACTOR: f64 = 1.0 + std::f64::consts::SQRT_2;

impl Skip {
    /// The relative round-off allowance of the bound (see the module doc).
    pub const ROUND: f64 = 1e-9;

    /// Forgets the reference: the next check is evaluated in full.
    pub fn invalidate(&mut self) {
        self.valid = false;
    }

    /// Whether the model's nodal stress is linear in `u` (the bound's premise).
    pub fn applies(model: &Model) -> bool {
        !model.corotational && !model.stateful
    }

    /// `L_k` of every copy (once per model).
    fn ensure_lip(&mut self, model: &Model) {
        let topo = &model.topo;
        let nk = topo.copy_cluster.len();
        if self.lip.len() == nk {
            return;
        }
        let mut direct = Vec::new();
        if model.corner_lipschitz(&mut direct) {
            // Every block gives its operator's row sums from its gradients in one pass (the
            // probing below costs 2 x colours corner-stress passes: ~80 ms at 1e5 Q4).
            self.lip = direct.into_iter().map(|l| l * (1.0 + Self::ROUND)).collect();
            return;
        }
        self.lip = Self::probed_lip(model);
    }

    /// `L_k` of every copy by probing the blocks' `corner_stress` with unit displacements
    /// (the general path; `Block::corner_lipschitz` is the shortcut; public for the tests that
    /// hold one against the other).
    pub fn probed_lip(model: &Model) -> Vec<f64> {
        let topo = &model.topo;
        let nk = topo.copy_cluster.len();
        let nc = topo.n_clusters();
        // Elements of each cluster (CSR), then a greedy distance-2 colouring: no two clusters
        // of one colour share an element, so a unit displacement on one colour class moves at
        // most one corner of each element.
        let mut start = vec![0u32; nc + 1];
        for c in &topo.copy_cluster {
            start[c.idx() + 1] += 1;
        }
        for i in 0..nc {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut elems = vec![0u32; nk];
        for (k, c) in topo.copy_cluster.iter().enumerate() {
            elems[fill[c.idx()] as usize] = topo.copy_elem[k].0;
            fill[c.idx()] += 1;
        }
        let copies = |e: usize| topo.elem_first_copy[e] as usize..topo.elem_first_copy[e + 1] as usize;
        let mut colour = vec![u32::MAX; nc];
        let mut stamp: Vec<usize> = Vec::new();
        let mut n_col = 0u32;
        for c in 0..nc {
            for &e in &elems[start[c] as usize..start[c + 1] as usize] {
                for k in copies(e as usize) {
                    let col = colour[topo.copy_cluster[k].idx()];
                    if col != u32::MAX {
                        stamp[col as usize] = c + 1;
                    }
                }
            }
            let col = (0..n_col).find(|&q| stamp[q as usize] != c + 1).unwrap_or(n_col);
            if col == n_col {
                n_col += 1;
                stamp.push(0);
            }
            colour[c] = col;
        }
        let mut sums = vec![[0.0f64; 3]; nk];
        let (mut u, mut corner) = (vec![[0.0f64; 2]; nc], Vec::new());
        for col in 0..n_col {
            for d in 0..2 {
                for (c, uc) in u.iter_mut().enumerate() {
                    *uc = [0.0; 2];
                    if colour[c] == col {
                        uc[d] = 1.0;
                    }
                }
                model.corner_stresses(&u, &mut corner);
                for (s, x) in sums.iter_mut().zip(&corner) {
                    for r in 0..3 {
                        s[r] += x[r].abs();
                    }
                }
            }
        }
        sums.iter().map(|s| s[0].max(s[1]).max(s[2]) * (1.0 + Self::ROUND)).collect()
    }

    /// Takes `u` and the criterion's margins (`margin[c]`, stress units, after the round-off
    /// cut; `<= 0` or NaN: no skip) as the new reference. `cuts`: the cuts applied so far.
    pub fn set_reference(&mut self, model: &Model, u: &[[f64; 2]], margin: &[f64], cuts: usize) {
        self.valid = false;
        let topo = &model.topo;
        let nc = topo.n_clusters();
        // Every cluster must hold with room (a cluster without copies has zero stress and is
        // covered by its own margin here).
        if u.len() != nc || margin.len() != nc || !margin.iter().all(|&m| m > 0.0) {
            return;
        }
        self.ensure_lip(model);
        let first = &topo.elem_first_copy;
        self.allowed.clear();
        // The round-off allowance `ROUND max |u|` (both states) is split: `ROUND max |u_ref|`
        // comes off the allowance here, `ROUND max |du|` is added at the check
        // (`|u| <= |u_ref| + |du|`).
        self.allowed.extend((0..first.len() - 1).map(|e| {
            let ks = first[e] as usize..first[e + 1] as usize;
            let mag = ks.clone().map(|k| u[topo.copy_cluster[k].idx()]).fold(0.0f64, |a, x| a.max(x[0].abs()).max(x[1].abs()));
            ks.map(|k| margin[topo.copy_cluster[k].idx()] / (PRINCIPAL_FACTOR * self.lip[k])).fold(f64::INFINITY, f64::min) - Self::ROUND * mag
        }));
        self.uniform = (0..first.len() - 1).all(|e| first[e + 1] - first[e] == 4) as u8 * 4;
        if self.uniform == 0 && (0..first.len() - 1).all(|e| first[e + 1] - first[e] == 3) {
            self.uniform = 3;
        }
        // A NaN allowance propagates (never certified).
        self.allowed_min = self.allowed.iter().fold(f64::INFINITY, |m, &a| if a.is_nan() || m.is_nan() { f64::NAN } else { m.min(a) });
        self.base_is_ref = true;
        (self.wait, self.backoff) = (0, 0);
        self.u_ref.clear();
        self.u_ref.extend_from_slice(u);
        self.at = (nc, cuts);
        self.valid = true;
    }

    /// True when the check at `u` is certified to find no failing point (see the module doc).
    /// `margin_factor` is 1 (values above 1 make the bound unsafe: tests only). Chunks on the
    /// model's pool (a max and a min over fixed chunks: the answer does not depend on the threads).
    ///
    /// Two tiers, both exact consequences of the bound:
    /// 1. **Node tier**: `D = max_c |u_c - b_c|_inf` over all clusters against a base `b`, one
    ///    streaming pass over two arrays (no gather). The base is `u_ref` with the smallest
    ///    allowance, or the `u` of the last element pass that certified with the smallest
    ///    slack `S = (1 - ROUND) min_e (mf allowed_e - half_e - ROUND big_e)` it left (`mf` the
    ///    margin factor; a base kept under another factor is not used): the half range is a
    ///    seminorm and the largest change a norm, so `half_e(u - u_ref) <= half_e(b - u_ref) + D`
    ///    and `big_e(u - u_ref) <= big_e(b - u_ref) + D`, and `D (1 + ROUND)(1 + 2 ROUND) < S`
    ///    certifies every element at once (the `ROUND` factors cover the rounding of the
    ///    passes; the chained rounding, ~1e-16 relative, sits far inside the 1e-9 cushions of
    ///    the margins and allowances). It ignores the translation an element shares with its neighbours, so it is
    ///    weaker than the element pass: after it fails it waits 1, 3, 7, ... up to 63 checks.
    /// 2. **Element pass**: each element's half range against its own allowance; when the node
    ///    tier is due at the next check, it keeps `u` and the slack as the node tier's base.
    pub fn certified(&mut self, model: &Model, u: &[[f64; 2]], cuts: usize, margin_factor: f64) -> bool {
        let topo = &model.topo;
        if !self.valid || self.at != (topo.n_clusters(), cuts) || u.len() != self.u_ref.len() {
            return false;
        }
        let pool = model.pool.as_deref();
        if self.wait > 0 {
            self.wait -= 1;
        } else {
            let by_ref = self.base_is_ref || self.slack_factor != margin_factor;
            let (base, allowance) = if by_ref { (&self.u_ref[..], self.allowed_min * margin_factor) } else { (&self.u_base[..], self.slack) };
            if Self::node_pass(u, base, pool) * ((1.0 + Self::ROUND) * (1.0 + 2.0 * Self::ROUND)) < allowance {
                self.n_node_tier += 1;
                self.backoff = 0;
                return true;
            }
            self.backoff = (self.backoff + 1).min(6);
            self.wait = (1 << self.backoff) - 1;
        }
        const CHUNK: usize = 8192;
        let ne = self.allowed.len();
        let chunk = |k: usize| -> f64 {
            let r = k * CHUNK..((k + 1) * CHUNK).min(ne);
            match self.uniform {
                4 => self.pass::<4>(topo, u, r, margin_factor),
                3 => self.pass::<3>(topo, u, r, margin_factor),
                _ => self.pass::<0>(topo, u, r, margin_factor),
            }
        };
        // The smallest slack, or a value <= 0 (not certified); min is exact, so any split of
        // the chunks over threads gives the same value.
        let n_chunks = ne.div_ceil(CHUNK);
        let slack = match pool {
            Some(pool) if n_chunks > 1 => {
                use rayon::prelude::*;
                pool.install(|| (0..n_chunks).into_par_iter().map(chunk).reduce(|| f64::INFINITY, f64::min))
            }
            _ => (0..n_chunks).map(chunk).fold(f64::INFINITY, f64::min),
        };
        if !(slack > 0.0) {
            return false;
        }
        self.n_element_tier += 1;
        if self.wait == 0 {
            self.u_base.clear();
            self.u_base.extend_from_slice(u);
            self.base_is_ref = false;
            self.slack = slack * (1.0 - Self::ROUND);
            self.slack_factor = margin_factor;
        }
        true
    }

    /// `max_c |u_c - base_c|_inf`, or infinity when a change is not finite. Fixed chunks, a
    /// max per chunk, the max of those: the same value on any number of threads.
    fn node_pass(u: &[[f64; 2]], ur: &[[f64; 2]], pool: Option<&rayon::ThreadPool>) -> f64 {
        const CHUNK: usize = 16384;
        let chunk = |k: usize| -> f64 {
            let r = k * CHUNK..((k + 1) * CHUNK).min(u.len());
            // Branch-free and in lanes of 4 (vectorised); a NaN is caught by the sum.
            let (a, b) = (&u[r.clone()], &ur[r]);
            let (mut m, mut s) = ([0.0f64; 4], [0.0f64; 4]);
            let mut it = a.chunks_exact(2).zip(b.chunks_exact(2));
            for (x, y) in &mut it {
                let d = [x[0][0] - y[0][0], x[0][1] - y[0][1], x[1][0] - y[1][0], x[1][1] - y[1][1]];
                for l in 0..4 {
                    let ad = d[l].abs();
                    m[l] = if ad > m[l] { ad } else { m[l] };
                    s[l] += d[l];
                }
            }
            if a.len() % 2 == 1 {
                let (x, y) = (a[a.len() - 1], b[b.len() - 1]);
                let d = [x[0] - y[0], x[1] - y[1]];
                for l in 0..2 {
                    m[l] = m[l].max(d[l].abs());
                    s[l] += d[l];
                }
            }
            let sum = s[0] + s[1] + s[2] + s[3];
            if sum.is_finite() {
                m[0].max(m[1]).max(m[2]).max(m[3])
            } else {
                f64::INFINITY
            }
        };
        let n_chunks = u.len().div_ceil(CHUNK);
        match pool {
            Some(pool) if n_chunks > 1 => {
                use rayon::prelude::*;
                pool.install(|| (0..n_chunks).into_par_iter().map(chunk).reduce(|| 0.0, f64::max))
            }
            _ => (0..n_chunks).map(chunk).fold(0.0, f64::max),
        }
    }

    /// The elements `r`: the smallest slack `allowed_e - half_e - ROUND big_e`, or a value
    /// <= 0 at the first element beyond its allowance (not certified). `N`: the corners of
    /// every element (0: read them from the topology). Branch-free min/max (`a < b ? a : b`,
    /// one instruction); a NaN is caught by the sum of the changes instead.
    #[inline(always)]
    fn pass<const N: usize>(&self, topo: &crate::mesh::topology::Topology, u: &[[f64; 2]], r: std::ops::Range<usize>, margin_factor: f64) -> f64 {
        let (first, cl, ur) = (&topo.elem_first_copy, &topo.copy_cluster, &self.u_ref[..]);
        #[inline(always)]
        fn mn(a: f64, b: f64) -> f64 {
            if a < b {
                a
            } else {
                b
            }
        }
        #[inline(always)]
        fn mx(a: f64, b: f64) -> f64 {
            if a > b {
                a
            } else {
                b
            }
        }
        let mut least = f64::INFINITY;
        for e in r {
            let ks = if N == 0 { first[e] as usize..first[e + 1] as usize } else { N * e..N * e + N };
            let (mut lo, mut hi, mut sum) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2], 0.0f64);
            for c in &cl[ks] {
                let (x, y) = (u[c.idx()], ur[c.idx()]);
                let du = [x[0] - y[0], x[1] - y[1]];
                sum += du[0] + du[1];
                lo = [mn(du[0], lo[0]), mn(du[1], lo[1])];
                hi = [mx(du[0], hi[0]), mx(du[1], hi[1])];
            }
            let half = 0.5 * mx(hi[0] - lo[0], hi[1] - lo[1]);
            let big = mx(mx(hi[0], hi[1]), mx(-lo[0], -lo[1]));
            // A NaN (or infinite) displacement, or a NaN allowance, is never certified
            // (`b - a > 0` is `a < b` for floats).
            let s = self.allowed[e] * margin_factor - (half + Self::ROUND * big);
            if !sum.is_finite() || !(s > 0.0) {
                return 0.0;
            }
            least = mn(s, least);
        }
        least
    }
}

#[cfg(test)]
mod tests {
    use super::Skip;

    /// The node tier's pass over several chunks (reference: the plain maximum), the same on one
    /// and two threads, and infinite when a change is not finite.
    #[test]
    fn node_pass_is_the_max_change_on_any_threads() {
        let n = 40_001; // three chunks of 16 384, odd length
        let u: Vec<[f64; 2]> = (0..n).map(|i| [((i * 7919) % 1000) as f64 * 1e-3, -(((i * 104_729) % 997) as f64) * 1e-3]).collect();
        let b: Vec<[f64; 2]> = (0..n).map(|i| [((i * 31) % 17) as f64 * 1e-3, 0.0]).collect();
        let want = u.iter().zip(&b).flat_map(|(x, y)| [(x[0] - y[0]).abs(), (x[1] - y[1]).abs()]).fold(0.0f64, f64::max);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        assert_eq!(Skip::node_pass(&u, &b, None).to_bits(), want.to_bits());
        assert_eq!(Skip::node_pass(&u, &b, Some(&pool)).to_bits(), want.to_bits());
        for bad in [f64::NAN, f64::INFINITY] {
            let mut v = u.clone();
            v[n - 1][1] = bad;
            assert_eq!(Skip::node_pass(&v, &b, None), f64::INFINITY);
            assert_eq!(Skip::node_pass(&v, &b, Some(&pool)), f64::INFINITY);
        }
    }
}
