//! The Brazilian test in 3D (issue 38 must-show 3, second half; configs/3d/brazilian.toml,
//! docs/3d.md "The Brazilian disc"): a disc of diameter D = 50 mm and thickness t = 25 mm
//! loaded by a radial pressure p over two diametral strips of arc 2 alpha = 15 deg, held by a
//! statically determinate support. Rankine (f_t = 5 MPa) with the paper's separation rule
//! (`sigma1_nearest`, read in 3D). References and tolerances at each test.
//!
//! Reference (Hondros 1959; the plane-stress disc under a radial pressure p over the arcs
//! 2 alpha centred on the y axis): on the loaded diameter, at rho = r / R,
//! sigma_xx = (2 p / pi) [ (1 - rho^2) sin 2 alpha / (1 - 2 rho^2 cos 2 alpha + rho^4)
//! - atan((1 + rho^2) / (1 - rho^2) tan alpha) ], at the centre (2 p / pi) (sin 2 alpha - alpha)
//! = 2 P / (pi D t) (sin 2 alpha / alpha - 1) with Hondros's load P = p alpha D t (the strip
//! correction 0.97717 at 2 alpha = 15 deg). With nu = 0 the plane-stress field is the exact 3D
//! field of the disc (no out-of-plane strain, faces traction-free), so the 3D body must converge
//! to it; with nu > 0 the 3D disc differs from it (the faces' centre is more tensile than the
//! mid-plane's), so the nu = 0.2 scene is compared loosely.

use flem_core::mesh::{AnyMesh, RawMesh3};
use flem_core::plugin::traits::principal3;
use flem_core::scene3::Scene3;
use flem_core::solver::march3::March3;
use flem_plugins::check::solid3::{self, FaceLoad, FaceLoadKind, Problem3};

use crate::common::root;

const F_T: f64 = 5.0;
const R: f64 = 25.0;

/// Hondros's sigma_xx at the centre per unit strip pressure.
fn hondros_centre() -> f64 {
    let a = 7.5f64.to_radians();
    2.0 / std::f64::consts::PI * ((2.0 * a).sin() - a)
}

fn mesh(file: &str) -> RawMesh3 {
    flem_plugins::link();
    let src: Box<dyn flem_core::mesh::MeshSource> = toml::from_str(&format!("type = \"gmsh\"\nfile = \"{file}\"")).unwrap();
    let AnyMesh::Three(mut m) = src.load_any(&root().join("configs/3d")).unwrap() else { panic!("{file} is 3D") };
    m.validate(flem_core::mesh::ValidationOptions::Refuse).unwrap();
    m
}

/// The largest edge of the cells at each point (the local element size).
fn local_size(m: &RawMesh3) -> Vec<f64> {
    let mut l = vec![0.0f64; m.points.len()];
    for c in &m.cells {
        let k = c.corners();
        for (i, &a) in k.iter().enumerate() {
            for &b in &k[i + 1..] {
                let (xa, xb) = (m.points[a as usize], m.points[b as usize]);
                let d = ((xa[0] - xb[0]).powi(2) + (xa[1] - xb[1]).powi(2) + (xa[2] - xb[2]).powi(2)).sqrt();
                for &p in &[a, b] {
                    l[p as usize] = l[p as usize].max(d);
                }
            }
        }
    }
    l
}

/// The linear solution under p = 1 on both strips (the implicit solve, `check::solid3`, which
/// tests/march3.rs verifies equal to the march's equilibrium to 4e-11), the support of the
/// scene (a: xyz, b: yz, c: y): the Rankine initiation pressure `f_t / max sigma_1` and the point
/// where sigma_1 is largest.
fn initiation(m: &RawMesh3, nu: f64) -> (f64, usize) {
    let mut p = Problem3::new(m, 20000.0, nu);
    for (set, bits) in [("a", 7u8), ("b", 6), ("c", 2)] {
        for &q in &m.node_sets[set] {
            p.fix[q as usize] |= bits;
        }
    }
    for s in ["strip_top", "strip_bottom"] {
        p.face_loads.push(FaceLoad { faces: m.face_sets[s].clone(), load: FaceLoadKind::Pressure(1.0) });
    }
    let sol = solid3::solve(&p).unwrap();
    let s1: Vec<f64> = sol.nodal_stress.iter().map(|&s| -principal3(s).p.s3).collect();
    let k = (0..s1.len()).fold(0, |b, i| if s1[i] > s1[b] { i } else { b });
    (F_T / s1[k], k)
}

