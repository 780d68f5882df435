//! Learned controllers for the A1 on the project's one closed loop.
//!
//! - [`env`]: the environment interface and N environments stepped on a worker pool.
//! - [`tasks`]: the model-free baseline ([`tasks::model_free`]), the motion-imitation baseline
//!   ([`tasks::imitation`], on the retargeted dog motions of [`imitation`]) and a cart-pole test task.
//! - [`nn`], [`adam`], [`ppo`], [`normalizer`]: networks on candle, Adam with open state,
//!   the PPO update, running observation normalisation.
//! - [`cma_table`]: CMA-ES on EEMP-RL's residual (the second optimiser), a re-tuned table.
//! - [`train`]: the training loop with `train.csv`, checkpoints and resume.
//! - [`run`]: the one description of a walk by any controller, validated once and run.
//! - [`policy`]: policy files; [`controller`]: a trained policy as a [`eemp_core::controller::Controller`].

// Time, env and parameter indices (t, e, i) are the algorithm's notation here.
#![allow(clippy::needless_range_loop)]

#[cfg(feature = "learning")]
pub mod adam;
pub mod cma_table;
pub mod config;
#[cfg(feature = "learning")]
pub mod controller;
pub mod env;
pub mod imitation;
pub mod mirror;
#[cfg(feature = "learning")]
pub mod nn;
pub mod normalizer;
#[cfg(feature = "learning")]
pub mod policy;
#[cfg(feature = "learning")]
pub mod ppo;
pub mod run;
pub mod tasks;
#[cfg(feature = "learning")]
pub mod tensor_file;
#[cfg(feature = "learning")]
pub mod train;
