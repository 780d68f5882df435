//! The tasks PPO trains on.

pub mod cartpole;
pub mod eemp_rl;
pub mod imitation;
pub mod model_free;

use eemp_sim::closed_loop::{ClosedLoop, StateSource};

/// An A1 task steps the robot through one [`ClosedLoop`]; that is what lets training put it on
/// an estimator.
pub trait OnClosedLoop {
    fn closed_loop_mut(&mut self) -> &mut ClosedLoop;

    /// Observes (and, for EEMP, controls) through `source` from now on: the policy then trains
    /// on what the robot senses (`estimator = "kf"` in the training config).
    fn set_state_source(&mut self, source: &StateSource) -> Result<(), String> {
        self.closed_loop_mut()
            .set_state_source(source)
            .map_err(|e| e.to_string())
    }
}
