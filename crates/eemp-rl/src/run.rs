//! The one description of a walk by any controller: robot, world, controller (EEMP with its
//! parameters or table, or a trained policy), what it sees, the command and the duration.
//! `eemp walk` fills it from its arguments, the Python package from keyword arguments, a run
//! file from TOML; [`WalkDescription::build`] validates it once and assembles the run, and
//! [`BuiltWalk::run`] drives it through the one closed loop. No command assembles a controller
//! or a state source by hand.
//!
//! Error messages name the options as `eemp walk` spells them (`--duration`), the names a user
//! of the command line and of a run file (whose keys are the fields) both find in `--help`.

#[cfg(feature = "learning")]
use crate::config::{TaskKind, TrainEstimator};
#[cfg(feature = "learning")]
use crate::policy::Policy;
use eemp_core::config_error::load_toml;
use eemp_core::control::Controller;
use eemp_core::estimator::KfConfig;
use eemp_core::planner::params_table::ParamsTable;
use eemp_core::planner::{
    FreePairing, Gait, PlannerConfig, PlannerParams, VelocityCommand, WalkSupport,
};
use eemp_core::robot::RobotConfig;
use eemp_core::settings::ControllerSettings;
use eemp_sim::closed_loop::{Push, StateSource, StepRecord};
use eemp_sim::sensors::SensorNoise;
#[cfg(feature = "learning")]
use eemp_sim::walk::{run_walk_commanded, StartPose};
use eemp_sim::walk::{VelocityProfile, WalkRun, WalkSpec};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// The flags of the options that are set, in order.
fn set_flags<const N: usize>(options: [(&'static str, bool); N]) -> Vec<&'static str> {
    options
        .into_iter()
        .filter_map(|(flag, set)| set.then_some(flag))
        .collect()
}

/// What the controller sees.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Sensing {
    /// `ground-truth` (the simulator's state) or `kf` (the Kalman filter on the simulated IMU
    /// and encoders).
    pub estimator: String,
    /// With `kf`: noise-free sensors without latency.
    pub ideal_sensors: bool,
    /// Seed of the sensor noise and of the start perturbation (0: start at rest).
    pub seed: u64,
    pub kf: KfOptions,
}

impl Default for Sensing {
    fn default() -> Self {
        Sensing {
            estimator: "ground-truth".into(),
            ideal_sensors: false,
            seed: 0,
            kf: KfOptions::default(),
        }
    }
}

impl Sensing {
    pub fn source(&self, robot: &RobotConfig) -> Result<StateSource, String> {
        if self.ideal_sensors && self.estimator != "kf" {
            return Err(format!(
                "--ideal-sensors is for the kf estimator, not {} (ground truth has no sensors)",
                self.estimator
            ));
        }
        let mut source = state_source(&self.estimator, self.ideal_sensors, self.seed, robot)?;
        with_kf_options(
            &mut source,
            &self.kf,
            [
                "--kf-velocity-jump",
                "--kf-dragged-fraction",
                "--kf-leg-outlier",
            ],
        )?;
        Ok(source)
    }
}

/// Settings of the filter that a command or a suite method may override (`None`: the filter's
/// default).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct KfOptions {
    pub velocity_jump_mps: Option<f64>,
    pub velocity_jump_dragged_fraction: Option<f64>,
    pub leg_outlier_mps: Option<f64>,
}

/// Sets one filter setting.
type KfSetter = fn(&mut KfConfig, f64);

impl KfOptions {
    /// Each option with the filter setting it sets, in the order of the options' names.
    fn settings(&self) -> [(Option<f64>, KfSetter); 3] {
        [
            (self.velocity_jump_mps, |kf, v| kf.velocity_jump_mps = v),
            (self.velocity_jump_dragged_fraction, |kf, v| {
                kf.velocity_jump_dragged_fraction = v
            }),
            (self.leg_outlier_mps, |kf, v| kf.leg_outlier_mps = v),
        ]
    }
}

/// Applies `options` to the filter (`names` are the options' names, for the errors); refused
/// out of the filter's range, or for a run on ground truth.
pub fn with_kf_options(
    source: &mut StateSource,
    options: &KfOptions,
    names: [&str; 3],
) -> Result<(), String> {
    let settings = options.settings();
    let Some(kf) = source.kf_config_mut() else {
        let given = settings.iter().map(|(v, _)| *v);
        return match names.iter().zip(given).find_map(|(n, v)| v.map(|v| (n, v))) {
            Some((name, v)) => Err(format!("{name} {v} needs the kf estimator")),
            None => Ok(()),
        };
    };
    // One option at a time, each checked by the filter's own range and reported under the
    // option's name.
    for ((value, set), name) in settings.into_iter().zip(names) {
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
            "unknown estimator '{other}': allowed ground-truth, kf"
        )),
    }
}

#[cfg(feature = "learning")]
/// A policy trained on the filter runs on the filter it was trained on (its config's `[kf]`),
/// except for the settings `options` names.
pub fn adopt_policy_filter(source: &mut StateSource, policy: &Policy, options: &KfOptions) {
    if policy.config.estimator != TrainEstimator::Kf {
        return;
    }
    if let Some(kf) = source.kf_config_mut() {
        policy.config.kf.apply(kf);
        // What the options set (already applied and validated) stays.
        for (value, set) in options.settings() {
            if let Some(v) = value {
                set(kf, v);
            }
        }
    }
}

