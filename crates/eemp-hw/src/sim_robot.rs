//! `eemp sim-robot`: a MuJoCo robot on loopback that behaves, for its low-level interface, as
//! the robot does: the A1's UDP datagrams, or the Go2's DDS topics (`rt/lowcmd`,
//! `rt/lowstate`) with its motion-switcher service.
//!
//! Every physics step (the robot file's 1 ms) it reads the commands that arrived (bad CRC or
//! length: counted and ignored, as the robot's board does), applies the latest one with the
//! motor law τ_ff + K_p(q* − q) + K_d(q̇* − q̇) clamped to the robot file's per-joint limit (no
//! command yet: motors off), and every `state_period_s` sends a state — IMU, joints, torque
//! estimates, foot force sensors, tick — (UDP: to whoever sent the last command). It runs in
//! real time (the controller on the other side has a real clock) and starts standing in a pose
//! you choose, when the first command arrives. A simulated Go2 starts in sport mode, as one
//! switched on: its motors ignore low-level commands until the motion switcher releases them.

use crate::dds::{DdsConfig, Go2Endpoint, Role};
use crate::link::{Faults, Link, LinkStats};
use crate::motion_switcher::ModeServer;
use crate::wire::a1_protocol::{LowCmd, LowState, MotorCmd, MotorState, MOTORS};
use crate::wire::go2_idl;
use crate::wire::robot_io::{go2_motor_torque, motor_torque};
use eemp_core::leg::{Leg, LegMap};
use eemp_core::robot::MotorOrder;
use eemp_core::robot::RobotConfig;
use eemp_sim::closed_loop::FallLimits;
use eemp_sim::walk::StartPose;
use eemp_sim::Simulation;
use nalgebra::Vector3;
use serde::Serialize;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

#[derive(Clone, Debug)]
pub struct SimRobotOptions {
    /// Stop after this much simulated time, s (the robot "switches off").
    pub duration_s: f64,
    pub state_period_s: f64,
    /// Stop sending states after this time (a frozen state stream), s.
    pub freeze_after_s: Option<f64>,
    pub start: StartPose,
}

/// One sample of the simulated robot's true state (10 ms apart).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct TruthSample {
    pub t_s: f64,
    pub p_world: [f64; 3],
    pub v_world: [f64; 3],
    pub yaw_rate_rps: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct SimRobotReport {
    pub steps: usize,
    pub commands: usize,
    pub bad_datagrams: usize,
    /// Go2: well-formed commands that arrived while a motion-control mode held the motors.
    pub ignored_commands: usize,
    /// Physics steps that ran later than real time by more than 5 ms.
    pub late_steps: usize,
    pub fell_at_s: Option<f64>,
    pub link: LinkStats,
    pub truth: Vec<TruthSample>,
}

impl SimRobotReport {
    /// Velocity RMSE against a constant forward command over `[t0, t1]`, m/s (heading frame:
    /// the trunk's yaw is small on these straight runs, world axes are used).
    pub fn vel_rmse_mps(&self, vx_mps: f64, t0: f64, t1: f64) -> Option<f64> {
        let s: Vec<f64> = self
            .truth
            .iter()
            .filter(|r| r.t_s >= t0 && r.t_s <= t1)
            .map(|r| {
                let (vx, vy) = (r.v_world[0], r.v_world[1]);
                let speed = vx.hypot(vy);
                (speed - vx_mps).powi(2)
            })
            .collect();
        (!s.is_empty()).then(|| (s.iter().sum::<f64>() / s.len() as f64).sqrt())
    }
}

/// A state datagram of the simulation's current state (after `prepare_kinematics`).
fn low_state(
    sim: &Simulation,
    order: &MotorOrder,
    tau: &LegMap<Vector3<f64>>,
    tick: u32,
) -> LowState {
    let imu = sim.imu();
    let s = sim.ground_truth_state();
    let q = imu.r_world_body.coords;
    let (roll, pitch, yaw) = imu.r_world_body.euler_angles();
    let mut out = LowState {
        tick,
        ..Default::default()
    };
    out.imu.quaternion = [q.w as f32, q.x as f32, q.y as f32, q.z as f32];
    out.imu.gyroscope = imu.gyro_body.map(|v| v as f32).into();
    out.imu.accelerometer = imu.accel_body.map(|v| v as f32).into();
    out.imu.rpy = [roll as f32, pitch as f32, yaw as f32];
    let forces = sim.foot_normal_forces_n();
    for leg in Leg::ALL {
        for j in 0..3 {
            out.motors[order.index(leg, j)] = MotorState {
                mode: crate::wire::a1_protocol::MODE_SERVO,
                q: s.joints[leg].q[j] as f32,
                dq: s.joints[leg].qd[j] as f32,
                tau_est: tau[leg][j] as f32,
                q_raw: s.joints[leg].q[j] as f32,
                dq_raw: s.joints[leg].qd[j] as f32,
                ..Default::default()
            };
        }
        out.foot_force[order.slot(leg)] = forces[leg].round().clamp(0.0, 32767.0) as i16;
    }
    out
}

