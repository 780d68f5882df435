//! Short closed-loop walks under EEMP, one per gait, plus the paper's key behaviours.

use eemp_core::planner::{Gait, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_sim::walk::{run_walk, WalkRun, WalkSpec};

fn walk(gait: Gait, speed: f64, duration: f64, params: PlannerParams) -> WalkRun {
    let spec = WalkSpec::constant(
        PlannerConfig {
            gait,
            ..Default::default()
        },
        params,
        VelocityCommand {
            vx_mps: speed,
            ..Default::default()
        },
        duration,
    );
    run_walk(&RobotConfig::a1(), &spec, |_| {}).unwrap()
}

#[test]
fn each_gait_walks_without_falling() {
    for (gait, speed) in [(Gait::Trot, 0.5), (Gait::Walk, 0.2), (Gait::Free, 0.5)] {
        let run = walk(gait, speed, 6.0, PlannerParams::default());
        let m = &run.metrics;
        println!(
            "{gait} {speed} m/s: fell {} dist {:.3} vel rmse {:?} cot {:?} steps {:?} mpc fail {}",
            run.stats.fell, m.distance_m, m.vel_rmse_mps, m.cot, run.steps, run.stats.mpc_failures
        );
        assert!(!run.stats.fell, "{gait} fell at {:?}", run.stats.fell_at_s);
        assert!(
            m.distance_m > 0.5 * speed * 4.0,
            "{gait}: only {} m",
            m.distance_m
        );
    }
}
