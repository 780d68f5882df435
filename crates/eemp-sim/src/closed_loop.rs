//! The closed loop shared by every scenario: estimate → plan → control → physics, one step at a
//! time, with pushes, fall detection and a per-stage time budget.

use crate::backend::Simulation;
use eemp_core::body_state::RobotState;
use eemp_core::controller::{feet_world, ControlOutput, LocomotionController, Plan};
use eemp_core::leg::LegMap;
use nalgebra::Vector3;
use std::time::Instant;

/// A push: the trunk's velocity changes by `dv_world` at time `at_s` (an impulse on the whole
/// robot, since the legs move with the trunk). Stated as a velocity change so it means the same
/// on any robot mass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Push {
    pub at_s: f64,
    pub dv_world: Vector3<f64>,
}

/// When a run counts as fallen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FallLimits {
    /// Trunk origin below this height, m.
    pub min_height_m: f64,
    /// Roll or pitch beyond this, rad.
    pub max_tilt_rad: f64,
}

impl Default for FallLimits {
    fn default() -> Self {
        FallLimits {
            min_height_m: 0.12,
            max_tilt_rad: 0.8,
        }
    }
}

impl FallLimits {
    pub fn fallen(&self, state: &RobotState) -> bool {
        let rpy = state.body.rpy();
        !state.body.is_finite()
            || state.body.p_world.z < self.min_height_m
            || rpy.x.abs() > self.max_tilt_rad
            || rpy.y.abs() > self.max_tilt_rad
    }
}

/// Everything about one control step, for observers (metrics, traces).
pub struct StepRecord<'a> {
    pub state: &'a RobotState,
    pub plan: &'a Plan,
    pub output: &'a ControlOutput,
    pub feet_world: &'a LegMap<Vector3<f64>>,
    /// Feet touching the ground according to the simulator.
    pub contacts: LegMap<bool>,
}

/// Wall time spent per stage, s.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StageTimes {
    pub physics_s: f64,
    pub planner_s: f64,
    pub mpc_s: f64,
    /// Controller time outside the MPC solve (leg control, bookkeeping).
    pub leg_control_s: f64,
    pub observer_s: f64,
}

#[derive(Clone, Debug, Default)]
pub struct LoopStats {
    pub steps: usize,
    pub sim_time_s: f64,
    pub wall_time_s: f64,
    pub mpc_solves: usize,
    pub mpc_failures: usize,
    pub mpc_solve_times_s: Vec<f64>,
    pub fell: bool,
    pub fell_at_s: Option<f64>,
    pub stages: StageTimes,
}

impl LoopStats {
    /// Simulated seconds per wall-clock second.
    pub fn realtime_factor(&self) -> f64 {
        if self.wall_time_s > 0.0 {
            self.sim_time_s / self.wall_time_s
        } else {
            0.0
        }
    }

    pub fn mpc_solve_median_us(&self) -> f64 {
        percentile(&self.mpc_solve_times_s, 0.5) * 1e6
    }
}

/// The `p`-quantile (0..1) of `values` by nearest rank; 0 for an empty slice.
pub fn percentile(values: &[f64], p: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut v = values.to_vec();
    v.sort_by(|a, b| a.total_cmp(b));
    let idx = ((v.len() - 1) as f64 * p).round() as usize;
    v[idx.min(v.len() - 1)]
}

/// Runs the loop for `duration_s` of simulated time or until a fall.
/// `planner` maps (state, measured foot positions) to a plan; `observer` sees every step.
pub fn run_closed_loop(
    sim: &mut Simulation,
    controller: &mut LocomotionController,
    duration_s: f64,
    pushes: &[Push],
    limits: FallLimits,
    mut planner: impl FnMut(&RobotState, &LegMap<Vector3<f64>>) -> Plan,
    mut observer: impl FnMut(&StepRecord),
) -> LoopStats {
    let mut stats = LoopStats::default();
    let dt = sim.timestep_s();
    let steps = (duration_s / dt).round() as usize;
    let t_start = sim.time_s();
    let mut pending: Vec<Push> = pushes.to_vec();
    let wall = Instant::now();
    for _ in 0..steps {
        let t0 = Instant::now();
        sim.prepare();
        let state = sim.ground_truth_state();
        let t1 = Instant::now();
        let feet = feet_world(controller.kinematics(), &state);
        let plan = planner(&state, &feet);
        let t2 = Instant::now();
        let output = controller.update(state.time_s, &state, &plan, sim);
        let t3 = Instant::now();
        observer(&StepRecord {
            state: &state,
            plan: &plan,
            output: &output,
            feet_world: &feet,
            contacts: sim.foot_contacts(),
        });
        let t4 = Instant::now();
        sim.advance(&output.torques);
        // Pushes take effect between steps.
        pending.retain(|p| {
            if sim.time_s() - t_start >= p.at_s {
                let qvel = sim.data_mut().qvel_mut();
                for (v, dv) in qvel[..3].iter_mut().zip(p.dv_world.iter()) {
                    *v += dv;
                }
                false
            } else {
                true
            }
        });
        let t5 = Instant::now();

        if let Some(ev) = &output.mpc_event {
            stats.mpc_solves += 1;
            stats.mpc_solve_times_s.push(ev.solve_time_s);
            if !ev.status.is_solved() {
                stats.mpc_failures += 1;
            }
            stats.stages.mpc_s += ev.solve_time_s;
            stats.stages.leg_control_s += (t3 - t2).as_secs_f64() - ev.solve_time_s;
        } else {
            stats.stages.leg_control_s += (t3 - t2).as_secs_f64();
        }
        stats.stages.physics_s += (t1 - t0).as_secs_f64() + (t5 - t4).as_secs_f64();
        stats.stages.planner_s += (t2 - t1).as_secs_f64();
        stats.stages.observer_s += (t4 - t3).as_secs_f64();
        stats.steps += 1;
        if limits.fallen(&state) {
            stats.fell = true;
            stats.fell_at_s = Some(state.time_s - t_start);
            break;
        }
    }
    stats.sim_time_s = stats.steps as f64 * dt;
    stats.wall_time_s = wall.elapsed().as_secs_f64();
    stats
}
