//! Contact in 3D (issue 38 must-show 4: `flem_core::contact::contact3`, docs/3d.md "Contact
//! (3D)") against analytic references: a block on an inclined face sticks below the friction
//! angle and slides above it with Coulomb's acceleration; a block dropped onto a base does not
//! pass through it; the drop's energy ledger creates no energy. References and tolerances at
//! each test. The meshes are built here (boxes of bricks or tetrahedra, a shear map for the
//! incline), the interface declared as a face set.
use std::collections::BTreeMap;
use std::path::Path;

use flem_core::contact::ContactCfg;
use flem_core::mesh::{cell_face, Box3, CellKind3, RawMesh3, ValidationOptions};
use flem_core::plugin::damping::Damping;
use flem_core::scene3::Scene3;
use flem_core::solver::march3::{March3, Support3};

/// A box of `n` cells of `kind` at `origin`, its cells in region `region`, its side face and
/// node sets named `{prefix}_{side}`.
fn block(origin: [f64; 3], size: [f64; 3], n: [usize; 3], kind: CellKind3, region: &str, prefix: &str) -> RawMesh3 {
    let mut b = Box3::new(size, n, kind);
    b.origin = origin;
    let mut m = b.build().unwrap();
    m.cell_region = vec![region.to_string(); m.cells.len()];
    m.face_sets = std::mem::take(&mut m.face_sets).into_iter().map(|(k, v)| (format!("{prefix}_{k}"), v)).collect();
    m.node_sets = std::mem::take(&mut m.node_sets).into_iter().map(|(k, v)| (format!("{prefix}_{k}"), v)).collect();
    m
}

/// Two meshes as one (the second's points after the first's).
fn merge(mut a: RawMesh3, b: RawMesh3) -> RawMesh3 {
    let off = a.points.len() as u32;
    a.points.extend(b.points);
    for mut c in b.cells {
        let n = c.kind.nodes();
        for x in &mut c.nodes[..n] {
            *x += off;
        }
        a.cells.push(c);
    }
    a.cell_region.extend(b.cell_region);
    for (k, v) in b.node_sets {
        a.node_sets.insert(k, v.into_iter().map(|p| p + off).collect());
    }
    for (k, v) in b.face_sets {
        a.face_sets.insert(
            k,
            v.into_iter()
                .map(|mut f| {
                    for x in f.0.iter_mut().filter(|x| **x != flem_core::mesh::NO_CORNER) {
                        *x += off;
                    }
                    f
                })
                .collect(),
        );
    }
    a.source = "tests/contact3.rs".into();
    a
}

fn damping(name: &str) -> Box<dyn Damping> {
    flem_plugins::link();
    toml::from_str(&format!("type = \"{name}\"")).unwrap()
}

fn contact_cfg(text: &str) -> ContactCfg {
    flem_plugins::link();
    toml::from_str(text).unwrap()
}

/// A body of one linear elastic material (`E`, `nu`, `rho`; h8 bricks, t4 tetrahedra).
fn body(mut mesh: RawMesh3, e: f64, nu: f64, rho: f64, supports: &[Support3], damp: &str, safety: f64) -> March3 {
    mesh.validate(ValidationOptions::Reorient).unwrap();
    let kinds: BTreeMap<String, String> = mesh.cells.iter().zip(&mesh.cell_region).map(|(c, r)| (r.clone(), if c.kind == CellKind3::H8 { "h8".to_string() } else { "t4".to_string() })).collect();
    let material_of = |r: &str| Ok(([e, nu, rho], kinds.get(r).cloned()));
    March3::new(mesh, &material_of, supports, damping(damp), safety).unwrap()
}

/// Mass-weighted mean displacement and velocity of the clusters of the elements in `cells`.
fn mean_motion(m: &March3, in_part: &dyn Fn(usize) -> bool) -> ([f64; 3], [f64; 3]) {
    let mut seen = vec![false; m.topo.n_clusters()];
    for (k, e) in m.topo.copy_elem.iter().enumerate() {
        if in_part(e.idx()) {
            seen[m.topo.copy_cluster[k].idx()] = true;
        }
    }
    let (mut mu, mut mv, mut mm) = ([0.0; 3], [0.0; 3], 0.0);
    for c in (0..seen.len()).filter(|&c| seen[c]) {
        let w = m.state.mass[c];
        for d in 0..3 {
            mu[d] += w * m.state.u[c][d];
            mv[d] += w * m.state.v[c][d];
        }
        mm += w;
    }
    (mu.map(|x| x / mm), mv.map(|x| x / mm))
}

