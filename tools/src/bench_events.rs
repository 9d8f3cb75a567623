//! `flem bench events` and `flem bench events-path` (issue 19): the events stage solver
//! (`flem_core::solver::events`, ours) timed.
//!
//! - `events`: wall time per crack event against the number of dofs (a side-notched plate of
//!   structured Q4 pulled on top, Rankine, the crack running from the notch), with the growth
//!   exponent of a least-squares fit `t = a dofs^b`; per size also the share of the time spent
//!   in the linear solves (two right-hand sides per event; `--refactor-every 0`: a fresh
//!   factorisation per event, else low-rank updates of a kept factor between fresh ones).
//! - `events-path SCENE`: a one-stage events scene's crack path by events, then by the explicit
//!   solver (`explicit_twin`: load steps of `--step` of the stage's levels from the step below the
//!   events' first split, checks at equilibrium), stopped after as many splits as the events
//!   run made (or `--splits`, which stops the events run there too); wall time of each, their
//!   ratio, and how far the split logs (point, edges, order) agree. The events run is timed
//!   `--repeats` times (best kept), the explicit one once; beside the wall times the CPU time of
//!   each (every thread) and the machine's load averages at the start and the end, since the
//!   wall time on a shared machine moves with the others' load. `--events-only` skips the
//!   explicit run.
use anyhow::Result;
use flem_core::scene::Scene;
use flem_core::solver::events::{explicit_twin, LoggedSplit, SplitLog};
use flem_core::solver::Simulation;
use flem_core::FlemError;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

#[derive(Serialize)]
struct Row {
    dofs: usize,
    elements: usize,
    events: u64,
    solves: u64,
    wall_seconds: f64,
    seconds_per_event: f64,
    solve_share: f64,
    fresh_factorisations: u64,
    updates: u64,
}

fn notch_scene(nx: usize, events: u64, refactor_every: usize) -> String {
    format!(
        r#"title = "bench events"
[mesh]
type = "rectangle"
width = 1.0
height = 2.0
nx = {nx}
ny = {ny}
notch = {{ side = "left", y = 1.0, depth = 0.25 }}
[model]
plane = "stress"
separated = ["notch"]
[[material]]
young_modulus = 100.0
poisson_ratio = 0.2
density = 1.0
[solver]
type = "events"
max_events = {events}
refactor_every = {refactor_every}
on_loose_fragment = "stop"
[[support]]
nodes = "bottom"
fix = "y"
[[support]]
nodes = "bottom_left"
fix = "xy"
[[load]]
name = "pull"
type = "traction"
edges = "top"
value = [0.0, 1.0]
[cracking]
max_splits_per_check = 1
criterion = {{ type = "rankine", tensile_strength = 1.0 }}
separation = {{ type = "sigma1_nearest" }}
[[stage]]
levels = {{ pull = 1.0 }}
"#,
        ny = 2 * nx
    )
}

