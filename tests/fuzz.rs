//! Mutation fuzzing of the scenes in configs/ and the meshes they use (bad-input contract).
//!
//! Every scene (configs/, configs/paper/, configs/bench/, configs/verification/) and every mesh
//! file of configs/ is mutated deterministically (seeded xorshift; no external fuzzer): a key
//! removed, a value replaced by a wrong type, 0, a negative number, NaN, +-inf or a huge
//! number, a table duplicated, an unknown key, a node/edge set name misspelt, a stage level
//! naming an unknown load, a load value replaced by expressions of x, y, t (bad ones: a division
//! by zero, a sign before a power, an unknown variable, overflow, a syntax error, a NaN, and a
//! load of t and a good one that must run); mesh files truncated at several offsets, a line garbled, an
//! element referring to a missing node, a degenerate or inverted element, a physical group
//! removed. Each mutant goes through the library as `flem check` and `flem run` use it
//! (`Scene::from_str`, `Simulation::new`, the stage loop with `[check]` comparisons when the
//! scene has them) with every stage capped at 300 steps (`STEP_CAP`), inside `catch_unwind`.
//!
//! The contract (reference: the brief's "bad input gets a clear error that names the file, the
//! key or the element ... no panic, no NaN written"), asserted for every mutant:
//! - no panic;
//! - a refused mutant's message names the scene file (config mutants) or the mesh file (mesh
//!   mutants), and the key, table, set or load concerned (config mutants);
//! - an accepted mutant's state is finite whenever the run hands it to an observer (history,
//!   snapshot, splits, stage end, checkpoint), i.e. nothing non-finite would be written; a run
//!   that fails says why (a divergence names the step and dt_crit).
//! Every 30th accepted mutant and every run that failed is also run through the real
//! `OutputWriter`: its CSV logs and JSON files hold no NaN/inf and no temp file is left.
//! Scenes and meshes with large models (mesh files over 50 kB, generated meshes over 2 000 cells)
//! are sampled (16 seeded mutants each) for run time.
//! `FLEM_FUZZ_VERBOSE=1` prints every verdict (the per-class counts are always printed);
//! `FLEM_FUZZ_CRACK=1` also forces frequent multi-split failure checks (about 2 min: a deeper
//! run, not part of the suite's budget).
//!
//! About 4100 mutants in all. What the library does so that they get a named refusal:
//! magnitudes (material constants, loads, levels x values, gravity, probe and mesh coordinates)
//! are bounded by 1e100 (`scene::MAX_MAGNITUDE`, `mesh::MAX_COORD`) so that overflow is refused
//! by key instead of surfacing as a divergence; a non-finite critical step is refused naming the
//! materials; errors of generated meshes name the scene file.
use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use flem_core::scene::Scene;
use flem_core::solver::{Observer, Simulation, StagePos};
use toml::{Table, Value};

use crate::common::root;

/// Steps per stage of an accepted mutant (a few steps are enough to reach the state checks).
const STEP_CAP: u64 = 300;
/// Mutants kept of a scene or mesh whose model is large (seeded sample): run-time budget.
const LARGE_SAMPLE: usize = 16;
/// Every this many accepted mutants, one is also run through the real output writer.
const WRITE_EVERY: usize = 30;
/// Meshes above this many bytes count as large.
const LARGE_MESH: usize = 50_000;
/// Generated meshes (`nx` x `ny` cells) above this many cells count as large: the plastic
/// footings (2 700 - 4 900 cells) took 79 s of the shards' 138 s of CPU unsampled (measured).
const LARGE_CELLS: i64 = 2_000;

/// xorshift64*: deterministic, seeded.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Class {
    KeyRemoved,
    WrongType,
    Zero,
    Negative,
    Nan,
    Inf,
    Huge,
    TableDuplicated,
    UnknownKey,
    SetMisspelt,
    UnknownLoad,
    MeshTruncated,
    MeshGarbled,
    MeshMissingNode,
    MeshDegenerate,
    MeshInverted,
    MeshGroupMissing,
    /// A load value replaced by an expression of x, y, t (bad ones and a good one).
    Expression,
}

struct Mutant {
    class: Class,
    /// What was changed (for messages).
    what: String,
    /// Scene text and the name it is loaded under (messages must name it).
    text: String,
    scene_name: String,
    base_dir: PathBuf,
    /// Words of which the error message must contain at least one (the key, table, set,
    /// load; for mesh mutants the element, group or line).
    names: Vec<String>,
    /// Mesh mutants: the mesh file's name (its errors must name it, or the scene).
    mesh_file: Option<String>,
    /// The model is large (not run through the writer: run time).
    large: bool,
}

#[derive(Debug)]
enum Verdict {
    Refused(String),
    Ran,
    RunFailed(String),
    Panicked(String),
}

// ------------------------------------------------------------------------------------------
// Running a mutant as `flem check` + `flem run` do
// ------------------------------------------------------------------------------------------

/// An observer that fails the run when the state it is handed is not finite (what the output
/// writer would write at that call).
#[derive(Default)]
struct FiniteGuard {
    bad: Option<String>,
}

impl FiniteGuard {
    fn look(&mut self, sim: &Simulation, at: &str) {
        if self.bad.is_some() {
            return;
        }
        let st = &sim.state;
        let fields: [(&str, &[[f64; 2]]); 5] = [("u", &st.u), ("v", &st.v), ("f_int", &st.f_int), ("f_ext", &st.f_ext), ("f_con", &st.f_con)];
        for (name, f) in fields {
            if let Some(i) = f.iter().position(|x| !x[0].is_finite() || !x[1].is_finite()) {
                self.bad = Some(format!("{at}: {name}[{i}] = {:?} at step {}", f[i], st.step));
                return;
            }
        }
        let l = &sim.ledger;
        let ledger = [l.external_work, l.kinetic, l.strain, l.damping, l.contact_work, l.contact_energy, l.contact_dissipated, st.time, sim.dt];
        if let Some(x) = ledger.iter().find(|x| !x.is_finite()) {
            self.bad = Some(format!("{at}: the ledger/time holds {x} at step {}", st.step));
        }
    }
}

impl Observer for FiniteGuard {
    fn history(&mut self, sim: &Simulation, _stage: usize) -> flem_core::Result<()> {
        self.look(sim, "history");
        Ok(())
    }
    fn snapshot(&mut self, sim: &Simulation, _stage: usize, _label: &str) -> flem_core::Result<()> {
        self.look(sim, "snapshot");
        Ok(())
    }
    fn splits(&mut self, sim: &Simulation, _rec: &flem_core::mesh::topology::SplitRecord, _ev: &[flem_core::cracking::SplitEvent]) -> flem_core::Result<()> {
        self.look(sim, "splits");
        Ok(())
    }
    fn stage_end(&mut self, sim: &Simulation, _stage: usize) -> flem_core::Result<()> {
        self.look(sim, "stage end");
        Ok(())
    }
    fn checkpoint(&mut self, sim: &Simulation, _pos: &StagePos) -> flem_core::Result<()> {
        self.look(sim, "checkpoint");
        Ok(())
    }
}

