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

/// The events run's split log (every split up to the end of the run), the run ending at the
/// fragment without support (`on_loose_fragment = "stop"`: these tests compare the events path).
fn events_log(name: &str) -> (Vec<LoggedSplit>, Simulation) {
    let mut sc = scene(name);
    sc.file.solver.on_loose_fragment = flem_core::scene::LooseFragment::Stop;
    let mut sim = Simulation::new(sc).unwrap_or_else(|e| panic!("{e}"));
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
        // The events path alone (the march after it would compare round-off).
        sc.file.solver.on_loose_fragment = flem_core::scene::LooseFragment::Stop;
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
    // The events path alone: resumed, it is the same to round-off, which a march would amplify.
    let text = notch_ckpt_text().replace("type = \"events\"\n", "type = \"events\"\non_loose_fragment = \"stop\"\n");
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

/// The notched plate h = 0.25 with `[solver]` keys added (text for `Scene::from_str`).
fn notch_with(solver_keys: &str, extra: &str) -> Simulation {
    flem_plugins::link();
    let path = root().join("configs/events/notch_plate_h0.25.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("type = \"events\"\n"), "the scene changed: update the test");
    let text = text.replace("type = \"events\"\n", &format!("type = \"events\"\n{solver_keys}\n")) + extra;
    let sc = Scene::from_str(&text, &path, path.parent().unwrap()).unwrap_or_else(|e| panic!("{e}"));
    Simulation::new(sc).unwrap_or_else(|e| panic!("{e}"))
}

/// `[cracking] intact` (ours, session 33) in the events solver: the notched plate with the band
/// x in [2.5, 12], y in [3, 9] around the notch's plane (973 points) never split. Hundreds of its
/// points fail one after another (the stress field's shape does not change until a split). The
/// events search leaves intact points out from the start, so the solver checks only where it
/// splits: at most one check more than its splits (measured 53 checks, 52 splits). Before, it
/// stopped at each intact failure (410 checks for the same 52 splits, the same split log to the
/// bit), and before that 60 such refusals in a row stopped the run with "a failure ... that the
/// failure check does not confirm" (checked: at load factor 0.45). Reference: the key's
/// definition. The run must split outside the band and never inside it, with more than 60 points
/// of the band left beyond the criterion (measured 586).
#[test]
fn events_leave_intact_points_out_of_the_search() {
    flem_plugins::link();
    let path = root().join("configs/events/notch_plate_h0.25.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("[cracking]\n") && text.contains("type = \"events\"\n") && text.contains("levels = { pull = 0.2 }"), "the scene changed: update the test");
    let text = text
        .replace("levels = { pull = 0.2 }", "levels = { pull = 1.0 }")
        .replace("[cracking]\n", "[cracking]\nintact = [\"keep\"]\n")
        .replace("type = \"events\"\n", "type = \"events\"\non_loose_fragment = \"stop\"\n")
        + "\n[[set]]\nname = \"keep\"\nbox = [[2.49, 2.99], [12.01, 9.01]]\n";
    let sc = Scene::from_str(&text, &path, path.parent().unwrap()).unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::new(sc).unwrap_or_else(|e| panic!("{e}"));
    let keep: Vec<usize> = sim.model.node_set("keep", "keep", "test").unwrap().iter().map(|p| p.idx()).collect();
    assert!(keep.len() > 60, "{} points in the box", keep.len());
    let mut log = SplitLog { splits: Vec::new(), stop_after: usize::MAX };
    sim.run(&mut log).unwrap_or_else(|e| panic!("{e}"));
    let topo = &sim.model.topo;
    assert!(keep.iter().all(|&p| topo.point_clusters[p].len() == 1), "a point of the box split");
    let cr = sim.cracking.as_ref().unwrap();
    let beyond = keep.iter().filter(|&&p| cr.index[topo.point_clusters[p][0].idx()] >= 1.0).count();
    assert!(topo.point_clusters.iter().any(|c| c.len() > 1), "no split at all ({beyond} points of the box beyond the criterion)");
    let st = &sim.stages_done[0];
    assert!(st.checks <= st.splits as u64 + 1, "{} checks for {} splits: the search stops at intact points", st.checks, st.splits);
    assert!(beyond > 60, "{beyond} points of the box beyond the criterion: the test does not exercise 60 refusals in a row");
}

/// Today's end, kept as `on_loose_fragment = "stop"`: the solve after the last event is
/// singular (the upper part hangs free), the run stops there with a warning naming the
/// fragment, the stage is not converged, the velocities are zero and nothing is handed over.
#[test]
fn loose_fragment_stop_ends_the_run_naming_the_fragment() {
    let mut sim = notch_with("on_loose_fragment = \"stop\"", "");
    let mut log = SplitLog { splits: Vec::new(), stop_after: usize::MAX };
    sim.run(&mut log).unwrap();
    assert!(log.splits.len() >= 30, "{}", log.splits.len());
    let w = sim.warnings.iter().find(|w| w.contains("fragment")).unwrap_or_else(|| panic!("{:?}", sim.warnings));
    assert!(w.contains("on_loose_fragment = \"stop\"") && w.contains("ends the run"), "{w}");
    assert!(sim.hand_over.is_none());
    assert!(!sim.stages_done[0].converged);
    assert!(sim.state.v.iter().all(|v| *v == [0.0; 2]));
}

