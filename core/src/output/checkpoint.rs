//! Checkpoints: the whole state of a run in a versioned binary file with a checksum, so that a
//! run interrupted anywhere (Ctrl-C, SIGTERM, a crash, a full disk) continues bit for bit.
//!
//! # File layout (all integers little endian)
//! | bytes | what |
//! |---|---|
//! | 0..8 | magic `FLEMCKPT` |
//! | 8..12 | format version `u32` ([`FORMAT_VERSION`]) |
//! | 12..16 | CRC-32 (IEEE, `crc32fast`) of every byte from 16 to the end |
//! | 16..24 | `u64` length of the bytes from 24 to the end (a truncated file is named as such) |
//! | 24..32 | `u64` hash of the resolved scene and its mesh ([`scene_hash`]) |
//! | 32..34 | `u16` length `n` of the FLEM version string, then its `n` bytes |
//! | then | the payload: [`Checkpoint`] encoded with `postcard` |
//!
//! A file is refused, with its name and the reason, when the magic, the format version, the
//! length, the checksum, the FLEM version or the scene hash do not match; `--resume` then tries
//! the previous file ([`load_newest`]).
//!
//! # What is stored
//! Nodal arrays verbatim (u, v, f_int, f_ext, v_pres, mass, fixity), time and step counter, the
//! energy ledger, load levels, the step size, the damping plugin's `state()`, the last step's
//! statistics and damping coefficients (the adaptive damping reads them), the unbalanced
//! ratio, finished stage results, the position in the stage loop ([`StagePos`]), and the
//! cracking history as the ordered list of cuts (cluster, edges) logged by `Cracking::check`. On restore the cuts are replayed
//! through the same `Topology::cut` / `Model::apply_record` / `apply_split_record` calls as the
//! run made, then the copy-to-cluster map is compared with the stored one (a mismatch refuses
//! the file). Weibull strength factors are a stateless hash of (seed, point): nothing to store.
//!
//! # Adding state (e.g. contact pairs with their history)
//! Two ways, both in this file:
//! - a subsystem with its own state puts a **section**: `ck.put_section("contact", 1, &pairs)`
//!   when capturing (the observer's [`crate::solver::Observer::checkpoint`] or [`Checkpoint::capture`]),
//!   `ck.section::<Pairs>("contact", 1)` when restoring (in [`Checkpoint::restore`]). A section
//!   has its own version; a reader that meets an unknown version refuses it by name. The output
//!   writer keeps its snapshot list and the byte length + CRC-32 of `history.csv` and
//!   `splits.csv` in section `"output"` (version 2; `crate::output::WriterState`): a resume
//!   checks those files' prefixes and truncates them (`crate::output::csvlog`), so a checkpoint's
//!   size does not grow with the number of rows.
//! - a new field of [`Checkpoint`] itself: add it at the end and bump [`FORMAT_VERSION`]
//!   (postcard is not self-describing, so old files are then refused with a clear message).
//!
//! # When a checkpoint is taken
//! The stage loop calls `Observer::checkpoint(sim, &StagePos)` between two steps: every
//! `output.checkpoint_every` steps (global step count) or when `Observer::checkpoint_due` (the
//! writer's `checkpoint_seconds`), at the end of every stage (position = start of the next
//! stage), and when `Observer::should_stop` (polled once per step; the CLI's SIGINT/SIGTERM flag
//! from `signal-hook`) asks to stop: then a snapshot "interrupted" and `FlemError::Interrupted`.
//! The divergence guard runs before every checkpoint, and the CSV logs are synced.
//!
//! # Re-entrant stage loop
//! `Simulation::run_from(StagePos)` / `run_stage_from`; `StagePos` holds the stage, the step
//! within it, whether `begin_stage` was applied, and the loop's counters (splits, ratio, wall
//! time). `run()` is `run_from(StagePos::start(0))`.
//!
//! # Files, versions, sections
//! `checkpoint_{seq:06}.bin`: the newest `checkpoint_keep` are kept; older ones are removed
//! only after the new one is in place. The scene hash is FNV-1a of the resolved TOML + the
//! mesh's points and cells. `FORMAT_VERSION` is 3 (issue 36: the ledger's `fracture`; version 2
//! files lack it and are refused by name); version-1 files carried the logs' contents. `--resume` refuses a log that is shorter or whose recorded
//! prefix changed (naming the log and the checkpoint), truncates it to the recorded length (or
//! copies the prefix when resuming into another folder; a log the checkpoint did not record
//! yet is removed) and appends from there, so the logs end byte for byte as in an
//! uninterrupted run and a checkpoint's size does not grow with the rows (4.5 MB -> 6 KB for
//! the 22k-step run of `csvlog.rs`). Contact stores its pairs in section `"contact"` (version 2)
//! and the Verlet list's build state (surface displacements at the last build, pending flag,
//! rebuild count) in `"contact_verlet"`: the resumed run rebuilds the same list and rebuilds it
//! again at the same steps (`Contact::restore_verlet`; tests/ckpt.rs interrupts a cracking run
//! while pairs exist). The events solver (`solver/events.rs`) stores its stage loop in section
//! `"events"` (version 1: `EventsInfo`); it checkpoints between events (tests/events.rs). The
//! run's warnings so far are section `"warnings"` (version 1, issue 35): a resumed run's
//! summary.json lists the earlier stages' warnings too (an older file without it: only the
//! warnings of building the model).
use std::path::{Path, PathBuf};

