//! Thresholds fixed by a robot's size rather than tuned: each is written once here with the
//! A1's value and its unit, and every robot gets it scaled by that unit at equal Froude number
//! ([`RobotScale::sized`]; λ and μ are exactly 1 for the A1, whose values are unchanged).
//! They apply to every robot, typed or read from its own model: they define measurements (when
//! a run has fallen, when a foot carries the robot) and plausible inputs, not the controller's
//! tuning (that is the settings tree, scaled for model robots by
//! [`crate::robot::RobotConfig::settings_scale`]).
//!
//! `eemp robot check` prints the table for the robot it checks; `docs/robots.md` lists the
//! rules.

use crate::robot::RobotScale;

/// A size-bound constant: the A1's value, its unit (as the settings keys write units) and why.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SizedConstant {
    pub name: &'static str,
    pub a1_value: f64,
    pub unit: &'static str,
    pub about: &'static str,
}

/// A run has fallen when the trunk origin is lower than this above the ground.
pub const FALL_MIN_HEIGHT: SizedConstant = SizedConstant {
    name: "fall.min_height_m",
    a1_value: 0.12,
    unit: "m",
    about:
        "a run has fallen with the trunk origin below this height (0.4 of the A1's standing height)",
};

/// A foot carries the robot above this normal force (metrics, touchdowns, the learned tasks'
/// contact terms). The floor's contacts are soft: a swinging foot can touch it with a few
/// newtons, a stance foot of the A1 carries 30–60 N.
pub const LOADED_FOOT: SizedConstant = SizedConstant {
    name: "contact.loaded_foot_n",
    a1_value: 5.0,
    unit: "N",
    about: "a foot counts as carrying the robot above this normal force (4 % of the A1's weight)",
};

/// With no plan (a learned controller), the filter trusts a leg as a stance leg from the
/// vertical force its torques exert: none at this force, fully at [`TRUST_FORCE_FULL`].
pub const TRUST_FORCE_NONE: SizedConstant = SizedConstant {
    name: "filter.trust_force_none_n",
    a1_value: 10.0,
    unit: "N",
    about: "without a plan, a leg pushing down less than this is not a stance leg for the filter",
};

/// See [`TRUST_FORCE_NONE`].
pub const TRUST_FORCE_FULL: SizedConstant = SizedConstant {
    name: "filter.trust_force_full_n",
    a1_value: 30.0,
    unit: "N",
    about: "without a plan, a leg pushing down this much is fully trusted as a stance leg",
};

/// The largest forward (and backward) speed a walk accepts.
pub const MAX_FORWARD_SPEED: SizedConstant = SizedConstant {
    name: "command.max_forward_mps",
    a1_value: 1.5,
    unit: "m/s",
    about: "the largest forward or backward speed a walk accepts",
};

/// The largest sideways speed a walk accepts.
pub const MAX_LATERAL_SPEED: SizedConstant = SizedConstant {
    name: "command.max_lateral_mps",
    a1_value: 0.5,
    unit: "m/s",
    about: "the largest sideways speed a walk accepts",
};

/// The largest yaw rate a walk accepts.
pub const MAX_YAW_RATE: SizedConstant = SizedConstant {
    name: "command.max_yaw_rate_rps",
    a1_value: 1.5,
    unit: "rad/s",
    about: "the largest yaw rate a walk accepts",
};

/// The heaviest payload a walk accepts on the trunk.
pub const MAX_PAYLOAD: SizedConstant = SizedConstant {
    name: "payload.max_kg",
    a1_value: 10.0,
    unit: "kg",
    about: "the heaviest payload a walk accepts (0.8 of the A1's mass)",
};

/// Every size-bound constant, in the order the check report lists them.
pub const SIZED_CONSTANTS: [SizedConstant; 8] = [
    FALL_MIN_HEIGHT,
    LOADED_FOOT,
    TRUST_FORCE_NONE,
    TRUST_FORCE_FULL,
    MAX_FORWARD_SPEED,
    MAX_LATERAL_SPEED,
    MAX_YAW_RATE,
    MAX_PAYLOAD,
];

impl RobotScale {
    /// The A1's value of `c` scaled to this robot by the constant's unit.
    pub fn sized(&self, c: &SizedConstant) -> f64 {
        // Every unit above is a physical one: `factor` knows it.
        c.a1_value * self.factor(c.unit).unwrap_or(1.0)
    }

    /// The walk's command ranges for this robot: forward m/s, lateral m/s, yaw rate rad/s.
    pub fn command_ranges(&self) -> [[f64; 2]; 3] {
        [MAX_FORWARD_SPEED, MAX_LATERAL_SPEED, MAX_YAW_RATE].map(|c| {
            let v = self.sized(&c);
            [-v, v]
        })
    }

    /// The A1's own scale (every factor 1).
    pub const A1: RobotScale = RobotScale {
        length: 1.0,
        mass: 1.0,
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_unit_is_a_physical_one() {
        let s = RobotScale {
            length: 2.0,
            mass: 3.0,
        };
        for c in SIZED_CONSTANTS {
            assert!(s.factor(c.unit).is_some(), "{}: unit {}", c.name, c.unit);
        }
    }

    #[test]
    fn the_a1_keeps_its_values_and_others_scale_by_unit() {
        for c in SIZED_CONSTANTS {
            assert_eq!(RobotScale::A1.sized(&c), c.a1_value, "{}", c.name);
        }
        // λ = 4, μ = 8: lengths × 4, forces × 8, speeds × 2, rates × 1/2, masses × 8.
        let s = RobotScale {
            length: 4.0,
            mass: 8.0,
        };
        assert!((s.sized(&FALL_MIN_HEIGHT) - 0.48).abs() < 1e-12);
        assert!((s.sized(&LOADED_FOOT) - 40.0).abs() < 1e-12);
        assert!((s.sized(&MAX_FORWARD_SPEED) - 3.0).abs() < 1e-12);
        assert!((s.sized(&MAX_YAW_RATE) - 0.75).abs() < 1e-12);
        assert!((s.sized(&MAX_PAYLOAD) - 80.0).abs() < 1e-12);
        assert_eq!(s.command_ranges()[1], [-1.0, 1.0]);
    }
}
