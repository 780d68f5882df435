use super::*;
use crate::body_state::{BodyState, LegJointState};
use crate::robot::RobotConfig;
use nalgebra::UnitQuaternion;

/// The MPC's nominal friction coefficient (`MpcConfig::default()`), as the planner sees it
/// without slip handling.
const NOMINAL_MU: f64 = 0.6;

fn standing(kin: &LegKinematics, x: f64) -> (RobotState, LegMap<Vector3<f64>>) {
    let height = 0.31;
    let feet_world = LegMap::from_fn(|leg| {
        let mut p = kin.nominal_foot_body(leg);
        p.z = 0.02;
        p
    });
    let body = BodyState {
        p_world: Vector3::new(x, 0.0, height),
        r_world_body: UnitQuaternion::identity(),
        v_world: Vector3::new(0.1, 0.0, 0.0),
        omega_world: Vector3::zeros(),
    };
    let joints = LegMap::from_fn(|leg| LegJointState {
        q: kin.inverse(leg, &(feet_world[leg] - body.p_world)).unwrap(),
        qd: Vector3::zeros(),
    });
    (
        RobotState {
            time_s: 0.0,
            body,
            joints,
        },
        feet_world,
    )
}

fn planner(gait: Gait) -> EemPlanner {
    planner_with(PlannerConfig {
        gait,
        ..Default::default()
    })
}

/// The A1's planner: foot radius 2 cm, a 10-step horizon of 25 ms.
fn planner_with(config: PlannerConfig) -> EemPlanner {
    EemPlanner::new(
        config,
        LegKinematics::new(&RobotConfig::a1()),
        0.02,
        10,
        0.025,
    )
    .unwrap()
}

#[test]
fn all_feet_inside_means_four_stance_legs_and_a_moving_body_reference() {
    let mut p = planner(Gait::Trot);
    let kin = LegKinematics::new(&RobotConfig::a1());
    let (state, feet) = standing(&kin, 0.03);
    let cmd = VelocityCommand {
        vx_mps: 0.1,
        ..Default::default()
    };
    let params = PlannerParams::default();
    p.plan(0.0, &state, &feet, &cmd, &params, NOMINAL_MU);
    let plan = p.plan(1.0, &state, &feet, &cmd, &params, NOMINAL_MU);
    assert_eq!(plan.stance, LegMap::splat(true));
    assert!(plan
        .contacts_horizon
        .iter()
        .all(|c| *c == LegMap::splat(true)));
    // The reference moves forward at the command along the horizon.
    let dx = plan.body_horizon[9].p_world.x - plan.body_now.p_world.x;
    assert!((dx - 0.1 * 0.25).abs() < 1e-12, "{dx}");
    assert!((plan.body_now.p_world.z - 0.31).abs() < 1e-12);
}

#[test]
fn a_foot_outside_its_ellipse_starts_a_swing_to_the_hip_plus_progress() {
    let mut p = planner(Gait::Trot);
    let kin = LegKinematics::new(&RobotConfig::a1());
    // Body 8 cm ahead of the feet: every foot is 8 cm behind its hip, beyond r_x = 7 cm.
    let (state, feet) = standing(&kin, 0.08);
    let cmd = VelocityCommand::default();
    let params = PlannerParams::default();
    let plan = p.plan(0.0, &state, &feet, &cmd, &params, NOMINAL_MU);
    let swinging: Vec<Leg> = Leg::ALL.into_iter().filter(|l| !plan.stance[*l]).collect();
    assert_eq!(swinging.len(), 2, "a trot pair swings");
    assert_eq!(swinging[0].diagonal(), swinging[1]);
    let leg = swinging[0];
    let tr = p.swings[leg].unwrap().trajectory;
    // Command 0 (so no hip travel), body velocity 0.1: p_prog = √(0.31/9.81)·0.1 in x and
    // p_ell = −0.08 in x; the world displacement is p_prog − p_ell.
    let k = (0.31f64 / 9.81).sqrt();
    assert!(
        (tr.displacement_xy.x - (0.1 * k + 0.08)).abs() < 1e-9,
        "{:?}",
        tr.displacement_xy
    );
    assert!(tr.displacement_xy.y.abs() < 1e-9);
    // The horizon has the legs in the air for ΔT = 0.25 s = 10 steps of 25 ms, then back.
    assert!(plan.contacts_horizon.iter().all(|c| !c[leg]));
    let later = p.plan(0.26, &state, &feet, &cmd, &params, NOMINAL_MU);
    assert!(later.stance[leg], "swing ended after ΔT");
    assert_eq!(p.steps()[leg], 1);
}

