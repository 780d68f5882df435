//! `--estimator`, `--ideal-sensors`, `--seed`: what a controller sees, shared by every command
//! that runs the robot.

use eemp_core::estimator::KfConfig;
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
    /// least this large, m/s (`KfConfig::velocity_jump_mps`, default 0.15; 0: off).
    #[arg(long)]
    pub kf_velocity_jump: Option<f64>,
    /// With --estimator kf: fade out a stance leg whose velocity disagrees with the estimate and
    /// with every other stance leg by more than this, m/s (`KfConfig::leg_outlier_mps`, default
    /// 0.15; 0: off).
    #[arg(long)]
    pub kf_leg_outlier: Option<f64>,
}

impl StateSourceArgs {
    pub fn source(&self, robot: &RobotConfig) -> Result<StateSource, String> {
        let mut source = state_source(&self.estimator, self.ideal_sensors, self.seed, robot)?;
        with_kf_options(
            &mut source,
            &self.kf_options(),
            ["--kf-velocity-jump", "--kf-leg-outlier"],
        )?;
        Ok(source)
    }

    pub fn kf_options(&self) -> KfOptions {
        KfOptions {
            velocity_jump_mps: self.kf_velocity_jump,
            leg_outlier_mps: self.kf_leg_outlier,
        }
    }
}

/// Settings of the filter that a command or a suite method may override (`None`: the filter's
/// default).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct KfOptions {
    pub velocity_jump_mps: Option<f64>,
    pub leg_outlier_mps: Option<f64>,
}

/// Applies `options` to the filter (`names` are the options' names, for the errors); refused
/// out of the filter's range, or for a run on ground truth.
pub fn with_kf_options(
    source: &mut StateSource,
    options: &KfOptions,
    names: [&str; 2],
) -> Result<(), String> {
    let given = [options.velocity_jump_mps, options.leg_outlier_mps];
    let Some(kf) = source.kf_config_mut() else {
        return match names.iter().zip(given).find_map(|(n, v)| v.map(|v| (n, v))) {
            Some((name, v)) => Err(format!("{name} {v} needs the kf estimator")),
            None => Ok(()),
        };
    };
    // One option at a time, each checked by the filter's own range and reported under the
    // option's name.
    let setters: [fn(&mut KfConfig, f64); 2] = [
        |kf, v| kf.velocity_jump_mps = v,
        |kf, v| kf.leg_outlier_mps = v,
    ];
    for ((value, name), set) in given.into_iter().zip(names).zip(setters) {
        if let Some(v) = value {
            set(kf, v);
            kf.validate().map_err(|e| format!("{name}: {e}"))?;
        }
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

/// A policy trained on the filter runs on the filter it was trained on (its config's `[kf]`),
/// except for the settings `options` names.
pub fn adopt_policy_filter(
    source: &mut StateSource,
    policy: &eemp_rl::policy::Policy,
    options: &KfOptions,
) {
    if policy.config.estimator != eemp_rl::config::TrainEstimator::Kf {
        return;
    }
    if let Some(kf) = source.kf_config_mut() {
        let (jump, outlier) = (kf.velocity_jump_mps, kf.leg_outlier_mps);
        policy.config.kf.apply(kf);
        // What the options set (already applied and validated) stays.
        if options.velocity_jump_mps.is_some() {
            kf.velocity_jump_mps = jump;
        }
        if options.leg_outlier_mps.is_some() {
            kf.leg_outlier_mps = outlier;
        }
    }
}
