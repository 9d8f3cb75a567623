//! Crack tips against time (issue 36): `crack_tips.csv` in the run folder, one row per crack
//! tip each time the cracks change (after a failure check that split something) and at every
//! stage end, append-only like `history.csv` (`csvlog.rs`; checkpoint section `"tips"`).
//!
//! # What a tip is
//! The *crack graph* has the mesh points as vertices and, as edges, the element edges that are
//! crack faces: separated at one end or both (`Topology::crack_state`), plus the pre-separated
//! edges of `model.separated` (the notch). Its *roots* are the notch's points (without a notch:
//! the point of the run's first split). A *tip* is a vertex of degree 1 that is no root: the
//! joined end of an edge separated at its other end (where the two faces still meet), or the
//! end of a crack that has reached the outer boundary. Its *arc* is its distance from the
//! roots along the crack graph (reference lengths, Dijkstra from every root at once).
//!
//! Spurs are no tips: a split cuts two edges through its point, and on an unstructured mesh
//! the one behind is seldom the crack's last edge, so the crack grows one-edge side twigs.
//! Candidates are taken by decreasing straight distance from the root their path starts at
//! (a side twig at the crack's end lies nearer the notch than the end itself, whose arc may be
//! the same); one is a tip when the part of its path not shared
//! with an accepted tip's path (its own branch) is at least `min_branch` long (the first always
//! is). `min_branch` is 5 x the mean length of the crack edges made so far (ours).
//!
//! # Branches
//! A branch is a tip followed through time: at each record, a branch whose tip is still a tip
//! keeps it; otherwise the tips whose path back to the roots passes within `min_branch` of its
//! last tip continue it (the crack grew from there). When several tips continue one branch (it
//! forked), the one farthest from the branch's fork (then the lowest point id) keeps the branch
//! and the others open new branches whose `parent` is it; their *fork* is where their path
//! meets the continuing tip's path (the branching point). A tip that continues no branch (a
//! side crack that grew to `min_branch`, a crack from the notch faces elsewhere) starts a branch
//! whose fork is where its path meets another tip's path and whose parent is that tip's branch
//! (else: its root, no parent). A branch's identity can pass to a side crack that is momentarily
//! the farther from its fork; the crack's front is the farthest tip of all. Tips not connected
//! to a root (a crack of its own, e.g. from a compressed impact zone) get one row per crack,
//! with an empty branch.
//!
//! # Speed (a window of ours)
//! A branch's speed at a record is the chord speed `|x_k - x_j| / (t_k - t_j)`: `x_k` its tip
//! now, `x_j` its tip at the latest earlier record at least `window` before; no speed while the
//! branch has no record that old (session 32: before, the branch's first record stood in, and
//! the burst of splits where a crack starts, a few elements in consecutive steps, was written as
//! a speed of 20-90 c_R on Kalthoff-Winkler; a checkpoint written before the change resumes with
//! the new rule, so its crack_tips.csv holds both). The chord over a window
//! smooths the zig-zag of a crack along element edges and the one-element jumps of a split;
//! `window` is `[output] tip_window` (time), by default 10 x the mean element edge over the
//! Rayleigh speed `c_R = c_s (0.862 + 1.14 nu) / (1 + nu)` of the first material: about the time
//! a crack at half the Rayleigh speed takes to cross 5 elements.
//!
//! # Columns
//! `time,step,branch,parent,x,y,arc,speed,fork_x,fork_y,boundary,crack_length,fracture_energy,
//! fracture_per_length`: `boundary` 1 when the tip is on the outer boundary; `crack_length` the
//! length of the crack faces made during the run (an edge separated at both ends whole, at one
//! end half: the area of the cohesive bond at each cut end, `contact::Bond`), the
//! notch excluded; `fracture_energy` the ledger's (`Ledger::fracture`, per the thickness of the
//! first material); `fracture_per_length` = `fracture_energy / (crack_length x thickness)`,
//! to compare with the cohesive law's `G_f`.
use std::collections::BinaryHeap;
use std::fmt::Write as _;
use std::path::Path;

