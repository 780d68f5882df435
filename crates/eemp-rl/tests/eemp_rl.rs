//! EEMP-RL: the action squashing covers Table I exactly and never leaves it; a policy that
//! answers fixed parameters walks exactly as EEMP with those parameters; the environment steps;
//! the residual form with a zero action is EEMP-Analytical bit for bit and rewards eq. 8; the
//! paired reward measures a correction against the table's walk from the same state.

use eemp_core::planner::params::table_i;
use eemp_core::planner::params_table::ParamsTable;
use eemp_core::planner::{Gait, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_rl::env::Env;
use eemp_rl::tasks::eemp_rl::{
    squash, unsquash, walk_spec, EempRlConfig, EempRlController, EempRlEnv, FixedAction, RANGES,
};
use eemp_sim::walk::{eemp_controller, run_walk, run_walk_with, VelocityProfile, WalkSpec};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn as_array(p: &PlannerParams) -> [f64; 5] {
    p.to_array()
}

#[test]
fn squashing_covers_table_i_and_never_leaves_it() {
    assert_eq!(RANGES[0], table_i::SWING_TIME_S);
    assert_eq!(RANGES[2], table_i::BODY_HEIGHT_M);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for _ in 0..10_000 {
        let a: Vec<f32> = (0..5)
            .map(|_| match rng.random_range(0..4) {
                0 => rng.random_range(-3.0..3.0),
                1 => rng.random_range(-1e6..1e6),
                2 => f32::NAN,
                _ => f32::INFINITY,
            })
            .collect();
        let p = squash(&a);
        p.validate().unwrap();
        for (v, [lo, hi]) in as_array(&p).iter().zip(RANGES) {
            assert!(*v >= lo && *v <= hi, "{v} outside [{lo}, {hi}]");
        }
    }
    // The ends of the ranges are reached, and the middle is the zero action.
    let lo = as_array(&squash(&[-50.0; 5]));
    let hi = as_array(&squash(&[50.0; 5]));
    let mid = as_array(&squash(&[0.0; 5]));
    for i in 0..5 {
        assert_eq!(lo[i], RANGES[i][0]);
        assert_eq!(hi[i], RANGES[i][1]);
        assert!((mid[i] - (RANGES[i][0] + RANGES[i][1]) / 2.0).abs() < 1e-12);
    }
    // Table II's values have an action that gives them back.
    let t2 = PlannerParams::default();
    let back = as_array(&squash(&unsquash(&t2)));
    for (a, b) in back.iter().zip(as_array(&t2)) {
        assert!((a - b).abs() < 1e-6, "{a} vs {b}");
    }
}

#[test]
fn a_fixed_answer_walks_exactly_as_eemp_with_those_parameters() {
    let robot = RobotConfig::a1();
    let cfg = EempRlConfig::default();
    let action = unsquash(&PlannerParams::default());
    let params = squash(&action);
    let mut spec = walk_spec(
        &EempRlConfig {
            episode_s: 4.0,
            ..cfg.clone()
        },
        params,
    );
    spec.profile = VelocityProfile::constant(
        0.0,
        VelocityCommand {
            vx_mps: 0.3,
            ..Default::default()
        },
    );
    let start = EempRlController::<FixedAction>::start_pose(&robot, &cfg, 0.3).unwrap();
    let mut trace_a = Vec::new();
    let mut eemp = eemp_controller(&robot, &spec).unwrap();
    let a = run_walk_with(&robot, &spec, &start, &mut eemp, |r| {
        trace_a.push(r.state.body.p_world)
    })
    .unwrap();
    let mut trace_b = Vec::new();
    let mut rl = EempRlController::new(&robot, cfg, FixedAction(action)).unwrap();
    let b = run_walk_with(&robot, &spec, &start, &mut rl, |r| {
        trace_b.push(r.state.body.p_world)
    })
    .unwrap();
    assert_eq!(trace_a, trace_b, "bit for bit");
    assert_eq!(a.metrics.cot, b.metrics.cot);
    assert!(!a.stats.fell);
    assert_eq!(rl.invalid_decisions, 0);
}

#[test]
fn the_environment_steps_and_rewards_per_decision() {
    let robot = RobotConfig::a1();
    let model = eemp_sim::backend::build_model(&robot, &Default::default()).unwrap();
    let cfg = EempRlConfig {
        episode_s: 2.0,
        ..Default::default()
    };
    let mut env = EempRlEnv::new(&robot, model, cfg.clone()).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let mut obs = vec![0f32; cfg.obs_dim()];
    let mut terms = vec![0.0; 3];
    env.reset(&mut rng, &mut obs);
    let mut n = 0;
    loop {
        let info = env.step(&[0.0, -1.0, 0.5, 0.0, 0.0], &mut rng, &mut obs, &mut terms);
        n += 1;
        assert!(obs.iter().all(|v| v.is_finite()));
        assert!(!info.invalid && !info.terminated, "step {n}: {info:?}");
        assert!(
            terms[0] < 0.0 && terms[1] > 0.0 && terms[2] > 0.0,
            "{terms:?}"
        );
        if info.truncated {
            break;
        }
    }
    assert_eq!(n, 4, "2 s of 0.5 s decisions");
    // A non-finite action is squashed to the range's middle, never outside.
    env.reset(&mut rng, &mut obs);
    let info = env.step(&[f32::NAN; 5], &mut rng, &mut obs, &mut terms);
    assert!(!info.invalid);
}

fn repo_file(path: &str) -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(path)
}

