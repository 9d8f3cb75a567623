//! Every scene in configs/ validates and builds; every bad scene gives its expected message.
use std::path::Path;

use flem_core::scene::Scene;
use flem_core::solver::Simulation;

use crate::common::root;

fn toml_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    let Ok(rd) = std::fs::read_dir(dir) else { return };
    let mut entries: Vec<_> = rd.flatten().map(|e| e.path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            toml_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "toml") {
            out.push(p);
        }
    }
}

#[test]
fn every_config_scene_passes_check() {
    flem_plugins::link();
    let mut files = Vec::new();
    toml_files(&root().join("configs"), &mut files);
    assert!(!files.is_empty());
    for f in files {
        let scene = Scene::from_file(&f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        Simulation::new(scene).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
    }
}

/// Each file in tests/bad_scenes starts with `# expect: <text>`; loading it must fail with a
/// message containing that text (and the file name).
#[test]
fn bad_scenes_give_their_messages() {
    flem_plugins::link();
    let mut files = Vec::new();
    toml_files(&root().join("tests/bad_scenes"), &mut files);
    assert!(files.len() >= 5, "the bad-scene folder lost files");
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        let expect = text.lines().next().and_then(|l| l.strip_prefix("# expect: ")).unwrap_or_else(|| panic!("{}: first line must be '# expect: ...'", f.display()));
        let err = match Scene::from_file(&f) {
            Err(e) => e.to_string(),
            Ok(s) => match Simulation::new(s) {
                Err(e) => e.to_string(),
                Ok(_) => panic!("{}: expected an error containing {expect:?}, but the scene loaded", f.display()),
            },
        };
        assert!(err.contains(expect), "{}: message {err:?} does not contain {expect:?}", f.display());
        assert!(err.contains(f.file_name().unwrap().to_str().unwrap()), "{}: message {err:?} does not name the file", f.display());
    }
}

/// `flem check` exits 0 on a good scene and 1 with the message on a bad one; `flem plugins`
/// lists kinds and names.
#[test]
fn cli_check_and_plugins() {
    let exe = env!("CARGO_BIN_EXE_flem");
    let ok = std::process::Command::new(exe).arg("check").arg(root().join("configs/default.toml")).output().unwrap();
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let bad = std::process::Command::new(exe).arg("check").arg(root().join("tests/bad_scenes/unknown_key.toml")).output().unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown field"));
    let pl = std::process::Command::new(exe).arg("plugins").output().unwrap();
    let s = String::from_utf8_lossy(&pl.stdout);
    assert!(s.lines().any(|l| l.split_whitespace().collect::<Vec<_>>() == ["damping", "adaptive"]), "{s}");
}

/// Every registry entry really deserialises through typetag (the list and the registrations agree).
#[test]
fn registry_names_deserialise() {
    flem_plugins::link();
    for (kind, name) in flem_plugins::registry() {
        if kind == "damping" {
            let r: Result<Box<dyn flem_core::damping::Damping>, _> = toml::from_str(&format!("type = \"{name}\""));
            // A missing parameter is fine here; an unknown name is not.
            if let Err(e) = r {
                assert!(!e.to_string().contains("unknown variant"), "{kind} {name}: {e}");
            }
        }
    }
}
