//! The core crate's kinematics and the dynamics the controllers read, checked against MuJoCo.

use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::leg_control::{operational_space_mass, DynamicsModel};
use eemp_core::robot::RobotConfig;
use eemp_sim::mjcf::SceneExtras;
use eemp_sim::Simulation;
use nalgebra::{UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};

fn random_pose(rng: &mut impl Rng) -> (Vector3<f64>, UnitQuaternion<f64>, LegMap<Vector3<f64>>) {
    let p = Vector3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(2.0..3.0),
    );
    let r = UnitQuaternion::from_euler_angles(
        rng.random_range(-0.5..0.5),
        rng.random_range(-0.5..0.5),
        rng.random_range(-3.0..3.0),
    );
    let q = LegMap::from_fn(|_| {
        Vector3::new(
            rng.random_range(-0.8..0.8),
            rng.random_range(-1.0..4.1),
            rng.random_range(-2.69..-0.92),
        )
    });
    (p, r, q)
}

fn set_pose(
    sim: &mut Simulation,
    p: Vector3<f64>,
    r: UnitQuaternion<f64>,
    q: &LegMap<Vector3<f64>>,
) {
    sim.reset(p, q);
    let c = r.coords;
    sim.data_mut().qpos_mut()[3..7].copy_from_slice(&[c.w, c.x, c.y, c.z]);
    sim.data_mut().forward();
}

/// Every robot the project ships (`robots/*.toml`), typed into its file or read from its own
/// model: a robot added there is checked here without a list to keep.
fn shipped_robots() -> Vec<String> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| {
            let p = e.unwrap().path();
            match p.extension().is_some_and(|x| x == "toml") {
                true => p.file_stem().map(|s| s.to_string_lossy().into_owned()),
                false => None,
            }
        })
        .collect();
    names.sort();
    assert!(names.len() >= 9, "robots/ lists {names:?}");
    names
}

#[test]
fn foot_positions_and_jacobians_match_mujoco_on_every_shipped_robot() {
    for name in shipped_robots() {
        let robot = robot_file(&name);
        let kin = LegKinematics::new(&robot);
        let mut sim = Simulation::new(&robot, &SceneExtras::default()).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut worst = (0.0f64, 0.0f64);
        for _ in 0..200 {
            let (p, r, _) = random_pose(&mut rng);
            // Anywhere in the joint ranges.
            let q = LegMap::from_fn(|leg| {
                Vector3::from_fn(|j, _| {
                    let [lo, hi] = robot.joint_range_rad(leg, j);
                    rng.random_range(lo.max(-3.0)..hi.min(3.0))
                })
            });
            set_pose(&mut sim, p, r, &q);
            let feet = sim.foot_positions_world();
            for leg in Leg::ALL {
                let core = p + r * kin.foot_position_body(leg, &q[leg]);
                worst.0 = worst.0.max((core - feet[leg]).norm());
                let jac_core_world =
                    r.to_rotation_matrix().matrix() * kin.foot_jacobian_body(leg, &q[leg]);
                worst.1 = worst
                    .1
                    .max((jac_core_world - sim.foot_jacobian_world(leg)).abs().max());
            }
        }
        assert!(
            worst.0 < 1e-9,
            "{name}: worst foot position error {} m",
            worst.0
        );
        assert!(
            worst.1 < 1e-9,
            "{name}: worst Jacobian entry error {}",
            worst.1
        );
    }
}

#[test]
fn leg_dynamics_match_mujoco_inverse_dynamics() {
    // No damping or joint friction, robot in the air: then qfrc_inverse = M q̈ + bias exactly.
    let mut robot = RobotConfig::a1();
    robot.leg.damping = [0.0; 3];
    robot.leg.frictionloss_nm = [0.0; 3];
    let kin = LegKinematics::new(&robot);
    let mut sim = Simulation::new(&robot, &SceneExtras::default()).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    for trial in 0..50 {
        let (p, r, q) = random_pose(&mut rng);
        set_pose(&mut sim, p, r, &q);
        let nv = sim.nv();
        // Random velocities everywhere (trunk too) for the bias term, except on the first trials
        // where the Λ check needs q̇ = 0.
        let moving = trial >= 10;
        for i in 0..nv {
            sim.data_mut().qvel_mut()[i] = if moving {
                rng.random_range(-2.0..2.0)
            } else {
                0.0
            };
        }
        sim.prepare();
        for leg in Leg::ALL {
            let dynamics = sim.leg_dynamics(leg);
            let d = sim.dof_adr(leg);
            let qdd_leg = Vector3::new(
                rng.random_range(-20.0..20.0),
                rng.random_range(-20.0..20.0),
                rng.random_range(-20.0..20.0),
            );
            let mut qacc = vec![0.0; nv];
            qacc[d..d + 3].copy_from_slice(qdd_leg.as_slice());
            let tau_inv = sim.inverse_dynamics(&qacc);
            let tau_model = dynamics.mass_matrix * qdd_leg + dynamics.bias_torque;
            for j in 0..3 {
                assert!(
                    (tau_inv[d + j] - tau_model[j]).abs() < 1e-9,
                    "{leg:?} joint {j}: inverse {} vs M q̈ + b {}",
                    tau_inv[d + j],
                    tau_model[j]
                );
            }
            if !moving {
                // Foot acceleration a (relative to the trunk) at q̇ = 0 needs q̈ = J⁻¹a, so the
                // torque is M J⁻¹ a + b, which eq. (1)'s Jᵀ Λ a + b must reproduce.
                let jac = kin.foot_jacobian_body(leg, &q[leg]);
                if jac.determinant().abs() < 1e-4 {
                    continue;
                }
                let a = Vector3::new(3.0, -2.0, 5.0);
                let lambda = operational_space_mass(&jac, &dynamics.mass_matrix).unwrap();
                let qdd = jac.try_inverse().unwrap() * a;
                let mut qacc = vec![0.0; nv];
                qacc[d..d + 3].copy_from_slice(qdd.as_slice());
                let tau_inv = sim.inverse_dynamics(&qacc);
                let tau_eq1 = jac.transpose() * lambda * a + dynamics.bias_torque;
                for j in 0..3 {
                    assert!(
                        (tau_inv[d + j] - tau_eq1[j]).abs() < 1e-8,
                        "{leg:?} Λ check joint {j}: {} vs {}",
                        tau_inv[d + j],
                        tau_eq1[j]
                    );
                }
            }
        }
    }
}

