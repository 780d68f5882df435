//! The hardware path end to end on loopback: `run_hw` (KF, EEMP, safety layer, UDP) against
//! the simulated robot (`run_sim_robot`), both in real time, with faults injected on either
//! side. One test runs the cases one after another: each needs both cores in real time.

use eemp_core::estimator::KfConfig;
use eemp_core::hardware::safety::SafetyConfig;
use eemp_core::leg::Leg;
use eemp_core::planner::params_table::ParamsTable;
use eemp_core::planner::{Gait, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_hw::link::{Faults, Link};
use eemp_hw::runner::{run_hw, HwOptions, HwReport, TorqueSpike, Transport};
use eemp_hw::sim_robot::{run_sim_robot, SimRobotOptions, SimRobotReport};
use eemp_sim::walk::{eemp_controller, StartPose, WalkSpec};
use std::net::SocketAddr;
use std::path::Path;
use std::sync::atomic::AtomicBool;

const SPEED: f64 = 0.3;

fn spec(duration_s: f64) -> WalkSpec {
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
    let table = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tables/a1_trot.toml");
    spec.params_table = Some(ParamsTable::load(&table).unwrap());
    spec
}

struct Case {
    name: &'static str,
    duration_s: f64,
    state_faults: Faults,
    command_faults: Faults,
    freeze_after_s: Option<f64>,
    spike: Option<TorqueSpike>,
}

fn run(case: &Case) -> (SimRobotReport, HwReport) {
    let robot = RobotConfig::a1();
    let spec = spec(case.duration_s);
    let start = StartPose::eemp(&robot, &spec).unwrap();
    let any: SocketAddr = "127.0.0.1:0".parse().unwrap();
    let sim_link = Link::bind(any, case.state_faults.clone()).unwrap();
    let sim_addr = sim_link.local_addr();
    let stop = AtomicBool::new(false);
    let sim_opts = SimRobotOptions {
        // A little longer than the controller runs: the robot outlives its driver.
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
        let sim = s.spawn(|| run_sim_robot(&robot, &sim_opts, sim_link, &stop).unwrap());
        let _guard = StopOnDrop(&stop);
        let mut controller = eemp_controller(&robot, &spec).unwrap();
        let opts = HwOptions {
            transport: Transport::Udp {
                robot: sim_addr,
                bind: any,
                faults: case.command_faults.clone(),
            },
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
            &robot,
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

#[test]
fn eemp_walks_the_simulated_robot_over_udp_and_survives_faults() {
    let none = Faults::default();
    let lossy = Faults {
        drop_prob: 0.05,
        seed: 3,
        ..Default::default()
    };
    let nasty = Faults {
        drop_prob: 0.02,
        corrupt_prob: 0.02,
        reorder_prob: 0.02,
        delay_s: 0.001,
        seed: 4,
    };
    let cases = [
        Case {
            name: "clean",
            duration_s: 6.0,
            state_faults: none.clone(),
            command_faults: none.clone(),
            freeze_after_s: None,
            spike: None,
        },
        Case {
            name: "5 % loss both ways",
            duration_s: 6.0,
            state_faults: lossy.clone(),
            command_faults: Faults { seed: 5, ..lossy },
            freeze_after_s: None,
            spike: None,
        },
        Case {
            name: "corrupt, reordered, delayed, a torque spike",
            duration_s: 4.0,
            state_faults: nasty.clone(),
            command_faults: Faults { seed: 6, ..nasty },
            freeze_after_s: None,
            spike: Some(TorqueSpike {
                at_s: 2.0,
                leg: Leg::FrontLeft,
                joint: 2,
                nm: 200.0,
            }),
        },
        Case {
            name: "frozen state stream",
            duration_s: 3.0,
            state_faults: none.clone(),
            command_faults: none,
            freeze_after_s: Some(2.0),
            spike: None,
        },
    ];
    for case in &cases {
        let (sim, hw) = run(case);
        eprintln!("{}: sim {sim:?}", case.name);
        eprintln!("{}: hw {hw:?}", case.name);
        let sim_rmse = sim.vel_rmse_mps(SPEED, 2.0, case.duration_s);
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
            }
            Some(freeze) => {
                // States stop at `freeze` (robot time ≈ runner time here): damping is sent
                // within the watchdog time of the last state (the command it replaces would
                // have stayed in force until the next cycle).
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
        if case.name == "clean" {
            // EEMP alone never asks for more than the motors give here: a clamp in the spike
            // case is the spike's.
            assert_eq!(clamped, 0, "clean run clamped torques");
        }
        if case.spike.is_some() {
            assert!(clamped >= 1, "the spike was not clamped");
            assert!(
                hw.bad_datagrams > 0 && sim.bad_datagrams > 0,
                "corruption seen"
            );
        }
    }
}
