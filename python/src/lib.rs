//! `flem._native`: the Rust side of the Python package `flem` (python/flem/__init__.py is the
//! public face; docs/python.md). Scenes travel as TOML text with their path (for messages) and
//! folder (for relative paths): a `flem.Scene` is that text, validated here by the same
//! `Scene::from_str` as the CLI, so its errors are the CLI's messages (raised as
//! `flem.SceneError`). A run happens with the GIL released (`Python::detach`), in a folder,
//! through the CLI's own `flem_core::output::run::run_in_folder`; its observer re-attaches
//! every 20 ms of wall time to run `Python::check_signals` (Ctrl-C: the run stops after the
//! step, writes a checkpoint and an "interrupted" snapshot as `flem run` does, and
//! `flem.RunInterrupted`, a `KeyboardInterrupt`, is raised) and at the end of each stage to call
//! the stage callback. The arrays come from `flem_core::output::arrays::result_arrays`, the
//! function the VTU writer uses: they equal the last snapshot's arrays bit for bit.
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use flem_core::output::arrays::{result_arrays, ResultArrays};
use flem_core::output::run::{resume, run_in_folder};
use flem_core::output::sweep::{json_to_toml, run_task as core_run_task, scene_with};
use flem_core::output::OutputWriter;
use flem_core::scene::Scene;
use flem_core::solver::{Observer, Progress, Simulation, StagePos};
use flem_core::FlemError;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// How often a run re-attaches to Python to check for signals (Ctrl-C).
const SIGNAL_EVERY: Duration = Duration::from_millis(20);

/// An error of the core as a Python exception: a scene error as `flem.SceneError(message,
/// file, key)`, anything else as `flem.FlemError` (a RuntimeError), message as the CLI prints it.
fn to_py(py: Python<'_>, e: FlemError) -> PyErr {
    let msg = e.to_string();
    let (class, args) = match &e {
        FlemError::Config { file, key, .. } => ("SceneError", (msg, file.clone(), key.clone())),
        FlemError::Mesh { file, .. } => ("SceneError", (msg, file.clone(), String::new())),
        _ => ("FlemError", (msg, String::new(), String::new())),
    };
    match py.import("flem._errors").and_then(|m| m.getattr(class)).and_then(|c| c.call1(args.clone())) {
        Ok(v) => PyErr::from_value(v),
        Err(_) if class == "SceneError" => PyValueError::new_err(args.0),
        Err(_) => PyRuntimeError::new_err(args.0),
    }
}

fn paths(path: &str, base: &str) -> (PathBuf, PathBuf) {
    (PathBuf::from(path), PathBuf::from(base))
}

/// Validates scene text as `flem run` would (a 3D scene as one); raises SceneError with the
/// CLI's message.
#[pyfunction]
fn scene_check(py: Python<'_>, text: &str, path: &str, base: &str) -> PyResult<()> {
    let (p, b) = paths(path, base);
    if flem_core::scene3::scene_dim(text) == 3 {
        return flem_core::scene3::Scene3::from_str(text, &p, &b).map(|_| ()).map_err(|e| to_py(py, e));
    }
    Scene::from_str(text, &p, &b).map(|_| ()).map_err(|e| to_py(py, e))
}

/// The scene text with `key` (a key path, e.g. "cracking.criterion.tensile_strength" or
/// "material[0].young_modulus") set to `value_json` (a JSON value), validated.
#[pyfunction]
fn scene_set(py: Python<'_>, text: &str, path: &str, base: &str, key: &str, value_json: &str) -> PyResult<String> {
    let (p, b) = paths(path, base);
    let v: serde_json::Value = serde_json::from_str(value_json).map_err(|e| PyValueError::new_err(format!("{key}: the value is not JSON: {e}")))?;
    let v = json_to_toml(&v).map_err(|m| to_py(py, FlemError::config(path, key, m)))?;
    scene_with(text, &p, &b, &[(key.to_string(), v)]).map(|(t, _)| t).map_err(|e| to_py(py, e))
}

