//! `flem bench step`: explicit step throughput (issue 9), printed as one JSON object.
//!
//! Measured in one process, so every ratio compares figures of the same run:
//! Sizes are element counts on a 2 x 1 rectangle, `nx = sqrt(2 n)` (T3: two per cell), so
//! 2048, 32768, 524288 are exactly the peers' meshes n = 64, 256, 1024 (../shared/peers).
//! - the bare kernel (`Model::internal_forces`: the blocked element loop and its scatter) in
//!   element-updates per second and ns per element-update, Q4 and T3, at each size, for each
//!   thread count, with the check that forces are bit-identical to one thread;
//! - memory per element (block: geometry, connectivity, kernel packs, schedule; node state),
//!   and the bytes an update streams (`Block::kernel_bytes` + 48 per cluster, 64 when the
//!   force array is zeroed before the pass: `zeroing_sweep`), against the
//!   triad measured in the same run (issue 24);
//! - the full `Simulation::step` against the bare kernel and against a bare central-difference
//!   step (kernel + the textbook update loop written here), and a whole stage (`run_stage`,
//!   which adds the unbalanced-force ratio every `ratio_every` steps);
//! - failure checks every k steps (a cracking scene whose strength is never reached, so the
//!   checks run and nothing splits) against the share `t_check / (k t_step)` they should cost;
//!   `overhead` with the certified skip (the default, issue 24: every check after the first is
//!   certified and skipped here), `every_point_overhead` evaluating every point at every check.
//!   Each stage starts on a fresh model, so each pays the first check's one-time set-up
//!   (corner gradients, the skip's Lipschitz constants), also timed alone (`first_check_ms`,
//!   and its share of a checking stage, `first_check_in_stage_share`).
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use flem_core::element::block::Simd;
use flem_core::element::model::Model;
use flem_core::element::Plane;
use flem_core::mesh::{CellKind, Rectangle, ValidationOptions};
use flem_core::scene::{MaterialCfg, Scene};
use flem_core::solver::{NoOutput, Simulation};
use serde_json::{json, Value};

/// A registered element kind (`flem_core::element::registry`).
pub type Kind = &'static flem_core::element::registry::ElementKind;

/// Options of `flem bench step`.
pub struct StepOpts {
    pub sizes: Vec<usize>,
    pub threads: Vec<usize>,
    pub kinds: Vec<Kind>,
    pub min_time: f64,
    pub step_sizes: Vec<usize>,
    /// Radius of the nonlocal check's cost, in element sizes.
    pub nonlocal_radius_h: f64,
}

/// CPU seconds used so far by every thread of this process (Linux `/proc/self/task/*/schedstat`,
/// nanosecond resolution; 0 elsewhere). On a shared machine the wall time counts the time other
/// processes hold the cores; the CPU time does not.
fn cpu_seconds() -> f64 {
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else { return 0.0 };
    dir.filter_map(|e| std::fs::read_to_string(e.ok()?.path().join("schedstat")).ok()).filter_map(|s| s.split_whitespace().next()?.parse::<f64>().ok()).sum::<f64>() * 1e-9
}

/// Median (wall, CPU) seconds per call of `f`: 5 batches of at least `min_time / 5` each.
pub(crate) fn time_per_call(min_time: f64, mut f: impl FnMut()) -> (f64, f64) {
    f();
    let t0 = Instant::now();
    f();
    let one = t0.elapsed().as_secs_f64().max(1e-9);
    let reps = ((min_time / 5.0 / one).ceil() as usize).max(1);
    let mut batches: Vec<(f64, f64)> = (0..5)
        .map(|_| {
            let (t, c) = (Instant::now(), cpu_seconds());
            for _ in 0..reps {
                f();
            }
            (t.elapsed().as_secs_f64() / reps as f64, (cpu_seconds() - c) / reps as f64)
        })
        .collect();
    batches.sort_by(|a, b| a.0.total_cmp(&b.0));
    batches[2]
}

