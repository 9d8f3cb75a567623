//! Return-mapping tests of `mohr_coulomb`. References: the yield conditions and flow rule
//! themselves (on the surface, multipliers >= 0, plastic strain along the potential), the
//! variational inequality of the closest-point projection (associated flow), and the closed
//! form of a uniaxial-strain (oedometer) path in plane strain.
use super::*;

fn mat() -> Material {
    Material { young: 1000.0, poisson: 0.3, density: 1.0, thickness: 1.0, plane: Plane::Strain }
}

fn law(c: f64, phi_deg: f64, psi_deg: f64, st: Option<f64>) -> MohrCoulomb {
    MohrCoulombCfg { cohesion: c, friction_angle_deg: phi_deg, dilation_angle_deg: psi_deg, tension_cutoff: st, softening: None }.law(&mat())
}

/// Principal elastic compliance applied to a stress difference: `D^-1 ds`.
fn compliance(l: &MohrCoulomb, ds: [f64; 3]) -> [f64; 3] {
    let (lam, g) = (l.lambda, l.g);
    let e = g * (3.0 * lam + 2.0 * g) / (lam + g);
    let nu = lam / (2.0 * (lam + g));
    std::array::from_fn(|i| (ds[i] - nu * (ds[(i + 1) % 3] + ds[(i + 2) % 3])) / e)
}

fn f13(l: &MohrCoulomb, s: [f64; 3]) -> f64 {
    l.f(0, &s)
}

/// The admissible set: every plane in use.
fn admissible(l: &MohrCoulomb, s: &[f64; 3], tol: f64) -> bool {
    (0..6).filter(|&k| l.used & (1 << k) != 0).all(|k| l.f(k, s) <= tol)
}

/// A trial in the face region returns onto F13 = 0 with the plastic strain along the
/// potential G13 (non-associated, psi = 10 deg): de2p = 0, de1p / de3p = -(1 + sin psi) /
/// (1 - sin psi), and sigma_tr - sigma = D dep (consistency). Tolerance 1e-9 relative.
/// The median over points `[sxx, syy, sxy, szz]` of the cohesion that puts each on the
/// Mohr-Coulomb surface of friction angle `phi_deg` (`(s1 - s3) + (s1 + s3) sin phi = 2 c cos phi`,
/// compression negative).
fn median_cohesion_needed(stress: &[[f64; 4]], phi_deg: f64) -> f64 {
    let (sp, cp) = (phi_deg.to_radians().sin(), phi_deg.to_radians().cos());
    let mut need: Vec<f64> = stress
        .iter()
        .map(|s| {
            let (m, r) = (0.5 * (s[0] + s[1]), (0.25 * (s[0] - s[1]).powi(2) + s[2] * s[2]).sqrt());
            let (s1, s3) = ((m + r).max(s[3]), (m - r).min(s[3]));
            ((s1 - s3) + (s1 + s3) * sp) / (2.0 * cp)
        })
        .collect();
    need.sort_by(f64::total_cmp);
    need[need.len() / 2]
}

#[test]
fn face_return_is_on_the_surface_and_flows_along_the_potential() {
    let l = law(1.0, 30.0, 10.0, None);
    let tr = [0.0, -8.0, -20.0];
    assert!(f13(&l, tr) > 0.0);
    let (s, dep) = l.return_principal(tr).expect("plastic");
    assert!(f13(&l, s).abs() < 1e-9 * 20.0, "{s:?}");
    assert!(s[0] >= s[1] && s[1] >= s[2], "order kept: {s:?}");
    let sp = 10f64.to_radians().sin();
    assert!(dep[1].abs() < 1e-15);
    assert!((dep[0] / dep[2] + (1.0 + sp) / (1.0 - sp)).abs() < 1e-9, "{dep:?}");
    assert!(dep[0] > 0.0, "multiplier >= 0");
    let back = compliance(&l, [tr[0] - s[0], tr[1] - s[1], tr[2] - s[2]]);
    for d in 0..3 {
        assert!((back[d] - dep[d]).abs() < 1e-9 * dep[0].abs(), "consistency {back:?} {dep:?}");
    }
}

/// A trial with s2 close to s3 (compression meridian): the face return would put s3 above
/// s2; the edge return ends with s2 = s3 and both planes F13, F12 at 0. 1e-9 relative.
#[test]
fn edge_return_s2_equals_s3() {
    let l = law(1.0, 30.0, 30.0, None);
    let tr = [0.0, -19.0, -20.0];
    let (s, _) = l.return_principal(tr).unwrap();
    assert!((s[1] - s[2]).abs() < 1e-9 * 20.0, "{s:?}");
    assert!(l.f(0, &s).abs() < 1e-9 * 20.0 && l.f(2, &s).abs() < 1e-9 * 20.0, "{s:?}");
    assert!(admissible(&l, &s, 1e-9));
}

/// A trial with s1 close to s2 (extension meridian): edge s1 = s2, planes F13 and F23 at 0.
#[test]
fn edge_return_s1_equals_s2() {
    let l = law(1.0, 30.0, 30.0, None);
    let tr = [-1.0, -1.5, -25.0];
    let (s, _) = l.return_principal(tr).unwrap();
    assert!((s[0] - s[1]).abs() < 1e-9 * 25.0, "{s:?}");
    assert!(l.f(0, &s).abs() < 1e-9 * 25.0 && l.f(1, &s).abs() < 1e-9 * 25.0, "{s:?}");
    assert!(admissible(&l, &s, 1e-9));
}

/// Hydrostatic tension beyond the apex returns to the apex s1 = s2 = s3 = c cot(phi).
#[test]
fn apex_return() {
    let l = law(1.0, 30.0, 30.0, None);
    let apex = 1.0 / 30f64.to_radians().tan();
    for tr in [[5.0, 5.0, 5.0], [6.0, 4.0, 3.5]] {
        let (s, _) = l.return_principal(tr).unwrap();
        for v in s {
            assert!((v - apex).abs() < 1e-9 * 6.0, "{tr:?} -> {s:?}");
        }
    }
}

/// Tension cut-off sigma_t = 0.5 (below the apex 1.73): a trial with s1 = 2 and a small
/// deviator returns to s1 = sigma_t along D e1, i.e. ds2 = ds3 = lambda / (lambda + 2G) ds1.
#[test]
fn tension_cutoff_return() {
    let l = law(1.0, 30.0, 0.0, Some(0.5));
    let tr = [2.0, -0.2, -0.4];
    let (s, dep) = l.return_principal(tr).unwrap();
    assert!((s[0] - 0.5).abs() < 1e-12, "{s:?}");
    let ratio = l.lambda / (l.lambda + 2.0 * l.g);
    assert!(((tr[1] - s[1]) - ratio * (tr[0] - s[0])).abs() < 1e-12);
    assert!(dep[0] > 0.0 && dep[1] == 0.0 && dep[2] == 0.0);
    assert!(admissible(&l, &s, 1e-9));
    // The corner of the cut-off and the shear face: a corner point plus positive multiples of
    // D m13 and D e1 (the flow directions there) returns to that point.
    let s3 = (0.75 - 2.0 * 30f64.to_radians().cos()) / 0.5;
    let corner = [0.5, -1.0, s3];
    assert!(l.f(0, &corner).abs() < 1e-12);
    let tr: [f64; 3] = std::array::from_fn(|d| corner[d] + 0.7 * l.dm[0][d] * 1e-3 + 0.4 * l.dm[3][d] * 1e-3);
    let (s, dep) = l.return_principal(tr).unwrap();
    for d in 0..3 {
        assert!((s[d] - corner[d]).abs() < 1e-9, "{s:?} {corner:?}");
    }
    assert!((dep[0] - 1.1e-3).abs() < 1e-12 && (dep[2] + 0.7e-3).abs() < 1e-12, "{dep:?}");
}

