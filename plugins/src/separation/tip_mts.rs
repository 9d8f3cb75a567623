//! `tip_mts` (ours, issue 34; docs/paths.md): a separation rule that grows crack tips in the
//! direction of the maximum tangential stress, off the mesh's edges, by crack-tip node
//! relocation. Not the paper's: `sigma1_nearest` stays the default.
//!
//! **Away from crack tips** (a point that fails far from every tip: initiation in the body,
//! at a corner) it is `sigma1_nearest` (the paper's edge rule, same cap option).
//!
//! **At a crack tip** (a point where one crack face ends, `flem_core::cracking::path`), and for
//! a failed point within `route` element sizes of one (it grows that tip instead of starting a
//! crack of its own beside it). A failed point on a crack (it has split), or joined to one by
//! an edge, farther from every tip is not cut: the method grows cracks at their tips only (no
//! branches off the faces, no slivers cut beside them).
//! 1. *Direction.* `K_I` and `K_II` by the interaction integral on the domain
//!    `radius h / 2 < r < radius h` (`check::sif::domain_sif`, `h` the element size at the tip;
//!    then on half that radius), and the maximum tangential stress kink (Erdogan & Sih 1963,
//!    rationalised form):
//!
//!    ```text
//!    theta = 2 atan( -2 r / (1 + sqrt(1 + 8 r^2)) ),   r = K_II / K_I   (-0.05 |K_II| <= K_I <= 0: K_I = 0)
//!    ```
//!
//!    measured from the crack's direction at the tip; the crack is to follow the line through
//!    the tip at that angle. A closed tip (`K_I < 0`) is not cut. A tip grown along such a
//!    line keeps to it (aiming one element size ahead on it) until the crack behind it is
//!    straight over `every` domain radii (default 1; 2 before session 17); then the factors are evaluated again (on
//!    `reradius` times the domain) and a new line starts there (a curved path as a chain of
//!    straight pieces). A tip at most `staircase h` off its line (partial moves: quads, a
//!    structured grid) counts as on it, and is evaluated in the line's frame with the faces
//!    allowed `2 staircase h` off its axis (`check::sif::domain_sif_tol`; ours, session 15:
//!    without it a staircase path never turned after its first kink). Where the integral is
//!    refused (another tip or the boundary inside the domain) the tip keeps to its line, or
//!    goes straight on.
//! 2. *Link.* Among the edges joined at the tip, the one whose direction is nearest the aim
//!    (ahead of the tip) is cut, with the crack face ending there (a closed fan falls in two).
//!    A tip on the boundary (the crack has reached it) is cut along its face alone: the crack
//!    runs through.
//! 3. *Relocation.* Before the cut, the link's far node moves to the foot of its perpendicular
//!    on the line, or `max_move` times the link's length towards it when the foot is farther
//!    (a structured Q4 grid, whose fans have no link near 45 deg, then follows the line as a
//!    staircase within about half an element of it). The core
//!    refuses a move of a point that carries a boundary condition (a support, a point load, a
//!    prescribed velocity or displacement, an end of a loaded face: a mask built once at set-up,
//!    session 18), of a boundary point, of a point on a crack face, or one that inverts or
//!    flattens an element (a corner below 15 deg); a move the element check refuses is tried
//!    at 7/8, 3/4, ... down to 1/4 of its length (session 25) and the largest admitted is
//!    made; when none is, the core cuts the link where it is. The
//!    moved node's elements are rebuilt (geometry, gradients, lumped masses:
//!    `Model::move_point`); checkpoints keep the moves.
//!
//! Limits: linear elastic q4/t3 models only at tips (the integral's limits, docs/paths.md);
//! a held point (support, load) on the path is not moved, so the crack passes it on the mesh's
//! own node (partial staircase there); the tip's lines and moves are replayed by checkpoints.
//!
//! Parameters: `radius` (element sizes, default 4), `max_move` (fraction of the link length,
//! default 0.5), `route` (element sizes, default 3), `relocate` (default true; false: the
//! direction only, cut along the nearest link), `cap_unsplit_boundary` (as `sigma1_nearest`),
//! `staircase` (element sizes, default 0.5; 0: a tip must be on its line to 1e-6 h), `every`
//! (domain radii, default 1), `reradius` (fraction of `radius`, default 1), `shrink` (element
//! sizes, default 2; 0: off) and `slide` (default true), session 17: near the boundary, a
//! re-evaluation whose domain leaves the body uses the largest smaller one down to `shrink h`,
//! and the last link's node on a straight stretch of the boundary slides along it to where the
//! line meets it (the crack leaves the body there, not at the nearest boundary node). All ours.
//! `piece` (fraction of the specimen's size, default 0: off; ours, session 19): a tip is
//! evaluated again once the crack is straight over `min(every reradius radius h, piece L)`
//! (`L` the larger side of the mesh's bounding box), so that a curved path is a chain of
//! pieces of about the same length on every mesh (with `every` alone the pieces are `4 h`, a
//! first-order error in `h` where the path curves). The domain stays `reradius radius h`; when
//! it still reaches behind the line's origin it is evaluated in the line's frame with the
//! faces allowed `2 staircase h` off its axis (a larger previous turn is refused and the tip
//! keeps to its line until the domain has cleared it).
//!
//! `shield` (element sizes at the failed point, default 0: off; ours, session 27): a failed
//! point that no tip takes (farther than `route` from every tip) and that lies within `shield`
//! element sizes of a crack edge (`cracking::path::near_crack`: the Euclidean distance to any
//! edge separated at one end or both, with a relative margin of 1e-9) is not cut; this includes
//! failed points ahead of a tip between `route` and `shield`. Without it such a point starts a crack by the
//! edge rule, and a crack with cohesive faces grows a band of parallel cracks beside it (the
//! L-panel's fine grids, docs/paths.md "Session 27"). The exclusion radius of crack-tracking
//! schemes (Cervera & Chiumenti 2006; the nonlocal check's `exclusion` does the same for the
//! paper's rules by routing to the nearest tip instead). `shield_length` (the mesh's unit, default
//! 0: off; ours) gives the same radius as a length, the same on every mesh and in every region of
//! a graded one; with both keys the larger radius counts. The shielded point keeps its stress above
//! the strength (counted in `beyond_criterion`).
//!
//! `fork_ratio` (0: off, the default; ours, session 31, experimental: docs/dynamic.md "Session
//! 31"): a tip forks into two branches when the hoop stress ahead of it peaks off its axis on
//! both sides, the signal of a running crack about to branch (Yoffe 1951: above about 0.6 c_s the
//! hoop stress of a running crack peaks off its axis). At each tip evaluation, with the tip's
//! direction `dir`:
//!
//! ```text
//! S(bin)  = mean over elements with centroid at r in [1, 4] h, theta in the bin, of
//!           sigma_thetatheta (the linear elastic stress at the centroid; 18 bins of 10 deg
//!           over the forward half-plane, `check::sif::hoop_profile`)
//! S_axis  = mean of the two bins within 10 deg of the axis  (> 0)
//! fork   <=> min( max_{theta <= -30 deg} S, max_{theta >= 30 deg} S ) >= fork_ratio S_axis
//! ```
//!
//! and no other tip lies within `FORK_CLEAR` (8) element sizes. A forking tip cuts its face and
//! two links in one cut, one on each side of `dir`: the link nearest `dir +- fork_angle_deg`
//! (default 15 deg), within `FORK_LINK_TOL` (30 deg) of it, whose far point has not split. Its
//! point falls in three, each branch's far node moves onto its line as a tip's does, and each
//! branch is a tip with its own line from there. `fork_angle_deg` is a setting, not a result.
//! Limits: linear elastic `t3` and `q4` elements near the tip (other kinds: no fork). The paths
//! after a fork are not yet trustworthy: the branches wander, and one of them often arrests.
//!
//! `anchor` (default false; ours, session 35): a re-evaluated tip's new line starts at the
//! tip's foot on its previous line (`o + ((x_q - o) . d) d` for the line through `o` along the
//! unit vector `d`), not at the tip `x_q` itself, which lies up to `staircase h` off that line
//! where the moves are partial (quads). The lines then form one continuous polyline, and the
//! staircase's offsets do not add up from one piece to the next; the tip aims one element size
//! ahead of its foot on the new line. A tip on its line to 1e-6 h starts the new line where it
//! is, as without the key, and so do a fork's two branches (`fork_ratio`).
//!
//! The setting measured for must-shows 2 and 3 (ours, session 25; docs/paths.md "Session 25"):
//! `every = 1.25`, `piece = 0.05`, `shrink = 1.5` (all 72 kink tips within 5 deg, the shear
//! series within 1.31 % Hausdorff). Session 35's (S35, docs/paths.md "Session 35") adds
//! `anchor = true` and `shrink = 1.0`: the kinks the same, the shear series on unstructured quad
//! meshes within 1.41 % (2.72 % with session 25's), the beam within 0.49 %. Neither is the
//! default: the keys' default values are those of sessions 14-19 (their results moved a little
//! with session 25's finer move fractions).
//!
//! ```toml
//! [cracking.separation]
//! type = "tip_mts"   # ours (issue 34): MTS direction at crack tips, node relocation
//! radius = 4.0
//! max_move = 0.5
//! route = 3.0
//! staircase = 0.5
//! every = 1.0
//! reradius = 1.0
//! shrink = 2.0
//! slide = true
//! piece = 0.0        # ours (session 19): 0 = off; e.g. 0.05 with shrink = 1.5 (docs/paths.md)
//! shield = 0.0       # ours (session 27): 0 = off (element sizes)
//! shield_length = 0.0   # ours (session 27): 0 = off (the mesh's unit; 0.04 m in the L-panel scenes)
//! fork_ratio = 0.0   # ours (session 31, experimental): 0 = off; e.g. 1.5 (docs/dynamic.md)
//! fork_angle_deg = 15.0  # ours (session 31): the branches' angle to the tip's direction (deg)
//! anchor = false     # ours (session 35): true = a new line starts on the previous one
//! ```
use serde::{Deserialize, Serialize};

