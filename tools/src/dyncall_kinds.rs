//! `flem bench dyncall`, the kinds of issue 25: what a contact law, a damping scheme and a
//! material law from a shared library cost against their built-in twins (the example
//! library's copies: `example_spring_dashpot`, `example_adaptive`, `example_mohr_coulomb`).
//!
//! - Material law: (a) the law alone, per point: the same 4096 (stress, strain increment,
//!   history) inputs updated by the built-in `mohr_coulomb` (inlined in the loop, as inside a
//!   block) and by the dynamic law (one call through the C table per point); (b) per element
//!   update: the stateful block's `update_internal_forces` (strain, law at 4 Gauss points,
//!   B-bar forces) of the strip footing, alternating between two displacement fields of a
//!   plastic run so that every call has a strain increment, the same sequence for both;
//!   (c) the whole step of that scene with each law.
//! - Contact law: one batch of 4096 pairs (deterministic kinematics) through `evaluate`, per
//!   pair; and the step of the paper's direct shear box with each.
//! - Damping: one `coeffs` call, against the step of the strip footing.
//!
//! Every timing is the best of `reps`; the built-in and dynamic outputs are checked equal.
use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use flem_core::contact::{ContactLaw, PairForce, PairKinematics, PairState};
use flem_core::element::law::MaterialLaw;
use flem_core::element::{Material, Plane};
use flem_core::plugin::damping::{Damping, StepStats};
use flem_core::scene::Scene;
use flem_core::solver::Simulation;

use crate::bench_dyncall::best;

/// A deterministic pseudo-random sequence in [0, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn law_per_point<L: MaterialLaw>(law: &L, reps: usize, s0: &[[f64; 4]], de: &[[f64; 4]], h0: &[f64]) -> (f64, Vec<u64>) {
    let ns = law.n_state();
    let (mut s, mut h) = (s0.to_vec(), h0.to_vec());
    let t = best(reps, || {
        s.copy_from_slice(s0);
        h.copy_from_slice(h0);
        for k in 0..s.len() {
            law.update(&mut s[k], black_box(de[k]), &mut h[k * ns..(k + 1) * ns]);
        }
    });
    (t / s0.len() as f64, s.iter().flatten().chain(&h).map(|x| x.to_bits()).collect())
}

fn footing_text(lib: &Path, law: &str, n: usize, steps: u64) -> Result<String> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).to_path_buf();
    let t = std::fs::read_to_string(root.join("configs/verification/strip_footing.toml")).context("configs/verification/strip_footing.toml")?;
    Ok(t.replace("nx = 64", &format!("nx = {n}"))
        .replace("ny = 48", &format!("ny = {}", n * 3 / 4))
        .replace("max_steps = 9000", &format!("max_steps = {steps}"))
        .replace("type = \"mohr_coulomb\"", &format!("type = \"{law}\""))
        + &format!("\n[plugins]\nload = [{:?}]\n", lib.display().to_string()))
}

fn sim(text: &str, base: &Path) -> Result<Simulation> {
    Ok(Simulation::new(Scene::from_str(text, Path::new("<bench dyncall>"), base)?)?)
}

/// Per element update of the footing's stateful block, and per step, for one law.
fn footing(lib: &Path, law: &str, n: usize, reps: usize) -> Result<(f64, f64, usize, Vec<u64>)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/verification");
    let mut s = sim(&footing_text(lib, law, n, 400)?, &root)?;
    for _ in 0..300 {
        s.step()?;
    }
    let ua = s.state.u.clone();
    let t = Instant::now();
    for _ in 0..100 {
        s.step()?;
    }
    let step_ns = t.elapsed().as_nanos() as f64 / 100.0;
    let ub = s.state.u.clone();
    let mut f = vec![[0.0; 2]; ua.len()];
    let b = s.model.blocks.iter_mut().max_by_key(|b| b.len()).context("a block")?;
    let ne = b.len();
    const CALLS: usize = 10;
    let t = best(reps, || {
        for k in 0..CALLS {
            f.iter_mut().for_each(|x| *x = [0.0; 2]);
            b.update_internal_forces(if k % 2 == 0 { &ua } else { &ub }, &mut f, None);
        }
    });
    let mut st = Vec::new();
    b.save_state(&mut st);
    Ok((t / (CALLS * ne) as f64, step_ns, ne, st.iter().chain(f.iter().flatten()).map(|x| x.to_bits()).collect()))
}

