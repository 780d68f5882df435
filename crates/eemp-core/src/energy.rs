//! Energy as the battery sees it: the motor model of a robot file's `[motor]` section and the
//! one energy account every walk, suite, sweep, policy reward and hardware run reads.
//!
//! Each joint's drive draws electrical power p = τq̇ + k·τ² (mechanical power plus the winding's
//! Joule heat, k in W/(N·m)² on the joint side). A drive that brakes (p < 0) returns power to
//! the bus; how much of it the battery sees is the robot's bus model
//! ([`MotorModel::bus_power_w`]). The electronics draw a constant idle power on top. Eq. (8),
//! the paper's energy, is the net mechanical power of all joints clipped after the sum
//! (`metrics::positive_power_w`); it is kept beside these figures, labelled as the
//! paper's, never in their place.

use crate::config_error::{check_range, ConfigError};
use crate::leg::{Leg, LegMap};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// The joints of a leg in the order every per-joint array uses.
pub const JOINT_NAMES: [&str; 3] = ["abduction", "thigh", "calf"];

/// The band of heat coefficients every report shows, as multiples of the robot file's k: for
/// the A1's 0.3 W/(N·m)² this is 0.1 / 0.3 / 0.6, the band `docs/energy.md` argues for (Yang et
/// al.'s value, and the Mini Cheetah's motor constant carried to the A1's gear ratio at the top).
pub const HEAT_BAND_SCALES: [f64; 3] = [1.0 / 3.0, 1.0, 2.0];

/// One joint's drive as a robot file states it: the joint-side heat coefficient directly, or the
/// motor data it follows from (k = R / (K_t·N)²).
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct JointMotorConfig {
    /// Joule heat per squared joint torque, W/(N·m)².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heat_coefficient_w_per_nm2: Option<f64>,
    /// Joint turns per rotor turn, inverted: rotor speed / joint speed (≥ 1 for a reducer).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gear_ratio: Option<f64>,
    /// Rotor torque per ampere of the current whose square times R is the copper loss, N·m/A.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub torque_constant_nm_per_a: Option<f64>,
    /// Winding resistance in the same convention as the torque constant, Ω.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub winding_resistance_ohm: Option<f64>,
}

/// `[motor]` in a robot file: per joint (abduction, thigh, calf) the drive, the electronics'
/// idle power, and the bus's take-back of braking power.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MotorConfig {
    pub abduction: JointMotorConfig,
    pub thigh: JointMotorConfig,
    pub calf: JointMotorConfig,
    /// Electronics (computers, drivers, sensors) drawn whatever the legs do, W.
    pub idle_power_w: f64,
    /// Share of a braking drive's power the bus takes back, in [0, 1] (0: dumped as heat).
    pub regeneration_fraction: f64,
    /// Whether the drives share one bus, so one joint's braking feeds another's draw in the same
    /// instant before anything reaches the battery.
    pub shared_bus: bool,
}

/// The validated motor model: what the energy account computes with.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MotorModel {
    /// Joint-side heat coefficient per joint (abduction, thigh, calf), W/(N·m)².
    pub heat_coefficient_w_per_nm2: [f64; 3],
    pub idle_power_w: f64,
    pub regeneration_fraction: f64,
    pub shared_bus: bool,
}

/// Joint-side heat coefficient from motor data: k = R / (K_t·N)², W/(N·m)². A joint torque τ
/// is a rotor torque τ/N and a current τ/(N·K_t), which heats the winding by R·(τ/(N·K_t))².
pub fn heat_coefficient_from_motor(
    gear_ratio: f64,
    torque_constant_nm_per_a: f64,
    winding_resistance_ohm: f64,
) -> f64 {
    winding_resistance_ohm / (torque_constant_nm_per_a * gear_ratio).powi(2)
}

/// One joint's mechanical power τq̇, W (negative while it brakes).
pub fn joint_mechanical_power_w(qd: f64, tau: f64) -> f64 {
    tau * qd
}

/// One joint's Joule heat k·τ², W.
pub fn joint_heat_w(tau: f64, heat_coefficient: f64) -> f64 {
    heat_coefficient * tau * tau
}

/// One joint's electrical draw τq̇ + k·τ², W (negative while the drive generates).
pub fn joint_electrical_power_w(qd: f64, tau: f64, heat_coefficient: f64) -> f64 {
    joint_mechanical_power_w(qd, tau) + joint_heat_w(tau, heat_coefficient)
}

