"""One warm-started forward-kinematics solve in plain Python floats (low latency).

The batched Newton in fk.py pays about a microsecond of numpy call
overhead per operation, which dominates a single 6x6 problem (the pose
estimate at the joint-state rate). This module runs the same iteration on
Python floats: residual g_i = |p + R a_i - b_i| - l_i, Jacobian rows
[n_i, (R a_i) x n_i], step J [dp; dphi] = -g, update p += dp,
R <- exp([dphi]x) R, step halving while max|g| does not decrease. The 6x6
system is solved by Gaussian elimination with partial pivoting, whose pivots
also give the sign of det J (the assembly-mode test). Loops run over the six
legs of one sample, never over a batch.
"""

from __future__ import annotations

import math

import numpy as np

from .rotations import rotation_from_rpy_scalar, rpy_from_rotation_scalar, so3_exp_scalar

Vector = tuple[float, float, float]
Matrix = tuple[Vector, Vector, Vector]


def solve_linear_6(matrix: list[list[float]], rhs: list[float]) -> tuple[list[float], float] | None:
    """Solve A x = b (n x n, here 6) by Gaussian elimination with partial pivoting.

    Args:
        matrix: A as n rows of n floats; overwritten (rows swapped and eliminated).
        rhs: b, n floats; overwritten.

    Returns:
        (x, sign of det A): x a list of n floats, the sign 1.0 or -1.0; None when a pivot is exactly zero.
    """
    n = len(rhs)
    sign = 1.0
    for col in range(n):
        pivot_row, best = col, abs(matrix[col][col])
        for k in range(col + 1, n):
            value = abs(matrix[k][col])
            if value > best:
                pivot_row, best = k, value
        if best == 0.0:
            return None
        if pivot_row != col:
            matrix[col], matrix[pivot_row] = matrix[pivot_row], matrix[col]
            rhs[col], rhs[pivot_row] = rhs[pivot_row], rhs[col]
            sign = -sign
        top = matrix[col]
        pivot = top[col]
        if pivot < 0.0:
            sign = -sign
        columns = range(col + 1, n)
        for k in columns:
            row = matrix[k]
            factor = row[col] / pivot
            if factor != 0.0:
                for j in columns:
                    row[j] -= factor * top[j]
                rhs[k] -= factor * rhs[col]
    x = [0.0] * n
    for k in range(n - 1, -1, -1):
        row = matrix[k]
        acc = rhs[k]
        for j in range(k + 1, n):
            acc -= row[j] * x[j]
        x[k] = acc / row[k]
    return x, sign


def leg_residuals(hinges, base, position: Vector, rot: Matrix, target):
    """Per leg (d_i, r_i = R a_i, l_i) and the residual max|l_i - target_i| (m).

    Args:
        hinges: the six platform hinges a_i as (x, y, z) floats (platform frame, m).
        base: the six base hinges b_i as (x, y, z) floats (base frame, m).
        position: platform origin p (base frame, m).
        rot: platform rotation R as three rows of three floats.
        target: the six target leg lengths (m).

    Returns:
        (legs, worst): legs a list of six tuples (d_x, d_y, d_z, r_x, r_y, r_z, l_i, l_i - target_i) with
        d_i = p + R a_i - b_i and r_i = R a_i (base frame, m); worst = max_i |l_i - target_i| (m).
    """
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = rot
    px, py, pz = position
    legs = []
    worst = 0.0
    for (ax, ay, az), (bx, by, bz), want in zip(hinges, base, target):
        rx = r00 * ax + r01 * ay + r02 * az
        ry = r10 * ax + r11 * ay + r12 * az
        rz = r20 * ax + r21 * ay + r22 * az
        dx, dy, dz = rx + px - bx, ry + py - by, rz + pz - bz
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        legs.append((dx, dy, dz, rx, ry, rz, length, length - want))
        worst = max(worst, abs(length - want))
    return legs, worst


def _jacobian_system(legs) -> tuple[list[list[float]], list[float]]:
    """Rows [n_i, r_i x n_i] and right-hand side -g_i."""
    rows, rhs = [], []
    for dx, dy, dz, rx, ry, rz, length, g in legs:
        nx, ny, nz = dx / length, dy / length, dz / length
        rows.append([nx, ny, nz, ry * nz - rz * ny, rz * nx - rx * nz, rx * ny - ry * nx])
        rhs.append(-g)
    return rows, rhs


def _least_squares_step(rows, rhs) -> list[float]:
    """Least-squares step for a singular Jacobian (rare, so numpy's overhead does not matter)."""
    return np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)[0].tolist()


def forward_kinematics_scalar(hinges, base, target, start, tol: float, max_iter: int, home_det_sign: float):
    """Newton FK from a warm start for one sample.

    Args:
        hinges: the six platform hinges a_i as (x, y, z) floats (platform frame, m).
        base: the six base hinges b_i as (x, y, z) floats (base frame, m).
        target: the six target leg lengths (m).
        start: start pose [x, y, z, roll, pitch, yaw] (m, rad).
        tol: convergence threshold on max_i |l_i - target_i| (m).
        max_iter: most Newton iterations.
        home_det_sign: sign of det J at the home pose (the expected assembly mode).

    Returns:
        (pose, rotation, iterations, residual, assembly_ok): pose a tuple of six floats (m, rad), rotation R
        as three row tuples, iterations an int, residual max_i |l_i - target_i| (m), and assembly_ok true when
        every platform hinge is above its base hinge (d_z > 0) and sign(det J) equals ``home_det_sign``.
    """
    position = (float(start[0]), float(start[1]), float(start[2]))
    rotation = rotation_from_rpy_scalar(float(start[3]), float(start[4]), float(start[5]))
    legs, res = leg_residuals(hinges, base, position, rotation, target)
    iterations = 0
    det_sign = None
    while res >= tol and iterations < max_iter:
        rows, rhs = _jacobian_system(legs)
        solved = solve_linear_6(rows, rhs)
        if solved is None:
            step, det_sign = _least_squares_step(*_jacobian_system(legs)), 0.0
        else:
            step, det_sign = solved
        alpha = 1.0
        for halving in range(11):
            p_try = (position[0] + alpha * step[0], position[1] + alpha * step[1], position[2] + alpha * step[2])
            rot_try = so3_exp_scalar((alpha * step[3], alpha * step[4], alpha * step[5]), rotation)
            legs_try, res_try = leg_residuals(hinges, base, p_try, rot_try, target)
            if res_try < res or res_try < tol or halving == 10:
                break
            alpha *= 0.5
        position, rotation, legs, res = p_try, rot_try, legs_try, res_try
        iterations += 1
    if det_sign is None:
        # already converged at the start: the sign of det J there
        solved = solve_linear_6(*_jacobian_system(legs))
        det_sign = 0.0 if solved is None else solved[1]
    # the last Newton Jacobian is within one (converged) step of the solution,
    # so its determinant sign identifies the assembly mode
    assembly_ok = all(leg[2] > 0.0 for leg in legs) and det_sign == home_det_sign
    pose = (*position, *rpy_from_rotation_scalar(rotation))
    return pose, rotation, iterations, res, assembly_ok
