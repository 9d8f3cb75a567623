//! `flem sweep SWEEP.toml --workers N`: a parameter sweep without Python (issue 22). The engine
//! is local worker processes, not Dask: N threads each start `flem sweep-task` (a hidden
//! subcommand: one task through `flem_core::output::sweep::run_task`, its row as JSON on
//! stdout) for the next task until none is left, so a task that crashes its process is a row
//! with its error and the others go on. The Python package's `flem.sweep` runs the same task
//! function on a Dask cluster (docs/python.md); both give the same rows.
//!
//! ```toml
//! scene = "../configs/verification/weibull_tension.toml"   # relative to this file
//! out = "out/weibull_sweep"        # default: out/<this file's name>; task i in task_NNNN/
//! threads = 1                      # solver.threads of each task (default 1)
//! [grid]                           # every combination of these values (keys are key paths)
//! "cracking.weibull.seed" = [1, 2, 3, 4]
//! [[task]]                         # and/or tasks listed one by one (after the grid's)
//! "cracking.weibull.seed" = 99
//! "cracking.criterion.tensile_strength" = 1.2
//! ```
//! Results: `sweep.csv` in `out` (one row per task, in task order: `task`, the parameters, then
//! `initiation_load`, `initiation_loadname`, `initiation_stage`, `splits`, `energy_residual`,
//! `steps`, `converged`, `wall_seconds`, `out`, `error`).
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use anyhow::{Context, Result};
use flem_core::output::sweep::{run_task, Row};

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct SweepFile {
    scene: PathBuf,
    out: Option<PathBuf>,
    #[serde(default = "one")]
    threads: usize,
    #[serde(default)]
    grid: toml::Table,
    #[serde(default)]
    task: Vec<toml::Table>,
}

fn one() -> usize {
    1
}

/// Every combination of the grid's values (the first key varies slowest), then the listed tasks.
pub fn expand(grid: &toml::Table, tasks: &[toml::Table], file: &str) -> Result<Vec<Vec<(String, toml::Value)>>> {
    let mut out: Vec<Vec<(String, toml::Value)>> = if grid.is_empty() { Vec::new() } else { vec![Vec::new()] };
    for (k, v) in grid {
        let vals = v.as_array().with_context(|| format!("{file}: grid.\"{k}\" must be an array of values"))?;
        anyhow::ensure!(!vals.is_empty(), "{file}: grid.\"{k}\" is empty");
        out = out.into_iter().flat_map(|p| vals.iter().map(move |x| [p.clone(), vec![(k.clone(), x.clone())]].concat())).collect();
    }
    out.extend(tasks.iter().map(|t| t.iter().map(|(k, v)| (k.clone(), v.clone())).collect()));
    anyhow::ensure!(!out.is_empty(), "{file}: no task: give a [grid] or [[task]] tables");
    Ok(out)
}

pub fn run(file: &Path, workers: Option<usize>, allow_plugins: bool) -> Result<()> {
    let name = file.display().to_string();
    let text = std::fs::read_to_string(file).with_context(|| format!("cannot read {name}"))?;
    let sf: SweepFile = toml::from_str(&text).with_context(|| format!("{name} is not a valid sweep file"))?;
    anyhow::ensure!(sf.threads <= 1024, "{name}: threads = {} is incorrect; it must be in [0, 1024] (0: one per core)", sf.threads);
    let base = file.parent().unwrap_or(Path::new(""));
    let scene = base.join(&sf.scene);
    // The scene itself must be valid before any task starts.
    flem_core::scene::Scene::from_file(&scene)?;
    let tasks = expand(&sf.grid, &sf.task, &name)?;
    let stem = file.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "sweep".into());
    let out = sf.out.map(|o| base.join(o)).unwrap_or_else(|| PathBuf::from("out").join(stem));
    let _lock = crate::lock_out(&out)?;
    flem_core::output::prepare_dir(&out)?;
    let workers = workers.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())).clamp(1, tasks.len());
    eprintln!("flem sweep: {} tasks of {} on {workers} worker processes (local; results in {})", tasks.len(), scene.display(), out.display());
    let t0 = std::time::Instant::now();
    let next = AtomicUsize::new(0);
    let rows: Mutex<Vec<Row>> = Mutex::new(Vec::new());
    let exe = std::env::current_exe().context("finding the flem executable")?;
    std::thread::scope(|s| {
        for _ in 0..workers {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(params) = tasks.get(i) else { break };
                let dir = out.join(format!("task_{i:04}"));
                let row = spawn_task(&exe, i, &scene, params, &dir, sf.threads, allow_plugins);
                eprintln!(
                    "task {i}: {}",
                    row.error.as_deref().map_or_else(|| format!("{} splits, initiation load {:?}, {:.2} s", row.splits, row.initiation_load, row.wall_seconds), |e| format!("FAILED: {e}"))
                );
                rows.lock().unwrap().push(row);
            });
        }
    });
    let mut rows = rows.into_inner().unwrap();
    rows.sort_by_key(|r| r.task);
    let csv = to_csv(&rows);
    flem_core::output::atomic_write(&out.join("sweep.csv"), csv.as_bytes())?;
    let failed = rows.iter().filter(|r| r.error.is_some()).count();
    eprintln!("{} tasks, {failed} failed, wall time {:.2} s; results in {}", rows.len(), t0.elapsed().as_secs_f64(), out.join("sweep.csv").display());
    Ok(())
}

