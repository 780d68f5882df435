//! The energy-efficient motion planner, Algorithm 1 of the paper.
//!
//! Every control step: finish a swing whose ΔT has elapsed; if no swing is running, check
//! eq. (5) for every stance foot and, when one has left its ellipse, start the swing the gait
//! rule picks (touchdown by eq. (6), trajectory by eq. (7)). The body reference is the Euler
//! integral of the commanded velocity from the current state, so with all feet inside their
//! ellipses the MPC keeps pushing the body along on four stance legs.

pub mod ellipse;
// The gait's types sit below the planner (the robot and slip handling read them too).
pub use crate::gait;
pub use plan::{Plan, PlanGeometry};
pub mod params;
pub mod params_stats;
pub mod params_table;
pub mod plan;
pub mod swing_trajectory;
pub mod touchdown;

use crate::body_reference::BodyReference;
use crate::body_state::RobotState;
use crate::config_error::{check_range, ConfigError};
use crate::kinematics::LegKinematics;
use crate::leg::{Leg, LegMap};
use crate::leg_control::FootReference;
pub use gait::{FreePairing, Gait, WalkSupport};
use nalgebra::{Rotation3, Vector2, Vector3};
pub use params::PlannerParams;
use serde::{Deserialize, Serialize};
pub use swing_trajectory::SwingTrajectory;

/// Eq. (6)'s factor on V_des·ΔT as the paper's text prints it (its Algorithm 1 uses 1).
pub const PAPER_PROGRESS_FACTOR: f64 = 0.5;

/// Allowed [`PlannerConfig::progress_factor`] (also for a sweep's and a table's factor).
pub const PROGRESS_FACTOR_RANGE: [f64; 2] = [0.0, 2.0];

/// Allowed `PlannerConfig::ellipse_friction_factor` (0: off).
pub const ELLIPSE_FRICTION_FACTOR_RANGE: [f64; 2] = [0.0, 3.0];

/// Allowed `PlannerConfig::touchdown_friction_factor` (0: off).
pub const TOUCHDOWN_FRICTION_FACTOR_RANGE: [f64; 2] = [0.0, 3.0];

/// The gait's `PlannerConfig::touchdown_friction_factor` where the config leaves it unset:
/// `settings/<gait>.toml`'s (the trot's and the free gait's 0.5, the walk's 0, the paper's
/// unbounded step; why, in those files).
pub fn default_touchdown_friction_factor(gait: Gait) -> f64 {
    crate::gait_settings::gait_number(&gait.to_string(), "planner", "touchdown_friction_factor")
}

/// The gait's `PlannerConfig::ellipse_friction_factor` where the config leaves it unset:
/// `settings/<gait>.toml`'s (1 for the trot and the free gait, 0, off, for the walk).
pub fn default_ellipse_friction_factor(gait: Gait) -> f64 {
    crate::gait_settings::gait_number(&gait.to_string(), "planner", "ellipse_friction_factor")
}

/// How much wider than eq. (6)'s commanded touchdown offset an ellipse shrunk into the friction
/// cone stays: a foot that lands outside its ellipse swings again, so an ellipse shrunk below the
/// commanded offset makes the robot re-step where it should walk. At 1.25 the trot's table at
/// 0.5 m/s (r_x 0.07 m, offset 0.0625 m) is left alone even on a 0.2 floor (cone 0.056 m).
pub const STRIDE_MARGIN: f64 = 1.25;

