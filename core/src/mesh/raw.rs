use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::error::{FlemError, Result};

/// First-order 2D cells FLEM computes with.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CellKind {
    /// 3-node constant-strain triangle.
    T3,
    /// 4-node bilinear quadrilateral.
    Q4,
}

/// `[mesh] element` of the generated meshes: a cell type, with an error that names the key
/// (the mesh table is read through its `type` tag, which loses the value's position in the
/// file, so serde's own message pointed at the table's first line).
pub fn de_mesh_element<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<CellKind, D::Error> {
    let s = String::deserialize(d)?;
    match s.as_str() {
        "q4" => Ok(CellKind::Q4),
        "t3" => Ok(CellKind::T3),
        _ => Err(serde::de::Error::custom(format!(
            "mesh.element = \"{s}\" is not a cell type: give \"q4\" (quadrilaterals) or \"t3\" (triangles); the element kind computed on them (q4, qm6, t3, ...) is chosen per material with [[material]] element"
        ))),
    }
}

impl CellKind {
    pub fn nodes(self) -> usize {
        match self {
            CellKind::T3 => 3,
            CellKind::Q4 => 4,
        }
    }
}

/// One cell: its kind and its corner points, counter-clockwise after validation.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct RawCell {
    pub kind: CellKind,
    /// Corner point indices; for T3 only the first three are used.
    pub nodes: [u32; 4],
}

impl RawCell {
    pub fn corners(&self) -> &[u32] {
        &self.nodes[..self.kind.nodes()]
    }
}

/// A mesh with its named groups, as read or generated.
#[derive(Clone, Debug, Default)]
pub struct RawMesh {
    /// Name of the file (or generator) it came from, for error messages.
    pub source: String,
    pub points: Vec<[f64; 2]>,
    pub cells: Vec<RawCell>,
    /// Region (material) name per cell; `None` everywhere means one region "all".
    pub cell_region: Vec<String>,
    /// Named sets of points (supports, point loads, probes).
    pub node_sets: BTreeMap<String, Vec<u32>>,
    /// Named sets of edges as point pairs (pressure loads, pre-separated edges, contact surfaces).
    pub edge_sets: BTreeMap<String, Vec<[u32; 2]>>,
    /// The ids the file gives its points and cells, for error messages (`None`: generated or
    /// handmade; messages then give 0-based indices).
    pub ids: Option<FileIds>,
}

/// How a mesh file names the points and cells of a [`RawMesh`]: one id per point and per cell,
/// as the user sees them in the file (gmsh node and element tags; VTK point and cell indices,
/// counting the cells FLEM skips), so that an error names what the user can find.
#[derive(Clone, Debug, Default)]
pub struct FileIds {
    /// What a point id is called ("node tag", "VTK point").
    pub point_word: &'static str,
    /// What a cell id is called ("element tag", "VTK cell").
    pub cell_word: &'static str,
    /// Whether the ids are 0-based indices (VTK); said in messages, since most tools count from 1.
    pub zero_based: bool,
    pub points: Vec<u64>,
    pub cells: Vec<u64>,
}

