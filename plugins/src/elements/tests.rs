//! Unit tests of the element plugins (the mesh-level patch tests, Cook's membrane and the
//! cantilever are in tests/elements.rs).
use flem_core::element::kernel::{Blocked, LANES};
use flem_core::element::{Dmat, Material, Plane};

use super::{Q4Closed, Qm6, Q4, T3};

fn lcg(s: &mut u64) -> f64 {
    *s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    (*s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
}

fn mat(plane: Plane) -> Material {
    Material { young: 210e9, poisson: 0.3, density: 1.0, thickness: 0.7, plane }
}

const DISTORTED: [[f64; 2]; 4] = [[0.0, 0.0], [1.0, 0.1], [1.3, 0.9], [-0.2, 1.1]];

/// The blocked kernel equals the one-element reference (`force_ref`) to 1e-12 relative on
/// distorted elements with random displacements, including a partly filled pack (the generic
/// `check` below). Both sides multiply the same condensed matrices, so this checks the packing
/// and the lane layout; the element's physics is checked by the patch and bending tests.
#[test]
fn blocked_qm6_matches_reference() {
    check::<Qm6, 4>(DISTORTED);
}

/// The condensed stiffness is symmetric, free of force under the three rigid-body modes
/// (reference: exact zero; tolerance 1e-12 of the largest entry times the displacement), and
/// softer than Q4's (condensing internal modes can only lower the energy of every nodal
/// displacement: u^T (K_q4 - K_qm6) u >= 0, Rayleigh).
#[test]
fn qm6_stiffness_is_symmetric_rigid_free_and_softer_than_q4() {
    let m = mat(Plane::Strain);
    let d = m.dmat();
    let mut k = [0.0; 64];
    let mut kq = [0.0; 64];
    <Qm6 as Blocked<4>>::stiffness(&DISTORTED, &d, m.thickness, &mut k);
    <Q4 as Blocked<4>>::stiffness(&DISTORTED, &d, m.thickness, &mut kq);
    let kmax = k.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    for i in 0..8 {
        for j in 0..8 {
            assert_eq!(k[i * 8 + j], k[j * 8 + i]);
        }
    }
    let rigid = |mode: usize| -> [f64; 8] {
        std::array::from_fn(|j| match mode {
            0 => [1.0, 0.0][j % 2],
            1 => [0.0, 1.0][j % 2],
            _ => {
                let x = DISTORTED[j / 2];
                [-x[1], x[0]][j % 2]
            }
        })
    };
    for mode in 0..3 {
        let u = rigid(mode);
        for i in 0..8 {
            let f: f64 = (0..8).map(|j| k[i * 8 + j] * u[j]).sum();
            assert!(f.abs() <= 1e-12 * kmax * 2.0, "rigid mode {mode}: f[{i}] = {f}");
        }
    }
    let mut s = 11u64;
    for _ in 0..50 {
        let u: [f64; 8] = std::array::from_fn(|_| lcg(&mut s));
        let e = |k: &[f64; 64]| -> f64 { (0..8).map(|i| u[i] * (0..8).map(|j| k[i * 8 + j] * u[j]).sum::<f64>()).sum() };
        assert!(e(&kq) - e(&k) >= -1e-12 * e(&kq), "{} < {}", e(&kq), e(&k));
    }
}

/// Constant strain on a distorted element (the single-element form of the patch test,
/// Taylor et al. 1976): the internal parameters stay zero and the stress at every corner point
/// and Gauss point is `D eps` exactly. Reference: `D eps`; tolerance 1e-12 relative.
#[test]
fn qm6_reproduces_constant_strain_on_a_distorted_element() {
    for plane in [Plane::Strain, Plane::Stress] {
        let m = mat(plane);
        let d = m.dmat();
        let eps = [1e-3, -4e-4, 7e-4];
        let u: [[f64; 2]; 4] = std::array::from_fn(|a| {
            let [x, y] = DISTORTED[a];
            [eps[0] * x + 0.5 * eps[2] * y + 0.3, 0.5 * eps[2] * x + eps[1] * y - 0.1]
        });
        let mut h = [0.0; 32];
        Qm6::recovery(&DISTORTED, &d, m.thickness, &mut h);
        let want = d.stress(eps);
        let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for xi in [[0.9999, 0.9999], [-0.9999, 0.9999], [0.577, -0.577], [0.0, 0.0], [0.3, 0.8]] {
            let s = Qm6::stress(&DISTORTED, &u, &d, xi, &h);
            for k in 0..3 {
                assert!((s[k] - want[k]).abs() <= 1e-12 * scale, "{plane:?} at {xi:?}: {s:?} vs {want:?}");
            }
        }
    }
}

/// Pure bending of a rectangular element (plane stress): with the nodal values of the exact
/// field `u_x = k x y`, `u_y = -k (x^2 + nu y^2) / 2` the element's stress is the exact
/// `sxx = E k y`, `syy = sxy = 0` everywhere (Wilson et al. 1973: the incompatible modes make
/// the rectangle exact in pure bending), where Q4 shows the spurious shear `sxy = G k x` that
/// makes it lock. Reference: the beam solution; tolerance 1e-9 of E k h.
#[test]
fn qm6_rectangle_is_exact_in_pure_bending_and_q4_is_not() {
    let m = Material { young: 1000.0, poisson: 0.25, density: 1.0, thickness: 1.0, plane: Plane::Stress };
    let d: Dmat = m.dmat();
    let (a, b, k) = (2.0, 0.5, 1e-3);
    let x: [[f64; 2]; 4] = [[-a, -b], [a, -b], [a, b], [-a, b]];
    let u: [[f64; 2]; 4] = std::array::from_fn(|i| {
        let [x, y] = x[i];
        [k * x * y, -0.5 * k * (x * x + 0.25 * y * y)]
    });
    let mut h = [0.0; 32];
    Qm6::recovery(&x, &d, 1.0, &mut h);
    let tol = 1e-9 * 1000.0 * k * b;
    for xi in [[0.577, 0.577], [-0.577, 0.577], [0.9999, -0.9999], [0.2, 0.4]] {
        let s = Qm6::stress(&x, &u, &d, xi, &h);
        let y = b * xi[1];
        assert!((s[0] - 1000.0 * k * y).abs() < tol && s[1].abs() < tol && s[2].abs() < tol, "qm6 at {xi:?}: {s:?}");
    }
    let sq = <Q4 as Blocked<4>>::stress(&x, &u, &d, [0.577, 0.577], &[]);
    assert!(sq[2].abs() > 0.1 * 1000.0 * k * b, "Q4 shows the parasitic shear: {sq:?}");
}

// The built-in kinds moved from core (issue 20): their blocked kernels against the reference.
/// The blocked kernels equal `element::internal_force` (the reference, one element at a
/// time) to 1e-12 relative on distorted elements and random displacements, including
/// partially filled packs.
fn check<S: Blocked<N>, const N: usize>(base: [[f64; 2]; N]) {
    let mut s = 7u64;
    for plane in [Plane::Strain, Plane::Stress] {
        let mat = Material { young: 210e9, poisson: 0.3, density: 1.0, thickness: 0.7, plane };
        let d = mat.dmat();
        for n in [LANES, 3] {
            let xs: Vec<[[f64; 2]; N]> = (0..n).map(|_| std::array::from_fn(|a| [1e3 + base[a][0] + 0.2 * lcg(&mut s), -5.0 + base[a][1] + 0.2 * lcg(&mut s)])).collect();
            let us: Vec<[[f64; 2]; N]> = (0..n).map(|_| std::array::from_fn(|_| [1e-3 * lcg(&mut s), 1e-3 * lcg(&mut s)])).collect();
            let (p, e) = (S::pack(&xs, &d, mat.thickness), S::extra(&xs, &d, mat.thickness));
            let mut ug = [[[0.0; LANES]; 2]; N];
            for (l, ue) in us.iter().enumerate() {
                for a in 0..N {
                    ug[a][0][l] = ue[a][0];
                    ug[a][1][l] = ue[a][1];
                }
            }
            let mut fg = [[[f64::NAN; LANES]; 2]; N];
            match &e {
                Some(e) => S::forces_extra(&p, e, &S::scaled_d(&d, mat.thickness), &ug, &mut fg),
                None => S::forces(&p, &S::scaled_d(&d, mat.thickness), &ug, &mut fg),
            }
            for l in 0..LANES {
                if l >= n {
                    assert!((0..N).all(|a| fg[a][0][l] == 0.0 && fg[a][1][l] == 0.0), "empty lane gives zero force");
                    continue;
                }
                let r = S::force_ref(&xs[l], &us[l], &d, mat.thickness);
                let scale = r.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
                for a in 0..N {
                    for k in 0..2 {
                        assert!((fg[a][k][l] - r[a][k]).abs() <= 1e-12 * scale, "corner {a} dim {k}: {} vs {}", fg[a][k][l], r[a][k]);
                    }
                }
            }
        }
    }
}

#[test]
fn blocked_q4_matches_reference() {
    check::<Q4, 4>([[0.0, 0.0], [1.0, 0.0], [1.2, 0.9], [-0.1, 1.1]]);
}

/// `q4_closed` (ours, issue 42): the closed form of the 2 x 2 Gauss sum on parallelograms
/// equals `q4`'s Gauss form and the one-element 2 x 2 Gauss reference (`element::internal_force`)
/// to 1e-12 of the largest force (reference: the same integral, summed point by point), on 200
/// packs of random parallelograms (corners on a 1/1024 grid so that `h` is exactly zero; edge
/// lengths 0.5-1.5 times an aspect ratio 1 to 20, the second edge at 45 to 135 deg from the
/// first) with random displacements (hourglass modes included), plane strain and stress; a
/// partly filled pack of parallelograms gives zero force in its empty lanes; a
/// non-parallelogram pack takes `q4`'s Gauss form bit for bit.
#[test]
fn q4_closed_equals_the_gauss_sum_on_parallelograms() {
    let mut s = 7u64;
    let (mut worst_ref, mut worst_q4, mut worst_q4_ref, mut lean_packs) = (0.0f64, 0.0f64, 0.0f64, 0);
    let q = |v: f64| (v * 1024.0).round() / 1024.0;
    let parallelogram = |s: &mut u64| -> [[f64; 2]; 4] {
        let o = [q(100.0 * lcg(s)), q(100.0 * lcg(s))];
        let aspect = 20.0f64.powf(lcg(s) + 0.5);
        let (l1, l2) = (1.0 + lcg(s), (1.0 + lcg(s)) * aspect);
        let (t1, skew) = (lcg(s) * 6.3, std::f64::consts::FRAC_PI_2 + lcg(s) * std::f64::consts::FRAC_PI_2);
        let (e1, e2) = ([q(l1 * t1.cos()), q(l1 * t1.sin())], [q(l2 * (t1 + skew).cos()), q(l2 * (t1 + skew).sin())]);
        [o, [o[0] + e1[0], o[1] + e1[1]], [o[0] + e1[0] + e2[0], o[1] + e1[1] + e2[1]], [o[0] + e2[0], o[1] + e2[1]]]
    };
    for round in 0..200 {
        let plane = if round % 2 == 0 { Plane::Strain } else { Plane::Stress };
        let d = mat(plane).dmat();
        let xs: Vec<[[f64; 2]; 4]> = (0..LANES).map(|_| parallelogram(&mut s)).collect();
        let (p, _, lean) = super::q4::full_pack(&xs);
        lean_packs += lean as usize;
        let dk = <Q4 as Blocked<4>>::scaled_d(&d, 0.7);
        let ug: [[[f64; LANES]; 2]; 4] = std::array::from_fn(|_| std::array::from_fn(|_| std::array::from_fn(|_| 1e-3 * lcg(&mut s))));
        let (mut fc, mut fq) = ([[[0.0; LANES]; 2]; 4], [[[0.0; LANES]; 2]; 4]);
        <Q4Closed as Blocked<4>>::forces(&p, &dk, &ug, &mut fc);
        <Q4 as Blocked<4>>::forces(&p, &dk, &ug, &mut fq);
        for l in 0..LANES {
            let u: [[f64; 2]; 4] = std::array::from_fn(|a| [ug[a][0][l], ug[a][1][l]]);
            let r = <Q4 as Blocked<4>>::force_ref(&xs[l], &u, &d, 0.7);
            let scale = r.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
            for a in 0..4 {
                for k in 0..2 {
                    let (c, qq) = (fc[a][k][l], fq[a][k][l]);
                    worst_ref = worst_ref.max((c - r[a][k]).abs() / scale);
                    worst_q4 = worst_q4.max((c - qq).abs() / scale);
                    worst_q4_ref = worst_q4_ref.max((qq - r[a][k]).abs() / scale);
                    assert!((c - r[a][k]).abs() <= 1e-12 * scale && (c - qq).abs() <= 1e-12 * scale, "lane {l} corner {a} dim {k}: closed {c}, q4 {qq}, reference {}", r[a][k]);
                }
            }
        }
    }
    assert!(lean_packs == 200, "every pack of parallelograms takes the closed form: {lean_packs}");
    assert!(worst_q4 > 0.0, "the closed form is another sum: some round-off expected");
    eprintln!("largest difference, of the largest force: q4_closed - q4 {worst_q4:.2e}, q4_closed - reference {worst_ref:.2e}, q4 - reference {worst_q4_ref:.2e}");
    // A partly filled pack of parallelograms: zero force in the empty lanes.
    let xs: Vec<[[f64; 2]; 4]> = (0..3).map(|_| parallelogram(&mut s)).collect();
    let (p, _, lean) = super::q4::full_pack(&xs);
    assert!(lean);
    let dk = <Q4 as Blocked<4>>::scaled_d(&mat(Plane::Strain).dmat(), 0.7);
    let ug: [[[f64; LANES]; 2]; 4] = std::array::from_fn(|_| std::array::from_fn(|_| std::array::from_fn(|_| 1e-3 * lcg(&mut s))));
    let mut fc = [[[f64::NAN; LANES]; 2]; 4];
    <Q4Closed as Blocked<4>>::forces(&p, &dk, &ug, &mut fc);
    assert!((0..4).all(|a| (0..2).all(|k| fc[a][k][..3].iter().all(|v| v.is_finite() && *v != 0.0) && fc[a][k][3..].iter().all(|v| *v == 0.0))), "empty lanes give zero force: {fc:?}");
    // A non-parallelogram pack: q4's Gauss form, bit for bit.
    let xs = vec![DISTORTED; 3];
    let (p, e, lean) = super::q4::full_pack(&xs);
    assert!(!lean);
    let d = mat(Plane::Strain).dmat();
    let dk = <Q4 as Blocked<4>>::scaled_d(&d, 0.7);
    let ug: [[[f64; LANES]; 2]; 4] = std::array::from_fn(|_| std::array::from_fn(|_| std::array::from_fn(|_| 1e-3 * lcg(&mut s))));
    let (mut fc, mut fq) = ([[[0.0; LANES]; 2]; 4], [[[0.0; LANES]; 2]; 4]);
    <Q4Closed as Blocked<4>>::forces_extra(&p, &e, &dk, &ug, &mut fc);
    <Q4 as Blocked<4>>::forces_extra(&p, &e, &dk, &ug, &mut fq);
    let bits = |f: &[[[f64; LANES]; 2]; 4]| f.iter().flatten().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&fc), bits(&fq), "a non-parallelogram pack is q4's Gauss form");
    // The non-parallelogram path through the generic check (a partly filled pack too).
    check::<Q4Closed, 4>([[0.0, 0.0], [1.0, 0.0], [1.2, 0.9], [-0.1, 1.1]]);
}

