//! The consistent tangent of `mohr_coulomb` against central finite differences of `update`
//! on every branch of the return (elastic, face, both edges, tension plane, tension edge,
//! apex; Tresca and Mohr-Coulomb, associated and not). Reference: the derivative of `update`
//! itself, `(update(de + h e_j) - update(de - h e_j)) / 2h`, h = 1e-7; tolerance 1e-6 of the
//! largest entry of the tangent (at least `lambda + 2 G`: the apex's tangent is 0), on each
//! entry. A tangent that forgets the return (the elastic
//! moduli), the rotation of the axes or a plane of the active set fails it by O(1).
use super::super::{MohrCoulomb, MohrCoulombCfg, Trial};
use flem_core::element::law::MaterialLaw;
use flem_core::element::{Material, Plane};

fn law(c: f64, phi_deg: f64, psi_deg: f64, st: Option<f64>) -> MohrCoulomb {
    let mat = Material { young: 1000.0, poisson: 0.3, density: 1.0, thickness: 1.0, plane: Plane::Strain };
    MohrCoulombCfg { cohesion: c, friction_angle_deg: phi_deg, dilation_angle_deg: psi_deg, tension_cutoff: st, softening: None }.law(&mat)
}

/// The start stress that gives the trial `[pa, pb, pz]` (in-plane principal at angle `theta`
/// from x, out-of-plane `pz`) with the increment `de`.
fn start_for(l: &MohrCoulomb, p: [f64; 3], theta: f64, de: [f64; 4]) -> [f64; 4] {
    let (m, h) = (0.5 * (p[0] + p[1]), 0.5 * (p[0] - p[1]));
    let tr = [m + h * (2.0 * theta).cos(), m - h * (2.0 * theta).cos(), h * (2.0 * theta).sin(), p[2]];
    let (lam, g) = (l.lambda, l.g);
    let ev = de[0] + de[1] + de[3];
    [tr[0] - lam * ev - 2.0 * g * de[0], tr[1] - lam * ev - 2.0 * g * de[1], tr[2] - g * de[2], tr[3] - lam * ev - 2.0 * g * de[3]]
}

/// The active planes of the update (empty: elastic).
fn active(l: &MohrCoulomb, st: &[f64; 4], de: [f64; 4]) -> Vec<usize> {
    let t: Trial = l.trial(st, de);
    if t.inside {
        return vec![];
    }
    let mut s = [t.pa, t.pb, t.pz];
    s.sort_by(|a, b| b.total_cmp(a));
    match l.return_active(s) {
        None => vec![],
        Some(r) => r.act[..r.size].to_vec(),
    }
}

/// Largest entry difference between the tangent and central differences, relative to the
/// tangent's largest entry (at least the elastic `lambda + 2 G`).
fn fd_error(l: &MohrCoulomb, st: [f64; 4], de: [f64; 4]) -> f64 {
    let mut t = [[0.0; 4]; 4];
    assert!(l.tangent(&st, de, &[0.0, 0.0], &mut t));
    // The apex's tangent is zero: the scale is then the elastic lambda + 2 G.
    let scale = t.iter().flatten().fold(l.lambda + 2.0 * l.g, |m, v| m.max(v.abs()));
    let h = 1e-7;
    let mut worst = 0.0f64;
    for j in 0..4 {
        let run = |sgn: f64| {
            let mut d = de;
            d[j] += sgn * h;
            let mut s = st;
            l.update(&mut s, d, &mut [0.0, 0.0]);
            s
        };
        let (p, m) = (run(1.0), run(-1.0));
        for i in 0..4 {
            worst = worst.max(((p[i] - m[i]) / (2.0 * h) - t[i][j]).abs() / scale);
        }
    }
    worst
}

const DE: [f64; 4] = [1.3e-3, -0.7e-3, 0.9e-3, 0.0];

/// Every branch: `(law, trial principal [pa, pb, pz], expected active planes)`.
#[test]
fn tangent_matches_finite_differences_on_every_branch() {
    let mc = law(1.0, 30.0, 10.0, None);
    let mca = law(1.0, 30.0, 30.0, None);
    let tresca = law(1.0, 0.0, 0.0, None);
    let cut = law(1.0, 30.0, 10.0, Some(0.5));
    let cases: Vec<(&str, &MohrCoulomb, [f64; 3], Vec<usize>)> = vec![
        ("elastic", &mc, [-1.0, -2.0, -1.5], vec![]),
        ("face, z middle", &mc, [0.0, -20.0, -8.0], vec![0]),
        ("face, z largest", &mc, [-8.0, -20.0, 0.0], vec![0]),
        ("face, z smallest", &mc, [0.0, -8.0, -20.0], vec![0]),
        ("face, associated", &mca, [0.0, -20.0, -8.0], vec![0]),
        ("edge s2 = s3", &mca, [0.0, -20.0, -19.0], vec![0, 2]),
        ("edge s1 = s2, non-associated", &mc, [-1.0, -20.0, -1.5], vec![0, 1]),
        ("Tresca face", &tresca, [3.0, -1.0, 0.5], vec![0]),
        ("Tresca edge", &tresca, [3.0, -1.0, 2.8], vec![0, 1]),
        ("tension plane", &cut, [1.5, -0.5, -0.2], vec![3]),
        ("tension edge", &cut, [1.5, -0.5, 1.2], vec![3, 4]),
        ("apex", &mc, [5.0, 3.0, 4.0], vec![0, 1, 5]),
    ];
    let mut bad = Vec::new();
    for (name, l, p, want) in cases {
        for theta in [0.0, 0.4, 1.1] {
            let st = start_for(l, p, theta, DE);
            let got = active(l, &st, DE);
            let e = fd_error(l, st, DE);
            eprintln!("{name}, theta {theta}: active {got:?}, tangent vs finite differences {e:.2e}");
            if got != want || !(e < 1e-6) {
                bad.push(format!("{name}, theta {theta}: active {got:?} (want {want:?}), error {e:.2e}"));
            }
        }
    }
    assert!(bad.is_empty(), "{bad:#?}");
}

/// The tangent is symmetric for associated flow (Tresca, psi = phi) and not for psi < phi.
/// Reference: the closest-point projection's tangent is symmetric (de Souza Neto et al. 2008,
/// section 4.3.4); tolerance 1e-9 of the largest entry.
#[test]
fn tangent_symmetric_exactly_for_associated_flow() {
    let asym = |l: &MohrCoulomb, p: [f64; 3]| {
        let st = start_for(l, p, 0.4, DE);
        let mut t = [[0.0; 4]; 4];
        l.tangent(&st, DE, &[0.0, 0.0], &mut t);
        let scale = t.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        (0..4).flat_map(|i| (0..4).map(move |j| (i, j))).fold(0.0f64, |m, (i, j)| m.max((t[i][j] - t[j][i]).abs() / scale))
    };
    let (mca, tresca, mc) = (law(1.0, 30.0, 30.0, None), law(1.0, 0.0, 0.0, None), law(1.0, 30.0, 10.0, None));
    assert!(mca.tangent_symmetric() && tresca.tangent_symmetric() && !mc.tangent_symmetric());
    assert!(asym(&mca, [0.0, -20.0, -8.0]) < 1e-9);
    assert!(asym(&mca, [0.0, -20.0, -19.0]) < 1e-9);
    assert!(asym(&tresca, [3.0, -1.0, 2.8]) < 1e-9);
    assert!(asym(&mc, [0.0, -20.0, -8.0]) > 1e-3);
}
