//! Importer tests: every file in configs/meshes, format equivalence, bad inputs with their
//! messages, and a mutation fuzz test (cases from FLEM_FUZZ_CASES, default 256).
use std::path::PathBuf;

use flem_core::mesh::{CellKind, MeshSource, RawMesh, ValidationOptions};

use super::{read_msh_bytes, read_vtk_bytes, Gmsh, Vtk};

fn meshes() -> PathBuf {
    crate::snippets::configs_dir().join("meshes")
}

fn gmsh(file: &str) -> RawMesh {
    let m = Gmsh { file: file.into() }.load(&meshes()).unwrap_or_else(|e| panic!("{file}: {e}"));
    let mut v = m.clone();
    v.validate(ValidationOptions::Refuse).unwrap_or_else(|e| panic!("{file}: {e}"));
    m
}

fn vtk(file: &str, region_array: Option<&str>) -> RawMesh {
    let m = Vtk { file: file.into(), region_array: region_array.map(Into::into) }.load(&meshes()).unwrap_or_else(|e| panic!("{file}: {e}"));
    let mut v = m.clone();
    v.validate(ValidationOptions::Refuse).unwrap_or_else(|e| panic!("{file}: {e}"));
    m
}

fn keys<V>(m: &std::collections::BTreeMap<String, V>) -> Vec<&str> {
    m.keys().map(|s| s.as_str()).collect()
}

fn count(m: &RawMesh, k: CellKind) -> usize {
    m.cells.iter().filter(|c| c.kind == k).count()
}

fn msh_err(text: &str) -> String {
    match read_msh_bytes("test.msh", text.as_bytes()) {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => e.to_string(),
    }
}

const SIDES: [&str; 4] = ["bottom", "left", "right", "top"];

#[test]
fn rectangle_of_quads_in_four_versions_is_identical() {
    let files = ["rect_quad_v41.msh", "rect_quad_v41_bin.msh", "rect_quad_v22.msh", "rect_quad_v22_bin.msh"];
    let first = gmsh(files[0]);
    assert_eq!((first.points.len(), count(&first, CellKind::Q4), first.cells.len()), (45, 32, 32));
    assert!(first.cell_region.iter().all(|r| r == "domain"));
    assert_eq!(keys(&first.edge_sets), SIDES);
    assert_eq!(keys(&first.node_sets), SIDES);
    let lens: Vec<usize> = SIDES.iter().map(|s| first.edge_sets[*s].len()).collect();
    assert_eq!(lens, [8, 4, 4, 8]);
    let lens: Vec<usize> = SIDES.iter().map(|s| first.node_sets[*s].len()).collect();
    assert_eq!(lens, [9, 5, 5, 9]);
    for &i in &first.node_sets["left"] {
        assert!(first.points[i as usize][0].abs() < 1e-12);
    }
    for f in &files[1..] {
        let m = gmsh(f);
        // ASCII files hold 16 significant digits, binary ones all 17: equal to rounding.
        assert_eq!(m.points.len(), first.points.len(), "{f}");
        for (a, b) in m.points.iter().zip(&first.points) {
            assert!((a[0] - b[0]).abs() < 1e-14 && (a[1] - b[1]).abs() < 1e-14, "{f}: {a:?} != {b:?}");
        }
        assert_eq!(m.cells, first.cells, "{f}");
        assert_eq!(m.cell_region, first.cell_region, "{f}");
        assert_eq!(m.node_sets, first.node_sets, "{f}");
        assert_eq!(m.edge_sets, first.edge_sets, "{f}");
    }
}

#[test]
fn every_mesh_file_in_configs_loads_and_validates() {
    let mut n = 0;
    for entry in std::fs::read_dir(meshes()).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_str().unwrap().to_string();
        match path.extension().and_then(|e| e.to_str()) {
            Some("msh") => drop(gmsh(&name)),
            Some("vtu" | "vtk") => drop(vtk(&name, None)),
            _ => continue,
        }
        n += 1;
    }
    assert!(n >= 9, "only {n} mesh files found");
}

