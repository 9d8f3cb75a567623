//! The nonlocal failure check (issue 18, ours): the initiation load under mesh refinement,
//! bad radii in a scene, the config snippets of its docs.
use std::path::Path;

use flem_core::cracking::initiation::{initiation, Initiation};
use flem_core::scene::Scene;
use flem_core::solver::Simulation;

use crate::common::{rel, root};

/// configs/converge/notch_plate.toml on another mesh, with or without the nonlocal radius.
fn notch_scene(mesh: &str, nonlocal: bool) -> Scene {
    flem_plugins::link();
    let path = root().join("configs/converge/notch_plate.toml");
    let mut text = std::fs::read_to_string(&path).unwrap().replace("../meshes/notch_q4_h0.25_v22.msh", mesh);
    if !nonlocal {
        text = text.replace("nonlocal = { radius = 0.5 }", "");
    }
    Scene::from_str(&text, &path, path.parent().unwrap()).unwrap_or_else(|e| panic!("{e}"))
}

/// The exact initiation factor (elastic solve by the check solver at the first stage's levels).
fn init(scene: Scene) -> Initiation {
    let mut sim = Simulation::new(scene).unwrap_or_else(|e| panic!("{e}"));
    sim.set_stage_levels(0);
    let u1 = flem_plugins::check::static_solve(&sim).unwrap();
    let crit = &sim.scene.file.cracking.as_ref().unwrap().criterion;
    let cr = sim.cracking.as_mut().unwrap();
    let scale = cr.scale.clone();
    initiation(crit.as_ref(), &scale, &sim.model, &u1, cr.nonlocal.as_mut()).unwrap()
}

/// Reference: mesh convergence of a regularised quantity (issue 18): with R = 0.5 the
/// initiation load of the peers' notched plate (gen_meshes.py) is the same on h = 0.25 Q4,
/// h = 0.25 T3 and h = 0.125 Q4 within 3 % (the issue's tolerance), and the first failing node
/// is ahead of the notch end face (x in (3, 3 + R]) at mid-height within 0.25. The paper's
/// corner mean on the same meshes drifts by more than 3 % (0.121 -> 0.108, the issue's
/// numbers, checked to 1 %): the test separates the two checks. The h = 0.0625 level (36k
/// elements) is measured in docs/nonlocal.md, not here.
#[test]
fn notched_plate_initiation_load_converges_with_the_nonlocal_check() {
    let meshes = ["../meshes/notch_q4_h0.25_v22.msh", "../meshes/notch_t3_h0.25_v22.msh", "../meshes/notch_q4_h0.125_v22.msh"];
    let nl: Vec<Initiation> = meshes.iter().map(|m| init(notch_scene(m, true))).collect();
    let p: Vec<f64> = nl.iter().map(|i| i.factor).collect();
    let (lo, hi) = (p.iter().cloned().fold(f64::INFINITY, f64::min), p.iter().cloned().fold(0.0, f64::max));
    assert!(hi / lo - 1.0 < 0.03, "nonlocal initiation loads {p:?} spread more than 3 %");
    for i in &nl {
        assert!(i.x[0] > 3.0 && i.x[0] <= 3.5 + 1e-9 && (i.x[1] - 6.0).abs() <= 0.25 + 1e-9, "first failure at {:?}", i.x);
        // Mode I ahead of the notch: sigma1 horizontal (the crack plane along the ligament).
        let d = i.sigma1_deg.min(180.0 - i.sigma1_deg);
        assert!(d < 10.0, "sigma1 direction {} deg", i.sigma1_deg);
    }
    let local: Vec<f64> = [meshes[0], meshes[2]].iter().map(|m| init(notch_scene(m, false)).factor).collect();
    assert!(rel(local[0], 0.121) < 0.01 && rel(local[1], 0.108) < 0.01, "local {local:?} (issue: 0.121, 0.108)");
    assert!(local[0] / local[1] - 1.0 > 0.03, "the local check drifts: {local:?}");
}

