"""The vibration units as identified on the robot (pure): each unit's response to its own demand and the
platform's 6-DOF response to each unit, per identified frequency, with their quality; the calibration file
the planner loads; the response between identified frequencies.

Frames and units: demands and unit displacements in m along the leg; the platform response [dp (m); dphi
(rad)] in the base frame at the platform origin, per m of demand. Complex amplitudes follow
x = |c| sin(2 pi f t + arg c). The file is YAML (complex values as [real, imag]), written by the
identification and read by the planner; nothing in it comes from the plant's truth.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from ..errors import InvalidInputError
from ..safe_yaml import load_yaml

FILE_KIND = "stewart_vibration/vibration_identification"
MIN_COHERENCE = 0.95  # a unit's own response below this is not trusted
MAX_RELATIVE_UNCERTAINTY = 0.02  # standard error of a response column per its magnitude


@dataclass(frozen=True)
class VibrationIdentification:
    """An identification at one pose (see the module docstring for frames and units).

    pose (6,) [m, rad]: where it was made; frequencies (F,) Hz, increasing; amplitude_m: the excitation's
    demand amplitude; unit_response (F, 6) complex: each unit's displacement per demand;
    platform_response (F, 6, 6) complex [frequency, platform DOF, unit]; *_coherence in [0, 1] and
    *_uncertainty (standard errors, same shapes and units as the responses); provenance: free text
    (date, plant-independent facts of how it was made).
    """

    pose: np.ndarray
    frequencies: np.ndarray
    amplitude_m: float
    unit_response: np.ndarray
    unit_coherence: np.ndarray
    unit_uncertainty: np.ndarray
    platform_response: np.ndarray
    platform_coherence: np.ndarray
    platform_uncertainty: np.ndarray
    provenance: dict = field(default_factory=dict)

    def __post_init__(self):
        f = np.asarray(self.frequencies, dtype=float)
        n = f.size
        shapes = {"pose": (6,), "unit_response": (n, 6), "unit_coherence": (n, 6), "unit_uncertainty": (n, 6),
                  "platform_response": (n, 6, 6), "platform_coherence": (n, 6, 6),
                  "platform_uncertainty": (n, 6, 6)}
        for name, shape in shapes.items():
            value = np.asarray(getattr(self, name))
            if value.shape != shape or not np.isfinite(value).all():
                raise InvalidInputError(f"identification: {name} must be finite with shape {shape}, got "
                                        f"{value.shape}")
        if n < 1 or not np.isfinite(f).all() or np.any(np.diff(f) <= 0) or f[0] <= 0:
            raise InvalidInputError("identification: frequencies must be positive and increasing")

    def unit_response_at(self, frequency: float) -> np.ndarray:
        """Each unit's response (6,) complex at ``frequency`` (Hz), interpolated between identified ones."""
        return interpolate_response(self.frequencies, self.unit_response, frequency)

    def platform_response_at(self, frequency: float) -> np.ndarray:
        """The platform's response (6, 6) complex [DOF, unit] at ``frequency`` (Hz), interpolated."""
        return interpolate_response(self.frequencies, self.platform_response, frequency)


def interpolate_response(frequencies, responses, frequency: float) -> np.ndarray:
    """Complex responses (F, ...) at ``frequency`` (Hz): magnitude and unwrapped phase each linear between
    the two identified frequencies around it (a resonance between them is smoothed, so identify densely
    enough around the band used).

    Raises:
        InvalidInputError: ``frequency`` outside the identified range (no extrapolation).
    """
    f = np.asarray(frequencies, dtype=float)
    h = np.asarray(responses, dtype=complex)
    if not (f[0] - 1e-9 <= frequency <= f[-1] + 1e-9):
        raise InvalidInputError(f"{frequency:g} Hz is outside the identified band {f[0]:g}-{f[-1]:g} Hz: "
                                "identify the vibration units over it first")
    if f.size == 1:
        return h[0].copy()
    k = int(np.clip(np.searchsorted(f, frequency) - 1, 0, f.size - 2))
    x = (frequency - f[k]) / (f[k + 1] - f[k])
    magnitude = (1 - x) * np.abs(h[k]) + x * np.abs(h[k + 1])
    phase_k = np.angle(h[k])
    step = np.angle(h[k + 1] * np.conj(h[k]))  # the shorter way round
    return magnitude * np.exp(1j * (phase_k + x * step))


