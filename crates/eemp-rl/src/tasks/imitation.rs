//! The motion-imitation baseline of the paper (Sec. II-C, after Peng et al. 2020): a policy
//! follows a retargeted dog gait cycle, played at a rate and stride set by the commanded speed
//! (see [`crate::imitation::reference`]), and outputs joint targets tracked by the joint PD.
//!
//! Observation O^I = O^M (as the model-free task, with its extras and history) + the reference
//! at the current phase and at `future_s` ahead: q_ref (12) and X_ref = feet in the body frame
//! (12), root height and roll, pitch (3), each frame 27; + sin/cos of the phase and the
//! playback rate and stride scale (4).
//! Rewards: the paper's terms (1) joint and foot position kernels and (2) velocity tracking,
//! each a named function with its weight in [`ImitationRewards`], plus switchable shaping.
//! Reference-state initialisation and early termination as Peng et al.: start at a random phase
//! in the reference's pose with `rsi_prob`; end on a fall, a trunk contact or a root more than
//! `root_drift_limit_m` from where the command would have taken it.

use super::model_free::{
    action_rate, base_obs_dim, collision, lin_vel_z_error, observe, orientation, run_pd_period,
    targets_about, torques, tracking_ang_vel, tracking_lin_vel, ExtraObs, PdPeriod, PolicyMemory,
};
use crate::env::{Env, StepInfo};
use crate::imitation::motion::ReferenceMotion;
use crate::imitation::reference::{RefSample, ReferenceCycle, SpeedMapping};
use eemp_core::body_state::{BodyState, LegJointState, RobotState};
use eemp_core::config_error::{check_range, ConfigError};
use eemp_core::joint_pd::{JointPd, PdGains};
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::planner::VelocityCommand;
use eemp_core::robot::RobotConfig;
use eemp_sim::backend::SimSnapshot;
use eemp_sim::closed_loop::ClosedLoop;
use eemp_sim::walk::StartPose;
use eemp_sim::Simulation;
use mujoco_rs::prelude::MjModel;
use nalgebra::{UnitQuaternion, Vector2, Vector3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

pub const ACT_DIM: usize = 12;
/// One reference frame in the observation.
const REF_FRAME: usize = 27;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImitationRewards {
    // (1) imitation
    pub joint_pos: f64,
    pub foot_pos: f64,
    // (2) tracking
    pub tracking_lin_vel: f64,
    pub tracking_ang_vel: f64,
    pub lin_vel_z: f64,
    // shaping (not in the paper's row (1)+(2); the model-free task's terms)
    pub orientation: f64,
    pub action_rate: f64,
    pub torques: f64,
    pub collision: f64,
}

impl Default for ImitationRewards {
    fn default() -> Self {
        ImitationRewards {
            joint_pos: 1.0,
            foot_pos: 1.0,
            tracking_lin_vel: 1.0,
            tracking_ang_vel: 0.5,
            lin_vel_z: -2.0,
            orientation: -1.0,
            action_rate: -0.01,
            torques: -2e-4,
            collision: -1.0,
        }
    }
}

pub const REWARD_TERMS: [&str; 9] = [
    "joint_pos",
    "foot_pos",
    "tracking_lin_vel",
    "tracking_ang_vel",
    "lin_vel_z",
    "orientation",
    "action_rate",
    "torques",
    "collision",
];

impl ImitationRewards {
    fn as_array(&self) -> [f64; 9] {
        [
            self.joint_pos,
            self.foot_pos,
            self.tracking_lin_vel,
            self.tracking_ang_vel,
            self.lin_vel_z,
            self.orientation,
            self.action_rate,
            self.torques,
            self.collision,
        ]
    }
}

/// Where an action's joint targets are measured from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ActionOrigin {
    /// q_ref at the next policy step + scaled action (a residual on the reference).
    Reference,
    /// The standing pose + scaled action (Peng et al.'s pose offsets).
    DefaultPose,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImitationConfig {
    /// The reference motion (a file of `eemp retarget`), read when training starts and stored
    /// inside the policy file.
    pub motion_file: String,
    pub policy_period_s: f64,
    pub train_timestep_s: f64,
    pub pd: PdGains,
    pub action_origin: ActionOrigin,
    pub action_scale: f64,
    pub action_clip: f64,
    pub history: usize,
    pub extra_obs: ExtraObs,
    /// Reference frames in the observation besides the current one, s ahead.
    pub future_s: Vec<f64>,
    pub speed_mapping: SpeedMapping,
    /// Forward speed commands sampled per episode (and at each resampling), m/s. The clip
    /// walks straight: no lateral or yaw commands.
    pub vx_mps: [f64; 2],
    pub resample_s: f64,
    pub episode_s: f64,
    pub rewards: ImitationRewards,
    /// σ of the joint kernel exp(−Σ(q − q_ref)²/σ), rad² (Peng et al.'s scale 5 → 0.2).
    pub sigma_joint: f64,
    /// σ of the foot kernel, m² (Peng et al.'s scale 40 → 0.025).
    pub sigma_foot: f64,
    /// σ of the velocity-tracking kernels, (m/s)² and (rad/s)².
    pub sigma_track: f64,
    pub only_positive_rewards: bool,
    /// Probability of starting an episode in the reference's state at a random phase.
    pub rsi_prob: f64,
    pub root_drift_limit_m: f64,
    pub reset_joint_noise_rad: f64,
}

impl Default for ImitationConfig {
    fn default() -> Self {
        ImitationConfig {
            motion_file: "motions/a1_trot.csv".into(),
            policy_period_s: 0.02,
            train_timestep_s: 0.004,
            pd: PdGains::default(),
            action_origin: ActionOrigin::Reference,
            action_scale: 0.25,
            action_clip: 5.0,
            history: 1,
            extra_obs: ExtraObs::default(),
            future_s: vec![0.04, 0.2],
            speed_mapping: SpeedMapping::default(),
            vx_mps: [0.0, 1.0],
            resample_s: 10.0,
            episode_s: 20.0,
            rewards: ImitationRewards::default(),
            sigma_joint: 0.2,
            sigma_foot: 0.025,
            sigma_track: 0.25,
            only_positive_rewards: true,
            rsi_prob: 0.9,
            root_drift_limit_m: 1.0,
            reset_joint_noise_rad: 0.05,
        }
    }
}

impl ImitationConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        let p = "imitation";
        if self.extra_obs.gait_clock_hz != 0.0 {
            return Err(ConfigError::Invalid {
                name: format!("{p}.extra_obs.gait_clock_hz"),
                message: format!(
                    "{} is not allowed: the reference motion's phase is the imitation policy's clock (use 0)",
                    self.extra_obs.gait_clock_hz
                ),
            });
        }
        check_range(
            &format!("{p}.policy_period_s"),
            self.policy_period_s,
            0.002,
            0.1,
        )?;
        check_range(
            &format!("{p}.train_timestep_s"),
            self.train_timestep_s,
            0.0005,
            0.005,
        )?;
        let ratio = self.policy_period_s / self.train_timestep_s;
        if (ratio - ratio.round()).abs() > 1e-6 {
            return Err(ConfigError::Invalid {
                name: format!("{p}.policy_period_s"),
                message: format!(
                    "{} is not a whole number of train_timestep_s {}",
                    self.policy_period_s, self.train_timestep_s
                ),
            });
        }
        self.pd.validate()?;
        check_range(&format!("{p}.action_scale"), self.action_scale, 0.01, 2.0)?;
        check_range(&format!("{p}.action_clip"), self.action_clip, 0.1, 100.0)?;
        check_range(&format!("{p}.history"), self.history as f64, 0.0, 10.0)?;
        if self.future_s.len() > 8 {
            return Err(ConfigError::Invalid {
                name: format!("{p}.future_s"),
                message: format!("{} frames: allowed at most 8", self.future_s.len()),
            });
        }
        for (i, f) in self.future_s.iter().enumerate() {
            check_range(&format!("{p}.future_s[{i}]"), *f, 0.0, 2.0)?;
        }
        self.speed_mapping.validate(&format!("{p}.speed_mapping"))?;
        check_range(&format!("{p}.vx_mps[0]"), self.vx_mps[0], 0.0, 1.5)?;
        check_range(
            &format!("{p}.vx_mps[1]"),
            self.vx_mps[1],
            self.vx_mps[0],
            1.5,
        )?;
        check_range(&format!("{p}.resample_s"), self.resample_s, 0.1, 3600.0)?;
        check_range(&format!("{p}.episode_s"), self.episode_s, 0.1, 3600.0)?;
        for (name, w) in REWARD_TERMS.iter().zip(self.rewards.as_array()) {
            check_range(&format!("{p}.rewards.{name}"), w, -1e3, 1e3)?;
        }
        check_range(&format!("{p}.sigma_joint"), self.sigma_joint, 1e-4, 100.0)?;
        check_range(&format!("{p}.sigma_foot"), self.sigma_foot, 1e-5, 10.0)?;
        check_range(&format!("{p}.sigma_track"), self.sigma_track, 1e-3, 10.0)?;
        check_range(&format!("{p}.rsi_prob"), self.rsi_prob, 0.0, 1.0)?;
        check_range(
            &format!("{p}.root_drift_limit_m"),
            self.root_drift_limit_m,
            0.05,
            100.0,
        )?;
        check_range(
            &format!("{p}.reset_joint_noise_rad"),
            self.reset_joint_noise_rad,
            0.0,
            0.5,
        )
    }

    pub fn obs_dim(&self) -> usize {
        base_obs_dim(&self.extra_obs, self.history) + REF_FRAME * (1 + self.future_s.len()) + 4
    }
}

