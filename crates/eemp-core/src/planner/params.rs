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

/// What any robot's body height X_z may be, m: a plausibility bound. Table I's 0.28–0.311 m is
/// the A1 paper's grid, not a limit: the battery's optimum lies above it (straighter knees hold
/// the weight with less torque), and a larger robot stands higher. The robot's own reach is
/// checked where the robot is known ([`crate::robot::RobotConfig::body_height_range_m`]).
pub const BODY_HEIGHT_LIMITS_M: [f64; 2] = [0.05, 2.0];

/// What any robot's swing time, step height and ellipse axes may be: plausibility bounds, as
/// [`BODY_HEIGHT_LIMITS_M`]. Table I's ranges are the A1 paper's grid (the sweeps' and the
/// residuals' ranges); a larger robot swings longer and steps higher
/// ([`PlannerParams::scaled`]).
pub const SWING_TIME_LIMITS_S: [f64; 2] = [0.05, 1.0];
pub const STEP_HEIGHT_LIMITS_M: [f64; 2] = [0.005, 0.5];
pub const ELLIPSE_AXIS_LIMITS_M: [f64; 2] = [0.005, 0.5];
/// The speeds a per-speed table may list, m/s (Table I's 0.05–1 m/s scaled to a large robot
/// goes past 1).
pub const TABLE_SPEED_LIMITS_MPS: [f64; 2] = [0.01, 5.0];

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

/// Table I's range of each parameter, in the order of [`PlannerParams::to_array`].
pub const TABLE_I_RANGES: [[f64; 2]; 5] = [
    table_i::SWING_TIME_S,
    table_i::STEP_HEIGHT_M,
    table_i::BODY_HEIGHT_M,
    table_i::ELLIPSE_AXIS_M,
    table_i::ELLIPSE_AXIS_M,
];

impl PlannerParams {
    /// These parameters on a robot of `scale` (lengths × λ, the swing time × √λ: equal Froude
    /// number, [`crate::robot::RobotScale`]).
    pub fn scaled(&self, scale: &crate::robot::RobotScale) -> Self {
        let (l, t) = (scale.length, scale.length.sqrt());
        PlannerParams {
            swing_time_s: self.swing_time_s * t,
            step_height_m: self.step_height_m * l,
            body_height_m: self.body_height_m * l,
            ellipse_rx_m: self.ellipse_rx_m * l,
            ellipse_ry_m: self.ellipse_ry_m * l,
        }
    }

    /// The names of the parameters, in the order of [`PlannerParams::to_array`].
    pub const NAMES: [&'static str; 5] = [
        "swing_time_s",
        "step_height_m",
        "body_height_m",
        "ellipse_rx_m",
        "ellipse_ry_m",
    ];

    /// [ΔT, h_step, X_z, r_x, r_y].
    pub fn to_array(&self) -> [f64; 5] {
        [
            self.swing_time_s,
            self.step_height_m,
            self.body_height_m,
            self.ellipse_rx_m,
            self.ellipse_ry_m,
        ]
    }

    pub fn from_array(a: [f64; 5]) -> Self {
        PlannerParams {
            swing_time_s: a[0],
            step_height_m: a[1],
            body_height_m: a[2],
            ellipse_rx_m: a[3],
            ellipse_ry_m: a[4],
        }
    }

    /// These parameters moved by `delta` (in [`PlannerParams::to_array`]'s order), each clamped
    /// into Table I; a non-finite component of `delta` counts as 0. With a zero `delta` the
    /// result is `self`, bit for bit, when `self` is inside Table I.
    pub fn offset_within_table_i(&self, delta: &[f64; 5]) -> Self {
        self.offset_within(delta, &TABLE_I_RANGES)
    }

    /// [`Self::offset_within_table_i`] with `ranges` in place of Table I's (e.g. a table's own,
    /// [`super::params_table::ParamsTable::param_ranges`]).
    pub fn offset_within(&self, delta: &[f64; 5], ranges: &[[f64; 2]; 5]) -> Self {
        let mut a = self.to_array();
        for ((v, d), &[lo, hi]) in a.iter_mut().zip(delta).zip(ranges) {
            let d = if d.is_finite() { *d } else { 0.0 };
            *v = (*v + d).clamp(lo, hi);
        }
        Self::from_array(a)
    }

    /// The ellipses shrunk, where needed, to r ≤ `factor` · `mu` · X_z: a stance foot at the
    /// edge of an ellipse that wide sits r from under its hip, and a leg force pointing along
    /// the leg (the cheapest in joint torque) then leans r / X_z from the vertical, which a floor
    /// of friction μ holds only for r ≤ μ · X_z. Never below `floor_m` per axis ([r_x, r_y]:
    /// where eq. (6) puts the touchdown, so a foot does not land outside its ellipse and swing
    /// again at once) nor Table I's smallest axis, and never above the axis it had. `factor` 0
    /// (or a non-finite `mu`) leaves them as they are.
    pub fn within_friction_cone(&self, mu: f64, factor: f64, floor_m: [f64; 2]) -> Self {
        if factor <= 0.0 || !mu.is_finite() {
            return *self;
        }
        let cap = factor * mu * self.body_height_m;
        let shrink = |r: f64, floor: f64| {
            let floor = if floor.is_finite() { floor } else { 0.0 };
            r.min(cap.max(floor).max(table_i::ELLIPSE_AXIS_M[0]))
        };
        PlannerParams {
            ellipse_rx_m: shrink(self.ellipse_rx_m, floor_m[0]),
            ellipse_ry_m: shrink(self.ellipse_ry_m, floor_m[1]),
            ..*self
        }
    }

