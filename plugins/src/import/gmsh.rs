//! `[mesh] type = "gmsh"`: gmsh `.msh` files, versions 4.1 (through mshio) and 2.2 (own
//! reader), ASCII or binary.
//!
//! Physical groups become FLEM groups:
//! - dimension 2 (surfaces): element regions; `cell_region` is the group's name, "all" for a
//!   cell in no 2D group, the group with the smallest tag for a cell in several;
//! - dimension 1 (curves): an edge set (point pairs of its 2-node lines) and a node set (their
//!   points) of the same name;
//! - dimension 0 (points): a node set.
//!
//! Unnamed groups are named by their tag ("7"). First-order triangles (type 2) and quadrangles
//! (type 3) become cells, 2-node lines (1) and points (15) only feed groups; any other element
//! type is refused with its name. Node tags may be sparse: the points used by 2D cells are
//! numbered densely in increasing tag order; cells are ordered by element tag. A named group
//! that ends up empty (no element, or only points outside the 2D mesh) is an error, since a
//! scene naming it would silently act on nothing.
//!
//! A file with volume elements is a 3D mesh: `load_any` reads it (`gmsh3.rs`: tetrahedra and
//! hexahedra, physical volumes as regions, physical surfaces as face sets) and the 2D `load`
//! refuses it, saying so.
//!
//! ```toml
//! [mesh]
//! type = "gmsh"
//! file = "meshes/rect_quad_v41.msh"
//! ```
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use flem_core::mesh::{AnyMesh, CellKind, MeshSource, RawCell, RawMesh};
use flem_core::{FlemError, Result};
use serde::{Deserialize, Serialize};

use super::cursor::{parse_tok, shorten, Cursor};
use super::{msh2, msh4, read_input, Gathered};

/// A gmsh mesh file; `file` is relative to the scene file's folder.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gmsh {
    pub file: String,
}

#[typetag::serde(name = "gmsh")]
impl MeshSource for Gmsh {
    fn load(&self, base_dir: &Path) -> Result<RawMesh> {
        let (shown, _, bytes) = read_input(base_dir, &self.file)?;
        read_msh_bytes(&shown, &bytes)
    }

    /// The 2D mesh, or the 3D one when the file has volume elements (`gmsh3.rs`).
    fn load_any(&self, base_dir: &Path) -> Result<AnyMesh> {
        let (shown, _, bytes) = read_input(base_dir, &self.file)?;
        read_msh_any(&shown, &bytes)
    }
}

/// One element as read from either format: its tag, gmsh type, physical tags and node tags.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct MshElement {
    pub id: u64,
    pub ty: i32,
    pub phys: Vec<i32>,
    pub nodes: Vec<u64>,
}

/// The format-independent content of a msh file.
#[derive(Default, Debug)]
pub(crate) struct MshContent {
    /// (node tag, coordinates) in file order.
    pub nodes: Vec<(u64, [f64; 3])>,
    pub elements: Vec<MshElement>,
    /// `$PhysicalNames`: (dimension, tag) -> name.
    pub names: BTreeMap<(i32, i32), String>,
}

/// Reads a msh file held in memory; `src` names it in errors.
pub fn read_msh_bytes(src: &str, bytes: &[u8]) -> Result<RawMesh> {
    to_raw_mesh(src, parse_msh(src, bytes)?)
}

/// Reads a msh file held in memory in its own dimension: [`AnyMesh::Three`] when it has volume
/// elements (`gmsh3.rs`), else the mesh of [`read_msh_bytes`].
pub fn read_msh_any(src: &str, bytes: &[u8]) -> Result<AnyMesh> {
    super::gmsh3::to_any_mesh(src, parse_msh(src, bytes)?)
}

/// The format-independent content of a msh file of either version.
fn parse_msh(src: &str, bytes: &[u8]) -> Result<MshContent> {
    let mut c = Cursor::new(src, bytes);
    let (version, binary) = read_header(&mut c)?;
    let content = if version.starts_with("2.") || version == "2" {
        msh2::parse(c, binary)?
    } else if version == "4.1" {
        msh4::parse(src, bytes)?
    } else {
        return Err(FlemError::mesh(src, format!("msh format version {version} is not supported; save the mesh as version 4.1 or 2.2 (gmsh -format msh41 / msh22)")));
    };
    Ok(content)
}

