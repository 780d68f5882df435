use super::*;
use crate::kinematics::LegKinematics;
use crate::robot::RobotConfig;
use approx::assert_relative_eq;
use nalgebra::{Matrix3, UnitQuaternion};
use rand::{Rng, SeedableRng};

struct Scene {
    mpc: ConvexMpc,
    body: BodyState,
    reference: Vec<BodyReference>,
    feet: Vec<LegMap<Vector3<f64>>>,
    contacts: Vec<LegMap<bool>>,
}

fn standing_scene(mut config: MpcConfig) -> Scene {
    let robot = RobotConfig::a1();
    // The bound `LocomotionController::new` gives the A1 (its file's).
    config.f_max_n.get_or_insert(robot.mpc_f_max_n());
    let kin = LegKinematics::new(&robot);
    let composite = robot.composite_body(&robot.standing_pose());
    let n = config.horizon;
    let body = BodyState {
        p_world: Vector3::new(0.0, 0.0, 0.3),
        r_world_body: UnitQuaternion::identity(),
        v_world: Vector3::zeros(),
        omega_world: Vector3::zeros(),
    };
    let feet = LegMap::from_fn(|leg| {
        let mut p = kin.nominal_foot_body(leg) + body.p_world;
        p.z = 0.02;
        p
    });
    let reference = vec![
        BodyReference {
            rpy: Vector3::zeros(),
            p_world: body.p_world,
            omega_world: Vector3::zeros(),
            v_world: Vector3::zeros()
        };
        n
    ];
    Scene {
        mpc: ConvexMpc::new(config, composite).unwrap(),
        body,
        reference,
        feet: vec![feet; n],
        contacts: vec![LegMap::splat(true); n],
    }
}

impl Scene {
    fn solve(&mut self) -> MpcSolution {
        let input = MpcInput {
            body: &self.body,
            reference: &self.reference,
            feet_world: &self.feet,
            contacts: &self.contacts,
            heat: None,
        };
        self.mpc.solve(&input)
    }
}

#[test]
fn standing_forces_carry_the_weight_and_split_by_the_centre_of_mass() {
    for solver in [QpSolverKind::Quadprog, QpSolverKind::Clarabel] {
        let mut scene = standing_scene(MpcConfig {
            solver,
            ..MpcConfig::default()
        });
        let sol = scene.solve();
        assert!(sol.status.is_solved(), "{:?}", sol.status);
        let body = scene.mpc.body().clone();
        let total: Vector3<f64> = sol.forces_world.0.iter().sum();
        let weight = body.mass_kg * GRAVITY;
        assert_relative_eq!(total.z, weight, max_relative = 2e-3);
        assert!(total.xy().norm() < 1e-2 * weight, "horizontal {total:?}");
        // Zero moment about the COM: the lever law front/rear and left/right.
        let com = scene.body.p_world + body.com_body;
        let moment: Vector3<f64> = Leg::ALL
            .iter()
            .map(|l| (scene.feet[0][*l] - com).cross(&sol.forces_world[*l]))
            .sum();
        // The force-effort term trades a residual moment for evener forces; it must stay below
        // 0.5 % of weight × half the hip spacing (≈ 0.11 N·m for the A1).
        let scale =
            weight * (scene.feet[0][Leg::FrontLeft].x - scene.feet[0][Leg::RearLeft].x) / 2.0;
        assert!(
            moment.norm() < 5e-3 * scale,
            "moment about COM {moment:?} N·m vs scale {scale} N·m ({solver:?})"
        );
        let front = sol.forces_world[Leg::FrontLeft].z + sol.forces_world[Leg::FrontRight].z;
        let rear = sol.forces_world[Leg::RearLeft].z + sol.forces_world[Leg::RearRight].z;
        let x_front = scene.feet[0][Leg::FrontLeft].x;
        let x_rear = scene.feet[0][Leg::RearLeft].x;
        // Lever law within 1 %: the same effort-versus-moment trade-off as above.
        assert_relative_eq!(
            front * (x_front - com.x),
            rear * (com.x - x_rear),
            max_relative = 1e-2
        );
    }
}

