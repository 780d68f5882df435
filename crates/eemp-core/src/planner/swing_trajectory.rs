//! Eq. (7): the sinusoidal swing from lift-off to touchdown.

use crate::leg_control::FootReference;
use nalgebra::{Vector2, Vector3};
use std::f64::consts::PI;

/// A swing that starts at `start_body` and moves the foot by `displacement_xy` in ΔT, lifting it
/// to `step_height_m` halfway (m). The frame is the caller's: the planner uses the world frame
/// (see [`super::EemPlanner`]), so `start_body` is then a world position.
///
/// x/y follow ā(ΔT/π)²(1 − cos(πt/ΔT)) and z follows ā_z(ΔT/2π)²(1 − cos(2πt/ΔT)), so position,
/// velocity and acceleration are given in closed form. The paper's ā_x uses (p_ell + p_prog);
/// the foot must travel from p_cur to the ellipse centre plus p_prog, a displacement of
/// p_prog − p_ell with p_ell = p_cur − p_hip, which is what callers pass here.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SwingTrajectory {
    pub start_body: Vector3<f64>,
    pub displacement_xy: Vector2<f64>,
    pub step_height_m: f64,
    pub duration_s: f64,
}

impl SwingTrajectory {
    /// Maximum accelerations ā_x, ā_y (x/y) and ā_z of eq. (7), m/s².
    pub fn peak_accelerations(&self) -> Vector3<f64> {
        let w = PI / self.duration_s;
        let axy = self.displacement_xy * 0.5 * w * w;
        let wz = 2.0 * PI / self.duration_s;
        Vector3::new(axy.x, axy.y, self.step_height_m * 0.5 * wz * wz)
    }

    /// Reference at `t` s after lift-off (clamped to [0, ΔT]).
    pub fn sample(&self, t: f64) -> FootReference {
        let t = t.clamp(0.0, self.duration_s);
        let a = self.peak_accelerations();
        let w = PI / self.duration_s;
        let wz = 2.0 * w;
        let (s, c) = (w * t).sin_cos();
        let (sz, cz) = (wz * t).sin_cos();
        let offset = Vector3::new(
            a.x / (w * w) * (1.0 - c),
            a.y / (w * w) * (1.0 - c),
            a.z / (wz * wz) * (1.0 - cz),
        );
        FootReference {
            p_body: self.start_body + offset,
            v_body: Vector3::new(a.x / w * s, a.y / w * s, a.z / wz * sz),
            a_body: Vector3::new(a.x * c, a.y * c, a.z * cz),
        }
    }

    /// Touchdown point (body frame).
    pub fn end_body(&self) -> Vector3<f64> {
        self.start_body + Vector3::new(self.displacement_xy.x, self.displacement_xy.y, 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn traj() -> SwingTrajectory {
        SwingTrajectory {
            start_body: Vector3::new(-0.05, 0.13, -0.29),
            displacement_xy: Vector2::new(0.12, -0.02),
            step_height_m: 0.1,
            duration_s: 0.25,
        }
    }

    #[test]
    fn endpoints_apex_and_rest() {
        let tr = traj();
        let start = tr.sample(0.0);
        let end = tr.sample(tr.duration_s);
        assert!((start.p_body - tr.start_body).norm() < 1e-15);
        assert!((end.p_body - tr.end_body()).norm() < 1e-12);
        // At rest at both ends.
        assert!(start.v_body.norm() < 1e-12 && end.v_body.norm() < 1e-12);
        // Apex: z offset h at ΔT/2, halfway in x/y.
        let mid = tr.sample(tr.duration_s / 2.0);
        assert!((mid.p_body.z - (tr.start_body.z + 0.1)).abs() < 1e-12);
        assert!((mid.p_body.x - (tr.start_body.x + 0.06)).abs() < 1e-12);
        // Peak accelerations by hand: ā_z = h·½·(2π/ΔT)² = 0.1·0.5·(8π)² = 31.583…
        let a = tr.peak_accelerations();
        assert!((a.z - 0.05 * (8.0 * PI).powi(2)).abs() < 1e-9);
        assert!((a.x - 0.12 * 0.5 * (4.0 * PI).powi(2)).abs() < 1e-9);
    }

    #[test]
    fn velocity_and_acceleration_are_derivatives_of_position() {
        let tr = traj();
        let h = 1e-6;
        for i in 1..50 {
            let t = tr.duration_s * i as f64 / 50.0;
            let (a, b, m) = (tr.sample(t - h), tr.sample(t + h), tr.sample(t));
            let v_fd = (b.p_body - a.p_body) / (2.0 * h);
            let a_fd = (b.v_body - a.v_body) / (2.0 * h);
            assert!(
                (v_fd - m.v_body).norm() < 1e-6,
                "t {t}: v {:?} fd {:?}",
                m.v_body,
                v_fd
            );
            assert!(
                (a_fd - m.a_body).norm() < 1e-4,
                "t {t}: a {:?} fd {:?}",
                m.a_body,
                a_fd
            );
        }
    }

    #[test]
    fn continuous_everywhere() {
        let tr = traj();
        let mut prev = tr.sample(0.0).p_body;
        for i in 1..=1000 {
            let p = tr.sample(tr.duration_s * i as f64 / 1000.0).p_body;
            assert!((p - prev).norm() < 1e-3);
            prev = p;
        }
    }
}
