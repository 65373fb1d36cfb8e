"""Soft tissue in the loop with the real nodes over DDS on sim time: hardware_emulator applying
config/tissue.yaml, kinematics (tissue-aware checks, force guard), leg_force_estimator, vibration_planner.

- the estimator's external wrench matches the wrench the emulator applies (ground_truth/tissue_wrench) during
  moves and holds (RMS error <= 2 % of the peak applied force and moment) and during a 35 Hz / 0.3 g
  vibration (RMS force error <= 1 N);
- the force guard stops a move that would exceed guard_force_n with the peak estimated force <= limit +
  10 %, every strut within its velocity and acceleration limits, ends the goal GUARD_STOPPED, reports ERROR,
  refuses goals further in that direction (GUARD_BLOCKED) and accepts them again after kinematics/reset_guard;
- a path that would overload a strut is refused by plan_path, naming the leg and the waypoint.

Moves are goals of kinematics' move_to_pose action; refusals are checked by their outcome codes.
"""

from __future__ import annotations

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped, WrenchStamped
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_client import RosTestClient
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from stewart_vibration.messages.status_values import guard_status_from_cdr
from stewart_vibration.nodes.message_conversions import pose_from_msg
from stewart_vibration.nodes.move_messages import MOVE_ACTION
from stewart_vibration.paper import paper_pose
from stewart_vibration.runtime.processes import ros_environment, start_python_module
from stewart_vibration.runtime.sim_clock import HeldFor
from stewart_vibration_interfaces.action import MoveToPose
from stewart_vibration_interfaces.msg import ForceGuardStatus, LegTrajectoryStatus, Outcome

pytestmark = pytest.mark.integration
SIM = ["--ros-args", "-p", "use_sim_time:=true"]
TISSUE = ["-p", "tissue_config:=tissue.yaml"]
# the emulator waits for late estimates: on a machine whose two cores the suite and this test's 500 Hz readers
# fill, real time left the estimates seconds behind and the guard paused every move (a stopped estimator is
# still run past after the emulator's longest wait, so the blind pause is tested as before)
LOCKSTEP = ["-p", "lockstep:=true"]
STATUS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


@pytest.fixture(scope="module")
def suite(tmp_path_factory, module_ros_domain):
    log_dir = tmp_path_factory.mktemp("tissue_logs")
    env = ros_environment(module_ros_domain)
    procs = []
    client = None
    try:
        procs = [
            start_python_module("emulator", "stewart_vibration.nodes.hardware_emulator_node",
                                ["--ros-args", "-p", "real_time_factor:=1"] + LOCKSTEP + TISSUE, env, log_dir),
            start_python_module("kinematics", "stewart_vibration.nodes.kinematics_node", SIM + TISSUE, env, log_dir),
            start_python_module("estimator", "stewart_vibration.nodes.leg_force_estimator_node", SIM, env, log_dir),
            start_python_module("planner", "stewart_vibration.nodes.vibration_planner_node", SIM, env, log_dir),
        ]
        client = RosTestClient()
        rec = {
            "clock": client.subscribe("/clock", Clock, depth=10),
            "applied": client.subscribe("ground_truth/tissue_wrench", WrenchStamped, depth=5000),
            "estimate": client.subscribe("platform/external_wrench_estimate", WrenchStamped, depth=5000),
            "states": client.subscribe("legs/joint_states", JointState, depth=5000),
            "truth": client.subscribe("ground_truth/platform_pose", PoseStamped, depth=100),
            "diagnostics": client.subscribe("/diagnostics", DiagnosticArray),
            "trajectory_status": client.subscribe("legs/trajectory_status", LegTrajectoryStatus),
            "guard": [],
        }
        client.node.create_subscription(ForceGuardStatus, "kinematics/guard_status", rec["guard"].append, STATUS_QOS,
                                        raw=True)
        poses = []
        ready = client.node.create_subscription(PoseStamped, "platform/pose_estimate", poses.append, 1)
        assert client.spin_until(lambda: rec["clock"] and rec["estimate"] and rec["applied"] and rec["guard"] and
                                 poses, 90), \
            logs(procs)  # /clock too: the tests read the sim time from it (CI: IndexError when it came last)
        assert client.action_server_ready(MoveToPose, MOVE_ACTION, 60), logs(procs)
        client.node.destroy_subscription(ready)
        yield procs, client, rec
    finally:
        if client is not None:
            client.close()
        for proc in procs:
            proc.stop()


