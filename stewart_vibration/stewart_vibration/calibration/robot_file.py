"""The calibrated robot file: the drawing's robot.yaml with the identified hinge corrections and strut zero
offsets, and the calibration's provenance (the same schema; every node loads it through ``robot_config``)."""

from __future__ import annotations

import datetime

import numpy as np
import yaml

from ..kinematics.robot_config import robot_from_config
from ..robot import drawing_tree
from .geometry_parameters import parameter_names, split_parameters
from .identification import CalibrationResult

HEADER = """\
# A calibrated robot file: config/robot.yaml (the drawing) with the hinge corrections and strut zero offsets a
# kinematic calibration identified from tracker poses (geometry.*.hinge_corrections_m, geometry.strut_zero_offsets_m),
# the payload and load cell offsets identified from the cells at rest (inertia.payload_identified,
# load_cells.offsets_n) and its provenance (calibration). Load it wherever robot.yaml is loaded (robot_config
# parameter, --robot).
# Written by the calibration; edit the drawing, not this file.
"""


def calibrated_tree(tree: dict, result: CalibrationResult, provenance: dict, load: dict | None = None) -> dict:
    """The robot file tree of ``result`` on the drawing ``tree`` (a parsed robot.yaml, calibrated or not):
    corrections = identified - drawn; ``provenance`` (plain values) goes into ``calibration`` with the fit's
    figures; ``load`` (``payload_identification.payload_tree``, or None) gives the identified payload, the load
    cells' offsets and the payload's figures (``calibration.payload``)."""
    drawing = robot_from_config(drawing_tree(tree), "the drawing")
    base, platform, offsets = split_parameters(result.theta)
    out = drawing_tree(tree)

    def rows(values: np.ndarray) -> list:
        return [[float(f"{v:.9f}") for v in row] for row in values]

    out["geometry"]["base"]["hinge_corrections_m"] = rows(base - drawing.base_hinges)
    out["geometry"]["platform"]["hinge_corrections_m"] = rows(platform - drawing.platform_hinges)
    out["geometry"]["strut_zero_offsets_m"] = [float(f"{v:.9f}") for v in offsets]
    used = result.used
    out["calibration"] = {
        **provenance,
        "written": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "poses": int(used.size),
        "poses_used": int(used.sum()),
        "poses_dropped": [{"pose": d.index + 1, "chi2": round(d.chi2, 3),
                           "residual_rms_m": float(f"{d.residual_rms_m:.3g}")} for d in result.dropped],
        "residual_rms_m": float(f"{np.sqrt(np.mean(result.residual_rms_m[used] ** 2)):.3g}"),
        "reduced_chi2": round(result.reduced_chi2, 4),
        "condition_number": round(result.condition_number, 2),
        "parameter_std_m": {name: float(f"{s:.3g}") for name, s in zip(parameter_names(), result.std)},
    }
    if load is not None:
        out["inertia"]["payload_identified"] = load["payload_identified"]
        out["load_cells"] = load["load_cells"]
        out["calibration"]["payload"] = load["provenance"]
    return out


def dump_robot_file(tree: dict) -> str:
    """The YAML text of a calibrated robot file tree, with its header."""
    return HEADER + yaml.safe_dump(tree, sort_keys=False, default_flow_style=None, width=110)
