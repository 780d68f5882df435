//! Running a sweep: the runs of the grid (or of one shard) that `results.csv` does not hold yet,
//! in canonical order on a rayon pool, each row appended the moment its run ends.

use crate::config::{Grid, MpcWeights, ProgressFactors, SweepConfig, SweepEstimator};
use crate::error::StudyError;
use crate::grid::{RunSpec, Shard};
use crate::store::{append_sessions, ResultRow, ResultStore, RunOutcome, SessionRow};
use eemp_core::planner::{PlannerConfig, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_sim::closed_loop::StateSource;
use eemp_sim::sensors::SensorNoise;
use eemp_sim::walk::{run_walk, WalkRun, WalkSpec};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::iter::{ParallelBridge, ParallelIterator};
use std::io::IsTerminal;
use std::panic::{self, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock, PoisonError};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// The walking run of one grid point and seed: the A1 from rest, a constant forward command
/// from 0.5 s on, metrics from min(2 s, duration/2) (see `WalkSpec::constant`), eq. (6)'s
/// progress factor of the point's gait from `factors`, on the grid's `estimator` (the Kalman
/// filter's sensor noise seeded by the run's seed), with the grid's MPC weights.
pub fn walk_spec(
    spec: &RunSpec,
    factors: &ProgressFactors,
    estimator: SweepEstimator,
    mpc_weights: &MpcWeights,
    robot: &RobotConfig,
) -> Result<WalkSpec, String> {
    let p = &spec.point;
    let mut walk = WalkSpec::constant(
        PlannerConfig {
            gait: p.gait,
            progress_factor: factors.get(p.gait),
            ..Default::default()
        },
        p.params,
        VelocityCommand {
            vx_mps: p.speed_mps,
            ..Default::default()
        },
        p.duration_s,
    );
    walk.seed = spec.seed;
    if estimator == SweepEstimator::Kf {
        walk.state_source = StateSource::kf(robot, SensorNoise::default(), spec.seed);
    }
    // Settings tuned on the A1 scaled to the robot, as a walk's are (`RobotConfig::settings_scale`);
    // the grid's own values (its parameters, its MPC weights) are the sweep's, not scaled.
    if let Some(scale) = robot.settings_scale() {
        let settings = eemp_core::settings::ControllerSettings {
            planner: walk.planner.clone(),
            controller: walk.controller.clone(),
            filter: walk.state_source.kf_config().cloned(),
        };
        let s = settings.scaled(&scale)?;
        walk.planner = s.planner;
        walk.controller = s.controller;
        if let (Some(kf), Some(mine)) = (s.filter, walk.state_source.kf_config_mut()) {
            *mine = kf;
        }
    }
    mpc_weights.apply(&mut walk.controller.mpc);
    Ok(walk)
}

/// The runner `eemp sweep` uses: each run in MuJoCo, with the grid's progress factors,
/// estimator and MPC weights.
/// Runs on the grid's robot (with its joint damping); a robot file that no longer loads fails
/// every run, saying why.
pub fn simulator(grid: &Grid) -> impl Fn(&RunSpec) -> RunOutcome + Sync {
    let (factors, estimator, weights) = (grid.progress_factor, grid.estimator, grid.mpc_weights);
    let robot = grid.robot_config();
    move |spec| match &robot {
        Ok(robot) => simulate_on(robot, spec, &factors, estimator, &weights),
        Err(e) => RunOutcome::failed(e.clone()),
    }
}

/// Runs one grid point in MuJoCo.
pub fn simulate(
    spec: &RunSpec,
    factors: &ProgressFactors,
    estimator: SweepEstimator,
) -> RunOutcome {
    static A1: OnceLock<RobotConfig> = OnceLock::new();
    let weights = MpcWeights::default();
    simulate_on(
        A1.get_or_init(RobotConfig::a1),
        spec,
        factors,
        estimator,
        &weights,
    )
}

/// Runs one grid point on `robot`.
pub fn simulate_on(
    robot: &RobotConfig,
    spec: &RunSpec,
    factors: &ProgressFactors,
    estimator: SweepEstimator,
    mpc_weights: &MpcWeights,
) -> RunOutcome {
    let walk = match walk_spec(spec, factors, estimator, mpc_weights, robot) {
        Ok(w) => w,
        Err(e) => return RunOutcome::failed(e),
    };
    match run_walk(robot, &walk, |_| {}) {
        Ok(run) => outcome_of(&run, walk.metrics_start_s),
        Err(e) => RunOutcome::failed(e.to_string()),
    }
}

fn outcome_of(run: &WalkRun, metrics_start_s: f64) -> RunOutcome {
    let m = &run.metrics;
    RunOutcome {
        fell: run.stats.fell,
        fell_at_s: run.stats.fell_at_s,
        cot: m.cot,
        cot_j_per_m: m.cot_j_per_m,
        cot_abs_power: m.cot_abs_power,
        cot_electrical: m.cot_electrical,
        manipulability: m.manipulability,
        vel_rmse_mps: m.vel_rmse_mps,
        distance_m: m.distance_m,
        energy_j: m.energy_j,
        all_stance_fraction: m.all_stance_fraction,
        steps_total: run.steps.0.iter().sum::<usize>() as u64,
        steps_per_leg: run.steps.0.map(|n| n as u64),
        mpc_solves: run.stats.mpc_solves as u64,
        mpc_failures: run.stats.mpc_failures as u64,
        sim_time_s: run.stats.sim_time_s,
        metrics_window_s: (run.stats.sim_time_s - metrics_start_s).max(0.0),
        error: None,
    }
}

/// How progress is shown on stderr.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ProgressMode {
    /// A progress bar on a terminal; otherwise (batch jobs, CI) a plain line every 5 % or
    /// minute.
    #[default]
    Auto,
    Hidden,
}

