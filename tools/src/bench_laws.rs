//! `flem bench laws`: ns per element-update of the material laws (issue 21), one JSON object.
//!
//! One Q4 mesh (2 x 1 rectangle), one thread, `Model::update_internal_forces` (the step's
//! element loop: stress update, history, forces, scatter) timed for:
//! - `elastic`: the default linear elastic law on the stateless blocked kernel (the reference);
//! - `mohr_coulomb_elastic`: the plastic law while every point stays elastic (cohesion far
//!   above the stress): the cost of the stateful block and of the yield check;
//! - `mohr_coulomb_elastic_stored`: the same with `elastic_shortcut = false` (every point's
//!   stress stored and updated incrementally; the default gives a pack whose points never
//!   yielded the stress of the total strain, storing nothing: `element/stateful.rs`);
//! - `mohr_coulomb_plastic`: every point returns at every update, to an edge or a corner of
//!   the tension cut-off (cohesion far below the stress, a shear with a stretch alternating in
//!   sign, `tension_cutoff = 0`): the return's worst case, several active sets tried per point;
//! - `mohr_coulomb_plastic_face`: every point returns to the main (shear) face at every update
//!   (a compression with a shear alternating in sign, no cut-off below the apex): the usual
//!   return of a plastic zone in compression (the footing, the slope);
//! - `large_strain_elastic`, `large_strain_mohr_coulomb_elastic`, `large_strain_mohr_coulomb`:
//!   the same with `large_strain` (geometry and spin recomputed every update);
//! - `corotational`: the linear law with `corotational = true` (`element::corot`: each
//!   element's best-fit rotation, the linear kernel on the local displacements, the forces
//!   rotated back), the kinematics of the paper's direct shear scenes.
//!
//! Each case alternates between two displacement fields, so every update sees a real
//! strain increment. `plastic_fraction` is the fraction of the elements whose points were
//! plastic in the last update (the cases say what they measure). `over_elastic` divides by the
//! `elastic` figure of the same run; `ratios` gives the must-show quotients of issue 21 (plastic
//! law against the elastic kernel, large strain against small strain).
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

/// The two displacement fields a case alternates between.
#[derive(Clone, Copy)]
enum Motion {
    /// A shear and a stretch of 1e-3, and the opposite.
    ShearStretch,
    /// A compression of 1e-3 with a shear of 2e-3, and the same compression with the opposite
    /// shear: the increments are pure shear, the stress stays compressive.
    CompressedShear,
}

pub fn run(n: usize, min_time: f64, only: &[String]) -> Result<()> {
    let mc_el = "law = { type = \"mohr_coulomb\", cohesion = 1e6, friction_angle_deg = 30.0, dilation_angle_deg = 0.0 }";
    let mc_pl = "law = { type = \"mohr_coulomb\", cohesion = 1e-6, friction_angle_deg = 30.0, dilation_angle_deg = 0.0, tension_cutoff = 0.0 }";
    let mc_face = "law = { type = \"mohr_coulomb\", cohesion = 1e-6, friction_angle_deg = 30.0, dilation_angle_deg = 0.0 }";
    let mc_el_stored = format!("elastic_shortcut = false\n{mc_el}");
    use Motion::*;
    let cases = [
        ("elastic", "", false, ShearStretch),
        ("mohr_coulomb_elastic", mc_el, false, ShearStretch),
        ("mohr_coulomb_elastic_stored", mc_el_stored.as_str(), false, ShearStretch),
        ("mohr_coulomb_plastic", mc_pl, false, ShearStretch),
        ("mohr_coulomb_plastic_face", mc_face, false, CompressedShear),
        ("large_strain_elastic", "", true, ShearStretch),
        ("large_strain_mohr_coulomb_elastic", mc_el, true, ShearStretch),
        ("large_strain_mohr_coulomb", mc_pl, true, ShearStretch),
        ("corotational", "corotational = true", false, ShearStretch),
    ];
    let mut rows = Vec::new();
    let mut ns_of = std::collections::BTreeMap::new();
    let mut base = 0.0;
    for o in only {
        anyhow::ensure!(cases.iter().any(|c| c.0 == o), "--cases: no case `{o}` (cases: {})", cases.map(|c| c.0).join(", "));
    }
    for (name, law, large, motion) in cases {
        if name != "elastic" && !only.is_empty() && !only.iter().any(|o| o == name) {
            continue;
        }
        let mut m = model(n, law, large)?;
        let x0 = m.cluster_x0();
        let nc = x0.len();
        let (ua, ub): (Vec<[f64; 2]>, Vec<[f64; 2]>) = match motion {
            ShearStretch => {
                let ua: Vec<[f64; 2]> = x0.iter().map(|p| [1e-3 * (p[1] + 0.3 * p[0]), -1e-3 * 0.5 * p[1]]).collect();
                let ub = ua.iter().map(|v| [-v[0], -v[1]]).collect();
                (ua, ub)
            }
            CompressedShear => {
                let f = |p: &[f64; 2], g: f64| [-1e-3 * p[0] + 0.5 * g * p[1], -1e-3 * p[1] + 0.5 * g * p[0]];
                (x0.iter().map(|p| f(p, 4e-3)).collect(), x0.iter().map(|p| f(p, -4e-3)).collect())
            }
        };
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
        let plastic = m.blocks.iter().flat_map(|b| (0..b.len()).map(move |i| b.plastic(i))).filter(|p| matches!(p, Some((_, 1)))).count();
        ns_of.insert(name, ns);
        rows.push(json!({"law": name, "elements": ne, "ns_per_elem_update": ns, "cpu_ns_per_elem_update": cpu * 1e9 / ne, "over_elastic": ns / base, "plastic_fraction": plastic as f64 / ne}));
        eprintln!("bench laws: {name} {ns:.1} ns per element-update");
    }
    // A quotient of two cases that ran (`--cases` may leave some out).
    let mut ratios = serde_json::Map::new();
    for (key, a, b) in [
        ("plastic_law_elastic_regime_over_elastic", "mohr_coulomb_elastic", "elastic"),
        ("plastic_law_elastic_regime_stored_over_elastic", "mohr_coulomb_elastic_stored", "elastic"),
        ("plastic_regime_over_elastic", "mohr_coulomb_plastic", "elastic"),
        ("plastic_face_over_elastic", "mohr_coulomb_plastic_face", "elastic"),
        ("large_over_small_elastic", "large_strain_elastic", "elastic"),
        ("large_over_small_mohr_coulomb_elastic", "large_strain_mohr_coulomb_elastic", "mohr_coulomb_elastic"),
        ("large_over_small_mohr_coulomb_plastic", "large_strain_mohr_coulomb", "mohr_coulomb_plastic"),
        ("corotational_over_elastic", "corotational", "elastic"),
    ] {
        if let (Some(x), Some(y)) = (ns_of.get(a), ns_of.get(b)) {
            ratios.insert(key.into(), json!(x / y));
        }
    }
    let ratios = serde_json::Value::Object(ratios);
    eprintln!("bench laws: ratios {ratios}");
    println!("{}", serde_json::to_string_pretty(&json!({"bench": "laws", "kind": "Q4", "threads": 1, "cases": rows, "ratios": ratios}))?);
    Ok(())
}