/// The machine's own memory bandwidth, measured in the same run: the STREAM triad
/// `a[i] = b[i] + s c[i]` over three arrays of 2^25 f64 (768 MiB in all, far beyond the caches),
/// split into equal chunks over `threads` threads, counted as STREAM does (24 bytes per index:
/// two reads and a write, the write-allocate read not counted). Median of 5 batches, GB/s.
fn triad_gb_per_s(threads: usize, min_time: f64) -> Result<f64> {
    use rayon::prelude::*;
    const N: usize = 1 << 25;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build()?;
    let (mut a, b, c) = (vec![0.0f64; N], vec![1.0f64; N], vec![2.0f64; N]);
    let chunk = N.div_ceil(threads.max(1));
    let (t, _) = time_per_call(min_time, || {
        pool.install(|| {
            a.par_chunks_mut(chunk).zip(b.par_chunks(chunk)).zip(c.par_chunks(chunk)).for_each(|((a, b), c)| {
                for i in 0..a.len() {
                    a[i] = b[i] + 3.0 * c[i];
                }
            })
        })
    });
    std::hint::black_box(&a);
    Ok(24.0 * N as f64 / t / 1e9)
}

/// `nx x ny` for about `n` elements on a 2 x 1 rectangle (T3: two per cell).
fn grid_for(n: usize, kind: CellKind) -> (usize, usize) {
    let cells = if kind == CellKind::T3 { n / 2 } else { n } as f64;
    let nx = (2.0 * cells).sqrt().round().max(2.0) as usize;
    (nx, (nx / 2).max(1))
}

fn kind_name(k: CellKind) -> &'static str {
    match k {
        CellKind::Q4 => "q4",
        CellKind::T3 => "t3",
    }
}

fn model(nx: usize, ny: usize, kind: Kind) -> Result<Model> {
    let mut mesh = Rectangle::new(2.0, 1.0, nx, ny, kind.cell).build()?;
    mesh.validate(ValidationOptions::Reorient)?;
    mesh.derive_node_sets();
    let mat = MaterialCfg { element: Some(kind.name.into()), ..MaterialCfg::elastic(100.0, 0.3, 1.0) };
    Ok(Model::new(mesh, &[mat], Plane::Strain, "<bench>")?)
}

/// Kernel throughput of one mesh for each thread count.
fn kernel_case(nx: usize, ny: usize, kind: Kind, o: &StepOpts, triad: &[(usize, f64)]) -> Result<Value> {
    let mut m = model(nx, ny, kind)?;
    let (ne, nc) = (m.n_elems(), m.topo.n_clusters());
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    let u: Vec<[f64; 2]> = (0..nc)
        .map(|_| {
            std::array::from_fn(|_| {
                seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                1e-3 * ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5)
            })
        })
        .collect();
    let mut f = vec![[0.0; 2]; nc];
    let mut reference: Option<Vec<[f64; 2]>> = None;
    let mut per_thread = Vec::new();
    // The bytes an element-update must move at the least: the block data the force pass
    // streams once (`Block::kernel_bytes`: packs and their extra parts, connectivity, schedule;
    // not the corner coordinates and ids, which it does not read), and per cluster u read
    // (16 B), f_int read and written (32 B), and zeroed before (16 B) unless the model's pass
    // writes every entry (`Model::zero_free`, issue 24 session 11; before it every byte the
    // block held was counted and the zeroing was not).
    let block_bytes = m.blocks.iter().map(|b| b.kernel_bytes()).sum::<usize>() as f64 / ne as f64;
    let zero_free = m.zero_free();
    let cluster_bytes = if zero_free { 48.0 } else { 64.0 };
    let min_bytes = block_bytes + cluster_bytes * nc as f64 / ne as f64;
    for &t in &o.threads {
        m.set_threads(t)?;
        let (s, cpu) = time_per_call(o.min_time, || m.internal_forces(&u, &mut f));
        m.internal_forces(&u, &mut f);
        let identical = match &reference {
            None => {
                reference = Some(f.clone());
                true
            }
            Some(r) => r.iter().zip(&f).all(|(a, b)| a[0].to_bits() == b[0].to_bits() && a[1].to_bits() == b[1].to_bits()),
        };
        let eff = min_bytes * ne as f64 / s / 1e9;
        let tri = triad.iter().find(|(n, _)| *n == m.threads()).map(|x| x.1);
        per_thread.push(json!({"threads": m.threads(), "ns_per_elem_update": s * 1e9 / ne as f64, "elem_updates_per_s": ne as f64 / s, "cpu_ns_per_elem_update": cpu * 1e9 / ne as f64, "bit_identical_to_first": identical,
            "bytes_per_elem_update_min": min_bytes, "zeroing_sweep": !zero_free, "bytes_per_cluster": cluster_bytes, "effective_gb_per_s": eff, "triad_gb_per_s": tri, "fraction_of_triad": tri.map(|t| eff / t)}));
    }
    let block: usize = m.blocks.iter().map(|b| b.memory_bytes()).sum();
    // u, v, f_int, f_ext, v_pres ([f64; 2]), mass (f64), fix (u8) per cluster.
    let node_bytes = nc * (5 * 16 + 8 + 1);
    let kernel_bytes = kind.bytes_per_elem;
    Ok(json!({
        "kind": kind.name, "nx": nx, "ny": ny, "elements": ne, "clusters": nc,
        "kernel": per_thread,
        "memory_bytes_per_element": {"kernel_packs": kernel_bytes, "kernel_streamed": block_bytes, "block_total": block as f64 / ne as f64, "node_state": node_bytes as f64 / ne as f64, "block_plus_node_state": (block + node_bytes) as f64 / ne as f64},
    }))
}

