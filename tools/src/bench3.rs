//! `flem bench step3`: the 3D explicit step's throughput (issue 38, must-show 6), printed as one
//! JSON object, with `flem bench step`'s machinery (`bench.rs`): every timed figure once per
//! round, at least 5 rounds one after the other, each round measuring the STREAM triad first
//! and then every case at every thread count in turn, so that the load of a shared machine hits
//! every figure alike; each figure printed as median, range (min, max) and rounds.
//!
//! Meshes: `[mesh] type = "box"` (core/src/mesh/box3.rs), a unit cube of `n^3` bricks (H8) or
//! of `6 n^3` tetrahedra (T4, six per brick), `n` the nearest to the element count asked; E =
//! 100, nu = 0.3, rho = 1; `xmin` held, a pressure on `xmax`. Element order: the mesh's
//! (`--order mesh`: bricks x fastest, then y, then z; a brick's six tetrahedra together) or the
//! cells sorted along a Morton curve of their centroids (`--order morton`).
//!
//! Per case and thread count:
//! - `kernel`: the element loop (`March3::internal_forces`: the force array zeroed, then every
//!   block's coloured pass, `plugins/src/elements3d/block.rs`) at a random displacement, in ns
//!   per element-update, with the check that the forces are the same bits as on one thread;
//!   the bytes an update streams at the least (the block's packs and connectivity,
//!   `Block3::kernel_bytes`, plus per cluster `u` read 24 B, `f_int` zeroed 24 B and read and
//!   written 48 B) over the time, against the triad of the same round (`fraction_of_triad`);
//! - `step`: the whole step (`March3::step`: element loop, loads, damping coefficients, the
//!   node update and its sums) of the loaded cube, ns per element-update.
//!
//! `--write-msh DIR` writes the T4 meshes of `--sizes` as gmsh 2.2 files (`box_t4_<n>_v22.msh`:
//! physical surfaces `xmin` (1), `xmax` (2), physical volume `body` (3)) and measures nothing:
//! the meshes of the Akantu peer, `tools/peers/akantu_3d_throughput.py`.
use std::path::PathBuf;

use anyhow::{Context, Result};
use flem_core::mesh::{Box3, CellKind3, RawMesh3};
use flem_core::plugin::damping::Damping;
use flem_core::solver::march3::{March3, Support3};
use serde_json::{json, Value};

use crate::bench::{time_per_call, triad_gb_per_s, Spread};

#[derive(clap::Args)]
pub struct Args {
    /// Element counts (about: the cube of the nearest whole number of bricks per side).
    #[arg(long, value_delimiter = ',', default_value = "100000,1000000")]
    sizes: Vec<usize>,
    /// Thread counts (0: one per core).
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    threads: Vec<usize>,
    /// 3D element kinds (t4, h8, h8_full).
    #[arg(long, value_delimiter = ',', default_value = "t4,h8")]
    kinds: Vec<String>,
    /// Element orders: mesh, morton (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "mesh")]
    order: Vec<String>,
    /// Seconds spent per timing (median of 5 batches).
    #[arg(long, default_value_t = 1.0)]
    min_time: f64,
    /// Rounds of every figure (at least 5).
    #[arg(long, default_value_t = 5)]
    rounds: usize,
    /// Skip the whole-step figures (the element loop only).
    #[arg(long)]
    no_step: bool,
    /// Write the T4 box meshes of `--sizes` as gmsh 2.2 into this folder and stop.
    #[arg(long)]
    write_msh: Option<PathBuf>,
}

/// Bricks per side for about `n` elements of `cell`.
fn side(n: usize, cell: CellKind3) -> usize {
    let bricks = if cell == CellKind3::T4 { n as f64 / 6.0 } else { n as f64 };
    (bricks.cbrt().round() as usize).max(1)
}

fn box_mesh(n: usize, cell: CellKind3) -> Result<RawMesh3> {
    let s = side(n, cell);
    Ok(Box3::new([1.0, 1.0, 1.0], [s, s, s], cell).build()?)
}

