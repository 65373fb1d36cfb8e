"""The run report's streaming reducers (analysis.report_scan) against the whole series at once: the same result
whatever the batches, the envelope's strokes covering every sample between its min and max, the activity span
and the leg-force error equal to the direct computations (fits.force_error, the threshold over all samples)."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.analysis.fits import force_error
from stewart_vibration.analysis.report_scan import ForceErrorScan, StreamEnvelope, VibrationActivity
from stewart_vibration.errors import InvalidInputError

RNG = np.random.default_rng(7)


def batches(n: int, pieces: int):
    """Random cuts of range(n) into consecutive batches (some empty, some of one sample)."""
    cuts = np.sort(RNG.integers(0, n + 1, pieces))
    return list(zip(np.r_[0, cuts], np.r_[cuts, n], strict=True))


def fed(reducer_add, t, y, pieces):
    for a, b in batches(t.size, pieces):
        reducer_add(t[a:b], y[a:b])


@pytest.mark.parametrize("n", [1, 3999, 4000, 4001, 12_345, 300_000])
def test_the_envelope_is_the_same_for_any_batches_and_holds_every_sample(n):
    t = np.arange(n) / 500.0
    y = np.column_stack([np.sin(2 * np.pi * 35 * t), RNG.normal(size=n)])
    if n > 10:
        y[n // 3, 1], y[n // 2, 0] = 50.0, np.nan  # a spike stays drawn; a NaN is left out of min and max
    whole = StreamEnvelope(2)
    whole.add(t, y)
    tw, yw = whole.result()
    for pieces in (1, 7, 200):
        env = StreamEnvelope(2)
        fed(env.add, t, y, pieces)
        te, ye = env.result()
        np.testing.assert_array_equal(te, tw)
        np.testing.assert_array_equal(ye, yw)
        assert env.samples == n
    if n <= 4000:  # few samples: the series itself
        np.testing.assert_array_equal(tw, t)
        np.testing.assert_array_equal(yw, y)
        return
    strokes = yw.shape[0] // 2
    assert 2000 <= strokes <= 4000 and np.all(np.diff(tw) >= 0)
    # each stroke spans exactly its run of k samples (the last one what is left)
    k = whole.k
    for s in range(strokes):
        run = y[s * k:(s + 1) * k]
        np.testing.assert_array_equal(yw[2 * s], np.nanmin(run, axis=0))
        np.testing.assert_array_equal(yw[2 * s + 1], np.nanmax(run, axis=0))
        assert t[s * k] <= tw[2 * s] <= t[min((s + 1) * k, n - 1)]
    assert np.nanmax(yw[:, 1]) == 50.0


@pytest.mark.parametrize("kind", ["vibration", "none", "ramps"])
def test_the_activity_span_is_the_threshold_over_all_samples(kind):
    t = np.arange(20_000) / 500.0
    vib = np.zeros((t.size, 6))
    if kind != "none":
        envelope = np.clip((t - 10) / 0.2, 0, 1) * np.clip((30 - t) / 0.2, 0, 1) if kind == "ramps" else \
            ((t > 10) & (t < 30)).astype(float)
        vib = envelope[:, None] * 5e-5 * np.sin(2 * np.pi * 35 * t[:, None] + np.arange(6))
        vib += 1e-7 * RNG.normal(size=vib.shape)  # sensor noise, below the threshold
    level = np.abs(vib).max(axis=1)
    active = np.flatnonzero(level > 0.02 * level.max()) if level.max() > 0 else []
    expected = (t[active[0]], t[active[-1]]) if len(active) and kind != "none" else None
    for pieces in (1, 5, 300):
        activity = VibrationActivity()
        fed(activity.add, t, vib, pieces)
        span = activity.span()
        assert span == expected  # none: the units never moved
        assert activity.rising.size + activity.falling.size < 3000  # not every sample is kept


def test_the_leg_force_error_is_force_errors_over_the_whole_run():
    tm = np.arange(5_000) / 500.0 + 0.0003
    te = np.arange(4_990) / 500.0 + 0.01  # the estimates start later and end earlier than the measurements
    measured = 40 + 3 * np.sin(2 * np.pi * 35 * tm[:, None] + np.arange(6))
    estimated = 40.4 + 3 * np.sin(2 * np.pi * 35 * te[:, None] + np.arange(6)) + 0.1 * RNG.normal(size=(te.size, 6))
    expected = force_error(te, estimated, tm, measured, None)
    for pieces in (1, 9, 400):
        scan = ForceErrorScan()
        estimate_cuts, measured_cuts = batches(te.size, pieces), batches(tm.size, pieces)
        for (a, b), (c, d) in zip(estimate_cuts, measured_cuts, strict=True):  # interleaved, as topics flush
            scan.add_measured(tm[c:d], measured[c:d])
            scan.add_estimates(te[a:b], estimated[a:b])
        got = scan.result()
        assert got is not None and got["samples"] == expected["samples"]
        for key in ("rms_error_n", "force_amplitude_n", "relative_rms_error"):
            np.testing.assert_allclose(got[key], expected[key], rtol=1e-12)


def test_without_overlap_the_force_error_is_refused_and_without_estimates_there_is_none():
    scan = ForceErrorScan()
    scan.add_measured(np.arange(10.0), np.zeros((10, 6)))
    assert scan.result() is None
    scan.add_estimates(np.arange(20.0, 30.0), np.zeros((10, 6)))
    with pytest.raises(InvalidInputError):
        scan.result()
