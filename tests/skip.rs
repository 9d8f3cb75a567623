//! The certified skip of the failure check (ours, issue 24, `core/src/cracking/skip.rs`):
//! reference = the same run evaluating every point at every check (`certified_skip = false`);
//! tolerance = exact bits (splits, their order, failure index written, final state).
use flem_core::mesh::topology::SplitRecord;
use flem_core::plugin::traits::{FailureCriterion, Principal};
use flem_core::solver::{Observer, Simulation};

use crate::common;

/// Splits (as bits) and the failure index at every history row (what the output writes).
#[derive(Default)]
struct Log(Vec<String>, Vec<u64>);

impl Observer for Log {
    fn splits(&mut self, _s: &Simulation, _r: &SplitRecord, ev: &[flem_core::cracking::SplitEvent]) -> flem_core::Result<()> {
        self.0.extend(ev.iter().map(|e| {
            format!("{} {:?} {:?} {:?} {:?} {:x} {:x} {:?} {:x?}", e.step, e.point, e.cluster, e.new_cluster, e.mode, e.index.to_bits(), e.sigma1_deg.to_bits(), e.edges, e.stress.map(f64::to_bits))
        }));
        Ok(())
    }
    fn history(&mut self, s: &Simulation, _stage: usize) -> flem_core::Result<()> {
        let (cr, cfg) = (s.cracking.as_ref().unwrap(), s.scene.file.cracking.as_ref().unwrap());
        self.1.extend(cr.failure_index(cfg, &s.model, &s.state.u).iter().map(|x| x.to_bits()));
        Ok(())
    }
}

/// (splits, failure indices at history rows and at the end, final u and v bits, checks
/// evaluated in full, checks skipped, skipped by the node tier and by the element pass).
type Run = (Vec<String>, Vec<u64>, Vec<u64>, u64, u64, (u64, u64));

fn run(text: &str, skip: bool, factor: f64) -> Run {
    let mut sim = common::sim(text);
    let cr = sim.cracking.as_mut().unwrap();
    cr.certified_skip = skip;
    cr.skip_margin_factor = factor;
    let mut log = Log::default();
    sim.run(&mut log).unwrap_or_else(|e| panic!("{e}"));
    let (cr, cfg) = (sim.cracking.as_ref().unwrap(), sim.scene.file.cracking.as_ref().unwrap());
    log.1.extend(cr.failure_index(cfg, &sim.model, &sim.state.u).iter().map(|x| x.to_bits()));
    let state = sim.state.u.iter().chain(&sim.state.v).flat_map(|x| x.map(f64::to_bits)).collect();
    (log.0, log.1, state, cr.n_full, cr.n_skipped, cr.skip_tiers())
}

/// The skipped run equals the every-point run bit for bit, skips most checks, and an unsafe
/// bound (margins times `unsafe_factor`) changes the splits (the comparison has teeth).
fn same_with_skip(text: &str, min_splits: usize, unsafe_factor: Option<f64>) -> (u64, u64) {
    let every = run(text, false, 1.0);
    assert!(every.0.len() >= min_splits, "the reference run must crack: {} splits", every.0.len());
    assert_eq!(every.4, 0);
    let skip = run(text, true, 1.0);
    assert!(skip.4 > 0, "no check was skipped ({} full)", skip.3);
    assert_eq!(every.3, skip.3 + skip.4, "the same number of checks");
    assert_eq!(every.0, skip.0, "splits differ with the certified skip");
    assert_eq!(every.1, skip.1, "failure index (output) differs with the certified skip");
    assert_eq!(every.2, skip.2, "final state differs with the certified skip");
    eprintln!("skip: {} splits, {} of {} checks skipped ({} by the node tier, {} by the element pass)", skip.0.len(), skip.4, skip.3 + skip.4, skip.5 .0, skip.5 .1);
    if let Some(f) = unsafe_factor {
        let bad = run(text, true, f);
        assert_ne!(every.0, bad.0, "margins x {f} (an unsafe bound) still gave the same splits: the test has no teeth");
    }
    skip.5
}

