//! Dynamic plugins: failure criteria, separation rules, contact laws, damping schemes and
//! material laws loaded at run time from a shared library (`[plugins] load =
//! ["path/to/libfoo.so"]`), then chosen by `type = "name"` exactly like a built-in. The ABI of
//! every kind, and where each keeps its state (core-owned arrays), is in [`abi`]'s docs; the
//! contact law's wrapper lives in `crate::contact::dynlaw` (its trait's layer), the material
//! law reaches `[[material]] law` through the hook `element::law::DYN_LAW` (set when a library
//! loads), for the same reason.
//!
//! Why not typetag: typetag's registry is filled at link time and cannot see impls inside a
//! library opened with `dlopen` (typetag issue #94; the library has its own registry). So the
//! library describes itself through a plain C ABI ([`abi`]), the host keeps a registry of what
//! it loaded ([`load_library`]), and the scene's plugin tables are read first as TOML values and
//! handed to the dynamic registry when their name is not a built-in ([`de_criterion`]).
//!
//! Rules the loader keeps:
//! - the header (ABI version, FLEM core version) is checked before anything else of the library
//!   is read; a mismatch is refused with a message naming both versions;
//! - a missing file or entry symbol is reported with the system loader's own message (the
//!   `source()` chain of libloading's error, whose own text is only "dlopen failed");
//! - a library is never unloaded (it is leaked into a global registry: function pointers and
//!   names from it live as long as the process);
//! - a plugin name may not shadow a built-in or a name from another loaded library;
//! - plugin errors and panics come back as `Err` (the SDK catches panics on its side).
//!
//! How a scene gets there: `Scene::from_str` first loads the `[plugins] load` libraries
//! (libloading), then deserializes the scene; the criterion and separation tables go through
//! `de_criterion`/`de_separation`, which read them as TOML values and build a `DynCriterion` /
//! `DynSeparation` when `type` names a loaded plugin, else hand them to typetag. The library's
//! one C entry point, `flem_plugin_entry_v1`, returns a `#[repr(C)]` descriptor (`abi.rs`)
//! whose frozen header (ABI version, FLEM core version, compiler) is checked first; only C
//! types cross, parameters go as JSON text, errors come back in a host buffer. A 64-bit ELF
//! whose headers or loadable segments reach past the end of the file (truncated) is refused by
//! name before dlopen, which would map it and die of SIGBUS. The failure check calls a dynamic
//! criterion once per 256 points (`try_check_batch`, which also carries a plugin's error or
//! panic up as a `FlemError`). Writing a plugin: docs/plugins.md, `plugins/sdk`,
//! `plugins/example`.
pub mod abi;
mod wrap;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

use serde::de::Error as _;
use serde::{Deserialize, Deserializer};

use crate::element::law::LawCfg;
use crate::error::{FlemError, Result};
use crate::plugin::damping::Damping;
use crate::plugin::traits::{FailureCriterion, SeparationRule};
use abi::{Descriptor, PluginEntry, ABI_VERSION, CONTACT_STATE_MAX, CORE_VERSION, ENTRY_SYMBOL, KIND_CONTACT, KIND_CRITERION, KIND_DAMPING, KIND_MATERIAL, KIND_SEPARATION, RUSTC_VERSION};
pub(crate) use wrap::{call_fault, err_slot, instance_methods, read_err, Instance, CHUNK};
pub use wrap::{DynCriterion, DynDamping, DynLaw, DynLawBlocks, DynLawCfg, DynSeparation};

/// A plugin provided by a loaded library.
#[derive(Clone, Debug, PartialEq)]
pub struct PluginInfo {
    /// "criterion", "separation", "contact law", "damping" or "material law".
    pub kind: &'static str,
    pub name: &'static str,
    /// The library it came from (canonical path).
    pub file: PathBuf,
    /// The FLEM core and compiler versions the library was built with.
    pub core_version: String,
    pub rustc_version: String,
}

struct Registered {
    info: PluginInfo,
    entry: &'static PluginEntry,
}

