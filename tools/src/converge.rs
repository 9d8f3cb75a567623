//! `flem converge SCENE --levels K`: the crack-initiation load under mesh refinement (issue 18).
//!
//! The scene runs on K meshes, each twice as fine as the one before: a `rectangle` mesh gets
//! `nx`, `ny` doubled (the notch depth, a length, is kept); any other mesh takes its files from
//! `--meshes a.msh,b.msh,...` (one per level, coarse first). For every level:
//! - the **exact initiation load**: the elastic solution at the first stage's load levels by the
//!   implicit check solver (`flem_plugins::check::static_solve`), then the smallest load factor
//!   at which some node fails (`flem_core::cracking::initiation`), with the paper's corner-mean
//!   nodal stress (`local`) and, when a radius is given (`--radius` or the scene's
//!   `cracking.nonlocal.radius`), the nonlocal average (ours): the failing node and its sigma1
//!   direction;
//! - unless `--no-explicit`: explicit runs of the first stage at 0.97 and 1.03 of the factor
//!   (of the scene's own check: nonlocal when it has a radius), which must split nothing and
//!   something, and at 1.05, whose split points are the crack path;
//! - elements, dofs, wall time (model build + solve + initiation; the explicit runs apart).
//!
//! The load must be proportional to the levels (traction, pressure, point loads; no gravity, no
//! prescribed velocity or displacement) and the body linear (no co-rotational material, no
//! contact before the first split): otherwise it is refused ("does not suit `flem converge`").
//! A scene with a fixed `solver.dt` keeps its ratio dt/dt_crit on each finer mesh
//! (`chart::keep_dt_ratio`); a body without support under self-equilibrated loads (the paper's
//! opening model) gets a statically determinate support in the elastic solve
//! (`flem_core::plugin::support`), said in the output and in converge.json (`supports`). Writes `converge.json` and the
//! picture `converge.png` / `.svg` (p_crit against h for both checks; crack paths overlaid).
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use flem_core::cracking::initiation::{initiation, Initiation};
use flem_core::scene::Scene;
use flem_core::solver::{NoOutput, Simulation};
use serde::Serialize;