impl FileIds {
    fn based(&self) -> &'static str {
        if self.zero_based {
            " (0-based, as in the file)"
        } else {
            ""
        }
    }

    /// The ids of `idx` (cells or points) joined by ", ", the file's word for them ("element
    /// tag", "VTK point"...) and the note after them; without file ids (a generated or handmade
    /// mesh, or an index past the file's list) the 0-based indices, no word and
    /// " (0-based, in file order)". Every name below is built from this.
    fn list(ids: Option<&FileIds>, cells: bool, idx: &[usize]) -> (String, Option<&'static str>, &'static str) {
        let file = ids.map(|i| if cells { (i, &i.cells, i.cell_word) } else { (i, &i.points, i.point_word) }).filter(|(_, v, _)| idx.iter().all(|&k| k < v.len()));
        match file {
            Some((i, v, word)) => (idx.iter().map(|&k| v[k].to_string()).collect::<Vec<_>>().join(", "), Some(word), i.based()),
            None => (idx.iter().map(usize::to_string).collect::<Vec<_>>().join(", "), None, " (0-based, in file order)"),
        }
    }

    /// See [`RawMesh::cell_name`].
    pub fn cell(ids: Option<&FileIds>, e: usize) -> String {
        let (l, word, note) = Self::list(ids, true, &[e]);
        format!("{} {l}{note}", word.unwrap_or("element"))
    }

    /// See [`RawMesh::point_name`].
    pub fn point(ids: Option<&FileIds>, p: usize) -> String {
        let (l, word, note) = Self::list(ids, false, &[p]);
        format!("{} {l}{note}", word.unwrap_or("point"))
    }

    /// Elements, `more` after the list: "element tags 14, 15, 16, ...", "VTK cells 3, 4
    /// (0-based, as in the file)", "elements 14, 15, 16, ... (0-based, in file order)".
    pub fn cells(ids: Option<&FileIds>, es: &[usize], more: &str) -> String {
        let (l, word, note) = Self::list(ids, true, es);
        format!("{}s {l}{more}{note}", word.unwrap_or("element"))
    }

    /// Corner points: "points [node tags 3, 4, 9]" or "points [3, 4, 9] (0-based, in file
    /// order)".
    pub fn points(ids: Option<&FileIds>, ps: &[u32]) -> String {
        let idx: Vec<usize> = ps.iter().map(|&p| p as usize).collect();
        match Self::list(ids, false, &idx) {
            (l, Some(word), note) => format!("points [{word}s {l}]{note}"),
            (l, None, note) => format!("points [{l}]{note}"),
        }
    }
}

/// How [`RawMesh::validate`] treats clockwise cells.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ValidationOptions {
    /// Reorient clockwise cells and report each in a warning (default).
    #[default]
    Reorient,
    /// Refuse clockwise cells.
    Refuse,
}

/// Signed area of a polygon given by its corners (counter-clockwise positive).
pub fn signed_area(p: &[[f64; 2]]) -> f64 {
    let n = p.len();
    let mut a = 0.0;
    for i in 0..n {
        let j = (i + 1) % n;
        a += p[i][0] * p[j][1] - p[j][0] * p[i][1];
    }
    0.5 * a
}

/// Largest coordinate magnitude (and mesh size) accepted by [`RawMesh::validate`].
pub const MAX_COORD: f64 = 1e100;

