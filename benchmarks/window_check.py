"""What checking one vibration window against the units' limits costs (``vibration.feasibility.check_command_limits``:
the Hermite spline's extremes, sampled at each segment's ends and 4 points inside, 64 where a limit is near): the
emulator runs it on every window it takes, and the estimator too (it refuses what the robot would). A window as
the planner sends one: 2.3 s of 35 Hz vibration at 1 kHz, six units, quintic (positions, velocities,
accelerations), at 0.3 g; then at 95 % of the displacement limit (every segment refined).

Each is timed through the check as it runs now (the Hermite basis evaluated once for the segments' common sample
points, each segment a weighted sum of its knot terms) and through evaluating the per-point Hermite formulas
(``splines.spline_segments``) on the same points, as the check did before. Best and median of --repeats, ms.

Run: .venv/bin/python benchmarks/window_check.py [--repeats 15] [--json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

from stewart_vibration import load_robot
from stewart_vibration.splines import REFINED_SAMPLES, SAMPLES_PER_SEGMENT, spline_segments
from stewart_vibration.vibration.feasibility import check_command_limits


def window(acceleration: float, seconds: float = 2.3, hz: float = 35.0, dt: float = 1e-3):
    """(times, positions, velocities, accelerations) of a six-unit sine window of peak ``acceleration`` m/s^2."""
    t = np.arange(0.0, seconds, dt)
    w = 2 * np.pi * hz
    amp = acceleration / w**2 * np.linspace(0.8, 1.0, 6)
    phase = np.linspace(0, np.pi, 6)
    arg = w * t[:, None] + phase
    return t, amp * np.sin(arg), amp * w * np.cos(arg), -amp * w * w * np.sin(arg)


def per_point(t, p, v, a, samples: int) -> tuple:
    """The extremes from the per-point formulas on every segment's ends and ``samples`` points inside."""
    seg = np.arange(t.size - 1)
    frac = np.arange(samples + 2) / (samples + 1)
    grid = (t[seg, None] + (t[seg + 1] - t[seg])[:, None] * frac).ravel()
    pp, vv, aa = spline_segments(t, p, v, a, grid, np.repeat(seg, samples + 2))
    shape = (seg.size, samples + 2, -1)
    return pp.reshape(shape).min(axis=1), np.abs(vv).reshape(shape).max(axis=1), np.abs(aa).reshape(shape).max(axis=1)


def timed(fn, repeats: int) -> dict:
    runs = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        runs.append((time.perf_counter() - start) * 1e3)
    return {"best_ms": min(runs), "median_ms": statistics.median(runs)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    limits = load_robot().vibration_unit
    rows = {}
    for name, accel, samples in (("0.3 g", 0.3 * 9.80665, SAMPLES_PER_SEGMENT),
                                 ("near the limit", 0.95 * limits.amplitude_max * (2 * np.pi * 35.0) ** 2,
                                  REFINED_SAMPLES)):
        t, p, v, a = window(accel)
        now = timed(lambda t=t, p=p, v=v, a=a: check_command_limits(limits, t, p, v, a), args.repeats)
        before = timed(lambda t=t, p=p, v=v, a=a, s=samples: per_point(t, p, v, a, s), args.repeats)
        rows[name] = {"check": now, "per_point_formulas": before,
                      "speedup": before["median_ms"] / now["median_ms"]}
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    for name, row in rows.items():
        print(f"{name:>15}: check {row['check']['best_ms']:7.2f} ms best / {row['check']['median_ms']:7.2f} median; "
              f"per-point formulas {row['per_point_formulas']['median_ms']:7.2f} ms median; "
              f"{row['speedup']:.1f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
