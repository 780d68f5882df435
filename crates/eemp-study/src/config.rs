//! The sweep file (`sweeps/*.toml`): the grid's axes and the selection settings, checked against
//! the paper's Table I before anything runs.
//!
//! ```toml
//! [grid]
//! gaits = ["trot", "walk"]                              # trot, walk, free
//! speed_mps = [0.1, 0.5]                                # V_x,des, Table I: 0.05–1.00
//! swing_time_s = { min = 0.10, max = 0.25, steps = 4 }  # ΔT, 0.10–0.25 (ends included)
//! step_height_m = [0.10]                                # h_step, 0.05–0.15
//! body_height_m = 0.31                                  # X_z, 0.28–0.311 (a number = one value)
//! ellipse_rx_m = [0.04, 0.07]                           # r_x, 0.01–0.15
//! ellipse_ry_m = [0.05]                                 # r_y, 0.01–0.15
//! duration_s = 20.0                                     # simulated seconds per run, 1–3600
//! seeds = [0]                                           # 0 = unperturbed start
//! progress_factor = { walk = 1.5 }                      # optional: eq. (6)'s factor per gait
//! estimator = "kf"                                       # optional: runs on the Kalman filter
//!
//! [selection]                                           # optional, these are the defaults
//! max_vel_rmse_mps = 0.25
//! max_speed_error_ratio = 0.5                           # |mean speed − command| ≤ 0.5 · command
//! manipulability_weight = 0.01
//! interpolation = "nearest"
//! ```

use crate::error::StudyError;
use eemp_core::planner::params::table_i;
use eemp_core::planner::params_table::Interpolation;
use eemp_core::planner::{Gait, PAPER_PROGRESS_FACTOR, PROGRESS_FACTOR_RANGE};
use serde::de::{self, Deserializer, MapAccess, SeqAccess, Visitor};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::Path;

/// Every grid value is rounded to 1e-6 (1 µm, 1 µs, 1 µm/s), so a value has one spelling:
/// `{ min = 0.1, max = 0.25, steps = 4 }` gives exactly 0.1, 0.15, 0.2, 0.25.
pub fn quantize(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

/// Most runs one grid may hold (a guard against a typo such as `steps = 1000`).
pub const MAX_RUNS: usize = 1_000_000;

/// Largest allowed `[selection] max_speed_error_ratio`.
pub const MAX_SPEED_ERROR_RATIO: f64 = 10.0;

/// Allowed simulated duration of one run, s.
pub const DURATION_S: [f64; 2] = [1.0, 3600.0];

/// Gaits in canonical order (the order of the run list).
pub const GAIT_ORDER: [Gait; 3] = [Gait::Trot, Gait::Walk, Gait::Free];

/// Position of a gait in [`GAIT_ORDER`].
pub fn gait_rank(gait: Gait) -> usize {
    GAIT_ORDER
        .iter()
        .position(|g| *g == gait)
        .expect("every gait is listed")
}

/// One axis as written in the file: a list (or a single number), or `{ min, max, steps }`
/// evenly spaced with both ends included.
#[derive(Clone, Debug, PartialEq)]
pub enum AxisSpec {
    List(Vec<f64>),
    Range { min: f64, max: f64, steps: i64 },
}

/// The validated grid: every axis quantised, sorted ascending and free of repeats; gaits in
/// [`GAIT_ORDER`]. Two grids are the same sweep exactly when they are equal.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Grid {
    pub gaits: Vec<Gait>,
    /// Commanded forward speed V_x,des, m/s.
    pub speed_mps: Vec<f64>,
    /// ΔT, s.
    pub swing_time_s: Vec<f64>,
    /// h_step, m.
    pub step_height_m: Vec<f64>,
    /// X_z, m.
    pub body_height_m: Vec<f64>,
    /// r_x, m.
    pub ellipse_rx_m: Vec<f64>,
    /// r_y, m.
    pub ellipse_ry_m: Vec<f64>,
    /// Simulated time of every run, s.
    pub duration_s: f64,
    /// Start seeds (0 = unperturbed start; see `WalkSpec::seed`).
    pub seeds: Vec<u64>,
    /// Eq. (6)'s progress factor of every run, per gait (a setting, not an axis: it does not
    /// multiply the runs, and a run's id does not include it; the folder's `sweep.toml` does).
    /// Gaits not in `gaits` keep the default.
    #[serde(skip_serializing_if = "ProgressFactors::is_default")]
    pub progress_factor: ProgressFactors,
    /// What every run's controller sees: the simulator's state (default) or the Kalman filter
    /// on the simulated IMU and encoders with the default sensor noise, seeded by the run's
    /// seed. A setting like `progress_factor`, stored in `sweep.toml`.
    #[serde(skip_serializing_if = "SweepEstimator::is_ground_truth")]
    pub estimator: SweepEstimator,
    /// The robot file every run simulates (`[grid] robot = "robots/go2.toml"`; none: the
    /// shipped A1). A setting, stored in `sweep.toml`; the tables are stamped with its id and
    /// named `<robot>_<gait>.toml`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub robot: Option<std::path::PathBuf>,
    /// Viscous joint damping (abduction, thigh, calf), N·m·s/rad, in place of the robot file's
    /// (`[grid] joint_damping_nms = [1, 2, 2]`, Menagerie's A1): a modelling choice of the
    /// sensitivity study (`eemp sweep sensitivity`), a setting stored in `sweep.toml`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joint_damping_nms: Option<[f64; 3]>,
    /// MPC cost weights in place of the defaults (`[grid.mpc_weights] velocity = [10, 10, 5]`):
    /// the other modelling choice of the sensitivity study, a setting like the damping.
    #[serde(skip_serializing_if = "MpcWeights::is_default")]
    pub mpc_weights: MpcWeights,
}

impl Grid {
    /// The robot of the runs (validated when the sweep file was read), with the grid's joint
    /// damping if it sets one.
    pub fn robot_config(&self) -> Result<eemp_core::robot::RobotConfig, String> {
        let mut robot = eemp_sim::robot_model::load_robot_or_a1(self.robot.as_deref())
            .map_err(|e| e.to_string())?;
        if let Some(d) = self.joint_damping_nms {
            robot.leg.damping = d;
        }
        Ok(robot)
    }
}

/// Eq. (2)'s cost weights that a sweep replaces (`[grid.mpc_weights]`); a weight left out keeps
/// `MpcConfig`'s default. Each is ≥ 0 and finite.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MpcWeights {
    /// Roll, pitch, yaw.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rpy: Option<[f64; 3]>,
    /// Trunk position x, y, z.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position: Option<[f64; 3]>,
    /// Angular velocity.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub omega: Option<[f64; 3]>,
    /// Linear velocity.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<[f64; 3]>,
    /// Ground reaction forces (one weight for every component).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force: Option<f64>,
    /// The motors' heat (`mpc.weight_heat`, 1/W; absent: the robot file's `[control]`
    /// default). The paper's sweeps set 0: its cost has no heat term.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heat: Option<f64>,
}