/// The shipped residual config (its table read from the repository), on the flat floor.
fn residual_config(episode_s: f64) -> EempRlConfig {
    let text = std::fs::read_to_string(repo_file("policies/a1_eemp_rl.toml")).unwrap();
    let mut c: eemp_rl::config::TrainConfig = toml::from_str(&text).unwrap();
    let r = c
        .eemp_rl
        .residual
        .as_mut()
        .expect("the shipped config is residual");
    r.table_file = repo_file(&r.table_file.display().to_string());
    c.eemp_rl.read_files().unwrap();
    c.eemp_rl.worlds = None;
    c.eemp_rl.episode_s = episode_s;
    c.eemp_rl.command_every_s = 1e3;
    c.eemp_rl.validate().unwrap();
    c.eemp_rl
}

/// `eemp walk --gait free --params-table tables/a1_free.toml --speed v --seed s`'s run.
fn table_walk_spec(cfg: &EempRlConfig, speed: f64, duration_s: f64, seed: u64) -> WalkSpec {
    let table = ParamsTable::load(&repo_file("tables/a1_free.toml")).unwrap();
    let planner = PlannerConfig {
        gait: Gait::Free,
        progress_factor: table.progress_factor.unwrap(),
        ..Default::default()
    };
    assert_eq!(
        planner.free_pairing, cfg.free_pairing,
        "the current swing rule"
    );
    let mut spec = WalkSpec::constant(
        planner,
        PlannerParams::default(),
        VelocityCommand {
            vx_mps: speed,
            ..Default::default()
        },
        duration_s,
    );
    spec.params_table = Some(table);
    spec.seed = seed;
    // EEMP-RL's controller, slip handling as its config says (the shipped config: on, as the
    // free gait's default).
    assert!(
        cfg.adapt_friction,
        "the shipped policy runs with slip handling"
    );
    spec.controller.slip.adapt_friction = cfg.adapt_friction;
    spec
}

