//! Many walks, one table: methods × scenarios × speeds × seeds, each a 20 s walk through the
//! same scenario and metrics code (`eemp_sim::walk`), run on a thread pool and resumable.
//!
//! A suite folder holds `suite.toml` (the config, written on the first start; a later start
//! with another config is refused) and `results.csv`: one row per finished run, appended and
//! flushed as each ends. A kill can leave only a partial last line, which the next start
//! drops; runs with a row are not run again. `eemp compare` and `eemp robustness` are this
//! runner with their own configs and reports.

use crate::state_source_arg::KfOptions;
use eemp_core::planner::params_table::ParamsTable;
use eemp_core::planner::{FreePairing, Gait, PlannerConfig, WalkSupport};
use eemp_core::robot::RobotConfig;
use eemp_rl::run::{Sensing, WalkDescription};
use eemp_sim::closed_loop::StateSource;
use eemp_sim::scenario::Scenario;
use eemp_sim::walk::VelocityProfile;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// One method of a suite.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MethodConfig {
    /// Its name in tables and figures.
    pub name: String,
    /// `eemp`, `eemp-rl`, `model-free` or `imitation`.
    pub kind: String,
    /// EEMP: the gait (`trot`, `walk`, `free`) and its per-speed table.
    #[serde(default)]
    pub gait: Option<String>,
    #[serde(default)]
    pub table: Option<PathBuf>,
    /// A learned method's policy file.
    #[serde(default)]
    pub policy: Option<PathBuf>,
    /// What this method's controller sees, in place of the suite's `estimator` (e.g. the same
    /// method on ground truth beside it on the filter).
    #[serde(default)]
    pub estimator: Option<String>,
    /// EEMP: slip handling (`eemp_core::slip`); absent: the gait's default (on; the walk's below
    /// 0.6 m/s, `SlipConfig::default_for`).
    #[serde(default)]
    pub adapt_friction: Option<bool>,
    /// EEMP with slip handling: the friction coefficient it starts from (absent: the robot
    /// file's, else `slip::CAUTIOUS_START`).
    #[serde(default)]
    pub initial_friction: Option<f64>,
    /// EEMP with slip handling: the coefficient's floor (`slip.min_friction`; absent: the
    /// gait's, 0.15 for the trot and the free gait, 0.2 for the walk).
    #[serde(default)]
    pub min_friction: Option<f64>,
    /// EEMP with slip handling: the cap on raises after a slip (`slip.hold_cap_after_slip`;
    /// absent: its default; 0: off).
    #[serde(default)]
    pub hold_cap_after_slip: Option<f64>,
    /// EEMP with slip handling: the fraction of the asked ratio a hold raises the coefficient to
    /// (`slip.hold_raise_fraction`; absent: the gait's, 0.8 for the trot and the free gait, 1 for
    /// the walk).
    #[serde(default)]
    pub hold_raise_fraction: Option<f64>,
    /// EEMP with slip handling: the reference speed above which it rests at the nominal
    /// coefficient (`slip.max_speed_mps`; absent: the gait's, the walk's 0.6; 0: no limit).
    #[serde(default)]
    pub slip_max_speed_mps: Option<f64>,
    /// EEMP with slip handling: the coefficient below which the speed is capped for a floor
    /// found slippery (`slip.slow_below_friction`; absent: the gait's, the walk's 0.205; 0: never).
    #[serde(default)]
    pub slow_below_friction: Option<f64>,
    /// EEMP with slip handling: that cap, m/s (`slip.slow_speed_mps`; absent: 0.3; refused
    /// where the cap is off, e.g. the trot without `slow_below_friction`).
    #[serde(default)]
    pub slow_speed_mps: Option<f64>,
    /// EEMP: the ellipses' cap by the slip detector's coefficient
    /// (`planner.ellipse_friction_factor`; absent: the gait's, 1 for the trot and the free gait,
    /// 0 for the walk; 0: off).
    #[serde(default)]
    pub ellipse_friction_factor: Option<f64>,
    /// EEMP: the capture step's cap by the MPC's coefficient
    /// (`planner.touchdown_friction_factor`; absent: the gait's, 0.5 for the trot and the free
    /// gait, 0 for the walk; 0: off).
    #[serde(default)]
    pub touchdown_friction_factor: Option<f64>,
    /// On the filter: its velocity-jump threshold, m/s (`KfConfig::velocity_jump_mps`; 0: off;
    /// absent: the filter's default).
    #[serde(default)]
    pub kf_velocity_jump_mps: Option<f64>,
    /// On the filter: the share of a jump that marks a leg dragged along by a push
    /// (`KfConfig::velocity_jump_dragged_fraction`; 0: off; absent: the filter's default).
    #[serde(default)]
    pub kf_dragged_fraction: Option<f64>,
    /// On the filter: its leg-outlier threshold, m/s (`KfConfig::leg_outlier_mps`; 0: off;
    /// absent: the filter's default).
    #[serde(default)]
    pub kf_leg_outlier_mps: Option<f64>,
    /// EEMP's free gait: when a diagonal partner swings along (`FreePairing`; absent: its
    /// default; `{ pair_tolerance = 0.0, support_check = false }` is the earlier rule).
    #[serde(default)]
    pub free_pairing: Option<FreePairing>,
    /// EEMP's walk: its support check (`WalkSupport`; absent: its default; `{ check = false }`
    /// is the paper's fixed order).
    #[serde(default)]
    pub walk_support: Option<WalkSupport>,
    /// EEMP: the MPC's horizon in steps of its dt (absent: `MpcConfig`'s default).
    #[serde(default)]
    pub mpc_horizon: Option<usize>,
    /// EEMP whose free-gait table EEMP-RL learned (CMA-ES's re-tuned table,
    /// `policies/a1_eemp_rl_cmaes_entry.toml`): the reports count it as EEMP-RL, against the
    /// free gait's table. Kind eemp, gait free.
    #[serde(default)]
    pub eemp_rl: bool,
    /// Controller settings as `key=value`, applied last (`eemp walk --set`; `eemp config
    /// show` lists the keys).
    #[serde(default)]
    pub set: Vec<String>,
}