/// Runs an accepted mutant again through the real output writer into `dir` (as `flem run`:
/// summary.json also after an error) and checks what was written: no NaN/inf in the CSV logs
/// and JSON files, no temp file left (a half-written file). `Err` describes the breach.
fn check_written(m: &Mutant, scratch: &Path) -> Result<(), String> {
    let dir = scratch.join("out");
    let _ = std::fs::remove_dir_all(&dir);
    let r = catch_unwind(AssertUnwindSafe(|| -> Result<(), String> {
        let mut scene = Scene::from_str(&m.text, &scratch.join(&m.scene_name), &m.base_dir).map_err(|e| format!("reloading: {e}"))?;
        cap_steps(&mut scene);
        let mut sim = Simulation::new(scene).map_err(|e| format!("rebuilding: {e}"))?;
        let mut w = flem_core::output::OutputWriter::new(&dir, &sim).map_err(|e| e.to_string())?;
        let _ = if sim.scene.file.check.is_some() {
            let mut c = flem_core::output::compare::Comparer::new(&mut w, &dir).map_err(|e| e.to_string())?;
            sim.run(&mut c)
        } else {
            sim.run(&mut w)
        };
        w.write_summary(&sim, 0.0).map_err(|e| e.to_string())
    }));
    match r {
        Err(_) => return Err("PANIC while writing the results".into()),
        Ok(Err(e)) => return Err(format!("writing the results failed: {e}")),
        Ok(Ok(())) => {}
    }
    for f in std::fs::read_dir(&dir).map_err(|e| e.to_string())?.flatten() {
        let name = f.file_name().to_string_lossy().to_string();
        if name.contains(".tmp") {
            return Err(format!("a temp file was left: {name}"));
        }
        if name.ends_with(".csv") || name.ends_with(".json") {
            let text = std::fs::read_to_string(f.path()).map_err(|e| e.to_string())?;
            let bad = text
                .split(|c: char| c == ',' || c == ':' || c.is_whitespace() || c == '[' || c == ']')
                .map(|t| t.trim_matches('"'))
                .find(|t| ["nan", "inf", "-inf", "infinity", "-infinity"].contains(&t.to_ascii_lowercase().as_str()));
            if let Some(t) = bad {
                return Err(format!("{name} holds {t}"));
            }
        }
    }
    Ok(())
}

/// `flem run` with fewer steps: every stage capped.
fn cap_steps(scene: &mut Scene) {
    if std::env::var("FLEM_FUZZ_CRACK").is_ok() {
        if let Some(c) = scene.file.cracking.as_mut() {
            c.at_equilibrium = false;
            c.check_every = 3;
            c.max_splits_per_check = 6;
        }
    }
    let s = &mut scene.file.solver;
    s.max_steps = s.max_steps.min(STEP_CAP);
    // The events solver: a loose fragment's explicit march too.
    s.hand_over_max_steps = s.hand_over_max_steps.min(STEP_CAP);
    for st in &mut scene.file.stages {
        st.max_steps = Some(st.max_steps.unwrap_or(STEP_CAP).min(STEP_CAP));
    }
}

fn evaluate(m: &Mutant, scratch: &Path) -> Verdict {
    let r = catch_unwind(AssertUnwindSafe(|| {
        let path = scratch.join(&m.scene_name);
        let mut scene = match Scene::from_str(&m.text, &path, &m.base_dir) {
            Ok(s) => s,
            Err(e) => return Verdict::Refused(e.to_string()),
        };
        cap_steps(&mut scene);
        let mut sim = match Simulation::new(scene) {
            Ok(s) => s,
            Err(e) => return Verdict::Refused(e.to_string()),
        };
        let mut guard = FiniteGuard::default();
        let r = if sim.scene.file.check.is_some() {
            let mut c = match flem_core::output::compare::Comparer::new(&mut guard, &scratch.join("compare")) {
                Ok(c) => c,
                Err(e) => return Verdict::RunFailed(format!("(harness) {e}")),
            };
            sim.run(&mut c)
        } else {
            sim.run(&mut guard)
        };
        if let Some(b) = guard.bad {
            return Verdict::RunFailed(format!("NON-FINITE STATE HANDED TO THE WRITER: {b}"));
        }
        match r {
            Ok(()) => Verdict::Ran,
            Err(e) => Verdict::RunFailed(e.to_string()),
        }
    }));
    r.unwrap_or_else(|p| Verdict::Panicked(p.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| p.downcast_ref::<String>().cloned()).unwrap_or_else(|| "(no message)".into())))
}

/// The contract for one verdict; `Err` describes the breach.
fn judge(m: &Mutant, v: &Verdict) -> Result<(), String> {
    match v {
        Verdict::Panicked(p) => Err(format!("PANIC: {p}")),
        Verdict::Refused(msg) | Verdict::RunFailed(msg) => {
            if msg.trim().is_empty() {
                return Err("empty error message".into());
            }
            if msg.contains("NON-FINITE") {
                return Err(msg.clone());
            }
            if let Verdict::RunFailed(_) = v {
                // A run error must say why: a divergence names the step and dt_crit.
                if msg.contains("diverged") && !msg.contains("dt_crit") {
                    return Err(format!("divergence without dt_crit: {msg}"));
                }
                return Ok(());
            }
            let file_ok = msg.contains(&m.scene_name) || m.mesh_file.as_ref().is_some_and(|f| msg.contains(f.as_str()));
            if !file_ok {
                return Err(format!("the message names neither the scene nor the mesh file: {msg}"));
            }
            if !m.names.is_empty() && !m.names.iter().any(|n| msg.contains(n.as_str())) {
                return Err(format!("the message names none of {:?}: {msg}", m.names));
            }
            Ok(())
        }
        Verdict::Ran => Ok(()),
    }
}

// ------------------------------------------------------------------------------------------
// Scene mutations (on the TOML tree)
// ------------------------------------------------------------------------------------------

#[derive(Clone, Debug)]
enum Seg {
    Key(String),
    Idx(usize),
}

fn show(path: &[Seg]) -> String {
    let mut s = String::new();
    for p in path {
        match p {
            Seg::Key(k) => {
                if !s.is_empty() {
                    s.push('.');
                }
                s.push_str(k);
            }
            Seg::Idx(i) => s.push_str(&format!("[{i}]")),
        }
    }
    s
}

fn get_mut<'a>(root: &'a mut Table, path: &[Seg]) -> Option<&'a mut Value> {
    let (Seg::Key(k0), rest) = path.split_first()? else { return None };
    let mut v = root.get_mut(k0)?;
    for p in rest {
        v = match (p, v) {
            (Seg::Key(k), Value::Table(t)) => t.get_mut(k)?,
            (Seg::Idx(i), Value::Array(a)) => a.get_mut(*i)?,
            _ => return None,
        };
    }
    Some(v)
}

