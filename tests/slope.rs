//! Factor of safety by strength reduction (issue 21, `flem fos`, `flem_core::solver::fos`)
//! against a limit-equilibrium factor computed here: Bishop's simplified method over circular
//! slips (Bishop 1955, Geotechnique 5(1):7).
use crate::common::{rel, root};

/// The slope of configs/verification/slope.toml: ground height at `x` (crest at y = 10 for
/// x <= 15, the 2:1 face down to the toe at x = 35, y = 0 beyond; the base y = 0 is rigid).
fn ground(x: f64) -> f64 {
    if x <= 15.0 {
        10.0
    } else if x <= 35.0 {
        10.0 - (x - 15.0) / 2.0
    } else {
        0.0
    }
}

/// Bishop's simplified factor of safety of the circle (xc, yc, r) with `n` slices, or `None`
/// when the circle is not a slip of this slope (it leaves the model at x = 0, dips below the
/// rigid base, cuts nothing, or drives nothing). Dry soil: per slice of width b, weight W and
/// base angle alpha (sin alpha = (xc - x) / r: the mass moves down to the right),
/// `F = sum (c b + W tan phi) / m_alpha / sum W sin alpha`, `m_alpha = cos alpha + sin alpha
/// tan phi / F`, iterated from F = 1 to a fixed point.
fn bishop(xc: f64, yc: f64, r: f64, c: f64, tan_phi: f64, gamma: f64, n: usize) -> Option<f64> {
    if r > yc + 1e-12 {
        return None;
    }
    // The arc's x range within the model.
    let (a, b) = ((xc - r).max(0.0), (xc + r).min(35.0));
    if b <= a {
        return None;
    }
    let arc = |x: f64| yc - (r * r - (x - xc) * (x - xc)).max(0.0).sqrt();
    let dx = (b - a) / n as f64;
    let mut sl = Vec::with_capacity(n);
    let mut started = false;
    for k in 0..n {
        let x = a + (k as f64 + 0.5) * dx;
        let h = ground(x) - arc(x);
        if h > 0.0 {
            if k == 0 && a <= 0.0 {
                return None; // the slip would leave the model through x = 0
            }
            if started && sl.last().is_some_and(|s: &(f64, f64)| s.0 < x - 1.5 * dx) {
                return None; // two separate masses: not a simple slip
            }
            started = true;
            sl.push((x, gamma * h * dx));
        }
    }
    if sl.len() < 5 {
        return None;
    }
    let slices: Vec<(f64, f64, f64)> = sl.iter().map(|&(x, w)| (w, ((xc - x) / r).clamp(-1.0, 1.0), dx)).collect();
    let drive: f64 = slices.iter().map(|&(w, s, _)| w * s).sum();
    if drive <= 0.0 {
        return None;
    }
    let mut f = 1.0;
    for _ in 0..200 {
        let mut resist = 0.0;
        for &(w, s, bw) in &slices {
            let cos = (1.0 - s * s).sqrt();
            let m = cos + s * tan_phi / f;
            if m <= 0.0 {
                return None;
            }
            // The base length is bw / cos alpha; c l cos alpha = c b.
            resist += (c * bw + w * tan_phi) / m;
        }
        let nf = resist / drive;
        if (nf - f).abs() < 1e-10 * f {
            return Some(nf);
        }
        f = nf;
    }
    Some(f)
}

/// The smallest Bishop factor over circles: a grid of centres and radii, then two local
/// refinements around the best. Returns (F, xc, yc, r).
pub(crate) fn bishop_search(c: f64, tan_phi: f64, gamma: f64) -> (f64, f64, f64, f64) {
    let mut best = (f64::INFINITY, 0.0, 0.0, 0.0);
    // Radii from the circle tangent to the base (r = yc) down to a 10 m shallower one, or
    // within `dr_span` of the best so far.
    let scan = |xs: (f64, f64, f64), ys: (f64, f64, f64), dr: f64, dr_span: Option<(f64, f64)>, n: usize, best: &mut (f64, f64, f64, f64)| {
        let mut xc = xs.0;
        while xc <= xs.1 + 1e-9 {
            let mut yc = ys.0;
            while yc <= ys.1 + 1e-9 {
                let (r_hi, r_lo) = match dr_span {
                    Some((r0, span)) => ((r0 + span).min(yc), (r0 - span).max(0.5)),
                    None => (yc, (yc - 10.0).max(0.5)),
                };
                let mut r = r_hi;
                while r > r_lo {
                    if let Some(f) = bishop(xc, yc, r, c, tan_phi, gamma, n) {
                        if f < best.0 {
                            *best = (f, xc, yc, r);
                        }
                    }
                    r -= dr;
                }
                yc += ys.2;
            }
            xc += xs.2;
        }
    };
    scan((5.0, 40.0, 1.0), (10.0, 45.0, 1.0), 0.5, None, 150, &mut best);
    let b = best;
    scan((b.1 - 1.5, b.1 + 1.5, 0.1), (b.2 - 1.5, b.2 + 1.5, 0.1), 0.1, Some((b.3, 3.0)), 300, &mut best);
    let b = best;
    scan((b.1 - 0.2, b.1 + 0.2, 0.02), (b.2 - 0.2, b.2 + 0.2, 0.02), 0.02, Some((b.3, 0.4)), 600, &mut best);
    best
}

