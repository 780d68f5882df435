//! Condensed QP of the MPC: the states are eliminated, the forces U = (u₀ … u_{N−1}) remain.
//!
//! Cost Σₖ₌₁ᴺ ‖xₖ − rₖ‖²_Q + Σₗ ‖uₗ‖²_R with xₖ = Aᵏx₀ + Σₗ₍ₗ<ₖ₎ Aᵏ⁻¹⁻ˡ Bₗ uₗ gives
//! J = UᵀHU + 2gᵀU + const. A is constant over the horizon (yaw frozen), so for j ≥ l
//!   H_jl = B_jᵀ W_{N−1−j} A^{j−l} B_l,   W₀ = Q, W_n = Q + Aᵀ W_{n−1} A,
//!   g_l = B_lᵀ λ_l,   λ_{N−1} = Q e_N, λ_l = Q e_{l+1} + Aᵀ λ_{l+1},   e_k = Aᵏx₀ − r_k.
//! This costs O(N²·NX²·NU) instead of the O(N³·NX·NU²) of forming Bqpᵀ Q̄ Bqp; the test below
//! checks it against that naive product.

use super::model::{InputMatrix, StateMatrix, StateVector, NU, NX};
use nalgebra::{DMatrix, DVector, SMatrix};

/// Fills `h` (N·NU square, full symmetric) and `g` (N·NU) for the given model and references.
/// `q_diag` are the state weights, `r_diag` the force weights (per force component).
#[allow(clippy::too_many_arguments)] // model, references, weights and two outputs: all needed, none related
pub fn condense(
    a: &StateMatrix,
    b: &[InputMatrix],
    x0: &StateVector,
    reference: &[StateVector],
    q_diag: &StateVector,
    r_diag: f64,
    h: &mut DMatrix<f64>,
    g: &mut DVector<f64>,
) {
    let n = b.len();
    assert_eq!(reference.len(), n, "one reference per horizon step");
    assert_eq!(h.nrows(), n * NU);
    assert_eq!(g.len(), n * NU);
    let q = StateMatrix::from_diagonal(q_diag);
    let at = a.transpose();

    // W_n for n = 0..N−1.
    let mut w = Vec::with_capacity(n);
    w.push(q);
    for i in 1..n {
        let next = q + at * w[i - 1] * a;
        w.push(next);
    }
    // C_j = B_jᵀ W_{N−1−j}.
    let c: Vec<SMatrix<f64, NU, NX>> = (0..n).map(|j| b[j].transpose() * w[n - 1 - j]).collect();

    // Column l: T = A^{j−l} B_l for j = l..N−1.
    for l in 0..n {
        let mut t = b[l];
        for j in l..n {
            if j > l {
                t = a * t;
            }
            let block = c[j] * t;
            h.fixed_view_mut::<NU, NU>(j * NU, l * NU).copy_from(&block);
            if j != l {
                h.fixed_view_mut::<NU, NU>(l * NU, j * NU)
                    .copy_from(&block.transpose());
            }
        }
    }
    for i in 0..n * NU {
        h[(i, i)] += r_diag;
    }

    // Free response errors and the backward recursion for the gradient.
    let mut e = Vec::with_capacity(n);
    let mut x = *x0;
    for r in reference {
        x = a * x;
        e.push(x - r);
    }
    let mut lambda = q * e[n - 1];
    for l in (0..n).rev() {
        if l < n - 1 {
            lambda = q * e[l] + at * lambda;
        }
        g.fixed_rows_mut::<NU>(l * NU)
            .copy_from(&(b[l].transpose() * lambda));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::convex_mpc::model::{input_matrix, state_matrix, GRAVITY};
    use approx::assert_relative_eq;
    use nalgebra::{Matrix3, Vector3};

    /// The textbook condensation: X = Aqp x₀ + Bqp U, H = Bqpᵀ Q̄ Bqp + R̄, g = Bqpᵀ Q̄ (Aqp x₀ − Y).
    fn naive(
        a: &StateMatrix,
        b: &[InputMatrix],
        x0: &StateVector,
        reference: &[StateVector],
        q_diag: &StateVector,
        r: f64,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let n = b.len();
        let mut bqp = DMatrix::zeros(n * NX, n * NU);
        let mut aqp_x0 = DVector::zeros(n * NX);
        for k in 1..=n {
            let mut ak = StateMatrix::identity();
            for _ in 0..k {
                ak = a * ak;
            }
            aqp_x0
                .fixed_rows_mut::<NX>((k - 1) * NX)
                .copy_from(&(ak * x0));
            for l in 0..k {
                let mut p = StateMatrix::identity();
                for _ in 0..(k - 1 - l) {
                    p = a * p;
                }
                bqp.view_mut(((k - 1) * NX, l * NU), (NX, NU))
                    .copy_from(&(p * b[l]));
            }
        }
        let mut qbar = DMatrix::zeros(n * NX, n * NX);
        let mut y = DVector::zeros(n * NX);
        for k in 0..n {
            for i in 0..NX {
                qbar[(k * NX + i, k * NX + i)] = q_diag[i];
            }
            y.fixed_rows_mut::<NX>(k * NX).copy_from(&reference[k]);
        }
        let h = bqp.transpose() * &qbar * &bqp + DMatrix::identity(n * NU, n * NU) * r;
        let g = bqp.transpose() * &qbar * (aqp_x0 - y);
        (h, g)
    }

    #[test]
    fn structured_condensation_equals_the_naive_product() {
        let n = 7;
        let a = state_matrix(0.4, 0.03);
        let inertia = Matrix3::new(0.1, 0.01, 0.0, 0.01, 0.3, 0.02, 0.0, 0.02, 0.35);
        let b: Vec<InputMatrix> = (0..n)
            .map(|k| {
                let s = k as f64 * 0.01;
                input_matrix(
                    0.4,
                    0.03,
                    12.0,
                    &inertia,
                    &[
                        Vector3::new(0.2 + s, -0.13, -0.3),
                        Vector3::new(0.2, 0.13 - s, -0.3),
                        Vector3::new(-0.2, -0.13, -0.3 + s),
                        Vector3::new(-0.2 - s, 0.13, -0.3),
                    ],
                )
            })
            .collect();
        let mut x0 = StateVector::from_fn(|i, _| (i as f64 * 0.37).sin() * 0.1);
        x0[12] = GRAVITY;
        let reference: Vec<StateVector> = (0..n)
            .map(|k| StateVector::from_fn(|i, _| ((i + k) as f64 * 0.11).cos() * 0.05))
            .collect();
        let q_diag = StateVector::from_fn(|i, _| 1.0 + i as f64);
        let mut h = DMatrix::zeros(n * NU, n * NU);
        let mut g = DVector::zeros(n * NU);
        condense(&a, &b, &x0, &reference, &q_diag, 1e-4, &mut h, &mut g);
        let (h_ref, g_ref) = naive(&a, &b, &x0, &reference, &q_diag, 1e-4);
        assert_relative_eq!(h, h_ref, epsilon = 1e-12, max_relative = 1e-9);
        assert_relative_eq!(g, g_ref, epsilon = 1e-12, max_relative = 1e-9);
    }
}
