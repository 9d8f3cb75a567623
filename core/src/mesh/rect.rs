//! The built-in structured mesh generator: a rectangle of quads or triangles, with an optional
//! side notch made of pre-separated edges, so that a scene needs no mesh file.
use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::{CellKind, MeshSource, RawCell, RawMesh, MAX_COORD};
use crate::error::{FlemError, Result};

/// A side notch: the horizontal grid line at height `y` is separated from the side `side`
/// over `depth`. Its edges form the edge set "notch" (declare it in `cracking.separated`),
/// the point at its end the node set "notch_tip".
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Notch {
    /// "left" or "right".
    pub side: String,
    /// Height of the notch line (must fall on a grid line).
    pub y: f64,
    /// Length of the notch from the side (must be a whole number of element widths).
    pub depth: f64,
}

/// `[mesh] type = "rectangle"`: `nx` x `ny` cells on `[x0, x0 + width] x [y0, y0 + height]`.
///
/// Groups: node and edge sets `left`, `right`, `bottom`, `top`; node sets `bottom_left`,
/// `bottom_right`, `top_left`, `top_right`, `all`; region `all`.
/// T3 cells split each square by the diagonal from its bottom-left to its top-right corner, so
/// an interior point has a fan of six triangles.
/// `distort` moves interior points by up to `distort` x the cell size (deterministic; for
/// patch tests on distorted meshes).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rectangle {
    pub width: f64,
    pub height: f64,
    pub nx: usize,
    pub ny: usize,
    #[serde(default = "default_q4", deserialize_with = "crate::mesh::raw::de_mesh_element")]
    pub element: CellKind,
    #[serde(default)]
    pub origin: [f64; 2],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub notch: Option<Notch>,
    #[serde(default)]
    pub distort: f64,
    /// Heights of horizontal grid lines cut through the whole width (a pre-cut specimen):
    /// their edges form the edge set "cut" (declare it in `model.separated`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub cuts: Vec<f64>,
    /// Graded grid along x: zones `[[length, cells, ratio], ...]` from the left, each with
    /// `cells` cells growing by a constant factor so that its last cell is `ratio` times its
    /// first (1: uniform). The lengths must add up to `width`, the cells to `nx`. Absent:
    /// uniform. Not with a notch or cuts.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub grading_x: Vec<[f64; 3]>,
    /// The same along y, zones from the bottom (lengths add up to `height`, cells to `ny`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub grading_y: Vec<[f64; 3]>,
}

/// Grid lines `0..=n` over `[o, o + len]` with last/first cell ratio `g`.
fn graded(o: f64, len: f64, n: usize, g: f64) -> Vec<f64> {
    if g == 1.0 || n == 1 {
        let h = len / n as f64;
        return (0..=n).map(|i| o + i as f64 * h).collect();
    }
    let q = g.powf(1.0 / (n - 1) as f64);
    let mut x = Vec::with_capacity(n + 1);
    let (mut acc, mut h) = (0.0, 1.0);
    x.push(0.0);
    for _ in 0..n {
        acc += h;
        x.push(acc);
        h *= q;
    }
    let total = acc;
    x.iter().enumerate().map(|(i, v)| if i == n { o + len } else { o + len * v / total }).collect()
}

/// Grid lines of one direction: uniform, or the zones of `grading` (checked against `len`, `n`).
fn lines(o: f64, len: f64, n: usize, zones: &[[f64; 3]], key: &str) -> std::result::Result<Vec<f64>, (String, String)> {
    if zones.is_empty() {
        return Ok(graded(o, len, n, 1.0));
    }
    let mut out = vec![o];
    let (mut at, mut cells) = (o, 0usize);
    for (k, z) in zones.iter().enumerate() {
        let [l, c, r] = *z;
        if !(l > 0.0 && l.is_finite() && c >= 1.0 && c <= 4096.0 && c.fract() == 0.0 && (0.01..=100.0).contains(&r)) {
            return Err((format!("{key}[{k}]"), format!("= {z:?} is incorrect; it must be [length > 0, cells (a whole number in [1, 4096]), ratio in [0.01, 100]]")));
        }
        let g = graded(at, l, c as usize, r);
        out.extend_from_slice(&g[1..]);
        at += l;
        cells += c as usize;
    }
    if cells != n || ((at - o) - len).abs() > 1e-9 * len {
        return Err((key.to_string(), format!("zones give {cells} cells over {}; they must give exactly the cells (n = {n}) and the length ({len}) of the rectangle", at - o)));
    }
    *out.last_mut().expect("non-empty") = o + len;
    Ok(out)
}

