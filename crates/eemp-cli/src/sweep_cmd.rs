//! `eemp sweep`: the parameter study (EEMP-Analytical). Run a grid (or a shard of it), merge
//! shard folders, write the report.

use eemp_study::merge::merge;
use eemp_study::{run_sweep, simulator, ProgressMode, Shard, SweepConfig, SweepOptions};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
#[command(
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true,
    after_help = "Run again with the same arguments to resume after a kill: finished runs are \
                  kept, the rest are run. See sweeps/*.toml for the file format."
)]
pub struct SweepArgs {
    #[command(subcommand)]
    pub action: Option<SweepAction>,
    /// Sweep file (TOML: [grid] axes, optional [selection]); e.g. sweeps/paper.toml.
    #[arg(long, required = true)]
    pub config: Option<PathBuf>,
    /// Sweep folder: sweep.toml, results.csv (one row per run), sessions.csv.
    #[arg(long, required = true)]
    pub out: Option<PathBuf>,
    /// Run only the K-th of N disjoint slices of the run list (1-based), e.g. 3/8.
    #[arg(long)]
    pub shard: Option<String>,
    /// Worker threads (default: every core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// The same study at a small scale, to check a pipeline (`eemp reproduce --quick`): the
    /// ends of the speed and swing-time axes, the first value of the others, one seed, 3 s runs.
    #[arg(long)]
    pub quick: bool,
}

#[derive(clap::Subcommand, Debug)]
pub enum SweepAction {
    /// Combine shard folders of one grid into one sweep folder.
    Merge {
        /// Shard folders (each written by `eemp sweep --shard K/N --out DIR`).
        #[arg(required = true, num_args = 1..)]
        dirs: Vec<PathBuf>,
        /// Merged folder (new, or a folder of the same grid).
        #[arg(long)]
        out: PathBuf,
    },
    /// Select the best parameters and write report.md, report.html, tables/ and figures/.
    Report {
        /// Sweep folder.
        dir: PathBuf,
        /// Also write the tables (a1_<gait>.toml) into this folder, e.g. the repository's
        /// tables/ (a stale table of a gait of this sweep without a selectable point is
        /// removed; other gaits' tables are left alone).
        #[arg(long, value_name = "DIR")]
        tables_out: Option<PathBuf>,
    },
    /// The paper's figures that do not reproduce (trot and walk gains of the per-speed table,
    /// walk/trot energy) under each modelling choice: one finished sweep folder per simulation
    /// choice (joint damping, MPC weights: settings of its grid), each analysed under three CoT
    /// definitions and three constants. Writes report.md, report.html, sensitivity.csv/.png.
    Sensitivity {
        /// Finished sweep folders of one grid, differing only in joint_damping_nms and
        /// mpc_weights; the first is the reference.
        #[arg(required = true, num_args = 1..)]
        dirs: Vec<PathBuf>,
        /// Report folder.
        #[arg(long)]
        out: PathBuf,
    },
}

pub fn run(args: &SweepArgs) -> Result<(), String> {
    match &args.action {
        Some(SweepAction::Merge { dirs, out }) => {
            let s = merge(dirs, out).map_err(|e| e.to_string())?;
            for p in &s.partial_lines {
                eprintln!(
                    "note: ignored a partial last line in {} (an interrupted run)",
                    p.display()
                );
            }
            println!(
                "merged {} folder(s) into {}: {} runs, {} duplicate(s) kept once, {} failed-run \
                 row(s) replaced by another row of the run, {} run(s) of the grid missing",
                s.inputs,
                out.display(),
                s.rows,
                s.duplicates,
                s.superseded_failures,
                s.missing
            );
            Ok(())
        }
        Some(SweepAction::Report { dir, tables_out }) => {
            let written = crate::sweep_report::write_report(dir, tables_out.as_deref())?;
            println!("wrote {}", written.join(", "));
            Ok(())
        }
        Some(SweepAction::Sensitivity { dirs, out }) => {
            let written = crate::sensitivity_report::write(dirs, out)?;
            println!("wrote {}", written.join(", "));
            Ok(())
        }
        None => sweep(args),
    }
}

