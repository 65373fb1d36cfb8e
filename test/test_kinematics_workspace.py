"""What the six struts do together along a path (kinematics.workspace.check_strut_path): the poses it finds are
the ones the lengths come from, legal-per-strut moves that wreck the platform are refused where a dense
independent FK crosses the limit, a crossing between samples is caught, and the first-order margins bound
the real change of every quantity."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from stewart_vibration import inverse_kinematics
from stewart_vibration.errors import JointLimitError, SingularPoseError, StrokeLimitError, UnreachablePoseError
from stewart_vibration.install import default_config_dir
from stewart_vibration.kinematics import condition_number, forward_kinematics, joint_angles
from stewart_vibration.kinematics.fk import _newton_rows
from stewart_vibration.kinematics.path_sampling import MAX_PATH_SAMPLES, PATH_SPACING_M
from stewart_vibration.kinematics.pose_margins import PoseState
from stewart_vibration.kinematics.workspace import check_strut_path
from stewart_vibration.motion.profiles import minimum_jerk, minimum_jerk_duration
from stewart_vibration.robot import robot_from_dict


def pose_path(robot, offset, duration):
    """l(t) = IK(home + offset s(t)), s the minimum-jerk smoothstep over ``duration``: (sampler, poses(t))."""
    home = np.asarray(robot.home_pose, float)

    def poses(t):
        s = minimum_jerk(0.0, 1.0, duration, np.atleast_1d(t))[0]
        return home + s * np.asarray(offset, float)

    return (lambda t: inverse_kinematics(robot, poses(t), check_limits=False)), poses


def dense_reference(robot, lengths):
    """Poses of strut lengths [n, 6] by an independent route: every 10th row solved from the previous one (the
    batched Newton row by row), the rows between in one batch from the nearest solved pose; stops at the
    first failure (the rows beyond are not returned)."""
    pose = np.asarray(robot.home_pose, float)
    anchors = []
    for row in lengths[::10]:
        p, _, _, _, conv, ok = _newton_rows(robot, row[None, :], pose[None, :], 1e-12, 50)
        if not (conv[0] and ok[0]):
            break
        pose = p[0]
        anchors.append(pose)
    count = min(len(lengths), 10 * len(anchors))
    guess = np.array(anchors)[np.arange(count) // 10]
    p, _, _, _, conv, ok = _newton_rows(robot, lengths[:count], guess, 1e-12, 50)
    good = conv & ok
    return p[:int(np.argmin(good)) if not good.all() else count]


def first_crossing(robot, times, poses):
    """(time, name) of the first pose beyond a joint or conditioning limit (None if none)."""
    lim = robot.limits
    u, s = joint_angles(robot, poses)
    cond = condition_number(robot, poses)
    bad = ((u > lim.universal_joint_max).any(1) | (s > lim.spherical_joint_max).any(1)
           | (cond > lim.condition_number_max))
    if not bad.any():
        return None
    k = int(np.argmax(bad))
    name = ("universal_joint_max" if (u[k] > lim.universal_joint_max).any() else
            "spherical_joint_max" if (s[k] > lim.spherical_joint_max).any() else "condition_number_max")
    return float(times[k]), name


def test_the_poses_along_an_accepted_path_are_the_ones_its_lengths_come_from(robot):
    sample, poses = pose_path(robot, [0.015, -0.01, 0.012, 0.15, -0.1, 0.2], 4.0)
    result = check_strut_path(robot, sample, 0.0, 4.0)
    assert np.abs(result.poses - poses(result.times)).max() < 1e-9
    # the same samples to rounding (which numpy kernel runs, and so the last bit, depends on the CPU)
    assert np.abs(result.lengths - sample(result.times)).max() <= 1e-15
    # every instant lies within half the spacing of a checked sample (strut travel, infinity norm)
    dense = np.linspace(0.0, 4.0, 8001)
    after = np.clip(np.searchsorted(result.times, dense), 1, len(result.times) - 1)  # the samples around each instant
    lengths = sample(dense)
    nearest = np.minimum(np.abs(lengths - result.lengths[after - 1]).max(axis=1),
                         np.abs(lengths - result.lengths[after]).max(axis=1))
    assert nearest.max() <= 0.5 * PATH_SPACING_M


@pytest.mark.parametrize("delta", [[0.045, -0.03] * 3, [0.07, 0.07, -0.07, -0.07, 0.0, 0.0]])
def test_legal_per_strut_moves_that_wreck_the_platform_are_refused_where_the_limit_is_crossed(robot, delta):
    """The two known wrecking commands: minimum-jerk strut moves within every per-strut limit whose platform
    passes the joint limits (and then a singularity, where MuJoCo went unstable)."""
    home = inverse_kinematics(robot, robot.home_pose)
    goal = home + np.array(delta)
    duration = minimum_jerk_duration(home, goal, 0.9 * robot.limits.strut_velocity_max, 0.5)

    def sample(t):
        return minimum_jerk(home, goal, duration, np.atleast_1d(t))[0]

    with pytest.raises((JointLimitError, SingularPoseError)) as refused:
        check_strut_path(robot, sample, 0.0, duration)
    dense_t = np.arange(0.0, duration, 2e-3)
    reference = dense_reference(robot, sample(dense_t))
    crossing = first_crossing(robot, dense_t[:len(reference)], reference)
    assert crossing is not None, "the reference never crosses a limit"
    error = refused.value
    assert error.limit_name == crossing[1]
    assert crossing[0] - 0.05 <= error.time <= crossing[0] + 2e-3, (error.time, crossing)
    assert 1 <= error.leg <= 6 and str(error)


def bumped_roll(robot, peak, duration=6.0):
    """l(t) of a roll sin^2(pi t / T) * peak (rad) about home: its joint angles peak at t = T / 2."""
    home = np.asarray(robot.home_pose, float)

    def poses(t):
        t = np.atleast_1d(t)
        return home + np.outer(np.sin(np.pi * t / duration) ** 2, [0, 0, 0, peak, 0, 0])

    return (lambda t: inverse_kinematics(robot, poses(t), check_limits=False)), poses


def angle_excess(robot, poses):
    """Per pose [n]: the largest joint angle minus its limit over the legs (rad)."""
    u, s = joint_angles(robot, np.atleast_2d(poses))
    return np.maximum((u - robot.limits.universal_joint_max).max(-1), (s - robot.limits.spherical_joint_max).max(-1))


def peak_angle_excess(robot, peak):
    """angle_excess at the roll ``peak`` (rad) about home."""
    return float(angle_excess(robot, np.asarray(robot.home_pose, float) + np.array([0, 0, 0, peak, 0, 0]))[0])


def roll_with_peak_excess(robot, excess):
    """The roll peak (rad) whose largest joint angle sits ``excess`` (rad) above its limit (bisection)."""
    lo, hi = 0.0, 1.2
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if peak_angle_excess(robot, mid) < excess else (lo, mid)
    return hi


@pytest.mark.parametrize("excess_deg,refused", [(-0.05, False), (0.003, True), (0.05, True)])
def test_a_limit_crossed_for_an_instant_between_samples_is_caught(robot, excess_deg, refused):
    """A roll that tips a joint over its limit by 0.003 deg for a few milliseconds (well between two samples
    of the coarse grid): refused at the peak; 0.05 deg inside: accepted (no vibration reach here: the sampling
    alone)."""
    sample, poses = bumped_roll(robot, roll_with_peak_excess(robot, np.radians(excess_deg)))
    t = np.linspace(0.0, 6.0, 6001)
    lengths = sample(t)
    accel = np.abs(np.diff(lengths, 2, axis=0)).max() / (t[1] - t[0]) ** 2
    assert accel < robot.limits.strut_acceleration_max  # the path keeps the precondition
    over = np.flatnonzero(angle_excess(robot, poses(t)) > 0)
    if not refused:
        check_strut_path(robot, sample, 0.0, 6.0, reach=0.0)
        assert over.size == 0
        return
    with pytest.raises(JointLimitError) as error:
        check_strut_path(robot, sample, 0.0, 6.0, reach=0.0)
    assert over.size and t[over[0]] - 0.2 <= error.value.time <= t[over[-1]] + 1e-3
    assert error.value.limit_name in ("universal_joint_max", "spherical_joint_max")


def test_the_struts_leave_room_for_the_vibration_units(robot):
    """The units ride on the struts (up to amplitude_max each): a path that keeps its joints inside the limit
    by less than what 100 um of the units can add is refused, and that amount is real -- some pattern of
    +-100 um at the peak pose takes the joint over the limit; a path further inside is taken."""
    amp = robot.vibration_unit.amplitude_max
    peak_pose = robot.home_pose + np.array([0, 0, 0, roll_with_peak_excess(robot, 0.0), 0, 0])
    state = PoseState.at(robot, peak_pose[None, :])
    room = float(max(state.margins(robot, np.array([amp]))[1].max(), state.margins(robot, np.array([amp]))[2].max()))
    for inside, refused in ((0.3 * room, True), (1.5 * room, False)):
        sample, poses = bumped_roll(robot, roll_with_peak_excess(robot, -inside))
        if refused:
            with pytest.raises(JointLimitError, match="vibration units"):
                check_strut_path(robot, sample, 0.0, 6.0)
            lengths = inverse_kinematics(robot, poses(3.0), check_limits=False)[0]
            signs = np.array([[(k >> i) & 1 for i in range(6)] for k in range(64)]) * 2.0 - 1.0
            fk = forward_kinematics(robot, lengths + amp * signs, guess=np.broadcast_to(poses(3.0), (64, 6)))
            assert fk.converged.all() and (angle_excess(robot, fk.pose) > 0).any()
        else:
            check_strut_path(robot, sample, 0.0, 6.0)


def test_the_first_order_margins_bound_the_real_change(robot):
    """For poses across the workspace and strut changes of at most h (every sign pattern of +-h and random
    ones), the real change of d_z, both joint angles and the condition number stays within the margins the
    check adds for h (so a limit held by sample + margin holds within h of the sample)."""
    rng = np.random.default_rng(7)
    poses = robot.home_pose + np.concatenate([rng.uniform(-0.03, 0.03, (150, 3)), rng.uniform(-0.35, 0.35, (150, 3))],
                                             axis=1)
    lengths = inverse_kinematics(robot, poses, check_limits=False)
    keep = (lengths.min(1) > robot.limits.stroke_min) & (lengths.max(1) < robot.limits.stroke_max)
    poses, lengths = poses[keep], lengths[keep]
    h = 0.5 * PATH_SPACING_M
    state = PoseState.at(robot, poses)
    dz, mu, ms, mc = state.margins(robot, np.full(len(poses), h))
    signs = np.array([[(k >> i) & 1 for i in range(6)] for k in range(64)]) * 2.0 - 1.0
    steps = np.concatenate([signs, rng.uniform(-1, 1, (64, 6))]) * h
    worst = 0.0
    for step in steps:
        fk = forward_kinematics(robot, lengths + step, guess=poses, check_limits=False)
        assert fk.converged.all()
        moved = PoseState.at(robot, fk.pose)
        for change, margin in ((np.abs(moved.d[..., 2] - state.d[..., 2]), dz),
                               (np.abs(moved.universal - state.universal), mu),
                               (np.abs(moved.spherical - state.spherical), ms),
                               (np.abs(moved.condition - state.condition)[:, None], mc[:, None])):
            assert (change <= margin).all()
            worst = max(worst, float((change / margin).max()))
    assert worst > 0.2  # the margins are bounds, not gross overestimates


def test_near_singular_paths_are_refused_by_the_condition_number(robot):
    """A robot whose joints allow 89 deg: a yaw toward its singularity is refused at condition_number_max where
    the dense reference crosses it -- earlier with the vibration units' reach, where 100 um of them would take
    the condition number most of the way there."""
    tree = yaml.safe_load((default_config_dir() / "robot.yaml").read_text())
    tree["limits"].update(universal_joint_max_deg=89.0, spherical_joint_max_deg=89.0, stroke_max_m=0.4)
    loose = robot_from_dict(tree, "loose")
    yaws = np.linspace(0.0, 1.6, 1601)
    cond = condition_number(loose, np.asarray(loose.home_pose) + np.outer(yaws, [0, 0, 0, 0, 0, 1]))
    assert cond.max() > loose.limits.condition_number_max
    sample, poses = pose_path(loose, [0, 0, 0, 0, 0, 1.6], 8.0)
    t = np.linspace(0.0, 8.0, 8001)
    crossing = t[np.argmax(condition_number(loose, poses(t)) > loose.limits.condition_number_max)]
    with pytest.raises(SingularPoseError) as exact:  # the path alone: refused where it crosses
        check_strut_path(loose, sample, 0.0, 8.0, reach=0.0)
    assert exact.value.limit_name == "condition_number_max"
    assert crossing - 0.1 <= exact.value.time <= crossing + 1e-3
    with pytest.raises(SingularPoseError) as error:  # with the vibration units' reach: earlier, and rightly so
        check_strut_path(loose, sample, 0.0, 8.0)
    assert error.value.time < exact.value.time
    pose = poses(error.value.time)[0]
    lengths = inverse_kinematics(loose, pose, check_limits=False)
    signs = np.array([[(k >> i) & 1 for i in range(6)] for k in range(64)]) * 2.0 - 1.0
    fk = forward_kinematics(loose, lengths + loose.vibration_unit.amplitude_max * signs,
                            guess=np.broadcast_to(pose, (64, 6)), check_limits=False)
    reached = condition_number(loose, fk.pose[fk.converged]).max()
    here = float(condition_number(loose, pose))
    assert reached > here + 0.5 * (loose.limits.condition_number_max - here)  # the units can take it most of the way


def test_a_path_through_the_stroke_is_refused_with_the_stroke_limit(robot):
    home = inverse_kinematics(robot, robot.home_pose)
    goal = home.copy()
    goal[2] = robot.limits.stroke_max + 0.002
    with pytest.raises(StrokeLimitError):
        check_strut_path(robot, lambda t: minimum_jerk(home, goal, 8.0, np.atleast_1d(t))[0], 0.0, 8.0)


def test_a_path_too_long_to_check_is_refused_from_its_cost(robot):
    """An hour of full-speed oscillation: refused as too long to check (max_path_samples) before any FK."""
    home = inverse_kinematics(robot, robot.home_pose)
    omega = robot.limits.strut_velocity_max / 0.004

    def sample(t):
        return home + 0.004 * np.sin(omega * np.atleast_1d(t))[:, None]

    with pytest.raises(UnreachablePoseError) as error:
        check_strut_path(robot, sample, 0.0, 3600.0)
    assert error.value.limit_name == "max_path_samples" and error.value.value > MAX_PATH_SAMPLES
