//! The paper's two scenes (issue 8; Nishimura et al., section 4; METHOD section 9):
//! configs/paper/opening.toml (side notch, uniaxial tension, tension check only) and
//! configs/paper/direct_shear.toml (21 quads + 1 triangle, bc pre-separated, q then p, shear
//! check only), each also on a finer mesh. The measured numbers are printed (`--nocapture`)
//! and collected in docs/paper.md.
use flem_core::ids::EdgeId;
use flem_core::plugin::traits::principal;
use flem_core::solver::Simulation;

use crate::common::{rel, root};

/// rho g of Table 1 (g/cm^3 x cm/s^2): the load value per unit level in the configs.
const RHO_G: f64 = 2.65 * 980.0;
/// Table 1 strengths, dyn/cm^2.
const SIGMA_T: f64 = 980665.0;
const COHESION: f64 = 98066.5;

fn config(name: &str) -> String {
    std::fs::read_to_string(root().join("configs/paper").join(name)).unwrap()
}

/// The config with its stages replaced by `stages` (TOML `[[stage]]` blocks).
fn with_stages(text: &str, stages: &str) -> String {
    let a = text.find("[[stage]]").expect("a stage");
    let b = text.find("[output]").unwrap_or(text.len());
    format!("{}{stages}\n{}", &text[..a], &text[b..])
}

/// Paper-relative sim: configs/paper/ is the base folder of the mesh files.
fn paper_sim(text: &str) -> Simulation {
    flem_plugins::link();
    let s = flem_core::scene::Scene::from_str(text, std::path::Path::new("<paper test>"), &root().join("configs/paper")).unwrap_or_else(|e| panic!("{e}"));
    Simulation::new(s).unwrap_or_else(|e| panic!("{e}"))
}

/// Largest tension (tension positive) of the nodal stress of every cluster for displacement u.
fn nodal_tension(sim: &Simulation, u: &[[f64; 2]]) -> Vec<f64> {
    let (mut corner, mut nodal) = (Vec::new(), Vec::new());
    sim.model.nodal_stress(u, &mut corner, &mut nodal);
    nodal.iter().map(|s| -principal(*s, 0.0).s3).collect()
}

/// p_crit / (rho g) of an opening config: the load level at which the elastic nodal stress at
/// the notch tip reaches sigma_t, from a linear static solve (the faer check solver, METHOD 10)
/// at unit level, by linearity. Also returns the largest nodal tension anywhere at unit level.
pub fn opening_p_crit(text: &str) -> (f64, f64, f64) {
    let mut sim = paper_sim(text);
    let k = sim.loads.loads.iter().position(|l| l.name == "p").unwrap();
    sim.levels[k] = 1.0;
    let u = flem_plugins::check::static_solve(&sim).unwrap();
    let t = nodal_tension(&sim, &u);
    let tip = sim.model.mesh.node_sets["notch_tip"][0] as usize;
    let tip_c = sim.model.topo.point_clusters[tip][0].idx();
    let tmax = t.iter().copied().fold(f64::MIN, f64::max);
    (SIGMA_T / t[tip_c], t[tip_c], tmax)
}

/// Runs an opening config at 0.95 and 1.05 p_crit; returns (splits at 0.95, splits at 1.05,
/// first split point, fragments at the end, cut edges).
fn opening_runs(text: &str, p_crit: f64) -> (usize, usize, usize, usize, Vec<EdgeId>, Simulation) {
    let st = format!("[[stage]]\nname = \"below\"\nlevels = {{ p = {} }}\n\n[[stage]]\nname = \"above\"\nlevels = {{ p = {} }}\nmax_steps = 20000\n", 0.95 * p_crit, 1.05 * p_crit);
    let mut sim = paper_sim(&with_stages(text, &st));
    let mut log = SplitLog::default();
    sim.run_stage(0, &mut log).unwrap();
    let below = log.events.len();
    sim.run_stage(1, &mut log).unwrap();
    let above = log.events.len() - below;
    let first = log.events.first().map(|e| e.point.idx()).unwrap_or(usize::MAX);
    let (_, nfrag) = sim.model.topo.fragments();
    let path = &log.events[..log.separated_at.unwrap_or(log.events.len())];
    let edges = path.iter().flat_map(|e| e.edges.clone()).collect();
    (below, above, first, nfrag, edges, sim)
}

