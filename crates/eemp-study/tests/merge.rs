//! `merge`: shard folders of one grid combine into the same rows as one unsharded sweep.

mod common;

use common::{config, fake, options, GRID};
use eemp_study::merge::merge;
use eemp_study::store::{load_results, load_sessions, COLUMNS, RESULTS_FILE};
use eemp_study::{run_sweep, ResultRow, StudyError, SweepOptions};
use std::path::{Path, PathBuf};

fn rows(dir: &Path) -> Vec<ResultRow> {
    let mut rows = load_results(&dir.join(RESULTS_FILE)).unwrap().rows;
    for r in &mut rows {
        r.wall_time_s = 0.0;
    }
    rows.sort_by_key(|r| r.run_id);
    rows
}

fn shards(root: &Path, n: usize) -> Vec<PathBuf> {
    let config = config(GRID);
    (1..=n)
        .map(|k| {
            let dir = root.join(format!("shard-{k}"));
            let opts = SweepOptions {
                shard: Some(format!("{k}/{n}").parse().unwrap()),
                ..options(2)
            };
            run_sweep(&config, &dir, &opts, fake).unwrap();
            dir
        })
        .collect()
}

#[test]
fn merged_shards_equal_one_full_sweep() {
    let root = tempfile::tempdir().unwrap();
    let dirs = shards(root.path(), 3);
    let out = root.path().join("merged");
    let s = merge(&dirs, &out).unwrap();
    assert_eq!((s.inputs, s.rows, s.duplicates, s.missing), (3, 48, 0, 0));
    let full = root.path().join("full");
    run_sweep(&config(GRID), &full, &options(2), fake).unwrap();
    assert_eq!(rows(&out), rows(&full));
    assert_eq!(load_sessions(&out).unwrap().len(), 3);
    // The merged folder is a complete sweep folder: resuming it runs nothing.
    let again = run_sweep(&config(GRID), &out, &options(1), |_| {
        panic!("nothing to run")
    })
    .unwrap();
    assert_eq!(again.already_done, 48);
    // Merging again into it (itself among the inputs) changes nothing and counts no session twice.
    let mut with_self = dirs.clone();
    with_self.push(out.clone());
    let s = merge(&with_self, &out).unwrap();
    assert_eq!((s.rows, s.duplicates), (48, 48));
    assert_eq!(load_sessions(&out).unwrap().len(), 3);
}

#[test]
fn incomplete_shards_merge_with_the_missing_runs_counted() {
    let root = tempfile::tempdir().unwrap();
    let dirs = shards(root.path(), 4);
    let s = merge(&dirs[..3], &root.path().join("m")).unwrap();
    assert_eq!((s.rows, s.missing), (36, 12));
}

#[test]
fn identical_duplicates_are_kept_once_and_conflicts_are_errors() {
    let root = tempfile::tempdir().unwrap();
    let dirs = shards(root.path(), 2);
    // A copy of shard 1 (as if it ran twice, e.g. on another node): same results.
    let copy = root.path().join("copy");
    std::fs::create_dir_all(&copy).unwrap();
    for f in ["sweep.toml", RESULTS_FILE] {
        std::fs::copy(dirs[0].join(f), copy.join(f)).unwrap();
    }
    let text = std::fs::read_to_string(copy.join(RESULTS_FILE)).unwrap();
    let column = |name: &str| COLUMNS.iter().position(|c| *c == name).unwrap();
    // Only wall times differ.
    let retimed: String = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            let mut cells: Vec<&str> = l.split(',').collect();
            let wall = format!("{}", 9.0 + i as f64);
            if i > 0 {
                cells[column("wall_time_s")] = &wall;
            }
            cells.join(",") + "\n"
        })
        .collect();
    std::fs::write(copy.join(RESULTS_FILE), &retimed).unwrap();
    let inputs = vec![dirs[0].clone(), dirs[1].clone(), copy.clone()];
    let s = merge(&inputs, &root.path().join("m1")).unwrap();
    assert_eq!((s.rows, s.duplicates), (48, 24));

    // Now one run's CoT differs in the copy.
    let mut lines: Vec<String> = retimed.lines().map(String::from).collect();
    let mut cells: Vec<String> = lines[1].split(',').map(String::from).collect();
    cells[column("cot")] = "0.123".into();
    lines[1] = cells.join(",");
    std::fs::write(copy.join(RESULTS_FILE), lines.join("\n") + "\n").unwrap();
    let err = merge(&inputs, &root.path().join("m2")).unwrap_err();
    assert!(matches!(err, StudyError::Merge { .. }), "{err}");
    let msg = err.to_string();
    assert!(
        msg.contains(&cells[0]) && msg.contains("different results") && msg.contains("copy"),
        "{msg}"
    );
    assert!(!root.path().join("m2").join(RESULTS_FILE).exists());
}

#[test]
fn shards_of_different_grids_are_rejected() {
    let root = tempfile::tempdir().unwrap();
    let dirs = shards(root.path(), 2);
    let other = root.path().join("other");
    run_sweep(
        &config(&GRID.replace("seeds = [0, 1]", "seeds = [0]")),
        &other,
        &options(2),
        fake,
    )
    .unwrap();
    let err = merge(&[dirs[0].clone(), other.clone()], &root.path().join("m")).unwrap_err();
    assert!(matches!(err, StudyError::GridMismatch { .. }), "{err}");
    let msg = err.to_string();
    assert!(
        msg.contains("other") && msg.contains("seeds") && msg.contains("mismatched grid"),
        "{msg}"
    );
    assert!(!root.path().join("m").join(RESULTS_FILE).exists());
    let err = merge(&[root.path().join("nothing-here")], &root.path().join("m")).unwrap_err();
    assert!(err.to_string().contains("not a sweep folder"), "{err}");
    assert!(merge(&[], &root.path().join("m")).is_err());
}

#[test]
fn a_retried_shard_replaces_its_failed_rows_in_an_earlier_merge() {
    let root = tempfile::tempdir().unwrap();
    let config = config(GRID);
    let opts = |k: usize| SweepOptions {
        shard: Some(format!("{k}/2").parse().unwrap()),
        ..options(2)
    };
    let (a, b) = (root.path().join("a"), root.path().join("b"));
    run_sweep(&config, &a, &opts(1), fake).unwrap();
    let broken = |r: &eemp_study::RunSpec| {
        if r.index % 4 == 1 {
            eemp_study::RunOutcome::failed("no simulator")
        } else {
            fake(r)
        }
    };
    let first = run_sweep(&config, &b, &opts(2), broken).unwrap();
    assert_eq!(first.failed, 12);
    let out = root.path().join("merged");
    merge(&[a.clone(), b.clone()], &out).unwrap();
    assert_eq!(rows(&out).iter().filter(|r| r.failed()).count(), 12);
    // Shard 2 run again: its failed runs are retried; merging again into the same folder
    // (whose old rows are among the sources) keeps the results.
    let again = run_sweep(&config, &b, &opts(2), fake).unwrap();
    assert_eq!((again.dropped_failed, again.ran), (12, 12));
    let s = merge(&[a, b], &out).unwrap();
    assert_eq!((s.rows, s.superseded_failures, s.missing), (48, 12, 0));
    assert!(rows(&out).iter().all(|r| !r.failed()));
}