#[test]
fn a_foot_out_of_contact_gets_zero_force() {
    for drop_swing_forces in [true, false] {
        let mut scene = standing_scene(MpcConfig {
            drop_swing_forces,
            ..MpcConfig::default()
        });
        for c in scene.contacts.iter_mut() {
            c[Leg::FrontRight] = false;
            c[Leg::RearLeft] = false;
        }
        let sol = scene.solve();
        assert!(
            sol.status.is_solved(),
            "drop {drop_swing_forces}: {:?}",
            sol.status
        );
        assert!(
            sol.forces_world[Leg::FrontRight].norm() < 1e-6,
            "{:?}",
            sol.forces_world
        );
        assert!(sol.forces_world[Leg::RearLeft].norm() < 1e-6);
        assert!(
            sol.forces_world[Leg::FrontLeft].z > 20.0,
            "{:?}",
            sol.forces_world
        );
    }
}

#[test]
fn friction_and_force_limits_hold_on_every_solution() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    for solver in [QpSolverKind::Quadprog, QpSolverKind::Clarabel] {
        for _ in 0..30 {
            let config = MpcConfig {
                solver,
                friction_coefficient: rng.random_range(0.2..0.8),
                f_max_n: Some(rng.random_range(60.0..150.0)),
                ..MpcConfig::default()
            };
            let (mu, fmax) = (config.friction_coefficient, config.f_max_n.unwrap());
            let mut scene = standing_scene(config);
            // Demanding references: push hard sideways and forward, tilt, with random contacts.
            let v = Vector3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                0.0,
            );
            for (k, r) in scene.reference.iter_mut().enumerate() {
                r.v_world = v;
                r.p_world += v * 0.025 * (k + 1) as f64;
                r.rpy = Vector3::new(
                    rng.random_range(-0.3..0.3),
                    rng.random_range(-0.3..0.3),
                    rng.random_range(-0.5..0.5),
                );
            }
            for c in scene.contacts.iter_mut() {
                for leg in Leg::ALL {
                    c[leg] = rng.random_bool(0.7);
                }
            }
            let sol = scene.solve();
            assert!(sol.status.is_solved(), "{:?}", sol.status);
            for leg in Leg::ALL {
                let f = sol.forces_world[leg];
                let tol = 1e-6 * (1.0 + fmax);
                assert!(
                    f.x.abs() <= mu * f.z + tol && f.y.abs() <= mu * f.z + tol,
                    "{leg:?} {f:?} mu {mu}"
                );
                assert!(
                    f.z <= fmax + tol && f.z >= -tol,
                    "{leg:?} {f:?} fmax {fmax}"
                );
                if !scene.contacts[0][leg] {
                    assert!(f.norm() < 1e-6);
                }
            }
        }
    }
}

#[test]
fn the_two_qp_solvers_agree() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for _ in 0..10 {
        let mut a = standing_scene(MpcConfig::default());
        let v = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            0.0,
        );
        for r in a.reference.iter_mut() {
            r.v_world = v;
        }
        a.contacts[0][Leg::FrontLeft] = false;
        let mut b = standing_scene(MpcConfig {
            solver: QpSolverKind::Clarabel,
            ..MpcConfig::default()
        });
        b.reference = a.reference.clone();
        b.contacts = a.contacts.clone();
        let (sa, sb) = (a.solve(), b.solve());
        for leg in Leg::ALL {
            assert!(
                (sa.forces_world[leg] - sb.forces_world[leg]).norm() < 0.05,
                "{leg:?}: {:?} vs {:?}",
                sa.forces_world[leg],
                sb.forces_world[leg]
            );
        }
    }
}