/// The same state as the Go2's `LowState_`, sealed with its CRC (`tick` in ms).
fn go2_low_state(
    sim: &Simulation,
    order: &MotorOrder,
    tau: &LegMap<Vector3<f64>>,
    tick: u32,
) -> go2_idl::LowState {
    let a1 = low_state(sim, order, tau, tick);
    let mut out = go2_idl::LowState {
        tick,
        ..Default::default()
    };
    let imu = &mut out.imu_state;
    imu.quaternion = a1.imu.quaternion;
    imu.gyroscope = a1.imu.gyroscope;
    imu.accelerometer = a1.imu.accelerometer;
    imu.rpy = a1.imu.rpy;
    for (i, m) in a1.motors.iter().enumerate() {
        out.motor_state[i] = go2_idl::MotorState {
            mode: go2_idl::MODE_FOC,
            q: m.q,
            dq: m.dq,
            tau_est: m.tau_est,
            q_raw: m.q_raw,
            dq_raw: m.dq_raw,
            ..Default::default()
        };
    }
    out.foot_force = a1.foot_force;
    out.seal();
    out
}

/// The motor commands in force.
enum Motors {
    A1(Box<[MotorCmd; MOTORS]>),
    Go2(Box<[go2_idl::MotorCmd; go2_idl::MOTORS]>),
}

impl Motors {
    fn torque(&self, motor: usize, q: f64, dq: f64, limit_nm: f64) -> f64 {
        match self {
            Motors::A1(m) => motor_torque(&m[motor], q, dq, limit_nm),
            Motors::Go2(m) => go2_motor_torque(&m[motor], q, dq, limit_nm),
        }
    }
}

/// The simulated robot's end of the wire.
pub enum RobotWire {
    /// The A1's datagrams; states go to whoever sent the last command.
    Udp {
        link: Box<Link>,
        peer: Option<SocketAddr>,
    },
    /// The Go2's topics, and its motion-switcher service when `modes` is set (None: a robot
    /// already in low-level mode). Fields drop in order: the service before the participant
    /// it lives on.
    Dds {
        modes: Option<Box<ModeServer>>,
        endpoint: Box<Go2Endpoint>,
    },
}

impl RobotWire {
    pub fn udp(link: Link) -> Self {
        RobotWire::Udp {
            link: Box::new(link),
            peer: None,
        }
    }

    /// The Go2 on `cfg`, with `faults` on the states it sends; `sport_mode`: starts with
    /// "normal" (sport mode) holding the motors, as a Go2 switched on.
    pub fn dds(cfg: &DdsConfig, faults: Faults, sport_mode: bool) -> Result<Self, String> {
        let endpoint = Go2Endpoint::new(cfg, Role::Robot, faults)?;
        let modes = if sport_mode {
            Some(Box::new(ModeServer::new(endpoint.participant(), "normal")?))
        } else {
            None
        };
        Ok(RobotWire::Dds {
            endpoint: Box::new(endpoint),
            modes,
        })
    }

    /// Where it listens, for the user.
    pub fn describe(&self) -> String {
        match self {
            RobotWire::Udp { link, .. } => format!("UDP {}", link.local_addr()),
            RobotWire::Dds { endpoint, modes } => format!(
                "DDS {}{}",
                endpoint.describe(),
                if modes.is_some() {
                    ", sport mode on (release it through motion_switcher)"
                } else {
                    ", low-level mode"
                }
            ),
        }
    }

    /// The newest well-formed command among those that arrived (never blocks).
    fn recv(&mut self, report: &mut SimRobotReport) -> Option<Motors> {
        let mut newest = None;
        match self {
            RobotWire::Udp { link, peer } => {
                while let Some((bytes, from)) = link.recv() {
                    match LowCmd::decode(&bytes) {
                        Ok(c) => {
                            newest = Some(Motors::A1(Box::new(c.motors)));
                            *peer = Some(from);
                            report.commands += 1;
                        }
                        Err(_) => report.bad_datagrams += 1,
                    }
                }
            }
            RobotWire::Dds { endpoint, modes } => {
                if let Some(m) = modes.as_mut() {
                    m.serve();
                }
                while let Some(bytes) = endpoint.recv() {
                    let cmd = go2_idl::LowCmd::from_cdr(&bytes)
                        .ok()
                        .filter(|c| c.check_crc().is_ok());
                    match cmd {
                        None => report.bad_datagrams += 1,
                        Some(_) if modes.as_ref().is_some_and(|m| !m.released()) => {
                            report.ignored_commands += 1
                        }
                        Some(c) => {
                            newest = Some(Motors::Go2(Box::new(c.motor_cmd)));
                            report.commands += 1;
                        }
                    }
                }
            }
        }
        newest
    }

