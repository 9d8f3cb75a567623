//! `flem`: run, check and inspect FLEM scenes.
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use flem_core::output::OutputWriter;
use flem_core::scene::Scene;
use flem_core::solver::NoOutput;
use flem_core::solver::{Simulation, StagePos};
use flem_core::FlemError;
use indicatif::{ProgressBar, ProgressStyle};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

mod bench;
mod bench3;
mod bench_answer;
mod bench_contact;
mod bench_dyncall;
mod bench_events;
mod bench_laws;
mod chart;
mod chart_crack;
mod converge;
mod dyncall_kinds;
mod fos;
mod paths;
mod sif;
mod stability;
mod sweep;

/// The scene run by `flem` (and `cargo run --release`) with no arguments.
/// The paper's opening model as the paper ran it (issues 8, 17): a notched plate pulled from both
/// sides, cracking in tension at p/(rho g) = 115, pictures in plots/.
const DEFAULT_SCENE: &str = include_str!("../../configs/paper/opening.toml");
const DEFAULT_NAME: &str = "configs/paper/opening.toml";

#[derive(Parser)]
#[command(name = "flem", version, about = "FLEM: the flow element method with cracking")]
struct Cli {
    #[command(subcommand)]
    cmd: Option<Cmd>,
    /// Let scenes load the native plugin libraries they name in `[plugins] load` (code that runs
    /// on this machine: give it only for scenes you trust). Without it such a scene is refused,
    /// unless the library lies in a folder listed in FLEM_PLUGIN_PATH or in
    /// ~/.config/flem/plugins; `flem check` then validates the rest of the scene without loading.
    #[arg(long, global = true)]
    allow_plugins: bool,
}

#[derive(Subcommand)]
enum Cmd {
    /// Factor of safety by strength reduction (c and tan(phi) divided by F, bisection on F;
    /// ours, docs/materials.md): DIR/fos.json and the mechanism picture.
    Fos(fos::Args),
    /// Stress intensity factors K_I, K_II at the crack tips (pre-cut edges) from the implicit
    /// solve of each stage: interaction integral on 2-3 domains, J as a check, the maximum
    /// tangential stress kink angle (docs/paths.md). Prints a table, writes DIR/sif.json.
    Sif(sif::Args),
    /// Crack paths (issue 34): runs scenes and measures the new crack's kink over its first
    /// element sizes at every initial tip against the MTS angle of the implicit solution, and
    /// the debris (docs/paths.md). Prints a table; --out writes JSON.
    Paths(paths::Args),
    /// Run a scene: stages to equilibrium, results (VTU/PVD, history.csv, summary.json) into --out.
    Run {
        scene: PathBuf,
        /// Output folder (default: out/<scene name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
        /// Continue from the newest valid checkpoint in this folder (results go on there
        /// unless --out says otherwise).
        #[arg(long, value_name = "DIR")]
        resume: Option<PathBuf>,
        /// Draw the pictures at the end (as `flem plot`; also when the scene sets output.plots).
        #[arg(long)]
        plot: bool,
        /// Quick look: cap every stage's step limit (and solver.max_events) at N; a stage that
        /// reaches it is not in equilibrium and says so.
        #[arg(long, value_name = "N")]
        max_steps: Option<u64>,
    },
    /// Draw a finished run's pictures (PNG and SVG) into RUN_DIR/plots: deformed mesh frames,
    /// crack sequence, load-displacement curve.
    Plot { run_dir: PathBuf },
    /// Validate a scene (and build its mesh) without running it; exit 1 with the message on error.
    Check { scenes: Vec<PathBuf> },
    /// List the built-in plugins (kind and name) and the dynamic ones loaded with --load or by a
    /// scene's `[plugins] load`, with the file each came from.
    Plugins {
        /// A plugin library to load (repeatable).
        #[arg(long)]
        load: Vec<PathBuf>,
        /// A scene whose `[plugins] load` libraries to load.
        scene: Option<PathBuf>,
    },
    /// The speed-accuracy chart: sweep damping, dt safety, tolerance and mesh refinement;
    /// wall time against the error (vs the implicit solve, a refined reference, or an
    /// analytic probe value); Pareto front marked. Writes chart.csv, chart.json and pictures.
    Chart {
        scene: PathBuf,
        /// Output folder (default: out/<scene name>_chart).
        #[arg(long)]
        out: Option<PathBuf>,
        /// A small sweep (2 dampings x 1 safety x 2 tolerances x 2 refinements).
        #[arg(long)]
        quick: bool,
        /// Analytic value of a probe's displacement: PROBE:x=VALUE or PROBE:y=VALUE.
        #[arg(long)]
        analytic: Option<chart::Analytic>,
        /// Run only the first K stages (e.g. the elastic stage of a cracking scene).
        #[arg(long, value_name = "K")]
        stages: Option<usize>,
        /// Drop the scene's [cracking] (the elastic problem; pre-separated edges stay).
        #[arg(long)]
        no_cracking: bool,
        /// Element kinds to sweep too (e.g. q4,qm6), set on every [[material]]; default: the
        /// scene's own.
        #[arg(long, value_delimiter = ',')]
        elements: Vec<String>,
        /// Quick look: cap every stage's step limit (and solver.max_events) at N; a stage that
        /// reaches it is not in equilibrium and says so.
        #[arg(long, value_name = "N")]
        max_steps: Option<u64>,
    },
    /// Speed against accuracy for cracking (ours, issue 19): explicit runs in load steps of 5,
    /// 2, 1, 0.5 % at two tolerances and the events solver, per one-stage events scene: errors
    /// of the initiation load and of the crack path (PNG, SVG, CSV; a Markdown table instead of
    /// a chart for an error that is the same in every run; docs/events.md).
    ChartCrack {
        /// One-stage events scenes (configs/events/).
        #[arg(required = true)]
        scenes: Vec<PathBuf>,
        /// Output folder (default: out/chart_crack).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Compare the first N splits of every run.
        #[arg(long, default_value_t = 12)]
        splits: usize,
        /// A small sweep: load steps of 5 and 2 % at the tolerance 1e-4 (the reference path is
        /// then the 2 % run's).
        #[arg(long)]
        quick: bool,
        /// Instead: the path error (Hausdorff distance to the finest mesh's path, % of the
        /// specimen) against wall time, the edge rule beside `tip_mts` (issue 34), over the
        /// scenes given (one benchmark on several meshes, e.g. configs/paths/sen_*.toml).
        #[arg(long)]
        paths: bool,
        /// With --paths: the path method's rule and keys instead of `tip_mts` with its
        /// defaults, as TOML of `[cracking.separation]` (as `flem paths --separation`), e.g.
        /// $'type = "tip_mts"\nevery = 1.25\npiece = 0.05\nshrink = 1.5'.
        #[arg(long, requires = "paths")]
        separation: Option<String>,
    },
    /// The stability map: measured blow-up step against the prediction per mesh and damping,
    /// steps to rest against the damping parameter, the implicit solver after separation.
    Stability {
        /// Output folder (default: out/stability).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Fewer cases and shorter runs.
        #[arg(long)]
        quick: bool,
    },
    /// Run a scene and, after every stage, the implicit check solve on the same model: per-stage
    /// VTU with both fields and their differences, and compare.json, into --out.
    Compare {
        scene: PathBuf,
        /// Output folder (default: out/<scene name>_compare).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Quick look: cap every stage's step limit (and solver.max_events) at N; a stage that
        /// reaches it is not in equilibrium and says so.
        #[arg(long, value_name = "N")]
        max_steps: Option<u64>,
    },
    /// Crack-initiation load under mesh refinement (exact, by the check solver; local and
    /// nonlocal check), checked by explicit runs: converge.json and converge.png/.svg in --out.
    Converge(converge::Args),
    /// A parameter sweep (SWEEP.toml: the scene, a [grid] of key-path values or [[task]]
    /// tables): each task in its own folder, run by N local worker processes (not Dask; the
    /// Python package's flem.sweep runs the same tasks on Dask), one row per task in sweep.csv.
    Sweep {
        sweep: PathBuf,
        /// Worker processes (default: one per core).
        #[arg(long)]
        workers: Option<usize>,
    },
    /// One sweep task (used by `flem sweep`): its row as JSON on stdout.
    #[command(hide = true)]
    SweepTask {
        scene: PathBuf,
        #[arg(long)]
        task: usize,
        #[arg(long)]
        out: PathBuf,
        #[arg(long, default_value_t = 1)]
        threads: usize,
        /// The parameters, a TOML table of key paths.
        #[arg(long)]
        params: String,
    },
    /// Benchmarks; each prints JSON.
    Bench {
        #[command(subcommand)]
        what: BenchWhat,
    },
}

