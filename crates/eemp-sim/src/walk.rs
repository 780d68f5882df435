//! The walking scenario: the A1 starts standing at X_z and walks under EEMP at the commanded
//! velocity (constant or a piecewise profile).

use crate::backend::Simulation;
use crate::closed_loop::{run_closed_loop, FallLimits, LoopStats, Push, StepRecord};
use crate::mjcf::SceneExtras;
use crate::stand::ScenarioError;
use eemp_core::config_error::{check_range, ConfigError};
use eemp_core::controller::{ControllerConfig, LocomotionController};
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
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

    pub fn validate(&self) -> Result<(), ConfigError> {
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
            check_range(&format!("profile.segment[{i}].vx_mps"), s.vx_mps, -1.5, 1.5)?;
            check_range(&format!("profile.segment[{i}].vy_mps"), s.vy_mps, -0.5, 0.5)?;
            check_range(
                &format!("profile.segment[{i}].yaw_rate_rps"),
                s.yaw_rate_rps,
                -1.5,
                1.5,
            )?;
        }
        Ok(())
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
}

impl WalkSpec {
    /// A constant-speed run of `duration_s` starting 0.5 s after t = 0, metrics from 2 s.
    pub fn constant(
        planner: PlannerConfig,
        params: PlannerParams,
        command: VelocityCommand,
        duration_s: f64,
    ) -> Self {
        WalkSpec {
            controller: ControllerConfig::default(),
            planner,
            params,
            params_table: None,
            profile: VelocityProfile::constant(0.5, command),
            duration_s,
            metrics_start_s: 2.0_f64.min(duration_s / 2.0),
            pushes: Vec::new(),
            floor_friction: None,
            seed: 0,
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
        self.profile.validate()?;
        check_range("duration_s", self.duration_s, 0.01, 3600.0)?;
        check_range(
            "metrics_start_s",
            self.metrics_start_s,
            0.0,
            self.duration_s,
        )?;
        if let Some(mu) = self.floor_friction {
            check_range("floor_friction", mu, 0.05, 5.0)?;
        }
        Ok(())
    }
}

/// Result of a walking run.
#[derive(Clone, Debug)]
pub struct WalkRun {
    pub stats: LoopStats,
    pub metrics: WalkMetrics,
    pub steps: LegMap<usize>,
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

/// Runs a walk; `observer` sees every control step.
pub fn run_walk(
    robot: &RobotConfig,
    spec: &WalkSpec,
    mut observer: impl FnMut(&StepRecord),
) -> Result<WalkRun, ScenarioError> {
    spec.validate()?;
    let mut robot = robot.clone();
    if let Some(mu) = spec.floor_friction {
        robot.simulation.floor_friction = mu;
    }
    let mut sim = Simulation::new(&robot, &SceneExtras::default())?;
    let mut controller = LocomotionController::new(&robot, spec.controller.clone())?;
    let kin = LegKinematics::new(&robot);
    let first = spec
        .profile
        .segments
        .first()
        .map(|s| s.start_s)
        .unwrap_or(0.0);
    let start_height = spec.params_at(first).body_height_m;
    let q0 = standing_joints(&kin, start_height, robot.leg.foot_radius_m)?;
    sim.reset(Vector3::new(0.0, 0.0, start_height + 1e-3), &q0);
    if spec.seed != 0 {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(spec.seed);
        let yaw: f64 = rng.random_range(-0.05..0.05);
        let (vx, vy): (f64, f64) = (rng.random_range(-0.05..0.05), rng.random_range(-0.05..0.05));
        let data = sim.data_mut();
        data.qpos_mut()[3..7].copy_from_slice(&[(yaw / 2.0).cos(), 0.0, 0.0, (yaw / 2.0).sin()]);
        data.qvel_mut()[0] = vx;
        data.qvel_mut()[1] = vy;
        data.forward();
    }
    let mut planner = EemPlanner::new(
        spec.planner.clone(),
        kin.clone(),
        robot.leg.foot_radius_m,
        spec.controller.mpc.horizon,
        spec.controller.mpc.dt_s,
    )?;
    let mut metrics = MetricsAccumulator::default();
    let dt = sim.timestep_s();
    let mass = robot.total_mass_kg();
    let stats = run_closed_loop(
        &mut sim,
        &mut controller,
        spec.duration_s,
        &spec.pushes,
        FallLimits::default(),
        |state, feet| {
            planner.plan(
                state.time_s,
                state,
                feet,
                &spec.profile.command_at(state.time_s),
                &spec.params_at(state.time_s),
            )
        },
        |record| {
            let t = record.state.time_s;
            if t >= spec.metrics_start_s {
                let cmd = spec.profile.command_at(t);
                let qd = record.state.joints.map(|_, j| j.qd);
                let jac =
                    LegMap::from_fn(|leg| kin.foot_jacobian_body(leg, &record.state.joints[leg].q));
                metrics.observe(
                    dt,
                    &record.state.body.p_world,
                    &record.state.body.v_heading(),
                    [cmd.vx_mps, cmd.vy_mps],
                    &qd,
                    &record.output.torques,
                    &record.plan.stance,
                    &jac,
                );
            }
            observer(record);
        },
    );
    let steps = planner.steps();
    Ok(WalkRun {
        stats,
        metrics: metrics.finish(mass),
        steps,
    })
}
