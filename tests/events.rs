//! The events stage solver (issue 19, ours; `[solver] type = "events"`, docs/events.md) against
//! two references: the exact first-failure load of the linear body (`cracking::initiation`, a
//! bisection on the criterion itself, independent of the events solver's closed forms), and the
//! explicit FLEM's split log (damped relaxation, checks at equilibrium, one split per check) on
//! the same scene loaded in steps of 0.5 % of the stage's levels.
use flem_core::cracking::initiation::initiation;
use flem_core::scene::Scene;
use flem_core::solver::events::{explicit_twin, LoggedSplit, SplitLog};
use flem_core::solver::{NoOutput, Simulation};
use flem_core::FlemError;

use crate::common::{rel, root};

fn scene(name: &str) -> Scene {
    flem_plugins::link();
    Scene::from_file(&root().join("configs/events").join(name)).unwrap_or_else(|e| panic!("{e}"))
}

/// The events run's split log (every split up to the end of the run).
fn events_log(name: &str) -> (Vec<LoggedSplit>, Simulation) {
    let mut sim = Simulation::new(scene(name)).unwrap_or_else(|e| panic!("{e}"));
    let mut log = SplitLog { splits: Vec::new(), stop_after: usize::MAX };
    sim.run(&mut log).unwrap_or_else(|e| panic!("{e}"));
    (log.splits, sim)
}

/// The exact initiation factor of the scene's stage (linear solve at the stage's levels).
fn exact_factor(name: &str) -> f64 {
    let mut sim = Simulation::new(scene(name)).unwrap();
    sim.set_stage_levels(0);
    let u1 = flem_plugins::check::static_solve(&sim).unwrap();
    let crit = &sim.scene.file.cracking.as_ref().unwrap().criterion;
    let cr = sim.cracking.as_mut().unwrap();
    let scale = cr.scale.clone();
    initiation(crit.as_ref(), &scale, &sim.model, &u1, cr.nonlocal.as_mut()).unwrap().factor
}

/// The explicit twin's split log: stages at `k step` of the events stage's levels from the last
/// multiple of `step` below `t_init`, stopped after `n` splits.
fn explicit_log(name: &str, t_init: f64, step: f64, to: f64, max_steps: u64, n: usize) -> Vec<LoggedSplit> {
    let mut sc = scene(name);
    let k0 = (t_init / step).floor() as u64;
    explicit_twin(&mut sc, k0, step, to, max_steps, 1e-5).unwrap();
    let mut sim = Simulation::new(sc).unwrap_or_else(|e| panic!("{e}"));
    let mut log = SplitLog { splits: Vec::new(), stop_after: n };
    match sim.run(&mut log) {
        Ok(()) | Err(FlemError::Interrupted { .. }) => {}
        Err(e) => panic!("{e}"),
    }
    log.splits
}

/// Reference: `cracking::initiation` (bisection to 1e-13 on the criterion, independent of the
/// events solver's closed-form roots). The events solver's first split is at the exact linear
/// initiation load to 1e-10 relative (the tolerance), on the paper's opening model
/// (Mohr-Coulomb tension branch, plane strain) and the peers' notched plate (Rankine), and the
/// explicit run in 0.5 % load steps splits first at the first step at or above it.
#[test]
fn first_event_is_the_exact_initiation_load_and_the_explicit_run_is_within_its_step() {
    for (name, level) in [("opening_roller.toml", 150.0), ("notch_plate_h0.25.toml", 0.2)] {
        let exact = exact_factor(name) * level;
        let (log, sim) = events_log(name);
        let first = log[0].levels[0];
        assert!(rel(first, exact) < 1e-10, "{name}: first event at {first:e}, exact initiation {exact:e}");
        // Stopped at the first fragment without support, named (a warning; the run ends).
        assert!(sim.warnings.iter().any(|w| w.contains("fragment") && w.contains("events solver ends the run")), "{name}: {:?}", sim.warnings);
        if name.starts_with("opening") {
            let ex = explicit_log(name, first / level, 0.005, 0.8, 20000, 1);
            let l = ex[0].levels[0];
            assert!(l >= exact && l <= exact + 0.005 * level, "{name}: explicit first split at {l}, exact {exact}, step {}", 0.005 * level);
        }
    }
}

