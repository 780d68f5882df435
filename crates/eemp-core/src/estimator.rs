//! State estimation from the robot's own senses (no simulator inside): attitude from the IMU,
//! and a linear Kalman filter for the trunk's position and velocity that fuses the IMU's
//! acceleration with leg kinematics, trusting a leg by where it is in its stance (the structure
//! of MIT Cheetah-Software's `LinearKFPositionVelocityEstimator`, with legged_control's ½dt²
//! position input; values in `../shared/reference/estimation-hardware-notes.md` §1).
//!
//! State (18, world frame): trunk position p, trunk velocity v, the four foot positions.
//! Measurements (28): per leg p − p_foot = −R·p_foot_body (3), v = −R·(ω × p_foot_body + J q̇) (3),
//! and the foot's height = its nominal height on flat ground (1). A leg's velocity and height
//! rows and its foot's process noise are inflated by 1 + 100·(1 − trust): a swinging foot moves,
//! so it neither measures the trunk's velocity nor stays on the ground.

use crate::body_state::{BodyState, LegJointState, RobotState};
use crate::config_error::{check_range, ConfigError};
use crate::kinematics::LegKinematics;
use crate::leg::{Leg, LegMap};
use crate::planner::Plan;
use crate::robot::RobotScale;
use crate::robot_size;
use nalgebra::{SMatrix, SVector, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// What an IMU reports, body frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuReading {
    /// Attitude (rotates body vectors into the world frame).
    pub r_world_body: UnitQuaternion<f64>,
    /// Angular velocity, rad/s.
    pub gyro_body: Vector3<f64>,
    /// Specific force (acceleration minus gravity), m/s²: (0, 0, 9.81) at rest.
    pub accel_body: Vector3<f64>,
}

/// How soon after the legs last agreed with the estimate a group's jump may be taken, and how
/// long after a jump none is, s ([`KfConfig::velocity_jump_dragged_fraction`]): a push's
/// readings part within tens of ms from legs that agreed (the pushed walk's held pair was
/// trusted 31 ms after it), while on a floor where feet slide all the time (the Go1's walk at
/// 0.5 m/s on friction 0.2) the legs scatter for longer and jumps follow one another, and a
/// group of sliding feet was taken for the held ones.
pub const PUSH_WINDOW_S: f64 = 0.06;

/// Time over which a leg's trust ramps from 0 to 1 after it enters stance, s (Cheetah's 0.2
/// of a 0.15–0.25 s stance).
pub const TRUST_RAMP_S: f64 = 0.04;

/// Foot force on the ground implied by a leg's joint torques, assuming the leg is static:
/// τ = −Jᵀ Rᵀ f ⇒ f = −R J⁻ᵀ τ (world frame, N); `None` near a singular leg.
pub fn foot_force_from_torque(
    jacobian_body: &nalgebra::Matrix3<f64>,
    r_world_body: &UnitQuaternion<f64>,
    tau: &Vector3<f64>,
) -> Option<Vector3<f64>> {
    let jt_inv = jacobian_body.transpose().try_inverse()?;
    Some(-(r_world_body * (jt_inv * tau)))
}

/// Each leg's trust as a stance leg, for the filter: from the controller's plan (ramped over
/// [`TRUST_RAMP_S`] after touchdown) or, for a controller without a plan, from the vertical
/// load its last torques imply (10 N → 0, 30 N → 1). Never from a simulator's contact list:
/// the same code runs on the robot.
#[derive(Clone, Debug, PartialEq)]
pub struct ContactTrust {
    /// When each leg entered stance, s.
    stance_since: LegMap<Option<f64>>,
    /// Without a plan: the vertical leg force of no trust and of full trust, N (the robot's,
    /// [`crate::robot_size::TRUST_FORCE_NONE`] and [`crate::robot_size::TRUST_FORCE_FULL`]).
    force_n: [f64; 2],
}

impl ContactTrust {
    /// All legs in stance since `t_s` (episodes start standing), for a robot of size `size`.
    pub fn new(t_s: f64, size: &RobotScale) -> Self {
        ContactTrust {
            stance_since: LegMap::splat(Some(t_s)),
            force_n: [
                size.sized(&robot_size::TRUST_FORCE_NONE),
                size.sized(&robot_size::TRUST_FORCE_FULL),
            ],
        }
    }

    /// `state` needs the sensed joints and attitude only.
    pub fn update(
        &mut self,
        plan: Option<&Plan>,
        kin: &LegKinematics,
        state: &RobotState,
        last_torques: &LegMap<Vector3<f64>>,
    ) -> LegMap<f64> {
        let t = state.time_s;
        match plan {
            Some(plan) => LegMap::from_fn(|leg| {
                if plan.stance[leg] {
                    let since = *self.stance_since[leg].get_or_insert(t);
                    ((t - since) / TRUST_RAMP_S).clamp(0.0, 1.0)
                } else {
                    self.stance_since[leg] = None;
                    0.0
                }
            }),
            None => LegMap::from_fn(|leg| {
                let j = kin.foot_jacobian_body(leg, &state.joints[leg].q);
                foot_force_from_torque(&j, &state.body.r_world_body, &last_torques[leg])
                    .map(|f| {
                        let [none, full] = self.force_n;
                        ((f.z - none) / (full - none)).clamp(0.0, 1.0)
                    })
                    .unwrap_or(0.0)
            }),
        }
    }
}

/// What the estimator reads each step besides the IMU.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EstimatorInput {
    pub time_s: f64,
    pub imu: ImuReading,
    pub joints: LegMap<LegJointState>,
    /// How much each leg is trusted as a stance leg, 0 (swing) … 1 (mid-stance).
    pub contact_trust: LegMap<f64>,
}

