"""``stewart-vibration paper --out DIR``: the paper's section-4 figures, corrected, with JSON and markdown."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..kinematics.robot_config import load_robot
from ..paper import paper_pose
from ..vibration.paper_study import classification_dict, clinical_case, fig7_cases, naive_comparison, paper_case
from .output import format_table, to_jsonable


def register(subparsers) -> None:
    """Add the ``paper`` subcommand to ``subparsers``."""
    cmd = subparsers.add_parser("paper", help="reproduce the paper's vibration figures (Fig. 7/8/9) corrected: "
                                              "PNG + JSON + markdown")
    cmd.add_argument("--out", required=True, help="output directory (created)")
    cmd.set_defaults(func=run)


def _decomposition_json(case: dict) -> dict:
    plan = case["plan"]
    keys = ("fft_fundamental_m", "fft_second_harmonic_m", "fft_dc_m", "predicted_second_harmonic_ratio",
            "second_order_residual_ratio", "roundtrip_angle_linear_rad", "roundtrip_angle_exact_rad",
            "roundtrip_rotation_linear_rad", "roundtrip_rotation_exact_rad")
    return {
        "amplitude_m": plan.amplitude, "frequency_hz": plan.frequency, "phase_rad": plan.phase,
        "direction_base": plan.direction, "nominal_lengths_m": plan.nominal_lengths, "gains": plan.gains,
        "leg_amplitudes_m": plan.leg_amplitudes, "leg_phases_rad": plan.leg_phases,
        "peak_exact_minus_linear_m": np.abs(case["difference"]).max(axis=0),
        "peak_predicted_second_order_m": np.abs(case["predicted_difference"]).max(axis=0),
        "peak_leg_acceleration_m_s2": plan.peak_leg_acceleration, "equations": plan.equations(),
        **{k: case[k] for k in keys},
    }


def _leg_table(case: dict) -> str:
    plan = case["plan"]
    rows = []
    for i in range(6):
        rows.append([f"{i + 1}", f"{plan.nominal_lengths[i] * 1e3:.3f}", f"{plan.gains[i]:+.6f}",
                     f"{plan.leg_amplitudes[i] * 1e6:.5g}", f"{plan.leg_phases[i]:.4f}",
                     f"{np.abs(case['difference'][:, i]).max():.4g}",
                     f"{np.abs(case['predicted_difference'][:, i]).max():.4g}",
                     f"{case['fft_second_harmonic_m'][i] / case['fft_fundamental_m'][i]:.4g}",
                     f"{case['predicted_second_harmonic_ratio'][i]:.4g}"])
    headers = ["leg", "l0 (mm)", "gain k", "amplitude (um)", "phase (rad)", "max exact-linear (m)",
               "max (1-k^2)d^2/2l (m)", "FFT 2f/f", "predicted 2f/f"]
    return _markdown(headers, rows)


def _markdown(headers, rows) -> str:
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def run(args) -> int:
    """``paper``: write the Fig. 7/8/9 PNGs, vibration_paper.json and vibration_paper.md to ``--out``.

    Returns 0. Raises ConfigError (robot file) and OSError if the output folder cannot be written.
    """
    from . import paper_figures as figs  # matplotlib only for this command

    robot = load_robot(args.robot)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    f7, paper, clinical, naive = fig7_cases(robot), paper_case(robot), clinical_case(robot), naive_comparison(robot)
    written = [
        figs.fig7(f7, out / "fig7_superposition.png"),
        figs.fig8(paper, "paper example", out / "fig8_paper_legs.png"),
        figs.fig9(paper, "paper example", out / "fig9_paper_leg1.png"),
        figs.fig8(clinical, "clinical 35 Hz, 0.3 g", out / "fig8_clinical_legs.png"),
        figs.fig9(clinical, "clinical 35 Hz, 0.3 g", out / "fig9_clinical_leg1.png"),
        figs.fig_naive(naive, out / "fig_naive_vs_jacobian.png"),
    ]
    report = {
        "pose": paper_pose(robot), "robot_config": robot.source,
        "fig7": {k: {"label": c["label"], "legs_amplitude_frequency_phase": c["legs"],
                     "exact": classification_dict(c["result"].classification_exact),
                     "linear": classification_dict(c["result"].classification_linear),
                     "fk_iterations_max": c["result"].fk_iterations, "fk_residual_m": c["result"].fk_residual}
                 for k, c in f7.items()},
        "paper_example": _decomposition_json(paper), "clinical": _decomposition_json(clinical),
        "naive_vs_jacobian": {k: {"direction_base": v["direction_base"], "naive_direction_base":
                                  v["naive_direction_base"], "length_ratio": v["length_ratio"],
                                  "angle_error_deg": float(np.degrees(v["angle_error_rad"]))}
                              for k, v in naive.items()},
        "figures": [p.name for p in written],
    }
    (out / "vibration_paper.json").write_text(json.dumps(to_jsonable(report), indent=2))
    md = ["# Vibration superposition and decomposition (paper section 4, corrected)", "",
          f"Pose: paper pose {np.array2string(paper_pose(robot), precision=5)} (m, rad). Robot: `{robot.source}`.", "",
          "## Fig. 7 equivalents: superposition (exact FK, classified)", "",
          _markdown(["case", "legs", "class", "principal direction (base)", "off-axis ratio", "amplitude (um)",
                     "rotation (mrad)"],
                    [[k, c["label"], c["result"].classification.kind,
                      np.array2string(c["result"].classification.principal_direction, precision=4),
                      f"{c['result'].classification.off_axis_ratio:.3g}",
                      f"{c['result'].classification.translation_amplitude * 1e6:.4g}",
                      f"{c['result'].classification.rotation_amplitude * 1e3:.4g}"] for k, c in f7.items()]), ""]
    for title, case in (("Fig. 8/9 equivalents: paper example (1 um, 2 rad/s, phase 2pi/3)", paper),
                        ("Clinical default (35 Hz, 0.3 g)", clinical)):
        md += [f"## {title}", "", _leg_table(case), "",
               f"Exact-minus-linear vs second-order prediction: residual {case['second_order_residual_ratio']:.3g} "
               f"of its peak. Round trip superpose(decompose(u)): direction error "
               f"{case['roundtrip_angle_linear_rad']:.3g} rad (linear), {case['roundtrip_angle_exact_rad']:.3g} rad "
               f"(exact); rotation {case['roundtrip_rotation_linear_rad']:.3g} rad (linear), "
               f"{case['roundtrip_rotation_exact_rad']:.3g} rad (exact).", ""]
    md += ["## The paper's naive superposition vs J^-1", "",
           _markdown(["direction", "length ratio naive / J^-1", "angle error (deg)"],
                     [[k, f"{v['length_ratio']:.4g}", f"{np.degrees(v['angle_error_rad']):.4g}"]
                      for k, v in naive.items()]), ""]
    (out / "vibration_paper.md").write_text("\n".join(md))
    print(format_table(["file", "kind"], [[p.name, "figure"] for p in written] +
                       [["vibration_paper.json", "data"], ["vibration_paper.md", "table"]]))
    print(f"written to {out}")
    return 0