/// Largest MPC weight a sweep may set (the defaults reach 500).
pub const MAX_MPC_WEIGHT: f64 = 1e6;

impl MpcWeights {
    pub fn is_default(&self) -> bool {
        *self == MpcWeights::default()
    }

    /// `mpc` with these weights in place.
    pub fn apply(&self, mpc: &mut eemp_core::convex_mpc::MpcConfig) {
        let set3 = |dst: &mut [f64; 3], v: Option<[f64; 3]>| {
            if let Some(v) = v {
                *dst = v;
            }
        };
        set3(&mut mpc.weight_rpy, self.rpy);
        set3(&mut mpc.weight_position, self.position);
        set3(&mut mpc.weight_omega, self.omega);
        set3(&mut mpc.weight_velocity, self.velocity);
        if let Some(f) = self.force {
            mpc.weight_force = f;
        }
        if let Some(h) = self.heat {
            mpc.weight_heat = Some(h);
        }
    }

    /// Each weight as (key, values), for validation and reports.
    fn entries(&self) -> Vec<(&'static str, Vec<f64>)> {
        let mut out = Vec::new();
        for (k, v) in [
            ("rpy", self.rpy),
            ("position", self.position),
            ("omega", self.omega),
            ("velocity", self.velocity),
        ] {
            if let Some(v) = v {
                out.push((k, v.to_vec()));
            }
        }
        if let Some(f) = self.force {
            out.push(("force", vec![f]));
        }
        if let Some(h) = self.heat {
            out.push(("heat", vec![h]));
        }
        out
    }

    /// The `--set` assignments that run a walk with these weights, as the sweep ran them
    /// (`mpc.weight_velocity=[10, 10, 5]`, `mpc.weight_heat=0.002`).
    pub fn as_sets(&self) -> Vec<String> {
        self.entries()
            .into_iter()
            .map(|(k, v)| {
                let key = match k {
                    "heat" => "mpc.weight_heat".to_string(),
                    "force" => "mpc.weight_force".to_string(),
                    other => format!("mpc.weight_{other}"),
                };
                match v.as_slice() {
                    [x] => format!("{key}={x}"),
                    xs => format!(
                        "{key}=[{}]",
                        xs.iter().map(f64::to_string).collect::<Vec<_>>().join(", ")
                    ),
                }
            })
            .collect()
    }

    /// `velocity = [10, 10, 5]; force = 0.001`, or `default`.
    pub fn describe(&self) -> String {
        let e = self.entries();
        if e.is_empty() {
            return "default".into();
        }
        e.iter()
            .map(|(k, v)| match v.as_slice() {
                [x] => format!("{k} = {x}"),
                _ => format!("{k} = {v:?}"),
            })
            .collect::<Vec<_>>()
            .join("; ")
    }
}

/// The state source of a sweep's runs (`[grid] estimator = "ground-truth" | "kf"`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SweepEstimator {
    #[default]
    GroundTruth,
    Kf,
}

impl SweepEstimator {
    pub fn is_ground_truth(&self) -> bool {
        *self == SweepEstimator::GroundTruth
    }

    /// As written in sweep files.
    pub fn name(&self) -> &'static str {
        match self {
            SweepEstimator::GroundTruth => "ground-truth",
            SweepEstimator::Kf => "kf",
        }
    }
}

/// Eq. (6)'s factor on V·ΔT per gait (`PlannerConfig::progress_factor`); default 0.5 (the
/// paper's text) for every gait. A sweep file gives one number for all gaits or a table
/// `{ trot = …, walk = …, free = … }` (gaits left out keep 0.5). Stored (serialised) as the
/// table of the factors that differ from the default, so a grid that keeps the default stores
/// no key, as before the setting existed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProgressFactors {
    pub trot: f64,
    pub walk: f64,
    pub free: f64,
}

impl Default for ProgressFactors {
    fn default() -> Self {
        let d = PAPER_PROGRESS_FACTOR;
        ProgressFactors {
            trot: d,
            walk: d,
            free: d,
        }
    }
}

impl Serialize for ProgressFactors {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let d = ProgressFactors::default();
        let own: Vec<(Gait, f64)> = GAIT_ORDER
            .iter()
            .map(|&g| (g, self.get(g)))
            .filter(|&(g, v)| v != d.get(g))
            .collect();
        let mut map = s.serialize_map(Some(own.len()))?;
        for (g, v) in own {
            map.serialize_entry(&g.to_string(), &v)?;
        }
        map.end()
    }
}

impl ProgressFactors {
    /// Every gait at the default (nothing to store).
    pub fn is_default(&self) -> bool {
        *self == ProgressFactors::default()
    }

    pub fn get(&self, gait: Gait) -> f64 {
        match gait {
            Gait::Trot => self.trot,
            Gait::Walk => self.walk,
            Gait::Free => self.free,
        }
    }

    fn set(&mut self, gait: Gait, factor: f64) {
        match gait {
            Gait::Trot => self.trot = factor,
            Gait::Walk => self.walk = factor,
            Gait::Free => self.free = factor,
        }
    }
}

impl Grid {
    /// Lengths of the axes that make up a grid point, in file order.
    fn point_axes(&self) -> [usize; 7] {
        [
            self.gaits.len(),
            self.speed_mps.len(),
            self.swing_time_s.len(),
            self.step_height_m.len(),
            self.body_height_m.len(),
            self.ellipse_rx_m.len(),
            self.ellipse_ry_m.len(),
        ]
    }

    /// Number of grid points (runs without the seed axis); `None` if it does not fit a
    /// `usize`.
    pub fn checked_point_count(&self) -> Option<usize> {
        self.point_axes()
            .iter()
            .try_fold(1usize, |n, &len| n.checked_mul(len))
    }

    /// Number of runs (grid points × seeds); `None` if it does not fit a `usize`.
    pub fn checked_run_count(&self) -> Option<usize> {
        self.checked_point_count()?.checked_mul(self.seeds.len())
    }

    /// Number of grid points, saturating at `usize::MAX` (a validated grid has at most
    /// [`MAX_RUNS`] runs).
    pub fn point_count(&self) -> usize {
        self.checked_point_count().unwrap_or(usize::MAX)
    }

    /// Number of runs (grid points × seeds), saturating at `usize::MAX` (a validated grid has
    /// at most [`MAX_RUNS`]).
    pub fn run_count(&self) -> usize {
        self.checked_run_count().unwrap_or(usize::MAX)
    }

