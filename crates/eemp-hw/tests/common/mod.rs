//! The hardware path end to end on loopback, shared by the A1 (UDP) and Go2 (DDS) tests:
//! `run_hw` (KF, EEMP, safety layer) against the simulated robot (`run_sim_robot`), both in
//! real time, with faults injected on either side. Each test binary runs its cases one after
//! another (each needs both cores in real time; cargo runs test binaries one at a time).

use eemp_core::estimator::KfConfig;
use eemp_core::planner::params_table::ParamsTable;
use eemp_core::planner::{Gait, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_core::safety::SafetyConfig;
use eemp_hw::link::Faults;
use eemp_hw::runner::{run_hw, HwOptions, HwReport, TorqueSpike, Transport};
use eemp_hw::sim_robot::{run_sim_robot, RobotWire, SimRobotOptions, SimRobotReport};
use eemp_sim::walk::{eemp_controller, StartPose, WalkSpec};
use std::path::Path;
use std::sync::atomic::AtomicBool;

pub const SPEED: f64 = 0.3;

pub fn repo_path(rel: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

/// The trot at [`SPEED`] with the robot's shipped table.
pub fn spec(robot: &RobotConfig, duration_s: f64) -> WalkSpec {
    let mut spec = WalkSpec::constant(
        PlannerConfig {
            gait: Gait::Trot,
            ..Default::default()
        },
        PlannerParams::default(),
        VelocityCommand {
            vx_mps: SPEED,
            ..Default::default()
        },
        duration_s,
    );
    let table = repo_path(&format!("tables/{}_trot.toml", robot.name));
    spec.params_table = Some(ParamsTable::load(&table).unwrap());
    spec
}

pub struct Case {
    pub name: &'static str,
    pub duration_s: f64,
    pub state_faults: Faults,
    pub command_faults: Faults,
    pub freeze_after_s: Option<f64>,
    pub spike: Option<TorqueSpike>,
}

/// The two ends of one case's wire: the robot's (with the state faults) and the runner's
/// transport (with the command faults).
pub type Wires = (RobotWire, Transport);

pub fn run(robot: &RobotConfig, case: &Case, wires: Wires) -> (SimRobotReport, HwReport) {
    let spec = spec(robot, case.duration_s);
    let start = StartPose::eemp(robot, &spec).unwrap();
    let (sim_wire, transport) = wires;
    let stop = AtomicBool::new(false);
    let sim_opts = SimRobotOptions {
        // Longer than the controller runs: the robot outlives its driver (and the time a
        // motion-switcher release takes before the runner starts).
        duration_s: case.duration_s + 0.5,
        state_period_s: 0.002,
        freeze_after_s: case.freeze_after_s,
        start,
    };
    // Stops the simulated robot even when the controller side panics (else the scope waits).
    struct StopOnDrop<'a>(&'a AtomicBool);
    impl Drop for StopOnDrop<'_> {
        fn drop(&mut self) {
            self.0.store(true, std::sync::atomic::Ordering::Relaxed);
        }
    }
    std::thread::scope(|s| {
        let sim = s.spawn(|| run_sim_robot(robot, &sim_opts, sim_wire, &stop).unwrap());
        let _guard = StopOnDrop(&stop);
        let mut controller = eemp_controller(robot, &spec).unwrap();
        let opts = HwOptions {
            transport,
            rate_hz: 500.0,
            duration_s: case.duration_s,
            safety: SafetyConfig {
                soft_start_s: 0.5,
                ..Default::default()
            },
            kf: KfConfig::default(),
            torque_spike: case.spike,
        };
        let cmd = spec.profile.clone();
        let hw = run_hw(
            robot,
            &mut controller,
            &|t| cmd.command_at(t),
            &opts,
            &mut |_| {},
        )
        .unwrap();
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        (sim.join().unwrap(), hw)
    })
}

/// What every case must show: no fall, tracking and progress; for a frozen state stream,
/// damping within the watchdog time of the last state.
pub fn check(case: &Case, sim: &SimRobotReport, hw: &HwReport) {
    eprintln!(
        "{}: sim: {} steps, {} commands, {} bad, {} ignored, {} late steps, fell {:?}, {:?}",
        case.name,
        sim.steps,
        sim.commands,
        sim.bad_datagrams,
        sim.ignored_commands,
        sim.late_steps,
        sim.fell_at_s,
        sim.link
    );
    eprintln!("{}: hw {hw:?}", case.name);
    let sim_rmse = sim.vel_rmse_mps(SPEED, 2.0, case.duration_s);
    eprintln!(
        "{}: velocity RMSE over [2 s, end] {sim_rmse:?} m/s, x at the end {:?} m",
        case.name,
        sim.truth.last().map(|t| t.p_world[0])
    );
    match case.freeze_after_s {
        None => {
            assert_eq!(sim.fell_at_s, None, "{}: fell", case.name);
            let rmse = sim_rmse.unwrap();
            assert!(rmse < 0.12, "{}: velocity RMSE {rmse}", case.name);
            let x = sim.truth.last().unwrap().p_world[0];
            assert!(
                x > SPEED * (case.duration_s - 1.5) * 0.7,
                "{}: walked {x} m",
                case.name
            );
            assert!(hw.states > 100 && sim.commands > 100, "{}", case.name);
            // The battery's account from the robot's own torque estimates and velocities: the
            // drives' power over the run at least holds the robot up (tens of watts), and the
            // idle power is on top.
            let e = hw
                .electrical
                .as_ref()
                .expect("the robot file has a motor model");
            let (battery, drives) = (e.mean_power_w.unwrap(), e.mean_motor_power_w.unwrap());
            assert!(
                drives > 10.0 && drives < 500.0,
                "{}: drives {drives} W",
                case.name
            );
            assert!((battery - drives - e.idle_power_w).abs() < 1e-9);
            assert!(hw.electrical_note.is_none());
        }
        Some(freeze) => {
            // States stop at `freeze` (robot time ≈ runner time here): damping is sent within
            // the watchdog time of the last state (the command it replaces would have stayed
            // in force until the next cycle).
            let last = hw.last_state_s.unwrap();
            let first = hw.watchdog_after_last_state_s.expect("watchdog");
            assert!(
                first > last,
                "damping at {first} s before the last state at {last} s"
            );
            let watchdog = SafetyConfig::default().watchdog_s;
            assert!(
                first - last <= watchdog + 1e-3,
                "damping {:.4} s after the last state (watchdog {watchdog} s)",
                first - last
            );
            assert!(
                last > freeze - 0.3 && last < freeze + 0.3,
                "last state at {last}"
            );
        }
    }
    let clamped = hw.interventions.get("torque_clamped").copied().unwrap_or(0);
    if case.spike.is_none()
        && case.freeze_after_s.is_none()
        && case.state_faults == Faults::default()
    {
        // EEMP alone never asks for more than the motors give here: a clamp in the spike case
        // is the spike's.
        assert_eq!(clamped, 0, "{}: clean run clamped torques", case.name);
    }
    if case.spike.is_some() {
        assert!(clamped >= 1, "the spike was not clamped");
    }
}

impl Case {
    /// Whether either side damages what it sends.
    pub fn corrupt(&self) -> bool {
        self.state_faults.corrupt_prob > 0.0 || self.command_faults.corrupt_prob > 0.0
    }
}