#[derive(Subcommand)]
enum BenchWhat {
    /// The implicit check solver (assembly, factorisation, solve) against faer's bare Cholesky
    /// on the same matrix, on structured Q4 meshes.
    Implicit {
        /// Target numbers of dofs, comma separated.
        #[arg(long, value_delimiter = ',', default_values_t = vec![1e4, 1e5, 5e5])]
        dofs: Vec<f64>,
        /// Repetitions per size (the best time is kept).
        #[arg(long, default_value_t = 2)]
        repeats: usize,
        /// Thread counts (a pool of each size; faer's factorisation and solves use it).
        #[arg(long, value_delimiter = ',', default_value = "1,2")]
        threads: Vec<usize>,
    },
    /// Explicit step throughput: bare kernel (ns per element-update, 1 and N threads, Q4/T3),
    /// memory per element, full step against the bare step, failure checks every k steps.
    Step {
        /// Element counts of the kernel runs (2 x 1 rectangle).
        #[arg(long, value_delimiter = ',', default_value = "1000,10000,100000,1000000")]
        sizes: Vec<usize>,
        /// Thread counts (0: one per core).
        #[arg(long, value_delimiter = ',', default_value = "1,2")]
        threads: Vec<usize>,
        /// Element kinds (registered names: q4, t3, qm6, ...; `flem plugins` lists them).
        #[arg(long, value_delimiter = ',', default_value = "q4,t3")]
        kinds: Vec<String>,
        /// Element counts of the full-step and failure-check runs.
        #[arg(long, value_delimiter = ',', default_value = "10000,100000")]
        step_sizes: Vec<usize>,
        /// Seconds spent per timing (median of 5 batches).
        #[arg(long, default_value_t = 1.0)]
        min_time: f64,
        /// Radius of the nonlocal failure check (ours, issue 18), in element sizes.
        #[arg(long, default_value_t = 2.0)]
        nonlocal_radius_h: f64,
        /// Rounds of every figure (each printed as median and range; at least 5).
        #[arg(long, default_value_t = 5)]
        rounds: usize,
        /// Element counts of the step's task-graph analysis, Q4 and T3 with and without a
        /// crack (0: none).
        #[arg(long, value_delimiter = ',', default_value = "100000,1000000")]
        graph_sizes: Vec<usize>,
        /// Dataflows of the kernel runs on several threads, each timed in every round (auto,
        /// phases, local: `flem_core::element::kernel::Dataflow`; the same forces bit for bit).
        #[arg(long, value_delimiter = ',', default_value = "auto")]
        dataflows: Vec<flem_core::element::kernel::Dataflow>,
    },
    /// Cost of a dynamic (shared-library) criterion in the failure check, against the built-in
    /// one and against the whole step.
    Dyncall(bench_dyncall::Args),
    /// The 3D explicit step (issue 38): ns per element-update of T4 and H8 boxes on 1 and 2
    /// threads, bit-identity across threads, the fraction of the triad (docs/3d.md "Speed").
    Step3(bench3::Args),
    /// Time to answer of the plastic verification scenes (the strip footings' plateau, the
    /// slope's factor of safety), explicit beside implicit, and the chart of wall time against
    /// error (ours, issue 37; docs/materials.md).
    Answer(bench_answer::Args),
    /// ns per element-update of the material laws (mohr_coulomb, large strain) against the
    /// linear elastic kernel (issue 21).
    Laws {
        /// Element count (Q4).
        #[arg(long, default_value_t = 100000)]
        elements: usize,
        /// Seconds spent per timing (median of 5 batches).
        #[arg(long, default_value_t = 1.0)]
        min_time: f64,
        /// Cases to time (names as in the JSON; `elastic`, the reference, always runs). All when empty.
        #[arg(long, value_delimiter = ',')]
        cases: Vec<String>,
    },
    /// Contact search cost against the number of surface nodes, with the growth exponent.
    Contact {
        /// Surface-node counts to measure.
        #[arg(long, value_delimiter = ',', default_values_t = vec![1000usize, 10000, 100000])]
        sizes: Vec<usize>,
        /// Timed repetitions per size (the best is kept).
        #[arg(long, default_value_t = 5)]
        repeats: usize,
    },
    /// The events solver (ours, issue 19): wall time per crack event against dofs, with the
    /// growth exponent.
    Events {
        /// Target numbers of dofs, comma separated.
        #[arg(long, value_delimiter = ',', default_values_t = vec![1e3, 1e4, 1e5])]
        dofs: Vec<f64>,
        /// Events per size (the stage stops there: solver.max_events).
        #[arg(long, default_value_t = 10)]
        events: u64,
        /// Instead: per event, a fresh factorisation against a kept factor with a Woodbury
        /// (capacitance) update, on the same matrices (flem_plugins::check::woodbury).
        #[arg(long)]
        woodbury: bool,
        /// solver.refactor_every of the runs (0: a fresh factorisation per event).
        #[arg(long, default_value_t = 50)]
        refactor_every: usize,
    },
    /// A one-stage events scene's crack path by events and by the explicit solver in load
    /// steps: wall times, their ratio, and the agreement of the split logs.
    EventsPath {
        scene: PathBuf,
        /// Explicit load step, as a fraction of the stage's levels.
        #[arg(long, default_value_t = 0.005)]
        step: f64,
        /// Step limit of each explicit stage.
        #[arg(long, default_value_t = 1_000_000)]
        max_steps: u64,
        /// Equilibrium tolerance (unbalanced-force ratio) of the explicit stages.
        #[arg(long, default_value_t = 1e-5)]
        tolerance: f64,
        /// Compare at most this many splits (default: all the events run made).
        #[arg(long)]
        splits: Option<usize>,
        /// Events runs timed (the best is kept; the explicit run is timed once).
        #[arg(long, default_value_t = 3)]
        repeats: usize,
        /// Time the events run only (no explicit run).
        #[arg(long)]
        events_only: bool,
    },
}

