//! Each terrain builds, says its own height right (against MuJoCo's ray casts), a sphere
//! dropped on it comes to rest at that height, and a foot resting on the rough field comes free
//! when it is lifted.

use eemp_core::leg::LegMap;
use eemp_core::robot::RobotConfig;
use eemp_sim::terrain::{FrictionPatch, Ramp, Rough, Stairs, Step, Terrain};
use eemp_sim::Simulation;
use mujoco_rs::prelude::*;
use nalgebra::Vector3;

fn terrains() -> Vec<(&'static str, Terrain)> {
    vec![
        (
            "rough",
            Terrain {
                rough: Some(Rough {
                    amplitude_m: 0.02,
                    wavelength_m: 0.5,
                    seed: 3,
                    size_m: 8.0,
                }),
                ..Default::default()
            },
        ),
        (
            "ramp",
            Terrain {
                ramp: Some(Ramp {
                    start_x_m: 1.0,
                    grade: 0.1,
                    rise_m: 0.2,
                    plateau_m: 1.0,
                }),
                ..Default::default()
            },
        ),
        (
            "step",
            Terrain {
                step: Some(Step {
                    at_x_m: 1.0,
                    height_m: 0.04,
                }),
                ..Default::default()
            },
        ),
        (
            "step down",
            Terrain {
                step: Some(Step {
                    at_x_m: 1.0,
                    height_m: -0.08,
                }),
                ..Default::default()
            },
        ),
        ("stairs up", stairs(0.05)),
        ("stairs down", stairs(-0.05)),
        ("patch", patch()),
    ]
}

fn stairs(rise_m: f64) -> Terrain {
    Terrain {
        stairs: Some(Stairs {
            at_x_m: 0.5,
            rise_m,
            run_m: 0.3,
            count: 4,
        }),
        ..Default::default()
    }
}

#[test]
fn ground_that_goes_down_starts_on_a_platform_and_bad_steps_are_refused_by_name() {
    // Four 5 cm steps down: the start stands 20 cm up, each step 5 cm lower, the landing on the
    // floor plane.
    let down = stairs(-0.05);
    assert!((down.start_lift_m() - 0.2).abs() < 1e-12);
    for (x, z) in [
        (0.0, 0.2),
        (0.6, 0.15),
        (0.9, 0.1),
        (1.2, 0.05),
        (1.6, 0.0),
        (5.0, 0.0),
    ] {
        assert!(
            (down.height_at(x, 0.0) - z).abs() < 1e-12,
            "{x}: {}",
            down.height_at(x, 0.0)
        );
    }
    let up = stairs(0.05);
    assert_eq!(up.start_lift_m(), 0.0);
    assert!((up.height_at(1.6, 0.0) - 0.2).abs() < 1e-12);
    for (t, says) in [
        (
            Terrain {
                step: Some(Step {
                    at_x_m: 1.0,
                    height_m: 0.001,
                }),
                ..Default::default()
            },
            "terrain.step.height_m",
        ),
        (
            Terrain {
                stairs: Some(Stairs {
                    at_x_m: 1.0,
                    rise_m: 0.3,
                    run_m: 0.3,
                    count: 4,
                }),
                ..Default::default()
            },
            "terrain.stairs.rise_m",
        ),
        (
            Terrain {
                ramp: Some(Ramp {
                    start_x_m: 1.0,
                    grade: 0.1,
                    rise_m: 0.2,
                    plateau_m: 1.0,
                }),
                ..stairs(-0.05)
            },
            "terrain.ramp",
        ),
    ] {
        let e = t.validate().unwrap_err().to_string();
        assert!(e.contains(says), "{e}");
    }
}

fn patch() -> Terrain {
    Terrain {
        friction_patch: vec![FrictionPatch {
            x0_m: 0.5,
            x1_m: 2.5,
            width_m: 4.0,
            friction: 0.2,
        }],
        ..Default::default()
    }
}

const R: f64 = 0.03;

