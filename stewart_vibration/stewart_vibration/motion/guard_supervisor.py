"""The force guard's events and the actions they call for (pure): what the kinematics node hears (joint states,
wrench estimates, the robot's answer to a stop) goes in, and what it must do comes out (send this stop, report
this trip, publish the guard's status, send the interrupted target again). The node converts messages and
carries the actions out; every decision is here, testable with a stepped clock.

Times are s of the emulator's clock as the node knows it; lengths m; wrenches [force N, torque N m].
"""

from __future__ import annotations

from dataclasses import dataclass

from .force_guard import ForceGuard
from .guarded_move import GuardTrip, StopPlan


@dataclass(frozen=True)
class SendStop:
    """Send ``stop`` (a one-point leg trajectory, stamp 0) on behalf of ``by`` ("guard": a trip's; "cancel"),
    the ``attempt``-th after the robot refused the earlier ones; ``why``: for the log, why it replaces a stop that
    did not take ("" for a first stop)."""

    stop: StopPlan
    by: str = "guard"
    attempt: int = 0
    why: str = ""


@dataclass(frozen=True)
class Tripped:
    """Report ``trip`` (ERROR, the guard's status, the move goal stopping or pausing). ``held``: the struts are
    held by an earlier stop already (a load found over a limit when estimates returned after a blind pause), so
    the goal stops now and no stop goes with it."""

    trip: GuardTrip
    held: bool = False


@dataclass(frozen=True)
class PublishStatus:
    """Publish the guard's status: a stop is over (its peak load is final), or the move it watched has ended
    otherwise (the robot refused it)."""


@dataclass(frozen=True)
class ResumeTarget:
    """Estimates are fresh again after a blind pause and the load is within the limits: send the interrupted
    target again (the guard is as it was before the pause)."""


Action = SendStop | Tripped | PublishStatus | ResumeTarget


def _trip_actions(trip: GuardTrip | None) -> list[Action]:
    """A new trip: its stop first (if the move does not end before one could), then the report."""
    actions: list[Action] = []
    if trip is not None:
        actions += [SendStop(trip.stop)] if trip.stop is not None else []
        actions.append(Tripped(trip))
    return actions


class GuardSupervisor:
    """One ForceGuard driven by events. ``batch_period``: s between the node's batches of estimates and states
    (the guard assumes the next check no sooner)."""

    def __init__(self, guard: ForceGuard, batch_period: float):
        self.guard = guard
        self.batch_period = float(batch_period)

    def states_read(self, stamps, strut_lengths) -> None:
        """Measured strut lengths [n, 6] at stamps [n] (s): the move's progress moves on. Estimates queued
        meanwhile are read next (they are newer news than their absence), then ``on_states`` judges."""
        self.guard.observe_states(stamps, strut_lengths)

    def on_states(self, now: float, newest_state_time: float) -> list[Action]:
        """After a batch of states (and the estimates queued with it): trip if a stop sent at the next check would
        end above a limit, or blind if the estimates lag the states (``newest_state_time``: the newest state this
        node read, not /clock, since a stall of the node delays both); a stop that did not take is sent again."""
        guard = self.guard
        actions = _trip_actions(guard.assess(now, self.batch_period) or guard.check_estimates(newest_state_time))
        retry = guard.missed_stop(now)
        if retry is not None:
            actions.append(SendStop(retry, "guard", 0, "force guard: the struts ran past the commanded stop still on "
                                                       "the move (it did not take)"))
        return actions

    def on_wrenches(self, stamps, wrenches, now: float, newest_state_time: float | None,
                    target_to_resume: bool) -> list[Action]:
        """Wrench estimates [n, 6] at stamps [n] (s). ``newest_state_time``: None before any state;
        ``target_to_resume``: whether the node has an interrupted target it could send again."""
        guard = self.guard
        was_watching = guard.move is not None
        actions = _trip_actions(guard.observe(stamps, wrenches, now, self.batch_period))
        if not actions and guard.tripped and was_watching and guard.move is None:
            actions.append(PublishStatus())  # the stop is over: its peak load
        # the freshness count runs whether or not there is a target to resume
        if newest_state_time is not None and guard.blind_stop_over(newest_state_time) and target_to_resume:
            if guard.resume_after_blind():
                actions.append(ResumeTarget())
            elif guard.trip is not None:  # the load passed a limit while the guard could not see it: latched
                actions.append(Tripped(guard.trip, held=True))
        return actions

    def on_stop_refused(self, by: str, attempt: int, now: float, reason: str) -> list[Action]:
        """The robot refused (``reason``) the ``attempt``-th stop sent on behalf of ``by`` ("guard" or "cancel"): it
        arrived later than it could still be taken; another is planned over a doubled window (a limited number of
        times)."""
        guard = self.guard
        retry = guard.missed_stop(now, refused=True) if by == "guard" else guard.cancel(now, attempt + 1)
        return [] if retry is None else [SendStop(retry, by, attempt + 1, f"the robot refused the stop ({reason})")]