fn remove(root: &mut Table, path: &[Seg]) {
    let (last, parent) = path.split_last().unwrap();
    let holder = if parent.is_empty() { None } else { get_mut(root, parent) };
    match (last, holder) {
        (Seg::Key(k), None) => {
            root.remove(k);
        }
        (Seg::Key(k), Some(Value::Table(t))) => {
            t.remove(k);
        }
        (Seg::Idx(i), Some(Value::Array(a))) => {
            a.remove(*i);
        }
        _ => {}
    }
}

/// Every path to a value: (path, is a table/array-of-tables element).
fn paths(v: &Table) -> Vec<Vec<Seg>> {
    fn walk(v: &Value, path: &mut Vec<Seg>, out: &mut Vec<Vec<Seg>>) {
        out.push(path.clone());
        match v {
            Value::Table(t) => {
                for (k, x) in t {
                    path.push(Seg::Key(k.clone()));
                    walk(x, path, out);
                    path.pop();
                }
            }
            Value::Array(a) => {
                // Long arrays (23 stages): the first two and the last.
                let n = a.len();
                for i in (0..n).filter(|&i| i < 2 || i + 1 == n) {
                    path.push(Seg::Idx(i));
                    walk(&a[i], path, out);
                    path.pop();
                }
            }
            _ => {}
        }
    }
    let mut out = Vec::new();
    for (k, x) in v {
        walk(x, &mut vec![Seg::Key(k.clone())], &mut out);
    }
    out
}

/// The key words a message about `path` may name: its last key and the keys above it.
fn key_names(path: &[Seg]) -> Vec<String> {
    path.iter().filter_map(|p| if let Seg::Key(k) = p { Some(k.clone()) } else { None }).collect()
}

/// Keys whose string values name mesh groups.
const SET_KEYS: &[&str] = &["nodes", "edges", "region", "separated", "surfaces"];

fn scene_mutants(file: &Path, rng: &mut Rng) -> Vec<Mutant> {
    let text = std::fs::read_to_string(file).unwrap();
    let doc: Table = toml::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    let stem = file.file_stem().unwrap().to_string_lossy().to_string();
    let base_dir = file.parent().unwrap().to_path_buf();
    let mut out = Vec::new();
    let mut n = 0usize;
    let mut push = |class: Class, what: String, text: String, names: Vec<String>| {
        n += 1;
        out.push(Mutant { class, what, text, scene_name: format!("{stem}~{n}.toml"), base_dir: base_dir.clone(), names, mesh_file: None, large: false });
    };
    let ser = |t: &Table| toml::to_string(t).unwrap();
    for path in paths(&doc) {
        let names = key_names(&path);
        let shown = show(&path);
        let with = |v: Value| {
            let mut t = doc.clone();
            *get_mut(&mut t, &path).unwrap() = v;
            ser(&t)
        };
        // Removal.
        let mut t = doc.clone();
        remove(&mut t, &path);
        push(Class::KeyRemoved, format!("{shown} removed"), ser(&t), names.clone());
        let cur = get_mut(&mut doc.clone(), &path).unwrap().clone();
        let wrong = match &cur {
            Value::String(_) => Value::Integer(7),
            Value::Boolean(_) => Value::String("yes".into()),
            _ => Value::String("oops".into()),
        };
        push(Class::WrongType, format!("{shown} = {wrong}"), with(wrong.clone()), names.clone());
        let num = match cur {
            Value::Integer(i) => Some(i as f64),
            Value::Float(x) => Some(x),
            _ => None,
        };
        let is_int = matches!(cur, Value::Integer(_));
        if let Some(x) = num {
            let mk = |f: f64| if is_int && f.is_finite() && f.abs() < 9e18 { Value::Integer(f as i64) } else { Value::Float(f) };
            push(Class::Zero, format!("{shown} = 0"), with(mk(0.0)), names.clone());
            let neg = if x == 0.0 { -1.0 } else { -x.abs() };
            push(Class::Negative, format!("{shown} = {neg}"), with(mk(neg)), names.clone());
            push(Class::Nan, format!("{shown} = nan"), with(Value::Float(f64::NAN)), names.clone());
            let inf = if rng.next() % 2 == 0 { f64::INFINITY } else { f64::NEG_INFINITY };
            push(Class::Inf, format!("{shown} = {inf}"), with(Value::Float(inf)), names.clone());
            let huge = if is_int { Value::Integer(i64::MAX) } else { Value::Float(1e300) };
            push(Class::Huge, format!("{shown} = {}", if is_int { "i64::MAX" } else { "1e300" }), with(huge), names.clone());
        }
        // Load values as expressions (issue 23): every kind of bad expression is refused by key,
        // a good one runs; none may write a non-finite force.
        let in_load_value = names.iter().any(|n| n == "value") && path.iter().any(|p| matches!(p, Seg::Key(k) if k == "load"));
        if in_load_value && num.is_some() {
            for e in ["1 / (x - x)", "-x^2", "z * 2", "1e300 * 1e300 * (1 + y)", "x +* (", "sqrt(-1 - x^2)", "1e99 * (1 + t)", "0.5 * (1 + y)"] {
                push(Class::Expression, format!("{shown} = \"{e}\""), with(Value::String(e.into())), names.clone());
            }
        }
        if let (Value::String(s), Some(Seg::Key(k))) = (&cur, path.iter().rev().find(|p| matches!(p, Seg::Key(_)))) {
            if SET_KEYS.contains(&k.as_str()) && s != "all" {
                let bad = misspell(s, rng);
                push(Class::SetMisspelt, format!("{shown} = \"{bad}\""), with(Value::String(bad.clone())), vec![bad]);
            }
        }
        // An unknown key in every table (levels: an unknown load name).
        if let Value::Table(_) = cur {
            let mut t = doc.clone();
            let is_levels = matches!(path.last(), Some(Seg::Key(k)) if k == "levels");
            let (class, key) = if is_levels { (Class::UnknownLoad, "no_such_load".to_string()) } else { (Class::UnknownKey, "zz_unknown_key".to_string()) };
            if let Some(Value::Table(tt)) = get_mut(&mut t, &path) {
                tt.insert(key.clone(), Value::Integer(1));
            }
            push(class, format!("{shown}.{key} added"), ser(&t), vec![key]);
            if is_levels {
                // A level misspelling an existing load.
                if let Some(Value::Table(tt)) = get_mut(&mut doc.clone(), &path) {
                    if let Some((k, v)) = tt.iter().next() {
                        let bad = misspell(k, rng);
                        let mut t = doc.clone();
                        if let Some(Value::Table(tt)) = get_mut(&mut t, &path) {
                            tt.remove(k);
                            tt.insert(bad.clone(), v.clone());
                        }
                        push(Class::UnknownLoad, format!("{shown}.{k} renamed {bad}"), ser(&t), vec![bad]);
                    }
                }
            }
        }
    }
    let mut t = doc.clone();
    t.insert("zz_unknown_key".into(), Value::Integer(1));
    push(Class::UnknownKey, "top-level zz_unknown_key added".into(), ser(&t), vec!["zz_unknown_key".into()]);
    // A stage naming an unknown load when none was named.
    if let Some(Value::Array(st)) = doc.get("stage") {
        if !st.is_empty() {
            let mut t = doc.clone();
            if let Some(Value::Table(s0)) = get_mut(&mut t, &[Seg::Key("stage".into()), Seg::Idx(0)]) {
                s0.insert("levels".into(), Value::Table(Table::from_iter([("no_such_load".to_string(), Value::Float(1.0))])));
            }
            push(Class::UnknownLoad, "stage[0].levels = { no_such_load = 1 }".into(), ser(&t), vec!["no_such_load".into()]);
        }
    }
    // Textual: each [table] header's block appended again (a duplicated table).
    let lines: Vec<&str> = text.lines().collect();
    for (i, l) in lines.iter().enumerate() {
        let h = l.trim();
        if h.starts_with('[') && !h.starts_with("[[") {
            let end = (i + 1..lines.len()).find(|&j| lines[j].trim_start().starts_with('[')).unwrap_or(lines.len());
            let name = h.trim_start_matches('[').split(']').next().unwrap_or("").trim().to_string();
            let dup = format!("{text}\n{}\n", lines[i..end].join("\n"));
            push(Class::TableDuplicated, format!("[{name}] duplicated"), dup, vec![name.rsplit('.').next().unwrap().to_string()]);
        }
    }
    out
}