// ---- reward terms of row (1): value before weight and period ----

/// exp(−Σ_j (q_j − q_ref,j)²/σ).
pub fn joint_pos(q: &LegMap<Vector3<f64>>, q_ref: &LegMap<Vector3<f64>>, sigma: f64) -> f64 {
    let e2: f64 = Leg::ALL
        .iter()
        .map(|&l| (q[l] - q_ref[l]).norm_squared())
        .sum();
    (-e2 / sigma).exp()
}

/// exp(−Σ_feet |p − p_ref|²/σ), feet relative to the root in the heading frame with z the
/// height above the floor (Peng et al.'s end-effector term).
pub fn foot_pos(p: &LegMap<Vector3<f64>>, p_ref: &LegMap<Vector3<f64>>, sigma: f64) -> f64 {
    let e2: f64 = Leg::ALL
        .iter()
        .map(|&l| (p[l] - p_ref[l]).norm_squared())
        .sum();
    (-e2 / sigma).exp()
}

/// The robot's feet relative to its root in the heading frame, z above the floor (flat ground).
pub fn feet_heading(kin: &LegKinematics, state: &RobotState) -> LegMap<Vector3<f64>> {
    let (roll, pitch, _) = state.body.r_world_body.euler_angles();
    let r = UnitQuaternion::from_euler_angles(roll, pitch, 0.0);
    LegMap::from_fn(|leg| {
        r * kin.foot_position_body(leg, &state.joints[leg].q)
            + Vector3::new(0.0, 0.0, state.body.p_world.z)
    })
}

