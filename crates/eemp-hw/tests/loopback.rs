//! The A1's hardware path end to end on loopback over UDP (see `common`): EEMP walks the
//! simulated A1 and survives loss, corruption, reordering, delay, a torque spike and a frozen
//! state stream.

mod common;

use common::{check, run, Case, Wires};
use eemp_core::leg::Leg;
use eemp_core::robot::RobotConfig;
use eemp_hw::link::{Faults, Link};
use eemp_hw::runner::{TorqueSpike, Transport};
use eemp_hw::sim_robot::RobotWire;
use std::net::SocketAddr;

fn udp(case: &Case) -> Wires {
    let any: SocketAddr = "127.0.0.1:0".parse().unwrap();
    let sim_link = Link::bind(any, case.state_faults.clone()).unwrap();
    let transport = Transport::Udp {
        robot: sim_link.local_addr(),
        bind: any,
        faults: case.command_faults.clone(),
    };
    (RobotWire::udp(sim_link), transport)
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
    let robot = RobotConfig::a1();
    for case in &cases {
        let (sim, hw) = run(&robot, case, udp(case));
        check(case, &sim, &hw);
        if case.corrupt() {
            assert!(
                hw.bad_datagrams > 0 && sim.bad_datagrams > 0,
                "{}: corruption not seen",
                case.name
            );
        }
    }
}
