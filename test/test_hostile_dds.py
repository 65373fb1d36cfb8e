"""Hostile input through the real nodes over DDS.

The hardware emulator (real time), kinematics, vibration planner and leg force estimator run as separate
processes. A client sends a few hundred malformed and boundary messages as a user could -- move_to_pose
goals (malformed and boundary targets and values), leg and vibration JointTrajectory messages (also raw
garbage bytes), bad parameters, PlanPath requests, vibrate goals (hostile ones among them) / cancels / e-stop /
reset in odd orders -- then checks that every node is still alive, that every bad parameter was refused with a
reason and changed nothing, that every move and vibrate goal ended with a code of the outcome table (a bad one
with its typed refusal, never run), that every PlanPath answer has its code and every sample of a planned
path is reachable, that no joint state published during the barrage broke a limit (and the force estimator's
model stayed within the strut force limit: it mirrors the commands, and must refuse what the emulator
refuses), and that the robot still reaches a valid target (the paper's pose) to 10 um and 0.01 deg.
"""

from __future__ import annotations

import math
import re
import time

import numpy as np
import pytest
from action_msgs.srv import CancelGoal
from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import PoseStamped
from malformed_messages import mangled as garbage
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from ros_client import RosTestClient
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from stewart_vibration import inverse_kinematics, load_robot
from stewart_vibration.errors import StewartError
from stewart_vibration.kinematics import check_pose
from stewart_vibration.kinematics.rotations import quaternion_from_rpy
from stewart_vibration.messages.joint_trajectory import encode_joint_trajectory
from stewart_vibration.motion.move_goal import move_request
from stewart_vibration.nodes.message_conversions import pose_from_msg, pose_stamped
from stewart_vibration.nodes.move_messages import MOVE_ACTION, base_pose
from stewart_vibration.nodes.outcomes import outcome_name
from stewart_vibration.paper import paper_pose
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES
from stewart_vibration.runtime.processes import ros_environment, start_python_module
from stewart_vibration.vibration.waveform import sinusoid
from stewart_vibration_interfaces.action import MoveToPose
from stewart_vibration_interfaces.srv import PlanPath

pytestmark = [pytest.mark.integration]
SIM = ["--ros-args", "-p", "use_sim_time:=true"]
NODES = {  # name: (module, arguments)
    "emulator": ("stewart_vibration.nodes.hardware_emulator_node",  # lockstep: a busy machine slows sim time
                 ["--ros-args", "-p", "real_time_factor:=1", "-p", "lockstep:=true"]),
    "kinematics": ("stewart_vibration.nodes.kinematics_node", SIM),
    "planner": ("stewart_vibration.nodes.vibration_planner_node", SIM),
    "estimator": ("stewart_vibration.nodes.leg_force_estimator_node", SIM),
}
NAN, INF = math.nan, math.inf
CALL_TIMEOUT = 10.0


def stamp_msg(seconds: float) -> Time:
    sec = math.floor(seconds)
    return Time(sec=int(np.clip(sec, -2**31, 2**31 - 1)), nanosec=int((seconds - sec) * 1e9) % 1_000_000_000)


def duration_msg(seconds: float) -> Duration:
    sec = math.floor(seconds)
    return Duration(sec=int(np.clip(sec, -2**31, 2**31 - 1)), nanosec=int((seconds - sec) * 1e9) % 1_000_000_000)


def trajectory(names, stamp: float, times, positions, velocities=None, accelerations=None) -> JointTrajectory:
    """A JointTrajectory as a hostile sender builds it: any names and stamp, points that may lack positions,
    velocities or accelerations (the nodes' own builder, nodes.message_conversions.leg_trajectory_msg, makes only
    well-formed leg moves)."""
    msg = JointTrajectory()
    msg.header.stamp = stamp_msg(stamp)
    msg.joint_names = list(names)
    for i, t in enumerate(times):
        point = JointTrajectoryPoint()
        point.positions = [float(x) for x in positions[i]] if i < len(positions) else []
        if velocities is not None and i < len(velocities):
            point.velocities = [float(x) for x in velocities[i]]
        if accelerations is not None and i < len(accelerations):
            point.accelerations = [float(x) for x in accelerations[i]]
        point.time_from_start = duration_msg(t)
        msg.points.append(point)
    return msg