/// Noise parameters (standard deviations or their squares as named), Cheetah-Software's values.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct KfConfig {
    pub imu_process_noise_position: f64,
    pub imu_process_noise_velocity: f64,
    pub foot_process_noise_position: f64,
    pub foot_sensor_noise_position: f64,
    pub foot_sensor_noise_velocity: f64,
    pub foot_height_sensor_noise: f64,
    /// Height of a foot centre above flat ground in stance, m (the foot radius).
    pub foot_height_m: f64,
    /// Factor by which an untrusted leg's noise grows (Cheetah's high_suspect_number).
    pub suspect_factor: f64,
    /// A velocity jump the IMU did not sense: when the fully trusted stance legs (two or more)
    /// agree on a trunk velocity at least this far from the estimate, m/s, the velocity's
    /// variance is raised by the squared difference, so the legs take over at once instead of
    /// over the filter's ≈ 50 ms time constant (after a push that moves the whole robot, which
    /// the accelerometer cannot sense). A robot sliding on all its feet reads as a jump too.
    /// 0 turns it off.
    pub velocity_jump_mps: f64,
    /// How closely the legs must agree for a jump: each within this fraction of the jump from
    /// their mean (a single slipping foot disagrees with the others and is left to the filter).
    pub velocity_jump_agreement: f64,
    /// A push's jump that only some legs read. After a push the IMU did not sense, a held foot
    /// reads the trunk's new velocity, and a foot that slides with the trunk reads only part of
    /// the change (it moved with the trunk at first and friction brakes it slowly). Within
    /// [`PUSH_WINDOW_S`] of an update whose planted legs all agreed with the estimate, and not
    /// after a jump, when two or more fully trusted legs agree on a horizontal jump of at least
    /// `velocity_jump_mps` and every other one reads, along it, between this fraction of it and
    /// `1 − velocity_jump_agreement` of it, the group's jump is taken and the others are not
    /// read until they agree with the estimate again or their foot lifts. (Following the mix of
    /// held and dragged feet, the estimate would lag the pushed trunk by a large share of the
    /// push, and the MPC cannot brake a velocity it does not see.) Feet that slip while the
    /// others hold read none of the change, so that case is left to the leg gate. 0 turns it
    /// off.
    pub velocity_jump_dragged_fraction: f64,
    /// A planned stance leg whose velocity reading disagrees by more than this, m/s, both with
    /// the estimate and with every other stance leg (trust ≥ ½) is a foot off the ground or
    /// sliding: its trust fades linearly to 0 at twice this disagreement. (A stance leg's
    /// reading is good to ≈ 0.02 m/s with the A1's encoders; when the trunk tipped over a lone
    /// swing of the free gait, the diagonal foot, planned in stance, rose 2 cm off the ground
    /// and its reading pulled the estimate 0.6 m/s off.) 0 turns it off.
    pub leg_outlier_mps: f64,
}

impl Default for KfConfig {
    fn default() -> Self {
        KfConfig {
            imu_process_noise_position: 0.02,
            imu_process_noise_velocity: 0.02,
            foot_process_noise_position: 0.002,
            foot_sensor_noise_position: 0.001,
            foot_sensor_noise_velocity: 0.1,
            foot_height_sensor_noise: 0.001,
            foot_height_m: 0.02,
            suspect_factor: 100.0,
            velocity_jump_mps: 0.15,
            velocity_jump_agreement: 0.5,
            velocity_jump_dragged_fraction: 0.15,
            leg_outlier_mps: 0.15,
        }
    }
}

impl KfConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        for (name, v) in [
            (
                "kf.imu_process_noise_position",
                self.imu_process_noise_position,
            ),
            (
                "kf.imu_process_noise_velocity",
                self.imu_process_noise_velocity,
            ),
            (
                "kf.foot_process_noise_position",
                self.foot_process_noise_position,
            ),
            (
                "kf.foot_sensor_noise_position",
                self.foot_sensor_noise_position,
            ),
            (
                "kf.foot_sensor_noise_velocity",
                self.foot_sensor_noise_velocity,
            ),
            ("kf.foot_height_sensor_noise", self.foot_height_sensor_noise),
        ] {
            check_range(name, v, 1e-9, 100.0)?;
        }
        check_range("kf.foot_height_m", self.foot_height_m, 0.0, 0.2)?;
        check_range("kf.suspect_factor", self.suspect_factor, 1.0, 1e6)?;
        check_range("kf.velocity_jump_mps", self.velocity_jump_mps, 0.0, 10.0)?;
        check_range(
            "kf.velocity_jump_agreement",
            self.velocity_jump_agreement,
            0.0,
            1.0,
        )?;
        check_range(
            "kf.velocity_jump_dragged_fraction",
            self.velocity_jump_dragged_fraction,
            0.0,
            1.0,
        )?;
        check_range("kf.leg_outlier_mps", self.leg_outlier_mps, 0.0, 10.0)
    }
}

/// Every group of two or more legs (bit `Leg::index`), largest first.
const LEG_GROUPS: [u8; 11] = [
    0b1111, 0b0111, 0b1011, 0b1101, 0b1110, 0b0011, 0b0101, 0b0110, 0b1001, 0b1010, 0b1100,
];

/// A velocity jump the legs read and the IMU did not: the change, and which legs read it (the
/// others are not read in the update that takes it).
struct Jump {
    dv: Vector3<f64>,
    read_by: LegMap<bool>,
}

