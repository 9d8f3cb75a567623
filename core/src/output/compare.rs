//! The FLEM-vs-implicit comparison run after every stage (METHOD.md section 10): an observer of
//! the solver that calls the scene's check solver (`crate::plugin::check::CheckSolver`, chosen
//! by the `[check]` section, `crate::plugin::check::CheckCfg`).
//!
//! After a stage reaches equilibrium, the check solver solves the linear static problem of the
//! *same* model: the current clusters (after any split), the current fixities and prescribed
//! displacements, and the external force at the stage's load levels
//! ([`Simulation::external_force`]; follower pressures on the reference configuration, so the
//! two agree only while displacements are small). The comparison measures, over clusters,
//!
//! ```text
//! rel_l2_displacement        = |u_flem - u_imp|_2 / |u_imp|_2
//! max_abs_displacement_error = max_c,d |u_flem - u_imp|
//! rel_l2_nodal_stress        = |s_flem - s_imp|_2 / |s_imp|_2   (nodal stress, METHOD section 3)
//! ```
//!
//! and writes per stage one VTU (`compare_NNNN_<stage>.vtu`: the snapshot fields, whose
//! `displacement` and `nodal_stress` are FLEM's, plus `displacement_implicit`,
//! `nodal_stress_implicit`, `displacement_difference` and `nodal_stress_difference`, each
//! FLEM minus implicit) and `compare.json` (rewritten atomically after every stage). A ratio
//! whose denominator is zero, or any non-finite number, is written as `null`, never as NaN.
//!
//! A stage is *comparable* when it has an equilibrium the implicit check can compute: FLEM at
//! rest at its end (the stage reached its tolerance; not a dynamic stage), every fragment held
//! (`plugin::support::plan`: enough prescribed dofs, or none and self-equilibrated loads, which
//! get a statically determinate support), no contact force acting, and the stage not marked
//! `check = false` (a plastic stage goes to the implicit plastic check, `compare_plastic_stage`, with the same reasons; large strain is refused as a whole, `Simulation::new`). Otherwise the row says
//! `comparable: false` with every `reason` (figures still given when the solve succeeded). On a
//! fragment given a statically determinate support the implicit displacement is shifted by the
//! rigid motion that fits FLEM's best (`plugin::support::align_rigid`) before the figures.
//!
//! [`Comparer`] is an `Observer` wrapper: it forwards everything to the run's observer (the
//! output writer) and at `Observer::stage_end` solves the current model (clusters after splits,
//! current fixities and load levels). `compare.json` also holds the wall times, the ratio
//! reached and the number of dofs. Used by `flem compare` and by `flem run` when the scene has
//! `[check]`.
use crate::cracking::SplitEvent;
use crate::error::{FlemError, Result};
use crate::mesh::topology::SplitRecord;
use crate::output::{atomic_write, prepare_dir, snapshot_vtk, vtu_bytes};
use crate::plugin::check::CheckSolver;
use crate::plugin::support::{self, AddedSupport};
use crate::solver::{Observer, Progress, Simulation};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;
use vtkio::model::{Attribute, DataSet, Piece};

