//! The sweep folder survives a kill: a partial last row is cut away, finished runs are never
//! run again, and nothing is lost or duplicated. A fake runner stands in for the simulator.

mod common;

use common::{config, fake, options, GRID};
use eemp_study::grid::RunId;
use eemp_study::store::{load_results, ResultStore, RESULTS_FILE, SWEEP_FILE};
use eemp_study::{run_sweep, ResultRow, RunOutcome, Shard, StudyError};
use std::collections::BTreeSet;
use std::io::Write;
use std::sync::Mutex;

#[test]
fn resume_after_a_kill_repairs_the_partial_row_and_redoes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let config = config(GRID);
    let runs = config.grid.runs();
    assert_eq!(runs.len(), 48);
    // A sweep killed while writing its 11th row: 10 complete rows, then half a line.
    {
        let (mut store, state) = ResultStore::open(dir.path(), &config, None).unwrap();
        assert!(state.done.is_empty());
        for r in &runs[..10] {
            store.append(&ResultRow::new(r, &fake(r), 0.1)).unwrap();
        }
    }
    let path = dir.path().join(RESULTS_FILE);
    let line = ResultRow::new(&runs[10], &fake(&runs[10]), 0.1).to_line();
    let mut f = std::fs::OpenOptions::new()
        .append(true)
        .open(&path)
        .unwrap();
    f.write_all(&line[..line.len() / 2]).unwrap();
    drop(f);
    assert!(load_results(&path).unwrap().dropped_tail.is_some());

    let calls = Mutex::new(Vec::<RunId>::new());
    let summary = run_sweep(&config, dir.path(), &options(3), |r| {
        calls.lock().unwrap().push(r.run_id());
        fake(r)
    })
    .unwrap();
    assert_eq!(summary.already_done, 10);
    assert_eq!(summary.ran, 38);
    let (cut, reason) = summary.repaired.clone().unwrap();
    assert_eq!(cut as usize, line.len() / 2, "{reason}");

    // Each unfinished run exactly once, no finished one again.
    let calls = calls.into_inner().unwrap();
    let called: BTreeSet<RunId> = calls.iter().copied().collect();
    assert_eq!(called.len(), calls.len(), "a run was run twice");
    let expected: BTreeSet<RunId> = runs[10..].iter().map(|r| r.run_id()).collect();
    assert_eq!(called, expected);

    // Every run once in the file, which ends on a complete line.
    let loaded = load_results(&path).unwrap();
    assert!(loaded.dropped_tail.is_none());
    assert_eq!(loaded.duplicates, 0);
    let ids: BTreeSet<RunId> = loaded.rows.iter().map(|r| r.run_id).collect();
    assert_eq!(ids.len(), 48);
    assert_eq!(ids, runs.iter().map(|r| r.run_id()).collect());
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.ends_with('\n'));
    assert_eq!(text.lines().count(), 49);

    // Once more: nothing left to do, nothing written.
    let again = run_sweep(&config, dir.path(), &options(2), |_| {
        panic!("no run may be repeated")
    })
    .unwrap();
    assert_eq!((again.ran, again.already_done), (0, 48));
    assert_eq!(std::fs::read_to_string(&path).unwrap(), text);
}

#[test]
fn a_kill_inside_the_header_starts_the_file_over() {
    let dir = tempfile::tempdir().unwrap();
    let config = config(GRID);
    std::fs::write(dir.path().join(RESULTS_FILE), "run_id,point_").unwrap();
    let s = run_sweep(&config, dir.path(), &options(2), fake).unwrap();
    assert_eq!(s.ran, 48);
    assert_eq!(
        load_results(&dir.path().join(RESULTS_FILE))
            .unwrap()
            .rows
            .len(),
        48
    );
}

#[test]
fn a_different_grid_in_the_same_folder_is_rejected_and_nothing_changes() {
    let dir = tempfile::tempdir().unwrap();
    run_sweep(&config(GRID), dir.path(), &options(2), fake).unwrap();
    let before = std::fs::read(dir.path().join(RESULTS_FILE)).unwrap();
    let other = config(&GRID.replace("[0.1, 0.3, 0.5]", "[0.1, 0.3, 0.6]"));
    let err = run_sweep(&other, dir.path(), &options(2), |_| panic!("must not run")).unwrap_err();
    assert!(matches!(err, StudyError::GridMismatch { .. }), "{err}");
    let msg = err.to_string();
    assert!(
        msg.contains(SWEEP_FILE) && msg.contains("mismatched grid") && msg.contains("speed_mps"),
        "{msg}"
    );
    assert_eq!(
        std::fs::read(dir.path().join(RESULTS_FILE)).unwrap(),
        before
    );
    // A changed [selection] alone is not another grid: it replaces the stored one.
    let looser = config(&format!("{GRID}\n[selection]\nmax_vel_rmse_mps = 0.5\n"));
    let s = run_sweep(&looser, dir.path(), &options(1), fake).unwrap();
    assert!(s.selection_updated && s.ran == 0);
}

