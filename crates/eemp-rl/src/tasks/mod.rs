//! The tasks PPO trains on.

pub mod cartpole;
pub mod imitation;
pub mod model_free;
