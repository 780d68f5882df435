#!/usr/bin/env python3
"""A Go2 low-level peer on Eclipse Cyclone DDS's own Python binding (`cyclonedds` from PyPI),
for the interop tests of the eemp DDS link (crates/eemp-hw/tests/cyclone_interop.rs).

It plays the robot: publishes rt/lowstate (LowState_) and subscribes rt/lowcmd (LowCmd_), with
the IDL types of unitree_go_idl.py and Cyclone's default QoS (as unitree_sdk2_python: qos=None).
Every command received is checked here, independently of the Rust code: its CRC is recomputed
over the C struct image packed with `struct` (scripts/go2_golden.py, a port of `_crc_py`).

  --mode fixture: publishes go2_golden's `low_state_filled`; counts the commands equal to
                  `low_cmd_filled` field for field.
  --mode stand:   publishes a level robot at rest in --pose (12 joint angles, rad, SDK order), at
                  --rate-hz with a ms tick, like a robot waiting for a controller.
  --sdk-types:    the message types and the CRC are Unitree's own, from the `unitree-sdk2` wheel
                  (unitree_sdk2py 1.0.1, installed without its dependencies: it pins
                  cyclonedds==0.10.2, which has no wheel for this Python). Its package __init__
                  imports a module the wheel lacks (`b2`) and its CRC loads a `crc_amd64.so` the
                  wheel lacks, so the subpackages are imported under a stub parent and the CRC
                  takes its pure-Python path (`_crc_py`). Each command's CRC is then checked both
                  by the SDK's CRC and by go2_golden's, and the SDK's CRC of a state at rest
                  against go2_golden's.

It prints one JSON line (and writes it to --out) when --seconds are over, or as soon as
--until-commands commands arrived and --linger seconds more passed.
"""
import argparse
import importlib.metadata
import json
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from cyclonedds.domain import Domain, DomainParticipant  # noqa: E402
from cyclonedds.pub import DataWriter  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402

import go2_golden as golden  # noqa: E402

SDK_CRC = None


def load_types(sdk: bool):
    """Binds the IDL classes (ours from unitree_go_idl.py, or the SDK's) as module globals."""
    global BmsState_, IMUState_, LowCmd_, LowState_, MotorState_, SDK_CRC
    if not sdk:
        from unitree_go_idl import BmsState_, IMUState_, LowCmd_, LowState_, MotorState_  # noqa: F401
        return
    import importlib.util
    import platform
    import types

    spec = importlib.util.find_spec("unitree_sdk2py")
    if spec is None:
        raise SystemExit("--sdk-types: unitree_sdk2py is not installed (scripts/install-dds-peer.sh)")
    stub = types.ModuleType("unitree_sdk2py")
    stub.__path__ = list(spec.submodule_search_locations)
    sys.modules["unitree_sdk2py"] = stub
    from unitree_sdk2py.idl.unitree_go.msg.dds_ import (  # noqa: F401
        BmsState_,
        IMUState_,
        LowCmd_,
        LowState_,
        MotorState_,
    )

    real = platform.system
    platform.system = lambda: "not-linux"  # CRC() then uses its pure-Python _crc_py
    try:
        from unitree_sdk2py.utils.crc import CRC

        SDK_CRC = CRC()
    finally:
        platform.system = real


def cmd_parts(m):
    """A received LowCmd_ as go2_golden's flat field lists."""
    head = list(m.head) + [m.level_flag, m.frame_reserve] + list(m.sn) + list(m.version) + [m.bandwidth]
    motors = []
    for c in m.motor_cmd:
        motors += [c.mode, c.q, c.dq, c.tau, c.kp, c.kd] + list(c.reserve)
    bms = [m.bms_cmd.off] + list(m.bms_cmd.reserve)
    return head, motors, bms, list(m.wireless_remote), list(m.led), list(m.fan), m.gpio, m.reserve


def cmd_crc(m):
    return golden.unitree_crc(golden.pack_cmd(golden.IMAGE_CMD, cmd_parts(m), 0))


