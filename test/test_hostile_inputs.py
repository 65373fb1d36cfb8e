"""Hostile input through every message-to-core validation path, property-based.

Hypothesis generates malformed and boundary inputs (NaN/inf, huge values, wrong names, sizes, frames and
stamps, non-increasing times, discontinuous splices, garbage bytes) next to legal ones, and checks for
each: only the library's typed errors (StewartError) escape, every refusal says why (a non-empty
message), and whatever is accepted keeps every joint within its limits -- judged on the command the
emulator will actually follow, sampled densely (and on the physics step grid around every knot, where a
velocity step would show), not on the checker's own points. Example counts (MAX_EXAMPLES) add up to
more than 10,000.
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from stewart_vibration import load_robot
from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.emulation.strut_trajectory import build_trajectory
from stewart_vibration.emulation.vibration_buffer import VibrationBuffer
from stewart_vibration.errors import (
    InvalidInputError,
    StewartError,
    VibrationLimitError,
)
from stewart_vibration.kinematics import check_pose, condition_number, joint_angles, leg_vectors
from stewart_vibration.kinematics.rotations import (
    pose_from_position_quaternion,
    quaternion_from_rpy,
    rotation_from_quaternion,
    rotation_from_rpy,
)
from stewart_vibration.messages.joint_states import JointStateDecoder, JointStateEncoder, decode_joint_states
from stewart_vibration.messages.joint_trajectory import decode_joint_trajectory, encode_joint_trajectory
from stewart_vibration.messages.stamped_doubles import PoseStampedEncoder, decode_pose_stamped
from stewart_vibration.motion.force_guard import ForceGuard
from stewart_vibration.motion.move_goal import move_request
from stewart_vibration.motion.path_plan import path_waypoints
from stewart_vibration.motion.path_plan import plan_path as path_plan
from stewart_vibration.motion.profiles import minimum_jerk, minimum_jerk_duration
from stewart_vibration.nodes.move_messages import base_pose
from stewart_vibration.nodes.outcomes import NAMES, outcome_of
from stewart_vibration.paper import paper_pose
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES
from stewart_vibration.sim.mjcf import load_simulation_settings
from stewart_vibration.splines import spline_segments
from stewart_vibration.vibration import decompose_vibration
from stewart_vibration.vibration.feasibility import check_command_limits
from stewart_vibration.vibration.settings import SETTINGS, default_settings, settings_reason
from stewart_vibration.vibration.streaming import StreamSettings, VibrationStream
from stewart_vibration.vibration.waveform import sinusoid
from stewart_vibration_interfaces.action import MoveToPose
from stewart_vibration_interfaces.srv import PlanPath

# hostile numbers (1e308, inf) overflow inside numpy on their way to a refusal: expected, not worth a line each
pytestmark = [pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning"),
              pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")]
ROBOT = load_robot()
LIM, UNIT = ROBOT.limits, ROBOT.vibration_unit
HOME = np.asarray(ROBOT.home_pose, float)
REL = 1e-3  # sampling between the checkers' points: relative allowance on velocity and acceleration
STROKE_TOL = 1e-9  # m

# examples per property; the sum is the number of hostile inputs (>= 10,000)
MAX_EXAMPLES = {"pose": 2500, "struts": 2000, "vibration_emulator": 1000, "vibration_buffer": 800,
                "vibration_splices": 1000,
                "settings": 1200, "settings_plan": 300, "plan_path": 800, "cdr_trajectory": 600,
                "cdr_joint_state": 400, "cdr_joint_states": 300, "cdr_pose": 300}
assert sum(MAX_EXAMPLES.values()) >= 10_000
FAST_SHARE = 0.1 if os.environ.get("STEWART_FAST_TESTS") == "1" else 1.0  # ./tools/test --fast: a tenth of them


def examples(name: str):
    return settings(max_examples=max(10, round(MAX_EXAMPLES[name] * FAST_SHARE)), deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.filter_too_much])


def attempt(call, *args, label: str = ""):
    """(result, None), or (None, the typed refusal) after checking it says why; any other exception escapes.
    With a ``label``, the outcome is counted (pytest --hypothesis-show-statistics)."""
    try:
        result = call(*args)
    except StewartError as exc:
        assert str(exc).strip(), f"{type(exc).__name__} refused without a reason"
        if label:
            event(f"{label}: refused ({type(exc).__name__})")
        return None, exc
    if label:
        event(f"{label}: accepted")
    return result, None


# -- value strategies ----------------------------------------------------------------------------------
SPECIAL = [math.nan, math.inf, -math.inf, 0.0, -0.0, 1e308, -1e308, 5e-324, 1e9, -1e9, 1e-12]
ANY_FLOAT = st.floats(allow_nan=True, allow_infinity=True)


def near(center: float, spread: float):
    """Mostly within center +- spread, sometimes a special or any float."""
    return st.one_of(st.floats(center - spread, center + spread), st.floats(center - spread, center + spread),
                     st.floats(center - spread, center + spread), st.sampled_from(SPECIAL), ANY_FLOAT)


BAD_FRAMES = st.one_of(st.sampled_from(["world", "platform", "Base", "/base", "base ", " ", "base\x00", "odom"]),
                       st.text(max_size=12))
ANY_FRAME = st.one_of(st.sampled_from(["base", ""]), BAD_FRAMES)


@st.composite
def quaternions(draw, kind=None, tilt=0.6):
    """Unit quaternions (roll, pitch, yaw within +-tilt) scaled by 1 +- 2e-3 ("scaled") or by exactly the
    1e-3 tolerance +- 1e-9 ("edge"), within tolerance ("unit"), zero, with a special value, or any four floats."""
    kind = kind or draw(st.sampled_from(["scaled", "scaled", "edge", "zero", "special", "any"]))
    if kind == "zero":
        return [0.0, 0.0, 0.0, 0.0]
    if kind == "any":
        return draw(st.lists(ANY_FLOAT | st.floats(-1.5, 1.5), min_size=4, max_size=4))
    rpy = draw(st.lists(st.floats(-tilt, tilt), min_size=3, max_size=3))
    q = quaternion_from_rpy(np.array(rpy)) * draw(st.sampled_from([1.0, -1.0]))
    if kind == "unit":
        q = q * (1.0 + draw(st.floats(-0.999e-3, 0.999e-3) | st.sampled_from([0.0, 0.999e-3, -0.999e-3])))
    elif kind == "scaled":
        q = q * (1.0 + draw(st.floats(-2e-3, 2e-3)))
    elif kind == "edge":
        q = q * (1.0 + draw(st.sampled_from([1e-3, -1e-3])) * (1.0 + draw(st.sampled_from([-1e-6, 1e-6]))))
    else:
        q[draw(st.integers(0, 3))] = draw(st.sampled_from(SPECIAL))
    return [float(v) for v in q]


@st.composite
def pose_messages(draw, spread=0.04, tilt=0.6):
    """PoseStamped around the home pose (+- spread m, +- tilt rad): well-formed in base (half of them), or with
    a bad frame, position or quaternion, or bad everywhere."""
    corrupt = draw(st.sampled_from(["none"] * 5 + ["frame", "position", "quaternion", "all", "all"]))
    msg = PoseStamped()
    msg.header.frame_id = draw(BAD_FRAMES if corrupt == "frame" else ANY_FRAME if corrupt == "all"
                               else st.sampled_from(["base", ""]))
    p = msg.pose.position
    if corrupt in ("position", "all"):
        p.x, p.y, p.z = (draw(near(float(c), spread)) for c in HOME[:3])
    else:
        p.x, p.y, p.z = (draw(st.floats(float(c) - spread, float(c) + spread)) for c in HOME[:3])
    o = msg.pose.orientation
    o.x, o.y, o.z, o.w = draw(quaternions(None if corrupt in ("quaternion", "all") else "unit", tilt))
    return msg


def quaternion_of(msg) -> np.ndarray:
    o = msg.pose.orientation
    return np.array([o.x, o.y, o.z, o.w])


def assert_pose_feasible(poses) -> None:
    """Independent of check_pose: leg lengths within the stroke, joint angles within their limits,
    conditioning within condition_number_max, for every pose [n, 6]."""
    poses = np.atleast_2d(poses)
    assert np.isfinite(poses).all()
    lengths = np.linalg.norm(leg_vectors(ROBOT, poses), axis=-1)
    assert (lengths >= LIM.stroke_min - STROKE_TOL).all() and (lengths <= LIM.stroke_max + STROKE_TOL).all()
    universal, spherical = joint_angles(ROBOT, poses)
    assert (universal <= LIM.universal_joint_max + 1e-12).all() and (spherical <= LIM.spherical_joint_max + 1e-12).all()
    assert (condition_number(ROBOT, poses) <= LIM.condition_number_max * (1 + 1e-12)).all()


# -- 1. poses as messages: move goals --------------------------------------------------------------------
# the kinematics node's values a move goal's 0 stands for (its parameters' defaults)
NODE_SPEED_SCALE, NODE_FORCE_N, NODE_MOMENT_NM = 0.5, 200.0, 15.0
SLOWEST_SPEED_SCALE = 0.01  # the slowest move a goal may ask for (the speed_scale parameter's minimum too)


@st.composite
def move_goals(draw):
    """MoveToPose goals to the pose messages, their values mostly 0 (the node's), legal, or hostile."""
    speed = draw(st.one_of(st.just(0.0), st.just(0.0), st.floats(SLOWEST_SPEED_SCALE, 1.0), near(0.5, 0.6),
                           st.floats(0.0, 2 * SLOWEST_SPEED_SCALE)))
    force = draw(st.one_of(st.just(0.0), st.just(0.0), st.floats(0.0, NODE_FORCE_N), near(100.0, 150.0)))
    moment = draw(st.one_of(st.just(0.0), st.just(0.0), st.floats(0.0, NODE_MOMENT_NM), near(8.0, 10.0)))
    return MoveToPose.Goal(target=draw(pose_messages()), speed_scale=speed, force_limit_n=force,
                           moment_limit_nm=moment)


def message_goal(goal):
    """What the kinematics node does with a MoveToPose goal before it looks at the robot: the frame
    (UNKNOWN_FRAME), the pose (quaternion normalised within 1e-3), the values (0 = the node's; a goal may only
    lower a limit): the MoveRequest."""
    target = base_pose(goal.target, "target pose")
    return move_request(target, goal.speed_scale, goal.force_limit_n, goal.moment_limit_nm, NODE_SPEED_SCALE,
                        NODE_FORCE_N, NODE_MOMENT_NM)


def planned_move(request, goal_lengths):
    """What the node plans from home for ``request``: the minimum-jerk strut move at its speed scale, sampled
    (positions, velocities) and its duration."""
    home = check_pose(ROBOT, HOME)
    speed = LIM.strut_velocity_max * request.speed_scale
    duration = minimum_jerk_duration(home, goal_lengths, speed, 0.5)
    pos, vel, _ = minimum_jerk(home, goal_lengths, duration, np.linspace(0.0, duration, 101))
    return pos, vel, duration


def refused_as(refusal) -> str:
    """The outcome name a refusal ends a goal with: one of the table's, never INTERNAL_ERROR (a defect)."""
    code = outcome_of(refusal).code
    assert code in NAMES and NAMES[code] != "INTERNAL_ERROR", (type(refusal).__name__, refusal.outcome, str(refusal))
    return NAMES[code]


@examples("pose")
@given(goal=move_goals())
def test_move_goals_are_refused_with_their_code_or_reachable(goal):
    msg = goal.target
    request, refusal = attempt(message_goal, goal, label="goal")
    q = quaternion_of(msg)
    position = np.array([msg.pose.position.x, msg.pose.position.y, msg.pose.position.z])
    finite = bool(np.isfinite(q).all() and np.isfinite(position).all())
    norm = float(np.linalg.norm(q)) if finite else math.nan
    frame_ok = msg.header.frame_id in ("", "base")
    speed, force, moment = goal.speed_scale, goal.force_limit_n, goal.moment_limit_nm
    values_ok = bool(np.isfinite([speed, force, moment]).all() and (speed == 0.0 or SLOWEST_SPEED_SCALE <= speed <= 1.0)
                     and 0.0 <= force <= NODE_FORCE_N and 0.0 <= moment <= NODE_MOMENT_NM)
    if refusal is None:
        assert frame_ok and finite and abs(norm - 1.0) <= 1e-3 * (1 + 1e-9), (msg.header.frame_id, q, position)
        assert values_ok, (speed, force, moment)
        pose = request.target
        assert np.isfinite(pose).all()
        # the orientation is that of the normalised quaternion
        assert np.abs(rotation_from_rpy(pose[3:]) - rotation_from_quaternion(q / norm)).max() < 1e-9
        assert np.array_equal(pose[:3], position)
        # 0 = the node's values; a goal's own limit is never above the node's
        assert SLOWEST_SPEED_SCALE <= request.speed_scale <= 1.0 and request.speed_scale == (speed or NODE_SPEED_SCALE)
        assert (request.force_limit, request.moment_limit) == (force or NODE_FORCE_N, moment or NODE_MOMENT_NM)
        lengths, refusal = attempt(check_pose, ROBOT, pose, label="pose")
        if refusal is None:
            assert_pose_feasible(pose)
            assert np.abs(lengths - np.linalg.norm(leg_vectors(ROBOT, pose), axis=-1)).max() < 1e-12
            # the move it plans there at the goal's speed scale: finite, within that fraction of the strut speed
            planned, refusal = attempt(planned_move, request, lengths, label="plan")
            if refusal is None:
                pos, vel, duration = planned
                assert np.isfinite(duration) and np.isfinite(pos).all() and np.isfinite(vel).all()
                assert np.abs(vel).max() <= LIM.strut_velocity_max * request.speed_scale * (1 + REL)
            else:
                assert refused_as(refusal) in ("INVALID_ARGUMENT", "LIMIT_EXCEEDED"), str(refusal)
        else:
            assert refused_as(refusal) == "UNREACHABLE_POSE", str(refusal)
    else:
        # refused: a frame other than base, a bad number or a value out of its range; a unit quaternion (within
        # 1e-3) in base with values in range never is
        assert not (frame_ok and finite and abs(norm - 1.0) <= 1e-3 * (1 - 1e-9) and values_ok), \
            (msg.header.frame_id, q, (speed, force, moment), str(refusal))
        name = refused_as(refusal)
        # the first check that fails names the code: the frame, then the numbers
        assert name == ("UNKNOWN_FRAME" if not frame_ok else "INVALID_ARGUMENT"), (msg.header.frame_id, name,
                                                                                   str(refusal))


# -- 2. PlanPath requests -----------------------------------------------------------------------------
@st.composite
def plan_requests(draw):
    """PlanPath requests of 0-3 waypoints (one: from the pose estimate, which there may not be yet) and a speed
    scale, legal or hostile."""
    request = PlanPath.Request(waypoints=draw(st.lists(pose_messages(0.02, 0.3), min_size=0, max_size=3)))
    request.speed_scale = draw(st.one_of(st.just(0.0), st.floats(SLOWEST_SPEED_SCALE, 1.0), ANY_FLOAT))
    estimate = draw(st.sampled_from([None, "home", "paper"]))
    return request, {None: None, "home": HOME, "paper": paper_pose(ROBOT)}[estimate]


def plan_path(request, estimate):
    """The kinematics node's plan_path service for ``request`` with the pose estimate ``estimate`` (None: none
    yet): the waypoints' frames and poses (nodes.move_messages.base_pose), then motion.path_plan as the node calls
    it, its guard untripped."""
    poses, offset = path_waypoints([base_pose(msg, f"plan_path waypoint {i}")
                                    for i, msg in enumerate(request.waypoints)], estimate)
    guard = ForceGuard(ROBOT, NODE_FORCE_N, NODE_MOMENT_NM)
    plan = path_plan(ROBOT, poses, offset, request.speed_scale, NODE_SPEED_SCALE, 0.5, guard)
    return poses, plan.samples


@examples("plan_path")
@given(case=plan_requests())
def test_plan_path_requests_are_refused_with_their_code_or_every_sample_is_reachable(case):
    request, estimate = case
    result, refusal = attempt(plan_path, request, estimate, label="plan")
    if refusal is None:
        poses, samples = result
        assert np.allclose(samples[0], poses[0], atol=1e-12) and np.array_equal(samples[-1], poses[-1])
        assert_pose_feasible(samples)
        steps = np.linalg.norm(np.diff(samples[:, :3], axis=0), axis=1)
        assert steps.max(initial=0.0) <= 1e-3 * (1 + 1e-9)
        assert request.speed_scale == 0.0 or SLOWEST_SPEED_SCALE <= request.speed_scale <= 1.0
    else:
        assert refused_as(refusal) in ("INVALID_ARGUMENT", "UNKNOWN_FRAME", "NOT_READY", "UNREACHABLE_POSE",
                                       "LIMIT_EXCEEDED"), (type(refusal).__name__, str(refusal))


# -- 3. leg trajectories on the emulator ------------------------------------------------------------------
@pytest.fixture(scope="module")
def emu():
    """One emulator for the module, run 4 s so that past stamps are real times."""
    emulator = HardwareEmulator(ROBOT, load_simulation_settings(timestep=1 / 2000))
    emulator.advance(4.0)
    return emulator


@st.composite
def joint_names(draw, names, malformed=True):
    """A permutation of ``names`` (the columns follow it), or (``malformed``) mostly a malformed list."""
    perm = draw(st.permutations(range(6)))
    kind = draw(st.sampled_from(["ok"] + ["empty", "missing", "duplicate", "foreign", "extra"] * malformed))
    listed = [names[i] for i in perm]
    if kind == "empty":
        listed = []
    elif kind == "missing":
        listed = listed[:5]
    elif kind == "duplicate":
        listed[5] = listed[0]
    elif kind == "foreign":
        listed[draw(st.integers(0, 5))] = draw(st.sampled_from(["leg_7", "vib_1", "leg_1", "", "LEG_1"])
                                               | st.text(max_size=6))
    else:
        listed = listed + [draw(st.text(max_size=6))] if kind == "extra" else listed
    return listed, list(perm)


@st.composite
def point_times(draw, malformed=True, max_points=6, spacing=(0.05, 3.0)):
    """time_from_start [n]: increasing, or (``malformed``) mostly NaN, negative, repeated, empty..."""
    n = draw(st.integers(int(not malformed), max_points) | st.just(1) | st.just(2))
    kind = draw(st.sampled_from(["ok", "zero_first"] + ["any", "repeat", "decreasing", "special"] * malformed))
    if kind == "any":
        return np.array(draw(st.lists(ANY_FLOAT, min_size=n, max_size=n)))
    steps = np.array(draw(st.lists(st.floats(*spacing), min_size=n, max_size=n)))
    times = np.cumsum(steps)
    if kind == "zero_first" and n:
        times = times - times[0]
    elif n >= 2 and kind == "repeat":
        times[-1] = times[-2]
    elif n >= 2 and kind == "decreasing":
        times = times[::-1].copy()
    elif n and kind == "special":
        times[draw(st.integers(0, n - 1))] = draw(st.sampled_from(SPECIAL + [-1.0]))
    return times


def table(draw, rows, width, values, malformed=False):
    """[rows, width] from an element strategy, or (``malformed``) mostly a bad shape or value; list or ndarray."""
    kind = draw(st.sampled_from(["ok"] + ["rows-1", "rows+1", "narrow", "wide", "special", "empty_rows"] * malformed))
    data = np.array(draw(st.lists(st.lists(values, min_size=width, max_size=width), min_size=rows, max_size=rows)),
                    dtype=float).reshape(rows, width)
    if kind == "rows-1":
        data = data[:-1]
    elif kind == "rows+1":
        data = np.vstack([data, np.zeros((1, width))])
    elif kind == "narrow":
        data = data[:, :-1]
    elif kind == "wide":
        data = np.hstack([data, np.zeros((rows, 1))])
    elif kind == "special" and data.size:
        data.flat[draw(st.integers(0, data.size - 1))] = draw(st.sampled_from(SPECIAL))
    elif kind == "empty_rows":
        return [[] for _ in range(rows)]
    return data if draw(st.booleans()) else data.tolist()


@st.composite
def strut_commands(draw):
    """A leg_* trajectory: well-formed (70 %) or with one part malformed (names, times or a table); its stamp,
    the positions around the commanded lengths, home or zero, and what runs before it (``prior``)."""
    bad = draw(st.sampled_from([None] * 7 + ["names", "times", "positions", "velocities", "accelerations"]))
    names, perm = draw(joint_names(LEG_NAMES, bad == "names"))
    times = draw(point_times(bad == "times"))
    n = times.size
    stamp = draw(st.sampled_from(["zero", "zero", "now", "future", "past", "past", "far", "special"]))
    offset = {"zero": 0.0, "now": 0.0, "future": draw(st.floats(1e-4, 12.0)), "past": -draw(st.floats(1e-4, 8.0)),
              "far": draw(st.sampled_from([1e3, 1e6, 1e12])), "special": draw(st.sampled_from(SPECIAL))}[stamp]
    base = draw(st.sampled_from(["current", "current", "current", "home", "absolute"]))
    scale = draw(st.sampled_from([1e-6, 1e-4, 1e-3, 3e-3, 1e-2, 0.1]))
    deltas = table(draw, n, 6, st.floats(-scale, scale), bad == "positions")
    fields = draw(st.sampled_from(["positions", "velocities", "velocities", "accelerations", "accelerations",
                                   "accelerations_only", "moving_end"]))
    velocities = accelerations = None
    if fields != "positions":
        speed = draw(st.sampled_from([0.0, 1e-4, 2e-3, 1e-2, 0.03]))
        velocities = table(draw, n, 6, st.floats(-speed, speed), bad == "velocities")
        if fields != "moving_end" and well_formed(velocities):
            velocities[-1] = [0.0] * 6 if isinstance(velocities, list) else 0.0  # most end at rest, as planners do
    if fields in ("accelerations", "accelerations_only"):
        accel = draw(st.sampled_from([0.0, 1e-3, 0.05, 0.3]))
        accelerations = table(draw, n, 6, st.floats(-accel, accel), bad == "accelerations")
        if fields == "accelerations_only":
            velocities = None
    return dict(names=names, perm=perm, times=times, stamp=stamp, offset=offset, base=base, deltas=deltas,
                velocities=velocities, accelerations=accelerations, prior=draw(prior_motions()),
                estop=draw(st.sampled_from([False] * 30 + [True])))


@st.composite
def prior_motions(draw):
    """What runs when the hostile command arrives: nothing (held at home), or a legal minimum-jerk move of
    up to 3 mm per strut starting up to 0.5 s ago or 2 s ahead; the command arrives ``elapsed`` s later."""
    if draw(st.integers(0, 3)) == 0:
        return None
    move = np.array(draw(st.lists(st.floats(-3e-3, 3e-3), min_size=6, max_size=6)))
    duration = draw(st.floats(1.0, 4.0))
    return dict(move=move, duration=duration, stamp=draw(st.floats(-0.5, 2.0)),
                elapsed=draw(st.integers(0, 40)) * 0.002)


def run_prior(emu, prior) -> None:
    """Canonical state for an example (so that hypothesis can replay it): at rest at home, no e-stop, then the
    prior motion, run for its ``elapsed`` time."""
    emu.place_at_rest()
    if prior is None:
        return
    home = emu.home_lengths
    times = np.linspace(prior["duration"] / 20, prior["duration"], 20)
    pos, vel, acc = minimum_jerk(home, home + prior["move"], prior["duration"], times)
    attempt(emu.command_struts, LEG_NAMES, emu.time + prior["stamp"], times, pos, vel, acc)
    if prior["elapsed"]:
        emu.advance(prior["elapsed"])


def well_formed(values) -> bool:
    return values is not None and len(values) > 0 and all(len(row) == 6 for row in values)


def as_message(values, perm, base=None):
    """Per-joint values [n, 6] (+ ``base``) as the message carries them: columns in the order of its names (the
    joint of column j is perm[j]), as the list or array they came in; malformed tables pass unchanged."""
    if not well_formed(values):
        return values
    out = np.asarray(values, dtype=float) + (0.0 if base is None else base)
    out = out[:, perm]
    return out if isinstance(values, np.ndarray) else out.tolist()


def strut_step_checks(emu, knots) -> None:
    """The commanded lengths on the physics step grid around each knot, as the emulator's servo references are
    built from them: first differences / dt within the velocity limit, second differences / dt^2 within the
    acceleration limit (a weighted mean of the acceleration where the lengths are smooth, a velocity step / dt
    where they are not)."""
    dt = emu.dt
    grid = knots[:, None] + dt * np.arange(-2, 3)
    p = emu.struts.sample(grid.ravel())[0].reshape(len(knots), 5, 6)
    speed = np.abs(np.diff(p, axis=1)).max() / dt
    accel = np.abs(p[:, 2:] - 2 * p[:, 1:-1] + p[:, :-2]).max() / dt**2
    assert speed <= LIM.strut_velocity_max * (1 + REL), f"strut speed {speed} m/s on the step grid at {knots}"
    assert accel <= LIM.strut_acceleration_max * (1 + REL), f"strut acceleration {accel} m/s^2 on the step grid"


def dense_segments(knots, per_segment):
    """Times: every knot and ``per_segment`` points inside each interval between consecutive knots."""
    frac = np.arange(per_segment) / per_segment
    inner = (knots[:-1, None] + np.diff(knots)[:, None] * frac).ravel()
    return np.concatenate([inner, knots[-1:]])


def assert_struts_within_limits(emu, now: float, before) -> None:
    """The accepted command from ``now`` to well after its end: stroke, velocity, acceleration sampled densely,
    the step grid around every knot, and continuity with the command held just before it arrived."""
    traj = emu.struts.active
    knots = np.unique(np.concatenate([[now], [traj.start], traj.start + traj.times]))
    knots = knots[knots >= now]
    tail = np.linspace(knots[-1], knots[-1] + 1.0, 11)
    t = np.concatenate([dense_segments(knots, 64), tail])
    p, v, a = emu.struts.sample(t)
    assert (p >= LIM.stroke_min - STROKE_TOL).all() and (p <= LIM.stroke_max + STROKE_TOL).all(), \
        f"strut length {p.min()}..{p.max()} m outside the stroke"
    assert np.abs(v).max() <= LIM.strut_velocity_max * (1 + REL), f"strut velocity {np.abs(v).max()} m/s"
    assert np.abs(a).max() <= LIM.strut_acceleration_max * (1 + REL), f"strut acceleration {np.abs(a).max()} m/s^2"
    strut_step_checks(emu, knots)
    after = emu.struts.sample([now])
    # a first point at the start time may lie within 1e-9 m of the commanded length (the checker's allowance)
    assert np.abs(after[0] - before[0]).max() <= 1e-9, "the commanded strut lengths jump when the command arrives"
    assert np.abs(after[1] - before[1]).max() <= LIM.strut_acceleration_max * emu.dt * REL, \
        "the commanded strut velocity jumps when the command arrives"


@examples("struts")
@given(cmd=strut_commands())
def test_leg_trajectories_are_refused_with_a_reason_or_followed_within_every_limit(emu, cmd):
    run_prior(emu, cmd["prior"])
    if cmd["estop"]:
        emu.emergency_stop()
    now = emu.time
    current = emu.struts.sample([now])
    base = {"current": current[0][0], "home": emu.home_lengths, "absolute": np.zeros(6)}[cmd["base"]]
    positions = as_message(cmd["deltas"], cmd["perm"], base)
    start = {"zero": 0.0, "special": cmd["offset"]}.get(cmd["stamp"], now + cmd["offset"])
    traj, refusal = attempt(emu.command_struts, cmd["names"], start, cmd["times"], positions,
                            as_message(cmd["velocities"], cmd["perm"]), as_message(cmd["accelerations"], cmd["perm"]),
                            label="trajectory")
    if refusal is None:
        assert not cmd["estop"], "a command was accepted during an emergency stop"
        assert_struts_within_limits(emu, now, current)
    else:
        after = emu.struts.sample([now])
        assert np.array_equal(after[0], current[0]) and np.array_equal(after[1], current[1]), \
            "a refused command changed the motion"


# -- 4. vibration windows --------------------------------------------------------------------------------
A_MAX, V_MAX, ACC_MAX = UNIT.amplitude_max, UNIT.velocity_max, UNIT.acceleration_max


KINDS = ["sine"] * 3 + ["continue"] * 3 + ["short", "short", "random", "ended"]
MALFORMED = ["names", "nan", "rows", "width", "times", "acc_only", "empty"]
ANY_OFFSET = st.sampled_from([0.0, -0.002]) | st.floats(-0.1, 0.4)


@st.composite
def window_specs(draw, kinds=KINDS, offsets=ANY_OFFSET, well_formed=0.7, prior=None):
    """A vib_* window to build against the buffer it arrives at (see ``build_window``): a ramped sinusoid from
    rest, a continuation of what is buffered (a splice), 1-2 points, random samples, or one that has ended;
    corrupted (names, NaN, shapes, times) with probability 1 - well_formed; ``prior``: a strategy for the
    window buffered before it (None: nothing buffered), with when this one arrives and an e-stop."""
    kind = draw(st.sampled_from(kinds))
    spec = dict(kind=kind, offset=draw(offsets), stamp_zero=draw(st.integers(0, 9)) == 0,
                fields=draw(st.sampled_from(["pva", "pva", "pv", "p"])), phase=draw(st.floats(-math.pi, math.pi)))
    if kind in ("sine", "continue"):
        spec.update(period=draw(st.sampled_from([2.5e-4, 5e-4, 1e-3, 1e-3, 2e-3, 5e-3, 0.02])),
                    duration=draw(st.floats(0.01, 0.4)),
                    amplitudes=draw(st.sampled_from([0.05, 0.3, 0.6, 0.9, 1.0, 1.3])) * A_MAX
                    * np.array(draw(st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6))),
                    frequency=draw(st.floats(0.5, 40.0) | st.floats(0.5, 120.0)),
                    ramp=draw(st.sampled_from([0.0, 0.005, 0.02, 0.05, 0.05, 0.1])),
                    ending=draw(st.sampled_from(["ramp_out", "ramp_out", "cut"])))
    elif kind in ("short", "random"):
        points = draw(st.integers(1, 2) if kind == "short" else st.integers(1, 40))
        spec.update(points=points, spacing=np.array(draw(st.lists(st.floats(1e-5, 0.5), min_size=points - 1,
                                                                   max_size=points - 1))),
                    scale=draw(st.sampled_from([0.0, 1e-8, 1e-6, 3e-5, 1e-4, 1e-3])),
                    speed=draw(st.sampled_from([0.0, 1e-5, 1e-3, 0.02, 0.1])))
    ok = draw(st.floats(0.0, 1.0)) < well_formed
    spec["corrupt"] = "none" if ok else draw(st.sampled_from(MALFORMED))
    spec["names"] = (list(VIB_NAMES), list(range(6))) if ok else draw(joint_names(VIB_NAMES, True))
    if ok and draw(st.booleans()):  # names in another order (the columns follow them)
        perm = draw(st.permutations(range(6)))
        spec["names"] = ([VIB_NAMES[i] for i in perm], list(perm))
    if prior is not None:
        spec["prior"] = draw(st.none() | prior)
        # when the window arrives: within the buffered command ("span": fraction of it) or after its end
        # (braking, the watchdog's ramp at 0.5 s, rest); an e-stop this long before it arrives
        spec["elapsed"] = draw(st.tuples(st.just("span"), st.floats(0.0, 1.0))
                               | st.tuples(st.just("after"), st.sampled_from([0.0, 0.002, 0.02, 0.1, 0.49, 0.51,
                                                                             0.53, 0.6, 1.2])))
        spec["stop"] = draw(st.sampled_from([None] * 6 + [0.0, 0.01, 0.03, 0.06, 0.2]))
    else:
        spec["prior"] = None
    return spec


