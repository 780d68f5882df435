//! `--robot FILE` and `--allow-robot-mismatch`, shared by every command that runs a robot.

use eemp_core::robot::RobotConfig;
use std::path::PathBuf;

#[derive(clap::Args, Clone, Debug, Default)]
pub struct RobotArgs {
    /// Robot description: robots/a1.toml (the default, compiled in), robots/go2.toml,
    /// robots/go1.toml, or your own file.
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Run per-speed tables and policies made for another robot (an experiment: refused
    /// otherwise; said in summary.json).
    #[arg(long)]
    pub allow_robot_mismatch: bool,
}

impl RobotArgs {
    /// The robot file, loaded and validated (the A1 without `--robot`).
    pub fn load(&self) -> Result<RobotConfig, String> {
        load_robot(self.robot.as_deref())
    }
}

/// `path`'s robot, or the shipped A1 (`eemp_sim::robot_model::load_robot_or_a1`).
pub fn load_robot(path: Option<&std::path::Path>) -> Result<RobotConfig, String> {
    eemp_sim::robot_model::load_robot_or_a1(path).map_err(|e| e.to_string())
}

/// What summary.json says about the robot a run used.
pub fn robot_json(robot: &RobotConfig, allow_mismatch: bool) -> serde_json::Value {
    let id = robot.id();
    serde_json::json!({
        "name": id.name,
        "physics_hash": id.physics_hash,
        "allow_robot_mismatch": allow_mismatch,
    })
}