/// A name one edit away (a swapped pair of letters or a letter added).
fn misspell(s: &str, rng: &mut Rng) -> String {
    let c: Vec<char> = s.chars().collect();
    if c.len() >= 2 && rng.next() % 2 == 0 {
        let i = rng.below(c.len() - 1);
        if c[i] != c[i + 1] {
            let mut d = c.clone();
            d.swap(i, i + 1);
            return d.into_iter().collect();
        }
    }
    format!("{s}x")
}

// ------------------------------------------------------------------------------------------
// Mesh mutations (on the file's bytes)
// ------------------------------------------------------------------------------------------

#[derive(Copy, Clone, PartialEq, Debug)]
enum Fmt {
    Msh2,
    Msh4,
    MshBin,
    VtkLegacy,
    VtuAscii,
    VtuBin,
}

fn format_of(name: &str, bytes: &[u8]) -> Fmt {
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(400)]).to_string();
    if name.ends_with(".msh") {
        let v = head.lines().nth(1).unwrap_or("");
        if v.split_whitespace().nth(1) == Some("1") {
            Fmt::MshBin
        } else if v.starts_with("4") {
            Fmt::Msh4
        } else {
            Fmt::Msh2
        }
    } else if name.ends_with(".vtk") {
        Fmt::VtkLegacy
    } else if head.contains("format=\"ascii\"") {
        Fmt::VtuAscii
    } else {
        Fmt::VtuBin
    }
}

/// Byte ranges of the whitespace-separated tokens of `text` in `[from, to)`.
fn tokens(text: &str, from: usize, to: usize) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = from;
    while i < to {
        while i < to && b[i].is_ascii_whitespace() {
            i += 1;
        }
        let s = i;
        while i < to && !b[i].is_ascii_whitespace() {
            i += 1;
        }
        if i > s {
            out.push((s, i));
        }
    }
    out
}

/// The byte ranges of the node tokens of one 2D element (`pick`-th found), per format.
fn element_nodes(fmt: Fmt, text: &str, pick: usize) -> Option<Vec<(usize, usize)>> {
    let tok = |r: &(usize, usize)| &text[r.0..r.1];
    let section = |start: &str, end: &str| -> Option<(usize, usize)> {
        let a = text.find(start)? + start.len();
        let b = a + text[a..].find(end)?;
        Some((a, b))
    };
    let mut found = Vec::new();
    match fmt {
        Fmt::Msh2 => {
            let (a, b) = section("$Elements", "$EndElements")?;
            let mut pos = a;
            for line in text[a..b].split_inclusive('\n') {
                let t = tokens(text, pos, pos + line.len());
                pos += line.len();
                if t.len() >= 5 {
                    let ty = tok(&t[1]);
                    let nt: usize = tok(&t[2]).parse().ok()?;
                    if ty == "2" || ty == "3" {
                        found.push(t[3 + nt..].to_vec());
                    }
                }
            }
        }
        Fmt::Msh4 => {
            let (a, b) = section("$Elements", "$EndElements")?;
            let t = tokens(text, a, b);
            let mut k = 4;
            while k + 4 <= t.len() {
                let ty = tok(&t[k + 2]).to_string();
                let n: usize = tok(&t[k + 3]).parse().ok()?;
                let per = match ty.as_str() {
                    "1" => 2,
                    "2" => 3,
                    "3" => 4,
                    "15" => 1,
                    _ => return None,
                };
                k += 4;
                for e in 0..n {
                    let s = k + e * (per + 1);
                    if per >= 3 && s + per < t.len() + 1 {
                        found.push(t[s + 1..s + 1 + per].to_vec());
                    }
                }
                k += n * (per + 1);
            }
        }
        Fmt::VtkLegacy => {
            let a = text.find("CELLS")?;
            let a = a + text[a..].find('\n')?;
            let b = text.find("CELL_TYPES")?;
            let t = tokens(text, a, b);
            let mut k = 0;
            while k < t.len() {
                let n: usize = tok(&t[k]).parse().ok()?;
                if n >= 3 {
                    found.push(t[k + 1..(k + 1 + n).min(t.len())].to_vec());
                }
                k += n + 1;
            }
        }
        Fmt::VtuAscii => {
            let c = text.find("Name=\"connectivity\"")?;
            let c = c + text[c..].find('>')? + 1;
            let ce = c + text[c..].find('<')?;
            let o = text.find("Name=\"offsets\"")?;
            let o = o + text[o..].find('>')? + 1;
            let oe = o + text[o..].find('<')?;
            let conn = tokens(text, c, ce);
            let mut prev = 0usize;
            for r in tokens(text, o, oe) {
                let end: usize = tok(&r).parse().ok()?;
                if end - prev >= 3 && end <= conn.len() {
                    found.push(conn[prev..end].to_vec());
                }
                prev = end;
            }
        }
        Fmt::MshBin | Fmt::VtuBin => return None,
    }
    if found.is_empty() {
        return None;
    }
    let i = pick % found.len();
    Some(found.swap_remove(i))
}

fn splice(text: &str, edits: &mut [((usize, usize), String)]) -> String {
    edits.sort_by_key(|e| std::cmp::Reverse(e.0 .0));
    let mut s = text.to_string();
    for ((a, b), r) in edits.iter() {
        s.replace_range(*a..*b, r);
    }
    s
}

