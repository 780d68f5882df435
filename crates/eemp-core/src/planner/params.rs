//! The planner's five parameters [ΔT, h_step, X_z, r_x, r_y], bounded by the paper's Table I.

use crate::config_error::{check_range, ConfigError};
use serde::{Deserialize, Serialize};

/// Table I: the ranges the parameter study covers, used as validation bounds.
pub mod table_i {
    pub const SPEED_MPS: [f64; 2] = [0.05, 1.00];
    pub const SWING_TIME_S: [f64; 2] = [0.10, 0.25];
    pub const STEP_HEIGHT_M: [f64; 2] = [0.05, 0.15];
    pub const BODY_HEIGHT_M: [f64; 2] = [0.28, 0.311];
    pub const ELLIPSE_AXIS_M: [f64; 2] = [0.01, 0.15];
}

/// Planner parameters (the action of EEMP-RL, the grid of EEMP-Analytical).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlannerParams {
    /// ΔT: swing duration, s.
    pub swing_time_s: f64,
    /// h_step: apex height of the swing, m.
    pub step_height_m: f64,
    /// X_z: trunk height above the ground, m.
    pub body_height_m: f64,
    /// r_x: ellipse semi-axis along the heading, m.
    pub ellipse_rx_m: f64,
    /// r_y: ellipse semi-axis across the heading, m.
    pub ellipse_ry_m: f64,
}

impl Default for PlannerParams {
    /// Table II: the best constant parameters across velocities in the paper.
    fn default() -> Self {
        PlannerParams {
            swing_time_s: 0.25,
            step_height_m: 0.10,
            body_height_m: 0.31,
            ellipse_rx_m: 0.07,
            ellipse_ry_m: 0.05,
        }
    }
}

impl PlannerParams {
    /// Checks every parameter against Table I; the error names the parameter and its range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        use table_i::*;
        check_range(
            "swing_time_s (ΔT)",
            self.swing_time_s,
            SWING_TIME_S[0],
            SWING_TIME_S[1],
        )?;
        check_range(
            "step_height_m (h_step)",
            self.step_height_m,
            STEP_HEIGHT_M[0],
            STEP_HEIGHT_M[1],
        )?;
        check_range(
            "body_height_m (X_z)",
            self.body_height_m,
            BODY_HEIGHT_M[0],
            BODY_HEIGHT_M[1],
        )?;
        check_range(
            "ellipse_rx_m (r_x)",
            self.ellipse_rx_m,
            ELLIPSE_AXIS_M[0],
            ELLIPSE_AXIS_M[1],
        )?;
        check_range(
            "ellipse_ry_m (r_y)",
            self.ellipse_ry_m,
            ELLIPSE_AXIS_M[0],
            ELLIPSE_AXIS_M[1],
        )?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_ii_defaults_are_valid_and_out_of_range_values_are_named() {
        PlannerParams::default().validate().unwrap();
        let err = PlannerParams {
            swing_time_s: 0.3,
            ..Default::default()
        }
        .validate()
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("swing_time_s") && err.contains("[0.1, 0.25]"),
            "{err}"
        );
        let err = PlannerParams {
            ellipse_ry_m: 0.0,
            ..Default::default()
        }
        .validate()
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("ellipse_ry_m") && err.contains("[0.01, 0.15]"),
            "{err}"
        );
        let err = PlannerParams {
            body_height_m: f64::NAN,
            ..Default::default()
        }
        .validate()
        .unwrap_err()
        .to_string();
        assert!(err.contains("body_height_m"), "{err}");
    }
}
