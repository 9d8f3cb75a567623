//! `sigma1_nearest`: the paper's separation rule (paper section 2.2 with figs. 3-5, section
//! 3.1 for the second split along Aa'; METHOD section 5).
//!
//! For both failure modes the failure plane is taken as the sigma1 direction `d = theta1`
//! (the paper: the true shear planes lie within pi/4 - phi/2 of it, and eq. (1) tension
//! failure gives that plane exactly):
//! - closed fan: cut the link whose ray is nearest `d` and, among the others, the one nearest
//!   `d + pi` (two distinct links; BB' in figs. 3(c), 4(c));
//! - open fan: cut the link nearest `d` as a line (mod pi); at a point that has already split
//!   (the paper's a', a'', section 3.1) only if that angle is < pi/4. At a point that never
//!   split (a boundary point, a corner, the tip of a pre-cut edge) the paper (section 2.2)
//!   has no cap: the nearest link is cut whatever the angle, unless `cap_unsplit_boundary =
//!   true` (ours: our first reading, which applied the cap there too; METHOD 5).
//!
//! Ties within 1e-9 rad: the link counter-clockwise from the target (signed offset in (0, pi]
//! for rays, (0, pi/2] for lines), then the smaller edge id (see [`super`]).
//! Angles in radians. Parameter: `cap_unsplit_boundary` (bool, default `false` = the paper).
//!
//! ```toml
//! [cracking.separation]
//! type = "sigma1_nearest"
//! ```
//!
//! ```toml
//! [cracking.separation]
//! type = "sigma1_nearest"
//! cap_unsplit_boundary = true   # ours: the pi/4 cap also at never-split boundary points
//! ```
use serde::{Deserialize, Serialize};

use flem_core::plugin::traits::{FailureCheck, FanView, Proposal, SeparationRule};

use super::{cap_for, closed_cut, open_cut};

/// The paper's rule: cut along the sigma1 direction (see the module docs).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sigma1Nearest {
    /// Ours (not the paper's): the pi/4 open-fan cap also at points that never split.
    #[serde(default)]
    pub cap_unsplit_boundary: bool,
}

/// The sigma1-nearest proposal for a target direction `d` (radians).
pub(crate) fn propose_along(fan: &FanView, d: f64, cap_unsplit_boundary: bool) -> Option<Proposal> {
    if fan.closed {
        closed_cut(fan.links, d)
    } else {
        open_cut(fan.links, d, cap_for(fan, cap_unsplit_boundary))
    }
}

#[typetag::serde(name = "sigma1_nearest")]
impl SeparationRule for Sigma1Nearest {
    fn propose(&self, fan: &FanView, failure: &FailureCheck) -> Option<Proposal> {
        failure.mode?;
        propose_along(fan, fan.principal.theta1, self.cap_unsplit_boundary)
    }
}

#[cfg(test)]
mod tests {
    use super::super::fixture::{failed, fan, fan_dir, ids, links};
    use super::*;
    use flem_core::plugin::traits::FailureMode::{Shear, Tension};

    fn run(f: &FanView) -> Option<Vec<u32>> {
        ids(Sigma1Nearest::default().propose(f, &failed(Tension, &[])))
    }

    /// Structured 4-link closed fan (0, 90, 180, 270 deg) under tension along x: sigma1 is
    /// along y, so the links at 90 and 270 deg are cut (a vertical crack). Exact.
    #[test]
    fn structured_closed_fan_tension_x() {
        let l = links(&[0.0, 90.0, 180.0, 270.0]);
        let f = fan(&l, true, [1.0, 0.0, 0.0]);
        assert_eq!(run(&f), Some(vec![1, 3]));
        // shear mode uses the same direction
        assert_eq!(ids(Sigma1Nearest::default().propose(&f, &failed(Shear, &[60.0, 120.0]))), Some(vec![1, 3]));
        // compression along x (sigma1 along x): links at 0 and 180
        assert_eq!(run(&fan(&l, true, [-1.0, 0.0, 0.0])), Some(vec![0, 2]));
        // a check that did not fail proposes nothing
        assert_eq!(Sigma1Nearest::default().propose(&f, &FailureCheck::default()), None);
    }

    /// Open fan: splits when the link is at 44 deg to d, not at 46 deg (threshold pi/4). Exact.
    #[test]
    fn open_fan_threshold() {
        for d in [0.0, 30.0, 90.0, 170.0] {
            let l44 = links(&[d + 44.0, d + 180.0 + 44.0]);
            assert_eq!(run(&fan_dir(&l44, false, d)), Some(vec![0]), "d = {d}");
            let l46 = links(&[d + 46.0, d - 46.0 + 360.0, d + 180.0 + 46.0]);
            assert_eq!(run(&fan_dir(&l46, false, d)), None, "d = {d}");
            let lm44 = links(&[d + 90.0, d - 44.0 + 180.0]);
            assert_eq!(run(&fan_dir(&lm44, false, d)), Some(vec![1]), "d = {d}");
        }
        assert_eq!(run(&fan_dir(&[], false, 0.0)), None);
    }

