//! The Unitree Go2's low-level messages (`unitree_go::msg::dds_`, unitree_sdk2's IDL; field
//! lists in `../shared/reference/go2-dds-notes.md` §1.4): the structs in their IDL field order,
//! their XCDR1 serialization (what DDS carries) and their C struct image (812 / 1180 bytes,
//! what Unitree's CRC covers, §1.5).
//!
//! No DDS here: bytes in, bytes out, for the robot computer and `eemp sim-robot` alike. Decoding
//! checks the encapsulation and the length and never panics; the CRC is checked separately
//! ([`LowCmd::check_crc`], [`LowState::check_crc`]) because unitree_mujoco's simulator never
//! fills it in, and a caller decides what a mismatch means.

use super::a1_protocol::{datagram_crc, POS_STOP, VEL_STOP};
use super::idl_layout::{to_bytes, IdlReader, IdlStruct, IdlWriter, Layout, LayoutError};

/// DDS type names on the wire (C++ `TopicTraits<…>::getTypeName()`).
pub const LOW_CMD_TYPE_NAME: &str = "unitree_go::msg::dds_::LowCmd_";
pub const LOW_STATE_TYPE_NAME: &str = "unitree_go::msg::dds_::LowState_";
/// `head` of every low-level message.
pub const HEAD: [u8; 2] = [0xFE, 0xEF];
/// `level_flag` of low-level commands (LOWLEVEL).
pub const LEVEL_LOW: u8 = 0xFF;
/// Motor mode: FOC (servo) control; 0x00 stops the motor. (The A1's is 0x0A.)
pub const MODE_FOC: u8 = 0x01;
pub const MOTORS: usize = 20;
/// Bytes of the C struct images.
pub const LOW_CMD_IMAGE_LEN: usize = 812;
pub const LOW_STATE_IMAGE_LEN: usize = 1180;
/// Bytes of the CDR serializations, the 4-byte encapsulation header included.
pub const LOW_CMD_CDR_LEN: usize = 4 + 808;
pub const LOW_STATE_CDR_LEN: usize = 4 + 1176;
/// XCDR1 little endian (CDR_LE), options 0: what Cyclone DDS sends for these `final` types.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];
/// XCDR2 little endian, plain (`final`), which decoding accepts too.
pub const XCDR2_LE_HEADER: [u8; 4] = [0x00, 0x07, 0x00, 0x00];

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Go2Error {
    #[error("{type_name}: {len} bytes, expected {expected} (CDR with its 4-byte header)")]
    Length {
        type_name: &'static str,
        len: usize,
        expected: usize,
    },
    #[error(
        "{type_name}: encapsulation {got:02x?} is not plain CDR little endian (00 01 or 00 07)"
    )]
    Encapsulation {
        type_name: &'static str,
        got: [u8; 4],
    },
    #[error("{0}: {1}")]
    Layout(&'static str, LayoutError),
    #[error("{type_name}: CRC mismatch: message says {stored:#010x}, its contents give {computed:#010x}")]
    Crc {
        type_name: &'static str,
        stored: u32,
        computed: u32,
    },
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MotorCmd {
    pub mode: u8,
    /// Target position, rad (POS_STOP: none).
    pub q: f32,
    /// Target velocity, rad/s (VEL_STOP: none).
    pub dq: f32,
    /// Feed-forward torque, N·m.
    pub tau: f32,
    /// Position gain, N·m/rad.
    pub kp: f32,
    /// Velocity gain, N·m·s/rad.
    pub kd: f32,
    pub reserve: [u32; 3],
}

impl MotorCmd {
    /// `InitLowCmd`'s motor: FOC mode, no targets, no gains, no torque.
    pub const IDLE: MotorCmd = MotorCmd {
        mode: MODE_FOC,
        q: POS_STOP,
        dq: VEL_STOP,
        tau: 0.0,
        kp: 0.0,
        kd: 0.0,
        reserve: [0; 3],
    };
}

impl IdlStruct for MotorCmd {
    const ALIGN: usize = 4;
    fn write(&self, w: &mut IdlWriter) {
        w.u8(self.mode);
        for v in [self.q, self.dq, self.tau, self.kp, self.kd] {
            w.f32(v);
        }
        self.reserve.iter().for_each(|&v| w.u32(v));
    }
    fn read(r: &mut IdlReader) -> Result<Self, LayoutError> {
        Ok(MotorCmd {
            mode: r.u8()?,
            q: r.f32()?,
            dq: r.f32()?,
            tau: r.f32()?,
            kp: r.f32()?,
            kd: r.f32()?,
            reserve: r.array(|r| r.u32())?,
        })
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BmsCmd {
    pub off: u8,
    pub reserve: [u8; 3],
}

impl IdlStruct for BmsCmd {
    const ALIGN: usize = 1;
    fn write(&self, w: &mut IdlWriter) {
        w.u8(self.off);
        w.u8s(&self.reserve);
    }
    fn read(r: &mut IdlReader) -> Result<Self, LayoutError> {
        Ok(BmsCmd {
            off: r.u8()?,
            reserve: r.u8s()?,
        })
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct LowCmd {
    pub head: [u8; 2],
    pub level_flag: u8,
    pub frame_reserve: u8,
    pub sn: [u32; 2],
    pub version: [u32; 2],
    pub bandwidth: u16,
    pub motor_cmd: [MotorCmd; MOTORS],
    pub bms_cmd: BmsCmd,
    pub wireless_remote: [u8; 40],
    pub led: [u8; 12],
    pub fan: [u8; 2],
    pub gpio: u8,
    pub reserve: u32,
    pub crc: u32,
}

impl Default for LowCmd {
    /// unitree_sdk2's `InitLowCmd`: head FE EF, low level, every motor idle in FOC mode. The
    /// CRC is left 0 ([`LowCmd::seal`] sets it).
    fn default() -> Self {
        LowCmd {
            head: HEAD,
            level_flag: LEVEL_LOW,
            frame_reserve: 0,
            sn: [0; 2],
            version: [0; 2],
            bandwidth: 0,
            motor_cmd: [MotorCmd::IDLE; MOTORS],
            bms_cmd: BmsCmd::default(),
            wireless_remote: [0; 40],
            led: [0; 12],
            fan: [0; 2],
            gpio: 0,
            reserve: 0,
            crc: 0,
        }
    }
}

/// The 22-byte header every low-level message starts with.
fn write_header(
    w: &mut IdlWriter,
    head: [u8; 2],
    level: u8,
    fr: u8,
    sn: [u32; 2],
    ver: [u32; 2],
    bw: u16,
) {
    w.u8s(&head);
    w.u8(level);
    w.u8(fr);
    sn.iter().chain(&ver).for_each(|&v| w.u32(v));
    w.u16(bw);
}

type Header = ([u8; 2], u8, u8, [u32; 2], [u32; 2], u16);

fn read_header(r: &mut IdlReader) -> Result<Header, LayoutError> {
    Ok((
        r.u8s()?,
        r.u8()?,
        r.u8()?,
        r.array(|r| r.u32())?,
        r.array(|r| r.u32())?,
        r.u16()?,
    ))
}

impl IdlStruct for LowCmd {
    const ALIGN: usize = 4;
    fn write(&self, w: &mut IdlWriter) {
        write_header(
            w,
            self.head,
            self.level_flag,
            self.frame_reserve,
            self.sn,
            self.version,
            self.bandwidth,
        );
        self.motor_cmd.iter().for_each(|m| w.nested(m));
        w.nested(&self.bms_cmd);
        w.u8s(&self.wireless_remote);
        w.u8s(&self.led);
        w.u8s(&self.fan);
        w.u8(self.gpio);
        w.u32(self.reserve);
        w.u32(self.crc);
    }
    fn read(r: &mut IdlReader) -> Result<Self, LayoutError> {
        let (head, level_flag, frame_reserve, sn, version, bandwidth) = read_header(r)?;
        Ok(LowCmd {
            head,
            level_flag,
            frame_reserve,
            sn,
            version,
            bandwidth,
            motor_cmd: r.array(|r| r.nested())?,
            bms_cmd: r.nested()?,
            wireless_remote: r.u8s()?,
            led: r.u8s()?,
            fan: r.u8s()?,
            gpio: r.u8()?,
            reserve: r.u32()?,
            crc: r.u32()?,
        })
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImuState {
    /// Attitude (w, x, y, z).
    pub quaternion: [f32; 4],
    /// rad/s, body frame.
    pub gyroscope: [f32; 3],
    /// m/s², body frame.
    pub accelerometer: [f32; 3],
    /// rad.
    pub rpy: [f32; 3],
    /// °C.
    pub temperature: u8,
}

impl IdlStruct for ImuState {
    const ALIGN: usize = 4;
    fn write(&self, w: &mut IdlWriter) {
        self.quaternion
            .iter()
            .chain(&self.gyroscope)
            .chain(&self.accelerometer)
            .chain(&self.rpy)
            .for_each(|&v| w.f32(v));
        w.u8(self.temperature);
    }
    fn read(r: &mut IdlReader) -> Result<Self, LayoutError> {
        Ok(ImuState {
            quaternion: r.array(|r| r.f32())?,
            gyroscope: r.array(|r| r.f32())?,
            accelerometer: r.array(|r| r.f32())?,
            rpy: r.array(|r| r.f32())?,
            temperature: r.u8()?,
        })
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MotorState {
    pub mode: u8,
    /// rad.
    pub q: f32,
    /// rad/s.
    pub dq: f32,
    /// rad/s².
    pub ddq: f32,
    /// Estimated torque, N·m.
    pub tau_est: f32,
    pub q_raw: f32,
    pub dq_raw: f32,
    pub ddq_raw: f32,
    /// °C.
    pub temperature: u8,
    pub lost: u32,
    pub reserve: [u32; 2],
}

impl IdlStruct for MotorState {
    const ALIGN: usize = 4;
    fn write(&self, w: &mut IdlWriter) {
        w.u8(self.mode);
        for v in [
            self.q,
            self.dq,
            self.ddq,
            self.tau_est,
            self.q_raw,
            self.dq_raw,
            self.ddq_raw,
        ] {
            w.f32(v);
        }
        w.u8(self.temperature);
        w.u32(self.lost);
        self.reserve.iter().for_each(|&v| w.u32(v));
    }
    fn read(r: &mut IdlReader) -> Result<Self, LayoutError> {
        Ok(MotorState {
            mode: r.u8()?,
            q: r.f32()?,
            dq: r.f32()?,
            ddq: r.f32()?,
            tau_est: r.f32()?,
            q_raw: r.f32()?,
            dq_raw: r.f32()?,
            ddq_raw: r.f32()?,
            temperature: r.u8()?,
            lost: r.u32()?,
            reserve: r.array(|r| r.u32())?,
        })
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BmsState {
    pub version_high: u8,
    pub version_low: u8,
    pub status: u8,
    /// State of charge, %.
    pub soc: u8,
    /// mA.
    pub current: i32,
    pub cycle: u16,
    pub bq_ntc: [u8; 2],
    pub mcu_ntc: [u8; 2],
    /// mV.
    pub cell_vol: [u16; 15],
}

impl IdlStruct for BmsState {
    const ALIGN: usize = 4;
    fn write(&self, w: &mut IdlWriter) {
        w.u8s(&[self.version_high, self.version_low, self.status, self.soc]);
        w.i32(self.current);
        w.u16(self.cycle);
        w.u8s(&self.bq_ntc);
        w.u8s(&self.mcu_ntc);
        self.cell_vol.iter().for_each(|&v| w.u16(v));
    }
    fn read(r: &mut IdlReader) -> Result<Self, LayoutError> {
        Ok(BmsState {
            version_high: r.u8()?,
            version_low: r.u8()?,
            status: r.u8()?,
            soc: r.u8()?,
            current: r.i32()?,
            cycle: r.u16()?,
            bq_ntc: r.u8s()?,
            mcu_ntc: r.u8s()?,
            cell_vol: r.array(|r| r.u16())?,
        })
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct LowState {
    pub head: [u8; 2],
    pub level_flag: u8,
    pub frame_reserve: u8,
    pub sn: [u32; 2],
    pub version: [u32; 2],
    pub bandwidth: u16,
    pub imu_state: ImuState,
    pub motor_state: [MotorState; MOTORS],
    pub bms_state: BmsState,
    /// Foot force sensors, raw.
    pub foot_force: [i16; 4],
    pub foot_force_est: [i16; 4],
    /// Robot clock (ms, as the Go1's; the Go2's unit is not documented).
    pub tick: u32,
    pub wireless_remote: [u8; 40],
    pub bit_flag: u8,
    pub adc_reel: f32,
    pub temperature_ntc1: u8,
    pub temperature_ntc2: u8,
    /// V.
    pub power_v: f32,
    /// A.
    pub power_a: f32,
    pub fan_frequency: [u16; 4],
    pub reserve: u32,
    pub crc: u32,
}

impl Default for LowState {
    fn default() -> Self {
        LowState {
            head: HEAD,
            level_flag: LEVEL_LOW,
            frame_reserve: 0,
            sn: [0; 2],
            version: [0; 2],
            bandwidth: 0,
            imu_state: ImuState::default(),
            motor_state: [MotorState::default(); MOTORS],
            bms_state: BmsState::default(),
            foot_force: [0; 4],
            foot_force_est: [0; 4],
            tick: 0,
            wireless_remote: [0; 40],
            bit_flag: 0,
            adc_reel: 0.0,
            temperature_ntc1: 0,
            temperature_ntc2: 0,
            power_v: 0.0,
            power_a: 0.0,
            fan_frequency: [0; 4],
            reserve: 0,
            crc: 0,
        }
    }
}

impl IdlStruct for LowState {
    const ALIGN: usize = 4;
    fn write(&self, w: &mut IdlWriter) {
        write_header(
            w,
            self.head,
            self.level_flag,
            self.frame_reserve,
            self.sn,
            self.version,
            self.bandwidth,
        );
        w.nested(&self.imu_state);
        self.motor_state.iter().for_each(|m| w.nested(m));
        w.nested(&self.bms_state);
        self.foot_force
            .iter()
            .chain(&self.foot_force_est)
            .for_each(|&v| w.i16(v));
        w.u32(self.tick);
        w.u8s(&self.wireless_remote);
        w.u8(self.bit_flag);
        w.f32(self.adc_reel);
        w.u8(self.temperature_ntc1);
        w.u8(self.temperature_ntc2);
        w.f32(self.power_v);
        w.f32(self.power_a);
        self.fan_frequency.iter().for_each(|&v| w.u16(v));
        w.u32(self.reserve);
        w.u32(self.crc);
    }
    fn read(r: &mut IdlReader) -> Result<Self, LayoutError> {
        let (head, level_flag, frame_reserve, sn, version, bandwidth) = read_header(r)?;
        Ok(LowState {
            head,
            level_flag,
            frame_reserve,
            sn,
            version,
            bandwidth,
            imu_state: r.nested()?,
            motor_state: r.array(|r| r.nested())?,
            bms_state: r.nested()?,
            foot_force: r.array(|r| r.i16())?,
            foot_force_est: r.array(|r| r.i16())?,
            tick: r.u32()?,
            wireless_remote: r.u8s()?,
            bit_flag: r.u8()?,
            adc_reel: r.f32()?,
            temperature_ntc1: r.u8()?,
            temperature_ntc2: r.u8()?,
            power_v: r.f32()?,
            power_a: r.f32()?,
            fan_frequency: r.array(|r| r.u16())?,
            reserve: r.u32()?,
            crc: r.u32()?,
        })
    }
}

/// Serialization as DDS carries it: the CDR_LE encapsulation header, then the XCDR1 body.
fn to_cdr<T: IdlStruct>(v: &T) -> Vec<u8> {
    let mut out = CDR_LE_HEADER.to_vec();
    out.extend(to_bytes(v, Layout::Cdr));
    out
}

fn from_cdr<T: IdlStruct>(
    bytes: &[u8],
    type_name: &'static str,
    expected: usize,
) -> Result<T, Go2Error> {
    // RTPS may pad a serialized payload to a multiple of 4; these are multiples already.
    if bytes.len() != expected {
        return Err(Go2Error::Length {
            type_name,
            len: bytes.len(),
            expected,
        });
    }
    let header: [u8; 4] = bytes[..4].try_into().expect("length checked");
    // XCDR2 differs from XCDR1 only in aligning 8-byte members to 4; these types have none,
    // so a peer that picks XCDR2 for them sends the same body.
    if header[..2] != CDR_LE_HEADER[..2] && header[..2] != XCDR2_LE_HEADER[..2] {
        return Err(Go2Error::Encapsulation {
            type_name,
            got: header,
        });
    }
    T::read(&mut IdlReader::new(&bytes[4..], Layout::Cdr))
        .map_err(|e| Go2Error::Layout(type_name, e))
}

macro_rules! message_impl {
    ($t:ty, $name:expr, $cdr_len:expr, $image_len:expr) => {
        impl $t {
            /// The CDR serialization (encapsulation header included).
            pub fn to_cdr(&self) -> Vec<u8> {
                to_cdr(self)
            }
            /// Decodes a CDR serialization (encapsulation header included). The CRC is not
            /// checked here.
            pub fn from_cdr(bytes: &[u8]) -> Result<Self, Go2Error> {
                from_cdr(bytes, $name, $cdr_len)
            }
            /// The C struct image the CRC covers (little endian, natural alignment).
            pub fn c_image(&self) -> Vec<u8> {
                let image = to_bytes(self, Layout::CStruct);
                debug_assert_eq!(image.len(), $image_len);
                image
            }
            /// Unitree's CRC of this message: over every 32-bit word of the image but the last
            /// (the `crc` field).
            pub fn compute_crc(&self) -> u32 {
                datagram_crc(&self.c_image())
            }
            /// Sets `crc` to the CRC of the contents.
            pub fn seal(&mut self) {
                self.crc = self.compute_crc();
            }
            pub fn check_crc(&self) -> Result<(), Go2Error> {
                let computed = self.compute_crc();
                if computed != self.crc {
                    return Err(Go2Error::Crc {
                        type_name: $name,
                        stored: self.crc,
                        computed,
                    });
                }
                Ok(())
            }
        }
    };
}

message_impl!(
    LowCmd,
    LOW_CMD_TYPE_NAME,
    LOW_CMD_CDR_LEN,
    LOW_CMD_IMAGE_LEN
);
message_impl!(
    LowState,
    LOW_STATE_TYPE_NAME,
    LOW_STATE_CDR_LEN,
    LOW_STATE_IMAGE_LEN
);

/// The messages `scripts/go2_golden.py` fills, field for field, for the golden tests and the
/// Cyclone DDS interop test.
pub mod fixtures {
    use super::*;

    /// `low_cmd_filled()`: every field set, distinct values, exact in f32.
    pub fn low_cmd_filled() -> LowCmd {
        let mut c = LowCmd {
            frame_reserve: 7,
            sn: [0x0102_0304, 0xA0B0_C0D0],
            version: [3, 0xFFFF_FFFE],
            bandwidth: 0x1234,
            bms_cmd: BmsCmd {
                off: 0x5A,
                reserve: [1, 2, 3],
            },
            wireless_remote: std::array::from_fn(|k| ((k * 7 + 1) % 256) as u8),
            led: std::array::from_fn(|k| 200 + k as u8),
            fan: [0x11, 0x22],
            gpio: 0x33,
            reserve: 0xDEAD_BEEF,
            ..Default::default()
        };
        for (i, m) in c.motor_cmd.iter_mut().enumerate() {
            let f = i as f32;
            *m = MotorCmd {
                mode: (i % 3) as u8,
                q: -1.5 + 0.125 * f,
                dq: 0.25 * f - 2.0,
                tau: 0.5 * f - 3.0,
                kp: 20.0 + f,
                kd: 0.5 + 0.0625 * f,
                reserve: [i as u32, 100 + i as u32, 0xFFFF_0000 + i as u32],
            };
        }
        c.seal();
        c
    }

    /// `low_state_filled()`.
    pub fn low_state_filled() -> LowState {
        let mut s = LowState {
            frame_reserve: 9,
            sn: [5, 6],
            version: [7, 8],
            bandwidth: 0x0102,
            imu_state: ImuState {
                quaternion: [1.0, -0.25, 0.5, -0.125],
                gyroscope: [0.5, -1.5, 2.25],
                accelerometer: [0.125, -0.375, 9.75],
                rpy: [0.0625, -0.03125, 3.0],
                temperature: 41,
            },
            bms_state: BmsState {
                version_high: 1,
                version_low: 2,
                status: 3,
                soc: 87,
                current: -1234,
                cycle: 321,
                bq_ntc: [25, 26],
                mcu_ntc: [27, 28],
                cell_vol: std::array::from_fn(|k| 3600 + 10 * k as u16),
            },
            foot_force: [10, -20, 300, -32768],
            foot_force_est: [1, 2, 3, 32767],
            tick: 123_456_789,
            wireless_remote: std::array::from_fn(|k| 255 - k as u8),
            bit_flag: 0x5A,
            adc_reel: 1.5,
            temperature_ntc1: 40,
            temperature_ntc2: 41,
            power_v: 28.5,
            power_a: -3.25,
            fan_frequency: [1000, 2000, 3000, 65535],
            reserve: 0xCAFE_BABE,
            ..Default::default()
        };
        for (i, m) in s.motor_state.iter_mut().enumerate() {
            let f = i as f32;
            let (q, dq, ddq) = (0.25 * f - 2.5, -0.5 * f + 1.0, 3.0 * f);
            *m = MotorState {
                mode: 1,
                q,
                dq,
                ddq,
                tau_est: 0.75 * f - 4.0,
                q_raw: q + 0.5,
                dq_raw: dq - 0.25,
                ddq_raw: -ddq,
                temperature: 30 + i as u8,
                lost: 1000 * i as u32,
                reserve: [i as u32, 0x8000_0000 + i as u32],
            };
        }
        s.seal();
        s
    }
}

#[cfg(test)]
mod tests {
    use super::fixtures::*;
    use super::*;

    /// The standard (reflected, zlib) CRC-32, to compare fingerprints with Python's zlib.crc32.
    fn zlib_crc32(bytes: &[u8]) -> u32 {
        let mut crc = 0xFFFF_FFFFu32;
        for &b in bytes {
            crc ^= b as u32;
            for _ in 0..8 {
                crc = if crc & 1 != 0 {
                    (crc >> 1) ^ 0xEDB8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }

    /// (crc, image fingerprint, CDR fingerprint): the output of `python3 scripts/go2_golden.py`,
    /// which packs the same messages with `struct` and ports `_crc_py`.
    const LOW_CMD_INIT: (u32, u32, u32) = (0x06E5_77CD, 0xCC78_58E6, 0x07AC_78EF);
    const LOW_CMD_FILLED: (u32, u32, u32) = (0x0C65_3951, 0xEDE4_4370, 0x6D2E_2540);
    const LOW_STATE_FILLED: (u32, u32, u32) = (0x8BD8_4B5B, 0x2EC2_6A63, 0xCF0A_E08F);

    #[test]
    fn zlib_crc32_is_the_standard_one() {
        assert_eq!(zlib_crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn commands_match_the_independent_golden_values() {
        let mut init = LowCmd::default();
        init.seal();
        for (name, cmd, (crc, image_fp, cdr_fp)) in [
            ("init", init, LOW_CMD_INIT),
            ("filled", low_cmd_filled(), LOW_CMD_FILLED),
        ] {
            let image = cmd.c_image();
            assert_eq!(image.len(), LOW_CMD_IMAGE_LEN);
            assert_eq!(cmd.crc, crc, "{name}: CRC {:#010x}", cmd.crc);
            assert_eq!(zlib_crc32(&image), image_fp, "{name}: image bytes");
            let cdr = cmd.to_cdr();
            assert_eq!(cdr.len(), LOW_CMD_CDR_LEN);
            assert_eq!(zlib_crc32(&cdr), cdr_fp, "{name}: CDR bytes");
            assert_eq!(LowCmd::from_cdr(&cdr).unwrap(), cmd);
            cmd.check_crc().unwrap();
        }
    }

    #[test]
    fn states_match_the_independent_golden_values() {
        let s = low_state_filled();
        let (crc, image_fp, cdr_fp) = LOW_STATE_FILLED;
        assert_eq!(s.crc, crc, "CRC {:#010x}", s.crc);
        let image = s.c_image();
        assert_eq!(image.len(), LOW_STATE_IMAGE_LEN);
        assert_eq!(zlib_crc32(&image), image_fp);
        let cdr = s.to_cdr();
        assert_eq!(cdr.len(), LOW_STATE_CDR_LEN);
        assert_eq!(zlib_crc32(&cdr), cdr_fp);
        assert_eq!(LowState::from_cdr(&cdr).unwrap(), s);
    }

    #[test]
    fn the_documented_offsets_hold() {
        let c = low_cmd_filled();
        let image = c.c_image();
        let cdr = c.to_cdr();
        // motor_cmd[0].mode: image 24, CDR body 22; q right after its padding.
        assert_eq!(image[24], 0);
        assert_eq!(&image[28..32], &(-1.5f32).to_le_bytes());
        assert_eq!(&cdr[4 + 24..4 + 28], &(-1.5f32).to_le_bytes());
        // motor_cmd[1].mode (1): image 60, CDR 56.
        assert_eq!((image[60], cdr[4 + 56]), (1, 1));
        // bms_cmd.off @744, wireless @748, led @788, fan @800, gpio @802, reserve @804, crc @808.
        assert_eq!(image[744], 0x5A);
        assert_eq!(image[748], 1);
        assert_eq!(image[788], 200);
        assert_eq!(&image[800..803], &[0x11, 0x22, 0x33]);
        assert_eq!(&image[804..808], &0xDEAD_BEEFu32.to_le_bytes());
        assert_eq!(&image[808..812], &c.crc.to_le_bytes());
        let s = low_state_filled();
        let image = s.c_image();
        // imu @24, motor_state @80 (48 B each), bms @1040, foot_force @1084, tick @1100,
        // bit_flag @1144, adc_reel @1148, power_v @1156, fan @1164, reserve @1172, crc @1176.
        assert_eq!(&image[24..28], &1.0f32.to_le_bytes());
        assert_eq!(image[80], 1);
        assert_eq!(&image[84..88], &(-2.5f32).to_le_bytes());
        assert_eq!(image[80 + 48 + 32], 31);
        assert_eq!(image[1043], 87);
        assert_eq!(&image[1084..1086], &10i16.to_le_bytes());
        assert_eq!(&image[1100..1104], &123_456_789u32.to_le_bytes());
        assert_eq!(image[1144], 0x5A);
        assert_eq!(&image[1148..1152], &1.5f32.to_le_bytes());
        assert_eq!(&image[1156..1160], &28.5f32.to_le_bytes());
        assert_eq!(&image[1164..1166], &1000u16.to_le_bytes());
        assert_eq!(&image[1172..1176], &0xCAFE_BABEu32.to_le_bytes());
    }

    #[test]
    fn a_changed_field_breaks_the_crc_and_bad_bytes_are_refused() {
        let mut c = low_cmd_filled();
        c.motor_cmd[7].kp += 1.0;
        assert!(matches!(c.check_crc(), Err(Go2Error::Crc { .. })));
        // Padding is not covered by the CDR: flipping a CDR byte changes a field.
        let mut cdr = low_cmd_filled().to_cdr();
        cdr[4 + 30] ^= 0x40;
        let back = LowCmd::from_cdr(&cdr).unwrap();
        assert!(back.check_crc().is_err());
        let cdr = low_cmd_filled().to_cdr();
        assert!(matches!(
            LowCmd::from_cdr(&cdr[..cdr.len() - 1]),
            Err(Go2Error::Length { .. })
        ));
        let mut be = cdr.clone();
        be[1] = 0x00;
        assert!(matches!(
            LowCmd::from_cdr(&be),
            Err(Go2Error::Encapsulation { .. })
        ));
        // A LowState is not a LowCmd.
        assert!(LowCmd::from_cdr(&low_state_filled().to_cdr()).is_err());
        assert!(LowState::from_cdr(&[]).is_err());
    }
}
