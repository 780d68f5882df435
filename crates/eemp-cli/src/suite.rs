//! Many walks, one table: methods × scenarios × speeds × seeds, each a 20 s walk through the
//! same scenario and metrics code (`eemp_sim::walk`), run on a thread pool and resumable.
//!
//! A suite folder holds `suite.toml` (the config, written on the first start; a later start
//! with another config is refused) and `results.csv`: one row per finished run, appended and
//! flushed as each ends. A kill can leave only a partial last line, which the next start
//! drops; runs with a row are not run again. `eemp compare` and `eemp robustness` are this
//! runner with their own configs and reports.

use eemp_core::planner::params_table::ParamsTable;
use eemp_core::planner::Gait;
use eemp_core::robot::RobotConfig;
use eemp_core::settings::key_of;
use eemp_rl::run::{Sensing, WalkDescription};
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
    /// EEMP whose free-gait table EEMP-RL learned (CMA-ES's re-tuned table,
    /// `policies/a1_eemp_rl_cmaes_entry.toml`): the reports count it as EEMP-RL, against the
    /// free gait's table. Kind eemp, gait free.
    #[serde(default)]
    pub eemp_rl: bool,
    /// Controller settings as `key=value` over the gait's and the robot's defaults (`eemp walk
    /// --set`; `eemp config show` lists the keys): e.g. `["slip.adapt_friction=false",
    /// "mpc.horizon=8"]`. A learned method takes only `filter.*` (a policy runs with the
    /// controller it was trained with).
    #[serde(default)]
    pub set: Vec<String>,
}

impl MethodConfig {
    /// EEMP-RL: a residual policy (kind eemp-rl) or a table it learned (`eemp_rl = true`).
    pub fn is_eemp_rl(&self) -> bool {
        self.kind == "eemp-rl" || self.eemp_rl
    }

    /// The value the method's `set` gives `key` (its last assignment), as written.
    pub fn set_of(&self, key: &str) -> Option<&str> {
        self.set.iter().rev().find_map(|s| {
            let (k, v) = s.split_once('=')?;
            (k.trim() == key).then_some(v.trim())
        })
    }

    /// Slip handling as the method's `set` says (`slip.adapt_friction`); None: the gait's
    /// default.
    pub fn adapt_friction(&self) -> Option<bool> {
        self.set_of("slip.adapt_friction")
            .and_then(|v| v.parse().ok())
    }

    /// The method's settings other than those of `keys`, and other than the filter's: what
    /// makes its controller differ from the gait's default one.
    pub fn controller_sets_besides(&self, keys: &[&str]) -> Vec<&str> {
        self.set
            .iter()
            .map(String::as_str)
            .filter(|s| {
                let k = key_of(s);
                !keys.contains(&k) && !k.starts_with("filter.")
            })
            .collect()
    }

    /// Builds the method's walk on the flat floor at 0.3 m/s, as every run builds it, so a bad
    /// setting or table is refused before any run.
    fn check_walk(&self, suite: &SuiteConfig, robot: &RobotConfig) -> Result<(), String> {
        let flat = ScenarioConfig {
            name: "flat".into(),
            file: None,
            speeds_mps: vec![0.3],
            profile: None,
        };
        self.walk(suite, &flat, 0.3, 1, robot)
            .build()
            .map(|_| ())
            .map_err(|e| format!("method '{}': {e}", self.name))
    }

    /// The method's estimator: its own or the suite's.
    pub fn estimator<'a>(&'a self, suite: &'a SuiteConfig) -> &'a str {
        self.estimator.as_deref().unwrap_or(&suite.estimator)
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
            d.gait = gait;
        }
        d.set = self.set.clone();
        d
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
    /// Command every robot at the A1's Froude numbers: each `speeds_mps` × √λ, λ the robot's
    /// leg length over the A1's (`RobotConfig::scale`), so one suite file checks any robot.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub speeds_scale_with_robot: bool,
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
            crate::state_source_arg::state_source(m.estimator(self), false, 0, &robot)
                .map_err(|e| format!("method '{}': {e}", m.name))?;
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
                        // Slip handling as the table was trained; nothing else of the controller.
                        if let Some(s) = m
                            .set
                            .iter()
                            .find(|s| key_of(s) != "slip.adapt_friction")
                        {
                            return Err(format!(
                                "method '{}': set {s} is not for eemp_rl = true (a learned table \
                                 runs the free table's controller; slip.adapt_friction may say \
                                 how it was trained)",
                                m.name
                            ));
                        }
                    }
                    m.check_walk(self, &robot)?;
                }
                k @ ("model-free" | "imitation" | "eemp-rl") => {
                    if m.eemp_rl {
                        return Err(format!(
                            "method '{}': eemp_rl = true marks a learned table of kind eemp, \
                             not kind {k}",
                            m.name
                        ));
                    }
                    let planner = [(m.gait.is_some(), "gait"), (m.table.is_some(), "table")];
                    for (set, key) in planner {
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
                    m.check_walk(self, &robot)?;
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

    /// Every scenario's speeds as run, in the scenarios' order: × √λ when
    /// `speeds_scale_with_robot` (rounded to the millimetre per second that run ids and tables
    /// print; the robot is loaded once), else as written.
    pub fn scenario_speeds(&self) -> Result<Vec<Vec<f64>>, String> {
        let factor = match self.speeds_scale_with_robot {
            true => Some(
                crate::robot_arg::load_robot(self.robot.as_deref())?
                    .scale()
                    .length
                    .sqrt(),
            ),
            false => None,
        };
        self.scenarios
            .iter()
            .map(|s| {
                let speeds = s.speeds()?;
                Ok(match factor {
                    Some(f) => speeds
                        .into_iter()
                        .map(|v| (v * f * 1000.0).round() / 1000.0)
                        .collect(),
                    None => speeds,
                })
            })
            .collect()
    }

    pub fn runs(&self) -> Result<Vec<SuiteRun>, String> {
        let mut runs = Vec::new();
        for (si, speeds) in self.scenario_speeds()?.into_iter().enumerate() {
            for v in speeds {
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
