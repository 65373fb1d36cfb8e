"""Every config is checked for physical plausibility with one error naming the key: the shipped files pass,
and each implausible value of robot.yaml, a tissue file, simulation.yaml, a scenario and the planner's
settings is refused with its key named. The tissue's wrench bound is checked against the model itself
(sampled states) and against the emulator, which must stay finite with the steepest tissue it accepts."""

from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from stewart_vibration import inverse_kinematics, load_robot
from stewart_vibration.dynamics.tissue import TissueModel, tissue_wrench
from stewart_vibration.dynamics.tissue_bounds import (
    CHECK_ROTATION_RAD,
    CHECK_TRANSLATION_M,
    WRENCH_FACTOR,
    check_tissue_wrench,
    tissue_wrench_bound,
)
from stewart_vibration.dynamics.tissue_config import load_tissue, tissue_from_dict
from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.errors import ConfigError
from stewart_vibration.kinematics.rotations import rpy_from_rotation, so3_exp
from stewart_vibration.motion.profiles import minimum_jerk, minimum_jerk_duration
from stewart_vibration.robot import LEG_NAMES
from stewart_vibration.runtime.scenario import load_scenario
from stewart_vibration.sim.mjcf import load_simulation_settings
from stewart_vibration.vibration.settings import default_settings, plan_vibration, settings_reason

CONFIG = Path(__file__).resolve().parents[1] / "stewart_vibration" / "config"
STATE_RATE_HZ = yaml.safe_load((CONFIG / "suite_params.yaml").read_text())["/**/hardware_emulator"][
    "ros__parameters"]["state_rate_hz"]


def tree_of(name: str) -> dict:
    return yaml.safe_load((CONFIG / name).read_text())


def with_value(tree: dict, dotted: str, value) -> dict:
    changed = copy.deepcopy(tree)
    node = changed
    *parents, last = dotted.split(".")
    for key in parents:
        node = node[key]
    node[last] = value
    return changed


def write(tmp_path, tree, name="config.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(tree))
    return path


def refused(call, *args) -> str:
    with pytest.raises(ConfigError) as caught:
        call(*args)
    assert "\n" not in str(caught.value)
    return str(caught.value)


# -- robot.yaml ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("key", "value", "words"), [
    ("vibration_unit.amplitude_max_m", 1000.0, "'vibration_unit.amplitude_max_m' = 1000 is outside"),  # 1 km
    ("gravity_m_s2", [0.0, 0.0, -1e300], "'gravity_m_s2[2]' = -1e+300 is outside"),
    ("gravity_m_s2", [15.0, 15.0, -15.0], "'gravity_m_s2' has magnitude 25.98"),
    ("limits.stroke_max_m", 1000.0, "'limits.stroke_max_m' = 1000 is outside its plausible range [0.01, 2] m"),
    ("limits.stroke_min_m", 0.001, "'limits.stroke_min_m' = 0.001 is outside"),
    ("limits.stroke_min_m", 0.245, "the stroke 'limits.stroke_max_m' - 'limits.stroke_min_m' = 0.005 m"),
    ("limits.stroke_min_m", 0.3, "'limits.stroke_min_m' 0.3 must be < 'limits.stroke_max_m' 0.25"),
    ("limits.strut_velocity_max_m_s", 0.0, "'limits.strut_velocity_max_m_s' = 0 is outside its plausible range (0"),
    ("limits.strut_velocity_max_m_s", "fast", "'limits.strut_velocity_max_m_s' must be a number, got 'fast'"),
    ("limits.strut_velocity_max_m_s", float("inf"), "'limits.strut_velocity_max_m_s' must be finite"),
    ("limits.strut_acceleration_max_m_s2", True, "'limits.strut_acceleration_max_m_s2' must be a number, got True"),
    ("limits.strut_force_max_n", 1e9, "'limits.strut_force_max_n' = 1e+09 is outside"),
    ("limits.universal_joint_max_deg", 120.0, "'limits.universal_joint_max_deg' = 120 is outside"),
    ("inertia.platform.mass_kg", 0.0, "'inertia.platform.mass_kg' = 0 is outside"),
    ("inertia.piston.mass_kg", -0.1, "'inertia.piston.mass_kg' = -0.1 is outside"),
    ("inertia.payload.inertia_kg_m2", [1.0, 1.0, 5.0], "'inertia.payload.inertia_kg_m2' [1.0, 1.0, 5.0] is not a body"),
    ("inertia.payload.com_m", [0.0, 0.0], "'inertia.payload.com_m' must be a list of 3 numbers"),
    ("geometry.base.radius_m", 1e-4, "'geometry.base.radius_m' = 0.0001 is outside"),
    ("geometry.platform", "round", "'geometry.platform' must be a mapping"),
    ("vibration_unit.frequency_min_hz", 200.0, "'vibration_unit.frequency_min_hz' 200 must be <"),
    # the home pose must be one the robot can take: strokes, joints and conditioning (kinematics.check_pose)
    ("geometry.home_pose", [0.0, 0.0, 0.5, 0.0, 0.0, 0.0], "'geometry.home_pose' [0.0, 0.0, 0.5, 0.0, 0.0, 0.0] "
                                                           "cannot be taken by this robot: StrokeLimitError"),
    ("limits.universal_joint_max_deg", 20.0, "'geometry.home_pose' [0.0, 0.0, 0.16, 0.0, 0.0, 0.0] cannot be taken "
                                             "by this robot: JointLimitError"),
    ("limits.condition_number_max", 3.0, "cannot be taken by this robot: SingularPoseError"),
])
def test_an_implausible_robot_value_is_refused_naming_its_key(tmp_path, key, value, words):
    path = write(tmp_path, with_value(tree_of("robot.yaml"), key, value))
    text = refused(load_robot, path)
    assert text.startswith(f"robot config {path}: ") and words in text, text