/// Initiation against Hondros. With nu = 0 (the 3D field is Hondros's plane-stress field), on
/// the scene's mesh (h = 5 mm, strips' edges 2.5 mm) and a finer one (h = 3.5 mm): the Rankine
/// initiation pressure p_i = f_t / max sigma_1 against Hondros's f_t / (2 (sin 2 alpha - alpha)
/// / pi) = 61.398 MPa. Tolerances: 8 % on the coarse mesh, 5 % on the finer one, and the error
/// must fall with h (measured +6.1 % and +3.2 %, as h^1.8 between the two meshes: the
/// constant-strain tetrahedra's averaged nodal stress is low). The failing point lies
/// near the centre: within its local element size of the loaded plane x = 0 and at |y| <= 0.4 R
/// (Hondros's sigma_xx on the loaded diameter is within 3.4 % of its centre value up to
/// rho = 0.4, inside the coarse mesh's error, so the maximum may sit anywhere there). With the
/// scene's nu = 0.2 the 3D disc's faces are more tensile than Hondros's plane stress and the
/// mid-plane less, and the largest sigma_1 lies on a face: p_i within 10 % of Hondros
/// (measured: -0.8 % coarse, -8.1 % fine, the fine mesh's first failure on the face z = t at
/// y = -11.6 mm: the faces' 3D excess against the mesh's deficit; its place is not asserted).
#[test]
fn brazilian_initiation_against_hondros() {
    let p_h = F_T / hondros_centre();
    let mut errs = Vec::new();
    for (file, tol) in [("brazilian_h5_v41.msh", 0.08), ("brazilian_h3.5_v41.msh", 0.05)] {
        let m = mesh(file);
        let l = local_size(&m);
        let (p_i, k) = initiation(&m, 0.0);
        let x = m.points[k];
        let e = p_i / p_h - 1.0;
        eprintln!("{file} nu = 0: {} points, p_i = {p_i:.4} (Hondros {p_h:.4}, {:+.2} %) at {x:?}", m.points.len(), 100.0 * e);
        assert!(e.abs() <= tol, "{file}: initiation at p = {p_i}, Hondros {p_h}");
        assert!(x[0].abs() <= l[k] && x[1].abs() <= 0.4 * R, "{file}: the first failure at {x:?} is not near the centre (local size {})", l[k]);
        errs.push(e.abs());
        let (p2, k2) = initiation(&m, 0.2);
        let e2 = p2 / p_h - 1.0;
        eprintln!("{file} nu = 0.2: p_i = {p2:.4} ({:+.2} % of Hondros's plane stress) at {:?}", 100.0 * e2, m.points[k2]);
        assert!(e2.abs() <= 0.10, "{file} nu = 0.2: {p2}");
    }
    assert!(errs[1] < errs[0], "the error does not fall with the mesh size: {errs:?}");
}