#[test]
fn the_zero_residual_environment_walks_bit_for_bit_as_eemp_analytical_and_rewards_eq_8() {
    let robot = RobotConfig::a1();
    let model = eemp_sim::backend::build_model(&robot, &Default::default()).unwrap();
    let cfg = residual_config(3.0);
    let w = cfg.residual.as_ref().unwrap().rewards.clone();
    let table = ParamsTable::load(&repo_file("tables/a1_free.toml")).unwrap();
    let mut env = EempRlEnv::new(&robot, model, cfg.clone()).unwrap();
    for (speed, seed) in [(0.1, 3), (0.4, 5), (0.8, 7)] {
        let command = VelocityCommand {
            vx_mps: speed,
            ..Default::default()
        };
        let mut obs = vec![0f32; cfg.obs_dim()];
        let mut terms = vec![0.0; 4];
        env.reset_with(command, seed, &[], &mut obs);
        let mut ends = Vec::new();
        let mut energy_terms = Vec::new();
        let mut cots = Vec::new();
        loop {
            let info = env.step(
                &[0.0; 5],
                &mut ChaCha8Rng::seed_from_u64(0),
                &mut obs,
                &mut terms,
            );
            assert!(!info.terminated && !info.invalid, "{speed} m/s: {info:?}");
            ends.push(env.sim().ground_truth_state().body.p_world);
            energy_terms.push(terms[0]);
            cots.push(env.last_interval().unwrap().cot);
            if info.truncated {
                break;
            }
        }
        assert_eq!(ends.len(), 6, "3 s of 0.5 s decisions");
        // The same walk as `eemp walk`: the state after every physics step.
        let spec = table_walk_spec(&cfg, speed, 3.0, seed);
        let mut states = Vec::new();
        let mut power = Vec::new();
        run_walk(&robot, &spec, |r| {
            states.push(r.state.body.p_world);
            let qd = r.state.joints.map(|_, j| j.qd);
            power.push(eemp_core::metrics::positive_power_w(&qd, &r.output.torques));
        })
        .unwrap();
        for (k, p) in ends.iter().enumerate() {
            let after = 500 * (k + 1);
            if after < states.len() {
                assert_eq!(*p, states[after], "{speed} m/s, decision {k}: bit for bit");
            }
        }
        // Eq. (8) by hand over decision 3's window (steps 1500..2000 of the walk): E/(m g ΔD).
        let dt = robot.simulation.timestep_s;
        let energy: f64 = power[1500..2000].iter().map(|p| p * dt).sum();
        let (a, b) = (states[1500], states[1999]);
        let distance = (b.x - a.x).hypot(b.y - a.y);
        let cot = energy / (robot.total_mass_kg() * 9.81 * distance);
        let rewarded = cots[3].unwrap();
        assert!(
            (rewarded - cot).abs() < 1e-3 * cot,
            "{speed} m/s: rewarded CoT {rewarded}, eq. 8 {cot}"
        );
        let (cot_table, _) = table.metrics_at(speed).unwrap();
        let expect = w.energy * (1.0 - (rewarded / cot_table).clamp(0.0, w.ratio_clip));
        assert!((energy_terms[3] - expect).abs() < 1e-12);
    }
}

#[test]
fn the_zero_residual_controller_is_eemp_analytical_and_an_untrained_policy_answers_zero() {
    let robot = RobotConfig::a1();
    let cfg = residual_config(20.0);
    let spec = table_walk_spec(&cfg, 0.5, 3.0, 2);
    let mut a = Vec::new();
    run_walk(&robot, &spec, |r| a.push(r.state.body.p_world)).unwrap();
    let start = EempRlController::<FixedAction>::start_pose(&robot, &cfg, 0.5).unwrap();
    let mut rl = EempRlController::new(&robot, cfg.clone(), FixedAction([0.0; 5])).unwrap();
    let mut b = Vec::new();
    run_walk_with(&robot, &spec, &start, &mut rl, |r| {
        b.push(r.state.body.p_world)
    })
    .unwrap();
    assert_eq!(a, b, "bit for bit");
    // An untrained residual policy (zero last layer) answers exactly zero, whatever it sees.
    let text = std::fs::read_to_string(repo_file("policies/a1_eemp_rl.toml")).unwrap();
    let mut train: eemp_rl::config::TrainConfig = toml::from_str(&text).unwrap();
    train.eemp_rl = cfg;
    let policy = eemp_rl::policy::Policy::new(&train).unwrap();
    let obs: Vec<f32> = (0..train.eemp_rl.obs_dim())
        .map(|i| (i as f32).sin())
        .collect();
    assert!(policy.act(&obs).unwrap().iter().all(|&v| v == 0.0));
}