GUARD_PARAMETERS = ("guard_force_n", "guard_max_estimate_age_s", "speed_scale")


@pytest.fixture(autouse=True)
def armed_guard(suite):
    """Every test starts with the guard reset and kinematics' guard parameters at the suite's start values
    (the tests share one suite: a test that failed with the guard tripped must not fail the next ones)."""
    procs, client, rec = suite
    request = GetParameters.Request(names=list(GUARD_PARAMETERS))
    start_values = [v.double_value for v in client.call(GetParameters, "kinematics/get_parameters", request).values]
    yield
    set_params(client, "kinematics", **dict(zip(GUARD_PARAMETERS, start_values)))
    assert client.call(Trigger, "kinematics/reset_guard", Trigger.Request()).success
    assert client.spin_until(lambda: guard_values(rec["guard"][-1])["state"] == "armed", 5)


def logs(procs):
    return "\n".join(f"--- {p.name}\n{p.log_text()[-3000:]}" for p in procs)


def stamp_of(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def sim_now(rec) -> float:
    c = rec["clock"][-1].clock
    return c.sec + c.nanosec * 1e-9


def wrench_series(messages) -> dict:
    return {(m.header.stamp.sec, m.header.stamp.nanosec): [m.wrench.force.x, m.wrench.force.y, m.wrench.force.z,
                                                           m.wrench.torque.x, m.wrench.torque.y, m.wrench.torque.z]
            for m in messages}


def paired(rec, t0: float, t1: float):
    """(stamps [n], applied [n, 6], estimated [n, 6]) of the states stamped in [t0, t1]."""
    applied, estimate = wrench_series(rec["applied"]), wrench_series(rec["estimate"])
    keys = sorted(k for k in applied if k in estimate and t0 <= k[0] + k[1] * 1e-9 <= t1)
    stamps = np.array([k[0] + k[1] * 1e-9 for k in keys])
    return stamps, np.array([applied[k] for k in keys]), np.array([estimate[k] for k in keys])


def move_to(client, rec, pose, timeout=60.0, tolerance=10e-6) -> float:
    """A move goal to ``pose``: it must end SUCCEEDED; then wait until the ground truth has held the pose for
    0.5 s of sim time (as the runner does: a goal sent while the last move still ends is refused BUSY);
    returns the sim time it settled."""
    goal = client.move(pose)
    name, message = goal.outcome(timeout)
    assert (name, goal.status()) == ("SUCCEEDED", 4), (np.round(pose, 6).tolist(), name, message)
    held = HeldFor(0.5)

    def settled():
        if not rec["truth"]:
            return False
        err = pose_from_msg(rec["truth"][-1].pose) - pose
        there = np.abs(err[:3]).max() < tolerance and np.degrees(np.abs(err[3:]).max()) < 0.01
        return held.update(bool(there), stamp_of(rec["truth"][-1]))

    assert client.spin_until(settled, timeout), f"did not settle at {np.round(pose, 6).tolist()}"
    return sim_now(rec)


def set_params(client, node: str, **values):
    request = SetParameters.Request()
    for name, value in values.items():
        if isinstance(value, list):
            v = ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=[float(x) for x in value])
        elif isinstance(value, str):
            v = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value)
        else:
            v = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=float(value))
        request.parameters.append(ParameterMsg(name=name, value=v))
    results = client.call(SetParameters, f"{node}/set_parameters", request).results
    assert all(r.successful for r in results), [r.reason for r in results]