# a move goal's values beside its target: (speed_scale, force_limit_n, moment_limit_nm); 0 = the node's
GOAL_VALUES = [(0.0, 0.0, 0.0), (NAN, 0.0, 0.0), (2.0, 0.0, 0.0), (-0.5, 0.0, 0.0), (INF, 0.0, 0.0),
               (0.0, NAN, 0.0), (0.0, -1.0, 0.0), (0.0, 1e9, 0.0), (0.0, 0.0, -INF), (0.0, 0.0, 1e9),
               (1.0, 50.0, 5.0), (1e-300, 0.0, 0.0)]  # 1e-300: within (0, 1], a move of ~1e298 s


def hostile_targets(robot, rng) -> list[PoseStamped]:
    """Malformed and boundary PoseStamped targets (of move goals), and a few legal ones near home."""
    home = np.asarray(robot.home_pose, float)
    out = []
    specials = [NAN, INF, -INF, 1e308, -1e308, 0.0, 1e9]
    for i in range(90):
        pose = home + rng.uniform(-0.03, 0.03, 6) * [1, 1, 1, 10, 10, 10]
        msg = pose_stamped(pose, Time(), rng.choice(["base", "", "base", "world", "platform", "Base", " base"]))
        q = msg.pose.orientation
        kind = i % 6
        if kind == 0:
            setattr(msg.pose.position, "xyz"[i % 3], float(rng.choice(specials)))
        elif kind == 1:
            q.x, q.y, q.z, q.w = (0.0, 0.0, 0.0, 0.0) if i % 2 else (NAN, 0.0, 0.0, 1.0)
        elif kind == 2:  # quaternion norm around the 1e-3 tolerance
            scale = 1.0 + float(rng.choice([5e-4, -9.9e-4, 1.1e-3, -2e-3, 0.5]))
            q.x, q.y, q.z, q.w = (v * scale for v in (q.x, q.y, q.z, q.w))
        elif kind == 3:
            q.x, q.y, q.z, q.w = (float(v) for v in rng.uniform(-1, 1, 4))
        elif kind == 4:  # legal if reachable: the robot moves
            msg.header.frame_id = "base"
            pose = home + rng.uniform(-0.005, 0.005, 6) * [1, 1, 1, 10, 10, 10]
            msg = pose_stamped(pose, Time(), "base")
        out.append(msg)
    return out


def hostile_leg_trajectories(robot, rng) -> list[tuple[JointTrajectory, bool]]:
    """Malformed, boundary and a few legal leg_* trajectories, each with whether its stamp is relative to the
    sim time it is sent at (else 0 = now)."""
    home = inverse_kinematics(robot, robot.home_pose)
    lim = robot.limits
    out = []
    for i in range(96):
        n = int(rng.integers(1, 5))
        times = np.cumsum(rng.uniform(0.2, 2.0, n))
        pos = home + rng.uniform(-0.004, 0.004, (n, 6))
        vel = np.zeros((n, 6))
        names = list(LEG_NAMES)
        stamp = 0.0
        kind = i % 16
        if kind == 0:
            names = names[::-1][:5] + ["vib_1"]
        elif kind == 1:
            stamp = -5.0  # late: past points dropped, or refused
        elif kind == 2:
            stamp = 1000.0
        elif kind == 3:
            pos[-1, i % 6] = NAN
        elif kind == 4:
            pos[-1] = home + 0.05  # a 50 mm jump
            times = times * 0.01
        elif kind == 5:
            times = times[::-1].copy()
        elif kind == 6:
            pos = pos[:, :5]
        elif kind == 7:
            vel[-1] = 0.01  # ends moving
        elif kind == 8:
            pos[-1, 0] = lim.stroke_max + 0.01
        elif kind == 9:
            times = np.array([0.0])[:n] if n == 1 else times - times[0]  # a first point at the start
        elif kind == 10:
            vel = None  # positions only
        elif kind == 11:
            stamp = float(rng.uniform(0.1, 3.0))  # in the future
        elif kind == 12:
            out.append((trajectory(names, 0.0, [], []), False))  # no points
            continue
        elif kind == 13:
            stamp = -float(rng.uniform(0.05, 0.5))
        elif kind == 15:  # points that have velocities but no positions at all
            out.append((trajectory(names, 0.0, times, [], vel), False))
            continue
        out.append((trajectory(names, stamp, times, pos, vel), kind in (1, 2, 11, 13)))
    return out


