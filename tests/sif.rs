//! Stress intensity factors from the implicit solve (issue 34, "Must show 1";
//! `flem_plugins::check::sif`, `flem sif`, docs/paths.md): the interaction integral against
//! closed forms on unstructured gmsh meshes with the crack as pre-cut edges (configs/sif/,
//! configs/meshes/sif_*.geo), the maximum tangential stress angles from the computed factors, and
//! the named refusals.
use flem_core::scene::Scene;
use flem_core::solver::Simulation;
use flem_plugins::check::sif::{crack_tips, domain_sif, mts_angle, stage_sif, Radii, StageSif, TipSif};

use crate::common::{rel, root, sim};

fn run(path: &str, radii: &Radii) -> StageSif {
    flem_plugins::link();
    let mut s = Simulation::new(Scene::from_file(&root().join(path)).unwrap_or_else(|e| panic!("{e}"))).unwrap_or_else(|e| panic!("{e}"));
    stage_sif(&mut s, 0, None, radii).unwrap_or_else(|e| panic!("{path}: {e}"))
}

fn tips(s: &StageSif) -> Vec<&TipSif> {
    s.tips.iter().map(|t| t.sif.as_ref().unwrap_or_else(|| panic!("tip {}: {:?}", t.point, t.error))).collect()
}

/// The factors of the inclined centre crack with their closed forms: (beta, scene).
const INCLINED: [(f64, &str); 4] =
    [(30.0, "configs/sif/inclined_30_t3.toml"), (45.0, "configs/sif/inclined_45_t3.toml"), (60.0, "configs/sif/inclined_60_t3.toml"), (45.0, "configs/sif/inclined_45_q4.toml")];

/// Inclined centre crack of half-length a = 1 in a plate 20 a wide under uniaxial tension s = 1
/// along y, the crack at beta to the load (configs/sif/inclined_*.toml). Reference: the infinite
/// plate, K_I = s sqrt(pi a) sin^2(beta), K_II = s sqrt(pi a) sin(beta) cos(beta) (e.g.
/// Anderson, Fracture Mechanics, sec. 2.7.1). Tolerance 2 % (issue 34) on both factors at both
/// tips, on every one of the three domains (r_out = 4, 6, 8 element sizes: the factors must not
/// depend on the domain); measured 0.0-0.5 % (docs/paths.md). The finite plate adds about
/// +0.6 % (Feddersen's secant factor), inside the tolerance. J (computed separately, quadratic in
/// the field) agrees with G = (K_I^2 + K_II^2) / E* within 2 %: a sign or factor error in either
/// integral, or the wrong E*, breaks it.
#[test]
fn inclined_centre_crack_factors_within_two_percent() {
    for (beta, path) in INCLINED {
        let b = beta.to_radians();
        let k0 = std::f64::consts::PI.sqrt();
        let (k1, k2) = (k0 * b.sin().powi(2), k0 * b.sin() * b.cos());
        let s = run(path, &Radii::default());
        let t = tips(&s);
        assert_eq!(t.len(), 2, "{path}: a centre crack has two tips");
        for tip in t {
            assert_eq!(tip.domains.len(), 3);
            for d in &tip.domains {
                assert!(rel(d.k1, k1) < 0.02 && rel(d.k2, k2) < 0.02, "{path} tip {} r_out {}: K_I {} (want {k1}), K_II {} (want {k2})", tip.tip.point, d.r_out, d.k1, d.k2);
                assert!(rel(d.j, d.g) < 0.02, "{path}: J {} vs G {}", d.j, d.g);
            }
            assert!(tip.spread < 0.005, "{path}: the domains differ by {}", tip.spread);
            // Cross-check by displacement correlation (faces within r_out / 2..r_out, linear
            // fit to r = 0): linear elements make it 3-10 % low here; 12 % catches a side or
            // sign mix-up.
            let [d1, d2, n] = tip.displacement_correlation.expect("face points behind the tip");
            assert!(n >= 2.0 && rel(d1, k1) < 0.12 && rel(d2, k2) < 0.12, "{path}: displacement correlation K_I {d1}, K_II {d2}");
        }
    }
}

