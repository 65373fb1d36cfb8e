"""The sampling of a strut path l(t) (m over s) for the workspace check: a sub-grid (SUBGRID_S) with a bound on
every strut's travel within each sub-interval (the chord plus a_max h^2 / 8), split until no bound exceeds
PATH_SPACING_M / 2 (m), and the count of checked samples a path may need (MAX_PATH_SAMPLES).
"""

from __future__ import annotations

import numpy as np

from ..errors import UnreachablePoseError
from ..robot import Robot

PATH_SPACING_M = 2.5e-4  # bound on the strut travel between two neighbouring checked samples (m)
SUBGRID_S = 0.01  # time step of the sub-grid that bounds the travel (s)
MAX_SUBGRID = 200_000  # the sub-grid step grows beyond this many points (very long paths)
MAX_PATH_SAMPLES = 20_000  # a path needing more checked samples is refused (what one check may cost)


def half_travel(travel):
    """Per sample [n]: half the larger travel bound of its two intervals [n - 1] (m): how far the path strays
    from it (the nearer sample of every instant)."""
    return 0.5 * np.maximum(np.concatenate([travel, [0.0]]), np.concatenate([[0.0], travel]))


def check_sample_count(count: int, text: str, time: float) -> None:
    """Raise UnreachablePoseError "max_path_samples" (``text`` says why, at ``time`` s) beyond MAX_PATH_SAMPLES."""
    if count > MAX_PATH_SAMPLES:
        raise UnreachablePoseError(f"{text}; at most {MAX_PATH_SAMPLES}: send shorter trajectories",
                                   limit_name="max_path_samples", value=float(count), limit=float(MAX_PATH_SAMPLES),
                                   time=time)


def subgrid(robot: Robot, sample_lengths, start: float, end: float, knots, what: str):
    """(times [m], lengths [m, 6], travel bound of each sub-interval [m - 1]) with every bound <= PATH_SPACING_M / 2.

    Raises UnreachablePoseError "max_path_samples" when the path needs more than MAX_PATH_SAMPLES checked samples
    (from the first sub-grid already: before any FK)."""
    a_max = robot.limits.strut_acceleration_max
    span = max(end - start, 0.0)
    step = max(SUBGRID_S, span / MAX_SUBGRID)
    count = int(np.ceil(span / step)) if span > 0 else 0
    grid: list[np.ndarray] = [start + step * np.arange(count), np.array([end])]
    if knots is not None:
        k = np.asarray(knots, dtype=float)
        grid.append(k[(k > start) & (k < end)])
    times = np.unique(np.concatenate(grid))
    lengths = np.asarray(sample_lengths(times), dtype=float)
    if not np.isfinite(lengths).all():
        raise UnreachablePoseError("non-finite strut lengths along the path", limit_name="forward_kinematics",
                                   time=float(times[np.argmax(~np.isfinite(lengths).all(axis=1))]))
    bound = travel_bounds(times, lengths, a_max)
    needed = int(bound.sum() / (0.5 * PATH_SPACING_M)) + 2
    check_sample_count(needed, f"{what} needs {needed} workspace samples (its struts may travel {bound.sum():.3f} m)",
                 start)
    split = np.ceil(bound / (0.5 * PATH_SPACING_M)).astype(int)
    if (split > 1).any():  # fast sub-intervals: split each into `split` equal steps, sample once more
        pieces = np.maximum(split, 1)
        interval = np.repeat(np.arange(len(bound)), pieces)
        frac = (np.arange(int(pieces.sum())) - np.repeat(np.cumsum(pieces) - pieces, pieces)) / pieces[interval]
        times = np.concatenate([times[interval] + np.diff(times)[interval] * frac, times[-1:]])
        lengths = np.asarray(sample_lengths(times), dtype=float)
        bound = travel_bounds(times, lengths, a_max)
    return times, lengths, bound


def travel_bounds(times, lengths, a_max):
    """max over struts of |chord| + a_max h^2 / 8 per sub-interval: how far a strut can be from the interval's
    ends (its path deviates from the chord by at most a_max h^2 / 8)."""
    h = np.diff(times)
    return np.abs(np.diff(lengths, axis=0)).max(axis=1) + a_max * h * h / 8.0

