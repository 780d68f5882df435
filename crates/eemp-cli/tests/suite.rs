//! The suite runner behind `eemp compare` and `eemp robustness`: it resumes after a kill
//! without losing or repeating rows, a resumed run gives the same rows, and bad configs are
//! refused before anything runs; shards cover the runs once and merge into the whole suite; the
//! same runs give the same `results.csv` bytes however they were run.

use eemp_cli::suite::{
    load_rows, merge_rows, run_suite, run_suite_shard, MethodConfig, ScenarioConfig, SuiteConfig,
};
use std::path::{Path, PathBuf};

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(p)
}

fn config() -> SuiteConfig {
    SuiteConfig {
        duration_s: 3.0,
        seeds: vec![1, 2],
        estimator: "kf".into(),
        methods: vec![
            MethodConfig {
                name: "EEMP trot".into(),
                kind: "eemp".into(),
                gait: Some("trot".into()),
                table: Some(repo("tables/a1_trot.toml")),
                policy: None,
                estimator: None,
                eemp_rl: false,
                set: Vec::new(),
            },
            MethodConfig {
                name: "model-free RL".into(),
                kind: "model-free".into(),
                gait: None,
                table: None,
                policy: Some(repo("policies/a1_model_free_v1.safetensors")),
                estimator: None,
                eemp_rl: false,
                set: Vec::new(),
            },
        ],
        scenarios: vec![
            ScenarioConfig {
                name: "flat".into(),
                file: None,
                speeds_mps: vec![0.3],
                profile: None,
            },
            ScenarioConfig {
                name: "payload".into(),
                file: Some(repo("scenarios/payload-2kg.toml")),
                speeds_mps: vec![0.3],
                profile: None,
            },
        ],
        robot: None,
        allow_robot_mismatch: false,
        speeds_scale_with_robot: false,
    }
}

#[test]
fn a_killed_suite_resumes_without_losing_or_repeating_rows() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config();
    let all = run_suite(&cfg, dir.path(), 2, &|_, _, _| {}).unwrap();
    assert_eq!(all.len(), 8);
    assert!(
        all.iter().all(|r| !r.fell && r.vel_rmse_mps.is_some()),
        "{all:?}"
    );
    // A kill mid-write: two full rows and a partial third stay.
    let path = dir.path().join("results.csv");
    let first_bytes = std::fs::read(&path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let cut = format!(
        "{}\n{}\n{}\n{}",
        lines[0],
        lines[1],
        lines[2],
        &lines[3][..20]
    );
    std::fs::write(&path, cut).unwrap();
    assert_eq!(load_rows(&path).unwrap().len(), 2);
    let again = run_suite(&cfg, dir.path(), 1, &|_, _, _| {}).unwrap();
    assert_eq!(again.len(), 8);
    let on_disk = load_rows(&path).unwrap();
    assert_eq!(on_disk.len(), 8, "no row lost, none repeated");
    assert!(
        std::fs::read(&path).unwrap() == first_bytes,
        "the same runs give the same results.csv, byte for byte (2 threads whole, 1 resumed)"
    );
    // The same seed gives the same run, whatever the thread count.
    for r in &all {
        let s = on_disk.iter().find(|x| x.run_id == r.run_id).unwrap();
        assert_eq!(
            (s.fell, s.vel_rmse_mps, s.cot, s.steps_total),
            (r.fell, r.vel_rmse_mps, r.cot, r.steps_total)
        );
    }
    // Another config on the same folder is refused.
    let mut other = cfg.clone();
    other.seeds = vec![3];
    let e = run_suite(&other, dir.path(), 1, &|_, _, _| {}).unwrap_err();
    assert!(e.contains("another config"), "{e}");

    // Two shards cover the runs once; merged, they are the whole suite's rows.
    let shards = [tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap()];
    let mut sizes = Vec::new();
    for (k, d) in shards.iter().enumerate() {
        sizes.push(
            run_suite_shard(
                &cfg,
                d.path(),
                1,
                Some(eemp_study::Shard {
                    index: k + 1,
                    count: 2,
                }),
                &|_, _, _| {},
            )
            .unwrap()
            .len(),
        );
    }
    assert_eq!(sizes, [4, 4]);
    let merged = tempfile::tempdir().unwrap();
    let dirs: Vec<PathBuf> = shards.iter().map(|d| d.path().to_path_buf()).collect();
    assert_eq!(merge_rows(&cfg, &dirs, merged.path()).unwrap(), 8);
    assert!(
        std::fs::read(merged.path().join("results.csv")).unwrap() == first_bytes,
        "merged shards give the whole suite's results.csv, byte for byte"
    );
    let rows = run_suite(&cfg, merged.path(), 1, &|_, n, _| panic!("run {n} again")).unwrap();
    for r in &all {
        let m = rows.iter().find(|x| x.run_id == r.run_id).unwrap();
        assert_eq!((m.cot, m.vel_rmse_mps), (r.cot, r.vel_rmse_mps));
    }
    // A shard of another suite is refused before anything is written.
    let e = merge_rows(&other, &dirs, &merged.path().join("new")).unwrap_err();
    assert!(e.contains("another config"), "{e}");
    assert!(!merged.path().join("new").exists());
}