fn with_probe(t: &Terrain, at: [f64; 2]) -> Simulation {
    let robot = RobotConfig::a1();
    let mut extras = t.scene(robot.simulation.floor_friction);
    extras.world_geoms_xml += &format!(
        r#"    <body name="probe" pos="{} {} {}"><freejoint/><geom name="probe" type="sphere" size="{R}" mass="0.2" contype="1" conaffinity="1" condim="6" friction="1 0.5 0.5"/></body>
"#,
        at[0],
        at[1],
        t.height_at(at[0], at[1]) + R + 0.02
    );
    Simulation::new(&robot, &extras).unwrap()
}

#[test]
fn every_terrain_reports_the_height_mujoco_sees() {
    for (name, t) in terrains() {
        t.validate().unwrap();
        let mut sim = with_probe(&t, [0.0, 3.5]);
        sim.data_mut().forward();
        for k in 0..200 {
            let (x, y) = (-1.5 + 0.031 * k as f64, 1.2 + 0.013 * (k % 37) as f64);
            let (hit, dist) =
                sim.data_mut()
                    .ray(&[x, y, 2.0], &[0.0, 0.0, -1.0], None, true, None, None);
            assert!(hit.is_some(), "{name}: nothing below ({x}, {y})");
            let ground = 2.0 - dist;
            let said = t.height_at(x, y);
            assert!(
                (ground - said).abs() < 2e-3,
                "{name} at ({x:.3}, {y:.3}): MuJoCo {ground:.4} m, terrain says {said:.4} m"
            );
        }
    }
}

/// Where the probe sphere comes to rest (its centre), dropped at `at`.
fn rest(t: &Terrain, at: [f64; 2]) -> [f64; 3] {
    let mut sim = with_probe(t, at);
    for _ in 0..1500 {
        sim.step_bare(&LegMap::splat(Vector3::zeros()));
    }
    let body = sim
        .model()
        .name_to_id(MjtObjBase::mjOBJ_BODY, "probe")
        .unwrap();
    sim.data().xpos()[body]
}

#[test]
fn a_sphere_rests_at_the_height_the_terrain_says() {
    // The floor's contacts are soft (the sphere sinks ~14 mm into it): the flat floor gives the
    // resting height of the same sphere on level ground. The rough field and the patch are
    // stiff (see `eemp_sim::terrain`): the sphere hardly sinks into them.
    let flat = rest(&Terrain::default(), [1.3, 2.2])[2];
    assert!((flat - R).abs() < 0.02);
    for (name, t) in terrains() {
        // On the plateau / after the step / in the field.
        let at = match name {
            "ramp" => [3.5, 2.0],
            "step" => [1.5, 2.0],
            "patch" => [1.5, 1.0],
            _ => [1.3, 2.2],
        };
        let p = rest(&t, at);
        let sink = if name == "patch" || name == "rough" {
            0.0
        } else {
            flat - R
        };
        let expected = t.height_at(p[0], p[1]) + R + sink;
        assert!(
            (p[2] - expected).abs() < 0.003 || (name == "patch" && (p[2] - expected).abs() < 0.002),
            "{name}: sphere at {:.4} m, the terrain says it rests at {expected:.4} m",
            p[2]
        );
    }
}