/// Associated flow: the return is the closest point in the energy norm, so for every
/// admissible y, (sigma_tr - sigma) . D^-1 (y - sigma) <= 0 (projection onto a convex set).
/// Random trials and random admissible points (fixed seed); also: the return never leaves
/// the surface. Tolerance 1e-9 of the scale.
#[test]
fn associated_return_is_the_energy_norm_projection() {
    let mut seed: u64 = 12345;
    let mut rnd = || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for (phi, st) in [(30.0, None), (30.0, Some(0.4)), (0.0, None), (0.0, Some(1.0)), (45.0, Some(0.0))] {
        let l = law(1.0, phi, phi, st);
        let mut ys = Vec::new();
        while ys.len() < 300 {
            let mut y = [20.0 * rnd() - 15.0, 20.0 * rnd() - 15.0, 20.0 * rnd() - 15.0];
            y.sort_by(|a, b| b.partial_cmp(a).unwrap());
            if admissible(&l, &y, 0.0) {
                ys.push(y);
            }
        }
        for _ in 0..500 {
            let mut tr = [30.0 * rnd() - 20.0, 30.0 * rnd() - 20.0, 30.0 * rnd() - 20.0];
            tr.sort_by(|a, b| b.partial_cmp(a).unwrap());
            let Some((s, _)) = l.return_principal(tr) else {
                assert!(admissible(&l, &tr, 1e-9));
                continue;
            };
            assert!(admissible(&l, &s, 1e-8), "phi {phi} st {st:?}: {tr:?} -> {s:?}");
            let dp = compliance(&l, [tr[0] - s[0], tr[1] - s[1], tr[2] - s[2]]);
            for y in &ys {
                let v: f64 = (0..3).map(|d| dp[d] * (y[d] - s[d])).sum();
                assert!(v <= 1e-9, "phi {phi} st {st:?}: {tr:?} -> {s:?} not the projection (y = {y:?}: {v})");
            }
        }
    }
}

/// Plane strain, Tresca (phi = psi = 0, c = 1), uniaxial strain exx = -e (oedometer):
/// elastic sxx = (lambda + 2G) exx, syy = szz = lambda exx until sxx - syy = -2c, then
/// (incompressible plastic flow on the edge s1 = s2 = syy = szz) every component grows by
/// K dexx, K = lambda + 2G/3. Closed form; tolerance 1e-9 relative. The out-of-plane stress
/// szz follows the in-plane syy through the edge return.
#[test]
fn plane_strain_szz_on_an_oedometer_path() {
    let l = law(1.0, 0.0, 0.0, None);
    let (lam, g) = (l.lambda, l.g);
    let k = lam + 2.0 * g / 3.0;
    let (mut s, mut h) = ([0.0; 4], [0.0; 2]);
    let de = -1e-5;
    let n = 1000;
    for _ in 0..n {
        l.update(&mut s, [de, 0.0, 0.0, 0.0], &mut h);
    }
    let e = de * n as f64;
    let ey = -2.0 / (2.0 * g); // sxx - syy = 2 G exx reaches -2c
    assert!(e < ey);
    let sxx = (lam + 2.0 * g) * ey + k * (e - ey);
    let syy = lam * ey + k * (e - ey);
    assert!((s[0] - sxx).abs() < 1e-9 * sxx.abs(), "{s:?} {sxx}");
    assert!((s[1] - syy).abs() < 1e-9 * syy.abs(), "{s:?} {syy}");
    assert!((s[3] - syy).abs() < 1e-9 * syy.abs(), "szz {s:?} {syy}");
    assert!(s[2].abs() < 1e-12);
    assert_eq!(h[1], 1.0, "plastic now");
    // Plastic shear strain: de1p - de3p accumulated = the strain beyond yield times 2G/(2G)...
    // the plastic part of exx beyond yield: dexx_p = dexx - dsxx_dev/(2G) = (e - ey) (all deviatoric).
    let gp = (e - ey).abs() * (1.0 - 0.0);
    assert!((h[0] - gp).abs() < 1e-6 * gp.max(1e-12) + 1e-12, "{} {gp}", h[0]);
    // Unloading is elastic and marks the past.
    l.update(&mut s, [-de, 0.0, 0.0, 0.0], &mut h);
    assert_eq!(h[1], 2.0);
}

/// The return does not depend on the in-plane axes: a trial rotated by 30 degrees returns to
/// the rotated stress (isotropy). Tolerance 1e-9 relative.
#[test]
fn update_is_objective_in_plane() {
    let l = law(1.0, 30.0, 0.0, Some(0.5));
    let de = [2e-3, -5e-3, 3e-3, 0.0];
    let (mut s, mut h) = ([0.0, -1.0, 0.0, -0.5], [0.0; 2]);
    l.update(&mut s, de, &mut h);
    assert_eq!(h[1], 1.0);
    let th = 30f64.to_radians();
    let (c, sn) = (th.cos(), th.sin());
    let rot = |v: [f64; 4], shear_factor: f64| -> [f64; 4] {
        // v = [xx, yy, xy * shear_factor, zz] rotated by th (strain: engineering shear).
        let (xx, yy, xy) = (v[0], v[1], v[2] / shear_factor);
        [c * c * xx - 2.0 * c * sn * xy + sn * sn * yy, sn * sn * xx + 2.0 * c * sn * xy + c * c * yy, (c * sn * (xx - yy) + (c * c - sn * sn) * xy) * shear_factor, v[3]]
    };
    let (mut sr, mut hr) = (rot([0.0, -1.0, 0.0, -0.5], 1.0), [0.0; 2]);
    l.update(&mut sr, rot(de, 2.0), &mut hr);
    let want = rot(s, 1.0);
    for d in 0..4 {
        assert!((sr[d] - want[d]).abs() < 1e-9, "{sr:?} {want:?}");
    }
    assert!((hr[0] - h[0]).abs() < 1e-12);
}

/// Bad parameters are refused with the key.
#[test]
fn validate_names_the_key() {
    let bad = MohrCoulombCfg { cohesion: 1.0, friction_angle_deg: 30.0, dilation_angle_deg: 40.0, tension_cutoff: None, softening: None };
    assert_eq!(bad.validate(&mat()).unwrap_err().0, "dilation_angle_deg");
    let bad = MohrCoulombCfg { cohesion: 1.0, friction_angle_deg: 30.0, dilation_angle_deg: 0.0, tension_cutoff: Some(5.0), softening: None };
    assert_eq!(bad.validate(&mat()).unwrap_err().0, "tension_cutoff");
    let ps = Material { plane: Plane::Stress, ..mat() };
    let ok = MohrCoulombCfg { cohesion: 1.0, friction_angle_deg: 30.0, dilation_angle_deg: 0.0, tension_cutoff: None, softening: None };
    assert!(ok.validate(&ps).is_err());
}

