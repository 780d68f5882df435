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

/// Each case (arguments, what the message must contain) exits 2 naming it and writes nothing.
fn assert_refused(dir: &Path, cases: &[(&[&str], &[&str])]) {
    for (args, needles) in cases {
        let (code, stderr, wrote) = eemp(dir, args);
        assert_eq!(code, Some(2), "{args:?}: {stderr}");
        for n in needles.iter() {
            assert!(stderr.contains(n), "{args:?}: '{n}' not in: {stderr}");
        }
        assert!(!wrote, "{args:?} wrote its output folder");
    }
}

#[test]
fn bad_walk_and_stand_input_exits_2_names_the_value_and_writes_nothing() {
    let dir = scratch("walk");
    let bad_params = dir.join("params.toml");
    std::fs::write(
        &bad_params,
        "swing_time_s = 1.5\nstep_height_m = 0.1\nbody_height_m = 0.31\n\
         ellipse_rx_m = 0.07\nellipse_ry_m = 0.05\n",
    )
    .unwrap();
    let malformed = dir.join("profile.toml");
    std::fs::write(&malformed, "[[segment]\nstart_s = ").unwrap();
    let missing = dir.join("missing.toml");
    let (bad_params, missing, malformed) = (
        bad_params.to_str().unwrap(),
        missing.to_str().unwrap(),
        malformed.to_str().unwrap(),
    );
    // (arguments, what the message must contain)
    let cases: [(&[&str], &[&str]); 20] = [
        (
            &["walk", "--gait", "gallop"],
            &["gallop", "trot, walk, free"],
        ),
        (
            &["walk", "--duration", "-1"],
            &["--duration -1", "(0, 3600]"],
        ),
        (&["walk", "--duration", "NaN"], &["--duration", "(0, 3600]"]),
        (
            &["walk", "--params", bad_params],
            &["swing_time_s", "1.5", "[0.05, 1]"],
        ),
        (&["walk", "--params", missing], &["missing.toml"]),
        (&["walk", "--profile", malformed], &["profile.toml"]),
        (
            &["walk", "--set", "planner.progress_factor=3"],
            &[
                "--set planner.progress_factor=3",
                "planner.progress_factor",
                "[0, 2]",
            ],
        ),
        (
            &["walk", "--set", "planner.progress_factr=1"],
            &["progress_factr", "--set planner.progress_factr=1"],
        ),
        (
            &["stand", "--duration", "-3"],
            &["--duration -3", "(0, 3600]"],
        ),
        (
            &["walk", "--set", "slip.hold_cap_after_slip=1.5"],
            &["slip.hold_cap_after_slip", "1.5", "[0, 1]"],
        ),
        (
            &["walk", "--set", "slip.hold_raise_fraction=0.05"],
            &["slip.hold_raise_fraction", "0.05", "[0.1, 1]"],
        ),
        (
            &["walk", "--set", "slip.max_speed_mps=-1"],
            &["slip.max_speed_mps", "-1", "[0, 10]"],
        ),
        (
            &[
                "walk",
                "--gait",
                "walk",
                "--set",
                "slip.slow_speed_mps=-0.3",
            ],
            &["slip.slow_speed_mps", "-0.3", "[0, 10]"],
        ),
        (
            &["walk", "--set", "slip.min_friction=0"],
            &["slip.min_friction", "0", "[0.05, 2]"],
        ),
        (
            // The walk's cap comes on below 0.205: a floor at or above it leaves it no room.
            &["walk", "--gait", "walk", "--set", "slip.min_friction=0.21"],
            &[
                "slip.slow_below_friction",
                "0.205",
                "slip.min_friction = 0.21",
            ],
        ),
        (
            // The cap lifts at 0.25: a threshold above it leaves no room to lift.
            &[
                "walk",
                "--gait",
                "walk",
                "--set",
                "slip.slow_below_friction=0.3",
            ],
            &["slip.slow_below_friction", "0.3", "[0, 0.25]"],
        ),
        (
            &[
                "walk",
                "--estimator",
                "kf",
                "--set",
                "filter.leg_outlier_mps=-1",
            ],
            &["filter.leg_outlier_mps", "-1", "[0, 10]"],
        ),
        (
            &["walk", "--set", "filter.leg_outlier_mps=0.1"],
            &["filter", "kf estimator"],
        ),
        (
            &["stand", "--set", "planner.progress_factor=1"],
            &["standing has no planner"],
        ),
        (
            &[
                "stand",
                "--estimator",
                "kf",
                "--set",
                "filter.leg_outlier_mps=-1",
            ],
            &["filter.leg_outlier_mps", "[0, 10]"],
        ),
    ];
    assert_refused(&dir, &cases);
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

#[test]
fn bad_training_and_policy_input_exits_2_names_the_file_and_writes_nothing() {
    let dir = scratch("train");
    let bad_config = dir.join("train.toml");
    std::fs::write(&bad_config, "task = \"model-free\"\n[ppo]\nclip = 3.0\n").unwrap();
    let cart_config = dir.join("cart.toml");
    std::fs::write(&cart_config, "task = \"cart-pole\"\n").unwrap();
    let not_a_policy = dir.join("policy.safetensors");
    std::fs::write(&not_a_policy, b"junk").unwrap();
    let missing = dir.join("missing.safetensors");
    let terrain = dir.join("terrain.toml");
    std::fs::write(
        &terrain,
        "[terrain.rough]\namplitude_m = 0.5\nwavelength_m = 0.5\nseed = 1\n",
    )
    .unwrap();
    let weak = dir.join("weak.toml");
    std::fs::write(&weak, "[model_error]\nmotor_strength_scale = 3.0\n").unwrap();
    let weak = weak.to_str().unwrap().to_string();
    let terrain_key = dir.join("terrain_key.toml");
    std::fs::write(&terrain_key, "[lava]\ndepth_m = 1\n").unwrap();
    let (terrain, terrain_key) = (terrain.to_str().unwrap(), terrain_key.to_str().unwrap());
    let (bad_config, cart_config, not_a_policy, missing) = (
        bad_config.to_str().unwrap(),
        cart_config.to_str().unwrap(),
        not_a_policy.to_str().unwrap(),
        missing.to_str().unwrap(),
    );
    let cases: [(&[&str], &[&str]); 12] = [
        (
            &["walk", "--scenario", terrain],
            &["terrain.toml", "terrain.rough.amplitude_m", "[0.001, 0.1]"],
        ),
        (
            &["walk", "--scenario", &weak],
            &[
                "weak.toml",
                "model_error.motor_strength_scale",
                "[0.5, 1.5]",
            ],
        ),
        (
            &["walk", "--scenario", terrain_key],
            &["terrain_key.toml", "lava"],
        ),
        (
            &["walk", "--estimator", "magic"],
            &["magic", "ground-truth, kf"],
        ),
        (
            &["train", "--task", "dance"],
            &["dance", "model-free, imitation, eemp-rl, cart-pole"],
        ),
        (
            &["train", "--task", "model-free", "--config", bad_config],
            &["train.toml", "ppo.clip", "[0.01, 1]"],
        ),
        (
            &["train", "--task", "model-free", "--config", cart_config],
            &["cart.toml", "cart-pole"],
        ),
        (
            &["train", "--task", "model-free", "--threads", "0"],
            &["--threads 0"],
        ),
        (
            &["walk", "--controller", "model-free", "--policy", missing],
            &["missing.safetensors"],
        ),
        (
            &[
                "walk",
                "--controller",
                "model-free",
                "--policy",
                not_a_policy,
            ],
            &["policy.safetensors", "safetensors"],
        ),
        (&["walk", "--controller", "model-free"], &["--policy"]),
        (
            &["walk", "--controller", "mpc"],
            &["mpc", "eemp, model-free"],
        ),
    ];
    assert_refused(&dir, &cases);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_clips_and_motions_exit_2_name_the_file_frame_and_marker_and_write_nothing() {
    let dir = scratch("retarget");
    let good_line = vec!["0.1"; 81].join(",");
    let wide = dir.join("wide_joint_pos.txt");
    std::fs::write(&wide, format!("{good_line}\n{good_line},0.2\n")).unwrap();
    let malformed = dir.join("malformed_joint_pos.txt");
    let mut cells = vec!["0.1"; 81];
    cells[31] = "x1";
    std::fs::write(&malformed, format!("{good_line}\n{}\n", cells.join(","))).unwrap();
    let degenerate = dir.join("degenerate_joint_pos.txt");
    std::fs::write(&degenerate, vec![good_line.clone(); 5].join("\n")).unwrap();
    let truncated = dir.join("truncated_joint_pos.txt");
    std::fs::write(&truncated, format!("{good_line}\n0.1,0.2,0.3\n")).unwrap();
    let real = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/reference/dog_mocap/raw_keypoints/dog_walk00_joint_pos.txt");
    let paths =
        [&wide, &malformed, &truncated, &degenerate].map(|p| p.to_str().unwrap().to_string());
    let real = real.to_str().unwrap();
    let cases: [(Vec<&str>, Vec<&str>); 7] = [
        (
            vec!["retarget", "--clip", &paths[0]],
            vec!["wide_joint_pos.txt", "frame 1", "82 values"],
        ),
        (
            vec!["retarget", "--clip", &paths[1]],
            vec!["malformed_joint_pos.txt", "frame 1", "marker 10", "x1"],
        ),
        (
            vec!["retarget", "--clip", &paths[2]],
            vec!["truncated_joint_pos.txt", "frame 1", "3 values"],
        ),
        (
            vec!["retarget", "--clip", real, "--frames", "200..200"],
            vec!["--frames 200..200", "empty"],
        ),
        (
            vec!["retarget", "--clip", real, "--frames", "500..700"],
            vec!["dog_walk00_joint_pos.txt", "500..700", "593 frames"],
        ),
        (
            // All markers at one point: no heading to take from them.
            vec!["retarget", "--clip", &paths[3]],
            vec!["degenerate_joint_pos.txt", "frame 0", "markers 0 and 3"],
        ),
        (
            vec!["retarget", "--clip", "no_such_clip"],
            vec!["no_such_clip_joint_pos.txt"],
        ),
    ];
    for (args, want) in cases {
        let (code, err, wrote) = eemp(&dir, &args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        for w in want {
            assert!(err.contains(w), "{args:?}: '{err}' lacks '{w}'");
        }
        assert!(!wrote, "{args:?} wrote its output");
    }
    // The IK cannot follow: a clip whose toes are stretched 30 cm below the paws.
    let text = std::fs::read_to_string(real).unwrap();
    let stretched: Vec<String> = text
        .lines()
        .take(20)
        .map(|l| {
            let mut v: Vec<f64> = l.split(',').map(|c| c.trim().parse().unwrap()).collect();
            for toe in [10, 19, 15, 23] {
                v[3 * toe + 1] -= 0.3; // y is up in the capture
            }
            v.iter()
                .map(|x| format!("{x:.5}"))
                .collect::<Vec<_>>()
                .join(",")
        })
        .collect();
    let far = dir.join("far_joint_pos.txt");
    std::fs::write(&far, stretched.join("\n")).unwrap();
    let (code, err, wrote) = eemp(&dir, &["retarget", "--clip", far.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("far_joint_pos.txt") && err.contains("frame 0"),
        "{err}"
    );
    assert!(err.contains("toe marker"), "{err}");
    assert!(!wrote);
    // A policy for another task cannot drive an imitation walk.
    let (code, err, _) = eemp(
        &dir,
        &[
            "walk",
            "--controller",
            "imitation",
            "--policy",
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../policies/a1_model_free_v1.safetensors")
                .to_str()
                .unwrap(),
        ],
    );
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("not imitation"), "{err}");
}

#[test]
fn bad_hardware_input_exits_2_names_the_value_and_writes_nothing() {
    let dir = scratch("hw");
    let cases: [(&[&str], &[&str]); 12] = [
        (
            &["hw", "--dry-run", "--speed", "9"],
            &["--speed 9", "[-1.5, 1.5]"],
        ),
        (
            &["hw", "--dry-run", "--rate", "5"],
            &["rate 5 Hz", "[50, 2000]"],
        ),
        (
            &["hw", "--address", "127.0.0.1:9", "--drop", "1.5"],
            &["drop_prob = 1.5", "[0, 1]"],
        ),
        (&["hw", "--speed", "0.3"], &["--address"]),
        (
            &[
                "hw",
                "--dry-run",
                "--robot",
                concat!(env!("CARGO_MANIFEST_DIR"), "/../../robots/go2.toml"),
                "--link",
                "udp",
            ],
            &["--link udp", "'go2'", "go2-dds", "--link dds"],
        ),
        (
            &["hw", "--link", "dds", "--speed", "0"],
            &["'a1'", "a1-udp", "--link udp"],
        ),
        (
            &[
                "hw",
                "--robot",
                concat!(env!("CARGO_MANIFEST_DIR"), "/../../robots/go2.toml"),
                "--domain",
                "233",
            ],
            &["domain 233", "0..=232"],
        ),
        (
            &[
                "sim-robot",
                "--robot",
                concat!(env!("CARGO_MANIFEST_DIR"), "/../../robots/go2.toml"),
                "--iface",
                "nosuch0",
            ],
            &["'nosuch0'", "allowed"],
        ),
        (
            &["sim-robot", "--low-level-mode"],
            &["--low-level-mode", "DDS"],
        ),
        (
            &[
                "sim-robot",
                "--robot",
                concat!(env!("CARGO_MANIFEST_DIR"), "/../../robots/go1.toml"),
            ],
            &["'go1'", "'none'"],
        ),
        (
            &["hw", "--dry-run", "--controller", "imitation"],
            &["--policy"],
        ),
        (
            &["sim-robot", "--duration", "0"],
            &["--duration 0", "(0, 3600]"],
        ),
    ];
    for (args, want) in cases {
        let (code, err, wrote) = eemp(&dir, args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        for w in want {
            assert!(err.contains(w), "{args:?}: '{err}' lacks '{w}'");
        }
        assert!(!wrote, "{args:?} wrote its output");
    }
}

#[test]
fn a_residual_eemp_rl_config_with_a_missing_or_wrong_table_exits_2_naming_the_file() {
    let dir = scratch("residual");
    let shipped = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../policies/a1_eemp_rl.toml"),
    )
    .unwrap();
    let missing = dir.join("missing.toml");
    std::fs::write(
        &missing,
        shipped.replace("tables/a1_free.toml", "no/such/free_table.toml"),
    )
    .unwrap();
    let (code, stderr, wrote) = eemp(
        &dir,
        &[
            "train",
            "--task",
            "eemp-rl",
            "--config",
            missing.to_str().unwrap(),
        ],
    );
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("no/such/free_table.toml"), "{stderr}");
    assert!(!wrote);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_walk_traces_the_parameters_in_force_and_summarises_them_per_speed() {
    let dir = scratch("params-in-force");
    let table = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tables/a1_free.toml");
    let (code, stderr, _) = eemp(
        &dir,
        &[
            "walk",
            "--gait",
            "free",
            "--params-table",
            table.to_str().unwrap(),
            "--speed",
            "0.3",
            "--duration",
            "1.5",
        ],
    );
    assert_eq!(code, Some(0), "{stderr}");
    let trace = std::fs::read_to_string(dir.join("out/trace.csv")).unwrap();
    let header: Vec<&str> = trace.lines().next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let last: Vec<f64> = trace
        .lines()
        .last()
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    // The table's entry for 0.3 m/s (tables/a1_free.toml).
    let t = eemp_core::planner::params_table::ParamsTable::load(&table).unwrap();
    let p = t.lookup(0.3);
    assert_eq!(last[col("swing_time_s")], p.swing_time_s);
    assert_eq!(last[col("ellipse_rx_m")], p.ellipse_rx_m);
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out/summary.json")).unwrap())
            .unwrap();
    // Table II's constants did not run: no "params"; per speed: 0 (standing) and 0.3 m/s.
    assert!(s["params"].is_null(), "{}", s["params"]);
    let speeds = s["params_in_force"].as_array().unwrap();
    assert_eq!(speeds.len(), 2, "{speeds:?}");
    let mean = speeds[1]["mean"]["body_height_m"].as_f64().unwrap();
    assert!((mean - p.body_height_m).abs() < 1e-12, "{mean}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_walk_takes_the_shipped_table_by_default_and_table_ii_on_request() {
    let dir = scratch("default-table");
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let walk = |cwd: &Path, extra: &[&str]| {
        let out = dir.join(format!("out-{}", extra.len()));
        let o = Command::new(env!("CARGO_BIN_EXE_eemp"))
            .current_dir(cwd)
            .args([
                "walk",
                "--gait",
                "walk",
                "--speed",
                "0.2",
                "--duration",
                "1",
            ])
            .args(extra)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{stderr}");
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap())
                .unwrap();
        (s, stderr)
    };
    // From the repository: the A1's walk table, as eemp hw, teleop and the suites use.
    let (s, stderr) = walk(&repo, &[]);
    assert!(!stderr.contains("above the table's last entry"), "{stderr}");
    assert_eq!(
        s["params_table"], "tables/a1_walk.toml",
        "{}",
        s["params_table"]
    );
    assert!(s["params"].is_null());
    let t = eemp_core::planner::params_table::ParamsTable::load(&repo.join("tables/a1_walk.toml"))
        .unwrap();
    let ran = &s["params_in_force"].as_array().unwrap()[1]["mean"];
    assert_eq!(
        ran["swing_time_s"].as_f64(),
        Some(t.lookup(0.2).swing_time_s)
    );
    // A command beyond the table's last entry (1.0 m/s) walks on that entry, and says so.
    let o = Command::new(env!("CARGO_BIN_EXE_eemp"))
        .current_dir(&repo)
        .args([
            "walk",
            "--gait",
            "walk",
            "--speed",
            "1.2",
            "--duration",
            "0.1",
        ])
        .arg("--out")
        .arg(dir.join("out-fast"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains("speed 1.2 m/s is above the table's last entry (1 m/s)"),
        "{stderr}"
    );
    // --table-ii: the paper's constants.
    let (s, _) = walk(&repo, &["--table-ii"]);
    assert!(s["params_table"].is_null());
    assert_eq!(s["params"]["swing_time_s"], 0.25, "{}", s["params"]);
    // A folder without tables/: Table II, and the walk says so.
    let (s, stderr) = walk(&dir, &["--seed", "0"]);
    assert!(s["params_table"].is_null());
    assert!(stderr.contains("no tables/a1_walk.toml"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_friction_and_baseline_input_exits_2_names_the_key_and_writes_nothing() {
    // Issue 22: a friction outside (0, 2], friction segments out of order or overlapping.
    // Issue 21: an energy weight out of range, a mirror loss on a task without a mirror, a
    // training floor outside (0, 2].
    let dir = scratch("friction");
    let write = |name: &str, text: &str| {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p.to_str().unwrap().to_string()
    };
    let overlap = write(
        "overlap.toml",
        "[[terrain.friction_patch]]\nx0_m = 1.0\nx1_m = 2.0\nfriction = 0.2\n\n\
         [[terrain.friction_patch]]\nx0_m = 1.5\nx1_m = 3.0\nfriction = 0.4\n",
    );
    let unordered = write(
        "unordered.toml",
        "[[terrain.friction_patch]]\nx0_m = 3.0\nx1_m = 4.0\nfriction = 0.2\n\n\
         [[terrain.friction_patch]]\nx0_m = 0.5\nx1_m = 1.0\nfriction = 0.4\n",
    );
    let floor = write("floor.toml", "floor_friction = 2.5\n");
    let energy = write(
        "energy.toml",
        "task = \"model-free\"\n[model_free.rewards]\nenergy = -5000.0\n",
    );
    let mirror = write(
        "mirror.toml",
        "task = \"cart-pole\"\ntotal_env_steps = 2048\n[ppo]\nsymmetry_coef = 0.5\n",
    );
    let floors = write(
        "floors.toml",
        "task = \"model-free\"\n[model_free]\nfloor_frictions = [0.5, 0.0]\n",
    );
    let cases: [(Vec<&str>, &[&str]); 8] = [
        (
            vec!["walk", "--friction", "0"],
            &["floor_friction", "(0, 2]"],
        ),
        (
            vec!["walk", "--friction", "2.5"],
            &["floor_friction", "2.5"],
        ),
        (
            vec!["walk", "--scenario", &overlap],
            &["friction_patch[1].x0_m", "1.5"],
        ),
        (
            vec!["walk", "--scenario", &unordered],
            &["friction_patch[1].x0_m", "0.5"],
        ),
        (
            vec!["walk", "--scenario", &floor],
            &["floor_friction", "2.5"],
        ),
        (
            vec!["train", "--task", "model-free", "--config", &energy],
            &["model_free.rewards.energy", "-5000"],
        ),
        (
            vec!["train", "--task", "cart-pole", "--config", &mirror],
            &["ppo.symmetry_coef", "no left–right mirror"],
        ),
        (
            vec!["train", "--task", "model-free", "--config", &floors],
            &["model_free.floor_frictions[1]", "(0, 2]"],
        ),
    ];
    for (args, want) in cases {
        let (code, err, wrote) = eemp(&dir, &args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        for w in want {
            assert!(err.contains(w), "{args:?}: {err:?} lacks {w:?}");
        }
        assert!(!wrote, "{args:?} wrote its output");
    }
}

#[test]
fn artifacts_of_another_robot_are_refused_naming_both_unless_allowed() {
    let dir = scratch("robot-mismatch");
    let go1 = concat!(env!("CARGO_MANIFEST_DIR"), "/../../robots/go1.toml");
    let table = concat!(env!("CARGO_MANIFEST_DIR"), "/../../tables/a1_trot.toml");
    let policy = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../policies/a1_model_free_v1.safetensors"
    );
    for args in [
        vec![
            "walk",
            "--robot",
            go1,
            "--gait",
            "trot",
            "--params-table",
            table,
        ],
        vec![
            "walk",
            "--robot",
            go1,
            "--controller",
            "model-free",
            "--policy",
            policy,
        ],
    ] {
        let (code, err, wrote) = eemp(&dir, &[&args[..], &["--duration", "0.5"]].concat());
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert!(err.contains("'a1'") && err.contains("'go1'"), "{err}");
        assert!(err.contains("--allow-robot-mismatch"), "{err}");
        assert!(!wrote, "{args:?} wrote output");
    }
    // Allowed for an experiment, and said in summary.json.
    let (code, err, _) = eemp(
        &dir,
        &[
            "walk",
            "--robot",
            go1,
            "--gait",
            "trot",
            "--params-table",
            table,
            "--allow-robot-mismatch",
            "--duration",
            "0.5",
        ],
    );
    assert_eq!(code, Some(0), "{err}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out/summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["robot"]["name"], "go1");
    assert_eq!(summary["robot"]["allow_robot_mismatch"], true);
}

#[test]
fn a_run_file_walks_as_its_options_would_and_a_bad_one_is_named() {
    let dir = scratch("run-file");
    let file = dir.join("run.toml");
    std::fs::write(
        &file,
        "gait = \"walk\"\nspeed_mps = 0.2\nduration_s = 1.5\n",
    )
    .unwrap();
    let summary = |d: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(d.join("out/summary.json")).unwrap()).unwrap()
    };
    let (code, err, _) = eemp(&dir, &["walk", "--run", file.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    let by_options = scratch("run-file-options");
    let (code, err, _) = eemp(
        &by_options,
        &[
            "walk",
            "--gait",
            "walk",
            "--speed",
            "0.2",
            "--duration",
            "1.5",
        ],
    );
    assert_eq!(code, Some(0), "{err}");
    for key in ["cot", "distance_m", "vel_rmse_mps", "steps_total"] {
        assert_eq!(summary(&dir)[key], summary(&by_options)[key], "{key}");
    }
    let bad = scratch("run-file-bad");
    let file = bad.join("run.toml");
    std::fs::write(&file, "sped_mps = 1\n").unwrap();
    let (code, err, wrote) = eemp(&bad, &["walk", "--run", file.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("unknown field `sped_mps`") && err.contains("run.toml"),
        "{err}"
    );
    assert!(!wrote);
}

#[test]
fn ignored_options_a_silent_robot_link_and_a_replay_on_another_robot_are_refused() {
    let dir = scratch("ignored");
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let file = |p: &str| repo.join(p).to_str().unwrap().to_string();
    let sensors = dir.join("sensors.toml");
    std::fs::write(&sensors, "[sensors]\n").unwrap();
    let run = dir.join("run.toml");
    std::fs::write(&run, "gait = \"trot\"\nspeed_mps = 0.3\nduration_s = 1.0\n").unwrap();
    let (sensors, run) = (sensors.to_str().unwrap(), run.to_str().unwrap());
    let (mf, rl) = (
        file("policies/a1_model_free.safetensors"),
        file("policies/a1_eemp_rl.safetensors"),
    );
    let (trot, slippery) = (
        file("tables/a1_trot.toml"),
        file("scenarios/slippery-0.2.toml"),
    );
    let bad_video = dir.join("a-file");
    std::fs::write(&bad_video, "").unwrap();
    let bad_video = bad_video.join("walk.gif");
    let bad_video = bad_video.to_str().unwrap();
    // (arguments, what the message must contain)
    let cases: [(&[&str], &[&str]); 10] = [
        (
            &[
                "walk",
                "--controller",
                "model-free",
                "--policy",
                &mf,
                "--params-table",
                &trot,
            ],
            &["--params-table", "--controller eemp, not model-free"],
        ),
        (
            &[
                "walk",
                "--controller",
                "eemp-rl",
                "--policy",
                &rl,
                "--gait",
                "walk",
            ],
            &["--gait", "--controller eemp, not eemp-rl"],
        ),
        (&["walk", "--ideal-sensors"], &["--ideal-sensors", "kf"]),
        (
            &[
                "walk",
                "--estimator",
                "kf",
                "--ideal-sensors",
                "--scenario",
                sensors,
            ],
            &["--ideal-sensors", "[sensors]", "sensors.toml"],
        ),
        (
            &["walk", "--friction", "1.5", "--scenario", &slippery],
            &["--friction 1.5", "floor_friction 0.2", "slippery-0.2.toml"],
        ),
        (
            &["walk", "--push-dv", "0.5"],
            &["--push-dv 0.5", "--push-at"],
        ),
        // A walk option beside a run file would be ignored (clap refuses the pair).
        (
            &["walk", "--run", run, "--speed", "0.5"],
            &["--run", "--speed"],
        ),
        (
            &["walk", "--duration", "1", "--video", bad_video],
            &["--video", "a-file"],
        ),
        // Named by the option, not by the profile segment it becomes.
        (&["walk", "--speed", "5"], &["--speed 5", "[-1.5, 1.5]"]),
        (
            &[
                "teleop",
                "--joystick",
                "/dev/null",
                "--headless",
                "--duration",
                "1",
            ],
            &["--joystick /dev/null", "not a joystick"],
        ),
    ];
    assert_refused(&dir, &cases);
    // A hardware run that never hears from the robot is an error (its summary says what was
    // sent), not a success.
    let (code, stderr, _) = eemp(
        &dir,
        &[
            "hw",
            "--address",
            "127.0.0.1:9",
            "--bind",
            "127.0.0.1:0",
            "--duration",
            "0.2",
            "--params-table",
            &trot,
        ],
    );
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("no valid state arrived"), "{stderr}");
    // A replay on another robot's body than the walk's is refused, naming both.
    let walked = dir.join("walked");
    let o = Command::new(env!("CARGO_BIN_EXE_eemp"))
        .args([
            "walk",
            "--duration",
            "0.3",
            "--params-table",
            &trot,
            "--out",
        ])
        .arg(&walked)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let gif = dir.join("replay.gif");
    let o = Command::new(env!("CARGO_BIN_EXE_eemp"))
        .arg("replay")
        .arg(&walked)
        .args(["--robot", &file("robots/go2.toml"), "--video"])
        .arg(&gif)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("another robot") && stderr.contains("go2.toml"),
        "{stderr}"
    );
    assert!(!gif.exists());
    // Unless asked for.
    let o = Command::new(env!("CARGO_BIN_EXE_eemp"))
        .arg("replay")
        .arg(&walked)
        .args([
            "--robot",
            &file("robots/go2.toml"),
            "--allow-robot-mismatch",
            "--video",
        ])
        .arg(&gif)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(gif.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
