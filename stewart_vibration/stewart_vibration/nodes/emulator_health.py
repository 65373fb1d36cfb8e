"""The hardware emulator's health on /diagnostics and in its log (rclpy): a latched physics fault or e-stop
stays first (and ERROR) whatever else is reported; refused commands counted and logged thinned; the physics
thread's failed blocks, newly latched faults and pace figures; MuJoCo's warnings. The bookkeeping is
emulation.emulator_reports."""

from __future__ import annotations

import traceback

from ..emulation.emulator_reports import RejectionTally, latched_first, thinned
from ..emulation.physics_guard import PhysicsFault
from ..emulation.physics_thread import BlockFailure, PhysicsPacing
from .diagnostics import ERROR, WARN, Diagnostics

MUJOCO_WARNINGS_LOGGED_FIRST, MUJOCO_WARNINGS_LOGGED_EVERY = 5, 100


class EmulatorHealth:
    """/diagnostics ("hardware emulator") and the log of ``node``; ``emulator()`` is the emulator now (None while
    unconfigured), read for what it has latched."""

    def __init__(self, node, emulator):
        self.node, self.emulator = node, emulator
        self.diagnostics = Diagnostics(node, "hardware emulator")
        self.rejections = RejectionTally()
        self.mujoco_warnings = 0

    def set(self, level, message: str, **values) -> None:
        """The status as given (a transition or a service that says what holds the robot itself)."""
        self.diagnostics.set(level, message, **values)

    def report(self, level, message: str, **values) -> None:
        """The status, never better than ERROR while the e-stop or a physics fault is latched, which stays first
        in the message."""
        emulator = self.emulator()
        if emulator is None:
            self.diagnostics.set(level, message, **values)
            return
        self.diagnostics.set(ERROR if emulator.estopped else level,
                             latched_first(message, emulator.fault, emulator.estopped), **values)

    def reject(self, what: str, reason: str) -> None:
        """A refused command: counted and on /diagnostics (WARN), logged thinned (emulator_reports.RejectionTally)."""
        if self.rejections.add(what, reason):
            self.node.get_logger().warning(f"rejected {what}: {reason} ({self.rejections.count} rejections so far)")
        self.report(WARN, f"rejected {what}: {reason}", last_rejection=reason, rejections=self.rejections.count)

    def fault_latched(self, fault: PhysicsFault, failures: int) -> None:
        """A newly latched physics fault (``failures``: failed blocks so far): ERROR with its time and reason."""
        self.node.get_logger().error(f"physics fault at sim time {fault.time:.3f} s: {fault.reason}; the robot is held "
                                     "at its last good state (cleanup + configure to rebuild)")
        self.report(ERROR, "physics stopped following the commands", physics_fault=fault.reason,
                    physics_fault_time_s=f"{fault.time:.6f}", physics_errors=failures)

    def block_failed(self, failure: BlockFailure) -> None:
        """A physics block raised: logged thinned, with its traceback; the fault it latched is ERROR."""
        error = failure.error
        if failure.logged:
            self.node.get_logger().error(f"physics block failed ({failure.count} so far): {type(error).__name__}: "
                                         f"{error}\n{''.join(traceback.format_exception(error))}")
        if failure.latch_error is not None:
            again = failure.latch_error
            self.node.get_logger().error(f"latching the physics fault failed: {type(again).__name__}: {again}")
        self.diagnostics.set(ERROR, f"physics fault: {type(error).__name__}: {error}; robot held",
                             physics_errors=failure.count)

    def physics_stopped(self, error: Exception) -> None:
        """The physics thread died of ``error`` (call it in the handler: the traceback is logged)."""
        text = f"physics stopped: {type(error).__name__}: {error}"
        self.node.get_logger().error(f"{text}\n{traceback.format_exc()}")
        self.diagnostics.set(ERROR, f"{text}; the robot is held where it was (restart the emulator)")

    def report_pace(self, sim_time: float, pacing: PhysicsPacing) -> None:
        """The pace figures as /diagnostics values: sim time (s), the achieved real-time factor, its resets,
        the waits for consumers and the wall time they took (s), the consumers run past."""
        pace, consumers = pacing.wall, pacing.consumers
        self.diagnostics.values.update(sim_time_s=f"{sim_time:.3f}", achieved_rtf=f"{pace.achieved_rtf:.2f}",
                                       pace_resets=str(pace.behind_resets), consumer_waits=str(consumers.waits),
                                       consumer_waited_s=f"{consumers.waited_s:.2f}",
                                       consumers_run_past=str(consumers.gave_up))

    def mujoco_warning(self, text: str) -> None:
        """MuJoCo's warning handler (called from the physics thread): the first few and every 100th, logged."""
        self.mujoco_warnings += 1
        if thinned(self.mujoco_warnings, MUJOCO_WARNINGS_LOGGED_FIRST, MUJOCO_WARNINGS_LOGGED_EVERY):
            self.node.get_logger().warning(f"MuJoCo: {text} ({self.mujoco_warnings} warnings so far)")
