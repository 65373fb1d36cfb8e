"""Newton-Euler leg forces: power balance, statics limit, symmetry, options.

References are computed here independently of stewart_vibration.dynamics.newton_euler.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from reference import config_hinges, rot_x, rot_y, rot_z

from stewart_vibration.dynamics.newton_euler import Friction, leg_forces, leg_forces_paper
from stewart_vibration.dynamics.platform_trajectory import SinusoidalTrajectory
from stewart_vibration.errors import InvalidInputError
from stewart_vibration.kinematics import jacobian
from stewart_vibration.kinematics.rotations import rotation_from_rpy
from stewart_vibration.paper import paper_pose


def random_trajectory(robot, seed, k=3, scale=1.0):
    rng = np.random.default_rng(seed)
    amp = rng.uniform(-1, 1, (k, 6)) * np.array([0.005, 0.005, 0.005, 0.05, 0.05, 0.05]) * scale
    return SinusoidalTrajectory(paper_pose(robot), amp, rng.uniform(2.0, 40.0, k), rng.uniform(0, 2 * np.pi, (k, 6)))


def energy(robot, pose, twist):
    """T + V (J) of platform, payload, cylinders and pistons, from body velocities.

    Leg masses: cylinder; piston + vibration unit (lumped, the documented model choice).
    """
    g = robot.gravity
    body = robot.moving_body
    rot = rotation_from_rpy(pose[:, 3:])
    p, v, w = pose[:, :3], twist[:, :3], twist[:, 3:]
    c = np.einsum("nij,j->ni", rot, body.com)
    v_c = v + np.cross(w, c)
    inertia = rot @ body.inertia @ np.swapaxes(rot, 1, 2)
    t = 0.5 * body.mass * np.sum(v_c**2, -1) + 0.5 * np.einsum("ni,nij,nj->n", w, inertia, w)
    pot = -body.mass * (p + c) @ g
    leg = robot.leg
    m1, e1, m2, e2 = leg.cylinder_mass, leg.cylinder_com_offset, leg.piston_mass + leg.vibration_unit_mass, \
        leg.piston_com_offset
    it = leg.cylinder_inertia_transverse + leg.piston_inertia_transverse
    for i in range(6):
        arm = np.einsum("nij,j->ni", rot, robot.platform_hinges[i])
        d = p + arm - robot.base_hinges[i]
        length = np.linalg.norm(d, axis=-1)
        s = d / length[:, None]
        v_a = v + np.cross(w, arm)
        l_dot = np.sum(s * v_a, -1)
        s_dot = (v_a - l_dot[:, None] * s) / length[:, None]
        w_leg = np.cross(s, s_dot)
        v2 = l_dot[:, None] * s + (length - e2)[:, None] * s_dot
        t += 0.5 * m1 * e1**2 * np.sum(s_dot**2, -1) + 0.5 * m2 * np.sum(v2**2, -1) + 0.5 * it * np.sum(w_leg**2, -1)
        pot += -m1 * (robot.base_hinges[i] + e1 * s) @ g - m2 * (robot.base_hinges[i] + (length - e2)[:, None] * s) @ g
    return t + pot


def strut_rates(robot, pose, twist):
    rot = rotation_from_rpy(pose[:, 3:])
    arm = np.einsum("nij,kj->nki", rot, robot.platform_hinges)
    d = pose[:, None, :3] + arm - robot.base_hinges
    s = d / np.linalg.norm(d, axis=-1, keepdims=True)
    return np.sum(s * (twist[:, None, :3] + np.cross(twist[:, None, 3:], arm)), -1)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_power_balance_along_random_trajectories(robot, seed):
    traj = random_trajectory(robot, seed)
    duration = 0.5
    nodes, weights = np.polynomial.legendre.leggauss(300)
    t = 0.5 * duration * (nodes + 1.0)
    samp = traj.sample(t)
    rng = np.random.default_rng(100 + seed)
    wrench = rng.normal(size=6) * np.array([5, 5, 5, 0.3, 0.3, 0.3])
    forces = leg_forces(robot, samp.pose, samp.twist, samp.accel, external_wrench=wrench)
    power = np.sum(forces * strut_rates(robot, samp.pose, samp.twist), -1) + samp.twist @ wrench
    work = 0.5 * duration * weights @ power
    ends = traj.sample(np.array([0.0, duration]))
    e = energy(robot, ends.pose, ends.twist)
    scale = 0.5 * duration * weights @ np.abs(power)
    residual = abs((e[1] - e[0]) - work) / scale
    assert residual <= 1e-8, residual


def test_power_balance_detects_a_missing_term(robot):
    """The same check rejects the paper model (it drops leg dynamics): the test can fail."""
    traj = random_trajectory(robot, 0)
    nodes, weights = np.polynomial.legendre.leggauss(300)
    t = 0.25 * (nodes + 1.0)
    samp = traj.sample(t)
    power = np.sum(leg_forces_paper(robot, samp.pose, samp.twist, samp.accel)
                   * strut_rates(robot, samp.pose, samp.twist), -1)
    ends = traj.sample(np.array([0.0, 0.5]))
    e = energy(robot, ends.pose, ends.twist)
    assert abs((e[1] - e[0]) - 0.25 * weights @ power) / (0.25 * weights @ np.abs(power)) > 1e-3


def com_motion(robot, samp):
    """Platform R, COM offset c = R c_p, w, alpha and COM acceleration (base frame)."""
    rot = rotation_from_rpy(samp.pose[:, 3:])
    c = np.einsum("nij,j->ni", rot, robot.moving_body.com)
    w, alpha = samp.twist[:, 3:], samp.accel[:, 3:]
    return rot, c, w, alpha, samp.accel[:, :3] + np.cross(alpha, c) + np.cross(w, np.cross(w, c))


def massless_legs(robot):
    leg = dataclasses.replace(robot.leg, cylinder_mass=0.0, cylinder_inertia_transverse=0.0,
                              cylinder_inertia_axial=0.0, piston_mass=0.0, piston_inertia_transverse=0.0,
                              piston_inertia_axial=0.0, vibration_unit_mass=0.0)
    return dataclasses.replace(robot, leg=leg)


def test_massless_legs_reduce_to_jacobian_statics(robot):
    light = massless_legs(robot)
    samp = random_trajectory(robot, 7).sample(np.linspace(0, 0.3, 9))
    rng = np.random.default_rng(7)
    wrench = rng.normal(size=6) * np.array([5, 5, 5, 0.3, 0.3, 0.3])
    forces = leg_forces(light, samp.pose, samp.twist, samp.accel, external_wrench=wrench)
    # platform wrench (force; moment about the platform origin) the legs must supply
    body = robot.moving_body
    rot, c, w, alpha, a_c = com_motion(robot, samp)
    inertia = rot @ body.inertia @ np.swapaxes(rot, 1, 2)
    f = body.mass * (a_c - robot.gravity) - wrench[:3]
    mom = (np.einsum("nij,nj->ni", inertia, alpha) + np.cross(w, np.einsum("nij,nj->ni", inertia, w))
           + np.cross(c, body.mass * (a_c - robot.gravity)) - wrench[3:])
    jt_f = np.einsum("nij,ni->nj", jacobian(robot, samp.pose), forces)
    expected = np.concatenate([f, mom], -1)
    assert np.abs(jt_f - expected).max() <= 1e-12 * np.abs(expected).max()
    # the paper model is the same when the legs are massless
    paper = leg_forces_paper(light, samp.pose, samp.twist, samp.accel, external_wrench=wrench)
    assert np.allclose(paper, forces, rtol=1e-12, atol=1e-12)


def test_symmetric_pose_gives_equal_forces(robot):
    pose = robot.home_pose
    twist = np.array([0.0, 0.0, 0.01, 0.0, 0.0, 0.0])
    accel = np.array([0.0, 0.0, 3.0, 0.0, 0.0, 0.0])
    forces = leg_forces(robot, pose, twist, accel)
    assert np.ptp(forces) <= 1e-12 * np.abs(forces).max()
    # weight check, closed form: massless legs, six equal struts at s_z = z / l carry m (a_z - g_z)
    base, platform = config_hinges(robot.source)
    length = np.linalg.norm(pose[:3] + platform[0] - base[0])
    s_z = pose[2] / length
    lifted = robot.moving_body.mass * (accel[2] - robot.gravity[2])
    light = leg_forces(massless_legs(robot), pose, twist, accel)
    np.testing.assert_allclose(light, lifted / (6 * s_z), rtol=1e-12, atol=0)
    # with the legs' mass: power balance at this instant, 6 F l_dot = dE/dt along z(t) = z0 + v t + a t^2 / 2
    h = 1e-3
    t = np.array([-2, -1, 1, 2]) * h
    path = np.tile(pose, (4, 1))
    path[:, 2] += twist[2] * t + 0.5 * accel[2] * t**2
    rates = np.zeros((4, 6))
    rates[:, 2] = twist[2] + accel[2] * t
    e = energy(robot, path, rates)
    de_dt = (e[0] - 8 * e[1] + 8 * e[2] - e[3]) / (12 * h)
    np.testing.assert_allclose(forces, de_dt / (6 * s_z * twist[2]), rtol=1e-9, atol=0)
    assert forces[0] > light[0]  # the legs' own weight adds to the platform's
    asym = leg_forces(robot, paper_pose(robot), twist, accel)
    assert np.ptp(asym) > 0.1


def test_reactions_balance_each_leg_and_platform(robot):
    samp = random_trajectory(robot, 11).sample(np.linspace(0, 0.2, 5))
    res = leg_forces(robot, samp.pose, samp.twist, samp.accel, return_reactions=True)
    forces = leg_forces(robot, samp.pose, samp.twist, samp.accel)
    assert np.allclose(res.force, forces, rtol=0, atol=1e-12)
    body = robot.moving_body
    rot, c, w, alpha, a_c = com_motion(robot, samp)
    # sum of leg-on-platform forces = m (a_c - g)
    assert np.allclose(res.platform_joint.sum(axis=1), body.mass * (a_c - robot.gravity), rtol=0, atol=1e-10)
    # transverse part is normal to the leg; axial part of platform_joint - transverse is along s
    m = leg_forces(robot, samp.pose, samp.twist, samp.accel, return_reactions=True)
    d = samp.pose[:, None, :3] + np.einsum("nij,kj->nki", rot, robot.platform_hinges) - robot.base_hinges
    s = d / np.linalg.norm(d, axis=-1, keepdims=True)
    assert np.abs(np.sum(m.transverse * s, -1)).max() < 1e-12
    # whole-robot momentum: base reactions + gravity = rate of momentum of all moving bodies
    total_leg_mass = robot.leg.cylinder_mass + robot.leg.piston_mass + robot.leg.vibration_unit_mass
    weight = (body.mass + 6 * total_leg_mass) * robot.gravity
    static = leg_forces(robot, robot.home_pose, np.zeros(6), np.zeros(6), return_reactions=True)
    assert np.allclose(static.base_joint.sum(axis=0), -weight, rtol=0, atol=1e-10)


def test_friction_adds_on_top(robot):
    samp = random_trajectory(robot, 5).sample(np.linspace(0, 0.2, 6))
    base = leg_forces(robot, samp.pose, samp.twist, samp.accel)
    fric = Friction(coulomb=2.0, viscous=np.full(6, 30.0))
    forces = leg_forces(robot, samp.pose, samp.twist, samp.accel, friction=fric)
    rates = strut_rates(robot, samp.pose, samp.twist)
    assert np.allclose(forces - base, 2.0 * np.sign(rates) + 30.0 * rates, rtol=0, atol=1e-12)
    coulomb_only = leg_forces(robot, samp.pose, samp.twist, samp.accel, friction=Friction(coulomb=2.0))
    assert np.allclose(coulomb_only - base, 2.0 * np.sign(rates), rtol=0, atol=1e-12)  # viscous 0 by default


def test_external_wrench_sign_and_batch_shapes(robot):
    pose = paper_pose(robot)
    zero = np.zeros(6)
    free = leg_forces(robot, pose, zero, zero)
    # an upward external force equal to the weight unloads the struts by the platform's share
    weight = np.r_[-robot.moving_body.mass * robot.gravity, np.cross(
        rotation_from_rpy(pose[3:]) @ robot.moving_body.com, -robot.moving_body.mass * robot.gravity)]
    lifted = leg_forces(robot, pose, zero, zero, external_wrench=weight)
    only_legs = leg_forces(massless_legs(robot), pose, zero, zero)
    assert np.allclose(free - lifted, only_legs, rtol=0, atol=1e-12)
    batch = leg_forces(robot, np.broadcast_to(pose, (2, 3, 6)), zero, zero)
    assert batch.shape == (2, 3, 6) and np.allclose(batch, free, rtol=0, atol=1e-12)
    with pytest.raises(InvalidInputError):
        leg_forces(robot, np.full(6, np.nan), zero, zero)
    with pytest.raises(InvalidInputError):
        leg_forces(robot, pose, np.zeros(5), zero)


def euler_twist_reference(pose, rate, acc):
    """Twist and accel [n, 6] from nested axes, one sample at a time (independent of the library's E(theta)).

    R = Rz(yaw) Ry(pitch) Rx(roll): w = yaw' z + pitch' Rz y + roll' Rz Ry x; each axis turns with the
    angular velocity of the rotations before it, so alpha adds pitch' (w_z x Rz y) + roll' (w_zy x Rz Ry x).
    """
    twist, accel = np.empty_like(pose), np.empty_like(pose)
    for k, (q, qd, qdd) in enumerate(zip(pose, rate, acc)):
        rz = rot_z(q[5])
        z_axis, y_axis, x_axis = np.array([0.0, 0, 1]), rz[:, 1], (rz @ rot_y(q[4]))[:, 0]
        w_z = qd[5] * z_axis
        w_zy = w_z + qd[4] * y_axis
        twist[k] = np.r_[qd[:3], w_zy + qd[3] * x_axis]
        alpha = (qdd[5] * z_axis + qdd[4] * y_axis + qd[4] * np.cross(w_z, y_axis) + qdd[3] * x_axis
                 + qd[3] * np.cross(w_zy, x_axis))
        accel[k] = np.r_[qdd[:3], alpha]
    return twist, accel


@pytest.mark.parametrize("seed", [9, 10])
def test_euler_rate_input_agrees_with_twist(robot, seed):
    """twist_from_euler_rates against the nested-axes closed form; leg forces from either input agree."""
    from stewart_vibration.dynamics.platform_trajectory import twist_from_euler_rates

    traj = random_trajectory(robot, seed, scale=10.0)  # angles up to 0.5 rad, rates ~ 10 rad/s
    pose, rate, acc = traj.pose_derivatives(np.linspace(0, 0.2, 9))
    twist, accel = twist_from_euler_rates(pose, rate, acc)
    ref_twist, ref_accel = euler_twist_reference(pose, rate, acc)
    assert np.abs(twist - ref_twist).max() <= 1e-13 * np.abs(ref_twist).max()
    assert np.abs(accel - ref_accel).max() <= 1e-13 * np.abs(ref_accel).max()
    forces = leg_forces(robot, pose, twist, accel)
    ref = leg_forces(robot, pose, ref_twist, ref_accel)
    assert np.abs(forces - ref).max() <= 1e-12 * np.abs(ref).max()


def test_solver_falls_back_to_lapack_when_elimination_fails(robot, monkeypatch):
    import stewart_vibration.dynamics.newton_euler as dyn

    samp = random_trajectory(robot, 13).sample(np.linspace(0, 0.2, 7))
    good = leg_forces(robot, samp.pose, samp.twist, samp.accel)
    monkeypatch.setattr(dyn, "_eliminate", lambda g, b: np.full_like(b, np.nan))
    assert np.allclose(leg_forces(robot, samp.pose, samp.twist, samp.accel), good, rtol=1e-12, atol=1e-12)


def test_workspace_samples_are_solved_by_the_fast_elimination(robot, monkeypatch):
    """The preconditioner is H^-1 at home (H built here from the YAML hinges), and with it the unpivoted
    elimination solves workspace samples by itself: the LAPACK fallback is never needed there."""
    import stewart_vibration.dynamics.newton_euler as dyn

    base, platform = config_hinges(robot.source)
    home = robot.home_pose
    rot = rot_z(home[5]) @ rot_y(home[4]) @ rot_x(home[3])
    arms = platform @ rot.T
    d = home[:3] + arms - base
    s = d / np.linalg.norm(d, axis=1, keepdims=True)
    rho = arms - rot @ robot.moving_body.com
    h_home = np.vstack([s.T, np.cross(rho, s).T])  # column i = [s_i; rho_i x s_i]
    np.testing.assert_allclose(dyn._preconditioner(robot) @ h_home, np.eye(6), rtol=0, atol=1e-12)

    samp = random_trajectory(robot, 13).sample(np.linspace(0, 0.2, 7))
    good = leg_forces(robot, samp.pose, samp.twist, samp.accel)

    def no_lapack(*_args, **_kwargs):
        raise AssertionError("LAPACK fallback used for a workspace sample")

    monkeypatch.setattr(np.linalg, "solve", no_lapack)
    np.testing.assert_allclose(leg_forces(robot, samp.pose, samp.twist, samp.accel), good, rtol=1e-12, atol=1e-12)
