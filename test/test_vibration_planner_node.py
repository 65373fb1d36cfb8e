"""vibration planner node in its own process over real DDS: the vibrate action (goal, feedback, result with
its outcome code, cancel = ramp-out), its windows, and its refusals."""

from __future__ import annotations

import re
import time
from contextlib import contextmanager

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from ros_client import PLANNER_NOT_READY, node_under_test
from trajectory_msgs.msg import JointTrajectory

from stewart_vibration import pose_to_position_quaternion, rotation_from_rpy
from stewart_vibration.nodes.message_conversions import stamp_seconds
from stewart_vibration.paper import paper_pose

pytestmark = pytest.mark.integration

F, G_ACC, RAMP, DT = 35.0, 0.3, 0.2, 0.001
VIB = [f"vib_{i}" for i in range(1, 7)]


@pytest.fixture
def planner(ros_domain, tmp_path):
    with node_under_test("planner", "stewart_vibration.nodes.vibration_planner_node", ros_domain, tmp_path) as pair:
        yield pair


def pose_msg(pose):
    position, q = pose_to_position_quaternion(pose)
    msg = PoseStamped()
    msg.header.frame_id = "base"
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = map(float, position)
    o = msg.pose.orientation
    o.x, o.y, o.z, o.w = map(float, q)
    return msg


def set_params(client, **values):
    request = SetParameters.Request()
    for name, value in values.items():
        kind = Parameter.Type.from_parameter_value(value)
        request.parameters.append(Parameter(name, kind, value).to_parameter_msg())
    return client.call(SetParameters, "vibration_planner/set_parameters", request).results


def start_with_pose(client, poses, pose, timeout_s: float = 10.0, publish_also=None, waiting_for=PLANNER_NOT_READY,
                    **vibration):
    """Publish a pose estimate (a pose vector or a PoseStamped) and send a vibrate goal; while the planner has
    no pose (or, with ``publish_also``, no /clock) yet -- a first sample sent as DDS was still matching waits for
    a heartbeat: CI -- publish again (``publish_also()`` too) and send again for up to ``timeout_s``. A goal that
    started (its plan came) or ended with another outcome than those in ``waiting_for`` is returned at once."""
    msg = pose if isinstance(pose, PoseStamped) else pose_msg(pose)
    deadline = time.monotonic() + timeout_s
    while True:
        if publish_also is not None:
            publish_also()
        poses.publish(msg)
        client.spin_for(0.2)
        goal = client.vibrate(**vibration)
        if goal.plan() is not None or goal.outcome()[0] not in waiting_for or time.monotonic() > deadline:
            return goal


def plan_t0(plan) -> float:
    return stamp_seconds(plan.t0)


def independent_gains(robot, pose):
    """k_i = n_i . u, u = platform z axis, from the hinge points (not the package's decomposition)."""
    rot = rotation_from_rpy(pose[3:])
    d = pose[:3] + robot.platform_hinges @ rot.T - robot.base_hinges
    n = d / np.linalg.norm(d, axis=1, keepdims=True)
    return n @ rot[:, 2]


def seconds(duration) -> float:
    return duration.sec + duration.nanosec * 1e-9


def samples_of(window):
    """(times s from t0, positions, velocities, accelerations) of one window."""
    t = np.array([seconds(p.time_from_start) for p in window.points])
    return t, *(np.array([getattr(p, f) for p in window.points]) for f in ("positions", "velocities",
                                                                              "accelerations"))


def emulator_status(state, since, event_seq=0, event="", event_stamp=None, level=0, reason="", event_outcome="",
                    now=None):
    """A vibration/status message as the hardware emulator publishes it (of its VibrationReport); ``now`` is the
    robot's clock when sent (default ``since``)."""
    from stewart_vibration.emulation.vibration_status import VibrationReport
    from stewart_vibration.nodes.status_messages import vibration_status_msg

    return vibration_status_msg(VibrationReport(
        state=state, level=("ok", "warn", "error")[level], reason=reason, since=since,
        time=since if now is None else now,
        event_seq=event_seq, event=event, event_stamp=event_stamp, event_reason=reason,
        event_outcome=event_outcome or ("SUCCEEDED" if event == "accepted" else "LIMIT_EXCEEDED" if event else "")))


def status_publisher(client):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from stewart_vibration_interfaces.msg import VibrationUnitsStatus

    if "status" not in client._publishers:
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        client._publishers["status"] = client.node.create_publisher(VibrationUnitsStatus, "vibration/status", qos)
    return client._publishers["status"]


def idle_robot_heartbeat(client, clock=time.time, period_s: float = 0.5):
    """The emulator's word the planner needs before it starts anything: its units idle, repeated with the
    robot's clock ``clock()`` (s) every ``period_s`` while ``client`` spins (the emulator repeats every second)."""
    status = status_publisher(client)
    return client.node.create_timer(period_s, lambda: status.publish(emulator_status("idle", 0.0, now=clock())))


def planner_messages(diagnostics):
    return [s.message for a in diagnostics for s in a.status if s.name.startswith("vibration_planner")]