/// The incline: a box 1 x 1 x 1 of 4 x 2 x 2 bricks cut in two at z = 0.5 (the interface face
/// set `interface`, separated), sheared `z' = z + x tan(theta)` so that the interface is a
/// plane inclined by `theta` about y. The lower block is held at its bottom; the upper block
/// rests on the interface under gravity `g` along -z, ramped in over `ramp` (a smooth cosine,
/// so that the elastic transient is small), and marched without damping (the contact's
/// dashpots damp the contact modes). Returns (times, the upper block's mean displacement and
/// velocity down the slope) and the block's mean normal displacement at the end.
fn incline(kind: CellKind3, theta: f64, mu: f64, ramp: f64, t_end: f64, every: usize) -> (Vec<(f64, f64, f64)>, f64) {
    let g = 10.0;
    let mut mesh = block([0.0; 3], [1.0, 1.0, 1.0], [4, 2, 2], kind, "all", "box");
    let mid: Vec<usize> = (0..mesh.cells.len()).filter(|&e| mesh.cells[e].corners().iter().all(|&p| mesh.points[p as usize][2] <= 0.5 + 1e-12)).collect();
    let on_mid = |p: &u32| (mesh.points[*p as usize][2] - 0.5).abs() < 1e-12;
    let iface = mid.iter().flat_map(|&e| kind.faces().iter().map(move |l| (e, l))).map(|(e, l)| cell_face(&mesh.cells[e], l)).filter(|f| f.corners().iter().all(on_mid)).collect();
    mesh.face_sets.insert("interface".into(), iface);
    let upper: Vec<bool> = (0..mesh.cells.len()).map(|e| !mid.contains(&e)).collect();
    let t = theta.tan();
    for p in &mut mesh.points {
        p[2] += p[0] * t;
    }
    let bottom = mesh.node_sets["box_zmin"].clone();
    let mut m = body(mesh, 1e5, 0.25, 1.0, &[Support3 { points: bottom, fix: 7, velocity: [0.0; 3] }], "none", 0.9);
    m.separate_face_set("interface").unwrap();
    let cfg = contact_cfg(&format!(
        "law = {{ type = \"spring_dashpot\", normal_stiffness = 1e5, shear_stiffness = 1e5, normal_damping = 100.0, shear_damping = 100.0, friction = {mu} }}\nsurfaces = [\"interface\"]\ncrack_faces = false"
    ));
    m.attach_contact(cfg, "incline", None, 0.9, false).unwrap();
    let down = [-theta.cos(), 0.0, -theta.sin()];
    let normal = [-theta.sin(), 0.0, theta.cos()];
    let steps = (t_end / m.dt).ceil() as usize;
    let mut out = Vec::new();
    for k in 0..steps {
        // The level at the step's middle (the first step has gravity: a body at rest with no
        // work done yet and round-off contact forces would trip the divergence guard).
        let time = m.state.time + 0.5 * m.dt;
        let level = if time < ramp { 0.5 * (1.0 - (std::f64::consts::PI * time / ramp).cos()) } else { 1.0 };
        if m.gravity[2] != -g * level {
            m.gravity = [0.0, 0.0, -g * level];
            m.rebuild_forces();
        }
        m.step().unwrap();
        if k % every == 0 || k + 1 == steps {
            let (u, v) = mean_motion(&m, &|e| upper[e]);
            out.push((m.state.time, u[0] * down[0] + u[2] * down[2], v[0] * down[0] + v[2] * down[2]));
        }
    }
    let (u, _) = mean_motion(&m, &|e| upper[e]);
    (out, u[0] * normal[0] + u[2] * normal[2])
}

/// Least-squares slope of `(t, y)` pairs.
fn slope(pts: &[(f64, f64)]) -> f64 {
    let n = pts.len() as f64;
    let (mt, my) = (pts.iter().map(|p| p.0).sum::<f64>() / n, pts.iter().map(|p| p.1).sum::<f64>() / n);
    pts.iter().map(|p| (p.0 - mt) * (p.1 - my)).sum::<f64>() / pts.iter().map(|p| (p.0 - mt).powi(2)).sum::<f64>()
}

