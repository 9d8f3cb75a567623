//! Element kinds (issue 20): the patch test of every registered kind on distorted meshes, the
//! implicit check against the explicit equilibrium with `qm6`, Cook's membrane and the
//! cantilever of the speed-accuracy chart. References and tolerances at each test.
use flem_core::element::registry;
use flem_core::solver::Simulation;
use flem_plugins::check::ImplicitSolver;

use crate::common::{root, sim};

/// (element, mesh cell type) of every element kind that the test binary links.
fn kinds() -> Vec<(&'static str, &'static str)> {
    flem_plugins::link();
    registry::kinds().iter().map(|k| (k.name, if k.cell == flem_core::mesh::CellKind::Q4 { "q4" } else { "t3" })).collect()
}

/// The linear field `u = c + A x` of the patch test (constant strain exx, eyy, gxy + a rotation).
const EPS: [f64; 3] = [1.0e-3, -4.0e-4, 6.0e-4];
fn u_lin(x: [f64; 2]) -> [f64; 2] {
    let w = 2.0e-4;
    [1e-3 + EPS[0] * x[0] + (0.5 * EPS[2] - w) * x[1], -2e-3 + (0.5 * EPS[2] + w) * x[0] + EPS[1] * x[1]]
}

/// The patch test (Taylor, Beresford & Wilson 1976; Zienkiewicz & Taylor, The Finite Element
/// Method vol. 1, ch. 10) for every element kind, plane strain and plane stress, on a 6 x 5
/// rectangle mesh whose interior points are moved by up to 0.25 of a cell (distorted
/// quadrilaterals; triangles: each quad split in two), and on the same mesh undistorted
/// (rectangles: the parallelogram packs of `q4`, `q4_closed`; a linear field has no hourglass
/// part, so there the test checks the centre term of `q4_closed`'s closed form only). Reference: the exact linear field and
/// its constant stress `D eps`. Tolerance 1e-12 relative for
/// (A) the internal force at every interior node under the exact nodal values (zero),
/// (B) the stress at every corner point (0.9999 corners: the nodal-stress rule) and
/// (C) the interior displacements solved by the implicit solver with the exact field
///     prescribed on the boundary.
#[test]
fn patch_test_of_every_element_kind_on_rectangles_and_distorted_meshes() {
    let ks = kinds();
    assert!(ks.iter().any(|k| k.0 == "qm6") && ks.iter().any(|k| k.0 == "q4") && ks.iter().any(|k| k.0 == "t3"), "{ks:?}");
    for (elem, cell) in ks {
        for (plane, distort) in [("strain", 0.25), ("stress", 0.25), ("strain", 0.0), ("stress", 0.0)] {
            let text = format!(
                "[mesh]\ntype = \"rectangle\"\nwidth = 2.0\nheight = 1.5\nnx = 6\nny = 5\nelement = \"{cell}\"\ndistort = {distort}\n[model]\nplane = \"{plane}\"\n[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\nthickness = 0.7\nelement = \"{elem}\"\n[[support]]\nnodes = \"left\"\nfix = \"xy\"\n[[stage]]\nlevels = {{}}\n"
            );
            let s = sim(&text);
            let m = &s.model;
            assert!(m.blocks.iter().all(|b| b.element() == elem), "{elem}: blocks {:?}", m.blocks.iter().map(|b| b.element()).collect::<Vec<_>>());
            let x0 = m.cluster_x0();
            let u: Vec<[f64; 2]> = x0.iter().map(|&x| u_lin(x)).collect();
            let mut boundary = vec![false; x0.len()];
            for set in ["left", "right", "top", "bottom"] {
                for p in m.node_set(set, "test", "test").unwrap() {
                    boundary[p.idx()] = true;
                }
            }
            assert!(boundary.iter().filter(|b| !**b).count() >= 20, "interior nodes");
            // (A)
            let mut f = vec![[0.0; 2]; x0.len()];
            m.internal_forces(&u, &mut f);
            let fscale = f.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
            for (c, fc) in f.iter().enumerate().filter(|(c, _)| !boundary[*c]) {
                assert!(fc[0].abs() <= 1e-12 * fscale && fc[1].abs() <= 1e-12 * fscale, "{elem} {plane}: interior force at cluster {c}: {fc:?} (scale {fscale})");
            }
            // (B)
            let want = m.material_of(flem_core::ids::ElemId(0)).dmat().stress(EPS);
            let sscale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let mut corner = Vec::new();
            m.corner_stresses(&u, &mut corner);
            for (k, sk) in corner.iter().enumerate() {
                for d in 0..3 {
                    assert!((sk[d] - want[d]).abs() <= 1e-12 * sscale, "{elem} {plane}: copy {k}: {sk:?} vs {want:?}");
                }
            }
            // (C)
            let fix: Vec<u8> = boundary.iter().map(|&b| if b { 3 } else { 0 }).collect();
            let zero = vec![[0.0; 2]; x0.len()];
            let sol = ImplicitSolver::default().solve(m, &fix, &zero, &u).unwrap();
            let uscale = u.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
            for c in 0..x0.len() {
                for d in 0..2 {
                    assert!((sol[c][d] - u[c][d]).abs() <= 1e-12 * uscale, "{elem} {plane}: solved u at cluster {c}: {:?} vs {:?}", sol[c], u[c]);
                }
            }
        }
    }
}