#[test]
fn a_repeated_solve_equals_a_fresh_solve() {
    // The MPC object keeps workspace between solves; it must not leak into the answer.
    let mut used = standing_scene(MpcConfig::default());
    for r in used.reference.iter_mut() {
        r.v_world = Vector3::new(0.8, 0.0, 0.0);
    }
    used.solve();
    let mut fresh = standing_scene(MpcConfig::default());
    used.reference = fresh.reference.clone();
    let (s1, s2) = (used.solve(), fresh.solve());
    assert_eq!(s1.forces_world, s2.forces_world);
}

#[test]
fn bad_numbers_give_a_fallback_never_nan() {
    let mut scene = standing_scene(MpcConfig::default());
    scene.body.v_world.x = f64::NAN;
    let sol = scene.solve();
    assert!(
        matches!(sol.status, MpcStatus::FallbackStatic(_)),
        "{:?}",
        sol.status
    );
    assert!(sol
        .forces_world
        .0
        .iter()
        .all(|f| f.iter().all(|v| v.is_finite())));
    // Static fallback still carries the weight.
    scene.body.v_world.x = 0.0;
    let good = scene.solve();
    assert!(good.status.is_solved());
    scene.reference[3].p_world.z = f64::INFINITY;
    let sol = scene.solve();
    assert!(
        matches!(sol.status, MpcStatus::FallbackLastGood(_)),
        "{:?}",
        sol.status
    );
    assert_eq!(sol.forces_world, good.forces_world);
}

#[test]
fn static_distribution_matches_the_lever_law() {
    let scene = standing_scene(MpcConfig::default());
    let input = MpcInput {
        body: &scene.body,
        reference: &scene.reference,
        feet_world: &scene.feet,
        contacts: &scene.contacts,
        heat: None,
    };
    let f = scene.mpc.static_forces(&input, LegMap::splat(true));
    let total: f64 = f.0.iter().map(|v| v.z).sum();
    assert_relative_eq!(
        total,
        scene.mpc.body().mass_kg * GRAVITY,
        max_relative = 1e-9
    );
}

#[test]
fn config_validation_names_the_value() {
    let err = MpcConfig {
        horizon: 0,
        ..MpcConfig::default()
    }
    .validate()
    .unwrap_err()
    .to_string();
    assert!(err.contains("mpc.horizon"), "{err}");
    let err = MpcConfig {
        friction_coefficient: f64::NAN,
        ..MpcConfig::default()
    }
    .validate()
    .unwrap_err()
    .to_string();
    assert!(err.contains("mpc.friction_coefficient"), "{err}");
    let err = MpcConfig {
        f_min_n: 50.0,
        f_max_n: Some(10.0),
        ..MpcConfig::default()
    }
    .validate()
    .unwrap_err()
    .to_string();
    assert!(err.contains("mpc.f_max_n"), "{err}");
    for hold in [0, 11] {
        let err = MpcConfig {
            force_hold_steps: hold,
            ..MpcConfig::default()
        }
        .validate()
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("mpc.force_hold_steps") && err.contains("10"),
            "{err}"
        );
    }
}

#[test]
fn a_diagonal_pair_shares_the_weight() {
    for solver in [QpSolverKind::Quadprog, QpSolverKind::Clarabel] {
        let mut scene = standing_scene(MpcConfig {
            solver,
            ..MpcConfig::default()
        });
        // Put the trunk origin over the FR–RL diagonal's midpoint minus the COM offset so the
        // whole-body COM sits on the diagonal.
        let c = scene.mpc.body().com_body;
        let mid = (scene.feet[0][Leg::FrontRight] + scene.feet[0][Leg::RearLeft]) / 2.0;
        scene.body.p_world = Vector3::new(mid.x - c.x, mid.y - c.y, 0.3);
        for r in scene.reference.iter_mut() {
            r.p_world = scene.body.p_world;
        }
        for c in scene.contacts.iter_mut() {
            c[Leg::FrontLeft] = false;
            c[Leg::RearRight] = false;
        }
        let sol = scene.solve();
        let (fr, rl) = (
            sol.forces_world[Leg::FrontRight],
            sol.forces_world[Leg::RearLeft],
        );
        let weight = scene.mpc.body().mass_kg * GRAVITY;
        println!("{solver:?}: FR {fr:?} RL {rl:?}");
        assert!(
            (fr.z + rl.z - weight).abs() < 0.02 * weight,
            "sum {} vs weight {weight}",
            fr.z + rl.z
        );
        assert!(
            (fr.z - rl.z).abs() < 0.1 * weight,
            "FR {} vs RL {}",
            fr.z,
            rl.z
        );
    }
}

