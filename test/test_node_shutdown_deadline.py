"""A stopped node ends even when its shutdown hangs (run_loop.run_node): real rclpy in a child process, SIGTERM, a
shutdown that never returns; the process exits 1 after the deadline with every thread's traceback in its stderr.
A shutdown that returns ends the process at once with 0."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import time

import pytest

from stewart_vibration.runtime.processes import ros_environment

pytestmark = pytest.mark.integration

NODE = textwrap.dedent("""
    import sys, time
    from rclpy.node import Node
    from stewart_vibration.nodes.run_loop import run_node

    class Sleeper(Node):
        def __init__(self):
            super().__init__("sleeper")
            print("spinning", flush=True)

        def shutdown(self):
            if sys.argv[1] == "hang":
                time.sleep(3600)  # stands for a DDS call that never returns

    sys.exit(run_node(Sleeper, [], shutdown_deadline_s=2.0))
""")


@pytest.mark.parametrize("shutdown", ["hang", "return"])
def test_a_node_ends_after_sigterm_within_its_shutdown_deadline(ros_domain, shutdown):
    proc = subprocess.Popen([sys.executable, "-c", NODE, shutdown], env=ros_environment(ros_domain),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "spinning", proc.stderr.read()
        proc.send_signal(signal.SIGTERM)
        sent = time.monotonic()
        code = proc.wait(timeout=30)
        took = time.monotonic() - sent
        stderr = proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
    if shutdown == "hang":
        assert code == 1 and 2.0 <= took < 15.0, (code, took, stderr)
        assert "Timeout" in stderr and "in shutdown" in stderr, stderr  # the stuck call, named
    else:
        assert code == 0 and took < 2.0, (code, took, stderr)