/// Bishop's slices on a case with a known answer: the frictionless circle. For phi = 0 Bishop's simplified method is exact moment equilibrium of the circle:
/// `F = c L r / (W d)` (arc length L, weight W of the mass, lever arm d of W about the
/// centre). Here both sides are computed by a fine independent quadrature of the same
/// circle. Reference: that formula; tolerance 1e-3 (slice discretisation).
#[test]
fn bishop_slices_give_the_moment_balance_of_a_frictionless_circle() {
    let (xc, yc, r, c, gamma) = (22.0, 20.0, 18.0, 10.0, 20.0);
    let fb = bishop(xc, yc, r, c, 0.0, gamma, 4000).expect("a slip");
    // Moment balance by a finer independent quadrature: sum of W (xc - x) and the arc length.
    let n = 200_000;
    let (a, b) = ((xc - r).max(0.0), (xc + r).min(35.0));
    let dx = (b - a) / n as f64;
    let (mut m, mut xs) = (0.0, Vec::new());
    for k in 0..n {
        let x = a + (k as f64 + 0.5) * dx;
        let h = ground(x) - (yc - (r * r - (x - xc).powi(2)).sqrt());
        if h > 0.0 {
            m += gamma * h * dx * (xc - x);
            xs.push(x);
        }
    }
    let (x0, x1) = (xs[0] - 0.5 * dx, xs[xs.len() - 1] + 0.5 * dx);
    let ang = |x: f64| ((x - xc) / r).asin();
    let l = r * (ang(x1) - ang(x0));
    let fm = c * l * r / m;
    assert!(rel(fb, fm) < 1e-3, "Bishop {fb} vs moment balance {fm}");
}