# windows spliced onto a vibrating buffer: a legal ramped sinusoid first, then mostly continuations of it
PRIOR_WINDOWS = window_specs(kinds=["sine"], offsets=st.floats(0.0, 0.1), well_formed=1.0)
SPLICES = window_specs(kinds=["continue"] * 4 + ["sine", "short"], offsets=st.sampled_from([0.0, -0.003])
                       | st.floats(-0.01, 0.05) | st.floats(0.0, 0.4), well_formed=0.9, prior=PRIOR_WINDOWS)
ANY_WINDOWS = window_specs(prior=window_specs())


def build_window(spec, buffer: VibrationBuffer, now: float):
    """(stamp, times from the stamp [n], positions, velocities, accelerations [n, 6] or None) per joint."""
    kind, period = spec["kind"], spec.get("period")
    first = now + spec["offset"]
    if kind in ("sine", "continue"):
        rel = np.arange(max(int(spec["duration"] / period), 1) + 1) * period
        ramp = min(spec["ramp"], spec["duration"] / 2)
        duration = spec["duration"] if spec["ending"] == "ramp_out" else None
        legs = [sinusoid(rel, amp, spec["frequency"], spec["phase"], duration=duration, ramp_time=ramp)
                for amp in spec["amplitudes"]]
        pos, vel, acc = (np.stack([leg[k] for leg in legs], axis=1) for k in range(3))
        if kind == "continue":  # what is buffered, plus the new vibration (zero with its slope at the splice)
            old = buffer.sample(first + rel)
            pos, vel, acc = pos + old[0], vel + old[1], acc + old[2]
    elif kind == "ended":
        rel = np.array([0.0, 0.01])
        first = now - 0.05
        pos = vel = acc = np.zeros((2, 6))
    else:
        n = spec["points"]
        rel = np.concatenate([[0.0], np.cumsum(spec["spacing"])])
        flat = np.linspace(-1.0, 1.0, n * 6).reshape(n, 6)
        pos = spec["scale"] * np.sin(7.0 * flat + spec["phase"])
        vel = spec["speed"] * np.cos(5.0 * flat)
        acc = 100.0 * spec["speed"] * np.sin(3.0 * flat)
    fields = spec["fields"]
    vel = vel if "v" in fields else None
    acc = acc if "a" in fields else None
    return (0.0 if spec["stamp_zero"] else first), rel, pos, vel, acc


