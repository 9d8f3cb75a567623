//! A 3D scene (issue 38, docs/3d.md): `[model] dim = 3`. The same scene language as 2D, with
//! the sections that 3D has today (`[mesh]`, `[[set]]`-free node and face sets of the mesh,
//! `[[material]]`, `[solver]`, `[[support]]`, `[[load]]`, `[[stage]]`, `[cracking]`,
//! `[contact]` (node-to-face, `crate::contact::contact3`), `[check]` (`output::compare3`),
//! `[output]`); the 2D sections and keys that have no 3D form yet are refused by name
//! (material laws, co-rotation, the events solver, nonlocal stress,
//! Weibull scatter, probes), so that a 3D scene never runs something else than it says.
//!
//! 3D keys: `[[support]] fix` takes any of `x`, `y`, `z` (`"xyz"`, `"z"`, `"xz"`...);
//! `[[load]]` is `type = "pressure"` on a face set (`faces = "..."`, positive pushing into the
//! body, direction fixed at the initial face normal), `type = "point"` (`nodes`, `value =
//! [fx, fy, fz]`, on every point of the set) or `type = "velocity"` (`nodes`, `x`, `y`, `z`:
//! the prescribed velocity of those dofs); `[model] gravity = [gx, gy, gz]` and
//! `[model] separated = ["face set", ...]` (faces separated from the start).
//!
//! ```toml
//! title = "a bar pulled along x"
//! [model]
//! dim = 3
//! [mesh]
//! type = "gmsh"
//! file = "bar.msh"
//! [[material]]
//! young_modulus = 1000.0
//! poisson_ratio = 0.25
//! density = 1.0
//! [[support]]
//! nodes = "xmin"
//! fix = "xyz"
//! [[load]]
//! name = "pull"
//! type = "pressure"
//! faces = "xmax"
//! value = -1.0
//! [[stage]]
//! levels = { pull = 1.0 }
//! ```
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::element::model::MaterialCfg;
use crate::error::{FlemError, Result};
use crate::mesh::MeshSource;
use crate::scene::{CrackingCfg, SolverCfg, SolverKind, StageCfg, MAX_MAGNITUDE};

/// `[model]` of a 3D scene.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Model3Cfg {
    /// 3.
    pub dim: u8,
    #[serde(default)]
    pub gravity: [f64; 3],
    /// Face sets separated from the start.
    #[serde(default)]
    pub separated: Vec<String>,
    /// "reorient" inverted cells with a warning (default) or "refuse" them.
    #[serde(default)]
    pub orientation: crate::mesh::ValidationOptions,
}

/// `[[support]]` of a 3D scene.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Support3Cfg {
    pub nodes: String,
    /// Any of "x", "y", "z", each at most once ("xyz", "z", "xz"...).
    pub fix: String,
}

impl Support3Cfg {
    /// The fixed-dof bits (1: x, 2: y, 4: z), or `None` for a string that is not a set of x, y, z.
    pub fn bits(&self) -> Option<u8> {
        let mut b = 0u8;
        for ch in self.fix.chars() {
            let k = match ch {
                'x' => 1,
                'y' => 2,
                'z' => 4,
                _ => return None,
            };
            if b & k != 0 {
                return None;
            }
            b |= k;
        }
        (b != 0).then_some(b)
    }
}

/// `[[load]]` of a 3D scene (a stage's `levels` scale it by name).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Load3Cfg {
    /// Uniform pressure on a face set, positive pushing into the body.
    Pressure { name: String, faces: String, value: f64 },
    /// Force on every point of a node set.
    Point { name: String, nodes: String, value: [f64; 3] },
    /// Prescribed velocity of the given components of a node set (scaled by the level).
    Velocity {
        name: String,
        nodes: String,
        #[serde(default)]
        x: Option<f64>,
        #[serde(default)]
        y: Option<f64>,
        #[serde(default)]
        z: Option<f64>,
    },
}

impl Load3Cfg {
    pub fn name(&self) -> &str {
        match self {
            Load3Cfg::Pressure { name, .. } | Load3Cfg::Point { name, .. } | Load3Cfg::Velocity { name, .. } => name,
        }
    }
}