/// Settings of the planner other than the five tuned parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlannerConfig {
    pub gait: Gait,
    /// Factor on V_des·ΔT in eq. (6): ½ as in the paper's eq. (6) (default), 1 as in its
    /// Algorithm 1.
    pub progress_factor: f64,
    /// The body reference follows a step in the command at most this fast, m/s² (the MPC
    /// otherwise asks for forces the friction cone cannot give). 0.5 by default: started from
    /// rest at a high speed the free gait's first swings are single-leg ones, which cannot keep
    /// up with feet leaving their ellipses as fast as a quicker reference drives them out.
    pub max_accel_mps2: f64,
    /// Re-evaluate eq. (6) at every control step of a running swing with the velocity measured
    /// then, and move the touchdown point accordingly (as the MIT Cheetah controllers do). On
    /// by default: a touchdown fixed at lift-off cannot catch the trunk tipping about the
    /// diagonal of a trot pair, which made a Table II trot at 0.1 m/s track to 0.157 m/s RMSE
    /// instead of 0.059 (see the README's walking table).
    pub retarget_swing: bool,
    /// Show the MPC the swings Algorithm 1 will start within its horizon (eq. (5) checked on
    /// the feet carried back at the commanded velocity), not only the running ones, so it can
    /// shift the trunk before a foot lifts. The paper's schedule holds only the running swings;
    /// preview is on by default because, without it, the MPC meets each lift-off unprepared and
    /// the trunk tips over the support line: Table II free gait at 0.3 m/s tracked to
    /// 0.139 m/s RMSE without preview and 0.029 with it (the README's walking table).
    pub preview_swings: bool,
    /// When the free gait swings a leg's diagonal partner with it (see [`FreePairing`]); the
    /// trot and the walk ignore it.
    pub free_pairing: FreePairing,
    /// Whether the walk passes over a leg whose lone swing would leave the capture point of the
    /// velocity error outside the other feet (see [`WalkSupport`]); the trot and the free gait
    /// ignore it.
    pub walk_support: WalkSupport,
    /// Take the first step as soon as a horizontal speed is commanded, instead of waiting for
    /// a foot to leave its ellipse (every ellipse value is raised by 1 until the first swing):
    /// with a wide ellipse the trunk otherwise runs up to r_x ahead of its feet before the
    /// first lift-off. Off by default (the shipped tables and reports were made without it).
    pub first_step_on_command: bool,
    /// Keeps the placement ellipses inside the friction cone seen from the hip: r_x, r_y ≤
    /// factor · μ̂ · X_z, μ̂ the slip detector's coefficient ([`PlannerParams::within_friction_cone`]).
    /// 0 turns it off. At the nominal μ̂ = 0.6 it never binds (Table I's widest ellipse,
    /// 0.15 m, is below 0.6 · 0.28 m), so it only acts once slips have lowered μ̂: a foot placed
    /// further from the hip than the cone reaches cannot brake the trunk on that floor, so the
    /// trot's wide slow-speed ellipses (r_x 0.15 m, r_y 0.10 m at 0.1 m/s) fall on a 0.2 floor
    /// where ellipses inside the cone walk. `None` (the default): the gait's, 1 for
    /// the trot and the free gait, 0 for the walk ([`default_ellipse_friction_factor`];
    /// [`PlannerConfig::ellipse_friction_factor_in_force`]).
    pub ellipse_friction_factor: Option<f64>,
    /// Keeps eq. (6)'s feedback term √(X_z/g)·(V_cur − V_des) at most factor · μ̂ · X_z long
    /// (μ̂ the MPC's friction coefficient, the slip detector's where it runs;
    /// [`touchdown::progress`]); 0 turns it off. The paper's capture step assumes the foot can
    /// brake the trunk with a leg force leaning as far as the step; on a slippery floor it
    /// cannot, and the wide step makes the trunk roll over its diagonal under a side push on a
    /// slippery floor. At the nominal μ̂ = 0.6 and the default ½ it binds only above a
    /// 0.5 m/s velocity error. `None` (the default): the gait's
    /// ([`default_touchdown_friction_factor`]; [`PlannerConfig::touchdown_friction_factor_in_force`]).
    pub touchdown_friction_factor: Option<f64>,
    /// Hold the commanded displacement, not only the speed: the body reference's horizontal
    /// position is the commanded velocity integrated over time, kept within this distance of
    /// the trunk, m. A trunk that lags the command (EEMP steps only when a foot leaves its
    /// ellipse, and the MPC's velocity error alone leaves a standing lag) is pulled towards where
    /// the command would have it, at most this far, so a push or a fall-back never winds it up.
    /// 0 (the default, the paper's): the reference starts at the trunk at every step.
    pub position_error_max_m: f64,
}

