"""Whether a vibration may start now (pure): the planner's checks of the robot's state before it plans,
each refusal with its outcome name (RefusedError)."""

from __future__ import annotations

from ..errors import RefusedError

UNITS_MOVING = ("ramping_in", "running", "ramping_out")  # vibration/status states of units that vibrate
BUSY_STATES = ("pending", *UNITS_MOVING)  # a window queued or the units moving: not at rest
UNITS_AT_REST = ("idle", "stopped", "estopped")  # vibration/status states with the units still
CLOCK_MISMATCH_S = 10.0  # the planner's clock this far from the robot's: not the same clock


def check_can_start(planner_state: str, units_state: str | None, status_age_s: float, status_stale_s: float,
                    robot_time_s: float | None, now_s: float, pose_age_s: float | None, pose_timeout_s: float,
                    clock_rate: float = 1.0, robot_active: bool = True) -> None:
    """Refuse a start the robot cannot carry out now; return None when it may go ahead.

    Args:
        planner_state: the planner's state ("idle", "running", "stopping", "aborted: ...").
        units_state: the latest vibration/status state of the units, None before one arrived.
        status_age_s: wall seconds since that status arrived.
        status_stale_s: an older status says nothing about now (this process was held up).
        robot_time_s: the robot's clock when that status was sent (s), None if unknown.
        now_s: the planner's clock (s; 0 when it does not run).
        pose_age_s: wall seconds since the latest pose estimate, None before one.
        pose_timeout_s: a pose estimate older than this is stale (s).
        clock_rate: the planner's clock's rate (s per wall s; faster than real time the robot's clock moves
            that much more while a status ages).
        robot_active: that status says the robot takes commands (the emulator's lifecycle state is active).

    Raises:
        RefusedError: BUSY, ESTOP_LATCHED, ROBOT_INACTIVE, UNITS_NOT_AT_REST, NOT_READY (no or a stale status
            or pose estimate: a start the robot's state cannot confirm is refused), CLOCK_NOT_RUNNING or
            CLOCK_MISMATCH, with the reason and what to do.
    """
    if planner_state in ("running", "stopping"):
        raise RefusedError("BUSY", f"a vibration is {planner_state}; cancel it first")
    if planner_state == "identifying":
        raise RefusedError("BUSY", "the vibration units are being identified; wait for it or cancel it")
    fresh = units_state is not None and status_age_s <= status_stale_s
    if units_state == "estopped":
        raise RefusedError("ESTOP_LATCHED", "emergency stop latched on the hardware emulator: call "
                                            "hardware_emulator/reset first")
    if fresh and not robot_active:
        raise RefusedError("ROBOT_INACTIVE", "the hardware emulator is not active (lifecycle): it refuses every "
                                             "command; activate it first (ros2 lifecycle set <its node> activate)")
    if fresh and units_state in BUSY_STATES:
        raise RefusedError("UNITS_NOT_AT_REST", f"the vibration units are not at rest ({units_state}); start again "
                                                "when they are")
    if units_state is None:
        raise RefusedError("NOT_READY", "no vibration/status from the hardware emulator yet: its units' state and "
                                        "clock are unknown (is it running, in this ROS domain and namespace?)")
    if not fresh:
        raise RefusedError("NOT_READY", f"the last vibration/status from the hardware emulator is "
                                        f"{status_age_s:.1f} s old (it repeats every second): the units' state "
                                        "is unknown; try again")
    if now_s <= 0:
        raise RefusedError("CLOCK_NOT_RUNNING", "the planner's clock is not running (use_sim_time without /clock?)")
    if robot_time_s is not None and \
            abs(now_s - robot_time_s) > CLOCK_MISMATCH_S + status_age_s * max(clock_rate, 1.0):
        raise RefusedError("CLOCK_MISMATCH", f"the planner's clock reads {now_s:.3f} s but the robot's read "
                                             f"{robot_time_s:.3f} s {status_age_s:.1f} s ago: start the planner "
                                             "with use_sim_time:=true when the robot runs on /clock")
    if pose_age_s is None:
        raise RefusedError("NOT_READY", "no platform/pose_estimate received yet")
    if pose_age_s > pose_timeout_s:
        raise RefusedError("NOT_READY", f"pose estimate is {pose_age_s:.3f} s old (wall time; pose_timeout_s "
                                        f"{pose_timeout_s})")


def robot_stop(report, t0: float, new_event: bool) -> tuple[str, str] | None:
    """Whether the robot stopped what the planner started at ``t0`` (s, the robot's clock), from its latest
    vibration/status ``report`` (emulation.vibration_status.VibrationReport; ``new_event``: its event is one
    not seen before): (outcome name, reason), or None while it goes on.

    A refused window of this run (ROBOT_REFUSED), the emergency stop (EMERGENCY_STOPPED, or PHYSICS_FAULT
    when a physics fault latched it), a safety ramp since t0 (its own outcome, e.g. UNIT_TRAVEL_STOPPED;
    STOPPED_EARLY for another stop)."""
    if new_event and report.event == "refused" and report.event_stamp is not None \
            and report.event_stamp >= t0 - 1e-6:
        return "ROBOT_REFUSED", (f"the hardware emulator refused a window of this run ({report.event_outcome}: "
                                 f"{report.event_reason})")
    if report.state == "estopped":
        return ("PHYSICS_FAULT" if report.fault else "EMERGENCY_STOPPED",
                "emergency stop on the hardware emulator (call hardware_emulator/reset)")
    if report.state == "stopped" and report.since >= t0:
        return (report.event_outcome if report.event == "safety_ramp" else "STOPPED_EARLY",
                f"the vibration units stopped: {report.reason}")
    return None
