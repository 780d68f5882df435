//! The closed loop shared by every scenario: estimate → plan → control → physics, one step at a
//! time, with pushes, fall detection and a per-stage time budget.

use crate::backend::Simulation;
use crate::sensors::{SensorNoise, Sensors};
use eemp_core::body_state::RobotState;
use eemp_core::controller::Controller;

use eemp_core::estimator::{KfConfig, LinearKf};
use eemp_core::leg::LegMap;
use eemp_core::locomotion::{ControlOutput, Plan};
use eemp_core::pipeline::{ControlPipeline, Prepared, Sensed};
use eemp_core::planner::VelocityCommand;
use eemp_core::robot::RobotScale;
use eemp_core::robot_size;
use nalgebra::Vector3;
use std::time::Instant;

/// A push of the robot's momentum by `mass × dv_world` at time `at_s`. Stated as a velocity
/// change so it means the same on any robot mass.
///
/// With `duration_s` 0 the robot's velocity steps between two physics steps (the legs move with
/// the trunk, as legged_gym's `push_robots` does): no onboard sensor can sense such a step
/// until the sliding feet stop, so an estimator must lag it. With `duration_s` > 0 it is a force
/// on the trunk's centre of mass for n = round(duration_s / dt) ≥ 1 physics steps, of
/// `mass × dv / (n·dt)` — what a hand or a collision does — which the accelerometer senses and
/// the feet resist.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Push {
    pub at_s: f64,
    pub dv_world: Vector3<f64>,
    pub duration_s: f64,
}

impl Push {
    /// A velocity step (duration 0).
    pub fn step(at_s: f64, dv_world: Vector3<f64>) -> Self {
        Push {
            at_s,
            dv_world,
            duration_s: 0.0,
        }
    }
}

/// When a run counts as fallen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FallLimits {
    /// Trunk origin below this height, m.
    pub min_height_m: f64,
    /// Roll or pitch beyond this, rad.
    pub max_tilt_rad: f64,
}

impl FallLimits {
    /// The limits of a robot of size `size`: the height is
    /// [`eemp_core::robot_size::FALL_MIN_HEIGHT`] scaled to it, the tilt is an angle.
    pub fn for_size(size: &RobotScale) -> Self {
        FallLimits {
            min_height_m: size.sized(&robot_size::FALL_MIN_HEIGHT),
            max_tilt_rad: 0.8,
        }
    }

    /// Whether `state` counts as fallen on the flat floor.
    pub fn fallen(&self, state: &RobotState) -> bool {
        self.fallen_above(state, 0.0)
    }

    /// Whether `state` counts as fallen with the ground `ground_z_m` under the trunk.
    pub fn fallen_above(&self, state: &RobotState, ground_z_m: f64) -> bool {
        let rpy = state.body.rpy();
        !state.body.is_finite()
            || state.body.p_world.z - ground_z_m < self.min_height_m
            || rpy.x.abs() > self.max_tilt_rad
            || rpy.y.abs() > self.max_tilt_rad
    }
}

/// Everything about one control step, for observers (metrics, traces).
pub struct StepRecord<'a> {
    /// The simulator's true state (metrics are measured on it).
    pub state: &'a RobotState,
    /// What the controller was given: the true state, or the estimator's output.
    pub estimate: &'a RobotState,
    /// The controller's plan, when it has one (EEMP does, a learned policy does not).
    pub plan: Option<&'a Plan>,
    pub command: VelocityCommand,
    pub output: &'a ControlOutput,
    pub feet_world: &'a LegMap<Vector3<f64>>,
    /// Feet touching the ground according to the simulator.
    pub contacts: LegMap<bool>,
    /// Feet carrying more than [`eemp_core::robot_size::LOADED_FOOT`] (the robot's; from the
    /// previous step's contact solve).
    pub loaded: LegMap<bool>,
    /// Each foot's normal force from the previous step's contact solve, N.
    pub foot_normal_n: LegMap<f64>,
}

/// Where the controller's state comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum StateSource {
    /// The simulator's own state, read without noise or delay.
    GroundTruth,
    /// The linear Kalman filter on the simulated IMU and encoders (`eemp_core::estimator`),
    /// with their noise; `seed` seeds the noise.
    Kf {
        kf: KfConfig,
        sensors: SensorNoise,
        seed: u64,
    },
}

