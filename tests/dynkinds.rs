//! Contact laws, damping schemes and material laws from a shared library (issue 25): the
//! example library's copies (plugins/example: `example_spring_dashpot`, `example_adaptive`,
//! `example_mohr_coulomb`) loaded at run time give results bit-identical to the built-ins they
//! copy; a checkpoint written with dynamic plugins resumes bit-identically; a library lacking
//! a function is refused when it loads, naming it; a plugin returning NaN stops the run with
//! its name.
//!
//! Reference for the comparisons: the same scene with the built-in plugin (the arithmetic is
//! the same, in the same order, so any difference is the ABI's: a lost history slot, a
//! reordered batch, a wrong stride). Tolerance: none (`f64::to_bits`).
use std::path::Path;

use flem_core::plugin::dynload;
use flem_core::solver::Simulation;

use crate::common::root;
use crate::dynplug::{libs, load_line, scene_in, Log};

/// Every bit a run leaves: its splits, the final u and v of every cluster, the contact pairs
/// with their history, and the blocks' state (stress and history of every Gauss point).
#[derive(PartialEq, Debug)]
struct Print {
    splits: Vec<String>,
    uv: Vec<u64>,
    pairs: Vec<String>,
    blocks: Vec<u64>,
}

fn run(text: &str, base: &Path) -> (Print, Simulation) {
    let mut sim = Simulation::new(scene_in(text, base).unwrap_or_else(|e| panic!("{e}"))).unwrap_or_else(|e| panic!("{e}"));
    let mut log = Log::default();
    sim.run(&mut log).unwrap_or_else(|e| panic!("{e}"));
    let splits = log.0.iter().map(|e| format!("{} {:?} {:?} {:?} {:x} {:?} {:x?}", e.step, e.point, e.new_cluster, e.mode, e.index.to_bits(), e.edges, e.stress.map(f64::to_bits))).collect();
    let uv = sim.state.u.iter().chain(&sim.state.v).flat_map(|x| x.map(f64::to_bits)).collect();
    let pairs = sim
        .contact
        .as_ref()
        .map(|c| {
            c.history
                .pairs
                .iter()
                .map(|p| {
                    let s = &p.state;
                    format!("{} {:?} {:x?} {}", p.slave, p.master, [s.en, s.es, s.max_open, s.offset, s.area, s.stored].map(f64::to_bits), s.fresh)
                })
                .collect()
        })
        .unwrap_or_default();
    let mut st = Vec::new();
    for b in &sim.model.blocks {
        b.save_state(&mut st);
    }
    let blocks = st.iter().map(|x| x.to_bits()).collect();
    (Print { splits, uv, pairs, blocks }, sim)
}

fn replace_once(text: &str, from: &str, to: &str) -> String {
    assert_eq!(text.matches(from).count(), 1, "{from:?} must occur once");
    text.replacen(from, to, 1)
}

/// The paper's direct shear box (configs/paper/direct_shear.toml: splits under compression,
/// crack faces in contact, pairs sliding) with its contact law `spring_dashpot` and with the
/// library's `example_spring_dashpot`: the same splits, displacements, velocities and contact
/// pairs with their history, bit for bit (the full scene: 22 elements, about 0.5 s).
#[test]
fn example_contact_law_is_bit_identical_to_spring_dashpot_on_the_direct_shear() {
    let base = root().join("configs/paper");
    let text = std::fs::read_to_string(base.join("direct_shear.toml")).unwrap();
    let (builtin, _) = run(&text, &base);
    let dynamic = replace_once(&text, "law = { type = \"spring_dashpot\"", "law = { type = \"example_spring_dashpot\"") + "\n" + &load_line(&libs().example);
    let (dynamic, _) = run(&dynamic, &base);
    assert!(builtin.splits.len() > 10 && !builtin.pairs.is_empty(), "the scene must split and keep contact pairs: {} splits, {} pairs", builtin.splits.len(), builtin.pairs.len());
    assert!(builtin == dynamic, "the dynamic contact law differs from the built-in");
}

