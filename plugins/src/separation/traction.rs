//! `traction`: cut the link(s) whose plane carries the most critical traction (METHOD
//! section 5, an alternative to the paper's sigma1-nearest rule of section 2.2).
//!
//! For a link (edge leaving the point at angle `a`) with unit normal `n = (-sin a, cos a)`
//! (`LinkGeom::normal`) and unit tangent `s = (cos a, sin a)`, the traction of the nodal
//! stress (tension positive, `FanView::stress = [sxx, syy, sxy]`) on that plane is
//! `t = sigma n`, with normal component `t_n = t . n` (tension positive) and shear component
//! `t_s = t . s`. The score of a link (stress units) is
//! - tension failure: `t_n` (the most tensile plane wins);
//! - shear failure: `|t_s|` (the plane of largest shear traction wins).
//!
//! Closed fan: cut the best link and, among the links on the other side (ray angle to the
//! first more than pi/2 + 1e-9 rad, so a perpendicular link never counts under rounding),
//! the best one; no link there: no cut. Open fan: cut the best link if its score is > 0.
//! Ties: scores within 1e-9 of the largest |score| (relative) count as equal; then the smaller
//! edge id. A check that did not fail proposes nothing. No parameters.
//!
//! ```toml
//! [cracking.separation]
//! type = "traction"
//! ```
use std::f64::consts::FRAC_PI_2;

use serde::{Deserialize, Serialize};

use flem_core::plugin::traits::{ray_angle, FailureCheck, FailureMode, FanView, LinkGeom, Proposal, SeparationRule};

use super::{pick, Cand, TIE};

/// Cut where the traction is most critical (see the module docs).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Traction {}

/// `(t_n, t_s)` of the tension-positive stress `s` on the plane of link `l`.
pub fn traction(s: [f64; 3], l: &LinkGeom) -> (f64, f64) {
    let n = l.normal;
    let t = [s[0] * n[0] + s[2] * n[1], s[2] * n[0] + s[1] * n[1]];
    let tan = [n[1], -n[0]];
    (t[0] * n[0] + t[1] * n[1], t[0] * tan[0] + t[1] * tan[1])
}

/// The score of a link for a failure mode (larger is more critical).
pub fn score(s: [f64; 3], l: &LinkGeom, mode: FailureMode) -> f64 {
    let (tn, ts) = traction(s, l);
    match mode {
        FailureMode::Tension => tn,
        FailureMode::Shear => ts.abs(),
    }
}

/// The best link among `which` (candidate distance = -score).
fn best(fan: &FanView, mode: FailureMode, which: impl Fn(usize) -> bool) -> Option<(usize, f64)> {
    let c: Vec<Cand> = (0..fan.links.len()).filter(|&i| which(i)).map(|i| Cand { dist: -score(fan.stress, &fan.links[i], mode), ccw: true, edge: fan.links[i].edge, link: i, slot: 0 }).collect();
    let scale = c.iter().map(|c| c.dist.abs()).filter(|d| d.is_finite()).fold(0.0, f64::max);
    pick(&c, TIE * scale).map(|c| (c.link, -c.dist))
}

#[typetag::serde(name = "traction")]
impl SeparationRule for Traction {
    fn propose(&self, fan: &FanView, failure: &FailureCheck) -> Option<Proposal> {
        let mode = failure.mode?;
        let (first, s) = best(fan, mode, |_| true)?;
        if !fan.closed {
            return (s > 0.0).then(|| Proposal { edges: vec![fan.links[first].edge] });
        }
        let a = fan.links[first].angle;
        let other = |i: usize| ray_angle(fan.links[i].angle, a) > FRAC_PI_2 + TIE;
        let (second, _) = best(fan, mode, other)?;
        Some(Proposal { edges: vec![fan.links[first].edge, fan.links[second].edge] })
    }
}

#[cfg(test)]
mod tests {
    use super::super::fixture::{failed, fan, ids, links};
    use super::*;
    use FailureMode::{Shear, Tension};

    fn run(f: &FanView, mode: FailureMode) -> Option<Vec<u32>> {
        ids(Traction {}.propose(f, &failed(mode, &[])))
    }

    /// Traction components on hand planes (tolerance 1e-12): uniaxial tension sxx = 1 gives
    /// t_n = 1, t_s = 0 on the vertical link and t_n = 0 on the horizontal one; pure shear
    /// sxy = 1 gives t_n = 0, |t_s| = 1 on both and t_n = 1 at 135 deg.
    #[test]
    fn traction_components() {
        let l = links(&[90.0, 0.0, 135.0]);
        let (tn, ts) = traction([1.0, 0.0, 0.0], &l[0]);
        assert!((tn - 1.0).abs() < 1e-12 && ts.abs() < 1e-12);
        let (tn, ts) = traction([1.0, 0.0, 0.0], &l[1]);
        assert!(tn.abs() < 1e-12 && ts.abs() < 1e-12);
        let (tn, ts) = traction([0.0, 0.0, 1.0], &l[1]);
        assert!(tn.abs() < 1e-12 && (ts.abs() - 1.0).abs() < 1e-12);
        let (tn, _) = traction([0.0, 0.0, 1.0], &l[2]);
        assert!((tn - 1.0).abs() < 1e-12);
    }

    /// Structured closed fan under tension along x: the links at 90 and 270 deg (t_n = 1).
    /// Open fan: the most tensile link if t_n > 0, nothing in compression. Exact.
    #[test]
    fn tension_closed_and_open() {
        let l = links(&[0.0, 90.0, 180.0, 270.0]);
        assert_eq!(run(&fan(&l, true, [1.0, 0.0, 0.0]), Tension), Some(vec![1, 3]));
        assert_eq!(run(&fan(&l, true, [0.0, 1.0, 0.0]), Tension), Some(vec![0, 2]));
        let open = links(&[0.0, 90.0]);
        assert_eq!(run(&fan(&open, false, [1.0, 0.2, 0.0]), Tension), Some(vec![1]));
        assert_eq!(run(&fan(&open, false, [-1.0, -0.2, 0.0]), Tension), None);
        assert_eq!(Traction {}.propose(&fan(&open, false, [1.0, 0.0, 0.0]), &FailureCheck::default()), None);
    }

    /// Shear: pure shear sxy has |t_s| = 1 on the 0 and 90 deg links (tie: smaller edge id
    /// 0, then 180 on the other side); the T3 fan gives two distinct links. Exact.
    #[test]
    fn shear_and_t3() {
        let l = links(&[0.0, 90.0, 180.0, 270.0]);
        assert_eq!(run(&fan(&l, true, [0.0, 0.0, 1.0]), Shear), Some(vec![0, 2]));
        let t3 = links(&[0.0, 45.0, 90.0, 180.0, 225.0, 270.0]);
        for k in 0..36 {
            let a = (k as f64 * 5.0).to_radians();
            let (c, s) = (a.cos(), a.sin());
            for mode in [Tension, Shear] {
                let got = run(&fan(&t3, true, [c * c, s * s, c * s]), mode).unwrap();
                assert!(got.len() == 2 && got[0] != got[1], "{mode:?} a = {k}: {got:?}");
            }
        }
        // no link on the other side: nothing; NaN stress: nothing
        assert_eq!(run(&fan(&links(&[0.0, 60.0]), true, [1.0, 0.0, 0.0]), Tension), None);
        assert_eq!(run(&fan(&l, true, [f64::NAN, 0.0, 0.0]), Tension), None);
    }
}