#[test]
fn the_deadband_drops_small_corrections_and_keeps_the_full_bound_reachable() {
    let robot = RobotConfig::a1();
    let mut cfg = residual_config(20.0);
    let r = cfg.residual.as_mut().unwrap();
    r.deadband = 0.3;
    // By hand, bounds [0.05 s, 0.03 m, 0.01 m, 0.04 m, 0.04 m]: swing time tanh(a) = 0.2 lies
    // inside ±0.3 → 0; step height 0.65 → (0.65 − 0.3)/0.7 = 0.5 → 0.015 m; body height −0.86 →
    // −0.8 → −0.008 m; r_x tanh(20) = 1 → the bound, 0.04 m; r_y NaN → 0.
    let a = |u: f64| u.atanh() as f32;
    let d = r.delta(&[a(0.2), a(0.65), a(-0.86), 20.0, f32::NAN]);
    let b = r.bounds.to_array();
    let want = [0.0, 0.5 * b[1], -0.8 * b[2], b[3], 0.0];
    for (i, ((got, want), bound)) in d.iter().zip(want).zip(b).enumerate() {
        assert!((got - want).abs() < 1e-6 * bound, "{i}: {got} vs {want}");
    }
    // Without the band the same action moves every finite component, and the correction is
    // b·tanh(a) bit for bit (what every policy trained before the band ran; a −0 correction
    // comes back as +0, which leaves the parameter the same).
    r.deadband = 0.0;
    assert!((r.delta(&[a(0.2)])[0] - 0.2 * b[0]).abs() < 1e-9);
    let actions = [a(0.2), 1e-8, 1.7, -3.1, -0.0];
    for (i, (got, act)) in r.delta(&actions).iter().zip(actions).enumerate() {
        let want = b[i] * (act as f64).tanh();
        assert!(
            got.to_bits() == want.to_bits() || (*got == 0.0 && want == 0.0),
            "{i}"
        );
    }
    // A policy whose answers stay inside the band walks bit for bit as the table.
    r.deadband = 0.3;
    let spec = table_walk_spec(&cfg, 0.5, 3.0, 2);
    let mut table = Vec::new();
    run_walk(&robot, &spec, |r| table.push(r.state.body.p_world)).unwrap();
    let start = EempRlController::<FixedAction>::start_pose(&robot, &cfg, 0.5).unwrap();
    let small = [0.25f64.atanh() as f32, -0.1, 0.2, -0.3, 0.05];
    let mut rl = EempRlController::new(&robot, cfg.clone(), FixedAction(small)).unwrap();
    let mut banded = Vec::new();
    run_walk_with(&robot, &spec, &start, &mut rl, |r| {
        banded.push(r.state.body.p_world)
    })
    .unwrap();
    assert_eq!(table, banded, "inside the band: the table, bit for bit");
    // Out-of-range bands are refused, naming the key.
    for bad in [-0.1, 0.95, f64::NAN] {
        cfg.residual.as_mut().unwrap().deadband = bad;
        let err = cfg
            .residual
            .as_ref()
            .unwrap()
            .validate()
            .unwrap_err()
            .to_string();
        assert!(err.contains("eemp_rl.residual.deadband"), "{bad}: {err}");
    }
}

#[test]
fn a_residual_config_with_a_bad_table_or_bounds_is_refused_naming_the_file_and_value() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(repo_file("policies/a1_eemp_rl.toml")).unwrap();
    let table = repo_file("tables/a1_free.toml").display().to_string();
    let trot = repo_file("tables/a1_trot.toml").display().to_string();
    let with = |from: &str, to: &str| text.replace(from, to);
    let cases = [
        (
            with("\"tables/a1_free.toml\"", "\"no/such/table.toml\""),
            "no/such/table.toml",
        ),
        (
            with("\"tables/a1_free.toml\"", &format!("{trot:?}")),
            "trot",
        ),
        (
            with("\"tables/a1_free.toml\"", &format!("{table:?}"))
                .replace("swing_time_s = 0.05", "swing_time_s = 0.2"),
            "eemp_rl.residual.bounds.swing_time_s",
        ),
        (
            with("\"tables/a1_free.toml\"", &format!("{table:?}"))
                .replace("body_height_m = 0.01", "body_height_m = -0.01"),
            "eemp_rl.residual.bounds.body_height_m",
        ),
    ];
    for (i, (config, want)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("c{i}.toml"));
        std::fs::write(&path, config).unwrap();
        let err = eemp_rl::config::TrainConfig::load(&path)
            .unwrap_err()
            .to_string();
        assert!(err.contains(want), "case {i}: {err}");
    }
    // A table without the selection metrics the reward needs.
    let stripped: String = std::fs::read_to_string(&table)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with("cot") && !l.starts_with("manipulability"))
        .map(|l| format!("{l}\n"))
        .collect();
    let bare = dir.path().join("bare.toml");
    std::fs::write(&bare, stripped).unwrap();
    let path = dir.path().join("c_bare.toml");
    std::fs::write(
        &path,
        with(
            "\"tables/a1_free.toml\"",
            &format!("{:?}", bare.display().to_string()),
        ),
    )
    .unwrap();
    let err = eemp_rl::config::TrainConfig::load(&path)
        .unwrap_err()
        .to_string();
    assert!(err.contains("bare.toml") && err.contains("cot"), "{err}");
}