#[derive(Default)]
struct SplitLog {
    events: Vec<flem_core::cracking::SplitEvent>,
    /// Number of events when the body first fell in two (after that the freed half is a
    /// mechanism under load control, and its motion may crack the rest: not the crack path).
    separated_at: Option<usize>,
}
impl flem_core::solver::Observer for SplitLog {
    fn splits(&mut self, s: &Simulation, _r: &flem_core::mesh::topology::SplitRecord, ev: &[flem_core::cracking::SplitEvent]) -> flem_core::Result<()> {
        self.events.extend(ev.iter().cloned());
        if self.separated_at.is_none() && s.model.topo.fragments().1 >= 2 {
            self.separated_at = Some(self.events.len());
        }
        Ok(())
    }
}

fn check_opening(file: &str) -> f64 {
    let text = config(file);
    let (p_crit, tip_unit, tmax) = opening_p_crit(&text);
    println!("{file}: p_crit/(rho g) = {:.2} (tip tension at unit level {:.4} = {:.3} x the nominal rho g; paper: no crack at 110, crack at 115)", p_crit / 1.0, tip_unit, tip_unit / RHO_G);
    // The notch tip carries the largest nodal tension (reference: the notch concentrates stress).
    assert!(rel(tip_unit, tmax) < 1e-9, "{file}: the largest nodal tension {tmax} is not at the notch tip ({tip_unit})");
    let (below, above, first, nfrag, edges, sim) = opening_runs(&text, p_crit);
    let tip = sim.model.mesh.node_sets["notch_tip"][0] as usize;
    println!("{file}: splits at 0.95 p_crit: {below}; at 1.05 p_crit: {above} (first at point {first}, tip {tip}), fragments {nfrag}");
    assert_eq!(below, 0, "{file}: a split below p_crit");
    assert!(above > 0, "{file}: no crack above p_crit");
    assert_eq!(first, tip, "{file}: the first split is not at the notch tip");
    // Through the ligament: every edge of the notch line from the tip to the far side is
    // separated (at both ends but possibly the far side's last point: once a single point holds
    // the two halves, the upper one turns about it and never comes to equilibrium; the stall
    // checks, `cracking.stall_steps`, then usually split it), and every edge cut until the
    // plate falls in two lies on the notch line y = 3 (the crack runs straight across).
    let topo = &sim.model.topo;
    let pts = &sim.model.mesh.points;
    let lig: Vec<usize> = (0..topo.edges.len())
        .filter(|&e| {
            let q = topo.edges[e].points;
            let (a, b) = (pts[q[0].idx()], pts[q[1].idx()]);
            (a[1] - 3.0).abs() < 1e-9 && (b[1] - 3.0).abs() < 1e-9 && a[0].min(b[0]) > 2.0 - 1e-9
        })
        .collect();
    let states: Vec<u8> = lig.iter().map(|&e| topo.crack_state(EdgeId::new(e))).collect();
    let open = states.iter().filter(|&&s| s == 2).count();
    println!("{file}: ligament edges {}: open at both ends {open}, all cracked: {}; fragments {nfrag}", lig.len(), states.iter().all(|&s| s >= 1));
    assert!(states.iter().all(|&s| s >= 1) && open + 1 >= lig.len(), "{file}: the crack did not run through the ligament: {states:?}");
    let ymax_dev = edges
        .iter()
        .map(|e| {
            let p = topo.edges[e.idx()].points;
            let (a, b) = (pts[p[0].idx()], pts[p[1].idx()]);
            (a[1] - 3.0).abs().max((b[1] - 3.0).abs())
        })
        .fold(0.0, f64::max);
    assert!(ymax_dev < 1e-9, "{file}: the crack left the notch line by {ymax_dev}");
    p_crit
}

/// Opening model, 36 quads (configs/paper/opening.toml). Reference: p_crit from a linear static
/// solve at unit load (linearity); criterion sigma_t (Table 1). No split at 0.95 p_crit (5 %
/// margin: FLEM's equilibrium at tolerance 1e-5 agrees with the static solve far closer), a
/// crack starting at the notch tip and running along the notch line through the ligament at
/// 1.05 p_crit. The paper: no crack at p/(rho g) = 110, a crack at 115.
#[test]
fn paper_opening_cracks_between_095_and_105_p_crit() {
    let p = check_opening("opening.toml");
    // The config's own stages bracket p_crit the same way (0.95 and 1.05, rounded to 0.1).
    let t = config("opening.toml");
    let lv: Vec<f64> = t.match_indices("levels = { p = ").map(|(i, _)| t[i + 15..].split(' ').next().unwrap().parse().unwrap()).collect();
    assert!(lv.len() == 2 && rel(lv[0], 0.95 * p) < 2e-3 && rel(lv[1], 1.05 * p) < 2e-3, "opening.toml stages {lv:?} are not 0.95/1.05 x p_crit = {p}");
}

