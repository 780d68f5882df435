//! The path to a real A1: its legacy low-level UDP protocol (no sockets here: bytes in, bytes
//! out, so the robot computer and the tests use the same code).

pub mod a1_protocol;
