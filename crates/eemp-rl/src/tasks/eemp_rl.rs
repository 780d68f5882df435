//! EEMP-RL (paper Sec. III-C): PPO chooses the planner's five parameters
//! a = [ΔT, h_step, X_z, r_x, r_y] continuously instead of a per-speed table.
//!
//! - Action: five numbers squashed into Table I's ranges, p = lo + (hi − lo)·(tanh(a) + 1)/2
//!   ([`squash`]), held for one decision interval.
//! - Decision interval: a fixed `decision_period_s` (0.5 s by default: two to five swings at
//!   Table I's swing times, long enough for a parameter change to show in CoT and short enough to
//!   follow the command changes; a per-swing decision would give the free gait, whose swings
//!   start at no fixed rate, decision intervals of very different lengths and rewards).
//! - Observation O^I: q − q₀, q̇, τ, feet (body), a_{t−1}, the command, trunk velocity, angular
//!   velocity and gravity in the body frame, q_ref (IK of the planner's swing references; stance
//!   legs keep their angles), the parameters in force (normalised) and t/t_max.
//! - Reward (row 4 of the paper's table), over the interval: −w10·CoT (eq. 8, E/(m g ΔD), clipped
//!   at `cot_clip`) + w11·manipulability (eq. 9, mean over the stance legs) + w12·t/t_max.
//! - 20 s episodes; the commanded speed changes within the episode (0.05–1.0 m/s, a new one every
//!   `command_every_s`), so the policy meets the transitions; free gait.

use super::model_free::run_period;
use crate::env::{Env, StepInfo};
use eemp_core::body_state::RobotState;
use eemp_core::config_error::{check_range, ConfigError};
use eemp_core::control::Controller;
use eemp_core::eemp_controller::{EempController, ParamsSource};
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::metrics::{cost_of_transport_dimensionless, force_manipulability, positive_power_w};
use eemp_core::planner::params::table_i;
use eemp_core::planner::{FreePairing, Gait, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_sim::closed_loop::{ClosedLoop, FallLimits};
use eemp_sim::walk::{eemp_controller, reset_to_start, StartPose, WalkSpec};
use eemp_sim::Simulation;
use mujoco_rs::prelude::MjModel;
use nalgebra::Vector3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

pub const ACT_DIM: usize = 5;

/// Table I's range of each action component, in action order.
pub const RANGES: [[f64; 2]; ACT_DIM] = [
    table_i::SWING_TIME_S,
    table_i::STEP_HEIGHT_M,
    table_i::BODY_HEIGHT_M,
    table_i::ELLIPSE_AXIS_M,
    table_i::ELLIPSE_AXIS_M,
];

/// The planner parameters of an action (never outside Table I).
pub fn squash(action: &[f32]) -> PlannerParams {
    let p = |i: usize| {
        let [lo, hi] = RANGES[i];
        let a = action[i] as f64;
        let s = if a.is_finite() {
            (a.tanh() + 1.0) / 2.0
        } else {
            0.5
        };
        (lo + (hi - lo) * s).clamp(lo, hi)
    };
    PlannerParams {
        swing_time_s: p(0),
        step_height_m: p(1),
        body_height_m: p(2),
        ellipse_rx_m: p(3),
        ellipse_ry_m: p(4),
    }
}

/// The action that [`squash`] maps to `params` (inside the ranges).
pub fn unsquash(params: &PlannerParams) -> [f32; ACT_DIM] {
    let v = [
        params.swing_time_s,
        params.step_height_m,
        params.body_height_m,
        params.ellipse_rx_m,
        params.ellipse_ry_m,
    ];
    let mut a = [0f32; ACT_DIM];
    for i in 0..ACT_DIM {
        let [lo, hi] = RANGES[i];
        let s = ((v[i] - lo) / (hi - lo)).clamp(1e-9, 1.0 - 1e-9);
        a[i] = (2.0 * s - 1.0).atanh() as f32;
    }
    a
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EempRlRewards {
    /// w10 on −CoT.
    pub cot: f64,
    /// w11 on manipulability.
    pub manipulability: f64,
    /// w12 on t/t_max.
    pub time: f64,
}

impl Default for EempRlRewards {
    fn default() -> Self {
        // A walking gait's step reward stays positive (CoT ≈ 0.2, manipulability ≈ 3), so
        // that falling early never pays.
        EempRlRewards {
            cot: 0.3,
            manipulability: 0.1,
            time: 1.0,
        }
    }
}

pub const REWARD_TERMS: [&str; 3] = ["cot", "manipulability", "time"];

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EempRlConfig {
    pub decision_period_s: f64,
    pub episode_s: f64,
    /// Commanded forward speeds, m/s (Table I's range by default).
    pub vx_mps: [f64; 2],
    /// A new command every this long, s.
    pub command_every_s: f64,
    pub rewards: EempRlRewards,
    /// CoT of an interval is clipped here (a standing interval has no distance).
    pub cot_clip: f64,
    /// The controller lowers the MPC's friction after slips (`eemp_core::slip`). Off by
    /// default: the shipped policy was trained without it, and a policy runs with the
    /// controller it was trained with (with an early form of the adapter on, floor 0.1–0.2,
    /// the 450 k policy fell in 0 to 6 of the comparison's 30 runs depending on the floor,
    /// against 1 without; the 700 k policy at floor 0.1 in 4, against 0).
    pub adapt_friction: bool,
    /// When the free gait swings a diagonal partner along (`eemp_core::planner::FreePairing`).
    /// The earlier rule (`FreePairing::UNPAIRED`) by default: the shipped policy was trained
    /// with it, and a policy runs with the controller it was trained with.
    pub free_pairing: FreePairing,
}

impl Default for EempRlConfig {
    fn default() -> Self {
        EempRlConfig {
            decision_period_s: 0.5,
            episode_s: 20.0,
            vx_mps: table_i::SPEED_MPS,
            command_every_s: 5.0,
            rewards: EempRlRewards::default(),
            cot_clip: 1.5,
            adapt_friction: false,
            free_pairing: FreePairing::UNPAIRED,
        }
    }
}

impl EempRlConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range(
            "eemp_rl.decision_period_s",
            self.decision_period_s,
            0.02,
            5.0,
        )?;
        check_range(
            "eemp_rl.episode_s",
            self.episode_s,
            self.decision_period_s,
            3600.0,
        )?;
        check_range("eemp_rl.vx_mps[0]", self.vx_mps[0], 0.0, 1.5)?;
        check_range("eemp_rl.vx_mps[1]", self.vx_mps[1], self.vx_mps[0], 1.5)?;
        check_range("eemp_rl.command_every_s", self.command_every_s, 0.1, 3600.0)?;
        self.free_pairing.validate("eemp_rl.free_pairing")?;
        for (n, w) in REWARD_TERMS.iter().zip([
            self.rewards.cot,
            self.rewards.manipulability,
            self.rewards.time,
        ]) {
            check_range(&format!("eemp_rl.rewards.{n}"), w, -1e3, 1e3)?;
        }
        check_range("eemp_rl.cot_clip", self.cot_clip, 0.01, 100.0)
    }

    pub fn obs_dim(&self) -> usize {
        4 * 12 + ACT_DIM + 3 + 9 + 12 + ACT_DIM + 1
    }
}

