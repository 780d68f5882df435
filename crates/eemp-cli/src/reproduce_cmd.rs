//! `eemp reproduce`: the whole study from `reproduce.toml`, stage by stage (each resumable,
//! skipped when its manifest says it is up to date), the experiments on request, and `--check`
//! of the shipped artifacts.

use eemp_study::pipeline::{
    check_stage, hash_all, parse_shard, Action, Manifest, Pipeline, Stage, StageCheck, StageKind,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Debug)]
#[command(
    after_help = "Stages, their inputs, outputs and commands: reproduce.toml (docs/reproduce.md). \
                        Kill and run again to resume: every stage's commands keep their finished work."
)]
pub struct ReproduceArgs {
    /// The root to (re)generate, laid out as the repository: `.` regenerates the shipped
    /// artifacts in place; a new folder gets a copy of the configs first.
    #[arg(long, required_unless_present_any = ["check", "list", "record", "write_report"])]
    pub out: Option<PathBuf>,
    /// Only these stages (repeatable; of the study or experiments), in pipeline order; artifacts
    /// of earlier stages they read are copied from the repository when the root has none.
    /// Without it: the study's stages (`kind = "study"`), with --experiments all of them.
    #[arg(long = "stage", value_name = "NAME")]
    pub stages: Vec<String>,
    /// Run the experiments too (the stages with `kind = "experiment"`: earlier policy variants,
    /// ablations), after the study's stages they follow in the pipeline. --check, --list and
    /// --record cover every stage without it.
    #[arg(long, visible_alias = "all", conflicts_with = "stages")]
    pub experiments: bool,
    /// The same pipeline at a small scale (short sweeps and trainings, one seed, short runs):
    /// checks that it works end to end; its manifests say `quick = true`.
    #[arg(long)]
    pub quick: bool,
    /// Run only the K-th of N slices of the shardable stages' long steps (sweeps and suites),
    /// into `out/reproduce/<stage>.shard-K-of-N`; merge (`eemp sweep merge`, or the suite's
    /// command with `--merge-from`), then run the stage (`scripts/reproduce-slurm.sh`).
    #[arg(long, value_name = "K/N")]
    pub shard: Option<String>,
    /// Before running, gather the N shard folders of every selected shardable stage (written
    /// by `--shard K/N`, K = 1…N) into the folder its full step writes; then run as usual.
    #[arg(long, value_name = "N", conflicts_with = "shard")]
    pub merge_shards: Option<usize>,
    /// List the artifacts whose inputs changed since their manifest (in --out, default `.`) and
    /// exit with status 1 if any did (`--record` and `--check` work on `.` without --out).
    #[arg(long)]
    pub check: bool,
    /// With --check: a change of the code that made an artifact counts too.
    #[arg(long, requires = "check")]
    pub strict: bool,
    /// Run the selected stages even when they are up to date, from scratch (a finished run's
    /// scratch folder is emptied; a run that was killed resumes, unless its inputs or code
    /// changed since).
    #[arg(long, conflicts_with = "check")]
    pub force: bool,
    /// List the stages and what they make.
    #[arg(long, conflicts_with = "check")]
    pub list: bool,
    /// Write manifests for artifacts already made by the stages' commands (by hand), from the
    /// inputs as they are now (`made_by = "recorded"`, no code version): for adopting them.
    #[arg(long, conflicts_with_all = ["check", "force", "quick", "shard"])]
    pub record: bool,
    /// Write reports/paper (report.md, report.html, figures/) in the root from the stages'
    /// reports and manifests: the pipeline's last stage.
    #[arg(long, conflicts_with_all = ["check", "force", "quick", "shard", "record", "list"])]
    pub write_report: bool,
    /// The pipeline file.
    #[arg(long, default_value = "reproduce.toml")]
    pub pipeline: PathBuf,
}

