"""The paper's section-4 cases recomputed with the corrected science (data for figures/tables).

Fig. 7 equivalents (superposition of six leg vibrations that differ in
frequency, phase or amplitude), Fig. 8/9 equivalents (decomposition at the
paper's pose: exact IK vs linear k_i delta and their difference, for the
paper's 1 um / 2 rad/s example and the clinical 35 Hz / 0.3 g), and the
paper's naive sum vs J^-1. Pure numpy; plotting lives in the CLI.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, cast

import numpy as np

from ..paper import (
    CLINICAL_ACCELERATION_G,
    CLINICAL_FREQUENCY_HZ,
    PAPER_AMPLITUDE_M,
    PAPER_FREQUENCY_HZ,
    PAPER_PHASE_RAD,
    paper_pose,
)
from ..robot import Robot
from .decompose import decompose_vibration
from .superpose import axis_angle, superpose_vibration

if TYPE_CHECKING:
    from .classify import MotionClassification

FIG7_AMPLITUDE_M = 20e-6
FIG7_FREQUENCY_HZ = 5.0
FIG7_CASES = {
    "7a": ("different frequencies, equal amplitude and phase",
           np.column_stack([np.full(6, FIG7_AMPLITUDE_M), np.arange(1.0, 7.0), np.zeros(6)])),
    "7b": ("different phases, equal amplitude and frequency",
           np.column_stack([np.full(6, FIG7_AMPLITUDE_M), np.full(6, FIG7_FREQUENCY_HZ), np.arange(6) * np.pi / 3])),
    "7c": ("different amplitudes, equal frequency and phase",
           np.column_stack([np.arange(1, 7) * 10e-6, np.full(6, FIG7_FREQUENCY_HZ), np.zeros(6)])),
}
NAIVE_DIRECTIONS = {
    "platform z (tibia axis)": [0.0, 0.0, 1.0],
    "platform x": [1.0, 0.0, 0.0],
    "platform y": [0.0, 1.0, 0.0],
    "platform [1, 1, 1]": [1.0, 1.0, 1.0],
}


def classification_dict(cls) -> dict:
    """A MotionClassification as a JSON-ready dict (amplitudes in m and rad, period in s).

    Args:
        cls: the MotionClassification.

    Returns:
        {"kind", "principal_direction" (3,) (base frame), "off_axis_ratio", "planarity",
        "translation_amplitude_m" (m), "rotation_amplitude_rad" (rad), "rotational_ratio", "periodic",
        "period_s" (s or None)}.
    """
    return {
        "kind": cls.kind, "principal_direction": cls.principal_direction, "off_axis_ratio": cls.off_axis_ratio,
        "planarity": cls.planarity, "translation_amplitude_m": cls.translation_amplitude,
        "rotation_amplitude_rad": cls.rotation_amplitude, "rotational_ratio": cls.rotational_ratio,
        "periodic": cls.periodic, "period_s": cls.period,
    }


def fig7_cases(robot: Robot) -> dict:
    """Superposition of the three Fig. 7 leg sets at the paper's pose (exact FK and J^-1).

    Args:
        robot: the robot.

    Returns:
        {"7a" | "7b" | "7c": {"label": str, "legs": (6, 3) [amplitude m, frequency Hz, phase rad],
        "result": SuperpositionResult (96 samples per period of the fastest leg)}}.

    Raises:
        VibrationLimitError, StrokeLimitError, ForwardKinematicsError: from ``superpose_vibration``, if
            the robot's vibration unit or stroke does not allow a leg set, or the FK fails.
    """
    pose = paper_pose(robot)
    out = {}
    for key, (label, table) in FIG7_CASES.items():
        result = superpose_vibration(robot, pose, table, samples_per_period=96)
        out[key] = {"label": label, "legs": table, "result": result}
    return out


def decomposition_case(robot: Robot, amplitude, acceleration_g, frequency, phase, periods: float = 2.0) -> dict:
    """Decomposition along the tibia axis at the paper's pose with exact and linear signals and FFT.

    Args:
        robot: the robot.
        amplitude: platform amplitude A (m), or None to use ``acceleration_g``.
        acceleration_g: peak platform acceleration (g), or None.
        frequency: vibration frequency (Hz).
        phase: vibration phase (rad).
        periods: number of periods sampled for ``plan`` and the differences.

    Returns:
        {"plan": VibrationDecomposition over ``periods`` periods, "difference": exact - linear leg
        signals [N, 6] (m), "predicted_difference": (1 - k_i^2) delta^2 / (2 l_i) [N, 6] (m),
        "fft_fundamental_m", "fft_second_harmonic_m", "fft_dc_m": [6] (m, from one period of 512
        samples of the exact signals), "predicted_second_harmonic_ratio" [6],
        "second_order_residual_ratio" (float), "roundtrip_angle_linear_rad" / "roundtrip_angle_exact_rad"
        (rad, principal direction of the superposed legs vs the planned direction),
        "roundtrip_rotation_linear_rad" / "roundtrip_rotation_exact_rad" (rad)}.

    Raises:
        InvalidInputError: a bad amplitude, acceleration or frequency (``decompose_vibration``).
        VibrationLimitError, UnreachablePoseError, StrokeLimitError, JointLimitError: from
            ``decompose_vibration`` / ``superpose_vibration``, if the robot's limits do not allow the case.
        ForwardKinematicsError: the round-trip FK (``superpose_vibration``) fails.
    """
    pose = paper_pose(robot)
    plan = decompose_vibration(robot, pose, amplitude=amplitude, acceleration_g=acceleration_g,
                               frequency=frequency, phase=phase, duration=periods / frequency)
    one = decompose_vibration(robot, pose, amplitude=amplitude, acceleration_g=acceleration_g,
                              frequency=frequency, phase=phase, samples_per_period=512)
    # exact_signals and classification_exact below: set by the default method "exact"
    spectrum = np.fft.rfft(cast(np.ndarray, one.exact_signals), axis=0) / one.times.size
    k, a, l0 = plan.gains, plan.amplitude, plan.nominal_lengths
    predicted = (1 - k**2) * plan.delta[:, None] ** 2 / (2 * l0)
    diff = plan.exact_signals - plan.linear_signals
    roundtrip = superpose_vibration(robot, pose, one, times=one.times)
    return {
        "plan": plan, "difference": diff, "predicted_difference": predicted,
        "fft_fundamental_m": 2 * np.abs(spectrum[1]), "fft_second_harmonic_m": 2 * np.abs(spectrum[2]),
        "fft_dc_m": spectrum[0].real,
        "predicted_second_harmonic_ratio": (1 - k**2) * a / (4 * l0 * np.abs(k)),
        "second_order_residual_ratio": float(np.abs(diff - predicted).max() / np.abs(predicted).max()),
        "roundtrip_angle_linear_rad": axis_angle(roundtrip.classification_linear.principal_direction, plan.direction),
        "roundtrip_angle_exact_rad": axis_angle(
            cast("MotionClassification", roundtrip.classification_exact).principal_direction, plan.direction),
        "roundtrip_rotation_linear_rad": float(np.abs(roundtrip.linear[:, 3:]).max()),
        "roundtrip_rotation_exact_rad": cast("MotionClassification", roundtrip.classification_exact).rotation_amplitude,
    }


def paper_case(robot: Robot) -> dict:
    """The paper's example: 1 um, 2 rad/s, phase 2 pi/3 along the tibia axis.

    ``decomposition_case`` for ``robot`` over 2 periods (its dict; its errors if the robot's limits
    do not allow the case).
    """
    return decomposition_case(robot, PAPER_AMPLITUDE_M, None, PAPER_FREQUENCY_HZ, PAPER_PHASE_RAD)


def clinical_case(robot: Robot) -> dict:
    """The clinical default: 35 Hz at 0.3 g (~61 um) along the tibia axis, phase 2 pi/3.

    ``decomposition_case`` for ``robot`` over 3 periods (its dict; its errors if the robot's limits
    do not allow the case).
    """
    return decomposition_case(robot, None, CLINICAL_ACCELERATION_G, CLINICAL_FREQUENCY_HZ, PAPER_PHASE_RAD, 3.0)


def naive_comparison(robot: Robot) -> dict:
    """The paper's sum_i n_i dl_i vs J^-1 dl for the legs that make a line along several directions.

    Each direction of NAIVE_DIRECTIONS (platform frame) is decomposed linearly with the paper's
    1 um, 2 rad/s, phase 2 pi/3 and superposed back over one period.

    Args:
        robot: the robot.

    Returns:
        {label: {"direction_base": planned unit direction (3,) (base frame), "naive_direction_base":
        principal axis (3,) of the naive sum (base frame, sign arbitrary), "length_ratio",
        "angle_error_rad" (rad), "result": SuperpositionResult, "plan": VibrationDecomposition}}.

    Raises:
        VibrationLimitError, UnreachablePoseError, StrokeLimitError, JointLimitError, ForwardKinematicsError:
            from ``decompose_vibration`` / ``superpose_vibration``, if the robot's limits do not allow a case.
    """
    pose = paper_pose(robot)
    out = {}
    for label, direction in NAIVE_DIRECTIONS.items():
        plan = decompose_vibration(robot, pose, direction=direction, amplitude=PAPER_AMPLITUDE_M,
                                   frequency=PAPER_FREQUENCY_HZ, phase=PAPER_PHASE_RAD, method="linear")
        result = superpose_vibration(robot, pose, plan, times=plan.times)
        err = result.naive_error()
        centred = result.naive - result.naive.mean(axis=0)
        naive_dir = np.linalg.svd(centred, full_matrices=False)[2][0]
        out[label] = {"direction_base": plan.direction, "naive_direction_base": naive_dir,
                      "length_ratio": err["length_ratio"], "angle_error_rad": err["angle_rad"],
                      "result": result, "plan": plan}
    return out