    /// Ties: d at 45 deg on the structured fan cuts 90 and 270 (counter-clockwise from 45 and
    /// from 225); d at 135 deg cuts 180 and 0. Open fan with links at 0 and 90 and d = 45:
    /// the counter-clockwise one (90). Equal angles: the smaller edge id. Exact.
    #[test]
    fn tie_rule() {
        let l = links(&[0.0, 90.0, 180.0, 270.0]);
        assert_eq!(run(&fan_dir(&l, true, 45.0)), Some(vec![1, 3]));
        assert_eq!(run(&fan_dir(&l, true, 135.0)), Some(vec![2, 0]));
        // METHOD row 3: pure shear gives sigma1 at 135 deg from the stress itself
        assert_eq!(run(&fan(&l, true, [0.0, 0.0, 0.3])), Some(vec![2, 0]));
        let open = links(&[0.0, 90.0]);
        assert_eq!(run(&fan_dir(&open, false, 40.0)), Some(vec![0]));
        assert_eq!(run(&fan_dir(&open, false, 50.0)), Some(vec![1]));
        let same = links(&[30.0, 30.0, 200.0]);
        assert_eq!(run(&fan_dir(&same, false, 30.0)), Some(vec![0]));
    }

    /// 6-link closed T3 fan (0, 45, 90, 180, 225, 270 deg): every sigma1 direction gives two
    /// distinct links, and the expected pairs for d = 0, 45, 90. Exact.
    #[test]
    fn t3_closed_fan_two_distinct_links() {
        let l = links(&[0.0, 45.0, 90.0, 180.0, 225.0, 270.0]);
        for k in 0..360 {
            let d = k as f64 * 0.5;
            let got = run(&fan_dir(&l, true, d)).unwrap();
            assert!(got.len() == 2 && got[0] != got[1], "d = {d}: {got:?}");
        }
        assert_eq!(run(&fan_dir(&l, true, 0.0)), Some(vec![0, 3]));
        assert_eq!(run(&fan_dir(&l, true, 45.0)), Some(vec![1, 4]));
        assert_eq!(run(&fan_dir(&l, true, 90.0)), Some(vec![2, 5]));
        // fewer than two links: nothing to cut in a closed fan; NaN direction: nothing
        assert_eq!(run(&fan_dir(&links(&[0.0]), true, 0.0)), None);
        assert_eq!(run(&fan_dir(&l, true, f64::NAN)), None);
    }

    /// The cap at a point that never split (METHOD 5): an open fan (a boundary point) with
    /// its two links at 60 deg to sigma1 (beyond pi/4). The paper (default): cut the nearer
    /// link whatever the angle; `cap_unsplit_boundary = true`: nothing. At an already split
    /// point the cap holds in both settings (the paper's section 3.1). Exact.
    #[test]
    fn cap_unsplit_boundary_option() {
        let l = links(&[0.0, 60.0 + 90.0 + 60.0]); // links at 0 and 210 deg
        let mut f = fan_dir(&l, false, 60.0); // line angles 60 and 30 deg -> nearest 210 (30 deg)
        let l75 = links(&[0.0, 105.0]);
        let mut f75 = fan_dir(&l75, false, 60.0); // line angles 60 and 45
        let capped = Sigma1Nearest { cap_unsplit_boundary: true };
        let paper = Sigma1Nearest::default();
        // 30 deg: below the cap, cut in every setting
        f.never_split = true;
        assert_eq!(ids(paper.propose(&f, &failed(Tension, &[]))), Some(vec![1]));
        assert_eq!(ids(capped.propose(&f, &failed(Tension, &[]))), Some(vec![1]));
        // 45 deg and 60 deg: beyond the cap
        f75.never_split = true;
        assert_eq!(ids(paper.propose(&f75, &failed(Tension, &[]))), Some(vec![1]), "never split, paper: cut at 45 deg");
        assert_eq!(ids(capped.propose(&f75, &failed(Tension, &[]))), None, "never split, capped: no cut");
        f75.never_split = false;
        assert_eq!(ids(paper.propose(&f75, &failed(Tension, &[]))), None, "already split: the paper's cap");
        assert_eq!(ids(capped.propose(&f75, &failed(Tension, &[]))), None);
        let l80 = links(&[140.0, 145.0]);
        let mut f80 = fan_dir(&l80, false, 60.0); // line angles 80 and 85 deg
        f80.never_split = true;
        assert_eq!(ids(paper.propose(&f80, &failed(Tension, &[]))), Some(vec![0]), "80 deg: the nearer link");
        assert_eq!(ids(capped.propose(&f80, &failed(Tension, &[]))), None);
    }
}