fn main() -> ExitCode {
    flem_plugins::link();
    let cli = Cli::parse();
    flem_core::plugin::dynload::set_scene_plugin_consent(cli.allow_plugins);
    // 3D scenes (issue 38) go to `flem run` and `flem check`; the other commands are 2D only
    // for now and say so.
    let three_d: Option<(&str, PathBuf)> = match &cli.cmd {
        Some(Cmd::Chart { scene, .. }) => Some(("chart", scene.clone())),
        Some(Cmd::SweepTask { scene, .. }) => Some(("sweep-task", scene.clone())),
        Some(Cmd::Converge(a)) => Some(("converge", a.scene.clone())),
        Some(Cmd::Fos(a)) => Some(("fos", a.scene.clone())),
        Some(Cmd::Sif(a)) => Some(("sif", a.scene.clone())),
        Some(Cmd::ChartCrack { scenes, .. }) => scenes.iter().find(|p| is_3d(p)).map(|p| ("chart-crack", p.clone())),
        Some(Cmd::Paths(a)) => a.scenes.iter().find(|p| is_3d(p)).map(|p| ("paths", p.clone())),
        _ => None,
    }
    .filter(|(_, p)| is_3d(p));
    let r = match cli.cmd {
        _ if three_d.is_some() => {
            let (tool, p) = three_d.unwrap();
            Err(unsuited(&p, tool, "it is a 3D scene ([model] dim = 3); `flem run`, `flem check` and `flem compare` take 3D scenes, the other commands are 2D only for now (docs/3d.md)"))
        }
        None => run_default(),
        Some(Cmd::Run { scene, out, quiet: _, resume, plot, max_steps }) if is_3d(&scene) => run3(&scene, out, resume, plot, max_steps),
        Some(Cmd::Run { scene, out, quiet, resume, plot, max_steps }) => load(&scene).and_then(|mut s| {
            cap_steps(&mut s, max_steps);
            run(s, out, quiet, resume, plot)
        }),
        Some(Cmd::Plot { run_dir }) => plot(&run_dir),
        Some(Cmd::Check { scenes }) => check(&scenes),
        Some(Cmd::Chart { scene, out, quick, analytic, stages, no_cracking, elements, max_steps }) => chart::chart(&scene, out, quick, analytic, stages, no_cracking, &elements, max_steps),
        Some(Cmd::Stability { out, quick }) => stability::run(out, quick),
        Some(Cmd::ChartCrack { scenes, out, splits, quick, paths, separation }) => {
            if paths {
                chart_crack::run_paths(&scenes, out, separation.as_deref())
            } else {
                chart_crack::run(&scenes, out, splits, quick)
            }
        }
        Some(Cmd::Compare { scene, out, max_steps }) if is_3d(&scene) => compare3(&scene, out, max_steps),
        Some(Cmd::Compare { scene, out, max_steps }) => load(&scene).and_then(|mut s| {
            cap_steps(&mut s, max_steps);
            compare(s, out)
        }),
        Some(Cmd::Bench { what }) => bench(what),
        Some(Cmd::Sweep { sweep, workers }) => sweep::run(&sweep, workers, cli.allow_plugins),
        Some(Cmd::SweepTask { scene, task, out, threads, params }) => sweep::task(&scene, task, &out, threads, &params),
        Some(Cmd::Converge(a)) => converge::run(a),
        Some(Cmd::Fos(a)) => fos::run(a),
        Some(Cmd::Sif(a)) => sif::run(a),
        Some(Cmd::Paths(a)) => paths::run(a),
        Some(Cmd::Plugins { load, scene }) => plugins(&load, scene.as_deref()),
    };
    match r {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.downcast_ref::<Stopped>().is_some() => {
            eprintln!("{e:#}");
            ExitCode::from(130)
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn bench_step(
    sizes: Vec<usize>,
    threads: Vec<usize>,
    kinds: Vec<String>,
    step_sizes: Vec<usize>,
    min_time: f64,
    nonlocal_radius_h: f64,
    rounds: usize,
    graph_sizes: Vec<usize>,
    dataflows: Vec<flem_core::element::kernel::Dataflow>,
) -> Result<()> {
    anyhow::ensure!(!dataflows.is_empty(), "--dataflows: give at least one (auto, phases, local)");
    anyhow::ensure!(nonlocal_radius_h > 0.0 && nonlocal_radius_h.is_finite(), "--nonlocal-radius-h = {nonlocal_radius_h} is incorrect; it must be > 0");
    let kinds = kinds
        .iter()
        .map(|k| {
            flem_core::element::registry::find(k).ok_or_else(|| {
                let names: Vec<&str> = flem_core::element::registry::kinds().iter().map(|k| k.name).collect();
                anyhow::anyhow!("--kinds: \"{k}\" is incorrect; it must be one of {names:?}")
            })
        })
        .collect::<Result<Vec<_>>>()?;
    anyhow::ensure!(min_time > 0.0 && min_time.is_finite(), "--min-time = {min_time} is incorrect; it must be > 0");
    anyhow::ensure!(sizes.iter().chain(&step_sizes).all(|&n| (8..=16_000_000).contains(&n)), "--sizes/--step-sizes: each must be in [8, 16000000]");
    anyhow::ensure!(rounds >= 5, "--rounds = {rounds} is incorrect; it must be at least 5 (a median and a range need them)");
    let graph_sizes: Vec<usize> = graph_sizes.into_iter().filter(|&n| n != 0).collect();
    anyhow::ensure!(graph_sizes.iter().all(|&n| (8..=16_000_000).contains(&n)), "--graph-sizes: each must be 0 or in [8, 16000000]");
    bench::step(&bench::StepOpts { sizes, threads, kinds, min_time, step_sizes, nonlocal_radius_h, rounds, graph_sizes, dataflows })
}

fn plugins(libs: &[PathBuf], scene: Option<&Path>) -> Result<()> {
    for l in libs {
        flem_core::plugin::dynload::load_library(l)?;
    }
    if let Some(p) = scene {
        let text = std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))?;
        flem_core::plugin::dynload::load_scene_plugins(&text, &p.display().to_string(), p.parent().unwrap_or(Path::new("")))?;
    }
    for (kind, name) in flem_plugins::registry() {
        println!("{kind:<12} {name}");
    }
    for p in flem_core::plugin::dynload::loaded() {
        println!("{:<12} {:<24} loaded from {} (FLEM core {}, {})", p.kind, p.name, p.file.display(), p.core_version, p.rustc_version);
    }
    Ok(())
}

/// Whether the scene file asks for 3D (`[model] dim = 3`; issue 38). An unreadable file is
/// not: the 2D path then says why it cannot read it.
fn is_3d(path: &Path) -> bool {
    std::fs::read_to_string(path).is_ok_and(|t| flem_core::scene3::scene_dim(&t) == 3)
}

/// `flem run` on a 3D scene (`output::run3`: snapshots, history.csv, splits3.csv,
/// summary.json, checkpoints); `--resume` continues in the folder of its checkpoints; `--plot`
/// is not available in 3D yet.
fn run3(path: &Path, out: Option<PathBuf>, resume: Option<PathBuf>, plot: bool, max_steps: Option<u64>) -> Result<()> {
    anyhow::ensure!(!plot, "{}: --plot is not available for 3D scenes yet (ParaView or pyvista read the VTU; docs/3d.md)", path.display());
    let mut scene = load3(path, max_steps)?;
    let stem = path.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "run".into());
    let out = out.or_else(|| resume.clone()).unwrap_or_else(|| PathBuf::from("out").join(stem));
    if let Some(r) = &resume {
        anyhow::ensure!(
            r.canonicalize().ok().zip(out.canonicalize().ok()).map_or(r == &out, |(a, b)| a == b),
            "{}: a 3D run resumes in the folder of its checkpoints ({}); leave out --out or give the same folder",
            path.display(),
            r.display()
        );
    }
    let _lock = lock_out(&out)?;
    flem_core::output::prepare_dir(&out)?;
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register_conditional_shutdown(sig, 130, Arc::clone(&stop)).context("installing the signal handler")?;
        signal_hook::flag::register(sig, Arc::clone(&stop)).context("installing the signal handler")?;
    }
    let t0 = std::time::Instant::now();
    let (m, stages) = match flem_core::output::run3::run3_with(&mut scene, &out, resume.is_some(), Some(stop)) {
        Err(e @ FlemError::Interrupted { .. }) => {
            return Err(Stopped(format!("flem: {e}: a checkpoint is in {}\nresume with: {}", out.display(), resume_command(path, &out))).into());
        }
        r => r?,
    };
    for w in &m.warnings {
        eprintln!("warning: {w}");
    }
    eprintln!("3D: {} elements, {} points; dt = {:.4e}", m.topo.n_elems(), m.topo.n_points, m.dt);
    for r in &stages {
        let how = if r.at_rest { "in equilibrium".to_string() } else { "step limit or end time: NOT in equilibrium".to_string() };
        eprintln!("{}: {} steps, ratio {:.2e} ({how}), {} splits, {} fragment(s)", r.name, r.steps, r.ratio, r.splits, r.fragments);
    }
    eprintln!("wall time {:.2} s; results in {}", t0.elapsed().as_secs_f64(), out.display());
    Ok(())
}