use flem_core::plugin::traits::{FailureCheck, FanView, ParamError, Proposal, SeparationRule, TipContext, TipFork, TipPlan};

use super::sigma1_nearest::propose_along;
use crate::check::sif::{domain_sif, domain_sif_tol, hoop_profile, mts_angle, CrackTip, SifError};

fn four() -> f64 {
    4.0
}
fn half() -> f64 {
    0.5
}
fn three() -> f64 {
    3.0
}
fn one() -> f64 {
    1.0
}
fn two() -> f64 {
    2.0
}
fn yes() -> bool {
    true
}

/// The path method's rule (see the module docs).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TipMts {
    #[serde(default = "four")]
    pub radius: f64,
    #[serde(default = "half")]
    pub max_move: f64,
    #[serde(default = "three")]
    pub route: f64,
    #[serde(default = "yes")]
    pub relocate: bool,
    #[serde(default)]
    pub cap_unsplit_boundary: bool,
    /// A tip at most this many element sizes off its line is evaluated again in the line's
    /// frame (ours; 0: only a tip on its line to 1e-6 h, the first version).
    #[serde(default = "half")]
    pub staircase: f64,
    /// A tip grown along a line is evaluated again once the crack behind it is straight over
    /// this many domain radii (ours; default 1 since session 17, was 2).
    #[serde(default = "one")]
    pub every: f64,
    /// The domain of a re-evaluation along a line, as a fraction of `radius` (ours).
    #[serde(default = "one")]
    pub reradius: f64,
    /// Near the boundary (ours, session 17): when a re-evaluation's domain leaves the body, the
    /// largest smaller domain (`0.8^k` of it) down to `shrink` element sizes that stays inside
    /// is used, once the crack is straight over `every` of *its* radii. 0: off (the tip keeps
    /// to its line up to the boundary, as before). Default 2 (session 17).
    #[serde(default = "two")]
    pub shrink: f64,
    /// Ours (session 17): the last link's far node, when it lies on a straight stretch of the
    /// outer boundary and carries no boundary condition (session 18), slides along it towards where the line meets the boundary (at most
    /// `max_move` of the link's length; `path::slides_along_boundary`). false: a boundary node
    /// never moves (the crack leaves the body at the nearest node, as before). Default true
    /// (session 17).
    #[serde(default = "yes")]
    pub slide: bool,
    /// Ours (session 19): the longest straight piece between two evaluations along a line, as a
    /// fraction of the specimen's size (the larger side of the mesh's bounding box), the same
    /// length on every mesh. A tip is evaluated again once the crack is straight over
    /// `min(every reradius radius h, piece size)`; the domain stays `reradius radius h`. When
    /// that domain still reaches behind the line's origin (the previous turn), it is evaluated
    /// in the line's frame with the faces allowed `2 staircase h` off its axis (as a staircase
    /// tip); a domain that holds a larger turn is refused, and the tip keeps to its line. 0:
    /// off (pieces of `every` domain radii, the default).
    #[serde(default)]
    pub piece: f64,
    /// Ours (session 27): a failed point that no tip takes (farther than `route` from every tip)
    /// and that lies within `shield` element sizes (at the point) of a crack edge is not cut
    /// (`SeparationRule::shield_distance`): no crack starts beside a crack. 0: off (the default;
    /// such a point starts a crack by the edge rule, as before).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub shield: f64,
    /// Ours (session 27): the shield as a length in the mesh's unit (the same radius on every
    /// mesh and in every region of a graded mesh); with `shield` too, the larger of the two.
    /// 0: off (the default).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub shield_length: f64,
    /// Ours (session 31): a tip forks into two when the hoop stress on the ring `FORK_RING`
    /// peaks off its axis on both sides by this factor over the axis value (`fork_signal`).
    /// 0: off (the default; no tip forks, as before).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub fork_ratio: f64,
    /// Ours (session 31): the two branches of a fork leave at `+- fork_angle_deg` degrees from the
    /// tip's direction (a setting, not a result: docs/dynamic.md).
    #[serde(default = "fifteen", skip_serializing_if = "is_fifteen")]
    pub fork_angle_deg: f64,
    /// Ours (session 35): a re-evaluated tip's new line starts at the tip's foot on its previous
    /// line, not at the tip (a tip up to `staircase h` off its line): the lines form one
    /// continuous polyline, and the staircase's offsets do not add up from piece to piece.
    /// false: the new line starts at the tip (the default, as before).
    #[serde(default, skip_serializing_if = "is_false")]
    pub anchor: bool,
}