/// Tip deflection `u_y(48, 52)` (the middle of the loaded edge) of Cook's membrane (configs/verification/cook.toml, meshes from
/// configs/meshes/cook.geo) with `element` on `n` x `n` cells, by the implicit solver (the
/// same element stiffness as the explicit step: `implicit_check_equals_explicit_equilibrium_with_qm6`).
fn cook_tip(elem: &str, n: usize) -> f64 {
    let base = std::fs::read_to_string(root().join("configs/verification/cook.toml")).unwrap();
    let mesh = if elem == "t3" { format!("meshes/cook_{n}_t3.msh") } else { format!("meshes/cook_{n}.msh") };
    let text = base.replace("../meshes/cook_8.msh", &mesh).replace("element = \"qm6\"", &format!("element = \"{elem}\""));
    let mut s: Simulation = sim(&text);
    s.set_stage_levels(0);
    let f = s.external_force().unwrap();
    let u = ImplicitSolver::default().solve(&s.model, &s.state.fix, &f, &s.state.u).unwrap();
    // The point Cook's reference is quoted at: the middle of the loaded edge, (48, 52).
    let c = s.model.cluster_x0().iter().position(|x| (x[0] - 48.0).abs() < 1e-6 && (x[1] - 52.0).abs() < 1e-6).expect("a node at (48, 52)");
    u[c][1]
}

/// Cook's membrane: plane stress, E = 1, nu = 1/3, unit total shear on the right edge.
/// Reference: the converged deflection 23.96 of the middle of the loaded edge, (48, 52) (Simo &
/// Rifai 1990; the FinEtools Cook tutorial: 23.97 at `Mid_edge = [48, 52]`). Not the top corner
/// (48, 60): that converges to about 25.1 (Q4 at 64 x 64: 25.04, our own numpy Q4 which also
/// gives Q4's published 18.30 / 22.08 / 23.43 at (48, 52) for 4 / 8 / 16). Asserted: `qm6`
/// within 3 % of 23.96 at 8 x 8 and within 1 % at 16 x 16; Q4 and T3 (quads split in two) lock:
/// both more than 5 % short at 8 x 8; every element increases monotonically with refinement and
/// stays below the reference plus 0.5 % (the reference itself is quoted to 0.04 %).
/// The table is in docs/elements.md.
#[test]
fn cooks_membrane_tip_deflection() {
    const REF: f64 = 23.96;
    let mut table = String::new();
    let mut at = std::collections::BTreeMap::new();
    for elem in ["q4", "t3", "qm6"] {
        let mut prev = 0.0;
        for n in [4, 8, 16] {
            let v = cook_tip(elem, n);
            table += &format!("{elem} {n}: {v:.3} ({:+.1} %)\n", 100.0 * (v / REF - 1.0));
            assert!(v > prev && v < REF * 1.005, "{elem} at {n}: {v} (previous {prev})");
            prev = v;
            at.insert((elem, n), v);
        }
    }
    eprintln!("{table}");
    assert!((at[&("qm6", 8)] / REF - 1.0).abs() < 0.03, "{table}");
    assert!((at[&("qm6", 16)] / REF - 1.0).abs() < 0.01, "{table}");
    assert!(at[&("q4", 8)] < 0.95 * REF && at[&("t3", 8)] < 0.95 * REF, "{table}");
}