/// A walk, as files and values. Field names follow `eemp walk`'s options.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WalkDescription {
    /// The robot file (none: the shipped A1).
    pub robot: Option<PathBuf>,
    /// Run tables and policies made for another robot.
    pub allow_robot_mismatch: bool,
    /// `eemp`, `model-free`, `imitation` or `eemp-rl`.
    pub controller: String,
    /// The policy file of a learned controller.
    pub policy: Option<PathBuf>,
    pub sensing: Sensing,
    /// `trot`, `walk` or `free` (EEMP).
    pub gait: String,
    pub speed_mps: f64,
    pub lateral_mps: f64,
    pub yaw_rate_rps: f64,
    /// A velocity profile file in place of the constant command.
    pub profile: Option<PathBuf>,
    pub duration_s: f64,
    /// Constant planner parameters. Without them or `params_table`, EEMP walks on the robot's
    /// shipped per-speed table of the gait (`tables/<robot>_<gait>.toml`, relative to the
    /// working folder) as every other command does, or on Table II where there is none.
    pub params: Option<PathBuf>,
    /// A per-speed parameter table in place of `params`.
    pub params_table: Option<PathBuf>,
    /// Walk on the paper's Table II constants rather than the shipped table.
    pub table_ii: bool,
    /// Eq. (6)'s factor (default: the table's, else the paper's 0.5).
    pub progress_factor: Option<f64>,
    pub retarget_swing: bool,
    pub first_step_on_command: bool,
    pub preview_swings: bool,
    pub max_accel_mps2: f64,
    /// `PlannerConfig::ellipse_friction_factor` (0: the ellipses ignore the slip detector;
    /// None: the gait's).
    pub ellipse_friction_factor: Option<f64>,
    /// `PlannerConfig::touchdown_friction_factor` (0: eq. (6)'s capture step unbounded; None:
    /// the gait's).
    pub touchdown_friction_factor: Option<f64>,
    /// A scenario file, applied over the rest.
    pub scenario: Option<PathBuf>,
    pub floor_friction: Option<f64>,
    /// One lateral push: at this time [s], of `push_dv_mps`.
    pub push_at_s: Option<f64>,
    pub push_dv_mps: f64,
    pub mpc_friction: Option<f64>,
    pub mpc_horizon: Option<usize>,
    pub mpc_period_s: f64,
    /// `Some(false)`: no slip handling; `Some(true)`: on whatever the gait; `None`: the gait's
    /// default.
    pub adapt_friction: Option<bool>,
    /// With slip handling: the coefficient it starts from (`slip.initial_friction`).
    pub initial_friction: Option<f64>,
    /// With slip handling: the coefficient's floor (`slip.min_friction`; default: the gait's).
    pub min_friction: Option<f64>,
    /// With slip handling: the cap on raises after a slip (`slip.hold_cap_after_slip`; 0: off).
    pub hold_cap_after_slip: Option<f64>,
    /// With slip handling: the fraction of the asked ratio a hold raises the coefficient to
    /// (`slip.hold_raise_fraction`, 0.1–1; default: the gait's, 0.8 for the trot and the free
    /// gait, 1 for the walk).
    pub hold_raise_fraction: Option<f64>,
    /// With slip handling: the planner's reference speed above which it rests at the nominal
    /// coefficient, m/s (`slip.max_speed_mps`; 0: no limit; default: the gait's, the walk's
    /// 0.6).
    pub slip_max_speed_mps: Option<f64>,
    /// With slip handling: the coefficient below which the command's speed is capped for a
    /// floor found slippery (`slip.slow_below_friction`; 0: never; default: the gait's, the
    /// walk's 0.205).
    pub slow_below_friction: Option<f64>,
    /// With slip handling: that cap, m/s (`slip.slow_speed_mps`; default 0.3).
    pub slow_speed_mps: Option<f64>,
    pub free_pair_tolerance: Option<f64>,
    pub free_support_margin_m: Option<f64>,
    /// Whether the free gait's support rule applies (`FreePairing::support_check`).
    pub free_support_check: Option<bool>,
    pub free_unpaired: bool,
    /// The walk: how far inside the other feet's triangle the capture point must lie for the
    /// next leg of its order to swing, m (`WalkSupport::margin_m`; None: the default).
    pub walk_support_margin_m: Option<f64>,
    /// The walk: whether that check applies (`WalkSupport::check`; None: the default, on).
    pub walk_support_check: Option<bool>,
    /// The walk: the commanded speed from which that check is off, m/s
    /// (`WalkSupport::max_speed_mps`; 0: none; None: the default, 0.6).
    pub walk_support_max_speed_mps: Option<f64>,
    /// Controller settings as `key=value`, applied last, in order, over everything above
    /// (`eemp_core::settings`: `planner.*`, `mpc.*`, `swing.*`, `slip.*`, `schedule.*`, and
    /// `filter.*` on the kf estimator). `eemp config show` lists the keys.
    pub set: Vec<String>,
}