def guard_values(data: bytes) -> dict:
    """A raw kinematics/guard_status as plain values (motion.guard_status.GuardStatus.record)."""
    return guard_status_from_cdr(data).record()


def test_estimate_matches_the_applied_tissue_wrench(robot, suite):
    procs, client, rec = suite
    begin = sim_now(rec)
    # the main scenario against the tissue: reduce to the paper's pose, hold, vibrate 35 Hz / 0.3 g along the
    # tibia axis, hold, return home
    move_to(client, rec, paper_pose(robot))
    client.spin_for(0.5)
    goal = client.vibrate(direction=[0.0, 0.0, 1.0], frame="platform", acceleration_g=0.3, frequency_hz=35.0,
                          duration_s=2.0, ramp_s=0.2)
    plan = goal.plan()
    assert plan is not None, goal.outcome()
    t0 = plan.t0.sec + plan.t0.nanosec * 1e-9
    assert client.spin_until(lambda: sim_now(rec) > t0 + 2.5, 60), logs(procs)
    move_to(client, rec, robot.home_pose)
    end = sim_now(rec) - 0.1
    assert client.spin_until(lambda: len(rec["estimate"]) and stamp_of(rec["estimate"][-1]) >= end, 10)

    stamps, applied, estimate = paired(rec, begin, end)
    assert stamps.size > 0.9 * (end - begin) * 500, (stamps.size, end - begin)  # every state got both
    vib = (stamps >= t0) & (stamps <= t0 + 2.0)
    quiet = ~vib
    err = estimate - applied
    peak_f = np.linalg.norm(applied[:, :3], axis=1).max()
    peak_m = np.linalg.norm(applied[:, 3:], axis=1).max()
    rms_f = np.sqrt((np.linalg.norm(err[quiet, :3], axis=1) ** 2).mean())
    rms_m = np.sqrt((np.linalg.norm(err[quiet, 3:], axis=1) ** 2).mean())
    rms_vib_f = np.sqrt((np.linalg.norm(err[vib, :3], axis=1) ** 2).mean())
    rms_vib_m = np.sqrt((np.linalg.norm(err[vib, 3:], axis=1) ** 2).mean())
    print(f"peak applied {peak_f:.1f} N, {peak_m:.2f} N m; moves+holds RMS error {rms_f:.3f} N "
          f"({rms_f / peak_f * 100:.3f} %), {rms_m:.4f} N m ({rms_m / peak_m * 100:.3f} %); vibration RMS error "
          f"{rms_vib_f:.3f} N, {rms_vib_m:.4f} N m over {vib.sum()} states")
    assert peak_f > 100 and peak_m > 5  # the tissue really loads the platform
    assert rms_f <= 0.02 * peak_f and rms_m <= 0.02 * peak_m
    assert vib.sum() > 800 and rms_vib_f <= 1.0
    # the wrench changes during the vibration (tissue spring + damper at 35 Hz): the estimate follows it
    assert np.ptp(applied[vib, 2]) > 2.0
    assert all(p.alive() for p in procs), logs(procs)