/// Strength reduction (`flem fos`): c / F and tan(phi) / F, psi capped at the reduced phi, the
/// tension cut-off kept; the reduced law validates. Reference: the definition; 1e-12.
#[test]
fn strength_reduced_divides_c_and_tan_phi() {
    let cfg = MohrCoulombCfg { cohesion: 10.0, friction_angle_deg: 30.0, dilation_angle_deg: 30.0, tension_cutoff: Some(5.0), softening: None };
    let r = cfg.strength_reduced(2.0).expect("a strength");
    let v = toml::Value::try_from(&r).unwrap();
    let t = |k: &str| v.get(k).and_then(|x| x.as_float()).unwrap();
    assert!((t("cohesion") - 5.0).abs() < 1e-12);
    assert!((t("friction_angle_deg").to_radians().tan() - 30f64.to_radians().tan() / 2.0).abs() < 1e-12);
    assert!((t("dilation_angle_deg") - t("friction_angle_deg")).abs() < 1e-12);
    assert!((t("tension_cutoff") - 5.0).abs() < 1e-12);
    r.validate(&mat()).unwrap();
    let psi0 = MohrCoulombCfg { dilation_angle_deg: 0.0, ..cfg };
    let v = toml::Value::try_from(&psi0.strength_reduced(1.5).unwrap()).unwrap();
    assert_eq!(v.get("dilation_angle_deg").and_then(|x| x.as_float()), Some(0.0));
}

/// `update_lanes` (the stateful block's vectorised path: elastic trial, main-face return)
/// gives bit for bit what `update` gives point by point (the contract of
/// `MaterialLaw::update_lanes`), on stresses and increments spread over every return region
/// (elastic, face, edges, apex, tension cut-off), with full and partial packs.
/// Reference: `update` itself; tolerance: none (bitwise).
#[test]
fn update_lanes_is_update_bit_for_bit() {
    use flem_core::element::kernel::LANES;
    let laws = [law(1.0, 30.0, 10.0, None), law(1.0, 30.0, 0.0, Some(0.5)), law(1.0, 0.0, 0.0, None), law(0.0, 35.0, 35.0, Some(0.0))];
    let mut rnd = xorshift(0x9E37_79B9_7F4A_7C15);
    let (mut n_pl, mut n_el) = (0, 0);
    for law in &laws {
        for round in 0..400 {
            let n = if round % 5 == 4 { 1 + round % LANES } else { LANES };
            let mut s = [[0.0; LANES]; 4];
            let mut de = [[0.0; LANES]; 4];
            let mut hist = vec![0.0; LANES * 6];
            for l in 0..LANES {
                // Stress within a few cohesions, increments from tiny (elastic) to large.
                let scale = [0.01, 0.1, 1.0, 5.0][(round + l) % 4];
                for c in 0..4 {
                    s[c][l] = 2.0 * rnd() - 1.0;
                    de[c][l] = if c == 3 { 0.0 } else { scale * 0.01 * rnd() };
                }
                hist[l * 6] = rnd().abs();
                hist[l * 6 + 1] = [0.0, 1.0, 2.0][(round + 2 * l) % 3];
            }
            let (mut s_ref, mut h_ref) = (s, hist.clone());
            for l in 0..n {
                let mut sl = [s_ref[0][l], s_ref[1][l], s_ref[2][l], s_ref[3][l]];
                law.update(&mut sl, [de[0][l], de[1][l], de[2][l], de[3][l]], &mut h_ref[l * 6..l * 6 + 2]);
                for c in 0..4 {
                    s_ref[c][l] = sl[c];
                }
                if h_ref[l * 6 + 1] == 1.0 {
                    n_pl += 1;
                } else {
                    n_el += 1;
                }
            }
            law.update_lanes(&mut s, &de, &mut hist, 6, n);
            for l in 0..n {
                for c in 0..4 {
                    assert_eq!(s[c][l].to_bits(), s_ref[c][l].to_bits(), "stress {c} of lane {l}, round {round}");
                }
                assert_eq!(hist[l * 6].to_bits(), h_ref[l * 6].to_bits(), "plastic shear strain of lane {l}, round {round}");
                assert_eq!(hist[l * 6 + 1], h_ref[l * 6 + 1], "state of lane {l}, round {round}");
            }
        }
    }
    // Both paths are exercised: points that stay elastic and points that yield.
    assert!(n_el > 100 && n_pl > 100, "elastic {n_el}, plastic {n_pl}");
}

/// `update_lanes` against `update` lane by lane on trials that return to the edges and
/// corners (issue 37: the edge returns in lanes, `MohrCoulomb::edge_lanes`): the in-plane
/// stresses nearly equal (a small Mohr circle, radius `e`) and the out-of-plane one `b` away
/// from them, `|b|` from 1 to 6 cohesions, so that two principal stresses are close and the
/// trial lies beyond an edge `s1 = s2` or `s2 = s3` (for `b > 0` and `b < 0`), with the
/// tension planes on and off, associated and not. Reference: the scalar return
/// (`return_active`'s ordered search), bit for bit; the history too. Counts that the edge
/// sets were reached: lanes whose returned stress has two equal principal stresses.
#[test]
fn update_lanes_edges_are_update_bit_for_bit() {
    use flem_core::element::kernel::LANES;
    let laws = [law(1.0, 0.0, 0.0, None), law(1.0, 30.0, 10.0, None), law(1.0, 30.0, 30.0, Some(0.5)), law(2.0, 20.0, 0.0, Some(0.0))];
    let mut rnd = xorshift(0x2545_F491_4F6C_DD1D);
    let mut edges = 0;
    for law in &laws {
        for round in 0..300 {
            let n = if round % 7 == 6 { 1 + round % LANES } else { LANES };
            let mut s = [[0.0; LANES]; 4];
            let mut de = [[0.0; LANES]; 4];
            let mut hist = vec![0.0; LANES * 4];
            for l in 0..LANES {
                let (a, b, e) = (-3.0 * rnd().abs(), (1.0 + 5.0 * rnd().abs()) * if rnd() > 0.0 { 1.0 } else { -1.0 }, 0.05 * rnd());
                s[0][l] = a + e;
                s[1][l] = a - e;
                s[2][l] = 0.5 * e * rnd();
                s[3][l] = a + b;
                for c in 0..3 {
                    de[c][l] = 1e-4 * rnd();
                }
                hist[l * 4] = rnd().abs();
                hist[l * 4 + 1] = [0.0, 1.0, 2.0][(round + l) % 3];
            }
            let (mut s_ref, mut h_ref) = (s, hist.clone());
            for l in 0..n {
                let mut sl = [s_ref[0][l], s_ref[1][l], s_ref[2][l], s_ref[3][l]];
                law.update(&mut sl, [de[0][l], de[1][l], de[2][l], de[3][l]], &mut h_ref[l * 4..l * 4 + 2]);
                let (c, r) = (0.5 * (sl[0] + sl[1]), (0.25 * (sl[0] - sl[1]).powi(2) + sl[2] * sl[2]).sqrt());
                let close = |x: f64, y: f64| (x - y).abs() < 1e-9 * (1.0 + x.abs());
                if h_ref[l * 4 + 1] == 1.0 && (close(c + r, sl[3]) || close(c - r, sl[3]) || r < 1e-12) {
                    edges += 1;
                }
                for c in 0..4 {
                    s_ref[c][l] = sl[c];
                }
            }
            law.update_lanes(&mut s, &de, &mut hist, 4, n);
            for l in 0..n {
                for c in 0..4 {
                    assert_eq!(s[c][l].to_bits(), s_ref[c][l].to_bits(), "stress {c} of lane {l}, round {round}");
                }
                assert_eq!(hist[l * 4].to_bits(), h_ref[l * 4].to_bits(), "plastic shear strain of lane {l}, round {round}");
                assert_eq!(hist[l * 4 + 1], h_ref[l * 4 + 1], "state of lane {l}, round {round}");
            }
        }
    }
    assert!(edges > 1000, "only {edges} returns to an edge or a corner");
}

