"""The spline extremes against the splines themselves: every segment's sampled minimum, maximum, peak speed and
peak acceleration equal those of ``spline_segments`` (the per-point Hermite formulas) evaluated at the same
points -- quintic, cubic and mixed segments, uneven knots -- and a sinusoid's extremes are its closed form."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.splines import _segment_extremes, spline_extremes, spline_segments


def reference(t, p, v, a, samples, segments):
    """The same extremes from spline_segments at each segment's ends and ``samples`` points inside."""
    out = []
    for seg in segments:
        grid = t[seg] + (t[seg + 1] - t[seg]) * np.arange(samples + 2) / (samples + 1)
        pp, vv, aa = spline_segments(t, p, v, a, grid, np.full(grid.size, seg))
        out.append((pp.min(axis=0), pp.max(axis=0), np.abs(vv).max(axis=0), np.abs(aa).max(axis=0)))
    return tuple(np.array(column) for column in zip(*out, strict=True))


@pytest.mark.parametrize("kind", ["quintic", "cubic", "mixed"])
@pytest.mark.parametrize("samples", [4, 64])
def test_segment_extremes_match_the_splines_at_the_same_points(kind, samples):
    rng = np.random.default_rng(7)
    n, k = 40, 6
    t = np.cumsum(rng.uniform(0.5e-3, 2e-3, n))
    p, v = rng.normal(0, 1e-4, (n, k)), rng.normal(0, 1e-2, (n, k))
    a = None if kind == "cubic" else rng.normal(0, 3.0, (n, k))
    if kind == "mixed":
        a[rng.random(n) < 0.3] = np.nan
    segments = np.arange(n - 1) if samples == 4 else np.array([0, 5, 17, n - 2])
    got = _segment_extremes(t, p, v, a, samples, segments)
    for mine, theirs in zip(got, reference(t, p, v, a, samples, segments), strict=True):
        np.testing.assert_allclose(mine, theirs, rtol=1e-9, atol=1e-15)


def test_a_sampled_sinusoid_has_its_closed_form_extremes():
    amp, w = 30e-6, 2 * np.pi * 35.0
    t = np.arange(0.0, 1.0, 1e-3)
    p = amp * np.sin(w * t)[:, None]
    v = amp * w * np.cos(w * t)[:, None]
    a = -amp * w * w * np.sin(w * t)[:, None]
    low, high, speed, accel = spline_extremes(t, p, v, a)
    np.testing.assert_allclose([-low[0], high[0], speed[0], accel[0]], [amp, amp, amp * w, amp * w * w], rtol=2e-4)
