//! Checkpoints of a 3D run (issue 38 must-show 3; docs/3d.md "Checkpoints"): the whole state
//! of a [`March3`] and of its stage loop, in the file layout of the 2D checkpoints
//! (`checkpoint.rs`: magic, format version, CRC-32, length, scene hash, FLEM version, then a
//! `postcard` payload), so that a run interrupted between two steps continues bit for bit.
//!
//! What is stored: every per-cluster array of the state verbatim (u, v, f_int, f_ext, f_con,
//! mass, fixity, prescribed velocity), time and step counter, the energy ledger, the step
//! size, the stiffness bound, the last step's statistics (the adaptive damping reads them), the
//! damping plugin's `state()`, the unbalanced ratio, every load's level, the stage loop's
//! position ([`Pos3`]: stage, begun, steps, clusters at its start, stages done), the failure
//! check's cuts in order ((cluster, faces): on restore they are replayed through the same
//! `Topology3::cut` after `March3::from_scene` has cut the pre-separated face sets again, and
//! the copy-to-cluster map is compared with the stored one), and named sections: the output
//! writer's ("output3": snapshot count and the logs' byte length and CRC-32, so that a resume
//! truncates `history.csv` and `splits3.csv` to what they were, `csvlog.rs`) and, with
//! `[contact]`, the contact pairs with their history and the Verlet list's build state
//! ("contact3").
//!
//! The scene hash is FNV-1a of the tag "3D", the scene as parsed (JSON of `Scene3File`, every
//! default filled in) and the mesh's points and cells after validation: a 2D checkpoint is never
//! read as a 3D one or the other way round, and an edited scene or mesh is refused by name.
//! Files are `checkpoint_NNNNNN.bin` as in 2D (`checkpoint::{list, prune, file_name}`).
use std::path::{Path, PathBuf};

use serde::{de::DeserializeOwned, Deserialize, Serialize};

use crate::error::{FlemError, Result};
use crate::output::checkpoint::{fnv1a, frame, newest_valid, put_section, section, unframe, Section};
use crate::plugin::damping::StepStats;
use crate::solver::march3::{March3, Pos3};
use crate::solver::Ledger;

/// The payload of a 3D checkpoint file.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Checkpoint3 {
    pub seq: u64,
    pub pos: Pos3,
    pub step: u64,
    pub time: f64,
    pub dt: f64,
    pub omega_max: f64,
    pub u: Vec<[f64; 3]>,
    pub v: Vec<[f64; 3]>,
    pub f_int: Vec<[f64; 3]>,
    pub f_ext: Vec<[f64; 3]>,
    pub f_con: Vec<[f64; 3]>,
    pub v_pres: Vec<[f64; 3]>,
    pub mass: Vec<f64>,
    pub fix: Vec<u8>,
    pub ledger: Ledger,
    pub levels: Vec<f64>,
    pub ratio: f64,
    /// The last step's statistics (step, dt, omega_max, kinetic, u.f_int, u.M.u).
    pub stats: (u64, f64, f64, f64, f64, f64),
    pub damping_state: Vec<f64>,
    pub cuts: Vec<(u32, Vec<u32>)>,
    pub copy_cluster: Vec<u32>,
    pub sections: Vec<Section>,
}

/// The hash of a 3D scene (as parsed, JSON) and of its body's mesh (module doc).
pub fn scene_hash3(scene_json: &str, m: &March3) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    fnv1a(&mut h, b"3D");
    fnv1a(&mut h, scene_json.as_bytes());
    for p in &m.mesh.points {
        for x in p {
            fnv1a(&mut h, &x.to_le_bytes());
        }
    }
    for c in &m.mesh.cells {
        for &q in c.corners() {
            fnv1a(&mut h, &q.to_le_bytes());
        }
    }
    h
}