/// FLEM's damped explicit equilibrium with `qm6` equals the implicit solve of the same model
/// (configs/verification/cook.toml at 4 x 4, whose [check] runs the implicit solver with the same
/// element stiffness). Reference: the implicit (faer Cholesky) solution; tolerance: relative L2
/// of displacements and of nodal stresses (with the enhanced field) below 1e-6.
#[test]
fn implicit_check_equals_explicit_equilibrium_with_qm6() {
    let base = std::fs::read_to_string(root().join("configs/verification/cook.toml")).unwrap();
    let text = base.replace("../meshes/cook_8.msh", "meshes/cook_4.msh") + "\n[solver]\ntolerance = 1e-9\nmax_steps = 2000000\n";
    let s = sim(&text);
    assert_eq!(s.model.blocks[0].element(), "qm6");
    explicit_equals_implicit(s, "qm6", 1e-6);
}

/// Runs `s` (one stage, with `[check]`) and asserts that its damped explicit equilibrium equals
/// the implicit solve of the same model: relative L2 of displacements and nodal stresses below
/// `tol` (the implicit solve converged, the explicit stage at rest).
fn explicit_equals_implicit(mut s: Simulation, name: &str, tol: f64) {
    use flem_core::output::compare::Comparer;
    use flem_core::solver::NoOutput;
    let dir = std::env::temp_dir().join(format!("flem-test-{name}-check-{}", std::process::id()));
    let mut quiet = NoOutput;
    let mut c = Comparer::new(&mut quiet, &dir).unwrap();
    s.run(&mut c).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(c.rows.len(), 1);
    let r = &c.rows[0];
    eprintln!("{name} check: ratio {:?}, rel_l2 u {:?}, s {:?}", r.unbalanced_ratio, r.rel_l2_displacement, r.rel_l2_nodal_stress);
    assert!(r.flem_converged && r.implicit_error.is_none(), "{r:?}");
    assert!(r.rel_l2_displacement.unwrap() < tol && r.rel_l2_nodal_stress.unwrap() < tol, "{r:?}");
}

/// `q4_closed` (ours, issue 42) in a model: a cantilever of 32 x 8 rectangles (parallelogram
/// packs: the closed form runs), tip shear, plane stress. Reference: the implicit (faer Cholesky)
/// solve of the same model, whose stiffness is the generic 2 x 2 Gauss integral
/// (`element::stiffness`), through the scene's `[check]`; tolerance: relative L2 of displacements
/// and nodal stresses below 1e-6 at the damped explicit equilibrium. And the model's internal
/// forces under a random field equal `q4`'s to 1e-12 of the largest, with some bits different
/// (the closed form ran, not `q4`'s sum).
#[test]
fn q4_closed_explicit_equilibrium_equals_the_implicit_solve() {
    let text = |elem: &str| {
        format!(
            "[mesh]\ntype = \"rectangle\"\nwidth = 8.0\nheight = 2.0\nnx = 32\nny = 8\n[model]\nplane = \"stress\"\n[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\nelement = \"{elem}\"\n[[support]]\nnodes = \"left\"\nfix = \"xy\"\n[[load]]\nname = \"shear\"\ntype = \"traction\"\nedges = \"right\"\nvalue = [0.0, -1.0]\n[solver]\ntolerance = 1e-10\nmax_steps = 2000000\n[check]\n[[stage]]\nlevels = {{ shear = 1.0 }}\n"
        )
    };
    let (closed, q4) = (sim(&text("q4_closed")), sim(&text("q4")));
    assert!(closed.model.blocks.iter().all(|b| b.element() == "q4_closed"));
    let nc = closed.model.topo.n_clusters();
    let u = crate::common::scattered_field(nc, 1e-3);
    let (mut fc, mut fq) = (vec![[0.0; 2]; nc], vec![[0.0; 2]; nc]);
    closed.model.internal_forces(&u, &mut fc);
    q4.model.internal_forces(&u, &mut fq);
    let scale = fq.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let worst = fc.iter().flatten().zip(fq.iter().flatten()).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(worst <= 1e-12 * scale && worst > 0.0, "q4_closed against q4: {worst:e} of {scale:e}");
    explicit_equals_implicit(closed, "q4_closed", 1e-6);
}