#[test]
fn no_new_swing_starts_while_one_is_running() {
    let mut p = planner(Gait::Walk);
    let kin = LegKinematics::new(&RobotConfig::a1());
    let (state, feet) = standing(&kin, 0.08);
    let params = PlannerParams::default();
    let still = VelocityCommand::default();
    let first = p.plan(0.0, &state, &feet, &still, &params, NOMINAL_MU);
    assert_eq!(
        first.stance.0.iter().filter(|s| !**s).count(),
        1,
        "walk: one leg"
    );
    for i in 1..10 {
        let plan = p.plan(i as f64 * 0.02, &state, &feet, &still, &params, NOMINAL_MU);
        assert_eq!(plan.stance, first.stance, "same swing continues");
    }
}

#[test]
fn no_gait_starts_a_swing_while_another_runs() {
    let kin = LegKinematics::new(&RobotConfig::a1());
    let (state, feet0) = standing(&kin, 0.0);
    let params = PlannerParams::default();
    let cmd = VelocityCommand::default();
    for gait in [Gait::Free, Gait::Walk] {
        let mut p = planner(gait);
        let mut feet = feet0;
        // Only FR is out (8 cm behind its hip): it swings alone.
        feet[Leg::FrontRight].x -= 0.08;
        let first = p.plan(0.0, &state, &feet, &cmd, &params, NOMINAL_MU);
        assert_eq!(first.stance, LegMap([false, true, true, true]), "{gait:?}");
        // RL (FR's diagonal) leaves its ellipse mid-swing: it waits for FR to land.
        feet[Leg::RearLeft].x -= 0.08;
        let second = p.plan(0.1, &state, &feet, &cmd, &params, NOMINAL_MU);
        assert_eq!(second.stance, first.stance, "{gait:?}");
        let after = p.plan(0.26, &state, &feet, &cmd, &params, NOMINAL_MU);
        assert!(
            !after.stance[Leg::RearLeft],
            "{gait:?}: RL swings once FR has landed"
        );
    }
}

#[test]
fn the_walk_checks_its_swing_against_the_capture_point_of_the_velocity_error() {
    let kin = LegKinematics::new(&RobotConfig::a1());
    let params = PlannerParams::default();
    let still = VelocityCommand::default();
    // After RL the walk's order lifts FL; FL is 8 cm behind its hip (outside, so a swing starts).
    let choice = |vy_mps: f64, support: WalkSupport, cmd: VelocityCommand| {
        let mut p = planner_with(PlannerConfig {
            gait: Gait::Walk,
            walk_support: support,
            ..Default::default()
        });
        p.previous_legs = vec![Leg::RearLeft];
        let (mut state, mut feet) = standing(&kin, 0.0);
        state.body.v_world = Vector3::new(0.0, vy_mps, 0.0);
        feet[Leg::FrontLeft].x -= 0.08;
        let plan = p.plan(0.0, &state, &feet, &cmd, &params, NOMINAL_MU);
        let swinging: Vec<Leg> = Leg::ALL.into_iter().filter(|l| !plan.stance[*l]).collect();
        assert_eq!(swinging.len(), 1, "the walk lifts one leg: {swinging:?}");
        swinging[0]
    };
    let on = WalkSupport::default();
    // Standing still and pushed to the right (away from FL): FL, as the order says.
    assert_eq!(choice(0.0, on, still), Leg::FrontLeft);
    assert_eq!(choice(-0.5, on, still), Leg::FrontLeft);
    // Pushed left at 0.5 m/s: the capture point, √(0.31/9.81)·0.5 = 8.9 cm left of the trunk,
    // lies ≈ 7 cm outside the FR–RR–RL triangle, so FL waits and RR (FR–FL–RL holds it) swings.
    assert_eq!(choice(0.5, on, still), Leg::RearRight);
    // The paper's walk lifts FL regardless, and so does the walk commanded 0.6 m/s or faster
    // (the reference has not moved yet at the first step: the same capture point).
    assert_eq!(choice(0.5, WalkSupport::OFF, still), Leg::FrontLeft);
    let fast = VelocityCommand {
        vx_mps: 0.6,
        ..Default::default()
    };
    assert_eq!(choice(0.5, on, fast), Leg::FrontLeft);
}