def test_guard_stops_a_move_that_would_exceed_the_limit(robot, suite):
    procs, client, rec = suite
    limit = 150.0
    # 4 mm/s: the guard's look-ahead (command delay + stop) covers little progress, so it trips near the limit
    # also when a busy machine widens its receipt window (CI at 10 mm/s: tripped at 58 N, stopped at 104 N)
    set_params(client, "kinematics", guard_force_n=limit, speed_scale=0.2)
    move_to(client, rec, robot.home_pose)
    guard_before = len(rec["guard"])
    begin = sim_now(rec)
    target = robot.home_pose + np.array([0.0, 0.0, 0.010, 0.0, 0.0, 0.0])  # 10 mm distraction: ~410 N
    statuses_before = len(rec["trajectory_status"])
    move = client.move(target)
    # under load the guard may first pause the move while the estimates lag (an "estimates" trip that resumes by
    # itself: run 3 of a series beside a CPU hog); the force trip is the one this test is about

    def force_trips():
        return [guard_values(m) for m in rec["guard"][guard_before:]
                if guard_values(m)["state"] == "tripped" and guard_values(m)["trip_limit"] == "force"]

    assert client.spin_until(force_trips, 60), logs(procs)
    trip = force_trips()[0]
    assert trip["state"] == "tripped"
    # the stop completes and the platform holds short of the target
    assert client.spin_until(lambda: sim_now(rec) > trip["trip_time_s"] + 1.5, 30)
    end = sim_now(rec)
    stamps, applied, estimate = paired(rec, begin, end - 0.1)
    peak_est = np.linalg.norm(estimate[:, :3], axis=1).max()
    peak_applied = np.linalg.norm(applied[:, :3], axis=1).max()
    held = pose_from_msg(rec["truth"][-1].pose)
    print(f"guard limit {limit} N: tripped at {trip['trip_force_n']:.1f} N (predicted "
          f"{trip['predicted_force_n']:.1f} N); peak estimated {peak_est:.1f} N, applied {peak_applied:.1f} N; "
          f"held at {(held[2] - robot.home_pose[2]) * 1e3:.3f} mm of 10 mm")
    assert peak_est <= 1.1 * limit and peak_applied <= 1.1 * limit
    # the goal ends GUARD_STOPPED (aborted) once the struts are at rest, short of the target, with its peak load
    name, message = move.outcome(30)
    assert (name, move.status()) == ("GUARD_STOPPED", 6), (name, message, logs(procs))
    result = move.result()
    print(f"goal: {name}: {message}; peak {result.peak_force_n:.1f} N, position error "
          f"{result.position_error_m * 1e3:.3f} mm")
    assert 0.6 * limit < result.peak_force_n <= 1.1 * limit, result.peak_force_n
    assert result.position_error_m > 1e-3  # held short of the 10 mm target
    # it stopped well into the load, not at the start. Near the limit (0.8) is checked at the node's nominal check
    # cadence in test_tissue's closed loop; here, in real processes, a busy machine makes the guard look further
    # ahead (its check gaps) and stop earlier by design (beside a hog and the suite: tripped 85 N, peak 126 N)
    assert peak_est > 0.6 * limit
    assert 1e-3 < held[2] - robot.home_pose[2] < 9e-3
    # struts within their limits all along (measured: legs/joint_states, strut = leg_i)
    times = np.array([stamp_of(m) for m in rec["states"]])
    sel = (times >= begin) & (times <= end)
    vel = np.array([rec["states"][i].velocity[:6] for i in np.flatnonzero(sel)])
    t = times[sel]
    lim = robot.limits
    assert np.abs(vel).max() <= lim.strut_velocity_max * 1.01
    step = np.diff(t)
    acc = np.diff(vel, axis=0)[step < 3e-3] / step[step < 3e-3, None]
    smooth = np.array([np.convolve(a, np.ones(5) / 5, mode="valid") for a in acc.T]).T  # 10 ms mean
    print(f"peak strut speed {np.abs(vel).max() * 1e3:.2f} mm/s, peak acceleration {np.abs(smooth).max():.4f} m/s^2")
    assert np.abs(smooth).max() <= lim.strut_acceleration_max * 1.05
    # the robot took every leg trajectory of the move and of its stop (its typed answers)
    refused = [(m.seq, m.outcome.code, m.outcome.message) for m in rec["trajectory_status"][statuses_before:]
               if not m.accepted]
    assert len(rec["trajectory_status"]) > statuses_before and not refused, refused
    kin_levels = [s.level for a in rec["diagnostics"][-5:] for s in a.status if s.name.startswith("kinematics")]
    assert client.spin_until(lambda: any(s.level == DiagnosticStatus.ERROR and "force guard" in s.message
                                         for a in rec["diagnostics"] for s in a.status
                                         if s.name.startswith("kinematics")), 5), kin_levels

    # further in the same direction: refused GUARD_BLOCKED, naming the way out; back: accepted
    further = held + np.array([0.0, 0.0, 0.001, 0.0, 0.0, 0.0])
    blocked = client.move(further)
    name, message = blocked.outcome(10)
    assert (name, blocked.status()) == ("GUARD_BLOCKED", 6), (name, message)
    assert "kinematics/reset_guard" in message, message
    plan = client.plan_path(further)
    assert (plan.outcome.code, plan.failing_waypoint, len(plan.path.poses)) == (Outcome.GUARD_BLOCKED, 0, 0), plan
    back = held - np.array([0.0, 0.0, 0.002, 0.0, 0.0, 0.0])
    move_to(client, rec, back)
    # reset: the same direction is accepted again (a small step, below the limit)
    res = client.call(Trigger, "kinematics/reset_guard", Trigger.Request())
    assert res.success and "reset" in res.message
    assert client.spin_until(lambda: guard_values(rec["guard"][-1])["state"] == "armed", 5)
    move_to(client, rec, back + np.array([0.0, 0.0, 0.001, 0.0, 0.0, 0.0]))
    move_to(client, rec, robot.home_pose)
    assert all(p.alive() for p in procs), logs(procs)


