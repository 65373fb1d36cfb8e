"""Generate the MuJoCo model (MJCF) of the 6-UPS robot from the robot config (pure python).

Structure (names are the public contract used by the simulator and the
hardware emulator):
- world: fixed base; gravity from robot.yaml; contacts disabled.
- per leg i = 1..6: body ``cylinder_i`` at B_i with a universal joint
  (hinges ``u1_i``, ``u2_i``, both normal to the home leg axis) or, with
  ``base_joint="ball"``, a ball joint ``ball_i``; child body ``piston_i`` on
  the slide joint ``leg_i`` along the leg. The slide's position IS the strut
  length (m, hinge centre to hinge centre, ``ref`` = home length). Actuator
  ``leg_i``: a ``general`` actuator with force = ctrl + b1 q + b2 q_dot (gear 1,
  N, positive extends); the model has b1 = b2 = 0, i.e. a pure force motor
  (ctrl = axial force); the hardware emulator's servo drive sets b1 = -kp,
  b2 = -kv at run time (``emulation.servo_drive``). Sensor ``force_leg_i``
  (actuatorfrc) reads the applied force.
- body ``platform`` (platform + payload, one rigid body, platform frame) on a
  free joint ``platform``.
- equality ``connect`` between site ``tip_i`` (on the piston, at A_i) and
  site ``a_i`` (on the platform): the spherical joint at A_i.
Every body's frame has its z axis along the home leg axis (legs) or is the
platform frame; the model is assembled at the home pose by IK, so all
constraints hold at qpos0. Leg masses follow ``Robot.leg_bodies`` (vibration
unit lumped into the piston), the same as the Newton-Euler model.

With ``units`` (a ``UnitSliders``, the emulated robot as built) each vibration unit is a body of its own:
body ``unit_i`` inside ``piston_i`` at the piston's tip, on the slide joint ``vib_i`` along the leg (its
position is the unit's displacement, m, 0 at rest; a flexure spring of the unit's stiffness towards 0),
holding site ``tip_i``; the piston then carries its own mass only, the slider the unit's moving mass, and
actuator ``vib_i`` (a pure force motor like ``leg_i``) is the unit's coil. The hinge-to-hinge length is
then leg_i + vib_i.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from ..config_values import Plausible, as_choice, as_number, check_keys
from ..errors import ConfigError
from ..install import default_config_dir
from ..kinematics import leg_vectors
from ..kinematics.rotations import quaternion_from_rpy
from ..robot import LEG_NAMES, VIB_NAMES, Robot
from ..safe_yaml import load_yaml, short_repr

BASE_JOINTS = ("universal", "ball")
SLIDER_INERTIA = 1e-7  # kg m^2, a slider's own rotational inertia (it turns with its leg; a token value)


@dataclass(frozen=True)
class UnitSliders:
    """The vibration units as bodies: each slider's moving mass (kg) and flexure stiffness (6,) (N/m)."""

    mass_kg: float
    stiffness_n_m: tuple


@dataclass(frozen=True)
class SimulationSettings:
    """Numerical settings of the generated model (see config/simulation.yaml for the reasons)."""

    timestep: float = 1.0e-4
    integrator: str = "RK4"
    solref_timeconst_factor: float = 2.0
    solref_dampratio: float = 1.0
    solimp: tuple = (0.9999, 0.9999, 0.001, 0.5, 2.0)
    armature: float = 0.0
    solver: str = "Newton"
    solver_iterations: int = 50
    solver_tolerance: float = 1.0e-12
    drive_bandwidth_hz: float = 50.0
    drive_damping_ratio: float = 1.0
    emulator_integrator: str = "Euler"
    servo_bandwidth_hz: float = 10.0

    @property
    def solref(self) -> tuple[float, float]:
        """(time constant s, damping ratio) of the equality constraints."""
        return (self.solref_timeconst_factor * self.timestep, self.solref_dampratio)