/// configs/verification/slope.toml (Griffiths & Lane 1999, example 1: 2:1 slope, H = 10 m,
/// base at toe level, gamma = 20 kN/m3, c = 10 kPa, phi = 20 deg, psi = 0, E = 1e5 kPa,
/// nu = 0.3): `flem fos` (coarse mesh: 300 Q4 of about 1 m, bracket to 2 %) against Bishop's
/// simplified method over circular slips computed above. Literature: Bishop & Morgenstern's
/// charts 1.38, Griffiths & Lane's FE strength reduction 1.4. Measured: Bishop here 1.38
/// (printed), `flem fos` 1.39 (bracket [1.383, 1.391] with --rel-tol 0.01). Tolerance 5 %:
/// strength reduction and limit equilibrium differ by a few per cent (Griffiths & Lane
/// +1.4 %, Dawson et al. 1999 within 2 %: the FE mechanism need not be a circle, here it
/// runs along the rigid base to the toe), plus the 2 % bracket and the coarse mesh. Also
/// checked: the picture files, and that the strength reduction moves the answer (the same
/// slope with c = 20 kPa has a larger factor, as Bishop's).
#[test]
fn slope_fos_by_strength_reduction_against_bishop() {
    let (fb, xc, yc, r) = bishop_search(10.0, 20f64.to_radians().tan(), 20.0);
    eprintln!("Bishop's simplified method: F = {fb:.4} (circle centre ({xc:.2}, {yc:.2}), radius {r:.2})");
    assert!((1.3..1.45).contains(&fb), "Bishop {fb} far from the charts' 1.38");
    let dir = std::env::temp_dir().join(format!("flem_fos_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let scene = root().join("configs/verification/slope.toml");
    let out = std::process::Command::new(crate::common::flem_exe())
        .args(["fos", scene.to_str().unwrap(), "--out", dir.to_str().unwrap(), "--lo", "1.0", "--hi", "2.0", "--rel-tol", "0.02"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("fos.json")).unwrap()).unwrap();
    let f = j["fos"].as_f64().unwrap();
    let (lo, hi) = (j["bracket"][0].as_f64().unwrap(), j["bracket"][1].as_f64().unwrap());
    eprintln!("flem fos: F = {f:.4} in [{lo:.4}, {hi:.4}]; difference from Bishop {:+.2} %", 100.0 * (f - fb) / fb);
    assert!(lo < hi && hi - lo <= 0.02 * lo + 1e-12 && lo <= f && f <= hi);
    let trials = j["trials"].as_array().unwrap();
    assert!(trials.iter().any(|t| t["f"].as_f64() == Some(lo) && t["flows"] == false));
    assert!(trials.iter().any(|t| t["f"].as_f64() == Some(hi) && t["flows"] == true));
    assert!(rel(f, fb) < 0.05, "strength reduction {f} vs Bishop {fb}");
    for p in ["mechanism.png", "mechanism.svg"] {
        assert!(std::fs::metadata(dir.join(p)).map(|m| m.len() > 1000).unwrap_or(false), "{p} missing");
    }
    let _ = std::fs::remove_dir_all(&dir);
    // A stronger soil: both methods rise (Bishop's by itself; strength reduction by the law).
    let (fb2, ..) = bishop_search(20.0, 20f64.to_radians().tan(), 20.0);
    assert!(fb2 > fb + 0.2, "Bishop with c = 20: {fb2}");
    let text = std::fs::read_to_string(&scene).unwrap().replace("cohesion = 10.0", "cohesion = 20.0");
    let base = scene.parent().unwrap();
    let (t, _) = flem_core::solver::fos::trial(&text, &scene, base, fb2 * 0.95, 0.1).unwrap();
    assert!(!t.flows, "c = 20 kPa at 0.95 of Bishop's factor {fb2} flows: {t:?}");
}

/// `flem fos` refuses, naming the key, a scene without a law that has a strength and a bad
/// bracket; nothing is run.
#[test]
fn fos_refuses_what_it_cannot_judge() {
    flem_plugins::link();
    use flem_core::solver::fos::{factor_of_safety, FosOptions};
    let opts = FosOptions::default();
    let cant = root().join("configs/verification/cantilever.toml");
    let text = std::fs::read_to_string(&cant).unwrap();
    let e = factor_of_safety(&text, &cant, cant.parent().unwrap(), &opts, &mut |_| {}).err().expect("refused").to_string();
    assert!(e.contains("material") && e.contains("strength"), "{e}");
    let slope = root().join("configs/verification/slope.toml");
    let text = std::fs::read_to_string(&slope).unwrap();
    let bad = FosOptions { lo: 2.0, hi: 1.0, ..FosOptions::default() };
    let e = factor_of_safety(&text, &slope, slope.parent().unwrap(), &bad, &mut |_| {}).err().expect("refused").to_string();
    assert!(e.contains("bracket"), "{e}");
}

/// The warm start of `flem fos` (ours, `FosOptions::warm`: a trial above the highest F that
/// stood starts from that trial's final state) on configs/verification/slope.toml, bracket
/// [1.0, 2.0] to 2 %. References: Bishop's simplified method (computed here, 1.3762) within
/// 5 % as the cold search (the test above), and the cold search itself within 0.5 % (issue 37:
/// the factor unchanged by the speed-up; measured on the default bracket: 1.3838 both). Also:
/// the warm trials say which trial they started from, and every warm start is from a lower F
/// that stood. A warm start that lost the state (a restore into the wrong stage, the stress
/// reset) would change the verdicts near the factor or fail the restore.
///
/// The early verdicts of `flem fos` (ours, `FosOptions::early`: a trial's last stage stopped
/// once its largest displacement clearly accelerates or comes to rest) on
/// configs/verification/slope.toml, bracket [1.0, 2.0] to 2 %. References: Bishop's
/// simplified method (computed here, 1.3762) within 5 % as the full search, and the full
/// search within 0.5 % (issue 37: the factor unchanged by the speed-up). Also: the trials that
/// flow stop early, each before its step limit, and the search takes at most two thirds of the
/// full search's steps (measured: about half). A rule that called a standing trial flowing
/// (or the reverse) near the factor would move the bracket by a bisection step (about 1 %).
///
/// Both options are checked against one cold search (it is the costly part of the test).
#[test]
fn fos_warm_start_and_early_verdicts_keep_the_factor_of_safety() {
    flem_plugins::link();
    use flem_core::solver::fos::{factor_of_safety, FosOptions};
    let (fb, ..) = bishop_search(10.0, 20f64.to_radians().tan(), 20.0);
    let scene = root().join("configs/verification/slope.toml");
    let text = std::fs::read_to_string(&scene).unwrap();
    let base = scene.parent().unwrap();
    let o = FosOptions { lo: 1.0, hi: 2.0, rel_tol: 0.02, ..FosOptions::default() };
    let cold = factor_of_safety(&text, &scene, base, &o, &mut |_| {}).unwrap();
    // Warm starts.
    let warm = factor_of_safety(&text, &scene, base, &FosOptions { warm: true, ..o }, &mut |_| {}).unwrap();
    eprintln!("cold {:.4} {:?}, warm {:.4} {:?}, Bishop {fb:.4}", cold.fos, cold.bracket, warm.fos, warm.bracket);
    assert!(rel(warm.fos, cold.fos) < 0.005, "warm {} vs cold {}", warm.fos, cold.fos);
    assert!(rel(warm.fos, fb) < 0.05, "warm {} vs Bishop {fb}", warm.fos);
    let froms: Vec<(f64, f64)> = warm.trials.iter().filter_map(|t| t.from.map(|s| (t.f, s))).collect();
    assert!(!froms.is_empty(), "no trial was warm-started");
    for (f, s) in froms {
        assert!(s < f && warm.trials.iter().any(|t| t.f == s && !t.flows), "trial {f} started from {s}");
    }
    assert!(cold.trials.iter().all(|t| t.from.is_none()));
    // Early verdicts.
    let full = &cold;
    let early = factor_of_safety(&text, &scene, base, &FosOptions { early: true, ..o }, &mut |_| {}).unwrap();
    eprintln!("full {:.4} {:?}, early {:.4} {:?}, Bishop {fb:.4}", full.fos, full.bracket, early.fos, early.bracket);
    assert!(rel(early.fos, full.fos) < 0.005, "early {} vs full {}", early.fos, full.fos);
    assert!(rel(early.fos, fb) < 0.05, "early {} vs Bishop {fb}", early.fos);
    let limit = 6000;
    for t in early.trials.iter().filter(|t| t.flows) {
        assert!(t.early && t.steps < limit, "trial {} flowed after {} steps without an early verdict", t.f, t.steps);
    }
    assert!(full.trials.iter().all(|t| !t.early));
    let steps = |r: &flem_core::solver::fos::FosResult| r.trials.iter().map(|t| t.steps).sum::<u64>();
    assert!(3 * steps(&early) <= 2 * steps(full), "early {} steps, full {}", steps(&early), steps(full));
}

/// The trend search (ours, `FosOptions::trend`, with early verdicts): on the coarse slope with
/// the default bracket [0.5, 3] and 1 %, the factor of safety within 2 % of Bishop's simplified
/// method (computed here; the full bisection is +0.5 % from it, the bracket itself 1 % wide),
/// the bracket 1 % wide with its lower end a trial that stood and its upper end one that
/// flowed, at most 7 trials (bisection: 10), and after the two first trials (3 and the
/// mid-point 1.75, far from the answer) every trial within 5 % of Bishop's factor: the
/// extrapolated estimate, not bisection,
/// placed them. A wrong estimate (say, the ratios not falling with F) would fall back to
/// bisection and put trials at 1.1 and 1.3 (more than 5 % away).
#[test]
fn fos_trend_search_places_the_trials_near_the_factor_of_safety() {
    flem_plugins::link();
    use flem_core::solver::fos::{factor_of_safety, FosOptions};
    let (fb, ..) = bishop_search(10.0, 20f64.to_radians().tan(), 20.0);
    let scene = root().join("configs/verification/slope.toml");
    let text = std::fs::read_to_string(&scene).unwrap();
    let base = scene.parent().unwrap();
    let r = factor_of_safety(&text, &scene, base, &FosOptions { early: true, trend: true, ..FosOptions::default() }, &mut |_| {}).unwrap();
    let seq: Vec<(f64, bool, u64)> = r.trials.iter().map(|t| (t.f, t.flows, t.steps)).collect();
    eprintln!("trend: {:.4} {:?}, Bishop {fb:.4}, trials {seq:?}", r.fos, r.bracket);
    assert!(rel(r.fos, fb) < 0.02, "trend {} vs Bishop {fb}", r.fos);
    let [lo, hi] = r.bracket;
    assert!(hi - lo <= 0.01 * lo * (1.0 + 1e-9), "bracket {:?}", r.bracket);
    assert!(r.trials.iter().any(|t| t.f == lo && !t.flows) && r.trials.iter().any(|t| t.f == hi && t.flows), "bracket ends not run: {seq:?}");
    // Measured: 5 trials with each of three round-offs of the step (session 30; the ratio the
    // trend reads is the mean over the verdict's second half: with the ratio of the verdict's
    // own step the same three gave 5, 8 and 8); bisection takes 10.
    assert!(r.trials.len() <= 7, "{} trials: {seq:?}", r.trials.len());
    for t in &r.trials[2..] {
        assert!(rel(t.f, fb) < 0.05, "trial at {} far from the factor {fb}: {seq:?}", t.f);
    }
}