#[test]
fn rectangle_of_triangles() {
    let m = gmsh("rect_tri_v22.msh");
    assert_eq!((m.points.len(), count(&m, CellKind::T3), m.cells.len()), (45, 64, 64));
    assert_eq!(keys(&m.edge_sets), SIDES);
    assert!(m.cell_region.iter().all(|r| r == "domain"));
}

#[test]
fn plate_with_hole() {
    let m = gmsh("plate_hole_v41.msh");
    assert_eq!((m.points.len(), count(&m, CellKind::T3), m.cells.len()), (112, 188, 188));
    assert_eq!(keys(&m.edge_sets), ["bottom", "hole", "left", "right", "top"]);
    assert_eq!(keys(&m.node_sets), ["bottom", "hole", "left", "right", "top"]);
    assert!(m.cell_region.iter().all(|r| r == "plate"));
    for &i in &m.node_sets["hole"] {
        let p = m.points[i as usize];
        assert!(((p[0] * p[0] + p[1] * p[1]).sqrt() - 0.5).abs() < 1e-9);
    }
}

#[test]
fn vtu_binary_and_ascii_match_the_msh() {
    let reference = gmsh("rect_quad_v41.msh");
    for f in ["rect_quad.vtu", "rect_quad_ascii.vtu"] {
        let m = vtk(f, None);
        assert_eq!((m.points.len(), count(&m, CellKind::Q4)), (45, 32), "{f}");
        assert!(m.cell_region.iter().all(|r| r == "1"), "{f}");
        // Same cells on the same coordinates (point order may differ).
        let cell_xy = |m: &RawMesh| -> Vec<Vec<[u64; 2]>> {
            let mut v: Vec<Vec<[u64; 2]>> = m.cells.iter().map(|c| c.corners().iter().map(|&n| m.points[n as usize].map(|x| (x * 1e6).round() as u64)).collect()).collect();
            v.sort();
            v
        };
        assert_eq!(cell_xy(&m), cell_xy(&reference), "{f}");
        let explicit = vtk(f, Some("region"));
        assert_eq!(explicit.cell_region, m.cell_region);
    }
}

#[test]
fn legacy_vtk_with_gmsh_physical_lines() {
    let m = vtk("rect_tri.vtk", None);
    assert_eq!((m.points.len(), count(&m, CellKind::T3)), (45, 64));
    assert!(m.cell_region.iter().all(|r| r == "5"));
    assert_eq!(keys(&m.edge_sets), ["1", "2", "3", "4"]);
    assert_eq!(m.edge_sets["1"].len(), 8);
}

#[test]
fn vtk_missing_region_array_is_named() {
    let e = Vtk { file: "rect_quad.vtu".into(), region_array: Some("material".into()) }.load(&meshes()).unwrap_err().to_string();
    assert!(e.contains("mesh.region_array = \"material\"") && e.contains("region"), "{e}");
}

#[test]
fn missing_file_names_the_path() {
    let e = Gmsh { file: "no_such.msh".into() }.load(&meshes()).unwrap_err().to_string();
    assert!(e.contains("cannot read the mesh file") && e.contains("meshes/no_such.msh") && e.contains("mesh.file = \"no_such.msh\""), "{e}");
    let e = Vtk { file: "no_such.vtu".into(), region_array: None }.load(&meshes()).unwrap_err().to_string();
    assert!(e.contains("meshes/no_such.vtu"), "{e}");
}

#[test]
fn config_parses_with_deny_unknown_fields() {
    let s: Box<dyn MeshSource> = toml::from_str("type = \"gmsh\"\nfile = \"rect_quad_v22.msh\"").unwrap();
    assert_eq!(s.load(&meshes()).unwrap().cells.len(), 32);
    let e = toml::from_str::<Box<dyn MeshSource>>("type = \"gmsh\"\nfile = \"a.msh\"\nfiel = 1").unwrap_err().to_string();
    assert!(e.contains("fiel"), "{e}");
    let s: Box<dyn MeshSource> = toml::from_str("type = \"vtk\"\nfile = \"rect_quad.vtu\"\nregion_array = \"region\"").unwrap();
    assert_eq!(s.load(&meshes()).unwrap().cells.len(), 32);
}

