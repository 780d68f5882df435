//! The model-free RL baseline of the paper (Sec. II-C): a policy maps proprioception and the
//! velocity command to joint position targets, tracked by a joint PD at the physics rate.
//!
//! Observation O^M = [q − q₀, q̇, τ, X_cur (feet, body frame), a_{t−1}] + command
//! (+ N_prev past frames of q − q₀, q̇), as the paper; the field's recipes (legged_gym,
//! mujoco_playground) add the trunk's velocity, angular velocity and gravity direction in the
//! body frame — switchable, listed apart (`extra_obs`). Rewards: the paper's terms (2)+(3) of
//! its reward table, each a named function below with its weight in [`RewardWeights`], plus
//! the shaping terms the recipes use, also switchable.

use crate::env::{Env, StepInfo};
use crate::mirror::{MirrorBuilder, MirrorMap, AXIAL, JOINTS, POLAR};
use eemp_core::body_state::RobotState;
use eemp_core::config_error::{check_range, ConfigError};
use eemp_core::energy::MotorModel;
use eemp_core::joint_pd::{JointPd, PdGains};
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::planner::VelocityCommand;
use eemp_core::robot::RobotConfig;
use eemp_sim::backend::{build_model, SimSnapshot};
use eemp_sim::closed_loop::{ClosedLoop, EpisodeEnd, Push};
use eemp_sim::mjcf::SceneExtras;
use eemp_sim::walk::StartPose;
use eemp_sim::Simulation;
use mujoco_rs::prelude::MjModel;
use nalgebra::{UnitQuaternion, Vector3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::sync::Arc;

pub const ACT_DIM: usize = 12;
/// One proprioceptive frame of the history: q − q₀ and q̇.
const FRAME: usize = 24;

/// Reward weights (each term's value is multiplied by its weight and by the policy period, as
/// legged_gym does, so weights do not depend on the control rate). 0 switches a term off.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RewardWeights {
    // The paper's terms (reward table, rows 2 and 3).
    pub tracking_lin_vel: f64,
    pub tracking_ang_vel: f64,
    pub lin_vel_z: f64,
    pub joint_acc: f64,
    pub action_rate: f64,
    pub feet_air_time: f64,
    /// Thighs or knees touching the ground (the model has no leg–leg contacts, so this is the
    /// self-collision term's reading, as legged_gym's "collision"; trunk contact ends the
    /// episode).
    pub collision: f64,
    // Shaping terms from legged_gym / mujoco_playground (not in the paper).
    pub orientation: f64,
    pub ang_vel_xy: f64,
    pub torques: f64,
    pub joint_limits: f64,
    pub energy: f64,
    /// mujoco_playground's feet_clearance: moving feet away from the swing height are
    /// penalised. Without it the policy shuffled with its feet in (soft) contact (measured).
    pub feet_clearance: f64,
    /// Feet whose contact state matches the gait clock's trot schedule (FL+RR swing in the
    /// clock's first half, FR+RL in its second), as a share of the four (Walk These Ways'
    /// contact tracking, binary form). Needs `extra_obs.gait_clock_hz` > 0.
    pub gait_schedule: f64,
    /// The drives' electrical power, W, from the robot file's motor model (`[motor]`, no idle
    /// power: a constant would only reward ending episodes), averaged over the policy period's
    /// physics steps: the energy a battery pays, in place of `energy`'s Σ|τq̇|.
    pub electrical_power: f64,
}

impl Default for RewardWeights {
    /// legged_gym's A1 weights for the shared terms; orientation from its flat-terrain configs.
    fn default() -> Self {
        RewardWeights {
            tracking_lin_vel: 1.0,
            tracking_ang_vel: 0.5,
            lin_vel_z: -2.0,
            joint_acc: -2.5e-7,
            action_rate: -0.01,
            feet_air_time: 1.0,
            collision: -1.0,
            orientation: -1.0,
            ang_vel_xy: -0.05,
            torques: -2e-4,
            joint_limits: -10.0,
            energy: 0.0,
            feet_clearance: -2.0,
            gait_schedule: 0.0,
            electrical_power: 0.0,
        }
    }
}

/// The names of the reward terms, in the order of [`RewardWeights`] and of `train.csv`.
pub const REWARD_TERMS: [&str; 15] = [
    "tracking_lin_vel",
    "tracking_ang_vel",
    "lin_vel_z",
    "joint_acc",
    "action_rate",
    "feet_air_time",
    "collision",
    "orientation",
    "ang_vel_xy",
    "torques",
    "joint_limits",
    "energy",
    "feet_clearance",
    "gait_schedule",
    "electrical_power",
];

impl RewardWeights {
    fn as_array(&self) -> [f64; 15] {
        [
            self.tracking_lin_vel,
            self.tracking_ang_vel,
            self.lin_vel_z,
            self.joint_acc,
            self.action_rate,
            self.feet_air_time,
            self.collision,
            self.orientation,
            self.ang_vel_xy,
            self.torques,
            self.joint_limits,
            self.energy,
            self.feet_clearance,
            self.gait_schedule,
            self.electrical_power,
        ]
    }
}

/// Observation terms beyond the paper's O^M.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ExtraObs {
    /// Trunk linear velocity in the body frame (an estimator supplies it on the robot).
    pub base_lin_vel: bool,
    /// Trunk angular velocity in the body frame (gyro).
    pub base_ang_vel: bool,
    /// Gravity direction in the body frame (IMU attitude).
    pub gravity: bool,
    /// A gait clock (sin 2πφ, cos 2πφ) at this frequency, Hz, appended last; 0 = none (as
    /// the shipped baseline). It breaks the standing pose's left–right tie: a mirror-symmetric
    /// memoryless policy cannot choose which diagonal lifts first (measured: trained from
    /// scratch with the mirror loss it learned to stand), and the clock's mirror is a
    /// half-period shift, so the mirror loss then asks for alternating legs.
    pub gait_clock_hz: f64,
}