#[test]
fn blocked_t3_matches_reference() {
    check::<T3, 3>([[0.0, 0.0], [1.0, 0.1], [0.2, 0.9]]);
}

/// Co-rotational Q4 block (moved from core with Q4): a pure stretch is the linear result; the
/// same stretch rotated by 30 degrees gives the rotated stress. Reference: the linear kernel
/// and `R sigma R^T` written out; 1e-9 and 1e-6 relative.
#[test]
fn corotational_q4_rotated_stretch_is_the_rotated_linear_result() {
    use flem_core::element::block::{Block, ElementBlock};
    use flem_core::element::corot::CorotBlock;
    use flem_core::ids::ElemId;
    let mat = Material { young: 1000.0, poisson: 0.3, density: 1.0, thickness: 1.0, plane: Plane::Strain };
    let mut e = ElementBlock::<Q4, 4>::new("all".into(), mat);
    e.push(ElemId(0), [[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]], [0, 1, 2, 3]);
    let b = CorotBlock(e);
    let eps = 1e-4;
    let x = b.0.x[0];
    let u: Vec<[f64; 2]> = x.iter().map(|p| [eps * p[0], 0.0]).collect();
    let lin = flem_core::element::stress_at::<Q4, 4>(&x, &[u[0], u[1], u[2], u[3]], &b.0.d, [0.0, 0.0]);
    let s0 = b.mean_stress(0, &u);
    for k in 0..3 {
        assert!((s0[k] - lin[k]).abs() < 1e-9 * 1000.0, "{s0:?} {lin:?}");
    }
    let th = 30f64.to_radians();
    let (c, s) = (th.cos(), th.sin());
    let ur: Vec<[f64; 2]> = x
        .iter()
        .map(|p| {
            let q = [(1.0 + eps) * p[0], p[1]];
            [c * q[0] - s * q[1] - p[0], s * q[0] + c * q[1] - p[1]]
        })
        .collect();
    let sr = b.mean_stress(0, &ur);
    let [sx, sy, sxy] = lin;
    let want = [c * c * sx + s * s * sy - 2.0 * c * s * sxy, s * s * sx + c * c * sy + 2.0 * c * s * sxy, c * s * (sx - sy) + (c * c - s * s) * sxy];
    for k in 0..3 {
        assert!((sr[k] - want[k]).abs() < 1e-6 * lin[0].abs(), "{sr:?} {want:?}");
    }
}

