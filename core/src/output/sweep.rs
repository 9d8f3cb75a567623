//! One task of a parameter sweep (issue 22): a scene with some parameters changed by key path,
//! run into its own folder, summed up in one [`Row`]. `flem sweep` (local worker processes) and
//! the Python package's `flem.sweep` (Dask distributed) both run a task through [`run_task`],
//! so their rows are the same. A task that fails, at any point (a bad parameter, a refused
//! scene, a divergence, a panic), is a row with its error, never a lost sweep.
//!
//! Key paths name a scene value as the scene's error messages do: tables by `.`, an element of
//! an array of tables by `[i]` (`cracking.criterion.tensile_strength`,
//! `material[0].young_modulus`, `stage[1].levels.pull`). Missing tables on the way are created
//! (`cracking.weibull.seed` on a scene without `[cracking.weibull]`), so the scene's own
//! validation (`Scene::from_str`, with the CLI's messages) decides what is allowed.
use std::path::Path;
use std::time::Instant;

use crate::cracking::SplitEvent;
use crate::error::Result;
use crate::mesh::topology::SplitRecord;
use crate::output::run::run_in_folder;
use crate::output::OutputWriter;
use crate::scene::Scene;
use crate::solver::{Observer, Simulation, StagePos};

/// Sets the value at `key` (see the module doc) in a scene document. Errors say which part of
/// the path is wrong.
pub fn set_key(doc: &mut toml::Table, key: &str, value: toml::Value) -> std::result::Result<(), String> {
    let parts: Vec<&str> = key.split('.').collect();
    if key.is_empty() || parts.iter().any(|p| p.is_empty()) {
        return Err(format!("\"{key}\" is not a key path (names joined by '.', e.g. cracking.criterion.tensile_strength)"));
    }
    let mut table = doc;
    for (n, part) in parts.iter().enumerate() {
        let last = n + 1 == parts.len();
        let (name, index) = split_index(part).ok_or_else(|| format!("\"{part}\" in \"{key}\" is not a name or name[index]"))?;
        match index {
            None if last => {
                table.insert(name.to_string(), value);
                return Ok(());
            }
            None => {
                let v = table.entry(name.to_string()).or_insert_with(|| toml::Value::Table(toml::Table::new()));
                table = v.as_table_mut().ok_or_else(|| format!("\"{name}\" in \"{key}\" is a value, not a table"))?;
            }
            Some(i) => {
                let arr = table.get_mut(name).and_then(|v| v.as_array_mut()).ok_or_else(|| format!("\"{name}\" in \"{key}\" is not an array in the scene"))?;
                let len = arr.len();
                let slot = arr.get_mut(i).ok_or_else(|| format!("\"{part}\" in \"{key}\": the scene has {len} {name} entries"))?;
                if last {
                    *slot = value;
                    return Ok(());
                }
                table = slot.as_table_mut().ok_or_else(|| format!("\"{part}\" in \"{key}\" is a value, not a table"))?;
            }
        }
    }
    unreachable!("the loop returns at the last part")
}

/// `name` or `name[i]`.
fn split_index(part: &str) -> Option<(&str, Option<usize>)> {
    match part.find('[') {
        None => Some((part, None)),
        Some(a) => {
            let rest = part[a + 1..].strip_suffix(']')?;
            Some((&part[..a], Some(rest.parse().ok()?)))
        }
    }
}

/// A JSON value as a TOML value (`null` has none).
pub fn json_to_toml(v: &serde_json::Value) -> std::result::Result<toml::Value, String> {
    use serde_json::Value as J;
    Ok(match v {
        J::Null => return Err("null (None) has no TOML value".into()),
        J::Bool(b) => toml::Value::Boolean(*b),
        J::Number(n) => match n.as_i64() {
            Some(i) => toml::Value::Integer(i),
            None => toml::Value::Float(n.as_f64().ok_or("a number out of range")?),
        },
        J::String(s) => toml::Value::String(s.clone()),
        J::Array(a) => toml::Value::Array(a.iter().map(json_to_toml).collect::<std::result::Result<_, _>>()?),
        J::Object(o) => {
            let mut t = toml::Table::new();
            for (k, x) in o {
                t.insert(k.clone(), json_to_toml(x)?);
            }
            toml::Value::Table(t)
        }
    })
}

