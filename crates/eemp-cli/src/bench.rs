//! `eemp bench mpc`: how long one convex-MPC solve takes, per QP solver option, against one bare
//! MuJoCo step of the robot (the A1 by default, `--robot FILE`) measured in the same run (so the ratio does not depend on the machine).
//!
//! Two representative states are solved repeatedly, each time slightly perturbed by a seeded
//! RNG so the solver does real work:
//! - standing: four feet in contact over the whole horizon, hold pose, forward velocity 0–0.5 m/s;
//! - trot: a diagonal pair in contact at a time (FR+RL for the first half of the horizon, FL+RR
//!   for the second), forward velocity 0.5 m/s.
//!
//! Only [`ConvexMpc::solve`] is timed (condensation, QP assembly and the QP itself).

use eemp_core::body_reference::BodyReference;
use eemp_core::body_state::BodyState;
use eemp_core::convex_mpc::{ConvexMpc, MpcConfig, MpcInput, QpSolverKind};
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::locomotion::ControllerConfig;
use eemp_core::robot::RobotConfig;
use eemp_core::stand_profile::BodyMotionProfile;
use eemp_sim::mjcf::SceneExtras;
use eemp_sim::stand::run_stand;
use eemp_sim::Simulation;
use nalgebra::{UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::time::Instant;

/// Trunk height of the representative states, m.
const TRUNK_HEIGHT_M: f64 = 0.30;
/// Ground height of the feet (foot centres), m.
const FOOT_Z_M: f64 = 0.02;
/// Forward velocity of the trot reference, m/s.
const TROT_SPEED_M_S: f64 = 0.5;
/// Untimed solves before each case's timed ones (caches, allocator, branch predictors).
const WARMUP_SOLVES: usize = 20;

/// What to measure.
#[derive(Clone, Debug, PartialEq)]
pub struct MpcBenchOptions {
    /// MPC horizon (steps).
    pub horizon: usize,
    /// Timed solves per case (default 300).
    pub solves: usize,
    /// Timed bare MuJoCo steps (default 20000).
    pub mujoco_steps: usize,
    /// The robot whose MPC and MuJoCo model are timed (default the A1).
    pub robot: RobotConfig,
}

impl Default for MpcBenchOptions {
    fn default() -> Self {
        MpcBenchOptions {
            horizon: MpcConfig::default().horizon,
            solves: 300,
            mujoco_steps: 20_000,
            robot: RobotConfig::a1(),
        }
    }
}

/// One case × solver option.
#[derive(Clone, Debug, PartialEq)]
pub struct MpcBenchRow {
    /// "standing" or "trot".
    pub label: String,
    /// "quadprog" or "clarabel".
    pub solver: String,
    pub drop_swing_forces: bool,
    /// `mpc.force_hold_steps` (move blocking; 1: a force per horizon step).
    pub force_hold_steps: usize,
    /// Feet in contact at any one time.
    pub feet: usize,
    /// QP variables and constraint rows (of the last solve).
    pub vars: usize,
    pub constraints: usize,
    /// Median and 99th-percentile (nearest rank) time of one `ConvexMpc::solve`, µs.
    pub median_us: f64,
    pub p99_us: f64,
    /// Mean solver iterations per solve (active-set additions for quadprog, interior-point
    /// iterations for clarabel).
    pub mean_iterations: f64,
    /// Timed solves that ended in a fallback instead of a QP solution (should be 0: a fallback
    /// is cheap and would make the times meaningless).
    pub fallbacks: usize,
}

/// Everything one benchmark run measured.
#[derive(Clone, Debug, PartialEq)]
pub struct MpcBenchReport {
    pub horizon: usize,
    pub rows: Vec<MpcBenchRow>,
    /// Median time of one bare MuJoCo step (`mj_step`, zero torques), µs.
    pub mujoco_step_us: f64,
    /// Default MPC config (`MpcConfig::default()` solver and swing-force option), standing on
    /// four feet: median and p99 solve time, µs.
    pub median_us: f64,
    pub p99_us: f64,
    /// Default MPC config, trotting on two diagonal feet: median solve time, µs.
    pub trot_median_us: f64,
    /// `median_us / mujoco_step_us`.
    pub ratio: f64,
    /// The default config with move blocking (`mpc.force_hold_steps` = 2), four feet: median
    /// solve time, µs, and its ratio to the bare step.
    pub blocked_median_us: f64,
    pub blocked_ratio: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Case {
    Standing,
    Trot,
}

impl Case {
    const ALL: [Case; 2] = [Case::Standing, Case::Trot];

    fn label(self) -> &'static str {
        match self {
            Case::Standing => "standing",
            Case::Trot => "trot",
        }
    }

    fn feet(self) -> usize {
        match self {
            Case::Standing => 4,
            Case::Trot => 2,
        }
    }
}

fn solver_name(kind: QpSolverKind) -> &'static str {
    match kind {
        QpSolverKind::Quadprog => "quadprog",
        QpSolverKind::Clarabel => "clarabel",
    }
}

