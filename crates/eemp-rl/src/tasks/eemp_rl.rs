//! EEMP-RL (paper Sec. III-C): PPO chooses the planner's five parameters
//! a = [ΔT, h_step, X_z, r_x, r_y] continuously instead of a per-speed table.
//!
//! Two forms of the action ([`EempRlConfig::residual`]):
//! - **Residual** (the shipped policy): a bounded correction of the per-speed table's parameters
//!   at the commanded speed, p = clamp(table(v) + b ⊙ shrink(tanh(a)), the table's ranges)
//!   (Table I widened to the table's entries, `ParamsTable::param_ranges`; [`ResidualConfig`],
//!   shrink the `deadband`'s soft threshold, the identity at 0); a zero
//!   action is EEMP-Analytical bit for bit, and with a zero last layer an untrained policy is.
//!   Its reward pays for improving on the table ([`ResidualRewards`]).
//! - **Absolute** (the first policy, `a1_eemp_rl_v1`): five numbers squashed into Table I's
//!   ranges, p = lo + (hi − lo)·(tanh(a) + 1)/2 ([`squash`]), held for one decision interval,
//!   with the paper's row (4) reward. Described below.
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

use super::model_free::TrainPushes;
use crate::env::{Env, StepInfo};
use eemp_core::body_state::RobotState;
use eemp_core::config_error::{check_range, ConfigError};
use eemp_core::controller::Controller;
use eemp_core::eemp::{EempController, ParamsSource};
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::metrics::{
    cost_of_transport_dimensionless, force_manipulability, positive_power_w, CotObjective,
    MetricsAccumulator, WalkMetrics,
};
use eemp_core::planner::params::{table_i, TABLE_I_RANGES};
use eemp_core::planner::params_table::ParamsTable;
use eemp_core::planner::{FreePairing, Gait, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_sim::closed_loop::{ClosedLoop, EpisodeEnd, Push, StepRecord};
use eemp_sim::terrain::{FrictionPatch, Rough, Terrain};
use eemp_sim::walk::{
    eemp_controller, observe_metrics, reset_to_start, simulated_world, ModelError, StartPose,
    WalkSpec,
};
use eemp_sim::Simulation;
use mujoco_rs::prelude::MjModel;
use nalgebra::Vector3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::Arc;

pub const ACT_DIM: usize = 5;

/// Table I's range of each action component, in action order.
pub const RANGES: [[f64; 2]; ACT_DIM] = TABLE_I_RANGES;

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

/// The absolute form's reward terms (row 4 of the paper's table).
pub const REWARD_TERMS: [&str; 3] = ["cot", "manipulability", "time"];
/// The residual form's reward terms ([`ResidualRewards`]).
pub const RESIDUAL_REWARD_TERMS: [&str; 4] = ["energy", "tracking", "manipulability", "fall"];

/// The largest correction of each parameter a residual policy can make, |Δ| ≤ bound.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ResidualBounds {
    pub swing_time_s: f64,
    pub step_height_m: f64,
    pub body_height_m: f64,
    pub ellipse_rx_m: f64,
    pub ellipse_ry_m: f64,
}

impl Default for ResidualBounds {
    /// About a third of Table I's span of each parameter: enough to move between the grid's
    /// neighbouring points and beyond, not enough to leave the gait the table chose.
    fn default() -> Self {
        ResidualBounds {
            swing_time_s: 0.05,
            step_height_m: 0.03,
            body_height_m: 0.01,
            ellipse_rx_m: 0.04,
            ellipse_ry_m: 0.04,
        }
    }
}

impl ResidualBounds {
    pub fn to_array(&self) -> [f64; 5] {
        [
            self.swing_time_s,
            self.step_height_m,
            self.body_height_m,
            self.ellipse_rx_m,
            self.ellipse_ry_m,
        ]
    }
}

/// What the residual form rewards over a decision interval (all measured with the evaluation's
/// own metrics code, `eemp_sim::walk::observe_metrics`, on the simulator's state). Every term
/// is zero or negative for a robot that stands still under a walking command: nothing pays for
/// merely staying up.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ResidualRewards {
    /// w on 1 − CoT/CoT_table (eq. 8 over the interval against the table's CoT at the
    /// commanded speed, the ratio clipped to [0, `ratio_clip`]): +w·1 % per percent saved.
    /// Not counted while the command is below half of Table I's lowest speed.
    pub energy: f64,
    pub ratio_clip: f64,
    /// w on −MSE/(0.1 m/s)², the interval's mean squared velocity error (eq. 10's samples):
    /// 0.3 makes 0.01 m/s more RMSE at the table's typical 0.05 m/s cost as much as about 3 %
    /// more energy.
    pub tracking: f64,
    /// w on manipulability/manipulability_table − 1 (eq. 9, the paper's row 4 term, relative
    /// to the table's so that it is 0 for the table).
    pub manipulability: f64,
    /// Paid once, negatively, when the episode ends in a fall (which ends it).
    pub fall: f64,
    /// The energy the energy term's CoT counts: eq. (8) (the paper's) or the battery's
    /// electrical CoT under the robot file's motor model. It must be the one the table's `cot`
    /// counts (its `objective`), since the term is their ratio.
    #[serde(default, skip_serializing_if = "CotObjective::is_eq8")]
    pub objective: CotObjective,
}

impl Default for ResidualRewards {
    fn default() -> Self {
        ResidualRewards {
            energy: 1.0,
            ratio_clip: 3.0,
            tracking: 0.3,
            manipulability: 0.1,
            fall: 10.0,
            objective: CotObjective::Eq8,
        }
    }
}