/// TOML text of a scene given as JSON (a dict from Python), validated.
#[pyfunction]
fn scene_from_json(py: Python<'_>, json: &str, path: &str, base: &str) -> PyResult<String> {
    let v: serde_json::Value = serde_json::from_str(json).map_err(|e| PyValueError::new_err(format!("the scene dict is not JSON-like: {e}")))?;
    let t = json_to_toml(&v).map_err(|m| to_py(py, FlemError::config(path, "", m)))?;
    let text = toml::to_string(&t).map_err(|e| to_py(py, FlemError::config(path, "", format!("is not a table of TOML values: {e}"))))?;
    scene_check(py, &text, path, base)?;
    Ok(text)
}

/// The scene as JSON (all TOML values have one).
#[pyfunction]
fn scene_to_json(text: &str) -> PyResult<String> {
    let t: toml::Table = toml::from_str(text).map_err(|e| PyValueError::new_err(e.to_string()))?;
    serde_json::to_string(&t).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// The scene with every default filled in (scene.resolved.toml of a run).
#[pyfunction]
fn scene_resolved(py: Python<'_>, text: &str, path: &str, base: &str) -> PyResult<String> {
    let (p, b) = paths(path, base);
    Scene::from_str(text, &p, &b).map(|s| s.resolved_toml()).map_err(|e| to_py(py, e))
}

/// The observer of a Python run: signals, stage and progress callbacks.
struct PyObserver {
    on_stage: Option<Py<PyAny>>,
    on_progress: Option<Py<PyAny>>,
    progress_every: Duration,
    last_signal: Instant,
    last_progress: Option<Instant>,
    /// The first Python error (KeyboardInterrupt, a callback's exception): stops the run.
    err: Option<PyErr>,
}

impl Observer for PyObserver {
    fn stage_end(&mut self, sim: &Simulation, stage: usize) -> flem_core::Result<()> {
        let (Some(cb), None) = (&self.on_stage, &self.err) else { return Ok(()) };
        let Some(s) = sim.stages_done.last() else { return Ok(()) };
        let info = serde_json::json!({
            "stage": stage, "name": s.name, "steps": s.steps, "converged": s.converged, "final_ratio": s.final_ratio,
            "wall_seconds": s.wall_seconds, "time": s.time, "splits": s.splits, "energy_residual": s.energy_residual,
            "total_splits": sim.cracking.as_ref().map_or(0, |c| c.n_splits), "levels": sim.levels,
        })
        .to_string();
        let r = Python::attach(|py| -> PyResult<()> {
            let d = py.import("json")?.call_method1("loads", (info,))?;
            cb.call1(py, (d,))?;
            Ok(())
        });
        if let Err(e) = r {
            self.err = Some(e);
        }
        Ok(())
    }

    fn progress(&mut self, p: &Progress) {
        let (Some(cb), None) = (&self.on_progress, &self.err) else { return };
        if self.last_progress.is_some_and(|t| t.elapsed() < self.progress_every) {
            return;
        }
        self.last_progress = Some(Instant::now());
        let r = Python::attach(|py| -> PyResult<()> {
            let d = PyDict::new(py);
            d.set_item("stage", p.stage)?;
            d.set_item("n_stages", p.n_stages)?;
            d.set_item("step", p.step)?;
            d.set_item("stage_step", p.stage_step)?;
            d.set_item("max_steps", p.max_steps)?;
            d.set_item("ratio", p.ratio)?;
            d.set_item("tolerance", p.tolerance)?;
            cb.call1(py, (d,))?;
            Ok(())
        });
        if let Err(e) = r {
            self.err = Some(e);
        }
    }

    fn should_stop(&mut self, _sim: &Simulation) -> bool {
        if self.err.is_none() && self.last_signal.elapsed() >= SIGNAL_EVERY {
            self.last_signal = Instant::now();
            if let Err(e) = Python::attach(|py| py.check_signals()) {
                self.err = Some(e);
            }
        }
        self.err.is_some()
    }
}

/// What a detached run hands back.
struct Outcome {
    result: flem_core::Result<()>,
    arrays: Option<ResultArrays>,
    compare: Vec<flem_core::output::compare::StageComparison>,
    last_checkpoint: Option<PathBuf>,
    warnings: Vec<String>,
}

fn run_detached(text: &str, path: &Path, base: &Path, out: &Path, threads: Option<usize>, resume_dir: Option<&Path>, obs: &mut PyObserver) -> flem_core::Result<Outcome> {
    let t0 = Instant::now();
    let mut scene = Scene::from_str(text, path, base)?;
    if let Some(t) = threads {
        scene.file.solver.threads = t;
    }
    let _lock = flem_core::output::lock::lock_dir(out, &format!("python flem.run (process {})", std::process::id()))?;
    flem_core::output::prepare_dir(out)?;
    let mut sim = Simulation::new(scene)?;
    let mut w = OutputWriter::new(out, &sim)?;
    let mut pos = StagePos::start(0);
    let mut warnings = Vec::new();
    if let Some(dir) = resume_dir {
        let (p, _, refused) = resume(&mut sim, &mut w, dir)?;
        warnings.extend(refused);
        pos = p;
    }
    let end = run_in_folder(&mut sim, &mut w, pos, obs, t0);
    warnings.extend(sim.warnings.iter().cloned());
    let arrays = end.result.is_ok().then(|| result_arrays(&sim));
    Ok(Outcome { result: end.result, arrays, compare: end.compare_rows, last_checkpoint: w.last_checkpoint.clone(), warnings })
}

fn arr2<'py, const N: usize>(py: Python<'py>, v: &[[f64; N]]) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_vec(py, v.as_flattened().to_vec()).reshape([v.len(), N])?.into_any())
}