/// `Ok(false)`: `--check` found stale artifacts (exit status 1).
pub fn run(args: &ReproduceArgs) -> Result<bool, String> {
    let pipeline = Pipeline::load(&args.pipeline).map_err(|e| e.to_string())?;
    let repo = args
        .pipeline
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
        .to_path_buf();
    // Running regenerates the study unless told otherwise; looking (--check, --list, --record)
    // covers every stage.
    let every_stage = args.experiments || args.check || args.list || args.record;
    let stages = pipeline
        .select(&args.stages, every_stage)
        .map_err(|e| e.to_string())?;
    let shard = args.shard.as_deref().map(parse_shard).transpose()?;
    if args.merge_shards == Some(0) {
        return Err("--merge-shards 0 is out of range: allowed ≥ 1".into());
    }
    if args.list {
        list(&pipeline, &stages);
        return Ok(true);
    }
    let root = args.out.clone().unwrap_or_else(|| PathBuf::from("."));
    if args.check {
        return check(&root, &repo, &stages, args.strict);
    }
    if args.write_report {
        let written = crate::paper_report::write(&root, &pipeline, &root.join("reports/paper"))?;
        println!("wrote {}", written.join(", "));
        return Ok(true);
    }
    if args.record {
        return record(&root, &repo, &stages).map(|_| true);
    }
    if let Some((k, n)) = shard {
        if !stages.iter().any(|s| s.shardable()) {
            return Err(format!(
                "--shard {k}/{n}: none of the selected stages is shardable (shardable: {})",
                names(pipeline.stages.iter().filter(|s| s.shardable()))
            ));
        }
    }
    if let Some(n) = args.merge_shards {
        if !stages.iter().any(|s| s.shardable()) {
            return Err(format!(
                "--merge-shards {n}: none of the selected stages is shardable (shardable: {})",
                names(pipeline.stages.iter().filter(|s| s.shardable()))
            ));
        }
        for stage in stages.iter().filter(|s| s.shardable()) {
            if let Some(missing) = stage
                .shard_outputs(args.quick, n)
                .into_iter()
                .find(|d| !root.join(d).is_dir())
            {
                return Err(format!(
                    "--merge-shards {n}: stage '{}' has no shard folder {} (run --shard K/{n} \
                     for every K first)",
                    stage.name,
                    root.join(&missing).display()
                ));
            }
        }
    }
    prepare_root(&root, &repo, &pipeline, &stages)?;
    if args.stages.is_empty() {
        let experiments = pipeline.stages.iter().filter(|s| !s.is_study()).count();
        let (what, more) = match (args.experiments, experiments) {
            (true, _) => ("the study and the experiments", String::new()),
            (false, 0) => ("the study", String::new()),
            (false, n) => (
                "the study",
                format!("; --experiments adds the {n} experiments"),
            ),
        };
        println!(
            "{what}: {} stage(s), ≈ {:.1} h on 2 cores{more}",
            stages.len(),
            pipeline.minutes_2_cores(args.experiments) / 60.0
        );
    }
    let mut timings = Vec::new();
    for stage in &stages {
        if let Some((k, n)) = shard {
            if !stage.shardable() {
                println!("[{}] not shardable: skipped under --shard", stage.name);
                continue;
            }
            let inputs = hash_all(&root, &stage.inputs).map_err(|e| e.to_string())?;
            claim_work_dir(
                &root,
                stage,
                &work_digest(&repo, stage, &inputs, args.quick)?,
                Some((k, n)),
                args.force,
            )?;
            run_actions(&root, stage, &stage.actions(args.quick, Some((k, n))))?;
            mark_finished(&root, &stage.work_dir_of(Some((k, n))))?;
            println!(
                "[{}] shard {k}/{n} done; merge the shards into {} (eemp sweep merge …, or \
                 eemp compare|robustness … --merge-from …) and run this stage without --shard",
                stage.name,
                stage.work_dir()
            );
            continue;
        }
        let state = check_stage(&root, &repo, stage, args.quick).map_err(|e| e.to_string())?;
        if state.up_to_date(false) && !args.force {
            println!(
                "[{}] up to date (manifests/{}.toml)",
                stage.name, stage.name
            );
            continue;
        }
        let t0 = Instant::now();
        let actions = stage.actions(args.quick, None);
        // What the stage starts from: an input replaced while it runs (a parent policy retrained
        // beside it) leaves it stale, not up to date.
        let inputs = hash_all(&root, &stage.inputs).map_err(|e| e.to_string())?;
        let digest = work_digest(&repo, stage, &inputs, args.quick)?;
        claim_work_dir(&root, stage, &digest, None, args.force)?;
        if let (Some(n), true) = (args.merge_shards, stage.shardable()) {
            if shards_current(&root, stage, &digest, n) {
                run_actions(&root, stage, &stage.merge_actions(args.quick, n))?;
            } else {
                println!(
                    "[{}] its shards were made from other inputs: not merged, run here",
                    stage.name
                );
            }
        }
        run_actions(&root, stage, &actions)?;
        let wall_s = t0.elapsed().as_secs_f64();
        manifest(
            &root,
            &repo,
            stage,
            &actions,
            args.quick,
            Some(wall_s),
            inputs,
        )?
        .save(&root)
        .map_err(|e| e.to_string())?;
        mark_finished(&root, &stage.work_dir_of(None))?;
        println!("[{}] done in {:.0} s", stage.name, wall_s);
        timings.push((stage.name.clone(), wall_s));
    }
    if !timings.is_empty() {
        println!("\nstage wall times:");
        for (n, s) in &timings {
            println!("  {n:<24} {:>8.1} min", s / 60.0);
        }
    }
    Ok(true)
}