/// `$MeshFormat` / `version file-type data-size`: returns the version text and whether binary.
fn read_header<'a>(c: &mut Cursor<'a>) -> Result<(&'a str, bool)> {
    c.skip_ws();
    let first = c.line().unwrap_or_default();
    if first.strip_suffix(b"\r").unwrap_or(first) != b"$MeshFormat" {
        return Err(c.err("this is not a gmsh .msh file: it does not start with $MeshFormat"));
    }
    let l = c.text_line("the format line (version file-type data-size)")?;
    let mut t = l.split_whitespace();
    let version = t.next().unwrap_or("");
    let ft: i32 = parse_tok(c, t.next(), "the file type")?;
    let ds: i32 = parse_tok(c, t.next(), "the data size")?;
    if ft != 0 && ft != 1 {
        return Err(c.err(format!("the file type must be 0 (ASCII) or 1 (binary), not {ft}")));
    }
    if ds != 8 {
        return Err(c.err(format!("the data size must be 8 (double precision), not {ds}")));
    }
    Ok((version, ft == 1))
}

/// Parses the body of `$PhysicalNames` (`n`, then `dim tag "name"` lines) and its end line.
pub(crate) fn read_physical_names(c: &mut Cursor, names: &mut BTreeMap<(i32, i32), String>) -> Result<()> {
    let l = c.count_line()?;
    let n: usize = parse_tok(c, Some(l), "the number of physical names")?;
    for _ in 0..n {
        let l = c.text_line("a physical name (dim tag \"name\")")?;
        let mut t = l.splitn(3, char::is_whitespace);
        let dim: i32 = parse_tok(c, t.next(), "the physical group dimension")?;
        let tag: i32 = parse_tok(c, t.next(), "the physical group tag")?;
        let rest = t.next().unwrap_or("").trim();
        let name = rest.strip_prefix('"').and_then(|r| r.strip_suffix('"'));
        let Some(name) = name else {
            return Err(c.err(format!("the physical name {} is not in double quotes", shorten(rest))));
        };
        if !(0..=3).contains(&dim) {
            return Err(c.err(format!("physical group \"{name}\" has dimension {dim}; it must be 0, 1, 2 or 3")));
        }
        if names.insert((dim, tag), name.to_string()).is_some() {
            return Err(c.err(format!("physical group (dimension {dim}, tag {tag}) is named twice")));
        }
    }
    c.expect_end("PhysicalNames")
}

impl<'a> Cursor<'a> {
    /// The next non-blank trimmed text line (a count line).
    pub(crate) fn count_line(&mut self) -> Result<&'a str> {
        self.skip_ws();
        self.text_line("a count")
    }
}

/// Number of nodes of the gmsh element types FLEM knows by name, with that name.
pub(crate) fn element_type(ty: i32) -> Option<(usize, &'static str)> {
    Some(match ty {
        1 => (2, "2-node line"),
        2 => (3, "3-node triangle"),
        3 => (4, "4-node quadrangle"),
        4 => (4, "4-node tetrahedron"),
        5 => (8, "8-node hexahedron"),
        6 => (6, "6-node prism"),
        7 => (5, "5-node pyramid"),
        8 => (3, "3-node second order line"),
        9 => (6, "6-node second order triangle"),
        10 => (9, "9-node second order quadrangle"),
        11 => (10, "10-node second order tetrahedron"),
        12 => (27, "27-node second order hexahedron"),
        13 => (18, "18-node second order prism"),
        14 => (14, "14-node second order pyramid"),
        15 => (1, "1-node point"),
        16 => (8, "8-node second order quadrangle"),
        17 => (20, "20-node second order hexahedron"),
        18 => (15, "15-node second order prism"),
        19 => (13, "13-node second order pyramid"),
        20 => (9, "9-node third order incomplete triangle"),
        21 => (10, "10-node third order triangle"),
        22 => (12, "12-node fourth order incomplete triangle"),
        23 => (15, "15-node fourth order triangle"),
        24 => (15, "15-node fifth order incomplete triangle"),
        25 => (21, "21-node fifth order complete triangle"),
        26 => (4, "4-node third order line"),
        27 => (5, "5-node fourth order line"),
        28 => (6, "6-node fifth order line"),
        29 => (20, "20-node third order tetrahedron"),
        30 => (35, "35-node fourth order tetrahedron"),
        31 => (56, "56-node fifth order tetrahedron"),
        36 => (16, "16-node third order quadrangle"),
        37 => (25, "25-node fourth order quadrangle"),
        _ => return None,
    })
}

fn unsupported(src: &str, id: u64, ty: i32) -> FlemError {
    let name = element_type(ty).map(|t| t.1).unwrap_or("unknown to FLEM");
    if super::gmsh3::is_volume_type(ty) {
        return FlemError::mesh(
            src,
            format!("element {id}: element type {ty} ({name}) is not supported in a 2D mesh: this file has volume elements, it is a 3D mesh; a 3D scene reads it (docs/3d.md)"),
        );
    }
    FlemError::mesh(src, format!("element {id}: element type {ty} ({name}) is not supported: FLEM uses first-order triangles and quadrilaterals (and 2-node lines and points for groups)"))
}

