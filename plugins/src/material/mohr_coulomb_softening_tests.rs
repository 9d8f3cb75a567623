//! Tests of the strain-softening `mohr_coulomb`. References: the yield condition at the
//! parameters of the stored hardening parameter, FLAC's hardening increment computed from the
//! plastic strain that the elastic compliance gives (not from the return's own), the flow rule,
//! and the closed form of a pure-shear path.
use super::*;
use flem_core::element::law::LawCfg;
use flem_core::element::Plane;

fn mat() -> Material {
    Material { young: 1000.0, poisson: 0.3, density: 1.0, thickness: 1.0, plane: Plane::Strain }
}

fn cfg(c: f64, phi: f64, psi: f64, sc: SofteningCfg) -> MohrCoulombCfg {
    MohrCoulombCfg { cohesion: c, friction_angle_deg: phi, dilation_angle_deg: psi, tension_cutoff: None, softening: Some(sc) }
}

/// c 2 -> 1 -> 0.5, phi 35 -> 30 -> 25, psi 10 -> 5 -> 0 at e_ps 0, 0.002, 0.006.
fn soft() -> MohrCoulombCfg {
    cfg(
        2.0,
        35.0,
        10.0,
        SofteningCfg { eps_ps: vec![0.0, 0.002, 0.006], cohesion: Some(vec![2.0, 1.0, 0.5]), friction_angle_deg: Some(vec![35.0, 30.0, 25.0]), dilation_angle_deg: Some(vec![10.0, 5.0, 0.0]) },
    )
}

fn law_of(c: &MohrCoulombCfg) -> MohrCoulombSoftening {
    c.validate(&mat()).unwrap();
    MohrCoulombSoftening::new(c, c.softening.as_ref().unwrap(), &mat())
}

/// `D^-1 ds` in principal space.
fn compliance(l: &MohrCoulomb, ds: [f64; 3]) -> [f64; 3] {
    let (lam, g) = (l.lambda, l.g);
    let e = g * (3.0 * lam + 2.0 * g) / (lam + g);
    let nu = lam / (2.0 * (lam + g));
    std::array::from_fn(|i| (ds[i] - nu * (ds[(i + 1) % 3] + ds[(i + 2) % 3])) / e)
}

/// FLAC's formula as its manual writes it (face: de_2 = 0), independent of the law's code.
fn flac_increment(d1: f64, d3: f64) -> f64 {
    let m = (d1 + d3) / 3.0;
    ((d1 - m).powi(2) + m * m + (d3 - m).powi(2)).sqrt() / 2f64.sqrt()
}

/// The tables interpolate linearly and stay at the last entry beyond it. Exact.
#[test]
fn tables_interpolate_and_hold_the_residual() {
    let l = law_of(&soft());
    let (c, phi, psi) = l.params(0.001);
    assert!((c - 1.5).abs() < 1e-14 && (phi.to_degrees() - 32.5).abs() < 1e-12 && (psi.to_degrees() - 7.5).abs() < 1e-12);
    let (c, phi, psi) = l.params(0.004);
    assert!((c - 0.75).abs() < 1e-14 && (phi.to_degrees() - 27.5).abs() < 1e-12 && (psi.to_degrees() - 2.5).abs() < 1e-12);
    assert_eq!(l.params(0.5), l.params(0.006));
    assert_eq!(l.params(0.0).0, 2.0);
}