/// A 3D scene, every stage's step limit capped at `max_steps`.
fn load3(path: &Path, max_steps: Option<u64>) -> Result<flem_core::scene3::Scene3> {
    let mut scene = flem_core::scene3::Scene3::from_file(path)?;
    if let Some(n) = max_steps {
        let f = &mut scene.file;
        let global = f.solver.max_steps;
        f.solver.max_steps = global.min(n);
        for s in &mut f.stages {
            s.max_steps = Some(s.max_steps.unwrap_or(global).min(n));
        }
    }
    Ok(scene)
}

/// `flem compare` on a 3D scene: the run with the implicit check after every stage
/// (`output::compare3`), the scene's `[check]` or the defaults with 2D's tolerance rule.
fn compare3(path: &Path, out: Option<PathBuf>, max_steps: Option<u64>) -> Result<()> {
    let mut scene = load3(path, max_steps)?;
    if scene.file.check.is_none() {
        let f = &scene.file;
        let loosest = f.stages.iter().map(|s| s.tolerance.unwrap_or(f.solver.tolerance)).fold(f.solver.tolerance, f64::max);
        let tol = (1000.0 * loosest).clamp(1e-6, 0.1);
        eprintln!("the scene has no [check]: the comparison tolerance is {tol:e} (1000 x its loosest equilibrium tolerance, within [1e-6, 0.1]; ours)");
        let mut c = flem_core::plugin::check::CheckCfg::with_defaults(&path.display().to_string())?;
        c.tolerance = tol;
        scene.file.check = Some(c);
    }
    let tol = scene.file.check.as_ref().map_or(0.0, |c| c.tolerance);
    let stem = path.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "run".into());
    let out = out.unwrap_or_else(|| PathBuf::from("out").join(format!("{stem}_compare")));
    let _lock = lock_out(&out)?;
    flem_core::output::prepare_dir(&out)?;
    flem_core::output::run3::run3_in_folder(&mut scene, &out)?;
    let json = out.join("compare.json");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).with_context(|| json.display().to_string())?).with_context(|| json.display().to_string())?;
    let rows: Vec<flem_core::output::compare::StageComparison> = serde_json::from_value(v["stages"].clone())?;
    print!("{}", flem_core::output::compare::table(&rows));
    println!("results in {}", json.display());
    judge_compare(&rows, tol)
}

