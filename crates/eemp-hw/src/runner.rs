//! `eemp hw`: any [`Controller`] on an A1 through its legacy low-level UDP protocol, or on a
//! Go2 through its low-level DDS interface (`rt/lowcmd` / `rt/lowstate`, [`crate::dds`]).
//!
//! Every cycle (500 Hz by default): read the state datagrams that arrived (bad CRC or length
//! counted and dropped; a tick not newer than the last one — a late or reordered datagram —
//! dropped), show the newest to the safety layer, run the Kalman filter on it (IMU attitude,
//! leg kinematics, contact trust from the controller's plan or its torques, as in simulation:
//! [`eemp_core::estimator::ContactTrust`]), run the controller on the estimate, pass its
//! torques through the safety layer and send the command datagram. A cycle without a new state
//! re-sends the last command through the safety layer, whose watchdog turns a silent robot
//! into damping. The controller's dynamics (mass matrix and bias of each leg, for the swing
//! law) come from MuJoCo evaluated at the estimate — a model of the robot file, never stepped.

use crate::dds::{DdsConfig, Go2Endpoint, Role};
use crate::link::{Faults, Link, LinkStats};
use crate::motion_switcher;
use crate::wire::a1_protocol::LowState;
use crate::wire::go2_idl;
use crate::wire::robot_io::{go2_low_cmd, low_cmd, torque_command, SensedState};
use eemp_core::body_state::{BodyState, RobotState};
use eemp_core::controller::Controller;
use eemp_core::estimator::{KfConfig, LinearKf};
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::pipeline::{ControlPipeline, Sensed};
use eemp_core::planner::VelocityCommand;
use eemp_core::robot::RobotConfig;
use eemp_core::safety::{Damping, Intervention, RobotCommand, SafetyConfig, SafetyLayer};
use eemp_sim::backend::EvaluatedAt;
use eemp_sim::Simulation;
use nalgebra::Vector3;
use serde::Serialize;
use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::time::{Duration, Instant};

/// A torque added to one joint's command for one cycle, the first with a state at or after
/// `at_s` (fault injection: the safety layer must catch it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TorqueSpike {
    pub at_s: f64,
    pub leg: Leg,
    pub joint: usize,
    pub nm: f64,
}

/// Where commands go and states come from.
#[derive(Clone, Debug)]
pub enum Transport {
    /// UDP to the robot (or `eemp sim-robot`), with faults on the commands sent.
    Udp {
        robot: SocketAddr,
        bind: SocketAddr,
        faults: Faults,
    },
    /// DDS to a Go2 (or `eemp sim-robot --link dds`), with faults on the commands written.
    /// `release`: first ask the robot's motion-switcher service to release its sport mode
    /// (refusing to start when it cannot); None for a robot already in low-level mode.
    Dds {
        config: DdsConfig,
        faults: Faults,
        release: Option<motion_switcher::ReleaseOptions>,
    },
    /// No socket: the robot is taken to stand still in `state` (the state datagram it would
    /// send), and the commands are only shown to the observer.
    DryRun { state: Box<LowState> },
}

#[derive(Clone, Debug)]
pub struct HwOptions {
    pub transport: Transport,
    pub rate_hz: f64,
    pub duration_s: f64,
    pub safety: SafetyConfig,
    pub kf: KfConfig,
    pub torque_spike: Option<TorqueSpike>,
}

impl HwOptions {
    pub fn validate(&self) -> Result<(), String> {
        if !(50.0..=2000.0).contains(&self.rate_hz) {
            return Err(format!(
                "rate {} Hz is out of range: allowed [50, 2000]",
                self.rate_hz
            ));
        }
        if !(self.duration_s > 0.0 && self.duration_s <= 3600.0) {
            return Err(format!(
                "duration {} s is out of range: allowed (0, 3600]",
                self.duration_s
            ));
        }
        self.safety.validate().map_err(|e| e.to_string())?;
        self.kf.validate().map_err(|e| e.to_string())?;
        match &self.transport {
            Transport::Udp { faults, .. } => faults.validate("hw")?,
            Transport::Dds {
                config,
                faults,
                release,
            } => {
                faults.validate("hw")?;
                config.validate()?;
                if let Some(r) = release {
                    r.validate()?;
                }
            }
            Transport::DryRun { .. } => {}
        }
        Ok(())
    }
}

