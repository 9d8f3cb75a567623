//! The map of core (ARCHITECTURE.md, issue 23): the folders of core/src depend on each other in
//! one direction only, `mesh -> element -> plugin -> contact -> scene -> cracking, loads ->
//! solver -> output` (`error` and `ids` under everything), and no two modules import each other
//! in a circle. Reference: the layering rule written in ARCHITECTURE.md; the graph is read from
//! the `crate::` paths of the sources' code lines (comments left out).
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use crate::common::root;

/// Module path (`solver::loads`, `element`) of each .rs file under core/src, with its text.
fn modules() -> BTreeMap<String, String> {
    fn walk(dir: &Path, base: &Path, out: &mut BTreeMap<String, String>) {
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(&p, base, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                let rel = p.strip_prefix(base).unwrap().with_extension("");
                let mut parts: Vec<String> = rel.iter().map(|s| s.to_string_lossy().to_string()).collect();
                if parts.last().is_some_and(|l| l == "mod") {
                    parts.pop();
                }
                let code: String = std::fs::read_to_string(&p).unwrap().lines().filter(|l| !l.trim_start().starts_with("//")).collect::<Vec<_>>().join("\n");
                out.insert(parts.join("::"), code);
            }
        }
    }
    let mut m = BTreeMap::new();
    walk(&root().join("core/src"), &root().join("core/src"), &mut m);
    m
}

/// Edges module -> module it names with `crate::...` (the longest module prefix of the path).
fn graph(mods: &BTreeMap<String, String>) -> BTreeMap<String, BTreeSet<String>> {
    let mut g = BTreeMap::new();
    for (m, code) in mods {
        let mut deps = BTreeSet::new();
        for (i, _) in code.match_indices("crate::") {
            let path: String = code[i + 7..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == ':').collect();
            let parts: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
            if let Some(k) = (1..=parts.len()).rev().map(|k| parts[..k].join("::")).find(|c| mods.contains_key(c)) {
                if &k != m {
                    deps.insert(k);
                }
            }
        }
        g.insert(m.clone(), deps);
    }
    g
}

#[test]
fn core_modules_have_no_cycle_and_folders_keep_their_layers() {
    let mods = modules();
    let g = graph(&mods);
    assert!(g.len() > 20 && g.contains_key("solver") && g.contains_key("mesh::topology"), "core/src not read: {:?}", g.keys());
    // No cycle between modules: a depth-first search that meets a module on its own path.
    fn visit<'a>(v: &'a str, g: &'a BTreeMap<String, BTreeSet<String>>, state: &mut BTreeMap<&'a str, u8>, path: &mut Vec<&'a str>) {
        match state.get(v) {
            Some(2) => return,
            Some(1) => {
                let at = path.iter().position(|p| *p == v).unwrap();
                panic!("module cycle in core: {} -> {v}", path[at..].join(" -> "));
            }
            _ => {}
        }
        state.insert(v, 1);
        path.push(v);
        for w in &g[v] {
            visit(w, g, state, path);
        }
        path.pop();
        state.insert(v, 2);
    }
    let mut state = BTreeMap::new();
    for v in g.keys() {
        visit(v, &g, &mut state, &mut Vec::new());
    }
    // Folder layers: a folder may use only its own layer or those below.
    let layer = |m: &str| -> usize {
        match m.split("::").next().unwrap() {
            "error" | "ids" | "lib" | "expr" => 0,
            "mesh" => 1,
            "element" => 2,
            "plugin" => 3,
            "contact" => 4,
            "scene" | "scene3" => 5,
            "cracking" => 6,
            "solver" => 7,
            "output" => 8,
            other => panic!("core/src/{other} is in no layer of ARCHITECTURE.md: add it there and here"),
        }
    };
    let mut wrong = Vec::new();
    for (m, deps) in &g {
        for d in deps {
            if layer(d) > layer(m) {
                wrong.push(format!("{m} -> {d}"));
            }
        }
    }
    assert!(wrong.is_empty(), "imports against the layering of ARCHITECTURE.md: {wrong:?}");
}

/// The unit-test harnesses (tests/unit/core, tests/unit/plugins; CI time) compile core/src and
/// plugins/src from manifests of their own: they must build the same crate as the library's
/// manifest does, i.e. the same source file, build script, dependencies and features, while the
/// libraries themselves keep `test = false` (their unit tests would otherwise be compiled twice)
/// and the harnesses are the ones built at opt-level 0. Reference: the two manifests' tables.
#[test]
fn unit_test_harnesses_build_the_libraries_own_crates() {
    let read = |p: &str| -> toml::Table { toml::from_str(&std::fs::read_to_string(root().join(p)).unwrap()).unwrap_or_else(|e| panic!("{p}: {e}")) };
    let ws = read("Cargo.toml");
    for (lib_dir, unit_dir, unit_name) in [("core", "tests/unit/core", "flem-core-unit"), ("plugins", "tests/unit/plugins", "flem-plugins-unit")] {
        let lib = read(&format!("{lib_dir}/Cargo.toml"));
        let unit = read(&format!("{unit_dir}/Cargo.toml"));
        for table in ["dependencies", "dev-dependencies", "features"] {
            assert_eq!(lib.get(table), unit.get(table), "[{table}] of {lib_dir}/Cargo.toml and {unit_dir}/Cargo.toml differ");
        }
        assert_eq!(lib["lib"].get("test").and_then(toml::Value::as_bool), Some(false), "{lib_dir}/Cargo.toml: [lib] test = false");
        let src = root().join(unit_dir).join(unit["lib"]["path"].as_str().unwrap()).canonicalize().unwrap();
        assert_eq!(src, root().join(lib_dir).join("src/lib.rs").canonicalize().unwrap(), "{unit_dir}: [lib] path");
        let build = |t: &toml::Table, dir: &str| t["package"].get("build").and_then(toml::Value::as_str).map(|b| root().join(dir).join(b).canonicalize().unwrap());
        let lib_build = build(&lib, lib_dir).or_else(|| root().join(lib_dir).join("build.rs").canonicalize().ok());
        assert_eq!(build(&unit, unit_dir), lib_build, "{unit_dir}: build script");
        assert_eq!(ws["profile"]["release"]["package"][unit_name]["opt-level"].as_integer(), Some(0), "[profile.release.package.{unit_name}]");
        assert!(ws["workspace"]["members"].as_array().unwrap().iter().any(|m| m.as_str() == Some(unit_dir)), "{unit_dir} is a workspace member");
    }
}