/// The walk an EEMP-RL env runs: EEMP with the free gait and constant parameters.
pub fn walk_spec(config: &EempRlConfig, params: PlannerParams) -> WalkSpec {
    let mut spec = WalkSpec::constant(
        PlannerConfig {
            gait: Gait::Free,
            free_pairing: config.free_pairing,
            ..Default::default()
        },
        params,
        VelocityCommand::default(),
        config.episode_s,
    );
    spec.controller.slip.adapt_friction = config.adapt_friction;
    spec
}

/// What the interval's reward needs, summed over its physics steps.
#[derive(Clone, Debug, Default)]
struct Interval {
    energy_j: f64,
    start_xy: Option<[f64; 2]>,
    end_xy: [f64; 2],
    manip_sum: f64,
    manip_n: usize,
}

pub struct EempRlEnv {
    config: EempRlConfig,
    robot: RobotConfig,
    kin: LegKinematics,
    q0: LegMap<Vector3<f64>>,
    loop_: ClosedLoop,
    controller: EempController,
    start: StartPose,
    command: VelocityCommand,
    prev_action: [f32; ACT_DIM],
    params: PlannerParams,
    last_tau: LegMap<Vector3<f64>>,
    q_ref: LegMap<Vector3<f64>>,
    steps: usize,
    max_steps: usize,
    substeps: usize,
    fell: bool,
}

impl super::OnClosedLoop for EempRlEnv {
    fn closed_loop_mut(&mut self) -> &mut ClosedLoop {
        &mut self.loop_
    }
}

