//! Where a recording goes, checked before a run starts.

use crate::VizError;
use std::net::{SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The Rerun port a viewer listens on by default (`rerun` with no arguments).
pub const DEFAULT_VIEWER_PORT: u16 = 9876;

/// Allowed [`RerunOptions::frame_hz`]: a frame per control step at most (the loop runs at
/// 1 kHz), one per second at least.
pub const FRAME_HZ_RANGE: [f64; 2] = [1.0, 1000.0];

/// Where the recording of a run goes.
#[derive(Clone, Debug, PartialEq)]
pub enum RerunTarget {
    /// An `.rrd` file; `rerun FILE.rrd` opens it (also while it is being written).
    File(PathBuf),
    /// A running viewer on another process or machine: `HOST:PORT` or
    /// `rerun+http://HOST:PORT/proxy`.
    Connect(String),
    /// Serve the recording on this port (all interfaces) for viewers that connect later:
    /// `rerun rerun+http://ROBOT:PORT/proxy`. The run's data is kept in memory for them.
    Serve(u16),
}

/// A recording's target and how densely it samples the run.
#[derive(Clone, Debug, PartialEq)]
pub struct RerunOptions {
    pub target: RerunTarget,
    /// Frames (robot pose, plan geometry, forces, plotted values) per second of simulated
    /// time. Touchdowns and pushes are logged at the step they happen, whatever this is.
    pub frame_hz: f64,
    /// Messages the control loop may have queued for the recorder (16384 for a file, 4096 for a
    /// stream); beyond it they are dropped and counted (the loop never waits for a slow or
    /// vanished recorder or viewer).
    pub queue_frames: usize,
    /// Which library writes the recording.
    pub recorder: crate::Recorder,
}

impl RerunOptions {
    pub fn new(target: RerunTarget) -> Self {
        // A file has no viewer to keep up with: a deeper queue lets the Python recorder (≈ 1
        // ms a frame) finish a two-minute walk at 100 frames/s without dropping any (a frame is
        // 1.5 KB, frame.rs's test: ≤ 25 MB). A stream keeps a short one, so a live view stays live.
        let queue_frames = match target {
            RerunTarget::File(_) => 16384,
            _ => 4096,
        };
        RerunOptions {
            target,
            frame_hz: 100.0,
            queue_frames,
            recorder: crate::Recorder::default_for_build(),
        }
    }

    /// Checks the options and the target: the file can be created, a viewer listens at the
    /// address, the port is free. Run before the simulation starts.
    pub fn validate(&self) -> Result<(), VizError> {
        let [lo, hi] = FRAME_HZ_RANGE;
        if !(self.frame_hz.is_finite() && (lo..=hi).contains(&self.frame_hz)) {
            return Err(VizError::Option(format!(
                "--rerun-hz {} is out of range: allowed [{lo}, {hi}] frames per simulated second",
                self.frame_hz
            )));
        }
        if self.queue_frames == 0 {
            return Err(VizError::Option(
                "the recorder's queue must hold at least one frame".into(),
            ));
        }
        match &self.target {
            RerunTarget::File(path) => check_writable(path),
            RerunTarget::Connect(address) => {
                let (url, socket) = viewer_url(address)?;
                TcpStream::connect_timeout(&socket, Duration::from_secs(2)).map_err(|e| {
                    VizError::Target(format!(
                        "no Rerun viewer is listening at {url} ({e}); start one with `rerun` \
                         (pip install rerun-sdk=={}) or record to a file with --rerun FILE.rrd",
                        crate::RERUN_VERSION
                    ))
                })?;
                Ok(())
            }
            RerunTarget::Serve(port) => {
                if *port == 0 {
                    return Err(VizError::Option(
                        "--rerun-serve 0 is out of range: allowed 1–65535".into(),
                    ));
                }
                TcpListener::bind(("0.0.0.0", *port))
                    .map(drop)
                    .map_err(|e| {
                        VizError::Target(format!("cannot serve the recording on port {port}: {e}"))
                    })
            }
        }
    }
}

fn check_writable(path: &Path) -> Result<(), VizError> {
    if path.extension().and_then(|e| e.to_str()) != Some("rrd") {
        return Err(VizError::Target(format!(
            "recording path {} must end in .rrd (the format `rerun FILE` opens)",
            path.display()
        )));
    }
    // Open it for writing now, so that a missing folder or a read-only place is reported
    // before the run, not after it; neither truncate it (an old recording stays until the
    // recorder replaces it) nor leave a new empty one behind (the run may still be refused).
    let existed = path.exists();
    std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(false)
        .open(path)
        .map(drop)
        .map_err(|e| {
            VizError::Target(format!(
                "cannot write the recording {}: {e}",
                path.display()
            ))
        })?;
    if !existed {
        let _ = std::fs::remove_file(path);
    }
    Ok(())
}

/// `HOST:PORT`, `HOST` or `rerun+http://HOST:PORT/proxy` → the viewer's gRPC URL and the
/// socket it listens on.
pub fn viewer_url(address: &str) -> Result<(String, SocketAddr), VizError> {
    let bad = |why: &str| {
        VizError::Option(format!(
            "--rerun-connect '{address}' {why}: expected HOST:PORT or rerun+http://HOST:PORT/proxy"
        ))
    };
    let host_port = address
        .strip_prefix("rerun+http://")
        .or_else(|| address.strip_prefix("rerun+https://"))
        .unwrap_or(address);
    let host_port = host_port.strip_suffix("/proxy").unwrap_or(host_port);
    if host_port.is_empty() || host_port.contains('/') {
        return Err(bad("is not an address"));
    }
    let with_port = if host_port
        .rsplit_once(':')
        .is_some_and(|(_, p)| !p.is_empty())
    {
        host_port.to_string()
    } else {
        format!("{}:{DEFAULT_VIEWER_PORT}", host_port.trim_end_matches(':'))
    };
    let socket = with_port
        .to_socket_addrs()
        .map_err(|_| bad("does not resolve"))?
        .next()
        .ok_or_else(|| bad("does not resolve"))?;
    Ok((format!("rerun+http://{with_port}/proxy"), socket))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn viewer_addresses_take_the_forms_rerun_prints() {
        let (url, socket) = viewer_url("127.0.0.1").unwrap();
        assert_eq!(url, "rerun+http://127.0.0.1:9876/proxy");
        assert_eq!(socket.port(), 9876);
        let (url, _) = viewer_url("rerun+http://127.0.0.1:9000/proxy").unwrap();
        assert_eq!(url, "rerun+http://127.0.0.1:9000/proxy");
        assert!(viewer_url("").is_err());
        assert!(viewer_url("http://x/y/z").is_err());
    }

    #[test]
    fn bad_options_are_refused_before_a_run() {
        let dir = tempfile::tempdir().unwrap();
        let mut o = RerunOptions::new(RerunTarget::File(dir.path().join("run.rrd")));
        o.validate().unwrap();
        o.frame_hz = f64::NAN;
        assert!(o
            .validate()
            .unwrap_err()
            .to_string()
            .contains("--rerun-hz NaN"));
        o.frame_hz = 2000.0;
        assert!(o.validate().is_err());
        let o = RerunOptions::new(RerunTarget::File(dir.path().join("no/such/run.rrd")));
        assert!(o
            .validate()
            .unwrap_err()
            .to_string()
            .contains("cannot write"));
        let o = RerunOptions::new(RerunTarget::File(dir.path().join("run.txt")));
        assert!(o.validate().unwrap_err().to_string().contains(".rrd"));
        // Nothing listens on a port just released.
        let port = TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let o = RerunOptions::new(RerunTarget::Connect(format!("127.0.0.1:{port}")));
        assert!(o
            .validate()
            .unwrap_err()
            .to_string()
            .contains("no Rerun viewer"));
    }
}