def test_parameter_validation_and_refused_goals(planner):
    proc, client = planner
    diagnostics = client.subscribe("/diagnostics", DiagnosticArray)
    for values in ({"lookahead_s": 0.4},  # not longer than window_period_s (0.5)
                   {"start_lead_s": 0.1},  # the first window would begin after t0 (lead_s 0.3)
                   {"max_lookahead_s": 1.0}):  # below lookahead_s
        (result,) = set_params(client, **values)
        assert not result.successful and result.reason, values
    (typed,) = set_params(client, lead_s=1)  # an integer for a double is that number (ros2 param set ... 1)
    assert typed.successful, typed.reason
    (text,) = set_params(client, lead_s="soon")  # another type is refused by rclpy's type check, with the type
    assert not text.successful and "DOUBLE" in text.reason
    assert set_params(client, lead_s=0.3)[0].successful
    (gone,) = set_params(client, frequency_hz=40.0)  # the vibration is the goal's: no parameter for it
    assert not gone.successful

    name, message = client.vibrate().outcome()  # nothing from the robot yet: it cannot be confirmed
    assert name == "NOT_READY" and "no vibration/status from the hardware emulator" in message, (name, message)
    idle_robot_heartbeat(client)
    assert client.wait_for_subscribers("vibration/status")
    assert client.spin_until(lambda: "pose_estimate" in client.vibrate().outcome()[1], 10)
    assert client.vibrate().outcome() == ("NOT_READY", "no platform/pose_estimate received yet")
    nan = pose_msg(np.zeros(6))
    nan.pose.position.x = float("nan")
    nan_poses = client.publisher("platform/pose_estimate", PoseStamped)
    assert client.wait_for_subscribers("platform/pose_estimate")
    goal = start_with_pose(client, nan_poses, nan)  # the NaN estimate is refused when a goal needs it
    name, message = goal.outcome()
    assert name == "NOT_READY" and "pose estimate unusable" in message and "non-finite" in message
    assert goal.status() == 6  # aborted
    assert client.spin_until(lambda: any("rejected start: pose estimate unusable" in m
                                         for m in planner_messages(diagnostics)), 5)

    poses = nan_poses
    for bad in ({"frequency_hz": 500.0}, {"direction": [0.0, 0.0, 0.0]}, {"frame": "world"}, {"frame": ""},
                {"duration_s": 0.1},  # shorter than the two 0.2 s ramps
                {"ramp_s": -1.0}, {"ramp_s": 0.0}, {"acceleration_g": 0.0}, {"phase_rad": float("nan")}):
        goal = start_with_pose(client, poses, np.array([0, 0, 0.165, 0, 0, 0]), **bad)
        name, message = goal.outcome()
        assert name == "INVALID_ARGUMENT" and message, (bad, name, message)
        assert goal.plan() is None
    assert proc.alive()


def test_a_goal_streams_reports_feedback_and_its_cancel_ramps_out(robot, planner):
    proc, client = planner
    windows = client.subscribe("vibration/joint_trajectory", JointTrajectory)
    poses = client.publisher("platform/pose_estimate", PoseStamped)
    pose = paper_pose(robot)
    idle_robot_heartbeat(client)
    assert client.wait_for_subscribers("platform/pose_estimate"), proc.log_text()
    assert client.wait_matched("vibration/joint_trajectory"), proc.log_text()
    goal = start_with_pose(client, poses, pose, duration_s=0.0)  # until cancelled
    plan = goal.plan()
    assert plan is not None, goal.outcome()
    amp = G_ACC * 9.80665 / (2 * np.pi * F) ** 2
    gains = independent_gains(robot, pose)
    np.testing.assert_allclose(plan.gains, gains, atol=1e-9)
    np.testing.assert_allclose(plan.leg_amplitudes_m, np.abs(gains) * amp, rtol=1e-9)
    assert abs(plan.amplitude_m - amp) < 1e-12 and plan.frequency_hz == F and plan.duration_s == 0.0
    assert client.vibrate().outcome()[0] == "BUSY"  # one vibration at a time
    assert client.spin_until(lambda: len(windows) >= 4, 10), proc.log_text()
    running = list(windows)

    # common stamp (= the plan's t0) and names; each window safe on its own: from rest and back to rest at its end
    assert {(w.header.stamp.sec, w.header.stamp.nanosec) for w in running} == {(plan.t0.sec, plan.t0.nanosec)}
    assert all(list(w.joint_names) == VIB for w in running)
    parts = [samples_of(w) for w in running]
    assert parts[0][0][0] == 0.0 and np.abs(parts[0][1][0]).max() == 0.0
    for t, pos, vel, acc in parts:
        assert np.abs(pos[-1]).max() < 1e-15 and np.abs(vel[-1]).max() < 1e-12  # the tail ends at rest
        assert t[-1] - t[0] >= 1.5 + RAMP - 1e-9  # 1.5 s look-ahead plus the ramp-out tail
        assert acc.shape == pos.shape  # quintic windows
        np.testing.assert_allclose(np.gradient(pos, t, axis=0)[1:-1], vel[1:-1], atol=0.01 * 2 * np.pi * F * 60e-6)
    # the next window starts where the previous one is still at full amplitude, and agrees with it there
    for (t0_, p0, *_), (t1, p1, *_) in zip(parts, parts[1:]):
        tail_start = t0_[-1] - RAMP
        assert t1[0] < tail_start
        common, i, j = np.intersect1d(np.round(t0_ * 1e6), np.round(t1 * 1e6), return_indices=True)
        before = common < round(tail_start * 1e6)
        assert before.sum() > 100 and np.abs(p0[i[before]] - p1[j[before]]).max() < 1e-15

    # steady state: vib_i = k_i A sin(w t) (+ second order), amplitude |k_i| A, phase 0 or pi
    t, pos = parts[0][0], parts[0][1]
    steady = (t >= RAMP + 0.01) & (t < RAMP + 0.01 + 10 / F)
    w = 2 * np.pi * F
    basis = np.column_stack([np.sin(w * t[steady]), np.cos(w * t[steady]), np.ones(steady.sum())])
    coef = np.linalg.lstsq(basis, pos[steady], rcond=None)[0]
    np.testing.assert_allclose(coef[0], gains * amp, atol=1e-3 * amp)  # signed: phase 0 (k>0) or pi (k<0)
    assert np.abs(coef[1]).max() < 1e-3 * amp

    # feedback at 10 Hz (wall), each with the plan; counted over 2 s so that one stall of either process on a
    # busy machine (a few hundred ms) does not read as a missing stream
    count = len(goal.feedback)
    client.spin_for(2.0)
    assert len(goal.feedback) - count >= 14, len(goal.feedback) - count
    assert all(plan_t0(f.feedback.plan) == plan_t0(plan) for f in goal.feedback)

    # cancel: one last window ramping out from a sample the previous windows carried at full amplitude
    # found by content, not by count: windows published before the cancel may still be queued here (beside a
    # CPU hog 3 of them arrived after it); the ramp-out spans the ramp only, a streamed window 1.5 s and more
    def is_ramp_out(window) -> bool:
        t = samples_of(window)[0]
        return abs(t[-1] - t[0] - RAMP) < 2 * DT

    before = len(windows)
    goal.cancel()
    assert client.spin_until(lambda: any(is_ramp_out(w) for w in windows[before:]), 5)
    name, message = goal.outcome(10)
    assert name == "CANCELED" and goal.status() == 5, (name, message)
    result = goal.result()
    assert result.active_s > 1.0 and result.cycles_delivered > F * (result.active_s - 2 * RAMP) - 1e-6
    ramp_outs = [k for k in range(before, len(windows)) if is_ramp_out(windows[k])]
    assert ramp_outs == [len(windows) - 1], "windows after the cancel: one ramp-out, and nothing after it"
    stop_index = ramp_outs[0]
    ts, ps, *_ = samples_of(windows[stop_index])
    t_prev, p_prev, *_ = samples_of(windows[stop_index - 1])
    k = int(np.flatnonzero(np.round(t_prev * 1e6) == round(ts[0] * 1e6))[0])
    assert np.abs(ps[0] - p_prev[k]).max() < 1e-15 and ts[0] < t_prev[-1] - RAMP
    assert abs(ts[-1] - ts[0] - RAMP) < 2 * DT and np.abs(ps[-1]).max() < 1e-15
    assert np.abs(np.diff(ps, axis=0)).max() <= 1.05 * w * amp * DT  # no step

    # infeasible: 150 um is above the unit's 100 um
    goal = start_with_pose(client, poses, pose, amplitude_m=150e-6)
    name, message = goal.outcome()
    assert name == "LIMIT_EXCEEDED" and "amplitude_max" in message, (name, message)
    # a pose the robot cannot reach: the typed error's outcome and text come back
    goal = start_with_pose(client, poses, pose + np.array([0, 0, 0.2, 0, 0, 0]))
    name, message = goal.outcome()
    assert name == "UNREACHABLE_POSE" and "StrokeLimitError" in message, (name, message)
    assert proc.alive()