impl StateSource {
    /// The Kalman filter for `robot` (its foot radius as the foot height) on sensors with
    /// `sensors` noise, seeded `seed`: what `--estimator kf` selects.
    pub fn kf(robot: &eemp_core::robot::RobotConfig, sensors: SensorNoise, seed: u64) -> Self {
        StateSource::Kf {
            kf: KfConfig {
                foot_height_m: robot.leg.foot_radius_m,
                ..Default::default()
            },
            sensors,
            seed,
        }
    }

    /// The filter's settings, when the controller runs on the filter.
    pub fn kf_config(&self) -> Option<&KfConfig> {
        match self {
            StateSource::Kf { kf, .. } => Some(kf),
            StateSource::GroundTruth => None,
        }
    }

    /// The filter's settings to change, when the controller runs on the filter.
    pub fn kf_config_mut(&mut self) -> Option<&mut KfConfig> {
        match self {
            StateSource::Kf { kf, .. } => Some(kf),
            StateSource::GroundTruth => None,
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            StateSource::GroundTruth => "ground-truth",
            StateSource::Kf { .. } => "kf",
        }
    }
}

/// Estimation error against the simulator's truth over an episode.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EstimationStats {
    sq_vel: f64,
    sq_pos: f64,
    n: usize,
}

impl EstimationStats {
    /// RMS error of the trunk velocity estimate, m/s.
    pub fn vel_rmse_mps(&self) -> Option<f64> {
        (self.n > 0).then(|| (self.sq_vel / self.n as f64).sqrt())
    }
    /// RMS error of the trunk position estimate, m.
    pub fn pos_rmse_m(&self) -> Option<f64> {
        (self.n > 0).then(|| (self.sq_pos / self.n as f64).sqrt())
    }
}

pub use eemp_core::estimator::{foot_force_from_torque, ContactTrust, TRUST_RAMP_S};

impl StepRecord<'_> {
    /// Legs carrying the robot: the plan's stance set, or the loaded feet without a plan.
    pub fn stance(&self) -> LegMap<bool> {
        self.plan.map(|p| p.stance).unwrap_or(self.loaded)
    }
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
    /// The lowest friction coefficient an MPC solve used (lowered after slips); None without
    /// MPC solves.
    pub mpc_friction_min: Option<f64>,
    /// The friction coefficient of the last MPC solve and the sum over the solves (the
    /// controller's belief about the floor, capped at the MPC's nominal; `eemp_core::slip`).
    pub mpc_friction_last: Option<f64>,
    pub mpc_friction_sum: f64,
    /// Steps whose plan had slip handling's speed cap on (a floor found slippery; a command
    /// already below the cap is counted too).
    pub slowed_steps: usize,
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

/// The closed loop as an episode object: every scenario (stand, walk), sweep, learned-controller
/// environment and evaluation steps the robot through [`ClosedLoop::step`].
#[derive(Clone)]
pub struct ClosedLoop {
    sim: Simulation,
    pending: Vec<Push>,
    /// Force pulses under way: the force on the trunk and the physics steps it has left.
    pulses: Vec<(Vector3<f64>, usize)>,
    limits: FallLimits,
    /// The ground the fall height is measured above (None: the floor plane).
    ground: Option<crate::terrain::Ground>,
    stats: LoopStats,
    t_start: f64,
    wall_start: Instant,
    loaded: LegMap<bool>,
    /// A foot carries the robot above this normal force, N.
    loaded_foot_n: f64,
    foot_normal_n: LegMap<f64>,
    /// The simulated IMU and encoders, where the controller runs on the filter.
    sensors: Option<Sensors>,
    /// Estimate → controller, as on the robot.
    pipeline: ControlPipeline,
    /// The state the controller saw at the last step, when it is an estimate.
    last_estimate: Option<RobotState>,
    estimation: EstimationStats,
}

/// What one step of the loop ended in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepOutcome {
    /// The state at the start of the step counts as fallen (the episode is over).
    pub fell: bool,
}