/// The comparison of one stage (one entry of `compare.json`).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct StageComparison {
    pub stage: usize,
    pub name: String,
    pub clusters: usize,
    /// Free dofs of the implicit system.
    pub dofs: usize,
    pub flem_steps: u64,
    pub flem_converged: bool,
    /// Unbalanced-force ratio FLEM reached at the end of the stage.
    pub unbalanced_ratio: Option<f64>,
    pub splits: usize,
    pub rel_l2_displacement: Option<f64>,
    pub max_abs_displacement_error: Option<f64>,
    /// Largest displacement component of the implicit solution (the scale of the error above).
    pub max_abs_displacement: Option<f64>,
    pub rel_l2_nodal_stress: Option<f64>,
    pub wall_seconds_flem: f64,
    pub wall_seconds_implicit: f64,
    /// Both relative differences at most `[check] tolerance` (false when not computed).
    pub within_tolerance: bool,
    /// Why the implicit solve failed (e.g. a fragment without support, named).
    pub implicit_error: Option<String>,
    /// The comparison VTU, relative to the output folder.
    pub vtu: Option<String>,
    /// Whether the stage has an equilibrium to compare (module doc): false when FLEM is not at
    /// rest at its end (step limit; a dynamic stage), when a fragment has no support (the
    /// implicit problem is singular), or when the scene marks the stage `check = false`.
    /// Figures, when the implicit solve succeeded, are still given; `within_tolerance` is then
    /// not a verdict.
    #[serde(default)]
    pub comparable: bool,
    /// Why the stage is not comparable (every reason, "; "-separated).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// Statically determinate supports the implicit solve added to fragments without any and
    /// with self-equilibrated loads (`plugin::support`); the implicit displacement of such a
    /// fragment is shifted by the rigid motion that fits FLEM's best before the comparison.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub added_supports: Vec<AddedSupport>,
    /// A plastic stage (a block with a plastic law; `compare_plastic_stage`): the
    /// Gauss-point stress difference `|s_flem - s_imp|_2 / |s_imp|_2` (in place of the nodal
    /// one), the plastic-zone difference (elements yielded in one solution and not in the
    /// other, over those yielded in either) and what Newton did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rel_l2_point_stress: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plastic_zone_difference: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub newton: Option<crate::plugin::check::PlasticStage>,
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// `|a - b|_2 / |b|_2` over every component (`None` when `|b| = 0` and `a != b`, 0 when both 0).
pub fn rel_l2<const N: usize>(a: &[[f64; N]], b: &[[f64; N]]) -> Option<f64> {
    let (mut d, mut n) = (0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        for k in 0..N {
            d += (x[k] - y[k]) * (x[k] - y[k]);
            n += y[k] * y[k];
        }
    }
    if n == 0.0 {
        return if d == 0.0 { Some(0.0) } else { None };
    }
    finite((d / n).sqrt())
}

/// The stage just ended and its row with FLEM's side filled in (elastic and plastic stages).
fn stage_row(sim: &Simulation, stage: usize) -> (crate::solver::StageResult, StageComparison) {
    let st = sim.stages_done.last().cloned().unwrap_or_default();
    let c = StageComparison {
        stage,
        name: st.name.clone(),
        clusters: sim.model.topo.n_clusters(),
        dofs: sim.state.fix.iter().map(|&b| 2 - (b & 1) as usize - ((b >> 1) & 1) as usize).sum(),
        flem_steps: st.steps,
        flem_converged: st.converged,
        unbalanced_ratio: finite(st.final_ratio),
        splits: st.splits,
        wall_seconds_flem: st.wall_seconds,
        ..Default::default()
    };
    (st, c)
}

/// Why the stage just ended has no equilibrium to compare (empty: it has one), besides what
/// the implicit solve itself finds; `Err` holds the one reason that skips the solve (the scene
/// marks the stage `check = false`). Shared by elastic and plastic stages.
fn stage_reasons(sim: &Simulation, stage: usize, st: &crate::solver::StageResult) -> std::result::Result<Vec<String>, String> {
    let cfg = sim.scene.file.stages.get(stage);
    if cfg.is_some_and(|s| !s.check) {
        return Err(format!("the scene marks this stage as not checked (stage[{stage}].check = false)"));
    }
    let mut reasons = Vec::new();
    if cfg.is_some_and(|s| s.dynamic) {
        reasons.push("FLEM is not at rest: a dynamic stage (stage.dynamic = true) runs a fixed number of steps, not to equilibrium".to_string());
    } else if sim.scene.file.solver.kind == crate::scene::SolverKind::Events {
        // The events solver (ours): its state is a linear solve at the stage's levels only when
        // the stage ran to its end.
        let max = sim.scene.file.solver.max_events;
        if !st.converged {
            reasons
                .push(format!("the events solver stopped after {} events, before the end of the stage (the run's warning says why): its state is not an equilibrium at the stage's levels", st.steps));
        } else if st.steps >= max {
            reasons.push(format!("the events solver stopped at solver.max_events = {max}, before the end of the stage: its state is that of its last event, not an equilibrium at the stage's levels"));
        }
    } else if !st.converged {
        let tol = cfg.and_then(|s| s.tolerance).unwrap_or(sim.scene.file.solver.tolerance);
        reasons.push(format!(
            "FLEM is not at rest: the stage stopped after {} steps with the unbalanced-force ratio {:.3e}, above its tolerance {tol:.0e} (no equilibrium reached)",
            st.steps, st.final_ratio
        ));
    }
    Ok(reasons)
}

