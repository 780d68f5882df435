//! Unitree A1 low-level protocol of the legacy `unitree_legged_sdk` 3.2/3.3.x: the command
//! (`LowCmd`, 610 bytes) and state (`LowState`, 771 bytes) datagrams as they travel on the wire,
//! and their CRC. The wire layout is not the SDK's public C structs: torques and gains are
//! 16-bit fixed point (see `../shared/reference/estimation-hardware-notes.md` §2.3).
//!
//! Encoding refuses values the fixed-point fields cannot hold (the SDK would wrap them around,
//! turning a large torque into its opposite); decoding checks the length and the CRC and never
//! panics on any input.

/// Bytes of a command datagram.
pub const LOW_CMD_LEN: usize = 610;
/// Bytes of a state datagram.
pub const LOW_STATE_LEN: usize = 771;
/// `levelFlag` of low-level datagrams.
pub const LOWLEVEL: u8 = 0xFF;
/// Position and velocity values that tell a motor to ignore them (the SDK's PosStopF, VelStopF).
pub const POS_STOP: f32 = 2.146e9;
pub const VEL_STOP: f32 = 16000.0;
/// Motor mode: servo (FOC) control; 0 = off.
pub const MODE_SERVO: u8 = 0x0A;
/// Motors in a datagram (the A1 uses the first 12: FR, FL, RR, RL × hip, thigh, calf).
pub const MOTORS: usize = 20;

const CRC_POLY: u32 = 0x04C1_1DB7;

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ProtocolError {
    #[error("datagram has {got} bytes, expected {expected}")]
    Length { got: usize, expected: usize },
    #[error("CRC mismatch: datagram says {stored:#010x}, contents give {computed:#010x}")]
    Crc { stored: u32, computed: u32 },
    #[error("motor {motor}: {field} = {value} does not fit the wire format (allowed |{field}| < {limit})")]
    Range {
        motor: usize,
        field: &'static str,
        value: f32,
        limit: f32,
    },
    #[error("levelFlag {0:#04x} is not low level (0xff)")]
    Level(u8),
}

/// Unitree's CRC: MSB-first, polynomial 0x04C11DB7, initial value 0xFFFFFFFF, no final XOR,
/// over 32-bit words (the words' bits from 31 down to 0).
pub fn crc32_words(words: impl IntoIterator<Item = u32>) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for w in words {
        for b in (0..32).rev() {
            let msb = crc >> 31;
            crc <<= 1;
            if msb != 0 {
                crc ^= CRC_POLY;
            }
            if (w >> b) & 1 != 0 {
                crc ^= CRC_POLY;
            }
        }
    }
    crc
}

/// The CRC of a datagram: over its first `(len/4) − 1` little-endian words.
pub fn datagram_crc(bytes: &[u8]) -> u32 {
    let words = (bytes.len() / 4).saturating_sub(1);
    crc32_words(
        bytes[..4 * words]
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])),
    )
}

/// The common first 10 bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Header {
    pub level_flag: u8,
    pub comm_version: u16,
    pub robot_id: u16,
    pub sn: u32,
    pub band_width: u8,
}

/// One motor's command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorCmd {
    pub mode: u8,
    /// Target position, rad (POS_STOP: none).
    pub q: f32,
    /// Target velocity, rad/s (VEL_STOP: none).
    pub dq: f32,
    /// Feed-forward torque, N·m (|τ| < 128).
    pub tau: f32,
    /// Position gain, N·m/rad (< 1024).
    pub kp: f32,
    /// Velocity gain, N·m·s/rad (< 2048).
    pub kd: f32,
}

impl MotorCmd {
    /// The SDK's `InitCmdData`: servo mode, no targets, no gains, no torque.
    pub const IDLE: MotorCmd = MotorCmd {
        mode: MODE_SERVO,
        q: POS_STOP,
        dq: VEL_STOP,
        tau: 0.0,
        kp: 0.0,
        kd: 0.0,
    };
}

#[derive(Clone, Debug, PartialEq)]
pub struct LowCmd {
    pub header: Header,
    pub motors: [MotorCmd; MOTORS],
    pub led: [[u8; 3]; 4],
    pub wireless_remote: [u8; 40],
}

impl Default for LowCmd {
    fn default() -> Self {
        LowCmd {
            header: Header {
                level_flag: LOWLEVEL,
                ..Default::default()
            },
            motors: [MotorCmd::IDLE; MOTORS],
            led: [[0; 3]; 4],
            wireless_remote: [0; 40],
        }
    }
}

/// Fixed-point field limits: (name, scale, |value| limit).
const TAU: (&str, f32) = ("tau", 256.0);
const KP: (&str, f32) = ("Kp", 32.0);
const KD: (&str, f32) = ("Kd", 16.0);