/// `q4_closed` with a plastic law (configs/verification/strip_footing.toml, Tresca, B-bar): its
/// stateful blocks are `q4`'s (they have no elastic force kernel, docs/elements.md), so the
/// blocks report `q4` and the stored-state forces under the same displacements are `q4`'s bit for
/// bit (reference: the scene with `q4`; exact equality).
#[test]
fn q4_closed_with_a_plastic_law_is_q4() {
    let base = std::fs::read_to_string(root().join("configs/verification/strip_footing.toml")).unwrap();
    let with = |elem: &str| base.replacen("density = 1.0\n", &format!("density = 1.0\nelement = \"{elem}\"\n"), 1);
    let (mut a, mut b) = (sim(&with("q4")), sim(&with("q4_closed")));
    assert!(a.model.stateful && b.model.stateful);
    assert!(b.model.blocks.iter().all(|k| k.element() == "q4"), "{:?}", b.model.blocks.iter().map(|k| k.element()).collect::<Vec<_>>());
    let n = a.state.u.len();
    // Large enough to yield under the footing.
    let u: Vec<[f64; 2]> = (0..n).map(|i| [1e-2 * ((i * 7919) % 13) as f64, -1e-2 * ((i * 104729) % 11) as f64]).collect();
    let (mut fa, mut fb) = (vec![[0.0; 2]; n], vec![[0.0; 2]; n]);
    a.model.update_internal_forces(&u, &mut fa);
    b.model.update_internal_forces(&u, &mut fb);
    assert!(fa.iter().flatten().any(|v| *v != 0.0));
    assert!(fa.iter().flatten().zip(fb.iter().flatten()).all(|(x, y)| x.to_bits() == y.to_bits()));
}

/// An unknown element name is refused naming the key and the nearest kind; a name of another
/// cell type leaves the cells on their default (the element applies to its own cell type).
#[test]
fn element_names_are_checked() {
    flem_plugins::link();
    let text =
        "[mesh]\ntype = \"rectangle\"\nwidth = 1.0\nheight = 1.0\nnx = 2\nny = 2\n[[material]]\nyoung_modulus = 1.0\npoisson_ratio = 0.3\ndensity = 1.0\nelement = \"qm7\"\n[[stage]]\nlevels = {}\n";
    let e = Simulation::new(crate::common::scene(text)).err().expect("refused").to_string();
    assert!(e.contains("material[0].element") && e.contains("did you mean \"qm6\""), "{e}");
    let s = sim(&text.replace("qm7", "t3"));
    assert_eq!(s.model.blocks[0].element(), "q4");
}

/// Records every split event and when the body first fell in two.
#[derive(Default)]
struct Splits {
    events: Vec<flem_core::cracking::SplitEvent>,
    separated_at: Option<usize>,
}
impl flem_core::solver::Observer for Splits {
    fn splits(&mut self, s: &Simulation, _r: &flem_core::mesh::topology::SplitRecord, ev: &[flem_core::cracking::SplitEvent]) -> flem_core::Result<()> {
        self.events.extend(ev.iter().cloned());
        if self.separated_at.is_none() && s.model.topo.fragments().1 >= 2 {
            self.separated_at = Some(self.events.len());
        }
        Ok(())
    }
}

