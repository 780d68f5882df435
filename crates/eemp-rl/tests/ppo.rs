//! PPO learns, its gradient is right, the environments are deterministic whatever the thread
//! count, a resumed run equals an uninterrupted one, and policy files round-trip.

use eemp_core::robot::RobotConfig;
use eemp_rl::config::{Activation, LrSchedule, NetworkConfig, PpoConfig, TaskKind, TrainConfig};
use eemp_rl::env::{env_seed, VecEnv};
use eemp_rl::nn::ActorCritic;
use eemp_rl::policy::Policy;
use eemp_rl::ppo::{ppo_loss, Minibatch};
use eemp_rl::tasks::model_free::{training_model, ModelFreeConfig, ModelFreeEnv, TrainPushes};
use eemp_rl::train::{train, IterationLog, TrainOptions};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn cart_pole(lr: f64, steps: u64) -> TrainConfig {
    TrainConfig {
        task: TaskKind::CartPole,
        num_envs: 16,
        steps_per_env: 64,
        total_env_steps: steps,
        checkpoint_every: 2,
        ppo: PpoConfig {
            learning_rate: lr,
            lr_schedule: LrSchedule::Constant,
            entropy_coef: 0.0,
            init_std: 0.5,
            min_std: 0.05,
            ..Default::default()
        },
        network: NetworkConfig {
            actor_hidden: vec![32, 32],
            critic_hidden: vec![32, 32],
            activation: Activation::Tanh,
            actor_output_gain: 0.01,
        },
        ..Default::default()
    }
}

fn run(
    config: &TrainConfig,
    out: &std::path::Path,
    resume: bool,
    max: Option<usize>,
) -> (Policy, Vec<IterationLog>) {
    run_on(config, out, resume, max, 2)
}

fn run_on(
    config: &TrainConfig,
    out: &std::path::Path,
    resume: bool,
    max: Option<usize>,
    threads: usize,
) -> (Policy, Vec<IterationLog>) {
    let mut logs = Vec::new();
    let p = train(
        config,
        &RobotConfig::a1(),
        &TrainOptions {
            out: out.to_path_buf(),
            resume,
            threads,
            max_iterations: max,
        },
        &mut |l| logs.push(l.clone()),
    )
    .unwrap();
    (p, logs)
}

#[test]
fn ppo_balances_the_cart_pole_and_does_not_with_learning_rate_zero() {
    let dir = tempfile::tempdir().unwrap();
    let (_, logs) = run(&cart_pole(1e-3, 40_960), &dir.path().join("a"), false, None);
    let learned = logs.last().unwrap().mean_return;
    let (_, logs0) = run(&cart_pole(0.0, 40_960), &dir.path().join("b"), false, None);
    let frozen = logs0.last().unwrap().mean_return;
    // Episodes last ≤ 200 steps (+1 per step). A random policy keeps the pole up ~25 steps.
    assert!(learned >= 100.0, "PPO reached only {learned}");
    assert!(
        frozen <= 50.0,
        "learning rate 0 reached {frozen}: the test cannot fail"
    );
}

fn params(p: &Policy) -> Vec<Vec<f32>> {
    p.net
        .named()
        .iter()
        .map(|(_, t)| t.flatten_all().unwrap().to_vec1::<f32>().unwrap())
        .collect()
}

#[test]
fn a_resumed_cart_pole_run_equals_an_uninterrupted_one() {
    let dir = tempfile::tempdir().unwrap();
    let config = cart_pole(1e-3, 6 * 16 * 64);
    let (whole, logs) = run(&config, &dir.path().join("whole"), false, None);
    let split = dir.path().join("split");
    run(&config, &split, false, Some(4));
    let (resumed, logs_r) = run(&config, &split, true, None);
    assert_eq!(params(&whole), params(&resumed));
    assert_eq!(logs_r.first().unwrap().iteration, 5);
    assert_eq!(
        logs.last().unwrap().mean_return,
        logs_r.last().unwrap().mean_return
    );
    let rows = std::fs::read_to_string(split.join("train.csv")).unwrap();
    assert_eq!(
        rows.lines().count(),
        1 + 6,
        "one header and one row per iteration"
    );
}

