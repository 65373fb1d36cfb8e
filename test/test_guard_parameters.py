"""The force guard's settings from the kinematics node's parameters, without ROS (motion.guard_parameters): a
guard made from them, a later set applied at once, and a changed limit clearing a latched trip."""

from __future__ import annotations

from tripped_guard import lift_into

from stewart_vibration.motion.guard_parameters import GUARD_PARAMETERS, apply_guard_parameters, guard_from_parameters
from stewart_vibration.parameters.tables import spec_of

VALUES = {"guard_force_n": 120.0, "guard_moment_nm": 9.0, "guard_deceleration_scale": 0.6,
          "guard_max_estimate_age_s": 0.3, "guard_blind_travel_m": 2e-3, "speed_scale": 0.5}


def test_the_names_are_the_kinematics_nodes_parameters():
    for name in GUARD_PARAMETERS:
        assert spec_of("kinematics", name).kind == "double"


def test_a_guard_takes_every_setting_and_a_set_applies_at_once(robot):
    guard = guard_from_parameters(robot, VALUES)
    assert (guard.force_limit, guard.moment_limit, guard.deceleration_scale) == (120.0, 9.0, 0.6)
    assert (guard.estimates.max_estimate_age, guard.estimates.blind_travel) == (0.3, 2e-3)
    assert apply_guard_parameters(guard, {"speed_scale": 0.9, "batch_size": 20}) is None  # none of the guard's
    assert apply_guard_parameters(guard, {"guard_deceleration_scale": 1, "guard_blind_travel_m": 0.0,
                                          "guard_max_estimate_age_s": 0.5}) is False
    assert guard.deceleration_scale == 1.0 and isinstance(guard.deceleration_scale, float)
    assert (guard.estimates.blind_travel, guard.estimates.max_estimate_age) == (0.0, 0.5)
    assert apply_guard_parameters(guard, {"guard_moment_nm": 4}) is False and guard.moment_limit == 4.0


def test_a_changed_limit_clears_a_trip_and_the_same_one_does_not(robot):
    guard = guard_from_parameters(robot, VALUES | {"guard_force_n": 200.0})
    lift_into(guard, robot)
    assert apply_guard_parameters(guard, {"guard_force_n": 200.0, "guard_deceleration_scale": 0.7}) is False
    assert guard.tripped and guard.deceleration_scale == 0.7
    assert apply_guard_parameters(guard, {"guard_force_n": 250.0}) is True
    assert not guard.tripped and guard.force_limit == 250.0
