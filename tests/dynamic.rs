//! Dynamic fracture tools (issue 36): velocity ramps, the crack-tip tracker, the ledger's
//! fracture energy. Each test names its reference and tolerance.
use flem_core::output::tips::TipTracker;
use flem_core::solver::{NoOutput, Simulation};

use crate::common::{rel, sim};

/// The point of the mesh nearest to `x`.
fn point_at(s: &Simulation, x: [f64; 2]) -> usize {
    let pts = &s.model.mesh.points;
    (0..pts.len()).min_by(|&a, &b| ((pts[a][0] - x[0]).hypot(pts[a][1] - x[1])).total_cmp(&(pts[b][0] - x[0]).hypot(pts[b][1] - x[1]))).unwrap()
}

/// A velocity ramp `v0 min(t / T, 1)` on the left end of an elastic bar, fixed dt with T a
/// whole number of steps. Reference: the displacement of the driven nodes is the integral of
/// the ramp, `v0 (t - T / 2)` for t >= T (the velocity is taken at each step's middle: the
/// midpoint rule, exact for a linear ramp): 1e-12 relative. The energy ledger of a linear
/// elastic body is exact for the central-difference scheme (`Ledger`): the work done by the
/// driven nodes (element forces plus the inertial force that changes their velocity) equals
/// KE + U to 1e-9 of the work; without the inertial work of the ramp the residual would be the
/// driven nodes' kinetic energy, which the test checks is above 1e-3 of the work (so that the
/// 1e-9 bound would catch it).
#[test]
fn velocity_ramp_follows_its_integral_and_the_ledger_closes() {
    let (v0, dt, n_ramp, n) = (0.01, 1e-3, 50u64, 400u64);
    let t_ramp = n_ramp as f64 * dt;
    let text = format!(
        "[mesh]\ntype = \"rectangle\"\nwidth = 4.0\nheight = 0.5\nnx = 16\nny = 2\n[[material]]\nyoung_modulus = 100.0\npoisson_ratio = 0.25\ndensity = 1.0\n[solver]\ndt = {dt}\ndamping = {{ type = \"none\" }}\n[[load]]\nname = \"push\"\ntype = \"velocity\"\nnodes = \"left\"\nx = \"{v0} * min(t / {t_ramp}, 1)\"\n[[stage]]\nlevels = {{ push = 1.0 }}\ndynamic = true\nmax_steps = {n}\n"
    );
    let mut s = sim(&text);
    s.run(&mut NoOutput).unwrap();
    let t = s.state.time;
    assert!(rel(t, n as f64 * dt) < 1e-12);
    let p = point_at(&s, [0.0, 0.25]);
    let c = s.model.topo.point_clusters[p][0].idx();
    let want = v0 * (t - 0.5 * t_ramp);
    assert!(rel(s.state.u[c][0], want) < 1e-12, "u = {} want {want}", s.state.u[c][0]);
    assert!(rel(s.state.v[c][0], v0) < 1e-12);
    let l = &s.ledger;
    assert!(l.external() > 0.0 && l.kinetic > 0.0 && l.strain > 0.0);
    assert!(l.residual().abs() < 1e-9 * l.external(), "residual {} of work {}", l.residual(), l.external());
    let driven: f64 = s
        .model
        .mesh
        .points
        .iter()
        .enumerate()
        .filter(|(_, x)| x[0] == 0.0)
        .flat_map(|(p, _)| s.model.topo.point_clusters[p].iter())
        .map(|c| 0.5 * s.state.mass[c.idx()] * s.state.v[c.idx()][0].powi(2))
        .sum();
    assert!(driven > 1e-3 * l.external(), "driven nodes' kinetic energy {driven} against work {}", l.external());
}