def test_the_goal_follows_the_emulators_status(robot, planner):
    """Refusal of its window, e-stop, units not at rest: the goal ends with the outcome, streaming stops, and
    the next goal works or ends with why not."""
    proc, client = planner
    windows = client.subscribe("vibration/joint_trajectory", JointTrajectory)
    diagnostics = client.subscribe("/diagnostics", DiagnosticArray)
    status = status_publisher(client)
    poses = client.publisher("platform/pose_estimate", PoseStamped)
    assert client.wait_for_subscribers("platform/pose_estimate") and client.wait_for_subscribers("vibration/status")
    assert client.wait_matched("vibration/joint_trajectory"), proc.log_text()
    status.publish(emulator_status("idle", time.time()))  # the planner runs on the wall clock here

    def start(**vibration):
        return start_with_pose(client, poses, paper_pose(robot), **vibration)

    goal = start(duration_s=0.0)
    t0 = plan_t0(goal.plan())
    assert client.spin_until(lambda: len(windows) >= 2, 5)
    status.publish(emulator_status("pending", t0 - 1, event_seq=1, level=1, event="refused",
                                   reason="vib_3: discontinuous splice at t = 12.0 s", event_stamp=t0))
    name, message = goal.outcome(5)
    assert name == "ROBOT_REFUSED" and "discontinuous splice" in message and goal.status() == 6
    count = len(windows)
    client.spin_for(1.2)  # more than two window periods: nothing more is sent
    assert len(windows) == count

    status.publish(emulator_status("idle", t0 + 1))
    goal = start(duration_s=0.0)  # after an abort a new goal works (no reset needed)
    t0 = plan_t0(goal.plan())
    status.publish(emulator_status("estopped", t0 + 0.1, event_seq=2, level=2, reason="emergency stop latched"))
    assert goal.outcome(5)[0] == "EMERGENCY_STOPPED"
    levels = [s.level for a in diagnostics for s in a.status if "aborted: emergency stop" in s.message]
    assert client.spin_until(lambda: levels or [s.level for a in diagnostics for s in a.status
                                                if "aborted: emergency stop" in s.message], 5)
    assert all(s.level == b"\x02" for a in diagnostics for s in a.status if "aborted: emergency stop" in s.message)
    assert start().outcome()[0] == "ESTOP_LATCHED"
    status.publish(emulator_status("ramping_out", t0 + 2))
    assert start().outcome()[0] == "UNITS_NOT_AT_REST"
    status.publish(emulator_status("stopped", t0 + 3, reason="emergency stop"))
    goal = start()
    assert goal.plan() is not None, goal.outcome()
    goal.cancel()
    assert goal.outcome(10)[0] == "CANCELED"
    # the robot's own safety ramp (a unit's travel protection) ends the goal with that ramp's outcome
    goal = start(duration_s=0.0)
    t0 = plan_t0(goal.plan())
    status.publish(emulator_status("stopped", t0 + 0.1, event_seq=3, level=1, event="safety_ramp",
                                   reason="ramp to zero: vib_2 read 140 um", event_outcome="UNIT_TRAVEL_STOPPED"))
    assert goal.outcome(5)[0] == "UNIT_TRAVEL_STOPPED"
    # a robot on another clock (its status says 100 s: a sim clock) and a planner on the wall clock
    status.publish(emulator_status("idle", 100.0))
    name, message = start().outcome()
    assert name == "CLOCK_MISMATCH" and "use_sim_time:=true" in message, (name, message)
    assert proc.alive()


