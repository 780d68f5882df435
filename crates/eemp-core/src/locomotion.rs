//! One control step, top to bottom: plan in → MPC (at its own rate) → leg torques out.
//!
//! The plan comes from the EEMP planner when walking, or from a body-motion profile when
//! standing; the controller does not care which.

use crate::body_state::RobotState;
use crate::config_error::{check_range, ConfigError};
use crate::convex_mpc::{ConvexMpc, MpcConfig, MpcInput, MpcStatus};
use crate::kinematics::LegKinematics;
use crate::leg::{Leg, LegMap};
use crate::leg_control::{
    clamp_torque, stance_torque, swing_torque, DynamicsModel, FootMeasurement, FootReference,
    SwingGains,
};
use crate::robot::RobotConfig;
use crate::slip::{FrictionAdapter, SlipConfig};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

// What a planner hands the controller: defined with the planner, which makes it.
pub use crate::planner::{Plan, PlanGeometry};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerConfig {
    pub mpc: MpcConfig,
    pub swing: SwingGains,
    /// Time between MPC solves, s; a change of the stance set triggers an extra solve. 20 ms:
    /// with swing preview and retargeting (planner) the Table II walks at 20 ms track within
    /// ±0.015 m/s RMSE of the 10 ms ones (free at 0.5 m/s better, 0.048 vs 0.128) for half the
    /// MPC time. (Before those, 20 ms made the free gait fall.)
    pub mpc_period_s: f64,
    /// Lowering the MPC's friction coefficient when a stance foot slides ([`crate::slip`]).
    pub slip: SlipConfig,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        ControllerConfig {
            mpc: MpcConfig::default(),
            swing: SwingGains::default(),
            mpc_period_s: 0.02,
            slip: SlipConfig::default(),
        }
    }
}

impl ControllerConfig {
    /// This config with what it leaves open filled from the robot file's `[control]`: the slip
    /// detector's start (else [`crate::slip::CAUTIOUS_START`]), the MPC's heat weight (else 0)
    /// and its foot-force bound ([`RobotConfig::mpc_f_max_n`]). The controller calls it, and so
    /// does a run's description before its `--set`, so `eemp config show` sees the values.
    pub fn with_robot_defaults(mut self, robot: &RobotConfig) -> Self {
        self.slip.initial_friction.get_or_insert(
            robot
                .control
                .slip_initial_friction
                .unwrap_or(crate::slip::CAUTIOUS_START),
        );
        self.mpc
            .weight_heat
            .get_or_insert(robot.control.mpc_weight_heat.unwrap_or(0.0));
        if self.mpc.f_max_n.is_none() {
            self.mpc.f_max_n = Some(robot.mpc_f_max_n());
        }
        self
    }

    pub fn validate(&self) -> Result<(), ConfigError> {
        self.mpc.validate()?;
        self.swing.validate()?;
        self.slip.validate()?;
        check_range("schedule.mpc_period_s", self.mpc_period_s, 0.001, 0.1)
    }
}

/// Statistics of one MPC solve, for logs and summaries.
#[derive(Clone, Debug, PartialEq)]
pub struct MpcEvent {
    pub status: MpcStatus,
    pub solve_time_s: f64,
    pub qp_size: (usize, usize),
    /// The friction coefficient of this solve's pyramid (lowered after slips).
    pub friction_coefficient: f64,
}

/// What one control step produced.
#[derive(Clone, Debug, PartialEq)]
pub struct ControlOutput {
    /// Joint torques, clamped to the motor limit, N·m.
    pub torques: LegMap<Vector3<f64>>,
    /// Ground-reaction forces in use (world frame), N.
    pub forces_world: LegMap<Vector3<f64>>,
    /// Set when the MPC was solved in this step.
    pub mpc_event: Option<MpcEvent>,
}

#[derive(Clone)]
pub struct LocomotionController {
    config: ControllerConfig,
    kinematics: LegKinematics,
    mpc: ConvexMpc,
    torque_limit_nm: [f64; 3],
    forces_world: LegMap<Vector3<f64>>,
    last_solve_time_s: Option<f64>,
    last_stance: LegMap<bool>,
    friction: FrictionAdapter,
    /// The robot's joint heat coefficients (W/(N·m)²) when the MPC weighs heat.
    heat_coefficients: Option<[f64; 3]>,
}