/// The pre-test's slack (`slack_lanes`, session 37) on special stresses: zeros of either sign,
/// ones, 1e155 (whose squares overflow), infinities and NaN in every component. A lane it
/// passes (`slack >= 0`) must pass `trial`'s quick test, the exact test `update` uses (the
/// trial is then the answer), and the former boolean pre-test (2cd6d0f's `inside_lanes`,
/// written out below as the reference); on finite states the two pre-tests agree exactly.
/// Tolerance: none (booleans).
#[test]
fn pre_test_passes_only_lanes_inside_nan_and_infinities_included() {
    use flem_core::element::kernel::LANES;
    let old_inside = |law: &MohrCoulomb, mid: f64, rr: f64, pz: f64| {
        let (ka, kb, r) = (law.n[0][0], -law.n[0][2], law.r[0]);
        let [ra, ba, rb, ab] = law.pre;
        let lo = |a: f64, b: f64| if a < b { a } else { b };
        let mut x = lo(lo(0.5 * (r - (ka - kb) * mid), ra + ba * pz - mid), rb - ab * pz + mid);
        let mut z_ok = true;
        if law.used & 8 != 0 {
            x = lo(x, law.r[3] - mid);
            z_ok = pz <= law.r[3];
        }
        (x >= 0.0) & (rr <= x * x) & z_ok
    };
    let laws = [law(1.0, 0.0, 0.0, None), law(1.0, 30.0, 10.0, None), law(1.0, 30.0, 0.0, Some(0.5)), law(0.5, 40.0, 40.0, Some(0.2))];
    let v = [0.0, -0.0, 0.25, -0.25, 1.0, -1.0, 1e155, -1e155, f64::INFINITY, f64::NEG_INFINITY, f64::NAN];
    let mut rnd = xorshift(0x0F1E_2D3C_4B5A_6978);
    let (mut passed, mut special) = (0, 0);
    for law in &laws {
        for _ in 0..2000 {
            let mut s = [[0.0; LANES]; 4];
            for c in s.iter_mut() {
                for x in c.iter_mut() {
                    *x = v[(rnd().abs() * 11.0) as usize % 11];
                }
            }
            let (mid, _, rr) = mohr_circle(&s);
            let slack = law.slack_lanes(&mid, &rr, &s[3]);
            for l in 0..LANES {
                let st = [s[0][l], s[1][l], s[2][l], s[3][l]];
                let old = old_inside(law, mid[l], rr[l], s[3][l]);
                if slack[l] >= 0.0 {
                    passed += 1;
                    assert!(law.trial(&st, [0.0; 4]).inside, "{st:?}: the pre-test passes a lane the quick test fails");
                    assert!(old, "{st:?}: the pre-test passes a lane the former one failed");
                }
                if st.iter().all(|x| x.abs() < 1e150) {
                    assert_eq!(slack[l] >= 0.0, old, "{st:?}: the two pre-tests differ on a finite state");
                } else {
                    special += 1;
                }
            }
        }
    }
    assert!(passed > 1000 && special > 10000, "passed {passed}, special {special}");
}

/// `update_points_lanes` (the four points of a Q4 pack at once, the points that yield in one
/// call) against `update_lanes` point by point, which the test above ties to `update`: packs
/// whose points stay elastic, yield to the face, to an edge, or mix, with the tension planes
/// on and off, full and partial packs, of 4 points and of 1, 3 and 5 (more than it takes
/// together). It checks the routing and the offsets; the return's bits come from the tests of
/// `update_lanes` and of the AVX-512 return. Reference: `update_lanes`; tolerance: none (bitwise).
#[test]
fn update_points_lanes_is_update_lanes_point_by_point() {
    use flem_core::element::kernel::LANES;
    let laws = [law(1.0, 30.0, 10.0, None), law(1.0, 30.0, 0.0, Some(0.5)), law(1.0, 0.0, 0.0, None), law(0.0, 35.0, 35.0, Some(0.0))];
    let mut rnd = xorshift(0x3C6E_F372_FE94_F82B);
    let ns = 2;
    let mut mixed = 0;
    // Four points (a Q4 pack), fewer, and more than `update_points_lanes` takes together (it
    // then goes point by point).
    for (law, ng) in laws.iter().flat_map(|l| [4, 1, 3, 5].map(|ng| (l, ng))) {
        let stride = ng * ns;
        for round in 0..150 {
            let n = if round % 5 == 4 { 1 + round % LANES } else { LANES };
            let mut s = vec![[[0.0; LANES]; 4]; ng];
            let mut de = vec![[[0.0; LANES]; 4]; ng];
            let mut hist = vec![0.0; LANES * stride];
            for k in 0..ng {
                // Per point: tiny increments (elastic), or large ones (returns).
                let size = [1e-6, 1e-2, 5e-2, 1e-5][(round + k) % 4];
                for l in 0..LANES {
                    for c in 0..4 {
                        // Small increments from small stresses (mostly elastic), large ones
                        // from stresses of the cohesion's size.
                        s[k][c][l] = if size < 1e-4 { -0.2 + 0.05 * rnd() } else { 2.0 * rnd() - 1.0 };
                        de[k][c][l] = if c == 3 { 0.0 } else { size * rnd() };
                    }
                    hist[l * stride + k * ns] = rnd().abs();
                    hist[l * stride + k * ns + 1] = [0.0, 1.0, 2.0][(round + k + l) % 3];
                }
            }
            let (mut s_ref, mut h_ref) = (s.clone(), hist.clone());
            for k in 0..ng {
                law.update_lanes(&mut s_ref[k], &de[k], &mut h_ref[k * ns..], stride, n);
            }
            law.update_points_lanes(&mut s, &de, &mut hist, stride, n);
            for k in 0..ng {
                for l in 0..LANES {
                    for c in 0..4 {
                        assert_eq!(s[k][c][l].to_bits(), s_ref[k][c][l].to_bits(), "stress {c} of point {k}, lane {l}, round {round}");
                    }
                }
            }
            assert!(hist.iter().zip(&h_ref).all(|(a, b)| a.to_bits() == b.to_bits()), "history, round {round}");
            let yielded = (0..ng).filter(|&k| (0..n).any(|l| h_ref[l * stride + k * ns + 1] == 1.0)).count();
            mixed += usize::from(yielded > 0 && yielded < ng);
        }
    }
    // Packs where some points yield and others stay elastic were met.
    assert!(mixed > 100, "only {mixed} mixed packs");
}

