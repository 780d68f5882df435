//! `eemp compare` (the paper's Fig. 7 and Fig. 9: methods against speed) and `eemp robustness`
//! (methods across scenarios): suites of walks (`crate::suite`) and their reports.

use crate::plots::{grouped_bars, line_panels, Band, BarPanel, Panel, Series};
use crate::suite::{merge_rows, run_suite_shard, MethodConfig, SuiteConfig, SuiteRow};
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct SuiteArgs {
    /// The suite (TOML: duration_s, seeds, estimator, [[method]], [[scenario]]); default:
    /// suites/compare.toml or suites/robustness.toml.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Output folder: suite.toml, results.csv (resumable), figures, report.md, report.html.
    #[arg(long)]
    pub out: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Robot file for every run, over the suite's `robot` key (default: the shipped A1).
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Run tables and policies made for another robot (an experiment).
    #[arg(long)]
    pub allow_robot_mismatch: bool,
    /// The suite at a small scale, to check a pipeline (`eemp reproduce --quick`), not a
    /// result: the first seed only, runs of at most 4 s.
    #[arg(long)]
    pub quick: bool,
    /// Run only the K-th of N disjoint slices of the run list (1-based, e.g. 3/8), into --out,
    /// without a report: one folder per shard, then a run with --merge-from (a cluster array).
    #[arg(long, value_name = "K/N")]
    pub shard: Option<String>,
    /// Shard folders of this suite (same config) whose results --out takes before it runs what
    /// is still missing and writes the report.
    #[arg(long, value_name = "DIR", num_args = 1.., conflicts_with = "shard")]
    pub merge_from: Vec<PathBuf>,
}

/// Mean, min and max over the runs that did not fall; falls and runs.
#[derive(Clone, Debug, Default)]
pub struct Cell {
    pub runs: usize,
    pub falls: usize,
    pub cot: Stat,
    pub manipulability: Stat,
    pub vel_rmse: Stat,
    pub negative_work_share: Stat,
    pub cot_abs_power: Stat,
    pub diagonal_together: Stat,
    pub lateral_together: Stat,
    pub left_right_imbalance: Stat,
    pub duty_factor_min: Stat,
    /// One per [`ENERGY_DEFINITIONS`] entry, in its order.
    pub energy: Vec<Stat>,
    /// The battery's mean power, W (the robot file's motor model, with idle power).
    pub electrical_power_w: Stat,
}

/// One way to count a run's energy, as the reports compare them.
pub struct EnergyDefinition {
    /// How the report names it.
    pub label: &'static str,
    /// The run's CoT under it (dimensionless; `None`: not measured).
    pub cot: fn(&SuiteRow) -> Option<f64>,
}

fn plus(a: Option<f64>, b: Option<f64>) -> Option<f64> {
    a.zip(b).map(|(a, b)| a + b)
}

/// The energy definitions of the reports' lead tables: the battery's first (the robot file's
/// motor model with idle power, then its heat coefficients k at 1/3, 1 and 2 times, with and
/// without idle power), then the mechanical measures (the paper's eq. 8 and Σ|τq̇|).
pub const ENERGY_DEFINITIONS: [EnergyDefinition; 8] = [
    EnergyDefinition {
        label: "electrical, k, idle",
        cot: |r| r.cot_electrical,
    },
    EnergyDefinition {
        label: "electrical, k/3, idle",
        cot: |r| plus(r.cot_electrical_motors_low_k, r.cot_idle),
    },
    EnergyDefinition {
        label: "electrical, 2k, idle",
        cot: |r| plus(r.cot_electrical_motors_high_k, r.cot_idle),
    },
    EnergyDefinition {
        label: "electrical, k, no idle",
        cot: |r| r.cot_electrical_motors,
    },
    EnergyDefinition {
        label: "electrical, k/3, no idle",
        cot: |r| r.cot_electrical_motors_low_k,
    },
    EnergyDefinition {
        label: "electrical, 2k, no idle",
        cot: |r| r.cot_electrical_motors_high_k,
    },
    EnergyDefinition {
        label: "eq. 8 (paper)",
        cot: |r| r.cot,
    },
    EnergyDefinition {
        label: "Σ|τq̇|",
        cot: |r| r.cot_abs_power,
    },
];

/// The index of the paper's eq. (8) in [`ENERGY_DEFINITIONS`].
const EQ8: usize = 6;

#[derive(Clone, Debug, Default)]
pub struct Stat {
    values: Vec<f64>,
}

impl Stat {
    fn push(&mut self, v: Option<f64>) {
        if let Some(v) = v.filter(|v| v.is_finite()) {
            self.values.push(v);
        }
    }
    pub fn mean(&self) -> f64 {
        if self.values.is_empty() {
            f64::NAN
        } else {
            self.values.iter().sum::<f64>() / self.values.len() as f64
        }
    }
    pub fn min(&self) -> f64 {
        self.values.iter().copied().fold(f64::NAN, f64::min)
    }
    pub fn max(&self) -> f64 {
        self.values.iter().copied().fold(f64::NAN, f64::max)
    }
}

/// The learned baselines EEMP's lead is measured over: every model-free policy.
fn rivals(cfg: &SuiteConfig) -> Vec<&MethodConfig> {
    cfg.methods
        .iter()
        .filter(|m| m.kind == "model-free")
        .collect()
}

/// 1 − CoT_EEMP / CoT_method per speed, under energy definition `def`; NaN where either has no
/// CoT.
fn lead_at(
    cells: &BTreeMap<CellKey, Cell>,
    key: &dyn Fn(&str, f64) -> CellKey,
    eemp: &str,
    rival: &str,
    v: f64,
    def: usize,
) -> f64 {
    let cot = |m: &str| {
        cells
            .get(&key(m, v))
            .and_then(|c| c.energy.get(def))
            .map(Stat::mean)
            .unwrap_or(f64::NAN)
    };
    1.0 - cot(eemp) / cot(rival)
}