/// A two-triangle msh 2.2 file with extra element lines and names.
fn small_v22(names: &str, extra_elements: &[&str]) -> String {
    let mut els = vec!["1 2 2 5 1 1 2 3", "2 2 2 5 1 1 3 4", "3 1 2 7 1 1 2"];
    els.extend_from_slice(extra_elements);
    format!(
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n{}\n{names}$EndPhysicalNames\n$Nodes\n7\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n5 0.5 0 0\n6 1 0.5 0\n7 0.5 0.5 0.5\n$EndNodes\n$Elements\n{}\n{}\n$EndElements\n",
        names.lines().count(),
        els.len(),
        els.join("\n")
    )
}

#[test]
fn small_v22_reads_with_unnamed_and_named_groups() {
    let m = read_msh_bytes("t.msh", small_v22("2 5 \"rock\"\n", &[]).as_bytes()).unwrap();
    assert_eq!(m.points.len(), 4);
    assert_eq!(m.cell_region, ["rock", "rock"]);
    assert_eq!(m.edge_sets["7"], [[0, 1]]);
    assert_eq!(m.node_sets["7"], [0, 1]);
}

#[test]
fn second_order_element_is_refused_by_name() {
    let e = msh_err(&small_v22("", &["4 9 2 5 1 1 2 3 5 6 7"]));
    assert!(e.contains("element 4: element type 9 (6-node second order triangle) is not supported: FLEM uses first-order triangles and quadrilaterals"), "{e}");
    assert!(e.starts_with("test.msh: "), "{e}");
}

#[test]
fn three_d_element_is_refused_by_name() {
    let e = msh_err(&small_v22("", &["4 4 2 9 1 1 2 3 7"]));
    assert!(e.contains("element type 4 (4-node tetrahedron) is not supported"), "{e}");
}

#[test]
fn physical_group_referring_to_nothing() {
    let e = msh_err(&small_v22("2 5 \"rock\"\n1 8 \"ghost\"\n", &[]));
    assert!(e.contains("physical group \"ghost\" (dimension 1, tag 8) refers to no element"), "{e}");
    // A line group whose line lies outside the 2D mesh.
    let e = msh_err(&small_v22("", &["4 1 2 9 1 5 7"]));
    assert!(e.contains("physical group \"9\" (dimension 1, tag 9) has no point in the 2D mesh"), "{e}");
}

#[test]
fn element_referring_to_a_missing_node() {
    let e = msh_err(&small_v22("", &["4 2 2 5 1 1 2 99"]));
    assert!(e.contains("element 4 refers to node 99"), "{e}");
}

#[test]
fn non_planar_mesh_is_refused() {
    let text = small_v22("", &[]).replace("3 1 1 0\n", "3 1 1 0.25\n");
    let e = msh_err(&text);
    assert!(e.contains("not a 2D mesh: node tag 3 has z = 0.25"), "{e}");
}

#[test]
fn truncated_files_give_errors() {
    for f in ["rect_quad_v22.msh", "rect_quad_v22_bin.msh", "rect_quad_v41.msh", "rect_quad_v41_bin.msh"] {
        let b = std::fs::read(meshes().join(f)).unwrap();
        for cut in [b.len() / 3, b.len() / 2, b.len() - 20] {
            let e = read_msh_bytes(f, &b[..cut]).map(|_| ()).unwrap_err().to_string();
            assert!(e.starts_with(&format!("{f}: ")), "{e}");
        }
    }
    let e = msh_err("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n2 1");
    assert!(e.contains("line 7") && e.contains("the node's y"), "{e}");
    let e = msh_err("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n");
    assert!(e.contains("the file ends where a node line"), "{e}");
}

#[test]
fn other_versions_and_non_msh_files() {
    assert!(msh_err("hello").contains("does not start with $MeshFormat"));
    assert!(msh_err("$MeshFormat\n4 0 8\n$EndMeshFormat\n").contains("version 4 is not supported"));
    assert!(msh_err("$MeshFormat\n4.1 0 4\n$EndMeshFormat\n").contains("data size must be 8"));
}

