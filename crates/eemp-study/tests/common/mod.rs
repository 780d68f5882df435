//! Shared helpers: a small grid and a fake runner (no simulation) whose results are a
//! deterministic function of the run.

#![allow(dead_code)]

use eemp_study::grid::RunSpec;
use eemp_study::{ProgressMode, RunOutcome, SweepConfig, SweepOptions};
use std::path::Path;

/// 2 gaits × 3 speeds × 2 ΔT × 1 × 1 × 2 r_x × 1 × 2 seeds = 48 runs.
pub const GRID: &str = r#"
[grid]
gaits = ["trot", "walk"]
speed_mps = [0.1, 0.3, 0.5]
swing_time_s = [0.2, 0.25]
step_height_m = [0.1]
body_height_m = [0.31]
ellipse_rx_m = [0.05, 0.1]
ellipse_ry_m = [0.05]
duration_s = 3
seeds = [0, 1]
"#;

pub fn config(text: &str) -> SweepConfig {
    SweepConfig::parse(text, Path::new("test.toml")).unwrap()
}

pub fn options(threads: usize) -> SweepOptions {
    SweepOptions {
        threads: Some(threads),
        shard: None,
        progress: ProgressMode::Hidden,
    }
}

/// CoT from the parameters; walk falls at 0.5 m/s with ΔT 0.25.
pub fn fake(spec: &RunSpec) -> RunOutcome {
    let p = &spec.point;
    let walk = p.gait == eemp_core::planner::Gait::Walk;
    RunOutcome {
        fell: walk && p.speed_mps > 0.4 && p.params.swing_time_s > 0.22,
        cot: Some(0.2 / p.speed_mps + p.params.swing_time_s + p.params.ellipse_rx_m),
        manipulability: Some(3.0 + spec.seed as f64 * 0.1),
        vel_rmse_mps: Some(0.1),
        distance_m: p.speed_mps * p.duration_s,
        sim_time_s: p.duration_s,
        metrics_window_s: p.duration_s - 2.0_f64.min(p.duration_s / 2.0),
        ..Default::default()
    }
}