#[test]
fn composite_body_matches_mujoco_mass_com_and_inertia_on_every_shipped_robot() {
    for name in shipped_robots() {
        let robot = robot_file(&name);
        let mut sim = Simulation::new(&robot, &SceneExtras::default()).unwrap();
        let q = robot.standing_pose();
        sim.reset(Vector3::new(0.0, 0.0, 1.0), &q);
        let body = robot.composite_body(&q);
        let trunk = sim
            .data()
            .model()
            .name_to_id(mujoco_rs::prelude::MjtObjBase::mjOBJ_BODY, "trunk")
            .unwrap();
        let com_world = sim.data().subtree_com()[trunk];
        let expected = Vector3::new(0.0, 0.0, 1.0) + body.com_body;
        assert!(
            (Vector3::from(com_world) - expected).norm() < 1e-9,
            "{name}: MuJoCo COM {com_world:?} vs core {expected:?}"
        );
        let mujoco_mass = sim.data().model().body_subtreemass()[trunk];
        assert!(
            (mujoco_mass - body.mass_kg).abs() < 1e-9
                && (robot.total_mass_kg() - body.mass_kg).abs() < 1e-9,
            "{name}: mass {mujoco_mass} vs {}",
            body.mass_kg
        );
        // Second method for the inertia about the COM: Σ over bodies of R I Rᵀ + m (|d|² − d dᵀ)
        // from MuJoCo's own body frames at this pose.
        let (data, model) = (sim.data(), sim.data().model());
        let mut inertia = nalgebra::Matrix3::zeros();
        for b in 1..model.ffi().nbody as usize {
            let x = data.ximat()[b];
            let rot = nalgebra::Matrix3::new(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8]);
            let i = rot
                * nalgebra::Matrix3::from_diagonal(&Vector3::from(model.body_inertia()[b]))
                * rot.transpose();
            let d = Vector3::from(data.xipos()[b]) - Vector3::from(com_world);
            inertia += i + model.body_mass()[b]
                * (nalgebra::Matrix3::identity() * d.dot(&d) - d * d.transpose());
        }
        assert!(
            (inertia - body.inertia_body).abs().max() < 1e-9,
            "{name}: inertia {inertia} vs core {}",
            body.inertia_body
        );
    }
}

#[test]
fn ground_truth_velocities_match_mujoco_object_velocity() {
    use mujoco_rs::prelude::MjtObjBase;
    let robot = RobotConfig::a1();
    let mut sim = Simulation::new(&robot, &SceneExtras::default()).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    for _ in 0..20 {
        let (p, r, q) = random_pose(&mut rng);
        set_pose(&mut sim, p, r, &q);
        for i in 0..sim.nv() {
            sim.data_mut().qvel_mut()[i] = rng.random_range(-1.0..1.0);
        }
        sim.data_mut().forward();
        let state = sim.ground_truth_state();
        let trunk = sim
            .data()
            .model()
            .name_to_id(MjtObjBase::mjOBJ_BODY, "trunk")
            .unwrap();
        // [angular; linear] at the trunk frame origin (XBODY; BODY would be the COM), world axes.
        let v = sim
            .data()
            .object_velocity(MjtObjBase::mjOBJ_XBODY, trunk, false);
        let omega = Vector3::new(v[0], v[1], v[2]);
        let lin = Vector3::new(v[3], v[4], v[5]);
        assert!(
            (state.body.omega_world - omega).norm() < 1e-9,
            "ω {:?} vs MuJoCo {:?}",
            state.body.omega_world,
            omega
        );
        assert!(
            (state.body.v_world - lin).norm() < 1e-9,
            "v {:?} vs MuJoCo {:?}",
            state.body.v_world,
            lin
        );
    }
}

