"""Malformed versions of every message type the suite's nodes subscribe to, as raw CDR bytes (for tests).

Each generator takes a seeded ``numpy.random.Generator`` and returns a list of bytes: values of the right kind
but absurd (huge, negative, empty, very long) and of the wrong kind (non-numeric text, NaN, inf, NUL and control
characters, bytes that are not UTF-8), wrong array lengths and names, stamps with nanosec past a second,
truncated and random bytes. rclpy cannot send some of these itself (it cuts a str at a NUL, refuses bytes that
are not UTF-8): those are rclpy's serialization with a placeholder string replaced (``with_raw_string``), which is
what another DDS client (or a C++ node with std::string) can put on the wire.
"""

from __future__ import annotations

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.serialization import serialize_message
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from stewart_vibration.emulation.vibration_status import VibrationReport
from stewart_vibration.messages import cdr
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES

# text of the wrong kind for a field that holds a number, a count or a state
BAD_TEXT = ["many", "nan", "NaN", "inf", "-inf", "", "1e999", "-1", "1.5", "\u0661\u0662", " 7", "7 ", "0x10", "1_000",
            "1,2", "\U0001f600", "x" * 70_000, "\t", "None", "[]"]
NOT_NUMBERS = [t for t in BAD_TEXT if t not in ("", "-1", "1.5")]  # not a number in any field
# the vibration/status values a reader takes as a number, a count or a state
READ_AS_NUMBERS = ("state", "since_s", "time_s", "amplitude_um", "commanded_until_s", "ramp_start_s", "event_seq",
                   "event_stamp_s", "event_time_s", "accepted_windows", "refused_windows")
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


def vibration_statuses(rng, count: int = 60) -> list[bytes]:
    """vibration/status messages named like the emulator's, each malformed in one way."""
    good = VibrationReport(state="running", level="ok", reason="commanded until 9.000 s", since=1.0, time=2.0,
                           amplitude=np.full(6, 2e-5), commanded_until=9.0, event_seq=4, event="accepted",
                           event_stamp=1.0, event_time=0.8, accepted=3).as_values()
    name = "hardware_emulator: vibration"
    out = []
    keys = sorted(good)
    for i in range(count):
        values = dict(good)
        kind = i % 6
        if kind in (0, 1):  # a value of the wrong kind in a field read as a number, count or state
            key = READ_AS_NUMBERS[int(rng.integers(len(READ_AS_NUMBERS)))] if kind else "event_seq"
            values[key] = NOT_NUMBERS[i % len(NOT_NUMBERS)]
            out.append(serialize_message(_status(name, values)))
        elif kind == 2:  # a key missing
            del values[keys[int(rng.integers(len(keys)))]]
            out.append(serialize_message(_status(name, values)))
        elif kind == 3:  # NUL, control characters, bytes that are not UTF-8
            values[keys[int(rng.integers(len(keys)))]] = PLACEHOLDER
            out.append(with_raw_string(_status(name, values), PLACEHOLDER, RAW_STRINGS[i % len(RAW_STRINGS)]))
        elif kind == 4:  # a level beyond STALE, a duplicated key, a very long message
            msg = _status(name, values, level=int(rng.choice([4, 7, 255])))
            msg.values.append(KeyValue(key="state", value="idle"))
            msg.message = "m" * 100_000 if i % 12 == 4 else msg.message
            out.append(serialize_message(msg))
        else:
            refused = dict(good, event_seq="many")  # a flipped bit must not make a well-formed status
            out.extend(mangled(rng, serialize_message(_status(name, refused)), 1, i))
    return out


def guard_statuses(rng, count: int = 12) -> list[bytes]:
    """kinematics/guard_status messages with a malformed state, trip limit or trip time."""
    out = []
    for i in range(count):
        values = {"state": "tripped", "trip_limit": "force", "trip_time_s": BAD_TEXT[i % len(BAD_TEXT)]}
        if i % 3 == 1:
            values = {"state": BAD_TEXT[i % len(BAD_TEXT)]}
        if i % 3 == 2:
            values = {"state": "tripped", "trip_limit": PLACEHOLDER, "trip_time_s": "1.0"}
            out.append(with_raw_string(_status("kinematics: force guard", values, 2), PLACEHOLDER,
                                       RAW_STRINGS[i % len(RAW_STRINGS)]))
            continue
        out.append(serialize_message(_status("kinematics: force guard", values, 2)))
    return out + mangled(rng, out[0], 4)


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
    encoder = cdr.JointStateEncoder(names)
    good = encoder.encode(1.0, np.full(k, 0.17), np.zeros(k), np.zeros(k))
    out = []
    for i in range(count):
        kind = i % 7
        if kind == 0:
            pos = np.full(k, 0.17)
            pos[int(rng.integers(k))] = float(rng.choice([np.nan, np.inf, -np.inf, 1e300, -1e300]))
            out.append(encoder.encode(1.0 + i * 1e-3, pos, np.zeros(k), np.zeros(k)))
        elif kind == 1:
            out.append(cdr.JointStateEncoder(names[:-1] + names[:1]).encode(1.0, np.full(k, 0.17)))  # repeated
        elif kind == 2:
            short = cdr.JointStateEncoder(names, fields=("velocity",))
            out.append(short.encode(1.0, velocity=np.zeros(k)))  # no positions at all
        elif kind == 3:
            out.append(cdr.JointStateEncoder([names[0] + "\0x"] + names[1:]).encode(1.0, np.full(k, 0.17)))
        elif kind == 4:
            bad = bytearray(good)
            bad[8:12] = int(rng.integers(1_000_000_000, 2**32)).to_bytes(4, "little")
            out.append(bytes(bad))
        elif kind == 5:
            out.append(cdr.JointStateEncoder(names[:3]).encode(1.0, np.full(3, 0.17)))  # names missing
        else:
            out.extend(mangled(rng, good, 1, i))
    return out