/// The mean of the finite values, NaN if none.
fn finite_mean(xs: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = xs.filter(|x| x.is_finite()).collect();
    match v.len() {
        0 => f64::NAN,
        n => v.iter().sum::<f64>() / n as f64,
    }
}

fn pct(x: f64) -> String {
    if x.is_finite() {
        format!("{:.1} %", 100.0 * x)
    } else {
        "–".into()
    }
}

/// The lines a reader wants first: EEMP's CoT lead (1 − CoT_EEMP / CoT_method) over every
/// model-free method per speed, under the battery's energy and under the paper's eq. (8); then
/// the mean lead at ≤ 0.6 m/s under every energy definition, and whether the methods' ranking
/// holds under all of them.
fn lead_section(
    md: &mut String,
    cfg: &SuiteConfig,
    speeds: &[f64],
    cells: &BTreeMap<CellKey, Cell>,
    key: &dyn Fn(&str, f64) -> CellKey,
) {
    // Every EEMP-Analytical method of the suite (the default one first, then variants such as
    // the battery-aware controller).
    let eemps: Vec<&MethodConfig> = cfg
        .methods
        .iter()
        .filter(|m| m.kind == "eemp" && !m.eemp_rl)
        .collect();
    let rivals = rivals(cfg);
    if eemps.is_empty() || rivals.is_empty() {
        return;
    }
    let low: Vec<f64> = speeds
        .iter()
        .copied()
        .filter(|v| *v <= 0.6 + 1e-9)
        .collect();
    for (def, title) in [
        (
            0,
            "the battery's energy: electrical CoT, the robot file's k, with idle power",
        ),
        (
            EQ8,
            "the paper's eq. 8 (net mechanical power; paper: 50.4 % at ≤ 0.6 m/s)",
        ),
    ] {
        let _ = writeln!(
            md,
            "## EEMP's lead in CoT over model-free RL under {title}\n\n\
             1 − CoT(EEMP) / CoT(method) per speed, means over the seeds that did not fall.\n"
        );
        for e in &eemps {
            let _ = writeln!(md, "{}:\n", e.name);
            let head: Vec<String> = rivals.iter().map(|m| format!("over {}", m.name)).collect();
            let _ = writeln!(md, "| speed m/s | {} |", head.join(" | "));
            let _ = writeln!(md, "|---|{}", "---|".repeat(rivals.len()));
            for &v in speeds {
                let cols: Vec<String> = rivals
                    .iter()
                    .map(|m| pct(lead_at(cells, key, &e.name, &m.name, v, def)))
                    .collect();
                let _ = writeln!(md, "| {v:.2} | {} |", cols.join(" | "));
            }
            let means: Vec<String> = rivals
                .iter()
                .map(|m| {
                    let x = finite_mean(
                        low.iter()
                            .map(|&v| lead_at(cells, key, &e.name, &m.name, v, def)),
                    );
                    format!("**{}**", pct(x))
                })
                .collect();
            let _ = writeln!(md, "| mean ≤ 0.6 | {} |\n", means.join(" | "));
        }
    }
    let _ = writeln!(
        md,
        "## The lead under every energy definition\n\n\
         Mean over the speeds ≤ 0.6 m/s of 1 − CoT(EEMP) / CoT(method). Electrical: each joint \
         draws τq̇ + k·τ² under the robot file's `[motor]` model (k its heat coefficients, scaled \
         by 1/3 and 2 for the band), with or without the electronics' idle power; eq. 8: the \
         paper's net mechanical power; Σ|τq̇|: absolute joint power (docs/energy.md).\n"
    );
    let _ = writeln!(
        md,
        "| EEMP | over | {} |",
        ENERGY_DEFINITIONS.map(|d| d.label).join(" | ")
    );
    let _ = writeln!(md, "|---|---|{}", "---|".repeat(ENERGY_DEFINITIONS.len()));
    for e in &eemps {
        for m in &rivals {
            let cols: Vec<String> = (0..ENERGY_DEFINITIONS.len())
                .map(|d| {
                    pct(finite_mean(
                        low.iter()
                            .map(|&v| lead_at(cells, key, &e.name, &m.name, v, d)),
                    ))
                })
                .collect();
            let _ = writeln!(md, "| {} | {} | {} |", e.name, m.name, cols.join(" | "));
        }
    }
    // The ranking of every method by its mean CoT at ≤ 0.6 m/s, per definition.
    let ranking = |d: usize| -> Vec<String> {
        let mut scored: Vec<(f64, &str)> = cfg
            .methods
            .iter()
            .map(|m| {
                let c: Vec<f64> = low
                    .iter()
                    .map(|&v| {
                        cells
                            .get(&key(&m.name, v))
                            .and_then(|c| c.energy.get(d))
                            .map(Stat::mean)
                            .unwrap_or(f64::NAN)
                    })
                    .collect();
                let all = c.iter().all(|x| x.is_finite());
                (
                    if all {
                        c.iter().sum::<f64>() / c.len() as f64
                    } else {
                        f64::NAN
                    },
                    m.name.as_str(),
                )
            })
            .filter(|(x, _)| x.is_finite())
            .collect();
        scored.sort_by(|a, b| a.0.total_cmp(&b.0));
        scored.into_iter().map(|(_, n)| n.to_string()).collect()
    };
    let rankings: Vec<Vec<String>> = (0..ENERGY_DEFINITIONS.len()).map(ranking).collect();
    let same = rankings.windows(2).all(|w| w[0] == w[1]);
    let first_same = rankings.iter().all(|r| r.first() == rankings[0].first());
    let _ = writeln!(
        md,
        "\nThe methods ranked by mean CoT at ≤ 0.6 m/s (methods with a CoT at every such speed): \
         the ranking is {} under every definition{}.\n",
        if same { "the same" } else { "**not** the same" },
        if same {
            String::new()
        } else if first_same {
            format!(
                ", but {} is first under all of them",
                rankings[0].first().map(String::as_str).unwrap_or("–")
            )
        } else {
            ", and the first place changes".into()
        }
    );
    let _ = writeln!(md, "| definition | ranking, lowest CoT first |\n|---|---|");
    for (d, r) in ENERGY_DEFINITIONS.iter().zip(&rankings) {
        let _ = writeln!(md, "| {} | {} |", d.label, r.join(" < "));
    }
    let _ = writeln!(md);
}

