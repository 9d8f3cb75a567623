//! The yielding lanes of `MohrCoulomb::update_lanes` written with AVX-512 intrinsics (ours,
//! session 37): the principal stresses, `trial`'s quick test, the sort and the main-face return
//! of a pack's 8 lanes in `zmm` registers, the lane decisions as `__mmask8`. The generic body
//! (`yield_lanes_body`, loops over the lanes) was compiled with its lane booleans as bytes, and
//! its selects of a stored trial against a computed return as selects of addresses with
//! scalar loads and stores, whose whole-pack reloads stalled.
//!
//! Every operation is the generic body's, on the same operands in the same order, with no
//! fused multiply-add (`_mm512_mul_pd` then `_mm512_add_pd`, as Rust compiles `a * b + c`):
//! so the same bits (`avx512_yield_is_the_generic_body_bit_for_bit` compares the two directly;
//! `update_lanes_is_update_bit_for_bit` ties both to `update`). `f64::max` / `f64::min` are
//! written as LLVM lowers them (`max_rs`, `min_rs`: a NaN operand gives the other one, a tie of
//! `+0` and `-0` the first); the values they take here only meet comparisons, absolute values
//! or non-negative zeros, so even a different tie rule would not change a stored bit. The edges, the corners and the tension planes are left to the generic code
//! (`edge_lanes`, `plastic_update`), as in the generic body.
use std::arch::x86_64::*;

use super::{lane_history, LaneTrial, MohrCoulomb, Trial, MAX_POINTS};
use flem_core::element::kernel::LANES;
use flem_core::element::law::MaterialLaw;

const _: () = assert!(LANES == 8, "the AVX-512 return holds a pack in one register");

/// Rust's `a.max(b)` as LLVM lowers it on x86: `vmaxpd(b, a)` (which answers `a` when `b` is
/// NaN, and on a tie of `+0` and `-0`), then `b` where `a` is NaN.
#[inline]
#[target_feature(enable = "avx512f,avx512vl,avx512dq")]
fn max_rs(a: __m512d, b: __m512d) -> __m512d {
    _mm512_mask_blend_pd(_mm512_cmp_pd_mask::<_CMP_UNORD_Q>(a, a), _mm512_max_pd(b, a), b)
}

/// Rust's `a.min(b)`, as [`max_rs`].
#[inline]
#[target_feature(enable = "avx512f,avx512vl,avx512dq")]
fn min_rs(a: __m512d, b: __m512d) -> __m512d {
    _mm512_mask_blend_pd(_mm512_cmp_pd_mask::<_CMP_UNORD_Q>(a, a), _mm512_min_pd(b, a), b)
}

#[inline]
#[target_feature(enable = "avx512f,avx512vl,avx512dq")]
fn abs(a: __m512d) -> __m512d {
    _mm512_abs_pd(a)
}

#[inline]
#[target_feature(enable = "avx512f")]
fn load(a: &[f64; LANES]) -> __m512d {
    // SAFETY: 8 f64 in bounds.
    unsafe { _mm512_loadu_pd(a.as_ptr()) }
}

#[inline]
#[target_feature(enable = "avx512f")]
fn store(a: &mut [f64; LANES], v: __m512d) {
    // SAFETY: 8 f64 in bounds.
    unsafe { _mm512_storeu_pd(a.as_mut_ptr(), v) }
}

#[inline]
#[target_feature(enable = "avx512f")]
fn splat(x: f64) -> __m512d {
    _mm512_set1_pd(x)
}

impl MohrCoulomb {
    /// `f_k(s)` of plane `k` (`MohrCoulomb::f`'s order: `((n0 s0 + n1 s1) + n2 s2) - r`).
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn f8(&self, k: usize, s: &[__m512d; 3]) -> __m512d {
        let n = &self.n[k];
        let a = _mm512_add_pd(_mm512_mul_pd(splat(n[0]), s[0]), _mm512_mul_pd(splat(n[1]), s[1]));
        _mm512_sub_pd(_mm512_add_pd(a, _mm512_mul_pd(splat(n[2]), s[2])), splat(self.r[k]))
    }

