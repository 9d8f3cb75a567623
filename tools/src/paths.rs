//! `flem paths SCENE... [--separation NAME] [--sizes N] [--out FILE]` (issue 34, must-show 2
//! and 4; docs/paths.md): runs each scene and measures the new crack's direction over its first
//! `N` element sizes at every initial crack tip (`flem_plugins::check::paths::kinks`), beside the
//! maximum tangential stress angle predicted from the implicit solution's `K_I`, `K_II` at that
//! tip (`check::sif::stage_sif`, first stage, domains of 4, 6 and 8 element sizes). Also the
//! fragments of fewer than 3 elements, the events and the path method's moves. Prints a table;
//! `--out` writes the rows as JSON (atomically).
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use flem_core::plugin::traits::SeparationRule;
use flem_core::scene::Scene;
use flem_core::solver::{NoOutput, Simulation};
use flem_plugins::check::paths::{crack_faces, fragment_sizes, hausdorff, kinks_in_order, Kink};
use flem_plugins::check::sif::{crack_tips, stage_sif, Radii};
use flem_plugins::separation::tip_mts::kink_angle;
use serde::Serialize;

#[derive(clap::Args)]
pub struct Args {
    #[arg(required = true)]
    pub scenes: Vec<PathBuf>,
    /// Replace the scene's separation rule by this one, as TOML of `[cracking.separation]`
    /// (e.g. `type = "tip_mts"`, or just `tip_mts`).
    #[arg(long)]
    pub separation: Option<String>,
    /// Element sizes over which the kink is measured.
    #[arg(long, default_value_t = 5.0)]
    pub sizes: f64,
    /// Write the rows as JSON to this file.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write the Hausdorff distances between the paths (see `hausdorff_groups`) as JSON here.
    #[arg(long)]
    pub hausdorff_out: Option<PathBuf>,
}

/// One initial tip of one run.
#[derive(Serialize)]
pub struct Row {
    pub scene: String,
    pub separation: String,
    /// The MTS angle from the implicit solution at the tip (deg; `None`: not available).
    pub mts_deg: Option<f64>,
    pub k1: Option<f64>,
    pub k2: Option<f64>,
    pub kink: Kink,
    /// Chord angle minus the MTS angle (deg).
    pub error_deg: Option<f64>,
    pub small_fragments: usize,
    pub events: u64,
    pub splits: usize,
    pub moves: usize,
    pub refused_moves: u64,
    /// Of `refused_moves`, those of a point that carries a boundary condition (ours, session 18).
    pub refused_held: u64,
    pub wall_s: f64,
    /// The specimen's size: the larger side of the mesh's bounding box.
    pub size: f64,
    /// The run's error, when it stopped early (the path is still measured).
    pub run_error: Option<String>,
}

/// Parses `--separation`: a bare name or TOML.
pub fn parse_rule(s: &str) -> Result<Box<dyn SeparationRule>> {
    let text = if s.contains('=') { s.to_string() } else { format!("type = \"{s}\"") };
    let r: Box<dyn SeparationRule> = toml::from_str(&text).with_context(|| format!("--separation {s}"))?;
    r.validate().map_err(|e| anyhow::anyhow!("--separation {s}: {} {}", e.key, e.msg))?;
    Ok(r)
}

fn load(path: &PathBuf, rule: Option<&str>) -> Result<Scene> {
    let mut scene = Scene::from_file(path)?;
    if let Some(r) = rule {
        let cr = scene.file.cracking.as_mut().with_context(|| format!("{}: the scene has no [cracking]", path.display()))?;
        cr.separation = parse_rule(r)?;
    }
    Ok(scene)
}

