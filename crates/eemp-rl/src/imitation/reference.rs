//! The reference a policy follows: the retargeted cycle played at a rate and with a stride that
//! depend on the commanded speed.
//!
//! Speed mapping: with ρ = v_cmd / v_clip, the cycle plays at rate s_f = clamp(ρ^α, rate range)
//! (cycles per second = s_f / T_cycle) and the feet's fore–aft excursion about their mean in
//! the body frame is scaled by s_l = clamp(ρ / s_f, 0, stride_max), so that s_f · s_l · v_clip =
//! v_cmd while both stay in range. α = 0.5 shares a speed change between cadence and stride as
//! animals roughly do. It stops making sense beyond ρ = rate_max · stride_max (the reference
//! cannot go faster; the tracking term still asks for the command) and at ρ → 0, where the
//! reference steps in place at rate_min. Joint angles of a scaled stride come from the leg IK.

use super::motion::ReferenceMotion;
use super::retarget::leg_ik;
use eemp_core::config_error::{check_range, ConfigError};
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SpeedMapping {
    pub alpha: f64,
    /// Playback rate range (1 = the dog's own cadence).
    pub rate_range: [f64; 2],
    pub stride_max: f64,
}

impl Default for SpeedMapping {
    fn default() -> Self {
        SpeedMapping {
            alpha: 0.5,
            rate_range: [0.5, 1.5],
            stride_max: 1.3,
        }
    }
}

impl SpeedMapping {
    pub fn validate(&self, prefix: &str) -> Result<(), ConfigError> {
        check_range(&format!("{prefix}.alpha"), self.alpha, 0.0, 1.0)?;
        check_range(
            &format!("{prefix}.rate_range[0]"),
            self.rate_range[0],
            0.05,
            5.0,
        )?;
        check_range(
            &format!("{prefix}.rate_range[1]"),
            self.rate_range[1],
            self.rate_range[0],
            5.0,
        )?;
        check_range(&format!("{prefix}.stride_max"), self.stride_max, 0.0, 3.0)
    }
}

/// One frame of the cycle in the root frame.
#[derive(Clone, Debug)]
struct CycleFrame {
    root_height_m: f64,
    roll: f64,
    pitch: f64,
    q: LegMap<Vector3<f64>>,
    p_foot_body: LegMap<Vector3<f64>>,
}

/// The reference at one instant.
#[derive(Clone, Debug, PartialEq)]
pub struct RefSample {
    pub q: LegMap<Vector3<f64>>,
    pub p_foot_body: LegMap<Vector3<f64>>,
    pub root_height_m: f64,
    pub roll: f64,
    pub pitch: f64,
}

impl RefSample {
    /// Root orientation without yaw.
    pub fn r_level_root(&self) -> UnitQuaternion<f64> {
        UnitQuaternion::from_euler_angles(self.roll, self.pitch, 0.0)
    }

    /// Feet relative to the root in the heading frame, z = height above the floor.
    pub fn feet_heading(&self) -> LegMap<Vector3<f64>> {
        let r = self.r_level_root();
        self.p_foot_body
            .map(|_, p| r * p + Vector3::new(0.0, 0.0, self.root_height_m))
    }
}

#[derive(Clone, Debug)]
pub struct ReferenceCycle {
    frames: Vec<CycleFrame>,
    frame_s: f64,
    speed_mps: f64,
    mean_foot_x: LegMap<f64>,
    mapping: SpeedMapping,
}

impl ReferenceCycle {
    pub fn new(motion: &ReferenceMotion, kin: &LegKinematics, mapping: SpeedMapping) -> Self {
        let frames: Vec<CycleFrame> = motion
            .frames
            .iter()
            .map(|f| {
                let (roll, pitch, _) = f.r_world_root.euler_angles();
                CycleFrame {
                    root_height_m: f.p_root_world.z,
                    roll,
                    pitch,
                    q: f.q,
                    p_foot_body: LegMap::from_fn(|leg| kin.foot_position_body(leg, &f.q[leg])),
                }
            })
            .collect();
        let n = frames.len() as f64;
        let mean_foot_x =
            LegMap::from_fn(|leg| frames.iter().map(|f| f.p_foot_body[leg].x).sum::<f64>() / n);
        ReferenceCycle {
            frames,
            frame_s: motion.frame_s,
            speed_mps: motion.speed_mps(),
            mean_foot_x,
            mapping,
        }
    }

    pub fn cycle_s(&self) -> f64 {
        self.frames.len() as f64 * self.frame_s
    }

    /// The clip's own speed, m/s.
    pub fn speed_mps(&self) -> f64 {
        self.speed_mps
    }

    /// (playback rate, stride scale) for a commanded forward speed.
    pub fn scales(&self, v_cmd_mps: f64) -> (f64, f64) {
        let m = &self.mapping;
        let rho = (v_cmd_mps / self.speed_mps).max(0.0);
        let rate = rho.powf(m.alpha).clamp(m.rate_range[0], m.rate_range[1]);
        (rate, (rho / rate).clamp(0.0, m.stride_max))
    }

    /// Phase advance per second (cycles/s) at a commanded speed.
    pub fn phase_rate(&self, v_cmd_mps: f64) -> f64 {
        self.scales(v_cmd_mps).0 / self.cycle_s()
    }

    /// The reference at `phase` ∈ [0, 1) with stride scale `stride`.
    pub fn sample(&self, kin: &LegKinematics, phase: f64, stride: f64) -> RefSample {
        let n = self.frames.len();
        let x = phase.rem_euclid(1.0) * n as f64;
        let k = (x.floor() as usize).min(n - 1);
        let w = x - k as f64;
        let (a, b) = (&self.frames[k], &self.frames[(k + 1) % n]);
        let lerp = |u: f64, v: f64| u + w * (v - u);
        let mut q = LegMap::from_fn(|_| Vector3::zeros());
        let p_foot_body = LegMap::from_fn(|leg: Leg| {
            let mut p = a.p_foot_body[leg].lerp(&b.p_foot_body[leg], w);
            let q_file = a.q[leg].lerp(&b.q[leg], w);
            if (stride - 1.0).abs() > 1e-9 {
                p.x = self.mean_foot_x[leg] + stride * (p.x - self.mean_foot_x[leg]);
                q[leg] = leg_ik(kin, leg, &p, &q_file).0;
                kin.foot_position_body(leg, &q[leg])
            } else {
                q[leg] = q_file;
                kin.foot_position_body(leg, &q_file)
            }
        });
        RefSample {
            q,
            p_foot_body,
            root_height_m: lerp(a.root_height_m, b.root_height_m),
            roll: lerp(a.roll, b.roll),
            pitch: lerp(a.pitch, b.pitch),
        }
    }

    /// Joint velocities and root vertical velocity of the reference at `phase` and speed, by a
    /// one-frame difference.
    pub fn rates(
        &self,
        kin: &LegKinematics,
        phase: f64,
        v_cmd_mps: f64,
    ) -> (LegMap<Vector3<f64>>, f64) {
        let (rate, stride) = self.scales(v_cmd_mps);
        let dphase = 1.0 / self.frames.len() as f64;
        let dt = self.frame_s / rate;
        let a = self.sample(kin, phase, stride);
        let b = self.sample(kin, phase + dphase, stride);
        (
            LegMap::from_fn(|leg| (b.q[leg] - a.q[leg]) / dt),
            (b.root_height_m - a.root_height_m) / dt,
        )
    }
}
