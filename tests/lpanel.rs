//! Winkler's L-shaped panel (issue 34 must-show 3, second half; docs/paths.md, section
//! "Winkler's L-panel"): the scenes of configs/lpanel/ are the experiment's specimen, and on a
//! small mesh the crack starts at the re-entrant corner, as in the experiments.
//!
//! Reference: Winkler, Hofstetter & Niederwanger (2001), Proc. IMechE L 215, 75-86 (../shared/
//! BENCHMARKS.md): panel 500 x 500 mm less a 250 x 250 mm cut-out, t = 100 mm; bottom of the leg
//! fixed; upward displacement on 470-500 mm of the arm's underside; E = 25.85 GPa, nu = 0.18,
//! G_c 89-95 N/m, f_t 2.65-2.7 MPa; peak 6.7-7.6 kN at u ~ 0.20 mm (configs/lpanel/
//! winkler_band.csv); the crack starts at the re-entrant corner.
use flem_core::solver::{Observer, Simulation};

use crate::common::{mesh_area, root, sim};

/// The scene `configs/lpanel/NAME.toml` as text for `common::sim` (paths against configs/).
fn text(name: &str) -> String {
    let t = std::fs::read_to_string(root().join(format!("configs/lpanel/{name}.toml"))).unwrap();
    let mesh = format!("file = \"{name}.msh\"");
    assert!(t.contains(&mesh), "{name}: the scene's mesh line changed: update the test");
    t.replace(&mesh, &format!("file = \"lpanel/{name}.msh\""))
}

const KINDS: [&str; 3] = ["t3", "quad", "q4"];

/// Every scene is the specimen: the mesh fills the L (area 0.5^2 - 0.25^2 m^2 to 1e-9, no
/// point inside the cut-out), the load acts on the arm's underside at 470-500 mm, the support on
/// the leg's bottom, plane stress, E and nu as published, the criterion's and the cohesive law's
/// strength and the fracture energy inside the published ranges (f_t 2.65-2.7 MPa, G_c 89-95
/// N/m), the softening Cornelissen's exponential law for concrete (session 33; Petersson's
/// before), and the points kept intact (ours, session 33) only at the ends of the load strip and
/// of the clamped edge: within 31 mm of them (in x and in y), never the re-entrant corner. A scene with the load
/// on the wrong edge, a cut-out on the wrong side, a strength off the published range or an
/// intact zone reaching the crack's corner fails here. The path method's setting: session 27's
/// shield and local damping, session 33's `every = 2`.
#[test]
fn lpanel_scenes_are_winklers_specimen() {
    for kind in KINDS {
        for i in 1..=3 {
            let name = format!("lpanel_{kind}_{i}");
            let t = text(&name);
            let s = sim(&t);
            let m = &s.model;
            let pts = &m.mesh.points;
            for x in pts {
                assert!(x[0] > -1e-12 && x[0] < 0.5 + 1e-12 && x[1] > -1e-12 && x[1] < 0.5 + 1e-12, "{name}: point {x:?} outside the panel");
                assert!(!(x[0] > 0.25 + 1e-9 && x[1] < 0.25 - 1e-9), "{name}: point {x:?} inside the cut-out");
            }
            let area = mesh_area(&m.mesh);
            assert!((area - 0.1875).abs() < 1e-9, "{name}: area {area}");
            let lift = m.node_set("lift", "lift", &name).unwrap();
            assert!(lift.len() >= 2);
            for p in &lift {
                let x = pts[p.idx()];
                assert!((x[1] - 0.25).abs() < 1e-9 && x[0] >= 0.47 - 1e-6 && x[0] <= 0.5 + 1e-12, "{name}: load point {x:?}");
            }
            let bottom = m.node_set("bottom", "bottom", &name).unwrap();
            for p in &bottom {
                let x = pts[p.idx()];
                assert!(x[1].abs() < 1e-12 && x[0] <= 0.25 + 1e-12, "{name}: support point {x:?}");
            }
            assert!(t.contains("plane = \"stress\""));
            assert!(t.contains("young_modulus = 25.85e9\npoisson_ratio = 0.18\n"));
            let num = |key: &str| -> f64 {
                let i = t.find(key).unwrap_or_else(|| panic!("{name}: no {key}")) + key.len();
                t[i..].split(|c: char| c == ',' || c == '\n' || c == ' ' || c == '}').find(|w| !w.is_empty()).unwrap().parse().unwrap()
            };
            let (ft, gc) = (num("tensile_strength = "), num("fracture_energy = "));
            assert!((2.65e6..=2.7e6).contains(&ft) && (89.0..=95.0).contains(&gc), "{name}: f_t {ft}, G_c {gc}");
            assert!(t.contains("type = \"cohesive\"") && t.contains("type = \"tip_mts\""));
            // Concrete's softening: Cornelissen's exponential law (docs/paths.md, session 33).
            assert!(t.contains("softening = \"cornelissen\""), "{name}: not Cornelissen's softening");
            // The intact zones (session 33): the load strip's end and the clamp's end only.
            assert!(t.contains("intact = [\"lift_zone\", \"base_end\"]"), "{name}: not session 33's intact zones");
            // Each zone within 31 mm (in x and in y) of the strip (470-500 mm on y = 250 mm) or of
            // the clamp's end (250, 0) mm.
            for (set, x_lo, end) in [("lift_zone", 0.47, [0.5, 0.25]), ("base_end", 0.25, [0.25, 0.0])] {
                let pts_set = m.node_set(set, set, &name).unwrap();
                assert!(!pts_set.is_empty(), "{name}: {set} is empty");
                for p in &pts_set {
                    let x = pts[p.idx()];
                    let (dx, dy) = ((x_lo - x[0]).max(x[0] - end[0]).max(0.0), (x[1] - end[1]).abs());
                    assert!(dx <= 0.031 && dy <= 0.031 && (x[0] - 0.25).hypot(x[1] - 0.25) > 0.1, "{name}: {set} holds {x:?}");
                }
            }
            // Session 27 (docs/paths.md): local damping (the fine unstructured meshes come to
            // rest) and the shield (no parallel cracks beside the main one).
            assert!(t.contains("damping = { type = \"local\", ratio = 0.8 }") && num("shield_length = ") == 0.04, "{name}: not session 27's setting");
            // Session 33: the direction evaluated again after two domain radii of straight crack.
            assert!(num("\nevery = ") == 2.0, "{name}: not session 33's every = 2");
        }
    }
}