impl Default for WalkDescription {
    fn default() -> Self {
        let planner = PlannerConfig::default();
        WalkDescription {
            robot: None,
            allow_robot_mismatch: false,
            controller: "eemp".into(),
            policy: None,
            sensing: Sensing::default(),
            gait: "trot".into(),
            speed_mps: 0.3,
            lateral_mps: 0.0,
            yaw_rate_rps: 0.0,
            profile: None,
            duration_s: 20.0,
            params: None,
            params_table: None,
            table_ii: false,
            progress_factor: None,
            retarget_swing: planner.retarget_swing,
            first_step_on_command: planner.first_step_on_command,
            preview_swings: planner.preview_swings,
            max_accel_mps2: planner.max_accel_mps2,
            ellipse_friction_factor: planner.ellipse_friction_factor,
            touchdown_friction_factor: planner.touchdown_friction_factor,
            scenario: None,
            floor_friction: None,
            push_at_s: None,
            push_dv_mps: 0.3,
            mpc_friction: None,
            mpc_horizon: None,
            mpc_period_s: eemp_core::controller::ControllerConfig::default().mpc_period_s,
            adapt_friction: None,
            initial_friction: None,
            min_friction: None,
            hold_cap_after_slip: None,
            hold_raise_fraction: None,
            slip_max_speed_mps: None,
            slow_below_friction: None,
            slow_speed_mps: None,
            free_pair_tolerance: None,
            free_support_margin_m: None,
            free_support_check: None,
            free_unpaired: false,
            walk_support_margin_m: None,
            walk_support_check: None,
            walk_support_max_speed_mps: None,
            set: Vec::new(),
        }
    }
}

/// Which controller a walk runs.
pub enum Driver {
    Eemp,
    /// A trained policy (model-free, imitation or EEMP-RL).
    #[cfg(feature = "learning")]
    Policy(Box<Policy>),
}

/// A validated walk, ready to run.
pub struct BuiltWalk {
    pub robot: RobotConfig,
    pub spec: WalkSpec,
    pub driver: Driver,
    pub gait: Gait,
    /// The constant parameters given (`params`, or Table II).
    pub params: PlannerParams,
    /// The per-speed table EEMP walks on (`params_table`, or the shipped one), if any.
    pub params_table_path: Option<PathBuf>,
}

