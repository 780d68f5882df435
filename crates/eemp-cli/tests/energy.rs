//! The battery's energy in `eemp walk`: the summary's electrical figures against an independent
//! computation from the 1 kHz trace of the same run, a robot file without a motor model, and a
//! bad `[motor]` section.

use std::path::{Path, PathBuf};
use std::process::Command;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("eemp-energy-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn eemp(out: &Path, args: &[&str]) -> (Option<i32>, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_eemp"))
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn repo(rel: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
        .to_str()
        .unwrap()
        .to_string()
}

fn summary(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
}

/// The A1 file's motor model, read here from the file itself (k per joint, idle power).
fn a1_motor() -> ([f64; 3], f64) {
    let v: toml::Value =
        toml::from_str(&std::fs::read_to_string(repo("robots/a1.toml")).unwrap()).unwrap();
    let m = &v["motor"];
    let k = ["abduction", "thigh", "calf"]
        .map(|j| m[j]["heat_coefficient_w_per_nm2"].as_float().unwrap());
    (k, m["idle_power_w"].as_float().unwrap())
}

#[test]
fn a_walks_electrical_figures_agree_with_its_1khz_trace() {
    let dir = scratch("trace");
    let out = dir.join("out");
    let (code, stderr) = eemp(
        &out,
        &[
            "walk",
            "--gait",
            "free",
            "--params-table",
            &repo("tables/a1_free.toml"),
            "--speed",
            "0.4",
            "--duration",
            "5",
            "--trace-hz",
            "1000",
        ],
    );
    assert_eq!(code, Some(0), "{stderr}");
    let s = summary(&out);
    let e = &s["electrical"];
    let [t0, t1] = [0, 1].map(|i| s["metrics_window_s"][i].as_f64().unwrap());
    // Independently: Σⱼ max(τⱼq̇ⱼ + kⱼτⱼ², 0) + idle from the trace's torque and velocity columns
    // (the file's model has no regeneration), each row held for 1 ms over the metrics window.
    let (k, idle) = a1_motor();
    let mut rd = csv::Reader::from_path(out.join("trace.csv")).unwrap();
    let h = rd.headers().unwrap().clone();
    let col = |n: &str| {
        h.iter()
            .position(|x| x == n)
            .unwrap_or_else(|| panic!("{n}"))
    };
    let (t_col, p_col) = (col("time_s"), col("electrical_power_w"));
    let joints: Vec<(usize, usize, f64)> = ["FR", "FL", "RR", "RL"]
        .iter()
        .flat_map(|l| (0..3).map(move |j| (*l, j)))
        .map(|(l, j)| {
            (
                col(&format!("{l}_tau{j}_nm")),
                col(&format!("{l}_qd{j}_radps")),
                k[j],
            )
        })
        .collect();
    let (mut energy_j, mut traced_j, mut rows) = (0.0, 0.0, 0);
    for r in rd.records() {
        let r = r.unwrap();
        let x = |i: usize| r[i].parse::<f64>().unwrap();
        let t = x(t_col);
        if t < t0 - 1e-9 || t > t1 + 1e-9 {
            continue;
        }
        let p: f64 = joints
            .iter()
            .map(|&(ti, qi, k)| (x(ti) * x(qi) + k * x(ti) * x(ti)).max(0.0))
            .sum::<f64>()
            + idle;
        energy_j += p * 1e-3;
        traced_j += x(p_col) * 1e-3;
        rows += 1;
    }
    assert!(rows > 2500, "{rows} trace rows in the window");
    let summary_j = e["energy_j"].as_f64().unwrap();
    let rel = (summary_j / energy_j - 1.0).abs();
    println!("summary {summary_j:.2} J, trace {energy_j:.2} J ({rows} rows), rel {rel:.4}");
    assert!(
        rel < 0.02,
        "summary {summary_j} J against the trace's {energy_j} J"
    );
    assert!((traced_j / energy_j - 1.0).abs() < 1e-6);
    // The CoT and Wh/km follow from the same energy and the summary's distance.
    let (m, d) = (12.453, s["distance_m"].as_f64().unwrap());
    let cot = e["cot"].as_f64().unwrap();
    assert!(
        (cot / (energy_j / (m * 9.81 * d)) - 1.0).abs() < 0.02,
        "{cot}"
    );
    let whkm = e["wh_per_km"].as_f64().unwrap();
    assert!((whkm / (energy_j / 3.6 / d) - 1.0).abs() < 0.02, "{whkm}");
    // Eq. (8) is reported beside it, far below: the battery pays for heat and electronics.
    assert!(s["cot"].as_f64().unwrap() < 0.5 * cot);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_robot_without_a_motor_model_says_so_instead_of_printing_zeros() {
    let dir = scratch("no-motor");
    let text = std::fs::read_to_string(repo("robots/a1.toml")).unwrap();
    let cut = text.find("[motor]").unwrap();
    // Everything before the section's comment block.
    let cut = text[..cut].rfind("\n\n").unwrap();
    let robot = dir.join("a1-no-motor.toml");
    std::fs::write(&robot, &text[..cut]).unwrap();
    let out = dir.join("out");
    let (code, stderr) = eemp(
        &out,
        &[
            "walk",
            "--robot",
            robot.to_str().unwrap(),
            "--gait",
            "trot",
            "--speed",
            "0.3",
            "--duration",
            "2.5",
        ],
    );
    assert_eq!(code, Some(0), "{stderr}");
    let s = summary(&out);
    assert!(s["electrical"].is_null());
    assert!(s["electrical_note"].as_str().unwrap().contains("[motor]"));
    assert!(s["cot"].is_number());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_bad_motor_section_is_refused_naming_the_file_and_key() {
    let dir = scratch("bad-motor");
    let text = std::fs::read_to_string(repo("robots/a1.toml")).unwrap();
    for (from, to, key) in [
        (
            "thigh = { heat_coefficient_w_per_nm2 = 0.3 }",
            "thigh = { heat_coefficient_w_per_nm2 = -0.3 }",
            "motor.thigh.heat_coefficient_w_per_nm2",
        ),
        (
            "calf = { heat_coefficient_w_per_nm2 = 0.3 }",
            "calf = { heat_coefficient_w_per_nm2 = nan }",
            "motor.calf.heat_coefficient_w_per_nm2",
        ),
        (
            "regeneration_fraction = 0.0",
            "regeneration_fraction = 1.2",
            "motor.regeneration_fraction",
        ),
        (
            "idle_power_w = 20.0",
            "idle_power_w = inf",
            "motor.idle_power_w",
        ),
        (
            "abduction = { heat_coefficient_w_per_nm2 = 0.3 }",
            "abduction = { gear_ratio = 9.1 }",
            "motor.abduction",
        ),
        (
            "thigh = { heat_coefficient_w_per_nm2 = 0.3 }\n",
            "",
            "thigh",
        ),
    ] {
        assert!(text.contains(from), "{from}");
        let robot = dir.join("a1-bad.toml");
        std::fs::write(&robot, text.replacen(from, to, 1)).unwrap();
        let out = dir.join("out");
        let (code, stderr) = eemp(
            &out,
            &[
                "walk",
                "--robot",
                robot.to_str().unwrap(),
                "--speed",
                "0.3",
                "--duration",
                "2.5",
            ],
        );
        assert_eq!(code, Some(2), "{to}: {stderr}");
        assert!(stderr.contains(key), "{to}: '{key}' not in {stderr}");
        assert!(stderr.contains("a1-bad.toml"), "{to}: {stderr}");
        assert!(!out.exists(), "{to}: wrote its output");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
