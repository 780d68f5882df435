//! `eemp sweep merge`: shard folders of one grid combined into one sweep folder.

use crate::config::SweepConfig;
use crate::error::StudyError;
use crate::grid::RunId;
use crate::store::{
    append_sessions, load_results, load_sessions, load_stored_config, prefer_result, write_atomic,
    FolderLock, ResultRow, COLUMNS, RESULTS_FILE, SESSIONS_FILE, SWEEP_FILE,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What a merge did.
#[derive(Clone, Debug, Default)]
pub struct MergeSummary {
    pub inputs: usize,
    pub rows: usize,
    /// Runs found in more than one input with the same results (kept once).
    pub duplicates: usize,
    /// Rows of failed runs left out because another row of the run (a result, or a later
    /// failure) was found.
    pub superseded_failures: usize,
    /// Runs of the grid that no input holds.
    pub missing: usize,
    /// Inputs whose partial last line was ignored (they are not changed).
    pub partial_lines: Vec<PathBuf>,
}

/// Merges the sweep folders `inputs` into `out`. Every input must hold the same grid (and so
/// must `out`, if it already is a sweep folder: its rows are merged too). A run present in
/// several folders must have the same results there (wall time aside) and is kept once; a
/// failed run's row gives way to a result of that run.
/// `out` gets `sweep.toml` (the first input's), `results.csv` in canonical run order and the
/// sources' `sessions.csv` rows (each once). Inputs are only read.
pub fn merge(inputs: &[PathBuf], out: &Path) -> Result<MergeSummary, StudyError> {
    let Some(first) = inputs.first() else {
        return Err(StudyError::Merge {
            message: "no input folders given".into(),
        });
    };
    let config = stored(first)?;
    let mut sources: Vec<PathBuf> = Vec::new();
    for dir in inputs {
        let c = stored(dir)?;
        let differences = config.grid.differences(&c.grid);
        if !differences.is_empty() {
            return Err(StudyError::GridMismatch {
                path: dir.join(SWEEP_FILE),
                detail: format!(
                    "its grid differs from {}'s ({}); only shards of one sweep can be merged",
                    first.display(),
                    differences.join("; ")
                ),
            });
        }
        if !sources.iter().any(|s| same_dir(s, dir)) {
            sources.push(dir.clone());
        }
    }
    let _lock = FolderLock::acquire(out)?;
    if let Some(c) = load_stored_config(out)? {
        if c.grid != config.grid {
            return Err(StudyError::GridMismatch {
                path: out.join(SWEEP_FILE),
                detail: format!(
                    "the output folder holds another sweep ({}); use a new --out folder",
                    config.grid.differences(&c.grid).join("; ")
                ),
            });
        }
        if !sources.iter().any(|s| same_dir(s, out)) && out.join(RESULTS_FILE).exists() {
            sources.push(out.to_path_buf());
        }
    }

    let order: BTreeMap<RunId, usize> = config
        .grid
        .runs()
        .iter()
        .map(|r| (r.run_id(), r.index))
        .collect();
    let mut merged: BTreeMap<usize, (ResultRow, &Path)> = BTreeMap::new();
    let mut summary = MergeSummary {
        inputs: sources.len(),
        ..Default::default()
    };
    let mut sessions = Vec::new();
    for dir in &sources {
        let path = dir.join(RESULTS_FILE);
        let loaded = load_results(&path)?;
        if loaded.dropped_tail.is_some() {
            summary.partial_lines.push(path.clone());
        }
        summary.duplicates += loaded.duplicates;
        summary.superseded_failures += loaded.superseded_failures;
        for row in loaded.rows {
            let Some(&index) = order.get(&row.run_id) else {
                return Err(StudyError::Results {
                    path: path.clone(),
                    message: format!("run {} is not in the grid", row.run_id),
                });
            };
            match merged.get(&index) {
                Some((kept, _)) if kept.same_result(&row) => summary.duplicates += 1,
                // A failed run's row is no result: a result replaces it (e.g. a shard run again
                // after a failure, merged into an earlier merge's folder).
                Some((kept, _)) if kept.failed() || row.failed() => {
                    summary.superseded_failures += 1;
                    if prefer_result(kept, &row) {
                        merged.insert(index, (row, dir.as_path()));
                    }
                }
                Some((kept, from)) => {
                    return Err(StudyError::Merge {
                        message: format!(
                            "run {} ({}) has different results in {} (cot {:?}, fell {}) and {} \
                             (cot {:?}, fell {}); were they run with different code?",
                            row.run_id,
                            row.spec().canonical(),
                            from.display(),
                            kept.cot,
                            kept.fell,
                            dir.display(),
                            row.cot,
                            row.fell
                        ),
                    })
                }
                None => {
                    merged.insert(index, (row, dir.as_path()));
                }
            }
        }
        for s in load_sessions(dir)? {
            if !sessions.contains(&s) {
                sessions.push(s);
            }
        }
    }
    summary.rows = merged.len();
    summary.missing = order.len() - merged.len();

    let mut text = format!("{}\n", COLUMNS.join(",")).into_bytes();
    for (row, _) in merged.values() {
        text.extend(row.to_line());
    }
    write_atomic(&out.join(SWEEP_FILE), config.to_toml().as_bytes())?;
    write_atomic(&out.join(RESULTS_FILE), &text)?;
    // Rewritten from the sources (the output's own rows included when it is one), so
    // merging again does not count a session twice.
    let sessions_path = out.join(SESSIONS_FILE);
    if sessions_path.exists() {
        std::fs::remove_file(&sessions_path).map_err(|e| StudyError::write(&sessions_path, e))?;
    }
    if !sessions.is_empty() {
        append_sessions(out, &sessions)?;
    }
    Ok(summary)
}

fn stored(dir: &Path) -> Result<SweepConfig, StudyError> {
    load_stored_config(dir)?.ok_or_else(|| StudyError::Read {
        path: dir.join(SWEEP_FILE),
        message: "not found: this is not a sweep folder".into(),
    })
}

fn same_dir(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}