fn arrays_dict<'py>(py: Python<'py>, r: &ResultArrays) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("points", arr2(py, &r.points)?)?;
    d.set_item("point_id", PyArray1::from_vec(py, r.point_id.iter().map(|&x| x as i64).collect()))?;
    d.set_item("clusters", PyArray1::from_vec(py, r.clusters.iter().map(|&x| x as i64).collect()))?;
    d.set_item("copy_offsets", PyArray1::from_vec(py, r.copy_offsets.iter().map(|&x| x as i64).collect()))?;
    // Element connectivity by kind (meshio's cells_dict names), elements in order within a kind.
    let cells = PyDict::new(py);
    for (kind, name, n) in [(flem_core::mesh::CellKind::Q4, "quad", 4usize), (flem_core::mesh::CellKind::T3, "triangle", 3)] {
        let mut conn = Vec::new();
        for (e, k) in r.kinds.iter().enumerate() {
            if *k == kind {
                let (a, b) = (r.copy_offsets[e] as usize, r.copy_offsets[e + 1] as usize);
                conn.extend(r.clusters[a..b].iter().map(|&c| c as i64));
            }
        }
        if !conn.is_empty() {
            let m = conn.len() / n;
            cells.set_item(name, PyArray1::from_vec(py, conn).reshape([m, n])?)?;
        }
    }
    d.set_item("cells", cells)?;
    d.set_item("cell_kinds", PyList::new(py, r.kinds.iter().map(|k| if *k == flem_core::mesh::CellKind::Q4 { "quad" } else { "triangle" }))?)?;
    d.set_item("region", PyArray1::from_vec(py, r.region.clone()))?;
    d.set_item("elem_stress", arr2(py, &r.elem_stress)?)?;
    let faces: Vec<i64> = r.crack_faces.iter().flat_map(|f| f.map(|c| c as i64)).collect();
    d.set_item("crack_faces", PyArray1::from_vec(py, faces).reshape([r.crack_faces.len(), 2])?)?;
    d.set_item("crack_state", PyArray1::from_vec(py, r.crack_state.iter().map(|&x| x as i32).collect()))?;
    d.set_item("displacement", arr2(py, &r.displacement)?)?;
    d.set_item("velocity", arr2(py, &r.velocity)?)?;
    d.set_item("mass", PyArray1::from_vec(py, r.mass.clone()))?;
    d.set_item("nodal_stress", arr2(py, &r.nodal_stress)?)?;
    match &r.failure_index {
        Some(f) => d.set_item("failure_index", PyArray1::from_vec(py, f.clone()))?,
        None => d.set_item("failure_index", py.None())?,
    }
    Ok(d)
}

