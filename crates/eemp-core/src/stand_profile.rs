//! Standing: rise from the ground, then move the trunk on four stance legs along a profile.

use crate::body_reference::BodyReference;
use crate::body_state::RobotState;
use crate::config_error::{check_range, ConfigError};
use crate::leg::LegMap;
use crate::planner::Plan;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Which trunk coordinate a segment moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Axis {
    X,
    Y,
    Z,
    Roll,
    Pitch,
    Yaw,
}

/// One sinusoidal excursion: offset(t) = amplitude · sin(2π t / period) for `cycles` periods.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionSegment {
    pub axis: Axis,
    /// m for x/y/z, rad for roll/pitch/yaw.
    pub amplitude: f64,
    pub period_s: f64,
    #[serde(default = "one")]
    pub cycles: u32,
}

fn one() -> u32 {
    1
}

/// A standing profile: rise to `height_m` in `rise_s`, then the segments one after another,
/// then hold. Offsets are relative to the pose after rising.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodyMotionProfile {
    /// Standing height of the trunk origin above the ground, m.
    pub height_m: f64,
    /// Time to rise from the start height to `height_m`, s.
    pub rise_s: f64,
    pub segments: Vec<MotionSegment>,
}

impl Default for BodyMotionProfile {
    /// The issue's 20 s test: rise in 2 s, then ±3 cm x/y/z and ±0.15 rad roll/pitch/yaw,
    /// one axis at a time, 3 s each.
    fn default() -> Self {
        let seg = |axis, amplitude| MotionSegment {
            axis,
            amplitude,
            period_s: 3.0,
            cycles: 1,
        };
        BodyMotionProfile {
            height_m: 0.30,
            rise_s: 2.0,
            segments: vec![
                seg(Axis::X, 0.03),
                seg(Axis::Y, 0.03),
                seg(Axis::Z, 0.03),
                seg(Axis::Roll, 0.15),
                seg(Axis::Pitch, 0.15),
                seg(Axis::Yaw, 0.15),
            ],
        }
    }
}

impl BodyMotionProfile {
    /// This profile on a robot of `scale`: heights and translations × λ, times × √λ (equal
    /// Froude number, [`crate::robot::RobotScale`]).
    pub fn scaled(&self, scale: &crate::robot::RobotScale) -> Self {
        let (l, t) = (scale.length, scale.length.sqrt());
        BodyMotionProfile {
            height_m: self.height_m * l,
            rise_s: self.rise_s * t,
            segments: self
                .segments
                .iter()
                .map(|s| MotionSegment {
                    amplitude: match s.axis {
                        Axis::X | Axis::Y | Axis::Z => s.amplitude * l,
                        Axis::Roll | Axis::Pitch | Axis::Yaw => s.amplitude,
                    },
                    period_s: s.period_s * t,
                    ..s.clone()
                })
                .collect(),
        }
    }

    pub fn validate(&self) -> Result<(), ConfigError> {
        // Any robot's plausible height; the robot's own reach is checked where it is known
        // (`RobotConfig::check_body_height`). Translations at most a fifth of the height
        // (the A1's 6 cm at 0.30 m), so the bound grows with the robot.
        let [lo, hi] = crate::planner::params::BODY_HEIGHT_LIMITS_M;
        check_range("profile.height_m", self.height_m, lo, hi)?;
        check_range("profile.rise_s", self.rise_s, 0.1, 10.0)?;
        for (i, s) in self.segments.iter().enumerate() {
            let max = match s.axis {
                Axis::X | Axis::Y | Axis::Z => 0.2 * self.height_m,
                Axis::Roll | Axis::Pitch | Axis::Yaw => 0.4,
            };
            check_range(
                &format!("profile.segments[{i}].amplitude"),
                s.amplitude,
                -max,
                max,
            )?;
            check_range(
                &format!("profile.segments[{i}].period_s"),
                s.period_s,
                0.5,
                60.0,
            )?;
        }
        Ok(())
    }

    /// Seconds from the start until the last segment ends.
    pub fn duration_s(&self) -> f64 {
        self.rise_s
            + self
                .segments
                .iter()
                .map(|s| s.period_s * s.cycles as f64)
                .sum::<f64>()
    }

