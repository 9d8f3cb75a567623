//! `flem chart SCENE`: the speed-accuracy chart (issue 9).
//!
//! The scene is run over a sweep of the explicit solver's knobs (damping scheme, dt safety
//! factor, equilibrium tolerance) and of mesh refinement (rectangle meshes: nx, ny times 1, 2,
//! 4). For every run: the wall time (model build + all stages) and its errors:
//! - `err_implicit`: relative L2 displacement error against the implicit solve on the same
//!   mesh and topology (what the explicit solver itself gets wrong);
//! - `err_reference`: against a reference, the implicit solve on a rectangle twice as fine as
//!   the finest of the sweep, compared at the points both meshes share (discretisation plus
//!   solver error; only for rectangle meshes and runs without splits);
//! - `err_analytic`: with `--analytic PROBE:x|y=VALUE`, the relative error of that probe's
//!   displacement component against the analytic value.
//!
//! With `--elements q4,qm6` the whole sweep runs once per element kind (set on every
//! `[[material]]`; column `element`, series prefixed by the kind).
//!
//! The implicit solves appear as their own points (method "implicit"). The Pareto front
//! (no other point both faster and more accurate) is marked over the chart's error, the first
//! of analytic, reference, implicit that exists. Written: chart.csv, chart.json (and the
//! pictures, see `plot`).
//!
//! How: the scene is edited as a TOML table (damping, `dt_safety`, tolerance, `nx`/`ny` x r),
//! each variant runs to equilibrium without output (`NoOutput`), the implicit solves are
//! `flem_plugins::check::static_solve`; for the refined reference (positions shared with the
//! coarse mesh) points with several clusters are skipped. Pictures by `flem_plot::charts`.
//!
//! A scene with a fixed `solver.dt` keeps its ratio dt/dt_crit on each refined mesh
//! ([`keep_dt_ratio`], printed). A body without support under self-equilibrated loads gets a
//! statically determinate support in the implicit solves (`flem_core::plugin::support`,
//! printed); its errors are then measured after removing the best-fit rigid motion.
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use flem_core::output::compare::rel_l2;
use flem_core::scene::Scene;
use flem_core::solver::{NoOutput, Simulation};
use serde::Serialize;

#[derive(Clone, Debug, Serialize)]
pub struct Point {
    pub method: String,
    /// Element kind set by `--elements` ("" = the scene's own).
    pub element: String,
    pub damping: String,
    pub dt_safety: f64,
    pub tolerance: f64,
    pub refine: usize,
    pub elements: usize,
    pub steps: u64,
    pub converged: bool,
    pub wall_seconds: f64,
    pub err_implicit: Option<f64>,
    pub err_reference: Option<f64>,
    pub err_analytic: Option<f64>,
    pub pareto: bool,
}

impl Point {
    /// The error the chart plots: analytic, else reference, else same-mesh implicit.
    pub fn error(&self) -> Option<f64> {
        self.err_analytic.or(self.err_reference).or(self.err_implicit)
    }
    pub fn error_kind(&self) -> &'static str {
        if self.err_analytic.is_some() {
            "analytic"
        } else if self.err_reference.is_some() {
            "reference"
        } else {
            "implicit"
        }
    }
}

/// An analytic value for one probe component.
#[derive(Clone, Debug)]
pub struct Analytic {
    pub probe: String,
    pub comp: usize,
    pub value: f64,
}

impl std::str::FromStr for Analytic {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let bad = || format!("--analytic {s:?} is incorrect; write PROBE:x=VALUE or PROBE:y=VALUE (a probe of [output] probes)");
        let (probe, rest) = s.split_once(':').ok_or_else(bad)?;
        let (c, v) = rest.split_once('=').ok_or_else(bad)?;
        let comp = match c {
            "x" => 0,
            "y" => 1,
            _ => return Err(bad()),
        };
        let value: f64 = v.trim().parse().map_err(|_| bad())?;
        if !value.is_finite() || value == 0.0 {
            return Err(format!("--analytic {s:?}: the value must be finite and non-zero (the error is relative)"));
        }
        Ok(Analytic { probe: probe.to_string(), comp, value })
    }
}

