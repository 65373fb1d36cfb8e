"""Malformed versions of every message type the suite's nodes subscribe to, as raw CDR bytes (for tests).

Each generator takes a seeded ``numpy.random.Generator`` and returns a list of bytes: values of the right kind
but absurd (huge, negative, empty, very long) and of the wrong kind (non-numeric text, NaN, inf, NUL and control
characters, bytes that are not UTF-8), wrong array lengths and names, stamps with nanosec past a second,
truncated and random bytes. rclpy cannot send some of these itself (it cuts a str at a NUL, refuses bytes that
are not UTF-8): those are rclpy's serialization with a placeholder string replaced (``with_raw_string``), which is
what another DDS client (or a C++ node with std::string) can put on the wire.
"""

from __future__ import annotations

import math

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.serialization import serialize_message
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from stewart_vibration.emulation.vibration_status import VibrationReport
from stewart_vibration.messages.joint_states import JointStateEncoder
from stewart_vibration.messages.joint_trajectory import encode_joint_trajectory
from stewart_vibration.messages.stamped_doubles import PoseStampedEncoder, WrenchStampedEncoder
from stewart_vibration.motion.guard_status import GuardStatus
from stewart_vibration.nodes.status_messages import guard_status_msg, vibration_status_msg
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES
from stewart_vibration_interfaces.msg import ForceGuardStatus, VibrationUnitsStatus

# text of the wrong kind for a field that holds a number, a count or a state
BAD_TEXT = ["many", "nan", "NaN", "inf", "-inf", "", "1e999", "-1", "1.5", "\u0661\u0662", " 7", "7 ", "0x10", "1_000",
            "1,2", "\U0001f600", "x" * 70_000, "\t", "None", "[]"]
NOT_NUMBERS = [t for t in BAD_TEXT if t not in ("", "-1", "1.5")]  # not a number in any field
PLACEHOLDER = "PLACEHOLDERXYZ"  # replaced in serialized bytes by RAW_STRINGS of its length
RAW_STRINGS = [b"12\0abcdefghijk", b"base\0xyzabcdef", b"\xff\xfe\xfdbad utf-8\xc3(", b"\x01\x02\x1b[31mred\x7f\x00xy"]
# the names the suite's statuses go by on /diagnostics (node: what), for spoofs named like each publisher
STATUS_NAMES = {"hardware_emulator: hardware emulator": ("rejections", "sim_time_s", "achieved_rtf"),
                "kinematics: kinematics": ("states_received", "states_lost", "fk_failures"),
                "vibration_planner: vibration planner": ("state", "t0_s", "windows_sent"),
                "leg_force_estimator: leg force estimator": ("states_received", "rms_error_n"),
                "mcap_recorder: mcap recorder": ("path", "last_file"),
                "planning_ui: planning UI": ("url",),
                "foxglove_bridge: foxglove bridge": ("port",)}


def with_raw_string(msg, placeholder: str, raw: bytes) -> bytes:
    """rclpy's serialization of ``msg`` with the string ``placeholder`` replaced by ``raw`` (same length)."""
    data = bytearray(serialize_message(msg))
    at = data.find(placeholder.encode())
    assert at > 0 and len(raw) == len(placeholder), (placeholder, raw)
    data[at:at + len(raw)] = raw
    return bytes(data)