/// Maximum tangential stress kink angles (Erdogan & Sih 1963, rationalised form, r = K_II /
/// K_I) from the computed factors of the inclined cracks: -60.0, -53.13, -43.22 deg for beta =
/// 30, 45, 60 (r = cot beta; ../shared/BENCHMARKS.md), measured from the crack's own direction,
/// counter-clockwise positive. Tolerance 1 deg (issue 34 asks 1-2); measured within 0.05 deg.
/// The kinked direction in the global frame is the crack's direction plus that angle.
#[test]
fn mts_angles_of_the_inclined_cracks_within_one_degree() {
    for (beta, path) in INCLINED {
        let r = 1.0 / beta.to_radians().tan();
        let want = (2.0 * (-2.0 * r / (1.0 + (1.0 + 8.0 * r * r).sqrt())).atan()).to_degrees();
        let tabled = match beta as i32 {
            30 => -60.0,
            45 => -53.13,
            _ => -43.22,
        };
        assert!((want - tabled).abs() < 0.01, "{want} vs the benchmark table's {tabled}");
        for tip in tips(&run(path, &Radii::default())) {
            let got = tip.mts_deg.expect("an open crack has an MTS angle");
            assert!((got - want).abs() < 1.0, "{path} tip {}: MTS {got} deg, want {want}", tip.tip.point);
            let dir = tip.tip.dir[1].atan2(tip.tip.dir[0]).to_degrees();
            let kink = tip.kink_direction_deg.unwrap();
            assert!(((kink - dir - got + 540.0) % 360.0 - 180.0).abs() < 1e-9);
        }
    }
    // Closed crack: no angle.
    assert!(mts_angle(-0.1, 0.2).is_none());
}

/// Edge crack of depth a in a strip of width W under uniform end tension s (configs/sif/edge_*):
/// Tada, Paris & Irwin's handbook, K_I = F(a/W) s sqrt(pi a), F = 1.12 - 0.231 x + 10.55 x^2 -
/// 21.72 x^3 + 30.39 x^4 (Brown & Srawley's fit of Gross, Srawley & Brown 1964, NASA TN D-2395:
/// their Y = 1.99 - 0.41 x + 18.70 x^2 - 38.48 x^3 + 53.85 x^4 is sqrt(pi) F; 0.5 % for a/W <=
/// 0.6). a/W = 0.3 on triangles in plane strain, 0.5 on quads in plane stress (the factor does
/// not depend on the plane; E* does: J = G checks it). Tolerance 2 % (issue 34); measured -1.3 %
/// on these small meshes, -0.5 % on a mesh ten times finer (docs/paths.md). K_II vanishes by
/// symmetry: |K_II| < 0.5 % of K_I.
#[test]
fn edge_crack_against_tada() {
    let f = |x: f64| 1.12 - 0.231 * x + 10.55 * x * x - 21.72 * x.powi(3) + 30.39 * x.powi(4);
    for (aw, path) in [(0.3, "configs/sif/edge_0.3_t3.toml"), (0.5, "configs/sif/edge_0.5_q4.toml")] {
        let want = f(aw) * (std::f64::consts::PI * aw).sqrt();
        let s = run(path, &Radii::default());
        let t = tips(&s);
        assert_eq!(t.len(), 1, "{path}: one tip (the mouth is on the boundary)");
        let tip = t[0];
        assert!((tip.tip.x[0] - aw).abs() < 1e-12 && tip.tip.x[1].abs() < 1e-12 && (tip.tip.dir[0] - 1.0).abs() < 1e-12);
        for d in &tip.domains {
            assert!(rel(d.k1, want) < 0.02, "{path} r_out {}: K_I {} want {want}", d.r_out, d.k1);
            assert!(d.k2.abs() < 0.005 * want, "{path}: K_II {}", d.k2);
            assert!(rel(d.j, d.g) < 0.02, "{path}: J {} vs G {}", d.j, d.g);
        }
        let plane_stress = path.contains("q4");
        let e_star = if plane_stress { 1000.0 } else { 1000.0 / (1.0 - 0.09) };
        assert!(rel(tip.e_star, e_star) < 1e-12, "{path}: E* {}", tip.e_star);
    }
}