pub struct Sweep {
    pub dampings: Vec<&'static str>,
    pub safeties: Vec<f64>,
    pub tolerances: Vec<f64>,
    pub refines: Vec<usize>,
}

impl Sweep {
    pub fn full() -> Sweep {
        Sweep { dampings: vec!["adaptive", "local"], safeties: vec![0.5, 0.8, 0.95], tolerances: vec![1e-4, 1e-6, 1e-8], refines: vec![1, 2, 4] }
    }
    pub fn quick() -> Sweep {
        Sweep { dampings: vec!["adaptive", "local"], safeties: vec![0.8], tolerances: vec![1e-4, 1e-7], refines: vec![1, 2] }
    }
}

fn damping_table(name: &str) -> toml::Table {
    let mut t = toml::Table::new();
    t.insert("type".into(), toml::Value::String(name.into()));
    t
}

/// The scene text with the sweep's settings: damping, dt safety, tolerance (global and every
/// stage's), and rectangle refinement.
/// `dt`: the fixed step of a refined mesh by [`keep_dt_ratio`] (when the scene fixes dt and
/// `safety` is not swept).
fn variant(base: &toml::Table, element: Option<&str>, damping: Option<&str>, safety: Option<f64>, tol: Option<f64>, refine: usize, dt: Option<f64>) -> Result<String> {
    let mut t = base.clone();
    if let Some(e) = element {
        if let Some(toml::Value::Array(mats)) = t.get_mut("material") {
            for m in mats.iter_mut().filter_map(|m| m.as_table_mut()) {
                m.insert("element".into(), toml::Value::String(e.into()));
            }
        }
    }
    let solver = t.entry("solver").or_insert(toml::Value::Table(toml::Table::new())).as_table_mut().context("[solver] is not a table")?;
    if let Some(d) = damping {
        solver.insert("damping".into(), toml::Value::Table(damping_table(d)));
    }
    if let Some(s) = safety {
        solver.insert("dt_safety".into(), toml::Value::Float(s));
        solver.remove("dt");
    }
    if let Some(tol) = tol {
        solver.insert("tolerance".into(), toml::Value::Float(tol));
        if let Some(toml::Value::Array(stages)) = t.get_mut("stage") {
            for st in stages {
                if let Some(st) = st.as_table_mut() {
                    if st.contains_key("tolerance") {
                        st.insert("tolerance".into(), toml::Value::Float(tol));
                    }
                }
            }
        }
    }
    if refine > 1 {
        refine_rectangle(&mut t, refine as i64)?;
    }
    if let (Some(dt), None) = (dt, safety) {
        if let Some(s) = t.get_mut("solver").and_then(|s| s.as_table_mut()) {
            s.insert("dt".into(), toml::Value::Float(dt));
        }
    }
    Ok(toml::to_string(&t)?)
}

/// The critical step of the scene `t` (its `solver.dt` left out, so that any mesh builds).
fn dt_crit(t: &toml::Table, scene: &Scene) -> Result<f64> {
    let mut t = t.clone();
    if let Some(s) = t.get_mut("solver").and_then(|s| s.as_table_mut()) {
        s.remove("dt");
    }
    Ok(Simulation::new(load(&toml::to_string(&t)?, scene)?)?.stable.dt_crit)
}

/// The dt rule of the tools that change the mesh (`flem chart`, `flem converge`): a scene with a
/// fixed `solver.dt` keeps its ratio dt/dt_crit on a changed mesh, `dt' = dt dt_crit' / dt_crit`
/// (the scene's dt is kept as is on its own mesh). Sets `solver.dt` of `changed` and returns
/// the line that says so; `None` when the scene has no fixed dt (its `dt_safety` rules).
pub(crate) fn keep_dt_ratio(base: &toml::Table, changed: &mut toml::Table, scene: &Scene) -> Result<Option<String>> {
    let Some(dt) = base.get("solver").and_then(|s| s.get("dt")).and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64))) else { return Ok(None) };
    let (c0, c1) = (dt_crit(base, scene)?, dt_crit(changed, scene)?);
    let new = dt * c1 / c0;
    if let Some(s) = changed.get_mut("solver").and_then(|s| s.as_table_mut()) {
        s.insert("dt".into(), toml::Value::Float(new));
    }
    Ok(Some(format!("solver.dt = {dt:e} of the scene (dt/dt_crit = {:.4}) becomes {new:.4e} on this mesh (dt_crit {c1:.4e}): the same ratio dt/dt_crit", dt / c0)))
}

