//! `eemp bench estimator`: the linear Kalman filter's cost per update against a bare MuJoCo
//! step of the robot (the A1 by default), in one run (the filter runs in the robot's 1 kHz loop).

use eemp_core::estimator::{EstimatorInput, KfConfig, LinearKf};
use eemp_core::leg::LegMap;
use eemp_core::robot::RobotConfig;
use eemp_sim::mjcf::SceneExtras;
use eemp_sim::walk::StartPose;
use eemp_sim::Simulation;
use nalgebra::Vector3;
use std::time::Instant;

pub struct EstimatorBench {
    pub update_us: f64,
    pub mujoco_step_us: f64,
}

impl EstimatorBench {
    pub fn ratio(&self) -> f64 {
        self.update_us / self.mujoco_step_us
    }

    pub fn json_line(&self) -> String {
        serde_json::json!({
            "kf_update_us": self.update_us,
            "mujoco_step_us": self.mujoco_step_us,
            "ratio": self.ratio(),
        })
        .to_string()
    }
}

/// Times `updates` filter updates on a standing robot's readings and as many bare steps.
pub fn bench_estimator(updates: usize, robot: &RobotConfig) -> Result<EstimatorBench, String> {
    let robot = robot.clone();
    let mut sim = Simulation::new(&robot, &SceneExtras::default()).map_err(|e| e.to_string())?;
    let q0 = robot.standing_pose();
    let start = StartPose::from_joints(&robot, q0);
    sim.reset(Vector3::new(0.0, 0.0, start.trunk_height_m + 1e-3), &q0);
    sim.prepare();
    let truth = sim.ground_truth_state();
    let imu = sim.imu();
    let mut kf = LinearKf::new(KfConfig::default(), sim.kinematics().clone(), &truth)
        .map_err(|e| e.to_string())?;
    let tau = LegMap::splat(Vector3::new(0.0, 2.0, -4.0));
    let t = Instant::now();
    for i in 0..updates {
        kf.update(&EstimatorInput {
            time_s: truth.time_s + (i + 1) as f64 * 1e-3,
            imu,
            joints: truth.joints,
            contact_trust: LegMap::splat(if i % 2 == 0 { 1.0 } else { 0.5 }),
        });
    }
    let update = t.elapsed().as_secs_f64() / updates as f64;
    let t = Instant::now();
    for i in 0..updates {
        if i % 2000 == 0 {
            sim.reset(Vector3::new(0.0, 0.0, start.trunk_height_m + 1e-3), &q0);
        }
        sim.step_bare(&tau);
    }
    let step = t.elapsed().as_secs_f64() / updates as f64;
    if !kf.is_finite() {
        return Err("the filter diverged during the benchmark".into());
    }
    Ok(EstimatorBench {
        update_us: update * 1e6,
        mujoco_step_us: step * 1e6,
    })
}