/// Every library loaded so far and its plugins, in load order. Never shrinks.
static REGISTRY: Mutex<Vec<Registered>> = Mutex::new(Vec::new());
/// Canonical paths of the loaded libraries.
static LIBRARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn kind_name(kind: u32) -> Option<&'static str> {
    match kind {
        KIND_CRITERION => Some("criterion"),
        KIND_SEPARATION => Some("separation"),
        KIND_CONTACT => Some("contact law"),
        KIND_DAMPING => Some("damping"),
        KIND_MATERIAL => Some("material law"),
        _ => None,
    }
}

/// `e` and every `source()` below it, joined by ": " (libloading's own text is only
/// "dlopen failed"; the system's message is its source).
pub fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cur = e.source();
    while let Some(c) = cur {
        s.push_str(": ");
        s.push_str(&c.to_string());
        cur = c.source();
    }
    s
}

/// Checks a descriptor's header against this host. Reads only the frozen header fields.
pub fn check_header(d: &Descriptor, file: &str) -> Result<(String, String)> {
    let err = |m: String| FlemError::Plugin { file: file.to_string(), msg: m };
    // SAFETY: header strings are statics of the library, which is never unloaded.
    let core = unsafe { d.core_version.as_str() }.map_err(|e| err(format!("its core version string is not UTF-8 ({e})")))?.to_string();
    let rustc = unsafe { d.rustc_version.as_str() }.map_err(|e| err(format!("its compiler version string is not UTF-8 ({e})")))?.to_string();
    if d.abi_version != ABI_VERSION || core != CORE_VERSION {
        return Err(err(format!(
            "version mismatch: the library was built for plugin ABI {} and FLEM core {core} ({rustc}), but this flem has plugin ABI {ABI_VERSION} and FLEM core {CORE_VERSION} ({RUSTC_VERSION}); rebuild the plugin against flem-plugin-sdk {CORE_VERSION}",
            d.abi_version
        )));
    }
    Ok((core, rustc))
}

/// Whether a typetag built-in of this kind has this name.
pub fn is_builtin(kind: u32, name: &str) -> bool {
    match kind {
        KIND_CRITERION => registry_has::<dyn FailureCriterion>(name),
        // Contact laws live in a layer above this one (`crate::contact::dynlaw::is_builtin`,
        // which `[contact] law` consults when it meets a loaded name).
        KIND_CONTACT => false,
        KIND_DAMPING => registry_has::<dyn Damping>(name),
        KIND_MATERIAL => registry_has::<dyn LawCfg>(name),
        _ => registry_has::<dyn SeparationRule>(name),
    }
}

/// Whether typetag's registry of `T` has an entry of this name (the registry is only
/// reachable through deserialization: an unknown name gives "unknown variant").
pub fn registry_has<T: ?Sized>(name: &str) -> bool
where
    Box<T>: serde::de::DeserializeOwned,
{
    let mut t = toml::Table::new();
    t.insert("type".into(), toml::Value::String(name.into()));
    !Box::<T>::deserialize(toml::Value::Table(t)).err().is_some_and(|e| e.to_string().contains("unknown variant"))
}

/// Refuses a 64-bit little-endian ELF file whose headers or loadable segments reach past its
/// end (a truncated or partly copied library): glibc's dlopen maps such a file and the
/// process dies of SIGBUS on the first touch of the missing pages, with no message (found by
/// tests/fuzz.rs). Anything else is left to dlopen, which reports it.
fn elf_extents(path: &Path) -> std::result::Result<(), String> {
    let Ok(b) = std::fs::read(path) else { return Ok(()) };
    if b.len() < 4 || &b[..4] != b"\x7fELF" {
        return Ok(());
    }
    let trunc = |what: &str, end: u64| format!("is cut short: its {what} ends at byte {end} but the file has {} bytes (a truncated or partly copied library?)", b.len());
    if b.len() < 64 {
        return Err(trunc("ELF header", 64));
    }
    if b[4] != 2 || b[5] != 1 {
        return Ok(()); // not ELF64 little-endian: dlopen decides
    }
    let u64_at = |o: usize| b.get(o..o + 8).map(|x| u64::from_le_bytes(x.try_into().unwrap()));
    let u16_at = |o: usize| u16::from_le_bytes([b[o], b[o + 1]]) as u64;
    let len = b.len() as u64;
    let (phoff, shoff) = (u64_at(0x20).unwrap_or(0), u64_at(0x28).unwrap_or(0));
    let (phent, phnum, shent, shnum) = (u16_at(0x36), u16_at(0x38), u16_at(0x3A), u16_at(0x3C));
    let ph_end = phoff.saturating_add(phent.saturating_mul(phnum));
    if ph_end > len {
        return Err(trunc("program header table", ph_end));
    }
    for k in 0..phnum {
        let h = (phoff + k * phent) as usize;
        let p_type = b.get(h..h + 4).map_or(0, |x| u32::from_le_bytes(x.try_into().unwrap()));
        let (off, filesz) = (u64_at(h + 8).unwrap_or(0), u64_at(h + 32).unwrap_or(0));
        if p_type == 1 && off.saturating_add(filesz) > len {
            return Err(trunc(&format!("loadable segment {k}"), off.saturating_add(filesz)));
        }
    }
    let sh_end = shoff.saturating_add(shent.saturating_mul(shnum));
    if shoff != 0 && sh_end > len {
        return Err(trunc("section header table", sh_end));
    }
    Ok(())
}

