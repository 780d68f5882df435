//! `eemp bench viewer`: what the Rerun recorder costs the closed loop, in one run: the same walk
//! without a recorder, recording to a file, and streaming to an address that accepts and never
//! answers (a viewer that is gone or stuck), rounds interleaved so the host's load hits all three.

use crate::rerun_arg::RerunArgs;
use eemp_core::planner::{Gait, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_sim::walk::{run_walk, WalkSpec};
use std::time::Instant;

pub struct ViewerBench {
    /// Real-time factor per case (best of the rounds): none, file, stuck viewer.
    pub rtf: [f64; 3],
    /// Frames the stuck viewer's queue dropped (last round).
    pub dropped_stuck: u64,
}

impl ViewerBench {
    pub fn json_line(&self) -> String {
        serde_json::json!({
            "rtf_none": self.rtf[0],
            "rtf_file": self.rtf[1],
            "rtf_stuck_viewer": self.rtf[2],
            "file_over_none": self.rtf[1] / self.rtf[0],
            "stuck_over_none": self.rtf[2] / self.rtf[0],
            "dropped_stuck": self.dropped_stuck,
        })
        .to_string()
    }
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
    let mut best = [0.0f64; 3];
    let mut dropped_stuck = 0;
    for _ in 0..rounds.max(1) {
        for (case, best_rtf) in best.iter_mut().enumerate() {
            let mut args = RerunArgs {
                rerun: None,
                rerun_connect: None,
                rerun_serve: None,
                rerun_hz: 100.0,
            };
            match case {
                1 => args.rerun = Some(tmp.join("bench.rrd")),
                2 => args.rerun_connect = Some(stuck_addr.clone()),
                _ => {}
            }
            let mut recorder = args.open("bench", &robot, &spec)?;
            let t0 = Instant::now();
            let run =
                run_walk(&robot, &spec, |r| recorder.observe(r)).map_err(|e| e.to_string())?;
            let wall = t0.elapsed().as_secs_f64();
            let summary = recorder.finish();
            if case == 2 {
                dropped_stuck = summary
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
        rtf: best,
        dropped_stuck,
    })
}

fn tempfile_dir() -> Result<std::path::PathBuf, String> {
    let d = std::env::temp_dir().join(format!("eemp-bench-viewer-{}", std::process::id()));
    std::fs::create_dir_all(&d).map_err(|e| format!("{}: {e}", d.display()))?;
    Ok(d)
}