fn fixed(
    motor: usize,
    (field, scale): (&'static str, f32),
    value: f32,
) -> Result<i16, ProtocolError> {
    let limit = 32768.0 / scale;
    if !(value.is_finite() && value.abs() < limit) {
        return Err(ProtocolError::Range {
            motor,
            field,
            value,
            limit,
        });
    }
    // Truncation toward zero, as the SDK's conversion.
    Ok((value * scale) as i16)
}

struct Writer<'a> {
    buf: &'a mut [u8],
    at: usize,
}

impl Writer<'_> {
    fn bytes(&mut self, b: &[u8]) {
        self.buf[self.at..self.at + b.len()].copy_from_slice(b);
        self.at += b.len();
    }
    fn header(&mut self, h: &Header) {
        self.bytes(&[h.level_flag]);
        self.bytes(&h.comm_version.to_le_bytes());
        self.bytes(&h.robot_id.to_le_bytes());
        self.bytes(&h.sn.to_le_bytes());
        self.bytes(&[h.band_width]);
    }
}

struct Reader<'a> {
    buf: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        out.copy_from_slice(&self.buf[self.at..self.at + N]);
        self.at += N;
        out
    }
    fn u8(&mut self) -> u8 {
        self.take::<1>()[0]
    }
    fn i8(&mut self) -> i8 {
        self.take::<1>()[0] as i8
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take())
    }
    fn i16(&mut self) -> i16 {
        i16::from_le_bytes(self.take())
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.take())
    }
    fn header(&mut self) -> Header {
        Header {
            level_flag: self.u8(),
            comm_version: self.u16(),
            robot_id: self.u16(),
            sn: self.u32(),
            band_width: self.u8(),
        }
    }
}

/// Checks length and CRC of a datagram.
fn check(bytes: &[u8], expected: usize) -> Result<(), ProtocolError> {
    if bytes.len() != expected {
        return Err(ProtocolError::Length {
            got: bytes.len(),
            expected,
        });
    }
    let stored = u32::from_le_bytes(bytes[expected - 4..].try_into().expect("4 bytes"));
    let computed = datagram_crc(bytes);
    if stored != computed {
        return Err(ProtocolError::Crc { stored, computed });
    }
    Ok(())
}