/// Loads a plugin library (an explicit path: a bare name would search system folders) and
/// registers its plugins. Loading the same file again returns its plugins without reloading.
pub fn load_library(path: &Path) -> Result<Vec<PluginInfo>> {
    // One load at a time: two threads loading the same file would both pass the "already
    // loaded" check and the second would find its names taken.
    static LOADING: Mutex<()> = Mutex::new(());
    let _one = LOADING.lock().unwrap_or_else(|p| p.into_inner());
    let shown = path.display().to_string();
    let perr = |m: String| FlemError::Plugin { file: shown.clone(), msg: m };
    if let Ok(c) = path.canonicalize() {
        if LIBRARIES.lock().unwrap_or_else(|p| p.into_inner()).contains(&c) {
            return Ok(loaded().into_iter().filter(|p| p.file == c).collect());
        }
    }
    elf_extents(path).map_err(perr)?;
    // SAFETY: loading a library runs its initialisers; FLEM plugins are trusted code chosen by
    // the user, like the scene itself.
    let lib = unsafe { libloading::Library::new(path) }.map_err(|e| perr(format!("cannot be loaded: {}", error_chain(&e))))?;
    let file = path.canonicalize().unwrap_or_else(|_| path.to_path_buf());
    // Never unloaded: every pointer taken from it below lives as long as the process.
    let lib: &'static libloading::Library = Box::leak(Box::new(lib));
    type Entry = unsafe extern "C" fn() -> *const Descriptor;
    // SAFETY: the symbol's type is fixed by the ABI (checked by the header right after).
    let entry = unsafe { lib.get::<Entry>(ENTRY_SYMBOL) }.map_err(|e| {
        perr(format!(
            "is not a FLEM plugin for plugin ABI {ABI_VERSION}: it has no entry point `{ENTRY_SYMBOL}` (build it with flem-plugin-sdk {CORE_VERSION} and its export_plugins! macro): {}",
            error_chain(&e)
        ))
    })?;
    // SAFETY: the entry point of the SDK returns a pointer to a static descriptor.
    let d = unsafe { entry() };
    if d.is_null() {
        return Err(perr(format!("`{ENTRY_SYMBOL}` returned a null descriptor")));
    }
    // SAFETY: non-null, static in the never-unloaded library.
    let d: &'static Descriptor = unsafe { &*d };
    let (core, rustc) = check_header(d, &shown)?;
    let entries: &'static [PluginEntry] = if d.n_plugins == 0 {
        &[]
    } else {
        // SAFETY: the header matched, so the body has the ABI 1 layout: n_plugins entries.
        unsafe { std::slice::from_raw_parts(d.plugins, d.n_plugins) }
    };
    let mut new = Vec::new();
    for e in entries {
        let kind = kind_name(e.kind).ok_or_else(|| perr(format!("provides a plugin of unknown kind {} (this flem knows criterion, separation, contact law, damping and material law)", e.kind)))?;
        // SAFETY: a static of the library.
        let name: &'static str = unsafe { e.name.as_str() }.map_err(|_| perr("has a plugin name that is not UTF-8".into()))?;
        let missing = e.missing();
        if !missing.is_empty() {
            return Err(perr(format!("{kind} \"{name}\" lacks the function(s) {} that a {kind} must provide (nothing of the library was used)", missing.join(", "))));
        }
        if e.kind == KIND_CONTACT && e.n_state > CONTACT_STATE_MAX {
            return Err(perr(format!("{kind} \"{name}\" declares {} f64 of history per pair; the core keeps at most {CONTACT_STATE_MAX} (PairState en, es, max_open)", e.n_state)));
        }
        if e.n_state > 1 << 16 {
            return Err(perr(format!("{kind} \"{name}\" declares {} f64 of state (at most 65536)", e.n_state)));
        }
        if is_builtin(e.kind, name) {
            return Err(perr(format!("{kind} \"{name}\" has the name of a built-in {kind}; rename it")));
        }
        if let Some(other) = find(e.kind, name) {
            return Err(perr(format!("{kind} \"{name}\" is already provided by {}", other.info.file.display())));
        }
        if new.iter().any(|r: &Registered| r.entry.kind == e.kind && r.info.name == name) {
            return Err(perr(format!("provides {kind} \"{name}\" twice")));
        }
        new.push(Registered { info: PluginInfo { kind, name, file: file.clone(), core_version: core.clone(), rustc_version: rustc.clone() }, entry: e });
    }
    let infos = new.iter().map(|r| r.info.clone()).collect();
    let _ = crate::element::law::DYN_LAW.set(law_from_table);
    REGISTRY.lock().unwrap_or_else(|p| p.into_inner()).extend(new);
    LIBRARIES.lock().unwrap_or_else(|p| p.into_inner()).push(file);
    Ok(infos)
}