/// EEMP-RL's residual form: the action corrects a per-speed table's parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ResidualConfig {
    /// The free gait's per-speed table the policy corrects (with each entry's CoT and
    /// manipulability, which the reward is relative to).
    pub table_file: PathBuf,
    pub bounds: ResidualBounds,
    /// Corrections within this share of their bound are not applied: each component's
    /// tanh(a) is soft-thresholded, sign(u)·max(|u| − d, 0)/(1 − d), so the full bound is still
    /// reachable and a policy whose mean sits inside the band walks exactly the table. 0: off
    /// (every policy trained before it). Why: PPO cannot resolve the ≤ 1 % CoT a few
    /// millimetres of ellipse cost on the flat floor (one decision window's CoT varies by
    /// more), so without it the corrections learnt on disturbed floors carried onto the flat
    /// one (issue 20, stage 2: 0.5–1 % above the table at 0.3–0.6 m/s).
    pub deadband: f64,
    /// Measure each window against the table's own walk over the same window, from the same
    /// state (a copy of the simulation, the filter and the controller, the same pushes and
    /// sensor noise): the energy, tracking and manipulability terms become the policy's minus
    /// the table's ([`paired_reward_terms`]). A correction the table does not need earns
    /// exactly 0 instead of the window's own ±1–3 % of CoT noise, which the plain reward left
    /// PPO to average out (issue 20). Costs a second simulation of every window. false: the
    /// plain reward (every policy trained before it).
    pub paired: bool,
    pub rewards: ResidualRewards,
    /// The table itself, read from `table_file` when a config file is loaded
    /// ([`ResidualConfig::read_table`]) and kept in a policy file's config, so that a policy
    /// always runs on the table it was trained on.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub table: Option<ParamsTable>,
}

impl Default for ResidualConfig {
    fn default() -> Self {
        ResidualConfig {
            table_file: "tables/a1_free.toml".into(),
            bounds: ResidualBounds::default(),
            deadband: 0.0,
            paired: false,
            rewards: ResidualRewards::default(),
            table: None,
        }
    }
}

impl ResidualConfig {
    /// Reads `table_file` into `table` (errors name the file).
    pub fn read_table(&mut self) -> Result<(), ConfigError> {
        self.table = Some(ParamsTable::load(&self.table_file)?);
        Ok(())
    }

    pub fn validate(&self) -> Result<(), ConfigError> {
        let file = self.table_file.display();
        for ((name, b), [lo, hi]) in PlannerParams::NAMES
            .iter()
            .zip(self.bounds.to_array())
            .zip(TABLE_I_RANGES)
        {
            // The bound is at most Table I's span: a larger one could never be used whole.
            check_range(&format!("eemp_rl.residual.bounds.{name}"), b, 1e-6, hi - lo)?;
        }
        check_range("eemp_rl.residual.deadband", self.deadband, 0.0, 0.9)?;
        let r = &self.rewards;
        for (n, w) in [
            ("energy", r.energy),
            ("tracking", r.tracking),
            ("manipulability", r.manipulability),
            ("fall", r.fall),
        ] {
            check_range(&format!("eemp_rl.residual.rewards.{n}"), w, 0.0, 1e3)?;
        }
        check_range(
            "eemp_rl.residual.rewards.ratio_clip",
            r.ratio_clip,
            1.0,
            100.0,
        )?;
        let table = self.table.as_ref().ok_or_else(|| ConfigError::Invalid {
            name: "eemp_rl.residual.table".into(),
            message: format!("{file} has not been read (ResidualConfig::read_table)"),
        })?;
        let invalid = |message: String| ConfigError::Invalid {
            name: format!("eemp_rl.residual.table_file {file}"),
            message,
        };
        table.validate().map_err(|e| invalid(e.to_string()))?;
        if table.objective != r.objective {
            return Err(ConfigError::Invalid {
                name: "eemp_rl.residual.rewards.objective".into(),
                message: format!(
                    "is \"{}\" but the cot of {file} counts \"{}\" (its objective): the energy \
                     term is their ratio (allowed: \"{}\", or a table selected under \"{}\")",
                    r.objective.name(),
                    table.objective.name(),
                    table.objective.name(),
                    r.objective.name()
                ),
            });
        }
        if table.gait != Gait::Free {
            return Err(invalid(format!(
                "is a table for the {} gait; EEMP-RL walks the free gait (e.g. tables/a1_free.toml)",
                table.gait
            )));
        }
        for (i, e) in table.entries.iter().enumerate() {
            if !e.cot.is_some_and(|c| c.is_finite() && c > 0.0)
                || !e.manipulability.is_some_and(|m| m.is_finite() && m > 0.0)
            {
                return Err(invalid(format!(
                    "entry[{i}] (speed {} m/s) needs a positive cot and manipulability (the \
                     reward is relative to them; `eemp sweep report` writes both)",
                    e.speed_mps
                )));
            }
        }
        Ok(())
    }

    fn table(&self) -> &ParamsTable {
        self.table.as_ref().expect("validated: the table is read")
    }

    /// The parameter correction of an action: Δ = bounds ⊙ shrink(tanh(a)), shrink the
    /// deadband's soft threshold, the teleop sticks' own deadzone-and-rescale (a non-finite
    /// component counts as 0).
    pub fn delta(&self, action: &[f32]) -> [f64; 5] {
        let b = self.bounds.to_array();
        std::array::from_fn(|i| {
            let a = action.get(i).copied().unwrap_or(0.0) as f64;
            if a.is_finite() {
                b[i] * eemp_core::teleop::deadzone(a.tanh(), self.deadband)
            } else {
                0.0
            }
        })
    }
}

/// When EEMP-RL decides.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DecisionTiming {
    /// Every `decision_period_s`.
    #[default]
    Period,
    /// At each touchdown (a leg the plan had in swing back in stance), at least
    /// `min_decision_s` and at most `decision_period_s` apart; a semi-MDP whose steps are
    /// discounted by γ^(length / decision_period_s).
    Touchdown,
}

