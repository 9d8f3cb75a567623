//! Weibull strength scatter: a deterministic per-point factor for the `scale` argument of
//! [`FailureCriterion::check`](flem_core::plugin::traits::FailureCriterion::check) (METHOD section 4;
//! not in the paper, which uses uniform strengths; Akantu's cohesive models do the same).
//!
//! The factor `X` is Weibull distributed with shape (modulus) `m > 0` and scale
//! `lambda = 1 / Gamma(1 + 1/m)`, so that `E[X] = lambda Gamma(1 + 1/m) = 1`:
//!
//! `P(X <= x) = 1 - exp(-(x / lambda)^m)`, sampled as `X = lambda (-ln(1 - U))^(1/m)`.
//!
//! The uniform `U` in (0, 1) comes from a stateless hash, `splitmix64(seed ^ splitmix64(point))`,
//! so a point's factor depends only on `(seed, point)`: not on the order of calls nor on
//! threads. Large `m` gives little scatter (coefficient of variation about 1.28 / m).
//! Dimensionless. A modulus that is not finite and > 0 gives 1 (no scatter), never a panic.
//!
//! A scene selects it in its cracking table (every point's strengths are multiplied by its factor):
//! `[cracking.weibull]` with `modulus = 10.0` and `seed = 1`.

/// One step of SplitMix64 (Steele, Lea, Flood 2014): a bijective 64-bit mixer.
pub fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A uniform number in the open interval (0, 1) from `(seed, point)` (53 random bits).
pub fn uniform(seed: u64, point_index: u64) -> f64 {
    let h = splitmix64(seed ^ splitmix64(point_index));
    ((h >> 11) as f64 + 0.5) * (1.0 / (1u64 << 53) as f64)
}

/// Gamma(x) for x > 0 (Lanczos, g = 7, n = 9; relative error about 1e-15 on [1, 2]).
pub fn gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        return std::f64::consts::PI / ((std::f64::consts::PI * x).sin() * gamma(1.0 - x));
    }
    let x = x - 1.0;
    let mut a = C[0];
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    let t = x + G + 0.5;
    (2.0 * std::f64::consts::PI).sqrt() * t.powf(x + 0.5) * (-t).exp() * a
}

/// The Weibull strength factor of one point: mean 1, shape `modulus` (see the module docs).
pub fn weibull_scale(modulus: f64, seed: u64, point_index: u64) -> f64 {
    if !(modulus.is_finite() && modulus > 0.0) {
        return 1.0;
    }
    let lambda = 1.0 / gamma(1.0 + 1.0 / modulus);
    let u = uniform(seed, point_index);
    let x = lambda * (-(-u).ln_1p()).powf(1.0 / modulus);
    if x.is_finite() {
        x
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Gamma at known values (1, 2, 0.5 = sqrt(pi), 1.5, 4.5); tolerance 1e-13 relative.
    #[test]
    fn gamma_known_values() {
        let pi = std::f64::consts::PI;
        for (x, g) in [(1.0, 1.0), (2.0, 1.0), (0.5, pi.sqrt()), (1.5, 0.5 * pi.sqrt()), (4.5, 11.631_728_396_567_45)] {
            assert!((gamma(x) - g).abs() < 1e-13 * g, "Gamma({x}) = {}", gamma(x));
        }
    }

    /// The sample mean over 1e5 points is 1 within 1 % for several moduli; the same
    /// (seed, point) gives the same value; another seed gives another sequence.
    /// Reference: E[X] = 1 by construction.
    #[test]
    fn mean_one_and_deterministic() {
        for m in [2.0, 5.0, 12.0] {
            let n = 100_000u64;
            let mean = (0..n).map(|i| weibull_scale(m, 42, i)).sum::<f64>() / n as f64;
            assert!((mean - 1.0).abs() < 0.01, "m = {m}: mean {mean}");
        }
        // order independence: backwards gives bit-identical values
        let fwd: Vec<f64> = (0..1000).map(|i| weibull_scale(8.0, 7, i)).collect();
        let bwd: Vec<f64> = (0..1000).rev().map(|i| weibull_scale(8.0, 7, i)).collect();
        assert!(fwd.iter().zip(bwd.iter().rev()).all(|(a, b)| a.to_bits() == b.to_bits()));
        assert_ne!(weibull_scale(8.0, 7, 3), weibull_scale(8.0, 8, 3));
        assert!(fwd.iter().all(|x| x.is_finite() && *x > 0.0));
    }

    /// Bad moduli give 1, extreme seeds never panic.
    #[test]
    fn bad_modulus_gives_one() {
        for m in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(weibull_scale(m, 1, 1), 1.0);
        }
        assert!(weibull_scale(0.1, u64::MAX, u64::MAX).is_finite());
        let u = uniform(0, 0);
        assert!(u > 0.0 && u < 1.0);
    }
}