use crate::cracking::SplitEvent;
use crate::error::Result;
use crate::ids::{EdgeId, PointId};
use crate::mesh::topology::SplitRecord;
use crate::output::csvlog::{CsvLog, LogMark};
use crate::solver::{Observer, Simulation, StagePos};

/// The checkpoint section of the tracker ([`TipState`]).
pub const TIPS_SECTION: &str = "tips";
pub const TIPS_SECTION_VERSION: u32 = 1;

const HEADER: &str = "time,step,branch,parent,x,y,arc,speed,fork_x,fork_y,boundary,crack_length,fracture_energy,fracture_per_length\n";

/// One branch followed through time.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Branch {
    pub parent: Option<u32>,
    /// The tip point at the last record.
    pub tip: u32,
    pub fork: [f64; 2],
    /// (time, x, y) of the tip at each record where the branch was alive.
    pub track: Vec<(f64, f64, f64)>,
    pub alive: bool,
}

/// What the tracker keeps (checkpoint section `"tips"`).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct TipState {
    pub branches: Vec<Branch>,
    /// The run's first split point (the root when there is no notch).
    pub origin: Option<u32>,
    pub log: Option<LogMark>,
    /// Separated edge ends at the last record (a record without a change writes no rows).
    pub last_ends: Option<usize>,
}

/// One tip at a record (for tests and callers).
#[derive(Clone, Debug, PartialEq)]
pub struct Tip {
    pub branch: Option<u32>,
    pub parent: Option<u32>,
    pub point: PointId,
    pub x: [f64; 2],
    pub arc: f64,
    pub speed: Option<f64>,
    pub fork: Option<[f64; 2]>,
    pub boundary: bool,
}

/// The crack-tip tracker: an [`Observer`] that writes `crack_tips.csv` (see the module doc).
pub struct TipTracker {
    log: CsvLog,
    pub window: f64,
    notch: Vec<bool>,
    on_boundary: Vec<bool>,
    pub state: TipState,
    /// The tips of the last record.
    pub last: Vec<Tip>,
    row: String,
}