/// `flem sif` prints the table and writes sif.json with the factors, the radii and the MTS
/// angle; `--tip` picks one tip. Same reference and tolerance as the inclined-crack test.
#[test]
fn cli_sif_writes_json() {
    let exe = crate::common::flem_exe();
    let dir = std::env::temp_dir().join(format!("flem-sif-{}", std::process::id()));
    let out = std::process::Command::new(exe)
        .args(["sif", root().join("configs/sif/inclined_45_t3.toml").to_str().unwrap(), "--stage", "1", "--tip", "0.7071,0.7071", "--radii", "4,8", "--out", dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("MTS kink"));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("sif.json")).unwrap()).unwrap();
    let tips = v["stages"][0]["tips"].as_array().unwrap();
    assert_eq!(tips.len(), 1);
    let k = (std::f64::consts::PI).sqrt() * 0.5;
    assert!(rel(tips[0]["k1"].as_f64().unwrap(), k) < 0.02 && rel(tips[0]["k2"].as_f64().unwrap(), k) < 0.02, "{}", tips[0]);
    assert_eq!(tips[0]["domains"].as_array().unwrap().len(), 2);
    assert!((tips[0]["mts_deg"].as_f64().unwrap() + 53.13).abs() < 1.0);
    // A point on no tip: exit 1, the message names the nearest tip.
    let bad = std::process::Command::new(exe).args(["sif", root().join("configs/sif/inclined_45_t3.toml").to_str().unwrap(), "--tip", "0,0", "--out", dir.to_str().unwrap()]).output().unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("is not on a crack tip"), "{}", String::from_utf8_lossy(&bad.stderr));
    let _ = std::fs::remove_dir_all(&dir);
}

/// The error of a scene text, or of the inclined scene with one change.
fn err_of(text: &str, at: Option<[f64; 2]>, radii: &Radii) -> String {
    let mut s = sim(text);
    match stage_sif(&mut s, 0, at, radii) {
        Err(e) => e.to_string(),
        Ok(r) => r.tips.iter().filter_map(|t| t.error.clone()).collect::<Vec<_>>().join("; "),
    }
}

fn inclined_text(change: impl Fn(String) -> String) -> String {
    let t = std::fs::read_to_string(root().join("configs/sif/inclined_45_t3.toml")).unwrap().replace("../meshes/", "meshes/");
    change(t)
}

/// Bad cases are refused by name: no crack, a point on no tip, a domain that leaves the body,
/// a support or a body force inside the domain, an element kind the integral does not support.
#[test]
fn named_refusals() {
    let none = Radii::default();
    // No pre-cut edges: no tip.
    let e = err_of(&inclined_text(|t| t.replace("separated = [\"crack\"]", "")), None, &none);
    assert!(e.contains("no crack tip found"), "{e}");
    // A point away from both tips.
    let e = err_of(&inclined_text(|t| t), Some([0.0, 0.0]), &none);
    assert!(e.contains("is not on a crack tip") && e.contains("nearest tip"), "{e}");
    // A domain larger than the plate.
    let e = err_of(&inclined_text(|t| t), None, &Radii::Absolute(vec![15.0]));
    assert!(e.contains("leaves the body"), "{e}");
    // A domain reaching the other tip.
    let e = err_of(&inclined_text(|t| t), None, &Radii::Absolute(vec![2.5]));
    assert!(e.contains("another crack tip (point"), "{e}");
    // A crack that does not run straight behind the tip (here: the tip's direction turned by
    // 10 deg, as a kinked crack would see it).
    let mut s = sim(&inclined_text(|t| t));
    let mut tip = crack_tips(&s.model)[1].clone();
    let (c, d) = (10f64.to_radians().cos(), 10f64.to_radians().sin());
    tip.dir = [c * tip.dir[0] - d * tip.dir[1], d * tip.dir[0] + c * tip.dir[1]];
    s.set_stage_levels(0);
    let u = flem_plugins::check::static_solve(&s).unwrap();
    let f = s.external_force().unwrap();
    let e = domain_sif(&s.model, &u, &s.state.fix, &f, &tip, 0.1, 0.2).unwrap_err().to_string();
    assert!(e.contains("not straight inside the domain"), "{e}");
    // Gravity: a body force inside the domain.
    let e = err_of(&inclined_text(|t| t.replace("separated = [\"crack\"]", "separated = [\"crack\"]\ngravity = [0.0, -1.0]")), None, &none);
    assert!(e.contains("applied force"), "{e}");
    // A support inside the domain (the crack faces' nodes held).
    let e = err_of(&inclined_text(|t| t.replace("nodes = \"roller\"", "nodes = \"crack\"")), None, &none);
    assert!(e.contains("support acts inside the domain"), "{e}");
    // qm6 (condensed internal modes): refused by name.
    let edge = std::fs::read_to_string(root().join("configs/sif/edge_0.5_q4.toml")).unwrap().replace("../meshes/", "meshes/");
    let e = err_of(&edge.replace("density = 1.0", "density = 1.0\nelement = \"qm6\""), None, &none);
    assert!(e.contains("\"qm6\"") && e.contains("q4"), "{e}");
    // Bad radius.
    let e = err_of(&inclined_text(|t| t), None, &Radii::Absolute(vec![f64::NAN]));
    assert!(e.contains("radii"), "{e}");
}

