"""The messages the planning page gets besides its answers (pure): ``hello`` when it opens (the robot and the
conventions) and the live ``frame`` at frame_rate_hz (streams, poses, the move, the vibration, the suite); and
the backend the web server asks for them, for commands and for files (PageBackend).

Lengths in the messages are mm (um for vibration amplitudes and errors), angles deg, forces N; poses of the
platform frame in the base frame; times s (``wall``: since the epoch; ages: of the node's monotonic clock).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..paper import paper_pose
from ..robot import STANDARD_GRAVITY, Robot
from . import model
from .command_queue import CommandInbox, Reply
from .live_streams import LiveStreams
from .move_follow import SETTLE_ANGLE_RAD, SETTLE_POSITION_M, FollowedMove
from .planner_settings import PlannerSettings
from .suite_status import SuiteStatus
from .vibration_follow import PLANNER_STATUS, VibrationFollow


def hello(robot: Robot, namespace: str) -> dict:
    """What a page needs once: the pose convention, the robot's geometry and limits, the paper's pose and the
    settle tolerance the move follow uses."""
    lim, unit = robot.limits, robot.vibration_unit
    return model.jsonable({
        "convention": model.CONVENTION, "namespace": namespace,
        "robot": {"base_points_mm": robot.base_hinges * 1e3, "platform_hinges_mm": robot.platform_hinges * 1e3,
                  "home": model.pose_fields(robot.home_pose), "stroke_mm": [lim.stroke_min * 1e3,
                                                                            lim.stroke_max * 1e3],
                  "unit": {"acceleration_max_g": unit.acceleration_max / STANDARD_GRAVITY,
                           "amplitude_max_um": unit.amplitude_max * 1e6,
                           "frequency_band_hz": [unit.frequency_min, unit.frequency_max]}},
        "paper_pose": model.pose_fields(paper_pose(robot)), "settle": {"position_um": SETTLE_POSITION_M * 1e6,
                                                                    "angle_deg": math.degrees(SETTLE_ANGLE_RAD)},
    })


def frame(robot: Robot, now: float, wall: float, stale_after_s: float, streams: LiveStreams,
          move: FollowedMove | None, vibration: VibrationFollow, suite: SuiteStatus,
          planner: PlannerSettings) -> dict:
    """One live frame (JSON-ready): the streams' ages and plot rows since the last frame (taken), the latest pose
    estimate with the platform's hinge points, the legs, the move, the vibration, the nodes, the MCAP file, the
    events, the last run's summary and report files."""
    message = {"type": "frame", "wall": wall, "stale_after_s": stale_after_s,
               "ages": {k: now - t for k, t in streams.seen.items()},
               "plots": {k: np.round(np.asarray(v), 4).tolist() for k, v in streams.take_plots().items()}}
    estimate = streams.latest_estimate
    if estimate is not None:
        stamp, pose = estimate
        message["estimate"] = {"stamp": stamp, "fields": model.pose_fields(pose),
                               "points_mm": (model.platform_points(robot, pose) * 1e3).tolist()}
    if streams.latest_joints is not None:
        stamp, row = streams.latest_joints
        message["legs"] = {"stamp": stamp, "length_mm": ((row[:6] + row[6:12]) * 1e3).tolist(),
                           "vib_um": (row[6:12] * 1e6).tolist(), "force_n": row[12:18].tolist()}
    if move is not None:
        message["move"] = move.view(now, estimate[1] if estimate is not None else None)
    message["vibration"] = vibration.view(suite.nodes.get(PLANNER_STATUS))
    message["nodes"] = suite.nodes_view(now)
    message["mcap"] = suite.recorder.view()
    message["events"] = suite.events.view()
    message["summary"] = vibration.summary
    message["report"] = suite.report
    message["planner_known"] = planner.known
    return model.jsonable(message)


@dataclass(frozen=True)
class PageBackend:
    """What ui.server asks of the node, from the server's own thread: the ``hello`` message, a command (queued
    for the node's executor) and a report file (one the recorder's report lists)."""

    hello_message: dict
    inbox: CommandInbox
    suite: SuiteStatus

    def hello(self) -> dict:
        """The message a page gets when it opens."""
        return self.hello_message

    def command(self, cmd: str, args: dict, reply: Reply) -> None:
        """A page's command (e-stops go before the others)."""
        self.inbox.put(cmd, args, reply)

    def file(self, kind: str, name: str) -> Path | None:
        """The path of a file the page may fetch, None if it may not."""
        return self.suite.report_file(kind, name)