/// The opening model (configs/paper/opening.toml: side notch, pulled from both sides, tension
/// check only) with `element = "qm6"`: the enhanced corner stresses drive the failure check and
/// the splits. qm6 is softer in bending than Q4, so its elastic notch-tip stress is lower and
/// its critical level higher than the paper's bracket (110, 115) of Q4; the stages are therefore
/// set from qm6's own static p_crit (`paper::opening_p_crit`: the implicit solve, whose
/// stiffness is qm6's). Reference: that p_crit and the paper's crack path (figure 11). Asserted
/// exactly (topology): no split at 0.97 p_crit (and equilibrium); at 1.1 p_crit the first split
/// is at the notch tip, the crack runs along the notch line (y = 3) only and opens every
/// ligament edge at both ends, and the plate falls in exactly two.
#[test]
fn opening_model_with_qm6_splits_along_the_ligament() {
    use flem_core::ids::EdgeId;
    let text = std::fs::read_to_string(root().join("configs/paper/opening.toml")).unwrap();
    let text = text.replacen("density = 2.65\n", "density = 2.65\nelement = \"qm6\"\n", 1);
    assert!(text.contains("element = \"qm6\""));
    let (p_crit, _, _) = crate::paper::opening_p_crit(&text);
    let (p1, p2) = (0.97 * p_crit, 1.1 * p_crit);
    eprintln!("qm6 opening: static p_crit/(rho g) = {p_crit:.2}; stages {p1:.2}, {p2:.2}");
    let a = text.find("[[stage]]").unwrap();
    let b = text.find("[output]").unwrap();
    let stages = format!(
        "[[stage]]\nname = \"below\"\nlevels = {{ p = {p1}, p_bottom = {p1} }}\nmax_steps = 4000\n\n[[stage]]\nname = \"above\"\nlevels = {{ p = {p2}, p_bottom = {p2} }}\nmax_steps = 3000\n\n"
    );
    let text = format!("{}{stages}{}", &text[..a], &text[b..]);
    flem_plugins::link();
    let scene = flem_core::scene::Scene::from_str(&text, std::path::Path::new("<qm6 opening>"), &root().join("configs/paper")).unwrap();
    let mut s = Simulation::new(scene).unwrap();
    assert!(s.model.blocks.iter().all(|b| b.element() == "qm6"));
    let mut log = Splits::default();
    s.run_stage(0, &mut log).unwrap();
    assert!(log.events.is_empty() && s.stages_done[0].converged, "qm6: {} splits below p_crit", log.events.len());
    s.run_stage(1, &mut log).unwrap();
    let tip = s.model.mesh.node_sets["notch_tip"][0] as usize;
    assert_eq!(log.events.first().map(|e| e.point.idx()), Some(tip), "qm6: the first split is not at the notch tip");
    let topo = &s.model.topo;
    let pts = &s.model.mesh.points;
    let on_line = |e: usize| {
        let q = topo.edges[e].points;
        (pts[q[0].idx()][1] - 3.0).abs() < 1e-9 && (pts[q[1].idx()][1] - 3.0).abs() < 1e-9
    };
    let lig: Vec<usize> = (0..topo.edges.len()).filter(|&e| on_line(e) && pts[topo.edges[e].points[0].idx()][0].min(pts[topo.edges[e].points[1].idx()][0]) > 2.0 - 1e-9).collect();
    let states: Vec<u8> = lig.iter().map(|&e| topo.crack_state(EdgeId::new(e))).collect();
    eprintln!("qm6 opening: {} splits; ligament edge states {states:?}; fragments {}", log.events.len(), topo.fragments().1);
    assert!(!lig.is_empty() && states.iter().all(|&st| st == 2), "qm6: the ligament is not open: {states:?}");
    assert_eq!(topo.fragments().1, 2, "qm6: the plate did not fall in exactly two");
    for ev in &log.events[..log.separated_at.unwrap_or(log.events.len())] {
        assert!(ev.edges.iter().all(|e| on_line(e.idx())), "qm6: the crack left the notch line at point {}", ev.point.0);
    }
}