impl WalkDescription {
    /// The options of slip handling's own settings the run sets (not whether it is on), by
    /// their flags: the one list both refusals name.
    fn slip_settings_set(&self) -> Vec<&'static str> {
        set_flags([
            ("--initial-friction", self.initial_friction.is_some()),
            ("--min-friction", self.min_friction.is_some()),
            ("--hold-cap-after-slip", self.hold_cap_after_slip.is_some()),
            ("--hold-raise-fraction", self.hold_raise_fraction.is_some()),
            ("--slip-max-speed", self.slip_max_speed_mps.is_some()),
            ("--slow-below-friction", self.slow_below_friction.is_some()),
            ("--slow-speed", self.slow_speed_mps.is_some()),
        ])
    }

    /// The planner's and the MPC's options the run sets away from their defaults, by their
    /// flags: a policy runs the gait, parameters, planner and MPC it was trained with (EEMP-RL
    /// reads the table and controller of its config), so for a learned controller they would be
    /// ignored, and are refused.
    fn eemp_options_set(&self) -> Vec<&'static str> {
        let defaults = WalkDescription::default();
        set_flags([
            ("--gait", self.gait != defaults.gait),
            ("--params", self.params.is_some()),
            ("--params-table", self.params_table.is_some()),
            ("--table-ii", self.table_ii),
            ("--progress-factor", self.progress_factor.is_some()),
            (
                "--retarget-swing",
                self.retarget_swing != defaults.retarget_swing,
            ),
            (
                "--first-step-on-command",
                self.first_step_on_command != defaults.first_step_on_command,
            ),
            (
                "--preview-swings",
                self.preview_swings != defaults.preview_swings,
            ),
            (
                "--max-accel",
                self.max_accel_mps2 != defaults.max_accel_mps2,
            ),
            (
                "--ellipse-friction-factor",
                self.ellipse_friction_factor.is_some(),
            ),
            (
                "--touchdown-friction-factor",
                self.touchdown_friction_factor.is_some(),
            ),
            ("--mpc-friction", self.mpc_friction.is_some()),
            ("--mpc-horizon", self.mpc_horizon.is_some()),
            ("--mpc-period", self.mpc_period_s != defaults.mpc_period_s),
        ])
    }

    /// Validates everything and assembles the run; an error names the option and its range.
    pub fn build(&self) -> Result<BuiltWalk, String> {
        let gait: Gait = self.gait.parse()?;
        let is_eemp = self.controller == "eemp";
        let driver = match (self.controller.as_str(), &self.policy) {
            ("eemp", None) => Driver::Eemp,
            ("eemp", Some(_)) => {
                return Err(
                    "--policy is for a learned --controller (model-free, imitation, eemp-rl), \
                     not eemp"
                        .into(),
                )
            }
            (c @ ("model-free" | "imitation" | "eemp-rl"), Some(p)) => learned_driver(c, p)?,
            (c @ ("model-free" | "imitation" | "eemp-rl"), None) => {
                return Err(format!(
                    "--controller {c} needs --policy FILE (e.g. policies/a1_{}.safetensors)",
                    c.replace('-', "_")
                ))
            }
            (other, _) => {
                return Err(format!(
                    "unknown --controller '{other}': allowed eemp, model-free, imitation, eemp-rl"
                ))
            }
        };
        let free_flags = self.free_unpaired
            || self.free_pair_tolerance.is_some()
            || self.free_support_margin_m.is_some()
            || self.free_support_check.is_some();
        if free_flags && (!is_eemp || gait != Gait::Free) {
            return Err(format!(
                "--free-unpaired, --free-pair-tolerance and --free-support-margin are for \
                 --controller eemp --gait free, not --controller {} --gait {gait} (EEMP-RL runs \
                 the rule it was trained with)",
                self.controller
            ));
        }
        // The walk's support-check options the run sets, named as given.
        let walk_tuning = set_flags([
            (
                "--walk-support-margin",
                self.walk_support_margin_m.is_some(),
            ),
            (
                "--walk-support-max-speed",
                self.walk_support_max_speed_mps.is_some(),
            ),
        ]);
        let walk_switch = self.walk_support_check.map(|on| match on {
            true => "walk_support.check = true",
            false => "--no-walk-support",
        });
        if (!walk_tuning.is_empty() || walk_switch.is_some()) && (!is_eemp || gait != Gait::Walk) {
            return Err(format!(
                "{}: the walk's support-check options are for --controller eemp --gait walk, \
                 not --controller {} --gait {gait}",
                walk_tuning
                    .iter()
                    .copied()
                    .chain(walk_switch)
                    .collect::<Vec<_>>()
                    .join(", "),
                self.controller
            ));
        }
        if self.walk_support_check == Some(false) && !walk_tuning.is_empty() {
            return Err(format!(
                "{}: the walk's support check is off (--no-walk-support or walk_support.check = \
                 false): drop one or the other",
                walk_tuning.join(", ")
            ));
        }
        let planner_options = self.eemp_options_set();
        if !is_eemp && !planner_options.is_empty() {
            return Err(format!(
                "{}: the planner's and the MPC's options are for --controller eemp, not {} (a \
                 policy walks with the gait, parameters and controller it was trained with)",
                planner_options.join(", "),
                self.controller
            ));
        }
        let slip_settings = self.slip_settings_set();
        if (self.adapt_friction.is_some() || !slip_settings.is_empty()) && !is_eemp {
            let switch = self.adapt_friction.map(|on| match on {
                true => "--adapt-friction",
                false => "--no-adapt-friction",
            });
            return Err(format!(
                "{}: slip handling is for --controller eemp, not {} (a policy runs with the \
                 controller it was trained with)",
                switch
                    .into_iter()
                    .chain(slip_settings.iter().copied())
                    .collect::<Vec<_>>()
                    .join(", "),
                self.controller
            ));
        }
        if !(self.duration_s.is_finite() && self.duration_s > 0.0 && self.duration_s <= 3600.0) {
            return Err(format!(
                "--duration {} is out of range: allowed (0, 3600] s",
                self.duration_s
            ));
        }
        let robot = RobotConfig::load_or_a1(self.robot.as_deref()).map_err(|e| e.to_string())?;
        #[cfg(feature = "learning")]
        let driver = match driver {
            Driver::Policy(mut p) => {
                p.allow_robot_mismatch = self.allow_robot_mismatch;
                p.check_robot(&robot)?;
                Driver::Policy(p)
            }
            d => d,
        };
        let params: PlannerParams = match &self.params {
            Some(p) => load_toml(p).map_err(|e| e.to_string())?,
            None => PlannerParams::default(),
        };
        if self.params.is_some() {
            robot
                .check_body_height("--params body_height_m", params.body_height_m)
                .map_err(|e| e.to_string())?;
        }
        if self.table_ii && (self.params.is_some() || self.params_table.is_some()) {
            return Err(
                "--table-ii asks for Table II's constants: drop --params / --params-table \
                        (or --table-ii)"
                    .into(),
            );
        }
        let params_table_path = match (&self.params, &self.params_table) {
            (None, None) if is_eemp && !self.table_ii => {
                let shipped = robot.shipped_table_path(gait);
                if shipped.exists() {
                    Some(shipped)
                } else {
                    eprintln!(
                        "note: no {} in this folder: walking on Table II's constants (run from \
                         the repository, give --params-table FILE, or --table-ii to say so)",
                        shipped.display()
                    );
                    None
                }
            }
            (_, t) => t.clone(),
        };
        let shipped_by_default = self.params.is_none() && self.params_table.is_none();
        let params_table = match &params_table_path {
            Some(p) => {
                let t = ParamsTable::load(p).map_err(|e| e.to_string())?;
                if t.gait != gait {
                    return Err(format!(
                        "{}: is a table for gait {} but the walk uses {gait} (give --gait {} or \
                         another table)",
                        p.display(),
                        t.gait,
                        t.gait
                    ));
                }
                for e in &t.entries {
                    robot
                        .check_body_height(
                            &format!(
                                "{}: the {} m/s entry's body_height_m",
                                p.display(),
                                e.speed_mps
                            ),
                            e.body_height_m,
                        )
                        .map_err(|e| e.to_string())?;
                }
                if !self.allow_robot_mismatch {
                    t.robot_id()
                        .check(&robot, &p.display().to_string())
                        .map_err(|e| match shipped_by_default {
                            true => format!(
                                "{e} (the default table of a robot named '{}'; --table-ii or \
                                 --params-table FILE walks without it)",
                                robot.name
                            ),
                            false => e,
                        })?;
                }
                Some(t)
            }
            None => None,
        };
        // Outside its speeds a table walks on its end entry (`ParamsTable::lookup`): say so
        // where the command asks for more than it was selected for.
        if let (Some(t), None) = (&params_table, &self.profile) {
            let speed = self.speed_mps.hypot(self.lateral_mps);
            if let Some(last) = t.entries.last().filter(|e| speed > e.speed_mps + 1e-9) {
                eprintln!(
                    "note: the command's speed {speed} m/s is above the table's last entry \
                     ({} m/s): walking on that entry's parameters",
                    last.speed_mps
                );
            }
        }
        if let Some(f) = self.progress_factor {
            let [lo, hi] = eemp_core::planner::PROGRESS_FACTOR_RANGE;
            if !(f.is_finite() && (lo..=hi).contains(&f)) {
                return Err(format!(
                    "--progress-factor {f} is out of range: allowed [{lo}, {hi}] (0.5 = the \
                     paper's eq. 6, 1 = its Algorithm 1)"
                ));
            }
            if let Some(theirs) = params_table.as_ref().and_then(|t| t.progress_factor) {
                if theirs != f {
                    eprintln!(
                        "note: --params-table was selected with progress factor {theirs}; \
                         walking with --progress-factor {f} as asked"
                    );
                }
            }
        }
        let planner = PlannerConfig {
            gait,
            progress_factor: progress_factor(self.progress_factor, params_table.as_ref()),
            retarget_swing: self.retarget_swing,
            max_accel_mps2: self.max_accel_mps2,
            preview_swings: self.preview_swings,
            free_pairing: self.free_pairing(),
            walk_support: self.walk_support(),
            first_step_on_command: self.first_step_on_command,
            ellipse_friction_factor: self.ellipse_friction_factor,
            touchdown_friction_factor: self.touchdown_friction_factor,
        };
        planner.validate().map_err(|e| e.to_string())?;
        // Named by the options given (the profile's check would name its segment).
        if self.profile.is_none() {
            let given = [
                ("--speed", self.speed_mps, "m/s"),
                ("--lateral", self.lateral_mps, "m/s"),
                ("--yaw-rate", self.yaw_rate_rps, "rad/s"),
            ];
            for ((flag, v, unit), [lo, hi]) in given.into_iter().zip(eemp_sim::walk::COMMAND_RANGES)
            {
                if !(v.is_finite() && (lo..=hi).contains(&v)) {
                    return Err(format!(
                        "{flag} {v} is out of range: allowed [{lo}, {hi}] {unit}"
                    ));
                }
            }
        }
        let command = VelocityCommand {
            vx_mps: self.speed_mps,
            vy_mps: self.lateral_mps,
            yaw_rate_rps: self.yaw_rate_rps,
        };
        let mut spec = WalkSpec::constant(planner, params, command, self.duration_s);
        if let Some(p) = &self.profile {
            spec.profile = load_toml::<VelocityProfile>(p).map_err(|e| e.to_string())?;
        }
        spec.controller.mpc_period_s = self.mpc_period_s;
        if let Some(h) = self.mpc_horizon {
            spec.controller.mpc.horizon = h;
        }
        if let Some(mu) = self.mpc_friction {
            spec.controller.mpc.friction_coefficient = mu;
        }
        if let Some(on) = self.adapt_friction {
            spec.controller.slip.adapt_friction = on;
        }
        if let Some(mu) = self.initial_friction {
            spec.controller.slip.initial_friction = Some(mu);
        }
        if let Some(mu) = self.min_friction {
            spec.controller.slip.min_friction = mu;
        }
        if let Some(cap) = self.hold_cap_after_slip {
            spec.controller.slip.hold_cap_after_slip = cap;
        }
        if let Some(k) = self.hold_raise_fraction {
            spec.controller.slip.hold_raise_fraction = k;
        }
        if let Some(v) = self.slip_max_speed_mps {
            spec.controller.slip.max_speed_mps = v;
        }
        if let Some(mu) = self.slow_below_friction {
            spec.controller.slip.slow_below_friction = mu;
        }
        if let Some(v) = self.slow_speed_mps {
            spec.controller.slip.slow_speed_mps = v;
        }
        // Settings of slip handling where it is off would be silently ignored.
        if !spec.controller.slip.adapt_friction && !slip_settings.is_empty() {
            return Err(format!(
                "{}: slip handling is off for this walk (--gait {gait}, --no-adapt-friction or \
                 a suite method's adapt_friction = false): drop one or the other",
                slip_settings.join(", ")
            ));
        }
        // So would a cap speed where the cap never comes on.
        if self.slow_speed_mps.is_some() && spec.controller.slip.slow_below_friction <= 0.0 {
            return Err(format!(
                "--slow-speed: the speed cap on slippery floors is off for this walk \
                 (slip.slow_below_friction = 0, the {gait}'s default or as given): set \
                 --slow-below-friction too (allowed: (0.15, 0.25]), or drop --slow-speed"
            ));
        }
        spec.seed = self.sensing.seed;
        spec.state_source = self.sensing.source(&robot)?;
        spec.allow_robot_mismatch = self.allow_robot_mismatch;
        #[cfg(feature = "learning")]
        if let Driver::Policy(p) = &driver {
            adopt_policy_filter(&mut spec.state_source, p, &self.sensing.kf);
        }
        spec.floor_friction = self.floor_friction;
        if let Some(path) = &self.scenario {
            let sc = eemp_sim::scenario::Scenario::load(path).map_err(|e| e.to_string())?;
            if let (Some(mu), Some(theirs)) = (self.floor_friction, sc.floor_friction) {
                return Err(format!(
                    "--friction {mu} and the scenario {}'s floor_friction {theirs} both set the \
                     floor: drop one",
                    path.display()
                ));
            }
            if self.sensing.ideal_sensors && sc.sensors.is_some() {
                return Err(format!(
                    "--ideal-sensors and the scenario {}'s [sensors] both set the sensor noise: \
                     drop one",
                    path.display()
                ));
            }
            sc.apply(&mut spec);
            if let Some(noise) = &sc.sensors {
                if let StateSource::Kf { sensors, .. } = &mut spec.state_source {
                    *sensors = noise.clone();
                }
            }
        }
        spec.params_table = params_table;
        // The floor the walk gets (option, scenario or robot file; patches aside).
        let floor = spec
            .floor_friction
            .unwrap_or(robot.simulation.floor_friction);
        if let Some(mu) = self.mpc_friction.filter(|mu| *mu > floor) {
            eprintln!(
                "note: --mpc-friction {mu} is above the floor's friction {floor}: the MPC may ask \
                 the feet for more than the floor gives"
            );
        }
        if self.push_at_s.is_none() && self.push_dv_mps != WalkDescription::default().push_dv_mps {
            return Err(format!(
                "--push-dv {} needs --push-at (the time of the push)",
                self.push_dv_mps
            ));
        }
        if let Some(at) = self.push_at_s {
            if !(at.is_finite() && at >= 0.0 && at < self.duration_s) {
                return Err(format!(
                    "--push-at {at} is out of range: allowed [0, duration {})",
                    self.duration_s
                ));
            }
            spec.pushes
                .push(Push::step(at, Vector3::new(0.0, self.push_dv_mps, 0.0)));
        }
        // The robot file's defaults, resolved here so `--set` and `eemp config show` see them.
        if spec.controller.mpc.weight_heat.is_none() {
            spec.controller.mpc.weight_heat = Some(robot.control.mpc_weight_heat.unwrap_or(0.0));
        }
        apply_sets(&mut spec, &self.set, is_eemp)?;
        spec.validate().map_err(|e| e.to_string())?;
        Ok(BuiltWalk {
            robot,
            spec,
            driver,
            gait,
            params,
            params_table_path,
        })
    }

    fn walk_support(&self) -> WalkSupport {
        let mut w = WalkSupport::default();
        if let Some(m) = self.walk_support_margin_m {
            w.margin_m = m;
        }
        if let Some(c) = self.walk_support_check {
            w.check = c;
        }
        if let Some(v) = self.walk_support_max_speed_mps {
            w.max_speed_mps = v;
        }
        w
    }

    fn free_pairing(&self) -> FreePairing {
        if self.free_unpaired {
            return FreePairing::UNPAIRED;
        }
        let mut p = FreePairing::default();
        if let Some(t) = self.free_pair_tolerance {
            p.pair_tolerance = t;
        }
        if let Some(m) = self.free_support_margin_m {
            p.support_margin_m = m;
        }
        if let Some(c) = self.free_support_check {
            p.support_check = c;
        }
        p
    }
}

