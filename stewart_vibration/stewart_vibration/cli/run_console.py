"""What ``stewart-vibration run`` prints on the console: time-stamped progress lines, the addresses of the
optional nodes (UI, Foxglove bridge), the help for a suite kept running and the run summary with its figures
(um, deg, Hz, N, s) against the scenario's bounds.
"""

from __future__ import annotations

import time

import numpy as np

from ..runtime.suite import OPTIONAL_NODES


def log(message: str) -> None:
    """Print ``message`` as one progress line, stamped with the wall-clock time."""
    print(f"[{time.strftime('%H:%M:%S')}] {message}", flush=True)


def print_views(runner, extra) -> None:
    """The addresses the optional nodes print in their logs (lines with 'http://' or 'ws://')."""
    for key in extra:
        node = OPTIONAL_NODES[key].name
        deadline = time.monotonic() + 20
        lines: list[str] = []
        while time.monotonic() < deadline and not lines:
            lines = runner.log_lines(node, "://")
            time.sleep(0.2)
        for line in lines[-2:]:
            log(f"{node}: {line.split('] ')[-1]}")
        if not lines:
            log(f"{node}: no address in its log yet (see {runner.record.log_dir}/{node}.log)")


def print_ui_help(namespace: str, domain: int) -> None:
    """How to drive the running suite from another shell (ros2 action and service calls in ``namespace``)."""
    ns = namespace.rstrip("/")
    print(f"""
Nodes are running (Ctrl-C stops them and finishes the MCAP). In another shell:
  export ROS_DOMAIN_ID={domain} ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
  ros2 action send_goal --feedback {ns}/kinematics/move_to_pose stewart_vibration_interfaces/action/MoveToPose \\
    "{{target: {{header: {{frame_id: base}}, pose: {{position: {{z: 0.165}}, orientation: {{w: 1.0}}}}}}}}"
  ros2 action send_goal --feedback {ns}/vibration_planner/vibrate stewart_vibration_interfaces/action/Vibrate \\
    "{{direction: [0.0, 0.0, 1.0], frame: platform, acceleration_g: 0.3, frequency_hz: 35.0, \\
      duration_s: 2.0, ramp_s: 0.2}}"
  ros2 service call {ns}/vibration_planner/vibrate/_action/cancel_goal action_msgs/srv/CancelGoal
  ros2 service call {ns}/hardware_emulator/emergency_stop std_srvs/srv/Trigger
""", flush=True)