#[test]
fn retargeting_moves_the_touchdown_with_the_measured_velocity() {
    let robot = RobotConfig::a1();
    let kin = LegKinematics::new(&robot);
    let mut p = EemPlanner::new(
        PlannerConfig {
            gait: Gait::Trot,
            retarget_swing: true,
            ..Default::default()
        },
        LegKinematics::new(&robot),
        0.02,
        10,
        0.025,
    )
    .unwrap();
    let (state, feet) = standing(&kin, 0.08);
    let cmd = VelocityCommand::default();
    let params = PlannerParams::default();
    let mut slippery = p.clone();
    let plan = p.plan(0.0, &state, &feet, &cmd, &params, NOMINAL_MU);
    let leg = Leg::ALL.into_iter().find(|l| !plan.stance[*l]).unwrap();
    let start = p.swings[leg].unwrap().trajectory.start_body;
    // 0.1 s later the trunk has been pushed sideways: it moves at (0.1, −0.3) m/s from
    // x = 0.09. The target is the ellipse centre now, carried on at the commanded velocity
    // (0) for the 0.15 s left, plus eq. (6) with V_cur = (0.1, −0.3) and V_des = 0.
    let (mut pushed, _) = standing(&kin, 0.09);
    pushed.body.v_world = Vector3::new(0.1, -0.3, 0.0);
    p.plan(0.1, &pushed, &feet, &cmd, &params, NOMINAL_MU);
    let swing = p.swings[leg].unwrap();
    let k = (0.31f64 / 9.81).sqrt();
    let centre = pushed.body.p_world + kin.nominal_foot_body(leg);
    let expected_x = centre.x + 0.1 * k;
    let expected_y = centre.y - 0.3 * k;
    assert!((swing.touchdown_world.x - expected_x).abs() < 1e-9);
    assert!((swing.touchdown_world.y - expected_y).abs() < 1e-9);
    // The lift-off point and the trajectory's end follow: it ends on the new target.
    assert_eq!(swing.trajectory.start_body, start);
    let end = swing.trajectory.sample(swing.trajectory.duration_s).p_body;
    assert!((end.x - expected_x).abs() < 1e-9 && (end.y - expected_y).abs() < 1e-9);

    // The same push where the MPC's coefficient is 0.2: eq. (6)'s feedback step
    // (0.1, −0.3)·k, 0.0562 m long, is shortened to ½ · 0.2 · X_z = 0.031 m along the same
    // direction (the default touchdown_friction_factor; X_z = 0.31 m).
    assert_eq!(p.config().touchdown_friction_factor_in_force(), 0.5);
    slippery.plan(0.0, &state, &feet, &cmd, &params, 0.2);
    slippery.plan(0.1, &pushed, &feet, &cmd, &params, 0.2);
    let swing = slippery.swings[leg].unwrap();
    let limit = 0.5 * 0.2 * 0.31;
    let dir = Vector3::new(0.1, -0.3, 0.0).normalize();
    assert!((0.1f64.hypot(0.3) * k - 0.0562).abs() < 1e-4 && limit < 0.1f64.hypot(0.3) * k);
    assert!((swing.touchdown_world.x - (centre.x + dir.x * limit)).abs() < 1e-9);
    assert!((swing.touchdown_world.y - (centre.y + dir.y * limit)).abs() < 1e-9);
}

