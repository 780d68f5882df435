//! Simulated sensors for the estimator: the IMU (attitude, gyro, accelerometer) and the joint
//! encoders, with noise, gyro bias and latency. Noise is uniform in ±level (as MIT
//! Cheetah-Software's simulator draws it) from a seeded RNG, so a run repeats exactly.

use eemp_core::body_state::LegJointState;
use eemp_core::config_error::{check_range, ConfigError};
use eemp_core::estimator::ImuReading;
use eemp_core::leg::LegMap;
use nalgebra::{UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorNoise {
    /// Gyro noise, rad/s.
    pub gyro_rps: f64,
    /// Accelerometer noise, m/s².
    pub accel_mps2: f64,
    /// Attitude noise per axis (small rotation), rad.
    pub attitude_rad: f64,
    /// Joint angle noise, rad.
    pub joint_pos_rad: f64,
    /// Joint velocity noise, rad/s.
    pub joint_vel_rps: f64,
    /// Constant gyro bias, rad/s.
    pub gyro_bias_rps: [f64; 3],
    /// Every reading arrives this late, s (rounded to physics steps).
    pub latency_s: f64,
}

impl Default for SensorNoise {
    /// A1-like levels: Cheetah-Software's simulated IMU (±0.005 gyro and accelerometer,
    /// ±0.003 attitude), encoders ±0.001 rad and ±0.05 rad/s (a 1/8192-turn encoder on a 9:1
    /// gearbox, differentiated at 1 kHz and filtered, as Unitree's motors report), no bias,
    /// 1 ms latency.
    fn default() -> Self {
        SensorNoise {
            gyro_rps: 0.005,
            accel_mps2: 0.005,
            attitude_rad: 0.003,
            joint_pos_rad: 0.001,
            joint_vel_rps: 0.05,
            gyro_bias_rps: [0.0; 3],
            latency_s: 0.001,
        }
    }
}

impl SensorNoise {
    /// Perfect sensors.
    pub fn none() -> Self {
        SensorNoise {
            gyro_rps: 0.0,
            accel_mps2: 0.0,
            attitude_rad: 0.0,
            joint_pos_rad: 0.0,
            joint_vel_rps: 0.0,
            gyro_bias_rps: [0.0; 3],
            latency_s: 0.0,
        }
    }

    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("sensors.gyro_rps", self.gyro_rps, 0.0, 1.0)?;
        check_range("sensors.accel_mps2", self.accel_mps2, 0.0, 10.0)?;
        check_range("sensors.attitude_rad", self.attitude_rad, 0.0, 0.2)?;
        check_range("sensors.joint_pos_rad", self.joint_pos_rad, 0.0, 0.1)?;
        check_range("sensors.joint_vel_rps", self.joint_vel_rps, 0.0, 5.0)?;
        for (i, b) in self.gyro_bias_rps.iter().enumerate() {
            check_range(&format!("sensors.gyro_bias_rps[{i}]"), *b, -0.5, 0.5)?;
        }
        check_range("sensors.latency_s", self.latency_s, 0.0, 0.05)
    }
}

/// One reading of everything the robot senses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorReading {
    pub imu: ImuReading,
    pub joints: LegMap<LegJointState>,
}

#[derive(Clone)]
pub struct Sensors {
    noise: SensorNoise,
    rng: ChaCha8Rng,
    delay_steps: usize,
    queue: VecDeque<SensorReading>,
}

impl Sensors {
    pub fn new(noise: SensorNoise, seed: u64, timestep_s: f64) -> Result<Self, ConfigError> {
        noise.validate()?;
        Ok(Sensors {
            delay_steps: (noise.latency_s / timestep_s).round() as usize,
            noise,
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0x5E45_0125),
            queue: VecDeque::new(),
        })
    }

    fn u(&mut self, level: f64) -> f64 {
        if level > 0.0 {
            self.rng.random_range(-level..level)
        } else {
            0.0
        }
    }

    fn v3(&mut self, level: f64) -> Vector3<f64> {
        Vector3::new(self.u(level), self.u(level), self.u(level))
    }

    /// Forgets the readings in the latency pipe (a new episode).
    pub fn clear(&mut self) {
        self.queue.clear();
    }

    /// Takes the true readings of this step; returns what the robot sees now (the reading of
    /// `latency` ago, noisy). Until the pipe has filled, the oldest reading is repeated.
    pub fn read(&mut self, imu: ImuReading, joints: &LegMap<LegJointState>) -> SensorReading {
        let n = self.noise.clone();
        let bias = Vector3::from(n.gyro_bias_rps);
        let tilt = self.v3(n.attitude_rad);
        let noisy = SensorReading {
            imu: ImuReading {
                r_world_body: imu.r_world_body * UnitQuaternion::from_scaled_axis(tilt),
                gyro_body: imu.gyro_body + bias + self.v3(n.gyro_rps),
                accel_body: imu.accel_body + self.v3(n.accel_mps2),
            },
            joints: LegMap::from_fn(|leg| LegJointState {
                q: joints[leg].q + self.v3(n.joint_pos_rad),
                qd: joints[leg].qd + self.v3(n.joint_vel_rps),
            }),
        };
        self.queue.push_back(noisy);
        while self.queue.len() > self.delay_steps + 1 {
            self.queue.pop_front();
        }
        *self.queue.front().expect("just pushed")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn imu() -> ImuReading {
        ImuReading {
            r_world_body: UnitQuaternion::identity(),
            gyro_body: Vector3::new(0.1, 0.0, 0.0),
            accel_body: Vector3::new(0.0, 0.0, 9.81),
        }
    }

    #[test]
    fn noise_stays_within_its_level_and_latency_delays_readings() {
        let noise = SensorNoise {
            latency_s: 0.002,
            ..Default::default()
        };
        let mut s = Sensors::new(noise, 3, 0.001).unwrap();
        let joints = |q: f64| {
            LegMap::splat(LegJointState {
                q: Vector3::repeat(q),
                qd: Vector3::zeros(),
            })
        };
        let first = s.read(imu(), &joints(0.0));
        assert!((first.imu.gyro_body.x - 0.1).abs() <= 0.005);
        assert!((first.imu.accel_body.z - 9.81).abs() <= 0.005);
        assert!(first.joints.0[0].q.x.abs() <= 0.001);
        s.read(imu(), &joints(1.0));
        let third = s.read(imu(), &joints(2.0));
        // Two steps of latency: the third call returns the first reading's angles (≈ 0).
        assert!(third.joints.0[0].q.x.abs() <= 0.001);
        let fourth = s.read(imu(), &joints(3.0));
        assert!((fourth.joints.0[0].q.x - 1.0).abs() <= 0.001);
    }

    #[test]
    fn no_noise_is_the_truth() {
        let mut s = Sensors::new(SensorNoise::none(), 1, 0.001).unwrap();
        let j = LegMap::splat(LegJointState {
            q: Vector3::new(0.1, 0.9, -1.8),
            qd: Vector3::new(1.0, 2.0, 3.0),
        });
        let r = s.read(imu(), &j);
        assert_eq!(r.imu, imu());
        assert_eq!(r.joints, j);
    }
}