/// `[output]` of a 3D scene.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Output3Cfg {
    /// Steps between rows of history.csv (0: one row per stage).
    #[serde(default)]
    pub history_every: u64,
    /// Steps (global count) between checkpoints (0: none by step count); one is also written
    /// at the end of every stage and when the run is interrupted (`output::checkpoint3`).
    #[serde(default)]
    pub checkpoint_every: u64,
    /// Wall-clock seconds between checkpoints (0: none by time).
    #[serde(default = "default_ck_seconds")]
    pub checkpoint_seconds: f64,
    /// Checkpoint files kept (the newest).
    #[serde(default = "default_ck_keep")]
    pub checkpoint_keep: usize,
}

fn default_ck_seconds() -> f64 {
    600.0
}
fn default_ck_keep() -> usize {
    2
}

impl Default for Output3Cfg {
    fn default() -> Self {
        Output3Cfg { history_every: 0, checkpoint_every: 0, checkpoint_seconds: default_ck_seconds(), checkpoint_keep: default_ck_keep() }
    }
}

/// A 3D scene file as read.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene3File {
    #[serde(default)]
    pub title: String,
    pub mesh: Box<dyn MeshSource>,
    pub model: Model3Cfg,
    #[serde(rename = "material")]
    pub materials: Vec<MaterialCfg>,
    #[serde(default)]
    pub solver: SolverCfg,
    #[serde(default, rename = "support")]
    pub supports: Vec<Support3Cfg>,
    #[serde(default, rename = "load")]
    pub loads: Vec<Load3Cfg>,
    #[serde(rename = "stage")]
    pub stages: Vec<StageCfg>,
    #[serde(default)]
    pub output: Output3Cfg,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cracking: Option<CrackingCfg>,
    /// `[check]`: every stage compared with the implicit solve (`output::compare3`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub check: Option<crate::plugin::check::CheckCfg>,
    /// `[contact]` (docs/3d.md "Contact (3D)"): `surfaces` are face sets; the law must have a
    /// 3D form. Taken by the body it builds (`March3::from_scene`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact: Option<crate::contact::ContactCfg>,
}

/// A validated 3D scene.
#[derive(Debug)]
pub struct Scene3 {
    pub file: Scene3File,
    pub path: PathBuf,
    pub base_dir: PathBuf,
}

/// The dimension a scene text asks for: `[model] dim` (2 when absent). Read before the scene
/// is parsed, so that a 3D scene is parsed as one.
pub fn scene_dim(text: &str) -> u8 {
    let v: Option<toml::Table> = toml::from_str(text).ok();
    v.and_then(|t| t.get("model")?.get("dim")?.as_integer()).map_or(2, |d| d.clamp(0, 255) as u8)
}

/// `[contact]` of a 3D scene: its keys, and a law with a 3D form (refused by name otherwise).
fn validate_contact3(c: &crate::contact::ContactCfg, file: &str) -> Result<()> {
    c.validate(file)?;
    c.law.evaluate_3d(&[], &mut [], &mut []).map_err(|e| FlemError::config(file, "contact.law", format!("{e}: a 3D scene takes \"spring_dashpot\" or \"penalty\"")))
}

/// Sections and keys of the 2D scene language with no 3D form yet: named in the refusal.
const NOT_IN_3D: [(&str, &str); 2] = [("set", "[[set]] selections by geometry are 2D; name the mesh's physical groups"), ("plugins", "dynamic plugin libraries have no 3D ABI yet")];

impl Scene3 {
    /// Parses and validates a 3D scene text (`[model] dim = 3`); `path` is used in messages,
    /// `base_dir` for relative paths.
    pub fn from_str(text: &str, path: &Path, base_dir: &Path) -> Result<Scene3> {
        let name = path.display().to_string();
        let table: toml::Table = toml::from_str(text).map_err(|e| FlemError::config(&name, "", format!("is not valid TOML: {e}")))?;
        for (key, why) in NOT_IN_3D {
            if table.contains_key(key) {
                return Err(FlemError::config(&name, key, format!("is not available in a 3D scene ([model] dim = 3): {why} (docs/3d.md)")));
            }
        }
        let mut file: Scene3File = toml::from_str(text).map_err(|e| crate::scene::parse_error(&name, text, e))?;
        if file.solver.damping.is_none() {
            let d = toml::from_str("type = \"adaptive\"")
                .map_err(|e| FlemError::config(&name, "solver.damping", format!("is not given and the default \"adaptive\" is not registered in this program ({e})")))?;
            file.solver.damping = Some(d);
        }
        if let Some(c) = file.check.as_mut() {
            c.fill_default(&name)?;
        }
        let scene = Scene3 { file, path: path.to_path_buf(), base_dir: base_dir.to_path_buf() };
        scene.validate()?;
        Ok(scene)
    }