/// Cells sorted along a Morton curve of their centroids (21 bits per axis over the bounding box).
fn morton(mesh: &mut RawMesh3) {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in &mesh.points {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    let spread = |x: u64| {
        let mut x = x & 0x1f_ffff;
        x = (x | x << 32) & 0x1f00000000ffff;
        x = (x | x << 16) & 0x1f0000ff0000ff;
        x = (x | x << 8) & 0x100f00f00f00f00f;
        x = (x | x << 4) & 0x10c30c30c30c30c3;
        (x | x << 2) & 0x1249249249249249
    };
    let code = |c: &flem_core::mesh::RawCell3| {
        let k = c.corners();
        let mut q = [0u64; 3];
        for d in 0..3 {
            let x = k.iter().map(|&p| mesh.points[p as usize][d]).sum::<f64>() / k.len() as f64;
            q[d] = (((x - lo[d]) / (hi[d] - lo[d]).max(1e-300)) * ((1u64 << 21) - 1) as f64) as u64;
        }
        spread(q[0]) | spread(q[1]) << 1 | spread(q[2]) << 2
    };
    let mut idx: Vec<(u64, usize)> = mesh.cells.iter().enumerate().map(|(i, c)| (code(c), i)).collect();
    idx.sort_unstable();
    mesh.cells = idx.iter().map(|&(_, i)| mesh.cells[i]).collect();
    if !mesh.cell_region.is_empty() {
        mesh.cell_region = idx.iter().map(|&(_, i)| mesh.cell_region[i].clone()).collect();
    }
    if let Some(ids) = mesh.ids.as_mut() {
        if ids.cells.len() == idx.len() {
            ids.cells = idx.iter().map(|&(_, i)| ids.cells[i]).collect();
        }
    }
}

struct Case {
    kind: String,
    order: String,
    m: March3,
    u: Vec<[f64; 3]>,
    reference: Vec<[f64; 3]>,
    identical: Vec<bool>,
    kernel: Vec<Spread>,
    step: Vec<Spread>,
    min_bytes: f64,
    fixed: Value,
}

impl Case {
    fn new(kind: &str, n: usize, order: &str, a: &Args) -> Result<Case> {
        let cell = flem_plugins::elements3d::Kind3::from_name(kind).with_context(|| format!("--kinds: \"{kind}\" is no 3D element kind (t4, h8, h8_full)"))?.cell();
        let t0 = std::time::Instant::now();
        let mut mesh = box_mesh(n, cell)?;
        if order == "morton" {
            morton(&mut mesh);
        }
        mesh.validate(Default::default())?;
        let xmin = mesh.node_sets["xmin"].clone();
        let material = |_: &str| -> flem_core::Result<([f64; 3], Option<String>)> { Ok(([100.0, 0.3, 1.0], Some(kind.to_string()))) };
        let damping: Box<dyn Damping> = toml::from_str("type = \"adaptive\"")?;
        let mut m = March3::new(mesh, &material, &[Support3 { points: xmin, fix: 7, velocity: [0.0; 3] }], damping, 0.9)?;
        let k = m.add_load("p");
        m.add_face_pressure(k, "xmax", 1.0)?;
        m.set_levels(&[("p".to_string(), 1.0)].into_iter().collect());
        let build_s = t0.elapsed().as_secs_f64();
        let (ne, nc) = (m.mesh.cells.len(), m.topo.n_clusters());
        let mut seed = 0x9E37_79B9_7F4A_7C15u64;
        let u: Vec<[f64; 3]> = (0..nc)
            .map(|_| {
                std::array::from_fn(|_| {
                    seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    1e-3 * ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5)
                })
            })
            .collect();
        m.set_threads(1)?;
        let reference = kernel_forces(&mut m, &u);
        let kernel_bytes: usize = m.blocks.iter().map(|b| b.kernel_bytes()).sum();
        let min_bytes = (kernel_bytes as f64 + 96.0 * nc as f64) / ne as f64;
        let colours: Vec<usize> = m.blocks.iter().map(|b| b.colours()).collect();
        let fixed = json!({
            "kind": kind, "order": order, "bricks_per_side": side(n, cell), "elements": ne, "clusters": nc,
            "build_s": build_s, "colours": colours, "dt": m.dt,
            "bytes_per_element": {"kernel_streamed": kernel_bytes as f64 / ne as f64, "per_update_min": min_bytes},
        });
        let nt = a.threads.len();
        Ok(Case {
            kind: kind.to_string(),
            order: order.to_string(),
            m,
            u,
            reference,
            identical: vec![true; nt],
            kernel: (0..nt).map(|_| Spread::default()).collect(),
            step: (0..nt).map(|_| Spread::default()).collect(),
            min_bytes,
            fixed,
        })
    }

    fn round(&mut self, a: &Args, triad: &[(usize, f64)]) -> Result<()> {
        let ne = self.m.mesh.cells.len() as f64;
        for (i, &t) in a.threads.iter().enumerate() {
            self.m.set_threads(t)?;
            // The element loop at a random displacement (the state's is kept aside).
            let keep = std::mem::replace(&mut self.m.state.u, self.u.clone());
            let m = &mut self.m;
            let (s, cpu) = time_per_call(a.min_time, || m.internal_forces());
            self.identical[i] &= self.m.state.f_int.iter().zip(&self.reference).all(|(x, y)| (0..3).all(|d| x[d].to_bits() == y[d].to_bits()));
            self.m.state.u = keep;
            let eff = self.min_bytes * ne / s / 1e9;
            let fig = &mut self.kernel[i];
            fig.add("ns_per_elem_update", s * 1e9 / ne);
            fig.add("cpu_ns_per_elem_update", cpu * 1e9 / ne);
            fig.add("effective_gb_per_s", eff);
            if let Some(&(_, tri)) = triad.iter().find(|(n, _)| *n == self.m.threads()) {
                fig.add("triad_gb_per_s", tri);
                fig.add("fraction_of_triad", eff / tri);
            }
            if !a.no_step {
                let m = &mut self.m;
                let mut err = None;
                let (s, cpu) = time_per_call(a.min_time, || {
                    if let Err(e) = m.step() {
                        err = Some(e);
                    }
                });
                if let Some(e) = err {
                    return Err(e.into());
                }
                let fig = &mut self.step[i];
                fig.add("ns_per_elem_update", s * 1e9 / ne);
                fig.add("cpu_ns_per_elem_update", cpu * 1e9 / ne);
            }
        }
        Ok(())
    }

    fn json(&self, a: &Args) -> Value {
        let all = std::thread::available_parallelism().map_or(1, |n| n.get());
        let per: Vec<Value> = a
            .threads
            .iter()
            .enumerate()
            .map(|(i, &t)| {
                let mut v = json!({"threads": if t == 0 { all } else { t }, "kernel": self.kernel[i].json(), "bit_identical_to_one_thread": self.identical[i]});
                if !a.no_step {
                    v["step"] = self.step[i].json();
                }
                v
            })
            .collect();
        let mut v = self.fixed.clone();
        v["threads"] = json!(per);
        let _ = (&self.kind, &self.order);
        v
    }
}

