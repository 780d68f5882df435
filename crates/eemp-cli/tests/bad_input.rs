//! Bad input to `eemp walk` / `eemp stand`: exit status 2, a message naming the value and what
//! is allowed, and nothing written.

use std::path::{Path, PathBuf};
use std::process::Command;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("eemp-bad-input-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs `eemp args… --out <dir>/out`; returns (status code, stderr, whether out exists).
fn eemp(dir: &Path, args: &[&str]) -> (Option<i32>, String, bool) {
    let out = dir.join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_eemp"))
        .args(args)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
        out.exists(),
    )
}

#[test]
fn bad_walk_and_stand_input_exits_2_names_the_value_and_writes_nothing() {
    let dir = scratch("walk");
    let bad_params = dir.join("params.toml");
    std::fs::write(
        &bad_params,
        "swing_time_s = 0.5\nstep_height_m = 0.1\nbody_height_m = 0.31\n\
         ellipse_rx_m = 0.07\nellipse_ry_m = 0.05\n",
    )
    .unwrap();
    let malformed = dir.join("profile.toml");
    std::fs::write(&malformed, "[[segment]\nstart_s = ").unwrap();
    let missing = dir.join("missing.toml");
    let p = |path: &Path| path.to_str().unwrap().to_string();
    let cases: Vec<(Vec<String>, Vec<&str>)> = vec![
        (
            vec!["walk".into(), "--gait".into(), "gallop".into()],
            vec!["gallop", "trot, walk, free"],
        ),
        (
            vec!["walk".into(), "--duration".into(), "-1".into()],
            vec!["--duration -1", "(0, 3600]"],
        ),
        (
            vec!["walk".into(), "--duration".into(), "NaN".into()],
            vec!["--duration", "(0, 3600]"],
        ),
        (
            vec!["walk".into(), "--params".into(), p(&bad_params)],
            vec!["swing_time_s", "0.5", "[0.1, 0.25]"],
        ),
        (
            vec!["walk".into(), "--params".into(), p(&missing)],
            vec!["missing.toml"],
        ),
        (
            vec!["walk".into(), "--profile".into(), p(&malformed)],
            vec!["profile.toml"],
        ),
        (
            vec!["walk".into(), "--progress-factor".into(), "3".into()],
            vec!["--progress-factor 3", "[0, 2]"],
        ),
        (
            vec!["walk".into(), "--progress-factor".into(), "-1".into()],
            vec!["--progress-factor -1", "[0, 2]"],
        ),
        (
            vec!["stand".into(), "--duration".into(), "-3".into()],
            vec!["--duration -3", "(0, 3600]"],
        ),
    ];
    for (args, needles) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let (code, stderr, wrote) = eemp(&dir, &args);
        assert_eq!(code, Some(2), "{args:?}: {stderr}");
        for n in needles {
            assert!(stderr.contains(n), "{args:?}: '{n}' not in: {stderr}");
        }
        assert!(!wrote, "{args:?} wrote its output folder");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_negative_speed_is_a_backward_command_not_an_option() {
    let dir = scratch("backward");
    let (code, stderr, wrote) = eemp(&dir, &["walk", "--speed", "-0.2", "--duration", "1"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(wrote && dir.join("out/summary.json").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
