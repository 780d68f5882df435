//! Single-rigid-body model of Di Carlo et al. (2018), linearised about the current yaw.
//!
//! State (13): [Θ (roll, pitch, yaw), p (world), ω (world), v (world), g]; the constant g state
//! carries gravity into an affine model without an offset term. Continuous dynamics:
//! Θ̇ = Rz(ψ)ᵀω, ṗ = v, ω̇ = I_w⁻¹ Σ rᵢ × fᵢ, v̇ = Σ fᵢ/m − g·ẑ, with I_w = Rz I_b Rzᵀ and
//! rᵢ the foot position relative to the COM. Discretised with forward Euler at the MPC step.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

pub const NX: usize = 13;
pub const NU: usize = 12;
pub type StateVector = SVector<f64, NX>;
pub type StateMatrix = SMatrix<f64, NX, NX>;
pub type InputMatrix = SMatrix<f64, NX, NU>;

/// Gravity, m/s².
pub const GRAVITY: f64 = 9.81;

fn rot_z(yaw: f64) -> Matrix3<f64> {
    let (s, c) = yaw.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

fn skew(r: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -r.z, r.y, r.z, 0.0, -r.x, -r.y, r.x, 0.0)
}

/// Discrete A = I + A_c·dt for the yaw `yaw`.
pub fn state_matrix(yaw: f64, dt: f64) -> StateMatrix {
    let mut a = StateMatrix::identity();
    let rz_t = rot_z(yaw).transpose();
    a.fixed_view_mut::<3, 3>(0, 6).copy_from(&(rz_t * dt));
    a.fixed_view_mut::<3, 3>(3, 9)
        .copy_from(&(Matrix3::identity() * dt));
    a[(11, 12)] = -dt;
    a
}

/// Discrete B = B_c·dt for feet at `r_com_to_foot_world` (4 vectors, COM → foot, world frame).
pub fn input_matrix(
    yaw: f64,
    dt: f64,
    mass_kg: f64,
    inertia_body: &Matrix3<f64>,
    r_com_to_foot_world: &[Vector3<f64>; 4],
) -> InputMatrix {
    let rz = rot_z(yaw);
    let inertia_world = rz * inertia_body * rz.transpose();
    let inv_i = inertia_world
        .try_inverse()
        .expect("inertia is positive definite");
    let mut b = InputMatrix::zeros();
    for (i, r) in r_com_to_foot_world.iter().enumerate() {
        b.fixed_view_mut::<3, 3>(6, 3 * i)
            .copy_from(&(inv_i * skew(r) * dt));
        b.fixed_view_mut::<3, 3>(9, 3 * i)
            .copy_from(&(Matrix3::identity() * (dt / mass_kg)));
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn weight_support_keeps_a_resting_body_at_rest() {
        let m = 12.0;
        let r = [
            Vector3::new(0.2, 0.1, -0.3),
            Vector3::new(0.2, -0.1, -0.3),
            Vector3::new(-0.2, 0.1, -0.3),
            Vector3::new(-0.2, -0.1, -0.3),
        ];
        let a = state_matrix(0.3, 0.02);
        let b = input_matrix(
            0.3,
            0.02,
            m,
            &Matrix3::from_diagonal(&Vector3::new(0.1, 0.2, 0.25)),
            &r,
        );
        let mut x = StateVector::zeros();
        x[5] = 0.3;
        x[12] = GRAVITY;
        let mut u = SVector::<f64, NU>::zeros();
        for i in 0..4 {
            u[3 * i + 2] = m * GRAVITY / 4.0;
        }
        let x1 = a * x + b * u;
        assert_relative_eq!(x1, x, epsilon = 1e-12);
    }

    #[test]
    fn a_vertical_force_at_a_lever_arm_pitches_the_body() {
        // Force up under the front (x > 0): nose-up torque = rotation about −y.
        let r = [
            Vector3::new(0.2, 0.0, -0.3),
            Vector3::zeros(),
            Vector3::zeros(),
            Vector3::zeros(),
        ];
        let inertia = Matrix3::from_diagonal(&Vector3::new(0.1, 0.2, 0.25));
        let b = input_matrix(0.0, 0.01, 10.0, &inertia, &r);
        let mut u = SVector::<f64, NU>::zeros();
        u[2] = 10.0;
        let dx = b * u;
        // τ = r × f = (0.2,0,−0.3) × (0,0,10) = (0, −2, 0); ω̇_y = −2/0.2 = −10 → Δω_y = −0.1.
        assert_relative_eq!(dx[7], -0.1, epsilon = 1e-12);
        assert_relative_eq!(dx[11], 0.01, epsilon = 1e-12);
    }
}