/// `f_int` at `u` (the state's displacement for the call).
fn kernel_forces(m: &mut March3, u: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let keep = std::mem::replace(&mut m.state.u, u.to_vec());
    m.internal_forces();
    m.state.u = keep;
    m.state.f_int.clone()
}

/// A T4 box as gmsh 2.2 ASCII: the boundary triangles of `xmin` and `xmax` (physical 1 and 2)
/// and the tetrahedra (physical 3), nodes and elements numbered from 1.
fn write_msh(mesh: &RawMesh3, path: &std::path::Path) -> Result<()> {
    use std::fmt::Write;
    let mut s = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n3\n2 1 \"xmin\"\n2 2 \"xmax\"\n3 3 \"body\"\n$EndPhysicalNames\n$Nodes\n");
    writeln!(s, "{}", mesh.points.len())?;
    for (i, p) in mesh.points.iter().enumerate() {
        writeln!(s, "{} {:?} {:?} {:?}", i + 1, p[0], p[1], p[2])?;
    }
    s += "$EndNodes\n$Elements\n";
    let mut rows = Vec::new();
    for (tag, set) in [(1, "xmin"), (2, "xmax")] {
        for f in &mesh.face_sets[set] {
            let c = f.corners();
            anyhow::ensure!(c.len() == 3, "face set {set}: a face of {} corners", c.len());
            rows.push(format!("2 2 {tag} {tag} {} {} {}", c[0] + 1, c[1] + 1, c[2] + 1));
        }
    }
    for c in &mesh.cells {
        let k = c.corners();
        rows.push(format!("4 2 3 3 {} {} {} {}", k[0] + 1, k[1] + 1, k[2] + 1, k[3] + 1));
    }
    writeln!(s, "{}", rows.len())?;
    for (i, r) in rows.iter().enumerate() {
        writeln!(s, "{} {r}", i + 1)?;
    }
    s += "$EndElements\n";
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