impl EempRlEnv {
    pub fn new(
        robot: &RobotConfig,
        model: Arc<MjModel>,
        config: EempRlConfig,
    ) -> Result<Self, String> {
        config.validate().map_err(|e| e.to_string())?;
        let sim = Simulation::with_model(model, robot).map_err(|e| e.to_string())?;
        let params = PlannerParams::default();
        let spec = walk_spec(&config, params);
        let controller = eemp_controller(robot, &spec).map_err(|e| e.to_string())?;
        let start = StartPose::eemp(robot, &spec).map_err(|e| e.to_string())?;
        let substeps = (config.decision_period_s / sim.timestep_s()).round() as usize;
        Ok(EempRlEnv {
            max_steps: (config.episode_s / config.decision_period_s).round() as usize,
            substeps,
            kin: LegKinematics::new(robot),
            q0: robot.standing_pose(),
            loop_: ClosedLoop::new(sim, &[], FallLimits::default()),
            controller,
            start,
            command: VelocityCommand::default(),
            prev_action: unsquash(&params),
            params,
            last_tau: LegMap::splat(Vector3::zeros()),
            q_ref: robot.standing_pose(),
            steps: 0,
            fell: false,
            robot: robot.clone(),
            config,
        })
    }

    pub fn sim(&self) -> &Simulation {
        self.loop_.sim()
    }

    fn sample_command(&mut self, rng: &mut ChaCha8Rng) {
        let [lo, hi] = self.config.vx_mps;
        self.command = VelocityCommand {
            vx_mps: if hi > lo {
                rng.random_range(lo..hi)
            } else {
                lo
            },
            ..Default::default()
        };
    }

    fn write_obs(&self, out: &mut [f32]) {
        let s = self.loop_.observed_state();
        write_observation(
            &ObsParts {
                kin: &self.kin,
                q0: &self.q0,
                last_tau: &self.last_tau,
                prev_action: &self.prev_action,
                command: &self.command,
                q_ref: &self.q_ref,
                params: &self.params,
                progress: self.steps as f64 / self.max_steps.max(1) as f64,
            },
            &s,
            out,
        );
    }
}

fn write_observation(o: &ObsParts, s: &RobotState, out: &mut [f32]) {
    let mut i = 0;
    let mut put = |v: f64| {
        out[i] = v as f32;
        i += 1;
    };
    for leg in Leg::ALL {
        (s.joints[leg].q - o.q0[leg]).iter().for_each(|&v| put(v));
    }
    for leg in Leg::ALL {
        s.joints[leg].qd.iter().for_each(|&v| put(v));
    }
    for leg in Leg::ALL {
        o.last_tau[leg].iter().for_each(|&v| put(v));
    }
    for leg in Leg::ALL {
        o.kin
            .foot_position_body(leg, &s.joints[leg].q)
            .iter()
            .for_each(|&v| put(v));
    }
    o.prev_action.iter().for_each(|&v| put(v as f64));
    put(o.command.vx_mps);
    put(o.command.vy_mps);
    put(o.command.yaw_rate_rps);
    let r = s.body.r_world_body.inverse();
    (r * s.body.v_world).iter().for_each(|&v| put(v));
    (r * s.body.omega_world).iter().for_each(|&v| put(v));
    (r * Vector3::new(0.0, 0.0, -1.0))
        .iter()
        .for_each(|&v| put(v));
    for leg in Leg::ALL {
        (o.q_ref[leg] - o.q0[leg]).iter().for_each(|&v| put(v));
    }
    let p = o.params;
    for (v, [lo, hi]) in [
        p.swing_time_s,
        p.step_height_m,
        p.body_height_m,
        p.ellipse_rx_m,
        p.ellipse_ry_m,
    ]
    .iter()
    .zip(RANGES)
    {
        put((v - lo) / (hi - lo) * 2.0 - 1.0);
    }
    put(o.progress);
}

/// q_ref: IK of the plan's swing references; stance legs keep their measured angles.
fn reference_joints(
    kin: &LegKinematics,
    plan: Option<&eemp_core::controller::Plan>,
    s: &RobotState,
) -> LegMap<Vector3<f64>> {
    LegMap::from_fn(|leg| {
        plan.and_then(|p| p.swing[leg])
            .and_then(|sw| kin.inverse(leg, &sw.p_body).ok())
            .unwrap_or(s.joints[leg].q)
    })
}