use serde::{de::DeserializeOwned, Deserialize, Serialize};

use crate::error::{FlemError, Result};
use crate::ids::{ClusterId, EdgeId};
use crate::plugin::damping::{DampingCoeffs, StepStats};
use crate::solver::{Ledger, Simulation, StagePos, StageResult};

pub const MAGIC: &[u8; 8] = b"FLEMCKPT";
/// Version of the layout and of the [`Checkpoint`] payload. 2: the output section records the
/// CSV logs' lengths and checksums instead of their contents (the CSV files beside the
/// checkpoint are part of the state).
pub const FORMAT_VERSION: u32 = 3;

/// One named, versioned, opaque part of a checkpoint (postcard bytes).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Section {
    pub name: String,
    pub version: u32,
    pub bytes: Vec<u8>,
}

/// The payload of a checkpoint file.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Checkpoint {
    /// Sequence number (the file is `checkpoint_{seq:06}.bin`).
    pub seq: u64,
    pub pos: StagePos,
    pub step: u64,
    pub time: f64,
    pub dt: f64,
    pub u: Vec<[f64; 2]>,
    pub v: Vec<[f64; 2]>,
    pub f_int: Vec<[f64; 2]>,
    pub f_ext: Vec<[f64; 2]>,
    pub v_pres: Vec<[f64; 2]>,
    pub mass: Vec<f64>,
    pub fix: Vec<u8>,
    pub ledger: Ledger,
    pub levels: Vec<f64>,
    pub last_ratio: f64,
    /// The last step's statistics (step, dt, omega_max, kinetic, u.f_int, u.M.u).
    pub stats: (u64, f64, f64, f64, f64, f64),
    /// The last step's damping coefficients (viscous, local).
    pub coeffs: (f64, f64),
    /// The stable step (dt_crit, element bound, omega_max, iterations) and the eigenvector
    /// that warm-starts its next estimate after a split.
    pub stable: (f64, f64, f64, u64),
    pub stable_vec: Vec<[f64; 2]>,
    /// The contact part of the stable step (2 / omega_contact; infinite without contact).
    pub stable_dt_contact: f64,
    pub damping_state: Vec<f64>,
    pub stages_done: Vec<StageResult>,
    /// Cuts applied by the cracking driver, in order: (cluster, edges).
    pub cuts: Vec<(u32, Vec<u32>)>,
    /// Cluster of every copy after the cuts (checked after the replay).
    pub copy_cluster: Vec<u32>,
    pub failure_index: Vec<f64>,
    pub n_splits: usize,
    /// Extension sections (output writer state, contact pairs, ...).
    pub sections: Vec<Section>,
}

/// Adds (or replaces) a section of a checkpoint's list (2D and 3D).
pub fn put_section<T: Serialize>(sections: &mut Vec<Section>, name: &str, version: u32, value: &T) -> Result<()> {
    let bytes = postcard::to_stdvec(value).map_err(|e| FlemError::Other(format!("checkpoint section \"{name}\" cannot be encoded: {e}")))?;
    sections.retain(|s| s.name != name);
    sections.push(Section { name: name.to_string(), version, bytes });
    Ok(())
}