/// The inputs of one solve, rebuilt in place for every perturbation.
struct Scene {
    body: BodyState,
    reference: Vec<BodyReference>,
    feet: Vec<LegMap<Vector3<f64>>>,
    contacts: Vec<LegMap<bool>>,
}

impl Scene {
    fn new(case: Case, horizon: usize, kin: &LegKinematics) -> Self {
        let origin = Vector3::new(0.0, 0.0, TRUNK_HEIGHT_M);
        let nominal = LegMap::from_fn(|leg| {
            let mut p = kin.nominal_foot_body(leg) + origin;
            p.z = FOOT_Z_M;
            p
        });
        let (feet, contacts) = match case {
            Case::Standing => (vec![nominal; horizon], vec![LegMap::splat(true); horizon]),
            Case::Trot => {
                let half = horizon / 2;
                let first = |leg: Leg| matches!(leg, Leg::FrontRight | Leg::RearLeft);
                let contacts = (0..horizon)
                    .map(|k| LegMap::from_fn(|leg| first(leg) == (k < half)))
                    .collect();
                // The second pair touches down where the trunk will be by then.
                let ahead = TROT_SPEED_M_S * half as f64 * MpcConfig::default().dt_s;
                let touchdown = LegMap::from_fn(|leg| {
                    let mut p = nominal[leg];
                    if !first(leg) {
                        p.x += ahead;
                    }
                    p
                });
                (vec![touchdown; horizon], contacts)
            }
        };
        let hold = BodyReference {
            rpy: Vector3::zeros(),
            p_world: origin,
            omega_world: Vector3::zeros(),
            v_world: Vector3::zeros(),
        };
        Scene {
            body: BodyState {
                p_world: origin,
                r_world_body: UnitQuaternion::identity(),
                v_world: Vector3::zeros(),
                omega_world: Vector3::zeros(),
            },
            reference: vec![hold; horizon],
            feet,
            contacts,
        }
    }

    /// A new current state near the nominal one and a new forward-velocity reference.
    fn perturb(&mut self, case: Case, dt_s: f64, rng: &mut ChaCha8Rng) {
        let mut sym = |a: f64| rng.random_range(-a..=a);
        let rpy = Vector3::new(sym(0.03), sym(0.03), sym(0.05));
        self.body = BodyState {
            p_world: Vector3::new(sym(0.01), sym(0.01), TRUNK_HEIGHT_M + sym(0.01)),
            r_world_body: UnitQuaternion::from_euler_angles(rpy.x, rpy.y, rpy.z),
            v_world: Vector3::new(sym(0.1), sym(0.1), sym(0.05)),
            omega_world: Vector3::new(sym(0.2), sym(0.2), sym(0.2)),
        };
        let speed = match case {
            Case::Standing => rng.random_range(0.0..=0.5),
            Case::Trot => TROT_SPEED_M_S,
        };
        for (k, r) in self.reference.iter_mut().enumerate() {
            r.p_world = Vector3::new(speed * (k + 1) as f64 * dt_s, 0.0, TRUNK_HEIGHT_M);
            r.v_world = Vector3::new(speed, 0.0, 0.0);
        }
    }

    fn input(&self) -> MpcInput<'_> {
        MpcInput {
            body: &self.body,
            reference: &self.reference,
            feet_world: &self.feet,
            contacts: &self.contacts,
            heat: None,
        }
    }
}

