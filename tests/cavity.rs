//! Cylindrical cavity expansion in a Mohr-Coulomb medium (issue 21): configs/verification/cavity.toml
//! against the closed form of Salencon (1969), implemented here.
use flem_core::solver::NoOutput;

use crate::common::{rel, root, sim};

/// The closed-form cavity expansion (compression positive; plane strain, sigma_z intermediate):
/// cavity radius `a`, pressure `p` in it, in-situ stress `p0`, `c`, `phi`, `psi` (radians),
/// `e`, `nu`, outer boundary at `b` under `p0` (`f64::INFINITY`: Salencon's infinite medium).
/// Returns the plastic radius and the wall displacement (outward, from the in-situ state).
///
/// - Plastic zone `a <= r <= rho`: `sigma_r = N sigma_t + 2 c sqrt(N)`, `N = (1 + sin phi) /
///   (1 - sin phi)`; with `H = c cot phi`, equilibrium gives `sigma_r + H = (p + H) (a / r)^alpha`,
///   `alpha = (N - 1) / N`, `sigma_t + H = (sigma_r + H) / N`.
/// - Elastic zone `rho <= r <= b`: Lame, `sigma_r = A + B / r^2`, `sigma_t = A - B / r^2`, with
///   `sigma_r(b) = p0` and yield at `rho`: `B = ((N - 1) p0 + 2 c sqrt(N)) / ((1 + N) / rho^2 +
///   (N - 1) / b^2)`, `A = p0 - B / b^2` (`b = infinity`: `A = p0`, Salencon's
///   `sigma_rho = (2 N p0 + 2 c sqrt(N)) / (1 + N)`). `rho` solves `sigma_r(rho)` of both zones
///   equal (bisection; closed form for `b = infinity`: `rho / a = ((p + H) / (sigma_rho + H))^(1
///   / alpha)`).
/// - Displacement: `u(rho) = -(rho / 2G) ((1 - 2 nu)(A - p0) - B / rho^2)`; inside, plastic
///   strains along the potential `G = sigma_r - K sigma_t`, `K = (1 + sin psi) / (1 - sin psi)`:
///   `eps_r^p = -eps_t^p / K`, so `u' + u / (K r) = eps_r^e + eps_t^e / K` with the plane-strain
///   elastic strains of the stress change, integrated in closed form with the factor `r^(1/K)`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn salencon(a: f64, b: f64, p: f64, p0: f64, c: f64, phi: f64, psi: f64, e: f64, nu: f64) -> (f64, f64) {
    let n = (1.0 + phi.sin()) / (1.0 - phi.sin());
    let k = (1.0 + psi.sin()) / (1.0 - psi.sin());
    let h = c / phi.tan();
    let alpha = (n - 1.0) / n;
    let g2 = e / (1.0 + nu); // 2 G
    let lame = |rho: f64| {
        let inv_b2 = if b.is_finite() { 1.0 / (b * b) } else { 0.0 };
        let bb = ((n - 1.0) * p0 + 2.0 * c * n.sqrt()) / ((1.0 + n) / (rho * rho) + (n - 1.0) * inv_b2);
        (p0 - bb * inv_b2, bb)
    };
    let sr_plastic = |rho: f64| (p + h) * (a / rho).powf(alpha) - h;
    let sr_elastic = |rho: f64| {
        let (aa, bb) = lame(rho);
        aa + bb / (rho * rho)
    };
    assert!(sr_plastic(a) > sr_elastic(a), "p = {p} does not yield the cavity wall");
    let (mut lo, mut hi) = (a, if b.is_finite() { b } else { 1e6 * a });
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if sr_plastic(mid) > sr_elastic(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let rho = 0.5 * (lo + hi);
    let (aa, bb) = lame(rho);
    let u_rho = -(rho / g2) * ((1.0 - 2.0 * nu) * (aa - p0) - bb / (rho * rho));
    // g(r) = eps_r^e + eps_t^e / K = -(1/2G) (S k1 - q (1 - 2 nu)(1 + 1/K)), S = (p + H)(a/r)^alpha.
    let q = h + p0;
    let k1 = (1.0 - nu) - nu / n + ((1.0 - nu) / n - nu) / k;
    let m = 1.0 / k;
    let sa = (p + h) * a.powf(alpha);
    let e1 = m - alpha + 1.0;
    let integral = -(1.0 / g2) * (k1 * sa * (rho.powf(e1) - a.powf(e1)) / e1 - q * (1.0 - 2.0 * nu) * (rho.powf(m + 1.0) - a.powf(m + 1.0)));
    let u_a = (u_rho * rho.powf(m) - integral) / a.powf(m);
    // Self-check of the algebra: RK4 on the same ODE from rho down to a.
    let g = |r: f64| {
        let s = sa * r.powf(-alpha);
        let (dsr, dst) = (s - h - p0, s / n - h - p0);
        let er = -((1.0 - nu) * dsr - nu * dst) / g2;
        let et = -((1.0 - nu) * dst - nu * dsr) / g2;
        er + et / k
    };
    let f = |r: f64, u: f64| g(r) - u / (k * r);
    let steps = 20_000;
    let dr = (a - rho) / steps as f64;
    let (mut r, mut u) = (rho, u_rho);
    for _ in 0..steps {
        let k1 = f(r, u);
        let k2 = f(r + 0.5 * dr, u + 0.5 * dr * k1);
        let k3 = f(r + 0.5 * dr, u + 0.5 * dr * k2);
        let k4 = f(r + dr, u + dr * k3);
        u += dr / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        r += dr;
    }
    assert!((u - u_a).abs() < 1e-9 * u_a.abs(), "closed form {u_a} vs RK4 {u}");
    (rho, u_a)
}

