//! EEMP on the robot's own senses: the linear Kalman filter on the simulated IMU and encoders
//! (contact trust from the plan) in the closed loop.

use eemp_core::estimator::KfConfig;
use eemp_core::planner::{Gait, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_sim::closed_loop::StateSource;
use eemp_sim::sensors::SensorNoise;
use eemp_sim::walk::{run_walk, WalkSpec};

fn trot(source: StateSource) -> eemp_sim::walk::WalkRun {
    let mut spec = WalkSpec::constant(
        PlannerConfig {
            gait: Gait::Trot,
            ..Default::default()
        },
        PlannerParams::default(),
        VelocityCommand {
            vx_mps: 0.3,
            ..Default::default()
        },
        10.0,
    );
    spec.state_source = source;
    run_walk(&RobotConfig::a1(), &spec, |_| {}).unwrap()
}

#[test]
fn a_10_s_trot_on_the_kalman_filter_tracks_like_one_on_ground_truth() {
    let truth = trot(StateSource::GroundTruth);
    let kf = trot(StateSource::Kf {
        kf: KfConfig::default(),
        sensors: SensorNoise::none(),
        seed: 1,
    });
    assert!(!kf.stats.fell);
    // The bounds leave room above what the filter gives on this trot (an estimate error near
    // 0.017 m/s and 0.07 m; tracking on a par with ground truth's).
    let v_err = kf.estimation.vel_rmse_mps().unwrap();
    let p_err = kf.estimation.pos_rmse_m().unwrap();
    assert!(v_err <= 0.04, "velocity estimate RMSE {v_err} m/s");
    assert!(p_err <= 0.15, "position estimate RMSE {p_err} m over 10 s");
    let (a, b) = (
        kf.metrics.vel_rmse_mps.unwrap(),
        truth.metrics.vel_rmse_mps.unwrap(),
    );
    assert!(
        a <= 1.3 * b,
        "tracking on the filter {a} vs on ground truth {b}"
    );
    assert!(truth.estimation.vel_rmse_mps().is_none());
}

#[test]
fn the_filter_on_noisy_late_sensors_stays_finite_and_the_trot_walks() {
    let run = trot(StateSource::Kf {
        kf: KfConfig::default(),
        sensors: SensorNoise::default(),
        seed: 4,
    });
    assert!(!run.stats.fell);
    let v_err = run.estimation.vel_rmse_mps().unwrap();
    assert!(
        v_err.is_finite() && v_err <= 0.06,
        "velocity estimate RMSE {v_err} m/s"
    );
    assert!(run.metrics.vel_rmse_mps.unwrap() <= 0.1);
}