/// Same on the finer mesh (configs/paper/opening_fine.toml, each cell split 2 x 2).
#[test]
fn paper_opening_fine_cracks_between_095_and_105_p_crit() {
    check_opening("opening_fine.toml");
}

/// One row per p stage of a direct shear run: (p/(rho g), stage in equilibrium, cd edges open at
/// both ends, cd edges cracked at one end or more, crack faces off the plane y = 4, splits so far).
type ShearRow = (f64, bool, usize, usize, usize, usize, f64, usize);

/// Direct shear: q alone, then p in steps until cd is open along its whole length or a stage
/// ends out of equilibrium (`to_the_end`: every stage); the state of the plane cd after every
/// stage. Returns (splits under q, number of cd edges, rows, energy residual, split events).
fn direct_shear(file: &str, to_the_end: bool) -> (usize, usize, Vec<ShearRow>, f64, Vec<flem_core::cracking::SplitEvent>) {
    let mut sim = paper_sim(&config(file));
    let cd = sim.model.edge_set("cd", "cd", file).unwrap();
    let kp = sim.loads.loads.iter().position(|l| l.name == "p").unwrap();
    let mut log = SplitLog::default();
    sim.run_stage(0, &mut log).unwrap();
    let under_q = log.events.len();
    let mut rows = Vec::new();
    for i in 1..sim.scene.file.stages.len() {
        sim.run_stage(i, &mut log).unwrap();
        let topo = &sim.model.topo;
        let pts = &sim.model.mesh.points;
        let open = cd.iter().filter(|e| topo.crack_state(**e) == 2).count();
        let cracked = cd.iter().filter(|e| topo.crack_state(**e) >= 1).count();
        let off = (0..topo.edges.len())
            .filter(|&e| topo.crack_state(EdgeId::new(e)) > 0)
            .filter(|&e| {
                let q = topo.edges[e].points;
                (pts[q[0].idx()][1] - 4.0).abs() > 1e-6 || (pts[q[1].idx()][1] - 4.0).abs() > 1e-6
            })
            .count();
        // Points beyond the criterion at the stage's last check that no rule split (an open fan
        // whose joined edges lie more than 45 deg from sigma1 is not cut): they carry stress
        // above their strength, the method has no plasticity.
        let beyond = sim.cracking.as_ref().map_or(0, |c| c.beyond_criterion());
        let row = (sim.levels[kp], sim.stages_done[i].converged, open, cracked, off, log.events.len(), sim.ledger.relative_residual(), beyond);
        println!(
            "{file}: p/(rho g) = {:5.0}: in equilibrium {:5}, cd edges open {}/{} (cracked {}), crack faces off the plane {}, splits {}, energy residual {:.1e}, points beyond the criterion {beyond}",
            row.0,
            row.1,
            row.2,
            cd.len(),
            row.3,
            row.4,
            row.5,
            row.6
        );
        rows.push(row);
        if !to_the_end && (open == cd.len() || !row.1) {
            break;
        }
    }
    (under_q, cd.len(), rows, sim.ledger.relative_residual(), log.events)
}

