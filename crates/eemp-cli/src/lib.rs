//! Library side of the `eemp` command: plotting helpers shared by its subcommands.
pub mod plots;