impl MotorConfig {
    /// Validates every number and resolves each joint's heat coefficient. Errors name the key
    /// (`motor.<joint>.<field>`) and the allowed range.
    pub fn resolve(&self) -> Result<MotorModel, ConfigError> {
        let joints = [&self.abduction, &self.thigh, &self.calf];
        let mut k = [0.0; 3];
        for (j, (cfg, name)) in joints.iter().zip(JOINT_NAMES).enumerate() {
            k[j] = cfg.heat_coefficient(&format!("motor.{name}"))?;
        }
        check_range("motor.idle_power_w", self.idle_power_w, 0.0, 1e5)?;
        check_range(
            "motor.regeneration_fraction",
            self.regeneration_fraction,
            0.0,
            1.0,
        )?;
        Ok(MotorModel {
            heat_coefficient_w_per_nm2: k,
            idle_power_w: self.idle_power_w,
            regeneration_fraction: self.regeneration_fraction,
            shared_bus: self.shared_bus,
        })
    }
}

impl JointMotorConfig {
    fn heat_coefficient(&self, key: &str) -> Result<f64, ConfigError> {
        let data = [
            self.gear_ratio,
            self.torque_constant_nm_per_a,
            self.winding_resistance_ohm,
        ];
        match (self.heat_coefficient_w_per_nm2, data) {
            (Some(k), [None, None, None]) => {
                check_range(&format!("{key}.heat_coefficient_w_per_nm2"), k, 0.0, 100.0)?;
                Ok(k)
            }
            (None, [Some(n), Some(kt), Some(r)]) => {
                check_range(&format!("{key}.gear_ratio"), n, 1e-3, 1e3)?;
                check_range(&format!("{key}.torque_constant_nm_per_a"), kt, 1e-6, 1e3)?;
                check_range(&format!("{key}.winding_resistance_ohm"), r, 0.0, 1e3)?;
                Ok(heat_coefficient_from_motor(n, kt, r))
            }
            _ => Err(ConfigError::Invalid {
                name: key.to_string(),
                message: "give either heat_coefficient_w_per_nm2, or all three of gear_ratio, \
                          torque_constant_nm_per_a and winding_resistance_ohm"
                    .into(),
            }),
        }
    }
}

impl MotorModel {
    /// The same model with every heat coefficient multiplied by `scale` (the report's band).
    pub fn with_heat_scaled(&self, scale: f64) -> MotorModel {
        MotorModel {
            heat_coefficient_w_per_nm2: self.heat_coefficient_w_per_nm2.map(|k| k * scale),
            ..*self
        }
    }

    /// What the battery pays the drives for joint draws `draws_w`, W (idle power not included):
    /// - separate buses: Σ p⁺ − η Σ p⁻ (each drive's braking, times η, goes back to the battery);
    /// - one shared bus: the net draw Σ p when it is positive, else η times it (braking feeds
    ///   the other drives first, only the surplus reaches the battery).
    ///
    /// With η = 0 and separate buses this is Σ max(p, 0), Yang et al.'s (CoRL 2021) form.
    pub fn bus_power_w(&self, draws_w: impl Iterator<Item = f64>) -> f64 {
        let (mut drawn, mut returned) = (0.0, 0.0);
        for p in draws_w {
            if p >= 0.0 {
                drawn += p;
            } else {
                returned -= p;
            }
        }
        let eta = self.regeneration_fraction;
        if self.shared_bus {
            let net = drawn - returned;
            if net >= 0.0 {
                net
            } else {
                eta * net
            }
        } else {
            drawn - eta * returned
        }
    }

    /// The drives' electrical power for joint velocities `qd` and torques `tau`, W, without the
    /// idle power: the bus's take on each joint's τq̇ + k·τ².
    pub fn motor_power_w(&self, qd: &LegMap<Vector3<f64>>, tau: &LegMap<Vector3<f64>>) -> f64 {
        let k = self.heat_coefficient_w_per_nm2;
        self.bus_power_w(
            Leg::ALL
                .iter()
                .flat_map(|l| (0..3).map(move |j| (qd[*l][j], tau[*l][j], k[j])))
                .map(|(w, t, k)| joint_electrical_power_w(w, t, k)),
        )
    }