fn default_q4() -> CellKind {
    CellKind::Q4
}

const SRC: &str = "mesh (rectangle)";

impl Rectangle {
    pub fn new(width: f64, height: f64, nx: usize, ny: usize, element: CellKind) -> Self {
        Rectangle { width, height, nx, ny, element, origin: [0.0, 0.0], notch: None, distort: 0.0, cuts: Vec::new(), grading_x: Vec::new(), grading_y: Vec::new() }
    }

    pub fn build(&self) -> Result<RawMesh> {
        let bad = |key: &str, msg: String| FlemError::config(SRC, format!("mesh.{key}"), msg);
        if !(self.width > 0.0 && self.width <= MAX_COORD) {
            return Err(bad("width", format!("= {} is incorrect; it must be in (0, {MAX_COORD:e}]", self.width)));
        }
        if !(self.height > 0.0 && self.height <= MAX_COORD) {
            return Err(bad("height", format!("= {} is incorrect; it must be in (0, {MAX_COORD:e}]", self.height)));
        }
        for (d, o) in self.origin.iter().enumerate() {
            if !(o.abs() <= MAX_COORD) {
                return Err(bad(&format!("origin[{d}]"), format!("= {o} is incorrect; it must be in [-{MAX_COORD:e}, {MAX_COORD:e}]")));
            }
        }
        if self.nx == 0 || self.nx > 4096 {
            return Err(bad("nx", format!("= {} is incorrect; it must be in [1, 4096]", self.nx)));
        }
        if self.ny == 0 || self.ny > 4096 {
            return Err(bad("ny", format!("= {} is incorrect; it must be in [1, 4096]", self.ny)));
        }
        if !(0.0..0.3).contains(&self.distort) {
            return Err(bad("distort", format!("= {} is incorrect; it must be in [0, 0.3)", self.distort)));
        }
        if !(self.grading_x.is_empty() && self.grading_y.is_empty()) && (self.notch.is_some() || !self.cuts.is_empty()) {
            return Err(bad("grading_x", "and grading_y cannot be combined with a notch or cuts (their lines are placed on a uniform grid)".into()));
        }
        let (nx, ny) = (self.nx, self.ny);
        let gx = lines(self.origin[0], self.width, nx, &self.grading_x, "grading_x").map_err(|(k, m)| bad(&k, m))?;
        let gy = lines(self.origin[1], self.height, ny, &self.grading_y, "grading_y").map_err(|(k, m)| bad(&k, m))?;
        let (hx, hy) = (self.width / nx as f64, self.height / ny as f64);
        let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
        let mut points = Vec::with_capacity((nx + 1) * (ny + 1));
        let mut seed: u64 = 0x2545_F491_4F6C_DD1D;
        for j in 0..=ny {
            for i in 0..=nx {
                let mut x = [gx[i], gy[j]];
                if self.distort > 0.0 && i > 0 && i < nx && j > 0 && j < ny {
                    for (d, h) in [hx, hy].into_iter().enumerate() {
                        seed ^= seed << 13;
                        seed ^= seed >> 7;
                        seed ^= seed << 17;
                        let r = (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
                        x[d] += r * self.distort * h;
                    }
                }
                points.push(x);
            }
        }
        let mut cells = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                match self.element {
                    CellKind::Q4 => cells.push(RawCell { kind: CellKind::Q4, nodes: [a, b, c, d] }),
                    CellKind::T3 => {
                        cells.push(RawCell { kind: CellKind::T3, nodes: [a, b, c, 0] });
                        cells.push(RawCell { kind: CellKind::T3, nodes: [a, c, d, 0] });
                    }
                }
            }
        }
        let mut node_sets = BTreeMap::new();
        let mut edge_sets = BTreeMap::new();
        let side = |f: &dyn Fn(usize) -> u32, n: usize| -> (Vec<u32>, Vec<[u32; 2]>) { ((0..=n).map(f).collect(), (0..n).map(|k| [f(k), f(k + 1)]).collect()) };
        for (name, (ns, es)) in [("left", side(&|j| id(0, j), ny)), ("right", side(&|j| id(nx, j), ny)), ("bottom", side(&|i| id(i, 0), nx)), ("top", side(&|i| id(i, ny), nx))] {
            node_sets.insert(name.to_string(), ns);
            edge_sets.insert(name.to_string(), es);
        }
        node_sets.insert("bottom_left".into(), vec![id(0, 0)]);
        node_sets.insert("bottom_right".into(), vec![id(nx, 0)]);
        node_sets.insert("top_left".into(), vec![id(0, ny)]);
        node_sets.insert("top_right".into(), vec![id(nx, ny)]);
        node_sets.insert("all".into(), (0..points.len() as u32).collect());
        if let Some(n) = &self.notch {
            let jf = (n.y - self.origin[1]) / hy;
            let j = jf.round();
            // Written so that NaN fails (every comparison with NaN is false).
            if !((jf - j).abs() <= 1e-6 && j >= 1.0 && j <= (ny - 1) as f64) {
                return Err(bad("notch.y", format!("= {} is incorrect; it must be an interior grid line y0 + k * {hy} with k in [1, {}]", n.y, ny - 1)));
            }
            let kf = n.depth / hx;
            let k = kf.round();
            if !((kf - k).abs() <= 1e-6 && k >= 1.0 && k <= (nx - 1) as f64) {
                return Err(bad("notch.depth", format!("= {} is incorrect; it must be k * {hx} with k in [1, {}]", n.depth, nx - 1)));
            }
            let (j, k) = (j as usize, k as usize);
            let (edges, tip): (Vec<[u32; 2]>, u32) = match n.side.as_str() {
                "left" => ((0..k).map(|i| [id(i, j), id(i + 1, j)]).collect(), id(k, j)),
                "right" => ((nx - k..nx).map(|i| [id(i, j), id(i + 1, j)]).collect(), id(nx - k, j)),
                other => return Err(bad("notch.side", format!("= \"{other}\" is incorrect; it must be \"left\" or \"right\""))),
            };
            edge_sets.insert("notch".into(), edges);
            node_sets.insert("notch_tip".into(), vec![tip]);
        }
        if !self.cuts.is_empty() {
            let mut edges = Vec::new();
            for (k, &y) in self.cuts.iter().enumerate() {
                let jf = (y - self.origin[1]) / hy;
                let j = jf.round();
                if !((jf - j).abs() <= 1e-6 && j >= 1.0 && j <= (ny - 1) as f64) {
                    return Err(bad(&format!("cuts[{k}]"), format!("= {y} is incorrect; it must be an interior grid line y0 + k * {hy} with k in [1, {}]", ny - 1)));
                }
                edges.extend((0..nx).map(|i| [id(i, j as usize), id(i + 1, j as usize)]));
            }
            edge_sets.insert("cut".into(), edges);
        }
        let n = cells.len();
        Ok(RawMesh { source: SRC.into(), points, cells, cell_region: vec!["all".into(); n], node_sets, edge_sets, ids: None })
    }
}

#[typetag::serde(name = "rectangle")]
impl MeshSource for Rectangle {
    fn load(&self, _base: &std::path::Path) -> Result<RawMesh> {
        self.build()
    }
}