def test_the_shipped_robot_and_a_plausible_variant_load(tmp_path):
    robot = load_robot()
    assert robot.limits.stroke_max == 0.25 and robot.vibration_unit.amplitude_max == 1e-4
    variant = with_value(tree_of("robot.yaml"), "limits.stroke_max_m", 0.2)
    variant["vibration_unit"]["amplitude_max_m"] = "5e-4"  # PyYAML reads 5e-4 (no dot) as text: still a number
    loaded = load_robot(write(tmp_path, variant))
    assert loaded.limits.stroke_max == 0.2 and loaded.vibration_unit.amplitude_max == 5e-4


# -- tissue files -------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("key", "value", "words"), [
    ("stiffening", {"type": "exponential", "length_m": 1e-6}, "'stiffening.length_m' = 1e-06 is outside"),
    ("axial", {"stiffness_n_m": 1e9, "damping_n_s_m": 150.0}, "'axial.stiffness_n_m' = 1e+09 is outside"),
    ("lateral", {"stiffness_n_m": 3000.0, "damping_n_s_m": "x"}, "'lateral.damping_n_s_m' must be a number"),
    ("bending", {"stiffness_nm_rad": float("nan"), "damping_nm_s_rad": 0.05}, "'bending.stiffness_nm_rad' must be "
                                                                              "finite"),
    ("torsional", [3.0, 0.03], "'torsional' needs stiffness_nm_rad and damping_nm_s_rad"),
    ("preload_n", -1.0, "'preload_n' = -1 is outside"),
    ("center_m", [0.0, 0.0, 5.0], "'center_m[2]' = 5 is outside"),
    ("rest_pose", [0.0, 0.0, 0.5, 0.0, 0.0, 0.0], "'rest_pose' [0.0, 0.0, 0.5, 0.0, 0.0, 0.0] cannot be taken by "
                                                  "the robot: StrokeLimitError"),
    ("rest_pose", "upright", "'rest_pose' needs home, paper or 6 numbers"),
    ("name", ["a"], "'name' must be text"),
    ("friction", 1.0, "unknown keys ['friction']"),
    # within the reduction workspace the wrench must stay below 10x what the six struts hold
    ("axial", {"stiffness_n_m": 9e5, "damping_n_s_m": 150.0}, "the tissue's force reaches"),
    ("stiffening", {"type": "exponential", "length_m": 0.002}, "the tissue's force reaches"),
    ("bending", {"stiffness_nm_rad": 1e4, "damping_nm_s_rad": 0.05}, "the tissue's moment reaches"),
])
def test_an_implausible_tissue_value_is_refused_naming_its_key(robot, tmp_path, key, value, words):
    path = write(tmp_path, with_value(tree_of("tissue.yaml"), key, value), "tissue.yaml")
    text = refused(load_tissue, path, robot)
    assert text.startswith(f"tissue config {path}: ") and words in text, text


