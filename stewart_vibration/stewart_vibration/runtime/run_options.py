"""How the main job runs (``RunOptions``: namespace, domain, sim speed, output, tolerances) and what it records
(``RunRecord``: the MCAP, per-step results and event times in sim s). No rclpy.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .suite import DEFAULT_NAMESPACE

# how the main job controls a vibration: "closed_loop" (identify the units at the vibration's pose and
# frequency, plan with the identification's feed-forward, correct from the platform IMU), "feedforward" (the
# same without the loop), "off" (the drawing's decomposition, uncompensated)
VIBRATION_CONTROL = ("closed_loop", "feedforward", "off")


@dataclass
class RunOptions:
    """How the main job runs: namespace, ROS domain, sim speed, output, extra nodes, tolerances."""

    namespace: str = DEFAULT_NAMESPACE
    domain_id: int = 42
    real_time_factor: float = 1.0
    lockstep: bool = False  # the emulator waits for late estimates: sim time slows instead of moves pausing
    out_dir: Path = Path("runs")
    params_file: Path | None = None
    hardware_params_file: Path | None = None  # node parameters applied after the suite's (--params-file)
    extra_nodes: tuple = ()  # runtime.suite.OPTIONAL_NODES keys to start as well ("foxglove", "ui")
    tissue_config: str | None = None  # soft-tissue YAML for the emulator (applied) and kinematics (checked)
    robot_config: str | None = None  # robot YAML for every node that reads one (None: config/robot.yaml)
    plant_config: str | None = None  # the emulator's robot as built (None: the drawing)
    plant_seed: int | None = None  # its seed (None: the plant file's)
    vibration_control: str = "closed_loop"  # VIBRATION_CONTROL: identify the units before each vibration, and how
    identification_file: Path | None = None  # an identification to reuse where it holds (else the run identifies)
    settle_tolerance_m: float = 1e-5
    settle_tolerance_rad: float = np.radians(0.01)
    step_timeout_s: float = 120.0  # wall clock, per step
    progress: Any = print


@dataclass
class RunRecord:
    """What happened: MCAP path, per-step results and event times (sim s)."""

    mcap_path: Path | None = None
    log_dir: Path | None = None
    # dicts: name, target, time, pose_error_m / _deg (ground truth), estimate_error_m / _deg (the controller's view)
    moves: list = field(default_factory=list)
    vibrations: list = field(default_factory=list)  # dicts: parameters (what ran), start_time, t0, stop_time, ...
    interrupted: bool = False
    failures: list = field(default_factory=list)  # what went wrong outside the steps (exits, recorder)
    recorder_stats: dict | None = None  # the recorder's counts of its last file (received, written, dropped)
    restarts: list = field(default_factory=list)  # dicts: node, exit_code, sim_time_s (restarted, --keep-running)
    recording_span: list = field(default_factory=lambda: [None, None])  # sim s: recorder ready .. its stop
    guard_stops: list = field(default_factory=list)  # dicts: target, time, guard (status values), stopped_pose
    identifications: list = field(default_factory=list)  # dicts: label, frequency_hz, outcome, message, path, problems
