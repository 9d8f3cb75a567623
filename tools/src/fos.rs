//! `flem fos SCENE --out DIR`: factor of safety by strength reduction (ours, issue 21). The
//! search and its criterion are `flem_core::solver::fos` (docs/materials.md); this file writes
//! DIR/fos.json and the mechanism picture DIR/mechanism.png/.svg (plastic shear strain of the
//! lowest F that flowed, on the deformed mesh).
use std::path::PathBuf;

use anyhow::{Context, Result};
use flem_core::solver::fos::{factor_of_safety, FosOptions, Trial};

#[derive(clap::Args)]
pub struct Args {
    pub scene: PathBuf,
    /// Output folder (default: out/<scene name>_fos).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Initial bracket (widened when lo flows or hi stands).
    #[arg(long, default_value_t = 0.5)]
    pub lo: f64,
    #[arg(long, default_value_t = 3.0)]
    pub hi: f64,
    /// Bisect until hi - lo <= rel_tol * lo.
    #[arg(long, default_value_t = 0.01)]
    pub rel_tol: f64,
    #[arg(long, default_value_t = 16)]
    pub max_trials: usize,
    /// A stage short of its tolerance at its step limit flows when its largest displacement grew
    /// by more than this fraction over the second half of its steps.
    #[arg(long, default_value_t = 0.1)]
    pub growth: f64,
}

pub fn run(a: Args) -> Result<()> {
    let text = std::fs::read_to_string(&a.scene).with_context(|| format!("{}: cannot be read", a.scene.display()))?;
    let base = a.scene.parent().map(|p| p.to_path_buf()).unwrap_or_default();
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join(format!("{}_fos", a.scene.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default())));
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot be created", out.display()))?;
    // A scene whose laws have no strength to reduce has no factor of safety: said before any trial.
    if let Err(e) = flem_core::solver::fos::reduced_scene(&text, &a.scene, &base, 1.0) {
        if matches!(&e, flem_core::FlemError::Config { key, .. } if key == "material") {
            return Err(crate::unsuited(&a.scene, "fos", format!("it reduces the strength of the material laws, and {e}")));
        }
        return Err(e.into());
    }
    let o = FosOptions { lo: a.lo, hi: a.hi, rel_tol: a.rel_tol, max_trials: a.max_trials, growth: a.growth };
    let mut show = |t: &Trial| {
        eprintln!(
            "F = {:.4}: {} (ratio {:.2e} after {} steps, {}; largest displacement {:.4e}, grew {:.1} % over the second half) {:.1} s",
            t.f,
            if t.flows { "flows" } else { "equilibrium" },
            t.ratio,
            t.steps,
            if t.converged { "converged" } else { "step limit" },
            t.u_max,
            100.0 * t.growth,
            t.seconds
        );
    };
    let r = factor_of_safety(&text, &a.scene, &base, &o, &mut show)?;
    // The mechanism: plastic shear strain of the lowest F that flowed, on the deformed mesh
    // (true scale: the mechanism's own displacement).
    let arr = flem_core::output::arrays::result_arrays(&r.flow);
    let (g, _) = arr.plastic.clone().context("the scene has no plastic law: no mechanism to draw")?;
    let cells: Vec<Vec<[f64; 2]>> = (0..arr.kinds.len())
        .map(|e| {
            let (s, t) = (arr.copy_offsets[e] as usize, arr.copy_offsets[e + 1] as usize);
            arr.clusters[s..t].iter().map(|&c| [arr.points[c as usize][0] + arr.displacement[c as usize][0], arr.points[c as usize][1] + arr.displacement[c as usize][1]]).collect()
        })
        .collect();
    let title = format!("{}: plastic shear strain at F = {:.4} (flows); factor of safety {:.4} in [{:.4}, {:.4}]", a.scene.display(), r.bracket[1], r.fos, r.bracket[0], r.bracket[1]);
    let files =
        flem_plot::field::element_field(&out.join("mechanism"), &flem_plot::field::Field { title: &title, label: "plastic shear strain (deformed mesh, true scale)", cells: &cells, values: &g })?;
    let json = serde_json::json!({
        "fos": r.fos,
        "bracket": r.bracket,
        "scene": a.scene.display().to_string(),
        "criterion": {
            "equilibrium": "the last stage reaches its unbalanced-force ratio tolerance, or its largest displacement grows by at most `growth` of its final value over the second half of its steps",
            "flows": "the ratio is above the tolerance at the step limit and the largest displacement grew by more than `growth` over the second half",
            "growth": a.growth,
            "rel_tol": a.rel_tol,
        },
        "reduction": "c / F and tan(phi) / F for every law with a strength (dilation angle capped at the reduced friction angle)",
        "mechanism_f": r.bracket[1],
        "pictures": files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
        "trials": r.trials,
    });
    flem_core::output::atomic_write(&out.join("fos.json"), serde_json::to_string_pretty(&json)?.as_bytes())?;
    println!("factor of safety {:.4} (bracket [{:.4}, {:.4}], {} trials); {}", r.fos, r.bracket[0], r.bracket[1], r.trials.len(), out.join("fos.json").display());
    Ok(())
}