impl RawMesh {
    /// The smallest box `(lo, hi)` holding every point (infinite bounds for a mesh without
    /// points). One pass, in point order.
    pub fn bounding_box(&self) -> ([f64; 2], [f64; 2]) {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in &self.points {
            for d in 0..2 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        (lo, hi)
    }

    /// Cell `e` as the user's file names it: "element tag 57" (gmsh), "VTK cell 12 (0-based, as
    /// in the file)", or "element 12 (0-based, in file order)" without [`FileIds`].
    pub fn cell_name(&self, e: usize) -> String {
        FileIds::cell(self.ids.as_ref(), e)
    }

    /// Point `p` as the user's file names it ("node tag 33", "VTK point 33 (0-based, as in the
    /// file)", "point 33 (0-based, in file order)").
    pub fn point_name(&self, p: usize) -> String {
        FileIds::point(self.ids.as_ref(), p)
    }

    /// Points as the user's file names them ("points [node tags 3, 18]"; see [`FileIds::points`]).
    pub fn points_name(&self, ps: &[u32]) -> String {
        FileIds::points(self.ids.as_ref(), ps)
    }

    /// Elements as the user's file names them, `more` after the list ([`FileIds::cells`]).
    pub fn cells_name(&self, es: &[usize], more: &str) -> String {
        FileIds::cells(self.ids.as_ref(), es, more)
    }

    /// Checks the mesh; returns warnings (reoriented cells) or the first error, naming the file
    /// and the element and points by the ids of the file ([`RawMesh::cell_name`]; 0-based
    /// indices in the file's order of 2D cells and of used points without [`FileIds`]).
    pub fn validate(&mut self, opt: ValidationOptions) -> Result<Vec<String>> {
        let src = self.source.clone();
        let np = self.points.len();
        let mut warnings = Vec::new();
        if self.cells.is_empty() {
            return Err(FlemError::mesh(&src, "the mesh has no 2D elements (triangles or quadrilaterals)"));
        }
        if self.cell_region.len() != self.cells.len() {
            self.cell_region = vec!["all".to_string(); self.cells.len()];
        }
        for (i, p) in self.points.iter().enumerate() {
            if !p[0].is_finite() || !p[1].is_finite() {
                return Err(FlemError::mesh(&src, format!("{} has a non-finite coordinate {p:?}", self.point_name(i))));
            }
        }
        // Lengths for relative tolerances.
        let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
        for p in &self.points {
            for d in 0..2 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        let diam = ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2)).sqrt().max(f64::MIN_POSITIVE);
        // Areas and stiffnesses square and cube lengths: beyond this they overflow f64 (and the
        // zero-area test below would misfire), so refuse such coordinates here, by name.
        let far = lo.iter().chain(&hi).fold(0.0f64, |m, x| m.max(x.abs()));
        if !(far <= MAX_COORD && diam <= MAX_COORD) {
            return Err(FlemError::mesh(&src, format!("coordinates reach {far:e} (the mesh is {diam:e} across); they must stay below {MAX_COORD:e} in magnitude: rescale the units")));
        }
        let ids = self.ids.as_ref();
        let name = |e: usize| FileIds::cell(ids, e);
        let pname = |p: usize| FileIds::point(ids, p);
        let pnames = |ps: &[u32]| FileIds::points(ids, ps);
        let mut flipped = 0usize;
        for (e, c) in self.cells.iter_mut().enumerate() {
            let k = c.kind.nodes();
            for a in 0..k {
                let n = c.nodes[a] as usize;
                if n >= np {
                    return Err(FlemError::mesh(&src, format!("{} refers to point index {n}, but there are only {np} points", name(e))));
                }
                for b in 0..a {
                    if c.nodes[b] == c.nodes[a] {
                        return Err(FlemError::mesh(&src, format!("{} uses {} twice", name(e), pname(c.nodes[a] as usize))));
                    }
                }
            }
            let corners: Vec<[f64; 2]> = c.corners().iter().map(|&n| self.points[n as usize]).collect();
            let area = signed_area(&corners);
            let h = corners.iter().zip(corners.iter().cycle().skip(1)).map(|(a, b)| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()).fold(0.0, f64::max);
            if area.abs() <= 1e-12 * h * h.max(diam * 1e-9) || h == 0.0 {
                return Err(FlemError::mesh(&src, format!("{} has zero area ({})", name(e), pnames(c.corners()))));
            }
            if area < 0.0 {
                if opt == ValidationOptions::Refuse {
                    return Err(FlemError::mesh(&src, format!("{} is clockwise ({}); reorient it or set model.orientation = \"reorient\"", name(e), pnames(c.corners()))));
                }
                c.nodes[..k].reverse();
                flipped += 1;
                if flipped <= 5 {
                    warnings.push(format!("{src}: {} was clockwise and has been reoriented", name(e)));
                }
            }
            if c.kind == CellKind::Q4 {
                // Convexity: every corner must turn left.
                let pts: Vec<[f64; 2]> = c.corners().iter().map(|&n| self.points[n as usize]).collect();
                for a in 0..4 {
                    let (p0, p1, p2) = (pts[a], pts[(a + 1) % 4], pts[(a + 2) % 4]);
                    let cross = (p1[0] - p0[0]) * (p2[1] - p1[1]) - (p1[1] - p0[1]) * (p2[0] - p1[0]);
                    if cross <= 0.0 {
                        return Err(FlemError::mesh(&src, format!("{} is not a convex quadrilateral ({})", name(e), pnames(c.corners()))));
                    }
                }
            }
        }
        if flipped > 5 {
            warnings.push(format!("{src}: {} elements in all were clockwise and have been reoriented", flipped));
        }
        // Edges shared by more than two elements.
        let mut edges: Vec<([u32; 2], u32)> = Vec::new();
        for (e, c) in self.cells.iter().enumerate() {
            let k = c.kind.nodes();
            for a in 0..k {
                let (p, q) = (c.nodes[a], c.nodes[(a + 1) % k]);
                edges.push(([p.min(q), p.max(q)], e as u32));
            }
        }
        edges.sort_unstable();
        for w in edges.windows(3) {
            if w[0].0 == w[1].0 && w[1].0 == w[2].0 {
                return Err(FlemError::mesh(
                    &src,
                    format!(
                        "the edge between {} and {} is shared by more than two elements: {}, {}, {}",
                        self.point_name(w[0].0[0] as usize),
                        self.point_name(w[0].0[1] as usize),
                        self.cell_name(w[0].1 as usize),
                        self.cell_name(w[1].1 as usize),
                        self.cell_name(w[2].1 as usize)
                    ),
                ));
            }
        }
        // Duplicate points (used ones only; tolerance relative to the mesh size).
        let mut used = vec![false; np];
        for c in &self.cells {
            for &n in c.corners() {
                used[n as usize] = true;
            }
        }
        let mut order: Vec<usize> = (0..np).filter(|&i| used[i]).collect();
        order.sort_by(|&a, &b| self.points[a][0].total_cmp(&self.points[b][0]).then(self.points[a][1].total_cmp(&self.points[b][1])));
        let tol = 1e-10 * diam;
        for i in 0..order.len() {
            let a = order[i];
            for &b in &order[i + 1..] {
                if self.points[b][0] - self.points[a][0] > tol {
                    break;
                }
                if (self.points[b][1] - self.points[a][1]).abs() <= tol {
                    return Err(FlemError::mesh(
                        &src,
                        format!(
                            "duplicate points: {} and {} are both at ({}, {}): merge them or declare the edges between them separated",
                            self.point_name(a.min(b)),
                            self.point_name(a.max(b)),
                            self.points[a][0],
                            self.points[a][1]
                        ),
                    ));
                }
            }
        }
        if let Some(i) = (0..np).find(|&i| !used[i]) {
            let n = used.iter().filter(|u| !**u).count();
            return Err(FlemError::mesh(&src, format!("{} is not used by any element ({n} unreferenced points in all); remove them from the mesh", self.point_name(i))));
        }
        // Groups must refer to existing points.
        for (name, set) in &self.node_sets {
            if let Some(&n) = set.iter().find(|&&n| n as usize >= np) {
                return Err(FlemError::mesh(&src, format!("node set \"{name}\" refers to point {n}, but there are only {np} points")));
            }
        }
        for (name, set) in &self.edge_sets {
            if let Some(e) = set.iter().find(|e| e[0] as usize >= np || e[1] as usize >= np) {
                return Err(FlemError::mesh(&src, format!("edge set \"{name}\" refers to edge {e:?}, but there are only {np} points")));
            }
        }
        Ok(warnings)
    }

    /// Adds node sets for every edge set that has no node set of the same name.
    pub fn derive_node_sets(&mut self) {
        let names: Vec<String> = self.edge_sets.keys().cloned().collect();
        for name in names {
            if !self.node_sets.contains_key(&name) {
                let mut v: Vec<u32> = self.edge_sets[&name].iter().flat_map(|e| [e[0], e[1]]).collect();
                v.sort_unstable();
                v.dedup();
                self.node_sets.insert(name, v);
            }
        }
    }
}
