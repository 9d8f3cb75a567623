//! Node and edge sets chosen by geometry in the scene (`[[set]]`, issue 23), for meshes whose
//! file lacks a group, or for one point to hold: as MOOSE's `BoundingBoxNodeSet` and
//! `SideSetsFromBoundingBox` do. A set gets a name usable wherever a mesh group's is (supports,
//! loads, probes, `model.separated`, contact surfaces):
//!
//! ```toml
//! [[set]]
//! name = "pin"
//! nearest = [0.0, 0.0]            # the one mesh point nearest to (x, y)
//!
//! [[set]]
//! name = "load_zone"
//! box = [[0.0, 3.9], [1.0, 4.1]]  # points in the box [x0, x1] x [y0, y1] (edges: both ends in it)
//!
//! [[set]]
//! name = "ligament"
//! segment = [[2.0, 0.0], [2.0, 1.0]]  # points on the segment (edges: both ends on it)
//! tolerance = 1e-6                # distance to the segment or box that still counts (default 1e-6 x the mesh's size)
//! boundary = false                # edges: also interior edges (default true: edges of the body's boundary only)
//! ```
//!
//! Exactly one of `nearest`, `box`, `segment`. A box or segment names both a node set and an
//! edge set; `nearest` a node set. A selection that catches nothing, or a name that a mesh group
//! already has, is refused naming the key. Sets are made from the mesh as read (reference
//! coordinates), before any split.
use serde::{Deserialize, Serialize};

use super::RawMesh;
use crate::error::{FlemError, Result};

/// `[[set]]`: a node set (and edge set) chosen by geometry.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SetCfg {
    pub name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nearest: Option<[f64; 2]>,
    #[serde(default, rename = "box", skip_serializing_if = "Option::is_none")]
    pub bbox: Option<[[f64; 2]; 2]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub segment: Option<[[f64; 2]; 2]>,
    /// Distance to the box or segment that still counts (default: 1e-6 x the mesh's size).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Edge sets: only edges on the body's boundary (`false`: interior edges too).
    #[serde(default = "yes")]
    pub boundary: bool,
}

fn yes() -> bool {
    true
}

/// Distance from `p` to the segment `a`-`b`.
fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let s = if l2 > 0.0 { (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0) } else { 0.0 };
    (p[0] - a[0] - s * dx).hypot(p[1] - a[1] - s * dy)
}

impl SetCfg {
    /// Checks the keys (finite coordinates, one selection, a positive tolerance); errors name
    /// `set[i].<key>`.
    pub fn validate(&self, i: usize, file: &str) -> Result<()> {
        let key = |k: &str| format!("set[{i}].{k}");
        let n = [self.nearest.is_some(), self.bbox.is_some(), self.segment.is_some()].iter().filter(|&&b| b).count();
        if n != 1 {
            return Err(FlemError::config(file, key("name"), format!("= \"{}\" gives {n} selections; give exactly one of nearest, box, segment", self.name)));
        }
        let coords: Vec<(String, f64)> = match (&self.nearest, &self.bbox, &self.segment) {
            (Some(p), _, _) => p.iter().enumerate().map(|(d, v)| (key(&format!("nearest[{d}]")), *v)).collect(),
            (_, Some(b), _) => b.iter().enumerate().flat_map(|(k, p)| p.iter().enumerate().map(move |(d, v)| (format!("set[{i}].box[{k}][{d}]"), *v))).collect(),
            (_, _, Some(s)) => s.iter().enumerate().flat_map(|(k, p)| p.iter().enumerate().map(move |(d, v)| (format!("set[{i}].segment[{k}][{d}]"), *v))).collect(),
            _ => Vec::new(),
        };
        for (k, v) in coords {
            if !v.is_finite() || v.abs() > super::MAX_COORD {
                return Err(FlemError::config(file, k, format!("= {v} is incorrect; a coordinate must be finite and at most {:e} in magnitude", super::MAX_COORD)));
            }
        }
        if let Some(b) = &self.bbox {
            if b[0][0] > b[1][0] || b[0][1] > b[1][1] {
                return Err(FlemError::config(file, key("box"), "must be [[x0, y0], [x1, y1]] with x0 <= x1 and y0 <= y1"));
            }
        }
        if let Some([a, b]) = &self.segment {
            if a == b {
                return Err(FlemError::config(file, key("segment"), "has two equal ends; give two distinct points (or `nearest` for one point)"));
            }
        }
        if let Some(t) = self.tolerance {
            if !(t.is_finite() && t >= 0.0 && t <= super::MAX_COORD) {
                return Err(FlemError::config(file, key("tolerance"), format!("= {t} is incorrect; it must be a finite distance >= 0")));
            }
        }
        Ok(())
    }
}

