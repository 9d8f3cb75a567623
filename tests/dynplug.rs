//! Dynamic plugins (issue 7): the example library (plugins/example, a cdylib that `flem` does
//! not link) is built by cargo from this test, loaded by a scene's `[plugins] load`, and must
//! give results bit-identical to the built-in plugins it copies. Every way a library can be
//! wrong gives its message, and nothing aborts the process.
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use flem_core::cracking::SplitEvent;
use flem_core::mesh::topology::SplitRecord;
use flem_core::plugin::dynload::{self, abi};
use flem_core::scene::Scene;
use flem_core::solver::{Observer, Simulation};

use crate::common::root;

/// The libraries built for these tests.
pub(crate) struct Libs {
    /// plugins/example.
    pub(crate) example: PathBuf,
    /// plugins/testlib: a header for FLEM core "0.0.1-old".
    pub(crate) stale: PathBuf,
    /// plugins/testlib/examples/no_entry.rs: no entry point.
    pub(crate) no_entry: PathBuf,
    /// plugins/testlib/examples/missing_fn.rs: a contact law without its evaluate function.
    pub(crate) missing_fn: PathBuf,
    /// The `flem` binary (`common::flem_exe`).
    pub(crate) flem: PathBuf,
}

/// Builds plugins/example and plugins/testlib, and the `flem` binary, once, with the cargo,
/// target folder and profile of this test binary (target/<profile>/deps/flem_tests-*), and finds
/// the shared libraries and the executable in cargo's JSON messages rather than guessing file
/// names (after `cargo test` all are up to date: cargo only checks). `--workspace --lib --examples` gives
/// the dependencies the same features as `cargo test --workspace`, so their compiled artifacts
/// are reused: only the two small crates compile (a few seconds), not a second copy of the
/// dependency tree.
pub(crate) fn libs() -> &'static Libs {
    static LIBS: OnceLock<Libs> = OnceLock::new();
    LIBS.get_or_init(|| {
        let exe = std::env::current_exe().unwrap();
        let profile_dir = exe.parent().and_then(Path::parent).expect("test binary in target/<profile>/deps");
        let target_dir = profile_dir.parent().expect("target folder");
        let profile = match profile_dir.file_name().and_then(|s| s.to_str()) {
            Some("debug") => "dev",
            Some(p) => p,
            None => "release",
        };
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let out = Command::new(cargo)
            // Not the unit-test harnesses (tests/unit/*): `cargo test` builds them as tests only.
            .args([
                "build",
                "--quiet",
                "--message-format=json",
                "--workspace",
                "--exclude",
                "flem-core-unit",
                "--exclude",
                "flem-plugins-unit",
                "--lib",
                "--bins",
                "--examples",
                "--profile",
                profile,
                "--target-dir",
            ])
            .arg(target_dir)
            .current_dir(root())
            .output()
            .expect("run cargo");
        assert!(out.status.success(), "building the plugin libraries failed:\n{}", String::from_utf8_lossy(&out.stderr));
        let mut found = std::collections::BTreeMap::new();
        for line in String::from_utf8_lossy(&out.stdout).lines() {
            let Ok(v) = serde_json::from_str::<serde_json::Value>(line) else { continue };
            if v["reason"] != "compiler-artifact" {
                continue;
            }
            let name = v["target"]["name"].as_str().unwrap_or_default().to_string();
            if let Some(exe) = v["executable"].as_str() {
                found.insert(format!("bin {name}"), PathBuf::from(exe));
            }
            for f in v["filenames"].as_array().into_iter().flatten().filter_map(|f| f.as_str()) {
                if f.ends_with(std::env::consts::DLL_SUFFIX) {
                    found.insert(name.clone(), PathBuf::from(f));
                }
            }
        }
        let get = |n: &str| found.get(n).cloned().unwrap_or_else(|| panic!("cargo built no shared library or executable for {n}: {found:?}"));
        Libs { example: get("flem_plugin_example"), stale: get("flem_plugin_testlib"), no_entry: get("no_entry"), missing_fn: get("missing_fn"), flem: get("bin flem") }
    })
}

/// A scene from text whose relative paths resolve against `base`.
pub(crate) fn scene_in(text: &str, base: &Path) -> flem_core::Result<Scene> {
    flem_plugins::link();
    // These scenes are the tests' own: consent to their libraries (the refusal without it is
    // tested through the CLI, in its own process, by scene_plugins_load_only_with_consent).
    dynload::set_scene_plugin_consent(true);
    Scene::from_str(text, Path::new("<dynplug scene>"), base)
}

