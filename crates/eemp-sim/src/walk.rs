//! The walking scenario: the A1 starts standing at X_z and walks under EEMP at the commanded
//! velocity (constant or a piecewise profile).

use crate::backend::Simulation;
use crate::closed_loop::{
    run_closed_loop, ClosedLoop, EstimationStats, LoopStats, Push, StateSource, StepRecord,
};
use crate::mjcf::SceneExtras;
use crate::stand::ScenarioError;
use crate::terrain::Terrain;
use eemp_core::config_error::{check_range, ConfigError};
use eemp_core::controller::Controller;
use eemp_core::eemp::{EempController, ParamsSource};
use eemp_core::gait_measure::{GaitMeasure, GaitMeter};
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::locomotion::{ControllerConfig, LocomotionController};
use eemp_core::metrics::{MetricsAccumulator, WalkMetrics};
use eemp_core::planner::params_table::ParamsTable;
use eemp_core::planner::{EemPlanner, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// One piece of a velocity profile: hold `command` from `start_s` on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProfileSegment {
    pub start_s: f64,
    #[serde(default)]
    pub vx_mps: f64,
    #[serde(default)]
    pub vy_mps: f64,
    #[serde(default)]
    pub yaw_rate_rps: f64,
}

/// Piecewise-constant commands over time (a file: `[[segment]]` tables with `start_s`, `vx_mps`,
/// `vy_mps`, `yaw_rate_rps`). Before the first segment the command is zero.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VelocityProfile {
    #[serde(rename = "segment")]
    pub segments: Vec<ProfileSegment>,
}

impl VelocityProfile {
    /// A constant command from `start_s` on.
    pub fn constant(start_s: f64, command: VelocityCommand) -> Self {
        VelocityProfile {
            segments: vec![ProfileSegment {
                start_s,
                vx_mps: command.vx_mps,
                vy_mps: command.vy_mps,
                yaw_rate_rps: command.yaw_rate_rps,
            }],
        }
    }

    /// The profile's structure and finite commands (a run checks them against its robot's
    /// ranges, [`VelocityProfile::validate_within`]).
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.validate_within([[f64::NEG_INFINITY, f64::INFINITY]; 3])
    }

    /// The profile's structure and its commands within `ranges` (forward m/s, lateral m/s,
    /// yaw rate rad/s, each [min, max]: the robot's,
    /// [`eemp_core::robot::RobotScale::command_ranges`]).
    pub fn validate_within(&self, ranges: [[f64; 2]; 3]) -> Result<(), ConfigError> {
        if self.segments.is_empty() {
            return Err(ConfigError::Invalid {
                name: "profile.segment".into(),
                message: "needs at least one segment".into(),
            });
        }
        let mut last = f64::NEG_INFINITY;
        for (i, s) in self.segments.iter().enumerate() {
            check_range(
                &format!("profile.segment[{i}].start_s"),
                s.start_s,
                0.0,
                1e6,
            )?;
            if s.start_s <= last {
                return Err(ConfigError::Invalid {
                    name: format!("profile.segment[{i}].start_s"),
                    message: format!(
                        "{} must be after the previous segment's start {last}",
                        s.start_s
                    ),
                });
            }
            last = s.start_s;
            let [vx, vy, yaw] = ranges;
            check_range(
                &format!("profile.segment[{i}].vx_mps"),
                s.vx_mps,
                vx[0],
                vx[1],
            )?;
            check_range(
                &format!("profile.segment[{i}].vy_mps"),
                s.vy_mps,
                vy[0],
                vy[1],
            )?;
            check_range(
                &format!("profile.segment[{i}].yaw_rate_rps"),
                s.yaw_rate_rps,
                yaw[0],
                yaw[1],
            )?;
        }
        Ok(())
    }

    /// The command of the first segment (what a walk starts towards).
    pub fn first_speed_mps(&self) -> f64 {
        self.segments
            .first()
            .map_or(0.0, |s| s.vx_mps.hypot(s.vy_mps))
    }

    pub fn command_at(&self, t: f64) -> VelocityCommand {
        self.segments
            .iter()
            .rev()
            .find(|s| t >= s.start_s)
            .map(|s| VelocityCommand {
                vx_mps: s.vx_mps,
                vy_mps: s.vy_mps,
                yaw_rate_rps: s.yaw_rate_rps,
            })
            .unwrap_or_default()
    }
}