/// One scalar measurement: x[plus] − x[minus] = y with variance `var`.
#[derive(Clone, Copy, Debug)]
struct Row {
    plus: usize,
    minus: Option<usize>,
    y: f64,
    var: f64,
}

type State = SVector<f64, 18>;
type Cov = SMatrix<f64, 18, 18>;

const GRAVITY: Vector3<f64> = Vector3::new(0.0, 0.0, -9.81);

/// The linear Kalman filter for trunk position and velocity.
#[derive(Clone, Debug)]
pub struct LinearKf {
    config: KfConfig,
    kinematics: LegKinematics,
    x: State,
    p: Cov,
    last_time_s: Option<f64>,
    dragged: DraggedLegs,
}

/// The dragged-leg rule's memory ([`KfConfig::velocity_jump_dragged_fraction`]).
#[derive(Clone, Debug, Default)]
struct DraggedLegs {
    /// Legs found dragged along by a push: not read until they agree with the estimate again
    /// or their foot lifts.
    legs: LegMap<bool>,
    /// The last update whose planted legs all agreed with the estimate, and the last that took a
    /// jump, s: a group's jump is looked for only shortly after the one and not after the other.
    last_calm_s: Option<f64>,
    last_jump_s: Option<f64>,
}

impl DraggedLegs {
    /// Before the jump test at `t_s`: releases the legs that read the estimate again (within
    /// `agree_mps`) or lifted, takes the others out of `trust`, and says whether a group's jump
    /// may be looked for.
    fn before_jump_test(
        &mut self,
        t_s: f64,
        planned: &LegMap<f64>,
        v_legs: &LegMap<Vector3<f64>>,
        v_hat: &Vector3<f64>,
        agree_mps: f64,
        trust: &mut LegMap<f64>,
    ) -> bool {
        let agrees = |leg: Leg| (v_legs[leg] - v_hat).norm() < agree_mps;
        for leg in Leg::ALL {
            if planned[leg] <= 0.0 || agrees(leg) {
                self.legs[leg] = false;
            }
            if self.legs[leg] {
                trust[leg] = 0.0;
            }
        }
        // Calm: every leg the plan has fully in stance reads the estimate (the gate's fading
        // does not count, or a leg reading a push would make the rest look calm).
        if Leg::ALL
            .into_iter()
            .filter(|&l| planned[l] >= 1.0)
            .all(agrees)
        {
            self.last_calm_s = Some(t_s);
        }
        let recent = |at: Option<f64>| at.is_some_and(|at| t_s - at <= PUSH_WINDOW_S);
        recent(self.last_calm_s) && !recent(self.last_jump_s)
    }

    /// A jump was taken at `t_s`: the planned stance legs that did not read it are dragged.
    fn jump_taken(
        &mut self,
        t_s: f64,
        jump: &Jump,
        planned: &LegMap<f64>,
        trust: &mut LegMap<f64>,
    ) {
        self.last_jump_s = Some(t_s);
        for leg in Leg::ALL {
            if !jump.read_by[leg] && planned[leg] > 0.0 {
                trust[leg] = 0.0;
                self.legs[leg] = true;
            }
        }
    }
}

impl LinearKf {
    /// Starts at `p_world` at rest with the feet where the kinematics put them.
    pub fn new(
        config: KfConfig,
        kinematics: LegKinematics,
        start: &RobotState,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        let mut kf = LinearKf {
            config,
            kinematics,
            x: State::zeros(),
            p: Cov::identity() * 100.0,
            last_time_s: None,
            dragged: DraggedLegs::default(),
        };
        kf.reset(start);
        Ok(kf)
    }

    /// Re-initialises from a known state (a start pose).
    pub fn reset(&mut self, s: &RobotState) {
        self.x.fixed_rows_mut::<3>(0).copy_from(&s.body.p_world);
        self.x.fixed_rows_mut::<3>(3).copy_from(&s.body.v_world);
        for leg in Leg::ALL {
            let p = s.body.p_world
                + s.body.r_world_body * self.kinematics.foot_position_body(leg, &s.joints[leg].q);
            self.x
                .fixed_rows_mut::<3>(6 + 3 * leg.index())
                .copy_from(&p);
        }
        self.p = Cov::identity() * 1e-4;
        self.last_time_s = Some(s.time_s);
        self.dragged = DraggedLegs::default();
    }

    pub fn position_world(&self) -> Vector3<f64> {
        self.x.fixed_rows::<3>(0).into()
    }

    pub fn velocity_world(&self) -> Vector3<f64> {
        self.x.fixed_rows::<3>(3).into()
    }

    pub fn foot_world(&self, leg: Leg) -> Vector3<f64> {
        self.x.fixed_rows::<3>(6 + 3 * leg.index()).into()
    }

