//! Pinned determinism digests: a 3 s walk per shipped robot and gait (each on its own per-speed
//! table, as `eemp walk` runs it), hashed over every physics step's state and torques. A
//! refactor meant to change no behaviour proves "same bytes" here in seconds; a change that is
//! meant to move results updates the pins below and says why in its commit.
//!
//! On a mismatch the test prints every digest in the form of the table, to paste in after
//! checking that the change was meant.

use eemp_rl::run::WalkDescription;
use std::path::PathBuf;

fn repo(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

/// FNV-1a, 64 bit, over the little-endian bytes of each value's bits.
struct Fnv(u64);

impl Fnv {
    fn push(&mut self, x: f64) {
        for b in x.to_bits().to_le_bytes() {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x100_0000_01b3);
        }
    }
}

/// (robot, gait, estimator, pinned digest). The Go1's and Go2's free-gait tables give the free
/// gait the trot's parameters, and with them it pairs the diagonal legs and walks the trot's bytes.
const PINS: [(&str, &str, &str, u64); 11] = [
    ("a1", "trot", "ground-truth", 0x4f74e08fbda9e0ce),
    ("a1", "walk", "ground-truth", 0x1f97c71e7e9cc472),
    ("a1", "free", "ground-truth", 0xe80118ea7dc1e400),
    ("a1", "free", "kf", 0x441b3080f63ecbb9),
    ("a1", "trot", "kf", 0x44715f71003edb2a),
    ("go1", "trot", "kf", 0xa15e2e79e1e9f475),
    ("go1", "walk", "kf", 0x722ae2074e1c2474),
    ("go2", "trot", "kf", 0xb245dc670c437ffa),
    ("go2", "walk", "kf", 0x0a0d2a7c6343b613),
    ("go1", "free", "kf", 0xa15e2e79e1e9f475),
    ("go2", "free", "kf", 0xb245dc670c437ffa),
];

fn digest(robot: &str, gait: &str, estimator: &str) -> (u64, bool) {
    digest_of(
        robot,
        gait,
        estimator,
        &format!("tables/{robot}_{gait}.toml"),
        &[],
    )
}

fn digest_of(robot: &str, gait: &str, estimator: &str, table: &str, set: &[&str]) -> (u64, bool) {
    let mut d = WalkDescription {
        robot: (robot != "a1").then(|| repo(&format!("robots/{robot}.toml"))),
        gait: gait.into(),
        speed_mps: 0.3,
        duration_s: 3.0,
        params_table: Some(repo(table)),
        set: set.iter().map(|s| s.to_string()).collect(),
        ..Default::default()
    };
    d.sensing.estimator = estimator.into();
    d.sensing.seed = 1;
    let mut h = Fnv(0xcbf2_9ce4_8422_2325);
    let run = d
        .build()
        .unwrap()
        .run(|r| {
            let b = &r.state.body;
            h.push(r.state.time_s);
            b.p_world
                .iter()
                .chain(b.v_world.iter())
                .for_each(|x| h.push(*x));
            b.omega_world.iter().for_each(|x| h.push(*x));
            for leg in eemp_core::leg::Leg::ALL {
                r.state.joints[leg].q.iter().for_each(|x| h.push(*x));
                r.output.torques[leg].iter().for_each(|x| h.push(*x));
            }
        })
        .unwrap();
    (h.0, run.stats.fell)
}

#[test]
fn every_shipped_robot_and_gait_walks_its_pinned_bytes() {
    let mut got = Vec::new();
    for (robot, gait, estimator, _) in PINS {
        let (d, fell) = digest(robot, gait, estimator);
        assert!(!fell, "{robot} {gait} on {estimator} fell within 3 s");
        got.push(d);
    }
    let table: Vec<String> = PINS
        .iter()
        .zip(&got)
        .map(|((r, g, e, _), d)| format!("    (\"{r}\", \"{g}\", \"{e}\", {d:#018x}),"))
        .collect();
    let mismatched: Vec<String> = PINS
        .iter()
        .zip(&got)
        .filter(|((.., pin), d)| pin != *d)
        .map(|((r, g, e, _), _)| format!("{r} {g} {e}"))
        .collect();
    assert!(
        mismatched.is_empty(),
        "walks differ from their pins: {}\nnew table:\n{}",
        mismatched.join(", "),
        table.join("\n")
    );
}

/// Move blocking (`mpc.force_hold_steps = 2`, opt-in: docs/design-choices.md): its walks are
/// pinned as the defaults are.
#[test]
fn the_move_blocked_mpc_walks_its_pinned_bytes() {
    let (mut got, mut mismatched) = (Vec::new(), false);
    for (gait, estimator, pin) in [
        ("trot", "ground-truth", 0xa4030ff9f13b1acf_u64),
        ("walk", "ground-truth", 0x2bbbbd62d9d0e065),
        ("free", "kf", 0x2d070514a5ae2610),
    ] {
        let table = format!("tables/a1_{gait}.toml");
        let (d, fell) = digest_of("a1", gait, estimator, &table, &["mpc.force_hold_steps=2"]);
        assert!(!fell, "{gait} {estimator} fell");
        got.push(format!("{gait} {estimator}: {d:#018x}"));
        mismatched |= d != pin;
    }
    assert!(!mismatched, "digests now:\n{}", got.join("\n"));
}

/// The battery-aware EEMP (docs/energy.md): the battery tables on the MPC that weighs the
/// motors' heat. Its free gait pairs the diagonal legs with the trot's parameters at 0.3 m/s and
/// walks the trot's bytes.
#[test]
fn the_battery_aware_configuration_walks_its_pinned_bytes() {
    let (mut got, mut mismatched) = (Vec::new(), false);
    for (gait, table, estimator, pin) in [
        (
            "trot",
            "tables/a1_trot_battery.toml",
            "ground-truth",
            0x641b17c07593c2d0_u64,
        ),
        (
            "free",
            "tables/a1_free_battery.toml",
            "ground-truth",
            0x641b17c07593c2d0,
        ),
        (
            "free",
            "tables/a1_free_battery.toml",
            "kf",
            0x79a74ea31073e788,
        ),
        (
            "walk",
            "tables/a1_walk.toml",
            "ground-truth",
            0xdf6af96642de152a,
        ),
    ] {
        let (d, fell) = digest_of("a1", gait, estimator, table, &["mpc.weight_heat=0.002"]);
        assert!(!fell, "{gait} {estimator} fell");
        got.push(format!("{gait} {estimator}: {d:#018x}"));
        mismatched |= d != pin;
    }
    assert!(!mismatched, "digests now:\n{}", got.join("\n"));
}