/// A 3D scene's run (`[model] dim = 3`, `output::run3`) in `out`: its arrays.
/// With `resume`, the run continues from the newest valid checkpoint in `out`
/// (`output::checkpoint3`); its `[check]` rows are `compare.json`'s.
fn run3_detached(text: &str, path: &Path, base: &Path, out: &Path, resume: bool) -> flem_core::Result<(flem_core::output::run3::Arrays3, Vec<String>, String)> {
    let mut scene = flem_core::scene3::Scene3::from_str(text, path, base)?;
    let _lock = flem_core::output::lock::lock_dir(out, &format!("python flem.run (process {})", std::process::id()))?;
    flem_core::output::prepare_dir(out)?;
    let (m, _) = flem_core::output::run3::run3_with(&mut scene, out, resume, None)?;
    let compare = match scene.file.check {
        Some(_) => {
            std::fs::read_to_string(out.join("compare.json")).ok().and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok()).map_or_else(|| "[]".to_string(), |v| v["stages"].to_string())
        }
        None => "[]".to_string(),
    };
    Ok((flem_core::output::run3::arrays3(&m), m.warnings.clone(), compare))
}

/// The arrays of a 3D run (docs/python.md "3D runs"): `dim` = 3, points, displacement and
/// velocity (n, 3), nodal_stress (n, 6) `[xx, yy, zz, xy, yz, zx]`, cells on clusters
/// (`tetra` (m, 4), `hexahedron` (m, 8)), elem_stress (nelems, 6), crack_faces (nf, 2): the two
/// elements of each separated face.
fn arrays3_dict<'py>(py: Python<'py>, r: &flem_core::output::run3::Arrays3) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("dim", 3)?;
    d.set_item("points", arr2(py, &r.points)?)?;
    d.set_item("point_id", PyArray1::from_vec(py, r.point_id.iter().map(|&x| x as i64).collect()))?;
    let cells = PyDict::new(py);
    for (kind, name, n) in [(flem_core::mesh::CellKind3::T4, "tetra", 4usize), (flem_core::mesh::CellKind3::H8, "hexahedron", 8)] {
        let conn: Vec<i64> = r.cells.iter().filter(|c| c.kind == kind).flat_map(|c| c.corners().iter().map(|&p| p as i64)).collect();
        if !conn.is_empty() {
            let m = conn.len() / n;
            cells.set_item(name, PyArray1::from_vec(py, conn).reshape([m, n])?)?;
        }
    }
    d.set_item("cells", cells)?;
    d.set_item("cell_kinds", PyList::new(py, r.cells.iter().map(|c| if c.kind == flem_core::mesh::CellKind3::T4 { "tetra" } else { "hexahedron" }))?)?;
    d.set_item("region", PyArray1::from_vec(py, r.region.clone()))?;
    d.set_item("displacement", arr2(py, &r.displacement)?)?;
    d.set_item("velocity", arr2(py, &r.velocity)?)?;
    d.set_item("mass", PyArray1::from_vec(py, r.mass.clone()))?;
    d.set_item("nodal_stress", arr2(py, &r.nodal_stress)?)?;
    d.set_item("elem_stress", arr2(py, &r.elem_stress)?)?;
    d.set_item("fragment", PyArray1::from_vec(py, r.fragment.iter().map(|&x| x as i64).collect()))?;
    let faces: Vec<i64> = r.crack_faces.iter().flat_map(|f| f.map(|c| c as i64)).collect();
    d.set_item("crack_faces", PyArray1::from_vec(py, faces).reshape([r.crack_faces.len(), 2])?)?;
    d.set_item("crack_state", PyArray1::from_vec(py, r.crack_state.iter().map(|&x| x as i32).collect()))?;
    d.set_item("failure_index", py.None())?;
    Ok(d)
}