/// The uniaxial tension crack scene (configs/verification/tension_crack.toml) with its
/// criterion and separation tables replaced and a `[plugins]` table added.
fn tension_scene(plugins: &str, criterion: &str, separation: &str) -> String {
    let base = std::fs::read_to_string(root().join("configs/verification/tension_crack.toml")).unwrap();
    let start = base.find("[cracking.criterion]").unwrap();
    let end = base.find("[[stage]]").unwrap();
    format!("{}[cracking.criterion]\n{criterion}\n\n[cracking.separation]\n{separation}\n\n{}\n{plugins}", &base[..start], &base[end..])
}

pub(crate) fn load_line(lib: &Path) -> String {
    format!("[plugins]\nload = [{:?}]\n", lib.display().to_string())
}

#[derive(Default)]
pub(crate) struct Log(pub(crate) Vec<SplitEvent>);
impl Observer for Log {
    fn splits(&mut self, _s: &Simulation, _r: &SplitRecord, ev: &[SplitEvent]) -> flem_core::Result<()> {
        self.0.extend(ev.iter().cloned());
        Ok(())
    }
}

/// Everything a run produces that must match, as bits: every split (step, point, clusters,
/// mode, index, sigma1 direction, cut edges, nodal stress) and the final displacement and
/// velocity of every cluster.
fn fingerprint(text: &str, base: &Path) -> (Vec<String>, Vec<u64>) {
    let mut sim = Simulation::new(scene_in(text, base).unwrap_or_else(|e| panic!("{e}"))).unwrap();
    let mut log = Log::default();
    sim.run(&mut log).unwrap();
    let splits = log
        .0
        .iter()
        .map(|e| {
            format!("{} {:?} {:?} {:?} {:?} {:x} {:x} {:?} {:x?}", e.step, e.point, e.cluster, e.new_cluster, e.mode, e.index.to_bits(), e.sigma1_deg.to_bits(), e.edges, e.stress.map(f64::to_bits))
        })
        .collect();
    let state = sim.state.u.iter().chain(&sim.state.v).flat_map(|x| x.map(f64::to_bits)).collect();
    (splits, state)
}

/// The example's `example_rankine` and `example_sigma1_nearest` (loaded from the cdylib, by a
/// path relative to the scene folder) reproduce the built-in `rankine` and `sigma1_nearest` bit
/// for bit on the tension crack scene: same splits, same displacements and velocities.
/// Reference: the built-in run (the plugins copy their arithmetic); tolerance: exact bits.
#[test]
fn dynamic_plugins_match_builtins_bit_for_bit() {
    let lib = &libs().example;
    let dir = lib.parent().unwrap();
    let rel = format!("[plugins]\nload = [{:?}]\n", lib.file_name().unwrap().to_str().unwrap());
    let builtin = fingerprint(&tension_scene("", "type = \"rankine\"\ntensile_strength = 1.0", "type = \"sigma1_nearest\""), dir);
    assert!(builtin.0.len() >= 3, "the reference run must crack: {:?}", builtin.0);
    let both = fingerprint(&tension_scene(&rel, "type = \"example_rankine\"\ntensile_strength = 1.0", "type = \"example_sigma1_nearest\""), dir);
    assert_eq!(builtin, both, "dynamic criterion + separation differ from the built-ins");
    let crit = fingerprint(&tension_scene(&rel, "type = \"example_rankine\"\ntensile_strength = 1.0", "type = \"sigma1_nearest\""), dir);
    assert_eq!(builtin, crit, "dynamic criterion differs from the built-in");
}

/// The resolved scene names the dynamic plugin as written and reads back (typetag's hidden
/// name method is implemented by hand in core/src/dynload/wrap.rs).
#[test]
fn resolved_scene_round_trips() {
    let text = tension_scene(&load_line(&libs().example), "type = \"example_rankine\"\ntensile_strength = 2.5", "type = \"example_sigma1_nearest\"");
    let s = scene_in(&text, &root()).unwrap();
    let resolved = s.resolved_toml();
    assert!(resolved.contains("type = \"example_rankine\"") && resolved.contains("tensile_strength = 2.5") && resolved.contains("type = \"example_sigma1_nearest\""), "{resolved}");
    let again = scene_in(&resolved, &root()).unwrap();
    assert_eq!(again.resolved_toml(), resolved);
}

