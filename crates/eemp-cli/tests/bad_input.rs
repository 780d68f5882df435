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
    let (bad_params, missing, malformed) = (
        bad_params.to_str().unwrap(),
        missing.to_str().unwrap(),
        malformed.to_str().unwrap(),
    );
    // (arguments, what the message must contain)
    let cases: [(&[&str], &[&str]); 9] = [
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
            &["swing_time_s", "0.5", "[0.1, 0.25]"],
        ),
        (&["walk", "--params", missing], &["missing.toml"]),
        (&["walk", "--profile", malformed], &["profile.toml"]),
        (
            &["walk", "--progress-factor", "3"],
            &["--progress-factor 3", "[0, 2]"],
        ),
        (
            &["walk", "--progress-factor", "-1"],
            &["--progress-factor -1", "[0, 2]"],
        ),
        (
            &["stand", "--duration", "-3"],
            &["--duration -3", "(0, 3600]"],
        ),
    ];
    for (args, needles) in cases {
        let (code, stderr, wrote) = eemp(&dir, args);
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
    let terrain_key = dir.join("terrain_key.toml");
    std::fs::write(&terrain_key, "[lava]\ndepth_m = 1\n").unwrap();
    let (terrain, terrain_key) = (terrain.to_str().unwrap(), terrain_key.to_str().unwrap());
    let (bad_config, cart_config, not_a_policy, missing) = (
        bad_config.to_str().unwrap(),
        cart_config.to_str().unwrap(),
        not_a_policy.to_str().unwrap(),
        missing.to_str().unwrap(),
    );
    let cases: [(&[&str], &[&str]); 11] = [
        (
            &["walk", "--scenario", terrain],
            &["terrain.toml", "terrain.rough.amplitude_m", "[0.001, 0.1]"],
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
            &["dance", "model-free, cart-pole"],
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
    for (args, needles) in cases {
        let (code, stderr, wrote) = eemp(&dir, args);
        assert_eq!(code, Some(2), "{args:?}: {stderr}");
        for n in needles {
            assert!(stderr.contains(n), "{args:?}: '{n}' not in: {stderr}");
        }
        assert!(!wrote, "{args:?} wrote its output folder");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
