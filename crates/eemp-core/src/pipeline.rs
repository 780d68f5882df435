//! The control update every loop runs — the simulation (`eemp_sim::closed_loop`), the robot
//! (`eemp_hw::runner`) and Python — top to bottom:
//!
//! 1. **estimate**: the linear Kalman filter on the IMU and encoders with each stance leg's
//!    trust from the plan and the last torques ([`crate::estimator`]), or the state as given
//!    (ground truth in simulation, the caller's state in Python);
//! 2. **the controller** ([`Controller`]): for EEMP the planner (Algorithm 1, with the slip
//!    detector's friction estimate), the MPC (eq. 2) and the leg laws (eq. 1), in
//!    [`crate::eemp`];
//! 3. **safety** ([`crate::safety`]) on a robot: the runner passes the torques through the
//!    safety layer, whose watchdog keeps the robot's command timing.
//!
//! The loops differ only in where the sensed state comes from and where the torques go.

use crate::body_state::RobotState;
use crate::controller::{ControlInput, Controller};
use crate::estimator::{ContactTrust, EstimatorInput, ImuReading, LinearKf};
use crate::kinematics::LegKinematics;
use crate::leg::LegMap;
use crate::leg_control::DynamicsModel;
use crate::locomotion::{feet_world, ControlOutput};
use crate::planner::VelocityCommand;
use crate::robot::RobotScale;
use nalgebra::Vector3;
use std::time::Instant;

/// What the loop sensed at one control step.
pub struct Sensed {
    /// The state the loop knows without the filter: the whole state where there is no filter;
    /// with the filter, the joints, the IMU's attitude and a prior of the trunk's position and
    /// velocity (which the filter replaces), at the sensing time.
    pub seen: RobotState,
    /// The IMU's reading (the filter needs it).
    pub imu: Option<ImuReading>,
}

/// The joint-space dynamics the controller is given, at the estimate.
pub trait DynamicsAt {
    /// The model at `estimate`; `full`: the mass matrix and bias too (else kinematics only).
    fn at(&mut self, estimate: &RobotState, full: bool) -> &dyn DynamicsModel;
}

/// A model already evaluated where the caller wants it (the simulator's own state).
pub struct Prepared<'a>(pub &'a dyn DynamicsModel);

impl DynamicsAt for Prepared<'_> {
    fn at(&mut self, _: &RobotState, _: bool) -> &dyn DynamicsModel {
        self.0
    }
}

/// What one update produced.
pub struct Update {
    /// The state the controller acted on.
    pub estimate: RobotState,
    pub feet_world: LegMap<Vector3<f64>>,
    pub output: ControlOutput,
    /// Wall time spent estimating, s (for the loops' time budgets).
    pub estimate_s: f64,
}

/// The estimator's state between updates and the controller's last torques.
#[derive(Clone)]
pub struct ControlPipeline {
    filter: Option<LinearKf>,
    size: RobotScale,
    trust: ContactTrust,
    last_torques: LegMap<Vector3<f64>>,
}

impl ControlPipeline {
    /// A pipeline without a filter (the state is used as sensed), starting at `time_s`, for a
    /// robot of size `size` (the filter's contact trust without a plan follows it).
    pub fn new(time_s: f64, size: RobotScale) -> Self {
        ControlPipeline {
            filter: None,
            size,
            trust: ContactTrust::new(time_s, &size),
            last_torques: LegMap::splat(Vector3::zeros()),
        }
    }

    /// Runs the filter from now on (None: the state as sensed).
    pub fn set_filter(&mut self, filter: Option<LinearKf>) {
        self.filter = filter;
    }

    pub fn filter_mut(&mut self) -> Option<&mut LinearKf> {
        self.filter.as_mut()
    }

    /// Starts over at `time_s`: no stance legs trusted yet, no torques sent.
    pub fn restart(&mut self, time_s: f64) {
        self.trust = ContactTrust::new(time_s, &self.size);
        self.last_torques = LegMap::splat(Vector3::zeros());
    }

    /// The torques of the last update.
    pub fn last_torques(&self) -> &LegMap<Vector3<f64>> {
        &self.last_torques
    }

    /// One control update: estimate → controller (plan → MPC → leg control).
    ///
    /// # Panics
    /// With a filter ([`ControlPipeline::set_filter`]) and no IMU reading in `sensed`: a loop
    /// that runs the filter reads the IMU at every step.
    pub fn update(
        &mut self,
        sensed: &Sensed,
        kin: &LegKinematics,
        controller: &mut dyn Controller,
        command: VelocityCommand,
        dynamics: &mut dyn DynamicsAt,
    ) -> Update {
        let t0 = Instant::now();
        let estimate = match &mut self.filter {
            Some(kf) => {
                let imu = sensed.imu.expect("the filter runs on the IMU's reading");
                let trust =
                    self.trust
                        .update(controller.plan(), kin, &sensed.seen, &self.last_torques);
                kf.update(&EstimatorInput {
                    time_s: sensed.seen.time_s,
                    imu,
                    joints: sensed.seen.joints,
                    contact_trust: trust,
                })
            }
            None => sensed.seen,
        };
        let estimate_s = t0.elapsed().as_secs_f64();
        let feet = feet_world(kin, &estimate);
        let model = dynamics.at(&estimate, controller.needs_dynamics());
        let output = controller.control(&ControlInput {
            state: &estimate,
            feet_world: &feet,
            command,
            dynamics: model,
        });
        self.last_torques = output.torques;
        Update {
            estimate,
            feet_world: feet,
            output,
            estimate_s,
        }
    }
}
