//! `--estimator`, `--ideal-sensors`, `--seed`: what a controller sees, shared by every command
//! that runs the robot.

use eemp_core::robot::RobotConfig;
use eemp_sim::closed_loop::StateSource;
use eemp_sim::sensors::SensorNoise;

/// The options, flattened into `eemp walk` and `eemp stand`.
#[derive(clap::Args, Debug)]
pub struct StateSourceArgs {
    /// What the controller sees: ground-truth (the simulator's state) or kf (the linear Kalman
    /// filter on the simulated IMU and joint encoders).
    #[arg(long, default_value = "ground-truth")]
    pub estimator: String,
    /// With --estimator kf: noise-free sensors without latency (default: A1-like noise, see
    /// `eemp_sim::sensors::SensorNoise`).
    #[arg(long)]
    pub ideal_sensors: bool,
    /// Seed of the sensor noise (and, for walks, of the start perturbation; 0: start at rest).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// With --estimator kf: take a velocity jump the stance legs agree on at once when it is at
    /// least this large, m/s (`KfConfig::velocity_jump_mps`; 0: off, the default; 0.15 was
    /// measured in the README's robustness section).
    #[arg(long, default_value_t = 0.0)]
    pub kf_velocity_jump: f64,
}

impl StateSourceArgs {
    pub fn source(&self, robot: &RobotConfig) -> Result<StateSource, String> {
        let mut source = state_source(&self.estimator, self.ideal_sensors, self.seed, robot)?;
        with_velocity_jump(&mut source, self.kf_velocity_jump, "--kf-velocity-jump")?;
        Ok(source)
    }
}

/// Sets the filter's velocity-jump threshold (`name` is the option, for the error); refused
/// out of range or for a run on ground truth unless 0.
pub fn with_velocity_jump(
    source: &mut StateSource,
    jump_mps: f64,
    name: &str,
) -> Result<(), String> {
    match source {
        StateSource::Kf { kf, .. } => {
            kf.velocity_jump_mps = jump_mps;
            // The filter's own range, reported under the option's name.
            kf.validate()
                .map_err(|e| format!("{name} {jump_mps}: {e}"))?;
        }
        StateSource::GroundTruth if jump_mps != 0.0 => {
            return Err(format!("{name} {jump_mps} needs the kf estimator"))
        }
        StateSource::GroundTruth => {}
    }
    Ok(())
}

/// `ground-truth` or `kf` (with A1-like sensor noise unless `ideal_sensors`).
pub fn state_source(
    name: &str,
    ideal_sensors: bool,
    seed: u64,
    robot: &RobotConfig,
) -> Result<StateSource, String> {
    match name {
        "ground-truth" => Ok(StateSource::GroundTruth),
        "kf" => Ok(StateSource::kf(
            robot,
            if ideal_sensors {
                SensorNoise::none()
            } else {
                SensorNoise::default()
            },
            seed,
        )),
        other => Err(format!(
            "unknown --estimator '{other}': allowed ground-truth, kf"
        )),
    }
}
