//! Runs that lose nothing (issue 10): checkpoints, resume, interruption, atomic results.
//!
//! Reference for every comparison: the same scene run uninterrupted; tolerance: none (bit for
//! bit: displacements compared by `to_bits`, history/split log/PVD/VTU compared byte for byte).
//! Contact pairs (issue 4) go into the checkpoint section "contact" (core/src/checkpoint.rs);
//! `interrupted_with_splits_and_contacts_is_bit_identical` interrupts while pairs exist.
//! The CSV logs are appended row by row and a checkpoint records their length and CRC-32
//! (core/src/output/csvlog.rs): `checkpoint_records_csv_lengths_not_contents`,
//! `resume_checks_and_truncates_the_csv_logs`.
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use flem_core::mesh::topology::SplitRecord;
use flem_core::output::checkpoint::{self, Checkpoint};
use flem_core::output::{OutputWriter, WriterState, OUTPUT_SECTION, OUTPUT_SECTION_VERSION};
use flem_core::solver::{Observer, Progress, Simulation, StagePos};
use flem_core::FlemError;

use crate::common::{root, scene};

pub(crate) fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("flem-ckpt-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn notch_path() -> PathBuf {
    root().join("configs/verification/notched_crack.toml")
}

/// The tension specimen of configs/verification/tension_crack.toml with frequent history rows
/// and step-count checkpoints.
fn tension_text() -> String {
    std::fs::read_to_string(root().join("configs/verification/tension_crack.toml")).unwrap()
        + "\n[output]\nhistory_every = 37\ncheckpoint_every = 300\nprobes = [{ name = \"top\", at = [2.0, 4.0] }]\n"
}

/// The output writer, told to stop once the step counter reaches `at` (what SIGINT does
/// through the writer's flag), and optionally doing something to the folder at a step.
struct StopAt<F: FnMut(&Simulation)> {
    w: OutputWriter,
    at: u64,
    hook: F,
}

impl<F: FnMut(&Simulation)> Observer for StopAt<F> {
    fn history(&mut self, sim: &Simulation, stage: usize) -> flem_core::Result<()> {
        (self.hook)(sim);
        self.w.history(sim, stage)
    }
    fn snapshot(&mut self, sim: &Simulation, stage: usize, label: &str) -> flem_core::Result<()> {
        self.w.snapshot(sim, stage, label)
    }
    fn splits(&mut self, sim: &Simulation, rec: &SplitRecord, ev: &[flem_core::cracking::SplitEvent]) -> flem_core::Result<()> {
        self.w.splits(sim, rec, ev)
    }
    fn progress(&mut self, p: &Progress) {
        self.w.progress(p)
    }
    fn stage_end(&mut self, sim: &Simulation, stage: usize) -> flem_core::Result<()> {
        // The writer's tip tracker records at stage ends (crack_tips.csv).
        self.w.stage_end(sim, stage)
    }
    fn should_stop(&mut self, sim: &Simulation) -> bool {
        sim.state.step >= self.at
    }
    fn checkpoint_due(&mut self, sim: &Simulation) -> bool {
        self.w.checkpoint_due(sim)
    }
    fn checkpoint(&mut self, sim: &Simulation, pos: &StagePos) -> flem_core::Result<()> {
        self.w.checkpoint(sim, pos)
    }
}

fn bits(v: &[[f64; 2]]) -> Vec<[u64; 2]> {
    v.iter().map(|a| [a[0].to_bits(), a[1].to_bits()]).collect()
}

/// Result files of a folder (no checkpoints, no summary: its wall time differs), by name.
fn results(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| (n.ends_with(".csv") || n.ends_with(".pvd") || n.ends_with(".vtu")) && !n.contains("interrupted"))
        .map(|n| (n.clone(), std::fs::read(dir.join(&n)).unwrap()))
        .collect();
    v.sort();
    v
}

fn assert_same_results(reference: &Path, other: &Path, what: &str) {
    let (a, b) = (results(reference), results(other));
    let names = |v: &[(String, Vec<u8>)]| v.iter().map(|x| x.0.clone()).collect::<Vec<_>>();
    assert_eq!(names(&a), names(&b), "{what}: not the same result files");
    for ((n, x), (_, y)) in a.iter().zip(&b) {
        assert!(x == y, "{what}: {n} differs from the uninterrupted run");
    }
}

/// A run stopped after step `at` (checkpoint + snapshot), then resumed from its folder by a
/// new `Simulation`, ends bit-identical to `reference` (final u and v, every result file).
pub(crate) fn interrupt_and_resume(text: &str, at: u64, reference: &Simulation, ref_dir: &Path, tag: &str) {
    interrupt_and_resume_checked(text, at, reference, ref_dir, tag, |_| {});
}