/// Multiplies a `rectangle` mesh's `nx` and `ny` by `factor` (the notch, if any, keeps its
/// size: it is given in lengths). Shared by `flem chart` and `flem converge`.
pub(crate) fn refine_rectangle(t: &mut toml::Table, factor: i64) -> Result<()> {
    let mesh = t.get_mut("mesh").and_then(|m| m.as_table_mut()).context("the scene has no [mesh] table")?;
    for k in ["nx", "ny"] {
        let n = mesh.get(k).and_then(|v| v.as_integer()).with_context(|| format!("mesh.{k} is missing"))?;
        mesh.insert(k.into(), toml::Value::Integer(n * factor));
    }
    // A graded rectangle: each zone's cells too (same lengths and end ratios; its grid lines
    // are then not those of the coarse mesh, so no reference error is measured on it).
    for k in ["grading_x", "grading_y"] {
        if let Some(toml::Value::Array(zones)) = mesh.get_mut(k) {
            for z in zones.iter_mut() {
                if let Some(c) = z.as_array_mut().and_then(|z| z.get_mut(1)) {
                    let n = c.as_integer().map(|i| i as f64).or_else(|| c.as_float()).with_context(|| format!("mesh.{k}: a zone's cells is not a number"))?;
                    *c = toml::Value::Integer(n as i64 * factor);
                }
            }
        }
    }
    Ok(())
}

fn is_rectangle(t: &toml::Table) -> bool {
    t.get("mesh").and_then(|m| m.get("type")).and_then(|v| v.as_str()) == Some("rectangle")
}

/// Reference field keyed by position (rounded), for comparison at shared points.
struct Reference {
    at: std::collections::BTreeMap<(i64, i64), [f64; 2]>,
    scale: f64,
    /// The reference body had no support (a statically determinate one was added): its
    /// displacement is defined up to a rigid motion, removed before comparing (`rigid_fit`).
    free: bool,
}

/// `mine` minus the rigid motion (translation and small rotation about the centroid) that fits
/// `mine - refs` best in the least-squares sense at the positions `x`
/// (`flem_core::plugin::support::align_rigid` on the points both meshes share).
fn rigid_fit(x: &[[f64; 2]], mine: &mut [[f64; 2]], refs: &[[f64; 2]]) {
    let n = x.len().max(1) as f64;
    let (mut xc, mut yc, mut dx, mut dy) = (0.0, 0.0, 0.0, 0.0);
    for i in 0..x.len() {
        xc += x[i][0] / n;
        yc += x[i][1] / n;
        dx += (mine[i][0] - refs[i][0]) / n;
        dy += (mine[i][1] - refs[i][1]) / n;
    }
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..x.len() {
        let (rx, ry) = (x[i][0] - xc, x[i][1] - yc);
        num += rx * (mine[i][1] - refs[i][1] - dy) - ry * (mine[i][0] - refs[i][0] - dx);
        den += rx * rx + ry * ry;
    }
    let th = if den > 0.0 { num / den } else { 0.0 };
    for i in 0..x.len() {
        let (rx, ry) = (x[i][0] - xc, x[i][1] - yc);
        mine[i][0] -= dx - th * ry;
        mine[i][1] -= dy + th * rx;
    }
}