def test_a_move_pauses_while_the_estimator_is_stopped_and_then_resumes(robot, suite):
    """SIGSTOP the estimator early in a move: kinematics stops the struts within guard_max_estimate_age_s (trip
    limit 'estimates'), the platform holds short of the target; SIGCONT: the guard re-arms and the same target is
    reached without a new command."""
    import os
    import signal

    procs, client, rec = suite
    # 2 mm/s: the 4 mm move lasts ~3.8 s, so the SIGSTOP lands early in it however late this test reacts
    # (CI beside a hog at 10 mm/s: the move reached 3.74 of 4 mm before the pause)
    set_params(client, "kinematics", guard_max_estimate_age_s=0.2, speed_scale=0.1)
    move_to(client, rec, robot.home_pose)
    guard_before = len(rec["guard"])
    target = robot.home_pose + np.array([0.0, 0.0, 0.004, 0.0, 0.0, 0.0])  # 4 mm: well below the force limit
    move = client.move(target)
    estimator = next(p for p in procs if p.name == "estimator").popen.pid
    assert client.spin_until(lambda: rec["truth"] and pose_from_msg(rec["truth"][-1].pose)[2] >
                             robot.home_pose[2] + 0.2e-3, 20), logs(procs)
    os.kill(estimator, signal.SIGSTOP)
    try:
        assert client.spin_until(lambda: any(guard_values(m).get("trip_limit") == "estimates"
                                             for m in rec["guard"][guard_before:]), 10), logs(procs)
        trip = next(guard_values(m) for m in rec["guard"][guard_before:]
                    if guard_values(m).get("trip_limit") == "estimates")
        assert client.spin_until(lambda: sim_now(rec) > trip["trip_time_s"] + 1.5, 30)
        held = pose_from_msg(rec["truth"][-1].pose)
        print(f"estimator stopped: paused at {(held[2] - robot.home_pose[2]) * 1e3:.3f} mm of 4 mm")
        assert held[2] < target[2] - 0.3e-3  # held short of the target while blind
    finally:
        os.kill(estimator, signal.SIGCONT)
    held = HeldFor(0.5)

    def reached():  # at the target and the guard armed (a busy machine may pause the move again on its way)
        err = np.abs(pose_from_msg(rec["truth"][-1].pose) - target)
        armed = guard_values(rec["guard"][-1])["state"] == "armed"
        return held.update(bool(err[:3].max() < 10e-6) and armed, sim_now(rec))

    assert client.spin_until(reached, 60), logs(procs)  # resumed by itself: no new goal was sent
    # the pause was part of the same goal: it goes on to succeed
    name, message = move.outcome(30)
    assert (name, move.status()) == ("SUCCEEDED", 4), (name, message)
    move_to(client, rec, robot.home_pose)
    assert all(p.alive() for p in procs), logs(procs)