/// Reads a section of a checkpoint's list: `Ok(None)` when absent, an error when its version
/// is not `version`.
pub fn section<T: DeserializeOwned>(sections: &[Section], name: &str, version: u32) -> Result<Option<T>> {
    let Some(s) = sections.iter().find(|s| s.name == name) else { return Ok(None) };
    if s.version != version {
        return Err(FlemError::Other(format!("checkpoint section \"{name}\" has version {}, this program reads version {version}", s.version)));
    }
    postcard::from_bytes(&s.bytes).map(Some).map_err(|e| FlemError::Other(format!("checkpoint section \"{name}\" cannot be decoded: {e}")))
}

/// FNV-1a, 64 bit. Hand-written (6 lines) because the scene hash must be stable across Rust
/// releases (std's `DefaultHasher` is not) and a cryptographic hash would add a dependency
/// for no gain: it guards against resuming with another scene, not against an adversary.
pub(crate) fn fnv1a(h: &mut u64, bytes: &[u8]) {
    for &b in bytes {
        *h ^= b as u64;
        *h = h.wrapping_mul(0x0100_0000_01b3);
    }
}

/// Hash of the resolved scene (every default filled in) and of the mesh it built (points,
/// cells), so that a checkpoint cannot be resumed with another scene or an edited mesh file.
pub fn scene_hash(sim: &Simulation) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    fnv1a(&mut h, sim.scene.resolved_toml().as_bytes());
    // The mesh as read: points moved by the path method (ours) are hashed where they started.
    let moves = sim.cracking.as_ref().map_or(&[][..], |c| &c.path.moves[..]);
    let mut points = std::borrow::Cow::Borrowed(&sim.model.mesh.points);
    for m in moves.iter().rev() {
        points.to_mut()[m.point as usize] = m.from;
    }
    for p in points.iter() {
        fnv1a(&mut h, &p[0].to_le_bytes());
        fnv1a(&mut h, &p[1].to_le_bytes());
    }
    for e in 0..sim.model.topo.n_elems() {
        for k in sim.model.topo.elem_copies(crate::ids::ElemId::new(e)) {
            fnv1a(&mut h, &sim.model.topo.copy_point[k].0.to_le_bytes());
        }
    }
    h
}

impl Checkpoint {
    /// The state of `sim` at `pos` (nothing in `sim` changes).
    pub fn capture(sim: &Simulation, pos: &StagePos) -> Result<Checkpoint> {
        let st = &sim.state;
        let s = &sim.stats;
        let (cuts, failure_index, n_splits) = match &sim.cracking {
            Some(c) => (c.cuts.clone(), c.failure_index(sim.scene.file.cracking.as_ref().expect("cracking config"), &sim.model, &sim.state.u).into_owned(), c.n_splits),
            None => (Vec::new(), Vec::new(), 0),
        };
        let mut ck = Checkpoint {
            seq: 0,
            pos: pos.clone(),
            step: st.step,
            time: st.time,
            dt: sim.dt,
            u: st.u.clone(),
            v: st.v.clone(),
            f_int: st.f_int.clone(),
            f_ext: st.f_ext.clone(),
            v_pres: st.v_pres.clone(),
            mass: st.mass.clone(),
            fix: st.fix.clone(),
            ledger: sim.ledger,
            levels: sim.levels.clone(),
            last_ratio: sim.last_ratio,
            stats: (s.step, s.dt, s.omega_max, s.kinetic, s.u_f_int, s.u_m_u),
            coeffs: (sim.coeffs.viscous, sim.coeffs.local),
            stable: (sim.stable.dt_crit, sim.stable.dt_element_bound, sim.stable.omega_max, sim.stable.iterations as u64),
            stable_vec: sim.stable_vec.clone(),
            stable_dt_contact: sim.stable.dt_contact,
            damping_state: sim.scene.file.solver.damping.as_ref().map(|d| d.state()).unwrap_or_default(),
            stages_done: sim.stages_done.clone(),
            cuts,
            copy_cluster: sim.model.topo.copy_cluster.iter().map(|c| c.0).collect(),
            failure_index,
            n_splits,
            sections: Vec::new(),
        };
        // Contact pairs with their history (version 2: PairState::offset), and the Verlet list's build state (section
        // "contact_verlet": without it, as in older checkpoints, the list is rebuilt on the
        // next step, which can change the candidate sets and the rebuild steps after).
        // Stateful blocks (plastic laws, large strain): every block's point stress, history,
        // last displacements and internal work (`Block::save_state`), in block order.
        if sim.model.stateful {
            let blocks = sim.model.block_states();
            ck.put_section("blocks", 1, &blocks)?;
        }
        // The events solver's stage loop (its path, factor, left-out clusters, counters, the
        // kept factor's ordering): solver/events.rs.
        if let Some(ev) = &sim.events {
            ck.put_section("events", 1, ev)?;
        }
        // The path method's moves and tip lines (ours, issue 34): only when it moved or grew.
        if let Some(c) = sim.cracking.as_ref().filter(|c| c.path != crate::cracking::path::PathState::default()) {
            ck.put_section("path", 1, &c.path)?;
        }
        // Ours (session 18): the moves refused for a held point, only when some were.
        if let Some(c) = sim.cracking.as_ref().filter(|c| c.held_refused > 0) {
            ck.put_section("path_held", 1, &c.held_refused)?;
        }
        // Ours (issue 36): the ledger's relocation term (the path method's node moves), only
        // when a node moved (postcard lays the ledger out without it).
        if sim.ledger.relocation != 0.0 {
            ck.put_section("ledger_relocation", 1, &sim.ledger.relocation)?;
        }
        // The run's warnings so far (issue 35: a resumed run kept only those of building the
        // model and lost the earlier stages'). Absent in older checkpoints: the new
        // simulation's own are kept then.
        ck.put_section("warnings", 1, &sim.warnings)?;
        if let Some(c) = &sim.contact {
            ck.put_section("contact", 2, &c.history)?;
            ck.put_section("contact_verlet", 1, &c.verlet_state())?;
            if c.per_face() {
                ck.put_section("contact_bonds", 1, &c.bonds)?;
                // The margin of a list that splits updated locally (session 18).
                ck.put_section("contact_verlet_margin", 1, &c.verlet_margin())?;
            }
        }
        Ok(ck)
    }

