//! One run at a time in an output folder: [`lock_dir`] takes an exclusive OS lock on
//! `DIR/.flem.lock` for the life of the run (`flem run`, `--resume`, `flem compare`, `flem chart`).
//! A second run into a locked folder is refused at once, naming the folder and the process that
//! holds it (its pid and command, written into the lock file by the holder).
//!
//! The lock is `flock(2)` through `std::fs::File::try_lock` (stable since Rust 1.89): the kernel
//! releases it when the holding process ends, however it ends (SIGKILL, a crash), so a killed
//! run never leaves a folder locked; the file itself may stay and is reused. We use the standard
//! library rather than a crate (fs4, fd-lock) because it now has exactly this call. On a file
//! system that does not support locks (`ErrorKind::Unsupported`), the run goes on unlocked and
//! says so. The lock file is not a result: it is written in place (not through
//! [`super::atomic_write`]), and readers of a run folder ignore it.
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

use crate::error::{FlemError, Result};

/// The lock file's name inside an output folder.
pub const LOCK_FILE: &str = ".flem.lock";

/// An output folder held by this process; dropping it (or the process ending) releases it.
#[derive(Debug)]
pub struct DirLock {
    /// `None` when the file system does not support locks (see [`DirLock::note`]).
    _file: Option<File>,
    pub path: PathBuf,
    /// A warning to show when the folder could not be locked.
    pub note: Option<String>,
}

/// Creates `dir` if needed and locks it for this process; `what` (e.g. the command line) is
/// written into the lock file so that a refused run can name the holder.
pub fn lock_dir(dir: &Path, what: &str) -> Result<DirLock> {
    let out_err = |msg: String| FlemError::Output { path: dir.display().to_string(), msg };
    std::fs::create_dir_all(dir).map_err(|e| out_err(format!("the output folder cannot be created: {e}")))?;
    let path = dir.join(LOCK_FILE);
    let mut f = OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(&path)
        .map_err(|e| out_err(format!("the output folder is not writable: its lock file {LOCK_FILE} cannot be created ({e})")))?;
    match f.try_lock() {
        Ok(()) => {}
        Err(TryLockError::WouldBlock) => {
            let mut holder = String::new();
            let _ = f.read_to_string(&mut holder);
            let holder = holder.trim();
            let holder = if holder.is_empty() { "another process (starting up)".to_string() } else { holder.to_string() };
            return Err(out_err(format!(
                "is in use by another run: {holder} holds it ({}); two runs cannot write one folder: wait for that run to end, stop it, or choose another --out",
                path.display()
            )));
        }
        // No lock support on this file system (Unsupported), or NFS without a lock daemon (ENOLCK).
        Err(TryLockError::Error(e)) if e.kind() == std::io::ErrorKind::Unsupported || e.raw_os_error() == Some(libc::ENOLCK) => {
            return Ok(DirLock { _file: None, path, note: Some(format!("{}: this file system does not support file locks; nothing stops a second run from writing the same folder", dir.display())) });
        }
        Err(TryLockError::Error(e)) => return Err(out_err(format!("the lock file {LOCK_FILE} cannot be locked: {e}"))),
    }
    let stamp = format!("process {} ({what})\n", std::process::id());
    let w = f.set_len(0).and_then(|_| f.rewind()).and_then(|_| f.write_all(stamp.as_bytes())).and_then(|_| f.flush());
    w.map_err(|e| out_err(format!("the lock file {LOCK_FILE} cannot be written: {e}")))?;
    Ok(DirLock { _file: Some(f), path, note: None })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A second lock on a held folder is refused, naming the folder and the holder's pid; once
    /// the first is dropped the folder can be taken again. (flock locks belong to the open file
    /// description, so two opens in one process exclude each other as two processes do.)
    #[test]
    fn second_lock_is_refused_naming_the_holder() {
        let dir = std::env::temp_dir().join(format!("flem_lock_test_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let a = lock_dir(&dir, "flem run a.toml").unwrap();
        let e = lock_dir(&dir, "flem run b.toml").unwrap_err().to_string();
        assert!(e.contains(&dir.display().to_string()) && e.contains(&format!("process {} (flem run a.toml)", std::process::id())) && e.contains("in use by another run"), "{e}");
        drop(a);
        let b = lock_dir(&dir, "flem run b.toml").unwrap();
        assert_eq!(std::fs::read_to_string(&b.path).unwrap(), format!("process {} (flem run b.toml)\n", std::process::id()));
        drop(b);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
