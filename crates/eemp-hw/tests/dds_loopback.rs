//! The Go2 DDS link between two RustDDS participants on one machine (a test domain, 77, so a
//! robot or simulator on 0 / 1 is not disturbed): discovery on the exact topic and type names,
//! a LowState_ one way and a LowCmd_ the other, decoded and CRC-checked by eemp-core's codec;
//! a corrupted sample fails its CRC (or, flipped in padding, decodes to what was sent).

use eemp_hw::dds::{DdsConfig, Go2Endpoint, Role};
use eemp_hw::link::Faults;
use eemp_hw::wire::go2_idl::{fixtures, LowCmd, LowState};
use std::time::{Duration, Instant};

const DOMAIN: u16 = 77;

/// Sends `out` from `tx` every 10 ms until `rx` hands over a sample `accept` takes, or 20 s.
fn exchange<T>(
    tx: &mut Go2Endpoint,
    rx: &mut Go2Endpoint,
    out: &[u8],
    mut accept: impl FnMut(&[u8]) -> Option<T>,
) -> Option<T> {
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(20) {
        tx.send(out, t0.elapsed().as_secs_f64());
        std::thread::sleep(Duration::from_millis(10));
        while let Some(bytes) = rx.recv() {
            if let Some(v) = accept(&bytes) {
                return Some(v);
            }
        }
    }
    None
}

#[test]
fn a_state_and_a_command_cross_between_two_participants() {
    let cfg = DdsConfig {
        domain_id: DOMAIN,
        iface: None,
    };
    let mut robot = Go2Endpoint::new(&cfg, Role::Robot, Faults::default()).unwrap();
    let mut controller = Go2Endpoint::new(&cfg, Role::Controller, Faults::default()).unwrap();
    let state = fixtures::low_state_filled();
    let got = exchange(&mut robot, &mut controller, &state.to_cdr(), |b| {
        LowState::from_cdr(b).ok()
    })
    .expect("no LowState_ within 20 s");
    got.check_crc().unwrap();
    assert_eq!(got, state);
    let cmd = fixtures::low_cmd_filled();
    let got = exchange(&mut controller, &mut robot, &cmd.to_cdr(), |b| {
        LowCmd::from_cdr(b).ok()
    })
    .expect("no LowCmd_ within 20 s");
    got.check_crc().unwrap();
    assert_eq!(got, cmd);
    assert!(controller.matched_readers() >= 1);
    assert_eq!((robot.read_errors, controller.read_errors), (0, 0));
}

#[test]
fn a_corrupted_command_arrives_with_a_failing_crc() {
    let cfg = DdsConfig {
        domain_id: DOMAIN + 1,
        iface: Some("lo".into()),
    };
    let mut robot = Go2Endpoint::new(&cfg, Role::Robot, Faults::default()).unwrap();
    let corrupt = Faults {
        corrupt_prob: 1.0,
        seed: 9,
        ..Default::default()
    };
    let mut controller = Go2Endpoint::new(&cfg, Role::Controller, corrupt).unwrap();
    let cmd = fixtures::low_cmd_filled();
    // Every sample has one byte flipped. A flip in the CDR padding (which no field reads)
    // decodes to the command sent; any other fails to decode or fails its CRC: a damaged
    // sample never yields a different command. At least one must be caught.
    let caught = exchange(
        &mut controller,
        &mut robot,
        &cmd.to_cdr(),
        |b| match LowCmd::from_cdr(b) {
            Ok(c) if c.check_crc().is_ok() => {
                assert_eq!(c, cmd, "a damaged sample passed its CRC as another command");
                None
            }
            _ => Some(()),
        },
    );
    assert!(caught.is_some(), "no damaged sample caught within 20 s");
    assert!(controller.stats.corrupted > 0);
}

#[test]
fn bad_settings_are_refused_naming_the_value() {
    let e = DdsConfig {
        domain_id: 233,
        iface: None,
    }
    .validate()
    .unwrap_err();
    assert!(e.contains("233") && e.contains("0..=232"), "{e}");
    let e = DdsConfig {
        domain_id: 1,
        iface: Some("nosuch0".into()),
    }
    .validate()
    .unwrap_err();
    assert!(e.contains("'nosuch0'") && e.contains("lo"), "{e}");
}

#[test]
fn a_writer_with_the_wrong_type_name_is_not_heard() {
    use eemp_hw::dds::{raw_writer, CdrBytes, TOPIC_LOWSTATE};
    let cfg = DdsConfig {
        domain_id: DOMAIN + 2,
        iface: Some("lo".into()),
    };
    let mut controller = Go2Endpoint::new(&cfg, Role::Controller, Faults::default()).unwrap();
    let other = cfg.participant().unwrap();
    // The right topic and bytes, but ROS 2's name without the trailing underscore.
    let wrong = raw_writer(&other, TOPIC_LOWSTATE, "unitree_go::msg::dds_::LowState").unwrap();
    let state = CdrBytes(fixtures::low_state_filled().to_cdr());
    let t0 = Instant::now();
    let mut heard = 0;
    while t0.elapsed() < Duration::from_secs(3) {
        let _ = wrong.write(state.clone(), None);
        std::thread::sleep(Duration::from_millis(10));
        while controller.recv().is_some() {
            heard += 1;
        }
    }
    assert_eq!(heard, 0, "samples of another type were delivered");
    assert!(
        controller.stats.wrong_type > 10,
        "{} dropped",
        controller.stats.wrong_type
    );
}