/// Runs a scene into `out` with the GIL released. Returns a dict: `arrays` (numpy arrays of the
/// final state), `compare` (JSON rows of a `[check]` scene), `warnings`. Raises SceneError or
/// FlemError as the CLI would stop, `flem.RunInterrupted` (a KeyboardInterrupt) after Ctrl-C
/// with the checkpoint written, and a callback's own exception (the run stopped the same way).
#[pyfunction]
#[pyo3(signature = (text, path, base, out, threads=None, resume=None, on_stage=None, on_progress=None, progress_every=0.2))]
#[allow(clippy::too_many_arguments)]
fn run<'py>(
    py: Python<'py>,
    text: &str,
    path: &str,
    base: &str,
    out: &str,
    threads: Option<usize>,
    resume: Option<&str>,
    on_stage: Option<Py<PyAny>>,
    on_progress: Option<Py<PyAny>>,
    progress_every: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let (p, b) = paths(path, base);
    let out_p = PathBuf::from(out);
    if flem_core::scene3::scene_dim(text) == 3 {
        // A 3D scene (issue 38): resume in its own folder; no callbacks yet (the stage
        // observer of 3D runs is not wired to Python).
        if on_stage.is_some() || on_progress.is_some() {
            return Err(to_py(py, FlemError::config(path, "model.dim", "= 3: flem.run of a 3D scene takes no on_stage or on_progress yet")));
        }
        if let Some(r) = resume.filter(|r| Path::new(r).canonicalize().ok().zip(out_p.canonicalize().ok()).map_or(Path::new(r) != out_p, |(a, b)| a != b)) {
            return Err(to_py(py, FlemError::config(path, "model.dim", format!("= 3: a 3D run resumes in the folder of its checkpoints; resume = {r:?} is not out = {out:?}"))));
        }
        let (arrays, warnings, compare) = py.detach(|| run3_detached(text, &p, &b, &out_p, resume.is_some())).map_err(|e| to_py(py, e))?;
        let d = PyDict::new(py);
        d.set_item("arrays", arrays3_dict(py, &arrays)?)?;
        d.set_item("compare", compare)?;
        d.set_item("warnings", warnings)?;
        d.set_item("checkpoint", py.None())?;
        return Ok(d);
    }
    let resume_p = resume.map(PathBuf::from);
    let mut obs = PyObserver { on_stage, on_progress, progress_every: Duration::from_secs_f64(progress_every.max(0.0)), last_signal: Instant::now(), last_progress: None, err: None };
    let r = py.detach(|| run_detached(text, &p, &b, &out_p, threads, resume_p.as_deref(), &mut obs));
    let o = r.map_err(|e| to_py(py, e))?;
    let ck = o.last_checkpoint.as_ref().map(|c| c.display().to_string());
    match (o.result, obs.err) {
        (Err(FlemError::Interrupted { .. }), Some(e)) if e.is_instance_of::<pyo3::exceptions::PyKeyboardInterrupt>(py) => {
            let msg = format!("flem.run interrupted; the checkpoint {} holds the run: continue with flem.run(scene, out={out:?}, resume={out:?})", ck.clone().unwrap_or_default());
            let cls = py.import("flem._errors")?.getattr("RunInterrupted")?;
            Err(PyErr::from_value(cls.call1((msg, out, ck))?))
        }
        (_, Some(e)) => Err(e),
        (Err(e), None) => Err(to_py(py, e)),
        (Ok(()), None) => {
            let d = PyDict::new(py);
            d.set_item("arrays", arrays_dict(py, o.arrays.as_ref().expect("arrays of a finished run"))?)?;
            d.set_item("compare", serde_json::to_string(&o.compare).unwrap_or_default())?;
            d.set_item("warnings", o.warnings)?;
            d.set_item("checkpoint", ck)?;
            Ok(d)
        }
    }
}