/// Bad radii in a scene are refused naming the file and `cracking.nonlocal.radius`; a radius
/// that catches no Gauss point names the node; one below the element size gives a warning.
#[test]
fn bad_radius_in_a_scene_is_refused_naming_the_key() {
    flem_plugins::link();
    let base = std::fs::read_to_string(root().join("configs/verification/notched_crack.toml")).unwrap();
    let with = |r: &str| base.replace("[cracking]\n", &format!("[cracking]\nnonlocal = {{ radius = {r} }}\n"));
    for r in ["0.0", "-1.0", "nan", "inf"] {
        let e = Scene::from_str(&with(r), Path::new("bad.toml"), &root().join("configs/verification")).err().unwrap_or_else(|| panic!("R = {r} accepted")).to_string();
        assert!(e.contains("bad.toml") && e.contains("cracking.nonlocal.radius"), "{e}");
    }
    // h = 1/6: the Gauss points nearest a corner are 0.211 h * sqrt(2) = 0.05 away.
    let s = Scene::from_str(&with("0.01"), Path::new("small.toml"), &root().join("configs/verification")).unwrap();
    let e = Simulation::new(s).err().expect("refused").to_string();
    assert!(e.contains("small.toml") && e.contains("cracking.nonlocal.radius") && e.contains("point 0"), "{e}");
    let s = Scene::from_str(&with("0.1"), Path::new("warn.toml"), &root().join("configs/verification")).unwrap();
    let sim = Simulation::new(s).unwrap();
    assert!(sim.warnings.iter().any(|w| w.contains("cracking.nonlocal.radius") && w.contains("degenerates to the local stress")), "{:?}", sim.warnings);
    let unknown = base.replace("[cracking]\n", "[cracking]\nnonlocal = { raduis = 0.5 }\n");
    let e = Scene::from_str(&unknown, Path::new("typo.toml"), &root().join("configs/verification")).err().expect("refused").to_string();
    assert!(e.contains("raduis"), "{e}");
}

/// The `toml` blocks of docs/nonlocal.md and of the cracking module doc parse and validate as
/// the `[cracking]` table of a scene (the docs cannot drift from the code).
#[test]
fn doc_snippets_parse_and_validate() {
    flem_plugins::link();
    let base = std::fs::read_to_string(root().join("configs/verification/notched_crack.toml")).unwrap();
    let head = &base[..base.find("[cracking]").unwrap()];
    let tail = &base[base.find("[[stage]]").unwrap()..];
    let mut n = 0;
    for (file, prefix) in [("docs/nonlocal.md", ""), ("core/src/cracking/mod.rs", "//! ")] {
        let text = std::fs::read_to_string(root().join(file)).unwrap();
        let lines: Vec<&str> = text.lines().map(|l| l.strip_prefix(prefix).or_else(|| l.strip_prefix(prefix.trim_end())).unwrap_or(l)).collect();
        let mut i = 0;
        while i < lines.len() {
            if lines[i].trim() == "```toml" {
                let end = i + 1 + lines[i + 1..].iter().position(|l| l.trim() == "```").expect("closed block");
                let snippet = lines[i + 1..end].join("\n");
                let s = Scene::from_str(&format!("{head}\n{snippet}\n{tail}"), Path::new(file), &root().join("configs/verification")).unwrap_or_else(|e| panic!("{file}: {e}"));
                assert!(s.file.cracking.as_ref().unwrap().nonlocal.is_some(), "{file}: the snippet sets no radius");
                n += 1;
                i = end;
            }
            i += 1;
        }
    }
    assert!(n >= 2, "{n} snippets");
}

