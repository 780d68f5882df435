//! `--estimator`, `--ideal-sensors`, `--seed`: what a controller sees, shared by every command
//! that runs the robot.

use eemp_core::robot::RobotConfig;
use eemp_sim::closed_loop::StateSource;
// The run description owns what a controller sees; these are its command-line options.
pub use eemp_rl::run::{state_source, with_kf_options, KfOptions, Sensing};

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
    /// least this large, m/s (`KfConfig::velocity_jump_mps`, default 0.15; 0: off).
    #[arg(long)]
    pub kf_velocity_jump: Option<f64>,
    /// With --estimator kf: take a jump that a group of the stance legs agree on when every
    /// other one reads at least this fraction of it (a foot dragged along by a push;
    /// `KfConfig::velocity_jump_dragged_fraction`, default 0.15; 0: off).
    #[arg(long)]
    pub kf_dragged_fraction: Option<f64>,
    /// With --estimator kf: fade out a stance leg whose velocity disagrees with the estimate and
    /// with every other stance leg by more than this, m/s (`KfConfig::leg_outlier_mps`, default
    /// 0.15; 0: off).
    #[arg(long)]
    pub kf_leg_outlier: Option<f64>,
}

impl StateSourceArgs {
    /// The run description's part these options fill.
    pub fn sensing(&self) -> Sensing {
        Sensing {
            estimator: self.estimator.clone(),
            ideal_sensors: self.ideal_sensors,
            seed: self.seed,
            kf: self.kf_options(),
        }
    }

    pub fn source(&self, robot: &RobotConfig) -> Result<StateSource, String> {
        self.sensing().source(robot)
    }

    pub fn kf_options(&self) -> KfOptions {
        KfOptions {
            velocity_jump_mps: self.kf_velocity_jump,
            velocity_jump_dragged_fraction: self.kf_dragged_fraction,
            leg_outlier_mps: self.kf_leg_outlier,
        }
    }
}
