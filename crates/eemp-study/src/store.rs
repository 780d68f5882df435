//! A sweep folder on disk:
//!
//! - `sweep.toml`: the validated config (canonical text), written on the first start; a later
//!   start with another grid is rejected.
//! - `results.csv`: one row per finished run, appended and flushed as each run ends, in any
//!   order. A kill can only leave a partial last line (each row is one `write`); opening the
//!   store cuts it away, so the run is simply done again. A row with an `error` (the run could
//!   not be done: simulator error, panic) is not a result: opening the store drops such rows
//!   (rewriting the file atomically) so those runs are tried again.
//! - `sessions.csv`: one row per `eemp sweep` invocation that ended (elapsed time, threads), for
//!   the report's throughput.
//! - `.lock`: held (advisory file lock) while a sweep or merge writes the folder.

use crate::config::SweepConfig;
use crate::error::StudyError;
use crate::grid::{GridPoint, RunId, RunSpec, Shard};
use eemp_core::planner::{Gait, PlannerParams};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

pub const SWEEP_FILE: &str = "sweep.toml";
pub const RESULTS_FILE: &str = "results.csv";
pub const SESSIONS_FILE: &str = "sessions.csv";
const LOCK_FILE: &str = ".lock";

/// What one run produced (everything but its identity and wall time).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RunOutcome {
    pub fell: bool,
    pub fell_at_s: Option<f64>,
    /// Dimensionless CoT E/(m g ΔD) over the metrics window (`None` if ΔD ≤ 0).
    pub cot: Option<f64>,
    pub cot_j_per_m: Option<f64>,
    /// CoT of the absolute joint power, Σⱼ|τⱼq̇ⱼ| (`WalkMetrics::cot_abs_power`).
    pub cot_abs_power: Option<f64>,
    /// CoT of the electrical estimate with Joule heat (`WalkMetrics::cot_electrical`).
    pub cot_electrical: Option<f64>,
    /// Mean eq. (9) force manipulability of the stance legs.
    pub manipulability: Option<f64>,
    pub vel_rmse_mps: Option<f64>,
    pub distance_m: f64,
    pub energy_j: f64,
    pub all_stance_fraction: f64,
    pub steps_total: u64,
    /// Swings started per leg, in `Leg::ALL` order (FR, FL, RR, RL).
    pub steps_per_leg: [u64; 4],
    pub mpc_solves: u64,
    pub mpc_failures: u64,
    pub sim_time_s: f64,
    /// Length of the window the metrics are taken over (from the settling time to the end or
    /// the fall), s.
    pub metrics_window_s: f64,
    /// Why the run could not be done (simulator error, panic); `None` for a run that ran,
    /// whether it fell or not.
    pub error: Option<String>,
}

impl RunOutcome {
    pub fn failed(message: impl Into<String>) -> Self {
        RunOutcome {
            error: Some(message.into()),
            ..Default::default()
        }
    }
}

/// One line of `results.csv`. Empty cells are absent values (`None`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ResultRow {
    pub run_id: RunId,
    pub point_id: RunId,
    pub gait: Gait,
    pub speed_mps: f64,
    pub swing_time_s: f64,
    pub step_height_m: f64,
    pub body_height_m: f64,
    pub ellipse_rx_m: f64,
    pub ellipse_ry_m: f64,
    pub duration_s: f64,
    pub seed: u64,
    pub fell: bool,
    pub fell_at_s: Option<f64>,
    pub cot: Option<f64>,
    pub cot_j_per_m: Option<f64>,
    /// The other CoT definitions (`eemp sweep sensitivity`): |τ·q̇| and with Joule heat.
    pub cot_abs_power: Option<f64>,
    pub cot_electrical: Option<f64>,
    pub manipulability: Option<f64>,
    pub vel_rmse_mps: Option<f64>,
    pub distance_m: f64,
    pub energy_j: f64,
    pub all_stance_fraction: f64,
    pub steps_total: u64,
    #[serde(rename = "steps_FR")]
    pub steps_fr: u64,
    #[serde(rename = "steps_FL")]
    pub steps_fl: u64,
    #[serde(rename = "steps_RR")]
    pub steps_rr: u64,
    #[serde(rename = "steps_RL")]
    pub steps_rl: u64,
    pub mpc_solves: u64,
    pub mpc_failures: u64,
    pub sim_time_s: f64,
    pub metrics_window_s: f64,
    /// Wall-clock time of the run, s (the only field that differs between repeats of a run).
    pub wall_time_s: f64,
    /// Empty unless the run could not be done.
    pub error: String,
}