/// (class, what, bytes) mutants of one mesh file.
fn mesh_mutants(name: &str, bytes: &[u8], rng: &mut Rng) -> Vec<(Class, String, Vec<u8>)> {
    let fmt = format_of(name, bytes);
    let mut out = Vec::new();
    let n = bytes.len();
    let mut cuts: Vec<usize> = (1..8).map(|k| n * k / 8).collect();
    cuts.extend([0, 1, 17, n.saturating_sub(1), n.saturating_sub(2), 1 + rng.below(n - 1)]);
    cuts.sort_unstable();
    cuts.dedup();
    for c in cuts {
        out.push((Class::MeshTruncated, format!("truncated at byte {c} of {n}"), bytes[..c].to_vec()));
    }
    // Garbled: a line replaced by junk (text) or a run of bytes overwritten (binary).
    let text = std::str::from_utf8(bytes).ok().filter(|_| !matches!(fmt, Fmt::MshBin | Fmt::VtuBin));
    match text {
        Some(t) => {
            let starts: Vec<usize> = std::iter::once(0).chain(t.match_indices('\n').map(|(i, _)| i + 1)).filter(|&i| i < n).collect();
            let mut picks: Vec<usize> = (0..6).map(|_| rng.below(starts.len())).collect();
            picks.extend([1, 2, 4.min(starts.len() - 1)]);
            picks.sort_unstable();
            picks.dedup();
            for p in picks {
                let a = starts[p];
                let b = a + t[a..].find('\n').unwrap_or(t.len() - a);
                let junk = ["#@! x 1e999 -- 3", "", "1 2", "$Nodes", "nan nan nan", "-7 -7 -7 -7 -7"][rng.below(6)];
                let s = splice(t, &mut [((a, b), junk.to_string())]);
                out.push((Class::MeshGarbled, format!("line {} replaced by {junk:?}", p + 1), s.into_bytes()));
            }
        }
        None => {
            for _ in 0..6 {
                let mut b = bytes.to_vec();
                let at = rng.below(n);
                for x in b.iter_mut().skip(at).take(8) {
                    *x = rng.next() as u8;
                }
                out.push((Class::MeshGarbled, format!("8 bytes garbled at {at}"), b));
            }
        }
    }
    let Some(t) = text else { return out };
    for pick in [0usize, 7, 1 + rng.below(1000)] {
        let Some(nodes) = element_nodes(fmt, t, pick) else { continue };
        let tok = |i: usize| t[nodes[i].0..nodes[i].1].to_string();
        let missing = if matches!(fmt, Fmt::Msh2 | Fmt::Msh4) { "999999" } else { "99999" };
        let k = nodes.len();
        out.push((Class::MeshMissingNode, format!("element #{pick}: node {} -> {missing}", tok(k - 1)), splice(t, &mut [(nodes[k - 1], missing.into())]).into_bytes()));
        out.push((Class::MeshDegenerate, format!("element #{pick}: node {} repeated", tok(0)), splice(t, &mut [(nodes[1], tok(0))]).into_bytes()));
        if k == 4 {
            // A collapsed quadrilateral: two opposite corners the same point.
            out.push((Class::MeshDegenerate, format!("element #{pick}: corners 0 and 2 the same"), splice(t, &mut [(nodes[2], tok(0))]).into_bytes()));
        }
        // Inverted: two corners swapped (a clockwise triangle, a bow-tie quadrilateral).
        out.push((Class::MeshInverted, format!("element #{pick}: corners 0 and 1 swapped"), splice(t, &mut [(nodes[0], tok(1)), (nodes[1], tok(0))]).into_bytes()));
        // Fully reversed (clockwise, reoriented with a warning).
        let mut e: Vec<_> = (0..k).map(|i| (nodes[i], tok(k - 1 - i))).collect();
        out.push((Class::MeshInverted, format!("element #{pick}: corners reversed"), splice(t, &mut e).into_bytes()));
    }
    // Physical groups: a $PhysicalNames entry removed (count kept right, then the count wrong).
    if let Some(a) = t.find("$PhysicalNames\n") {
        let a = a + "$PhysicalNames\n".len();
        let cl = a + t[a..].find('\n').unwrap();
        let count: usize = t[a..cl].trim().parse().unwrap_or(0);
        if count > 0 {
            let mut starts = vec![cl + 1];
            for _ in 0..count {
                let s = *starts.last().unwrap();
                starts.push(s + t[s..].find('\n').unwrap() + 1);
            }
            for g in [0, count - 1, rng.below(count)] {
                let line = &t[starts[g]..starts[g + 1]];
                let gname = line.split('"').nth(1).unwrap_or("").to_string();
                let s = splice(t, &mut [((a, cl), (count - 1).to_string()), ((starts[g], starts[g + 1]), String::new())]);
                out.push((Class::MeshGroupMissing, format!("physical group \"{gname}\" removed"), s.into_bytes()));
            }
            let s = splice(t, &mut [((starts[0], starts[1]), String::new())]);
            out.push((Class::MeshGroupMissing, "a physical name removed, count unchanged".into(), s.into_bytes()));
        }
    }
    // VTK: the region array removed.
    if fmt == Fmt::VtkLegacy {
        if let Some(a) = t.find("CELL_DATA") {
            out.push((Class::MeshGroupMissing, "CELL_DATA removed".into(), t[..a].as_bytes().to_vec()));
        }
    }
    out
}

// ------------------------------------------------------------------------------------------
// The test
// ------------------------------------------------------------------------------------------

fn scene_files() -> Vec<PathBuf> {
    let mut out = Vec::new();
    for d in ["configs", "configs/meshes", "configs/paper", "configs/bench", "configs/verification"] {
        let mut v: Vec<PathBuf> = std::fs::read_dir(root().join(d)).unwrap().flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|e| e == "toml")).collect();
        v.sort();
        out.extend(v);
    }
    out
}

fn mesh_file_of(doc: &Table) -> Option<String> {
    doc.get("mesh")?.get("file")?.as_str().map(String::from)
}

/// A scene without groups, for mesh files no scene uses.
const HOST: &str = r#"
[mesh]
type = "TYPE"
file = "FILE"

[[material]]
young_modulus = 1000.0
poisson_ratio = 0.25
density = 1.0

[[stage]]
"#;

// The mutants in three shards, one test each, so that the test harness runs them beside each
// other and beside the other tests (issue 35: this one test was the suite's critical path, 131
// s of its 157 on two cores). Every shard builds the same mutants (one seeded sequence) and
// evaluates those of index `i % SHARDS == shard`.
const SHARDS: usize = 3;

#[test]
fn mutated_scenes_and_meshes_keep_the_bad_input_contract_0() {
    fuzz_shard(0);
}

#[test]
fn mutated_scenes_and_meshes_keep_the_bad_input_contract_1() {
    fuzz_shard(1);
}

#[test]
fn mutated_scenes_and_meshes_keep_the_bad_input_contract_2() {
    fuzz_shard(2);
}

