//! Append-only CSV logs (`history.csv`, `splits.csv`): the file is kept open and every row
//! (or batch of rows) goes out with one `write` of whole lines, so writing a run's log costs
//! O(rows), not O(rows^2) as rewriting the whole file at every row did.
//!
//! # What a reader may see
//! The header is created with [`super::atomic_write`] at the first row, so the file never lacks
//! it. A row is one `write(2)` of complete lines: a process that exits, panics or gets SIGINT
//! or SIGTERM never leaves part of a row (the kernel finishes the write before a handler runs).
//! Only SIGKILL (or a power cut) can cut a row: Linux checks for a fatal signal between page
//! cache pages, so a row that straddles a 4 KiB boundary may be written in part. Readers
//! therefore leave out a last line without its newline (`flem_plot::run::History::read`, which
//! reports it and refuses any other damaged line by number), and `--resume` truncates the file
//! to the length the checkpoint recorded, which removes it.
//!
//! # Durability (fsync policy)
//! fsync costs about 9 ms per file on this machine's disk, a row a few microseconds, so the
//! logs are synced only where it matters: [`CsvLog::sync`] is called by the output writer
//! before every checkpoint is written (at every stage end, including the last, every
//! `checkpoint_every` steps or `checkpoint_seconds`, and on interruption) and when
//! `summary.json` is written (end of the run, also after a divergence). A checkpoint is thus
//! never durable before the log prefix it records; rows after the last checkpoint may be lost
//! in a power cut (not in a process crash: they are in the page cache), and a resume truncates
//! them anyway.
//!
//! # Checkpoints
//! A checkpoint records a [`LogMark`] (byte length and CRC-32 of those bytes) per log instead
//! of the contents. [`CsvLog::resume`] reads the file's first `len` bytes, refuses (naming the
//! file and the checkpoint) a file that is shorter or whose prefix changed, then truncates it
//! to `len` and appends from there; a resumed run therefore writes the same bytes as an
//! uninterrupted one. Resuming into another folder copies the recorded prefix there; a log the
//! checkpoint did not record yet is removed.
//!
//! # Why, and the remaining cases
//! Rewriting the whole file per row was quadratic: a 22k-step run with `history_every = 1` took
//! 52 s instead of 0.1 s (and its checkpoints shrank from 4.5 MB to 6 KB once they stopped
//! carrying the logs). A write error cuts the file back to its last whole row and names it. A
//! log that got no row is written with its header only when `summary.json` is, so a run without
//! splits never leaves an older run's `splits.csv` in its folder. `flem plot`'s note for a cut
//! last line names `history.csv:LINE`.
use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use crate::error::{FlemError, Result};

/// Where a log stood at a checkpoint: its byte length and the CRC-32 (IEEE, `crc32fast`) of
/// those bytes. The CRC guards against an edited or replaced file, not an adversary.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct LogMark {
    pub len: u64,
    pub crc: u32,
}

/// One append-only CSV file, created at its first row.
pub struct CsvLog {
    path: PathBuf,
    header: String,
    /// Open for appending once the file has been created (or resumed).
    file: Option<File>,
    len: u64,
    crc: crc32fast::Hasher,
}