#[test]
fn a_finished_run_extended_to_more_steps_equals_the_longer_run() {
    let dir = tempfile::tempdir().unwrap();
    let long = cart_pole(1e-3, 6 * 16 * 64);
    let (whole, _) = run(&long, &dir.path().join("whole"), false, None);
    // A run of 4 iterations (it checkpoints at its end), then the same config with 6.
    let short = cart_pole(1e-3, 4 * 16 * 64);
    let ext = dir.path().join("extended");
    run(&short, &ext, false, None);
    let (extended, logs) = run(&long, &ext, true, None);
    assert_eq!(logs.first().unwrap().iteration, 5);
    assert_eq!(params(&whole), params(&extended));
    // Anything else changed, or a schedule that depends on the total, is refused.
    let mut other = long.clone();
    other.ppo.learning_rate = 2e-3;
    let refused = |c: &TrainConfig, out: &std::path::Path| {
        train(
            c,
            &RobotConfig::a1(),
            &TrainOptions {
                out: out.to_path_buf(),
                resume: true,
                threads: 1,
                max_iterations: None,
            },
            &mut |_| {},
        )
        .err()
        .expect("refused")
    };
    assert!(refused(&other, &ext).contains("another config"));
    let mut linear = short.clone();
    linear.ppo.lr_schedule = LrSchedule::Linear;
    let lin = dir.path().join("linear");
    run(&linear, &lin, false, None);
    let mut linear_long = linear.clone();
    linear_long.total_env_steps = long.total_env_steps;
    assert!(refused(&linear_long, &lin).contains("linear"));
}

#[test]
fn a_resumed_model_free_run_equals_an_uninterrupted_one() {
    // A smoke training of the A1 task (seconds): MuJoCo state, warm starts, normaliser, every
    // RNG and the pushes still to come in each episode must survive the checkpoint (pushes
    // every 0.5 s: the checkpoint at 0.64 s falls between two).
    let dir = tempfile::tempdir().unwrap();
    let config = TrainConfig {
        num_envs: 4,
        steps_per_env: 16,
        total_env_steps: 3 * 4 * 16,
        checkpoint_every: 1,
        network: NetworkConfig {
            actor_hidden: vec![16],
            critic_hidden: vec![16],
            activation: Activation::Elu,
            actor_output_gain: 0.01,
        },
        model_free: ModelFreeConfig {
            pushes: TrainPushes {
                every_s: 0.5,
                max_dv_mps: 0.5,
            },
            ..Default::default()
        },
        ..Default::default()
    };
    let (whole, logs) = run(&config, &dir.path().join("whole"), false, None);
    let split = dir.path().join("split");
    run(&config, &split, false, Some(2));
    let (resumed, logs_r) = run(&config, &split, true, None);
    assert_eq!(params(&whole), params(&resumed));
    assert_eq!(logs.last().unwrap().terms, logs_r.last().unwrap().terms);
    assert_eq!(whole.normalizer, resumed.normalizer);
    assert!(dir.path().join("whole/policy.safetensors").exists());
}

#[test]
fn training_on_one_or_two_threads_gives_the_same_policy() {
    let dir = tempfile::tempdir().unwrap();
    let config = TrainConfig {
        num_envs: 4,
        steps_per_env: 16,
        total_env_steps: 2 * 4 * 16,
        network: NetworkConfig {
            actor_hidden: vec![16],
            critic_hidden: vec![16],
            activation: Activation::Elu,
            actor_output_gain: 0.01,
        },
        ..Default::default()
    };
    let (a, _) = run_on(&config, &dir.path().join("one"), false, None, 1);
    let (b, _) = run_on(&config, &dir.path().join("two"), false, None, 2);
    assert_eq!(params(&a), params(&b));
    assert_eq!(a.normalizer, b.normalizer);
}

#[test]
fn stepping_on_one_or_two_threads_gives_identical_rollouts() {
    let robot = RobotConfig::a1();
    let config = TrainConfig::default();
    let model = training_model(&robot, &config.model_free).unwrap();
    let make = |threads| {
        let envs = (0..5)
            .map(|_| ModelFreeEnv::new(&robot, model.clone(), config.model_free.clone()).unwrap())
            .collect();
        VecEnv::new(envs, 11, threads).unwrap()
    };
    let (mut a, mut b) = (make(1), make(2));
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for _ in 0..40 {
        let act: Vec<f32> = (0..5 * 12).map(|_| rng.random_range(-2.0..2.0)).collect();
        a.step(&act);
        b.step(&act);
        assert_eq!(a.obs, b.obs);
        assert_eq!(a.terms, b.terms);
        assert_eq!(a.infos, b.infos);
    }
}

