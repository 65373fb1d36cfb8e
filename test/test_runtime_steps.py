"""The scenario's steps (runtime/steps.py) against a scripted client: no ROS, no processes. What the main job
does over DDS (test_main_job) is the same code with nodes/suite_client.py as the client."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from stewart_vibration.motion.guard_status import GuardStatus
from stewart_vibration.runtime.run_options import RunOptions, RunRecord
from stewart_vibration.runtime.scenario import MoveStep, Scenario, VibrateStep
from stewart_vibration.runtime.steps import ScenarioSteps
from stewart_vibration.runtime.suite_interface import (
    IdentificationEnd,
    MoveResult,
    StepFailed,
    VibrationEnd,
    VibrationStart,
)


class ScriptedSuite:
    """A suite that answers at once: moves reach their target after 0.2 s of sim time (or stop 1 mm short when
    the guard trips), a vibration runs from t0 for ``active_s`` and the units then go idle."""

    def __init__(self, active_s=None, refuse=None, guard_trips=False, report_period_s=0.0, truth_offset=None,
                 outcome="SUCCEEDED", move_outcome="SUCCEEDED", identification="SUCCEEDED", demand_correction=0.0):
        self.clock, self.target, self.pose = 0.0, None, np.zeros(6)
        # the robot as built: the truth is off the controller's estimate by this much (6,)
        self.truth_offset = np.zeros(6) if truth_offset is None else np.asarray(truth_offset, float)
        self.vibration_status, self.outcome, self.result = None, outcome, None
        self.move_outcome = move_outcome
        self.status_history = []
        self.report_period_s, self._reported = report_period_s, float("-inf")
        self.active_s, self.refuse, self.guard_trips = active_s, refuse, guard_trips
        self.t0 = self.duration = None
        self.following = []
        self.sent_parameters = {}
        self.identification, self.identified = identification, []  # the outcome to give; (time, frequencies, path)
        self.demand_correction = demand_correction  # how far the closed loop moved the demands
        self.vibrations = 0  # vibrate goals started; ``outcome`` and ``demand_correction`` may list one per goal

    def spin_until(self, predicate, timeout, what):
        for _ in range(100_000):
            if predicate():
                return
            self.clock += 0.01
            self._advance()
        raise StepFailed(f"timed out waiting for {what}")

    def wait_sim(self, seconds, what):
        end = self.clock + seconds
        self.spin_until(lambda: self.clock >= end, 0, what)

    def _advance(self):
        if self.target is not None:
            goal = self.target - (np.r_[0, 0, 1e-3, 0, 0, 0] if self.guard_trips else 0)
            self.pose = goal if self.clock - self.sent_at > 0.2 else self.pose
        if self.t0 is not None and self.clock - self._reported >= self.report_period_s - 1e-9:
            # a report every report_period_s of sim time (the emulator reports at 10 Hz of wall time)
            self._reported = self.clock
            end = self.t0 + self.active_s
            state = "pending" if self.clock < self.t0 else "running" if self.clock < end else "idle"
            since = self.t0 if state == "running" else end if state == "idle" else 0.0
            if not self.status_history or self.status_history[-1][:2] != (state, since):
                self.status_history.append((state, since, ""))
            self.vibration_status = SimpleNamespace(state=state, since=since, time=self.clock, message=state,
                                                    event="accepted", event_stamp=self.t0, reason="")
            if state == "idle" and self.result is None:  # the planner's result once the units are at rest
                outcome, correction = self._this_vibration(self.outcome), self._this_vibration(self.demand_correction)
                self.result = VibrationEnd(outcome, "the vibration ran as planned" if outcome == "SUCCEEDED" else
                                           "the vibration units stopped", self.active_s,
                                           35.0 * (self.active_s - 0.2), 4, correction)

    def _this_vibration(self, value):
        """``value``, or its item for the vibration under way when it is a list (one per vibrate goal)."""
        return value[min(self.vibrations - 1, len(value) - 1)] if isinstance(value, list) else value

    def send_move(self, pose):
        self.target, self.sent_at = np.asarray(pose, float), self.clock

    def move_result(self):
        """A move ends 0.2 s after it was sent: at its target, or GUARD_STOPPED 1 mm short (guard_trips)."""
        if self.target is None or self.clock - self.sent_at <= 0.2:
            return None
        if self.guard_trips:
            return MoveResult("GUARD_STOPPED", "force guard tripped: force", 1e-3, 0.0, 55.0, 1.0, 0.2)
        return MoveResult(self.move_outcome, "at the target", 0.0, 0.0, 3.0, 0.1, 0.2)

    def ground_truth(self):
        return self.pose + self.truth_offset

    def pose_estimate(self):
        return self.pose.copy()

    def follow_poses(self, on):
        self.following.append(on)

    def guard_status(self):
        tripped = self.guard_trips and self.target is not None and self.clock > self.sent_at
        if tripped:
            return GuardStatus("tripped", 50.0, 0.0, "tripped: force", "force", self.sent_at)
        return GuardStatus("armed", 50.0, 0.0, "armed")

    def identify_units(self, frequencies_hz, output_path, timeout_s):
        self.identified.append((self.clock, list(frequencies_hz), output_path))
        self.clock += 5.2
        if self.identification == "SUCCEEDED":
            return IdentificationEnd("SUCCEEDED", f"identified: {output_path}", output_path, [])
        return IdentificationEnd(self.identification, "1 problems, first: uncertain by 9.9%", "", ["uncertain"])

    def start_vibration(self, vibration):
        self.sent_parameters = dict(vibration)
        if self.refuse:
            return VibrationStart(*self.refuse, None)
        self.vibrations, self.result = self.vibrations + 1, None
        self.t0, self.duration = self.clock + 1.0, float(vibration["duration_s"])
        self.active_s = self.duration if self.active_s is None else self.active_s
        plan = {"t0_s": self.t0, "pose": [0.0] * 6, "ramp_s": 0.2, "duration_s": self.duration, "frequency_hz": 35.0,
                "amplitude_m": 6e-5, "acceleration_g": 0.3, "direction_base": [0.0, 0.0, 1.0], "gains": [0.5] * 6,
                "leg_amplitudes_m": [3e-5] * 6}
        return VibrationStart("SUCCEEDED", "started", plan)

    def vibration_result(self):
        return self.result

    def stop_vibration(self):
        return False


def run(client, steps, **options):
    record = RunRecord()
    ScenarioSteps(client, RunOptions(progress=lambda *_: None, **options), record).run(Scenario("test", steps))
    return record


def test_each_vibration_is_identified_first_at_its_frequency_unless_control_is_off(tmp_path):
    client = ScriptedSuite()
    vibration = VibrateStep({"duration_s": 2.0, "frequency_hz": 40.0})
    record = run(client, [vibration, vibration], out_dir=tmp_path)
    assert [(f, p) for _, f, p in client.identified] == [([40.0], str(tmp_path / "vibration_identification_1.yaml")),
                                                        ([40.0], str(tmp_path / "vibration_identification_2.yaml"))]
    assert client.identified[0][0] < record.vibrations[0]["start_time"]  # before its vibration
    assert [i["outcome"] for i in record.identifications] == ["SUCCEEDED"] * 2
    off = ScriptedSuite()
    record = run(off, [vibration], vibration_control="off")
    assert off.identified == [] and record.identifications == [] and len(record.vibrations) == 1


@pytest.mark.parametrize("correction, outcomes", [(0.05, ["REUSED", "REUSED"]),
                                                  (0.35, ["REUSED"] + ["SUCCEEDED"] * 3)])
def test_a_given_identification_is_reused_where_it_holds_until_the_loop_finds_it_stale(tmp_path, correction,
                                                                                         outcomes):
    """identification_file: a vibration at its pose and within its frequencies reuses it (no identification
    run); a closed loop that moved the demands more than 20 % from its feed-forward marks it stale, and the
    units are identified again at once (and before each vibration from then on, as without a file; this
    script's loop reports the same correction every time, so each vibration's file is found stale too)."""
    from test_compensation import linear_identification

    from stewart_vibration import load_robot
    from stewart_vibration.paper import paper_pose
    from stewart_vibration.vibration.unit_identification import save_identification

    pose = paper_pose(load_robot())
    path = save_identification(tmp_path / "given.yaml", linear_identification(load_robot(), pose))
    client = ScriptedSuite(demand_correction=correction)
    vibration = VibrateStep({"duration_s": 2.0, "frequency_hz": 35.0})
    record = run(client, [MoveStep("paper", pose), vibration, vibration], out_dir=tmp_path, identification_file=path)
    assert [i["outcome"] for i in record.identifications] == outcomes
    first = record.vibrations[0]
    assert first["demand_correction"] == correction
    if correction > 0.2:
        assert "35%" in first["stale_identification"] and "no longer describes the robot" in \
            first["stale_identification"]
        assert client.identified[0][0] > first["t0"] + 2.0  # after the stale file's vibration
    else:
        assert client.identified == [] and "stale_identification" not in first
    # elsewhere (5 mm off its pose) or at a frequency it does not cover, the run identifies
    for target, frequency in ((pose + np.r_[0.005, 0, 0, 0, 0, 0], 35.0), (pose, 50.0)):
        elsewhere = ScriptedSuite()
        record = run(elsewhere, [MoveStep("pose", target), VibrateStep({"duration_s": 2.0, "frequency_hz": frequency})],
                     out_dir=tmp_path, identification_file=path)
        assert [i["outcome"] for i in record.identifications] == ["SUCCEEDED"] and len(elsewhere.identified) == 1


def test_a_vibration_the_loop_could_not_hold_fails_saying_the_identification_was_stale(tmp_path):
    client = ScriptedSuite(outcome="DELIVERY_LIMIT", demand_correction=0.4)
    with pytest.raises(StepFailed, match=r"DELIVERY_LIMIT.*moved the legs' demands by 40% .*no longer describes"):
        run(client, [VibrateStep({"duration_s": 2.0, "frequency_hz": 35.0})], out_dir=tmp_path)


def test_a_vibration_failed_by_a_stale_reused_identification_runs_again_on_a_fresh_one(tmp_path):
    """The given file holds at the pose but proves stale: its vibration ends DELIVERY_LIMIT (the loop could not
    hold it); the units are identified here and the vibration runs again, and succeeds; both attempts are in
    the record. A vibration that fails on a fresh identification is not run again."""
    from test_compensation import linear_identification

    from stewart_vibration import load_robot
    from stewart_vibration.paper import paper_pose
    from stewart_vibration.vibration.unit_identification import save_identification

    pose = paper_pose(load_robot())
    path = save_identification(tmp_path / "given.yaml", linear_identification(load_robot(), pose))
    steps = [MoveStep("paper", pose), VibrateStep({"duration_s": 2.0, "frequency_hz": 35.0})]
    client = ScriptedSuite(outcome=["DELIVERY_LIMIT", "SUCCEEDED"], demand_correction=[0.4, 0.01])
    record = run(client, steps, out_dir=tmp_path, identification_file=path)
    assert [i["outcome"] for i in record.identifications] == ["REUSED", "SUCCEEDED"]
    failed, again = record.vibrations
    assert "DELIVERY_LIMIT" in failed["failure"] and "no longer describes" in failed["stale_identification"]
    assert "failure" not in again and again["outcome"] == "SUCCEEDED" and again["t0"] > client.identified[0][0]
    fresh = ScriptedSuite(outcome="DELIVERY_LIMIT", demand_correction=0.4)
    with pytest.raises(StepFailed, match="DELIVERY_LIMIT"):
        run(fresh, steps, out_dir=tmp_path)
    assert fresh.vibrations == 1


def test_a_rejected_identification_fails_the_step_before_anything_vibrates(tmp_path):
    client = ScriptedSuite(identification="IDENTIFICATION_REJECTED")
    with pytest.raises(StepFailed, match="IDENTIFICATION_REJECTED"):
        run(client, [VibrateStep({"duration_s": 2.0, "frequency_hz": 35.0})], out_dir=tmp_path)
    assert client.sent_parameters == {}  # no vibrate goal


def test_moves_settle_and_vibrations_are_recorded_with_the_settings_that_ran():
    client = ScriptedSuite()
    record = run(client, [MoveStep("home", np.r_[0, 0, 0.16, 0, 0, 0]),
                          VibrateStep({"duration_s": 2.0, "frequency_hz": 35.0})])
    assert record.moves[0]["pose_error_m"] == 0.0 and client.following == [True, False]
    vib = record.vibrations[0]
    assert vib["parameters"]["plan"]["ramp_s"] == 0.2 and vib["parameters"]["duration_s"] == 2.0  # the plan's
    assert vib["t0"] == pytest.approx(vib["start_time"] + 1.0) and vib["status_active_s"] == pytest.approx(2.0)
    assert vib["outcome"] == "SUCCEEDED" and vib["cycles_delivered"] == pytest.approx(35.0 * 1.8)
    assert "failure" not in vib


def test_a_move_settles_on_the_controllers_estimate_and_records_the_truths_error():
    """On the robot as built the truth misses the target the estimate holds (geometry errors): the move settles
    (the runner waits on the robot's own view) and its judged error is the truth's, the estimate's beside it."""
    client = ScriptedSuite(truth_offset=[3e-4, 0, -2e-4, 0, np.radians(0.02), 0])
    record = run(client, [MoveStep("home", np.r_[0, 0, 0.16, 0, 0, 0])])
    move = record.moves[0]
    assert move["pose_error_m"] == pytest.approx(3e-4) and move["pose_error_deg"] == pytest.approx(0.02)
    assert move["estimate_error_m"] == 0.0 and move["estimate_error_deg"] == 0.0


def test_a_short_vibration_or_a_refused_start_fails_the_step():
    client = ScriptedSuite(active_s=1.0)
    with pytest.raises(StepFailed, match="ended 1.000 s early"):
        run(client, [VibrateStep({"duration_s": 2.0, "frequency_hz": 35.0})])
    with pytest.raises(StepFailed, match=r"vibration start refused \(LIMIT_EXCEEDED\): infeasible"):
        run(ScriptedSuite(refuse=("LIMIT_EXCEEDED", "infeasible vibration (VibrationLimitError): ...")),
            [VibrateStep({"duration_s": 2.0, "frequency_hz": 35.0})])
    with pytest.raises(StepFailed, match=r"the planner ended the vibration \(STOPPED_EARLY\)"):
        run(ScriptedSuite(outcome="STOPPED_EARLY"), [VibrateStep({"duration_s": 2.0, "frequency_hz": 35.0})])


def test_a_guarded_move_must_be_stopped_by_the_force_guard():
    target = np.r_[0, 0, 0.17, 0, 0, 0]
    record = run(ScriptedSuite(guard_trips=True), [MoveStep("guarded", target, guarded=True)])
    stop = record.guard_stops[0]
    assert stop["short_of_target_m"] == pytest.approx(1e-3) and stop["peak_force_n"] == 55.0
    with pytest.raises(StepFailed, match="the force guard did not stop the move"):
        run(ScriptedSuite(guard_trips=False), [MoveStep("guarded", target, guarded=True)])
    with pytest.raises(StepFailed, match="ended CANCELED"):
        run(ScriptedSuite(move_outcome="CANCELED"), [MoveStep("guarded", target, guarded=True)])


def test_a_move_that_does_not_succeed_fails_its_step_with_the_outcome():
    with pytest.raises(StepFailed, match=r"the move to home ended TIMEOUT: at the target"):
        run(ScriptedSuite(move_outcome="TIMEOUT"), [MoveStep("home", np.r_[0, 0, 0.16, 0, 0, 0])])


def test_the_start_is_judged_from_a_report_from_t0_on():
    """Faster than real time the emulator's reports (10 Hz of wall time) are sparse in sim time: at t0 + ramp the
    newest one can still say 'pending'; the step waits for a report from t0 on and finds the start in the state
    changes seen. A vibration that never began still fails."""
    client = ScriptedSuite(report_period_s=0.45)  # reports at 0.9 (pending), 1.35 (running) around t0 = 1.01
    record = run(client, [VibrateStep({"duration_s": 2.0, "frequency_hz": 35.0})])
    assert "failure" not in record.vibrations[0]
    with pytest.raises(StepFailed, match="did not begin"):
        run(ScriptedSuite(active_s=0.0, report_period_s=0.45), [VibrateStep({"duration_s": 2.0, "frequency_hz": 35.0})])
