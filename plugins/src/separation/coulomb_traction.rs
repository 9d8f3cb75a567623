//! `coulomb_traction`: for shear failure, cut the link(s) whose own plane is most critical by
//! Mohr-Coulomb (METHOD sections 4-5; an alternative to the paper's sigma1-nearest rule of
//! section 2.2, which for shear failure takes the sigma1 direction as the failure plane).
//!
//! For a link (edge leaving the point at angle `a`) with unit normal `n = (-sin a, cos a)` and
//! tangent `s = (cos a, sin a)`, the traction of the nodal stress (tension positive,
//! `FanView::stress`) on that plane has normal part `t_n = t . n` (tension positive) and shear
//! part `t_s = t . s` ([`super::traction::traction`]). With `sigma_n = -t_n` (compression
//! positive, METHOD 4) the link's **Coulomb excess** is
//!
//! `e = |t_s| - (c + sigma_n tan(phi))`  (stress units; e >= 0: the edge's own plane fails)
//!
//! with `c` = `cohesion` and `phi` = `friction_angle_deg` (give the criterion's values so that
//! the rule and METHOD 4's shear check agree: the largest `e` over all planes is >= 0 exactly
//! when the Mohr-Coulomb check fails).
//! - **shear failure**: closed fan: cut the link of largest `e` and, among the links on the
//!   other side (ray angle to the first more than pi/2 + 1e-9 rad), the one of largest `e`
//!   (two distinct links; on a structured quad mesh a straight line); no link there: no cut.
//!   Open fan: cut the link of largest `e` only if `e > 0` (its plane really fails).
//! - **tension failure**: exactly as `sigma1_nearest` (the paper's rule; eq. (1) gives the
//!   plane exactly), with its `cap_unsplit_boundary` (default `false`, the paper: no pi/4 cap
//!   at points that never split; `true` is ours).
//! - Ties: excesses within 1e-9 (relative to the largest |e|) count as equal; then the smaller
//!   edge id. A check that did not fail proposes nothing; NaN stress proposes nothing.
//!
//! Why: on a plane where the normal stresses differ much (the direct shear scene: sigma_yy
//! from q and p far more compressive than sigma_xx near the plane cd), the sigma1 direction
//! and the plane of largest |t_s| need not be the plane that fails first by Coulomb; this rule
//! cuts the edge whose own plane is closest to (or furthest beyond) Coulomb's limit.
//!
//! Units: `cohesion` stress; `friction_angle_deg` degrees in [0, 90); `cap_unsplit_boundary`
//! bool (default false).
//!
//! ```toml
//! [cracking.separation]
//! type = "coulomb_traction"
//! cohesion = 98066.5          # 0.1 kgf/cm^2 in dyn/cm^2 (paper Table 1)
//! friction_angle_deg = 30.0
//! cap_unsplit_boundary = false  # the paper (tension splits: no pi/4 cap at never-split points)
//! ```
//!
//! Relation to the other rules (issue 8): on a closed fan it picks the best link and the best
//! one on the other side, as `traction` does, reusing `traction::traction` and the shared `pick`
//! tie rule. On orthogonal fans it cuts the same edges as the paper's rule (equal `|t_s|` on
//! both planes: the less compressed one wins); it differs on skewed fans and open fans. The
//! direct shear scene with contact and both rules: `docs/paper.md`.
use std::f64::consts::FRAC_PI_2;

use serde::{Deserialize, Serialize};

use flem_core::plugin::traits::{ray_angle, FailureCheck, FailureMode, FanView, ParamError, Proposal, SeparationRule};

use super::sigma1_nearest::propose_along;
use super::traction::traction;
use super::{pick, Cand, TIE};

/// Cut the edge whose own plane is most critical by Mohr-Coulomb (see the module docs).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoulombTraction {
    /// c, stress units (>= 0).
    pub cohesion: f64,
    /// phi, degrees in [0, 90).
    pub friction_angle_deg: f64,
    /// Ours (not the paper's): for tension splits, the pi/4 open-fan cap also at points that
    /// never split (see `sigma1_nearest`).
    #[serde(default)]
    pub cap_unsplit_boundary: bool,
}

impl CoulombTraction {
    /// The Coulomb excess `|t_s| - (c + sigma_n tan(phi))` of the tension-positive stress `s`
    /// on the plane of a link, `sigma_n = -t_n`.
    pub fn excess(&self, s: [f64; 3], l: &flem_core::plugin::traits::LinkGeom) -> f64 {
        let (tn, ts) = traction(s, l);
        ts.abs() - (self.cohesion - tn * self.friction_angle_deg.to_radians().tan())
    }

