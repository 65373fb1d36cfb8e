"""Classify a platform vibration trajectory: still, line, ellipse, Lissajous or non-periodic.

The translational part (platform origin, base frame) is centred and its
principal axes taken (SVD): sigma_1 >= sigma_2 >= sigma_3 are RMS extents.
off_axis_ratio = sqrt(sigma_2^2 + sigma_3^2) / sigma_1 (0 for a line; b/a for
an ellipse with semi-axes a >= b); planarity = sigma_3 / sigma_1. A line has
off_axis_ratio < line_tol. Otherwise, one common frequency gives an ellipse,
commensurate frequencies a Lissajous figure (periodic), incommensurate ones
a non-periodic curve. The rotational content is reported separately: a
"line" with rotation is a rocking (screw) motion, not a pure translation.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from math import gcd, lcm

import numpy as np

from ..errors import InvalidInputError


@dataclass(frozen=True)
class MotionClassification:
    """kind: "still" | "line" | "ellipse" | "lissajous" | "non-periodic".

    principal_direction (3,) unit, base frame (sign: largest component > 0);
    plane_normal (3,); off_axis_ratio, planarity (dimensionless);
    translation_amplitude (m, half the peak-to-peak extent along the principal
    direction); rotation_amplitude (rad, peak |dphi - mean|); rotational_ratio
    = RMS |dphi| L / RMS |dp| with L the characteristic length (m);
    frequencies (Hz, distinct active); periodic, period (s or None).
    """

    kind: str
    principal_direction: np.ndarray
    plane_normal: np.ndarray
    off_axis_ratio: float
    planarity: float
    translation_amplitude: float
    rotation_amplitude: float
    rotational_ratio: float
    frequencies: np.ndarray
    periodic: bool
    period: float | None

    def summary(self) -> str:
        """One line: kind, principal direction (base frame), off-axis ratio, amplitude (um), rotation (urad)."""
        d = self.principal_direction
        return (f"{self.kind}: direction [{d[0]:+.4f}, {d[1]:+.4f}, {d[2]:+.4f}], "
                f"off-axis {self.off_axis_ratio:.3g}, amplitude {self.translation_amplitude * 1e6:.4g} um, "
                f"rotation {self.rotation_amplitude * 1e6:.4g} urad")


def distinct_frequencies(frequencies, rtol: float = 1e-9) -> np.ndarray:
    """Sorted distinct positive frequencies (Hz), merging values within rtol.

    Args:
        frequencies: frequencies (Hz), any shape; values <= 0 are dropped.
        rtol: relative tolerance under which neighbouring sorted values are merged (the smaller is kept).

    Returns:
        Distinct positive frequencies [m] (Hz), ascending; empty if none is positive.
    """
    f = np.sort(np.asarray(frequencies, dtype=float).ravel())
    f = f[f > 0]
    if f.size == 0:
        return f
    keep = np.concatenate([[True], np.diff(f) > rtol * f[1:]])
    return f[keep]


def common_period(frequencies, max_denominator: int = 32, rtol: float = 1e-9) -> float | None:
    """Smallest T (s) with f_i T integer for all f_i, if the ratios are small rationals; else None.

    Args:
        frequencies: frequencies (Hz), any shape; only distinct positive ones count.
        max_denominator: largest denominator accepted for the ratios f_i / f_min.
        rtol: relative tolerance of the rational approximation of each ratio.

    Returns:
        The common period T (s), or None if there is no positive frequency or a ratio is not a
        rational with denominator <= ``max_denominator`` (within ``rtol``).
    """
    f = distinct_frequencies(frequencies)
    if f.size == 0:
        return None
    base = f[0]
    fractions = []
    for ratio in f / base:
        frac = Fraction(float(ratio)).limit_denominator(max_denominator)
        if abs(float(frac) - ratio) > rtol * ratio:
            return None
        fractions.append(frac)
    den = lcm(*(fr.denominator for fr in fractions))
    multiples = [fr.numerator * den // fr.denominator for fr in fractions]
    return den / (base * gcd(*multiples))


def _unit_sign(v: np.ndarray) -> np.ndarray:
    return v if v[np.argmax(np.abs(v))] >= 0 else -v


def classify_motion(
    displacement,
    frequencies=None,
    *,
    characteristic_length: float = 0.1,
    line_tol: float = 1e-2,
    still_tol: float = 1e-15,
) -> MotionClassification:
    """Classify sampled platform motion [N, 6] ([dp (m); dphi (rad)], base frame) or [N, 3] (dp only).

    Args:
        displacement: platform displacement [N, 6] ([dp (m); dphi (rad)], base frame) or [N, 3]
            (dp only), N >= 3.
        frequencies: the leg vibration frequencies (Hz) that drive it (zero amplitude legs excluded
            by the caller); None is treated as one frequency.
        characteristic_length: length L (m) for ``rotational_ratio`` = RMS |dphi| L / RMS |dp|.
        line_tol: off-axis ratio below which the motion is a "line".
        still_tol: RMS extent sigma_1 (m) at or below which the motion is "still".

    Returns:
        MotionClassification (kind, principal axes in the base frame, ratios, amplitudes in m and rad,
        distinct frequencies in Hz, period in s or None).

    Raises:
        InvalidInputError: ``displacement`` is not 2-D [N >= 3, 3 or 6].
    """
    x = np.asarray(displacement, dtype=float)
    if x.ndim != 2 or x.shape[1] not in (3, 6) or x.shape[0] < 3:
        raise InvalidInputError(f"displacement: expected [N >= 3, 3 or 6], got {list(x.shape)}")
    dp = x[:, :3] - x[:, :3].mean(axis=0)
    dphi = x[:, 3:] - x[:, 3:].mean(axis=0) if x.shape[1] == 6 else np.zeros_like(dp)
    _, sv, vt = np.linalg.svd(dp, full_matrices=False)
    sv = sv / np.sqrt(dp.shape[0])
    freqs = distinct_frequencies([] if frequencies is None else frequencies)
    period = common_period(freqs) if freqs.size else None
    periodic = freqs.size <= 1 or period is not None
    direction = _unit_sign(vt[0])
    normal = _unit_sign(vt[2])
    along = dp @ direction
    amplitude = 0.5 * float(along.max() - along.min())
    rms_dp = float(np.sqrt((dp**2).sum(axis=1).mean()))
    rms_dphi = float(np.sqrt((dphi**2).sum(axis=1).mean()))
    rotation_amplitude = float(np.sqrt((dphi**2).sum(axis=1)).max())
    if sv[0] <= still_tol:
        return MotionClassification("still", direction, normal, 0.0, 0.0, amplitude, rotation_amplitude,
                                    np.inf if rms_dphi > 0 else 0.0, freqs, True, period)
    off_axis = float(np.hypot(sv[1], sv[2]) / sv[0])
    planarity = float(sv[2] / sv[0])
    if off_axis < line_tol:
        kind = "line"
    elif freqs.size <= 1:
        kind = "ellipse"
    elif periodic:
        kind = "lissajous"
    else:
        kind = "non-periodic"
    return MotionClassification(
        kind=kind, principal_direction=direction, plane_normal=normal, off_axis_ratio=off_axis,
        planarity=planarity, translation_amplitude=amplitude, rotation_amplitude=rotation_amplitude,
        rotational_ratio=rms_dphi * characteristic_length / rms_dp, frequencies=freqs,
        periodic=bool(periodic), period=period if freqs.size > 1 else (1.0 / freqs[0] if freqs.size else None),
    )