#[test]
fn preview_shows_the_mpc_a_swing_that_starts_later_in_the_horizon() {
    let robot = RobotConfig::a1();
    let kin = LegKinematics::new(&robot);
    let make = |preview_swings| {
        EemPlanner::new(
            PlannerConfig {
                gait: Gait::Trot,
                preview_swings,
                ..Default::default()
            },
            LegKinematics::new(&robot),
            0.02,
            10,
            0.025,
        )
        .unwrap()
    };
    // Feet 6.2 cm behind their hips (inside r_x = 7 cm) and a command of 0.2 m/s: the feet
    // leave their ellipses 0.04 s later, so at horizon step 2 (0.05 s; 25 ms steps), once the
    // slew-limited reference has reached the command (the planner is first run long enough).
    let (state, feet) = standing(&kin, 0.062);
    let cmd = VelocityCommand {
        vx_mps: 0.2,
        ..Default::default()
    };
    let params = PlannerParams::default();
    for preview in [false, true] {
        let mut p = make(preview);
        p.plan(0.0, &state, &feet, &cmd, &params, NOMINAL_MU);
        let plan = p.plan(1.0, &state, &feet, &cmd, &params, NOMINAL_MU);
        assert_eq!(plan.stance, LegMap::splat(true), "no foot is outside now");
        let off: Vec<usize> = (0..10)
            .filter(|k| plan.contacts_horizon[*k] != LegMap::splat(true))
            .collect();
        if !preview {
            assert!(off.is_empty(), "{off:?}");
            continue;
        }
        // 0.008 m to go at 0.2 m/s = 0.04 s: the first step after it is k = 2 (0.05 s); the
        // pair then stays up for ΔT = 0.25 s = 10 steps, to the end of the horizon.
        assert_eq!(off, (2..10).collect::<Vec<_>>());
        let lifted: Vec<Leg> = Leg::ALL
            .into_iter()
            .filter(|l| !plan.contacts_horizon[2][*l])
            .collect();
        assert_eq!(lifted.len(), 2);
        assert_eq!(lifted[0].diagonal(), lifted[1], "a trot pair");
        // Its predicted touchdown: the hip 0.05 + 0.25 s on at 0.2 m/s, plus V·ΔT/2.
        let leg = lifted[0];
        let expected_x =
            state.body.p_world.x + kin.nominal_foot_body(leg).x + 0.2 * 0.30 + 0.2 * 0.125;
        assert!((plan.feet_horizon_world[2][leg].x - expected_x).abs() < 1e-9);
    }
}

#[test]
fn the_first_step_on_command_starts_one_trot_pair_at_once_then_the_ellipses_rule() {
    let kin = LegKinematics::new(&RobotConfig::a1());
    // Feet 3 cm behind their hips: inside r_x = 7 cm.
    let (state, feet) = standing(&kin, 0.03);
    let params = PlannerParams::default();
    let go = VelocityCommand {
        vx_mps: 0.3,
        ..Default::default()
    };
    let mut off = planner(Gait::Trot);
    assert_eq!(
        off.plan(0.0, &state, &feet, &go, &params, NOMINAL_MU)
            .stance,
        LegMap::splat(true)
    );
    let mut on = planner_with(PlannerConfig {
        gait: Gait::Trot,
        first_step_on_command: true,
        ..Default::default()
    });
    // Standing still: no step, whatever the flag.
    let rest = VelocityCommand::default();
    let at_rest = on.plan(0.0, &state, &feet, &rest, &params, NOMINAL_MU);
    assert_eq!(at_rest.stance, LegMap::splat(true));
    // Commanded: a diagonal pair lifts now.
    let plan = on.plan(0.001, &state, &feet, &go, &params, NOMINAL_MU);
    let swinging: Vec<Leg> = Leg::ALL.into_iter().filter(|l| !plan.stance[*l]).collect();
    assert_eq!(swinging.len(), 2, "{swinging:?}");
    assert_eq!(swinging[0].diagonal(), swinging[1]);
    // After that swing, the ellipses decide again: feet inside, no new swing.
    let after = on.plan(1.0, &state, &feet, &go, &params, NOMINAL_MU);
    assert_eq!(after.stance, LegMap::splat(true));
}

