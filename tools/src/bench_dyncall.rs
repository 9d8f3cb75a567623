//! `flem bench dyncall`: what a criterion from a shared library costs in the failure check.
//!
//! One plane-stress square (n x n Q4) under a uniform traction well below the strength (no
//! split, so every measurement sees the same state), run for `steps` steps; then, on that
//! state, the best of `reps` timings of
//! - the whole failure check (`Cracking::check`: nodal stress, principal values, criterion,
//!   candidates) with the built-in `rankine` and with the example library's `example_rankine`;
//! - the criterion batch alone (`try_check_batch` over every cluster) for both;
//! - one call with a batch of one point (the fixed cost of a call through the C table).
//!
//! Printed as JSON; `dynamic_extra_per_check_over_step` is the extra cost of one dynamic check
//! in units of one explicit step (checks run every `check_every` steps or at equilibrium).
//! Then the contact law, damping and material law of issue 25 (`dyncall_kinds.rs`): keys
//! `material_law`, `contact_law`, `damping`.
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use flem_core::plugin::traits::{principal, FailureCheck, FailureCriterion, Principal};
use flem_core::scene::Scene;
use flem_core::solver::{NoOutput, Simulation};

#[derive(clap::Args)]
pub struct Args {
    /// The example plugin library (default: the one beside this executable, built by
    /// `cargo build --release -p flem-plugin-example`).
    #[arg(long)]
    load: Option<PathBuf>,
    /// Elements per side of the square.
    #[arg(long, default_value_t = 100)]
    n: usize,
    /// Steps timed for the per-step cost.
    #[arg(long, default_value_t = 200)]
    steps: u64,
    /// Repetitions of each check measurement (the best is kept).
    #[arg(long, default_value_t = 30)]
    reps: usize,
    /// Elements across the strip footing of the material-law measurement (x 3/4 down).
    #[arg(long, default_value_t = 64)]
    footing_n: usize,
}

fn scene_text(a: &Args, lib: &Path, criterion: &str) -> String {
    format!(
        r#"[plugins]
load = [{lib:?}]
[mesh]
type = "rectangle"
width = 1.0
height = 1.0
nx = {n}
ny = {n}
[model]
plane = "stress"
[[material]]
young_modulus = 100.0
poisson_ratio = 0.2
density = 1.0
[[support]]
nodes = "bottom"
fix = "y"
[[support]]
nodes = "bottom_left"
fix = "xy"
[[load]]
name = "pull"
type = "traction"
edges = "top"
value = [0.0, 1.0]
[cracking]
at_equilibrium = false
check_every = 1000000000000
[cracking.criterion]
type = "{criterion}"
tensile_strength = 1e9
[cracking.separation]
type = "sigma1_nearest"
[[stage]]
levels = {{ pull = 1.0 }}
max_steps = {steps}
tolerance = 1e-300
"#,
        lib = lib.display().to_string(),
        n = a.n,
        steps = a.steps
    )
}

/// Best of `reps` runs of `f`, in nanoseconds.
pub(crate) fn best(reps: usize, mut f: impl FnMut()) -> f64 {
    (0..reps.max(1))
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_nanos() as f64
        })
        .fold(f64::INFINITY, f64::min)
}

struct Measured {
    step_ns: f64,
    check_ns: f64,
    p: Vec<Principal>,
    scale: Vec<f64>,
    sim: Simulation,
}

fn measure(a: &Args, lib: &Path, criterion: &str) -> Result<Measured> {
    let scene = Scene::from_str(&scene_text(a, lib, criterion), Path::new("<bench dyncall>"), Path::new("."))?;
    let mut sim = Simulation::new(scene)?;
    let t = Instant::now();
    sim.run_stage(0, &mut NoOutput)?;
    let step_ns = t.elapsed().as_nanos() as f64 / a.steps as f64;
    let cfg = sim.scene.file.cracking.as_ref().context("cracking")?;
    let cr = sim.cracking.as_mut().context("cracking state")?;
    let (u, x0, time, step) = (&sim.state.u, &sim.x0, sim.state.time, sim.state.step);
    let mut splits = 0;
    let check_ns = best(a.reps, || {
        let (rec, _) = cr.check(cfg, &mut sim.model, u, x0, time, step).expect("check");
        splits += rec.new_clusters.len();
    });
    anyhow::ensure!(splits == 0, "the bench state must not crack");
    let p: Vec<Principal> = cr.nodal.iter().map(|s| principal(*s, 0.0)).collect();
    let scale = vec![1.0; p.len()];
    Ok(Measured { step_ns, check_ns, p, scale, sim })
}

