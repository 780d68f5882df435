//! The hardware path, on the core's safety layer:
//!
//! - [`wire`]: the A1's UDP protocol and the Go2's DDS messages, bytes in and out, and their
//!   mapping to the controller's joints and commands.
//! - [`link`]: a non-blocking UDP endpoint with fault injection (drop, corrupt, delay, reorder)
//!   for tests against the simulated robot.
//! - [`dds`]: the Go2's low-level DDS interface (`rt/lowcmd`, `rt/lowstate`) on RustDDS, with
//!   the same fault injection.
//! - [`runner`]: `eemp hw` — a controller on the robot at 500 Hz: state datagrams → Kalman
//!   filter → controller → safety layer → command datagrams.
//! - [`sim_robot`]: `eemp sim-robot` — a MuJoCo A1 in real time that answers commands as the
//!   A1's motors do and sends state datagrams, so the whole path runs without a robot.

pub mod dds;
pub mod link;
pub mod motion_switcher;
pub mod runner;
pub mod sim_robot;
pub mod wire;