/// The controller settings a walk runs with (planner, MPC, swing, slip, schedule, filter).
pub fn settings_of(spec: &WalkSpec) -> ControllerSettings {
    ControllerSettings {
        planner: spec.planner.clone(),
        controller: spec.controller.clone(),
        filter: spec.state_source.kf_config().cloned(),
    }
}

/// Applies `sets` (`key=value`) to the walk's settings; a learned controller takes only the
/// filter's (it walks with the planner and controller it was trained with).
fn apply_sets(spec: &mut WalkSpec, sets: &[String], is_eemp: bool) -> Result<(), String> {
    if sets.is_empty() {
        return Ok(());
    }
    if let Some(s) = sets
        .iter()
        .find(|s| !is_eemp && !s.trim_start().starts_with("filter."))
    {
        return Err(format!(
            "--set {s}: the planner's and the controller's settings are for --controller eemp \
             (a policy walks with the ones it was trained with); only filter.* applies"
        ));
    }
    let settings = settings_of(spec).with_sets(sets)?;
    spec.planner = settings.planner;
    spec.controller = settings.controller;
    if let (Some(kf), Some(mine)) = (settings.filter, spec.state_source.kf_config_mut()) {
        *mine = kf;
    }
    Ok(())
}

/// The trained policy a learned `--controller` runs.
#[cfg(feature = "learning")]
fn learned_driver(controller: &str, policy: &std::path::Path) -> Result<Driver, String> {
    Ok(Driver::Policy(Box::new(Policy::load(
        policy,
        Some(controller.parse()?),
    )?)))
}