/// A tip made by a split, not by a pre-cut: cutting the edge ahead of the edge crack's tip at
/// the tip's cluster (`Topology::cut`, what a separation rule's proposal does) moves the tip to
/// that edge's far end, with the crack's direction along the cut edge.
#[test]
fn a_split_moves_the_tip() {
    let edge = std::fs::read_to_string(root().join("configs/sif/edge_0.3_t3.toml")).unwrap().replace("../meshes/", "meshes/");
    let mut s = sim(&edge);
    let tips = crack_tips(&s.model);
    assert_eq!(tips.len(), 1);
    let p = flem_core::ids::PointId::new(tips[0].point);
    let topo = &s.model.topo;
    let pts = &s.model.mesh.points;
    // The edge through the tip that points most nearly along +x.
    let ahead = *topo
        .point_edges
        .row(p.idx())
        .iter()
        .max_by(|a, b| {
            let dx = |e: &flem_core::ids::EdgeId| {
                let q = pts[topo.other_end(*e, p).idx()];
                let d = [q[0] - pts[p.idx()][0], q[1] - pts[p.idx()][1]];
                d[0] / d[0].hypot(d[1])
            };
            dx(a).total_cmp(&dx(b))
        })
        .unwrap();
    let q = topo.other_end(ahead, p);
    let c = topo.point_clusters[p.idx()][0];
    let rec = s.model.topo.cut(c, &[ahead], true);
    assert!(!rec.new_clusters.is_empty(), "the cut split the tip's cluster");
    s.apply_split_record(&rec);
    let tips = crack_tips(&s.model);
    assert_eq!(tips.len(), 1, "{tips:?}");
    assert_eq!(tips[0].point, q.idx());
    let (xp, xq) = (s.model.mesh.points[p.idx()], s.model.mesh.points[q.idx()]);
    let l = (xq[0] - xp[0]).hypot(xq[1] - xp[1]);
    assert!((tips[0].dir[0] - (xq[0] - xp[0]) / l).abs() < 1e-12 && (tips[0].dir[1] - (xq[1] - xp[1]) / l).abs() < 1e-12);
}