/// The header of `results.csv`, in order.
pub const COLUMNS: [&str; 33] = [
    "run_id",
    "point_id",
    "gait",
    "speed_mps",
    "swing_time_s",
    "step_height_m",
    "body_height_m",
    "ellipse_rx_m",
    "ellipse_ry_m",
    "duration_s",
    "seed",
    "fell",
    "fell_at_s",
    "cot",
    "cot_j_per_m",
    "cot_abs_power",
    "cot_electrical",
    "manipulability",
    "vel_rmse_mps",
    "distance_m",
    "energy_j",
    "all_stance_fraction",
    "steps_total",
    "steps_FR",
    "steps_FL",
    "steps_RR",
    "steps_RL",
    "mpc_solves",
    "mpc_failures",
    "sim_time_s",
    "metrics_window_s",
    "wall_time_s",
    "error",
];

impl ResultRow {
    pub fn new(spec: &RunSpec, outcome: &RunOutcome, wall_time_s: f64) -> Self {
        let p = &spec.point.params;
        ResultRow {
            run_id: spec.run_id(),
            point_id: spec.point.point_id(),
            gait: spec.point.gait,
            speed_mps: spec.point.speed_mps,
            swing_time_s: p.swing_time_s,
            step_height_m: p.step_height_m,
            body_height_m: p.body_height_m,
            ellipse_rx_m: p.ellipse_rx_m,
            ellipse_ry_m: p.ellipse_ry_m,
            duration_s: spec.point.duration_s,
            seed: spec.seed,
            fell: outcome.fell,
            fell_at_s: outcome.fell_at_s,
            cot: outcome.cot,
            cot_j_per_m: outcome.cot_j_per_m,
            cot_abs_power: outcome.cot_abs_power,
            cot_electrical: outcome.cot_electrical,
            manipulability: outcome.manipulability,
            vel_rmse_mps: outcome.vel_rmse_mps,
            distance_m: outcome.distance_m,
            energy_j: outcome.energy_j,
            all_stance_fraction: outcome.all_stance_fraction,
            steps_total: outcome.steps_total,
            steps_fr: outcome.steps_per_leg[0],
            steps_fl: outcome.steps_per_leg[1],
            steps_rr: outcome.steps_per_leg[2],
            steps_rl: outcome.steps_per_leg[3],
            mpc_solves: outcome.mpc_solves,
            mpc_failures: outcome.mpc_failures,
            sim_time_s: outcome.sim_time_s,
            metrics_window_s: outcome.metrics_window_s,
            wall_time_s,
            // One row is one line: no line breaks inside a cell.
            error: outcome
                .error
                .as_deref()
                .unwrap_or("")
                .replace(['\n', '\r'], " "),
        }
    }

    pub fn point(&self) -> GridPoint {
        GridPoint {
            gait: self.gait,
            speed_mps: self.speed_mps,
            params: PlannerParams {
                swing_time_s: self.swing_time_s,
                step_height_m: self.step_height_m,
                body_height_m: self.body_height_m,
                ellipse_rx_m: self.ellipse_rx_m,
                ellipse_ry_m: self.ellipse_ry_m,
            },
            duration_s: self.duration_s,
        }
    }

    /// The run this row claims to be (index unknown: 0).
    pub fn spec(&self) -> RunSpec {
        RunSpec {
            index: 0,
            point: self.point(),
            seed: self.seed,
        }
    }

