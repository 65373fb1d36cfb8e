"""The readers of received messages without DDS: field checks (messages.fields), the DiagnosticStatus /
DiagnosticArray decoders against rclpy's own serialization, the VibrationUnitsStatus and ForceGuardStatus readers
(messages.status_values) against the emulator's and the force guard's writers through rclpy's serializer, every
malformed kind refused with its kind and field, the checked pose and wrench batches (messages.stamped) and the
rate-limited count (messages.malformed)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from malformed_messages import (
    BAD_VIBRATION_FIELDS,
    good_guard_status,
    good_vibration_status,
    guard_statuses,
    vibration_statuses,
    with_raw_string,
)
from rclpy.serialization import deserialize_message, serialize_message

from stewart_vibration.emulation.vibration_status import VibrationReport
from stewart_vibration.errors import InvalidInputError, MalformedMessageError
from stewart_vibration.kinematics.rotations import pose_from_position_quaternion, quaternion_from_rpy
from stewart_vibration.messages.diagnostic_status import decode_diagnostic_array, decode_diagnostic_status
from stewart_vibration.messages.fields import (
    MAX_TEXT,
    check_frame,
    check_number,
    check_text,
    check_time,
    parse_integer,
    parse_number,
)
from stewart_vibration.messages.joint_states import (
    JointStateEncoder,
    decode_joint_states,
    decode_joint_states_dropping_malformed,
)
from stewart_vibration.messages.joint_trajectory import decode_joint_trajectory, encode_joint_trajectory
from stewart_vibration.messages.malformed import MalformedCounter
from stewart_vibration.messages.stamped import pose_from_cdr, poses_from_cdr, rows_within, wrenches_from_cdr
from stewart_vibration.messages.stamped_doubles import (
    PoseStampedEncoder,
    WrenchStampedEncoder,
    decode_pose_stamped,
    decode_stamped_doubles,
)
from stewart_vibration.messages.status_values import (
    MAX_VALUES,
    StatusMessage,
    checked_status,
    emulator_rejections,
    guard_status_from_cdr,
    planner_settings,
    recorder_files,
    status_from_cdr,
    status_from_msg,
    statuses_from_cdr,
    vibration_report_from_cdr,
)
from stewart_vibration.nodes.status_messages import guard_status_msg, vibration_status_msg
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES
from stewart_vibration.vibration.settings import STREAM_KEYS, default_settings
from stewart_vibration_interfaces.msg import ForceGuardStatus, Outcome, VibrationUnitsStatus


def malformed(kind: str, field: str | None = None):
    """pytest.raises for a MalformedMessageError of ``kind`` (and ``field``)."""
    class Check:
        def __enter__(self):
            self.ctx = pytest.raises(MalformedMessageError)
            self.info = self.ctx.__enter__()
            return self.info

        def __exit__(self, *exc):
            handled = self.ctx.__exit__(*exc)
            assert self.info.value.kind == kind, self.info.value
            if field is not None:
                assert self.info.value.field == field, self.info.value
            return handled
    return Check()


# -- fields --------------------------------------------------------------------------------------------------
def test_frame_is_base_or_empty_only():
    assert check_frame("base", "x") == "base" and check_frame("", "x") == ""
    for bad in ("base\0x", "world", "Base", " base", "base ", "\0", b"base", None):
        with malformed("frame", "frame_id"):
            check_frame(bad, "target pose")


def test_text_refuses_nul_control_characters_replacement_and_length():
    assert check_text("ok\ttab\nnewline ü", "f") == "ok\ttab\nnewline ü"
    for bad in ("a\0b", "\x01", "\x1b[31m", "\x7f", "bad \ufffd utf-8", "x" * (MAX_TEXT + 1)):
        with malformed("text", "f"):
            check_text(bad, "f")
    with malformed("type", "f"):
        check_text(b"bytes", "f")


@pytest.mark.parametrize("text, value", [("1.5", 1.5), ("-2e-3", -2e-3), ("+.5", 0.5), ("10", 10.0), ("3.", 3.0),
                                         ("1E+2", 100.0)])
def test_numbers_as_text(text, value):
    assert parse_number(text, "n") == value


@pytest.mark.parametrize("text", ["abc", "", " 1", "1 ", "1_0", "\u0661\u0662", "0x10", "1e", "--1", "nan", "NaN",
                                  "inf", "-Infinity", "1" * 65, None, 1.0])
def test_non_numbers_are_refused(text):
    with malformed("type", "n"):
        parse_number(text, "n")


def test_number_finiteness_and_range():
    with malformed("not_finite", "n"):
        parse_number("1e999", "n")
    with malformed("range", "n"):
        parse_number("-1", "n", low=0.0)
    assert parse_integer("12", "i") == 12 and parse_integer("-3", "i", low=-10) == -3
    for bad in ("1.0", "1e3", "x", "", "٣", None):
        with malformed("type", "i"):
            parse_integer(bad, "i")
    with malformed("range", "i"):
        parse_integer("-1", "i")
    with malformed("range", "i"):
        parse_integer(str(2**60), "i")
    assert check_number(3, "c") == 3.0
    for bad, kind in ((True, "type"), ("1", "type"), (None, "type"), (math.nan, "not_finite"), (math.inf, "not_finite"),
                      (-1.0, "range")):
        with malformed(kind, "c"):
            check_number(bad, "c", low=0.0)


def test_times():
    assert check_time(0, 0, "clock") == (0, 0) and check_time(5, 999_999_999, "clock") == (5, 999_999_999)
    for sec, nanosec in ((-1, 0), (0, 1_000_000_000), (0, -1), (1.5, 0), (None, 0)):
        with malformed("range", "clock"):
            check_time(sec, nanosec, "clock")


def test_a_clock_that_is_no_time_is_dropped_not_raised(ros_domain):
    """rclpy's TimeSource raises on /clock with negative seconds (the node died); guarded, it is counted and the
    clock keeps its last time. The callback is called directly: no other process, no DDS traffic."""
    import rclpy
    from builtin_interfaces.msg import Time
    from rclpy.context import Context
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rosgraph_msgs.msg import Clock

    from stewart_vibration.nodes.diagnostics import MalformedInputs
    from stewart_vibration.nodes.run_loop import guard_sim_clock

    guard_sim_clock()
    context = Context()
    context.init(domain_id=ros_domain)
    try:
        node = Node("clock_guard_test", context=context, parameter_overrides=[Parameter("use_sim_time", value=True)])
        node.malformed = MalformedInputs(node, None)
        source = node._time_source
        source.clock_callback(Clock(clock=Time(sec=12, nanosec=500)))
        source.clock_callback(Clock(clock=Time(sec=-5, nanosec=0)))
        source.clock_callback(Clock(clock=Time(sec=13, nanosec=1_500_000_000)))
        assert node.get_clock().now().nanoseconds == 12_000_000_500
        assert node.malformed.counter.counts == {"/clock": 2}
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


# -- DiagnosticStatus / DiagnosticArray on the wire ---------------------------------------------------------------
def status_msg(name="hardware_emulator: vibration", values=None, level=0, message="m"):
    return DiagnosticStatus(level=bytes([level]), name=name, message=message, hardware_id="stewart_vibration",
                            values=[KeyValue(key=k, value=v) for k, v in (values or {}).items()])


def test_status_decoder_matches_rclpy_serialization():
    values = {"state": "running", "since_s": "1.250000", "amplitude_um": "1.000,2.000", "ü": "ß"}
    msg = status_msg(values=values, level=2, message="commanded until 3.000 s")
    status = status_from_cdr(serialize_message(msg))
    assert status == status_from_msg(msg)
    assert (status.level, status.level_name, status.name, status.node) == (2, "error", msg.name, "hardware_emulator")
    assert dict(status.values) == values and status.message == msg.message
    array = DiagnosticArray(status=[status_msg("a: x", {"k": "1"}), status_msg("b: y", {}, 1), msg])
    array.header.stamp.sec, array.header.frame_id = 7, "f"
    stamp, frame, decoded = decode_diagnostic_array(serialize_message(array))
    assert (stamp, frame, [d.name for d in decoded]) == (7.0, "f", ["a: x", "b: y", msg.name])
    good, bad = statuses_from_cdr(serialize_message(array))
    assert [s.name for s in good] == ["a: x", "b: y", msg.name] and not bad


def test_a_nul_rclpy_would_cut_is_seen_in_raw_bytes():
    data = with_raw_string(status_msg(values={"rejections": "12XYZ"}), "12XYZ", b"12\0YZ")
    assert decode_diagnostic_status(data).values == (("rejections", "12\0YZ"),)
    with malformed("text", "rejections"):
        status_from_cdr(data)


def test_one_bad_status_of_an_array_costs_only_itself():
    array = DiagnosticArray(status=[status_msg("good: a", {"k": "v"}), status_msg("bad: b", {"k": "QQ"})])
    data = with_raw_string(array, "QQ", b"Q\x01")
    good, bad = statuses_from_cdr(data)
    assert [s.name for s in good] == ["good: a"] and len(bad) == 1 and bad[0].kind == "text"


@pytest.mark.parametrize("data", [b"", b"\x00\x01", b"\x01\x00\x00\x00" + bytes(40), bytes(range(256)) * 3,
                                  b"\x00\x01\x00\x00" + b"\xff" * 64])
def test_garbage_is_no_status(data):
    with pytest.raises(MalformedMessageError):
        status_from_cdr(data)
    assert statuses_from_cdr(data)[0] == []


def test_truncated_and_non_utf8_statuses_are_refused():
    data = serialize_message(status_msg(values={"state": "idle"}))
    for cut in range(4, len(data) - 1, 7):
        with pytest.raises(MalformedMessageError):
            status_from_cdr(data[:cut])
    with pytest.raises(MalformedMessageError, match="UTF-8"):
        status_from_cdr(with_raw_string(status_msg(values={"state": "idle"}), "idle", b"id\xffe"))


def test_status_level_keys_and_size():
    for level in (4, 255, -1, "0", True, b"\x07"):
        with malformed("range", "level"):
            checked_status(level, "n", "m", "", [])
    assert checked_status(b"\x01", "n", "m", "", []).level == 1
    with malformed("names"):
        checked_status(0, "n", "m", "", [("k", "1"), ("k", "2")])
    with malformed("names"):
        checked_status(0, "n", "m", "", [("", "1")])
    with malformed("length", "values"):
        checked_status(0, "n", "m", "", [(f"k{i}", "") for i in range(MAX_VALUES + 1)])
    with malformed("text", "name"):
        checked_status(0, "hardware_emulator\0: x", "m", "", [])


# -- vibration/status: VibrationUnitsStatus -------------------------------------------------------------------
REPORTS = [
    VibrationReport(state="idle", level="ok", reason="no vibration commanded yet", since=0.0, time=0.0),
    VibrationReport(state="running", level="ok", reason="commanded until 12.000 s", since=3.25, time=4.5,
                    amplitude=np.array([1e-5, 2e-5, 3e-5, 4e-5, 5e-5, 6e-5]), commanded_until=12.0, event_seq=3,
                    event="accepted", event_outcome="SUCCEEDED", event_reason="window accepted", event_stamp=3.0,
                    event_time=2.7, accepted=2, refused=1),
    VibrationReport(state="ramping_out", level="warn", reason="watchdog", since=5.0, time=5.1, commanded_until=5.2,
                    ramp_start=5.0, ramp_reason="watchdog: the commands ran out", ramp_cause="watchdog", event_seq=4,
                    event="refused", event_outcome="LIMIT_EXCEEDED", event_reason="vib_2 above velocity_max",
                    event_stamp=4.9, event_time=4.8, accepted=2, refused=2),
    VibrationReport(state="estopped", level="error", reason="emergency stop latched", since=9.0, time=9.5,
                    commanded_until=9.05, ramp_start=9.0, ramp_reason="emergency stop", ramp_cause="emergency_stop",
                    event_seq=7, event="safety_ramp", event_outcome="EMERGENCY_STOPPED",
                    event_reason="ramp to zero: emergency stop", event_time=9.0, accepted=5, fault="diverged"),
]


def same_report(a: VibrationReport, b: VibrationReport) -> bool:
    """Field by field (the amplitudes to 1e-15 m, the time to the ns of a stamp)."""
    fields = [f for f in a.__dataclass_fields__ if f not in ("amplitude", "time")]
    return all(getattr(a, f) == getattr(b, f) for f in fields) and abs(a.time - b.time) < 1e-9 and \
        np.allclose(a.amplitude, b.amplitude, atol=1e-15, rtol=0)


@pytest.mark.parametrize("report", REPORTS, ids=[r.state for r in REPORTS])
def test_vibration_report_reads_back_what_the_emulator_writes(report):
    """Core report -> the emulator's VibrationUnitsStatus -> rclpy's serializer -> our reader: the same report; and
    rclpy's own deserializer agrees with the message (the enums are the .msg constants)."""
    msg = vibration_status_msg(report)
    data = serialize_message(msg)
    assert same_report(vibration_report_from_cdr(data), report)
    wire = deserialize_message(data, VibrationUnitsStatus)
    assert wire.state == getattr(VibrationUnitsStatus, report.state.upper())
    assert wire.event == getattr(VibrationUnitsStatus, f"EVENT_{(report.event or 'none').upper()}")
    assert wire.ramp_cause == getattr(VibrationUnitsStatus, f"RAMP_{(report.ramp_cause or 'none').upper()}")
    if report.event:
        assert wire.event_outcome.code == getattr(Outcome, report.event_outcome)