/// The heat term splits a standing robot's weight by what each leg's heat costs. Feet on a
/// rectangle centred under the COM: every split f_FL = f_RR = s, f_FR = f_RL = W/2 − s carries
/// the weight with zero moment. With vertical heat m·f_z² per foot (m = 1 on FL and RR, 3 on FR
/// and RL) the heat m_FL s² + m_RR s² + m_FR (W/2 − s)² + m_RL (W/2 − s)² is least at
/// s* = (m_FR + m_RL)·(W/2) / Σm = 3W/8 (by hand); the force-norm cost alone splits W/4 each.
#[test]
fn the_heat_term_moves_the_standing_weight_to_the_legs_whose_torques_heat_less() {
    let heat = LegMap::from_fn(|leg| {
        let m = match leg {
            Leg::FrontLeft | Leg::RearRight => 1.0,
            _ => 3.0,
        };
        Matrix3::from_diagonal(&Vector3::new(0.05, 0.05, m))
    });
    let split = |weight_heat: f64| {
        // A force per step: the problem the optimum below was worked out for (move blocking
        // ties the later steps' forces and shifts the split by about 1 % of the weight).
        let mut scene = standing_scene(MpcConfig {
            weight_heat: Some(weight_heat),
            force_hold_steps: 1,
            ..MpcConfig::default()
        });
        let com = scene.body.p_world + scene.mpc.body().com_body;
        let feet = LegMap::from_fn(|leg| {
            Vector3::new(
                com.x + 0.18 * leg.front_sign(),
                com.y + 0.13 * leg.side_sign(),
                0.02,
            )
        });
        scene.feet = vec![feet; scene.reference.len()];
        let input = MpcInput {
            body: &scene.body,
            reference: &scene.reference,
            feet_world: &scene.feet,
            contacts: &scene.contacts,
            heat: Some(&heat),
        };
        let sol = scene.mpc.solve(&input);
        assert!(sol.status.is_solved(), "{:?}", sol.status);
        let w = scene.mpc.body().mass_kg * GRAVITY;
        let heat_w: f64 = Leg::ALL
            .iter()
            .map(|l| sol.forces_world[*l].dot(&(heat[*l] * sol.forces_world[*l])))
            .sum();
        (sol.forces_world, w, heat_w)
    };
    let (plain, w, plain_heat) = split(0.0);
    let (heated, _, heated_heat) = split(1e-3);
    // Without the term: a quarter of the weight on each foot.
    for l in Leg::ALL {
        assert_relative_eq!(plain[l].z, w / 4.0, max_relative = 0.02);
    }
    // With it: the hand-worked optimum, 3/8 of the weight on FL and RR, 1/8 on the others.
    for (l, share) in [
        (Leg::FrontLeft, 0.375),
        (Leg::RearRight, 0.375),
        (Leg::FrontRight, 0.125),
        (Leg::RearLeft, 0.125),
    ] {
        assert_relative_eq!(heated[l].z / w, share, epsilon = 0.01);
    }
    // m(s) at s = W/4: 8·(W/4)² = W²/2; at 3W/8: 2·(9/64) + 6·(1/64) = 24/64 = 3W²/8.
    assert_relative_eq!(plain_heat / (w * w), 0.5, max_relative = 0.03);
    // (The tracking terms and the small tangential heat keep it a few % above the optimum.)
    assert_relative_eq!(heated_heat / (w * w), 0.375, max_relative = 0.06);
    assert!(heated_heat < 0.8 * plain_heat);
}

