//! The study report: lookup-table files and a document (Markdown and self-contained HTML) with
//! the grid summary, tables, best constants, improvements and the comparison with the paper.
//! Figures are drawn by the caller (`eemp-cli`) and passed in as PNG bytes.

use crate::config::{Grid, SweepConfig, GAIT_ORDER};
use crate::error::StudyError;
use crate::select::{
    cot_jump_pct_text, cot_saving, most_fell_pct_text, Improvement, Scored, Study, COT_JUMP,
};
use crate::store::{ResultRow, SessionRow};
use eemp_core::planner::params_table::Interpolation;
use eemp_core::planner::{Gait, PlannerParams};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The paper's numbers (Sec. V and the conclusion).
pub mod paper {
    /// CoT improvement of the per-speed parameters over the constant ones, trot, % (Sec. V).
    pub const TROT_IMPROVEMENT_PCT: f64 = 35.5;
    /// The same, as stated in the conclusion, %.
    pub const TROT_IMPROVEMENT_CONCLUSION_PCT: f64 = 34.5;
    pub const WALK_IMPROVEMENT_PCT: f64 = 13.3;
    /// Walk energy as a share of trot energy at speeds up to 0.4 m/s, %.
    pub const WALK_TROT_ENERGY_PCT: f64 = 59.0;
    /// Speed range of that comparison, m/s.
    pub const LOW_SPEED_MAX_MPS: f64 = 0.4;
    /// Walk is unstable above this speed, m/s.
    pub const WALK_UNSTABLE_ABOVE_MPS: f64 = 0.4;
    /// Fig. 5's speeds, m/s (0.01 is below Table I's 0.05; the nearest grid speed stands in).
    pub const FIG5_SPEEDS_MPS: [f64; 4] = [0.01, 0.10, 0.50, 1.00];
}

/// Fig. 5's panels: each paper speed with the nearest grid speed, repeats removed.
pub fn fig5_speeds(grid_speeds: &[f64]) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::new();
    for target in paper::FIG5_SPEEDS_MPS {
        if let Some(v) = crate::select::nearest(grid_speeds, target) {
            if !out.iter().any(|o| o.1 == v) {
                out.push((target, v));
            }
        }
    }
    out
}

/// A PNG figure: `file` is its path relative to the sweep folder.
#[derive(Clone, Debug)]
pub struct Figure {
    pub file: String,
    pub title: String,
    pub caption: String,
    pub png: Vec<u8>,
}

/// One block of the document.
#[derive(Clone, Debug)]
pub enum Block {
    Heading(u8, String),
    /// Text; `code` spans in backticks.
    Paragraph(String),
    Bullets(Vec<String>),
    Table {
        header: Vec<String>,
        rows: Vec<Vec<String>>,
    },
    Figure(Figure),
}

/// A report rendered to Markdown (figures linked) or HTML (figures embedded as data URIs).
#[derive(Clone, Debug)]
pub struct Document {
    pub title: String,
    pub blocks: Vec<Block>,
}

impl Document {
    pub fn to_markdown(&self) -> String {
        let mut s = format!("# {}\n\n", self.title);
        for b in &self.blocks {
            match b {
                Block::Heading(level, text) => {
                    let _ = writeln!(s, "{} {text}\n", "#".repeat(usize::from(*level) + 1));
                }
                Block::Paragraph(text) => {
                    let _ = writeln!(s, "{text}\n");
                }
                Block::Bullets(items) => {
                    for i in items {
                        let _ = writeln!(s, "- {i}");
                    }
                    s.push('\n');
                }
                Block::Table { header, rows } => {
                    let cell = |c: &String| c.replace('|', "\\|");
                    let line = |cells: &[String]| {
                        format!(
                            "| {} |",
                            cells.iter().map(cell).collect::<Vec<_>>().join(" | ")
                        )
                    };
                    let _ = writeln!(s, "{}", line(header));
                    let _ = writeln!(s, "|{}", "---|".repeat(header.len()));
                    for r in rows {
                        let _ = writeln!(s, "{}", line(r));
                    }
                    s.push('\n');
                }
                Block::Figure(f) => {
                    let _ = writeln!(s, "![{}]({})\n\n*{}*\n", f.title, f.file, f.caption);
                }
            }
        }
        s
    }

