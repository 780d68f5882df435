//! The tasks PPO trains on.

pub mod cartpole;
pub mod eemp_rl;
pub mod imitation;
pub mod model_free;