/// `flem bench events`: time per event against dofs.
pub fn run(dofs: &[f64], events: u64, refactor_every: usize) -> Result<()> {
    let mut rows = Vec::new();
    for &d in dofs {
        // dofs = 2 (nx + 1)(2 nx + 1): nx a multiple of 4 (the notch depth 0.25).
        let nx = (((d / 4.0).sqrt() / 4.0).round().max(1.0) as usize) * 4;
        let text = notch_scene(nx, events, refactor_every);
        let scene = Scene::from_str(&text, Path::new("<bench events>"), Path::new("."))?;
        let mut sim = Simulation::new(scene)?;
        let t = Instant::now();
        sim.run(&mut flem_core::solver::NoOutput)?;
        let wall = t.elapsed().as_secs_f64();
        let ev = sim.events.as_ref().expect("an events run");
        anyhow::ensure!(ev.events > 0, "no event at {d} dofs");
        rows.push(Row {
            dofs: 2 * sim.model.topo.n_points,
            elements: sim.model.n_elems(),
            events: ev.events,
            solves: ev.solves,
            wall_seconds: wall,
            seconds_per_event: wall / ev.events as f64,
            solve_share: ev.solve_seconds / wall,
            fresh_factorisations: ev.fresh_factorisations,
            updates: ev.updates,
        });
        eprintln!("{} dofs: {} events, {:.3e} s per event", rows.last().unwrap().dofs, ev.events, wall / ev.events as f64);
    }
    let (xs, ys): (Vec<f64>, Vec<f64>) = rows.iter().map(|r| (r.dofs as f64, r.seconds_per_event)).unzip();
    // One size gives no slope (0 / 0 = NaN, as before).
    let exponent = crate::bench_contact::slope(&xs, &ys);
    let out = serde_json::json!({
        "what": "events solver: wall time per crack event against dofs (side-notched Q4 plate, Rankine)",
        "refactor_every": refactor_every,
        "rows": rows,
        "growth_exponent": if exponent.is_finite() { Some(exponent) } else { None },
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}

/// The machine's load averages (1, 5, 15 min) from /proc/loadavg (empty where it is missing):
/// reported beside the wall times, which the other processes of a shared machine move.
fn load_average() -> Vec<f64> {
    std::fs::read_to_string("/proc/loadavg").map(|s| s.split_whitespace().take(3).filter_map(|x| x.parse().ok()).collect()).unwrap_or_default()
}

/// CPU seconds of this process so far, every thread (utime + stime of /proc/self/stat, in
/// USER_HZ = 100 ticks; NaN where it is missing): on a shared machine the wall time moves with
/// the others' load, the CPU time much less.
fn cpu_seconds() -> f64 {
    let Ok(s) = std::fs::read_to_string("/proc/self/stat") else { return f64::NAN };
    // Fields after the command name (which is in parentheses and may hold spaces).
    let rest = s.rsplit_once(')').map_or("", |x| x.1);
    let f: Vec<&str> = rest.split_whitespace().collect();
    match (f.get(11).and_then(|x| x.parse::<f64>().ok()), f.get(12).and_then(|x| x.parse::<f64>().ok())) {
        (Some(u), Some(k)) => (u + k) / 100.0,
        _ => f64::NAN,
    }
}

/// `flem bench events-path SCENE`: events (best of `repeats`) against the explicit run of the
/// same path (once; skipped when `explicit` is false).
pub fn path(scene_path: &Path, step: f64, max_steps: u64, tolerance: f64, splits: Option<usize>, repeats: usize, explicit: bool) -> Result<()> {
    anyhow::ensure!(step > 0.0 && step < 1.0, "--step must be in (0, 1)");
    // With --splits the events run stops there too (solver.max_events; one split per event with
    // max_splits_per_check = 1), so that both solvers are timed on the same path.
    let scene0 = || -> Result<Scene> {
        let mut sc0 = Scene::from_file(scene_path)?;
        // The events part alone is timed (a loose fragment's explicit march is not the path).
        sc0.file.solver.on_loose_fragment = flem_core::scene::LooseFragment::Stop;
        if let Some(n) = splits {
            sc0.file.solver.max_events = n as u64;
        }
        Ok(sc0)
    };
    // The events run, best of `repeats` (the explicit run is timed once: it takes minutes).
    let load_start = load_average();
    let mut best: Option<(f64, f64, Simulation, Vec<LoggedSplit>)> = None;
    let (mut walls, mut cpus) = (Vec::new(), Vec::new());
    for _ in 0..repeats.max(1) {
        let sc0 = scene0()?;
        let (t, c) = (Instant::now(), cpu_seconds());
        let mut sim = Simulation::new(sc0)?;
        let setup = t.elapsed().as_secs_f64();
        let mut log = SplitLog { splits: Vec::new(), stop_after: usize::MAX };
        sim.run(&mut log)?;
        let wall = t.elapsed().as_secs_f64();
        walls.push(wall);
        cpus.push(cpu_seconds() - c);
        if best.as_ref().is_none_or(|b| wall < b.0) {
            best = Some((wall, setup, sim, log.splits));
        }
    }
    let (wall_events, setup_events, sim, ev) = best.expect("one run at least");
    let cpu_events = cpus.iter().copied().fold(f64::INFINITY, f64::min);
    anyhow::ensure!(!ev.is_empty(), "the events run made no split");
    let target = sim.scene.file.stages[0].levels.values().copied().fold(0.0f64, |a, v| a.max(v.abs()));
    let first = ev[0].levels.iter().copied().fold(0.0f64, |a, v| a.max(v.abs())) / target;
    let n = splits.unwrap_or(ev.len()).min(ev.len());
    let mut sc = Scene::from_file(scene_path)?;
    explicit_twin(&mut sc, (first / step).floor() as u64, step, 1.0, max_steps, tolerance)?;
    if !explicit {
        let e = sim.events.as_ref();
        let out = serde_json::json!({
            "scene": scene_path.display().to_string(),
            "elements": sim.model.n_elems(),
            "dofs": 2 * sim.model.topo.n_points,
            "load_average_1_5_15": [load_start, load_average()],
            "events": { "splits": ev.len(), "wall_seconds": wall_events, "setup_seconds": setup_events, "wall_seconds_every_repeat": walls, "cpu_seconds_best": cpu_events,
                "solves": e.map(|e| e.solves), "solve_seconds": e.map(|e| e.solve_seconds), "fresh_factorisations": e.map(|e| e.fresh_factorisations), "updates": e.map(|e| e.updates), "warnings": sim.warnings },
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    let (t, c) = (Instant::now(), cpu_seconds());
    let mut ex_sim = Simulation::new(sc)?;
    let setup_explicit = t.elapsed().as_secs_f64();
    let mut ex = SplitLog { splits: Vec::new(), stop_after: n };
    let outcome = match ex_sim.run(&mut ex) {
        Ok(()) => "ran every stage".to_string(),
        Err(FlemError::Interrupted { .. }) => format!("stopped after {n} splits"),
        Err(e) => return Err(e.into()),
    };
    let wall_explicit = t.elapsed().as_secs_f64();
    let cpu_explicit = cpu_seconds() - c;
    let same = ev.iter().zip(&ex.splits).take_while(|(a, b)| a.point == b.point && a.edges == b.edges).count();
    let first_difference = ev
        .iter()
        .zip(&ex.splits)
        .nth(same)
        .map(|(a, b)| serde_json::json!({"index": same, "events": {"point": a.point, "edges": a.edges, "levels": a.levels}, "explicit": {"point": b.point, "edges": b.edges, "levels": b.levels}}));
    let out = serde_json::json!({
        "scene": scene_path.display().to_string(),
        "elements": sim.model.n_elems(),
        "load_average_1_5_15": [load_start, load_average()],
        "events": { "splits": ev.len(), "wall_seconds": wall_events, "setup_seconds": setup_events, "wall_seconds_every_repeat": walls, "cpu_seconds_best": cpu_events, "first_split_levels": ev[0].levels, "solves": sim.events.as_ref().map(|e| e.solves), "solve_seconds": sim.events.as_ref().map(|e| e.solve_seconds), "fresh_factorisations": sim.events.as_ref().map(|e| e.fresh_factorisations), "updates": sim.events.as_ref().map(|e| e.updates), "warnings": sim.warnings },
        "explicit": { "splits": ex.splits.len(), "wall_seconds": wall_explicit, "cpu_seconds": cpu_explicit, "setup_seconds": setup_explicit, "steps": ex_sim.state.step, "stages": ex_sim.stages_done.len(), "load_step": step, "tolerance": tolerance, "max_steps_per_stage": max_steps, "outcome": outcome, "first_split_levels": ex.splits.first().map(|s| s.levels.clone()) },
        "compared_splits": n.min(ex.splits.len()),
        "identical_prefix": same,
        "first_difference": first_difference,
        "wall_time_ratio_explicit_over_events": wall_explicit / wall_events,
        "ratio_without_setup": (wall_explicit - setup_explicit) / (wall_events - setup_events),
        "cpu_time_ratio_explicit_over_events": cpu_explicit / cpu_events,
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}
