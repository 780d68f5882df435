//! `--estimator`, `--ideal-sensors`, `--seed`: what a controller sees, shared by every command
//! that runs the robot.

use eemp_core::estimator::KfConfig;
use eemp_core::robot::RobotConfig;
use eemp_sim::closed_loop::StateSource;
use eemp_sim::sensors::SensorNoise;

/// `ground-truth` or `kf` (with A1-like sensor noise unless `ideal_sensors`).
pub fn state_source(
    name: &str,
    ideal_sensors: bool,
    seed: u64,
    robot: &RobotConfig,
) -> Result<StateSource, String> {
    match name {
        "ground-truth" => Ok(StateSource::GroundTruth),
        "kf" => Ok(StateSource::Kf {
            kf: KfConfig {
                foot_height_m: robot.leg.foot_radius_m,
                ..Default::default()
            },
            sensors: if ideal_sensors {
                SensorNoise::none()
            } else {
                SensorNoise::default()
            },
            seed,
        }),
        other => Err(format!(
            "unknown --estimator '{other}': allowed ground-truth, kf"
        )),
    }
}