impl Reference {
    fn key(x: [f64; 2], scale: f64) -> (i64, i64) {
        ((x[0] / scale * 1e9).round() as i64, (x[1] / scale * 1e9).round() as i64)
    }
    fn new(sim: &Simulation, u: &[[f64; 2]], free: bool) -> Reference {
        let scale = sim.x0.iter().fold(0.0f64, |m, x| m.max(x[0].abs()).max(x[1].abs())).max(f64::MIN_POSITIVE);
        let mut at = std::collections::BTreeMap::new();
        let mut twice = std::collections::BTreeSet::new();
        for (x, u) in sim.x0.iter().zip(u) {
            let k = Self::key(*x, scale);
            if at.insert(k, *u).is_some() {
                twice.insert(k);
            }
        }
        // Points with several clusters (pre-separated edges) are left out: which of them is
        // which is not defined across meshes.
        for k in twice {
            at.remove(&k);
        }
        Reference { at, scale, free }
    }
    /// Relative L2 error of `u` at the points of `sim` found (once) in the reference; every
    /// point of `sim` with one cluster must be found (a refinement of the reference's mesh).
    fn error(&self, sim: &Simulation) -> Option<f64> {
        let topo = &sim.model.topo;
        let (mut mine, mut refs, mut xs) = (Vec::new(), Vec::new(), Vec::new());
        for (c, (x, u)) in sim.x0.iter().zip(&sim.state.u).enumerate() {
            if topo.point_clusters[topo.cluster_point[c].idx()].len() > 1 {
                continue;
            }
            match self.at.get(&Self::key(*x, self.scale)) {
                Some(r) => {
                    mine.push(*u);
                    refs.push(*r);
                    xs.push(*x);
                }
                None => return None,
            }
        }
        if self.free {
            rigid_fit(&xs, &mut mine, &refs);
        }
        if mine.is_empty() {
            None
        } else {
            rel_l2(&mine, &refs)
        }
    }
}

/// The cluster of a probe (the same point the output writer's history follows).
fn probe_index(sim: &Simulation, name: &str) -> Result<usize> {
    let p = sim.scene.file.output.probes.iter().find(|p| p.name == name).with_context(|| format!("--analytic: no probe {name:?} in [output] probes of the scene"))?;
    Ok(sim.model.topo.point_clusters[flem_core::output::nearest_point(sim, p.at)][0].idx())
}

fn load(text: &str, scene: &Scene) -> Result<Scene> {
    Ok(Scene::from_str(text, &scene.path, &scene.base_dir)?)
}

