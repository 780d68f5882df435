//! Short closed-loop standing runs: rise, hold, follow, absorb a push.

use eemp_core::joint_pd::{JointPd, PdGains};
use eemp_core::locomotion::ControllerConfig;
use eemp_core::planner::VelocityCommand;
use eemp_core::robot::RobotConfig;
use eemp_core::stand_profile::BodyMotionProfile;
use eemp_sim::closed_loop::{ClosedLoop, Push};
use eemp_sim::mjcf::SceneExtras;
use eemp_sim::stand::run_stand;
use eemp_sim::Simulation;
use nalgebra::Vector3;

#[test]
fn rises_and_tracks_the_body_profile() {
    let robot = RobotConfig::a1();
    let mut sq_pos = 0.0;
    let mut sq_rpy = 0.0;
    let mut n = 0usize;
    let run = run_stand(
        &robot,
        ControllerConfig::default(),
        BodyMotionProfile::default(),
        20.0,
        &[],
        |r| {
            if r.state.time_s > 2.5 {
                let e = r.state.body.p_world - r.plan.unwrap().body_now.p_world;
                sq_pos += e.norm_squared();
                let mut er = r.state.body.rpy() - r.plan.unwrap().body_now.rpy;
                er.z = (er.z + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI)
                    - std::f64::consts::PI;
                sq_rpy += er.norm_squared();
                n += 1;
            }
        },
    )
    .unwrap();
    let rmse_pos = (sq_pos / n as f64).sqrt();
    let rmse_rpy = (sq_rpy / n as f64).sqrt();
    println!(
        "rmse pos {rmse_pos} m, rpy {rmse_rpy} rad, mpc failures {}, rtf {}",
        run.stats.mpc_failures,
        run.stats.realtime_factor()
    );
    assert!(!run.stats.fell, "fell at {:?}", run.stats.fell_at_s);
    assert!(rmse_pos <= 0.01, "position RMSE {rmse_pos} m");
    assert!(rmse_rpy <= 0.03, "attitude RMSE {rmse_rpy} rad");
    assert_eq!(run.stats.mpc_failures, 0);
}

#[test]
fn absorbs_a_lateral_push_of_0_3_m_per_s() {
    let robot = RobotConfig::a1();
    let mut profile = BodyMotionProfile::default();
    profile.segments.clear();
    let push = Push::step(3.0, Vector3::new(0.0, 0.3, 0.0));
    let mut max_dev: f64 = 0.0;
    let run = run_stand(
        &robot,
        ControllerConfig::default(),
        profile,
        6.0,
        &[push],
        |r| {
            if r.state.time_s > 2.5 {
                max_dev =
                    max_dev.max((r.state.body.p_world - r.plan.unwrap().body_now.p_world).norm());
            }
        },
    )
    .unwrap();
    println!("max deviation after push {max_dev} m");
    assert!(!run.stats.fell, "fell at {:?}", run.stats.fell_at_s);
}

/// A push as a force pulse: the trunk gains its velocity over the pulse (not at once, as a
/// step gives it), about the impulse's worth, and the robot stands through it.
#[test]
fn a_push_as_a_force_pulse_builds_up_over_its_duration() {
    let robot = RobotConfig::a1();
    let mut profile = BodyMotionProfile::default();
    profile.segments.clear();
    let lateral_at = |push: Push, t_s: f64| {
        let mut vy = f64::NAN;
        let run = run_stand(
            &robot,
            ControllerConfig::default(),
            profile.clone(),
            5.0,
            &[push],
            |r| {
                if (r.state.time_s - t_s).abs() < 0.5e-3 {
                    vy = r.state.body.v_world.y;
                }
            },
        )
        .unwrap();
        assert!(!run.stats.fell, "fell at {:?}", run.stats.fell_at_s);
        vy
    };
    let dv = Vector3::new(0.0, 0.3, 0.0);
    let pulse = Push {
        at_s: 3.0,
        dv_world: dv,
        duration_s: 0.05,
    };
    // 2 ms in: a step has (almost) all of it, the pulse a few percent.
    let step_early = lateral_at(Push::step(3.0, dv), 3.002);
    let pulse_early = lateral_at(pulse, 3.002);
    let pulse_end = lateral_at(pulse, 3.05);
    println!("step {step_early}, pulse {pulse_early} then {pulse_end} m/s");
    assert!(step_early > 0.25, "{step_early}");
    assert!(pulse_early.abs() < 0.05, "{pulse_early}");
    // The feet and the controller resist it, so less than the full 0.3 m/s but most of it.
    assert!(pulse_end > 0.15 && pulse_end < 0.32, "{pulse_end}");
}

/// A pulse acts for round(duration / dt) whole physics steps with exactly mass × Δv of impulse,
/// whatever the phase its start meets, and a restart clears a pulse under way.
#[test]
fn a_pulse_acts_for_its_whole_steps_and_a_restart_clears_it() {
    let robot = RobotConfig::a1();
    let sim = Simulation::new(&robot, &SceneExtras::default()).unwrap();
    let (dt, m) = (sim.timestep_s(), sim.total_mass_kg());
    // Starts 0.6 of a step after a step boundary; 10.4 steps long → 10 steps.
    let pulse = Push {
        at_s: 0.0106,
        dv_world: Vector3::new(0.0, 0.3, 0.0),
        duration_s: 0.0104,
    };
    let mut lp = ClosedLoop::new(sim, &[pulse], robot.scale());
    let mut pd = JointPd {
        gains: PdGains::default(),
        targets: robot.standing_pose(),
        torque_limit_nm: robot.leg.torque_limit_nm,
    };
    // The force set after a step acts during the next one.
    let mut forces = Vec::new();
    for _ in 0..40 {
        lp.step(&mut pd, VelocityCommand::default(), &mut |_| {});
        forces.push(lp.sim().trunk_force());
    }
    let on: Vec<_> = forces.iter().filter(|f| f.norm() > 0.0).collect();
    assert_eq!(on.len(), 10, "{forces:?}");
    let impulse: f64 = on.iter().map(|f| f.y * dt).sum();
    assert!(
        (impulse - m * 0.3).abs() < 1e-9,
        "{impulse} against {}",
        m * 0.3
    );
    assert_eq!(forces.last().unwrap().norm(), 0.0);
    // A restart during a pulse leaves no force behind.
    lp.restart(&[Push { at_s: 0.0, ..pulse }]);
    for _ in 0..3 {
        lp.step(&mut pd, VelocityCommand::default(), &mut |_| {});
    }
    assert!(lp.sim().trunk_force().norm() > 0.0);
    lp.restart(&[]);
    assert_eq!(lp.sim().trunk_force().norm(), 0.0);
}