fn time_case(
    case: Case,
    solver: QpSolverKind,
    drop_swing_forces: bool,
    force_hold_steps: usize,
    options: &MpcBenchOptions,
) -> MpcBenchRow {
    let robot = &options.robot;
    let kin = LegKinematics::new(robot);
    let config = MpcConfig {
        horizon: options.horizon,
        solver,
        drop_swing_forces,
        force_hold_steps: config_hold(force_hold_steps, options),
        f_max_n: Some(robot.mpc_f_max_n()),
        ..MpcConfig::default()
    };
    let dt_s = config.dt_s;
    let mut mpc = ConvexMpc::new(config, robot.composite_body(&robot.standing_pose()))
        .expect("benchmark MPC config is valid");
    let mut scene = Scene::new(case, options.horizon, &kin);
    // The same seed for every row: every solver option sees the same sequence of states.
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut times_us = Vec::with_capacity(options.solves);
    let (mut unsolved, mut iterations, mut qp_size) = (0, 0, (0, 0));
    for i in 0..WARMUP_SOLVES + options.solves {
        scene.perturb(case, dt_s, &mut rng);
        let input = scene.input();
        let start = Instant::now();
        let solution = mpc.solve(std::hint::black_box(&input));
        let elapsed = start.elapsed();
        let solution = std::hint::black_box(solution);
        if i < WARMUP_SOLVES {
            continue;
        }
        times_us.push(elapsed.as_secs_f64() * 1e6);
        if !solution.status.is_solved() {
            unsolved += 1;
        }
        iterations += solution.iterations;
        if solution.qp_size != (0, 0) {
            qp_size = solution.qp_size;
        }
    }
    let (median_us, p99_us) = median_and_p99(&mut times_us);
    MpcBenchRow {
        label: case.label().to_string(),
        solver: solver_name(solver).to_string(),
        drop_swing_forces,
        force_hold_steps: config_hold(force_hold_steps, options),
        feet: case.feet(),
        vars: qp_size.0,
        constraints: qp_size.1,
        median_us,
        p99_us,
        mean_iterations: iterations as f64 / options.solves.max(1) as f64,
        fallbacks: unsolved,
    }
}

/// Nearest-rank percentile (`p` in (0, 1]) of sorted samples; NaN when there are none.
fn nearest_rank(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let rank = (p * sorted.len() as f64).ceil().max(1.0) as usize;
    sorted[rank.min(sorted.len()) - 1]
}

fn median_and_p99(samples: &mut [f64]) -> (f64, f64) {
    samples.sort_by(f64::total_cmp);
    (nearest_rank(samples, 0.5), nearest_rank(samples, 0.99))
}

/// Median time of one bare `mj_step` of the robot in the states it is in while standing under
/// control (four foot contacts), µs. States and torques are recorded from a standing run, then
/// each is restored and stepped once; a collapsing robot would give contact-rich, slower steps
/// and flatter every ratio against it.
fn time_mujoco_step(robot: &RobotConfig, steps: usize) -> f64 {
    let mut profile = BodyMotionProfile::default();
    profile.segments.truncate(3);
    let mut recorded = Vec::new();
    let mut i = 0usize;
    run_stand(robot, ControllerConfig::default(), profile, 4.0, &[], |r| {
        if r.state.time_s > 2.2 && i.is_multiple_of(10) {
            recorded.push((*r.state, r.output.torques));
        }
        i += 1;
    })
    .expect("the standing scenario runs");
    let mut sim =
        Simulation::new(robot, &SceneExtras::default()).expect("the robot model builds in MuJoCo");
    let mut per_step_us = Vec::with_capacity(steps);
    for k in 0..steps.max(1) {
        let (state, torques) = &recorded[k % recorded.len()];
        sim.set_state(state);
        let start = Instant::now();
        sim.step_bare(std::hint::black_box(torques));
        per_step_us.push(start.elapsed().as_secs_f64() * 1e6);
    }
    median_and_p99(&mut per_step_us).0
}

fn config_hold(force_hold_steps: usize, options: &MpcBenchOptions) -> usize {
    force_hold_steps.min(options.horizon)
}