/// Runs the sweep; progress lines on stderr.
#[allow(clippy::too_many_arguments)]
pub fn sweep(scene: &Scene, text: &str, sweep: &Sweep, analytic: Option<&Analytic>, stages: Option<usize>, no_cracking: bool, elements: &[String], max_steps: Option<u64>) -> Result<Vec<Point>> {
    let mut base: toml::Table = toml::from_str(text).context("the scene is not TOML")?;
    if no_cracking {
        // The elastic problem of a cracking scene (pre-separated edges stay separated).
        base.remove("cracking");
    }
    if let Some(k) = stages {
        // Only the first k stages (e.g. the elastic stage of a cracking scene).
        if let Some(toml::Value::Array(st)) = base.get_mut("stage") {
            anyhow::ensure!(k >= 1 && k <= st.len(), "--stages {k}: the scene has {} stages", st.len());
            st.truncate(k);
        }
    }
    let rect = is_rectangle(&base);
    let refines: Vec<usize> = if rect { sweep.refines.clone() } else { vec![1] };
    // A scene with a fixed dt keeps its ratio dt/dt_crit on each refined mesh (the runs of the
    // sweep set dt_safety themselves; this is for the implicit points and the reference, whose
    // scene must still pass the stable-step check).
    let mut dts = std::collections::BTreeMap::new();
    for r in refines.iter().copied().chain([refines.iter().max().copied().unwrap_or(1) * 2]).filter(|&r| rect && r > 1) {
        let mut t = base.clone();
        refine_rectangle(&mut t, r as i64)?;
        if let Some(msg) = keep_dt_ratio(&base, &mut t, scene)? {
            eprintln!("refinement x{r}: {msg}");
            dts.insert(r, t["solver"]["dt"].as_float());
        }
    }
    let dt = |r: usize| dts.get(&r).copied().flatten();
    let reference = if rect {
        let finest = refines.iter().max().copied().unwrap_or(1) * 2;
        let s = load(&variant(&base, None, None, None, None, finest, dt(finest))?, scene)?;
        let mut sim = Simulation::new(s)?;
        // Static reference: the load levels of the last stage, no explicit steps.
        sim.set_stage_levels(sim.scene.file.stages.len() - 1);
        let sol = flem_plugins::check::static_solve_supported(&sim)
            .map_err(|e| crate::unsuited(&scene.path, "chart", format!("the implicit solve at the last stage's levels, the chart's reference, is not possible: {e}")))?;
        eprintln!("reference: implicit solve on {} elements (refinement x{finest})", sim.model.n_elems());
        for n in sol.notes() {
            eprintln!("  {n}; its rigid motion is removed from every error against it");
        }
        Some(Reference::new(&sim, &sol.u, !sol.added.is_empty()))
    } else {
        None
    };
    let mut pts = Vec::new();
    let elems: Vec<Option<&str>> = if elements.is_empty() { vec![None] } else { elements.iter().map(|e| Some(e.as_str())).collect() };
    for (&el, &r) in elems.iter().flat_map(|e| refines.iter().map(move |r| (e, r))) {
        let ename = el.unwrap_or_default().to_string();
        // The implicit solve as its own point.
        let s = load(&variant(&base, el, None, None, None, r, dt(r))?, scene)?;
        let t0 = Instant::now();
        let mut sim = Simulation::new(s)?;
        sim.set_stage_levels(sim.scene.file.stages.len() - 1);
        let sol = flem_plugins::check::static_solve_supported(&sim)
            .map_err(|e| crate::unsuited(&scene.path, "chart", format!("the implicit solve at the last stage's levels, the chart's reference, is not possible: {e}")))?;
        let wall = t0.elapsed().as_secs_f64();
        for n in sol.notes() {
            eprintln!("implicit x{r}: {n}; the explicit runs are compared after removing their best-fit rigid motion");
        }
        sim.state.u = sol.u.clone();
        let (implicit_u, implicit_added) = (sol.u, sol.added);
        let err_ref = reference.as_ref().and_then(|rf| rf.error(&sim));
        let err_an = match analytic {
            Some(a) => Some((sim.state.u[probe_index(&sim, &a.probe)?][a.comp] - a.value).abs() / a.value.abs()),
            None => None,
        };
        pts.push(Point {
            method: "implicit".into(),
            element: ename.clone(),
            damping: "-".into(),
            dt_safety: 0.0,
            tolerance: 0.0,
            refine: r,
            elements: sim.model.n_elems(),
            steps: 0,
            converged: true,
            wall_seconds: wall,
            err_implicit: Some(0.0),
            err_reference: err_ref,
            err_analytic: err_an,
            pareto: false,
        });
        for &d in &sweep.dampings {
            for &sf in &sweep.safeties {
                for &tol in &sweep.tolerances {
                    let mut s = load(&variant(&base, el, Some(d), Some(sf), Some(tol), r, None)?, scene)?;
                    crate::cap_steps(&mut s, max_steps);
                    let t0 = Instant::now();
                    let mut sim = Simulation::new(s)?;
                    sim.run(&mut NoOutput)?;
                    let wall = t0.elapsed().as_secs_f64();
                    let steps: u64 = sim.stages_done.iter().map(|s| s.steps).sum();
                    let converged = sim.stages_done.iter().all(|s| s.converged);
                    let split = sim.cracking.as_ref().is_some_and(|c| c.n_splits > 0);
                    // Against the implicit solve of the same model; a body given a statically
                    // determinate support: that solve shifted by its best-fit rigid motion.
                    let err_imp = if split {
                        flem_plugins::check::static_solve_supported(&sim).ok().and_then(|mut so| {
                            flem_core::plugin::support::align_rigid(&sim.model, &so.added, &sim.state.u, &mut so.u);
                            rel_l2(&sim.state.u, &so.u)
                        })
                    } else {
                        let mut ui = implicit_u.clone();
                        flem_core::plugin::support::align_rigid(&sim.model, &implicit_added, &sim.state.u, &mut ui);
                        rel_l2(&sim.state.u, &ui)
                    };
                    let err_ref = if split { None } else { reference.as_ref().and_then(|rf| rf.error(&sim)) };
                    let err_an = match analytic {
                        Some(a) => Some((sim.state.u[probe_index(&sim, &a.probe)?][a.comp] - a.value).abs() / a.value.abs()),
                        None => None,
                    };
                    let p = Point {
                        method: "explicit".into(),
                        element: ename.clone(),
                        damping: d.into(),
                        dt_safety: sf,
                        tolerance: tol,
                        refine: r,
                        elements: sim.model.n_elems(),
                        steps,
                        converged,
                        wall_seconds: wall,
                        err_implicit: err_imp,
                        err_reference: err_ref,
                        err_analytic: err_an,
                        pareto: false,
                    };
                    eprintln!("{ename} x{r} {d:<8} safety {sf:<4} tol {tol:.0e}: {steps:>8} steps {wall:>8.3} s  error {:.3e} ({})", p.error().unwrap_or(f64::NAN), p.error_kind());
                    pts.push(p);
                }
            }
        }
    }
    mark_pareto(&mut pts);
    Ok(pts)
}