/// `10 x mean edge / c_R` of the first material (module doc).
pub fn default_window(sim: &Simulation) -> f64 {
    let topo = &sim.model.topo;
    let pts = &sim.model.mesh.points;
    let len: f64 = topo.edges.iter().map(|e| dist(pts[e.points[0].idx()], pts[e.points[1].idx()])).sum::<f64>() / topo.edges.len().max(1) as f64;
    let m = &sim.scene.file.materials[0];
    let cs = (m.young_modulus / (2.0 * (1.0 + m.poisson_ratio)) / m.density).sqrt();
    let cr = cs * (0.862 + 1.14 * m.poisson_ratio) / (1.0 + m.poisson_ratio);
    10.0 * len / cr
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

/// A Dijkstra queue entry (smallest distance first, then lowest point).
#[derive(PartialEq)]
struct Q(f64, u32);
impl Eq for Q {}
impl PartialOrd for Q {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Q {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
    }
}

impl TipTracker {
    /// A tracker writing `dir/crack_tips.csv` (nothing is written before the first record);
    /// `window`: the speed window (None: [`default_window`]).
    pub fn new(dir: &Path, sim: &Simulation, window: Option<f64>) -> Result<Self> {
        let topo = &sim.model.topo;
        let file = sim.scene.path.display().to_string();
        let mut notch = vec![false; topo.edges.len()];
        for (i, g) in sim.scene.file.model.separated.iter().enumerate() {
            for e in sim.model.edge_set(g, &format!("model.separated[{i}]"), &file)? {
                notch[e.idx()] = true;
            }
        }
        let mut on_boundary = vec![false; topo.n_points];
        for e in &topo.edges {
            if e.sides[1].is_none() {
                on_boundary[e.points[0].idx()] = true;
                on_boundary[e.points[1].idx()] = true;
            }
        }
        Ok(TipTracker {
            log: CsvLog::new(dir.join("crack_tips.csv"), HEADER.to_string()),
            window: window.unwrap_or_else(|| default_window(sim)),
            notch,
            on_boundary,
            state: TipState::default(),
            last: Vec::new(),
            row: String::new(),
        })
    }

    /// The crack graph (module doc): per point its neighbours with the edge length, in edge
    /// order; whether each point is a crack vertex; the crack-face length made during the run;
    /// the number of separated edge ends; the mean length of the run's crack edges.
    fn graph(&self, sim: &Simulation) -> (Vec<Vec<(u32, f64)>>, Vec<bool>, f64, usize, f64) {
        let topo = &sim.model.topo;
        let pts = &sim.model.mesh.points;
        let mut vert = vec![false; topo.n_points];
        let (mut length, mut ends, mut sum, mut cnt) = (0.0, 0, 0.0, 0usize);
        let lens: Vec<f64> = topo.edges.iter().map(|e| dist(pts[e.points[0].idx()], pts[e.points[1].idx()])).collect();
        for (i, e) in topo.edges.iter().enumerate() {
            let s = topo.crack_state(EdgeId::new(i));
            if s == 0 && !self.notch[i] {
                continue;
            }
            vert[e.points[0].idx()] = true;
            vert[e.points[1].idx()] = true;
            ends += s as usize;
            if !self.notch[i] {
                length += 0.5 * s as f64 * lens[i];
                sum += lens[i];
                cnt += 1;
            }
        }
        let mut adj: Vec<Vec<(u32, f64)>> = vec![Vec::new(); topo.n_points];
        for (i, e) in topo.edges.iter().enumerate() {
            let [a, b] = e.points;
            if vert[a.idx()] && vert[b.idx()] {
                adj[a.idx()].push((b.0, lens[i]));
                adj[b.idx()].push((a.0, lens[i]));
            }
        }
        let mean = if cnt > 0 { sum / cnt as f64 } else { lens.iter().sum::<f64>() / lens.len().max(1) as f64 };
        (adj, vert, length, ends, mean)
    }

    /// Finds the tips and follows the branches (module doc); returns the tips, the crack
    /// length, and whether the cracks changed since the last record.
    pub fn locate(&mut self, sim: &Simulation) -> (Vec<Tip>, f64, bool) {
        let (adj, vert, length, ends, mean_edge) = self.graph(sim);
        let changed = self.state.last_ends != Some(ends);
        self.state.last_ends = Some(ends);
        let pts = &sim.model.mesh.points;
        let n = adj.len();
        // Roots: the notch's points, else the first split's point.
        let mut root = vec![false; n];
        for (i, e) in sim.model.topo.edges.iter().enumerate() {
            if self.notch[i] {
                root[e.points[0].idx()] = true;
                root[e.points[1].idx()] = true;
            }
        }
        if !root.iter().any(|&r| r) {
            if let Some(o) = self.state.origin {
                root[o as usize] = true;
            }
        }
        let (mut d, mut parent) = (vec![f64::INFINITY; n], vec![u32::MAX; n]);
        let mut heap = BinaryHeap::new();
        for p in 0..n {
            if root[p] {
                d[p] = 0.0;
                heap.push(Q(0.0, p as u32));
            }
        }
        while let Some(Q(dp, p)) = heap.pop() {
            if dp > d[p as usize] {
                continue;
            }
            for &(q, l) in &adj[p as usize] {
                if dp + l < d[q as usize] {
                    d[q as usize] = dp + l;
                    parent[q as usize] = p;
                    heap.push(Q(dp + l, q));
                }
            }
        }
        // The root each point's path starts at.
        let mut origin = vec![u32::MAX; n];
        let mut order: Vec<u32> = (0..n as u32).filter(|&p| d[p as usize].is_finite()).collect();
        order.sort_by(|&a, &b| d[a as usize].total_cmp(&d[b as usize]).then(a.cmp(&b)));
        for &p in &order {
            let q = parent[p as usize];
            origin[p as usize] = if q == u32::MAX { p } else { origin[q as usize] };
        }
        // Candidates by decreasing distance from their root; a tip needs its own part of the
        // path (up to the first point of an accepted tip's path) to be min_branch long.
        let min_branch = 5.0 * mean_edge;
        let far = |p: u32| dist(pts[p as usize], pts[origin[p as usize] as usize]);
        let mut cand: Vec<u32> = order.iter().copied().filter(|&p| !root[p as usize]).collect();
        cand.sort_by(|&a, &b| far(b).total_cmp(&far(a)).then(a.cmp(&b)));
        let mut claimed = vec![false; n];
        let mut reach: Vec<u32> = Vec::new();
        let mut chains: Vec<Vec<u32>> = Vec::new();
        for p in cand {
            if claimed[p as usize] {
                continue;
            }
            let mut q = p;
            while !claimed[q as usize] && parent[q as usize] != u32::MAX {
                q = parent[q as usize];
            }
            if claimed[q as usize] && d[p as usize] - d[q as usize] < min_branch {
                continue;
            }
            let mut c = vec![p];
            let mut q = p;
            while parent[q as usize] != u32::MAX {
                q = parent[q as usize];
                c.push(q);
            }
            c.iter().for_each(|&q| claimed[q as usize] = true);
            reach.push(p);
            chains.push(c);
        }
        let mut owner: Vec<Option<u32>> = vec![None; reach.len()];
        let nb = self.state.branches.len();
        // A branch whose tip is still a tip keeps it.
        let mut matched = vec![false; nb];
        for (b, m) in matched.iter_mut().enumerate() {
            let br = &self.state.branches[b];
            if let Some(k) = reach.iter().position(|&p| p == br.tip).filter(|_| br.alive) {
                owner[k] = Some(b as u32);
                *m = true;
            }
        }
        // A branch that grew: the tips whose path passes within min_branch of its old tip (a
        // shortest path may pass beside it) continue it.
        for b in 0..nb {
            if !self.state.branches[b].alive || matched[b] {
                continue;
            }
            let old = pts[self.state.branches[b].tip as usize];
            let mut cont: Vec<usize> = (0..reach.len()).filter(|&k| owner[k].is_none() && chains[k].iter().any(|&q| dist(pts[q as usize], old) <= min_branch)).collect();
            if cont.is_empty() {
                self.state.branches[b].alive = false;
                continue;
            }
            // The continuation: the tip farthest from the branch's fork.
            let fk = self.state.branches[b].fork;
            cont.sort_by(|&a, &c| dist(pts[reach[c] as usize], fk).total_cmp(&dist(pts[reach[a] as usize], fk)).then(reach[a].cmp(&reach[c])));
            let first = cont[0];
            owner[first] = Some(b as u32);
            self.state.branches[b].tip = reach[first];
            for &k in &cont[1..] {
                let meet = chains[k].iter().copied().find(|q| chains[first].contains(q)).unwrap_or(self.state.branches[b].tip);
                let id = self.state.branches.len() as u32;
                self.state.branches.push(Branch { parent: Some(b as u32), tip: reach[k], fork: pts[meet as usize], track: Vec::new(), alive: true });
                owner[k] = Some(id);
            }
        }
        for k in 0..reach.len() {
            if owner[k].is_some() {
                continue;
            }
            // A new crack from the roots, or one whose old tip is no longer near its path: it
            // forks where its path meets an earlier tip's path (that tip's branch is its
            // parent), else at its root.
            let meet = chains[k].iter().copied().find_map(|q| (0..reach.len()).find(|&j| j != k && owner[j].is_some() && chains[j].contains(&q)).map(|j| (q, owner[j])));
            let (fork, parent) = match meet {
                Some((q, o)) => (pts[q as usize], o),
                None => (pts[*chains[k].last().expect("a chain holds its tip") as usize], None),
            };
            let id = self.state.branches.len() as u32;
            self.state.branches.push(Branch { parent, tip: reach[k], fork, track: Vec::new(), alive: true });
            owner[k] = Some(id);
        }
        let t = sim.state.time;
        let mut tips = Vec::new();
        for (k, &p) in reach.iter().enumerate() {
            let b = owner[k].expect("every tip has a branch");
            let br = &mut self.state.branches[b as usize];
            let x = pts[p as usize];
            if br.track.last().is_none_or(|l| l.0 < t) {
                br.track.push((t, x[0], x[1]));
            }
            let speed = speed_of(&br.track, self.window);
            tips.push(Tip { branch: Some(b), parent: br.parent, point: PointId(p), x, arc: d[p as usize], speed, fork: Some(br.fork), boundary: self.on_boundary[p as usize] });
        }
        // Cracks not connected to a root: one row per component, at its lowest point id.
        let mut seen = vec![false; n];
        for p in 0..n {
            if !vert[p] || seen[p] || d[p].is_finite() {
                continue;
            }
            let mut stack = vec![p as u32];
            seen[p] = true;
            while let Some(q) = stack.pop() {
                for &(r, _) in &adj[q as usize] {
                    if !seen[r as usize] {
                        seen[r as usize] = true;
                        stack.push(r);
                    }
                }
            }
            tips.push(Tip { branch: None, parent: None, point: PointId(p as u32), x: pts[p], arc: f64::NAN, speed: None, fork: None, boundary: self.on_boundary[p] });
        }
        tips.sort_by_key(|t| (t.branch.map_or(u32::MAX, |b| b), t.point.0));
        (tips, length, changed)
    }

    /// Records the tips now (rows only when the cracks changed, unless `force`).
    pub fn record(&mut self, sim: &Simulation, force: bool) -> Result<()> {
        let (tips, length, changed) = self.locate(sim);
        self.last = tips;
        if !changed && !force {
            return Ok(());
        }
        let thick = sim.scene.file.materials[0].thickness;
        let frac = sim.ledger.fracture / thick;
        let r = &mut self.row;
        r.clear();
        let num = |r: &mut String, v: f64| {
            r.push(',');
            if v.is_finite() {
                let _ = write!(r, "{v:e}");
            }
        };
        for tip in &self.last {
            let _ = write!(r, "{:e},{}", sim.state.time, sim.state.step);
            r.push(',');
            if let Some(b) = tip.branch {
                let _ = write!(r, "{b}");
            }
            r.push(',');
            if let Some(b) = tip.parent {
                let _ = write!(r, "{b}");
            }
            num(r, tip.x[0]);
            num(r, tip.x[1]);
            num(r, tip.arc);
            num(r, tip.speed.unwrap_or(f64::NAN));
            let f = tip.fork.unwrap_or([f64::NAN; 2]);
            num(r, f[0]);
            num(r, f[1]);
            let _ = write!(r, ",{}", tip.boundary as u8);
            num(r, length);
            num(r, frac);
            num(r, if length > 0.0 { frac / length } else { f64::NAN });
            r.push('\n');
        }
        self.log.append(self.row.as_bytes())
    }

    /// fsync of the rows so far.
    pub fn sync(&self) -> Result<()> {
        self.log.sync()
    }

    /// Writes the header when no row was written yet (end of a run).
    pub fn finish(&mut self) -> Result<()> {
        self.log.append(&[])?;
        self.log.sync()
    }

    /// The state to checkpoint (after [`Self::sync`]).
    pub fn checkpoint_state(&self) -> TipState {
        TipState { log: self.log.mark(), ..self.state.clone() }
    }

    /// Continues from a checkpoint's state (`path`: the checkpoint file; its folder holds the
    /// log's recorded prefix).
    pub fn resume(&mut self, st: TipState, path: &Path) -> Result<()> {
        let src = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        self.log.resume(&src.join("crack_tips.csv"), st.log, path)?;
        self.state = st;
        Ok(())
    }
}

/// The chord speed of a track at its last point over `window` (module doc).
pub fn speed_of(track: &[(f64, f64, f64)], window: f64) -> Option<f64> {
    let &(t, x, y) = track.last()?;
    let earlier = &track[..track.len() - 1];
    let j = earlier.iter().rev().find(|p| p.0 <= t - window)?;
    (t > j.0).then(|| ((x - j.1).powi(2) + (y - j.2).powi(2)).sqrt() / (t - j.0))
}

impl Observer for TipTracker {
    fn splits(&mut self, sim: &Simulation, _rec: &SplitRecord, events: &[SplitEvent]) -> Result<()> {
        if self.state.origin.is_none() {
            self.state.origin = events.first().map(|e| e.point.0);
        }
        self.record(sim, false)
    }
    fn stage_end(&mut self, sim: &Simulation, _stage: usize) -> Result<()> {
        self.record(sim, true)
    }
    fn checkpoint(&mut self, _sim: &Simulation, _pos: &StagePos) -> Result<()> {
        self.sync()
    }
}
