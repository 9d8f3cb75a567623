//! `flem stability`: the stability map (issue 9): where each method fails, measured.
//!
//! 1. Explicit step: for each mesh kind (regular Q4, distorted Q4, T3) and damping scheme, the
//!    step at which an undriven-to-blow-up dynamic run diverges, found by bisection on
//!    dt / dt_crit (a run "diverges" when the solver's guard stops it within `steps` steps),
//!    against the prediction (power iteration times the scheme's stability factor: 1 means
//!    the prediction is exact, < 1 that it is unsafe).
//! 2. Damping: steps a bar needs to come to rest (ratio 1e-8) against the damping parameter,
//!    too little (oscillates for long) to too much (crawls): `local` ratio and `viscous`
//!    alpha as a multiple of the critical 2 omega_1 (omega_1 from the Rayleigh quotient of the
//!    static solution).
//! 3. Contact stiffness against dt: a block pressed onto a fixed base (penalty contact, no
//!    damping) for contact normal stiffness k_n over several decades, from below the elastic
//!    stiffness (the element term of the step rules) to far above (the contact term rules):
//!    the blow-up step by bisection on dt / dt_crit, where the prediction dt_crit includes the
//!    contact term `omega^2 = omega_el^2 + 4 k_n A_max / m_min` (core/src/contact/search.rs).
//!    Unilateral contact blows up non-monotonically in dt, so the threshold is the first
//!    divergent factor of an upward scan (0.05 / 0.02 apart), refined by bisection.
//! 4. Implicit after separation: a crack that cuts a fragment free leaves the stiffness
//!    singular; the implicit check solver must name the fragment while the explicit run goes on.
//!
//! Writes stability.csv, stability.json and stability.md (the table of docs/stability.md).
//!
//! The studies' names (`Row::study`): `explicit_dt`, `contact_dt`, `damping`,
//! `implicit_after_separation`. The blow-up runs are dynamic stages with `allow_unstable_dt`,
//! stopped by the solver's divergence guard. Results of the last run: `docs/stability/`.
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use flem_core::scene::Scene;
use flem_core::solver::{NoOutput, Simulation};
use serde::Serialize;

#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// "explicit_dt", "contact_dt", "damping", "implicit_after_separation".
    pub study: String,
    pub case: String,
    /// The swept parameter's name and value.
    pub parameter: String,
    pub value: f64,
    /// What was measured (threshold / prediction, steps to rest, ...).
    pub measured: f64,
    pub outcome: String,
}

fn scene(text: &str) -> Result<Scene> {
    Ok(Scene::from_str(text, Path::new("<stability>"), Path::new("."))?)
}

fn mesh_block(kind: &str) -> &'static str {
    match kind {
        "q4" => "[mesh]\ntype = \"rectangle\"\nwidth = 4.0\nheight = 1.0\nnx = 8\nny = 2\n",
        "q4_distorted" => "[mesh]\ntype = \"rectangle\"\nwidth = 4.0\nheight = 1.0\nnx = 8\nny = 2\ndistort = 0.2\n",
        _ => "[mesh]\ntype = \"rectangle\"\nwidth = 4.0\nheight = 1.0\nnx = 8\nny = 2\nelement = \"t3\"\n",
    }
}

const BODY: &str = "[[material]]\nyoung_modulus = 100.0\npoisson_ratio = 0.3\ndensity = 1.0\n[[support]]\nnodes = \"left\"\nfix = \"xy\"\n[[load]]\nname = \"p\"\ntype = \"traction\"\nedges = \"right\"\nvalue = [0.3, -0.2]\n";

/// Runs a scene; Ok(true) when the solver's divergence guard stopped it.
fn blows_up(text: &str) -> Result<bool> {
    let mut s = Simulation::new(scene(text)?)?;
    match s.run(&mut NoOutput) {
        Ok(()) => Ok(false),
        Err(flem_core::FlemError::Diverged { .. }) => Ok(true),
        Err(e) => Err(e.into()),
    }
}