def test_every_malformed_vibration_status_is_refused():
    """Every kind the fuzzer sends (tests' malformed_messages): out-of-table enums and codes, non-finite times and
    amplitudes, bad strings, trailing and mangled bytes -- refused, never a wrong report."""
    statuses = vibration_statuses(np.random.default_rng(3), 120)
    for data in statuses:
        with pytest.raises(MalformedMessageError):
            vibration_report_from_cdr(data)
    assert vibration_report_from_cdr(serialize_message(good_vibration_status())).state == "running"


@pytest.mark.parametrize("field, value", [(f, v) for f, values in BAD_VIBRATION_FIELDS for v in values])
def test_each_out_of_range_vibration_field_is_named(field, value):
    msg = good_vibration_status()
    setattr(msg, field, value)
    with pytest.raises(MalformedMessageError) as info:
        vibration_report_from_cdr(serialize_message(msg))
    assert info.value.field == field, info.value


def test_an_inactive_robot_reads_back_inactive_and_a_bool_that_is_no_bool_is_refused():
    data = serialize_message(vibration_status_msg(REPORTS[0], active=False))
    assert vibration_report_from_cdr(data).active is False
    live = serialize_message(vibration_status_msg(REPORTS[0], active=True))
    (where,) = [i for i, (a, b) in enumerate(zip(data, live)) if a != b]  # the one byte of `active`
    assert vibration_report_from_cdr(live).active is True
    with pytest.raises(MalformedMessageError) as info:
        vibration_report_from_cdr(live[:where] + bytes([2]) + live[where + 1:])
    assert info.value.field == "active"


