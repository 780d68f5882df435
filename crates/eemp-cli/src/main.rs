//! `eemp`: the energy-efficient motion planner on a simulated Unitree A1.

use clap::{Parser, Subcommand};
#[cfg(feature = "hardware")]
use eemp_cli::hw_cmd;
#[cfg(feature = "learning")]
use eemp_cli::train_cmd;
use eemp_cli::{
    config_cmd, replay_cmd, reproduce_cmd, retarget_cmd, stand_cmd, suite_cmd, sweep_cmd,
    teleop_cmd, walk_cmd,
};

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

/// A command this build leaves out (`make demo` builds `--no-default-features`): whatever
/// follows it, to say so instead of clap's "unrecognized subcommand".
#[cfg(not(all(feature = "learning", feature = "hardware")))]
#[derive(clap::Args)]
struct NotBuilt {
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, hide = true)]
    _args: Vec<String>,
}

#[cfg(not(all(feature = "learning", feature = "hardware")))]
fn not_built(command: &str, feature: &str) -> String {
    format!(
        "`eemp {command}` is not in this build: it was built without the `{feature}` feature \
         (`--no-default-features`, as `make demo` builds it); build the whole command with \
         `cargo build --release -p eemp-cli`"
    )
}

#[derive(Subcommand)]
enum Command {
    /// Rise from the ground and follow a body-motion profile on four stance legs.
    Stand(stand_cmd::StandArgs),
    /// Walk under EEMP at a commanded velocity; metrics and figures in --out.
    Walk(Box<walk_cmd::WalkArgs>),
    /// Parameter study (EEMP-Analytical): run a grid of walks (resumable, shardable), merge
    /// shards, report the best parameters per speed.
    Sweep(sweep_cmd::SweepArgs),
    #[cfg(feature = "learning")]
    /// Train a learned controller with PPO (resumable); policy, log and curves in --out.
    Train(train_cmd::TrainArgs),
    #[cfg(not(feature = "learning"))]
    /// (Not in this build: `cargo build --release -p eemp-cli` builds it.)
    Train(NotBuilt),
    /// Retarget a raw dog motion-capture clip to an A1 reference motion (imitation baseline).
    Retarget(retarget_cmd::RetargetArgs),
    #[cfg(feature = "hardware")]
    /// Run a controller on an A1 over its low-level UDP protocol, behind the safety layer.
    Hw(Box<hw_cmd::HwArgs>),
    #[cfg(feature = "hardware")]
    /// A MuJoCo A1 that speaks the A1's low-level protocol on UDP (for `eemp hw`).
    SimRobot(hw_cmd::SimRobotArgs),
    #[cfg(not(feature = "hardware"))]
    /// (Not in this build: `cargo build --release -p eemp-cli` builds it.)
    Hw(NotBuilt),
    #[cfg(not(feature = "hardware"))]
    /// (Not in this build: `cargo build --release -p eemp-cli` builds it.)
    SimRobot(NotBuilt),
    /// Drive EEMP in the simulation from a gamepad, the keyboard or a command script.
    Teleop(teleop_cmd::TeleopArgs),
    /// Render a video of a finished walk from its trace.
    Replay(replay_cmd::ReplayArgs),
    /// The methods against speed (the paper's Fig. 7 and Fig. 9), resumable, with a report.
    Compare(suite_cmd::SuiteArgs),
    /// The methods across terrains, friction, pushes and payloads, resumable, with a report.
    Robustness(suite_cmd::SuiteArgs),
    /// The whole study in order (sweeps, tables, trainings, comparison, robustness, teleop),
    /// each stage resumable and skipped when up to date; --check lists stale artifacts.
    Reproduce(reproduce_cmd::ReproduceArgs),
    /// Benchmarks.
    Bench {
        /// Robot description to time (default: the shipped A1).
        #[arg(long, global = true)]
        robot: Option<std::path::PathBuf>,
        #[command(subcommand)]
        what: BenchCommand,
    },
    /// Robots: `eemp robot check ROBOT` reads one, checks it against MuJoCo, stands and trots it.
    Robot {
        #[command(subcommand)]
        what: eemp_cli::robot_cmd::RobotCommand,
    },
    /// Controller settings: `eemp config show` prints those a walk would run with.
    Config {
        #[command(subcommand)]
        what: config_cmd::ConfigCommand,
    },
    /// Print the MuJoCo model (MJCF) of the robot: generated from a typed robot file, or a bound
    /// model as the simulation compiles it.
    Model {
        /// Robot description (default: the shipped A1, robots/a1.toml).
        #[arg(long)]
        robot: Option<std::path::PathBuf>,
        /// Scenario file (scenarios/*.toml): print the world a walk in it simulates (terrain,
        /// floor friction, payload, model errors) rather than the bare robot on a flat floor.
        #[arg(long)]
        scenario: Option<std::path::PathBuf>,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Time the MPC solve (standing and trotting) against a bare MuJoCo step, in one run.
    Mpc {
        /// Solves per case.
        #[arg(long, default_value_t = 300)]
        solves: usize,
        /// MPC horizon (steps of the MPC's dt).
        #[arg(long, default_value_t = eemp_core::convex_mpc::MpcConfig::default().horizon)]
        horizon: usize,
    },
    /// What the Rerun recorder costs a walk (this build's recorder: Python's rerun-sdk, or the
    /// Rust SDK with `--features rerun`): real-time factor without it, recording to a file, and
    /// streaming to a viewer that never answers.
    Viewer {
        /// Simulated seconds per walk, [1, 600].
        #[arg(long, default_value_t = 10.0)]
        duration: f64,
        /// Interleaved rounds (best of each case).
        #[arg(long, default_value_t = 3)]
        rounds: usize,
    },
    /// Time one Kalman-filter update against a bare MuJoCo step, in one run.
    Estimator {
        #[arg(long, default_value_t = 20000)]
        updates: usize,
    },
    #[cfg(feature = "learning")]
    /// Time the learned-controller pipeline: env stepping (1 thread, all), training, bare MuJoCo.
    Rl {
        /// Environments (as many as the shipped training config).
        #[arg(long, default_value_t = 256)]
        envs: usize,
        /// Policy steps per environment in each stepping measurement.
        #[arg(long, default_value_t = 30)]
        steps: usize,
        /// PPO iterations in the training measurement.
        #[arg(long, default_value_t = 3)]
        train_iterations: usize,
        /// Threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Hidden layer widths of actor and critic, e.g. 128,128.
        #[arg(long, value_delimiter = ',', default_value = "128,128")]
        hidden: Vec<usize>,
    },
    #[cfg(not(feature = "learning"))]
    /// (Not in this build: `cargo build --release -p eemp-cli` builds it.)
    Rl(NotBuilt),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Stand(args) => stand_cmd::run(&args),
        Command::Walk(args) => walk_cmd::run(&args),
        Command::Config { what } => config_cmd::run(&what),
        Command::Robot { what } => eemp_cli::robot_cmd::run(&what),
        Command::Sweep(args) => sweep_cmd::run(&args),
        #[cfg(feature = "learning")]
        Command::Train(args) => train_cmd::run(&args),
        #[cfg(not(feature = "learning"))]
        Command::Train(_) => Err(not_built("train", "learning")),
        #[cfg(not(feature = "hardware"))]
        Command::Hw(_) => Err(not_built("hw", "hardware")),
        #[cfg(not(feature = "hardware"))]
        Command::SimRobot(_) => Err(not_built("sim-robot", "hardware")),
        Command::Retarget(args) => retarget_cmd::run(&args),
        #[cfg(feature = "hardware")]
        Command::Hw(args) => hw_cmd::run_hw_cmd(&args),
        #[cfg(feature = "hardware")]
        Command::SimRobot(args) => hw_cmd::run_sim_robot_cmd(&args),
        Command::Teleop(args) => teleop_cmd::run(&args),
        Command::Replay(args) => replay_cmd::run(&args),
        Command::Reproduce(args) => match reproduce_cmd::run(&args) {
            Ok(true) => Ok(()),
            Ok(false) => std::process::exit(1),
            Err(e) => Err(e),
        },
        Command::Compare(args) => suite_cmd::compare(&args),
        Command::Robustness(args) => suite_cmd::robustness(&args),
        Command::Bench {
            robot,
            what: BenchCommand::Mpc { solves, horizon },
        } => (|| {
            if !(1..=1_000_000).contains(&solves) {
                return Err(format!(
                    "--solves {solves} is out of range: allowed [1, 1000000]"
                ));
            }
            if !(2..=30).contains(&horizon) {
                return Err(format!(
                    "--horizon {horizon} is out of range: allowed [2, 30]"
                ));
            }
            let report = eemp_cli::bench::bench_mpc(&eemp_cli::bench::MpcBenchOptions {
                horizon,
                solves,
                mujoco_steps: 20000,
                robot: eemp_cli::robot_arg::load_robot(robot.as_deref())?,
            });
            println!("{}", report.table());
            println!("{}", report.json_line());
            Ok(())
        })(),
        #[cfg(feature = "learning")]
        Command::Bench {
            robot,
            what:
                BenchCommand::Rl {
                    envs,
                    steps,
                    train_iterations,
                    threads,
                    hidden,
                },
        } => eemp_cli::robot_arg::load_robot(robot.as_deref())
            .and_then(|robot| {
                eemp_cli::bench_rl::bench_rl(&eemp_cli::bench_rl::RlBenchOptions {
                    robot,
                    num_envs: envs,
                    steps,
                    train_iterations,
                    hidden,
                    threads: threads.unwrap_or_else(|| {
                        std::thread::available_parallelism()
                            .map(|n| n.get())
                            .unwrap_or(1)
                    }),
                })
            })
            .map(|r| {
                println!("{}", r.table());
                println!("{}", r.json_line());
            }),
        Command::Bench {
            robot,
            what: BenchCommand::Viewer { duration, rounds },
        } => eemp_cli::robot_arg::load_robot(robot.as_deref())
            .and_then(|robot| eemp_cli::bench_viewer::bench_viewer(duration, rounds, &robot))
            .map(|r| {
                println!("{}", r.table(rounds));
                println!("{}", r.json_line());
            }),
        Command::Bench {
            robot,
            what: BenchCommand::Estimator { updates },
        } => match updates {
            0 => Err("--updates 0 is out of range: allowed [1, ∞)".to_string()),
            n => eemp_cli::robot_arg::load_robot(robot.as_deref())
                .and_then(|robot| eemp_cli::bench_estimator::bench_estimator(n, &robot)),
        }
        .map(|r| {
            println!(
                "Kalman filter update {:.2} µs, bare MuJoCo step {:.2} µs: {:.2} bare steps",
                r.update_us,
                r.mujoco_step_us,
                r.ratio()
            );
            println!("{}", r.json_line());
        }),
        #[cfg(not(feature = "learning"))]
        Command::Bench {
            what: BenchCommand::Rl(_),
            ..
        } => Err(not_built("bench rl", "learning")),
        Command::Model { robot, scenario } => (|| {
            let robot = match robot {
                Some(p) => eemp_sim::robot_model::load_robot(&p).map_err(|e| e.to_string())?,
                None => eemp_core::robot::RobotConfig::a1(),
            };
            let scenario = match scenario {
                Some(p) => eemp_sim::scenario::Scenario::load(&p).map_err(|e| e.to_string())?,
                None => Default::default(),
            };
            let (robot, scene) = scenario.simulated_world(&robot);
            if robot.model.is_none() {
                print!("{}", eemp_sim::mjcf::robot_mjcf(&robot, &scene));
                return Ok(());
            }
            // A bound model: the scene as MuJoCo writes it back (its writer may leave out some
            // default-class values; the simulation compiles the spec itself, not this text).
            let mut spec =
                eemp_sim::backend::bound_scene_spec(&robot, &scene).map_err(|e| e.to_string())?;
            spec.compile().map_err(|e| e.to_string())?;
            print!(
                "<!-- {}: the robot's own model as the simulation compiles it, written back by \
                 MuJoCo (which may drop some default-class values) -->\n{}",
                robot.name,
                spec.save_xml_string(1 << 22).map_err(|e| e.to_string())?
            );
            Ok(())
        })(),
    };
    if let Err(message) = result {
        eprintln!("error: {message}");
        std::process::exit(2);
    }
}

#[cfg(test)]
mod tests {
    /// clap's own checks of the definitions (in a debug build): every id an option names, such
    /// as `--run`'s list of the options a run file replaces, exists.
    #[test]
    fn the_command_line_definition_is_consistent() {
        use clap::CommandFactory;
        super::Cli::command().debug_assert();
    }

    /// Every option of `eemp walk` is either an output or one that `--run FILE` replaces (and
    /// so refuses beside it): a new walk option must join one of the two lists.
    #[test]
    fn every_walk_option_is_an_output_or_replaced_by_a_run_file() {
        use clap::CommandFactory;
        let cli = super::Cli::command();
        let walk = cli.find_subcommand("walk").expect("walk");
        let outputs = [
            "out",
            "video",
            "trace_hz",
            "run",
            "rerun",
            "rerun_connect",
            "rerun_serve",
            "rerun_hz",
            "help",
        ];
        let replaced = eemp_cli::walk_cmd::RUN_FILE_REPLACES;
        for arg in walk.get_arguments() {
            let id = arg.get_id().as_str();
            assert!(
                outputs.contains(&id) || replaced.contains(&id),
                "walk option '{id}' is neither an output nor in RUN_FILE_REPLACES"
            );
        }
    }
}