/// The worlds EEMP-RL trains in: each environment gets its own floor (rough or flat, its
/// friction, perhaps a patch of lower friction ahead) and payload, drawn once from the run's
/// seed; pushes are drawn per episode. Terrain seeds start at `terrain_seed_base`, kept apart
/// from the low seeds the robustness suite's rough floor and runs use, so that a policy is not
/// evaluated on the very ground it trained on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrainWorlds {
    /// Share of the environments on rough ground.
    pub rough_share: f64,
    pub rough_amplitude_m: [f64; 2],
    pub rough_wavelength_m: [f64; 2],
    pub floor_friction: [f64; 2],
    /// Share of the environments with a patch of lower friction ahead of the start.
    pub patch_share: f64,
    pub patch_friction: [f64; 2],
    /// Where the patch starts ahead of the start, m, and how long it is.
    pub patch_start_m: [f64; 2],
    pub patch_length_m: [f64; 2],
    pub payload_kg: [f64; 2],
    pub pushes: TrainPushes,
    pub terrain_seed_base: u64,
    /// Share of the environments in the robot file's own world: its flat floor and friction,
    /// no payload, no pushes (the world the comparison measures; without any, the policy
    /// learns only corrections for disturbed worlds and carries them onto the flat floor).
    pub nominal_share: f64,
}

impl Default for TrainWorlds {
    fn default() -> Self {
        TrainWorlds {
            rough_share: 0.4,
            rough_amplitude_m: [0.005, 0.02],
            rough_wavelength_m: [0.3, 1.0],
            floor_friction: [0.3, 1.0],
            patch_share: 0.3,
            patch_friction: [0.2, 0.4],
            patch_start_m: [0.5, 4.0],
            patch_length_m: [0.5, 2.0],
            payload_kg: [0.0, 2.0],
            pushes: TrainPushes {
                every_s: 4.0,
                max_dv_mps: 0.5,
            },
            terrain_seed_base: 1000,
            nominal_share: 0.0,
        }
    }
}

/// One environment's world.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainWorld {
    pub terrain: Terrain,
    /// None: the robot file's.
    pub floor_friction: Option<f64>,
    pub payload_kg: f64,
    /// Whether episodes here get the run's pushes.
    pub pushes: bool,
}

impl TrainWorlds {
    pub fn validate(&self) -> Result<(), ConfigError> {
        let p = "eemp_rl.worlds";
        check_range(&format!("{p}.rough_share"), self.rough_share, 0.0, 1.0)?;
        check_range(&format!("{p}.patch_share"), self.patch_share, 0.0, 1.0)?;
        check_range(&format!("{p}.nominal_share"), self.nominal_share, 0.0, 1.0)?;
        for (name, [lo, hi], min, max) in [
            ("rough_amplitude_m", self.rough_amplitude_m, 0.001, 0.1),
            ("rough_wavelength_m", self.rough_wavelength_m, 0.1, 5.0),
            ("floor_friction", self.floor_friction, 0.05, 5.0),
            ("patch_friction", self.patch_friction, 0.05, 5.0),
            ("patch_start_m", self.patch_start_m, 0.0, 100.0),
            ("patch_length_m", self.patch_length_m, 0.05, 100.0),
            ("payload_kg", self.payload_kg, 0.0, 10.0),
        ] {
            check_range(&format!("{p}.{name}[0]"), lo, min, max)?;
            check_range(&format!("{p}.{name}[1]"), hi, lo, max)?;
        }
        self.pushes.validate_as(&format!("{p}.pushes"))
    }

    /// Environment `index`'s world, from the run's `seed` (the same for every thread count).
    pub fn draw(&self, seed: u64, index: usize) -> TrainWorld {
        use rand::SeedableRng;
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x3011_D5EE_D000 ^ (index as u64) << 20);
        let mut uniform = |[lo, hi]: [f64; 2]| {
            if hi > lo {
                rng.random_range(lo..hi)
            } else {
                lo
            }
        };
        let rough = uniform([0.0, 1.0]) < self.rough_share;
        let amplitude = uniform(self.rough_amplitude_m);
        let wavelength = uniform(self.rough_wavelength_m);
        let floor_friction = uniform(self.floor_friction);
        let patch = uniform([0.0, 1.0]) < self.patch_share;
        let patch_friction = uniform(self.patch_friction);
        let x0 = uniform(self.patch_start_m);
        let length = uniform(self.patch_length_m);
        let payload_kg = uniform(self.payload_kg);
        // Drawn last, so that the other draws are those of a config without it.
        if uniform([0.0, 1.0]) < self.nominal_share {
            return TrainWorld::nominal();
        }
        TrainWorld {
            terrain: Terrain {
                rough: rough.then(|| Rough {
                    amplitude_m: amplitude,
                    wavelength_m: wavelength,
                    seed: self.terrain_seed_base + index as u64,
                    size_m: 16.0,
                }),
                friction_patch: if patch {
                    vec![FrictionPatch {
                        x0_m: x0,
                        x1_m: x0 + length,
                        width_m: 4.0,
                        friction: patch_friction,
                    }]
                } else {
                    Vec::new()
                },
                ..Default::default()
            },
            floor_friction: Some(floor_friction),
            payload_kg,
            pushes: true,
        }
    }
}

impl TrainWorld {
    /// The robot file's own world: its flat floor and friction, no payload, no pushes.
    pub fn nominal() -> Self {
        TrainWorld {
            terrain: Terrain::default(),
            floor_friction: None,
            payload_kg: 0.0,
            pushes: false,
        }
    }