/// `flem compare`: the rows of compare.json as JSON text (the GIL released during the run).
#[pyfunction]
fn compare(py: Python<'_>, text: &str, path: &str, base: &str, out: &str) -> PyResult<String> {
    let (p, b) = paths(path, base);
    let out_p = PathBuf::from(out);
    let r = py.detach(|| -> flem_core::Result<_> {
        let scene = Scene::from_str(text, &p, &b)?;
        let _lock = flem_core::output::lock::lock_dir(&out_p, "python flem.compare")?;
        flem_core::output::run::compare_in_folder(scene, &out_p, None)
    });
    let (res, rows, _) = r.map_err(|e| to_py(py, e))?;
    res.map_err(|e| to_py(py, e))?;
    Ok(serde_json::to_string(&rows).unwrap_or_default())
}

/// One sweep task (`flem_core::output::sweep::run_task`, as `flem sweep`): its row as JSON.
/// `params_json` is a JSON object of key paths; never raises for the task's own failure.
#[pyfunction]
#[pyo3(signature = (task, text, path, base, params_json, out, threads=Some(1)))]
#[allow(clippy::too_many_arguments)]
fn run_task(py: Python<'_>, task: usize, text: &str, path: &str, base: &str, params_json: &str, out: &str, threads: Option<usize>) -> PyResult<String> {
    let (p, b) = paths(path, base);
    let params: serde_json::Map<String, serde_json::Value> = serde_json::from_str(params_json).map_err(|e| PyValueError::new_err(format!("the parameters are not a JSON object: {e}")))?;
    let out_p = PathBuf::from(out);
    let row = py.detach(|| {
        let mut ps = Vec::new();
        for (k, v) in &params {
            match json_to_toml(v) {
                Ok(t) => ps.push((k.clone(), t)),
                Err(m) => {
                    let mut r = flem_core::output::sweep::Row { task, out: out_p.display().to_string(), error: Some(format!("{}: {k} {m}", p.display())), ..Default::default() };
                    r.params = params.iter().filter_map(|(k, v)| json_to_toml(v).ok().map(|t| (k.clone(), t))).collect();
                    return r;
                }
            }
        }
        core_run_task(task, text, &p, &b, &ps, &out_p, threads, &format!("python flem.sweep task {task}"))
    });
    Ok(row.to_json().to_string())
}

/// The registered plugins: (kind, name), then those loaded from libraries (kind, name, file).
#[pyfunction]
fn plugins() -> Vec<(String, String, Option<String>)> {
    let mut v: Vec<(String, String, Option<String>)> = flem_plugins::registry().into_iter().map(|(k, n)| (k.to_string(), n.to_string(), None)).collect();
    for p in flem_core::plugin::dynload::loaded() {
        v.push((p.kind.to_string(), p.name.to_string(), Some(p.file.display().to_string())));
    }
    v
}

/// Lets scenes load the plugin libraries they name (`flem --allow-plugins`).
#[pyfunction]
fn allow_plugins(yes: bool) {
    flem_core::plugin::dynload::set_scene_plugin_consent(yes);
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    flem_plugins::link();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(scene_check, m)?)?;
    m.add_function(wrap_pyfunction!(scene_set, m)?)?;
    m.add_function(wrap_pyfunction!(scene_from_json, m)?)?;
    m.add_function(wrap_pyfunction!(scene_to_json, m)?)?;
    m.add_function(wrap_pyfunction!(scene_resolved, m)?)?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    m.add_function(wrap_pyfunction!(run_task, m)?)?;
    m.add_function(wrap_pyfunction!(plugins, m)?)?;
    m.add_function(wrap_pyfunction!(allow_plugins, m)?)?;
    Ok(())
}
