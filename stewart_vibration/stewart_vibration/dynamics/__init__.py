"""Dynamics of the 6-UPS platform (pure numpy; ``mujoco_validation`` also needs MuJoCo).

- ``newton_euler``: axial leg forces by Newton-Euler with the full leg model (docs/dynamics.md), and
  the paper's simplified model (eqs 12-20) for comparison;
- ``platform_trajectory``: analytic platform trajectories (pose, twist, acceleration), Euler-rate
  conversion;
- ``tissue``: the soft-tissue load on the platform (a visco-elastic wrench); ``tissue_config`` reads its
  YAML file, ``tissue_bounds`` bounds its worst-case wrench near the rest pose;
- ``mujoco_validation``: Newton-Euler against a MuJoCo forward simulation (Figs. 11, 12), imported on
  its own (it loads MuJoCo).
"""

from .newton_euler import Friction, LegForceResult, leg_forces, leg_forces_paper
from .platform_trajectory import SinusoidalTrajectory, twist_from_euler_rates, vibration_trajectory

__all__ = [
    "Friction",
    "LegForceResult",
    "SinusoidalTrajectory",
    "leg_forces",
    "leg_forces_paper",
    "twist_from_euler_rates",
    "vibration_trajectory",
]
