//! 3D meshes in and out (issue 38): gmsh files with tetrahedra and hexahedra read as meshio
//! reads them, in both msh versions (ASCII and binary); the refusals of the importer and of
//! `RawMesh3::validate`, named; the 3D VTU read back by meshio and pyvista. These tests need
//! Python with meshio and pyvista (`bash .ci/run` installs them into .venv; FLEM_PYTHON names
//! another interpreter); they fail, rather than skip, when it is missing.
use std::path::{Path, PathBuf};
use std::process::Command;

use flem_core::mesh::{AnyMesh, CellKind3, MeshSource, RawMesh3, ValidationOptions};

use crate::common::root;

fn python() -> String {
    std::env::var("FLEM_PYTHON").unwrap_or_else(|_| {
        let venv = root().join(".venv/bin/python");
        if venv.exists() {
            venv.display().to_string()
        } else {
            "python3".into()
        }
    })
}

fn run_py(args: &[&str]) -> serde_json::Value {
    let out = Command::new(python()).args(args).output().unwrap_or_else(|e| panic!("cannot run {}: {e}; run `bash .ci/run` once to create .venv with meshio", python()));
    assert!(out.status.success(), "{} {:?} failed: {}\n(meshio or pyvista missing? `bash .ci/run` installs them into .venv)", python(), args, String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

fn gmsh_source(file: &str) -> Box<dyn MeshSource> {
    flem_plugins::link();
    toml::from_str(&format!("type = \"gmsh\"\nfile = {file:?}")).unwrap()
}

/// The 3D mesh of a file (relative to `dir`), or the error of `load_any`.
fn load3(dir: &Path, file: &str) -> flem_core::Result<RawMesh3> {
    match gmsh_source(file).load_any(dir)? {
        AnyMesh::Three(m) => Ok(m),
        AnyMesh::Two(_) => panic!("{file}: read as 2D"),
    }
}

fn dir3() -> PathBuf {
    root().join("configs/3d")
}

fn xyz(v: &serde_json::Value) -> [f64; 3] {
    let a = v.as_array().unwrap();
    [a[0].as_f64().unwrap(), a[1].as_f64().unwrap(), a[2].as_f64().unwrap()]
}

/// Every 3D gmsh file of configs/3d, read by our importer and by meshio 5.3.5 (the reference,
/// tests/python/read_msh3.py), gives the same cells (kind and corner coordinates, in order,
/// bit for bit), regions, face sets (faces by corner coordinates in the file's order) and node
/// sets, and the same number of points; every file validates without a reoriented cell.
#[test]
fn gmsh_3d_files_read_as_meshio_reads_them() {
    let dir = dir3();
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir).unwrap().flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|e| e == "msh")).collect();
    files.sort();
    assert!(files.len() >= 11, "{files:?}");
    let args: Vec<String> = std::iter::once(root().join("tests/python/read_msh3.py").display().to_string()).chain(files.iter().map(|f| f.display().to_string())).collect();
    let argv: Vec<&str> = args.iter().map(String::as_str).collect();
    let v = run_py(&argv);
    let mut kinds = std::collections::BTreeSet::new();
    for (f, rec) in files.iter().zip(v["files"].as_array().unwrap()) {
        let name = f.file_name().unwrap().to_str().unwrap();
        let mut m = load3(&dir, name).unwrap_or_else(|e| panic!("{e}"));
        let w = m.validate(ValidationOptions::Refuse).unwrap_or_else(|e| panic!("{e}"));
        assert!(w.is_empty(), "{name}: {w:?}");
        assert_eq!(m.points.len() as u64, rec["points_3d"].as_u64().unwrap(), "{name}");
        let cells = rec["cells"].as_array().unwrap();
        assert_eq!(m.cells.len(), cells.len(), "{name}");
        for (e, (c, r)) in m.cells.iter().zip(cells).enumerate() {
            let kind = match r[0].as_str().unwrap() {
                "tetra" => CellKind3::T4,
                "hexahedron" => CellKind3::H8,
                t => panic!("{name}: meshio type {t}"),
            };
            kinds.insert((kind, name.contains("_v22")));
            assert_eq!(c.kind, kind, "{name}: cell {e}");
            let theirs: Vec<[f64; 3]> = r[1].as_array().unwrap().iter().map(xyz).collect();
            let ours: Vec<[f64; 3]> = c.corners().iter().map(|&p| m.points[p as usize]).collect();
            assert_eq!(ours, theirs, "{name}: cell {e}");
        }
        let regions: Vec<&str> = rec["region"].as_array().unwrap().iter().map(|x| x.as_str().unwrap()).collect();
        assert_eq!(m.cell_region, regions, "{name}");
        let sorted = |mut v: Vec<Vec<[f64; 3]>>| {
            v.sort_by(|a, b| a.partial_cmp(b).unwrap());
            v
        };
        let theirs = rec["face_sets"].as_object().unwrap();
        assert_eq!(m.face_sets.keys().collect::<Vec<_>>(), theirs.keys().collect::<Vec<_>>(), "{name}");
        for (set, faces) in &m.face_sets {
            let ours = sorted(faces.iter().map(|f| f.corners().iter().map(|&p| m.points[p as usize]).collect()).collect());
            let t = sorted(theirs[set].as_array().unwrap().iter().map(|f| f.as_array().unwrap().iter().map(xyz).collect()).collect());
            assert_eq!(ours, t, "{name}: face set {set}");
        }
        let theirs = rec["node_sets"].as_object().unwrap();
        assert_eq!(m.node_sets.keys().collect::<Vec<_>>(), theirs.keys().collect::<Vec<_>>(), "{name}");
        for (set, pts) in &m.node_sets {
            let mut ours: Vec<[f64; 3]> = pts.iter().map(|&p| m.points[p as usize]).collect();
            ours.sort_by(|a, b| a.partial_cmp(b).unwrap());
            let t: Vec<[f64; 3]> = theirs[set].as_array().unwrap().iter().map(xyz).collect();
            assert_eq!(ours, t, "{name}: node set {set}");
        }
    }
    // Both kinds in both versions.
    assert_eq!(kinds.len(), 4, "{kinds:?}");
}