/// Why an episode ends after a step ([`ClosedLoop::episode_end`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EpisodeEnd {
    /// MuJoCo reported an unstable simulation (counted as a fall too).
    Unstable,
    /// The fall limits were crossed, or the trunk touched the floor.
    Fell,
}

impl ClosedLoop {
    /// Starts an episode from the simulation's current state, on ground truth.
    /// `size` is the robot's as described (not as simulated with a payload or model errors):
    /// the fall limits, the loaded-foot force and the filter's contact trust follow it
    /// ([`eemp_core::robot_size`]).
    pub fn new(sim: Simulation, pushes: &[Push], size: RobotScale) -> Self {
        let t_start = sim.time_s();
        ClosedLoop {
            sensors: None,
            pipeline: ControlPipeline::new(t_start, size),
            loaded_foot_n: size.sized(&robot_size::LOADED_FOOT),
            last_estimate: None,
            estimation: EstimationStats::default(),
            sim,
            pending: pushes.to_vec(),
            pulses: Vec::new(),
            limits: FallLimits::for_size(&size),
            ground: None,
            stats: LoopStats::default(),
            t_start,
            wall_start: Instant::now(),
            // Episodes start standing.
            loaded: LegMap::splat(true),
            foot_normal_n: LegMap::splat(0.0),
        }
    }

    /// Starts an episode whose controller sees `source` (the filter starts at the current true
    /// state: the robot is put down at a known pose).
    pub fn with_state_source(
        sim: Simulation,
        pushes: &[Push],
        size: RobotScale,
        source: &StateSource,
    ) -> Result<Self, eemp_core::config_error::ConfigError> {
        let mut lp = ClosedLoop::new(sim, pushes, size);
        lp.set_state_source(source)?;
        Ok(lp)
    }

    /// Puts the controller on `source` from now on (the filter starts at the current true
    /// state).
    pub fn set_state_source(
        &mut self,
        source: &StateSource,
    ) -> Result<(), eemp_core::config_error::ConfigError> {
        match source {
            StateSource::GroundTruth => {
                self.pipeline.set_filter(None);
                self.sensors = None;
            }
            StateSource::Kf { kf, sensors, seed } => {
                self.sim.prepare_kinematics();
                let start = self.sim.ground_truth_state();
                let filter = LinearKf::new(kf.clone(), self.sim.kinematics().clone(), &start)?;
                self.sensors = Some(Sensors::new(sensors.clone(), *seed, self.sim.timestep_s())?);
                self.pipeline.set_filter(Some(filter));
            }
        }
        self.last_estimate = None;
        Ok(())
    }

    /// Measures the fall height above `terrain`'s ground under the trunk (a collapse on a
    /// platform or a stair is a fall).
    pub fn set_ground(&mut self, terrain: &crate::terrain::Terrain) {
        self.ground = Some(crate::terrain::Ground::new(terrain));
    }

    /// What the robot knows of itself now: the estimate its controller saw at the last step,
    /// or the simulator's state on ground truth (and right after a start, when the filter
    /// starts from the known pose).
    pub fn observed_state(&self) -> RobotState {
        self.last_estimate
            .unwrap_or_else(|| self.sim.ground_truth_state())
    }

    pub fn estimation(&self) -> &EstimationStats {
        &self.estimation
    }

    /// Starts a new episode on the same simulation (the caller has reset its state).
    pub fn restart(&mut self, pushes: &[Push]) {
        self.pending = pushes.to_vec();
        if !self.pulses.is_empty() {
            self.pulses.clear();
            self.sim.set_trunk_force(Vector3::zeros());
        }
        self.stats = LoopStats::default();
        self.t_start = self.sim.time_s();
        self.wall_start = Instant::now();
        self.loaded = LegMap::splat(true);
        self.foot_normal_n = LegMap::splat(0.0);
        self.pipeline.restart(self.t_start);
        self.estimation = EstimationStats::default();
        self.last_estimate = None;
        if let (Some(kf), Some(sensors)) = (self.pipeline.filter_mut(), self.sensors.as_mut()) {
            self.sim.prepare_kinematics();
            kf.reset(&self.sim.ground_truth_state());
            sensors.clear();
        }
    }