/// The reference-following state a policy carries (the same in training and on the robot).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImitationMemory {
    pub policy: PolicyMemory,
    /// Phase of the reference cycle, [0, 1).
    pub phase: f64,
}

/// What the imitation policy needs besides its network: the reference and the kinematics.
#[derive(Clone, Debug)]
pub struct ImitationAgent {
    pub config: ImitationConfig,
    pub cycle: ReferenceCycle,
    pub kin: LegKinematics,
    pub q0: LegMap<Vector3<f64>>,
}

impl ImitationAgent {
    pub fn new(config: ImitationConfig, motion: &ReferenceMotion, robot: &RobotConfig) -> Self {
        let kin = LegKinematics::new(robot);
        ImitationAgent {
            cycle: ReferenceCycle::new(motion, &kin, config.speed_mapping.clone()),
            config,
            kin,
            q0: robot.standing_pose(),
        }
    }

    pub fn reference(&self, phase: f64, vx_mps: f64) -> RefSample {
        let (_, stride) = self.cycle.scales(vx_mps);
        self.cycle.sample(&self.kin, phase, stride)
    }

    /// The phase one policy period after `phase` at the commanded speed.
    pub fn next_phase(&self, phase: f64, vx_mps: f64) -> f64 {
        (phase + self.cycle.phase_rate(vx_mps) * self.config.policy_period_s).rem_euclid(1.0)
    }