/// Runs the implicit solve on the simulation's current state and compares. Returns the entry
/// and, when the solve succeeded, the implicit displacement (rigidly aligned with FLEM's on
/// fragments given a statically determinate support) and nodal stress. `stage` indexes the
/// scene's stages.
pub fn compare_stage(sim: &Simulation, solver: &dyn CheckSolver, stage: usize, tolerance: f64) -> (StageComparison, Option<(Vec<[f64; 2]>, Vec<[f64; 3]>)>) {
    let (st, mut c) = stage_row(sim, stage);
    let mut reasons = match stage_reasons(sim, stage, &st) {
        Ok(r) => r,
        Err(why) => {
            c.reason = Some(why);
            return (c, None);
        }
    };
    // What the implicit check (linear, small strain, no contact) does not model.
    if sim.state.f_con.iter().any(|f| f[0] != 0.0 || f[1] != 0.0) {
        reasons.push("contact forces act at the end of the stage, and the implicit check models no contact".to_string());
    }
    let t0 = Instant::now();
    // Outer error: the solve failed; inner error: the supports refuse a fragment (plan).
    let solved = sim.external_force().and_then(|f| {
        let support::Plan { fix, mut added } = match support::plan(&sim.model, &sim.state.fix, &[f.as_slice()]) {
            Ok(p) => p,
            Err(e) => return Ok(Err(e)),
        };
        let u = solver.solve(&sim.model, &fix, &f, &sim.state.u)?;
        support::check_reactions(&sim.model, &mut added, &f, &u)?;
        Ok(Ok((u, added)))
    });
    c.wall_seconds_implicit = t0.elapsed().as_secs_f64();
    let done = |mut c: StageComparison, reasons: Vec<String>| {
        c.comparable = reasons.is_empty();
        c.reason = (!reasons.is_empty()).then(|| reasons.join("; "));
        c
    };
    let (mut u_imp, added) = match solved {
        Ok(Ok((u, added))) if u.iter().all(|v| v[0].is_finite() && v[1].is_finite()) => (u, added),
        Ok(Ok(_)) => {
            c.implicit_error = Some("the implicit solution is not finite".into());
            return (done(c, reasons), None);
        }
        Ok(Err(e)) => {
            // A fragment the implicit problem cannot hold: no equilibrium to compare.
            c.implicit_error = Some(e.to_string());
            reasons.push(format!("a fragment without support: {e}"));
            return (done(c, reasons), None);
        }
        Err(e) => {
            // A fragment named singular by the solve (a mechanism, e.g. two parts joined at one
            // cluster) has no equilibrium to compare either; any other error is a failure.
            let m = e.to_string();
            if m.ends_with(support::SINGULAR) {
                reasons.push(format!("a fragment without support or a mechanism: {m}"));
            }
            c.implicit_error = Some(m);
            return (done(c, reasons), None);
        }
    };
    support::align_rigid(&sim.model, &added, &sim.state.u, &mut u_imp);
    c.added_supports = added;
    let mut c = done(c, reasons);
    let (mut corner, mut s_flem, mut s_imp) = (Vec::new(), Vec::new(), Vec::new());
    sim.model.nodal_stress(&sim.state.u, &mut corner, &mut s_flem);
    sim.model.nodal_stress(&u_imp, &mut corner, &mut s_imp);
    c.rel_l2_displacement = rel_l2(&sim.state.u, &u_imp);
    c.rel_l2_nodal_stress = rel_l2(&s_flem, &s_imp);
    let max_err = sim.state.u.iter().zip(&u_imp).flat_map(|(a, b)| [(a[0] - b[0]).abs(), (a[1] - b[1]).abs()]).fold(0.0, f64::max);
    c.max_abs_displacement_error = finite(max_err);
    c.max_abs_displacement = finite(u_imp.iter().flat_map(|v| [v[0].abs(), v[1].abs()]).fold(0.0, f64::max));
    c.within_tolerance = matches!((c.rel_l2_displacement, c.rel_l2_nodal_stress), (Some(a), Some(b)) if a <= tolerance && b <= tolerance);
    (c, Some((u_imp, s_imp)))
}