/// [`interrupt_and_resume`], calling `check` on the interrupted simulation (its state is the
/// checkpoint's).
fn interrupt_and_resume_checked(text: &str, at: u64, reference: &Simulation, ref_dir: &Path, tag: &str, check: impl Fn(&Simulation)) {
    let dir = tmp(tag);
    let mut sim = Simulation::new(scene(text)).unwrap();
    let w = OutputWriter::new(&dir, &sim).unwrap();
    let mut obs = StopAt { w, at, hook: |_: &Simulation| {} };
    match sim.run(&mut obs) {
        Err(FlemError::Interrupted { step, .. }) => assert_eq!(step, at, "{tag}: stopped at the wrong step"),
        other => panic!("{tag}: expected an interruption at step {at}, got {other:?}"),
    }
    check(&sim);
    assert!(std::fs::read_dir(&dir).unwrap().flatten().any(|e| e.file_name().to_string_lossy().contains("interrupted")), "{tag}: no final snapshot");
    let mut sim = Simulation::new(scene(text)).unwrap();
    let (ck, path, refused) = checkpoint::load_newest(&dir, &sim).unwrap();
    assert!(refused.is_empty(), "{refused:?}");
    assert_eq!(ck.step, at, "{tag}: the newest checkpoint is not the interruption's");
    ck.restore(&mut sim).unwrap();
    let mut w = OutputWriter::new(&dir, &sim).unwrap();
    w.resume(&ck, &path).unwrap();
    sim.run_from(ck.pos.clone(), &mut w).unwrap();
    assert_eq!(sim.state.step, reference.state.step, "{tag}: step count");
    assert!(bits(&sim.state.u) == bits(&reference.state.u), "{tag}: final displacements differ");
    assert!(bits(&sim.state.v) == bits(&reference.state.v), "{tag}: final velocities differ");
    assert_eq!(sim.model.topo.n_clusters(), reference.model.topo.n_clusters(), "{tag}: clusters");
    assert_eq!(sim.ledger.residual().to_bits(), reference.ledger.residual().to_bits(), "{tag}: energy ledger");
    if let (Some(a), Some(b)) = (&sim.contact, &reference.contact) {
        // The Verlet list is rebuilt from the checkpoint's build state, not afresh: the same
        // number of rebuilds (hence the same candidate sets) as the uninterrupted run.
        assert_eq!(a.rebuilds, b.rebuilds, "{tag}: Verlet list rebuilds");
        assert!(a.history == b.history, "{tag}: contact pairs and their history");
    }
    let steps = |s: &Simulation| s.stages_done.iter().map(|r| (r.steps, r.converged, r.final_ratio.to_bits(), r.splits)).collect::<Vec<_>>();
    assert_eq!(steps(&sim), steps(reference), "{tag}: stage results");
    assert_same_results(ref_dir, &dir, tag);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Interrupted at arbitrary steps (mid-stage, right after a split, on the last step of a
/// stage) and resumed: bit-identical to the uninterrupted run, on the tension specimen (splits
/// in stage 2) and on the notched plate (a crack from a pre-separated notch).
#[test]
fn interrupted_then_resumed_is_bit_identical() {
    for (name, text) in [("tension", tension_text()), ("notch", std::fs::read_to_string(notch_path()).unwrap())] {
        let ref_dir = tmp(&format!("{name}-ref"));
        let mut reference = Simulation::new(scene(&text)).unwrap();
        let mut w = OutputWriter::new(&ref_dir, &reference).unwrap();
        reference.run(&mut w).unwrap();
        let total = reference.state.step;
        let splits_log = std::fs::read_to_string(ref_dir.join("splits.csv")).unwrap();
        let first_split: u64 = splits_log.lines().nth(1).unwrap_or_else(|| panic!("{name}: no split")).split(',').nth(1).unwrap().parse().unwrap();
        let end_stage1 = reference.stages_done[0].steps;
        let mut stops = vec![total / 7 + 3, end_stage1, first_split, first_split + 1, (first_split + total) / 2 + 1, total - 1];
        stops.sort_unstable();
        stops.dedup();
        for at in stops {
            interrupt_and_resume(&text, at, &reference, &ref_dir, &format!("{name}-{at}"));
        }
        let _ = std::fs::remove_dir_all(&ref_dir);
    }
}

/// The notched plate of configs/verification/notched_crack.toml with cohesive contact on the
/// crack faces: the notch faces are contact surfaces and every split creates a cohesive pair
/// (at the new crack tip) that carries tension while the crack opens, so pairs and splits
/// coexist; a third stage at the same load lets the crack grow four edges (the contact term
/// shortens the stable step, so the crack stage alone ends after the first split).
fn notch_contact_text() -> String {
    std::fs::read_to_string(notch_path()).unwrap()
        + "\n[contact]\nlaw = { type = \"cohesive\", normal_stiffness = 2000.0, shear_stiffness = 800.0, tensile_strength = 0.5, fracture_energy = 0.005, friction = 0.5 }\n"
        + "\n[[stage]]\nname = \"more\"\nlevels = { pull = 0.6 }\nmax_steps = 30000\n"
}

/// Interrupted at several steps while contact pairs exist (right after a split, mid-crack,
/// at arbitrary steps between history rows) and resumed: final u, v, energy ledger, stage
/// results, split log and every result file are bit-identical to the uninterrupted run.
/// Reference: the uninterrupted run; tolerance: none (bit for bit).
#[test]
fn interrupted_with_splits_and_contacts_is_bit_identical() {
    let text = notch_contact_text();
    let ref_dir = tmp("contact-ref");
    let mut reference = Simulation::new(scene(&text)).unwrap();
    // Steps (at history rows) where pairs exist, seen from the uninterrupted run.
    let with_pairs = std::cell::RefCell::new(Vec::new());
    let w = OutputWriter::new(&ref_dir, &reference).unwrap();
    let mut obs = StopAt {
        w,
        at: u64::MAX,
        hook: |s: &Simulation| {
            // Pairs and cohesive bonds (cohesion per face end, issue 36 session 17).
            let c = s.contact.as_ref().unwrap();
            let n = c.history.pairs.len() + c.bonds.len();
            if n > 0 {
                with_pairs.borrow_mut().push((s.state.step, n));
            }
        },
    };
    reference.run(&mut obs).unwrap();
    let total = reference.state.step;
    let with_pairs = with_pairs.into_inner();
    // The cohesive law updates the Verlet list locally at a split (session 18): the resumes
    // below must go through such lists, whose full rebuild at the saved margin must give the
    // same pairs for the runs to stay bit-identical.
    let patches = reference.contact.as_ref().unwrap().patches;
    assert!(patches > 0, "no local Verlet update in the reference run");
    let splits_log = std::fs::read_to_string(ref_dir.join("splits.csv")).unwrap();
    let split_steps: Vec<u64> = splits_log.lines().skip(1).map(|l| l.split(',').nth(1).unwrap().parse().unwrap()).collect();
    eprintln!("contact scene: {total} steps, {} splits at {:?}..., pairs at history rows: {:?}", split_steps.len(), &split_steps[..split_steps.len().min(5)], with_pairs);
    assert!(split_steps.len() >= 3, "the crack must grow: {split_steps:?}");
    assert!(with_pairs.len() >= 3, "pairs must exist through the crack growth: {with_pairs:?}");
    // Right after the second split, an arbitrary step between history rows in the middle of
    // the pair-carrying period, and the step after the last row with pairs.
    let mid = with_pairs[with_pairs.len() / 2].0;
    let mut stops = vec![split_steps[1] + 1, mid + 17, with_pairs[with_pairs.len() - 1].0 + 1];
    stops.sort_unstable();
    stops.dedup();
    for at in stops {
        let tag = format!("contact-{at}");
        interrupt_and_resume_checked(&text, at, &reference, &ref_dir, &tag, |s| {
            let c = s.contact.as_ref().unwrap();
            assert!(!c.history.pairs.is_empty() || !c.bonds.is_empty(), "{tag}: no contact pair or cohesive bond at the interruption");
            assert!(s.model.topo.n_clusters() > Simulation::new(scene(&text)).unwrap().model.topo.n_clusters(), "{tag}: no split before the interruption");
        });
    }
    let _ = std::fs::remove_dir_all(&ref_dir);
}

/// Every single-byte flip anywhere in a checkpoint is refused (magic, version, length,
/// checksum, scene hash, FLEM version, payload) with a message naming the file; `load_newest`
/// then uses the previous checkpoint. A checkpoint of another scene is refused as such.
#[test]
fn corrupt_or_foreign_checkpoint_is_refused() {
    let dir = tmp("flip");
    let text = tension_text();
    let mut sim = Simulation::new(scene(&text)).unwrap();
    let mut w = OutputWriter::new(&dir, &sim).unwrap();
    sim.run(&mut w).unwrap();
    let files = checkpoint::list(&dir).unwrap();
    assert_eq!(files.len(), 2, "checkpoint_keep = 2 keeps two files: {files:?}");
    let (newest, previous) = (files[0].1.clone(), files[1].1.clone());
    let fresh = Simulation::new(scene(&text)).unwrap();
    let hash = checkpoint::scene_hash(&fresh);
    let good = std::fs::read(&newest).unwrap();
    Checkpoint::decode(&newest, &good, hash).unwrap();
    for i in 0..good.len() {
        let mut b = good.clone();
        b[i] ^= 0x10;
        let e = Checkpoint::decode(&newest, &b, hash).err().unwrap_or_else(|| panic!("a flipped byte at {i} of {} was not detected", good.len()));
        assert!(e.to_string().contains(&newest.display().to_string()), "{e}");
    }
    // A checkpoint of format version 1 (it carried the CSV contents): refused as older.
    let mut b = good.clone();
    b[8..12].copy_from_slice(&1u32.to_le_bytes());
    let e = Checkpoint::decode(&newest, &b, hash).unwrap_err().to_string();
    assert!(e.contains(&newest.display().to_string()) && e.contains(&format!("format version 1, this program reads version {}", checkpoint::FORMAT_VERSION)) && e.contains("older FLEM"), "{e}");
    // Truncated (a half-written file that did not go through atomic_write).
    let e = Checkpoint::decode(&newest, &good[..good.len() / 2], hash).unwrap_err().to_string();
    assert!(e.contains("truncated"), "{e}");
    // Flip one payload byte on disk: the previous checkpoint is used, the message says why.
    let mut b = good.clone();
    let mid = b.len() / 2;
    b[mid] ^= 1;
    std::fs::write(&newest, &b).unwrap();
    let (ck, path, refused) = checkpoint::load_newest(&dir, &fresh).unwrap();
    assert_eq!(path, previous);
    assert!(ck.seq < files[0].0);
    assert_eq!(refused.len(), 1);
    assert!(refused[0].contains(&newest.display().to_string()) && refused[0].contains("checksum"), "{}", refused[0]);
    // Another scene (another tolerance): every file refused, naming the reason.
    let other = Simulation::new(scene(&text.replace("tolerance = 1e-7", "tolerance = 2e-7"))).unwrap();
    let e = checkpoint::load_newest(&dir, &other).err().unwrap().to_string();
    assert!(e.contains("another scene") && e.contains(&previous.display().to_string()), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Replaces this process's open descriptor of `path` (the output writer's append handle) by
/// one on /dev/full, so that every later write to it fails with ENOSPC as on a full disk; the
/// file on disk keeps what was written. Returns whether such a descriptor was found.
fn fill_disk_under(path: &Path) -> bool {
    let target = std::fs::canonicalize(path).unwrap();
    for e in std::fs::read_dir("/proc/self/fd").unwrap().flatten() {
        let Ok(fd) = e.file_name().to_string_lossy().parse::<i32>() else { continue };
        if std::fs::read_link(e.path()).is_ok_and(|l| l == target) {
            let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
            // SAFETY: dup2 onto a descriptor this process owns (the writer's File, which stays
            // open, now on /dev/full, until it is dropped); `full` is closed after.
            assert!(unsafe { libc::dup2(full.as_raw_fd(), fd) } >= 0, "dup2 failed");
            return true;
        }
    }
    false
}

/// Resumes the run of `text` in `dir` from its newest checkpoint to the end (writing into `out`).
fn resume_to_end(text: &str, dir: &Path, out: &Path) -> Simulation {
    let mut sim = Simulation::new(scene(text)).unwrap();
    let (ck, path, refused) = checkpoint::load_newest(dir, &sim).unwrap();
    assert!(refused.is_empty(), "{refused:?}");
    ck.restore(&mut sim).unwrap();
    let mut w = OutputWriter::new(out, &sim).unwrap();
    w.resume(&ck, &path).unwrap();
    sim.run_from(ck.pos.clone(), &mut w).unwrap();
    sim
}

/// A write error in the middle of a run (here: the disk fills up under history.csv, whose
/// append handle is pointed at /dev/full) stops the run with a message naming the file; the
/// last checkpoint stays whole, and resuming from it once there is room again gives the
/// results of an uninterrupted run (reference; tolerance: none, byte for byte).
#[test]
fn write_error_stops_the_run_and_keeps_the_last_checkpoint() {
    let (dir, ref_dir) = (tmp("werr"), tmp("werr-ref"));
    let text = tension_text();
    let mut reference = Simulation::new(scene(&text)).unwrap();
    let mut w = OutputWriter::new(&ref_dir, &reference).unwrap();
    reference.run(&mut w).unwrap();
    let mut sim = Simulation::new(scene(&text)).unwrap();
    let w = OutputWriter::new(&dir, &sim).unwrap();
    let (d2, mut full) = (dir.clone(), false);
    let mut obs = StopAt {
        w,
        at: u64::MAX,
        hook: |s: &Simulation| {
            if s.state.step >= 700 && !full {
                full = fill_disk_under(&d2.join("history.csv"));
                assert!(full, "history.csv is not held open by the writer");
            }
        },
    };
    let e = sim.run(&mut obs).unwrap_err().to_string();
    assert!(e.contains("history.csv") && e.contains("cannot write") && e.contains("No space left"), "{e}");
    drop(obs);
    let fresh = Simulation::new(scene(&text)).unwrap();
    let (ck, _, refused) = checkpoint::load_newest(&dir, &fresh).unwrap();
    assert!(refused.is_empty() && ck.step >= 600, "{refused:?} step {}", ck.step);
    assert!(std::fs::read_dir(&dir).unwrap().flatten().all(|e| !e.file_name().to_string_lossy().contains(".tmp")), "a temporary file was left");
    let hist = std::fs::read_to_string(dir.join("history.csv")).unwrap();
    assert!(hist.ends_with('\n'), "history.csv was left with a cut row");
    resume_to_end(&text, &dir, &dir);
    assert_same_results(&ref_dir, &dir, "disk full + resume");
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&ref_dir);
}

/// The output section of a checkpoint file.
fn writer_state(path: &Path, text: &str) -> WriterState {
    let hash = checkpoint::scene_hash(&Simulation::new(scene(text)).unwrap());
    let ck = Checkpoint::decode(path, &std::fs::read(path).unwrap(), hash).unwrap();
    ck.section::<WriterState>(OUTPUT_SECTION, OUTPUT_SECTION_VERSION).unwrap().expect("no output section")
}

/// A checkpoint records the byte length of each CSV log, not its contents: at the end of a run
/// the last checkpoint's lengths are the files' lengths, and its size is the same (within a
/// few bytes of varint lengths) with a history row every step as with a few rows, while
/// history.csv grows by orders of magnitude. Reference: the files on disk.
#[test]
fn checkpoint_records_csv_lengths_not_contents() {
    let mut sizes = Vec::new();
    for every in [1000, 1] {
        let dir = tmp(&format!("len-{every}"));
        let text = tension_text().replace("history_every = 37", &format!("history_every = {every}"));
        let mut sim = Simulation::new(scene(&text)).unwrap();
        let mut w = OutputWriter::new(&dir, &sim).unwrap();
        sim.run(&mut w).unwrap();
        let newest = checkpoint::list(&dir).unwrap()[0].1.clone();
        let st = writer_state(&newest, &text);
        for (name, mark) in [("history.csv", st.history), ("splits.csv", st.splits)] {
            let len = std::fs::metadata(dir.join(name)).unwrap().len();
            assert_eq!(mark.map(|m| m.len), Some(len), "history_every = {every}: {name} length in the last checkpoint");
        }
        let ck_size = std::fs::metadata(&newest).unwrap().len();
        let hist = std::fs::metadata(dir.join("history.csv")).unwrap().len();
        eprintln!("history_every = {every}: {} steps, history.csv {hist} bytes, checkpoint {ck_size} bytes", sim.state.step);
        sizes.push((hist, ck_size));
        let _ = std::fs::remove_dir_all(&dir);
    }
    assert!(sizes[1].0 > 50 * sizes[0].0, "{sizes:?}");
    assert!(sizes[1].1.abs_diff(sizes[0].1) <= 16, "the checkpoint grows with the history: {sizes:?}");
}

/// `--resume` checks each CSV log against the checkpoint: shorter than recorded, or a changed
/// byte in the recorded prefix, or splits.csv with a field cut out of a recorded row, is refused
/// with the file and the checkpoint named; rows written after the checkpoint and a row cut by a
/// kill are truncated away, and the run then ends byte-identical to an uninterrupted one
/// (reference; tolerance: none), also when resumed into another folder (the prefix is copied).
#[test]
fn resume_checks_and_truncates_the_csv_logs() {
    let text = tension_text();
    let (ref_dir, dir, other) = (tmp("trunc-ref"), tmp("trunc"), tmp("trunc-other"));
    let mut reference = Simulation::new(scene(&text)).unwrap();
    let mut w = OutputWriter::new(&ref_dir, &reference).unwrap();
    reference.run(&mut w).unwrap();
    let at = reference.state.step / 2 + 5;
    let mut sim = Simulation::new(scene(&text)).unwrap();
    let w = OutputWriter::new(&dir, &sim).unwrap();
    let mut obs = StopAt { w, at, hook: |_: &Simulation| {} };
    assert!(matches!(sim.run(&mut obs), Err(FlemError::Interrupted { .. })));
    drop(obs);
    let hist = dir.join("history.csv");
    let good = std::fs::read(&hist).unwrap();
    let (ck_path, mark) = {
        let p = checkpoint::list(&dir).unwrap()[0].1.clone();
        let m = writer_state(&p, &text).history.unwrap();
        (p, m)
    };
    assert_eq!(mark.len, good.len() as u64, "the interruption's checkpoint is taken after the last row");
    let try_resume = || -> flem_core::Result<()> {
        let mut sim = Simulation::new(scene(&text)).unwrap();
        let (ck, path, _) = checkpoint::load_newest(&dir, &sim).unwrap();
        ck.restore(&mut sim).unwrap();
        OutputWriter::new(&dir, &sim).unwrap().resume(&ck, &path)
    };
    let named = |e: &str| e.contains(&hist.display().to_string()) && e.contains(&ck_path.display().to_string()) && e.contains("without --resume");
    // Shorter than recorded.
    std::fs::write(&hist, &good[..good.len() - 1]).unwrap();
    let e = try_resume().unwrap_err().to_string();
    assert!(named(&e) && e.contains("fewer than"), "{e}");
    // One byte of the prefix changed (a digit of a middle row).
    let mut b = good.clone();
    let i = good.len() / 2 + good[good.len() / 2..].iter().position(|c| c.is_ascii_digit() && *c != b'7').unwrap();
    b[i] = b'7';
    std::fs::write(&hist, &b).unwrap();
    let e = try_resume().unwrap_err().to_string();
    assert!(named(&e) && e.contains("changed since the checkpoint"), "{e}");
    // Missing.
    std::fs::remove_file(&hist).unwrap();
    let e = try_resume().unwrap_err().to_string();
    assert!(named(&e) && e.contains("cannot be read"), "{e}");
    std::fs::write(&hist, &good).unwrap();
    // splits.csv (the run has split before the checkpoint): a field of a recorded row cut out.
    let sp = dir.join("splits.csv");
    let sgood = std::fs::read(&sp).unwrap();
    let smark = writer_state(&ck_path, &text).splits.expect("the run splits before the interruption");
    assert_eq!(smark.len, sgood.len() as u64);
    let text_sp = String::from_utf8(sgood.clone()).unwrap();
    let cut = text_sp.lines().nth(1).unwrap().rsplit_once(',').unwrap().0.to_string();
    std::fs::write(&sp, text_sp.replacen(text_sp.lines().nth(1).unwrap(), &cut, 1)).unwrap();
    let e = try_resume().unwrap_err().to_string();
    assert!(e.contains(&sp.display().to_string()) && e.contains(&ck_path.display().to_string()) && (e.contains("changed since the checkpoint") || e.contains("fewer than")), "{e}");
    std::fs::write(&sp, &sgood).unwrap();
    // Whole rows after the checkpoint and a row cut by a kill: truncated away.
    let mut b = good.clone();
    b.extend_from_slice(b"999999,1e0,1,2e0\n12345,6.7e-");
    std::fs::write(&hist, &b).unwrap();
    resume_to_end(&text, &dir, &other);
    resume_to_end(&text, &dir, &dir);
    assert_same_results(&ref_dir, &dir, "resumed after extra and cut rows");
    for name in ["history.csv", "splits.csv"] {
        assert!(std::fs::read(ref_dir.join(name)).unwrap() == std::fs::read(other.join(name)).unwrap(), "resumed into another folder: {name} differs");
    }
    for d in [dir, ref_dir, other] {
        let _ = std::fs::remove_dir_all(&d);
    }
}

/// A folder we cannot write into: chmod 555 (or, when the tests run as root, who writes
/// anyway, /sys/kernel, a read-only sysfs folder).
fn read_only_dir() -> PathBuf {
    use std::os::unix::fs::PermissionsExt;
    let d = tmp("ro");
    std::fs::create_dir_all(&d).unwrap();
    std::fs::set_permissions(&d, std::fs::Permissions::from_mode(0o555)).unwrap();
    if std::fs::write(d.join("probe"), b"x").is_err() {
        return d;
    }
    let _ = std::fs::remove_file(d.join("probe"));
    let sys = PathBuf::from("/sys/kernel");
    assert!(sys.is_dir() && std::fs::write(sys.join(".flem-probe"), b"x").is_err(), "no read-only folder to test with");
    sys
}

/// A read-only output folder is refused before any step: `flem run` exits 1 with the folder
/// named, before the model is even built (no "dt =" line), and no result file appears.
#[test]
fn read_only_output_dir_fails_before_any_step() {
    let ro = read_only_dir();
    let out = Command::new(crate::common::flem_exe()).args(["run", notch_path().to_str().unwrap(), "--quiet", "--out", ro.to_str().unwrap()]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains(&ro.display().to_string()) && err.contains("not writable"), "{err}");
    assert!(!err.contains("dt ="), "a step was prepared: {err}");
    assert!(!ro.join("history.csv").exists() && !ro.join("scene.resolved.toml").exists());
    // The library refuses it too (OutputWriter::new probes the folder).
    let sim = Simulation::new(scene(&tension_text())).unwrap();
    let e = OutputWriter::new(&ro, &sim).err().unwrap().to_string();
    assert!(e.contains("not writable"), "{e}");
}

fn wait_for(pred: impl Fn() -> bool, what: &str) {
    let t = Instant::now();
    while !pred() {
        assert!(t.elapsed() < Duration::from_secs(60), "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn flem_run(args: &[&str]) -> std::process::Output {
    Command::new(crate::common::flem_exe()).args(args).stdin(Stdio::null()).output().unwrap()
}

/// `flem run` stopped by SIGINT once its first checkpoint is on disk: it exits 130 with the
/// exact resume command; running that command finishes the run with results identical to an
/// uninterrupted `flem run` (history, split log, snapshots, PVD), on the notched plate with splits.
#[test]
fn sigint_then_resume_command_gives_the_same_results() {
    let scene_path = notch_path();
    let sp = scene_path.to_str().unwrap();
    let (ref_dir, dir) = (tmp("sig-ref"), tmp("sig"));
    let r = flem_run(&["run", sp, "--quiet", "--out", ref_dir.to_str().unwrap()]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let child = Command::new(crate::common::flem_exe()).args(["run", sp, "--quiet", "--out", dir.to_str().unwrap()]).stderr(Stdio::piped()).stdout(Stdio::null()).spawn().unwrap();
    wait_for(|| dir.join(checkpoint::file_name(1)).exists(), "the first checkpoint");
    // SAFETY: kill(2) on our own child's pid.
    assert_eq!(unsafe { libc::kill(child.id() as i32, libc::SIGINT) }, 0);
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{err}");
    let cmd = format!("flem run {sp} --resume {}", dir.display());
    assert!(err.contains("interrupted after step") && err.contains(&cmd), "{err}");
    let line = err.lines().find(|l| l.starts_with("resume with: ")).unwrap();
    let args: Vec<&str> = line.trim_start_matches("resume with: flem ").split(' ').collect();
    let r = flem_run(&[&args[..], &["--quiet"]].concat());
    let rerr = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success() && rerr.contains("resuming from"), "{rerr}");
    assert_same_results(&ref_dir, &dir, "SIGINT + resume");
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&ref_dir);
}

/// Every result file left in `dir` is whole: VTU parse (vtkio), JSON parses, the PVD is closed
/// and names existing files, every checkpoint decodes with a good checksum. The CSV logs are
/// appended in place: each is a byte prefix of the uninterrupted run's (`ref_dir`) with its
/// header, and its whole lines have the header's field count; a last row cut by SIGKILL (no
/// newline; readers skip it, a resume truncates it away) is counted in `cut`, and refused
/// when `complete` (the run has finished).
fn check_all_whole(dir: &Path, ref_dir: &Path, hash: u64, round: usize, complete: bool, cut: &mut usize) -> usize {
    let mut n = 0;
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        let p = e.path();
        if name.starts_with('.') {
            continue; // a temporary file of atomic_write: never a result
        }
        let bytes = std::fs::read(&p).unwrap();
        let ctx = format!("round {round}: {name} ({} bytes)", bytes.len());
        if name.ends_with(".vtu") {
            vtkio::Vtk::import(&p).unwrap_or_else(|e| panic!("{ctx}: {e}"));
        } else if name.ends_with(".csv") {
            let reference = std::fs::read(ref_dir.join(&name)).unwrap_or_default();
            assert!(reference.starts_with(&bytes), "{ctx}: not a prefix of the uninterrupted run's {name}");
            let t = String::from_utf8(bytes).unwrap();
            let whole = &t[..t.rfind('\n').map_or(0, |i| i + 1)];
            assert!(!whole.is_empty(), "{ctx}: no header");
            if whole.len() < t.len() {
                assert!(!complete, "{ctx}: truncated");
                *cut += 1;
            }
            let mut lines = whole.lines();
            let k = lines.next().unwrap().split(',').count();
            for l in lines {
                assert_eq!(l.split(',').count(), k, "{ctx}: a short row: {l}");
            }
        } else if name.ends_with(".json") {
            serde_json::from_slice::<serde_json::Value>(&bytes).unwrap_or_else(|e| panic!("{ctx}: {e}"));
        } else if name.ends_with(".pvd") {
            let t = String::from_utf8(bytes).unwrap();
            assert!(t.ends_with("</VTKFile>\n"), "{ctx}: truncated");
            for f in t.split("file=\"").skip(1) {
                let f = &f[..f.find('"').unwrap()];
                assert!(dir.join(f).exists(), "{ctx}: names missing {f}");
            }
        } else if name.ends_with(".bin") {
            Checkpoint::decode(&p, &bytes, hash).unwrap_or_else(|e| panic!("{ctx}: {e}"));
        } else if name.ends_with(".toml") {
            toml::from_str::<toml::Value>(std::str::from_utf8(&bytes).unwrap()).unwrap_or_else(|e| panic!("{ctx}: {e}"));
        } else {
            panic!("{ctx}: unexpected file");
        }
        n += 1;
    }
    n
}

/// A child `flem run` killed with SIGKILL at random moments, again and again (resuming from
/// its checkpoints in between): after every kill, every file in the folder is whole (old or new
/// version, never truncated; the CSV logs a prefix of the final ones, see [`check_all_whole`]),
/// and the run finally completes with results identical to an
/// uninterrupted run. Output is made very frequent (a history row every 10 steps, a snapshot
/// every 500, a checkpoint every 250) so that kills land during writes.
#[test]
fn sigkill_during_output_leaves_every_file_whole() {
    let text = std::fs::read_to_string(notch_path()).unwrap().replace("history_every = 50\ncheckpoint_every = 1000", "history_every = 10\nsnapshot_every = 500\ncheckpoint_every = 250");
    assert!(text.contains("history_every = 10"));
    let (ref_dir, dir) = (tmp("kill-ref"), tmp("kill"));
    std::fs::create_dir_all(&dir).unwrap();
    let sp = dir.with_extension("toml");
    std::fs::write(&sp, &text).unwrap();
    let sps = sp.to_str().unwrap();
    let t_ref = std::time::Instant::now();
    let r = flem_run(&["run", sps, "--quiet", "--out", ref_dir.to_str().unwrap()]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    // Kill delays scale with the uninterrupted run's wall time (the machine's speed varies), so
    // that several kills land before the run completes.
    let mut span_ms = (t_ref.elapsed().as_millis() as u64 / 4).max(40);
    flem_plugins::link();
    let hash = checkpoint::scene_hash(&Simulation::new(flem_core::scene::Scene::from_file(&sp).unwrap()).unwrap());
    let seed = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_nanos() as u64;
    eprintln!("sigkill test: random seed {seed}");
    let mut rng = seed;
    let (mut kills, mut checked, mut cut) = (0, 0, 0);
    // The delays come from the reference run's wall time; when the machine's load drops after
    // it, the children finish before enough kills: start again, fresh, with shorter delays
    // (whatever each attempt wrote is checked whole all the same).
    for attempt in 0..4 {
        if attempt > 0 {
            if kills >= 3 && checked >= 10 {
                break;
            }
            eprintln!("sigkill test: attempt {attempt}: {kills} kills, {checked} files in the last one; delays / 2");
            span_ms = (span_ms / 2).max(10);
            (kills, checked) = (0, 0);
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(&dir).unwrap();
        }
        for round in 0..12 {
            let resume = !checkpoint::list(&dir).unwrap().is_empty();
            let mut args = vec!["run", sps, "--quiet", "--out", dir.to_str().unwrap()];
            if resume {
                args.extend(["--resume", dir.to_str().unwrap()]);
            }
            let mut child = Command::new(crate::common::flem_exe()).args(&args).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
            rng = flem_core::cracking::weibull::splitmix64(rng);
            std::thread::sleep(Duration::from_millis(20 + rng % span_ms));
            let done = child.try_wait().unwrap().is_some();
            if !done {
                child.kill().unwrap();
                kills += 1;
            }
            child.wait().unwrap();
            // A kill before the first write leaves nothing: legitimate, counted below.
            checked += check_all_whole(&dir, &ref_dir, hash, round, false, &mut cut);
            if done {
                break;
            }
        }
    }
    eprintln!("sigkill test: {kills} kills, {checked} files checked whole, {cut} CSV logs with a cut last row");
    assert!(checked >= 10, "too few files written to check ({checked})");
    assert!(kills >= 3, "the run finished before it could be killed enough ({kills} kills)");
    let resume = !checkpoint::list(&dir).unwrap().is_empty();
    let mut args = vec!["run", sps, "--quiet", "--out", dir.to_str().unwrap()];
    if resume {
        args.extend(["--resume", dir.to_str().unwrap()]);
    }
    let r = flem_run(&args);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    check_all_whole(&dir, &ref_dir, hash, 99, true, &mut cut);
    assert_same_results(&ref_dir, &dir, "after SIGKILLs and resumes");
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&ref_dir);
    let _ = std::fs::remove_file(&sp);
}

/// A run that makes no split, written into the folder of an earlier run that did, ends with a
/// `splits.csv` of its own (the header, no row): the folder never pairs this run's summary with
/// another run's split log. Reference: the writer's contract (OutputWriter::write_summary);
/// the earlier run's log is checked to have had rows, the new one to be exactly the header.
#[test]
fn a_run_without_splits_replaces_an_older_split_log() {
    let dir = tmp("stale-splits");
    let text = tension_text();
    // A whole run into `dir`, as `flem run` does it; returns the splits.csv it leaves.
    let run_into = |text: &str, cracking: bool| {
        let mut s = Simulation::new(scene(text)).unwrap();
        assert_eq!(s.scene.file.cracking.is_some(), cracking);
        let mut w = OutputWriter::new(&dir, &s).unwrap();
        s.run(&mut w).unwrap();
        w.write_summary(&s, 0.0).unwrap();
        std::fs::read_to_string(dir.join("splits.csv")).unwrap()
    };
    let old = run_into(&text, true);
    assert!(old.lines().count() > 1, "the cracking run wrote no split row");
    // The same specimen without [cracking]: elastic, no split.
    let mut skip = false;
    let elastic: String = text
        .lines()
        .filter(|l| {
            if l.starts_with('[') {
                skip = l.starts_with("[cracking");
            }
            !skip
        })
        .map(|l| format!("{l}\n"))
        .collect();
    let new = run_into(&elastic, false);
    assert_eq!(new.lines().count(), 1, "splits.csv of the run without splits: {new}");
    assert!(new.starts_with("time,step,point"), "{new}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Two runs given one `--out` folder (issue 23's reproduction: the notched plate, then the
/// opening model 0.2 s later): the second is refused at once, naming the folder and the first
/// run's process, and writes nothing there; `--resume` into the held folder is refused the same
/// way. The first run's files stay its own (summary title, resolved scene). A SIGKILLed holder
/// releases the lock (the OS drops it with the process): a later run takes the folder.
#[test]
fn a_second_run_into_a_locked_folder_is_refused() {
    let dir = tmp("lock");
    // The notched plate made long: a tolerance no stage reaches and many steps.
    let long = std::fs::read_to_string(notch_path()).unwrap().replace("tolerance = 1e-5", "tolerance = 1e-300").replace("max_steps = 12000", "max_steps = 100000000");
    std::fs::create_dir_all(&dir).unwrap();
    let long_path = dir.with_extension("toml");
    std::fs::write(&long_path, long).unwrap();
    let d = dir.to_str().unwrap();
    let mut first = Command::new(crate::common::flem_exe()).args(["run", long_path.to_str().unwrap(), "--quiet", "--out", d]).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
    let holder = format!("process {} (", first.id());
    wait_for(|| std::fs::read_to_string(dir.join(".flem.lock")).is_ok_and(|s| s.starts_with(&holder)), "the first run's lock");
    std::thread::sleep(Duration::from_millis(200));
    let opening = root().join("configs/paper/opening.toml");
    for args in [vec!["run", opening.to_str().unwrap(), "--quiet", "--out", d], vec!["run", long_path.to_str().unwrap(), "--quiet", "--resume", d]] {
        let t = Instant::now();
        let second = flem_run(&args);
        let err = String::from_utf8_lossy(&second.stderr);
        assert_eq!(second.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(d) && err.contains("in use by another run") && err.contains(&holder), "{args:?}: {err}");
        assert!(t.elapsed() < Duration::from_secs(20), "the refusal was not at once");
    }
    assert!(first.try_wait().unwrap().is_none(), "the first run did not survive the second's refusal");
    let resolved = std::fs::read_to_string(dir.join("scene.resolved.toml")).unwrap_or_default();
    assert!(!resolved.contains("opening"), "the second run wrote its scene into the held folder");
    // SAFETY: kill(2) on our own child's pid.
    assert_eq!(unsafe { libc::kill(first.id() as i32, libc::SIGKILL) }, 0);
    first.wait().unwrap();
    let after = flem_run(&["run", opening.to_str().unwrap(), "--quiet", "--out", d]);
    assert!(after.status.success(), "a killed run left the folder locked: {}", String::from_utf8_lossy(&after.stderr));
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_file(&long_path);
}

/// A plastic run (the Tresca footing, 1200 steps) interrupted mid-stage and resumed is
/// bit-identical to the uninterrupted run: the checkpoint carries every Gauss point's stress
/// and history (section "blocks"). Reference: the uninterrupted run; exact.
#[test]
fn plastic_run_interrupted_then_resumed_is_bit_identical() {
    let text = std::fs::read_to_string(crate::common::root().join("configs/verification/strip_footing.toml")).unwrap().replace("max_steps = 9000", "max_steps = 1200");
    let ref_dir = tmp("plastic-ref");
    let mut reference = Simulation::new(scene(&text)).unwrap();
    let mut w = OutputWriter::new(&ref_dir, &reference).unwrap();
    reference.run(&mut w).unwrap();
    interrupt_and_resume(&text, 777, &reference, &ref_dir, "plastic-777");
    let _ = std::fs::remove_dir_all(&ref_dir);
}