/// A build without the `learning` feature (`make demo`'s) has no policies to run.
#[cfg(not(feature = "learning"))]
fn learned_driver(controller: &str, _policy: &std::path::Path) -> Result<Driver, String> {
    Err(format!(
        "--controller {controller} runs a trained policy, and this eemp was built without \
         policies (`--no-default-features`, as `make demo` builds it): build the whole \
         command with `cargo build --release -p eemp-cli`"
    ))
}

/// Checks what a walk's build checks of a learned `controller`'s `policy`: the file is a policy
/// of that kind, trained on `robot` (unless `allow_robot_mismatch`). For suites, before any run.
#[cfg(feature = "learning")]
pub fn check_policy(
    controller: &str,
    policy: &std::path::Path,
    robot: &RobotConfig,
    allow_robot_mismatch: bool,
) -> Result<(), String> {
    let mut p = Policy::load(policy, Some(controller.parse()?))?;
    p.allow_robot_mismatch = allow_robot_mismatch;
    p.check_robot(robot)
}

/// Without the `learning` feature no policy runs: says so.
#[cfg(not(feature = "learning"))]
pub fn check_policy(
    controller: &str,
    policy: &std::path::Path,
    _robot: &RobotConfig,
    _allow_robot_mismatch: bool,
) -> Result<(), String> {
    learned_driver(controller, policy).map(|_| ())
}