    /// Mean forward speed over the metrics window, m/s: straight-line distance over the
    /// window's length (`None` when the run fell before the window opened).
    pub fn mean_speed_mps(&self) -> Option<f64> {
        (self.metrics_window_s > 0.0).then(|| self.distance_m / self.metrics_window_s)
    }

    /// The run could not be done (as opposed to: ran and maybe fell).
    pub fn failed(&self) -> bool {
        !self.error.is_empty()
    }

    /// Same run with the same results; only the wall time may differ (a repeat of a
    /// deterministic run on another machine or shard).
    pub fn same_result(&self, other: &ResultRow) -> bool {
        let mut a = self.clone();
        a.wall_time_s = other.wall_time_s;
        // Compared as text, so NaN metrics (a blown-up run) equal themselves.
        a.to_line() == other.to_line()
    }

    /// The CSV line (with its newline).
    pub fn to_line(&self) -> Vec<u8> {
        let mut w = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(Vec::new());
        w.serialize(self).expect("a result row serialises");
        w.into_inner().expect("writing to memory")
    }
}

fn header_line() -> String {
    COLUMNS.join(",")
}

/// What reading a `results.csv` found.
#[derive(Debug, Default)]
pub struct LoadedResults {
    /// Rows in file order (identical repeats of a run kept once).
    pub rows: Vec<ResultRow>,
    /// Bytes of the file that hold the header and complete, valid rows.
    pub valid_len: u64,
    /// The file has no complete header line (missing, empty, or cut inside the header).
    pub needs_header: bool,
    /// A partial or unreadable last line, to be cut away: (bytes, reason).
    pub dropped_tail: Option<(u64, String)>,
    /// Identical repeats of a run that were skipped.
    pub duplicates: usize,
    /// Rows of failed runs (non-empty `error`) replaced by another row of the same run: a
    /// retry's result, or a later failure (the latest failure is kept).
    pub superseded_failures: usize,
}

/// Reads a `results.csv` without changing it. A damaged *last* line (no newline, wrong column
/// count, unparsable) is reported in `dropped_tail`; damage anywhere else, a header from
/// another format, a row whose `run_id` does not match its parameters, or two different results
/// for one run are errors. A failed run's row (see [`ResultRow::failed`]) is not a result: a
/// later row of the same run replaces it, and it never replaces a result
/// ([`prefer_result`]).
pub fn load_results(path: &Path) -> Result<LoadedResults, StudyError> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok(LoadedResults {
                needs_header: true,
                ..Default::default()
            })
        }
        Err(e) => return Err(StudyError::read(path, e)),
    };
    let bad = |message: String| StudyError::Results {
        path: path.to_path_buf(),
        message,
    };
    let Some(header_end) = bytes.iter().position(|&b| b == b'\n') else {
        return Ok(LoadedResults {
            needs_header: true,
            dropped_tail: (!bytes.is_empty())
                .then(|| (bytes.len() as u64, "partial header line".to_string())),
            ..Default::default()
        });
    };
    let header = String::from_utf8_lossy(&bytes[..header_end]);
    if header.trim_end_matches('\r') != header_line() {
        return Err(bad(format!(
            "line 1: unexpected columns '{header}'; expected '{}' (a results file of another \
             format or version?)",
            header_line()
        )));
    }
    let mut out = LoadedResults::default();
    let mut by_id: BTreeMap<RunId, usize> = BTreeMap::new();
    let mut pos = header_end + 1;
    let mut line_no = 1;
    while pos < bytes.len() {
        line_no += 1;
        let Some(n) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            let len = (bytes.len() - pos) as u64;
            out.dropped_tail = Some((len, "partial last line (no newline)".into()));
            break;
        };
        let end = pos + n + 1;
        let is_last = end == bytes.len();
        match parse_row(&bytes[pos..end]) {
            Ok(row) => {
                let expected = row.spec().run_id();
                if row.run_id != expected || row.point_id != row.point().point_id() {
                    return Err(bad(format!(
                        "line {line_no}: run_id {} does not match its parameters (expected {expected})",
                        row.run_id
                    )));
                }
                match by_id.get(&row.run_id) {
                    Some(&i) if out.rows[i].same_result(&row) => out.duplicates += 1,
                    Some(&i) if out.rows[i].failed() || row.failed() => {
                        out.superseded_failures += 1;
                        if prefer_result(&out.rows[i], &row) {
                            out.rows[i] = row;
                        }
                    }
                    Some(&i) => {
                        return Err(bad(format!(
                            "line {line_no}: run {} appears again with different results \
                             (first: cot {:?}, fell {}; now: cot {:?}, fell {})",
                            row.run_id, out.rows[i].cot, out.rows[i].fell, row.cot, row.fell
                        )))
                    }
                    None => {
                        by_id.insert(row.run_id, out.rows.len());
                        out.rows.push(row);
                    }
                }
            }
            Err(reason) if is_last => {
                out.dropped_tail = Some(((end - pos) as u64, format!("bad last line: {reason}")));
                break;
            }
            Err(reason) => return Err(bad(format!("line {line_no}: {reason}"))),
        }
        pos = end;
    }
    out.valid_len = pos as u64;
    if let Some((len, _)) = &out.dropped_tail {
        out.valid_len = bytes.len() as u64 - len;
    }
    Ok(out)
}

