//! The exact crack-initiation load of a linear-elastic body (issue 18, `flem converge`).
//!
//! Before the first split the body is linear: the displacement at load factor `lambda` is
//! `lambda u1`, with `u1` the elastic solution at the first stage's load levels (the check
//! solver, `flem_plugins::check::static_solve`), and so is every nodal stress, local (the
//! paper's corner mean) or nonlocal. At every cluster the smallest factor at which the criterion
//! fails is found by bracketing (doubling or halving from 1) and bisection to a relative width
//! of 1e-13, for any criterion (built-in or plugin): no closed form is assumed. The initiation
//! factor is the smallest over the clusters; its cluster, position and sigma1 direction (of the
//! stress at that factor) are reported.
use crate::cracking::nonlocal::Nonlocal;
use crate::element::model::Model;
use crate::error::{FlemError, Result};
use crate::ids::ClusterId;
use crate::plugin::traits::{principal, FailureCheck, FailureCriterion};

/// The first failure of a proportionally loaded linear body.
#[derive(Clone, Debug)]
pub struct Initiation {
    /// Load factor on the levels of the solve (infinite when no node ever fails).
    pub factor: f64,
    pub cluster: ClusterId,
    /// Reference position of its point.
    pub x: [f64; 2],
    /// sigma1 direction at failure, degrees in [0, 180).
    pub sigma1_deg: f64,
    /// Nodal stress at factor 1 (tension positive).
    pub stress: [f64; 3],
}

/// Smallest `lambda > 0` at which `criterion` fails for the stress `lambda s` (out-of-plane
/// stress `lambda szz`), strength factor `scale`. Infinite if it holds up to 1e30.
pub fn failure_factor(criterion: &dyn FailureCriterion, s: [f64; 3], szz: f64, scale: f64) -> Result<f64> {
    let fails = |l: f64| -> Result<bool> {
        let p = principal([l * s[0], l * s[1], l * s[2]], l * szz);
        let mut out = [FailureCheck::default()];
        criterion.try_check_batch(&[p], &[scale], &mut out).map_err(FlemError::Other)?;
        Ok(out[0].failed())
    };
    let (mut lo, mut hi);
    if fails(1.0)? {
        hi = 1.0;
        lo = 0.5;
        while fails(lo)? {
            hi = lo;
            lo *= 0.5;
            if lo < 1e-30 {
                return Ok(0.0);
            }
        }
    } else {
        lo = 1.0;
        hi = 2.0;
        while !fails(hi)? {
            lo = hi;
            hi *= 2.0;
            if hi > 1e30 {
                return Ok(f64::INFINITY);
            }
        }
    }
    while hi - lo > 1e-13 * hi {
        let mid = 0.5 * (lo + hi);
        if fails(mid)? {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Ok(hi)
}

/// The initiation factor of `model` loaded to `u1` (factor 1): the nodal stress is the paper's
/// corner mean, or the nonlocal average when `nonlocal` is given. Ties go to the lower cluster id.
pub fn initiation(criterion: &dyn FailureCriterion, scale: &[f64], model: &Model, u1: &[[f64; 2]], nonlocal: Option<&mut Nonlocal>) -> Result<Initiation> {
    let mut nodal = Vec::new();
    match nonlocal {
        Some(nl) => nl.nodal_stress(model, u1, &mut nodal),
        None => model.nodal_stress(u1, &mut Vec::new(), &mut nodal),
    }
    let topo = &model.topo;
    let mut best: Option<Initiation> = None;
    for (c, &s) in nodal.iter().enumerate() {
        let p = topo.cluster_point[c];
        let mat = model.material_of(topo.copy_elem[topo.point_copies.row(p.idx())[0].idx()]);
        let f = failure_factor(criterion, s, mat.szz(s), scale.get(p.idx()).copied().unwrap_or(1.0))?;
        if best.as_ref().is_none_or(|b| f < b.factor) {
            let pr = principal([f * s[0], f * s[1], f * s[2]], f * mat.szz(s));
            let theta = if f.is_finite() { pr.theta1.to_degrees().rem_euclid(180.0) } else { f64::NAN };
            best = Some(Initiation { factor: f, cluster: ClusterId(c as u32), x: model.mesh.points[p.idx()], sigma1_deg: theta, stress: s });
        }
    }
    best.ok_or_else(|| FlemError::Other("the model has no node".into()))
}