/// A block on an inclined face (the paper's spring_dashpot law, mu = 0.5) just below and just
/// above the friction angle: `tan(theta) = 0.98 mu` sticks, `1.02 mu` slides (issue 38
/// must-show 4: the analytic threshold `tan(theta) = mu` within 2 %). Reference: Coulomb's law
/// for a rigid block on a plane. Stick: after the ramp the block's mean velocity down the slope
/// stays below 1e-3 of the slide's (creep, none for a Coulomb stick) and its displacement
/// below 20 x the elastic shear estimate `m g sin(theta) / (k_s A)`. Slide: its acceleration
/// down the slope (least squares on the mean velocity after the ramp) is
/// `g (sin(theta) - mu cos(theta))` within 10 % (a difference of two terms 50 x larger: 10 %
/// of it is 0.2 % of the friction force).
#[test]
fn block_on_an_incline_sticks_below_and_slides_above_the_friction_angle() {
    let (mu, g) = (0.5, 10.0);
    let (ramp, t_end) = (0.2, 1.2);
    let mut accel = Vec::new();
    for (ratio, slides) in [(0.98, false), (1.02, true)] {
        let theta = (ratio * mu as f64).atan();
        let (hist, un) = incline(CellKind3::H8, theta, mu, ramp, t_end, 20);
        let after: Vec<(f64, f64)> = hist.iter().filter(|h| h.0 > ramp + 0.1).map(|h| (h.0, h.2)).collect();
        let a = slope(&after);
        let a_ref = g * (theta.sin() - mu * theta.cos());
        let (_, s_end, v_end) = *hist.last().unwrap();
        let elastic = 0.5 * g * theta.sin() / 1e5;
        eprintln!("tan(theta) = {ratio} mu: acceleration {a:.5e} (Coulomb {a_ref:.5e}), displacement down the slope {s_end:.4e} (elastic estimate {elastic:.2e}), velocity {v_end:.3e}, normal displacement {un:.3e}");
        if slides {
            assert!((a - a_ref).abs() <= 0.1 * a_ref.abs(), "sliding: acceleration {a:.5e}, Coulomb {a_ref:.5e}");
            assert!(s_end > 100.0 * elastic, "sliding: displacement {s_end:.3e}");
            accel.push(a);
        } else {
            let v_slide = g * 0.02 * mu * theta.cos() * (t_end - ramp);
            assert!(v_end.abs() < 1e-3 * v_slide, "sticking: velocity {v_end:.3e} (a slide would reach {v_slide:.3e})");
            assert!(s_end.abs() < 20.0 * elastic, "sticking: displacement {s_end:.3e}, elastic {elastic:.3e}");
        }
        // Resting on the face: pressed in by about its weight / (k_n A), not through it.
        assert!(un < 0.0 && un.abs() < 5.0 * 0.5 * g / 1e5, "normal displacement {un:.3e}");
    }
}

/// The same incline well above the friction angle (`tan(theta) = 1.5 mu`), on bricks (bilinear
/// master faces) and on tetrahedra (triangles, six per brick): the block slides with
/// `g (sin(theta) - mu cos(theta))`, also across the edges of the faces below it (it slides
/// more than a face's length, 0.25). Reference: Coulomb's law for a rigid block; 2 %.
#[test]
fn block_slides_down_a_steep_incline_with_coulomb_acceleration() {
    let (mu, g) = (0.5, 10.0);
    let theta = (1.5 * mu as f64).atan();
    for kind in [CellKind3::H8, CellKind3::T4] {
        let (hist, _) = incline(kind, theta, mu, 0.1, 0.6, 10);
        let after: Vec<(f64, f64)> = hist.iter().filter(|h| h.0 > 0.2).map(|h| (h.0, h.2)).collect();
        let a = slope(&after);
        let a_ref = g * (theta.sin() - mu * theta.cos());
        let s_end = hist.last().unwrap().1;
        eprintln!("{kind:?}: tan(theta) = 1.5 mu: acceleration {a:.5e} (Coulomb {a_ref:.5e}, {:+.3} %), slid {s_end:.3}", 100.0 * (a / a_ref - 1.0));
        assert!(s_end > 0.3, "{kind:?}: slid {s_end}: less than a face");
        assert!((a - a_ref).abs() <= 0.02 * a_ref, "{kind:?}: acceleration {a:.5e}, Coulomb {a_ref:.5e}");
    }
}