/// Reference: the explicit FLEM (max_splits_per_check = 1, checks at equilibrium to an
/// unbalanced ratio of 1e-5, load steps of 0.5 % of the stage). The paper's opening model
/// (roller variant): the whole split log up to the fragment without support (4 splits: points,
/// edges and their order) is the events solver's. The crack runs under load control in both:
/// every split of the explicit run is at its first load step above the initiation load.
#[test]
fn opening_model_split_log_equals_the_explicit_runs() {
    let (ev, _) = events_log("opening_roller.toml");
    assert_eq!(ev.len(), 4, "{ev:?}");
    let ex = explicit_log("opening_roller.toml", ev[0].levels[0] / 150.0, 0.005, 0.8, 20000, usize::MAX);
    let key = |l: &[LoggedSplit]| l.iter().map(|s| (s.point, s.edges.clone())).collect::<Vec<_>>();
    assert_eq!(key(&ex[..4]), key(&ev), "explicit {ex:?}\nevents {ev:?}");
    assert!(ex[..4].iter().all(|s| s.levels == ex[0].levels), "explicit levels {ex:?}");
}

/// Reference: as above, on the peers' notched plate (gen_meshes.py, h = 0.25, 2280 Q4; corner
/// mean, Rankine). The first 12 splits of the explicit run (loads 0.121 to 0.136 in steps of
/// 0.001 = 0.5 % of 0.2) are the events solver's, point, edges and order. The events run splits
/// the notch corner at 0.12141 and then, after a rise to 0.13588, runs through the ligament at
/// that load; the explicit run needs the step 0.136 for the second split and runs at it (the
/// whole path, 33 of 36 splits before the explicit stage's step limit, is quoted in
/// docs/events.md from `flem bench events-path`).
#[test]
fn notched_plate_split_log_equals_the_explicit_runs() {
    let (ev, _) = events_log("notch_plate_h0.25.toml");
    assert!(ev.len() >= 30, "{ev:?}");
    let n = 12;
    let ex = explicit_log("notch_plate_h0.25.toml", ev[0].levels[0] / 0.2, 0.005, 0.7, 400_000, n);
    let key = |l: &[LoggedSplit]| l.iter().map(|s| (s.point, s.edges.clone())).collect::<Vec<_>>();
    assert_eq!(key(&ex[..n]), key(&ev[..n]), "explicit {ex:?}\nevents {ev:?}");
    // Each explicit split is at the first load step at or above the events' level.
    for (a, b) in ex[..n].iter().zip(&ev[..n]) {
        assert!(a.levels[0] >= b.levels[0] - 1e-12 && a.levels[0] < b.levels[0] + 0.001 + 1e-12, "explicit {:?} events {:?}", a.levels, b.levels);
    }
}

/// Bad input: the events solver refuses what it cannot do, naming the key.
#[test]
fn events_scenes_outside_the_solver_are_refused_naming_the_key() {
    flem_plugins::link();
    let base = std::fs::read_to_string(root().join("configs/events/opening_roller.toml")).unwrap();
    let path = root().join("configs/events/opening_roller.toml");
    let err = |text: &str| Scene::from_str(text, &path, path.parent().unwrap()).and_then(Simulation::new).err().map(|e| e.to_string()).unwrap_or_default();
    let no_crack = base.split("[cracking]").next().unwrap().to_string() + "[[stage]]\nlevels = { p = 1.0 }\n";
    assert!(err(&no_crack).contains("solver.type") && err(&no_crack).contains("[cracking]"), "{}", err(&no_crack));
    let dynamic = base.replace("name = \"pull\"\n", "name = \"pull\"\ndynamic = true\nmax_steps = 10\n");
    assert!(err(&dynamic).contains("stage[0].dynamic"), "{}", err(&dynamic));
    let bad_type = base.replace("type = \"events\"", "type = \"event\"");
    assert!(err(&bad_type).contains("event"), "{}", err(&bad_type));
    let t_load = base.replace("value = [0.0, 2597.0]", "value = [\"0\", \"2597 * t\"]");
    assert!(err(&t_load).contains("load[0].value"), "{}", err(&t_load));
    let _ = NoOutput;
}

/// Reference: the fresh factorisation at every event (`solver.refactor_every = 0`, the check
/// solver's own path, verified in tests/compare.rs). The kept factor with low-rank updates
/// (the default, 50 updates between fresh factorisations; plugins/src/check/kept.rs) gives the
/// same split log (points, edges, order) and the same event loads to 1e-9 relative, on the
/// notched plate h = 0.25 (36 events, so the updates reach a capacitance of about 200 columns),
/// and it did update (it is not the fresh path in disguise).
/// The same holds with the `qm6` element (issue 20), whose condensed stiffness the updates
/// take from `Block::stiffness` as the fresh assembly does.
#[test]
fn kept_factor_updates_give_the_fresh_factorisations_path() {
    kept_vs_fresh(None);
    kept_vs_fresh(Some("qm6"));
}