    pub fn to_html(&self) -> String {
        let mut s =
            String::from("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n");
        let _ = writeln!(s, "<title>{}</title>", escape(&self.title));
        s.push_str(
            "<style>body{font-family:sans-serif;max-width:1250px;margin:2em auto;padding:0 1em;\
             color:#222}table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;\
             padding:3px 8px;text-align:right}th{background:#eee}td:first-child,th:first-child\
             {text-align:left}img{max-width:100%}figcaption{font-style:italic;margin-bottom:2em}\
             code{background:#f3f3f3;padding:0 3px}</style>\n</head>\n<body>\n",
        );
        let _ = writeln!(s, "<h1>{}</h1>", inline(&self.title));
        for b in &self.blocks {
            match b {
                Block::Heading(level, text) => {
                    let _ = writeln!(s, "<h{0}>{1}</h{0}>", level + 1, inline(text));
                }
                Block::Paragraph(text) => {
                    let _ = writeln!(s, "<p>{}</p>", inline(text));
                }
                Block::Bullets(items) => {
                    s.push_str("<ul>\n");
                    for i in items {
                        let _ = writeln!(s, "<li>{}</li>", inline(i));
                    }
                    s.push_str("</ul>\n");
                }
                Block::Table { header, rows } => {
                    s.push_str("<table>\n<tr>");
                    for h in header {
                        let _ = write!(s, "<th>{}</th>", inline(h));
                    }
                    s.push_str("</tr>\n");
                    for r in rows {
                        s.push_str("<tr>");
                        for c in r {
                            let _ = write!(s, "<td>{}</td>", inline(c));
                        }
                        s.push_str("</tr>\n");
                    }
                    s.push_str("</table>\n");
                }
                Block::Figure(f) => {
                    let _ = writeln!(
                        s,
                        "<figure><img alt=\"{}\" src=\"data:image/png;base64,{}\">\
                         <figcaption>{}</figcaption></figure>",
                        escape(&f.title),
                        base64(&f.png),
                        inline(&f.caption)
                    );
                }
            }
        }
        s.push_str("</body>\n</html>\n");
        s
    }
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Escapes text and turns `code` spans into `<code>`.
fn inline(text: &str) -> String {
    escape(text)
        .split('`')
        .enumerate()
        .map(|(i, part)| {
            if i % 2 == 1 {
                format!("<code>{part}</code>")
            } else {
                part.to_string()
            }
        })
        .collect()
}

/// Standard base64 with padding (RFC 4648).
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(char::from(A[(n >> (18 - 6 * i) & 63) as usize]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Where the report puts the tables, relative to the sweep folder.
pub const TABLES_DIR: &str = "tables";

/// The file name of a gait's table: `a1_<gait>.toml`.
pub fn table_file_name(robot: &str, gait: Gait) -> String {
    format!("{robot}_{gait}.toml")
}

/// What [`write_tables`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WrittenTables {
    /// One table per gait with a selectable point: `tables_dir` joined with its file name.
    pub written: Vec<(Gait, PathBuf)>,
    /// Stale tables removed: gaits of the grid that no longer get a table.
    pub removed: Vec<PathBuf>,
}

/// Writes `tables_dir/a1_<gait>.toml` for every gait of `study` with a table (each file
/// through a temporary file and a rename), selected from the sweep folder `sweep_dir` whose
/// grid is `grid` (each table records its gait's progress factor). The table of a gait in the
/// grid that gets no table (no selectable point) is removed, so no stale table survives; other
/// files, and tables of gaits this sweep did not run (another sweep's), are left alone. A table
/// file that was selected with another progress factor is neither replaced nor removed (an
/// error): it belongs to another study (`tables/` holds the paper-factor tables).
pub fn write_tables(
    sweep_dir: &Path,
    tables_dir: &Path,
    study: &Study,
    grid: &Grid,
) -> Result<WrittenTables, StudyError> {
    let grid_gaits = &grid.gaits;
    let sel = &study.selection;
    let robot = grid.robot_config().map_err(|message| StudyError::Results {
        path: sweep_dir.to_path_buf(),
        message,
    })?;
    let table_file_name = |gait: Gait| table_file_name(&robot.name, gait);
    // Refuse before writing anything.
    for &gait in grid_gaits {
        let path = tables_dir.join(table_file_name(gait));
        let Ok(existing) = eemp_core::planner::params_table::ParamsTable::load(&path) else {
            continue; // absent or not a table: nothing to protect
        };
        let theirs = existing
            .progress_factor
            .unwrap_or(eemp_core::planner::PAPER_PROGRESS_FACTOR);
        let ours = grid.progress_factor.get(gait);
        if theirs != ours {
            return Err(StudyError::Results {
                path: path.clone(),
                message: format!(
                    "this {gait} table was selected with progress factor {theirs}, this sweep \
                     ran {gait} with {ours}; write the tables elsewhere (--tables-out) or \
                     remove the file first"
                ),
            });
        }
    }
    let mut out = WrittenTables::default();
    for g in &study.gaits {
        let Some(table) = g.table(sel.interpolation) else {
            continue;
        };
        let table = table
            .and_then(|t| t.with_progress_factor(grid.progress_factor.get(g.gait)))
            .map(|t| eemp_core::planner::params_table::ParamsTable {
                robot: Some(robot.id()),
                objective: sel.objective,
                ..t
            })
            .map_err(|e| StudyError::Results {
                path: sweep_dir.to_path_buf(),
                message: format!("the selected {} table is invalid: {e}", g.gait),
            })?;
        std::fs::create_dir_all(tables_dir).map_err(|e| StudyError::write(tables_dir, e))?;
        let path = tables_dir.join(table_file_name(g.gait));
        let kf_note = if grid.estimator.is_ground_truth() {
            ""
        } else {
            "# Selected from runs on the Kalman filter (sweep estimator = \"kf\").\n"
        };
        let objective_note = match sel.objective {
            crate::config::Objective::Eq8 => String::new(),
            o => {
                let m = crate::sensitivity::CotMeasure::of_objective(o);
                format!(
                    "# cot is the {} CoT (selection.objective = \"{}\"), not eq. (8)'s.\n",
                    m.describe(),
                    m.name()
                )
            }
        };
        let text = format!(
            "# EEMP-Analytical lookup table for the {} gait, selected by `eemp sweep report` from\n\
             # {}: per speed the grid point with the lowest score cot - {} * manipulability among\n\
             # points that stood in every seed, tracked the command within {} m/s (velocity RMSE)\n\
             # and whose mean speed is off the command by at most {} x the command.\n\
             # Use (with the MPC it was selected on): eemp walk --gait {} --params-table {}{}\n\
             {kf_note}{objective_note}{}",
            g.gait,
            sweep_dir.display(),
            sel.manipulability_weight,
            sel.max_vel_rmse_mps,
            sel.max_speed_error_ratio,
            g.gait,
            path.display(),
            grid.mpc_weights
                .as_sets()
                .iter()
                .map(|s| format!(" --set {s}"))
                .collect::<String>(),
            table.to_toml()
        );
        crate::store::write_atomic(&path, text.as_bytes())?;
        out.written.push((g.gait, path));
    }
    for gait in GAIT_ORDER {
        if !grid_gaits.contains(&gait) || out.written.iter().any(|w| w.0 == gait) {
            continue;
        }
        let path = tables_dir.join(table_file_name(gait));
        match std::fs::remove_file(&path) {
            Ok(()) => out.removed.push(path),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(StudyError::write(&path, e)),
        }
    }
    Ok(out)
}

/// Everything the report is made of.
pub struct ReportInput<'a> {
    pub dir: &'a Path,
    pub config: &'a SweepConfig,
    pub rows: &'a [ResultRow],
    pub sessions: &'a [SessionRow],
    pub study: &'a Study,
    /// Written table files, relative to `dir`.
    pub tables: &'a [(Gait, PathBuf)],
    pub figures: Vec<Figure>,
}

fn num(v: f64, digits: usize) -> String {
    if v.is_finite() {
        format!("{v:.digits$}")
    } else {
        "–".into()
    }
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("–".into(), |v| num(v, digits))
}

fn list(values: &[f64]) -> String {
    values
        .iter()
        .map(|v| v.to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

fn params_text(p: &PlannerParams) -> String {
    format!(
        "ΔT {} s, h {} m, X_z {} m, r ({}, {}) m",
        p.swing_time_s, p.step_height_m, p.body_height_m, p.ellipse_rx_m, p.ellipse_ry_m
    )
}

/// Builds the report document.
pub fn build(input: ReportInput) -> Document {
    let ReportInput {
        dir,
        config,
        rows,
        sessions,
        study,
        tables,
        figures,
    } = input;
    let g = &config.grid;
    let sel = &study.selection;
    let mut b = vec![Block::Paragraph(format!(
        "Sweep folder `{}`, grid from its `sweep.toml`, results from `results.csv`. \
         Reproduce: `eemp sweep --config {}/sweep.toml --out {}` then `eemp sweep report {}`.",
        dir.display(),
        dir.display(),
        dir.display(),
        dir.display()
    ))];

    b.push(Block::Heading(1, "Grid".into()));
    let gaits: Vec<String> = g.gaits.iter().map(Gait::to_string).collect();
    let seeds: Vec<String> = g.seeds.iter().map(u64::to_string).collect();
    let mut grid_rows = vec![
        vec!["gaits".into(), gaits.join(", "), gaits.len().to_string()],
        axis_row("speed V_x,des [m/s]", &g.speed_mps),
        axis_row("swing time ΔT [s]", &g.swing_time_s),
        axis_row("step height h_step [m]", &g.step_height_m),
        axis_row("body height X_z [m]", &g.body_height_m),
        axis_row("ellipse r_x [m]", &g.ellipse_rx_m),
        axis_row("ellipse r_y [m]", &g.ellipse_ry_m),
        vec!["duration [s]".into(), g.duration_s.to_string(), "1".into()],
        vec!["seeds".into(), seeds.join(", "), seeds.len().to_string()],
        vec![
            "eq. (6) progress factor (a setting, not an axis)".into(),
            g.gaits
                .iter()
                .map(|&gait| format!("{gait} {}", g.progress_factor.get(gait)))
                .collect::<Vec<_>>()
                .join(", "),
            "1".into(),
        ],
    ];
    if g.estimator == crate::config::SweepEstimator::Kf {
        grid_rows.push(vec![
            "state source (a setting, not an axis)".into(),
            "Kalman filter, default sensor noise seeded by the run's seed".into(),
            "1".into(),
        ]);
    }
    b.push(Block::Table {
        header: vec!["axis".into(), "values".into(), "count".into()],
        rows: grid_rows,
    });

    b.push(Block::Heading(1, "Summary".into()));
    let fell = rows.iter().filter(|r| r.fell).count();
    let failed = rows.iter().filter(|r| r.failed()).count();
    let run_wall: f64 = rows.iter().map(|r| r.wall_time_s).sum();
    let session_elapsed: f64 = sessions.iter().map(|s| s.elapsed_s).sum();
    let session_runs: usize = sessions.iter().map(|s| s.runs_done).sum();
    let pct = |n: usize, d: usize| {
        if d == 0 {
            "–".into()
        } else {
            format!("{:.1} %", 100.0 * n as f64 / d as f64)
        }
    };
    let mut summary = vec![
        vec!["runs in the grid".into(), g.run_count().to_string()],
        vec![
            "runs with results".into(),
            format!("{} ({})", rows.len(), pct(rows.len(), g.run_count())),
        ],
        vec!["fell".into(), format!("{fell} ({})", pct(fell, rows.len()))],
        vec!["could not run (simulator error)".into(), failed.to_string()],
        vec![
            "wall time of the runs (sum over runs)".into(),
            format!("{} s ({} s per run)", num(run_wall, 0), {
                num(run_wall / rows.len().max(1) as f64, 2)
            }),
        ],
    ];
    if session_elapsed > 0.0 {
        let threads: Vec<String> = {
            let mut t: Vec<usize> = sessions.iter().map(|s| s.threads).collect();
            t.sort_unstable();
            t.dedup();
            t.iter().map(usize::to_string).collect()
        };
        summary.push(vec![
            "sweep wall time (sum over sessions)".into(),
            format!(
                "{} s in {} session(s), {} thread(s)",
                num(session_elapsed, 0),
                sessions.len(),
                threads.join("/")
            ),
        ]);
        summary.push(vec![
            "throughput".into(),
            format!(
                "{} runs/s ({} runs in the recorded sessions)",
                num(session_runs as f64 / session_elapsed, 2),
                session_runs
            ),
        ]);
    }
    b.push(Block::Table {
        header: vec!["quantity".into(), "value".into()],
        rows: summary,
    });
    let mut errors: BTreeMap<&str, usize> = BTreeMap::new();
    for r in rows.iter().filter(|r| r.failed()) {
        *errors.entry(r.error.as_str()).or_default() += 1;
    }
    if !errors.is_empty() {
        b.push(Block::Bullets(
            errors
                .iter()
                .map(|(e, n)| format!("{n} run(s) failed: {e}"))
                .collect(),
        ));
    }

    b.push(Block::Heading(1, "Selection".into()));
    b.push(Block::Paragraph(format!(
        "Per grid point the metrics are averaged over its seeds. A point is excluded if it fell \
         or could not be run (simulator error) in any seed, if it lacks a finite CoT, \
         manipulability, velocity RMSE or mean speed, if its velocity RMSE exceeds {} m/s \
         (`[selection] max_vel_rmse_mps`), or if its mean speed (distance over the metrics \
         window) differs from the commanded speed by more than {} × the commanded speed \
         (`[selection] max_speed_error_ratio`; the RMSE limit alone is absolute and would admit \
         points far off a low command). Score = CoT − {} · manipulability \
         (`[selection] manipulability_weight`): the paper's objective is the lowest CoT, with \
         the force-manipulability measure (eq. 9, higher = more robust) as the robustness term. \
         CoT is the dimensionless E/(m g ΔD) of eq. (8) over the metrics window. The lowest \
         score per gait and speed is the lookup table; lookup between speeds: {}. The last \
         column counts the grid points at each speed and, in brackets, the excluded ones: fell \
         (in some seed), failed (could not be run: no information about the gait), off command \
         (velocity RMSE or mean speed beyond its limit), no metrics.",
        sel.max_vel_rmse_mps,
        sel.max_speed_error_ratio,
        sel.manipulability_weight,
        match sel.interpolation {
            Interpolation::Nearest => "nearest tabulated speed (the paper's discrete look-up)",
            Interpolation::Linear => "linear interpolation",
        }
    )));

    for gs in &study.gaits {
        let file = tables
            .iter()
            .find(|t| t.0 == gs.gait)
            .map_or("no table (no selectable point)".into(), |t| {
                format!("`{}`", t.1.display())
            });
        b.push(Block::Heading(
            2,
            format!("Lookup table: {} — {file}", gs.gait),
        ));
        let header = [
            "speed [m/s]",
            "ΔT [s]",
            "h_step [m]",
            "X_z [m]",
            "r_x [m]",
            "r_y [m]",
            "CoT [-]",
            "CoT [J/m]",
            "manip. [-]",
            "vel. RMSE [m/s]",
            "mean speed [m/s]",
            "score",
            "points (fell / failed / off command / no metrics)",
        ];
        let rows = gs
            .speeds
            .iter()
            .map(|s| {
                let counts = format!(
                    "{} ({} / {} / {} / {})",
                    s.points, s.fell, s.failed, s.off_command, s.no_metrics
                );
                match &s.best {
                    Some(best) => {
                        let p = &best.summary.point.params;
                        vec![
                            s.speed_mps.to_string(),
                            p.swing_time_s.to_string(),
                            p.step_height_m.to_string(),
                            p.body_height_m.to_string(),
                            p.ellipse_rx_m.to_string(),
                            p.ellipse_ry_m.to_string(),
                            opt(best.summary.cot, 3),
                            opt(best.summary.cot_j_per_m, 1),
                            opt(best.summary.manipulability, 2),
                            opt(best.summary.vel_rmse_mps, 3),
                            opt(best.summary.mean_speed_mps, 3),
                            num(best.score, 3),
                            counts,
                        ]
                    }
                    None => {
                        let mut r = vec![s.speed_mps.to_string()];
                        r.extend(std::iter::repeat_n("–".to_string(), 11));
                        r.push(counts);
                        r
                    }
                }
            })
            .collect();
        b.push(Block::Table {
            header: header.iter().map(|h| h.to_string()).collect(),
            rows,
        });
    }

    b.push(Block::Heading(
        1,
        "Best constant parameters (Table II analogue)".into(),
    ));
    b.push(Block::Paragraph(format!(
        "Per gait: the parameter combination, ignoring speed, that is selectable (stood in every \
         seed, tracked the command) at every speed of the gait's stable range, with the lowest \
         mean score over those speeds. The stable range is the table's speeds below the speed \
         where the gait becomes unstable (see the instability rule below; all table speeds if \
         there is none): a gait is not used where it is unstable, and a lone surviving point \
         there would otherwise dictate the constant for the whole range. {IMPROVEMENT_DEFINITION}"
    )));
    let const_rows = study
        .gaits
        .iter()
        .map(|gs| match &gs.constant {
            Some(c) => vec![
                gs.gait.to_string(),
                c.params.swing_time_s.to_string(),
                c.params.step_height_m.to_string(),
                c.params.body_height_m.to_string(),
                c.params.ellipse_rx_m.to_string(),
                c.params.ellipse_ry_m.to_string(),
                num(c.mean_cot(), 3),
                num(c.mean_score, 3),
                list(&speeds_of(&c.per_speed)),
                opt(gs.improvement.as_ref().map(|i| i.pct), 1) + " %",
            ],
            None => {
                let mut r = vec![gs.gait.to_string()];
                r.extend(std::iter::repeat_n("–".to_string(), 8));
                r.push("no combination is selectable at every table speed".into());
                r
            }
        })
        .collect();
    b.push(Block::Table {
        header: [
            "gait",
            "ΔT [s]",
            "h_step [m]",
            "X_z [m]",
            "r_x [m]",
            "r_y [m]",
            "mean CoT [-]",
            "mean score",
            "speeds [m/s]",
            "CoT improvement of the table",
        ]
        .iter()
        .map(|h| h.to_string())
        .collect(),
        rows: const_rows,
    });
    for gs in &study.gaits {
        let Some(c) = &gs.constant else { continue };
        let rows = c
            .per_speed
            .iter()
            .filter_map(|k| {
                let speed = k.summary.point.speed_mps;
                let t = gs.best_at(speed)?;
                Some(vec![
                    speed.to_string(),
                    num(t.cot(), 3),
                    num(k.cot(), 3),
                    num(100.0 * cot_saving(k.cot(), t.cot()), 1) + " %",
                ])
            })
            .collect();
        b.push(Block::Heading(
            2,
            format!("{}: per-speed table vs best constant", gs.gait),
        ));
        b.push(Block::Table {
            header: vec![
                "speed [m/s]".into(),
                "CoT table [-]".into(),
                "CoT constant [-]".into(),
                "improvement".into(),
            ],
            rows,
        });
    }

    b.push(Block::Heading(1, "Paper vs this project".into()));
    b.push(paper_table(study));
    let default_factor = eemp_core::planner::PAPER_PROGRESS_FACTOR;
    let own_factor: Vec<String> = g
        .gaits
        .iter()
        .filter(|&&gait| g.progress_factor.get(gait) != default_factor)
        .map(|&gait| format!("{gait} {}", g.progress_factor.get(gait)))
        .collect();
    let mut notes = Vec::new();
    if !own_factor.is_empty() {
        notes.push(format!(
            "Eq. (6) progress factor: this sweep ran {} instead of the paper's text ({}); every \
             number of those gaits above, including the Table II row, is with that factor.",
            own_factor.join(", "),
            default_factor
        ));
    }
    b.push(Block::Bullets(notes.into_iter().chain([
        format!(
            "Walk/trot energy: mean over the speeds ≤ {} m/s where both gaits have a selected \
             point of CoT_walk / CoT_trot (best per speed). The robot's mass is the same in both, \
             so this is the ratio of energy per distance travelled.",
            paper::LOW_SPEED_MAX_MPS
        ),
        format!(
            "Instability (walk, and every gait's stable range): the lower of (a) the lowest \
             grid speed v such that no point is selectable at v or at any higher grid speed \
             (speeds where every point failed to run are not counted as unstable; a speed \
             without a selectable point below a selectable one is a gap, not the instability), \
             (b) the lowest speed whose best CoT is more than {COT_JUMP}× (+{}) the best \
             CoT at the previous speed with a selected point (the paper's \"sharp increase in \
             CoT\"), and (c) the lowest speed v such that at v and at every higher grid speed \
             more than {} of the grid points that ran fell (a lone survivor among falling \
             neighbours is luck, not a working gait). The red line in the walk-vs-trot figure \
             marks it.",
            cot_jump_pct_text(),
            most_fell_pct_text()
        ),
        format!(
            "Mean speed: the straight-line distance over the metrics window divided by its \
             length. CoT is energy per distance, so a point that moves faster than commanded \
             looks cheaper; the velocity-RMSE limit ({} m/s) is absolute, so at the lowest \
             speeds it alone would admit points that overshoot the command by tens of percent, \
             hence the relative limit (mean speed within {} × the command of it). Compare the \
             mean speed with the commanded speed in the tables.",
            sel.max_vel_rmse_mps, sel.max_speed_error_ratio
        ),
        "Fig. 5 analogue: the paper's 0.01 m/s panel is outside Table I (speeds 0.05–1.00 m/s); \
         the nearest grid speed is shown instead."
            .into(),
        "The paper's numbers come from its own simulator and controller; the comparison is of \
         trends, not a reproduction to the digit."
            .into(),
    ])
    .collect()));

    if !figures.is_empty() {
        b.push(Block::Heading(1, "Figures".into()));
        b.extend(figures.into_iter().map(Block::Figure));
    }
    Document {
        title: "EEMP-Analytical parameter study".into(),
        blocks: b,
    }
}

/// The one definition of the table's improvement, as the report states it.
pub const IMPROVEMENT_DEFINITION: &str =
    "Improvement of the per-speed table over fixed parameters (the best constant here, the \
     paper's Table II in the comparison below: one definition for both) = mean of \
     (CoT_fixed − CoT_table) / CoT_fixed over the table speeds of the gait's stable range where \
     both the table and the fixed parameters are selectable.";

/// "12.3 %, mean over 0.1, 0.3 m/s".
fn improvement_text(i: &Improvement) -> String {
    format!("{:.1} %, mean over {} m/s", i.pct, list(&i.speeds_mps))
}

fn axis_row(name: &str, values: &[f64]) -> Vec<String> {
    vec![name.into(), list(values), values.len().to_string()]
}

fn speeds_of(points: &[Scored]) -> Vec<f64> {
    points.iter().map(|p| p.summary.point.speed_mps).collect()
}

fn paper_table(study: &Study) -> Block {
    let improvement = |gait: Gait| {
        study.gait(gait).map_or("gait not in the grid".into(), |g| {
            g.improvement
                .as_ref()
                .map_or("– (no best constant)".into(), improvement_text)
        })
    };
    let ratio = study
        .cot_ratio(Gait::Walk, Gait::Trot, paper::LOW_SPEED_MAX_MPS)
        .map_or(
            "– (needs walk and trot results at the same speeds ≤ 0.4 m/s)".into(),
            |(r, speeds)| format!("{:.0} % (speeds {} m/s)", 100.0 * r, list(&speeds)),
        );
    let unstable = study
        .gait(Gait::Walk)
        .map_or("walk not in the grid".into(), |w| {
            w.instability
                .map_or("not found: walk works at every grid speed".into(), |i| {
                    i.to_string()
                })
        });
    let constants = study
        .gaits
        .iter()
        .map(|g| {
            format!(
                "{}: {}",
                g.gait,
                g.constant
                    .as_ref()
                    .map_or("none".into(), |c| params_text(&c.params))
            )
        })
        .collect::<Vec<_>>()
        .join("; ");
    let table_ii = study
        .gaits
        .iter()
        .map(|g| {
            let text = match study.fixed_params(g.gait, &PlannerParams::default()) {
                None => "not on the grid".to_string(),
                Some(f) => format!(
                    "{} (Table II selectable at {} of the grid's {} speeds)",
                    f.improvement(g).map_or(
                        "– (not selectable at any stable-range table speed)".into(),
                        |i| improvement_text(&i)
                    ),
                    f.selectable(),
                    f.per_speed.len()
                ),
            };
            format!("{}: {text}", g.gait)
        })
        .collect::<Vec<_>>()
        .join("; ");
    Block::Table {
        header: vec!["quantity".into(), "paper".into(), "this project".into()],
        rows: vec![
            vec![
                "trot: CoT improvement, per-speed table over best constant (definition above)"
                    .into(),
                format!(
                    "{} % (Sec. V; the conclusion says {} %)",
                    paper::TROT_IMPROVEMENT_PCT,
                    paper::TROT_IMPROVEMENT_CONCLUSION_PCT
                ),
                improvement(Gait::Trot),
            ],
            vec![
                "walk: CoT improvement, per-speed table over best constant (definition above)"
                    .into(),
                format!("{} %", paper::WALK_IMPROVEMENT_PCT),
                improvement(Gait::Walk),
            ],
            vec![
                format!(
                    "walk energy as a share of trot energy, ≤ {} m/s",
                    paper::LOW_SPEED_MAX_MPS
                ),
                format!("{} %", paper::WALK_TROT_ENERGY_PCT),
                ratio,
            ],
            vec![
                "walk becomes unstable".into(),
                format!("above {} m/s", paper::WALK_UNSTABLE_ABOVE_MPS),
                unstable,
            ],
            vec![
                "best constant parameters (Table II)".into(),
                params_text(&PlannerParams::default()) + " (walk and trot)",
                constants,
            ],
            vec![
                "the paper's Table II parameters here: per-speed table's CoT improvement over \
                 them (same definition as above)"
                    .into(),
                "–".into(),
                table_ii,
            ],
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc_4648_vectors() {
        for (input, expected) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(input.as_bytes()), expected);
        }
        assert_eq!(base64(&[0xff, 0xfe, 0x00]), "//4A");
    }

    #[test]
    fn write_tables_removes_a_stale_table_of_a_gait_of_the_grid_only() {
        use crate::config::SelectionConfig;
        use crate::grid::{GridPoint, RunSpec};
        use crate::store::RunOutcome;
        let config = SweepConfig::parse(
            "[grid]\ngaits = [\"trot\", \"walk\"]\nspeed_mps = 0.5\nswing_time_s = 0.25\n\
             step_height_m = 0.1\nbody_height_m = 0.31\nellipse_rx_m = 0.07\n\
             ellipse_ry_m = 0.05\nduration_s = 20\nseeds = [0]\n\
             progress_factor = { trot = 0.75 }\n",
            Path::new("t.toml"),
        )
        .unwrap();
        let row = |gait: Gait, fell: bool| {
            let spec = RunSpec {
                index: 0,
                point: GridPoint {
                    gait,
                    speed_mps: 0.5,
                    params: PlannerParams::default(),
                    duration_s: 20.0,
                },
                seed: 0,
            };
            let outcome = RunOutcome {
                fell,
                cot: Some(0.3),
                manipulability: Some(3.0),
                vel_rmse_mps: Some(0.05),
                distance_m: 9.0,
                metrics_window_s: 18.0,
                ..Default::default()
            };
            ResultRow::new(&spec, &outcome, 1.0)
        };
        // Trot gets a table; every walk point fell; free is not in this grid.
        let study = Study::analyse(
            &[row(Gait::Trot, false), row(Gait::Walk, true)],
            SelectionConfig::default(),
        );
        let dir = std::env::temp_dir().join(format!("eemp-tables-{}", std::process::id()));
        let tables = dir.join("shipped");
        std::fs::create_dir_all(&tables).unwrap();
        for f in ["a1_walk.toml", "a1_free.toml", "notes.txt"] {
            std::fs::write(tables.join(f), "old\n").unwrap();
        }
        let w = write_tables(&dir, &tables, &study, &config.grid).unwrap();
        assert_eq!(w.written, vec![(Gait::Trot, tables.join("a1_trot.toml"))]);
        assert_eq!(w.removed, vec![tables.join("a1_walk.toml")]);
        assert!(!tables.join("a1_walk.toml").exists());
        assert!(tables.join("a1_free.toml").exists() && tables.join("notes.txt").exists());
        let text = std::fs::read_to_string(tables.join("a1_trot.toml")).unwrap();
        assert!(text.contains("--params-table ") && text.contains("0.5 x the command"));
        // The table records the progress factor its gait ran with.
        let t = eemp_core::planner::params_table::ParamsTable::load(&tables.join("a1_trot.toml"))
            .unwrap();
        assert_eq!(t.progress_factor, Some(0.75));
        // Again: nothing more to remove.
        let w = write_tables(&dir, &tables, &study, &config.grid).unwrap();
        assert!(w.removed.is_empty());
        // A sweep that ran trot with another factor does not overwrite this table.
        let mut other = config.grid.clone();
        other.progress_factor.trot = 0.5;
        let before = std::fs::read_to_string(tables.join("a1_trot.toml")).unwrap();
        let e = write_tables(&dir, &tables, &study, &other)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("progress factor 0.75") && e.contains("with 0.5"),
            "{e}"
        );
        assert_eq!(
            std::fs::read_to_string(tables.join("a1_trot.toml")).unwrap(),
            before
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn fig5_speeds_map_to_the_nearest_grid_speed_once() {
        let speeds = [0.05, 0.1, 0.3, 0.5, 0.8, 1.0];
        assert_eq!(
            fig5_speeds(&speeds),
            vec![(0.01, 0.05), (0.1, 0.1), (0.5, 0.5), (1.0, 1.0)]
        );
        assert_eq!(fig5_speeds(&[0.1, 0.3]), vec![(0.01, 0.1), (0.5, 0.3)]);
        assert!(fig5_speeds(&[]).is_empty());
    }

    #[test]
    fn markdown_and_html_render_every_block() {
        let doc = Document {
            title: "T <1>".into(),
            blocks: vec![
                Block::Heading(1, "H".into()),
                Block::Paragraph("see `a|b` & more".into()),
                Block::Bullets(vec!["x".into()]),
                Block::Table {
                    header: vec!["a".into(), "b".into()],
                    rows: vec![vec!["1|2".into(), "3".into()]],
                },
                Block::Figure(Figure {
                    file: "figures/f.png".into(),
                    title: "F".into(),
                    caption: "cap".into(),
                    png: b"foo".to_vec(),
                }),
            ],
        };
        let md = doc.to_markdown();
        assert!(md.contains("## H") && md.contains("| 1\\|2 | 3 |") && md.contains("|---|---|"));
        assert!(md.contains("![F](figures/f.png)"));
        let html = doc.to_html();
        assert!(html.contains("<title>T &lt;1&gt;</title>"));
        assert!(html.contains("<code>a|b</code> &amp; more"));
        assert!(html.contains("src=\"data:image/png;base64,Zm9v\""));
        assert!(html.contains("<td>1|2</td>"));
    }
}