/// Allowed [`PlannerConfig::position_error_max_m`], m.
pub const POSITION_ERROR_MAX_RANGE: [f64; 2] = [0.0, 0.5];

impl Default for PlannerConfig {
    fn default() -> Self {
        PlannerConfig {
            gait: Gait::Trot,
            progress_factor: PAPER_PROGRESS_FACTOR,
            max_accel_mps2: 0.5,
            retarget_swing: true,
            preview_swings: true,
            free_pairing: FreePairing::default(),
            walk_support: WalkSupport::default(),
            first_step_on_command: false,
            ellipse_friction_factor: None,
            touchdown_friction_factor: None,
            position_error_max_m: 0.0,
        }
    }
}

impl PlannerConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        let [lo, hi] = PROGRESS_FACTOR_RANGE;
        check_range("planner.progress_factor", self.progress_factor, lo, hi)?;
        check_range("planner.max_accel_mps2", self.max_accel_mps2, 0.05, 20.0)?;
        let [lo, hi] = POSITION_ERROR_MAX_RANGE;
        check_range(
            "planner.position_error_max_m",
            self.position_error_max_m,
            lo,
            hi,
        )?;
        if let Some(f) = self.ellipse_friction_factor {
            let [lo, hi] = ELLIPSE_FRICTION_FACTOR_RANGE;
            check_range("planner.ellipse_friction_factor", f, lo, hi)?;
        }
        if let Some(f) = self.touchdown_friction_factor {
            let [lo, hi] = TOUCHDOWN_FRICTION_FACTOR_RANGE;
            check_range("planner.touchdown_friction_factor", f, lo, hi)?;
        }
        self.free_pairing.validate("planner.free_pairing")?;
        self.walk_support.validate("planner.walk_support")
    }

    /// The ellipses' cone factor in force: the config's, else the gait's.
    pub fn ellipse_friction_factor_in_force(&self) -> f64 {
        self.ellipse_friction_factor
            .unwrap_or_else(|| default_ellipse_friction_factor(self.gait))
    }

    /// The capture step's bound in force: the config's, else the gait's.
    pub fn touchdown_friction_factor_in_force(&self) -> f64 {
        self.touchdown_friction_factor
            .unwrap_or_else(|| default_touchdown_friction_factor(self.gait))
    }

    /// `params` with the ellipses inside the friction cone of coefficient `mu`
    /// ([`PlannerParams::within_friction_cone`] with this config's factor), each axis kept at
    /// least [`STRIDE_MARGIN`] × eq. (6)'s offset at the commanded velocity.
    pub fn within_friction_cone(
        &self,
        params: &PlannerParams,
        mu: f64,
        command: &VelocityCommand,
    ) -> PlannerParams {
        let v = Vector2::new(command.vx_mps, command.vy_mps);
        let offset = touchdown::progress(
            &v,
            &v,
            params.swing_time_s,
            params.body_height_m,
            self.progress_factor,
            f64::INFINITY,
        );
        params.within_friction_cone(
            mu,
            self.ellipse_friction_factor_in_force(),
            [
                STRIDE_MARGIN * offset.x.abs(),
                STRIDE_MARGIN * offset.y.abs(),
            ],
        )
    }
}

/// The operator's command in the heading frame (yaw-aligned, horizontal).
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct VelocityCommand {
    /// Forward speed, m/s.
    pub vx_mps: f64,
    /// Lateral speed (left positive), m/s.
    pub vy_mps: f64,
    /// Yaw rate, rad/s.
    pub yaw_rate_rps: f64,
}

impl VelocityCommand {
    /// The same command with its horizontal speed at most `max_speed_mps` (direction and yaw
    /// rate kept).
    pub fn with_speed_at_most(&self, max_speed_mps: f64) -> Self {
        let speed = self.vx_mps.hypot(self.vy_mps);
        if speed <= max_speed_mps || !speed.is_finite() {
            return *self;
        }
        let k = max_speed_mps.max(0.0) / speed;
        VelocityCommand {
            vx_mps: self.vx_mps * k,
            vy_mps: self.vy_mps * k,
            ..*self
        }
    }
}