#[derive(clap::Args)]
pub struct Args {
    pub scene: PathBuf,
    /// Number of meshes (each twice as fine as the one before).
    #[arg(long, default_value_t = 3)]
    pub levels: usize,
    /// Mesh files of the levels (coarse first), for scenes whose mesh is not a rectangle.
    #[arg(long, value_delimiter = ',')]
    pub meshes: Vec<PathBuf>,
    /// Nonlocal radius (default: the scene's cracking.nonlocal.radius; none: local check only).
    #[arg(long)]
    pub radius: Option<f64>,
    /// Distance weight of the nonlocal average: uniform or bell (default: the scene's).
    #[arg(long)]
    pub weight: Option<String>,
    /// Crack-tracking exclusion distance of the nonlocal check (default: the scene's; ours).
    #[arg(long)]
    pub exclusion: Option<f64>,
    /// Skip the explicit runs at 0.97, 1.03 and 1.05 of the initiation load.
    #[arg(long)]
    pub no_explicit: bool,
    /// Also run a load ramp from the initiation load up to this multiple of it, in stages of
    /// `--ramp-step` (each to equilibrium, the scene's settings): the crack path under rising
    /// load and the peak load (the highest level still in equilibrium).
    #[arg(long)]
    pub ramp_to: Option<f64>,
    /// Increment of the ramp, as a fraction of the initiation load.
    #[arg(long, default_value_t = 0.025)]
    pub ramp_step: f64,
    /// Step limit of each ramp stage (a stage that reaches it has not come to rest: the crack
    /// runs through, and the ramp stops).
    #[arg(long, default_value_t = 50_000)]
    pub ramp_max_steps: u64,
    /// Output folder (default: out/<scene name>_converge).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

#[derive(Serialize, Clone, Debug)]
pub struct Check {
    pub p_crit: f64,
    /// Coordinates of the first failing node.
    pub node: [f64; 2],
    pub direction_deg: f64,
    pub wall_seconds: f64,
}

#[derive(Serialize, Clone, Debug)]
pub struct Explicit {
    /// Splits of the explicit run at 0.97 p_crit (0 expected) and 1.03 p_crit (> 0 expected).
    pub splits_below: usize,
    pub splits_above: usize,
    /// Split points of the run at 1.05 p_crit, in order.
    pub path: Vec<[f64; 2]>,
    pub wall_seconds: f64,
}

#[derive(Serialize, Clone, Debug)]
pub struct Ramp {
    /// Split points in order, and the factor on the first stage's levels at which each split.
    pub path: Vec<[f64; 2]>,
    pub path_factor: Vec<f64>,
    /// The highest ramp level (factor on the first stage's levels) whose stage came to rest.
    pub peak: f64,
    /// The first ramp level whose stage did not come to rest within its step limit (the crack
    /// ran through), if one did not.
    pub run_through: Option<f64>,
    pub wall_seconds: f64,
}

#[derive(Serialize, Clone, Debug)]
pub struct Level {
    /// Mean element edge length.
    pub h: f64,
    pub elements: usize,
    pub dofs: usize,
    pub mesh: String,
    /// The scene's check (nonlocal with a radius, else local): factor on the first stage's levels.
    pub p_crit: f64,
    pub node: [f64; 2],
    pub direction_deg: f64,
    pub wall_seconds: f64,
    /// The paper's corner-mean check.
    pub local: Check,
    /// Ours, with `radius`.
    pub nonlocal: Option<Check>,
    pub explicit: Option<Explicit>,
    /// With `--ramp-to`: the crack path and the peak load under a rising load.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ramp: Option<Ramp>,
    /// The statically determinate support the elastic solve added to a body without support
    /// under self-equilibrated loads (`flem_core::plugin::support`), one note per fragment.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub supports: Vec<String>,
    /// The dt rule on this level's mesh (a scene with a fixed dt keeps its dt/dt_crit).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dt_rule: Option<String>,
}

#[derive(Serialize)]
struct Report<'a> {
    scene: String,
    radius: Option<f64>,
    command: String,
    levels: &'a [Level],
}

/// The nonlocal settings that `flem converge` may override.
#[derive(Clone, Default)]
struct NlOpts {
    weight: Option<String>,
    exclusion: Option<f64>,
}

fn level_table(base: &toml::Table, level: usize, meshes: &[PathBuf], radius: Option<f64>, o: &NlOpts) -> Result<toml::Table> {
    let mut t = base.clone();
    let mesh = t.get_mut("mesh").and_then(|m| m.as_table_mut()).context("the scene has no [mesh] table")?;
    let kind = mesh.get("type").and_then(|v| v.as_str()).unwrap_or("").to_string();
    if !meshes.is_empty() {
        let f = &meshes[level];
        let abs = std::fs::canonicalize(f).with_context(|| format!("--meshes: {} cannot be read", f.display()))?;
        mesh.insert("file".into(), toml::Value::String(abs.display().to_string()));
    } else if kind == "rectangle" {
        crate::chart::refine_rectangle(&mut t, 1 << level)?;
    } else {
        bail!("the scene's mesh is of type \"{kind}\": give one mesh file per level with --meshes a.msh,b.msh,...");
    }
    let cr = t.get_mut("cracking").and_then(|c| c.as_table_mut()).context("the scene has no [cracking] table: there is no failure to converge")?;
    match radius {
        Some(r) => {
            // The scene's own nonlocal settings (weight, exclusion) are kept unless overridden.
            let mut nl = cr.get("nonlocal").and_then(|v| v.as_table()).cloned().unwrap_or_default();
            nl.insert("radius".into(), toml::Value::Float(r));
            if let Some(w) = &o.weight {
                nl.insert("weight".into(), toml::Value::String(w.clone()));
            }
            if let Some(x) = o.exclusion {
                nl.insert("exclusion".into(), toml::Value::Float(x));
            }
            cr.insert("nonlocal".into(), toml::Value::Table(nl));
        }
        None => {
            cr.remove("nonlocal");
        }
    }
    Ok(t)
}