#[test]
fn the_heat_matrix_is_the_heat_of_the_torques_that_hold_a_force() {
    // Second method: τ = −Jᵀ Rᵀ f, heat Σ k τ².
    let j = Matrix3::new(0.0, -0.21, -0.1, 0.2, 0.01, 0.0, 0.05, 0.1, 0.18);
    let r = UnitQuaternion::from_euler_angles(0.1, -0.2, 0.7);
    let k = [0.3, 0.5, 0.2];
    let f = Vector3::new(3.0, -2.0, 30.0);
    let tau = -(j.transpose() * (r.inverse() * f));
    let by_hand: f64 = (0..3).map(|i| k[i] * tau[i] * tau[i]).sum();
    let m = heat_matrix(&j, &r, &k);
    assert_relative_eq!(f.dot(&(m * f)), by_hand, max_relative = 1e-12);
}

#[test]
fn the_decoupled_heat_is_the_trunk_frame_diagonal_whatever_the_heading() {
    let j = Matrix3::new(0.0, -0.21, -0.1, 0.2, 0.01, 0.0, 0.05, 0.1, 0.18);
    let k = [0.3, 0.5, 0.2];
    let level = heat_matrix_decoupled(&j, &UnitQuaternion::identity(), &k);
    let full = heat_matrix(&j, &UnitQuaternion::identity(), &k);
    // Level and facing +x: the full matrix's diagonal, no cross terms.
    for r in 0..3 {
        for c in 0..3 {
            let want = if r == c { full[(r, c)] } else { 0.0 };
            assert_relative_eq!(level[(r, c)], want, epsilon = 1e-15);
        }
    }
    // Turned by any yaw, a force turned with it costs the same.
    let f = Vector3::new(3.0, -2.0, 30.0);
    for yaw in [0.3, std::f64::consts::FRAC_PI_4, 2.0] {
        let r = UnitQuaternion::from_euler_angles(0.0, 0.0, yaw);
        let m = heat_matrix_decoupled(&j, &r, &k);
        assert_relative_eq!(
            (r * f).dot(&(m * (r * f))),
            f.dot(&(level * f)),
            max_relative = 1e-12
        );
    }
}

#[test]
fn force_blocks_hold_runs_of_equal_contact_after_the_first_step() {
    let n = 10;
    let standing = vec![LegMap::splat(true); n];
    let steps = |blocks: &[ForceBlock], leg: Leg| -> Vec<(usize, usize)> {
        blocks
            .iter()
            .filter(|b| b.leg == leg)
            .map(|b| (b.first, b.steps))
            .collect()
    };
    // Worked by hand: steps 0 and 1 alone, then pairs.
    let b = force_blocks(&standing, 2, 2, true);
    assert_eq!(
        steps(&b, Leg::RearLeft),
        [(0, 1), (1, 1), (2, 2), (4, 2), (6, 2), (8, 2)]
    );
    assert_eq!(b.len(), 4 * 6);
    // Holding from step 1: the last step is left alone.
    assert_eq!(
        steps(&force_blocks(&standing, 1, 2, true), Leg::RearLeft),
        [(0, 1), (1, 2), (3, 2), (5, 2), (7, 2), (9, 1)]
    );
    // Ordered by step, then leg.
    assert!(b
        .windows(2)
        .all(|w| (w[0].first, w[0].leg.index()) < (w[1].first, w[1].leg.index())));
    // 1: one block per (step, foot), the paper's problem.
    let b = force_blocks(&standing, 2, 1, true);
    assert_eq!(b.len(), 4 * n);
    assert!(b.iter().all(|b| b.steps == 1));
    // A trot switching pairs at step 5: a run never spans the switch; swing runs are dropped,
    // or kept as zero-force blocks.
    let trot: Vec<LegMap<bool>> = (0..n)
        .map(|k| LegMap::from_fn(|leg| matches!(leg, Leg::FrontRight | Leg::RearLeft) == (k < 5)))
        .collect();
    let b = force_blocks(&trot, 2, 3, true);
    assert_eq!(steps(&b, Leg::FrontRight), [(0, 1), (1, 1), (2, 3)]);
    assert_eq!(steps(&b, Leg::FrontLeft), [(5, 3), (8, 2)]);
    let kept = force_blocks(&trot, 2, 3, false);
    assert_eq!(
        steps(&kept, Leg::FrontLeft),
        [(0, 1), (1, 1), (2, 3), (5, 3), (8, 2)]
    );
    assert!(kept
        .iter()
        .all(|b| b.contact == trot[b.first][b.leg]
            && b.contact == trot[b.first + b.steps - 1][b.leg]));
}