impl Checkpoint3 {
    /// The state of `m` at `pos` (nothing in `m` changes).
    pub fn capture(m: &March3, pos: &Pos3) -> Result<Checkpoint3> {
        let st = &m.state;
        let s = &m.stats;
        let mut ck = Checkpoint3 {
            seq: 0,
            pos: pos.clone(),
            step: st.step,
            time: st.time,
            dt: m.dt,
            omega_max: m.omega_max,
            u: st.u.clone(),
            v: st.v.clone(),
            f_int: st.f_int.clone(),
            f_ext: st.f_ext.clone(),
            f_con: st.f_con.clone(),
            v_pres: st.v_pres.clone(),
            mass: st.mass.clone(),
            fix: st.fix.clone(),
            ledger: m.ledger,
            levels: m.loads.iter().map(|l| l.level).collect(),
            ratio: m.ratio,
            stats: (s.step, s.dt, s.omega_max, s.kinetic, s.u_f_int, s.u_m_u),
            damping_state: m.damping.state(),
            cuts: m.cuts.clone(),
            copy_cluster: m.topo.copy_cluster.iter().map(|c| c.0).collect(),
            sections: Vec::new(),
        };
        // Contact (`[contact]`): the open pairs with their history and the Verlet list's build
        // state (`Contact3::restore` rebuilds the same list, rebuilt again at the same steps).
        if let Some(c) = &m.contact {
            ck.put_section("contact3", 1, &(&c.pairs, c.verlet_state()))?;
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

    /// Puts the state into `m`, a body freshly built from the same scene
    /// (`March3::from_scene`): replays the cuts, checks the topology, copies every array.
    pub fn restore(&self, m: &mut March3) -> Result<()> {
        let bad = |msg: String| FlemError::Other(format!("the checkpoint does not fit this scene: {msg}"));
        if m.state.step != 0 || !m.cuts.is_empty() {
            return Err(FlemError::Other("a checkpoint can only be restored into a new body".into()));
        }
        for (c, faces) in &self.cuts {
            m.replay_cut(*c, faces).map_err(|e| bad(e.to_string()))?;
        }
        m.after_cuts();
        if m.topo.copy_cluster.iter().map(|c| c.0).ne(self.copy_cluster.iter().copied()) {
            return Err(bad("the replayed cuts give another topology than the run's".into()));
        }
        let nc = m.topo.n_clusters();
        let lens = [self.u.len(), self.v.len(), self.f_int.len(), self.f_ext.len(), self.f_con.len(), self.v_pres.len(), self.mass.len(), self.fix.len()];
        if lens.iter().any(|&l| l != nc) {
            return Err(bad(format!("arrays of {lens:?} entries for {nc} clusters")));
        }
        if self.levels.len() != m.loads.len() {
            return Err(bad(format!("{} load levels for {} loads", self.levels.len(), m.loads.len())));
        }
        for (l, &v) in m.loads.iter_mut().zip(&self.levels) {
            l.level = v;
        }
        m.rebuild_forces();
        let st = &mut m.state;
        st.u.clone_from(&self.u);
        st.v.clone_from(&self.v);
        st.f_int.clone_from(&self.f_int);
        st.f_ext.clone_from(&self.f_ext);
        st.f_con.clone_from(&self.f_con);
        st.v_pres.clone_from(&self.v_pres);
        st.mass.clone_from(&self.mass);
        st.fix.clone_from(&self.fix);
        st.time = self.time;
        st.step = self.step;
        m.dt = self.dt;
        m.omega_max = self.omega_max;
        m.ledger = self.ledger;
        m.ratio = self.ratio;
        let s = self.stats;
        m.stats = StepStats { step: s.0, dt: s.1, omega_max: s.2, kinetic: s.3, u_f_int: s.4, u_m_u: s.5 };
        m.damping.set_state(&self.damping_state);
        let contact = self.section::<(Vec<crate::contact::contact3::Pair3>, crate::contact::contact3::VerletState3)>("contact3", 1)?;
        match (m.contact.as_mut(), contact) {
            (Some(c), Some((pairs, verlet))) => c.restore(&m.mesh, &m.topo, pairs, verlet),
            (None, None) => {}
            (Some(_), None) => return Err(bad("the scene has [contact] and the checkpoint no contact state".into())),
            (None, Some(_)) => return Err(bad("the checkpoint has contact pairs and the scene has no [contact]".into())),
        }
        Ok(())
    }

    /// The file bytes.
    pub fn encode(&self, scene_hash: u64) -> Result<Vec<u8>> {
        let payload = postcard::to_stdvec(self).map_err(|e| FlemError::Other(format!("checkpoint cannot be encoded: {e}")))?;
        Ok(frame(&payload, scene_hash))
    }

    /// Reads and checks a checkpoint file; the error names the file and the reason.
    pub fn decode(path: &Path, bytes: &[u8], scene_hash: u64) -> Result<Checkpoint3> {
        let payload = unframe(path, bytes, scene_hash)?;
        postcard::from_bytes(payload).map_err(|e| FlemError::Checkpoint { path: path.display().to_string(), msg: format!("payload cannot be decoded: {e}") })
    }
}

/// A checkpoint file read for inspection, whatever scene it was written for (every other
/// check of `Checkpoint3::decode` applies).
pub fn peek3(path: &Path) -> Result<Checkpoint3> {
    let b = std::fs::read(path).map_err(|e| FlemError::Checkpoint { path: path.display().to_string(), msg: format!("cannot be read: {e}") })?;
    let hash = b.get(24..32).map_or(0, |h| u64::from_le_bytes(h.try_into().unwrap()));
    Checkpoint3::decode(path, &b, hash)
}

/// The newest checkpoint of `dir` valid for the scene hash, its path, and one message per newer
/// file refused (naming the file and the reason).
pub fn load_newest3(dir: &Path, hash: u64) -> Result<(Checkpoint3, PathBuf, Vec<String>)> {
    newest_valid(dir, |path, b| Checkpoint3::decode(path, b, hash))
}