impl LowCmd {
    pub fn encode(&self) -> Result<[u8; LOW_CMD_LEN], ProtocolError> {
        let mut buf = [0u8; LOW_CMD_LEN];
        let mut w = Writer {
            buf: &mut buf,
            at: 0,
        };
        w.header(&self.header);
        for (i, m) in self.motors.iter().enumerate() {
            w.bytes(&[m.mode]);
            w.bytes(&m.q.to_le_bytes());
            w.bytes(&m.dq.to_le_bytes());
            w.bytes(&fixed(i, TAU, m.tau)?.to_le_bytes());
            w.bytes(&fixed(i, KP, m.kp)?.to_le_bytes());
            w.bytes(&fixed(i, KD, m.kd)?.to_le_bytes());
            w.bytes(&[0u8; 12]);
        }
        for led in &self.led {
            w.bytes(led);
        }
        w.bytes(&self.wireless_remote);
        w.bytes(&[0u8; 4]);
        debug_assert_eq!(w.at, LOW_CMD_LEN - 4);
        let crc = datagram_crc(&buf);
        buf[LOW_CMD_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
        Ok(buf)
    }

    /// Decodes a command datagram (what a robot, or `sim-robot`, receives).
    pub fn decode(bytes: &[u8]) -> Result<Self, ProtocolError> {
        check(bytes, LOW_CMD_LEN)?;
        let mut r = Reader { buf: bytes, at: 0 };
        let header = r.header();
        if header.level_flag != LOWLEVEL {
            return Err(ProtocolError::Level(header.level_flag));
        }
        let mut motors = [MotorCmd::IDLE; MOTORS];
        for m in motors.iter_mut() {
            *m = MotorCmd {
                mode: r.u8(),
                q: r.f32(),
                dq: r.f32(),
                tau: r.i16() as f32 / TAU.1,
                kp: r.i16() as f32 / KP.1,
                kd: r.i16() as f32 / KD.1,
            };
            r.take::<12>();
        }
        let mut led = [[0u8; 3]; 4];
        for l in led.iter_mut() {
            *l = r.take();
        }
        Ok(LowCmd {
            header,
            motors,
            led,
            wireless_remote: r.take(),
        })
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Imu {
    /// Attitude (w, x, y, z).
    pub quaternion: [f32; 4],
    /// rad/s.
    pub gyroscope: [f32; 3],
    /// m/s².
    pub accelerometer: [f32; 3],
    pub rpy: [f32; 3],
    pub temperature: i8,
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MotorState {
    pub mode: u8,
    pub q: f32,
    pub dq: f32,
    pub ddq: f32,
    /// Estimated torque, N·m (1/256 resolution).
    pub tau_est: f32,
    pub q_raw: f32,
    pub dq_raw: f32,
    pub ddq_raw: f32,
    pub temperature: i8,
}

#[derive(Clone, Debug, PartialEq)]
pub struct LowState {
    pub header: Header,
    pub imu: Imu,
    pub motors: [MotorState; MOTORS],
    pub foot_force: [i16; 4],
    pub foot_force_est: [i16; 4],
    /// Robot clock, µs.
    pub tick: u32,
    pub wireless_remote: [u8; 40],
}

impl Default for LowState {
    fn default() -> Self {
        LowState {
            header: Header {
                level_flag: LOWLEVEL,
                ..Default::default()
            },
            imu: Imu::default(),
            motors: [MotorState::default(); MOTORS],
            foot_force: [0; 4],
            foot_force_est: [0; 4],
            tick: 0,
            wireless_remote: [0; 40],
        }
    }
}

impl LowState {
    /// Decodes a state datagram from the robot.
    pub fn decode(bytes: &[u8]) -> Result<Self, ProtocolError> {
        check(bytes, LOW_STATE_LEN)?;
        let mut r = Reader { buf: bytes, at: 0 };
        let header = r.header();
        if header.level_flag != LOWLEVEL {
            return Err(ProtocolError::Level(header.level_flag));
        }
        let f3 = |r: &mut Reader| [r.f32(), r.f32(), r.f32()];
        let imu = Imu {
            quaternion: [r.f32(), r.f32(), r.f32(), r.f32()],
            gyroscope: f3(&mut r),
            accelerometer: f3(&mut r),
            rpy: f3(&mut r),
            temperature: r.i8(),
        };
        let mut motors = [MotorState::default(); MOTORS];
        for m in motors.iter_mut() {
            *m = MotorState {
                mode: r.u8(),
                q: r.f32(),
                dq: r.f32(),
                ddq: r.i16() as f32,
                tau_est: r.i16() as f32 / 256.0,
                q_raw: r.f32(),
                dq_raw: r.f32(),
                ddq_raw: r.i16() as f32,
                temperature: r.i8(),
            };
            r.take::<8>();
        }
        let foot_force = [r.i16(), r.i16(), r.i16(), r.i16()];
        let foot_force_est = [r.i16(), r.i16(), r.i16(), r.i16()];
        let tick = r.u32();
        let wireless_remote = r.take();
        Ok(LowState {
            header,
            imu,
            motors,
            foot_force,
            foot_force_est,
            tick,
            wireless_remote,
        })
    }

    /// Encodes a state datagram (what a robot, or `sim-robot`, sends).
    pub fn encode(&self) -> Result<[u8; LOW_STATE_LEN], ProtocolError> {
        let mut buf = [0u8; LOW_STATE_LEN];
        let mut w = Writer {
            buf: &mut buf,
            at: 0,
        };
        w.header(&self.header);
        let imu = &self.imu;
        for v in imu
            .quaternion
            .iter()
            .chain(&imu.gyroscope)
            .chain(&imu.accelerometer)
            .chain(&imu.rpy)
        {
            w.bytes(&v.to_le_bytes());
        }
        w.bytes(&[imu.temperature as u8]);
        for (i, m) in self.motors.iter().enumerate() {
            w.bytes(&[m.mode]);
            w.bytes(&m.q.to_le_bytes());
            w.bytes(&m.dq.to_le_bytes());
            w.bytes(&fixed(i, ("ddq", 1.0), m.ddq)?.to_le_bytes());
            w.bytes(&fixed(i, ("tauEst", 256.0), m.tau_est)?.to_le_bytes());
            w.bytes(&m.q_raw.to_le_bytes());
            w.bytes(&m.dq_raw.to_le_bytes());
            w.bytes(&fixed(i, ("ddq_raw", 1.0), m.ddq_raw)?.to_le_bytes());
            w.bytes(&[m.temperature as u8]);
            w.bytes(&[0u8; 8]);
        }
        for f in self.foot_force.iter().chain(&self.foot_force_est) {
            w.bytes(&f.to_le_bytes());
        }
        w.bytes(&self.tick.to_le_bytes());
        w.bytes(&self.wireless_remote);
        w.bytes(&[0u8; 4]);
        debug_assert_eq!(w.at, LOW_STATE_LEN - 4);
        let crc = datagram_crc(&buf);
        buf[LOW_STATE_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
        Ok(buf)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// CRC-32/MPEG-2 bytewise (second method): its published check value for "123456789" is
    /// 0x0376E6E7.
    fn crc_mpeg2(bytes: &[u8]) -> u32 {
        let mut crc = 0xFFFF_FFFFu32;
        for &b in bytes {
            crc ^= (b as u32) << 24;
            for _ in 0..8 {
                crc = if crc & 0x8000_0000 != 0 {
                    (crc << 1) ^ CRC_POLY
                } else {
                    crc << 1
                };
            }
        }
        crc
    }

    #[test]
    fn unitree_crc_is_crc32_mpeg2_over_the_words_big_endian_bytes() {
        assert_eq!(crc_mpeg2(b"123456789"), 0x0376_E6E7);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        for n in [1usize, 2, 7, 151] {
            let words: Vec<u32> = (0..n).map(|_| rng.random()).collect();
            let be: Vec<u8> = words.iter().flat_map(|w| w.to_be_bytes()).collect();
            assert_eq!(
                crc32_words(words.iter().copied()),
                crc_mpeg2(&be),
                "{n} words"
            );
        }
        // One word of zeros: 0xFFFFFFFF·x³² mod G, worked out by the bytewise method.
        assert_eq!(crc32_words([0]), crc_mpeg2(&[0, 0, 0, 0]));
    }

    #[test]
    fn a_hand_built_command_has_the_documented_bytes() {
        let mut cmd = LowCmd::default();
        cmd.motors[0] = MotorCmd {
            mode: MODE_SERVO,
            q: 0.5,
            dq: 0.0,
            tau: 1.5,
            kp: 20.0,
            kd: 0.5,
        };
        let b = cmd.encode().unwrap();
        assert_eq!(b.len(), 610);
        assert_eq!(b[0], 0xFF);
        assert_eq!(b[10], 0x0A);
        assert_eq!(&b[11..15], &0.5f32.to_le_bytes());
        // τ·256 = 384 = 0x0180; Kp·32 = 640 = 0x0280; Kd·16 = 8.
        assert_eq!(&b[19..25], &[0x80, 0x01, 0x80, 0x02, 0x08, 0x00]);
        // Motor 1 is idle: q = PosStopF (0x4EFFD2B9), dq = VelStopF (0x467A0000).
        assert_eq!(&b[38..42], &0x4EFF_D2B9u32.to_le_bytes());
        assert_eq!(&b[42..46], &0x467A_0000u32.to_le_bytes());
        let crc = u32::from_le_bytes(b[606..].try_into().unwrap());
        assert_eq!(
            crc,
            crc32_words(
                b[..604]
                    .chunks(4)
                    .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
            )
        );
        assert_eq!(LowCmd::decode(&b).unwrap(), cmd);
    }

    #[test]
    fn values_the_wire_cannot_hold_are_refused_not_wrapped() {
        let mut cmd = LowCmd::default();
        cmd.motors[4].tau = 130.0;
        let e = cmd.encode().unwrap_err();
        assert!(
            matches!(
                e,
                ProtocolError::Range {
                    motor: 4,
                    field: "tau",
                    ..
                }
            ),
            "{e}"
        );
        cmd.motors[4].tau = f32::NAN;
        assert!(cmd.encode().is_err());
        cmd.motors[4].tau = -127.0;
        cmd.motors[4].kp = 2000.0;
        assert!(cmd.encode().is_err());
    }

    #[test]
    fn state_round_trips_and_corruption_is_caught() {
        let mut s = LowState::default();
        s.imu.quaternion = [1.0, 0.0, 0.0, 0.0];
        s.imu.accelerometer = [0.1, -0.2, 9.81];
        s.motors[11].q = -1.8;
        s.motors[11].tau_est = -3.5;
        s.foot_force = [10, 200, -3, 0];
        s.tick = 123_456;
        let mut b = s.encode().unwrap();
        assert_eq!(b.len(), 771);
        assert_eq!(&b[703..705], &10i16.to_le_bytes());
        assert_eq!(&b[719..723], &123_456u32.to_le_bytes());
        assert_eq!(LowState::decode(&b).unwrap(), s);
        b[100] ^= 0x10;
        assert!(matches!(
            LowState::decode(&b),
            Err(ProtocolError::Crc { .. })
        ));
    }

    #[test]
    fn random_and_truncated_datagrams_never_panic() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let good = LowState::default().encode().unwrap();
        for _ in 0..2000 {
            let n = rng.random_range(0..900);
            let junk: Vec<u8> = (0..n).map(|_| rng.random()).collect();
            let _ = LowState::decode(&junk);
            let _ = LowCmd::decode(&junk);
            let cut = rng.random_range(0..good.len());
            assert!(LowState::decode(&good[..cut]).is_err());
        }
        // A random body with a valid CRC decodes to something (no panic) or a clean error.
        for _ in 0..200 {
            let mut b: Vec<u8> = (0..LOW_CMD_LEN).map(|_| rng.random()).collect();
            let crc = datagram_crc(&b);
            b[LOW_CMD_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
            let _ = LowCmd::decode(&b);
        }
    }
}