fn scene_text(nx: usize, ny: usize, kind: Kind, threads: usize, steps: u64, cracking: Option<u64>) -> String {
    let mut s = format!(
        "[mesh]\ntype = \"rectangle\"\nwidth = 2.0\nheight = 1.0\nnx = {nx}\nny = {ny}\nelement = \"{}\"\n[[material]]\nyoung_modulus = 100.0\npoisson_ratio = 0.3\ndensity = 1.0\nelement = \"{}\"\n[solver]\nthreads = {threads}\n[[support]]\nnodes = \"left\"\nfix = \"xy\"\n[[load]]\nname = \"pull\"\ntype = \"traction\"\nedges = \"right\"\nvalue = [1.0, 0.0]\n[[stage]]\nlevels = {{ pull = 1.0 }}\ndynamic = true\nmax_steps = {steps}\nsnapshot = false\n",
        kind_name(kind.cell),
        kind.name
    );
    if let Some(k) = cracking {
        // A strength never reached: the checks run in full, nothing splits.
        s += &format!("[cracking]\nat_equilibrium = false\ncheck_every = {k}\n[cracking.criterion]\ntype = \"rankine\"\ntensile_strength = 1e30\n[cracking.separation]\ntype = \"sigma1_nearest\"\n");
    }
    s
}

fn sim(text: &str) -> Result<Simulation> {
    Ok(Simulation::new(Scene::from_str(text, Path::new("<bench scene>"), Path::new("."))?)?)
}

/// (wall, CPU) seconds per step of a whole dynamic stage of `steps` steps (best of 3 runs each).
fn stage_time(text: &str, steps: u64) -> Result<(f64, f64)> {
    let (mut wall, mut cpu) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..3 {
        let (w, c) = stage_once(text, steps, true)?;
        wall = wall.min(w);
        cpu = cpu.min(c);
    }
    Ok((wall, cpu))
}

/// Rounds of the interleaved failure-check measurement (baseline, skip, every point).
const CHECK_ROUNDS: usize = 4;

/// (wall, CPU) seconds per step of one dynamic stage of `steps` steps.
fn stage_once(text: &str, steps: u64, skip: bool) -> Result<(f64, f64)> {
    let mut s = sim(text)?;
    if let Some(c) = s.cracking.as_mut() {
        c.certified_skip = skip;
    }
    let (t, c) = (Instant::now(), cpu_seconds());
    s.run_stage(0, &mut NoOutput)?;
    Ok((t.elapsed().as_secs_f64() / steps as f64, (cpu_seconds() - c) / steps as f64))
}

/// The bare explicit step: kernel plus the textbook central-difference update.
struct Bare {
    u: Vec<[f64; 2]>,
    v: Vec<[f64; 2]>,
    f: Vec<[f64; 2]>,
    fe: Vec<[f64; 2]>,
    m: Vec<f64>,
    fix: Vec<u8>,
    dt: f64,
}

impl Bare {
    /// The state, loads, masses and step of `s`.
    fn of(s: &Simulation) -> Bare {
        let st = &s.state;
        Bare { u: st.u.clone(), v: st.v.clone(), f: vec![[0.0; 2]; st.u.len()], fe: st.f_ext.clone(), m: st.mass.clone(), fix: st.fix.clone(), dt: s.dt }
    }

    fn step(&mut self, s: &Simulation) {
        s.model.internal_forces(&self.u, &mut self.f);
        self.update();
    }

    /// The textbook central-difference update alone.
    fn update(&mut self) {
        for c in 0..self.u.len() {
            for d in 0..2 {
                if self.fix[c] & (1 << d) == 0 {
                    self.v[c][d] += self.dt * (self.fe[c][d] - self.f[c][d]) / self.m[c];
                    self.u[c][d] += self.dt * self.v[c][d];
                }
            }
        }
    }
}

