//! The implicit check of a 3D run (issue 38; docs/3d.md "Implicit check"): after every stage
//! of a 3D scene with `[check]`, the check solver's 3D form (`CheckSolver::solve_3d`; the
//! built-in `faer_cholesky` assembles the same element kinds and factorises with the project's
//! sparse Cholesky, `flem-plugins/src/check/solid3.rs`) solves the linear static problem of
//! the *same* body: one point per cluster (so every face separated by a split or by
//! `model.separated` is open), each cell's material and element kind, the current fixities
//! with the prescribed dofs at FLEM's displacement, and the external force in force (loads at
//! the stage's levels and gravity). The figures are 2D's (`compare.rs`):
//!
//! ```text
//! rel_l2_displacement        = |u_flem - u_imp|_2 / |u_imp|_2
//! max_abs_displacement_error = max_c,d |u_flem - u_imp|
//! rel_l2_nodal_stress        = |s_flem - s_imp|_2 / |s_imp|_2   (mean of the copies' 0.9999 corners)
//! ```
//!
//! written to `compare.json` (rewritten atomically after each stage; a non-finite figure is
//! `null`) and, with `vtu = true`, `compare_NNNN_stageK.vtu` (the snapshot's arrays plus
//! `displacement_implicit`, `displacement_difference` and the norm of the nodal stress
//! difference, FLEM minus implicit).
//!
//! A stage is comparable when FLEM ended it at rest (not at its step limit, not a dynamic
//! stage), no contact force acts (the linear check models no contact) and the scene does not
//! mark it `check = false`; a body that is not held against its rigid motions (a fragment cut
//! loose, a mechanism) makes the solve singular, which the row names as the reason. What 2D
//! has and 3D has not yet: statically determinate supports added to free fragments
//! (`plugin::support`), the plastic check.
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::{FlemError, Result};
use crate::mesh::RawMesh3;
use crate::output::compare::{rel_l2, StageComparison};
use crate::output::{atomic_write, body3::snapshot3};
use crate::plugin::check::{CheckCfg, Linear3};
use crate::scene3::Scene3;
use crate::solver::march3::{March3, Observer3, Stage3Result};

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// The body of `m` as the implicit check sees it: one point per cluster, the cells naming
/// clusters, and per cell its material and kind.
pub fn linear3_of<'a>(m: &March3, scene: &Scene3, mesh: &'a mut RawMesh3) -> Result<Vec<(f64, f64, &'static str)>> {
    let t = &m.topo;
    mesh.source = format!("{} (its clusters after the run's splits)", m.mesh.source);
    mesh.points = t.cluster_point.iter().map(|p| m.mesh.points[p.idx()]).collect();
    mesh.cells = crate::output::body3::cluster_cells(m);
    mesh.ids = m.mesh.ids.clone();
    let name = scene.path.display().to_string();
    let mut cells = vec![(0.0, 0.0, ""); t.n_elems()];
    for b in &m.blocks {
        for &e in b.elems() {
            let region = m.mesh.cell_region.get(e.idx()).map_or("all", |s| s.as_str());
            let mat = scene.material_for(region).ok_or_else(|| FlemError::config(&name, "material", format!("no [[material]] for region \"{region}\"")))?;
            cells[e.idx()] = (mat.young_modulus, mat.poisson_ratio, b.kind());
        }
    }
    Ok(cells)
}

