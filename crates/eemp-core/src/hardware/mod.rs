//! The path to a real robot: the A1's legacy low-level UDP protocol, the Go2's low-level DDS
//! messages (their CDR and the C image its CRC covers; the DDS transport itself is in
//! eemp-hw), and the safety layer every command passes (no sockets here: bytes in, bytes out,
//! so the robot computer and the tests use the same code).

pub mod a1_protocol;
pub mod go2_idl;
pub mod idl_layout;
pub mod robot_io;
pub mod safety;
