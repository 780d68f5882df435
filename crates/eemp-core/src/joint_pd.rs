//! Joint-space PD: τ = K_p (q* − q) − K_d q̇, clamped to the motor limit. How learned policies
//! act (their action is a set of joint position targets) and how the A1's own low-level
//! controller holds a pose.

use crate::config_error::{check_range, ConfigError};
use crate::controller::{ControlInput, Controller};
use crate::leg::LegMap;
use crate::leg_control::clamp_torque;
use crate::locomotion::ControlOutput;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PdGains {
    /// Stiffness, N·m/rad (all joints).
    pub kp_nm_per_rad: f64,
    /// Damping, N·m·s/rad (all joints).
    pub kd_nm_s_per_rad: f64,
}

impl Default for PdGains {
    /// Kp 40, Kd 1: legged_gym's A1 gains (Kp 20, Kd 0.5) let the robot sag from the project's
    /// standing pose (thigh 0.9, calf −1.8 rad) to a 0.19 m trunk with the knees on the floor
    /// (measured); twice those hold it at 0.26 m and stay well inside the 4 ms step's
    /// stability limit (Kd·dt/I ≈ 0.3).
    fn default() -> Self {
        PdGains {
            kp_nm_per_rad: 40.0,
            kd_nm_s_per_rad: 1.0,
        }
    }
}

impl PdGains {
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("pd.kp_nm_per_rad", self.kp_nm_per_rad, 0.0, 1000.0)?;
        check_range("pd.kd_nm_s_per_rad", self.kd_nm_s_per_rad, 0.0, 100.0)
    }
}

/// PD torques for `targets` at the joint state `q`, `qd`.
pub fn pd_torques(
    gains: &PdGains,
    targets: &LegMap<Vector3<f64>>,
    q: &LegMap<Vector3<f64>>,
    qd: &LegMap<Vector3<f64>>,
    torque_limit_nm: [f64; 3],
) -> LegMap<Vector3<f64>> {
    LegMap::from_fn(|leg| {
        let tau = (targets[leg] - q[leg]) * gains.kp_nm_per_rad - qd[leg] * gains.kd_nm_s_per_rad;
        clamp_torque(&tau, &torque_limit_nm)
    })
}

/// Holds the joints at targets that the owner sets between steps.
#[derive(Clone, Debug)]
pub struct JointPd {
    pub gains: PdGains,
    pub targets: LegMap<Vector3<f64>>,
    /// Per joint (abduction, thigh, calf), N·m.
    pub torque_limit_nm: [f64; 3],
}

impl Controller for JointPd {
    fn control(&mut self, input: &ControlInput) -> ControlOutput {
        let q = input.state.joints.map(|_, j| j.q);
        let qd = input.state.joints.map(|_, j| j.qd);
        ControlOutput {
            torques: pd_torques(&self.gains, &self.targets, &q, &qd, self.torque_limit_nm),
            forces_world: LegMap::splat(Vector3::zeros()),
            mpc_event: None,
        }
    }

    fn needs_dynamics(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pd_torque_matches_a_hand_computed_value_and_is_clamped() {
        let gains = PdGains {
            kp_nm_per_rad: 20.0,
            kd_nm_s_per_rad: 0.5,
        };
        let targets = LegMap::splat(Vector3::new(0.1, 0.9, -1.8));
        let q = LegMap::splat(Vector3::new(0.0, 1.0, -1.8));
        let qd = LegMap::splat(Vector3::new(2.0, 0.0, -4.0));
        let tau = pd_torques(&gains, &targets, &q, &qd, [33.5; 3]);
        // 20·0.1 − 0.5·2 = 1; 20·(−0.1) = −2; 0.5·4 = 2.
        assert!((tau.0[0] - Vector3::new(1.0, -2.0, 2.0)).norm() < 1e-12);
        let far = LegMap::splat(Vector3::new(3.0, 0.0, 0.0));
        let tau = pd_torques(&gains, &far, &q, &qd, [33.5; 3]);
        assert!((tau.0[0].x - 33.5).abs() < 1e-12);
    }
}