#[test]
fn model_errors_change_the_simulated_robot_only_as_stated() {
    use eemp_sim::walk::ModelError;
    let robot = RobotConfig::a1();
    let error = ModelError {
        trunk_mass_scale: 1.2,
        trunk_inertia_scale: 1.3,
        motor_strength_scale: 0.5,
    };
    let (mut sim_robot, mut scene) = (robot.clone(), SceneExtras::default());
    error.apply(&mut sim_robot, &mut scene);
    let mut sim = Simulation::new(&sim_robot, &scene).unwrap();
    let nominal = Simulation::new(&robot, &SceneExtras::default()).unwrap();
    // What MuJoCo built: the trunk's mass ×1.2 and its inertia (trace of the principal
    // moments) ×1.3, every other body as before.
    use mujoco_rs::prelude::MjtObjBase;
    let trunk = |s: &Simulation| {
        let m = s.model();
        let id = m.name_to_id(MjtObjBase::mjOBJ_BODY, "trunk").unwrap();
        let i = m.body_inertia()[id];
        (
            m.body_mass()[id],
            i[0] + i[1] + i[2],
            m.body_subtreemass()[0],
        )
    };
    let ((m1, i1, total1), (m0, i0, total0)) = (trunk(&sim), trunk(&nominal));
    assert!((m1 - 1.2 * m0).abs() < 1e-9, "trunk mass {m1} vs {m0}");
    assert!((i1 - 1.3 * i0).abs() < 1e-9, "trunk inertia {i1} vs {i0}");
    assert!(
        (total1 - total0 - 0.2 * m0).abs() < 1e-9,
        "only the trunk changed"
    );
    // Half the commanded torque, and the limit halves with it.
    let [abduction_limit, _, limit] = robot.leg.torque_limit_nm;
    let mut tau = LegMap::splat(Vector3::new(4.0, -6.0, 2.0 * limit));
    tau[Leg::RearLeft] = Vector3::new(-2.0 * abduction_limit, 1.0, 0.0);
    sim.step_bare(&tau);
    let applied = sim.applied_torques();
    assert_eq!(
        applied[Leg::FrontRight],
        Vector3::new(2.0, -3.0, 0.5 * limit)
    );
    assert_eq!(
        applied[Leg::RearLeft],
        Vector3::new(-0.5 * abduction_limit, 0.5, 0.0)
    );
    // No error: the generated model is the nominal one (same MJCF, same torques).
    let (mut same, mut scene) = (robot.clone(), SceneExtras::default());
    ModelError::default().apply(&mut same, &mut scene);
    assert_eq!(same, robot);
    assert_eq!(
        eemp_sim::mjcf::robot_mjcf(&same, &scene),
        eemp_sim::mjcf::robot_mjcf(&robot, &SceneExtras::default())
    );
}

fn robot_file(name: &str) -> RobotConfig {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../robots")
        .join(format!("{name}.toml"));
    eemp_sim::robot_model::load_robot(&path).unwrap()
}

#[test]
fn the_go2_and_go1_models_carry_their_per_joint_limits_and_match_the_core_kinematics() {
    for name in ["go2", "go1"] {
        let robot = robot_file(name);
        let xml = eemp_sim::mjcf::robot_mjcf(&robot, &SceneExtras::default());
        let [_, _, knee] = robot.leg.torque_limit_nm;
        assert!(
            xml.contains(&format!(
                r#"<motor name="FL_calf" joint="FL_calf_joint" ctrlrange="-{knee} {knee}"/>"#
            )),
            "{name}: knee limit {knee} not in the model"
        );
        assert!(
            xml.contains(r#"<motor name="RR_hip" joint="RR_hip_joint" ctrlrange="-23.7 23.7"/>"#)
        );
        let [lo, hi] = robot.joint_range_rad(Leg::RearRight, 1);
        assert!(
            xml.contains(&format!(
                r#"name="RR_thigh_joint" axis="0 1 0" range="{lo} {hi}""#
            )),
            "{name}: rear thigh range"
        );
        // Forward kinematics of the core against MuJoCo on this robot's model.
        let kin = LegKinematics::new(&robot);
        let mut sim = Simulation::new(&robot, &SceneExtras::default()).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        for _ in 0..50 {
            let (p, r, _) = random_pose(&mut rng);
            let q = robot
                .standing_pose()
                .map(|_, q| q + Vector3::from_fn(|_, _| rng.random_range(-0.3..0.3)));
            set_pose(&mut sim, p, r, &q);
            let feet = sim.foot_positions_world();
            for leg in Leg::ALL {
                let core = p + r * kin.foot_position_body(leg, &q[leg]);
                assert!((core - feet[leg]).norm() < 1e-9, "{name} {leg:?}");
            }
        }
        assert!((sim.total_mass_kg() - robot.total_mass_kg()).abs() < 1e-9);
    }
    // Front and rear thigh ranges differ on the Go2 only.
    let go2 = robot_file("go2");
    assert_ne!(
        go2.joint_range_rad(Leg::FrontLeft, 1),
        go2.joint_range_rad(Leg::RearLeft, 1)
    );
}
