"""vibration planner node in its own process over real DDS (issue 5)."""

from __future__ import annotations

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from ros_client import node_under_test
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from stewart_vibration import pose_to_position_quaternion, rotation_from_rpy
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


def trigger(client, name):
    return client.call(Trigger, f"vibration_planner/{name}", Trigger.Request())


def independent_gains(robot, pose):
    """k_i = n_i . u, u = platform z axis, from the hinge points (not the package's decomposition)."""
    rot = rotation_from_rpy(pose[3:])
    d = pose[:3] + robot.platform_hinges @ rot.T - robot.base_hinges
    n = d / np.linalg.norm(d, axis=1, keepdims=True)
    return n @ rot[:, 2]


def merged(windows):
    """{time key (us): (t, positions, velocities)} over windows; asserts overlapping samples agree."""
    out, worst = {}, 0.0
    for w in windows:
        for p in w.points:
            t = p.time_from_start.sec + p.time_from_start.nanosec * 1e-9
            key = round(t * 1e6)
            if key in out:
                worst = max(worst, np.abs(np.subtract(out[key][1], p.positions)).max())
            out[key] = (t, np.array(p.positions), np.array(p.velocities))
    return out, worst


def test_parameter_validation_and_bad_starts(planner):
    proc, client = planner
    diagnostics = client.subscribe("/diagnostics", DiagnosticArray)
    bad = [
        {"frequency_hz": 500.0},
        {"direction": [0.0, 0.0, 0.0]},
        {"frame": "world"},
        {"duration_s": 0.1},  # shorter than the two 0.2 s ramps
        {"window_s": 0.1},  # not longer than window_period_s
        {"ramp_s": -1.0},
        {"start_lead_s": 0.1},  # the first window would begin after t0 (lead_s 0.3)
    ]
    for values in bad:
        (result,) = set_params(client, **values)
        assert not result.successful and result.reason, values
    (ok,) = set_params(client, frequency_hz=40.0)
    assert ok.successful
    set_params(client, frequency_hz=F)

    response = trigger(client, "start")
    assert not response.success and "no platform/pose_estimate" in response.message
    nan = pose_msg(np.zeros(6))
    nan.pose.position.x = float("nan")
    client.publisher("platform/pose_estimate", PoseStamped).publish(nan)
    client.spin_for(0.3)
    response = trigger(client, "start")  # the NaN estimate is refused when a start needs it
    assert not response.success and "pose estimate unusable" in response.message and "non-finite" in response.message
    assert trigger(client, "stop").success  # idle: nothing to do
    messages = [s.message for a in diagnostics for s in a.status]
    assert any("rejected start: pose estimate unusable" in m for m in messages), messages
    assert proc.alive()