impl Default for ExtraObs {
    fn default() -> Self {
        ExtraObs {
            base_lin_vel: true,
            base_ang_vel: true,
            gravity: true,
            gait_clock_hz: 0.0,
        }
    }
}

/// Ranges of the commands sampled per episode (and at each resampling).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CommandRanges {
    pub vx_mps: [f64; 2],
    pub vy_mps: [f64; 2],
    pub yaw_rate_rps: [f64; 2],
    /// Probability that the lateral and yaw commands are zero in an episode (the evaluation
    /// walks straight).
    pub straight_prob: f64,
    /// Commands are resampled after this long, s.
    pub resample_s: f64,
}

impl Default for CommandRanges {
    fn default() -> Self {
        CommandRanges {
            vx_mps: [0.0, 1.0],
            vy_mps: [-0.3, 0.3],
            yaw_rate_rps: [-0.5, 0.5],
            straight_prob: 0.5,
            resample_s: 10.0,
        }
    }
}

/// Random pushes in training (legged_gym's `push_robots`): every `every_s` (each up to half of
/// it late, at random) the trunk's horizontal velocity steps by a uniform draw in ±`max_dv_mps`
/// per axis, as `eemp_sim::closed_loop::Push::step` does in the robustness suite. `every_s` 0:
/// no pushes (the default, as the shipped policy was trained).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrainPushes {
    pub every_s: f64,
    pub max_dv_mps: f64,
}

impl TrainPushes {
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.validate_as("model_free.pushes")
    }

    /// [`TrainPushes::validate`] with the keys named under `prefix`.
    pub fn validate_as(&self, prefix: &str) -> Result<(), ConfigError> {
        if self.every_s != 0.0 {
            check_range(&format!("{prefix}.every_s"), self.every_s, 0.5, 3600.0)?;
        }
        check_range(&format!("{prefix}.max_dv_mps"), self.max_dv_mps, 0.0, 2.0)
    }

    /// The pushes of an episode of `episode_s`, drawn from `rng` (none when off).
    pub fn draw(&self, episode_s: f64, rng: &mut ChaCha8Rng) -> Vec<Push> {
        let mut out = Vec::new();
        if self.every_s <= 0.0 {
            return out;
        }
        let m = self.max_dv_mps;
        let mut slot = self.every_s;
        while slot < episode_s {
            let at_s = slot + rng.random_range(0.0..0.5 * self.every_s);
            let dv = match m > 0.0 {
                true => Vector3::new(rng.random_range(-m..m), rng.random_range(-m..m), 0.0),
                false => Vector3::zeros(),
            };
            out.push(Push::step(at_s, dv));
            slot += self.every_s;
        }
        out
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ModelFreeConfig {
    /// Time between policy actions, s (50 Hz).
    pub policy_period_s: f64,
    /// MuJoCo time step while training, s. Evaluation always runs the robot file's 1 ms.
    pub train_timestep_s: f64,
    pub pd: PdGains,
    /// Joint target = q₀ + action_scale · clip(a, ±action_clip), rad per action unit.
    pub action_scale: f64,
    pub action_clip: f64,
    /// Past proprioceptive frames (q − q₀, q̇) in the observation (the paper's N_prev).
    pub history: usize,
    pub extra_obs: ExtraObs,
    pub commands: CommandRanges,
    pub episode_s: f64,
    pub rewards: RewardWeights,
    /// σ of the tracking kernels exp(−e²/σ), (m/s)² and (rad/s)².
    pub tracking_sigma: f64,
    /// Air time a swing is rewarded above, s (a foot is in the air when it carries less than
    /// `eemp_sim::closed_loop::LOADED_FOOT_N`).
    pub air_time_target_s: f64,
    /// Swing height of the feet_clearance term (foot sole above the floor), m.
    pub clearance_height_m: f64,
    /// Clip the summed step reward at 0 (legged_gym): penalties cannot make living worse than
    /// falling.
    pub only_positive_rewards: bool,
    /// Reset noise: joint angles ± this, rad; trunk velocity ± reset_vel_noise_mps.
    pub reset_joint_noise_rad: f64,
    pub reset_vel_noise_mps: f64,
    pub pushes: TrainPushes,
    /// Friction randomisation: the floor frictions trained on, environment i on entry i mod n
    /// (empty: the robot file's floor).
    pub floor_frictions: Vec<f64>,
}

impl Default for ModelFreeConfig {
    fn default() -> Self {
        ModelFreeConfig {
            policy_period_s: 0.02,
            train_timestep_s: 0.004,
            pd: PdGains::default(),
            action_scale: 0.25,
            action_clip: 5.0,
            history: 1,
            extra_obs: ExtraObs::default(),
            commands: CommandRanges::default(),
            episode_s: 20.0,
            rewards: RewardWeights::default(),
            tracking_sigma: 0.25,
            air_time_target_s: 0.25,
            clearance_height_m: 0.08,
            only_positive_rewards: true,
            reset_joint_noise_rad: 0.1,
            reset_vel_noise_mps: 0.1,
            pushes: TrainPushes::default(),
            floor_frictions: Vec::new(),
        }
    }
}

impl ModelFreeConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range(
            "model_free.policy_period_s",
            self.policy_period_s,
            0.002,
            0.1,
        )?;
        check_range(
            "model_free.train_timestep_s",
            self.train_timestep_s,
            0.0005,
            0.005,
        )?;
        let ratio = self.policy_period_s / self.train_timestep_s;
        if (ratio - ratio.round()).abs() > 1e-6 {
            return Err(ConfigError::Invalid {
                name: "model_free.policy_period_s".into(),
                message: format!(
                    "{} is not a whole number of train_timestep_s {}",
                    self.policy_period_s, self.train_timestep_s
                ),
            });
        }
        self.pd.validate()?;
        check_range("model_free.action_scale", self.action_scale, 0.01, 2.0)?;
        check_range("model_free.action_clip", self.action_clip, 0.1, 100.0)?;
        check_range("model_free.history", self.history as f64, 0.0, 10.0)?;
        let c = &self.commands;
        for (name, r, lim) in [
            ("vx_mps", c.vx_mps, 1.5),
            ("vy_mps", c.vy_mps, 1.0),
            ("yaw_rate_rps", c.yaw_rate_rps, 2.0),
        ] {
            check_range(&format!("model_free.commands.{name}[0]"), r[0], -lim, lim)?;
            check_range(&format!("model_free.commands.{name}[1]"), r[1], r[0], lim)?;
        }
        check_range(
            "model_free.commands.straight_prob",
            c.straight_prob,
            0.0,
            1.0,
        )?;
        check_range("model_free.commands.resample_s", c.resample_s, 0.1, 3600.0)?;
        check_range("model_free.episode_s", self.episode_s, 0.1, 3600.0)?;
        for (name, w) in REWARD_TERMS.iter().zip(self.rewards.as_array()) {
            check_range(&format!("model_free.rewards.{name}"), w, -1e3, 1e3)?;
        }
        check_range("model_free.tracking_sigma", self.tracking_sigma, 1e-3, 10.0)?;
        check_range(
            "model_free.air_time_target_s",
            self.air_time_target_s,
            0.0,
            2.0,
        )?;
        check_range(
            "model_free.clearance_height_m",
            self.clearance_height_m,
            0.0,
            0.3,
        )?;
        check_range(
            "model_free.reset_joint_noise_rad",
            self.reset_joint_noise_rad,
            0.0,
            0.5,
        )?;
        check_range(
            "model_free.reset_vel_noise_mps",
            self.reset_vel_noise_mps,
            0.0,
            1.0,
        )?;
        check_range(
            "model_free.extra_obs.gait_clock_hz",
            self.extra_obs.gait_clock_hz,
            0.0,
            10.0,
        )?;
        if self.rewards.gait_schedule != 0.0 && self.extra_obs.gait_clock_hz == 0.0 {
            return Err(ConfigError::Invalid {
                name: "model_free.rewards.gait_schedule".into(),
                message: format!(
                    "{} needs a gait clock: set model_free.extra_obs.gait_clock_hz in (0, 10]",
                    self.rewards.gait_schedule
                ),
            });
        }
        for (i, &mu) in self.floor_frictions.iter().enumerate() {
            eemp_core::config_error::check_friction(
                &format!("model_free.floor_frictions[{i}]"),
                mu,
            )?;
        }
        self.pushes.validate()
    }

    pub fn obs_dim(&self) -> usize {
        base_obs_dim(&self.extra_obs, self.history)
    }
}