_YAML_KEYS = {
    "timestep_s": "timestep", "integrator": "integrator",
    "solref_timeconst_factor": "solref_timeconst_factor", "solref_dampratio": "solref_dampratio",
    "solimp": "solimp", "armature": "armature", "solver": "solver",
    "solver_iterations": "solver_iterations", "solver_tolerance": "solver_tolerance",
    "drive_bandwidth_hz": "drive_bandwidth_hz", "drive_damping_ratio": "drive_damping_ratio",
    "emulator_integrator": "emulator_integrator", "servo_bandwidth_hz": "servo_bandwidth_hz",
}


INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")  # MuJoCo's
SOLVERS = ("Newton", "CG", "PGS")
# Plausible ranges of the numeric settings (by YAML key; SI): what MuJoCo accepts and the drives stay
# stable with, far around the values config/simulation.yaml gives and explains.
_PLAUSIBLE = {
    "timestep_s": Plausible(1e-6, 0.01, "s"),
    "solref_timeconst_factor": Plausible(1.0, 1000.0),
    "solref_dampratio": Plausible(0.0, 10.0, low_open=True),
    "armature": Plausible(0.0, 10.0, "kg or kg m^2"),
    "solver_iterations": Plausible(1, 10_000),
    "solver_tolerance": Plausible(0.0, 1e-2),
    "drive_bandwidth_hz": Plausible(0.0, 1000.0, "Hz", low_open=True),
    "drive_damping_ratio": Plausible(0.0, 10.0, low_open=True),
    "servo_bandwidth_hz": Plausible(0.0, 1000.0, "Hz", low_open=True),
}
# solimp [dmin, dmax, width m, midpoint, power]: MuJoCo's impedance lies in [1e-4, 0.9999]
_SOLIMP = (Plausible(1e-4, 0.9999), Plausible(1e-4, 0.9999), Plausible(0.0, 1.0, "m", low_open=True),
           Plausible(0.0, 1.0, low_open=True), Plausible(1.0, 100.0))


def _checked_settings(values: dict, where: str) -> SimulationSettings:
    """SimulationSettings from ``values`` (by field name), each value checked: one ConfigError naming its key."""
    field_key = {field: key for key, field in _YAML_KEYS.items()}
    checked: dict[str, Any] = {}
    for name, value in values.items():
        key = field_key[name]
        if name in ("integrator", "emulator_integrator"):
            checked[name] = as_choice(value, key, where, INTEGRATORS)
        elif name == "solver":
            checked[name] = as_choice(value, key, where, SOLVERS)
        elif name == "solimp":
            if not isinstance(value, (list, tuple)) or len(value) != len(_SOLIMP):
                raise ConfigError(f"{where}: 'solimp' must be a list of 5 numbers [dmin, dmax, width, midpoint, "
                                  f"power], got {short_repr(value)}")
            checked[name] = tuple(as_number(v, f"solimp[{i}]", where, _SOLIMP[i]) for i, v in enumerate(value))
        elif name == "solver_iterations":
            checked[name] = int(as_number(value, key, where, _PLAUSIBLE[key], integer=True))
        else:
            checked[name] = as_number(value, key, where, _PLAUSIBLE[key])
    return SimulationSettings(**checked)


def load_simulation_settings(path=None, **overrides) -> SimulationSettings:
    """Settings from config/simulation.yaml (or ``path``), then keyword overrides, every value checked.

    Args:
        path: the YAML file; None = simulation.yaml in ``default_config_dir()``.
        **overrides: SimulationSettings fields to set after the file's values (e.g. timestep from a physics
            rate), checked like the file's.

    Returns:
        The SimulationSettings.

    Raises:
        ConfigError: one line naming the file and the key: the file cannot be read safely
            (``safe_yaml.load_yaml``), has unknown keys, a mistyped value, an integrator or solver MuJoCo
            does not have, or a number outside its plausible range; or (``path`` None) no config directory.
        TypeError: an override is not a SimulationSettings field.
    """
    path = Path(path).expanduser() if path is not None else default_config_dir() / "simulation.yaml"
    where = f"simulation config {path}"
    tree = load_yaml(path, "simulation config")
    check_keys(tree, _YAML_KEYS, where)
    unknown = set(overrides) - set(_YAML_KEYS.values())
    if unknown:
        raise TypeError(f"load_simulation_settings: unknown settings {sorted(unknown)}")
    defaults = SimulationSettings()
    values: dict[str, Any] = {field.name: getattr(defaults, field.name) for field in fields(SimulationSettings)}
    values.update({_YAML_KEYS[k]: v for k, v in tree.items()})
    values.update(overrides)
    return _checked_settings(values, where + (f" (with {', '.join(sorted(overrides))} set)" if overrides else ""))