/// Scene text with `params` set (see [`set_key`]), validated as `flem run` would: the error is
/// the CLI's message (a bad path names the key; a bad value gets the scene's own message).
pub fn scene_with(text: &str, path: &Path, base: &Path, params: &[(String, toml::Value)]) -> Result<(String, Scene)> {
    let name = path.display().to_string();
    let new_text = if params.is_empty() {
        text.to_string()
    } else {
        let mut doc: toml::Table = match toml::from_str(text) {
            Ok(d) => d,
            // Not TOML: the scene's own parse gives the message.
            Err(_) => return Err(Scene::from_str(text, path, base).err().unwrap_or_else(|| crate::FlemError::config(&name, "", "is not TOML"))),
        };
        for (k, v) in params {
            set_key(&mut doc, k, v.clone()).map_err(|m| crate::FlemError::config(&name, k.as_str(), m))?;
        }
        toml::to_string(&doc).map_err(|e| crate::FlemError::config(&name, "", format!("cannot be written back as TOML: {e}")))?
    };
    let scene = Scene::from_str(&new_text, path, base)?;
    Ok((new_text, scene))
}

/// Records the load levels at the first split (the initiation load of a sweep row).
#[derive(Default)]
pub struct FirstSplit {
    /// (levels of every load, stage index, time) at the first check that split.
    pub at: Option<(Vec<f64>, usize, f64)>,
}

impl Observer for FirstSplit {
    fn splits(&mut self, sim: &Simulation, _rec: &SplitRecord, events: &[SplitEvent]) -> Result<()> {
        if self.at.is_none() && !events.is_empty() {
            self.at = Some((sim.levels.clone(), sim.stages_done.len(), sim.state.time));
        }
        Ok(())
    }
}

/// One row of a sweep: the task's parameters and what its run gave.
#[derive(Clone, Debug, Default)]
pub struct Row {
    pub task: usize,
    pub params: Vec<(String, toml::Value)>,
    /// The highest load level at the first split (the first load on ties); None: no split.
    pub initiation_load: Option<f64>,
    /// The name of the load carrying it, and the stage (index) it happened in.
    pub initiation_loadname: Option<String>,
    pub initiation_stage: Option<usize>,
    pub splits: usize,
    /// Energy residual relative to the work done (`Ledger::relative_residual`).
    pub energy_residual: Option<f64>,
    pub steps: u64,
    /// Every stage reached equilibrium (or was dynamic).
    pub converged: bool,
    pub wall_seconds: f64,
    pub out: String,
    pub error: Option<String>,
}

impl Row {
    /// The row as a flat JSON object: `task`, each parameter by its key path, then the results.
    pub fn to_json(&self) -> serde_json::Value {
        let mut m = serde_json::Map::new();
        m.insert("task".into(), self.task.into());
        for (k, v) in &self.params {
            m.insert(k.clone(), serde_json::to_value(v).unwrap_or(serde_json::Value::Null));
        }
        m.insert("initiation_load".into(), self.initiation_load.into());
        m.insert("initiation_loadname".into(), self.initiation_loadname.clone().into());
        m.insert("initiation_stage".into(), self.initiation_stage.into());
        m.insert("splits".into(), self.splits.into());
        m.insert("energy_residual".into(), self.energy_residual.into());
        m.insert("steps".into(), self.steps.into());
        m.insert("converged".into(), self.converged.into());
        m.insert("wall_seconds".into(), self.wall_seconds.into());
        m.insert("out".into(), self.out.clone().into());
        m.insert("error".into(), self.error.clone().into());
        serde_json::Value::Object(m)
    }
}