/// Issue 24: a Q4 pack of parallelograms keeps only `a, b` (the lean form) and computes its one
/// `1 / det J`; on a parallelogram the lean and the general form give the same forces bit for
/// bit (the reference is the general form, the layout used before; exact equality).
#[test]
fn q4_lean_pack_equals_general_bit_for_bit() {
    let mut s = 11u64;
    for _ in 0..50 {
        // Parallelograms o, o + e1, o + e1 + e2, o + e2 with coordinates on a 1/64 grid (exact
        // sums, so h is exactly zero, as on a generated rectangle), random edge vectors.
        let mut g = |lo: f64, hi: f64| ((lo + (hi - lo) * (lcg(&mut s) + 0.5)) * 64.0).round() / 64.0;
        let xs: Vec<[[f64; 2]; 4]> = (0..LANES)
            .map(|_| {
                let (o, e1, e2) = ([g(-100.0, 100.0), g(-100.0, 100.0)], [g(0.5, 1.5), g(-0.3, 0.3)], [g(-0.3, 0.3), g(0.5, 1.5)]);
                [o, [o[0] + e1[0], o[1] + e1[1]], [o[0] + e1[0] + e2[0], o[1] + e1[1] + e2[1]], [o[0] + e2[0], o[1] + e2[1]]]
            })
            .collect();
        let (p, e, lean) = super::q4::full_pack(&xs);
        let d = mat(Plane::Strain).dmat();
        let dk = <Q4 as Blocked<4>>::scaled_d(&d, 0.7);
        let ug: [[[f64; LANES]; 2]; 4] = std::array::from_fn(|_| std::array::from_fn(|_| std::array::from_fn(|_| 1e-3 * lcg(&mut s))));
        let (mut f1, mut f2) = ([[[0.0; LANES]; 2]; 4], [[[0.0; LANES]; 2]; 4]);
        <Q4 as Blocked<4>>::forces_extra(&p, &e, &dk, &ug, &mut f2);
        assert!(lean, "a parallelogram on an exact grid is lean: {xs:?}");
        <Q4 as Blocked<4>>::forces(&p, &dk, &ug, &mut f1);
        let bits = |f: &[[[f64; LANES]; 2]; 4]| f.iter().flatten().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&f1), bits(&f2), "lean and general Q4 forces differ on parallelograms");
    }
    // A non-parallelogram is never lean.
    assert!(!super::q4::full_pack(&[DISTORTED]).2);
}

