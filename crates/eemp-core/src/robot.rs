//! The robot description ([`RobotConfig`], loaded from `robots/<name>.toml`) and what is derived
//! from it: link inertias per leg and the composite rigid body the MPC uses.

use crate::config_error::{check_positive, check_range, ConfigError};
use crate::kinematics::LegKinematics;
use crate::leg::{Leg, LegMap};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// The project's A1 description, compiled in so tests and tools need no working directory.
pub const A1_TOML: &str = include_str!("../../../robots/a1.toml");

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RobotConfig {
    pub name: String,
    pub simulation: SimulationConfig,
    pub trunk: TrunkConfig,
    pub leg: LegConfig,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SimulationConfig {
    /// Physics time step, s.
    pub timestep_s: f64,
    /// Sliding friction coefficient of the floor.
    pub floor_friction: f64,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TrunkConfig {
    pub mass_kg: f64,
    /// Centre of mass in the trunk frame, m.
    pub com_m: [f64; 3],
    /// ixx iyy izz ixy ixz iyz about the COM, kg·m².
    pub inertia_kg_m2: [f64; 6],
    pub collision_half_size_m: [f64; 3],
}

/// Mass properties of one link, expressed for the front-left leg in the link's joint frame.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LinkConfig {
    pub mass_kg: f64,
    pub com_m: [f64; 3],
    /// ixx iyy izz ixy ixz iyz about the COM, kg·m².
    pub inertia_kg_m2: [f64; 6],
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LegConfig {
    pub hip_offset_m: [f64; 2],
    pub abduction_to_thigh_m: f64,
    pub thigh_length_m: f64,
    pub calf_length_m: f64,
    pub foot_radius_m: f64,
    pub abduction_range_rad: [f64; 2],
    pub thigh_range_rad: [f64; 2],
    pub calf_range_rad: [f64; 2],
    pub torque_limit_nm: f64,
    pub damping: [f64; 3],
    pub armature_kg_m2: [f64; 3],
    pub frictionloss_nm: [f64; 3],
    pub standing_pose_rad: [f64; 3],
    pub hip_link: LinkConfig,
    pub thigh_link: LinkConfig,
    pub calf_link: LinkConfig,
}

/// Which link of a leg.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkKind {
    Hip,
    Thigh,
    Calf,
}

impl LinkConfig {
    /// This link's (com, inertia) for `leg`, mirrored from the front-left description.
    /// Mirroring y flips ixy and iyz; mirroring x (rear hips only) flips ixy and ixz.
    pub fn mirrored(&self, leg: Leg, kind: LinkKind) -> (Vector3<f64>, [f64; 6]) {
        let mut com = Vector3::from(self.com_m);
        let mut inertia = self.inertia_kg_m2;
        if leg.side_sign() < 0.0 {
            com.y = -com.y;
            inertia[3] = -inertia[3];
            inertia[5] = -inertia[5];
        }
        if kind == LinkKind::Hip && leg.front_sign() < 0.0 {
            com.x = -com.x;
            inertia[3] = -inertia[3];
            inertia[4] = -inertia[4];
        }
        (com, inertia)
    }
}

fn inertia_matrix(i: &[f64; 6]) -> Matrix3<f64> {
    Matrix3::new(i[0], i[3], i[4], i[3], i[1], i[5], i[4], i[5], i[2])
}

/// Mass, centre of mass and inertia of the whole robot as one rigid body, in the trunk frame.
#[derive(Clone, Debug, PartialEq)]
pub struct CompositeBody {
    pub mass_kg: f64,
    /// Whole-robot COM in the trunk frame, m.
    pub com_body: Vector3<f64>,
    /// Inertia about the COM in trunk-frame axes, kg·m².
    pub inertia_body: Matrix3<f64>,
}

impl RobotConfig {
    /// The A1 shipped with the project (`robots/a1.toml`).
    pub fn a1() -> Self {
        let config: RobotConfig = toml::from_str(A1_TOML).expect("robots/a1.toml parses");
        config.validate().expect("robots/a1.toml is valid");
        config
    }

    /// Loads and validates a robot file.
    pub fn load(path: &std::path::Path) -> Result<Self, ConfigError> {
        let config: RobotConfig = crate::config_error::load_toml(path)?;
        config.validate()?;
        Ok(config)
    }

    pub fn validate(&self) -> Result<(), ConfigError> {
        let s = &self.simulation;
        check_range("simulation.timestep_s", s.timestep_s, 1e-5, 0.005)?;
        check_range("simulation.floor_friction", s.floor_friction, 0.0, 5.0)?;
        check_positive("trunk.mass_kg", self.trunk.mass_kg)?;
        let l = &self.leg;
        for (name, v) in [
            ("leg.abduction_to_thigh_m", l.abduction_to_thigh_m),
            ("leg.thigh_length_m", l.thigh_length_m),
            ("leg.calf_length_m", l.calf_length_m),
            ("leg.foot_radius_m", l.foot_radius_m),
            ("leg.torque_limit_nm", l.torque_limit_nm),
            ("leg.hip_link.mass_kg", l.hip_link.mass_kg),
            ("leg.thigh_link.mass_kg", l.thigh_link.mass_kg),
            ("leg.calf_link.mass_kg", l.calf_link.mass_kg),
        ] {
            check_positive(name, v)?;
        }
        for (name, r) in [
            ("leg.abduction_range_rad", l.abduction_range_rad),
            ("leg.thigh_range_rad", l.thigh_range_rad),
            ("leg.calf_range_rad", l.calf_range_rad),
        ] {
            if r[0].partial_cmp(&r[1]) != Some(std::cmp::Ordering::Less) {
                return Err(ConfigError::Invalid {
                    name: name.to_string(),
                    message: format!("min {} must be below max {}", r[0], r[1]),
                });
            }
        }
        let ranges = [l.abduction_range_rad, l.thigh_range_rad, l.calf_range_rad];
        for (j, name) in ["abduction", "thigh", "calf"].iter().enumerate() {
            check_range(
                &format!("leg.standing_pose_rad[{name}]"),
                l.standing_pose_rad[j],
                ranges[j][0],
                ranges[j][1],
            )?;
        }
        Ok(())
    }

    /// Total mass of the robot, kg.
    pub fn total_mass_kg(&self) -> f64 {
        let l = &self.leg;
        self.trunk.mass_kg + 4.0 * (l.hip_link.mass_kg + l.thigh_link.mass_kg + l.calf_link.mass_kg)
    }

    /// The robot as one rigid body with every leg at joint angles `q` (e.g. the standing pose):
    /// mass, COM and inertia about the COM, in the trunk frame (parallel-axis theorem).
    pub fn composite_body(&self, q: &LegMap<Vector3<f64>>) -> CompositeBody {
        let kin = LegKinematics::new(self);
        // (mass, com in trunk frame, inertia about own com in trunk axes)
        let mut parts: Vec<(f64, Vector3<f64>, Matrix3<f64>)> = vec![(
            self.trunk.mass_kg,
            Vector3::from(self.trunk.com_m),
            inertia_matrix(&self.trunk.inertia_kg_m2),
        )];
        for leg in Leg::ALL {
            let frames = kin.link_frames(leg, &q[leg]);
            for (kind, link) in [
                (LinkKind::Hip, &self.leg.hip_link),
                (LinkKind::Thigh, &self.leg.thigh_link),
                (LinkKind::Calf, &self.leg.calf_link),
            ] {
                let (com, inertia) = link.mirrored(leg, kind);
                let (origin, rot) = frames.of(kind);
                parts.push((
                    link.mass_kg,
                    origin + rot * com,
                    rot * inertia_matrix(&inertia) * rot.transpose(),
                ));
            }
        }
        let mass: f64 = parts.iter().map(|p| p.0).sum();
        let com = parts.iter().map(|p| p.1 * p.0).sum::<Vector3<f64>>() / mass;
        let mut inertia = Matrix3::zeros();
        for (m, c, i) in &parts {
            let d = c - com;
            inertia += i + *m * (Matrix3::identity() * d.dot(&d) - d * d.transpose());
        }
        CompositeBody {
            mass_kg: mass,
            com_body: com,
            inertia_body: inertia,
        }
    }

    /// Standing joint angles for every leg.
    pub fn standing_pose(&self) -> LegMap<Vector3<f64>> {
        LegMap::splat(Vector3::from(self.leg.standing_pose_rad))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn a1_total_mass_matches_reference() {
        let robot = RobotConfig::a1();
        // Reference README: total ≈ 12.5 kg.
        assert_relative_eq!(
            robot.total_mass_kg(),
            4.713 + 4.0 * (0.696 + 1.013 + 0.226),
            epsilon = 1e-12
        );
        let body = robot.composite_body(&robot.standing_pose());
        assert_relative_eq!(body.mass_kg, robot.total_mass_kg(), epsilon = 1e-12);
        // Symmetric robot: COM near the centre line, inertia positive definite.
        assert!(body.com_body.y.abs() < 0.01, "com {:?}", body.com_body);
        assert!(body.inertia_body.symmetric_eigenvalues().min() > 0.0);
    }

    #[test]
    fn validation_names_the_value_and_range() {
        let mut robot = RobotConfig::a1();
        robot.simulation.floor_friction = -0.1;
        let err = robot.validate().unwrap_err().to_string();
        assert!(
            err.contains("simulation.floor_friction") && err.contains("[0, 5]"),
            "{err}"
        );
        let mut robot = RobotConfig::a1();
        robot.simulation.timestep_s = f64::NAN;
        assert!(matches!(
            robot.validate(),
            Err(ConfigError::NotFinite { .. })
        ));
        let mut robot = RobotConfig::a1();
        robot.leg.standing_pose_rad[2] = 0.5;
        let err = robot.validate().unwrap_err().to_string();
        assert!(err.contains("standing_pose_rad[calf]"), "{err}");
    }

    #[test]
    fn unknown_fields_are_rejected() {
        let text = A1_TOML.replace("name = \"a1\"", "name = \"a1\"\nmystery = 3");
        assert!(toml::from_str::<RobotConfig>(&text).is_err());
    }
}