/// Marks the points no other point beats on both wall time and error.
pub fn mark_pareto(pts: &mut [Point]) {
    let key: Vec<Option<(f64, f64)>> = pts.iter().map(|p| p.error().map(|e| (p.wall_seconds, e))).collect();
    for i in 0..pts.len() {
        let Some((ti, ei)) = key[i] else { continue };
        pts[i].pareto = !key.iter().enumerate().any(|(j, k)| j != i && k.is_some_and(|(tj, ej)| tj <= ti && ej <= ei && (tj < ti || ej < ei)));
    }
}

pub fn csv(pts: &[Point]) -> String {
    let f = |x: Option<f64>| x.map(|v| format!("{v:e}")).unwrap_or_default();
    let mut s = String::from("method,damping,dt_safety,tolerance,refine,elements,steps,converged,wall_seconds,err_implicit,err_reference,err_analytic,pareto,element\n");
    for p in pts {
        s += &format!(
            "{},{},{},{:e},{},{},{},{},{:e},{},{},{},{},{}\n",
            p.method,
            p.damping,
            p.dt_safety,
            p.tolerance,
            p.refine,
            p.elements,
            p.steps,
            p.converged,
            p.wall_seconds,
            f(p.err_implicit),
            f(p.err_reference),
            f(p.err_analytic),
            p.pareto,
            p.element
        );
    }
    s
}

/// `flem chart`: sweep, then chart.csv, chart.json and the pictures into `out`.
#[allow(clippy::too_many_arguments)]
pub fn chart(scene_path: &Path, out: Option<PathBuf>, quick: bool, analytic: Option<Analytic>, stages: Option<usize>, no_cracking: bool, elements: &[String], max_steps: Option<u64>) -> Result<()> {
    let text = std::fs::read_to_string(scene_path).with_context(|| format!("{}: cannot be read", scene_path.display()))?;
    let scene = Scene::from_file(scene_path)?;
    if let Some(a) = &analytic {
        if !scene.file.output.probes.iter().any(|p| p.name == a.probe) {
            bail!("{}: --analytic names probe {:?}, but [output] probes has {:?}", scene_path.display(), a.probe, scene.file.output.probes.iter().map(|p| &p.name).collect::<Vec<_>>());
        }
    }
    let stem = scene_path.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "scene".into());
    let out = out.unwrap_or_else(|| PathBuf::from("out").join(format!("{stem}_chart")));
    let _lock = crate::lock_out(&out)?;
    flem_core::output::prepare_dir(&out)?;
    let sw = if quick { Sweep::quick() } else { Sweep::full() };
    let pts = sweep(&scene, &text, &sw, analytic.as_ref(), stages, no_cracking, elements, max_steps)?;
    flem_core::output::atomic_write(&out.join("chart.csv"), csv(&pts).as_bytes())?;
    flem_core::output::atomic_write(&out.join("chart.json"), serde_json::to_string_pretty(&pts)?.as_bytes())?;
    let kind = pts.iter().find(|p| p.method == "explicit").map_or("implicit", |p| p.error_kind());
    let label = match kind {
        "analytic" => "relative error vs analytic (dimensionless)",
        "reference" => "rel. L2 error vs refined implicit (dimensionless)",
        _ => "rel. L2 error vs implicit, same mesh (dimensionless)",
    };
    let cp: Vec<flem_plot::charts::ChartPoint> = pts.iter().filter_map(|p| p.error().map(|e| chart_point(p, e))).collect();
    flem_plot::charts::speed_accuracy(&out.join("chart"), &format!("speed vs accuracy: {}", scene.file.title), label, &cp)?;
    // The explicit solver's own error: against the implicit solve of the same mesh.
    let mut solver: Vec<Point> = pts
        .iter()
        .filter(|p| p.method == "explicit" && p.err_implicit.is_some())
        .cloned()
        .map(|mut p| {
            (p.err_analytic, p.err_reference) = (None, None);
            p
        })
        .collect();
    mark_pareto(&mut solver);
    let cp2: Vec<flem_plot::charts::ChartPoint> = solver.iter().map(|p| chart_point(p, p.err_implicit.unwrap_or(f64::NAN))).collect();
    flem_plot::charts::speed_accuracy(&out.join("chart_solver"), &format!("explicit solver error: {}", scene.file.title), "rel. L2 error vs implicit, same mesh (dimensionless)", &cp2)?;
    eprintln!("{} points ({} on the Pareto front); chart.csv, chart.json, chart.png/svg, chart_solver.png/svg in {}", pts.len(), pts.iter().filter(|p| p.pareto).count(), out.display());
    Ok(())
}

