//! One three-hinge leg at zero joint angles: its anchors, axis signs and knee branch, and
//! its closed-form forward kinematics, Jacobian and inverse kinematics in the body frame. The
//! robot description holds one per leg; `kinematics::LegKinematics` walks them in named frames
//! (this module knows nothing of the robot, so both can use it).

use crate::leg::Leg;
use nalgebra::Vector3;

/// Why a leg cannot be described as a [`LegGeometry`].
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LegGeometryError {
    #[error("{what} of leg {leg:?} is {value:?}: {why}")]
    Invalid {
        leg: Leg,
        what: &'static str,
        value: Vec<f64>,
        why: &'static str,
    },
}

/// One leg at zero joint angles, in the body frame.
///
/// With θⱼ = sⱼ qⱼ (sⱼ = ±1 the axis signs) the foot is
/// p(q) = h + Rx(θ₀) (a + Ry(θ₁) k + Ry(θ₁ + θ₂) f): h the abduction anchor, a the thigh anchor
/// relative to it, k the knee anchor relative to the thigh anchor, f the foot point relative to
/// the knee (thigh and knee axes are parallel, so the shank turns by θ₁ + θ₂).
#[derive(Clone, Debug, PartialEq)]
pub struct LegGeometry {
    /// Abduction joint anchor h, body frame, m.
    pub abduction_anchor_m: Vector3<f64>,
    /// Thigh joint anchor relative to the abduction anchor, a, m.
    pub thigh_from_abduction_m: Vector3<f64>,
    /// Knee joint anchor relative to the thigh anchor, k, m.
    pub knee_from_thigh_m: Vector3<f64>,
    /// Foot point relative to the knee anchor, f, m.
    pub foot_from_knee_m: Vector3<f64>,
    /// Axis signs: the abduction turns about sₒ·x, thigh and knee about s₁·y and s₂·y.
    pub axis_sign: [f64; 3],
    /// The knee's branch: the side the shank bends to at the standing pose, the sign of
    /// sin(θ₂ + ψ(f) − ψ(k)) (−1 for a Unitree leg, whose knee sits behind the foot's line).
    pub knee_branch: f64,
    /// Thigh and shank lengths in the leg plane (|k| and |f| without their y parts), m.
    pub(crate) thigh_length_m: f64,
    pub(crate) shank_length_m: f64,
    /// ψ(f) − ψ(k): the shank's angle against the thigh at a zero knee angle, rad
    /// (ψ(v) = atan2(−vₓ, −v_z), the angle from straight down).
    pub(crate) knee_offset_rad: f64,
}

/// ψ(v): a vector's angle in the leg plane measured from straight down, positive towards −x
/// (the direction a positive rotation about y turns a downward vector).
pub(crate) fn plane_angle(v: &Vector3<f64>) -> f64 {
    (-v.x).atan2(-v.z)
}

impl LegGeometry {
    /// A leg from its anchors and axis signs, its knee branch from the standing pose `home`;
    /// refused (naming what) where the leg has no length in its plane, an axis sign is not ±1
    /// or the standing knee is straight (which way it bends is then unknown).
    pub fn new(
        leg: Leg,
        abduction_anchor_m: Vector3<f64>,
        thigh_from_abduction_m: Vector3<f64>,
        knee_from_thigh_m: Vector3<f64>,
        foot_from_knee_m: Vector3<f64>,
        axis_sign: [f64; 3],
        home: &Vector3<f64>,
    ) -> Result<Self, LegGeometryError> {
        let invalid = |what, value: Vec<f64>, why| LegGeometryError::Invalid {
            leg,
            what,
            value,
            why,
        };
        for v in [
            abduction_anchor_m,
            thigh_from_abduction_m,
            knee_from_thigh_m,
            foot_from_knee_m,
        ] {
            if v.iter().any(|c| !c.is_finite()) {
                return Err(invalid("an anchor", v.as_slice().to_vec(), "not finite"));
            }
        }
        if axis_sign.iter().any(|s| s.abs() != 1.0) {
            return Err(invalid(
                "axis_sign",
                axis_sign.to_vec(),
                "each must be +1 or −1",
            ));
        }
        let plane_length = |v: &Vector3<f64>| (v.x * v.x + v.z * v.z).sqrt();
        let (l1, l2) = (
            plane_length(&knee_from_thigh_m),
            plane_length(&foot_from_knee_m),
        );
        if l1 < 1e-3 || l2 < 1e-3 {
            return Err(invalid(
                "thigh and shank lengths in the leg plane",
                vec![l1, l2],
                "each must be at least 1 mm",
            ));
        }
        let knee_offset_rad = plane_angle(&foot_from_knee_m) - plane_angle(&knee_from_thigh_m);
        let bend = (axis_sign[2] * home[2] + knee_offset_rad).sin();
        if bend.is_nan() || bend.abs() <= 1e-3 {
            return Err(invalid(
                "the standing pose's knee",
                home.as_slice().to_vec(),
                "is straight (or not finite): which way the knee bends is unknown",
            ));
        }
        Ok(LegGeometry {
            knee_offset_rad,
            knee_branch: bend.signum(),
            abduction_anchor_m,
            thigh_from_abduction_m,
            knee_from_thigh_m,
            foot_from_knee_m,
            axis_sign,
            thigh_length_m: l1,
            shank_length_m: l2,
        })
    }

    /// A Unitree leg (the hand-typed robot files): abduction anchor at (±x, ±y, 0), the thigh
    /// joint `abduction_to_thigh` to the side, knee and foot straight below, axes +x, +y, +y,
    /// knee behind.
    pub fn unitree(
        leg: Leg,
        hip_offset_m: [f64; 2],
        abduction_to_thigh_m: f64,
        thigh_length_m: f64,
        calf_length_m: f64,
    ) -> Self {
        LegGeometry {
            abduction_anchor_m: Vector3::new(
                leg.front_sign() * hip_offset_m[0],
                leg.side_sign() * hip_offset_m[1],
                0.0,
            ),
            thigh_from_abduction_m: Vector3::new(0.0, leg.side_sign() * abduction_to_thigh_m, 0.0),
            knee_from_thigh_m: Vector3::new(0.0, 0.0, -thigh_length_m),
            foot_from_knee_m: Vector3::new(0.0, 0.0, -calf_length_m),
            axis_sign: [1.0; 3],
            knee_branch: -1.0,
            thigh_length_m,
            shank_length_m: calf_length_m,
            knee_offset_rad: 0.0,
        }
    }

    /// The foot's constant offset along the thigh axis from the abduction anchor, m.
    pub fn lateral_m(&self) -> f64 {
        self.thigh_from_abduction_m.y + self.knee_from_thigh_m.y + self.foot_from_knee_m.y
    }

    /// Thigh and shank lengths in the leg plane, m.
    pub fn segment_lengths_m(&self) -> [f64; 2] {
        [self.thigh_length_m, self.shank_length_m]
    }

    /// Effective rotation angles θⱼ = sⱼ qⱼ.
    pub(crate) fn theta(&self, q: &Vector3<f64>) -> [f64; 3] {
        [
            self.axis_sign[0] * q[0],
            self.axis_sign[1] * q[1],
            self.axis_sign[2] * q[2],
        ]
    }
}

/// Ry(θ) v.
pub(crate) fn rot_y(s: f64, c: f64, v: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(c * v.x + s * v.z, v.y, -s * v.x + c * v.z)
}

/// ∂(Ry(θ) v)/∂θ, without its y part (zero).
pub(crate) fn rot_y_derivative(s: f64, c: f64, v: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(-s * v.x + c * v.z, 0.0, -c * v.x - s * v.z)
}
