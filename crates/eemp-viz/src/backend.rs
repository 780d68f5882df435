//! Who writes a recording: Rerun's Rust SDK inside this process (feature `sdk`, `make viewer`),
//! or Python's `rerun-sdk` in a child process fed through a pipe (every build; needs a Python
//! with `pip install rerun-sdk==0.36.3`). Both log the same operations.

use crate::ops::{Layout, Op};
use crate::target::RerunTarget;
use std::path::PathBuf;

/// Logs operations and, at the end, writes everything out.
pub trait Backend: Send {
    /// Logs `ops` in order; returns how many log calls failed.
    fn log(&mut self, ops: &[Op]) -> usize;
    /// Writes out what is pending (a file completely, a stream within a time limit) and
    /// closes: whether everything was written out, and how many more log calls failed.
    fn finish(self: Box<Self>) -> (bool, usize);
    /// A way to stop the backend from another thread when it will not finish in time (a
    /// child process to kill); None when dropping it is enough.
    fn abort_handle(&self) -> Option<Box<dyn Fn() + Send>> {
        None
    }
}

/// Which library writes the recording.
#[derive(Clone, Debug, PartialEq)]
pub enum Recorder {
    /// Rerun's Rust SDK, in this process (a build with the `sdk` feature).
    Sdk,
    /// Python's `rerun-sdk` in a child process run by this interpreter.
    Python(PathBuf),
}

/// The environment variable naming the Python that records (default `python3`).
pub const PYTHON_ENV: &str = "EEMP_PYTHON";

impl Recorder {
    /// The Rust SDK where it is built in, else Python (`$EEMP_PYTHON`, or `python3`).
    pub fn default_for_build() -> Self {
        if cfg!(feature = "sdk") {
            Recorder::Sdk
        } else {
            Recorder::Python(default_python())
        }
    }

    pub fn name(&self) -> String {
        match self {
            Recorder::Sdk => format!("Rerun's Rust SDK {}", crate::RERUN_VERSION),
            Recorder::Python(p) => format!("Python rerun-sdk ({})", p.display()),
        }
    }
}

pub fn default_python() -> PathBuf {
    std::env::var_os(PYTHON_ENV)
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("python3"))
}

/// What a backend needs to open its recording.
pub struct Opening<'a> {
    pub target: &'a RerunTarget,
    pub recording_name: &'a str,
    pub layout: &'a Layout,
}
