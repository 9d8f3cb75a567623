//! Test support: the ```toml snippets in plugin docs are parsed by the tests, so the docs cannot
//! drift from the code. Public (hidden from the docs) so that the integration tests share
//! the parser.

/// Reads the ```toml blocks of a module's `//!` doc comment.
pub fn toml_blocks(src: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur: Option<String> = None;
    for line in src.lines() {
        let Some(doc) = line.trim_start().strip_prefix("//!") else { continue };
        let doc = doc.strip_prefix(' ').unwrap_or(doc);
        match (&mut cur, doc.trim()) {
            (None, "```toml") => cur = Some(String::new()),
            (Some(_), "```") => out.extend(cur.take()),
            (Some(s), _) => {
                s.push_str(doc);
                s.push('\n');
            }
            _ => {}
        }
    }
    out
}

/// Deserialises the table at `path` (e.g. `["cracking", "criterion"]`) of every ```toml block
/// of every source; panics naming the file on any failure, on a source without a block, or on
/// a name of `names` that no snippet shows. Returns (file, value) pairs for further checks.
#[cfg(test)]
pub(crate) fn doc_snippets<T: serde::de::DeserializeOwned>(sources: &[(&str, &str)], path: &[&str], names: &[&str]) -> Vec<(String, T)> {
    let mut seen = Vec::new();
    let mut out = Vec::new();
    for (file, src) in sources {
        let blocks = toml_blocks(src);
        assert!(!blocks.is_empty(), "{file} has no ```toml block");
        for b in blocks {
            let mut v: toml::Value = toml::from_str::<toml::Table>(&b).unwrap_or_else(|e| panic!("{file}: {e}\n{b}")).into();
            for key in path {
                v = v.get(*key).unwrap_or_else(|| panic!("{file}: snippet has no {path:?} table\n{b}")).clone();
            }
            seen.push(v.get("type").and_then(|t| t.as_str()).unwrap_or_default().to_string());
            out.push((file.to_string(), v.try_into().unwrap_or_else(|e| panic!("{file}: {e}\n{b}"))));
        }
    }
    for n in names {
        assert!(seen.iter().any(|s| s == n), "no doc snippet shows {n}");
    }
    out
}

/// The repository's configs/ folder, for the unit tests: found from the crate's manifest folder
/// upwards, because these modules are compiled from two manifests (plugins/Cargo.toml and the
/// unit-test harness tests/unit/plugins/Cargo.toml, two levels deeper).
#[cfg(test)]
pub(crate) fn configs_dir() -> std::path::PathBuf {
    let here = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    here.ancestors().map(|d| d.join("configs")).find(|c| c.is_dir()).unwrap_or_else(|| panic!("no configs/ folder above {}", here.display()))
}
