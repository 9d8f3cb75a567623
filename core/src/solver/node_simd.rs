//! The node update (`NodeCtx::update`) vectorised: two nodes per AVX2 register.
//!
//! The scalar update sums its ledger terms in four fixed lanes, node parity x dof, so that the
//! sums do not depend on the number of threads. Two nodes `[x0, y0, x1, y1]` are exactly one
//! `__m256d` of those four lanes: here each lane does the same IEEE operations, in the same
//! order, as the scalar code does for its dof (Rust never contracts a multiply and an add into
//! an FMA, and every operation used is correctly rounded), so the displacements, velocities and
//! sums are the same bit for bit (unit test `vector_update_equals_scalar`).
//!
//! Fixed dofs without branches: a pair whose four dofs are free (nearly all of them) runs
//! without masks; a pair with a fixed dof computes both the free and the prescribed update and
//! keeps one per lane with a mask (the `fix` bits index a table of masks). A term the scalar
//! code does not add for a dof is added here as `+0.0`, which leaves a sum unchanged: the lane
//! sums start at `+0.0` and a sum that starts at `+0.0` is never `-0.0` under rounding to
//! nearest, and `x + 0.0 == x` for every other `x`, infinities and NaN included.
//!
//! Compiled for AVX2, which also runs where [`Simd::best`] is AVX-512; chosen once per process
//! by [`Simd::best`] (`FLEM_SIMD=plain` keeps the scalar update). The odd last node of a chunk
//! runs the scalar code (it is in lanes 0 and 1 there too).
use super::{NodeCtx, UpdateFn, NSUM};
use crate::element::block::Simd;