#[derive(Clone, Copy, Debug, Default)]
pub struct SweepOptions {
    /// Worker threads; `None` = every core.
    pub threads: Option<usize>,
    pub shard: Option<Shard>,
    pub progress: ProgressMode,
}

/// What one invocation did.
#[derive(Clone, Debug)]
pub struct SweepSummary {
    pub results: PathBuf,
    /// Runs of the grid (or shard).
    pub total: usize,
    /// Runs found in `results.csv` at the start (not run again).
    pub already_done: usize,
    /// Rows of failed runs found at the start and removed from `results.csv`: those runs were
    /// tried again (they are among `ran`).
    pub dropped_failed: usize,
    /// Runs done by this invocation.
    pub ran: usize,
    pub fell: usize,
    pub failed: usize,
    pub threads: usize,
    pub elapsed_s: f64,
    /// A partial last line cut away at the start: (bytes, reason).
    pub repaired: Option<(u64, String)>,
    pub selection_updated: bool,
}

impl SweepSummary {
    pub fn runs_per_s(&self) -> f64 {
        if self.elapsed_s > 0.0 {
            self.ran as f64 / self.elapsed_s
        } else {
            0.0
        }
    }
}

pub fn default_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Runs what is missing of `config`'s grid (or `options.shard` of it) into the folder `out`
/// with `runner`, appending one row per run. Stops at the first write error; a panicking run is
/// recorded as failed (and tried again by the next call). Safe to kill at any moment and call
/// again.
pub fn run_sweep<R>(
    config: &SweepConfig,
    out: &Path,
    options: &SweepOptions,
    runner: R,
) -> Result<SweepSummary, StudyError>
where
    R: Fn(&RunSpec) -> RunOutcome + Sync,
{
    let threads = options.threads.unwrap_or_else(default_threads);
    if threads == 0 {
        return Err(StudyError::Threads {
            threads,
            message: "--threads must be 1 or more".into(),
        });
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(|i| format!("eemp-sweep-{i}"))
        .build()
        .map_err(|e| StudyError::Threads {
            threads,
            message: e.to_string(),
        })?;
    let runs: Vec<RunSpec> = config
        .grid
        .runs()
        .into_iter()
        .filter(|r| options.shard.is_none_or(|s| s.contains(r.index)))
        .collect();
    let (store, state) = ResultStore::open(out, config, options.shard)?;
    let todo: Vec<&RunSpec> = runs
        .iter()
        .filter(|r| !state.done.contains(&r.run_id()))
        .collect();
    let started_unix_s = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let started = Instant::now();
    let progress = Progress::start(options.progress, runs.len(), runs.len() - todo.len());
    let store = Mutex::new(store);
    let write_error: Mutex<Option<StudyError>> = Mutex::new(None);
    let stop = AtomicBool::new(false);
    let (ran, fell, failed) = (
        AtomicUsize::new(0),
        AtomicUsize::new(0),
        AtomicUsize::new(0),
    );
    pool.install(|| {
        // par_bridge hands the runs out in list order, one at a time per free worker.
        todo.iter().par_bridge().for_each(|spec| {
            if stop.load(Ordering::Relaxed) {
                return;
            }
            let t0 = Instant::now();
            let outcome = panic::catch_unwind(AssertUnwindSafe(|| runner(spec)))
                .unwrap_or_else(|p| RunOutcome::failed(format!("panicked: {}", panic_text(&p))));
            let row = ResultRow::new(spec, &outcome, t0.elapsed().as_secs_f64());
            let mut store = store.lock().unwrap_or_else(PoisonError::into_inner);
            if stop.load(Ordering::Relaxed) {
                return;
            }
            if let Err(e) = store.append(&row) {
                stop.store(true, Ordering::Relaxed);
                write_error
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .get_or_insert(e);
                return;
            }
            drop(store);
            ran.fetch_add(1, Ordering::Relaxed);
            let f =
                fell.fetch_add(usize::from(row.fell), Ordering::Relaxed) + usize::from(row.fell);
            failed.fetch_add(usize::from(row.failed()), Ordering::Relaxed);
            progress.inc(f);
        });
    });
    let elapsed_s = started.elapsed().as_secs_f64();
    progress.finish();
    let store = store.into_inner().unwrap_or_else(PoisonError::into_inner);
    if let Some(e) = write_error
        .into_inner()
        .unwrap_or_else(PoisonError::into_inner)
    {
        return Err(e);
    }
    let summary = SweepSummary {
        results: store.path().to_path_buf(),
        total: runs.len(),
        already_done: runs.len() - todo.len(),
        dropped_failed: state.dropped_failed,
        ran: ran.into_inner(),
        fell: fell.into_inner(),
        failed: failed.into_inner(),
        threads,
        elapsed_s,
        repaired: state.repaired,
        selection_updated: state.selection_updated,
    };
    if summary.ran > 0 {
        append_sessions(
            out,
            &[SessionRow {
                started_unix_s,
                elapsed_s,
                shard: options.shard.map_or("all".into(), |s| s.to_string()),
                threads,
                runs_done: summary.ran,
                runs_fell: summary.fell,
                runs_failed: summary.failed,
            }],
        )?;
    }
    drop(store);
    Ok(summary)
}

fn panic_text(payload: &Box<dyn std::any::Any + Send>) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(no message)".into())
}