def mangled(rng, good: bytes, count: int, first: int = 0) -> list[bytes]:
    """Truncated, bit-flipped, count-overwritten and random byte strings derived from ``good`` (the kinds in turn
    from ``first``). For a command, pass one already refused (e.g. with NaN values): a flipped bit must not make a
    command that moves."""
    out = []
    for i in range(first, first + count):
        buf = bytearray(good)
        kind = i % 4
        if kind == 0:
            del buf[int(rng.integers(0, len(buf))):]
        elif kind == 1:
            for at in rng.integers(0, len(buf), 3):
                buf[at] ^= 1 << int(rng.integers(0, 8))
        elif kind == 2:
            at = 4 * int(rng.integers(1, len(buf) // 4))
            buf[at:at + 4] = int(rng.choice([0xFFFFFFFF, 2**31, 1000, 7])).to_bytes(4, "little")
        else:
            buf = bytearray(rng.bytes(int(rng.integers(0, 200))))
        out.append(bytes(buf))
    return out


def _status(name: str, values: dict, level: int = 0, message: str = "m") -> DiagnosticStatus:
    return DiagnosticStatus(level=bytes([level]), name=name, message=message, hardware_id="stewart_vibration",
                            values=[KeyValue(key=k, value=v) for k, v in values.items()])


def good_vibration_status() -> VibrationUnitsStatus:
    """A well-formed vibration/status (the units running after an accepted window), as the emulator writes it."""
    return vibration_status_msg(VibrationReport(
        state="running", level="ok", reason="commanded until 9.000 s", since=1.0, time=2.0,
        amplitude=np.full(6, 2e-5), commanded_until=9.0, event_seq=4, event="accepted", event_outcome="SUCCEEDED",
        event_reason="window accepted", event_stamp=1.0, event_time=0.8, accepted=3))


# (field, values) a vibration/status reader must refuse: enums past their tables, times and amplitudes that are no
# measurement
BAD_VIBRATION_FIELDS = [("state", [7, 9, 255]), ("level", [3, 4, 255]), ("event", [4, 200]), ("ramp_cause", [7, 255]),
                        ("since_s", [math.nan, math.inf, -math.inf]), ("commanded_until_s", [math.nan, math.inf]),
                        ("ramp_start_s", [math.inf, -math.inf]), ("event_stamp_s", [math.inf]),
                        ("event_time_s", [-math.inf]),
                        ("amplitude_m", [[math.nan] * 6, [-1e-6] * 6, [2.0] * 6, [0, 0, 0, 0, 0, math.inf]])]
RAW_STRING_FIELDS = ("reason", "ramp_reason", "fault")


def vibration_statuses(rng, count: int = 60) -> list[bytes]:
    """VibrationUnitsStatus messages, each malformed in one way: an enum or outcome code outside its table, a
    time or amplitude that is not finite or out of range, a NUL / control character / bytes that are not UTF-8 in a
    string, bytes after the message, and mangled bytes."""
    out = []
    for i in range(count):
        msg = good_vibration_status()
        kind = i % 6
        if kind in (0, 1):
            name, values = BAD_VIBRATION_FIELDS[int(rng.integers(len(BAD_VIBRATION_FIELDS)))]
            setattr(msg, name, values[i % len(values)])
            out.append(serialize_message(msg))
        elif kind == 2:  # an event whose outcome is not in the table
            msg.event_outcome.code = int(rng.choice([2, 99, 9999, 65535]))
            out.append(serialize_message(msg))
        elif kind == 3:
            if i % 12 == 3:
                msg.event_outcome.message = PLACEHOLDER
            else:
                setattr(msg, RAW_STRING_FIELDS[i % len(RAW_STRING_FIELDS)], PLACEHOLDER)
            out.append(with_raw_string(msg, PLACEHOLDER, RAW_STRINGS[i % len(RAW_STRINGS)]))
        elif kind == 4:  # bytes after the message: not one
            out.append(serialize_message(msg) + bytes(rng.integers(0, 256, 8 + i % 9, dtype=np.uint8)))
        else:
            msg.state = 99  # a flipped bit must not make a well-formed status
            out.extend(mangled(rng, serialize_message(msg), 1, i))
    return out


def good_guard_status() -> ForceGuardStatus:
    """A well-formed kinematics/guard_status: a force trip and its stop, as kinematics writes it."""
    status = GuardStatus("tripped", 30.0, 0.0, "tripped at 2.000 s: force", "force", 2.0, 31.0, 0.2, 33.0, 0.3,
                         34.0, 0.4, 0.12, 0.8, tripped_goal=np.array([0.0, 0.0, 0.3, 0.0, 0.0, 0.0]),
                         tripped_direction=np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0]), blocked_directions=1)
    return guard_status_msg(status, Time(sec=2))