    /// The episode's pushes still to come (times from the episode's start; force pulses under
    /// way are not included). With [`ClosedLoop::episode_start_s`] and [`ClosedLoop::resume`],
    /// what a snapshot of an episode keeps.
    pub fn pending_pushes(&self) -> &[Push] {
        &self.pending
    }

    /// Simulation time at which the episode started, s.
    pub fn episode_start_s(&self) -> f64 {
        self.t_start
    }

    /// Continues an episode restored into the simulation: like [`ClosedLoop::restart`], but
    /// with its pending pushes timed from the episode's original start (so a restored episode
    /// meets them at exactly the steps the uninterrupted one does).
    pub fn resume(&mut self, pushes: &[Push], episode_start_s: f64) {
        self.restart(pushes);
        self.t_start = episode_start_s;
    }

    /// Feet carrying more than [`LOADED_FOOT_N`] after the last step.
    pub fn loaded(&self) -> LegMap<bool> {
        self.loaded
    }

    pub fn sim(&self) -> &Simulation {
        &self.sim
    }

    pub fn sim_mut(&mut self) -> &mut Simulation {
        &mut self.sim
    }

    pub fn stats(&self) -> &LoopStats {
        &self.stats
    }

    /// Episode time, s.
    pub fn elapsed_s(&self) -> f64 {
        self.sim.time_s() - self.t_start
    }

    /// Whether the episode ends after a step that returned `out`: an instability (taken from
    /// the simulation, so it is reported once), else a fall or a trunk contact. The learning
    /// tasks' one test of the end, so that every environment and the paired table walk stop
    /// on the same conditions.
    pub fn episode_end(&mut self, out: StepOutcome) -> Option<EpisodeEnd> {
        if self.sim.take_instability() {
            Some(EpisodeEnd::Unstable)
        } else if out.fell || self.sim.trunk_contact() {
            Some(EpisodeEnd::Fell)
        } else {
            None
        }
    }

