"""Faster than real time, the emulator waits for the nodes that read its states (pure Python).

At ``real_time_factor`` > 1 (or 0, as fast as possible) the emulator can outrun the nodes that turn its
states into estimates: on 2 cores the suite needs about 2.2 cores at 2x. The estimates then lag the clock,
and the force guard slows or pauses every move (it cannot see the load in time). Above real time
that is a simulation artefact, not the hardware's behaviour, so the physics holds sim time while a
consumer's newest output lags more than ``max_lag_s`` behind it (like a simulator in lockstep with its
controllers). At real time and below it never waits: the hardware does not wait for its software,
and the force guard is what copes with a late estimator there.

A consumer that stays behind for ``max_wait_s`` of wall time (stopped, or dead but still discovered)
is run past: physics goes on without it, as at 1x, until it catches up again.
"""

from __future__ import annotations

import time

MAX_WAIT_S = 2.0  # wall time one wait may last before a stalled consumer is run past (s)

def paces_consumers(real_time_factor: float, lockstep: bool = False) -> bool:
    """True where the emulator waits for its consumers: above real time, as fast as possible (0), or at any
    rate in ``lockstep`` (a busy machine then slows sim time instead of leaving the estimates behind)."""
    return lockstep or real_time_factor == 0.0 or real_time_factor > 1.0


class ConsumerPace:
    """Newest output stamp per consumer topic (sim time, s) and the wait it implies.

    Args:
        max_lag_s: the most a consumer's newest stamp may trail sim time before physics waits (s);
            0 = never wait.
        max_wait_s: wall time one wait may last before the stalled consumer is run past (s).
    """

    def __init__(self, max_lag_s: float, max_wait_s: float = MAX_WAIT_S):
        self.max_lag_s = float(max_lag_s)
        self.max_wait_s = float(max_wait_s)
        self.newest: dict[str, float] = {}  # topic -> stamp of its last message (s, sim time)
        self.run_past: set[str] = set()  # consumers given up on until they catch up
        self.waits = 0  # waits begun
        self.waited_s = 0.0  # wall time spent waiting
        self.gave_up = 0  # waits that ended by running past a stalled consumer

    def heard(self, topic: str, stamp_s: float) -> None:
        """A consumer's output stamped ``stamp_s`` (s, sim time); the last one counts (a sim reset restarts it)."""
        self.newest[topic] = stamp_s

    def forget(self) -> None:
        """Drop every stamp (sim time restarts, or pacing is switched off)."""
        self.newest.clear()
        self.run_past.clear()

    def behind(self, now: float) -> dict[str, float]:
        """Consumers whose newest stamp trails ``now`` (s) by more than max_lag_s: topic -> lag (s).
        A consumer never heard from is not waited for (it may not exist), nor one being run past."""
        if self.max_lag_s <= 0:
            return {}
        late = {}
        for topic, stamp in list(self.newest.items()):  # heard() runs on another thread
            lag = now - stamp
            if lag <= self.max_lag_s:
                self.run_past.discard(topic)  # caught up: waited for again
            elif topic not in self.run_past:
                late[topic] = lag
        return late

    def wait(self, now: float, keep_running, sleep=time.sleep, clock=time.monotonic,
             poll_s: float = 0.002) -> float:
        """Block while a consumer trails ``now`` (s) by more than max_lag_s, at most max_wait_s; a
        consumer still behind then is run past. ``keep_running()`` False ends the wait at once.
        Returns the wall time waited (s)."""
        late = self.behind(now)
        if not late:
            return 0.0
        start = clock()
        self.waits += 1
        while late and keep_running():
            if clock() - start >= self.max_wait_s:
                self.run_past.update(late)
                self.gave_up += 1
                break
            sleep(poll_s)
            late = self.behind(now)
        waited = clock() - start
        self.waited_s += waited
        return waited
