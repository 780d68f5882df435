//! Library side of the `eemp` command: plotting helpers shared by its subcommands.
pub mod bench;
pub mod bench_estimator;
pub mod bench_rl;
pub mod hw_cmd;
pub mod output;
pub mod plots;
pub mod retarget_cmd;
pub mod stand_cmd;
pub mod state_source_arg;
pub mod sweep_cmd;
pub mod sweep_report;
pub mod train_cmd;
pub mod walk_cmd;