def test_nan_times_are_none_and_no_ramp_is_minus_inf():
    report = vibration_report_from_cdr(serialize_message(vibration_status_msg(REPORTS[0])))
    assert (report.commanded_until, report.ramp_start, report.event_stamp, report.event_time) == (
        -math.inf, None, None, None)
    assert (report.event, report.event_outcome, report.event_reason) == ("", "", "")


# -- /diagnostics of the nodes, guard status ---------------------------------------------------------------------
def test_emulator_rejections():
    def status(**values):
        return StatusMessage(1, "hardware_emulator: hardware emulator", "rejected ...", values=values)
    assert emulator_rejections(status()) is None and emulator_rejections(status(rejections="3")) == 3
    for bad in ("many", "-1", "2.5", "", "nan"):
        with pytest.raises(MalformedMessageError):
            emulator_rejections(status(rejections=bad))


def test_recorder_statuses():
    files = recorder_files(StatusMessage(0, "mcap_recorder: recorder", "ok", values={"path": "/r/a.mcap"}))
    assert (files.path, files.last_file) == ("/r/a.mcap", "")
    with malformed("text", "path"):
        recorder_files(StatusMessage(0, "r", "ok", values={"path": "/" + "a" * 5000}))


def test_guard_status_reads_what_the_force_guard_writes(robot):
    """An armed, an off and a tripped guard (a force trip during a move, with its stop) -> ForceGuardStatus ->
    rclpy's serializer -> our reader: the guard's own status."""
    from stewart_vibration.motion.force_guard import ForceGuard

    armed = ForceGuard(robot, 200.0, 15.0)
    back = guard_status_from_cdr(serialize_message(guard_status_msg(armed.status(), Time(sec=3))))
    assert (back.state, back.force_limit_n, back.moment_limit_nm, back.trip_limit) == ("armed", 200.0, 15.0, "")
    assert math.isnan(back.trip_time_s) and back.message == armed.message()
    off = guard_status_from_cdr(serialize_message(guard_status_msg(ForceGuard(robot, 0.0, 0.0).status(), Time())))
    assert off.state == "off"
    good = good_guard_status()
    tripped = guard_status_from_cdr(serialize_message(good))
    assert (tripped.state, tripped.trip_limit, tripped.trip_time_s, tripped.peak_force_n) == (
        "tripped", "force", 2.0, 34.0)
    np.testing.assert_allclose(tripped.tripped_goal, [0.0, 0.0, 0.3, 0.0, 0.0, 0.0], atol=1e-12)
    assert tripped.record()["tripped_direction"] == [0.0, 0.0, 1.0, 0.0, 0.0, 0.0] and tripped.blocked_directions == 1
    assert deserialize_message(serialize_message(good), ForceGuardStatus).state == ForceGuardStatus.TRIPPED