/// configs/verification/cantilever.toml (20 x 2 quads, plane stress, end shear) with
/// `element = "qm6"`, run by the explicit solver to its tolerance: the tip deflection within 1 %
/// of Timoshenko & Goodier's 4.02625 (the scene's header: sec. 21, shear included; the scene's
/// clamp and uniform end shear cost about 0.1 %). Q4 on the same mesh locks (3.597, -10.7 %).
#[test]
fn cantilever_tip_with_qm6_within_one_percent() {
    let text = std::fs::read_to_string(root().join("configs/verification/cantilever.toml")).unwrap();
    let text = text.replacen("density = 1.0\n", "density = 1.0\nelement = \"qm6\"\n", 1);
    // Without its [check] section (the implicit comparison is another test's).
    let mut s = sim(text.split("\n[check]").next().unwrap());
    assert_eq!(s.model.blocks[0].element(), "qm6");
    s.run(&mut flem_core::solver::NoOutput).unwrap();
    assert!(s.stages_done.iter().all(|st| st.converged));
    let c = s.model.cluster_x0().iter().position(|x| (x[0] - 10.0).abs() < 1e-9 && (x[1] - 0.5).abs() < 1e-9).unwrap();
    let tip = s.state.u[c][1];
    eprintln!("qm6 cantilever tip u_y = {tip} ({:+.2} % of -4.02625)", 100.0 * (tip / -4.02625 - 1.0));
    assert!((tip / -4.02625 - 1.0).abs() < 0.01, "tip {tip}");
}

/// The ```toml snippets of docs/elements.md and of every element plugin's `//!` doc build a
/// model whose quadrilateral blocks are the element the snippet names (the docs cannot drift
/// from the code).
#[test]
fn element_doc_snippets_build() {
    let md = std::fs::read_to_string(root().join("docs/elements.md")).unwrap();
    let mut snippets: Vec<(String, String)> = Vec::new();
    let mut cur: Option<String> = None;
    for line in md.lines() {
        match (&mut cur, line.trim()) {
            (None, "```toml") => cur = Some(String::new()),
            (Some(_), "```") => snippets.push(("docs/elements.md".into(), cur.take().unwrap())),
            (Some(s), _) => {
                s.push_str(line);
                s.push('\n');
            }
            _ => {}
        }
    }
    for file in ["plugins/src/elements/q4.rs", "plugins/src/elements/q4_closed.rs", "plugins/src/elements/t3.rs", "plugins/src/elements/qm6.rs"] {
        let src = std::fs::read_to_string(root().join(file)).unwrap();
        let blocks = flem_plugins::snippets::toml_blocks(&src);
        assert!(!blocks.is_empty(), "{file} has no ```toml block");
        snippets.extend(blocks.into_iter().map(|b| (file.to_string(), b)));
    }
    assert!(snippets.len() >= 2);
    for (file, snip) in snippets {
        let t: toml::Table = toml::from_str(&snip).unwrap_or_else(|e| panic!("{file}: {e}\n{snip}"));
        let want = t["material"].as_array().unwrap()[0]["element"].as_str().unwrap().to_string();
        // The rectangle's cells are of the element's cell type.
        let cell = match flem_core::element::registry::find(&want).unwrap_or_else(|| panic!("{file}: no kind {want}")).cell {
            flem_core::mesh::CellKind::Q4 => "q4",
            flem_core::mesh::CellKind::T3 => "t3",
        };
        let text = format!("[mesh]\ntype = \"rectangle\"\nwidth = 2.0\nheight = 1.0\nnx = 4\nny = 2\nelement = \"{cell}\"\n{snip}\n[[stage]]\nlevels = {{}}\n");
        let s = sim(&text);
        assert!(s.model.blocks.iter().all(|b| b.element() == want), "{file}: {want}");
    }
}

