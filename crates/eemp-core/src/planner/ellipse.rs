//! Eq. (5): the placement set of a foot is an ellipse centred under its hip.

use nalgebra::Vector2;

/// (p_ell^dx / r_x)² + (p_ell^dy / r_y)²: below 1 inside the ellipse, above 1 outside.
/// `p_ell` is the foot position relative to the ellipse centre (heading frame, m).
pub fn ellipse_value(p_ell: &Vector2<f64>, r_x: f64, r_y: f64) -> f64 {
    (p_ell.x / r_x).powi(2) + (p_ell.y / r_y).powi(2)
}

/// Eq. (5): true when a foot in contact has left its ellipse (strictly outside; on the boundary
/// counts as inside).
pub fn outside_ellipse(p_ell: &Vector2<f64>, r_x: f64, r_y: f64) -> bool {
    ellipse_value(p_ell, r_x, r_y) > 1.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boundary_cases() {
        let (rx, ry) = (0.07, 0.05);
        assert!(!outside_ellipse(&Vector2::zeros(), rx, ry));
        // On the axes' ends: exactly 1, inside.
        assert!(!outside_ellipse(&Vector2::new(0.07, 0.0), rx, ry));
        assert!(!outside_ellipse(&Vector2::new(0.0, -0.05), rx, ry));
        assert!(outside_ellipse(&Vector2::new(0.0701, 0.0), rx, ry));
        assert!(outside_ellipse(&Vector2::new(0.0, 0.0501), rx, ry));
        // On the boundary at 45° in normalised coordinates: (rx/√2, ry/√2) → 1.
        let s = std::f64::consts::FRAC_1_SQRT_2;
        assert!((ellipse_value(&Vector2::new(rx * s, ry * s), rx, ry) - 1.0).abs() < 1e-12);
        // Within r_x along x but beyond it diagonally.
        assert!(outside_ellipse(&Vector2::new(0.06, 0.03), rx, ry));
        // 0.06²/0.07² + 0.03²/0.05² = 0.7347 + 0.36 = 1.0947.
        assert!(
            (ellipse_value(&Vector2::new(0.06, 0.03), rx, ry) - 1.094_693_877_551_020_4).abs()
                < 1e-12
        );
    }
}