/// True when some block of the model has a plastic law (the linear check does not apply).
pub fn is_plastic(sim: &Simulation) -> bool {
    sim.model.blocks.iter().any(|b| !b.is_empty() && b.plastic(0).is_some())
}

/// The comparison of a plastic stage with the implicit plastic check (ours, issue 37): Newton
/// advances its own solution, from its last converged state, to this stage's external force
/// and prescribed displacements in `increments` load increments
/// (`crate::plugin::check::PlasticCheck`), and the stage is compared as an elastic one is
/// (displacements), with the Gauss-point stress in place of the nodal stress (a stateful
/// block's nodal stress is its stored points') and the plastic zone: the elements with a
/// yielded point in FLEM (`Block::plastic`, state not 0) against those in the implicit
/// solution, as the fraction `|A xor B| / |A or B|` (0 when neither yielded). No VTU.
pub fn compare_plastic_stage(sim: &Simulation, check: &mut dyn crate::plugin::check::PlasticCheck, stage: usize, tolerance: f64, increments: usize) -> StageComparison {
    let (st, mut c) = stage_row(sim, stage);
    let reasons = match stage_reasons(sim, stage, &st) {
        Ok(r) => r,
        Err(why) => {
            c.reason = Some(why);
            return c;
        }
    };
    c.comparable = reasons.is_empty();
    c.reason = (!reasons.is_empty()).then(|| reasons.join("; "));
    if !c.comparable {
        // No equilibrium to compare: the Newton solve (a whole plastic solve, unlike the linear
        // one an elastic stage still gets for its figures) is skipped; the next stage's advance
        // starts from the last state it reached.
        return c;
    }
    let t0 = Instant::now();
    let r = sim.external_force().and_then(|f| check.advance(&sim.model, &sim.state.fix, &f, &sim.state.u, increments));
    c.wall_seconds_implicit = t0.elapsed().as_secs_f64();
    match r {
        Ok(st) => c.newton = Some(st),
        Err(e) => {
            c.implicit_error = Some(e.to_string());
            return c;
        }
    }
    let u_imp = check.displacement();
    c.rel_l2_displacement = rel_l2(&sim.state.u, u_imp);
    c.max_abs_displacement_error = finite(sim.state.u.iter().zip(u_imp).flat_map(|(a, b)| [(a[0] - b[0]).abs(), (a[1] - b[1]).abs()]).fold(0.0, f64::max));
    c.max_abs_displacement = finite(u_imp.iter().flat_map(|v| [v[0].abs(), v[1].abs()]).fold(0.0, f64::max));
    let (mut sf, mut si) = (Vec::new(), Vec::new());
    for (b, s_imp) in sim.model.blocks.iter().zip(check.point_stress()) {
        if let Some(s) = b.point_stress(&sim.state.u) {
            if s.len() == s_imp.len() {
                sf.extend(s);
                si.extend(s_imp);
            }
        }
    }
    c.rel_l2_point_stress = rel_l2(&sf, &si);
    let (mut either, mut differ) = (0usize, 0usize);
    for (b, y_imp) in sim.model.blocks.iter().zip(check.yielded()) {
        for (i, yi) in y_imp.into_iter().enumerate() {
            let yf = b.plastic(i).is_some_and(|(_, f)| f != 0);
            either += (yf || yi) as usize;
            differ += (yf != yi) as usize;
        }
    }
    c.plastic_zone_difference = Some(if either == 0 { 0.0 } else { differ as f64 / either as f64 });
    c.within_tolerance = matches!((c.rel_l2_displacement, c.rel_l2_point_stress), (Some(a), Some(b)) if a <= tolerance && b <= tolerance);
    c
}