/// The shipped CMA-ES config, shrunk to a run of seconds: 4 candidates × 1 episode of 1 s.
fn tiny_cmaes_config() -> eemp_rl::config::TrainConfig {
    let text = std::fs::read_to_string(repo_file("policies/a1_eemp_rl_cmaes.toml")).unwrap();
    let mut c: eemp_rl::config::TrainConfig = toml::from_str(&text).unwrap();
    assert_eq!(c.optimizer, eemp_rl::config::Optimizer::Cmaes);
    c.eemp_rl = residual_config(1.0);
    // The shipped PPO config's band: CMA-ES has none.
    c.eemp_rl.residual.as_mut().unwrap().deadband = 0.0;
    c.cmaes.population = 4;
    c.cmaes.episodes_per_candidate = 1;
    c.total_env_steps = 16;
    c.validate().unwrap();
    c
}

#[test]
fn cmaes_corrects_each_entry_within_its_bounds_and_table_i() {
    use eemp_rl::cma_table::corrected_table;
    let table = ParamsTable::load(&repo_file("tables/a1_free.toml")).unwrap();
    let bounds = [0.05, 0.03, 0.01, 0.04, 0.04];
    let n = 5 * table.entries.len();
    // x = 0 is the table itself (its selection metrics dropped: they were measured for it).
    let same = corrected_table(&table, &bounds, &vec![0.0; n]);
    for (a, b) in same.entries.iter().zip(&table.entries) {
        assert_eq!(a.params(), b.params());
        assert_eq!(a.cot, None);
    }
    // Any x stays within ±bounds of the entry and inside Table I.
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for _ in 0..200 {
        let x: Vec<f64> = (0..n).map(|_| rng.random_range(-20.0..20.0)).collect();
        let t = corrected_table(&table, &bounds, &x);
        t.validate().unwrap();
        for (a, b) in t.entries.iter().zip(&table.entries) {
            for (i, (va, vb)) in as_array(&a.params())
                .iter()
                .zip(as_array(&b.params()))
                .enumerate()
            {
                assert!((va - vb).abs() <= bounds[i] + 1e-12, "{va} vs {vb}");
                assert!(*va >= RANGES[i][0] && *va <= RANGES[i][1]);
            }
        }
    }
}

