//! Between the protocol's datagrams and the project's types: what a state datagram says about
//! the robot (IMU, joints, motor torques, foot sensors), the command datagram for the safety
//! layer's joint commands, and the motor law the motors apply to a command; for the A1's UDP
//! datagrams and the Go2's DDS messages alike.

use super::a1_protocol::{LowCmd, LowState, MotorCmd, MODE_SERVO, POS_STOP, VEL_STOP};
use super::go2_idl;
use eemp_core::body_state::LegJointState;
use eemp_core::estimator::ImuReading;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::robot::MotorOrder;
use eemp_core::safety::{JointCommand, MeasuredJoints, RobotCommand};
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

    /// The same from a Go2 `LowState_` (`order`: the robot file's `[sdk] leg_order`, FR 0–2,
    /// FL 3–5, RR 6–8, RL 9–11 in unitree_sdk2). `tick_s` reads the tick as ms (the Go1's unit;
    /// the Go2's is undocumented and unitree_mujoco leaves it 0), so a caller should not make
    /// it the filter's clock.
    pub fn from_go2_low_state(s: &go2_idl::LowState, order: &MotorOrder) -> Self {
        let imu = &s.imu_state;
        let q = imu.quaternion.map(|v| v as f64);
        let v3 = |a: [f32; 3]| Vector3::new(a[0] as f64, a[1] as f64, a[2] as f64);
        let motor = |leg: Leg, j: usize| &s.motor_state[order.index(leg, j)];
        SensedState {
            tick_s: s.tick as f64 * 1e-3,
            imu: ImuReading {
                r_world_body: UnitQuaternion::from_quaternion(Quaternion::new(
                    q[0], q[1], q[2], q[3],
                )),
                gyro_body: v3(imu.gyroscope),
                accel_body: v3(imu.accelerometer),
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

/// The Go2 `LowCmd_` for the 12 joints, sealed with its CRC: `InitLowCmd`'s head, level
/// and idle motors (FOC mode 0x01, PosStopF / VelStopF) for motors 12–19, and a stop value
/// wherever a gain is 0, as the A1's datagram.
pub fn go2_low_cmd(cmd: &RobotCommand, order: &MotorOrder) -> go2_idl::LowCmd {
    let mut out = go2_idl::LowCmd::default();
    for leg in Leg::ALL {
        for j in 0..3 {
            let c = cmd[leg][j];
            out.motor_cmd[order.index(leg, j)] = go2_idl::MotorCmd {
                mode: go2_idl::MODE_FOC,
                q: if c.kp > 0.0 { c.q as f32 } else { POS_STOP },
                dq: if c.kd > 0.0 { c.dq as f32 } else { VEL_STOP },
                tau: c.tau as f32,
                kp: c.kp as f32,
                kd: c.kd as f32,
                reserve: [0; 3],
            };
        }
    }
    out.seal();
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
    let on = cmd.mode == MODE_SERVO;
    motor_law(
        on,
        [cmd.q, cmd.dq, cmd.tau, cmd.kp, cmd.kd],
        q,
        dq,
        limit_nm,
    )
}

/// The same law for a Go2 motor command (its FOC mode is 0x01, not the A1's 0x0A).
/// unitree_mujoco's bridge applies τ + K_p(q* − q) + K_d(q̇* − q̇) without looking at the mode
/// or the stop values; here the stop values drop their terms as on the A1, so an idle motor
/// (PosStopF with a gain left over) cannot produce a 10⁹ N·m torque before the clamp.
pub fn go2_motor_torque(cmd: &go2_idl::MotorCmd, q: f64, dq: f64, limit_nm: f64) -> f64 {
    let on = cmd.mode == go2_idl::MODE_FOC;
    motor_law(
        on,
        [cmd.q, cmd.dq, cmd.tau, cmd.kp, cmd.kd],
        q,
        dq,
        limit_nm,
    )
}

/// `[q*, q̇*, τ_ff, K_p, K_d]` applied at (`q`, `dq`).
fn motor_law(
    on: bool,
    [q_t, dq_t, tau_ff, kp, kd]: [f32; 5],
    q: f64,
    dq: f64,
    limit_nm: f64,
) -> f64 {
    if !on {
        return 0.0;
    }
    let mut tau = tau_ff as f64;
    if q_t != POS_STOP {
        tau += kp as f64 * (q_t as f64 - q);
    }
    if dq_t != VEL_STOP {
        tau += kd as f64 * (dq_t as f64 - dq);
    } else {
        tau -= kd as f64 * dq;
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
    fn a_go2_command_maps_legs_by_the_sdk_order_and_round_trips_through_cdr() {
        let mut cmd = torque_command(&LegMap::from_fn(|l| {
            Vector3::new(1.0, 2.0, 3.0) * (l.index() as f64 + 1.0)
        }));
        cmd[Leg::RearLeft][1] = JointCommand {
            q: 0.9,
            dq: 0.1,
            kp: 40.0,
            kd: 1.0,
            tau: 0.5,
        };
        // The Go2 file's order: FR, FL, RR, RL.
        let robot = eemp_core::robot::RobotConfig::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../robots/go2.toml"
        )))
        .unwrap();
        let order = robot.motor_order();
        let wire = go2_low_cmd(&cmd, &order);
        wire.check_crc().unwrap();
        assert_eq!(
            (wire.head, wire.level_flag),
            (go2_idl::HEAD, go2_idl::LEVEL_LOW)
        );
        // RL thigh is motor 10, FR calf motor 2 (τ = 3 · (FR index + 1)).
        let rl = wire.motor_cmd[10];
        assert_eq!((rl.mode, rl.q, rl.kp, rl.tau), (0x01, 0.9, 40.0, 0.5));
        let fr = Leg::FrontRight;
        assert_eq!(wire.motor_cmd[2].tau, 3.0 * (fr.index() as f32 + 1.0));
        assert_eq!(wire.motor_cmd[2].q, POS_STOP);
        assert_eq!(wire.motor_cmd[2].dq, VEL_STOP);
        for m in &wire.motor_cmd[12..] {
            assert_eq!(*m, go2_idl::MotorCmd::IDLE);
            assert_eq!(go2_motor_torque(m, 0.3, 0.3, 45.43), 0.0);
        }
        let back = go2_idl::LowCmd::from_cdr(&wire.to_cdr()).unwrap();
        back.check_crc().unwrap();
        for leg in Leg::ALL {
            for j in 0..3 {
                let c = cmd[leg][j];
                let want = c.tau + c.kp * (c.q - 0.7) + c.kd * (c.dq - 0.2);
                let got = go2_motor_torque(&back.motor_cmd[order.index(leg, j)], 0.7, 0.2, 45.43);
                assert!((got - want).abs() < 1e-5, "{leg:?} {j}: {got} vs {want}");
            }
        }
        // The A1's servo mode means nothing to a Go2 motor.
        let a1_mode = go2_idl::MotorCmd {
            mode: MODE_SERVO,
            ..rl
        };
        assert_eq!(go2_motor_torque(&a1_mode, 0.0, 0.0, 45.43), 0.0);
    }

    #[test]
    fn a_go2_state_reads_joints_by_the_sdk_order() {
        let mut s = go2_idl::LowState::default();
        s.imu_state.quaternion = [1.0, 0.0, 0.0, 0.0];
        s.imu_state.accelerometer = [0.0, 0.0, 9.81];
        for (i, m) in s.motor_state.iter_mut().enumerate() {
            m.q = i as f32;
            m.dq = -(i as f32);
            m.tau_est = 0.5 * i as f32;
        }
        s.foot_force = [10, 20, 30, 40];
        s.tick = 2500;
        let order = MotorOrder::unitree();
        let sensed = SensedState::from_go2_low_state(&s, &order);
        assert!(sensed.is_finite());
        assert_eq!(sensed.joints[Leg::FrontLeft].q, Vector3::new(3.0, 4.0, 5.0));
        assert_eq!(
            sensed.joints[Leg::RearLeft].qd,
            Vector3::new(-9.0, -10.0, -11.0)
        );
        assert_eq!(sensed.tau[Leg::RearRight][2], 4.0);
        assert_eq!(sensed.foot_force[Leg::RearRight], 30);
        assert!((sensed.tick_s - 2.5).abs() < 1e-12);
        assert!((sensed.imu.accel_body.z - 9.81).abs() < 1e-6);
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
        let order = eemp_core::robot::MotorOrder::unitree();
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
