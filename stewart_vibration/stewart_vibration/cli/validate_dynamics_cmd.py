"""``stewart-vibration validate-dynamics``: Newton-Euler leg forces against a MuJoCo forward simulation."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InvalidInputError
from ..kinematics.robot_config import load_robot
from ..paper import PAPER_OMEGA_RAD_S
from ..sim.mjcf import load_simulation_settings
from .arguments import positive_float
from .output import format_table, print_json, to_jsonable

WORST_LEG_LIMIT = 1e-4  # acceptance: worst-leg RMS relative error
# the simulation must be the motion the forces were computed for: hinge gaps (the connect constraints) and the
# platform's deviation from the prescribed trajectory, relative to its amplitude (measured: 2e-10 m; 3e-4 and
# 3.4e-3 of the amplitude at the default 0.1 ms step)
CONSTRAINT_VIOLATION_LIMIT_M = 1e-8
TRACKING_LIMIT_RELATIVE = 0.01
MAX_STEPS = 1_000_000  # simulation steps per scenario: 100 s at the default 0.1 ms (the default runs 31,416)


def register(subparsers) -> None:
    """Add the ``validate-dynamics`` subcommand to ``subparsers``."""
    cmd = subparsers.add_parser(
        "validate-dynamics",
        help="MuJoCo forward simulation of the paper example and the clinical 35 Hz, 0.3 g case "
             "vs Newton-Euler leg forces (full model and the paper's)",
    )
    cmd.add_argument("--json", action="store_true", help="print JSON")
    cmd.add_argument("--out", metavar="DIR", help="write Fig. 11/12-like plots (PNG) and a JSON report here")
    cmd.add_argument("--paper-duration", type=positive_float, default=2 * np.pi / PAPER_OMEGA_RAD_S,
                     help="simulated time of the paper example, s (default: one period, pi s)")
    cmd.add_argument("--clinical-duration", type=positive_float, default=0.1,
                     help="simulated time of the clinical case, s (default 0.1 = 3.5 periods)")
    cmd.add_argument("--timestep", type=positive_float, help="override config/simulation.yaml timestep_s (s)")
    cmd.set_defaults(func=run)


def _scenario_report(res, elapsed: float) -> dict:
    """One scenario's figures and its verdict: passed only if every figure judged is within its limit."""
    out = {
        "description": res.description,
        "samples": len(res.run.time),
        "duration_s": float(res.run.time[-1] + (res.run.time[1] - res.run.time[0])),
        "wall_time_s": elapsed,
        "full_model": {"rms_relative_per_leg": res.full.rms_relative, "overall_rms_relative": res.full.overall,
                       "worst_leg_rms_relative": res.full.worst, "max_relative": res.full.max_relative},
        "paper_model": {"rms_relative_per_leg": res.paper.rms_relative, "overall_rms_relative": res.paper.overall,
                        "worst_leg_rms_relative": res.paper.worst, "max_relative": res.paper.max_relative},
        "constraint_violation_max_m": float(res.run.violation.max()),
        "tracking_error_max_m": res.tracking_error,
        "force_rms_n": np.sqrt((res.run.forces ** 2).mean(axis=0)),
        "force_peak_to_peak_n": np.ptp(res.run.forces, axis=0),
        "tracking_error_relative": res.tracking_error / res.amplitude,
        "checks": {
            "worst_leg_rms_relative": bool(res.full.worst <= WORST_LEG_LIMIT),
            "constraint_violation": bool(res.run.violation.max() <= CONSTRAINT_VIOLATION_LIMIT_M),
            "tracking_error": bool(res.tracking_error <= TRACKING_LIMIT_RELATIVE * res.amplitude),
        },
    }
    out["passed"] = all(out["checks"].values())
    return out


