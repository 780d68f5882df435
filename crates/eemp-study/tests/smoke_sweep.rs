//! The one test that simulates: `sweeps/smoke.toml` run for real into a temporary folder, then
//! run again, which must find every run done and redo none.

use eemp_core::planner::Gait;
use eemp_study::store::{load_results, RESULTS_FILE};
use eemp_study::{run_sweep, simulator, ProgressMode, Study, SweepConfig, SweepOptions};
use std::path::Path;

#[test]
fn smoke_sweep_runs_for_real_and_a_rerun_redoes_nothing() {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../sweeps/smoke.toml");
    let config = SweepConfig::load(&file).unwrap();
    let n = config.grid.run_count();
    assert!(n <= 8, "the smoke sweep is for CI: {n} runs");
    let dir = tempfile::tempdir().unwrap();
    let options = SweepOptions {
        threads: Some(2),
        shard: None,
        progress: ProgressMode::Hidden,
    };
    let first = run_sweep(&config, dir.path(), &options, simulator(&config.grid)).unwrap();
    println!(
        "smoke: {} runs in {:.2} s ({:.2} runs/s, {} fell)",
        first.ran,
        first.elapsed_s,
        first.runs_per_s(),
        first.fell
    );
    assert_eq!((first.ran, first.failed), (n, 0));
    let path = dir.path().join(RESULTS_FILE);
    let rows = load_results(&path).unwrap().rows;
    assert_eq!(rows.len(), n);
    for r in rows.iter().filter(|r| !r.fell) {
        assert!(r.cot.is_some_and(|c| c.is_finite() && c > 0.0), "{r:?}");
        assert!(r.manipulability.is_some_and(|m| m >= 1.0), "{r:?}");
        assert!(r.distance_m > 0.0 && r.steps_total > 0, "{r:?}");
        assert!(
            (r.sim_time_s - config.grid.duration_s).abs() < 1e-6,
            "{r:?}"
        );
    }
    let study = Study::analyse(&rows, config.selection);
    let trot = study.gait(Gait::Trot).expect("trot results");
    assert!(
        trot.best().count() > 0,
        "trot has a selectable point: {trot:?}"
    );

    let bytes = std::fs::read(&path).unwrap();
    let again = run_sweep(&config, dir.path(), &options, simulator(&config.grid)).unwrap();
    assert_eq!((again.ran, again.already_done), (0, n));
    assert_eq!(load_results(&path).unwrap().rows.len(), n);
    assert_eq!(std::fs::read(&path).unwrap(), bytes, "nothing rewritten");
}