    /// The link of largest excess among `which`, with its excess.
    fn best(&self, fan: &FanView, which: impl Fn(usize) -> bool) -> Option<(usize, f64)> {
        let c: Vec<Cand> = (0..fan.links.len()).filter(|&i| which(i)).map(|i| Cand { dist: -self.excess(fan.stress, &fan.links[i]), ccw: true, edge: fan.links[i].edge, link: i, slot: 0 }).collect();
        let scale = c.iter().map(|c| c.dist.abs()).filter(|d| d.is_finite()).fold(0.0, f64::max);
        pick(&c, TIE * scale).map(|c| (c.link, -c.dist))
    }
}

#[typetag::serde(name = "coulomb_traction")]
impl SeparationRule for CoulombTraction {
    fn validate(&self) -> Result<(), ParamError> {
        ParamError::range("cohesion", self.cohesion, 0.0, true, f64::INFINITY, false)?;
        ParamError::range("friction_angle_deg", self.friction_angle_deg, 0.0, true, 90.0, false)
    }
    fn propose(&self, fan: &FanView, failure: &FailureCheck) -> Option<Proposal> {
        if failure.mode? != FailureMode::Shear {
            return propose_along(fan, fan.principal.theta1, self.cap_unsplit_boundary);
        }
        let (first, e) = self.best(fan, |_| true)?;
        if !fan.closed {
            return (e > 0.0).then(|| Proposal { edges: vec![fan.links[first].edge] });
        }
        let a = fan.links[first].angle;
        let (second, _) = self.best(fan, |i| ray_angle(fan.links[i].angle, a) > FRAC_PI_2 + TIE)?;
        Some(Proposal { edges: vec![fan.links[first].edge, fan.links[second].edge] })
    }
}

#[cfg(test)]
mod tests {
    use super::super::fixture::{failed, fan, ids, links};
    use super::*;
    use crate::criteria::mohr_coulomb::MohrCoulomb;
    use flem_core::plugin::traits::{principal, FailureCriterion};
    use FailureMode::{Shear, Tension};

    /// c = 0.1, phi = 30 deg (METHOD 4's worked values).
    fn rule() -> CoulombTraction {
        CoulombTraction { cohesion: 0.1, friction_angle_deg: 30.0, cap_unsplit_boundary: false }
    }
    fn run(f: &FanView, mode: FailureMode) -> Option<Vec<u32>> {
        ids(rule().propose(f, &failed(mode, &[])))
    }

    /// Hand values of the excess (tolerance 1e-12): stress (sxx, syy, sxy) = (-0.2, -1.0, 0.5)
    /// (tension positive). Horizontal link: t_s = 0.5, sigma_n = 1.0, e = 0.5 - 0.1 - tan30 =
    /// -0.17735; vertical link: sigma_n = 0.2, e = 0.5 - 0.1 - 0.2 tan30 = 0.28453.
    #[test]
    fn excess_hand_values() {
        let l = links(&[0.0, 90.0, 180.0, 270.0]);
        let s = [-0.2, -1.0, 0.5];
        let t = 30f64.to_radians().tan();
        for (i, want) in [(0, 0.4 - t), (1, 0.4 - 0.2 * t), (2, 0.4 - t), (3, 0.4 - 0.2 * t)] {
            let e = rule().excess(s, &l[i]);
            assert!((e - want).abs() < 1e-12, "link {i}: {e} vs {want}");
        }
        assert!((0.4 - t - -0.17735).abs() < 1e-5 && (0.4 - 0.2 * t - 0.28453).abs() < 1e-5);
    }

    /// The direct shear state near the plane (vertical stress far more compressive than the
    /// horizontal one): the vertical links are cut (a vertical crack). When the horizontal
    /// stress is the more compressive ((-1.0, -0.2, 0.5): sigma_n on the horizontal plane 0.2),
    /// the horizontal links (the plane y = const) are cut instead. For equal normal stresses
    /// the larger |t_s| ties: pure shear ties between 0 and 90 deg and the smaller edge id (0)
    /// wins, then 180. Exact.
    #[test]
    fn structured_fan_cuts_the_coulomb_critical_plane() {
        let l = links(&[0.0, 90.0, 180.0, 270.0]);
        assert_eq!(run(&fan(&l, true, [-0.2, -1.0, 0.5]), Shear), Some(vec![1, 3]));
        assert_eq!(run(&fan(&l, true, [-1.0, -0.2, 0.5]), Shear), Some(vec![0, 2]));
        assert_eq!(run(&fan(&l, true, [0.0, 0.0, 1.0]), Shear), Some(vec![0, 2]));
        // uniaxial compression along x (sxx = -1): the 45 deg planes have |t_s| = 0.5,
        // sigma_n = 0.5: e = 0.5 - 0.1 - 0.5 tan30 = 0.111 on the T3 fan's 45/225 links,
        // while the 0/90 links have |t_s| = 0: the cut is 45 and 225.
        let t3 = links(&[0.0, 45.0, 90.0, 180.0, 225.0, 270.0]);
        assert_eq!(run(&fan(&t3, true, [-1.0, 0.0, 0.0]), Shear), Some(vec![1, 4]));
    }

