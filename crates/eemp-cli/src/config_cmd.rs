//! `eemp config show`: the controller settings a walk would run with, every key of the settings
//! tree (`eemp_core::settings`) with its value, unit, range and the layer it came from.
//!
//! Layers, each over the one before: the config structs' defaults, the gait's file
//! (`settings/<gait>.toml`), the robot file's `[control]`, the per-speed table (eq. 6's progress
//! factor), and the run's `--set`.

use eemp_core::gait_settings::gait_file;
use eemp_core::locomotion::ControllerConfig;
use eemp_core::planner::{Gait, PlannerConfig};
use eemp_core::settings::{leaves, ControllerSettings, TABLES};
use eemp_core::settings_keys::doc;
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
    /// A per-speed parameter table in place of the robot's shipped one for the gait.
    #[arg(long)]
    pub params_table: Option<PathBuf>,
    /// A setting, KEY=VALUE, as `eemp walk --set` takes it (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

#[derive(clap::Subcommand, Debug)]
pub enum ConfigCommand {
    /// Print the resolved controller settings of a robot and gait: every key with its value,
    /// unit, range and where the value came from (a TOML file `--set` keys address).
    Show(ConfigShowArgs),
}

pub fn run(cmd: &ConfigCommand) -> Result<(), String> {
    match cmd {
        ConfigCommand::Show(args) => print!("{}", show(args)?),
    }
    Ok(())
}

fn value_at(tree: &toml::Table, table: &str, key: &str) -> Option<toml::Value> {
    tree.get(table)
        .and_then(|t| t.as_table())
        .and_then(|t| leaves(t).into_iter().find(|(k, _)| k == key))
        .map(|(_, v)| v)
}

/// The settings as commented TOML: each key's meaning, unit and range above it, its source
/// (`default`, the gait's file, the robot file's `[control]`, the table, or `--set`) beside it.
pub fn show(args: &ConfigShowArgs) -> Result<String, String> {
    let mut d = WalkDescription {
        robot: args.robot.clone(),
        gait: args.gait.clone(),
        speed_mps: args.speed,
        params_table: args.params_table.clone(),
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
    let (gait_path, gait_tree) = gait_file(&gait.to_string());
    let robot_file = args
        .robot
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_else(|| "robots/a1.toml".into());
    let control = &resolved.robot.control;
    let resolved_tree = settings_of(&resolved.spec).to_tree();
    d.set = args.set.clone();
    let with_sets = settings_of(&d.build()?.spec).to_tree();
    let table = resolved
        .params_table_path
        .as_ref()
        .map(|p| p.display().to_string());
    let mut out = format!(
        "# Controller settings of {} walking {} on {}{}.\n# Layers: default < {gait_path} < \
         {robot_file} [control] < table < --set. Any key: eemp walk --set KEY=VALUE.\n",
        resolved.robot.name,
        gait,
        args.estimator,
        table
            .as_ref()
            .map(|p| format!(", table {p}"))
            .unwrap_or_default()
    );
    for t in TABLES {
        let Some(tree) = with_sets.get(t).and_then(|t| t.as_table()) else {
            continue;
        };
        out.push_str(&format!("\n[{t}]\n"));
        for (key, v) in leaves(tree) {
            let dotted = format!("{t}.{key}");
            if dotted == "planner.gait" {
                continue; // what the run asks for (--gait), not a setting
            }
            let in_gait_file = value_at(gait_tree, t, &key).as_ref() == Some(&v);
            let from_robot = match dotted.as_str() {
                "slip.initial_friction" => control.slip_initial_friction.is_some(),
                "mpc.weight_heat" => control.mpc_weight_heat.is_some(),
                "mpc.f_max_n" => control.mpc_f_max_n.is_some(),
                _ => false,
            };
            let from_table = dotted == "planner.progress_factor"
                && value_at(&plain, t, &key).as_ref() != Some(&v);
            let source = if value_at(&resolved_tree, t, &key).as_ref() != Some(&v) {
                "--set".to_string()
            } else if from_table {
                format!("table {}", table.clone().unwrap_or_default())
            } else if from_robot {
                format!("{robot_file} [control]")
            } else if in_gait_file {
                gait_path.to_string()
            } else {
                "default".to_string()
            };
            if let Some(k) = doc(&dotted) {
                let unit = match k.unit {
                    "" => String::new(),
                    u => format!("{u}, "),
                };
                out.push_str(&format!("# {} ({unit}{})\n", k.what, k.range));
            }
            out.push_str(&format!("{key} = {v}  # {source}\n"));
        }
    }
    Ok(out)
}