/// The split points and the load's reaction at every stage end.
#[derive(Default)]
struct Log {
    splits: Vec<[f64; 2]>,
    force: Vec<(f64, f64)>,
    lift: Vec<flem_core::ids::PointId>,
}

impl Observer for Log {
    fn splits(&mut self, sim: &Simulation, _rec: &flem_core::mesh::topology::SplitRecord, events: &[flem_core::cracking::SplitEvent]) -> flem_core::error::Result<()> {
        self.splits.extend(events.iter().map(|e| sim.model.mesh.points[e.point.idx()]));
        Ok(())
    }
    fn stage_end(&mut self, sim: &Simulation, _stage: usize) -> flem_core::error::Result<()> {
        // kN on the 100 mm thick panel against the load point's displacement in mm.
        self.force.push((sim.levels[0], sim.reaction(&self.lift)[1].abs() * 0.1 / 1e3));
        Ok(())
    }
}

/// The small mesh (h = 25 mm, 435 triangles; tools/gen_lpanel.py) with the scene's stages up
/// to `u_max` mm.
fn small(u_max: f64) -> (Simulation, Log) {
    up_to(text("lpanel_t3_1").replace("file = \"lpanel/lpanel_t3_1.msh\"", "file = \"lpanel/lpanel_t3_test.msh\""), u_max)
}

