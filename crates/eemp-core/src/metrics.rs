//! Energy and robustness measures: cost of transport (eq. 8), force manipulability (eq. 9),
//! velocity tracking.

use crate::convex_mpc::model::GRAVITY;
use crate::energy::{ElectricalMetrics, EnergyAccount, MotorModel};
use crate::leg::{Leg, LegMap};
use nalgebra::{Matrix3, Vector3};

/// Eq. (8)'s summand: positive mechanical power of all joints, max(q̇ᵀτ, 0), W. Power the motors
/// absorb (negative work) is not credited back, as in the paper.
pub fn positive_power_w(qd: &LegMap<Vector3<f64>>, tau: &LegMap<Vector3<f64>>) -> f64 {
    Leg::ALL
        .iter()
        .map(|l| qd[*l].dot(&tau[*l]))
        .sum::<f64>()
        .max(0.0)
}

/// Eq. (8): CoT = Σ max(q̇ᵀτ, 0)·dt / ΔD, in J/m. `None` when the distance is not positive.
pub fn cost_of_transport_j_per_m(energy_j: f64, distance_m: f64) -> Option<f64> {
    (distance_m > 0.0).then(|| energy_j / distance_m)
}

/// The dimensionless CoT beside eq. (8): E / (m g ΔD).
pub fn cost_of_transport_dimensionless(
    energy_j: f64,
    mass_kg: f64,
    distance_m: f64,
) -> Option<f64> {
    cost_of_transport_j_per_m(energy_j, distance_m).map(|c| c / (mass_kg * GRAVITY))
}

/// Eq. (9): √(λ_max/λ_min) of U = (J Jᵀ)⁻¹, i.e. the ratio of the longest to the shortest axis
/// of the force ellipsoid fᵀ J Jᵀ f ≤ 1 (equal to J's condition number σ_max/σ_min).
///
/// What "higher" means: the ellipsoid is more elongated. For a stance leg its long axis points
/// along the leg (roughly the ground normal), so a higher value is a leg that can push much
/// harder along the normal than tangentially, which the paper reads as a favourable,
/// non-slipping configuration ("maximise the manipulability measure"). The value is 1 for an
/// isotropic leg and grows without bound toward a singular (straight) leg. `None` if J is
/// singular.
pub fn force_manipulability(jacobian: &Matrix3<f64>) -> Option<f64> {
    let jjt = jacobian * jacobian.transpose();
    let u = jjt.try_inverse()?;
    let eig = u.symmetric_eigen().eigenvalues;
    let (min, max) = (eig.min(), eig.max());
    (min > 0.0).then(|| (max / min).sqrt())
}

/// Running sums over a run; `finish` turns them into [`WalkMetrics`].
#[derive(Clone, Debug, Default)]
pub struct MetricsAccumulator {
    pub energy_j: f64,
    start_xy: Option<[f64; 2]>,
    end_xy: [f64; 2],
    path_m: f64,
    sq_vel_err: f64,
    vel_samples: usize,
    manip_sum: f64,
    manip_samples: usize,
    all_stance_time_s: f64,
    time_s: f64,
    joint_positive_work_j: f64,
    joint_negative_work_j: f64,
    /// The battery's account, at every observed (physics) step; `None` without a motor model.
    electrical: Option<EnergyAccount>,
}

/// A run's CoTs are reported only over a straight-line displacement of at least this much, m.
/// Below it the distance is the trunk's sway and drift, not travel, and eq. (8)'s ratio means
/// nothing: a trot commanded to 0 m/s did no positive work over 9 mm of drift and read CoT 0.
pub const MIN_COT_DISTANCE_M: f64 = 0.05;

/// Which energy a cost of transport counts: what a sweep's selection minimises
/// (`[selection] objective`), what a table's `cot` column holds, and what EEMP-RL's reward
/// measures (`rewards.objective`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CotObjective {
    /// Eq. (8): the net mechanical power of all joints (the paper's).
    #[default]
    Eq8,
    /// The drives' electrical power under the robot's `[motor]` model (its bus model included).
    Electrical,
    /// The same plus the electronics' idle power: what the battery pays.
    ElectricalIdle,
}

impl CotObjective {
    /// The energy it counts over a run, J (`None`: an electrical objective without a motor
    /// model).
    pub fn energy_j(self, m: &WalkMetrics) -> Option<f64> {
        match self {
            CotObjective::Eq8 => Some(m.energy_j),
            CotObjective::Electrical => m.electrical.as_ref().map(|e| e.motor_energy_j),
            CotObjective::ElectricalIdle => m.electrical.as_ref().map(|e| e.energy_j),
        }
    }