/// The yielding lanes written with AVX-512 intrinsics (`mohr_coulomb_avx512.rs`, what
/// `update_lanes` runs on a CPU that has AVX-512) against the generic body (`yield_lanes_body`,
/// what it runs elsewhere), on trial states like those of the two tests above (anywhere within
/// a few cohesions, and near the edges: every return region, tension planes on and off, full
/// and partial packs) and on packs holding special values (zeros of either sign, a zero Mohr
/// radius, NaN and infinite stresses). Reference: the generic body, which
/// `update_lanes_is_update_bit_for_bit` ties to `update`; tolerance: none (bitwise; a NaN
/// against a NaN whatever its payload). The outputs start from different sentinels, so a lane
/// one side leaves unwritten fails; counts that the face, the edges in lanes and the scalar
/// returns were all reached. On a CPU without AVX-512 it passes without comparing (and says
/// so on stderr).
#[test]
fn avx512_yield_is_the_generic_body_bit_for_bit() {
    use flem_core::element::kernel::LANES;
    #[cfg(target_arch = "x86_64")]
    {
        if !(std::arch::is_x86_feature_detected!("avx512f") && std::arch::is_x86_feature_detected!("avx512vl") && std::arch::is_x86_feature_detected!("avx512dq")) {
            eprintln!("avx512_yield_is_the_generic_body_bit_for_bit: no AVX-512 on this CPU, skipped");
            return;
        }
        let laws =
            [law(1.0, 30.0, 10.0, None), law(1.0, 30.0, 0.0, Some(0.5)), law(1.0, 0.0, 0.0, None), law(0.0, 35.0, 35.0, Some(0.0)), law(2.0, 20.0, 0.0, Some(0.0)), law(1.0, 30.0, 30.0, Some(0.5))];
        let mut rnd = xorshift(0x51_7CC1_B727_220A);
        let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        let mut counted = [0usize; 3];
        // Face returns; edges of a law without tension planes (`edge_lanes`); edges and corners
        // with them (the scalar `plastic_update`).
        let mut paths = [0usize; 3];
        for law in &laws {
            for round in 0..600 {
                let n = if round % 5 == 4 { 1 + round % LANES } else { LANES };
                let mut ts = [[0.0; LANES]; 4];
                for l in 0..LANES {
                    match (round + l) % 3 {
                        // Anywhere within a few cohesions.
                        0 => {
                            for c in ts.iter_mut() {
                                c[l] = 4.0 * rnd();
                            }
                        }
                        // Near an edge: a small Mohr circle, szz away from it.
                        1 => {
                            let (a, b, e) = (-3.0 * rnd().abs(), (1.0 + 5.0 * rnd().abs()) * rnd().signum(), 0.05 * rnd());
                            (ts[0][l], ts[1][l], ts[2][l], ts[3][l]) = (a + e, a - e, 0.5 * e * rnd(), a + b);
                        }
                        // Special values.
                        _ => {
                            let v = [0.0, -0.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1.0, -1.0];
                            for c in ts.iter_mut() {
                                c[l] = v[(rnd().abs() * 7.0) as usize % 7];
                            }
                        }
                    }
                }
                // `update_lanes`' trial quantities, as it computes them.
                let (mid, half, rr) = mohr_circle(&ts);
                let mut hist = vec![0.0; LANES * 4];
                for l in 0..LANES {
                    hist[l * 4] = rnd().abs();
                    hist[l * 4 + 1] = [0.0, 1.0, 2.0][(round + l) % 3];
                }
                let (mut s_ref, mut h_ref) = ([[-999.0; LANES]; 4], hist.clone());
                law.yield_lanes_body(&mut s_ref, &ts, &half, &mid, &rr, &mut h_ref, 4, n);
                let mut s = [[1234.5; LANES]; 4];
                // SAFETY: the CPU has AVX-512 (checked above).
                unsafe { law.yield_lanes_avx512(&mut s, &ts, &half, &mid, &rr, &mut hist, 4, n) };
                for l in 0..LANES {
                    for c in 0..4 {
                        assert!(same(s[c][l], s_ref[c][l]), "stress {c} of lane {l}, round {round}: {} against {}", s[c][l], s_ref[c][l]);
                    }
                    assert!(same(hist[l * 4], h_ref[l * 4]), "plastic shear strain of lane {l}, round {round}");
                    assert!(same(hist[l * 4 + 1], h_ref[l * 4 + 1]), "state of lane {l}, round {round}");
                    if l < n {
                        counted[(round + l) % 3] += usize::from(h_ref[l * 4 + 1] == 1.0);
                        // Which return a finite plastic lane took: two equal principal
                        // stresses (an edge or a corner) or not (the face).
                        let sl = [s_ref[0][l], s_ref[1][l], s_ref[2][l], s_ref[3][l]];
                        if h_ref[l * 4 + 1] == 1.0 && sl.iter().all(|v| v.is_finite()) {
                            let (c, r) = (0.5 * (sl[0] + sl[1]), (0.25 * (sl[0] - sl[1]).powi(2) + sl[2] * sl[2]).sqrt());
                            let close = |x: f64, y: f64| (x - y).abs() < 1e-9 * (1.0 + x.abs());
                            let edge = close(c + r, sl[3]) || close(c - r, sl[3]) || r < 1e-12;
                            paths[usize::from(edge) + usize::from(law.r[3].is_finite() && edge)] += 1;
                        }
                    }
                }
            }
        }
        // Returns happened in the random and the edge packs (the special values mostly give NaN).
        assert!(counted[0] > 1000 && counted[1] > 1000, "returns counted: {counted:?}");
        assert!(paths.iter().all(|&c| c > 100), "face, edges in lanes, scalar edges and corners: {paths:?}");
    }
}

