"""The hardware emulator's physics thread (pure Python, no ROS): one block of physics steps per state period,
what each period hands out (``Block``: the sensors, the truth, and which of /clock, status, markers and a new
fault are due), the pacing between wake-ups (``wall_pace``, and ``consumer_pace`` above real time), and the
brake to rest before it stops.

It never dies on an exception in a block: the block fails, a physics fault is latched (the robot is held at
its last good state, the vibration dropped) and time goes on, so the held state and /clock are still
published. The node publishes each block and reports the rest (``PhysicsReports``); commands reach the
emulator on other threads under the same lock.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

from .consumer_pace import ConsumerPace, paces_consumers
from .emulator_reports import thinned
from .physics_guard import PhysicsFault
from .vibration_status import VibrationReport
from .wall_pace import WallPace, state_periods

if TYPE_CHECKING:
    from .emulator import HardwareEmulator

PACE_PARAMETERS = ("real_time_factor", "max_consumer_lag_s", "lockstep")  # the node's live pacing parameters
PACE_REPORT_EVERY = 500  # state periods between reports of the pace figures (1 s of sim time at 500 Hz)
FAILURES_LOGGED_FIRST, FAILURES_LOGGED_EVERY = 3, 1000  # failed blocks that get a log line (emulator_reports.thinned)
BRAKE_POLL_S = 0.01  # wall time between checks whether the robot is at rest while braking (s)


def every(rate_hz: float, state_rate_hz: float) -> int:
    """State periods between two events at ``rate_hz`` (Hz) when states come at ``state_rate_hz`` (Hz); at
    least one (an event cannot come more often than the states)."""
    return max(int(round(state_rate_hz / rate_hz)), 1)


@dataclass(frozen=True)
class BlockSchedule:
    """Which state periods do what, in state periods: a /clock tick, the markers (0: never), an evaluation
    of the vibration status, a wake-up of the pacing."""

    period_s: float  # one state period (s of sim time)
    clock_every: int
    marker_every: int
    status_every: int
    wakeup_every: int

    @classmethod
    def from_rates(cls, state_rate_hz: float, clock_rate_hz: float, marker_rate_hz: float, status_period_s: float,
                   pace_period_s: float) -> BlockSchedule:
        """The schedule for states at ``state_rate_hz``, /clock at ``clock_rate_hz`` and markers at
        ``marker_rate_hz`` (Hz, 0: none), a status evaluation every ``status_period_s`` and a wake-up every
        ``pace_period_s`` (s of sim time)."""
        return cls(period_s=1.0 / state_rate_hz, clock_every=every(clock_rate_hz, state_rate_hz),
                   marker_every=every(marker_rate_hz, state_rate_hz) if marker_rate_hz > 0 else 0,
                   status_every=state_periods(status_period_s, state_rate_hz),
                   wakeup_every=state_periods(pace_period_s, state_rate_hz))


class PhysicsPacing:
    """How physics is paced, as the live parameters ``PACE_PARAMETERS`` set it: on the wall clock at
    ``real_time_factor`` (``wall``), and waiting for consumers that trail sim time by more than
    ``max_consumer_lag_s`` (``consumers``) above real time or in ``lockstep``. Outlives the emulators built at
    configure: a figure set while unconfigured applies to the next one.

    Args:
        clock, sleep: the wall clock (s, monotonic) and its sleep, for ``wall`` (injectable for tests).
    """

    def __init__(self, real_time_factor: float, max_consumer_lag_s: float, lockstep: bool, clock=time.monotonic,
                 sleep=time.sleep):
        self.wall = WallPace(real_time_factor, clock=clock, sleep=sleep)
        self.consumers = ConsumerPace(max_consumer_lag_s)
        self.lockstep = bool(lockstep)

    def set(self, name: str, value) -> None:
        """A live parameter ``name`` (of PACE_PARAMETERS) set to ``value``; a new rate counts from the next
        wake-up."""
        if name == "max_consumer_lag_s":
            self.consumers.max_lag_s = float(value)
            return
        if name == "lockstep":
            self.lockstep = bool(value)
        elif name == "real_time_factor":
            self.wall.real_time_factor = float(value)
        else:
            raise KeyError(f"{name} is no pacing parameter ({', '.join(PACE_PARAMETERS)})")
        self.wall.restart()

    def waits_for_consumers(self) -> bool:
        """Whether physics waits for late consumers at these settings (``consumer_pace.paces_consumers``)."""
        return paces_consumers(self.wall.real_time_factor, self.lockstep)


@dataclass(frozen=True)
class Block:
    """One state period's output, read under the lock at sim time ``time`` (s).

    ``sensors``: (joint state tuple, IMU sample, tracker frames due); ``truth``: (true joint state tuple,
    platform position (3,) m and quaternion (4,) [x, y, z, w] in base, tissue wrench (6,) N, N m); ``report``:
    the vibration status when evaluated this period (``report_changed``: it differs from the last evaluation);
    ``new_fault``: a physics fault latched since the last block."""

    sensors: tuple
    truth: tuple
    time: float
    clock_due: bool = True
    markers_due: bool = False
    report: VibrationReport | None = None
    report_changed: bool = False
    new_fault: PhysicsFault | None = None


@dataclass(frozen=True)
class BlockFailure:
    """A block that raised ``error``: the ``count``-th so far; ``logged``: it gets a log line; ``latch_error``:
    what latching the physics fault raised in turn, if anything."""

    error: Exception
    count: int
    logged: bool
    latch_error: Exception | None = None


class PhysicsReports(Protocol):
    """Where the physics thread reports how it runs (the node's /diagnostics and log)."""

    def block_failed(self, failure: BlockFailure) -> None:
        """A block raised; its physics fault is latched already."""

    def report_pace(self, sim_time: float, pacing: PhysicsPacing) -> None:
        """Every PACE_REPORT_EVERY state periods, after a wake-up: the pace figures at ``sim_time`` (s)."""


class PhysicsThread:
    """Runs ``emulator`` state period by state period on a thread of its own.

    Args:
        emulator: the robot; read and stepped only under ``lock``.
        lock: shared with whoever commands the emulator.
        schedule: the periods (``BlockSchedule``).
        pacing: the wall clock's pace and the consumers' (shared with who sets the live parameters); the
            consumers are waited for while ``paced_by_consumers()`` is true (the node hears them then).
        clock, sleep: the wall clock (s, monotonic) and its sleep (injectable for tests).
    """

    def __init__(self, emulator: HardwareEmulator, lock, schedule: BlockSchedule, pacing: PhysicsPacing,
                 paced_by_consumers=lambda: False, clock=time.monotonic, sleep=time.sleep):
        self.emulator, self.lock, self.schedule = emulator, lock, schedule
        self.pacing, self.paced_by_consumers = pacing, paced_by_consumers
        self.clock, self.sleep = clock, sleep
        self.running = False  # cleared to stop the loop (any thread)
        self.thread: threading.Thread | None = None
        self.failures = 0  # blocks that raised
        self._fault_seen: PhysicsFault | None = None  # the latched fault last handed out as new

    def start(self, target) -> None:
        """Run ``target`` (the node's wrapper around ``run``) on a new daemon thread named "physics"."""
        self.running = True
        self.thread = threading.Thread(target=target, name="physics", daemon=True)
        self.thread.start()

    def alive(self) -> bool:
        """Whether the physics thread runs (started, not stopped, not dead)."""
        return self.running and self.thread is not None and self.thread.is_alive()

    def stop(self, join_s: float = 2.0) -> None:
        """End the loop and wait for the thread, at most ``join_s`` of wall time (s)."""
        self.running = False
        if self.thread is not None:
            self.thread.join(timeout=join_s)
            self.thread = None

    def run(self, publish_block: Callable[[Block], None], reports: PhysicsReports) -> None:
        """The loop, while ``running``: the state now, then per state period a block of physics steps handed to
        ``publish_block``; at each wake-up the consumers waited for (if paced by them) and the wall clock."""
        emulator, schedule, pace, consumers = self.emulator, self.schedule, self.pacing.wall, self.pacing.consumers
        with self.lock:
            sensors, truth, now = self.read()
        pace.start(now)
        publish_block(Block(sensors, truth, now))
        done = 0  # state periods run
        while self.running:
            try:
                with self.lock:
                    emulator.advance(schedule.period_s)
                    sensors, truth, now = self.read()
                    fault = emulator.fault
                    new_fault = fault if fault is not None and fault is not self._fault_seen else None
                    report, changed = (None, False)
                    if done % schedule.status_every == 0 or new_fault is not None:
                        report, changed = emulator.vibration_report()
            except Exception as exc:  # noqa: BLE001 - a failed block: latch a fault, hold the robot, go on
                self._failed(exc, reports)
                self.sleep(schedule.period_s)
                continue
            done += 1
            if not self.running:
                break  # stopping: the publishers may already be gone
            if new_fault is not None:
                self._fault_seen = new_fault
            publish_block(Block(
                sensors, truth, now, clock_due=done % schedule.clock_every == 0,
                markers_due=bool(schedule.marker_every) and done % schedule.marker_every == 0,
                report=report, report_changed=changed, new_fault=new_fault))
            wall = pace.measure(now)
            if done % schedule.wakeup_every:
                continue  # the next state period at once: one wake-up per pace period
            if self.paced_by_consumers() and consumers.wait(now, lambda: self.running, self.sleep, self.clock) > 0:
                pace.restart()  # waited for the estimates: keep the pace from here, do not race
            pace.wake_up(now, wall)
            if done % PACE_REPORT_EVERY == 0:
                reports.report_pace(now, self.pacing)

    def read(self):
        """(sensors, truth, sim time s) as ``Block`` holds them; call under the lock."""
        emulator = self.emulator
        position, quaternion = emulator.sim.platform_position_quaternion()
        state = emulator.joint_state()
        sensors = (state, emulator.imu_sample(quaternion), emulator.tracker_frames(position, quaternion))
        return sensors, (emulator.true_joint_state(state), position, quaternion, emulator.tissue_wrench), emulator.time

    def _failed(self, error: Exception, reports: PhysicsReports) -> None:
        """A block raised ``error``: latch a physics fault (the robot is held, time goes on) and say so."""
        self.failures += 1
        latch_error = None
        try:
            with self.lock:
                self.emulator.latch_fault(f"{type(error).__name__} in the physics thread: {error}")
        except Exception as again:  # noqa: BLE001 - the failure is reported whatever happens
            latch_error = again
        reports.block_failed(BlockFailure(error, self.failures,
                                          thinned(self.failures, FAILURES_LOGGED_FIRST, FAILURES_LOGGED_EVERY),
                                          latch_error))

    def brake_to_rest(self, reason: str, timeout_s: float) -> bool:
        """Before physics stops: a safety stop (``HardwareEmulator.halt`` with ``reason``) and physics running on
        until the robot is at rest, at most ``timeout_s`` of wall time (s). True when it came to rest (or no
        physics runs to bring it there)."""
        emulator = self.emulator
        if not self.alive():
            return True
        with self.lock:
            if emulator.at_rest():
                return True
            emulator.halt(reason)
        deadline = self.clock() + timeout_s
        while self.clock() < deadline and self.alive():
            with self.lock:
                if emulator.at_rest():
                    return True
            self.sleep(BRAKE_POLL_S)
        return False