    /// Its CoT over a run (`None` under [`MIN_COT_DISTANCE_M`] or without a motor model).
    pub fn cot(self, m: &WalkMetrics) -> Option<f64> {
        match self {
            CotObjective::Eq8 => m.cot,
            CotObjective::Electrical => m.electrical.as_ref().and_then(|e| e.cot_motors),
            CotObjective::ElectricalIdle => m.electrical.as_ref().and_then(|e| e.cot),
        }
    }

    pub fn is_eq8(&self) -> bool {
        *self == CotObjective::Eq8
    }

    /// Its name in files (`eq8`, `electrical`, `electrical-idle`).
    pub fn name(self) -> &'static str {
        match self {
            CotObjective::Eq8 => "eq8",
            CotObjective::Electrical => "electrical",
            CotObjective::ElectricalIdle => "electrical-idle",
        }
    }
}

/// Summary metrics of a run (over the measured window).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct WalkMetrics {
    /// Horizontal straight-line distance from the window's start to its end, m (ΔD of eq. 8).
    pub distance_m: f64,
    /// Horizontal path length, m.
    pub path_length_m: f64,
    pub energy_j: f64,
    /// Eq. (8), J/m; `None` under [`MIN_COT_DISTANCE_M`] of distance.
    pub cot_j_per_m: Option<f64>,
    /// Eq. (8) over m·g; `None` under [`MIN_COT_DISTANCE_M`] of distance.
    pub cot: Option<f64>,
    pub manipulability: Option<f64>,
    pub vel_rmse_mps: Option<f64>,
    pub all_stance_fraction: f64,
    pub duration_s: f64,
    /// Work of the joints where each joint's power is positive, Σⱼ max(q̇ⱼτⱼ, 0)·dt, J (eq. 8
    /// clips the sum over joints instead, so it credits one joint's absorbed power to another).
    pub joint_positive_work_j: f64,
    /// Work the joints absorb, Σⱼ max(−q̇ⱼτⱼ, 0)·dt, J (negative work, braking).
    pub joint_negative_work_j: f64,
    /// Share of the joints' absolute work that is negative: negative / (positive + negative).
    pub negative_work_share: Option<f64>,
    /// CoT of the absolute joint power, Σⱼ |q̇ⱼτⱼ|·dt / (m g ΔD) (Fu et al. 2021's energy
    /// measure), for comparison with papers that use it.
    pub cot_abs_power: Option<f64>,
    /// The drives' electrical CoT under the robot's motor model, no idle power (`None` without
    /// one): `electrical.cot_motors`, kept as the sweeps' column.
    pub cot_electrical: Option<f64>,
    /// What the battery paid ([`crate::energy`]); `None` without a motor model, with
    /// `electrical_note` saying so.
    pub electrical: Option<ElectricalMetrics>,
    pub electrical_note: Option<&'static str>,
}

impl MetricsAccumulator {
    /// An accumulator that also keeps the battery's account under `motor` (the robot file's
    /// `[motor]`; `None`: no electrical figures).
    pub fn new(motor: Option<MotorModel>) -> Self {
        MetricsAccumulator {
            electrical: motor.map(EnergyAccount::new),
            ..Default::default()
        }
    }

    /// One control step of length `dt`: body position, body velocity and command in the heading
    /// frame, joint velocities and applied torques, stance set and the stance legs' Jacobians.
    #[allow(clippy::too_many_arguments)]
    pub fn observe(
        &mut self,
        dt: f64,
        p_world: &Vector3<f64>,
        v_heading: &Vector3<f64>,
        v_command_xy: [f64; 2],
        qd: &LegMap<Vector3<f64>>,
        tau: &LegMap<Vector3<f64>>,
        stance: &LegMap<bool>,
        jacobians: &LegMap<Matrix3<f64>>,
    ) {
        let xy = [p_world.x, p_world.y];
        if self.start_xy.is_none() {
            self.start_xy = Some(xy);
        } else {
            self.path_m +=
                ((xy[0] - self.end_xy[0]).powi(2) + (xy[1] - self.end_xy[1]).powi(2)).sqrt();
        }
        self.end_xy = xy;
        self.energy_j += positive_power_w(qd, tau) * dt;
        for leg in Leg::ALL {
            for j in 0..3 {
                let p = crate::energy::joint_mechanical_power_w(qd[leg][j], tau[leg][j]);
                match p >= 0.0 {
                    true => self.joint_positive_work_j += p * dt,
                    false => self.joint_negative_work_j -= p * dt,
                }
            }
        }
        if let Some(e) = &mut self.electrical {
            e.observe(dt, qd, tau);
        }
        self.sq_vel_err +=
            (v_heading.x - v_command_xy[0]).powi(2) + (v_heading.y - v_command_xy[1]).powi(2);
        self.vel_samples += 1;
        let mut n_stance = 0;
        for leg in Leg::ALL {
            if stance[leg] {
                n_stance += 1;
                if let Some(m) = force_manipulability(&jacobians[leg]) {
                    self.manip_sum += m;
                    self.manip_samples += 1;
                }
            }
        }
        if n_stance == 4 {
            self.all_stance_time_s += dt;
        }
        self.time_s += dt;
    }