/// The drop: a base 1 x 1 x 0.25 of 4 x 4 x 1 bricks held at its bottom, and a block 0.5 x 0.5 x
/// 0.25 of tetrahedra (2 x 2 x 2 bricks, six each) 0.05 above it, falling under gravity 10;
/// contact on every boundary face (`boundary = true`). Returns the body after `t_end` and the
/// largest penetration of a block point below the base's top surface (bilinear between the
/// base's top points at their current positions, independent of the contact code) seen
/// every step.
fn drop(law: &str, damp: &str, t_end: f64) -> (March3, f64, f64) {
    let (mut m, nb) = drop_body(law, damp);
    let top: Vec<u32> = m.mesh.node_sets["base_zmax"].clone();
    // The base's top points on the 5 x 5 grid (x, y = 0.25 i, 0.25 j).
    let mut grid = [[0u32; 5]; 5];
    for &p in &top {
        let x = m.mesh.points[p as usize];
        grid[(x[0] / 0.25).round() as usize][(x[1] / 0.25).round() as usize] = p;
    }
    let mut pen_max: f64 = 0.0;
    let steps = (t_end / m.dt).ceil() as usize;
    for _ in 0..steps {
        m.step().unwrap();
        for p in nb..m.mesh.points.len() {
            let c = m.topo.point_clusters[p][0].idx();
            let x: [f64; 3] = std::array::from_fn(|d| m.mesh.points[p][d] + m.state.u[c][d]);
            let (fx, fy) = ((x[0] / 0.25).clamp(0.0, 3.999), (x[1] / 0.25).clamp(0.0, 3.999));
            let (i, j) = (fx.floor() as usize, fy.floor() as usize);
            let (s, t) = (fx - i as f64, fy - j as f64);
            let z = |a: usize, b: usize| {
                let q = grid[a][b] as usize;
                m.mesh.points[q][2] + m.state.u[q][2]
            };
            let zs = (1.0 - s) * (1.0 - t) * z(i, j) + s * (1.0 - t) * z(i + 1, j) + s * t * z(i + 1, j + 1) + (1.0 - s) * t * z(i, j + 1);
            pen_max = pen_max.max(zs - x[2]);
        }
    }
    let h = 0.125;
    (m, pen_max, h)
}

/// The body of [`drop`] and the number of the base's points (the block's come after them).
fn drop_body(law: &str, damp: &str) -> (March3, usize) {
    let base = block([0.0; 3], [1.0, 1.0, 0.25], [4, 4, 1], CellKind3::H8, "base", "base");
    let blk = block([0.25, 0.25, 0.3], [0.5, 0.5, 0.25], [2, 2, 2], CellKind3::T4, "block", "block");
    let nb = base.points.len();
    let mesh = merge(base, blk);
    let bottom = mesh.node_sets["base_zmin"].clone();
    let mut m = body(mesh, 1e5, 0.25, 1.0, &[Support3 { points: bottom, fix: 7, velocity: [0.0; 3] }], damp, 0.9);
    m.gravity = [0.0, 0.0, -10.0];
    m.rebuild_forces();
    let cfg = contact_cfg(&format!("law = {law}\nboundary = true"));
    m.attach_contact(cfg, "drop", None, 0.9, false).unwrap();
    (m, nb)
}

/// The contact state of a run (pairs and the Verlet list's build state, `Contact3::pairs`,
/// `verlet_state`) restored into a fresh body resumes the drop bit-identically (what a 3D
/// checkpoint needs from contact). Reference: the uninterrupted run; exact, every displacement
/// and the ledger's contact terms, 400 steps after a resume in the middle of the impact.
#[test]
fn contact_state_restores_bit_identically() {
    let law = "{ type = \"spring_dashpot\", normal_stiffness = 1e5, shear_stiffness = 1e5, friction = 0.5 }";
    let (mut a, _) = drop_body(law, "none");
    let n0 = (0.104 / a.dt) as usize;
    for _ in 0..n0 {
        a.step().unwrap();
    }
    let c = a.contact.as_ref().unwrap();
    assert!(!c.pairs.is_empty(), "the resume is in the impact");
    let (mut b, _) = drop_body(law, "none");
    b.state.u = a.state.u.clone();
    b.state.v = a.state.v.clone();
    b.state.time = a.state.time;
    b.state.step = a.state.step;
    b.ledger = a.ledger;
    let (pairs, verlet) = (c.pairs.clone(), c.verlet_state());
    b.contact.as_mut().unwrap().restore(&b.mesh, &b.topo, pairs, verlet);
    for _ in 0..400 {
        a.step().unwrap();
        b.step().unwrap();
    }
    assert!(a.state.u.iter().zip(&b.state.u).all(|(x, y)| x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits())));
    assert_eq!(a.ledger.contact_dissipated.to_bits(), b.ledger.contact_dissipated.to_bits());
    assert_eq!(a.contact.as_ref().unwrap().pairs, b.contact.as_ref().unwrap().pairs);
}