/// A face-region trial from a point at e_ps = 0.001 returns onto the surface of its NEW e_ps
/// (1e-10 of the stress), the new e_ps is the old plus FLAC's increment of the plastic strain
/// D^-1 (s_tr - s) (1e-12 relative), the plastic strain flows along the potential of the new
/// psi (de_2 = 0, de_1 / de_3 = -(1 + sin psi) / (1 - sin psi)); the stress lies strictly
/// inside the surface of the old e_ps (softening shrank it).
#[test]
fn return_lands_on_the_surface_of_the_updated_parameter() {
    let l = law_of(&soft());
    let k0 = 0.001;
    let tr = [1.0, -4.0, -14.0];
    let (s, dep, k1) = l.return_softening(tr, k0).expect("plastic");
    let at1 = l.at(k1);
    assert!(at1.f(0, &s).abs() < 1e-10 * 14.0, "on the surface at k1: {}", at1.f(0, &s));
    let pl = compliance(&l.base, [tr[0] - s[0], tr[1] - s[1], tr[2] - s[2]]);
    for d in 0..3 {
        assert!((pl[d] - dep[d]).abs() < 1e-9 * dep[0].abs(), "consistency {pl:?} {dep:?}");
    }
    assert!(pl[1].abs() < 1e-12 * pl[0].abs(), "face flow: de2 = 0");
    let dk = flac_increment(pl[0], pl[2]);
    assert!(((k1 - k0) - dk).abs() < 1e-12 * dk, "k1 - k0 = {} vs FLAC {dk}", k1 - k0);
    let (_, _, psi) = l.params(k1);
    let sp = psi.sin();
    assert!((pl[0] / pl[2] + (1.0 + sp) / (1.0 - sp)).abs() < 1e-8, "flow along the potential of psi(k1)");
    assert!(k1 > k0 + 1e-4, "a real softening step: {k1}");
    assert!(l.at(k0).f(0, &s) < -1e-3, "the old surface is larger than the new one");
}

/// Edge and apex regions of the softened surface: on the surface of the updated parameter,
/// admissible for every plane, the parameter consistent with the plastic strain from the
/// compliance (the general form sqrt(1/2 sum (de_i - de_m)^2) at edges). Random trials, fixed
/// seed; 1e-9 of the stress scale.
#[test]
fn random_returns_are_consistent_in_every_region() {
    let l = law_of(&soft());
    let mut seed: u64 = 99;
    let mut rnd = || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut n_plastic, mut n_shear) = (0, 0);
    for _ in 0..2000 {
        let mut tr = [30.0 * rnd() - 25.0, 30.0 * rnd() - 25.0, 30.0 * rnd() - 25.0];
        tr.sort_by(|a, b| b.partial_cmp(a).unwrap());
        let k0 = 0.008 * rnd();
        let Some((s, dep, k1)) = l.return_softening(tr, k0) else { continue };
        n_plastic += 1;
        let at1 = l.at(k1);
        let scale = 25.0;
        for k in 0..6 {
            if at1.used & (1 << k) != 0 {
                assert!(at1.f(k, &s) <= 1e-9 * scale, "plane {k} violated: {tr:?} -> {s:?} at {k1}");
            }
        }
        assert!((0..6).any(|k| at1.used & (1 << k) != 0 && at1.f(k, &s).abs() <= 1e-9 * scale), "on the surface: {tr:?} -> {s:?}");
        let pl = compliance(&l.base, [tr[0] - s[0], tr[1] - s[1], tr[2] - s[2]]);
        for d in 0..3 {
            assert!((pl[d] - dep[d]).abs() < 1e-9 * (1e-6 + dep.iter().map(|x| x.abs()).fold(0.0, f64::max)), "{pl:?} {dep:?}");
        }
        assert!(k1 >= k0);
        let tension = (3..6).any(|k| at1.used & (1 << k) != 0 && at1.f(k, &s) > -1e-9 * scale);
        if !tension {
            let dk = hardening_increment(pl);
            assert!(((k1 - k0) - dk).abs() <= 1e-9 * dk + 1e-15, "{tr:?}: k1 - k0 = {} vs {dk}", k1 - k0);
            n_shear += 1;
        }
    }
    assert!(n_plastic > 500 && n_shear > 300, "{n_plastic} {n_shear}");
}