#[test]
fn a_foot_resting_on_the_rough_field_comes_free_when_lifted() {
    // An A1 foot (a 2 cm sphere) dropped from 10 cm (landing at 1.4 m/s, as a stance leg that
    // reaches down for ground lower than planned does) at 60 points of a ±2 cm field, many of
    // them on the corners of its 5 cm cells, then pulled up with its weight + 20 N for 0.2 s.
    // With the floor's soft contact 20 of these 60 stayed caught between the walls of
    // neighbouring cells (what held a swing foot on the ground and toppled every EEMP gait).
    let t = Terrain {
        rough: Some(Rough {
            amplitude_m: 0.02,
            wavelength_m: 0.5,
            seed: 1,
            size_m: 16.0,
        }),
        ..Default::default()
    };
    let robot = RobotConfig::a1();
    let (radius, mass) = (robot.leg.foot_radius_m, 1.0);
    let points: Vec<(f64, f64)> = (0..20)
        .flat_map(|i| [-0.3, -0.319, -0.2].map(|y| (2.0 + 0.05 * i as f64, y)))
        .collect();
    // One model, one foot per point; the feet touch the ground but not each other (contype 2).
    let mut extras = t.scene(robot.simulation.floor_friction);
    for (k, (x, y)) in points.iter().enumerate() {
        extras.world_geoms_xml += &format!(
            r#"    <body name="foot{k}" pos="{x} {y} {}"><freejoint/><geom type="sphere" size="{radius}" mass="{mass}" contype="2" conaffinity="1" condim="3" friction="0.8 0.02 0.01"/></body>
"#,
            t.height_at(*x, *y) + radius + 0.1
        );
    }
    let mut sim = Simulation::new(&robot, &extras).unwrap();
    let bodies: Vec<usize> = (0..points.len())
        .map(|k| {
            sim.model()
                .name_to_id(MjtObjBase::mjOBJ_BODY, &format!("foot{k}"))
                .unwrap()
        })
        .collect();
    for _ in 0..600 {
        sim.step_bare(&LegMap::splat(Vector3::zeros()));
    }
    let z0: Vec<f64> = bodies.iter().map(|b| sim.data().xpos()[*b][2]).collect();
    for _ in 0..200 {
        for b in &bodies {
            sim.data_mut().xfrc_applied_mut()[*b] = [0.0, 0.0, mass * 9.81 + 20.0, 0.0, 0.0, 0.0];
        }
        sim.step_bare(&LegMap::splat(Vector3::zeros()));
    }
    let caught: Vec<(f64, f64)> = bodies
        .iter()
        .zip(&z0)
        .zip(&points)
        .filter(|((b, z), _)| sim.data().xpos()[**b][2] - **z < 0.05)
        .map(|(_, p)| *p)
        .collect();
    assert!(caught.is_empty(), "feet caught at {caught:?}");
}

/// How far a 2 kg box launched at 1 m/s along x from `x0` slides before it stops.
fn slide(t: &Terrain, x0: f64) -> f64 {
    let robot = RobotConfig::a1();
    let mut extras = t.scene(robot.simulation.floor_friction);
    let z = t.height_at(x0, 1.0) + 0.05;
    extras.world_geoms_xml += &format!(
        r#"    <body name="puck" pos="{x0} 1 {z}"><freejoint/><geom type="box" size="0.05 0.05 0.05" mass="2" contype="1" conaffinity="1"/></body>
"#
    );
    let mut sim = Simulation::new(&robot, &extras).unwrap();
    let body = sim
        .model()
        .name_to_id(MjtObjBase::mjOBJ_BODY, "puck")
        .unwrap();
    for _ in 0..300 {
        sim.step_bare(&LegMap::splat(Vector3::zeros()));
    }
    let start = sim.data().xpos()[body][0];
    let dof = sim.model().body_dofadr()[body] as usize;
    sim.data_mut().qvel_mut()[dof] = 1.0;
    for _ in 0..2000 {
        sim.step_bare(&LegMap::splat(Vector3::zeros()));
    }
    sim.data().xpos()[body][0] - start
}

#[test]
fn a_box_slides_further_on_the_low_friction_patch() {
    // v²/(2μg): 0.25 m at μ = 0.2, 0.064 m at the floor's 0.8.
    let on_patch = slide(&patch(), 1.0);
    let on_floor = slide(&Terrain::default(), 1.0);
    assert!(
        (on_patch - 0.255).abs() < 0.05,
        "slid {on_patch} m on the patch"
    );
    assert!(
        (on_floor - 0.064).abs() < 0.02,
        "slid {on_floor} m on the floor"
    );
}