/// The scene `t` with its stages up to `u_max` mm, run with the log.
fn up_to(mut t: String, u_max: f64) -> (Simulation, Log) {
    let cut = t.find("[[stage]]").unwrap();
    let stages = t.split_off(cut);
    for st in stages.split("[[stage]]").filter(|s| !s.trim().is_empty()) {
        let v: f64 = st.split("lift = ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
        if v <= u_max + 1e-12 {
            t += "[[stage]]";
            t += st;
        }
    }
    let mut s = sim(&t);
    let lift = s.model.node_set("lift", "lift", "test").unwrap();
    let mut log = Log { lift, ..Log::default() };
    s.run(&mut log).unwrap();
    (s, log)
}

/// Reference: the experiments (the crack starts at the re-entrant corner, Winkler 2001) and
/// beam theory for its direction: the upward load F at x = 0.485 m bends the leg's top section
/// (y = 0.25, lever 0.485 - 0.125 = 0.36 m) more than the arm's root section (x = 0.25, lever
/// 0.235 m), both 0.25 m deep, so the vertical stress sigma_yy at the corner exceeds sigma_xx
/// (ratio about 1.5) and the crack leaves the corner leftwards, nearer horizontal than vertical.
/// Tolerances: the first split within 1.2 element sizes (h = 25 mm) of the corner (the corner
/// point itself or the next point on the leg's face); the chord from it to the fourth split of
/// that crack runs leftwards within 45 deg of the horizontal (measured: 152 deg from +x, 28 deg
/// above the horizontal). With the load reversed (the arm pushed down, the corner in
/// compression) nothing splits up to 0.1 mm (checked once by hand), and the test fails.
#[test]
fn lpanel_crack_starts_at_the_re_entrant_corner_and_runs_left() {
    let (_s, log) = small(0.1);
    assert!(log.splits.len() >= 4, "{} splits up to u = 0.1 mm: {:?}, forces {:?}", log.splits.len(), log.splits, log.force);
    let first = log.splits[0];
    let d = (first[0] - 0.25).hypot(first[1] - 0.25);
    assert!(d <= 1.2 * 0.025, "first split at {first:?}, {d} m from the corner");
    let last = log.splits[3];
    let ang = (last[1] - first[1]).atan2(last[0] - first[0]).to_degrees();
    assert!((135.0..=225.0).contains(&ang), "the crack from the corner runs at {ang:.1} deg from +x: {:?}", &log.splits[..4]);
}

/// Reference: the experiments' peak, 6.7-7.6 kN (configs/lpanel/winkler_band.csv). Not met on
/// this mesh (docs/paths.md, "Winkler's L-panel"): 7.96 kN at 0.14 mm with session 33's setting
/// (8.30 with session 27's, 12.4 kN with the linear law); kept, ignored, as the record of the gap
/// (run it with `cargo test --release -p flem-tests -- --ignored lpanel`).
#[test]
#[ignore = "not met on the small mesh: 7.96 kN against 6.7-7.6 kN (docs/paths.md, Winkler's L-panel)"]
fn lpanel_peak_inside_the_experimental_band() {
    let (_s, log) = small(0.4);
    let peak = log.force.iter().map(|f| f.1).fold(0.0, f64::max);
    assert!((6.7..=7.6).contains(&peak), "peak {peak:.2} kN: {:?}", log.force);
}

/// The experiments' band at `u` mm (configs/lpanel/winkler_band.csv, linear between its rows):
/// (lower, upper) bound of the force in kN.
fn band_at(u: f64) -> (f64, f64) {
    let t = std::fs::read_to_string(root().join("configs/lpanel/winkler_band.csv")).unwrap();
    let rows: Vec<[f64; 3]> = t
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("U_mm"))
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.trim().parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect();
    let k = rows.windows(2).position(|w| w[0][0] <= u && u <= w[1][0]).unwrap_or_else(|| panic!("u = {u} mm outside the band's rows"));
    let (a, b) = (rows[k], rows[k + 1]);
    let f = (u - a[0]) / (b[0] - a[0]);
    (a[1] + f * (b[1] - a[1]), a[2] + f * (b[2] - a[2]))
}

/// Reference: the experiments' band (configs/lpanel/winkler_band.csv: peak 6.7-7.6 kN), on the
/// coarsest committed structured grid (q4_1, h = 12.5 mm) with the scenes' setting (session 33:
/// Cornelissen's softening, the intact zones and `every = 2`, with session 27's `tip_mts`, 40 mm
/// shield and local damping; docs/paths.md): the peak inside the band (measured 6.99 kN at
/// 0.14 mm) and the force falling after it up to 0.30 mm. Every stage at rest, no fragment of
/// fewer than 3 elements, and no split right of x = 0.4 m or below y = 0.1 m (the
/// intact zones: without them the strip's end splits at 0.10 mm, at (500, 262.5) mm; with them
/// a crack starts above the zone at 0.35 mm, one stage past this test). With the
/// linear softening instead the peak is 8.53 kN and the test fails (checked). After its peak
/// the force falls below the band (3.91 kN at 0.30 mm against 4.0-6.0: the model peaks at
/// 0.14 mm, the experiments at 0.20 mm; docs/paths.md "Session 33"), so the band is not asked
/// there. The nine meshes peak at 6.99-7.55 kN; about 10 s of CPU.
#[test]
fn lpanel_q4_1_peak_inside_the_band_and_softening() {
    let (s, log) = up_to(text("lpanel_q4_1"), 0.3);
    let (ipk, &(upk, peak)) = log.force.iter().enumerate().max_by(|a, b| a.1 .1.total_cmp(&b.1 .1)).unwrap();
    assert!((6.7..=7.6).contains(&peak), "peak {peak:.2} kN at {upk} mm: {:?}", log.force);
    assert!(log.force[ipk..].windows(2).all(|w| w[1].1 < w[0].1), "not softening after the peak: {:?}", log.force);
    let &(u_end, _) = log.force.last().unwrap();
    assert!((u_end - 0.3).abs() < 1e-12, "the run ended at {u_end} mm");
    assert!(s.stages_done.iter().all(|st| st.converged), "a stage not at rest: {:?}", s.stages_done.iter().map(|st| st.converged).collect::<Vec<_>>());
    assert!(flem_plugins::check::paths::fragment_sizes(&s.model).iter().all(|&n| n >= 3));
    let near: Vec<&[f64; 2]> = log.splits.iter().filter(|x| x[0] > 0.4 || x[1] < 0.1).collect();
    assert!(near.is_empty(), "splits at the load strip or the clamp: {near:?}");
}

