"""rclpy helpers shared by the suite's nodes: run loop, diagnostics, message conversion."""

from __future__ import annotations

import os
import signal
import sys
import time

import numpy as np
import rclpy
from builtin_interfaces.msg import Duration as DurationMsg
from builtin_interfaces.msg import Time as TimeMsg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType, SetParametersResult
from rclpy._rclpy_pybind11 import RCLError
from rclpy.clock import Clock, ClockType
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher

from ..errors import ConfigError, InvalidInputError, MalformedMessageError
from ..kinematics.rotations import (
    MESSAGE_QUATERNION_TOLERANCE,
    pose_from_position_quaternion,
    pose_to_position_quaternion,
)
from ..messages.cdr import stamp_parts
from ..messages.fields import BASE_FRAME, check_frame, check_time
from ..messages.malformed import MalformedCounter
from ..parameters.spec import ParameterSpec
from ..rate_limit import RepeatedLine
from ..robot import LEG_NAMES, VIB_NAMES
from ..safe_yaml import load_yaml

# History depth of the 500 Hz streams (publishers and subscribers): with reliable KEEP_LAST QoS a
# reader that stalls longer than depth / rate loses samples. 6 s of sim time at real time, 3 s at twice real
# time: on a 2-core machine shared with a browser and a test run (load average 7-10) kinematics once stalled
# ~1.4 s and lost 196 states with 1 s of depth; beside a CPU hog at twice real time the estimator lost 109
# states with 1.5 s (of wall time). The memory is ~1 MB per endpoint.
STREAM_DEPTH = 3000

OK, WARN, ERROR, STALE = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR, DiagnosticStatus.STALE


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


def run_node(factory, args=None, executor: str = "events") -> int:
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
    is no time is dropped (``guard_sim_clock``).
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
        if node is not None:
            if hasattr(node, "shutdown"):
                node.shutdown()
            node.destroy_node()
        rclpy.try_shutdown()
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


PARAMETER_TYPES = {"double": ParameterType.PARAMETER_DOUBLE, "integer": ParameterType.PARAMETER_INTEGER,
                   "string": ParameterType.PARAMETER_STRING, "bool": ParameterType.PARAMETER_BOOL,
                   "string_array": ParameterType.PARAMETER_STRING_ARRAY}


def descriptor_of(spec: ParameterSpec) -> ParameterDescriptor:
    """The rclpy descriptor of a parameter spec: its type, description (with the unit), read-only flag and
    range (what ``ros2 param describe`` shows and rclpy enforces on a set)."""
    description = f"{spec.description} [{spec.unit}]" if spec.unit else spec.description
    descriptor = ParameterDescriptor(name=spec.name, type=PARAMETER_TYPES[spec.kind], description=description,
                                     read_only=spec.read_only)
    low, high = spec.bounds
    if spec.kind == "double" and (spec.low is not None or spec.high is not None):
        descriptor.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)]
    elif spec.kind == "integer":
        descriptor.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
    return descriptor


def declare_spec(node, spec: ParameterSpec):
    """Declare one parameter from its spec and return its value.

    The value given at start (``-p name:=value``, a params file) is read through rclpy's public API: a first,
    dynamically typed declaration takes whatever was given; it is checked against the spec (an integer for a
    double is that number) and then declared with the spec's descriptor, overrides ignored, so rclpy's own
    type check never refuses a value the spec accepts. ValueError naming the parameter for a value of the
    wrong kind or out of range (the node then exits with that line)."""
    loose = ParameterDescriptor(description=spec.description, dynamic_typing=True)
    given = node.declare_parameter(spec.name, spec.default, loose).value
    node.undeclare_parameter(spec.name)
    try:
        value = spec.checked(given)
    except InvalidInputError as exc:
        raise ValueError(str(exc)) from None
    if spec.kind == "string_array" and not value:
        value = [""]  # rclpy cannot type an empty list; the nodes drop empty names
    return node.declare_parameter(spec.name, value, descriptor_of(spec), ignore_override=True).value