#[test]
fn reseeding_used_environments_restarts_them_as_freshly_built_ones() {
    // What the Python bindings' reset(seed) relies on: reseed(env_seed(s, i)) after any
    // history steps exactly as VecEnv::new(.., s, ..) (first episodes staggered again).
    let robot = RobotConfig::a1();
    let mut config = TrainConfig::default();
    config.model_free.episode_s = 0.4;
    let model = training_model(&robot, &config.model_free).unwrap();
    let make = |seed| {
        let envs = (0..3)
            .map(|_| ModelFreeEnv::new(&robot, model.clone(), config.model_free.clone()).unwrap())
            .collect();
        VecEnv::new(envs, seed, 1).unwrap()
    };
    let (mut fresh, mut used) = (make(4), make(99));
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let mut actions = || -> Vec<f32> { (0..3 * 12).map(|_| rng.random_range(-1.0..1.0)).collect() };
    for _ in 0..30 {
        used.step(&actions());
    }
    used.reseed(&(0..3).map(|i| env_seed(4, i)).collect::<Vec<_>>())
        .unwrap();
    assert_eq!(fresh.obs, used.obs);
    let mut ends = 0;
    for _ in 0..60 {
        let a = actions();
        fresh.step(&a);
        used.step(&a);
        assert_eq!(fresh.obs, used.obs);
        assert_eq!(fresh.infos, used.infos);
        ends += fresh.ended.len();
    }
    assert!(ends >= 3, "20-step episodes end in the window");
    assert!(used.reseed(&[1, 2]).is_err());
}

#[test]
fn a_nan_action_ends_the_episode_is_counted_and_never_reaches_the_observation() {
    let robot = RobotConfig::a1();
    let config = TrainConfig::default();
    let model = training_model(&robot, &config.model_free).unwrap();
    let envs = (0..2)
        .map(|_| ModelFreeEnv::new(&robot, model.clone(), config.model_free.clone()).unwrap())
        .collect();
    let mut v = VecEnv::new(envs, 3, 1).unwrap();
    let mut act = vec![0f32; 24];
    act[13] = f32::NAN;
    v.step(&act);
    assert!(v.infos[1].invalid && v.infos[1].terminated && !v.infos[1].truncated);
    assert!(!v.infos[0].invalid);
    assert!(v.obs.iter().all(|x| x.is_finite()));
    assert_eq!(v.ended.len(), 1);
    assert!(v.ended[0].invalid && !v.ended[0].fell);
}

