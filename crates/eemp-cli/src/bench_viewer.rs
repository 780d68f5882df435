//! `eemp bench viewer`: what the Rerun recorder costs the closed loop, in one run: the same walk
//! without a recorder, and for each recorder this build has (Python's rerun-sdk; the Rust SDK
//! with `--features rerun`) recording to a file and streaming to an address that accepts and
//! never answers (a viewer that is gone or stuck), rounds interleaved so the host's load hits
//! every case.

use crate::rerun_arg::RerunArgs;
use eemp_core::planner::{Gait, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_sim::walk::{run_walk, WalkSpec};
use eemp_viz::Recorder;
use std::time::Instant;

/// One recorder's cost.
pub struct RecorderCost {
    /// "python" or "sdk".
    pub recorder: &'static str,
    /// Real-time factor (best of the rounds) recording to a file and streaming to a stuck viewer.
    pub rtf_file: f64,
    pub rtf_stuck: f64,
    /// Frames the stuck viewer's queue dropped (last round).
    pub dropped_stuck: u64,
}

pub struct ViewerBench {
    /// Real-time factor without a recorder (best of the rounds).
    pub rtf_none: f64,
    pub recorders: Vec<RecorderCost>,
}

impl ViewerBench {
    pub fn json_line(&self) -> String {
        let mut j = serde_json::json!({ "rtf_none": self.rtf_none });
        for r in &self.recorders {
            let n = r.recorder;
            j[format!("rtf_file_{n}")] = r.rtf_file.into();
            j[format!("rtf_stuck_viewer_{n}")] = r.rtf_stuck.into();
            j[format!("file_over_none_{n}")] = (r.rtf_file / self.rtf_none).into();
            j[format!("stuck_over_none_{n}")] = (r.rtf_stuck / self.rtf_none).into();
            j[format!("dropped_stuck_{n}")] = r.dropped_stuck.into();
        }
        j.to_string()
    }

    pub fn table(&self, rounds: usize) -> String {
        let mut s = format!(
            "real-time factor, best of {rounds}: no recorder {:.1}x",
            self.rtf_none
        );
        for r in &self.recorders {
            s += &format!(
                "\n  {}: to a file {:.1}x ({:.2}), to a viewer that never answers {:.1}x ({:.2}, {} frames dropped)",
                r.recorder,
                r.rtf_file,
                r.rtf_file / self.rtf_none,
                r.rtf_stuck,
                r.rtf_stuck / self.rtf_none,
                r.dropped_stuck
            );
        }
        s
    }
}

/// The recorders to measure: Python's (the interpreter `eemp` would use) and, in a build with
/// it, the Rust SDK.
fn recorders() -> Vec<(&'static str, Option<std::path::PathBuf>)> {
    let mut r = vec![("python", Some(eemp_viz::backend::default_python()))];
    if Recorder::default_for_build() == Recorder::Sdk {
        r.push(("sdk", None));
    }
    r
}

pub fn bench_viewer(
    duration_s: f64,
    rounds: usize,
    robot: &RobotConfig,
) -> Result<ViewerBench, String> {
    if !(duration_s.is_finite() && (1.0..=600.0).contains(&duration_s)) {
        return Err(format!(
            "--duration {duration_s} is out of range: allowed [1, 600] s"
        ));
    }
    let robot = robot.clone();
    let spec = WalkSpec::constant(
        PlannerConfig {
            gait: Gait::Trot,
            ..Default::default()
        },
        PlannerParams::default(),
        VelocityCommand {
            vx_mps: 0.3,
            ..Default::default()
        },
        duration_s,
    );
    let tmp = tempfile_dir()?;
    // Accepts connections and never speaks gRPC.
    let stuck = std::net::TcpListener::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
    let stuck_addr = stuck.local_addr().map_err(|e| e.to_string())?.to_string();
    let recorders = recorders();
    // Case 0: no recorder; then file and stuck viewer per recorder.
    let cases = 1 + 2 * recorders.len();
    let mut best = vec![0.0f64; cases];
    let mut dropped_stuck = vec![0u64; recorders.len()];
    for _ in 0..rounds.max(1) {
        for (case, best_rtf) in best.iter_mut().enumerate() {
            let mut args = RerunArgs {
                rerun: None,
                rerun_connect: None,
                rerun_serve: None,
                rerun_hz: 100.0,
                rerun_python: None,
            };
            if case > 0 {
                let (_, python) = &recorders[(case - 1) / 2];
                args.rerun_python = python.clone();
                if case % 2 == 1 {
                    args.rerun = Some(tmp.join("bench.rrd"));
                } else {
                    args.rerun_connect = Some(stuck_addr.clone());
                }
            }
            let mut recorder = args.open("bench", &robot, &spec)?;
            let t0 = Instant::now();
            let run =
                run_walk(&robot, &spec, |r| recorder.observe(r)).map_err(|e| e.to_string())?;
            let wall = t0.elapsed().as_secs_f64();
            let summary = recorder.finish();
            if case > 0 && case % 2 == 0 {
                dropped_stuck[(case - 1) / 2] = summary
                    .as_ref()
                    .and_then(|s| s["dropped"].as_u64())
                    .unwrap_or(0);
            }
            *best_rtf = best_rtf.max(run.stats.sim_time_s / wall);
        }
    }
    let _ = std::fs::remove_dir_all(&tmp);
    drop(stuck);
    Ok(ViewerBench {
        rtf_none: best[0],
        recorders: recorders
            .iter()
            .enumerate()
            .map(|(i, (name, _))| RecorderCost {
                recorder: name,
                rtf_file: best[1 + 2 * i],
                rtf_stuck: best[2 + 2 * i],
                dropped_stuck: dropped_stuck[i],
            })
            .collect(),
    })
}

fn tempfile_dir() -> Result<std::path::PathBuf, String> {
    let d = std::env::temp_dir().join(format!("eemp-bench-viewer-{}", std::process::id()));
    std::fs::create_dir_all(&d).map_err(|e| format!("{}: {e}", d.display()))?;
    Ok(d)
}