/// Loading a library lists its plugins with the file they came from; loading it again is a
/// no-op (libraries are never unloaded or reloaded).
#[test]
fn loaded_plugins_name_their_file() {
    let lib = &libs().example;
    let a = dynload::load_library(lib).unwrap();
    let b = dynload::load_library(lib).unwrap();
    assert_eq!(a, b);
    let names: Vec<_> = a.iter().map(|p| (p.kind, p.name)).collect();
    assert_eq!(
        names,
        [
            ("criterion", "example_rankine"),
            ("separation", "example_sigma1_nearest"),
            ("criterion", "example_panic"),
            ("contact law", "example_spring_dashpot"),
            ("damping", "example_adaptive"),
            ("material law", "example_mohr_coulomb"),
            ("material law", "example_nan_law")
        ]
    );
    assert!(a.iter().all(|p| p.file == lib.canonicalize().unwrap() && p.core_version == abi::CORE_VERSION));
}

fn scene_err(text: &str) -> String {
    scene_in(text, &root()).map(|_| ()).unwrap_err().to_string()
}

/// A library built for another FLEM core version is refused before anything past its header
/// is read (its body is deliberately invalid), naming both versions.
#[test]
fn version_mismatch_is_refused() {
    let lib = &libs().stale;
    let e = scene_err(&tension_scene(&load_line(lib), "type = \"rankine\"\ntensile_strength = 1.0", "type = \"sigma1_nearest\""));
    assert!(e.contains("plugins.load[0]") && e.contains("version mismatch") && e.contains("FLEM core 0.0.1-old") && e.contains(&format!("FLEM core {}", abi::CORE_VERSION)), "{e}");
}

/// A shared library without the entry point: the message names the symbol and carries the
/// system loader's own message (libloading's is only "dlsym failed").
#[test]
fn missing_symbol_is_reported() {
    let e = dynload::load_library(&libs().no_entry).unwrap_err().to_string();
    assert!(e.contains("no entry point `flem_plugin_entry_v1`") && e.contains("dlsym failed: ") && e.contains("undefined symbol"), "{e}");
}

/// A missing file, given relative to the scene folder: the key, the path and the loader's
/// message.
#[test]
fn missing_file_is_reported() {
    let e = scene_err(&tension_scene("[plugins]\nload = [\"no/such/libplugin.so\"]\n", "type = \"rankine\"\ntensile_strength = 1.0", "type = \"sigma1_nearest\""));
    let want = root().join("no/such/libplugin.so").display().to_string();
    assert!(e.contains("plugins.load[0] = \"no/such/libplugin.so\"") && e.contains(&want) && e.contains("dlopen failed: ") && e.contains("No such file"), "{e}");
}

/// Bad parameters are validated by the plugin and reported under the scene key, like a
/// built-in's; an unknown plugin name gets a "did you mean" among built-ins and loaded names.
#[test]
fn bad_parameters_and_names_are_reported() {
    let load = load_line(&libs().example);
    let sep = "type = \"sigma1_nearest\"";
    let e = scene_err(&tension_scene(&load, "type = \"example_rankine\"\ntensile_strength = -1.0", sep));
    assert!(e.contains("cracking.criterion.tensile_strength = -1 is incorrect; it must be in (0, inf) (plugin example_rankine from "), "{e}");
    let e = scene_err(&tension_scene(&load, "type = \"example_rankine\"\ntensile_strength = 1.0\ncohesion = 1.0", sep));
    assert!(e.contains("cracking.criterion.cohesion unknown field `cohesion`"), "{e}");
    let e = scene_err(&tension_scene(&load, "type = \"example_rankine\"", sep));
    assert!(e.contains("cracking.criterion.tensile_strength missing field `tensile_strength`"), "{e}");
    let e = scene_err(&tension_scene(&load, "type = \"example_panic\"\nwhen = \"later\"", sep));
    assert!(e.contains("cracking.criterion.when = \"later\" is incorrect"), "{e}");
    let e = scene_err(&tension_scene(&load, "type = \"example_rankin\"\ntensile_strength = 1.0", sep));
    assert!(e.contains("did you mean \"example_rankine\"") && e.contains("`rankine`"), "{e}");
}