/// The bracketed bisection of `failure_factor` against closed forms. Rankine: lambda =
/// sigma_t / sigma_max (the largest tensile principal stress); the in-plane tensor (0.3, -0.2,
/// 0.25) has sigma_max = 0.05 + sqrt(0.25^2 + 0.25^2). Mohr-Coulomb with the tension check off
/// (c = 0.1, phi = 30 deg, METHOD section 4): uniaxial compression (-1, 0, 0) fails at the UCS
/// 2 c cos(phi) / (1 - sin(phi)) = 0.34641. A criterion that never fails gives infinity; the
/// strength factor scales the result. Tolerance 1e-12 relative (bisection width 1e-13).
#[test]
fn failure_factor_matches_closed_forms() {
    use flem_core::cracking::initiation::failure_factor;
    use flem_core::plugin::traits::FailureCriterion;
    flem_plugins::link();
    let rankine: Box<dyn FailureCriterion> = toml::from_str("type = \"rankine\"\ntensile_strength = 2.0").unwrap();
    let smax = 0.05 + (0.25f64 * 0.25 + 0.25 * 0.25).sqrt();
    let l = failure_factor(rankine.as_ref(), [0.3, -0.2, 0.25], 0.0, 1.0).unwrap();
    assert!(rel(l, 2.0 / smax) < 1e-12, "{l} vs {}", 2.0 / smax);
    let l = failure_factor(rankine.as_ref(), [0.3, -0.2, 0.25], 0.0, 0.5).unwrap();
    assert!(rel(l, 1.0 / smax) < 1e-12, "{l}");
    // Far above the strength at factor 1: bracketed by halving.
    let l = failure_factor(rankine.as_ref(), [300.0, 0.0, 0.0], 0.0, 1.0).unwrap();
    assert!(rel(l, 2.0 / 300.0) < 1e-12, "{l}");
    assert_eq!(failure_factor(rankine.as_ref(), [-1.0, -2.0, 0.0], 0.0, 1.0).unwrap(), f64::INFINITY);
    let mc: Box<dyn FailureCriterion> = toml::from_str("type = \"mohr_coulomb\"\ncohesion = 0.1\nfriction_angle_deg = 30.0\ntensile_strength = 1.0\ntension = false").unwrap();
    let l = failure_factor(mc.as_ref(), [-1.0, 0.0, 0.0], 0.0, 1.0).unwrap();
    let ucs = 2.0 * 0.1 * 30f64.to_radians().cos() / (1.0 - 30f64.to_radians().sin());
    assert!(rel(l, ucs) < 1e-12, "{l} vs {ucs}");
}