/// Direct shear with contact (the paper's spring_dashpot law, Table 1) on the coarse mesh
/// (configs/paper/direct_shear.toml: 21 quads + 1 triangle) and the fine one, each with the
/// paper's sigma1-nearest rule and with the coulomb_traction variant.
/// References (statics of the upper block, bc pre-separated carries nothing, side ab from
/// (2,4) to (4,8), q = 100 rho g on the top, 8 cm):
/// (1) under q alone nothing fails: near uniaxial compression q below the uniaxial compressive
///     strength 2 c cos(phi)/(1 - sin(phi)) = 130.8 rho g (METHOD 4);
/// (2) cd as a rigid-block slip plane with cohesion: p_lim = 8 (c + q tan(phi)) /
///     (4 - 2 tan(phi)) = 268.5 rho g; the first split comes below it (elastic stress
///     concentrations at b and along cd);
/// (3) cd with friction only (mu = tan(phi), c lost): p_f = 8 q tan(phi) / (4 - 2 tan(phi)) =
///     162.3 rho g: on the coarse mesh, with contact, the block holds at every stage up to p_f;
/// (4) energy balance (central differences with the paper's contact law and co-rotational
///     elements): relative residual below 1e-2 at every stage (measured: at most 1.6e-4 coarse,
///     8.6e-6 fine, since session 5's slip dissipation; 1.3e-3 / 1.2e-4 in session 4; 0.23-0.98 before its contact fix).
/// Not asserted, measured (docs/paper.md): the coarse block "holds" to p = 400 = 1.49 p_lim,
/// beyond the 321.6 of shearing the whole specimen over y = 2, with 28 points beyond the
/// criterion that no rule splits (open fans whose joined edges lie more than 45 deg from
/// sigma1): the method has no plasticity, such points carry stress above their strength. The
/// held row is clamped point by point, so the y = 2 mechanism is not open to the model anyway.
/// Measured and asserted as measured: the paper's separation along cd (fig. 8) is NOT
/// reproduced; when equilibrium is lost, cd is not open along its whole length (the points on
/// cd fail with sigma1 steeper than 45 deg and cut vertical edges; on these structured fans
/// coulomb_traction picks the same edges as sigma1_nearest). docs/paper.md has the table.
#[test]
fn paper_direct_shear_with_contact_does_not_open_cd() {
    let tphi = 30f64.to_radians().tan();
    let (q, c) = (100.0 * RHO_G, COHESION);
    let p_lim = 8.0 * (c + q * tphi) / (4.0 - 2.0 * tphi) / RHO_G;
    let p_f = 8.0 * q * tphi / (4.0 - 2.0 * tphi) / RHO_G;
    let p_y2 = (12.0 * c + 8.0 * q * tphi) / (4.0 - 2.0 * tphi) / RHO_G;
    assert!((p_lim - 268.5).abs() < 0.1 && (p_f - 162.3).abs() < 0.1 && (p_y2 - 321.6).abs() < 0.1, "{p_lim} {p_f} {p_y2}");
    for file in ["direct_shear.toml", "direct_shear_coulomb.toml", "direct_shear_fine.toml", "direct_shear_fine_coulomb.toml"] {
        let (under_q, n_cd, rows, residual, _) = direct_shear(file, false);
        assert_eq!(under_q, 0, "{file}: splits under q alone");
        let first = rows.iter().find(|r| r.5 > 0).unwrap_or_else(|| panic!("{file}: nothing failed up to p = {}", rows.last().unwrap().0));
        let end = rows.last().unwrap();
        let last_eq = rows.iter().take_while(|r| r.1).last().map_or(0.0, |r| r.0);
        println!("{file}: first split at p/(rho g) = {} ({:.3} p_lim); last equilibrium {last_eq} ({:.3} p_lim); equilibrium lost at {} ({:.3} p_lim); cd open at both ends {}/{n_cd}, cracked {}; p_lim = {p_lim:.1}, p_f = {p_f:.1}, p_y2 = {p_y2:.1}", first.0, first.0 / p_lim, last_eq / p_lim, end.0, end.0 / p_lim, end.2, end.3);
        assert!(first.0 < p_lim, "{file}: first split at {} above the limit {p_lim:.1}", first.0);
        assert!(!end.1, "{file}: the block still holds at p = {}", end.0);
        println!("{file}: energy residual at the end {residual:.2e}");
        for r in &rows {
            assert!(r.6 < 1e-2, "{file}: energy residual {} at p = {}", r.6, r.0);
            // Statics of the upper block: with |t| <= c + s_n tan(phi) on cd (implied by the
            // criterion at its points) and friction mu = tan(phi) on bc, its horizontal hold is
            // at most 8 c + (8 q + 2 p) tan(phi), i.e. p <= p_lim. An equilibrium past p_lim
            // therefore needs points beyond the criterion (the nodal stress approximates this).
            if r.1 && r.0 > p_lim {
                assert!(r.7 > 0, "{file}: in equilibrium at p = {} > p_lim = {p_lim:.1} with every point within the criterion", r.0);
            }
        }
        if !file.contains("fine") {
            assert!(last_eq >= p_f, "{file}: equilibrium lost at {} below the frictional limit {p_f:.1}", end.0);
        }
        assert!(end.2 < n_cd, "{file}: cd is open along its whole length at p = {}: the paper's result is reproduced now, update docs/paper.md", end.0);
    }
}

