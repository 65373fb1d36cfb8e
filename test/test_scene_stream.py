"""The live scene's ticks without ROS: the vibration arrow shown only while the robot's units are busy with a
vibration, along the planned window's direction (from the paper's decomposition, an independent plan), deleted
once when it ends; the static entities sent every period and at once to a client that comes back."""

from __future__ import annotations

import numpy as np

from stewart_vibration import pose_to_position_quaternion
from stewart_vibration.paper import paper_pose
from stewart_vibration.vibration.decompose import decompose_vibration
from stewart_vibration.visualization.scene import STATIC_ENTITIES, VIBRATION_ENTITY, SceneBuilder
from stewart_vibration.visualization.scene_stream import SceneStream


def ids(frame) -> set[str]:
    return {e.id for e in frame.entities}


def test_the_arrow_follows_the_robots_vibration_state_and_the_planned_window(robot):
    pose = paper_pose(robot)
    position, quat = pose_to_position_quaternion(pose)
    plan = decompose_vibration(robot, pose, [0, 0, 1], acceleration_g=0.3, frequency=35.0)
    t = np.arange(0, 0.5, 0.001)
    stream = SceneStream(SceneBuilder(robot), static_period_s=1.0)
    stream.on_window((plan.amplitude * np.sin(2 * np.pi * 35.0 * t))[:, None] * plan.gains)
    frame = stream.frame(position, quat, 1.0, now=0.0)
    assert VIBRATION_ENTITY not in ids(frame) and not frame.delete_arrow  # planned, not yet under way
    stream.on_status("pending")
    frame = stream.frame(position, quat, 1.1, now=0.1)
    (arrow_entity,) = [e for e in frame.entities if e.id == VIBRATION_ENTITY]
    np.testing.assert_allclose(arrow_entity.arrows[0].direction, plan.direction, atol=1e-9)
    stream.on_status("running")
    assert VIBRATION_ENTITY in ids(stream.frame(position, quat, 1.2, now=0.2))
    stream.on_status("idle")
    ended = stream.frame(position, quat, 1.3, now=0.3)
    assert ended.delete_arrow and VIBRATION_ENTITY not in ids(ended)
    assert not stream.frame(position, quat, 1.4, now=0.4).delete_arrow  # deleted once


def test_static_entities_every_period_and_at_once_for_a_client_that_comes_back(robot):
    position, quat = pose_to_position_quaternion(robot.home_pose)
    stream = SceneStream(SceneBuilder(robot), static_period_s=1.0)
    static = set(STATIC_ENTITIES)
    assert static <= ids(stream.frame(position, quat, 0.0, now=10.0))
    between = ids(stream.frame(position, quat, 0.5, now=10.5))
    assert not static & between and between == {f"leg_{i}" for i in range(1, 7)}  # the moving ones go every tick
    assert static <= ids(stream.frame(position, quat, 1.0, now=11.0))
    stream.unwatched()
    assert static <= ids(stream.frame(position, quat, 1.1, now=11.1))
