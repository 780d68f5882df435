//! What the control loop hands the recorder: owned copies, made in microseconds, so that all
//! logging work happens on the recorder's thread.

use eemp_core::body_state::RobotState;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::locomotion::PlanGeometry;
use eemp_core::planner::VelocityCommand;
use nalgebra::Vector3;

/// One sampled control step.
#[derive(Clone, Debug)]
pub struct Frame {
    pub time_s: f64,
    /// The simulator's true state.
    pub truth: RobotState,
    /// What the controller believed (the filter's output); None on ground truth.
    pub estimate: Option<RobotState>,
    pub command: VelocityCommand,
    pub feet_world: LegMap<Vector3<f64>>,
    /// Feet carrying the robot (see `eemp_sim::closed_loop::LOADED_FOOT_N`).
    pub loaded: LegMap<bool>,
    /// Stance legs per the plan (per the contacts without one).
    pub stance: LegMap<bool>,
    /// Ground-reaction forces the controller applies, world frame, N.
    pub forces_world: LegMap<Vector3<f64>>,
    pub torques_nm: LegMap<Vector3<f64>>,
    pub geometry: Option<PlanGeometry>,
    /// The last MPC solve's wall time (s) and friction coefficient; None without an MPC.
    pub mpc: Option<MpcReading>,
    /// Eq. (8)'s CoT and eq. (9)'s manipulability over the run so far.
    pub cot_so_far: Option<f64>,
    pub manipulability_so_far: Option<f64>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MpcReading {
    pub solve_time_s: f64,
    pub friction_coefficient: f64,
}

/// A foot landing: where it landed and where the planner meant it to (eq. 6), world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Touchdown {
    pub time_s: f64,
    pub leg: Leg,
    pub p_foot_world: Vector3<f64>,
    pub planned_world: Option<Vector3<f64>>,
}

/// A push on the trunk as the scenario applies it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PushEvent {
    pub time_s: f64,
    pub p_trunk_world: Vector3<f64>,
    pub dv_world: Vector3<f64>,
}

/// The recorder's input queue.
#[derive(Clone, Debug)]
pub enum Message {
    Frame(Box<Frame>),
    Touchdown(Touchdown),
    Push(PushEvent),
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The file target's queue holds 16384 frames (target.rs): its memory bound rests on a
    /// frame's size (boxed, no heap parts besides the box).
    #[test]
    fn a_queued_frame_stays_small() {
        let bytes = std::mem::size_of::<Frame>();
        println!("a Frame is {bytes} bytes");
        assert!(bytes <= 4096, "a Frame is {bytes} bytes");
    }
}