/// Direct shear with a stop at the upper block's right end (configs/paper/direct_shear_stop.toml:
/// direct_shear.toml plus `upper_right` held in x). The paper's figure 8 shows equilibria at
/// p/(rho g) = 894 and 2235 with cd separated; without a stop no equilibrium exists above
/// p_lim = 268.5 (statics, see the test above), so the paper's model must have carried p
/// elsewhere. References:
/// (1) statics: with the stop the upper block is held at every stage, including the paper's
///     894 and 2235 (3.3 and 8.3 p_lim);
/// (2) the paper's figure 8 (b): cd open along its whole length at p = 2235;
/// (3) the separation rule (METHOD 5): a cd edge is cut at a point only when sigma1 there lies
///     within 45 deg of cd, i.e. (exact, from tan 2 theta = 2 t / (sxx - syy)) when the
///     horizontal compression exceeds the vertical one: checked on the stress of every split
///     that cut a cd edge;
/// (4) energy balance: relative residual below 1e-2 (measured at most 8.7e-4, at p = 894).
/// Measured, not asserted (docs/paper.md): the rest of the specimen is not intact (the lower
/// specimen row cracks vertically from p = 360, the upper block along y = 6 at 894).
#[test]
fn paper_direct_shear_with_a_stop_separates_cd() {
    let file = "direct_shear_stop.toml";
    let (under_q, n_cd, rows, residual, events) = direct_shear(file, true);
    assert_eq!(under_q, 0, "{file}: splits under q alone");
    for r in &rows {
        assert!(r.1, "{file}: not in equilibrium at p = {} with the stop", r.0);
    }
    let at = |p: f64| rows.iter().find(|r| (r.0 - p).abs() < 1e-9).unwrap_or_else(|| panic!("{file}: no stage at p = {p}"));
    let full = rows.iter().find(|r| r.2 == n_cd).unwrap_or_else(|| panic!("{file}: cd never open along its whole length"));
    // The ratio: the push of p on ab (4 p per unit thickness, horizontal) against what cd
    // can carry, (c + sigma_n tan(phi)) x 8 cm with sigma_n = (8 q + 2 p) / 8; above 1 the stop
    // carries the rest.
    let tphi = 30f64.to_radians().tan();
    let ratio = |p: f64| 4.0 * p * RHO_G / ((COHESION + (8.0 * 100.0 + 2.0 * p) / 8.0 * RHO_G * tphi) * 8.0);
    println!("{file}: cd open at both ends of all {n_cd} edges from p/(rho g) = {} ({:.2} p_lim; 4 p / ((c + sigma_n tan phi) x 8 cm) = {:.2}); at 894: {}/{n_cd}, at 2235: {}/{n_cd}; crack faces off cd at 2235: {}; energy residual {residual:.2e}", full.0, full.0 / 268.5, ratio(full.0), at(894.0).2, at(2235.0).2, at(2235.0).4);
    assert!((ratio(268.5) - 1.0).abs() < 1e-3, "the ratio is 1 at p_lim: {}", ratio(268.5));
    assert_eq!(at(2235.0).2, n_cd, "{file}: cd not open along its whole length at the paper's p = 2235");
    let sim = paper_sim(&config(file));
    let cd = sim.model.edge_set("cd", "cd", file).unwrap();
    let mut cd_cuts = 0;
    for ev in events.iter().filter(|ev| ev.edges.iter().any(|e| cd.contains(e))) {
        // compression positive: -sxx > -syy
        assert!(-ev.stress[0] > -ev.stress[1], "{file}: cd cut at point {} with sxx {} syy {} (sigma1 at {:.1} deg)", ev.point.0, ev.stress[0], ev.stress[1], ev.sigma1_deg);
        cd_cuts += 1;
    }
    assert!(cd_cuts >= n_cd, "{file}: {cd_cuts} cd cuts");
    assert!(residual < 1e-2, "{file}: energy residual {residual}");
}