/// The predicted dt_crit of a case (one power iteration, reused by every run of its bisection).
fn predicted(text: &str) -> Result<f64> {
    Ok(Simulation::new(scene(text)?)?.stable.dt_crit)
}

/// A dynamic run at `factor` x the predicted `dt_crit`; Ok(true) when it diverged.
fn diverges(mesh: &str, damping: &str, dt_crit: f64, factor: f64, steps: u64) -> Result<bool> {
    let dt = factor * dt_crit;
    blows_up(&format!("{mesh}{BODY}[solver]\ndt = {dt:e}\nallow_unstable_dt = true\n[solver.damping]\n{damping}\n[[stage]]\nlevels = {{ p = 1.0 }}\ndynamic = true\nmax_steps = {steps}\n"))
}

/// `iters` halvings of `[lo, hi]` (`lo` stable, `hi` divergent) around the divergence threshold.
fn bisect(mut lo: f64, mut hi: f64, iters: usize, mut diverges: impl FnMut(f64) -> Result<bool>) -> Result<(f64, f64)> {
    for _ in 0..iters {
        let mid = 0.5 * (lo + hi);
        if diverges(mid)? {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Ok((lo, hi))
}

fn explicit_dt(quick: bool, rows: &mut Vec<Row>) -> Result<()> {
    let steps = if quick { 3000 } else { 20000 };
    let iters = if quick { 6 } else { 9 };
    let dampings = [("none", "type = \"none\""), ("viscous", "type = \"viscous\"\nalpha = 0.5"), ("local_0.8", "type = \"local\"\nratio = 0.8"), ("adaptive", "type = \"adaptive\"")];
    for mesh in ["q4", "q4_distorted", "t3"] {
        for (name, d) in dampings {
            let crit = predicted(&format!("{}{BODY}[solver.damping]\n{d}\n[[stage]]\n", mesh_block(mesh)))?;
            let (mut lo, mut hi) = (0.5, 1.6);
            if diverges(mesh_block(mesh), d, crit, hi, steps)? {
                (lo, hi) = bisect(lo, hi, iters, |f| diverges(mesh_block(mesh), d, crit, f, steps))?;
            } else {
                lo = hi;
            }
            let m = 0.5 * (lo + hi);
            let outcome = if hi >= 1.6 && lo >= 1.6 {
                "stable up to 1.6 x prediction (conservative)".to_string()
            } else if lo < 1.0 - 0.02 {
                format!("UNSAFE: blows up below the prediction ({m:.3})")
            } else {
                format!("blow-up at {m:.3} x prediction")
            };
            eprintln!("explicit dt {mesh:<13} {name:<10} threshold/prediction = {m:.4}");
            rows.push(Row { study: "explicit_dt".into(), case: format!("{mesh} / {name}"), parameter: "dt/dt_crit".into(), value: m, measured: m, outcome });
        }
    }
    Ok(())
}

/// A block (1 x 0.5, 4 x 2 Q4) 1e-7 above a fixed base, pressed by a pressure on its top;
/// penalty contact of normal stiffness `kn` between `block_bottom` and `base_top` only
/// (`crack_faces = false`: the bound is the surface one, not the every-corner one).
fn contact_block(kn: f64, solver: &str, steps: u64) -> String {
    format!(
        "[mesh]\ntype = \"rectangles\"\nparts = [\n  {{ name = \"base\", origin = [0.0, 0.0], width = 2.0, height = 0.5, nx = 8, ny = 2 }},\n  {{ name = \"block\", origin = [0.5, 0.5000001], width = 1.0, height = 0.5, nx = 4, ny = 2 }},\n]\n\
[[material]]\nyoung_modulus = 1e5\npoisson_ratio = 0.25\ndensity = 1.0\n\
[contact]\nlaw = {{ type = \"penalty\", normal_stiffness = {kn:e} }}\nsurfaces = [\"block_bottom\", \"base_top\"]\ncrack_faces = false\n\
[[support]]\nnodes = \"base_all\"\nfix = \"xy\"\n[[support]]\nnodes = \"block_top\"\nfix = \"x\"\n\
[[load]]\nname = \"p\"\ntype = \"pressure\"\nedges = \"block_top\"\nvalue = 100.0\n\
{solver}[solver.damping]\ntype = \"none\"\n[[stage]]\nlevels = {{ p = 1.0 }}\ndynamic = true\nmax_steps = {steps}\n"
    )
}

/// A dynamic run of the pressed block at `factor` x its predicted `dt_crit`; Ok(true) when the
/// solver's guard stopped it.
fn contact_diverges(kn: f64, dt_crit: f64, factor: f64, steps: u64) -> Result<bool> {
    let dt = factor * dt_crit;
    blows_up(&contact_block(kn, &format!("[solver]\ndt = {dt:e}\nallow_unstable_dt = true\n"), steps))
}

fn contact_dt(quick: bool, rows: &mut Vec<Row>) -> Result<()> {
    let steps = if quick { 3000 } else { 20000 };
    let iters = if quick { 6 } else { 9 };
    let grid = if quick { 0.05 } else { 0.02 };
    let kns: &[f64] = if quick { &[1e4, 1e6, 1e8] } else { &[1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9] };
    for &kn in kns {
        let probe = Simulation::new(scene(&contact_block(kn, "", steps))?)?;
        let share = (probe.stable.dt_crit / probe.stable.dt_contact).powi(2);
        // Unilateral contact makes divergence non-monotone in dt (a run can blow up at 2.0 x and
        // survive 2.25 x: separation interrupts the growth), so bisection from a wide bracket
        // can miss the lowest threshold: scan a grid upwards to the first divergent factor,
        // then bisect between it and the last stable grid point.
        let (mut lo, mut hi) = (0.5, f64::INFINITY);
        let mut f = 0.5;
        while f <= 4.0 + 1e-9 {
            if contact_diverges(kn, probe.stable.dt_crit, f, steps)? {
                hi = f;
                break;
            }
            lo = f;
            f += grid;
        }
        if hi.is_finite() {
            (lo, hi) = bisect(lo, hi, iters, |f| contact_diverges(kn, probe.stable.dt_crit, f, steps))?;
        } else {
            hi = lo;
        }
        let m = 0.5 * (lo + hi);
        let outcome = if lo >= 4.0 - 1e-9 {
            "stable up to 4 x prediction (conservative)".to_string()
        } else if lo < 0.98 {
            format!("UNSAFE: blows up below the prediction ({m:.3})")
        } else {
            format!("blow-up at {m:.3} x prediction (contact share of omega^2: {share:.2})")
        };
        eprintln!("contact dt k_n = {kn:e}: threshold/prediction = {m:.4} (contact share of omega^2 {share:.3})");
        rows.push(Row { study: "contact_dt".into(), case: format!("block on base / k_n = {kn:e}"), parameter: "k_n (measured: dt/dt_crit)".into(), value: kn, measured: m, outcome });
    }
    Ok(())
}

const BAR: &str = "[mesh]\ntype = \"rectangle\"\nwidth = 10.0\nheight = 1.0\nnx = 20\nny = 2\n[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.25\ndensity = 1.0\n[[support]]\nnodes = \"left\"\nfix = \"x\"\n[[support]]\nnodes = \"bottom_left\"\nfix = \"xy\"\n[[load]]\nname = \"pull\"\ntype = \"traction\"\nedges = \"right\"\nvalue = [1.0, 0.0]\n";

fn steps_to_rest(damping: &str, cap: u64) -> Result<(u64, bool)> {
    let text = format!("{BAR}[solver]\ntolerance = 1e-8\nmax_steps = {cap}\n[solver.damping]\n{damping}\n[[stage]]\nlevels = {{ pull = 1.0 }}\n");
    let mut s = Simulation::new(scene(&text)?)?;
    s.run(&mut NoOutput)?;
    Ok((s.stages_done[0].steps, s.stages_done[0].converged))
}

fn damping(quick: bool, rows: &mut Vec<Row>) -> Result<()> {
    let cap = if quick { 100_000 } else { 400_000 };
    // omega_1 from the Rayleigh quotient of the static solution: w^2 = u.K u / u.M u.
    let mut s = Simulation::new(scene(&format!("{BAR}[[stage]]\nlevels = {{ pull = 1.0 }}\n"))?)?;
    s.set_stage_levels(0);
    let u = flem_plugins::check::static_solve(&s)?;
    let mut f = vec![[0.0; 2]; u.len()];
    s.model.internal_forces(&u, &mut f);
    let uku: f64 = u.iter().zip(&f).map(|(a, b)| a[0] * b[0] + a[1] * b[1]).sum();
    let umu: f64 = u.iter().zip(&s.state.mass).map(|(a, m)| m * (a[0] * a[0] + a[1] * a[1])).sum();
    // the axial mode the load excites (the bar's bending modes are far lower: a multiple of
    // this "critical" value overdamps them, which the table shows)
    let w1 = (uku / umu).sqrt();
    let crit = 2.0 * w1;
    let ratios: &[f64] = if quick { &[0.1, 0.5, 0.8, 0.95] } else { &[0.02, 0.05, 0.1, 0.2, 0.4, 0.6, 0.8, 0.9, 0.95, 0.99] };
    for &r in ratios {
        let (n, ok) = steps_to_rest(&format!("type = \"local\"\nratio = {r}"), cap)?;
        eprintln!("damping local ratio {r}: {n} steps{}", if ok { "" } else { " (not at rest)" });
        rows.push(Row {
            study: "damping".into(),
            case: "local".into(),
            parameter: "ratio".into(),
            value: r,
            measured: n as f64,
            outcome: if ok { "at rest".into() } else { format!("not at rest after {cap} steps") },
        });
    }
    let mults: &[f64] = if quick { &[0.1, 1.0, 10.0] } else { &[0.03, 0.1, 0.3, 0.5, 1.0, 2.0, 4.0, 10.0, 30.0] };
    for &m in mults {
        let (n, ok) = steps_to_rest(&format!("type = \"viscous\"\nalpha = {}", m * crit), cap)?;
        eprintln!("damping viscous {m} x critical: {n} steps{}", if ok { "" } else { " (not at rest)" });
        rows.push(Row {
            study: "damping".into(),
            case: "viscous".into(),
            parameter: "alpha/(2 omega_1)".into(),
            value: m,
            measured: n as f64,
            outcome: if ok { "at rest".into() } else { format!("not at rest after {cap} steps") },
        });
    }
    let (n, ok) = steps_to_rest("type = \"adaptive\"", cap)?;
    rows.push(Row {
        study: "damping".into(),
        case: "adaptive".into(),
        parameter: "-".into(),
        value: 0.0,
        measured: n as f64,
        outcome: if ok { "at rest".into() } else { format!("not at rest after {cap} steps") },
    });
    Ok(())
}

fn implicit_after_separation(rows: &mut Vec<Row>) -> Result<()> {
    // A plate with a pre-cut side notch over 3/4 of its width and a weak ligament (Rankine,
    // sigma_t = 0.5 under a traction of 1): the crack runs and leaves the top part held by a
    // hinge (or free): a mechanism, which the explicit run carries on with.
    let text = "[mesh]\ntype = \"rectangle\"\nwidth = 2.0\nheight = 2.0\nnx = 4\nny = 4\nnotch = { side = \"left\", y = 1.0, depth = 1.5 }\n[model]\nseparated = [\"notch\"]\n[[material]]\nyoung_modulus = 100.0\npoisson_ratio = 0.3\ndensity = 1.0\n[[support]]\nnodes = \"bottom\"\nfix = \"xy\"\n[[load]]\nname = \"pull\"\ntype = \"traction\"\nedges = \"top\"\nvalue = [0.0, 1.0]\n[cracking]\nstall_steps = 10000\n[cracking.criterion]\ntype = \"rankine\"\ntensile_strength = 0.5\n[cracking.separation]\ntype = \"sigma1_nearest\"\n[[stage]]\nlevels = { pull = 1.0 }\nmax_steps = 60000\n";
    let mut s = Simulation::new(scene(text)?)?;
    s.run(&mut NoOutput)?;
    let frags = s.model.topo.fragments().1;
    let explicit_ok = s.state.u.iter().all(|u| u[0].is_finite() && u[1].is_finite());
    let msg = match flem_plugins::check::static_solve(&s) {
        Ok(_) => "implicit solve succeeded (unexpected)".to_string(),
        Err(e) => e.to_string(),
    };
    eprintln!("implicit after separation: {frags} fragments; explicit finite = {explicit_ok}; implicit: {msg}");
    rows.push(Row {
        study: "implicit_after_separation".into(),
        case: format!("cracked plate: {frags} fragment(s), top part hinged or free"),
        parameter: "-".into(),
        value: 0.0,
        measured: explicit_ok as u8 as f64,
        outcome: format!("explicit runs on (finite: {explicit_ok}); implicit: {msg}"),
    });
    Ok(())
}

pub fn markdown(rows: &[Row]) -> String {
    let mut s = String::from("| study | case | parameter | value | measured | outcome |\n|---|---|---|---|---|---|\n");
    for r in rows {
        let num = |x: f64| if x.fract() == 0.0 { format!("{x}") } else { format!("{x:.4}") };
        s += &format!("| {} | {} | {} | {} | {} | {} |\n", r.study, r.case, r.parameter, num(r.value), num(r.measured), r.outcome.replace('|', "/").replace('\n', " "));
    }
    s
}

pub fn csv(rows: &[Row]) -> String {
    let mut s = String::from("study,case,parameter,value,measured,outcome\n");
    for r in rows {
        s += &format!("{},\"{}\",\"{}\",{:e},{:e},\"{}\"\n", r.study, r.case, r.parameter, r.value, r.measured, r.outcome.replace('"', "'"));
    }
    s
}

pub fn run(out: Option<PathBuf>, quick: bool) -> Result<()> {
    let out = out.unwrap_or_else(|| PathBuf::from("out/stability"));
    let _lock = crate::lock_out(&out)?;
    flem_core::output::prepare_dir(&out)?;
    let mut rows = Vec::new();
    explicit_dt(quick, &mut rows).context("explicit step study")?;
    contact_dt(quick, &mut rows).context("contact stiffness study")?;
    damping(quick, &mut rows).context("damping study")?;
    implicit_after_separation(&mut rows).context("implicit after separation")?;
    flem_core::output::atomic_write(&out.join("stability.csv"), csv(&rows).as_bytes())?;
    flem_core::output::atomic_write(&out.join("stability.json"), serde_json::to_string_pretty(&rows)?.as_bytes())?;
    flem_core::output::atomic_write(&out.join("stability.md"), markdown(&rows).as_bytes())?;
    let mut d = flem_plot::charts::StabilityData::default();
    for r in &rows {
        match r.study.as_str() {
            "explicit_dt" => d.thresholds.push((r.case.clone(), r.measured)),
            "contact_dt" => d.thresholds.push((format!("contact k_n = {:.0e}", r.value), r.measured)),
            "damping" if r.case != "adaptive" => d.damping.push((r.case.clone(), r.value, r.measured, r.outcome == "at rest")),
            _ => {}
        }
    }
    flem_plot::charts::stability(&out.join("stability"), &d)?;
    eprintln!("{} rows: stability.csv, stability.json, stability.md, stability.png, stability.svg in {}", rows.len(), out.display());
    Ok(())
}
