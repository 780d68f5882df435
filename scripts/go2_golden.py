#!/usr/bin/env python3
"""Golden values for the Go2 codec tests (crates/eemp-hw/src/wire/go2_idl.rs).

Standard library only, written from the IDL field lists and the CRC description in
../shared/reference/go2-dds-notes.md (§1.4, §1.5), not from the Rust code:

- the C struct image (natural alignment) with the struct formats of unitree_sdk2_python's
  utils/crc.py: LowCmd_ 812 bytes, LowState_ 1180 bytes;
- Unitree's CRC (a port of `_crc_py`: init 0xFFFFFFFF, poly 0x04C11DB7, each little-endian
  32-bit word MSB first, no reflection, no final XOR) over every word but the last (the crc);
- the XCDR1 little-endian serialization (encapsulation 00 01 00 00; each primitive aligned to
  its size from the start of the body, nested structs not padded), with offsets worked out by
  hand below: LowCmd_ 808 + 4 bytes, LowState_ 1176 + 4 bytes.

For each message it prints the image length, the CRC, and zlib.crc32 (the standard reflected
CRC-32, a different algorithm) of the whole image and of the whole CDR serialization (header
included, crc field filled in) as fingerprints. Run: python3 scripts/go2_golden.py
"""
import struct
import zlib

POS_STOP_F = 2.146e9
VEL_STOP_F = 16000.0

# C images (utils/crc.py's formats; signedness follows the IDL, the sizes are the same).
IMAGE_CMD = "<4B4IH2x" + "B3x5f3I" * 20 + "4B" + "55Bx2I"
IMAGE_STATE = "<4B4IH2x" + "13fB3x" + "B3x7fB3x3I" * 20 + "4BiH4B15H" + "8hI41B3xf2B2x2f4H2I"
# XCDR1 bodies. LowCmd_: header 22 B; motor_cmd[0].mode at 22, q at 24 (1 pad byte), each later
# MotorCmd_ starts 4-aligned (mode, 3 pad); bms_cmd at 740; wireless 744; led 784; fan 796;
# gpio 798; 1 pad; reserve 800; crc 804.
CDR_CMD = "<4B4IH" + "Bx5f3I" + "B3x5f3I" * 19 + "4B" + "55Bx2I"
# LowState_: imu at 22 (2 pad before the quaternion), temperature at 76; motor_state[0].mode at
# 77 (2 pad), temperature at 108 (3 pad), lost 112; later motors 48 B from 124; bms_state at 1036
# (no pad); foot_force 1080; tick 1096; wireless 1100; bit_flag 1140 (3 pad); adc_reel 1144;
# ntc 1148/1149 (2 pad); power_v 1152; power_a 1156; fan 1160; reserve 1168; crc 1172.
CDR_STATE = (
    "<4B4IH" + "2x13fB" + "B2x7fB3x3I" + "B3x7fB3x3I" * 19 + "4BiH4B15H" + "8hI41B3xf2B2x2f4H2I"
)


def crc_py(words):
    """Port of unitree_sdk2py.utils.crc._crc_py."""
    crc = 0xFFFFFFFF
    poly = 0x04C11DB7
    for w in words:
        for bit in range(31, -1, -1):
            msb = crc & 0x80000000
            crc = (crc << 1) & 0xFFFFFFFF
            if msb:
                crc ^= poly
            if (w >> bit) & 1:
                crc ^= poly
    return crc


def unitree_crc(image):
    n = len(image) // 4 - 1
    return crc_py(struct.unpack("<%dI" % n, image[: 4 * n]))


def low_cmd_init():
    """InitLowCmd: head FE EF, level_flag 0xFF, every motor mode 0x01 with the stop values."""
    motors = []
    for _ in range(20):
        motors += [0x01, POS_STOP_F, VEL_STOP_F, 0.0, 0.0, 0.0, 0, 0, 0]
    return [0xFE, 0xEF, 0xFF, 0, 0, 0, 0, 0, 0], motors, [0, 0, 0, 0], [0] * 40, [0] * 12, [0, 0], 0, 0


