"""The independent limit check of a recorded run (analysis.limit_check): a legal recording passes every
figure; each kind of violation, put into a synthetic recording at a known place, fails exactly its figure
with the value put there; the whole path from an MCAP written by the project's writer works too."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.analysis.limit_check import check_limits, joint_angles_at, limit_failures
from stewart_vibration.kinematics import inverse_kinematics, joint_angles

RATE = 500.0


def legal_run(robot, seconds=4.0):
    """A recording that keeps every limit: a slow 4 mm heave of the platform (min-jerk-like cosine, peak strut
    speed ~3 mm/s) with a 35 Hz, 50 um vibration of every unit; /clock at 100 Hz."""
    t = 100.0 + np.arange(int(seconds * RATE)) / RATE
    poses = np.tile(robot.home_pose, (t.size, 1))
    poses[:, 2] += 0.002 * (1 - np.cos(2 * np.pi * (t - t[0]) / seconds))
    legs = inverse_kinematics(robot, poses)
    vib = 50e-6 * np.sin(2 * np.pi * 35.0 * (t - t[0]))[:, None] * np.ones(6)
    joints = (t, {"position": np.hstack([legs, vib]), "velocity": np.zeros((t.size, 12)),
                  "effort": np.full((t.size, 12), 40.0)})
    return joints, (t.copy(), poses), t[::5].copy()


def violated(figures):
    return {f.name for f in figures if f.violated}


def test_a_legal_recording_keeps_every_limit(robot):
    joints, pose, clock = legal_run(robot)
    figures = check_limits(robot, joints, pose, clock)
    assert violated(figures) == set() and limit_failures(figures) == []
    by = {f.name: f for f in figures}
    # the figures are the recording's own: 2 mm x 2 pi / 4 s peak heave speed along the legs, 35 Hz unit motion
    assert by["vibration unit displacement"].worst == pytest.approx(50e-6, rel=1e-3)
    assert by["vibration unit velocity"].worst == pytest.approx(50e-6 * 2 * np.pi * 35, rel=0.02)
    assert by["vibration unit acceleration"].worst == pytest.approx(50e-6 * (2 * np.pi * 35) ** 2, rel=0.03)
    assert 0 < by["strut velocity"].worst < 0.002 * 2 * np.pi / 4.0 * 1.01


def spoil(robot, kind):
    """The legal run with one violation put at t = 101 s (index 500); returns (joints, pose, clock, figure,
    the value put there)."""
    joints, (pt, poses), clock = legal_run(robot)
    t, cols = joints
    pos = cols["position"].copy()
    i = 500
    value = None
    if kind == "stroke":
        pos[i:i + 10, 2] = robot.limits.stroke_max + 0.001  # leg 3, 1 mm past the end of its stroke
        value, name = robot.limits.stroke_max + 0.001, "stroke"
    elif kind == "strut velocity":
        ramp = 0.03 * (t - t[i]).clip(0, 0.2)  # leg 1 runs at 30 mm/s for 0.2 s
        pos[:, 0] += ramp
        value, name = 0.03 + 0.0, "strut velocity"
    elif kind == "strut acceleration":
        # leg 2, where the heave is at rest (102 s): 1 s easing to -18 mm/s, 0.3 m/s^2 for 0.12 s (longer than the
        # drive band's averages and stencil: it is read whole), 1 s easing back to rest; under the speed limit
        accel = np.select([(t >= 100.88) & (t < 101.88), (t >= 101.88) & (t < 102.0), (t >= 102.0) & (t < 103.0)],
                          [-0.018, 0.3, -0.018], 0.0)
        velocity = np.concatenate([[0.0], np.cumsum(0.5 * (accel[1:] + accel[:-1]) / RATE)])
        pos[:, 1] += np.concatenate([[0.0], np.cumsum(0.5 * (velocity[1:] + velocity[:-1]) / RATE)])
        value, name = 0.3, "strut acceleration"
    elif kind == "vibration unit displacement":
        sel = (t >= t[i]) & (t < t[i] + 0.2)  # unit 5 at 120 um for 7 whole periods (from a zero crossing)
        pos[sel, 6 + 4] = 120e-6 * np.sin(2 * np.pi * 35.0 * (t[sel] - t[0]))
        value, name = 120e-6, "vibration unit displacement"
    elif kind == "vibration unit acceleration":
        sel = (t >= t[i]) & (t < t[i] + 0.2)
        pos[sel, 6 + 5] = 90e-6 * np.sin(2 * np.pi * 60.0 * (t[sel] - t[i]))  # 12.8 m/s^2 > 1 g
        value, name = None, "vibration unit acceleration"
    elif kind == "universal joint angle":
        poses = poses.copy()
        poses[i:i + 3, 0] = 0.14  # 140 mm sideways: every joint past 50 deg
        value, name = None, "universal joint angle"
    elif kind == "condition number":
        poses = poses.copy()
        poses[i, :] = [0.0, 0.0, 0.16, 0.0, 0.0, np.radians(90.0)]  # legs coplanar in pairs
        value, name = None, "condition number"
    elif kind == "non-finite values":
        pos[i, 3] = np.nan
        value, name = 1.0, "non-finite values"
    elif kind == "time going back":
        clock = clock.copy()
        clock[300:] -= 19.0  # sim time jumps back 19 s
        value, name = 1.0, "time going back (/clock, state stamps)"
    joints = (t, dict(cols, position=pos))
    return joints, (pt, poses), clock, name, value


@pytest.mark.parametrize("kind", ["stroke", "strut velocity", "strut acceleration", "vibration unit displacement",
                                  "vibration unit acceleration", "universal joint angle", "condition number",
                                  "non-finite values", "time going back"])
def test_each_violation_fails_exactly_its_figure(robot, kind):
    joints, pose, clock, name, value = spoil(robot, kind)
    figures = check_limits(robot, joints, pose, clock)
    bad = violated(figures)
    # what a violation also implies: a length or speed that jumps is a huge rate too; a pose far from home
    # strains the joints and the conditioning together; a NaN is not finite in every figure it reaches
    implied = {"stroke": {"strut velocity", "strut acceleration"}, "strut velocity": {"strut acceleration"},
               "vibration unit displacement": {"vibration unit acceleration"},
               "universal joint angle": {"spherical joint angle", "condition number"},
               "condition number": {"universal joint angle", "spherical joint angle"},
               "non-finite values": {"stroke", "strut velocity", "strut acceleration"}}.get(kind, set())
    assert name in bad and bad <= {name} | implied, bad
    figure = next(f for f in figures if f.name == name)
    if kind == "strut velocity":  # 30 mm/s on top of the heave (at most 3.2 mm/s)
        assert 0.03 <= figure.worst <= 0.03 + 0.0032
    elif value is not None:
        assert figure.worst == pytest.approx(value, rel=0.02)
    if kind in ("stroke", "strut velocity", "vibration unit displacement"):
        assert abs(figure.time_s - 101.0) < 0.25
    line = next(x for x in limit_failures(figures) if name in x)
    assert line.startswith("limits over the recorded states: ") and "limit" in line


@pytest.mark.parametrize("frequency", [20.0, 35.0, 60.0])
def test_a_strut_shaken_in_the_therapy_band_is_not_a_drive_acceleration(robot, frequency):
    """The units' reaction shakes a strut's servo at the vibration frequency (the realistic plant: ~4 um, 0.19
    m/s^2 at 35 Hz), which no command asked for: judged on the struts' own motion (the drive band) it adds
    under 1/25 of the drive's limit to the slow heave's anywhere in the therapy band; raw it is twice the limit.
    A slow move at that acceleration is read whole (test_each_violation_fails_exactly_its_figure)."""
    joints, pose, clock = legal_run(robot)
    t, cols = joints
    raw = 2 * robot.limits.strut_acceleration_max
    pos = cols["position"].copy()
    pos[:, :6] += raw / (2 * np.pi * frequency) ** 2 * np.sin(2 * np.pi * frequency * (t - t[0]) + 0.3)[:, None]
    figures = {f.name: f for f in check_limits(robot, (t, dict(cols, position=pos)), pose, clock)}
    heave = {f.name: f for f in check_limits(robot, joints, pose, clock)}["strut acceleration"].worst  # 0.005
    assert not figures["strut acceleration"].violated
    assert figures["strut acceleration"].worst - heave < robot.limits.strut_acceleration_max / 25


def test_the_joint_angles_agree_with_the_kinematics_module(robot):
    """The check computes the angles on its own; kinematics.joint_angles is the reference."""
    rng = np.random.default_rng(4)
    poses = robot.home_pose + rng.uniform(-1, 1, (50, 6)) * [0.01, 0.01, 0.01, 0.2, 0.2, 0.2]
    universal, spherical = joint_angles_at(robot, poses)
    ref_u, ref_s = joint_angles(robot, poses)
    np.testing.assert_allclose(universal, ref_u, atol=1e-12)
    np.testing.assert_allclose(spherical, ref_s, atol=1e-12)


def test_no_difference_across_a_gap(robot):
    """Lost states are a gap, not a jump: 0.5 s of a 2 mm/s move missing does not read as 1 m/s."""
    joints, pose, clock = legal_run(robot)
    t, cols = joints
    keep = (t < 101.0) | (t > 101.5)
    figures = check_limits(robot, (t[keep], {k: v[keep] for k, v in cols.items()}), pose, clock)
    assert violated(figures) == set()


def test_from_an_mcap_written_by_the_recorders_writer(robot, tmp_path):
    """The run summary's path: joint states, true poses and /clock in an MCAP (real CDR), load_signals, the
    check; a violation put into the file is found there."""
    from rosbags.typesys import Stores, get_typestore

    from stewart_vibration.analysis.run_signals import load_signals
    from stewart_vibration.analysis.run_verdict import limit_summary
    from stewart_vibration.kinematics.rotations import quaternion_from_rpy
    from stewart_vibration.mcap_log import McapRunWriter
    from stewart_vibration.robot import LEG_NAMES, VIB_NAMES

    store = get_typestore(Stores.ROS2_JAZZY)
    T = store.types
    joints, (pt, poses), clock = legal_run(robot, seconds=1.0)
    t, cols = joints
    sel = (t >= t[0] + 0.4) & (t < t[0] + 0.6)  # unit 1 at 101 um for 7 periods, from a zero crossing: its rates
    cols["position"][sel, 6] = 101e-6 * np.sin(2 * np.pi * 35.0 * (t[sel] - t[0]))  # stay within theirs
    path = tmp_path / "run.mcap"
    w = McapRunWriter(path)
    for topic, kind in (("/s/legs/joint_states", "sensor_msgs/msg/JointState"),
                        ("/s/ground_truth/platform_pose", "geometry_msgs/msg/PoseStamped"),
                        ("/clock", "rosgraph_msgs/msg/Clock")):
        w.add_topic(topic, kind, "[]")
    quats = quaternion_from_rpy(poses[:, 3:])
    for k, tk in enumerate(t):
        ns = int(round(tk * 1e9))
        stamp = T["builtin_interfaces/msg/Time"](ns // 10**9, ns % 10**9)
        h = T["std_msgs/msg/Header"](stamp, "base")
        js = T["sensor_msgs/msg/JointState"](h, [*LEG_NAMES, *VIB_NAMES], cols["position"][k], cols["velocity"][k],
                                              cols["effort"][k])
        w.submit("/s/legs/joint_states", ns, bytes(store.serialize_cdr(js, "sensor_msgs/msg/JointState")))
        p = T["geometry_msgs/msg/Pose"](T["geometry_msgs/msg/Point"](*poses[k, :3]),
                                        T["geometry_msgs/msg/Quaternion"](*quats[k]))
        pose_cdr = store.serialize_cdr(T["geometry_msgs/msg/PoseStamped"](h, p), "geometry_msgs/msg/PoseStamped")
        w.submit("/s/ground_truth/platform_pose", ns, bytes(pose_cdr))
        if k % 5 == 0:
            w.submit("/clock", ns, bytes(store.serialize_cdr(T["rosgraph_msgs/msg/Clock"](stamp),
                                                             "rosgraph_msgs/msg/Clock")))
    w.close()
    rows = {r["name"]: r for r in limit_summary(robot, load_signals(path))}
    assert {n for n, r in rows.items() if r["violations"]} == {"vibration unit displacement"}
    assert rows["vibration unit displacement"]["worst"] == pytest.approx(101e-6, rel=1e-3)
    assert t[0] + 0.4 <= rows["vibration unit displacement"]["time_s"] < t[0] + 0.6
    assert rows["time going back (/clock, state stamps)"]["violations"] == 0
    assert rows["universal joint angle"]["worst"] == pytest.approx(np.degrees(joint_angles(robot, poses)[0].max()))


@pytest.mark.parametrize("kind", ["universal joint angle", "spherical joint angle", "condition number"])
def test_pose_figures_over_slabs_are_those_of_the_whole_run(robot, monkeypatch, kind):
    from stewart_vibration.analysis import limit_check

    joints, (pt, poses), clock = legal_run(robot)
    poses = poses.copy()
    poses[650:720, 4] += 0.66  # a tilt past the spherical joints' limit, across a slab boundary (679)
    poses[1333, 4] += 0.7  # and a worse one, alone, in a later slab
    whole = {f.name: f for f in check_limits(robot, joints, (pt, poses), clock)}
    monkeypatch.setattr(limit_check, "POSE_SLAB", 97)
    slabbed = {f.name: f for f in check_limits(robot, joints, (pt, poses), clock)}
    assert slabbed == whole
    legal = {f.name: f for f in check_limits(robot, *legal_run(robot))}
    assert whole[kind].worst > legal[kind].worst  # the figure is a tilted sample's, found across the slabs
    assert whole[kind].time_s in set(pt[650:720]) | {pt[1333]}
    assert whole["spherical joint angle"].violations > 2  # summed over the slabs the tilt spans