    /// The simulated robot (with the payload) and its MuJoCo model.
    pub fn build(&self, robot: &RobotConfig) -> Result<(RobotConfig, Arc<MjModel>), String> {
        let (r, scene) = simulated_world(
            robot,
            &self.terrain,
            self.floor_friction,
            &ModelError::default(),
            self.payload_kg,
        );
        let model = eemp_sim::backend::build_model(&r, &scene).map_err(|e| e.to_string())?;
        Ok((r, model))
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EempRlConfig {
    /// Time between decisions (with `decision = "touchdown"`: the longest), s.
    pub decision_period_s: f64,
    pub decision: DecisionTiming,
    /// With `decision = "touchdown"`: the shortest time between decisions, s.
    pub min_decision_s: f64,
    pub episode_s: f64,
    /// Commanded forward speeds, m/s (Table I's range by default).
    pub vx_mps: [f64; 2],
    /// A new command every this long, s.
    pub command_every_s: f64,
    /// The command is zero until this long into an episode, s (0.5: as `eemp walk` starts).
    pub command_start_s: f64,
    /// The absolute form's reward (row 4 of the paper's table).
    pub rewards: EempRlRewards,
    /// CoT of an interval is clipped here (a standing interval has no distance).
    pub cot_clip: f64,
    /// The controller lowers the MPC's friction after slips (`eemp_core::slip`). Off when a
    /// file does not say, as the earlier policies (v1, stage 1, touchdown) were trained; a
    /// policy runs with the controller it was trained with (its actions were learned against
    /// that controller's friction, and under another one it can fall where it walked). The
    /// shipped policy's config turns it on.
    pub adapt_friction: bool,
    /// When the free gait swings a diagonal partner along (`eemp_core::planner::FreePairing`).
    /// The earlier rule (`FreePairing::UNPAIRED`) when a file does not say, as the first
    /// policy was trained; the shipped config sets the current default.
    pub free_pairing: FreePairing,
    /// The MPC's weight on the motors' heat (`mpc.weight_heat`): 0 when a file does not say,
    /// as every policy trained before the heat term was (a policy runs with the controller it
    /// was trained with).
    pub mpc_weight_heat: f64,
    /// The residual form (None: the absolute form of the first policy).
    pub residual: Option<ResidualConfig>,
    /// Training worlds (None: the robot file's flat floor, no pushes, no payload).
    pub worlds: Option<TrainWorlds>,
}

impl Default for EempRlConfig {
    fn default() -> Self {
        EempRlConfig {
            decision_period_s: 0.5,
            decision: DecisionTiming::Period,
            min_decision_s: 0.1,
            episode_s: 20.0,
            vx_mps: table_i::SPEED_MPS,
            command_every_s: 5.0,
            command_start_s: 0.0,
            rewards: EempRlRewards::default(),
            cot_clip: 1.5,
            adapt_friction: false,
            free_pairing: FreePairing::UNPAIRED,
            mpc_weight_heat: 0.0,
            residual: None,
            worlds: None,
        }
    }
}

impl EempRlConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("eemp_rl.mpc_weight_heat", self.mpc_weight_heat, 0.0, 1.0)?;
        check_range(
            "eemp_rl.decision_period_s",
            self.decision_period_s,
            0.02,
            5.0,
        )?;
        check_range(
            "eemp_rl.min_decision_s",
            self.min_decision_s,
            0.001,
            self.decision_period_s,
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
        check_range(
            "eemp_rl.command_start_s",
            self.command_start_s,
            0.0,
            self.episode_s,
        )?;
        self.free_pairing.validate("eemp_rl.free_pairing")?;
        for (n, w) in REWARD_TERMS.iter().zip([
            self.rewards.cot,
            self.rewards.manipulability,
            self.rewards.time,
        ]) {
            check_range(&format!("eemp_rl.rewards.{n}"), w, -1e3, 1e3)?;
        }
        if let Some(r) = &self.residual {
            r.validate()?;
        }
        if let Some(w) = &self.worlds {
            w.validate()?;
        }
        check_range("eemp_rl.cot_clip", self.cot_clip, 0.01, 100.0)
    }

    /// Reads what the config's files hold (the residual's table); a config file's loader
    /// calls it before validating.
    pub fn read_files(&mut self) -> Result<(), ConfigError> {
        match &mut self.residual {
            Some(r) => r.read_table(),
            None => Ok(()),
        }
    }

    pub fn obs_dim(&self) -> usize {
        4 * 12 + ACT_DIM + 3 + 9 + 12 + ACT_DIM + 1
    }

    /// The parameters' source an action sets: the table corrected by the action (residual) or
    /// the squashed action itself (absolute).
    pub fn params_source(&self, action: &[f32]) -> ParamsSource {
        match &self.residual {
            Some(r) => ParamsSource::Residual {
                table: r.table().clone(),
                delta: r.delta(action),
            },
            None => ParamsSource::Constant(squash(action)),
        }
    }

    /// The source before the first decision: the table (residual) or Table II (absolute).
    pub fn initial_params_source(&self) -> ParamsSource {
        match &self.residual {
            Some(r) => ParamsSource::Residual {
                table: r.table().clone(),
                delta: [0.0; 5],
            },
            None => ParamsSource::Constant(PlannerParams::default()),
        }
    }

    /// The action before the first decision (what the observation shows as a_{t−1}).
    fn initial_action(&self) -> [f32; ACT_DIM] {
        match &self.residual {
            Some(_) => [0.0; ACT_DIM],
            None => unsquash(&PlannerParams::default()),
        }
    }

    /// The command at `t` into an episode whose sampled command is `sampled`.
    fn command_at(&self, t: f64, sampled: VelocityCommand) -> VelocityCommand {
        if t >= self.command_start_s {
            sampled
        } else {
            VelocityCommand::default()
        }
    }

    /// The start pose for a run whose first command is `first` (m/s): the table's X_z there
    /// (residual), Table II's (absolute).
    pub fn start_pose(
        &self,
        robot: &RobotConfig,
        first_speed_mps: f64,
    ) -> Result<StartPose, String> {
        let source = self.initial_params_source();
        let params = source.at_speed(first_speed_mps);
        StartPose::eemp(robot, &walk_spec(self, params)).map_err(|e| e.to_string())
    }
}

/// The walk an EEMP-RL env runs: EEMP with the free gait and constant parameters (the
/// residual's table sets eq. 6's progress factor it was selected with).
pub fn walk_spec(config: &EempRlConfig, params: PlannerParams) -> WalkSpec {
    let defaults = PlannerConfig::default();
    let progress_factor = config
        .residual
        .as_ref()
        .and_then(|r| r.table.as_ref())
        .and_then(|t| t.progress_factor)
        .unwrap_or(defaults.progress_factor);
    let mut spec = WalkSpec::constant(
        PlannerConfig {
            gait: Gait::Free,
            free_pairing: config.free_pairing,
            progress_factor,
            ..defaults
        },
        params,
        VelocityCommand::default(),
        config.episode_s,
    );
    spec.controller.slip.adapt_friction = config.adapt_friction;
    spec.controller.mpc.weight_heat = Some(config.mpc_weight_heat);
    spec
}

/// The legs the plan has back in stance that `before` had in swing (a touchdown).
fn touched_down(before: &LegMap<bool>, now: &LegMap<bool>) -> bool {
    Leg::ALL.into_iter().any(|l| !before[l] && now[l])
}

/// What the absolute form's reward needs, summed over its physics steps.
#[derive(Clone, Debug, Default)]
struct Interval {
    energy_j: f64,
    start_xy: Option<[f64; 2]>,
    end_xy: [f64; 2],
    manip_sum: f64,
    manip_n: usize,
}

impl Interval {
    fn observe(&mut self, kin: &LegKinematics, dt: f64, r: &StepRecord) {
        let qd = r.state.joints.map(|_, j| j.qd);
        let p = r.state.body.p_world;
        self.energy_j += positive_power_w(&qd, &r.output.torques) * dt;
        self.start_xy.get_or_insert([p.x, p.y]);
        self.end_xy = [p.x, p.y];
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
            self.manip_sum += sum / n as f64;
            self.manip_n += 1;
        }
    }
}

