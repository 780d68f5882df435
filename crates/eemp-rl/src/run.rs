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
use eemp_core::controller::Controller;
use eemp_core::planner::params_table::ParamsTable;
use eemp_core::planner::{Gait, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_core::settings::{key_of, ControllerSettings};
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
}

impl Default for Sensing {
    fn default() -> Self {
        Sensing {
            estimator: "ground-truth".into(),
            ideal_sensors: false,
            seed: 0,
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
        state_source(&self.estimator, self.ideal_sensors, self.seed, robot)
    }
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
/// A policy trained on the filter runs on the filter it was trained on (its config's `[kf]`);
/// a walk's `filter.*` settings apply over it.
pub fn adopt_policy_filter(source: &mut StateSource, policy: &Policy) {
    if policy.config.estimator != TrainEstimator::Kf {
        return;
    }
    if let Some(kf) = source.kf_config_mut() {
        policy.config.kf.apply(kf);
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
    /// A scenario file, applied over the rest.
    pub scenario: Option<PathBuf>,
    pub floor_friction: Option<f64>,
    /// One lateral push: at this time [s], of `push_dv_mps`.
    pub push_at_s: Option<f64>,
    pub push_dv_mps: f64,
    /// Controller settings as `key=value`, applied last, in order, over the gait's and the
    /// robot's defaults (`eemp_core::settings`: `planner.*`, `mpc.*`, `swing.*`, `slip.*`,
    /// `schedule.*`, and `filter.*` on the kf estimator). `eemp config show` lists the keys.
    pub set: Vec<String>,
}

impl Default for WalkDescription {
    fn default() -> Self {
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
            scenario: None,
            floor_friction: None,
            push_at_s: None,
            push_dv_mps: 0.3,
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
    /// The options that choose EEMP's parameters, by their flags, where the run sets them: a
    /// policy walks with the gait, parameters and controller it was trained with (EEMP-RL reads
    /// the table and controller of its config), so for a learned controller they would be
    /// ignored, and are refused.
    fn eemp_options_set(&self) -> Vec<&'static str> {
        let defaults = WalkDescription::default();
        set_flags([
            ("--gait", self.gait != defaults.gait),
            ("--params", self.params.is_some()),
            ("--params-table", self.params_table.is_some()),
            ("--table-ii", self.table_ii),
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
        let planner_options = self.eemp_options_set();
        if !is_eemp && !planner_options.is_empty() {
            return Err(format!(
                "{}: EEMP's gait and parameters are for --controller eemp, not {} (a policy \
                 walks with the gait, parameters and controller it was trained with)",
                planner_options.join(", "),
                self.controller
            ));
        }
        if !(self.duration_s.is_finite() && self.duration_s > 0.0 && self.duration_s <= 3600.0) {
            return Err(format!(
                "--duration {} is out of range: allowed (0, 3600] s",
                self.duration_s
            ));
        }
        let robot = eemp_sim::robot_model::load_robot_or_a1(self.robot.as_deref())
            .map_err(|e| e.to_string())?;
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
        let mut planner = PlannerConfig {
            gait,
            progress_factor: progress_factor(params_table.as_ref()),
            ..PlannerConfig::default()
        };
        // The gait file's values, resolved here so `--set` and `eemp config show` see them.
        planner.ellipse_friction_factor = Some(planner.ellipse_friction_factor_in_force());
        planner.touchdown_friction_factor = Some(planner.touchdown_friction_factor_in_force());
        planner.validate().map_err(|e| e.to_string())?;
        // Named by the options given (the profile's check would name its segment).
        if self.profile.is_none() {
            let given = [
                ("--speed", self.speed_mps, "m/s"),
                ("--lateral", self.lateral_mps, "m/s"),
                ("--yaw-rate", self.yaw_rate_rps, "rad/s"),
            ];
            for ((flag, v, unit), [lo, hi]) in given.into_iter().zip(robot.scale().command_ranges())
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
        spec.seed = self.sensing.seed;
        spec.state_source = self.sensing.source(&robot)?;
        // Settings tuned on the A1 scaled to this robot, under the gait file's and before the
        // robot file's, the scenario's and the run's own (`RobotConfig::settings_scale`).
        if let Some(scale) = robot.settings_scale() {
            let scaled = settings_of(&spec).scaled(&scale)?;
            spec.planner = scaled.planner;
            spec.controller = scaled.controller;
            if let (Some(kf), Some(mine)) = (scaled.filter, spec.state_source.kf_config_mut()) {
                *mine = kf;
            }
            if self.params.is_none() && params_table.is_none() {
                spec.params = spec.params.scaled(&scale);
            }
        }
        spec.allow_robot_mismatch = self.allow_robot_mismatch;
        #[cfg(feature = "learning")]
        if let Driver::Policy(p) = &driver {
            adopt_policy_filter(&mut spec.state_source, p);
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
        spec.controller = spec.controller.clone().with_robot_defaults(&robot);
        let before_sets = (
            spec.planner.progress_factor,
            spec.controller.mpc.friction_coefficient,
        );
        apply_sets(&mut spec, &self.set, is_eemp)?;
        // What a set moved away from the table or above the floor, said (not refused: an
        // experiment may want it).
        if let Some(theirs) = spec.params_table.as_ref().and_then(|t| t.progress_factor) {
            let mine = spec.planner.progress_factor;
            if mine != before_sets.0 && mine != theirs {
                eprintln!(
                    "note: the table was selected with progress factor {theirs}; walking with \
                     planner.progress_factor = {mine} as set"
                );
            }
        }
        let floor = spec
            .floor_friction
            .unwrap_or(robot.simulation.floor_friction);
        let mu = spec.controller.mpc.friction_coefficient;
        if mu != before_sets.1 && mu > floor {
            eprintln!(
                "note: mpc.friction_coefficient {mu} is above the floor's friction {floor}: the \
                 MPC may ask the feet for more than the floor gives"
            );
        }
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
        .find(|s| !is_eemp && !key_of(s).starts_with("filter."))
    {
        return Err(format!(
            "--set {s}: the planner's and the controller's settings are for --controller eemp \
             (a policy walks with the ones it was trained with); only filter.* applies"
        ));
    }
    let settings = settings_of(spec).with_sets(sets)?;
    refuse_ignored(&settings, sets)?;
    spec.planner = settings.planner;
    spec.controller = settings.controller;
    if let (Some(kf), Some(mine)) = (settings.filter, spec.state_source.kf_config_mut()) {
        *mine = kf;
    }
    Ok(())
}

/// Refuses a `set` the run would ignore: a setting of another gait's rule, or of slip handling
/// (or its speed cap, or the walk's support check) where it is off.
fn refuse_ignored(settings: &ControllerSettings, sets: &[String]) -> Result<(), String> {
    let gait = settings.planner.gait;
    let slip = &settings.controller.slip;
    let support = &settings.planner.walk_support;
    for s in sets {
        let key = key_of(s);
        let why = if key.starts_with("planner.walk_support.") && gait != Gait::Walk {
            Some(format!(
                "it is the walk's rule, and this run's gait is {gait}"
            ))
        } else if key.starts_with("planner.free_pairing.") && gait != Gait::Free {
            Some(format!(
                "it is the free gait's rule, and this run's gait is {gait}"
            ))
        } else if key.starts_with("planner.walk_support.")
            && key != "planner.walk_support.check"
            && !support.check
        {
            Some("the walk's support check is off (planner.walk_support.check = false)".into())
        } else if key.starts_with("slip.") && key != "slip.adapt_friction" && !slip.adapt_friction {
            Some("slip handling is off (slip.adapt_friction = false)".into())
        } else if key == "slip.slow_speed_mps" && slip.slow_below_friction <= 0.0 {
            Some(format!(
                "the speed cap on slippery floors is off (slip.slow_below_friction = 0, the \
                 {gait}'s default or as set): set slip.slow_below_friction too"
            ))
        } else {
            None
        };
        if let Some(why) = why {
            return Err(format!("--set {s}: the run would ignore it: {why}"));
        }
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

/// Eq. (6)'s factor of a walk before its `set`: the one the parameter table was selected with
/// (a table's entries are best with the factor they were found with), else the paper's 0.5.
pub fn progress_factor(table: Option<&ParamsTable>) -> f64 {
    table
        .and_then(|t| t.progress_factor)
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
    fn the_progress_factor_comes_from_the_table_then_the_paper() {
        let table = ParamsTable::new(
            Gait::Walk,
            Interpolation::Nearest,
            vec![TableEntry::new(0.3, &PlannerParams::default())],
        )
        .unwrap();
        assert_eq!(progress_factor(None), 0.5);
        assert_eq!(progress_factor(Some(&table)), 0.5);
        let table = table.with_progress_factor(1.5).unwrap();
        assert_eq!(progress_factor(Some(&table)), 1.5);
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
        let sets = |gait: &str, sets: &[&str]| WalkDescription {
            gait: gait.into(),
            set: sets.iter().map(|s| s.to_string()).collect(),
            ..Default::default()
        };
        bad(
            sets("walk", &["planner.walk_support.margin_m=0.1"]),
            "planner.walk_support.margin_m",
        );
        bad(sets("trot", &["slip.slow_speed=0.2"]), "slow_speed");
        // Settings the run would ignore are refused, naming why.
        bad(
            sets("trot", &["planner.walk_support.margin_m=-0.1"]),
            "the walk's rule, and this run's gait is trot",
        );
        bad(
            sets("walk", &["planner.free_pairing.pair_tolerance=0.2"]),
            "the free gait's rule",
        );
        bad(
            sets(
                "walk",
                &["slip.adapt_friction=false", "slip.hold_raise_fraction=0.8"],
            ),
            "slip handling is off",
        );
        bad(
            sets("trot", &["slip.slow_speed_mps=0.2"]),
            "the speed cap on slippery floors is off",
        );
        bad(
            sets(
                "walk",
                &[
                    "planner.walk_support.check=false",
                    "planner.walk_support.margin_m=-0.1",
                ],
            ),
            "support check is off",
        );
        assert!(sets(
            "trot",
            &["slip.slow_below_friction=0.2", "slip.slow_speed_mps=0.2"]
        )
        .build()
        .is_ok());
        let built = sets("walk", &["slip.slow_speed_mps=0.2", "mpc.horizon=12"])
            .build()
            .unwrap();
        assert_eq!(built.spec.controller.slip.slow_speed_mps, 0.2);
        assert_eq!(built.spec.controller.mpc.horizon, 12);
        // A table's progress factor is the default a `set` replaces.
        let built = sets("free", &["planner.progress_factor=1.0"])
            .build()
            .unwrap();
        assert_eq!(built.spec.planner.progress_factor, 1.0);
        #[cfg(feature = "learning")]
        bad(
            WalkDescription {
                controller: "eemp-rl".into(),
                policy: Some(
                    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                        .join("../../policies/a1_eemp_rl.safetensors"),
                ),
                set: vec!["slip.max_speed_mps=0.5".into()],
                ..Default::default()
            },
            "only filter.* applies",
        );
        assert!(toml::from_str::<WalkDescription>("sped_mps = 1").is_err());
    }
}
