//! `eemp walk`: the options of a walk, parsed into the one run description
//! ([`eemp_rl::run::WalkDescription`], which builds and runs it) and the outputs
//! ([`crate::walk_outputs`], which write it).

use eemp_rl::run::WalkDescription;
use std::path::PathBuf;

/// The options a run file replaces (clap's argument ids, the fields' names).
pub const RUN_FILE_REPLACES: [&str; 21] = [
    "controller",
    "policy",
    "estimator",
    "ideal_sensors",
    "seed",
    "gait",
    "speed",
    "lateral",
    "yaw_rate",
    "profile",
    "duration",
    "params",
    "params_table",
    "table_ii",
    "scenario",
    "friction",
    "push_at",
    "push_dv",
    "robot",
    "allow_robot_mismatch",
    "set",
];

#[derive(clap::Args, Debug)]
// `--speed -0.3` is a backward command and `--duration -1` must reach the range check.
#[command(allow_negative_numbers = true)]
pub struct WalkArgs {
    /// Who drives the robot: eemp, or a trained policy (model-free, imitation, eemp-rl; --policy).
    #[arg(long, default_value = "eemp")]
    pub controller: String,
    /// Policy file for a learned --controller (e.g. policies/a1_model_free.safetensors).
    #[arg(long)]
    pub policy: Option<PathBuf>,
    #[command(flatten)]
    pub sensing: crate::state_source_arg::StateSourceArgs,
    /// trot, walk or free (no predetermined order). EEMP only.
    #[arg(long, default_value = "trot")]
    pub gait: String,
    /// Forward speed command, m/s (heading frame). Ignored with --profile.
    #[arg(long, default_value_t = 0.3)]
    pub speed: f64,
    /// Lateral speed command, m/s.
    #[arg(long, default_value_t = 0.0)]
    pub lateral: f64,
    /// Yaw-rate command, rad/s.
    #[arg(long, default_value_t = 0.0)]
    pub yaw_rate: f64,
    /// Velocity profile (TOML `[[segment]]` tables: start_s, vx_mps, vy_mps, yaw_rate_rps) in place of --speed.
    #[arg(long)]
    pub profile: Option<PathBuf>,
    /// Simulated seconds.
    #[arg(long, default_value_t = 20.0)]
    pub duration: f64,
    #[command(flatten)]
    pub params: crate::params_arg::ParamsArgs,
    /// Scenario file (scenarios/*.toml: terrain, friction patches, pushes, payload, model
    /// errors, sensor noise; format: `eemp_sim::scenario`), applied over the rest.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Floor friction coefficient (slippery ground below ~0.4); default: the robot file's.
    #[arg(long)]
    pub friction: Option<f64>,
    #[command(flatten)]
    pub push: crate::push_arg::PushArgs,
    /// A controller setting, KEY=VALUE (repeatable, applied in order over the gait's and the
    /// robot's defaults): dotted keys into the settings tree (planner.*, mpc.*, swing.*, slip.*,
    /// schedule.*, filter.*), e.g. `--set mpc.horizon=12 --set slip.adapt_friction=false`;
    /// `eemp config show --gait G` lists every key with its value, unit and range.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Rows per second in trace.csv (the simulation runs at 1 kHz; every step costs ≈ ¼ of the run).
    #[arg(long, default_value_t = 100.0)]
    pub trace_hz: f64,
    #[command(flatten)]
    pub robot: crate::robot_arg::RobotArgs,
    #[command(flatten)]
    pub rerun: crate::rerun_arg::RerunArgs,
    /// Also write a video of the walk (animated GIF, 25 frames/s, rendered offscreen).
    #[arg(long)]
    pub video: Option<PathBuf>,
    /// A run file (TOML: the fields of `eemp_rl::run::WalkDescription`) in place of the walk's
    /// options; only the outputs (--out, --video, --trace-hz, --rerun…) still apply, and a walk
    /// option given beside it is refused (it would be ignored).
    #[arg(long, value_name = "FILE", conflicts_with_all = RUN_FILE_REPLACES)]
    pub run: Option<PathBuf>,
    /// Output folder.
    #[arg(long, default_value = "out/walk")]
    pub out: PathBuf,
}

impl WalkArgs {
    /// The run these options describe.
    pub fn description(&self) -> WalkDescription {
        WalkDescription {
            robot: self.robot.robot.clone(),
            allow_robot_mismatch: self.robot.allow_robot_mismatch,
            controller: self.controller.clone(),
            policy: self.policy.clone(),
            sensing: self.sensing.sensing(),
            gait: self.gait.clone(),
            speed_mps: self.speed,
            lateral_mps: self.lateral,
            yaw_rate_rps: self.yaw_rate,
            profile: self.profile.clone(),
            duration_s: self.duration,
            params: self.params.params.clone(),
            params_table: self.params.params_table.clone(),
            table_ii: self.params.table_ii,
            scenario: self.scenario.clone(),
            floor_friction: self.friction,
            push_at_s: self.push.push_at,
            push_dv_mps: self.push.push_dv,
            set: self.set.clone(),
        }
    }
}

pub fn run(args: &WalkArgs) -> Result<(), String> {
    let description = match &args.run {
        Some(p) => eemp_core::config_error::load_toml(p).map_err(|e| e.to_string())?,
        None => args.description(),
    };
    crate::walk_outputs::walk(
        &description,
        &crate::walk_outputs::WalkOutputs {
            out: args.out.clone(),
            video: args.video.clone(),
            trace_hz: args.trace_hz,
            rerun: &args.rerun,
        },
    )
}