fn batch_ns(reps: usize, c: &dyn FailureCriterion, p: &[Principal], scale: &[f64], out: &mut [FailureCheck]) -> f64 {
    best(reps, || c.try_check_batch(black_box(p), scale, out).expect("batch"))
}

fn single_call_ns(c: &dyn FailureCriterion, p: &[Principal]) -> f64 {
    const CALLS: usize = 100_000;
    let mut out = [FailureCheck::default()];
    best(5, || {
        for i in 0..CALLS {
            c.try_check_batch(black_box(&p[i % p.len()..i % p.len() + 1]), &[1.0], &mut out).expect("call");
        }
    }) / CALLS as f64
}

pub fn run(a: &Args) -> Result<()> {
    let lib = match &a.load {
        Some(l) => l.clone(),
        None => std::env::current_exe()?.with_file_name(format!("{}flem_plugin_example{}", std::env::consts::DLL_PREFIX, std::env::consts::DLL_SUFFIX)),
    };
    anyhow::ensure!(lib.exists(), "{} does not exist: build it with `cargo build --release -p flem-plugin-example` or give --load", lib.display());
    // The library is the one named on this command line (or flem's own example beside it): the
    // user's choice, so the scene this benchmark builds around it may load it.
    flem_core::plugin::dynload::set_scene_plugin_consent(true);
    let b = measure(a, &lib, "rankine")?;
    let d = measure(a, &lib, "example_rankine")?;
    let cb = b.sim.scene.file.cracking.as_ref().context("cracking")?.criterion.as_ref();
    let cd = d.sim.scene.file.cracking.as_ref().context("cracking")?.criterion.as_ref();
    let n = b.p.len();
    let (mut ob, mut od) = (vec![FailureCheck::default(); n], vec![FailureCheck::default(); n]);
    let batch_b = batch_ns(a.reps, cb, &b.p, &b.scale, &mut ob);
    let batch_d = batch_ns(a.reps, cd, &b.p, &b.scale, &mut od);
    anyhow::ensure!(ob == od, "the built-in and the dynamic criterion disagree");
    let (one_b, one_d) = (single_call_ns(cb, &b.p), single_call_ns(cd, &b.p));
    let step_ns = b.step_ns.min(d.step_ns);
    let kinds = crate::dyncall_kinds::measure(&lib, a.reps.min(10), a.footing_n)?;
    let json = serde_json::json!({
        "bench": "dyncall",
        "library": lib.display().to_string(),
        "elements": a.n * a.n,
        "clusters": n,
        "step_ns": step_ns,
        "failure_check_ns": { "builtin": b.check_ns, "dynamic": d.check_ns },
        "criterion_batch_ns": { "builtin": batch_b, "dynamic": batch_d },
        "criterion_per_point_ns": { "builtin": batch_b / n as f64, "dynamic": batch_d / n as f64 },
        "single_point_call_ns": { "builtin": one_b, "dynamic": one_d },
        "dynamic_extra_per_check_ns": batch_d - batch_b,
        "dynamic_extra_per_check_over_step": (batch_d - batch_b) / step_ns,
        "failure_check_over_step": { "builtin": b.check_ns / step_ns, "dynamic": d.check_ns / step_ns },
        "material_law": kinds["material_law"],
        "contact_law": kinds["contact_law"],
        "damping": kinds["damping"],
    });
    println!("{}", serde_json::to_string_pretty(&json)?);
    Ok(())
}