    /// One predict + update; returns the estimated robot state.
    pub fn update(&mut self, input: &EstimatorInput) -> RobotState {
        let dt = match self.last_time_s {
            Some(t) => (input.time_s - t).clamp(0.0, 0.1),
            None => 0.0,
        };
        self.last_time_s = Some(input.time_s);
        let c = &self.config;
        let r = input.imu.r_world_body;
        let omega_world = r * input.imu.gyro_body;
        // Predict: p += v dt + ½ a dt², v += a dt, feet stay.
        let a_world = r * input.imu.accel_body + GRAVITY;
        let v = self.velocity_world();
        let p_new = self.position_world() + v * dt + a_world * (0.5 * dt * dt);
        self.x.fixed_rows_mut::<3>(0).copy_from(&p_new);
        self.x.fixed_rows_mut::<3>(3).copy_from(&(v + a_world * dt));
        // P ← A P Aᵀ + Q with A = I + dt·(v into p): only the position rows and columns change.
        for i in 0..3 {
            for k in 0..18 {
                let v = self.p[(3 + i, k)];
                self.p[(i, k)] += dt * v;
            }
        }
        for i in 0..3 {
            for k in 0..18 {
                let v = self.p[(k, 3 + i)];
                self.p[(k, i)] += dt * v;
            }
        }
        for i in 0..3 {
            self.p[(i, i)] += dt / 20.0 * c.imu_process_noise_position;
            self.p[(3 + i, 3 + i)] += dt * 9.81 / 20.0 * c.imu_process_noise_velocity;
        }
        let v_legs = self.leg_velocities_world(input, &omega_world);
        // The predicted velocity, which the gate, the jump test and the rows all compare with.
        let v_hat = self.velocity_world();
        let mut trust = self.consistent_trust(&input.contact_trust, &v_legs, &v_hat);
        let after_a_push = self.dragged.before_jump_test(
            input.time_s,
            &input.contact_trust,
            &v_legs,
            &v_hat,
            c.velocity_jump_mps,
            &mut trust,
        );
        for leg in Leg::ALL {
            let suspect = 1.0 + (1.0 - trust[leg].clamp(0.0, 1.0)) * c.suspect_factor;
            for i in 0..3 {
                let k = 6 + 3 * leg.index() + i;
                self.p[(k, k)] += dt * c.foot_process_noise_position * suspect;
            }
        }
        if let Some(jump) = self.unsensed_velocity_jump(&trust, &v_legs, &v_hat, after_a_push) {
            for i in 0..3 {
                self.p[(3 + i, 3 + i)] += jump.dv[i] * jump.dv[i];
            }
            self.dragged
                .jump_taken(input.time_s, &jump, &input.contact_trust, &mut trust);
        }
        let rows = self.measurements(input, &trust, &v_legs, &v_hat);
        self.correct_sequential(&rows);
        RobotState {
            time_s: input.time_s,
            body: BodyState {
                p_world: self.position_world(),
                r_world_body: r,
                v_world: self.velocity_world(),
                omega_world,
            },
            joints: input.joints,
        }
    }

    /// For each leg, the trunk's velocity in the world frame if its foot is still:
    /// v = −(ω × p_rel + R J q̇), once per update (the jump test and the measurement rows both
    /// read it). (The sphere's rolling is left in: in MuJoCo's soft floor contact the A1's feet sink
    /// ≈ 2 cm and taking out a full-radius roll biased the estimate the other way, +0.009
    /// against −0.011 m/s in a 0.3 m/s trot.)
    fn leg_velocities_world(
        &self,
        input: &EstimatorInput,
        omega_world: &Vector3<f64>,
    ) -> LegMap<Vector3<f64>> {
        LegMap::from_fn(|leg| {
            let j = &input.joints[leg];
            -self.kinematics.foot_velocity_relative_world(
                leg,
                &j.q,
                &j.qd,
                &input.imu.r_world_body,
                omega_world,
            )
        })
    }

    /// The plan's trust, faded for a leg that disagrees with both the estimate and every other
    /// stance leg (see [`KfConfig::leg_outlier_mps`]). Legs that agree with each other keep their
    /// trust however far from the estimate they are: that is how an unsensed velocity change
    /// (a push, a landing) reaches the filter.
    fn consistent_trust(
        &self,
        planned: &LegMap<f64>,
        v_legs: &LegMap<Vector3<f64>>,
        v_hat: &Vector3<f64>,
    ) -> LegMap<f64> {
        let gate = self.config.leg_outlier_mps;
        if gate <= 0.0 {
            return *planned;
        }

        LegMap::from_fn(|leg| {
            let trust = planned[leg];
            if trust <= 0.0 {
                return trust;
            }
            if !v_legs[leg].iter().all(|v| v.is_finite()) {
                return 0.0;
            }
            let off_estimate = (v_legs[leg] - v_hat).norm();
            let seconded = Leg::ALL.into_iter().any(|other| {
                other != leg
                    && planned[other] >= 0.5
                    && (v_legs[leg] - v_legs[other]).norm() <= gate
            });
            if seconded {
                trust
            } else {
                trust * ((2.0 * gate - off_estimate) / gate).clamp(0.0, 1.0)
            }
        })
    }