/// What a stage's scratch folders are stamped with: its scale, the hashes of its inputs
/// (`hash_all`) and of its code folders in the repository. A run killed and started again after
/// a code change must not resume into rows the earlier code made (a suite's finished runs are
/// kept by name, whatever made them).
fn work_digest(
    repo: &Path,
    stage: &Stage,
    inputs: &BTreeMap<String, Option<String>>,
    quick: bool,
) -> Result<String, String> {
    let lines = |hashes: &BTreeMap<String, Option<String>>| -> String {
        hashes
            .iter()
            .map(|(p, h)| format!("{p} {}\n", h.as_deref().unwrap_or("-")))
            .collect()
    };
    let code = hash_all(repo, &stage.code).map_err(|e| e.to_string())?;
    Ok(format!(
        "quick = {quick}\n{}{CODE_SECTION}{}",
        lines(inputs),
        lines(&code)
    ))
}

/// Opens the code folders' part of a work digest (an input's line ends in its hash, never so).
const CODE_SECTION: &str = "[code]\n";

/// Why the work stamped `old` is not valid for `new` (both from [`work_digest`]).
fn why_digest_differs(old: &str, new: &str) -> &'static str {
    fn inputs_part(d: &str) -> &str {
        d.split_once(CODE_SECTION).map_or(d, |(inputs, _)| inputs)
    }
    if inputs_part(old) == inputs_part(new) {
        "the code it runs changed"
    } else {
        "its inputs changed"
    }
}

/// Where the digest of the scratch folder `rel` is kept: beside the folders, not inside (a step
/// that copies `{work}` into a report must not take it along); `.digest`, so that the atomic
/// write's temporary file differs per shard too.
fn stamp_of(root: &Path, rel: &str) -> PathBuf {
    let name = Path::new(rel)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    root.join("out/reproduce/.inputs")
        .join(format!("{name}.digest"))
}