/// Reference: a uniform stress (a displacement linear in x and y, which T3 reproduces exactly),
/// for which `sigma_thetatheta = sxx sin^2(phi) + syy cos^2(phi) - sxy sin(2 phi)` at polar angle
/// `phi` about the tip. `hoop_profile` (ours, session 31, `tip_mts`'s `fork_ratio`) on the edge
/// crack's T3 mesh, tolerances 1e-9 relative and 1e-12 of the stress scale:
/// - equal biaxial strain: every non-empty bin's mean is the uniform value;
/// - `eps_yy` alone, with the tip's direction along the crack (+x) and turned by 30 deg: each
///   bin's mean lies between the formula's values at its edge angles (the formula is monotone
///   within each bin, and the bins' centroids lie in them), on both sides of the axis;
/// - a simple shear `u = (e y, 0)`: the hoop stress is odd in `phi`, positive below the axis and
///   negative above it (the sign of `theta`).
#[test]
fn hoop_profile_of_uniform_fields() {
    use flem_plugins::check::sif::{hoop_profile, CrackTip};
    let edge = std::fs::read_to_string(root().join("configs/sif/edge_0.3_t3.toml")).unwrap().replace("../meshes/", "meshes/");
    let s = sim(&edge);
    let tips = crack_tips(&s.model);
    let tip = &tips[0];
    assert!(tip.dir[0] > 1.0 - 1e-12, "the edge crack runs along +x: {:?}", tip.dir);
    let (r_in, r_out) = (1.0 * tip.h, 4.0 * tip.h);
    let d = s.model.material_of(flem_core::ids::ElemId::new(0)).dmat();
    let pts: Vec<[f64; 2]> = (0..s.model.topo.n_clusters()).map(|c| s.model.mesh.points[s.model.topo.cluster_point[c].idx()]).collect();
    let e = 1e-3;
    let field = |f: &dyn Fn([f64; 2]) -> [f64; 2]| -> Vec<[f64; 2]> { pts.iter().map(|&x| f(x)).collect() };
    // Equal biaxial strain e: sxx = syy = (d11 + d12) e, shear 0.
    let bins = hoop_profile(&s.model, &field(&|x| [e * x[0], e * x[1]]), tip, r_in, r_out).expect("linear T3 model");
    let want = (d.d11 + d.d12) * e;
    let n: u32 = bins.iter().map(|b| b.1).sum();
    for (k, &(sum, c)) in bins.iter().enumerate() {
        if c > 0 {
            assert!(rel(sum / c as f64, want) < 1e-9, "bin {k}: {} against {want}", sum / c as f64);
        }
    }
    assert!(n >= 20, "{n} elements in the ring");
    // eps_yy = e alone: sxx = d12 e, syy = d11 e; the tip's frame along +x and turned by 30 deg.
    let (sxx, syy) = (d.d12 * e, d.d11 * e);
    let f = |deg: f64| {
        let p = deg.to_radians();
        sxx * p.sin().powi(2) + syy * p.cos().powi(2)
    };
    let u = field(&|x| [0.0, e * x[1]]);
    for turn in [0.0f64, 30.0] {
        let t = CrackTip { dir: [turn.to_radians().cos(), turn.to_radians().sin()], ..tip.clone() };
        let bins = hoop_profile(&s.model, &u, &t, r_in, r_out).unwrap();
        let (mut below, mut above) = (0, 0);
        for (k, &(sum, c)) in bins.iter().enumerate() {
            if c == 0 {
                continue;
            }
            let (a, b) = (turn - 90.0 + 10.0 * k as f64, turn - 80.0 + 10.0 * k as f64);
            let (lo, hi) = (f(a).min(f(b)), f(a).max(f(b)));
            let v = sum / c as f64;
            assert!(v >= lo - 1e-12 * syy && v <= hi + 1e-12 * syy, "turn {turn}: bin {k} [{a}, {b}] deg: {v} not in [{lo}, {hi}]");
            if k < 9 {
                below += c;
            } else {
                above += c;
            }
        }
        assert!(below > 5 && above > 5, "turn {turn}: both sides of the axis hold elements: {below}, {above}");
    }
    // Simple shear: sxy = d33 e, hoop = -sxy sin(2 phi): > 0 below the axis, < 0 above.
    let bins = hoop_profile(&s.model, &field(&|x| [e * x[1], 0.0]), tip, r_in, r_out).unwrap();
    let tol = 1e-12 * d.d33 * e;
    for (k, &(sum, c)) in bins.iter().enumerate() {
        if c > 0 {
            let v = sum / c as f64;
            assert!(if k < 9 { v > -tol } else { v < tol }, "shear: bin {k} mean {v}");
        }
    }
    assert!(bins[2].0 > 0.0 && bins[15].0 < 0.0, "shear: the bins at -65 and +65 deg have the signs of -sin(2 phi)");
}

