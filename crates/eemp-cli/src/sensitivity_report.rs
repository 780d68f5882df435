//! `eemp sweep sensitivity DIR… --out DIR`: the paper's three analytical figures that do not
//! reproduce (trot and walk gains of the per-speed table, the walk's energy against the trot's)
//! under each modelling choice, from sweep folders that differ only in their simulation
//! settings ([`eemp_study::sensitivity`]).
//!
//! Writes `sensitivity.csv` (one row per folder × CoT definition × constant), `sensitivity.png`
//! and `report.md` / `report.html`.

use crate::plots::{grouped_bars, BarPanel};
use eemp_study::sensitivity::{
    analyse_variant, describe_variant, ConstantChoice, CotMeasure, SensitivityRow,
    PAPER_TROT_GAIN_PCT, PAPER_WALK_GAIN_PCT, PAPER_WALK_OVER_TROT_PCT, WALK_TROT_MAX_SPEED_MPS,
};
use eemp_study::store::{load_results, load_stored_config, RESULTS_FILE};
use eemp_study::SweepConfig;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One sweep folder, read and checked.
struct Variant {
    /// The folder's name (the figure's label).
    short: String,
    config: SweepConfig,
    rows: Vec<SensitivityRow>,
    runs: usize,
}

fn read_variant(dir: &Path) -> Result<Variant, String> {
    let config = load_stored_config(dir)
        .map_err(|e| e.to_string())?
        .ok_or_else(|| format!("{}: no sweep.toml: not a sweep folder", dir.display()))?;
    let loaded = load_results(&dir.join(RESULTS_FILE)).map_err(|e| e.to_string())?;
    let expected = config.grid.run_count();
    if loaded.rows.len() < expected {
        return Err(format!(
            "{}: {} of {} runs have results; finish the sweep first (eemp sweep --config … --out {})",
            dir.display(),
            loaded.rows.len(),
            expected,
            dir.display()
        ));
    }
    let label = describe_variant(&config.grid);
    let robot = config.grid.robot_config()?;
    let idle = eemp_study::sensitivity::IdleCharge::of(&robot);
    let rows = analyse_variant(&label, &loaded.rows, config.selection, idle.as_ref());
    let short = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| dir.display().to_string());
    Ok(Variant {
        short,
        config,
        rows,
        runs: loaded.rows.len(),
    })
}

/// The folders must be the same study but for the simulation choices, so that a difference in
/// a figure is the choice's.
fn check_same_study(variants: &[Variant], dirs: &[PathBuf]) -> Result<(), String> {
    let base = &variants[0].config;
    for (v, dir) in variants.iter().zip(dirs).skip(1) {
        let mut grid = v.config.grid.clone();
        grid.joint_damping_nms = base.grid.joint_damping_nms;
        grid.mpc_weights = base.grid.mpc_weights;
        let diff = base.grid.differences(&grid);
        if !diff.is_empty() || v.config.selection != base.selection {
            return Err(format!(
                "{} is another study than {} (beyond joint damping and MPC weights: {}); \
                 give folders of one grid and selection",
                dir.display(),
                dirs[0].display(),
                if diff.is_empty() {
                    "[selection]".to_string()
                } else {
                    diff.join("; ")
                }
            ));
        }
    }
    Ok(())
}

fn pct(v: Option<f64>) -> String {
    v.map_or("—".into(), |x| format!("{x:.1} %"))
}

fn csv_num(v: Option<f64>) -> String {
    v.map_or(String::new(), |x| format!("{x:.4}"))
}

