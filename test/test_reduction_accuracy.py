"""The fracture-site residual against closed forms: pure translation, pure twist, a tilt about the platform
origin that swings the site on a circle, and a twist combined with a tilt."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.analysis.reduction_accuracy import fracture_residual

SITE = np.array([0.0, 0.0, -0.060])
PLANNED = np.array([0.002, 0.002, 0.162, 0.2, 0.25, 0.17])


def rpy_after(planned_rpy, local_rotation):
    """rpy of R(planned) @ local_rotation (a rotation in the planned fragment's frame)."""
    from stewart_vibration.kinematics.rotations import rotation_from_rpy, rpy_from_rotation

    return rpy_from_rotation(rotation_from_rpy(planned_rpy) @ local_rotation)


def rot(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return {"x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]), "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]


def test_a_translation_is_all_displacement():
    reached = PLANNED + np.array([3e-4, -4e-4, 0.0, 0, 0, 0])
    r = fracture_residual(reached, PLANNED, SITE)
    assert r.displacement_m == pytest.approx(5e-4, abs=1e-12)
    assert r.angulation_rad == pytest.approx(0.0, abs=1e-12) and r.rotation_rad == pytest.approx(0.0, abs=1e-12)


def test_a_twist_about_the_tibia_axis_is_rotation_only():
    reached = PLANNED.copy()
    reached[3:] = rpy_after(PLANNED[3:], rot("z", np.radians(2.0)))
    r = fracture_residual(reached, PLANNED, SITE)
    assert r.rotation_rad == pytest.approx(np.radians(2.0), abs=1e-10)
    assert r.displacement_m == pytest.approx(0.0, abs=1e-12) and r.angulation_rad == pytest.approx(0.0, abs=1e-10)


def test_a_tilt_about_the_platform_origin_swings_the_site_on_a_circle():
    alpha = np.radians(1.5)
    reached = PLANNED.copy()
    reached[3:] = rpy_after(PLANNED[3:], rot("x", alpha))
    r = fracture_residual(reached, PLANNED, SITE)
    assert r.angulation_rad == pytest.approx(alpha, abs=1e-10)
    assert r.displacement_m == pytest.approx(2 * 0.060 * np.sin(alpha / 2), abs=1e-12)  # chord of the circle
    assert r.rotation_rad == pytest.approx(0.0, abs=1e-10)


def test_twist_and_tilt_are_told_apart():
    reached = PLANNED.copy()
    reached[3:] = rpy_after(PLANNED[3:], rot("x", np.radians(1.0)) @ rot("z", np.radians(3.0)))  # swing, then twist
    r = fracture_residual(reached, PLANNED, SITE)
    assert r.angulation_rad == pytest.approx(np.radians(1.0), abs=1e-10)
    assert r.rotation_rad == pytest.approx(np.radians(3.0), abs=1e-10)