/// Runs one scene and measures it (see the module doc).
pub fn measure(path: &PathBuf, rule: Option<&str>, sizes: f64) -> Result<Vec<Row>> {
    let name = path.display().to_string();
    // The prediction: K_I, K_II of the implicit solution at the initial tips, first stage.
    let mut pre = Simulation::new(load(path, rule)?)?;
    let st = stage_sif(&mut pre, 0, None, &Radii::default()).with_context(|| format!("{name}: stress intensity factors"))?;
    let mut sim = Simulation::new(load(path, rule)?)?;
    let separation = sim.scene.file.cracking.as_ref().map(|c| format!("{:?}", c.separation)).unwrap_or_default();
    let tips = crack_tips(&sim.model);
    let size = {
        let pts = &sim.model.mesh.points;
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in pts {
            for d in 0..2 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        (hi[0] - lo[0]).max(hi[1] - lo[1])
    };
    let initial = crack_faces(&sim.model);
    let t0 = Instant::now();
    let run_error = sim.run(&mut NoOutput).err().map(|e| e.to_string());
    let wall_s = t0.elapsed().as_secs_f64();
    let cuts = sim.cracking.as_ref().map_or(&[][..], |c| &c.cuts[..]);
    let ks = kinks_in_order(&sim.model, &tips, &initial, sizes, cuts);
    let small = fragment_sizes(&sim.model).iter().filter(|&&s| s < 3).count();
    let cr = sim.cracking.as_ref();
    let (splits, moves, refused, held) = cr.map_or((0, 0, 0, 0), |c| (c.n_splits, c.path.moves.len(), c.path.refused, c.held_refused));
    Ok(ks
        .into_iter()
        .map(|k| {
            let t = st.tips.iter().find(|t| t.point == k.tip_point).and_then(|t| t.sif.as_ref());
            let (k1, k2) = (t.map(|s| s.k1), t.map(|s| s.k2));
            // A K_I at or below zero by at most 5 % of |K_II| is zero (the shear test's tip:
            // pure mode II, its faces pressed together by round-off or slightly): `kink_angle`.
            let mts = t.and_then(|s| kink_angle(s.k1, s.k2)).map(f64::to_degrees);
            let error_deg = match (k.chord_deg, mts) {
                (Some(c), Some(m)) if k.reached => Some(c - m),
                _ => None,
            };
            Row {
                scene: name.clone(),
                separation: separation.clone(),
                mts_deg: mts,
                k1,
                k2,
                kink: k,
                error_deg,
                small_fragments: small,
                events: sim.state.step,
                splits,
                moves,
                refused_moves: refused,
                refused_held: held,
                wall_s,
                size,
                run_error: run_error.clone(),
            }
        })
        .collect())
}

pub fn table(rows: &[Row]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<44} {:>6} {:>8} {:>8} {:>8} {:>8} {:>7} {:>5} {:>5} {:>6} {:>6} {:>5} {:>7}",
        "scene", "tip", "h", "MTS", "chord", "lsq", "error", "frag", "br", "moves", "refus", "held", "wall s"
    );
    let f = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
    for r in rows {
        let k = &r.kink;
        let err = if k.reached { f(r.error_deg) } else { format!("short {:.2}", k.length / k.h) };
        let _ = writeln!(
            s,
            "{:<44} {:>6} {:>8.4} {:>8} {:>8} {:>8} {:>7} {:>5} {:>5} {:>6} {:>6} {:>5} {:>7.2}{}",
            r.scene,
            k.tip_point,
            k.h,
            f(r.mts_deg),
            f(k.chord_deg),
            f(k.lsq_deg),
            err,
            r.small_fragments,
            k.branches,
            r.moves,
            r.refused_moves,
            r.refused_held,
            r.wall_s,
            r.run_error.as_ref().map_or(String::new(), |e| format!("  [stopped: {}]", e.lines().next().unwrap_or("")))
        );
    }
    s
}

/// The Hausdorff distance between two runs' paths from one tip.
#[derive(Serialize)]
pub struct Pair {
    pub a: String,
    pub b: String,
    pub distance: f64,
    /// `distance` as a percentage of the specimen's size.
    pub percent: f64,
}

/// The paths of one benchmark from one initial tip: every pair's Hausdorff distance.
#[derive(Serialize)]
pub struct Group {
    pub family: String,
    pub tip: [f64; 2],
    pub size: f64,
    pub scenes: Vec<String>,
    pub pairs: Vec<Pair>,
    /// The largest pair (percent of the size).
    pub max_percent: f64,
}

/// The benchmark a scene belongs to: its file stem without the last two `_` parts (the scenes
/// of configs/paths/ are named `FAMILY_KIND_N`: `sen_quad_2` is of `sen`).
pub fn family(scene: &str) -> String {
    let stem = std::path::Path::new(scene).file_stem().map_or(scene.to_string(), |s| s.to_string_lossy().into_owned());
    let parts: Vec<&str> = stem.split('_').collect();
    if parts.len() > 2 {
        parts[..parts.len() - 2].join("_")
    } else {
        stem
    }
}