/// Issue 24: the chunk loop compiled for wider vector units (AVX2, AVX-512, when this CPU has
/// them) gives the same forces bit for bit as the baseline one, on a block mixing lean and
/// general Q4 packs, the same with `q4_closed`, and on T3; and the blocked Q4 and `q4_closed`
/// blocks equal the one-element reference (`add_internal_forces_range`) to 1e-12 relative.
#[test]
fn simd_chunk_loops_are_bit_identical() {
    use flem_core::element::block::{Block, ElementBlock, Simd};
    use flem_core::ids::ElemId;
    let (nx, ny) = (37, 23);
    let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let mut s = 5u64;
    // Corner points of a grid, distorted in its upper half only (mixed packs).
    let pts: Vec<[f64; 2]> = (0..=ny).flat_map(|j| (0..=nx).map(move |i| (i, j))).map(|(i, j)| [i as f64 + if j > ny / 2 { 0.3 * lcg(&mut s) } else { 0.0 }, j as f64]).collect();
    let u: Vec<[f64; 2]> = (0..pts.len()).map(|_| [1e-3 * lcg(&mut s), 1e-3 * lcg(&mut s)]).collect();
    let m = mat(Plane::Strain);
    let mut q = ElementBlock::<Q4, 4>::new("r".into(), m);
    let mut qc = ElementBlock::<Q4Closed, 4>::new("r".into(), m);
    let mut t = ElementBlock::<T3, 3>::new("r".into(), m);
    for j in 0..ny {
        for i in 0..nx {
            let c = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
            q.push(ElemId((j * nx + i) as u32), c.map(|c| pts[c as usize]), c);
            qc.push(ElemId((j * nx + i) as u32), c.map(|c| pts[c as usize]), c);
            for tri in [[c[0], c[1], c[2]], [c[0], c[2], c[3]]] {
                t.push(ElemId(t.len() as u32), tri.map(|c| pts[c as usize]), tri);
            }
        }
    }
    q.prepare(pts.len());
    qc.prepare(pts.len());
    t.prepare(pts.len());
    type Run<'a> = &'a dyn Fn(&mut [[f64; 2]], Simd) -> bool;
    let run = |b: Run, simd| {
        let mut f = vec![[0.0; 2]; pts.len()];
        b(&mut f, simd).then_some(f)
    };
    let (rq, rt): (Run, Run) = (&|f, s| q.add_internal_forces_simd(&u, f, s), &|f, s| t.add_internal_forces_simd(&u, f, s));
    let rqc: Run = &|f, s| qc.add_internal_forces_simd(&u, f, s);
    for b in [rq, rt, rqc] {
        let plain = run(b, Simd::Plain).expect("the baseline always runs");
        for simd in [Simd::Avx2, Simd::Avx512] {
            if let Some(f) = run(b, simd) {
                assert!(plain.iter().zip(&f).all(|(a, b)| a[0].to_bits() == b[0].to_bits() && a[1].to_bits() == b[1].to_bits()), "{simd:?} differs from the baseline");
            }
        }
    }
    let mut r = vec![[0.0; 2]; pts.len()];
    q.add_internal_forces_range(0..q.len(), &u, &mut r);
    let plain = run(rq, Simd::Plain).unwrap();
    let scale = r.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(plain.iter().flatten().zip(r.iter().flatten()).all(|(a, b)| (a - b).abs() <= 1e-12 * scale));
    // `q4_closed` (lean packs in the lower half take the closed form): the reference too.
    let closed = run(rqc, Simd::Plain).unwrap();
    assert!(closed.iter().flatten().zip(r.iter().flatten()).all(|(a, b)| (a - b).abs() <= 1e-12 * scale));
    assert!(closed.iter().flatten().zip(plain.iter().flatten()).any(|(a, b)| a.to_bits() != b.to_bits()), "q4_closed ran q4's sum");
}

