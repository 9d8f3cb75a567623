//! Interoperability: what we write, meshio reads identically; what gmsh writes, we read as
//! meshio does (issue 6). These tests need Python with meshio (`bash .ci/run` installs it into
//! .venv); they fail, rather than skip, when it is missing.
use std::process::Command;

use flem_core::output::{snapshot_vtk, vtu_bytes};
use flem_core::solver::NoOutput;

use crate::common::{root, sim};

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
    assert!(out.status.success(), "{} {:?} failed: {}\n(meshio missing? `bash .ci/run` installs it into .venv)", python(), args, String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// A run's VTU, read back by meshio: same points, cells (elements and crack lines) and arrays,
/// value for value (raw and zlib). Reference: our in-memory state.
#[test]
fn meshio_reads_our_vtu() {
    let mut s = sim(r#"
[mesh]
type = "rectangle"
width = 4.0
height = 2.0
nx = 8
ny = 4
notch = { side = "left", y = 1.0, depth = 1.0 }
[model]
separated = ["notch"]
[[material]]
young_modulus = 100.0
poisson_ratio = 0.3
density = 1.0
[[support]]
nodes = "bottom"
fix = "xy"
[[load]]
name = "pull"
type = "traction"
edges = "top"
value = [0.0, 1.0]
[[stage]]
levels = { pull = 1.0 }
"#);
    s.run(&mut NoOutput).unwrap();
    let dir = std::env::temp_dir().join(format!("flem-interop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for compress in [false, true] {
        let path = dir.join(format!("snap_{compress}.vtu"));
        std::fs::write(&path, vtu_bytes(snapshot_vtk(&s), compress).unwrap()).unwrap();
        let v = run_py(&[root().join("tests/python/read_vtu.py").to_str().unwrap(), path.to_str().unwrap()]);
        let pts = v["points"].as_array().unwrap();
        assert_eq!(pts.len(), s.model.topo.n_clusters());
        for (c, p) in pts.iter().enumerate() {
            assert_eq!(p[0].as_f64().unwrap(), s.x0[c][0]);
            assert_eq!(p[1].as_f64().unwrap(), s.x0[c][1]);
        }
        let quads = v["cells"]["quad"].as_array().unwrap();
        assert_eq!(quads.len(), s.model.n_elems());
        for (e, q) in quads.iter().enumerate() {
            // vtkio writes UInt64 connectivity, which meshio hands back as float64: compare as integers.
            let conn: Vec<u64> = q.as_array().unwrap().iter().map(|x| x.as_f64().unwrap() as u64).collect();
            let mine: Vec<u64> = s.model.topo.elem_copies(flem_core::ids::ElemId::new(e)).map(|k| s.model.topo.copy_cluster[k].0 as u64).collect();
            assert_eq!(conn, mine);
        }
        // The notch: 2 elements' faces per separated edge, drawn as lines.
        let (one, two) = s.model.topo.crack_counts();
        assert!(one + two >= 2);
        assert_eq!(v["cells"]["line"].as_array().unwrap().len(), 2 * (one + two));
        let disp = v["point_data"]["displacement"].as_array().unwrap();
        for (c, d) in disp.iter().enumerate() {
            assert_eq!(d[0].as_f64().unwrap(), s.state.u[c][0]);
            assert_eq!(d[1].as_f64().unwrap(), s.state.u[c][1]);
        }
        assert!(v["cell_data"]["crack"].is_array() && v["cell_data"]["stress"].is_array());
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Our gmsh importer and meshio see the same node and cell counts and the same physical
/// groups in every .msh file of configs/meshes (2.2 and 4.1, ASCII and binary).
/// Reference: meshio 5.3.5.
#[test]
fn gmsh_files_read_as_meshio_reads_them() {
    flem_plugins::link();
    let dir = root().join("configs/meshes");
    let mut files: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|e| e == "msh")).collect();
    files.sort();
    assert!(files.len() >= 5);
    let args: Vec<String> = std::iter::once(root().join("tools/mesh_compare.py").display().to_string()).chain(files.iter().map(|f| f.display().to_string())).collect();
    let argv: Vec<&str> = args.iter().map(String::as_str).collect();
    let v = run_py(&argv);
    for (f, rec) in files.iter().zip(v["files"].as_array().unwrap()) {
        assert!(rec["ok"].as_bool().unwrap(), "{}: meshio failed: {}", f.display(), rec["error"]);
        let src: Box<dyn flem_core::mesh::MeshSource> = toml::from_str(&format!("type = \"gmsh\"\nfile = {:?}", f.display().to_string())).unwrap();
        let m = src.load(&dir).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(m.points.len() as u64, rec["nodes_2d"].as_u64().unwrap(), "{}", f.display());
        let tri = m.cells.iter().filter(|c| c.kind == flem_core::mesh::CellKind::T3).count() as u64;
        let quad = m.cells.len() as u64 - tri;
        assert_eq!(tri, rec["cells_2d"]["triangle"].as_u64().unwrap(), "{}", f.display());
        assert_eq!(quad, rec["cells_2d"]["quad"].as_u64().unwrap(), "{}", f.display());
        let lines: Vec<&str> = rec["physical_groups"]["1"].as_array().unwrap().iter().map(|x| x.as_str().unwrap()).collect();
        let mine: Vec<&str> = m.edge_sets.keys().map(String::as_str).collect();
        assert_eq!(mine, lines, "{}", f.display());
        let mut regions: Vec<&str> = m.cell_region.iter().map(String::as_str).collect();
        regions.sort();
        regions.dedup();
        let surf: Vec<&str> = rec["physical_groups"]["2"].as_array().unwrap().iter().map(|x| x.as_str().unwrap()).collect();
        assert_eq!(regions, surf, "{}", f.display());
    }
}

/// End to end as a user does it: `flem run` on a scene over a gmsh mesh (and on a cracking
/// scene), then the run directory opened by meshio through results.pvd (and by pyvista/VTK
/// where it installs: `bash .ci/run` tries). Reference: the same scene run in-process, whose
/// final displacements must come back bit for bit; every PVD entry must exist and read.
#[test]
fn gmsh_scene_runs_end_to_end_and_opens_in_meshio() {
    for (scene_path, n_stages, cracks) in [("configs/meshes/gmsh_bar.toml", 1, false), ("configs/verification/tension_crack.toml", 2, true)] {
        let dir = std::env::temp_dir().join(format!("flem-e2e-{}-{}", std::process::id(), n_stages));
        let _ = std::fs::remove_dir_all(&dir);
        let out = Command::new(crate::common::flem_exe()).args(["run", root().join(scene_path).to_str().unwrap(), "--out", dir.to_str().unwrap(), "--quiet"]).output().unwrap();
        assert!(out.status.success(), "{scene_path}: {}", String::from_utf8_lossy(&out.stderr));
        let v = run_py(&[root().join("tests/python/read_run.py").to_str().unwrap(), dir.to_str().unwrap()]);
        let ds = v["datasets"].as_array().unwrap();
        assert_eq!(ds.len(), n_stages, "{scene_path}: one snapshot per stage");
        // the same scene in-process
        flem_plugins::link();
        let sc = flem_core::scene::Scene::from_file(&root().join(scene_path)).unwrap();
        let mut s = flem_core::solver::Simulation::new(sc).unwrap();
        s.run(&mut NoOutput).unwrap();
        let last = &ds[n_stages - 1];
        let disp = last["point_data"]["displacement"].as_array().unwrap();
        assert_eq!(disp.len(), s.model.topo.n_clusters(), "{scene_path}");
        for (c, d) in disp.iter().enumerate() {
            assert_eq!([d[0].as_f64().unwrap(), d[1].as_f64().unwrap()], s.state.u[c], "{scene_path}: cluster {c}");
        }
        assert_eq!(last["timestep"].as_f64().unwrap(), s.state.time);
        assert_eq!(last["cells"].get("line").is_some(), cracks, "{scene_path}: crack lines");
        match v["pyvista"].as_object() {
            Some(pv) => {
                let blocks = pv["blocks"].as_array().unwrap();
                assert_eq!(blocks.len(), n_stages);
                let b = &blocks[n_stages - 1];
                assert_eq!(b["points"].as_u64().unwrap() as usize, s.model.topo.n_clusters());
                let d = b["displacement"].as_array().unwrap();
                for (c, d) in d.iter().enumerate() {
                    assert_eq!(d[0].as_f64().unwrap(), s.state.u[c][0], "pyvista, {scene_path}: cluster {c}");
                }
                println!("{scene_path}: meshio and pyvista {} read {} snapshots", pv["version"], blocks.len());
            }
            None => println!("{scene_path}: meshio read it; {}", v["pyvista_error"]),
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