/// Move blocking minimises the same cost over forces tied equal within each block: checked
/// against the full problem (every step's forces) with the ties as equality rows, solved by
/// its KKT system, where no inequality is active.
#[test]
fn a_blocked_solve_is_the_full_problem_with_held_forces_tied() {
    for (start, hold) in [(2, 2), (1, 2), (2, 3)] {
        let mut scene = standing_scene(MpcConfig {
            force_hold_start: start,
            force_hold_steps: hold,
            ..MpcConfig::default()
        });
        for (k, r) in scene.reference.iter_mut().enumerate() {
            r.v_world = Vector3::new(0.05, -0.02, 0.0);
            r.p_world += r.v_world * 0.025 * (k + 1) as f64;
        }
        scene.body.v_world = Vector3::new(0.02, 0.01, 0.0);
        scene.body.omega_world = Vector3::new(0.02, -0.03, 0.01);
        let blocked = scene.solve();
        assert!(blocked.status.is_solved());
        assert_eq!(blocked.iterations, 0, "an inequality is active");
        assert_eq!(
            blocked.qp_size.0,
            3 * force_blocks(&scene.contacts, start, hold, true).len()
        );

        let input = MpcInput {
            body: &scene.body,
            reference: &scene.reference,
            feet_world: &scene.feet,
            contacts: &scene.contacts,
            heat: None,
        };
        scene.mpc.condense_horizon(&input);
        let (h, g) = (scene.mpc.h_full.clone(), scene.mpc.g_full.clone());
        let nu = h.nrows();
        let mut ties = Vec::new();
        for b in force_blocks(&scene.contacts, start, hold, true) {
            for k in b.first + 1..b.first + b.steps {
                for c in 0..3 {
                    let col = |step: usize| step * NU + 3 * b.leg.index() + c;
                    ties.push((col(b.first), col(k)));
                }
            }
        }
        // [2H Eᵀ; E 0] [U; λ] = [−2g; 0] (J = UᵀHU + 2gᵀU).
        let m = ties.len();
        let mut kkt = DMatrix::zeros(nu + m, nu + m);
        let mut rhs = DVector::zeros(nu + m);
        kkt.view_mut((0, 0), (nu, nu)).copy_from(&(&h * 2.0));
        rhs.rows_mut(0, nu).copy_from(&(&g * -2.0));
        for (r, (a, b)) in ties.iter().enumerate() {
            for (col, sign) in [(*a, 1.0), (*b, -1.0)] {
                kkt[(nu + r, col)] = sign;
                kkt[(col, nu + r)] = sign;
            }
        }
        let u = kkt.lu().solve(&rhs).expect("the KKT system is regular");
        for leg in Leg::ALL {
            let full = Vector3::new(
                u[3 * leg.index()],
                u[3 * leg.index() + 1],
                u[3 * leg.index() + 2],
            );
            assert!(
                (full - blocked.forces_world[leg]).norm() < 1e-6,
                "hold {hold}, {leg:?}: {full:?} vs {:?}",
                blocked.forces_world[leg]
            );
        }
    }
}
