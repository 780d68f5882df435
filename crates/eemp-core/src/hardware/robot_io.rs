//! Between the protocol's datagrams and the project's types: what a state datagram says about
//! the robot (IMU, joints, motor torques, foot sensors), the command datagram for the safety
//! layer's joint commands, and the motor law the A1's motors apply to a command.

use super::a1_protocol::{LowCmd, LowState, MotorCmd, MODE_SERVO, POS_STOP, VEL_STOP};
use super::safety::{JointCommand, MeasuredJoints, RobotCommand};
use crate::body_state::LegJointState;
use crate::estimator::ImuReading;
use crate::leg::{Leg, LegMap};
use crate::robot::MotorOrder;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// What a state datagram tells the controller.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensedState {
    /// Robot clock, s (the datagram's µs tick).
    pub tick_s: f64,
    pub imu: ImuReading,
    pub joints: LegMap<LegJointState>,
    /// Motor torque estimates, N·m.
    pub tau: LegMap<Vector3<f64>>,
    /// The foot force sensors' raw readings.
    pub foot_force: LegMap<i16>,
}

impl SensedState {
    /// `order`: the robot file's SDK motor numbering (`quadruped.h` on the A1: FR 0–2,
    /// FL 3–5, RR 6–8, RL 9–11).
    pub fn from_low_state(s: &LowState, order: &MotorOrder) -> Self {
        let q = s.imu.quaternion.map(|v| v as f64);
        let v3 = |a: [f32; 3]| Vector3::new(a[0] as f64, a[1] as f64, a[2] as f64);
        let motor = |leg: Leg, j: usize| &s.motors[order.index(leg, j)];
        SensedState {
            tick_s: s.tick as f64 * 1e-6,
            imu: ImuReading {
                r_world_body: UnitQuaternion::from_quaternion(Quaternion::new(
                    q[0], q[1], q[2], q[3],
                )),
                gyro_body: v3(s.imu.gyroscope),
                accel_body: v3(s.imu.accelerometer),
            },
            joints: LegMap::from_fn(|leg| LegJointState {
                q: Vector3::from_fn(|j, _| motor(leg, j).q as f64),
                qd: Vector3::from_fn(|j, _| motor(leg, j).dq as f64),
            }),
            tau: LegMap::from_fn(|leg| Vector3::from_fn(|j, _| motor(leg, j).tau_est as f64)),
            foot_force: LegMap::from_fn(|leg| s.foot_force[order.slot(leg)]),
        }
    }

    /// Finite everywhere (a datagram with a good CRC can still carry a NaN).
    pub fn is_finite(&self) -> bool {
        self.imu.r_world_body.coords.iter().all(|v| v.is_finite())
            && self.imu.gyro_body.iter().all(|v| v.is_finite())
            && self.imu.accel_body.iter().all(|v| v.is_finite())
            && Leg::ALL.iter().all(|&l| {
                self.joints[l].q.iter().all(|v| v.is_finite())
                    && self.joints[l].qd.iter().all(|v| v.is_finite())
                    && self.tau[l].iter().all(|v| v.is_finite())
            })
    }

    /// What the safety layer reads, stamped with the time it arrived (the runner's clock).
    pub fn measured(&self, received_s: f64) -> MeasuredJoints {
        MeasuredJoints {
            time_s: received_s,
            q: self.joints.map(|_, j| j.q),
            dq: self.joints.map(|_, j| j.qd),
            tau: self.tau,
        }
    }
}

/// The command datagram for the 12 joints (the other 8 motors idle).
pub fn low_cmd(cmd: &RobotCommand, order: &MotorOrder) -> LowCmd {
    let mut out = LowCmd::default();
    for leg in Leg::ALL {
        for j in 0..3 {
            let c = cmd[leg][j];
            out.motors[order.index(leg, j)] = MotorCmd {
                mode: MODE_SERVO,
                q: if c.kp > 0.0 { c.q as f32 } else { POS_STOP },
                dq: if c.kd > 0.0 { c.dq as f32 } else { VEL_STOP },
                tau: c.tau as f32,
                kp: c.kp as f32,
                kd: c.kd as f32,
            };
        }
    }
    out
}