def print_summary(summary: dict, bounds: dict) -> None:
    """Print the run's ``summary`` (moves, vibrations, recording, problems, the verdict) against ``bounds``."""
    print("\n=== run summary ===")
    print(f"scenario: {summary['scenario']}")
    for move in summary["moves"]:
        print(f"move to {move['name']}: ground-truth error {move['pose_error_m'] * 1e6:.3f} um, "
              f"{move['pose_error_deg']:.5f} deg; the controller's estimate {move['estimate_error_m'] * 1e6:.3f} um, "
              f"{move['estimate_error_deg']:.5f} deg (bounds {bounds['pose_error_m'] * 1e6:g} um, "
              f"{bounds['pose_error_deg']:g} deg, both)")
        if "fracture_displacement_mm" in move:
            print(f"  at the fracture site (reduction accuracy): displacement {move['fracture_displacement_mm']:.3f} "
                  f"mm, angulation {move['fracture_angulation_deg']:.4f} deg, rotation "
                  f"{move['fracture_rotation_deg']:.4f} deg")
    for i, vib in enumerate(summary["vibrations"], start=1):
        print(f"vibration {i}: {vib['frequency_hz']:g} Hz, planned {vib['planned_amplitude_m'] * 1e6:.2f} um along "
              f"{np.round(vib['planned_direction'], 4).tolist()} (base frame)")
        print(f"  platform (ground truth): amplitude {vib['measured_amplitude_m'] * 1e6:.3f} um "
              f"(error {vib['amplitude_error'] * 100:.3f} %), direction error {vib['direction_error_deg']:.4f} deg, "
              f"off-axis ratio {vib['off_axis_ratio']:.2e}")
        view = vib.get("controller_view")
        if view is not None:
            legs = view.get("leg_amplitude_error")
            worst = f"; worst leg amplitude error {float(np.max(legs)) * 100:.3f} %" if legs is not None else ""
            print(f"  platform (the controller's view: its pose estimate and sensors): amplitude "
                  f"{view['measured_amplitude_m'] * 1e6:.3f} um (error {view['amplitude_error'] * 100:.3f} %), "
                  f"direction error {view['direction_error_deg']:.4f} deg, off-axis ratio "
                  f"{view['off_axis_ratio']:.2e}{worst}")
        print("  leg   amplitude_um  expected_um  phase_deg  expected_deg  freq_Hz")
        for k in range(6):
            amp, expected = vib["leg_amplitude_m"][k] * 1e6, vib["leg_amplitude_expected_m"][k] * 1e6
            print(f"  {k + 1}     {amp:10.3f}  {expected:10.3f}"
                  f"  {vib['leg_phase_deg'][k]:9.3f}  {vib['leg_phase_expected_deg'][k]:12.3f}"
                  f"  {vib['leg_frequency_hz'][k]:.5f}")
        if vib["force"] is not None:
            f = vib["force"]
            print(f"  leg forces, model vs emulator: RMS error {np.round(f['rms_error_n'], 4).tolist()} N; "
                  f"worst leg {f['worst_leg_vs_largest_amplitude'] * 100:.3f} % of the largest leg's force "
                  f"amplitude ({f['worst_leg_relative'] * 100:.3f} % of its own)")
        print(f"  active (>= half amplitude) {vib['active_duration_s']:.3f} s of the planned "
              f"{vib['planned_active_duration_s']:.3f} s")
        loop = vib.get("closed_loop") or {}
        if loop.get("loop_corrections"):
            stale = f"; stale: {loop['stale_identification']}" if loop.get("stale_identification") else ""
            print(f"  closed loop: {loop['loop_corrections']} corrections, the demands moved "
                  f"{loop['demand_correction']:.1%} from the identification's feed-forward{stale}")
        if vib.get("failure"):
            print(f"  this vibration failed: {vib['failure']}")
    from ..analysis.run_coverage import recording_lines
    from ..analysis.tissue_figures import tissue_lines

    for line in tissue_lines(summary) + recording_lines(summary):
        print(line)
    streams = summary.get("streams")
    if streams:
        counts = ", ".join(f"{t} {row['count']} ({row['ratio'] * 100:.2f} %)" for t, row in streams["topics"].items())
        print(f"samples: {counts}")
        for node, row in streams["nodes"].items():
            print(f"  {node}: {row['received']} states received, {row['lost']} lost, lag p50 {row['lag_p50_ms']:.1f} "
                  f"ms / p99 {row['lag_p99_ms']:.1f} ms")
    if summary.get("recorder"):
        r = summary["recorder"]
        lost = ", ".join(f"{t} {n}" for t, n in sorted((r.get("lost_per_topic") or {}).items()))
        print(f"recorder (its last file): {r.get('written')} messages written, {r.get('dropped')} dropped, "
              f"{r.get('lost', 0)} lost before they reached it" + (f" ({lost})" if lost else ""))
    print(f"MCAP: {summary['mcap']}")
    print(f"report: {summary.get('report_dir')}")
    for problem in summary.get("problems", []):
        print(f"PROBLEM: {problem}")
    if summary.get("failure"):
        print(f"FAILED: {summary['failure']}")
    elif summary.get("interrupted"):
        print("INTERRUPTED (the summary above covers what ran)")
    elif summary.get("problems"):
        print("FAILED: see the problems above")
    elif summary.get("bound_failures"):
        print("MISSED BOUNDS:\n  " + "\n  ".join(summary["bound_failures"]))
    else:
        print("all figures within their bounds")
