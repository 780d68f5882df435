//! The path to a real A1: its legacy low-level UDP protocol and the safety layer every command
//! passes (no sockets here: bytes in, bytes
//! out, so the robot computer and the tests use the same code).

pub mod a1_protocol;
pub mod robot_io;
pub mod safety;
