//! Bittencourt's asymmetrically notched beam with three holes (issue 34 must-show 3, the curved
//! benchmark; docs/paths.md, section "Bittencourt's beam with holes"): the scenes of configs/beam/
//! are the specimen, and on the coarsest mesh the crack from the notch runs into the middle hole.
//!
//! Reference: T. N. Bittencourt, P. A. Wawrzynek, A. R. Ingraffea, J. L. Sousa (1996), Eng.
//! Fract. Mech. 55, 321-334 (also Miehe et al. 2010, Ambati et al. 2015): a beam 20 x 8 in,
//! 0.5 in thick, on a pin at x = 1 and a roller at x = 19, loaded downwards at x = 10 on top;
//! a notch from the bottom at x = 4, 1 in deep; three holes of diameter 0.5 in centred at x = 6,
//! y = 2.75, 4.75, 6.75. In the experiments of this configuration the crack curves towards the
//! holes and runs into the middle one (as the brief and the phase-field papers describe it; the
//! paper itself was not available to us: docs/paths.md says what was checked).
use flem_core::solver::{NoOutput, Simulation};
use flem_plugins::check::paths::{crack_faces, fragment_sizes, kinks_in_order};
use flem_plugins::check::sif::crack_tips;

use crate::common::{mesh_area, root, sim};

const HOLES: [[f64; 2]; 3] = [[6.0, 2.75], [6.0, 4.75], [6.0, 6.75]];
const R: f64 = 0.25;