/// Everything that defines a walking run.
#[derive(Clone, Debug, PartialEq)]
pub struct WalkSpec {
    pub controller: ControllerConfig,
    pub planner: PlannerConfig,
    /// Constant parameters, used when there is no table.
    pub params: PlannerParams,
    /// EEMP-Analytical: parameters looked up per commanded speed at every step.
    pub params_table: Option<ParamsTable>,
    pub profile: VelocityProfile,
    pub duration_s: f64,
    /// Metrics ignore the first seconds (standing up to speed), s.
    pub metrics_start_s: f64,
    pub pushes: Vec<Push>,
    /// Floor friction override (slippery ground); `None` keeps the robot file's value.
    pub floor_friction: Option<f64>,
    /// 0: start exactly at rest. Otherwise the seed of a small random start (heading ±0.05 rad,
    /// trunk velocity ±0.05 m/s per horizontal axis), so repeated runs of one grid point sample
    /// different trajectories; the same seed always gives the same run.
    pub seed: u64,
    /// What the controller sees: the simulator's state or the Kalman filter's estimate.
    pub state_source: StateSource,
    /// Run a per-speed table made for another robot (an experiment; refused otherwise).
    pub allow_robot_mismatch: bool,
    /// The ground (flat by default).
    pub terrain: Terrain,
    /// Mass added at the trunk's centre of mass, kg (the controllers keep the nominal model).
    pub payload_kg: f64,
    /// How the simulated robot differs from the model the controllers were built from.
    pub model_error: ModelError,
}

/// Errors of the simulated robot against the nominal model every controller is built from
/// (the robot file): trunk mass and inertia, motor strength. Default: none.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ModelError {
    /// Simulated trunk mass over the nominal one (the centre of mass stays), [0.5, 2].
    pub trunk_mass_scale: f64,
    /// Simulated trunk inertia about its centre of mass over the nominal one, [0.5, 2].
    pub trunk_inertia_scale: f64,
    /// Torque the simulated motors deliver per commanded N·m, [0.5, 1.5]; their maximum scales
    /// with it (a torque-constant error, as a worn or cold motor).
    pub motor_strength_scale: f64,
}

impl Default for ModelError {
    fn default() -> Self {
        ModelError {
            trunk_mass_scale: 1.0,
            trunk_inertia_scale: 1.0,
            motor_strength_scale: 1.0,
        }
    }
}

impl ModelError {
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range(
            "model_error.trunk_mass_scale",
            self.trunk_mass_scale,
            0.5,
            2.0,
        )?;
        check_range(
            "model_error.trunk_inertia_scale",
            self.trunk_inertia_scale,
            0.5,
            2.0,
        )?;
        check_range(
            "model_error.motor_strength_scale",
            self.motor_strength_scale,
            0.5,
            1.5,
        )
    }

    /// The simulated robot: `robot` with these errors (the scene gets the motor strength).
    pub fn apply(&self, robot: &mut RobotConfig, scene: &mut SceneExtras) {
        robot.trunk.mass_kg *= self.trunk_mass_scale;
        for i in &mut robot.trunk.inertia_kg_m2 {
            *i *= self.trunk_inertia_scale;
        }
        if self.motor_strength_scale != 1.0 {
            scene.motor_strength_scale = Some(self.motor_strength_scale);
        }
    }
}

/// The robot and scene the simulator runs: floor friction, terrain, model errors and payload
/// applied to `robot`. The simulated robot carries the payload and has the model errors; the
/// controllers, built from `robot`, do not know.
pub fn simulated_world(
    robot: &RobotConfig,
    terrain: &Terrain,
    floor_friction: Option<f64>,
    model_error: &ModelError,
    payload_kg: f64,
) -> (RobotConfig, SceneExtras) {
    let mut robot = robot.clone();
    if let Some(mu) = floor_friction {
        robot.simulation.floor_friction = mu;
    }
    let mut scene = terrain.scene(robot.simulation.floor_friction);
    model_error.apply(&mut robot, &mut scene);
    robot.trunk.mass_kg += payload_kg;
    (robot, scene)
}

impl WalkSpec {
    /// The robot and scene the simulator runs for this walk (see [`simulated_world`]).
    pub fn simulated_world(&self, robot: &RobotConfig) -> (RobotConfig, SceneExtras) {
        simulated_world(
            robot,
            &self.terrain,
            self.floor_friction,
            &self.model_error,
            self.payload_kg,
        )
    }