    pub fn observe(
        &self,
        state: &RobotState,
        command: &VelocityCommand,
        memory: &ImitationMemory,
        out: &mut [f32],
    ) {
        let mut i = observe(
            &self.config.extra_obs,
            &self.kin,
            &self.q0,
            state,
            command,
            &memory.policy,
            out,
        );
        let mut put = |v: f64| {
            out[i] = v as f32;
            i += 1;
        };
        let rate = self.cycle.phase_rate(command.vx_mps);
        for dt in std::iter::once(0.0).chain(self.config.future_s.iter().copied()) {
            let r = self.reference(memory.phase + rate * dt, command.vx_mps);
            for leg in Leg::ALL {
                r.q[leg].iter().for_each(|&v| put(v));
            }
            for leg in Leg::ALL {
                r.p_foot_body[leg].iter().for_each(|&v| put(v));
            }
            put(r.root_height_m);
            put(r.roll);
            put(r.pitch);
        }
        let a = 2.0 * std::f64::consts::PI * memory.phase;
        put(a.sin());
        put(a.cos());
        let (rate, stride) = self.cycle.scales(command.vx_mps);
        put(rate);
        put(stride);
    }

    /// Joint targets for an action taken at `phase` (they aim at the next step's reference).
    pub fn targets(&self, phase: f64, vx_mps: f64, action: &[f32]) -> LegMap<Vector3<f64>> {
        let origin = match self.config.action_origin {
            ActionOrigin::Reference => self.reference(self.next_phase(phase, vx_mps), vx_mps).q,
            ActionOrigin::DefaultPose => self.q0,
        };
        targets_about(
            &origin,
            self.config.action_scale,
            self.config.action_clip,
            action,
        )
    }
}