/// The scene `configs/beam/NAME.toml` as text for `common::sim` (paths against configs/).
fn text(name: &str) -> String {
    let t = std::fs::read_to_string(root().join(format!("configs/beam/{name}.toml"))).unwrap();
    let mesh = format!("file = \"{name}.msh\"");
    assert!(t.contains(&mesh), "{name}: the scene's mesh line changed: update the test");
    t.replace(&mesh, &format!("file = \"beam/{name}.msh\""))
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Every coarsest scene (T3, gmsh quads, block-structured Q4) is the specimen: the mesh fills
/// [0, 20] x [0, 8] less three holes of radius 0.25 at the published centres (every point
/// outside them, at least 16 points on each circle, the area between that of the exact holes
/// and 5 % more of hole area: a hole of diameter 1, as one public mesh has it, fails); one crack
/// tip, at (4, 1), the pre-cut notch along x = 4 from the bottom (total length 1); the pin at
/// (1, 0), the roller at (19, 0), the loaded patch on the top between x = 9.9 and 10.1; plane
/// stress, nu = 0.3, the events solver and `tip_mts`.
#[test]
fn beam_scenes_are_bittencourts_specimen() {
    for kind in ["t3", "quad", "q4"] {
        let name = format!("beam_{kind}_1");
        let t = text(&name);
        let s = sim(&t);
        let m = &s.model;
        let pts = &m.mesh.points;
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for x in pts {
            for d in 0..2 {
                lo[d] = lo[d].min(x[d]);
                hi[d] = hi[d].max(x[d]);
            }
            for c in HOLES {
                assert!(dist(*x, c) > R - 1e-9, "{name}: point {x:?} inside the hole at {c:?}");
            }
        }
        assert!(lo[0].abs() < 1e-12 && lo[1].abs() < 1e-12 && (hi[0] - 20.0).abs() < 1e-12 && (hi[1] - 8.0).abs() < 1e-12, "{name}: bounding box {lo:?} {hi:?}");
        for c in HOLES {
            let on = pts.iter().filter(|x| (dist(**x, c) - R).abs() < 1e-9).count();
            assert!(on >= 16, "{name}: {on} points on the hole at {c:?}");
        }
        let area = mesh_area(&m.mesh);
        let holes = 3.0 * std::f64::consts::PI * R * R;
        assert!(area > 160.0 - holes && area < 160.0 - 0.95 * holes, "{name}: area {area}, the exact holes give {}", 160.0 - holes);
        let tips = crack_tips(m);
        assert_eq!(tips.len(), 1, "{name}: tips {tips:?}");
        assert!(dist(tips[0].x, [4.0, 1.0]) < 1e-12 && (tips[0].dir[1] - 1.0).abs() < 1e-12, "{name}: tip {:?}", tips[0]);
        let faces = crack_faces(m);
        let mut notch = 0.0;
        for (e, &f) in faces.iter().enumerate() {
            if f {
                let [a, b] = m.topo.edges[e].points.map(|p| pts[p.idx()]);
                assert!((a[0] - 4.0).abs() < 1e-12 && (b[0] - 4.0).abs() < 1e-12 && a[1].max(b[1]) <= 1.0 + 1e-12, "{name}: notch face {a:?} {b:?}");
                notch += dist(a, b);
            }
        }
        assert!((notch - 1.0).abs() < 1e-12, "{name}: notch length {notch}");
        let set = |n: &str| m.node_set(n, n, &name).unwrap().iter().map(|p| pts[p.idx()]).collect::<Vec<_>>();
        assert_eq!(set("pin"), vec![[1.0, 0.0]], "{name}: pin");
        assert_eq!(set("roller"), vec![[19.0, 0.0]], "{name}: roller");
        let punch = set("punch");
        assert!(punch.len() >= 3 && punch.iter().all(|x| x[1] == 8.0 && (9.9 - 1e-9..=10.1 + 1e-9).contains(&x[0])), "{name}: punch {punch:?}");
        assert!(punch.iter().any(|x| (x[0] - 9.9).abs() < 1e-9) && punch.iter().any(|x| (x[0] - 10.1).abs() < 1e-9), "{name}: punch {punch:?}");
        for key in ["plane = \"stress\"", "poisson_ratio = 0.3\n", "type = \"events\"", "type = \"rankine\"", "type = \"tip_mts\"", "fix = \"xy\"", "y = -1.0\n"] {
            assert!(t.contains(key), "{name}: no {key}");
        }
    }
}

/// Runs the scene `name` with `tip_mts` for at most `events` events and returns the path from
/// the notch tip to where it first meets a boundary.
fn run(name: &str, events: u32) -> (Vec<[f64; 2]>, Simulation) {
    run_text(name, &text(name).replace("max_events = 400", &format!("max_events = {events}")))
}

/// [`run`] on the scene text `t` (named `name` in messages).
fn run_text(name: &str, t: &str) -> (Vec<[f64; 2]>, Simulation) {
    let mut s = sim(t);
    let tips = crack_tips(&s.model);
    let initial = crack_faces(&s.model);
    s.run(&mut NoOutput).unwrap_or_else(|e| panic!("{name}: {e}"));
    let cuts = s.cracking.as_ref().unwrap().cuts.clone();
    let k = kinks_in_order(&s.model, &tips, &initial, 5.0, &cuts).remove(0);
    assert!(k.boundary_at.is_some(), "{name}: the crack did not reach a boundary: {:?}", k.path);
    (k.through().to_vec(), s)
}

/// Reference: the experiment (module doc): the crack from the notch curves towards the holes and
/// ends in the middle one. On the coarsest T3 mesh (h = 0.1 in) with `tip_mts` as the scene
/// carries it (S35 since session 35, S25 in session 34; with the defaults before):
/// the path starts at the notch tip (4, 1), first meets a boundary on the middle hole's circle
/// (within 1e-9 of radius 0.25 from (6, 4.75)), turns right of the notch's line (its end at
/// x > 5.5) and stays below the middle hole's centre line plus a radius; no fragment below
/// 3 elements (must-show 4). A straight path up the notch's line (what the edge rule gives on
/// the Q4 grids) ends on the top and fails; the edge rule on this mesh fails too (its path from
/// the tip meets no boundary: docs/paths.md). Measured (docs/paths.md): the nine meshes end on
/// the middle hole within 0.49 % of 20 in of each other with session 35's setting (0.95 % with
/// session 25's, 1.17 % with the defaults before session 25).
#[test]
fn beam_crack_runs_from_the_notch_into_the_middle_hole() {
    let (path, s) = run("beam_t3_1", 70);
    assert!(dist(path[0], [4.0, 1.0]) < 1e-12, "the path starts at {:?}", path[0]);
    let end = *path.last().unwrap();
    assert!((dist(end, HOLES[1]) - R).abs() < 1e-9, "the path ends at {end:?}, not on the middle hole");
    assert!(end[0] > 5.5 && path.iter().all(|p| p[1] <= HOLES[1][1] + R), "path {path:?}");
    let small: Vec<usize> = fragment_sizes(&s.model).into_iter().filter(|&n| n < 3).collect();
    assert!(small.is_empty(), "fragments of {small:?} elements");
}

/// Reference: the experiment (module doc): the crack runs into the middle hole. On the coarsest
/// block-structured Q4 grid (h = 0.1 in) as committed, with session 35's setting of `tip_mts`
/// (`every = 1.25, piece = 0.05, shrink = 1.0, anchor = true`, in the scenes since session 35,
/// session 25's before; docs/paths.md "Session 35": all nine meshes within 0.49 % of 20 in): the
/// path from the notch tip ends on the middle hole's circle, no fragment below 3 elements. With
/// the defaults this mesh's crack has missed the middle hole since session 25's move fractions
/// (b5ea291): it ends on the beam's top at x = 6.41 in (docs/paths.md, "Results"), so this test
/// fails with the setting's lines removed from the scene. About 5 s of CPU.
#[test]
fn beam_q4_1_runs_into_the_middle_hole() {
    let t = text("beam_q4_1");
    for key in ["every = 1.25", "piece = 0.05", "shrink = 1.0", "anchor = true"] {
        assert!(t.lines().any(|l| l.starts_with(key)), "beam_q4_1: the scene lost `{key}`");
    }
    let (path, s) = run_text("beam_q4_1", &t);
    let end = *path.last().expect("a path");
    assert!((dist(end, HOLES[1]) - R).abs() < 1e-9, "the path ends at {end:?}, not on the middle hole");
    assert!(fragment_sizes(&s.model).iter().all(|&n| n >= 3));
}