    /// A readable account of how `self` differs from `other` (empty when equal).
    pub fn differences(&self, other: &Grid) -> Vec<String> {
        let mut out = Vec::new();
        let mut axis = |key: &str, a: &[f64], b: &[f64]| {
            if a != b {
                out.push(format!("{key}: {a:?} vs {b:?}"));
            }
        };
        axis("speed_mps", &self.speed_mps, &other.speed_mps);
        axis("swing_time_s", &self.swing_time_s, &other.swing_time_s);
        axis("step_height_m", &self.step_height_m, &other.step_height_m);
        axis("body_height_m", &self.body_height_m, &other.body_height_m);
        axis("ellipse_rx_m", &self.ellipse_rx_m, &other.ellipse_rx_m);
        axis("ellipse_ry_m", &self.ellipse_ry_m, &other.ellipse_ry_m);
        axis("duration_s", &[self.duration_s], &[other.duration_s]);
        if self.gaits != other.gaits {
            out.push(format!("gaits: {:?} vs {:?}", self.gaits, other.gaits));
        }
        if self.seeds != other.seeds {
            out.push(format!("seeds: {:?} vs {:?}", self.seeds, other.seeds));
        }
        if self.estimator != other.estimator {
            out.push(format!(
                "estimator: {} vs {}",
                self.estimator.name(),
                other.estimator.name()
            ));
        }
        if self.progress_factor != other.progress_factor {
            out.push(format!(
                "progress_factor: {:?} vs {:?}",
                self.progress_factor, other.progress_factor
            ));
        }
        if self.robot != other.robot {
            out.push(format!("robot: {:?} vs {:?}", self.robot, other.robot));
        }
        if self.joint_damping_nms != other.joint_damping_nms {
            out.push(format!(
                "joint_damping_nms: {:?} vs {:?}",
                self.joint_damping_nms, other.joint_damping_nms
            ));
        }
        if self.mpc_weights != other.mpc_weights {
            out.push(format!(
                "mpc_weights: {} vs {}",
                self.mpc_weights.describe(),
                other.mpc_weights.describe()
            ));
        }
        out
    }
}

/// How the report picks parameters (`[selection]`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SelectionConfig {
    /// Grid points whose seed-averaged velocity RMSE exceeds this are excluded, m/s
    /// (a run that does not follow the command is not a valid way to move at that speed).
    pub max_vel_rmse_mps: f64,
    /// Grid points whose seed-averaged mean speed (distance over the metrics window) differs
    /// from the command by more than this fraction of the command are excluded. The RMSE
    /// limit is absolute and so admits large relative errors at low speeds; CoT is per
    /// distance, so a point that overshoots the command looks cheaper than it is.
    pub max_speed_error_ratio: f64,
    /// Weight w of the robustness term in the score `cot − w · manipulability`; 0 = CoT only.
    pub manipulability_weight: f64,
    /// Lookup between the tabulated speeds in the written tables.
    pub interpolation: Interpolation,
    /// Which CoT the score uses: the paper's eq. (8), or the battery's electrical CoT under the
    /// robot file's motor model (the drives alone, or with the idle power).
    pub objective: Objective,
}

/// The energy a sweep's selection minimises (`[selection] objective`), written into its tables.
pub use eemp_core::metrics::CotObjective as Objective;

impl Default for SelectionConfig {
    fn default() -> Self {
        SelectionConfig {
            max_vel_rmse_mps: 0.25,
            max_speed_error_ratio: 0.5,
            manipulability_weight: 0.01,
            interpolation: Interpolation::Nearest,
            objective: Objective::Eq8,
        }
    }
}

/// A validated sweep file.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SweepConfig {
    pub grid: Grid,
    pub selection: SelectionConfig,
}

impl SweepConfig {
    /// The same study at `--quick` scale, to check a pipeline end to end (not a result): the
    /// slowest and the fastest speed, the shortest and the longest swing time, the first value
    /// of every other axis, the first seed, runs of at most 3 s.
    pub fn quick(&self) -> SweepConfig {
        let ends = |v: &[f64]| -> Vec<f64> {
            let mut e = vec![v[0], v[v.len() - 1]];
            e.dedup();
            e
        };
        let first = |v: &[f64]| vec![v[0]];
        let g = &self.grid;
        SweepConfig {
            grid: Grid {
                speed_mps: ends(&g.speed_mps),
                swing_time_s: ends(&g.swing_time_s),
                step_height_m: first(&g.step_height_m),
                body_height_m: first(&g.body_height_m),
                ellipse_rx_m: first(&g.ellipse_rx_m),
                ellipse_ry_m: first(&g.ellipse_ry_m),
                duration_s: g.duration_s.min(3.0),
                seeds: vec![g.seeds[0]],
                ..g.clone()
            },
            selection: self.selection,
        }
    }

    /// Reads and validates a sweep file; errors name the file and the key.
    pub fn load(path: &Path) -> Result<Self, StudyError> {
        let text = std::fs::read_to_string(path).map_err(|e| StudyError::read(path, e))?;
        Self::parse(&text, path)
    }