def test_a_goal_on_sim_time(robot, ros_domain, tmp_path):
    from rosgraph_msgs.msg import Clock

    args = ["--ros-args", "-p", "use_sim_time:=true"]
    with node_under_test("planner_sim", "stewart_vibration.nodes.vibration_planner_node", ros_domain, tmp_path,
                         args) as (proc, client):
        windows = client.subscribe("vibration/joint_trajectory", JointTrajectory)
        clock = client.publisher("/clock", Clock)
        poses = client.publisher("platform/pose_estimate", PoseStamped)
        sim = 100.0
        heartbeat = idle_robot_heartbeat(client, clock=lambda: sim)
        assert client.wait_for_subscribers("platform/pose_estimate"), proc.log_text()
        goal = start_with_pose(client, poses, paper_pose(robot), waiting_for=("NOT_READY",), duration_s=1.0,
                               ramp_s=0.1)
        assert goal.outcome()[0] == "CLOCK_NOT_RUNNING", goal.outcome()

        goal = start_with_pose(client, poses, paper_pose(robot), duration_s=1.0, ramp_s=0.1,
                               publish_also=lambda: clock.publish(Clock(clock=Time(sec=100))))
        assert goal.plan() is not None, goal.outcome()
        status = status_publisher(client)
        while sim < 102.5:  # 2.5 s of sim time at ~4x wall speed
            sim += 0.01
            # from t0 = 101 s the robot says its units vibrate, repeated as the emulator repeats it; its idle
            # heartbeat ends (a later "idle" would replace "running" in the topic's history of one undelivered)
            if 101.0 <= sim < 102.1 and round(sim * 100) % 20 == 0:
                heartbeat.cancel()
                status.publish(emulator_status("running", 101.0, now=sim))
            ns = round(sim * 1e9)
            clock.publish(Clock(clock=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)))
            client.spin_for(0.0025)
        client.spin_for(0.2)
        stamp = windows[0].header.stamp
        assert abs(stamp.sec + stamp.nanosec * 1e-9 - 101.0) < 1e-6  # t0 = sim now + start_lead_s (1 s)
        assert len(windows) == 1  # a finite vibration that fits the look-ahead limit is sent whole
        t, pos, vel, _ = samples_of(windows[0])
        assert t[0] == 0.0 and abs(t[-1] - 1.0) < 1e-9 and len(t) == 1001
        assert np.abs(pos[[0, -1]]).max() < 1e-15 and np.abs(vel[[0, -1]]).max() < 1e-12  # rest to rest
        name, _ = goal.outcome(10)
        assert name == "SUCCEEDED" and goal.status() == 4
        result = goal.result()
        # the whole vibration ran: 1 s with 0.1 s quintic ramps (each half its length at full amplitude)
        assert abs(result.active_s - 1.0) < 0.02 and abs(result.cycles_delivered - F * 0.9) < 0.02 * F


def test_a_goal_beside_a_real_emulator_refuses_an_inactive_robot_and_the_wall_clock(robot, ros_domain, tmp_path):
    """With the real hardware emulator deactivated (lifecycle), a vibrate goal ends ROBOT_INACTIVE saying to
    activate it -- before anything is streamed; active again, the same goal plans. A planner started on the wall
    clock beside it ends CLOCK_MISMATCH naming use_sim_time -- never SUCCEEDED: before the emulator's status
    reaches it, it refuses NOT_READY (it cannot tell the robot's clock), and a goal whose units the robot never
    reported moving does not succeed."""
    from lifecycle_msgs.msg import Transition

    emulator_args = ["--ros-args", "-p", "autostart:=false"]
    planner = "stewart_vibration.nodes.vibration_planner_node"
    with node_under_test("emulator", "stewart_vibration.nodes.hardware_emulator_node", ros_domain, tmp_path,
                         emulator_args) as (emulator, robot_client):
        for transition in (Transition.TRANSITION_CONFIGURE, Transition.TRANSITION_ACTIVATE,
                           Transition.TRANSITION_DEACTIVATE):
            assert robot_client.transition("hardware_emulator", transition), emulator.log_text()
        with node_under_test("planner", planner, ros_domain, tmp_path,
                             ["--ros-args", "-p", "use_sim_time:=true"]) as (proc, client):
            windows = client.subscribe("vibration/joint_trajectory", JointTrajectory)
            poses = client.publisher("platform/pose_estimate", PoseStamped)
            assert client.wait_for_subscribers("platform/pose_estimate"), proc.log_text()
            name, message = start_with_pose(client, poses, paper_pose(robot), duration_s=1.0).outcome()
            assert name == "ROBOT_INACTIVE" and "activate" in message, (name, message)
            assert not windows
            assert robot_client.transition("hardware_emulator", Transition.TRANSITION_ACTIVATE)
            goal = start_with_pose(client, poses, paper_pose(robot),
                                   waiting_for=PLANNER_NOT_READY + ("ROBOT_INACTIVE",), duration_s=1.0)
            assert goal.plan() is not None, goal.outcome()
            goal.cancel()
            assert goal.outcome(10)[0] == "CANCELED"
        with node_under_test("wall_planner", planner, ros_domain, tmp_path) as (_, client):  # no use_sim_time
            poses = client.publisher("platform/pose_estimate", PoseStamped)
            assert client.wait_for_subscribers("platform/pose_estimate")
            name, message = start_with_pose(client, poses, paper_pose(robot), duration_s=1.0,
                                            waiting_for=PLANNER_NOT_READY + ("UNITS_NOT_AT_REST",)).outcome()
            assert name == "CLOCK_MISMATCH" and "use_sim_time:=true" in message, (name, message)
        assert emulator.alive()


