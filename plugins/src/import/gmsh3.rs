//! gmsh files with volume elements (issue 38): the 3D path of `[mesh] type = "gmsh"`.
//!
//! A file is 3D when it holds volume elements (any gmsh type of dimension 3);
//! `Gmsh::load_any` then gives [`AnyMesh::Three`] built here, while the 2D `load` refuses it
//! saying that it is 3D. Both msh versions (2.2 own reader, 4.1 through mshio; ASCII or binary)
//! give the same [`MshContent`] as for 2D, so only the mapping differs:
//! - first-order tetrahedra (type 4) become T4 cells, hexahedra (type 5) H8 cells, in VTK/gmsh
//!   corner order; every other volume type (prisms, pyramids, second-order cells such as the
//!   10-node tetrahedron) is refused by name with its element tag;
//! - physical volumes (dimension 3) are regions: `cell_region` is the group's name, "all" for
//!   a cell in no volume group, the group with the smallest tag for a cell in several;
//! - physical surfaces (dimension 2, triangles type 2 and quadrangles type 3) become a face
//!   set (faces by their corner points, in the file's corner order) and a node set of the same
//!   name; second-order faces are refused;
//! - physical curves (2-node lines, type 1) and physical points (type 15) become node sets.
//!
//! As in 2D, unnamed groups are named by their tag; the points used by volume cells are numbered
//! densely in increasing tag order (others are dropped, with them the set members outside the
//! mesh); cells are ordered by element tag; a group that ends up empty is an error.
//! [`RawMesh3::validate`] checks the result (orientation, volumes, faces of the face sets).
//!
//! ```toml
//! [mesh]
//! type = "gmsh"
//! file = "3d/cube_tet_v41.msh"
//! ```
use std::collections::{BTreeMap, BTreeSet};

use flem_core::mesh::{AnyMesh, CellKind3, FileIds, RawCell3, RawFace, RawMesh3, NO_CORNER};
use flem_core::{FlemError, Result};

use super::gmsh::{element_type, group_name, merge_elements, MshContent};

/// Whether gmsh element type `ty` is a volume element: the tetrahedra, hexahedra, prisms and
/// pyramids that [`element_type`] names, the 22- and 28-node tetrahedra (32, 33) and
/// polyhedra (35) (gmsh's numbering, GmshDefines.h). Other types are refused as unknown.
pub(crate) fn is_volume_type(ty: i32) -> bool {
    matches!(ty, 4 | 5 | 6 | 7 | 11 | 12 | 13 | 14 | 17 | 18 | 19 | 29 | 30 | 31 | 32 | 33 | 35)
}

/// Whether the file's elements make it a 3D mesh.
pub(crate) fn is_3d(content: &MshContent) -> bool {
    content.elements.iter().any(|e| is_volume_type(e.ty))
}

fn unsupported3(src: &str, id: u64, ty: i32) -> FlemError {
    let name = element_type(ty).map(|t| t.1).unwrap_or("unknown to FLEM");
    FlemError::mesh(
        src,
        format!(
            "element tag {id}: element type {ty} ({name}) is not supported in a 3D mesh: FLEM uses first-order tetrahedra (type 4) and hexahedra (type 5), with triangles and quadrangles (types 2, 3), 2-node lines and points for groups; mesh with Mesh.ElementOrder = 1 and without prisms or pyramids"
        ),
    )
}

