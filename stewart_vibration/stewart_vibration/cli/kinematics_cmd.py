"""``stewart-vibration ik`` and ``fk``: kinematics from the command line.

``ik`` runs the library's full pose check (kinematics.check_pose: finite,
above the base, strokes, joints, conditioning), so a pose the robot cannot take
or a singular one is a typed error (exit 2), never a printed result.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..kinematics import check_pose, condition_number, forward_kinematics, joint_angles
from ..kinematics.robot_config import load_robot
from .arguments import finite_float, float_in, int_in, positive_float
from .output import format_table, print_json

GUESS_MAX = 10.0  # m or rad: a starting pose beyond this is no guess of this robot's pose
TOLERANCE_RANGE = (1e-15, 1e-3)  # m: below, float rounding of the leg lengths; above, not a solution
FK_MAX_ITERATIONS = 1000  # Newton converges in < 10 from home; more only spends time on a pose it cannot find
POSE_FIELDS = ["x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad"]


def register(subparsers) -> None:
    """Add the ``ik`` and ``fk`` subcommands to ``subparsers``."""
    ik = subparsers.add_parser("ik", help="inverse kinematics: pose -> six leg lengths")
    ik.add_argument("pose", nargs=6, type=finite_float, metavar="Q",
                    help="x y z (m) roll pitch yaw (rad, or deg with --deg); R = Rz(yaw) Ry(pitch) Rx(roll)")
    ik.add_argument("--deg", action="store_true", help="angles in degrees")
    ik.add_argument("--json", action="store_true", help="print JSON")
    ik.set_defaults(func=run_ik)

    fk = subparsers.add_parser("fk", help="forward kinematics (Newton): six leg lengths -> pose")
    fk.add_argument("lengths", nargs=6, type=positive_float, metavar="L", help="leg lengths l1..l6 (m)")
    fk.add_argument("--guess", nargs=6, type=float_in(-GUESS_MAX, GUESS_MAX), metavar="Q",
                    help=f"initial pose x y z roll pitch yaw (m, rad; each within +-{GUESS_MAX:g}); default: from home")
    fk.add_argument("--tol", type=float_in(*TOLERANCE_RANGE, "m"), default=1e-12,
                    help=f"residual tolerance, m ({TOLERANCE_RANGE[0]:g} to {TOLERANCE_RANGE[1]:g}, default 1e-12)")
    fk.add_argument("--max-iter", type=int_in(1, FK_MAX_ITERATIONS), default=50,
                    help=f"Newton iterations at most (default 50, at most {FK_MAX_ITERATIONS})")
    fk.add_argument("--json", action="store_true", help="print JSON")
    fk.set_defaults(func=run_fk)


def run_ik(args) -> int:
    """``ik``: print a pose's six leg lengths (m), joint angles (deg) and condition number; exit 0.

    The pose is x y z (m) roll pitch yaw (rad, deg with --deg), the platform in the base frame. Raises
    ConfigError (robot file), InvalidInputError, StrokeLimitError, JointLimitError or another
    UnreachablePoseError, and SingularPoseError, from ``check_pose``.
    """
    robot = load_robot(args.robot)
    pose = np.array(args.pose)
    if args.deg:
        pose[3:] = np.radians(pose[3:])
    lengths = check_pose(robot, pose)  # SingularPoseError / StrokeLimitError / ... name the reason
    universal, spherical = joint_angles(robot, pose)
    cond = float(condition_number(robot, pose))
    if args.json:
        print_json({"pose": dict(zip(POSE_FIELDS, pose)), "lengths_m": lengths,
                    "universal_joint_deg": np.degrees(universal),
                    "spherical_joint_deg": np.degrees(spherical), "condition_number": cond})
        return 0
    rows = [[f"leg_{i + 1}", lengths[i], np.degrees(universal[i]), np.degrees(spherical[i])] for i in range(6)]
    print(format_table(["leg", "length_m", "universal_deg", "spherical_deg"], rows))
    print(f"condition number (dimensionally homogeneous): {cond:.4f}")
    return 0


def run_fk(args) -> int:
    """``fk``: print the pose (m, rad; platform in the base frame) of six leg lengths (m), solved by Newton.

    Returns 0, or 3 if Newton did not converge or found another assembly mode. Raises ConfigError
    (robot file), InvalidInputError (a length <= 0, bad guess) and StrokeLimitError (a length outside
    the stroke).
    """
    robot = load_robot(args.robot)
    result = forward_kinematics(robot, np.array(args.lengths), guess=args.guess, tol=args.tol,
                                max_iter=args.max_iter)
    payload: dict[str, Any] = {"pose": dict(zip(POSE_FIELDS, result.pose)), "iterations": int(result.iterations),
               "residual_m": float(result.residual), "converged": bool(result.converged),
               "assembly_ok": bool(result.assembly_ok)}
    if args.json:
        print_json(payload)
    else:
        print(format_table(["field", "value"], [[k, v] for k, v in payload["pose"].items()], "{:.12f}"))
        print(f"iterations {payload['iterations']}, residual {payload['residual_m']:.3e} m, "
              f"converged {payload['converged']}, assembly ok {payload['assembly_ok']}")
    return 0 if result.converged and result.assembly_ok else 3