    /// On a structured fan (links at 0, 90, 180, 270 deg) both planes carry the same |t_s| =
    /// |sxy|, so the excess differs only by sigma_n tan(phi): the less compressed plane wins,
    /// i.e. the plane parallel to the more compressive direction, which is the plane that
    /// sigma1_nearest cuts (sigma1 within 45 deg of it). So on orthogonal fans the two rules
    /// agree whenever sxx != syy and sxy != 0 (checked on a grid of 4620 stress states).
    /// Reference: that identity; exact.
    #[test]
    fn agrees_with_sigma1_nearest_on_orthogonal_fans() {
        use super::super::sigma1_nearest::Sigma1Nearest;
        let l = links(&[0.0, 90.0, 180.0, 270.0]);
        let mut n = 0;
        for i in -10..=10 {
            for j in -10..=10 {
                for k in [-2.0, -0.7, -0.1, 0.1, 0.7, 1.0, 2.0, 3.0, 5.0, 8.0, 13.0] {
                    let (sxx, syy, sxy) = (i as f64 * 0.13, j as f64 * 0.13, k * 0.1);
                    if (sxx - syy).abs() < 1e-9 {
                        continue;
                    }
                    let f = fan(&l, true, [sxx, syy, sxy]);
                    let a = ids(rule().propose(&f, &failed(Shear, &[]))).unwrap();
                    let b = ids(Sigma1Nearest::default().propose(&f, &failed(Shear, &[]))).unwrap();
                    let set = |v: &[u32]| {
                        let mut v = v.to_vec();
                        v.sort();
                        v
                    };
                    assert_eq!(set(&a), set(&b), "stress ({sxx}, {syy}, {sxy})");
                    n += 1;
                }
            }
        }
        assert_eq!(n, 21 * 20 * 11);
    }

    /// The largest excess over every plane is >= 0 exactly when METHOD 4's Mohr-Coulomb check
    /// fails in shear: on a fan of 3600 links (0.1 deg apart) the rule's best excess and the
    /// criterion agree on the worked states of METHOD 4 (compression positive there) and on a
    /// state just inside / just outside the envelope. Reference: Mohr's circle tangent to the
    /// Coulomb line; tolerance: the 0.1 deg link spacing (excess within 1e-6 of the maximum).
    #[test]
    fn best_excess_agrees_with_the_mohr_coulomb_check() {
        let deg: Vec<f64> = (0..3600).map(|k| k as f64 * 0.1).collect();
        let l = links(&deg);
        let mc = MohrCoulomb { cohesion: 0.1, friction_angle_deg: 30.0, tensile_strength: 1.0, tension: false, shear: true };
        for s in [[-2.0, -0.5, 0.0], [-2.0, -0.6, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 0.3], [-0.2, -1.0, 0.5], [-0.35, 0.0, 0.0], [-0.34, 0.0, 0.0]] {
            let check = mc.check(&principal(s, 0.0), 1.0);
            let f = fan(&l, true, s);
            let (_, e) = rule().best(&f, |_| true).unwrap();
            // UCS = 0.34641: -0.35 fails, -0.34 holds
            assert_eq!(e >= 0.0, check.mode == Some(Shear), "{s:?}: best excess {e}, check {:?}", check.mode);
        }
    }

    /// Open fan: cut only a link whose own plane fails (e > 0); tension failure and a check
    /// that did not fail behave as sigma1_nearest / propose nothing; bad parameters name the
    /// key; NaN stress proposes nothing. Exact.
    #[test]
    fn open_fan_tension_and_bad_input() {
        let open = links(&[0.0, 90.0]);
        assert_eq!(run(&fan(&open, false, [-0.2, -1.0, 0.5]), Shear), Some(vec![1]));
        assert_eq!(run(&fan(&open, false, [-0.2, -1.0, 0.05]), Shear), None);
        // tension along x: sigma1 (compression-positive) along y: the vertical link
        assert_eq!(run(&fan(&open, false, [1.0, 0.0, 0.0]), Tension), Some(vec![1]));
        assert_eq!(rule().propose(&fan(&open, false, [1.0, 0.0, 0.0]), &FailureCheck::default()), None);
        let l = links(&[0.0, 90.0, 180.0, 270.0]);
        assert_eq!(run(&fan(&l, true, [f64::NAN, 0.0, 0.0]), Shear), None);
        let e = CoulombTraction { cohesion: -1.0, friction_angle_deg: 30.0, cap_unsplit_boundary: false }.validate().unwrap_err();
        assert_eq!(e.key, "cohesion");
        let e = CoulombTraction { cohesion: 0.0, friction_angle_deg: 90.0, cap_unsplit_boundary: false }.validate().unwrap_err();
        assert_eq!(e.key, "friction_angle_deg");
    }
}