/// A block dropped onto a base (issue 38 must-show 4: no node passes through a face). The
/// paper's spring_dashpot law (k_n = k_s = 1e5 per unit area, mu = 0.5, no dashpots), no
/// damping. Reference: a rigid block of mass M landing at v0 = sqrt(2 g 0.05) = 1 m/s on a
/// spring k_n A (A = 0.25) sinks at most `v0 sqrt(M / (k_n A)) + M g / (k_n A)` = 1.6e-3 (the
/// elastic block spreads the impact: less); asserted: every block point stays above the
/// base's top surface but for 2.5 x that estimate (3 % of the block's element size 0.125), at
/// every step of 0.3 s (the fall, the impact, the rebound); and the block has landed (it fell
/// 0.05, bounced). The ledger of the same run creates no energy: its residual `W_ext - (KE + U
/// + E_contact + D_contact)` is above -1e-3 of the work of gravity (the explicit scheme's
/// impact loses a little: it credits the contact force's work by the trapezoid across the
/// step in which the gap closes, more than the spring stores) and its magnitude below 2 %.
#[test]
fn dropped_block_does_not_pass_through_the_base_and_creates_no_energy() {
    let (m, pen, h) = drop("{ type = \"spring_dashpot\", normal_stiffness = 1e5, shear_stiffness = 1e5, friction = 0.5 }", "none", 0.3);
    let mass: f64 = 0.5 * 0.5 * 0.25;
    let (v0, k) = ((2.0f64 * 10.0 * 0.05).sqrt(), 1e5 * 0.25);
    let est = v0 * (mass / k).sqrt() + mass * 10.0 / k;
    let l = &m.ledger;
    eprintln!(
        "drop (spring_dashpot): largest penetration {pen:.3e} ({:.2} % of h; rigid estimate {est:.3e}); ledger: W_ext {:.5e}, KE {:.5e}, U {:.5e}, E_contact {:.5e}, D_contact {:.5e}, residual {:.3e} ({:.3e} relative); {} contact rebuilds",
        100.0 * pen / h,
        l.external(),
        l.kinetic,
        l.strain,
        l.contact_energy,
        l.contact_dissipated,
        l.residual(),
        l.relative_residual(),
        m.contact.as_ref().unwrap().rebuilds
    );
    assert!(pen > 0.0 && pen < 2.5 * est && pen < 0.03 * h, "penetration {pen:.3e}, estimate {est:.3e}, h {h}");
    assert!(l.external() > 0.9 * mass * 10.0 * 0.05 * 0.5, "the block fell: work of gravity {:.3e}", l.external());
    assert!(l.residual() > -1e-3 * l.external(), "energy created: residual {:.3e} of {:.3e}", l.residual(), l.external());
    assert!(l.relative_residual() < 2e-2, "energy residual {:.3e}", l.relative_residual());
}

/// The same drop with the `penalty` law (ours: total gap, regularised friction) and the
/// paper's local damping: the block comes to rest on the base. Reference: statics, the block's
/// weight carried by the contact: at rest (unbalanced-force ratio below 1e-4) the sum of the
/// contact forces on the block's points is its weight `M g` within 1e-3 (the rest is the
/// ratio's imbalance), and nowhere is the block through the base (as above). `slip_velocity`
/// is 1e-2: the regularised friction is a dashpot `mu f_n / v_reg` per pair, and with 1e-4 it
/// exceeds the explicit step's bound on this light mesh (the nodes chatter at the step's
/// period, ratio stuck at 0.6; docs/3d.md, limits).
#[test]
fn dropped_block_comes_to_rest_on_its_weight() {
    let (m, pen, h) = drop("{ type = \"penalty\", normal_stiffness = 1e5, friction = 0.3, slip_velocity = 1e-2 }", "local", 1.0);
    let mass = 0.5 * 0.5 * 0.25;
    let c = m.contact.as_ref().unwrap();
    let nb = 25 * 2;
    let block_slave = |r: &&flem_core::contact::contact3::PairReport3| m.topo.cluster_point[r.slave as usize].idx() >= nb;
    let on_block: f64 = c.forces().iter().filter(block_slave).map(|r| r.force[2]).sum::<f64>() - c.forces().iter().filter(|r| !block_slave(r)).map(|r| r.force[2]).sum::<f64>();
    let w = mass * 10.0;
    eprintln!("drop (penalty, local damping): force on the block {on_block:.6e} (weight {w:.6e}); largest penetration {pen:.3e}; ratio {:.2e}; {} pairs", m.ratio, c.forces().len());
    assert!(m.ratio < 1e-4, "not at rest: ratio {:.3e}", m.ratio);
    assert!((on_block - w).abs() < 1e-3 * w, "contact force on the block {on_block:.6e}, weight {w:.6e}");
    assert!(pen < 0.03 * h, "penetration {pen:.3e}");
}