/// The residual form's reward terms, in [`RESIDUAL_REWARD_TERMS`]' order, for an interval
/// measured as `m` (eq. 8–10 over the interval) under a command of `speed_mps` whose table
/// entry recorded (CoT, manipulability) `table`.
pub fn residual_reward_terms(
    w: &ResidualRewards,
    m: &WalkMetrics,
    speed_mps: f64,
    table: (f64, f64),
    fell: bool,
) -> [f64; 4] {
    if fell {
        return [0.0, 0.0, 0.0, -w.fall];
    }
    let (cot_table, manip_table) = table;
    let walking = speed_mps >= 0.5 * table_i::SPEED_MPS[0];
    let energy = match (walking, w.objective.cot(m)) {
        (false, _) => 0.0,
        (true, Some(c)) if m.distance_m > 1e-6 => {
            w.energy * (1.0 - (c / cot_table).clamp(0.0, w.ratio_clip))
        }
        // No distance under a walking command: the worst ratio.
        (true, _) => w.energy * (1.0 - w.ratio_clip),
    };
    let mse = m.vel_rmse_mps.map_or(0.0, |r| r * r);
    let tracking = -w.tracking * mse / 0.01;
    let manipulability = m
        .manipulability
        .map_or(0.0, |v| w.manipulability * (v / manip_table - 1.0));
    [energy, tracking, manipulability, 0.0]
}

/// The paired form's reward terms ([`ResidualConfig::paired`]): the policy's window `m` and the
/// table's window `m_table` from the same state, each scored by [`residual_reward_terms`], and
/// the difference kept. A fall of the policy costs `fall` whatever the table did; where only the
/// table fell the window has nothing to compare and earns 0.
pub fn paired_reward_terms(
    w: &ResidualRewards,
    m: &WalkMetrics,
    m_table: &WalkMetrics,
    speed_mps: f64,
    table: (f64, f64),
    fell: bool,
    table_fell: bool,
) -> [f64; 4] {
    if fell || table_fell {
        return [0.0, 0.0, 0.0, if fell { -w.fall } else { 0.0 }];
    }
    let policy = residual_reward_terms(w, m, speed_mps, table, false);
    let baseline = residual_reward_terms(w, m_table, speed_mps, table, false);
    [
        policy[0] - baseline[0],
        policy[1] - baseline[1],
        policy[2] - baseline[2],
        0.0,
    ]
}

pub struct EempRlEnv {
    config: EempRlConfig,
    /// The nominal robot (the controller's model).
    robot: RobotConfig,
    /// The simulated robot's mass (with the world's payload), for eq. 8.
    mass_kg: f64,
    kin: LegKinematics,
    q0: LegMap<Vector3<f64>>,
    loop_: ClosedLoop,
    controller: EempController,
    command: VelocityCommand,
    prev_action: [f32; ACT_DIM],
    last_tau: LegMap<Vector3<f64>>,
    q_ref: LegMap<Vector3<f64>>,
    plan_stance: LegMap<bool>,
    steps: usize,
    max_steps: usize,
    substeps: usize,
    min_substeps: usize,
    fell: bool,
    last_interval: Option<WalkMetrics>,
    /// Whether this environment's world gets the training worlds' pushes.
    world_pushes: bool,
}

impl super::OnClosedLoop for EempRlEnv {
    fn closed_loop_mut(&mut self) -> &mut ClosedLoop {
        &mut self.loop_
    }
}

impl EempRlEnv {
    /// An environment on the robot file's flat floor, with `model` built from `robot`.
    pub fn new(
        robot: &RobotConfig,
        model: Arc<MjModel>,
        config: EempRlConfig,
    ) -> Result<Self, String> {
        Self::with_model(robot, robot, model, config)
    }