    /// Σ k·τ² over the twelve joints, W.
    pub fn heat_w(&self, tau: &LegMap<Vector3<f64>>) -> f64 {
        let k = self.heat_coefficient_w_per_nm2;
        Leg::ALL
            .iter()
            .flat_map(|l| (0..3).map(move |j| joint_heat_w(tau[*l][j], k[j])))
            .sum()
    }

    /// Battery power: the drives plus the idle power, W.
    pub fn battery_power_w(&self, qd: &LegMap<Vector3<f64>>, tau: &LegMap<Vector3<f64>>) -> f64 {
        self.motor_power_w(qd, tau) + self.idle_power_w
    }
}

/// Running electrical sums of a run at the physics rate; [`EnergyAccount::finish`] turns them
/// into [`ElectricalMetrics`].
#[derive(Clone, Debug)]
pub struct EnergyAccount {
    model: MotorModel,
    /// Drive energy at each of [`HEAT_BAND_SCALES`] (the middle one is the robot file's k), J.
    motor_energy_j: [f64; 3],
    heat_j: f64,
    time_s: f64,
}

impl EnergyAccount {
    pub fn new(model: MotorModel) -> Self {
        EnergyAccount {
            model,
            motor_energy_j: [0.0; 3],
            heat_j: 0.0,
            time_s: 0.0,
        }
    }

    pub fn model(&self) -> &MotorModel {
        &self.model
    }

    /// One physics step of length `dt`.
    pub fn observe(&mut self, dt: f64, qd: &LegMap<Vector3<f64>>, tau: &LegMap<Vector3<f64>>) {
        for (e, scale) in self.motor_energy_j.iter_mut().zip(HEAT_BAND_SCALES) {
            let model = if scale == 1.0 {
                self.model
            } else {
                self.model.with_heat_scaled(scale)
            };
            *e += model.motor_power_w(qd, tau) * dt;
        }
        self.heat_j += self.model.heat_w(tau) * dt;
        self.time_s += dt;
    }

    /// The figures over the observed time, for a robot of weight `weight_n` (m·g) that travelled
    /// `travelled_m` (straight line; `None` when it did not travel far enough for a CoT).
    pub fn finish(&self, weight_n: f64, travelled_m: Option<f64>) -> ElectricalMetrics {
        let idle_j = self.model.idle_power_w * self.time_s;
        let motor_j = self.motor_energy_j[1];
        let energy_j = motor_j + idle_j;
        let cot = |e: f64| travelled_m.map(|d| e / (weight_n * d));
        ElectricalMetrics {
            heat_coefficient_w_per_nm2: self.model.heat_coefficient_w_per_nm2,
            idle_power_w: self.model.idle_power_w,
            regeneration_fraction: self.model.regeneration_fraction,
            shared_bus: self.model.shared_bus,
            energy_j,
            motor_energy_j: motor_j,
            heat_j: self.heat_j,
            mean_power_w: (self.time_s > 0.0).then(|| energy_j / self.time_s),
            mean_motor_power_w: (self.time_s > 0.0).then(|| motor_j / self.time_s),
            wh_per_km: travelled_m.map(|d| energy_j / 3600.0 / (d / 1000.0)),
            cot: cot(energy_j),
            cot_motors: cot(motor_j),
            band: HEAT_BAND_SCALES
                .iter()
                .zip(self.motor_energy_j)
                .map(|(&scale, e)| HeatBandPoint {
                    heat_scale: scale,
                    cot_motors: cot(e),
                    cot: cot(e + idle_j),
                })
                .collect(),
        }
    }
}

/// One point of the heat-coefficient band: the CoTs with every k multiplied by `heat_scale`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HeatBandPoint {
    pub heat_scale: f64,
    pub cot_motors: Option<f64>,
    pub cot: Option<f64>,
}