/// A progress bar on a terminal, plain lines otherwise, or nothing.
struct Progress {
    bar: Option<ProgressBar>,
    lines: Option<Mutex<LineLog>>,
}

struct LineLog {
    total: usize,
    done: usize,
    start_done: usize,
    started: Instant,
    last: Instant,
    every: usize,
}

impl Progress {
    fn start(mode: ProgressMode, total: usize, done: usize) -> Self {
        let quiet = Progress {
            bar: None,
            lines: None,
        };
        if mode == ProgressMode::Hidden || done == total {
            return quiet;
        }
        if std::io::stderr().is_terminal() {
            let bar = ProgressBar::with_draw_target(
                Some(total as u64),
                ProgressDrawTarget::stderr_with_hz(4),
            );
            bar.set_style(
                ProgressStyle::with_template(
                    "{elapsed_precise} [{wide_bar}] {pos}/{len} runs  {per_sec}  ETA {eta}  {msg}",
                )
                .expect("valid template")
                .progress_chars("=> "),
            );
            bar.set_position(done as u64);
            bar.reset_eta();
            bar.set_message("0 fell");
            bar.enable_steady_tick(Duration::from_millis(500));
            return Progress {
                bar: Some(bar),
                lines: None,
            };
        }
        let now = Instant::now();
        Progress {
            bar: None,
            lines: Some(Mutex::new(LineLog {
                total,
                done,
                start_done: done,
                started: now,
                last: now,
                every: (total / 20).max(1),
            })),
        }
    }