/// The same mesh written by gmsh in msh 2.2 and 4.1, ASCII and binary, reads as the same
/// RawMesh3 (points equal to the 16 digits the ASCII files hold, 1e-14 here; cells, regions,
/// node and face sets identical). Reference: one gmsh run wrote the four files
/// (tools/gen_meshes.py 3d).
#[test]
fn each_kind_reads_the_same_in_both_msh_versions() {
    for kind in ["tet", "hex"] {
        let files: Vec<String> = ["v41", "v41_bin", "v22", "v22_bin"].iter().map(|v| format!("cube_{kind}_{v}.msh")).collect();
        let first = load3(&dir3(), &files[0]).unwrap();
        let (n, c) = if kind == "tet" { (78, 200) } else { (45, 16) };
        assert_eq!((first.points.len(), first.cells.len()), (n, c), "{kind}");
        assert_eq!(first.face_sets.keys().collect::<Vec<_>>(), ["interface", "xmax", "xmin", "zmax"]);
        assert_eq!(first.node_sets.keys().collect::<Vec<_>>(), ["bottom_front", "interface", "origin", "xmax", "xmin", "zmax"]);
        for f in &files[1..] {
            let m = load3(&dir3(), f).unwrap();
            assert_eq!(m.points.len(), first.points.len(), "{f}");
            for (a, b) in m.points.iter().zip(&first.points) {
                assert!((0..3).all(|d| (a[d] - b[d]).abs() < 1e-14), "{f}: {a:?} != {b:?}");
            }
            assert_eq!(m.cells, first.cells, "{f}");
            assert_eq!(m.cell_region, first.cell_region, "{f}");
            assert_eq!(m.node_sets, first.node_sets, "{f}");
            assert_eq!(m.face_sets, first.face_sets, "{f}");
            assert_eq!(m.ids.as_ref().unwrap().cells, first.ids.as_ref().unwrap().cells, "{f}");
        }
    }
}

/// A 2D mesh (gmsh, VTK) read through `load_any` is exactly the mesh of `load` (the 2D path
/// unchanged);
/// a 3D file given to the 2D `load` is refused, saying that it is 3D. Reference: the 2D reader.
#[test]
fn two_d_files_stay_two_d_and_three_d_files_say_so() {
    let meshes = root().join("configs/meshes");
    for f in ["rect_quad_v41.msh", "rect_quad_v22_bin.msh", "plate_hole_v41.msh"] {
        let src = gmsh_source(f);
        let two = src.load(&meshes).unwrap();
        let AnyMesh::Two(any) = src.load_any(&meshes).unwrap() else { panic!("{f}: read as 3D") };
        assert_eq!(format!("{two:?}"), format!("{any:?}"), "{f}");
    }
    for f in ["rect_quad.vtu", "rect_tri.vtk"] {
        let src: Box<dyn MeshSource> = toml::from_str(&format!("type = \"vtk\"\nfile = {f:?}")).unwrap();
        let two = src.load(&meshes).unwrap();
        let AnyMesh::Two(any) = src.load_any(&meshes).unwrap() else { panic!("{f}: read as 3D") };
        assert_eq!(format!("{two:?}"), format!("{any:?}"), "{f}");
    }
    for f in ["cube_tet_v41.msh", "cube_hex_v22_bin.msh"] {
        let e = gmsh_source(f).load(&dir3()).unwrap_err().to_string();
        assert!(e.contains(f) && e.contains("is not supported in a 2D mesh: this file has volume elements, it is a 3D mesh"), "{e}");
    }
}