def run(args) -> int:
    """``validate-dynamics``: MuJoCo-simulate both scenarios and compare the Newton-Euler leg forces (N).

    Prints (or writes with --out) the per-leg RMS relative errors, constraint violation (m) and
    tracking error. Returns 0 if every check passes, else 1. Raises InvalidInputError if a duration is
    shorter than 10 simulation steps, ConfigError (robot or simulation file).
    """
    # MuJoCo only here: every other subcommand (the report of an hour's run among them) is spared its memory
    from ..dynamics.mujoco_validation import run_scenario
    from ..sim.mujoco_sim import StewartSim

    robot = load_robot(args.robot)
    overrides = {} if args.timestep is None else {"timestep": args.timestep}
    settings = load_simulation_settings(**overrides)
    for flag, duration in (("--paper-duration", args.paper_duration), ("--clinical-duration", args.clinical_duration)):
        if duration < 10 * settings.timestep:
            raise InvalidInputError(f"{flag} {duration:g} s is shorter than 10 simulation steps "
                                    f"({10 * settings.timestep:g} s at timestep {settings.timestep:g} s)")
        if duration > MAX_STEPS * settings.timestep:
            raise InvalidInputError(f"{flag} {duration:g} s is more than {MAX_STEPS:,} simulation steps "
                                    f"({MAX_STEPS * settings.timestep:g} s at timestep {settings.timestep:g} s)")
    out = Path(args.out) if args.out else None
    if out is not None:  # before the simulations: an unusable folder fails in one line, not after them
        out.mkdir(parents=True, exist_ok=True)
    sim = StewartSim(robot, settings)
    report: dict[str, Any] = {
        "what": "MuJoCo forward simulation (generated 6-UPS model, U-joints, computed-force strut drive) "
                "of the prescribed vibration; Newton-Euler forces evaluated on the simulated platform motion "
                "and compared with the forces MuJoCo applied. Error = RMS(difference) / RMS(force).",
        "settings": {"timestep_s": settings.timestep, "integrator": settings.integrator,
                     "solref": settings.solref, "solimp": settings.solimp, "armature": settings.armature},
        "limit_worst_leg_rms_relative": WORST_LEG_LIMIT,
        "limit_constraint_violation_m": CONSTRAINT_VIOLATION_LIMIT_M,
        "limit_tracking_error_relative": TRACKING_LIMIT_RELATIVE,
        "scenarios": {},
    }
    results = {}
    for name, duration in (("paper", args.paper_duration), ("clinical", args.clinical_duration)):
        start = time.perf_counter()
        results[name] = run_scenario(robot, name, duration, sim=sim)
        report["scenarios"][name] = _scenario_report(results[name], time.perf_counter() - start)
    if out is not None:
        from . import dynamics_figures as figs  # matplotlib only when plotting

        files = []
        for name, res in results.items():
            files.append(str(figs.forces_figure(res, out / f"{name}_forces.png")))
            files.append(str(figs.legs_figure(res, out / f"{name}_legs.png")))
        report["figures"] = files
        (out / "validate_dynamics.json").write_text(json.dumps(to_jsonable(report), indent=2))
    ok = all(s["passed"] for s in report["scenarios"].values())
    if args.json:
        print_json(report)
        return 0 if ok else 1
    for name, rep in report["scenarios"].items():
        print(f"[{name}] {rep['description']}: {rep['samples']} steps, {rep['wall_time_s']:.1f} s wall")
        rows = [[f"leg_{i + 1}", rep["force_rms_n"][i], rep["full_model"]["rms_relative_per_leg"][i],
                 rep["paper_model"]["rms_relative_per_leg"][i]] for i in range(6)]
        print(format_table(["leg", "force_rms_N", "full_rms_rel_err", "paper_rms_rel_err"], rows, "{:.3e}"))
        print(f"  full model: overall {rep['full_model']['overall_rms_relative']:.3e}, worst leg "
              f"{rep['full_model']['worst_leg_rms_relative']:.3e}, max {rep['full_model']['max_relative']:.3e} "
              f"(limit {WORST_LEG_LIMIT:g}: {'PASS' if rep['checks']['worst_leg_rms_relative'] else 'FAIL'})")
        print(f"  paper model: overall {rep['paper_model']['overall_rms_relative']:.3e}, worst leg "
              f"{rep['paper_model']['worst_leg_rms_relative']:.3e}")
        checks = rep["checks"]
        print(f"  constraint violation max {rep['constraint_violation_max_m']:.2e} m (limit "
              f"{CONSTRAINT_VIOLATION_LIMIT_M:g} m: {'PASS' if checks['constraint_violation'] else 'FAIL'}), "
              f"tracking error max {rep['tracking_error_max_m']:.2e} m = {rep['tracking_error_relative']:.2e} of "
              f"the amplitude (limit {TRACKING_LIMIT_RELATIVE:g}: {'PASS' if checks['tracking_error'] else 'FAIL'})")
    if args.out:
        print("wrote " + ", ".join(report["figures"]) + f", {Path(args.out) / 'validate_dynamics.json'}")
    return 0 if ok else 1