#[test]
fn cmaes_needs_the_residual_on_a_nearest_table_and_a_resumed_run_replays_to_the_same_table() {
    use eemp_rl::cma_table::train_cmaes;
    use eemp_rl::train::TrainOptions;
    let mut absolute = tiny_cmaes_config();
    absolute.eemp_rl.residual = None;
    let e = absolute.validate().unwrap_err().to_string();
    assert!(e.contains("optimizer") && e.contains("residual"), "{e}");
    let mut ppo_task = tiny_cmaes_config();
    ppo_task.task = eemp_rl::config::TaskKind::ModelFree;
    assert!(ppo_task.validate().is_err());
    let mut banded = tiny_cmaes_config();
    banded.eemp_rl.residual.as_mut().unwrap().deadband = 0.3;
    let e = banded.validate().unwrap_err().to_string();
    assert!(
        e.contains("eemp_rl.residual.deadband") && e.contains("0.3"),
        "{e}"
    );

    let config = tiny_cmaes_config();
    let robot = RobotConfig::a1();
    let dir = tempfile::tempdir().unwrap();
    let run = |out: &std::path::Path, resume: bool, threads: usize| {
        let opts = TrainOptions {
            out: out.to_path_buf(),
            resume,
            threads,
            max_iterations: None,
        };
        let mut generations = 0;
        let t = train_cmaes(&config, &robot, &opts, &mut |_| generations += 1).unwrap();
        (t, generations)
    };
    let (whole, gens) = run(&dir.path().join("a"), false, 2);
    assert!(gens >= 2, "{gens} generations");
    // The distribution moved: the table changed.
    let table = ParamsTable::load(&repo_file("tables/a1_free.toml")).unwrap();
    assert!(whole
        .entries
        .iter()
        .zip(&table.entries)
        .any(|(a, b)| a.params() != b.params()));
    // A run killed after its first generation (its cache cut there) resumes to the same table,
    // on one thread.
    let b = dir.path().join("b");
    std::fs::create_dir_all(b.join("checkpoint")).unwrap();
    let cache = std::fs::read_to_string(dir.path().join("a/checkpoint/evaluations.csv")).unwrap();
    let first: String = cache
        .lines()
        .filter(|l| l.starts_with("0,"))
        .map(|l| format!("{l}\n"))
        .collect();
    assert_eq!(first.lines().count(), 4);
    std::fs::write(b.join("checkpoint/evaluations.csv"), first).unwrap();
    let (resumed, _) = run(&b, true, 1);
    assert_eq!(resumed, whole);
    assert_eq!(
        std::fs::read_to_string(b.join("cmaes.csv"))
            .unwrap()
            .lines()
            .count(),
        gens + 1
    );
}

#[test]
fn cmaes_per_entry_keeps_only_the_corrections_that_beat_the_table_and_resumes() {
    use eemp_rl::cma_table::train_cmaes;
    use eemp_rl::train::TrainOptions;
    let mut config = tiny_cmaes_config();
    // Both checks need the per-entry search.
    for (name, set) in [
        ("cmaes.validation_episodes", (1, 0)),
        ("cmaes.nominal_episodes", (0, 1)),
    ] {
        (
            config.cmaes.validation_episodes,
            config.cmaes.nominal_episodes,
        ) = set;
        let e = config.validate().unwrap_err().to_string();
        assert!(e.contains(name) && e.contains("per_entry"), "{e}");
    }
    config.cmaes.per_entry = true;
    config.cmaes.nominal_cot_tolerance = 1.5;
    let e = config.validate().unwrap_err().to_string();
    assert!(
        e.contains("cmaes.nominal_cot_tolerance") && e.contains("1.5"),
        "{e}"
    );
    config.cmaes.nominal_cot_tolerance = 0.01;
    config.cmaes.validation_episodes = 1;
    let table = ParamsTable::load(&repo_file("tables/a1_free.toml")).unwrap();
    let n = table.entries.len();
    // Two generations of 4 candidates × 1 episode of 2 decisions per entry.
    config.total_env_steps = 16 * n as u64;
    config.validate().unwrap();
    let robot = RobotConfig::a1();
    let dir = tempfile::tempdir().unwrap();
    let run = |resume: bool| {
        let opts = TrainOptions {
            out: dir.path().to_path_buf(),
            resume,
            threads: 2,
            max_iterations: None,
        };
        let mut generations = 0;
        let t = train_cmaes(&config, &robot, &opts, &mut |_| generations += 1).unwrap();
        (t, generations)
    };
    let (found, gens) = run(false);
    assert!(gens >= 2 * n, "{gens} generations");
    // One validation row per entry: kept where the correction beat the table's return on the
    // disturbed episodes and stayed within 1 % of its energy per distance on the nominal ones,
    // without a fall; an entry not kept is the table's, bit for bit.
    let validation = std::fs::read_to_string(dir.path().join("validation.csv")).unwrap();
    let rows: Vec<Vec<String>> = validation
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    assert_eq!(rows.len(), n);
    for (k, row) in rows.iter().enumerate() {
        let f = |i: usize| row[i].parse::<f64>().unwrap();
        let (base, corrected) = (f(3), f(4));
        let (nominal_base, nominal_corrected, nominal_falls) = (f(6), f(7), f(8));
        assert!(nominal_base > 0.0 && nominal_corrected > 0.0, "{row:?}");
        let kept = row[9] == "true";
        assert_eq!(
            kept,
            corrected > base && nominal_corrected <= nominal_base * 1.01 && nominal_falls == 0.0,
            "entry {k}: {row:?}"
        );
        let same = found.entries[k].params() == table.entries[k].params();
        assert!(kept || same, "entry {k} not kept but changed");
    }
    // Resumed from its own cache, the run replays to the same table without simulating.
    let (again, _) = run(true);
    assert_eq!(again, found);
    assert_eq!(
        std::fs::read_to_string(dir.path().join("validation.csv")).unwrap(),
        validation
    );
    // A row cut by a kill is dropped from the cache on resume (else the next row written would
    // run on from it and the file could not be read again): resumed twice, the same table.
    let cache = dir.path().join("checkpoint/evaluations.csv");
    let mut text = std::fs::read_to_string(&cache).unwrap();
    text.push_str("3,00ab");
    std::fs::write(&cache, &text).unwrap();
    assert_eq!(run(true).0, found);
    assert!(std::fs::read_to_string(&cache).unwrap().ends_with('\n'));
    assert_eq!(run(true).0, found);
}