    /// The legs' common velocity minus the estimate, when the fully trusted legs agree on one
    /// far from it (see [`KfConfig::velocity_jump_mps`]), or a group of them does while the
    /// others are dragged along (see [`KfConfig::velocity_jump_dragged_fraction`]).
    fn unsensed_velocity_jump(
        &self,
        trust: &LegMap<f64>,
        v_legs: &LegMap<Vector3<f64>>,
        v_hat: &Vector3<f64>,
        groups_allowed: bool,
    ) -> Option<Jump> {
        let c = &self.config;
        if c.velocity_jump_mps <= 0.0 {
            return None;
        }
        let v_hat = *v_hat;
        let trusted_mask = Leg::ALL
            .into_iter()
            .filter(|&leg| trust[leg] >= 1.0)
            .fold(0u8, |m, leg| m | 1 << leg.index());
        if trusted_mask.count_ones() < 2 {
            return None;
        }
        let in_group = |mask: u8, leg: Leg| mask & (1 << leg.index()) != 0;
        let legs_of = |mask: u8| Leg::ALL.into_iter().filter(move |&l| in_group(mask, l));
        // The group that agrees on a jump: all the trusted legs, else (largest first) a subset
        // of two or more whose jump every other trusted leg read part of.
        let groups_allowed = groups_allowed && c.velocity_jump_dragged_fraction > 0.0;
        let subsets = LEG_GROUPS
            .into_iter()
            .filter(|&mask| groups_allowed && mask & !trusted_mask == 0 && mask != trusted_mask);
        for mask in std::iter::once(trusted_mask).chain(subsets) {
            let whole = mask == trusted_mask;
            // A foot slides over the ground, not into it: a group's jump is horizontal.
            let seen = |v: Vector3<f64>| match whole {
                true => v,
                false => Vector3::new(v.x, v.y, 0.0),
            };
            let members = || legs_of(mask).map(|l| seen(v_legs[l]));
            let mean = members().sum::<Vector3<f64>>() / mask.count_ones() as f64;
            let dv = mean - seen(v_hat);
            let size = dv.norm();
            if size < c.velocity_jump_mps
                || !members().all(|v| (v - mean).norm() <= c.velocity_jump_agreement * size)
            {
                continue;
            }
            if whole {
                return Some(Jump {
                    dv,
                    read_by: LegMap::splat(true),
                });
            }
            let direction = dv / size;
            let dragged = |v: Vector3<f64>| {
                let off = seen(v) - seen(v_hat);
                let along = off.dot(&direction);
                let across = (off - direction * along).norm();
                along >= c.velocity_jump_dragged_fraction * size
                    && along <= (1.0 - c.velocity_jump_agreement) * size
                    && across <= c.velocity_jump_agreement * size
            };
            if legs_of(trusted_mask & !mask).all(|l| dragged(v_legs[l])) {
                return Some(Jump {
                    dv,
                    read_by: LegMap::from_fn(|l| in_group(mask, l)),
                });
            }
        }
        None
    }

    /// The 28 scalar measurements: (state index with +1, state index with −1, value, variance).
    fn measurements(
        &self,
        input: &EstimatorInput,
        trust: &LegMap<f64>,
        v_legs: &LegMap<Vector3<f64>>,
        v_hat: &Vector3<f64>,
    ) -> Vec<Row> {
        let c = &self.config;
        let r = input.imu.r_world_body;
        let mut rows = Vec::with_capacity(28);
        for leg in Leg::ALL {
            let i = leg.index();
            let j = &input.joints[leg];
            let trust = trust[leg].clamp(0.0, 1.0);
            let suspect = 1.0 + (1.0 - trust) * c.suspect_factor;
            let p_rel_world = r * self.kinematics.foot_position_body(leg, &j.q);
            let v_meas = v_legs[leg];
            let foot = 6 + 3 * i;
            for k in 0..3 {
                // p − p_foot = −R p_rel
                rows.push(Row {
                    plus: k,
                    minus: Some(foot + k),
                    y: -p_rel_world[k],
                    var: c.foot_sensor_noise_position,
                });
            }
            for k in 0..3 {
                rows.push(Row {
                    plus: 3 + k,
                    minus: None,
                    // (An untrusted leg's reading is not read at all: it may be NaN.)
                    y: if trust > 0.0 {
                        (1.0 - trust) * v_hat[k] + trust * v_meas[k]
                    } else {
                        v_hat[k]
                    },
                    var: c.foot_sensor_noise_velocity * suspect,
                });
            }
            rows.push(Row {
                plus: foot + 2,
                minus: None,
                y: (1.0 - trust) * self.x[foot + 2] + trust * c.foot_height_m,
                var: c.foot_height_sensor_noise * suspect,
            });
        }
        rows
    }

    /// The measurement update one scalar at a time (R is diagonal, so this equals the batch
    /// update; each row of C has one or two ±1 entries, so each step is O(n²) with no solve).
    fn correct_sequential(&mut self, rows: &[Row]) {
        let mut pc = [0.0f64; 18];
        for row in rows {
            for (k, v) in pc.iter_mut().enumerate() {
                *v = self.p[(k, row.plus)] - row.minus.map_or(0.0, |m| self.p[(k, m)]);
            }
            let s = pc[row.plus] - row.minus.map_or(0.0, |m| pc[m]) + row.var;
            if s.is_nan() || s <= 0.0 {
                continue;
            }
            let predicted = self.x[row.plus] - row.minus.map_or(0.0, |m| self.x[m]);
            let innovation = row.y - predicted;
            for k in 0..18 {
                self.x[k] += pc[k] / s * innovation;
            }
            for a in 0..18 {
                let ka = pc[a] / s;
                for b in 0..18 {
                    self.p[(a, b)] -= ka * pc[b];
                }
            }
        }
        self.p = (self.p + self.p.transpose()) * 0.5;
    }

    /// The textbook batch update (S = C P Cᵀ + R, K = P Cᵀ S⁻¹), the second method the tests
    /// compare the sequential one with.
    #[cfg(test)]
    fn correct_batch(&mut self, rows: &[Row]) {
        let mut cm = SMatrix::<f64, 28, 18>::zeros();
        let mut y = SVector::<f64, 28>::zeros();
        let mut rn = SVector::<f64, 28>::zeros();
        for (i, row) in rows.iter().enumerate() {
            cm[(i, row.plus)] = 1.0;
            if let Some(m) = row.minus {
                cm[(i, m)] = -1.0;
            }
            y[i] = row.y;
            rn[i] = row.var;
        }
        let pct = self.p * cm.transpose();
        let s = cm * pct + SMatrix::<f64, 28, 28>::from_diagonal(&rn);
        let chol = s.cholesky().expect("S is positive definite");
        let innovation = y - cm * self.x;
        let k_gain = chol.solve(&pct.transpose()).transpose();
        self.x += k_gain * innovation;
        self.p = (Cov::identity() - k_gain * cm) * self.p;
        self.p = (self.p + self.p.transpose()) * 0.5;
    }

