//! EEMP simulation: the MuJoCo backend and the closed-loop scenarios built on it.

pub mod backend;
pub mod closed_loop;
pub mod mjcf;
pub mod robot_model;
pub mod scenario;
pub mod sensors;
pub mod stand;
pub mod terrain;
pub mod walk;

pub use backend::{SimError, Simulation};