/// A point of the pictures: colour = method ("implicit (faer)", "explicit adaptive", ...),
/// marker shape = mesh refinement ("x1", "x2"), marker fill = element kind (`--elements`).
pub fn chart_point(p: &Point, error: f64) -> flem_plot::charts::ChartPoint {
    let method = if p.method == "implicit" { "implicit (faer)".to_string() } else { format!("{} {}", p.method, p.damping) };
    flem_plot::charts::ChartPoint { method, element: p.element.clone(), mesh: format!("x{}", p.refine), wall_seconds: p.wall_seconds, error, pareto: p.pareto }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The series of `flem chart --elements q4,qm6` over the full sweep (implicit and both
    /// damping schemes, meshes x1 x2 x4, two element kinds): every series is drawn in its own
    /// style (colour, shape, fill) and has its own legend entry; colour follows the method only,
    /// shape the mesh only, fill the element kind only (issue 40).
    #[test]
    fn chart_series_are_told_apart() {
        let sw = Sweep::full();
        let mut pts = Vec::new();
        for el in ["q4", "qm6"] {
            for &r in &sw.refines {
                let p = |method: &str, damping: &str| Point {
                    method: method.into(),
                    element: el.into(),
                    damping: damping.into(),
                    dt_safety: 0.8,
                    tolerance: 1e-6,
                    refine: r,
                    elements: 40,
                    steps: 10,
                    converged: true,
                    wall_seconds: 0.1,
                    err_implicit: Some(0.1),
                    err_reference: None,
                    err_analytic: None,
                    pareto: false,
                };
                pts.push(p("implicit", "-"));
                for d in &sw.dampings {
                    pts.push(p("explicit", d));
                }
            }
        }
        let cp: Vec<_> = pts.iter().map(|p| chart_point(p, 0.1)).collect();
        let st = flem_plot::charts::series_styles(&cp).unwrap();
        assert_eq!(st.len(), 2 * sw.refines.len() * (1 + sw.dampings.len()));
        for (i, a) in st.iter().enumerate() {
            for b in &st[i + 1..] {
                assert!((a.colour, a.shape, a.fill) != (b.colour, b.shape, b.fill), "{} and {} are drawn alike", a.label, b.label);
                assert_ne!(a.label, b.label);
                assert_eq!(a.colour == b.colour, a.method == b.method, "colour is the method: {} / {}", a.label, b.label);
                assert_eq!(a.shape == b.shape, a.mesh == b.mesh, "shape is the mesh: {} / {}", a.label, b.label);
                assert_eq!(a.fill == b.fill, a.element == b.element, "fill is the element kind: {} / {}", a.label, b.label);
            }
        }
    }
}