/// The never-yielded shortcut of the stateful block (`StatefulOpts::elastic_shortcut`: a pack
/// whose points never yielded takes the stress of the total strain and stores nothing)
/// against the stored path (every point's stress updated incrementally), on a distorted
/// 6 x 3 Q4 mesh (two full packs and a part pack), B-bar on and off, under a non-uniform
/// displacement field raised in 40 steps. Reference: the stored path, which is the law's
/// `update` applied step by step. Cohesion: the median of what the points need at the last
/// step, so about half the points yield on the way and the rest never do. Tolerances: 1e-12
/// relative (of the largest value) on every point's stress and every nodal force while no
/// point has yielded, 1e-9 after (the yielding points' trial, `s_n + D de` against `D eps`,
/// differs in round-off only), the same on the internal work (`strain_energy`), and the same
/// plastic state per element. Stress and work are read at the next step's displacements: both
/// paths must answer at the time level of the last element pass.
#[test]
fn never_yielded_shortcut_matches_the_stored_path() {
    use flem_core::element::block::Block;
    use flem_core::element::law::{LawCfg, StatefulOpts};
    let (nx, ny) = (6usize, 3usize);
    let (nodes, elems) = distorted_q4(nx, ny);
    let field = |a: f64| -> Vec<[f64; 2]> { nodes.iter().map(|p| [a * (0.02 * p[1] * p[1] - 0.01 * p[0]), a * (-0.015 * p[1] + 0.004 * p[0] * p[1])]).collect() };
    let (steps, nn) = (40, nodes.len());
    let cfg = |c: f64| MohrCoulombCfg { cohesion: c, friction_angle_deg: 30.0, dilation_angle_deg: 5.0, tension_cutoff: None, softening: None };
    let block = |c: f64, bbar: bool, shortcut: bool| {
        let mut b = cfg(c).build("r", mat(), StatefulOpts { bbar, large_strain: false, elastic_shortcut: shortcut }, &elems).pop().unwrap();
        b.prepare(nn);
        b
    };
    for bbar in [true, false] {
        // The cohesion each point needs at the last step (elastic stresses), then their median.
        let mut probe = block(1e9, bbar, false);
        let mut f = vec![[0.0; 2]; nn];
        let u1 = field(1.0);
        probe.update_internal_forces(&u1, &mut f, None);
        let c = median_cohesion_needed(&probe.point_stress(&u1).unwrap(), 30.0);
        assert!(c > 0.0, "the field must load the points in shear");
        let (mut a, mut b) = (block(c, bbar, true), block(c, bbar, false));
        let mut yielded_once = false;
        for step in 1..=steps {
            let u = field(step as f64 / steps as f64);
            let (mut fa, mut fb) = (vec![[0.0; 2]; nn], vec![[0.0; 2]; nn]);
            a.update_internal_forces(&u, &mut fa, None);
            b.update_internal_forces(&u, &mut fb, None);
            let plastic = |blk: &Box<dyn Block>| (0..blk.len()).map(|i| blk.plastic(i).unwrap().1).collect::<Vec<_>>();
            let (pa, pb) = (plastic(&a), plastic(&b));
            assert_eq!(pa, pb, "bbar {bbar} step {step}: plastic states");
            yielded_once |= pb.iter().any(|&s| s > 0);
            let tol = if yielded_once { 1e-9 } else { 1e-12 };
            let fmax = fb.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
            for (x, y) in fa.iter().flatten().zip(fb.iter().flatten()) {
                assert!((x - y).abs() <= tol * fmax, "bbar {bbar} step {step}: force {x} against {y}");
            }
            // Read at other displacements (as a failure check after the node update does):
            // every point answers at the time level of the last element pass.
            let un = field((step + 1) as f64 / steps as f64);
            let (sa, sb) = (a.point_stress(&un).unwrap(), b.point_stress(&un).unwrap());
            let smax = sb.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
            for (x, y) in sa.iter().flatten().zip(sb.iter().flatten()) {
                assert!((x - y).abs() <= tol * smax, "bbar {bbar} step {step}: stress {x} against {y}");
            }
            let (ea, eb) = (a.strain_energy(&un).unwrap(), b.strain_energy(&un).unwrap());
            assert!((ea - eb).abs() <= tol * eb.abs().max(1e-300), "bbar {bbar} step {step}: strain energy {ea} against {eb}");
        }
        let last = (0..b.len()).filter(|&i| b.plastic(i).unwrap().1 > 0).count();
        assert!(last > 0 && last < b.len(), "bbar {bbar}: {last} of {} elements plastic: the test needs both kinds", b.len());
    }
}