fn kept_vs_fresh(element: Option<&str>) {
    let run = |every: usize| {
        let mut sc = scene("notch_plate_h0.25.toml");
        sc.file.solver.refactor_every = every;
        sc.file.materials[0].element = element.map(String::from);
        let mut sim = Simulation::new(sc).unwrap();
        let mut log = SplitLog { splits: Vec::new(), stop_after: usize::MAX };
        sim.run(&mut log).unwrap();
        let ev = sim.events.as_ref().unwrap();
        (log.splits, ev.fresh_factorisations, ev.updates)
    };
    let (fresh, nf, nu) = run(0);
    assert_eq!(nu, 0);
    assert!(nf >= 30, "{nf}");
    let (kept, kf, ku) = run(50);
    // Measured: 3 fresh (the first; one after an update whose residual check failed; the last,
    // which names the fragment without support), 33 updates; since a refused update gets one
    // refinement step (kept.rs): 1 fresh, 35 updates.
    assert!(ku >= 30 && kf <= 4, "{element:?}: fresh {kf}, updates {ku}");
    assert_eq!(fresh.len(), kept.len());
    for (a, b) in fresh.iter().zip(&kept) {
        assert_eq!((a.point, &a.edges), (b.point, &b.edges));
        assert!(rel(b.levels[0], a.levels[0]) < 1e-9, "{:?} {:?}", a.levels, b.levels);
    }
}

/// Reference: `cracking::initiation` with the same nonlocal average (issue 18's, ours). With
/// `[cracking] nonlocal = { radius = 0.5 }` the events solver's stress paths are the nonlocal
/// nodal stresses (`Cracking::nodal_stress_of`), so its first event is the exact nonlocal
/// initiation load to 1e-10, on the notched plate h = 0.25 loaded to 1 (stopped after 2 events).
#[test]
fn first_event_with_the_nonlocal_check_is_its_exact_initiation_load() {
    flem_plugins::link();
    let path = root().join("configs/events/notch_plate_h0.25.toml");
    let text = std::fs::read_to_string(&path).unwrap().replace("[cracking]\n", "[cracking]\nnonlocal = { radius = 0.5 }\n").replace("levels = { pull = 0.2 }", "levels = { pull = 1.0 }");
    let sc = || Scene::from_str(&text, &path, path.parent().unwrap()).unwrap();
    let mut sim = Simulation::new(sc()).unwrap();
    sim.set_stage_levels(0);
    let u1 = flem_plugins::check::static_solve(&sim).unwrap();
    let crit = &sim.scene.file.cracking.as_ref().unwrap().criterion;
    let cr = sim.cracking.as_mut().unwrap();
    let scale = cr.scale.clone();
    let exact = initiation(crit.as_ref(), &scale, &sim.model, &u1, cr.nonlocal.as_mut()).unwrap().factor;
    let mut s = sc();
    s.file.solver.max_events = 2;
    let mut ev = Simulation::new(s).unwrap();
    let mut log = SplitLog { splits: Vec::new(), stop_after: usize::MAX };
    ev.run(&mut log).unwrap();
    assert!(!log.splits.is_empty() && exact < 1.0, "no event below the level 1 (exact {exact})");
    assert!(rel(log.splits[0].levels[0], exact) < 1e-10, "events {:?}, exact {exact}", log.splits[0].levels);
}

/// The events solver needs a stress linear in the load (docs/events.md): a material law with
/// state (Mohr-Coulomb plasticity) or large strain is refused when the scene is built, naming
/// the key and the file.
#[test]
fn a_nonlinear_material_or_large_strain_is_refused() {
    flem_plugins::link();
    let path = root().join("configs/events/notch_plate_h0.25.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("type = \"events\"\n") && text.contains("[[material]]\n"), "the scene changed: update the test");
    let ls = text.replace("type = \"events\"\n", "type = \"events\"\nlarge_strain = true\n");
    let mc = text.replace("[[material]]\n", "[[material]]\nlaw = { type = \"mohr_coulomb\", cohesion = 10.0, friction_angle_deg = 20.0, dilation_angle_deg = 0.0 }\n");
    for (t, key) in [(ls, "solver.large_strain"), (mc, "material[0].law")] {
        let s = Scene::from_str(&t, &path, path.parent().unwrap()).unwrap_or_else(|e| panic!("{e}"));
        let e = Simulation::new(s).err().expect("refused").to_string();
        assert!(e.contains(key) && e.contains("notch_plate_h0.25.toml") && e.contains("events"), "{e}");
    }
}