def declare_table(node, specs) -> dict:
    """Declare every parameter of a node's table (parameters.tables) and check every later set against the
    same specs (an on-set callback: a refused value's reason names the parameter); an integer set on a double
    (``ros2 param set ... real_time_factor 0``) is taken as that number (a pre-set callback). Returns
    {name: value}."""
    values = {spec.name: declare_spec(node, spec) for spec in specs}
    by_name = {spec.name: spec for spec in specs}
    doubles = {spec.name for spec in specs if spec.kind == "double"}

    def integers_as_doubles(params) -> list:
        return [Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
                if p.name in doubles and p.type_ == Parameter.Type.INTEGER else p for p in params]

    def check_sets(params) -> SetParametersResult:
        for param in params:
            spec = by_name.get(param.name)
            if spec is None:
                continue
            try:
                spec.checked(param.value)
            except InvalidInputError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    node.add_pre_set_parameters_callback(integers_as_doubles)
    node.add_on_set_parameters_callback(check_sets)
    return values


class Diagnostics:
    """One DiagnosticStatus on /diagnostics, republished every ``period_s`` of wall time (so it goes on when
    /clock stops) and on change. Inputs registered with ``watch`` are checked on wall time: one that has not
    arrived within its timeout turns the status STALE, naming what is missing, until it arrives again."""

    values: dict[str, str]

    def __init__(self, node, name: str, period_s: float = 1.0):
        self._node = node
        self._name = f"{node.get_name()}: {name}"
        self._pub = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.level, self.message, self.values = OK, "starting", {}
        self._watched: dict[str, tuple[float, float, str]] = {}  # input -> (timeout s, last seen, hint)
        self._stale: tuple = ()
        self._outputs: dict[str, Publisher] = {}  # output name -> its publisher (matched readers are reported)
        self._started = time.monotonic()
        self.rejection_lines = RepeatedLine()  # the node's refusal log: one repeated line a second, with a count
        node.create_timer(period_s, self.publish, clock=Clock(clock_type=ClockType.STEADY_TIME))
        node.create_timer(0.25, self._check_inputs, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def watch(self, name: str, timeout_s: float, hint: str = "") -> None:
        """Expect input ``name`` at least every ``timeout_s`` (wall s) once it has started or the node has run
        that long; ``hint`` says which node provides it."""
        self._watched[name] = (timeout_s, self._started, hint)

    def report_readers(self, name: str, publisher: Publisher) -> None:
        """Report how many subscriptions ``publisher`` (output ``name``) has matched, as the value
        "matched_subscribers <name>" of every status: who really receives it (a reader the graph shows
        may not be matched yet)."""
        self._outputs[name] = publisher

    def seen(self, name: str) -> None:
        """Input ``name`` arrived now."""
        timeout, _, hint = self._watched[name]
        self._watched[name] = (timeout, time.monotonic(), hint)

    def _check_inputs(self) -> None:
        now = time.monotonic()
        stale = tuple(f"no {name} for {now - last:.1f} s{f' ({hint})' if hint else ''}"
                      for name, (timeout, last, hint) in self._watched.items() if now - last > timeout)
        if bool(stale) != bool(self._stale) or (stale and self._stale and len(stale) != len(self._stale)):
            self._stale = stale
            self.publish()
        self._stale = stale

    def set(self, level: bytes, message: str, **values) -> None:
        changed = (level, message) != (self.level, self.message)
        self.level, self.message = level, message
        self.values.update({k: str(v) for k, v in values.items()})
        if changed:
            self.publish()

    def publish(self) -> None:
        for name, publisher in self._outputs.items():
            self.values[f"matched_subscribers {name}"] = str(publisher.get_subscription_count())
        level, message = self.level, self.message
        if self._stale:  # an ERROR of the node's own stays ERROR; the missing inputs are named either way
            level = ERROR if level == ERROR else STALE
            message = f"stale: {'; '.join(self._stale)}; {message}"
        status = DiagnosticStatus(
            level=level,
            name=self._name,
            message=message,
            hardware_id="stewart_vibration",
            values=[KeyValue(key=k, value=v) for k, v in sorted(self.values.items())],
        )
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self._node.get_clock().now().to_msg()
        self._pub.publish(msg)


def reject(node, diagnostics: Diagnostics, what: str, reason: str, log: bool = True) -> None:
    """Log a rejected input with its reason (unless ``log`` is False: the caller logs, rate-limited) and report
    it on /diagnostics (WARN)."""
    if log:
        line = diagnostics.rejection_lines.line(f"rejected {what}: {reason}", time.monotonic())
        if line is not None:
            node.get_logger().warning(line)
    diagnostics.set(WARN, f"rejected {what}: {reason}", last_rejection=reason)


class MalformedInputs:
    """Malformed messages a node ignored (it goes on with its last good state): counted per input
    (messages.malformed.MalformedCounter), logged -- the first of each reason, then at most one line per
    second per input -- and reported on /diagnostics as ``malformed <input>`` counts (``diagnostics`` None:
    logged only, e.g. the runner's client)."""

    LOG_CHARACTERS = 300  # a logged reason is cut here (a hostile message can be megabytes)

    def __init__(self, node, diagnostics: Diagnostics | None):
        self.node, self.diagnostics = node, diagnostics
        self.counter = MalformedCounter()

    def read(self, input_name: str, parse, data):
        """``parse(data)``, or None after counting the MalformedMessageError it raised for ``input_name``."""
        try:
            return parse(data)
        except MalformedMessageError as exc:
            self.refuse(input_name, exc)
            return None

    def refuse(self, input_name: str, error: Exception, count: int = 1) -> None:
        """``count`` malformed messages of ``input_name`` (topic or service), ``error`` saying why."""
        # a typed core error (e.g. a trajectory's InvalidInputError) names its fault in its first words
        reason = error.reason if isinstance(error, MalformedMessageError) else f"{type(error).__name__} {error}"[:48]
        text = str(error)[:self.LOG_CHARACTERS]
        log = self.counter.record(input_name, reason, text, time.monotonic(), count)
        if self.diagnostics is not None:
            self.diagnostics.values.update(self.counter.values())
        if log:
            self.node.get_logger().warning(f"ignored malformed {input_name} ({self.counter.counts[input_name]} so "
                                           f"far): {text}")
            if self.diagnostics is not None:
                self.diagnostics.publish()


def pose_from_msg(msg) -> np.ndarray:
    """geometry_msgs/Pose -> pose [x, y, z, roll, pitch, yaw]; the quaternion is normalised if its norm is
    within 1e-3 of 1 (hand-typed input), InvalidInputError on NaN or a quaternion further off."""
    p, q = msg.position, msg.orientation
    return pose_from_position_quaternion([p.x, p.y, p.z], [q.x, q.y, q.z, q.w],
                                         unit_tolerance=MESSAGE_QUATERNION_TOLERANCE)


def pose_stamped(pose, stamp, frame_id: str = BASE_FRAME) -> PoseStamped:
    """Pose vector -> geometry_msgs/PoseStamped in ``frame_id``."""
    position, quat = pose_to_position_quaternion(pose)
    msg = PoseStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in position)
    o = msg.pose.orientation
    o.x, o.y, o.z, o.w = (float(v) for v in quat)
    return msg