/// One cycle, for logs and traces.
pub struct HwCycle<'a> {
    /// Runner clock, s.
    pub t_s: f64,
    /// The estimate the controller acted on (None before the first state).
    pub estimate: Option<&'a RobotState>,
    pub command: VelocityCommand,
    /// What was sent.
    pub sent: &'a RobotCommand,
    pub interventions: &'a [Intervention],
    pub new_state: bool,
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct HwReport {
    pub cycles: usize,
    pub states: usize,
    pub bad_datagrams: usize,
    /// State datagrams older than one already seen (reordered or duplicated).
    pub stale_states: usize,
    /// Cycles that started more than one period late.
    pub late_cycles: usize,
    /// Interventions of the safety layer by kind.
    pub interventions: BTreeMap<String, usize>,
    /// When the watchdog first sent damping after states had arrived, runner clock, s.
    pub first_watchdog_s: Option<f64>,
    /// When the watchdog started the damping that followed the last state received (None if
    /// states kept coming to the end), runner clock, s.
    pub watchdog_after_last_state_s: Option<f64>,
    /// When the last state datagram arrived, runner clock, s.
    pub last_state_s: Option<f64>,
    pub latched: Option<String>,
    pub link: LinkStats,
    /// What the motion switcher said before the start (DDS with release).
    pub release: Option<String>,
    /// What the battery paid under the robot file's motor model over the whole run (standing
    /// included), from the robot's own torque estimates and joint velocities at each state
    /// received; the CoT's distance is the filter's estimate of the run's displacement. `None` without a `[motor]` section, with `electrical_note` saying so.
    pub electrical: Option<eemp_core::energy::ElectricalMetrics>,
    pub electrical_note: Option<&'static str>,
}

/// One vector per leg (joint velocities or torques).
type JointVectors = LegMap<nalgebra::Vector3<f64>>;

/// The runner's end of the wire.
enum Wire {
    Udp(Box<Link>, SocketAddr),
    Dds(Box<Go2Endpoint>),
    DryRun,
}

impl Wire {
    fn send(
        &mut self,
        cmd: &RobotCommand,
        order: &eemp_core::robot::MotorOrder,
        now: f64,
    ) -> Result<(), String> {
        match self {
            Wire::Udp(l, to) => {
                let bytes = low_cmd(cmd, order).encode().map_err(|e| e.to_string())?;
                l.send(&bytes, *to, now);
            }
            Wire::Dds(e) => e.send(&go2_low_cmd(cmd, order).to_cdr(), now),
            Wire::DryRun => {}
        }
        Ok(())
    }

    fn flush(&mut self, now: f64) {
        match self {
            Wire::Udp(l, _) => l.flush(now),
            Wire::Dds(e) => e.flush(now),
            Wire::DryRun => {}
        }
    }

    fn stats(&self) -> LinkStats {
        match self {
            Wire::Udp(l, _) => l.stats,
            Wire::Dds(e) => e.stats,
            Wire::DryRun => LinkStats::default(),
        }
    }
}

/// A received state, decoded by the wire's protocol: (state, tick for ordering; 0 = none).
/// A Go2 state with a CRC that does not match its contents is refused like a bad datagram.
fn decode_go2(
    bytes: &[u8],
    order: &eemp_core::robot::MotorOrder,
    now: f64,
) -> Option<(SensedState, u32)> {
    let s = go2_idl::LowState::from_cdr(bytes).ok()?;
    s.check_crc().ok()?;
    let mut sensed = SensedState::from_go2_low_state(&s, order);
    // The Go2's tick unit is undocumented (and unitree_mujoco leaves it 0): the filter runs on
    // the arrival clock instead.
    sensed.tick_s = now;
    Some((sensed, s.tick))
}

fn kind(i: &Intervention) -> &'static str {
    match i {
        Intervention::Watchdog { .. } => "watchdog",
        Intervention::EStop => "estop",
        Intervention::PowerProtect { .. } => "power_protect",
        Intervention::SoftStart { .. } => "soft_start",
        Intervention::PositionClamped { .. } => "position_clamped",
        Intervention::TorqueClamped { .. } => "torque_clamped",
        Intervention::GainClamped { .. } => "gain_clamped",
        Intervention::NonFinite => "non_finite",
    }
}

/// The estimate the filter starts from: attitude from the IMU, the trunk above its lowest
/// foot on flat ground, at rest.
fn start_state(kin: &LegKinematics, foot_radius_m: f64, s: &SensedState, t_s: f64) -> RobotState {
    let r = s.imu.r_world_body;
    let lowest = Leg::ALL
        .iter()
        .map(|&l| (r * kin.foot_position_body(l, &s.joints[l].q)).z)
        .fold(f64::INFINITY, f64::min);
    RobotState {
        time_s: t_s,
        body: BodyState {
            p_world: Vector3::new(0.0, 0.0, -lowest + foot_radius_m),
            r_world_body: r,
            v_world: Vector3::zeros(),
            omega_world: r * s.imu.gyro_body,
        },
        joints: s.joints,
    }
}