/// The snapshot VTU of `sim` with the implicit fields and the differences added.
pub fn comparison_vtu(sim: &Simulation, u_imp: &[[f64; 2]], s_imp: &[[f64; 3]], compress: bool) -> Result<Vec<u8>> {
    let mut vtk = snapshot_vtk(sim);
    let (mut corner, mut s_flem) = (Vec::new(), Vec::new());
    sim.model.nodal_stress(&sim.state.u, &mut corner, &mut s_flem);
    let du: Vec<f64> = sim.state.u.iter().zip(u_imp).flat_map(|(a, b)| [a[0] - b[0], a[1] - b[1], 0.0]).collect();
    let ds: Vec<f64> = s_flem.iter().zip(s_imp).flat_map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]]).collect();
    let attrs = [
        Attribute::generic("displacement_implicit", 3).with_data(u_imp.iter().flat_map(|v| [v[0], v[1], 0.0]).collect::<Vec<f64>>()),
        Attribute::generic("nodal_stress_implicit", 3).with_data(s_imp.iter().flat_map(|s| *s).collect::<Vec<f64>>()),
        Attribute::generic("displacement_difference", 3).with_data(du),
        Attribute::generic("nodal_stress_difference", 3).with_data(ds),
    ];
    match &mut vtk.data {
        DataSet::UnstructuredGrid { pieces, .. } => match pieces.first_mut() {
            Some(Piece::Inline(p)) => p.data.point.extend(attrs),
            _ => return Err(FlemError::Other("comparison VTU: the snapshot has no inline piece".into())),
        },
        _ => return Err(FlemError::Other("comparison VTU: the snapshot is not an unstructured grid".into())),
    }
    vtu_bytes(vtk, compress)
}

/// The comparison table printed by `flem compare` and `flem run` with `[check]`.
pub fn table(rows: &[StageComparison]) -> String {
    let f = |v: Option<f64>| v.map(|x| format!("{x:.2e}")).unwrap_or_else(|| "-".into());
    let mut s = format!("{:<14} {:>8} {:>9} {:>10} {:>10} {:>10} {:>9} {:>9}  ok\n", "stage", "dofs", "ratio", "rel_l2_u", "max|du|", "rel_l2_s", "t_flem", "t_impl");
    for r in rows {
        let _ = writeln!(
            s,
            "{:<14} {:>8} {:>9} {:>10} {:>10} {:>10} {:>8.3}s {:>8.3}s  {}",
            r.name,
            r.dofs,
            f(r.unbalanced_ratio),
            f(r.rel_l2_displacement),
            f(r.max_abs_displacement_error),
            f(r.rel_l2_nodal_stress),
            r.wall_seconds_flem,
            r.wall_seconds_implicit,
            if !r.comparable {
                "n/c"
            } else if r.within_tolerance {
                "yes"
            } else {
                "NO"
            }
        );
        if let Some(n) = &r.newton {
            let _ = writeln!(
                s,
                "    plastic: rel_l2_point_stress {}, plastic-zone difference {}; Newton: {} increments, {} iterations, {} halvings, tangent {}, {}",
                f(r.rel_l2_point_stress),
                f(r.plastic_zone_difference),
                n.increments,
                n.iterations,
                n.bisections,
                n.tangent,
                n.factorisation
            );
        }
        for a in &r.added_supports {
            let _ = writeln!(s, "    support added: {}", a.note());
        }
        match (&r.reason, &r.implicit_error) {
            (Some(why), _) => {
                let _ = writeln!(s, "    not comparable: {why}");
                if let Some(e) = r.implicit_error.as_ref().filter(|e| !why.contains(e.as_str())) {
                    let _ = writeln!(s, "    implicit solve failed: {e}");
                }
            }
            (None, Some(e)) => {
                let _ = writeln!(s, "    implicit solve failed: {e}");
            }
            _ => {}
        }
    }
    s
}

/// An observer that forwards everything to `inner` and, at the end of every stage, runs the
/// comparison with the scene's `[check]` solver, writes the VTU and rewrites `compare.json`
/// in `dir`.
pub struct Comparer<'a> {
    inner: &'a mut dyn Observer,
    dir: PathBuf,
    pub rows: Vec<StageComparison>,
    /// Called with each new row (the CLI prints it).
    pub on_row: Option<Box<dyn FnMut(&StageComparison) + 'a>>,
    /// The implicit plastic check of a plastic model, kept from stage to stage (its own
    /// history); made at the first plastic stage from the check solver.
    plastic: Option<Box<dyn crate::plugin::check::PlasticCheck>>,
}