def hostile_vibration_windows(robot, rng) -> list[tuple[JointTrajectory, bool]]:
    """Malformed, boundary and a few legal vib_* windows (ramped sinusoids, 1-2 points, late, too large), each
    stamped relative to the sim time it is sent at."""
    unit = robot.vibration_unit
    out = []
    for i in range(70):
        t0 = float(rng.uniform(0.1, 0.5))
        rel = np.arange(0.0, 0.4, 1e-3)
        amp = float(rng.choice([10e-6, 30e-6, 2 * unit.amplitude_max]))
        freq = float(rng.choice([35.0, 80.0, 119.0, 300.0]))
        p, v, a = sinusoid(rel, amp, freq, 0.0, duration=0.4, ramp_time=0.1)
        gains = rng.uniform(-1, 1, 6)
        pos, vel, acc = p[:, None] * gains, v[:, None] * gains, a[:, None] * gains
        names = list(VIB_NAMES)
        kind = i % 10
        if kind == 0:
            names[2] = "leg_3"
        elif kind == 1:
            t0 = -0.2  # late: the units are not where it starts
        elif kind == 2:
            rel, pos, vel, acc = rel[:1], np.full((1, 6), 5e-5), None, None  # one point away from rest
        elif kind == 3:
            rel, pos, vel, acc = rel[:2] * 10, np.array([np.zeros(6), np.full(6, 2e-5)]), None, None
        elif kind == 4:
            pos = pos.copy()
            pos[5, 0] = INF
        elif kind == 5:
            acc = acc[:-1]
        elif kind == 6:
            t0 = 1e4  # far beyond max_lookahead_s
        elif kind == 7:
            rel, pos, vel, acc = rel[:200], pos[:200], vel[:200], acc[:200]  # ends moving (watchdog)
        out.append((trajectory(names, t0, rel, pos, vel, acc), True))
    return out