def low_cmd_filled():
    head = [0xFE, 0xEF, 0xFF, 7, 0x01020304, 0xA0B0C0D0, 3, 0xFFFFFFFE, 0x1234]
    motors = []
    for i in range(20):
        motors += [
            i % 3,
            -1.5 + 0.125 * i,
            0.25 * i - 2.0,
            0.5 * i - 3.0,
            20.0 + i,
            0.5 + 0.0625 * i,
            i,
            100 + i,
            0xFFFF0000 + i,
        ]
    bms = [0x5A, 1, 2, 3]
    wireless = [(k * 7 + 1) % 256 for k in range(40)]
    led = [200 + k for k in range(12)]
    return head, motors, bms, wireless, led, [0x11, 0x22], 0x33, 0xDEADBEEF


def pack_cmd(fmt, parts, crc):
    head, motors, bms, wireless, led, fan, gpio, reserve = parts
    return struct.pack(fmt, *head, *motors, *bms, *wireless, *led, *fan, gpio, reserve, crc)


def low_state_filled():
    head = [0xFE, 0xEF, 0xFF, 9, 5, 6, 7, 8, 0x0102]
    imu = [1.0, -0.25, 0.5, -0.125, 0.5, -1.5, 2.25, 0.125, -0.375, 9.75, 0.0625, -0.03125, 3.0, 41]
    motors = []
    for i in range(20):
        q = 0.25 * i - 2.5
        dq = -0.5 * i + 1.0
        ddq = 3.0 * i
        motors += [1, q, dq, ddq, 0.75 * i - 4.0, q + 0.5, dq - 0.25, -ddq, 30 + i, 1000 * i, i, 0x80000000 + i]
    bms = [1, 2, 3, 87, -1234, 321, 25, 26, 27, 28] + [3600 + 10 * k for k in range(15)]
    tail = (
        [10, -20, 300, -32768, 1, 2, 3, 32767, 123456789]
        + [255 - k for k in range(40)]
        + [0x5A, 1.5, 40, 41, 28.5, -3.25, 1000, 2000, 3000, 65535, 0xCAFEBABE]
    )
    return head + imu + motors + bms + tail


def pack_state(fmt, values, crc):
    return struct.pack(fmt, *values, crc)


def report(name, image_fmt, cdr_fmt, pack, parts):
    image = pack(image_fmt, parts, 0)
    crc = unitree_crc(image)
    image = pack(image_fmt, parts, crc)
    cdr = b"\x00\x01\x00\x00" + pack(cdr_fmt, parts, crc)
    print(
        "%s: image_len %d crc 0x%08X image_zlib 0x%08X cdr_len %d cdr_zlib 0x%08X"
        % (name, len(image), crc, zlib.crc32(image), len(cdr), zlib.crc32(cdr))
    )


if __name__ == "__main__":
    assert struct.calcsize(IMAGE_CMD) == 812 and struct.calcsize(IMAGE_STATE) == 1180
    assert struct.calcsize(CDR_CMD) == 808 and struct.calcsize(CDR_STATE) == 1176
    # Check of the CRC port: CRC-32/MPEG-2 of "123456789" is 0x0376E6E7; over whole words its
    # bytes are the words' big-endian bytes ("1234", "5678"; one word of "9\0\0\0" differs, so
    # the published value is checked on 8 bytes against the bytewise definition instead).
    def mpeg2(data):
        crc = 0xFFFFFFFF
        for b in data:
            crc ^= b << 24
            for _ in range(8):
                crc = ((crc << 1) ^ 0x04C11DB7) & 0xFFFFFFFF if crc & 0x80000000 else (crc << 1) & 0xFFFFFFFF
        return crc

    assert mpeg2(b"123456789") == 0x0376E6E7
    assert crc_py(struct.unpack(">2I", b"12345678")) == mpeg2(b"12345678")
    report("low_cmd_init", IMAGE_CMD, CDR_CMD, pack_cmd, low_cmd_init())
    report("low_cmd_filled", IMAGE_CMD, CDR_CMD, pack_cmd, low_cmd_filled())
    report("low_state_filled", IMAGE_STATE, CDR_STATE, pack_state, low_state_filled())