#[test]
fn the_friction_cone_keeps_each_ellipse_at_least_eq6s_offset_wide() {
    let config = PlannerConfig::default();
    // The trot's table at 0.5 m/s: ΔT 0.25, X_z 0.31, r_x 0.07, r_y 0.05.
    let p = PlannerParams {
        swing_time_s: 0.25,
        body_height_m: 0.31,
        ellipse_rx_m: 0.07,
        ellipse_ry_m: 0.05,
        ..Default::default()
    };
    let command = VelocityCommand {
        vx_mps: 0.5,
        vy_mps: 0.0,
        yaw_rate_rps: 0.0,
    };
    // μ̂ 0.2: the cone gives 0.2 · 0.31 = 0.062 m, eq. (6)'s offset 0.5 · 0.25 · ½ = 0.0625 m
    // × 1.25 = 0.078125 m along x: r_x stays 0.07; across, no offset: r_y 0.05 < 0.062 stays.
    assert_eq!(config.within_friction_cone(&p, 0.2, &command), p);
    // At 0.1 m/s the offset is 0.015625 m: r_x shrinks to the cone's 0.062 m.
    let slow = VelocityCommand {
        vx_mps: 0.1,
        ..command
    };
    let q = config.within_friction_cone(&p, 0.2, &slow);
    assert!((q.ellipse_rx_m - 0.062).abs() < 1e-12, "{q:?}");
    assert_eq!(q.ellipse_ry_m, 0.05);
    // Factor 0: off.
    let off = PlannerConfig {
        ellipse_friction_factor: Some(0.0),
        ..config
    };
    assert_eq!(off.within_friction_cone(&p, 0.2, &slow), p);
}

#[test]
fn a_command_capped_in_speed_keeps_its_direction_and_yaw_rate() {
    let c = VelocityCommand {
        vx_mps: 0.3,
        vy_mps: 0.4,
        yaw_rate_rps: 0.2,
    };
    let capped = c.with_speed_at_most(0.25);
    assert!((capped.vx_mps - 0.15).abs() < 1e-12 && (capped.vy_mps - 0.2).abs() < 1e-12);
    assert_eq!(capped.yaw_rate_rps, 0.2);
    assert_eq!(c.with_speed_at_most(0.5), c);
    assert_eq!(c.with_speed_at_most(0.5 + 1e-12), c);
}