/// What gait each method walks and how much of its joints' work is negative, averaged over
/// the speeds (`GaitMeasure`, `WalkMetrics`).
fn gait_section(
    md: &mut String,
    cfg: &SuiteConfig,
    speeds: &[f64],
    cells: &BTreeMap<CellKey, Cell>,
    key: &dyn Fn(&str, f64) -> CellKey,
) {
    let _ = writeln!(
        md,
        "## Gait and energy of each method\n\n\
         Means over the speeds (and the seeds that did not fall): the fraction of time the \
         diagonal pairs (FR–RL, FL–RR) and the lateral pairs (FR–RR, FL–RL) share their contact \
         state, the left/right imbalance of the feet's load ((L − R)/(L + R)), the smallest \
         duty factor of the four feet, the joints' negative share of their absolute work, and \
         the CoT of the absolute joint power (Σ|τq̇|, Fu et al. 2021) beside eq. 8's.\n"
    );
    let _ = writeln!(
        md,
        "| method | diagonal together | lateral together | left/right imbalance | min duty factor | negative work share | CoT eq. 8 | CoT abs. power |"
    );
    let _ = writeln!(md, "|---|---|---|---|---|---|---|---|");
    for m in &cfg.methods {
        let avg = |f: fn(&Cell) -> &Stat| {
            let v: Vec<f64> = speeds
                .iter()
                .filter_map(|&s| cells.get(&key(&m.name, s)).map(|c| f(c).mean()))
                .filter(|x| x.is_finite())
                .collect();
            match v.is_empty() {
                true => "–".to_string(),
                false => format!("{:.3}", v.iter().sum::<f64>() / v.len() as f64),
            }
        };
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} | {} |",
            m.name,
            avg(|c| &c.diagonal_together),
            avg(|c| &c.lateral_together),
            avg(|c| &c.left_right_imbalance),
            avg(|c| &c.duty_factor_min),
            avg(|c| &c.negative_work_share),
            avg(|c| &c.cot),
            avg(|c| &c.cot_abs_power),
        );
    }
    let _ = writeln!(md);
}

/// (method, scenario, speed in mm/s).
type CellKey = (String, String, i64);

/// Cells keyed by (method, scenario, speed in mm/s).
pub fn aggregate(rows: &[SuiteRow]) -> BTreeMap<CellKey, Cell> {
    let mut m: BTreeMap<(String, String, i64), Cell> = BTreeMap::new();
    for r in rows {
        let key = (
            r.method.clone(),
            r.scenario.clone(),
            (r.speed_mps * 1000.0).round() as i64,
        );
        let c = m.entry(key).or_default();
        c.runs += 1;
        c.energy
            .resize_with(ENERGY_DEFINITIONS.len(), Stat::default);
        if r.fell {
            c.falls += 1;
            continue;
        }
        c.cot.push(r.cot);
        c.manipulability.push(r.manipulability);
        c.vel_rmse.push(r.vel_rmse_mps);
        c.negative_work_share.push(r.negative_work_share);
        c.cot_abs_power.push(r.cot_abs_power);
        c.diagonal_together.push(r.diagonal_pairs_together);
        c.lateral_together.push(r.lateral_pairs_together);
        c.left_right_imbalance.push(r.left_right_imbalance);
        c.duty_factor_min.push(r.duty_factor_min);
        for (stat, def) in c.energy.iter_mut().zip(&ENERGY_DEFINITIONS) {
            stat.push((def.cot)(r));
        }
        c.electrical_power_w.push(r.electrical_power_w);
    }
    m
}

fn threads(args: &SuiteArgs) -> usize {
    args.threads.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    })
}

/// Runs the suite's missing runs (of one shard under --shard); the config and every row, or
/// `None` after a shard (its report waits for the merge).
fn run(args: &SuiteArgs, default: &str) -> Result<Option<(SuiteConfig, Vec<SuiteRow>)>, String> {
    if args.threads == Some(0) {
        return Err("--threads 0 is out of range: allowed ≥ 1".into());
    }
    // The sweeps' shard: run i belongs to shard i mod N + 1.
    let shard = args
        .shard
        .as_deref()
        .map(eemp_study::pipeline::parse_shard)
        .transpose()?
        .map(|(index, count)| eemp_study::Shard { index, count });
    let path = args
        .config
        .clone()
        .unwrap_or_else(|| PathBuf::from(default));
    // The command line's robot first, then one validation against it.
    let mut cfg: SuiteConfig =
        eemp_core::config_error::load_toml(&path).map_err(|e| e.to_string())?;
    if let Some(r) = &args.robot {
        cfg.robot = Some(r.clone());
    }
    cfg.allow_robot_mismatch |= args.allow_robot_mismatch;
    if args.quick {
        cfg.seeds.truncate(1);
        cfg.duration_s = cfg.duration_s.min(4.0);
    }
    cfg.validate()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    if !args.merge_from.is_empty() {
        let n = merge_rows(&cfg, &args.merge_from, &args.out)?;
        eprintln!(
            "took {n} run(s) from {} shard folder(s) into {}",
            args.merge_from.len(),
            args.out.display()
        );
    }
    let total = (0..cfg.runs()?.len())
        .filter(|&i| shard.is_none_or(|s| s.contains(i)))
        .count();
    let bar = ProgressBar::new(total as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} runs, {elapsed} elapsed, eta {eta}")
            .expect("valid template"),
    );
    let t0 = std::time::Instant::now();
    let rows = run_suite_shard(&cfg, &args.out, threads(args), shard, &|_, n, _| {
        bar.set_position(n as u64)
    })?;
    bar.finish_and_clear();
    eprintln!(
        "{} runs in {}, {:.0} s this session",
        rows.len(),
        args.out.display(),
        t0.elapsed().as_secs_f64()
    );
    if let Some(s) = shard {
        println!(
            "shard {s} done in {}; when every shard is: the same command without --shard, \
             with --merge-from <the shard folders> --out <the report folder>",
            args.out.display()
        );
        return Ok(None);
    }
    Ok(Some((cfg, rows)))
}