/// Length of what [`observe`] writes: O^M, the command, the extras and the history.
pub fn base_obs_dim(e: &ExtraObs, history: usize) -> usize {
    5 * 12
        + 3
        + 3 * (e.base_lin_vel as usize + e.base_ang_vel as usize + e.gravity as usize)
        + FRAME * history
        + 2 * (e.gait_clock_hz > 0.0) as usize
}

/// The left–right mirror of [`observe`]'s layout (`crate::mirror`). It holds when the standing
/// pose's hip angle is 0 (q − q₀ and the actions are about q₀).
pub fn observation_mirror(extra: &ExtraObs, history: usize) -> MirrorMap {
    let mut b = MirrorBuilder::new()
        .per_leg(JOINTS) // q − q₀
        .per_leg(JOINTS) // q̇
        .per_leg(JOINTS) // τ
        .per_leg(POLAR) // feet, body frame
        .per_leg(JOINTS) // a_{t−1}
        .scalar(1.0) // vx
        .scalar(-1.0) // vy
        .scalar(-1.0); // yaw rate
    if extra.base_lin_vel {
        b = b.vector(POLAR);
    }
    if extra.base_ang_vel {
        b = b.vector(AXIAL);
    }
    if extra.gravity {
        b = b.vector(POLAR);
    }
    b = b.repeat(history, |f| f.per_leg(JOINTS).per_leg(JOINTS));
    if extra.gait_clock_hz > 0.0 {
        // φ ↦ φ + ½: the mirrored robot is half a cycle on.
        b = b.scalar(-1.0).scalar(-1.0);
    }
    b.build()
}

/// The left–right mirror of the actions (joint targets about q₀).
pub fn action_mirror() -> MirrorMap {
    MirrorBuilder::new().per_leg(JOINTS).build()
}

/// Refuses the mirror for a standing pose with a nonzero hip angle (q₀ is not its own mirror).
pub fn check_mirror_pose(q0: &LegMap<Vector3<f64>>) -> Result<(), String> {
    for leg in Leg::ALL {
        let (a, b) = (q0[leg], q0[leg.mirror()]);
        if (a.x + b.x).abs() > 1e-9 || (a.y - b.y).abs() > 1e-9 || (a.z - b.z).abs() > 1e-9 {
            return Err(format!(
                "the standing pose (leg.standing_pose_rad) is not its own mirror: {} {:?} against {} {:?}",
                leg.short_name(),
                a.as_slice(),
                leg.mirror().short_name(),
                b.as_slice()
            ));
        }
    }
    Ok(())
}

