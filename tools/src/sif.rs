//! `flem sif SCENE [--stage K] [--tip x,y] [--out DIR]`: stress intensity factors at the crack
//! tips of a scene's model (pre-cut edges), from the implicit solve of each stage (issue 34).
//! The integrals are `flem_plugins::check::sif` (interaction integral, domain form; docs/paths.md);
//! this file solves, prints a table and writes DIR/sif.json atomically.
use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result};
use flem_core::scene::Scene;
use flem_core::solver::Simulation;
use flem_plugins::check::sif::{stage_sif, Radii, StageSif};

#[derive(clap::Args)]
pub struct Args {
    pub scene: PathBuf,
    /// Only stage K (1-based; default: every stage, each with the load levels of the stages up
    /// to it).
    #[arg(long, value_name = "K")]
    pub stage: Option<usize>,
    /// Only the crack tip at this point (within half an element size): x,y.
    #[arg(long, value_name = "X,Y", value_delimiter = ',')]
    pub tip: Option<Vec<f64>>,
    /// Outer domain radii as multiples of the element size at the tip (r_in = r_out / 2).
    #[arg(long, value_delimiter = ',', default_values_t = vec![4.0, 6.0, 8.0], conflicts_with = "radius")]
    pub radii: Vec<f64>,
    /// Outer domain radii in the scene's length unit instead (r_in = r_out / 2).
    #[arg(long, value_delimiter = ',')]
    pub radius: Vec<f64>,
    /// Output folder (default: out/<scene name>_sif).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    let radii = if a.radius.is_empty() { Radii::ElementSizes(a.radii.clone()) } else { Radii::Absolute(a.radius.clone()) };
    let rs = match &radii {
        Radii::ElementSizes(v) | Radii::Absolute(v) => v,
    };
    anyhow::ensure!(!rs.is_empty() && rs.iter().all(|&r| r.is_finite() && r > 0.0), "--radii/--radius: every value must be finite and > 0");
    anyhow::ensure!(a.tip.as_ref().is_none_or(|t| t.len() == 2 && t.iter().all(|v| v.is_finite())), "--tip: give two finite coordinates, x,y");
    let tip = a.tip.as_ref().map(|t| [t[0], t[1]]);
    let scene = Scene::from_file(&a.scene)?;
    let n = scene.file.stages.len();
    let stages: Vec<usize> = match a.stage {
        Some(k) => {
            anyhow::ensure!(k >= 1 && k <= n, "--stage {k}: the scene {} has {n} stage(s) (counted from 1)", a.scene.display());
            vec![k - 1]
        }
        None => (0..n).collect(),
    };
    let stem = a.scene.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "scene".into());
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join(format!("{stem}_sif")));
    let _lock = crate::lock_out(&out)?;
    let mut sim = Simulation::new(scene)?;
    let plane = format!("{:?}", sim.model.plane).to_lowercase();
    let mut rows: Vec<StageSif> = Vec::new();
    for &k in &stages {
        let r = stage_sif(&mut sim, k, tip, &radii).with_context(|| format!("stage {}", k + 1))?;
        print!("{}", table(&r));
        rows.push(r);
    }
    let v = serde_json::json!({
        "scene": a.scene.display().to_string(),
        "title": sim.scene.file.title,
        "plane": plane,
        "method": "interaction integral, domain form (Yau, Wang & Corten 1980; Moes et al. 1999); q = 1 inside r_in, linear to 0 at r_out; K = mean over the domains",
        "mts": "theta = 2 atan(-2 r / (1 + sqrt(1 + 8 r^2))), r = K_II / K_I, degrees from the crack's direction, counter-clockwise positive",
        "radii": radii,
        "stages": rows,
    });
    let path = out.join("sif.json");
    flem_core::output::atomic_write(&path, serde_json::to_string_pretty(&v)?.as_bytes())?;
    println!("results in {}", path.display());
    let failed: Vec<String> = rows.iter().flat_map(|s| s.tips.iter().filter(|t| t.error.is_some()).map(move |t| format!("stage {} tip at point {}", s.stage + 1, t.point))).collect();
    anyhow::ensure!(failed.is_empty(), "no factors at {} (see above and sif.json)", failed.join(", "));
    Ok(())
}

/// The printed table of one stage.
fn table(s: &StageSif) -> String {
    let mut o = format!("stage {} ({})\n", s.stage + 1, s.name);
    for t in &s.tips {
        let _ = write!(o, "  tip at point {} ({:.6}, {:.6})", t.point, t.x[0], t.x[1]);
        let Some(r) = &t.sif else {
            let _ = writeln!(o, ": {}", t.error.as_deref().unwrap_or("no result"));
            continue;
        };
        let _ = writeln!(o, ", crack direction {:.2} deg, element size {:.3e}", r.tip.dir[1].atan2(r.tip.dir[0]).to_degrees(), r.tip.h);
        let _ = writeln!(o, "    {:>10} {:>10} {:>6} {:>12} {:>12} {:>12} {:>12}", "r_in", "r_out", "elems", "K_I", "K_II", "J", "G");
        for d in &r.domains {
            let _ = writeln!(o, "    {:>10.3e} {:>10.3e} {:>6} {:>12.5e} {:>12.5e} {:>12.5e} {:>12.5e}", d.r_in, d.r_out, d.elements, d.k1, d.k2, d.j, d.g);
        }
        let mts = r.mts_deg.map_or_else(|| "none (K_I < 0: closed)".to_string(), |t| format!("{t:.2} deg"));
        let _ = writeln!(o, "    mean K_I {:.5e}, K_II {:.5e} (spread over the domains {:.2e}); J {:.5e}, G {:.5e}; MTS kink {mts}", r.k1, r.k2, r.spread, r.j, r.g);
        if let Some([k1, k2, n]) = r.displacement_correlation {
            let _ = writeln!(o, "    cross-check by displacement correlation ({n} face points): K_I {k1:.5e}, K_II {k2:.5e}");
        }
    }
    o
}