/// The split (configs/3d/brazilian.toml as written: nu = 0.2, h = 5 mm, local damping, Rankine
/// and `sigma1_nearest`, checks at rest, 32 splits per check). First the march at rest under
/// p = 1: its initiation pressure equals the implicit solve's to 1e-3 (the ratio 1e-7 leaves
/// less). Then the scene's "cracking" stage (p = 70, 1.15 times initiation), relaxed to a ratio
/// of 1e-4 before each check until a check splits nothing:
/// - the first split lies near the centre (within its local element size of x = 0, |y| <= 0.4 R);
/// - every split point lies within its local element size (the longest edge of its cells) of
///   the loaded plane x = 0, except points within one local size of a strip's edge (x = +-R sin
///   alpha on the side face), where the pressure jumps and wedge splits under the strips' edges
///   are the known secondary failure of the test;
/// - the crack runs towards both strips: splits beyond |y| = 0.7 R on both sides, where the
///   uncracked body's tension (Hondros) is 65 % of the centre's, below f_t / 1.15 = 0.87 of it:
///   the crack got there by its own stress concentration, not by the elastic field.
///
/// Measured: 169 splits, y from -20.3 to 24.5 mm; two points (z = 0 and 1.7, near the top
/// strip's edge) beyond one local size of the plane.
#[test]
fn brazilian_splits_along_the_loaded_plane() {
    flem_plugins::link();
    let mut sc = Scene3::from_file(&root().join("configs/3d/brazilian.toml")).unwrap();
    let mut m = March3::from_scene(&mut sc).unwrap();
    let l = local_size(&m.mesh);
    let cr = sc.file.cracking.as_ref().unwrap();
    let one = [("top".to_string(), 1.0), ("bottom".to_string(), 1.0)].into();
    m.set_levels(&one);
    m.run_to_rest(1e-7, 10, 100_000).unwrap();
    assert!(m.ratio <= 1e-7, "not at rest: {}", m.ratio);
    let s1max = m.nodal_stress().iter().map(|&s| -principal3(s).p.s3).fold(f64::MIN, f64::max);
    let (p_imp, _) = initiation(&m.mesh, 0.2);
    let p_march = F_T / s1max;
    eprintln!("march initiation p = {p_march:.5}, implicit {p_imp:.5}");
    assert!((p_march / p_imp - 1.0).abs() <= 1e-3, "{p_march} vs {p_imp}");

    let levels = sc.stage_levels();
    let st = sc.file.stages.iter().position(|s| s.name == "cracking").unwrap();
    let p = levels[st]["top"];
    assert!(p > 1.1 * p_march && p < 1.2 * p_march, "the cracking stage's p = {p} is not about 1.15 times initiation {p_march}");
    m.set_levels(&levels[st]);
    let mut split: Vec<[f64; 3]> = Vec::new();
    let mut pts: Vec<usize> = Vec::new();
    loop {
        m.run_to_rest(1e-4, 10, 60_000).unwrap();
        assert!(m.ratio <= 1e-4, "not at rest after {} splits: {}", split.len(), m.ratio);
        let rec = m.check_failure(cr.criterion.as_ref(), cr.separation.as_ref(), cr.max_splits_per_check).unwrap();
        if rec.is_empty() {
            break;
        }
        for c in &rec.new_clusters {
            split.push(m.mesh.points[c.point.idx()]);
            pts.push(c.point.idx());
        }
    }
    let (ymin, ymax) = split.iter().fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x[1]), b.max(x[1])));
    eprintln!("{} splits, y from {ymin:.2} to {ymax:.2}, first at {:?}", split.len(), split.first());
    assert!(split.len() >= 20, "{} splits", split.len());
    let x0 = split[0];
    assert!(x0[0].abs() <= l[pts[0]] && x0[1].abs() <= 0.4 * R, "the first split at {x0:?} is not near the centre");
    let xs = R * 7.5f64.to_radians().sin();
    let ys = R * 7.5f64.to_radians().cos();
    let mut off = 0;
    for (x, &q) in split.iter().zip(&pts) {
        if x[0].abs() <= l[q] {
            continue;
        }
        let edge = (x[0].abs() - xs).hypot(x[1].abs() - ys);
        assert!(edge <= l[q], "split at {x:?}: {:.2} from x = 0 and {edge:.2} from a strip's edge, local size {:.2}", x[0].abs(), l[q]);
        off += 1;
    }
    eprintln!("{off} split points beyond one local size of x = 0, all at a strip's edge");
    assert!(ymin <= -0.7 * R && ymax >= 0.7 * R, "the crack does not run towards both strips: y from {ymin} to {ymax}");
}