impl<'a> Comparer<'a> {
    /// `dir` is created if needed (an unwritable folder fails here, before any step).
    pub fn new(inner: &'a mut dyn Observer, dir: &Path) -> Result<Self> {
        prepare_dir(dir)?;
        Ok(Comparer { inner, dir: dir.to_path_buf(), rows: Vec::new(), on_row: None, plastic: None })
    }

    fn write_json(&self, sim: &Simulation) -> Result<()> {
        let tol = sim.scene.file.check.as_ref().map_or(crate::plugin::check::default_tol(), |c| c.tolerance);
        let v = serde_json::json!({
            "scene": sim.scene.path.display().to_string(),
            "title": sim.scene.file.title,
            "solver": sim.scene.file.check.as_ref().and_then(|c| c.solver.as_ref()).and_then(|s| serde_json::to_value(s).ok()),
            "tolerance": tol,
            "stages": self.rows,
        });
        atomic_write(&self.dir.join("compare.json"), serde_json::to_string_pretty(&v).unwrap_or_default().as_bytes())
    }
}

impl Observer for Comparer<'_> {
    fn history(&mut self, sim: &Simulation, stage: usize) -> Result<()> {
        self.inner.history(sim, stage)
    }
    fn snapshot(&mut self, sim: &Simulation, stage: usize, label: &str) -> Result<()> {
        self.inner.snapshot(sim, stage, label)
    }
    fn splits(&mut self, sim: &Simulation, rec: &SplitRecord, events: &[SplitEvent]) -> Result<()> {
        self.inner.splits(sim, rec, events)
    }
    fn progress(&mut self, p: &Progress) {
        self.inner.progress(p)
    }
    fn should_stop(&mut self, sim: &Simulation) -> bool {
        self.inner.should_stop(sim)
    }
    fn checkpoint_due(&mut self, sim: &Simulation) -> bool {
        self.inner.checkpoint_due(sim)
    }
    fn checkpoint(&mut self, sim: &Simulation, pos: &crate::solver::StagePos) -> Result<()> {
        self.inner.checkpoint(sim, pos)
    }
    fn stage_end(&mut self, sim: &Simulation, stage: usize) -> Result<()> {
        self.inner.stage_end(sim, stage)?;
        let file = sim.scene.path.display().to_string();
        let cfg = sim.scene.file.check.as_ref().ok_or_else(|| FlemError::config(&file, "check", "is missing: the comparison needs a [check] section"))?;
        if is_plastic(sim) {
            if self.plastic.is_none() {
                self.plastic = cfg.solver().plastic();
            }
            let mut row = match self.plastic.as_mut() {
                Some(p) => compare_plastic_stage(sim, p.as_mut(), stage, cfg.tolerance, cfg.increments),
                None => {
                    let (mut row, _) = compare_stage(sim, cfg.solver(), stage, cfg.tolerance);
                    row.implicit_error =
                        Some("a plastic stage: this check solver has no implicit plastic check (CheckSolver::plastic), and its linear solve is no equilibrium of the plastic model".into());
                    row.within_tolerance = false;
                    row
                }
            };
            row.vtu = None;
            if let Some(f) = self.on_row.as_mut() {
                f(&row);
            }
            self.rows.push(row);
            return self.write_json(sim);
        }
        let (mut row, fields) = compare_stage(sim, cfg.solver(), stage, cfg.tolerance);
        if let (Some((u, s)), true) = (fields, cfg.vtu) {
            let name = format!("compare_{stage:04}_{}.vtu", sanitize(&row.name));
            let bytes = comparison_vtu(sim, &u, &s, sim.scene.file.output.compress)?;
            atomic_write(&self.dir.join(&name), &bytes)?;
            row.vtu = Some(name);
        }
        if let Some(f) = self.on_row.as_mut() {
            f(&row);
        }
        self.rows.push(row);
        self.write_json(sim)
    }
}

/// A stage name usable in a file name.
fn sanitize(s: &str) -> String {
    s.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect()
}
