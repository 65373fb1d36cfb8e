"""vibration.identification_runner driven with stepped time (no ROS): each step's window sent once, queue_s
ahead of its start and stamped t0 + its start; the feedback naming the step every 0.1 wall s; a cancel; the
robot's stops; the wait for the robot's word that its units rest before concluding; and the conclusion on a
synthetic linear robot (units that follow their demand, a platform moved by J^-1 of them, an IMU that reports
that motion): the file written holds that robot, read back; too noisy a record or a folder that is not there
writes nothing."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from stewart_vibration.emulation.vibration_status import VibrationReport
from stewart_vibration.kinematics.jacobian import jacobian
from stewart_vibration.kinematics.rotations import rotation_from_rpy
from stewart_vibration.paper import paper_pose
from stewart_vibration.robot import VIB_NAMES
from stewart_vibration.vibration.identification_run import step_samples
from stewart_vibration.vibration.identification_runner import METHOD, QUEUE_S, REST_REPORT_WAIT_S, IdentificationRunner
from stewart_vibration.vibration.identification_session import identification_steps
from stewart_vibration.vibration.unit_identification import load_identification

F, NOW, TICK, RATE = 35.0, 10.0, 0.01, 500.0


def new_runner(robot, path) -> IdentificationRunner:
    """A run of the six units at F Hz started at NOW with a lead of 0.5 s; the robot's event 4 seen before."""
    steps, amplitude = identification_steps((F,), 0.0, robot.vibration_unit)
    return IdentificationRunner.start(steps, amplitude, paper_pose(robot), NOW, 0.5, path, seen_event=4)


@pytest.fixture
def runner(robot, tmp_path):
    return new_runner(robot, tmp_path / "ident.yaml")


def at_rest(time: float, state: str = "idle", event_seq: int = 4, **event) -> VibrationReport:
    return VibrationReport(state=state, level="ok", reason=event.get("event_reason", ""), since=time - 1.0,
                           time=time, event_seq=event_seq, **event)


def test_each_window_goes_once_queue_s_ahead_of_its_step_stamped_with_its_start(runner):
    assert runner.t0 == NOW + 0.5 and runner.queue_s == QUEUE_S  # a lead shorter than the queue: the queue
    steps = runner.session.steps
    assert IdentificationRunner.start(steps, 2e-5, runner.session.pose, NOW, QUEUE_S + 0.5, runner.path,
                                      0).queue_s == QUEUE_S + 0.5  # a longer lead: the lead
    sent = []
    for k in range(1, int((runner.session.end + 1.5) / TICK)):
        now = NOW + k * TICK
        for stamp, times, position, _, _ in runner.tick(now, 0.0, False, None).windows:
            sent.append((now, stamp, times, position))
    assert [stamp for _, stamp, _, _ in sent] == pytest.approx([runner.t0 + s.start for s in steps])
    for (now, stamp, times, position), step in zip(sent, steps, strict=True):
        due = stamp - QUEUE_S  # the first step is due before the first tick, the others on their tick
        assert now == NOW + TICK if due < NOW + TICK else due - 1e-9 <= now < due + TICK + 1e-9, (now, due)
        assert times[0] == 0.0 and times[-1] == pytest.approx(step.duration)
        others = np.delete(position, step.unit, axis=1)
        assert not others.any() and abs(position[[0, -1], step.unit]).max() < 1e-12  # one unit, from rest to rest
        assert abs(position[:, step.unit]).max() == pytest.approx(runner.session.amplitude_m, rel=1e-3)


def test_feedback_names_the_step_and_the_unit_every_tenth_of_a_wall_second(runner):
    step = runner.session.steps[2]
    middle = runner.t0 + step.start + step.duration / 2
    assert runner.tick(middle, 100.0, False, None).progress == (3, 6, step.unit + 1, F)
    assert runner.tick(middle, 100.05, False, None).progress is None
    gap = runner.t0 + step.end + 0.01  # between two steps: no unit moves
    assert runner.tick(gap, 100.1, False, None).progress == (3, 6, 0, 0.0)


def test_it_concludes_once_the_robot_says_its_units_rest_after_the_last_step_or_the_wait_runs_out(runner):
    end = runner.t0 + runner.session.end
    assert not runner.tick(end + 0.09, 0.0, False, at_rest(end + 0.09)).ready  # the last step just ended
    assert runner.tick(end + 0.1, 0.0, False, at_rest(end + 0.1)).ready
    assert not runner.tick(end + 0.5, 0.0, False, at_rest(end - 0.2)).ready  # a word from before the end
    assert not runner.tick(end + 0.5, 0.0, False, at_rest(end + 0.5, state="ramping_out")).ready
    assert not runner.tick(end + REST_REPORT_WAIT_S - 0.01, 0.0, False, None).ready
    assert runner.tick(end + REST_REPORT_WAIT_S, 0.0, False, None).ready  # no word: the wait ran out


