//! Failure factors along an affine stress path, for the events solver (ours, issue 19;
//! `solver::events`, docs/events.md).
//!
//! A linear-elastic body under loads `L(t) = L0 + t (L1 - L0)` has the displacement
//! `u(t) = u0 + t (u1 - u0)`, and every nodal stress (the paper's corner mean, or the nonlocal
//! average: both linear in `u`) is affine in `t`: `s(t) = s0 + t ds`. At each cluster,
//! [`first_failure`] finds the smallest `t` in `[t0, t1]` at which the criterion fails:
//! - a criterion with a closed form (`FailureCriterion::affine_failure`; the built-ins Rankine
//!   and Mohr-Coulomb: the root of a quadratic) gives a candidate, which is checked against the
//!   criterion itself; where the check at the candidate holds by round-off, the candidate is
//!   moved up by a few ulps until it fails; a candidate that the criterion contradicts
//!   otherwise falls back to the search below;
//! - any other criterion (Drucker-Prager, Hoek-Brown, dynamic plugins): bisection on `[t0, t1]`
//!   to a relative width of 1e-14, from one batch call that finds the clusters failing at `t1`.
//!   The search assumes the safe set of the criterion is convex in stress space (true of every
//!   built-in), so that a path safe at both ends is safe in between.
use crate::error::{FlemError, Result};
use crate::plugin::traits::{principal, FailureCheck, FailureCriterion};

/// The stress path of one cluster: `s0 + t ds`, out-of-plane `szz0 + t dszz`, strength factor.
#[derive(Copy, Clone, Debug, Default)]
pub struct Path {
    pub s0: [f64; 3],
    pub ds: [f64; 3],
    pub szz0: f64,
    pub dszz: f64,
    pub scale: f64,
}

impl Path {
    pub fn at(&self, t: f64) -> ([f64; 3], f64) {
        (std::array::from_fn(|k| self.s0[k] + t * self.ds[k]), self.szz0 + t * self.dszz)
    }
}

fn fails(criterion: &dyn FailureCriterion, p: &Path, t: f64) -> Result<bool> {
    let (s, szz) = p.at(t);
    let mut out = [FailureCheck::default()];
    criterion.try_check_batch(&[principal(s, szz)], &[p.scale], &mut out).map_err(FlemError::Other)?;
    Ok(out[0].failed())
}

/// Bisection for the first failure on `[t0, t1]` of a path that holds at `t0` and fails at `t1`.
fn bisect(criterion: &dyn FailureCriterion, p: &Path, mut lo: f64, mut hi: f64) -> Result<f64> {
    while hi - lo > 1e-14 * hi.abs().max(lo.abs()).max(f64::MIN_POSITIVE) {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if fails(criterion, p, mid)? {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Ok(hi)
}

/// The smallest `t` in `[t0, t1]` at which `criterion` fails on the path (infinite if none).
/// Counts in `stats` whether the closed form answered.
pub fn first_failure(criterion: &dyn FailureCriterion, p: &Path, t0: f64, t1: f64, stats: &mut FactorStats) -> Result<f64> {
    if let Some(t) = criterion.affine_failure(p.s0, p.ds, p.szz0, p.dszz, p.scale, t0, t1) {
        if t.is_infinite() || t > t1 {
            if !fails(criterion, p, t1)? {
                stats.closed += 1;
                return Ok(f64::INFINITY);
            }
        } else {
            // The candidate, moved up by round-off until the criterion agrees.
            let mut c = t.max(t0);
            for _ in 0..8 {
                if fails(criterion, p, c)? {
                    // It must not fail clearly before the candidate either.
                    let before = c - 1e-9 * c.abs().max(1e-300);
                    if c == t0 || before < t0 || !fails(criterion, p, before)? {
                        stats.closed += 1;
                        return Ok(c);
                    }
                    break;
                }
                let next = c + 4.0 * f64::EPSILON * c.abs().max(f64::MIN_POSITIVE);
                if next > t1 {
                    break;
                }
                c = next;
            }
        }
        stats.fallback += 1;
    }
    stats.searched += 1;
    if fails(criterion, p, t0)? {
        return Ok(t0);
    }
    if !fails(criterion, p, t1)? {
        return Ok(f64::INFINITY);
    }
    bisect(criterion, p, t0, t1)
}

/// How the factors of a run were found (closed form, closed form contradicted, bisection).
#[derive(Copy, Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct FactorStats {
    pub closed: u64,
    pub fallback: u64,
    pub searched: u64,
}

/// The smallest first-failure factor on `[t0, t1]` over all paths, and its cluster (ties: the
/// lower cluster). Paths whose criterion holds at `t1` are found with one batch call and skipped
/// (convex safe set), so a criterion without closed form pays its bisection only where it fails.
pub fn smallest_failure(criterion: &dyn FailureCriterion, paths: &[Path], t0: f64, t1: f64, stats: &mut FactorStats) -> Result<(f64, Option<usize>)> {
    let has_closed = paths.first().is_some_and(|p| criterion.affine_failure(p.s0, p.ds, p.szz0, p.dszz, p.scale, t0, t1).is_some());
    let mut at_end = vec![FailureCheck::default(); paths.len()];
    if !has_closed {
        let pr: Vec<_> = paths
            .iter()
            .map(|p| {
                let (s, szz) = p.at(t1);
                principal(s, szz)
            })
            .collect();
        let sc: Vec<f64> = paths.iter().map(|p| p.scale).collect();
        criterion.try_check_batch(&pr, &sc, &mut at_end).map_err(FlemError::Other)?;
    }
    let mut best = (f64::INFINITY, None);
    for (c, p) in paths.iter().enumerate() {
        if !has_closed && !at_end[c].failed() {
            continue;
        }
        let t = first_failure(criterion, p, t0, t1, stats)?;
        if t < best.0 {
            best = (t, Some(c));
        }
    }
    Ok(best)
}