def poses(rng, count: int = 40) -> list[bytes]:
    """PoseStamped messages each malformed in one way: frame "base\\0x", another or a very long frame, NaN / inf
    / 1e300 coordinates, a zero or non-unit quaternion, nanosec past a second, mangled bytes."""
    q = np.array([0.0, 0.0, 0.0, 1.0])
    p = np.array([0.0, 0.0, 0.16])
    refused = cdr.PoseStampedEncoder("base").encode(1.0, [np.nan, 0.0, 0.16], q)  # the base of the mangled ones
    out = []
    frames = ["base\0x", "world", "Base", " base", "x" * 70_000, "base\x01", "\0"]
    for i in range(count):
        kind = i % 6
        if kind == 0:
            out.append(cdr.PoseStampedEncoder(frames[i % len(frames)]).encode(1.0, p, q))
        elif kind == 1:
            bad = p.copy()
            bad[i % 3] = float(rng.choice([np.nan, np.inf, -np.inf, 1e300]))
            out.append(cdr.PoseStampedEncoder("base").encode(1.0, bad, q))
        elif kind == 2:
            out.append(cdr.PoseStampedEncoder("base").encode(1.0, p, [0, 0, 0, 0] if i % 2 else [0, 0, 0, 2.0]))
        elif kind == 3:
            out.append(cdr.PoseStampedEncoder("base").encode(1.0, p, [np.nan, 0, 0, 1]))
        elif kind == 4:
            bad = bytearray(cdr.PoseStampedEncoder("base").encode(1.0, p, q))
            bad[8:12] = (4_000_000_000).to_bytes(4, "little")
            out.append(bytes(bad))
        else:
            out.extend(mangled(rng, refused, 1, i))
    return out


def wrenches(rng, count: int = 30) -> list[bytes]:
    """WrenchStamped messages each malformed in one way: non-finite values, a frame other than base, mangled."""
    refused = cdr.WrenchStampedEncoder("base").encode(1.0, np.full(6, np.nan))
    out = []
    for i in range(count):
        kind = i % 3
        if kind == 0:
            w = np.zeros(6)
            w[i % 6] = float(rng.choice([np.nan, np.inf, -np.inf]))
            out.append(cdr.WrenchStampedEncoder("base").encode(1.0, w))
        elif kind == 1:
            out.append(cdr.WrenchStampedEncoder(["platform", "base\0x", "world"][i % 3]).encode(1.0, np.ones(6)))
        else:
            out.extend(mangled(rng, refused, 1, i))
    return out


def trajectories(rng, names, count: int = 40) -> list[bytes]:
    """JointTrajectory messages (leg_* or vib_* commands) each malformed in one way: NaN / 1e300 positions, names
    missing, repeated or with a NUL, times decreasing or negative, rows of the wrong length, no points, mangled."""
    names = list(names)
    k = len(names)
    base = 0.17 if names[0].startswith("leg") else 0.0
    refused = cdr.encode_joint_trajectory(names, 0.0, [0.5, 1.0], np.full((2, k), np.nan), np.zeros((2, k)))
    out = []
    for i in range(count):
        kind = i % 8
        pos = np.full((2, k), base)
        if kind == 0:
            pos[1, i % k] = float(rng.choice([np.nan, np.inf, 1e300, -1e300]))
            out.append(cdr.encode_joint_trajectory(names, 0.0, [0.5, 1.0], pos, np.zeros((2, k))))
        elif kind == 1:
            out.append(cdr.encode_joint_trajectory(names[:-1] + names[:1], 0.0, [0.5, 1.0], pos))
        elif kind == 2:
            out.append(cdr.encode_joint_trajectory([names[0] + "\0x"] + names[1:], 0.0, [0.5, 1.0], pos))
        elif kind == 3:
            out.append(cdr.encode_joint_trajectory(names, 0.0, [1.0, 0.5], pos))  # times decreasing
        elif kind == 4:
            msg = JointTrajectory(joint_names=names)
            msg.points = [JointTrajectoryPoint(positions=[base] * (k - 1)), JointTrajectoryPoint(positions=[base] * k)]
            msg.points[1].time_from_start.sec = 1
            out.append(serialize_message(msg))
        elif kind == 5:
            out.append(serialize_message(JointTrajectory(joint_names=names)))  # no points
        elif kind == 6:
            out.append(cdr.encode_joint_trajectory(names, -5.0, [-1.0, 0.5], pos))  # negative time_from_start
        else:
            out.extend(mangled(rng, refused, 1, i))
    return out
