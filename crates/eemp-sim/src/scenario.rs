//! Scenario files (`scenarios/*.toml`): what the world does to a walk — terrain, floor friction,
//! pushes (at given times or every few seconds), a payload, errors of the robot's mass, inertia
//! and motor strength (`[model_error]`), and the sensors' noise — in one
//! validated file that `eemp walk --scenario FILE` applies to any controller.

use crate::closed_loop::Push;
use crate::sensors::SensorNoise;
use crate::terrain::Terrain;
use crate::walk::{ModelError, WalkSpec};
use eemp_core::config_error::{check_range, ConfigError};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// One push: the trunk's velocity changes by `dv_mps` (world frame) at `at_s`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PushSpec {
    pub at_s: f64,
    pub dv_mps: [f64; 3],
    /// 0: a step of the velocity; > 0: a force pulse this long, s (see [`Push`]).
    #[serde(default)]
    pub duration_s: f64,
}

/// Pushes of the same size every `every_s` from `first_s` on, alternating left and right, each
/// late by a random `[0, jitter_s)` drawn from the run's seed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PushSchedule {
    pub first_s: f64,
    pub every_s: f64,
    /// Size of the lateral velocity change, m/s.
    pub dv_mps: f64,
    /// 0: a step of the velocity; > 0: a force pulse this long, s (see [`Push`]).
    #[serde(default)]
    pub duration_s: f64,
    /// Each push comes up to this much later than its slot, s, uniformly at random from the
    /// run's seed: on a periodic gait, fixed times would hit every run's gait in the same few
    /// phases, and a push's effect depends strongly on the phase it meets.
    #[serde(default)]
    pub jitter_s: f64,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    #[serde(default)]
    pub terrain: Terrain,
    /// Floor friction; default: the robot file's.
    #[serde(default)]
    pub floor_friction: Option<f64>,
    #[serde(default)]
    pub push: Vec<PushSpec>,
    #[serde(default)]
    pub push_schedule: Option<PushSchedule>,
    #[serde(default)]
    pub payload_kg: f64,
    /// Sensor noise for runs on the estimator; default: `SensorNoise::default()`.
    #[serde(default)]
    pub sensors: Option<SensorNoise>,
    /// Trunk mass/inertia and motor strength errors of the simulated robot.
    #[serde(default)]
    pub model_error: ModelError,
}