impl MethodConfig {
    /// EEMP-RL: a residual policy (kind eemp-rl) or a table it learned (`eemp_rl = true`).
    pub fn is_eemp_rl(&self) -> bool {
        self.kind == "eemp-rl" || self.eemp_rl
    }

    /// The controller settings of its own only an EEMP method may have (besides
    /// `adapt_friction`), each with whether it is set: a policy refuses them, and the table
    /// EEMP-RL is measured against has none.
    pub fn eemp_controller_settings(&self) -> [(bool, &'static str); 12] {
        [
            (self.initial_friction.is_some(), "initial_friction"),
            (self.min_friction.is_some(), "min_friction"),
            (self.hold_cap_after_slip.is_some(), "hold_cap_after_slip"),
            (self.hold_raise_fraction.is_some(), "hold_raise_fraction"),
            (self.slip_max_speed_mps.is_some(), "slip_max_speed_mps"),
            (self.slow_below_friction.is_some(), "slow_below_friction"),
            (self.slow_speed_mps.is_some(), "slow_speed_mps"),
            (
                self.ellipse_friction_factor.is_some(),
                "ellipse_friction_factor",
            ),
            (
                self.touchdown_friction_factor.is_some(),
                "touchdown_friction_factor",
            ),
            (self.free_pairing.is_some(), "free_pairing"),
            (self.walk_support.is_some(), "walk_support"),
            (self.mpc_horizon.is_some(), "mpc_horizon"),
        ]
    }

    /// The method's estimator: its own or the suite's.
    pub fn estimator<'a>(&'a self, suite: &'a SuiteConfig) -> &'a str {
        self.estimator.as_deref().unwrap_or(&suite.estimator)
    }

    fn kf_options(&self) -> KfOptions {
        KfOptions {
            velocity_jump_mps: self.kf_velocity_jump_mps,
            velocity_jump_dragged_fraction: self.kf_dragged_fraction,
            leg_outlier_mps: self.kf_leg_outlier_mps,
        }
    }

    /// The method's walk at `speed_mps` (or the scenario's profile) and `seed`: the run
    /// description every command shares ([`eemp_rl::run`]), which builds and runs it. EEMP walks
    /// with its per-speed table (the method's, else the robot's shipped one for the gait).
    pub fn walk(
        &self,
        suite: &SuiteConfig,
        scenario: &ScenarioConfig,
        speed_mps: f64,
        seed: u64,
        robot: &RobotConfig,
    ) -> WalkDescription {
        let gait = self.gait.clone().unwrap_or_else(|| "trot".into());
        let mut d = WalkDescription {
            robot: suite.robot.clone(),
            allow_robot_mismatch: suite.allow_robot_mismatch,
            controller: self.kind.clone(),
            policy: self.policy.clone(),
            sensing: Sensing {
                estimator: self.estimator(suite).into(),
                ideal_sensors: false,
                seed,
                kf: self.kf_options(),
            },
            speed_mps,
            duration_s: suite.duration_s,
            profile: scenario.profile.clone(),
            scenario: scenario.file.clone(),
            ..Default::default()
        };
        if self.kind == "eemp" {
            d.params_table =
                Some(self.table.clone().unwrap_or_else(|| {
                    robot.shipped_table_path(gait.parse().unwrap_or(Gait::Trot))
                }));
            d.adapt_friction = self.adapt_friction;
            d.initial_friction = self.initial_friction;
            d.min_friction = self.min_friction;
            d.hold_cap_after_slip = self.hold_cap_after_slip;
            d.hold_raise_fraction = self.hold_raise_fraction;
            d.slip_max_speed_mps = self.slip_max_speed_mps;
            d.slow_below_friction = self.slow_below_friction;
            d.slow_speed_mps = self.slow_speed_mps;
            d.mpc_horizon = self.mpc_horizon;
            if let Some(f) = self.ellipse_friction_factor {
                d.ellipse_friction_factor = Some(f);
            }
            d.touchdown_friction_factor = self.touchdown_friction_factor;
            if let Some(p) = self.free_pairing {
                d.free_pair_tolerance = Some(p.pair_tolerance);
                d.free_support_margin_m = Some(p.support_margin_m);
                d.free_support_check = Some(p.support_check);
            }
            if let Some(w) = self.walk_support {
                d.walk_support_margin_m = w.check.then_some(w.margin_m);
                d.walk_support_max_speed_mps = w.check.then_some(w.max_speed_mps);
                d.walk_support_check = Some(w.check);
            }
        }
        if self.kind == "eemp" {
            d.gait = gait;
        }
        d.set = self.set.clone();
        d
    }

    /// Applies the method's filter settings to `source`.
    fn apply_kf_options(&self, source: &mut StateSource) -> Result<(), String> {
        crate::state_source_arg::with_kf_options(
            source,
            &self.kf_options(),
            [
                &format!("method '{}': kf_velocity_jump_mps", self.name),
                &format!("method '{}': kf_dragged_fraction", self.name),
                &format!("method '{}': kf_leg_outlier_mps", self.name),
            ],
        )
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioConfig {
    pub name: String,
    /// A scenario file (`scenarios/*.toml`); none: the flat floor.
    #[serde(default)]
    pub file: Option<PathBuf>,
    /// Commanded forward speeds, m/s (leave out with `profile`).
    #[serde(default)]
    pub speeds_mps: Vec<f64>,
    /// A velocity profile (`profiles/*.toml`) in place of constant speeds: one run per method
    /// and seed, listed at the profile's top forward speed.
    #[serde(default)]
    pub profile: Option<PathBuf>,
}

impl ScenarioConfig {
    fn load_profile(&self) -> Result<Option<VelocityProfile>, String> {
        self.profile
            .as_ref()
            .map(|p| {
                let v: VelocityProfile =
                    eemp_core::config_error::load_toml(p).map_err(|e| e.to_string())?;
                v.validate().map_err(|e| format!("{}: {e}", p.display()))?;
                Ok(v)
            })
            .transpose()
    }

    /// The speeds its runs are listed at: `speeds_mps`, or a profile's top forward speed (an
    /// unreadable profile is an error, naming the file).
    pub fn speeds(&self) -> Result<Vec<f64>, String> {
        Ok(match self.load_profile()? {
            Some(p) => vec![p
                .segments
                .iter()
                .map(|s| s.vx_mps.abs())
                .fold(0.0, f64::max)],
            None => self.speeds_mps.clone(),
        })
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SuiteConfig {
    #[serde(default = "default_duration")]
    pub duration_s: f64,
    /// Seeds of the start perturbation and sensor noise (0: start exactly at rest).
    pub seeds: Vec<u64>,
    /// `ground-truth` or `kf`.
    #[serde(default = "default_estimator")]
    pub estimator: String,
    #[serde(rename = "method")]
    pub methods: Vec<MethodConfig>,
    #[serde(rename = "scenario")]
    pub scenarios: Vec<ScenarioConfig>,
    /// The robot file every run simulates (default: the shipped A1); `eemp compare|robustness
    /// --robot FILE` sets it. Tables default to `tables/<robot>_<gait>.toml`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<PathBuf>,
    /// Run tables and policies made for another robot (an experiment).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub allow_robot_mismatch: bool,
}

fn default_duration() -> f64 {
    20.0
}
fn default_estimator() -> String {
    "ground-truth".into()
}

/// One walk of a suite.
#[derive(Clone, Debug, PartialEq)]
pub struct SuiteRun {
    pub method: usize,
    pub scenario: usize,
    pub speed_mps: f64,
    pub seed: u64,
}

/// One row of `results.csv`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SuiteRow {
    pub run_id: String,
    pub method: String,
    pub scenario: String,
    pub speed_mps: f64,
    pub seed: u64,
    pub fell: bool,
    pub fell_at_s: Option<f64>,
    pub vel_rmse_mps: Option<f64>,
    pub cot: Option<f64>,
    pub manipulability: Option<f64>,
    pub distance_m: f64,
    pub steps_total: u64,
    /// Why the run could not be done (a bad file, a simulator error); not a result.
    pub error: Option<String>,
    /// Mean planner parameters in force over the metrics window (EEMP methods; empty for the
    /// others and in results written before these columns existed).
    #[serde(default)]
    pub swing_time_s: Option<f64>,
    #[serde(default)]
    pub step_height_m: Option<f64>,
    #[serde(default)]
    pub body_height_m: Option<f64>,
    #[serde(default)]
    pub ellipse_rx_m: Option<f64>,
    #[serde(default)]
    pub ellipse_ry_m: Option<f64>,
    /// Energy beside eq. 8 (`WalkMetrics`): the joints' negative share of their absolute work
    /// and the CoT of the absolute joint power.
    #[serde(default)]
    pub negative_work_share: Option<f64>,
    #[serde(default)]
    pub cot_abs_power: Option<f64>,
    /// The gait walked (`GaitMeasure`): diagonal and lateral pairs sharing their contact state,
    /// (left − right) / (left + right) of the feet's load, the smallest duty factor.
    #[serde(default)]
    pub diagonal_pairs_together: Option<f64>,
    #[serde(default)]
    pub lateral_pairs_together: Option<f64>,
    #[serde(default)]
    pub left_right_imbalance: Option<f64>,
    #[serde(default)]
    pub duty_factor_min: Option<f64>,
    /// The battery's energy under the robot file's motor model (`WalkMetrics::electrical`;
    /// empty without one, and in results written before these columns existed): the electrical
    /// CoT with idle power, the drives' alone at the file's k and at 1/3 and 2 times it, the
    /// idle power's share of the CoT (add it to a drives-only CoT for the total), the mean
    /// battery power, W, and the energy per distance, Wh/km.
    #[serde(default)]
    pub cot_electrical: Option<f64>,
    #[serde(default)]
    pub cot_electrical_motors: Option<f64>,
    #[serde(default)]
    pub cot_electrical_motors_low_k: Option<f64>,
    #[serde(default)]
    pub cot_electrical_motors_high_k: Option<f64>,
    #[serde(default)]
    pub cot_idle: Option<f64>,
    #[serde(default)]
    pub electrical_power_w: Option<f64>,
    #[serde(default)]
    pub wh_per_km: Option<f64>,
}

impl SuiteRow {
    /// The mean parameters in force, in `PlannerParams::to_array`'s order.
    pub fn params_mean(&self) -> Option<[f64; 5]> {
        Some([
            self.swing_time_s?,
            self.step_height_m?,
            self.body_height_m?,
            self.ellipse_rx_m?,
            self.ellipse_ry_m?,
        ])
    }

    fn set_params_mean(&mut self, p: Option<[f64; 5]>) {
        let at = |i: usize| p.map(|a| a[i]);
        self.swing_time_s = at(0);
        self.step_height_m = at(1);
        self.body_height_m = at(2);
        self.ellipse_rx_m = at(3);
        self.ellipse_ry_m = at(4);
    }
}

pub const RESULTS: &str = "results.csv";
/// Each run's wall time (`run_id,wall_s`, appended as runs finish): kept out of `results.csv`,
/// whose bytes are the same for the same runs.
pub const TIMING: &str = "timing.csv";
/// The columns of `results.csv` (the fields of [`SuiteRow`]).
const HEADER: &str = "run_id,method,scenario,speed_mps,seed,fell,fell_at_s,vel_rmse_mps,cot,manipulability,distance_m,steps_total,error,swing_time_s,step_height_m,body_height_m,ellipse_rx_m,ellipse_ry_m,negative_work_share,cot_abs_power,diagonal_pairs_together,lateral_pairs_together,left_right_imbalance,duty_factor_min,cot_electrical,cot_electrical_motors,cot_electrical_motors_low_k,cot_electrical_motors_high_k,cot_idle,electrical_power_w,wh_per_km";
pub const CONFIG: &str = "suite.toml";

impl SuiteConfig {
    /// The robot every run simulates.
    pub fn robot_config(&self) -> Result<RobotConfig, String> {
        crate::robot_arg::load_robot(self.robot.as_deref())
    }

    pub fn load(path: &Path) -> Result<Self, String> {
        let c: SuiteConfig = eemp_core::config_error::load_toml(path).map_err(|e| e.to_string())?;
        c.validate()
            .map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(c)
    }

    /// Checks values and that every file exists and loads (so no run fails on a typo later).
    pub fn validate(&self) -> Result<(), String> {
        if !(self.duration_s > 2.0 && self.duration_s <= 600.0) {
            return Err(format!(
                "duration_s = {} is out of range: allowed (2, 600] s",
                self.duration_s
            ));
        }
        if self.seeds.is_empty() || self.methods.is_empty() || self.scenarios.is_empty() {
            return Err(
                "a suite needs at least one seed, one [[method]] and one [[scenario]]".into(),
            );
        }
        let robot = self.robot_config()?;
        crate::state_source_arg::state_source(&self.estimator, false, 0, &robot)?;
        for m in &self.methods {
            let mut source =
                crate::state_source_arg::state_source(m.estimator(self), false, 0, &robot)
                    .map_err(|e| format!("method '{}': {e}", m.name))?;
            m.apply_kf_options(&mut source)?;
        }
        // Run ids must be unique (resume finds runs by id).
        let mut seeds = self.seeds.clone();
        seeds.sort_unstable();
        if seeds.windows(2).any(|w| w[0] == w[1]) {
            return Err(format!("seeds {:?} repeat a seed", self.seeds));
        }
        for name in self
            .methods
            .iter()
            .map(|m| &m.name)
            .chain(self.scenarios.iter().map(|s| &s.name))
        {
            if name.is_empty() || name.contains('|') {
                return Err(format!(
                    "name '{name}' is empty or holds '|' (the run-id separator)"
                ));
            }
        }
        let mut names = std::collections::BTreeSet::new();
        for (i, m) in self.methods.iter().enumerate() {
            if !names.insert(&m.name) {
                return Err(format!("method[{i}]: the name '{}' is used twice", m.name));
            }
            match m.kind.as_str() {
                "eemp" => {
                    let g: Gait = m.gait.as_deref().unwrap_or("trot").parse()?;
                    let t = m
                        .table
                        .clone()
                        .unwrap_or_else(|| robot.shipped_table_path(g));
                    let table = ParamsTable::load(&t)
                        .map_err(|e| format!("method '{}': {e}", m.name))?;
                    if !self.allow_robot_mismatch {
                        table
                            .robot_id()
                            .check(&robot, &t.display().to_string())
                            .map_err(|e| format!("method '{}': {e}", m.name))?;
                    }
                    if m.eemp_rl {
                        if g != Gait::Free {
                            return Err(format!(
                                "method '{}': eemp_rl = true is for a free-gait table EEMP-RL \
                                 learned (gait = \"free\"), not gait {g}",
                                m.name
                            ));
                        }
                        if m.table.is_none() {
                            return Err(format!(
                                "method '{}': eemp_rl = true needs the learned table \
                                 (table = FILE)",
                                m.name
                            ));
                        }
                        // Compared with the plain free table: the same controller, or the
                        // comparison is not like for like.
                        let kf = [
                            (m.kf_velocity_jump_mps.is_some(), "kf_velocity_jump_mps"),
                            (m.kf_dragged_fraction.is_some(), "kf_dragged_fraction"),
                            (m.kf_leg_outlier_mps.is_some(), "kf_leg_outlier_mps"),
                        ];
                        if let Some((_, key)) = m
                            .eemp_controller_settings()
                            .into_iter()
                            .chain(kf)
                            .find(|(set, _)| *set)
                        {
                            return Err(format!(
                                "method '{}': {key} is not for eemp_rl = true (a learned table \
                                 runs the free table's controller)",
                                m.name
                            ));
                        }
                    }
                    if m.free_pairing.is_some() && g != Gait::Free {
                        return Err(format!(
                            "method '{}': free_pairing is for gait free, not {g}",
                            m.name
                        ));
                    }
                    if m.walk_support.is_some() && g != Gait::Walk {
                        return Err(format!(
                            "method '{}': walk_support is for gait walk, not {g}",
                            m.name
                        ));
                    }
                    PlannerConfig {
                        gait: g,
                        free_pairing: m.free_pairing.unwrap_or_default(),
                        walk_support: m.walk_support.unwrap_or_default(),
                        ..Default::default()
                    }
                    .validate()
                    .map_err(|e| format!("method '{}': {e}", m.name))?;
                    // The rest (slip settings, the table's parameters) as every run builds it.
                    let flat = ScenarioConfig {
                        name: "flat".into(),
                        file: None,
                        speeds_mps: vec![0.3],
                        profile: None,
                    };
                    m.walk(self, &flat, 0.3, 1, &robot)
                        .build()
                        .map_err(|e| format!("method '{}': {e}", m.name))?;
                }
                k @ ("model-free" | "imitation" | "eemp-rl") => {
                    if m.eemp_rl {
                        return Err(format!(
                            "method '{}': eemp_rl = true marks a learned table of kind eemp, \
                             not kind {k}",
                            m.name
                        ));
                    }
                    let slip = (m.adapt_friction.is_some(), "adapt_friction");
                    let planner = [(m.gait.is_some(), "gait"), (m.table.is_some(), "table")];
                    for (set, key) in std::iter::once(slip)
                        .chain(planner)
                        .chain(m.eemp_controller_settings())
                    {
                        if set {
                            return Err(format!(
                                "method '{}': {key} is for kind eemp (a policy runs with the \
                                 controller it was trained with)",
                                m.name
                            ));
                        }
                    }
                    let p = m.policy.as_ref().ok_or_else(|| {
                        format!("method '{}': kind {k} needs policy = FILE", m.name)
                    })?;
                    eemp_rl::run::check_policy(k, p, &robot, self.allow_robot_mismatch)
                        .map_err(|e| format!("method '{}': {e}", m.name))?;
                }
                other => {
                    return Err(format!(
                        "method '{}': unknown kind '{other}': allowed eemp, eemp-rl, model-free, imitation",
                        m.name
                    ))
                }
            }
        }
        let mut names = std::collections::BTreeSet::new();
        for s in &self.scenarios {
            if !names.insert(&s.name) {
                return Err(format!("scenario name '{}' is used twice", s.name));
            }
            if let Some(f) = &s.file {
                Scenario::load(f).map_err(|e| format!("scenario '{}': {e}", s.name))?;
            }
            match (
                s.load_profile()
                    .map_err(|e| format!("scenario '{}': {e}", s.name))?,
                s.speeds_mps.is_empty(),
            ) {
                (Some(_), false) => {
                    return Err(format!(
                        "scenario '{}': give either speeds_mps or a profile, not both",
                        s.name
                    ))
                }
                (None, true) => return Err(format!("scenario '{}': speeds_mps is empty", s.name)),
                _ => {}
            }
            let mut mm: Vec<i64> = s
                .speeds_mps
                .iter()
                .map(|v| (v * 1000.0).round() as i64)
                .collect();
            mm.sort_unstable();
            if mm.windows(2).any(|w| w[0] == w[1]) {
                return Err(format!(
                    "scenario '{}': speeds {:?} repeat a speed (to the mm/s)",
                    s.name, s.speeds_mps
                ));
            }
            for v in &s.speeds_mps {
                if !(v.is_finite() && (0.0..=1.5).contains(v)) {
                    return Err(format!(
                        "scenario '{}': speed {v} is out of range: allowed [0, 1.5] m/s",
                        s.name
                    ));
                }
            }
        }
        Ok(())
    }

    pub fn runs(&self) -> Result<Vec<SuiteRun>, String> {
        let mut runs = Vec::new();
        for (si, s) in self.scenarios.iter().enumerate() {
            for v in s.speeds()? {
                for mi in 0..self.methods.len() {
                    for &seed in &self.seeds {
                        runs.push(SuiteRun {
                            method: mi,
                            scenario: si,
                            speed_mps: v,
                            seed,
                        });
                    }
                }
            }
        }
        Ok(runs)
    }

    pub fn run_id(&self, r: &SuiteRun) -> String {
        format!(
            "{}|{}|{:.3}|{}",
            self.methods[r.method].name, self.scenarios[r.scenario].name, r.speed_mps, r.seed
        )
    }
}

/// Runs one walk of the suite.
pub fn simulate(
    cfg: &SuiteConfig,
    run: &SuiteRun,
    robot: &RobotConfig,
) -> Result<SuiteRow, String> {
    let m = &cfg.methods[run.method];
    let sc = &cfg.scenarios[run.scenario];
    let built = m.walk(cfg, sc, run.speed_mps, run.seed, robot).build()?;
    // The parameters in force over the metrics window (EEMP's constant or table, EEMP-RL's).
    let mut params = eemp_core::planner::params_stats::ParamsStats::default();
    let metrics_start_s = built.spec.metrics_start_s;
    let observe = |r: &eemp_sim::closed_loop::StepRecord| {
        if r.state.time_s >= metrics_start_s {
            if let Some(p) = r.plan.and_then(|p| p.params) {
                params.observe(r.command.vx_mps.hypot(r.command.vy_mps), &p);
            }
        }
    };
    let walk = built.run(observe)?;
    let mut row = SuiteRow {
        run_id: cfg.run_id(run),
        method: m.name.clone(),
        scenario: sc.name.clone(),
        speed_mps: run.speed_mps,
        seed: run.seed,
        fell: walk.stats.fell,
        fell_at_s: walk.stats.fell_at_s,
        vel_rmse_mps: walk.metrics.vel_rmse_mps,
        cot: walk.metrics.cot,
        manipulability: walk.metrics.manipulability,
        distance_m: walk.metrics.distance_m,
        steps_total: walk.steps.0.iter().sum::<usize>() as u64,
        error: None,
        ..Default::default()
    };
    row.set_params_mean(params.mean().map(|p| p.to_array()));
    row.negative_work_share = walk.metrics.negative_work_share;
    row.cot_abs_power = walk.metrics.cot_abs_power;
    if let Some(e) = &walk.metrics.electrical {
        row.cot_electrical = e.cot;
        row.cot_electrical_motors = e.cot_motors;
        row.cot_electrical_motors_low_k = e.band[0].cot_motors;
        row.cot_electrical_motors_high_k = e.band[2].cot_motors;
        row.cot_idle = e.cot.zip(e.cot_motors).map(|(a, b)| a - b);
        row.electrical_power_w = e.mean_power_w;
        row.wh_per_km = e.wh_per_km;
    }
    if let Some(g) = &walk.gait {
        row.diagonal_pairs_together = Some(g.diagonal_pairs_together);
        row.lateral_pairs_together = Some(g.lateral_pairs_together);
        row.left_right_imbalance = Some(g.left_right_imbalance);
        row.duty_factor_min = g.duty_factor.values().copied().reduce(f64::min);
    }
    Ok(row)
}

/// Reads the rows of a results file, dropping a partial last line and rows with an error.
pub fn load_rows(path: &Path) -> Result<Vec<SuiteRow>, String> {
    if !path.exists() {
        return Ok(Vec::new());
    }
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let complete = match text.rfind('\n') {
        Some(i) => &text[..=i],
        None => "",
    };
    let mut rd = csv::Reader::from_reader(complete.as_bytes());
    let mut rows = Vec::new();
    for (k, r) in rd.deserialize::<SuiteRow>().enumerate() {
        let r = r.map_err(|e| format!("{} row {}: {e}", path.display(), k + 2))?;
        if r.error.is_none() {
            rows.push(r);
        }
    }
    Ok(rows)
}

/// Refuses a folder that holds another suite; stores `cfg` in a new one.
fn claim_folder(cfg: &SuiteConfig, dir: &Path) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let stored = dir.join(CONFIG);
    if stored.exists() {
        let old: SuiteConfig =
            eemp_core::config_error::load_toml(&stored).map_err(|e| e.to_string())?;
        if &old != cfg {
            return Err(format!(
                "{} holds a suite with another config; use another --out (or delete it)",
                dir.display()
            ));
        }
    } else {
        let text = toml::to_string(cfg).map_err(|e| e.to_string())?;
        std::fs::write(&stored, &text)
            .map_err(|e| format!("cannot write {}: {e}", stored.display()))?;
    }
    Ok(())
}

/// `rows` in the order of `cfg.runs()` (as written out once a suite or a merge is complete, so
/// that the same runs give the same bytes however the threads finished them).
fn in_run_order(cfg: &SuiteConfig, mut rows: Vec<SuiteRow>) -> Result<Vec<SuiteRow>, String> {
    let order: std::collections::HashMap<String, usize> = cfg
        .runs()?
        .iter()
        .enumerate()
        .map(|(i, r)| (cfg.run_id(r), i))
        .collect();
    rows.sort_by(|a, b| {
        let key = |r: &SuiteRow| order.get(&r.run_id).copied().unwrap_or(usize::MAX);
        key(a).cmp(&key(b)).then_with(|| a.run_id.cmp(&b.run_id))
    });
    Ok(rows)
}

/// Writes `rows` as `path` (header first), atomically.
fn write_rows(path: &Path, rows: &[SuiteRow]) -> Result<(), String> {
    let mut w = csv::Writer::from_writer(Vec::new());
    for r in rows {
        w.serialize(r).map_err(|e| e.to_string())?;
    }
    let mut body = w.into_inner().map_err(|e| e.to_string())?;
    if rows.is_empty() {
        body = format!("{HEADER}\n").into_bytes();
    }
    eemp_study::store::write_atomic(path, &body).map_err(|e| e.to_string())
}

/// Takes the results of shard folders of `cfg` into `dir` (a run `dir` already holds is kept);
/// returns how many runs were added. A folder of another suite is refused, before anything is
/// written.
pub fn merge_rows(cfg: &SuiteConfig, shards: &[PathBuf], dir: &Path) -> Result<usize, String> {
    let mut taken = Vec::new();
    for s in shards {
        let stored = s.join(CONFIG);
        let theirs: SuiteConfig = eemp_core::config_error::load_toml(&stored)
            .map_err(|e| format!("{} is not a shard of this suite: {e}", s.display()))?;
        if &theirs != cfg {
            return Err(format!(
                "{} holds a suite with another config than this one; merge shards of one suite",
                s.display()
            ));
        }
        taken.extend(load_rows(&s.join(RESULTS))?);
    }
    claim_folder(cfg, dir)?;
    let path = dir.join(RESULTS);
    let mut rows = load_rows(&path)?;
    let mut done: std::collections::BTreeSet<String> =
        rows.iter().map(|r| r.run_id.clone()).collect();
    let before = rows.len();
    for r in taken {
        if done.insert(r.run_id.clone()) {
            rows.push(r);
        }
    }
    let added = rows.len() - before;
    write_rows(&path, &in_run_order(cfg, rows)?)?;
    Ok(added)
}

/// Runs every run of `cfg` that `dir/results.csv` does not hold yet; returns all rows.
pub fn run_suite(
    cfg: &SuiteConfig,
    dir: &Path,
    threads: usize,
    on_row: &(dyn Fn(&SuiteRow, usize, usize) + Sync),
) -> Result<Vec<SuiteRow>, String> {
    run_suite_shard(cfg, dir, threads, None, on_row)
}

/// [`run_suite`] for the runs of one shard (run i in shard i mod n + 1, as a sweep's), or all
/// of them.
pub fn run_suite_shard(
    cfg: &SuiteConfig,
    dir: &Path,
    threads: usize,
    shard: Option<eemp_study::Shard>,
    on_row: &(dyn Fn(&SuiteRow, usize, usize) + Sync),
) -> Result<Vec<SuiteRow>, String> {
    cfg.validate()?;
    claim_folder(cfg, dir)?;
    let path = dir.join(RESULTS);
    let mut rows = load_rows(&path)?;
    // Rewrite without a partial line or failed rows, then append.
    write_rows(&path, &rows)?;
    let done: std::collections::BTreeSet<String> = rows.iter().map(|r| r.run_id.clone()).collect();
    let all: Vec<SuiteRun> = cfg
        .runs()?
        .into_iter()
        .enumerate()
        .filter(|(i, _)| shard.is_none_or(|s| s.contains(*i)))
        .map(|(_, r)| r)
        .collect();
    let total = all.len();
    let todo: Vec<SuiteRun> = all
        .into_iter()
        .filter(|r| !done.contains(&cfg.run_id(r)))
        .collect();
    let file = Mutex::new(
        std::fs::OpenOptions::new()
            .append(true)
            .open(&path)
            .map_err(|e| format!("cannot append to {}: {e}", path.display()))?,
    );
    let timing_path = dir.join(TIMING);
    let new_timing = !timing_path.exists();
    let mut timing_file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&timing_path)
        .map_err(|e| format!("cannot append to {}: {e}", timing_path.display()))?;
    if new_timing {
        timing_file
            .write_all(b"run_id,wall_s\n")
            .map_err(|e| e.to_string())?;
    }
    let timing = Mutex::new(timing_file);
    let finished = Mutex::new(rows.len());
    let robot = cfg.robot_config()?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
        .map_err(|e| e.to_string())?;
    let new_rows: Vec<Result<SuiteRow, String>> = pool.install(|| {
        todo.par_iter()
            .map(|run| {
                let t0 = std::time::Instant::now();
                let row = simulate(cfg, run, &robot).unwrap_or_else(|e| SuiteRow {
                    run_id: cfg.run_id(run),
                    method: cfg.methods[run.method].name.clone(),
                    scenario: cfg.scenarios[run.scenario].name.clone(),
                    speed_mps: run.speed_mps,
                    seed: run.seed,
                    fell: false,
                    fell_at_s: None,
                    vel_rmse_mps: None,
                    cot: None,
                    manipulability: None,
                    distance_m: 0.0,
                    steps_total: 0,
                    error: Some(e),
                    ..Default::default()
                });
                let mut w = csv::WriterBuilder::new()
                    .has_headers(false)
                    .from_writer(Vec::new());
                w.serialize(&row).map_err(|e| e.to_string())?;
                let line = w.into_inner().map_err(|e| e.to_string())?;
                {
                    // One write per row: a kill leaves at most a partial last line.
                    let mut f = file.lock().expect("not poisoned");
                    f.write_all(&line).map_err(|e| e.to_string())?;
                    f.flush().map_err(|e| e.to_string())?;
                }
                if row.error.is_none() {
                    let mut w = csv::WriterBuilder::new()
                        .has_headers(false)
                        .from_writer(Vec::new());
                    w.serialize((&row.run_id, t0.elapsed().as_secs_f64()))
                        .map_err(|e| e.to_string())?;
                    let line = w.into_inner().map_err(|e| e.to_string())?;
                    let mut f = timing.lock().expect("not poisoned");
                    f.write_all(&line).map_err(|e| e.to_string())?;
                }
                let mut n = finished.lock().expect("not poisoned");
                *n += 1;
                on_row(&row, *n, total);
                Ok(row)
            })
            .collect()
    });
    for r in new_rows {
        let r = r?;
        if let Some(e) = &r.error {
            return Err(format!("run {} could not be done: {e}", r.run_id));
        }
        rows.push(r);
    }
    // Complete: the file again, in the runs' order.
    let rows = in_run_order(cfg, rows)?;
    write_rows(&path, &rows)?;
    Ok(rows)
}