def region_states(model: TissueModel, rng, n: int, speed: float, angular: float):
    """Platform poses [n, 6] and twists [n, 6] whose tissue centre is displaced by at most CHECK_TRANSLATION_M
    and rotated by at most CHECK_ROTATION_RAD along / about each tissue axis from rest, the centre moving at
    most ``speed`` and the platform turning at most ``angular`` per axis: the region the bound is for. Every
    eighth state is a corner."""
    u = rng.uniform(-1, 1, (n, 3))
    theta, vc, wt = rng.uniform(-1, 1, (n, 3)), rng.uniform(-1, 1, (n, 3)), rng.uniform(-1, 1, (n, 3))
    for a in (u, theta, vc, wt):
        a[::8] = np.sign(a[::8])
    u, theta, vc, wt = u * CHECK_TRANSLATION_M, theta * CHECK_ROTATION_RAD, vc * speed, wt * angular
    rest = model.rest_rotation
    rot = rest @ so3_exp(theta)
    arm = rot @ model.center
    position = model.rest_center + u @ rest.T - arm
    omega = wt @ rest.T
    velocity = vc @ rest.T - np.cross(omega, arm)
    return np.c_[position, rpy_from_rotation(rot)], np.c_[velocity, omega]


@pytest.mark.parametrize("variant", ["shipped", "piecewise", "offset centre"])
def test_the_wrench_bound_holds_for_the_model_itself(robot, variant):
    tree = tree_of("tissue.yaml")
    if variant == "piecewise":
        tree["stiffening"] = {"type": "piecewise_linear", "breakpoints_m": [0.0, 0.003, 0.006],
                              "stiffness_n_m": [12000.0, 24000.0, 48000.0]}
    if variant == "offset centre":
        tree["center_m"], tree["rest_pose"] = [0.01, -0.02, -0.08], "paper"
    model = tissue_from_dict(tree, robot)
    speed = robot.limits.strut_velocity_max + robot.vibration_unit.velocity_max
    angular = speed / robot.characteristic_length
    bound = tissue_wrench_bound(model, CHECK_TRANSLATION_M, CHECK_ROTATION_RAD, speed, angular)
    assert bound == check_tissue_wrench(model, robot, "x")
    pose, twist = region_states(model, np.random.default_rng(7), 20_000, speed, angular)
    wrench = tissue_wrench(model, pose, twist)
    force, moment = np.linalg.norm(wrench[:, :3], axis=1), np.linalg.norm(wrench[:, 3:], axis=1)
    assert np.isfinite(wrench).all()
    assert force.max() <= bound.force_n * (1 + 1e-12) and moment.max() <= bound.moment_nm * (1 + 1e-12)
    assert force.max() > 0.9 * bound.force_n  # the corners reach it: the bound is not loose
    assert bound.force_n <= WRENCH_FACTOR * 6 * robot.limits.strut_force_max


def steepest_accepted_length(robot) -> float:
    """The shortest stiffening length (m) of the shipped tissue that the check accepts (bisection)."""
    low, high = 1e-3, 0.005  # refused, accepted
    assert "force reaches" in refused(tissue_from_dict, with_value(tree_of("tissue.yaml"), "stiffening.length_m", low),
                                      robot)
    for _ in range(30):
        mid = 0.5 * (low + high)
        try:
            tissue_from_dict(with_value(tree_of("tissue.yaml"), "stiffening.length_m", mid), robot)
            high = mid
        except ConfigError:
            low = mid
    return high