/// Bad 3D files are refused by name (tests/data/mesh3, one defect each): the element tag and
/// the node tags of the file, the file's name. Reference: the handmade files.
#[test]
fn bad_3d_files_are_refused_by_name() {
    let dir = root().join("tests/data/mesh3");
    let err = |f: &str| load3(&dir, f).unwrap_err().to_string();
    let e = err("prism.msh");
    assert!(e.contains("prism.msh: element tag 7: element type 6 (6-node prism) is not supported in a 3D mesh"), "{e}");
    let e = err("tet10.msh");
    assert!(e.contains("tet10.msh: element tag 9: element type 11 (10-node second order tetrahedron) is not supported"), "{e}");
    // Inverted: refused, or reoriented with a warning.
    let m = load3(&dir, "inverted_tet.msh").unwrap();
    assert_eq!(m.cell_region, ["rock", "rock"]);
    let e = m.clone().validate(ValidationOptions::Refuse).unwrap_err().to_string();
    assert!(e.contains("inverted_tet.msh: element tag 12 is inverted (negative volume; points [node tags 2, 4, 3, 5])"), "{e}");
    let mut r = m.clone();
    let w = r.validate(ValidationOptions::Reorient).unwrap();
    assert!(w.len() == 1 && w[0].contains("inverted_tet.msh: element tag 12 was inverted (negative volume) and has been reoriented"), "{w:?}");
    let mut f = load3(&dir, "face_not_of_a_cell.msh").unwrap();
    let e = f.validate(ValidationOptions::Reorient).unwrap_err().to_string();
    assert!(e.contains("face_not_of_a_cell.msh: face set \"base\" holds a face that is not a face of any element: points [node tags 1, 2, 5]"), "{e}");
    let mut d = load3(&dir, "duplicate_points.msh").unwrap();
    let e = d.validate(ValidationOptions::Reorient).unwrap_err().to_string();
    assert!(e.contains("duplicate_points.msh: duplicate points: node tag 1 and node tag 6 are both at (0, 0, 0)"), "{e}");
}

/// Flattens a JSON value of nested numbers.
fn flat(v: &serde_json::Value, out: &mut Vec<f64>) {
    match v {
        serde_json::Value::Array(a) => a.iter().for_each(|x| flat(x, out)),
        x => out.push(x.as_f64().unwrap()),
    }
}

fn flat_of(v: &serde_json::Value) -> Vec<f64> {
    let mut out = Vec::new();
    flat(v, &mut out);
    out
}

