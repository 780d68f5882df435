//! EEMP-Analytical, the paper's parameter study (Sec. V): a grid of walking runs over gait,
//! speed and the planner's five parameters, run in parallel, resumable after a kill and
//! splittable into shards; then the selection of the best parameters per speed (the lookup
//! table), the best constant parameters (Table II) and the report data.
//!
//! - [`config`]: the sweep file and its validation against Table I;
//! - [`grid`]: the canonical run list, run ids, shards;
//! - [`store`]: the sweep folder (`sweep.toml`, `results.csv`, `sessions.csv`);
//! - [`runner`]: running the missing runs (MuJoCo via `eemp-sim`, or any closure);
//! - [`merge`]: combining shard folders;
//! - [`select`]: seed averages, per-speed choice, best constants, instability;
//! - [`sensitivity`]: the paper's figures that do not reproduce, under other modelling choices;
//! - [`report`]: table files and the Markdown/HTML report (figures come from the caller);
//! - [`pipeline`]: `reproduce.toml`'s stages and the manifests of what made each artifact.

pub mod config;
pub mod error;
pub mod grid;
pub mod merge;
pub mod pipeline;
pub mod report;
pub mod runner;
pub mod select;
pub mod sensitivity;
pub mod store;

pub use config::{Grid, SelectionConfig, SweepConfig};
pub use error::StudyError;
pub use grid::{GridPoint, RunId, RunSpec, Shard};
pub use runner::{run_sweep, simulate, simulator, ProgressMode, SweepOptions, SweepSummary};
pub use select::Study;
pub use store::{ResultRow, RunOutcome};
