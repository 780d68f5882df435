//! `eemp sweep report DIR`: the study's figures (drawn with [`crate::plots`] from the data
//! `eemp-study` selects) and the report files.
//!
//! Writes `DIR/tables/<robot>_<gait>.toml`, `DIR/figures/*.png`, `DIR/report.md` (figures linked) and
//! `DIR/report.html` (figures embedded); with `--tables-out DIR2`, the tables also to DIR2.
//! The selection settings are the folder's `sweep.toml` `[selection]` (a key missing there takes
//! its default).

use crate::plots::{heatmap_grid, line_panels, HeatmapCell, Panel, Series};
use eemp_core::planner::Gait;
use eemp_study::report::{self, fig5_speeds, table_file_name, Figure, ReportInput, TABLES_DIR};
use eemp_study::select::{cot_jump_pct_text, most_fell_pct_text, GaitStudy, Study};
use eemp_study::store::{load_results, load_sessions, load_stored_config, RESULTS_FILE};
use std::path::Path;

pub const FIGURES_DIR: &str = "figures";

/// Writes the report of the sweep folder `dir` (and, if `tables_out` is given, the tables to
/// that folder too); returns the written paths.
pub fn write_report(dir: &Path, tables_out: Option<&Path>) -> Result<Vec<String>, String> {
    let config = load_stored_config(dir)
        .map_err(|e| e.to_string())?
        .ok_or_else(|| format!("{}: no sweep.toml: not a sweep folder", dir.display()))?;
    let results = dir.join(RESULTS_FILE);
    let loaded = load_results(&results).map_err(|e| e.to_string())?;
    if loaded.dropped_tail.is_some() {
        eprintln!(
            "note: ignored a partial last line in {} (an interrupted run)",
            results.display()
        );
    }
    if loaded.rows.len() < config.grid.run_count() {
        eprintln!(
            "note: {} of {} runs have results; the report covers those",
            loaded.rows.len(),
            config.grid.run_count()
        );
    }
    let sessions = load_sessions(dir).map_err(|e| e.to_string())?;
    // The selection's objective: the rows' CoT is its definition's from here on (tables,
    // figures and report).
    let robot = config.grid.robot_config()?;
    let idle = eemp_study::sensitivity::IdleCharge::of(&robot);
    let objective = config.selection.objective;
    if objective != eemp_study::config::Objective::Eq8 && robot.motor_model().is_none() {
        return Err(format!(
            "selection.objective = {objective:?} needs the robot's motor model, and the {} \
             robot file has no [motor] section",
            robot.name
        ));
    }
    let rows = eemp_study::sensitivity::CotMeasure::of_objective(objective)
        .apply(&loaded.rows, idle.as_ref());
    let study = Study::analyse(&rows, config.selection);
    let mut written: Vec<String> = Vec::new();
    let mut write_tables = |to: &Path| {
        let w = report::write_tables(dir, to, &study, &config.grid).map_err(|e| e.to_string())?;
        for path in &w.removed {
            eprintln!(
                "note: removed {}: its gait no longer has a selectable point",
                path.display()
            );
        }
        written.extend(w.written.iter().map(|t| t.1.display().to_string()));
        Ok::<_, String>(w)
    };
    // The extra folder first: if it refuses (a table of another progress factor there),
    // nothing has been written.
    if let Some(to) = tables_out {
        write_tables(to)?;
    }
    let own = write_tables(&dir.join(TABLES_DIR))?;
    // Relative to the sweep folder, for the report's links.
    let tables: Vec<_> = own
        .written
        .iter()
        .map(|t| {
            let name = t.1.file_name().map(|n| n.to_string_lossy().into_owned());
            let name = name.unwrap_or_else(|| table_file_name("a1", t.0));
            (t.0, Path::new(TABLES_DIR).join(name))
        })
        .collect();
    let figures = draw_figures(dir, &config.grid.speed_mps, &study)?;
    written.extend(
        figures
            .iter()
            .map(|f| dir.join(&f.file).display().to_string()),
    );
    let doc = report::build(ReportInput {
        dir,
        config: &config,
        rows: &loaded.rows,
        sessions: &sessions,
        study: &study,
        tables: &tables,
        figures,
    });
    for (name, text) in [
        ("report.md", doc.to_markdown()),
        ("report.html", doc.to_html()),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        written.push(path.display().to_string());
    }
    Ok(written)
}

