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
//!   ratio, and how far the split logs (point, edges, order) agree.
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

/// `flem bench events-path SCENE`: events against the explicit run of the same path.
pub fn path(scene_path: &Path, step: f64, max_steps: u64, tolerance: f64, splits: Option<usize>) -> Result<()> {
    anyhow::ensure!(step > 0.0 && step < 1.0, "--step must be in (0, 1)");
    // With --splits the events run stops there too (solver.max_events; one split per event with
    // max_splits_per_check = 1), so that both solvers are timed on the same path.
    let mut sc0 = Scene::from_file(scene_path)?;
    if let Some(n) = splits {
        sc0.file.solver.max_events = n as u64;
    }
    let t = Instant::now();
    let mut sim = Simulation::new(sc0)?;
    let setup_events = t.elapsed().as_secs_f64();
    let mut log = SplitLog { splits: Vec::new(), stop_after: usize::MAX };
    sim.run(&mut log)?;
    let wall_events = t.elapsed().as_secs_f64();
    let ev: Vec<LoggedSplit> = log.splits;
    anyhow::ensure!(!ev.is_empty(), "the events run made no split");
    let target = sim.scene.file.stages[0].levels.values().copied().fold(0.0f64, |a, v| a.max(v.abs()));
    let first = ev[0].levels.iter().copied().fold(0.0f64, |a, v| a.max(v.abs())) / target;
    let n = splits.unwrap_or(ev.len()).min(ev.len());
    let mut sc = Scene::from_file(scene_path)?;
    explicit_twin(&mut sc, (first / step).floor() as u64, step, 1.0, max_steps, tolerance)?;
    let t = Instant::now();
    let mut ex_sim = Simulation::new(sc)?;
    let setup_explicit = t.elapsed().as_secs_f64();
    let mut ex = SplitLog { splits: Vec::new(), stop_after: n };
    let outcome = match ex_sim.run(&mut ex) {
        Ok(()) => "ran every stage".to_string(),
        Err(FlemError::Interrupted { .. }) => format!("stopped after {n} splits"),
        Err(e) => return Err(e.into()),
    };
    let wall_explicit = t.elapsed().as_secs_f64();
    let same = ev.iter().zip(&ex.splits).take_while(|(a, b)| a.point == b.point && a.edges == b.edges).count();
    let first_difference = ev
        .iter()
        .zip(&ex.splits)
        .nth(same)
        .map(|(a, b)| serde_json::json!({"index": same, "events": {"point": a.point, "edges": a.edges, "levels": a.levels}, "explicit": {"point": b.point, "edges": b.edges, "levels": b.levels}}));
    let out = serde_json::json!({
        "scene": scene_path.display().to_string(),
        "elements": sim.model.n_elems(),
        "events": { "splits": ev.len(), "wall_seconds": wall_events, "setup_seconds": setup_events, "first_split_levels": ev[0].levels, "solves": sim.events.as_ref().map(|e| e.solves), "warnings": sim.warnings },
        "explicit": { "splits": ex.splits.len(), "wall_seconds": wall_explicit, "setup_seconds": setup_explicit, "steps": ex_sim.state.step, "stages": ex_sim.stages_done.len(), "load_step": step, "tolerance": tolerance, "max_steps_per_stage": max_steps, "outcome": outcome, "first_split_levels": ex.splits.first().map(|s| s.levels.clone()) },
        "compared_splits": n.min(ex.splits.len()),
        "identical_prefix": same,
        "first_difference": first_difference,
        "wall_time_ratio_explicit_over_events": wall_explicit / wall_events,
        "ratio_without_setup": (wall_explicit - setup_explicit) / (wall_events - setup_events),
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}