impl CsvLog {
    /// A log of `path` with its header line (ending in a newline); nothing is written yet.
    pub fn new(path: PathBuf, header: String) -> Self {
        CsvLog { path, header, file: None, len: 0, crc: crc32fast::Hasher::new() }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    fn err(&self, msg: impl std::fmt::Display) -> FlemError {
        FlemError::Output { path: self.path.display().to_string(), msg: msg.to_string() }
    }

    /// Replaces whatever is at the path (e.g. an older run's log) by the header, atomically
    /// and durably, and opens it for appending.
    fn create(&mut self) -> Result<()> {
        super::atomic_write(&self.path, self.header.as_bytes())?;
        self.open_append()?;
        self.len = self.header.len() as u64;
        self.crc = crc32fast::Hasher::new();
        self.crc.update(self.header.as_bytes());
        Ok(())
    }

    fn open_append(&mut self) -> Result<()> {
        let f = OpenOptions::new().append(true).open(&self.path).map_err(|e| self.err(format!("cannot be opened for appending: {e}")))?;
        self.file = Some(f);
        Ok(())
    }

    /// Appends `lines` (whole lines, each ending in a newline) with one write; creates the
    /// file with its header first if needed (even when `lines` is empty). On a failed write
    /// (disk full...) the file is cut back to its last whole row when possible and the error
    /// names the file.
    pub fn append(&mut self, lines: &[u8]) -> Result<()> {
        debug_assert!(lines.is_empty() || lines.ends_with(b"\n"));
        if self.file.is_none() {
            self.create()?;
        }
        if lines.is_empty() {
            return Ok(());
        }
        let f = self.file.as_mut().expect("opened above");
        if let Err(e) = f.write_all(lines) {
            let _ = f.set_len(self.len);
            return Err(self.err(e));
        }
        self.len += lines.len() as u64;
        self.crc.update(lines);
        Ok(())
    }

    /// fsync of the rows written so far (see the module docs for when it is called).
    pub fn sync(&self) -> Result<()> {
        match &self.file {
            Some(f) => f.sync_data().map_err(|e| self.err(format!("fsync failed: {e}"))),
            None => Ok(()),
        }
    }

    /// The length and CRC-32 of what has been written; `None` before the first row.
    pub fn mark(&self) -> Option<LogMark> {
        self.file.as_ref().map(|_| LogMark { len: self.len, crc: self.crc.clone().finalize() })
    }

    /// Continues the log as it stood at checkpoint `ck` (`mark`, `None`: the log did not exist
    /// then and is created at its next row; a file at this log's path is removed). The first `mark.len` bytes are read from `src` (the
    /// same-named file beside the checkpoint) and checked against the CRC; a shorter file or a
    /// changed prefix is refused with both files named. When `src` is this log's own file it is
    /// truncated to `mark.len` (dropping rows written after the checkpoint, or a row cut by a
    /// kill); otherwise (resuming into another folder) the prefix is copied atomically.
    pub fn resume(&mut self, src: &Path, mark: Option<LogMark>, ck: &Path) -> Result<()> {
        self.file = None;
        self.len = 0;
        self.crc = crc32fast::Hasher::new();
        let Some(m) = mark else {
            // Not created at the checkpoint: a file here now holds rows written after it (the
            // resumed run writes them again) or belongs to another run (resuming into another
            // folder); either way it is not this run's log at this point, so it goes, as a
            // truncation to nothing would (a run that never writes a row again would otherwise
            // leave it looking like its own).
            return match std::fs::remove_file(&self.path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(self.err(format!("cannot be removed: the checkpoint {} recorded no such log yet ({e})", ck.display()))),
                _ => Ok(()),
            };
        };
        let refuse = |msg: String| FlemError::Checkpoint { path: ck.display().to_string(), msg: format!("{msg}; the results cannot continue bit for bit: start the run again without --resume") };
        let mut f = File::open(src).map_err(|e| refuse(format!("{} cannot be read ({e}); the checkpoint recorded its first {} bytes", src.display(), m.len)))?;
        let have = f.metadata().map(|md| md.len()).unwrap_or(0);
        if have < m.len {
            return Err(refuse(format!("{} has {have} bytes, fewer than the {} bytes the checkpoint recorded (it was truncated or replaced since)", src.display(), m.len)));
        }
        let mut prefix = Vec::with_capacity(m.len as usize);
        (&mut f).take(m.len).read_to_end(&mut prefix).map_err(|e| refuse(format!("{} cannot be read ({e})", src.display())))?;
        // One pass over the prefix: the hasher that checks it goes on hashing the appended rows.
        let mut hasher = crc32fast::Hasher::new();
        hasher.update(&prefix);
        let crc = hasher.clone().finalize();
        if prefix.len() as u64 != m.len || crc != m.crc {
            return Err(refuse(format!("the first {} bytes of {} changed since the checkpoint (CRC-32 {crc:08x}, recorded {:08x})", m.len, src.display(), m.crc)));
        }
        drop(f);
        let same = std::fs::canonicalize(src).ok().zip(std::fs::canonicalize(&self.path).ok()).is_some_and(|(a, b)| a == b);
        if same {
            let f = OpenOptions::new().write(true).open(&self.path).map_err(|e| self.err(format!("cannot be opened to truncate it to the checkpoint ({e})")))?;
            f.set_len(m.len).map_err(|e| self.err(format!("cannot be truncated to the checkpoint's {} bytes ({e})", m.len)))?;
        } else {
            super::atomic_write(&self.path, &prefix)?;
        }
        self.open_append()?;
        self.len = m.len;
        self.crc = hasher;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    /// A resume from a checkpoint taken before a log existed removes a file at the log's path
    /// (rows written after the checkpoint, or another run's log when resuming into another
    /// folder), so that a run that never writes that log again does not leave a foreign one;
    /// with a mark, the file is cut back to the recorded bytes. Reference: the bytes written here.
    #[test]
    fn resume_without_a_mark_removes_a_foreign_log() {
        let dir = std::env::temp_dir().join(format!("flem-csvlog-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (path, ck) = (dir.join("splits.csv"), dir.join("checkpoint_000001.bin"));
        std::fs::write(&path, "time,step\n1e0,5\n").unwrap();
        let mut log = super::CsvLog::new(path.clone(), "time,step\n".into());
        log.resume(&path, None, &ck).unwrap();
        assert!(!path.exists() && log.mark().is_none());
        log.append(b"2e0,7\n").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "time,step\n2e0,7\n");
        let m = log.mark().unwrap();
        std::fs::write(&path, "time,step\n2e0,7\n3e0,9\n4e").unwrap();
        let mut log = super::CsvLog::new(path.clone(), "time,step\n".into());
        log.resume(&path, Some(m), &ck).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "time,step\n2e0,7\n");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