/// Compares the state of `m` at the end of stage `stage` (`r`) with the implicit solve.
/// Returns the row and, when the solve succeeded, the implicit displacement and nodal stress.
pub fn compare_stage3(m: &March3, scene: &Scene3, cfg: &CheckCfg, stage: usize, r: &Stage3Result, wall_flem: f64) -> Result<(StageComparison, Option<(Vec<[f64; 3]>, Vec<[f64; 6]>)>)> {
    let st = &m.state;
    let mut c = StageComparison {
        stage,
        name: r.name.clone(),
        clusters: m.topo.n_clusters(),
        dofs: st.fix.iter().map(|&b| 3 - (b & 7).count_ones() as usize).sum(),
        flem_steps: r.steps,
        flem_converged: r.at_rest,
        unbalanced_ratio: finite(r.ratio),
        splits: r.splits,
        wall_seconds_flem: wall_flem,
        ..Default::default()
    };
    let st_cfg = scene.file.stages.get(stage);
    if st_cfg.is_some_and(|s| !s.check) {
        c.reason = Some(format!("the scene marks this stage as not checked (stage[{stage}].check = false)"));
        return Ok((c, None));
    }
    let mut reasons = Vec::new();
    if st_cfg.is_some_and(|s| s.dynamic) {
        reasons.push("FLEM is not at rest: a dynamic stage (stage.dynamic = true) runs a fixed number of steps, not to equilibrium".to_string());
    } else if !r.at_rest {
        reasons.push(format!("FLEM is not at rest: the stage stopped after {} steps with the unbalanced-force ratio {:.3e}, above its tolerance (no equilibrium reached)", r.steps, r.ratio));
    }
    if st.f_con.iter().any(|f| f.iter().any(|&x| x != 0.0)) {
        reasons.push("contact forces act at the end of the stage, and the implicit check models no contact".to_string());
    }
    let mut mesh = RawMesh3::default();
    let cells = linear3_of(m, scene, &mut mesh)?;
    let problem = Linear3 { mesh: &mesh, cells, fix: &st.fix, u_prescribed: &st.u, f_ext: &m.f_const };
    let t0 = Instant::now();
    let solved = cfg.solver().solve_3d(&problem);
    c.wall_seconds_implicit = t0.elapsed().as_secs_f64();
    let done = |mut c: StageComparison, reasons: Vec<String>| {
        c.comparable = reasons.is_empty();
        c.reason = (!reasons.is_empty()).then(|| reasons.join("; "));
        c
    };
    let sol = match solved {
        Ok(s) if s.u.iter().all(|v| v.iter().all(|x| x.is_finite())) && s.nodal_stress.iter().all(|v| v.iter().all(|x| x.is_finite())) => s,
        Ok(_) => {
            c.implicit_error = Some("the implicit solution is not finite".into());
            return Ok((done(c, reasons), None));
        }
        Err(e) => {
            let msg = e.to_string();
            if msg.contains("singular") {
                reasons.push(format!("a fragment without support or a mechanism: {msg}"));
            }
            c.implicit_error = Some(msg);
            return Ok((done(c, reasons), None));
        }
    };
    c.dofs = sol.n_dofs;
    let mut c = done(c, reasons);
    let s_flem = m.nodal_stress();
    c.rel_l2_displacement = rel_l2(&st.u, &sol.u);
    c.rel_l2_nodal_stress = rel_l2(&s_flem, &sol.nodal_stress);
    c.max_abs_displacement_error = finite(st.u.iter().zip(&sol.u).flat_map(|(a, b)| (0..3).map(move |d| (a[d] - b[d]).abs())).fold(0.0, f64::max));
    c.max_abs_displacement = finite(sol.u.iter().flat_map(|v| v.iter().map(|x| x.abs())).fold(0.0, f64::max));
    c.within_tolerance = matches!((c.rel_l2_displacement, c.rel_l2_nodal_stress), (Some(a), Some(b)) if a <= cfg.tolerance && b <= cfg.tolerance);
    Ok((c, Some((sol.u, sol.nodal_stress))))
}

/// An observer that forwards to `inner` and, at the end of every stage, runs the comparison,
/// writes its VTU (`vtu = true`) and rewrites `compare.json` in `dir`.
pub struct Comparer3<'a> {
    inner: &'a mut dyn Observer3,
    scene: &'a Scene3,
    dir: PathBuf,
    pub rows: Vec<StageComparison>,
    t_stage: Instant,
}