def guard_statuses(rng, count: int = 12) -> list[bytes]:
    """ForceGuardStatus messages with a state or trip limit outside its table, a trip without its time or limit, a
    limit that is negative or not finite, a tripped goal that is no pose, a NUL or bad UTF-8 in the message, bytes
    after it, and mangled bytes."""
    out = []
    for i in range(count):
        msg = good_guard_status()
        kind = i % 6
        if kind == 0:
            msg.state = int(rng.choice([3, 4, 255]))
        elif kind == 1:
            msg.trip_limit = int(rng.choice([4, 9, 255])) if i % 12 == 1 else ForceGuardStatus.LIMIT_NONE
        elif kind == 2:
            msg.trip_time_s = [math.nan, math.inf][i % 2]
        elif kind == 3:
            msg.force_limit_n = [-1.0, math.nan, math.inf][i % 3]
        elif kind == 4:
            msg.tripped_goal.orientation.w = 0.0  # a zero quaternion
        else:
            msg.message = PLACEHOLDER
            out.append(with_raw_string(msg, PLACEHOLDER, RAW_STRINGS[i % len(RAW_STRINGS)]))
            continue
        out.append(serialize_message(msg))
    refused = good_guard_status()
    refused.state = 77
    return out + [serialize_message(good_guard_status()) + b"\x01" * 8] + mangled(rng, serialize_message(refused), 4)


