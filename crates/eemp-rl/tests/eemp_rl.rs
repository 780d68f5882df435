//! EEMP-RL: the action squashing covers Table I exactly and never leaves it; a policy that
//! answers fixed parameters walks exactly as EEMP with those parameters; the environment steps.

use eemp_core::planner::params::table_i;
use eemp_core::planner::{PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_rl::env::Env;
use eemp_rl::tasks::eemp_rl::{
    squash, unsquash, walk_spec, EempRlConfig, EempRlController, EempRlEnv, FixedAction, RANGES,
};
use eemp_sim::walk::{eemp_controller, run_walk_with, VelocityProfile};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn as_array(p: &PlannerParams) -> [f64; 5] {
    [
        p.swing_time_s,
        p.step_height_m,
        p.body_height_m,
        p.ellipse_rx_m,
        p.ellipse_ry_m,
    ]
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
    let start = EempRlController::<FixedAction>::start_pose(&robot, &cfg).unwrap();
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