/// The loaded plugin of a kind with this name: its info and its entry.
pub(crate) fn find_entry(kind: u32, name: &str) -> Option<(PluginInfo, &'static PluginEntry)> {
    find(kind, name).map(|r| (r.info, r.entry))
}

fn find(kind: u32, name: &str) -> Option<Registered> {
    REGISTRY.lock().unwrap_or_else(|p| p.into_inner()).iter().find(|r| r.entry.kind == kind && r.info.name == name).map(|r| Registered { info: r.info.clone(), entry: r.entry })
}

/// Every plugin loaded so far, in load order.
pub fn loaded() -> Vec<PluginInfo> {
    REGISTRY.lock().unwrap_or_else(|p| p.into_inner()).iter().map(|r| r.info.clone()).collect()
}

/// Whether the user consented to loading the libraries that scenes name (`--allow-plugins`).
static CONSENT: AtomicBool = AtomicBool::new(false);

/// The environment variable listing folders (separated like `PATH`) whose libraries a scene
/// may load without `--allow-plugins`: folders the user set up for plugins they trust.
pub const PLUGIN_PATH_VAR: &str = "FLEM_PLUGIN_PATH";

/// Gives (or takes back) the user's consent to load the plugin libraries that scenes name
/// (`flem --allow-plugins`). Without it a scene's `[plugins] load` is refused before anything
/// is loaded, unless the library lies in a trusted folder ([`trusted_dirs`]).
pub fn set_scene_plugin_consent(on: bool) {
    CONSENT.store(on, Ordering::SeqCst);
}

/// Whether consent was given with [`set_scene_plugin_consent`].
pub fn scene_plugin_consent() -> bool {
    CONSENT.load(Ordering::SeqCst)
}

/// The folders whose libraries a scene may load without explicit consent: each folder of
/// `FLEM_PLUGIN_PATH`, and the user's own `$XDG_CONFIG_HOME/flem/plugins` (or
/// `~/.config/flem/plugins`). A folder is trusted because the user made it, as a macro
/// folder of an office suite is; a scene file alone never is.
pub fn trusted_dirs() -> Vec<PathBuf> {
    // Relative entries are ignored (as the XDG spec says of XDG_CONFIG_HOME): trust must not
    // depend on the folder flem is run from, e.g. inside a downloaded project.
    let mut v: Vec<PathBuf> = std::env::var_os(PLUGIN_PATH_VAR).map(|p| std::env::split_paths(&p).filter(|d| d.is_absolute()).collect()).unwrap_or_default();
    let config = std::env::var_os("XDG_CONFIG_HOME")
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| std::env::var_os("HOME").map(PathBuf::from).filter(|h| h.is_absolute()).map(|h| h.join(".config")));
    if let Some(c) = config {
        v.push(c.join("flem").join("plugins"));
    }
    v
}