def state_from_values(v):
    """A LowState_ from go2_golden's flat value list (the order of its struct formats)."""
    it = iter(v)

    def take(n):
        return [next(it) for _ in range(n)]

    head = take(2)
    level, fr = take(2)
    sn, version = take(2), take(2)
    (bandwidth,) = take(1)
    imu = take(14)
    motors = []
    for _ in range(20):
        f = take(12)
        motors.append(
            MotorState_(
                mode=f[0], q=f[1], dq=f[2], ddq=f[3], tau_est=f[4], q_raw=f[5], dq_raw=f[6],
                ddq_raw=f[7], temperature=f[8], lost=f[9], reserve=f[10:12],
            )
        )
    b = take(25)
    bms = BmsState_(
        version_high=b[0], version_low=b[1], status=b[2], soc=b[3], current=b[4], cycle=b[5],
        bq_ntc=b[6:8], mcu_ntc=b[8:10], cell_vol=b[10:25],
    )
    t = take(60)
    return LowState_(
        head=head, level_flag=level, frame_reserve=fr, sn=sn, version=version, bandwidth=bandwidth,
        imu_state=IMUState_(
            quaternion=imu[0:4], gyroscope=imu[4:7], accelerometer=imu[7:10], rpy=imu[10:13],
            temperature=imu[13],
        ),
        motor_state=motors, bms_state=bms, foot_force=t[0:4], foot_force_est=t[4:8], tick=t[8],
        wireless_remote=t[9:49], bit_flag=t[49], adc_reel=t[50], temperature_ntc1=t[51],
        temperature_ntc2=t[52], power_v=t[53], power_a=t[54], fan_frequency=t[55:59], reserve=t[59],
        crc=0,
    )


def sealed(values):
    """The state and its CRC over the C image (computed here)."""
    s = state_from_values(values)
    s.crc = golden.unitree_crc(golden.pack_state(golden.IMAGE_STATE, values, 0))
    return s