@contextmanager
def planner_vibrating(robot, ros_domain, tmp_path, name: str, args, **vibration):
    """A planner started with ``args`` on the wall clock beside an idle robot's status, vibrating at the
    paper's pose: (process, client, windows received, pose publisher, the goal that began)."""
    with node_under_test(name, "stewart_vibration.nodes.vibration_planner_node", ros_domain, tmp_path,
                         ["--ros-args", *args]) as (proc, client):
        windows = client.subscribe("vibration/joint_trajectory", JointTrajectory)
        poses = client.publisher("platform/pose_estimate", PoseStamped)
        client.heartbeat = idle_robot_heartbeat(client)  # SyntheticImu.at_start ends it: the units then run
        assert client.wait_for_subscribers("platform/pose_estimate"), proc.log_text()
        assert client.wait_matched("vibration/joint_trajectory"), proc.log_text()  # a short vibration is one window
        goal = start_with_pose(client, poses, paper_pose(robot), **vibration)
        assert goal.plan() is not None, goal.outcome()
        yield proc, client, windows, poses, goal


@pytest.mark.parametrize("closed_loop", [False, True])
def test_a_goal_cancelled_before_its_t0_never_moves_a_unit(robot, ros_domain, tmp_path, closed_loop):
    """A 60 s vibration cancelled while it waits for its t0 (start_lead_s 2 s; the first window, ramp-in and
    all, already sent): the goal ends CANCELED, and the windows the units received, replayed into the
    emulator's own buffer in their order, command rest from before t0 to long after it -- with the feed-forward
    of an identification and its closed loop too."""
    from test_compensation import linear_identification

    from stewart_vibration.emulation.strut_trajectory import build_trajectory
    from stewart_vibration.emulation.vibration_buffer import VibrationBuffer
    from stewart_vibration.vibration.unit_identification import save_identification

    args = ["-p", "start_lead_s:=2.0"]
    if closed_loop:
        path = save_identification(tmp_path / "units.yaml", linear_identification(robot, paper_pose(robot)))
        args += ["-p", "closed_loop:=true", "-p", f"identification_file:={path}"]
    with planner_vibrating(robot, ros_domain, tmp_path, f"planner_early_{closed_loop}", args,
                           duration_s=60.0) as (proc, client, windows, _, goal):
        t0 = plan_t0(goal.plan())
        assert client.spin_until(lambda: len(windows) >= 1, 5), proc.log_text()
        cancelled_at = time.time()
        assert cancelled_at < t0 - 0.5, (cancelled_at, t0)  # well before it begins
        goal.cancel()
        name, message = goal.outcome(10)
        assert name == "CANCELED", (name, message, proc.log_text()[-2000:])
        client.spin_for(0.5)
        assert "stopping before the vibration began" in proc.log_text()
    def received(window):  # as the emulator takes it: validated and ordered by the joint names
        return build_trajectory(list(window.joint_names), VIB, stamp_seconds(window.header.stamp),
                                *samples_of(window))

    buffer = VibrationBuffer(robot.vibration_unit)
    first, *rest = windows
    buffer.add(received(first), t0 - 1.5)
    for window in rest:
        buffer.add(received(window), cancelled_at)
    assert np.abs(samples_of(first)[1]).max() > 10e-6  # the first window did hold the vibration
    t = t0 + np.arange(-0.5, 3.0, 0.001)
    assert np.abs(buffer.sample(t)[0]).max() == 0.0


def test_a_goal_with_an_identification_streams_its_feedforward(robot, ros_domain, tmp_path):
    """identification_file: the windows carry the identification's feed-forward demands (a linear robot's, so
    the reference is closed form); a file that does not load is refused with the reason; '' goes back to the
    decomposition's legs, and the log says which."""
    from test_compensation import linear_identification

    from stewart_vibration.analysis.fits import fit_sinusoid
    from stewart_vibration.vibration.compensation import compensated_demands
    from stewart_vibration.vibration.decompose import decompose_vibration
    from stewart_vibration.vibration.unit_identification import save_identification

    pose = paper_pose(robot)
    path = save_identification(tmp_path / "units.yaml", linear_identification(robot, pose))
    (tmp_path / "broken.yaml").write_text("kind: something else\n")
    with planner_vibrating(robot, ros_domain, tmp_path, "planner_ff", ["-p", f"identification_file:={path}"],
                           duration_s=2.0, ramp_s=0.2) as (proc, client, windows, _, goal):
        assert client.spin_until(lambda: len(windows) >= 1, 5), proc.log_text()
        t, pos, *_ = samples_of(windows[0])
        steady = (t > 0.3) & (t < 1.7)
        plan = decompose_vibration(robot, pose, [0.0, 0.0, 1.0], acceleration_g=G_ACC, frequency=F)
        demands, how = compensated_demands(linear_identification(robot, pose), plan)
        np.testing.assert_allclose(fit_sinusoid(t[steady], pos[steady], F).complex_amplitude, demands,
                                   atol=1e-6 * plan.amplitude)
        assert client.spin_until(lambda: "identified feed-forward" in proc.log_text(), 5), proc.log_text()
        goal.cancel()
        (refused,) = set_params(client, identification_file=str(tmp_path / "broken.yaml"))
        assert not refused.successful and "identification_file" in refused.reason and "not a vibration " \
            "identification file" in refused.reason
        assert set_params(client, identification_file="")[0].successful
        assert proc.alive()


