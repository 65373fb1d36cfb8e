"""Pacing the emulator's sim time on the wall clock (pure Python): ``real_time_factor`` s of sim time per s of
wall time (0 = as fast as possible).

The physics thread runs state periods back to back and wakes up once per ``pace_period_s`` of sim time
(``state_periods``): a thread that slept after every 2 ms period would pay a wake-up and cold caches 500
times a second. At a wake-up it sleeps until the wall clock catches up with sim time. A thread that falls
behind (a busy machine) by more than ``max_behind_s`` does not race to catch up -- the nodes reading its
states would see a burst faster than real time -- it keeps the pace from there instead. Waiting for late
consumers (``consumer_pace``) restarts the pace the same way.
"""

from __future__ import annotations

import time

MAX_BEHIND_S = 0.5  # wall time the thread may fall behind before it keeps the pace from where it is (s)


def state_periods(duration_s: float, state_rate_hz: float) -> int:
    """State periods in ``duration_s`` of sim time (s) at ``state_rate_hz`` (Hz), at least one: e.g. how many
    the physics thread runs per wake-up (``pace_period_s``)."""
    return max(int(round(duration_s * state_rate_hz)), 1)


class WallPace:
    """Sim time against the wall clock since the last (re)start; ``real_time_factor`` may change at any time
    (call ``restart`` then, so the new rate counts from that instant).

    Args:
        real_time_factor: s of sim time per s of wall time; 0 = never sleep.
        clock: the wall clock (s, monotonic); sleep: sleeps s of wall time (both injectable for tests).
        max_behind_s: wall time (s) behind the pace after which the pace restarts instead of catching up.
    """

    def __init__(self, real_time_factor: float, clock=time.monotonic, sleep=time.sleep,
                 max_behind_s: float = MAX_BEHIND_S):
        self.real_time_factor = float(real_time_factor)
        self.clock, self.sleep = clock, sleep
        self.max_behind_s = float(max_behind_s)
        self.achieved_rtf = 0.0  # sim s per wall s since the last (re)start
        self.behind_resets = 0  # restarts because the thread fell behind
        self._wall0, self._sim0 = clock(), 0.0
        self._restart = False

    def start(self, sim_time: float) -> None:
        """Pace from now, sim time ``sim_time`` (s); a restart asked before is dropped."""
        self._wall0, self._sim0, self._restart = self.clock(), sim_time, False

    def restart(self) -> None:
        """Keep the pace from the next wake-up on (another thread may call it: a flag, read there)."""
        self._restart = True

    def measure(self, sim_time: float) -> float:
        """After a state period ending at ``sim_time`` (s): update ``achieved_rtf``; returns the wall time (s)
        since the pace started."""
        wall = self.clock() - self._wall0
        self.achieved_rtf = (sim_time - self._sim0) / wall if wall > 0 else 0.0
        return wall

    def wake_up(self, sim_time: float, wall: float) -> float:
        """At a wake-up, sim time ``sim_time`` (s), ``wall`` as ``measure`` returned it: restart the pace if
        asked, else sleep until the wall clock reaches sim time at real_time_factor (or restart when far
        behind). Returns the wall time slept (s)."""
        rtf = self.real_time_factor
        if self._restart:
            self.start(sim_time)
            return 0.0
        if rtf <= 0:
            return 0.0
        ahead = (sim_time - self._sim0) / rtf - wall
        if ahead > 0:
            self.sleep(ahead)
            return ahead
        if ahead < -self.max_behind_s:
            self.behind_resets += 1
            self._wall0, self._sim0 = self.clock(), sim_time
        return 0.0
