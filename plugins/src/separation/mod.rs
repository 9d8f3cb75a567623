//! Separation rules (METHOD section 5; the paper's sections 2.2 and 3.1, figs. 3-5).
//!
//! What: given a failed cluster's fan (the joined edges at the point, as rays leaving it) and
//! the criterion's answer, a rule *proposes* the edge(s) to cut; the core applies the cut only
//! if the fan then falls into exactly two non-empty parts (rules never touch topology).
//!
//! Shared logic of the direction-based rules (`sigma1_nearest`, `shear_plane_nearest`):
//! - **closed fan** (a cycle): cut the link whose ray is nearest the target ray `d` and, among
//!   the other links, the one nearest `d + pi`: two distinct links, so the cycle always falls
//!   into two non-empty parts (on a structured quad mesh: the straight line BB' of figs. 4-5).
//! - **open fan** (a path): cut the one link nearest `d` as an undirected line (mod pi). At a
//!   point that has already split (the paper's a', a''), only if its angle to `d` is strictly
//!   below pi/4 (the paper's second split along Aa', section 3.1). At a point that never split
//!   (`FanView::never_split`: a boundary point, a corner, the tip of a pre-cut edge) the paper
//!   states no cap (its first-split rule, section 2.2): by default the nearest link is cut
//!   whatever its angle; `cap_unsplit_boundary = true` (ours, our first reading) applies the
//!   pi/4 cap there too ([`cap_for`]).
//! - **ties** (distances within [`TIE`] = 1e-9 rad of the smallest): prefer the link that lies
//!   counter-clockwise from the target, i.e. whose signed offset `angle - target` is in
//!   (0, pi] for rays, (0, pi/2] for lines; then the smaller edge id. So on a structured fan
//!   with `d` at 45 deg, the links at 90 and 270 deg are cut (a straight line).
//! - A check that did not fail (`mode == None`) proposes nothing. Non-finite angles propose
//!   nothing; no input panics.
//!
//! Angles are radians from +x in the current configuration; the proposal lists the first and
//! then the second chosen edge.
pub mod coulomb_traction;
pub mod shear_plane_nearest;
pub mod sigma1_nearest;
pub mod tip_mts;
pub mod traction;

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

use flem_core::ids::EdgeId;
use flem_core::plugin::traits::{line_angle, ray_angle, FanView, LinkGeom, Proposal};

/// The registered rule names (typetag `type = "..."`), in documentation order.
pub const NAMES: &[&str] = &["sigma1_nearest", "shear_plane_nearest", "traction", "coulomb_traction", "tip_mts"];

/// Angular tie tolerance (radians).
pub const TIE: f64 = 1e-9;

/// A candidate link for a cut: its distance to the target (smaller is better), whether it
/// lies counter-clockwise from the target, its edge id and a slot (link index or plane pair).
#[derive(Copy, Clone, Debug)]
pub(crate) struct Cand {
    pub dist: f64,
    pub ccw: bool,
    pub edge: EdgeId,
    pub link: usize,
    pub slot: usize,
}

/// The best candidate: smallest `dist`; among those within `tol` of it, counter-clockwise
/// first, then the smaller edge id, then the smaller slot. NaN distances never win.
pub(crate) fn pick(cands: &[Cand], tol: f64) -> Option<Cand> {
    let best = cands.iter().map(|c| c.dist).filter(|d| !d.is_nan()).fold(f64::INFINITY, f64::min);
    if !best.is_finite() {
        return None;
    }
    cands.iter().filter(|c| c.dist <= best + tol).min_by_key(|c| (!c.ccw, c.edge, c.slot, c.link)).copied()
}

/// Candidate for link `i` against a target ray `t` (distance mod 2 pi).
pub(crate) fn ray_cand(links: &[LinkGeom], i: usize, t: f64) -> Cand {
    let off = (links[i].angle - t).rem_euclid(2.0 * PI);
    let ccw = off > 0.0 && off <= PI;
    Cand { dist: ray_angle(links[i].angle, t), ccw, edge: links[i].edge, link: i, slot: 0 }
}

/// Candidate for link `i` against a target line `t` (distance mod pi).
pub(crate) fn line_cand(links: &[LinkGeom], i: usize, t: f64, slot: usize) -> Cand {
    let off = (links[i].angle - t).rem_euclid(PI);
    let ccw = off > 0.0 && off <= FRAC_PI_2;
    Cand { dist: line_angle(links[i].angle, t), ccw, edge: links[i].edge, link: i, slot }
}

/// The link whose ray is nearest the ray `t`, skipping link `skip`.
pub(crate) fn nearest_ray(links: &[LinkGeom], t: f64, skip: Option<usize>) -> Option<usize> {
    let c: Vec<Cand> = (0..links.len()).filter(|&i| Some(i) != skip).map(|i| ray_cand(links, i, t)).collect();
    pick(&c, TIE).map(|c| c.link)
}

/// Closed fan, given the first link: add the link nearest `d + pi` among the others.
pub(crate) fn closed_from_first(links: &[LinkGeom], first: usize, d: f64) -> Option<Proposal> {
    let second = nearest_ray(links, d + PI, Some(first))?;
    Some(Proposal { edges: vec![links[first].edge, links[second].edge] })
}

/// Closed fan: the link nearest the ray `d`, then the one nearest `d + pi` among the others.
pub(crate) fn closed_cut(links: &[LinkGeom], d: f64) -> Option<Proposal> {
    let first = nearest_ray(links, d, None)?;
    closed_from_first(links, first, d)
}