#[test]
fn the_ppo_gradient_matches_finite_differences_on_a_tiny_network() {
    use candle_core::{DType, Device, Tensor};
    let net = NetworkConfig {
        actor_hidden: vec![4],
        critic_hidden: vec![3],
        activation: Activation::Tanh,
        actor_output_gain: 0.01,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let ac = ActorCritic::new(3, 2, &net, 0.7, &mut rng).unwrap();
    let m = 6;
    let r = |rng: &mut ChaCha8Rng, n: usize, s: f32| -> Vec<f32> {
        (0..n).map(|_| rng.random_range(-s..s)).collect()
    };
    let dev = Device::Cpu;
    let obs = Tensor::from_vec(r(&mut rng, m * 3, 1.0), (m, 3), &dev).unwrap();
    let actions = Tensor::from_vec(r(&mut rng, m * 2, 1.0), (m, 2), &dev).unwrap();
    // Old log-probabilities close to the current ones: ratios near 1, inside the clip range.
    let lp = ac
        .log_prob(&ac.mean(&obs).unwrap(), &actions)
        .unwrap()
        .detach();
    let old_lp = (lp + Tensor::from_vec(r(&mut rng, m, 0.05), m, &dev).unwrap()).unwrap();
    let mb = Minibatch {
        obs,
        actions,
        old_log_probs: old_lp,
        old_values: Tensor::from_vec(r(&mut rng, m, 3.0), m, &dev).unwrap(),
        returns: Tensor::from_vec(r(&mut rng, m, 2.0), m, &dev).unwrap(),
        advantages: Tensor::from_vec(r(&mut rng, m, 1.0), m, &dev).unwrap(),
        mirrored: None,
    };
    let cfg = PpoConfig {
        entropy_coef: 0.05,
        value_coef: 0.5,
        ..Default::default()
    };
    let loss = ppo_loss(&ac, &mb, &cfg).unwrap();
    let grads = loss.total.backward().unwrap();
    let f = |ac: &ActorCritic| -> f64 {
        ppo_loss(ac, &mb, &cfg)
            .unwrap()
            .total
            .to_dtype(DType::F64)
            .unwrap()
            .to_scalar::<f64>()
            .unwrap()
    };
    let h = 1e-2f32;
    let mut checked = 0;
    for var in ac.vars() {
        let g: Vec<f32> = grads
            .get(var.as_tensor())
            .unwrap()
            .flatten_all()
            .unwrap()
            .to_vec1()
            .unwrap();
        let base: Vec<f32> = var.as_tensor().flatten_all().unwrap().to_vec1().unwrap();
        let shape = var.as_tensor().dims().to_vec();
        for i in 0..base.len() {
            let mut p = base.clone();
            p[i] += h;
            var.set(&Tensor::from_vec(p.clone(), shape.clone(), &dev).unwrap())
                .unwrap();
            let up = f(&ac);
            p[i] -= 2.0 * h;
            var.set(&Tensor::from_vec(p, shape.clone(), &dev).unwrap())
                .unwrap();
            let down = f(&ac);
            var.set(&Tensor::from_vec(base.clone(), shape.clone(), &dev).unwrap())
                .unwrap();
            let fd = (up - down) / (2.0 * h as f64);
            assert!(
                (fd - g[i] as f64).abs() <= 2e-3 + 2e-2 * fd.abs(),
                "parameter {i} of a {shape:?} tensor: autodiff {} vs finite difference {fd}",
                g[i]
            );
            checked += 1;
        }
    }
    assert!(checked > 40);
}

#[test]
fn the_normaliser_and_the_network_round_trip_through_a_policy_file() {
    let dir = tempfile::tempdir().unwrap();
    let config = TrainConfig::default();
    let mut p = Policy::new(&config).unwrap();
    let d = p.normalizer.dim();
    let data: Vec<f32> = (0..d * 50)
        .map(|i| ((i * 31) % 97) as f32 * 0.03 - 1.0)
        .collect();
    p.normalizer.update(&data);
    let path = dir.path().join("p.safetensors");
    p.save(&path).unwrap();
    let q = Policy::load(&path, Some(TaskKind::ModelFree)).unwrap();
    assert_eq!(p.normalizer, q.normalizer);
    assert_eq!(params(&p), params(&q));
    assert_eq!(p.act(&data[..d]).unwrap(), q.act(&data[..d]).unwrap());
    // The wrong task, a missing file, a wrong shape: errors that name the file.
    let e = Policy::load(&path, Some(TaskKind::CartPole)).err().unwrap();
    assert!(
        e.contains("p.safetensors") && e.contains("model-free"),
        "{e}"
    );
    let e = Policy::load(&dir.path().join("none.safetensors"), None)
        .err()
        .unwrap();
    assert!(e.contains("none.safetensors"), "{e}");
    let mut f = eemp_rl::tensor_file::TensorFile::load(&path).unwrap();
    f.insert("actor.0.weight", vec![2, 2], vec![0.0; 4]);
    let bad = dir.path().join("bad.safetensors");
    f.save(&bad).unwrap();
    let e = Policy::load(&bad, None).err().unwrap();
    assert!(
        e.contains("bad.safetensors") && e.contains("actor.0.weight"),
        "{e}"
    );
    std::fs::write(&bad, b"not a tensor file").unwrap();
    assert!(Policy::load(&bad, None).is_err());
}

#[test]
fn a_config_out_of_range_names_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("c.toml");
    std::fs::write(&p, "[ppo]\nclip = 3.0\n").unwrap();
    let e = TrainConfig::load(&p).unwrap_err().to_string();
    assert!(e.contains("ppo.clip") && e.contains("c.toml"), "{e}");
    std::fs::write(&p, "[model_free]\npolicy_period_s = 0.021\n").unwrap();
    let e = TrainConfig::load(&p).unwrap_err().to_string();
    assert!(e.contains("policy_period_s"), "{e}");
    std::fs::write(&p, "num_envs = \"many\"\n").unwrap();
    assert!(TrainConfig::load(&p).is_err());
}