fn is_false(v: &bool) -> bool {
    !*v
}

fn fifteen() -> f64 {
    15.0
}
fn is_fifteen(v: &f64) -> bool {
    *v == 15.0
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

impl Default for TipMts {
    fn default() -> Self {
        TipMts {
            radius: 4.0,
            max_move: 0.5,
            route: 3.0,
            relocate: true,
            cap_unsplit_boundary: false,
            staircase: 0.5,
            every: 1.0,
            reradius: 1.0,
            shrink: 2.0,
            slide: true,
            piece: 0.0,
            shield: 0.0,
            shield_length: 0.0,
            fork_ratio: 0.0,
            fork_angle_deg: 15.0,
            anchor: false,
        }
    }
}

/// The MTS kink angle (radians) of `K_I`, `K_II` ([`mts_angle`]), with a `K_I` at or below zero
/// by at most [`CLOSED_TOL`] of `|K_II|` taken as zero: a tip loaded in shear whose faces press
/// together by round-off or by a slight closure kinks at the pure mode II angle (-70.5 deg for
/// `K_II > 0`) instead of not at all. `None`: a closed tip (`K_I` below that), or no load.
pub fn kink_angle(k1: f64, k2: f64) -> Option<f64> {
    let k1 = if k1 <= 0.0 && -k1 <= CLOSED_TOL * k2.abs() { 0.0 } else { k1 };
    mts_angle(k1, k2)
}

/// See [`kink_angle`].
pub const CLOSED_TOL: f64 = 0.05;

fn angle_of(v: [f64; 2]) -> f64 {
    v[1].atan2(v[0])
}

impl TipMts {
    /// The line (origin, direction) the tip is to follow and the direction to aim at from the
    /// tip; `None`: a closed tip.
    pub fn line(&self, ctx: &TipContext) -> Option<([f64; 2], f64, f64)> {
        let m = ctx.model;
        let q = ctx.fan.point;
        let xq = m.mesh.points[q.idx()];
        let p = m.topo.other_end(ctx.face, q);
        let xp = m.mesh.points[p.idx()];
        let (dx, dy) = (xq[0] - xp[0], xq[1] - xp[1]);
        let len = dx.hypot(dy);
        let e1 = [dx / len, dy / len];
        // A tip grown along a line is evaluated again only once the crack is straight over
        // twice the domain's radius behind it (nearer a kink the integral of a small domain
        // misreads the kinked field: measured, it turned the beta = 30 deg T3 paths by 12 deg
        // after 2.5 element sizes).
        // A staircase tip (ours, `staircase`): a tip off its line by at most `staircase h` (a
        // partial move: quads, a structured grid) is evaluated in the line's frame, the faces
        // behind it allowed `2 staircase h` off that frame's axis (`domain_sif_tol`). A tip on
        // its line to 1e-6 h is evaluated as before (its own face's direction, faces straight
        // to 1e-6 r_out).
        let mut frame: Option<[f64; 2]> = None;
        // Whether the tip lies off its line by more than 1e-6 h (a staircase tip): `anchor`
        // acts on it only.
        let mut off_line = false;
        let straight = match ctx.planned {
            None => f64::INFINITY,
            Some((o, dir)) => {
                let (ox, oy) = (xq[0] - o[0], xq[1] - o[1]);
                let off = (ox * dir.sin() - oy * dir.cos()).abs();
                if off <= 1e-6 * ctx.h {
                    ox.hypot(oy)
                } else if off <= self.staircase * ctx.h {
                    frame = Some([dir.cos(), dir.sin()]);
                    off_line = true;
                    ox * dir.cos() + oy * dir.sin()
                } else {
                    0.0
                }
            }
        };
        // `piece` (ours, session 19): a re-evaluation due before the domain has cleared the
        // line's origin sees the previous turn inside it; it is evaluated in the line's frame
        // with the staircase's tolerance (a larger turn is refused: the tip keeps to its line).
        let piece = self.piece_length(ctx);
        if let (None, Some((_, dir))) = (frame, ctx.planned) {
            if piece.is_finite() && straight < self.reradius * self.radius * ctx.h {
                frame = Some([dir.cos(), dir.sin()]);
            }
        }
        let e1 = frame.unwrap_or(e1);
        let tip = CrackTip { point: q.idx(), x: xq, dir: e1, edge: ctx.face.idx(), h: ctx.h, faces: 1 };
        let re = [self.reradius];
        let radii: &[f64] = if ctx.planned.is_none() { &[1.0, 0.5] } else { &re };
        // The last refused domain (its radius, and whether it left the body): `shrink` would
        // evaluate the same domain again first (the same function of the same arguments).
        let mut refused: Option<(f64, bool)> = None;
        // `anchor` (ours): the new line of a staircase tip starts at the tip's foot on its
        // previous line; a tip on its line to 1e-6 h starts it where it is, as without the key.
        let start = match ctx.planned {
            Some((o, dir)) if self.anchor && off_line => {
                let dh = [dir.cos(), dir.sin()];
                let s = (xq[0] - o[0]) * dh[0] + (xq[1] - o[1]) * dh[1];
                Some([o[0] + s * dh[0], o[1] + s * dh[1]])
            }
            _ => None,
        };
        for f in radii.iter().map(|f| f * self.radius).filter(|f| (self.every * f * ctx.h).min(piece) <= straight) {
            let r_out = f * ctx.h;
            let d = match frame {
                None => domain_sif(m, ctx.u, &[], &[], &tip, 0.5 * r_out, r_out),
                Some(_) => domain_sif_tol(m, ctx.u, &[], &[], &tip, 0.5 * r_out, r_out, 2.0 * self.staircase * ctx.h),
            };
            match d {
                Ok(d) => {
                    let th = kink_angle(d.k1, d.k2)?;
                    let dir = angle_of(e1) + th;
                    return Some(self.new_line(ctx, xq, start, dir));
                }
                Err(e) => refused = Some((r_out, matches!(e, SifError::DomainLeavesBody { .. }))),
            }
        }
        if let Some(th) = self.near_boundary_kink(ctx, &tip, frame.is_some(), straight, piece, refused) {
            let dir = angle_of(e1) + th?;
            return Some(self.new_line(ctx, xq, start, dir));
        }
        if let Some((o, dir)) = ctx.planned {
            // Not evaluated again: the tip keeps to its line.
            return Some(self.new_line(ctx, xq, Some(o), dir));
        }
        let dir = angle_of(e1);
        Some((xq, dir, dir))
    }
}

impl TipMts {
    /// The line along `dir` that the tip `xq` is to follow: (origin, direction, aim). Without
    /// `start` the line starts at the tip and the tip aims along it (a new line, as before
    /// `anchor`). With one it starts at `start` (the line kept, or with `anchor` a staircase
    /// tip's foot on its previous line), and the tip aims one element size ahead of its foot on
    /// the line.
    fn new_line(&self, ctx: &TipContext, xq: [f64; 2], start: Option<[f64; 2]>, dir: f64) -> ([f64; 2], f64, f64) {
        let Some(start) = start else { return (xq, dir, dir) };
        let dh = [dir.cos(), dir.sin()];
        let s = (xq[0] - start[0]) * dh[0] + (xq[1] - start[1]) * dh[1];
        (start, dir, angle_of([start[0] + (s + ctx.h) * dh[0] - xq[0], start[1] + (s + ctx.h) * dh[1] - xq[1]]))
    }
}

impl TipMts {
    /// `shrink` (ours, session 17): the kink angle on the largest domain `0.8^k reradius radius h`
    /// (k >= 1, down to `shrink h`) that stays inside the body, when the re-evaluation's own
    /// domain leaves it and the crack is straight over `every` of the smaller radii behind the
    /// tip. `None`: not used (off, a first evaluation, the full domain not refused for the
    /// boundary, or no smaller domain fits); `Some(None)`: a closed tip.
    /// `refused`: the caller's last refused domain (radius, left the body), reused when it is
    /// this one's full domain.
    fn near_boundary_kink(&self, ctx: &TipContext, tip: &CrackTip, staircase: bool, straight: f64, piece: f64, refused: Option<(f64, bool)>) -> Option<Option<f64>> {
        if self.shrink <= 0.0 || ctx.planned.is_none() {
            return None;
        }
        let m = ctx.model;
        let tol = 2.0 * self.staircase * ctx.h;
        let eval = |r: f64| if staircase { domain_sif_tol(m, ctx.u, &[], &[], tip, 0.5 * r, r, tol) } else { domain_sif(m, ctx.u, &[], &[], tip, 0.5 * r, r) };
        let full = self.reradius * self.radius * ctx.h;
        if (self.every * full).min(piece) > straight {
            return None;
        }
        let leaves = match refused {
            Some((r, leaves)) if r.to_bits() == full.to_bits() => leaves,
            _ => matches!(eval(full), Err(SifError::DomainLeavesBody { .. })),
        };
        if !leaves {
            return None;
        }
        let mut r = 0.8 * full;
        while r >= self.shrink * ctx.h && (self.every * r).min(piece) <= straight {
            match eval(r) {
                Ok(d) => return Some(kink_angle(d.k1, d.k2)),
                Err(SifError::DomainLeavesBody { .. }) => r *= 0.8,
                Err(_) => return None,
            }
        }
        None
    }
}

impl TipMts {
    /// `piece` (ours, session 19) in model units: `piece` times the larger side of the mesh's
    /// bounding box (one pass over the points, only when `piece` is on: negligible beside the
    /// interaction integral of the same evaluation); infinite when off.
    fn piece_length(&self, ctx: &TipContext) -> f64 {
        if self.piece <= 0.0 {
            return f64::INFINITY;
        }
        let (lo, hi) = ctx.model.mesh.bounding_box();
        self.piece * (hi[0] - lo[0]).max(hi[1] - lo[1])
    }

    /// `slide` (ours, session 17): the target of the boundary node `r` sliding along its straight
    /// boundary stretch towards where the line (`origin`, direction `dh`) meets it, at most
    /// `max_move` link lengths, and the slide's length. `None`: off, `r` interior, at a corner,
    /// or the line parallel to the boundary.
    fn boundary_slide(&self, ctx: &TipContext, r: flem_core::ids::PointId, origin: [f64; 2], dh: [f64; 2], len: f64) -> Option<([f64; 2], f64)> {
        if !self.slide {
            return None;
        }
        let topo = &ctx.model.topo;
        let x = &ctx.model.mesh.points;
        let xr = x[r.idx()];
        let ends: Vec<[f64; 2]> = topo.point_edges.row(r.idx()).iter().filter(|&&e| topo.edges[e.idx()].sides[1].is_none()).map(|&e| x[topo.other_end(e, r).idx()]).collect();
        if ends.len() != 2 {
            return None;
        }
        let a = [ends[0][0] - xr[0], ends[0][1] - xr[1]];
        let la = a[0].hypot(a[1]);
        let b = [a[0] / la, a[1] / la];
        let den = b[0] * dh[1] - b[1] * dh[0];
        if den.abs() < 1e-6 {
            return None;
        }
        // origin + s dh = xr + t b  =>  t = cross(origin - xr, dh) / cross(b, dh).
        let w = [origin[0] - xr[0], origin[1] - xr[1]];
        let t = (w[0] * dh[1] - w[1] * dh[0]) / den;
        let t = t.clamp(-self.max_move * len, self.max_move * len);
        Some(([xr[0] + t * b[0], xr[1] + t * b[1]], t.abs()))
    }
}

#[typetag::serde(name = "tip_mts")]
impl SeparationRule for TipMts {
    fn validate(&self) -> Result<(), ParamError> {
        if !(self.radius.is_finite() && self.radius >= 1.0 && self.radius <= 50.0) {
            return Err(ParamError::new("radius", format!("= {} is incorrect; it must be in [1, 50] (element sizes)", self.radius)));
        }
        if !(self.max_move.is_finite() && (0.0..=0.7).contains(&self.max_move)) {
            return Err(ParamError::new("max_move", format!("= {} is incorrect; it must be in [0, 0.7] (fraction of the link's length)", self.max_move)));
        }
        if !(self.route.is_finite() && (0.0..=10.0).contains(&self.route)) {
            return Err(ParamError::new("route", format!("= {} is incorrect; it must be in [0, 10] (element sizes)", self.route)));
        }
        if !(self.staircase.is_finite() && (0.0..=1.0).contains(&self.staircase)) {
            return Err(ParamError::new("staircase", format!("= {} is incorrect; it must be in [0, 1] (element sizes)", self.staircase)));
        }
        if !(self.reradius.is_finite() && (0.25..=1.0).contains(&self.reradius) && self.reradius * self.radius >= 1.0) {
            return Err(ParamError::new("reradius", format!("= {} is incorrect; it must be in [0.25, 1], with reradius * radius >= 1", self.reradius)));
        }
        if !(self.shrink.is_finite() && (self.shrink == 0.0 || (1.0..=self.radius).contains(&self.shrink))) {
            return Err(ParamError::new("shrink", format!("= {} is incorrect; it must be 0 (off) or in [1, radius] (element sizes)", self.shrink)));
        }
        if !(self.piece.is_finite() && (0.0..=1.0).contains(&self.piece)) {
            return Err(ParamError::new("piece", format!("= {} is incorrect; it must be 0 (off) or in (0, 1] (fraction of the specimen's size)", self.piece)));
        }
        if !(self.shield.is_finite() && (0.0..=20.0).contains(&self.shield)) {
            return Err(ParamError::new("shield", format!("= {} is incorrect; it must be 0 (off) or in (0, 20] (element sizes)", self.shield)));
        }
        if !(self.shield_length.is_finite() && self.shield_length >= 0.0) {
            return Err(ParamError::new("shield_length", format!("= {} is incorrect; it must be 0 (off) or a positive length (the mesh's unit)", self.shield_length)));
        }
        if !(self.fork_ratio.is_finite() && (self.fork_ratio == 0.0 || self.fork_ratio > 1.0)) {
            return Err(ParamError::new("fork_ratio", format!("= {} is incorrect; it must be 0 (off) or greater than 1", self.fork_ratio)));
        }
        if !(self.fork_angle_deg.is_finite() && self.fork_angle_deg > 0.0 && self.fork_angle_deg < 90.0) {
            return Err(ParamError::new("fork_angle_deg", format!("= {} is incorrect; it must be in (0, 90) degrees", self.fork_angle_deg)));
        }
        if !(self.every.is_finite() && (1.0..=10.0).contains(&self.every)) {
            return Err(ParamError::new("every", format!("= {} is incorrect; it must be in [1, 10] (domain radii)", self.every)));
        }
        Ok(())
    }

    fn propose(&self, fan: &FanView, failure: &FailureCheck) -> Option<Proposal> {
        failure.mode?;
        propose_along(fan, fan.principal.theta1, self.cap_unsplit_boundary)
    }

    fn grows_tips(&self) -> bool {
        true
    }

    fn route_radius(&self) -> f64 {
        self.route
    }

    fn shield_distance(&self, h: f64) -> f64 {
        (self.shield * h).max(self.shield_length)
    }

    fn propose_tip(&self, ctx: &TipContext) -> Option<TipPlan> {
        let (origin, dir, aim) = self.line(ctx)?;
        let topo = &ctx.model.topo;
        if topo.point_edges.row(ctx.fan.point.idx()).iter().any(|&e| topo.edges[e.idx()].sides[1].is_none()) {
            // The crack has reached the boundary: it runs through, along its face alone (no
            // link back into the body).
            return Some(TipPlan { edges: vec![ctx.face], relocate: None, origin, direction: dir, fork: None });
        }
        if let Some(plan) = self.fork_plan(ctx, dir) {
            return Some(plan);
        }
        let (edge, relocate, _) = self.link_toward(ctx, origin, dir, aim, 0.0)?;
        Some(TipPlan { edges: vec![edge, ctx.face], relocate, origin, direction: dir, fork: None })
    }
}

impl TipMts {
    /// The link at the tip nearest the direction `aim` (smaller edge id on a tie), its angle to
    /// `aim`, and the move of its far node onto the line (`origin`, direction `dir`): the foot
    /// of its perpendicular, at most `max_move` of the link's length, or its slide along the
    /// boundary (`boundary_slide`). `side` (a fork's branches): `+1.0` takes only links to the
    /// left of `dir` (counter-clockwise), `-1.0` only those to its right, `0.0` any. `None`: no
    /// link.
    #[allow(clippy::type_complexity)]
    fn link_toward(&self, ctx: &TipContext, origin: [f64; 2], dir: f64, aim: f64, side: f64) -> Option<(flem_core::ids::EdgeId, Option<(flem_core::ids::PointId, [f64; 2])>, f64)> {
        let m = ctx.model;
        let q = ctx.fan.point;
        let xq = m.mesh.points[q.idx()];
        let (ah, dh) = ([aim.cos(), aim.sin()], [dir.cos(), dir.sin()]);
        let mut best: Option<(f64, usize)> = None;
        for (i, l) in ctx.fan.links.iter().enumerate() {
            if l.edge == ctx.face {
                continue;
            }
            let r = m.topo.other_end(l.edge, q);
            let xr = m.mesh.points[r.idx()];
            let v = [xr[0] - xq[0], xr[1] - xq[1]];
            if side * (dh[0] * v[1] - dh[1] * v[0]) < 0.0 || (side != 0.0 && dh[0] * v[1] - dh[1] * v[0] == 0.0) {
                continue;
            }
            let c = (v[0] * ah[0] + v[1] * ah[1]) / v[0].hypot(v[1]);
            let a = c.clamp(-1.0, 1.0).acos();
            if best.is_none_or(|(b, j)| a < b - 1e-12 || (a <= b + 1e-12 && l.edge < ctx.fan.links[j].edge)) {
                best = Some((a, i));
            }
        }
        let (a, i) = best?;
        let edge = ctx.fan.links[i].edge;
        let r = m.topo.other_end(edge, q);
        let xr = m.mesh.points[r.idx()];
        let len = (xr[0] - xq[0]).hypot(xr[1] - xq[1]);
        // The far node onto the line: the foot of its perpendicular, ahead of the tip.
        let s = (xr[0] - origin[0]) * dh[0] + (xr[1] - origin[1]) * dh[1];
        let sq = (xq[0] - origin[0]) * dh[0] + (xq[1] - origin[1]) * dh[1];
        let foot = [origin[0] + s * dh[0], origin[1] + s * dh[1]];
        let mv = (foot[0] - xr[0]).hypot(foot[1] - xr[1]);
        // At most `max_move` of the link's length towards the foot (a mesh without a link near
        // the line, such as a structured Q4 grid at 45 deg, follows it as a staircase whose
        // steps are at most `(1 - max_move)` link lengths off it).
        let f = if mv > self.max_move * len { self.max_move * len / mv } else { 1.0 };
        let to = [xr[0] + f * (foot[0] - xr[0]), xr[1] + f * (foot[1] - xr[1])];
        let (to, mv) = match self.boundary_slide(ctx, r, origin, dh, len) {
            Some((t, d)) => (t, d),
            None => (to, mv),
        };
        let relocate = (self.relocate && a > 1e-6 && s - sq > 0.25 * len && mv > 1e-9 * len).then_some((r, to));
        Some((edge, relocate, a))
    }

    /// `fork_ratio` (ours, session 31): whether the tip branches, and the plan of its two links,
    /// one on each side of `dir`, nearest `dir +- fork_angle_deg` (module docs). `None`: off;
    /// another tip within `FORK_CLEAR` element sizes; a non-linear element or another kind
    /// within the ring; no signal (`fork_signal`); a side without a link within
    /// `FORK_LINK_TOL` of its aim; or a link whose far point has split already (the branch would
    /// cut into a crack).
    fn fork_plan(&self, ctx: &TipContext, dir: f64) -> Option<TipPlan> {
        if self.fork_ratio <= 0.0 {
            return None;
        }
        let m = ctx.model;
        let q = ctx.fan.point;
        let xq = m.mesh.points[q.idx()];
        // No fork while another tip (a sibling of the last fork) lies within `FORK_CLEAR h`.
        let near = |p: &flem_core::ids::PointId| {
            let x = m.mesh.points[p.idx()];
            *p != q && (x[0] - xq[0]).hypot(x[1] - xq[1]) < FORK_CLEAR * ctx.h
        };
        if ctx.tips.iter().any(near) {
            return None;
        }
        let tip = CrackTip { point: q.idx(), x: xq, dir: [dir.cos(), dir.sin()], edge: ctx.face.idx(), h: ctx.h, faces: 1 };
        let bins = hoop_profile(m, ctx.u, &tip, FORK_RING[0] * ctx.h, FORK_RING[1] * ctx.h)?;
        if !fork_signal(&bins, self.fork_ratio) {
            return None;
        }
        let a = self.fork_angle_deg.to_radians();
        let (ea, ra, erra) = self.link_toward(ctx, xq, dir + a, dir + a, 1.0)?;
        let (eb, rb, errb) = self.link_toward(ctx, xq, dir - a, dir - a, -1.0)?;
        let split = |e: flem_core::ids::EdgeId| m.topo.point_clusters[m.topo.other_end(e, q).idx()].len() > 1;
        if erra.max(errb) > FORK_LINK_TOL.to_radians() || split(ea) || split(eb) {
            return None;
        }
        Some(TipPlan { edges: vec![ea, ctx.face], relocate: ra, origin: xq, direction: dir + a, fork: Some(TipFork { edge: eb, relocate: rb, origin: xq, direction: dir - a }) })
    }
}

/// The ring of `fork_ratio`'s hoop profile, in element sizes at the tip (ours, session 31).
pub const FORK_RING: [f64; 2] = [1.0, 4.0];

/// No tip forks while another tip lies within this many element sizes (ours, session 31).
pub const FORK_CLEAR: f64 = 8.0;

/// A fork needs on each side of the tip's direction a link within this many degrees of its
/// branch's aim (ours, session 31).
pub const FORK_LINK_TOL: f64 = 30.0;

/// The fork test on a hoop profile ([`hoop_profile`]'s 18 bins of 10 deg from -90 deg): the
/// mean of the two bins within 10 deg of the axis is positive, and on each side the largest bin
/// mean at 30 deg or more from the axis is at least `ratio` times it. Empty bins do not count;
/// an empty axis bin or an empty side gives no fork.
pub fn fork_signal(bins: &[(f64, u32); 18], ratio: f64) -> bool {
    let mean = |k: usize| (bins[k].1 > 0).then(|| bins[k].0 / bins[k].1 as f64);
    let (Some(a), Some(b)) = (mean(8), mean(9)) else { return false };
    let on = 0.5 * (a + b);
    if on <= 0.0 {
        return false;
    }
    let side = |ks: std::ops::RangeInclusive<usize>| ks.filter_map(mean).fold(f64::NEG_INFINITY, f64::max);
    side(0..=5).min(side(12..=17)) >= ratio * on
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `fork_signal` on profiles made by hand (reference: its definition in the docs). A flat
    /// profile and flanks below the ratio do not fork; flanks at or above it on both sides do;
    /// one side alone does not; a non-positive or empty axis does not; bins within 30 deg of the
    /// axis (other than the axis's own two) do not count.
    #[test]
    fn fork_signal_reads_the_flanks_against_the_axis() {
        let flat = [(1.0, 1u32); 18];
        assert!(!fork_signal(&flat, 1.5));
        assert!(fork_signal(&flat, 1.0), "why `validate` asks a ratio above 1");
        let mut p = flat;
        p[0] = (1.6, 1);
        p[17] = (3.0, 2);
        assert!(fork_signal(&p, 1.5), "1.6 and 1.5 times the axis");
        p[17] = (2.8, 2);
        assert!(!fork_signal(&p, 1.5), "one side at 1.4");
        let mut q = flat;
        q[6] = (5.0, 1);
        q[11] = (5.0, 1);
        assert!(!fork_signal(&q, 1.5), "bins at 20-30 deg do not count");
        q[5] = (5.0, 1);
        q[12] = (5.0, 1);
        assert!(fork_signal(&q, 1.5), "bins at 30-40 deg do");
        let mut r = q;
        r[8] = (-1.0, 1);
        r[9] = (-1.0, 1);
        assert!(!fork_signal(&r, 1.5), "axis in compression");
        r[8] = (1.0, 0);
        r[9] = (1.0, 1);
        assert!(!fork_signal(&r, 1.5), "an empty axis bin");
        let mut e = q;
        for b in e.iter_mut().take(6) {
            *b = (0.0, 0);
        }
        assert!(!fork_signal(&e, 1.5), "an empty side");
    }

    /// Parameters out of range are refused by name; the defaults validate.
    #[test]
    fn validate_names_the_key() {
        assert!(TipMts::default().validate().is_ok());
        let e = TipMts { radius: 0.5, ..TipMts::default() }.validate().unwrap_err();
        assert!(format!("{e:?}").contains("radius"), "{e:?}");
        let e = TipMts { max_move: 0.9, ..TipMts::default() }.validate().unwrap_err();
        assert!(format!("{e:?}").contains("max_move"), "{e:?}");
        let e = TipMts { shrink: 0.5, ..TipMts::default() }.validate().unwrap_err();
        assert!(format!("{e:?}").contains("shrink"), "{e:?}");
        assert!(TipMts { shrink: 0.0, slide: false, every: 2.0, ..TipMts::default() }.validate().is_ok());
        let e = TipMts { piece: -0.1, ..TipMts::default() }.validate().unwrap_err();
        assert!(format!("{e:?}").contains("piece"), "{e:?}");
        assert!(TipMts { piece: 0.05, shrink: 1.5, ..TipMts::default() }.validate().is_ok());
        let e = TipMts { shield: -1.0, ..TipMts::default() }.validate().unwrap_err();
        assert!(format!("{e:?}").contains("shield"), "{e:?}");
        assert!(TipMts { shield: 4.0, ..TipMts::default() }.validate().is_ok());
        let e = TipMts { shield_length: f64::NAN, ..TipMts::default() }.validate().unwrap_err();
        assert!(format!("{e:?}").contains("shield_length"), "{e:?}");
        let e = TipMts { fork_ratio: 1.0, ..TipMts::default() }.validate().unwrap_err();
        assert!(format!("{e:?}").contains("fork_ratio"), "{e:?}");
        let e = TipMts { fork_ratio: 1.5, fork_angle_deg: 90.0, ..TipMts::default() }.validate().unwrap_err();
        assert!(format!("{e:?}").contains("fork_angle_deg"), "{e:?}");
        assert!(TipMts { fork_ratio: 1.5, fork_angle_deg: 20.0, ..TipMts::default() }.validate().is_ok());
    }
}