/// The planner's two friction-cone factors: each named in its refusal, each the gait's where
/// unset, the value set where set.
#[test]
fn the_friction_factors_are_the_gaits_unless_set_and_refused_by_name() {
    type Set = fn(&mut PlannerConfig, Option<f64>);
    type InForce = fn(&PlannerConfig) -> f64;
    let factors: [(&str, Set, InForce, [f64; 3]); 2] = [
        (
            "planner.touchdown_friction_factor",
            |c, f| c.touchdown_friction_factor = f,
            PlannerConfig::touchdown_friction_factor_in_force,
            // Trot, free, walk: 0.5, 0.5 and 0 (unbounded).
            [0.5, 0.5, 0.0],
        ),
        (
            "planner.ellipse_friction_factor",
            |c, f| c.ellipse_friction_factor = f,
            PlannerConfig::ellipse_friction_factor_in_force,
            // Trot, free, walk: 1, 1 and 0 (off).
            [1.0, 1.0, 0.0],
        ),
    ];
    for (name, set, in_force, defaults) in factors {
        for bad in [-0.1, 3.5, f64::NAN] {
            let mut c = PlannerConfig::default();
            set(&mut c, Some(bad));
            let e = c.validate().unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
        }
        for (gait, factor) in [Gait::Trot, Gait::Free, Gait::Walk]
            .into_iter()
            .zip(defaults)
        {
            let mut c = PlannerConfig {
                gait,
                ..Default::default()
            };
            assert_eq!(in_force(&c), factor, "{name} {gait:?}");
            for set_to in [0.0, 0.5] {
                set(&mut c, Some(set_to));
                assert!(c.validate().is_ok());
                assert_eq!(in_force(&c), set_to, "{name} {gait:?}");
            }
        }
    }
}

#[test]
fn the_walks_ellipses_stay_as_the_table_has_them_at_a_low_friction() {
    // The walk's default leaves eq. (5)'s ellipse as the table has it at a low μ̂; the trot's caps
    // it at μ̂ · X_z (0.15 · 0.31 = 0.0465 m), above eq. (6)'s offset at 0.1 m/s.
    let p = PlannerParams {
        swing_time_s: 0.25,
        step_height_m: 0.05,
        body_height_m: 0.31,
        ellipse_rx_m: 0.07,
        ellipse_ry_m: 0.05,
    };
    let cmd = VelocityCommand {
        vx_mps: 0.1,
        ..Default::default()
    };
    let walk = PlannerConfig {
        gait: Gait::Walk,
        ..Default::default()
    };
    let trot = PlannerConfig::default();
    let w = walk.within_friction_cone(&p, 0.15, &cmd);
    assert_eq!((w.ellipse_rx_m, w.ellipse_ry_m), (0.07, 0.05));
    let t = trot.within_friction_cone(&p, 0.15, &cmd);
    assert!((t.ellipse_rx_m - 0.0465).abs() < 1e-12, "{t:?}");
    assert!((t.ellipse_ry_m - 0.0465).abs() < 1e-12, "{t:?}");
}

#[test]
fn a_lagging_trunk_is_pulled_towards_the_integrated_command_up_to_the_bound() {
    let kin = LegKinematics::new(&RobotConfig::a1());
    let (state, feet) = standing(&kin, 0.03);
    let cmd = VelocityCommand {
        vx_mps: 0.1,
        ..Default::default()
    };
    let params = PlannerParams::default();
    let held = |max: f64, t: f64| {
        let mut p = planner_with(PlannerConfig {
            gait: Gait::Trot,
            position_error_max_m: max,
            // The reference at the command from the first step.
            max_accel_mps2: 20.0,
            ..Default::default()
        });
        p.plan(0.0, &state, &feet, &cmd, &params, NOMINAL_MU);
        let mut plan = p.plan(0.01, &state, &feet, &cmd, &params, NOMINAL_MU);
        // The trunk stays where it is while the command runs on.
        for k in 2..=(t / 0.01).round() as usize {
            plan = p.plan(k as f64 * 0.01, &state, &feet, &cmd, &params, NOMINAL_MU);
        }
        plan.body_now.p_world.x - state.body.p_world.x
    };
    // Off: the reference starts at the trunk.
    assert_eq!(held(0.0, 0.5), 0.0);
    // On: 0.1 m/s for 0.1 s ahead (0.01 m, under the bound), then held at the bound.
    assert!((held(0.05, 0.1) - 0.01).abs() < 1e-9, "{}", held(0.05, 0.1));
    assert!((held(0.05, 2.0) - 0.05).abs() < 1e-12);
    assert!(PlannerConfig {
        position_error_max_m: 0.6,
        ..Default::default()
    }
    .validate()
    .unwrap_err()
    .to_string()
    .contains("planner.position_error_max_m"));
}