/// The peers' notched plate (configs/bench/notch_q4_h0.25.toml: gen_meshes.py notch, h = 0.25,
/// 2280 quads, Rankine, checks every step).
#[test]
fn certified_skip_gives_the_same_splits_on_the_notched_plate() {
    let text = std::fs::read_to_string(common::root().join("configs/bench/notch_q4_h0.25.toml")).unwrap();
    let text = text.replace("../meshes/", "meshes/").replace("max_steps = 4000", "max_steps = 2500");
    let tiers = same_with_skip(&text, 4, Some(4.0));
    assert!(tiers.0 > 0 && tiers.1 > 0, "both tiers of the skip certify some check here: {tiers:?}");
}

/// The paper's opening model (configs/paper/opening.toml: Mohr-Coulomb, tension only), with
/// checks every step instead of every 10.
#[test]
fn certified_skip_gives_the_same_splits_on_the_opening_model() {
    let text = std::fs::read_to_string(common::root().join("configs/paper/opening.toml")).unwrap();
    let text = text.replace("check_every = 10", "check_every = 1").replace("plots = true", "plots = false");
    let tiers = same_with_skip(&text, 4, Some(100.0));
    assert!(tiers.0 > 0 && tiers.1 > 0, "both tiers of the skip certify some check here: {tiers:?}");
    // Checks every 3 steps, history rows every 10: the failure index written between checks
    // is that of a skipped check, from the displacement kept for it (`Cracking::before_step`).
    same_with_skip(&text.replace("check_every = 1\n", "check_every = 3\n"), 4, None);
}

fn criterion(toml: &str) -> Box<dyn FailureCriterion> {
    flem_plugins::link();
    toml::from_str(toml).unwrap_or_else(|e| panic!("{e}"))
}

/// Each built-in's margin against its own `check` (the reference): no principal triple within
/// the margin (max norm; random points and the box's corners) fails, and (Rankine,
/// Mohr-Coulomb: the bounds are tight) some triple just beyond it does.
#[test]
fn builtin_margins_are_safe_and_tight() {
    let cases = [
        ("type = \"rankine\"\ntensile_strength = 2.0", true),
        ("type = \"mohr_coulomb\"\ncohesion = 1.0\nfriction_angle_deg = 30.0\ntensile_strength = 0.8", true),
        ("type = \"mohr_coulomb\"\ncohesion = 1.0\nfriction_angle_deg = 20.0\ntensile_strength = 0.5\ntension = false", true),
        ("type = \"drucker_prager\"\nalpha = 0.2\nk = 1.0", false),
    ];
    let mut seed = 0x2545_F491_4F6C_DD1Du64;
    let mut rnd = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for (toml, tight) in cases {
        let c = criterion(toml);
        let (mut tested, mut beyond) = (0, 0);
        for _ in 0..4000 {
            let (a, b, s2, scale) = (6.0 * rnd() - 3.0, 6.0 * rnd() - 3.0, 6.0 * rnd() - 3.0, 0.5 + rnd());
            let p = Principal { s1: a.max(b), s3: a.min(b), s2, theta1: 0.0 };
            let m = c.margin(&p, scale).expect("built-ins give a margin");
            if c.check(&p, scale).failed() {
                assert!(m <= 0.0, "{toml}: a failed point has margin {m}");
                continue;
            }
            if m <= 0.0 {
                continue;
            }
            tested += 1;
            let mut found_beyond = false;
            for k in 0..40 {
                let d: [f64; 3] = if k < 8 { std::array::from_fn(|i| if k >> i & 1 == 1 { 1.0 } else { -1.0 }) } else { std::array::from_fn(|_| 2.0 * rnd() - 1.0) };
                let at = |f: f64| Principal { s1: p.s1 + f * m * d[0], s3: p.s3 + f * m * d[1], s2: p.s2 + f * m * d[2], theta1: 0.0 };
                assert!(!c.check(&at(0.999), scale).failed(), "{toml}: {p:?} margin {m} scale {scale}: {:?} fails", at(0.999));
                found_beyond |= k < 8 && c.check(&at(1.01), scale).failed();
            }
            beyond += found_beyond as usize;
        }
        assert!(tested > 500, "{toml}: only {tested} points inside");
        if tight {
            assert!(beyond * 2 > tested, "{toml}: the margin is far from tight ({beyond} of {tested})");
        }
    }
}

