//! Eq. (6): where the swing foot lands relative to the ellipse centre (Raibert heuristic).

use crate::convex_mpc::model::GRAVITY;
use nalgebra::Vector2;

/// p_prog = V_des·ΔT·factor + √(X_z/g)·(V_cur − V_des), all in the heading frame (m, m/s).
///
/// The paper's eq. (6) uses factor = ½ (half the distance the body covers during the swing, so
/// the foot lands ahead of the hip by as much as it will be behind it at lift-off); its
/// Algorithm 1 writes V_des·ΔT (factor = 1). `factor` is [`super::PlannerConfig::progress_factor`],
/// ½ by default.
pub fn progress(
    v_des: &Vector2<f64>,
    v_cur: &Vector2<f64>,
    swing_time_s: f64,
    body_height_m: f64,
    factor: f64,
) -> Vector2<f64> {
    v_des * (swing_time_s * factor) + (v_cur - v_des) * (body_height_m / GRAVITY).sqrt()
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
        );
        assert!((p.x - 0.080_276_5).abs() < 1e-6, "{p:?}");
        assert!((p.y + 0.005_276_5).abs() < 1e-6, "{p:?}");
        // Algorithm 1's reading (factor 1) adds another V_des·ΔT/2.
        let q = progress(
            &Vector2::new(0.5, 0.1),
            &Vector2::new(0.6, 0.0),
            0.25,
            0.31,
            1.0,
        );
        assert!((q - p - Vector2::new(0.0625, 0.0125)).norm() < 1e-12);
        // Tracking the command exactly: only the feed-forward term remains.
        let r = progress(
            &Vector2::new(0.3, 0.0),
            &Vector2::new(0.3, 0.0),
            0.2,
            0.3,
            0.5,
        );
        assert!((r - Vector2::new(0.03, 0.0)).norm() < 1e-15);
    }
}