/// The move blocking the bench times beside a force per step (`mpc.force_hold_steps`; opt-in,
/// docs/design-choices.md).
const BLOCKED_HOLD_STEPS: usize = 2;

/// Every case × solver × swing-force option, each with a force per horizon step (the paper's
/// QP, the default) and with move blocking.
fn run_cases(options: &MpcBenchOptions) -> Vec<MpcBenchRow> {
    let mut holds = vec![1, config_hold(BLOCKED_HOLD_STEPS, options)];
    holds.dedup();
    let mut out = Vec::new();
    for case in Case::ALL {
        for solver in [QpSolverKind::Quadprog, QpSolverKind::Clarabel] {
            for drop_swing_forces in [true, false] {
                for &hold in &holds {
                    out.push(time_case(case, solver, drop_swing_forces, hold, options));
                }
            }
        }
    }
    out
}

fn report_from(
    options: &MpcBenchOptions,
    rows: Vec<MpcBenchRow>,
    mujoco_step_us: f64,
) -> MpcBenchReport {
    let default = MpcConfig::default();
    let row = |case: Case, hold: usize| {
        rows.iter()
            .find(|r| {
                r.label == case.label()
                    && r.solver == solver_name(default.solver)
                    && r.drop_swing_forces == default.drop_swing_forces
                    && r.force_hold_steps == config_hold(hold, options)
            })
            .expect("the default config is among the measured rows")
    };
    let standing = row(Case::Standing, default.force_hold_steps);
    let (median_us, p99_us) = (standing.median_us, standing.p99_us);
    let trot_median_us = row(Case::Trot, default.force_hold_steps).median_us;
    let blocked_median_us = row(Case::Standing, BLOCKED_HOLD_STEPS).median_us;
    MpcBenchReport {
        horizon: options.horizon,
        median_us,
        p99_us,
        trot_median_us,
        blocked_median_us,
        blocked_ratio: blocked_median_us / mujoco_step_us,
        ratio: median_us / mujoco_step_us,
        mujoco_step_us,
        rows,
    }
}

/// Runs the whole benchmark: every case × solver option, then the bare MuJoCo step.
pub fn bench_mpc(options: &MpcBenchOptions) -> MpcBenchReport {
    let rows = run_cases(options);
    let mujoco_step_us = time_mujoco_step(&options.robot, options.mujoco_steps);
    report_from(options, rows, mujoco_step_us)
}

/// The machine-readable summary line (field order fixed).
#[derive(Serialize)]
struct Headline {
    horizon: usize,
    median_us: f64,
    p99_us: f64,
    trot_median_us: f64,
    mujoco_step_us: f64,
    ratio: f64,
    blocked_ratio: f64,
}

impl MpcBenchReport {
    /// Human-readable aligned table of every row, then the MuJoCo step and the ratio.
    pub fn table(&self) -> String {
        let mut s = format!("MPC solve time, horizon {}\n", self.horizon);
        s += &format!(
            "{:<9} {:<9} {:>10} {:>4} {:>5} {:>5} {:>6} {:>11} {:>11} {:>6} {:>9}\n",
            "case",
            "solver",
            "drop_swing",
            "hold",
            "feet",
            "vars",
            "cons",
            "median_us",
            "p99_us",
            "iters",
            "fallbacks"
        );
        for r in &self.rows {
            s += &format!(
                "{:<9} {:<9} {:>10} {:>4} {:>5} {:>5} {:>6} {:>11.1} {:>11.1} {:>6.1} {:>9}\n",
                r.label,
                r.solver,
                r.drop_swing_forces,
                r.force_hold_steps,
                r.feet,
                r.vars,
                r.constraints,
                r.median_us,
                r.p99_us,
                r.mean_iterations,
                r.fallbacks
            );
        }
        s += &format!(
            "MuJoCo step (bare mj_step): {:.2} us\n\
             default config, four feet: median {:.1} us, p99 {:.1} us = {:.1} MuJoCo steps\n\
             default config, trot (two feet): median {:.1} us\n\
             with move blocking (--set mpc.force_hold_steps={BLOCKED_HOLD_STEPS}), four feet: \
             median {:.1} us = {:.1} MuJoCo steps",
            self.mujoco_step_us,
            self.median_us,
            self.p99_us,
            self.ratio,
            self.trot_median_us,
            self.blocked_median_us,
            self.blocked_ratio
        );
        s
    }

