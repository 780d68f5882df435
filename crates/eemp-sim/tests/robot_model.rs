//! Robots read from their own MuJoCo models (`eemp_sim::robot_model`).

use eemp_sim::robot_model::load_robot;
use std::path::Path;

fn repo(p: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(p)
}

#[test]
fn b2_loads() {
    let robot = load_robot(&repo("robots/b2.toml")).unwrap();
    let m = robot.model.as_ref().unwrap();
    println!("{}", &m.mjcf[..3000.min(m.mjcf.len())]);
    println!(
        "mass {} trunk {:?} leg {:?}",
        robot.total_mass_kg(),
        robot.trunk,
        robot.leg
    );
    for leg in eemp_core::leg::Leg::ALL {
        println!("{leg:?} {:?}", m.legs[leg]);
    }
}
