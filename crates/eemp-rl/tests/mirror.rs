//! The left–right mirror (issue 21): the mirrored observation of a state is the observation of
//! the mirrored simulation, the A1's dynamics are (nearly) mirror-symmetric, and the mirror loss
//! is the mean squared gap between π(M_o o) and M_a π(o).

use candle_core::{Device, Tensor};
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::planner::VelocityCommand;
use eemp_core::robot::RobotConfig;
use eemp_rl::config::{Activation, NetworkConfig, PpoConfig};
use eemp_rl::mirror::{mirror_state, MirrorBuilder, JOINTS};
use eemp_rl::nn::ActorCritic;
use eemp_rl::ppo::{ppo_loss, ActionMirror, Minibatch};
use eemp_rl::tasks::model_free::{
    action_mirror, check_mirror_pose, observation_mirror, observe, training_model, ExtraObs,
    ModelFreeConfig, PolicyMemory,
};
use eemp_sim::Simulation;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn mirrored_memory(m: &PolicyMemory) -> PolicyMemory {
    let a = action_mirror();
    let frame = MirrorBuilder::new().per_leg(JOINTS).per_leg(JOINTS).build();
    let torques: Vec<f32> = m.last_torques.iter().map(|&t| t as f32).collect();
    let t = a.apply_rows(&torques);
    PolicyMemory {
        prev_action: a.apply_rows(&m.prev_action),
        history: m.history.iter().map(|h| frame.apply_rows(h)).collect(),
        last_torques: std::array::from_fn(|i| t[i] as f64),
        // The mirrored robot is half a gait cycle on.
        clock_phase: (m.clock_phase + 0.5).rem_euclid(1.0),
        clock_step: m.clock_step,
    }
}

/// A walking-like state: the robot dropped from standing with random torques for a while.
fn some_state(sim: &mut Simulation, robot: &RobotConfig, rng: &mut ChaCha8Rng) {
    sim.reset(Vector3::new(0.0, 0.0, 0.33), &robot.standing_pose());
    for _ in 0..40 {
        let tau = LegMap::from_fn(|_| Vector3::from_fn(|_, _| rng.random_range(-8.0..8.0)));
        sim.step_bare(&tau);
    }
}

#[test]
fn the_mirrored_observation_of_a_state_is_the_observation_of_the_mirrored_simulation() {
    let robot = RobotConfig::a1();
    check_mirror_pose(&robot.standing_pose()).unwrap();
    let model = training_model(&robot, &ModelFreeConfig::default()).unwrap();
    let mut sim = Simulation::with_model(model.clone(), &robot).unwrap();
    let mut mirrored = Simulation::with_model(model, &robot).unwrap();
    let kin = LegKinematics::new(&robot);
    let q0 = robot.standing_pose();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for (history, clock_hz) in [(0, 0.0), (2, 0.0), (1, 2.0)] {
        let extra = ExtraObs {
            gait_clock_hz: clock_hz,
            ..ExtraObs::default()
        };
        let map = observation_mirror(&extra, history);
        some_state(&mut sim, &robot, &mut rng);
        let s = sim.ground_truth_state();
        mirrored.set_state(&mirror_state(&s));
        let s_m = mirrored.ground_truth_state();
        let mut memory = PolicyMemory::new(history);
        memory.start(&s, &q0);
        memory.clock_phase = 0.17;
        memory.prev_action = (0..12).map(|_| rng.random_range(-1.0..1.0)).collect();
        memory.last_torques = std::array::from_fn(|_| rng.random_range(-20.0..20.0));
        for h in memory.history.iter_mut() {
            h.iter_mut().for_each(|v| *v += rng.random_range(-0.3..0.3));
        }
        let cmd = VelocityCommand {
            vx_mps: 0.4,
            vy_mps: 0.2,
            yaw_rate_rps: -0.6,
        };
        let cmd_m = VelocityCommand {
            vx_mps: 0.4,
            vy_mps: -0.2,
            yaw_rate_rps: 0.6,
        };
        let mut o = vec![0f32; map.len()];
        let mut o_m = vec![0f32; map.len()];
        assert_eq!(
            observe(&extra, &kin, &q0, &s, &cmd, &memory, &mut o),
            map.len()
        );
        observe(
            &extra,
            &kin,
            &q0,
            &s_m,
            &cmd_m,
            &mirrored_memory(&memory),
            &mut o_m,
        );
        let want = map.apply_rows(&o);
        for (i, (a, b)) in want.iter().zip(&o_m).enumerate() {
            assert!(
                (a - b).abs() < 1e-5,
                "history {history}, clock {clock_hz} Hz, entry {i}: {a} against {b}"
            );
        }
        // Not vacuous: the state is not its own mirror.
        assert!(o.iter().zip(&o_m).any(|(a, b)| (a - b).abs() > 1e-2));
    }
}