pub fn run(a: &Args) -> Result<()> {
    anyhow::ensure!(a.rounds >= 5, "--rounds = {} is incorrect; it must be at least 5 (a median and a range need them)", a.rounds);
    anyhow::ensure!(a.min_time > 0.0 && a.min_time.is_finite(), "--min-time = {} is incorrect; it must be > 0", a.min_time);
    anyhow::ensure!(a.sizes.iter().all(|&n| (6..=16_000_000).contains(&n)), "--sizes: each must be in [6, 16000000]");
    anyhow::ensure!(a.threads.iter().all(|&t| t <= 1024), "--threads: each must be in [0, 1024]");
    anyhow::ensure!(a.order.iter().all(|o| o == "mesh" || o == "morton"), "--order: each must be \"mesh\" or \"morton\"");
    if let Some(dir) = &a.write_msh {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let mut out = Vec::new();
        for &n in &a.sizes {
            let mesh = box_mesh(n, CellKind3::T4)?;
            let path = dir.join(format!("box_t4_{n}_v22.msh"));
            write_msh(&mesh, &path)?;
            out.push(json!({"file": path, "elements": mesh.cells.len(), "points": mesh.points.len(), "bricks_per_side": side(n, CellKind3::T4)}));
        }
        println!("{}", serde_json::to_string_pretty(&json!({"bench": "step3", "meshes": out}))?);
        return Ok(());
    }
    flem_plugins::link();
    let all = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut triad_threads = Vec::new();
    for &t in [1, all].iter().chain(&a.threads) {
        let n = if t == 0 { all } else { t };
        if !triad_threads.contains(&n) {
            triad_threads.push(n);
        }
    }
    let mut cases = Vec::new();
    for kind in &a.kinds {
        for &n in &a.sizes {
            for order in &a.order {
                cases.push(Case::new(kind, n, order, a)?);
                eprintln!("bench step3: built {kind} {n} ({order} order)");
            }
        }
    }
    let mut triad = Spread::default();
    for r in 0..a.rounds {
        let mut this = Vec::new();
        for &t in &triad_threads {
            let g = triad_gb_per_s(t, a.min_time)?;
            triad.add(&format!("threads_{t}"), g);
            this.push((t, g));
        }
        for c in cases.iter_mut() {
            c.round(a, &this)?;
        }
        eprintln!("bench step3: round {} of {} done (triad {this:?} GB/s)", r + 1, a.rounds);
    }
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    let out = json!({
        "bench": "step3",
        "cpus": all,
        "rounds": a.rounds,
        "min_time_per_figure_and_round": a.min_time,
        "loadavg_at_end": load.trim(),
        "triad_gb_per_s": triad.json(),
        "cases": cases.iter().map(|c| c.json(a)).collect::<Vec<_>>(),
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}