#[test]
fn bad_suite_configs_are_refused_naming_the_value() {
    let mut c = config();
    c.methods[1].policy = Some(repo("policies/nope.safetensors"));
    assert!(c.validate().unwrap_err().contains("nope.safetensors"));
    let mut c = config();
    c.methods[1].set = vec!["mpc.horizon=8".into()];
    let e = c.validate().unwrap_err();
    assert!(
        e.contains("mpc.horizon=8") && e.contains("--controller eemp"),
        "{e}"
    );
    let mut c = config();
    c.methods[0].kind = "magic".into();
    assert!(c.validate().unwrap_err().contains("unknown kind 'magic'"));
    let mut c = config();
    c.scenarios[0].speeds_mps = vec![2.0];
    assert!(c
        .validate()
        .unwrap_err()
        .contains("speed 2 is out of range"));
    let mut c = config();
    c.methods[1].name = "EEMP trot".into();
    assert!(c.validate().unwrap_err().contains("used twice"));
    let mut c = config();
    c.seeds = vec![1, 1];
    assert!(c.validate().unwrap_err().contains("repeat a seed"));
    let mut c = config();
    c.scenarios[0].speeds_mps = vec![0.3, 0.3001];
    assert!(c.validate().unwrap_err().contains("repeat a speed"));
    let mut c = config();
    c.methods[0].name = "a|b".into();
    assert!(c.validate().unwrap_err().contains("'|'"));
    let mut c = config();
    c.estimator = "oracle".into();
    assert!(c.validate().unwrap_err().contains("oracle"));
    let mut c = config();
    c.methods[1].estimator = Some("oracle".into());
    let e = c.validate().unwrap_err();
    assert!(e.contains("model-free RL") && e.contains("oracle"), "{e}");
    let mut c = config();
    c.scenarios[0].profile = Some(repo("profiles/up-and-down.toml"));
    assert!(c.validate().unwrap_err().contains("not both"));
    let mut c = config();
    c.scenarios[0].speeds_mps.clear();
    c.scenarios[0].profile = Some(repo("profiles/nope.toml"));
    assert!(c.validate().unwrap_err().contains("nope.toml"));
    let mut c = config();
    c.methods[0].set = vec!["filter.velocity_jump_mps=-0.1".into()];
    let e = c.validate().unwrap_err();
    assert!(
        e.contains("filter.velocity_jump_mps") && e.contains("-0.1"),
        "{e}"
    );
    let mut c = config();
    c.methods[0].set = vec!["filter.velocity_jump_dragged_fraction=1.5".into()];
    let e = c.validate().unwrap_err();
    assert!(
        e.contains("filter.velocity_jump_dragged_fraction") && e.contains("1.5"),
        "{e}"
    );
    let mut c = config();
    c.methods[0].set = vec!["filter.leg_outlier_mps=nan".into()];
    let e = c.validate().unwrap_err();
    assert!(
        e.contains("filter.leg_outlier_mps") && e.contains("NaN"),
        "{e}"
    );
    let mut c = config();
    c.methods[0].estimator = Some("ground-truth".into());
    c.methods[0].set = vec!["filter.velocity_jump_mps=0.15".into()];
    assert!(c.validate().unwrap_err().contains("kf estimator"));
    let mut c = config();
    c.methods[0].gait = Some("free".into());
    c.methods[0].table = Some(repo("tables/a1_free.toml"));
    c.methods[0].set = vec!["planner.free_pairing.pair_tolerance=1.5".into()];
    let e = c.validate().unwrap_err();
    assert!(e.contains("pair_tolerance") && e.contains("1.5"), "{e}");
    let mut c = config();
    c.methods[1].set = vec!["planner.free_pairing.pair_tolerance=0.0".into()];
    let e = c.validate().unwrap_err();
    assert!(e.contains("only filter.*"), "{e}");
    // A method's slip settings reach its walk: out of range, or where slip handling is off
    // (`adapt_friction = false`), they are refused; the walk's default is on (below 0.6 m/s).
    let mut c = config();
    c.methods[0].set = vec!["slip.hold_raise_fraction=0.05".into()];
    let e = c.validate().unwrap_err();
    assert!(
        e.contains("slip.hold_raise_fraction") && e.contains("0.05"),
        "{e}"
    );
    let mut c = config();
    c.methods[0].gait = Some("walk".into());
    c.methods[0].table = Some(repo("tables/a1_walk.toml"));
    c.methods[0].set = vec!["slip.hold_raise_fraction=0.8".into()];
    c.validate().unwrap();
    let mut c = config();
    c.methods[1].set = vec!["slip.hold_raise_fraction=0.8".into()];
    let e = c.validate().unwrap_err();
    assert!(
        e.contains("slip.hold_raise_fraction") && e.contains("only filter.*"),
        "{e}"
    );
}