/// Must-show 3 (issue 34): the rows grouped by benchmark ([`family`]) and initial tip (within
/// 1e-3 of the size), and in each group the Hausdorff distance between every two runs' whole
/// paths up to the outer boundary (`Kink::through`) (`check::paths::hausdorff`, sampled at 1e-4 of the size), as a percentage of the
/// specimen's size. Groups of one run are left out.
pub fn hausdorff_groups(rows: &[Row]) -> Vec<Group> {
    let mut groups: Vec<(String, [f64; 2], Vec<usize>)> = Vec::new();
    for (i, r) in rows.iter().enumerate() {
        let fam = family(&r.scene);
        let t = r.kink.tip;
        match groups.iter_mut().find(|(f, x, _)| *f == fam && (x[0] - t[0]).hypot(x[1] - t[1]) <= 1e-3 * r.size) {
            Some(g) => g.2.push(i),
            None => groups.push((fam, t, vec![i])),
        }
    }
    groups
        .into_iter()
        .filter(|g| g.2.len() > 1)
        .map(|(family, tip, ix)| {
            let size = ix.iter().map(|&i| rows[i].size).fold(0.0, f64::max);
            let mut pairs = Vec::new();
            for (n, &i) in ix.iter().enumerate() {
                for &j in &ix[n + 1..] {
                    let d = hausdorff(rows[i].kink.through(), rows[j].kink.through(), 1e-4 * size);
                    pairs.push(Pair { a: rows[i].scene.clone(), b: rows[j].scene.clone(), distance: d, percent: 100.0 * d / size });
                }
            }
            let max_percent = pairs.iter().map(|p| p.percent).fold(0.0, f64::max);
            Group { family, tip, size, scenes: ix.iter().map(|&i| rows[i].scene.clone()).collect(), pairs, max_percent }
        })
        .collect()
}

/// The Hausdorff table: per group, the matrix of percentages (runs in the order given).
pub fn hausdorff_table(groups: &[Group]) -> String {
    let mut s = String::new();
    for g in groups {
        let _ = writeln!(s, "Hausdorff distance between paths, % of the size {:.4}: {} tip ({:.4}, {:.4}); largest {:.2} %", g.size, g.family, g.tip[0], g.tip[1], g.max_percent);
        let short = |n: &str| std::path::Path::new(n).file_stem().map_or(n.to_string(), |s| s.to_string_lossy().into_owned());
        let _ = write!(s, "{:<20}", "");
        for n in &g.scenes {
            let _ = write!(s, " {:>9}", short(n).chars().rev().take(9).collect::<Vec<_>>().into_iter().rev().collect::<String>());
        }
        let _ = writeln!(s);
        for a in &g.scenes {
            let _ = write!(s, "{:<20}", short(a));
            for b in &g.scenes {
                let v = if a == b { 0.0 } else { g.pairs.iter().find(|p| (&p.a == a && &p.b == b) || (&p.a == b && &p.b == a)).map_or(f64::NAN, |p| p.percent) };
                let _ = write!(s, " {:>9.2}", v);
            }
            let _ = writeln!(s);
        }
    }
    s
}

pub fn run(a: Args) -> Result<()> {
    anyhow::ensure!(a.sizes.is_finite() && a.sizes > 0.0, "--sizes must be finite and > 0");
    if let Some(r) = &a.separation {
        parse_rule(r)?;
    }
    let mut rows = Vec::new();
    for p in &a.scenes {
        let r = measure(p, a.separation.as_deref(), a.sizes)?;
        print!("{}", table(&r));
        rows.extend(r);
    }
    if let Some(out) = &a.out {
        let text = serde_json::to_string_pretty(&rows)?;
        flem_core::output::atomic_write(out, text.as_bytes()).with_context(|| format!("writing {}", out.display()))?;
        println!("rows in {}", out.display());
    }
    let groups = hausdorff_groups(&rows);
    print!("{}", hausdorff_table(&groups));
    if let Some(out) = &a.hausdorff_out {
        let text = serde_json::to_string_pretty(&groups)?;
        flem_core::output::atomic_write(out, text.as_bytes()).with_context(|| format!("writing {}", out.display()))?;
        println!("Hausdorff distances in {}", out.display());
    }
    Ok(())
}