/// Pure shear, Tresca softening (phi = psi = 0, c = 1 -> 0.4 -> 0.2 at e_ps = 0, 0.01,
/// 0.03): exx = e, eyy = -e. Closed form: tau = (sxx - syy) / 2 = 2 G e until tau = c0; then
/// on the face de1p = -de3p = dl, d e_ps = dl (FLAC), tau = 2 G (e - e_ps) = c(e_ps), so on
/// the segment i of the table e_ps = (e - (c_i - s_i e_i) / 2G) / (1 + s_i / 2G), tau =
/// c(e_ps): a linear softening branch, then the residual plateau 0.2. The implicit update
/// follows it to round-off whatever the step (tolerance 1e-9 of c0), with steps of 1e-4
/// and of 3e-3 (a step over a whole segment).
#[test]
fn pure_shear_follows_the_softening_table_in_closed_form() {
    let c = cfg(1.0, 0.0, 0.0, SofteningCfg { eps_ps: vec![0.0, 0.01, 0.03], cohesion: Some(vec![1.0, 0.4, 0.2]), friction_angle_deg: None, dilation_angle_deg: None });
    let l = law_of(&c);
    let g = l.base.g;
    let (ek, ck) = ([0.0, 0.01, 0.03], [1.0, 0.4, 0.2]);
    let closed = |e: f64| -> f64 {
        if 2.0 * g * e <= ck[0] {
            return 2.0 * g * e;
        }
        for i in 0..2 {
            let s = (ck[i + 1] - ck[i]) / (ek[i + 1] - ek[i]);
            let k = (e - (ck[i] - s * ek[i]) / (2.0 * g)) / (1.0 + s / (2.0 * g));
            if k <= ek[i + 1] {
                return ck[i] + s * (k - ek[i]);
            }
        }
        ck[2]
    };
    for de in [1e-4, 3e-3] {
        let (mut s, mut h) = ([0.0; 4], [0.0; 3]);
        let (mut e, mut seen, mut peak) = (0.0, [false; 3], 0.0f64);
        while e < 0.06 {
            l.update(&mut s, [de, -de, 0.0, 0.0], &mut h);
            e += de;
            let tau = 0.5 * (s[0] - s[1]);
            let want = closed(e);
            assert!((tau - want).abs() < 1e-9, "de {de}: e {e}: tau {tau} vs {want}");
            assert!(s[3].abs() < 1e-9 && s[2].abs() < 1e-12);
            // The stored e_ps satisfies tau = 2 G (e - e_ps) once plastic.
            if h[1] == 1.0 {
                assert!((tau - 2.0 * g * (e - h[2])).abs() < 1e-9, "e_ps {} at e {e}", h[2]);
                // VTU's plastic shear strain de1p - de3p is twice FLAC's e_ps here.
                assert!((h[0] - 2.0 * h[2]).abs() < 1e-9 * h[0].max(1e-9));
            }
            seen[if h[1] == 0.0 {
                0
            } else if want > 0.2 + 1e-9 {
                1
            } else {
                2
            }] = true;
            peak = peak.max(tau);
        }
        assert!(seen[1] && seen[2] && (seen[0] || de > 1e-3), "elastic rise, softening branch and plateau all met: {seen:?}");
        assert!(peak <= 1.0 + 1e-9, "never above the peak strength: {peak}");
    }
}