def test_every_malformed_guard_status_is_refused():
    for data in guard_statuses(np.random.default_rng(4), 24):
        with pytest.raises(MalformedMessageError):
            guard_status_from_cdr(data)


# -- the planner's answers -------------------------------------------------------------------------------------
def test_planner_settings(robot):
    """The planner's streaming parameters as get_parameters answers them: every STREAM_KEYS name, numbers."""
    defaults = {k: v for k, v in default_settings(robot).items() if k in STREAM_KEYS}
    assert planner_settings(defaults) == defaults
    for key, value, kind in (("lead_s", math.nan, "not_finite"), ("lookahead_s", "2", "type")):
        with malformed(kind, key):
            planner_settings({**defaults, key: value})
    del defaults["pose_timeout_s"]
    with malformed("missing", "pose_timeout_s"):
        planner_settings(defaults)


# -- checked PoseStamped / WrenchStamped batches ------------------------------------------------------------------
def poses_and_messages(n=8, seed=1):
    rng = np.random.default_rng(seed)
    poses = np.column_stack([rng.uniform(-0.05, 0.05, (n, 3)), rng.uniform(-0.3, 0.3, (n, 3))])
    quats = quaternion_from_rpy(poses[:, 3:])
    encoder = PoseStampedEncoder("base")
    return poses, [encoder.encode(0.002 * i, poses[i, :3], quats[i]) for i in range(n)]