/// The vectorised node update of `simd` for the variant `<C, L, FULL, STATS>` of
/// [`NodeCtx::update`]; `None` when `simd` is `Plain`, this CPU lacks it, or the model is not
/// 2D (`D != 2`: the scalar update, issue 38).
pub(super) fn vector_update<const D: usize, const C: bool, const L: u8, const FULL: bool, const STATS: bool>(simd: Simd) -> Option<UpdateFn<D>> {
    if D != 2 {
        return None;
    }
    match simd {
        // A CPU with AVX-512 F runs AVX2: the same code (wider registers would not hold more
        // than the two nodes of the four lanes).
        #[cfg(target_arch = "x86_64")]
        Simd::Avx2 | Simd::Avx512 if Simd::Avx2.detected() => {
            // SAFETY: the CPU has AVX2 (`detected`, on the line above); `D == 2` (checked at the
            // top), so `NodeCtx<D>` is `NodeCtx<2>` and `[f64; D]` is `[f64; 2]`: the casts are
            // between identical types.
            Some(|x: &NodeCtx<D>, k, u: &mut [[f64; D]], v: &mut [[f64; D]]| unsafe {
                let x = &*(x as *const NodeCtx<D> as *const NodeCtx<2>);
                let (n, m) = (u.len(), v.len());
                let u = std::slice::from_raw_parts_mut(u.as_mut_ptr() as *mut [f64; 2], n);
                let v = std::slice::from_raw_parts_mut(v.as_mut_ptr() as *mut [f64; 2], m);
                x86::update_avx2::<C, L, FULL, STATS>(x, k, u, v)
            })
        }
        _ => None,
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::{NodeCtx, NSUM};
    use std::arch::x86_64::*;

    /// Lane masks of the free dofs of a pair of nodes, indexed by `(fix0 & 3) | (fix1 & 3) << 2`
    /// (bit 0 of `fix`: x fixed, bit 1: y fixed); lanes `[x0, y0, x1, y1]`.
    static FREE: [[u64; 4]; 16] = {
        let mut t = [[0u64; 4]; 16];
        let mut k = 0;
        while k < 16 {
            let mut l = 0;
            while l < 4 {
                t[k][l] = if k & (1 << l) == 0 { u64::MAX } else { 0 };
                l += 1;
            }
            k += 1;
        }
        t
    };

    /// [`body`] compiled for AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) fn update_avx2<const C: bool, const L: u8, const FULL: bool, const STATS: bool>(x: &NodeCtx, c0: usize, u: &mut [[f64; 2]], v: &mut [[f64; 2]]) -> [f64; NSUM] {
        body::<C, L, FULL, STATS>(x, c0, u, v)
    }

    /// Constants of a step, broadcast.
    #[derive(Clone, Copy)]
    struct K {
        dt: __m256d,
        inv_dt: __m256d,
        c1: __m256d,
        c2: __m256d,
        beta: __m256d,
        eta_hdt: __m256d,
        a_hdt: __m256d,
        one: __m256d,
        zero: __m256d,
        ones: __m256d,
        /// Lanes of the x dofs (where the per-node ratio terms are summed).
        xlanes: __m256d,
        /// All bits but the sign.
        abs: __m256d,
    }

    /// The pair loop of [`NodeCtx::update`], then its odd last node and its reduction.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn body<const C: bool, const L: u8, const FULL: bool, const STATS: bool>(x: &NodeCtx, c0: usize, u: &mut [[f64; 2]], v: &mut [[f64; 2]]) -> [f64; NSUM] {
        let n = u.len();
        // What `pair` reads without bounds checks.
        assert!(v.len() == n && x.mass.len() >= c0 + n && x.fix.len() >= c0 + n && x.f_int.len() >= c0 + n && x.f_ext.len() >= c0 + n && x.v_pres.len() >= c0 + n);
        assert!(!C || x.f_con.len() >= c0 + n);
        let k = K {
            dt: _mm256_set1_pd(x.dt),
            inv_dt: _mm256_set1_pd(x.inv_dt),
            c1: _mm256_set1_pd(x.c1),
            c2: _mm256_set1_pd(x.c2),
            beta: _mm256_set1_pd(x.beta),
            eta_hdt: _mm256_set1_pd(x.eta_hdt),
            a_hdt: _mm256_set1_pd(x.a_hdt),
            one: _mm256_set1_pd(1.0),
            zero: _mm256_setzero_pd(),
            ones: _mm256_castsi256_pd(_mm256_set1_epi64x(-1)),
            xlanes: _mm256_castsi256_pd(_mm256_setr_epi64x(-1, 0, -1, 0)),
            abs: _mm256_castsi256_pd(_mm256_set1_epi64x(i64::MAX)),
        };
        let mut acc = [_mm256_setzero_pd(); NSUM];
        let mut i = 0;
        while i + 1 < n {
            let c = c0 + i;
            let f = (x.fix[c] & 3) as usize | ((x.fix[c + 1] & 3) as usize) << 2;
            // SAFETY (both): nodes c, c + 1 exist in every array (`i + 1 < n`, the asserts).
            if f == 0 {
                unsafe { pair::<C, L, FULL, STATS, false>(x, &k, c, i, 0, u, v, &mut acc) };
            } else {
                unsafe { pair::<C, L, FULL, STATS, true>(x, &k, c, i, f, u, v, &mut acc) };
            }
            i += 2;
        }
        let mut lanes = [[0.0f64; NSUM]; 4];
        for (s, a) in acc.iter().enumerate() {
            let mut t = [0.0f64; 4];
            // SAFETY: four f64 into an array of four.
            unsafe { _mm256_storeu_pd(t.as_mut_ptr(), *a) };
            for (l, lane) in lanes.iter_mut().enumerate() {
                lane[s] = t[l];
            }
        }
        if i < n {
            let [a0, a1, ..] = &mut lanes;
            x.node::<C, L, FULL, STATS>(c0 + i, &mut u[i], &mut v[i], a0, a1);
        }
        x.reduce(&lanes)
    }

    /// The two dofs of node `c` and of node `c + 1`, `[x0, y0, x1, y1]`, of an array of nodes.
    ///
    /// # Safety
    /// `c + 1 < a.len()`.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn ld(a: &[[f64; 2]], c: usize) -> __m256d {
        // SAFETY: the caller's.
        unsafe { _mm256_loadu_pd(a.as_ptr().add(c) as *const f64) }
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    fn add(a: __m256d, b: __m256d) -> __m256d {
        _mm256_add_pd(a, b)
    }
    #[target_feature(enable = "avx2")]
    #[inline]
    fn sub(a: __m256d, b: __m256d) -> __m256d {
        _mm256_sub_pd(a, b)
    }
    #[target_feature(enable = "avx2")]
    #[inline]
    fn mul(a: __m256d, b: __m256d) -> __m256d {
        _mm256_mul_pd(a, b)
    }
    #[target_feature(enable = "avx2")]
    #[inline]
    fn and(a: __m256d, b: __m256d) -> __m256d {
        _mm256_and_pd(a, b)
    }

    /// Two nodes `c`, `c + 1` (their four dofs in one register; `i` is `c` in `u` and `v`);
    /// `ANYFIX`: some dof is fixed (`fix` the index of its masks in [`FREE`]). The lane
    /// operations are those of `NodeCtx::dof` and `node`, in their order.
    ///
    /// # Safety
    /// Nodes `c` and `c + 1` exist in every array of `x` the variant reads, `i + 1 < u.len()`,
    /// `i + 1 < v.len()`.
    #[target_feature(enable = "avx2")]
    #[inline]
    #[allow(clippy::too_many_arguments)]
    unsafe fn pair<const C: bool, const L: u8, const FULL: bool, const STATS: bool, const ANYFIX: bool>(
        x: &NodeCtx,
        k: &K,
        c: usize,
        i: usize,
        fix: usize,
        u: &mut [[f64; 2]],
        v: &mut [[f64; 2]],
        s: &mut [__m256d; NSUM],
    ) {
        // SAFETY: the caller's (nodes c, c + 1 and i, i + 1 exist); `fix < 16`.
        let (m2, fe, fi, fc, vpres, free) = unsafe {
            (
                _mm_loadu_pd(x.mass.as_ptr().add(c)),
                ld(x.f_ext, c),
                ld(x.f_int, c),
                if C { ld(x.f_con, c) } else { k.zero },
                if ANYFIX { ld(x.v_pres, c) } else { k.zero },
                if ANYFIX { _mm256_castsi256_pd(_mm256_loadu_si256(FREE.as_ptr().add(fix) as *const __m256i)) } else { k.ones },
            )
        };
        let pv = unsafe { v.as_mut_ptr().add(i) as *mut f64 };
        let pu = unsafe { u.as_mut_ptr().add(i) as *mut f64 };
        let (vm, ud) = unsafe { (_mm256_loadu_pd(pv), _mm256_loadu_pd(pu)) };
        // [m0, m0, m1, m1]
        let m = _mm256_permute4x64_pd::<0b01_01_00_00>(_mm256_castpd128_pd256(m2));
        let dt_m = _mm256_div_pd(k.dt, m);
        let (c1, c2) = if L == 3 {
            let h = add(k.a_hdt, _mm256_div_pd(k.eta_hdt, m));
            (sub(k.one, h), _mm256_div_pd(k.one, add(k.one, h)))
        } else {
            (k.c1, k.c2)
        };
        if FULL {
            s[8] = add(s[8], mul(ud, fi));
        }
        let f = if C { sub(add(fe, fc), fi) } else { sub(fe, fi) };
        let fa = if C { add(fe, fc) } else { fe };
        let fl = if L == 2 {
            // sign(vm) as the scalar code's `(vm > 0) - (vm < 0)`: 1, -1 or +0.
            let gt = and(_mm256_cmp_pd::<_CMP_GT_OQ>(vm, k.zero), k.one);
            let lt = and(_mm256_cmp_pd::<_CMP_LT_OQ>(vm, k.zero), k.one);
            sub(f, mul(mul(k.beta, and(f, k.abs)), sub(gt, lt)))
        } else {
            f
        };
        let vfree = if L == 0 { add(vm, mul(dt_m, fl)) } else { mul(add(mul(c1, vm), mul(dt_m, fl)), c2) };
        let fd = if L == 0 { k.zero } else { sub(f, mul(mul(m, sub(vfree, vm)), k.inv_dt)) };
        // Per lane: the free dof's terms, or the prescribed dof's.
        let (vp, g, gap) = if ANYFIX {
            let react = sub(fi, fc);
            (_mm256_blendv_pd(vpres, vfree, free), _mm256_blendv_pd(react, fe, free), _mm256_blendv_pd(react, fa, free))
        } else {
            (vfree, fe, fa)
        };
        let va = add(vm, vp);
        // Undamped, the scalar code skips `fe va` on a free dof without load (a zero, unless
        // `va` is not finite): the same here, by mask.
        let w = mul(g, va);
        s[0] = add(s[0], if L == 0 { and(w, _mm256_or_pd(_mm256_cmp_pd::<_CMP_NEQ_UQ>(fe, k.zero), _mm256_andnot_pd(free, k.ones))) } else { w });
        if L != 0 {
            s[1] = add(s[1], and(mul(fd, va), free));
        }
        if C {
            s[9] = add(s[9], mul(fc, va));
        }
        if FULL {
            s[2] = add(s[2], mul(g, vp));
            if L != 0 {
                s[3] = add(s[3], and(mul(fd, vp), free));
            }
            if C {
                s[10] = add(s[10], mul(fc, vp));
            }
            s[4] = add(s[4], mul(mul(m, vm), vp));
        }
        if FULL || STATS {
            s[6] = add(s[6], and(mul(ud, fi), free));
            s[7] = add(s[7], and(mul(mul(m, ud), ud), free));
            s[5] = add(s[5], mul(mul(m, vp), vp));
        }
        // SAFETY: as the loads above.
        unsafe {
            _mm256_storeu_pd(pv, vp);
            _mm256_storeu_pd(pu, add(ud, mul(k.dt, vp)));
        }
        if FULL {
            // The unbalanced-force ratio's terms per node, in its x lane: `ux + uy`, `ax + ay`.
            let un = and(mul(f, f), free);
            let ap = mul(gap, gap);
            let un = and(add(un, _mm256_permute_pd::<0b0101>(un)), k.xlanes);
            let ap = add(ap, _mm256_permute_pd::<0b0101>(ap));
            // `max(un, acc)` returns `acc` when `un` is NaN, as `f64::max` does.
            s[11] = _mm256_max_pd(un, s[11]);
            let pos = and(_mm256_cmp_pd::<_CMP_GT_OQ>(ap, k.zero), k.xlanes);
            s[12] = add(s[12], and(_mm256_sqrt_pd(ap), pos));
            s[13] = add(s[13], and(k.one, pos));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{pick_variant, NodeCtx, NSUM};
    use crate::element::block::Simd;

    /// A fixed, reproducible stream: the Weibull field's hash of a counter.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 += 1;
            crate::cracking::weibull::splitmix64(self.0)
        }
        /// A value in (-1, 1), or (one in eight) an exact zero.
        fn val(&mut self) -> f64 {
            let r = self.next();
            if r.is_multiple_of(8) {
                0.0
            } else {
                (r >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
            }
        }
    }

    /// The vectorised node update equals the scalar one bit for bit (displacements, velocities
    /// and all fourteen sums) over random states with fixed dofs, loads on some dofs only, for
    /// contact on and off, every damping mode, full, lean and lean-with-stats steps, chunks of
    /// odd and even length. Reference: the scalar `NodeCtx::update` (the code the vector path
    /// replaces); exact.
    #[test]
    fn vector_update_equals_scalar() {
        let simds: Vec<Simd> = [Simd::Avx2, Simd::Avx512].into_iter().filter(|s| s.detected()).collect();
        if simds.is_empty() {
            eprintln!("no AVX2 on this CPU: only the scalar update exists");
            return;
        }
        let mut r = Rng(0x9e37_79b9_7f4a_7c15);
        for n in [1usize, 2, 7, 64, 301] {
            let c0 = 6; // a chunk inside the arrays
            let len = c0 + n;
            let pair = |r: &mut Rng| -> Vec<[f64; 2]> { (0..len).map(|_| [r.val(), r.val()]).collect() };
            let (f_int, f_con, v_pres, u0, v0) = (pair(&mut r), pair(&mut r), pair(&mut r), pair(&mut r), pair(&mut r));
            // Loads on about one dof in four, the rest exact zeros (as on a real mesh).
            let f_ext: Vec<[f64; 2]> = (0..len).map(|_| [0, 1].map(|_| if r.next().is_multiple_of(4) { r.val() } else { 0.0 })).collect();
            let mass: Vec<f64> = (0..len).map(|_| 0.5 + r.val().abs()).collect();
            // Fixed dofs on about one node in three.
            let fix: Vec<u8> = (0..len).map(|_| if r.next().is_multiple_of(3) { (r.next() % 4) as u8 } else { 0 }).collect();
            let dt = 0.1;
            for (a, beta, eta) in [(0.0, 0.0, 0.0), (3.0, 0.0, 0.0), (0.0, 0.3, 0.0), (2.0, 0.0, 1.5)] {
                let (c1, c2) = (1.0 - 0.5 * a * dt, 1.0 / (1.0 + 0.5 * a * dt));
                let ctx =
                    NodeCtx { mass: &mass, fix: &fix, f_int: &f_int, f_ext: &f_ext, f_con: &f_con, v_pres: &v_pres, dt, inv_dt: 1.0 / dt, c1, c2, beta, eta_hdt: 0.5 * eta * dt, a_hdt: 0.5 * a * dt };
                let damp = if eta != 0.0 {
                    3
                } else if beta != 0.0 {
                    2
                } else if a != 0.0 {
                    1
                } else {
                    0
                };
                for contact in [false, true] {
                    for (full, stats) in [(true, true), (false, true), (false, false)] {
                        let run = |simd: Simd| -> (Vec<[f64; 2]>, Vec<[f64; 2]>, [f64; NSUM]) {
                            let (mut u, mut v) = (u0[c0..].to_vec(), v0[c0..].to_vec());
                            let f = pick_variant(contact, damp, full, stats, simd);
                            let s = f(&ctx, c0, &mut u, &mut v);
                            (u, v, s)
                        };
                        let bits = |(u, v, s): (Vec<[f64; 2]>, Vec<[f64; 2]>, [f64; NSUM])| -> Vec<u64> { u.iter().chain(&v).flatten().chain(&s).map(|x| x.to_bits()).collect() };
                        let want = bits(run(Simd::Plain));
                        for &simd in &simds {
                            assert_eq!(bits(run(simd)), want, "n {n}, damp {damp}, contact {contact}, full {full}, stats {stats}, {simd:?}");
                        }
                    }
                }
            }
        }
    }
}