/// Writes the sensitivity report of `dirs` (sweep folders) into `out`; returns the paths.
pub fn write(dirs: &[PathBuf], out: &Path) -> Result<Vec<String>, String> {
    if dirs.is_empty() {
        return Err("give at least one sweep folder".into());
    }
    let variants = dirs
        .iter()
        .map(|d| read_variant(d))
        .collect::<Result<Vec<_>, _>>()?;
    check_same_study(&variants, dirs)?;
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;

    let mut csv = String::from(
        "folder,variant,cot_measure,constant,trot_gain_pct,walk_gain_pct,walk_over_trot_pct\n",
    );
    for v in &variants {
        for r in &v.rows {
            let _ = writeln!(
                csv,
                "{},\"{}\",{},{},{},{},{}",
                v.short,
                r.variant,
                r.measure.name(),
                r.constant.name(),
                csv_num(r.figures.trot_gain_pct),
                csv_num(r.figures.walk_gain_pct),
                csv_num(r.figures.walk_over_trot_pct)
            );
        }
    }
    let csv_path = out.join("sensitivity.csv");
    std::fs::write(&csv_path, csv).map_err(|e| format!("{}: {e}", csv_path.display()))?;

    // The figure: each figure of the paper per folder, one bar per CoT definition, the
    // paper's value beside them (best constant of the grid).
    let categories: Vec<String> = variants.iter().map(|v| v.short.clone()).collect();
    let mut groups: Vec<String> = CotMeasure::ALL
        .iter()
        .map(|m| format!("CoT: {}", m.describe()))
        .collect();
    groups.push("the paper".into());
    let panel = |title: &str, paper: f64, f: fn(&SensitivityRow) -> Option<f64>| {
        let mut values: Vec<Vec<f64>> = CotMeasure::ALL
            .iter()
            .map(|m| {
                variants
                    .iter()
                    .map(|v| {
                        v.rows
                            .iter()
                            .find(|r| r.measure == *m && r.constant == ConstantChoice::BestOfGrid)
                            .and_then(f)
                            .unwrap_or(f64::NAN)
                    })
                    .collect()
            })
            .collect();
        values.push(vec![paper; variants.len()]);
        BarPanel {
            title: title.into(),
            y_label: "%".into(),
            values,
        }
    };
    let png = out.join("sensitivity.png");
    grouped_bars(
        &png,
        "The paper's analytical figures under other modelling choices (best constant of the grid)",
        &categories,
        &groups,
        &[
            panel(
                "Trot: CoT saved by the per-speed table over the best constant",
                PAPER_TROT_GAIN_PCT,
                |r| r.figures.trot_gain_pct,
            ),
            panel(
                "Walk: CoT saved by the per-speed table over the best constant",
                PAPER_WALK_GAIN_PCT,
                |r| r.figures.walk_gain_pct,
            ),
            panel(
                "Walk CoT as a share of the trot's at ≤ 0.4 m/s",
                PAPER_WALK_OVER_TROT_PCT,
                |r| r.figures.walk_over_trot_pct,
            ),
        ],
    )
    .map_err(|e| e.to_string())?;

    let md = markdown(&variants, dirs);
    let md_path = out.join("report.md");
    std::fs::write(&md_path, &md).map_err(|e| format!("{}: {e}", md_path.display()))?;
    let html_path = out.join("report.html");
    std::fs::write(
        &html_path,
        crate::suite_cmd::html_of(&md, "Sensitivity of the paper's analytical figures"),
    )
    .map_err(|e| format!("{}: {e}", html_path.display()))?;
    Ok([csv_path, png, md_path, html_path]
        .iter()
        .map(|p| p.display().to_string())
        .collect())
}