fn contact_per_pair(law: &dyn ContactLaw, reps: usize) -> (f64, Vec<u64>) {
    const N: usize = 4096;
    let mut r = Lcg(7);
    let kin: Vec<PairKinematics> = (0..N)
        .map(|i| PairKinematics {
            gap: -1e-4 * r.next(),
            dgap: 2e-6 * (r.next() - 0.6),
            dslip: 4e-6 * (r.next() - 0.5),
            vn: r.next() - 0.5,
            vs: r.next() - 0.5,
            area: 1.0,
            area_old: 1.0,
            dt: 1e-4,
            new: i % 97 == 0,
        })
        .collect();
    let mut h0 = vec![PairState::default(); N];
    let mut out = vec![PairForce::default(); N];
    let first: Vec<PairKinematics> = kin.iter().map(|k| PairKinematics { new: true, ..*k }).collect();
    law.evaluate(&first, &mut h0, &mut out);
    let mut h = h0.clone();
    let t = best(reps, || {
        h.copy_from_slice(&h0);
        law.evaluate(black_box(&kin), &mut h, &mut out);
    });
    (t / N as f64, out.iter().flat_map(|o| [o.normal.to_bits(), o.tangential.to_bits(), o.dissipated.to_bits()]).chain(h.iter().flat_map(|p| [p.en.to_bits(), p.es.to_bits()])).collect())
}

fn direct_shear_step(lib: &Path, law: &str) -> Result<f64> {
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/paper");
    let t = std::fs::read_to_string(base.join("direct_shear.toml")).context("configs/paper/direct_shear.toml")?;
    let t = t.replace("law = { type = \"spring_dashpot\"", &format!("law = {{ type = \"{law}\"")) + &format!("\n[plugins]\nload = [{:?}]\n", lib.display().to_string());
    let mut s = sim(&t, &base)?;
    let start = Instant::now();
    s.run(&mut flem_core::solver::NoOutput)?;
    Ok(start.elapsed().as_nanos() as f64 / s.state.step as f64)
}

fn damping_call(d: &mut dyn Damping) -> f64 {
    const CALLS: usize = 100_000;
    let st = StepStats { step: 1, dt: 1e-3, omega_max: 100.0, kinetic: 1.0, u_f_int: 2.0, u_m_u: 3.0 };
    best(5, || {
        for _ in 0..CALLS {
            black_box(d.coeffs(black_box(&st)));
        }
    }) / CALLS as f64
}