/// What a model-free policy remembers between its steps (the same in training and on the robot).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PolicyMemory {
    pub prev_action: Vec<f32>,
    /// Newest first.
    pub history: VecDeque<Vec<f32>>,
    pub last_torques: [f64; 12],
    /// The gait clock's phase φ ∈ [0, 1) and its advance per policy step (0: no clock).
    #[serde(default)]
    pub clock_phase: f64,
    #[serde(default)]
    pub clock_step: f64,
}

impl PolicyMemory {
    pub fn new(history: usize) -> Self {
        PolicyMemory {
            prev_action: vec![0.0; ACT_DIM],
            history: std::iter::repeat_n(vec![0.0; FRAME], history).collect(),
            last_torques: [0.0; 12],
            clock_phase: 0.0,
            clock_step: 0.0,
        }
    }

    /// The memory of a model-free policy of `config` (history and gait clock).
    pub fn for_config(config: &ModelFreeConfig) -> Self {
        let mut m = Self::new(config.history);
        m.clock_step = config.extra_obs.gait_clock_hz * config.policy_period_s;
        m
    }

    /// Fills the history with the current frame (an episode's start).
    pub fn start(&mut self, state: &RobotState, q0: &LegMap<Vector3<f64>>) {
        let f = frame(state, q0);
        for h in self.history.iter_mut() {
            h.clone_from(&f);
        }
        self.prev_action.iter_mut().for_each(|a| *a = 0.0);
        self.last_torques = [0.0; 12];
        self.clock_phase = 0.0;
    }

    /// One policy period on: the gait clock moves whether or not the action was usable.
    pub fn advance_clock(&mut self) {
        self.clock_phase = (self.clock_phase + self.clock_step).rem_euclid(1.0);
    }

    /// After a policy step: remember the action and push the frame of the state it acted on.
    pub fn push(&mut self, state: &RobotState, q0: &LegMap<Vector3<f64>>, action: &[f32]) {
        self.prev_action.copy_from_slice(action);
        if !self.history.is_empty() {
            self.history.pop_back();
            self.history.push_front(frame(state, q0));
        }
    }
}

fn frame(state: &RobotState, q0: &LegMap<Vector3<f64>>) -> Vec<f32> {
    let mut f = Vec::with_capacity(FRAME);
    for leg in Leg::ALL {
        f.extend((state.joints[leg].q - q0[leg]).iter().map(|&v| v as f32));
    }
    for leg in Leg::ALL {
        f.extend(state.joints[leg].qd.iter().map(|&v| v as f32));
    }
    f
}

/// The observation (see the module docs), written into `out` (length `config.obs_dim()`).
/// Returns how many values it wrote (tasks that extend O^M append after them).
pub fn observe(
    extra: &ExtraObs,
    kin: &LegKinematics,
    q0: &LegMap<Vector3<f64>>,
    state: &RobotState,
    command: &VelocityCommand,
    memory: &PolicyMemory,
    out: &mut [f32],
) -> usize {
    let mut i = 0;
    let mut put = |v: f64| {
        out[i] = v as f32;
        i += 1;
    };
    for leg in Leg::ALL {
        (state.joints[leg].q - q0[leg]).iter().for_each(|&v| put(v));
    }
    for leg in Leg::ALL {
        state.joints[leg].qd.iter().for_each(|&v| put(v));
    }
    memory.last_torques.iter().for_each(|&v| put(v));
    for leg in Leg::ALL {
        kin.foot_position_body(leg, &state.joints[leg].q)
            .iter()
            .for_each(|&v| put(v));
    }
    memory.prev_action.iter().for_each(|&v| put(v as f64));
    put(command.vx_mps);
    put(command.vy_mps);
    put(command.yaw_rate_rps);
    let r_body_world = state.body.r_world_body.inverse();
    let e = extra;
    if e.base_lin_vel {
        (r_body_world * state.body.v_world)
            .iter()
            .for_each(|&v| put(v));
    }
    if e.base_ang_vel {
        (r_body_world * state.body.omega_world)
            .iter()
            .for_each(|&v| put(v));
    }
    if e.gravity {
        (r_body_world * Vector3::new(0.0, 0.0, -1.0))
            .iter()
            .for_each(|&v| put(v));
    }
    for h in &memory.history {
        h.iter().for_each(|&v| put(v as f64));
    }
    if e.gait_clock_hz > 0.0 {
        let a = std::f64::consts::TAU * memory.clock_phase;
        put(a.sin());
        put(a.cos());
    }
    i
}

/// Joint targets for an action: q₀ + scale · clip(a, ±clip).
pub fn joint_targets(
    config: &ModelFreeConfig,
    q0: &LegMap<Vector3<f64>>,
    action: &[f32],
) -> LegMap<Vector3<f64>> {
    targets_about(q0, config.action_scale, config.action_clip, action)
}

/// Joint targets origin + scale · clip(a, ±clip).
pub fn targets_about(
    origin: &LegMap<Vector3<f64>>,
    scale: f64,
    clip: f64,
    action: &[f32],
) -> LegMap<Vector3<f64>> {
    LegMap::from_fn(|leg| {
        let k = 3 * leg.index();
        let a = |j: usize| (action[k + j] as f64).clamp(-clip, clip);
        origin[leg] + Vector3::new(a(0), a(1), a(2)) * scale
    })
}

// ---- reward terms: value before weight and period ----