    /// Validates sweep-file text; `path` is only used in messages.
    pub fn parse(text: &str, path: &Path) -> Result<Self, StudyError> {
        let raw: RawFile = toml::from_str(text).map_err(|e| StudyError::Parse {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let v = Validator { path };
        let g = &raw.grid;
        let gaits = v.gaits(&g.gaits)?;
        let estimator = match g.estimator.as_deref() {
            None | Some("ground-truth") => SweepEstimator::GroundTruth,
            Some("kf") => SweepEstimator::Kf,
            Some(other) => {
                return Err(v.error(
                    "grid.estimator",
                    format!("unknown estimator '{other}': allowed ground-truth, kf"),
                ))
            }
        };
        // Table I's ranges are the A1's; a robot whose settings are scaled
        // (`RobotConfig::settings_scale`) gets them scaled the same way.
        let scale = match &g.robot {
            Some(r) => eemp_sim::robot_model::load_robot(r)
                .map_err(|e| v.error("grid.robot", e.to_string()))?
                .settings_scale(),
            None => None,
        };
        let (l, t) = scale.map_or((1.0, 1.0), |s| (s.length, s.length.sqrt()));
        // Scaled bounds are written to the millimetre (or ms) in sweep files: a thousandth
        // of slack each side.
        let scaled = |r: [f64; 2], k: f64| match scale {
            Some(_) => [r[0] * k - 1e-3, r[1] * k + 1e-3],
            None => r,
        };
        let grid = Grid {
            estimator,
            robot: g.robot.clone(),
            joint_damping_nms: v.joint_damping(g.joint_damping_nms)?,
            mpc_weights: v.mpc_weights(&g.mpc_weights)?,
            progress_factor: v.progress_factor(g.progress_factor.as_ref(), &gaits)?,
            gaits,
            speed_mps: v.axis(
                "speed_mps",
                &g.speed_mps,
                scaled(table_i::SPEED_MPS, t),
                "m/s",
            )?,
            swing_time_s: v.axis(
                "swing_time_s",
                &g.swing_time_s,
                scaled(table_i::SWING_TIME_S, t),
                "s",
            )?,
            step_height_m: v.axis(
                "step_height_m",
                &g.step_height_m,
                scaled(table_i::STEP_HEIGHT_M, l),
                "m",
            )?,
            body_height_m: v.axis(
                "body_height_m",
                &g.body_height_m,
                eemp_core::planner::params::BODY_HEIGHT_LIMITS_M,
                "m",
            )?,
            ellipse_rx_m: v.axis(
                "ellipse_rx_m",
                &g.ellipse_rx_m,
                scaled(table_i::ELLIPSE_AXIS_M, l),
                "m",
            )?,
            ellipse_ry_m: v.axis(
                "ellipse_ry_m",
                &g.ellipse_ry_m,
                scaled(table_i::ELLIPSE_AXIS_M, l),
                "m",
            )?,
            duration_s: v.duration(g.duration_s.0)?,
            seeds: v.seeds(&g.seeds)?,
        };
        // Table I's body heights are the paper's grid; a sweep may widen them as far as the
        // robot's legs reach.
        let robot = grid.robot_config().map_err(|e| v.error("grid.robot", e))?;
        for h in &grid.body_height_m {
            robot
                .check_body_height("grid.body_height_m", *h)
                .map_err(|e| v.error("grid.body_height_m", e.to_string()))?;
        }
        if let Some(h) = grid.mpc_weights.heat {
            if !(0.0..=1.0).contains(&h) {
                return Err(v.error(
                    "grid.mpc_weights.heat",
                    format!("{h} is out of range: allowed [0, 1] (1/W)"),
                ));
            }
            if h > 0.0 && robot.motor_model().is_none() {
                return Err(v.error(
                    "grid.mpc_weights.heat",
                    format!("{h} weighs the motors' heat: the robot file has no [motor] section"),
                ));
            }
        }
        if grid.checked_run_count().is_none_or(|n| n > MAX_RUNS) {
            let mut axes: Vec<usize> = grid.point_axes().to_vec();
            axes.push(grid.seeds.len());
            let count = grid.checked_run_count().map_or_else(
                || format!("{:.3e}", axes.iter().map(|&n| n as f64).product::<f64>()),
                |n| n.to_string(),
            );
            let factors: Vec<String> = axes.iter().map(usize::to_string).collect();
            return Err(v.error(
                "grid",
                format!(
                    "{} = {count} runs (gaits × speeds × ΔT × h_step × X_z × r_x × r_y × \
                     seeds) is more than the {MAX_RUNS} one sweep may hold; use fewer values",
                    factors.join(" × ")
                ),
            ));
        }
        let selection = v.selection(&raw.selection)?;
        if selection.objective != Objective::Eq8 && robot.motor_model().is_none() {
            return Err(v.error(
                "selection.objective",
                "an electrical objective needs the robot's motor model: the robot file has no \
                 [motor] section"
                    .into(),
            ));
        }
        Ok(SweepConfig { grid, selection })
    }

    /// The canonical file text (explicit sorted lists), as stored in a sweep folder; parsing it
    /// gives back an equal config.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a sweep config serialises")
    }
}

struct Validator<'a> {
    path: &'a Path,
}