/// `flem plot` on a finished run of the opening model: one PNG + SVG per snapshot, the crack
/// sequence (four panels) and the load-displacement curve; every PNG decodes as a PNG with
/// non-white pixels and every SVG is an SVG document with the bundled font's text.
/// Reference: the files' own formats (PNG signature, `<svg`), and the snapshot count of
/// results.pvd.
#[test]
fn paper_plot_writes_frames_sequence_and_curve() {
    let dir = std::env::temp_dir().join(format!("flem_paper_plot_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut sim = paper_sim(&config("opening.toml"));
    let mut w = flem_core::output::OutputWriter::new(&dir, &sim).unwrap();
    sim.run(&mut w).unwrap();
    w.write_summary(&sim, 0.0).unwrap();
    let rep = flem_plot::plot_run(&dir).unwrap();
    let n_snap = flem_plot::run::snapshot_list(&dir).unwrap().len();
    assert!(n_snap >= 4, "one snapshot per stage and per split: {n_snap}");
    assert_eq!(rep.files.len(), 2 * (n_snap + 2), "{:?}", rep.files);
    assert_eq!(rep.sequence.len(), 4);
    for f in &rep.files {
        let b = std::fs::read(f).unwrap();
        if f.extension().unwrap() == "png" {
            assert_eq!(&b[..8], b"\x89PNG\r\n\x1a\n", "{}", f.display());
            let dec = png::Decoder::new(std::io::Cursor::new(&b));
            let mut r = dec.read_info().unwrap();
            let mut px = vec![0u8; r.output_buffer_size()];
            r.next_frame(&mut px).unwrap();
            assert!(px.iter().any(|&v| v < 128), "{}: blank picture", f.display());
        } else {
            let s = String::from_utf8(b).unwrap();
            assert!(s.contains("<svg") && s.contains("load levels") || s.contains("level of load"), "{}", f.display());
        }
    }
    assert!(rep.notes.is_empty(), "{:?}", rep.notes);
    // The same folder damaged (reference: the error contract, FILE:LINE and what): a row with a
    // missing column, a field that is not a number, a cut summary.json are refused before any
    // picture is drawn; a last line cut by a kill and a missing summary.json are drawn up to
    // what is whole and reported in the notes.
    let (hist, summary) = (dir.join("history.csv"), dir.join("summary.json"));
    let (good, sum) = (std::fs::read_to_string(&hist).unwrap(), std::fs::read_to_string(&summary).unwrap());
    let n = good.lines().count();
    let last = good.lines().last().unwrap();
    let short = last.rsplit_once(',').unwrap().0;
    std::fs::remove_dir_all(dir.join("plots")).unwrap();
    for (text, want) in [(format!("{good}{short}\n"), format!("history.csv:{}: ", n + 1)), (good.replacen(last, &last.replacen(',', ",x", 1), 1), format!("history.csv:{n}: column \"time\" = \"x"))] {
        std::fs::write(&hist, &text).unwrap();
        let e = flem_plot::plot_run(&dir).unwrap_err().to_string();
        assert!(e.contains(&want), "{want}: {e}");
        assert!(!dir.join("plots").exists(), "a picture was drawn from a damaged log");
    }
    std::fs::write(&hist, &good).unwrap();
    std::fs::write(&summary, &sum[..sum.len() / 2]).unwrap();
    let e = flem_plot::plot_run(&dir).unwrap_err().to_string();
    assert!(e.contains("summary.json:") && e.contains("cut short"), "{e}");
    std::fs::remove_file(&summary).unwrap();
    std::fs::write(&hist, format!("{good}{short}")).unwrap();
    let rep = flem_plot::plot_run(&dir).unwrap();
    assert!(rep.notes.iter().any(|m| m.contains(&format!("history.csv:{}: the last line is cut", n + 1))), "{:?}", rep.notes);
    assert!(rep.notes.iter().any(|m| m.contains("summary.json is missing")), "{:?}", rep.notes);
    // A run stopped before its first history row (Ctrl-C: the summary writes the header only),
    // or with its only row cut: frames drawn, no curve, a note (it panicked in session 5's review).
    let header = good.lines().next().unwrap();
    for text in [format!("{header}\n"), format!("{header}\n{short}")] {
        std::fs::write(&hist, &text).unwrap();
        let rep = flem_plot::plot_run(&dir).unwrap();
        assert!(rep.notes.iter().any(|m| m.contains("has no rows: no load-displacement curve")), "{:?}", rep.notes);
        assert!(!rep.files.iter().any(|f| f.to_string_lossy().contains("load_displacement")), "{:?}", rep.files);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `flem plot` on a folder that is not a run: a clear error naming results.pvd, no picture and
/// no plots/ folder written. Reference: the error contract (HELPERS: bad input names the file).
#[test]
fn paper_plot_refuses_a_folder_without_results() {
    let dir = std::env::temp_dir().join(format!("flem_paper_noplot_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let e = flem_plot::plot_run(&dir).unwrap_err().to_string();
    assert!(e.contains("results.pvd") && e.contains("run folder"), "{e}");
    assert!(!dir.join("plots").exists());
    let _ = std::fs::remove_dir_all(&dir);
}