def quality_problems(ident: VibrationIdentification, min_coherence: float = MIN_COHERENCE,
                     max_relative_uncertainty: float = MAX_RELATIVE_UNCERTAINTY) -> list[str]:
    """Why ``ident`` must not be used ([] when it may): a unit whose own response has a coherence below
    ``min_coherence``, or a response (a unit's own, or a unit's platform column) whose standard error exceeds
    ``max_relative_uncertainty`` of its magnitude, named with the frequency."""
    problems = []
    for k, f in enumerate(ident.frequencies):
        for i in range(6):
            coherence = ident.unit_coherence[k, i]
            if coherence < min_coherence:
                problems.append(f"unit {i + 1} at {f:g} Hz: coherence {coherence:.3f} < {min_coherence:g} "
                                "(noise or a non-linear response: a larger excitation, or more periods)")
            own = float(abs(ident.unit_response[k, i]))
            if ident.unit_uncertainty[k, i] > max_relative_uncertainty * own:
                problems.append(f"unit {i + 1} at {f:g} Hz: response uncertain by "
                                f"{ident.unit_uncertainty[k, i] / max(own, 1e-300):.1%}")
            column = float(np.linalg.norm(ident.platform_response[k, :, i]))
            spread = float(np.linalg.norm(ident.platform_uncertainty[k, :, i]))
            if spread > max_relative_uncertainty * column:
                problems.append(f"platform response to unit {i + 1} at {f:g} Hz uncertain by "
                                f"{spread / max(column, 1e-300):.1%}")
    return problems


def _complex_lists(value) -> list:
    array = np.asarray(value, dtype=complex)
    return np.stack([array.real, array.imag], axis=-1).tolist()


def _complex_array(value, name: str) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.ndim < 1 or array.shape[-1] != 2:
        raise InvalidInputError(f"identification file: {name} must hold [real, imag] pairs")
    return array[..., 0] + 1j * array[..., 1]


def save_identification(path, ident: VibrationIdentification) -> Path:
    """Write ``ident`` to ``path`` (YAML); returns the path."""
    tree = {
        "kind": FILE_KIND, "version": 1, "provenance": dict(ident.provenance),
        "pose": np.asarray(ident.pose, float).tolist(), "frequencies_hz": np.asarray(ident.frequencies).tolist(),
        "amplitude_m": float(ident.amplitude_m),
        "unit_response": _complex_lists(ident.unit_response),
        "unit_coherence": np.asarray(ident.unit_coherence).tolist(),
        "unit_uncertainty": np.asarray(ident.unit_uncertainty).tolist(),
        "platform_response": _complex_lists(ident.platform_response),
        "platform_coherence": np.asarray(ident.platform_coherence).tolist(),
        "platform_uncertainty": np.asarray(ident.platform_uncertainty).tolist(),
    }
    path = Path(path)
    path.write_text(yaml.safe_dump(tree, sort_keys=False, width=120))
    return path


def load_identification(path) -> VibrationIdentification:
    """Read a file of ``save_identification``.

    Raises:
        ConfigError: the file cannot be read or is not safe YAML (safe_yaml.load_yaml).
        InvalidInputError: not an identification file, a missing key or a malformed value (named).
    """
    tree = load_yaml(path, "vibration identification")
    if not isinstance(tree, dict) or tree.get("kind") != FILE_KIND:
        raise InvalidInputError(f"{path}: not a vibration identification file (kind {FILE_KIND!r})")
    try:
        return VibrationIdentification(
            pose=np.asarray(tree["pose"], float), frequencies=np.asarray(tree["frequencies_hz"], float),
            amplitude_m=float(tree["amplitude_m"]),
            unit_response=_complex_array(tree["unit_response"], "unit_response"),
            unit_coherence=np.asarray(tree["unit_coherence"], float),
            unit_uncertainty=np.asarray(tree["unit_uncertainty"], float),
            platform_response=_complex_array(tree["platform_response"], "platform_response"),
            platform_coherence=np.asarray(tree["platform_coherence"], float),
            platform_uncertainty=np.asarray(tree["platform_uncertainty"], float),
            provenance=dict(tree.get("provenance") or {}))
    except KeyError as exc:
        raise InvalidInputError(f"{path}: identification file without {exc.args[0]!r}") from None
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{path}: malformed identification file: {exc}") from None


def load_identification_option(path: str | None) -> VibrationIdentification | None:
    """``load_identification`` of a node parameter's value; None for '' (no identification)."""
    return load_identification(path) if path else None
