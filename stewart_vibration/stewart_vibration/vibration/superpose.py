"""Superposition: six leg vibrations -> platform motion (exact FK and linear J^-1).

Leg i vibrates by dl_i(t) = A_i sin(2 pi f_i t + phase_i) about its nominal
length at the pose. The platform motion is the forward kinematics of
l0 + dl(t) (exact; batched Newton, every sample warm-started from its
linear prediction) and, to first order, dx = J^-1 dl ([dp; dphi], base
frame). The paper's "superposition" sum_i n_i dl_i applies the force map to
displacements and is wrong (an error of the paper); it is computed only as a labelled
comparison (``naive``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from ..input_checks import as_batch
from ..kinematics import forward_kinematics
from ..kinematics.rotations import rotation_from_rpy, rpy_from_rotation, so3_exp, so3_log
from ..robot import Robot
from .classify import MotionClassification, classify_motion, common_period, distinct_frequencies
from .decompose import VibrationDecomposition
from .feasibility import check_frequency, check_leg_peaks
from .screw import nominal_leg_geometry


@dataclass(frozen=True)
class SuperpositionResult:
    """Platform motion produced by six leg vibrations (SI units, base frame).

    legs (6, 3) [amplitude m (signed allowed), frequency Hz, phase rad];
    times (N,, s); leg_changes (N, 6) dl_i (m); linear (N, 6) J^-1 dl
    [dp m; dphi rad]; exact (N, 6) FK displacement [p - p0; log(R R0^T)] or
    None; poses (N, 6) exact platform poses or None; naive (N, 3) the paper's
    sum_i n_i dl_i (m, wrong, comparison only); classification_linear /
    classification_exact; fk_iterations (max Newton iterations over samples),
    fk_residual (max |l(pose) - l| in m).
    """

    pose: np.ndarray
    legs: np.ndarray
    times: np.ndarray
    leg_changes: np.ndarray
    linear: np.ndarray
    exact: np.ndarray | None
    poses: np.ndarray | None
    naive: np.ndarray
    classification_linear: MotionClassification
    classification_exact: MotionClassification | None
    fk_iterations: int
    fk_residual: float

    @property
    def classification(self) -> MotionClassification:
        """The exact classification if computed, else the linear one."""
        return self.classification_exact or self.classification_linear

    def naive_error(self) -> dict:
        """The paper's naive sum vs J^-1: peak length ratio and principal-direction angle (rad)."""
        return compare_naive(self.naive, self.linear[:, :3])


def axis_angle(a, b) -> float:
    """Angle (rad, in [0, pi/2]) between the lines spanned by a and b (sign-free, accurate near 0).

    Args:
        a: a non-zero direction (3,), any length.
        b: a non-zero direction (3,), any length.

    Returns:
        The angle atan2(|a x b|, |a . b|) (rad, in [0, pi/2]).
    """
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.arctan2(np.linalg.norm(np.cross(a, b)), abs(a @ b)))


def compare_naive(naive, reference) -> dict:
    """{"length_ratio", "angle_rad"}: naive vs reference translation [N, 3] by principal axes.

    Each trajectory is centred; its size is the largest distance of a sample from the mean and its
    direction the first principal axis (SVD).

    Args:
        naive: the paper's naive platform translation [N, 3] (m, base frame).
        reference: the reference translation, e.g. J^-1 dl, [N, 3] (m, base frame).

    Returns:
        {"length_ratio": naive size / reference size, "angle_rad": angle between the two principal
        axes (rad, in [0, pi/2])}.
    """
    out = {}
    dirs, sizes = [], []
    for traj in (np.asarray(naive), np.asarray(reference)):
        centred = traj - traj.mean(axis=0)
        _, sv, vt = np.linalg.svd(centred, full_matrices=False)
        dirs.append(vt[0])
        sizes.append(np.sqrt((centred**2).sum(axis=1)).max())
    out["length_ratio"] = float(sizes[0] / sizes[1])
    out["angle_rad"] = axis_angle(dirs[0], dirs[1])
    return out


