"""The leg lengths a batch of joint states measures, read without ROS (messages.leg_lengths): struts plus units
carried forward by the sensors' latency (by hand), states that are no measurement dropped with their reason and
count, and a batch whose names lack a leg."""

from __future__ import annotations

import numpy as np

from stewart_vibration.messages.joint_states import JointStateBatch
from stewart_vibration.messages.leg_lengths import leg_lengths
from stewart_vibration.nodes.message_conversions import JointColumns

NAMES = tuple(f"vib_{i}" for i in range(1, 7)) + tuple(f"leg_{i}" for i in range(1, 7))  # units first


def batch(struts, units, rates, names=NAMES) -> JointStateBatch:
    struts, units, rates = (np.asarray(x, float) for x in (struts, units, rates))
    stamps = 0.002 * np.arange(len(struts))
    position = np.hstack([units, struts])
    velocity = np.hstack([rates, np.zeros_like(struts)])
    return JointStateBatch(stamps, names, position, velocity, np.full_like(position, np.nan))


def test_a_legs_length_is_its_strut_plus_its_unit_carried_forward_by_the_latency():
    struts = np.full((3, 6), 0.174) + 1e-4 * np.arange(18).reshape(3, 6)
    units = 1e-5 * np.arange(18).reshape(3, 6)
    rates = np.full((3, 6), 2e-3)
    rates[1, 2] = np.nan  # a rate the unit did not report is not carried
    states = leg_lengths(batch(struts, units, rates), *JointColumns()(NAMES), unit_sensor_latency_s=5e-4)
    expected = struts + units + 5e-4 * 2e-3
    expected[1, 2] = struts[1, 2] + units[1, 2]
    np.testing.assert_allclose(states.lengths, expected, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(states.struts, struts)
    assert states.kept.all() and states.dropped == () and np.array_equal(states.stamps, [0.0, 0.002, 0.004])
    legs_only = tuple(f"leg_{i}" for i in range(1, 7))
    alone = leg_lengths(JointStateBatch(np.zeros(1), legs_only, struts[:1], np.zeros((1, 6)), np.zeros((1, 6))),
                        *JointColumns()(legs_only))
    np.testing.assert_array_equal(alone.lengths, struts[:1])  # no units: the struts


def test_states_that_are_no_measurement_are_dropped_with_their_reason():
    struts = np.full((4, 6), 0.174)
    units = np.zeros((4, 6))
    struts[1, 3] = np.nan
    units[2, 0] = 11.0  # beyond 10 m
    states = leg_lengths(batch(struts, units, np.zeros((4, 6))), *JointColumns()(NAMES))
    assert states.kept.tolist() == [True, False, False, True] and np.array_equal(states.stamps, [0.0, 0.006])
    ((error, count),) = states.dropped
    assert count == 2 and error.kind == "not_finite" and error.field == "position" and "10 m" in str(error)


def test_a_batch_without_every_leg_is_dropped_whole():
    names = NAMES[:-1] + ("leg_7",)
    legs_at, vib_at = JointColumns()(names)
    states = leg_lengths(batch(np.full((2, 6), 0.174), np.zeros((2, 6)), np.zeros((2, 6)), names), legs_at, vib_at)
    assert legs_at is None and len(states.stamps) == 0 and not states.kept.any()
    ((error, count),) = states.dropped
    assert count == 2 and error.kind == "names" and "leg_6" in str(error)