/// One leg's running swing: when it started, its eq. (7) trajectory (world frame, see
/// [`EemPlanner::start_swing`]) and its eq. (6) touchdown point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlannedSwing {
    pub start_s: f64,
    pub trajectory: SwingTrajectory,
    /// Predicted touchdown point (world), for the MPC's view of the horizon.
    pub touchdown_world: Vector3<f64>,
}

impl PlannedSwing {
    /// Whether the swing is running at `t` (s).
    pub fn covers(&self, t: f64) -> bool {
        t >= self.start_s && t < self.start_s + self.trajectory.duration_s
    }
}

/// Algorithm 1 with its memory: the running swings, the previous swing's legs, step counts.
#[derive(Clone)]
pub struct EemPlanner {
    config: PlannerConfig,
    kinematics: LegKinematics,
    foot_radius_m: f64,
    horizon: usize,
    dt_s: f64,
    swings: LegMap<Option<PlannedSwing>>,
    previous_legs: Vec<Leg>,
    steps: LegMap<usize>,
    /// Slew-limited velocity reference (heading frame), m/s.
    v_ref: Vector2<f64>,
    /// The commanded velocity integrated into a position (world x, y), m, with
    /// [`PlannerConfig::position_error_max_m`].
    p_ref: Option<Vector2<f64>>,
    last_t: Option<f64>,
}

impl EemPlanner {
    pub fn new(
        config: PlannerConfig,
        kinematics: LegKinematics,
        foot_radius_m: f64,
        horizon: usize,
        dt_s: f64,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        // The gait's factors looked up once, not at every control step.
        let config = PlannerConfig {
            ellipse_friction_factor: Some(config.ellipse_friction_factor_in_force()),
            touchdown_friction_factor: Some(config.touchdown_friction_factor_in_force()),
            ..config
        };
        Ok(EemPlanner {
            config,
            kinematics,
            foot_radius_m,
            horizon,
            dt_s,
            swings: LegMap::splat(None),
            previous_legs: Vec::new(),
            steps: LegMap::splat(0),
            v_ref: Vector2::zeros(),
            p_ref: None,
            last_t: None,
        })
    }

    pub fn config(&self) -> &PlannerConfig {
        &self.config
    }

    /// Number of swings started per leg so far.
    pub fn steps(&self) -> LegMap<usize> {
        self.steps
    }

    /// eq. (5)'s left-hand side for every foot, using the heading frame (yaw only).
    pub fn ellipse_values(
        &self,
        state: &RobotState,
        feet_world: &LegMap<Vector3<f64>>,
        params: &PlannerParams,
    ) -> LegMap<f64> {
        LegMap::from_fn(|leg| {
            ellipse::ellipse_value(
                &self.p_ell(leg, state, feet_world),
                params.ellipse_rx_m,
                params.ellipse_ry_m,
            )
        })
    }

    /// Foot relative to its ellipse centre (the nominal foothold under the hip), heading frame.
    fn p_ell(
        &self,
        leg: Leg,
        state: &RobotState,
        feet_world: &LegMap<Vector3<f64>>,
    ) -> Vector2<f64> {
        let body = &state.body;
        let centre_world =
            body.p_world + body.r_world_body * self.kinematics.nominal_foot_body(leg);
        let yaw = body.rpy().z;
        let d =
            Rotation3::from_axis_angle(&Vector3::z_axis(), -yaw) * (feet_world[leg] - centre_world);
        Vector2::new(d.x, d.y)
    }

