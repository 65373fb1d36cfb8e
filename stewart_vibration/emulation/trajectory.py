"""Joint trajectories with ros2_control joint_trajectory_controller semantics (pure numpy).

A trajectory is a start time (s, the header stamp; 0 means "now") plus
points with strictly increasing time_from_start, positions and optional
velocities/accelerations for a fixed set of joint names. Sampling follows
the controller: from the state held when the trajectory starts, a spline to
the first point, then between points a quintic (pos+vel+acc), cubic
(pos+vel) or linear (pos only) segment; before its start the previous
command holds, after its last point the last point holds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from ..hermite import cubic_hermite, quintic_hermite


@dataclass(frozen=True)
class JointTrajectory:
    """Validated trajectory: start (s), times [n] (s from start), positions/velocities/accelerations [n, dof]."""

    start: float
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray | None
    accelerations: np.ndarray | None

    @property
    def end(self) -> float:
        return self.start + float(self.times[-1])


def build_trajectory(
    joint_names, expected_names, start: float, times, positions, velocities=None, accelerations=None
) -> JointTrajectory:
    """Validate a received trajectory and order its columns as ``expected_names``.

    Raises InvalidInputError with the reason (wrong names/count, empty,
    non-increasing times, mismatched sizes, non-finite values).
    """
    names = list(joint_names)
    expected = list(expected_names)
    if sorted(names) != sorted(expected) or len(set(names)) != len(names):
        raise InvalidInputError(f"joint names must be exactly {expected} (any order), got {names}")
    order = [names.index(n) for n in expected]
    times = np.asarray(times, dtype=float)
    if times.ndim != 1 or times.size == 0:
        raise InvalidInputError("trajectory has no points")
    if not np.isfinite(times).all() or times[0] < 0 or (np.diff(times) <= 0).any():
        raise InvalidInputError("time_from_start must be finite, >= 0 and strictly increasing")

    def table(values, what):
        if values is None:
            return None
        if isinstance(values, np.ndarray) and values.ndim == 2:  # already a table (decoded from CDR)
            if values.shape[1] != len(names):
                raise InvalidInputError(f"every point needs {len(names)} {what}")
            arr = values.astype(float, copy=False)[:, order]
            if not np.isfinite(arr).all():
                raise InvalidInputError(f"non-finite {what}")
            return arr
        rows = [list(v) for v in values]
        if all(len(r) == 0 for r in rows):
            return None
        if any(len(r) != len(names) for r in rows):
            raise InvalidInputError(f"every point needs {len(names)} {what}")
        arr = np.asarray(rows, dtype=float)[:, order]
        if not np.isfinite(arr).all():
            raise InvalidInputError(f"non-finite {what}")
        return arr

    pos = table(positions, "positions")
    if pos is None or pos.shape[0] != times.size:
        raise InvalidInputError("every point needs positions")
    vel, acc = table(velocities, "velocities"), table(accelerations, "accelerations")
    if acc is not None and vel is None:
        raise InvalidInputError("accelerations given without velocities")
    return JointTrajectory(float(start), times, pos, vel, acc)


class TrajectoryFollower:
    """Holds the active trajectory and the state it replaced; samples commanded (p, v, a).

    Interpolation as joint_trajectory_controller's spline: linear with
    positions only, cubic with velocities, quintic with accelerations.
    """

    def __init__(self, initial_positions):
        self.hold(initial_positions)

    @property
    def active(self) -> JointTrajectory | None:
        return self._active

    def hold(self, positions) -> None:
        """Drop any trajectory and hold ``positions`` at rest (reset, e-stop)."""
        positions = np.asarray(positions, dtype=float).copy()
        self._active = None
        self._from = (positions, np.zeros_like(positions), np.zeros_like(positions))

    def replace(self, traj: JointTrajectory, now: float) -> JointTrajectory:
        """Make ``traj`` the running trajectory (start 0 = now); it departs from the
        state commanded at its start time. Returns the trajectory with its absolute start."""
        start = now if traj.start <= 0 else traj.start
        p, v, a = self.sample(np.array([start]))
        self._from = (p[0], v[0], a[0])
        self._active = JointTrajectory(start, traj.times, traj.positions, traj.velocities, traj.accelerations)
        return self._active

    def finished(self, now: float) -> bool:
        return self._active is None or now >= self._active.end

    def sample(self, times):
        """Commanded (positions, velocities, accelerations), each [n, dof], at absolute times [n] (s)."""
        times = np.atleast_1d(np.asarray(times, dtype=float))
        p0, v0, a0 = self._from
        p = np.tile(p0, (times.size, 1))
        v = np.tile(v0, (times.size, 1))
        a = np.tile(a0, (times.size, 1))
        traj = self._active
        if traj is None:
            return p, v, a
        # knots: the departure state at the start, then the points
        kt = np.concatenate([[traj.start], traj.start + traj.times])
        kp = np.vstack([p0, traj.positions])
        kv = None if traj.velocities is None else np.vstack([v0, traj.velocities])
        ka = None if traj.accelerations is None else np.vstack([a0, traj.accelerations])
        after = times >= kt[-1]
        p[after] = kp[-1]
        v[after] = 0.0 if kv is None else kv[-1]
        a[after] = 0.0 if ka is None else ka[-1]
        inside = (times >= kt[0]) & ~after
        if not inside.any():
            return p, v, a
        t = times[inside]
        seg = np.searchsorted(kt, t, side="right") - 1
        seg = np.clip(seg, 0, kt.size - 2)
        h = (kt[seg + 1] - kt[seg])[:, None]
        h = np.where(h > 0, h, 1.0)  # a first point at time 0 makes a zero-length segment
        s = np.clip((t - kt[seg])[:, None] / h, 0.0, 1.0)
        if kv is None:
            p[inside] = kp[seg] + s * (kp[seg + 1] - kp[seg])
            v[inside] = (kp[seg + 1] - kp[seg]) / h
            a[inside] = 0.0
        elif ka is None:
            p[inside], v[inside], a[inside] = cubic_hermite(s, h, kp[seg], kv[seg], kp[seg + 1], kv[seg + 1])
        else:
            p[inside], v[inside], a[inside] = quintic_hermite(
                s, h, kp[seg], kv[seg], ka[seg], kp[seg + 1], kv[seg + 1], ka[seg + 1]
            )
        return p, v, a
