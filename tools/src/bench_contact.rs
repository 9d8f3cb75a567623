//! `flem bench contact`: the cost of the contact search against the number of surface nodes.
//!
//! Scene: `k` strips of 50 x 1 square elements stacked on each other (every node is a surface
//! node, `boundary = true`; 1e-6 apart, as touching parts may not share points), each strip
//! pressed 1e-6 into the one below so that every
//! interface is in contact. Measured per size: one Verlet-list build (grid broad phase) and
//! one contact step without rebuild (narrow phase + law + scatter), the best of `repeats`.
//! Prints JSON with the growth exponents (least-squares slope of log time against log n).
use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use flem_core::scene::Scene;
use flem_core::solver::Simulation;
use serde_json::json;

fn scene(strips: usize) -> String {
    let parts: Vec<String> = (0..strips).map(|k| format!("  {{ name = \"s{k}\", origin = [0.0, {}], width = 50.0, height = 1.0, nx = 50, ny = 1 }},", k as f64 * (1.0 + 1e-6))).collect();
    format!(
        "[mesh]\ntype = \"rectangles\"\nparts = [\n{}\n]\n\n[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.25\ndensity = 1.0\n\n[contact]\nlaw = {{ type = \"penalty\", normal_stiffness = 1e4 }}\nboundary = true\n\n[[stage]]\n",
        parts.join("\n")
    )
}

/// Least-squares slope of `ln y` against `ln x` (the growth exponent).
pub(crate) fn slope(xs: &[f64], ys: &[f64]) -> f64 {
    let n = xs.len() as f64;
    let (lx, ly): (Vec<f64>, Vec<f64>) = (xs.iter().map(|x| x.ln()).collect(), ys.iter().map(|y| y.ln()).collect());
    let (mx, my) = (lx.iter().sum::<f64>() / n, ly.iter().sum::<f64>() / n);
    let num: f64 = lx.iter().zip(&ly).map(|(x, y)| (x - mx) * (y - my)).sum();
    let den: f64 = lx.iter().map(|x| (x - mx) * (x - mx)).sum();
    num / den
}

pub fn run(sizes: &[usize], repeats: usize) -> Result<()> {
    let mut rows = Vec::new();
    let (mut ns, mut tb, mut ts) = (Vec::new(), Vec::new(), Vec::new());
    for &target in sizes {
        let strips = (target / 102).max(1);
        let sc = Scene::from_str(&scene(strips), Path::new("<bench contact>"), Path::new("."))?;
        let mut sim = Simulation::new(sc)?;
        for c in 0..sim.x0.len() {
            // Points are numbered part by part, 51 x 2 per strip.
            let k = (c / 102) as f64;
            sim.state.u[c][1] = -2e-6 * k;
        }
        let law = sim.scene.file.contact.as_ref().unwrap().law.as_ref();
        let con = sim.contact.as_mut().unwrap();
        let n = con.n_surface_nodes();
        let (mut best_build, mut best_step) = (f64::INFINITY, f64::INFINITY);
        let mut f = vec![[0.0; 2]; sim.x0.len()];
        con.compute(law, &sim.x0, &sim.state.u, &sim.state.v, 1e-3, &mut f);
        let active = con.n_active;
        for _ in 0..repeats {
            let t = Instant::now();
            con.build_verlet(&sim.x0, &sim.state.u);
            best_build = best_build.min(t.elapsed().as_secs_f64());
            let t = Instant::now();
            con.compute(law, &sim.x0, &sim.state.u, &sim.state.v, 1e-3, &mut f);
            best_step = best_step.min(t.elapsed().as_secs_f64());
        }
        rows.push(json!({ "surface_nodes": n, "faces": con.n_faces(), "active_pairs": active, "build_s": best_build, "step_s": best_step, "build_ns_per_node": 1e9 * best_build / n as f64, "step_ns_per_node": 1e9 * best_step / n as f64 }));
        ns.push(n as f64);
        tb.push(best_build);
        ts.push(best_step);
    }
    let out = json!({ "bench": "contact", "repeats": repeats, "sizes": rows, "exponent_build": slope(&ns, &tb), "exponent_step": slope(&ns, &ts) });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}
