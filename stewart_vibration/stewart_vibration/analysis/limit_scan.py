"""The independent limit check of a run read slab after slab (pure): the figures of ``limit_check.check_limits``
over the whole run, holding one slab of states and poses at a time instead of the run.

Each slab of joint states is checked with the last states of the slab before it in front (``CARRY`` of them:
the longest stencil, the strut acceleration's with its averages, so that a velocity or acceleration across the
seam is computed once, from the states on both sides); poses need no neighbours. The slabs' figures combine as
the whole run's do: the first largest worst, the violations and counts summed, the stroke's lowest and highest
values and the sample that is furthest outside. One difference: a gap between states is told from the median
step of each slab with its carry, not of the whole run (the same at any steady state rate).
"""

from __future__ import annotations

import numpy as np

from ..robot import Robot
from .limit_check import (
    STRUT_SUPPORT,
    LimitFigure,
    combined_worst,
    count_figures,
    not_finite_count,
    pose_figures,
    state_figures,
    steps_back,
    stroke_excess,
)

CARRY = 2 * STRUT_SUPPORT  # states of the slab before that complete the differences across the seam


class LimitScan:
    """check_limits' figures of a run whose joint states, true poses and /clock come slab after slab, each
    stream in its recorded order (``add_states``, ``add_poses``), then ``figures(clock_times)``."""

    def __init__(self, robot: Robot):
        self.robot = robot
        self._carry_t = np.empty(0)
        self._carry_x = np.empty((0, 12))
        self._states: list[list[LimitFigure]] = []
        self._stroke_excess: list[float] = []
        self._poses: list[list[LimitFigure]] = []
        self._not_finite = 0
        self._backwards = 0

    def add_states(self, times, columns: dict) -> None:
        """The next joint states: stamps [n] (s) and {"position", "velocity", "effort": [n, 12]} (leg_1..6 then
        vib_1..6; a field not read may be NaN, as ``check_limits`` takes it)."""
        times = np.asarray(times, float)
        if not times.size:
            return
        positions = np.asarray(columns["position"], float).reshape(-1, 12)
        first = self._carry_t.size
        t, x = np.concatenate([self._carry_t, times]), np.concatenate([self._carry_x, positions])
        figures = state_figures(self.robot, t, x, first)
        self._states.append(figures)
        lim = self.robot.limits
        hinge = positions[:, :6] + positions[:, 6:12]
        self._stroke_excess.append(float(stroke_excess(hinge, lim.stroke_min, lim.stroke_max).max()))
        self._not_finite += not_finite_count(columns)
        self._backwards += steps_back(t[max(first - 1, 0):], strict=True)
        self._carry_t, self._carry_x = t[-CARRY:].copy(), x[-CARRY:].copy()

    def add_poses(self, times, poses) -> None:
        """The next true poses: stamps [m] (s), poses [m, 6] (m, rad)."""
        times, poses = np.asarray(times, float), np.asarray(poses, float).reshape(-1, 6)
        finite = np.isfinite(poses).all(axis=1)
        self._not_finite += int(np.count_nonzero(~finite))
        if finite.any():
            self._poses.append(pose_figures(self.robot, times[finite], poses[finite]))

    def figures(self, clock_times=None) -> list[LimitFigure]:
        """The run's figures in check_limits' order; ``clock_times``: the /clock values (s) in recorded order."""
        empty = (np.empty(0), np.empty((0, 12)))
        states = (self._combined_states() if self._states
                  else state_figures(self.robot, *empty))
        poses = ([combined_worst(list(parts)) for parts in zip(*self._poses, strict=True)] if self._poses
                 else pose_figures(self.robot, np.empty(0), np.empty((0, 6))))
        backwards = self._backwards
        if clock_times is not None and len(clock_times) > 1:
            backwards += steps_back(clock_times, strict=False)
        return states + poses + count_figures(self._not_finite, backwards)

    def _combined_states(self) -> list[LimitFigure]:
        parts = list(zip(*self._states, strict=True))
        strokes = parts[0]
        furthest = strokes[int(np.argmax(self._stroke_excess))]
        stroke = LimitFigure(furthest.name, furthest.unit, float(np.nanmax([f.worst for f in strokes])),
                             furthest.limit, furthest.time_s, furthest.leg, sum(f.violations for f in strokes),
                             furthest.low_limit, float(np.nanmin([np.nan if f.least is None else f.least
                                                                  for f in strokes])))
        return [stroke] + [combined_worst(list(figures)) for figures in parts[1:]]
