//! The robot's left–right mirror (issue 21): the plane y = 0 of the body frame maps the robot
//! onto itself with the right and left legs exchanged. Only this mirror: the A1's knees bend
//! backwards at the front and at the rear, so front and rear are not mirror images.
//!
//! Under the mirror S = diag(1, −1, 1): a position or linear velocity v ↦ S v; an orientation
//! R ↦ S R S (quaternion (w, x, y, z) ↦ (w, −x, y, −z)); an angular velocity (a pseudovector)
//! ω ↦ −S ω; a leg's joints go to the partner leg with the hip's abduction angle negated (every
//! hip axis is +x, so the same angle moves a right foot inwards and a left foot outwards) and the
//! thigh and knee unchanged. A policy is symmetric when π(M_o o) = M_a π(o); the PPO update can
//! add ‖π(M_o o) − M_a π(o)‖² as a loss (`ppo.symmetry_coef`, rsl_rl's mirror loss).

use eemp_core::body_state::{BodyState, RobotState};
use eemp_core::leg::Leg;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// A signed permutation of a vector: `out[i] = sign[i] · x[source[i]]`, an involution.
#[derive(Clone, Debug, PartialEq)]
pub struct MirrorMap {
    source: Vec<usize>,
    sign: Vec<f32>,
}

impl MirrorMap {
    /// Checks that the map is a signed permutation that undoes itself (mirroring twice is the
    /// identity), so a wrong map fails here rather than in training.
    pub fn new(source: Vec<usize>, sign: Vec<f32>) -> Result<Self, String> {
        if source.len() != sign.len() {
            return Err(format!(
                "mirror map: {} sources but {} signs",
                source.len(),
                sign.len()
            ));
        }
        let n = source.len();
        for (i, (&j, &s)) in source.iter().zip(&sign).enumerate() {
            if j >= n {
                return Err(format!("mirror map: entry {i} reads {j}, outside 0..{n}"));
            }
            if s != 1.0 && s != -1.0 {
                return Err(format!("mirror map: entry {i} has sign {s}, not ±1"));
            }
            if source[j] != i || sign[j] != s {
                return Err(format!(
                    "mirror map: entry {i} ↦ {j} is not undone by entry {j} (mirroring twice must be the identity)"
                ));
            }
        }
        Ok(MirrorMap { source, sign })
    }

    pub fn len(&self) -> usize {
        self.source.len()
    }

    pub fn is_empty(&self) -> bool {
        self.source.is_empty()
    }

    pub fn source(&self) -> &[usize] {
        &self.source
    }

    pub fn sign(&self) -> &[f32] {
        &self.sign
    }

    /// Mirrors every row of `x` (rows of [`MirrorMap::len`] values).
    pub fn apply_rows(&self, x: &[f32]) -> Vec<f32> {
        let n = self.len();
        let mut out = vec![0f32; x.len()];
        for (row_in, row_out) in x.chunks(n).zip(out.chunks_mut(n)) {
            for i in 0..n {
                row_out[i] = self.sign[i] * row_in[self.source[i]];
            }
        }
        out
    }

    /// Refuses a map of the wrong size for `width` values (e.g. a policy's observation).
    pub fn check_width(&self, width: usize, what: &str) -> Result<(), String> {
        if self.len() != width {
            return Err(format!(
                "mirror map of {} values for {what} of {width} values",
                self.len()
            ));
        }
        Ok(())
    }
}

/// Builds a [`MirrorMap`] block by block, in the order a vector is laid out.
#[derive(Default)]
pub struct MirrorBuilder {
    source: Vec<usize>,
    sign: Vec<f32>,
}

/// Signs of a vector's (x, y, z) under the mirror.
pub const POLAR: [f32; 3] = [1.0, -1.0, 1.0];
/// Signs of an angular velocity's (x, y, z) under the mirror.
pub const AXIAL: [f32; 3] = [-1.0, 1.0, -1.0];
/// Signs of a leg's (hip abduction, thigh, knee) under the mirror.
pub const JOINTS: [f32; 3] = [-1.0, 1.0, 1.0];

impl MirrorBuilder {
    pub fn new() -> Self {
        Self::default()
    }

    /// A scalar that keeps (+1) or flips (−1) its sign.
    pub fn scalar(mut self, sign: f32) -> Self {
        self.source.push(self.source.len());
        self.sign.push(sign);
        self
    }

    /// A 3-vector with these signs.
    pub fn vector(mut self, signs: [f32; 3]) -> Self {
        let base = self.source.len();
        for (k, s) in signs.into_iter().enumerate() {
            self.source.push(base + k);
            self.sign.push(s);
        }
        self
    }