/// The crack faces of a 3D run in ParaView's and meshio's hands (`cracks_NNNN_stageK.vtu`,
/// `output::run3::crack_faces3`): configs/3d/notched_bar.toml (bricks, the notch y = 1,
/// 0 <= x <= 0.25 pre-separated) to rest under its first stage's pull, no split. Read back by
/// meshio 5.3.5 and pyvista (tests/python/read_vtu3.py): both sides of every notch face, as
/// quads (VTK 9) whose corners lie on the notch plane y = 1 at x <= 0.25 (exact); `opening`
/// equals the gap `u_side1 - u_side0` recomputed from the file's `displacement` and corners
/// along the side-0 normal (1e-12 of the largest opening), and is positive on every face
/// (tension opens the notch: the physics' sign), largest at the mouth x = 0; the snapshot's
/// `cracked_faces` counts each notch face once on each side.
#[test]
fn crack_faces_vtu_reads_back() {
    flem_plugins::link();
    let mut sc = Scene3::from_file(&root().join("configs/3d/notched_bar.toml")).unwrap();
    sc.file.stages.truncate(1);
    sc.file.cracking = None;
    let dir = std::env::temp_dir().join(format!("flem-cracks3-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let (m, _) = flem_core::output::run3::run3_in_folder(&mut sc, &dir).unwrap();
    let n_notch = m.mesh.face_sets["notch"].len();
    let py = std::env::var("FLEM_PYTHON").unwrap_or_else(|_| {
        let v = root().join(".venv/bin/python");
        if v.exists() {
            v.display().to_string()
        } else {
            "python3".into()
        }
    });
    let read = |f: &str| -> serde_json::Value {
        let out = std::process::Command::new(&py).arg(root().join("tests/python/read_vtu3.py")).arg(dir.join(f)).output().unwrap();
        assert!(out.status.success(), "{py}: {}", String::from_utf8_lossy(&out.stderr));
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let v = read("cracks_0000_stage0.vtu");
    let num = |x: &serde_json::Value| x.as_f64().unwrap();
    for reader in ["meshio", "pyvista"] {
        let r = &v[reader];
        let pts: Vec<[f64; 3]> = r["points"].as_array().unwrap().iter().map(|p| [num(&p[0]), num(&p[1]), num(&p[2])]).collect();
        let u: Vec<[f64; 3]> = r["point_data"]["displacement"].as_array().unwrap().iter().map(|p| [num(&p[0]), num(&p[1]), num(&p[2])]).collect();
        let polys: Vec<Vec<usize>> = match reader {
            "meshio" => r["cells"]
                .as_array()
                .unwrap()
                .iter()
                .map(|c| {
                    assert_eq!(c[0], "quad");
                    c[1].as_array().unwrap().iter().map(|x| x.as_u64().unwrap() as usize).collect()
                })
                .collect(),
            _ => {
                assert!(r["celltypes"].as_array().unwrap().iter().all(|t| t == 9));
                r["cells"].as_array().unwrap().iter().map(|c| c.as_array().unwrap().iter().map(|x| x.as_u64().unwrap() as usize).collect()).collect()
            }
        };
        assert_eq!(polys.len(), 2 * n_notch, "{reader}: both sides of each notch face");
        let cd = |k: &str| -> Vec<f64> { r["cell_data"][k].as_array().unwrap().iter().map(num).collect() };
        let (opening, side) = (cd("opening"), cd("side"));
        let omax = opening.iter().fold(0.0f64, |a, &b| a.max(b));
        let mut mouth = (0.0, f64::MAX);
        for (k, p) in polys.iter().enumerate() {
            assert!(p.iter().all(|&q| pts[q][1] == 1.0 && pts[q][0] <= 0.25), "{reader}: polygon {k} off the notch");
            assert_eq!(side[k], (k % 2) as f64);
            assert!(opening[k] > 0.0, "{reader}: the notch face {k} does not open ({})", opening[k]);
            if k % 2 == 1 {
                // Side 1 is wound the other way: its corner j is side 0's corner (n - 1 - j).
                let (p0, p1) = (&polys[k - 1], p);
                let nn = p0.len();
                let x: Vec<[f64; 3]> = p0.iter().map(|&q| pts[q]).collect();
                let (a, b) = ([x[1][0] - x[0][0], x[1][1] - x[0][1], x[1][2] - x[0][2]], [x[2][0] - x[0][0], x[2][1] - x[0][1], x[2][2] - x[0][2]]);
                let n = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
                let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                let mut g = 0.0;
                for j in 0..nn {
                    let (q0, q1) = (p0[j], p1[nn - 1 - j]);
                    assert_eq!(pts[q0], pts[q1], "{reader}: the sides' corners differ");
                    g += (0..3).map(|d| (u[q1][d] - u[q0][d]) * n[d] / l).sum::<f64>() / nn as f64;
                }
                assert!((g - opening[k]).abs() <= 1e-12 * omax, "{reader}: face {k}: opening {} but the gap is {g}", opening[k]);
                let xmean = x.iter().map(|p| p[0]).sum::<f64>() / nn as f64;
                if xmean < mouth.1 - 1e-12 {
                    mouth = (opening[k], xmean);
                } else if (xmean - mouth.1).abs() <= 1e-12 {
                    mouth.0 = f64::max(mouth.0, opening[k]);
                }
            }
        }
        eprintln!("{reader}: {} polygons, largest opening {omax:.4e}, at the mouth {:.4e}", polys.len(), mouth.0);
        assert!(mouth.0 >= omax * (1.0 - 1e-9), "{reader}: the opening is not largest at the mouth");
    }
    let s = read("snapshot_0000_stage0.vtu");
    let cracked: f64 = s["meshio"]["cell_data"]["cracked_faces"].as_array().unwrap().iter().map(num).sum();
    assert_eq!(cracked, 2.0 * n_notch as f64);
    let _ = std::fs::remove_dir_all(&dir);
}