/// Crack growth prescribed by hand on a structured Q4 grid (h = 0.1): a notch of 1.0 from the
/// left at y = 1.0, then one edge more along y = 1.0 at each record (t = k tau), then a side
/// branch of 6 edges up from x = 1.5 while the main crack keeps growing. Reference: the tip is
/// the joined end of the last cut edge, (1.0 + k h, 1.0); its chord speed over a window of
/// 2.5 tau is 3 h / 3 tau = h / tau (exact to round-off, 1e-9), and none before a record of the
/// branch is 2.5 tau old (records 1-3; session 32); the branch is reported with the
/// main crack as its parent and its fork at (1.5, 1.0), its tip at (1.5, 1.6).
#[test]
fn tip_tracker_follows_a_prescribed_crack_and_its_branch() {
    let text = "[mesh]\ntype = \"rectangle\"\nwidth = 4.0\nheight = 2.0\nnx = 40\nny = 20\nnotch = { side = \"left\", y = 1.0, depth = 1.0 }\n[model]\nseparated = [\"notch\"]\n[[material]]\nyoung_modulus = 100.0\npoisson_ratio = 0.25\ndensity = 1.0\n[cracking]\nat_equilibrium = false\ncheck_every = 1\n[cracking.criterion]\ntype = \"rankine\"\ntensile_strength = 1.0\n[cracking.separation]\ntype = \"sigma1_nearest\"\n[[stage]]\ndynamic = true\nmax_steps = 1\n";
    let mut s = sim(text);
    let dir = std::env::temp_dir().join(format!("flem-tips-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (h, tau) = (0.1, 1e-3);
    let mut tr = TipTracker::new(&dir, &s, Some(2.5 * tau)).unwrap();
    let cut = |s: &mut Simulation, a: [f64; 2], b: [f64; 2]| {
        let (p, q) = (point_at(s, a), point_at(s, b));
        let e = s.model.topo.edge_between(flem_core::ids::PointId(p as u32), flem_core::ids::PointId(q as u32)).expect("an edge");
        let rec = s.model.topo.separate_edges(&[e]);
        s.model.apply_record(&rec);
        s.apply_split_record(&rec);
    };
    for k in 1..=8 {
        let x = 1.0 + k as f64 * h;
        cut(&mut s, [x - h, 1.0], [x, 1.0]);
        s.state.time = k as f64 * tau;
        tr.record(&s, true).unwrap();
        let main: Vec<_> = tr.last.iter().filter(|t| t.branch == Some(0)).collect();
        assert_eq!(main.len(), 1, "record {k}: {:?}", tr.last);
        assert!((main[0].x[0] - x).abs() < 1e-9 && (main[0].x[1] - 1.0).abs() < 1e-9, "record {k}: {:?}", main[0]);
        assert!((main[0].arc - k as f64 * h).abs() < 1e-9);
        if k >= 4 {
            let v = main[0].speed.expect("a speed");
            assert!(rel(v, h / tau) < 1e-9, "record {k}: speed {v}");
        } else {
            // No record of the branch is a window (2.5 tau) old yet: no speed (session 32).
            assert!(main[0].speed.is_none(), "record {k}: a speed before the window {:?}", main[0].speed);
        }
    }
    // A branch up from (1.5, 1.0), 6 edges, while the main crack grows 6 more.
    for k in 1..=6 {
        cut(&mut s, [1.5, 1.0 + (k - 1) as f64 * h], [1.5, 1.0 + k as f64 * h]);
        let x = 1.8 + k as f64 * h;
        cut(&mut s, [x - h, 1.0], [x, 1.0]);
        s.state.time = (8 + k) as f64 * tau;
        tr.record(&s, true).unwrap();
    }
    let tips: Vec<_> = tr.last.iter().filter(|t| t.branch.is_some()).collect();
    assert_eq!(tips.len(), 2, "{:?}", tr.last);
    let main = tips.iter().find(|t| t.branch == Some(0)).expect("the main crack");
    assert!((main.x[0] - 2.4).abs() < 1e-9 && (main.x[1] - 1.0).abs() < 1e-9, "{main:?}");
    let br = tips.iter().find(|t| t.branch != Some(0)).expect("the branch");
    assert_eq!(br.parent, Some(0));
    assert!((br.x[0] - 1.5).abs() < 1e-9 && (br.x[1] - 1.6).abs() < 1e-9, "{br:?}");
    let f = br.fork.unwrap();
    assert!((f[0] - 1.5).abs() < 1e-9 && (f[1] - 1.0).abs() < 1e-9, "fork {f:?}");
    tr.finish().unwrap();
    let csv = std::fs::read_to_string(dir.join("crack_tips.csv")).unwrap();
    assert!(csv.starts_with("time,step,branch,parent,x,y,arc,speed"));
    // One row per tip per record: 14 records, the last with two tips.
    let last: Vec<&str> = csv.lines().filter(|l| l.starts_with(&format!("{:e},", s.state.time))).collect();
    assert_eq!(last.len(), 2, "{csv}");
    assert!(csv.lines().count() >= 1 + 14 + 1, "{csv}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A strip 1 x 0.5 (Q4, h = 1/16) whose mid-height line is split at t = 0 through the whole
/// width (b = 1, cut by `Topology::separate_edges` as a failure check would, so the faces are
/// fresh: the `cohesive` law acts on them), then pulled apart at top and bottom until the faces
/// have opened far beyond delta_f. Reference: the energy to separate faces of length b through
/// a cohesive law of fracture energy G_f is G_f b per unit thickness (the area under the
/// traction-separation curve per unit crack area, Hillerborg et al. 1976): the ledger's
/// fracture energy must equal it within 1 % (a pair area off by one end's h / 2 would show as
/// 3 %), and the ledger must close to 1e-3 of the work (issue 36 must-show 3).
#[test]
fn fracture_energy_is_gc_times_the_separated_length() {
    // The linear law, pulled to t = 0.35; Petersson's bilinear softening (session 26, the
    // L-panel's law: the area under its curve is G_f by construction, Petersson 1981), pulled
    // to 0.6 since its delta_f is 1.8 times the linear law's (measured: 2e-16, ledger 2.1e-7).
    // A knee missing from the law's kink work fails the law's unit test instead
    // (`work_of_the_forces_equals_stored_plus_dissipated`, 1e-9).
    // Cornelissen's exponential softening (session 32): delta_f = 5.14 g / sigma_t, pulled to 0.95.
    for (end, extra) in [(0.35, ""), (0.6, ", softening = \"petersson\""), (0.95, ", softening = \"cornelissen\"")] {
        let (gf, b) = (0.01, 1.0);
        let mut s = pulled_strip_law(gf, end, extra);
        let l = &s.ledger;
        eprintln!("law{extra}: fracture {} against G_f b = {}, residual {:e}", l.fracture, gf * b, l.relative_residual());
        assert!(rel(l.fracture, gf * b) < 0.01, "law{extra}: fracture energy {} against G_f b = {}", l.fracture, gf * b);
        let (one, two) = s.model.topo.crack_counts();
        assert_eq!((one, two), (0, 16), "the mid-height line is cracked through");
        assert!(l.relative_residual() < 1e-3, "law{extra}: residual {:e}", l.relative_residual());
        // The fracture account (summary.json `fracture_account`): the faces made are the line
        // (b x thickness 1), all traction-free, no cohesive zone left.
        let c = s.contact.as_mut().expect("contact");
        assert!(rel(c.fresh_face_area(&s.model), b) < 1e-12, "face area {}", c.fresh_face_area(&s.model));
        let law = s.scene.file.contact.as_ref().unwrap().law.as_ref();
        assert_eq!(c.zones(law), [0.0; 3], "law{extra}: every pair opened past delta_f");
    }
}

/// The fracture account in a half-open cohesive zone (issue 36 must-show 3, docs/dynamic.md
/// "Energy"): the strip of the test above pulled only until its faces opened into the
/// softening branch (delta_0 < delta < delta_f). Reference: the linear-softening law's energy
/// per area (Hillerborg et al. 1976): released so far R(delta_max) = W - 1/2 T delta, still to
/// release G_f - R; so fracture energy + the zone's pending energy = G_f x the zone's area,
/// and the zone's area is the face area b. Tolerances: 1e-9 (sums of the same terms); a pair
/// area off by a face end, or a pending energy that ignored the released part, fails by 3 % or
/// more. Then the same with Petersson's softening (session 26: the shape seen, not only its
/// area), pulled past the linear law's delta_f (2 g / sigma_t) but not past Petersson's
/// (3.6 g / sigma_t): every pair still softening and the same identity; with the key ignored
/// (a linear law) the faces would be traction-free there and the test fails (checked).
#[test]
fn fracture_account_of_a_half_open_cohesive_zone() {
    // (end, law's extra keys, least released and least pending energy as fractions of G_f b)
    // Cornelissen's law (session 32) pulled into its curved branch, short of its delta_f (5.14 g /
    // sigma_t): the released and pending energies of the curve (measured 0.77 / 0.23 G_f b).
    for (end, extra, f_min, p_min) in [(0.12, "", 0.05, 0.05), (0.28, ", softening = \"petersson\"", 0.5, 0.01), (0.3, ", softening = \"cornelissen\"", 0.5, 0.1)] {
        let (gf, b) = (0.01, 1.0);
        let mut s = pulled_strip_law(gf, end, extra);
        let fracture = s.ledger.fracture;
        let c = s.contact.as_mut().expect("contact");
        let law = s.scene.file.contact.as_ref().unwrap().law.as_ref();
        let [intact, soft, pending] = c.zones(law);
        eprintln!("half open{extra}: fracture {fracture}, intact {intact}, softening {soft}, pending {pending}");
        assert_eq!(intact, 0.0, "every pair passed the peak");
        assert!(rel(soft, b) < 1e-12, "law{extra}: softening area {soft} against b = {b}");
        assert!(fracture > f_min * gf * b && pending > p_min * gf * b, "law{extra}: the zone is part-way: fracture {fracture}, pending {pending}");
        assert!(rel(fracture + pending, gf * soft) < 1e-9, "fracture {fracture} + pending {pending} against G_f A = {}", gf * soft);
    }
}

/// A 1 x 0.5 strip cut along y = 0.25 at the start, top and bottom pulled apart at 0.05 each,
/// cohesive faces (sigma_t = 1, G_f = `gf`, `extra` appended to the law's table, e.g. a
/// softening key), run to `end`.
fn pulled_strip_law(gf: f64, end: f64, extra: &str) -> Simulation {
    let text = format!(
        "[mesh]\ntype = \"rectangle\"\nwidth = 1.0\nheight = 0.5\nnx = 16\nny = 8\n[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.2\ndensity = 1.0\n[solver]\ndt_safety = 0.5\ndamping = {{ type = \"none\" }}\n[[load]]\nname = \"up\"\ntype = \"velocity\"\nnodes = \"top\"\ny = 0.05\n[[load]]\nname = \"down\"\ntype = \"velocity\"\nnodes = \"bottom\"\ny = -0.05\n[contact]\nlaw = {{ type = \"cohesive\", normal_stiffness = 16000.0, shear_stiffness = 16000.0, tensile_strength = 1.0, fracture_energy = {gf}, friction = 0.0{extra} }}\n[[stage]]\nlevels = {{ up = 1.0, down = 1.0 }}\ndynamic = true\nend_time = {end}\nmax_steps = 200000\n"
    );
    let mut s = sim(&text);
    let on_line: Vec<flem_core::ids::EdgeId> = (0..s.model.topo.edges.len())
        .filter(|&i| {
            let [a, c] = s.model.topo.edges[i].points;
            let (pa, pc) = (s.model.mesh.points[a.idx()], s.model.mesh.points[c.idx()]);
            (pa[1] - 0.25).abs() < 1e-9 && (pc[1] - 0.25).abs() < 1e-9
        })
        .map(flem_core::ids::EdgeId::new)
        .collect();
    assert_eq!(on_line.len(), 16);
    let rec = s.model.topo.separate_edges(&on_line);
    s.model.apply_record(&rec);
    s.apply_split_record(&rec);
    s.run(&mut NoOutput).unwrap_or_else(|e| panic!("{e}"));
    s
}

/// A 2 x 2 square of four unit Q4 (no load, no support) with cohesive contact (sigma_t = 1,
/// G_f = 0.01, delta_f = 0.02), whose edges between the given points are cut as a failure
/// check would cut them (fresh faces), one `separate_edges` call per list; then driven by
/// prescribed displacements through `Contact::compute` directly (no march: the faces open
/// exactly as prescribed), one phase of 400 steps after the other: a phase gives a cluster,
/// from the mean centroid of its elements and the phase's time `t` in (0, 1], its displacement,
/// or `None` to keep it where it is. Returns after each phase the fracture energy summed so far
/// (`Contact::fracture_step`), the crack-face area made (`Contact::fresh_face_area`) and the
/// cohesive zones (`Contact::zones`: intact area, softening area, pending energy).
type Drive<'a> = &'a dyn Fn([f64; 2], f64) -> Option<[f64; 2]>;
fn cohesive_square_opened(cuts: &[&[([f64; 2], [f64; 2])]], phases: &[Drive]) -> Vec<(f64, f64, [f64; 3])> {
    let (mut s, centre, x0) = cohesive_square(cuts);
    let nc = x0.len();
    let law = s.scene.file.contact.as_ref().unwrap().law.as_ref();
    let c = s.contact.as_mut().unwrap();
    let (n, dt) = (400usize, 1.0);
    let mut u = vec![[0.0; 2]; nc];
    let mut f = vec![[0.0; 2]; nc];
    let mut fracture = 0.0;
    let mut out = Vec::new();
    for drive in phases {
        for i in 1..=n {
            let t = i as f64 / n as f64;
            let un: Vec<[f64; 2]> = (0..nc).map(|cl| drive(centre[cl], t).unwrap_or(u[cl])).collect();
            let v: Vec<[f64; 2]> = (0..nc).map(|cl| [(un[cl][0] - u[cl][0]) / dt, (un[cl][1] - u[cl][1]) / dt]).collect();
            u = un;
            c.compute(law, &x0, &u, &v, dt, &mut f);
            fracture += c.fracture_step;
        }
        out.push((fracture, c.fresh_face_area(&s.model), c.zones(law)));
    }
    out
}

/// The square of [`cohesive_square_opened`] with its cuts made: the simulation, the mean
/// centroid of every cluster's elements, and every cluster's reference position.
fn cohesive_square(cuts: &[&[([f64; 2], [f64; 2])]]) -> (Simulation, Vec<[f64; 2]>, Vec<[f64; 2]>) {
    let text = "[mesh]\ntype = \"rectangle\"\nwidth = 2.0\nheight = 2.0\nnx = 2\nny = 2\n[[material]]\nyoung_modulus = 1000.0\npoisson_ratio = 0.2\ndensity = 1.0\n[contact]\nlaw = { type = \"cohesive\", normal_stiffness = 1e4, shear_stiffness = 1e4, tensile_strength = 1.0, fracture_energy = 0.01, friction = 0.0 }\n[[stage]]\nlevels = {}\n";
    let mut s = sim(text);
    for cut in cuts {
        let edges: Vec<flem_core::ids::EdgeId> = cut
            .iter()
            .map(|&(a, b)| {
                let (pa, pb) = (point_at(&s, a), point_at(&s, b));
                s.model.topo.edge_between(flem_core::ids::PointId(pa as u32), flem_core::ids::PointId(pb as u32)).expect("an edge of the mesh")
            })
            .collect();
        let rec = s.model.topo.separate_edges(&edges);
        s.model.apply_record(&rec);
        s.apply_split_record(&rec);
    }
    let topo = &s.model.topo;
    let nc = topo.n_clusters();
    let mut centre = vec![[0.0; 3]; nc];
    for e in 0..topo.n_elems() {
        let r = topo.elem_copies(flem_core::ids::ElemId(e as u32));
        let pts: Vec<[f64; 2]> = r.clone().map(|k| s.model.mesh.points[topo.copy_point[k].idx()]).collect();
        let m = pts.len() as f64;
        for k in r {
            let c = &mut centre[topo.copy_cluster[k].idx()];
            c[0] += pts.iter().map(|p| p[0]).sum::<f64>() / m;
            c[1] += pts.iter().map(|p| p[1]).sum::<f64>() / m;
            c[2] += 1.0;
        }
    }
    let centre: Vec<[f64; 2]> = centre.iter().map(|c| [c[0] / c[2], c[1] / c[2]]).collect();
    let x0: Vec<[f64; 2]> = (0..nc).map(|c| s.model.mesh.points[topo.cluster_point[c].idx()]).collect();
    (s, centre, x0)
}

/// One crack face opened by a prescribed displacement (issue 36 must-show 3, the closed form
/// first): the edge from the left side (0, 1) to the centre (1, 1) is cut; its end at the left
/// side separates, the centre is the crack tip (one end: the face made is half the edge,
/// `fresh_face_area` 0.5), and the top-left element's own corners (the upper copy of (0, 1) and
/// (0, 2)) are lifted by 5 delta_f. Reference: a cohesive law releases G_f per unit of face
/// area opened past delta_f (the area under its traction-separation curve, Hillerborg et al.
/// 1976), so the fracture energy is G_f x 0.5 = 0.005, to 1e-9 (the law's released energy
/// telescopes over the steps); nothing intact or softening is left.
#[test]
fn one_cohesive_face_opened_releases_gc_times_its_area() {
    let lift = |c: [f64; 2], t: f64| (c[0] < 1.0 - 1e-9 && c[1] > 1.0 + 1e-9).then_some([0.0, 0.1 * t]);
    let r = cohesive_square_opened(&[&[([0.0, 1.0], [1.0, 1.0])]], &[&lift]);
    let (fracture, area, zones) = r[0];
    eprintln!("one face: fracture {fracture:.9e}, face area {area}, zones {zones:?}");
    assert!(rel(area, 0.5) < 1e-12, "face area {area}");
    assert!(rel(fracture, 0.01 * 0.5) < 1e-9, "fracture {fracture:.9e} against G_f x 0.5 = 5e-3");
    assert_eq!(zones, [0.0; 3]);
}

/// A node with two cut faces opened one after the other (the session-15 diagnosis of issue 36:
/// cohesion followed one pair per slave node, so the second face of a node came free without
/// its cohesion, or the first pair released both faces' energy at once). The square's
/// mid-height line is cut through (two edges; the centre's lower copy B faces the top-left and
/// the top-right elements), then the vertical edge from the centre to the top (1, 2) (the top
/// splits into the top-left element TL and the top-right TR; three crack edges, both ends
/// separated: face area 3). Phase 1 moves TL by (-5, 5) delta_f: the left half of the
/// mid-height line and the vertical edge open past delta_f, the right half stays closed.
/// Phase 2 moves TR by (5, 5) delta_f: the right half opens. Reference (Hillerborg: G_f per
/// unit area of face opened past delta_f, the area under the traction-separation curve):
/// after phase 1 the fracture energy is G_f x 2 and the right half (area 1) is intact; after
/// phase 2 it is G_f x 3 and nothing is left; 1e-9. One pair per node (before the fix): after
/// phase 1, 2.5 G_f or 1.5 G_f (B's one pair carried both halves of the mid-height line at
/// the centre against one master), 0.5 intact.
#[test]
fn a_node_with_two_cohesive_faces_releases_both() {
    let tl = |c: [f64; 2], t: f64| (c[0] < 1.0 - 1e-9 && c[1] > 1.0 + 1e-9).then_some([-0.1 * t, 0.1 * t]);
    let tr = |c: [f64; 2], t: f64| (c[0] > 1.0 + 1e-9 && c[1] > 1.0 + 1e-9).then_some([0.1 * t, 0.1 * t]);
    let line: &[([f64; 2], [f64; 2])] = &[([0.0, 1.0], [1.0, 1.0]), ([1.0, 1.0], [2.0, 1.0])];
    let r = cohesive_square_opened(&[line, &[([1.0, 1.0], [1.0, 2.0])]], &[&tl, &tr]);
    eprintln!("two faces at a node: {r:?}");
    let gf = 0.01;
    assert!(rel(r[1].1, 3.0) < 1e-12, "face area {}", r[1].1);
    assert!(rel(r[0].0, 2.0 * gf) < 1e-9, "after phase 1: fracture {:.9e} against 2 G_f", r[0].0);
    assert!(rel(r[0].2[0], 1.0) < 1e-12 && r[0].2[1] == 0.0, "after phase 1: zones {:?} (the right half intact)", r[0].2);
    assert!(rel(r[1].0, 3.0 * gf) < 1e-9, "after phase 2: fracture {:.9e} against 3 G_f", r[1].0);
    assert_eq!(r[1].2, [0.0; 3]);
}

/// Review r17 (the stable step across bonded cracks): a crack carries its faces in compression
/// by its bonds alone. The square's mid-height line is cut through (two edges, four bonded
/// ends, bond area 2 x thickness 1) and the upper half is pressed down by d = 1e-3 (a ramp over
/// 400 steps, driven through `Contact::compute`). Reference: the `cohesive` law's penalty in
/// compression, k_n per unit area over the crack's faces once (module doc of
/// `plugins/src/contact/cohesive.rs`: `k_n A max(-gap, 0)`), so the upper half is pushed up by
/// k_n x 2 x d = 20, to 1e-9. Before the fix the upper nodes' contact search also paired them
/// with the lower faces that the bonds hold (their bonds' slaves are the lower nodes), a second
/// spring over the same faces: 2 k_n x 2 x d = 40, and on a crack whose bonds alternate sides
/// a node pair carried 3 k A against the 2 k A that `Contact::omega2` assumes.
#[test]
fn a_closed_bonded_crack_is_pressed_by_its_bonds_alone() {
    let line: &[([f64; 2], [f64; 2])] = &[([0.0, 1.0], [1.0, 1.0]), ([1.0, 1.0], [2.0, 1.0])];
    let (mut s, centre, x0) = cohesive_square(&[line]);
    let nc = x0.len();
    let law = s.scene.file.contact.as_ref().unwrap().law.as_ref();
    let c = s.contact.as_mut().unwrap();
    assert_eq!(c.bonds.len(), 4, "one bond per cut edge end");
    let (n, d, k) = (400usize, 1e-3, 1e4);
    let mut u = vec![[0.0; 2]; nc];
    let mut f = vec![[0.0; 2]; nc];
    for i in 1..=n {
        let t = i as f64 / n as f64;
        let un: Vec<[f64; 2]> = (0..nc).map(|cl| if centre[cl][1] > 1.0 { [0.0, -d * t] } else { [0.0; 2] }).collect();
        let v: Vec<[f64; 2]> = (0..nc).map(|cl| [un[cl][0] - u[cl][0], un[cl][1] - u[cl][1]]).collect();
        u = un;
        c.compute(law, &x0, &u, &v, 1.0, &mut f);
    }
    let up: f64 = (0..nc).filter(|&cl| centre[cl][1] > 1.0).map(|cl| f[cl][1]).sum();
    let down: f64 = (0..nc).filter(|&cl| centre[cl][1] < 1.0).map(|cl| f[cl][1]).sum();
    eprintln!("pressed crack: force on the upper half {up}, lower half {down}, pairs {}", c.n_active);
    assert!(rel(up, k * 2.0 * d) < 1e-9, "upper half pushed by {up} against k_n x 2 x d = {}", k * 2.0 * d);
    assert!(rel(-down, up) < 1e-12, "momentum: {down} against {up}");
}

/// Checks the contact's Verlet list after every split and at every history row.
struct VerletWatch {
    checked: usize,
    patched_checks: usize,
}

impl flem_core::solver::Observer for VerletWatch {
    fn history(&mut self, sim: &Simulation, _stage: usize) -> flem_core::Result<()> {
        self.check(sim, "history row");
        Ok(())
    }
    fn splits(&mut self, sim: &Simulation, _rec: &flem_core::mesh::topology::SplitRecord, _ev: &[flem_core::cracking::SplitEvent]) -> flem_core::Result<()> {
        self.check(sim, "split");
        Ok(())
    }
}

impl VerletWatch {
    fn check(&mut self, sim: &Simulation, at: &str) {
        let c = sim.contact.as_ref().unwrap();
        if let Some(m) = c.verlet_list_mismatch(&sim.x0) {
            panic!("step {} ({at}): the Verlet list is not a full build's: {m}", sim.state.step);
        }
        // Session 36: the held faces and the bonds' slaves, kept between splits, against a
        // recomputation.
        if let Some(m) = c.cache_mismatch(&sim.model) {
            panic!("step {} ({at}): {m}", sim.state.step);
        }
        self.checked += 1;
        if c.patches > 0 {
            self.patched_checks += 1;
        }
    }
}

/// Checks the contact search's caches at every split and after every step
/// (`Contact::cache_mismatch`), and counts the steps in which bonds were removed (opened past
/// `delta_f`, which refreshes `held` outside a split).
struct CacheWatch {
    checked: usize,
    most_bonds: usize,
    last_bonds: usize,
    removals: usize,
}

impl CacheWatch {
    fn check(&mut self, sim: &Simulation, at: &str) {
        let c = sim.contact.as_ref().unwrap();
        if let Some(m) = c.cache_mismatch(&sim.model) {
            panic!("step {} ({at}): {m}", sim.state.step);
        }
        self.checked += 1;
        self.most_bonds = self.most_bonds.max(c.bonds.len());
    }
}

impl flem_core::solver::Observer for CacheWatch {
    fn splits(&mut self, sim: &Simulation, _rec: &flem_core::mesh::topology::SplitRecord, _ev: &[flem_core::cracking::SplitEvent]) -> flem_core::Result<()> {
        self.check(sim, "split");
        self.last_bonds = sim.contact.as_ref().unwrap().bonds.len();
        Ok(())
    }
    fn should_stop(&mut self, sim: &Simulation) -> bool {
        let n = sim.contact.as_ref().map_or(0, |c| c.bonds.len());
        if n < self.last_bonds {
            self.removals += 1;
        }
        self.last_bonds = n;
        self.check(sim, "step");
        false
    }
}

/// The contact search keeps, between splits, which faces a bond holds at each end and each
/// bond's slave node (session 36: asked of the topology only at the points a split touched).
/// On the branching plate (configs/dynamic/branching_h0.5.toml to 20 us: the crack's first
/// three hundred splits, in a band where points split again after their bonds were made, and
/// bonds that open) both must be what a recomputation gives after every split and every step
/// (`Contact::cache_mismatch`). Reference: the
/// definitions (`bonded`, the topology's clusters); tolerance: none.
#[test]
fn contact_caches_follow_the_splits_of_a_running_crack() {
    let dir = crate::common::root().join("configs/dynamic");
    let text = std::fs::read_to_string(dir.join("branching_h0.5.toml")).unwrap().replace("end_time = 80e-6", "end_time = 20e-6");
    let scene = flem_core::scene::Scene::from_str(&text, &dir.join("branching_h0.5.toml"), &dir).unwrap_or_else(|e| panic!("{e}"));
    let mut s = Simulation::new(scene).unwrap();
    let mut w = CacheWatch { checked: 0, most_bonds: 0, last_bonds: 0, removals: 0 };
    s.run(&mut w).unwrap();
    eprintln!("{} checks, up to {} bonds, bonds removed in {} steps", w.checked, w.most_bonds, w.removals);
    assert!(w.most_bonds >= 100 && w.removals >= 3, "the run must bond and open bonds: up to {} bonds, removals in {} steps", w.most_bonds, w.removals);
}

/// The local update of the Verlet list at splits (cohesive laws, session 18,
/// `Contact::patch_verlet`) against a full build (review r18: there was no such check). The
/// notched plate of configs/verification/notched_crack.toml with cohesive contact on the crack
/// faces grows its crack under a rising load; after every split and at every history row the
/// list must be exactly what a full build gives at the same build configuration and margin
/// (`Contact::verlet_list_mismatch`: brute force over every slave and face, no grid); and the
/// faces held by bonds and the bonds' slaves, kept between splits since session 36, must be
/// what a recomputation gives (`Contact::cache_mismatch`).
/// Reference: the definition of the list (every face within the margin of each slave, face
/// order), of `held` (`bonded`) and of a bond's slave (the topology); tolerance: none.
#[test]
fn verlet_list_patched_at_splits_is_a_full_build() {
    let path = crate::common::root().join("configs/verification/notched_crack.toml");
    let base = std::fs::read_to_string(path).unwrap();
    // The default skin (0.2 of the mean face) and a skin of three elements (1/6 each), with
    // which a new face lies within the margin of slaves that the split does not touch (the
    // list must then gain it for them).
    for (name, skin) in [("default", ""), ("0.5", "\nskin = 0.5")] {
        let text = format!(
            "{base}\n[contact]\nlaw = {{ type = \"cohesive\", normal_stiffness = 2000.0, shear_stiffness = 800.0, tensile_strength = 0.5, fracture_energy = 0.005, friction = 0.5 }}{skin}\n\n[[stage]]\nname = \"more\"\nlevels = {{ pull = 0.6 }}\nmax_steps = 30000\n"
        );
        let mut s = sim(&text);
        let mut w = VerletWatch { checked: 0, patched_checks: 0 };
        s.run(&mut w).unwrap_or_else(|e| panic!("skin {name}: {e}"));
        let c = s.contact.as_ref().unwrap();
        eprintln!("skin {name}: {} checks, {} after a local update; {} patches, {} full builds", w.checked, w.patched_checks, c.patches, c.rebuilds);
        assert!(c.patches >= 3, "skin {name}: the run must update its list locally at splits: {} patches", c.patches);
        assert!(w.patched_checks >= 3, "skin {name}: the checks must see patched lists: {}", w.patched_checks);
    }
}

/// Kalthoff-Winkler on the crack-path method (issue 36 must-shows 1 and 3 with issue 34's
/// `tip_mts`, ours: configs/dynamic/kalthoff_h1_path.toml, the whole 80 us). References: the
/// experiments' crack at about 70 deg to the notch line (Kalthoff & Winkler 1987), the issue's
/// band 60 to 72 deg for the mean angle of the split points 10 to 20 mm from the notch tip (the
/// measure of tools/dynamic_tables.py's `angle_splits`); no split at x < 30 mm (no tensile crack
/// from the compressed impact zone); the cohesive law releases G_c per area of traction-free
/// face (Hillerborg et al. 1976): fracture / (G_c x free faces) within 5 %; the ledger closes to
/// 1e-4 of the work (must-show 3: 1e-3) with the path method's node moves booked as `relocation` (without that term
/// the residual is above 1e-3: the moves put energy into the discrete system, and the test
/// fails if the booking is lost); the crack runs at least 60 mm (session 14's run of this rule
/// stopped after 10.8 mm).
#[test]
fn kalthoff_on_the_path_method_kinks_at_the_experiments_angle() {
    let path = crate::common::root().join("configs/dynamic/kalthoff_h1_path.toml");
    let dir = crate::ckpt::tmp("kalthoff-path");
    let mut s = Simulation::new(flem_core::scene::Scene::from_file(&path).unwrap()).unwrap();
    let mut w = flem_core::output::OutputWriter::new(&dir, &s).unwrap();
    s.run(&mut w).unwrap();
    w.write_summary(&s, 0.0).unwrap();
    drop(w);
    let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    let splits = std::fs::read_to_string(dir.join("splits.csv")).unwrap();
    let head: Vec<&str> = splits.lines().next().unwrap().split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).unwrap();
    let (cx, cy) = (col("x"), col("y"));
    let tip = [0.05, 0.025];
    let pts: Vec<[f64; 2]> = splits
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            [f[cx].parse::<f64>().unwrap(), f[cy].parse::<f64>().unwrap()]
        })
        .collect();
    let near: Vec<f64> = pts.iter().filter(|p| (0.010..=0.020).contains(&(p[0] - tip[0]).hypot(p[1] - tip[1]))).map(|p| (p[1] - tip[1]).atan2(p[0] - tip[0]).to_degrees()).collect();
    let angle = near.iter().sum::<f64>() / near.len() as f64;
    let reach = pts.iter().map(|p| (p[0] - tip[0]).hypot(p[1] - tip[1])).fold(0.0, f64::max);
    let impact = pts.iter().filter(|p| p[0] < 0.03).count();
    let e = &summary["energy"];
    let (work, resid, reloc) = (e["external_work"].as_f64().unwrap(), e["relative_residual"].as_f64().unwrap(), e["relocation"].as_f64().unwrap());
    let ratio = summary["fracture_account"]["fracture_over_g_f_free"].as_f64().unwrap();
    eprintln!(
        "angle {angle:.2} deg over {} splits, reach {:.1} mm, {impact} splits at x < 30 mm, fracture / (G_c free) {ratio:.4}, residual {resid:.2e}, relocation {reloc:.4e} ({:.2e} of the work)",
        near.len(),
        1e3 * reach,
        reloc / work
    );
    assert!(near.len() >= 4 && (60.0..=72.0).contains(&angle), "mean angle {angle} deg over {} splits", near.len());
    assert!(reach > 0.060, "the crack reached {reach} m from the notch tip");
    assert_eq!(impact, 0, "splits in the impact zone");
    assert!((ratio - 1.0).abs() < 0.05, "fracture / (G_c free) = {ratio}");
    // Must-show 3 asks 1e-3; measured 2.7e-6 (3.6e-5 at most over the settings study): 1e-4
    // catches a booking wrong by a few per cent of the term (6.4e-3 of the work).
    assert!(resid <= 1e-4, "ledger residual {resid:e}");
    assert!(reloc.abs() > 1e-3 * work, "relocation {reloc:e} against the work {work:e}: the moves should be booked");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The fork of the path method through the cracking check (ours, session 31: `tip_mts`
/// `fork_ratio`, `TipPlan::fork`; experimental). The branching plate (h = 0.5 mm) at sigma_c =
/// 6 MPa, to 29 us. Reference: the run of docs/dynamic.md "Session 31", whose first fork is at
/// x = 65.96 mm at 27.9 us, and the definition of a fork. Checked:
/// - one cut of three edges (the face and two links) at a point 60-70 mm from the left edge,
///   on the notch's line within 1 mm;
/// - the check's tip lines hold the two branches' lines from that point, at `+- fork_angle_deg`
///   from each other's mean;
/// - both branches were cut through their far points, and at least two tips lie beyond the fork;
/// - the ledger closes to 1e-4 of the work;
/// - (session 32) the same run on the mesh mirrored about the notch's line (y -> 0.04 - y, the
///   triangles' corners reordered, the top and bottom edge sets swapped) is the mirror image of
///   this one: the same splits at the same steps, at mirrored points within 1e-9 m, through
///   the fork. Reference: the equations are symmetric about y = 0.02, so no part of the check,
///   the rule or the fork may prefer a side (docs/dynamic.md "Session 32": which branch arrests
///   is set by the mesh). Fails when one branch's angle or link choice is biased (checked:
///   `dir - 0.9 a` for the lower branch). The 1e-9 m allows the round-off of `0.04 - y` and of
///   sums taken in another order (measured: 7e-13 m to 29 us, 5e-10 m to 80 us). Round-off can
///   also move a marginal split by a step (docs/dynamic.md "Session 32", the symmetric mesh):
///   after a change that should move only round-off, look there first if this part fails.
#[test]
fn a_fast_tip_forks_in_the_explicit_march() {
    let splits = fork_run("fork", "dynamic/branching_h0.5.msh", fork_checks);
    let mirror = crate::ckpt::tmp("fork-mirror-mesh");
    std::fs::create_dir_all(&mirror).unwrap();
    let msh = mirror.join("branching_h0.5_mirrored.msh");
    let src = std::fs::read_to_string(crate::common::root().join("configs/dynamic/branching_h0.5.msh")).unwrap();
    std::fs::write(&msh, mirrored_msh(&src, 0.04)).unwrap();
    let msplits = fork_run("fork-mirrored", msh.to_str().unwrap(), |_, _| {});
    let rows = |t: &str| -> Vec<(u64, f64, f64)> {
        let head: Vec<&str> = t.lines().next().unwrap().split(',').collect();
        let col = |name: &str| head.iter().position(|h| *h == name).unwrap();
        let (cs, cx, cy) = (col("step"), col("x"), col("y"));
        t.lines().skip(1).map(|l| l.split(',').collect::<Vec<_>>()).map(|f| (f[cs].parse().unwrap(), f[cx].parse().unwrap(), f[cy].parse().unwrap())).collect()
    };
    let (a, b) = (rows(&splits), rows(&msplits));
    assert_eq!(a.len(), b.len(), "as many splits on the mirrored mesh");
    for (i, (p, q)) in a.iter().zip(&b).enumerate() {
        assert!(p.0 == q.0 && (p.1 - q.1).abs() < 1e-9 && (p.2 - (0.04 - q.2)).abs() < 1e-9, "split {i}: {p:?} against the mirrored run's {q:?}");
    }
    let _ = std::fs::remove_dir_all(&mirror);
}

/// A gmsh 4.1 ASCII mesh mirrored about `y = height / 2`, for FLEM's reader (which reads the
/// tags, not the entities' geometry): each node's y becomes `height - y`, each triangle's
/// (quadrangle's) corners are listed in reverse after the first, so the elements keep their
/// counter-clockwise order, and the physical names "top" and "bottom" are swapped, so that the
/// scene's loads act on the mirrored edges. `$Entities` (bounding boxes) and the other names are
/// copied as they are. Node blocks with parametric coordinates are refused (a panic: a test
/// helper).
fn mirrored_msh(src: &str, height: f64) -> String {
    let lines: Vec<&str> = src.lines().collect();
    let mut out: Vec<String> = Vec::with_capacity(lines.len());
    let mut i = 0;
    let num = |l: &str, k: usize| -> usize { l.split_whitespace().nth(k).unwrap().parse().unwrap() };
    while i < lines.len() {
        let l = lines[i];
        out.push(l.replace("\"bottom\"", "\"@\"").replace("\"top\"", "\"bottom\"").replace("\"@\"", "\"top\""));
        i += 1;
        if l == "$Nodes" || l == "$Elements" {
            let blocks = num(lines[i], 0);
            out.push(lines[i].to_string());
            i += 1;
            for _ in 0..blocks {
                let (ty, n) = (num(lines[i], 2), num(lines[i], 3));
                assert!(l != "$Nodes" || ty == 0, "a node block with parametric coordinates: {}", lines[i]);
                out.push(lines[i].to_string());
                i += 1;
                if l == "$Nodes" {
                    out.extend(lines[i..i + n].iter().map(|s| s.to_string()));
                    i += n;
                    for c in &lines[i..i + n] {
                        let v: Vec<f64> = c.split_whitespace().map(|t| t.parse().unwrap()).collect();
                        out.push(format!("{:e} {:e} {:e}", v[0], height - v[1], v[2]));
                    }
                } else {
                    for c in &lines[i..i + n] {
                        let mut f: Vec<&str> = c.split_whitespace().collect();
                        if ty == 2 || ty == 3 {
                            f[2..].reverse();
                        }
                        out.push(f.join(" "));
                    }
                }
                i += n;
            }
        }
    }
    out.join("\n")
}

/// The branching plate at 6 MPa with `tip_mts` `fork_ratio = 1.5` to 29 us on `mesh` (relative
/// to configs/ or absolute), in a temporary folder `name`; `checks` reads the finished run and
/// its output folder. The run's splits.csv.
fn fork_run(name: &str, mesh: &str, checks: impl Fn(&Simulation, &std::path::Path)) -> String {
    let text = std::fs::read_to_string(crate::common::root().join("configs/dynamic/branching_h0.5.toml"))
        .unwrap()
        .replace("file = \"branching_h0.5.msh\"", &format!("file = \"{mesh}\""))
        .replace("tensile_strength = 3e6", "tensile_strength = 6e6")
        .replace("type = \"sigma1_nearest\"", "type = \"tip_mts\"\nfork_ratio = 1.5")
        .replace("end_time = 80e-6", "end_time = 29e-6");
    let mut s = crate::common::sim(&text);
    let dir = crate::ckpt::tmp(name);
    let mut w = flem_core::output::OutputWriter::new(&dir, &s).unwrap();
    s.run(&mut w).unwrap();
    w.write_summary(&s, 0.0).unwrap();
    drop(w);
    checks(&s, &dir);
    let splits = std::fs::read_to_string(dir.join("splits.csv")).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    splits
}

/// The checks of `a_fast_tip_forks_in_the_explicit_march` on the run on the committed mesh.
fn fork_checks(s: &Simulation, dir: &std::path::Path) {
    let splits = std::fs::read_to_string(dir.join("splits.csv")).unwrap();
    let head: Vec<&str> = splits.lines().next().unwrap().split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).unwrap();
    let (cx, cy, ce, cp) = (col("x"), col("y"), col("edges"), col("point"));
    let forks: Vec<(f64, f64, u32)> = splits
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|f| f[ce].split_whitespace().count() == 3)
        .map(|f| (f[cx].parse().unwrap(), f[cy].parse().unwrap(), f[cp].parse().unwrap()))
        .collect();
    assert!(!forks.is_empty(), "no fork by 29 us");
    let (x, y, p) = forks[0];
    eprintln!("first fork at ({:.2}, {:.2}) mm, {} fork cuts", 1e3 * x, 1e3 * y, forks.len());
    assert!((0.060..=0.070).contains(&x) && (y - 0.02).abs() < 1e-3, "first fork at ({x}, {y})");
    let cr = s.cracking.as_ref().unwrap();
    let xp = s.model.mesh.points[p as usize];
    let from: Vec<&flem_core::cracking::path::TipLine> = cr.path.lines.iter().filter(|l| (l.origin[0] - xp[0]).hypot(l.origin[1] - xp[1]) < 1e-12).collect();
    assert!(from.len() >= 2, "two lines from the fork point: {from:?}");
    let gap = (from[0].dir - from[1].dir).abs().to_degrees();
    assert!((gap - 30.0).abs() < 1e-9, "the branches' lines are 2 x 15 deg apart: {gap}");
    // Both branches were cut through their far points (each has split since), and the crack
    // has at least two tips beyond the fork.
    for l in &from[..2] {
        assert!(s.model.topo.point_clusters[l.point as usize].len() > 1, "branch end {} has split", l.point);
    }
    let tips = flem_core::cracking::path::tips(&s.model.topo, &s.model.mesh.points);
    let beyond = tips.iter().filter(|t| s.model.mesh.points[t.point.idx()][0] > x).count();
    assert!(beyond >= 2, "{beyond} tips beyond the fork");
    let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    let resid = summary["energy"]["relative_residual"].as_f64().unwrap();
    assert!(resid.abs() < 1e-4, "ledger residual {resid}");
}
