//! 3D elasticity (issue 38): the T4 and H8 elements (`flem_plugins::elements3d`) and the 3D
//! implicit solve (`flem_plugins::check::solid3`) against physics: patch tests on distorted
//! meshes, NAFEMS LE10, a cantilever against Timoshenko beam theory. The meshes are built here
//! (structured, mapped, randomly distorted bricks, and tetrahedra from split bricks), so that
//! these tests depend on no mesh reader or generator. References and tolerances at each test.
use flem_core::element::shape3::Dmat3;
use flem_core::mesh::{CellKind3, RawCell3, RawFace, RawMesh3};
use flem_plugins::check::solid3::{self, FaceLoad, FaceLoadKind, Problem3};
use flem_plugins::elements3d::Kind3;

/// A structured brick of `n[0] x n[1] x n[2]` hexahedra on the unit cube's grid, mapped by
/// `map` (orientation-preserving). Point `(i, j, k)` has index `i + (n0 + 1)(j + (n1 + 1) k)`.
fn bricks(n: [usize; 3], map: impl Fn([f64; 3]) -> [f64; 3]) -> RawMesh3 {
    let id = |i: usize, j: usize, k: usize| (i + (n[0] + 1) * (j + (n[1] + 1) * k)) as u32;
    let mut points = Vec::new();
    for k in 0..=n[2] {
        for j in 0..=n[1] {
            for i in 0..=n[0] {
                points.push(map([i as f64 / n[0] as f64, j as f64 / n[1] as f64, k as f64 / n[2] as f64]));
            }
        }
    }
    let mut cells = Vec::new();
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                let nodes = [id(i, j, k), id(i + 1, j, k), id(i + 1, j + 1, k), id(i, j + 1, k), id(i, j, k + 1), id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)];
                cells.push(RawCell3 { kind: CellKind3::H8, nodes });
            }
        }
    }
    RawMesh3 { source: "tests/solid3.rs bricks".into(), points, cells, ..Default::default() }
}

/// Each brick split into 6 tetrahedra around its diagonal 0-6 (Kuhn's split: neighbouring
/// bricks' faces get the same diagonal, so the tetrahedra are conforming), each turned to
/// positive volume.
fn tets(m: &RawMesh3) -> RawMesh3 {
    let mut cells = Vec::new();
    for c in &m.cells {
        let h = c.nodes;
        for [a, b] in [[1, 2], [1, 5], [3, 2], [3, 7], [4, 5], [4, 7]] {
            let mut t = [h[0], h[a], h[b], h[6]];
            let x = t.map(|p| m.points[p as usize]);
            if flem_core::mesh::tet_volume6(x[0], x[1], x[2], x[3]) < 0.0 {
                t.swap(1, 2);
            }
            let mut nodes = [0u32; 8];
            nodes[..4].copy_from_slice(&t);
            cells.push(RawCell3 { kind: CellKind3::T4, nodes });
        }
    }
    RawMesh3 { source: "tests/solid3.rs tets".into(), points: m.points.clone(), cells, ..Default::default() }
}