/// Reference: the mode I tip field (Williams; `u = K / (2 mu) sqrt(r / (2 pi)) [cos(t/2) (kappa -
/// 1 + 2 sin^2(t/2)), sin(t/2) (kappa + 1 - 2 cos^2(t/2))]`), whose hoop stress `K / sqrt(2 pi
/// r) cos^3(t/2)` peaks on the axis. Imposed on the edge crack's T3 mesh (plane strain):
/// the largest bin mean at 30 deg or more from the axis is below the axis value (`cos^3(theta/2)`
/// = 0.87 at 35 deg; measured 0.962, the bins mixing radii where the field goes as `r^-1/2`), so
/// `fork_signal` gives no fork even at ratio 1. A static crack does not fork.
#[test]
fn a_static_mode_one_tip_does_not_fork() {
    use flem_plugins::check::sif::hoop_profile;
    use flem_plugins::separation::tip_mts::fork_signal;
    let edge = std::fs::read_to_string(root().join("configs/sif/edge_0.3_t3.toml")).unwrap().replace("../meshes/", "meshes/");
    let s = sim(&edge);
    let tip = crack_tips(&s.model)[0].clone();
    let m = *s.model.material_of(flem_core::ids::ElemId::new(0));
    let mu = m.young / (2.0 * (1.0 + m.poisson));
    let kappa = 3.0 - 4.0 * m.poisson;
    let k1 = 1.0;
    let u: Vec<[f64; 2]> = (0..s.model.topo.n_clusters())
        .map(|c| {
            let x = s.model.mesh.points[s.model.topo.cluster_point[c].idx()];
            let (dx, dy) = (x[0] - tip.x[0], x[1] - tip.x[1]);
            let (r, t) = (dx.hypot(dy), dy.atan2(dx));
            let a = k1 / (2.0 * mu) * (r / (2.0 * std::f64::consts::PI)).sqrt();
            let (c2, s2) = ((0.5 * t).cos(), (0.5 * t).sin());
            [a * c2 * (kappa - 1.0 + 2.0 * s2 * s2), a * s2 * (kappa + 1.0 - 2.0 * c2 * c2)]
        })
        .collect();
    let bins = hoop_profile(&s.model, &u, &tip, 1.0 * tip.h, 4.0 * tip.h).unwrap();
    let mean = |k: usize| bins[k].0 / bins[k].1 as f64;
    let axis = 0.5 * (mean(8) + mean(9));
    let off = (0..=5).chain(12..=17).filter(|&k| bins[k].1 > 0).map(mean).fold(f64::NEG_INFINITY, f64::max);
    eprintln!("axis {axis:.4e}, largest bin at 30 deg or more {off:.4e} ({:.3})", off / axis);
    assert!(axis > 0.0 && off < axis, "axis {axis}, off-axis {off}");
    assert!(!fork_signal(&bins, 1.0));
}

/// A fork (ours, session 31: `TipPlan::fork`, what `tip_mts` proposes with `fork_ratio`) cuts
/// the crack face and two links at the tip in one cut: the tip's point falls in three clusters,
/// and the crack then has two tips, at the two links' far ends. Reference: the topology's
/// definition of a tip (the joined end of a separated edge).
#[test]
fn a_fork_makes_two_tips() {
    let edge = std::fs::read_to_string(root().join("configs/sif/edge_0.3_t3.toml")).unwrap().replace("../meshes/", "meshes/");
    let mut s = sim(&edge);
    let tips = crack_tips(&s.model);
    let p = flem_core::ids::PointId::new(tips[0].point);
    let face = flem_core::ids::EdgeId::new(tips[0].edge);
    let topo = &s.model.topo;
    let pts = &s.model.mesh.points;
    let xp = pts[p.idx()];
    // The links ahead of the tip nearest +20 deg and -20 deg.
    let nearest = |deg: f64, not: Option<flem_core::ids::EdgeId>| {
        let (c, sn) = (deg.to_radians().cos(), deg.to_radians().sin());
        *topo
            .point_edges
            .row(p.idx())
            .iter()
            .filter(|&&e| e != face && Some(e) != not)
            .max_by(|a, b| {
                let cosang = |e: &flem_core::ids::EdgeId| {
                    let q = pts[topo.other_end(*e, p).idx()];
                    let d = [q[0] - xp[0], q[1] - xp[1]];
                    (d[0] * c + d[1] * sn) / d[0].hypot(d[1])
                };
                cosang(a).total_cmp(&cosang(b))
            })
            .unwrap()
    };
    let a = nearest(20.0, None);
    let b = nearest(-20.0, Some(a));
    let (qa, qb) = (topo.other_end(a, p), topo.other_end(b, p));
    let c = topo.point_clusters[p.idx()][0];
    let rec = s.model.topo.cut(c, &[a, face, b], true);
    assert_eq!(rec.new_clusters.len(), 2, "the fork splits the tip's point in three");
    s.apply_split_record(&rec);
    assert_eq!(s.model.topo.point_clusters[p.idx()].len(), 3);
    let mut tips: Vec<usize> = crack_tips(&s.model).iter().map(|t| t.point).collect();
    tips.sort_unstable();
    let mut want = vec![qa.idx(), qb.idx()];
    want.sort_unstable();
    assert_eq!(tips, want, "two tips, at the links' far ends");
}