/// The verdict of `flem compare` (2D and 3D): only comparable stages judge; a stage without an
/// equilibrium to compare is reported.
fn judge_compare(rows: &[flem_core::output::compare::StageComparison], tol: f64) -> Result<()> {
    let failed: Vec<&str> = rows.iter().filter(|r| r.comparable && r.implicit_error.is_some()).map(|r| r.name.as_str()).collect();
    anyhow::ensure!(failed.is_empty(), "the implicit solve failed at comparable stage(s) {failed:?} (see above and compare.json)");
    let off: Vec<&str> = rows.iter().filter(|r| r.comparable && !r.within_tolerance).map(|r| r.name.as_str()).collect();
    anyhow::ensure!(off.is_empty(), "FLEM and the implicit solve disagree beyond check.tolerance = {tol:e} at comparable stage(s) {off:?} (see above and compare.json)");
    let nc = rows.iter().filter(|r| !r.comparable).count();
    if nc > 0 {
        println!("{nc} of {} stage(s) not comparable (the reasons above; compare.json: comparable = false, reason)", rows.len());
    }
    Ok(())
}

fn load(path: &Path) -> Result<Scene> {
    Ok(Scene::from_file(path)?)
}

fn run_default() -> Result<()> {
    let scene = Scene::from_str(DEFAULT_SCENE, Path::new(DEFAULT_NAME), Path::new("configs/paper"))?;
    eprintln!("flem: no scene given, running the default scene {DEFAULT_NAME} (see `flem --help`)");
    run(scene, None, false, None, false)
}

/// Locks a run's output folder for this process (`flem_core::output::lock`), naming this
/// command in the lock file; a folder held by another run is refused.
pub(crate) fn lock_out(out: &Path) -> Result<flem_core::output::lock::DirLock> {
    let cmd: Vec<String> = std::env::args().collect();
    let l = flem_core::output::lock::lock_dir(out, &cmd.join(" "))?;
    if let Some(n) = &l.note {
        eprintln!("warning: {n}");
    }
    Ok(l)
}

/// The refusal of a tool whose method does not apply to a scene (exit 1): "SCENE does not suit
/// `flem TOOL`: WHY" (tests/tools.rs looks for these words).
pub(crate) fn unsuited(scene: &Path, tool: &str, why: impl std::fmt::Display) -> anyhow::Error {
    anyhow::anyhow!("{} does not suit `flem {tool}`: {why}", scene.display())
}

/// Caps every stage's step limit (and the events solver's event limit) at `n`: the quick look
/// of `--max-steps` (a stage that reaches it is not in equilibrium, and says so).
pub(crate) fn cap_steps(scene: &mut Scene, n: Option<u64>) {
    let Some(n) = n else { return };
    let f = &mut scene.file;
    let global = f.solver.max_steps;
    f.solver.max_steps = global.min(n);
    f.solver.max_events = f.solver.max_events.min(n);
    for s in &mut f.stages {
        s.max_steps = Some(s.max_steps.unwrap_or(global).min(n));
    }
}