def corrupt_window(spec, window):
    """The window as a message carries it (names in any order, columns following them), maybe corrupted."""
    stamp, rel, pos, vel, acc = window
    names, perm = spec["names"]
    pos, vel, acc = (None if x is None else x[:, perm] for x in (pos, vel, acc))
    how = spec["corrupt"]
    if how == "names":
        names = names[:5] + ["vib_7"]
    elif how == "nan":
        pos = pos.copy()
        pos.flat[len(rel) // 2] = math.nan
    elif how == "rows" and len(rel) > 1:
        pos = pos[:-1]
    elif how == "width":
        pos = pos[:, :5]
    elif how == "times" and len(rel) > 1:
        rel = rel.copy()
        rel[-1] = rel[0]
    elif how == "acc_only" and acc is not None:
        vel = None
    elif how == "empty":
        rel, pos, vel, acc = rel[:0], pos[:0], None, None
    return names, stamp, rel, pos, vel, acc


def vibration_horizon(buffer: VibrationBuffer) -> float:
    """Time after which the buffered command is surely at rest: the watchdog's ramp and some margin."""
    return max(buffer.end, buffer.last_receive + buffer.watchdog_s) + buffer.ramp_s + 0.05


def assert_vibration_within_limits(buffer: VibrationBuffer, now: float, before) -> None:
    """From ``now`` to well after the end (braking, watchdog ramp, e-stop ramp): displacement, velocity and
    acceleration within the unit's limits, sampled at every knot, 8 points between knots and on a uniform
    grid; no jump at ``now`` (beyond the splice allowance of 0.1 % of the limits)."""
    horizon = vibration_horizon(buffer)
    knots = np.concatenate([[now], buffer.times[(buffer.times > now) & (buffer.times < horizon)], [horizon]])
    uniform = np.linspace(now, horizon, int(min((horizon - now) / 1e-4, 20_000)) + 2)
    t = np.concatenate([dense_segments(knots, 8), uniform])
    p, v, a = buffer.sample(t)
    assert np.abs(p).max() <= A_MAX * (1 + REL), f"vibration displacement {np.abs(p).max() * 1e6} um"
    assert np.abs(v).max() <= V_MAX * (1 + REL), f"vibration velocity {np.abs(v).max()} m/s"
    assert np.abs(a).max() <= ACC_MAX * (1 + REL), f"vibration acceleration {np.abs(a).max()} m/s^2"
    assert np.abs(p[-1]).max() <= buffer.rest_position and np.abs(v[-1]).max() <= buffer.rest_velocity, \
        "the units are not at rest after the watchdog's ramp"
    after = buffer.sample([now])
    assert np.abs(after[0] - before[0]).max() <= buffer.rest_position * (1 + 1e-9), \
        f"the vibration command jumps {np.abs(after[0] - before[0]).max() * 1e6} um when the window arrives"
    assert np.abs(after[1] - before[1]).max() <= buffer.rest_velocity * (1 + 1e-9), \
        f"the vibration velocity jumps {np.abs(after[1] - before[1]).max()} m/s when the window arrives"


def arrival(elapsed, now: float, buffer: VibrationBuffer) -> float:
    mode, value = elapsed
    end = buffer.end if buffer.times.size else now
    return now + value * max(end - now, 0.0) if mode == "span" else max(end, now) + value


def add_window(buffer: VibrationBuffer, names, stamp, rel, pos, vel, acc, now: float):
    """What the emulator (and the estimator's mirror) do with a vib_* message: validate, then splice."""
    return buffer.add(build_trajectory(names, VIB_NAMES, stamp, rel, pos, vel, acc), now)


@examples("vibration_buffer")
@given(spec=ANY_WINDOWS)
def test_vibration_windows_are_refused_with_a_reason_or_stay_within_the_unit_limits(spec):
    check_window_on_buffer(spec)


@examples("vibration_splices")
@given(spec=SPLICES)
def test_windows_spliced_onto_a_vibrating_buffer_are_refused_with_a_reason_or_continuous_and_within_limits(spec):
    check_window_on_buffer(spec)


def check_window_on_buffer(spec):
    buffer = VibrationBuffer(UNIT)
    now = 20.0
    if spec["prior"] is not None:  # something already buffered: the window splices onto it
        prior = spec["prior"]
        attempt(add_window, buffer, VIB_NAMES, *build_window(dict(prior, corrupt="none"), buffer, now), now)
        now = arrival(spec["elapsed"], now, buffer)
        if spec["stop"] is not None:
            buffer.stop(now - spec["stop"], "emergency stop", "emergency_stop")
    before = buffer.sample([now])
    window = corrupt_window(spec, build_window(spec, buffer, now))
    splice, refusal = attempt(add_window, buffer, *window, now, label="window")
    if refusal is None:
        assert splice >= now
        assert_vibration_within_limits(buffer, now, before)
    else:
        after = buffer.sample([now, now + 0.1])
        assert np.array_equal(after[0][:1], before[0]), "a refused window changed the command"


@examples("vibration_emulator")
@given(spec=ANY_WINDOWS)
def test_vibration_commands_to_the_emulator_are_refused_with_a_reason_or_stay_within_the_unit_limits(emu, spec):
    emu.place_at_rest()
    if spec["prior"] is not None:
        prior = build_window(dict(spec["prior"], corrupt="none"), emu.vibration, emu.time)
        attempt(emu.command_vibration, VIB_NAMES, *prior)
        emu.advance(min(arrival(spec["elapsed"], emu.time, emu.vibration) - emu.time, 0.3) + emu.dt)
    estop = spec["stop"] is not None and spec["stop"] < 0.02
    if estop:
        emu.emergency_stop()
    now = emu.time
    before = emu.vibration.sample([now])
    names, stamp, rel, pos, vel, acc = corrupt_window(spec, build_window(spec, emu.vibration, now))
    splice, refusal = attempt(emu.command_vibration, names, stamp, rel, pos, vel, acc, label="window")
    if refusal is None:
        assert not estop, "a vibration window was accepted during an emergency stop"
        assert_vibration_within_limits(emu.vibration, now, before)
    else:
        report = emu.status.report
        got = (report.event, report.event_outcome, report.event_reason)
        assert got == ("refused", refusal.outcome, str(refusal)), "the refusal is not in the vibration status"


# -- 5. vibration planner parameters ---------------------------------------------------------------------------
DEFAULT_SETTINGS = dict(direction=[0.0, 0.0, 1.0], frame="platform", amplitude_m=0.0, acceleration_g=0.3,
                        frequency_hz=35.0, phase_rad=0.0, duration_s=0.0, ramp_s=0.2, lookahead_s=2.0,
                        window_period_s=0.5, sample_period_s=0.001, lead_s=0.3, start_lead_s=1.0,
                        max_lookahead_s=5.0, pose_timeout_s=1.0)
assert DEFAULT_SETTINGS == default_settings(ROBOT)  # the planner's declared defaults (an independent copy)
NUMBERS = st.one_of(ANY_FLOAT, st.sampled_from(SPECIAL + [-1.0, 1e-4, 0.05, 600.0, 86400.0]), st.floats(-10.0, 100.0))
DIRECTIONS = st.one_of(st.lists(ANY_FLOAT | st.floats(-2.0, 2.0), max_size=5),
                       st.sampled_from([[0.0, 0.0, 0.0], [1e308, 1e308, 0.0], [5e-324, 0.0, 0.0], [1e-10, 0.0, 0.0],
                                        [0.0, 0.0, -1.0], [1.0, 1.0, 1.0]]))


@st.composite
def wild_settings(draw):
    """The planner's settings with 0-4 of them set to any value of their parameter type: double (NaN, inf,
    huge, negative), double array of any length, string."""
    s = dict(DEFAULT_SETTINGS)
    for name in draw(st.lists(st.sampled_from(SETTINGS), max_size=4, unique=True)):
        s[name] = draw(DIRECTIONS if name == "direction" else st.sampled_from(["platform", "base", "world", ""])
                       | st.text(max_size=8) if name == "frame" else NUMBERS)
    return s


@examples("settings")
@given(s=wild_settings())
def test_planner_settings_check_returns_a_reason_or_none_and_never_raises(s):
    reason = settings_reason(ROBOT, s)  # any exception fails the test
    event("settings: refused" if reason else "settings: accepted")
    assert reason is None or (isinstance(reason, str) and reason.strip())
    if reason is None:
        assert all(math.isfinite(v) for k, v in s.items() if k not in ("direction", "frame")), s
        direction = np.asarray(s["direction"], float)
        assert direction.shape == (3,) and np.isfinite(direction).all() and np.linalg.norm(direction) > 0
        assert UNIT.frequency_min <= s["frequency_hz"] <= UNIT.frequency_max and s["ramp_s"] > 0


def log_floats(low: float, high: float):
    return st.floats(math.log(low), math.log(high)).map(math.exp)


@st.composite
def ranged_settings(draw):
    """Settings within the parameters' declared ranges (what rclpy lets through), mostly consistent with each
    other, sized so that a window has at most ~4,000 samples."""
    period = draw(log_floats(1e-4, 0.05))
    longest = min(3.0, 4000 * period)
    frequency = draw(st.floats(UNIT.frequency_min, UNIT.frequency_max) | log_floats(1.0, min(0.1 / period, 120.0)))
    lookahead = draw(st.floats(0.05, longest))
    ramp = draw(st.floats(0.01, min(1.0, longest / 2)))
    lead = draw(st.floats(0.0, 2.0))
    s = dict(
        direction=draw(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3) | st.sampled_from([[0.0, 0.0, 1.0]])),
        frame=draw(st.sampled_from(["platform", "base"])),
        amplitude_m=draw(st.sampled_from([0.0, 0.0]) | log_floats(1e-7, 0.01)),
        acceleration_g=draw(st.floats(0.0, 10.0) | st.floats(0.0, 1.0)),
        frequency_hz=frequency, phase_rad=draw(st.floats(-2 * math.pi, 2 * math.pi)),
        duration_s=draw(st.sampled_from([0.0]) | st.floats(2 * ramp, max(2 * ramp, longest))),
        ramp_s=ramp, lookahead_s=lookahead, window_period_s=draw(st.floats(0.01, max(0.01, lookahead * 0.99))),
        sample_period_s=period, lead_s=lead, start_lead_s=draw(st.floats(lead, 5.0) | st.floats(0.0, 5.0)),
        max_lookahead_s=draw(st.floats(lookahead, 600.0) | st.floats(0.1, 600.0)),
        pose_timeout_s=draw(st.floats(0.01, 60.0)),
    )
    pose = draw(st.sampled_from(["home", "paper", "moved"]))
    offset = np.array(draw(st.lists(st.floats(-0.01, 0.01), min_size=6, max_size=6)))
    return s, {"home": HOME, "paper": paper_pose(ROBOT), "moved": HOME + offset}[pose], draw(st.floats(0.0, 1.0))


