//! Wire formats of the robots' low-level interfaces, bytes in and bytes out (no sockets, so the
//! robot computer and the tests use the same code): the A1's legacy UDP protocol
//! ([`a1_protocol`]), the Go2's DDS messages ([`go2_idl`]: their CDR and the C image their CRC
//! covers, on [`idl_layout`]), and the mapping between those messages and the controller's
//! joints, IMU and torque commands in the robot's motor order ([`robot_io`]). The transports are
//! the crate's `link` (UDP) and `dds` modules; the safety layer every command passes is
//! `eemp_core::safety`.

pub mod a1_protocol;
pub mod go2_idl;
pub mod idl_layout;
pub mod robot_io;