fn sweep(args: &SweepArgs) -> Result<(), String> {
    let (Some(config_path), Some(out)) = (&args.config, &args.out) else {
        return Err("--config FILE and --out DIR are required".into());
    };
    // Everything is checked before the folder is touched.
    let shard: Option<Shard> = args
        .shard
        .as_deref()
        .map(str::parse)
        .transpose()
        .map_err(|e: eemp_study::StudyError| e.to_string())?;
    if args.threads == Some(0) {
        return Err("--threads 0 is out of range: allowed 1 or more".into());
    }
    let mut config = SweepConfig::load(config_path).map_err(|e| e.to_string())?;
    if args.quick {
        config = config.quick();
    }
    let options = SweepOptions {
        threads: args.threads,
        shard,
        progress: ProgressMode::Auto,
    };
    let s =
        run_sweep(&config, out, &options, simulator(&config.grid)).map_err(|e| e.to_string())?;
    if let Some((bytes, reason)) = &s.repaired {
        eprintln!(
            "note: cut {bytes} byte(s) from the end of {} ({reason}): that run is done again",
            s.results.display()
        );
    }
    if s.dropped_failed > 0 {
        eprintln!(
            "note: removed {} row(s) of failed runs from {}: those runs were tried again",
            s.dropped_failed,
            s.results.display()
        );
    }
    if s.selection_updated {
        eprintln!("note: [selection] changed; the folder's sweep.toml now holds the new one");
    }
    let scope = shard.map_or("grid".into(), |k| format!("shard {k}"));
    println!(
        "{scope}: {} runs, {} already done, {} run now ({} fell, {} failed) in {:.1} s on {} \
         thread(s): {:.2} runs/s; results in {}",
        s.total,
        s.already_done,
        s.ran,
        s.fell,
        s.failed,
        s.elapsed_s,
        s.threads,
        s.runs_per_s(),
        s.results.display()
    );
    if shard.is_none() {
        println!("next: eemp sweep report {}", out.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(subcommand)]
        command: Command,
    }

    #[derive(clap::Subcommand)]
    enum Command {
        Sweep(SweepArgs),
    }

    fn parse(args: &[&str]) -> Result<SweepArgs, clap::Error> {
        let mut all = vec!["eemp", "sweep"];
        all.extend(args);
        Cli::try_parse_from(all).map(|c| match c.command {
            Command::Sweep(a) => a,
        })
    }

    #[test]
    fn arguments_parse_for_run_merge_and_report() {
        let a = parse(&["--config", "s.toml", "--out", "d", "--shard", "2/4"]).unwrap();
        assert!(a.action.is_none());
        assert_eq!(a.shard.as_deref(), Some("2/4"));
        assert_eq!(a.threads, None);
        let a = parse(&["merge", "a", "b", "--out", "m"]).unwrap();
        match a.action {
            Some(SweepAction::Merge { dirs, out }) => {
                assert_eq!(dirs, vec![PathBuf::from("a"), PathBuf::from("b")]);
                assert_eq!(out, PathBuf::from("m"));
            }
            other => panic!("{other:?}"),
        }
        let a = parse(&["report", "d"]).unwrap();
        assert!(matches!(
            a.action,
            Some(SweepAction::Report {
                tables_out: None,
                ..
            })
        ));
        let a = parse(&["report", "d", "--tables-out", "tables"]).unwrap();
        match a.action {
            Some(SweepAction::Report { dir, tables_out }) => {
                assert_eq!(dir, PathBuf::from("d"));
                assert_eq!(tables_out, Some(PathBuf::from("tables")));
            }
            other => panic!("{other:?}"),
        }
        assert!(parse(&["--config", "s.toml"]).is_err(), "--out is required");
        assert!(parse(&["merge", "--out", "m"]).is_err(), "no input folders");
    }

    #[test]
    fn bad_config_shard_or_threads_fail_before_anything_is_written() {
        let tmp = std::env::temp_dir().join(format!("eemp-sweep-cmd-{}", std::process::id()));
        std::fs::create_dir_all(&tmp).unwrap();
        let good = tmp.join("good.toml");
        let text = std::fs::read_to_string(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../sweeps/smoke.toml"),
        )
        .unwrap();
        std::fs::write(&good, &text).unwrap();
        let bad = tmp.join("bad.toml");
        std::fs::write(
            &bad,
            text.replace("swing_time_s = [0.20, 0.25]", "swing_time_s = [0.20, 0.35]"),
        )
        .unwrap();
        let out = tmp.join("out");
        let args = |config: &PathBuf, shard: Option<&str>, threads: Option<usize>| SweepArgs {
            action: None,
            config: Some(config.clone()),
            out: Some(out.clone()),
            shard: shard.map(String::from),
            threads,
            quick: false,
        };
        let cases = [
            (
                args(&bad, None, None),
                vec!["bad.toml", "grid.swing_time_s[1]", "[0.1, 0.25]"],
            ),
            (args(&good, Some("0/3"), None), vec!["--shard 0/3", "1..=3"]),
            (args(&good, Some("3"), None), vec!["--shard 3", "K/N"]),
            (args(&good, None, Some(0)), vec!["--threads 0"]),
            (
                args(&tmp.join("missing.toml"), None, None),
                vec!["missing.toml"],
            ),
        ];
        for (a, needles) in cases {
            let err = run(&a).unwrap_err();
            for n in needles {
                assert!(err.contains(n), "'{n}' not in: {err}");
            }
            assert!(!out.exists(), "nothing may be written: {err}");
        }
        std::fs::remove_dir_all(&tmp).unwrap();
    }
}