def test_the_emulator_stays_physical_with_the_steepest_tissue_it_accepts(robot):
    """The tissue bound keeps the emulator alive: with the steepest accepted tissue, a 20 mm distraction (the
    edge of the checked region) runs at the suite's state rate, every applied wrench is finite and within the
    bound, and the platform follows its struts. Without the check the same model family overflows
    (length_m 1e-6: what killed the physics thread)."""
    length = steepest_accepted_length(robot)
    model = tissue_from_dict(with_value(tree_of("tissue.yaml"), "stiffening.length_m", length), robot)
    bound = check_tissue_wrench(model, robot, "x")
    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000), tissue=model)
    target = robot.home_pose + [0.0, 0.0, CHECK_TRANSLATION_M, 0.0, 0.0, 0.0]
    start, goal = inverse_kinematics(robot, robot.home_pose), inverse_kinematics(robot, target)
    duration = minimum_jerk_duration(start, goal, 0.5 * robot.limits.strut_velocity_max, 0.5)
    times = np.linspace(duration / 50, duration, 50)
    emu.command_struts(LEG_NAMES, 0.0, times, *minimum_jerk(start, goal, duration, times))
    peak, previous = 0.0, emu.time
    while emu.time < duration + 0.2:
        emu.advance(1 / STATE_RATE_HZ)  # one state period per block, as the emulator node runs it
        assert emu.time > previous, "MuJoCo reset itself (unstable)"
        assert np.isfinite(emu.tissue_wrench).all() and np.isfinite(emu.platform_pose()).all()
        peak, previous = max(peak, float(np.linalg.norm(emu.tissue_wrench[:3]))), emu.time
    assert peak <= bound.force_n and peak > 0.5 * bound.force_n  # it did work against the steep part
    assert np.abs(emu.platform_pose() - target).max() < 1e-4
    unchecked = TissueModel(model.rest_pose, model.center, model.stiffness, model.damping, stiffening="exponential",
                            length_m=1e-6)
    with pytest.raises(OverflowError):
        unchecked.axial_spring_scalar(0.001)


# -- simulation.yaml ----------------------------------------------------------------------------------------

@pytest.mark.parametrize(("key", "value", "words"), [
    ("timestep_s", 1.0, "'timestep_s' = 1 is outside its plausible range [1e-06, 0.01] s"),
    ("timestep_s", "small", "'timestep_s' must be a number, got 'small'"),
    ("integrator", "Verlet", "'integrator' must be one of ['Euler', 'RK4', 'implicit', 'implicitfast']"),
    ("emulator_integrator", 4, "'emulator_integrator' must be one of"),
    ("solver", "Gauss", "'solver' must be one of ['Newton', 'CG', 'PGS']"),
    ("solimp", [0.9, 0.9, 0.001, 0.5], "'solimp' must be a list of 5 numbers"),
    ("solimp", [2.0, 0.9, 0.001, 0.5, 2.0], "'solimp[0]' = 2 is outside"),
    ("solver_iterations", 2.5, "'solver_iterations' must be a whole number"),
    ("servo_bandwidth_hz", 1e6, "'servo_bandwidth_hz' = 1e+06 is outside"),
    ("drive_damping_ratio", -1.0, "'drive_damping_ratio' = -1 is outside"),
    ("substeps", 4, "unknown keys ['substeps']"),
])
def test_an_implausible_simulation_setting_is_refused_naming_its_key(tmp_path, key, value, words):
    path = write(tmp_path, with_value(tree_of("simulation.yaml"), key, value), "simulation.yaml")
    text = refused(load_simulation_settings, path)
    assert text.startswith(f"simulation config {path}: ") and words in text, text


def test_simulation_overrides_are_checked_like_the_file():
    assert load_simulation_settings(timestep=1 / 2000).timestep == 1 / 2000
    with pytest.raises(ConfigError, match=r"\(with timestep set\): 'timestep_s' = 0.5 is outside"):
        load_simulation_settings(timestep=0.5)