    /// A constant-speed run of `duration_s` starting 0.5 s after t = 0, metrics from 2 s.
    pub fn constant(
        planner: PlannerConfig,
        params: PlannerParams,
        command: VelocityCommand,
        duration_s: f64,
    ) -> Self {
        WalkSpec {
            controller: ControllerConfig {
                slip: eemp_core::slip::SlipConfig::default_for(planner.gait),
                ..ControllerConfig::default()
            },
            planner,
            params,
            params_table: None,
            profile: VelocityProfile::constant(0.5, command),
            duration_s,
            metrics_start_s: 2.0_f64.min(duration_s / 2.0),
            pushes: Vec::new(),
            floor_friction: None,
            seed: 0,
            state_source: StateSource::GroundTruth,
            allow_robot_mismatch: false,
            terrain: Terrain::default(),
            payload_kg: 0.0,
            model_error: ModelError::default(),
        }
    }

    /// The planner parameters in force at time `t`.
    pub fn params_at(&self, t: f64) -> PlannerParams {
        match &self.params_table {
            Some(table) => {
                let c = self.profile.command_at(t);
                table.lookup(c.vx_mps.hypot(c.vy_mps))
            }
            None => self.params,
        }
    }

    /// [`WalkSpec::validate`] and what depends on the robot's size: the commands within its
    /// ranges and the payload within its cap ([`eemp_core::robot_size`]).
    pub fn validate_for(&self, robot: &RobotConfig) -> Result<(), ConfigError> {
        self.validate()?;
        let size = robot.scale();
        self.profile.validate_within(size.command_ranges())?;
        check_range(
            "payload_kg",
            self.payload_kg,
            0.0,
            size.sized(&eemp_core::robot_size::MAX_PAYLOAD),
        )
    }

    pub fn validate(&self) -> Result<(), ConfigError> {
        self.controller.validate()?;
        if let Some(t) = &self.params_table {
            t.validate()?;
            if t.gait != self.planner.gait {
                return Err(ConfigError::Invalid {
                    name: "params table".into(),
                    message: format!(
                        "is for gait {} but the run uses {}",
                        t.gait, self.planner.gait
                    ),
                });
            }
        }
        self.planner.validate()?;
        self.params.validate()?;
        // Commands and payload are checked against the robot's size when it runs
        // ([`WalkSpec::validate_for`]); here only what no robot can take.
        self.profile.validate()?;
        check_range("duration_s", self.duration_s, 0.01, 3600.0)?;
        check_range(
            "metrics_start_s",
            self.metrics_start_s,
            0.0,
            self.duration_s,
        )?;
        if let Some(mu) = self.floor_friction {
            eemp_core::config_error::check_friction("floor_friction", mu)?;
        }
        self.terrain.validate()?;
        check_range("payload_kg", self.payload_kg, 0.0, f64::MAX)?;
        self.model_error.validate()?;
        if let StateSource::Kf { kf, sensors, .. } = &self.state_source {
            kf.validate()?;
            sensors.validate()?;
        }
        Ok(())
    }
}

/// Result of a walking run.
#[derive(Clone, Debug)]
pub struct WalkRun {
    pub stats: LoopStats,
    /// Estimation error against the truth (empty on ground truth).
    pub estimation: EstimationStats,
    pub metrics: WalkMetrics,
    pub steps: LegMap<usize>,
    /// The gait walked over the metrics window (`None` if the window is empty).
    pub gait: Option<GaitMeasure>,
}

/// Joint angles that put every foot under its hip with the trunk at `height_m` (flat ground).
pub fn standing_joints(
    kin: &LegKinematics,
    height_m: f64,
    foot_radius_m: f64,
) -> Result<LegMap<Vector3<f64>>, ConfigError> {
    let mut q = LegMap::splat(Vector3::zeros());
    for leg in Leg::ALL {
        let mut p = kin.nominal_foot_body(leg);
        p.z = -(height_m - foot_radius_m);
        q[leg] = kin.inverse(leg, &p).map_err(|e| ConfigError::Invalid {
            name: "body_height_m".into(),
            message: e.to_string(),
        })?;
    }
    Ok(q)
}