/// Whether the pi/4 cap applies to an open fan: always at a point that has already split (the
/// paper, section 3.1); at a point that never split only with `cap_unsplit_boundary` (ours;
/// the paper's default is no cap there, METHOD 5).
pub(crate) fn cap_for(fan: &FanView, cap_unsplit_boundary: bool) -> bool {
    !fan.never_split || cap_unsplit_boundary
}

/// Open fan: the candidate wins if `cap` is off or its line angle is strictly below pi/4.
pub(crate) fn open_from(c: Cand, cap: bool) -> Option<Proposal> {
    (!cap || c.dist < FRAC_PI_4).then(|| Proposal { edges: vec![c.edge] })
}

/// Open fan: the link nearest the line `d`, cut only below pi/4 when `cap`.
pub(crate) fn open_cut(links: &[LinkGeom], d: f64, cap: bool) -> Option<Proposal> {
    let c: Vec<Cand> = (0..links.len()).map(|i| line_cand(links, i, d, 0)).collect();
    open_from(pick(&c, TIE)?, cap)
}

/// Test fixtures: hand-built fans.
#[cfg(test)]
pub(crate) mod fixture {
    use flem_core::ids::{ClusterId, EdgeId, PointId};
    use flem_core::plugin::traits::{principal, FailureCheck, FailureMode, FanView, LinkGeom};

    /// Links at the given angles (degrees), edge ids 0, 1, ... in that order.
    pub fn links(deg: &[f64]) -> Vec<LinkGeom> {
        deg.iter()
            .enumerate()
            .map(|(i, d)| {
                let a = d.to_radians().rem_euclid(std::f64::consts::TAU);
                let n = a + std::f64::consts::FRAC_PI_2;
                LinkGeom { edge: EdgeId(i as u32), angle: a, normal: [n.cos(), n.sin()] }
            })
            .collect()
    }

    /// A fan with the given stress (tension positive) and principal values from it.
    pub fn fan(links: &[LinkGeom], closed: bool, stress: [f64; 3]) -> FanView<'_> {
        FanView { point: PointId(0), cluster: ClusterId(0), closed, never_split: false, links, stress, principal: principal(stress, 0.0) }
    }

    /// A fan whose sigma1 direction is `theta1_deg` (stress consistent: uniaxial tension
    /// perpendicular to it).
    pub fn fan_dir(links: &[LinkGeom], closed: bool, theta1_deg: f64) -> FanView<'_> {
        let t = theta1_deg.to_radians() + std::f64::consts::FRAC_PI_2;
        let (c, s) = (t.cos(), t.sin());
        let mut f = fan(links, closed, [c * c, s * s, c * s]);
        f.principal.theta1 = theta1_deg.to_radians().rem_euclid(std::f64::consts::PI);
        f
    }

    pub fn failed(mode: FailureMode, planes_deg: &[f64]) -> FailureCheck {
        let mut p = [0.0; 2];
        for (i, d) in planes_deg.iter().enumerate().take(2) {
            p[i] = d.to_radians();
        }
        FailureCheck { index: 1.0, mode: Some(mode), planes: p, n_planes: planes_deg.len().min(2) as u8 }
    }

    /// The cut edges as ids.
    pub fn ids(p: Option<flem_core::plugin::traits::Proposal>) -> Option<Vec<u32>> {
        p.map(|p| p.edges.iter().map(|e| e.0).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use flem_core::plugin::traits::SeparationRule;

    const SOURCES: &[(&str, &str)] = &[
        ("sigma1_nearest.rs", include_str!("sigma1_nearest.rs")),
        ("shear_plane_nearest.rs", include_str!("shear_plane_nearest.rs")),
        ("traction.rs", include_str!("traction.rs")),
        ("coulomb_traction.rs", include_str!("coulomb_traction.rs")),
        ("tip_mts.rs", include_str!("tip_mts.rs")),
    ];

    /// Every ```toml block of every rule's module doc parses, its `[cracking.separation]`
    /// table deserializes into a `Box<dyn SeparationRule>` and validates. Exact.
    #[test]
    fn doc_toml_snippets_parse_and_validate() {
        for (file, rule) in crate::snippets::doc_snippets::<Box<dyn SeparationRule>>(SOURCES, &["cracking", "separation"], NAMES) {
            rule.validate().unwrap_or_else(|e| panic!("{file}: {e}"));
        }
    }

    /// An unknown key names the key; an unknown rule name names the name.
    #[test]
    fn bad_input_names_the_key() {
        let err = toml::from_str::<Box<dyn SeparationRule>>("type = \"traction\"\nscore = 1\n").unwrap_err().to_string();
        assert!(err.contains("unknown field `score`"), "{err}");
        let err = toml::from_str::<Box<dyn SeparationRule>>("type = \"sigma1_nearst\"\n").unwrap_err().to_string();
        assert!(err.contains("sigma1_nearst"), "{err}");
    }

    /// The pick order: distance, then counter-clockwise, then edge id. Exact.
    #[test]
    fn pick_order() {
        let l = fixture::links(&[10.0, 350.0, 10.0 + 1e-8]);
        assert_eq!(nearest_ray(&l, 0.0, None), Some(0)); // 10 (ccw) beats 350 (cw)
        let l = fixture::links(&[10.0, 10.0 + 1e-12, 350.0]);
        assert_eq!(nearest_ray(&l, 0.0, None), Some(0)); // same ray: smaller edge id
        assert_eq!(nearest_ray(&l, f64::NAN, None), None);
        assert_eq!(nearest_ray(&[], 0.0, None), None);
    }
}