def leg_frame(axis: np.ndarray) -> np.ndarray:
    """Rotation (3, 3) whose z column is the unit leg ``axis`` and x column is horizontal.

    Args:
        axis: unit leg axis (3,) (base frame).

    Returns:
        [x, axis x x, axis] as columns (3, 3), x = e_z x axis normalised (e_x when the axis is vertical).
    """
    x = np.cross([0.0, 0.0, 1.0], axis)
    if np.linalg.norm(x) < 1e-9:
        x = np.array([1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(axis, x), axis], axis=1)


def quat_wxyz_from_matrix(rot: np.ndarray) -> np.ndarray:
    """MuJoCo quaternion [w, x, y, z] of a rotation matrix (3, 3).

    Args:
        rot: rotation matrix (3, 3).

    Returns:
        Unit quaternion (4,) in MuJoCo order [w, x, y, z].
    """
    import mujoco

    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rot).reshape(9))
    return quat


def _f(values) -> str:
    return " ".join(f"{float(v):.17g}" for v in np.atleast_1d(values))


def build_mjcf(robot: Robot, settings: SimulationSettings | None = None, base_joint: str = "universal",
               units: UnitSliders | None = None) -> str:
    """MJCF XML string of the robot at its home pose (see module docstring).

    Args:
        robot: the robot.
        settings: numerical settings; None = SimulationSettings() defaults.
        base_joint: "universal" (the real robot) or "ball" (exact static check).
        units: the vibration units as slider bodies; None = lumped into the pistons.

    Returns:
        The MJCF document (str).

    Raises:
        ConfigError: ``base_joint`` is neither "universal" nor "ball".
    """
    if base_joint not in BASE_JOINTS:
        raise ConfigError(f"base_joint must be one of {BASE_JOINTS}, got {base_joint!r}")
    s = settings or SimulationSettings()
    p = robot.leg_bodies
    piston_mass = p.piston_mass if units is None else robot.leg.piston_mass
    cyl_com, pis_com = p.cylinder_com_offset, p.piston_com_offset
    cyl_inertia = _f([p.cylinder_inertia_transverse, p.cylinder_inertia_transverse, p.cylinder_inertia_axial])
    pis_inertia = _f([p.piston_inertia_transverse, p.piston_inertia_transverse, p.piston_inertia_axial])
    home = robot.home_pose
    d = leg_vectors(robot, home)
    lengths = np.linalg.norm(d, axis=1)
    body = robot.moving_body
    inertia = body.inertia
    full = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    xyzw = quaternion_from_rpy(home[3:])
    lines = [
        '<mujoco model="stewart_vibration_6ups">',
        '  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>',
        f'  <option timestep="{s.timestep:.17g}" integrator="{s.integrator}" gravity="{_f(robot.gravity)}"',
        f'          solver="{s.solver}" iterations="{s.solver_iterations}" tolerance="{s.solver_tolerance:.17g}"',
        '          jacobian="dense">',
        '    <flag contact="disable"/>',
        '  </option>',
        '  <default>',
        f'    <joint armature="{s.armature:.17g}" damping="0"/>',
        f'    <equality solref="{_f(s.solref)}" solimp="{_f(s.solimp)}"/>',
        '    <geom contype="0" conaffinity="0" group="1"/>',
        '  </default>',
        '  <worldbody>',
        '    <geom name="base" type="cylinder" size="0.11 0.003" rgba="0.5 0.5 0.5 1"/>',
    ]
    for i in range(6):
        n = i + 1
        axis = d[i] / lengths[i]
        frame = leg_frame(axis)
        lines.append(f'    <body name="cylinder_{n}" pos="{_f(robot.base_hinges[i])}" '
                     f'quat="{_f(quat_wxyz_from_matrix(frame))}">')
        if base_joint == "universal":
            lines.append(f'      <joint name="u1_{n}" type="hinge" axis="1 0 0"/>')
            lines.append(f'      <joint name="u2_{n}" type="hinge" axis="0 1 0"/>')
        else:
            lines.append(f'      <joint name="ball_{n}" type="ball"/>')
        lines += [
            f'      <inertial pos="0 0 {cyl_com:.17g}" mass="{p.cylinder_mass:.17g}" diaginertia="{cyl_inertia}"/>',
            f'      <geom type="capsule" fromto="0 0 0 0 0 {2 * cyl_com:.17g}" size="0.010" rgba="0.3 0.4 0.8 1"/>',
            f'      <body name="piston_{n}" pos="0 0 {lengths[i]:.17g}">',
            f'        <joint name="{LEG_NAMES[i]}" type="slide" axis="0 0 1" ref="{lengths[i]:.17g}"/>',
            f'        <inertial pos="0 0 {-pis_com:.17g}" mass="{piston_mass:.17g}" diaginertia="{pis_inertia}"/>',
            f'        <geom type="capsule" fromto="0 0 {-2 * pis_com:.17g} 0 0 0" size="0.006" rgba="0.8 0.8 0.8 1"/>',
        ]
        if units is None:
            lines.append(f'        <site name="tip_{n}" pos="0 0 0" size="0.004"/>')
        else:
            lines += [
                f'        <body name="unit_{n}">',
                f'          <joint name="{VIB_NAMES[i]}" type="slide" axis="0 0 1" '
                f'stiffness="{float(units.stiffness_n_m[i]):.17g}" springref="0"/>',
                f'          <inertial pos="0 0 0" mass="{units.mass_kg:.17g}" '
                f'diaginertia="{_f([SLIDER_INERTIA] * 3)}"/>',
                f'          <site name="tip_{n}" pos="0 0 0" size="0.004"/>',
                '        </body>',
            ]
        lines += ['      </body>', '    </body>']
    lines += [
        f'    <body name="platform" pos="{_f(home[:3])}" quat="{_f([xyzw[3], xyzw[0], xyzw[1], xyzw[2]])}">',
        '      <freejoint name="platform"/>',
        f'      <inertial pos="{_f(body.com)}" mass="{body.mass:.17g}" fullinertia="{_f(full)}"/>',
        '      <geom type="cylinder" size="0.105 0.003" rgba="0.8 0.5 0.3 0.6"/>',
    ]
    lines += [f'      <site name="a_{i + 1}" pos="{_f(robot.platform_hinges[i])}" size="0.004"/>' for i in range(6)]
    lines += ['    </body>', '  </worldbody>', '  <equality>']
    lines += [f'    <connect name="hinge_{i + 1}" site1="tip_{i + 1}" site2="a_{i + 1}"/>' for i in range(6)]
    lines += ['  </equality>', '  <actuator>']
    motors = LEG_NAMES + (VIB_NAMES if units is not None else ())
    lines += [f'    <general name="{name}" joint="{name}" gear="1" gainprm="1" biastype="affine" '
              'biasprm="0 0 0"/>' for name in motors]
    lines += ['  </actuator>', '  <sensor>']
    lines += [f'    <actuatorfrc name="force_{name}" actuator="{name}"/>' for name in LEG_NAMES]
    lines += ['  </sensor>', '</mujoco>']
    return "\n".join(lines) + "\n"


def build_model(robot: Robot, settings: SimulationSettings | None = None, base_joint: str = "universal",
                units: UnitSliders | None = None):
    """Compiled mujoco.MjModel of ``build_mjcf``.

    Args:
        robot: the robot.
        settings: numerical settings; None = SimulationSettings() defaults.
        base_joint: "universal" or "ball".
        units: the vibration units as slider bodies; None = lumped into the pistons.

    Returns:
        The mujoco.MjModel.

    Raises:
        ConfigError: ``base_joint`` is neither "universal" nor "ball".
        ValueError: MuJoCo cannot compile the generated XML.
    """
    import mujoco

    return mujoco.MjModel.from_xml_string(build_mjcf(robot, settings, base_joint, units))