/// The first stage alone, its levels times `factor`, no output.
fn scaled_first_stage(t: &toml::Table, factor: f64) -> Result<toml::Table> {
    let mut t = t.clone();
    let stages = t.get_mut("stage").and_then(|s| s.as_array_mut()).context("the scene has no [[stage]]")?;
    stages.truncate(1);
    let st = stages[0].as_table_mut().context("stage[0] is not a table")?;
    if let Some(lv) = st.get_mut("levels").and_then(|l| l.as_table_mut()) {
        for (_, v) in lv.iter_mut() {
            let x = v.as_float().or_else(|| v.as_integer().map(|i| i as f64)).context("a level is not a number")?;
            *v = toml::Value::Float(x * factor);
        }
    }
    t.remove("output");
    Ok(t)
}

fn build(scene: &Scene, t: &toml::Table) -> Result<Simulation> {
    let text = toml::to_string(t)?;
    let s = Scene::from_str(&text, &scene.path, &scene.base_dir)?;
    Ok(Simulation::new(s)?)
}

fn mean_edge(sim: &Simulation) -> f64 {
    let m = &sim.model.mesh;
    let (mut sum, mut n) = (0.0, 0usize);
    for c in &m.cells {
        let k = c.kind.nodes();
        for a in 0..k {
            let (p, q) = (m.points[c.nodes[a] as usize], m.points[c.nodes[(a + 1) % k] as usize]);
            sum += ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt();
            n += 1;
        }
    }
    sum / n.max(1) as f64
}

/// Refuses a scene whose load is not proportional to the levels or whose body is not linear.
fn proportional(scene: &Scene) -> Result<()> {
    if scene.file.model.gravity != [0.0; 2] {
        return Err(crate::unsuited(&scene.path, "converge", "model.gravity is not scaled by the load levels: the initiation load needs a load proportional to them"));
    }
    if let Some(i) = scene.file.materials.iter().position(|m| m.corotational) {
        return Err(crate::unsuited(&scene.path, "converge", format!("material[{i}] is co-rotational, not linear: the initiation load needs a linear body")));
    }
    for (i, l) in scene.file.loads.iter().enumerate() {
        if matches!(l, flem_core::scene::LoadCfg::Velocity { .. } | flem_core::scene::LoadCfg::Displacement { .. }) {
            return Err(crate::unsuited(&scene.path, "converge", format!("load[{i}] prescribes a velocity or displacement; the initiation load needs traction, pressure or point loads")));
        }
    }
    Ok(())
}

/// Elastic solve at the first stage's levels and the initiation of one check.
/// Also returns the notes of the statically determinate support the solve added, if any.
fn exact(scene: &Scene, t: &toml::Table) -> Result<(Initiation, Simulation, f64, Vec<String>)> {
    let t0 = Instant::now();
    let mut sim = build(scene, t)?;
    proportional(&sim.scene)?;
    sim.set_stage_levels(0);
    // A body without support under self-equilibrated loads (the paper's opening model) gets a
    // statically determinate support whose reactions are checked to vanish: said once per level.
    let sol = flem_plugins::check::static_solve_supported(&sim).map_err(|e| crate::unsuited(&scene.path, "converge", format!("the elastic solve at the first stage's levels is not possible: {e}")))?;
    let notes = sol.notes();
    for n in &notes {
        eprintln!("note: {n}");
    }
    let u1 = sol.u;
    let crit = &sim.scene.file.cracking.as_ref().context("no [cracking]")?.criterion;
    let cr = sim.cracking.as_mut().context("no [cracking]")?;
    let scale = cr.scale.clone();
    let init = initiation(crit.as_ref(), &scale, &sim.model, &u1, cr.nonlocal.as_mut())?;
    if !init.factor.is_finite() || init.factor <= 0.0 {
        return Err(crate::unsuited(&scene.path, "converge", "no node fails at any load factor up to 1e30 (or one fails at zero load): there is no initiation load"));
    }
    Ok((init, sim, t0.elapsed().as_secs_f64(), notes))
}