/// The largest joint-angle gap (rad) between the mirror of a run under random torques and the
/// run of the mirrored start under the mirrored torques, after 0.1 s.
fn mirror_gap(robot: &RobotConfig) -> f64 {
    let model = training_model(robot, &ModelFreeConfig::default()).unwrap();
    let mut sim = Simulation::with_model(model.clone(), robot).unwrap();
    let mut mirrored = Simulation::with_model(model, robot).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    some_state(&mut sim, robot, &mut rng);
    mirrored.set_state(&mirror_state(&sim.ground_truth_state()));
    for _ in 0..25 {
        let tau = LegMap::from_fn(|_| Vector3::from_fn(|_, _| rng.random_range(-8.0..8.0)));
        let tau_m = LegMap::from_fn(|leg: Leg| {
            let t = tau[leg.mirror()];
            Vector3::new(-t.x, t.y, t.z)
        });
        sim.step_bare(&tau);
        mirrored.step_bare(&tau_m);
    }
    let want = mirror_state(&sim.ground_truth_state());
    let got = mirrored.ground_truth_state();
    Leg::ALL
        .iter()
        .map(|&leg| (want.joints[leg].q - got.joints[leg].q).amax())
        .fold(0.0, f64::max)
}

#[test]
fn the_a1_under_mirrored_torques_moves_as_its_mirror_image() {
    // With the trunk's inertia made mirror-symmetric the simulated robot is its mirror image
    // (the generated MJCF mirrors every leg); the A1's trunk has its centre of mass 4.1 mm left
    // of the mid-plane and small products of inertia, which the mirror only approximates.
    let mut symmetric = RobotConfig::a1();
    symmetric.trunk.com_m[1] = 0.0;
    symmetric.trunk.inertia_kg_m2[3] = 0.0; // ixy
    symmetric.trunk.inertia_kg_m2[5] = 0.0; // iyz
    let exact = mirror_gap(&symmetric);
    assert!(
        exact < 1e-6,
        "symmetric trunk: joint angles differ by {exact} rad"
    );
    let a1 = mirror_gap(&RobotConfig::a1());
    assert!(a1 < 0.03, "A1: joint angles differ by {a1} rad");
}

