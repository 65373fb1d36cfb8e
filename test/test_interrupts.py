"""DeferredInterrupts: a real SIGINT inside deferred() waits for the block's end; outside, it interrupts at once."""

from __future__ import annotations

import os
import signal
import time

import pytest

from stewart_vibration.runtime.interrupts import DeferredInterrupts


@pytest.fixture
def interrupts():
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    handler = DeferredInterrupts()
    handler.install()
    yield handler
    for signum, old in saved.items():
        signal.signal(signum, old)


def _wait_for_signal_delivery():
    deadline = time.monotonic() + 1.0
    while time.monotonic() < deadline:
        time.sleep(0.001)


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_inside_the_block_is_raised_after_it(interrupts, signum):
    ran_to_end = False
    with pytest.raises(KeyboardInterrupt):
        with interrupts.deferred():
            os.kill(os.getpid(), signum)
            _wait_for_signal_delivery()  # the handler has run by now: it must not have raised here
            ran_to_end = True
    assert ran_to_end and interrupts.pending is None


def test_nested_blocks_raise_once_at_the_outermost_end(interrupts):
    inner_done = False
    with pytest.raises(KeyboardInterrupt):
        with interrupts.deferred():
            with interrupts.deferred():
                os.kill(os.getpid(), signal.SIGINT)
                _wait_for_signal_delivery()
            inner_done = True
    assert inner_done


def test_outside_a_block_a_signal_interrupts_at_once(interrupts):
    with pytest.raises(KeyboardInterrupt):
        os.kill(os.getpid(), signal.SIGINT)
        _wait_for_signal_delivery()
        pytest.fail("not interrupted")
    with interrupts.deferred():  # nothing pending afterwards
        pass