/// exp(−|v*_xy − v_xy|²/σ), heading frame.
pub fn tracking_lin_vel(cmd: &VelocityCommand, v_heading: &Vector3<f64>, sigma: f64) -> f64 {
    let e2 = (cmd.vx_mps - v_heading.x).powi(2) + (cmd.vy_mps - v_heading.y).powi(2);
    (-e2 / sigma).exp()
}

/// exp(−(ω*_z − ω_z)²/σ).
pub fn tracking_ang_vel(cmd: &VelocityCommand, yaw_rate: f64, sigma: f64) -> f64 {
    (-(cmd.yaw_rate_rps - yaw_rate).powi(2) / sigma).exp()
}

/// v_z² (world).
pub fn lin_vel_z(v_world: &Vector3<f64>) -> f64 {
    v_world.z * v_world.z
}

/// (v_z − v_z,ref)² (world): the tracking row's vertical term against a reference.
pub fn lin_vel_z_error(v_world: &Vector3<f64>, vz_ref: f64) -> f64 {
    (v_world.z - vz_ref).powi(2)
}

/// Σ q̈², with q̈ from the velocity change over one policy period.
pub fn joint_acc(qd: &[f64; 12], qd_prev: &[f64; 12], dt: f64) -> f64 {
    qd.iter()
        .zip(qd_prev)
        .map(|(a, b)| ((a - b) / dt).powi(2))
        .sum()
}

/// Σ (a − a_prev)².
pub fn action_rate(a: &[f32], a_prev: &[f32]) -> f64 {
    a.iter()
        .zip(a_prev)
        .map(|(x, y)| (*x as f64 - *y as f64).powi(2))
        .sum()
}

/// Σ over feet touching down now of (air time − target): rewards long swings (legged_gym).
pub fn feet_air_time(first_contact_air_times: &[f64], target_s: f64) -> f64 {
    first_contact_air_times.iter().map(|t| t - target_s).sum()
}

/// Number of non-foot contacts with the ground.
pub fn collision(non_foot_contacts: usize) -> f64 {
    non_foot_contacts as f64
}

/// |g_xy|² of gravity in the body frame (0 when level).
pub fn orientation(r_world_body: &UnitQuaternion<f64>) -> f64 {
    let g = r_world_body.inverse() * Vector3::new(0.0, 0.0, -1.0);
    g.x * g.x + g.y * g.y
}

/// ω_x² + ω_y² in the body frame.
pub fn ang_vel_xy(omega_body: &Vector3<f64>) -> f64 {
    omega_body.x.powi(2) + omega_body.y.powi(2)
}

/// Σ τ².
pub fn torques(tau: &[f64; 12]) -> f64 {
    tau.iter().map(|t| t * t).sum()
}

/// Σ distance beyond 90 % of each joint's range, rad (`ranges`: per leg, in `q`'s order).
pub fn joint_limits(q: &[f64; 12], ranges: &[[[f64; 2]; 3]; 4]) -> f64 {
    q.iter()
        .enumerate()
        .map(|(i, &x)| {
            let [lo, hi] = ranges[i / 3][i % 3];
            let (mid, half) = ((lo + hi) / 2.0, (hi - lo) / 2.0 * 0.9);
            (x - (mid + half)).max(0.0) + ((mid - half) - x).max(0.0)
        })
        .sum()
}

/// Σ over feet of |sole height − target| · √|v_xy| (mujoco_playground): 0 for feet at rest,
/// and for moving feet only at the swing height.
pub fn feet_clearance(sole_heights_m: &[f64; 4], speeds_xy: &[f64; 4], target_m: f64) -> f64 {
    sole_heights_m
        .iter()
        .zip(speeds_xy)
        .map(|(z, v)| (z - target_m).abs() * v.sqrt())
        .sum()
}

/// Which feet the trot schedule wants on the ground at clock phase φ: FL and RR swing in
/// [0, ½), FR and RL in [½, 1).
pub fn scheduled_stance(clock_phase: f64) -> LegMap<bool> {
    let first_half = clock_phase.rem_euclid(1.0) < 0.5;
    LegMap::from_fn(|leg| match leg {
        Leg::FrontLeft | Leg::RearRight => !first_half,
        Leg::FrontRight | Leg::RearLeft => first_half,
    })
}

/// Share of the feet whose contact state is the schedule's, in [0, 1].
pub fn gait_schedule(loaded: &LegMap<bool>, scheduled: &LegMap<bool>) -> f64 {
    Leg::ALL
        .iter()
        .filter(|&&l| loaded[l] == scheduled[l])
        .count() as f64
        / 4.0
}

/// Σ |q̇ τ|, W.
pub fn energy(qd: &[f64; 12], tau: &[f64; 12]) -> f64 {
    qd.iter().zip(tau).map(|(a, b)| (a * b).abs()).sum()
}

pub(crate) fn flat(m: &LegMap<Vector3<f64>>) -> [f64; 12] {
    let mut out = [0.0; 12];
    for leg in Leg::ALL {
        out[3 * leg.index()..3 * leg.index() + 3].copy_from_slice(m[leg].as_slice());
    }
    out
}

/// What one policy period of joint PD at the physics rate ended in.
pub(crate) struct PdPeriod {
    /// The robot fell or touched the ground with its trunk (the period stops there).
    pub fell: bool,
    /// MuJoCo reported an instability (counted as a fall too).
    pub unstable: bool,
    /// Joint torques of the last physics step.
    pub last_tau: [f64; 12],
    /// The drives' electrical power averaged over the period's physics steps, W (0 without a
    /// motor model).
    pub motor_power_w: f64,
}