/// `[contact]` in a 3D scene: the docs' snippet (docs/3d.md "Contact (3D)") parses and
/// validates; a law without a 3D form (`cohesive`) is refused by name; without `[contact]` a
/// 3D body has no contact. Reference: the docs; exact.
#[test]
fn contact_section_of_a_3d_scene() {
    flem_plugins::link();
    let doc = std::fs::read_to_string(crate::common::root().join("docs/3d.md")).unwrap();
    let sec = doc.split("## Contact (3D)").nth(1).expect("docs/3d.md has a section \"Contact (3D)\"");
    let snippet = sec.split("```toml").nth(1).and_then(|s| s.split("```").next()).expect("a toml snippet in \"Contact (3D)\"");
    let scene = |contact: &str| {
        format!("[model]\ndim = 3\n[mesh]\ntype = \"box\"\nsize = [1.0, 1.0, 1.0]\nnx = 1\nny = 1\nnz = 1\n[[material]]\nyoung_modulus = 1.0\npoisson_ratio = 0.2\ndensity = 1.0\n[[stage]]\n{contact}")
    };
    let s = Scene3::from_str(&scene(snippet), Path::new("docs/3d.md"), &crate::common::root()).unwrap();
    assert!(s.file.contact.is_some());
    let err = Scene3::from_str(
        &scene("[contact]\nlaw = { type = \"cohesive\", normal_stiffness = 1e6, shear_stiffness = 4e5, tensile_strength = 1.0, fracture_energy = 0.01, friction = 0.577 }\n"),
        Path::new("s.toml"),
        &crate::common::root(),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("contact.law") && err.contains("no 3D form"), "{err}");
    let mut s = Scene3::from_str(&scene(""), Path::new("s.toml"), &crate::common::root()).unwrap();
    assert!(March3::from_scene(&mut s).unwrap().contact.is_none());
}

/// The scene of configs/3d/ runs (`flem run` reads it): the block lands and rests on the base.
/// Reference: statics: the run ends at its tolerance (1e-4) with the contact forces on the block
/// equal to its weight within 1 %.
#[test]
fn contact_scene_of_configs_runs() {
    flem_plugins::link();
    let mut s = Scene3::from_file(&crate::common::root().join("configs/3d/contact_drop.toml")).unwrap();
    let mut m = March3::from_scene(&mut s).unwrap();
    struct Quiet;
    impl flem_core::solver::march3::Observer3 for Quiet {}
    let r = m.run_scene(&s, &mut Quiet).unwrap();
    let c = m.contact.as_ref().unwrap();
    eprintln!("configs/3d/contact_drop.toml: {} steps, ratio {:.2e}, {} pairs, {} slaves, {} faces", r[0].steps, r[0].ratio, c.forces().len(), c.n_surface_nodes(), c.n_faces());
    assert!(r.iter().all(|r| r.at_rest), "{r:?}");
    // The block's points are those after the base's 50; its weight 0.5 x 0.5 x 0.25 x 10.
    let nb = 50;
    let block_slave = |r: &&flem_core::contact::contact3::PairReport3| m.topo.cluster_point[r.slave as usize].idx() >= nb;
    let on_block: f64 = c.forces().iter().filter(block_slave).map(|r| r.force[2]).sum::<f64>() - c.forces().iter().filter(|r| !block_slave(r)).map(|r| r.force[2]).sum::<f64>();
    eprintln!("force on the block {on_block:.6e} (weight 0.625)");
    assert!((on_block - 0.625).abs() < 1e-2 * 0.625, "force on the block {on_block}");
}