/// Full step against the bare kernel and a bare step; failure checks every k steps.
fn step_case(nx: usize, ny: usize, kind: Kind, threads: usize, o: &StepOpts) -> Result<Value> {
    let mut s = sim(&scene_text(nx, ny, kind, threads, 1, None))?;
    let ne = s.model.n_elems() as f64;
    s.run_stage(0, &mut NoOutput)?;
    let (step, step_cpu) = time_per_call(o.min_time, || s.step().expect("bench scene is stable"));
    let (lean, lean_cpu) = time_per_call(o.min_time, || s.step_as(false).expect("bench scene is stable"));
    let (u, mut f) = (s.state.u.clone(), vec![[0.0; 2]; s.state.u.len()]);
    let (kernel, kernel_cpu) = time_per_call(o.min_time, || s.model.internal_forces(&u, &mut f));
    // The bare explicit step: kernel plus the textbook update (no damping, no ledger).
    let mut bare_state = Bare::of(&s);
    let (bare, bare_cpu) = time_per_call(o.min_time, || bare_state.step(&s));
    // The node update alone (a lean step's, default damping) with the scalar code and with the
    // vectorised one (`Simd::best`), beside the textbook update alone; the nodes are put back.
    let nc = s.state.u.len() as f64;
    let (u0, v0) = (s.state.u.clone(), s.state.v.clone());
    let (node_plain, _) = time_per_call(o.min_time, || s.bench_node_update(Simd::Plain));
    let (node_best, _) = time_per_call(o.min_time, || s.bench_node_update(Simd::best()));
    (s.state.u, s.state.v) = (u0, v0);
    let mut text_state = Bare::of(&s);
    let (node_text, _) = time_per_call(o.min_time, || text_state.update());
    let node_update = json!({"simd": format!("{:?}", Simd::best()).to_lowercase(), "clusters": nc,
        "ns_per_node": node_best * 1e9 / nc, "ns_per_node_scalar": node_plain * 1e9 / nc, "ns_per_node_textbook": node_text * 1e9 / nc,
        "ns_per_elem": node_best * 1e9 / ne, "ns_per_elem_scalar": node_plain * 1e9 / ne, "ns_per_elem_textbook": node_text * 1e9 / ne,
        "scalar_over_vector": node_plain / node_best, "over_textbook": node_best / node_text});
    let n_steps = ((2.0 * o.min_time / step).ceil() as u64).clamp(200, 100_000);
    let n_steps = n_steps.div_ceil(100) * 100;
    let (stage, stage_cpu) = stage_time(&scene_text(nx, ny, kind, threads, n_steps, None), n_steps)?;
    // What a scene without contact or failure pays over the bare step, measured as a whole
    // stage (ledger, damping, ratio checks every `ratio_every` steps) against as many bare
    // steps, interleaved round by round so that the load of a shared machine hits both; the
    // best round of each. Twice: with the default (adaptive) damping, and undamped.
    // About 1 s per stage, so that the stage set-up (loads, constraints) is a small share.
    let n_il = (((1.0 / step).ceil() as u64).clamp(50, 50_000)).div_ceil(10) * 10;
    let il = |damping: &str| -> Result<Value> {
        let (mut il_stage, mut il_bare) = (f64::INFINITY, f64::INFINITY);
        for _ in 0..7 {
            let mut t = sim(&(scene_text(nx, ny, kind, threads, n_il, None) + damping))?;
            let t0 = Instant::now();
            t.run_stage(0, &mut NoOutput)?;
            il_stage = il_stage.min(t0.elapsed().as_secs_f64() / n_il as f64);
            let mut b = Bare::of(&t);
            let t0 = Instant::now();
            for _ in 0..n_il {
                b.step(&t);
            }
            il_bare = il_bare.min(t0.elapsed().as_secs_f64() / n_il as f64);
        }
        Ok(json!({"steps": n_il, "rounds": 7, "stage_ns_per_elem": il_stage * 1e9 / ne, "bare_step_ns_per_elem": il_bare * 1e9 / ne, "stage_over_bare_step": il_stage / il_bare}))
    };
    let (il_adaptive, il_none) = (il("")?, il("[solver.damping]\ntype = \"none\"\n")?);
    // Checks every k steps, with the certified skip (the default, issue 24: the bench's
    // strength is never approached, so every check after the first is certified and skipped)
    // and evaluating every point at every check (`every_point`). Each against its own
    // baseline (the same stage without cracking), the three interleaved round by round so
    // that the load of a shared machine hits all of them; the best round of each.
    let mut checks = Vec::new();
    for k in [1u64, 10, 100] {
        let text = scene_text(nx, ny, kind, threads, n_steps, Some(k));
        let plain = scene_text(nx, ny, kind, threads, n_steps, None);
        let best = |a: (f64, f64), b: (f64, f64)| (a.0.min(b.0), a.1.min(b.1));
        let inf = (f64::INFINITY, f64::INFINITY);
        let (mut base, mut skip, mut every) = (inf, inf, inf);
        for _ in 0..CHECK_ROUNDS {
            base = best(base, stage_once(&plain, n_steps, true)?);
            skip = best(skip, stage_once(&text, n_steps, true)?);
            every = best(every, stage_once(&text, n_steps, false)?);
        }
        checks.push((k, base, skip, every));
    }
    // The first check of a model pays a one-time set-up (the corner gradients of the nodal
    // stress, the certified skip's Lipschitz constants): timed alone on a fresh simulation
    // (one step, then the check); it is inside every stage above, which start fresh.
    let first_check = {
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            let mut t = sim(&scene_text(nx, ny, kind, threads, n_steps, Some(1)))?;
            t.step()?;
            let (time, step) = (t.state.time, t.state.step);
            let (cr, cfg) = (t.cracking.as_mut().expect("cracking scene"), t.scene.file.cracking.as_ref().expect("cracking config"));
            let t0 = Instant::now();
            cr.check(cfg, &mut t.model, &t.state.u, &t.x0, time, step)?;
            best = best.min(t0.elapsed().as_secs_f64());
        }
        best
    };
    // The share a check every k steps should cost, from the cost of one check (k = 1 run).
    let per_check = checks[0].2 .0 - checks[0].1 .0;
    let per_check_cpu = checks[0].2 .1 - checks[0].1 .1;
    let checks_base = checks[0].1 .0;
    let checks: Vec<Value> = checks
        .iter()
        .map(|&(k, (b, bc), (t, c), (te, ce))| {
            json!({"every": k, "us_per_step": t * 1e6, "overhead": t / b - 1.0, "share_predicted": per_check / (k as f64 * b),
                   "cpu_us_per_step": c * 1e6, "cpu_overhead": c / bc - 1.0, "cpu_share_predicted": per_check_cpu / (k as f64 * bc),
                   "every_point_us_per_step": te * 1e6, "every_point_overhead": te / b - 1.0, "every_point_cpu_overhead": ce / bc - 1.0,
                   "baseline_us_per_step": b * 1e6, "rounds": CHECK_ROUNDS})
        })
        .collect();
    Ok(json!({
        "kind": kind.name, "elements": ne, "threads": s.model.threads(), "dt": s.dt, "stage_steps": n_steps,
        "ns_per_elem": {"kernel": kernel * 1e9 / ne, "bare_step": bare * 1e9 / ne, "step": step * 1e9 / ne, "lean_step": lean * 1e9 / ne, "stage": stage * 1e9 / ne},
        "lean_step_over_bare_step": lean / bare, "cpu_lean_step_over_bare_step": lean_cpu / bare_cpu,
        "cpu_stage_over_bare_step": stage_cpu / bare_cpu,
        "cpu_ns_per_elem": {"kernel": kernel_cpu * 1e9 / ne, "bare_step": bare_cpu * 1e9 / ne, "step": step_cpu * 1e9 / ne, "lean_step": lean_cpu * 1e9 / ne, "stage": stage_cpu * 1e9 / ne},
        "step_over_kernel": step / kernel,
        "cpu_step_over_bare_step": step_cpu / bare_cpu,
        "step_over_bare_step": step / bare,
        "stage_over_bare_step": stage / bare,
        "interleaved": il_adaptive, "interleaved_undamped": il_none,
        "node_update": node_update,
        "failure_check": {"us_per_check": per_check * 1e6, "cpu_us_per_check": per_check_cpu * 1e6, "every_k": checks, "first_check_ms": first_check * 1e3, "first_check_in_stage_share": first_check / (n_steps as f64 * checks_base)},
        "failure_check_nonlocal": nonlocal_case(nx, ny, kind, threads, o)?,
    }))
}