#[test]
fn a_method_can_run_on_its_own_estimator_and_a_scenario_on_a_profile() {
    let mut c = config();
    c.duration_s = 4.0;
    c.seeds = vec![1];
    let mut gt = c.methods[0].clone();
    gt.name = "EEMP trot, ground truth".into();
    gt.estimator = Some("ground-truth".into());
    c.methods = vec![c.methods[0].clone(), gt];
    c.scenarios = vec![ScenarioConfig {
        name: "up and down".into(),
        file: None,
        speeds_mps: vec![],
        profile: Some(repo("profiles/up-and-down.toml")),
    }];
    c.validate().unwrap();
    // One run per method and seed, listed at the profile's top speed (1.0 m/s).
    let runs = c.runs().unwrap();
    assert_eq!(runs.len(), 2);
    assert!(runs.iter().all(|r| (r.speed_mps - 1.0).abs() < 1e-12));
    let dir = tempfile::tempdir().unwrap();
    let rows = run_suite(&c, dir.path(), 2, &|_, _, _| {}).unwrap();
    let robot = eemp_core::robot::RobotConfig::a1();
    for r in &rows {
        let m = c.methods.iter().find(|m| m.name == r.method).unwrap();
        // Each row is the walk `eemp walk` does on that estimator along the profile.
        let mut spec = eemp_sim::walk::WalkSpec::constant(
            eemp_core::planner::PlannerConfig::default(),
            Default::default(),
            Default::default(),
            c.duration_s,
        );
        spec.seed = 1;
        spec.profile =
            eemp_core::config_error::load_toml(&repo("profiles/up-and-down.toml")).unwrap();
        spec.state_source =
            eemp_cli::state_source_arg::state_source(m.estimator(&c), false, 1, &robot).unwrap();
        spec.params_table = Some(
            eemp_core::planner::params_table::ParamsTable::load(&repo("tables/a1_trot.toml"))
                .unwrap(),
        );
        let mut ctl = eemp_sim::walk::eemp_controller(&robot, &spec).unwrap();
        let start = eemp_sim::walk::StartPose::eemp(&robot, &spec).unwrap();
        let walk = eemp_sim::walk::run_walk_with(&robot, &spec, &start, &mut ctl, |_| {}).unwrap();
        assert_eq!(walk.metrics.vel_rmse_mps, r.vel_rmse_mps, "{}", r.method);
    }
    assert_ne!(rows[0].vel_rmse_mps, rows[1].vel_rmse_mps);
}