/// The strip footing (configs/verification/strip_footing.toml, Prandtl's Tresca footing),
/// coarsened to 32 x 24 Q4 and 1200 steps, with friction: the same points go plastic with the
/// built-in `mohr_coulomb` and the library's `example_mohr_coulomb`, and every displacement,
/// velocity, Gauss-point stress and history is the same, bit for bit, for the Tresca law and a
/// frictional, dilatant one with a tension cut-off (the return's face, edge, apex and tension
/// branches). The dynamic run uses 2 threads (768 elements, above the block's parallel
/// threshold), the built-in 1: bit-identical whatever the thread count.
#[test]
fn example_material_law_is_bit_identical_to_mohr_coulomb_on_the_strip_footing() {
    let base = root().join("configs/verification");
    let text = std::fs::read_to_string(base.join("strip_footing.toml")).unwrap();
    let text = replace_once(&text, "nx = 64", "nx = 32");
    let text = replace_once(&text, "ny = 48", "ny = 24");
    let text = text.replace("max_steps = 9000", "max_steps = 1200");
    for law in ["cohesion = 1.0, friction_angle_deg = 0.0, dilation_angle_deg = 0.0", "cohesion = 1.0, friction_angle_deg = 30.0, dilation_angle_deg = 10.0, tension_cutoff = 0.5"] {
        let t = replace_once(&text, "cohesion = 1.0, friction_angle_deg = 0.0, dilation_angle_deg = 0.0", law);
        // The loaded law has no `elastic_start` (its points are always stored): the built-in
        // runs the same stored path (`elastic_shortcut = false`) for a bit-for-bit comparison.
        let t = replace_once(&t, "law = { type = \"mohr_coulomb\"", "elastic_shortcut = false\nlaw = { type = \"mohr_coulomb\"");
        let (builtin, sim) = run(&t, &base);
        let plastic = sim.model.blocks.iter().map(|b| (0..b.len()).filter(|&i| b.plastic(i).is_some_and(|p| p.1 > 0)).count()).sum::<usize>();
        assert!(plastic > 5, "{law}: only {plastic} elements went plastic");
        let dynamic = replace_once(&t, "type = \"mohr_coulomb\"", "type = \"example_mohr_coulomb\"");
        let dynamic = replace_once(&dynamic, "[solver]\n", "[solver]\nthreads = 2\n") + "\n" + &load_line(&libs().example);
        let (dynamic, dsim) = run(&dynamic, &base);
        assert!(builtin == dynamic, "{law}: the dynamic material law differs from the built-in");
        let plastic_dyn: Vec<_> = dsim.model.blocks.iter().flat_map(|b| (0..b.len()).map(|i| b.plastic(i).map(|(g, f)| (g.to_bits(), f)))).collect();
        let plastic_builtin: Vec<_> = sim.model.blocks.iter().flat_map(|b| (0..b.len()).map(|i| b.plastic(i).map(|(g, f)| (g.to_bits(), f)))).collect();
        assert_eq!(plastic_dyn, plastic_builtin, "{law}: the plastic output differs");
    }
}

/// The uniaxial tension crack (configs/verification/tension_crack.toml, two splits) with the
/// built-in `adaptive` damping and with the library's `example_adaptive` (its state, alpha,
/// kept by the core): the same splits, displacements and velocities, bit for bit, and the same
/// final damping state.
#[test]
fn example_damping_is_bit_identical_to_adaptive() {
    let base = root().join("configs/verification");
    let text = std::fs::read_to_string(base.join("tension_crack.toml")).unwrap();
    let with = |d: &str| replace_once(&text, "[solver]\n", &format!("[solver]\ndamping = {{ type = \"{d}\" }}\n"));
    let (builtin, bsim) = run(&with("adaptive"), &base);
    let (dynamic, dsim) = run(&(with("example_adaptive") + "\n" + &load_line(&libs().example)), &base);
    assert!(!builtin.splits.is_empty(), "the scene must split");
    assert!(builtin == dynamic, "the dynamic damping differs from the built-in");
    let state = |s: &Simulation| s.scene.file.solver.damping.as_ref().unwrap().state().iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert!(state(&bsim) == state(&dsim) && state(&bsim).len() == 1 && f64::from_bits(state(&bsim)[0]) > 0.0);
}

