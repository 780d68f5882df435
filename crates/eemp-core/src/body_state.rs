//! State of the trunk and the joints, with frames in every name.

use crate::leg::LegMap;
use nalgebra::{UnitQuaternion, Vector3};

/// Trunk state. Position and velocities are of the trunk-frame origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyState {
    /// Trunk origin in the world frame, m.
    pub p_world: Vector3<f64>,
    /// Orientation: rotates body-frame vectors into the world frame.
    pub r_world_body: UnitQuaternion<f64>,
    /// Linear velocity of the trunk origin in the world frame, m/s.
    pub v_world: Vector3<f64>,
    /// Angular velocity in the world frame, rad/s.
    pub omega_world: Vector3<f64>,
}

impl BodyState {
    /// Roll, pitch, yaw (ZYX convention: R = Rz(yaw)·Ry(pitch)·Rx(roll)), rad.
    pub fn rpy(&self) -> Vector3<f64> {
        let (r, p, y) = self.r_world_body.euler_angles();
        Vector3::new(r, p, y)
    }

    /// Linear velocity in the body frame, m/s.
    pub fn v_body(&self) -> Vector3<f64> {
        self.r_world_body.inverse() * self.v_world
    }

    /// Linear velocity in the yaw-aligned horizontal frame (heading frame), m/s: what a
    /// joystick command refers to.
    pub fn v_heading(&self) -> Vector3<f64> {
        let yaw = self.rpy().z;
        UnitQuaternion::from_euler_angles(0.0, 0.0, -yaw) * self.v_world
    }

    pub fn is_finite(&self) -> bool {
        self.p_world.iter().all(|v| v.is_finite())
            && self.r_world_body.coords.iter().all(|v| v.is_finite())
            && self.v_world.iter().all(|v| v.is_finite())
            && self.omega_world.iter().all(|v| v.is_finite())
    }
}

/// Joint angles (rad) and velocities (rad/s) of one leg: abduction, thigh, calf.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct LegJointState {
    pub q: Vector3<f64>,
    pub qd: Vector3<f64>,
}

/// Everything a controller reads each step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RobotState {
    /// Time since start, s.
    pub time_s: f64,
    pub body: BodyState,
    pub joints: LegMap<LegJointState>,
}