/// Of two rows of one run of which at least one failed: whether `new` replaces `kept`. A
/// result (the run ran, fell or not) beats a failure; of two failures the later is kept.
pub fn prefer_result(kept: &ResultRow, new: &ResultRow) -> bool {
    debug_assert!(kept.failed() || new.failed());
    kept.failed()
}

fn parse_row(line: &[u8]) -> Result<ResultRow, String> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(line);
    let record = reader
        .records()
        .next()
        .ok_or("empty line")?
        .map_err(|e| e.to_string())?;
    if record.len() != COLUMNS.len() {
        return Err(format!(
            "{} columns, expected {}",
            record.len(),
            COLUMNS.len()
        ));
    }
    let headers = csv::StringRecord::from(COLUMNS.to_vec());
    record
        .deserialize(Some(&headers))
        .map_err(|e| e.to_string())
}

/// One ended `eemp sweep` (or the sessions of merged shards).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SessionRow {
    /// Seconds since 1970 when the session started.
    pub started_unix_s: u64,
    pub elapsed_s: f64,
    /// `K/N`, or `all`.
    pub shard: String,
    pub threads: usize,
    pub runs_done: usize,
    pub runs_fell: usize,
    pub runs_failed: usize,
}

/// Reads `sessions.csv` (missing = none; unreadable lines are skipped: it is informative only).
pub fn load_sessions(dir: &Path) -> Result<Vec<SessionRow>, StudyError> {
    let path = dir.join(SESSIONS_FILE);
    match File::open(&path) {
        Ok(f) => Ok(csv::Reader::from_reader(f)
            .deserialize()
            .filter_map(Result::ok)
            .collect()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Vec::new()),
        Err(e) => Err(StudyError::read(&path, e)),
    }
}

/// Appends sessions to `sessions.csv`, writing its header first if it is new.
pub fn append_sessions(dir: &Path, sessions: &[SessionRow]) -> Result<(), StudyError> {
    let path = dir.join(SESSIONS_FILE);
    let exists = path.metadata().map(|m| m.len() > 0).unwrap_or(false);
    let file = OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .map_err(|e| StudyError::write(&path, e))?;
    let mut w = csv::WriterBuilder::new()
        .has_headers(!exists)
        .from_writer(file);
    for s in sessions {
        w.serialize(s).map_err(|e| StudyError::write(&path, e))?;
    }
    w.flush().map_err(|e| StudyError::write(&path, e))
}

/// The config stored in a sweep folder.
pub fn load_stored_config(dir: &Path) -> Result<Option<SweepConfig>, StudyError> {
    let path = dir.join(SWEEP_FILE);
    if !path.exists() {
        return Ok(None);
    }
    SweepConfig::load(&path).map(Some)
}