/// Eq. (6)'s factor of a walk: the one given, else the one the parameter table was selected
/// with (a table's entries are best with the factor they were found with), else the paper's 0.5.
pub fn progress_factor(given: Option<f64>, table: Option<&ParamsTable>) -> f64 {
    given
        .or_else(|| table.and_then(|t| t.progress_factor))
        .unwrap_or(eemp_core::planner::PAPER_PROGRESS_FACTOR)
}

impl BuiltWalk {
    /// The method's name in figures and reports: `EEMP (trot)`, `EEMP-RL`, `model-free RL`, ….
    pub fn method(&self) -> String {
        match &self.driver {
            Driver::Eemp => format!("EEMP ({})", self.gait),
            #[cfg(feature = "learning")]
            Driver::Policy(p) => match p.config.task {
                TaskKind::EempRl => "EEMP-RL".into(),
                TaskKind::Imitation => "motion imitation".into(),
                _ => "model-free RL".into(),
            },
        }
    }

    /// The walk's controller for a loop of the caller's own stepping at `timestep_s` (the
    /// hardware runner's), built as [`BuiltWalk::run`] builds it for the simulation.
    #[cfg_attr(not(feature = "learning"), allow(unused_variables))]
    pub fn into_controller(self, timestep_s: f64) -> Result<Box<dyn Controller>, String> {
        let robot = &self.robot;
        match self.driver {
            Driver::Eemp => Ok(Box::new(
                eemp_sim::walk::eemp_controller(robot, &self.spec).map_err(|e| e.to_string())?,
            )),
            #[cfg(feature = "learning")]
            Driver::Policy(policy) if policy.config.task == TaskKind::EempRl => {
                use crate::tasks::eemp_rl::EempRlController;
                let cfg = policy.config.eemp_rl.clone();
                Ok(Box::new(EempRlController::new(robot, cfg, *policy)?))
            }
            #[cfg(feature = "learning")]
            Driver::Policy(policy) => Ok(Box::new(crate::controller::PolicyController::new(
                *policy, robot, timestep_s,
            )?)),
        }
    }

    /// Runs the walk through the one closed loop, `observer` seeing every step.
    pub fn run(self, observer: impl FnMut(&StepRecord)) -> Result<WalkRun, String> {
        let profile = self.spec.profile.clone();
        self.run_commanded(&mut |t| profile.command_at(t), observer)
    }

