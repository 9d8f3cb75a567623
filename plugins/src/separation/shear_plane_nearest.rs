//! `shear_plane_nearest`: cut along the true failure planes for shear failure (METHOD
//! section 5, an alternative to the paper's rule; paper section 2.2, fig. 4(b): the planes
//! S1, S2 at `theta1 +- (pi/4 - phi/2)`, which the paper replaces by the sigma1 direction).
//!
//! - Shear failure with `n_planes >= 1`: among all (plane, link) pairs pick the one with the
//!   smallest line angle (mod pi) between the plane `FailureCheck.planes[j]` and the link
//!   (ties within 1e-9 rad: counter-clockwise from the plane, offset in (0, pi/2], then the
//!   smaller edge id, then the lower plane index).
//!   - closed fan: cut that link and, among the others, the link whose ray is nearest the
//!     opposite ray of the plane (the plane oriented towards the first link, plus pi);
//!   - open fan: cut that link; at a point that has already split only if its line angle to
//!     the plane is < pi/4; at a point that never split whatever the angle, unless
//!     `cap_unsplit_boundary = true` (ours; as in `sigma1_nearest`, METHOD 5).
//! - Tension failure (or a shear check without planes): exactly as `sigma1_nearest`.
//!
//! Angles in radians. Parameter: `cap_unsplit_boundary` (bool, default `false`).
//!
//! ```toml
//! [cracking.separation]
//! type = "shear_plane_nearest"
//! ```
//!
//! ```toml
//! [cracking.separation]
//! type = "shear_plane_nearest"
//! cap_unsplit_boundary = true   # ours: the pi/4 cap also at never-split boundary points
//! ```
use std::f64::consts::{FRAC_PI_2, PI};

use serde::{Deserialize, Serialize};

use flem_core::plugin::traits::{ray_angle, FailureCheck, FailureMode, FanView, Proposal, SeparationRule};

use super::sigma1_nearest::propose_along;
use super::{cap_for, closed_from_first, line_cand, open_from, pick, Cand, TIE};

/// Cut along the nearest true failure plane (see the module docs).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShearPlaneNearest {
    /// Ours (not the paper's): the pi/4 open-fan cap also at points that never split.
    #[serde(default)]
    pub cap_unsplit_boundary: bool,
}

/// The best (plane, link) pair; `slot` is the plane index.
fn best_pair(fan: &FanView, planes: &[f64]) -> Option<Cand> {
    let mut c = Vec::with_capacity(planes.len() * fan.links.len());
    for (j, &p) in planes.iter().enumerate() {
        c.extend((0..fan.links.len()).map(|i| line_cand(fan.links, i, p, j)));
    }
    pick(&c, TIE)
}

#[typetag::serde(name = "shear_plane_nearest")]
impl SeparationRule for ShearPlaneNearest {
    fn propose(&self, fan: &FanView, failure: &FailureCheck) -> Option<Proposal> {
        let n = (failure.n_planes as usize).min(2);
        if failure.mode? != FailureMode::Shear || n == 0 {
            return propose_along(fan, fan.principal.theta1, self.cap_unsplit_boundary);
        }
        let planes = &failure.planes[..n];
        let best = best_pair(fan, planes)?;
        if !fan.closed {
            return open_from(best, cap_for(fan, self.cap_unsplit_boundary));
        }
        let p = planes[best.slot];
        let towards = if ray_angle(fan.links[best.link].angle, p) <= FRAC_PI_2 { p } else { p + PI };
        closed_from_first(fan.links, best.link, towards)
    }
}

#[cfg(test)]
mod tests {
    use super::super::fixture::{failed, fan_dir, ids, links};
    use super::*;
    use crate::criteria::mohr_coulomb::MohrCoulomb;
    use flem_core::plugin::traits::{principal, FailureCriterion};

    fn run(f: &FanView, c: &FailureCheck) -> Option<Vec<u32>> {
        ids(ShearPlaneNearest::default().propose(f, c))
    }

    /// Uniaxial compression along x with phi = 30 deg: planes at 30 and 150 deg. On a T3 fan
    /// with links at 0, 45, 90, 180, 225, 270 deg (sigma1 along x), the closest pair is
    /// (30, 45) (15 deg), so the cut is 45 and 225; sigma1_nearest would cut 0 and 180. Exact.
    #[test]
    fn closed_fan_uses_true_planes() {
        let mc = MohrCoulomb { cohesion: 0.1, friction_angle_deg: 30.0, tensile_strength: 1.0, tension: true, shear: true };
        let check = mc.check(&principal([-1.0, 0.0, 0.0], 0.0), 1.0);
        assert_eq!(check.mode, Some(FailureMode::Shear));
        let l = links(&[0.0, 45.0, 90.0, 180.0, 225.0, 270.0]);
        let f = fan_dir(&l, true, 0.0);
        assert_eq!(run(&f, &check), Some(vec![1, 4]));
        // structured fan: 0 and 180 are both 30 deg from either plane; the pairs that lie
        // counter-clockwise (offset in (0, pi/2]) are (0, 150) and (180, 150): the smaller edge
        // id wins (edge 0), then the ray nearest the opposite of 150 oriented towards it: 180.
        let s = links(&[0.0, 90.0, 180.0, 270.0]);
        assert_eq!(run(&fan_dir(&s, true, 0.0), &check), Some(vec![0, 2]));
    }

    /// Open fan: cut below pi/4 to the nearest plane only; tension behaves as sigma1_nearest.
    #[test]
    fn open_fan_and_tension() {
        let shear = failed(FailureMode::Shear, &[30.0, 150.0]);
        let l = links(&[70.0, 250.0 + 20.0]);
        // 70 is 40 deg from 30 -> cut
        assert_eq!(run(&fan_dir(&l, false, 0.0), &shear), Some(vec![0]));
        let far = links(&[90.0, 270.0]);
        // 90 is 60 deg from 30 and 60 deg from 150 -> no cut
        assert_eq!(run(&fan_dir(&far, false, 0.0), &shear), None);
        let tension = failed(FailureMode::Tension, &[0.0]);
        assert_eq!(run(&fan_dir(&far, false, 0.0), &tension), None);
        assert_eq!(run(&fan_dir(&far, false, 80.0), &tension), Some(vec![0]));
        let s = links(&[0.0, 90.0, 180.0, 270.0]);
        assert_eq!(run(&fan_dir(&s, true, 90.0), &tension), Some(vec![1, 3]));
        assert_eq!(run(&fan_dir(&s, true, 90.0), &FailureCheck::default()), None);
    }
}