def standing_values(pose, tick):
    v = golden.low_state_filled()
    head = [0xFE, 0xEF, 0xFF, 0, 0, 0, 0, 0, 0]
    imu = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 9.81, 0.0, 0.0, 0.0, 30]
    motors = []
    for i in range(20):
        q = pose[i] if i < 12 else 0.0
        motors += [1, q, 0.0, 0.0, 0.0, q, 0.0, 0.0, 30, 0, 0, 0]
    bms = v[9 + 14 + 240: 9 + 14 + 240 + 25]
    tail = [0] * 8 + [tick] + [0] * 40 + [0, 0.0, 30, 30, 28.0, 1.0, 0, 0, 0, 0, 0]
    return head + imu + motors + bms + tail


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--domain", type=int, required=True)
    ap.add_argument("--iface", default="lo")
    ap.add_argument("--mode", choices=["fixture", "stand"], default="fixture")
    ap.add_argument("--pose", default="")
    ap.add_argument("--rate-hz", type=float, default=200.0)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--until-commands", type=int, default=0)
    ap.add_argument("--linger", type=float, default=1.0)
    ap.add_argument("--out", default="")
    ap.add_argument("--sdk-types", action="store_true")
    a = ap.parse_args()
    load_types(a.sdk_types)

    # As unitree_sdk2_python's ChannelFactoryInitialize(domain, iface) configures Cyclone.
    config = (
        '<CycloneDDS><Domain Id="any"><General><Interfaces>'
        '<NetworkInterface name="%s" priority="default" multicast="default"/>'
        "</Interfaces></General></Domain></CycloneDDS>" % a.iface
    )
    domain = Domain(a.domain, config)
    dp = DomainParticipant(a.domain)
    state_topic = Topic(dp, "rt/lowstate", LowState_)
    cmd_topic = Topic(dp, "rt/lowcmd", LowCmd_)
    writer = DataWriter(dp, state_topic)
    reader = DataReader(dp, cmd_topic)

    expected = golden.low_cmd_filled()
    expected_crc = golden.unitree_crc(golden.pack_cmd(golden.IMAGE_CMD, expected, 0))
    pose = [float(x) for x in a.pose.split(",")] if a.pose else [0.0] * 12
    result = {
        "cyclonedds": importlib.metadata.version("cyclonedds"),
        "states_sent": 0,
        "commands": 0,
        "crc_ok": 0,
        "crc_bad": 0,
        "fixture_equal": 0,
        "first_bad": None,
        "max_abs_tau_nm": 0.0,
        "max_kp": 0.0,
        "max_kd": 0.0,
        "idle_motors_ok": True,
        "sdk": importlib.metadata.version("unitree-sdk2") if a.sdk_types else None,
        "sdk_crc_ok": 0,
        "sdk_state_crc_equals_golden": None,
    }
    t0 = time.monotonic()
    enough_at = None
    period = 1.0 / a.rate_hz
    next_send = t0
    fixture_state = sealed(golden.low_state_filled())
    if SDK_CRC:
        # The SDK packs LowState_ with signed formats where the IDL is unsigned (temperatures
        # 'b', fan_frequency 'h'): the fixture's values above 127 / 32767 make its CRC raise,
        # so its state CRC is compared on a robot at rest, and the error on the fixture kept.
        rest = standing_values([0.1 * i for i in range(12)], 1234)
        want = golden.unitree_crc(golden.pack_state(golden.IMAGE_STATE, rest, 0))
        result["sdk_state_crc_equals_golden"] = SDK_CRC.Crc(state_from_values(rest)) == want
        try:
            SDK_CRC.Crc(fixture_state)
            result["sdk_state_crc_fixture_error"] = None
        except Exception as e:  # noqa: BLE001 (what the SDK raises is the finding)
            result["sdk_state_crc_fixture_error"] = "%s: %s" % (type(e).__name__, e)
    while True:
        now = time.monotonic()
        if now - t0 > a.seconds or (enough_at is not None and now - enough_at > a.linger):
            break
        if now >= next_send:
            next_send += period
            if a.mode == "fixture":
                writer.write(fixture_state)
            else:
                writer.write(sealed(standing_values(pose, int((now - t0) * 1000) + 1)))
            result["states_sent"] += 1
        for m in reader.take(N=100):
            result["commands"] += 1
            crc = cmd_crc(m)
            if crc == m.crc:
                result["crc_ok"] += 1
            else:
                result["crc_bad"] += 1
                if result["first_bad"] is None:
                    result["first_bad"] = "stored 0x%08X, computed 0x%08X" % (m.crc, crc)
            if SDK_CRC and SDK_CRC.Crc(m) == m.crc:
                result["sdk_crc_ok"] += 1
            if cmd_parts(m) == expected and m.crc == expected_crc:
                result["fixture_equal"] += 1
            for c in m.motor_cmd[:12]:
                result["max_abs_tau_nm"] = max(result["max_abs_tau_nm"], abs(c.tau))
                result["max_kp"] = max(result["max_kp"], c.kp)
                result["max_kd"] = max(result["max_kd"], c.kd)
            if a.mode == "stand":
                for c in m.motor_cmd[12:]:
                    if not (c.mode == 1 and c.q == golden_f32(golden.POS_STOP_F) and c.dq == 16000.0
                            and c.kp == 0.0 and c.kd == 0.0 and c.tau == 0.0):
                        result["idle_motors_ok"] = False
            if a.until_commands and enough_at is None and result["commands"] >= a.until_commands:
                enough_at = time.monotonic()
        time.sleep(max(0.0, min(next_send - time.monotonic(), 0.001)))
    line = json.dumps(result)
    print(line, flush=True)
    if a.out:
        with open(a.out, "w") as f:
            f.write(line + "\n")
    del domain


def golden_f32(x):
    """`x` rounded to float32, as the wire carries it."""
    import struct

    return struct.unpack("<f", struct.pack("<f", x))[0]


if __name__ == "__main__":
    main()