    /// One JSON object: horizon, median_us, p99_us, trot_median_us, mujoco_step_us, ratio,
    /// blocked_ratio.
    pub fn json_line(&self) -> String {
        serde_json::to_string(&Headline {
            horizon: self.horizon,
            median_us: self.median_us,
            p99_us: self.p99_us,
            trot_median_us: self.trot_median_us,
            mujoco_step_us: self.mujoco_step_us,
            ratio: self.ratio,
            blocked_ratio: self.blocked_ratio,
        })
        .expect("plain numbers serialise")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> MpcBenchOptions {
        MpcBenchOptions {
            horizon: 10,
            solves: 5,
            mujoco_steps: 200,
            robot: RobotConfig::a1(),
        }
    }

    #[test]
    fn nearest_rank_percentiles() {
        let mut v: Vec<f64> = (1..=100).rev().map(f64::from).collect();
        assert_eq!(median_and_p99(&mut v), (50.0, 99.0));
        assert_eq!(nearest_rank(&[7.0], 0.99), 7.0);
        assert!(nearest_rank(&[], 0.5).is_nan());
    }

    #[test]
    fn every_case_solves_with_the_expected_problem_size() {
        for r in run_cases(&tiny()) {
            assert_eq!(r.fallbacks, 0, "{r:?}");
            assert!(r.mean_iterations > 0.0, "{r:?}");
            // Variables: 3 per force block; rows: 5 per block in contact + 3 equality rows per
            // kept swing block (f_min is 0 by default).
            let case = Case::ALL
                .into_iter()
                .find(|c| c.label() == r.label)
                .unwrap();
            let scene = Scene::new(case, 10, &LegKinematics::new(&RobotConfig::a1()));
            let blocks = eemp_core::convex_mpc::force_blocks(
                &scene.contacts,
                MpcConfig::default().force_hold_start,
                r.force_hold_steps,
                r.drop_swing_forces,
            );
            let in_contact = blocks.iter().filter(|b| b.contact).count();
            assert_eq!(r.vars, 3 * blocks.len(), "{r:?}");
            assert_eq!(
                r.constraints,
                5 * in_contact + 3 * (blocks.len() - in_contact),
                "{r:?}"
            );
            if r.force_hold_steps == 1 {
                let kept = if r.drop_swing_forces { r.feet } else { 4 };
                assert_eq!(r.vars, 3 * kept * 10, "{r:?}");
            }
        }
    }

    #[test]
    fn tiny_report_is_finite_and_its_json_line_has_the_seven_keys() {
        let report = bench_mpc(&tiny());
        // 2 cases × 2 solvers × 2 swing-force options × (unblocked, default blocking).
        assert_eq!(report.rows.len(), 16);
        for r in &report.rows {
            assert!(r.median_us.is_finite() && r.median_us > 0.0, "{r:?}");
            assert!(r.p99_us.is_finite() && r.p99_us >= r.median_us, "{r:?}");
        }
        for v in [
            report.median_us,
            report.p99_us,
            report.trot_median_us,
            report.mujoco_step_us,
            report.ratio,
            report.blocked_ratio,
        ] {
            assert!(v.is_finite(), "{report:?}");
        }
        assert!(report.mujoco_step_us > 0.0);
        assert!(report.ratio > 0.0);
        let json: serde_json::Value = serde_json::from_str(&report.json_line()).unwrap();
        let object = json.as_object().unwrap();
        let mut keys: Vec<&str> = object.keys().map(String::as_str).collect();
        keys.sort_unstable();
        assert_eq!(
            keys,
            [
                "blocked_ratio",
                "horizon",
                "median_us",
                "mujoco_step_us",
                "p99_us",
                "ratio",
                "trot_median_us"
            ]
        );
        assert_eq!(object["horizon"], 10);
        assert!(object.values().all(|v| v.is_number()));
        assert!(report.table().contains("clarabel"));
    }
}
