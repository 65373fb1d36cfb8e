"""The suite's status messages from their core values: VibrationUnitsStatus of an
emulation.vibration_status.VibrationReport and ForceGuardStatus of a motion.guard_status.GuardStatus
(messages.status_values reads them back from the wire)."""

from __future__ import annotations

import math

import numpy as np

from stewart_vibration_interfaces.msg import ForceGuardStatus, VibrationUnitsStatus

from ..emulation.vibration_status import EVENTS, LEVELS, RAMP_CAUSES, STATES, VibrationReport
from ..messages.fields import BASE_FRAME
from ..motion.guard_status import GUARD_STATES, TRIP_LIMITS, GuardStatus
from .message_conversions import pose_stamped, time_message
from .outcomes import outcome


def _time_or_nan(value: float | None) -> float:
    return math.nan if value is None else float(value)


def vibration_status_msg(report: VibrationReport, active: bool = True) -> VibrationUnitsStatus:
    """The VibrationUnitsStatus of ``report`` (stamped with its time, s of the robot's clock); ``active``: the
    emulator takes commands (its lifecycle state)."""
    msg = VibrationUnitsStatus(
        state=STATES.index(report.state), level=LEVELS.index(report.level), reason=report.reason,
        since_s=float(report.since), commanded_until_s=float(report.commanded_until),
        ramp_start_s=_time_or_nan(report.ramp_start), ramp_cause=RAMP_CAUSES.index(report.ramp_cause),
        ramp_reason=report.ramp_reason, event_seq=int(report.event_seq), event=EVENTS.index(report.event),
        event_stamp_s=_time_or_nan(report.event_stamp), event_time_s=_time_or_nan(report.event_time),
        accepted_windows=int(report.accepted), refused_windows=int(report.refused), fault=report.fault,
        active=bool(active))
    msg.header.stamp = time_message(report.time)
    msg.amplitude_m = np.asarray(report.amplitude, float)
    if report.event:
        msg.event_outcome = outcome(report.event_outcome, report.event_reason)
    return msg


def guard_status_msg(status: GuardStatus, stamp) -> ForceGuardStatus:
    """The ForceGuardStatus of ``status`` stamped ``stamp`` (builtin_interfaces/Time, kinematics' clock)."""
    msg = ForceGuardStatus(
        state=GUARD_STATES.index(status.state), force_limit_n=float(status.force_limit_n),
        moment_limit_nm=float(status.moment_limit_nm), trip_time_s=float(status.trip_time_s),
        trip_limit=TRIP_LIMITS.index(status.trip_limit), trip_force_n=float(status.trip_force_n),
        trip_moment_nm=float(status.trip_moment_nm), predicted_force_n=float(status.predicted_force_n),
        predicted_moment_nm=float(status.predicted_moment_nm), peak_force_n=float(status.peak_force_n),
        peak_moment_nm=float(status.peak_moment_nm), stop_duration_s=float(status.stop_duration_s),
        stop_progress=float(status.stop_progress), blocked_directions=int(status.blocked_directions),
        message=status.message)
    msg.header.stamp = stamp
    msg.header.frame_id = BASE_FRAME
    if np.isfinite(status.tripped_goal).all():
        msg.tripped_goal = pose_stamped(status.tripped_goal, stamp).pose
    else:
        msg.tripped_goal.position.x = msg.tripped_goal.position.y = msg.tripped_goal.position.z = math.nan
        msg.tripped_goal.orientation.w = math.nan
    msg.tripped_direction = np.asarray(status.tripped_direction, float)
    return msg