/// One failure check called directly (`Cracking::check`, nothing splits) with the paper's
/// corner mean and with the nonlocal average (ours, issue 18) at radius `o.nonlocal_radius_h`
/// element sizes, at the displacement after 20 steps.
fn check_cost(nx: usize, ny: usize, kind: Kind, threads: usize, radius: Option<f64>, o: &StepOpts) -> Result<(f64, f64, f64, f64)> {
    let mut text = scene_text(nx, ny, kind, threads, 50, Some(1));
    if let Some(r) = radius {
        text = text.replace("[cracking]\n", &format!("[cracking]\nnonlocal = {{ radius = {r} }}\n"));
    }
    let t0 = Instant::now();
    let mut s = sim(&text)?;
    let build = t0.elapsed().as_secs_f64();
    for _ in 0..20 {
        s.step()?;
    }
    let (u, x0) = (s.state.u.clone(), s.x0.clone());
    let mut cr = s.cracking.take().context("bench scene has [cracking]")?;
    // The full check (every point), as before issue 24's certified skip.
    cr.certified_skip = false;
    let cfg = s.scene.file.cracking.as_ref().context("bench scene has [cracking]")?;
    let model = &mut s.model;
    let (t, c) = time_per_call(o.min_time, || {
        let (rec, _) = cr.check(cfg, model, &u, &x0, 0.0, 0).expect("check");
        assert!(rec.is_empty(), "the bench strength is never reached");
    });
    // The certified skip's own cost (issue 24): every check after the first is certified here.
    cr.certified_skip = true;
    let (ts, _) = time_per_call(o.min_time, || {
        let (rec, _) = cr.check(cfg, model, &u, &x0, 0.0, 0).expect("check");
        assert!(rec.is_empty(), "the bench strength is never reached");
    });
    Ok((t, c, build, ts))
}