/// A run stopped by SIGINT/SIGTERM after writing a checkpoint (exit code 130).
#[derive(Debug)]
struct Stopped(String);
impl std::fmt::Display for Stopped {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}
impl std::error::Error for Stopped {}

/// The command that resumes a run, for messages.
fn resume_command(scene: &Path, out: &Path) -> String {
    let q = |p: &Path| {
        let s = p.display().to_string();
        if s.chars().all(|c| c.is_ascii_alphanumeric() || "/._-+:,=".contains(c)) {
            s
        } else {
            format!("'{}'", s.replace('\'', "'\\''"))
        }
    };
    format!("flem run {} --resume {}", q(scene), q(out))
}

fn check(scenes: &[PathBuf]) -> Result<()> {
    anyhow::ensure!(!scenes.is_empty(), "give at least one scene file");
    for p in scenes {
        if is_3d(p) {
            let mut scene = flem_core::scene3::Scene3::from_file(p)?;
            let m = flem_core::solver::march3::March3::from_scene(&mut scene)?;
            for w in &m.warnings {
                eprintln!("warning: {w}");
            }
            println!("{}: ok (3D: {} elements, {} points, {} stages, dt = {:.3e})", p.display(), m.topo.n_elems(), m.topo.n_points, scene.file.stages.len(), m.dt);
            continue;
        }
        let (scene, notes) = load_for_check(p)?;
        let sim = match Simulation::new(scene) {
            Ok(s) => s,
            Err(e) => {
                // What was not loaded may be why (a stand-in criterion or rule).
                for n in &notes {
                    eprintln!("note: {n}");
                }
                return Err(e.into());
            }
        };
        for w in &sim.warnings {
            eprintln!("warning: {w}");
        }
        for n in &notes {
            eprintln!("note: {n}");
        }
        println!(
            "{}: ok ({} elements, {} points, {} stages, dt = {:.3e}, dt_crit = {:.3e}){}",
            p.display(),
            sim.model.n_elems(),
            sim.model.topo.n_points,
            sim.scene.file.stages.len(),
            sim.dt,
            sim.stable.dt_crit,
            if notes.is_empty() { "" } else { "; its plugin libraries were not loaded (see the notes)" }
        );
    }
    Ok(())
}

/// A scene for `flem check`: loaded as `flem run` would, except that plugin libraries the user
/// has not consented to (`--allow-plugins`, trusted folders) are not loaded. The scene is then
/// validated without them: its `[plugins]` table is left out and a criterion or separation rule
/// that is not built in stands in as a built-in (rankine, sigma1_nearest) so that everything
/// else is checked; the notes say what was not.
fn load_for_check(p: &Path) -> Result<(Scene, Vec<String>)> {
    use flem_core::plugin::dynload::{self, abi};
    let text = std::fs::read_to_string(p).map_err(|e| FlemError::config(p.display().to_string(), "", format!("cannot be read: {e}")))?;
    let base = p.parent().map(Path::to_path_buf).unwrap_or_default();
    let name = p.display().to_string();
    let libs = dynload::scene_plugin_paths(&text, &name, &base)?;
    if libs.iter().all(|(_, _, full)| dynload::may_load(full)) {
        return Ok((Scene::from_str(&text, p, &base)?, Vec::new()));
    }
    let mut doc: toml::Table = toml::from_str(&text).context("the scene is not TOML")?;
    doc.remove("plugins");
    let mut notes: Vec<String> = libs.iter().map(|(k, s, _)| format!("{name}: {k} = \"{s}\" was not loaded (no --allow-plugins; nothing of the scene's plugin libraries was)")).collect();
    if let Some(cr) = doc.get_mut("cracking").and_then(|c| c.as_table_mut()) {
        for (key, kind, stand_in) in [("criterion", abi::KIND_CRITERION, "type = \"rankine\"\ntensile_strength = 1.0"), ("separation", abi::KIND_SEPARATION, "type = \"sigma1_nearest\"")] {
            let Some(t) = cr.get(key).and_then(|v| v.get("type")).and_then(|v| v.as_str()).map(str::to_string) else { continue };
            if !dynload::is_builtin(kind, &t) {
                notes.push(format!("{name}: cracking.{key}.type = \"{t}\" is not built in; it would come from the plugin libraries, so it and its parameters were not checked"));
                cr.insert(key.into(), toml::Value::Table(toml::from_str(stand_in).expect("a built-in table")));
            }
        }
    }
    // Contact laws, damping schemes and material laws of the libraries (issue 25).
    let mut stand_in = |t: &mut toml::Value, key: &str, kind: u32, with: Option<&str>| {
        let Some(ty) = t.get("type").and_then(|v| v.as_str()).map(str::to_string) else { return false };
        let builtin = if kind == abi::KIND_CONTACT { flem_core::contact::dynlaw::is_builtin(&ty) } else { dynload::is_builtin(kind, &ty) };
        if builtin {
            return false;
        }
        notes.push(format!("{name}: {key}.type = \"{ty}\" is not built in; it would come from the plugin libraries, so it and its parameters were not checked"));
        if let Some(w) = with {
            *t = toml::Value::Table(toml::from_str(w).expect("a built-in table"));
        }
        true
    };
    if let Some(law) = doc.get_mut("contact").and_then(|c| c.get_mut("law")) {
        stand_in(law, "contact.law", abi::KIND_CONTACT, Some("type = \"penalty\"\nnormal_stiffness = 1.0"));
    }
    if let Some(d) = doc.get_mut("solver").and_then(|c| c.get_mut("damping")) {
        stand_in(d, "solver.damping", abi::KIND_DAMPING, Some("type = \"adaptive\""));
    }
    if let Some(mats) = doc.get_mut("material").and_then(|m| m.as_array_mut()) {
        for (i, m) in mats.iter_mut().enumerate() {
            let Some(tab) = m.as_table_mut() else { continue };
            if tab.get_mut("law").is_some_and(|law| stand_in(law, &format!("material[{i}].law"), abi::KIND_MATERIAL, None)) {
                tab.remove("law"); // linear elastic stands in
            }
        }
    }
    let stripped = toml::to_string(&doc).context("re-writing the scene without its plugins")?;
    Ok((Scene::from_str(&stripped, p, &base)?, notes))
}