    /// Three values per leg in actuator order ([`Leg::ALL`]), taken from the partner leg with
    /// these signs: [`JOINTS`] for joint angles, rates, torques and actions, [`POLAR`] for a
    /// foot's position.
    pub fn per_leg(mut self, signs: [f32; 3]) -> Self {
        let base = self.source.len();
        for leg in Leg::ALL {
            for (k, s) in signs.into_iter().enumerate() {
                self.source.push(base + 3 * leg.mirror().index() + k);
                self.sign.push(s);
            }
        }
        self
    }

    /// `count` copies of the block `block` builds.
    pub fn repeat(mut self, count: usize, block: impl Fn(MirrorBuilder) -> MirrorBuilder) -> Self {
        for _ in 0..count {
            let b = block(MirrorBuilder::new());
            let base = self.source.len();
            self.source.extend(b.source.iter().map(|j| base + j));
            self.sign.extend(b.sign);
        }
        self
    }

    pub fn build(self) -> MirrorMap {
        MirrorMap::new(self.source, self.sign).expect("blocks are signed involutions")
    }
}

fn polar(v: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(v.x, -v.y, v.z)
}

/// The mirrored robot state (the test of a map: observing it equals mirroring the observation).
pub fn mirror_state(s: &RobotState) -> RobotState {
    let q = s.body.r_world_body.quaternion();
    RobotState {
        time_s: s.time_s,
        body: BodyState {
            p_world: polar(&s.body.p_world),
            r_world_body: UnitQuaternion::new_normalize(Quaternion::new(q.w, -q.i, q.j, -q.k)),
            v_world: polar(&s.body.v_world),
            omega_world: -polar(&s.body.omega_world),
        },
        joints: eemp_core::leg::LegMap::from_fn(|leg| {
            let j = s.joints[leg.mirror()];
            let m = |v: Vector3<f64>| Vector3::new(-v.x, v.y, v.z);
            eemp_core::body_state::LegJointState {
                q: m(j.q),
                qd: m(j.qd),
            }
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_map_that_is_not_its_own_inverse_is_refused_with_the_entry() {
        let e = MirrorMap::new(vec![1, 2, 0], vec![1.0; 3]).unwrap_err();
        assert!(e.contains("entry 0"), "{e}");
        let e = MirrorMap::new(vec![1, 0], vec![1.0, -1.0]).unwrap_err();
        assert!(e.contains("not undone"), "{e}");
        let e = MirrorMap::new(vec![0, 1], vec![1.0]).unwrap_err();
        assert!(e.contains("2 sources but 1 signs"), "{e}");
        let m = MirrorBuilder::new().per_leg(JOINTS).build();
        assert!(m.check_width(13, "the observation").is_err());
    }

    #[test]
    fn joint_block_swaps_right_and_left_and_negates_the_hips() {
        let m = MirrorBuilder::new().per_leg(JOINTS).build();
        let x: Vec<f32> = (0..12).map(|i| i as f32 + 1.0).collect();
        let y = m.apply_rows(&x);
        // FR ← −FL hip, FL thigh, FL knee; FL ← FR; RR ← RL; RL ← RR.
        assert_eq!(
            y,
            vec![-4.0, 5.0, 6.0, -1.0, 2.0, 3.0, -10.0, 11.0, 12.0, -7.0, 8.0, 9.0]
        );
        assert_eq!(m.apply_rows(&y), x);
    }

    #[test]
    fn mirroring_a_state_twice_gives_it_back() {
        let s = RobotState {
            time_s: 0.3,
            body: BodyState {
                p_world: Vector3::new(0.1, 0.2, 0.3),
                r_world_body: UnitQuaternion::from_euler_angles(0.1, -0.2, 0.7),
                v_world: Vector3::new(0.4, -0.1, 0.05),
                omega_world: Vector3::new(0.3, 0.2, -0.5),
            },
            joints: eemp_core::leg::LegMap::from_fn(|leg| eemp_core::body_state::LegJointState {
                q: Vector3::new(0.1, 0.8, -1.7) * (1.0 + leg.index() as f64),
                qd: Vector3::new(1.0, -2.0, 3.0) * leg.index() as f64,
            }),
        };
        let m = mirror_state(&s);
        // Roll and yaw flip, pitch stays.
        let (r, p, y) = m.body.r_world_body.euler_angles();
        assert!((r + 0.1).abs() < 1e-12 && (p + 0.2).abs() < 1e-12 && (y + 0.7).abs() < 1e-12);
        let back = mirror_state(&m);
        assert!((back.body.r_world_body.angle_to(&s.body.r_world_body)).abs() < 1e-12);
        assert_eq!(back.joints, s.joints);
        assert_eq!(back.body.v_world, s.body.v_world);
    }
}
