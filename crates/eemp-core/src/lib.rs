//! EEMP core: everything that would run on the real robot, with no simulator inside.
//!
//! - [`robot`], [`kinematics`]: the robot description and leg kinematics in named frames.
//! - [`convex_mpc`]: stance control, the paper's eq. (2).
//! - [`leg_control`]: swing control, eq. (1), and the stance torque map.
//! - [`slip`]: the MPC's friction coefficient lowered when a stance foot slides.
//! - [`planner`]: the energy-efficient planner, eqs. (5)–(7) and Algorithm 1.
//! - [`pipeline`]: the control update every loop runs, top to bottom: estimate → controller
//!   (→ safety on a robot).
//! - [`controller`]: the [`controller::Controller`] interface every controller implements;
//!   [`eemp`] (EEMP walking and standing: the planner over [`locomotion`], which runs the MPC
//!   and the leg laws), [`joint_pd`] (joint PD, how policies act).
//! - [`estimator`]: attitude from the IMU and a linear Kalman filter for trunk position and
//!   velocity from IMU + leg kinematics (what the robot knows of itself).
//! - [`safety`]: the safety layer every command to a robot passes (limits, watchdog, damping).
//! - [`energy`]: the motor model and the electrical energy account (what the battery pays).
//! - [`metrics`]: cost of transport (eq. 8) and force manipulability (eq. 9); [`gait_measure`]:
//!   duty factors, pair synchrony and left/right load of any walk.

// Horizon and block indices (k, l, j) are the mathematics here; iterator chains would hide them.
#![allow(clippy::needless_range_loop)]

pub mod body_reference;
pub mod body_state;
pub mod config_error;
pub mod controller;
pub mod convex_mpc;
pub mod eemp;
pub mod energy;
pub mod estimator;
pub mod gait;
pub mod gait_measure;
pub mod gait_settings;
pub mod joint_pd;
pub mod kinematics;
pub mod leg;
pub mod leg_control;
pub mod leg_geometry;
pub mod locomotion;
pub mod metrics;
pub mod pipeline;
pub mod planner;
pub mod robot;
pub mod robot_size;
pub mod safety;
pub mod settings;
pub mod settings_keys;
pub mod slip;
pub mod stand_profile;
pub mod teleop;

pub use leg::{Leg, LegMap};