/// Runs one task in a child process (`flem sweep-task`); a child that dies is a row with its error.
fn spawn_task(exe: &Path, i: usize, scene: &Path, params: &[(String, toml::Value)], dir: &Path, threads: usize, allow_plugins: bool) -> Row {
    let failed = |e: String| Row { task: i, params: params.to_vec(), out: dir.display().to_string(), error: Some(e), ..Default::default() };
    let mut p = toml::Table::new();
    for (k, v) in params {
        p.insert(k.clone(), v.clone());
    }
    let mut cmd = std::process::Command::new(exe);
    cmd.arg("sweep-task").arg(scene).arg("--task").arg(i.to_string()).arg("--out").arg(dir).arg("--threads").arg(threads.to_string()).arg("--params").arg(toml::to_string(&p).unwrap_or_default());
    if allow_plugins {
        cmd.arg("--allow-plugins");
    }
    let o = match cmd.output() {
        Ok(o) => o,
        Err(e) => return failed(format!("cannot start {}: {e}", exe.display())),
    };
    let stdout = String::from_utf8_lossy(&o.stdout);
    match stdout.lines().last().map(|l| serde_json::from_str::<serde_json::Value>(l)) {
        Some(Ok(v)) if o.status.success() => row_from_json(&v, params).unwrap_or_else(|| failed(format!("the task printed a row that cannot be read: {v}"))),
        _ => failed(format!("the task process failed ({}): {}", o.status, String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or(""))),
    }
}

fn row_from_json(v: &serde_json::Value, params: &[(String, toml::Value)]) -> Option<Row> {
    let f = |k: &str| v.get(k).and_then(|x| x.as_f64());
    Some(Row {
        task: v.get("task")?.as_u64()? as usize,
        params: params.to_vec(),
        initiation_load: f("initiation_load"),
        initiation_loadname: v.get("initiation_loadname").and_then(|x| x.as_str()).map(String::from),
        initiation_stage: v.get("initiation_stage").and_then(|x| x.as_u64()).map(|x| x as usize),
        splits: v.get("splits")?.as_u64()? as usize,
        energy_residual: f("energy_residual"),
        steps: v.get("steps")?.as_u64()?,
        converged: v.get("converged")?.as_bool()?,
        wall_seconds: f("wall_seconds")?,
        out: v.get("out")?.as_str()?.to_string(),
        error: v.get("error").and_then(|x| x.as_str()).map(String::from),
    })
}

/// `flem sweep-task`: one task in this process, its row as one JSON line on stdout.
pub fn task(scene: &Path, i: usize, out: &Path, threads: usize, params: &str) -> Result<()> {
    let text = std::fs::read_to_string(scene).with_context(|| format!("cannot read {}", scene.display()))?;
    let p: toml::Table = toml::from_str(params).context("--params is not a TOML table")?;
    let params: Vec<(String, toml::Value)> = p.into_iter().collect();
    let base = scene.parent().unwrap_or(Path::new(""));
    let row = run_task(i, &text, scene, base, &params, out, Some(threads), &format!("flem sweep-task {i}"));
    println!("{}", row.to_json());
    Ok(())
}

/// The rows as CSV (RFC 4180 quoting; absent values empty).
pub fn to_csv(rows: &[Row]) -> String {
    let mut keys: Vec<String> = Vec::new();
    for r in rows {
        for (k, _) in &r.params {
            if !keys.contains(k) {
                keys.push(k.clone());
            }
        }
    }
    let q = |s: &str| if s.contains([',', '"', '\n']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_string() };
    let opt = |v: Option<String>| v.unwrap_or_default();
    let mut out = std::iter::once("task".to_string()).chain(keys.iter().map(|k| q(k))).collect::<Vec<_>>().join(",");
    out.push_str(",initiation_load,initiation_loadname,initiation_stage,splits,energy_residual,steps,converged,wall_seconds,out,error\n");
    for r in rows {
        let mut f = vec![r.task.to_string()];
        for k in &keys {
            f.push(q(&r.params.iter().find(|(x, _)| x == k).map(|(_, v)| v.as_str().map_or_else(|| v.to_string(), String::from)).unwrap_or_default()));
        }
        f.push(opt(r.initiation_load.map(|x| format!("{x:e}"))));
        f.push(q(&opt(r.initiation_loadname.clone())));
        f.push(opt(r.initiation_stage.map(|x| x.to_string())));
        f.push(r.splits.to_string());
        f.push(opt(r.energy_residual.map(|x| format!("{x:e}"))));
        f.push(r.steps.to_string());
        f.push(r.converged.to_string());
        f.push(format!("{:e}", r.wall_seconds));
        f.push(q(&r.out));
        f.push(q(&opt(r.error.clone())));
        out.push_str(&f.join(","));
        out.push('\n');
    }
    out
}