def hostile_move_goals(robot, rng) -> list[MoveToPose.Goal]:
    """move_to_pose goals to the hostile targets; those of the random poses (kind 5) also with hostile values
    (GOAL_VALUES, a legal one among them)."""
    goals = []
    for i, target in enumerate(hostile_targets(robot, rng)):
        speed, force, moment = GOAL_VALUES[(i // 6) % len(GOAL_VALUES)] if i % 6 == 5 else (0.0, 0.0, 0.0)
        goals.append(MoveToPose.Goal(target=target, speed_scale=speed, force_limit_n=force, moment_limit_nm=moment))
    return goals


def expected_refusal(robot, goal: MoveToPose.Goal, defaults: dict) -> str | None:
    """The outcome a move goal must be refused with (the node checks the frame, the pose message, the values,
    then the pose), or None for a legal goal (it may run, or be refused for what the robot does now)."""
    try:
        target = base_pose(goal.target, "target pose")
        move_request(target, goal.speed_scale, goal.force_limit_n, goal.moment_limit_nm, defaults["speed_scale"],
                     defaults["guard_force_n"], defaults["guard_moment_nm"])
        check_pose(robot, target)
    except StewartError as exc:
        return exc.outcome
    return None


def param(name: str, value) -> ParameterMsg:
    """A parameter message of any type (a string for a double, NaN, an array...)."""
    v = ParameterValue()
    if isinstance(value, bool):
        v.type, v.bool_value = ParameterType.PARAMETER_BOOL, value
    elif isinstance(value, int):
        v.type, v.integer_value = ParameterType.PARAMETER_INTEGER, value
    elif isinstance(value, float):
        v.type, v.double_value = ParameterType.PARAMETER_DOUBLE, value
    elif isinstance(value, str):
        v.type, v.string_value = ParameterType.PARAMETER_STRING, value
    else:
        v.type, v.double_array_value = ParameterType.PARAMETER_DOUBLE_ARRAY, [float(x) for x in value]
    return ParameterMsg(name=name, value=v)


BAD_PARAMETERS = {
    "vibration_planner": [
        ("lookahead_s", 0.2), ("lookahead_s", NAN), ("lookahead_s", "2"), ("sample_period_s", 0.0),
        ("sample_period_s", 0.04), ("start_lead_s", 0.0), ("max_lookahead_s", 1e9), ("lead_s", -INF),
        ("pose_timeout_s", -1.0), ("window_period_s", [1.0]), ("robot_config", "/etc/passwd"),
        ("no_such_parameter", 1.0), ("frequency_hz", 35.0),  # the vibration is a goal's, no parameter
        ("use_sim_time", "yes"),
    ],
    "hardware_emulator": [
        ("real_time_factor", -1.0), ("real_time_factor", NAN), ("real_time_factor", "fast"), ("real_time_factor", 1e9),
        ("watchdog_s", 0.0), ("watchdog_s", INF), ("vibration_ramp_s", 1.0), ("max_lookahead_s", -5.0),
        ("physics_rate_hz", 200.0), ("state_rate_hz", 50.0), ("autostart", False), ("robot_config", ""),
        ("drive_gain_interval", 0), ("marker_rate_hz", [1.0, 2.0]), ("no_such_parameter", True),
    ],
}


def hostile_plan_requests(robot, rng) -> list[tuple[PlanPath.Request, set]]:
    """PlanPath requests near home, mostly bad, each with the outcome names its answer may have."""
    out = []
    for i in range(30):
        goal = np.asarray(robot.home_pose, float) + rng.uniform(-0.01, 0.01, 6)
        request = PlanPath.Request(waypoints=[pose_stamped(goal, Time(), "base")])
        end = request.waypoints[0]
        kind, expected = i % 10, {"INVALID_ARGUMENT"}
        if kind == 0:
            end.pose.position.x = NAN
        elif kind == 1:
            end.header.frame_id, expected = "world", {"UNKNOWN_FRAME"}
        elif kind == 2:
            end.pose.position.z, expected = 1e7, {"UNREACHABLE_POSE", "GUARD_BLOCKED"}  # far: no path is built
        elif kind == 3:
            end.pose.orientation.w = end.pose.orientation.z = 0.0
        elif kind == 4:  # the path's start in another frame
            request.waypoints.insert(0, pose_stamped(goal, Time(), "platform"))
            expected = {"UNKNOWN_FRAME"}
        elif kind == 5:
            request.waypoints.insert(0, pose_stamped(goal, Time(), "base"))
            request.waypoints[0].pose.position.z = -INF
        elif kind == 6:
            request.speed_scale = NAN
        elif kind == 7:
            request.speed_scale = 1e-300  # slower than the slowest move
        elif kind == 8:
            request.waypoints = []
        else:  # a legal one-waypoint request: planned (or refused while the barrage trips the force guard)
            expected = {"SUCCEEDED", "GUARD_BLOCKED"}
        out.append((request, expected))
    return out


# "vibrate": the next of HOSTILE_GOALS (a legal one among them); "cancel": cancel every vibrate goal
TRIGGER_ORDER = ["vibrate", "vibrate", "hardware_emulator/reset", "cancel", "hardware_emulator/emergency_stop",
                 "vibrate", "hardware_emulator/emergency_stop", "cancel", "hardware_emulator/reset",
                 "hardware_emulator/reset", "vibrate", "hardware_emulator/emergency_stop", "hardware_emulator/reset",
                 "vibrate", "cancel", "cancel", "hardware_emulator/reset", "vibrate", "vibrate", "vibrate",
                 "vibrate", "vibrate", "vibrate", "vibrate", "vibrate"]
HOSTILE_GOALS = [  # vibrate goal fields over a legal 1 s vibration; each ends with a typed outcome, never a crash
    {}, {"duration_s": 0.0}, {"frequency_hz": NAN}, {"frequency_hz": 1e6}, {"frequency_hz": -35.0},
    {"amplitude_m": INF}, {"amplitude_m": -1e-5}, {"amplitude_m": 150e-6}, {"acceleration_g": 11.0},
    {"direction": [0.0, 0.0, 0.0]}, {"direction": [NAN, 0.0, 1.0]}, {"frame": "world"}, {"frame": "\x00" * 300},
    {"ramp_s": 0.0}, {"ramp_s": INF}, {"duration_s": 0.05}, {"duration_s": -1.0}, {"phase_rad": 1e300},
]
TYPED_REFUSALS = {"INVALID_ARGUMENT", "LIMIT_EXCEEDED", "UNREACHABLE_POSE", "BUSY", "ESTOP_LATCHED",
                  "UNITS_NOT_AT_REST", "NOT_READY"}
# a legal move goal: refused for what the robot does now, or run and ended by the barrage beside it (leg
# trajectories that take the struts elsewhere, e-stops, resets, cancels)
MOVE_DEFAULTS = ("speed_scale", "guard_force_n", "guard_moment_nm")  # kinematics' values a goal's 0 stands for
MOVE_REFUSALS = {"BUSY", "NOT_READY", "UNREACHABLE_POSE", "LIMIT_EXCEEDED", "GUARD_BLOCKED"}
MOVE_ENDS = {"SUCCEEDED", "CANCELED", "TIMEOUT", "GUARD_STOPPED", "EMERGENCY_STOPPED", "STOPPED_EARLY",
             "ROBOT_REFUSED", "ESTOP_LATCHED", "ROBOT_INACTIVE"}


class Hostile:
    """The four node processes and a client recording joint states, ground-truth poses and the clock."""

    def __init__(self, domain, log_dir):
        env = ros_environment(domain)
        self.procs = {name: start_python_module(name, module, args, env, log_dir)
                      for name, (module, args) in NODES.items()}
        self.client = c = RosTestClient("hostile_client")
        self.states = c.subscribe("legs/joint_states", JointState, depth=5000)
        self.poses = c.subscribe("ground_truth/platform_pose", PoseStamped, depth=100)
        self.clock = c.subscribe("/clock", Clock, depth=10)
        self.estimates = c.subscribe("platform/pose_estimate", PoseStamped, depth=10)
        self.forces = c.subscribe("legs/force_estimate", JointState, depth=5000)
        self.answers = []  # (what, success or None, message) of every service call
        ready = c.spin_until(lambda: self.clock and len(self.estimates) > 10 and len(self.states) > 100, 60)
        assert ready, self.logs()
        for srv_type, name in ((Trigger, "hardware_emulator/reset"), (PlanPath, "kinematics/plan_path"),
                               (SetParameters, "vibration_planner/set_parameters"),
                               (SetParameters, "hardware_emulator/set_parameters")):
            assert c.node.create_client(srv_type, name).wait_for_service(timeout_sec=30), (name, self.logs())
        assert c.vibrate_server_ready(30), self.logs()
        assert c.action_server_ready(MoveToPose, MOVE_ACTION, 30), self.logs()

    def now(self) -> float:
        c = self.clock[-1].clock
        return c.sec + c.nanosec * 1e-9

    def call(self, srv_type, name: str, request):
        response = self.client.call(srv_type, name, request, timeout=CALL_TIMEOUT)
        self.answers.append((name, getattr(response, "success", None), getattr(response, "message", "")))
        return response

    def dead(self) -> list[str]:
        return [name for name, proc in self.procs.items() if not proc.alive()]

    def logs(self) -> str:
        return "\n".join(f"--- {n}\n{p.log_text()[-3000:]}" for n, p in self.procs.items())

    def close(self) -> None:
        self.client.close()
        for proc in self.procs.values():
            proc.stop()


def assert_joint_states_within_limits(robot, states) -> None:
    """Every published state: strut lengths within the stroke, vib_i within amplitude_max, strut speed from
    consecutive samples within strut_velocity_max (1 %)."""
    lim, unit = robot.limits, robot.vibration_unit
    stamps = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in states])
    pos = np.array([m.position for m in states])
    order = np.argsort(stamps, kind="stable")
    stamps, pos = stamps[order], pos[order]
    struts, vib = pos[:, :6], pos[:, 6:12]
    assert struts.min() >= lim.stroke_min - 1e-5 and struts.max() <= lim.stroke_max + 1e-5, \
        f"strut lengths {struts.min()}..{struts.max()} m outside the stroke"
    assert np.abs(vib).max() <= unit.amplitude_max * (1 + 1e-3), f"vibration {np.abs(vib).max() * 1e6} um"
    dt = np.diff(stamps)
    consecutive = (dt > 1e-4) & (dt < 2.5e-3)
    speed = (np.abs(np.diff(struts, axis=0)).max(axis=1) / np.where(consecutive, dt, 1.0))[consecutive]
    assert consecutive.sum() > 0.5 * len(stamps), "too few consecutive joint states to judge the strut speed"
    assert speed.max() <= lim.strut_velocity_max * 1.01, f"strut speed {speed.max()} m/s"