/// The measurements of the three kinds, as JSON.
pub fn measure(lib: &Path, reps: usize, n: usize) -> Result<serde_json::Value> {
    // Material law, per point.
    let mat = Material { young: 1000.0, poisson: 0.3, density: 1.0, thickness: 1.0, plane: Plane::Strain };
    let params = "cohesion = 1.0\nfriction_angle_deg = 30.0\ndilation_angle_deg = 10.0";
    let cfg: flem_plugins::material::mohr_coulomb::MohrCoulombCfg = toml::from_str(params)?;
    let builtin = cfg.law(&mat);
    let table: toml::Value = toml::from_str(&format!("type = \"example_mohr_coulomb\"\n{params}"))?;
    let dynamic = flem_core::plugin::dynload::material_law(&table).context("example_mohr_coulomb is not loaded")?.bind(&mat).map_err(|(k, m)| anyhow::anyhow!("{k} {m}"))?;
    const P: usize = 4096;
    let mut r = Lcg(1);
    let s0: Vec<[f64; 4]> = (0..P).map(|_| [-2.0 * r.next(), -2.0 * r.next(), 0.5 * (r.next() - 0.5), -2.0 * r.next()]).collect();
    let de: Vec<[f64; 4]> = (0..P).map(|_| [2e-3 * (r.next() - 0.5), 2e-3 * (r.next() - 0.5), 2e-3 * (r.next() - 0.5), 0.0]).collect();
    let h0 = vec![0.0; 2 * P];
    let (pb, ob) = law_per_point(&builtin, reps, &s0, &de, &h0);
    let (pd, od) = law_per_point(&dynamic, reps, &s0, &de, &h0);
    anyhow::ensure!(ob == od, "the built-in and the dynamic material law disagree");
    let plastic = (0..P).filter(|&k| od[4 * P + 2 * k + 1] == 1.0f64.to_bits()).count();
    // Material law, per element update and per step (strip footing).
    let (eb, sb, ne, fb) = footing(lib, "mohr_coulomb", n, reps)?;
    let (ed, sd, _, fd) = footing(lib, "example_mohr_coulomb", n, reps)?;
    anyhow::ensure!(fb == fd, "the footing's element updates differ between the built-in and the dynamic law");
    // Contact law.
    let cb: Box<dyn ContactLaw> = toml::from_str("type = \"spring_dashpot\"\nnormal_stiffness = 8.06e6\nshear_stiffness = 2.015e6\nfriction = 0.577")?;
    let cd = flem_core::contact::dynlaw::de_contact(toml::Value::Table(toml::from_str("type = \"example_spring_dashpot\"\nnormal_stiffness = 8.06e6\nshear_stiffness = 2.015e6\nfriction = 0.577")?))?;
    let ((kb, ob), (kd, od)) = (contact_per_pair(cb.as_ref(), reps), contact_per_pair(cd.as_ref(), reps));
    anyhow::ensure!(ob == od, "the built-in and the dynamic contact law disagree");
    let (db_step, dd_step) = (direct_shear_step(lib, "spring_dashpot")?, direct_shear_step(lib, "example_spring_dashpot")?);
    // Damping.
    let mut damp_b: Box<dyn Damping> = toml::from_str("type = \"adaptive\"")?;
    let mut damp_d = flem_core::plugin::dynload::de_damping(toml::Value::Table(toml::from_str("type = \"example_adaptive\"")?))?.context("example_adaptive")?;
    let (qb, qd) = (damping_call(damp_b.as_mut()), damping_call(damp_d.as_mut()));
    let step = sb.min(sd);
    Ok(serde_json::json!({
        "material_law": {
            "law": "mohr_coulomb vs example_mohr_coulomb (c = 1, phi = 30, psi = 10)",
            "per_point_ns": { "builtin": pb, "dynamic": pd, "ratio": pd / pb, "points": P, "plastic_points": plastic },
            "per_element_update_ns": { "builtin": eb, "dynamic": ed, "ratio": ed / eb, "scene": format!("strip footing {n} x {} Q4, B-bar, 4 points per element", n * 3 / 4), "elements": ne },
            "step_ns": { "builtin": sb, "dynamic": sd, "ratio": sd / sb },
            "dynamic_extra_share_of_step": (ed - eb) * ne as f64 / step,
        },
        "contact_law": {
            "law": "spring_dashpot vs example_spring_dashpot",
            "per_pair_ns": { "builtin": kb, "dynamic": kd, "ratio": kd / kb, "pairs_per_call": 4096 },
            "direct_shear_step_ns": { "builtin": db_step, "dynamic": dd_step, "ratio": dd_step / db_step },
        },
        "damping": {
            "scheme": "adaptive vs example_adaptive",
            "per_call_ns": { "builtin": qb, "dynamic": qd },
            "dynamic_extra_share_of_footing_step": (qd - qb) / step,
        },
    }))
}