    pub fn finish(&self, mass_kg: f64) -> WalkMetrics {
        let start = self.start_xy.unwrap_or(self.end_xy);
        let distance =
            ((self.end_xy[0] - start[0]).powi(2) + (self.end_xy[1] - start[1]).powi(2)).sqrt();
        // Eq. (8)'s ΔD, only for a run that travelled (the CoTs are `None` otherwise).
        let travelled_m = (distance >= MIN_COT_DISTANCE_M).then_some(distance);
        let cot = |energy_j: f64| {
            travelled_m.and_then(|d| cost_of_transport_dimensionless(energy_j, mass_kg, d))
        };
        let electrical = self
            .electrical
            .as_ref()
            .map(|e| e.finish(mass_kg * GRAVITY, travelled_m));
        WalkMetrics {
            distance_m: distance,
            path_length_m: self.path_m,
            energy_j: self.energy_j,
            cot_j_per_m: travelled_m.and_then(|d| cost_of_transport_j_per_m(self.energy_j, d)),
            cot: cot(self.energy_j),
            manipulability: (self.manip_samples > 0)
                .then(|| self.manip_sum / self.manip_samples as f64),
            vel_rmse_mps: (self.vel_samples > 0)
                .then(|| (self.sq_vel_err / self.vel_samples as f64).sqrt()),
            all_stance_fraction: if self.time_s > 0.0 {
                self.all_stance_time_s / self.time_s
            } else {
                0.0
            },
            duration_s: self.time_s,
            joint_positive_work_j: self.joint_positive_work_j,
            joint_negative_work_j: self.joint_negative_work_j,
            negative_work_share: {
                let total = self.joint_positive_work_j + self.joint_negative_work_j;
                (total > 0.0).then(|| self.joint_negative_work_j / total)
            },
            cot_abs_power: cot(self.joint_positive_work_j + self.joint_negative_work_j),
            cot_electrical: electrical.as_ref().and_then(|e| e.cot_motors),
            electrical_note: electrical
                .is_none()
                .then_some(crate::energy::NO_MOTOR_MODEL_NOTE),
            electrical,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cost_of_transport_by_hand() {
        // Two steps of 0.5 s: power +20 W then −10 W (not credited): E = 10 J over 2 m → 5 J/m.
        let qd = LegMap::from_fn(|l| {
            if l == Leg::FrontLeft {
                Vector3::new(2.0, 0.0, 0.0)
            } else {
                Vector3::zeros()
            }
        });
        let tau_pos = LegMap::from_fn(|_| Vector3::new(10.0, 3.0, 3.0));
        let tau_neg = LegMap::from_fn(|_| Vector3::new(-5.0, 0.0, 0.0));
        let e = positive_power_w(&qd, &tau_pos) * 0.5 + positive_power_w(&qd, &tau_neg) * 0.5;
        assert_eq!(e, 10.0);
        assert_eq!(cost_of_transport_j_per_m(e, 2.0), Some(5.0));
        assert!(
            (cost_of_transport_dimensionless(e, 10.0, 2.0).unwrap() - 5.0 / 98.1).abs() < 1e-12
        );
        assert_eq!(cost_of_transport_j_per_m(e, 0.0), None);
    }

    #[test]
    fn manipulability_by_hand() {
        // J = diag(1, 2, 4): JJᵀ = diag(1, 4, 16), U = diag(1, 1/4, 1/16): √(1/(1/16)) = 4.
        assert!(
            (force_manipulability(&Matrix3::from_diagonal(&Vector3::new(1.0, 2.0, 4.0))).unwrap()
                - 4.0)
                .abs()
                < 1e-12
        );
        assert!((force_manipulability(&Matrix3::identity()).unwrap() - 1.0).abs() < 1e-12);
        // A rotation does not change it (second method: singular values).
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 1.0);
        let j = r.matrix() * Matrix3::from_diagonal(&Vector3::new(0.3, 0.2, 0.05));
        let svd = j.svd(false, false).singular_values;
        assert!((force_manipulability(&j).unwrap() - svd.max() / svd.min()).abs() < 1e-9);
        assert_eq!(force_manipulability(&Matrix3::zeros()), None);
    }

    #[test]
    fn accumulator_reports_distance_tracking_and_stance_fraction() {
        let mut acc = MetricsAccumulator::default();
        let zero = LegMap::splat(Vector3::zeros());
        let jac = LegMap::splat(Matrix3::identity());
        for i in 0..100 {
            let all = i < 25;
            let stance = LegMap::from_fn(|l| all || l == Leg::FrontLeft || l == Leg::RearRight);
            acc.observe(
                0.01,
                &Vector3::new(i as f64 * 0.003, 0.0, 0.3),
                &Vector3::new(0.3, 0.0, 0.0),
                [0.4, 0.0],
                &zero,
                &zero,
                &stance,
                &jac,
            );
        }
        let m = acc.finish(12.0);
        assert!((m.distance_m - 0.297).abs() < 1e-12);
        assert!((m.vel_rmse_mps.unwrap() - 0.1).abs() < 1e-12);
        assert!((m.all_stance_fraction - 0.25).abs() < 1e-12);
        assert_eq!(m.manipulability, Some(1.0));
    }

    #[test]
    fn a_run_that_does_not_travel_has_no_cot() {
        let walk = |dx_per_step_m: f64| {
            let mut acc = MetricsAccumulator::default();
            let mut qd = LegMap::splat(Vector3::zeros());
            let mut tau = LegMap::splat(Vector3::zeros());
            qd[Leg::FrontRight].x = 1.0;
            tau[Leg::FrontRight].x = 5.0;
            for i in 0..100 {
                acc.observe(
                    0.01,
                    &Vector3::new(i as f64 * dx_per_step_m, 0.0, 0.3),
                    &Vector3::zeros(),
                    [0.0, 0.0],
                    &qd,
                    &tau,
                    &LegMap::splat(true),
                    &LegMap::splat(Matrix3::identity()),
                )
            }
            acc.finish(10.0)
        };
        // 99 steps of 0.4 mm: 39.6 mm of drift, under the 50 mm minimum.
        let stand = walk(0.0004);
        assert!((stand.distance_m - 0.0396).abs() < 1e-12);
        assert_eq!(
            (stand.cot, stand.cot_j_per_m, stand.cot_abs_power),
            (None, None, None)
        );
        assert!(stand.energy_j > 0.0);
        // 99 steps of 0.6 mm: 59.4 mm, over it; 5 W for 1 s (the first sample opens the
        // window) is 5 J over 0.0594 m.
        let walked = walk(0.0006);
        assert!((walked.cot_j_per_m.unwrap() - walked.energy_j / 0.0594).abs() < 1e-9);
    }

    #[test]
    fn negative_work_and_absolute_power_by_hand() {
        // Two steps of 0.5 s with FR's hip at +20 W and FL's knee at −10 W: eq. 8 takes
        // max(20 − 10, 0) = 10 W (10 J), the joints do 20 J and absorb 10 J; the |power| CoT is
        // 30 J / (10 kg · g · 1 m).
        let mut acc = MetricsAccumulator::new(Some(MotorModel {
            heat_coefficient_w_per_nm2: [0.3; 3],
            idle_power_w: 0.0,
            regeneration_fraction: 0.0,
            shared_bus: false,
        }));
        let mut qd = LegMap::splat(Vector3::zeros());
        let mut tau = LegMap::splat(Vector3::zeros());
        qd[Leg::FrontRight].x = 2.0;
        tau[Leg::FrontRight].x = 10.0;
        qd[Leg::FrontLeft].z = -1.0;
        tau[Leg::FrontLeft].z = 10.0;
        let jac = LegMap::splat(Matrix3::identity());
        let none = LegMap::splat(false);
        for x in [0.0, 1.0] {
            acc.observe(
                0.5,
                &Vector3::new(x, 0.0, 0.3),
                &Vector3::zeros(),
                [0.0, 0.0],
                &qd,
                &tau,
                &none,
                &jac,
            );
        }
        let m = acc.finish(10.0);
        assert!((m.energy_j - 10.0).abs() < 1e-12);
        assert!((m.joint_positive_work_j - 20.0).abs() < 1e-12);
        assert!((m.joint_negative_work_j - 10.0).abs() < 1e-12);
        assert!((m.negative_work_share.unwrap() - 1.0 / 3.0).abs() < 1e-12);
        assert!((m.cot_abs_power.unwrap() - 30.0 / (10.0 * GRAVITY)).abs() < 1e-12);
        // Electrical: FR 20 + 0.3·100 = 50 W, FL max(−10 + 0.3·100, 0) = 20 W → 70 J.
        assert!((m.cot_electrical.unwrap() - 70.0 / (10.0 * GRAVITY)).abs() < 1e-12);
    }

    #[test]
    fn without_a_motor_model_the_electrical_figures_are_absent_and_said_so() {
        let m = MetricsAccumulator::default().finish(10.0);
        assert_eq!((m.cot_electrical, m.electrical.is_none()), (None, true));
        assert!(m.electrical_note.unwrap().contains("[motor]"));
    }
}