# -- scenarios ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("text", "words"), [
    ("steps: move_to home\n", "needs a non-empty 'steps' list, got 'move_to home'"),
    ("steps: [move_to]\n", "step 0 must be one of move_to / guarded_move_to / vibrate, got 'move_to'"),
    ("steps: [{jump: home}]\n", "step 0 has unknown kind 'jump'"),
    ("steps: [{move_to: [0, 0, up, 0, 0, 0]}]\n", "'step 0 move_to[2]' must be a number, got 'up'"),
    ("steps: [{move_to: [0, 0, 0.5, 0, 0, 0]}]\n", "step 0 move_to [0.0, 0.0, 0.5, 0.0, 0.0, 0.0] cannot be reached "
                                                   "by the robot"),
    ("steps: [{vibrate: [35]}]\n", "step 0 vibrate needs a mapping of planner settings"),
    ("steps: [{vibrate: {frequency_hz: fast, duration_s: 1}}]\n", "'step 0 vibrate.frequency_hz' must be a number"),
    ("steps: [{vibrate: {frequency_hz: 1000, duration_s: 1}}]\n", "step 0 vibrate: frequency_hz 1000.0 is outside "
                                                                  "the vibration unit's band"),
    ("steps: [{vibrate: {acceleration_g: 50, duration_s: 1}}]\n", "step 0 vibrate: acceleration_g 50.0 is outside "
                                                                  "its range [0, 10]"),
    ("steps: [{vibrate: {direction: [1, 0], duration_s: 1}}]\n", "'step 0 vibrate.direction' must be a list of 3"),
    ("steps: [{vibrate: {frame: world, duration_s: 1}}]\n", "'step 0 vibrate.frame' must be one of"),
    ("steps: [{vibrate: {duration_s: 1, speed: 2}}]\n", "unknown keys in 'step 0 vibrate' ['speed']"),
    ("steps: [{vibrate: {duration_s: .inf}}]\n", "'step 0 vibrate.duration_s' must be finite"),
    ("steps: [{move_to: home}]\nbounds: {pose_error_m: small}\n", "'bounds.pose_error_m' must be a number"),
    ("steps: [{move_to: home}]\nbounds: {pose_error_m: -1}\n", "'bounds.pose_error_m' = -1 is outside"),
    ("steps: [{move_to: home}]\nbounds: {pose_eror_m: 1}\n", "unknown keys in 'bounds' ['pose_eror_m']"),
    ("steps: [{move_to: home}]\nbounds: [1]\n", "'bounds' must be a mapping"),
    ("steps: [{move_to: home}]\ntissue: [a]\n", "'tissue' must be a file name"),
    ("steps: [{move_to: home}]\nname: {a: 1}\n", "'name' must be text"),
    ("steps: [{move_to: home}]\nstep: []\n", "unknown keys ['step']"),
])
def test_a_bad_scenario_is_refused_naming_the_step_or_key(robot, tmp_path, text, words):
    path = tmp_path / "scenario.yaml"
    path.write_text(text)
    message = refused(load_scenario, robot, path)
    assert message.startswith(f"scenario {path}: ") and words in message, message


def test_the_shipped_scenarios_load(robot):
    for name in ("scenario_paper.yaml", "scenario_tissue.yaml"):
        scenario = load_scenario(robot, CONFIG / name)
        assert scenario.steps and scenario.source == str(CONFIG / name)


# -- planner settings ---------------------------------------------------------------------------------------

def test_a_huge_direction_is_normalised_not_zeroed(robot):
    """[1e200, 0, 0] plans exactly as [1, 0, 0] (its square overflowed to inf: all-zero gains, "started")."""
    s = default_settings(robot)
    huge, unit = dict(s, direction=[1e200, 0.0, 0.0]), dict(s, direction=[1.0, 0.0, 0.0])
    assert settings_reason(robot, huge) is None
    gains = plan_vibration(robot, robot.home_pose, huge).gains
    assert np.abs(gains).max() > 0.1
    np.testing.assert_array_equal(gains, plan_vibration(robot, robot.home_pose, unit).gains)
    tiny = dict(s, direction=[3e-160, 4e-160, 0.0])  # its square underflows to 0; still a direction
    assert settings_reason(robot, tiny) is not None  # below the 1e-9 a direction must have: refused, as before
    overflow = dict(s, direction=[1.7e308, 1.7e308, 1.7e308])
    assert "its length overflows" in settings_reason(robot, overflow)


@pytest.mark.parametrize(("name", "value"), [("acceleration_g", 11.0), ("phase_rad", 7.0), ("ramp_s", 11.0),
                                              ("lookahead_s", 61.0), ("max_lookahead_s", 31.0), ("lead_s", 2.5)])
def test_every_declared_range_is_part_of_the_one_check(robot, name, value):
    s = dict(default_settings(robot), **{name: value})
    if name == "lookahead_s":
        s["max_lookahead_s"] = 30.0
    reason = settings_reason(robot, s)
    assert reason is not None and name in reason, reason
    assert math.isfinite(value)