fn jitter(rng: &mut ChaCha8Rng, q: Vector3<f64>, noise: f64) -> Vector3<f64> {
    q + Vector3::from_fn(|_, _| {
        if noise > 0.0 {
            rng.random_range(-noise..noise)
        } else {
            0.0
        }
    })
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImitationSnapshot {
    pub sim: SimSnapshot,
    pub memory: ImitationMemory,
    pub command: VelocityCommand,
    pub steps: usize,
    pub first_episode: bool,
    pub p_ref_xy: [f64; 2],
    pub heading: f64,
}

pub struct ImitationEnv {
    agent: ImitationAgent,
    foot_radius_m: f64,
    loop_: ClosedLoop,
    pd: JointPd,
    memory: ImitationMemory,
    command: VelocityCommand,
    steps: usize,
    max_steps: usize,
    substeps: usize,
    first_episode: bool,
    /// Stagger first episodes (training); off for gymnasium.
    staggered_start: bool,
    /// Where the command would have taken the root (world xy) and the heading it walks in.
    p_ref_xy: Vector2<f64>,
    heading: f64,
    fell: bool,
}

impl super::OnClosedLoop for ImitationEnv {
    fn closed_loop_mut(&mut self) -> &mut ClosedLoop {
        &mut self.loop_
    }
}

impl ImitationEnv {
    pub fn new(
        robot: &RobotConfig,
        model: Arc<MjModel>,
        config: ImitationConfig,
        motion: &ReferenceMotion,
    ) -> Result<Self, String> {
        config.validate().map_err(|e| e.to_string())?;
        let sim = Simulation::with_model(model, robot).map_err(|e| e.to_string())?;
        let substeps = (config.policy_period_s / sim.timestep_s()).round() as usize;
        let max_steps = (config.episode_s / config.policy_period_s).round() as usize;
        let agent = ImitationAgent::new(config, motion, robot);
        Ok(ImitationEnv {
            foot_radius_m: robot.leg.foot_radius_m,
            loop_: ClosedLoop::new(sim, &[], robot.scale()),
            pd: JointPd {
                gains: agent.config.pd.clone(),
                targets: agent.q0,
                torque_limit_nm: robot.leg.torque_limit_nm,
            },
            memory: ImitationMemory {
                policy: PolicyMemory::new(agent.config.history),
                phase: 0.0,
            },
            command: VelocityCommand::default(),
            steps: 0,
            max_steps,
            substeps,
            first_episode: true,
            staggered_start: true,
            p_ref_xy: Vector2::zeros(),
            heading: 0.0,
            fell: false,
            agent,
        })
    }

    pub fn sim(&self) -> &Simulation {
        self.loop_.sim()
    }

    fn sample_command(&mut self, rng: &mut ChaCha8Rng) {
        let r = self.agent.config.vx_mps;
        let vx = if r[1] > r[0] {
            rng.random_range(r[0]..r[1])
        } else {
            r[0]
        };
        self.command = VelocityCommand {
            vx_mps: vx,
            vy_mps: 0.0,
            yaw_rate_rps: 0.0,
        };
    }

    fn write_obs(&self, obs: &mut [f32]) {
        let state = self.loop_.observed_state();
        self.agent.observe(&state, &self.command, &self.memory, obs);
    }

    pub fn snapshot(&self) -> ImitationSnapshot {
        ImitationSnapshot {
            sim: self.loop_.sim().snapshot(),
            memory: self.memory.clone(),
            command: self.command,
            steps: self.steps,
            first_episode: self.first_episode,
            p_ref_xy: [self.p_ref_xy.x, self.p_ref_xy.y],
            heading: self.heading,
        }
    }

    pub fn restore(&mut self, s: &ImitationSnapshot) -> Result<(), String> {
        self.loop_
            .sim_mut()
            .restore(&s.sim)
            .map_err(|e| e.to_string())?;
        self.loop_.restart(&[]);
        self.memory = s.memory.clone();
        self.command = s.command;
        self.steps = s.steps;
        self.first_episode = s.first_episode;
        self.p_ref_xy = Vector2::new(s.p_ref_xy[0], s.p_ref_xy[1]);
        self.heading = s.heading;
        // The targets of the last action are rebuilt from the phase it was taken at.
        let prev_phase = (self.memory.phase
            - self.agent.cycle.phase_rate(self.command.vx_mps) * self.agent.config.policy_period_s)
            .rem_euclid(1.0);
        self.pd.targets = self.agent.targets(
            prev_phase,
            self.command.vx_mps,
            &self.memory.policy.prev_action,
        );
        Ok(())
    }
}

impl Env for ImitationEnv {
    fn obs_dim(&self) -> usize {
        self.agent.config.obs_dim()
    }
    fn act_dim(&self) -> usize {
        ACT_DIM
    }
    fn reward_terms(&self) -> &'static [&'static str] {
        &REWARD_TERMS
    }

    fn reset(&mut self, rng: &mut ChaCha8Rng, obs: &mut [f32]) {
        self.sample_command(rng);
        let cfg = &self.agent.config;
        let vx = self.command.vx_mps;
        let yaw: f64 = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        let noise = cfg.reset_joint_noise_rad;
        let rsi = rng.random::<f64>() < cfg.rsi_prob;
        let r_yaw = UnitQuaternion::from_euler_angles(0.0, 0.0, yaw);
        if rsi {
            let phase: f64 = rng.random_range(0.0..1.0);
            let r = self.agent.reference(phase, vx);
            let (qd, vz) = self.agent.cycle.rates(&self.agent.kin, phase, vx);
            let joints = r.q.map(|_, q| jitter(rng, *q, noise));
            // Lowest reference foot on the floor: the reference height is for flat ground.
            let r_body = r_yaw * r.r_level_root();
            let lowest = Leg::ALL
                .iter()
                .map(|&l| (r_body * self.agent.kin.foot_position_body(l, &joints[l])).z)
                .fold(f64::INFINITY, f64::min);
            let state = RobotState {
                time_s: 0.0,
                body: BodyState {
                    p_world: Vector3::new(0.0, 0.0, -lowest + self.foot_radius_m + 0.002),
                    r_world_body: r_body,
                    v_world: r_yaw * Vector3::new(vx, 0.0, vz),
                    omega_world: Vector3::zeros(),
                },
                joints: LegMap::from_fn(|l| LegJointState {
                    q: joints[l],
                    qd: qd[l],
                }),
            };
            let sim = self.loop_.sim_mut();
            sim.reset(state.body.p_world, &state.joints.map(|_, j| j.q));
            sim.set_state(&state);
            self.memory.phase = phase;
        } else {
            let joints = self.agent.q0.map(|_, q| jitter(rng, *q, noise));
            let start = StartPose::standing(&self.agent.kin, self.foot_radius_m, joints);
            let sim = self.loop_.sim_mut();
            sim.reset(
                Vector3::new(0.0, 0.0, start.trunk_height_m + 0.005),
                &start.joints,
            );
            let q = r_yaw.coords;
            let data = sim.data_mut();
            data.qpos_mut()[3..7].copy_from_slice(&[q.w, q.x, q.y, q.z]);
            data.forward();
            self.memory.phase = 0.0;
        }
        self.loop_.restart(&[]);
        let state = self.loop_.sim().ground_truth_state();
        self.memory.policy.start(&state, &self.agent.q0);
        self.pd.targets = state.joints.map(|_, j| j.q);
        self.steps = if self.first_episode && self.staggered_start {
            rng.random_range(0..self.max_steps)
        } else {
            0
        };
        self.first_episode = false;
        self.p_ref_xy = state.body.p_world.xy();
        self.heading = yaw;
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
        let state_before = self.loop_.sim().ground_truth_state();
        let vx = self.command.vx_mps;
        self.pd.targets = self.agent.targets(self.memory.phase, vx, action);
        let PdPeriod {
            fell,
            unstable,
            last_tau,
            ..
        } = run_pd_period(
            &mut self.loop_,
            &mut self.pd,
            self.command,
            self.substeps,
            None,
        );
        let cfg = &self.agent.config;
        let dt = cfg.policy_period_s;
        let phase = self.agent.next_phase(self.memory.phase, vx);
        let reference = self.agent.reference(phase, vx);
        let (_, vz_ref) = self.agent.cycle.rates(&self.agent.kin, phase, vx);
        let sim = self.loop_.sim();
        let state = sim.ground_truth_state();
        let q = state.joints.map(|_, j| j.q);
        let cmd = self.command;
        let values = [
            joint_pos(&q, &reference.q, cfg.sigma_joint),
            foot_pos(
                &feet_heading(&self.agent.kin, &state),
                &reference.feet_heading(),
                cfg.sigma_foot,
            ),
            tracking_lin_vel(&cmd, &state.body.v_heading(), cfg.sigma_track),
            tracking_ang_vel(&cmd, state.body.omega_world.z, cfg.sigma_track),
            lin_vel_z_error(&state.body.v_world, vz_ref),
            orientation(&state.body.r_world_body),
            action_rate(action, &self.memory.policy.prev_action),
            torques(&last_tau),
            collision(sim.leg_ground_contacts(0.06)),
        ];
        let mut reward = 0.0;
        for ((t, v), w) in terms.iter_mut().zip(values).zip(cfg.rewards.as_array()) {
            *t = v * w * dt;
            reward += *t;
        }
        let reward_finite = reward.is_finite();
        if cfg.only_positive_rewards {
            reward = reward.max(0.0);
        }
        self.memory.policy.last_torques = last_tau;
        self.memory
            .policy
            .push(&state_before, &self.agent.q0, action);
        self.memory.phase = phase;
        let dir = Vector2::new(self.heading.cos(), self.heading.sin());
        self.p_ref_xy += dir * (cmd.vx_mps * dt);
        let drifted = (state.body.p_world.xy() - self.p_ref_xy).norm() > cfg.root_drift_limit_m;
        self.steps += 1;
        let resample = (cfg.resample_s / dt).round() as usize;
        let ended = fell || drifted;
        if !ended && resample > 0 && self.steps.is_multiple_of(resample) {
            self.sample_command(rng);
        }
        self.fell = fell;
        self.write_obs(obs);
        StepInfo {
            reward,
            terminated: ended,
            truncated: !ended && self.steps >= self.max_steps,
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
        let snap: ImitationSnapshot =
            serde_json::from_value(s.clone()).map_err(|e| format!("imitation env state: {e}"))?;
        self.restore(&snap)
    }
}