def test_a_goal_sent_during_a_move_is_refused_and_the_move_stays_guarded(robot, suite):
    """A move goal while a move runs is refused BUSY (planned from rest it would be refused by the
    emulator, which runs on, while the guard watched the refused move: seen in a CPU-hog run, the platform then
    went on toward a 10 mm distraction unwatched). The running move goes on to its target, guarded: kinematics'
    guard status stays armed and the ground truth settles there."""
    procs, client, rec = suite
    set_params(client, "kinematics", speed_scale=0.1)  # 2 mm/s: the 4 mm move lasts ~3.8 s
    move_to(client, rec, robot.home_pose)
    target = robot.home_pose + np.array([0.0, 0.0, 0.004, 0.0, 0.0, 0.0])  # well below the force limit
    move = client.move(target)
    assert client.spin_until(lambda: rec["truth"] and pose_from_msg(rec["truth"][-1].pose)[2] >
                             robot.home_pose[2] + 0.2e-3, 20), logs(procs)
    second = client.move(robot.home_pose)
    name, message = second.outcome(10)
    assert (name, second.status()) == ("BUSY", 6), (name, message, logs(procs))
    held = HeldFor(0.5)

    def reached():
        err = np.abs(pose_from_msg(rec["truth"][-1].pose) - target)
        return held.update(bool(err[:3].max() < 10e-6), sim_now(rec))

    assert client.spin_until(reached, 30), logs(procs)
    assert guard_values(rec["guard"][-1])["state"] == "armed"
    name, message = move.outcome(30)
    assert (name, move.status()) == ("SUCCEEDED", 4), (name, message)
    move_to(client, rec, robot.home_pose)  # after the move: taken
    assert all(p.alive() for p in procs), logs(procs)


def test_plan_path_refuses_a_path_that_would_overload_a_strut(robot, suite):
    procs, client, rec = suite
    refused = client.plan_path(robot.home_pose, robot.home_pose + np.array([0.0, 0.0, 0.020, 0.0, 0.0, 0.0]))
    assert (refused.outcome.code, refused.failing_waypoint, len(refused.path.poses)) == (Outcome.TISSUE_LIMIT, 1, 0)
    assert refused.failing_time_s == 0.0, refused  # the first segment fails
    reason = refused.outcome.message
    print(reason)
    assert "strut_force_max_n" in reason and "leg_" in reason and "waypoint" in reason and "tissue" in reason
    # a shorter distraction stays within the limit
    shorter = client.plan_path(robot.home_pose, robot.home_pose + np.array([0.0, 0.0, 0.008, 0.0, 0.0, 0.0]))
    assert shorter.outcome.code == Outcome.SUCCEEDED and len(shorter.path.poses) > 5, shorter
    # a move goal there is refused too (TISSUE_LIMIT, nothing sent), with the leg and the waypoint
    far = robot.home_pose + np.array([0.0, 0.0, 0.020, 0.0, 0.0, 0.0])
    sent = len(rec["trajectory_status"])
    refused = client.move(far)
    name, message = refused.outcome(10)
    assert (name, refused.status()) == ("TISSUE_LIMIT", 6), (name, message)
    assert "leg_" in message and "waypoint" in message and "strut_force_max_n" in message, message
    client.spin_for(0.3)
    assert len(rec["trajectory_status"]) == sent  # the robot was sent nothing
    assert all(p.alive() for p in procs), logs(procs)
