//! The energy account closed-loop: a robot standing still turns the torques that hold it into
//! heat, Σ k·τ², with τ worked out independently from the ground's forces on its feet through
//! the leg Jacobians (τ = −Jᵀf), not from the torques the controller sent.

use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::planner::{Gait, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_sim::walk::{run_walk, WalkSpec};
use nalgebra::Vector3;

#[test]
fn standing_still_the_drives_dissipate_the_heat_of_the_holding_torques() {
    let robot = RobotConfig::a1();
    let motor = robot.motor_model().expect("the A1 file has a motor model");
    let kin = LegKinematics::new(&robot);
    // The free gait commanded to stand: EEMP steps only when a foot leaves its ellipse.
    let spec = WalkSpec::constant(
        PlannerConfig {
            gait: Gait::Free,
            ..Default::default()
        },
        PlannerParams::default(),
        VelocityCommand::default(),
        4.0,
    );
    let (mut heat_planned_j, mut heat_ground_j, mut window_s) = (0.0, 0.0, 0.0);
    let dt = robot.simulation.timestep_s;
    let run = run_walk(&robot, &spec, |r| {
        if r.state.time_s < spec.metrics_start_s {
            return;
        }
        let r_wb = *r.state.body.r_world_body.to_rotation_matrix().matrix();
        // τ = −Jᵀf of a force f at each foot (world frame), through the project's kinematics.
        let holding = |f: &dyn Fn(Leg) -> Vector3<f64>| {
            LegMap::from_fn(|leg: Leg| {
                let j_world = r_wb * kin.foot_jacobian_body(leg, &r.state.joints[leg].q);
                -(j_world.transpose() * f(leg))
            })
        };
        // The standing forces the MPC asked of the ground.
        heat_planned_j += motor.heat_w(&holding(&|leg| r.output.forces_world[leg])) * dt;
        // What the ground gave, read from MuJoCo's contacts (normal part only).
        heat_ground_j += motor.heat_w(&holding(&|leg| {
            Vector3::new(0.0, 0.0, r.foot_normal_n[leg])
        })) * dt;
        window_s += dt;
    })
    .unwrap();
    assert!(!run.stats.fell);
    let e = run.metrics.electrical.as_ref().unwrap();
    let heat_w = e.heat_j / run.metrics.duration_s;
    let (planned_w, ground_w) = (heat_planned_j / window_s, heat_ground_j / window_s);
    println!(
        "standing: heat {heat_w:.2} W from the torques sent, {planned_w:.2} W from the MPC's \
         forces, {ground_w:.2} W from the ground's; drives {:.2} W, battery {:.2} W",
        e.mean_motor_power_w.unwrap(),
        e.mean_power_w.unwrap()
    );
    // Hand check (energy notes): knees ≈ 4.4 N·m at this height, 4 · 0.3 · 4.4² ≈ 23 W.
    assert!((15.0..35.0).contains(&heat_w), "{heat_w} W");
    assert!(
        (heat_w / planned_w - 1.0).abs() < 0.02,
        "{heat_w} W from the torques against {planned_w} W from the standing forces"
    );
    // The ground also carries the legs' own weight (7.7 kg of the A1's 12.5), which the joints
    // do not hold through the foot: the contact forces give somewhat more heat, not less.
    assert!(
        (0.0..0.15).contains(&(ground_w / heat_w - 1.0)),
        "{heat_w} W from the torques against {ground_w} W from the ground's forces"
    );
    // Standing does no mechanical work: the drives' power is their heat, and the battery adds
    // the idle power; eq. (8)'s CoT and every CoT of a run that did not travel are absent.
    assert!((e.mean_motor_power_w.unwrap() / heat_w - 1.0).abs() < 0.05);
    assert!(
        (e.mean_power_w.unwrap() - e.mean_motor_power_w.unwrap() - motor.idle_power_w).abs() < 1e-9
    );
    assert_eq!((run.metrics.cot, e.cot), (None, None));
}