/// configs/verification/cavity.toml: quarter model, a = 1, b = 10, p0 = 100, p = 300, c = 10,
/// phi = 30 deg, psi = 10 deg, E = 1e5, nu = 0.3 (plane strain; the in-situ state of the scene is
/// the pressure p0 on both boundaries, ramped slowly and checked homogeneous and elastic; so
/// sigma_z starts at 2 nu p0, which stays the
/// intermediate principal stress at every plastic point, as the closed form assumes: checked).
/// Reference: the closed form above with the outer boundary at b (Salencon's b = infinity is
/// printed beside it). Plastic radius: between the outermost ring of Gauss points on the yield
/// surface (within 1 % of 2 c cos phi: points relaxed a little below it after yielding) and the
/// next ring out (their mid-point); wall displacement: the mean radial
/// displacement of the cavity nodes, less the in-situ stage's. Tolerance 2 % on each. Measured:
/// plastic radius 2.5491 vs 2.5393 (+0.38 %), wall displacement 4.9106e-3 vs 4.9167e-3 (-0.12 %);
/// at p = 200, 1.4915e-3 vs 1.4926e-3. The same run with the in-situ stress applied in one
/// jump (no ramp) yields the ground on the way and misses the displacement by 16 %.
#[test]
fn cavity_expansion_against_salencon() {
    let (a, b, p, p0, c, phi, psi, e, nu) = (1.0, 10.0, 300.0, 100.0, 10.0, 30f64.to_radians(), 10f64.to_radians(), 1.0e5, 0.3);
    let (rho, ua) = salencon(a, b, p, p0, c, phi, psi, e, nu);
    let (rho_inf, ua_inf) = salencon(a, f64::INFINITY, p, p0, c, phi, psi, e, nu);
    eprintln!("closed form, b = {b}: plastic radius {rho:.4}, wall displacement {ua:.6e}; Salencon b = infinity: {rho_inf:.4}, {ua_inf:.6e}");
    let text = std::fs::read_to_string(root().join("configs/verification/cavity.toml")).unwrap();
    let mut s = sim(&text.replace("file = \"cavity.msh\"", &format!("file = \"{}\"", root().join("configs/verification/cavity.msh").display())));
    let hole = s.model.node_set("hole", "test", "test").unwrap();
    let wall = |s: &flem_core::solver::Simulation| {
        let mut sum = 0.0;
        for pt in &hole {
            let x = s.model.mesh.points[pt.idx()];
            let cl = s.model.topo.point_clusters[pt.idx()][0].idx();
            let r = x[0].hypot(x[1]);
            sum += (s.state.u[cl][0] * x[0] + s.state.u[cl][1] * x[1]) / r;
        }
        sum / hole.len() as f64
    };
    let n_stages = s.scene.file.stages.len();
    s.run_stage(0, &mut NoOutput).unwrap();
    s.run_stage(1, &mut NoOutput).unwrap();
    let u0 = wall(&s);
    // The in-situ state is the homogeneous elastic one (no wave yielded the ground):
    // u = -(1 + nu)(1 - 2 nu) p0 a / E.
    let u_situ = -(1.0 + nu) * (1.0 - 2.0 * nu) * p0 * a / e;
    assert!(rel(u0, u_situ) < 2e-3, "in-situ wall displacement {u0} vs {u_situ}");
    for i in 2..n_stages {
        s.run_stage(i, &mut NoOutput).unwrap();
        eprintln!("stage {}: wall displacement {:.6e} ({} steps)", s.stages_done[i].name, wall(&s) - u0, s.stages_done[i].steps);
    }
    assert!(s.stages_done[1..].iter().all(|r| r.converged), "every static stage reaches equilibrium");
    let u_fe = wall(&s) - u0;
    let stress: Vec<Vec<[f64; 4]>> = s.model.blocks.iter().map(|b| b.point_stress(&s.state.u).expect("a stateful block")).collect();
    let rho_fe = plastic_radius(&s.model, &stress, c, phi, p);
    eprintln!("FLEM: plastic radius {rho_fe:.4}, wall displacement {u_fe:.6e}; differences {:+.2} %, {:+.2} %", 100.0 * (rho_fe - rho) / rho, 100.0 * (u_fe - ua) / ua);
    assert!(rel(rho_fe, rho) < 0.02, "plastic radius {rho_fe} vs {rho}");
    assert!(rel(u_fe, ua) < 0.02, "wall displacement {u_fe} vs {ua}");
}