impl Scenario {
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.terrain.validate()?;
        if let Some(mu) = self.floor_friction {
            eemp_core::config_error::check_friction("floor_friction", mu)?;
        }
        for (i, p) in self.push.iter().enumerate() {
            check_range(&format!("push[{i}].at_s"), p.at_s, 0.0, 3600.0)?;
            for (k, v) in p.dv_mps.iter().enumerate() {
                check_range(&format!("push[{i}].dv_mps[{k}]"), *v, -3.0, 3.0)?;
            }
            check_range(&format!("push[{i}].duration_s"), p.duration_s, 0.0, 1.0)?;
        }
        if let Some(s) = &self.push_schedule {
            check_range("push_schedule.first_s", s.first_s, 0.0, 3600.0)?;
            check_range("push_schedule.every_s", s.every_s, 0.2, 3600.0)?;
            check_range("push_schedule.dv_mps", s.dv_mps, 0.0, 3.0)?;
            check_range("push_schedule.duration_s", s.duration_s, 0.0, 1.0)?;
            check_range("push_schedule.jitter_s", s.jitter_s, 0.0, 3600.0)?;
            if s.duration_s + s.jitter_s >= s.every_s {
                return Err(ConfigError::Invalid {
                    name: "push_schedule".into(),
                    message: format!(
                        "duration_s {} + jitter_s {} must be shorter than every_s {} (pushes \
                         would overlap)",
                        s.duration_s, s.jitter_s, s.every_s
                    ),
                });
            }
        }
        // Within the robot's cap when it runs (`WalkSpec::validate_for`).
        check_range("payload_kg", self.payload_kg, 0.0, f64::MAX)?;
        self.model_error.validate()?;
        if let Some(s) = &self.sensors {
            s.validate()?;
        }
        Ok(())
    }

    /// Reads and validates a scenario file; errors name the file and the key.
    pub fn load(path: &std::path::Path) -> Result<Self, ConfigError> {
        let s: Scenario = eemp_core::config_error::load_toml(path)?;
        s.validate().map_err(|e| ConfigError::Invalid {
            name: path.display().to_string(),
            message: e.to_string(),
        })?;
        Ok(s)
    }

    /// Every push of a run of `duration_s` whose seed is `seed`.
    pub fn pushes(&self, duration_s: f64, seed: u64) -> Vec<Push> {
        let mut out: Vec<Push> = self
            .push
            .iter()
            .map(|p| Push {
                at_s: p.at_s,
                dv_world: Vector3::from(p.dv_mps),
                duration_s: p.duration_s,
            })
            .collect();
        if let Some(s) = &self.push_schedule {
            use rand::{Rng, SeedableRng};
            // Its own stream: the start perturbation and the sensor noise use the seed too.
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x9e37_79b9_7f4a_7c15);
            let mut t = s.first_s;
            let mut side = 1.0;
            while t < duration_s {
                let late = match s.jitter_s > 0.0 {
                    true => rng.random_range(0.0..s.jitter_s),
                    false => 0.0,
                };
                if t + late >= duration_s {
                    break;
                }
                out.push(Push {
                    at_s: t + late,
                    dv_world: Vector3::new(0.0, side * s.dv_mps, 0.0),
                    duration_s: s.duration_s,
                });
                side = -side;
                t += s.every_s;
            }
        }
        out.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
        out
    }

    /// The robot and scene a walk in this scenario simulates.
    pub fn simulated_world(
        &self,
        robot: &eemp_core::robot::RobotConfig,
    ) -> (eemp_core::robot::RobotConfig, crate::mjcf::SceneExtras) {
        crate::walk::simulated_world(
            robot,
            &self.terrain,
            self.floor_friction,
            &self.model_error,
            self.payload_kg,
        )
    }

    /// Applies the scenario to a walk (terrain, friction, pushes, payload).
    pub fn apply(&self, spec: &mut WalkSpec) {
        spec.terrain = self.terrain.clone();
        if self.floor_friction.is_some() {
            spec.floor_friction = self.floor_friction;
        }
        spec.pushes.extend(self.pushes(spec.duration_s, spec.seed));
        spec.payload_kg = self.payload_kg;
        spec.model_error = self.model_error;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_push_schedule_alternates_sides_until_the_end() {
        let s = Scenario {
            push_schedule: Some(PushSchedule {
                first_s: 2.0,
                every_s: 4.0,
                dv_mps: 0.5,
                duration_s: 0.0,
                jitter_s: 0.0,
            }),
            ..Default::default()
        };
        let p = s.pushes(12.0, 1);
        assert_eq!(p.len(), 3);
        assert_eq!(p[1].at_s, 6.0);
        assert_eq!(p[0].dv_world.y, 0.5);
        assert_eq!(p[1].dv_world.y, -0.5);
    }

    #[test]
    fn a_jittered_schedule_is_late_by_less_than_the_jitter_and_repeats_with_its_seed() {
        let mut s = Scenario {
            push_schedule: Some(PushSchedule {
                first_s: 3.0,
                every_s: 4.0,
                dv_mps: 0.5,
                duration_s: 0.1,
                jitter_s: 0.5,
            }),
            ..Default::default()
        };
        s.validate().unwrap();
        let a = s.pushes(20.0, 1);
        assert_eq!(a.len(), 5);
        for (k, p) in a.iter().enumerate() {
            let slot = 3.0 + 4.0 * k as f64;
            assert!(p.at_s >= slot && p.at_s < slot + 0.5, "{k}: {}", p.at_s);
            assert_eq!(p.duration_s, 0.1);
            assert_eq!(p.dv_world.y, if k % 2 == 0 { 0.5 } else { -0.5 });
        }
        assert_eq!(a, s.pushes(20.0, 1));
        let b = s.pushes(20.0, 2);
        assert!(a.iter().zip(&b).all(|(x, y)| x.at_s != y.at_s));
        // Pushes that would overlap the next slot are refused, naming the keys.
        s.push_schedule.as_mut().unwrap().jitter_s = 3.95;
        let e = s.validate().unwrap_err().to_string();
        assert!(e.contains("jitter_s") && e.contains("every_s"), "{e}");
    }
}