    /// Whether every state and covariance entry is finite.
    pub fn is_finite(&self) -> bool {
        self.x.iter().all(|v| v.is_finite()) && self.p.iter().all(|v| v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::RobotConfig;

    /// A trunk gliding at constant velocity over four planted feet (legs moving accordingly by
    /// IK): the IMU reads gravity only, the legs read the motion.
    fn gliding(
        v: Vector3<f64>,
        t: f64,
        kin: &LegKinematics,
        feet: &LegMap<Vector3<f64>>,
    ) -> RobotState {
        let p = Vector3::new(0.0, 0.0, 0.28) + v * t;
        let mut joints = LegMap::splat(LegJointState::default());
        for leg in Leg::ALL {
            let q = kin.inverse(leg, &(feet[leg] - p)).unwrap();
            // q̇ from the foot staying put: J q̇ = −v (body frame = world frame here).
            let qd = kin.foot_jacobian_body(leg, &q).try_inverse().unwrap() * (-v);
            joints[leg] = LegJointState { q, qd };
        }
        RobotState {
            time_s: t,
            body: BodyState {
                p_world: p,
                r_world_body: UnitQuaternion::identity(),
                v_world: v,
                omega_world: Vector3::zeros(),
            },
            joints,
        }
    }

    #[test]
    fn tracks_a_trunk_moving_over_planted_feet_from_a_wrong_velocity() {
        let robot = RobotConfig::a1();
        let kin = LegKinematics::new(&robot);
        let v = Vector3::new(0.2, -0.05, 0.0);
        let feet = LegMap::from_fn(|leg| {
            let mut f = kin.nominal_foot_body(leg) + Vector3::new(0.0, 0.0, 0.28);
            f.z = 0.02;
            f
        });
        let mut start = gliding(v, 0.0, &kin, &feet);
        start.body.v_world = Vector3::zeros(); // the filter starts wrong
        let mut kf = LinearKf::new(KfConfig::default(), kin.clone(), &start).unwrap();
        let dt = 0.002;
        let mut est = start;
        for k in 1..=500 {
            let truth = gliding(v, k as f64 * dt, &kin, &feet);
            est = kf.update(&EstimatorInput {
                time_s: truth.time_s,
                imu: ImuReading {
                    r_world_body: UnitQuaternion::identity(),
                    gyro_body: Vector3::zeros(),
                    accel_body: Vector3::new(0.0, 0.0, 9.81),
                },
                joints: truth.joints,
                contact_trust: LegMap::splat(1.0),
            });
        }
        let truth = gliding(v, 1.0, &kin, &feet);
        assert!(
            (est.body.v_world - v).norm() < 1e-3,
            "v {:?}",
            est.body.v_world
        );
        assert!(
            (est.body.p_world - truth.body.p_world).norm() < 0.01,
            "p {:?}",
            est.body.p_world
        );
        assert!(kf.is_finite());
    }

    #[test]
    fn the_sequential_update_equals_the_batch_update() {
        let robot = RobotConfig::a1();
        let kin = LegKinematics::new(&robot);
        let feet = LegMap::from_fn(|leg| {
            let mut f = kin.nominal_foot_body(leg) + Vector3::new(0.03, -0.02, 0.28);
            f.z = 0.02;
            f
        });
        let truth = gliding(Vector3::new(0.3, 0.1, 0.0), 0.0, &kin, &feet);
        let mut a = LinearKf::new(KfConfig::default(), kin.clone(), &truth).unwrap();
        a.p = Cov::from_fn(|i, j| {
            if i == j {
                0.01 + 0.001 * i as f64
            } else {
                1e-4 / (1.0 + (i + j) as f64)
            }
        });
        a.x[3] = 0.1;
        let mut b = a.clone();
        let input = EstimatorInput {
            time_s: 0.002,
            imu: ImuReading {
                r_world_body: UnitQuaternion::from_euler_angles(0.05, -0.03, 0.4),
                gyro_body: Vector3::new(0.2, -0.1, 0.3),
                accel_body: Vector3::new(0.3, 0.1, 9.7),
            },
            joints: truth.joints,
            contact_trust: LegMap::from_fn(|leg| [1.0, 0.3, 0.0, 0.8][leg.index()]),
        };
        let omega = input.imu.r_world_body * input.imu.gyro_body;
        let rows = a.measurements(
            &input,
            &input.contact_trust,
            &a.leg_velocities_world(&input, &omega),
            &a.velocity_world(),
        );
        assert_eq!(rows.len(), 28);
        a.correct_sequential(&rows);
        b.correct_batch(&rows);
        assert!((a.x - b.x).amax() < 1e-9, "{}", (a.x - b.x).amax());
        assert!((a.p - b.p).amax() < 1e-9, "{}", (a.p - b.p).amax());
    }

    #[test]
    fn an_untrusted_leg_does_not_pull_the_velocity() {
        // All legs in swing: the velocity comes from the IMU alone (here: unchanged).
        let robot = RobotConfig::a1();
        let kin = LegKinematics::new(&robot);
        let feet = LegMap::from_fn(|leg| {
            let mut f = kin.nominal_foot_body(leg) + Vector3::new(0.0, 0.0, 0.28);
            f.z = 0.02;
            f
        });
        let start = gliding(Vector3::new(0.3, 0.0, 0.0), 0.0, &kin, &feet);
        let mut kf = LinearKf::new(KfConfig::default(), kin.clone(), &start).unwrap();
        // Legs report a standing trunk, but nobody trusts them.
        let still = gliding(Vector3::zeros(), 0.0, &kin, &feet);
        for k in 1..=50 {
            kf.update(&EstimatorInput {
                time_s: k as f64 * 0.002,
                imu: ImuReading {
                    r_world_body: UnitQuaternion::identity(),
                    gyro_body: Vector3::zeros(),
                    accel_body: Vector3::new(0.0, 0.0, 9.81),
                },
                joints: still.joints,
                contact_trust: LegMap::splat(0.0),
            });
        }
        assert!(
            (kf.velocity_world().x - 0.3).abs() < 0.02,
            "{:?}",
            kf.velocity_world()
        );
    }

    /// The filter on a gliding trunk whose velocity jumps from `v0` to `v1` at step 100 (the
    /// legs read it, the IMU does not); `slipping` moves only the FR leg's reading. Returns the
    /// velocity estimate `steps_after` steps of 2 ms after the jump.
    fn after_a_jump(
        config: KfConfig,
        v0: Vector3<f64>,
        v1: Vector3<f64>,
        slipping: bool,
        steps_after: usize,
    ) -> Vector3<f64> {
        after_a_jump_on(config, v0, v1, slipping, steps_after, LegMap::splat(1.0))
    }

    /// [`after_a_jump`] with the plan's trust per leg (a trot's stance pair: two legs at 1).
    fn after_a_jump_on(
        config: KfConfig,
        v0: Vector3<f64>,
        v1: Vector3<f64>,
        slipping: bool,
        steps_after: usize,
        contact_trust: LegMap<f64>,
    ) -> Vector3<f64> {
        let read = LegMap::from_fn(|leg| match slipping {
            true if leg != Leg::FrontRight => 0.0,
            _ => 1.0,
        });
        after_a_jump_read(
            config,
            v0,
            v1,
            LegMap::splat(0.0),
            read,
            steps_after,
            contact_trust,
        )
    }

    /// The general case: each leg reads `v0 + before[leg] · (v1 − v0)` before the jump and
    /// `v0 + read[leg] · (v1 − v0)` after it (1: its foot holds and reads the whole jump; 0: it
    /// reads none of it).
    fn after_a_jump_read(
        config: KfConfig,
        v0: Vector3<f64>,
        v1: Vector3<f64>,
        before: LegMap<f64>,
        read: LegMap<f64>,
        steps_after: usize,
        contact_trust: LegMap<f64>,
    ) -> Vector3<f64> {
        let robot = RobotConfig::a1();
        let kin = LegKinematics::new(&robot);
        let feet = LegMap::from_fn(|leg| {
            let mut f = kin.nominal_foot_body(leg) + Vector3::new(0.0, 0.0, 0.28);
            f.z = 0.02;
            f
        });
        let start = gliding(v0, 0.0, &kin, &feet);
        let mut kf = LinearKf::new(config, kin.clone(), &start).unwrap();
        let dt = 0.002;
        for k in 1..=100 + steps_after {
            let t = k as f64 * dt;
            let v = |share: f64| v0 + (v1 - v0) * share;
            let joints = LegMap::from_fn(|leg| {
                let vb = v(before[leg]);
                if k <= 100 {
                    return gliding(vb, t, &kin, &feet).joints[leg];
                }
                // The trunk goes on from where the leg saw it: p0 + v_b·t_j + v_a·(t − t_j).
                let (t_j, va) = (100.0 * dt, v(read[leg]));
                let feet_seen = feet.map(|_, f| f - (vb - va) * t_j);
                gliding(va, t, &kin, &feet_seen).joints[leg]
            });
            kf.update(&EstimatorInput {
                time_s: t,
                imu: ImuReading {
                    r_world_body: UnitQuaternion::identity(),
                    gyro_body: Vector3::zeros(),
                    accel_body: Vector3::new(0.0, 0.0, 9.81),
                },
                joints,
                contact_trust,
            });
        }
        assert!(kf.is_finite());
        kf.velocity_world()
    }

    #[test]
    fn a_velocity_jump_the_legs_agree_on_is_taken_at_once() {
        let (v0, v1) = (Vector3::new(0.3, 0.0, 0.0), Vector3::new(0.3, 0.5, 0.0));
        let on = KfConfig::default();
        let off = KfConfig {
            velocity_jump_mps: 0.0,
            ..KfConfig::default()
        };
        let with = after_a_jump(on.clone(), v0, v1, false, 10);
        let without = after_a_jump(off.clone(), v0, v1, false, 10);
        // Without the jump test the filter's ≈ 50 ms time constant leaves most of the jump.
        assert!((with - v1).norm() < 0.02, "with {with:?}");
        assert!((without - v1).norm() > 0.1, "without {without:?}");
        // One foot slipping (1 m/s) disagrees with the other three: their mean moves by
        // 0.25 m/s, beyond the threshold, but there is no jump: the filter as without the test.
        // (With the leg-outlier gate off, which would fade that foot out before the test.)
        let ungated = |c: &KfConfig| KfConfig {
            leg_outlier_mps: 0.0,
            ..c.clone()
        };
        let v_slip = Vector3::new(0.3, 1.0, 0.0);
        let slip = after_a_jump(ungated(&on), v0, v_slip, true, 10);
        let slip_off = after_a_jump(ungated(&off), v0, v_slip, true, 10);
        assert!((slip - slip_off).norm() < 1e-12, "{slip:?} vs {slip_off:?}");
        assert!((slip - v0).norm() < 0.25, "{slip:?}");
        // A jump below the threshold is left to the filter too.
        let small = Vector3::new(0.3, 0.1, 0.0);
        let a = after_a_jump(on, v0, small, false, 10);
        let b = after_a_jump(off, v0, small, false, 10);
        assert!((a - b).norm() < 1e-12);
    }

    #[test]
    fn a_leg_that_disagrees_with_the_estimate_and_the_other_legs_is_faded_out() {
        let v0 = Vector3::new(0.3, 0.0, 0.0);
        let no_jump = KfConfig {
            velocity_jump_mps: 0.0,
            ..KfConfig::default()
        };
        let no_gate = KfConfig {
            leg_outlier_mps: 0.0,
            ..no_jump.clone()
        };
        // FR's foot slides at 0.5 m/s sideways for 0.1 s: faded out, it leaves the estimate
        // within 1 cm/s; trusted, it pulls it by up to a quarter (its share of four legs).
        let v_slip = Vector3::new(0.3, 0.5, 0.0);
        let gated = after_a_jump(no_jump.clone(), v0, v_slip, true, 50);
        let pulled = after_a_jump(no_gate.clone(), v0, v_slip, true, 50);
        assert!((gated - v0).norm() < 0.01, "gated {gated:?}");
        assert!((pulled - v0).norm() > 0.05, "pulled {pulled:?}");
        // All four legs agree on the new velocity: the gate changes nothing (here without the
        // jump test, the filter takes it at its own pace).
        let v1 = Vector3::new(0.3, 0.5, 0.0);
        let taken = after_a_jump(no_jump, v0, v1, false, 100);
        let ungated = after_a_jump(no_gate, v0, v1, false, 100);
        assert_eq!(taken, ungated);
        assert!((taken - v1).norm() < 0.05, "taken {taken:?}");
    }

    #[test]
    fn of_a_trots_two_stance_feet_the_sliding_one_does_not_drag_the_estimate() {
        // The hardest case for the gate: only the diagonal pair FR + RL in stance, FR's foot
        // sliding 0.4 m/s forward and sideways for 0.2 s (ice under one foot), RL planted. The
        // two legs disagree, so neither seconds the other; the planted one agrees with the
        // estimate and keeps its trust, the sliding one is faded out.
        let v0 = Vector3::new(0.3, 0.0, 0.0);
        let v_slip = Vector3::new(0.6, 0.3, 0.0);
        let pair = LegMap::from_fn(|l| match l {
            Leg::FrontRight | Leg::RearLeft => 1.0,
            _ => 0.0,
        });
        let on = KfConfig::default();
        let gate_off = KfConfig {
            leg_outlier_mps: 0.0,
            ..KfConfig::default()
        };
        let gated = after_a_jump_on(on, v0, v_slip, true, 100, pair);
        let dragged = after_a_jump_on(gate_off, v0, v_slip, true, 100, pair);
        assert!((gated - v0).norm() < 0.02, "gated {gated:?}");
        assert!((dragged - v0).norm() > 0.1, "dragged {dragged:?}");
    }

    #[test]
    fn after_a_push_the_held_feet_are_read_and_the_dragged_ones_are_not() {
        // All four feet down when a push the IMU did not sense moves the trunk 0.45 m/s
        // sideways: the two left feet hold and read it, the two right ones slide with the trunk
        // and read 30 % of it (the pushed walk on the 0.3 floor).
        let (v0, v1) = (Vector3::new(0.1, 0.0, 0.0), Vector3::new(0.1, 0.45, 0.0));
        let on = KfConfig::default();
        let off = KfConfig {
            velocity_jump_dragged_fraction: 0.0,
            ..KfConfig::default()
        };
        let stance = LegMap::splat(1.0);
        let left_held = LegMap::from_fn(|l| if l.side_sign() > 0.0 { 1.0 } else { 0.3 });
        let calm = LegMap::splat(0.0);
        let with = after_a_jump_read(on.clone(), v0, v1, calm, left_held, 10, stance);
        let without = after_a_jump_read(off.clone(), v0, v1, calm, left_held, 10, stance);
        assert!((with - v1).norm() < 0.03, "with {with:?}");
        assert!((without - v1).norm() > 0.1, "without {without:?}");
        // Two feet slipping while the other two hold: the held ones read none of the change, so
        // it is no push and the rule stays out of it (the filter as without it).
        let right_slip = LegMap::from_fn(|l| if l.side_sign() > 0.0 { 0.0 } else { 1.0 });
        let a = after_a_jump_read(on.clone(), v0, v1, calm, right_slip, 10, stance);
        let b = after_a_jump_read(off.clone(), v0, v1, calm, right_slip, 10, stance);
        assert_eq!(a, b);
        // Feet that read more of the change than the group are not dragged ones either.
        let beyond = LegMap::from_fn(|l| if l.side_sign() > 0.0 { 1.0 } else { 1.8 });
        let a = after_a_jump_read(on.clone(), v0, v1, calm, beyond, 10, stance);
        let b = after_a_jump_read(off.clone(), v0, v1, calm, beyond, 10, stance);
        assert_eq!(a, b);
        // Legs that already disagreed (feet sliding all the time: for 0.2 s the right pair
        // reads 0.36 m/s below the left): a split like a push's afterwards is not taken for one.
        let scattered = LegMap::from_fn(|l| if l.side_sign() > 0.0 { 0.0 } else { -0.8 });
        let split = LegMap::from_fn(|l| if l.side_sign() > 0.0 { 1.0 } else { -0.1 });
        let a = after_a_jump_read(on, v0, v1, scattered, split, 10, stance);
        let b = after_a_jump_read(off, v0, v1, scattered, split, 10, stance);
        assert_eq!(a, b);
    }
}
