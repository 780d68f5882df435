//! Joint torques of one leg: the swing law of eq. (1) and the stance map of eq. (2).

use crate::config_error::{check_range, ConfigError};
use crate::leg::Leg;
use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// Joint-space dynamics of one leg at the current state: the 3×3 block of the mass matrix for
/// its joints and the bias torque C(q, q̇)q̇ + G(q) on them (Coriolis/centrifugal + gravity,
/// the V + G of eq. 1), both including the coupling of the moving trunk.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LegDynamics {
    pub mass_matrix: Matrix3<f64>,
    pub bias_torque: Vector3<f64>,
}

/// What the controllers need from a rigid-body dynamics model. The simulator implements it
/// from MuJoCo's mass matrix and bias forces; on hardware a model library would.
pub trait DynamicsModel {
    fn leg_dynamics(&self, leg: Leg) -> LegDynamics;
}

/// Operational-space gains of the swing law, per body-frame axis.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SwingGains {
    /// Proportional gain K_p, N/m.
    pub kp_n_per_m: [f64; 3],
    /// Derivative gain K_d, N·s/m.
    pub kd_n_s_per_m: [f64; 3],
    /// Add the feed-forward J^T Λ a_ref term of eq. (1).
    pub feedforward_acceleration: bool,
}

impl Default for SwingGains {
    fn default() -> Self {
        SwingGains {
            kp_n_per_m: [700.0, 700.0, 700.0],
            kd_n_s_per_m: [20.0, 20.0, 20.0],
            feedforward_acceleration: true,
        }
    }
}

impl SwingGains {
    pub fn validate(&self) -> Result<(), ConfigError> {
        for i in 0..3 {
            check_range(
                &format!("swing.kp_n_per_m[{i}]"),
                self.kp_n_per_m[i],
                0.0,
                1e5,
            )?;
            check_range(
                &format!("swing.kd_n_s_per_m[{i}]"),
                self.kd_n_s_per_m[i],
                0.0,
                1e4,
            )?;
        }
        Ok(())
    }
}

/// Desired foot motion in the body frame (relative to the trunk): m, m/s, m/s².
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct FootReference {
    pub p_body: Vector3<f64>,
    pub v_body: Vector3<f64>,
    pub a_body: Vector3<f64>,
}

/// Measured foot motion in the body frame (forward kinematics of the encoders).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FootMeasurement {
    pub p_body: Vector3<f64>,
    pub v_body: Vector3<f64>,
    /// Foot Jacobian ∂p_body/∂q.
    pub jacobian: Matrix3<f64>,
}

/// Eq. (1): τ = Jᵀ[K_p(p_ref − p) + K_d(v_ref − v)] + Jᵀ Λ a_ref + V + G, with the
/// operational-space mass matrix Λ = (J M⁻¹ Jᵀ)⁻¹. Near a singular Jacobian Λ is dropped (the
/// feed-forward term would explode), leaving the PD and bias terms.
pub fn swing_torque(
    reference: &FootReference,
    foot: &FootMeasurement,
    gains: &SwingGains,
    dynamics: &LegDynamics,
) -> Vector3<f64> {
    let kp = Vector3::from(gains.kp_n_per_m);
    let kd = Vector3::from(gains.kd_n_s_per_m);
    let force = kp.component_mul(&(reference.p_body - foot.p_body))
        + kd.component_mul(&(reference.v_body - foot.v_body));
    let jt = foot.jacobian.transpose();
    let mut tau = jt * force + dynamics.bias_torque;
    if gains.feedforward_acceleration {
        if let Some(lambda) = operational_space_mass(&foot.jacobian, &dynamics.mass_matrix) {
            tau += jt * (lambda * reference.a_body);
        }
    }
    tau
}

/// Λ = (J M⁻¹ Jᵀ)⁻¹, or None when M or J J^T is (near) singular.
pub fn operational_space_mass(
    jacobian: &Matrix3<f64>,
    mass_matrix: &Matrix3<f64>,
) -> Option<Matrix3<f64>> {
    let m_inv = mass_matrix.try_inverse()?;
    let inv_lambda = jacobian * m_inv * jacobian.transpose();
    if inv_lambda.determinant().abs() < 1e-12 {
        return None;
    }
    inv_lambda.try_inverse()
}