fn run(scene: Scene, out: Option<PathBuf>, quiet: bool, resume: Option<PathBuf>, plot_flag: bool) -> Result<()> {
    let plots = plot_flag || scene.file.output.plots;
    let stem = scene.path.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "run".into());
    let out = out.or_else(|| resume.clone()).unwrap_or_else(|| PathBuf::from("out").join(stem));
    let scene_path = scene.path.clone();
    // One run at a time in a folder (held until this function returns, released by the OS if
    // the process dies); then fail on an unwritable folder before any step is computed.
    let _lock = lock_out(&out)?;
    // Resuming from another folder reads (and prunes) its checkpoints: hold it too.
    let _lock_from = match &resume {
        Some(r) if r != &out && r.is_dir() => Some(lock_out(r)?),
        _ => None,
    };
    flem_core::output::prepare_dir(&out)?;
    // SIGINT/SIGTERM set a flag the run polls once per step; a second signal while the flag is
    // set ends the process at once (files stay whole: every write is atomic, or one append of
    // whole CSV rows, which a handled signal does not cut).
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register_conditional_shutdown(sig, 130, Arc::clone(&stop)).context("installing the signal handler")?;
        signal_hook::flag::register(sig, Arc::clone(&stop)).context("installing the signal handler")?;
    }
    let t0 = std::time::Instant::now();
    let mut sim = Simulation::new(scene)?;
    let mut w = OutputWriter::new(&out, &sim)?;
    w.stop = Some(Arc::clone(&stop));
    let mut pos = StagePos::start(0);
    if let Some(dir) = &resume {
        let (p, path, refused) = flem_core::output::run::resume(&mut sim, &mut w, dir)?;
        for r in &refused {
            eprintln!("warning: {r}");
        }
        eprintln!("resuming from {} (step {}, stage {} step {})", path.display(), sim.state.step, p.stage + 1, p.stage_step);
        pos = p;
    }
    for w in &sim.warnings {
        eprintln!("warning: {w}");
    }
    // Warnings the run adds (a stage that was never checked) are printed after it.
    let n_warn = sim.warnings.len();
    eprintln!("{} elements, {} points; dt = {:.4e} (dt/dt_crit = {:.3}, dt_crit = {:.4e})", sim.model.n_elems(), sim.model.topo.n_points, sim.dt, sim.dt / sim.stable.dt_crit, sim.stable.dt_crit);
    let bar = if quiet || !std::io::IsTerminal::is_terminal(&std::io::stderr()) { ProgressBar::hidden() } else { ProgressBar::new(1) };
    bar.set_style(ProgressStyle::with_template("{prefix} [{bar:30}] {pos}/{len} steps {msg} (left <= {eta})").unwrap().progress_chars("=> "));
    let b2 = bar.clone();
    w.on_progress = Some(Box::new(move |p| {
        b2.set_length(p.max_steps);
        b2.set_position(p.stage_step);
        b2.set_prefix(format!("stage {}/{}", p.stage + 1, p.n_stages));
        b2.set_message(format!("step {} dt {:.2e} ratio {:.2e} (tol {:.0e})", p.step, p.dt, p.ratio, p.tolerance));
    }));
    // The run, the [check] comparison after every stage (compare.json beside the results) and
    // summary.json: shared with `flem sweep` and the Python package (output::run).
    let end = flem_core::output::run::run_in_folder(&mut sim, &mut w, pos, &mut NoOutput, t0);
    bar.finish_and_clear();
    if sim.scene.file.check.is_some() {
        eprint!("{}", flem_core::output::compare::table(&end.compare_rows));
    }
    let resume_hint = |w: &OutputWriter| match &w.last_checkpoint {
        Some(p) => format!("the last good checkpoint is {}; resume with: {}", p.display(), resume_command(&scene_path, &out)),
        None => String::from("no checkpoint was written"),
    };
    match end.result {
        Err(e @ FlemError::Interrupted { .. }) => {
            return Err(Stopped(format!("flem: {e}: {}\nresume with: {}", w.last_checkpoint.as_ref().map(|p| p.display().to_string()).unwrap_or_default(), resume_command(&scene_path, &out))).into());
        }
        Err(e @ FlemError::Output { .. }) => anyhow::bail!("{e}\nthe run stopped; {}", resume_hint(&w)),
        r => r?,
    }
    let events = sim.scene.file.solver.kind == flem_core::scene::SolverKind::Events;
    for s in &sim.stages_done {
        if events {
            // The events solver (ours): steps are events; a stage that did not end is named by a warning below.
            eprintln!(
                "{}: {} events, linear-solve ratio {:.2e}{}, {} splits, {:.2} s",
                s.name,
                s.steps,
                s.final_ratio,
                if s.converged { "" } else { " (stopped: see the warning)" },
                s.splits,
                s.wall_seconds
            );
        } else {
            eprintln!("{}: {} steps, ratio {:.2e}{}, {} splits, {:.2} s", s.name, s.steps, s.final_ratio, if s.converged { "" } else { " (step limit: NOT in equilibrium)" }, s.splits, s.wall_seconds);
        }
    }
    for w in &sim.warnings[n_warn.min(sim.warnings.len())..] {
        eprintln!("warning: {w}");
    }
    if let Some(n) = sim.cracking.as_ref().map(|c| c.beyond_criterion()).filter(|&n| n > 0) {
        // With a plastic law (issue 21) the stress is capped by the law's yield surface, not by
        // the failure criterion; without one the method has no plasticity.
        let why = if sim.model.stateful { "the material law, not the criterion, bounds their stress" } else { "they carry stress above their strength (no plasticity in the method)" };
        let intact = if sim.cracking.as_ref().is_some_and(|c| !c.intact.is_empty()) { " (or that [cracking] intact keeps whole)" } else { "" };
        eprintln!("{n} points beyond the failure criterion at the last check that the separation rule did not cut{intact}: {why}");
    }
    eprintln!("energy residual {:.2e} of the work done; wall time {:.2} s; results in {}", sim.ledger.relative_residual(), t0.elapsed().as_secs_f64(), out.display());
    if plots {
        plot(&out)?;
    }
    Ok(())
}