def assert_window_within_limits(window) -> None:
    """The spline through a window's samples (quintic, as the units follow it), 8 points between samples."""
    t = dense_segments(window.times, 8) if window.times.size > 1 else window.times
    if window.times.size > 1:
        p, v, a = spline_segments(window.times, window.position, window.velocity, window.acceleration, t)
    else:
        p, v, a = window.position, window.velocity, window.acceleration
    assert np.abs(p).max() <= A_MAX * (1 + REL), f"planned displacement {np.abs(p).max() * 1e6} um"
    assert np.abs(v).max() <= V_MAX * (1 + REL), f"planned velocity {np.abs(v).max()} m/s"
    assert np.abs(a).max() <= ACC_MAX * (1 + REL), f"planned acceleration {np.abs(a).max()} m/s^2"


def window_checked(window, label: str) -> None:
    """check_command_limits passes (then the window is sampled) or refuses it with a typed error."""
    if window is None:
        return
    _, refusal = attempt(check_command_limits, UNIT, window.times, window.position, window.velocity,
                         window.acceleration, label=label)
    if refusal is None:
        assert_window_within_limits(window)
    else:
        assert isinstance(refusal, VibrationLimitError)


def start_stream(s, pose):
    """What the planner's start does with its settings (decompose, stream, first window)."""
    plan = decompose_vibration(ROBOT, pose, list(s["direction"]),
                               amplitude=s["amplitude_m"] if s["amplitude_m"] > 0 else None,
                               acceleration_g=None if s["amplitude_m"] > 0 else s["acceleration_g"],
                               frequency=s["frequency_hz"], phase=s["phase_rad"], frame=s["frame"], method="exact",
                               check_limits=True)
    settings_ = StreamSettings(duration=s["duration_s"] if s["duration_s"] > 0 else None, ramp_s=s["ramp_s"],
                               sample_period_s=s["sample_period_s"], lookahead_s=s["lookahead_s"],
                               lead_s=s["lead_s"], max_lookahead_s=s["max_lookahead_s"])
    return plan, settings_


