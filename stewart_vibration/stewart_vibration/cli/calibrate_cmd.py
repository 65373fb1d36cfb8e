"""``stewart-vibration calibrate``: run kinematics' calibrate action on the running suite (ROS_DOMAIN_ID and
--namespace as the nodes'), print its progress and result, and the robot file it wrote.

Exit codes: 0 SUCCEEDED (the file written, or the plan reported with --plan-only); 1 the calibration ended
otherwise (its typed outcome printed: CALIBRATION_REJECTED, GUARD_STOPPED, ...); 2 no calibrate action
within --wait, or bad arguments; 130 interrupted (the calibration cancelled).
"""

from __future__ import annotations

import json

from .arguments import float_in, int_in, ros_namespace


def register(subparsers) -> None:
    """Add the ``calibrate`` subcommand to ``subparsers``."""
    from ..calibration.calibration_run import DEFAULTS, MAX_POSES
    from ..calibration.identification import MIN_POSES
    from ..runtime.suite import DEFAULT_NAMESPACE

    p = subparsers.add_parser(
        "calibrate",
        help="kinematic calibration on the running suite: writes a calibrated robot file",
        description="Ask the running kinematics node to calibrate the robot: plan poses inside every limit "
                    "(the predicted uncertainty is printed first), visit them, average the external tracker and "
                    "the strut readings at each, identify the hinges and strut zero offsets, and write a "
                    "calibrated robot file; start the nodes with it (--robot / robot_config) to use it.",
    )
    p.add_argument("--poses", type=int_in(MIN_POSES, MAX_POSES), default=DEFAULTS["poses"])
    p.add_argument("--settle", type=float_in(0.0, 10.0, "s"), default=DEFAULTS["settle_s"],
                   help="wait at each pose before averaging (s, robot clock)")
    p.add_argument("--window", type=float_in(0.1, 10.0, "s"), default=DEFAULTS["window_s"],
                   help="averaging window at each pose (s, robot clock)")
    p.add_argument("--reach", type=float_in(0.001, 0.1, "m"), default=DEFAULTS["reach_m"],
                   help="the poses' translation from home per axis at most (m; limits permitting)")
    p.add_argument("--tilt", type=float_in(0.0, 45.0, "deg"), default=DEFAULTS["tilt_deg"],
                   help="their rotation per axis at most (deg; limits permitting)")
    p.add_argument("--seed", type=int_in(0, 2**31 - 1), default=0, help="the pose plan's random seed")
    p.add_argument("--plan-only", action="store_true", help="plan and print the predicted uncertainty; nothing moves")
    p.add_argument("--output", default="", help="the robot file to write (relative to the kinematics node's working "
                                                "directory; default robot_calibrated_<date>_<time>.yaml there)")
    p.add_argument("--namespace", type=ros_namespace, default=DEFAULT_NAMESPACE,
                   help=f"the suite's namespace (default {DEFAULT_NAMESPACE})")
    p.add_argument("--wait", type=float_in(0.0, 600.0, "s"), default=30.0,
                   help="how long to wait for the calibrate action (wall s)")
    p.add_argument("--timeout", type=float_in(1.0, 86400.0, "s"), default=3600.0,
                   help="cancel the calibration without a result after this long (wall s)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run the calibration; the exit code (module docstring)."""
    from stewart_vibration_interfaces.action import Calibrate

    from ..nodes.calibrate_client import calibrate

    goal = Calibrate.Goal(poses=args.poses, settle_s=args.settle, window_s=args.window, reach_m=args.reach,
                          tilt_deg=args.tilt, seed=args.seed, plan_only=args.plan_only, output_path=args.output)
    quiet = args.json
    name, result = calibrate(args.namespace, goal, args.wait, args.timeout,
                             (lambda line: None) if quiet else (lambda line: print(line, flush=True)))
    if result is None and name == "NOT_READY":
        print(f"no {args.namespace}/kinematics/calibrate action within {args.wait:g} s (is the suite running, and "
              "ROS_DOMAIN_ID the suite's?)")
        return 2
    record = {"outcome": name, "message": result.outcome.message if result else ""}
    if result is not None:
        record.update(path=result.path, poses_used=result.poses_used, poses_dropped=list(result.poses_dropped),
                      residual_rms_m=result.residual_rms_m, reduced_chi2=result.reduced_chi2,
                      condition_number=result.condition_number, predicted_std_max_m=result.predicted_std_max_m,
                      parameter_std_max_m=result.parameter_std_max_m)
    if args.json:
        print(json.dumps(record))
    else:
        print(f"calibrate: {name}: {record['message']}")
        if result is not None and result.path:
            print(f"robot file: {result.path} (start the nodes with --robot {result.path})")
    if name == "CANCELED" and result is None:
        return 130
    return 0 if name == "SUCCEEDED" else 130 if name == "CANCELED" else 1
