//! The one interface every controller implements — EEMP (planner + MPC + swing law), a joint PD
//! hold, a learned policy — so one closed loop (simulated or on hardware) runs any of them.
//!
//! A control step is a function of explicit inputs (estimated state, measured feet, operator
//! command, the dynamics at this state) to explicit outputs (joint torques and what produced
//! them). The loop calls it at the physics rate; a controller that acts slower (the MPC, a
//! 50 Hz policy) keeps its own clock from `state.time_s`.

use crate::body_state::RobotState;
use crate::leg::LegMap;
use crate::leg_control::DynamicsModel;
use crate::locomotion::{ControlOutput, Plan};
use crate::planner::VelocityCommand;
use nalgebra::Vector3;

/// What a controller reads at one control step.
pub struct ControlInput<'a> {
    /// The state estimate (ground truth in simulation today).
    pub state: &'a RobotState,
    /// Foot positions in the world frame, from the encoders and the trunk pose.
    pub feet_world: &'a LegMap<Vector3<f64>>,
    /// The operator's velocity command (heading frame).
    pub command: VelocityCommand,
    /// Joint-space dynamics at this state; only valid when [`Controller::needs_dynamics`].
    pub dynamics: &'a dyn DynamicsModel,
}

pub trait Controller {
    /// One control step.
    fn control(&mut self, input: &ControlInput) -> ControlOutput;

    /// The plan of the last step, for controllers that have one (traces, figures).
    fn plan(&self) -> Option<&Plan> {
        None
    }

    /// Whether [`ControlInput::dynamics`] must be filled (a mass matrix per step costs time).
    fn needs_dynamics(&self) -> bool {
        true
    }

    /// Wall time the last step spent planning (inside [`Controller::control`]), s, for the
    /// loop's time budget; 0 for controllers without a planner.
    fn last_planning_time_s(&self) -> f64 {
        0.0
    }

    /// Steps (swings started) per leg so far, for controllers that count them.
    fn steps(&self) -> Option<LegMap<usize>> {
        None
    }
}
