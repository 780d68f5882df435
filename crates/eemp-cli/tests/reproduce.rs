//! `eemp reproduce`: the pipeline file names every file its stages read, the study is closed and
//! `--list` sums it, `--check` passes on the shipped artifacts and fails when a shipped table's
//! sweep config is edited, bad input exits 2.

use eemp_study::pipeline::{Action, Pipeline};
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn eemp(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_eemp"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

/// Every path-like string value in a TOML file (tables, policies, motions, robots).
fn referenced_files(path: &Path) -> Vec<String> {
    fn walk(v: &toml::Value, out: &mut Vec<String>) {
        match v {
            toml::Value::String(s)
                if ["tables/", "policies/", "motions/", "robots/", "profiles/"]
                    .iter()
                    .any(|p| s.starts_with(p)) =>
            {
                out.push(s.clone())
            }
            toml::Value::Array(a) => a.iter().for_each(|x| walk(x, out)),
            toml::Value::Table(t) => t.values().for_each(|x| walk(x, out)),
            _ => {}
        }
    }
    let v: toml::Value = toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let mut out = Vec::new();
    walk(&v, &mut out);
    out
}

#[test]
fn every_file_a_stage_reads_is_one_of_its_inputs() {
    let p = Pipeline::load(&repo().join("reproduce.toml")).unwrap();
    let mut checked = 0;
    for s in &p.stages {
        for a in s.actions(false, None) {
            let Action::Eemp(args) = a else { continue };
            let Some(i) = args.iter().position(|a| a == "--config") else {
                continue;
            };
            let config = &args[i + 1];
            assert!(
                s.inputs.contains(config),
                "{}: {config} not an input",
                s.name
            );
            for f in referenced_files(&repo().join(config)) {
                let covered = s
                    .inputs
                    .iter()
                    .any(|i| &f == i || f.starts_with(&format!("{i}/")));
                // A suite's robot comes from --robot; a robot file a robot file names is its own.
                let robot_of_suite = f.starts_with("robots/") && args.contains(&f);
                assert!(
                    covered || robot_of_suite,
                    "stage '{}' reads {f} (named in {config}) but does not list it as an input",
                    s.name
                );
                assert!(
                    repo().join(&f).exists(),
                    "{config} names {f}, which is missing"
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 30, "{checked}");
}

#[test]
fn the_study_is_closed_and_list_sums_it() {
    let p = Pipeline::load(&repo().join("reproduce.toml")).unwrap();
    let study: Vec<_> = p.stages.iter().filter(|s| s.is_study()).collect();
    // Every artifact of some stage that a study stage reads is made by a study stage, or named a
    // shipped input (a parent checkpoint, an earlier variant): the study's stages alone
    // regenerate it from the pipeline's sources and those files.
    for s in &study {
        for i in s.inputs.iter().filter(|i| !s.shipped_inputs.contains(i)) {
            if let Some(m) = p.maker_of(i) {
                assert!(
                    m.is_study(),
                    "study stage '{}' reads {i}, made by the experiment '{}'",
                    s.name,
                    m.name
                );
            }
        }
    }
    // What the paper's page reads and the default tables are the study's.
    for out in [
        "reports/paper",
        "reports/compare",
        "reports/robustness",
        "tables/a1_trot.toml",
        "tables/a1_walk.toml",
        "tables/a1_free.toml",
        "tables/go2_trot.toml",
        "tables/go1_walk.toml",
    ] {
        assert!(p.maker_of(out).unwrap().is_study(), "{out}");
    }
    assert!(study.len() < p.stages.len(), "some stages are experiments");

    let o = eemp(&repo(), &["reproduce", "--list"]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("sweep-a1 (study, ≈ 40 min"), "{stdout}");
    assert!(stdout.contains("cmaes (experiment, "), "{stdout}");
    let minutes: f64 = study.iter().filter_map(|s| s.minutes_2_cores).sum();
    let all: f64 = p.stages.iter().filter_map(|s| s.minutes_2_cores).sum();
    assert_eq!(minutes, p.minutes_2_cores(false));
    let line = |prefix: &str| {
        stdout
            .lines()
            .find(|l| l.starts_with(prefix))
            .unwrap_or_else(|| panic!("no line '{prefix}…' in {stdout}"))
            .to_string()
    };
    let study_line = line("the study (eemp reproduce): ");
    assert!(
        study_line.contains(&format!("{} stages, {minutes:.0} min", study.len())),
        "{study_line}"
    );
    let all_line = line("with the experiments (eemp reproduce --experiments): ");
    assert!(
        all_line.contains(&format!("{} stages, {all:.0} min", p.stages.len())),
        "{all_line}"
    );
    println!("{study_line}\n{all_line}");
    // A working day on 2 cores.
    assert!(minutes <= 360.0, "the study takes {minutes} min");
}

#[test]
fn a_plain_run_makes_the_study_and_experiments_run_on_request() {
    let d = tempfile::tempdir().unwrap();
    let root = d.path();
    std::fs::create_dir_all(root.join("robots")).unwrap();
    std::fs::copy(repo().join("robots/a1.toml"), root.join("robots/a1.toml")).unwrap();
    let stage = |name: &str, kind: &str| {
        format!(
            "[[stage]]\nname = \"{name}\"\nkind = \"{kind}\"\nabout = \"x\"\n\
             inputs = [\"robots/a1.toml\"]\noutputs = [\"{name}.toml\"]\nminutes_2_cores = 1\n\
             [[stage.step]]\ncopy = [\"robots/a1.toml\", \"{name}.toml\"]\n"
        )
    };
    std::fs::write(
        root.join("p.toml"),
        format!(
            "sources = [\"robots\"]\n{}{}",
            stage("made", "study"),
            stage("tried", "experiment")
        ),
    )
    .unwrap();
    let run = |args: &[&str]| {
        let mut all = vec!["reproduce", "--pipeline", "p.toml", "--out", "."];
        all.extend(args);
        let o = eemp(root, &all);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let stdout = run(&[]);
    assert!(
        stdout.contains("the study: 1 stage(s)") && stdout.contains("--experiments adds the 1"),
        "{stdout}"
    );
    assert!(root.join("made.toml").exists() && !root.join("tried.toml").exists());
    let stdout = run(&["--stage", "tried"]);
    assert!(stdout.contains("[tried] done"), "{stdout}");
    std::fs::remove_file(root.join("tried.toml")).unwrap();
    let stdout = run(&["--all"]);
    assert!(
        stdout.contains("[made] up to date") && stdout.contains("[tried] done"),
        "{stdout}"
    );
    // --check looks at every stage.
    let o = eemp(root, &["reproduce", "--pipeline", "p.toml", "--check"]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && stdout.contains("ok     made") && stdout.contains("ok     tried"),
        "{stdout}"
    );
}

fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.path().is_dir() {
            copy_tree(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), &target).unwrap();
        }
    }
}

#[test]
fn check_passes_on_the_shipped_artifacts_and_fails_when_a_sweep_config_changes() {
    let o = eemp(&repo(), &["reproduce", "--check"]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(stdout.contains("ok     sweep-a1"), "{stdout}");

    // The same on a copy, with the A1 sweep's config edited: its stage is stale, exit 1.
    let d = tempfile::tempdir().unwrap();
    let root = d.path();
    let p = Pipeline::load(&repo().join("reproduce.toml")).unwrap();
    std::fs::copy(repo().join("reproduce.toml"), root.join("reproduce.toml")).unwrap();
    copy_tree(&repo().join("manifests"), &root.join("manifests"));
    let stage = p.stage("sweep-a1").unwrap();
    for f in stage.inputs.iter().chain(&stage.outputs) {
        let (from, to) = (repo().join(f), root.join(f));
        if from.is_dir() {
            copy_tree(&from, &to);
        } else {
            std::fs::create_dir_all(to.parent().unwrap()).unwrap();
            std::fs::copy(&from, &to).unwrap();
        }
    }
    let check = |root: &Path| eemp(root, &["reproduce", "--check", "--stage", "sweep-a1"]);
    assert!(check(root).status.success());
    let cfg = root.join("sweeps/paper.toml");
    let text = std::fs::read_to_string(&cfg).unwrap();
    let edited: String = text
        .lines()
        .map(|l| match l.starts_with("seeds =") {
            true => "seeds = [0, 1]\n".to_string(),
            false => format!("{l}\n"),
        })
        .collect();
    assert_ne!(edited, text, "the sweep config has a seeds line");
    std::fs::write(&cfg, edited).unwrap();
    let o = check(root);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(1), "{stdout}");
    assert!(stdout.contains("STALE  sweep-a1"), "{stdout}");
    assert!(
        stdout.contains("input sweeps/paper.toml changed since"),
        "{stdout}"
    );
}

#[test]
fn bad_input_names_the_stage_shard_or_file_and_writes_nothing() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("out");
    let outs = out.to_str().unwrap();
    for (args, says) in [
        (
            vec!["reproduce", "--out", outs, "--stage", "sweeps"],
            "unknown stage 'sweeps'",
        ),
        (
            vec!["reproduce", "--out", outs, "--shard", "4/3"],
            "--shard '4/3': expected K/N with 1 ≤ K ≤ N",
        ),
        (
            vec![
                "reproduce",
                "--out",
                outs,
                "--stage",
                "teleop",
                "--shard",
                "1/2",
            ],
            "none of the selected stages is shardable",
        ),
        (
            vec!["reproduce", "--out", outs, "--merge-shards", "0"],
            "--merge-shards 0 is out of range",
        ),
        (
            vec![
                "reproduce",
                "--out",
                outs,
                "--experiments",
                "--stage",
                "compare",
            ],
            "cannot be used with",
        ),
        (
            vec![
                "reproduce",
                "--out",
                outs,
                "--stage",
                "compare",
                "--merge-shards",
                "2",
            ],
            "has no shard folder",
        ),
        (
            vec![
                "reproduce",
                "--out",
                outs,
                "--stage",
                "teleop",
                "--merge-shards",
                "2",
            ],
            "none of the selected stages is shardable",
        ),
    ] {
        let o = eemp(&repo(), &args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?}: nothing written");
    }
    // A manifest that does not parse, and a stage whose inputs are missing.
    let root = d.path().join("root");
    std::fs::create_dir_all(root.join("manifests")).unwrap();
    std::fs::copy(repo().join("reproduce.toml"), root.join("reproduce.toml")).unwrap();
    std::fs::write(root.join("manifests/teleop.toml"), "stage = [").unwrap();
    let o = eemp(&root, &["reproduce", "--check", "--stage", "teleop"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("manifests/teleop.toml: not a manifest"),
        "{err}"
    );
    std::fs::write(
        root.join("lonely.toml"),
        "sources = []\n[[stage]]\nname = \"s\"\nabout = \"a\"\ninputs = [\"tables/none.toml\"]\n\
         outputs = [\"reports/x\"]\n[[stage.step]]\nrun = [\"model\"]\n",
    )
    .unwrap();
    let o = eemp(
        &root,
        &["reproduce", "--pipeline", "lonely.toml", "--out", outs],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("stage 's' reads tables/none.toml, which neither"),
        "{err}"
    );
    assert!(!out.exists(), "nothing written");
}

#[test]
fn a_stage_whose_inputs_or_code_changed_or_that_is_forced_after_finishing_starts_afresh() {
    let d = tempfile::tempdir().unwrap();
    let root = d.path();
    std::fs::create_dir_all(root.join("robots")).unwrap();
    std::fs::create_dir_all(root.join("src")).unwrap();
    std::fs::write(root.join("src/lib.rs"), "// the controller\n").unwrap();
    std::fs::copy(repo().join("robots/a1.toml"), root.join("robots/a1.toml")).unwrap();
    std::fs::write(
        root.join("p.toml"),
        r#"
sources = ["robots"]

[[stage]]
name = "model"
about = "the A1's model"
inputs = ["robots/a1.toml"]
code = ["src"]
outputs = ["copied.toml"]
[[stage.step]]
run = ["model", "--robot", "robots/a1.toml"]
[[stage.step]]
copy = ["robots/a1.toml", "copied.toml"]
"#,
    )
    .unwrap();
    let run = || {
        let o = eemp(
            root,
            &["reproduce", "--pipeline", "p.toml", "--out", ".", "--force"],
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    run();
    // --force on a finished stage runs it from scratch (a resumable step would only copy the
    // finished results again)…
    let marker = root.join("out/reproduce/model/partial-work");
    std::fs::write(&marker, "").unwrap();
    let stdout = run();
    assert!(
        stdout.contains("--force") && stdout.contains("afresh"),
        "{stdout}"
    );
    assert!(!marker.exists());
    // …but work left by a run that was killed (not marked finished) is resumed while the
    // inputs hold…
    std::fs::write(&marker, "").unwrap();
    let finished = root.join("out/reproduce/.inputs/model.finished");
    assert!(finished.exists());
    std::fs::remove_file(&finished).unwrap();
    assert!(!run().contains("afresh"));
    assert!(marker.exists());
    // …and dropped once an input changed: it was made with the old robot file.
    let robot = root.join("robots/a1.toml");
    let text = std::fs::read_to_string(&robot).unwrap();
    std::fs::write(&robot, format!("{text}\n# edited\n")).unwrap();
    let stdout = run();
    assert!(
        stdout.contains("its inputs changed") && stdout.contains("starting it afresh"),
        "{stdout}"
    );
    assert!(!marker.exists());
    // A killed run does not resume under changed code either: its finished rows were made by
    // the earlier controller.
    std::fs::write(&marker, "").unwrap();
    std::fs::remove_file(&finished).unwrap();
    std::fs::write(root.join("src/lib.rs"), "// the controller, changed\n").unwrap();
    let stdout = run();
    assert!(
        stdout.contains("the code it runs changed") && stdout.contains("starting it afresh"),
        "{stdout}"
    );
    assert!(!marker.exists());
}