impl<'a> Comparer3<'a> {
    /// The scene must have `[check]` (`Scene3::from_str` fills in its default solver).
    pub fn new(inner: &'a mut dyn Observer3, scene: &'a Scene3, dir: &Path) -> Result<Self> {
        if scene.file.check.is_none() {
            return Err(FlemError::config(scene.path.display().to_string(), "check", "is missing: the comparison needs a [check] section"));
        }
        Ok(Comparer3 { inner, scene, dir: dir.to_path_buf(), rows: Vec::new(), t_stage: Instant::now() })
    }

    /// A resumed run (`run3::run3_with`): the rows of the stages before `stage` from the
    /// folder's `compare.json`; refused, naming the file, when it does not hold one row for each
    /// of them (the resumed compare.json and summary.json would lose their verdicts).
    pub fn keep_rows_before(&mut self, stage: usize) -> Result<()> {
        if stage == 0 {
            return Ok(());
        }
        let path = self.dir.join("compare.json");
        let rows = std::fs::read_to_string(&path)
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .and_then(|v| serde_json::from_value::<Vec<StageComparison>>(v["stages"].clone()).ok())
            .unwrap_or_default();
        self.rows = rows.into_iter().filter(|r| r.stage < stage).collect();
        if self.rows.len() != stage || self.rows.iter().enumerate().any(|(i, r)| r.stage != i) {
            return Err(FlemError::Output {
                path: path.display().to_string(),
                msg: format!("does not hold the implicit check of the {stage} stage(s) before the checkpoint (missing or edited); the resumed run cannot report them: start it again without --resume"),
            });
        }
        Ok(())
    }

    fn write_json(&self) -> Result<()> {
        let cfg = self.scene.file.check.as_ref();
        let v = serde_json::json!({
            "scene": self.scene.path.display().to_string(),
            "title": self.scene.file.title,
            "dim": 3,
            "solver": cfg.and_then(|c| c.solver.as_ref()).and_then(|s| serde_json::to_value(s).ok()),
            "tolerance": cfg.map(|c| c.tolerance),
            "stages": self.rows,
        });
        let path = self.dir.join("compare.json");
        let text = serde_json::to_string_pretty(&v).map_err(|e| FlemError::Output { path: path.display().to_string(), msg: e.to_string() })?;
        atomic_write(&path, text.as_bytes())
    }
}

impl Observer3 for Comparer3<'_> {
    fn start(&mut self, m: &March3) -> Result<()> {
        self.t_stage = Instant::now();
        self.inner.start(m)
    }
    fn every(&self) -> u64 {
        self.inner.every()
    }
    fn step(&mut self, m: &March3, stage: usize) -> Result<()> {
        self.inner.step(m, stage)
    }
    fn checkpoint_due(&mut self, m: &March3) -> bool {
        self.inner.checkpoint_due(m)
    }
    fn checkpoint(&mut self, m: &March3, pos: &crate::solver::march3::Pos3) -> Result<()> {
        self.inner.checkpoint(m, pos)
    }
    fn should_stop(&mut self) -> bool {
        self.inner.should_stop()
    }
    fn stage_done(&mut self, m: &March3, stage: usize, r: &Stage3Result) -> Result<()> {
        self.inner.stage_done(m, stage, r)?;
        let wall = self.t_stage.elapsed().as_secs_f64();
        let cfg = self.scene.file.check.as_ref().expect("checked in new");
        let (mut row, fields) = compare_stage3(m, self.scene, cfg, stage, r, wall)?;
        if let (true, Some((u_imp, s_imp))) = (cfg.vtu, fields) {
            let name = format!("compare_{:04}_stage{stage}.vtu", self.rows.len());
            let du: Vec<[f64; 3]> = m.state.u.iter().zip(&u_imp).map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]]).collect();
            let ds: Vec<f64> = m.nodal_stress().iter().zip(&s_imp).map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt()).collect();
            snapshot3(m)
                .point_vector("displacement_implicit", &u_imp)
                .point_vector("displacement_difference", &du)
                .point_scalar("nodal_stress_difference_norm", &ds)
                .write(&self.dir.join(&name), true)?;
            row.vtu = Some(name);
        }
        self.rows.push(row);
        self.write_json()?;
        self.t_stage = Instant::now();
        Ok(())
    }
}
