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
//! **In 3D** (issue 38; the paper's rule read in 3D, ours, docs/3d.md): the failure plane
//! contains the sigma1 and sigma2 directions, so its normal is `n = d3` (the most tensile
//! direction). The fan's elements are sorted by the side of the plane through the point their
//! centroid lies on, `s_e = (c_e - x) . n`; the elements with `s_e > 0` joined (through
//! the fan's links among them) to the one of largest `s_e` form one part, and every joined face
//! between that part and the rest is cut (`Topology3::plane_cut`): the element faces closest to
//! the plane. At a point that has split before, the cut is made only if those faces' normals
//! are within pi/4 of `n` on average (mean of `|n_f . n|` >= cos(pi/4): the paper's cap of
//! section 3.1, read in 3D); at a never-split point only with `cap_unsplit_boundary = true`.
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

use flem_core::ids::FaceId;
use flem_core::mesh::topology3::Topology3;
use flem_core::plugin::traits::{FailureCheck, FanView, FanView3, Proposal, SeparationRule};

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

    fn propose_3d(&self, fan: &FanView3, failure: &FailureCheck) -> Result<Option<Vec<FaceId>>, String> {
        if failure.mode.is_none() {
            return Ok(None);
        }
        Ok(plane_faces(fan, fan.principal.d3, !fan.never_split || self.cap_unsplit_boundary))
    }
}

/// The faces of a 3D fan closest to the plane through its point with unit normal `n` (see the
/// module doc); with `cap`, `None` unless the faces' normals are within pi/4 of `n` on average
/// (the mean of `|n_f . n|` at least cos(pi/4)).
pub(crate) fn plane_faces(fan: &FanView3, n: [f64; 3], cap: bool) -> Option<Vec<FaceId>> {
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let side: Vec<f64> = fan.centroids.iter().map(|c| dot([c[0] - fan.x[0], c[1] - fan.x[1], c[2] - fan.x[2]], n)).collect();
    let faces = Topology3::plane_cut(fan.fan, &side);
    if faces.is_empty() {
        return None;
    }
    if cap {
        let (mut sum, mut k) = (0.0, 0usize);
        for (l, nf) in fan.fan.links.iter().zip(fan.face_normals) {
            if faces.contains(&l.face) {
                sum += dot(*nf, n).abs();
                k += 1;
            }
        }
        if sum < std::f64::consts::FRAC_PI_4.cos() * k as f64 {
            return None;
        }
    }
    Some(faces)
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

    /// The rule read in 3D (module doc) on the centre point of a 2 x 2 x 2 box of unit cubes.
    /// Reference: construction. Tension along x, or along a direction 20 deg from x in the xz
    /// plane: the fan falls into two parts, each on one side of the plane through the point
    /// normal to the tension; on H8 (and on T4 along x) the faces cut are those of the plane
    /// x = 1, 4 + 4 hexahedra (12 + 12 tetrahedra). Tension 60 deg from x on H8: the plane z = 1. At a point that has split before, tension 30 deg from x is cut
    /// (within the pi/4 cap); tension along the cube's diagonal (54.7 deg from every face
    /// normal, H8) is refused there and cut at a never-split point.
    #[test]
    fn three_d_closed_fan_cuts_the_plane_normal_to_the_tension() {
        use flem_core::ids::ClusterId;
        use flem_core::mesh::topology3::{unit_cubes, Topology3};
        use flem_core::plugin::traits::{principal3, FanView3};
        for tets in [false, true] {
            let m = unit_cubes(2, tets);
            let t = Topology3::new(&m);
            let fan = t.fan(ClusterId(13));
            let centroid = |k: flem_core::ids::CopyId| {
                let c = m.cells[t.copy_elem[k.idx()].idx()];
                let n = c.corners().len() as f64;
                std::array::from_fn(|d| c.corners().iter().map(|&p| m.points[p as usize][d]).sum::<f64>() / n)
            };
            let centroids: Vec<[f64; 3]> = fan.copies.iter().map(|&k| centroid(k)).collect();
            let normals: Vec<[f64; 3]> = fan
                .links
                .iter()
                .map(|l| {
                    let p: Vec<[f64; 3]> = t.faces[l.face.idx()].corners().iter().map(|q| m.points[q.idx()]).collect();
                    let (a, b) = ([p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]], [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]]);
                    let n = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
                    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                    [n[0] / l, n[1] / l, n[2] / l]
                })
                .collect();
            for (deg, axis, never_split, want) in [(0.0, 0, true, true), (20.0, 0, true, true), (60.0, 2, true, true), (30.0, 0, false, !tets)] {
                let a = f64::to_radians(deg);
                let (c, s) = (a.cos(), a.sin());
                // uniaxial tension 1 along (c, 0, s)
                let stress = [c * c, 0.0, s * s, 0.0, 0.0, c * s];
                let view = FanView3 { fan: &fan, x: [1.0, 1.0, 1.0], centroids: &centroids, face_normals: &normals, never_split, principal: principal3(stress) };
                let got = Sigma1Nearest::default().propose_3d(&view, &failed(Tension, &[])).unwrap();
                if never_split || !tets {
                    assert_eq!(got.is_some(), want, "tets {tets} deg {deg} never_split {never_split}");
                }
                let Some(faces) = got else { continue };
                let parts = Topology3::fan_parts(&fan, &faces);
                assert_eq!(parts.len(), 2, "tets {tets} deg {deg}");
                // Each part's elements on one side of the plane through the point normal to the
                // tension (signed distances of the centroids all of one sign).
                let sd = |k: flem_core::ids::CopyId| {
                    let x = centroid(k);
                    (x[0] - 1.0) * c + (x[2] - 1.0) * s
                };
                for p in &parts {
                    assert!(p.iter().all(|&k| sd(k) > 0.0) || p.iter().all(|&k| sd(k) <= 0.0), "tets {tets} deg {deg}");
                }
                // H8 (any of these angles) and T4 along x: exactly the plane x[axis] = 1, halves.
                if !tets || deg == 0.0 {
                    for f in &faces {
                        assert!(t.faces[f.idx()].corners().iter().all(|p| m.points[p.idx()][axis] == 1.0), "tets {tets} deg {deg}");
                    }
                    assert_eq!(parts[0].len(), parts[1].len());
                    for p in &parts {
                        let lo = p.iter().filter(|&&k| centroid(k)[axis] < 1.0).count();
                        assert!(lo == 0 || lo == p.len(), "each part on one side of the plane");
                    }
                }
            }
            if !tets {
                let d = 1.0 / 3.0;
                let diag = principal3([d, d, d, d, d, d]);
                for (never_split, want) in [(false, false), (true, true)] {
                    let view = FanView3 { fan: &fan, x: [1.0; 3], centroids: &centroids, face_normals: &normals, never_split, principal: diag };
                    assert_eq!(Sigma1Nearest::default().propose_3d(&view, &failed(Tension, &[])).unwrap().is_some(), want, "diagonal, never_split {never_split}");
                }
            }
            // A check that did not fail proposes nothing.
            let view = FanView3 { fan: &fan, x: [1.0; 3], centroids: &centroids, face_normals: &normals, never_split: true, principal: principal3([1.0, 0.0, 0.0, 0.0, 0.0, 0.0]) };
            assert_eq!(Sigma1Nearest::default().propose_3d(&view, &FailureCheck::default()), Ok(None));
        }
    }
}