/// xorshift64 in [-1, 1).
fn rng(s: &mut u64) -> f64 {
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    (*s >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// The boundary faces of a mesh with all corners satisfying `on` (faces of cells that no other
/// cell shares).
fn faces_where(m: &RawMesh3, on: impl Fn([f64; 3]) -> bool) -> Vec<RawFace> {
    let mut count = std::collections::BTreeMap::new();
    for c in &m.cells {
        for lf in c.kind.faces() {
            let f = RawFace(std::array::from_fn(|i| if lf[i] == flem_core::mesh::NO_CORNER { lf[i] } else { c.nodes[lf[i] as usize] }));
            count.entry(f.key()).or_insert((f, 0)).1 += 1;
        }
    }
    count.into_values().filter(|&(f, n)| n == 1 && f.corners().iter().all(|&p| on(m.points[p as usize]))).map(|(f, _)| f).collect()
}

/// The linear field of the patch tests: `u = a + B x` with a full (non-symmetric) `B`.
const A: [f64; 3] = [1e-3, -2e-3, 0.5e-3];
const B: [[f64; 3]; 3] = [[1.0e-3, 0.4e-3, -0.3e-3], [-0.2e-3, -0.7e-3, 0.6e-3], [0.5e-3, 0.1e-3, 0.9e-3]];

fn linear_u(x: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| A[i] + B[i][0] * x[0] + B[i][1] * x[1] + B[i][2] * x[2])
}

/// Patch test of one element kind: the boundary points of a randomly distorted 4 x 4 x 4 brick
/// mesh of the unit cube (interior points moved by up to 0.2 of the spacing per coordinate:
/// faces warped, no two cells alike) prescribed to a linear field; the solve must give the
/// field at every interior point and its constant stress `D eps(B)` at every corner of every
/// cell (the 0.9999 corners of `h8` include the incompatible modes, which must stay 0).
/// Reference: the exact linear field (a consistent element reproduces it exactly: Irons's patch
/// test; Taylor, Beresford & Wilson 1976 for the corrected modes). Tolerance 1e-12 relative to
/// the largest displacement and stress (round-off of a well-conditioned solve; a wrong B matrix,
/// a missing Taylor correction or a wrong D give errors of order 1e-3 to 1).
fn patch(kind: Kind3) {
    let n = 4;
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    let h = 1.0 / n as f64;
    let mut m = bricks([n; 3], |x| x);
    for p in m.points.iter_mut() {
        let inner = p.iter().all(|&c| c > 1e-9 && c < 1.0 - 1e-9);
        let r = [rng(&mut seed), rng(&mut seed), rng(&mut seed)];
        if inner {
            for d in 0..3 {
                p[d] += 0.2 * h * r[d];
            }
        }
    }
    let m = if kind == Kind3::T4 { tets(&m) } else { m };
    let (e, nu) = (1000.0, 0.3);
    let mut pr = Problem3::new(&m, e, nu);
    pr.hex = if kind == Kind3::T4 { Kind3::H8 } else { kind };
    let mut interior = 0;
    for (i, p) in m.points.iter().enumerate() {
        if p.iter().any(|&c| c.abs() < 1e-12 || (c - 1.0).abs() < 1e-12) {
            pr.fix[i] = 7;
            pr.u_prescribed[i] = linear_u(*p);
        } else {
            interior += 1;
        }
    }
    assert_eq!(interior, 27);
    let sol = solid3::solve(&pr).unwrap();
    let umax = m.points.iter().map(|&p| linear_u(p).iter().fold(0.0f64, |a, v| a.max(v.abs()))).fold(0.0, f64::max);
    let mut err_u = 0.0f64;
    for (i, p) in m.points.iter().enumerate() {
        let ue = linear_u(*p);
        for d in 0..3 {
            err_u = err_u.max((sol.u[i][d] - ue[d]).abs());
        }
    }
    let eps = [B[0][0], B[1][1], B[2][2], B[0][1] + B[1][0], B[1][2] + B[2][1], B[2][0] + B[0][2]];
    let s_exact = Dmat3::new(e, nu).stress(eps);
    let smax = s_exact.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let mut err_s = 0.0f64;
    for cs in solid3::corner_stresses(&pr, &sol.u).iter().zip(&m.cells) {
        for s in &cs.0[..cs.1.kind.nodes()] {
            for k in 0..6 {
                err_s = err_s.max((s[k] - s_exact[k]).abs());
            }
        }
    }
    eprintln!("patch {}: {} cells, max |u - u_exact| / |u|max = {:.2e}, max |s - s_exact| / |s|max = {:.2e}", kind.name(), m.cells.len(), err_u / umax, err_s / smax);
    assert!(err_u <= 1e-12 * umax, "{}: displacement error {:e}", kind.name(), err_u / umax);
    assert!(err_s <= 1e-12 * smax, "{}: stress error {:e}", kind.name(), err_s / smax);
}

#[test]
fn patch_test_t4_distorted() {
    patch(Kind3::T4);
}

#[test]
fn patch_test_h8_distorted() {
    patch(Kind3::H8);
}

#[test]
fn patch_test_h8_full_distorted() {
    patch(Kind3::H8Full);
}

/// NAFEMS LE10 (thick plate pressure; NAFEMS R0015, *The Standard NAFEMS Benchmarks*, 1990):
/// a quarter of an elliptic annulus, inner ellipse `(x/2)^2 + y^2 = 1`, outer
/// `(x/3.25)^2 + (y/2.75)^2 = 1`, thickness 0.6 (z in [0, 0.6]), E = 210 GPa (210e3 MPa),
/// nu = 0.3; a uniform pressure of 1 MPa on the top face z = 0.6; u_y = 0 on y = 0 (face DCD'C'),
/// u_x = 0 on x = 0 (face ABA'B'), u_x = u_y = 0 on the outer curved face (BCB'C'), u_z = 0 on
/// the outer face's mid-plane line z = 0.3. Target: sigma_yy at D = (2, 0, 0.6) = -5.38 MPa.
/// Mapped mesh: `nr` bricks radially (straight lines between the ellipses at equal parametric
/// angle), `nt` around (parametric angle), `nz` through the thickness (even: the mid-plane is a
/// grid plane); `tets` splits each brick into 6. Returns (sigma_yy at D, dofs).
fn le10(nr: usize, nt: usize, nz: usize, kind: Kind3) -> (f64, usize) {
    assert!(nz % 2 == 0);
    let map = |q: [f64; 3]| {
        let th = std::f64::consts::FRAC_PI_2 * q[1];
        let (c, s) = (th.cos(), th.sin());
        let (xi, yi, xo, yo) = (2.0 * c, s, 3.25 * c, 2.75 * s);
        [xi + q[0] * (xo - xi), yi + q[0] * (yo - yi), 0.6 * q[2]]
    };
    let hex = bricks([nr, nt, nz], map);
    let m = if kind == Kind3::T4 { tets(&hex) } else { hex };
    let mut pr = Problem3::new(&m, 210e3, 0.3);
    pr.hex = if kind == Kind3::T4 { Kind3::H8 } else { kind };
    let ids = |i: usize, j: usize, k: usize| i + (nr + 1) * (j + (nt + 1) * k);
    for k in 0..=nz {
        for j in 0..=nt {
            for i in 0..=nr {
                let p = ids(i, j, k);
                if j == 0 {
                    pr.fix[p] |= 2;
                }
                if j == nt {
                    pr.fix[p] |= 1;
                }
                if i == nr {
                    pr.fix[p] |= 3;
                    if k == nz / 2 {
                        pr.fix[p] |= 4;
                    }
                }
            }
        }
    }
    pr.face_loads.push(FaceLoad { faces: faces_where(&m, |x| (x[2] - 0.6).abs() < 1e-12), load: FaceLoadKind::Pressure(1.0) });
    let sol = solid3::solve(&pr).unwrap();
    // Equilibrium of the solve: K u equals the external forces on every free dof (1e-9 of the
    // largest nodal load; the solve's residual is round-off).
    let (fi, fe) = (solid3::internal_forces(&pr, &sol.u), solid3::external_forces(&pr).unwrap());
    let fmax = fe.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
    for p in 0..m.points.len() {
        for d in 0..3 {
            if pr.fix[p] & (1 << d) == 0 {
                assert!((fi[p][d] - fe[p][d]).abs() < 1e-9 * fmax, "point {p} dof {d}: {} vs {}", fi[p][d], fe[p][d]);
            }
        }
    }
    let d = ids(0, 0, nz);
    assert!((m.points[d][0] - 2.0).abs() < 1e-12 && m.points[d][1].abs() < 1e-12 && (m.points[d][2] - 0.6).abs() < 1e-12);
    (sol.nodal_stress[d][1], sol.n_dofs)
}

/// LE10 with `h8` (incompatible modes) on two mapped meshes: the finer within 3 % of -5.38 MPa
/// (the issue's tolerance), the coarser within 10 % (what such a mesh gives: see the figures
/// printed and docs/3d.md), and the error falling with refinement.
#[test]
fn nafems_le10_h8() {
    let (coarse, n1) = le10(3, 6, 4, Kind3::H8);
    let (fine, n2) = le10(6, 12, 8, Kind3::H8);
    let (e1, e2) = (coarse / -5.38 - 1.0, fine / -5.38 - 1.0);
    eprintln!("LE10 h8: coarse ({n1} dofs) sigma_yy(D) = {coarse:.4} ({:+.2} %), fine ({n2} dofs) {fine:.4} ({:+.2} %)", 100.0 * e1, 100.0 * e2);
    assert!(e2.abs() < 0.03, "fine mesh: {fine}");
    assert!(e1.abs() < 0.10, "coarse mesh: {coarse}");
    assert!(e2.abs() < e1.abs());
}

/// LE10 with `t4` (each brick split into 6 tetrahedra). Reference: an independent code on the
/// same discrete problem, scikit-fem 12.0.2 with linear tetrahedra on the same points and
/// tetrahedra (`tools/le10_skfem.py --p1 3x6x4 6x12x8`: -3.08912796 and -4.32385022, the mean
/// of the two tetrahedra's constant stress at D). Tolerance 1e-6 relative (the printed digits;
/// both are direct solves of the same matrix: a wrong support, pressure sign or corner force
/// moves it by far more). Constant-strain tetrahedra converge slowly towards -5.38 (-42.6 %,
/// -19.6 % here; docs/3d.md for finer meshes): the error must fall with refinement.
#[test]
fn nafems_le10_t4() {
    let (coarse, n1) = le10(3, 6, 4, Kind3::T4);
    let (fine, n2) = le10(6, 12, 8, Kind3::T4);
    let (e1, e2) = (coarse / -5.38 - 1.0, fine / -5.38 - 1.0);
    eprintln!("LE10 t4: coarse ({n1} dofs) sigma_yy(D) = {coarse:.8} ({:+.2} %), fine ({n2} dofs) {fine:.8} ({:+.2} %)", 100.0 * e1, 100.0 * e2);
    assert!((coarse / -3.08912796 - 1.0).abs() < 1e-6, "coarse {coarse} vs scikit-fem -3.08912796");
    assert!((fine / -4.32385022 - 1.0).abs() < 1e-6, "fine {fine} vs scikit-fem -4.32385022");
    assert!(e2.abs() < e1.abs());
}

/// A cantilever `L x b x h = 10 x 1 x 1` (E = 1000, nu = 0.25), the root x = 0 clamped, a total
/// shear P = 1 (uniform traction -z on the tip face). Reference: Timoshenko beam theory with
/// shear, tip deflection `P L^3 / (3 E I) + P L / (kappa G A)` = 4.0 + 0.03 = 4.03 (I = b h^3 /
/// 12, kappa = 5/6, G = E / (2 (1 + nu)) = 400). Timoshenko & Goodier's plane-stress solution
/// gives 4.02625, Cowper's kappa for a square section 4.0294: the theories agree to 0.1 %, and the
/// clamp and the uniform end shear differ from them only locally (Saint-Venant). Returns the
/// deflection of the tip's centre point (x = L, y = b/2, z = h/2).
fn cantilever(kind: Kind3, n: [usize; 3]) -> f64 {
    let (l, b, h) = (10.0, 1.0, 1.0);
    let hex = bricks(n, |q| [l * q[0], b * q[1], h * q[2]]);
    let m = if kind == Kind3::T4 { tets(&hex) } else { hex };
    let mut pr = Problem3::new(&m, 1000.0, 0.25);
    pr.hex = if kind == Kind3::T4 { Kind3::H8 } else { kind };
    for (i, p) in m.points.iter().enumerate() {
        if p[0].abs() < 1e-12 {
            pr.fix[i] = 7;
        }
    }
    let tip = faces_where(&m, |x| (x[0] - l).abs() < 1e-12);
    pr.face_loads.push(FaceLoad { faces: tip, load: FaceLoadKind::Traction([0.0, 0.0, -1.0 / (b * h)]) });
    // The consistent face forces sum to the applied shear (exact for flat faces).
    let fe = solid3::external_forces(&pr).unwrap();
    let total: [f64; 3] = std::array::from_fn(|d| fe.iter().map(|f| f[d]).sum());
    assert!(total[0].abs() < 1e-14 && total[1].abs() < 1e-14 && (total[2] + 1.0).abs() < 1e-14, "{total:?}");
    let sol = solid3::solve(&pr).unwrap();
    // Global equilibrium: the reactions at the clamp balance the load (1e-10).
    let fi = solid3::internal_forces(&pr, &sol.u);
    let react: f64 = (0..m.points.len()).filter(|&i| pr.fix[i] == 7).map(|i| fi[i][2]).sum();
    assert!((react - 1.0).abs() < 1e-10, "reaction {react}");
    let c = m.points.iter().position(|p| (p[0] - l).abs() < 1e-12 && (p[1] - 0.5 * b).abs() < 1e-12 && (p[2] - 0.5 * h).abs() < 1e-12).expect("a tip centre point");
    -sol.u[c][2]
}

/// `h8` at 4 bricks through the depth (20 x 2 x 4 bricks, aspect 2:2:1) within 2 % of Timoshenko's
/// 4.03 (the issue's tolerance); `h8_full` on the same mesh locks (measured 3.597, 10.7 % too
/// stiff, as Q4 on the 2D cantilever: the test asks for more than 7 %, so it fails if `h8` loses
/// its incompatible modes).
#[test]
fn cantilever_h8_timoshenko() {
    let reference = 4.03;
    let w = cantilever(Kind3::H8, [20, 2, 4]);
    let w_full = cantilever(Kind3::H8Full, [20, 2, 4]);
    let w_t4 = cantilever(Kind3::T4, [20, 2, 4]);
    eprintln!(
        "cantilever tip: h8 {w:.5} ({:+.2} %), h8_full {w_full:.5} ({:+.2} %), t4 {w_t4:.5} ({:+.2} %) of {reference}",
        100.0 * (w / reference - 1.0),
        100.0 * (w_full / reference - 1.0),
        100.0 * (w_t4 / reference - 1.0)
    );
    assert!((w / reference - 1.0).abs() < 0.02, "h8 tip {w}");
    assert!(w_full / reference < 0.93, "h8_full tip {w_full}: no locking?");
}

/// Bad input gets a clear error naming the cell or the face; an unsupported body is refused.
#[test]
fn solid3_errors_name_the_culprit() {
    let m = bricks([2, 1, 1], |x| x);
    // No support: six rigid motions.
    let mut pr = Problem3::new(&m, 1000.0, 0.3);
    pr.f_ext[0] = [1.0, 0.0, 0.0];
    let e = solid3::solve(&pr).unwrap_err().to_string();
    assert!(e.contains("rigid motions"), "{e}");
    // An inverted cell (two corners swapped).
    let mut bad = m.clone();
    bad.cells[1].nodes.swap(0, 1);
    let e = solid3::solve(&Problem3::new(&bad, 1000.0, 0.3)).unwrap_err().to_string();
    assert!(e.contains("element 1") && e.contains("[2, 1, 5, 4, 7, 8, 11, 10]") && e.contains("inverted"), "{e}");
    // A face load on a face that is no cell's face.
    let mut pr = Problem3::new(&m, 1000.0, 0.3);
    pr.fix = vec![7; m.points.len()];
    pr.face_loads.push(FaceLoad { faces: vec![RawFace([0, 2, 8, 9])], load: FaceLoadKind::Pressure(1.0) });
    let e = solid3::solve(&pr).unwrap_err().to_string();
    assert!(e.contains("no face of a cell"), "{e}");
    // A tetrahedron kind for bricks.
    let mut pr = Problem3::new(&m, 1000.0, 0.3);
    pr.hex = Kind3::T4;
    assert!(solid3::solve(&pr).unwrap_err().to_string().contains("not a hexahedron kind"));
}

/// The ```toml snippets of the 3D element plugins name a 3D kind and a valid material.
#[test]
fn element3d_doc_snippets_parse() {
    for file in ["plugins/src/elements3d/t4.rs", "plugins/src/elements3d/h8.rs"] {
        let src = std::fs::read_to_string(crate::common::root().join(file)).unwrap();
        let blocks = flem_plugins::snippets::toml_blocks(&src);
        assert!(!blocks.is_empty(), "{file} has no ```toml block");
        for b in blocks {
            let t: toml::Table = toml::from_str(&b).unwrap_or_else(|e| panic!("{file}: {e}"));
            let mat = &t["material"].as_array().unwrap()[0];
            let kind = Kind3::from_name(mat["element"].as_str().unwrap()).unwrap_or_else(|| panic!("{file}: unknown kind"));
            let (e, nu) = (mat["young_modulus"].as_float().unwrap(), mat["poisson_ratio"].as_float().unwrap());
            // The snippet's material solves a single supported cell of its kind.
            let m = bricks([1, 1, 1], |x| x);
            let m = if kind == Kind3::T4 { tets(&m) } else { m };
            let mut pr = Problem3::new(&m, e, nu);
            if kind != Kind3::T4 {
                pr.hex = kind;
            }
            for (i, p) in m.points.iter().enumerate() {
                if p[2] == 0.0 {
                    pr.fix[i] = 7;
                }
            }
            pr.face_loads.push(FaceLoad { faces: faces_where(&m, |x| x[2] == 1.0), load: FaceLoadKind::Pressure(1.0) });
            let s = solid3::solve(&pr).unwrap();
            assert!(s.u.iter().all(|u| u[2] <= 0.0), "{file}");
        }
    }
}

/// LE10 on finer meshes (ignored by default for its time; the figures are in docs/3d.md):
/// `cargo test --release -p flem-tests -- --ignored nafems_le10_fine --nocapture`.
/// `h8` at 12 x 24 x 16 and 18 x 36 x 24 bricks within 3 % of -5.38 MPa; `t4` (6 per brick)
/// printed at 12 x 24 x 16 and 24 x 48 x 16.
#[test]
#[ignore]
fn nafems_le10_fine() {
    let mut worst = 0.0f64;
    for (nr, nt, nz) in [(12, 24, 16), (18, 36, 24)] {
        let t0 = std::time::Instant::now();
        let (h, n) = le10(nr, nt, nz, Kind3::H8);
        eprintln!("LE10 h8 {nr}x{nt}x{nz} ({n} dofs): sigma_yy(D) = {h:.4} ({:+.2} %), {:.1} s", 100.0 * (h / -5.38 - 1.0), t0.elapsed().as_secs_f64());
        worst = worst.max((h / -5.38 - 1.0).abs());
    }
    for (nr, nt, nz) in [(12, 24, 16), (24, 48, 16)] {
        let t0 = std::time::Instant::now();
        let (t, n) = le10(nr, nt, nz, Kind3::T4);
        eprintln!("LE10 t4 {nr}x{nt}x{nz} ({n} dofs): sigma_yy(D) = {t:.4} ({:+.2} %), {:.1} s", 100.0 * (t / -5.38 - 1.0), t0.elapsed().as_secs_f64());
    }
    assert!(worst < 0.03, "h8: {worst}");
}