def pose_error(msg, target) -> tuple[float, float]:
    """(position error m, orientation error deg) of a ground-truth PoseStamped against a pose vector."""
    p, o = msg.pose.position, msg.pose.orientation
    q = np.array([o.x, o.y, o.z, o.w])
    qt = quaternion_from_rpy(target[3:])
    angle = 2 * math.degrees(math.acos(min(1.0, abs(float(np.dot(q / np.linalg.norm(q), qt))))))
    return float(np.linalg.norm(np.array([p.x, p.y, p.z]) - target[:3])), angle


def snapshot(hostile, node: str, params) -> dict:
    """The node's values of the declared parameters among ``params`` (undeclared names are left out)."""
    names = sorted({n for n, _ in params if n not in ("no_such_parameter", "frequency_hz")})
    values = hostile.call(GetParameters, f"{node}/get_parameters", GetParameters.Request(names=names)).values
    return {n: (v.type, v.double_value, v.string_value, v.bool_value, v.integer_value)
            for n, v in zip(names, values, strict=True)}


@pytest.fixture
def hostile(ros_domain, tmp_path):
    suite = Hostile(ros_domain, tmp_path)
    try:
        yield suite
    finally:
        suite.close()


def test_hostile_messages_leave_every_node_alive_and_the_robot_reaching_a_target(hostile):
    robot = load_robot()
    rng = np.random.default_rng(13)
    c = hostile.client
    legs_pub = c.publisher("legs/joint_trajectory", JointTrajectory)
    vib_pub = c.publisher("vibration/joint_trajectory", JointTrajectory)
    assert c.wait_for_subscribers("legs/joint_trajectory", 2) and \
        c.wait_for_subscribers("vibration/joint_trajectory", 2), hostile.logs()
    names = list(MOVE_DEFAULTS)
    values = hostile.call(GetParameters, "kinematics/get_parameters", GetParameters.Request(names=names)).values
    defaults = {n: v.double_value for n, v in zip(names, values, strict=True)}
    first_state = len(hostile.states)
    now = hostile.now()
    sent = 0

    def publish(pub, msg):
        nonlocal sent
        if isinstance(msg, tuple):  # (trajectory, stamp relative to the sim time now)
            msg, relative = msg
            if relative:
                stamp = msg.header.stamp
                msg.header.stamp = stamp_msg(hostile.now() + stamp.sec + stamp.nanosec * 1e-9)
        pub.publish(msg)
        sent += 1
        c.spin_for(0.01)

    targets = hostile_move_goals(robot, rng)
    legs = hostile_leg_trajectories(robot, rng)
    windows = hostile_vibration_windows(robot, rng)
    valid_legs = encode_joint_trajectory(LEG_NAMES, now, [1.0, 2.0], np.full((2, 6), 0.174))
    valid_vib = encode_joint_trajectory(VIB_NAMES, now + 0.2, [0.0, 0.01], np.zeros((2, 6)), np.zeros((2, 6)))
    raw_legs, raw_vib = garbage(rng, valid_legs, 30), garbage(rng, valid_vib, 30)
    plans = hostile_plan_requests(robot, rng)
    triggers = iter(TRIGGER_ORDER)
    goals_to_send = iter(HOSTILE_GOALS * 2)
    goals = []  # (fields, ActionGoal) of every vibrate goal sent
    moves = []  # (MoveToPose.Goal, ActionGoal) of every move goal sent
    before = {node: snapshot(hostile, node, params) for node, params in BAD_PARAMETERS.items()}
    bad_params = [(node, p) for node, params in BAD_PARAMETERS.items() for p in params]
    refusals = []  # (node, parameter, value, successful, reason)
    paths = []  # (the outcome names it may have, the answer) of every PlanPath request
    for i in range(max(len(targets), len(legs), len(windows))):
        if i < len(targets):
            moves.append((targets[i], c.send_goal(MOVE_ACTION, targets[i])))
            sent += 1
        for pub, batch in ((legs_pub, legs), (vib_pub, windows), (legs_pub, raw_legs), (vib_pub, raw_vib)):
            if i < len(batch):
                publish(pub, batch[i])
        if i % 2 == 0 and bad_params:
            node, (name, value) = bad_params.pop()
            result = hostile.call(SetParameters, f"{node}/set_parameters",
                                  SetParameters.Request(parameters=[param(name, value)])).results[0]
            refusals.append((node, name, value, result.successful, result.reason))
            sent += 1
        if i % 3 == 0 and plans:
            request, expected = plans.pop()
            paths.append((expected, hostile.call(PlanPath, "kinematics/plan_path", request)))
            sent += 1
        if i % 5 == 0:
            name = next(triggers, None)
            if name == "vibrate":
                fields = next(goals_to_send, {})
                goals.append((fields, c.vibrate(**fields)))
                sent += 1
            elif name == "cancel":  # every vibrate goal, and every move goal
                hostile.call(CancelGoal, "vibration_planner/vibrate/_action/cancel_goal", CancelGoal.Request())
                hostile.call(CancelGoal, f"{MOVE_ACTION}/_action/cancel_goal", CancelGoal.Request())
                sent += 2
            elif name is not None:
                hostile.call(Trigger, name, Trigger.Request())
                sent += 1
    assert sent >= 300
    c.spin_for(1.0)
    assert not hostile.dead(), f"dead after the barrage: {hostile.dead()}\n{hostile.logs()}"
    taken = [r for r in refusals if r[3] or not r[4].strip()]
    assert not taken and len(refusals) == sum(map(len, BAD_PARAMETERS.values())), \
        f"bad parameters taken or refused without a reason: {taken}"
    for node, params in BAD_PARAMETERS.items():  # every bad value was refused: the values are unchanged
        assert snapshot(hostile, node, params) == before[node], node
    for fields, goal in goals:  # every goal ended, with a code of the table: run, cancelled or a typed refusal
        name, message = goal.outcome(30)
        # a legal one may also end by what the barrage does beside it (hostile windows, e-stops, cancels)
        ends = {"SUCCEEDED", "CANCELED", "EMERGENCY_STOPPED", "STOPPED_EARLY", "ROBOT_REFUSED", "HELD_UP"}
        assert name in TYPED_REFUSALS | ends and message, (fields, name, message)
        if fields and fields != {"duration_s": 0.0} and name not in ("BUSY", "ESTOP_LATCHED", "UNITS_NOT_AT_REST"):
            assert name in TYPED_REFUSALS, (fields, name, message)  # a bad goal never runs
    ran = 0
    for goal_msg, goal in moves:  # every move goal ended with a code of the table; a bad one with its refusal
        name, message = goal.outcome(40)
        expected = expected_refusal(robot, goal_msg, defaults)
        what = (goal_msg.target, goal_msg.speed_scale, goal_msg.force_limit_n, goal_msg.moment_limit_nm)
        assert message, (what, name)
        if expected is not None:  # never run: its own code, or BUSY (checked first, while another goal runs)
            assert name in (expected, "BUSY") and goal.status() == 6, (what, expected, name, message)
        else:
            assert name in MOVE_REFUSALS | MOVE_ENDS, (what, name, message)
            ran += name in MOVE_ENDS
    assert ran > 0, "no legal move goal ran during the barrage"
    assert sum(expected_refusal(robot, m, defaults) is None for m, _ in moves) < len(moves) // 2
    assert_joint_states_within_limits(robot, hostile.states[first_state:])
    for expected, answer in paths:  # a bad request gets its code and no path; a path's samples are reachable
        name = outcome_name(answer.outcome.code)
        assert name in expected and answer.outcome.message, (expected, name, answer.outcome.message)
        assert bool(answer.path.poses) == (name == "SUCCEEDED"), (name, len(answer.path.poses))
    planned = [answer.path.poses for _, answer in paths if answer.path.poses]
    assert planned, "no legal PlanPath request got a path"
    for path in planned:  # every sample of every answer is reachable (stroke, joints, conditioning)
        check_pose(robot, np.array([pose_from_msg(m.pose) for m in path]))
    # the force estimator mirrors the commands: those the emulator refused must not enter its model (a refused
    # 50 mm jump made it report 3 kN)
    modelled = np.abs(np.array([m.effort for m in hostile.forces])).max()
    assert modelled <= robot.limits.strut_force_max, f"modelled leg force {modelled} N"

    # the robot still works: stop any vibration and move, clear an e-stop and a force-guard trip (the barrage's
    # leg trajectories take the struts off a guarded move's path: a trip it makes is latched by design), go to the
    # paper's pose
    hostile.call(CancelGoal, "vibration_planner/vibrate/_action/cancel_goal", CancelGoal.Request())
    hostile.call(CancelGoal, f"{MOVE_ACTION}/_action/cancel_goal", CancelGoal.Request())
    hostile.call(Trigger, "hardware_emulator/emergency_stop", Trigger.Request())  # latched now, whatever it was
    resets = []

    def reset_taken() -> bool:  # refused while the e-stop's ramp is still running: asked again
        resets.append(hostile.call(Trigger, "hardware_emulator/reset", Trigger.Request()))
        if not resets[-1].success:
            c.spin_for(0.2)
        return resets[-1].success

    assert c.spin_until(reset_taken, 30), (resets[-1].message, hostile.logs())
    home_over = re.search(r"returning home over ([0-9.]+) s", resets[-1].message)
    assert home_over, resets[-1].message
    home_done = hostile.now() + float(home_over.group(1)) + 0.1  # sim s; a move planned during the reset's own
    # move home was refused for its velocity (CI beside a CPU hog: the target was never reached)
    assert c.spin_until(lambda: hostile.now() > home_done, 60), hostile.logs()
    assert hostile.call(Trigger, "kinematics/reset_guard", Trigger.Request()).success
    target = paper_pose(robot)
    tries = []  # (wall time sent, ActionGoal) of the move goals to the paper's pose

    def succeeded(goal) -> bool:
        return goal.result_future.done() and goal.outcome(0)[0] == "SUCCEEDED"

    def reached() -> bool:  # a goal ended short of the target (a stop left by the barrage: BUSY, TIMEOUT...) is
        # sent again after 1 s: that is not this test's subject; the robot reaching it is
        if not tries or (tries[-1][1].result_future.done() and not succeeded(tries[-1][1])
                         and time.monotonic() - tries[-1][0] > 1.0):
            tries.append((time.monotonic(), c.move(target)))
        recent = hostile.poses[-50:]
        return succeeded(tries[-1][1]) and len(recent) == 50 and all(
            e[0] <= 10e-6 and e[1] <= 0.01 for e in (pose_error(m, target) for m in recent))

    assert c.spin_until(reached, 60), (pose_error(hostile.poses[-1], target),
                                       [g.outcome(0) for _, g in tries if g.result_future.done()],
                                       hostile.answers[-6:], hostile.logs())
    assert not hostile.dead(), f"dead at the end: {hostile.dead()}\n{hostile.logs()}"
