//! Which parameters EEMP walks on (`eemp walk`): the shipped per-speed table by default,
//! another table, constants, or the paper's Table II.

use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct ParamsArgs {
    /// Constant planner parameters (TOML, the five of Table I). Default for EEMP: the robot's
    /// per-speed table, tables/<robot>_<gait>.toml, as every other command (else Table II).
    #[arg(long)]
    pub params: Option<PathBuf>,
    /// A per-speed parameter table (tables/<robot>_<gait>.toml) in place of the shipped one.
    #[arg(long, conflicts_with = "params")]
    pub params_table: Option<PathBuf>,
    /// Walk on the paper's Table II constants instead of the per-speed table.
    #[arg(long, conflicts_with_all = ["params", "params_table"])]
    pub table_ii: bool,
}