impl RawMesh {
    /// Adds the node set (and edge set) a `[[set]]` selects; `key` is `set[i]` for messages.
    pub fn add_selection(&mut self, set: &SetCfg, key: &str, file: &str) -> Result<()> {
        if self.node_sets.contains_key(&set.name) || self.edge_sets.contains_key(&set.name) {
            return Err(FlemError::config(file, format!("{key}.name"), format!("= \"{}\" is already a group of the mesh; choose another name", set.name)));
        }
        let (lo, hi) = self.bounding_box();
        let size = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(0.0);
        let tol = set.tolerance.unwrap_or(1e-6 * size);
        let (inside, what, sel_key): (Box<dyn Fn([f64; 2]) -> bool>, String, String) = if let Some(q) = set.nearest {
            // The nearest point; ties go to the lowest index.
            let best = (0..self.points.len()).min_by(|&a, &b| {
                let da = (self.points[a][0] - q[0]).hypot(self.points[a][1] - q[1]);
                let db = (self.points[b][0] - q[0]).hypot(self.points[b][1] - q[1]);
                da.total_cmp(&db).then(a.cmp(&b))
            });
            let Some(best) = best else { return Err(FlemError::config(file, format!("{key}.nearest"), "selects nothing: the mesh has no points")) };
            self.node_sets.insert(set.name.clone(), vec![best as u32]);
            return Ok(());
        } else if let Some([a, b]) = set.bbox {
            (Box::new(move |p: [f64; 2]| p[0] >= a[0] - tol && p[0] <= b[0] + tol && p[1] >= a[1] - tol && p[1] <= b[1] + tol), format!("the box {a:?}-{b:?}"), format!("{key}.box"))
        } else if let Some([a, b]) = set.segment {
            (Box::new(move |p: [f64; 2]| segment_distance(p, a, b) <= tol), format!("the segment {a:?}-{b:?}"), format!("{key}.segment"))
        } else {
            return Err(FlemError::config(file, format!("{key}.name"), "gives no selection; give one of nearest, box, segment"));
        };
        let points: Vec<u32> = (0..self.points.len() as u32).filter(|&p| inside(self.points[p as usize])).collect();
        if points.is_empty() {
            return Err(FlemError::config(file, sel_key, format!("selects no point of the mesh: none lies within {tol:e} of {what} (the mesh spans [{}, {}] x [{}, {}])", lo[0], hi[0], lo[1], hi[1])));
        }
        // Edges: both ends selected; on the boundary (one cell) unless `boundary = false`.
        let mut count: std::collections::BTreeMap<[u32; 2], u32> = std::collections::BTreeMap::new();
        for c in &self.cells {
            let k = c.corners();
            for j in 0..k.len() {
                let (p, q) = (k[j], k[(j + 1) % k.len()]);
                *count.entry([p.min(q), p.max(q)]).or_default() += 1;
            }
        }
        let is_in = |p: u32| points.binary_search(&p).is_ok();
        let edges: Vec<[u32; 2]> = count.iter().filter(|(e, &n)| is_in(e[0]) && is_in(e[1]) && (!set.boundary || n == 1)).map(|(e, _)| *e).collect();
        self.node_sets.insert(set.name.clone(), points);
        if !edges.is_empty() {
            self.edge_sets.insert(set.name.clone(), edges);
        }
        Ok(())
    }
}
