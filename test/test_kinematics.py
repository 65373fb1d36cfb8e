"""Kinematics: IK, Jacobian, FK against independent references."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from reference import config_hinges, reference_lengths, reference_rotation, rodrigues

from stewart_vibration import (
    ForwardKinematicsError,
    UnreachablePoseError,
    condition_number,
    forward_kinematics,
    inverse_kinematics,
    jacobian,
    joint_angles,
    load_robot,
)
from stewart_vibration.install import default_config_dir
from stewart_vibration.kinematics.fk_scalar import solve_linear_6
from stewart_vibration.robot import robot_from_dict


def random_workspace_poses(robot, count, seed=0):
    """Uniform in +-20 mm and +-15 deg around home (the reduction workspace)."""
    rng = np.random.default_rng(seed)
    offsets = np.concatenate(
        [rng.uniform(-0.02, 0.02, (count, 3)), rng.uniform(-np.radians(15), np.radians(15), (count, 3))], axis=1
    )
    return robot.home_pose + offsets


@pytest.fixture(scope="module")
def ref_geometry():
    """Hinge points rebuilt from the YAML file itself, not from the library."""
    return config_hinges(default_config_dir() / "robot.yaml")



def test_joint_angles_match_per_leg_reference(robot, ref_geometry):
    """Universal angle: leg axis against the base z axis; spherical: against the platform z axis R e_z
    (one leg at a time, hinges from the YAML text, the rotation from elementary rotations)."""
    base, plat = ref_geometry
    poses = random_workspace_poses(robot, 40, seed=4)
    universal, spherical = joint_angles(robot, poses)
    assert universal.shape == spherical.shape == (40, 6)
    for k, q in enumerate(poses):
        rot = reference_rotation(*q[3:])
        for i in range(6):
            axis = q[:3] + rot @ plat[i] - base[i]
            axis = axis / np.linalg.norm(axis)
            assert universal[k, i] == pytest.approx(np.arccos(axis[2]), abs=1e-12)
            assert spherical[k, i] == pytest.approx(np.arccos(axis @ rot[:, 2]), abs=1e-12)

def test_ik_matches_per_leg_reference(robot, ref_geometry):
    base, plat = ref_geometry
    poses = random_workspace_poses(robot, 300, seed=1)
    lengths = inverse_kinematics(robot, poses)  # batched (chunked path: > 64 poses)
    expected = np.array([reference_lengths(base, plat, q) for q in poses])
    assert np.abs(lengths - expected).max() <= 1e-12
    single = np.array([inverse_kinematics(robot, q) for q in poses[:20]])  # small-batch path
    assert np.abs(single - expected[:20]).max() <= 1e-12


def test_ik_large_angles_use_exact_trig(robot, ref_geometry):
    """Angles beyond 1.2 rad take the np.cos branch of the chunked IK."""
    base, plat = ref_geometry
    poses = np.tile(robot.home_pose, (100, 1))
    poses[:, 5] = np.linspace(-3.0, 3.0, 100)  # yaw through +-172 deg
    lengths = inverse_kinematics(robot, poses, check_limits=False)
    expected = np.array([reference_lengths(base, plat, q) for q in poses])
    assert np.abs(lengths - expected).max() <= 1e-12


def test_ik_batch_shapes(robot):
    poses = random_workspace_poses(robot, 24).reshape(2, 3, 4, 6)
    assert inverse_kinematics(robot, poses).shape == (2, 3, 4, 6)
    assert inverse_kinematics(robot, robot.home_pose).shape == (6,)


def test_home_is_symmetric(robot):
    lengths = inverse_kinematics(robot, robot.home_pose)
    assert np.ptp(lengths) < 1e-15


def test_jacobian_matches_central_differences(robot, ref_geometry):
    base, plat = ref_geometry
    for pose in random_workspace_poses(robot, 20, seed=2):
        jac = jacobian(robot, pose)
        h = 1e-6
        numeric = np.zeros((6, 6))
        rot0 = reference_rotation(*pose[3:])
        for k in range(6):
            lengths = []
            for sign in (1, -1):
                if k < 3:
                    p = pose[:3].copy()
                    p[k] += sign * h
                    rot = rot0
                else:
                    p = pose[:3]
                    phi = np.zeros(3)
                    phi[k - 3] = sign * h
                    rot = rodrigues(phi) @ rot0  # small rotation in the base frame
                lengths.append(np.array([np.linalg.norm(p + rot @ plat[i] - base[i]) for i in range(6)]))
            numeric[:, k] = (lengths[0] - lengths[1]) / (2 * h)
        rel = np.abs(jac - numeric).max() / np.abs(numeric).max()
        assert rel <= 1e-7


def test_jacobian_transpose_is_the_force_map(robot, ref_geometry):
    """J^T F equals the wrench of axial leg forces computed leg by leg."""
    base, plat = ref_geometry
    pose = random_workspace_poses(robot, 1, seed=3)[0]
    forces = np.array([10.0, -5.0, 3.0, 7.0, -2.0, 1.0])
    rot = reference_rotation(*pose[3:])
    force = np.zeros(3)
    moment = np.zeros(3)
    for i in range(6):
        arm = rot @ plat[i]
        axis = pose[:3] + arm - base[i]
        axis /= np.linalg.norm(axis)
        force += forces[i] * axis
        moment += np.cross(arm, forces[i] * axis)
    wrench = jacobian(robot, pose).T @ forces
    assert np.allclose(wrench, np.concatenate([force, moment]), atol=1e-12)


def test_condition_number_matches_reference(robot, ref_geometry):
    """sigma_max / sigma_min of J diag(1, 1, 1, 1/L, 1/L, 1/L), L the mean platform hinge radius, with J
    built leg by leg from the YAML hinges."""
    base, plat = ref_geometry
    scale = np.r_[1.0, 1.0, 1.0, [1.0 / np.linalg.norm(plat[:, :2], axis=1).mean()] * 3]
    poses = random_workspace_poses(robot, 20, seed=11)
    expected = []
    for pose in poses:
        rot = reference_rotation(*pose[3:])
        rows = []
        for i in range(6):
            arm = rot @ plat[i]
            n = pose[:3] + arm - base[i]
            n /= np.linalg.norm(n)
            rows.append(np.r_[n, np.cross(arm, n)])
        sv = np.linalg.svd(np.array(rows) * scale, compute_uv=False)
        expected.append(sv[0] / sv[-1])
    np.testing.assert_allclose(condition_number(robot, poses), expected, rtol=1e-10)


def test_condition_number_is_dimensionless_and_grows_near_singularity(robot):
    home = condition_number(robot, robot.home_pose)
    assert 1.0 <= home < robot.limits.condition_number_max
    low = robot.home_pose.copy()
    low[2] = 1e-4  # platform almost in the base plane: legs nearly horizontal
    assert condition_number(robot, low) > 100 * home
    # scaling the whole robot (and the pose translation) leaves it unchanged
    tree = yaml.safe_load((default_config_dir() / "robot.yaml").read_text())
    tree["geometry"]["base"]["radius_m"] *= 10
    tree["geometry"]["platform"]["radius_m"] *= 10
    from stewart_vibration.robot import robot_from_dict

    big = robot_from_dict(tree)
    pose = robot.home_pose.copy()
    pose[:3] *= 10
    assert condition_number(big, pose) == pytest.approx(home, rel=1e-9)


def test_fk_round_trip_10000_poses(robot):
    poses = random_workspace_poses(robot, 10_000, seed=4)
    lengths = inverse_kinematics(robot, poses)
    cold = forward_kinematics(robot, lengths)
    assert cold.converged.all() and cold.assembly_ok.all()
    assert cold.residual.max() <= 1e-12
    assert np.abs(cold.pose - poses).max() <= 1e-10
    assert np.median(cold.iterations) <= 5
    # warm start from a pose 10 um / 1e-4 rad away
    rng = np.random.default_rng(5)
    direction = rng.normal(size=(10_000, 6))
    direction[:, :3] *= 1e-5 / np.linalg.norm(direction[:, :3], axis=1, keepdims=True)
    direction[:, 3:] *= 1e-4 / np.linalg.norm(direction[:, 3:], axis=1, keepdims=True)
    warm = forward_kinematics(robot, lengths, guess=poses + direction)
    assert warm.converged.all() and warm.assembly_ok.all()
    assert np.abs(warm.pose - poses).max() <= 1e-10
    assert np.median(warm.iterations) <= 2


def test_fk_single_warm_path_matches_batched(robot):
    """The scalar single-solve path and the batched numpy path agree sample by sample."""
    poses = random_workspace_poses(robot, 200, seed=6)
    lengths = inverse_kinematics(robot, poses)
    rng = np.random.default_rng(8)
    guesses = poses + rng.normal(scale=[1e-3, 1e-3, 1e-3, 1e-2, 1e-2, 1e-2], size=poses.shape)
    batched = forward_kinematics(robot, lengths, guess=guesses)
    for k in range(len(poses)):
        single = forward_kinematics(robot, lengths[k], guess=guesses[k])
        assert single.pose.shape == (6,) and single.rotation.shape == (3, 3)
        assert np.abs(single.pose - poses[k]).max() <= 1e-10
        assert np.abs(single.pose - batched.pose[k]).max() <= 1e-12
        assert int(single.iterations) == int(batched.iterations[k])
        assert bool(single.converged) and bool(single.assembly_ok)


def test_scalar_linear_solve_and_determinant_sign_match_numpy():
    rng = np.random.default_rng(9)
    for _ in range(200):
        a = rng.normal(size=(6, 6))
        b = rng.normal(size=6)
        x, sign = solve_linear_6(a.tolist(), b.tolist())
        assert np.allclose(x, np.linalg.solve(a, b), rtol=1e-9, atol=1e-12)
        assert sign == np.sign(np.linalg.det(a))
    singular = np.ones((6, 6))
    assert solve_linear_6(singular.tolist(), [1.0] * 6) is None


def test_fk_rejects_other_assembly_mode(robot):
    """Mirror the platform through the base plane: same leg lengths, wrong mode."""
    pose = robot.home_pose.copy()
    lengths = inverse_kinematics(robot, pose)
    mirrored = pose.copy()
    mirrored[2] = -pose[2]
    result = forward_kinematics(robot, lengths, guess=mirrored)
    assert result.converged  # it is a valid solution of the equations ...
    assert not result.assembly_ok  # ... but not this robot's assembly mode
    with pytest.raises(ForwardKinematicsError, match="assembly mode"):
        result.raise_for_failure()


def test_fk_flags_a_solution_below_the_base(robot, ref_geometry):
    """Another real solution of the home leg lengths (found by a search from random guesses) with three
    platform hinges below the base plane: converged, but not this robot's assembly mode, in the scalar
    (single pose) and the batched path alike."""
    base, plat = ref_geometry
    lengths = inverse_kinematics(robot, robot.home_pose)
    guess = np.array([0.0614, -0.0978, -0.0123, -2.5449, 0.7933, -1.8749])
    single = forward_kinematics(robot, lengths, guess=guess)
    batched = forward_kinematics(robot, np.tile(lengths, (64, 1)), guess=np.tile(guess, (64, 1)))
    for result in (single, batched):
        assert np.all(result.converged) and not np.any(result.assembly_ok)
    assert np.abs(reference_lengths(base, plat, single.pose) - lengths).max() <= 1e-12  # it is a solution
    rot = reference_rotation(*single.pose[3:])
    heights = np.array([(single.pose[:3] + rot @ plat[i] - base[i])[2] for i in range(6)])
    assert (heights < -0.01).sum() == 3
    with pytest.raises(ForwardKinematicsError, match="assembly mode"):
        single.raise_for_failure()


def test_fk_backtracking_from_a_far_guess(robot):
    pose = random_workspace_poses(robot, 1, seed=7)[0]
    lengths = inverse_kinematics(robot, pose)
    far = robot.home_pose + np.array([0.03, -0.03, 0.03, 0.4, -0.4, 0.4])
    result = forward_kinematics(robot, lengths, guess=far)
    assert result.converged and result.assembly_ok
    assert np.abs(result.pose - pose).max() <= 1e-10


def test_fk_batched_backtracking_from_far_guesses(robot):
    """Corners of +-30 mm / +-0.4 rad away: plain Newton overshoots for some, the batched step halving
    brings every sample home, sample by sample as the scalar path does."""
    poses = random_workspace_poses(robot, 64, seed=7)
    lengths = inverse_kinematics(robot, poses)
    rng = np.random.default_rng(3)
    far = robot.home_pose + rng.choice([-1, 1], (64, 6)) * np.array([0.03, 0.03, 0.03, 0.4, 0.4, 0.4])
    batched = forward_kinematics(robot, lengths, guess=far)
    assert batched.converged.all() and batched.assembly_ok.all()
    assert np.abs(batched.pose - poses).max() <= 1e-10
    single = [int(forward_kinematics(robot, lengths[k], guess=far[k]).iterations) for k in range(len(poses))]
    assert batched.iterations.tolist() == single


def test_load_robot_explicit_path_equals_default(tmp_path):
    text = (default_config_dir() / "robot.yaml").read_text()
    path = tmp_path / "robot.yaml"
    path.write_text(text)
    a, b = load_robot(path), load_robot()
    assert np.array_equal(a.base_hinges, b.base_hinges)
    assert np.array_equal(a.platform_hinges, b.platform_hinges)


def _reference_validity(robot, poses):
    """Per pose: every platform hinge above its base hinge, strokes and joint angles
    within limits; textbook per-axis rotation matrices, explicit leg vectors."""
    roll, pitch, yaw = poses[:, 3], poses[:, 4], poses[:, 5]
    one, zero = np.ones_like(roll), np.zeros_like(roll)

    def stack(rows):
        return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)

    rx = stack([[one, zero, zero], [zero, np.cos(roll), -np.sin(roll)], [zero, np.sin(roll), np.cos(roll)]])
    ry = stack([[np.cos(pitch), zero, np.sin(pitch)], [zero, one, zero], [-np.sin(pitch), zero, np.cos(pitch)]])
    rz = stack([[np.cos(yaw), -np.sin(yaw), zero], [np.sin(yaw), np.cos(yaw), zero], [zero, zero, one]])
    rot = rz @ ry @ rx
    base, platform = config_hinges()  # the tests' robots keep the default geometry
    legs = poses[:, None, :3] + np.einsum("nij,kj->nki", rot, platform) - base
    lengths = np.linalg.norm(legs, axis=-1)
    axis = legs / lengths[..., None]
    universal = np.degrees(np.arccos(np.clip(axis[..., 2], -1, 1)))
    spherical = np.degrees(np.arccos(np.clip(np.einsum("nki,ni->nk", axis, rot[:, :, 2]), -1, 1)))
    lim = robot.limits
    violations = {
        "below base": ~(legs[..., 2] > 0),
        "stroke": (lengths < lim.stroke_min) | (lengths > lim.stroke_max),
        "universal": universal > np.degrees(lim.universal_joint_max),
        "spherical": spherical > np.degrees(lim.spherical_joint_max),
    }
    violations = {kind: mask.any(axis=-1) for kind, mask in violations.items()}
    valid = ~np.any(list(violations.values()), axis=0)
    return valid, lengths, violations


def test_large_batch_limit_checks_agree_with_reference():
    """The chunked, multi-threaded IK flags exactly the poses the reference rejects,
    and names the first bad sample wherever it lies in the batch."""
    tree = yaml.safe_load((default_config_dir() / "robot.yaml").read_text())
    tree["limits"].update(
        universal_joint_max_deg=35.0, spherical_joint_max_deg=40.0, stroke_min_m=0.13, stroke_max_m=0.20
    )
    strict = robot_from_dict(tree)
    rng = np.random.default_rng(10)
    wide = strict.home_pose + rng.uniform(-1, 1, (40_000, 6)) * [0.03, 0.03, 0.03, 0.25, 0.25, 0.25]
    valid, _, violations = _reference_validity(strict, wide)
    good = wide[valid]
    batch = good[rng.integers(0, len(good), 3 * 65_536)]
    ref_valid, ref_lengths, _ = _reference_validity(strict, batch)
    assert ref_valid.all()
    assert np.abs(inverse_kinematics(strict, batch) - ref_lengths).max() <= 1e-12
    # poses that break exactly one kind of limit, ten of each kind
    only = {k: m & (np.sum(list(violations.values()), axis=0) == 1) for k, m in violations.items()}
    examples = {k: wide[m][:10] for k, m in only.items() if k != "below base"}
    assert all(len(e) == 10 for e in examples.values()), {k: len(e) for k, e in examples.items()}
    for kind, poses in examples.items():
        for pose in poses:
            index = int(rng.integers(0, len(batch)))
            trial = batch.copy()
            trial[index] = pose
            with pytest.raises(UnreachablePoseError) as info:
                inverse_kinematics(strict, trial)
            assert info.value.sample == index, kind
    below = strict.home_pose.copy()
    below[2] = -0.16
    bad = [examples["stroke"][0], below]
    first, second = 1000, len(batch) - 1000  # one in each thread's rows
    trial = batch.copy()
    trial[[first, second]] = bad
    with pytest.raises(UnreachablePoseError) as info:
        inverse_kinematics(strict, trial)
    assert info.value.sample == first