/// Whether a library (an existing file) lies inside a trusted folder (both canonical, so that
/// `..` or a symbolic link cannot lead out of it).
fn in_trusted_dir(lib: &Path) -> bool {
    let Ok(lib) = lib.canonicalize() else { return false };
    trusted_dirs().iter().filter_map(|d| d.canonicalize().ok()).any(|d| lib.starts_with(d))
}

/// Whether a scene may load this library: the user consented, or it lies in a trusted folder.
pub fn may_load(lib: &Path) -> bool {
    scene_plugin_consent() || in_trusted_dir(lib)
}

/// The libraries of a scene's `[plugins] load` list: (key, path as written, path resolved
/// against `base_dir`). Text that is not TOML, or a list that is not one, gives none (the scene
/// parser names the error); an entry that is not a string is an error naming its key.
pub fn scene_plugin_paths(text: &str, file: &str, base_dir: &Path) -> Result<Vec<(String, String, PathBuf)>> {
    let Ok(doc) = toml::from_str::<toml::Table>(text) else { return Ok(Vec::new()) };
    let Some(list) = doc.get("plugins").and_then(|p| p.get("load")) else { return Ok(Vec::new()) };
    let Some(list) = list.as_array() else { return Ok(Vec::new()) };
    let mut out = Vec::new();
    for (i, item) in list.iter().enumerate() {
        let key = format!("plugins.load[{i}]");
        let Some(s) = item.as_str() else { return Err(FlemError::config(file, key, "must be a path (a string)")) };
        let p = Path::new(s);
        let mut full = if p.is_absolute() { p.to_path_buf() } else { base_dir.join(p) };
        if full.is_relative() && full.parent().is_none_or(|d| d.as_os_str().is_empty()) {
            full = Path::new(".").join(full); // never let the system search its folders
        }
        out.push((key, s.to_string(), full));
    }
    Ok(out)
}

/// Loads the libraries of a scene's `[plugins] load` list (paths relative to `base_dir`) before
/// the rest of the scene is deserialized. Each library needs the user's consent
/// ([`set_scene_plugin_consent`], or a trusted folder): without it the scene is refused before
/// any library is loaded, naming the library and the flag.
pub fn load_scene_plugins(text: &str, file: &str, base_dir: &Path) -> Result<()> {
    // Each library is checked and loaded by its canonical path, so that what was checked is what
    // is opened (a link swapped in between cannot lead elsewhere).
    let libs: Vec<(String, String, PathBuf)> = scene_plugin_paths(text, file, base_dir)?.into_iter().map(|(k, s, full)| (k, s, full.canonicalize().unwrap_or(full))).collect();
    {
        if let Some((key, s, full)) = libs.iter().find(|(_, _, full)| !may_load(full)) {
            return Err(FlemError::config(
                file,
                key.clone(),
                format!(
                    "= \"{s}\" names a native library ({}), which would run its code on this machine; a scene loads one only with your consent: give --allow-plugins to the flem command (or put the library in a folder listed in {PLUGIN_PATH_VAR}, or in ~/.config/flem/plugins). Nothing was loaded",
                    full.display()
                ),
            ));
        }
    }
    for (key, s, full) in libs {
        load_library(&full).map_err(|e| FlemError::config(file, key, format!("= \"{s}\": {e}")))?;
    }
    Ok(())
}

/// The names of loaded plugins of a kind, for messages.
fn names_of(kind: u32) -> Vec<&'static str> {
    REGISTRY.lock().unwrap_or_else(|p| p.into_inner()).iter().filter(|r| r.entry.kind == kind).map(|r| r.info.name).collect()
}

/// Adds the loaded names of this kind to typetag's "unknown variant `x`, expected one of ..."
/// so that the scene's "did you mean" hint considers them too.
pub(crate) fn with_loaded_names(msg: String, kind: u32) -> String {
    let names = names_of(kind);
    if names.is_empty() || !msg.contains("unknown variant") {
        return msg;
    }
    let extra: Vec<String> = names.iter().map(|n| format!("`{n}`")).collect();
    format!("{msg}, or a loaded plugin: {}", extra.join(", "))
}

fn type_name(v: &toml::Value) -> Option<&str> {
    v.get("type").and_then(|t| t.as_str())
}