fn plot(dir: &Path) -> Result<()> {
    let summary = std::fs::read_to_string(dir.join("summary.json")).unwrap_or_default();
    anyhow::ensure!(
        !summary.contains("\"dim\": 3"),
        "{} is the folder of a 3D run: `flem plot` draws 2D runs only for now; open its snapshot_*.vtu in ParaView or pyvista (docs/3d.md)",
        dir.display()
    );
    let rep = flem_plot::plot_run(dir).with_context(|| format!("drawing the pictures of {}", dir.display()))?;
    for n in &rep.notes {
        eprintln!("note: {n}");
    }
    eprintln!("{} pictures (PNG + SVG) in {} (displacements x {})", rep.files.len(), dir.join("plots").display(), rep.mag);
    Ok(())
}

/// `flem compare`: the scene's stages with the comparison after each (the scene's `[check]`, or
/// its defaults when the scene has none). Exit 1 when, on a comparable stage, the implicit solve
/// failed or the two disagree beyond `check.tolerance`; a stage that is not comparable (FLEM not
/// at rest, a fragment without support, `check = false`) is reported with its reason.
fn compare(scene: Scene, out: Option<PathBuf>) -> Result<()> {
    let stem = scene.path.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "run".into());
    let out = out.unwrap_or_else(|| PathBuf::from("out").join(format!("{stem}_compare")));
    let _lock = lock_out(&out)?;
    let on_row: Box<dyn FnMut(&flem_core::output::compare::StageComparison)> =
        Box::new(|r| eprintln!("stage {} ({}): FLEM {} steps, ratio {:.2e}; implicit {:.3} s", r.stage, r.name, r.flem_steps, r.unbalanced_ratio.unwrap_or(f64::NAN), r.wall_seconds_implicit));
    let sim_tolerance = scene.file.check.as_ref().map_or_else(|| flem_core::output::run::default_compare_tolerance(&scene), |c| c.tolerance);
    if scene.file.check.is_none() {
        eprintln!("the scene has no [check]: the comparison tolerance is {sim_tolerance:e} (1000 x its loosest equilibrium tolerance, within [1e-6, 0.1]; ours)");
    }
    let path = scene.path.clone();
    let (r, rows, warnings) = match flem_core::output::run::compare_in_folder(scene, &out, Some(on_row)) {
        Ok(x) => x,
        // The implicit check is linear elastic, small strain: a scene with another law.
        Err(e @ FlemError::Config { .. }) if matches!(&e, FlemError::Config { key, .. } if key == "check") => return Err(unsuited(&path, "compare", e)),
        Err(e) => return Err(e.into()),
    };
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    print!("{}", flem_core::output::compare::table(&rows));
    r?;
    println!("results in {}", out.join("compare.json").display());
    judge_compare(&rows, sim_tolerance)
}

fn bench(what: BenchWhat) -> Result<()> {
    match what {
        BenchWhat::Implicit { dofs, repeats, threads } => {
            anyhow::ensure!(dofs.iter().all(|&d| d.is_finite() && (8.0..=1e8).contains(&d)), "--dofs: every value must be in [8, 1e8]");
            anyhow::ensure!(threads.iter().all(|&t| (1..=1024).contains(&t)), "--threads: every value must be in [1, 1024]");
            let b = flem_plugins::check::bench::bench_implicit(&dofs, repeats, &threads)?;
            println!("{}", serde_json::to_string_pretty(&b)?);
        }
        BenchWhat::Step { sizes, threads, kinds, step_sizes, min_time, nonlocal_radius_h, rounds, graph_sizes, dataflows } => {
            bench_step(sizes, threads, kinds, step_sizes, min_time, nonlocal_radius_h, rounds, graph_sizes, dataflows)?
        }
        BenchWhat::Dyncall(a) => bench_dyncall::run(&a)?,
        BenchWhat::Step3(a) => bench3::run(&a)?,
        BenchWhat::Laws { elements, min_time, cases } => bench_laws::run(elements, min_time, &cases)?,
        BenchWhat::Answer(a) => bench_answer::run(&a)?,
        BenchWhat::Contact { sizes, repeats } => bench_contact::run(&sizes, repeats)?,
        BenchWhat::Events { dofs, events, woodbury, refactor_every } => {
            anyhow::ensure!(dofs.iter().all(|&d| d.is_finite() && (100.0..=1e7).contains(&d)), "--dofs: every value must be in [100, 1e7]");
            if woodbury {
                let rows: Vec<_> = dofs.iter().map(|&d| flem_plugins::check::woodbury::bench_woodbury(d, events as usize)).collect::<Result<_, _>>()?;
                println!("{}", serde_json::to_string_pretty(&rows)?);
            } else {
                bench_events::run(&dofs, events, refactor_every)?
            }
        }
        BenchWhat::EventsPath { scene, step, max_steps, tolerance, splits, repeats, events_only } => bench_events::path(&scene, step, max_steps, tolerance, splits, repeats, !events_only)?,
    }
    Ok(())
}