/// What the hand-over test records at every history row: time, splits so far, the momentum
/// of the free fragments (no prescribed dof) and whether they hold the whole top edge.
#[derive(Default)]
struct Rows {
    log: Vec<LoggedSplit>,
    rows: Vec<(f64, usize, [f64; 2], bool)>,
}

impl flem_core::solver::Observer for Rows {
    fn splits(&mut self, sim: &Simulation, rec: &flem_core::mesh::topology::SplitRecord, events: &[flem_core::cracking::SplitEvent]) -> flem_core::Result<()> {
        let mut l = SplitLog { splits: Vec::new(), stop_after: usize::MAX };
        l.splits(sim, rec, events)?;
        self.log.append(&mut l.splits);
        Ok(())
    }
    fn history(&mut self, sim: &Simulation, _stage: usize) -> flem_core::Result<()> {
        let topo = &sim.model.topo;
        let (frag, n) = topo.fragments();
        let mut elem_of = vec![usize::MAX; topo.n_clusters()];
        for (k, c) in topo.copy_cluster.iter().enumerate() {
            elem_of[c.idx()] = topo.copy_elem[k].0 as usize;
        }
        let mut free = vec![true; n];
        for c in 0..topo.n_clusters() {
            if sim.state.fix[c] != 0 {
                free[frag[elem_of[c]] as usize] = false;
            }
        }
        let pts = &sim.model.mesh.points;
        let top_free = (0..pts.len()).filter(|&p| (pts[p][1] - 12.0).abs() < 1e-9).all(|p| topo.point_clusters[p].iter().all(|c| free[frag[elem_of[c.idx()]] as usize]));
        let mut p = [0.0f64; 2];
        for c in 0..topo.n_clusters() {
            if free[frag[elem_of[c]] as usize] {
                for d in 0..2 {
                    p[d] += sim.state.mass[c] * sim.state.v[c][d];
                }
            }
        }
        self.rows.push((sim.state.time, self.log.len(), p, top_free));
        Ok(())
    }
}

/// Reference: Newton's second law for the loose fragment and the energy balance of the
/// central-difference scheme. The notched plate h = 0.25 cracks through (the events solver, as
/// in the test above: the last split leaves the upper part held by one node, a hinge, and the
/// solve is singular) and the default `on_loose_fragment = "hand_over"` continues the stage in
/// the explicit march, undamped (`damping = "none"`), with the traction held at the last
/// event's level `q`, failure checked every 10 steps (the hinge tears off; the undamped release
/// keeps cracking: measured 57 splits in 570 steps). Once the free fragments (no prescribed
/// dof) hold the whole top edge (length 12) they carry the net external force `(0, 12 q)` and
/// their internal forces cancel (no contact): between two history rows with no split between
/// them their momentum grows by `(0, 12 q dT)` (tolerance 1e-9 relative to the change: round-off of the
/// sums; a wrong load, mass or step breaks it). The energy residual of the explicit part is at
/// most 1e-3 of the work done in it (the tolerance; the scheme is exact to round-off for
/// linear elasticity). The split log up to the hand-over is the `stop` run's, bit for bit, and
/// the fragment leaves (moves more than 0.1 of the diagonal).
#[test]
fn loose_fragment_hands_over_and_the_fragment_is_pulled_away() {
    let mut stop = notch_with("on_loose_fragment = \"stop\"", "");
    let mut slog = SplitLog { splits: Vec::new(), stop_after: usize::MAX };
    stop.run(&mut slog).unwrap();
    let mut sim = notch_with("damping = { type = \"none\" }", "");
    sim.scene.file.output.history_every = 5;
    let mut obs = Rows::default();
    sim.run(&mut obs).unwrap();
    assert!(obs.log.len() > slog.splits.len(), "no split in the march: {} and {}", obs.log.len(), slog.splits.len());
    assert_eq!(obs.log[..slog.splits.len()], slog.splits[..], "the split log up to the hand-over changed");
    let h = sim.hand_over.clone().unwrap_or_else(|| panic!("no hand-over: {:?}", sim.warnings));
    println!(
        "hand-over: {:?} after {} steps and {} splits, dt {:e}, time {:e}, work {:e}, residual {:e}, moved {:e}",
        h.end,
        h.steps,
        h.splits,
        h.dt,
        h.time,
        h.work(),
        h.relative_residual(),
        h.moved
    );
    assert_eq!(h.end, flem_core::solver::events::HandOverEnd::Left);
    assert!(sim.stages_done[0].converged && sim.stages_done[0].energy_residual == h.relative_residual());
    assert!(h.work() > 0.0 && h.relative_residual() <= 1e-3, "{h:?}");
    assert!(h.moved > 0.1 * (2.0f64 * 144.0).sqrt());
    let q = sim.levels[0];
    assert!(q == slog.splits.last().unwrap().levels[0], "the load is not held at the last event's level");
    // Consecutive rows with no split between them (history every 5 steps, checks every 10)
    // and the top edge on free fragments.
    let mut pairs = 0;
    for w in obs.rows.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        if a.1 != b.1 || !a.3 || !b.3 || b.0 <= a.0 {
            continue;
        }
        let expect = 12.0 * q * (b.0 - a.0);
        let dp = [b.2[0] - a.2[0], b.2[1] - a.2[1]];
        assert!(rel(dp[1], expect) < 1e-9 && dp[0].abs() < 1e-9 * expect, "momentum change {dp:?} from time {} to {}, expected (0, {expect:e})", a.0, b.0);
        pairs += 1;
    }
    println!("{pairs} intervals checked against 12 q dT");
    assert!(pairs >= 10, "{pairs} intervals without a split");
    assert!(sim.warnings.iter().any(|w| w.contains("hand_over") && w.contains("fragment left")), "{:?}", sim.warnings);
}

