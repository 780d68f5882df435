//! `reports/paper/`: the paper's figures and claims beside the measured ones, gathered from the
//! reports the pipeline's stages wrote (each computes its own claims; this page puts them in the
//! paper's order) with the commands and manifests that made them.

use eemp_study::pipeline::{Manifest, Pipeline};
use std::fmt::Write;
use std::path::Path;

/// One part of the page: a heading, the figures and the report sections it shows.
struct Part {
    heading: &'static str,
    stage: &'static str,
    report: &'static str,
    figures: &'static [&'static str],
    sections: &'static [&'static str],
}

const PARTS: &[Part] = &[
    Part {
        heading: "Figs. 5 and 6, Table II: the parameter study (A1, trot and walk)",
        stage: "sweep-a1",
        report: "reports/paper-sweep",
        figures: &[
            "figures/fig5_cot_contours.png",
            "figures/fig6_walk_vs_trot.png",
            "figures/cot_table_vs_constant.png",
        ],
        sections: &["Paper vs this project"],
    },
    Part {
        heading: "The free gait's per-speed table (the one EEMP-Analytical and EEMP-RL use)",
        stage: "sweep-a1-free",
        report: "reports/free-sweep",
        figures: &["figures/cot_table_vs_constant.png"],
        sections: &["Paper vs this project"],
    },
    Part {
        heading: "Eq. (6) with the walk's factor 1.5",
        stage: "sweep-a1-walk-raibert",
        report: "reports/walk-raibert-sweep",
        figures: &[],
        sections: &["Paper vs this project"],
    },
    Part {
        heading: "Why the trot and walk gains and the walk's energy do not reproduce",
        stage: "sensitivity",
        report: "reports/sensitivity",
        figures: &["sensitivity.png"],
        sections: &["What moves each figure"],
    },
    Part {
        heading: "Figs. 7 and 9: EEMP against the learned controllers",
        stage: "compare",
        report: "reports/compare",
        figures: &["fig7.png", "fig9.png"],
        sections: &[
            "EEMP's lead in CoT over model-free RL under the paper's eq. 8 (net mechanical power; paper: 50.4 % at ≤ 0.6 m/s)",
            "EEMP's lead in CoT over model-free RL under the battery's energy: electrical CoT, the robot file's k, with idle power",
            "The lead under every energy definition",
            "The paper's claims, measured",
        ],
    },
    Part {
        heading: "Robustness (the paper's disturbances, on the Kalman filter)",
        stage: "robustness",
        report: "reports/robustness",
        figures: &["robustness.png"],
        sections: &["EEMP-RL against the table it learned from"],
    },
    Part {
        heading: "Fig. 10: a teleoperated session",
        stage: "teleop",
        report: "reports/teleop",
        figures: &["teleop.png"],
        sections: &[],
    },
];

/// The body of `## title` in a Markdown report (to the next `## `), if present.
fn section(md: &str, title: &str) -> Option<String> {
    let start = md
        .lines()
        .position(|l| l.strip_prefix("## ") == Some(title))?;
    let body: Vec<&str> = md
        .lines()
        .skip(start + 1)
        .take_while(|l| !l.starts_with("## "))
        .collect();
    Some(body.join("\n").trim().to_string())
}

/// Writes `out/report.md`, `out/report.html` and `out/figures/` from the reports in `root`.
pub fn write(root: &Path, pipeline: &Pipeline, out: &Path) -> Result<Vec<String>, String> {
    let figures = out.join("figures");
    std::fs::create_dir_all(&figures)
        .map_err(|e| format!("cannot create {}: {e}", figures.display()))?;
    let manifests: Vec<(String, Option<Manifest>)> = pipeline
        .stages
        .iter()
        .filter(|s| s.name != "paper")
        .map(|s| Manifest::load(root, &s.name).map(|m| (s.name.clone(), m)))
        .collect::<Result<_, _>>()
        .map_err(|e| e.to_string())?;
    let quick: Vec<&str> = manifests
        .iter()
        .filter(|(_, m)| m.as_ref().is_some_and(|m| m.quick))
        .map(|(n, _)| n.as_str())
        .collect();
    let mut md = String::from("# The paper, reproduced\n\n");
    if !quick.is_empty() {
        let _ = writeln!(
            md,
            "**QUICK SCALE** (`eemp reproduce --quick`): short sweeps and trainings, one seed, \
             short runs, in stages {}. This page checks that the pipeline runs end to end; its \
             numbers are not results.\n",
            quick.join(", ")
        );
    }
    md.push_str(
        "Each part shows the paper's figure or claim beside the one measured here, taken from the \
         report of the stage that made it (the report's own computation; follow its link for the \
         definitions). Regenerate everything: `eemp reproduce --out DIR`; one stage: \
         `eemp reproduce --out DIR --stage NAME`; check what is stale: `eemp reproduce --check`.\n\n",
    );
    for part in PARTS {
        let _ = writeln!(md, "## {}\n", part.heading);
        let report_md = root.join(part.report).join("report.md");
        let text = std::fs::read_to_string(&report_md).unwrap_or_default();
        if text.is_empty() && !part.sections.is_empty() {
            let _ = writeln!(
                md,
                "*Not made yet: stage `{}` writes {}.*\n",
                part.stage, part.report
            );
            continue;
        }
        for f in part.figures {
            let from = root.join(part.report).join(f);
            if !from.exists() {
                continue;
            }
            let name = format!(
                "{}-{}",
                part.stage,
                Path::new(f).file_name().expect("a file").to_string_lossy()
            );
            std::fs::copy(&from, figures.join(&name))
                .map_err(|e| format!("cannot copy {}: {e}", from.display()))?;
            let _ = writeln!(md, "![{}](figures/{name})\n", f);
        }
        for s in part.sections {
            match section(&text, s) {
                Some(body) => {
                    let _ = writeln!(md, "**{s}** (from `{}/report.md`)\n\n{body}\n", part.report);
                }
                None => {
                    let _ = writeln!(md, "*`{}/report.md` has no section '{s}'.*\n", part.report);
                }
            }
        }
    }
    // No wall times here (they are in the manifests): the page's bytes depend on its inputs only.
    md.push_str("## How each artifact was made\n\n| stage | made by | scale | commands |\n|---|---|---|---|\n");
    for (name, m) in &manifests {
        match m {
            Some(m) => {
                let _ = writeln!(
                    md,
                    "| {name} | {} | {} | {} |",
                    m.made_by,
                    if m.quick { "quick" } else { "full" },
                    m.commands
                        .iter()
                        .map(|c| format!("`{c}`"))
                        .collect::<Vec<_>>()
                        .join("; ")
                );
            }
            None => {
                let _ = writeln!(md, "| {name} | not made yet | | |");
            }
        }
    }
    let md_path = out.join("report.md");
    let html_path = out.join("report.html");
    std::fs::write(&md_path, &md).map_err(|e| format!("{}: {e}", md_path.display()))?;
    std::fs::write(
        &html_path,
        crate::suite_cmd::html_of(&md, "The paper, reproduced"),
    )
    .map_err(|e| format!("{}: {e}", html_path.display()))?;
    Ok(vec![
        md_path.display().to_string(),
        html_path.display().to_string(),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_section_runs_to_the_next_heading() {
        let md = "# T\n## A\none\n\ntwo\n## B\nthree\n";
        assert_eq!(section(md, "A").unwrap(), "one\n\ntwo");
        assert_eq!(section(md, "B").unwrap(), "three");
        assert_eq!(section(md, "C"), None);
    }
}
