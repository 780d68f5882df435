//! The standing scenario: the A1 starts crouched on the ground, rises, and follows a
//! body-motion profile on four stance legs.

use crate::backend::{SimError, Simulation};
use crate::closed_loop::{
    run_closed_loop, ClosedLoop, EstimationStats, LoopStats, Push, StateSource, StepRecord,
};
use crate::mjcf::SceneExtras;
use eemp_core::config_error::ConfigError;
use eemp_core::eemp::StandController;
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::locomotion::{ControllerConfig, LocomotionController};
use eemp_core::planner::VelocityCommand;
use eemp_core::robot::RobotConfig;
use eemp_core::stand_profile::{BodyMotionProfile, StandPlanner};
use nalgebra::Vector3;

#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Sim(#[from] SimError),
}

/// Crouched joint angles the A1 starts in: trunk low, feet under the hips.
pub const CROUCH_POSE_RAD: [f64; 3] = [0.0, 1.25, -2.5];

/// The crouch of `robot`: its standing pose with thigh and knee bent further by the A1's
/// crouch-to-stand ratios (1.25 / 0.9 and 2.5 / 1.8; the A1's own crouch exactly), kept in the
/// joint ranges. Works for either axis sign and knee direction, since it scales the robot's own
/// standing angles.
pub fn crouch_pose(robot: &RobotConfig) -> LegMap<Vector3<f64>> {
    let a1 = Vector3::from(RobotConfig::a1().leg.standing_pose_rad);
    let crouch = Vector3::from(CROUCH_POSE_RAD);
    robot.standing_pose().map(|leg, q| {
        if *q == a1 {
            return crouch;
        }
        Vector3::from_fn(|j, _| {
            let ratio = if a1[j] == 0.0 { 1.0 } else { crouch[j] / a1[j] };
            let [lo, hi] = robot.joint_range_rad(leg, j);
            (q[j] * ratio).clamp(lo, hi)
        })
    })
}

/// Puts the robot crouched at rest with its feet on the ground; returns the trunk height.
pub fn reset_crouched(sim: &mut Simulation, robot: &RobotConfig) -> f64 {
    let kin = LegKinematics::new(robot);
    let q = crouch_pose(robot);
    let foot_z = Leg::ALL
        .iter()
        .map(|&leg| kin.foot_position_body(leg, &q[leg]).z)
        .fold(f64::INFINITY, f64::min);
    let height = -foot_z + robot.leg.foot_radius_m + 1e-3;
    sim.reset(Vector3::new(0.0, 0.0, height), &q);
    height
}

pub struct StandRun {
    pub stats: LoopStats,
    pub planner: StandPlanner,
    /// Estimation error against the truth (empty on ground truth).
    pub estimation: EstimationStats,
}

/// Runs the standing scenario for `duration_s` on ground truth; `observer` sees every step.
pub fn run_stand(
    robot: &RobotConfig,
    controller_config: ControllerConfig,
    profile: BodyMotionProfile,
    duration_s: f64,
    pushes: &[Push],
    observer: impl FnMut(&StepRecord),
) -> Result<StandRun, ScenarioError> {
    run_stand_on(
        robot,
        controller_config,
        profile,
        duration_s,
        pushes,
        &StateSource::GroundTruth,
        observer,
    )
}

/// [`run_stand`] with the controller's state from `source` (ground truth or the filter).
pub fn run_stand_on(
    robot: &RobotConfig,
    controller_config: ControllerConfig,
    profile: BodyMotionProfile,
    duration_s: f64,
    pushes: &[Push],
    source: &StateSource,
    observer: impl FnMut(&StepRecord),
) -> Result<StandRun, ScenarioError> {
    let mut sim = Simulation::new(robot, &SceneExtras::default())?;
    let locomotion = LocomotionController::new(robot, controller_config.clone())?;
    reset_crouched(&mut sim, robot);
    sim.prepare();
    let start = sim.ground_truth_state();
    let planner = StandPlanner::new(
        profile,
        &start,
        controller_config.mpc.horizon,
        controller_config.mpc.dt_s,
    )?;
    let mut controller = StandController::new(planner, locomotion);
    let lp = run_closed_loop(
        ClosedLoop::with_state_source(sim, pushes, robot.scale(), source)?,
        &mut controller,
        duration_s,
        |_| VelocityCommand::default(),
        observer,
    );
    Ok(StandRun {
        stats: lp.stats().clone(),
        estimation: lp.estimation().clone(),
        planner: controller.planner,
    })
}