fn draw_figures(dir: &Path, grid_speeds: &[f64], study: &Study) -> Result<Vec<Figure>, String> {
    let mut figures = Vec::new();
    let mut add =
        |file: &str, title: &str, caption: String, draw: &dyn Fn(&Path) -> Result<(), String>| {
            let rel = format!("{FIGURES_DIR}/{file}");
            let path = dir.join(&rel);
            draw(&path)?;
            let png =
                std::fs::read(&path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
            figures.push(Figure {
                file: rel,
                title: title.into(),
                caption,
                png,
            });
            Ok::<(), String>(())
        };

    // Fig. 5: trot and walk side by side, one row per speed.
    let mut gaits: Vec<Gait> = [Gait::Trot, Gait::Walk]
        .into_iter()
        .filter(|g| study.gait(*g).is_some())
        .collect();
    if gaits.is_empty() {
        gaits = study.gaits.iter().map(|g| g.gait).collect();
    }
    let speeds = fig5_speeds(grid_speeds);
    let cells: Vec<HeatmapCell> = speeds
        .iter()
        .flat_map(|&(target, v)| {
            gaits.iter().map(move |&g| {
                let map = study.cot_map(g, v);
                let note = if (target - v).abs() > 1e-9 {
                    format!(" (paper: {target} m/s)")
                } else {
                    String::new()
                };
                HeatmapCell {
                    title: format!("{g}, {v} m/s{note}"),
                    x: map.swing_time_s,
                    y: map.ellipse_rx_m,
                    z: map.cot,
                }
            })
        })
        .collect();
    let title5 = "Fig. 5 analogue: CoT over swing time and ellipse r_x";
    add(
        "fig5_cot_contours.png",
        title5,
        format!(
            "CoT (dimensionless) per commanded speed (rows) for {} (columns), over r_x (y) and \
             ΔT (x); each row (speed) has its own colour scale and colour bar, shared by its \
             panels, so the structure at high speeds is not flattened by the higher CoT at low \
             speeds (compare values across rows by the bars). Each cell is the lowest \
             seed-averaged CoT over h_step, X_z and r_y among points that stood in every seed; \
             grey: every such point fell (or none was run). The paper's 0.01 m/s is below \
             Table I's 0.05 m/s: the nearest grid speed is shown.",
            gaits
                .iter()
                .map(Gait::to_string)
                .collect::<Vec<_>>()
                .join(" and ")
        ),
        &|p| {
            heatmap_grid(
                p,
                title5,
                "swing time ΔT [s]",
                "ellipse r_x [m]",
                "CoT [-]",
                &cells,
                gaits.len(),
            )
            .map_err(|e| e.to_string())
        },
    )?;

    // Fig. 6: walk vs trot, best per speed, with the walk instability marker.
    let best_series = |g: &GaitStudy, f: fn(&eemp_study::select::Scored) -> f64| Series {
        label: format!("{} (best per speed)", g.gait),
        x: g.speeds.iter().map(|s| s.speed_mps).collect(),
        y: g.speeds
            .iter()
            .map(|s| s.best.as_ref().map_or(f64::NAN, f))
            .collect(),
    };
    let unstable = |g: &GaitStudy| -> Vec<(f64, String)> {
        g.instability
            .map(|i| {
                (
                    i.speed_mps,
                    format!("{} unstable from {}\u{a0}m/s", g.gait, i.speed_mps),
                )
            })
            .into_iter()
            .collect()
    };
    let markers: Vec<(f64, String)> = study.gait(Gait::Walk).map_or(vec![], unstable);
    let panel = |title: &str, y_label: &str, f: fn(&eemp_study::select::Scored) -> f64| Panel {
        title: title.into(),
        x_label: "commanded speed [m/s]".into(),
        y_label: y_label.into(),
        series: gaits
            .iter()
            .filter_map(|g| study.gait(*g))
            .map(|g| best_series(g, f))
            .collect(),
        markers: markers.clone(),
        bands: vec![],
    };
    let panels6 = [
        panel("Cost of transport", "CoT [-]", |s| s.cot()),
        panel("Force manipulability (eq. 9)", "manipulability [-]", |s| {
            s.manipulability()
        }),
    ];
    // The paper's figure compares walk and trot; a grid without both gets a plain title.
    let has = |g: Gait| study.gait(g).is_some();
    let title6 = if has(Gait::Walk) && has(Gait::Trot) {
        "Fig. 6 analogue: walk vs trot".to_string()
    } else {
        let names: Vec<String> = gaits.iter().map(|g| g.to_string()).collect();
        format!(
            "Fig. 6 analogue: CoT and manipulability vs speed ({})",
            names.join(", ")
        )
    };
    let title6 = title6.as_str();
    add(
        "fig6_walk_vs_trot.png",
        title6,
        format!(
            "CoT (top) and manipulability (bottom) of the selected point per speed; gaps: no \
             selectable point. Red dashed line: where walk becomes unstable (no point selectable \
             at that or any higher speed, the best CoT jumped by more than {} from the \
             previous speed with a selectable point, or more than {} of the points fell there \
             and at every higher speed).",
            cot_jump_pct_text(),
            most_fell_pct_text()
        ),
        &|p| line_panels(p, title6, &panels6).map_err(|e| e.to_string()),
    )?;

    // Per-speed table vs best constant parameters, per gait.
    let panels_c: Vec<Panel> = study
        .gaits
        .iter()
        .map(|g| {
            let table = best_series(g, |s| s.cot());
            let mut series = vec![Series {
                label: "per-speed table".into(),
                ..table
            }];
            let mut title = format!("{}: no constant parameters work at every speed", g.gait);
            if let Some(c) = &g.constant {
                let p = &c.params;
                series.push(Series {
                    label: "best constant".into(),
                    x: c.per_speed
                        .iter()
                        .map(|s| s.summary.point.speed_mps)
                        .collect(),
                    y: c.per_speed.iter().map(|s| s.cot()).collect(),
                });
                title = format!(
                    "{}: constant ΔT {} s, h {} m, X_z {} m, r ({}, {}) m; table {:.1} % lower \
                     on average",
                    g.gait,
                    p.swing_time_s,
                    p.step_height_m,
                    p.body_height_m,
                    p.ellipse_rx_m,
                    p.ellipse_ry_m,
                    g.improvement.as_ref().map_or(f64::NAN, |i| i.pct)
                );
            }
            Panel {
                title,
                x_label: "commanded speed [m/s]".into(),
                y_label: "CoT [-]".into(),
                series,
                markers: unstable(g),
                bands: vec![],
            }
        })
        .collect();
    let title_c = "CoT: per-speed table vs best constant parameters";
    add(
        "cot_table_vs_constant.png",
        title_c,
        "CoT of the per-speed lookup table and of the gait's best constant parameters (Table II \
         analogue). The constant is chosen, and the improvement averaged, over the table's \
         speeds below the gait's instability (red dashed line, if any)."
            .into(),
        &|p| line_panels(p, title_c, &panels_c).map_err(|e| e.to_string()),
    )?;
    Ok(figures)
}

#[cfg(test)]
mod tests {
    use super::*;
    use eemp_core::planner::params_table::ParamsTable;
    use eemp_study::grid::RunSpec;
    use eemp_study::{run_sweep, ProgressMode, RunOutcome, SweepConfig, SweepOptions};

    /// A made-up study: CoT falls with speed and ΔT; walk falls at 0.7 m/s.
    fn fake(spec: &RunSpec) -> RunOutcome {
        let p = &spec.point;
        let walk = p.gait == Gait::Walk;
        RunOutcome {
            fell: walk && p.speed_mps > 0.6,
            cot: Some(
                0.1 / p.speed_mps + 1.0 - p.params.swing_time_s
                    + 2.0 * (p.params.ellipse_rx_m - 0.07).abs()
                    - if walk { 0.2 } else { 0.0 },
            ),
            manipulability: Some(3.0 + p.params.body_height_m),
            vel_rmse_mps: Some(0.1),
            distance_m: p.speed_mps * 18.0,
            metrics_window_s: 18.0,
            ..Default::default()
        }
    }

    #[test]
    fn report_has_tables_figures_and_the_paper_comparison() {
        let dir = std::env::temp_dir().join(format!("eemp-sweep-report-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let config = SweepConfig::parse(
            r#"
[grid]
gaits = ["trot", "walk"]
speed_mps = [0.05, 0.1, 0.3, 0.5, 0.7, 1.0]
swing_time_s = { min = 0.1, max = 0.25, steps = 4 }
step_height_m = [0.1]
body_height_m = [0.28, 0.31]
ellipse_rx_m = [0.03, 0.07, 0.11]
ellipse_ry_m = [0.05]
duration_s = 20
seeds = [0]
"#,
            Path::new("t.toml"),
        )
        .unwrap();
        let options = SweepOptions {
            threads: Some(2),
            shard: None,
            progress: ProgressMode::Hidden,
        };
        run_sweep(&config, &dir, &options, fake).unwrap();
        // A stale table of a gait of the grid, and another sweep's table, in the extra folder.
        let extra = dir.join("shipped-tables");
        std::fs::create_dir_all(&extra).unwrap();
        std::fs::write(extra.join("a1_free.toml"), "# another sweep's\n").unwrap();
        let written = write_report(&dir, Some(&extra)).unwrap();
        assert_eq!(written.len(), 2 + 2 + 3 + 2, "{written:?}");
        for g in ["trot", "walk"] {
            assert_eq!(
                std::fs::read_to_string(extra.join(format!("a1_{g}.toml"))).unwrap(),
                std::fs::read_to_string(dir.join(format!("tables/a1_{g}.toml")))
                    .unwrap()
                    .replace(
                        &dir.join("tables").display().to_string(),
                        &extra.display().to_string()
                    )
            );
        }
        assert!(
            extra.join("a1_free.toml").exists(),
            "free is not in this grid"
        );
        for g in ["trot", "walk"] {
            let t = ParamsTable::load(&dir.join(format!("tables/a1_{g}.toml"))).unwrap();
            assert!(t.entries.iter().all(|e| e.cot.is_some()));
            // Highest ΔT and the r_x nearest 0.07 win everywhere.
            assert!(t
                .entries
                .iter()
                .all(|e| e.swing_time_s == 0.25 && e.ellipse_rx_m == 0.07));
        }
        let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
        for needle in [
            "Paper vs this project",
            "35.5 %",
            "34.5 %",
            "13.3 %",
            "59 %",
            "walk becomes unstable",
            "0.7 m/s (every grid point fell, at this and every higher speed)",
            "points (fell / failed / off command / no metrics)",
            "max_speed_error_ratio",
            "figures/fig5_cot_contours.png",
            "tables/a1_trot.toml",
        ] {
            assert!(md.contains(needle), "'{needle}' not in report.md");
        }
        let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
        assert_eq!(
            html.matches("src=\"data:image/png;base64,iVBORw0KGgo")
                .count(),
            3
        );
        for f in [
            "fig5_cot_contours",
            "fig6_walk_vs_trot",
            "cot_table_vs_constant",
        ] {
            let png = std::fs::read(dir.join(format!("figures/{f}.png"))).unwrap();
            assert_eq!(&png[..4], b"\x89PNG");
        }
        if std::env::var_os("EEMP_KEEP_PLOTS").is_none() {
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }

    #[test]
    fn report_of_a_folder_without_sweep_toml_is_an_error() {
        let err = write_report(Path::new("/nonexistent/eemp-sweep"), None).unwrap_err();
        assert!(err.contains("not a sweep folder"), "{err}");
    }
}