    /// One physics step: state → controller → observer → torques → physics → pushes.
    /// After a fall the step is still taken; the caller ends the episode.
    pub fn step(
        &mut self,
        controller: &mut dyn Controller,
        command: VelocityCommand,
        observer: &mut dyn FnMut(&StepRecord),
    ) -> StepOutcome {
        let t0 = Instant::now();
        if controller.needs_dynamics() {
            self.sim.prepare();
        } else {
            self.sim.prepare_kinematics();
        }
        let truth = self.sim.ground_truth_state();
        let sensed = match self.sensors.as_mut() {
            None => Sensed {
                seen: truth,
                imu: None,
            },
            Some(sensors) => {
                // Encoders and the IMU; the attitude comes from the IMU as on the A1.
                let seen = sensors.read(self.sim.imu(), &truth.joints);
                Sensed {
                    seen: RobotState {
                        time_s: truth.time_s,
                        body: eemp_core::body_state::BodyState {
                            r_world_body: seen.imu.r_world_body,
                            ..truth.body
                        },
                        joints: seen.joints,
                    },
                    imu: Some(seen.imu),
                }
            }
        };
        let t1 = Instant::now();
        // The controller's dynamics are the simulator's own, at the true state.
        let update = self.pipeline.update(
            &sensed,
            self.sim.kinematics(),
            controller,
            command,
            &mut Prepared(&self.sim),
        );
        let t3 = Instant::now();
        let (state, feet, output) = (update.estimate, update.feet_world, update.output);
        if self.sensors.is_some() {
            self.estimation.sq_vel += (state.body.v_world - truth.body.v_world).norm_squared();
            self.estimation.sq_pos += (state.body.p_world - truth.body.p_world).norm_squared();
            self.estimation.n += 1;
            self.last_estimate = Some(state);
        }
        observer(&StepRecord {
            state: &truth,
            estimate: &state,
            plan: controller.plan(),
            command,
            output: &output,
            feet_world: &feet,
            contacts: self.sim.foot_contacts(),
            loaded: self.loaded,
            foot_normal_n: self.foot_normal_n,
        });
        let t4 = Instant::now();
        let sim = &mut self.sim;
        sim.advance(&output.torques);
        self.foot_normal_n = sim.foot_normal_forces_n();
        self.loaded = self.foot_normal_n.map(|_, f| *f > self.loaded_foot_n);
        // Pushes take effect between steps. A pulse acts for n = round(duration / dt) ≥ 1
        // whole physics steps with the force that gives exactly mass × Δv over them.
        let had_pulses = !self.pulses.is_empty();
        for p in self.pulses.iter_mut() {
            p.1 -= 1;
        }
        self.pulses.retain(|p| p.1 > 0);
        let t_start = self.t_start;
        let (dt, m) = (sim.timestep_s(), sim.total_mass_kg());
        let pulses = &mut self.pulses;
        self.pending.retain(|p| {
            if sim.time_s() - t_start < p.at_s {
                return true;
            }
            if p.duration_s > 0.0 {
                let n = ((p.duration_s / dt).round() as usize).max(1);
                pulses.push((p.dv_world * (m / (n as f64 * dt)), n));
            } else {
                let qvel = sim.data_mut().qvel_mut();
                for (v, dv) in qvel[..3].iter_mut().zip(p.dv_world.iter()) {
                    *v += dv;
                }
            }
            false
        });
        if had_pulses || !pulses.is_empty() {
            sim.set_trunk_force(pulses.iter().map(|p| p.0).sum());
        }
        let t5 = Instant::now();
        let stats = &mut self.stats;
        if controller.plan().is_some_and(|p| p.speed_cap_mps.is_some()) {
            stats.slowed_steps += 1;
        }
        let planning = controller.last_planning_time_s();
        if let Some(ev) = &output.mpc_event {
            stats.mpc_solves += 1;
            stats.mpc_solve_times_s.push(ev.solve_time_s);
            stats.mpc_friction_min = Some(
                stats
                    .mpc_friction_min
                    .map_or(ev.friction_coefficient, |m| m.min(ev.friction_coefficient)),
            );
            stats.mpc_friction_last = Some(ev.friction_coefficient);
            stats.mpc_friction_sum += ev.friction_coefficient;
            if !ev.status.is_solved() {
                stats.mpc_failures += 1;
            }
            stats.stages.mpc_s += ev.solve_time_s;
        }
        let control_s = (t3 - t1).as_secs_f64() - update.estimate_s;
        let solve_s = output.mpc_event.as_ref().map_or(0.0, |ev| ev.solve_time_s);
        stats.stages.leg_control_s += control_s - solve_s - planning;
        // Physics includes reading the state (and the estimator, when there is one).
        stats.stages.physics_s +=
            (t1 - t0).as_secs_f64() + update.estimate_s + (t5 - t4).as_secs_f64();
        stats.stages.planner_s += planning;
        stats.stages.observer_s += (t4 - t3).as_secs_f64();
        stats.steps += 1;
        stats.sim_time_s = stats.steps as f64 * self.sim.timestep_s();
        stats.wall_time_s = (t5 - self.wall_start).as_secs_f64();
        let ground_z = self.ground.as_ref().map_or(0.0, |t| {
            t.height_at(truth.body.p_world.x, truth.body.p_world.y)
        });
        let fell = self.limits.fallen_above(&truth, ground_z);
        if fell && !stats.fell {
            stats.fell = true;
            stats.fell_at_s = Some(truth.time_s - t_start);
        }
        StepOutcome { fell }
    }
}

/// Runs `lp` for `duration_s` of simulated time or until a fall, with the command of
/// `command_at(t)`; `observer` sees every step. Returns the loop (stats, estimation error).
pub fn run_closed_loop(
    mut lp: ClosedLoop,
    controller: &mut dyn Controller,
    duration_s: f64,
    mut command_at: impl FnMut(f64) -> VelocityCommand,
    mut observer: impl FnMut(&StepRecord),
) -> ClosedLoop {
    let steps = (duration_s / lp.sim().timestep_s()).round() as usize;
    for _ in 0..steps {
        let command = command_at(lp.sim().time_s());
        if lp.step(controller, command, &mut observer).fell {
            break;
        }
    }
    lp
}