/// Steps the closed loop `substeps` times under the joint PD; `motor` (the robot's motor model)
/// charges each physics step.
pub(crate) fn run_pd_period(
    loop_: &mut ClosedLoop,
    pd: &mut JointPd,
    command: VelocityCommand,
    substeps: usize,
    motor: Option<&MotorModel>,
) -> PdPeriod {
    let mut last_tau = [0.0; 12];
    let (mut energy_w_steps, mut n) = (0.0, 0usize);
    let (fell, unstable) = run_period(loop_, pd, command, substeps, &mut |r| {
        last_tau = flat(&r.output.torques);
        if let Some(m) = motor {
            energy_w_steps += m.motor_power_w(&r.state.joints.map(|_, j| j.qd), &r.output.torques);
            n += 1;
        }
    });
    PdPeriod {
        fell,
        unstable,
        last_tau,
        motor_power_w: if n > 0 {
            energy_w_steps / n as f64
        } else {
            0.0
        },
    }
}

/// Steps the closed loop `substeps` times under any controller, showing each step to
/// `observer`; stops early on a fall, a trunk contact or a MuJoCo instability. Returns
/// (fell, unstable) — an instability counts as a fall too.
pub(crate) fn run_period(
    loop_: &mut ClosedLoop,
    controller: &mut dyn eemp_core::controller::Controller,
    command: VelocityCommand,
    substeps: usize,
    observer: &mut dyn FnMut(&eemp_sim::closed_loop::StepRecord),
) -> (bool, bool) {
    for _ in 0..substeps {
        let out = loop_.step(controller, command, observer);
        match loop_.episode_end(out) {
            Some(EpisodeEnd::Unstable) => return (true, true),
            Some(EpisodeEnd::Fell) => return (true, false),
            None => {}
        }
    }
    (false, false)
}

/// Task state that a checkpoint must carry to continue bit for bit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelFreeSnapshot {
    pub sim: SimSnapshot,
    /// The episode's pushes still to come, (s from the episode's start, Δv world), and the
    /// simulation time the episode started at (training pushes are velocity steps).
    #[serde(default)]
    pub pushes: Vec<(f64, [f64; 3])>,
    #[serde(default)]
    pub episode_start_s: Option<f64>,
    pub memory: PolicyMemory,
    pub command: VelocityCommand,
    pub steps: usize,
    pub first_episode: bool,
    pub air_time: [f64; 4],
    pub last_contact: [bool; 4],
    pub qd_prev: [f64; 12],
}

pub struct ModelFreeEnv {
    config: ModelFreeConfig,
    kin: LegKinematics,
    q0: LegMap<Vector3<f64>>,
    joint_ranges: [[[f64; 2]; 3]; 4],
    foot_radius_m: f64,
    loop_: ClosedLoop,
    pd: JointPd,
    memory: PolicyMemory,
    command: VelocityCommand,
    steps: usize,
    max_steps: usize,
    substeps: usize,
    first_episode: bool,
    /// Stagger first episodes (training); off for gymnasium.
    staggered_start: bool,
    air_time: [f64; 4],
    last_contact: [bool; 4],
    qd_prev: [f64; 12],
    fell: bool,
    /// The robot's motor model, for the `electrical_power` reward term.
    motor: Option<MotorModel>,
}

/// The training model: the robot on flat ground at the training time step.
pub fn training_model(
    robot: &RobotConfig,
    config: &ModelFreeConfig,
) -> Result<Arc<MjModel>, String> {
    let mut robot = robot.clone();
    robot.simulation.timestep_s = config.train_timestep_s;
    build_model(&robot, &SceneExtras::default()).map_err(|e| e.to_string())
}

impl super::OnClosedLoop for ModelFreeEnv {
    fn closed_loop_mut(&mut self) -> &mut ClosedLoop {
        &mut self.loop_
    }
}

impl ModelFreeEnv {
    pub fn new(
        robot: &RobotConfig,
        model: Arc<MjModel>,
        config: ModelFreeConfig,
    ) -> Result<Self, String> {
        config.validate().map_err(|e| e.to_string())?;
        let motor = robot.motor_model();
        if config.rewards.electrical_power != 0.0 && motor.is_none() {
            return Err(format!(
                "rewards.electrical_power = {} needs the robot's motor model, and the {} robot \
                 file has no [motor] section",
                config.rewards.electrical_power, robot.name
            ));
        }
        let sim = Simulation::with_model(model, robot).map_err(|e| e.to_string())?;
        let q0 = robot.standing_pose();
        let kin = LegKinematics::new(robot);
        let substeps = (config.policy_period_s / sim.timestep_s()).round() as usize;
        Ok(ModelFreeEnv {
            joint_ranges: Leg::ALL.map(|leg| robot.joint_ranges_rad(leg)),
            kin,
            foot_radius_m: robot.leg.foot_radius_m,
            q0,
            loop_: ClosedLoop::new(sim, &[], robot.scale()),
            pd: JointPd {
                gains: config.pd.clone(),
                targets: q0,
                torque_limit_nm: robot.leg.torque_limit_nm,
            },
            memory: PolicyMemory::for_config(&config),
            command: VelocityCommand::default(),
            steps: 0,
            max_steps: (config.episode_s / config.policy_period_s).round() as usize,
            substeps,
            first_episode: true,
            staggered_start: true,
            air_time: [0.0; 4],
            last_contact: [true; 4],
            qd_prev: [0.0; 12],
            fell: false,
            motor,
            config,
        })
    }

    pub fn command(&self) -> VelocityCommand {
        self.command
    }

    pub fn sim(&self) -> &Simulation {
        self.loop_.sim()
    }