fn f3(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.3}")
    } else {
        "–".into()
    }
}

fn spread(s: &Stat) -> String {
    if s.values.len() > 1 {
        format!("{} ({}–{})", f3(s.mean()), f3(s.min()), f3(s.max()))
    } else {
        f3(s.mean())
    }
}

/// A plain HTML page of a Markdown report: headings, tables, images, paragraphs.
pub(crate) fn html_of(md: &str, title: &str) -> String {
    let mut h = format!(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>{title}</title><style>\
         body{{font-family:sans-serif;max-width:1200px;margin:2em auto}}table{{border-collapse:collapse}}\
         td,th{{border:1px solid #ccc;padding:3px 8px}}img{{max-width:100%}}</style></head><body>\n"
    );
    let mut in_table = false;
    for line in md.lines() {
        let esc = line
            .replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;");
        if line.starts_with('|') {
            if line.contains("---") {
                continue;
            }
            if !in_table {
                h.push_str("<table>\n");
                in_table = true;
            }
            let cells: Vec<&str> = esc.trim_matches('|').split('|').collect();
            h.push_str("<tr>");
            for c in cells {
                let _ = write!(h, "<td>{}</td>", c.trim());
            }
            h.push_str("</tr>\n");
            continue;
        }
        if in_table {
            h.push_str("</table>\n");
            in_table = false;
        }
        if let Some(t) = line.strip_prefix("## ") {
            let _ = writeln!(h, "<h2>{t}</h2>");
        } else if let Some(t) = line.strip_prefix("# ") {
            let _ = writeln!(h, "<h1>{t}</h1>");
        } else if let Some(rest) = line.strip_prefix("![") {
            if let Some((alt, src)) = rest.split_once("](") {
                let _ = writeln!(
                    h,
                    "<p><img alt=\"{alt}\" src=\"{}\"></p>",
                    src.trim_end_matches(')')
                );
            }
        } else if !line.trim().is_empty() {
            let _ = writeln!(h, "<p>{esc}</p>");
        }
    }
    if in_table {
        h.push_str("</table>\n");
    }
    h.push_str("</body></html>\n");
    h
}

fn write_report(dir: &Path, md: &str, title: &str) -> Result<(), String> {
    std::fs::write(dir.join("report.md"), md).map_err(|e| e.to_string())?;
    std::fs::write(dir.join("report.html"), html_of(md, title)).map_err(|e| e.to_string())
}

/// Training curves of the suite's learned methods: `<policy>.train.csv` beside each policy.
fn training_curves(cfg: &SuiteConfig, png: &Path) -> Result<Vec<String>, String> {
    let mut series = Vec::new();
    let mut found = Vec::new();
    for m in cfg.methods.iter().filter(|m| m.kind != "eemp") {
        let Some(p) = &m.policy else { continue };
        let csv_path = p.with_extension("train.csv");
        let Ok(mut rd) = csv::Reader::from_path(&csv_path) else {
            continue;
        };
        let h = rd.headers().map_err(|e| e.to_string())?.clone();
        let col = |n: &str| h.iter().position(|x| x == n);
        let (Some(xs), Some(ys)) = (col("env_steps"), col("mean_step_reward")) else {
            continue;
        };
        let (mut x, mut y) = (Vec::new(), Vec::new());
        for r in rd.records().flatten() {
            if let (Some(a), Some(b)) = (r.get(xs), r.get(ys)) {
                if let (Ok(a), Ok(b)) = (a.parse::<f64>(), b.parse::<f64>()) {
                    x.push(a / 1e6);
                    y.push(b);
                }
            }
        }
        found.push(format!("{} ({})", m.name, csv_path.display()));
        series.push(Series {
            label: m.name.clone(),
            x,
            y,
        });
    }
    line_panels(
        png,
        "Training curves (the paper's Fig. 9 analogue)",
        &[Panel {
            title: "mean reward per policy step (each task's own reward)".into(),
            x_label: "environment steps [millions]".into(),
            y_label: "mean step reward [-]".into(),
            series,
            markers: vec![],
            bands: vec![],
        }],
    )
    .map_err(|e| e.to_string())?;
    Ok(found)
}

/// The parameters in force per speed for every method that reports them (EEMP's), one panel
/// per parameter; false (no figure) when no method does.
fn params_figure(
    cfg: &SuiteConfig,
    rows: &[SuiteRow],
    speeds: &[f64],
    png: &Path,
) -> Result<bool, String> {
    let names = eemp_core::planner::PlannerParams::NAMES;
    let units = ["s", "m", "m", "m", "m"];
    let labels = [
        "swing time ΔT",
        "step height h_step",
        "body height X_z",
        "ellipse r_x",
        "ellipse r_y",
    ];
    let mut panels = Vec::new();
    for k in 0..names.len() {
        let mut series = Vec::new();
        for m in &cfg.methods {
            let y: Vec<f64> = speeds
                .iter()
                .map(|&v| {
                    let vals: Vec<f64> = rows
                        .iter()
                        .filter(|r| r.method == m.name && (r.speed_mps - v).abs() < 1e-6 && !r.fell)
                        .filter_map(|r| r.params_mean().map(|p| p[k]))
                        .collect();
                    match vals.is_empty() {
                        true => f64::NAN,
                        false => vals.iter().sum::<f64>() / vals.len() as f64,
                    }
                })
                .collect();
            if y.iter().any(|v| v.is_finite()) {
                series.push(Series {
                    label: m.name.clone(),
                    x: speeds.to_vec(),
                    y,
                });
            }
        }
        if series.is_empty() {
            return Ok(false);
        }
        panels.push(Panel {
            title: format!(
                "{} in force (mean over the metrics window and the seeds)",
                labels[k]
            ),
            x_label: "commanded speed [m/s]".into(),
            y_label: format!("{} [{}]", names[k], units[k]),
            series,
            markers: vec![],
            bands: vec![],
        });
    }
    line_panels(
        png,
        "Planner parameters each EEMP method walked with",
        &panels,
    )
    .map_err(|e| e.to_string())?;
    Ok(true)
}

pub fn compare(args: &SuiteArgs) -> Result<(), String> {
    let Some((cfg, rows)) = run(args, "suites/compare.toml")? else {
        return Ok(());
    };
    let cells = aggregate(&rows);
    let scen = cfg.scenarios[0].name.clone();
    let speeds: Vec<f64> = cfg.scenario_speeds()?.swap_remove(0);
    let key = |m: &str, v: f64| (m.to_string(), scen.clone(), (v * 1000.0).round() as i64);
    // Fig. 7: three panels against speed, one line per method, min–max over seeds shaded.
    let metric = |name: &str, unit: &str, f: fn(&Cell) -> &Stat| {
        let mut series = Vec::new();
        let mut bands = Vec::new();
        for (i, m) in cfg.methods.iter().enumerate() {
            let cs: Vec<Option<&Cell>> = speeds
                .iter()
                .map(|&v| cells.get(&key(&m.name, v)))
                .collect();
            let stat = |g: fn(&Stat) -> f64| -> Vec<f64> {
                cs.iter()
                    .map(|c| c.map(|c| g(f(c))).unwrap_or(f64::NAN))
                    .collect()
            };
            series.push(Series {
                label: m.name.clone(),
                x: speeds.clone(),
                y: stat(Stat::mean),
            });
            bands.push(Band {
                of: i,
                lo: stat(Stat::min),
                hi: stat(Stat::max),
            });
        }
        Panel {
            title: format!("{name} (mean of the seeds that did not fall, min–max shaded)"),
            x_label: "commanded speed [m/s]".into(),
            y_label: format!("{name} [{unit}]"),
            series,
            markers: vec![],
            bands,
        }
    };
    let panels = [
        metric(
            "electrical CoT, with idle power (robot file's motor model)",
            "-",
            |c| &c.energy[0],
        ),
        metric("CoT of eq. 8 (the paper's, mechanical)", "-", |c| &c.cot),
        metric("manipulability", "-", |c| &c.manipulability),
        metric("velocity RMSE", "m/s", |c| &c.vel_rmse),
    ];
    line_panels(
        &args.out.join("fig7.png"),
        "Methods against speed (the paper's Fig. 7 analogue)",
        &panels,
    )
    .map_err(|e| e.to_string())?;
    let curves = training_curves(&cfg, &args.out.join("fig9.png"))?;
    let with_params = params_figure(&cfg, &rows, &speeds, &args.out.join("params.png"))?;

    let mut md = String::new();
    let _ = writeln!(
        md,
        "# Comparison of {} methods (the paper's Fig. 7 compares four)\n",
        cfg.methods.len()
    );
    let _ = writeln!(
        md,
        "{} runs: {} methods × {} speeds × {} seeds, {} s each, estimator `{}`, flat floor. \
         Regenerate: `eemp compare --config {} --out DIR` (resumable: a killed run continues \
         where it stopped). Means are over the seeds that did not fall; the min–max over seeds \
         is in brackets.\n",
        rows.len(),
        cfg.methods.len(),
        speeds.len(),
        cfg.seeds.len(),
        cfg.duration_s,
        cfg.estimator,
        args.config
            .as_deref()
            .unwrap_or(Path::new("suites/compare.toml"))
            .display()
    );
    let _ = writeln!(
        md,
        "![Fig. 7 analogue](fig7.png)\n\n![Fig. 9 analogue](fig9.png)\n"
    );
    if with_params {
        let _ = writeln!(
            md,
            "The planner parameters each EEMP method walked with (mean over the metrics \
             window and the seeds; EEMP-RL's are its own choices, the table's are the table's \
             at the command):\n\n![parameters in force](params.png)\n"
        );
    }
    let _ = writeln!(
        md,
        "Training logs: {}.\n",
        if curves.is_empty() {
            "none found".into()
        } else {
            curves.join(", ")
        }
    );
    lead_section(&mut md, &cfg, &speeds, &cells, &key);
    gait_section(&mut md, &cfg, &speeds, &cells, &key);
    let _ = writeln!(md, "## Per speed\n");
    let _ = writeln!(
        md,
        "| speed m/s | method | falls | electrical CoT | battery power W | CoT eq. 8 | manipulability | vel RMSE m/s |"
    );
    let _ = writeln!(md, "|---|---|---|---|---|---|---|---|");
    for &v in &speeds {
        for m in &cfg.methods {
            if let Some(c) = cells.get(&key(&m.name, v)) {
                let _ = writeln!(
                    md,
                    "| {v:.2} | {} | {}/{} | {} | {} | {} | {} | {} |",
                    m.name,
                    c.falls,
                    c.runs,
                    spread(&c.energy[0]),
                    f3(c.electrical_power_w.mean()),
                    spread(&c.cot),
                    spread(&c.manipulability),
                    spread(&c.vel_rmse)
                );
            }
        }
    }
    // The paper's claims against what was measured.
    let by_kind = |k: &str| {
        cfg.methods
            .iter()
            .find(|m| m.kind == k)
            .map(|m| m.name.clone())
    };
    // EEMP-Analytical: the first EEMP method that is not a table EEMP-RL learned.
    let eemp = cfg
        .methods
        .iter()
        .find(|m| m.kind == "eemp" && !m.eemp_rl)
        .map(|m| m.name.clone());
    // EEMP-RL: the first policy or learned table, in the suite's order.
    let eemp_rl = cfg
        .methods
        .iter()
        .find(|m| m.is_eemp_rl())
        .map(|m| m.name.clone());
    let mf = by_kind("model-free");
    let im = by_kind("imitation");
    let low: Vec<f64> = speeds
        .iter()
        .copied()
        .filter(|v| *v <= 0.6 + 1e-9)
        .collect();
    let mean_of = |m: &str, v: f64, f: fn(&Cell) -> &Stat| {
        cells
            .get(&key(m, v))
            .map(|c| f(c).mean())
            .unwrap_or(f64::NAN)
    };
    let _ = writeln!(md, "\n## The paper's claims, measured\n");
    let _ = writeln!(md, "| claim (paper) | measured here |");
    let _ = writeln!(md, "|---|---|");
    if let Some(e) = &eemp {
        let mut best = [0usize; 3];
        for &v in &low {
            let others: Vec<&String> = cfg
                .methods
                .iter()
                .map(|m| &m.name)
                .filter(|n| *n != e)
                .collect();
            // A speed at which EEMP fell in any seed is not a win.
            let fell = cells.get(&key(e, v)).map(|c| c.falls > 0).unwrap_or(true);
            let wins = |f: fn(&Cell) -> &Stat, higher: bool| {
                let me = mean_of(e, v, f);
                !fell
                    && me.is_finite()
                    && others.iter().all(|o| {
                        let x = mean_of(o, v, f);
                        !x.is_finite() || if higher { me >= x } else { me <= x }
                    })
            };
            best[0] += wins(|c| &c.cot, false) as usize;
            best[1] += wins(|c| &c.manipulability, true) as usize;
            best[2] += wins(|c| &c.vel_rmse, false) as usize;
        }
        let (falls, runs) = low.iter().fold((0, 0), |(f, n), &v| {
            let c = cells.get(&key(e, v));
            (
                f + c.map(|c| c.falls).unwrap_or(0),
                n + c.map(|c| c.runs).unwrap_or(0),
            )
        });
        let _ = writeln!(
            md,
            "| {e} best at ≤ 0.6 m/s in CoT, manipulability and velocity tracking | best CoT at {} of {} speeds, best manipulability at {}, best tracking at {} (a speed with a fall counts as lost; it fell in {falls} of its {runs} runs there) |",
            best[0], low.len(), best[1], best[2]
        );
        for mf in cfg.methods.iter().filter(|m| m.kind == "model-free") {
            let imp: Vec<f64> = low
                .iter()
                .map(|&v| 1.0 - mean_of(e, v, |c| &c.cot) / mean_of(&mf.name, v, |c| &c.cot))
                .filter(|x| x.is_finite())
                .collect();
            if imp.is_empty() {
                let _ = writeln!(
                    md,
                    "| CoT improvement of EEMP over model-free RL at ≤ 0.6 m/s: 50.4 % | over {}: not measured (no speed ≤ 0.6 m/s where both have a CoT) |",
                    mf.name
                );
                continue;
            }
            let mean = imp.iter().sum::<f64>() / imp.len() as f64;
            let electrical = finite_mean(
                low.iter()
                    .map(|&v| lead_at(&cells, &key, e, &mf.name, v, 0)),
            );
            let _ = writeln!(
                md,
                "| CoT improvement of EEMP over model-free RL at ≤ 0.6 m/s: 50.4 % (eq. 8) | over {}: {:.1} % under eq. 8 (mean over {} speeds of 1 − CoT_EEMP / CoT_model-free); {} under the battery's energy (electrical CoT, the robot file's k, with idle power) |",
                mf.name,
                100.0 * mean,
                imp.len(),
                pct(electrical)
            );
        }
    }
    match (&eemp, eemp_rl) {
        (Some(_), Some(r)) if low.is_empty() => {
            let _ = writeln!(
                md,
                "| {r} \"slightly outperforms\" EEMP-Analytical | not measured: no speed ≤ 0.6 m/s in this suite |"
            );
        }
        (Some(e), Some(r)) => {
            let mut ge = [0usize; 3];
            let (mut worst_pct, mut sum_pct, mut within) = (f64::NEG_INFINITY, 0.0, 0usize);
            for &v in &low {
                let (cr, ce) = (mean_of(&r, v, |c| &c.cot), mean_of(e, v, |c| &c.cot));
                ge[0] += (cr <= ce) as usize;
                ge[1] += (mean_of(&r, v, |c| &c.manipulability)
                    >= mean_of(e, v, |c| &c.manipulability)) as usize;
                let (tr, te) = (
                    mean_of(&r, v, |c| &c.vel_rmse),
                    mean_of(e, v, |c| &c.vel_rmse),
                );
                ge[2] += (tr <= te) as usize;
                within += (tr <= te + 0.01) as usize;
                let pct = 100.0 * (cr / ce - 1.0);
                worst_pct = worst_pct.max(pct);
                sum_pct += pct;
            }
            let falls: usize = speeds
                .iter()
                .map(|&v| cells.get(&key(&r, v)).map(|c| c.falls).unwrap_or(0))
                .sum();
            let _ = writeln!(
                md,
                "| {r} \"slightly outperforms\" {e} in CoT and manipulability | at ≤ 0.6 m/s {r}'s CoT is lower or equal at {} of {} speeds (mean {:+.1} %, at most {:+.1} % against the table), manipulability higher or equal at {}, tracking better or equal at {} and within +0.01 m/s at {}; it fell in {falls} runs over all speeds |",
                ge[0], low.len(), sum_pct / low.len().max(1) as f64, worst_pct, ge[1], ge[2], within
            );
        }
        (e, r) => {
            let missing = match (e, r) {
                (None, None) => "no EEMP-Analytical and no EEMP-RL method",
                (None, Some(_)) => "no EEMP-Analytical method (a plain table of kind eemp)",
                _ => "no EEMP-RL method",
            };
            let _ = writeln!(
                md,
                "| EEMP-RL ≥ EEMP-Analytical | not measured: {missing} in this suite |"
            );
        }
    }
    if let (Some(mf), Some(im)) = (&mf, &im) {
        let mut worse = [0usize; 3];
        for &v in &speeds {
            worse[0] += (mean_of(im, v, |c| &c.cot) > mean_of(mf, v, |c| &c.cot)) as usize;
            worse[1] += (mean_of(im, v, |c| &c.manipulability)
                < mean_of(mf, v, |c| &c.manipulability)) as usize;
            worse[2] +=
                (mean_of(im, v, |c| &c.vel_rmse) > mean_of(mf, v, |c| &c.vel_rmse)) as usize;
        }
        let _ = writeln!(
            md,
            "| motion imitation below model-free RL at nearly all speeds | imitation worse in CoT at {} of {} speeds, in manipulability at {}, in tracking at {} |",
            worse[0], speeds.len(), worse[1], worse[2]
        );
    }
    write_report(&args.out, &md, "eemp compare")?;
    println!(
        "wrote {}/report.md, report.html, fig7.png, fig9.png, params.png, results.csv",
        args.out.display()
    );
    Ok(())
}

/// Each EEMP-RL method against EEMP-Analytical with the free gait's table on the same
/// estimator: falls per case and in total, and where neither falls which has the lower CoT.
/// A method's cell in a case (scenario, speed).
type CellOf<'a> = dyn Fn(&str, &(String, f64)) -> Option<&'a Cell> + 'a;

/// Whether an EEMP-RL policy's controller runs slip handling (its training config says); None
/// where the file cannot be read here.
#[cfg(feature = "learning")]
fn policy_runs_slip_handling(path: &Path) -> Option<bool> {
    let task = Some(eemp_rl::config::TaskKind::EempRl);
    let policy = eemp_rl::policy::Policy::load(path, task).ok()?;
    Some(policy.config.eemp_rl.adapt_friction)
}

#[cfg(not(feature = "learning"))]
fn policy_runs_slip_handling(_: &Path) -> Option<bool> {
    None
}

fn rl_against_table<'a>(
    cfg: &SuiteConfig,
    cats: &[(String, f64)],
    cell: &CellOf<'a>,
    md: &mut String,
) {
    // The table's walk with the controller EEMP-RL runs: slip handling as the policy was
    // trained (its config says), where the suite has that method, else the free gait's default.
    let free_table = |m: &&MethodConfig, slip: Option<bool>| {
        m.kind == "eemp"
            && !m.eemp_rl
            && m.gait.as_deref() == Some("free")
            && m.adapt_friction() == slip
            && m.set
                .iter()
                .all(|s| eemp_core::settings::key_of(s) == "slip.adapt_friction")
    };
    let mut lines = Vec::new();
    for r in cfg.methods.iter().filter(|m| m.is_eemp_rl()) {
        let same = |t: &&MethodConfig| t.estimator(cfg) == r.estimator(cfg);
        // A learned table walks with its method's own slip setting (absent: the default, on).
        let slip = match r.kind.as_str() {
            "eemp" => Some(r.adapt_friction() != Some(false)),
            _ => r.policy.as_deref().and_then(policy_runs_slip_handling),
        };
        if slip.is_none() {
            eprintln!(
                "note: cannot read {}'s policy: it is compared with the table without slip \
                 handling",
                r.name
            );
        }
        let order = match slip {
            Some(true) => [None, Some(true)],
            _ => [Some(false), None],
        };
        let Some(t) = order
            .into_iter()
            .find_map(|slip| cfg.methods.iter().find(|t| free_table(t, slip) && same(t)))
        else {
            continue;
        };
        let (mut fr, mut ft, mut more, mut both_walk, mut lower) = (0, 0, 0, 0, 0);
        for c in cats {
            let (Some(a), Some(b)) = (cell(&r.name, c), cell(&t.name, c)) else {
                continue;
            };
            fr += a.falls;
            ft += b.falls;
            more += (a.falls > b.falls) as usize;
            if a.falls == 0 && b.falls == 0 {
                both_walk += 1;
                lower += (a.cot.mean() < b.cot.mean()) as usize;
            }
        }
        lines.push(format!(
            "| {} | {} | {fr} | {ft} | {more} | {lower} of {both_walk} |",
            r.name, t.name
        ));
    }
    if !lines.is_empty() {
        let _ = writeln!(
            md,
            "\n## EEMP-RL against the table it learned from\n\nFalls over all cases, cases \
             where EEMP-RL fell in more runs, and among the cases where neither fell the ones \
             where EEMP-RL's mean CoT is lower.\n"
        );
        let _ = writeln!(
            md,
            "| EEMP-RL | EEMP-Analytical | EEMP-RL falls | table falls | cases with more falls | lower CoT |"
        );
        let _ = writeln!(md, "|---|---|---|---|---|---|");
        for l in lines {
            let _ = writeln!(md, "{l}");
        }
    }
}

pub fn robustness(args: &SuiteArgs) -> Result<(), String> {
    let Some((cfg, rows)) = run(args, "suites/robustness.toml")? else {
        return Ok(());
    };
    let cells = aggregate(&rows);
    let methods: Vec<String> = cfg.methods.iter().map(|m| m.name.clone()).collect();
    // One category per scenario and speed.
    let mut cats: Vec<(String, f64)> = Vec::new();
    let mut speed_count = std::collections::HashMap::new();
    for (s, speeds) in cfg.scenarios.iter().zip(cfg.scenario_speeds()?) {
        speed_count.insert(s.name.clone(), speeds.len());
        for v in speeds {
            cats.push((s.name.clone(), v));
        }
    }
    let names: Vec<String> = cats
        .iter()
        .map(|(s, v)| {
            if speed_count.get(s).copied().unwrap_or(1) > 1 {
                format!("{s} {v}")
            } else {
                s.clone()
            }
        })
        .collect();
    let cell = |m: &str, (s, v): &(String, f64)| {
        cells.get(&(m.to_string(), s.clone(), (v * 1000.0).round() as i64))
    };
    let values = |f: &dyn Fn(&Cell) -> f64| -> Vec<Vec<f64>> {
        methods
            .iter()
            .map(|m| {
                cats.iter()
                    .map(|c| cell(m, c).map(f).unwrap_or(f64::NAN))
                    .collect()
            })
            .collect()
    };
    let panels = [
        BarPanel {
            title: "success rate (20 s without a fall)".into(),
            y_label: "runs without a fall [%]".into(),
            values: values(&|c| 100.0 * (c.runs - c.falls) as f64 / c.runs.max(1) as f64),
        },
        BarPanel {
            title: "electrical CoT with idle power (mean over runs without a fall)".into(),
            y_label: "electrical CoT [-]".into(),
            values: values(&|c| c.energy[0].mean()),
        },
        BarPanel {
            title: "CoT of eq. 8, the paper's (mean over runs without a fall)".into(),
            y_label: "CoT eq. 8 [-]".into(),
            values: values(&|c| c.cot.mean()),
        },
        BarPanel {
            title: "velocity RMSE (mean over runs without a fall)".into(),
            y_label: "velocity RMSE [m/s]".into(),
            values: values(&|c| c.vel_rmse.mean()),
        },
    ];
    grouped_bars(
        &args.out.join("robustness.png"),
        "Robustness: methods across scenarios",
        &names,
        &methods,
        &panels,
    )
    .map_err(|e| e.to_string())?;
    let mut md = String::new();
    let _ = writeln!(md, "# Robustness suite\n");
    let _ = writeln!(
        md,
        "{} runs: {} methods × {} scenario–speed cases × {} seeds, {} s each, estimator `{}`. \
         Regenerate: `eemp robustness --config {} --out DIR` (resumable). A run succeeds if it \
         walks the whole time without a fall; CoT and velocity RMSE are means over the \
         successful runs (min–max over seeds in brackets). Electrical CoT: the battery's energy \
         under the robot file's motor model with idle power; CoT eq. 8: the paper's net \
         mechanical power (docs/energy.md).\n",
        rows.len(),
        methods.len(),
        cats.len(),
        cfg.seeds.len(),
        cfg.duration_s,
        cfg.estimator,
        args.config
            .as_deref()
            .unwrap_or(Path::new("suites/robustness.toml"))
            .display()
    );
    let _ = writeln!(md, "![robustness](robustness.png)\n");
    let _ = writeln!(
        md,
        "| scenario | speed m/s | method | success | electrical CoT | CoT eq. 8 | vel RMSE m/s | falls at s |"
    );
    let _ = writeln!(md, "|---|---|---|---|---|---|---|---|");
    for c in &cats {
        for m in &methods {
            if let Some(x) = cell(m, c) {
                let falls: Vec<String> = rows
                    .iter()
                    .filter(|r| {
                        &r.method == m
                            && r.scenario == c.0
                            && (r.speed_mps - c.1).abs() < 1e-9
                            && r.fell
                    })
                    .filter_map(|r| r.fell_at_s.map(|t| format!("{t:.1}")))
                    .collect();
                let _ = writeln!(
                    md,
                    "| {} | {:.2} | {m} | {}/{} | {} | {} | {} | {} |",
                    c.0,
                    c.1,
                    x.runs - x.falls,
                    x.runs,
                    spread(&x.energy[0]),
                    spread(&x.cot),
                    spread(&x.vel_rmse),
                    if falls.is_empty() {
                        "–".into()
                    } else {
                        falls.join(", ")
                    }
                );
            }
        }
    }
    // The same method on two estimators: how much the filter costs in tracking.
    let pairs: Vec<(&MethodConfig, &MethodConfig)> = cfg
        .methods
        .iter()
        .flat_map(|a| cfg.methods.iter().map(move |b| (a, b)))
        .filter(|(a, b)| {
            a.estimator(&cfg) == "kf"
                && b.estimator(&cfg) == "ground-truth"
                && (
                    &a.kind,
                    &a.gait,
                    &a.table,
                    &a.policy,
                    a.controller_sets_besides(&[]),
                ) == (
                    &b.kind,
                    &b.gait,
                    &b.table,
                    &b.policy,
                    b.controller_sets_besides(&[]),
                )
        })
        .collect();
    if !pairs.is_empty() {
        let _ = writeln!(
            md,
            "\n## The filter against ground truth\n\nVelocity RMSE on the Kalman filter divided \
             by the same method's on ground truth, over the seeds where both walked without a \
             fall (– where there is none).\n"
        );
        let _ = writeln!(
            md,
            "| scenario | speed m/s | {} |",
            pairs
                .iter()
                .map(|(a, _)| a.name.as_str())
                .collect::<Vec<_>>()
                .join(" | ")
        );
        let _ = writeln!(md, "|---|---|{}", "---|".repeat(pairs.len()));
        // Per seed, so both means are over the same starts: the seeds where both walked.
        let rmse_by_seed = |m: &str, (sc, v): &(String, f64)| -> BTreeMap<u64, f64> {
            rows.iter()
                .filter(|r| r.method == m && &r.scenario == sc && (r.speed_mps - v).abs() < 1e-9)
                .filter(|r| !r.fell)
                .filter_map(|r| r.vel_rmse_mps.map(|e| (r.seed, e)))
                .collect()
        };
        let mut worst: Option<f64> = None;
        for c in &cats {
            let ratios: Vec<String> = pairs
                .iter()
                .map(|(a, b)| {
                    let (k, g) = (rmse_by_seed(&a.name, c), rmse_by_seed(&b.name, c));
                    let both: Vec<(f64, f64)> = k
                        .iter()
                        .filter_map(|(s, e)| g.get(s).map(|f| (*e, *f)))
                        .collect();
                    let (sk, sg) = both
                        .iter()
                        .fold((0.0, 0.0), |(x, y), (e, f)| (x + e, y + f));
                    if both.is_empty() || sg <= 0.0 {
                        "–".into()
                    } else {
                        let r = sk / sg;
                        worst = Some(worst.map_or(r, |w: f64| w.max(r)));
                        format!("{r:.2}")
                    }
                })
                .collect();
            let _ = writeln!(md, "| {} | {:.2} | {} |", c.0, c.1, ratios.join(" | "));
        }
        if let Some(w) = worst {
            let _ = writeln!(md, "\nLargest ratio: {w:.2}.");
        }
    }
    rl_against_table(&cfg, &cats, &cell, &mut md);
    write_report(&args.out, &md, "eemp robustness")?;
    println!(
        "wrote {}/report.md, report.html, robustness.png, results.csv",
        args.out.display()
    );
    Ok(())
}
