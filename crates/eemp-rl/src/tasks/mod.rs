//! The tasks PPO trains on.

pub mod cartpole;
pub mod model_free;