/// The same with the scene's default damping (adaptive dynamic relaxation): the energy
/// residual of the explicit part stays at most 1e-3 of its work (reference: the balance
/// `W = KE + U + D`, exact to round-off for the scheme; measured 1.1e-13), the fragment leaves,
/// and a later stage is skipped with a warning. With `[contact]` (allowed in an events scene
/// only for the hand-over; the `cohesive` law, whose energy accounting is the most complete)
/// the run goes through and the fragment leaves, but the ledger does not close to 1e-3: its
/// residual is asserted below 5e-2 (measured 3.0e-2; `spring_dashpot` 0.31), a limit written in
/// docs/events.md: the march splits at every check (212 splits in 2120 steps) and the contact
/// ledger's per-pair terms of births, releases and splits (tests/contact.rs) do not add up
/// there; not investigated further. `stop` with `[contact]` is refused naming the key.
#[test]
fn loose_fragment_hand_over_with_damping_and_contact_balances_energy() {
    let contact = "\n[contact]\nlaw = { type = \"cohesive\", normal_stiffness = 4000.0, shear_stiffness = 1600.0, tensile_strength = 1.0, fracture_energy = 0.001, friction = 0.5 }\n";
    let second = "\n[[stage]]\nname = \"more\"\nlevels = { pull = 0.3 }\n";
    for extra in [second.to_string(), format!("{contact}{second}")] {
        let mut sim = notch_with("", &extra);
        sim.run(&mut NoOutput).unwrap();
        let h = sim.hand_over.clone().unwrap_or_else(|| panic!("no hand-over: {:?}", sim.warnings));
        println!(
            "contact {}: {:?} after {} steps and {} splits, work {:e}, residual {:e} (signed {:e})",
            sim.contact.is_some(),
            h.end,
            h.steps,
            h.splits,
            h.work(),
            h.relative_residual(),
            h.end_ledger.residual()
        );
        if sim.contact.is_some() {
            assert!(h.work() > 0.0 && h.relative_residual() <= 5e-2, "{h:?}");
        } else {
            assert!(h.work() > 0.0 && h.relative_residual() <= 1e-3, "{h:?}");
        }
        assert_eq!(h.end, flem_core::solver::events::HandOverEnd::Left);
        assert_eq!(sim.stages_done.len(), 1, "{:?}", sim.stages_done);
        assert!(sim.warnings.iter().any(|w| w.contains("\"more\" skipped")), "{:?}", sim.warnings);
    }
    let path = root().join("configs/events/notch_plate_h0.25.toml");
    let text = std::fs::read_to_string(&path).unwrap().replace("type = \"events\"\n", "type = \"events\"\non_loose_fragment = \"stop\"\n") + contact;
    let e = Scene::from_str(&text, &path, path.parent().unwrap()).err().expect("refused").to_string();
    assert!(e.contains("solver.type") && e.contains("[contact]") && e.contains("notch_plate_h0.25.toml"), "{e}");
}

/// Issue 35 (loose end): the run's warnings go into checkpoints. Stage 0 of the notched plate
/// stops at `solver.max_events = 3` with a warning; a checkpoint taken at the stage's end and
/// restored into a new simulation of the same scene carries that warning (before: only the
/// warnings of building the model, so a resumed run's summary lost the earlier stages').
#[test]
fn warnings_of_earlier_stages_survive_a_checkpoint() {
    use flem_core::output::checkpoint::Checkpoint;
    use flem_core::solver::StagePos;
    let mk = || {
        let mut sc = scene("notch_plate_h0.25.toml");
        sc.file.solver.max_events = 3;
        Simulation::new(sc).unwrap()
    };
    let mut sim = mk();
    sim.run_stage(0, &mut NoOutput).unwrap();
    assert!(sim.warnings.iter().any(|w| w.contains("max_events = 3")), "{:?}", sim.warnings);
    let ck = Checkpoint::capture(&sim, &StagePos::start(1)).unwrap();
    let mut resumed = mk();
    assert!(!resumed.warnings.iter().any(|w| w.contains("max_events = 3")));
    ck.restore(&mut resumed).unwrap();
    assert_eq!(resumed.warnings, sim.warnings);
}