fn markdown(variants: &[Variant], dirs: &[PathBuf]) -> String {
    let g = &variants[0].config.grid;
    let mut md = String::new();
    let _ = writeln!(md, "# Why three of the paper's figures do not reproduce\n");
    let _ = writeln!(
        md,
        "The paper's per-speed tuning saves {PAPER_TROT_GAIN_PCT} % of the trot's CoT and \
         {PAPER_WALK_GAIN_PCT} % of the walk's against constant parameters, and its walk spends \
         {PAPER_WALK_OVER_TROT_PCT} % of the trot's energy at ≤ {WALK_TROT_MAX_SPEED_MPS} m/s. \
         Each row below computes the same three figures with the parameter study's own code, \
         under one modelling choice: a simulation choice (a sweep folder: joint damping, MPC \
         weights), the CoT definition, and the constant the table is compared with. \
         Every folder runs the same grid: gaits {:?}, speeds {:?} m/s, ΔT {:?} s, h_step {:?} m, \
         X_z {:?} m, r_x {:?} m, r_y {:?} m, {} s per run, seeds {:?} ({} runs per folder).\n",
        g.gaits.iter().map(|x| x.to_string()).collect::<Vec<_>>(),
        g.speed_mps,
        g.swing_time_s,
        g.step_height_m,
        g.body_height_m,
        g.ellipse_rx_m,
        g.ellipse_ry_m,
        g.duration_s,
        g.seeds,
        variants[0].runs,
    );
    let _ = writeln!(
        md,
        "Regenerate: `eemp sweep --config FILE --out DIR` for each folder, then \
         `eemp sweep sensitivity {} --out DIR` (`eemp reproduce --stage sensitivity`).\n",
        dirs.iter()
            .map(|d| d.display().to_string())
            .collect::<Vec<_>>()
            .join(" ")
    );
    let _ = writeln!(md, "![sensitivity](sensitivity.png)\n");
    let _ = writeln!(
        md,
        "| folder | simulation | CoT definition | constant | trot gain | walk gain | walk / trot |"
    );
    let _ = writeln!(md, "|---|---|---|---|---|---|---|");
    let _ = writeln!(
        md,
        "| paper | | | Table II | {PAPER_TROT_GAIN_PCT} % | {PAPER_WALK_GAIN_PCT} % | {PAPER_WALK_OVER_TROT_PCT} % |"
    );
    for v in variants {
        for r in &v.rows {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {} | {} | {} |",
                v.short,
                r.variant,
                r.measure.describe(),
                r.constant.describe(),
                pct(r.figures.trot_gain_pct),
                pct(r.figures.walk_gain_pct),
                pct(r.figures.walk_over_trot_pct)
            );
        }
    }
    let _ = writeln!(md, "\n## What moves each figure\n");
    for (name, paper, f) in [
        (
            "Trot gain",
            PAPER_TROT_GAIN_PCT,
            (|r: &SensitivityRow| r.figures.trot_gain_pct) as fn(&SensitivityRow) -> Option<f64>,
        ),
        ("Walk gain", PAPER_WALK_GAIN_PCT, |r| {
            r.figures.walk_gain_pct
        }),
        ("Walk / trot energy", PAPER_WALK_OVER_TROT_PCT, |r| {
            r.figures.walk_over_trot_pct
        }),
    ] {
        let all: Vec<(&SensitivityRow, f64)> = variants
            .iter()
            .flat_map(|v| v.rows.iter())
            .filter_map(|r| Some((r, f(r)?)))
            .collect();
        let base = variants[0]
            .rows
            .iter()
            .find(|r| r.measure == CotMeasure::Eq8 && r.constant == ConstantChoice::BestOfGrid)
            .and_then(f);
        let nearest = all
            .iter()
            .min_by(|a, b| (a.1 - paper).abs().total_cmp(&(b.1 - paper).abs()));
        let _ = match (base, nearest) {
            (Some(b), Some((r, v))) => writeln!(
                md,
                "- **{name}** (paper {paper} %): {b:.1} % in {} (eq. 8, the grid's best \
                 constant); {:.1}–{:.1} % over every choice; nearest the paper {v:.1} %: {}; \
                 CoT {}; against {}.",
                variants[0].short,
                all.iter().map(|a| a.1).fold(f64::INFINITY, f64::min),
                all.iter().map(|a| a.1).fold(f64::NEG_INFINITY, f64::max),
                r.variant,
                r.measure.describe(),
                r.constant.describe()
            ),
            _ => writeln!(md, "- **{name}**: not available on this grid."),
        };
    }
    md
}