/// What the battery paid over a run (the robot file's motor model).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ElectricalMetrics {
    pub heat_coefficient_w_per_nm2: [f64; 3],
    pub idle_power_w: f64,
    pub regeneration_fraction: f64,
    pub shared_bus: bool,
    /// Battery energy: drives plus idle power, J.
    pub energy_j: f64,
    /// The drives alone (no idle power), J.
    pub motor_energy_j: f64,
    /// Σ k·τ² dt, the winding heat inside `motor_energy_j`, J.
    pub heat_j: f64,
    pub mean_power_w: Option<f64>,
    pub mean_motor_power_w: Option<f64>,
    pub wh_per_km: Option<f64>,
    /// Electrical CoT E / (m g ΔD) with idle power.
    pub cot: Option<f64>,
    /// Electrical CoT of the drives alone.
    pub cot_motors: Option<f64>,
    pub band: Vec<HeatBandPoint>,
}

/// What a summary says in place of the electrical figures when the robot file has no `[motor]`.
pub const NO_MOTOR_MODEL_NOTE: &str =
    "no electrical figures: the robot file has no [motor] section (see docs/energy.md)";

#[cfg(test)]
mod tests {
    use super::*;

    fn yang(k: f64) -> MotorModel {
        MotorModel {
            heat_coefficient_w_per_nm2: [k; 3],
            idle_power_w: 0.0,
            regeneration_fraction: 0.0,
            shared_bus: false,
        }
    }

    #[test]
    fn joint_terms_by_hand() {
        // τ = 4 N·m, q̇ = −2 rad/s, k = 0.3: mechanical −8 W, heat 4.8 W, draw −3.2 W.
        assert_eq!(joint_mechanical_power_w(-2.0, 4.0), -8.0);
        assert!((joint_heat_w(4.0, 0.3) - 4.8).abs() < 1e-12);
        assert!((joint_electrical_power_w(-2.0, 4.0, 0.3) + 3.2).abs() < 1e-12);
        // Mini Cheetah's knee (Cheetah-Software): R 0.173 Ω, K_t 0.05·1.5 N·m/A, N 9.33:
        // 0.173 / (0.075·9.33)² = 0.3535.
        let k = heat_coefficient_from_motor(9.33, 0.075, 0.173);
        assert!((k - 0.173 / (0.075f64 * 9.33).powi(2)).abs() < 1e-12);
        assert!((k - 0.3535).abs() < 1e-3);
    }

    #[test]
    fn bus_models_by_hand() {
        // Draws +10, +5, −6 W.
        let draws = [10.0, 5.0, -6.0];
        let mut m = yang(0.3);
        assert_eq!(m.bus_power_w(draws.into_iter()), 15.0);
        m.regeneration_fraction = 0.5;
        assert_eq!(m.bus_power_w(draws.into_iter()), 12.0);
        m.shared_bus = true;
        assert_eq!(m.bus_power_w(draws.into_iter()), 9.0);
        // A surplus of braking on a shared bus: 2 − 6 = −4 W, half of it charges the battery.
        assert_eq!(m.bus_power_w([2.0, -6.0].into_iter()), -2.0);
        m.regeneration_fraction = 0.0;
        assert_eq!(m.bus_power_w([2.0, -6.0].into_iter()), 0.0);
    }

    #[test]
    fn motor_power_is_the_per_joint_clipped_sum_without_regeneration() {
        let mut qd = LegMap::splat(Vector3::zeros());
        let mut tau = LegMap::splat(Vector3::new(0.0, 1.0, 4.0));
        qd[Leg::FrontLeft] = Vector3::new(0.0, 2.0, -3.0);
        tau[Leg::FrontLeft] = Vector3::new(1.0, 2.0, 4.0);
        let m = yang(0.3);
        // FL: 0.3; 4 + 1.2; max(−12 + 4.8, 0) = 0. Others: 0 + 0.3 + 4.8 each (×3).
        let expect = 0.3 + 5.2 + 0.0 + 3.0 * 5.1;
        assert!((m.motor_power_w(&qd, &tau) - expect).abs() < 1e-12);
        // Heat alone: 0.3·(1 + 4 + 16) + 3·0.3·(1 + 16).
        assert!((m.heat_w(&tau) - (0.3 * 21.0 + 0.9 * 17.0)).abs() < 1e-12);
        let idle = MotorModel {
            idle_power_w: 20.0,
            ..m
        };
        assert!((idle.battery_power_w(&qd, &tau) - expect - 20.0).abs() < 1e-12);
    }