/// The notched plate h = 0.25 as text for `common::scene` (paths against configs/), with
/// checkpoints every 5 events and none by time.
fn notch_ckpt_text() -> String {
    std::fs::read_to_string(root().join("configs/events/notch_plate_h0.25.toml"))
        .unwrap()
        .replace("../meshes/", "meshes/")
        .replace("[output]\n", "[output]\ncheckpoint_every = 5\ncheckpoint_seconds = 0\n")
}

/// Reference: the same events run uninterrupted (tolerance: none, bit for bit: final
/// displacements by `to_bits`, splits.csv, history.csv, PVD and VTU byte for byte, stage
/// results). Stopped after events 10 and 25 (checkpoints of `output.checkpoint_every = 5`,
/// where the kept factor restarts in both runs) and resumed by a new `Simulation` from the
/// folder: the resumed run ends as the uninterrupted one (tests/ckpt.rs's check).
#[test]
fn events_checkpoint_after_event_k_resumes_bit_for_bit() {
    let text = notch_ckpt_text();
    assert!(text.contains("checkpoint_every = 5"), "the scene has no [output] section: update the test");
    let ref_dir = crate::ckpt::tmp("events-ref");
    let mut reference = crate::common::sim(&text);
    let mut w = flem_core::output::OutputWriter::new(&ref_dir, &reference).unwrap();
    reference.run(&mut w).unwrap();
    assert!(reference.state.step > 25, "{} events", reference.state.step);
    let ev = reference.events.as_ref().unwrap();
    assert!(ev.updates > 15, "the kept factor made {} updates: the checkpoints should not replace them all", ev.updates);
    for at in [10, 25] {
        crate::ckpt::interrupt_and_resume(&text, at, &reference, &ref_dir, &format!("events-{at}"));
    }
    let _ = std::fs::remove_dir_all(&ref_dir);
}

