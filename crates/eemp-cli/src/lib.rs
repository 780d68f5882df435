//! Library side of the `eemp` command: plotting helpers shared by its subcommands.
// summary.json is one serde_json::json! literal of some 60 keys (walk_outputs.rs).
#![recursion_limit = "256"]
pub mod bench;
pub mod bench_estimator;
pub mod bench_rl;
pub mod bench_viewer;
pub mod hw_cmd;
pub mod mpc_arg;
pub mod output;
pub mod paper_report;
pub mod plots;
pub mod replay_cmd;
pub mod reproduce_cmd;
pub mod rerun_arg;
pub mod retarget_cmd;
pub mod robot_arg;
pub mod stand_cmd;
pub mod state_source_arg;
pub mod suite;
pub mod suite_cmd;
pub mod sweep_cmd;
pub mod sweep_report;
pub mod teleop_cmd;
pub mod train_cmd;
pub mod video;
pub mod walk_cmd;
pub mod walk_outputs;
