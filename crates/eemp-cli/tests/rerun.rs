//! `eemp walk --rerun FILE.rrd`: recorded through Python's rerun-sdk (`$EEMP_PYTHON`, the
//! repository's .venv), and by Rerun's Rust SDK in a build with `--features rerun`.

use std::process::Command;

#[test]
fn a_walk_records_to_rerun_and_says_so_in_its_summary() {
    let Some(python) = eemp_viz::testing::python() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let rrd = dir.path().join("walk.rrd");
    let out = dir.path().join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_eemp"))
        .args([
            "walk",
            "--gait",
            "free",
            "--speed",
            "0.3",
            "--duration",
            "2",
            "--rerun-hz",
            "50",
        ])
        .arg("--rerun")
        .arg(&rrd)
        .arg("--out")
        .arg(&out)
        .env("EEMP_PYTHON", &python)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let r = &summary["rerun"];
    assert_eq!(r["frames"], 100, "{r}");
    assert_eq!(r["dropped"], 0, "{r}");
    assert_eq!(r["flushed"], true, "{r}");
    let by = r["recorder"].as_str().unwrap();
    assert!(
        by.contains(if cfg!(feature = "rerun") {
            "Rust SDK"
        } else {
            "Python"
        }),
        "{by}"
    );
    assert!(std::fs::metadata(&rrd).unwrap().len() > 10_000);
}

#[test]
fn a_recording_that_cannot_be_made_stops_the_walk_before_it_starts() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    for (flag, value, says) in [
        (
            "--rerun",
            dir.path().join("no/such/walk.rrd").display().to_string(),
            "cannot write the recording",
        ),
        (
            "--rerun",
            dir.path().join("walk.txt").display().to_string(),
            "must end in .rrd",
        ),
        (
            "--rerun-hz",
            "0".to_string(),
            "--rerun-hz 0 is out of range",
        ),
    ] {
        let mut c = Command::new(env!("CARGO_BIN_EXE_eemp"));
        c.args(["walk", "--duration", "1", flag, &value]);
        if flag == "--rerun-hz" {
            c.arg("--rerun").arg(dir.path().join("ok.rrd"));
        }
        let o = c.arg("--out").arg(&out).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{flag} {value}: {err}");
        assert!(err.contains(says), "{flag} {value}: {err}");
        assert!(!out.exists(), "{flag} {value}: nothing written");
    }
    // A Python that is not there, and one that ends without opening the recording (as one
    // without rerun-sdk would): refused before the walk, saying how to record.
    let silent = dir.path().join("silent-python");
    std::fs::write(&silent, "#!/bin/sh\nexit 0\n").unwrap();
    let mut perms = std::fs::metadata(&silent).unwrap().permissions();
    std::os::unix::fs::PermissionsExt::set_mode(&mut perms, 0o755);
    std::fs::set_permissions(&silent, perms).unwrap();
    for (python, says) in [
        (dir.path().join("no/python3"), "cannot run the Python"),
        (silent, "ended before opening the recording"),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_eemp"))
            .args(["walk", "--duration", "1"])
            .env("EEMP_PYTHON", &python)
            .arg("--rerun")
            .arg(dir.path().join("py.rrd"))
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{}: {err}", python.display());
        assert!(err.contains(says), "{}: {err}", python.display());
        assert!(err.contains("pip install rerun-sdk==0.36.3"), "{err}");
        assert!(!out.exists(), "{}: nothing written", python.display());
        assert!(
            !dir.path().join("py.rrd").exists(),
            "{}: no empty recording left",
            python.display()
        );
    }
}

#[test]
fn a_replay_simulates_the_walk_again_and_records_its_geometry_when_the_trace_matches() {
    let Some(python) = eemp_viz::testing::python() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let walk = dir.path().join("walk");
    let o = Command::new(env!("CARGO_BIN_EXE_eemp"))
        .args([
            "walk",
            "--gait",
            "free",
            "--speed",
            "0.3",
            "--duration",
            "1.5",
        ])
        .arg("--out")
        .arg(&walk)
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let replay = |rrd: &str, extra: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_eemp"))
            .arg("replay")
            .arg(&walk)
            .args(["--rerun", rrd, "--rerun-hz", "50"])
            .args(extra)
            .env("EEMP_PYTHON", &python)
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (
            String::from_utf8_lossy(&o.stdout).to_string(),
            String::from_utf8_lossy(&o.stderr).to_string(),
            std::fs::metadata(dir.path().join(rrd)).unwrap().len(),
        )
    };
    let (out, _, full) = replay("full.rrd", &[]);
    assert!(out.contains("the same trace byte for byte"), "{out}");
    let (_, _, trace_only) = replay("trace.rrd", &["--from-trace"]);
    assert!(
        full > trace_only,
        "geometry and forces: {full} vs {trace_only} bytes"
    );
    // A trace that is not what the walk gives: the replay says so and records the trace.
    let t = walk.join("trace.csv");
    let text = std::fs::read_to_string(&t).unwrap();
    // The first row's last joint angle, one digit longer.
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    lines[1].push('1');
    std::fs::write(&t, lines.join("\n") + "\n").unwrap();
    let (_, err, _) = replay("edited.rrd", &[]);
    assert!(err.contains("does not give the same trace again"), "{err}");
}
