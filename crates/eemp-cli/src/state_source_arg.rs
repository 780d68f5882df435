//! `--estimator`, `--ideal-sensors`, `--seed`: what a controller sees, shared by every command
//! that runs the robot.

use eemp_core::robot::RobotConfig;
use eemp_sim::closed_loop::StateSource;
// The run description owns what a controller sees; these are its command-line options.
pub use eemp_rl::run::{state_source, Sensing};

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
}

impl StateSourceArgs {
    /// The run description's part these options fill.
    pub fn sensing(&self) -> Sensing {
        Sensing {
            estimator: self.estimator.clone(),
            ideal_sensors: self.ideal_sensors,
            seed: self.seed,
        }
    }

    pub fn source(&self, robot: &RobotConfig) -> Result<StateSource, String> {
        self.sensing().source(robot)
    }
}