    /// One more run done; `fell` runs of this session fell so far.
    fn inc(&self, fell: usize) {
        if let Some(bar) = &self.bar {
            bar.set_message(format!("{fell} fell"));
            bar.inc(1);
        }
        if let Some(lines) = &self.lines {
            let mut l = lines.lock().unwrap_or_else(PoisonError::into_inner);
            l.done += 1;
            let now = Instant::now();
            if l.done % l.every == 0 || l.done == l.total || now - l.last > Duration::from_secs(60)
            {
                l.last = now;
                let rate = (l.done - l.start_done) as f64 / (now - l.started).as_secs_f64();
                let eta = (l.total - l.done) as f64 / rate.max(1e-9);
                eprintln!(
                    "sweep: {}/{} runs, {rate:.2} runs/s, ETA {:.0} s, {fell} fell",
                    l.done, l.total, eta
                );
            }
        }
    }

    fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::GridPoint;
    use eemp_core::planner::{Gait, PlannerParams};

    #[test]
    fn each_run_gets_the_progress_factor_of_its_gait() {
        let factors = ProgressFactors {
            walk: 1.5,
            ..Default::default()
        };
        let spec = |gait| RunSpec {
            index: 0,
            point: GridPoint {
                gait,
                speed_mps: 0.3,
                params: PlannerParams::default(),
                duration_s: 20.0,
            },
            seed: 7,
        };
        let robot = RobotConfig::a1();
        let gt = SweepEstimator::GroundTruth;
        let w = MpcWeights::default();
        let walk = walk_spec(&spec(Gait::Walk), &factors, gt, &w, &robot).unwrap();
        assert_eq!(walk.planner.progress_factor, 1.5);
        assert_eq!(walk.planner.gait, Gait::Walk);
        assert_eq!(walk.seed, 7);
        assert_eq!(walk.state_source, StateSource::GroundTruth);
        assert_eq!(
            walk_spec(&spec(Gait::Trot), &factors, gt, &w, &robot)
                .unwrap()
                .planner
                .progress_factor,
            0.5
        );
        // On the filter, the sensor noise is seeded by the run's seed.
        let kf = walk_spec(&spec(Gait::Trot), &factors, SweepEstimator::Kf, &w, &robot).unwrap();
        match kf.state_source {
            StateSource::Kf { seed, .. } => assert_eq!(seed, 7),
            other => panic!("expected the Kalman filter, got {other:?}"),
        }
        assert_eq!(
            kf.controller.mpc,
            eemp_core::convex_mpc::MpcConfig::default()
        );
        // The grid's MPC weights replace only the weights they name.
        let heavy = MpcWeights {
            velocity: Some([10.0, 10.0, 5.0]),
            force: Some(1e-3),
            ..Default::default()
        };
        let mpc = walk_spec(&spec(Gait::Trot), &factors, gt, &heavy, &robot)
            .unwrap()
            .controller
            .mpc;
        let d = eemp_core::convex_mpc::MpcConfig::default();
        assert_eq!(mpc.weight_velocity, [10.0, 10.0, 5.0]);
        assert_eq!(mpc.weight_force, 1e-3);
        assert_eq!(
            (mpc.weight_rpy, mpc.weight_position),
            (d.weight_rpy, d.weight_position)
        );
    }
}