/// Eq. (2): the joint torques that make the ground push on the foot with `f_world` (force of the
/// ground on the robot, world frame): τ = −Jᵀ Rᵀ f. The paper writes τ = Jᵀ R f with f the
/// force the leg applies; the sign here follows from f being the ground-reaction force.
pub fn stance_torque(
    jacobian: &Matrix3<f64>,
    r_world_body: &UnitQuaternion<f64>,
    f_world: &Vector3<f64>,
) -> Vector3<f64> {
    -(jacobian.transpose() * (r_world_body.inverse() * f_world))
}

/// Clamps each joint torque to ±limit and replaces non-finite values by 0.
pub fn clamp_torque(tau: &Vector3<f64>, limits_nm: &[f64; 3]) -> Vector3<f64> {
    Vector3::from_fn(|j, _| {
        let t = tau[j];
        if t.is_finite() {
            t.clamp(-limits_nm[j], limits_nm[j])
        } else {
            0.0
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn swing_law_matches_eq_1_term_by_term() {
        let j = Matrix3::new(0.1, 0.02, 0.0, 0.0, 0.2, 0.05, -0.03, 0.0, 0.18);
        let m = Matrix3::new(0.08, 0.01, 0.0, 0.01, 0.05, 0.02, 0.0, 0.02, 0.03);
        let dynamics = LegDynamics {
            mass_matrix: m,
            bias_torque: Vector3::new(0.5, -1.0, 0.25),
        };
        let gains = SwingGains {
            kp_n_per_m: [100.0, 200.0, 300.0],
            kd_n_s_per_m: [1.0, 2.0, 3.0],
            feedforward_acceleration: true,
        };
        let r = FootReference {
            p_body: Vector3::new(0.1, 0.0, -0.2),
            v_body: Vector3::new(0.5, 0.0, 0.1),
            a_body: Vector3::new(2.0, 1.0, -3.0),
        };
        let f = FootMeasurement {
            p_body: Vector3::new(0.09, 0.01, -0.21),
            v_body: Vector3::new(0.4, 0.1, 0.0),
            jacobian: j,
        };
        let tau = swing_torque(&r, &f, &gains, &dynamics);
        // By hand: e = (0.01, −0.01, 0.01), ė = (0.1, −0.1, 0.1), so
        // PD force = (100·0.01 + 1·0.1, 200·(−0.01) + 2·(−0.1), 300·0.01 + 3·0.1) = (1.1, −2.2, 3.3).
        let pd = Vector3::new(1.1, -2.2, 3.3);
        let lambda = (j * m.try_inverse().unwrap() * j.transpose())
            .try_inverse()
            .unwrap();
        let expected =
            j.transpose() * pd + j.transpose() * lambda * r.a_body + dynamics.bias_torque;
        assert_relative_eq!(tau, expected, epsilon = 1e-9);
        // Λ: with J square and invertible, Jᵀ Λ J = M (a second way to compute it).
        assert_relative_eq!(
            j.transpose() * lambda * j,
            m,
            epsilon = 1e-12,
            max_relative = 1e-9
        );
    }

    #[test]
    fn stance_torque_pushes_the_ground_down_to_get_an_upward_force() {
        // With J = I the torque is just −Rᵀf.
        let r = UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        let tau = stance_torque(&Matrix3::identity(), &r, &Vector3::new(1.0, 0.0, 50.0));
        // World x is body −y after a 90° yaw: Rᵀ(1, 0, 50) = (0, −1, 50).
        assert_relative_eq!(tau, Vector3::new(0.0, 1.0, -50.0), epsilon = 1e-12);
    }

    #[test]
    fn clamp_respects_the_limit_and_removes_nan() {
        let t = clamp_torque(&Vector3::new(50.0, -50.0, f64::NAN), &[33.5; 3]);
        assert_eq!(t, Vector3::new(33.5, -33.5, 0.0));
        // Per joint (the Go2: 23.7 N·m at hip and thigh, 45.43 N·m at the knee).
        let go2 = [23.7, 23.7, 45.43];
        let t = clamp_torque(&Vector3::new(-30.0, 30.0, 50.0), &go2);
        assert_eq!(t, Vector3::new(-23.7, 23.7, 45.43));
    }
}