def test_pose_batch_round_trip_and_its_bad_messages(robot):
    poses, messages = poses_and_messages()
    batch = poses_from_cdr(messages)
    np.testing.assert_allclose(batch.values, poses, atol=1e-12)
    np.testing.assert_allclose(batch.stamps, 0.002 * np.arange(8), atol=1e-12)
    assert not batch.errors and list(batch.kept) == list(range(8))
    bad = list(messages)
    from stewart_vibration.kinematics.rotations import pose_to_position_quaternion

    p, q = pose_to_position_quaternion(poses[2])
    bad[1] = PoseStampedEncoder("base\0x").encode(0.0, p, q)  # what rclpy would send as "base"
    bad[2] = PoseStampedEncoder("world").encode(0.0, p, q)
    bad[3] = PoseStampedEncoder("base").encode(0.0, [np.nan, 0, 0], q)
    bad[4] = PoseStampedEncoder("base").encode(0.0, p, [0, 0, 0, 0])
    bad[5] = b"\x00\x01\x00\x00garbage"
    bad[6] = PoseStampedEncoder("base").encode(0.0, [5e3, 0, 0], q)
    batch = poses_from_cdr(bad)
    assert list(batch.kept) == [0, 7] and len(batch.errors) == 6
    np.testing.assert_allclose(batch.values, poses[[0, 7]], atol=1e-12)
    assert {e.kind for e in batch.errors} >= {"frame", "not_finite", "range", "structure"}
    with malformed("frame", "frame_id"):
        pose_from_cdr(bad[1], "target pose")
    stamp, pose = pose_from_cdr(messages[3])
    np.testing.assert_allclose(pose, pose_from_position_quaternion(*pose_to_position_quaternion(poses[3])), atol=1e-12)
    quaternion = poses_from_cdr(messages[:2], as_quaternion=True).values
    np.testing.assert_allclose(np.linalg.norm(quaternion[:, 3:], axis=1), 1.0)