/// The ramp: the first stage's levels times `p f` for f = 1, 1 + step, ..., `to`, one stage
/// each, run in turn until one does not come to rest.
fn ramp(scene: &Scene, t: &toml::Table, p: f64, to: f64, step: f64, max_steps: u64) -> Result<Ramp> {
    let t0 = Instant::now();
    let mut t = scaled_first_stage(t, p)?;
    let first = t["stage"].as_array().context("no [[stage]]")?[0].as_table().context("stage[0] is not a table")?.clone();
    let mut stages = Vec::new();
    let mut factors = Vec::new();
    let n = ((to - 1.0) / step + 1e-9).floor().max(0.0) as usize;
    for k in 0..=n {
        let f = 1.0 + k as f64 * step;
        let mut st = first.clone();
        st.insert("name".into(), toml::Value::String(format!("ramp{k}")));
        st.insert("max_steps".into(), toml::Value::Integer(max_steps as i64));
        if let Some(lv) = st.get_mut("levels").and_then(|l| l.as_table_mut()) {
            for (_, v) in lv.iter_mut() {
                let x = v.as_float().context("a level is not a number")?;
                *v = toml::Value::Float(x * f);
            }
        }
        stages.push(toml::Value::Table(st));
        factors.push(p * f);
    }
    t.insert("stage".into(), toml::Value::Array(stages));
    let mut sim = build(scene, &t)?;
    let (mut path_factor, mut peak, mut run_through) = (Vec::new(), 0.0, None);
    for (i, &f) in factors.iter().enumerate() {
        sim.run_stage(i, &mut NoOutput)?;
        let n_cuts = sim.cracking.as_ref().map_or(0, |c| c.cuts.len());
        path_factor.resize(n_cuts, f);
        if sim.stages_done.last().is_some_and(|s| s.converged) {
            peak = f;
        } else {
            run_through = Some(f);
            break;
        }
    }
    let cr = sim.cracking.as_ref().context("no [cracking]")?;
    let path = cr.cuts.iter().map(|(c, _)| sim.model.mesh.points[sim.model.topo.cluster_point[*c as usize].idx()]).collect();
    Ok(Ramp { path, path_factor, peak, run_through, wall_seconds: t0.elapsed().as_secs_f64() })
}

fn explicit(scene: &Scene, t: &toml::Table, p: f64) -> Result<Explicit> {
    let t0 = Instant::now();
    let mut splits = [0usize; 2];
    for (k, f) in [0.97, 1.03].into_iter().enumerate() {
        let mut sim = build(scene, &scaled_first_stage(t, f * p)?)?;
        sim.run(&mut NoOutput)?;
        splits[k] = sim.cracking.as_ref().map_or(0, |c| c.n_splits);
    }
    let mut sim = build(scene, &scaled_first_stage(t, 1.05 * p)?)?;
    sim.run(&mut NoOutput)?;
    let cr = sim.cracking.as_ref().context("no [cracking]")?;
    let path = cr.cuts.iter().map(|(c, _)| sim.model.mesh.points[sim.model.topo.cluster_point[*c as usize].idx()]).collect();
    Ok(Explicit { splits_below: splits[0], splits_above: splits[1], path, wall_seconds: t0.elapsed().as_secs_f64() })
}