/// A 3D VTU of bricks and tetrahedra (a distorted 2x2x2 H8 box and a T4 box beside it, in one
/// file), written raw and zlib-compressed, with the stress in both layouts, read back by meshio
/// 5.3.5 and by pyvista 0.49 (VTK's reader): the same points, cell types (VTK 10, 12) and
/// corners, and every point and cell array value for value. Reference: the arrays handed to the
/// writer; exact (f64 written in binary).
#[test]
fn vtu3_reads_back_in_meshio_and_pyvista() {
    use flem_core::mesh::{Box3, RawCell3};
    use flem_core::output::vtu3::{StressLayout, Vtu3};
    let mut b = Box3::new([1.0, 1.0, 1.0], [2, 2, 2], CellKind3::H8);
    b.distort = 0.1;
    let hexes = b.build().unwrap();
    let mut t = Box3::new([1.0, 0.5, 1.0], [1, 1, 1], CellKind3::T4);
    t.origin = [1.5, 0.0, 0.0];
    let tets = t.build().unwrap();
    let off = hexes.points.len() as u32;
    let points: Vec<[f64; 3]> = hexes.points.iter().chain(&tets.points).copied().collect();
    let cells: Vec<RawCell3> = hexes
        .cells
        .iter()
        .copied()
        .chain(tets.cells.iter().map(|c| {
            let mut c = *c;
            c.nodes[..4].iter_mut().for_each(|p| *p += off);
            c
        }))
        .collect();
    let (np, nc) = (points.len(), cells.len());
    let u: Vec<[f64; 3]> = points.iter().map(|x| [1e-3 * x[0] * x[1], -2e-3 * x[2], 0.1 + x[0] / 3.0]).collect();
    let temp: Vec<f64> = points.iter().map(|x| 20.0 + x[0] - x[2] / 7.0).collect();
    let vel: Vec<[f64; 3]> = points.iter().map(|x| [x[2], x[1] * 1e-9, -x[0]]).collect();
    let region: Vec<i32> = cells.iter().map(|c| if c.kind == CellKind3::H8 { 1 } else { 2 }).collect();
    let damage: Vec<f64> = (0..nc).map(|e| e as f64 / 7.0).collect();
    let stress: Vec<[[f64; 3]; 3]> = (0..nc)
        .map(|e| {
            let e = e as f64;
            let (xy, yz, xz) = (0.1 * e, -0.2 * e, 1.0 / (1.0 + e));
            [[1.0 + e, xy, xz], [xy, -e / 3.0, yz], [xz, yz, 2.5e6 * e]]
        })
        .collect();
    let dir = std::env::temp_dir().join(format!("flem-vtu3-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (compress, layout) in [(false, StressLayout::Symmetric6), (true, StressLayout::Full9)] {
        let path = dir.join(format!("snap_{compress}.vtu"));
        Vtu3::new(&points, &cells)
            .displacement(&u)
            .point_scalar("temperature", &temp)
            .point_vector("velocity", &vel)
            .region(&region)
            .stress(&stress, layout)
            .cell_scalar("damage", &damage)
            .write(&path, compress)
            .unwrap();
        let v = run_py(&[root().join("tests/python/read_vtu3.py").to_str().unwrap(), path.to_str().unwrap()]);
        let want_stress: Vec<f64> = match layout {
            StressLayout::Symmetric6 => stress.iter().flat_map(|s| [s[0][0], s[1][1], s[2][2], s[0][1], s[1][2], s[0][2]]).collect(),
            StressLayout::Full9 => stress.iter().flat_map(|s| s.iter().flatten().copied()).collect(),
        };
        let want_point: [(&str, Vec<f64>); 3] = [("displacement", u.iter().flatten().copied().collect()), ("temperature", temp.clone()), ("velocity", vel.iter().flatten().copied().collect())];
        let want_cell: [(&str, Vec<f64>); 3] = [("region", region.iter().map(|&r| r as f64).collect()), ("stress", want_stress), ("damage", damage.clone())];
        for reader in ["meshio", "pyvista"] {
            let r = &v[reader];
            let what = format!("{reader}, compress {compress}");
            assert_eq!(flat_of(&r["points"]), points.iter().flatten().copied().collect::<Vec<_>>(), "{what}");
            let corners: Vec<Vec<u64>> = match reader {
                "meshio" => {
                    let cs = r["cells"].as_array().unwrap();
                    let types: Vec<&str> = cs.iter().map(|c| c[0].as_str().unwrap()).collect();
                    let want: Vec<&str> = cells.iter().map(|c| if c.kind == CellKind3::H8 { "hexahedron" } else { "tetra" }).collect();
                    assert_eq!(types, want, "{what}");
                    cs.iter().map(|c| flat_of(&c[1]).iter().map(|&x| x as u64).collect()).collect()
                }
                _ => {
                    let types: Vec<u64> = r["celltypes"].as_array().unwrap().iter().map(|x| x.as_u64().unwrap()).collect();
                    assert_eq!(types, cells.iter().map(|c| c.kind.vtk_type() as u64).collect::<Vec<_>>(), "{what}");
                    r["cells"].as_array().unwrap().iter().map(|c| flat_of(c).iter().map(|&x| x as u64).collect()).collect()
                }
            };
            assert_eq!(corners, cells.iter().map(|c| c.corners().iter().map(|&p| p as u64).collect()).collect::<Vec<Vec<u64>>>(), "{what}");
            for (name, want) in &want_point {
                assert_eq!(flat_of(&r["point_data"][name]), *want, "{what}: point array {name}");
                assert_eq!(want.len() % np, 0);
            }
            for (name, want) in &want_cell {
                assert_eq!(flat_of(&r["cell_data"][name]), *want, "{what}: cell array {name}");
            }
            assert_eq!(r["point_data"].as_object().unwrap().len(), 3, "{what}");
            assert_eq!(r["cell_data"].as_object().unwrap().len(), 3, "{what}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