impl Env for EempRlEnv {
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
        self.sample_command(rng);
        let spec = walk_spec(&self.config, self.params);
        // A fresh controller per episode: the planner keeps swing state.
        if let Ok(c) = eemp_controller(&self.robot, &spec) {
            self.controller = c;
        }
        let seed: u64 = rng.random_range(1..u64::MAX);
        reset_to_start(self.loop_.sim_mut(), &self.start, seed);
        self.loop_.restart(&[]);
        self.params = PlannerParams::default();
        self.prev_action = unsquash(&self.params);
        self.controller.params = ParamsSource::Constant(self.params);
        self.last_tau = LegMap::splat(Vector3::zeros());
        let s = self.loop_.sim().ground_truth_state();
        self.q_ref = s.joints.map(|_, j| j.q);
        self.steps = 0;
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
        self.params = squash(action);
        self.controller.params = ParamsSource::Constant(self.params);
        let mut iv = Interval::default();
        let dt = self.loop_.sim().timestep_s();
        let kin = &self.kin;
        let last_tau = &mut self.last_tau;
        let (fell, unstable) = run_period(
            &mut self.loop_,
            &mut self.controller,
            self.command,
            self.substeps,
            &mut |r| {
                let qd = r.state.joints.map(|_, j| j.qd);
                let p = r.state.body.p_world;
                iv.energy_j += positive_power_w(&qd, &r.output.torques) * dt;
                iv.start_xy.get_or_insert([p.x, p.y]);
                iv.end_xy = [p.x, p.y];
                let stance = r.stance();
                let (mut sum, mut n) = (0.0, 0);
                for leg in Leg::ALL.into_iter().filter(|l| stance[*l]) {
                    if let Some(v) =
                        force_manipulability(&kin.foot_jacobian_body(leg, &r.state.joints[leg].q))
                    {
                        sum += v;
                        n += 1;
                    }
                }
                if n > 0 {
                    iv.manip_sum += sum / n as f64;
                    iv.manip_n += 1;
                }
                *last_tau = r.output.torques;
            },
        );
        let s = self.loop_.sim().ground_truth_state();
        self.q_ref = reference_joints(&self.kin, self.controller.plan(), &s);
        let dist = iv
            .start_xy
            .map(|a| (iv.end_xy[0] - a[0]).hypot(iv.end_xy[1] - a[1]))
            .unwrap_or(0.0);
        // Eq. (8), dimensionless; an interval without distance counts as the clip.
        let cot = cost_of_transport_dimensionless(iv.energy_j, self.robot.total_mass_kg(), dist)
            .filter(|_| dist > 1e-6)
            .map_or(self.config.cot_clip, |c| c.min(self.config.cot_clip));
        let manip = if iv.manip_n > 0 {
            iv.manip_sum / iv.manip_n as f64
        } else {
            0.0
        };
        self.steps += 1;
        let w = &self.config.rewards;
        let values = [
            -cot * w.cot,
            manip * w.manipulability,
            w.time * self.steps as f64 / self.max_steps as f64,
        ];
        let mut reward = 0.0;
        for (t, v) in terms.iter_mut().zip(values) {
            *t = if fell { 0.0 } else { v };
            reward += *t;
        }
        let every = (self.config.command_every_s / self.config.decision_period_s).round() as usize;
        if !fell && every > 0 && self.steps.is_multiple_of(every) {
            self.sample_command(rng);
        }
        self.prev_action.copy_from_slice(&action[..ACT_DIM]);
        self.fell = fell;
        self.write_obs(obs);
        StepInfo {
            reward,
            terminated: fell,
            truncated: !fell && self.steps >= self.max_steps,
            invalid: !s.body.is_finite() || !reward.is_finite() || unstable,
        }
    }

    fn fell(&self) -> bool {
        self.fell
    }
    fn observe(&self, obs: &mut [f32]) {
        self.write_obs(obs)
    }
    fn save_state(&self) -> serde_json::Value {
        // The planner's swing state is not serialisable: a resumed run restarts the episodes in
        // flight, from a seed stored here (deterministic, but not equal to an uninterrupted run).
        serde_json::json!({ "restart_seed": (self.steps as u64) ^ 0xEE3F_0000_u64 })
    }
    fn load_state(&mut self, s: &serde_json::Value) -> Result<(), String> {
        use rand::SeedableRng;
        let seed = s["restart_seed"]
            .as_u64()
            .ok_or("EEMP-RL env state: no restart_seed")?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut obs = vec![0f32; self.obs_dim()];
        self.reset(&mut rng, &mut obs);
        Ok(())
    }
}

/// What chooses the parameters of an [`EempRlController`]: a trained policy, or a fixed answer
/// (tests, baselines).
pub trait ParamsPolicy {
    fn act(&mut self, obs: &[f32]) -> Option<Vec<f32>>;
}

impl ParamsPolicy for crate::policy::Policy {
    fn act(&mut self, obs: &[f32]) -> Option<Vec<f32>> {
        crate::policy::Policy::act(self, obs).ok()
    }
}