pub fn run(a: Args) -> Result<()> {
    anyhow::ensure!((1..=8).contains(&a.levels), "--levels = {} is incorrect; it must be in [1, 8]", a.levels);
    if !a.meshes.is_empty() && a.meshes.len() != a.levels {
        bail!("--meshes gives {} files for --levels {}: give one per level", a.meshes.len(), a.levels);
    }
    if let Some(r) = a.radius {
        anyhow::ensure!(r.is_finite() && r > 0.0, "--radius = {r} is incorrect; it must be finite and > 0");
    }
    if let Some(to) = a.ramp_to {
        anyhow::ensure!(to.is_finite() && (1.0..=100.0).contains(&to), "--ramp-to = {to} is incorrect; it must be in [1, 100]");
        anyhow::ensure!(
            a.ramp_step.is_finite() && a.ramp_step > 0.0 && (to - 1.0) / a.ramp_step <= 10_000.0,
            "--ramp-step = {} is incorrect; it must be > 0 and give at most 10000 stages",
            a.ramp_step
        );
    }
    anyhow::ensure!(a.ramp_max_steps >= 1, "--ramp-max-steps = 0 is incorrect; it must be >= 1");
    if let Some(x) = a.exclusion {
        anyhow::ensure!(x.is_finite() && x >= 0.0, "--exclusion = {x} is incorrect; it must be finite and >= 0");
    }
    let o = NlOpts { weight: a.weight.clone(), exclusion: a.exclusion };
    let scene = Scene::from_file(&a.scene)?;
    proportional(&scene)?;
    if scene.file.cracking.is_none() {
        return Err(crate::unsuited(&a.scene, "converge", "it finds the crack-initiation load, and the scene has no [cracking]"));
    }
    if a.radius.is_none() && scene.file.cracking.as_ref().is_some_and(|c| c.nonlocal.is_none()) {
        for (flag, given) in [("--weight", a.weight.is_some()), ("--exclusion", a.exclusion.is_some())] {
            anyhow::ensure!(!given, "{flag} sets the nonlocal check, which needs a radius: give --radius (the scene {} has no cracking.nonlocal)", a.scene.display());
        }
    }
    let text = std::fs::read_to_string(&a.scene)?;
    let base: toml::Table = toml::from_str(&text).context("the scene is not TOML")?;
    let kind = base.get("mesh").and_then(|m| m.get("type")).and_then(|v| v.as_str()).unwrap_or("");
    if a.meshes.is_empty() && kind != "rectangle" && a.levels > 1 {
        return Err(crate::unsuited(
            &a.scene,
            "converge",
            format!("its mesh (type \"{kind}\") is not a generated rectangle that can be refined: give one mesh file per level with --meshes a.msh,b.msh,..."),
        ));
    }
    let radius = a.radius.or(scene.file.cracking.as_ref().and_then(|c| c.nonlocal.map(|n| n.radius)));
    // The flags' values, checked before the first solve: every mesh file is readable, and the
    // nonlocal overrides give a valid scene (named by flag, not only by the scene's key).
    for f in &a.meshes {
        std::fs::metadata(f).with_context(|| format!("--meshes: {} cannot be read", f.display()))?;
    }
    if radius.is_some() {
        let tn = level_table(&base, 0, &a.meshes, radius, &o)?;
        Scene::from_str(&toml::to_string(&tn)?, &scene.path, &scene.base_dir).context("--radius, --weight or --exclusion give a scene that is refused")?;
    }
    let stem = a.scene.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "scene".into());
    let out = a.out.clone().unwrap_or_else(|| Path::new("out").join(format!("{stem}_converge")));
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut levels: Vec<Level> = Vec::new();
    let mut bounds = [[f64::INFINITY; 2], [f64::NEG_INFINITY; 2]];
    for lv in 0..a.levels {
        let mut tl = level_table(&base, lv, &a.meshes, None, &o)?;
        // A fixed dt keeps the scene's ratio dt/dt_crit on each finer mesh (the scene's own
        // dt on level 0).
        let dt = if lv > 0 || !a.meshes.is_empty() { crate::chart::keep_dt_ratio(&base, &mut tl, &scene)? } else { None };
        if let Some(m) = &dt {
            eprintln!("level {lv}: {m}");
        }
        let (li, sim, lw, supports) = exact(&scene, &tl)?;
        for p in &sim.model.mesh.points {
            for d in 0..2 {
                bounds[0][d] = bounds[0][d].min(p[d]);
                bounds[1][d] = bounds[1][d].max(p[d]);
            }
        }
        let local = Check { p_crit: li.factor, node: li.x, direction_deg: li.sigma1_deg, wall_seconds: lw };
        let (elements, dofs, h) = (sim.model.n_elems(), 2 * sim.model.topo.n_clusters(), mean_edge(&sim));
        drop(sim);
        let (nonlocal, tn) = match radius {
            Some(r) => {
                let mut tn = level_table(&base, lv, &a.meshes, Some(r), &o)?;
                if dt.is_some() {
                    crate::chart::keep_dt_ratio(&base, &mut tn, &scene)?;
                }
                let (ni, _, nw, _) = exact(&scene, &tn)?;
                (Some(Check { p_crit: ni.factor, node: ni.x, direction_deg: ni.sigma1_deg, wall_seconds: nw }), tn)
            }
            None => (None, tl),
        };
        let main = nonlocal.clone().unwrap_or_else(|| local.clone());
        let ex = if a.no_explicit { None } else { Some(explicit(&scene, &tn, main.p_crit)?) };
        let rp = match a.ramp_to {
            Some(to) => Some(ramp(&scene, &tn, main.p_crit, to, a.ramp_step, a.ramp_max_steps)?),
            None => None,
        };
        let mesh = if a.meshes.is_empty() { format!("rectangle x{}", 1 << lv) } else { a.meshes[lv].display().to_string() };
        eprintln!(
            "level {lv}: h = {h:.4}, {elements} elements: p_crit local {:.5} at ({:.3}, {:.3}), nonlocal {}{}",
            local.p_crit,
            local.node[0],
            local.node[1],
            nonlocal.as_ref().map_or("-".into(), |n| format!("{:.5} at ({:.3}, {:.3}) dir {:.1} deg", n.p_crit, n.node[0], n.node[1], n.direction_deg)),
            ex.as_ref().map_or(String::new(), |e| format!("; explicit splits at 0.97: {}, at 1.03: {}, path of {} splits at 1.05", e.splits_below, e.splits_above, e.path.len()))
        );
        if let Some(r) = &rp {
            eprintln!(
                "  ramp: peak {:.5} ({:.3} p_crit), {} splits{}",
                r.peak,
                r.peak / main.p_crit,
                r.path.len(),
                r.run_through.map_or(" (did not run through)".into(), |f| format!(", ran through at {f:.5}"))
            );
        }
        levels.push(Level {
            h,
            elements,
            dofs,
            mesh,
            p_crit: main.p_crit,
            node: main.node,
            direction_deg: main.direction_deg,
            wall_seconds: main.wall_seconds,
            local,
            nonlocal,
            explicit: ex,
            ramp: rp,
            supports,
            dt_rule: dt,
        });
    }
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    let rep = Report { scene: a.scene.display().to_string(), radius, command, levels: &levels };
    flem_core::output::atomic_write(&out.join("converge.json"), serde_json::to_string_pretty(&rep)?.as_bytes())?;
    let cl: Vec<flem_plot::charts::ConvergeLevel> = levels
        .iter()
        .map(|l| flem_plot::charts::ConvergeLevel {
            h: l.h,
            p_local: Some(l.local.p_crit),
            p_nonlocal: l.nonlocal.as_ref().map(|n| n.p_crit),
            path: l.ramp.as_ref().map(|r| r.path.clone()).or_else(|| l.explicit.as_ref().map(|e| e.path.clone())).unwrap_or_default(),
        })
        .collect();
    let title = format!("{stem}: crack initiation under refinement{}", radius.map_or(String::new(), |r| format!(" (R = {r})")));
    flem_plot::charts::converge(&out.join("converge"), &title, &cl, bounds)?;
    eprintln!("converge.json and converge.png/.svg in {}", out.display());
    Ok(())
}
