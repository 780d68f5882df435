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
