"""How fresh the force guard's input is and how often it looks (pure numpy): the newest external-wrench estimate
against the newest joint state, the estimates' lag over the last seconds, the strut speed that lag allows, and
the gaps between the guard's own checks.

A guard that sees the load late must move slower: moves are slowed so that the struts cover at most
``blind_travel`` in the estimates' lag behind the states (the largest over the last LAG_MEMORY_S). Times are s
of the emulator's clock (sim time), speeds m/s.
"""

from __future__ import annotations

import numpy as np

from .stop_planning import MAX_WINDOW_S

LAG_MEMORY_S = 3.0  # the estimates' lag behind the states is remembered this long (s of sim time)
BLIND_TRAVEL_M = 1.5e-3  # default: moves are slowed so that the struts cover at most this in the estimates' lag
RESUME_FRESH_S = 0.5  # a blind pause ends once estimates have kept up this long (s of sim time)
CHECK_MEMORY_S = 1.0  # the largest gap between the guard's checks over this much sim time is its look-ahead
MAX_ESTIMATE_AGE_S = 0.25  # default: a move pauses when the newest wrench estimate is this far (s) behind the states


class EstimateWatch:
    """The newest wrench estimate's stamp, its lag behind the states, and whether it has kept up since a blind
    stop. ``max_estimate_age``: s of sim time a move goes on without a fresh estimate (0: never stop for that);
    ``blind_travel``: m the struts may cover in the estimates' lag (0: no speed limit)."""

    def __init__(self, max_estimate_age: float = MAX_ESTIMATE_AGE_S, blind_travel: float = BLIND_TRAVEL_M):
        self.max_estimate_age = float(max_estimate_age)
        self.blind_travel = float(blind_travel)
        self.newest = -np.inf  # stamp of the newest wrench estimate heard (s)
        self._lags = np.zeros((0, 2))  # (newest state time, its lag behind it of the newest estimate), s
        self._fresh_since: float | None = None  # since when (s) the estimates have kept up after a blind stop

    @property
    def heard(self) -> bool:
        """Whether any estimate has arrived (before one, no estimator runs: moves are unguarded)."""
        return bool(np.isfinite(self.newest))

    def arrived(self, stamps) -> None:
        """Wrench estimates arrived with these stamps [n] (s)."""
        self.newest = max(self.newest, float(np.max(stamps)))

    def checked(self, newest_state_time: float) -> None:
        """A check at the newest joint state's stamp (s): the estimates' lag behind it is remembered."""
        if self.heard:
            keep = self._lags[:, 0] >= newest_state_time - LAG_MEMORY_S
            self._lags = np.vstack([self._lags[keep], [newest_state_time, newest_state_time - self.newest]])

    def age(self, newest_state_time: float, since: float) -> float:
        """How long (s) before ``newest_state_time`` the load was last seen: the newest estimate, or ``since`` (a
        move's start) if that is later."""
        return newest_state_time - max(self.newest, since)

    @property
    def lag(self) -> float:
        """The largest lag (s) of the newest wrench estimate behind the newest state over the last LAG_MEMORY_S;
        0 before any."""
        return float(self._lags[:, 1].max()) if len(self._lags) else 0.0

    def speed_limit(self) -> float:
        """Strut speed (m/s) at which the struts cover at most ``blind_travel`` in the estimates' lag (inf when no
        estimator was heard or ``blind_travel`` is 0). Every lag counts in full, also one beyond
        ``max_estimate_age``, so one stall slows the next moves for LAG_MEMORY_S: counting it at most as
        ``max_estimate_age`` would rely on the blind pause, which comes late when kinematics itself is starved
        of CPU, and moves resumed at that speed ran through their stops."""
        if self.blind_travel <= 0 or not self.heard:
            return float("inf")
        return self.blind_travel / max(self.lag, 1e-3)

    def reset_freshness(self) -> None:
        """A blind stop began or was dropped: the estimates must keep up afresh before one may end."""
        self._fresh_since = None

    def kept_up(self, newest_state_time: float) -> bool:
        """Whether the estimates have been fresh (within half of ``max_estimate_age`` of ``newest_state_time``, s)
        for RESUME_FRESH_S without a break: an estimator that keeps falling behind does not end a blind stop."""
        if newest_state_time - self.newest > 0.5 * self.max_estimate_age:
            self._fresh_since = None
            return False
        if self._fresh_since is None:
            self._fresh_since = newest_state_time
        return newest_state_time - self._fresh_since >= RESUME_FRESH_S


class CheckGaps:
    """The emulator times (s) at which the guard checked the load over the last CHECK_MEMORY_S: a node starved
    of CPU checks late, so the next check is assumed no sooner than the largest recent gap."""

    def __init__(self):
        self._times = np.zeros(0)

    def checked(self, newest_state_time: float) -> None:
        """A check at the newest joint state's stamp (s)."""
        times = self._times
        self._times = np.append(times[times >= newest_state_time - CHECK_MEMORY_S], newest_state_time)

    @property
    def gap(self) -> float:
        """The largest gap (s of sim time) between consecutive checks over the last CHECK_MEMORY_S, at most
        MAX_WINDOW_S (a longer silence trips the guard blind instead); 0 before two checks."""
        gaps = np.diff(self._times)
        return float(min(gaps.max(), MAX_WINDOW_S)) if gaps.size else 0.0