    #[test]
    fn account_by_hand() {
        // 2 s of a constant 10 W of heat (one joint, τ = √(10/0.3)) and no motion, idle 5 W,
        // 4 m travelled by 10 kg: motors 20 J, battery 30 J, CoT 30 / (10·9.81·4).
        let mut m = yang(0.3);
        m.idle_power_w = 5.0;
        let mut tau = LegMap::splat(Vector3::zeros());
        tau[Leg::RearLeft].z = (10.0f64 / 0.3).sqrt();
        let qd = LegMap::splat(Vector3::zeros());
        let mut acc = EnergyAccount::new(m);
        for _ in 0..2000 {
            acc.observe(1e-3, &qd, &tau);
        }
        let g = crate::convex_mpc::model::GRAVITY;
        let e = acc.finish(10.0 * g, Some(4.0));
        assert!((e.motor_energy_j - 20.0).abs() < 1e-9);
        assert!((e.heat_j - 20.0).abs() < 1e-9);
        assert!((e.energy_j - 30.0).abs() < 1e-9);
        assert!((e.mean_power_w.unwrap() - 15.0).abs() < 1e-9);
        assert!((e.cot.unwrap() - 30.0 / (10.0 * g * 4.0)).abs() < 1e-12);
        assert!((e.cot_motors.unwrap() - 20.0 / (10.0 * g * 4.0)).abs() < 1e-12);
        // 30 J over 4 m = 7.5 J/m = 2.083 Wh/km.
        assert!((e.wh_per_km.unwrap() - 30.0 / 3.6 / 4.0).abs() < 1e-9);
        // The band: heat scales linearly without motion.
        let band: Vec<f64> = e.band.iter().map(|b| b.cot_motors.unwrap()).collect();
        assert!((band[0] * 3.0 - band[1]).abs() < 1e-12 && (band[2] - 2.0 * band[1]).abs() < 1e-12);
        assert_eq!(acc.finish(10.0 * g, None).cot, None);
    }

    fn config(text: &str) -> Result<MotorModel, String> {
        let c: MotorConfig = toml::from_str(text).map_err(|e| e.to_string())?;
        c.resolve().map_err(|e| e.to_string())
    }

    const GOOD: &str = "idle_power_w = 20.0\nregeneration_fraction = 0.0\nshared_bus = false\n\
        abduction = { heat_coefficient_w_per_nm2 = 0.3 }\nthigh = { heat_coefficient_w_per_nm2 = 0.3 }\n\
        calf = { gear_ratio = 9.1, torque_constant_nm_per_a = 0.1, winding_resistance_ohm = 0.2 }\n";

    #[test]
    fn motor_sections_resolve_or_name_the_key() {
        let m = config(GOOD).unwrap();
        assert_eq!(m.heat_coefficient_w_per_nm2[0], 0.3);
        assert!((m.heat_coefficient_w_per_nm2[2] - 0.2 / (0.91f64).powi(2)).abs() < 1e-12);
        for (from, to, key) in [
            (
                "idle_power_w = 20.0",
                "idle_power_w = -1.0",
                "motor.idle_power_w",
            ),
            (
                "idle_power_w = 20.0",
                "idle_power_w = nan",
                "motor.idle_power_w",
            ),
            (
                "idle_power_w = 20.0",
                "idle_power_w = inf",
                "motor.idle_power_w",
            ),
            (
                "regeneration_fraction = 0.0",
                "regeneration_fraction = 1.5",
                "motor.regeneration_fraction",
            ),
            (
                "thigh = { heat_coefficient_w_per_nm2 = 0.3 }",
                "thigh = { }",
                "motor.thigh",
            ),
            (
                "thigh = { heat_coefficient_w_per_nm2 = 0.3 }",
                "thigh = { heat_coefficient_w_per_nm2 = -0.3 }",
                "motor.thigh.heat_coefficient_w_per_nm2",
            ),
            (
                "winding_resistance_ohm = 0.2",
                "winding_resistance_ohm = nan",
                "motor.calf.winding_resistance_ohm",
            ),
            ("gear_ratio = 9.1, ", "", "motor.calf"),
        ] {
            let err = config(&GOOD.replace(from, to)).unwrap_err();
            assert!(err.contains(key), "{to}: {err}");
        }
        // A joint missing altogether is a parse error naming it.
        let err = config(&GOOD.replace("thigh = { heat_coefficient_w_per_nm2 = 0.3 }\n", ""))
            .unwrap_err();
        assert!(err.contains("thigh"), "{err}");
    }
}