class SyntheticImu:
    """The platform IMU (at the platform origin, platform axes) of a platform moving ``motion(t)`` (6,) complex
    [dp; dphi] (base frame) under the vibration's envelope; published as the emulator does, stamped with the
    wall clock (the planner here runs on it)."""

    def __init__(self, client, rotation, gravity, t0, ramp_s):
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import Imu

        self.pub = client.node.create_publisher(Imu, "platform/imu", QoSProfile(
            depth=500, reliability=ReliabilityPolicy.RELIABLE))
        self.client, self.rotation, self.gravity, self.t0, self.ramp_s = client, rotation, gravity, t0, ramp_s
        self.next_status = np.inf  # publish_running repeats the robot's status from then on

    @classmethod
    def at_start(cls, robot, pose, proc, client, poses, t0: float, ramp_s: float = 0.2) -> SyntheticImu:
        """The IMU of a vibration that starts at ``t0`` (wall s) at ``pose``, once the planner listens to it;
        the pose estimate is published until t0, and then the emulator's word that the units run."""
        imu = cls(client, rotation_from_rpy(pose[3:]), robot.gravity, t0, ramp_s)
        assert client.wait_for_subscribers("platform/imu", timeout=10), proc.log_text()
        while time.time() < t0:
            poses.publish(pose_msg(pose))
            client.spin_for(0.01)
        # the robot's status says the units run from t0 on, as the emulator's does: its idle heartbeat ends (a
        # later "idle" would replace "running" in the status topic's history of one before it was delivered)
        heartbeat = getattr(client, "heartbeat", None)
        if heartbeat is not None:
            heartbeat.cancel()
        imu.publish_running()
        return imu

    def publish_running(self) -> None:
        """The emulator's vibration/status: running since t0, sent now (repeated as the emulator repeats it)."""
        status_publisher(self.client).publish(emulator_status("running", self.t0, now=time.time()))
        self.next_status = time.time() + 0.5

    def run(self, motion, seconds: float, until=lambda: False) -> None:
        from sensor_msgs.msg import Imu

        from stewart_vibration.vibration.waveform import envelope

        w = 2 * np.pi * F
        end = time.time() + seconds
        while time.time() < end and not until():
            stamp = time.time()
            if stamp >= self.next_status:
                self.publish_running()
            t = stamp - self.t0
            e = float(envelope(np.array([t]), None, self.ramp_s)[0][0])
            y = motion(t) * e * np.exp(1j * w * t)
            accel = self.rotation.T @ (np.imag(-w * w * y[:3]) - self.gravity)
            rate = self.rotation.T @ np.imag(1j * w * y[3:])
            msg = Imu()
            msg.header.stamp.sec, msg.header.stamp.nanosec = int(stamp), int((stamp % 1) * 1e9)
            msg.header.frame_id = "platform"
            msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = map(float, accel)
            msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = map(float, rate)
            self.pub.publish(msg)
            self.client.spin_for(0.002)


@pytest.mark.parametrize("case", ["delivered", "too_loud", "imu_silent"])
def test_the_closed_loop_over_dds(robot, ros_domain, tmp_path, case):
    """closed_loop:=true with the platform IMU on platform/imu: a platform moving as planned keeps the demands
    and the goal SUCCEEDED; 1.5x the target (+3.5 dB) or an IMU that goes silent ends it DELIVERY_LIMIT with
    the reason, after a ramp-out window."""
    from test_compensation import linear_identification

    from stewart_vibration.vibration.compensation import target_motion
    from stewart_vibration.vibration.decompose import decompose_vibration
    from stewart_vibration.vibration.unit_identification import save_identification

    pose = paper_pose(robot)
    path = save_identification(tmp_path / "units.yaml", linear_identification(robot, pose))
    args = ["-p", "closed_loop:=true", "-p", "imu_average_s:=0.0", "-p", f"identification_file:={path}"]
    if case != "imu_silent":  # this test's IMU is Python on a shared machine: give it the slack of a slow link
        args += ["-p", "imu_silence_s:=0.5"]
    with planner_vibrating(robot, ros_domain, tmp_path, "planner_loop", args, duration_s=3.0,
                           ramp_s=0.2) as (proc, client, windows, poses, goal):
        t0 = plan_t0(goal.plan())
        plan = decompose_vibration(robot, pose, [0.0, 0.0, 1.0], acceleration_g=G_ACC, frequency=F)
        target = target_motion(plan)
        imu = SyntheticImu.at_start(robot, pose, proc, client, poses, t0)
        if case == "delivered":
            imu.run(lambda t: target, 3.3, until=goal.result_future.done)
            name, message = goal.outcome(5)
            assert name == "SUCCEEDED", (name, message, proc.log_text()[-2000:])
            # corrected all along its steady part, also once the stream's final window was out (from 1 s on)
            corrections = goal.result().loop_corrections
            assert corrections >= 3 and goal.feedback[-1].feedback.loop_corrections <= corrections, corrections
        elif case == "too_loud":
            imu.run(lambda t: 1.5 * target, 2.0, until=goal.result_future.done)
            name, message = goal.outcome(5)
            assert name == "DELIVERY_LIMIT" and "+3.5 dB" in message, (name, message, proc.log_text()[-3000:])
        else:
            imu.run(lambda t: target, 0.8)
            name, message = goal.outcome(5)
            assert name == "DELIVERY_LIMIT" and "IMU went silent" in message, (name, message)
        if case != "delivered":
            t, pos, *_ = samples_of(windows[-1])
            assert np.abs(pos[-1]).max() < 1e-15 and t[-1] - t[0] <= 0.2 + 2 * DT  # a ramp-out ended it
        assert "closed loop on the platform IMU" in proc.log_text()
        assert proc.alive()