#[test]
fn the_mirror_loss_is_the_mean_squared_gap_to_the_mirrored_action() {
    let net = NetworkConfig {
        actor_hidden: vec![8],
        critic_hidden: vec![8],
        activation: Activation::Tanh,
        actor_output_gain: 1.0,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let ac = ActorCritic::new(3, 2, &net, 0.5, &mut rng).unwrap();
    // Observation mirror: (a, b, c) ↦ (b, a, −c); action mirror: (u, v) ↦ (v, u).
    let om = eemp_rl::mirror::MirrorMap::new(vec![1, 0, 2], vec![1.0, 1.0, -1.0]).unwrap();
    let am_map = eemp_rl::mirror::MirrorMap::new(vec![1, 0], vec![1.0, 1.0]).unwrap();
    let am = ActionMirror::new(&am_map).unwrap();
    let dev = Device::Cpu;
    let x: Vec<f32> = vec![0.3, -0.2, 0.5, 1.0, 0.1, -0.7];
    let obs = Tensor::from_vec(x.clone(), (2, 3), &dev).unwrap();
    let obs_m = Tensor::from_vec(om.apply_rows(&x), (2, 3), &dev).unwrap();
    let mu: Vec<f32> = ac
        .mean(&obs)
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1()
        .unwrap();
    let mu_m: Vec<f32> = ac
        .mean(&obs_m)
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1()
        .unwrap();
    let target = am_map.apply_rows(&mu);
    let by_hand: f32 = mu_m
        .iter()
        .zip(&target)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f32>()
        / 4.0;
    let mb = Minibatch {
        obs,
        actions: Tensor::zeros((2, 2), candle_core::DType::F32, &dev).unwrap(),
        old_log_probs: Tensor::zeros(2, candle_core::DType::F32, &dev).unwrap(),
        old_values: Tensor::zeros(2, candle_core::DType::F32, &dev).unwrap(),
        returns: Tensor::zeros(2, candle_core::DType::F32, &dev).unwrap(),
        advantages: Tensor::zeros(2, candle_core::DType::F32, &dev).unwrap(),
        mirrored: Some((obs_m, &am)),
    };
    let loss = ppo_loss(&ac, &mb, &PpoConfig::default()).unwrap();
    let got = loss.symmetry.to_scalar::<f32>().unwrap();
    assert!(by_hand > 1e-4, "an untrained network is not symmetric");
    assert!((got - by_hand).abs() < 1e-6, "{got} against {by_hand}");
}

#[test]
fn the_trot_schedule_alternates_diagonal_pairs_and_its_reward_counts_matching_feet() {
    use eemp_rl::tasks::model_free::{gait_schedule, scheduled_stance};
    let first = scheduled_stance(0.1);
    let second = scheduled_stance(0.6);
    for leg in Leg::ALL {
        // Each leg swings in one half and stands in the other; the mirror leg the opposite.
        assert_ne!(first[leg], second[leg]);
        assert_ne!(first[leg], first[leg.mirror()]);
    }
    assert!(!first[Leg::FrontLeft] && !first[Leg::RearRight]);
    assert_eq!(gait_schedule(&first, &first), 1.0);
    assert_eq!(gait_schedule(&first, &second), 0.0);
    // All four loaded (standing) matches half the schedule at any phase.
    let all = LegMap::from_fn(|_| true);
    assert_eq!(gait_schedule(&all, &first), 0.5);
    assert_eq!(gait_schedule(&all, &scheduled_stance(1.6)), 0.5);
}

#[test]
fn the_clock_advances_one_period_per_step_and_restarts_with_the_episode() {
    let config = ModelFreeConfig {
        extra_obs: ExtraObs {
            gait_clock_hz: 2.0,
            ..ExtraObs::default()
        },
        ..ModelFreeConfig::default()
    };
    config.validate().unwrap();
    assert_eq!(config.obs_dim(), ModelFreeConfig::default().obs_dim() + 2);
    let robot = RobotConfig::a1();
    let model = training_model(&robot, &config).unwrap();
    let sim = Simulation::with_model(model, &robot).unwrap();
    let s = sim.ground_truth_state();
    let q0 = robot.standing_pose();
    let mut m = PolicyMemory::for_config(&config);
    m.start(&s, &q0);
    // 2 Hz at 50 Hz: 25 steps per cycle.
    for _ in 0..30 {
        m.push(&s, &q0, &[0.0; 12]);
        m.advance_clock();
    }
    assert!((m.clock_phase - 0.2).abs() < 1e-9, "{}", m.clock_phase);
    m.start(&s, &q0);
    assert_eq!(m.clock_phase, 0.0);
    // The schedule term needs the clock.
    let mut bad = ModelFreeConfig::default();
    bad.rewards.gait_schedule = 1.0;
    let e = bad.validate().unwrap_err().to_string();
    assert!(
        e.contains("gait_schedule") && e.contains("gait_clock_hz"),
        "{e}"
    );
}

#[test]
fn a_policy_widened_for_a_clock_acts_as_before_whatever_the_clock_reads() {
    use eemp_rl::config::{TaskKind, TrainConfig};
    use eemp_rl::policy::Policy;
    let config = TrainConfig {
        task: TaskKind::ModelFree,
        ..TrainConfig::default()
    };
    let mut p = Policy::new(&config).unwrap();
    let d = p.net.obs_dim();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    p.normalizer.mean = (0..d).map(|_| rng.random_range(-1.0..1.0)).collect();
    p.normalizer.var = (0..d).map(|_| rng.random_range(0.5..2.0)).collect();
    let o: Vec<f32> = (0..d).map(|_| rng.random_range(-2.0..2.0)).collect();
    let before = p.act(&o).unwrap();
    let wide = p.with_appended_inputs(d + 2).unwrap();
    assert_eq!(wide.net.obs_dim(), d + 2);
    for clock in [[0.0, 1.0], [0.8, -0.6]] {
        let mut o2 = o.clone();
        o2.extend(clock);
        assert_eq!(wide.act(&o2).unwrap(), before);
    }
    assert!(wide.with_appended_inputs(d).is_err());
}