fn nonlocal_case(nx: usize, ny: usize, kind: Kind, threads: usize, o: &StepOpts) -> Result<Value> {
    let h = 2.0 / nx as f64;
    let r = o.nonlocal_radius_h * h;
    let (local, local_cpu, local_build, skipped) = check_cost(nx, ny, kind, threads, None, o)?;
    let (nl, nl_cpu, nl_build, _) = check_cost(nx, ny, kind, threads, Some(r), o)?;
    Ok(json!({"radius": r, "radius_over_h": o.nonlocal_radius_h, "us_per_check_local": local * 1e6, "us_per_check_nonlocal": nl * 1e6, "us_per_check_local_certified_skip": skipped * 1e6,
              "nonlocal_over_local": nl / local, "cpu_nonlocal_over_local": nl_cpu / local_cpu,
              "scene_build_seconds_local": local_build, "scene_build_seconds_nonlocal": nl_build}))
}

pub fn step(o: &StepOpts) -> Result<()> {
    // The machine's bandwidth at each thread count, in this run (issue 24: the kernel's
    // effective bandwidth is quoted as a fraction of it).
    let mut triad = Vec::new();
    let all = std::thread::available_parallelism().map_or(1, |n| n.get());
    // Always one thread and all threads (issue 24), besides the thread counts asked for.
    for &t in [1, all].iter().chain(&o.threads) {
        let n = if t == 0 { std::thread::available_parallelism().map_or(1, |n| n.get()) } else { t };
        if !triad.iter().any(|(k, _)| *k == n) {
            triad.push((n, triad_gb_per_s(n, o.min_time)?));
        }
    }
    eprintln!("bench: triad {triad:?} GB/s");
    let mut kernels = Vec::new();
    for &kind in &o.kinds {
        for &n in &o.sizes {
            let (nx, ny) = grid_for(n, kind.cell);
            kernels.push(kernel_case(nx, ny, kind, o, &triad)?);
            eprintln!("bench: kernel {} {} elements done", kind.name, kernels.last().unwrap()["elements"]);
        }
    }
    let mut steps = Vec::new();
    for &kind in &o.kinds {
        for &n in o.step_sizes.iter() {
            let (nx, ny) = grid_for(n, kind.cell);
            for &t in &o.threads {
                steps.push(step_case(nx, ny, kind, t, o)?);
                eprintln!("bench: step {} {n} elements, {t} threads done", kind.name);
            }
        }
    }
    let out = json!({
        "bench": "step",
        "cpus": std::thread::available_parallelism().map_or(1, |n| n.get()),
        "triad": triad.iter().map(|(t, g)| json!({"threads": t, "gb_per_s": g})).collect::<Vec<_>>(),
        "kernel": kernels,
        "step": steps,
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}
