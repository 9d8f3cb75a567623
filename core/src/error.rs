//! Typed errors of the core. Every message names the file, key or element it is about.
use thiserror::Error;

#[derive(Debug, Error)]
pub enum FlemError {
    /// Scene input that does not parse or does not validate. `key` is the dotted path.
    #[error("{file}: {}{msg}", if key.is_empty() { String::new() } else { format!("{key} ") })]
    Config { file: String, key: String, msg: String },
    /// A mesh that cannot be used (bad element, bad group...).
    #[error("{file}: {msg}")]
    Mesh { file: String, msg: String },
    /// The explicit run blew up.
    #[error("the run diverged at step {step} (t = {time:.6e}, dt = {dt:.6e}, dt_crit = {dt_crit:.6e}, dt/dt_crit = {ratio:.3}): {why}. Nothing non-finite was written; reduce dt_safety or check stiffness/mass.")]
    Diverged { step: u64, time: f64, dt: f64, dt_crit: f64, ratio: f64, why: String },
    /// Writing results failed.
    #[error("cannot write {path}: {msg}")]
    Output { path: String, msg: String },
    /// The implicit check solver could not solve.
    #[error("{0}")]
    Solve(String),
    /// A dynamic plugin library that cannot be used (core/src/dynload).
    #[error("plugin library {file}: {msg}")]
    Plugin { file: String, msg: String },
    /// The run was asked to stop (SIGINT/SIGTERM): a checkpoint and a snapshot were written.
    #[error("interrupted after step {step} (stage {stage}, step {stage_step} of the stage); a checkpoint was written")]
    Interrupted { step: u64, stage: usize, stage_step: u64 },
    /// A checkpoint that cannot be used (corrupt, truncated, other scene or version).
    #[error("checkpoint {path} refused: {msg}")]
    Checkpoint { path: String, msg: String },
    /// Anything else, with its context.
    #[error("{0}")]
    Other(String),
}

pub type Result<T, E = FlemError> = std::result::Result<T, E>;

impl FlemError {
    pub fn config(file: impl Into<String>, key: impl Into<String>, msg: impl Into<String>) -> Self {
        FlemError::Config { file: file.into(), key: key.into(), msg: msg.into() }
    }
    pub fn mesh(file: impl Into<String>, msg: impl Into<String>) -> Self {
        FlemError::Mesh { file: file.into(), msg: msg.into() }
    }
}

/// Nearest name by edit distance, for "did you mean" hints.
pub fn nearest<'a>(name: &str, options: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    fn lev(a: &str, b: &str) -> usize {
        let b: Vec<char> = b.chars().collect();
        let mut prev: Vec<usize> = (0..=b.len()).collect();
        for (i, ca) in a.chars().enumerate() {
            let mut cur = vec![i + 1];
            for (j, cb) in b.iter().enumerate() {
                cur.push((prev[j] + (ca != *cb) as usize).min(prev[j + 1] + 1).min(cur[j] + 1));
            }
            prev = cur;
        }
        prev[b.len()]
    }
    options.into_iter().map(|o| (lev(name, o), o)).filter(|(d, o)| *d <= (o.len() / 2).max(2)).min().map(|(_, o)| o)
}