fn fuzz_shard(shard: usize) {
    flem_plugins::link();
    let t0 = std::time::Instant::now();
    let scratch = std::env::temp_dir().join(format!("flem-fuzz-{}-{shard}", std::process::id()));
    std::fs::create_dir_all(&scratch).unwrap();
    let verbose = std::env::var("FLEM_FUZZ_VERBOSE").is_ok_and(|v| v == "1");
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut mutants: Vec<Mutant> = Vec::new();
    // Mesh files and the scene that hosts each (the first scene that uses it).
    let mut hosts: BTreeMap<PathBuf, Option<PathBuf>> = BTreeMap::new();
    for f in std::fs::read_dir(root().join("configs/meshes")).unwrap().flatten().map(|e| e.path()) {
        if f.extension().is_some_and(|e| e == "msh" || e == "vtk" || e == "vtu") {
            hosts.insert(f, None);
        }
    }
    for f in scene_files() {
        let doc: Table = toml::from_str(&std::fs::read_to_string(&f).unwrap()).unwrap();
        if let Some(m) = mesh_file_of(&doc) {
            let p = f.parent().unwrap().join(m);
            let p = p.canonicalize().unwrap_or(p);
            let e = hosts.entry(p).or_insert(None);
            if e.is_none() {
                *e = Some(f.clone());
            }
        }
        let mut ms = scene_mutants(&f, &mut rng);
        let cells = |k: &str| doc.get("mesh").and_then(|m| m.get(k)).and_then(Value::as_integer).unwrap_or(0);
        let large = mesh_file_of(&doc).and_then(|m| std::fs::metadata(f.parent().unwrap().join(m)).ok()).is_some_and(|md| md.len() as usize > LARGE_MESH) || cells("nx") * cells("ny") > LARGE_CELLS;
        if large {
            ms.iter_mut().for_each(|m| m.large = true);
            ms = (0..LARGE_SAMPLE).map(|_| rng.below(ms.len())).collect::<std::collections::BTreeSet<_>>().into_iter().rev().map(|i| ms.swap_remove(i)).collect();
        }
        mutants.extend(ms);
    }
    let mesh_dir = scratch.join("meshes");
    std::fs::create_dir_all(&mesh_dir).unwrap();
    let mut k = 0usize;
    for (mesh, host) in &hosts {
        let bytes = std::fs::read(mesh).unwrap();
        let name = mesh.file_name().unwrap().to_string_lossy().to_string();
        let kind = if name.ends_with(".msh") { "gmsh" } else { "vtk" };
        let (host_text, host_name) = match host {
            Some(h) => (std::fs::read_to_string(h).unwrap(), h.file_stem().unwrap().to_string_lossy().to_string()),
            None => (HOST.replace("TYPE", kind).replace("FILE", &name), "host".to_string()),
        };
        let mut ms = mesh_mutants(&name, &bytes, &mut rng);
        if bytes.len() > LARGE_MESH {
            ms = (0..LARGE_SAMPLE).map(|_| rng.below(ms.len())).collect::<std::collections::BTreeSet<_>>().into_iter().rev().map(|i| ms.swap_remove(i)).collect();
        }
        for (class, what, b) in ms {
            k += 1;
            // Each mutant in its own folder under the mesh's own name (written by its shard).
            let d = mesh_dir.join(k.to_string());
            if mutants.len() % SHARDS == shard {
                std::fs::create_dir_all(&d).unwrap();
                std::fs::write(d.join(&name), &b).unwrap();
            }
            let mut doc: Table = toml::from_str(&host_text).unwrap();
            if let Some(Value::Table(m)) = doc.get_mut("mesh") {
                m.insert("file".into(), Value::String(name.clone()));
            }
            // What a refusal must name besides the file: the element (or cell/point) for an
            // element edit, the group for a removed group, the line for a broken section.
            let names: Vec<String> = match class {
                Class::MeshMissingNode | Class::MeshDegenerate | Class::MeshInverted => vec!["element".into(), "cell".into(), "point".into()],
                Class::MeshGroupMissing if what.starts_with("physical group \"") => vec![what.split('"').nth(1).unwrap_or("").to_string()],
                Class::MeshGroupMissing if what.contains("count unchanged") => vec!["line".into()],
                _ => Vec::new(),
            };
            mutants.push(Mutant {
                class,
                what: format!("{name}: {what}"),
                text: toml::to_string(&doc).unwrap(),
                scene_name: format!("{host_name}~m{k}.toml"),
                base_dir: d,
                names,
                mesh_file: Some(name.clone()),
                large: bytes.len() > LARGE_MESH,
            });
        }
    }
    let classes: std::collections::BTreeSet<Class> = mutants.iter().map(|m| m.class).collect();
    assert!(classes.len() == 18, "a mutation class produced no mutant: {classes:?}");
    assert!(mutants.len() > 1000, "too few mutants");
    // Run this shard's.
    let mut counts: BTreeMap<Class, [usize; 4]> = BTreeMap::new();
    let mut breaches = Vec::new();
    let (mut n_accepted, mut written) = (0usize, 0usize);
    for m in mutants.iter().skip(shard).step_by(SHARDS) {
        let v = evaluate(m, &scratch);
        let slot = match v {
            Verdict::Refused(_) => 0,
            Verdict::Ran => 1,
            Verdict::RunFailed(_) => 2,
            Verdict::Panicked(_) => 3,
        };
        counts.entry(m.class).or_default()[slot] += 1;
        if verbose {
            eprintln!("[{:?}] {} ({}): {v:?}", m.class, m.what, m.scene_name);
        }
        if let Err(b) = judge(m, &v) {
            breaches.push(format!("[{:?}] {} ({}): {b}", m.class, m.what, m.scene_name));
        }
        // Every WRITE_EVERY-th accepted mutant (and every one whose run failed) again through
        // the real writer, unless its mesh is large.
        let accepted = matches!(v, Verdict::Ran | Verdict::RunFailed(_));
        if accepted && (matches!(v, Verdict::RunFailed(_)) || n_accepted % WRITE_EVERY == 0) && !m.large {
            written += 1;
            if let Err(b) = check_written(m, &scratch) {
                breaches.push(format!("[{:?}] {} ({}): written results: {b}", m.class, m.what, m.scene_name));
            }
        }
        n_accepted += accepted as usize;
    }
    eprintln!("{:<18} {:>7} {:>7} {:>7} {:>7} {:>7}", "class", "mutants", "refused", "ran", "failed", "panic");
    let mut total = [0usize; 4];
    for (c, n) in &counts {
        eprintln!("{:<18} {:>7} {:>7} {:>7} {:>7} {:>7}", format!("{c:?}"), n.iter().sum::<usize>(), n[0], n[1], n[2], n[3]);
        for i in 0..4 {
            total[i] += n[i];
        }
    }
    eprintln!(
        "{:<18} {:>7} {:>7} {:>7} {:>7} {:>7}  ({written} runs also written and read back; {:.1} s)",
        "all",
        total.iter().sum::<usize>(),
        total[0],
        total[1],
        total[2],
        total[3],
        t0.elapsed().as_secs_f64()
    );
    let _ = std::fs::remove_dir_all(&scratch);
    assert!(total.iter().sum::<usize>() * SHARDS + SHARDS > mutants.len(), "shard {shard} evaluated too few mutants");
    assert!(breaches.is_empty(), "{} mutants break the bad-input contract:\n{}", breaches.len(), breaches.join("\n"));
}