/// Runs `controller` on the robot for `opts.duration_s`; `command_at(t)` is the operator's
/// command at robot time `t` (s since the first state).
pub fn run_hw(
    robot: &RobotConfig,
    controller: &mut dyn Controller,
    command_at: &dyn Fn(f64) -> VelocityCommand,
    opts: &HwOptions,
    observer: &mut dyn FnMut(&HwCycle),
) -> Result<HwReport, String> {
    opts.validate()?;
    let kin = LegKinematics::new(robot);
    let order = robot.motor_order();
    let mut model = Simulation::new(robot, &Default::default()).map_err(|e| e.to_string())?;
    let mut safety = SafetyLayer::new(robot, opts.safety.clone()).map_err(|e| e.to_string())?;
    let mut report = HwReport::default();
    let mut energy = robot
        .motor_model()
        .map(eemp_core::energy::EnergyAccount::new);
    // (time, joint velocities, torque estimates) of the last state received.
    let mut last_state: Option<(f64, JointVectors, JointVectors)> = None;
    let (mut start_xy, mut end_xy): (Option<[f64; 2]>, [f64; 2]) = (None, [0.0; 2]);
    let mut wire = match &opts.transport {
        Transport::Udp {
            bind,
            faults,
            robot,
        } => Wire::Udp(Box::new(Link::bind(*bind, faults.clone())?), *robot),
        Transport::Dds {
            config,
            faults,
            release,
        } => {
            if let Some(r) = release {
                report.release = Some(motion_switcher::release(config, r)?);
            }
            Wire::Dds(Box::new(Go2Endpoint::new(
                config,
                Role::Controller,
                faults.clone(),
            )?))
        }
        Transport::DryRun { .. } => Wire::DryRun,
    };
    let period = 1.0 / opts.rate_hz;
    let wall0 = Instant::now();
    // Estimate → controller, as in simulation; the filter starts at the first state.
    let mut pipeline = ControlPipeline::new(0.0, robot.scale());
    let mut started = false;
    let mut newest_tick: Option<u32> = None;
    let mut first_tick_s = 0.0;
    let mut estimate: Option<RobotState> = None;
    let mut cmd = torque_command(&LegMap::splat(Vector3::zeros()));
    let mut vel_cmd = VelocityCommand::default();
    let mut cycle = 0usize;
    let mut spiked = false;
    loop {
        let now = wall0.elapsed().as_secs_f64();
        if now >= opts.duration_s {
            break;
        }
        // The newest state that arrived since the last cycle.
        let mut newest: Option<SensedState> = None;
        let mut take = |decoded: Option<(SensedState, u32)>, report: &mut HwReport| {
            let Some((sensed, tick)) = decoded else {
                report.bad_datagrams += 1;
                return;
            };
            // Newer in wrap-around arithmetic (the A1's µs tick wraps after 71.6 min); a jump
            // back by more than half the range is a restart of the robot's clock, taken as new.
            // A Go2 tick of 0 (unitree_mujoco) says nothing about order.
            if tick != 0
                && newest_tick.is_some_and(|t| {
                    let d = tick.wrapping_sub(t) as i32;
                    d <= 0 && d > -1_000_000
                })
            {
                report.stale_states += 1;
                return;
            }
            if !sensed.is_finite() {
                report.bad_datagrams += 1;
                return;
            }
            if tick != 0 {
                newest_tick = Some(tick);
            }
            report.states += 1;
            newest = Some(sensed);
        };
        let a1 = |bytes: &[u8]| {
            LowState::decode(bytes)
                .ok()
                .map(|s| (SensedState::from_low_state(&s, &order), s.tick))
        };
        match (&mut wire, &opts.transport) {
            (Wire::Udp(l, _), _) => {
                while let Some((bytes, _)) = l.recv() {
                    take(a1(&bytes), &mut report);
                }
            }
            (Wire::Dds(e), _) => {
                while let Some(bytes) = e.recv() {
                    take(decode_go2(&bytes, &order, now), &mut report);
                }
            }
            (Wire::DryRun, Transport::DryRun { state }) => {
                let mut s = (**state).clone();
                s.tick = (now * 1e6) as u32 + 1;
                let bytes = s.encode().map_err(|e| e.to_string())?;
                take(a1(&bytes), &mut report);
            }
            (Wire::DryRun, _) => unreachable!("only a dry run has no wire"),
        }
        let fresh = newest.is_some();
        let mut spike_now: Option<TorqueSpike> = None;
        if let Some(sensed) = newest {
            report.last_state_s = Some(now);
            safety.observe(sensed.measured(now));
            if !started {
                first_tick_s = sensed.tick_s;
            }
            let t = sensed.tick_s - first_tick_s;
            // The time since the last state is charged at that state's torques and velocities
            // (what the robot held over it).
            let qd = sensed.joints.map(|_, j| j.qd);
            if let (Some(e), Some((prev_t, prev_qd, prev_tau))) = (energy.as_mut(), &last_state) {
                e.observe((t - prev_t).max(0.0), prev_qd, prev_tau);
            }
            last_state = Some((t, qd, sensed.tau));
            if !started {
                let start = start_state(&kin, robot.leg.foot_radius_m, &sensed, t);
                pipeline.set_filter(Some(
                    LinearKf::new(opts.kf.clone(), kin.clone(), &start)
                        .map_err(|e| e.to_string())?,
                ));
                pipeline.restart(t);
                started = true;
            }
            let seen = RobotState {
                time_s: t,
                body: BodyState {
                    r_world_body: sensed.imu.r_world_body,
                    ..estimate.map(|e| e.body).unwrap_or_else(|| {
                        start_state(&kin, robot.leg.foot_radius_m, &sensed, t).body
                    })
                },
                joints: sensed.joints,
            };
            vel_cmd = command_at(t);
            let update = pipeline.update(
                &Sensed {
                    seen,
                    imu: Some(sensed.imu),
                },
                &kin,
                controller,
                vel_cmd,
                &mut EvaluatedAt(&mut model),
            );
            let est = update.estimate;
            cmd = torque_command(&update.output.torques);
            if let Some(sp) = opts.torque_spike {
                // Once, at the first controller step at or after its time (states can be lost).
                if !spiked && t >= sp.at_s {
                    spike_now = Some(sp);
                    spiked = true;
                }
            }
            let xy = [est.body.p_world.x, est.body.p_world.y];
            start_xy.get_or_insert(xy);
            end_xy = xy;
            estimate = Some(est);
        }
        // The command sent now stays in force until the next cycle: the watchdog judges the
        // state's age at that time, so no command rests on a state older than `watchdog_s`.
        // The spike goes out in this cycle only (a cycle without a state re-sends `cmd`).
        let mut asked = cmd;
        if let Some(sp) = spike_now {
            asked[sp.leg][sp.joint].tau += sp.nm;
        }
        let (sent, log) = safety.filter(now + period, &asked);
        if fresh {
            report.watchdog_after_last_state_s = None;
        }
        for i in &log {
            *report.interventions.entry(kind(i).into()).or_default() += 1;
            if matches!(i, Intervention::Watchdog { silent_s } if silent_s.is_finite())
                && report.watchdog_after_last_state_s.is_none()
            {
                report.watchdog_after_last_state_s = Some(now);
            }
            if matches!(i, Intervention::Watchdog { silent_s } if silent_s.is_finite())
                && report.first_watchdog_s.is_none()
            {
                report.first_watchdog_s = Some(now);
            }
        }
        wire.send(&sent, &order, now)?;
        observer(&HwCycle {
            t_s: now,
            estimate: estimate.as_ref(),
            command: vel_cmd,
            sent: &sent,
            interventions: &log,
            new_state: fresh,
        });
        cycle += 1;
        report.cycles = cycle;
        let next = cycle as f64 * period;
        let wait = next - wall0.elapsed().as_secs_f64();
        if wait > 0.0 {
            std::thread::sleep(Duration::from_secs_f64(wait));
        } else if wait < -period {
            report.late_cycles += 1;
        }
    }
    report.latched = safety.damping().map(|d| match d {
        Damping::EStop => "estop".into(),
        Damping::PowerProtect => "power_protect".into(),
    });
    // Leaving: the motors keep the last command they got, so the last ones are damping.
    safety.estop();
    let (damp, _) = safety.filter(wall0.elapsed().as_secs_f64(), &cmd);
    for _ in 0..5 {
        let now = wall0.elapsed().as_secs_f64();
        wire.send(&damp, &order, now)?;
        wire.flush(now + 1.0);
        std::thread::sleep(Duration::from_millis(1));
    }
    report.link = wire.stats();
    let travelled_m = start_xy
        .map(|a| (end_xy[0] - a[0]).hypot(end_xy[1] - a[1]))
        .filter(|d| *d >= eemp_core::metrics::MIN_COT_DISTANCE_M);
    report.electrical = energy.map(|e| {
        e.finish(
            robot.total_mass_kg() * eemp_core::convex_mpc::model::GRAVITY,
            travelled_m,
        )
    });
    report.electrical_note = report
        .electrical
        .is_none()
        .then_some(eemp_core::energy::NO_MOTOR_MODEL_NOTE);
    Ok(report)
}