/// A plugin that panics while being created, or in the failure check, gives an error (the SDK
/// catches the panic on the plugin side): the scene is refused, or the run stops with the
/// message. Both happen in this process, which goes on (no abort).
#[test]
fn panicking_plugin_gives_an_error() {
    let load = load_line(&libs().example);
    let e = scene_err(&tension_scene(&load, "type = \"example_panic\"\nwhen = \"create\"", "type = \"sigma1_nearest\""));
    assert!(e.contains("cracking.criterion the plugin panicked: example_panic: asked to panic in create"), "{e}");
    let mut sim = Simulation::new(scene_in(&tension_scene(&load, "type = \"example_panic\"\nwhen = \"check\"", "type = \"sigma1_nearest\""), &root()).unwrap()).unwrap();
    let e = sim.run(&mut Log::default()).unwrap_err().to_string();
    assert!(e.contains("criterion \"example_panic\" from ") && e.contains("panicked in check_batch: example_panic: asked to panic in check"), "{e}");
}

/// The command line: `flem plugins --load` lists the loaded plugins with their file, and a run
/// whose plugin panics exits with status 1 and the message (a normal exit, not a signal).
#[test]
fn cli_lists_loaded_plugins_and_survives_a_panic() {
    let lib = &libs().example;
    let out = Command::new(crate::common::flem_exe()).args(["plugins", "--load"]).arg(lib).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(text.contains("criterion    rankine") && text.lines().any(|l| l.contains("example_rankine") && l.contains(&lib.canonicalize().unwrap().display().to_string())), "{text}");
    let dir = std::env::temp_dir().join(format!("flem-dynplug-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("panic.toml");
    std::fs::write(&scene, tension_scene(&load_line(lib), "type = \"example_panic\"\nwhen = \"check\"", "type = \"sigma1_nearest\"")).unwrap();
    let out = Command::new(crate::common::flem_exe()).arg("run").arg(&scene).arg("--out").arg(dir.join("out")).arg("--quiet").arg("--allow-plugins").output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("error: criterion \"example_panic\"") && err.contains("asked to panic in check"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The code blocks of a markdown text (or of a `//!` doc) in the given language.
pub(crate) fn blocks(text: &str, lang: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur: Option<String> = None;
    for line in text.lines() {
        let l = line.trim_start().strip_prefix("//!").map(|l| l.strip_prefix(' ').unwrap_or(l)).unwrap_or(line);
        match (&mut cur, l.trim()) {
            (None, t) if t == format!("```{lang}") => cur = Some(String::new()),
            (Some(_), "```") => out.extend(cur.take()),
            (Some(s), _) => {
                s.push_str(l);
                s.push('\n');
            }
            _ => {}
        }
    }
    out
}

/// docs/plugins.md is tested by the example: its Rust blocks appear verbatim in
/// plugins/example/src/lib.rs, and every scene snippet (there and in the example's docs) loads
/// the library by the path it shows (resolved against the built library's folder) and
/// validates with the tension scene.
#[test]
fn docs_are_the_tested_example() {
    let doc = std::fs::read_to_string(root().join("docs/plugins.md")).unwrap();
    let src = std::fs::read_to_string(root().join("plugins/example/src/lib.rs")).unwrap();
    let all: String = ["lib.rs", "contact.rs", "damping.rs", "material.rs"].iter().map(|f| std::fs::read_to_string(root().join("plugins/example/src").join(f)).unwrap()).collect();
    let rust = blocks(&doc, "rust");
    assert!(rust.len() >= 2);
    for b in &rust {
        assert!(all.contains(b.as_str()), "docs/plugins.md shows code that plugins/example/src/ does not have:\n{b}");
    }
    let lib = &libs().example;
    let mut n = 0;
    for (file, text) in [("docs/plugins.md", &doc), ("plugins/example/src/lib.rs", &src)] {
        for b in blocks(text, "toml").into_iter().filter(|b| b.contains("[cracking.criterion]")) {
            let t: toml::Table = toml::from_str(&b).unwrap_or_else(|e| panic!("{file}: {e}\n{b}"));
            let shown = t["plugins"]["load"][0].as_str().unwrap();
            assert!(shown.ends_with(lib.file_name().unwrap().to_str().unwrap()), "{file}: {shown}");
            let c = &t["cracking"];
            let scene = tension_scene(&format!("[plugins]\nload = [{:?}]\n", lib.display().to_string()), &toml::to_string(&c["criterion"]).unwrap(), &toml::to_string(&c["separation"]).unwrap());
            scene_in(&scene, &root()).unwrap_or_else(|e| panic!("{file}: {e}"));
            n += 1;
        }
    }
    assert_eq!(n, 2, "one scene snippet in each file");
}

/// The shipped plugin scene (configs/plugins/example_rankine.toml, issue 23): a library named
/// by a scene loads only with the user's consent. Without `--allow-plugins` the run is refused
/// naming the key, the library and the flag, and `flem check` validates the rest of the scene
/// without loading it; with the flag, or with the library's folder in FLEM_PLUGIN_PATH, it runs
/// and cracks (the tension crack splits above sigma_t).
#[test]
fn scene_plugins_load_only_with_consent() {
    let lib = &libs().example;
    let scene = root().join("configs/plugins/example_rankine.toml");
    let named = std::fs::read_to_string(&scene).unwrap();
    // The scene names target/release's library; the tests may build into another target folder,
    // so a copy names the library they built (by its absolute path).
    let text = named.replace("\"../../target/release/libflem_plugin_example.so\"", &format!("{:?}", lib.display().to_string()));
    assert_ne!(text, named, "the shipped scene no longer names ../../target/release/libflem_plugin_example.so");
    let dir = std::env::temp_dir().join(format!("flem-consent-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let sc = dir.join("example_rankine.toml");
    std::fs::write(&sc, &text).unwrap();
    let flem = |args: &[&str], env: Option<(&str, &Path)>| {
        let mut c = Command::new(crate::common::flem_exe());
        c.args(args).env_remove("FLEM_PLUGIN_PATH").env("XDG_CONFIG_HOME", dir.join("no-config"));
        if let Some((k, v)) = env {
            c.env(k, v);
        }
        c.output().unwrap()
    };
    let s = sc.to_str().unwrap();
    let out_dir = dir.join("out");
    let o = dir.join("out").display().to_string();
    let refused = flem(&["run", s, "--quiet", "--out", &o], None);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(1), "{err}");
    assert!(err.contains("plugins.load[0]") && err.contains("libflem_plugin_example") && err.contains("--allow-plugins") && err.contains("Nothing was loaded"), "{err}");
    assert!(!out_dir.join("summary.json").exists(), "a refused run wrote results");
    let checked = flem(&["check", s], None);
    let (cout, cerr) = (String::from_utf8_lossy(&checked.stdout), String::from_utf8_lossy(&checked.stderr));
    assert!(checked.status.success() && cout.contains(&format!("{s}: ok")), "{cout}{cerr}");
    assert!(cerr.contains("was not loaded") && cerr.contains("\"example_rankine\" is not built in"), "{cerr}");
    for (args, env) in [(vec!["run", s, "--quiet", "--out", &o, "--allow-plugins"], None), (vec!["run", s, "--quiet", "--out", &o], Some(("FLEM_PLUGIN_PATH", lib.parent().unwrap())))] {
        let ran = flem(&args, env);
        assert!(ran.status.success(), "{args:?} {env:?}: {}", String::from_utf8_lossy(&ran.stderr));
        let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap()).unwrap();
        let splits: u64 = summary["stages"].as_array().unwrap().iter().map(|st| st["splits"].as_u64().unwrap()).sum();
        assert!(splits > 0, "the tension crack did not split: {summary}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Issue 35 (loose end): a dynamic separation rule sees `FanView::never_split` (plugin ABI 3;
/// ABI 2 passed no such field and the plugin saw `false`). Reference: the built-in
/// `sigma1_nearest` with the paper's default (`cap_unsplit_boundary = false`: no pi/4 cap at a
/// point that never split) on the Drucker-Prager tension scene, whose first failures are open
/// fans of the bottom side at 90 deg from the crack plane (tests/cracking.rs: cut only without
/// the cap). The example's `example_sigma1_nearest`, loaded from its cdylib, gives the same run
/// bit for bit; with the field always `false` it capped those points and the runs differed.
#[test]
fn dynamic_separation_sees_never_split() {
    let lib = &libs().example;
    let dir = lib.parent().unwrap();
    let rel = format!("[plugins]\nload = [{:?}]\n", lib.file_name().unwrap().to_str().unwrap());
    let crit = "type = \"drucker_prager\"\nalpha = 0.1\nk = 0.6773502691896258";
    let builtin = fingerprint(&tension_scene("", crit, "type = \"sigma1_nearest\"\ncap_unsplit_boundary = false"), dir);
    let capped = fingerprint(&tension_scene("", crit, "type = \"sigma1_nearest\"\ncap_unsplit_boundary = true"), dir);
    assert!(!builtin.0.is_empty() && builtin != capped, "the scene does not exercise never_split: update the test");
    let dynamic = fingerprint(&tension_scene(&rel, crit, "type = \"example_sigma1_nearest\""), dir);
    assert_eq!(builtin, dynamic, "the dynamic rule differs from the built-in on never-split points");
}