/// Regression (found by the harness above: `cracking.max_splits_per_check` = i64::MAX on
/// configs/paper/direct_shear_steps.toml): several splits in one failure check, where a later
/// candidate's fan holds a cluster created by an earlier cut of the same check. Before the
/// fix `Cracking::link_geometry` indexed the solver's displacement array (not yet grown) with
/// the new cluster: index out of bounds. Asserted: some check splits more than one node
/// (the case is reached), the run ends without a panic, and the state stays finite.
#[test]
fn several_splits_in_one_check_reach_new_clusters() {
    flem_plugins::link();
    let path = root().join("configs/paper/direct_shear_steps.toml");
    let mut scene = Scene::from_file(&path).unwrap();
    scene.file.cracking.as_mut().unwrap().max_splits_per_check = 1000;
    // As the harness ran it (every stage capped at 300 steps), which reaches a check with
    // several failed nodes.
    for st in &mut scene.file.stages {
        st.max_steps = Some(STEP_CAP);
    }
    #[derive(Default)]
    struct Most(usize, FiniteGuard);
    impl Observer for Most {
        fn splits(&mut self, sim: &Simulation, _r: &flem_core::mesh::topology::SplitRecord, ev: &[flem_core::cracking::SplitEvent]) -> flem_core::Result<()> {
            self.0 = self.0.max(ev.iter().map(|e| e.cluster).collect::<std::collections::BTreeSet<_>>().len());
            self.1.look(sim, "splits");
            Ok(())
        }
    }
    let mut sim = Simulation::new(scene).unwrap();
    let mut obs = Most::default();
    let r = catch_unwind(AssertUnwindSafe(|| sim.run(&mut obs)));
    assert!(r.is_ok(), "the run panicked");
    assert!(obs.0 >= 2, "no check split more than one node ({}): the case is not reached", obs.0);
    assert!(obs.1.bad.is_none(), "{:?}", obs.1.bad);
}