/// More elements than one chunk of the element pass (8 192) and more clusters than one of the
/// node tier (16 384), on two threads: the chunked passes and their reductions. A bar pulled
/// suddenly (dynamic stage, undamped) overshoots its static stress 1 to ~2, so a strength of 2.5
/// splits it (~150 splits) while some checks between splits are skipped (by the element pass:
/// under a sudden load the node tier's one allowance is too small for the moving end; its
/// chunked pass is tested in `skip.rs`'s unit tests). Reference: the same run evaluating every
/// point (bits).
#[test]
fn certified_skip_is_exact_over_many_chunks_on_two_threads() {
    let text = "[mesh]\ntype = \"rectangle\"\nwidth = 2.0\nheight = 1.0\nnx = 184\nny = 92\n\
        [[material]]\nyoung_modulus = 100.0\npoisson_ratio = 0.3\ndensity = 1.0\n\
        [solver]\nthreads = 2\n[solver.damping]\ntype = \"none\"\n\
        [[support]]\nnodes = \"left\"\nfix = \"xy\"\n\
        [[load]]\nname = \"pull\"\ntype = \"traction\"\nedges = \"right\"\nvalue = [1.0, 0.0]\n\
        [[stage]]\nlevels = { pull = 1.0 }\ndynamic = true\nmax_steps = 400\nsnapshot = false\n\
        [cracking]\nat_equilibrium = false\ncheck_every = 1\nmax_splits_per_check = 1\n\
        [cracking.criterion]\ntype = \"rankine\"\ntensile_strength = 2.5\n\
        [cracking.separation]\ntype = \"sigma1_nearest\"\n";
    let tiers = same_with_skip(text, 50, None);
    assert!(tiers.1 > 0, "the element pass certifies some check here: {tiers:?}");
}

/// The Lipschitz constants of the corner-stress operator from the blocks' gradients
/// (`Block::corner_lipschitz`, one pass) against probing `corner_stress` with unit
/// displacements (`Skip::probed_lip`, the general path), on distorted Q4 and T3 meshes in plane
/// strain and plane stress: equal to round-off (1e-13 relative; the same products summed in
/// another order). A kind with internal fields (`qm6`) cannot give them and is probed.
#[test]
fn corner_lipschitz_from_gradients_equals_probing() {
    use flem_core::cracking::skip::Skip;
    for (cell, elem, plane) in [("q4", "q4", "strain"), ("t3", "t3", "stress"), ("q4", "qm6", "strain")] {
        let text = format!(
            "[mesh]\ntype = \"rectangle\"\nwidth = 2.0\nheight = 1.5\nnx = 9\nny = 7\nelement = \"{cell}\"\ndistort = 0.25\n[model]\nplane = \"{plane}\"\n\
             [[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\nthickness = 0.7\nelement = \"{elem}\"\n[[stage]]\nlevels = {{}}\n"
        );
        let s = common::sim(&text);
        let mut direct = Vec::new();
        let ok = s.model.corner_lipschitz(&mut direct);
        let probed = Skip::probed_lip(&s.model);
        if elem == "qm6" {
            assert!(!ok, "qm6 has internal fields: its corner stress is not D B(g) u");
            continue;
        }
        assert!(ok, "{elem}: an isoparametric kind gives its constants");
        assert_eq!(direct.len(), probed.len());
        for (k, (d, p)) in direct.iter().zip(&probed).enumerate() {
            let d = d * (1.0 + Skip::ROUND);
            assert!(d > 0.0 && ((d - p) / p).abs() < 1e-13, "{elem}: copy {k}: gradients {d} against probing {p}");
        }
    }
}