    /// Sends the current state (after `prepare_kinematics`) at `now` (wall clock, s).
    fn send_state(
        &mut self,
        sim: &Simulation,
        order: &MotorOrder,
        tau: &LegMap<Vector3<f64>>,
        now: f64,
    ) -> Result<(), String> {
        match self {
            RobotWire::Udp { link, peer } => {
                if let Some(to) = *peer {
                    let tick = (sim.time_s() * 1e6).round() as u32;
                    let bytes = low_state(sim, order, tau, tick)
                        .encode()
                        .map_err(|e| e.to_string())?;
                    link.send(&bytes, to, now);
                }
            }
            RobotWire::Dds { endpoint, .. } => {
                // A ms tick counting from 1 (0 means "no tick" to the runner).
                let tick = (sim.time_s() * 1e3).round() as u32 + 1;
                endpoint.send(&go2_low_state(sim, order, tau, tick).to_cdr(), now);
            }
        }
        Ok(())
    }

    fn flush(&mut self, now: f64) {
        match self {
            RobotWire::Udp { link, .. } => link.flush(now),
            RobotWire::Dds { endpoint, modes } => {
                if let Some(m) = modes.as_mut() {
                    m.serve();
                }
                endpoint.flush(now);
            }
        }
    }

    fn stats(&self) -> LinkStats {
        match self {
            RobotWire::Udp { link, .. } => link.stats,
            RobotWire::Dds { endpoint, .. } => endpoint.stats,
        }
    }
}

/// Runs the simulated robot on `wire` (made by the caller, with the faults of the states it
/// sends) until `duration_s` or until `stop` is set.
pub fn run_sim_robot(
    robot: &RobotConfig,
    opts: &SimRobotOptions,
    mut wire: RobotWire,
    stop: &AtomicBool,
) -> Result<SimRobotReport, String> {
    let order = robot.motor_order();
    let mut sim = Simulation::new(robot, &Default::default()).map_err(|e| e.to_string())?;
    sim.reset(
        Vector3::new(0.0, 0.0, opts.start.trunk_height_m + 0.002),
        &opts.start.joints,
    );
    let dt = sim.timestep_s();
    let limits = FallLimits::for_size(&robot.scale());
    let mut report = SimRobotReport {
        steps: 0,
        commands: 0,
        bad_datagrams: 0,
        ignored_commands: 0,
        late_steps: 0,
        fell_at_s: None,
        link: LinkStats::default(),
        truth: Vec::new(),
    };
    let state_every = (opts.state_period_s / dt).round().max(1.0) as usize;
    // The robot is put down in its start pose when the controller first speaks: until the
    // first command, time stands still (states are not sent either; the SDK's robot answers
    // only once commanded).
    let mut motors: Option<Motors> = None;
    while motors.is_none() && !stop.load(Ordering::Relaxed) {
        motors = wire.recv(&mut report);
        if motors.is_none() {
            wire.flush(0.0);
            std::thread::sleep(Duration::from_micros(200));
        }
    }
    let wall0 = Instant::now();
    while sim.time_s() < opts.duration_s && !stop.load(Ordering::Relaxed) {
        let now = wall0.elapsed().as_secs_f64();
        if let Some(m) = wire.recv(&mut report) {
            motors = Some(m);
        }
        sim.prepare_kinematics();
        let state = sim.ground_truth_state();
        let tau = LegMap::from_fn(|leg| {
            Vector3::from_fn(|j, _| match &motors {
                Some(m) => m.torque(
                    order.index(leg, j),
                    state.joints[leg].q[j],
                    state.joints[leg].qd[j],
                    robot.leg.torque_limit_nm[j],
                ),
                None => 0.0,
            })
        });
        let frozen = opts.freeze_after_s.is_some_and(|t| sim.time_s() >= t);
        if report.steps.is_multiple_of(state_every) && !frozen {
            wire.send_state(&sim, &order, &tau, now)?;
        }
        wire.flush(now);
        if report.steps.is_multiple_of(10) {
            let b = state.body;
            report.truth.push(TruthSample {
                t_s: state.time_s,
                p_world: b.p_world.into(),
                v_world: b.v_world.into(),
                yaw_rate_rps: b.omega_world.z,
            });
        }
        if report.fell_at_s.is_none() && (limits.fallen(&state) || sim.trunk_contact()) {
            report.fell_at_s = Some(state.time_s);
        }
        sim.advance(&tau);
        report.steps += 1;
        // Real time: wait for the wall clock to catch up with the simulation.
        let ahead = sim.time_s() - wall0.elapsed().as_secs_f64();
        if ahead > 0.0 {
            std::thread::sleep(Duration::from_secs_f64(ahead));
        } else if ahead < -0.005 {
            report.late_steps += 1;
        }
    }
    report.link = wire.stats();
    Ok(report)
}