#[test]
fn nominal_worlds_are_the_robot_files_and_leave_the_other_worlds_as_they_were() {
    use eemp_rl::tasks::eemp_rl::{TrainWorld, TrainWorlds};
    let base = TrainWorlds::default();
    let half = TrainWorlds {
        nominal_share: 0.5,
        ..TrainWorlds::default()
    };
    let mut nominal = 0;
    for i in 0..64 {
        let (a, b) = (base.draw(7, i), half.draw(7, i));
        assert!(a.pushes && a.floor_friction.is_some());
        if b == TrainWorld::nominal() {
            nominal += 1;
            assert!(b.terrain.rough.is_none() && b.terrain.friction_patch.is_empty());
            assert_eq!(
                (b.floor_friction, b.payload_kg, b.pushes),
                (None, 0.0, false)
            );
        } else {
            assert_eq!(a, b, "world {i}");
        }
    }
    assert!((20..=44).contains(&nominal), "{nominal} of 64 nominal");
    let bad = TrainWorlds {
        nominal_share: 1.5,
        ..TrainWorlds::default()
    };
    let err = bad.validate().unwrap_err().to_string();
    assert!(err.contains("eemp_rl.worlds.nominal_share"), "{err}");
}

#[test]
fn the_paired_reward_is_the_policys_terms_minus_the_tables_from_the_same_state() {
    use eemp_rl::tasks::OnClosedLoop;
    use eemp_sim::closed_loop::{Push, StateSource};
    let robot = RobotConfig::a1();
    let model = eemp_sim::backend::build_model(&robot, &Default::default()).unwrap();
    let mut cfg = residual_config(2.0);
    let mut paired_cfg = cfg.clone();
    paired_cfg.residual.as_mut().unwrap().paired = true;
    cfg.residual.as_mut().unwrap().paired = false;
    // On the filter with sensor noise and a push inside the second window: the copy must carry
    // the noise generator and the pending push, or the zero action would not score exactly 0.
    let env_on_kf = |cfg: &EempRlConfig| {
        let mut env = EempRlEnv::new(&robot, model.clone(), cfg.clone()).unwrap();
        env.set_state_source(&StateSource::kf(&robot, Default::default(), 11))
            .unwrap();
        env
    };
    let push = [Push::step(0.8, nalgebra::Vector3::new(0.0, 0.4, 0.0))];
    let command = VelocityCommand {
        vx_mps: 0.4,
        ..Default::default()
    };
    let mut obs = vec![0f32; cfg.obs_dim()];
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let first_window = |cfg: &EempRlConfig, action: &[f32; 5]| {
        let mut env = env_on_kf(cfg);
        let mut obs = vec![0f32; cfg.obs_dim()];
        let mut terms = vec![0.0; 4];
        env.reset_with(command, 4, &push, &mut obs);
        // The command starts at 0.5 s: the second window is the first that walks.
        for a in [&[0.0; 5], action] {
            let info = env.step(a, &mut ChaCha8Rng::seed_from_u64(0), &mut obs, &mut terms);
            assert!(!info.terminated, "{info:?}");
        }
        terms
    };
    // A zero correction earns exactly 0 in every window of the episode.
    let mut env = env_on_kf(&paired_cfg);
    env.reset_with(command, 4, &push, &mut obs);
    let mut terms = vec![0.0; 4];
    loop {
        let info = env.step(&[0.0; 5], &mut rng, &mut obs, &mut terms);
        assert!(!info.terminated);
        assert_eq!(terms, [0.0; 4], "the table against itself");
        if info.truncated {
            break;
        }
    }
    // A real correction (wider ellipses, a higher step) in the second window: the paired terms
    // are the plain terms of that window minus the plain terms of the zero action's window, both
    // measured by separate environments from the same state.
    let action = [0.0, 1.5, 0.0, 2.0, 2.0];
    let paired = first_window(&paired_cfg, &action);
    let plain = first_window(&cfg, &action);
    let table = first_window(&cfg, &[0.0; 5]);
    assert!(
        plain[0] != table[0],
        "the correction changes the energy term"
    );
    for i in 0..3 {
        assert!(
            (paired[i] - (plain[i] - table[i])).abs() < 1e-12,
            "term {i}: {} vs {} - {}",
            paired[i],
            plain[i],
            table[i]
        );
    }
    assert_eq!(paired[3], 0.0);
}