    /// An environment in `world` (its own MuJoCo model).
    pub fn in_world(
        robot: &RobotConfig,
        world: &TrainWorld,
        config: EempRlConfig,
    ) -> Result<Self, String> {
        let (simulated, model) = world.build(robot)?;
        let mut env = Self::with_model(robot, &simulated, model, config)?;
        env.world_pushes = world.pushes;
        Ok(env)
    }

    /// An environment whose controller models `robot` and whose simulation runs `simulated` on
    /// `model` (built by [`TrainWorld::build`]: several environments may share one model).
    pub fn with_model(
        robot: &RobotConfig,
        simulated: &RobotConfig,
        model: Arc<MjModel>,
        config: EempRlConfig,
    ) -> Result<Self, String> {
        config.validate().map_err(|e| e.to_string())?;
        if let Some(r) = &config.residual {
            if !r.rewards.objective.is_eq8() && robot.motor_model().is_none() {
                return Err(format!(
                    "eemp_rl.residual.rewards.objective = \"{}\" needs the robot's motor model: \
                     robot {} has no [motor] section (allowed: \"eq8\")",
                    r.rewards.objective.name(),
                    robot.name
                ));
            }
        }
        let sim = Simulation::with_model(model, simulated).map_err(|e| e.to_string())?;
        let source = config.initial_params_source();
        let spec = walk_spec(&config, source.at_speed(0.0));
        let mut controller = eemp_controller(robot, &spec).map_err(|e| e.to_string())?;
        controller.params = source;
        let dt = sim.timestep_s();
        Ok(EempRlEnv {
            max_steps: (config.episode_s / config.decision_period_s).round() as usize,
            substeps: (config.decision_period_s / dt).round() as usize,
            min_substeps: (config.min_decision_s / dt).round().max(1.0) as usize,
            mass_kg: simulated.total_mass_kg(),
            kin: LegKinematics::new(robot),
            q0: robot.standing_pose(),
            loop_: ClosedLoop::new(sim, &[], robot.scale()),
            controller,
            command: VelocityCommand::default(),
            prev_action: config.initial_action(),
            last_tau: LegMap::splat(Vector3::zeros()),
            q_ref: robot.standing_pose(),
            plan_stance: LegMap::splat(true),
            steps: 0,
            fell: false,
            last_interval: None,
            world_pushes: true,
            robot: robot.clone(),
            config,
        })
    }

    /// An empty accumulator for a decision interval: with the battery's account only where the
    /// reward counts electrical energy (`rewards.objective`), so eq. 8's training steps do not
    /// pay for it.
    fn interval_metrics(&self) -> MetricsAccumulator {
        let electrical = self
            .config
            .residual
            .as_ref()
            .is_some_and(|r| !r.rewards.objective.is_eq8());
        MetricsAccumulator::new(electrical.then(|| self.robot.motor_model()).flatten())
    }

    /// The last decision interval's metrics (eq. 8–10 over it; residual form only).
    pub fn last_interval(&self) -> Option<&WalkMetrics> {
        self.last_interval.as_ref()
    }

    pub fn sim(&self) -> &Simulation {
        self.loop_.sim()
    }

