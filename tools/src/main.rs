//! `flem`: run, check and inspect FLEM scenes.
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use flem_core::output::OutputWriter;
use flem_core::scene::Scene;
use flem_core::solver::Simulation;
use indicatif::{ProgressBar, ProgressStyle};

mod bench_contact;

/// The scene run by `flem` (and `cargo run --release`) with no arguments.
const DEFAULT_SCENE: &str = include_str!("../../configs/default.toml");
const DEFAULT_NAME: &str = "configs/default.toml";

#[derive(Parser)]
#[command(name = "flem", version, about = "FLEM: the flow element method with cracking")]
struct Cli {
    #[command(subcommand)]
    cmd: Option<Cmd>,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run a scene: stages to equilibrium, results (VTU/PVD, history.csv, summary.json) into --out.
    Run {
        scene: PathBuf,
        /// Output folder (default: out/<scene name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// Validate a scene (and build its mesh) without running it; exit 1 with the message on error.
    Check { scenes: Vec<PathBuf> },
    /// List the registered plugins (kind and name).
    Plugins,
    /// Benchmarks, printing JSON.
    Bench {
        #[command(subcommand)]
        what: BenchWhat,
    },
}

#[derive(Subcommand)]
enum BenchWhat {
    /// Contact search cost against the number of surface nodes, with the growth exponent.
    Contact {
        /// Surface-node counts to measure.
        #[arg(long, value_delimiter = ',', default_values_t = vec![1000usize, 10000, 100000])]
        sizes: Vec<usize>,
        /// Timed repetitions per size (the best is kept).
        #[arg(long, default_value_t = 5)]
        repeats: usize,
    },
}

fn main() -> ExitCode {
    flem_plugins::link();
    let cli = Cli::parse();
    let r = match cli.cmd {
        None => run_default(),
        Some(Cmd::Run { scene, out, quiet }) => load(&scene).and_then(|s| run(s, out, quiet)),
        Some(Cmd::Check { scenes }) => check(&scenes),
        Some(Cmd::Bench { what: BenchWhat::Contact { sizes, repeats } }) => bench_contact::run(&sizes, repeats),
        Some(Cmd::Plugins) => {
            for (kind, name) in flem_plugins::registry() {
                println!("{kind:<12} {name}");
            }
            Ok(())
        }
    };
    match r {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn load(path: &Path) -> Result<Scene> {
    Ok(Scene::from_file(path)?)
}

fn run_default() -> Result<()> {
    let scene = Scene::from_str(DEFAULT_SCENE, Path::new(DEFAULT_NAME), Path::new("configs"))?;
    eprintln!("flem: no scene given, running the default scene {DEFAULT_NAME} (see `flem --help`)");
    run(scene, None, false)
}

fn check(scenes: &[PathBuf]) -> Result<()> {
    anyhow::ensure!(!scenes.is_empty(), "give at least one scene file");
    for p in scenes {
        let sim = Simulation::new(load(p)?)?;
        for w in &sim.warnings {
            eprintln!("warning: {w}");
        }
        println!("{}: ok ({} elements, {} points, {} stages, dt = {:.3e}, dt_crit = {:.3e})", p.display(), sim.model.n_elems(), sim.model.topo.n_points, sim.scene.file.stages.len(), sim.dt, sim.stable.dt_crit);
    }
    Ok(())
}

fn run(scene: Scene, out: Option<PathBuf>, quiet: bool) -> Result<()> {
    let stem = scene.path.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "run".into());
    let out = out.unwrap_or_else(|| PathBuf::from("out").join(stem));
    // Fail on an unwritable folder before any step is computed.
    flem_core::output::prepare_dir(&out)?;
    let t0 = std::time::Instant::now();
    let mut sim = Simulation::new(scene)?;
    for w in &sim.warnings {
        eprintln!("warning: {w}");
    }
    eprintln!(
        "{} elements, {} points; dt = {:.4e} (dt/dt_crit = {:.3}, dt_crit = {:.4e})",
        sim.model.n_elems(),
        sim.model.topo.n_points,
        sim.dt,
        sim.dt / sim.stable.dt_crit,
        sim.stable.dt_crit
    );
    let mut w = OutputWriter::new(&out, &sim)?;
    let bar = if quiet || !std::io::IsTerminal::is_terminal(&std::io::stderr()) { ProgressBar::hidden() } else { ProgressBar::new(1) };
    bar.set_style(ProgressStyle::with_template("{prefix} [{bar:30}] {pos}/{len} steps {msg} (left <= {eta})").unwrap().progress_chars("=> "));
    let b2 = bar.clone();
    w.on_progress = Some(Box::new(move |p| {
        b2.set_length(p.max_steps);
        b2.set_position(p.stage_step);
        b2.set_prefix(format!("stage {}/{}", p.stage + 1, p.n_stages));
        b2.set_message(format!("step {} dt {:.2e} ratio {:.2e} (tol {:.0e})", p.step, p.dt, p.ratio, p.tolerance));
    }));
    let r = sim.run(&mut w);
    bar.finish_and_clear();
    w.write_summary(&sim, t0.elapsed().as_secs_f64()).with_context(|| "writing summary.json")?;
    r?;
    for s in &sim.stages_done {
        eprintln!("{}: {} steps, ratio {:.2e}{}, {} splits, {:.2} s", s.name, s.steps, s.final_ratio, if s.converged { "" } else { " (step limit: NOT in equilibrium)" }, s.splits, s.wall_seconds);
    }
    eprintln!("energy residual {:.2e} of the work done; wall time {:.2} s; results in {}", sim.ledger.relative_residual(), t0.elapsed().as_secs_f64(), out.display());
    Ok(())
}