/// Bad tables are refused naming the key.
#[test]
fn bad_tables_name_the_key() {
    let base = soft();
    let with = |f: &dyn Fn(&mut SofteningCfg)| {
        let mut c = base.clone();
        f(c.softening.as_mut().unwrap());
        c.validate(&mat()).err().map(|e| e.0)
    };
    assert_eq!(with(&|s| s.eps_ps = vec![0.0, 0.002, 0.002]), Some("softening.eps_ps[2]".into()));
    assert_eq!(with(&|s| s.eps_ps = vec![0.001, 0.002, 0.006]), Some("softening.eps_ps[0]".into()));
    assert_eq!(with(&|s| s.eps_ps = vec![]), Some("softening.eps_ps".into()));
    assert_eq!(with(&|s| s.cohesion = Some(vec![2.0, 1.0])), Some("softening.cohesion".into()));
    assert_eq!(with(&|s| s.cohesion = Some(vec![2.0, -1.0, 0.5])), Some("softening.cohesion[1]".into()));
    assert_eq!(with(&|s| s.cohesion = Some(vec![3.0, 1.0, 0.5])), Some("softening.cohesion[0]".into()));
    assert_eq!(with(&|s| s.dilation_angle_deg = Some(vec![10.0, 31.0, 0.0])), Some("softening.dilation_angle_deg[1]".into()));
    assert_eq!(with(&|s| s.friction_angle_deg = Some(vec![35.0, 30.0, f64::NAN])), Some("softening.friction_angle_deg[2]".into()));
    assert_eq!(
        with(&|s| {
            s.cohesion = Some(vec![2.0, 1.0, 0.0]);
            s.friction_angle_deg = Some(vec![35.0, 30.0, 0.0]);
            s.dilation_angle_deg = None;
        }),
        Some("dilation_angle_deg".into())
    );
    assert_eq!(
        with(&|s| {
            s.cohesion = Some(vec![2.0, 1.0, 0.0]);
            s.friction_angle_deg = Some(vec![35.0, 30.0, 0.0]);
            s.dilation_angle_deg = Some(vec![10.0, 5.0, 0.0]);
        }),
        Some("softening.cohesion[2]".into())
    );
    // Through the scene's TOML: unknown keys are refused by serde.
    let t = "type = \"mohr_coulomb\"\ncohesion = 1.0\nfriction_angle_deg = 30.0\nsoftening = { eps_ps = [0.0, 0.01], friction = [30.0, 25.0] }\n";
    assert!(toml::from_str::<MohrCoulombCfg>(t).is_err());
}

/// Strength reduction reduces every entry: c_i / F, tan(phi_i) / F, psi_i capped at the
/// reduced phi_i; the reduced law validates. Reference: the definition; 1e-12.
#[test]
fn strength_reduced_reduces_every_entry() {
    let r = soft().strength_reduced(1.5).unwrap();
    let mut v = toml::Value::try_from(&r).unwrap();
    v.as_table_mut().unwrap().remove("type");
    let back: MohrCoulombCfg = v.try_into().unwrap();
    back.validate(&mat()).unwrap();
    let s = back.softening.unwrap();
    let (c0, p0) = ([2.0, 1.0, 0.5], [35.0f64, 30.0, 25.0]);
    for i in 0..3 {
        assert!((s.cohesion.as_ref().unwrap()[i] - c0[i] / 1.5).abs() < 1e-12);
        let phi = s.friction_angle_deg.as_ref().unwrap()[i];
        assert!((phi.to_radians().tan() - p0[i].to_radians().tan() / 1.5).abs() < 1e-12);
        assert!(s.dilation_angle_deg.as_ref().unwrap()[i] <= phi);
    }
    assert_eq!(s.eps_ps, vec![0.0, 0.002, 0.006]);
    assert!((back.cohesion - 2.0 / 1.5).abs() < 1e-12);
    // Every combination of tables left out reduces to a law that validates (the first entries
    // stay equal to the reduced constants).
    for mask in 0..8u8 {
        let mut c = soft();
        let sc = c.softening.as_mut().unwrap();
        if mask & 1 != 0 {
            sc.cohesion = None;
        }
        if mask & 2 != 0 {
            sc.friction_angle_deg = None;
        }
        if mask & 4 != 0 {
            sc.dilation_angle_deg = None;
        }
        c.validate(&mat()).unwrap();
        for f in [0.5, 1.3, 4.0] {
            let mut v = toml::Value::try_from(&c.strength_reduced(f).unwrap()).unwrap();
            v.as_table_mut().unwrap().remove("type");
            let r: MohrCoulombCfg = v.try_into().unwrap();
            r.validate(&mat()).unwrap_or_else(|e| panic!("mask {mask} f {f}: {e:?}"));
        }
    }
}