/// Reference: the experiments' peak, 6.7-7.6 kN (configs/lpanel/winkler_band.csv), on quad_3
/// (recombined quads, h = 6.5 mm in the band) as committed, up to 0.18 mm: the peak inside the
/// band (measured 7.26 kN at 0.16 mm). With `tip_mts`'s default `every = 1` in place of the
/// scenes' `every = 2` the peak is 7.80 kN and the test fails (docs/paths.md, "Session 33": the
/// mesh that the setting brought into the band). About 20 s of CPU.
#[test]
fn lpanel_quad_3_peak_inside_the_band() {
    let (_s, log) = up_to(text("lpanel_quad_3"), 0.18);
    let (upk, peak) = log.force.iter().copied().max_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
    assert!((6.7..=7.6).contains(&peak), "peak {peak:.2} kN at {upk} mm: {:?}", log.force);
}

/// Reference: the experiments' band after the peak (configs/lpanel/winkler_band.csv: 4.52-6.48
/// kN at u = 0.28 mm), on quad_3 (recombined quads, h = 6.5 mm in the band) with the scenes'
/// setting but `tip_mts`'s default `every = 1` (the line `every = 2.0` removed), up to 0.28 mm:
/// the force there inside the band and at most 0.9 of the run's peak (measured 4.88 kN against
/// the peak 7.80 kN at 0.16 mm). Without the shield (`shield_length` removed too) `tip_mts`
/// leaves failed points beside the crack to the edge rule, which starts cracks beside the main
/// one, and the panel holds a plateau: 7.73 kN at 0.28 mm (peak 8.43 kN at 0.20 mm; docs/paths.md,
/// "Session 33"), and the test fails. With the scenes' `every = 2` the shield changes no peak and
/// no force up to 0.30 mm on quad_3 (4.65 kN at 0.28 mm with and without it): the test keeps
/// `every = 1`, where the shield is what makes the panel soften. About 40 s of CPU.
#[test]
fn lpanel_quad_3_softens_with_the_shield() {
    let t = text("lpanel_quad_3");
    let every = t.lines().find(|l| l.starts_with("every = 2.0")).expect("the scene's every line").to_string();
    let (_s, log) = up_to(t.replace(&format!("{every}\n"), ""), 0.28);
    let peak = log.force.iter().map(|f| f.1).fold(0.0, f64::max);
    let &(u_end, f_end) = log.force.last().unwrap();
    let (lo, hi) = band_at(0.28);
    assert!((u_end - 0.28).abs() < 1e-12 && (lo..=hi).contains(&f_end) && f_end <= 0.9 * peak, "{f_end:.2} kN at {u_end} mm (band {lo:.2}-{hi:.2}, peak {peak:.2}): {:?}", log.force);
}

/// Reference: the independent elastic solve of t3_3 outside FLEM (`tools/lpanel_elastic.py`,
/// docs/paths.md "Elastic stiffness": 62.45 kN/mm, so 1.561 kN at u = 0.025 mm). The scene's
/// first, elastic stage with its local damping (session 27) comes to rest within its 300 000
/// steps (measured: 99 460 steps) and its force is within 1 % of that solve (measured 1.569 kN,
/// +0.5 %). With the default adaptive relaxation it ended at the step limit at 1.812 kN (+16 %),
/// and the test fails. About 3 s of CPU.
#[test]
fn lpanel_t3_3_elastic_stage_comes_to_rest_with_local_damping() {
    let (s, log) = up_to(text("lpanel_t3_3"), 0.025);
    let (u, f) = log.force[0];
    assert!((u - 0.025).abs() < 1e-12 && s.stages_done[0].converged, "stage 0: {:?}", s.stages_done[0]);
    assert!((f / (62.45 * 0.025) - 1.0).abs() < 0.01, "{f:.4} kN at {u} mm against 1.561 kN");
}