    /// Adds (or replaces) a section.
    pub fn put_section<T: Serialize>(&mut self, name: &str, version: u32, value: &T) -> Result<()> {
        put_section(&mut self.sections, name, version, value)
    }

    /// Reads a section: `Ok(None)` when absent, an error when its version is not `version`.
    pub fn section<T: DeserializeOwned>(&self, name: &str, version: u32) -> Result<Option<T>> {
        section(&self.sections, name, version)
    }

    /// Puts the state into `sim`, a simulation freshly built from the same scene
    /// (`Simulation::new`): replays the cuts, checks the topology, copies every array.
    pub fn restore(&self, sim: &mut Simulation) -> Result<()> {
        let bad = |msg: String| FlemError::Other(format!("the checkpoint does not fit this scene: {msg}"));
        if sim.state.step != 0 || sim.cracking.as_ref().is_some_and(|c| !c.cuts.is_empty()) {
            return Err(FlemError::Other("a checkpoint can only be restored into a new simulation".into()));
        }
        sim.levels.clone_from(&self.levels);
        let path: crate::cracking::path::PathState = self.section("path", 1)?.unwrap_or_default();
        let held_refused: u64 = self.section("path_held", 1)?.unwrap_or(0);
        if let Some(cr) = sim.cracking.as_mut() {
            cr.held_refused = held_refused;
        }
        if !self.cuts.is_empty() {
            let Some(cr) = sim.cracking.as_mut() else { return Err(bad("it has splits and the scene has no [cracking]".into())) };
            cr.cuts.clone_from(&self.cuts);
            cr.path = path.clone();
            for (n, (c, edges)) in self.cuts.iter().enumerate() {
                let mut moved = Vec::new();
                for m in path.moves.iter().filter(|m| m.cut as usize == n) {
                    let p = crate::ids::PointId(m.point);
                    if p.idx() >= sim.model.mesh.points.len() {
                        return Err(bad(format!("move before cut {n} names point {} beyond the mesh", m.point)));
                    }
                    sim.model.move_point(p, m.to).map_err(|e| bad(format!("move before cut {n}: {e}")))?;
                    moved.push((p, m.to));
                }
                let edges: Vec<EdgeId> = edges.iter().map(|&e| EdgeId(e)).collect();
                if *c as usize >= sim.model.topo.n_clusters() || edges.iter().any(|e| e.idx() >= sim.model.topo.edges.len()) {
                    return Err(bad(format!("cut {n} names cluster {c} or an edge beyond the mesh")));
                }
                let mut rec = sim.model.topo.cut(ClusterId(*c), &edges, true);
                if rec.is_empty() {
                    return Err(bad(format!("cut {n} (cluster {c}) splits nothing when replayed")));
                }
                rec.moved = moved;
                sim.model.apply_record(&rec);
                sim.apply_split_arrays(&rec);
            }
        }
        let nc = sim.model.topo.n_clusters();
        let same_topology = self.copy_cluster.len() == sim.model.topo.copy_cluster.len() && self.copy_cluster.iter().zip(&sim.model.topo.copy_cluster).all(|(a, b)| *a == b.0);
        if !same_topology || self.u.len() != nc {
            return Err(bad(format!("after replaying {} cuts the clusters differ ({} clusters, the checkpoint has {})", self.cuts.len(), nc, self.u.len())));
        }
        for (name, len) in [("v", self.v.len()), ("f_int", self.f_int.len()), ("f_ext", self.f_ext.len()), ("v_pres", self.v_pres.len()), ("mass", self.mass.len()), ("fix", self.fix.len())] {
            if len != nc {
                return Err(bad(format!("array {name} has {len} entries for {nc} clusters")));
            }
        }
        if self.levels.len() != sim.loads.loads.len() {
            return Err(bad(format!("{} load levels for {} loads", self.levels.len(), sim.loads.loads.len())));
        }
        if self.pos.stage > sim.scene.file.stages.len() {
            return Err(bad(format!("stage {} of {}", self.pos.stage, sim.scene.file.stages.len())));
        }
        let st = &mut sim.state;
        st.u.clone_from(&self.u);
        st.v.clone_from(&self.v);
        st.f_int.clone_from(&self.f_int);
        st.f_ext.clone_from(&self.f_ext);
        st.v_pres.clone_from(&self.v_pres);
        st.mass.clone_from(&self.mass);
        st.fix.clone_from(&self.fix);
        st.time = self.time;
        st.step = self.step;
        sim.dt = self.dt;
        sim.ledger = self.ledger;
        sim.ledger.relocation = self.section("ledger_relocation", 1)?.unwrap_or(0.0);
        sim.last_ratio = self.last_ratio;
        let s = self.stats;
        sim.stats = StepStats { step: s.0, dt: s.1, omega_max: s.2, kinetic: s.3, u_f_int: s.4, u_m_u: s.5 };
        sim.coeffs = DampingCoeffs { viscous: self.coeffs.0, local: self.coeffs.1, ..Default::default() };
        let sb = self.stable;
        sim.stable = crate::solver::StableStep { dt_crit: sb.0, dt_element_bound: sb.1, omega_max: sb.2, iterations: sb.3 as usize, dt_contact: self.stable_dt_contact };
        // Empty in events runs (they make no power iteration).
        if !self.stable_vec.is_empty() && self.stable_vec.len() != nc {
            return Err(bad(format!("stable-step vector has {} entries for {nc} clusters", self.stable_vec.len())));
        }
        sim.stable_vec.clone_from(&self.stable_vec);
        sim.scene.file.solver.damping().set_state(&self.damping_state);
        sim.stages_done.clone_from(&self.stages_done);
        if let Some(cr) = sim.cracking.as_mut() {
            cr.index.clone_from(&self.failure_index);
            cr.index.resize(nc, 0.0);
            cr.n_splits = self.n_splits;
        }
        match (sim.model.stateful, self.section::<Vec<Vec<f64>>>("blocks", 1)?) {
            (true, Some(blocks)) => {
                if blocks.len() != sim.model.blocks.len() {
                    return Err(bad(format!("{} stateful blocks in the checkpoint, {} in the scene", blocks.len(), sim.model.blocks.len())));
                }
                for (i, (b, v)) in sim.model.blocks.iter_mut().zip(&blocks).enumerate() {
                    if !b.load_state(v) {
                        return Err(bad(format!("block {i} (region \"{}\") has {} values of history, the scene's needs {}", b.region(), v.len(), b.state_len())));
                    }
                }
            }
            (false, None) => {}
            (true, None) => return Err(bad("the scene has a material law with history (or large strain) and the checkpoint has no block state".into())),
            (false, Some(_)) => return Err(bad("the checkpoint has block state and the scene's materials keep none".into())),
        }
        match (sim.contact.as_mut(), self.section::<crate::contact::ContactHistory>("contact", 2)?) {
            (Some(c), Some(h)) => {
                c.restore(&sim.model, h);
                // Cohesion per crack face (issue 36): the bonds must come with a law that has
                // it, and such a law needs them (the cuts replayed above made fresh bonds, which
                // would release the fracture energy of faces already open a second time).
                match (c.per_face(), self.section::<Vec<crate::contact::Bond>>("contact_bonds", 1)?) {
                    (true, Some(b)) => c.restore_bonds(&sim.model, b).map_err(bad)?,
                    (false, None) => {}
                    (true, None) => return Err(bad("the scene's contact law has cohesion per crack face and the checkpoint has no cohesive bonds (section contact_bonds; written before session 17?): resume it with the binary that wrote it, or run the scene afresh".into())),
                    (false, Some(_)) => return Err(bad("the checkpoint has cohesive bonds (section contact_bonds) and the scene's contact law has no cohesion".into())),
                }
                if let Some(v) = self.section::<crate::contact::search::VerletState>("contact_verlet", 1)? {
                    let margin = self.section::<crate::contact::search::VerletMargin>("contact_verlet_margin", 1)?;
                    c.restore_verlet(&sim.x0, v, margin);
                }
            }
            (None, None) => {}
            (Some(_), None) => return Err(bad("the scene has [contact] and the checkpoint has no contact pairs".into())),
            (None, Some(_)) => return Err(bad("the checkpoint has contact pairs and the scene has no [contact]".into())),
        }
        sim.events = self.section::<crate::solver::events::EventsInfo>("events", 1)?;
        if let Some(w) = self.section::<Vec<String>>("warnings", 1)? {
            sim.warnings = w;
        }
        sim.refresh_constant_force();
        Ok(())
    }