    /// `yield_points_body` with AVX-512.
    #[target_feature(enable = "avx512f,avx512vl,avx512dq")]
    pub(super) fn yield_points_avx512(&self, s: &mut [[[f64; LANES]; 4]], tr: &[Option<LaneTrial>; MAX_POINTS], state: &mut [f64], stride: usize, n: usize) {
        for (k, (sk, t)) in s.iter_mut().zip(tr).enumerate() {
            if let Some(t) = t {
                self.yield_lanes_avx512(sk, &t.ts, &t.half, &t.mid, &t.rr, &mut state[k * Self::STATE..], stride, n);
            }
        }
    }

    /// `yield_lanes_body` with AVX-512 (see the module docs).
    #[inline]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq")]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn yield_lanes_avx512(&self, s: &mut [[f64; LANES]; 4], ts: &[[f64; LANES]; 4], half: &[f64; LANES], mid: &[f64; LANES], rr: &[f64; LANES], state: &mut [f64], stride: usize, n: usize) {
        let (t_on, r3) = (self.used & 8 != 0, self.r[3]);
        let (midv, halfv, sxy, pzv) = (load(mid), load(half), load(&ts[2]), load(&ts[3]));
        let rad = _mm512_sqrt_pd(load(rr));
        let pa = _mm512_add_pd(midv, rad);
        let pb = _mm512_sub_pd(midv, rad);
        // `trial`'s quick test: `F_13(hi, 0, lo) <= 0` and the first tension plane.
        let (hi, lo) = (max_rs(pa, pzv), min_rs(pb, pzv));
        let f13 = self.f8(0, &[hi, _mm512_setzero_pd(), lo]);
        let mut inside: __mmask8 = _mm512_cmp_pd_mask::<_CMP_LE_OQ>(f13, _mm512_setzero_pd());
        if t_on {
            inside &= _mm512_cmp_pd_mask::<_CMP_LE_OQ>(_mm512_sub_pd(hi, splat(r3)), _mm512_setzero_pd());
        }
        // Sorted `s1 >= s2 >= s3` over (pa, pb, pz), as `sort_principal`.
        let ya: __mmask8 = _mm512_cmp_pd_mask::<_CMP_GE_OQ>(pzv, pa);
        let yb: __mmask8 = _mm512_cmp_pd_mask::<_CMP_GE_OQ>(pzv, pb);
        let m1 = _mm512_mask_blend_pd(yb, pb, pzv);
        let q = [_mm512_mask_blend_pd(ya, pa, pzv), _mm512_mask_blend_pd(ya, m1, pa), _mm512_mask_blend_pd(yb, pzv, pb)];
        let big = self.a[0][0].abs().max(self.a[3][3].abs());
        let solvable = self.a[0][0].abs() > 1e-12 * big;
        let used: [bool; 6] = std::array::from_fn(|k| self.used & (1 << k) != 0);
        let scale = splat(self.scale);
        let amax = max_rs(abs(q[0]), abs(q[2]));
        let tol = _mm512_mul_pd(splat(1e-12), _mm512_add_pd(scale, amax));
        let f0 = self.f8(0, &q);
        let mut vio: __mmask8 = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(f0, tol);
        if used[3] {
            vio |= _mm512_cmp_pd_mask::<_CMP_GT_OQ>(self.f8(3, &q), tol);
        }
        let dl = _mm512_mul_pd(f0, splat(self.inv_diag[0]));
        let bound = _mm512_mul_pd(splat(-1e-14), _mm512_add_pd(splat(1.0), abs(dl)));
        let ok: __mmask8 = _mm512_cmp_pd_mask::<_CMP_GE_OQ>(dl, bound);
        let zero = _mm512_setzero_pd();
        let mut out = q;
        let mut dep = [zero; 3];
        for d in 0..3 {
            out[d] = _mm512_sub_pd(out[d], _mm512_mul_pd(dl, splat(self.dm[0][d])));
            dep[d] = _mm512_add_pd(dep[d], _mm512_mul_pd(dl, splat(self.m[0][d])));
        }
        let check = _mm512_mul_pd(splat(1e-9), _mm512_add_pd(scale, amax));
        let mut adm: __mmask8 = 0xff;
        for (k, &u) in used.iter().enumerate() {
            if u {
                adm &= _mm512_cmp_pd_mask::<_CMP_LE_OQ>(self.f8(k, &out), check);
            }
        }
        let mut face: __mmask8 = if solvable { vio & ok & adm } else { 0 };
        // `plastic_update`'s rotation back.
        let na = _mm512_mask_blend_pd(ya, out[0], out[1]);
        let nb = _mm512_mask_blend_pd(ya | yb, out[1], out[2]);
        let t = _mm512_mask_blend_pd(yb, out[2], out[1]);
        let nz = _mm512_mask_blend_pd(ya, t, out[0]);
        // `rotation`: `1 / rad` where `rad > 0`, else (1, 0).
        let pos: __mmask8 = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(rad, zero);
        let one = splat(1.0);
        let ir = _mm512_div_pd(one, _mm512_mask_blend_pd(pos, one, rad));
        let c2 = _mm512_mask_blend_pd(pos, one, _mm512_mul_pd(halfv, ir));
        let s2 = _mm512_mask_blend_pd(pos, zero, _mm512_mul_pd(sxy, ir));
        let half_ = splat(0.5);
        let m = _mm512_mul_pd(half_, _mm512_add_pd(na, nb));
        let h = _mm512_mul_pd(half_, _mm512_sub_pd(na, nb));
        let hc = _mm512_mul_pd(h, c2);
        let mut fs = [[0.0; LANES]; 4];
        store(&mut fs[0], _mm512_add_pd(m, hc));
        store(&mut fs[1], _mm512_sub_pd(m, hc));
        store(&mut fs[2], _mm512_mul_pd(h, s2));
        store(&mut fs[3], nz);
        let mut gam = [0.0; LANES];
        store(&mut gam, _mm512_sub_pd(max_rs(max_rs(dep[0], dep[1]), dep[2]), min_rs(min_rs(dep[0], dep[1]), dep[2])));
        let live: __mmask8 = if n >= LANES { 0xff } else { ((1u32 << n) - 1) as u8 };
        // The next active sets in lanes (`edge_lanes`), on the generic body's condition.
        if !t_on && (!inside & !face & vio & live).count_ones() >= 2 {
            let bools = |m: __mmask8| -> [bool; LANES] { std::array::from_fn(|l| m >> l & 1 == 1) };
            let mut qa = [[0.0; LANES]; 3];
            for d in 0..3 {
                store(&mut qa[d], q[d]);
            }
            let mut rada = [0.0; LANES];
            store(&mut rada, rad);
            let mut faceb = bools(face);
            self.edge_lanes(&qa, &bools(vio), &bools(ya), &bools(yb), &rada, half, &ts[2], &mut faceb, &mut fs, &mut gam);
            face = faceb.iter().enumerate().fold(0, |a, (l, &b)| a | (u8::from(b) << l));
        }
        // The elastic lanes take the trial, the others the return.
        for c in 0..4 {
            store(&mut s[c], _mm512_mask_blend_pd(inside, load(&fs[c]), load(&ts[c])));
        }
        for l in 0..n.min(LANES) {
            lane_history(&mut state[l * stride..l * stride + 2], face >> l & 1 == 1, inside >> l & 1 == 1, gam[l]);
        }
        let rest = !inside & !face & live;
        if rest != 0 {
            let (mut paa, mut pba) = ([0.0; LANES], [0.0; LANES]);
            let mut rada = [0.0; LANES];
            store(&mut paa, pa);
            store(&mut pba, pb);
            store(&mut rada, rad);
            for l in 0..LANES {
                if rest >> l & 1 == 1 {
                    let h = &mut state[l * stride..l * stride + 2];
                    let t = Trial { s: [ts[0][l], ts[1][l], ts[2][l], ts[3][l]], half: half[l], rad: rada[l], pa: paa[l], pb: pba[l], pz: ts[3][l], inside: false };
                    let mut sl = t.s;
                    self.plastic_update(&mut sl, &t, h);
                    (s[0][l], s[1][l], s[2][l], s[3][l]) = (sl[0], sl[1], sl[2], sl[3]);
                }
            }
        }
    }
}