/// A stage's scratch folder (or one shard's) holds work that its steps resume, valid only for
/// the inputs and code it was started with. A folder started with other inputs, other code (the
/// stage's `code` folders) or at the other scale is emptied first, so a changed robot file,
/// config or controller never resumes into results made before the change; a folder without a digest is kept as it is. Each shard claims only its own folder.
/// `force` (a stage run although up to date, e.g. after a code change): a folder whose run
/// finished (marked so when its steps succeeded) is emptied too, or the resumable steps would
/// only copy the old results again; a run that was killed (unmarked) resumes under the same
/// inputs and code.
fn claim_work_dir(
    root: &Path,
    stage: &Stage,
    digest: &str,
    shard: Option<(usize, usize)>,
    force: bool,
) -> Result<(), String> {
    let rel = stage.work_dir_of(shard);
    let work = root.join(&rel);
    let stamp = stamp_of(root, &rel);
    let done = finished_marker(&stamp);
    let finished = done.exists();
    if let Ok(old) = std::fs::read_to_string(&stamp) {
        let why = if old != digest {
            Some(format!(
                "{} since {rel} was started",
                why_digest_differs(&old, digest)
            ))
        } else if force && finished {
            Some(format!("--force: {rel} holds a finished run"))
        } else {
            None
        };
        if let (Some(why), true) = (why, work.exists()) {
            println!("[{}] {why}: starting it afresh", stage.name);
            std::fs::remove_dir_all(&work)
                .map_err(|e| format!("cannot empty {}: {e}", work.display()))?;
        }
    }
    if finished {
        std::fs::remove_file(&done)
            .map_err(|e| format!("cannot remove {}: {e}", done.display()))?;
    }
    let stamps = stamp
        .parent()
        .expect("in out/reproduce/.inputs")
        .to_path_buf();
    for d in [&work, &stamps] {
        std::fs::create_dir_all(d).map_err(|e| format!("cannot create {}: {e}", d.display()))?;
    }
    eemp_study::store::write_atomic(&stamp, digest.as_bytes())
        .map_err(|e| format!("cannot write {}: {e}", stamp.display()))
}

/// Beside a scratch folder's digest: its steps ran to the end (removed when it is claimed again).
fn finished_marker(stamp: &Path) -> PathBuf {
    stamp.with_extension("finished")
}

fn mark_finished(root: &Path, rel: &str) -> Result<(), String> {
    let done = finished_marker(&stamp_of(root, rel));
    std::fs::write(&done, b"").map_err(|e| format!("cannot write {}: {e}", done.display()))
}

/// Whether all `n` shards of `stage` were made from its inputs as they are now (a shard of
/// older inputs must not be merged: the stage then runs unsharded).
fn shards_current(root: &Path, stage: &Stage, digest: &str, n: usize) -> bool {
    (1..=n).all(|k| {
        let rel = stage.work_dir_of(Some((k, n)));
        std::fs::read_to_string(stamp_of(root, &rel)).is_ok_and(|d| d == digest)
    })
}

