//! A desired trunk state at one instant: what the planner hands the MPC for each horizon step.

use nalgebra::Vector3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyReference {
    /// Roll, pitch, yaw (ZYX), rad.
    pub rpy: Vector3<f64>,
    /// Trunk origin, world frame, m.
    pub p_world: Vector3<f64>,
    /// Angular velocity, world frame, rad/s.
    pub omega_world: Vector3<f64>,
    /// Linear velocity, world frame, m/s.
    pub v_world: Vector3<f64>,
}
