"""Starting a suite node and running it until it is stopped (rclpy): ``rclpy.init`` after every parameter
file is read safely, the executor, the SIGINT / SIGTERM stop flag and the spin loop, the guard on /clock
messages that are no time, and the history depth of the 500 Hz streams. Periods in wall s."""

from __future__ import annotations

import faulthandler
import os
import signal
import sys

import rclpy
from rclpy._rclpy_pybind11 import RCLError
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from ..errors import ConfigError, MalformedMessageError
from ..messages.fields import check_time
from ..safe_yaml import load_yaml
from .diagnostics import MalformedInputs

# History depth of the 500 Hz streams (publishers and subscribers): with reliable KEEP_LAST QoS a
# reader that stalls longer than depth / rate loses samples. 6 s of sim time at real time, 3 s at twice real
# time: on a 2-core machine shared with a browser and a test run (load average 7-10) kinematics once stalled
# ~1.4 s and lost 196 states with 1 s of depth; beside a CPU hog at twice real time the estimator lost 109
# states with 1.5 s (of wall time). The memory is ~1 MB per endpoint.
STREAM_DEPTH = 3000
# The longest a stopped node may take to end (wall s): the recorder finishing an hour's MCAP needs a few seconds; a
# node still alive after it is stuck (a DDS call that never returns) and would hold its domain and a core
SHUTDOWN_DEADLINE_S = 20.0
# the status topics (the robot's vibration status, the force guard's): a late joiner gets the current state
STATUS_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def make_executor(context=None):
    """rclpy's EventsExecutor (keeps up with >= 5,000 msg/s) or the single-threaded one, on ``context``
    (default: the global one)."""
    try:
        from rclpy.experimental import EventsExecutor

        return EventsExecutor(context=context)
    except Exception:  # noqa: BLE001 - older rclpy
        from rclpy.executors import SingleThreadedExecutor

        return SingleThreadedExecutor(context=context)


class StopFlag:
    """Set by the SIGINT / SIGTERM handlers (``install``), read by the spin loop. A plain attribute, no lock: a
    threading.Event set from a handler deadlocked a node when a second signal arrived while the first
    handler was inside Event.set (CI: an estimator hung after its runner was killed, holding its domain)."""

    def __init__(self) -> None:
        self.raised = False

    def set(self, *_args) -> None:
        """Raise the flag (signature of a signal handler)."""
        self.raised = True

    def is_set(self) -> bool:
        """Whether a stop signal arrived."""
        return self.raised

    def install(self, signals=(signal.SIGINT, signal.SIGTERM)) -> StopFlag:
        """Make ``signals`` raise this flag; returns it."""
        for signum in signals:
            signal.signal(signum, self.set)
        return self


def spin_until_stopped(executor, stop, period_s: float = 0.2) -> None:
    """Spin until ``stop`` (a StopFlag raised by a signal handler) is set or the context shuts down.

    The executor runs in C++ for ``period_s`` at a time (spin_until_future_complete on a future that never
    completes) rather than returning to Python after every event: a fifth less CPU per message than a
    spin_once loop at the suite's 500 Hz streams. Python signal handlers run between those periods.
    """
    import rclpy
    from rclpy.task import Future

    never = Future()
    while not stop.is_set() and rclpy.ok():
        executor.spin_until_future_complete(never, timeout_sec=period_s)


def guard_sim_clock() -> None:
    """Make rclpy's sim-time clock subscription drop a /clock message that is no time (negative seconds: rclpy's
    TimeSource raises in its callback and the node dies; nanosec >= 1e9: the clock jumps) instead of taking it,
    counting it as ``malformed /clock`` on the node's MalformedInputs (its ``malformed`` attribute) if it has one.
    rclpy subscribes /clock itself (use_sim_time), so its callback is wrapped, once per process, before any node
    is made."""
    from rclpy.time_source import TimeSource

    taken = TimeSource.clock_callback
    if getattr(taken, "checked", False):
        return

    def clock_callback(self, msg) -> None:
        try:
            check_time(msg.clock.sec, msg.clock.nanosec, "clock")
        except MalformedMessageError as exc:
            node = self._get_node()
            malformed = getattr(node, "malformed", None)
            if isinstance(malformed, MalformedInputs):
                malformed.refuse("/clock", exc)
            return
        taken(self, msg)

    clock_callback.checked = True  # type: ignore[attr-defined]
    TimeSource.clock_callback = clock_callback  # type: ignore[method-assign]


