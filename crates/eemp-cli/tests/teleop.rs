//! A scripted teleoperation session (forward, stop, turn, sideways, stop) runs headless on the
//! Kalman filter without a fall, and its commands are tracked.

use std::path::Path;
use std::process::Command;

#[test]
fn a_scripted_teleop_session_runs_headless_without_a_fall() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let out = std::env::temp_dir().join(format!("eemp-teleop-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let o = Command::new(env!("CARGO_BIN_EXE_eemp"))
        .current_dir(&repo)
        .args([
            "teleop",
            "--commands",
            "scripts/teleop/session.toml",
            "--headless",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["fell"], false, "{s}");
    assert_eq!(s["source"], "script");
    for (key, max) in [
        ("rmse_vx_mps", 0.1),
        ("rmse_vy_mps", 0.1),
        ("rmse_yaw_rate_rps", 0.1),
    ] {
        let v = s[key].as_f64().unwrap();
        assert!(v < max, "{key} = {v}");
    }
    // Forward 0.4 m/s for ~4 s, then 0.2 m/s while turning: it got somewhere.
    assert!(s["distance_m"].as_f64().unwrap() > 1.0, "{s}");
    assert!(out.join("teleop.png").exists() && out.join("trace.csv").exists());
    // The shaped command never jumps faster than the slew limits (1 m/s², 2 rad/s²).
    let trace = std::fs::read_to_string(out.join("trace.csv")).unwrap();
    let rows: Vec<Vec<f64>> = trace
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|c| c.parse().unwrap()).collect())
        .collect();
    for w in rows.windows(2) {
        let dt = w[1][0] - w[0][0];
        assert!((w[1][1] - w[0][1]).abs() <= 1.0 * dt + 1e-3);
        assert!((w[1][3] - w[0][3]).abs() <= 2.0 * dt + 1e-3);
    }
}

fn teleop(args: &[&str], out: &Path) -> std::process::Output {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    Command::new(env!("CARGO_BIN_EXE_eemp"))
        .current_dir(&repo)
        .arg("teleop")
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

fn summary(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
}

/// The operator drives the walk's own run description: a run file's floor, gait and sensing
/// hold, its command is replaced (and said so), and a learned controller can be driven too.
#[test]
fn teleop_drives_a_run_file_or_a_learned_controller() {
    let d = tempfile::tempdir().unwrap();
    let run = d.path().join("run.toml");
    std::fs::write(
        &run,
        "gait = \"free\"\nspeed_mps = 0.5\nfloor_friction = 0.5\n[sensing]\nestimator = \"kf\"\nseed = 2\n",
    )
    .unwrap();
    let script = ["--commands", "scripts/teleop/session.toml", "--headless"];
    let out = d.path().join("run");
    let o = teleop(
        &[
            &script[..],
            &["--duration", "4", "--run", run.to_str().unwrap()],
        ]
        .concat(),
        &out,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("teleop: speed_mps of"), "{err}");
    let s = summary(&out);
    assert_eq!(
        (s["method"].as_str(), s["gait"].as_str()),
        (Some("EEMP (free)"), Some("free"))
    );
    assert_eq!(s["fell"], false, "{s}");
    // Forward at up to 0.4 m/s from 1 s: it went forward, not the run file's 0.5 m/s × 3 s.
    let dist = s["distance_m"].as_f64().unwrap();
    assert!(dist > 0.3 && dist < 1.3, "{s}");

    let out = d.path().join("policy");
    let o = teleop(
        &[
            &script[..],
            &[
                "--duration",
                "3",
                "--controller",
                "model-free",
                "--policy",
                "policies/a1_model_free_omni.safetensors",
            ],
        ]
        .concat(),
        &out,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = summary(&out);
    assert_eq!(s["method"], "model-free RL");
    assert!(s["gait"].is_null(), "{s}");

    // The run file stands in for the options it holds; a bad one is named.
    let refused = |args: &[&str], says: &str| {
        let out = d.path().join("refused");
        let o = teleop(&[&script[..], args].concat(), &out);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(says), "{says}: {err}");
        assert!(!out.exists(), "nothing written");
    };
    refused(
        &["--run", run.to_str().unwrap(), "--gait", "walk"],
        "cannot be used with",
    );
    let bad = d.path().join("bad.toml");
    std::fs::write(&bad, "floor_friction = 7.0\n").unwrap();
    refused(&["--run", bad.to_str().unwrap()], "7");
    refused(&["--controller", "eemp-rl"], "needs --policy");
}