/// `flem chart --quick --elements q4,qm6` on the cantilever: both kinds' points in one sweep
/// (column `element`); the implicit solves' error against Timoshenko & Goodier's tip deflection
/// (4.02625) is below 1 % for qm6 on the scene's mesh and above 5 % for Q4 (locking).
#[test]
fn chart_sweeps_element_kinds() {
    let dir = std::env::temp_dir().join(format!("flem-chart-elements-{}", std::process::id()));
    let out = std::process::Command::new(crate::common::flem_exe())
        .args(["chart", root().join("configs/verification/cantilever.toml").to_str().unwrap(), "--quick", "--analytic", "tip:y=-4.02625", "--elements", "q4,qm6", "--out", dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let csv = std::fs::read_to_string(dir.join("chart.csv")).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 20, "{csv}");
    let implicit_x1 = |e: &str| rows.iter().find(|r| r[0] == "implicit" && r[4] == "1" && r[13] == e).map(|r| r[11].parse::<f64>().unwrap()).unwrap();
    let (q4, qm6) = (implicit_x1("q4"), implicit_x1("qm6"));
    assert!(qm6 < 0.01 && q4 > 0.05, "analytic errors: q4 {q4}, qm6 {qm6}");
}

/// qm6's blocked forces are bit-identical whatever the thread count (the colouring schedule of
/// `element::kernel`, as for Q4: tests/parallel.rs), on a block large enough to use the pool.
#[test]
fn qm6_forces_bit_identical_across_threads() {
    let text = "[mesh]\ntype = \"rectangle\"\nwidth = 7.0\nheight = 6.0\nnx = 70\nny = 60\ndistort = 0.2\n[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\nelement = \"qm6\"\n[[stage]]\nlevels = {}\n";
    let mut s = sim(text);
    assert!(s.model.n_elems() >= 4096 && s.model.blocks[0].element() == "qm6");
    let x0 = s.model.cluster_x0();
    let u: Vec<[f64; 2]> = x0.iter().map(|x| [1e-3 * (3.0 * x[0]).sin() * x[1], 1e-3 * (2.0 * x[1]).cos() * x[0]]).collect();
    let mut f1 = vec![[0.0; 2]; u.len()];
    s.model.internal_forces(&u, &mut f1);
    s.model.set_threads(2).unwrap();
    let mut f2 = vec![[0.0; 2]; u.len()];
    s.model.internal_forces(&u, &mut f2);
    assert!(f1.iter().zip(&f2).all(|(a, b)| a[0].to_bits() == b[0].to_bits() && a[1].to_bits() == b[1].to_bits()));
    assert!(f1.iter().any(|f| f[0] != 0.0));
}

/// A scene on the distorted 6 x 5 patch mesh with `element = "qm6"` and the `mohr_coulomb` law
/// at a cohesion no stress reaches (an elastic law run by the stateful block).
fn stateful_qm6(plane: &str, bbar: bool) -> Simulation {
    sim(&format!(
        "[mesh]\ntype = \"rectangle\"\nwidth = 2.0\nheight = 1.5\nnx = 6\nny = 5\ndistort = 0.25\n[model]\nplane = \"{plane}\"\n[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\nthickness = 0.7\nelement = \"qm6\"\nbbar = {bbar}\nlaw = {{ type = \"mohr_coulomb\", cohesion = 1e9, friction_angle_deg = 0.0 }}\n[[stage]]\nlevels = {{}}\n"
    ))
}

/// Patch test of the stateful qm6 block (incompatible modes condensed with the elastic moduli,
/// `StatefulBlock::with_enhanced`) with an elastic law (`mohr_coulomb` far from yield, which
/// needs plane strain), B-bar on and off, on the distorted mesh. Reference: the exact linear field and `D eps`. Tolerance 1e-12
/// relative: (A) zero internal force at every interior node under the exact nodal values,
/// (B) the stress of every Gauss point after the one-step update equal to `D eps`.
#[test]
fn stateful_qm6_patch_test() {
    for plane in ["strain"] {
        for bbar in [false, true] {
            let mut s = stateful_qm6(plane, bbar);
            assert!(s.model.stateful && s.model.blocks.iter().all(|b| b.element() == "qm6" && !b.isoparametric()));
            let x0 = s.model.cluster_x0();
            let u: Vec<[f64; 2]> = x0.iter().map(|&x| u_lin(x)).collect();
            let mut f = vec![[0.0; 2]; u.len()];
            s.model.update_internal_forces(&u, &mut f);
            let d = s.model.blocks[0].material().dmat();
            let want = d.stress(EPS);
            let t = 0.7;
            let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs())) * t * 0.25;
            for (c, x) in x0.iter().enumerate() {
                let interior = x[0] > 1e-9 && x[0] < 2.0 - 1e-9 && x[1] > 1e-9 && x[1] < 1.5 - 1e-9;
                if interior {
                    assert!(f[c][0].abs() < 1e-12 * scale && f[c][1].abs() < 1e-12 * scale, "{plane} bbar {bbar}: node {c} force {:?}", f[c]);
                }
            }
            let ps = s.model.blocks[0].point_stress(&u).expect("stateful block keeps its point stress");
            assert_eq!(ps.len(), 4 * s.model.n_elems());
            for p in ps {
                for k in 0..3 {
                    assert!((p[k] - want[k]).abs() <= 1e-12 * want[0].abs(), "{plane} bbar {bbar}: {p:?} vs {want:?}");
                }
            }
        }
    }
}