/// Builds the [`RawMesh3`] of a file with volume elements: checks element types and node
/// references, maps groups, keeps the points of the volume cells.
pub(crate) fn to_raw_mesh3(src: &str, content: MshContent) -> Result<RawMesh3> {
    let MshContent { nodes, elements, names } = content;
    let mut index: BTreeMap<u64, usize> = BTreeMap::new();
    for (k, (tag, _)) in nodes.iter().enumerate() {
        if index.insert(*tag, k).is_some() {
            return Err(FlemError::mesh(src, format!("node tag {tag} is defined twice")));
        }
    }
    // Candidate points in increasing tag order.
    let all_points: Vec<[f64; 3]> = index.values().map(|&k| nodes[k].1).collect();
    let labels: Vec<u64> = index.keys().copied().collect();
    let rank: BTreeMap<u64, u32> = index.keys().enumerate().map(|(r, &t)| (t, r as u32)).collect();
    let mut cells: Vec<RawCell3> = Vec::new();
    let mut cell_labels = Vec::new();
    let mut cell_region = Vec::new();
    let mut node_sets: BTreeMap<String, Vec<u32>> = BTreeMap::new();
    let mut face_sets: BTreeMap<String, Vec<RawFace>> = BTreeMap::new();
    let mut used_groups: BTreeSet<(i32, i32)> = BTreeSet::new();
    for e in merge_elements(src, elements)? {
        let (k, dim) = match e.ty {
            4 => (4, 3),
            5 => (8, 3),
            2 => (3, 2),
            3 => (4, 2),
            1 => (2, 1),
            15 => (1, 0),
            t => return Err(unsupported3(src, e.id, t)),
        };
        if e.nodes.len() != k {
            return Err(FlemError::mesh(src, format!("element tag {} (type {}) has {} nodes; it must have {k}", e.id, e.ty, e.nodes.len())));
        }
        let mut p = [0u32; 8];
        for (a, t) in e.nodes.iter().enumerate() {
            p[a] = *rank.get(t).ok_or_else(|| FlemError::mesh(src, format!("element tag {} refers to node {t}, which is not defined in $Nodes", e.id)))?;
        }
        let mut phys = e.phys.clone();
        phys.retain(|&t| t != 0);
        phys.sort_unstable();
        phys.dedup();
        used_groups.extend(phys.iter().map(|&t| (dim, t)));
        match dim {
            3 => {
                let kind = if k == 4 { CellKind3::T4 } else { CellKind3::H8 };
                cells.push(RawCell3 { kind, nodes: p });
                cell_labels.push(e.id);
                cell_region.push(phys.first().map(|&t| group_name(&names, 3, t)).unwrap_or_else(|| "all".into()));
            }
            2 => {
                let face = RawFace([p[0], p[1], p[2], if k == 4 { p[3] } else { NO_CORNER }]);
                for &t in &phys {
                    let name = group_name(&names, 2, t);
                    face_sets.entry(name.clone()).or_default().push(face);
                    node_sets.entry(name).or_default().extend_from_slice(face.corners());
                }
            }
            _ => {
                for &t in &phys {
                    node_sets.entry(group_name(&names, dim, t)).or_default().extend_from_slice(&p[..k]);
                }
            }
        }
    }
    if cells.is_empty() {
        return Err(FlemError::mesh(src, "the file has no tetrahedra or hexahedra (first-order 3D cells)"));
    }
    let g = Gathered3 { points: all_points, labels, words: ("node tag", "element tag"), zero_based: false, cells, cell_labels, cell_region, node_sets, face_sets };
    let mesh = g.finish(src)?;
    let (node_sets, face_sets) = (&mesh.node_sets, &mesh.face_sets);
    // Every named or used group must hold something in the 3D mesh.
    let all: BTreeSet<(i32, i32)> = names.keys().copied().chain(used_groups.iter().copied()).collect();
    for &(dim, tag) in &all {
        let name = group_name(&names, dim, tag);
        let empty = match dim {
            0 | 1 => node_sets.get(&name).is_none_or(|s| s.is_empty()),
            2 => face_sets.get(&name).is_none_or(|s| s.is_empty()),
            _ => !used_groups.contains(&(3, tag)),
        };
        if empty {
            let why = if used_groups.contains(&(dim, tag)) { "has no point in the 3D mesh" } else { "refers to no element" };
            return Err(FlemError::mesh(src, format!("physical group \"{name}\" (dimension {dim}, tag {tag}) {why}")));
        }
    }
    Ok(mesh)
}

/// What a 3D reader collects before the points are compacted (the 3D twin of
/// [`super::Gathered`]): candidate points with their ids in the file, cells, regions and sets
/// referring to them.
pub(crate) struct Gathered3 {
    pub points: Vec<[f64; 3]>,
    pub labels: Vec<u64>,
    pub words: (&'static str, &'static str),
    pub zero_based: bool,
    pub cells: Vec<RawCell3>,
    pub cell_labels: Vec<u64>,
    pub cell_region: Vec<String>,
    pub node_sets: BTreeMap<String, Vec<u32>>,
    pub face_sets: BTreeMap<String, Vec<RawFace>>,
}