impl LocomotionController {
    /// The robot's `[control]` defaults fill what `config` leaves open
    /// ([`ControllerConfig::with_robot_defaults`]).
    pub fn new(robot: &RobotConfig, config: ControllerConfig) -> Result<Self, ConfigError> {
        let config = config.with_robot_defaults(robot);
        config.validate()?;
        let weight_heat = config.mpc.weight_heat.unwrap_or(0.0);
        let heat_coefficients = match (weight_heat > 0.0, robot.motor_model()) {
            (false, _) => None,
            (true, Some(m)) => Some(m.heat_coefficient_w_per_nm2),
            (true, None) => {
                return Err(ConfigError::Invalid {
                    name: "mpc.weight_heat".into(),
                    message: format!(
                        "{weight_heat} weighs the motors' heat, and the {} robot file has no \
                         [motor] section to say what it is",
                        robot.name
                    ),
                })
            }
        };
        let body = robot.composite_body(&robot.standing_pose());
        Ok(LocomotionController {
            kinematics: LegKinematics::new(robot),
            mpc: ConvexMpc::new(config.mpc.clone(), body)?,
            torque_limit_nm: robot.leg.torque_limit_nm,
            forces_world: LegMap::splat(Vector3::zeros()),
            last_solve_time_s: None,
            last_stance: LegMap::splat(false),
            friction: FrictionAdapter::new(config.slip.clone(), config.mpc.friction_coefficient)?,
            heat_coefficients,
            config,
        })
    }

    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }

    /// The MPC's friction coefficient now (the slip detector's, when it runs).
    pub fn friction_coefficient(&self) -> f64 {
        self.mpc.friction_coefficient()
    }

    /// Slip handling's speed cap on a floor it found slippery, m/s (None: no cap).
    pub fn speed_cap_mps(&self) -> Option<f64> {
        self.friction.speed_cap_mps()
    }

    /// `clock_s` is the controller's own clock (used for the MPC rate), s.
    pub fn update(
        &mut self,
        clock_s: f64,
        state: &RobotState,
        plan: &Plan,
        dynamics: &dyn DynamicsModel,
    ) -> ControlOutput {
        let due = match self.last_solve_time_s {
            None => true,
            Some(t) => {
                clock_s - t >= self.config.mpc_period_s - 1e-9 || plan.stance != self.last_stance
            }
        };
        if self.config.slip.adapt_friction {
            let reference_speed_mps = plan
                .body_horizon
                .first()
                .map_or(0.0, |r| r.v_world.x.hypot(r.v_world.y));
            let mu = self.friction.update(
                clock_s,
                &plan.stance,
                &self.foot_velocities_world(state),
                &self.forces_world,
                reference_speed_mps,
            );
            if mu != self.mpc.friction_coefficient() {
                self.mpc.set_friction_coefficient(mu);
            }
        }
        let mu = self.mpc.friction_coefficient();
        let mut mpc_event = None;
        if due {
            let started = std::time::Instant::now();
            let heat = self.heat_coefficients.map(|k| {
                LegMap::from_fn(|leg| {
                    let j = self
                        .kinematics
                        .foot_jacobian_body(leg, &state.joints[leg].q);
                    crate::convex_mpc::heat_matrix_decoupled(&j, &state.body.r_world_body, &k)
                })
            });
            let solution = self.mpc.solve(&MpcInput {
                body: &state.body,
                reference: &plan.body_horizon,
                feet_world: &plan.feet_horizon_world,
                contacts: &plan.contacts_horizon,
                heat: heat.as_ref(),
            });
            mpc_event = Some(MpcEvent {
                status: solution.status.clone(),
                solve_time_s: started.elapsed().as_secs_f64(),
                qp_size: solution.qp_size,
                friction_coefficient: mu,
            });
            self.forces_world = solution.forces_world;
            self.last_solve_time_s = Some(clock_s);
            self.last_stance = plan.stance;
        }
        let torques = LegMap::from_fn(|leg| self.leg_torque(leg, state, plan, dynamics));
        let forces_world = LegMap::from_fn(|leg| {
            if plan.stance[leg] {
                self.forces_world[leg]
            } else {
                Vector3::zeros()
            }
        });
        ControlOutput {
            torques,
            forces_world,
            mpc_event,
        }
    }

    fn leg_torque(
        &self,
        leg: Leg,
        state: &RobotState,
        plan: &Plan,
        dynamics: &dyn DynamicsModel,
    ) -> Vector3<f64> {
        let joints = &state.joints[leg];
        let jacobian = self.kinematics.foot_jacobian_body(leg, &joints.q);
        let tau = match (plan.stance[leg], &plan.swing[leg]) {
            (true, _) => {
                stance_torque(&jacobian, &state.body.r_world_body, &self.forces_world[leg])
            }
            (false, Some(reference)) => {
                let foot = FootMeasurement {
                    p_body: self.kinematics.foot_position_body(leg, &joints.q),
                    v_body: jacobian * joints.qd,
                    jacobian,
                };
                swing_torque(
                    reference,
                    &foot,
                    &self.config.swing,
                    &dynamics.leg_dynamics(leg),
                )
            }
            // A leg neither in stance nor given a swing reference holds still in place.
            (false, None) => {
                let p = self.kinematics.foot_position_body(leg, &joints.q);
                let foot = FootMeasurement {
                    p_body: p,
                    v_body: jacobian * joints.qd,
                    jacobian,
                };
                swing_torque(
                    &FootReference {
                        p_body: p,
                        ..Default::default()
                    },
                    &foot,
                    &self.config.swing,
                    &dynamics.leg_dynamics(leg),
                )
            }
        };
        clamp_torque(&tau, &self.torque_limit_nm)
    }

    pub fn kinematics(&self) -> &LegKinematics {
        &self.kinematics
    }

    /// Stance feet slid so far ([`crate::slip`]).
    pub fn slips(&self) -> usize {
        self.friction.slips()
    }

    /// The velocity of each foot's lowest point (where it touches the ground), world frame,
    /// from the state and the encoders: the sphere's centre moves at v + ω × R p_b + R J q̇, and
    /// a foot rolling on the ground (the calf turning) moves its centre without sliding, so
    /// the calf's rotation is taken out: + ω_calf × (−r ẑ).
    fn foot_velocities_world(&self, state: &RobotState) -> LegMap<Vector3<f64>> {
        let body = &state.body;
        let r = body.r_world_body;
        LegMap::from_fn(|leg| {
            let j = &state.joints[leg];
            let p = r * self.kinematics.foot_position_body(leg, &j.q);
            let v_rel = r * (self.kinematics.foot_jacobian_body(leg, &j.q) * j.qd);
            // Written out (not `foot_velocity_relative_world`) to keep the sums' order, and so
            // every earlier result, bit for bit.
            let v_centre = body.v_world + body.omega_world.cross(&p) + v_rel;
            v_centre
                - self.kinematics.foot_rolling_velocity_world(
                    leg,
                    &j.q,
                    &j.qd,
                    &r,
                    &body.omega_world,
                )
        })
    }
}

