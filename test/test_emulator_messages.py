"""The hardware emulator's own messages built in-process (nodes.emulator_messages, no node started):
robot_markers in base at the given stamp, one marker per part with the outline's points; the answer to a leg
trajectory with its outcome code."""

from __future__ import annotations

import numpy as np
import pytest
from visualization_msgs.msg import Marker

from stewart_vibration.emulation.command_intake import LegTrajectoryAnswer
from stewart_vibration.errors import RefusedError
from stewart_vibration.nodes.emulator_messages import leg_trajectory_status_msg, robot_markers_msg
from stewart_vibration.visualization.robot_outline import robot_outline
from stewart_vibration_interfaces.msg import Outcome


def test_robot_markers_carry_the_outline_in_base_at_the_stamp(robot):
    outline = robot_outline(robot, [0.0, 0.0, 0.16], [0.0, 0.0, 0.0, 1.0])
    msg = robot_markers_msg(outline, 12.000000002)
    kinds = [(m.ns, m.id, m.type) for m in msg.markers]
    assert kinds == [("legs", 0, Marker.LINE_LIST), ("platform", 1, Marker.LINE_STRIP),
                     ("base", 2, Marker.LINE_STRIP), ("hinges", 3, Marker.SPHERE_LIST)]
    for marker, points in zip(msg.markers, (outline.legs, outline.platform, outline.base, outline.hinges),
                              strict=True):
        assert marker.header.frame_id == "base"
        assert (marker.header.stamp.sec, marker.header.stamp.nanosec) == (12, 2)
        assert marker.action == Marker.ADD and marker.color.a == 1.0
        assert np.array([[p.x, p.y, p.z] for p in marker.points]) == pytest.approx(points)


def test_the_leg_trajectory_status_says_taken_or_why_refused():
    final = np.array([0.17, 0.18, np.nan, 0.17, 0.18, 0.17])
    taken = leg_trajectory_status_msg(LegTrajectoryAnswer(4, 3, final, 2.5, end_time_s=3.5))
    assert (taken.seq, taken.accepted, taken.points, taken.end_time_s) == (4, True, 3, 3.5)
    assert (taken.header.stamp.sec, taken.header.stamp.nanosec) == (2, 500_000_000)
    assert np.asarray(taken.final_positions) == pytest.approx(final, nan_ok=True)
    assert (taken.outcome.code, taken.outcome.message) == (Outcome.SUCCEEDED, "taken")
    refused = leg_trajectory_status_msg(LegTrajectoryAnswer(5, 0, np.full(6, np.nan), 2.6,
                                                            error=RefusedError("ROBOT_INACTIVE", "inactive")))
    assert (refused.seq, refused.accepted, refused.points) == (5, False, 0) and np.isnan(refused.end_time_s)
    assert (refused.outcome.code, refused.outcome.message) == (Outcome.ROBOT_INACTIVE, "inactive")