/// `deserialize_with` for a scene's criterion table: a loaded plugin's name builds a
/// [`DynCriterion`], any other name goes to typetag (the built-ins).
pub fn de_criterion<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Box<dyn FailureCriterion>, D::Error> {
    let v = toml::Value::deserialize(d)?;
    if let Some(r) = type_name(&v).and_then(|n| find(KIND_CRITERION, n)) {
        return Ok(Box::new(DynCriterion::new(r.info, r.entry, v)));
    }
    Box::<dyn FailureCriterion>::deserialize(v).map_err(|e| D::Error::custom(with_loaded_names(e.to_string(), KIND_CRITERION)))
}

/// `deserialize_with` for a scene's separation table (see [`de_criterion`]).
pub fn de_separation<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Box<dyn SeparationRule>, D::Error> {
    let v = toml::Value::deserialize(d)?;
    if let Some(r) = type_name(&v).and_then(|n| find(KIND_SEPARATION, n)) {
        return Ok(Box::new(DynSeparation::new(r.info, r.entry, v)));
    }
    Box::<dyn SeparationRule>::deserialize(v).map_err(|e| D::Error::custom(with_loaded_names(e.to_string(), KIND_SEPARATION)))
}

/// `deserialize_with` for `[solver] damping` (see [`de_criterion`]).
pub fn de_damping<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Option<Box<dyn Damping>>, D::Error> {
    let v = toml::Value::deserialize(d)?;
    if let Some(r) = type_name(&v).and_then(|n| find(KIND_DAMPING, n)) {
        return Ok(Some(Box::new(DynDamping::new(r.info, r.entry, v))));
    }
    Box::<dyn Damping>::deserialize(v).map(Some).map_err(|e| D::Error::custom(with_loaded_names(e.to_string(), KIND_DAMPING)))
}

/// A `[[material]] law` table naming a loaded material law, as its configuration (`None`: no
/// loaded law has its `type`); `DynLawCfg::bind` gives a region's law (benchmarks, tests).
pub fn material_law(v: &toml::Value) -> Option<DynLawCfg> {
    let r = type_name(v).and_then(|n| find(KIND_MATERIAL, n))?;
    Some(DynLawCfg::new(r.info, r.entry, v.clone()))
}

/// The hook of `element::law::de_law`: a `[[material]] law` table naming a loaded material law.
fn law_from_table(v: &toml::Value) -> Option<Box<dyn LawCfg>> {
    let r = type_name(v).and_then(|n| find(KIND_MATERIAL, n))?;
    Some(Box::new(DynLawCfg::new(r.info, r.entry, v.clone())))
}

#[cfg(test)]
mod tests {
    use super::abi::RStr;
    use super::*;

    fn desc(abi: u32, core: &'static str) -> Descriptor {
        Descriptor { abi_version: abi, core_version: RStr::new(core), rustc_version: RStr::new("rustc 0.0.0 (test)"), n_plugins: 0, plugins: std::ptr::null() }
    }

    /// A descriptor of another ABI or core version is refused with both versions named; the
    /// matching one passes. Reference: the header rule of the module docs.
    #[test]
    fn header_mismatch_names_both_versions() {
        assert!(check_header(&desc(ABI_VERSION, CORE_VERSION), "x.so").is_ok());
        let e = check_header(&desc(ABI_VERSION + 1, CORE_VERSION), "x.so").unwrap_err().to_string();
        assert!(e.contains(&format!("plugin ABI {}", ABI_VERSION + 1)) && e.contains(&format!("plugin ABI {ABI_VERSION}")), "{e}");
        let e = check_header(&desc(ABI_VERSION, "0.0.1-old"), "x.so").unwrap_err().to_string();
        assert!(e.contains("FLEM core 0.0.1-old") && e.contains(&format!("FLEM core {CORE_VERSION}")) && e.starts_with("plugin library x.so"), "{e}");
    }

    /// A missing file reports the system loader's message (not only "dlopen failed").
    #[test]
    fn missing_file_reports_loader_message() {
        let e = load_library(Path::new("/nonexistent/libnope.so")).unwrap_err().to_string();
        assert!(e.contains("dlopen failed") && e.contains("/nonexistent/libnope.so") && e.contains("No such file"), "{e}");
    }
}
