//! `eemp config show`: the controller settings a walk would run with, every key of the settings
//! tree (`eemp_core::settings`) with its value and where the value came from.

use eemp_core::controller::ControllerConfig;
use eemp_core::planner::{Gait, PlannerConfig};
use eemp_core::settings::{leaves, ControllerSettings, TABLES};
use eemp_rl::run::{settings_of, WalkDescription};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct ConfigShowArgs {
    /// Robot description (default: the shipped A1).
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// trot, walk or free.
    #[arg(long, default_value = "trot")]
    pub gait: String,
    /// ground-truth or kf (the filter's settings are shown on kf).
    #[arg(long, default_value = "kf")]
    pub estimator: String,
    /// The commanded speed, m/s (a table's progress factor and the walk's defaults follow it).
    #[arg(long, default_value_t = 0.3)]
    pub speed: f64,
    /// A setting, KEY=VALUE, as `eemp walk --set` takes it (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

#[derive(clap::Subcommand, Debug)]
pub enum ConfigCommand {
    /// Print the resolved controller settings of a robot and gait, and where each came from.
    Show(ConfigShowArgs),
}

pub fn run(cmd: &ConfigCommand) -> Result<(), String> {
    match cmd {
        ConfigCommand::Show(args) => print!("{}", show(args)?),
    }
    Ok(())
}

/// The settings as commented TOML: `# default` (the structs' own), `# gait/robot/table` (the
/// gait's, the robot file's or the per-speed table's) or `# --set`.
pub fn show(args: &ConfigShowArgs) -> Result<String, String> {
    let mut d = WalkDescription {
        robot: args.robot.clone(),
        gait: args.gait.clone(),
        speed_mps: args.speed,
        duration_s: 1.0,
        ..Default::default()
    };
    d.sensing.estimator = args.estimator.clone();
    let resolved = d.build()?;
    let gait: Gait = args.gait.parse()?;
    let plain = ControllerSettings {
        planner: PlannerConfig {
            gait,
            ..Default::default()
        },
        controller: ControllerConfig::default(),
        filter: resolved
            .spec
            .state_source
            .kf_config()
            .map(|_| Default::default()),
    }
    .to_tree();
    let resolved_tree = settings_of(&resolved.spec).to_tree();
    d.set = args.set.clone();
    let with_sets = settings_of(&d.build()?.spec).to_tree();
    let value_at = |tree: &toml::Table, table: &str, key: &str| {
        tree.get(table)
            .and_then(|t| t.as_table())
            .and_then(|t| leaves(t).into_iter().find(|(k, _)| k == key))
            .map(|(_, v)| v)
    };
    let mut out = format!(
        "# Controller settings of {} walking {} on {}{} (eemp walk --set KEY=VALUE sets any key)\n",
        resolved.robot.name,
        gait,
        args.estimator,
        resolved
            .params_table_path
            .as_ref()
            .map(|p| format!(", table {}", p.display()))
            .unwrap_or_default()
    );
    for table in TABLES {
        let Some(t) = with_sets.get(table).and_then(|t| t.as_table()) else {
            continue;
        };
        out.push_str(&format!("\n[{table}]\n"));
        for (key, v) in leaves(t) {
            let source = if value_at(&resolved_tree, table, &key).as_ref() != Some(&v) {
                "--set"
            } else if value_at(&plain, table, &key).as_ref() != Some(&v) {
                "gait/robot/table"
            } else {
                "default"
            };
            out.push_str(&format!("{key} = {v}  # {source}\n"));
        }
    }
    Ok(out)
}
