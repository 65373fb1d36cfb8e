"""The 3D scene as plain data (stewart_vibration.visualization.scene): frames, legs, hinges, rings
and the vibration arrow checked against geometry computed here from config/robot.yaml, not the package."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from stewart_vibration.kinematics.rotations import pose_to_position_quaternion
from stewart_vibration.paper import paper_pose
from stewart_vibration.vibration.decompose import decompose_vibration
from stewart_vibration.visualization.scene import (
    LEG_FRAMES,
    STATIC_ENTITIES,
    VIBRATION_ENTITY,
    SceneBuilder,
    _z_to,
    quaternion_between,
    robot_scene,
    vibration_direction_from_window,
)

CONFIG = Path(__file__).resolve().parents[1] / "stewart_vibration" / "config" / "robot.yaml"


def yaml_hinges(which: str) -> np.ndarray:
    g = yaml.safe_load(CONFIG.read_text())["geometry"][which]
    a = np.radians(g["angles_deg"])
    return np.column_stack([g["radius_m"] * np.cos(a), g["radius_m"] * np.sin(a), np.full(6, g["z_m"])])


def rot(q) -> np.ndarray:
    """Rotation matrix of [x, y, z, w] by rotating the basis vectors with q v q* (written here)."""
    x, y, z, w = q

    def mul(a, b):
        return np.array([a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1],
                         a[3] * b[1] - a[0] * b[2] + a[1] * b[3] + a[2] * b[0],
                         a[3] * b[2] + a[0] * b[1] - a[1] * b[0] + a[2] * b[3],
                         a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2]])

    conj = np.array([-x, -y, -z, w])
    return np.column_stack([mul(mul(q, [*e, 0.0]), conj)[:3] for e in np.eye(3)])


POSES = [np.array([0.0, 0.0, 0.160, 0.0, 0.0, 0.0]),
         np.array([0.002, 0.002, 0.162, np.pi / 15, np.pi / 12, np.pi / 18]),
         np.array([-0.015, 0.01, 0.17, -0.2, 0.1, 0.25])]


@pytest.mark.parametrize("pose", POSES)
def test_frames_and_legs_match_the_pose_and_the_hinges(robot, pose):
    position, quat = pose_to_position_quaternion(pose)
    scene = robot_scene(robot, position, quat, stamp=12.5)
    assert scene.stamp == 12.5
    platform = scene.transform("platform")
    assert (platform.parent, platform.child) == ("base", "platform")
    np.testing.assert_allclose(platform.translation, position, rtol=0, atol=1e-12)
    np.testing.assert_allclose(platform.rotation, quat, rtol=0, atol=1e-12)

    base_hinges, platform_hinges = yaml_hinges("base"), yaml_hinges("platform")
    tips = position + platform_hinges @ rot(quat).T  # A_i in base, computed here
    assert [t.child for t in scene.transforms] == ["platform", *LEG_FRAMES]
    for i, frame in enumerate(LEG_FRAMES):
        t = scene.transform(frame)
        assert t.parent == "base"
        np.testing.assert_allclose(t.translation, base_hinges[i], rtol=0, atol=1e-12)
        leg = tips[i] - base_hinges[i]
        np.testing.assert_allclose(rot(t.rotation)[:, 2], leg / np.linalg.norm(leg), rtol=0, atol=1e-12)
        # the leg entity: its cylinder starts at the base hinge, its piston ends at the platform hinge
        entity = scene.entity(frame)
        assert entity.frame_id == frame and len(entity.cylinders) == 2
        ends = []
        for c in entity.cylinders:
            axis = rot(c.orientation)[:, 2] * c.size[2] / 2
            ends.append(scene.to_base(frame, [c.position - axis, c.position + axis]))
        np.testing.assert_allclose(ends[0][0], base_hinges[i], rtol=0, atol=1e-12)
        np.testing.assert_allclose(ends[1][1], tips[i], rtol=0, atol=1e-12)
        assert ends[0][1][2] < tips[i][2] and ends[1][0][2] > base_hinges[i][2]  # both inside the leg

    # hinges as spheres at B_i (base) and A_i (platform frame -> base), rings through the hinge circles
    base, plat = scene.entity("base"), scene.entity("platform")
    assert (base.frame_id, plat.frame_id) == ("base", "platform")
    np.testing.assert_allclose([s.position for s in base.spheres], base_hinges, rtol=0, atol=1e-12)
    np.testing.assert_allclose(scene.to_base("platform", [s.position for s in plat.spheres]), tips, rtol=0,
                               atol=1e-12)
    for entity, hinges in ((base, base_hinges), (plat, platform_hinges)):
        (ring,) = entity.lines
        assert ring.closed and len(ring.points) >= 36
        np.testing.assert_allclose(np.hypot(ring.points[:, 0], ring.points[:, 1]), 0.100, atol=1e-12)
        np.testing.assert_allclose(ring.points[:, 2], hinges[0, 2], atol=1e-12)
    assert scene.entity(VIBRATION_ENTITY) is None


def test_vibration_arrow_starts_at_the_platform_and_points_along_the_direction(robot):
    position, quat = pose_to_position_quaternion(POSES[1])
    u = np.array([0.3, -0.2, 0.9])
    (arrow,) = robot_scene(robot, position, quat, vibration_direction=u * 5).entity(VIBRATION_ENTITY).arrows
    np.testing.assert_allclose(arrow.position, position, atol=1e-15)
    np.testing.assert_allclose(arrow.direction, u / np.linalg.norm(u), atol=1e-15)
    np.testing.assert_allclose(rot(arrow.orientation)[:, 0], u / np.linalg.norm(u), atol=1e-12)
    assert arrow.shaft_length > 0 and arrow.head_length > 0


@pytest.mark.parametrize("a,b", [([0, 0, 1], [0.1, 0.2, 0.97]), ([1, 0, 0], [-1, 0, 0]), ([0, 0, 1], [0, 0, -2]),
                                 ([0, 1, 0], [0, 1, 0]), ([1, 2, 3], [-3, 1, 0.5])])
def test_quaternion_between_rotates_a_onto_b(a, b):
    q = quaternion_between(a, b)
    assert abs(np.linalg.norm(q) - 1) < 1e-12
    np.testing.assert_allclose(rot(q) @ (np.array(a) / np.linalg.norm(a)), np.array(b) / np.linalg.norm(b),
                               atol=1e-12)


def test_builder_shares_the_static_entities_and_matches_robot_scene(robot):
    builder = SceneBuilder(robot)
    a, b = (builder.scene(*pose_to_position_quaternion(p), stamp=1.0) for p in POSES[:2])
    for entity_id in STATIC_ENTITIES:
        assert a.entity(entity_id) is b.entity(entity_id)
    c = robot_scene(robot, *pose_to_position_quaternion(POSES[1]), stamp=1.0)
    for t, u in zip(b.transforms, c.transforms, strict=True):
        assert t.child == u.child
        np.testing.assert_array_equal(np.r_[t.translation, t.rotation], np.r_[u.translation, u.rotation])
    assert [e.id for e in b.entities] == [e.id for e in c.entities]


def test_leg_frame_rotations_at_once_match_one_by_one():
    rng = np.random.default_rng(3)
    d = np.vstack([rng.normal(size=(20, 3)), [[0, 0, -1.5], [0, 0, 2.0], [0.3, 0, -1]]])
    q = _z_to(d)
    for qi, di in zip(q, d, strict=True):
        np.testing.assert_allclose(rot(qi)[:, 2], di / np.linalg.norm(di), atol=1e-12)
        assert abs(np.linalg.norm(qi) - 1) < 1e-12


@pytest.mark.parametrize("direction,frame", [([0, 0, 1], "platform"), ([1, 0, 0], "base"), ([0.2, -0.5, 0.8], "base")])
def test_vibration_direction_from_a_planned_window(robot, direction, frame):
    pose = paper_pose(robot)
    plan = decompose_vibration(robot, pose, direction, acceleration_g=0.3, frequency=35.0, frame=frame)
    t = np.arange(0, 0.6, 0.001)
    envelope = np.clip(t / 0.2, 0, 1)  # a ramp-in, as the planner's first window has
    window = (envelope * plan.amplitude * np.sin(2 * np.pi * 35.0 * t))[:, None] * plan.gains
    position, quat = pose_to_position_quaternion(pose)
    u = vibration_direction_from_window(robot, position, quat, window)
    expected = plan.direction * np.sign(plan.direction @ rot(quat)[:, 2])  # toward the platform's +z side
    np.testing.assert_allclose(u, expected, atol=1e-9)
    np.testing.assert_allclose(vibration_direction_from_window(robot, position, quat, -window), expected, atol=1e-9)


def test_no_vibration_direction_without_motion_or_with_bad_samples(robot):
    position, quat = pose_to_position_quaternion(POSES[0])
    for bad in (np.zeros((100, 6)), np.full((10, 6), np.nan), np.ones((10, 5)), np.ones(6), np.ones((1, 6))):
        assert vibration_direction_from_window(robot, position, quat, bad) is None


def test_offline_render_draws_every_primitive_and_refuses_a_missing_run(robot, tmp_path, capsys):
    import matplotlib.pyplot as plt

    from stewart_vibration.visualization.render import draw_scene, main

    scene = robot_scene(robot, *pose_to_position_quaternion(POSES[1]), vibration_direction=[0, 0, 1])
    ax = plt.figure().add_subplot(projection="3d")
    # 2 x (6 hinges + 1 ring) + 6 x 2 leg cylinders + 1 arrow
    assert draw_scene(ax, scene) == 27
    plt.close("all")
    assert main([str(tmp_path / "missing.mcap"), "--out", str(tmp_path / "x.png")]) == 2
    assert capsys.readouterr().err.startswith("error: ")
    assert not (tmp_path / "x.png").exists()