impl Gathered3 {
    /// Keeps the points used by cells (in their order), remaps cells and sets (dropping set
    /// members outside the mesh), refuses non-finite coordinates.
    pub fn finish(self, src: &str) -> Result<RawMesh3> {
        let Gathered3 { points: all_points, labels, words, zero_based, mut cells, cell_labels, cell_region, node_sets, face_sets } = self;
        let based = if zero_based { " (0-based, as in the file)" } else { "" };
        // Keep the points of the volume cells, in tag order.
        let n = all_points.len();
        let mut new_id = vec![u32::MAX; n];
        for c in &cells {
            for &q in c.corners() {
                new_id[q as usize] = 0;
            }
        }
        let mut points = Vec::new();
        let mut point_ids = Vec::new();
        for (i, id) in new_id.iter_mut().enumerate() {
            if *id == 0 {
                let x = all_points[i];
                if !x.iter().all(|v| v.is_finite()) {
                    return Err(FlemError::mesh(src, format!("{} {}{based} has a non-finite coordinate {x:?}", words.0, labels[i])));
                }
                *id = points.len() as u32;
                points.push(x);
                point_ids.push(labels[i]);
            }
        }
        let map = |q: u32| new_id.get(q as usize).copied().filter(|&r| r != u32::MAX);
        for c in &mut cells {
            for q in c.nodes.iter_mut().take(c.kind.nodes()) {
                *q = new_id[*q as usize];
            }
            for q in c.nodes.iter_mut().skip(c.kind.nodes()) {
                *q = 0;
            }
        }
        let node_sets: BTreeMap<String, Vec<u32>> = node_sets
            .into_iter()
            .map(|(name, set)| {
                let mut v: Vec<u32> = set.into_iter().filter_map(map).collect();
                v.sort_unstable();
                v.dedup();
                (name, v)
            })
            .collect();
        let face_sets: BTreeMap<String, Vec<RawFace>> = face_sets
            .into_iter()
            .map(|(name, set)| {
                let v = set
                    .into_iter()
                    .filter_map(|f| {
                        let mut g = [NO_CORNER; 4];
                        for (a, &q) in f.corners().iter().enumerate() {
                            g[a] = map(q)?;
                        }
                        Some(RawFace(g))
                    })
                    .collect();
                (name, v)
            })
            .collect();
        let ids = (cell_labels.len() == cells.len()).then(|| FileIds { point_word: words.0, cell_word: words.1, zero_based, points: point_ids, cells: cell_labels });
        Ok(RawMesh3 { source: src.to_string(), points, cells, cell_region, node_sets, face_sets, ids })
    }
}

/// The mesh of a parsed file in its own dimension.
pub(crate) fn to_any_mesh(src: &str, content: MshContent) -> Result<AnyMesh> {
    if is_3d(&content) {
        Ok(AnyMesh::Three(to_raw_mesh3(src, content)?))
    } else {
        Ok(AnyMesh::Two(super::gmsh::to_raw_mesh(src, content)?))
    }
}

#[cfg(test)]
mod tests {
    use flem_core::mesh::{AnyMesh, MeshSource, ValidationOptions};

    /// The ```toml snippet of this module's doc loads its file (relative to configs/) as a 3D
    /// mesh that validates. Reference: the docs and the shipped mesh; exact.
    #[test]
    fn doc_toml_snippet_loads_a_3d_mesh() {
        let configs = crate::snippets::configs_dir();
        for (file, src) in crate::snippets::doc_snippets::<Box<dyn MeshSource>>(&[("import/gmsh3.rs", include_str!("gmsh3.rs"))], &["mesh"], &["gmsh"]) {
            let AnyMesh::Three(mut m) = src.load_any(&configs).unwrap_or_else(|e| panic!("{file}: {e}")) else { panic!("{file}: not 3D") };
            m.validate(ValidationOptions::Refuse).unwrap_or_else(|e| panic!("{file}: {e}"));
            assert_eq!(m.cells.len(), 200);
        }
    }
}