/// `rewards.objective = "electrical-idle"`: the energy term is the window's battery CoT (the
/// electrical CoT with idle power, the walk metrics' own) against a table whose `cot` counts
/// the same; a table selected under eq. (8) is refused, naming the key.
#[test]
fn the_electrical_objective_rewards_the_battery_cot_against_a_table_of_the_same() {
    use eemp_core::metrics::CotObjective;
    let mut cfg = residual_config(3.0);
    let mut r = cfg.residual.take().unwrap();
    r.rewards.objective = CotObjective::ElectricalIdle;
    // The eq.-8 table: refused.
    cfg.residual = Some(r.clone());
    let err = cfg.validate().unwrap_err().to_string();
    assert!(
        err.contains("eemp_rl.residual.rewards.objective") && err.contains("eq8"),
        "{err}"
    );
    // The same table marked as holding battery CoTs (its values are eq. 8's: only the ratio's
    // denominator, which the check below reads back).
    let mut table = r.table.take().unwrap();
    table.objective = CotObjective::ElectricalIdle;
    r.table = Some(table.clone());
    cfg.residual = Some(r.clone());
    cfg.validate().unwrap();

    let robot = RobotConfig::a1();
    let model = eemp_sim::backend::build_model(&robot, &Default::default()).unwrap();
    let mut env = EempRlEnv::new(&robot, model, cfg.clone()).unwrap();
    let speed = 0.4;
    let command = VelocityCommand {
        vx_mps: speed,
        ..Default::default()
    };
    let mut obs = vec![0f32; cfg.obs_dim()];
    let mut terms = vec![0.0; 4];
    env.reset_with(command, 3, &[], &mut obs);
    let mut checked = 0;
    loop {
        let info = env.step(
            &[0.0; 5],
            &mut ChaCha8Rng::seed_from_u64(0),
            &mut obs,
            &mut terms,
        );
        assert!(!info.terminated && !info.invalid, "{info:?}");
        let m = env.last_interval().unwrap();
        if let (Some(battery), Some(eq8)) = (m.electrical.as_ref().and_then(|e| e.cot), m.cot) {
            assert!(battery > 1.5 * eq8, "battery {battery} vs eq. 8 {eq8}");
            let (cot_table, _) = table.metrics_at(speed).unwrap();
            let w = &r.rewards;
            let expect = w.energy * (1.0 - (battery / cot_table).clamp(0.0, w.ratio_clip));
            assert!(
                (terms[0] - expect).abs() < 1e-12,
                "{} vs {expect}",
                terms[0]
            );
            checked += 1;
        }
        if info.truncated {
            break;
        }
    }
    assert!(checked >= 3, "{checked} windows with a CoT");
    // Without a motor model the electrical objective cannot be measured: refused by name.
    let mut bare = robot.clone();
    bare.motor = None;
    let model = eemp_sim::backend::build_model(&bare, &Default::default()).unwrap();
    let err = EempRlEnv::new(&bare, model, cfg).err().unwrap();
    assert!(
        err.contains("rewards.objective") && err.contains("[motor]"),
        "{err}"
    );
}