/// Runs one task (see the module doc) into `out` (locked for the run; `what` names the holder
/// in the lock file). `threads` overrides `solver.threads` (a sweep usually wants 1 per task).
/// Never fails: every error, and a panic, is the row's `error`.
pub fn run_task(task: usize, text: &str, path: &Path, base: &Path, params: &[(String, toml::Value)], out: &Path, threads: Option<usize>, what: &str) -> Row {
    let t0 = Instant::now();
    let mut row = Row { task, params: params.to_vec(), out: out.display().to_string(), ..Default::default() };
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run_task_inner(&mut row, text, path, base, params, out, threads, what)));
    match r {
        Ok(Ok(())) => {}
        Ok(Err(e)) => row.error = Some(e.to_string()),
        Err(p) => {
            let msg = p.downcast_ref::<String>().cloned().or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string())).unwrap_or_default();
            row.error = Some(format!("the task panicked: {msg}"));
        }
    }
    row.wall_seconds = t0.elapsed().as_secs_f64();
    row
}

#[allow(clippy::too_many_arguments)]
fn run_task_inner(row: &mut Row, text: &str, path: &Path, base: &Path, params: &[(String, toml::Value)], out: &Path, threads: Option<usize>, what: &str) -> Result<()> {
    let t0 = Instant::now();
    let (_, mut scene) = scene_with(text, path, base, params)?;
    if let Some(t) = threads {
        scene.file.solver.threads = t;
    }
    let _lock = crate::output::lock::lock_dir(out, what)?;
    let mut sim = Simulation::new(scene)?;
    let mut w = OutputWriter::new(out, &sim)?;
    let mut first = FirstSplit::default();
    let end = run_in_folder(&mut sim, &mut w, StagePos::start(0), &mut first, t0);
    row.splits = sim.cracking.as_ref().map_or(0, |c| c.n_splits);
    row.energy_residual = Some(sim.ledger.relative_residual()).filter(|r| r.is_finite());
    row.steps = sim.state.step;
    row.converged = sim.stages_done.iter().all(|s| s.converged);
    if let Some((levels, stage, _)) = first.at {
        let mut best: Option<(usize, f64)> = None;
        for (i, &l) in levels.iter().enumerate() {
            if best.is_none_or(|(_, b)| l > b) {
                best = Some((i, l));
            }
        }
        if let Some((i, l)) = best {
            row.initiation_load = Some(l);
            row.initiation_loadname = sim.loads.loads.get(i).map(|x| x.name.clone());
        }
        row.initiation_stage = Some(stage);
    }
    end.result
}

#[cfg(test)]
mod tests {
    use super::*;

    fn doc() -> toml::Table {
        toml::from_str("[cracking.criterion]\ntype = \"rankine\"\ntensile_strength = 1.0\n[[material]]\nyoung_modulus = 1.0\n[[stage]]\nlevels = { p = 1.0 }\n").unwrap()
    }

    #[test]
    fn set_key_reaches_tables_and_array_elements_and_creates_missing_tables() {
        let mut d = doc();
        set_key(&mut d, "cracking.criterion.tensile_strength", toml::Value::Float(2.0)).unwrap();
        set_key(&mut d, "material[0].young_modulus", toml::Value::Float(5.0)).unwrap();
        set_key(&mut d, "stage[0].levels.p", toml::Value::Float(0.5)).unwrap();
        set_key(&mut d, "cracking.weibull.seed", toml::Value::Integer(7)).unwrap();
        assert_eq!(d["cracking"]["criterion"]["tensile_strength"].as_float(), Some(2.0));
        assert_eq!(d["material"][0]["young_modulus"].as_float(), Some(5.0));
        assert_eq!(d["stage"][0]["levels"]["p"].as_float(), Some(0.5));
        assert_eq!(d["cracking"]["weibull"]["seed"].as_integer(), Some(7));
    }

    #[test]
    fn set_key_names_the_bad_part() {
        let mut d = doc();
        let e = |d: &mut toml::Table, k: &str| set_key(d, k, toml::Value::Integer(1)).unwrap_err();
        assert!(e(&mut d, "material[3].density").contains("the scene has 1 material entries"));
        assert!(e(&mut d, "cracking.criterion.type.x").contains("\"type\" in \"cracking.criterion.type.x\" is a value, not a table"));
        assert!(e(&mut d, "support[0].fix").contains("\"support\" in \"support[0].fix\" is not an array"));
        assert!(e(&mut d, "a..b").contains("is not a key path"));
        assert!(e(&mut d, "material[x].density").contains("is not a name or name[index]"));
    }
}