    fn sample_command(&mut self, rng: &mut ChaCha8Rng) {
        let c = &self.config.commands;
        let u = |rng: &mut ChaCha8Rng, r: [f64; 2]| {
            if r[1] > r[0] {
                rng.random_range(r[0]..r[1])
            } else {
                r[0]
            }
        };
        let vx = u(rng, c.vx_mps);
        let (vy, w) = if rng.random::<f64>() < c.straight_prob {
            (0.0, 0.0)
        } else {
            (u(rng, c.vy_mps), u(rng, c.yaw_rate_rps))
        };
        self.command = VelocityCommand {
            vx_mps: vx,
            vy_mps: vy,
            yaw_rate_rps: w,
        };
    }

    fn write_obs(&self, obs: &mut [f32]) {
        let state = self.loop_.observed_state();
        observe(
            &self.config.extra_obs,
            &self.kin,
            &self.q0,
            &state,
            &self.command,
            &self.memory,
            obs,
        );
    }

    pub fn snapshot(&self) -> ModelFreeSnapshot {
        ModelFreeSnapshot {
            sim: self.loop_.sim().snapshot(),
            pushes: self
                .loop_
                .pending_pushes()
                .iter()
                .map(|p| (p.at_s, p.dv_world.into()))
                .collect(),
            episode_start_s: Some(self.loop_.episode_start_s()),
            memory: self.memory.clone(),
            command: self.command,
            steps: self.steps,
            first_episode: self.first_episode,
            air_time: self.air_time,
            last_contact: self.last_contact,
            qd_prev: self.qd_prev,
        }
    }

    pub fn restore(&mut self, s: &ModelFreeSnapshot) -> Result<(), String> {
        self.loop_
            .sim_mut()
            .restore(&s.sim)
            .map_err(|e| e.to_string())?;
        let pushes: Vec<Push> = s
            .pushes
            .iter()
            .map(|(at_s, dv)| Push::step(*at_s, Vector3::from(*dv)))
            .collect();
        match s.episode_start_s {
            Some(t) => self.loop_.resume(&pushes, t),
            None => self.loop_.restart(&pushes),
        }
        self.memory = s.memory.clone();
        self.command = s.command;
        self.steps = s.steps;
        self.first_episode = s.first_episode;
        self.air_time = s.air_time;
        self.last_contact = s.last_contact;
        self.qd_prev = s.qd_prev;
        self.pd.targets = joint_targets(&self.config, &self.q0, &self.memory.prev_action);
        Ok(())
    }
}

