//! The one error type of the study: every variant names the file, key or folder at fault.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    /// A value in a sweep file is missing, malformed or outside its allowed range.
    #[error("{}: {key}: {message}", path.display())]
    Config {
        path: PathBuf,
        key: String,
        message: String,
    },
    /// The file is not valid TOML or has the wrong shape (unknown key, wrong type).
    #[error("cannot parse {}: {message}", path.display())]
    Parse { path: PathBuf, message: String },
    #[error("cannot read {}: {message}", path.display())]
    Read { path: PathBuf, message: String },
    #[error("cannot write {}: {message}", path.display())]
    Write { path: PathBuf, message: String },
    /// `--shard K/N` is malformed or out of range.
    #[error("--shard {value}: {message}")]
    Shard { value: String, message: String },
    /// A results file is damaged somewhere other than its last line, or disagrees with its grid.
    #[error("{}: {message}", path.display())]
    Results { path: PathBuf, message: String },
    /// A sweep folder holds a different grid than the one asked for.
    #[error("{}: mismatched grid: {detail}", path.display())]
    GridMismatch { path: PathBuf, detail: String },
    /// Two shard folders hold different results for the same run.
    #[error("merge: {message}")]
    Merge { message: String },
    /// Another `eemp sweep` is writing into the folder.
    #[error(
        "{}: another sweep holds the lock on this folder; wait for it or pick another --out",
        path.display()
    )]
    Locked { path: PathBuf },
    #[error("cannot start {threads} worker threads: {message}")]
    Threads { threads: usize, message: String },
}

impl StudyError {
    pub(crate) fn read(path: &std::path::Path, e: impl std::fmt::Display) -> Self {
        StudyError::Read {
            path: path.to_path_buf(),
            message: e.to_string(),
        }
    }

    pub(crate) fn write(path: &std::path::Path, e: impl std::fmt::Display) -> Self {
        StudyError::Write {
            path: path.to_path_buf(),
            message: e.to_string(),
        }
    }
}
