"""The vibration planner's settings as the planning page follows them (ui/planner_settings.py) and the
parameter answers they come from (nodes/parameter_answers.py, rcl_interfaces messages, no ROS graph): values by
name, declared ranges, malformed answers refused, and the defaults until the planner answers."""

from __future__ import annotations

import math

import pytest
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, ParameterType, ParameterValue

from stewart_vibration.errors import MalformedMessageError
from stewart_vibration.messages.status_values import planner_settings
from stewart_vibration.nodes.parameter_answers import ask_parameters, declared_ranges, parameter_values
from stewart_vibration.ui.planner_settings import PlannerSettings
from stewart_vibration.vibration.settings import STREAM_KEYS

VIBRATION = {"direction": [0, 0, 1], "frame": "platform", "mode": "amplitude", "amplitude_um": 40,
             "frequency_hz": 30, "phase_deg": 90, "duration_s": 2, "ramp_s": 0.25}


def double(value):
    return ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)


def test_the_page_s_vibration_goes_with_the_planner_s_streaming_settings(robot):
    planner = PlannerSettings.defaults(robot)
    assert not planner.known and planner.values["lookahead_s"] == 2.0 and planner.ranges == {}
    planner.got({"lookahead_s": 3.5, "frequency_hz": 99.0})  # only the streaming settings are the planner's
    assert planner.known and planner.values["lookahead_s"] == 3.5 and "frequency_hz" not in planner.values
    params, settings = planner.vibration(robot, VIBRATION)
    assert params["amplitude_m"] == pytest.approx(40e-6) and params["phase_rad"] == pytest.approx(math.pi / 2)
    assert settings["lookahead_s"] == 3.5 and settings["frequency_hz"] == 30.0  # the page's, not the planner's
    assert settings["acceleration_g"] == 0.3  # left out by the page: the default
    planner.declared({"frequency_hz": (10.0, 80.0)})
    assert planner.ranges == {"frequency_hz": (10.0, 80.0)}


def test_a_get_parameters_answer_becomes_values_by_name():
    values = parameter_values(["a", "b", "c"], [double(0.5), ParameterValue(type=ParameterType.PARAMETER_INTEGER,
                                                                            integer_value=3),
                                                ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY,
                                                               double_array_value=[1.0, 2.0])])
    assert values == {"a": 0.5, "b": 3, "c": [1.0, 2.0]} and type(values["c"]) is list
    with pytest.raises(MalformedMessageError, match="1 values for 2 names"):
        parameter_values(["a", "b"], [double(0.5)])
    with pytest.raises(MalformedMessageError, match="b: unexpected parameter type 99"):
        parameter_values(["a", "b"], [double(0.5), ParameterValue(type=99)])


def descriptor(name, low, high):
    return ParameterDescriptor(name=name, floating_point_range=[FloatingPointRange(from_value=low, to_value=high)])


def test_only_finite_declared_ranges_of_the_asked_names_are_kept():
    descriptors = [descriptor("lead_s", 0.0, 1.0), descriptor("lookahead_s", 0.1, math.inf),
                   descriptor("other", 0.0, 2.0), ParameterDescriptor(name="sample_period_s")]
    assert declared_ranges(descriptors, ["lead_s", "lookahead_s", "sample_period_s"]) == {"lead_s": (0.0, 1.0)}


class Answer:
    """A done rclpy Future of a service answer: its callback runs when added."""

    def __init__(self, result=None, error=None):
        self._result, self._error = result, error

    def exception(self):
        return self._error

    def result(self):
        return self._result

    def add_done_callback(self, callback):
        callback(self)


class Client:
    def __init__(self, ready, answer):
        self.ready, self.answer, self.requests = ready, answer, []

    def service_is_ready(self):
        return self.ready

    def call_async(self, request):
        self.requests.append(request)
        return self.answer


def test_the_planner_is_asked_for_its_settings_and_ranges_and_a_bad_answer_refused(robot):
    names = list(STREAM_KEYS)
    planner, refused = PlannerSettings.defaults(robot), []
    values = type("Values", (), {"values": [double(float(i + 1)) for i in range(len(names))]})()
    ranges = type("Ranges", (), {"descriptors": [descriptor("lead_s", 0.0, 1.0)]})()
    get, describe = Client(True, Answer(values)), Client(True, Answer(ranges))
    ask_parameters(get, describe, names, lambda v: planner.got(planner_settings(v)), planner.declared,
                   refused.append)
    assert get.requests[0].names == names and describe.requests[0].names == names
    assert planner.known and [planner.values[n] for n in names] == [float(i + 1) for i in range(len(names))]
    assert planner.ranges == {"lead_s": (0.0, 1.0)} and refused == []

    late = PlannerSettings.defaults(robot)
    short = type("Values", (), {"values": [double(1.0)]})()
    ask_parameters(Client(True, Answer(short)), Client(False, None), names, late.got, late.declared,
                   refused.append)
    assert not late.known and [e.reason for e in refused] == ["length values"]
    ask_parameters(Client(True, Answer(error=RuntimeError("gone"))), Client(True, Answer(error=RuntimeError())),
                   names, late.got, late.declared, refused.append)
    assert not late.known and late.ranges == {} and len(refused) == 1  # a failed call is asked again later