/// Writes `text` to `path` through a temporary file (synced to disk) and a rename, so readers
/// never see half and a crash leaves the old file or the new one.
pub fn write_atomic(path: &Path, text: &[u8]) -> Result<(), StudyError> {
    let tmp = path.with_extension("tmp");
    File::create(&tmp)
        .and_then(|mut f| f.write_all(text).and_then(|()| f.sync_all()))
        .map_err(|e| StudyError::write(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| StudyError::write(path, e))
}

/// The advisory lock on a sweep folder, released when dropped (or when the process dies).
#[derive(Debug)]
pub struct FolderLock {
    _file: File,
}

impl FolderLock {
    /// Creates the folder if needed and takes its lock, or fails at once if it is held.
    pub fn acquire(dir: &Path) -> Result<Self, StudyError> {
        std::fs::create_dir_all(dir).map_err(|e| StudyError::write(dir, e))?;
        let path = dir.join(LOCK_FILE);
        let file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|e| StudyError::write(&path, e))?;
        match file.try_lock() {
            Ok(()) => Ok(FolderLock { _file: file }),
            Err(std::fs::TryLockError::WouldBlock) => Err(StudyError::Locked {
                path: dir.to_path_buf(),
            }),
            Err(std::fs::TryLockError::Error(e)) => Err(StudyError::write(&path, e)),
        }
    }
}

/// What opening a sweep folder found.
#[derive(Debug, Default)]
pub struct ResumeState {
    /// Runs already in `results.csv` with a result (rows of failed runs do not count).
    pub done: BTreeSet<RunId>,
    /// Rows of failed runs (non-empty `error`) removed from `results.csv`, so that those runs
    /// are tried again.
    pub dropped_failed: usize,
    /// The partial last line that was cut away: (bytes, reason).
    pub repaired: Option<(u64, String)>,
    /// The stored `[selection]` differed and was replaced by the new one.
    pub selection_updated: bool,
}

/// `results.csv` open for appending, under the folder lock.
#[derive(Debug)]
pub struct ResultStore {
    path: PathBuf,
    file: File,
    _lock: FolderLock,
}

impl ResultStore {
    /// Opens (or creates) the sweep folder `dir` for `config`: takes the lock, checks or writes
    /// `sweep.toml`, loads `results.csv`, cuts away a partial last line and checks every row
    /// belongs to this grid (and `shard`, if given). Rows of failed runs are removed (the file
    /// is rewritten through a temporary file and a rename) and their runs are not `done`, so
    /// a sweep first run in a broken environment is completed by running it again.
    pub fn open(
        dir: &Path,
        config: &SweepConfig,
        shard: Option<Shard>,
    ) -> Result<(Self, ResumeState), StudyError> {
        let lock = FolderLock::acquire(dir)?;
        let mut state = ResumeState::default();
        let sweep_path = dir.join(SWEEP_FILE);
        let stored = load_stored_config(dir)?;
        if let Some(stored) = stored.as_ref().filter(|s| s.grid != config.grid) {
            return Err(StudyError::GridMismatch {
                path: sweep_path,
                detail: format!(
                    "this folder holds another sweep (stored vs new: {}); use a new --out folder",
                    stored.grid.differences(&config.grid).join("; ")
                ),
            });
        }

        let path = dir.join(RESULTS_FILE);
        let loaded = load_results(&path)?;
        let index: BTreeMap<RunId, usize> = config
            .grid
            .runs()
            .iter()
            .map(|r| (r.run_id(), r.index))
            .collect();
        for row in &loaded.rows {
            let Some(&i) = index.get(&row.run_id) else {
                return Err(StudyError::Results {
                    path: path.clone(),
                    message: format!(
                        "run {} ({}) is not in the grid of {}",
                        row.run_id,
                        row.spec().canonical(),
                        sweep_path.display()
                    ),
                });
            };
            if let Some(s) = shard.filter(|s| !s.contains(i)) {
                return Err(StudyError::Results {
                    path: path.clone(),
                    message: format!(
                        "run {} (#{i}) belongs to another shard than {s}: this folder was \
                         written with a different --shard; use one folder per shard",
                        row.run_id
                    ),
                });
            }
            if row.failed() {
                state.dropped_failed += 1;
            } else {
                state.done.insert(row.run_id);
            }
        }

        // Only now, with everything checked, is anything written.
        if stored
            .as_ref()
            .is_none_or(|s| s.selection != config.selection)
        {
            state.selection_updated = stored.is_some();
            write_atomic(&sweep_path, config.to_toml().as_bytes())?;
        }
        if !loaded.needs_header {
            state.repaired = loaded.dropped_tail.clone();
        }
        if state.dropped_failed > 0 || loaded.superseded_failures > 0 {
            // Without the failed rows (and any partial last line); a kill during the rewrite
            // leaves the old file, and the next start does this again.
            let mut text = format!("{}\n", header_line()).into_bytes();
            for row in loaded.rows.iter().filter(|r| !r.failed()) {
                text.extend(row.to_line());
            }
            write_atomic(&path, &text)?;
        } else {
            Self::repair(&path, &loaded)?;
        }
        let file = OpenOptions::new()
            .append(true)
            .open(&path)
            .map_err(|e| StudyError::write(&path, e))?;
        Ok((
            ResultStore {
                path,
                file,
                _lock: lock,
            },
            state,
        ))
    }