/// configs/converge/opening_nonlocal.toml on an n x n mesh, its stage level times `factor`.
fn opening_scene(n: usize, factor: f64) -> Scene {
    flem_plugins::link();
    let path = root().join("configs/converge/opening_nonlocal.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("nx = 6\nny = 6") && text.contains("levels = { p = 111.0 }"), "the scene changed: update the test");
    let text = text.replace("nx = 6\nny = 6", &format!("nx = {n}\nny = {n}")).replace("levels = { p = 111.0 }", &format!("levels = {{ p = {} }}", 111.0 * factor));
    Scene::from_str(&text, &path, path.parent().unwrap()).unwrap_or_else(|e| panic!("{e}"))
}

/// Reference: mesh convergence of a regularised quantity, the issue-18 must-show on the paper's
/// opening model (Nishimura et al. figures 9-11; the quasi-static roller variant) with our
/// nonlocal check R = 1.1 cm and crack tracking (exclusion 1.1 cm):
/// - the exact initiation loads on 6 x 6, 12 x 12 and 24 x 24 lie within 5 % of each other (the
///   issue's tolerance; measured 0.4 %), while the paper's corner mean on the same meshes falls
///   by more than 2x (1.053 -> 0.478: the notch-tip singularity, docs/paper.md);
/// - an explicit run at 1.05 times each mesh's own initiation load splits first at the notch tip
///   (2, 3) and then, one node per split, along the ligament y = 3 with x increasing, for every
///   ligament node up to x = 5 (the physics: mode I from a notch under load control is unstable,
///   the crack runs straight across). Without tracking the 24 x 24 mesh cracked a band of nodes
///   around (2.5, 2.9) and the 12 x 12 one arrested after one split (docs/nonlocal.md).
#[test]
fn opening_model_initiation_and_crack_path_converge_with_tracking() {
    let mut p = Vec::new();
    for n in [6usize, 12, 24] {
        let i = init(opening_scene(n, 1.0));
        p.push(i.factor);
        let mut sim = Simulation::new(opening_scene(n, 1.05 * i.factor)).unwrap_or_else(|e| panic!("{e}"));
        sim.run(&mut flem_core::solver::NoOutput).unwrap_or_else(|e| panic!("{e}"));
        let cr = sim.cracking.as_ref().unwrap();
        let path: Vec<[f64; 2]> = cr.cuts.iter().map(|(c, _)| sim.model.mesh.points[sim.model.topo.cluster_point[*c as usize].idx()]).collect();
        let h = 6.0 / n as f64;
        let on_ligament = ((5.0 - 2.0) / h).round() as usize + 1;
        assert!(path.len() >= on_ligament, "{n} x {n}: {} splits, the crack did not cross: {path:?}", path.len());
        for (k, x) in path[..on_ligament].iter().enumerate() {
            assert!((x[0] - (2.0 + k as f64 * h)).abs() < 1e-9 && (x[1] - 3.0).abs() < 1e-9, "{n} x {n}: split {k} at {x:?}, not the next ligament node from the tip: {path:?}");
        }
    }
    let (lo, hi) = (p.iter().cloned().fold(f64::INFINITY, f64::min), p.iter().cloned().fold(0.0, f64::max));
    assert!(hi / lo - 1.0 < 0.05, "nonlocal initiation loads {p:?} spread more than 5 %");
    let local = |n: usize| {
        let mut s = opening_scene(n, 1.0);
        s.file.cracking.as_mut().unwrap().nonlocal = None;
        init(s).factor
    };
    let (l6, l24) = (local(6), local(24));
    assert!(l6 / l24 > 2.0, "the paper's corner mean falls with h: {l6} -> {l24}");
}

/// Reference: the truncated quartic ("bell") weight of Bazant and Jirasek (2002, eq. 14)
/// is `(1 - r^2/R^2)^2` inside R and 0 beyond (exact values at r = 0, R/2, R, beyond). An
/// exclusion distance <= 0, NaN or inf is refused naming its key and the file; an unknown
/// weight is refused naming the choices.
#[test]
fn bell_weight_and_exclusion_are_checked() {
    use flem_core::scene::NonlocalWeight;
    let b = NonlocalWeight::Bell;
    assert_eq!(b.factor(0.0, 2.0), 1.0);
    assert!((b.factor(1.0, 2.0) - 0.5625).abs() < 1e-15);
    assert_eq!(b.factor(4.0, 2.0), 0.0);
    assert_eq!(b.factor(5.0, 2.0), 0.0);
    assert_eq!(NonlocalWeight::Uniform.factor(3.0, 2.0), 1.0);
    let path = root().join("configs/converge/opening_nonlocal.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    for bad in ["-1.0", "0.0", "nan", "inf"] {
        let t = text.replace("exclusion = 1.1", &format!("exclusion = {bad}"));
        let e = Scene::from_str(&t, &path, path.parent().unwrap()).err().expect("refused").to_string();
        assert!(e.contains("cracking.nonlocal.exclusion") && e.contains("opening_nonlocal.toml"), "{e}");
    }
    let t = text.replace("exclusion = 1.1", "exclusion = 1.1, weight = \"bel\"");
    let e = Scene::from_str(&t, &path, path.parent().unwrap()).err().expect("refused").to_string();
    assert!(e.contains("bell") || e.contains("weight"), "{e}");
}