    /// The file bytes (header, checksum, payload) for a run of the scene with hash `scene_hash`.
    pub fn encode(&self, scene_hash: u64) -> Result<Vec<u8>> {
        let payload = postcard::to_stdvec(self).map_err(|e| FlemError::Other(format!("checkpoint cannot be encoded: {e}")))?;
        Ok(frame(&payload, scene_hash))
    }

    /// Reads and checks a checkpoint file; the error names the file and the reason.
    pub fn decode(path: &Path, bytes: &[u8], scene_hash: u64) -> Result<Checkpoint> {
        let payload = unframe(path, bytes, scene_hash)?;
        postcard::from_bytes(payload).map_err(|e| FlemError::Checkpoint { path: path.display().to_string(), msg: format!("payload cannot be decoded: {e}") })
    }
}

/// The file layout around a payload (module doc): magic, format version, CRC-32, length, scene
/// hash, FLEM version. Shared by the 2D and the 3D checkpoints (`checkpoint3.rs`), whose scene
/// hashes differ, so that neither reads the other's file.
pub fn frame(payload: &[u8], scene_hash: u64) -> Vec<u8> {
    let ver = crate::VERSION.as_bytes();
    let mut out = Vec::with_capacity(34 + ver.len() + payload.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&[0; 4]);
    out.extend_from_slice(&((10 + ver.len() + payload.len()) as u64).to_le_bytes());
    out.extend_from_slice(&scene_hash.to_le_bytes());
    out.extend_from_slice(&(ver.len() as u16).to_le_bytes());
    out.extend_from_slice(ver);
    out.extend_from_slice(payload);
    let crc = crc32fast::hash(&out[16..]);
    out[12..16].copy_from_slice(&crc.to_le_bytes());
    out
}