pub(crate) fn group_name(names: &BTreeMap<(i32, i32), String>, dim: i32, tag: i32) -> String {
    names.get(&(dim, tag)).cloned().unwrap_or_else(|| tag.to_string())
}

/// Merges elements written once per physical group (msh 2.2 does that) and sorts by tag.
pub(crate) fn merge_elements(src: &str, elements: Vec<MshElement>) -> Result<Vec<MshElement>> {
    let mut by_id: BTreeMap<u64, MshElement> = BTreeMap::new();
    for e in elements {
        match by_id.get_mut(&e.id) {
            None => {
                by_id.insert(e.id, e);
            }
            Some(old) if old.ty == e.ty && old.nodes == e.nodes => old.phys.extend(e.phys),
            Some(_) => return Err(FlemError::mesh(src, format!("element tag {} is used by two different elements", e.id))),
        }
    }
    Ok(by_id.into_values().collect())
}

/// Builds the [`RawMesh`]: checks element types and node references, maps groups, compacts.
pub(crate) fn to_raw_mesh(src: &str, content: MshContent) -> Result<RawMesh> {
    let MshContent { nodes, elements, names } = content;
    let mut index: BTreeMap<u64, usize> = BTreeMap::new();
    for (k, (tag, _)) in nodes.iter().enumerate() {
        if index.insert(*tag, k).is_some() {
            return Err(FlemError::mesh(src, format!("node tag {tag} is defined twice")));
        }
    }
    // Points in increasing tag order.
    let order: Vec<usize> = index.values().copied().collect();
    let mut g = Gathered { points: order.iter().map(|&k| nodes[k].1).collect(), labels: index.keys().copied().collect(), words: ("node tag", "element tag"), ..Default::default() };
    let rank: BTreeMap<u64, u32> = index.keys().enumerate().map(|(r, &t)| (t, r as u32)).collect();
    let mut used_groups: BTreeSet<(i32, i32)> = BTreeSet::new();
    for e in merge_elements(src, elements)? {
        let (k, dim) = match e.ty {
            1 => (2, 1),
            2 => (3, 2),
            3 => (4, 2),
            15 => (1, 0),
            t => return Err(unsupported(src, e.id, t)),
        };
        if e.nodes.len() != k {
            return Err(FlemError::mesh(src, format!("element {} (type {}) has {} nodes; it must have {k}", e.id, e.ty, e.nodes.len())));
        }
        let mut p = [0u32; 4];
        for (a, t) in e.nodes.iter().enumerate() {
            p[a] = *rank.get(t).ok_or_else(|| FlemError::mesh(src, format!("element {} refers to node {t}, which is not defined in $Nodes", e.id)))?;
        }
        let mut phys = e.phys.clone();
        phys.retain(|&t| t != 0);
        phys.sort_unstable();
        phys.dedup();
        used_groups.extend(phys.iter().map(|&t| (dim, t)));
        match dim {
            2 => {
                let kind = if k == 3 { CellKind::T3 } else { CellKind::Q4 };
                g.cells.push(RawCell { kind, nodes: p });
                g.cell_labels.push(e.id);
                g.cell_region.push(phys.first().map(|&t| group_name(&names, 2, t)).unwrap_or_else(|| "all".into()));
            }
            1 => {
                for &t in &phys {
                    let name = group_name(&names, 1, t);
                    g.edge_sets.entry(name.clone()).or_default().push([p[0], p[1]]);
                    g.node_sets.entry(name).or_default().extend([p[0], p[1]]);
                }
            }
            _ => {
                for &t in &phys {
                    g.node_sets.entry(group_name(&names, 0, t)).or_default().push(p[0]);
                }
            }
        }
    }
    let mesh = g.finish(src)?;
    check_groups(src, &mesh, &names, &used_groups)?;
    Ok(mesh)
}

/// Every named or used physical group of dimension 0-2 must hold something in the 2D mesh.
fn check_groups(src: &str, mesh: &RawMesh, names: &BTreeMap<(i32, i32), String>, used: &BTreeSet<(i32, i32)>) -> Result<()> {
    let all: BTreeSet<(i32, i32)> = names.keys().copied().chain(used.iter().copied()).collect();
    for &(dim, tag) in &all {
        let name = group_name(names, dim, tag);
        let empty = match dim {
            0 | 1 => mesh.node_sets.get(&name).is_none_or(|s| s.is_empty()),
            2 => !used.contains(&(2, tag)),
            _ => false,
        };
        if empty {
            let why = if used.contains(&(dim, tag)) { "has no point in the 2D mesh" } else { "refers to no element" };
            return Err(FlemError::mesh(src, format!("physical group \"{name}\" (dimension {dim}, tag {tag}) {why}")));
        }
    }
    Ok(())
}
