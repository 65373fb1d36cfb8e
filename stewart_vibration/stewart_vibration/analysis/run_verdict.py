"""The verdict on a suite run (pure: no rclpy): every figure of the run summary against the scenario's bounds.

The figures come from ``vibration_figures``, ``tissue_figures`` and ``run_coverage`` (the moves' pose errors
after settling from the runner's record); the robot's limits over the recorded states from ``limit_check``.
Bounds in SI units, deg for angles.
"""

from __future__ import annotations

import numpy as np

from ..robot import Robot


def check_bounds(summary: dict, bounds: dict) -> list[str]:
    """Human-readable list of every figure that missed its bound (empty = all passed).

    Every figure the run summary prints is judged here: pose errors after moves; per vibration the
    platform's direction, amplitude and off-axis ratio, every leg's amplitude, phase (and its sign) and
    frequency, the same platform figures and leg amplitudes in the controller's view (``controller_view``), the
    active duration and every leg's force error (the worst); with a tissue the wrench
    estimate and the guard trips; the robot's limits over the recorded states (``limit_check``); the sample
    ratio of every derived stream and, per node, its lost input states and its lag.

    Args:
        summary: the run summary ("moves", "vibrations", optional "tissue", "limits" (``limit_summary``) and
            "streams").
        bounds: the scenario's bounds (SI units, deg for angles); wrench_error_relative (0.02),
            wrench_error_vibration_n (1 N) and guard_overshoot (0.1) have defaults.

    Returns:
        One line per missed bound (a NaN figure misses too); [] if all passed.

    Raises:
        KeyError: a required bound or figure is missing.
    """
    failures = []
    for move in summary["moves"]:
        if not (move["pose_error_m"] <= bounds["pose_error_m"] and move["pose_error_deg"] <= bounds["pose_error_deg"]):
            failures.append(f"move to {move['name']}: pose error {move['pose_error_m'] * 1e6:.2f} um / "
                            f"{move['pose_error_deg']:.4f} deg")
        for key, unit in (("fracture_displacement_mm", "mm"), ("fracture_angulation_deg", "deg"),
                          ("fracture_rotation_deg", "deg")):  # reduction accuracy, where the record has it
            if key in move and not move[key] <= bounds[key]:
                failures.append(f"move to {move['name']}: {key.replace('_', ' ').rsplit(' ', 1)[0]} "
                                f"{move[key]:.4f} {unit} at the fracture site (bound {bounds[key]:g})")
        # the controller's own view of the move (what the runner settled on), where the record has it
        believed = (move.get("estimate_error_m", 0.0), move.get("estimate_error_deg", 0.0))
        if not (believed[0] <= bounds["pose_error_m"] and believed[1] <= bounds["pose_error_deg"]):
            failures.append(f"move to {move['name']}: the controller's estimate is off by {believed[0] * 1e6:.2f} um "
                            f"/ {believed[1]:.4f} deg")
    for i, vib in enumerate(summary["vibrations"], start=1):
        checks = [
            ("direction error", vib["direction_error_deg"], bounds["direction_error_deg"], "deg"),
            ("amplitude error", vib["amplitude_error"], bounds["amplitude_error"], ""),
            ("off-axis ratio", vib["off_axis_ratio"], bounds["off_axis_ratio"], ""),
            ("leg amplitude error (worst leg)", float(np.max(vib["leg_amplitude_error"])),
             bounds["leg_amplitude_error"], ""),
            ("leg phase error", float(np.max(vib["leg_phase_error_deg"])), bounds["leg_phase_error_deg"], "deg"),
            ("leg frequency spread", vib["leg_frequency_spread_hz"], bounds["leg_frequency_spread_hz"], "Hz"),
            ("leg frequency error (worst leg)", vib["leg_frequency_error_hz"], bounds["leg_frequency_error_hz"], "Hz"),
            ("active duration error", vib["active_duration_error_s"], bounds["active_duration_error_s"], "s"),
        ]
        view = vib.get("controller_view")
        if view is not None:  # what the controller believes it delivered, judged on the same bounds
            checks += [("direction error in the controller's view", view["direction_error_deg"],
                        bounds["direction_error_deg"], "deg"),
                       ("amplitude error in the controller's view", view["amplitude_error"], bounds["amplitude_error"],
                        ""),
                       ("off-axis ratio in the controller's view", view["off_axis_ratio"], bounds["off_axis_ratio"],
                        "")]
            if view.get("leg_amplitude_error") is not None:
                checks.append(("leg amplitude error in the controller's view (worst leg)",
                               float(np.max(view["leg_amplitude_error"])), bounds["leg_amplitude_error"], ""))
        if vib["force"] is not None:
            checks.append(("force RMS error (worst leg) / the largest leg's force amplitude",
                           vib["force"]["worst_leg_vs_largest_amplitude"], bounds["force_rms_relative"], ""))
        else:
            failures.append(f"vibration {i}: no force estimates recorded")
        for name, value, bound, unit in checks:
            if not value <= bound:
                failures.append(f"vibration {i}: {name} {value:.4g} {unit} exceeds {bound:g} {unit}")
        if not vib["leg_phase_sign_ok"]:
            failures.append(f"vibration {i}: a leg vibrates in the wrong phase (0 vs pi)")
    tissue = summary.get("tissue")
    if tissue is not None:
        mh, limit = tissue["moves_holds"], bounds.get("wrench_error_relative", 0.02)
        for name, value in (("force", mh["relative_force"]), ("moment", mh["relative_moment"])):
            if value is not None and not value <= limit:
                failures.append(f"external-wrench estimate in moves and holds: RMS {name} error {value * 100:.3f} % "
                                f"of the peak applied exceeds {limit * 100:g} %")
        vib, vib_limit = tissue["vibration"], bounds.get("wrench_error_vibration_n", 1.0)
        if vib is not None and not vib["rms_force_error_n"] <= vib_limit:
            failures.append(f"external-wrench estimate during the vibration: RMS force error "
                            f"{vib['rms_force_error_n']:.3f} N exceeds {vib_limit:g} N")
        for trip in tissue["guard"]:
            if trip["limit"] == "force" and not trip["overshoot"] <= bounds.get("guard_overshoot", 0.1):
                failures.append(f"force guard at {trip['trip_time_s']:.3f} s: peak estimated force "
                                f"{trip['peak_estimated_force_n']:.1f} N is {trip['overshoot'] * 100:.1f} % over "
                                f"guard_force_n {trip['force_limit_n']:g} N")
    for figure in summary.get("limits") or []:
        if figure["violations"]:
            failures.append(f"limits over the recorded states: {figure['line']}")
    streams = summary.get("streams")
    if streams is not None:
        if not streams["worst_ratio"] >= bounds["sample_ratio_min"]:
            failures.append(f"estimates per joint state {streams['worst_ratio']:.5f} below "
                            f"{bounds['sample_ratio_min']:g} (samples lost: {streams['lost']})")
        for node, row in streams["nodes"].items():
            if row["lost"]:
                failures.append(f"{node} lost {row['lost']} of its input states")
            if not row["lag_p99_ms"] <= bounds["stream_lag_p99_ms"]:
                failures.append(f"{node}: lag p99 {row['lag_p99_ms']:.1f} ms exceeds "
                                f"{bounds['stream_lag_p99_ms']:g} ms")
    return failures


def limit_summary(robot: Robot, signals: dict) -> list[dict]:
    """The independent limit check (``limit_check.check_limits``) of the recorded states, as JSON-ready rows
    (the figure's fields plus its printed "line").

    Args:
        robot: the robot (limits and geometry from config/robot.yaml).
        signals: from ``load_signals``: its "limit_figures" when it checked every state as it read the run (a
            long run read in windows), else its joints, pose and clock.

    Returns:
        One dict per figure.
    """
    from dataclasses import asdict

    from .limit_check import check_limits

    figures = signals.get("limit_figures")
    if figures is None:
        figures = check_limits(robot, signals["joints"], signals["pose"], signals.get("clock"))
    return [dict(asdict(f), line=f.line()) for f in figures]
