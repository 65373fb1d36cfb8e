"""Log lines that repeat: one line a second per refusal, with the count of those left out."""

from __future__ import annotations

from stewart_vibration.rate_limit import RepeatedLine


def test_a_repeated_line_is_logged_once_per_interval_with_the_count_left_out():
    lines = RepeatedLine(interval_s=1.0)
    times = [0.0, 0.1, 0.2, 0.9, 1.05, 1.5]
    got = [lines.line("refused: blocked", t) for t in times]
    assert got[0] == "refused: blocked"
    assert got[1:4] == [None, None, None]
    assert got[4] == "refused: blocked (3 repeats of the previous line not logged)"
    assert got[5] is None


def test_a_different_line_is_logged_at_once_and_carries_the_count_of_the_last():
    lines = RepeatedLine(interval_s=1.0)
    assert lines.line("a", 0.0) == "a"
    assert lines.line("a", 0.1) is None
    assert lines.line("b", 0.2) == "b (1 repeats of the previous line not logged)"
    assert lines.line("a", 0.3) == "a"
