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