def test_quaternion_tolerance():
    _, messages = poses_and_messages(1)
    _, _, p, q = decode_pose_stamped(messages[0])
    slightly = PoseStampedEncoder("").encode(1.0, p, q * (1 + 5e-4))
    assert poses_from_cdr([slightly]).errors and not poses_from_cdr([slightly], unit_tolerance=1e-3).errors


def test_wrench_batch():
    encoder = WrenchStampedEncoder("base")
    wrenches = np.arange(30.0).reshape(5, 6)
    messages = [encoder.encode(0.01 * i, wrenches[i]) for i in range(5)]
    messages[2] = encoder.encode(0.02, [0, np.inf, 0, 0, 0, 0])
    messages[3] = WrenchStampedEncoder("platform").encode(0.03, wrenches[3])
    batch = wrenches_from_cdr(messages)
    assert list(batch.kept) == [0, 1, 4] and len(batch.errors) == 2
    np.testing.assert_array_equal(batch.values, wrenches[[0, 1, 4]])


def test_rows_within():
    rows = np.array([[0.1, 0.2], [np.nan, 0.0], [0.0, 11.0], [-10.0, 10.0], [np.inf, 0.0]])
    assert rows_within(rows, 10.0).tolist() == [True, False, False, True, False]


# -- stamps and names in the raw streams ---------------------------------------------------------------------------
def test_a_stamp_with_nanosec_past_a_second_is_malformed_and_dropped_alone():
    encoder = JointStateEncoder(LEG_NAMES + VIB_NAMES)
    messages = [encoder.encode(0.002 * i, np.full(12, 0.1), np.zeros(12), np.zeros(12)) for i in range(10)]
    bad = bytearray(messages[4])
    bad[8:12] = (1_500_000_000).to_bytes(4, "little")
    messages[4] = bytes(bad)
    with pytest.raises(InvalidInputError, match="nanosec"):
        decode_joint_states(messages)
    reasons = []
    batches, kept = decode_joint_states_dropping_malformed(messages, on_malformed=reasons.append)
    assert list(kept) == [0, 1, 2, 3, 5, 6, 7, 8, 9] and len(reasons) == 1 and "nanosec" in reasons[0]
    assert sum(len(b.stamps) for b in batches) == 9
    window = encode_joint_trajectory(VIB_NAMES, 1.0, [0.1, 0.2], np.zeros((2, 6)), np.zeros((2, 6)))
    assert decode_joint_trajectory(window).times.tolist() == pytest.approx([0.1, 0.2])
    data = bytearray(window)
    at = len(data) - 4  # the last point's time_from_start nanosec
    data[at:at + 4] = (2_000_000_000).to_bytes(4, "little")
    with pytest.raises(InvalidInputError, match="nanosec"):
        decode_joint_trajectory(bytes(data))