/// Checks a checkpoint file's layout (magic, version, length, checksum, FLEM version, scene
/// hash) and returns its payload; the error names the file and the reason.
pub fn unframe<'a>(path: &Path, bytes: &'a [u8], scene_hash: u64) -> Result<&'a [u8]> {
    let refuse = |msg: String| FlemError::Checkpoint { path: path.display().to_string(), msg };
    if bytes.len() < 8 || &bytes[..8] != MAGIC {
        return Err(refuse("not a FLEM checkpoint (bad magic)".into()));
    }
    if bytes.len() < 34 {
        return Err(refuse(format!("truncated ({} bytes)", bytes.len())));
    }
    let u32_at = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().unwrap());
    let u64_at = |i: usize| u64::from_le_bytes(bytes[i..i + 8].try_into().unwrap());
    let fv = u32_at(8);
    if fv != FORMAT_VERSION {
        let hint = if fv < FORMAT_VERSION { "an older FLEM wrote it: resume with that FLEM, or start the run again without --resume" } else { "a newer FLEM wrote it" };
        return Err(refuse(format!("format version {fv}, this program reads version {FORMAT_VERSION} ({hint})")));
    }
    let len = u64_at(16);
    if len != (bytes.len() - 24) as u64 {
        return Err(refuse(format!("truncated or padded: the header announces {} bytes, the file has {}", len + 24, bytes.len())));
    }
    let (stored, actual) = (u32_at(12), crc32fast::hash(&bytes[16..]));
    if stored != actual {
        return Err(refuse(format!("bad checksum (stored {stored:08x}, computed {actual:08x}): the file is corrupt")));
    }
    let n = u16::from_le_bytes([bytes[32], bytes[33]]) as usize;
    let ver = bytes.get(34..34 + n).map(String::from_utf8_lossy).unwrap_or_default();
    if ver != crate::VERSION {
        return Err(refuse(format!("written by FLEM {ver}, this is FLEM {}", crate::VERSION)));
    }
    let h = u64_at(24);
    if h != scene_hash {
        return Err(refuse(format!("written for another scene (scene hash {h:016x}, this scene {scene_hash:016x}); resume with the scene file the run started with")));
    }
    Ok(&bytes[34 + n..])
}

