"""``stewart-vibration offline-scenario``: the paper's pose, computed offline (no nodes)."""

from __future__ import annotations

import numpy as np

from ..kinematics import condition_number, forward_kinematics, inverse_kinematics, joint_angles
from ..kinematics.robot_config import load_robot
from ..paper import paper_pose
from .output import format_table, print_json


def register(subparsers) -> None:
    """Add the ``offline-scenario`` subcommand to ``subparsers``."""
    cmd = subparsers.add_parser(
        "offline-scenario",
        help="IK, FK and leg lengths at the paper's pose, computed offline (no ROS nodes)",
    )
    cmd.add_argument("--json", action="store_true", help="print JSON")
    cmd.set_defaults(func=run)


def run(args) -> int:
    """``offline-scenario``: print IK at home and at the paper's pose and the FK round trip (m, rad, deg).

    Returns 0, or 1 if FK did not converge (or, as text, found another assembly mode). Raises
    ConfigError (robot file).
    """
    robot = load_robot(args.robot)
    home, pose = robot.home_pose, paper_pose(robot)
    lengths_home = inverse_kinematics(robot, home)
    lengths = inverse_kinematics(robot, pose)
    fk = forward_kinematics(robot, lengths)
    universal, spherical = joint_angles(robot, pose)
    report = {
        "what": "offline computation with the core library: IK at home and at the paper's pose, "
                "then FK (Newton, cold start from home) back from the paper pose's leg lengths. "
                "No ROS nodes were started.",
        "robot_config": robot.source,
        "home_pose": home, "paper_pose": pose,
        "lengths_home_m": lengths_home, "lengths_paper_m": lengths,
        "fk_pose": fk.pose, "fk_pose_error": float(np.abs(fk.pose - pose).max()),
        "fk_iterations": int(fk.iterations), "fk_residual_m": float(fk.residual),
        "condition_number": float(condition_number(robot, pose)),
    }
    if args.json:
        print_json(report)
        return 0 if fk.converged else 1
    print(report["what"])
    print(f"robot config: {robot.source}")
    print("paper pose (home + [2 mm, 2 mm, 2 mm, pi/15, pi/12, pi/18]): "
          + " ".join(f"{v:.6f}" for v in pose))
    rows = [[f"leg_{i + 1}", lengths_home[i], lengths[i], (lengths[i] - lengths_home[i]) * 1e3,
             np.degrees(universal[i]), np.degrees(spherical[i])] for i in range(6)]
    print(format_table(["leg", "home_m", "paper_m", "change_mm", "universal_deg", "spherical_deg"], rows,
                       "{:.6f}"))
    print(f"FK round trip: {report['fk_iterations']} Newton iterations, residual "
          f"{report['fk_residual_m']:.2e} m, pose error {report['fk_pose_error']:.2e}")
    print(f"condition number at the paper pose: {report['condition_number']:.3f}")
    return 0 if fk.converged and fk.assembly_ok else 1