#[test]
fn the_ppo_loss_equals_a_hand_computed_value_with_both_clips_active() {
    use candle_core::{Device, Tensor};
    let net = NetworkConfig {
        actor_hidden: vec![4],
        critic_hidden: vec![3],
        activation: Activation::Tanh,
        actor_output_gain: 0.01,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let ac = ActorCritic::new(3, 2, &net, 0.7, &mut rng).unwrap();
    let dev = Device::Cpu;
    let obs = Tensor::new(&[[0.3f32, -0.2, 0.5]], &dev).unwrap();
    let actions = Tensor::new(&[[0.1f32, -0.4]], &dev).unwrap();
    let lp = ac.log_prob(&ac.mean(&obs).unwrap(), &actions).unwrap();
    let v: f32 = ac.value(&obs).unwrap().to_vec1::<f32>().unwrap()[0];
    // Ratio 1.5 with advantage 2: the clipped surrogate takes 1.2 · 2 (ε = 0.2).
    let old_lp = (lp - 1.5f64.ln()).unwrap();
    // V moved 0.5 from V_old: the clipped value V_old + 0.2 is further from the return V + 1,
    // so the value loss is (0.5 − 0.2 + 1)² = 1.69.
    let mb = Minibatch {
        obs,
        actions,
        old_log_probs: old_lp,
        old_values: Tensor::new(&[v - 0.5], &dev).unwrap(),
        returns: Tensor::new(&[v + 1.0], &dev).unwrap(),
        advantages: Tensor::new(&[2.0f32], &dev).unwrap(),
        mirrored: None,
    };
    let cfg = PpoConfig {
        value_coef: 0.5,
        entropy_coef: 0.1,
        ..Default::default()
    };
    let loss = ppo_loss(&ac, &mb, &cfg).unwrap();
    let entropy =
        2.0 * (0.7f64.ln() + 0.5 * (2.0 * std::f64::consts::PI * std::f64::consts::E).ln());
    let expected = -1.2 * 2.0 + 0.5 * 1.69 - 0.1 * entropy;
    let got = loss.total.to_scalar::<f32>().unwrap() as f64;
    assert!(
        (got - expected).abs() < 1e-4,
        "loss {got}, by hand {expected}"
    );
    assert!((loss.value.to_scalar::<f32>().unwrap() as f64 - 1.69).abs() < 1e-4);
}

#[test]
fn a_policy_trains_on_the_kalman_filter_seeing_noisy_sensors() {
    use eemp_rl::config::TrainEstimator;
    use eemp_rl::train::{make_envs_with, AnyVecEnv};
    let robot = RobotConfig::a1();
    let mut config = TrainConfig {
        num_envs: 2,
        steps_per_env: 8,
        total_env_steps: 16,
        ..Default::default()
    };
    let envs = |c: &TrainConfig| match make_envs_with(c, &robot, 1, None).unwrap() {
        AnyVecEnv::ModelFree(v) => v,
        _ => unreachable!(),
    };
    let mut gt = envs(&config);
    config.estimator = TrainEstimator::Kf;
    let mut kf = envs(&config);
    // The same episodes (same seed), seen through the filter: the first observation is the
    // known start pose on both; after steps the filter's noisy view differs, but stays close.
    assert_eq!(gt.obs, kf.obs);
    let zeros = vec![0.0f32; 2 * 12];
    for _ in 0..10 {
        gt.step(&zeros);
        kf.step(&zeros);
    }
    assert_ne!(gt.obs, kf.obs);
    assert!(kf.obs.iter().all(|x| x.is_finite()));
    let worst = gt
        .obs
        .iter()
        .zip(&kf.obs)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(
        worst < 2.0,
        "the filter's observation is {worst} off the truth's"
    );
    // A training run on the filter, one iteration; cart-pole has no filter to train on.
    let dir = tempfile::tempdir().unwrap();
    run(&config, dir.path(), false, None);
    let mut cp = cart_pole(1e-3, 1024);
    cp.estimator = TrainEstimator::Kf;
    assert!(cp.validate().unwrap_err().to_string().contains("estimator"));
}

#[test]
fn a_fine_tuned_run_starts_from_its_init_policy() {
    let dir = tempfile::tempdir().unwrap();
    let (a, _) = run(&cart_pole(1e-3, 40_960), &dir.path().join("a"), false, None);
    let file = dir.path().join("a/policy.safetensors");
    // Learning rate 0 keeps the networks where they start: the init policy's, and it plays as
    // well as it (a fresh network at learning rate 0 does not: see the test above).
    let mut tune = cart_pole(0.0, 16 * 64 * 2);
    tune.init_policy = Some(file.clone());
    let (b, logs) = run(&tune, &dir.path().join("b"), false, None);
    assert_eq!(params(&a), params(&b));
    assert!(
        logs.last().unwrap().mean_return >= 100.0,
        "{}",
        logs.last().unwrap().mean_return
    );
    // Other network shapes are refused, naming the file.
    let mut other = tune.clone();
    other.network.actor_hidden = vec![16];
    let e = train(
        &other,
        &RobotConfig::a1(),
        &TrainOptions {
            out: dir.path().join("c"),
            resume: false,
            threads: 1,
            max_iterations: None,
        },
        &mut |_| {},
    )
    .err()
    .expect("refused");
    assert!(
        e.contains("init_policy") && e.contains("policy.safetensors"),
        "{e}"
    );
    assert!(!dir.path().join("c").exists());
}