impl Env for ModelFreeEnv {
    fn obs_dim(&self) -> usize {
        self.config.obs_dim()
    }
    fn act_dim(&self) -> usize {
        ACT_DIM
    }
    fn reward_terms(&self) -> &'static [&'static str] {
        &REWARD_TERMS
    }

    fn reset(&mut self, rng: &mut ChaCha8Rng, obs: &mut [f32]) {
        let noise = self.config.reset_joint_noise_rad;
        let joints = self.q0.map(|_, q| {
            q + Vector3::from_fn(|_, _| {
                if noise > 0.0 {
                    rng.random_range(-noise..noise)
                } else {
                    0.0
                }
            })
        });
        let start = StartPose::standing(&self.kin, self.foot_radius_m, joints);
        let sim = self.loop_.sim_mut();
        sim.reset(
            Vector3::new(0.0, 0.0, start.trunk_height_m + 0.005),
            &start.joints,
        );
        let vn = self.config.reset_vel_noise_mps;
        if vn > 0.0 {
            let yaw: f64 = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
            let data = sim.data_mut();
            data.qpos_mut()[3..7].copy_from_slice(&[
                (yaw / 2.0).cos(),
                0.0,
                0.0,
                (yaw / 2.0).sin(),
            ]);
            data.qvel_mut()[0] = rng.random_range(-vn..vn);
            data.qvel_mut()[1] = rng.random_range(-vn..vn);
            data.forward();
        }
        let pushes = self.config.pushes.draw(self.config.episode_s, rng);
        self.loop_.restart(&pushes);
        self.sample_command(rng);
        let state = self.loop_.sim().ground_truth_state();
        self.memory.start(&state, &self.q0);
        self.pd.targets = self.q0;
        // The first episode of each env starts at a random time, so truncations spread out.
        self.steps = if self.first_episode && self.staggered_start {
            rng.random_range(0..self.max_steps)
        } else {
            0
        };
        self.first_episode = false;
        self.air_time = [0.0; 4];
        self.last_contact = [true; 4];
        self.qd_prev = flat(&state.joints.map(|_, j| j.qd));
        self.fell = false;
        self.write_obs(obs);
    }

    fn step(
        &mut self,
        action: &[f32],
        rng: &mut ChaCha8Rng,
        obs: &mut [f32],
        terms: &mut [f64],
    ) -> StepInfo {
        let cfg = &self.config;
        let state_before = self.loop_.sim().ground_truth_state();
        self.pd.targets = joint_targets(cfg, &self.q0, action);
        let PdPeriod {
            fell,
            unstable,
            last_tau,
            motor_power_w,
        } = run_pd_period(
            &mut self.loop_,
            &mut self.pd,
            self.command,
            self.substeps,
            self.motor.as_ref(),
        );
        let dt = cfg.policy_period_s;
        let sim = self.loop_.sim();
        let state = sim.ground_truth_state();
        let contacts = self.loop_.loaded();
        let mut sole = [0.0; 4];
        let mut speed = [0.0; 4];
        for leg in Leg::ALL {
            let q = &state.joints[leg];
            let r = state.body.r_world_body;
            let p_body = self.kin.foot_position_body(leg, &q.q);
            let v_world = state.body.v_world
                + state.body.omega_world.cross(&(r * p_body))
                + r * (self.kin.foot_jacobian_body(leg, &q.q) * q.qd);
            sole[leg.index()] = (state.body.p_world + r * p_body).z - self.foot_radius_m;
            speed[leg.index()] = v_world.x.hypot(v_world.y);
        }
        let qd = flat(&state.joints.map(|_, j| j.qd));
        let q = flat(&state.joints.map(|_, j| j.q));
        let omega_body = state.body.r_world_body.inverse() * state.body.omega_world;
        let mut first_contact_air = Vec::new();
        for leg in Leg::ALL {
            let i = leg.index();
            let c = contacts[leg];
            let filt = c || self.last_contact[i];
            if filt && self.air_time[i] > 0.0 && c {
                first_contact_air.push(self.air_time[i] + dt);
            }
            self.air_time[i] = if filt { 0.0 } else { self.air_time[i] + dt };
            self.last_contact[i] = c;
        }
        let cmd = self.command;
        let moving = cmd.vx_mps.hypot(cmd.vy_mps) > 0.1;
        let values = [
            tracking_lin_vel(&cmd, &state.body.v_heading(), cfg.tracking_sigma),
            tracking_ang_vel(&cmd, state.body.omega_world.z, cfg.tracking_sigma),
            lin_vel_z(&state.body.v_world),
            joint_acc(&qd, &self.qd_prev, dt),
            action_rate(action, &self.memory.prev_action),
            if moving {
                feet_air_time(&first_contact_air, cfg.air_time_target_s)
            } else {
                0.0
            },
            collision(sim.leg_ground_contacts(0.06)),
            orientation(&state.body.r_world_body),
            ang_vel_xy(&omega_body),
            torques(&last_tau),
            joint_limits(&q, &self.joint_ranges),
            energy(&qd, &last_tau),
            feet_clearance(&sole, &speed, cfg.clearance_height_m),
            // The phase the period just ran under (push() below advances it).
            gait_schedule(&contacts, &scheduled_stance(self.memory.clock_phase)),
            motor_power_w,
        ];
        let mut reward = 0.0;
        for ((t, v), w) in terms.iter_mut().zip(values).zip(cfg.rewards.as_array()) {
            *t = v * w * dt;
            reward += *t;
        }
        // (NaN.max(0) is 0: check before clipping, so a broken step is seen as one.)
        let reward_finite = reward.is_finite();
        if cfg.only_positive_rewards {
            reward = reward.max(0.0);
        }
        self.qd_prev = qd;
        self.memory.last_torques = last_tau;
        self.memory.push(&state_before, &self.q0, action);
        self.memory.advance_clock();
        self.steps += 1;
        let resample = (cfg.commands.resample_s / dt).round() as usize;
        if !fell && resample > 0 && self.steps.is_multiple_of(resample) {
            self.sample_command(rng);
        }
        self.fell = fell;
        self.write_obs(obs);
        StepInfo {
            reward,
            terminated: fell,
            truncated: !fell && self.steps >= self.max_steps,
            invalid: !state.body.is_finite() || !reward_finite || unstable,
            periods: None,
        }
    }

    fn restart(&mut self) {
        self.first_episode = true;
    }
    fn set_staggered_start(&mut self, on: bool) {
        self.staggered_start = on;
    }
    fn fell(&self) -> bool {
        self.fell
    }
    fn observe(&self, obs: &mut [f32]) {
        self.write_obs(obs)
    }
    fn save_state(&self) -> serde_json::Value {
        serde_json::to_value(self.snapshot()).expect("serialises")
    }
    fn load_state(&mut self, s: &serde_json::Value) -> Result<(), String> {
        let snap: ModelFreeSnapshot =
            serde_json::from_value(s.clone()).map_err(|e| format!("model-free env state: {e}"))?;
        self.restore(&snap)
    }
    fn mirror_maps(&self) -> Result<(MirrorMap, MirrorMap), String> {
        check_mirror_pose(&self.q0)?;
        Ok((
            observation_mirror(&self.config.extra_obs, self.config.history),
            action_mirror(),
        ))
    }
}

#[cfg(test)]
mod push_tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn training_pushes_come_once_per_slot_within_their_bounds_and_repeat_with_the_seed() {
        let p = TrainPushes {
            every_s: 4.0,
            max_dv_mps: 0.6,
        };
        p.validate().unwrap();
        let draw = |seed| p.draw(20.0, &mut ChaCha8Rng::seed_from_u64(seed));
        let a = draw(3);
        assert_eq!(a.len(), 4); // slots at 4, 8, 12, 16 s
        for (k, push) in a.iter().enumerate() {
            let slot = 4.0 * (k + 1) as f64;
            assert!(push.at_s >= slot && push.at_s < slot + 2.0, "{}", push.at_s);
            assert!(push.dv_world.x.abs() <= 0.6 && push.dv_world.y.abs() <= 0.6);
            assert_eq!(push.dv_world.z, 0.0);
            assert_eq!(push.duration_s, 0.0);
        }
        assert_eq!(a, draw(3));
        assert_ne!(a, draw(4));
        // Off: no pushes, and the RNG is not touched (runs without pushes are unchanged).
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        assert!(TrainPushes::default().draw(20.0, &mut rng).is_empty());
        assert_eq!(rng, ChaCha8Rng::seed_from_u64(3));
        let bad = TrainPushes {
            every_s: 0.1,
            max_dv_mps: 0.6,
        };
        assert!(bad.validate().unwrap_err().to_string().contains("every_s"));
    }
}