/// A truncated plugin library (`[plugins] load`, `flem plugins --load`) is refused with a
/// message naming it; before, glibc's dlopen mapped it and the process died of SIGBUS with no
/// message. The library here is the `flem` executable itself cut at several offsets (an ELF
/// file like any plugin; the check runs before dlopen). Run as a subprocess: a crash must not
/// take the test binary down.
#[test]
fn truncated_plugin_library_is_refused_by_name() {
    let exe = crate::common::flem_exe();
    let bytes = std::fs::read(exe).unwrap();
    let dir = std::env::temp_dir().join(format!("flem-fuzz-lib-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut rng = Rng(0xD1B5_4A32_D192_ED03);
    // Cuts in the headers, in the first segments and one byte short; the random ones within the
    // first 4 MB (the executable is tens of MB: the suite's other tests share the disk).
    let mut cuts = vec![0usize, 10, 63, 64, 200, 3000, (bytes.len() / 2).min(4 << 20), bytes.len() - 1];
    cuts.extend((0..4).map(|_| rng.below(bytes.len().min(4 << 20))));
    for cut in cuts {
        let lib = dir.join(format!("libcut{cut}.so"));
        std::fs::write(&lib, &bytes[..cut]).unwrap();
        let out = std::process::Command::new(exe).args(["plugins", "--load"]).arg(&lib).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "cut at {cut}: the process ended by {:?}: {err}", out.status);
        assert!(err.contains(&format!("libcut{cut}.so")), "cut at {cut}: the message does not name the library: {err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `flem converge` and `flem sweep` inputs (issue 35): bad levels, radius, weights, ramps,
/// mesh lists, scenes, sweep files and key paths. Reference: the bad-input contract (a clear
/// error naming the flag, the file or the key; no panic; no half-written output). Each bad
/// input is run through the real binary: its exit code is 1 (our refusal) or 2 (clap's), its
/// message names what is wrong, nothing panicked, and a refused `flem converge` created no
/// output folder. A sweep's bad key paths and values are refused per task, each row naming
/// its key, while a good task of the same sweep runs.
#[test]
fn converge_and_sweep_inputs_get_named_refusals() {
    use std::process::Command;
    let exe = crate::common::flem_exe();
    let dir = std::env::temp_dir().join(format!("flem-fuzz-tools-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let good = root().join("configs/converge/opening_nonlocal.toml");
    let text = std::fs::read_to_string(&good).unwrap();
    assert!(text.contains("[cracking]\nnonlocal = { radius = 1.1, exclusion = 1.1 }"), "the scene changed: update the test");
    let write = |name: &str, body: &str| {
        let p = dir.join(name);
        std::fs::write(&p, body).unwrap();
        p
    };
    // The rectangle mesh is generated: the copies need no mesh file.
    let no_nonlocal = write("local.toml", &text.replace("nonlocal = { radius = 1.1, exclusion = 1.1 }   # OURS (docs/nonlocal.md)\n", ""));
    let no_crack = write("no_crack.toml", &format!("{}{}", text.split("[cracking]").next().unwrap(), &text[text.find("[[stage]]").unwrap()..]));
    let gravity = write("gravity.toml", &text.replace("plane = \"strain\"\n", "plane = \"strain\"\ngravity = [0.0, -9.81]\n"));
    let not_toml = write("not_toml.toml", "this is [not toml");
    let gmsh = write(
        "gmsh.toml",
        &text.replace("type = \"rectangle\"", "type = \"gmsh\"\nfile = \"x.msh\"").replace("width = 6.0\nheight = 6.0\nnx = 6\nny = 6\nnotch = { side = \"left\", y = 3.0, depth = 2.0 }\n", ""),
    );
    let g = good.to_str().unwrap().to_string();
    let s = |p: &PathBuf| p.to_str().unwrap().to_string();
    let missing = dir.join("missing.toml");
    let cases: Vec<(Vec<String>, &str)> = vec![
        (vec![g.clone(), "--levels".into(), "0".into()], "--levels"),
        (vec![g.clone(), "--levels".into(), "9".into()], "--levels"),
        (vec![g.clone(), "--levels=-1".into()], "--levels"),
        (vec![g.clone(), "--levels".into(), "99999999999999999999999".into()], "--levels"),
        (vec![g.clone(), "--levels".into(), "two".into()], "--levels"),
        (vec![g.clone(), "--radius=-1".into()], "--radius"),
        (vec![g.clone(), "--radius".into(), "0".into()], "--radius"),
        (vec![g.clone(), "--radius".into(), "nan".into()], "--radius"),
        (vec![g.clone(), "--radius".into(), "inf".into()], "--radius"),
        (vec![g.clone(), "--radius".into(), "1e400".into()], "--radius"),
        (vec![g.clone(), "--radius".into(), "x".into()], "--radius"),
        (vec![g.clone(), "--weight".into(), "bogus".into()], "--weight"),
        (vec![g.clone(), "--exclusion=-1".into()], "--exclusion"),
        (vec![g.clone(), "--exclusion".into(), "nan".into()], "--exclusion"),
        (vec![s(&no_nonlocal), "--weight".into(), "bell".into()], "--weight"),
        (vec![s(&no_nonlocal), "--exclusion".into(), "1".into()], "--exclusion"),
        (vec![g.clone(), "--ramp-to".into(), "0.5".into()], "--ramp-to"),
        (vec![g.clone(), "--ramp-to".into(), "nan".into()], "--ramp-to"),
        (vec![g.clone(), "--ramp-to".into(), "1e9".into()], "--ramp-to"),
        (vec![g.clone(), "--ramp-to".into(), "2".into(), "--ramp-step".into(), "0".into()], "--ramp-step"),
        (vec![g.clone(), "--ramp-to".into(), "2".into(), "--ramp-step=-0.1".into()], "--ramp-step"),
        (vec![g.clone(), "--ramp-to".into(), "2".into(), "--ramp-step".into(), "nan".into()], "--ramp-step"),
        (vec![g.clone(), "--ramp-to".into(), "2".into(), "--ramp-step".into(), "1e-9".into()], "--ramp-step"),
        (vec![g.clone(), "--ramp-max-steps".into(), "0".into()], "--ramp-max-steps"),
        (vec![g.clone(), "--levels".into(), "3".into(), "--meshes".into(), "a.msh,b.msh".into()], "--meshes"),
        (vec![g.clone(), "--levels".into(), "1".into(), "--meshes".into(), s(&dir.join("nowhere.msh"))], "nowhere.msh"),
        (vec![s(&missing)], "missing.toml"),
        (vec![s(&not_toml)], "not_toml.toml"),
        (vec![s(&no_crack)], "[cracking]"),
        (vec![s(&gravity), "--levels".into(), "1".into(), "--no-explicit".into()], "model.gravity"),
        (vec![s(&gmsh), "--levels".into(), "1".into()], "--meshes"),
    ];
    let mut failures = Vec::new();
    for (k, (args, want)) in cases.iter().enumerate() {
        let out = dir.join(format!("converge_{k}"));
        let o = Command::new(exe).arg("converge").args(args).arg("--out").arg(&out).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        let code = o.status.code();
        if !matches!(code, Some(1) | Some(2)) || !err.contains(want) || err.contains("panicked") || out.exists() {
            failures.push(format!("flem converge {args:?}: exit {code:?}, output folder left: {}, stderr: {err}", out.exists()));
        }
    }
    // Sweep files refused as a whole (before any task).
    let gs = g.replace('\\', "/");
    let sweep_cases: Vec<(String, &str)> = vec![
        ("this is [not toml".into(), "sweep.toml"),
        (format!("sceen = \"{gs}\"\n[grid]\n\"solver.tolerance\" = [1e-5]\n"), "sceen"),
        ("[grid]\n\"solver.tolerance\" = [1e-5]\n".into(), "scene"),
        (format!("scene = \"{}\"\n[grid]\n\"solver.tolerance\" = [1e-5]\n", s(&missing)), "missing.toml"),
        (format!("scene = \"{}\"\n[grid]\n\"solver.tolerance\" = [1e-5]\n", s(&not_toml)), "not_toml.toml"),
        (format!("scene = \"{gs}\"\n[grid]\n\"solver.tolerance\" = 1e-5\n"), "grid.\"solver.tolerance\""),
        (format!("scene = \"{gs}\"\n[grid]\n\"solver.tolerance\" = []\n"), "grid.\"solver.tolerance\""),
        (format!("scene = \"{gs}\"\n"), "no task"),
        (format!("scene = \"{gs}\"\nthreads = -1\n[grid]\n\"solver.tolerance\" = [1e-5]\n"), "threads"),
        (format!("scene = \"{gs}\"\nthreads = 5000\n[grid]\n\"solver.tolerance\" = [1e-5]\n"), "threads"),
    ];
    for (k, (body, want)) in sweep_cases.iter().enumerate() {
        let f = write("sweep.toml", &format!("out = \"sweep_out_{k}\"\n{body}"));
        let o = Command::new(exe).arg("sweep").arg(&f).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        let code = o.status.code();
        if code != Some(1) || !err.contains(want) || err.contains("panicked") || dir.join(format!("sweep_out_{k}")).exists() {
            failures.push(format!("flem sweep {body:?}: exit {code:?}, stderr: {err}"));
        }
    }
    // Bad key paths and values: each task's row names its key; the good task runs.
    // (key path, value, what the row's error must name).
    let tasks: Vec<(&str, &str, &str)> = vec![
        ("cracking..xyz", "1", "cracking..xyz"),
        ("stage[9].levels.p", "1.0", "stage[9]"),
        ("stage[x].levels.p", "1.0", "stage[x]"),
        ("stage[0].levels.p.q", "1.0", "stage[0].levels.p.q"),
        ("material[0].young_modulus", "\"abc\"", "young_modulus"),
        ("material[0].young_modulus", "nan", "young_modulus"),
        ("material[0].young_modulus", "-1.0", "young_modulus"),
        ("material[0].young_modulus", "inf", "young_modulus"),
        ("solver.bogus_key", "1", "bogus_key"),
        ("cracking.criterion.tensile_strength", "-1.0", "tensile_strength"),
        ("solver.threads", "5000", "solver.threads"),
        ("stage[0].levels.nosuchload", "1.0", "nosuchload"),
        ("mesh.nx", "0", "nx"),
    ];
    let mut body = format!("scene = \"{gs}\"\nout = \"sweep_tasks\"\n");
    for (k, v, _) in &tasks {
        body.push_str(&format!("[[task]]\n\"{k}\" = {v}\n"));
    }
    body.push_str("[[task]]\n\"solver.tolerance\" = 1e-4\n");
    let f = write("tasks.toml", &body);
    let o = Command::new(exe).arg("sweep").arg(&f).arg("--workers").arg("1").output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    if o.status.code() != Some(0) || err.contains("panicked") {
        failures.push(format!("flem sweep (bad tasks): exit {:?}, stderr: {err}", o.status.code()));
    } else {
        let csv = std::fs::read_to_string(dir.join("sweep_tasks/sweep.csv")).unwrap();
        // Records, not lines: a quoted error may hold line breaks (a TOML error's excerpt).
        let mut records = Vec::new();
        let (mut quoted, mut start) = (false, 0);
        for (i, ch) in csv.char_indices() {
            match ch {
                '"' => quoted = !quoted,
                '\n' if !quoted => {
                    records.push(&csv[start..i]);
                    start = i + 1;
                }
                _ => {}
            }
        }
        let rows: Vec<&str> = records.into_iter().skip(1).collect();
        assert_eq!(rows.len(), tasks.len() + 1, "{csv}");
        for (i, (key, v, want)) in tasks.iter().enumerate() {
            let row = rows.iter().find(|r| r.starts_with(&format!("{i},"))).unwrap();
            // The parameter columns hold values and `out` the task folder: the key is named
            // by the error, the last column (empty: the row ends in ',').
            if !row.contains(want) || row.ends_with(',') || row.contains("panicked") {
                failures.push(format!("sweep task \"{key}\" = {v}: row {row}"));
            }
        }
        let good_row = rows.iter().find(|r| r.starts_with(&format!("{},", tasks.len()))).unwrap();
        assert!(good_row.ends_with(','), "the good task failed: {good_row}");
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert!(failures.is_empty(), "{} bad inputs without a named refusal:\n{}", failures.len(), failures.join("\n"));
}