/// The file name of checkpoint number `seq`.
pub fn file_name(seq: u64) -> String {
    format!("checkpoint_{seq:06}.bin")
}

/// The checkpoint files of `dir`, newest (highest sequence number) first.
pub fn list(dir: &Path) -> Result<Vec<(u64, PathBuf)>> {
    let rd = std::fs::read_dir(dir).map_err(|e| FlemError::Output { path: dir.display().to_string(), msg: format!("cannot list checkpoints: {e}") })?;
    let mut v: Vec<(u64, PathBuf)> = rd
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().to_string();
            let seq = name.strip_prefix("checkpoint_")?.strip_suffix(".bin")?.parse().ok()?;
            Some((seq, e.path()))
        })
        .collect();
    v.sort_by(|a, b| b.0.cmp(&a.0));
    Ok(v)
}

/// The newest checkpoint of `dir` that is valid for `sim`'s scene, its path, and one message
/// per newer file refused (naming the file and the reason).
pub fn load_newest(dir: &Path, sim: &Simulation) -> Result<(Checkpoint, PathBuf, Vec<String>)> {
    let hash = scene_hash(sim);
    newest_valid(dir, |path, b| Checkpoint::decode(path, b, hash))
}

/// The newest checkpoint file of `dir` that `decode` accepts (2D and 3D), its path, and one
/// message per newer file refused.
pub fn newest_valid<T>(dir: &Path, decode: impl Fn(&Path, &[u8]) -> Result<T>) -> Result<(T, PathBuf, Vec<String>)> {
    let mut refused = Vec::new();
    for (_, path) in list(dir)? {
        let r = std::fs::read(&path).map_err(|e| FlemError::Checkpoint { path: path.display().to_string(), msg: format!("cannot be read: {e}") }).and_then(|b| decode(&path, &b));
        match r {
            Ok(ck) => return Ok((ck, path, refused)),
            Err(e) => refused.push(format!("{e}; trying the previous one")),
        }
    }
    let why = if refused.is_empty() { String::from("it holds no checkpoint_*.bin file") } else { format!("every checkpoint was refused:\n  {}", refused.join("\n  ")) };
    Err(FlemError::Other(format!("cannot resume from {}: {why}", dir.display())))
}

/// Deletes the checkpoints of `dir` older than the `keep` newest ones with a sequence number
/// up to `newest` (files with a higher number, e.g. a refused one, are left alone: the run
/// overwrites them as it goes).
pub fn prune(dir: &Path, newest: u64, keep: usize) -> Result<()> {
    for (_, path) in list(dir)?.into_iter().filter(|(s, _)| *s <= newest).skip(keep) {
        std::fs::remove_file(&path).map_err(|e| FlemError::Output { path: path.display().to_string(), msg: format!("cannot remove an old checkpoint: {e}") })?;
    }
    Ok(())
}