    /// Writes the header of a new (or headerless) file, or cuts away a partial last line.
    fn repair(path: &Path, loaded: &LoadedResults) -> Result<(), StudyError> {
        let mut file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .read(true)
            .write(true)
            .open(path)
            .map_err(|e| StudyError::write(path, e))?;
        if loaded.needs_header {
            file.set_len(0).map_err(|e| StudyError::write(path, e))?;
            file.write_all(format!("{}\n", header_line()).as_bytes())
                .map_err(|e| StudyError::write(path, e))?;
        } else if loaded.dropped_tail.is_some() {
            file.set_len(loaded.valid_len)
                .map_err(|e| StudyError::write(path, e))?;
        }
        Ok(())
    }

    /// Appends one row as a single write and flushes it.
    pub fn append(&mut self, row: &ResultRow) -> Result<(), StudyError> {
        self.file
            .write_all(&row.to_line())
            .and_then(|()| self.file.flush())
            .map_err(|e| StudyError::write(&self.path, e))
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::GridPoint;

    pub(crate) fn row(gait: Gait, speed: f64, seed: u64, cot: Option<f64>) -> ResultRow {
        let mut r = failed_row(gait, speed, seed, cot);
        r.error.clear();
        r
    }

    /// A row of a run that could not be done (its error message has a line break).
    fn failed_row(gait: Gait, speed: f64, seed: u64, cot: Option<f64>) -> ResultRow {
        let spec = RunSpec {
            index: 0,
            point: GridPoint {
                gait,
                speed_mps: speed,
                params: PlannerParams::default(),
                duration_s: 3.0,
            },
            seed,
        };
        ResultRow::new(
            &spec,
            &RunOutcome {
                cot,
                manipulability: Some(3.0),
                vel_rmse_mps: Some(0.1),
                error: Some("line\nbreak".into()),
                ..Default::default()
            },
            0.5,
        )
    }

    #[test]
    fn mean_speed_is_distance_over_the_metrics_window() {
        let mut r = row(Gait::Trot, 0.5, 0, Some(0.3));
        // 3 s run: metrics from min(2, 3/2) = 1.5 s.
        (r.metrics_window_s, r.distance_m) = (1.5, 0.75);
        assert_eq!(r.mean_speed_mps(), Some(0.5));
        (r.metrics_window_s, r.distance_m) = (18.0, 9.0);
        assert_eq!(r.mean_speed_mps(), Some(0.5));
        // Fell before the window opened.
        r.metrics_window_s = 0.0;
        assert_eq!(r.mean_speed_mps(), None);
    }

    #[test]
    fn columns_match_the_serialised_header() {
        let mut w = csv::Writer::from_writer(Vec::new());
        w.serialize(row(Gait::Trot, 0.5, 0, Some(0.3))).unwrap();
        let text = String::from_utf8(w.into_inner().unwrap()).unwrap();
        assert_eq!(text.lines().next().unwrap(), header_line());
    }

    #[test]
    fn a_row_is_one_line_and_round_trips() {
        for r in [
            failed_row(Gait::Walk, 0.1, 7, None),
            row(Gait::Trot, 1.0, 0, Some(0.123_456_789_012_345_67)),
        ] {
            let line = r.to_line();
            assert_eq!(line.iter().filter(|&&b| b == b'\n').count(), 1);
            assert_eq!(*line.last().unwrap(), b'\n');
            let back = parse_row(&line).unwrap();
            assert_eq!(back, r);
        }
    }

    #[test]
    fn damaged_middle_line_is_an_error_and_a_damaged_last_line_is_dropped() {
        let dir = std::env::temp_dir().join(format!("eemp-store-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(RESULTS_FILE);
        let mut text = format!("{}\n", header_line()).into_bytes();
        text.extend(row(Gait::Trot, 0.5, 0, Some(0.3)).to_line());
        let good_len = text.len() as u64;
        // A complete line with too few columns, last: dropped.
        let mut last = text.clone();
        last.extend(b"abc,def\n");
        std::fs::write(&path, &last).unwrap();
        let l = load_results(&path).unwrap();
        assert_eq!((l.rows.len(), l.valid_len), (1, good_len));
        assert!(l.dropped_tail.unwrap().1.contains("2 columns"));
        // The same in the middle: an error naming the line.
        let mut middle = last.clone();
        middle.extend(row(Gait::Trot, 0.1, 0, Some(0.3)).to_line());
        std::fs::write(&path, &middle).unwrap();
        let e = load_results(&path).unwrap_err().to_string();
        assert!(e.contains("line 3") && e.contains("columns"), "{e}");
        // A tampered run id.
        let tampered = String::from_utf8(text.clone())
            .unwrap()
            .replace(",0.5,", ",0.6,");
        std::fs::write(&path, tampered).unwrap();
        let e = load_results(&path).unwrap_err().to_string();
        assert!(e.contains("does not match its parameters"), "{e}");
        // Another header.
        std::fs::write(&path, "a,b\n").unwrap();
        let e = load_results(&path).unwrap_err().to_string();
        assert!(e.contains("unexpected columns"), "{e}");
        // Conflicting duplicate vs identical duplicate.
        let mut dup = text.clone();
        let mut again = row(Gait::Trot, 0.5, 0, Some(0.3));
        again.wall_time_s = 9.0;
        dup.extend(again.to_line());
        std::fs::write(&path, &dup).unwrap();
        let l = load_results(&path).unwrap();
        assert_eq!((l.rows.len(), l.duplicates), (1, 1));
        dup.extend(row(Gait::Trot, 0.5, 0, Some(0.4)).to_line());
        std::fs::write(&path, &dup).unwrap();
        let e = load_results(&path).unwrap_err().to_string();
        assert!(e.contains("different results"), "{e}");
        // A failed run's row is replaced by a later row of that run, never the other way.
        let mut retried = text.clone();
        retried.extend(failed_row(Gait::Trot, 0.1, 0, None).to_line());
        retried.extend(row(Gait::Trot, 0.1, 0, Some(0.7)).to_line());
        retried.extend(failed_row(Gait::Trot, 0.1, 0, None).to_line());
        std::fs::write(&path, &retried).unwrap();
        let l = load_results(&path).unwrap();
        assert_eq!((l.rows.len(), l.superseded_failures), (2, 2));
        assert!(!l.rows[1].failed() && l.rows[1].cot == Some(0.7));
        // Cut inside the header.
        std::fs::write(&path, "run_id,poi").unwrap();
        let l = load_results(&path).unwrap();
        assert!(l.needs_header && l.rows.is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