def diagnostic_arrays(rng, count: int = 60) -> list[bytes]:
    """/diagnostics arrays with statuses named like each of the suite's publishers, each with a value of the wrong
    kind where a reader reads a number or a path (the emulator's rejection count, the planner's state and t0, the
    recorder's path, the nodes' stream counts), NUL or non-UTF-8 strings, and mangled bytes."""
    out = []
    names = list(STATUS_NAMES)
    for i in range(count):
        name = names[i % len(names)]
        kind = (i // len(names)) % 4
        values = {key: BAD_TEXT[(i + k) % len(BAD_TEXT)] for k, key in enumerate(STATUS_NAMES[name])}
        if name.startswith("vibration_planner"):
            values["state"] = "running"
        if name.startswith("mcap_recorder"):
            values["path"] = "/tmp/" + "a" * 5000 if kind == 0 else "/tmp/run\x01/x.mcap"
        if kind == 1:
            values[STATUS_NAMES[name][0]] = PLACEHOLDER
            array = DiagnosticArray(status=[_status(name, values, 1, "rejected leg trajectory: x")])
            out.append(with_raw_string(array, PLACEHOLDER, RAW_STRINGS[i % len(RAW_STRINGS)]))
            continue
        statuses = [_status(name, values, 1, "rejected leg trajectory: spoofed")]
        if kind == 2:  # among well-formed statuses of other (made-up) nodes, and many names
            statuses += [_status(f"spoof_{i}_{k}: x", {"k": "v"}) for k in range(40)]
        array = DiagnosticArray(status=statuses)
        out.append(serialize_message(array))
        if kind == 3:
            out.extend(mangled(rng, out[-1], 1, i))
    return out


def joint_states(rng, names=LEG_NAMES + VIB_NAMES, count: int = 60) -> list[bytes]:
    """JointState messages (500 Hz stream) each malformed in one way: NaN / inf / 1e300 positions, arrays shorter
    than the names, repeated or NUL names, a stamp's nanosec past a second, mangled bytes."""
    names = list(names)
    k = len(names)
    encoder = JointStateEncoder(names)
    good = encoder.encode(1.0, np.full(k, 0.17), np.zeros(k), np.zeros(k))
    out = []
    for i in range(count):
        kind = i % 7
        if kind == 0:
            pos = np.full(k, 0.17)
            pos[int(rng.integers(k))] = float(rng.choice([np.nan, np.inf, -np.inf, 1e300, -1e300]))
            out.append(encoder.encode(1.0 + i * 1e-3, pos, np.zeros(k), np.zeros(k)))
        elif kind == 1:
            out.append(JointStateEncoder(names[:-1] + names[:1]).encode(1.0, np.full(k, 0.17)))  # repeated
        elif kind == 2:
            short = JointStateEncoder(names, fields=("velocity",))
            out.append(short.encode(1.0, velocity=np.zeros(k)))  # no positions at all
        elif kind == 3:
            out.append(JointStateEncoder([names[0] + "\0x"] + names[1:]).encode(1.0, np.full(k, 0.17)))
        elif kind == 4:
            bad = bytearray(good)
            bad[8:12] = int(rng.integers(1_000_000_000, 2**32)).to_bytes(4, "little")
            out.append(bytes(bad))
        elif kind == 5:
            out.append(JointStateEncoder(names[:3]).encode(1.0, np.full(3, 0.17)))  # names missing
        else:
            out.extend(mangled(rng, good, 1, i))
    return out


def poses(rng, count: int = 40) -> list[bytes]:
    """PoseStamped messages each malformed in one way: frame "base\\0x", another or a very long frame, NaN / inf
    / 1e300 coordinates, a zero or non-unit quaternion, nanosec past a second, mangled bytes."""
    q = np.array([0.0, 0.0, 0.0, 1.0])
    p = np.array([0.0, 0.0, 0.16])
    refused = PoseStampedEncoder("base").encode(1.0, [np.nan, 0.0, 0.16], q)  # the base of the mangled ones
    out = []
    frames = ["base\0x", "world", "Base", " base", "x" * 70_000, "base\x01", "\0"]
    for i in range(count):
        kind = i % 6
        if kind == 0:
            out.append(PoseStampedEncoder(frames[i % len(frames)]).encode(1.0, p, q))
        elif kind == 1:
            bad = p.copy()
            bad[i % 3] = float(rng.choice([np.nan, np.inf, -np.inf, 1e300]))
            out.append(PoseStampedEncoder("base").encode(1.0, bad, q))
        elif kind == 2:
            out.append(PoseStampedEncoder("base").encode(1.0, p, [0, 0, 0, 0] if i % 2 else [0, 0, 0, 2.0]))
        elif kind == 3:
            out.append(PoseStampedEncoder("base").encode(1.0, p, [np.nan, 0, 0, 1]))
        elif kind == 4:
            bad = bytearray(PoseStampedEncoder("base").encode(1.0, p, q))
            bad[8:12] = (4_000_000_000).to_bytes(4, "little")
            out.append(bytes(bad))
        else:
            out.extend(mangled(rng, refused, 1, i))
    return out


def wrenches(rng, count: int = 30) -> list[bytes]:
    """WrenchStamped messages each malformed in one way: non-finite values, a frame other than base, mangled."""
    refused = WrenchStampedEncoder("base").encode(1.0, np.full(6, np.nan))
    out = []
    for i in range(count):
        kind = i % 3
        if kind == 0:
            w = np.zeros(6)
            w[i % 6] = float(rng.choice([np.nan, np.inf, -np.inf]))
            out.append(WrenchStampedEncoder("base").encode(1.0, w))
        elif kind == 1:
            out.append(WrenchStampedEncoder(["platform", "base\0x", "world"][i % 3]).encode(1.0, np.ones(6)))
        else:
            out.extend(mangled(rng, refused, 1, i))
    return out


def trajectories(rng, names, count: int = 40) -> list[bytes]:
    """JointTrajectory messages (leg_* or vib_* commands) each malformed in one way: NaN / 1e300 positions, names
    missing, repeated or with a NUL, times decreasing or negative, rows of the wrong length, no points, mangled."""
    names = list(names)
    k = len(names)
    base = 0.17 if names[0].startswith("leg") else 0.0
    refused = encode_joint_trajectory(names, 0.0, [0.5, 1.0], np.full((2, k), np.nan), np.zeros((2, k)))
    out = []
    for i in range(count):
        kind = i % 8
        pos = np.full((2, k), base)
        if kind == 0:
            pos[1, i % k] = float(rng.choice([np.nan, np.inf, 1e300, -1e300]))
            out.append(encode_joint_trajectory(names, 0.0, [0.5, 1.0], pos, np.zeros((2, k))))
        elif kind == 1:
            out.append(encode_joint_trajectory(names[:-1] + names[:1], 0.0, [0.5, 1.0], pos))
        elif kind == 2:
            out.append(encode_joint_trajectory([names[0] + "\0x"] + names[1:], 0.0, [0.5, 1.0], pos))
        elif kind == 3:
            out.append(encode_joint_trajectory(names, 0.0, [1.0, 0.5], pos))  # times decreasing
        elif kind == 4:
            msg = JointTrajectory(joint_names=names)
            msg.points = [JointTrajectoryPoint(positions=[base] * (k - 1)), JointTrajectoryPoint(positions=[base] * k)]
            msg.points[1].time_from_start.sec = 1
            out.append(serialize_message(msg))
        elif kind == 5:
            out.append(serialize_message(JointTrajectory(joint_names=names)))  # no points
        elif kind == 6:
            out.append(encode_joint_trajectory(names, -5.0, [-1.0, 0.5], pos))  # negative time_from_start
        else:
            out.extend(mangled(rng, refused, 1, i))
    return out