impl Validator<'_> {
    fn error(&self, key: &str, message: String) -> StudyError {
        StudyError::Config {
            path: self.path.to_path_buf(),
            key: key.to_string(),
            message,
        }
    }

    fn gaits(&self, names: &[String]) -> Result<Vec<Gait>, StudyError> {
        if names.is_empty() {
            return Err(self.error(
                "grid.gaits",
                "empty list: give at least one of trot, walk, free".into(),
            ));
        }
        let mut gaits = Vec::new();
        for (i, name) in names.iter().enumerate() {
            let gait: Gait = name
                .parse()
                .map_err(|e: String| self.error(&format!("grid.gaits[{i}]"), e))?;
            if gaits.contains(&gait) {
                return Err(self.error(
                    &format!("grid.gaits[{i}]"),
                    format!("'{gait}' is listed twice"),
                ));
            }
            gaits.push(gait);
        }
        gaits.sort_by_key(|g| gait_rank(*g));
        Ok(gaits)
    }

    fn axis(
        &self,
        name: &str,
        spec: &AxisSpec,
        [lo, hi]: [f64; 2],
        unit: &str,
    ) -> Result<Vec<f64>, StudyError> {
        let key = format!("grid.{name}");
        let in_range = |k: &str, v: f64| {
            if v.is_finite() && v >= lo && v <= hi {
                Ok(())
            } else {
                Err(self.error(
                    k,
                    format!("{v} is out of range: allowed [{lo}, {hi}] {unit} (Table I)"),
                ))
            }
        };
        let mut values = match spec {
            AxisSpec::List(list) => {
                if list.is_empty() {
                    return Err(self.error(
                        &key,
                        format!("empty list: give at least one value in [{lo}, {hi}] {unit}"),
                    ));
                }
                for (i, v) in list.iter().enumerate() {
                    in_range(&format!("{key}[{i}]"), *v)?;
                }
                list.iter().map(|v| quantize(*v)).collect::<Vec<f64>>()
            }
            &AxisSpec::Range { min, max, steps } => {
                in_range(&format!("{key}.min"), min)?;
                in_range(&format!("{key}.max"), max)?;
                if min > max {
                    return Err(self.error(&key, format!("min {min} is greater than max {max}")));
                }
                if steps < 1 {
                    return Err(self.error(
                        &format!("{key}.steps"),
                        format!("{steps} is out of range: allowed 1 or more"),
                    ));
                }
                if steps == 1 && min != max {
                    return Err(self.error(
                        &format!("{key}.steps"),
                        format!("1 step needs min == max (got {min} and {max}); use 2 or more"),
                    ));
                }
                if steps as usize > MAX_RUNS {
                    return Err(self.error(
                        &format!("{key}.steps"),
                        format!("{steps} is out of range: allowed at most {MAX_RUNS}"),
                    ));
                }
                let n = steps as usize;
                (0..n)
                    .map(|i| {
                        let f = if n == 1 {
                            0.0
                        } else {
                            i as f64 / (n - 1) as f64
                        };
                        quantize(min + f * (max - min))
                    })
                    .collect()
            }
        };
        values.sort_by(f64::total_cmp);
        if let Some(w) = values.windows(2).find(|w| w[0] == w[1]) {
            return Err(self.error(
                &key,
                format!(
                    "{} appears twice (values are compared at 1e-6 resolution)",
                    w[0]
                ),
            ));
        }
        Ok(values)
    }

    /// Gaits outside `gaits` keep the default, so two grids differ only in factors they use.
    fn progress_factor(
        &self,
        raw: Option<&toml::Value>,
        gaits: &[Gait],
    ) -> Result<ProgressFactors, StudyError> {
        let mut out = ProgressFactors::default();
        let number = |key: &str, v: &toml::Value| match v {
            toml::Value::Float(x) => Ok(*x),
            toml::Value::Integer(i) => Ok(*i as f64),
            other => Err(self.error(
                key,
                format!("expected a number, found {}", other.type_str()),
            )),
        };
        let check = |key: &str, v: f64| {
            let [lo, hi] = PROGRESS_FACTOR_RANGE;
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(quantize(v))
            } else {
                Err(self.error(
                    key,
                    format!(
                        "{v} is out of range: allowed [{lo}, {hi}] (factor on V·ΔT in eq. 6: \
                         0.5 = the paper's text, 1 = its Algorithm 1)"
                    ),
                ))
            }
        };
        const KEY: &str = "grid.progress_factor";
        match raw {
            None => {}
            Some(toml::Value::Table(per_gait)) => {
                for (name, value) in per_gait {
                    let key = format!("{KEY}.{name}");
                    let gait: Gait = name.parse().map_err(|e: String| self.error(&key, e))?;
                    let v = check(&key, number(&key, value)?)?;
                    if !gaits.contains(&gait) {
                        // The default is harmless (and what an early stored file holds).
                        if v == out.get(gait) {
                            continue;
                        }
                        return Err(self.error(
                            &key,
                            format!("{gait} is not in grid.gaits; give factors of its gaits only"),
                        ));
                    }
                    out.set(gait, v);
                }
            }
            Some(value) => {
                let v = check(KEY, number(KEY, value)?)?;
                for &gait in gaits {
                    out.set(gait, v);
                }
            }
        }
        Ok(out)
    }

    fn duration(&self, v: f64) -> Result<f64, StudyError> {
        let [lo, hi] = DURATION_S;
        if v.is_finite() && (lo..=hi).contains(&v) {
            Ok(quantize(v))
        } else {
            Err(self.error(
                "grid.duration_s",
                format!("{v} is out of range: allowed [{lo}, {hi}] s"),
            ))
        }
    }

    fn seeds(&self, seeds: &[i64]) -> Result<Vec<u64>, StudyError> {
        if seeds.is_empty() {
            return Err(self.error(
                "grid.seeds",
                "empty list: give at least one seed (0 = unperturbed start)".into(),
            ));
        }
        let mut out = Vec::new();
        for (i, s) in seeds.iter().enumerate() {
            let s = u64::try_from(*s).map_err(|_| {
                self.error(
                    &format!("grid.seeds[{i}]"),
                    format!("{s} is out of range: allowed 0 or more"),
                )
            })?;
            out.push(s);
        }
        out.sort_unstable();
        if let Some(w) = out.windows(2).find(|w| w[0] == w[1]) {
            return Err(self.error("grid.seeds", format!("{} appears twice", w[0])));
        }
        Ok(out)
    }

    /// Allowed [0, 10] N·m·s/rad per joint (Menagerie's A1 has 1–2).
    fn joint_damping(&self, d: Option<[f64; 3]>) -> Result<Option<[f64; 3]>, StudyError> {
        if let Some(d) = d {
            for (i, x) in d.iter().enumerate() {
                if !(x.is_finite() && (0.0..=10.0).contains(x)) {
                    return Err(self.error(
                        &format!("grid.joint_damping_nms[{i}]"),
                        format!("{x} is out of range: allowed [0, 10] N·m·s/rad"),
                    ));
                }
            }
        }
        Ok(d)
    }

    fn mpc_weights(&self, w: &MpcWeights) -> Result<MpcWeights, StudyError> {
        for (key, values) in w.entries() {
            for (i, x) in values.iter().enumerate() {
                if !(x.is_finite() && (0.0..=MAX_MPC_WEIGHT).contains(x)) {
                    let at = if values.len() > 1 {
                        format!("grid.mpc_weights.{key}[{i}]")
                    } else {
                        format!("grid.mpc_weights.{key}")
                    };
                    return Err(self.error(
                        &at,
                        format!("{x} is out of range: allowed [0, {MAX_MPC_WEIGHT:e}]"),
                    ));
                }
            }
        }
        Ok(*w)
    }

    fn selection(&self, raw: &RawSelection) -> Result<SelectionConfig, StudyError> {
        let d = SelectionConfig::default();
        let rmse = raw.max_vel_rmse_mps.map_or(d.max_vel_rmse_mps, |n| n.0);
        if rmse.is_nan() || rmse <= 0.0 {
            return Err(self.error(
                "selection.max_vel_rmse_mps",
                format!("{rmse} is out of range: allowed (0, inf] m/s (inf = no limit)"),
            ));
        }
        let ratio = raw
            .max_speed_error_ratio
            .map_or(d.max_speed_error_ratio, |n| n.0);
        if !(ratio.is_finite() && ratio > 0.0 && ratio <= MAX_SPEED_ERROR_RATIO) {
            return Err(self.error(
                "selection.max_speed_error_ratio",
                format!(
                    "{ratio} is out of range: allowed (0, {MAX_SPEED_ERROR_RATIO}] (a fraction of \
                     the commanded speed; 0.5 = mean speed within ±50 % of the command)"
                ),
            ));
        }
        let w = raw
            .manipulability_weight
            .map_or(d.manipulability_weight, |n| n.0);
        if !(w.is_finite() && (0.0..=10.0).contains(&w)) {
            return Err(self.error(
                "selection.manipulability_weight",
                format!("{w} is out of range: allowed [0, 10] (0 = CoT only)"),
            ));
        }
        Ok(SelectionConfig {
            max_vel_rmse_mps: rmse,
            max_speed_error_ratio: ratio,
            manipulability_weight: w,
            interpolation: raw.interpolation.unwrap_or(d.interpolation),
            objective: raw.objective.unwrap_or_default(),
        })
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    grid: RawGrid,
    #[serde(default)]
    selection: RawSelection,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGrid {
    gaits: Vec<String>,
    speed_mps: AxisSpec,
    swing_time_s: AxisSpec,
    step_height_m: AxisSpec,
    body_height_m: AxisSpec,
    ellipse_rx_m: AxisSpec,
    ellipse_ry_m: AxisSpec,
    duration_s: Number,
    seeds: Vec<i64>,
    /// `1.0` (every gait) or `{ walk = 1.5 }` (per gait); read by hand for clear errors.
    #[serde(default)]
    progress_factor: Option<toml::Value>,
    #[serde(default)]
    estimator: Option<String>,
    #[serde(default)]
    robot: Option<std::path::PathBuf>,
    #[serde(default)]
    joint_damping_nms: Option<[f64; 3]>,
    #[serde(default)]
    mpc_weights: MpcWeights,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawSelection {
    max_vel_rmse_mps: Option<Number>,
    max_speed_error_ratio: Option<Number>,
    manipulability_weight: Option<Number>,
    interpolation: Option<Interpolation>,
    objective: Option<Objective>,
}

/// A TOML number, integer or float (`0` and `0.0` alike).
#[derive(Clone, Copy, Debug)]
struct Number(f64);

impl<'de> Deserialize<'de> for Number {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = Number;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Number, E> {
                Ok(Number(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Number, E> {
                Ok(Number(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Number, E> {
                Ok(Number(v as f64))
            }
        }
        d.deserialize_any(V)
    }
}

impl<'de> Deserialize<'de> for AxisSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = AxisSpec;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number, a list of numbers, or a table { min, max, steps }")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<AxisSpec, E> {
                Ok(AxisSpec::List(vec![v]))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<AxisSpec, E> {
                Ok(AxisSpec::List(vec![v as f64]))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<AxisSpec, E> {
                Ok(AxisSpec::List(vec![v as f64]))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<AxisSpec, A::Error> {
                let mut values = Vec::new();
                while let Some(Number(v)) = seq.next_element()? {
                    values.push(v);
                }
                Ok(AxisSpec::List(values))
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<AxisSpec, A::Error> {
                const FIELDS: &[&str] = &["min", "max", "steps"];
                let (mut min, mut max, mut steps) = (None, None, None);
                while let Some(key) = map.next_key::<String>()? {
                    match key.as_str() {
                        "min" => min = Some(map.next_value::<Number>()?.0),
                        "max" => max = Some(map.next_value::<Number>()?.0),
                        "steps" => steps = Some(map.next_value::<i64>()?),
                        other => return Err(de::Error::unknown_field(other, FIELDS)),
                    }
                }
                Ok(AxisSpec::Range {
                    min: min.ok_or_else(|| de::Error::missing_field("min"))?,
                    max: max.ok_or_else(|| de::Error::missing_field("max"))?,
                    steps: steps.ok_or_else(|| de::Error::missing_field("steps"))?,
                })
            }
        }
        d.deserialize_any(V)
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn mpc_weights_as_sets_run_the_weights_the_sweep_applied() {
        let w = MpcWeights {
            velocity: Some([10.0, 10.0, 5.0]),
            force: Some(1e-4),
            heat: Some(0.002),
            ..Default::default()
        };
        let base = eemp_core::settings::ControllerSettings {
            planner: Default::default(),
            controller: Default::default(),
            filter: None,
        };
        let mut applied = base.controller.mpc.clone();
        w.apply(&mut applied);
        let set = base.with_sets(&w.as_sets()).unwrap();
        assert_eq!(set.controller.mpc, applied);
        assert!(MpcWeights::default().as_sets().is_empty());
    }

    use super::*;

    const GOOD: &str = r#"
[grid]
gaits = ["walk", "trot"]
speed_mps = [0.5, 0.1]
swing_time_s = { min = 0.10, max = 0.25, steps = 4 }
step_height_m = 0.1
body_height_m = [0.31]
ellipse_rx_m = { min = 0.01, max = 0.15, steps = 3 }
ellipse_ry_m = [0.05]
duration_s = 3
seeds = [1, 0]
"#;

    fn parse(text: &str) -> Result<SweepConfig, StudyError> {
        SweepConfig::parse(text, Path::new("test.toml"))
    }

    fn error_of(text: &str) -> String {
        parse(text).unwrap_err().to_string()
    }

    #[test]
    fn axes_are_expanded_quantised_and_sorted() {
        let c = parse(GOOD).unwrap();
        let g = &c.grid;
        assert_eq!(g.gaits, vec![Gait::Trot, Gait::Walk]);
        assert_eq!(g.speed_mps, vec![0.1, 0.5]);
        assert_eq!(g.swing_time_s, vec![0.1, 0.15, 0.2, 0.25]);
        assert_eq!(g.step_height_m, vec![0.1]);
        assert_eq!(g.ellipse_rx_m, vec![0.01, 0.08, 0.15]);
        assert_eq!(g.duration_s, 3.0);
        assert_eq!(g.seeds, vec![0, 1]);
        assert_eq!(g.point_count(), 2 * 2 * 4 * 3);
        assert_eq!(g.run_count(), 2 * 2 * 4 * 3 * 2);
        assert_eq!(c.selection, SelectionConfig::default());
    }

    #[test]
    fn the_quick_study_keeps_the_ends_of_speed_and_swing_time_and_one_of_the_rest() {
        let q = parse(GOOD).unwrap().quick();
        let g = &q.grid;
        assert_eq!(g.gaits, vec![Gait::Trot, Gait::Walk]);
        assert_eq!(g.speed_mps, vec![0.1, 0.5]);
        assert_eq!(g.swing_time_s, vec![0.1, 0.25]);
        assert_eq!(g.ellipse_rx_m, vec![0.01]);
        assert_eq!(g.seeds, vec![0]);
        assert_eq!(g.run_count(), 2 * 2 * 2);
        let one_speed = parse(&GOOD.replace("[0.5, 0.1]", "[0.3]")).unwrap().quick();
        assert_eq!(one_speed.grid.speed_mps, vec![0.3]);
    }

    #[test]
    fn canonical_text_round_trips() {
        let c = parse(GOOD).unwrap();
        let back = parse(&c.to_toml()).unwrap();
        assert_eq!(back, c);
        assert!(c
            .to_toml()
            .contains("swing_time_s = [0.1, 0.15, 0.2, 0.25]"));
    }

    #[test]
    fn bad_values_are_rejected_with_the_key_and_range() {
        let cases: [(&str, &str, &[&str]); 12] = [
            (
                "swing_time_s = { min = 0.10, max = 0.25, steps = 4 }",
                "swing_time_s = [0.1, 0.3]",
                &["grid.swing_time_s[1]", "0.3", "[0.1, 0.25]"],
            ),
            (
                "speed_mps = [0.5, 0.1]",
                "speed_mps = [0.01]",
                &["grid.speed_mps[0]", "[0.05, 1]", "m/s"],
            ),
            (
                "step_height_m = 0.1",
                "step_height_m = []",
                &["grid.step_height_m", "empty list"],
            ),
            (
                "ellipse_rx_m = { min = 0.01, max = 0.15, steps = 3 }",
                "ellipse_rx_m = { min = 0.10, max = 0.05, steps = 3 }",
                &["grid.ellipse_rx_m", "min 0.1 is greater than max 0.05"],
            ),
            (
                "ellipse_rx_m = { min = 0.01, max = 0.15, steps = 3 }",
                "ellipse_rx_m = { min = 0.01, max = 0.15, steps = 0 }",
                &["grid.ellipse_rx_m.steps", "allowed 1 or more"],
            ),
            (
                "ellipse_rx_m = { min = 0.01, max = 0.15, steps = 3 }",
                "ellipse_rx_m = { min = 0.01, max = 0.2, steps = 3 }",
                &["grid.ellipse_rx_m.max", "[0.01, 0.15]"],
            ),
            (
                "body_height_m = [0.31]",
                "body_height_m = [0.45]",
                &["grid.body_height_m", "legs reach [0.220, 0.400]"],
            ),
            (
                "gaits = [\"walk\", \"trot\"]",
                "gaits = [\"gallop\"]",
                &["grid.gaits[0]", "gallop", "trot, walk, free"],
            ),
            (
                "gaits = [\"walk\", \"trot\"]",
                "gaits = []",
                &["grid.gaits", "empty list"],
            ),
            (
                "duration_s = 3",
                "duration_s = 0.1",
                &["grid.duration_s", "[1, 3600]"],
            ),
            ("seeds = [1, 0]", "seeds = [-1]", &["grid.seeds[0]", "-1"]),
            (
                "ellipse_ry_m = [0.05]",
                "ellipse_ry_m = [0.05, 0.0500000001]",
                &["grid.ellipse_ry_m", "twice"],
            ),
        ];
        for (from, to, needles) in cases {
            assert!(GOOD.contains(from), "{from}");
            let msg = error_of(&GOOD.replace(from, to));
            assert!(msg.starts_with("test.toml: "), "{msg}");
            for n in needles {
                assert!(msg.contains(n), "'{n}' not in: {msg}");
            }
        }
    }

    #[test]
    fn shape_errors_name_the_key() {
        let msg = error_of(&GOOD.replace("seeds = [1, 0]", "seeds = [0]\nspeed = 1"));
        assert!(msg.contains("speed"), "{msg}");
        let msg = error_of(&GOOD.replace("seeds = [1, 0]\n", ""));
        assert!(msg.contains("seeds"), "{msg}");
        let msg = error_of(&GOOD.replace("steps = 4", "steps = 4, step = 1"));
        assert!(
            msg.contains("step") && msg.contains("swing_time_s"),
            "{msg}"
        );
        let msg = error_of(&GOOD.replace("steps = 4", "steps = 2.5"));
        assert!(msg.contains("swing_time_s"), "{msg}");
        let msg = error_of(&format!(
            "{GOOD}\n[selection]\nmanipulability_weight = -1\n"
        ));
        assert!(msg.contains("selection.manipulability_weight"), "{msg}");
        let msg = error_of(&format!("{GOOD}\n[selection]\nmax_vel_rmse_mps = 0\n"));
        assert!(msg.contains("selection.max_vel_rmse_mps"), "{msg}");
        for bad in ["0", "-0.1", "10.5", "nan", "inf"] {
            let msg = error_of(&format!(
                "{GOOD}\n[selection]\nmax_speed_error_ratio = {bad}\n"
            ));
            assert!(
                msg.contains("selection.max_speed_error_ratio")
                    && msg.contains("(0, 10]")
                    && msg.to_lowercase().contains(bad),
                "{msg}"
            );
        }
        let msg = error_of(&format!("{GOOD}\n[selection]\ninterpolation = \"cubic\"\n"));
        assert!(msg.contains("interpolation"), "{msg}");
        let msg = error_of(&GOOD.replace("steps = 4", "steps = 100000"));
        assert!(
            msg.contains("grid") && msg.contains("more than the"),
            "{msg}"
        );
    }

    #[test]
    fn selection_overrides_are_read() {
        let c = parse(&format!(
            "{GOOD}\n[selection]\nmax_vel_rmse_mps = inf\nmanipulability_weight = 0\ninterpolation = \"linear\"\n"
        ))
        .unwrap();
        assert_eq!(c.selection.max_vel_rmse_mps, f64::INFINITY);
        assert_eq!(c.selection.manipulability_weight, 0.0);
        assert_eq!(c.selection.interpolation, Interpolation::Linear);
        assert_eq!(c.selection.max_speed_error_ratio, 0.5, "the default");
        assert_eq!(parse(&c.to_toml()).unwrap(), c);
        let c = parse(&format!(
            "{GOOD}\n[selection]\nmax_speed_error_ratio = 10\n"
        ))
        .unwrap();
        assert_eq!(c.selection.max_speed_error_ratio, 10.0);
        assert!(c.to_toml().contains("max_speed_error_ratio = 10.0"));
    }

    #[test]
    fn a_stored_sweep_toml_without_the_speed_error_ratio_gets_the_default() {
        // What `eemp sweep` stored before the key existed.
        let old = format!(
            "{GOOD}\n[selection]\nmax_vel_rmse_mps = 0.25\nmanipulability_weight = 0.01\n\
             interpolation = \"nearest\"\n"
        );
        assert_eq!(parse(&old).unwrap().selection, SelectionConfig::default());
    }

    #[test]
    fn a_huge_grid_is_rejected_without_overflow() {
        // 3 × 95001 × 100001 × 50001 × 31001 × 140001 × 140001 × 2 runs: far beyond u64.
        let huge = r#"
[grid]
gaits = ["trot", "walk", "free"]
speed_mps = { min = 0.05, max = 1.0, steps = 95001 }
swing_time_s = { min = 0.10, max = 0.25, steps = 100001 }
step_height_m = { min = 0.05, max = 0.15, steps = 50001 }
body_height_m = { min = 0.28, max = 0.311, steps = 31001 }
ellipse_rx_m = { min = 0.01, max = 0.15, steps = 140001 }
ellipse_ry_m = { min = 0.01, max = 0.15, steps = 140001 }
duration_s = 3
seeds = [0, 1]
"#;
        let msg = error_of(huge);
        assert!(
            msg.starts_with("test.toml: grid: ")
                && msg.contains("3 × 95001 × 100001")
                && msg.contains("e30 runs")
                && msg.contains("more than the 1000000"),
            "{msg}"
        );
        // Just over the limit without overflow: 1000 × 1001 runs.
        let over = GOOD
            .replace(
                "swing_time_s = { min = 0.10, max = 0.25, steps = 4 }",
                "swing_time_s = { min = 0.10, max = 0.25, steps = 1000 }",
            )
            .replace(
                "ellipse_rx_m = { min = 0.01, max = 0.15, steps = 3 }",
                "ellipse_rx_m = { min = 0.01, max = 0.15, steps = 1001 }",
            )
            .replace("gaits = [\"walk\", \"trot\"]", "gaits = [\"walk\"]")
            .replace("speed_mps = [0.5, 0.1]", "speed_mps = [0.5]")
            .replace("seeds = [1, 0]", "seeds = [0]");
        let msg = error_of(&over);
        assert!(
            msg.contains("1 × 1 × 1000 × 1 × 1 × 1001 × 1 × 1 = 1001000 runs"),
            "{msg}"
        );
        let g = Grid {
            seeds: vec![0; 3],
            ..parse(GOOD).unwrap().grid
        };
        assert_eq!(g.checked_run_count(), Some(2 * 2 * 4 * 3 * 3));
        let mut big = g.clone();
        big.speed_mps = vec![0.1; 1 << 20];
        big.swing_time_s = vec![0.1; 1 << 20];
        big.ellipse_rx_m = vec![0.1; 1 << 20];
        big.ellipse_ry_m = vec![0.1; 1 << 20];
        assert_eq!(big.checked_run_count(), None);
        assert_eq!(big.run_count(), usize::MAX);
    }

    #[test]
    fn the_modelling_choices_are_stored_settings_and_checked() {
        let with = |extra: &str| parse(&format!("{GOOD}{extra}\n"));
        let plain = with("").unwrap();
        assert_eq!(plain.grid.joint_damping_nms, None);
        assert!(plain.grid.mpc_weights.is_default());
        let text = plain.to_toml();
        assert!(
            !text.contains("damping") && !text.contains("mpc_weights"),
            "{text}"
        );
        let c = with(
            "joint_damping_nms = [1, 2, 2]\n[grid.mpc_weights]\nvelocity = [10, 10, 5]\nforce = 0.001",
        )
        .unwrap();
        assert_eq!(c.grid.joint_damping_nms, Some([1.0, 2.0, 2.0]));
        assert_eq!(c.grid.mpc_weights.velocity, Some([10.0, 10.0, 5.0]));
        assert_eq!(
            c.grid.mpc_weights.describe(),
            "velocity = [10.0, 10.0, 5.0]; force = 0.001"
        );
        assert_eq!(parse(&c.to_toml()).unwrap(), c, "round trip");
        assert_eq!(c.grid.robot_config().unwrap().leg.damping, [1.0, 2.0, 2.0]);
        assert_eq!(c.grid.differences(&plain.grid).len(), 2);
        let msg = with("joint_damping_nms = [1, -2, 2]")
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("grid.joint_damping_nms[1]") && msg.contains("[0, 10]"),
            "{msg}"
        );
        let msg = with("[grid.mpc_weights]\nforce = nan")
            .unwrap_err()
            .to_string();
        assert!(msg.contains("grid.mpc_weights.force"), "{msg}");
        let msg = with("[grid.mpc_weights]\nspeed = [1, 1, 1]")
            .unwrap_err()
            .to_string();
        assert!(msg.contains("speed"), "{msg}");
    }

    #[test]
    fn the_estimator_is_a_stored_setting_and_checked() {
        let with = |line: &str| parse(&format!("{GOOD}{line}\n"));
        let gt = with("").unwrap();
        assert_eq!(gt.grid.estimator, SweepEstimator::GroundTruth);
        assert!(
            !gt.to_toml().contains("estimator"),
            "the default stores nothing"
        );
        let kf = with("estimator = \"kf\"").unwrap();
        assert_eq!(kf.grid.estimator, SweepEstimator::Kf);
        assert_eq!(parse(&kf.to_toml()).unwrap(), kf);
        assert!(kf
            .grid
            .differences(&gt.grid)
            .iter()
            .any(|d| d.starts_with("estimator")));
        let err = with("estimator = \"oracle\"").unwrap_err().to_string();
        assert!(
            err.contains("grid.estimator")
                && err.contains("oracle")
                && err.contains("ground-truth, kf"),
            "{err}"
        );
    }

    #[test]
    fn progress_factor_is_one_number_or_per_gait_and_checked() {
        let with = |line: &str| parse(&format!("{GOOD}{line}\n"));
        let d = with("").unwrap().grid.progress_factor;
        assert_eq!(d, ProgressFactors::default());
        assert_eq!((d.trot, d.walk, d.free), (0.5, 0.5, 0.5));
        // One number sets the grid's gaits (GOOD has trot and walk); free, not in the grid,
        // keeps the default, so it cannot make two equal sweeps differ.
        let all = with("progress_factor = 1").unwrap().grid;
        let f = all.progress_factor;
        assert_eq!((f.trot, f.walk, f.free), (1.0, 1.0, 0.5));
        assert_eq!(
            with("progress_factor = { trot = 1, walk = 1.0 }")
                .unwrap()
                .grid
                .differences(&all),
            Vec::<String>::new()
        );
        let one = with("progress_factor = { walk = 1.5 }").unwrap().grid;
        assert_eq!(one.progress_factor.get(Gait::Walk), 1.5);
        assert_eq!(one.progress_factor.get(Gait::Trot), 0.5);
        // It is part of the grid: a different factor is a different sweep, and the stored
        // file gives it back.
        assert!(one
            .differences(&with("").unwrap().grid)
            .iter()
            .any(|d| d.starts_with("progress_factor")));
        let stored = with("progress_factor = { walk = 1.5 }").unwrap();
        let text = stored.to_toml();
        assert!(
            text.contains("walk = 1.5") && !text.contains("trot = 0.5"),
            "{text}"
        );
        assert_eq!(parse(&text).unwrap(), stored);
        // The default stores nothing: a folder from before the setting reads the same.
        assert!(!with("").unwrap().to_toml().contains("progress_factor"));
        // A gait outside the grid at the default is harmless.
        assert_eq!(
            with("progress_factor = { walk = 1.5, free = 0.5 }").unwrap(),
            stored
        );
        for (line, needles) in [
            (
                "progress_factor = 2.5",
                vec!["grid.progress_factor", "2.5", "[0, 2]"],
            ),
            (
                "progress_factor = { walk = -1 }",
                vec!["grid.progress_factor.walk", "-1"],
            ),
            (
                "progress_factor = { gallop = 1 }",
                vec!["grid.progress_factor.gallop", "unknown gait"],
            ),
            (
                "progress_factor = \"fast\"",
                vec!["grid.progress_factor", "expected a number"],
            ),
            (
                "progress_factor = { free = 1 }",
                vec!["grid.progress_factor.free", "not in grid.gaits"],
            ),
            (
                "progress_factor = { free = 3 }",
                vec!["grid.progress_factor.free", "[0, 2]"],
            ),
        ] {
            let e = with(line).unwrap_err().to_string();
            for n in needles {
                assert!(e.contains(n), "{line}: '{n}' not in {e}");
            }
        }
    }

    #[test]
    fn grid_differences_are_listed() {
        let a = parse(GOOD).unwrap().grid;
        let mut b = a.clone();
        b.speed_mps.push(1.0);
        b.seeds = vec![0];
        let d = a.differences(&b);
        assert_eq!(d.len(), 2, "{d:?}");
        assert!(d[0].starts_with("speed_mps"));
        assert!(a.differences(&a).is_empty());
    }
}