/// The stateful qm6 block (elastic law, B-bar off) gives the forces of the stateless qm6
/// kernel (`f = K u` with the condensed K) for a random displacement in one step: with
/// `alpha = H u` the force `sum (B + G H)^T D (B + G H) u` is `K u` exactly in exact
/// arithmetic. Reference: the stateless block; tolerance 1e-12 relative.
#[test]
fn stateful_qm6_equals_the_stateless_qm6() {
    let lin = sim("[mesh]\ntype = \"rectangle\"\nwidth = 2.0\nheight = 1.5\nnx = 6\nny = 5\ndistort = 0.25\n[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\nthickness = 0.7\nelement = \"qm6\"\n[[stage]]\nlevels = {}\n");
    let mut st = stateful_qm6("strain", false);
    assert!(!lin.model.stateful && lin.model.blocks[0].element() == "qm6");
    crate::common::assert_same_forces(&lin, &mut st, 1e-12);
    // The implicit check's stiffness of the stateful block is qm6's condensed K.
    let (mut k1, mut k2) = (vec![0.0; 64], vec![0.0; 64]);
    lin.model.blocks[0].stiffness(3, &mut k1);
    st.model.blocks[0].stiffness(3, &mut k2);
    let km = k1.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(k1.iter().zip(&k2).all(|(a, b)| (a - b).abs() < 1e-12 * km));
}

/// qm6 with a stateful law and `[solver] large_strain` is refused naming the key (the
/// large-strain path has no incompatible modes).
#[test]
fn stateful_qm6_refuses_large_strain() {
    let text = "[mesh]\ntype = \"rectangle\"\nwidth = 2.0\nheight = 1.0\nnx = 2\nny = 1\n[solver]\nlarge_strain = true\n[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\nelement = \"qm6\"\n[[stage]]\nlevels = {}\n";
    let e = Simulation::new(crate::common::scene(text)).err().expect("refused").to_string();
    assert!(e.contains("material[0].element") && e.contains("qm6"), "{e}");
}

/// configs/verification/strip_footing.toml (smooth rigid strip footing on weightless Tresca
/// soil, c = 1, half model, b = 1) with `element = "qm6"` in the stateful block. Reference:
/// Prandtl's limit pressure (2 + pi) c = 5.1416; tolerance 3 % on the peak of
/// |reaction_footing_y| / b (measured 5.241, +1.9 %; q4 with B-bar gives 5.247).
#[test]
fn strip_footing_tresca_with_stateful_qm6() {
    let text = std::fs::read_to_string(root().join("configs/verification/strip_footing.toml")).unwrap().replacen("density = 1.0\n", "density = 1.0\nelement = \"qm6\"\n", 1);
    assert!(text.contains("element = \"qm6\""));
    let mut s = sim(&text);
    assert!(s.model.stateful && s.model.blocks.iter().all(|b| b.element() == "qm6"));
    struct Peak(Vec<flem_core::ids::PointId>, f64);
    impl flem_core::solver::Observer for Peak {
        fn history(&mut self, s: &Simulation, _stage: usize) -> flem_core::Result<()> {
            self.1 = self.1.max(s.reaction(&self.0)[1].abs());
            Ok(())
        }
    }
    let pts = s.model.node_set("footing", "test", "test").unwrap();
    let mut obs = Peak(pts, 0.0);
    s.run(&mut obs).unwrap_or_else(|e| panic!("{e}"));
    let prandtl = 2.0 + std::f64::consts::PI;
    assert!((obs.1 - prandtl).abs() / prandtl < 0.03, "footing pressure {} vs Prandtl {prandtl}", obs.1);
}