/// A run with a dynamic material law and a dynamic damping (the coarse strip footing) stopped
/// at several steps, its checkpoint written and resumed by a new simulation, ends bit-identical
/// to the uninterrupted run (final u, v, energy ledger, stage results, every result file): the
/// law's history and the scheme's state are the core's arrays (checkpoint section `blocks`,
/// the damping's state), nothing is the plugin's. Reference: tests/ckpt.rs's procedure.
#[test]
fn checkpoint_with_dynamic_law_and_damping_resumes_bit_identically() {
    let base = root().join("configs/verification");
    let text = std::fs::read_to_string(base.join("strip_footing.toml")).unwrap();
    let text = replace_once(&text, "nx = 64", "nx = 16");
    let text = replace_once(&text, "ny = 48", "ny = 12");
    let text = text.replace("max_steps = 9000", "max_steps = 900");
    let text = replace_once(&text, "type = \"mohr_coulomb\"", "type = \"example_mohr_coulomb\"");
    let text = replace_once(&text, "type = \"local\"\nratio = 0.8", "type = \"example_adaptive\"");
    let text = replace_once(&text, "history_every = 500", "history_every = 37\ncheckpoint_every = 200");
    // Absolute paths: tests/ckpt.rs reads scenes relative to configs/.
    let text = text + "\n" + &load_line(&libs().example);
    dynload::set_scene_plugin_consent(true);
    let ref_dir = crate::ckpt::tmp("dynlaw-ref");
    let mut reference = Simulation::new(crate::common::scene(&text)).unwrap();
    let mut w = flem_core::output::OutputWriter::new(&ref_dir, &reference).unwrap();
    reference.run(&mut w).unwrap();
    let plastic = reference.model.blocks.iter().map(|b| (0..b.len()).filter(|&i| b.plastic(i).is_some_and(|p| p.1 > 0)).count()).sum::<usize>();
    assert!(plastic > 0, "no plastic point: the test would not exercise the law's history");
    let total = reference.state.step;
    for at in [total / 3 + 1, total - 7] {
        crate::ckpt::interrupt_and_resume(&text, at, &reference, &ref_dir, &format!("dynlaw-{at}"));
    }
    let _ = std::fs::remove_dir_all(&ref_dir);
}

/// A library of the current ABI whose contact law lacks `contact_evaluate`
/// (plugins/testlib/examples/missing_fn.rs) is refused when it loads, naming the library, the
/// plugin and the function; a library built for another ABI and core version
/// (plugins/testlib) is refused naming both versions. Nothing of either runs.
#[test]
fn library_lacking_a_function_or_of_another_version_is_refused() {
    let lib = &libs().missing_fn;
    let e = dynload::load_library(lib).unwrap_err().to_string();
    assert!(e.contains(&lib.display().to_string()) && e.contains("contact law \"broken_contact\"") && e.contains("contact_evaluate"), "{e}");
    assert!(!dynload::loaded().iter().any(|p| p.name == "broken_contact"));
    let e = dynload::load_library(&libs().stale).unwrap_err().to_string();
    assert!(e.contains("plugin ABI 1") && e.contains(&format!("plugin ABI {}", dynload::abi::ABI_VERSION)) && e.contains("FLEM core 0.0.1-old"), "{e}");
}

/// `example_nan_law` returns NaN at a point's 40th update: the run stops with an error naming
/// the plugin, its library and the region (not a bare divergence), and nothing non-finite
/// is kept as a result.
#[test]
fn plugin_returning_nan_stops_the_run_with_its_name() {
    let base = root().join("configs/verification");
    let text = std::fs::read_to_string(base.join("tension_crack.toml")).unwrap();
    // Without its [check] (a linear elastic solve, which refuses any other law).
    let text = replace_once(&text, "[check]\nsolver = { type = \"faer_cholesky\" }\ntolerance = 1e-5", "");
    let text = replace_once(&text, "density = 1.0\n", "density = 1.0\nlaw = { type = \"example_nan_law\", nan_after = 40 }\n") + "\n" + &load_line(&libs().example);
    let mut sim = Simulation::new(scene_in(&text, &base).unwrap_or_else(|e| panic!("{e}"))).unwrap();
    let e = sim.run(&mut Log::default()).unwrap_err().to_string();
    assert!(
        e.contains("material law \"example_nan_law\"") && e.contains(&libs().example.canonicalize().unwrap().display().to_string()) && e.contains("non-finite stress") && e.contains("stopped at step"),
        "{e}"
    );
}