def run_node(factory, args=None, executor: str = "events", shutdown_deadline_s: float = SHUTDOWN_DEADLINE_S) -> int:
    """rclpy.init, spin the node from ``factory()`` until SIGINT / SIGTERM, clean up; returns the exit code.

    The signals only set a stop flag (no KeyboardInterrupt inside a callback);
    the executor is spun in periods of 0.2 s in C++ that check it in between (spin_until_stopped).
    ``executor="events"``: rclpy's EventsExecutor (half the CPU of the
    SingleThreadedExecutor at the suite's 500 Hz state rate). Its sim-time
    timers fire irregularly under load: timing-critical work polls the sim
    clock from a steady timer instead.
    ``executor="single"`` or STEWART_EXECUTOR=single selects the
    SingleThreadedExecutor. A node may define ``shutdown()``; it runs
    before the node is destroyed (e.g. to stop a physics thread or finish a file).
    A node that cannot start (bad ``--ros-args``, a parameter file that cannot be read, bad parameter or
    configuration) prints one line saying why and returns 2, without a traceback. A /clock message that
    is no time is dropped (``guard_sim_clock``). A node that has stopped spinning must end: if its shutdown
    (``shutdown()``, destroying the node, rclpy's) has not returned after ``shutdown_deadline_s``, every
    thread's traceback goes to stderr and the process exits with 1 (faulthandler's own thread does it, so a
    call that never returns while holding the GIL cannot stop it).
    """
    if not init_rclpy(args):
        return 2
    guard_sim_clock()
    stop = StopFlag().install()
    node = None
    code = 0
    try:
        try:
            node = factory()
        except (KeyboardInterrupt, ExternalShutdownException):
            raise
        except Exception as exc:  # noqa: BLE001 - any start-up failure: one clear line, exit code 2
            print(f"[FATAL] cannot start: {type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
            return 2
        if executor == "single" or os.environ.get("STEWART_EXECUTOR") == "single":
            spinner = SingleThreadedExecutor()
        else:
            spinner = make_executor()
        spinner.add_node(node)
        spin_until_stopped(spinner, stop)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        faulthandler.dump_traceback_later(shutdown_deadline_s, exit=True)
        if node is not None:
            if hasattr(node, "shutdown"):
                node.shutdown()
            node.destroy_node()
        rclpy.try_shutdown()
        faulthandler.cancel_dump_traceback_later()
    return code


def params_file_arguments(argv) -> list[str]:
    """The files named by ``--params-file`` in a node's command line ``argv``."""
    return [argv[i + 1] for i, arg in enumerate(argv[:-1]) if arg == "--params-file"]


def init_rclpy(args=None, prefix: str = "[FATAL] cannot start:") -> bool:
    """``rclpy.init(args)`` after reading every ``--params-file`` safely; False (with one line on stderr after
    ``prefix``) if a parameter file cannot be read or rcl refuses the arguments, instead of a traceback."""
    try:
        for path in params_file_arguments(sys.argv if args is None else args):
            load_yaml(path, "node parameter file")  # rcl's own reader blocks on a FIFO and says less
        rclpy.init(args=args)
    except (ConfigError, RCLError) as exc:
        print(f"{prefix} {' '.join(str(exc).split())}", file=sys.stderr, flush=True)
        return False
    return True


__all__ = [
    "STATUS_QOS",
    "SHUTDOWN_DEADLINE_S",
    "STREAM_DEPTH",
    "make_executor",
    "StopFlag",
    "spin_until_stopped",
    "guard_sim_clock",
    "run_node",
    "params_file_arguments",
    "init_rclpy",
]
