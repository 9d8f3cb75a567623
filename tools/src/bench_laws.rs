//! `flem bench laws`: ns per element-update of the material laws (issue 21), one JSON object.
//!
//! One Q4 mesh (2 x 1 rectangle), one thread, `Model::update_internal_forces` (the step's
//! element loop: stress update, history, forces, scatter) timed for:
//! - `elastic`: the default linear elastic law on the stateless blocked kernel (the reference);
//! - `mohr_coulomb_elastic`: the plastic law while every point stays elastic (cohesion far
//!   above the stress): the cost of the stateful block and of the yield check;
//! - `mohr_coulomb_plastic`: every point returns to the surface at every update (cohesion
//!   far below the stress, the displacement alternating in sign);
//! - `large_strain_elastic`, `large_strain_mohr_coulomb`: the same with `large_strain`
//!   (geometry and spin recomputed every update).
//!
//! Each case alternates between two displacement fields, so every update sees a real
//! strain increment. The ratios divide by the `elastic` figure of the same run.
use anyhow::Result;
use flem_core::element::model::{Model, ModelOpts};
use flem_core::element::Plane;
use flem_core::mesh::{CellKind, Rectangle, ValidationOptions};
use flem_core::scene::MaterialCfg;
use serde_json::json;

fn model(n: usize, law: &str, large: bool) -> Result<Model> {
    let nx = ((2 * n) as f64).sqrt().round() as usize;
    let mut mesh = Rectangle::new(2.0, 1.0, nx, nx / 2, CellKind::Q4).build()?;
    mesh.validate(ValidationOptions::Reorient)?;
    mesh.derive_node_sets();
    let mat: MaterialCfg = toml::from_str(&format!("young_modulus = 100.0\npoisson_ratio = 0.3\ndensity = 1.0\n{law}"))?;
    Ok(Model::new_with(mesh, &[mat], Plane::Strain, ModelOpts { large_strain: large }, "<bench>")?)
}

pub fn run(n: usize, min_time: f64) -> Result<()> {
    let cases = [
        ("elastic", "", false),
        ("mohr_coulomb_elastic", "law = { type = \"mohr_coulomb\", cohesion = 1e6, friction_angle_deg = 30.0, dilation_angle_deg = 0.0 }", false),
        ("mohr_coulomb_plastic", "law = { type = \"mohr_coulomb\", cohesion = 1e-6, friction_angle_deg = 30.0, dilation_angle_deg = 0.0, tension_cutoff = 0.0 }", false),
        ("large_strain_elastic", "", true),
        ("large_strain_mohr_coulomb", "law = { type = \"mohr_coulomb\", cohesion = 1e-6, friction_angle_deg = 30.0, dilation_angle_deg = 0.0, tension_cutoff = 0.0 }", true),
    ];
    let mut rows = Vec::new();
    let mut base = 0.0;
    for (name, law, large) in cases {
        let mut m = model(n, law, large)?;
        let x0 = m.cluster_x0();
        let nc = x0.len();
        // A shear and a stretch of 1e-3, and the opposite: every update is a real increment.
        let ua: Vec<[f64; 2]> = x0.iter().map(|p| [1e-3 * (p[1] + 0.3 * p[0]), -1e-3 * 0.5 * p[1]]).collect();
        let ub: Vec<[f64; 2]> = ua.iter().map(|v| [-v[0], -v[1]]).collect();
        let mut f = vec![[0.0; 2]; nc];
        let mut flip = false;
        let (s, cpu) = crate::bench::time_per_call(min_time, || {
            flip = !flip;
            m.update_internal_forces(if flip { &ua } else { &ub }, &mut f);
        });
        let ne = m.n_elems() as f64;
        let ns = s * 1e9 / ne;
        if name == "elastic" {
            base = ns;
        }
        rows.push(json!({"law": name, "elements": ne, "ns_per_elem_update": ns, "cpu_ns_per_elem_update": cpu * 1e9 / ne, "over_elastic": ns / base}));
        eprintln!("bench laws: {name} {ns:.1} ns per element-update");
    }
    println!("{}", serde_json::to_string_pretty(&json!({"bench": "laws", "kind": "Q4", "threads": 1, "cases": rows}))?);
    Ok(())
}