/// The state a walk starts from: trunk height and joint angles, at rest.
#[derive(Clone, Debug, PartialEq)]
pub struct StartPose {
    pub trunk_height_m: f64,
    pub joints: LegMap<Vector3<f64>>,
}

impl StartPose {
    /// EEMP's start: feet under the hips with the trunk at the first commanded X_z.
    pub fn eemp(robot: &RobotConfig, spec: &WalkSpec) -> Result<Self, ConfigError> {
        let kin = LegKinematics::new(robot);
        let first = spec
            .profile
            .segments
            .first()
            .map(|s| s.start_s)
            .unwrap_or(0.0);
        let trunk_height_m = spec.params_at(first).body_height_m;
        let joints = standing_joints(&kin, trunk_height_m, robot.leg.foot_radius_m)?;
        Ok(StartPose {
            trunk_height_m,
            joints,
        })
    }

    /// Standing in the joint pose `joints` with the feet on flat ground.
    pub fn from_joints(robot: &RobotConfig, joints: LegMap<Vector3<f64>>) -> Self {
        Self::standing(&LegKinematics::new(robot), robot.leg.foot_radius_m, joints)
    }

    /// [`StartPose::from_joints`] with the kinematics at hand: the trunk height that puts the
    /// lowest foot on the floor.
    pub fn standing(kin: &LegKinematics, foot_radius_m: f64, joints: LegMap<Vector3<f64>>) -> Self {
        let lowest = Leg::ALL
            .iter()
            .map(|l| kin.foot_position_body(*l, &joints[*l]).z)
            .fold(f64::INFINITY, f64::min);
        StartPose {
            trunk_height_m: -lowest + foot_radius_m,
            joints,
        }
    }
}

/// Puts `sim` in the start pose (1 mm above the floor), with the walk's seeded perturbation.
pub fn reset_to_start(sim: &mut Simulation, start: &StartPose, seed: u64) {
    sim.reset(
        Vector3::new(0.0, 0.0, start.trunk_height_m + 1e-3),
        &start.joints,
    );
    if seed != 0 {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let yaw: f64 = rng.random_range(-0.05..0.05);
        let (vx, vy): (f64, f64) = (rng.random_range(-0.05..0.05), rng.random_range(-0.05..0.05));
        let data = sim.data_mut();
        data.qpos_mut()[3..7].copy_from_slice(&[(yaw / 2.0).cos(), 0.0, 0.0, (yaw / 2.0).sin()]);
        data.qvel_mut()[0] = vx;
        data.qvel_mut()[1] = vy;
        data.forward();
    }
}

/// One control step of `record` into `metrics` (eq. 8's energy and distance, the velocity
/// error, eq. 9 over the `stance` legs), on the simulator's true state: the one place every
/// walk's metrics, and EEMP-RL's interval reward, are measured.
pub fn observe_metrics(
    metrics: &mut MetricsAccumulator,
    kin: &LegKinematics,
    dt: f64,
    record: &StepRecord,
    stance: &LegMap<bool>,
) {
    let cmd = record.command;
    let qd = record.state.joints.map(|_, j| j.qd);
    let jac = LegMap::from_fn(|leg| kin.foot_jacobian_body(leg, &record.state.joints[leg].q));
    metrics.observe(
        dt,
        &record.state.body.p_world,
        &record.state.body.v_heading(),
        [cmd.vx_mps, cmd.vy_mps],
        &qd,
        &record.output.torques,
        stance,
        &jac,
    );
}

/// Runs a walk under EEMP; `observer` sees every control step.
pub fn run_walk(
    robot: &RobotConfig,
    spec: &WalkSpec,
    observer: impl FnMut(&StepRecord),
) -> Result<WalkRun, ScenarioError> {
    run_walk_eemp_commanded(robot, spec, &mut |t| spec.profile.command_at(t), observer)
}

/// [`run_walk`] with the command from `command_at(t)` in place of the spec's profile (an
/// operator); EEMP starts as for the profile's first command.
pub fn run_walk_eemp_commanded(
    robot: &RobotConfig,
    spec: &WalkSpec,
    command_at: &mut dyn FnMut(f64) -> VelocityCommand,
    observer: impl FnMut(&StepRecord),
) -> Result<WalkRun, ScenarioError> {
    spec.validate_for(robot)?;
    let mut controller = eemp_controller(robot, spec)?;
    let start = StartPose::eemp(robot, spec)?;
    run_walk_commanded(robot, spec, &start, &mut controller, command_at, observer)
}

