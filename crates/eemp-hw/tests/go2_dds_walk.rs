//! The Go2's hardware path end to end on loopback over DDS (see `common`): `run_hw` with
//! `Transport::Dds` releases the simulated Go2's sport mode through its motion switcher, walks
//! it 20 s at 0.3 m/s with its shipped table, and survives 5 % loss, corruption and
//! reordering, and a frozen state stream. Each case has its own test domain (81–84) so that a
//! case's late samples cannot reach the next; none is 0 or 1 (a robot, Unitree's simulator).

mod common;

use common::{check, run, Case, Wires};
use eemp_core::robot::RobotConfig;
use eemp_hw::dds::DdsConfig;
use eemp_hw::link::Faults;
use eemp_hw::motion_switcher::ReleaseOptions;
use eemp_hw::runner::Transport;
use eemp_hw::sim_robot::RobotWire;

/// Both ends on `domain` over loopback; `sport_mode`: the robot starts in sport mode and the
/// runner releases it first.
fn dds(case: &Case, domain: u16, sport_mode: bool) -> Wires {
    let config = DdsConfig {
        domain_id: domain,
        iface: Some("lo".into()),
    };
    let sim = RobotWire::dds(&config, case.state_faults.clone(), sport_mode).unwrap();
    let transport = Transport::Dds {
        config,
        faults: case.command_faults.clone(),
        release: sport_mode.then(|| ReleaseOptions {
            retry_period_s: 0.2,
            ..Default::default()
        }),
    };
    (sim, transport)
}

#[test]
fn eemp_walks_the_simulated_go2_over_dds_and_survives_faults() {
    let robot = RobotConfig::load(&common::repo_path("robots/go2.toml")).unwrap();
    let none = Faults::default();
    let lossy = Faults {
        drop_prob: 0.05,
        seed: 3,
        ..Default::default()
    };
    let nasty = Faults {
        drop_prob: 0.02,
        corrupt_prob: 0.02,
        reorder_prob: 0.05,
        delay_s: 0.001,
        seed: 4,
    };
    let cases = [
        (
            Case {
                name: "released from sport mode, 20 s",
                duration_s: 20.0,
                state_faults: none.clone(),
                command_faults: none.clone(),
                freeze_after_s: None,
                spike: None,
            },
            81,
            true,
        ),
        (
            Case {
                name: "5 % loss both ways",
                duration_s: 6.0,
                state_faults: lossy.clone(),
                command_faults: Faults { seed: 5, ..lossy },
                freeze_after_s: None,
                spike: None,
            },
            82,
            false,
        ),
        (
            Case {
                name: "corrupt, reordered, delayed",
                duration_s: 5.0,
                state_faults: nasty.clone(),
                command_faults: Faults { seed: 6, ..nasty },
                freeze_after_s: None,
                spike: None,
            },
            83,
            false,
        ),
        (
            Case {
                name: "frozen state stream",
                duration_s: 3.0,
                state_faults: none.clone(),
                command_faults: none,
                freeze_after_s: Some(2.0),
                spike: None,
            },
            84,
            false,
        ),
    ];
    for (case, domain, sport_mode) in &cases {
        let (sim, hw) = run(&robot, case, dds(case, *domain, *sport_mode));
        check(case, &sim, &hw);
        if *sport_mode {
            assert_eq!(hw.release.as_deref(), Some("normal"), "{}", case.name);
        }
        if case.corrupt() {
            // A flipped byte can land in CDR padding, which no field reads: most, not all,
            // damaged samples fail their CRC.
            assert!(
                hw.bad_datagrams > 0 && sim.bad_datagrams > 0,
                "{}: corruption not seen",
                case.name
            );
        }
        // (A reordered sample is not seen late here: the reader keeps the last sample
        // written, KEEP_LAST 1, so a held-back state written after its successor replaces it
        // and reordering turns into the loss of the newer one.)
    }
}