#[test]
fn shards_run_only_their_slice_and_a_folder_keeps_its_shard() {
    let config = config(GRID);
    let dir = tempfile::tempdir().unwrap();
    let shard: Shard = "2/5".parse().unwrap();
    let opts = eemp_study::SweepOptions {
        shard: Some(shard),
        ..options(2)
    };
    let s = run_sweep(&config, dir.path(), &opts, fake).unwrap();
    let expected: BTreeSet<RunId> = config
        .grid
        .runs()
        .iter()
        .filter(|r| r.index % 5 == 1)
        .map(|r| r.run_id())
        .collect();
    assert_eq!(s.total, expected.len());
    let rows = load_results(&dir.path().join(RESULTS_FILE)).unwrap().rows;
    assert_eq!(
        rows.iter().map(|r| r.run_id).collect::<BTreeSet<_>>(),
        expected
    );
    let wrong = eemp_study::SweepOptions {
        shard: Some("3/5".parse().unwrap()),
        ..options(2)
    };
    let err = run_sweep(&config, dir.path(), &wrong, fake)
        .unwrap_err()
        .to_string();
    assert!(err.contains("another shard than 3/5"), "{err}");
}

#[test]
fn a_panicking_run_is_recorded_as_failed_and_the_sweep_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let config = config(GRID);
    let s = run_sweep(&config, dir.path(), &options(2), |r| {
        if r.index == 7 {
            panic!("boom at {}", r.index);
        }
        fake(r)
    })
    .unwrap();
    assert_eq!((s.ran, s.failed), (48, 1));
    let rows = load_results(&dir.path().join(RESULTS_FILE)).unwrap().rows;
    let failed: Vec<&ResultRow> = rows.iter().filter(|r| r.failed()).collect();
    assert_eq!(failed.len(), 1);
    assert!(failed[0].error.contains("boom at 7"), "{}", failed[0].error);
}

#[test]
fn failed_runs_are_dropped_and_tried_again_on_the_next_start() {
    let dir = tempfile::tempdir().unwrap();
    let config = config(GRID);
    let path = dir.path().join(RESULTS_FILE);
    // A broken environment: every third run cannot be done; then a kill mid-row.
    let broken = |r: &eemp_study::RunSpec| {
        if r.index.is_multiple_of(3) {
            RunOutcome::failed(format!("no simulator for #{}", r.index))
        } else {
            fake(r)
        }
    };
    let first = run_sweep(&config, dir.path(), &options(2), broken).unwrap();
    assert_eq!((first.ran, first.failed, first.dropped_failed), (48, 16, 0));
    let half = ResultRow::new(&config.grid.runs()[0], &fake(&config.grid.runs()[0]), 0.1);
    let mut f = std::fs::OpenOptions::new()
        .append(true)
        .open(&path)
        .unwrap();
    f.write_all(&half.to_line()[..20]).unwrap();
    drop(f);

    // Fixed: exactly the failed runs are run again; nothing else is redone.
    let calls = Mutex::new(Vec::<usize>::new());
    let second = run_sweep(&config, dir.path(), &options(2), |r| {
        calls.lock().unwrap().push(r.index);
        fake(r)
    })
    .unwrap();
    assert_eq!(second.dropped_failed, 16);
    assert_eq!(
        (second.already_done, second.ran, second.failed),
        (32, 16, 0)
    );
    assert!(second.repaired.is_some());
    let mut calls = calls.into_inner().unwrap();
    calls.sort_unstable();
    assert_eq!(calls, (0..48).filter(|i| i % 3 == 0).collect::<Vec<_>>());

    // One row per run, none failed, and the file reads back cleanly.
    let loaded = load_results(&path).unwrap();
    assert_eq!(loaded.rows.len(), 48);
    assert_eq!((loaded.duplicates, loaded.superseded_failures), (0, 0));
    assert!(loaded.dropped_tail.is_none());
    assert!(loaded.rows.iter().all(|r| !r.failed()));
    let ids: BTreeSet<RunId> = loaded.rows.iter().map(|r| r.run_id).collect();
    assert_eq!(ids.len(), 48);
    assert!(!dir.path().join("results.tmp").exists());

    // Nothing left to retry.
    let third = run_sweep(&config, dir.path(), &options(1), |_| {
        panic!("nothing to do")
    })
    .unwrap();
    assert_eq!(
        (third.ran, third.dropped_failed, third.already_done),
        (0, 0, 48)
    );
}

#[test]
fn a_second_sweep_into_a_busy_folder_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let config = config(GRID);
    let _held = ResultStore::open(dir.path(), &config, None).unwrap();
    let err = run_sweep(&config, dir.path(), &options(1), fake).unwrap_err();
    assert!(matches!(err, StudyError::Locked { .. }), "{err}");
}