    /// The speed commanded now, m/s (0 before `command_start_s`): the speed the residual's
    /// table is read at.
    pub fn commanded_speed_mps(&self) -> f64 {
        let c = self.config.command_at(self.loop_.elapsed_s(), self.command);
        c.vx_mps.hypot(c.vy_mps)
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

    /// The table's walk over `steps` physics steps from the state in `loop_` and `controller`
    /// (copies taken before the policy's window): its metrics and whether it fell.
    fn table_window(
        &self,
        mut loop_: ClosedLoop,
        mut controller: EempController,
        steps: usize,
    ) -> (WalkMetrics, bool) {
        controller.params = self.config.initial_params_source();
        let dt = loop_.sim().timestep_s();
        let kin = &self.kin;
        let mut metrics = self.interval_metrics();
        let mut fell = false;
        for _ in 0..steps {
            let command = self.config.command_at(loop_.elapsed_s(), self.command);
            let out = loop_.step(&mut controller, command, &mut |r| {
                observe_metrics(&mut metrics, kin, dt, r, &r.stance())
            });
            if loop_.episode_end(out).is_some() {
                fell = true;
                break;
            }
        }
        (metrics.finish(self.mass_kg), fell)
    }

    fn write_obs(&self, out: &mut [f32]) {
        let s = self.loop_.observed_state();
        let command = self.config.command_at(self.loop_.elapsed_s(), self.command);
        write_observation(
            &ObsParts {
                kin: &self.kin,
                q0: &self.q0,
                last_tau: &self.last_tau,
                prev_action: &self.prev_action,
                command: &command,
                q_ref: &self.q_ref,
                params: &self
                    .controller
                    .params
                    .at_speed(command.vx_mps.hypot(command.vy_mps)),
                progress: self.steps as f64 / self.max_steps.max(1) as f64,
            },
            &s,
            out,
        );
    }

    /// Starts an episode with `command` (from `command_start_s` on), the start perturbed by
    /// `seed` as `eemp walk --seed` does, and `pushes`.
    pub fn reset_with(
        &mut self,
        command: VelocityCommand,
        seed: u64,
        pushes: &[Push],
        obs: &mut [f32],
    ) {
        self.command = command;
        let source = self.config.initial_params_source();
        let start = self
            .config
            .start_pose(&self.robot, command.vx_mps.hypot(command.vy_mps))
            .or_else(|_| self.config.start_pose(&self.robot, 0.0))
            .expect("Table I's heights stand");
        let spec = walk_spec(&self.config, source.at_speed(0.0));
        // A fresh controller per episode: the planner keeps swing state.
        if let Ok(c) = eemp_controller(&self.robot, &spec) {
            self.controller = c;
        }
        self.controller.params = source;
        reset_to_start(self.loop_.sim_mut(), &start, seed);
        self.loop_.restart(pushes);
        self.prev_action = self.config.initial_action();
        self.last_tau = LegMap::splat(Vector3::zeros());
        let s = self.loop_.sim().ground_truth_state();
        self.q_ref = s.joints.map(|_, j| j.q);
        self.plan_stance = LegMap::splat(true);
        self.steps = 0;
        self.fell = false;
        self.write_obs(obs);
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
    for (v, [lo, hi]) in o.params.to_array().iter().zip(RANGES) {
        put((v - lo) / (hi - lo) * 2.0 - 1.0);
    }
    put(o.progress);
}

/// q_ref: IK of the plan's swing references; stance legs keep their measured angles.
fn reference_joints(
    kin: &LegKinematics,
    plan: Option<&eemp_core::locomotion::Plan>,
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
        match self.config.residual {
            Some(_) => &RESIDUAL_REWARD_TERMS,
            None => &REWARD_TERMS,
        }
    }

    fn reset(&mut self, rng: &mut ChaCha8Rng, obs: &mut [f32]) {
        self.sample_command(rng);
        let seed: u64 = rng.random_range(1..u64::MAX);
        // Drawn in every world, so that the episode's other draws do not depend on the world.
        let mut pushes = match &self.config.worlds {
            Some(w) => w.pushes.draw(self.config.episode_s, rng),
            None => Vec::new(),
        };
        if !self.world_pushes {
            pushes.clear();
        }
        self.reset_with(self.command, seed, &pushes, obs);
    }

    fn step(
        &mut self,
        action: &[f32],
        rng: &mut ChaCha8Rng,
        obs: &mut [f32],
        terms: &mut [f64],
    ) -> StepInfo {
        let before = match &self.config.residual {
            Some(r) if r.paired => Some((self.loop_.clone(), self.controller.clone())),
            _ => None,
        };
        self.controller.params = self.config.params_source(action);
        let dt = self.loop_.sim().timestep_s();
        let mut iv = Interval::default();
        let mut metrics = self.interval_metrics();
        let (kin, last_tau, plan_stance) = (&self.kin, &mut self.last_tau, &mut self.plan_stance);
        let touchdowns = self.config.decision == DecisionTiming::Touchdown;
        let residual = self.config.residual.is_some();
        let (mut fell, mut unstable, mut taken) = (false, false, 0usize);
        let mut speed_sum = 0.0;
        for k in 0..self.substeps {
            let command = self.config.command_at(self.loop_.elapsed_s(), self.command);
            speed_sum += command.vx_mps.hypot(command.vy_mps);
            let mut landed = false;
            let out = self.loop_.step(&mut self.controller, command, &mut |r| {
                match residual {
                    true => observe_metrics(&mut metrics, kin, dt, r, &r.stance()),
                    false => iv.observe(kin, dt, r),
                }
                if let Some(p) = r.plan {
                    landed = touched_down(plan_stance, &p.stance);
                    *plan_stance = p.stance;
                }
                *last_tau = r.output.torques;
            });
            taken = k + 1;
            match self.loop_.episode_end(out) {
                Some(EpisodeEnd::Unstable) => {
                    (fell, unstable) = (true, true);
                    break;
                }
                Some(EpisodeEnd::Fell) => {
                    fell = true;
                    break;
                }
                None => {}
            }
            if touchdowns && landed && taken >= self.min_substeps {
                break;
            }
        }
        let s = self.loop_.sim().ground_truth_state();
        self.q_ref = reference_joints(&self.kin, self.controller.plan(), &s);
        self.steps += 1;
        let values: Vec<f64> = match &self.config.residual {
            Some(r) => {
                let speed = speed_sum / taken.max(1) as f64;
                let table = r.table().metrics_at(speed).expect("validated");
                let m = metrics.finish(self.mass_kg);
                let terms = match before {
                    // A fall costs the same whatever the table did: no second walk.
                    Some((loop_, controller)) if !fell => {
                        let (m_table, table_fell) = self.table_window(loop_, controller, taken);
                        paired_reward_terms(
                            &r.rewards, &m, &m_table, speed, table, fell, table_fell,
                        )
                    }
                    _ => residual_reward_terms(&r.rewards, &m, speed, table, fell),
                };
                self.last_interval = Some(m);
                terms.to_vec()
            }
            None => {
                let dist = iv
                    .start_xy
                    .map(|a| (iv.end_xy[0] - a[0]).hypot(iv.end_xy[1] - a[1]))
                    .unwrap_or(0.0);
                // Eq. (8), dimensionless; an interval without distance counts as the clip.
                let cot = cost_of_transport_dimensionless(iv.energy_j, self.mass_kg, dist)
                    .filter(|_| dist > 1e-6)
                    .map_or(self.config.cot_clip, |c| c.min(self.config.cot_clip));
                let manip = if iv.manip_n > 0 {
                    iv.manip_sum / iv.manip_n as f64
                } else {
                    0.0
                };
                let w = &self.config.rewards;
                let v = [
                    -cot * w.cot,
                    manip * w.manipulability,
                    w.time * self.steps as f64 / self.max_steps as f64,
                ];
                v.iter().map(|&x| if fell { 0.0 } else { x }).collect()
            }
        };
        let mut reward = 0.0;
        for (t, v) in terms.iter_mut().zip(values) {
            *t = v;
            reward += v;
        }
        let episode_over = match self.config.decision {
            DecisionTiming::Period => self.steps >= self.max_steps,
            DecisionTiming::Touchdown => self.loop_.elapsed_s() + 0.5 * dt >= self.config.episode_s,
        };
        let every_s = self.config.command_every_s;
        let t_end = self.loop_.elapsed_s();
        let t_begin = t_end - taken as f64 * dt;
        // A new command when the interval crossed a multiple of command_every_s.
        if !fell && (t_end / every_s + 1e-9).floor() > (t_begin / every_s + 1e-9).floor() {
            self.sample_command(rng);
        }
        self.prev_action.copy_from_slice(&action[..ACT_DIM]);
        self.fell = fell;
        self.write_obs(obs);
        StepInfo {
            reward,
            terminated: fell,
            truncated: !fell && episode_over,
            invalid: !s.body.is_finite() || !reward.is_finite() || unstable,
            periods: touchdowns.then(|| taken as f64 / self.substeps as f64),
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
    /// Refuses a robot the policy was not trained on.
    fn check_robot(&self, _robot: &RobotConfig) -> Result<(), String> {
        Ok(())
    }
    /// Whether the caller allowed another robot (an experiment), for the table too.
    fn allow_robot_mismatch(&self) -> bool {
        false
    }
}

/// The same action every decision.
pub struct FixedAction(pub [f32; ACT_DIM]);

impl ParamsPolicy for FixedAction {
    fn act(&mut self, _obs: &[f32]) -> Option<Vec<f32>> {
        Some(self.0.to_vec())
    }
}

/// EEMP whose parameters a policy picks at each decision (the same observation as the
/// training environment; the policy's mean action, no sampling). Drop-in for `eemp walk` and
/// the comparison.
pub struct EempRlController<P: ParamsPolicy> {
    pub eemp: EempController,
    policy: P,
    config: EempRlConfig,
    kin: LegKinematics,
    q0: LegMap<Vector3<f64>>,
    next_decision_s: f64,
    last_decision_s: f64,
    touchdown_pending: bool,
    decisions: usize,
    max_decisions: usize,
    prev_action: [f32; ACT_DIM],
    last_tau: LegMap<Vector3<f64>>,
    obs: Vec<f32>,
    /// Decisions whose action was not finite (the parameters in force were kept).
    pub invalid_decisions: usize,
}

impl<P: ParamsPolicy> EempRlController<P> {
    pub fn new(robot: &RobotConfig, config: EempRlConfig, policy: P) -> Result<Self, String> {
        config.validate().map_err(|e| e.to_string())?;
        policy.check_robot(robot)?;
        let source = config.initial_params_source();
        if let (ParamsSource::Residual { table, .. }, false) =
            (&source, policy.allow_robot_mismatch())
        {
            table
                .robot_id()
                .check(robot, &format!("EEMP-RL's {} table", table.gait))?;
        }
        let mut eemp = eemp_controller(robot, &walk_spec(&config, source.at_speed(0.0)))
            .map_err(|e| e.to_string())?;
        eemp.params = source;
        Ok(EempRlController {
            eemp,
            policy,
            kin: LegKinematics::new(robot),
            q0: robot.standing_pose(),
            next_decision_s: f64::NEG_INFINITY,
            last_decision_s: f64::NEG_INFINITY,
            touchdown_pending: false,
            decisions: 0,
            max_decisions: (config.episode_s / config.decision_period_s).round() as usize,
            prev_action: config.initial_action(),
            last_tau: LegMap::splat(Vector3::zeros()),
            obs: vec![0.0; config.obs_dim()],
            invalid_decisions: 0,
            config,
        })
    }

    /// The start pose EEMP-RL walks from for a walk whose first commanded speed is
    /// `first_speed_mps`: EEMP's, at the table's X_z there (residual) or Table II's (absolute).
    pub fn start_pose(
        robot: &RobotConfig,
        config: &EempRlConfig,
        first_speed_mps: f64,
    ) -> Result<StartPose, String> {
        config.start_pose(robot, first_speed_mps)
    }

    fn decide(&mut self, input: &eemp_core::controller::ControlInput) {
        let s = input.state;
        let q_ref = reference_joints(&self.kin, self.eemp.plan(), s);
        let speed = input.command.vx_mps.hypot(input.command.vy_mps);
        write_observation(
            &ObsParts {
                kin: &self.kin,
                q0: &self.q0,
                last_tau: &self.last_tau,
                prev_action: &self.prev_action,
                command: &input.command,
                q_ref: &q_ref,
                params: &self.eemp.params.at_speed(speed),
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
                self.eemp.params = self.config.params_source(&a);
                self.prev_action.copy_from_slice(&a);
            }
            None => self.invalid_decisions += 1,
        }
        self.decisions += 1;
    }
}

impl<P: ParamsPolicy> Controller for EempRlController<P> {
    fn control(
        &mut self,
        input: &eemp_core::controller::ControlInput,
    ) -> eemp_core::locomotion::ControlOutput {
        let t = input.state.time_s;
        let period = self.config.decision_period_s;
        let due = t + 1e-9 >= self.next_decision_s
            || (self.touchdown_pending
                && t + 1e-9 >= self.last_decision_s + self.config.min_decision_s);
        if due {
            self.decide(input);
            self.touchdown_pending = false;
            self.last_decision_s = t;
            self.next_decision_s = match self.config.decision {
                DecisionTiming::Period if self.next_decision_s.is_finite() => {
                    self.next_decision_s + period
                }
                _ => t + period,
            };
        }
        let before = self.eemp.plan().map(|p| p.stance);
        let out = self.eemp.control(input);
        if self.config.decision == DecisionTiming::Touchdown {
            if let (Some(b), Some(p)) = (before, self.eemp.plan()) {
                self.touchdown_pending |= touched_down(&b, &p.stance);
            }
        }
        self.last_tau = out.torques;
        out
    }
    fn plan(&self) -> Option<&eemp_core::locomotion::Plan> {
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