    /// One iteration of Algorithm 1 at time `t` (s). `friction_coefficient` is the one the MPC
    /// uses (the slip detector's where it runs): it bounds eq. (6)'s feedback step
    /// ([`PlannerConfig::touchdown_friction_factor`]).
    pub fn plan(
        &mut self,
        t: f64,
        state: &RobotState,
        feet_world: &LegMap<Vector3<f64>>,
        command: &VelocityCommand,
        params: &PlannerParams,
        friction_coefficient: f64,
    ) -> Plan {
        let body = &state.body;
        let yaw = body.rpy().z;
        let heading = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw);
        let dt_ctrl = self.last_t.map(|lt| (t - lt).max(0.0)).unwrap_or(0.0);
        self.last_t = Some(t);
        let v_cmd = Vector2::new(command.vx_mps, command.vy_mps);
        let dv = v_cmd - self.v_ref;
        let max_dv = self.config.max_accel_mps2 * dt_ctrl;
        self.v_ref += if dv.norm() > max_dv {
            dv * (max_dv / dv.norm())
        } else {
            dv
        };
        // Where the reference starts: the trunk, or the integrated command near it.
        let origin = match self.config.position_error_max_m {
            max if max > 0.0 => {
                let here = body.p_world.xy();
                let v_world = heading * Vector3::new(self.v_ref.x, self.v_ref.y, 0.0);
                let mut p = self.p_ref.unwrap_or(here) + v_world.xy() * dt_ctrl;
                let e = p - here;
                if e.norm() > max {
                    p = here + e * (max / e.norm());
                }
                self.p_ref = Some(p);
                Vector3::new(p.x, p.y, body.p_world.z)
            }
            _ => body.p_world,
        };

        // "Swing phase complete": the legs land and rejoin the stance set.
        for leg in Leg::ALL {
            if self.swings[leg].is_some_and(|s| !s.covers(t)) {
                self.swings[leg] = None;
            }
        }
        // Eq. (6) for running swings and new ones alike: the same state and reference.
        let prog = self.touchdown_progress(state, params, friction_coefficient);
        if self.config.retarget_swing {
            self.retarget_swings(t, state, &prog);
        }
        // Stance feet on the ground: the ground height under the robot.
        let stance = self.swings.map(|_, s| s.is_none());
        let (sum_z, n_z) = Leg::ALL
            .iter()
            .filter(|l| stance[**l])
            .fold((0.0, 0usize), |(s, n), l| (s + feet_world[*l].z, n + 1));
        let ground_z = if n_z > 0 {
            sum_z / n_z as f64 - self.foot_radius_m
        } else {
            0.0
        };

        let kick = self.config.first_step_on_command
            && self.previous_legs.is_empty()
            && v_cmd.norm() >= 0.01;
        // The walk's support check as it applies under this command.
        let walk_support = self.config.walk_support.in_force(v_cmd.norm());
        let legs = self.next_legs(state, feet_world, params, &stance, kick, &walk_support);
        if !legs.is_empty() {
            for (leg, swing) in
                self.start_swing(t, state, feet_world, &legs, params, ground_z, &prog)
            {
                self.swings[leg] = Some(swing);
                self.steps[leg] += 1;
            }
            self.previous_legs = legs;
        }
        let stance = self.swings.map(|_, s| s.is_none());