    /// Offset (pose, velocity) from the standing pose at time `t` (s since start): 6 values each
    /// in the order x, y, z, roll, pitch, yaw.
    fn offset(&self, t: f64) -> ([f64; 6], [f64; 6]) {
        let mut pos = [0.0; 6];
        let mut vel = [0.0; 6];
        let mut start = self.rise_s;
        for s in &self.segments {
            let len = s.period_s * s.cycles as f64;
            if t >= start && t < start + len {
                let w = 2.0 * PI / s.period_s;
                let i = s.axis as usize;
                pos[i] = s.amplitude * (w * (t - start)).sin();
                vel[i] = s.amplitude * w * (w * (t - start)).cos();
                break;
            }
            start += len;
        }
        (pos, vel)
    }
}

/// Turns a [`BodyMotionProfile`] into plans with all four feet in stance.
#[derive(Clone, Debug)]
pub struct StandPlanner {
    profile: BodyMotionProfile,
    origin_xy: [f64; 2],
    start_height_m: f64,
    horizon: usize,
    dt_s: f64,
}

impl StandPlanner {
    /// `start` is the state at t = 0 (robot resting on the ground).
    pub fn new(
        profile: BodyMotionProfile,
        start: &RobotState,
        horizon: usize,
        dt_s: f64,
    ) -> Result<Self, ConfigError> {
        profile.validate()?;
        Ok(StandPlanner {
            profile,
            origin_xy: [start.body.p_world.x, start.body.p_world.y],
            start_height_m: start.body.p_world.z,
            horizon,
            dt_s,
        })
    }

    pub fn profile(&self) -> &BodyMotionProfile {
        &self.profile
    }

    /// The reference at time `t` (s since start).
    pub fn reference_at(&self, t: f64) -> BodyReference {
        let p = &self.profile;
        // Rise: z follows a half cosine from the start height to the standing height.
        let (z, vz) = if t < p.rise_s {
            let s = 0.5 * (1.0 - (PI * t / p.rise_s).cos());
            let ds = 0.5 * PI / p.rise_s * (PI * t / p.rise_s).sin();
            (
                self.start_height_m + (p.height_m - self.start_height_m) * s,
                (p.height_m - self.start_height_m) * ds,
            )
        } else {
            (p.height_m, 0.0)
        };
        let (o, v) = p.offset(t);
        BodyReference {
            rpy: Vector3::new(o[3], o[4], o[5]),
            p_world: Vector3::new(self.origin_xy[0] + o[0], self.origin_xy[1] + o[1], z + o[2]),
            // Small angles: ω ≈ (roll rate, pitch rate, yaw rate); one axis moves at a time.
            omega_world: Vector3::new(v[3], v[4], v[5]),
            v_world: Vector3::new(v[0], v[1], vz + v[2]),
        }
    }

    /// The plan at time `t`: all feet in stance where they are.
    pub fn plan(&self, t: f64, feet_world: &LegMap<Vector3<f64>>) -> Plan {
        let n = self.horizon;
        Plan {
            stance: LegMap::splat(true),
            swing: LegMap::splat(None),
            body_now: self.reference_at(t),
            body_horizon: (1..=n)
                .map(|k| self.reference_at(t + k as f64 * self.dt_s))
                .collect(),
            feet_horizon_world: vec![*feet_world; n],
            contacts_horizon: vec![LegMap::splat(true); n],
            params: None,
            geometry: None,
            speed_cap_mps: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_profile_lasts_twenty_seconds_and_stays_in_the_issue_bounds() {
        let p = BodyMotionProfile::default();
        assert!((p.duration_s() - 20.0).abs() < 1e-12);
        p.validate().unwrap();
        let mut max = [0.0f64; 6];
        for i in 0..20000 {
            let (o, _) = p.offset(i as f64 * 1e-3);
            for j in 0..6 {
                max[j] = max[j].max(o[j].abs());
            }
        }
        for j in 0..3 {
            assert!((max[j] - 0.03).abs() < 1e-4, "axis {j}: {}", max[j]);
            assert!(
                (max[3 + j] - 0.15).abs() < 1e-3,
                "axis {}: {}",
                3 + j,
                max[3 + j]
            );
        }
    }

    #[test]
    fn velocities_are_derivatives_of_positions() {
        let p = BodyMotionProfile::default();
        let h = 1e-6;
        for t in [2.3, 5.9, 9.1, 12.5, 15.2, 18.7] {
            let (a, _) = p.offset(t - h);
            let (b, _) = p.offset(t + h);
            let (_, v) = p.offset(t);
            for j in 0..6 {
                assert!(((b[j] - a[j]) / (2.0 * h) - v[j]).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn out_of_range_amplitude_is_rejected_with_its_name() {
        let mut p = BodyMotionProfile::default();
        p.segments[2].amplitude = 0.2;
        let err = p.validate().unwrap_err().to_string();
        assert!(err.contains("profile.segments[2].amplitude"), "{err}");
    }
}