/// The scene snippets of the new kinds (docs/plugins.md and the `//!` docs of
/// plugins/example/src/{contact,damping,material}.rs) load the library by the name they show
/// and validate: each contact law in the direct shear scene, each damping and material law in
/// the strip footing (plane strain), the library loaded by its built path.
#[test]
fn new_kind_snippets_load_and_validate() {
    let lib = &libs().example;
    let read = |p: &str| std::fs::read_to_string(root().join(p)).unwrap();
    let base_of = |p: &str| -> toml::Table { toml::from_str(&read(p)).unwrap() };
    let mut n = 0;
    for file in ["docs/plugins.md", "plugins/example/src/contact.rs", "plugins/example/src/damping.rs", "plugins/example/src/material.rs"] {
        for b in crate::dynplug::blocks(&read(file), "toml").into_iter().filter(|b| b.contains("[contact]") || b.contains("[solver.damping]") || b.contains("[[material]]")) {
            let t: toml::Table = toml::from_str(&b).unwrap_or_else(|e| panic!("{file}: {e}\n{b}"));
            if let Some(shown) = t.get("plugins").and_then(|p| p["load"][0].as_str()) {
                assert!(shown.ends_with(lib.file_name().unwrap().to_str().unwrap()), "{file}: {shown}");
            }
            let mut scenes = Vec::new();
            if let Some(law) = t.get("contact").and_then(|c| c.get("law")) {
                let mut s = base_of("configs/paper/direct_shear.toml");
                s["contact"].as_table_mut().unwrap().insert("law".into(), law.clone());
                scenes.push((s, "configs/paper"));
            }
            if let Some(d) = t.get("solver").and_then(|c| c.get("damping")) {
                let mut s = base_of("configs/verification/strip_footing.toml");
                s["solver"].as_table_mut().unwrap().insert("damping".into(), d.clone());
                scenes.push((s, "configs/verification"));
            }
            if let Some(m) = t.get("material") {
                let mut s = base_of("configs/verification/strip_footing.toml");
                s.insert("material".into(), m.clone());
                scenes.push((s, "configs/verification"));
            }
            assert!(!scenes.is_empty(), "{file}: a snippet of no new kind:\n{b}");
            for (mut s, dir) in scenes {
                s.insert("plugins".into(), toml::Value::Table(toml::from_str(&load_line(lib)).unwrap()).get("plugins").unwrap().clone());
                let text = toml::to_string(&s).unwrap();
                let scene = scene_in(&text, &root().join(dir)).unwrap_or_else(|e| panic!("{file}: {e}\n{b}"));
                flem_core::solver::Simulation::new(scene).unwrap_or_else(|e| panic!("{file}: {e}\n{b}"));
                n += 1;
            }
        }
    }
    assert!(n >= 7, "only {n} snippets checked");
}

/// Issue 35 (loose end): a loaded contact law or damping scheme that returns NaN stops the run
/// with an error naming the plugin, its kind and its library (the wrappers' fault, reported by
/// the divergence guard: `Simulation::diverged`), not a bare divergence, and at the step where
/// it happened. The example library's copies with `nan_after` (tests only): the contact law's
/// 200th pair evaluation on the direct shear box, the damping's step 30 on the tension crack.
#[test]
fn contact_law_and_damping_returning_nan_stop_the_run_with_their_names() {
    let lib = libs().example.canonicalize().unwrap().display().to_string();
    let base = root().join("configs/paper");
    let text = std::fs::read_to_string(base.join("direct_shear.toml")).unwrap();
    let text = replace_once(&text, "law = { type = \"spring_dashpot\",", "law = { type = \"example_spring_dashpot\", nan_after = 200,") + "\n" + &load_line(&libs().example);
    let mut sim = Simulation::new(scene_in(&text, &base).unwrap_or_else(|e| panic!("{e}"))).unwrap();
    let e = sim.run(&mut Log::default()).unwrap_err().to_string();
    assert!(e.contains("contact law \"example_spring_dashpot\"") && e.contains(&lib) && e.contains("non-finite force") && e.contains("stopped at step"), "{e}");
    let base = root().join("configs/verification");
    let text = std::fs::read_to_string(base.join("tension_crack.toml")).unwrap();
    let text = replace_once(&text, "[solver]\n", "[solver]\ndamping = { type = \"example_adaptive\", nan_after = 30 }\n") + "\n" + &load_line(&libs().example);
    let mut sim = Simulation::new(scene_in(&text, &base).unwrap_or_else(|e| panic!("{e}"))).unwrap();
    let e = sim.run(&mut Log::default()).unwrap_err().to_string();
    assert!(e.contains("damping \"example_adaptive\"") && e.contains(&lib) && e.contains("non-finite damping coefficients") && e.contains("at step 30") && e.contains("stopped at step"), "{e}");
}
