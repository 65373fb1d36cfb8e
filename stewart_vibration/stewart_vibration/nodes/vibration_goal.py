"""The vibrate action's messages (stewart_vibration_interfaces/action/Vibrate) to and from the planner's
settings and plan, for the planner and its clients (the runner, the planning UI)."""

from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg

from stewart_vibration_interfaces.action import Vibrate
from stewart_vibration_interfaces.msg import VibrationPlan, VibrationUnitsStatus

from ..vibration.decompose import VibrationDecomposition
from ..vibration.settings import VIBRATION_KEYS
from ..vibration.waveform import acceleration_from_displacement
from .message_conversions import pose_from_msg, pose_stamped, stamp_seconds, time_message

UNIT_STATES = {"idle": VibrationUnitsStatus.IDLE, "pending": VibrationUnitsStatus.PENDING,
               "ramping_in": VibrationUnitsStatus.RAMPING_IN, "running": VibrationUnitsStatus.RUNNING,
               "ramping_out": VibrationUnitsStatus.RAMPING_OUT, "stopped": VibrationUnitsStatus.STOPPED,
               "estopped": VibrationUnitsStatus.ESTOPPED}  # vibration/status state -> the message's constant


def goal_message(vibration: dict) -> Vibrate.Goal:
    """A Vibrate goal from the vibration settings (every key of VIBRATION_KEYS; SI units)."""
    goal = Vibrate.Goal()
    goal.direction = [float(v) for v in vibration["direction"]]
    goal.frame = str(vibration["frame"])
    for key in VIBRATION_KEYS[2:]:
        setattr(goal, key, float(vibration[key]))
    return goal


def goal_settings(goal: Vibrate.Goal) -> dict:
    """The vibration settings of a goal (VIBRATION_KEYS: direction a list of 3, frame, the rest floats)."""
    settings = {"direction": [float(v) for v in goal.direction], "frame": goal.frame}
    settings.update({key: float(getattr(goal, key)) for key in VIBRATION_KEYS[2:]})
    return settings


def plan_message(plan: VibrationDecomposition, settings: dict, t0: float) -> VibrationPlan:
    """The VibrationPlan of a started vibration: the decomposition, its ramp and duration, t0 (s)."""
    msg = VibrationPlan(t0=time_message(t0), frequency_hz=float(plan.frequency), amplitude_m=float(plan.amplitude),
                        acceleration_g=float(acceleration_from_displacement(plan.amplitude, plan.frequency)),
                        phase_rad=float(plan.phase), ramp_s=float(settings["ramp_s"]),
                        duration_s=float(settings["duration_s"]))
    msg.direction = [float(v) for v in plan.direction]
    msg.gains = [float(v) for v in plan.gains]
    msg.leg_amplitudes_m = [float(v) for v in plan.leg_amplitudes]
    msg.leg_phases_rad = [float(v) for v in plan.leg_phases]
    msg.pose = pose_stamped(plan.pose, TimeMsg()).pose
    return msg


def plan_record(msg: VibrationPlan) -> dict:
    """A VibrationPlan as plain values for a run's record: t0_s, pose [6] (m, rad), and every field (SI)."""
    return {"t0_s": stamp_seconds(msg.t0), "frequency_hz": msg.frequency_hz,
            "amplitude_m": msg.amplitude_m, "acceleration_g": msg.acceleration_g,
            "direction_base": np.asarray(msg.direction, float).tolist(), "phase_rad": msg.phase_rad,
            "ramp_s": msg.ramp_s, "duration_s": msg.duration_s, "gains": np.asarray(msg.gains, float).tolist(),
            "leg_amplitudes_m": np.asarray(msg.leg_amplitudes_m, float).tolist(),
            "leg_phases_rad": np.asarray(msg.leg_phases_rad, float).tolist(),
            "pose": pose_from_msg(msg.pose).tolist()}


def settings_of_plan(record: dict) -> dict:
    """The vibration settings (VIBRATION_KEYS) that give a plan record's vibration again: its direction in the
    base frame, its amplitude, frequency, phase, ramp and duration (what a summary judges a vibration against)."""
    return {"direction": list(record["direction_base"]), "frame": "base", "amplitude_m": record["amplitude_m"],
            "acceleration_g": record["acceleration_g"], "frequency_hz": record["frequency_hz"],
            "phase_rad": record["phase_rad"], "duration_s": record["duration_s"], "ramp_s": record["ramp_s"]}