mod fuzz {
    use proptest::prelude::*;

    use super::*;

    const FILES: [&str; 5] = ["rect_quad_v22.msh", "rect_quad_v22_bin.msh", "rect_quad_v41.msh", "rect_quad_v41_bin.msh", "rect_tri_v22.msh"];

    const FILES_3D: [&str; 4] = ["cube_tet_v22.msh", "cube_hex_v22_bin.msh", "cube_tet_v41.msh", "cube_hex_v41_bin.msh"];

    const VTK_FILES: [(&str, &str); 3] = [("rect_quad.vtu", "vtu"), ("rect_quad_ascii.vtu", "vtu"), ("rect_tri.vtk", "vtk")];

    fn cases() -> u32 {
        std::env::var("FLEM_FUZZ_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(256)
    }

    #[derive(Clone, Debug)]
    enum Mutation {
        /// XOR the byte at (fraction of length) with a non-zero value.
        Flip(f64, u8),
        /// Set the byte to an interesting character (digit, sign, space, newline, '$').
        Set(f64, u8),
        Truncate(f64),
        DeleteLine(f64),
        DuplicateLine(f64),
    }

    fn mutation() -> impl Strategy<Value = Mutation> {
        let at = 0.0..1.0f64;
        prop_oneof![
            (at.clone(), 1..=255u8).prop_map(|(a, b)| Mutation::Flip(a, b)),
            (at.clone(), prop::sample::select(b"0123456789-+. \n$e9".to_vec())).prop_map(|(a, b)| Mutation::Set(a, b)),
            at.clone().prop_map(Mutation::Truncate),
            at.clone().prop_map(Mutation::DeleteLine),
            at.prop_map(Mutation::DuplicateLine),
        ]
    }

    fn apply(b: &mut Vec<u8>, m: &Mutation) {
        let at = |f: f64, n: usize| ((f * n as f64) as usize).min(n.saturating_sub(1));
        let lines = |b: &Vec<u8>| -> Vec<usize> { std::iter::once(0).chain(b.iter().enumerate().filter(|(_, &c)| c == b'\n').map(|(i, _)| i + 1)).collect() };
        if b.is_empty() {
            return;
        }
        match *m {
            Mutation::Flip(f, x) => {
                let i = at(f, b.len());
                b[i] ^= x;
            }
            Mutation::Set(f, x) => {
                let i = at(f, b.len());
                b[i] = x;
            }
            Mutation::Truncate(f) => b.truncate(at(f, b.len())),
            Mutation::DeleteLine(f) | Mutation::DuplicateLine(f) => {
                let starts = lines(b);
                let k = at(f, starts.len());
                let s = starts[k];
                let e = starts.get(k + 1).copied().unwrap_or(b.len());
                if matches!(m, Mutation::DeleteLine(_)) {
                    b.drain(s..e);
                } else {
                    let line: Vec<u8> = b[s..e].to_vec();
                    b.splice(s..s, line);
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: cases(), failure_persistence: None, ..ProptestConfig::default() })]

        /// Mutated msh files give Ok or Err, never a panic; an Ok mesh also validates without
        /// panicking.
        #[test]
        fn mutated_msh_files_never_panic(file in 0..FILES.len(), muts in prop::collection::vec(mutation(), 1..4)) {
            let mut b = std::fs::read(meshes().join(FILES[file])).unwrap();
            for m in &muts {
                apply(&mut b, m);
            }
            if let Ok(mut mesh) = read_msh_bytes(FILES[file], &b) {
                let _ = mesh.validate(ValidationOptions::Reorient);
            }
        }

        /// The same for 3D msh files (issue 38: `read_msh_any`, then `RawMesh3::validate`).
        #[test]
        fn mutated_3d_msh_files_never_panic(file in 0..FILES_3D.len(), muts in prop::collection::vec(mutation(), 1..4)) {
            let dir = crate::snippets::configs_dir().join("3d");
            let mut b = std::fs::read(dir.join(FILES_3D[file])).unwrap();
            for m in &muts {
                apply(&mut b, m);
            }
            match super::super::read_msh_any(FILES_3D[file], &b) {
                Ok(flem_core::mesh::AnyMesh::Three(mut mesh)) => {
                    let _ = mesh.validate(ValidationOptions::Reorient);
                }
                Ok(flem_core::mesh::AnyMesh::Two(mut mesh)) => {
                    let _ = mesh.validate(ValidationOptions::Reorient);
                }
                Err(_) => {}
            }
        }

        /// The same for a 3D VTU (`read_vtk_any`, then `RawMesh3::validate`).
        #[test]
        fn mutated_3d_vtu_never_panics(muts in prop::collection::vec(mutation(), 1..4)) {
            let dir = crate::snippets::configs_dir().join("3d");
            let mut b = std::fs::read(dir.join("cube_hex.vtu")).unwrap();
            for m in &muts {
                apply(&mut b, m);
            }
            match super::super::read_vtk_any("cube_hex.vtu", "vtu", &b, None) {
                Ok(flem_core::mesh::AnyMesh::Three(mut mesh)) => {
                    let _ = mesh.validate(ValidationOptions::Reorient);
                }
                Ok(flem_core::mesh::AnyMesh::Two(mut mesh)) => {
                    let _ = mesh.validate(ValidationOptions::Reorient);
                }
                Err(_) => {}
            }
        }

        /// The same for VTK files (vtkio inside `catch_unwind`, then our checks).
        #[test]
        fn mutated_vtk_files_never_panic(file in 0..VTK_FILES.len(), muts in prop::collection::vec(mutation(), 1..4)) {
            let (name, ext) = VTK_FILES[file];
            let mut b = std::fs::read(meshes().join(name)).unwrap();
            for m in &muts {
                apply(&mut b, m);
            }
            if let Ok(mut mesh) = read_vtk_bytes(name, ext, &b, None) {
                let _ = mesh.validate(ValidationOptions::Reorient);
            }
        }
    }
}

/// A msh 4.1 ASCII file with sparse node tags (10..40) and one unused node (99).
const SPARSE_V41: &str = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n1 7 \"edge\"\n2 5 \"rock\"\n$EndPhysicalNames\n$Entities\n0 1 1 0\n1 0 0 0 1 0 0 1 7 0\n1 0 0 0 1 1 0 1 5 0\n$EndEntities\n$Nodes\n1 5 10 99\n2 1 0 5\n10\n20\n30\n40\n99\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n5 5 5\n$EndNodes\n$Elements\n2 3 1 3\n1 1 1 1\n3 10 20\n2 1 2 2\n1 10 20 30\n2 10 30 40\n$EndElements\n";

#[test]
fn sparse_node_tags_are_renumbered_in_v41() {
    let m = read_msh_bytes("s.msh", SPARSE_V41.as_bytes()).unwrap();
    assert_eq!(m.points, [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
    assert_eq!(m.cells.iter().map(|c| c.corners().to_vec()).collect::<Vec<_>>(), [vec![0, 1, 2], vec![0, 2, 3]]);
    assert_eq!(m.cell_region, ["rock", "rock"]);
    assert_eq!(m.edge_sets["edge"], [[0, 1]]);
    assert_eq!(m.node_sets["edge"], [0, 1]);
}

#[test]
fn sparse_node_tags_are_renumbered_in_v22() {
    let text = small_v22("", &[]).replace("\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n", "\n100 0 0 0\n20 1 0 0\n3 1 1 0\n4000 0 1 0\n");
    let text = text.replace("1 2 2 5 1 1 2 3\n2 2 2 5 1 1 3 4\n3 1 2 7 1 1 2", "1 2 2 5 1 100 20 3\n2 2 2 5 1 100 3 4000\n3 1 2 7 1 100 20");
    let m = read_msh_bytes("s.msh", text.as_bytes()).unwrap();
    // Increasing tag order: 3, 20, 100, 4000.
    assert_eq!(m.points, [[1.0, 1.0], [1.0, 0.0], [0.0, 0.0], [0.0, 1.0]]);
    assert_eq!(m.cells[0].corners(), [2, 1, 0]);
    assert_eq!(m.edge_sets["7"], [[2, 1]]);
}

#[test]
fn element_block_on_a_missing_entity() {
    let text = SPARSE_V41.replace("2 1 2 2\n1 10", "2 9 2 2\n1 10");
    let e = read_msh_bytes("s.msh", text.as_bytes()).unwrap_err().to_string();
    assert!(e.contains("entity (dimension 2, tag 9), which is not in $Entities"), "{e}");
}

#[test]
fn element_in_two_surface_groups_takes_the_smallest_tag() {
    // msh 2.2 writes such an element once per group.
    let m = read_msh_bytes("t.msh", small_v22("2 5 \"rock\"\n2 4 \"soil\"\n", &["1 2 2 4 1 1 2 3"]).as_bytes()).unwrap();
    assert_eq!(m.cell_region, ["soil", "rock"]);
    let e = msh_err(&small_v22("", &["1 2 2 4 1 1 2 4"]));
    assert!(e.contains("element tag 1 is used by two different elements"), "{e}");
}

#[test]
fn a_panic_inside_a_third_party_parser_becomes_an_error() {
    let r: Result<(), String> = super::no_panic("the test parser", || panic!("boom"));
    assert_eq!(r.unwrap_err(), "the test parser failed on this (corrupt?) file: boom");
}

/// Every ```toml snippet of the importer docs deserialises and loads its file (paths relative
/// to configs/, where scenes live). Reference: the docs and the shipped meshes; exact.
#[test]
fn doc_toml_snippets_load() {
    let sources = [("import/mod.rs", include_str!("mod.rs")), ("import/gmsh.rs", include_str!("gmsh.rs")), ("import/vtk.rs", include_str!("vtk.rs"))];
    let configs = crate::snippets::configs_dir();
    for (file, src) in crate::snippets::doc_snippets::<Box<dyn flem_core::mesh::MeshSource>>(&sources, &["mesh"], &["gmsh", "vtk"]) {
        let m = src.load(&configs).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(!m.cells.is_empty(), "{file}");
    }
}

/// Validation names elements and points by the ids of the user's file, not by FLEM's 0-based
/// internal indices: gmsh element and node tags (sparse here: elements 11 and 20, nodes 100, 20,
/// 3, 4000 become internal 0..3 in another order), VTK cell and point indices counted in the
/// file (the skipped line cells count). Reference: the files' own tags, written by hand here.
#[test]
fn validation_names_the_ids_of_the_file() {
    use flem_core::mesh::ValidationOptions;
    let text = small_v22("", &[]).replace("\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n", "\n100 0 0 0\n20 1 0 0\n3 1 1 0\n4000 0 1 0\n");
    // Element 20 is clockwise (100, 4000, 3); element 11 is fine.
    let text = text.replace("1 2 2 5 1 1 2 3\n2 2 2 5 1 1 3 4\n3 1 2 7 1 1 2", "11 2 2 5 1 100 20 3\n20 2 2 5 1 100 4000 3\n3 1 2 7 1 100 20");
    let mut m = read_msh_bytes("s.msh", text.as_bytes()).unwrap();
    let e = m.clone().validate(ValidationOptions::Refuse).unwrap_err().to_string();
    assert!(e.contains("s.msh: element tag 20 is clockwise (points [node tags 100, 4000, 3])"), "{e}");
    let w = m.validate(ValidationOptions::Reorient).unwrap();
    assert!(w[0].contains("s.msh: element tag 20 was clockwise"), "{w:?}");
    // A zero-area element: its tag and its nodes' tags.
    let flat = text.replace("\n3 1 1 0\n", "\n3 2 0 0\n");
    let e = read_msh_bytes("s.msh", flat.as_bytes()).unwrap().validate(ValidationOptions::Reorient).unwrap_err().to_string();
    assert!(e.contains("element tag 11 has zero area (points [node tags 100, 20, 3])"), "{e}");
    // Duplicate points: node tags.
    let dup = small_v22("", &["4 2 2 5 1 1 2 5"]).replace("\n5 0.5 0 0\n", "\n5 1 1 0\n");
    let e = read_msh_bytes("s.msh", dup.as_bytes()).unwrap().validate(ValidationOptions::Reorient).unwrap_err().to_string();
    assert!(e.contains("duplicate points: node tag 3 and node tag 5 are both at (1, 1)"), "{e}");
    // VTK: a legacy file whose first cell is a line (skipped) and whose cell 2 is degenerate.
    let vtk = "# vtk DataFile Version 4.2\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 double\n9 9 0 0 0 0 1 0 0 1 1 0 2 0 0\nCELLS 3 11\n2 1 2\n3 1 2 3\n3 1 2 4\nCELL_TYPES 3\n3\n5\n5\n";
    let e = read_vtk_bytes("t.vtk", "vtk", vtk.as_bytes(), None).unwrap().validate(ValidationOptions::Reorient).unwrap_err().to_string();
    assert!(e.contains("t.vtk: VTK cell 2 (0-based, as in the file) has zero area (points [VTK points 1, 2, 4] (0-based, as in the file))"), "{e}");
    // Without file ids (a mesh built by hand): 0-based, said so.
    let mut m = read_vtk_bytes("t.vtk", "vtk", vtk.as_bytes(), None).unwrap();
    m.ids = None;
    let e = m.validate(ValidationOptions::Reorient).unwrap_err().to_string();
    assert!(e.contains("element 1 (0-based, in file order) has zero area (points [0, 1, 3] (0-based, in file order))"), "{e}");
}

/// vtkio's parse errors carry no position: the importer adds the line, the data array and the
/// piece (vtu) or the section (legacy). Reference: the damage written here by hand.
#[test]
fn vtk_parse_errors_name_the_line_and_array() {
    let ascii = std::fs::read_to_string(meshes().join("rect_quad_ascii.vtu")).unwrap();
    let err = |name: &str, ext: &str, b: &[u8]| read_vtk_bytes(name, ext, b, None).map(|_| ()).unwrap_err().to_string();
    // A value that is not a number in the connectivity.
    let at = ascii.find("Name=\"connectivity\"").unwrap();
    let nl = at + ascii[at..].find('\n').unwrap() + 1;
    let line = ascii[..nl].lines().count() + 1;
    let bad = format!("{}x{}", &ascii[..nl], &ascii[nl + 1..]);
    let e = err("q.vtu", "vtu", bad.as_bytes());
    assert!(
        e.starts_with("q.vtu: cannot parse the VTK file")
            && e.contains(&format!("line {line}: "))
            && e.contains("<DataArray Name=\"connectivity\">")
            && e.contains("of <Cells> of piece 0")
            && e.contains("not a whole number"),
        "{e}"
    );
    // Cut in the middle of the points.
    let cut = ascii.find("Name=\"Points\"").unwrap() + 200;
    let e = err("q.vtu", "vtu", &ascii.as_bytes()[..cut]);
    assert!(e.contains("the file ends in <DataArray Name=\"Points\">") && e.contains("of <Points> of piece 0") && e.contains("cut short"), "{e}");
    // A binary (base64) array with a stray character.
    let bin = std::fs::read_to_string(meshes().join("rect_quad.vtu")).unwrap();
    let at = bin.find("Name=\"offsets\"").unwrap();
    let nl = at + bin[at..].find('\n').unwrap() + 1;
    let e = err("b.vtu", "vtu", format!("{}*{}", &bin[..nl], &bin[nl + 1..]).as_bytes());
    assert!(e.contains("not base64 in <DataArray Name=\"offsets\">"), "{e}");
    // Legacy: cut in CELLS, and a word among the points.
    let legacy = std::fs::read_to_string(meshes().join("rect_tri.vtk")).unwrap();
    let cells = legacy.find("CELLS").unwrap();
    let e = err("t.vtk", "vtk", &legacy.as_bytes()[..cells + 40]);
    assert!(e.contains("the file ends in CELLS (line 7) after") && e.contains("cut short"), "{e}");
    let e = err("t.vtk", "vtk", legacy.replacen("2.0 0.0 0.0", "2.0 zero 0.0", 1).as_bytes());
    assert!(e.contains("line 6: \"zero\" in POINTS (line 5), value 5 of 135, is not a number"), "{e}");
    // A CELLS size that does not match its cells (vtkio says only "Parse error: Tag").
    let cells_line = legacy.lines().find(|l| l.starts_with("CELLS")).unwrap();
    let (n, size) = cells_line[6..].split_once(' ').unwrap();
    let e = err("t.vtk", "vtk", legacy.replacen(cells_line, &format!("CELLS {n} {}", size.parse::<u64>().unwrap() - 1), 1).as_bytes());
    assert!(e.contains(&format!("line 7: CELLS {n} {}: its {n} cells take {size} values", size.parse::<u64>().unwrap() - 1)), "{e}");
    // Counts from a damaged file beyond u32 (vtkio refuses them): the scanner must neither walk
    // 1e14 cells (it hung) nor wrap its products (POINTS x 3 gave the opposite diagnosis).
    let t0 = std::time::Instant::now();
    let e = err("t.vtk", "vtk", legacy.replacen(cells_line, &format!("CELLS 99999999999999 {size}"), 1).as_bytes());
    assert!(e.contains(&format!("line 7: CELLS 99999999999999 {size}: its {size} values hold {n} cells, not 99999999999999")), "{e}");
    let points_line = legacy.lines().find(|l| l.starts_with("POINTS")).unwrap();
    let e = err("t.vtk", "vtk", legacy.replacen(points_line, "POINTS 6148914691236517206 double", 1).as_bytes());
    assert!(e.contains("line 7: \"CELLS\" in POINTS (line 5), value 136 of more than 2^64 declared, is not a number"), "{e}");
    assert!(t0.elapsed().as_secs_f64() < 5.0, "the scanner took {:?}", t0.elapsed());
}

/// Issue 35: a damaged msh 4.1 file (binary or ASCII) refused by mshio names the section
/// (and its lines) where the parse failed, and the line where mshio gives one; never mshio's
/// bare "Unknown error occurred". Every byte of the sections after the header is damaged in
/// turn (XOR 0x5A); the section named must be the one holding the damaged byte (mshio parses
/// the sections in order, each on its own).
#[test]
fn msh41_errors_name_the_section_and_line() {
    for file in ["rect_quad_v41_bin.msh", "rect_quad_v41.msh"] {
        let good = std::fs::read(meshes().join(file)).unwrap();
        let start = good.windows(9).position(|w| w == b"$Entities").unwrap();
        let (mut named, mut no_detail) = (0, 0);
        for i in start..good.len() {
            let mut b = good.clone();
            b[i] ^= 0x5A;
            let Err(e) = read_msh_bytes(file, &b) else { continue };
            let e = e.to_string();
            assert!(!e.contains("Unknown error"), "{file}, byte {i}: {e}");
            if !e.contains("cannot parse the msh 4.1 file") {
                continue;
            }
            // The section holding byte i: the last "$Name" line starting at or before it.
            let k = good[..=i].windows(2).rposition(|w| w == b"\n$").unwrap() + 1;
            let end = k + good[k..].iter().position(|&c| c == b'\n' || c == b'\r').unwrap();
            let sec = String::from_utf8_lossy(&good[k..end]).into_owned();
            let sec = sec.strip_prefix("$End").map(|s| format!("${s}")).unwrap_or(sec);
            assert!(e.contains(&format!("section {sec} (lines ")), "{file}, byte {i} in {sec}: {e}");
            named += 1;
            no_detail += usize::from(e.contains("mshio gives no detail"));
        }
        println!("{file}: {named} damaged bytes refused by mshio, {no_detail} without a detail from it");
        assert!(named > 50, "{file}: {named}");
    }
}