@examples("settings_plan")
@given(case=ranged_settings())
def test_accepted_planner_settings_give_windows_within_the_unit_limits_or_a_typed_refusal(case):
    s, pose, stop_fraction = case
    if settings_reason(ROBOT, s) is not None:
        event("settings: refused")
        return
    started, refusal = attempt(start_stream, s, pose, label="plan")
    if refusal is not None:
        return
    plan, stream_settings = started
    stream = VibrationStream(ROBOT, plan, stream_settings)
    now = -s["start_lead_s"]  # s from t0 at the start call
    window_checked(stream.next_window(now), "first window")
    for _ in range(2):  # the streamed windows that follow (the node sends them unchecked: the emulator checks)
        now += s["window_period_s"]
        window, _ = attempt(stream.next_window, now)
        window_checked(window, "later window")
    end = stream.planned_end if stream.planned_end is not None else now + s["lookahead_s"]
    window_checked(stream.stop_window(now + stop_fraction * max(end - now, 0.0)), "stop window")


# -- 6. raw CDR bytes ------------------------------------------------------------------------------------
@st.composite
def mutated(draw, data: bytes) -> bytes:
    """``data`` truncated, bit-flipped, with a count field overwritten, bytes inserted or removed, or replaced by
    random bytes (1-3 of these)."""
    buf = bytearray(data)
    for _ in range(draw(st.integers(1, 3))):
        how = draw(st.sampled_from(["truncate", "flip", "flip", "count", "insert", "delete", "random"]))
        at = draw(st.integers(0, max(len(buf) - 1, 0)))
        if how == "truncate":
            del buf[at:]
        elif how == "flip" and buf:
            buf[at] ^= 1 << draw(st.integers(0, 7))
        elif how == "count" and len(buf) >= 8:
            at = 4 + (at // 4) * 4 if at + 4 <= len(buf) - 4 else 4
            buf[at:at + 4] = draw(st.sampled_from([0, 1, 5, 6, 7, 255, 2**16, 2**31 - 1, 2**32 - 1, len(buf)])
                                  ).to_bytes(4, "little")
        elif how == "insert":
            buf[at:at] = draw(st.binary(min_size=1, max_size=9))
        elif how == "delete":
            del buf[at:at + draw(st.integers(1, 9))]
        elif how == "random":
            buf = bytearray(draw(st.sampled_from([b"", b"\x00\x01\x00\x00"])) + draw(st.binary(max_size=120)))
    return bytes(buf)


NAME_LISTS = st.sampled_from([LEG_NAMES, VIB_NAMES, LEG_NAMES[:3], []]) | st.lists(st.text(max_size=6), max_size=7)
VALUES = st.floats(allow_nan=True, allow_infinity=True, width=64)


@st.composite
def trajectory_bytes(draw):
    names = draw(NAME_LISTS)
    n, k = draw(st.integers(0, 4)), len(names)
    times = np.cumsum(draw(st.lists(st.floats(0.0, 2.0), min_size=n, max_size=n)))
    fields = [np.array(draw(st.lists(VALUES, min_size=n * k, max_size=n * k))).reshape(n, k) if draw(st.booleans())
              else None for _ in range(3)]
    if fields[0] is None:
        fields[0] = np.zeros((n, k))
    data = encode_joint_trajectory(names, draw(st.floats(0.0, 1e6)), times, *fields,
                                       frame_id=draw(st.sampled_from(["", "base"]) | st.text(max_size=5)))
    return draw(mutated(data)) if draw(st.integers(0, 5)) else data


@examples("cdr_trajectory")
@given(data=trajectory_bytes())
def test_joint_trajectory_bytes_decode_or_are_refused_with_a_reason_and_validate(data):
    decoded, refusal = attempt(decode_joint_trajectory, data, label="decode")
    assert refusal is None or isinstance(refusal, InvalidInputError)
    if refusal is None:  # then what the emulator does with it before the limits: names, shapes, numbers
        for names in (LEG_NAMES, VIB_NAMES):
            _, refusal = attempt(build_trajectory, decoded.names, names, decoded.stamp, decoded.times,
                                 decoded.positions, decoded.velocities, decoded.accelerations)
            assert refusal is None or isinstance(refusal, InvalidInputError)


@st.composite
def joint_state_bytes(draw, encoder_names=None):
    names = encoder_names if encoder_names is not None else draw(NAME_LISTS)
    fields = draw(st.sampled_from([("position", "velocity", "effort"), ("position",), ("position", "velocity"), ()]))
    encoder = JointStateEncoder(names, draw(st.sampled_from(["", "base"])), fields)
    k = len(names)
    arrays = {f: np.array(draw(st.lists(VALUES, min_size=k, max_size=k))) for f in fields}
    return encoder.encode(draw(st.floats(0.0, 1e6)), **arrays)


@examples("cdr_joint_state")
@given(data=joint_state_bytes().flatmap(lambda d: st.just(d) | mutated(d) | mutated(d)))
def test_joint_state_bytes_decode_or_are_refused_with_a_reason(data):
    _, refusal = attempt(JointStateDecoder().decode, data, label="decode")
    assert refusal is None or isinstance(refusal, InvalidInputError)


@st.composite
def joint_state_streams(draw):
    """2-5 messages of one publisher (same names and layout: the vectorised path), some of them mutated."""
    names = draw(st.sampled_from([LEG_NAMES + VIB_NAMES, LEG_NAMES, ["a"]]))
    messages = []
    for _ in range(draw(st.integers(2, 5))):
        data = draw(joint_state_bytes(names))
        messages.append(draw(mutated(data)) if draw(st.integers(0, 3)) == 0 else data)
    return messages


@examples("cdr_joint_states")
@given(messages=joint_state_streams())
def test_joint_state_streams_decode_or_are_refused_with_a_reason(messages):
    batches, refusal = attempt(decode_joint_states, messages, label="decode")
    assert refusal is None or isinstance(refusal, InvalidInputError)
    if refusal is None:
        assert sum(len(b.stamps) for b in batches) == len(messages)


@examples("cdr_pose")
@given(data=st.builds(lambda frame, stamp, values: PoseStampedEncoder(frame).encode(stamp, values[:3], values[3:]),
                      st.sampled_from(["", "base"]) | st.text(max_size=6), st.floats(0.0, 1e6),
                      st.lists(VALUES | st.floats(-1.0, 1.0), min_size=7, max_size=7))
       .flatmap(lambda d: st.just(d) | mutated(d) | mutated(d)))
def test_pose_stamped_bytes_decode_or_are_refused_with_a_reason(data):
    decoded, refusal = attempt(decode_pose_stamped, data, label="decode")
    assert refusal is None or isinstance(refusal, InvalidInputError)
    if refusal is None:  # the planner's use of a pose estimate
        _, refusal = attempt(pose_from_position_quaternion, decoded[2], decoded[3])
        assert refusal is None or isinstance(refusal, InvalidInputError)