def test_start_stream_stop_and_infeasible(robot, planner):
    proc, client = planner
    windows = client.subscribe("vibration/joint_trajectory", JointTrajectory)
    poses = client.publisher("platform/pose_estimate", PoseStamped)
    pose = paper_pose(robot)
    assert client.wait_for_subscribers("platform/pose_estimate"), proc.log_text()
    poses.publish(pose_msg(pose))
    client.spin_for(0.3)

    response = trigger(client, "start")
    assert response.success, response.message
    assert "gains k" in response.message and "leg amplitudes um" in response.message
    again = trigger(client, "start")
    assert not again.success and "already running" in again.message
    assert client.spin_until(lambda: len(windows) >= 6, 10), proc.log_text()
    running = list(windows)

    # common stamp, names, ramp-in from rest, window continuity (overlaps agree sample for sample)
    assert len({(w.header.stamp.sec, w.header.stamp.nanosec) for w in running}) == 1
    assert all(list(w.joint_names) == VIB for w in running)
    first = running[0].points[0]
    assert first.time_from_start.sec == 0 and first.time_from_start.nanosec == 0
    assert np.abs(first.positions).max() == 0.0
    samples, worst = merged(running)
    assert worst < 1e-15
    keys = sorted(samples)
    assert np.all(np.diff(keys) == round(DT * 1e6)), "gap in the streamed samples"
    t = np.array([samples[k][0] for k in keys])
    pos = np.array([samples[k][1] for k in keys])
    vel = np.array([samples[k][2] for k in keys])

    # steady state: vib_i = k_i A sin(w t) (+ second order), amplitude |k_i| A, phase 0 or pi
    amp = G_ACC * 9.80665 / (2 * np.pi * F) ** 2
    gains = independent_gains(robot, pose)
    steady = (t >= RAMP + 0.01) & (t < RAMP + 0.01 + 10 / F)
    w = 2 * np.pi * F
    basis = np.column_stack([np.sin(w * t[steady]), np.cos(w * t[steady]), np.ones(steady.sum())])
    coef = np.linalg.lstsq(basis, pos[steady], rcond=None)[0]
    np.testing.assert_allclose(coef[0], gains * amp, atol=1e-3 * amp)  # signed: phase 0 (k>0) or pi (k<0)
    assert np.abs(coef[1]).max() < 1e-3 * amp
    np.testing.assert_allclose(np.gradient(pos, t, axis=0)[1:-1], vel[1:-1], atol=0.01 * w * amp)
    assert np.abs(pos[t < RAMP]).max() < np.abs(pos).max()  # ramping in

    # stop: a window that ramps out from the buffered signal to exactly zero, then silence
    before = len(windows)
    response = trigger(client, "stop")
    assert response.success and "ramp-out" in response.message, response.message
    assert client.spin_until(lambda: len(windows) > before, 5)
    client.spin_for(0.6)
    stop_window = windows[before]
    assert len(windows) == before + 1, "windows after the stop ramp"
    sent, _ = merged(windows[:before])
    stop_points = merged([stop_window])[0]
    first_key = min(stop_points)
    # the ramp starts at 1 on an already sent sample; the stop window replaces everything after it
    assert np.abs(stop_points[first_key][1] - sent[first_key][1]).max() < 1e-9 * amp
    effective = {k: v for k, v in sent.items() if k < first_key} | stop_points
    keys = sorted(effective)
    tail = np.array([effective[k][1] for k in keys])
    assert np.all(np.diff(keys) == round(DT * 1e6))
    assert np.abs(stop_window.points[-1].positions).max() == 0.0
    assert np.abs(np.diff(tail, axis=0)).max() <= 1.05 * w * amp * DT  # no step anywhere
    ramp_span = (stop_window.points[-1].time_from_start.sec + stop_window.points[-1].time_from_start.nanosec * 1e-9
                 - stop_window.points[0].time_from_start.sec - stop_window.points[0].time_from_start.nanosec * 1e-9)
    assert abs(ramp_span - RAMP) < 2 * DT

    # infeasible: 150 um is above the unit's 100 um
    assert client.spin_until(lambda: trigger(client, "stop").message == "already idle", 5)
    (result,) = set_params(client, amplitude_m=150e-6)
    assert result.successful
    poses.publish(pose_msg(pose))
    client.spin_for(0.2)
    response = trigger(client, "start")
    assert not response.success and "amplitude_max" in response.message, response.message
    # a pose the robot cannot reach: the typed error text comes back
    poses.publish(pose_msg(pose + np.array([0, 0, 0.2, 0, 0, 0])))
    client.spin_for(0.2)
    (result,) = set_params(client, amplitude_m=0.0)
    response = trigger(client, "start")
    assert not response.success and "StrokeLimitError" in response.message, response.message
    assert proc.alive()


def test_streams_on_sim_time(robot, ros_domain, tmp_path):
    from rosgraph_msgs.msg import Clock

    args = ["--ros-args", "-p", "use_sim_time:=true", "-p", "duration_s:=1.0", "-p", "ramp_s:=0.1"]
    with node_under_test("planner_sim", "stewart_vibration.nodes.vibration_planner_node", ros_domain, tmp_path,
                         args) as (proc, client):
        windows = client.subscribe("vibration/joint_trajectory", JointTrajectory)
        clock = client.publisher("/clock", Clock)
        assert client.wait_for_subscribers("platform/pose_estimate"), proc.log_text()
        client.publisher("platform/pose_estimate", PoseStamped).publish(pose_msg(paper_pose(robot)))
        client.spin_for(0.2)
        response = trigger(client, "start")
        assert not response.success and "clock not running" in response.message, response.message

        sim = 100.0
        clock.publish(Clock(clock=Time(sec=100)))
        client.spin_for(0.2)
        client.publisher("platform/pose_estimate", PoseStamped).publish(pose_msg(paper_pose(robot)))
        client.spin_for(0.2)
        response = trigger(client, "start")
        assert response.success, response.message
        while sim < 102.5:  # 2.5 s of sim time at ~4x wall speed
            sim += 0.01
            ns = round(sim * 1e9)
            clock.publish(Clock(clock=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)))
            client.spin_for(0.0025)
        client.spin_for(0.2)
        stamp = windows[0].header.stamp
        assert abs(stamp.sec + stamp.nanosec * 1e-9 - 101.0) < 1e-6  # t0 = sim now + start_lead_s (1 s)
        samples, worst = merged(windows)
        last = samples[max(samples)]
        assert worst < 1e-15 and abs(last[0] - 1.0) < 1e-9 and np.abs(last[1]).max() == 0.0  # ends at rest
        assert 2 <= len(windows) <= 8  # one per 0.2 s of sim time until the end is covered
        assert trigger(client, "stop").message == "already idle"