    /// Checks every parameter against its plausibility bounds (any robot's; the robot's own
    /// reach is checked where the robot is known); the error names the parameter and its range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        for (name, v, [lo, hi]) in [
            ("swing_time_s (ΔT)", self.swing_time_s, SWING_TIME_LIMITS_S),
            (
                "step_height_m (h_step)",
                self.step_height_m,
                STEP_HEIGHT_LIMITS_M,
            ),
            (
                "body_height_m (X_z)",
                self.body_height_m,
                BODY_HEIGHT_LIMITS_M,
            ),
            (
                "ellipse_rx_m (r_x)",
                self.ellipse_rx_m,
                ELLIPSE_AXIS_LIMITS_M,
            ),
            (
                "ellipse_ry_m (r_y)",
                self.ellipse_ry_m,
                ELLIPSE_AXIS_LIMITS_M,
            ),
        ] {
            check_range(name, v, lo, hi)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_offset_is_added_and_clamped_into_table_i() {
        let p = PlannerParams::default();
        assert_eq!(p.offset_within_table_i(&[0.0; 5]), p);
        let q = p.offset_within_table_i(&[-0.05, 0.02, 0.1, -0.5, f64::NAN]);
        // 0.25 − 0.05 = 0.2; 0.10 + 0.02 = 0.12; 0.31 + 0.1 → 0.311 (X_z's top); 0.07 − 0.5 →
        // 0.01 (the axes' bottom); NaN → unchanged.
        assert!((q.swing_time_s - 0.2).abs() < 1e-12);
        assert!((q.step_height_m - 0.12).abs() < 1e-12);
        assert_eq!(q.body_height_m, 0.311);
        assert_eq!(q.ellipse_rx_m, 0.01);
        assert_eq!(q.ellipse_ry_m, p.ellipse_ry_m);
        assert_eq!(PlannerParams::from_array(p.to_array()), p);
    }

    #[test]
    fn the_ellipses_shrink_into_the_friction_cone_from_the_hip() {
        // The trot table's 0.1 m/s entry: r_x 0.15, r_y 0.1 at X_z 0.28.
        let p = PlannerParams {
            body_height_m: 0.28,
            ellipse_rx_m: 0.15,
            ellipse_ry_m: 0.1,
            ..Default::default()
        };
        // μ 0.6: 0.168 m, above both axes: unchanged, bit for bit.
        assert_eq!(p.within_friction_cone(0.6, 1.0, [0.0; 2]), p);
        // μ 0.2: 0.2 · 0.28 = 0.056 m for both; the rest unchanged.
        let q = p.within_friction_cone(0.2, 1.0, [0.0; 2]);
        assert!((q.ellipse_rx_m - 0.056).abs() < 1e-12, "{q:?}");
        assert!((q.ellipse_ry_m - 0.056).abs() < 1e-12);
        assert_eq!(
            (q.swing_time_s, q.step_height_m, q.body_height_m),
            (p.swing_time_s, p.step_height_m, p.body_height_m)
        );
        // A factor of 1.5 at μ 0.3: 0.126 m caps r_x only.
        let r = p.within_friction_cone(0.3, 1.5, [0.0; 2]);
        assert!((r.ellipse_rx_m - 0.126).abs() < 1e-12);
        assert_eq!(r.ellipse_ry_m, 0.1);
        // Not below the floor (the touchdown's offset), nor above the axis it had.
        let s = p.within_friction_cone(0.2, 1.0, [0.08, 0.2]);
        assert_eq!((s.ellipse_rx_m, s.ellipse_ry_m), (0.08, 0.1));
        // Never below Table I's smallest axis; off with factor 0 or without a coefficient.
        assert_eq!(
            p.within_friction_cone(0.001, 1.0, [0.0; 2]).ellipse_rx_m,
            0.01
        );
        assert_eq!(p.within_friction_cone(0.2, 0.0, [0.0; 2]), p);
        assert_eq!(p.within_friction_cone(f64::NAN, 1.0, [0.0; 2]), p);
    }

    #[test]
    fn table_ii_defaults_are_valid_and_out_of_range_values_are_named() {
        PlannerParams::default().validate().unwrap();
        // Plausibility bounds, not Table I's grid: a large robot swings longer than 0.25 s.
        PlannerParams {
            swing_time_s: 0.3,
            ..Default::default()
        }
        .validate()
        .unwrap();
        let err = PlannerParams {
            swing_time_s: 1.3,
            ..Default::default()
        }
        .validate()
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("swing_time_s") && err.contains("[0.05, 1]"),
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
            err.contains("ellipse_ry_m") && err.contains("[0.005, 0.5]"),
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