fn names<'a>(stages: impl Iterator<Item = &'a Stage>) -> String {
    stages
        .map(|s| s.name.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

fn list(pipeline: &Pipeline, stages: &[&Stage]) {
    for s in stages {
        let time = s
            .minutes_2_cores
            .map(|m| format!(", ≈ {m:.0} min on 2 cores"))
            .unwrap_or_default();
        println!("{} ({}{time}): {}", s.name, s.kind().name(), s.about);
        for a in s.actions(false, None) {
            println!("    {}", a.display());
        }
        println!("    makes: {}", s.outputs.join(", "));
    }
    let count = |kind: Option<StageKind>| {
        pipeline
            .stages
            .iter()
            .filter(|s| kind.is_none_or(|k| s.kind() == k))
            .count()
    };
    for (what, experiments, n) in [
        (
            "the study (eemp reproduce)",
            false,
            count(Some(StageKind::Study)),
        ),
        (
            "with the experiments (eemp reproduce --experiments)",
            true,
            count(None),
        ),
    ] {
        let m = pipeline.minutes_2_cores(experiments);
        println!(
            "{what}: {n} stages, {m:.0} min ≈ {:.1} h on 2 cores",
            m / 60.0
        );
    }
}

fn check(root: &Path, repo: &Path, stages: &[&Stage], strict: bool) -> Result<bool, String> {
    let mut stale = 0;
    for s in stages {
        let c: StageCheck = check_stage(root, repo, s, false).map_err(|e| e.to_string())?;
        let made = c
            .manifest
            .as_ref()
            .map(|m| format!(" ({})", m.made_by))
            .unwrap_or_default();
        if c.up_to_date(strict) {
            println!("ok     {}{made}: {}", s.name, s.outputs.join(", "));
        } else {
            stale += 1;
            println!("STALE  {}{made}: {}", s.name, s.outputs.join(", "));
            for why in &c.stale {
                println!("         {why}");
            }
        }
        if !c.code_changed.is_empty() {
            println!(
                "         note: code changed since: {} ({})",
                c.code_changed.join(", "),
                if strict {
                    "counted: --strict"
                } else {
                    "not counted without --strict"
                }
            );
        }
        if c.manifest.as_ref().is_some_and(|m| m.code.is_empty()) {
            println!("         note: recorded, the code version that made it is unknown");
        }
    }
    if stale > 0 {
        println!(
            "\n{stale} of {} stage(s) stale: eemp reproduce --out {} --stage NAME regenerates one",
            stages.len(),
            root.display()
        );
    } else {
        println!(
            "\nevery artifact of the {} stage(s) matches its inputs",
            stages.len()
        );
    }
    Ok(stale == 0)
}

fn record(root: &Path, repo: &Path, stages: &[&Stage]) -> Result<(), String> {
    for s in stages {
        let missing: Vec<&String> = s
            .outputs
            .iter()
            .filter(|o| !root.join(o).exists())
            .collect();
        if !missing.is_empty() {
            return Err(format!(
                "stage '{}': cannot record, {} not made yet",
                s.name,
                missing
                    .iter()
                    .map(|m| m.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
    }
    for s in stages {
        let actions = s.actions(false, None);
        let inputs = hash_all(root, &s.inputs).map_err(|e| e.to_string())?;
        let mut m = manifest(root, repo, s, &actions, false, None, inputs)?;
        m.made_by = "recorded".into();
        m.code.clear();
        m.save(root).map_err(|e| e.to_string())?;
        println!("recorded manifests/{}.toml", s.name);
    }
    Ok(())
}

/// A new root gets the pipeline's sources, and the artifacts of unselected stages that the
/// selected ones read; nothing already in the root is overwritten. Everything is checked before
/// the root is touched.
fn prepare_root(
    root: &Path,
    repo: &Path,
    pipeline: &Pipeline,
    stages: &[&Stage],
) -> Result<(), String> {
    let same =
        root.exists() && std::fs::canonicalize(root).ok() == std::fs::canonicalize(repo).ok();
    let mut copies: Vec<(String, Option<String>)> = Vec::new();
    if !same {
        for src in &pipeline.sources {
            if !repo.join(src).exists() {
                return Err(format!(
                    "the pipeline's source {src} is missing in {}",
                    repo.display()
                ));
            }
            copies.push((src.clone(), None));
        }
    }
    for s in stages {
        for input in &s.inputs {
            let made_by_selected = pipeline
                .maker_of(input)
                .is_some_and(|m| stages.iter().any(|t| t.name == m.name));
            let from_sources = pipeline
                .sources
                .iter()
                .any(|src| input == src || input.starts_with(&format!("{src}/")));
            if made_by_selected || root.join(input).exists() || (!same && from_sources) {
                continue;
            }
            if same || !repo.join(input).exists() {
                return Err(format!(
                    "stage '{}' reads {input}, which neither {} nor the repository has{}",
                    s.name,
                    root.display(),
                    pipeline
                        .maker_of(input)
                        .map(|m| format!(" (stage '{}' makes it)", m.name))
                        .unwrap_or_default()
                ));
            }
            copies.push((input.clone(), Some(s.name.clone())));
        }
    }
    std::fs::create_dir_all(root).map_err(|e| format!("cannot create {}: {e}", root.display()))?;
    for (path, for_stage) in copies {
        copy_missing(&repo.join(&path), &root.join(&path))?;
        if let Some(stage) = for_stage {
            println!("[{stage}] using the shipped {path}");
        }
    }
    Ok(())
}

fn copy_missing(from: &Path, to: &Path) -> Result<(), String> {
    if from.is_dir() {
        for e in std::fs::read_dir(from).map_err(|e| format!("{}: {e}", from.display()))? {
            let e = e.map_err(|e| format!("{}: {e}", from.display()))?;
            copy_missing(&e.path(), &to.join(e.file_name()))?;
        }
        Ok(())
    } else if from.is_file() {
        if to.exists() {
            return Ok(());
        }
        std::fs::create_dir_all(to.parent().expect("has a parent"))
            .and_then(|_| std::fs::copy(from, to).map(|_| ()))
            .map_err(|e| format!("cannot copy {} to {}: {e}", from.display(), to.display()))
    } else {
        Err(format!("{} does not exist", from.display()))
    }
}

fn replace_with_copy(from: &Path, to: &Path) -> Result<(), String> {
    if !from.exists() {
        return Err(format!("{} was not written", from.display()));
    }
    if to.is_dir() {
        std::fs::remove_dir_all(to).map_err(|e| format!("{}: {e}", to.display()))?;
    } else if to.exists() {
        std::fs::remove_file(to).map_err(|e| format!("{}: {e}", to.display()))?;
    }
    copy_missing(from, to)
}

fn run_actions(root: &Path, stage: &Stage, actions: &[Action]) -> Result<(), String> {
    let exe = std::env::current_exe().map_err(|e| format!("cannot find eemp itself: {e}"))?;
    for a in actions {
        println!("[{}] {}", stage.name, a.display());
        match a {
            Action::Eemp(args) => {
                let status = std::process::Command::new(&exe)
                    .args(args)
                    .current_dir(root)
                    .status()
                    .map_err(|e| {
                        format!("stage '{}': cannot run {}: {e}", stage.name, a.display())
                    })?;
                if !status.success() {
                    return Err(format!(
                        "stage '{}': `{}` failed ({status}); its finished work is kept, run again \
                         to resume",
                        stage.name,
                        a.display()
                    ));
                }
            }
            Action::Copy { from, to } => replace_with_copy(&root.join(from), &root.join(to))
                .map_err(|e| format!("stage '{}': {e}", stage.name))?,
        }
    }
    Ok(())
}

fn manifest(
    root: &Path,
    repo: &Path,
    stage: &Stage,
    actions: &[Action],
    quick: bool,
    wall_s: Option<f64>,
    inputs: BTreeMap<String, Option<String>>,
) -> Result<Manifest, String> {
    let present = |what: &str, m: BTreeMap<String, Option<String>>| {
        m.into_iter()
            .map(|(p, h)| {
                h.map(|h| (p.clone(), h))
                    .ok_or_else(|| format!("stage '{}': {what} {p} is missing", stage.name))
            })
            .collect::<Result<BTreeMap<_, _>, String>>()
    };
    let e = |e: eemp_study::pipeline::PipelineError| e.to_string();
    Ok(Manifest {
        stage: stage.name.clone(),
        made_by: "eemp reproduce".into(),
        quick,
        eemp_version: env!("CARGO_PKG_VERSION").into(),
        commands: actions.iter().map(Action::display).collect(),
        wall_s,
        inputs: present("input", inputs)?,
        code: present("code folder", hash_all(repo, &stage.code).map_err(e)?)?,
        outputs: present("output", hash_all(root, &stage.outputs).map_err(e)?)?,
    })
}
