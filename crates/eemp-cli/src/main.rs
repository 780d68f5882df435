//! `eemp`: the energy-efficient motion planner on a simulated Unitree A1.

use clap::{Parser, Subcommand};
use eemp_cli::{stand_cmd, sweep_cmd, walk_cmd};

#[derive(Parser)]
#[command(
    name = "eemp",
    version,
    about = "Energy-Efficient Motion Planner (EEMP) for the Unitree A1 in MuJoCo"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Rise from the ground and follow a body-motion profile on four stance legs.
    Stand(stand_cmd::StandArgs),
    /// Walk under EEMP at a commanded velocity; metrics and figures in --out.
    Walk(walk_cmd::WalkArgs),
    /// Parameter study (EEMP-Analytical): run a grid of walks (resumable, shardable), merge
    /// shards, report the best parameters per speed.
    Sweep(sweep_cmd::SweepArgs),
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        what: BenchCommand,
    },
    /// Print the MuJoCo model (MJCF) generated from the robot file.
    Model {
        /// Robot description (default: the shipped A1, robots/a1.toml).
        #[arg(long)]
        robot: Option<std::path::PathBuf>,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Time the MPC solve (standing and trotting) against a bare MuJoCo step, in one run.
    Mpc {
        /// Solves per case.
        #[arg(long, default_value_t = 300)]
        solves: usize,
    },
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Stand(args) => stand_cmd::run(&args),
        Command::Walk(args) => walk_cmd::run(&args),
        Command::Sweep(args) => sweep_cmd::run(&args),
        Command::Bench {
            what: BenchCommand::Mpc { solves },
        } => {
            let report = eemp_cli::bench::bench_mpc(&eemp_cli::bench::MpcBenchOptions {
                horizon: 10,
                solves,
                mujoco_steps: 20000,
            });
            println!("{}", report.table());
            println!("{}", report.json_line());
            Ok(())
        }
        Command::Model { robot } => (|| {
            let robot = match robot {
                Some(p) => eemp_core::robot::RobotConfig::load(&p).map_err(|e| e.to_string())?,
                None => eemp_core::robot::RobotConfig::a1(),
            };
            print!(
                "{}",
                eemp_sim::mjcf::robot_mjcf(&robot, &Default::default())
            );
            Ok(())
        })(),
    };
    if let Err(message) = result {
        eprintln!("error: {message}");
        std::process::exit(2);
    }
}
