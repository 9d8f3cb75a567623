//! `flem bench implicit`: the implicit check solver's path (checks, assembly, symbolic and
//! numeric Cholesky, solve with one refinement step) against faer's bare sparse Cholesky
//! (`SymbolicLlt::try_new` + `Llt::try_new_with_symbolic` + `solve`) on the same matrix, in the
//! same run, on structured plane-strain Q4 meshes (width 2 x height 1, `nx = 2 ny`, left side
//! clamped, a traction on the right side).
//!
//! `ratio_cold` = our first solve / bare, `ratio_warm` = a second solve on the same topology
//! (pattern, symbolic and numeric factorisations reused, as between the stages of a run without
//! splits: only the right-hand side is new) / bare. Each time is
//! the best of `repeats` runs. Each size runs on every thread count asked (`threads`, a rayon
//! pool of that size; faer's bare path gets the same `Par`). Ours orders by geometric nested
//! dissection (`factor.rs`), faer's bare path by its own AMD: `nnz_factor` and
//! `nnz_factor_bare` are the stored entries of each `L`.
use std::time::Instant;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymmetricOrdering};
use faer::{Conj, MatMut, Par, Side};
use flem_core::element::model::Model;
use flem_core::element::Plane;
use flem_core::mesh::{CellKind, Rectangle, ValidationOptions};
use flem_core::scene::MaterialCfg;
use flem_core::FlemError;
use serde::Serialize;

use super::{ImplicitSolver, Timings};

/// faer's bare Cholesky on the assembled matrix, seconds.
#[derive(Copy, Clone, Debug, Default, Serialize)]
pub struct BareTimings {
    pub symbolic: f64,
    pub numeric: f64,
    pub solve: f64,
    pub total: f64,
}

