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

/// A 2D mesh read through `load_any` is exactly the mesh of `load` (the 2D path unchanged);
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
