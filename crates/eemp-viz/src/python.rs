//! The recording written by Python's `rerun-sdk` in a child process: the operations go down
//! its stdin as JSON lines (python/eemp_rerun_bridge.py, embedded here, logs them). A build
//! without Rerun's ~300 Rust crates records this way.

use crate::backend::{Backend, Opening};
use crate::ops::Op;
use crate::target::{viewer_url, RerunTarget};
use crate::VizError;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The bridge's source, run with `python -c`.
pub const BRIDGE: &str = include_str!("../python/eemp_rerun_bridge.py");

/// How long Python may take to import rerun and open the target.
const OPEN_TIMEOUT: Duration = Duration::from_secs(60);
/// How long Python may take to write out a finished recording (less than the sink's
/// `FINISH_TIMEOUT`, so that this one decides).
pub const FINISH_TIMEOUT: Duration = Duration::from_secs(120);

pub struct PythonBackend {
    child: Arc<Mutex<Child>>,
    stdin: Option<ChildStdin>,
    replies: Receiver<String>,
    line: Vec<u8>,
    finished: bool,
}

fn header(o: &Opening) -> Result<serde_json::Value, VizError> {
    let target = match o.target {
        RerunTarget::File(path) => serde_json::json!({ "file": absolute(path) }),
        RerunTarget::Connect(address) => serde_json::json!({ "connect": viewer_url(address)?.0 }),
        RerunTarget::Serve(port) => serde_json::json!({ "serve": port }),
    };
    Ok(serde_json::json!({
        "version": crate::RERUN_VERSION,
        "application_id": crate::APPLICATION_ID,
        "recording_name": o.recording_name,
        "target": target,
        "layout": o.layout,
    }))
}

fn absolute(path: &Path) -> PathBuf {
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf())
}

/// Kills the child and reaps it.
fn stop(child: &Mutex<Child>) {
    if let Ok(mut c) = child.lock() {
        let _ = c.kill();
        let _ = c.wait();
    }
}

impl PythonBackend {
    /// Starts the bridge and waits until it has opened the target (or says why it cannot).
    pub fn open(python: &Path, o: &Opening) -> Result<Self, VizError> {
        let how = format!(
            "record through Python with rerun-sdk {v} (pip install rerun-sdk=={v}; \
             ${env} picks the interpreter), or build the Rust recorder \
             with `make viewer`",
            v = crate::RERUN_VERSION,
            env = crate::backend::PYTHON_ENV,
        );
        let mut first_line = serde_json::to_vec(&header(o)?)
            .map_err(|e| VizError::Target(format!("cannot encode the recording's header: {e}")))?;
        first_line.push(b'\n');
        // UTF-8 whatever the locale (names and units carry μ, −, ·).
        let mut child = Command::new(python)
            .args(["-u", "-X", "utf8", "-c", BRIDGE])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .map_err(|e| {
                VizError::Target(format!(
                    "cannot run the Python {} for the Rerun recording ({e}): {how}",
                    python.display()
                ))
            })?;
        let stdout = child.stdout.take().expect("piped");
        let mut stdin = child.stdin.take().expect("piped");
        let child = Arc::new(Mutex::new(child));
        let (tx, replies) = mpsc::channel();
        std::thread::Builder::new()
            .name("eemp-rerun-py".into())
            .spawn(move || {
                for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                    if tx.send(line).is_err() {
                        break;
                    }
                }
            })
            .map_err(|e| {
                stop(&child);
                VizError::Target(format!("cannot start the recorder thread: {e}"))
            })?;
        let fail = |why: String| {
            stop(&child);
            VizError::Target(why)
        };
        // A bridge that ended at once (no rerun-sdk) may have closed its stdin already: its
        // answer, not the broken pipe, says why.
        let _ = stdin.write_all(&first_line).and_then(|()| stdin.flush());
        match replies.recv_timeout(OPEN_TIMEOUT) {
            Ok(line) if line == "ready" => Ok(PythonBackend {
                child,
                stdin: Some(stdin),
                replies,
                line: Vec::with_capacity(1 << 16),
                finished: false,
            }),
            Ok(line) => Err(fail(format!(
                "{}; {how}",
                line.strip_prefix("error: ").unwrap_or(&line)
            ))),
            Err(RecvTimeoutError::Disconnected) => Err(fail(format!(
                "the Python recorder {} ended before opening the recording: {how}",
                python.display()
            ))),
            Err(RecvTimeoutError::Timeout) => Err(fail(format!(
                "the Python recorder {} did not open the recording within {} s",
                python.display(),
                OPEN_TIMEOUT.as_secs()
            ))),
        }
    }
}

impl Backend for PythonBackend {
    fn log(&mut self, ops: &[Op]) -> usize {
        let Some(stdin) = &mut self.stdin else {
            return ops.len();
        };
        self.line.clear();
        if serde_json::to_writer(&mut self.line, ops).is_err() {
            return ops.len();
        }
        self.line.push(b'\n');
        // One write per message, unbuffered: a live viewer gets each as it comes. A full pipe
        // blocks this (the recorder's) thread only; the loop's queue drops frames.
        if stdin.write_all(&self.line).is_err() {
            // Python went away: the rest is counted as failed, the run goes on.
            self.stdin = None;
            return ops.len();
        }
        0
    }

    fn finish(mut self: Box<Self>) -> (bool, usize) {
        // Closing stdin tells the bridge to write out and end.
        let closed = self.stdin.take().is_some();
        let deadline = Instant::now() + FINISH_TIMEOUT;
        let mut done: Option<(usize, bool)> = None;
        loop {
            match self
                .replies
                .recv_timeout(deadline.saturating_duration_since(Instant::now()))
            {
                Ok(line) => {
                    let mut words = line.strip_prefix("done ").unwrap_or("").split(' ');
                    if let (Some(Ok(n)), Some(f)) =
                        (words.next().map(str::parse::<usize>), words.next())
                    {
                        done = Some((n, f == "1"));
                    }
                }
                Err(RecvTimeoutError::Disconnected) => break,
                Err(RecvTimeoutError::Timeout) => {
                    stop(&self.child);
                    break;
                }
            }
        }
        self.finished = true;
        let exited = loop {
            let status = self.child.lock().map(|mut c| c.try_wait());
            match status {
                Ok(Ok(Some(s))) => break s.success(),
                Ok(Ok(None)) if Instant::now() < deadline => {
                    std::thread::sleep(Duration::from_millis(20))
                }
                _ => {
                    stop(&self.child);
                    break false;
                }
            }
        };
        match done {
            Some((failed, flushed)) => (closed && flushed && exited, failed),
            None => (false, 0),
        }
    }

    fn abort_handle(&self) -> Option<Box<dyn Fn() + Send>> {
        let child = Arc::clone(&self.child);
        Some(Box::new(move || stop(&child)))
    }
}

impl Drop for PythonBackend {
    /// A backend dropped without `finish` (an error while logging the scene, a panic) leaves
    /// no Python behind.
    fn drop(&mut self) {
        if !self.finished {
            stop(&self.child);
        }
    }
}