def test_repeated_joint_names_have_no_columns():
    from stewart_vibration.nodes.message_conversions import JointColumns

    columns = JointColumns()
    legs, vib = columns(LEG_NAMES + VIB_NAMES)
    assert list(legs) == list(range(6)) and list(vib) == list(range(6, 12))
    assert columns(LEG_NAMES + ("leg_1",) + VIB_NAMES) == (None, None)
    assert columns(LEG_NAMES)[1] is None and columns(("leg_1\0x",) + LEG_NAMES[1:])[0] is None


# -- counting and logging ---------------------------------------------------------------------------------------
def test_malformed_counter_logs_the_first_of_each_reason_then_once_a_second():
    counter = MalformedCounter(log_period_s=1.0)
    logged = [counter.record("vibration/status", reason, "m", t) for t, reason in
              [(0.0, "type since_s"), (0.1, "type since_s"), (0.2, "missing state"), (0.3, "type since_s"),
               (0.9, "missing state"), (1.25, "type since_s"), (1.3, "type since_s"), (2.3, "type since_s")]]
    assert logged == [True, False, True, False, False, True, False, True]
    assert counter.record("/diagnostics", "type since_s", "other input", 1.31)  # per input
    counter.record("/diagnostics", "x", "y", 1.32, count=4)
    values = counter.values()
    assert values["malformed vibration/status"] == "8" and values["malformed /diagnostics"] == "5"
    assert values["malformed_total"] == "13" and values["last_malformed"] == "/diagnostics: y"
    flood = MalformedCounter()
    lines = sum(flood.record("t", f"kind {i}", "m", 5.0 + i * 1e-4) for i in range(2000))  # 2000 reasons in 0.2 s
    assert lines <= 256 + 1


def test_the_run_summary_reads_recorded_statuses_through_the_same_readers():
    """A spoofed status recorded in the MCAP (a vibration status with a state outside its table, a /diagnostics status
    named like kinematics' with non-numeric values) is left out of the run summary's stream figures instead of
    raising."""
    from stewart_vibration.analysis.run_coverage import stream_summary

    good = serialize_message(vibration_status_msg(REPORTS[1]))
    spoofed = good_vibration_status()
    spoofed.state = 42
    signals = {"stream_counts": {"legs/joint_states": 100, "platform/pose_estimate": 100},
               "node_diagnostics": {"kinematics: kinematics": (0, "tracking", {"states_received": "many"}),
                                    "leg_force_estimator: leg force estimator": (
                                        0, "estimating", {"states_received": "100", "states_lost": "2",
                                                          "states_lag_p99_ms": "3.5"})},
               "vibration_status": [good, serialize_message(spoofed)]}
    streams = stream_summary(signals)
    assert streams["windows"] == {"accepted": 2, "refused": 1, "refusals": []}
    assert list(streams["nodes"]) == ["leg_force_estimator"] and streams["lost"] == 2
    assert streams["nodes"]["leg_force_estimator"]["lag_p99_ms"] == 3.5
    assert len(streams["malformed_statuses"]) == 2


def test_stamped_batches_decode_as_one_by_one_in_arrival_order():
    """decode_stamped_doubles against the one-message decoder: uniform runs through one view, the rest one by one
    (another frame of the same size, another size, a bad nanosec, garbage), in arrival order."""
    rng = np.random.default_rng(4)
    encoders = [PoseStampedEncoder(f) for f in ("base", "base", "base", "bass", "")]
    messages = [encoders[int(rng.integers(5))].encode(0.01 * i, rng.normal(size=3), rng.normal(size=4))
                for i in range(40)]
    bad_ns = bytearray(messages[7])
    bad_ns[8:12] = (1_000_000_000).to_bytes(4, "little")
    messages[7], messages[20] = bytes(bad_ns), b"\x00\x01\x00\x00" + bytes(3)
    stamps, frames, values, kept, errors = decode_stamped_doubles(messages, 7, "PoseStamped")
    assert list(kept) == [i for i in range(40) if i not in (7, 20)] and len(errors) == 2
    for j, i in enumerate(kept):
        stamp, frame, position, quaternion = decode_pose_stamped(messages[i])
        assert (stamps[j], frames[j]) == (stamp, frame)
        np.testing.assert_array_equal(values[j], np.concatenate([position, quaternion]))