def test_a_cancel_ends_it_at_once_with_nothing_written(runner):
    step = runner.tick(NOW, 0.0, True, None)
    assert step.windows == [] and step.progress is None and not step.ready
    assert runner.end.outcome == "CANCELED" and runner.end.path == "" and "nothing written" in runner.end.message
    assert not runner.tick(runner.t0 + runner.session.end + 1.0, 0.0, True, at_rest(runner.t0 + 99)).ready


def test_the_robots_stop_ends_it_once_with_its_outcome_and_how_long_it_ran(runner):
    refused = at_rest(runner.t0 + 2.0, state="pending", event="refused", event_stamp=runner.t0 + 1.0,
                      event_outcome="LIMIT_EXCEEDED", event_reason="vib_2: too fast")
    runner.on_status(refused)
    assert runner.end is None  # event 4 was seen before the run began: not this run's
    runner.on_status(replace(refused, event_seq=5))
    end = runner.end
    assert end.outcome == "ROBOT_REFUSED" and end.duration_s == pytest.approx(1.0) and "too fast" in end.problems[0]
    runner.on_status(at_rest(runner.t0 + 3.0, state="estopped", event_seq=6))
    assert runner.end is end  # the first end stays


def test_the_units_readings_are_taken_by_name_and_stamped_from_t0(runner):
    names = ["leg_1", *reversed(VIB_NAMES)]
    runner.add_unit_readings(runner.t0 + 0.25, names, [9.0, 6.0, 5.0, 4.0, 3.0, 2.0, 1.0])
    assert list(runner.session.units) == [250_000]
    np.testing.assert_array_equal(runner.session.units[250_000], [1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    runner.add_unit_readings(runner.t0 + 0.5, names[:-1], [9.0, 6.0, 5.0, 4.0, 3.0, 2.0])  # vib_1 missing
    runner.add_unit_readings(runner.t0 + 0.75, names, [9.0, 6.0, 5.0])  # positions that do not match the names
    assert list(runner.session.units) == [250_000]


def record(robot, runner, noise_m: float = 0.0) -> np.ndarray:
    """Feed ``runner`` the sensors of a linear robot over the whole run at RATE; returns its platform map
    J^-1 (6, 6): the platform's [dp (m); dphi (rad)] per unit displacement (m), base frame."""
    pose = paper_pose(robot)
    platform = np.linalg.inv(jacobian(robot, pose))
    rotation = rotation_from_rpy(pose[3:])
    times = np.arange(0.0, runner.session.end + 0.01, 1.0 / RATE)
    units, velocity, acceleration = (sum(parts) for parts in zip(
        *(step_samples(step, runner.session.amplitude_m, times) for step in runner.session.steps)))
    accel = (platform[:3] @ acceleration.T).T @ rotation  # R^T a per row: gravity 0 (the robot passed in)
    gyro = (platform[3:] @ velocity.T).T @ rotation
    readings = units + np.random.default_rng(1).normal(0.0, noise_m, units.shape) if noise_m else units
    for t, reading, a, w in zip(times, readings, accel, gyro, strict=True):
        runner.add_unit_readings(runner.t0 + t, VIB_NAMES, reading)
        runner.add_imu(runner.t0 + t, a, w)
    return platform


def test_the_identification_of_a_linear_robot_is_written_and_reads_back_as_that_robot(robot, runner):
    platform = record(robot, runner)
    end = runner.conclude(np.zeros(3), 0.0, 0.0)
    assert (end.outcome, end.problems, end.duration_s) == ("SUCCEEDED", [], runner.session.end)
    assert end.path == str(runner.path) and runner.end is end
    back = load_identification(end.path)
    np.testing.assert_allclose(back.frequencies, [F])
    np.testing.assert_allclose(back.unit_response[0], np.ones(6), atol=1e-6)
    np.testing.assert_allclose(back.platform_response[0], platform, atol=1e-6 * np.abs(platform).max())
    assert back.provenance["method"] == METHOD and back.provenance["date"] == runner.date


def test_a_noisy_record_is_rejected_with_its_problems_and_writes_nothing(robot, runner):
    record(robot, runner, noise_m=runner.session.amplitude_m)  # unit sensors as noisy as the demand
    end = runner.conclude(np.zeros(3), 0.0, 0.0)
    assert end.outcome == "IDENTIFICATION_REJECTED" and end.problems[0].startswith("unit 1 at 35 Hz") and \
        end.path == ""
    assert end.message.startswith(f"{len(end.problems)} problems, first: ") and not runner.path.exists()


def test_no_record_or_a_folder_that_is_not_there_writes_nothing(robot, tmp_path):
    empty = new_runner(robot, tmp_path / "ident.yaml").conclude(np.zeros(3), 0.0, 0.0)
    assert empty.outcome == "IDENTIFICATION_REJECTED" and empty.message.startswith("no identification")
    elsewhere = new_runner(robot, tmp_path / "missing" / "ident.yaml")
    record(robot, elsewhere)
    end = elsewhere.conclude(np.zeros(3), 0.0, 0.0)
    assert end.outcome == "INVALID_ARGUMENT" and end.message.startswith(f"could not write {elsewhere.path}")
    assert end.problems[0].startswith("not written") and end.path == ""