def streamed_demand(windows, t0: float, t: float):
    """The six complex leg demands (m, against sin(2 pi F (t - t0))) of the newest window in ``windows`` whose
    first point is due by ``t`` (wall s), fitted over its second half (after a correction's blend-in); None
    before one."""
    from stewart_vibration.analysis.fits import fit_sinusoid

    def start(window):  # a window is stamped with the vibration's t0; its first point is where it starts
        return stamp_seconds(window.header.stamp) + seconds(window.points[0].time_from_start)

    started = [w for w in windows if start(w) <= t]
    if not started:
        return None
    window = started[-1]
    if id(window) not in _FITTED:  # once per window: the IMU calls this per sample, and must keep its rate
        times, pos, *_ = samples_of(window)
        times = times + stamp_seconds(window.header.stamp) - t0
        half = times >= times[len(times) // 2]
        _FITTED[id(window)] = (window, fit_sinusoid(times[half], pos[half], F).complex_amplitude)
    return _FITTED[id(window)][1]


_FITTED: dict = {}  # id(window) -> (window, its demands); the window is kept so its id is not reused


def test_a_unit_that_loses_most_of_its_gain_mid_vibration_ends_the_goal_with_the_reason(robot, ros_domain, tmp_path):
    """closed_loop:=true over DDS, the platform IMU that of a linear robot whose unit 1 loses 70 % of its gain 1 s
    into the vibration (it moves as the identification says until then): the loop asks unit 1 for more than
    its travel allows (or, judged before that, the direction leaves its limit), and the goal ends DELIVERY_LIMIT
    naming unit 1 and the shortfall it delivers, after a ramp-out window -- never a demand
    beyond the unit's limit."""
    from test_compensation import linear_identification

    from stewart_vibration.vibration.unit_identification import save_identification

    pose = paper_pose(robot)
    ident = linear_identification(robot, pose)
    path = save_identification(tmp_path / "units.yaml", ident)
    args = ["-p", "closed_loop:=true", "-p", "imu_average_s:=0.0", "-p", f"identification_file:={path}",
            "-p", "imu_silence_s:=0.5"]  # this test's IMU is Python on a shared machine
    healthy = ident.platform_response_at(F)
    # 0.3: the loop's fixed point, 1 / 0.3 of unit 1's demand, is far beyond its travel (at half the gain, just
    # beyond it: a loop short of corrections could end the vibration before reaching it)
    failed = healthy @ np.diag([0.3, 1, 1, 1, 1, 1])
    with planner_vibrating(robot, ros_domain, tmp_path, "planner_unit", args, duration_s=6.0,
                           ramp_s=0.2) as (proc, client, windows, poses, goal):
        t0 = plan_t0(goal.plan())
        imu = SyntheticImu.at_start(robot, pose, proc, client, poses, t0)

        def motion(t):
            demand = streamed_demand(windows, t0, t0 + t)
            return np.zeros(6, complex) if demand is None else (failed if t > 1.0 else healthy) @ demand

        imu.run(motion, 6.0, until=goal.result_future.done)
        name, message = goal.outcome(5)
        # whichever limit trips first (the demand limit, or the direction once judged), the reason names unit 1
        # first among the units that deliver off their demand, and short of it (this IMU's plant: 0.3; read
        # through a Python IMU on a shared machine, whose samples lag the windows, so not to the digit)
        worst = re.search(r"; unit (\d) delivers (\d+\.\d\d) x", message)
        result = goal.result()
        assert name == "DELIVERY_LIMIT" and worst and worst.group(1) == "1" and float(worst.group(2)) < 0.75, \
            (name, message, result.loop_corrections, result.active_s, imu.sent, proc.log_text()[-3000:])
        t, pos, *_ = samples_of(windows[-1])
        assert np.abs(pos[-1]).max() < 1e-15 and t[-1] - t[0] <= 0.2 + 2 * DT  # a ramp-out ended it
        limit = 0.9 * robot.vibration_unit.amplitude_max / np.abs(ident.unit_response_at(F))
        for window in windows:  # no unit was ever sent beyond what its identified response allows
            assert (np.abs(samples_of(window)[1]) <= limit * (1 + 1e-6)).all()
        assert proc.alive()


IDENTIFY = "vibration_planner/identify_vibration_units"


@contextmanager
def beside_the_emulator(robot, ros_domain, tmp_path):
    """(planner process, client, publish_home()) with the hardware emulator (ideal plant) and a planner on its
    sim time, the identification action ready."""
    from stewart_vibration_interfaces.action import IdentifyVibrationUnits

    planner = "stewart_vibration.nodes.vibration_planner_node"
    with node_under_test("emulator", "stewart_vibration.nodes.hardware_emulator_node", ros_domain, tmp_path):
        with node_under_test("planner", planner, ros_domain, tmp_path,
                             ["--ros-args", "-p", "use_sim_time:=true"]) as (proc, client):
            poses = client.publisher("platform/pose_estimate", PoseStamped)
            home = pose_msg(robot.home_pose)
            assert client.wait_for_subscribers("platform/pose_estimate"), proc.log_text()
            assert client.action_server_ready(IdentifyVibrationUnits, IDENTIFY, 20)
            yield proc, client, lambda: poses.publish(home)


def identification_started(client, publish_home, goal_msg):
    """The identification goal once the planner took it to run (sent again while it had no pose estimate or
    emulator status yet)."""
    deadline = time.monotonic() + 30
    while True:
        publish_home()
        client.spin_for(0.3)
        goal = client.send_goal(IDENTIFY, goal_msg)
        if not client.spin_until(goal.result_future.done, 0.5) or time.monotonic() > deadline:
            return goal
        assert goal.result().outcome.code in (200, 204), goal.result().outcome  # NOT_READY, CLOCK_NOT_RUNNING


def test_the_identification_action_beside_the_real_emulator(robot, ros_domain, tmp_path):
    """identify_vibration_units with the hardware emulator (ideal plant, sim time): a malformed goal refused
    with its reason before anything moves; feedback per step, a file whose unit responses are 1 (ideal units)
    and whose platform responses are the kinematic map (a common sub-step delay aside), which the planner then
    loads; a second goal while one runs is BUSY."""
    from stewart_vibration.kinematics.jacobian import jacobian
    from stewart_vibration.vibration.unit_identification import load_identification
    from stewart_vibration_interfaces.action import IdentifyVibrationUnits

    with beside_the_emulator(robot, ros_domain, tmp_path) as (proc, client, publish_home):
        path = tmp_path / "units.yaml"
        for bad, why in ((dict(amplitude_m=1e-3), "amplitude_m"), (dict(frequencies_hz=[40.0, 35.0]), "increasing"),
                         (dict(output_path=str(tmp_path / "no" / "u.yaml")), "writable")):
            refused = client.send_goal(IDENTIFY, IdentifyVibrationUnits.Goal(**bad)).result()
            assert refused.outcome.code == 100 and why in refused.outcome.message, refused  # INVALID_ARGUMENT
            assert refused.path == "" and not (tmp_path / "no").exists()
        goal_msg = IdentifyVibrationUnits.Goal(frequencies_hz=[35.0], amplitude_m=2e-5, output_path=str(path))
        goal = identification_started(client, publish_home, goal_msg)
        busy = client.send_goal(IDENTIFY, goal_msg).result()
        assert busy.outcome.code == 201 and "identified" in busy.outcome.message  # BUSY
        while not goal.result_future.done():
            publish_home()
            client.spin_for(0.05)
        result = goal.result()
        assert result.outcome.code == 1, (result.outcome, list(result.problems), proc.log_text()[-2000:])
        assert result.path == str(path) and abs(result.duration_s - 6 * 0.87) < 0.3
        steps = {(f.feedback.step, f.feedback.unit) for f in goal.feedback}
        assert {(k, k) for k in range(1, 7)} <= steps
        ident = load_identification(path)
        np.testing.assert_allclose(ident.unit_response[0], 1.0, atol=0.005)
        kinematic = np.linalg.inv(jacobian(robot, robot.home_pose))
        ratio = ident.platform_response[0] / kinematic
        big = np.abs(kinematic) > 0.2 * np.abs(kinematic).max(axis=1, keepdims=True)
        np.testing.assert_allclose(np.abs(ratio[big]), 1.0, atol=0.02)
        assert np.degrees(np.abs(np.angle(ratio[big]))).max() < 5.0  # 35 Hz x under 0.5 ms
        assert client.spin_until(lambda: "identification: " + str(path) in proc.log_text(), 5)


@pytest.mark.parametrize("how", ["cancel", "emergency_stop"])
def test_an_identification_stopped_midway_writes_nothing(robot, ros_domain, tmp_path, how):
    """A cancel (CANCELED) or the robot's e-stop (EMERGENCY_STOPPED) during the run ends it with that
    outcome, no file, and the planner idle again (a vibrate goal is no longer BUSY)."""
    from std_srvs.srv import Trigger

    from stewart_vibration_interfaces.action import IdentifyVibrationUnits

    with beside_the_emulator(robot, ros_domain, tmp_path) as (proc, client, publish_home):
        path = tmp_path / "units.yaml"
        goal = identification_started(client, publish_home, IdentifyVibrationUnits.Goal(frequencies_hz=[30.0, 40.0],
                                                                                        output_path=str(path)))
        assert client.spin_until(lambda: any(f.feedback.step >= 2 for f in goal.feedback), 20), proc.log_text()
        if how == "cancel":
            goal.cancel()
        else:
            assert client.call(Trigger, "hardware_emulator/emergency_stop", Trigger.Request()).success
        result = goal.result(timeout=20)
        expected = {"cancel": 300, "emergency_stop": 303}[how]  # CANCELED, EMERGENCY_STOPPED
        assert result.outcome.code == expected and "nothing written" in result.outcome.message, result.outcome
        assert result.path == "" and not path.exists()
        assert goal.status() == (5 if how == "cancel" else 6)  # canceled / aborted
        publish_home()
        after = client.vibrate(duration_s=0.5).result()
        assert after.outcome.code != 201, after.outcome  # not BUSY: the run is over
