//! Rerun recordings and live views of EEMP runs (issue 23): the robot from the generated MJCF
//! (and the filter's estimate as a ghost), eq. (5)'s placement ellipses, eq. (6)'s planned and
//! the actual touchdowns, eq. (7)'s swing paths, stance forces in their friction cones, pushes,
//! and the run's time series, all on the simulation-time timeline, in a ready layout.
//!
//! [`RerunSink`] is an observer on the one closed loop (`eemp_sim::closed_loop`): it copies
//! what a step shows into a bounded queue and a thread of its own does the logging, so a slow
//! or vanished viewer costs dropped frames (counted), never a slower loop.
//!
//! The writer turns frames into backend-free log operations ([`ops`]); a [`backend`] logs
//! them: Python's `rerun-sdk` in a child process (every build), or Rerun's Rust SDK in this
//! process (feature `sdk`, ~300 more crates).

pub mod backend;
pub mod frame;
pub mod layout;
pub mod ops;
pub mod python;
pub mod scene;
#[cfg(feature = "sdk")]
pub mod sdk;
pub mod sink;
pub mod target;
pub mod writer;

/// For tests (this crate's and the CLI's): the Python that records and reads recordings back.
#[doc(hidden)]
pub mod testing {
    use std::path::{Path, PathBuf};
    use std::process::Command;

    /// `$EEMP_PYTHON`, else the repository's `.venv` (`make test` installs rerun-sdk there);
    /// None, with a loud note, when it cannot import rerun, unless `EEMP_REQUIRE_RERUN=1`
    /// (`make test`), which makes that a failure.
    pub fn python() -> Option<PathBuf> {
        let python = std::env::var_os(crate::backend::PYTHON_ENV)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
            .unwrap_or_else(|| {
                Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.venv/bin/python")
            });
        let ok = Command::new(&python)
            .args(["-c", "import rerun"])
            .output()
            .is_ok_and(|o| o.status.success());
        if ok {
            return Some(python);
        }
        let why = format!(
            "{} cannot import rerun (pip install rerun-sdk=={})",
            python.display(),
            crate::RERUN_VERSION
        );
        if std::env::var("EEMP_REQUIRE_RERUN").as_deref() == Ok("1") {
            panic!("{why}");
        }
        eprintln!("SKIPPED: {why}");
        None
    }
}

pub use backend::Recorder;
use eemp_core::robot::RobotConfig;
use eemp_sim::closed_loop::Push;
use eemp_sim::mjcf::SceneExtras;
pub use sink::{RerunReport, RerunSink};
pub use target::{RerunOptions, RerunTarget};

/// The Rerun version recordings are written with (the Rust SDK's, and the Python bridge
/// refuses another minor version); open them with the same minor version of the viewer
/// (`pip install rerun-sdk==0.36.3`).
pub const RERUN_VERSION: &str = "0.36.3";

/// The application id recordings carry (the viewer groups recordings by it).
pub const APPLICATION_ID: &str = "eemp";

/// What is being recorded: the simulated world (after any model error) and its events.
#[derive(Clone, Debug)]
pub struct RunView {
    /// The recording's name in the viewer, e.g. "walk: EEMP (free) at 0.3 m/s".
    pub name: String,
    pub robot: RobotConfig,
    pub scene: SceneExtras,
    pub pushes: Vec<Push>,
    /// Whether the controller sees a state estimate (drawn as a ghost beside the truth).
    pub estimated: bool,
    /// Time between the steps the recorder is shown, s: the control step live, a trace's row
    /// spacing in a replay.
    pub step_s: f64,
}

#[derive(Debug, thiserror::Error)]
pub enum VizError {
    /// An option out of its range or malformed.
    #[error("{0}")]
    Option(String),
    /// The recording's file, viewer or port cannot be used.
    #[error("{0}")]
    Target(String),
}