/// The plastic radius of a cavity model's Gauss-point stresses (`stress[block][4 i + k]`, Q4):
/// between the outermost ring of points on the yield surface (within 1 % of 2 c cos phi) and
/// the next ring out (their mid-point); checks that every point inside it is plastic and that
/// sigma_z is the intermediate principal stress at the plastic points.
pub(crate) fn plastic_radius(model: &flem_core::element::model::Model, stress: &[Vec<[f64; 4]>], c: f64, phi: f64, p: f64) -> f64 {
    // Gauss points: radius, normalised yield function, sigma_z intermediate.
    let g = 1.0 / 3f64.sqrt();
    let gauss = [[-g, -g], [g, -g], [g, g], [-g, g]];
    let (sp, cp) = (phi.sin(), phi.cos());
    // Yield-function value above which a point counts as plastic (relative to 2 c cos phi).
    let tol = 1e-2;
    let mut pts: Vec<(f64, f64)> = Vec::new();
    for (blk, st) in model.blocks.iter().zip(stress) {
        for i in 0..blk.len() {
            let x = blk.coords(i);
            for (k, xi) in gauss.iter().enumerate() {
                let n = [(1.0 - xi[0]) * (1.0 - xi[1]) / 4.0, (1.0 + xi[0]) * (1.0 - xi[1]) / 4.0, (1.0 + xi[0]) * (1.0 + xi[1]) / 4.0, (1.0 - xi[0]) * (1.0 + xi[1]) / 4.0];
                let (px, py) = (0..4).fold((0.0, 0.0), |acc, j| (acc.0 + n[j] * x[j][0], acc.1 + n[j] * x[j][1]));
                let sg = st[4 * i + k];
                let (m, rr) = (0.5 * (sg[0] + sg[1]), (0.25 * (sg[0] - sg[1]).powi(2) + sg[2] * sg[2]).sqrt());
                let (s1, s3) = ((m + rr).max(sg[3]), (m - rr).min(sg[3]));
                let f = ((s1 - s3) + (s1 + s3) * sp - 2.0 * c * cp) / (2.0 * c * cp);
                if f > -tol {
                    let (a1, a3) = (m + rr, m - rr);
                    assert!(sg[3] <= a1 + 1e-9 * p && sg[3] >= a3 - 1e-9 * p, "plastic point: sigma_z {} not intermediate in [{a3}, {a1}]", sg[3]);
                }
                pts.push((px.hypot(py), f));
            }
        }
    }
    let r_p = pts.iter().filter(|q| q.1 > -tol).map(|q| q.0).fold(0.0, f64::max);
    let r_e = pts.iter().filter(|q| q.0 > r_p + 1e-9).map(|q| q.0).fold(f64::INFINITY, f64::min);
    assert!(pts.iter().filter(|q| q.0 < r_p - 1e-6).all(|q| q.1 > -tol), "a point inside the plastic radius is elastic");
    eprintln!("  last plastic ring {r_p:.4}, first elastic {r_e:.4}");
    0.5 * (r_p + r_e)
}