/// The co-rotational pass (`CorotBlock`: `ElementBlock::corot_forces_simd`, each pack's local
/// displacements through the blocked kernel) against the element-by-element reference
/// (`CorotBlock::add_internal_forces_reference`: `Blocked::force_ref` on each element's local
/// displacements, the formulation of `element::corot`'s module doc): within 1e-12 of the
/// largest force for Q4 and `q4_closed` (a grid distorted in its upper half: lean and general
/// packs), T3 and qm6, on 851 elements (a partial last pack), the grid turned by 0 to 170 degrees with a small
/// strain on top; every SIMD variant bit for bit the baseline; the forces of two sub-ranges add
/// up to the whole range's, bit for bit in this order; a rigid rotation by 170 degrees
/// gives forces below 1e-9 of the strained grid's (reference: a rigid motion carries no stress,
/// the point of the co-rotational kinematics).
#[test]
fn corotational_blocked_pass_matches_the_reference() {
    use flem_core::element::block::{Block, ElementBlock, Simd};
    use flem_core::element::corot::CorotBlock;
    use flem_core::ids::ElemId;
    let (nx, ny) = (37, 23);
    let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let mut s = 7u64;
    let pts: Vec<[f64; 2]> = (0..=ny).flat_map(|j| (0..=nx).map(move |i| (i, j))).map(|(i, j)| [i as f64 + if j > ny / 2 { 0.3 * lcg(&mut s) } else { 0.0 }, j as f64]).collect();
    let quads: Vec<[u32; 4]> = (0..ny).flat_map(|j| (0..nx).map(move |i| [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)])).collect();
    let tris: Vec<[u32; 3]> = quads.iter().flat_map(|c| [[c[0], c[1], c[2]], [c[0], c[2], c[3]]]).collect();
    let m = mat(Plane::Strain);
    fn block<S: Blocked<N>, const N: usize>(m: Material, pts: &[[f64; 2]], cells: &[[u32; N]]) -> CorotBlock<S, N> {
        let mut e = ElementBlock::<S, N>::new("r".into(), m);
        for (k, c) in cells.iter().enumerate() {
            e.push(ElemId(k as u32), c.map(|c| pts[c as usize]), *c);
        }
        let mut b = CorotBlock(e);
        b.prepare(pts.len());
        b
    }
    let (q, t, qm) = (block::<Q4, 4>(m, &pts, &quads), block::<T3, 3>(m, &pts, &tris), block::<Qm6, 4>(m, &pts, &quads));
    let qc = block::<Q4Closed, 4>(m, &pts, &quads);
    let turned = |deg: f64, strain: f64| -> Vec<[f64; 2]> {
        let (c, sn) = (deg.to_radians().cos(), deg.to_radians().sin());
        pts.iter()
            .map(|p| {
                let x = [p[0] * (1.0 + strain) + 0.5 * strain * p[1], p[1] * (1.0 - 0.3 * strain)];
                [c * x[0] - sn * x[1] - p[0], sn * x[0] + c * x[1] - p[1]]
            })
            .collect()
    };
    type Pass<'a> = &'a dyn Fn(std::ops::Range<usize>, &[[f64; 2]], &mut [[f64; 2]], Option<Simd>) -> bool;
    let passes: [(&str, usize, Pass); 4] = [
        ("q4_closed", qc.len(), &|r, u, f, simd| match simd {
            None => {
                qc.add_internal_forces_reference(r, u, f);
                true
            }
            Some(s) => qc.0.corot_forces_simd(r, u, f, s),
        }),
        ("q4", q.len(), &|r, u, f, simd| match simd {
            None => {
                q.add_internal_forces_reference(r, u, f);
                true
            }
            Some(s) => q.0.corot_forces_simd(r, u, f, s),
        }),
        ("t3", t.len(), &|r, u, f, simd| match simd {
            None => {
                t.add_internal_forces_reference(r, u, f);
                true
            }
            Some(s) => t.0.corot_forces_simd(r, u, f, s),
        }),
        ("qm6", qm.len(), &|r, u, f, simd| match simd {
            None => {
                qm.add_internal_forces_reference(r, u, f);
                true
            }
            Some(s) => qm.0.corot_forces_simd(r, u, f, s),
        }),
    ];
    let bits = |f: &[[f64; 2]]| f.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
    let entry = |name: &str, u: &[[f64; 2]]| {
        let mut f = vec![[0.0; 2]; pts.len()];
        match name {
            "q4" => q.add_internal_forces(u, &mut f),
            "t3" => t.add_internal_forces(u, &mut f),
            "q4_closed" => qc.add_internal_forces(u, &mut f),
            _ => qm.add_internal_forces(u, &mut f),
        }
        f
    };
    for (name, len, pass) in passes {
        let run = |r: std::ops::Range<usize>, u: &[[f64; 2]], simd| {
            let mut f = vec![[0.0; 2]; pts.len()];
            pass(r, u, &mut f, simd).then_some(f)
        };
        let mut strained_scale = 0.0f64;
        for deg in [0.0, 30.0, 90.0, 135.0, 170.0] {
            let u = turned(deg, 1e-3);
            let reference = run(0..len, &u, None).unwrap();
            let plain = run(0..len, &u, Some(Simd::Plain)).expect("the baseline always runs");
            let scale = reference.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
            strained_scale = strained_scale.max(scale);
            assert!(scale > 0.0);
            for (a, b) in plain.iter().flatten().zip(reference.iter().flatten()) {
                assert!((a - b).abs() <= 1e-12 * scale, "{name} at {deg} deg: blocked {a} against reference {b} (largest force {scale})");
            }
            for simd in [Simd::Avx2, Simd::Avx512] {
                if let Some(f) = run(0..len, &u, Some(simd)) {
                    assert_eq!(bits(&f), bits(&plain), "{name} at {deg} deg: {simd:?} differs from the baseline");
                }
            }
            // The step's entry point (`Block::add_internal_forces`, the widest unit of this CPU).
            let step = entry(name, &u);
            assert_eq!(bits(&step), bits(&plain), "{name} at {deg} deg: Block::add_internal_forces differs from the baseline");
            // Two sub-ranges (the cut inside a pack) add up to the whole pass.
            let cut = 3 * LANES + 3;
            let mut f = vec![[0.0; 2]; pts.len()];
            pass(0..cut, &u, &mut f, Some(Simd::Plain));
            pass(cut..len, &u, &mut f, Some(Simd::Plain));
            assert_eq!(bits(&f), bits(&plain), "{name} at {deg} deg: two sub-ranges differ from the whole range");
        }
        let rigid = run(0..len, &turned(170.0, 0.0), Some(Simd::Plain)).unwrap();
        let worst = rigid.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(worst <= 1e-9 * strained_scale, "{name}: a rigid rotation gives a force {worst} (strained {strained_scale})");
    }
}