        // Body reference: Euler integration of the commanded velocity from `origin`.
        let reference_at = |tau: f64| -> BodyReference {
            let yaw_tau = yaw + command.yaw_rate_rps * tau;
            let v_world = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw_tau)
                * Vector3::new(self.v_ref.x, self.v_ref.y, 0.0);
            let mut p = origin + heading * Vector3::new(self.v_ref.x, self.v_ref.y, 0.0) * tau;
            p.z = ground_z + params.body_height_m;
            BodyReference {
                rpy: Vector3::new(0.0, 0.0, yaw_tau),
                p_world: p,
                omega_world: Vector3::new(0.0, 0.0, command.yaw_rate_rps),
                v_world,
            }
        };
        let (contacts_horizon, feet_horizon_world) =
            self.contact_schedule(t, state, feet_world, params, ground_z, &walk_support);
        let swing = self
            .swings
            .map(|_, s| s.map(|s| world_to_body(&s.trajectory.sample(t - s.start_s), state)));
        let geometry = PlanGeometry {
            ellipse_centres_world: LegMap::from_fn(|leg| {
                let mut c =
                    body.p_world + body.r_world_body * self.kinematics.nominal_foot_body(leg);
                c.z = ground_z + self.foot_radius_m;
                c
            }),
            heading_yaw_rad: yaw,
            ellipse_rx_m: params.ellipse_rx_m,
            ellipse_ry_m: params.ellipse_ry_m,
            ellipse_values: self.ellipse_values(state, feet_world, params),
            swings: self.swings,
        };
        Plan {
            stance,
            swing,
            body_now: reference_at(0.0),
            body_horizon: (1..=self.horizon)
                .map(|k| reference_at(k as f64 * self.dt_s))
                .collect(),
            feet_horizon_world,
            contacts_horizon,
            params: Some(*params),
            geometry: Some(geometry),
            speed_cap_mps: None,
        }
    }

    /// C_ref and the foot positions over the MPC horizon: the running swings (feet in the air
    /// until their ΔT ends, then at their touchdown points), and with `preview_swings` also
    /// the swings Algorithm 1 would start later in the horizon if the trunk moved at the
    /// commanded velocity.
    fn contact_schedule(
        &self,
        t: f64,
        state: &RobotState,
        feet_world: &LegMap<Vector3<f64>>,
        params: &PlannerParams,
        ground_z: f64,
        walk_support: &WalkSupport,
    ) -> (Vec<LegMap<bool>>, Vec<LegMap<Vector3<f64>>>) {
        let body = &state.body;
        let heading = Rotation3::from_axis_angle(&Vector3::z_axis(), body.rpy().z);
        let v_ref_world = heading * Vector3::new(self.v_ref.x, self.v_ref.y, 0.0);
        let centre_now = LegMap::from_fn(|leg| {
            body.p_world + body.r_world_body * self.kinematics.nominal_foot_body(leg)
        });
        // Each leg's (start, end, touchdown) swing, running or predicted.
        let mut swings = self.swings.map(|_, s| {
            s.map(|s| {
                (
                    s.start_s,
                    s.start_s + s.trajectory.duration_s,
                    s.touchdown_world,
                )
            })
        });
        let mut feet = *feet_world;
        let mut previous = self.previous_legs.clone();
        let mut contacts_horizon = Vec::with_capacity(self.horizon);
        let mut feet_horizon_world = Vec::with_capacity(self.horizon);
        for k in 0..self.horizon {
            let tk = t + k as f64 * self.dt_s;
            for leg in Leg::ALL {
                if let Some((_, end, touchdown)) = swings[leg] {
                    if tk >= end {
                        feet[leg] = touchdown;
                        swings[leg] = None;
                    }
                }
            }
            if self.config.preview_swings && k > 0 && swings.0.iter().all(Option::is_none) {
                let values = LegMap::from_fn(|leg| {
                    let centre = centre_now[leg] + v_ref_world * (tk - t);
                    let d = heading.inverse() * (feet[leg] - centre);
                    ellipse::ellipse_value(
                        &Vector2::new(d.x, d.y),
                        params.ellipse_rx_m,
                        params.ellipse_ry_m,
                    )
                });
                let trunk = body.p_world + v_ref_world * (tk - t);
                let legs = self.choose_swing(&values, &previous, &trunk, &feet, walk_support);
                let end = tk + params.swing_time_s;
                // Eq. (6) with the trunk on command: only the feed-forward term.
                let prog = heading
                    * Vector3::new(self.v_ref.x, self.v_ref.y, 0.0)
                    * (params.swing_time_s * self.config.progress_factor);
                for leg in &legs {
                    let mut touchdown = centre_now[*leg] + v_ref_world * (end - t) + prog;
                    touchdown.z = ground_z + self.foot_radius_m;
                    swings[*leg] = Some((tk, end, touchdown));
                }
                if !legs.is_empty() {
                    previous = legs;
                }
            }
            contacts_horizon.push(LegMap::from_fn(|leg| swings[leg].is_none()));
            feet_horizon_world.push(LegMap::from_fn(|leg| match swings[leg] {
                Some((_, _, touchdown)) => touchdown,
                None => feet[leg],
            }));
        }
        (contacts_horizon, feet_horizon_world)
    }

    /// The legs whose swing starts now: none while a swing runs ("swing phase complete" in
    /// Algorithm 1), else the gait rule's choice among the stance feet outside their ellipses.
    /// (Letting the free gait start a diagonal partner mid-swing was tried: it tracks worse at
    /// low speed and does not keep the robot up at high speed.)
    fn next_legs(
        &self,
        state: &RobotState,
        feet_world: &LegMap<Vector3<f64>>,
        params: &PlannerParams,
        stance: &LegMap<bool>,
        first_step_now: bool,
        walk_support: &WalkSupport,
    ) -> Vec<Leg> {
        if stance.0.iter().any(|s| !s) {
            return Vec::new();
        }
        let mut values = self.ellipse_values(state, feet_world, params);
        if first_step_now {
            // Every foot "outside", in the order of how far out it is.
            values = values.map(|_, v| v + 1.0);
        }
        self.choose_swing(
            &values,
            &self.previous_legs,
            &self.support_point(state, params),
            feet_world,
            walk_support,
        )
    }

    /// The point whose support the swing choice checks (world, m): the trunk's origin for the
    /// free gait; for the walk the capture point of the velocity error, the trunk carried by
    /// eq. (6)'s feedback term ([`WalkSupport`]). At the commanded velocity both are the trunk.
    fn support_point(&self, state: &RobotState, params: &PlannerParams) -> Vector3<f64> {
        let body = &state.body;
        if self.config.gait != Gait::Walk {
            return body.p_world;
        }
        let v = body.v_heading();
        let error = touchdown::feedback(&self.v_ref, &Vector2::new(v.x, v.y), params.body_height_m);
        body.p_world
            + Rotation3::from_axis_angle(&Vector3::z_axis(), body.rpy().z)
                * Vector3::new(error.x, error.y, 0.0)
    }

    /// The gait rule's choice, given the point whose support it checks and where the feet are
    /// (world frame; [`Self::support_point`]: the trunk's origin, not the centre of mass the
    /// MPC's model offsets from it), with the walk's support check as in force under the
    /// command ([`WalkSupport::in_force`]).
    fn choose_swing(
        &self,
        values: &LegMap<f64>,
        previous: &[Leg],
        p_support_world: &Vector3<f64>,
        feet_world: &LegMap<Vector3<f64>>,
        walk_support: &WalkSupport,
    ) -> Vec<Leg> {
        let xy = |v: &Vector3<f64>| Vector2::new(v.x, v.y);
        let lone_swing_margin_m = |leg: Leg| {
            let mut others = Leg::ALL.into_iter().filter(|l| *l != leg);
            let mut next = || xy(&feet_world[others.next().expect("three other legs")]);
            gait::triangle_margin(&xy(p_support_world), [next(), next(), next()])
        };
        gait::next_swing(
            self.config.gait,
            gait::SwingInputs {
                ellipse_values: values,
                lone_swing_margin_m: &lone_swing_margin_m,
                // The reference, heading frame: backwards once it points back.
                backward: self.v_ref.x < 0.0,
            },
            previous,
            &self.config.free_pairing,
            walk_support,
        )
    }

    /// Moves the touchdown point of every running swing to where eq. (6) puts it now: the
    /// ellipse centre carried forward at the commanded velocity for the time left (as at
    /// lift-off), plus p_prog with the velocity measured now. (Carrying the centre forward at
    /// the measured velocity instead tracked worse at 0.5–1.0 m/s.) The lift-off point stays, so the trajectory keeps its
    /// shape and only its x/y span changes.
    fn retarget_swings(&mut self, t: f64, state: &RobotState, prog: &Vector2<f64>) {
        let body = &state.body;
        let heading = Rotation3::from_axis_angle(&Vector3::z_axis(), body.rpy().z);
        for leg in Leg::ALL {
            let Some(swing) = self.swings[leg].as_mut() else {
                continue;
            };
            let remaining_s = swing.start_s + swing.trajectory.duration_s - t;
            if t <= swing.start_s || remaining_s <= 0.0 {
                continue;
            }
            let centre_world =
                body.p_world + body.r_world_body * self.kinematics.nominal_foot_body(leg);
            let target = centre_world
                + heading * Vector3::new(self.v_ref.x, self.v_ref.y, 0.0) * remaining_s
                + heading * Vector3::new(prog.x, prog.y, 0.0);
            let start = swing.trajectory.start_body;
            swing.trajectory.displacement_xy = Vector2::new(target.x - start.x, target.y - start.y);
            swing.touchdown_world.x = target.x;
            swing.touchdown_world.y = target.y;
        }
    }

    /// Eq. (6)'s p_prog for the touchdowns planned at this step, heading frame (m), its feedback
    /// term bounded by `friction_coefficient` ([`PlannerConfig::touchdown_friction_factor`]).
    fn touchdown_progress(
        &self,
        state: &RobotState,
        params: &PlannerParams,
        friction_coefficient: f64,
    ) -> Vector2<f64> {
        let factor = self.config.touchdown_friction_factor_in_force();
        let feedback_limit_m = if factor > 0.0 && friction_coefficient.is_finite() {
            factor * friction_coefficient * params.body_height_m
        } else {
            f64::INFINITY
        };
        let v_cur = state.body.v_heading();
        touchdown::progress(
            &self.v_ref,
            &Vector2::new(v_cur.x, v_cur.y),
            params.swing_time_s,
            params.body_height_m,
            self.config.progress_factor,
            feedback_limit_m,
        )
    }

    #[allow(clippy::too_many_arguments)] // when, the state, the feet, which legs, the parameters, the ground and eq. (6): each used once
    fn start_swing(
        &self,
        t: f64,
        state: &RobotState,
        feet_world: &LegMap<Vector3<f64>>,
        legs: &[Leg],
        params: &PlannerParams,
        ground_z: f64,
        prog: &Vector2<f64>,
    ) -> Vec<(Leg, PlannedSwing)> {
        let body = &state.body;
        let yaw = body.rpy().z;
        let heading = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw);
        let mut swings = Vec::with_capacity(legs.len());
        for leg in legs {
            // Eq. (7)'s displacement p_prog − p_ell is relative to the hip; the hip itself moves
            // with the body during the swing. Laying the sinusoids in the world frame from the
            // lift-off point to (hip at touchdown + p_prog) lands the foot at the same place as
            // the paper's construction but with zero ground speed; a trajectory fixed to the
            // trunk would touch down moving at the trunk's speed and skid.
            let p_ell = self.p_ell(*leg, state, feet_world);
            let travel =
                heading * Vector3::new(self.v_ref.x, self.v_ref.y, 0.0) * params.swing_time_s;
            let displacement_world =
                travel + heading * Vector3::new(prog.x - p_ell.x, prog.y - p_ell.y, 0.0);
            let start = feet_world[*leg];
            let trajectory = SwingTrajectory {
                start_body: start,
                displacement_xy: Vector2::new(displacement_world.x, displacement_world.y),
                step_height_m: params.step_height_m,
                duration_s: params.swing_time_s,
            };
            let mut touchdown_world = start + displacement_world;
            touchdown_world.z = ground_z + self.foot_radius_m;
            swings.push((
                *leg,
                PlannedSwing {
                    start_s: t,
                    trajectory,
                    touchdown_world,
                },
            ));
        }
        swings
    }
}

/// A world-frame foot reference seen from the moving trunk (eq. 1 works in the body frame):
/// p_b = Rᵀ(p − p_B), v_b = Rᵀ(v − v_B − ω × (p − p_B)), a_b ≈ Rᵀa (trunk acceleration unknown).
fn world_to_body(reference: &FootReference, state: &RobotState) -> FootReference {
    let body = &state.body;
    let r_inv = body.r_world_body.inverse();
    let rel = reference.p_body - body.p_world;
    FootReference {
        p_body: r_inv * rel,
        v_body: r_inv * (reference.v_body - body.v_world - body.omega_world.cross(&rel)),
        a_body: r_inv * reference.a_body,
    }
}

#[cfg(test)]
mod tests;