def named_values(names, values, wanted) -> np.ndarray | None:
    """Values for ``wanted`` names (in that order) from parallel name/value lists, None if any is missing."""
    index = {name: i for i, name in enumerate(names)}
    if len(values) < len(names) or any(name not in index for name in wanted):
        return None
    return np.array([values[index[name]] for name in wanted], dtype=float)


def emulator_now(node, state_time: float | None, fallback: float = 0.0) -> float:
    """The emulator's time as best known to ``node`` (s): on sim time the newer of /clock and the newest joint
    state's stamp ``state_time`` (a node may lag behind its input under load; /clock arrives unbatched), else
    ``state_time`` (``fallback`` before any state)."""
    now = state_time if state_time is not None else fallback
    clock = node.get_clock()
    if clock.ros_time_is_active:  # use_sim_time: the clock follows /clock (no parameter lookup per call)
        now = max(now, clock.now().nanoseconds * 1e-9)
    return now


class RawBatcher:
    """Raw messages queued by a subscription callback and handed to ``handler(messages, arrival_times)`` in
    batches: as soon as ``batch_size`` have queued (the emulator publishes its 500 Hz states in bursts of
    pace_period / state period, 10 by default, so a burst is processed the moment it is complete), and on a
    wall-clock timer every ``period_s`` for whatever is left. Batches amortise the per-call cost of the
    vectorised core; arrival times (time.monotonic) give the processing lag."""

    def __init__(self, node, batch_size: int, period_s: float, handler):
        self.batch_size, self.handler = int(batch_size), handler
        self.pending: list[bytes] = []
        self.arrivals: list[float] = []
        node.create_timer(period_s, self.flush, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def add(self, data: bytes) -> None:
        self.pending.append(data)
        self.arrivals.append(time.monotonic())
        if len(self.pending) >= self.batch_size:
            self.flush()

    def flush(self) -> None:
        if not self.pending:
            return
        messages, arrivals = self.pending, np.array(self.arrivals)
        self.pending, self.arrivals = [], []
        self.handler(messages, arrivals)


class JointColumns:
    """Column indices of leg_1..6 and of vib_1..6 in a JointState's names: (legs, vib), each an index
    array or None when a name is missing; both None when a name repeats (which column would it be?). Cached
    per name tuple (a stream repeats its names; at most MAX_LAYOUTS are kept, a fuzzer sends many)."""

    MAX_LAYOUTS = 64

    def __init__(self):
        self._cache = {}

    def __call__(self, names: tuple):
        if names not in self._cache:
            if len(self._cache) >= self.MAX_LAYOUTS:
                self._cache.clear()
            index = {n: i for i, n in enumerate(names)}
            if len(index) != len(names):
                self._cache[names] = (None, None)
                return self._cache[names]

            def find(wanted):
                return np.array([index[n] for n in wanted]) if all(n in index for n in wanted) else None

            self._cache[names] = (find(LEG_NAMES), find(VIB_NAMES))
        return self._cache[names]


def duration_msg(seconds: float) -> DurationMsg:
    """builtin_interfaces/Duration of ``seconds`` (s), rounded to the nanosecond."""
    sec, nanosec = divmod(int(round(seconds * 1e9)), 1_000_000_000)  # 0.9999999999 -> 1 s, not 0 s
    return DurationMsg(sec=sec, nanosec=nanosec)


def duration_seconds(msg) -> float:
    """Seconds of a builtin_interfaces/Duration."""
    return msg.sec + msg.nanosec * 1e-9


def stamp_seconds(stamp) -> float:
    """Seconds of a builtin_interfaces/Time stamp."""
    return stamp.sec + stamp.nanosec * 1e-9


def time_message(seconds: float) -> TimeMsg:
    """builtin_interfaces/Time of ``seconds`` (s)."""
    sec, nanosec = stamp_parts(seconds)
    return TimeMsg(sec=sec, nanosec=nanosec)


__all__ = [
    "STREAM_DEPTH",
    "BASE_FRAME",
    "check_frame",
    "ERROR",
    "LEG_NAMES",
    "OK",
    "STALE",
    "VIB_NAMES",
    "WARN",
    "Diagnostics",
    "InvalidInputError",
    "JointColumns",
    "MalformedInputs",
    "RawBatcher",
    "duration_msg",
    "duration_seconds",
    "declare_spec",
    "declare_table",
    "descriptor_of",
    "make_executor",
    "spin_until_stopped",
    "StopFlag",
    "named_values",
    "pose_from_msg",
    "pose_stamped",
    "reject",
    "init_rclpy",
    "run_node",
    "stamp_seconds",
]
