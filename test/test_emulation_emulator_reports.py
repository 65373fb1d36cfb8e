"""The emulator's report bookkeeping (emulation.emulator_reports) on a stepped wall clock: which repeated
events get a log line, a latched fault or e-stop first in the health message, vibration/status at once on news
and again after a second unchanged, refused commands all counted but logged once a second per kind."""

from __future__ import annotations

from stewart_vibration.emulation.emulator_reports import RejectionTally, StatusRepeats, latched_first, thinned
from stewart_vibration.emulation.physics_guard import PhysicsFault


class SteppedWall:
    """A wall clock (s) the test moves by hand."""

    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def test_thinned_logs_the_first_few_then_every_nth():
    logged = [n for n in range(1, 3001) if thinned(n, 3, 1000)]
    assert logged == [1, 2, 3, 1000, 2000, 3000]


def test_a_latched_fault_comes_first_then_an_estop_else_the_message_alone():
    fault = PhysicsFault(time=12.3456, reason="non-finite state")
    assert latched_first("running", fault, estopped=True) == (
        "physics fault latched at 12.346 s: non-finite state; robot held (cleanup + configure to rebuild); running")
    assert latched_first("running", None, estopped=True) == (
        "emergency stop latched (call hardware_emulator/reset to clear); running")
    assert latched_first("running", None, estopped=False) == "running"


def test_status_news_goes_out_at_once_and_an_unchanged_status_after_most_of_a_second():
    wall = SteppedWall()
    repeats = StatusRepeats(1.0, clock=wall)
    assert repeats.repeat_due()  # nothing sent yet
    assert repeats.is_news(0, changed=False)  # the first report: its event was never sent
    repeats.sent(0)
    assert not repeats.is_news(0, changed=False)
    assert repeats.is_news(0, changed=True)
    assert repeats.is_news(1, changed=False)  # a new command event
    wall.t += 0.85
    assert not repeats.repeat_due()
    wall.t += 0.06  # 0.91 s: due (the 1 s timer's jitter does not put it off a whole period)
    assert repeats.repeat_due()
    repeats.sent(1)
    assert not repeats.repeat_due()
    assert not repeats.is_news(1, changed=False)


def test_every_rejection_counts_and_each_kind_logs_at_most_once_a_second():
    wall = SteppedWall()
    tally = RejectionTally(1.0, clock=wall)
    too_far = "stroke_max: leg 3 would reach 0.61 m"
    assert tally.add("leg trajectory", too_far)
    wall.t += 0.5
    assert not tally.add("leg trajectory", "stroke_max: leg 4 would reach 0.62 m")  # same kind: first clause
    assert tally.add("leg trajectory", "the hardware emulator is inactive")  # another reason
    assert tally.add("vibration command", too_far)  # another command
    wall.t += 0.5
    assert tally.add("leg trajectory", too_far)  # a second after the first line
    assert tally.count == 5