/// One mesh size.
#[derive(Clone, Debug, Serialize)]
pub struct ImplicitBenchRow {
    /// Threads of the pool both paths ran in.
    pub threads: usize,
    pub nx: usize,
    pub ny: usize,
    pub elements: usize,
    pub dofs: usize,
    /// Stored entries of the lower triangle of `K_ff`.
    pub nnz_lower: usize,
    /// Stored entries of our factor `L` (nested dissection) and of faer's bare one (AMD).
    pub nnz_factor: usize,
    pub nnz_factor_bare: usize,
    pub ours_cold: Timings,
    /// The first cold solve of the row, with no buffer kept from an earlier factorisation
    /// (`factor::release_spare` before it): what a process's first solve of this size costs.
    /// `ours_cold` is the best of the repeats, which reuse the factor's pages (`factor::SPARE`).
    pub ours_cold_first: Timings,
    pub ours_warm: Timings,
    pub bare: BareTimings,
    pub ratio_cold: f64,
    pub ratio_warm: f64,
    /// max |u_ours - u_bare| / max |u_bare| (both solve the same system).
    pub max_rel_difference: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct ImplicitBench {
    pub what: &'static str,
    pub repeats: usize,
    pub goal_ratio: f64,
    pub rows: Vec<ImplicitBenchRow>,
}

/// A structured Q4 cantilever with about `dofs` free dofs: model, fixities, nodal forces.
fn problem(dofs: f64) -> Result<(Model, Vec<u8>, Vec<[f64; 2]>, usize, usize), FlemError> {
    let ny = ((dofs / 4.0).sqrt().round() as usize).max(1);
    let nx = 2 * ny;
    let mut mesh = Rectangle::new(2.0, 1.0, nx, ny, CellKind::Q4).build()?;
    mesh.validate(ValidationOptions::Reorient)?;
    mesh.derive_node_sets();
    let mat = MaterialCfg::elastic(1000.0, 0.3, 1.0);
    let m = Model::new(mesh, &[mat], Plane::Strain, "<bench>")?;
    let nc = m.topo.n_clusters();
    let mut fix = vec![0u8; nc];
    let mut f = vec![[0.0; 2]; nc];
    let cl = |p: u32| m.topo.point_clusters[p as usize][0].idx();
    for &p in &m.mesh.node_sets["left"] {
        fix[cl(p)] = 3;
    }
    let h = 1.0 / ny as f64;
    for &p in &m.mesh.node_sets["right"] {
        f[cl(p)] = [0.0, -h];
    }
    Ok((m, fix, f, nx, ny))
}

/// faer's bare Cholesky (its default AMD ordering; what `SymbolicLlt::try_new` +
/// `Llt::try_new_with_symbolic` + `solve` do, written with the low-level calls so that the
/// factor size can be read and the parallelism set). Returns the solution, the times and the
/// stored entries of `L`.
fn bare(a: &faer::sparse::SparseColMat<usize, f64>, rhs: &[f64], par: Par) -> Result<(Vec<f64>, BareTimings, usize), FlemError> {
    let err = |e: String| FlemError::Solve(format!("bench: faer's bare Cholesky failed: {e}"));
    let t0 = Instant::now();
    let sym = factorize_symbolic_cholesky(a.symbolic(), Side::Lower, SymmetricOrdering::Amd, Default::default()).map_err(|e| err(format!("{e:?}")))?;
    let t1 = Instant::now();
    let mut l = vec![0.0; sym.len_val()];
    let mut mem = MemBuffer::new(sym.factorize_numeric_llt_scratch::<f64>(par, Default::default()));
    sym.factorize_numeric_llt::<f64>(&mut l, a.as_ref(), Side::Lower, Default::default(), par, MemStack::new(&mut mem), Default::default()).map_err(|e| err(format!("{e:?}")))?;
    let t2 = Instant::now();
    let mut x = rhs.to_vec();
    let mut mem = MemBuffer::new(sym.solve_in_place_scratch::<f64>(1, par));
    LltRef::new(&sym, &l).solve_in_place_with_conj(Conj::No, MatMut::from_column_major_slice_mut(&mut x, rhs.len(), 1), par, MemStack::new(&mut mem));
    let t3 = Instant::now();
    let s = |a: Instant, b: Instant| (b - a).as_secs_f64();
    Ok((x, BareTimings { symbolic: s(t0, t1), numeric: s(t1, t2), solve: s(t2, t3), total: s(t0, t3) }, l.len()))
}

fn min_by_total<T: Copy>(v: &[T], total: impl Fn(&T) -> f64) -> T {
    *v.iter().min_by(|a, b| total(a).total_cmp(&total(b))).expect("repeats >= 1")
}

/// Runs the benchmark for each target number of dofs and each thread count.
pub fn bench_implicit(dofs: &[f64], repeats: usize, threads: &[usize]) -> Result<ImplicitBench, FlemError> {
    let mut rows = Vec::new();
    for &d in dofs {
        for &t in threads {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(t.max(1)).build().map_err(|e| FlemError::Solve(format!("bench: thread pool of {t}: {e}")))?;
            rows.push(pool.install(|| bench_one(d, repeats))?);
        }
    }
    Ok(ImplicitBench { what: "implicit check solver vs faer bare sparse Cholesky", repeats: repeats.max(1), goal_ratio: 1.3, rows })
}

fn bench_one(d: f64, repeats: usize) -> Result<ImplicitBenchRow, FlemError> {
    let repeats = repeats.max(1);
    let par = super::factor::par(d as usize);
    {
        let (m, fix, f, nx, ny) = problem(d)?;
        let zero = vec![[0.0; 2]; f.len()];
        let (mut cold, mut warm, mut bt) = (Vec::new(), Vec::new(), Vec::new());
        let (mut u_ours, mut x, mut nnz_bare, mut nnz_factor) = (Vec::new(), Vec::new(), 0, 0);
        let (a, rhs) = ImplicitSolver::assembled(&m, &fix, &f, &zero);
        super::factor::release_spare();
        // Ours and the bare Cholesky alternate, so that a change of load on a shared machine
        // falls on both sides of the ratio.
        for _ in 0..repeats {
            let solver = ImplicitSolver::new();
            let (u, t) = solver.solve_timed(&m, &fix, &f, &zero)?;
            cold.push(t);
            warm.push(solver.solve_timed(&m, &fix, &f, &zero)?.1);
            u_ours = u;
            nnz_factor = solver.factor_nnz().unwrap_or(0);
            let (xb, t, nb) = bare(&a, &rhs, par)?;
            bt.push(t);
            x = xb;
            nnz_bare = nb;
        }
        // Compare the solutions (free dofs in cluster order).
        let mut k = 0;
        let (mut diff, mut scale) = (0.0f64, 0.0f64);
        for (c, &b) in fix.iter().enumerate() {
            for dd in 0..2 {
                if b & (1 << dd) == 0 {
                    diff = diff.max((u_ours[c][dd] - x[k]).abs());
                    scale = scale.max(x[k].abs());
                    k += 1;
                }
            }
        }
        let (c, w, b) = (min_by_total(&cold, |t| t.total), min_by_total(&warm, |t| t.total), min_by_total(&bt, |t| t.total));
        Ok(ImplicitBenchRow {
            threads: rayon::current_num_threads(),
            nnz_factor,
            nnz_factor_bare: nnz_bare,
            nx,
            ny,
            elements: m.n_elems(),
            dofs: rhs.len(),
            nnz_lower: a.compute_nnz(),
            ours_cold: c,
            ours_cold_first: cold[0],
            ours_warm: w,
            bare: b,
            ratio_cold: c.total / b.total,
            ratio_warm: w.total / b.total,
            max_rel_difference: diff / scale.max(f64::MIN_POSITIVE),
        })
    }
}

#[cfg(test)]
mod tests {
    /// The benchmark runs on a small mesh and both paths solve the same system: the solutions
    /// agree to 1e-10 relative (reference: faer's bare Cholesky on the same matrix).
    #[test]
    fn bench_small_mesh_same_solution() {
        let b = super::bench_implicit(&[2000.0], 1, &[1]).unwrap();
        let r = &b.rows[0];
        assert!(r.dofs > 1500 && r.dofs < 2500, "{r:?}");
        assert!(r.max_rel_difference < 1e-10, "{r:?}");
        assert!(r.ours_warm.symbolic == 0.0, "warm solve recomputed the symbolic factorisation: {r:?}");
        assert!(r.ratio_cold.is_finite() && r.ratio_warm.is_finite());
        // The nested dissection's fill against faer's AMD on the same matrix (reference): an
        // ordering gone wrong (e.g. the identity) fills a band several times larger.
        assert!(r.nnz_factor > 0 && (r.nnz_factor as f64) < 1.5 * r.nnz_factor_bare as f64, "{r:?}");
    }
}