/// The same action every decision.
pub struct FixedAction(pub [f32; ACT_DIM]);

impl ParamsPolicy for FixedAction {
    fn act(&mut self, _obs: &[f32]) -> Option<Vec<f32>> {
        Some(self.0.to_vec())
    }
}

/// EEMP whose parameters a policy picks every decision interval (the same observation as the
/// training environment). Drop-in for `eemp walk` and the comparison.
pub struct EempRlController<P: ParamsPolicy> {
    pub eemp: EempController,
    policy: P,
    config: EempRlConfig,
    kin: LegKinematics,
    q0: LegMap<Vector3<f64>>,
    next_decision_s: f64,
    decisions: usize,
    max_decisions: usize,
    prev_action: [f32; ACT_DIM],
    params: PlannerParams,
    last_tau: LegMap<Vector3<f64>>,
    obs: Vec<f32>,
    /// Decisions whose action was not finite (the parameters in force were kept).
    pub invalid_decisions: usize,
}

impl<P: ParamsPolicy> EempRlController<P> {
    pub fn new(robot: &RobotConfig, config: EempRlConfig, policy: P) -> Result<Self, String> {
        config.validate().map_err(|e| e.to_string())?;
        let params = PlannerParams::default();
        let eemp =
            eemp_controller(robot, &walk_spec(&config, params)).map_err(|e| e.to_string())?;
        Ok(EempRlController {
            eemp,
            policy,
            kin: LegKinematics::new(robot),
            q0: robot.standing_pose(),
            next_decision_s: f64::NEG_INFINITY,
            decisions: 0,
            max_decisions: (config.episode_s / config.decision_period_s).round() as usize,
            prev_action: unsquash(&params),
            params,
            last_tau: LegMap::splat(Vector3::zeros()),
            obs: vec![0.0; config.obs_dim()],
            invalid_decisions: 0,
            config,
        })
    }

    /// The start pose EEMP-RL walks from (EEMP's, at Table II's height).
    pub fn start_pose(robot: &RobotConfig, config: &EempRlConfig) -> Result<StartPose, String> {
        StartPose::eemp(robot, &walk_spec(config, PlannerParams::default()))
            .map_err(|e| e.to_string())
    }
}

impl<P: ParamsPolicy> Controller for EempRlController<P> {
    fn control(
        &mut self,
        input: &eemp_core::control::ControlInput,
    ) -> eemp_core::controller::ControlOutput {
        let s = input.state;
        if s.time_s + 1e-9 >= self.next_decision_s {
            let q_ref = reference_joints(&self.kin, self.eemp.plan(), s);
            write_observation(
                &ObsParts {
                    kin: &self.kin,
                    q0: &self.q0,
                    last_tau: &self.last_tau,
                    prev_action: &self.prev_action,
                    command: &input.command,
                    q_ref: &q_ref,
                    params: &self.params,
                    progress: self.decisions as f64 / self.max_decisions.max(1) as f64,
                },
                s,
                &mut self.obs,
            );
            match self
                .policy
                .act(&self.obs)
                .filter(|a| a.len() == ACT_DIM && a.iter().all(|v| v.is_finite()))
            {
                Some(a) => {
                    self.params = squash(&a);
                    self.prev_action.copy_from_slice(&a);
                }
                None => self.invalid_decisions += 1,
            }
            self.eemp.params = ParamsSource::Constant(self.params);
            self.decisions += 1;
            self.next_decision_s = if self.next_decision_s.is_finite() {
                self.next_decision_s + self.config.decision_period_s
            } else {
                s.time_s + self.config.decision_period_s
            };
        }
        let out = self.eemp.control(input);
        self.last_tau = out.torques;
        out
    }
    fn plan(&self) -> Option<&eemp_core::controller::Plan> {
        self.eemp.plan()
    }
    fn steps(&self) -> Option<LegMap<usize>> {
        self.eemp.steps()
    }
    fn last_planning_time_s(&self) -> f64 {
        self.eemp.last_planning_time_s()
    }
}

/// Everything the observation is made of besides the state.
struct ObsParts<'a> {
    kin: &'a LegKinematics,
    q0: &'a LegMap<Vector3<f64>>,
    last_tau: &'a LegMap<Vector3<f64>>,
    prev_action: &'a [f32; ACT_DIM],
    command: &'a VelocityCommand,
    q_ref: &'a LegMap<Vector3<f64>>,
    params: &'a PlannerParams,
    progress: f64,
}