/// EEMP (planner, MPC, swing law) as the spec configures it: its planner and controller
/// settings, constant parameters or the per-speed table.
pub fn eemp_controller(
    robot: &RobotConfig,
    spec: &WalkSpec,
) -> Result<EempController, ScenarioError> {
    let kin = LegKinematics::new(robot);
    let planner = EemPlanner::new(
        spec.planner.clone(),
        kin,
        robot.leg.foot_radius_m,
        spec.controller.mpc.horizon,
        spec.controller.mpc.dt_s,
    )?;
    let locomotion = LocomotionController::new(robot, spec.controller.clone())?;
    let params = match &spec.params_table {
        Some(t) if !spec.allow_robot_mismatch => {
            t.robot_id()
                .check(robot, &format!("the {} table", t.gait))
                .map_err(|message| ConfigError::Invalid {
                    name: "params_table".into(),
                    message,
                })?;
            ParamsSource::Table(t.clone())
        }
        Some(t) => ParamsSource::Table(t.clone()),
        None => ParamsSource::Constant(spec.params),
    };
    Ok(EempController::new(planner, locomotion, params))
}

/// Runs a walk with any controller: the same scenario (start, command profile, pushes,
/// friction, duration) and the same metrics for every method. The spec's planner settings are
/// used only by EEMP's own constructor ([`run_walk`]).
pub fn run_walk_with(
    robot: &RobotConfig,
    spec: &WalkSpec,
    start: &StartPose,
    controller: &mut dyn Controller,
    observer: impl FnMut(&StepRecord),
) -> Result<WalkRun, ScenarioError> {
    run_walk_commanded(
        robot,
        spec,
        start,
        controller,
        &mut |t| spec.profile.command_at(t),
        observer,
    )
}

/// [`run_walk_with`] with the command from `command_at(t)` at every step instead of the spec's
/// profile (an operator: teleoperation, a script shaped like a joystick).
pub fn run_walk_commanded(
    robot: &RobotConfig,
    spec: &WalkSpec,
    start: &StartPose,
    controller: &mut dyn Controller,
    command_at: &mut dyn FnMut(f64) -> VelocityCommand,
    mut observer: impl FnMut(&StepRecord),
) -> Result<WalkRun, ScenarioError> {
    spec.validate_for(robot)?;
    let (robot, scene) = spec.simulated_world(robot);
    let mut sim = Simulation::new(&robot, &scene)?;
    // On the platform of ground that goes down from the start (a step or stairs down).
    let start = StartPose {
        trunk_height_m: start.trunk_height_m + spec.terrain.start_lift_m(),
        ..start.clone()
    };
    reset_to_start(&mut sim, &start, spec.seed);
    let kin = LegKinematics::new(&robot);
    let mut metrics = MetricsAccumulator::new(robot.motor_model());
    let mut gait = GaitMeter::default();
    let dt = sim.timestep_s();
    let mass = robot.total_mass_kg();
    let mut touchdowns = LegMap::splat(0usize);
    let mut was_down: Option<LegMap<bool>> = None;
    let mut lp =
        ClosedLoop::with_state_source(sim, &spec.pushes, robot.scale(), &spec.state_source)?;
    lp.set_ground(&spec.terrain);
    let lp = run_closed_loop(lp, controller, spec.duration_s, command_at, |record| {
        let t = record.state.time_s;
        let stance = record.stance();
        if let Some(prev) = was_down {
            for leg in Leg::ALL {
                if record.loaded[leg] && !prev[leg] {
                    touchdowns[leg] += 1;
                }
            }
        }
        was_down = Some(record.loaded);
        if t >= spec.metrics_start_s {
            observe_metrics(&mut metrics, &kin, dt, record, &stance);
            gait.observe(dt, &record.loaded, &record.foot_normal_n);
        }
        observer(record);
    });
    // EEMP counts the swings it started; a controller without a plan is counted by its
    // touchdowns (a foot becoming loaded, see `LOADED_FOOT_N`).
    let steps = controller.steps().unwrap_or(touchdowns);
    Ok(WalkRun {
        stats: lp.stats().clone(),
        estimation: lp.estimation().clone(),
        metrics: metrics.finish(mass),
        steps,
        gait: gait.finish(),
    })
}