/// The never-yielded pass in `q4`'s own form (parent coordinates, `Shape::total_strains` and
/// `total_forces`, session 11) against the same pass on the generic isoparametric geometry
/// (`StatefulBlock::generic_total`: gradients, Jacobians and the B-bar mean gradient at the
/// Gauss points, the form of session 10). Meshes of 8 x 3 Q4 (three packs) plus a part pack
/// of 5: parallelograms (sheared grid: the lean form), every element distorted (the full form),
/// and one row of packs distorted (both forms in one block); B-bar on and off; a non-uniform
/// field raised in 30 steps past the first yield. Reference: the generic form, whose B-bar
/// mean is `sum_k w_k det J_k B_k / sum_k w_k det J_k` from the gradients themselves.
/// Tolerances: every nodal force within 1e-12 of the largest while no point has yielded, the
/// plastic state of every element equal at every step (a pack leaves the shortcut at the same
/// step: the elastic test sees the same strain to round-off; the cohesion is the median need
/// of the last step, so about half the points cross the surface), the forces within 1e-9
/// after (both then run the stored path, seeded from strains equal to round-off).
/// The same with the shortcut off (`elastic_shortcut = false`: every pack on the stored path
/// from the first step): the stored path's strain increments and forces in `q4`'s own form
/// (session 30) against the stored gradients (`generic_total`), same tolerances. Every case
/// at thickness 0.7, and every point's stress and the internal work compared too.
#[test]
fn q4_total_form_matches_the_generic_shortcut() {
    use crate::elements::Q4;
    use flem_core::element::block::Block;
    use flem_core::element::law::StatefulOpts;
    use flem_core::element::stateful::StatefulBlock;
    use flem_core::ids::ElemId;
    let (nx, ny) = (8usize, 3usize);
    let meshes: [(&str, fn(f64, f64) -> [f64; 2]); 3] = [
        ("parallelogram", |x, y| [x + 0.25 * y, 0.75 * y]),
        ("distorted", |x, y| [x + 0.2 * (0.7 * y + 0.3 * x).sin(), y + 0.15 * (0.9 * x).cos()]),
        ("mixed", |x, y| if y >= 1.0 && y <= 2.0 { [x + 0.2 * (0.7 * y + 0.3 * x).sin() * (y - 1.0), y + 0.15 * (0.9 * x).cos() * (y - 1.0)] } else { [x, y] }),
    ];
    for (name, xy) in meshes {
        let mut nodes: Vec<[f64; 2]> = (0..=ny).flat_map(|j| (0..=nx).map(move |i| (i, j))).map(|(i, j)| xy(i as f64, j as f64)).collect();
        let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
        let mut cells: Vec<[u32; 4]> = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                cells.push([id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        // A part pack of 5 more elements on top (a row of its own nodes).
        let top = nodes.len() as u32;
        for i in 0..=5 {
            let p = xy(i as f64, (ny + 1) as f64);
            nodes.push([p[0] + 0.05 * i as f64, p[1] + 0.1 * (i % 2) as f64]);
        }
        for i in 0..5 {
            cells.push([id(i, ny), id(i + 1, ny), top + i as u32 + 1, top + i as u32]);
        }
        let nn = nodes.len();
        let field = |a: f64| -> Vec<[f64; 2]> { nodes.iter().map(|p| [a * (0.02 * p[1] * p[1] - 0.01 * p[0]), a * (-0.015 * p[1] + 0.004 * p[0] * p[1])]).collect() };
        let block = |c: f64, bbar: bool, generic: bool, shortcut: bool| -> Box<dyn Block> {
            let l = MohrCoulombCfg { cohesion: c, friction_angle_deg: 30.0, dilation_angle_deg: 5.0, tension_cutoff: None, softening: None }.law(&mat());
            // Thickness 0.7: the kind's form and the generic weights must carry it alike.
            let mut b = StatefulBlock::<Q4, MohrCoulomb, 4>::new("r".into(), Material { thickness: 0.7, ..mat() }, l, StatefulOpts { bbar, large_strain: false, elastic_shortcut: shortcut });
            if generic {
                b = b.generic_total();
            }
            for (e, c) in cells.iter().enumerate() {
                b.push(ElemId::new(e), c.map(|k| nodes[k as usize]), *c);
            }
            b.prepare(nn);
            Box::new(b)
        };
        for (bbar, shortcut) in [(true, true), (false, true), (true, false), (false, false)] {
            // The median cohesion the points need at the last step (elastic stresses).
            let mut probe = block(1e9, bbar, true, true);
            let u1 = field(1.0);
            probe.update_internal_forces(&u1, &mut vec![[0.0; 2]; nn], None);
            let c = median_cohesion_needed(&probe.point_stress(&u1).unwrap(), 30.0);
            let (mut a, mut b) = (block(c, bbar, false, shortcut), block(c, bbar, true, shortcut));
            let mut yielded_once = false;
            for step in 1..=30 {
                let u = field(step as f64 / 30.0);
                let (mut fa, mut fb) = (vec![[0.0; 2]; nn], vec![[0.0; 2]; nn]);
                a.update_internal_forces(&u, &mut fa, None);
                b.update_internal_forces(&u, &mut fb, None);
                let plastic = |blk: &Box<dyn Block>| (0..blk.len()).map(|i| blk.plastic(i).unwrap().1).collect::<Vec<_>>();
                let (pa, pb) = (plastic(&a), plastic(&b));
                assert_eq!(pa, pb, "{name} bbar {bbar} shortcut {shortcut} step {step}: plastic states");
                yielded_once |= pb.iter().any(|&s| s > 0);
                let tol = if yielded_once { 1e-9 } else { 1e-12 };
                let fmax = fb.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
                assert!(fmax > 0.0);
                for (x, y) in fa.iter().flatten().zip(fb.iter().flatten()) {
                    assert!((x - y).abs() <= tol * fmax, "{name} bbar {bbar} shortcut {shortcut} step {step}: force {x} against {y}");
                }
                // Every point's stress and the internal work (the energy ledger's term).
                let (sa, sb) = (a.point_stress(&u).unwrap(), b.point_stress(&u).unwrap());
                let smax = sb.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
                for (x, y) in sa.iter().flatten().zip(sb.iter().flatten()) {
                    assert!((x - y).abs() <= tol * smax, "{name} bbar {bbar} shortcut {shortcut} step {step}: stress {x} against {y}");
                }
                let (ea, eb) = (a.strain_energy(&u).unwrap(), b.strain_energy(&u).unwrap());
                assert!(eb > 0.0 && (ea - eb).abs() <= tol * eb, "{name} bbar {bbar} shortcut {shortcut} step {step}: work {ea} against {eb}");
            }
            let last = (0..b.len()).filter(|&i| b.plastic(i).unwrap().1 > 0).count();
            assert!(last > 0 && last < b.len(), "{name} bbar {bbar}: {last} of {} plastic: the test needs both", b.len());
        }
    }
}

/// The square-root-free pre-test of `update_lanes` (`MohrCoulomb::inside_lanes`) against the
/// quick test of `trial` (the reference), on random trial states clearly inside, clearly
/// outside and within round-off of the yield surface (main face, tension cut-off, every order
/// of `szz` among the in-plane principal stresses), for Tresca, Mohr-Coulomb with and without
/// a cut-off. Tolerance: the two tests agree wherever the reference's `F_13` (or the cut-off's
/// value) is beyond 1e-9 of the stress scale; on the surface they may differ, and there
/// `update_lanes` must still give `update`'s bits (the pre-test only routes a pack).
#[test]
fn elastic_pre_test_agrees_with_the_quick_test() {
    use flem_core::element::kernel::LANES;
    let laws = [law(1.0, 0.0, 0.0, None), law(1.0, 30.0, 10.0, None), law(1.0, 30.0, 0.0, Some(0.5)), law(0.5, 40.0, 40.0, Some(0.2))];
    let mut rnd = xorshift(0x2545_F491_4F6C_DD1D);
    let (mut agree_in, mut agree_out, mut near) = (0, 0, 0);
    for law in &laws {
        for round in 0..300 {
            let mut s = [[0.0; LANES]; 4];
            let de = [[0.0; LANES]; 4];
            for l in 0..LANES {
                // A principal state scaled onto the main face (or the cut-off), then pushed in or out.
                let (sa, sb, sz) = (3.0 * rnd(), 3.0 * rnd(), 3.0 * rnd());
                let (hi, lo) = (sa.max(sb).max(sz), sa.min(sb).min(sz));
                let f = law.f(0, &[hi, 0.0, lo]) + law.r[0];
                let k = match (round + l) % 4 {
                    0 => 1.0 + 1e-15 * rnd(),
                    1 => 0.5 + 0.4 * rnd().abs(),
                    2 => 1.2 + rnd().abs(),
                    _ => 1.0,
                };
                let t = if f > 0.0 { k * law.r[0] / f } else { 1.0 };
                let th = 3.0 * rnd();
                let (m, h) = (0.5 * (sa + sb) * t, 0.5 * (sa - sb) * t);
                s[0][l] = m + h * th.cos();
                s[1][l] = m - h * th.cos();
                s[2][l] = h * th.sin();
                s[3][l] = sz * t;
            }
            let (mid, _, rr) = mohr_circle(&s);
            let pre = law.inside_lanes(&mid, &rr, &s[3]);
            for l in 0..LANES {
                let t = law.trial(&[s[0][l], s[1][l], s[2][l], s[3][l]], [0.0; 4]);
                let (hi, lo) = (t.pa.max(t.pz), t.pb.min(t.pz));
                let f13 = law.f(0, &[hi, 0.0, lo]);
                let t1 = if law.r[3].is_finite() { hi - law.r[3] } else { f64::NEG_INFINITY };
                let margin = f13.max(t1);
                if margin.abs() > 1e-9 * (1.0 + hi.abs().max(lo.abs())) {
                    assert_eq!(pre[l], t.inside, "state {:?}: pre-test {} vs quick test {} (F_13 {f13:.3e}, T_1 {t1:.3e})", t.s, pre[l], t.inside);
                    if t.inside {
                        agree_in += 1;
                    } else {
                        agree_out += 1;
                    }
                } else {
                    near += 1;
                }
            }
            // Whatever the pre-test said, the pack gives `update`'s bits (a zero increment from
            // these states: the return of the ones outside, the trial for the others).
            let mut sl = s;
            let mut hist = vec![0.0; LANES * 2];
            law.update_lanes(&mut sl, &de, &mut hist, 2, LANES);
            for l in 0..LANES {
                let mut r = [s[0][l], s[1][l], s[2][l], s[3][l]];
                let mut h = [0.0; 2];
                law.update(&mut r, [0.0; 4], &mut h);
                for c in 0..4 {
                    assert_eq!(sl[c][l].to_bits(), r[c].to_bits(), "lane {l} component {c}");
                }
                assert_eq!(hist[2 * l].to_bits(), h[0].to_bits());
            }
        }
    }
    eprintln!("inside {agree_in}, outside {agree_out}, on the surface {near}");
    assert!(agree_in > 500 && agree_out > 500 && near > 100, "inside {agree_in}, outside {agree_out}, near {near}");
}

/// A small deterministic generator (xorshift) from `seed`, values in [-1, 1): the random states
/// of the bit-for-bit tests above.
/// Mohr's circle of a pack's stresses as `update_lanes` computes it: the centre, half the
/// in-plane difference and the squared radius, by lane.
fn mohr_circle(s: &[[f64; flem_core::element::kernel::LANES]; 4]) -> ([f64; 8], [f64; 8], [f64; 8]) {
    let (mut mid, mut half, mut rr) = ([0.0; 8], [0.0; 8], [0.0; 8]);
    for l in 0..8 {
        mid[l] = 0.5 * (s[0][l] + s[1][l]);
        half[l] = 0.5 * (s[0][l] - s[1][l]);
        rr[l] = half[l] * half[l] + s[2][l] * s[2][l];
    }
    (mid, half, rr)
}

fn xorshift(seed: u64) -> impl FnMut() -> f64 {
    let mut x = seed;
    move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// The stored state kept by pack (session 17: stress and last displacements as structure of
/// arrays, `element/stateful.rs`): a block of 19 distorted Q4 (two whole packs and a part pack
/// of 3), B-bar on and off, the shortcut on and off, a field raised past the first yield in
/// 30 steps. Reference: the checkpoint format of before the change and the block itself.
/// (1) `save_state` writes the element-major order: the last displacements element by element
/// (equal to the displacements given at the last step), then each point's stress `[sxx, syy,
/// sxy, szz]` (equal to `point_stress` on the stored path); (2) `load_state` then `save_state`
/// gives the same vector; (3) a block restored from it and the original continue for 15 more
/// steps with every force, stress and plastic state equal. Tolerance 0 (bits): only the
/// memory layout changed, not one operation.
#[test]
fn packed_state_checkpoints_element_major_and_resumes_bit_for_bit() {
    use flem_core::element::law::{LawCfg, StatefulOpts};
    let (nx, ny) = (19usize, 1usize);
    let (nodes, elems) = distorted_q4(nx, ny);
    let nn = nodes.len();
    let field = |a: f64| -> Vec<[f64; 2]> { nodes.iter().map(|p| [a * (0.02 * p[1] * p[1] - 0.01 * p[0] + 0.003 * p[0] * p[1]), a * (-0.015 * p[1] + 0.004 * p[0] * p[1])]).collect() };
    let cfg = |c: f64| MohrCoulombCfg { cohesion: c, friction_angle_deg: 30.0, dilation_angle_deg: 5.0, tension_cutoff: None, softening: None };
    let block = |c: f64, bbar: bool, shortcut: bool| {
        let mut b = cfg(c).build("r", mat(), StatefulOpts { bbar, large_strain: false, elastic_shortcut: shortcut }, &elems).pop().unwrap();
        b.prepare(nn);
        b
    };
    for bbar in [true, false] {
        let mut probe = block(1e9, bbar, false);
        let mut f = vec![[0.0; 2]; nn];
        let u1 = field(1.0);
        probe.update_internal_forces(&u1, &mut f, None);
        let c = median_cohesion_needed(&probe.point_stress(&u1).unwrap(), 30.0);
        for shortcut in [false, true] {
            let mut a = block(c, bbar, shortcut);
            let ne = a.len();
            assert_eq!(ne, 19);
            let mut f = vec![[0.0; 2]; nn];
            let mut u = field(0.0);
            for step in 1..=30 {
                u = field(step as f64 / 30.0);
                a.update_internal_forces(&u, &mut f, None);
            }
            let mut saved = Vec::new();
            a.save_state(&mut saved);
            assert_eq!(saved.len(), a.state_len());
            // (1) Element-major: the last displacements, then each point's stress.
            for i in 0..ne {
                let c = a.conn(i).to_vec();
                for (k, &n) in c.iter().enumerate() {
                    for d in 0..2 {
                        assert_eq!(saved[i * 8 + 2 * k + d].to_bits(), u[n as usize][d].to_bits(), "bbar {bbar} shortcut {shortcut}: u_prev of element {i}");
                    }
                }
            }
            if !shortcut {
                let ps = a.point_stress(&u).unwrap();
                for (j, s) in ps.iter().enumerate() {
                    for c in 0..4 {
                        assert_eq!(saved[ne * 8 + 4 * j + c].to_bits(), s[c].to_bits(), "bbar {bbar}: stress of point {j}");
                    }
                }
            }
            // (2) Restored and continued.
            let mut b = block(c, bbar, shortcut);
            assert!(b.load_state(&saved));
            let mut again = Vec::new();
            b.save_state(&mut again);
            assert!(saved.iter().zip(&again).all(|(x, y)| x.to_bits() == y.to_bits()), "bbar {bbar} shortcut {shortcut}: load_state then save_state");
            for step in 31..=45 {
                let u = field(step as f64 / 30.0);
                let (mut fa, mut fb) = (vec![[0.0; 2]; nn], vec![[0.0; 2]; nn]);
                a.update_internal_forces(&u, &mut fa, None);
                b.update_internal_forces(&u, &mut fb, None);
                assert!(fa.iter().flatten().zip(fb.iter().flatten()).all(|(x, y)| x.to_bits() == y.to_bits()), "bbar {bbar} shortcut {shortcut} step {step}: forces");
                let (sa, sb) = (a.point_stress(&u).unwrap(), b.point_stress(&u).unwrap());
                assert!(sa.iter().flatten().zip(sb.iter().flatten()).all(|(x, y)| x.to_bits() == y.to_bits()), "bbar {bbar} shortcut {shortcut} step {step}: stress");
                for i in 0..ne {
                    assert_eq!(a.plastic(i), b.plastic(i));
                }
            }
            let plastic = (0..ne).filter(|&i| a.plastic(i).unwrap().1 > 0).count();
            assert!(plastic > 0 && plastic < ne, "bbar {bbar}: {plastic} of {ne} elements plastic: the test needs both kinds");
        }
    }
}

/// An `nx` x `ny` grid of distorted Q4 (unit cells, each node moved by a smooth field: no two
/// elements alike), as the block tests build it: the nodes and the region's elements.
fn distorted_q4(nx: usize, ny: usize) -> (Vec<[f64; 2]>, flem_core::element::law::RegionElems) {
    let xy = |i: usize, j: usize| {
        let (x, y) = (i as f64, j as f64);
        [x + 0.2 * (0.7 * y + 0.3 * x).sin(), y + 0.15 * (0.9 * x).cos()]
    };
    let nodes: Vec<[f64; 2]> = (0..=ny).flat_map(|j| (0..=nx).map(move |i| (i, j))).map(|(i, j)| xy(i, j)).collect();
    let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let mut elems = flem_core::element::law::RegionElems { q4_kind: "q4", ..Default::default() };
    for j in 0..ny {
        for i in 0..nx {
            let c = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
            elems.q4.push((flem_core::ids::ElemId::new(j * nx + i), c.map(|k| nodes[k as usize]), c));
        }
    }
    (nodes, elems)
}