def leg_table(legs) -> np.ndarray:
    """(6, 3) [amplitude m, frequency Hz, phase rad] from an array or a VibrationDecomposition.

    Args:
        legs: a (6, 3) array [amplitude (m), frequency (Hz), phase (rad)] per leg, or a
            VibrationDecomposition (its ``leg_vibrations``).

    Returns:
        The (6, 3) table [amplitude m, frequency Hz, phase rad].

    Raises:
        InvalidInputError: ``legs`` is not numeric, not finite, not of shape (6, 3), or has a frequency <= 0.
    """
    if isinstance(legs, VibrationDecomposition):
        return legs.leg_vibrations
    table = as_batch(legs, 3, "legs")
    if table.shape != (6, 3):
        raise InvalidInputError(f"legs: expected (6, 3) [amplitude, frequency, phase], got {list(table.shape)}")
    if (table[:, 1] <= 0).any():
        raise InvalidInputError("legs: frequencies must be > 0 Hz")
    return table


def default_superposition_times(table: np.ndarray, duration=None, samples_per_period: int = 64) -> np.ndarray:
    """Sample times (s) over the common period (or ``duration``; 20 slowest periods if none).

    Only legs with a non-zero amplitude count (all legs if none has one).

    Args:
        table: leg table (6, 3) [amplitude m, frequency Hz, phase rad].
        duration: time span to sample (s); None: the common period of the frequencies, or 20 periods
            of the slowest one if they have none.
        samples_per_period: samples per period of the fastest frequency (the step is
            1 / (f_max samples_per_period)).

    Returns:
        Uniform sample times [M] (s) from 0, covering ``duration`` with the endpoint excluded.
    """
    active = table[table[:, 0] != 0]
    freqs = active[:, 1] if active.size else table[:, 1]
    if duration is None:
        period = common_period(freqs)
        duration = period if period is not None else 20.0 / freqs.min()
    step = 1.0 / (freqs.max() * samples_per_period)
    count = int(np.ceil(duration / step - 1e-9))
    return np.arange(count) * step


def naive_superposition(robot: Robot, pose, leg_changes) -> np.ndarray:
    """The paper's sum_i n_i dl_i [N, 3] (m, base frame). WRONG physics, for comparison only.

    Args:
        robot: the robot.
        pose: nominal platform pose (6,) [x, y, z, roll, pitch, yaw] (m, rad), base frame.
        leg_changes: leg-length changes dl [N, 6] (m).

    Returns:
        sum_i n_i dl_i [N, 3] (m, base frame), n_i the unit leg directions at ``pose``.

    Raises:
        InvalidInputError: ``pose`` is not numeric, not finite or not [..., 6].
    """
    d0, _, l0, _ = nominal_leg_geometry(robot, as_batch(pose, 6, "pose"))
    return np.asarray(leg_changes) @ (d0 / l0[:, None])


