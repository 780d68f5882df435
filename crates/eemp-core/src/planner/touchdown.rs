//! Eq. (6): where the swing foot lands relative to the ellipse centre (Raibert heuristic).

use crate::convex_mpc::model::GRAVITY;
use nalgebra::Vector2;

/// p_prog = V_des·ΔT·factor + √(X_z/g)·(V_cur − V_des), all in the heading frame (m, m/s).
///
/// The paper's eq. (6) uses factor = ½ (half the distance the body covers during the swing, so
/// the foot lands ahead of the hip by as much as it will be behind it at lift-off); its
/// Algorithm 1 writes V_des·ΔT (factor = 1). `factor` is [`super::PlannerConfig::progress_factor`],
/// ½ by default.
///
/// The feedback term √(X_z/g)·(V_cur − V_des) is shortened to at most `feedback_limit_m` (m;
/// `f64::INFINITY`: the paper's eq. (6) as printed). The planner sets that limit from the
/// friction coefficient ([`super::PlannerConfig::touchdown_friction_factor`]): a foot placed
/// d from under the hip can only brake the trunk with a leg force leaning d / X_z, which a floor
/// of friction μ gives only while d ≤ μ·X_z.
pub fn progress(
    v_des: &Vector2<f64>,
    v_cur: &Vector2<f64>,
    swing_time_s: f64,
    body_height_m: f64,
    factor: f64,
    feedback_limit_m: f64,
) -> Vector2<f64> {
    let feedback = feedback(v_des, v_cur, body_height_m);
    let norm = feedback.norm();
    let feedback = if norm > feedback_limit_m {
        feedback * (feedback_limit_m / norm)
    } else {
        feedback
    };
    v_des * (swing_time_s * factor) + feedback
}

/// Eq. (6)'s feedback term √(X_z/g)·(V_cur − V_des) (heading frame, m): the capture point of the
/// velocity error of a linear inverted pendulum X_z high, relative to the trunk.
pub fn feedback(v_des: &Vector2<f64>, v_cur: &Vector2<f64>, body_height_m: f64) -> Vector2<f64> {
    (v_cur - v_des) * (body_height_m / GRAVITY).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_worked_values() {
        // V_des = (0.5, 0.1), V_cur = (0.6, 0.0), ΔT = 0.25, X_z = 0.31, factor ½:
        // k = √(0.31/9.81) = 0.177765…; x: 0.5·0.125 + 0.1·k = 0.0625 + 0.0177765 = 0.0802765;
        // y: 0.1·0.125 − 0.1·k = 0.0125 − 0.0177765 = −0.0052765.
        let k = (0.31f64 / 9.81).sqrt();
        assert!((k - 0.177_765_3).abs() < 1e-6);
        let p = progress(
            &Vector2::new(0.5, 0.1),
            &Vector2::new(0.6, 0.0),
            0.25,
            0.31,
            0.5,
            f64::INFINITY,
        );
        assert!((p.x - 0.080_276_5).abs() < 1e-6, "{p:?}");
        assert!((p.y + 0.005_276_5).abs() < 1e-6, "{p:?}");
        // Its feedback term alone (the capture point of the velocity error): (0.1, −0.1)·k.
        let f = feedback(&Vector2::new(0.5, 0.1), &Vector2::new(0.6, 0.0), 0.31);
        assert!(
            (f - Vector2::new(0.1 * k, -0.1 * k)).norm() < 1e-12,
            "{f:?}"
        );
        // Algorithm 1's reading (factor 1) adds another V_des·ΔT/2.
        let q = progress(
            &Vector2::new(0.5, 0.1),
            &Vector2::new(0.6, 0.0),
            0.25,
            0.31,
            1.0,
            f64::INFINITY,
        );
        assert!((q - p - Vector2::new(0.0625, 0.0125)).norm() < 1e-12);
        // Tracking the command exactly: only the feed-forward term remains.
        let r = progress(
            &Vector2::new(0.3, 0.0),
            &Vector2::new(0.3, 0.0),
            0.2,
            0.3,
            0.5,
            f64::INFINITY,
        );
        assert!((r - Vector2::new(0.03, 0.0)).norm() < 1e-15);
    }

    #[test]
    fn the_feedback_term_is_shortened_to_its_limit_and_keeps_its_direction() {
        // V_des = (0.1, 0), V_cur = (0.1, 0.5) (a side push), X_z = 0.28, ΔT = 0.25, factor ½:
        // feed-forward (0.0125, 0); feedback (0, 0.5·√(0.28/9.81)) = (0, 0.0844717…).
        let v_des = Vector2::new(0.1, 0.0);
        let v_cur = Vector2::new(0.1, 0.5);
        let free = progress(&v_des, &v_cur, 0.25, 0.28, 0.5, f64::INFINITY);
        assert!(
            (free - Vector2::new(0.0125, 0.084_471_7)).norm() < 1e-6,
            "{free:?}"
        );
        // A limit of 0.5·μ·X_z at μ = 0.3: 0.042 m, along the same direction.
        let limited = progress(&v_des, &v_cur, 0.25, 0.28, 0.5, 0.5 * 0.3 * 0.28);
        assert!(
            (limited - Vector2::new(0.0125, 0.042)).norm() < 1e-12,
            "{limited:?}"
        );
        // A diagonal error keeps its direction: (0.3, 0.4)·k shortened to 0.02 m is (0.012, 0.016).
        let diag = progress(
            &Vector2::zeros(),
            &Vector2::new(0.3, 0.4),
            0.25,
            0.28,
            0.5,
            0.02,
        );
        assert!(
            (diag - Vector2::new(0.012, 0.016)).norm() < 1e-12,
            "{diag:?}"
        );
        // Under the limit nothing changes.
        assert_eq!(
            progress(&v_des, &v_cur, 0.25, 0.28, 0.5, 0.1),
            progress(&v_des, &v_cur, 0.25, 0.28, 0.5, f64::INFINITY)
        );
    }
}