    /// [`BuiltWalk::run`] with the command from `command_at(t)` at every step in place of the
    /// description's speed or profile: an operator (`eemp teleop`). The start is the one of
    /// the description's first command.
    pub fn run_commanded(
        self,
        command_at: &mut dyn FnMut(f64) -> VelocityCommand,
        observer: impl FnMut(&StepRecord),
    ) -> Result<WalkRun, String> {
        let (robot, spec) = (&self.robot, &self.spec);
        spec.validate().map_err(|e| e.to_string())?;
        match self.driver {
            Driver::Eemp => {
                eemp_sim::walk::run_walk_eemp_commanded(robot, spec, command_at, observer)
                    .map_err(|e| e.to_string())
            }
            #[cfg(feature = "learning")]
            Driver::Policy(policy) if policy.config.task == TaskKind::EempRl => {
                use crate::tasks::eemp_rl::EempRlController;
                let cfg = policy.config.eemp_rl.clone();
                let start = EempRlController::<Policy>::start_pose(
                    robot,
                    &cfg,
                    spec.profile.first_speed_mps(),
                )?;
                let mut c = EempRlController::new(robot, cfg, *policy)?;
                run_walk_commanded(robot, spec, &start, &mut c, command_at, observer)
                    .map_err(|e| e.to_string())
            }
            #[cfg(feature = "learning")]
            Driver::Policy(policy) => {
                let mut c = crate::controller::PolicyController::new(
                    *policy,
                    robot,
                    robot.simulation.timestep_s,
                )?;
                let start = StartPose::from_joints(robot, c.default_pose());
                let run = run_walk_commanded(robot, spec, &start, &mut c, command_at, observer)
                    .map_err(|e| e.to_string())?;
                if c.invalid_steps > 0 {
                    eprintln!(
                        "warning: {} policy steps had a non-finite observation or action \
                         (targets held)",
                        c.invalid_steps
                    );
                }
                Ok(run)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use eemp_core::planner::params_table::{Interpolation, TableEntry};

    #[test]
    fn the_progress_factor_comes_from_the_option_then_the_table_then_the_paper() {
        let table = ParamsTable::new(
            Gait::Walk,
            Interpolation::Nearest,
            vec![TableEntry::new(0.3, &PlannerParams::default())],
        )
        .unwrap();
        assert_eq!(progress_factor(None, None), 0.5);
        assert_eq!(progress_factor(None, Some(&table)), 0.5);
        let table = table.with_progress_factor(1.5).unwrap();
        assert_eq!(progress_factor(None, Some(&table)), 1.5);
        assert_eq!(progress_factor(Some(1.0), Some(&table)), 1.0);
    }

    #[test]
    fn a_run_file_is_the_same_description_and_bad_values_name_the_option() {
        let d: WalkDescription =
            toml::from_str("gait = \"free\"\nspeed_mps = 0.5\n[sensing]\nestimator = \"kf\"\n")
                .unwrap();
        assert_eq!(d.gait, "free");
        assert_eq!(d.speed_mps, 0.5);
        assert_eq!(d.duration_s, WalkDescription::default().duration_s);
        let built = d.build().unwrap();
        assert!(matches!(built.spec.state_source, StateSource::Kf { .. }));
        assert_eq!(built.method(), "EEMP (free)");
        let bad = |d: WalkDescription, says: &str| {
            let e = d.build().err().expect("refused");
            assert!(e.contains(says), "{e}");
        };
        bad(
            WalkDescription {
                duration_s: f64::NAN,
                ..Default::default()
            },
            "--duration NaN is out of range",
        );
        bad(
            WalkDescription {
                controller: "model-free".into(),
                ..Default::default()
            },
            "needs --policy",
        );
        bad(
            WalkDescription {
                free_unpaired: true,
                ..Default::default()
            },
            "are for --controller eemp --gait free",
        );
        bad(
            WalkDescription {
                walk_support_margin_m: Some(-0.05),
                ..Default::default()
            },
            "are for --controller eemp --gait walk, not --controller eemp --gait trot",
        );
        bad(
            WalkDescription {
                gait: "walk".into(),
                walk_support_margin_m: Some(-0.05),
                walk_support_check: Some(false),
                ..Default::default()
            },
            "the walk's support check is off",
        );
        bad(
            WalkDescription {
                gait: "walk".into(),
                walk_support_margin_m: Some(0.1),
                ..Default::default()
            },
            "planner.walk_support.margin_m",
        );
        // Slip handling's settings are named as given, where it is off and for a policy.
        bad(
            WalkDescription {
                adapt_friction: Some(false),
                hold_raise_fraction: Some(0.8),
                slip_max_speed_mps: Some(0.5),
                ..Default::default()
            },
            "--hold-raise-fraction, --slip-max-speed: slip handling is off for this walk",
        );
        // A cap speed where the cap is off (the trot's default) would be ignored.
        bad(
            WalkDescription {
                slow_speed_mps: Some(0.2),
                ..Default::default()
            },
            "--slow-speed: the speed cap on slippery floors is off for this walk",
        );
        assert!(WalkDescription {
            slow_speed_mps: Some(0.2),
            slow_below_friction: Some(0.2),
            ..Default::default()
        }
        .build()
        .is_ok());
        #[cfg(feature = "learning")]
        bad(
            WalkDescription {
                controller: "eemp-rl".into(),
                policy: Some(
                    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                        .join("../../policies/a1_eemp_rl.safetensors"),
                ),
                slip_max_speed_mps: Some(0.5),
                ..Default::default()
            },
            "--slip-max-speed: slip handling is for --controller eemp, not eemp-rl",
        );
        assert!(toml::from_str::<WalkDescription>("sped_mps = 1").is_err());
    }
}