def superpose_vibration(
    robot: Robot,
    pose,
    legs,
    times=None,
    *,
    duration: float | None = None,
    samples_per_period: int = 64,
    method: str = "exact",
    check_limits: bool = True,
    line_tol: float = 1e-2,
    fk_tol: float | None = None,
) -> SuperpositionResult:
    """Platform motion from six leg vibrations at ``pose`` (m, rad).

    Leg i vibrates by dl_i(t) = A_i sin(2 pi f_i t + phase_i); the platform moves by dx = J^-1 dl to
    first order, and method "exact" adds batched FK of l0 + dl (Newton warm-started from the linear
    prediction of every sample); "linear" gives only J^-1 dl.

    Args:
        robot: the robot.
        pose: nominal platform pose (6,) [x, y, z, roll, pitch, yaw] (m, rad), base frame.
        legs: (6, 3) [amplitude (m), frequency (Hz), phase (rad)] per leg (a negative amplitude is the
            same as phase + pi), or a VibrationDecomposition.
        times: sample times [N] (s), N >= 3; default the common period of the active leg frequencies
            (``default_superposition_times``).
        duration: time span (s) sampled when ``times`` is None.
        samples_per_period: samples per period of the fastest leg frequency when ``times`` is None.
        method: "exact" or "linear".
        check_limits: check the leg vibrations against the vibration unit and the FK lengths against
            the stroke.
        line_tol: off-axis ratio below which the motion is classified as a line.
        fk_tol: FK tolerance (m); default 1e-9 of the largest leg amplitude, at least 1e-15.

    Returns:
        SuperpositionResult (base frame, SI units): ``leg_changes`` [N, 6] (m), ``linear`` [N, 6]
        [dp m; dphi rad], ``exact`` [N, 6] and ``poses`` [N, 6] (None for "linear"), ``naive`` [N, 3] (m),
        and the linear / exact classifications.

    Raises:
        InvalidInputError: ``method`` unknown; ``pose`` not finite [..., 6]; ``legs`` malformed
            (``leg_table``); ``times`` not a finite 1-D array of at least 3 samples; a leg length <= 0.
        VibrationLimitError: with ``check_limits``, an active leg frequency is outside the unit's band,
            or a leg's peak amplitude |A_i| or acceleration |A_i| (2 pi f_i)^2 exceeds the unit's limit.
        StrokeLimitError: method "exact" with ``check_limits``, a vibrating leg length l0 + dl leaves
            the stroke.
        ForwardKinematicsError: method "exact", the FK of a sample did not converge or found another
            assembly mode.
    """
    if method not in ("exact", "linear"):
        raise InvalidInputError(f"method must be 'exact' or 'linear', got {method!r}")
    pose = as_batch(pose, 6, "pose")
    table = leg_table(legs)
    amplitudes, freqs, phases = table[:, 0], table[:, 1], table[:, 2]
    active = amplitudes != 0
    if check_limits:
        for f in distinct_frequencies(freqs[active]):
            check_frequency(robot, f)
        check_leg_peaks(robot, np.abs(amplitudes), np.abs(amplitudes) * (2 * np.pi * freqs) ** 2)
    t = default_superposition_times(table, duration, samples_per_period) if times is None else np.asarray(times)
    if t.ndim != 1 or t.size < 3 or not np.isfinite(t).all():
        raise InvalidInputError("times must be a finite 1-D array of at least 3 samples (s)")
    dl = amplitudes * np.sin(2 * np.pi * freqs * t[:, None] + phases)
    _, _, l0, jac = nominal_leg_geometry(robot, pose)
    linear = np.linalg.solve(jac, dl.T).T
    classify_kw = dict(characteristic_length=robot.characteristic_length, line_tol=line_tol)
    active_freqs = freqs[active]
    exact = poses = None
    iterations, residual = 0, 0.0
    if method == "exact":
        rot0 = rotation_from_rpy(pose[3:])
        guess_rot = so3_exp(linear[:, 3:]) @ rot0
        guess = np.concatenate([pose[:3] + linear[:, :3], rpy_from_rotation(guess_rot)], axis=-1)
        tol = fk_tol if fk_tol is not None else max(1e-15, 1e-9 * float(np.abs(amplitudes).max()))
        fk = forward_kinematics(robot, l0 + dl, guess=guess, tol=tol, check_limits=check_limits)
        fk.raise_for_failure()
        exact = np.concatenate([fk.pose[:, :3] - pose[:3], so3_log(fk.rotation @ rot0.T)], axis=-1)
        poses = fk.pose
        iterations, residual = int(fk.iterations.max()), float(fk.residual.max())
    return SuperpositionResult(
        pose=pose.copy(), legs=table, times=t, leg_changes=dl, linear=linear, exact=exact, poses=poses,
        naive=naive_superposition(robot, pose, dl),
        classification_linear=classify_motion(linear, active_freqs, **classify_kw),
        classification_exact=None if exact is None else classify_motion(exact, active_freqs, **classify_kw),
        fk_iterations=iterations, fk_residual=residual,
    )