/// Joint commands that send `tau` as feed-forward torques, no motor-side PD.
pub fn torque_command(tau: &LegMap<Vector3<f64>>) -> RobotCommand {
    LegMap::from_fn(|leg| {
        [0, 1, 2].map(|j| JointCommand {
            tau: tau[leg][j],
            ..Default::default()
        })
    })
}

/// The torque a motor applies for `cmd` at position `q` and velocity `dq`:
/// τ_ff + K_p (q* − q) + K_d (q̇* − q̇), a stop value dropping its term, clamped to ±`limit_nm`;
/// 0 when the motor is off.
pub fn motor_torque(cmd: &MotorCmd, q: f64, dq: f64, limit_nm: f64) -> f64 {
    if cmd.mode != MODE_SERVO {
        return 0.0;
    }
    let mut tau = cmd.tau as f64;
    if cmd.q != POS_STOP {
        tau += cmd.kp as f64 * (cmd.q as f64 - q);
    }
    if cmd.dq != VEL_STOP {
        tau += cmd.kd as f64 * (cmd.dq as f64 - dq);
    } else {
        tau -= cmd.kd as f64 * dq;
    }
    if tau.is_finite() {
        tau.clamp(-limit_nm, limit_nm)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_motor_law_drops_stopped_terms_and_clamps() {
        let m = MotorCmd {
            mode: MODE_SERVO,
            q: 1.0,
            dq: 0.5,
            tau: 2.0,
            kp: 10.0,
            kd: 2.0,
        };
        assert!((motor_torque(&m, 0.8, 0.0, 33.5) - (2.0 + 2.0 + 1.0)).abs() < 1e-6);
        let stopped = MotorCmd {
            q: POS_STOP,
            dq: VEL_STOP,
            ..m
        };
        // Damping mode: Kd with VelStop damps towards rest.
        assert!((motor_torque(&stopped, 0.8, 1.0, 33.5) - (2.0 - 2.0)).abs() < 1e-6);
        assert_eq!(
            motor_torque(
                &MotorCmd {
                    tau: 99.0,
                    ..stopped
                },
                0.0,
                0.0,
                33.5
            ),
            33.5
        );
        assert_eq!(
            motor_torque(&MotorCmd { mode: 0, ..m }, 0.0, 0.0, 33.5),
            0.0
        );
    }

    #[test]
    fn a_command_round_trips_through_the_wire_format() {
        let mut cmd = torque_command(&LegMap::from_fn(|l| {
            Vector3::repeat(l.index() as f64 - 1.5)
        }));
        cmd[Leg::RearLeft][1] = JointCommand {
            q: 0.9,
            dq: 0.0,
            kp: 40.0,
            kd: 1.0,
            tau: 0.5,
        };
        let order = crate::robot::MotorOrder::unitree();
        let wire = low_cmd(&cmd, &order).encode().unwrap();
        let back = LowCmd::decode(&wire).unwrap();
        for leg in Leg::ALL {
            for j in 0..3 {
                let m = back.motors[order.index(leg, j)];
                let c = cmd[leg][j];
                // The torque law the motor applies equals the one asked for, to the wire's
                // fixed-point resolution (1/256 N·m, 1/32 and 1/16 for the gains).
                let want = c.tau + c.kp * (c.q - 0.7) + c.kd * (c.dq - 0.2);
                assert!(
                    (motor_torque(&m, 0.7, 0.2, 33.5) - want).abs() < 0.01,
                    "{leg:?} {j}"
                );
            }
        }
        for m in &back.motors[12..] {
            assert_eq!(motor_torque(m, 0.3, 0.3, 33.5), 0.0);
        }
    }
}