    /// Reads and validates a 3D scene file.
    pub fn from_file(path: &Path) -> Result<Scene3> {
        let text = std::fs::read_to_string(path).map_err(|e| FlemError::config(path.display().to_string(), "", format!("cannot be read: {e}")))?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Scene3::from_str(&text, path, &base)
    }

    fn validate(&self) -> Result<()> {
        let f = &self.file;
        let n = self.path.display().to_string();
        let range = |key: &str, v: f64, lo: f64, lo_incl: bool, hi: f64, hi_incl: bool| {
            crate::plugin::traits::ParamError::range(key, v, lo, lo_incl, hi, hi_incl).map_err(|e| FlemError::config(&n, e.key, e.msg))
        };
        if f.model.dim != 3 {
            return Err(FlemError::config(&n, "model.dim", format!("= {} is incorrect here; a 3D scene has dim = 3 (2D scenes leave it out)", f.model.dim)));
        }
        for d in 0..3 {
            range(&format!("model.gravity[{d}]"), f.model.gravity[d], -MAX_MAGNITUDE, true, MAX_MAGNITUDE, true)?;
        }
        if f.materials.is_empty() {
            return Err(FlemError::config(&n, "material", "is missing; give at least one [[material]]"));
        }
        for (i, m) in f.materials.iter().enumerate() {
            let k = |s: &str| format!("material[{i}].{s}");
            range(&k("young_modulus"), m.young_modulus, 0.0, false, MAX_MAGNITUDE, true)?;
            range(&k("poisson_ratio"), m.poisson_ratio, -1.0, false, 0.5, false)?;
            range(&k("density"), m.density, 0.0, false, MAX_MAGNITUDE, true)?;
            if m.law.is_some() || m.corotational || m.bbar.is_some() || m.elastic_shortcut.is_some() {
                return Err(FlemError::config(
                    &n,
                    k(if m.law.is_some() {
                        "law"
                    } else if m.corotational {
                        "corotational"
                    } else if m.bbar.is_some() {
                        "bbar"
                    } else {
                        "elastic_shortcut"
                    }),
                    "is not available in 3D yet (linear elasticity only; docs/3d.md)",
                ));
            }
            if m.thickness != 1.0 {
                return Err(FlemError::config(&n, k("thickness"), "has no meaning in 3D (the mesh has its own thickness); remove it"));
            }
        }
        let s = &f.solver;
        if s.kind != SolverKind::Explicit {
            return Err(FlemError::config(&n, "solver.type", "= \"events\" is not available in 3D yet; the explicit march is"));
        }
        if s.large_strain {
            return Err(FlemError::config(&n, "solver.large_strain", "is not available in 3D yet"));
        }
        if s.mass_scaling {
            return Err(FlemError::config(&n, "solver.mass_scaling", "is not available in 3D yet"));
        }
        if let Some(dt) = s.dt {
            range("solver.dt", dt, 0.0, false, f64::INFINITY, false)?;
        }
        range("solver.dt_safety", s.dt_safety, 0.0, false, 1.0, true)?;
        range("solver.tolerance", s.tolerance, 0.0, false, 1.0, false)?;
        if s.max_steps == 0 || s.ratio_every == 0 {
            return Err(FlemError::config(&n, if s.max_steps == 0 { "solver.max_steps" } else { "solver.ratio_every" }, "= 0 is incorrect; it must be >= 1"));
        }
        s.damping.as_ref().map_or(Ok(()), |d| d.validate()).map_err(|e| FlemError::config(&n, format!("solver.damping.{}", e.key), e.msg))?;
        for (i, sup) in f.supports.iter().enumerate() {
            if sup.bits().is_none() {
                return Err(FlemError::config(&n, format!("support[{i}].fix"), format!("= \"{}\" is incorrect; it must be a set of x, y, z (\"x\", \"yz\", \"xyz\"...)", sup.fix)));
            }
        }
        let mut names: Vec<&str> = Vec::new();
        for (i, l) in f.loads.iter().enumerate() {
            if names.contains(&l.name()) {
                return Err(FlemError::config(&n, format!("load[{i}].name"), format!("= \"{}\" is used twice; load names must be unique", l.name())));
            }
            names.push(l.name());
            let vals: Vec<f64> = match l {
                Load3Cfg::Pressure { value, .. } => vec![*value],
                Load3Cfg::Point { value, .. } => value.to_vec(),
                Load3Cfg::Velocity { x, y, z, .. } => {
                    if x.is_none() && y.is_none() && z.is_none() {
                        return Err(FlemError::config(&n, format!("load[{i}]"), "prescribes none of x, y, z; give at least one"));
                    }
                    [x, y, z].iter().filter_map(|v| **v).collect()
                }
            };
            for v in vals {
                range(&format!("load[{i}].value"), v, -MAX_MAGNITUDE, true, MAX_MAGNITUDE, true)?;
            }
        }
        if f.stages.is_empty() {
            return Err(FlemError::config(&n, "stage", "is missing; give at least one [[stage]]"));
        }
        for (i, st) in f.stages.iter().enumerate() {
            for (load, &lv) in &st.levels {
                if !names.contains(&load.as_str()) {
                    return Err(FlemError::config(&n, format!("stage[{i}].levels.{load}"), format!("names no load (loads: {names:?})")));
                }
                range(&format!("stage[{i}].levels.{load}"), lv, -MAX_MAGNITUDE, true, MAX_MAGNITUDE, true)?;
            }
        }
        if let Some(c) = &f.check {
            c.validate(&n)?;
        }
        range("output.checkpoint_seconds", f.output.checkpoint_seconds, 0.0, true, f64::INFINITY, false)?;
        if f.output.checkpoint_keep == 0 {
            return Err(FlemError::config(&n, "output.checkpoint_keep", "= 0 is incorrect; it must be >= 1"));
        }
        if let Some(c) = &f.contact {
            validate_contact3(c, &n)?;
        }
        if let Some(c) = &f.cracking {
            if c.nonlocal.is_some() || c.weibull.is_some() || !c.intact.is_empty() {
                let key = if c.nonlocal.is_some() {
                    "cracking.nonlocal"
                } else if c.weibull.is_some() {
                    "cracking.weibull"
                } else {
                    "cracking.intact"
                };
                return Err(FlemError::config(&n, key, "is not available in 3D yet"));
            }
            c.criterion.validate().map_err(|e| FlemError::config(&n, format!("cracking.criterion.{}", e.key), e.msg))?;
            c.separation.validate().map_err(|e| FlemError::config(&n, format!("cracking.separation.{}", e.key), e.msg))?;
            if c.check_every == 0 || c.max_splits_per_check == 0 {
                return Err(FlemError::config(&n, if c.check_every == 0 { "cracking.check_every" } else { "cracking.max_splits_per_check" }, "= 0 is incorrect; it must be >= 1"));
            }
        }
        Ok(())
    }

    /// The `[[material]]` of a region of the mesh (or the one with `region = "all"`).
    pub fn material_for(&self, region: &str) -> Option<&MaterialCfg> {
        let ms = &self.file.materials;
        ms.iter().find(|m| m.region == region).or_else(|| ms.iter().find(|m| m.region == "all"))
    }

    /// The levels in force at each stage (a stage's level keeps its value until a later stage
    /// changes it), by load name.
    pub fn stage_levels(&self) -> Vec<BTreeMap<String, f64>> {
        let mut cur: BTreeMap<String, f64> = self.file.loads.iter().map(|l| (l.name().to_string(), 0.0)).collect();
        self.file
            .stages
            .iter()
            .map(|st| {
                for (k, v) in &st.levels {
                    cur.insert(k.clone(), *v);
                }
                cur.clone()
            })
            .collect()
    }
}