/// Foot positions in the world frame from the encoders and the trunk pose.
pub fn feet_world(kinematics: &LegKinematics, state: &RobotState) -> LegMap<Vector3<f64>> {
    LegMap::from_fn(|leg| {
        state.body.p_world
            + state.body.r_world_body * kinematics.foot_position_body(leg, &state.joints[leg].q)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_robot_files_slip_start_fills_what_the_run_leaves_open() {
        let mut robot = RobotConfig::a1();
        let start = |robot: &RobotConfig, config: ControllerConfig| {
            LocomotionController::new(robot, config)
                .unwrap()
                .config()
                .slip
                .initial_friction
        };
        assert_eq!(
            start(&robot, ControllerConfig::default()),
            Some(crate::slip::CAUTIOUS_START)
        );
        robot.control.slip_initial_friction = Some(0.25);
        assert_eq!(start(&robot, ControllerConfig::default()), Some(0.25));
        // The run's own start wins.
        let mut own = ControllerConfig::default();
        own.slip.initial_friction = Some(0.4);
        assert_eq!(start(&robot, own), Some(0.4));
        // Out of range in the robot file: named.
        robot.control.slip_initial_friction = Some(7.0);
        let e = robot.validate().unwrap_err().to_string();
        assert!(e.contains("control.slip_initial_friction"), "{e}");
    }
}