/// An interrupt between two events that is not at a checkpoint of the schedule (event 7; one
/// every 5): the run stops at once with a checkpoint and an "interrupted" snapshot; resumed,
/// its next solve is a fresh factorisation where the uninterrupted run updated, so it gives
/// the same split log (points, edges, order) and the same event loads to 1e-9 relative
/// (reference: the uninterrupted run; the tolerance of `kept_factor_updates_give_the_fresh_
/// factorisations_path`).
#[test]
fn events_interrupt_between_checkpoints_stops_and_resumes_the_same_path() {
    use flem_core::output::{checkpoint, OutputWriter};
    let text = notch_ckpt_text();
    let mut reference = crate::common::sim(&text);
    let mut log = SplitLog { splits: Vec::new(), stop_after: usize::MAX };
    reference.run(&mut log).unwrap();
    let dir = crate::ckpt::tmp("events-int7");
    /// The output writer and a split log, stopping once `at` events are done.
    struct StopAt(OutputWriter, SplitLog, u64);
    impl flem_core::solver::Observer for StopAt {
        fn splits(&mut self, sim: &Simulation, rec: &flem_core::mesh::topology::SplitRecord, ev: &[flem_core::cracking::SplitEvent]) -> flem_core::Result<()> {
            self.1.splits(sim, rec, ev)?;
            self.0.splits(sim, rec, ev)
        }
        fn history(&mut self, sim: &Simulation, stage: usize) -> flem_core::Result<()> {
            self.0.history(sim, stage)
        }
        fn snapshot(&mut self, sim: &Simulation, stage: usize, label: &str) -> flem_core::Result<()> {
            self.0.snapshot(sim, stage, label)
        }
        fn should_stop(&mut self, sim: &Simulation) -> bool {
            sim.state.step >= self.2
        }
        fn checkpoint(&mut self, sim: &Simulation, pos: &flem_core::solver::StagePos) -> flem_core::Result<()> {
            self.0.checkpoint(sim, pos)
        }
    }
    let mut sim = crate::common::sim(&text);
    let mut obs = StopAt(OutputWriter::new(&dir, &sim).unwrap(), SplitLog { splits: Vec::new(), stop_after: usize::MAX }, 7);
    match sim.run(&mut obs) {
        Err(FlemError::Interrupted { step: 7, .. }) => {}
        other => panic!("expected an interruption after event 7, got {other:?}"),
    }
    assert!(std::fs::read_dir(&dir).unwrap().flatten().any(|e| e.file_name().to_string_lossy().contains("interrupted")), "no snapshot \"interrupted\"");
    let mut first = obs.1.splits;
    assert_eq!(first.len(), 7);
    let mut sim = crate::common::sim(&text);
    let (ck, path, _) = checkpoint::load_newest(&dir, &sim).unwrap();
    assert_eq!(ck.step, 7, "the newest checkpoint is not the interruption's");
    ck.restore(&mut sim).unwrap();
    let mut w = OutputWriter::new(&dir, &sim).unwrap();
    w.resume(&ck, &path).unwrap();
    let mut rest = StopAt(w, SplitLog { splits: Vec::new(), stop_after: usize::MAX }, u64::MAX);
    sim.run_from(ck.pos.clone(), &mut rest).unwrap();
    first.append(&mut rest.1.splits);
    assert_eq!(first.len(), log.splits.len());
    for (a, b) in log.splits.iter().zip(&first) {
        assert_eq!((a.point, &a.edges), (b.point, &b.edges));
        assert!(rel(b.levels[0], a.levels[0]) < 1e-9, "{:?} {:?}", a.levels, b.levels);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A check solver of the tests' own: faer's sparse Cholesky through `CheckSolver::solve` only
/// (no `events_factor`), counting its calls.
#[derive(Debug, Default, serde::Serialize, serde::Deserialize)]
struct FreshOnly {}

static FRESH_ONLY_CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

#[typetag::serde(name = "test_fresh_only")]
impl flem_core::plugin::check::CheckSolver for FreshOnly {
    fn solve(&self, model: &flem_core::element::model::Model, fix: &[u8], f: &[[f64; 2]], up: &[[f64; 2]]) -> flem_core::Result<Vec<[f64; 2]>> {
        FRESH_ONLY_CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        flem_core::plugin::check::CheckSolver::solve(&flem_plugins::check::ImplicitSolver::new(), model, fix, f, up)
    }
}

/// `[check] solver` is the events solver's: a check solver without a kept factor (here the
/// tests' `test_fresh_only`) is called through `CheckSolver::solve`, two fresh solves per
/// event, and gives the default's split log (points, edges, order) and event loads to 1e-9
/// relative (reference: the default `faer_cholesky` with its kept factor, itself checked
/// against fresh factorisations above).
#[test]
fn the_configured_check_solver_is_used_by_events() {
    let path = root().join("configs/events/notch_plate_h0.25.toml");
    let text = std::fs::read_to_string(&path).unwrap() + "\n[check]\nsolver = { type = \"test_fresh_only\" }\n";
    let mut sc = Scene::from_str(&text, &path, path.parent().unwrap()).unwrap_or_else(|e| panic!("{e}"));
    sc.file.solver.max_events = 12;
    let mut sim = Simulation::new(sc).unwrap();
    let before = FRESH_ONLY_CALLS.load(std::sync::atomic::Ordering::Relaxed);
    let mut log = SplitLog { splits: Vec::new(), stop_after: usize::MAX };
    sim.run(&mut log).unwrap();
    let calls = FRESH_ONLY_CALLS.load(std::sync::atomic::Ordering::Relaxed) - before;
    let ev = sim.events.as_ref().unwrap();
    assert_eq!(calls as u64, ev.solves, "the configured check solver was not the one solving");
    assert!(calls >= 24 && ev.fresh_factorisations == 0 && ev.updates == 0, "calls {calls}, {ev:?}");
    let mut sc = scene("notch_plate_h0.25.toml");
    sc.file.solver.max_events = 12;
    let mut def = Simulation::new(sc).unwrap();
    let mut dlog = SplitLog { splits: Vec::new(), stop_after: usize::MAX };
    def.run(&mut dlog).unwrap();
    assert_eq!(log.splits.len(), 12);
    assert_eq!(dlog.splits.len(), 12);
    for (a, b) in dlog.splits.iter().zip(&log.splits) {
        assert_eq!((a.point, &a.edges), (b.point, &b.edges));
        assert!(rel(b.levels[0], a.levels[0]) < 1e-9, "{:?} {:?}", a.levels, b.levels);
    }
}
