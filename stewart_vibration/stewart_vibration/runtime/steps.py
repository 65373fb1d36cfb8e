"""The scenario's steps as the main job runs them (no rclpy): move, guarded move, vibrate.

The steps drive the suite through a client (``suite_interface.SuiteClient``: the ROS side,
``nodes.suite_client``) and record what happened in a ``RunRecord`` (``run_options``). Every wait is on
something observable (an action's result, the emulator's ground truth, vibration/status,
kinematics/guard_status, the sim clock), never a fixed sleep.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, cast

import numpy as np

from ..analysis.reduction_accuracy import fracture_residual
from ..vibration.compensation import identification_misses
from ..vibration.sine_control import SineControlLimits, stale_identification
from ..vibration.unit_identification import load_identification
from .run_options import RunOptions, RunRecord
from .scenario import DEFAULT_FRACTURE_SITE_M, MoveStep, Scenario, VibrateStep
from .sim_clock import HeldFor, StillFor
from .suite_interface import MoveResult, StepFailed, SuiteClient, VibrationEnd

IDENTIFICATION_TIMEOUT_S = 120.0  # wall s for one identification at one frequency (~6 s of sim time)
SETTLE_AFTER_VIBRATION_S = 0.5  # sim s between a vibration's end and the next step (a move)
SETTLE_HOLD_S = 0.5  # a move is done when the ground truth held within tolerance this long (sim s)


class ScenarioSteps:
    """Runs a scenario's steps through ``client``; results go to ``record``."""

    def __init__(self, client: SuiteClient, options: RunOptions, record: RunRecord):
        self.client, self.options, self.record = client, options, record
        self.fracture_site = np.array(DEFAULT_FRACTURE_SITE_M)  # the scenario's, once run
        self.identified = False  # this run identified: the planner plans with the run's own file from then on

    def run(self, scenario: Scenario) -> RunRecord:
        """Run the scenario's steps in order; returns the record. Raises StepFailed at a step that fails."""
        self.fracture_site = np.array(scenario.fracture_site_m, float)
        for index, step in enumerate(scenario.steps, start=1):
            label = f"step {index}/{len(scenario.steps)}"
            if isinstance(step, MoveStep):
                self.move_to(step, label)
            elif isinstance(step, VibrateStep):
                self.vibrate(step, label)
        return self.record

    # -- moves ---------------------------------------------------------------------------------------------
    def move_to(self, step: MoveStep, label: str) -> None:
        """Send the target; wait until it settles (or, for a guarded move, until the force guard stops it)."""
        self.options.progress(f"{label}: move to {step.name} {np.round(step.pose, 5).tolist()}")
        start = cast(float, self.client.clock)  # the clock runs (the suite was ready)
        # the 500 Hz poses only while a move settles: the runner must not load the machine
        self.client.follow_poses(True)
        try:
            (self._guarded if step.guarded else self._settle)(step, label, start)
        finally:
            self.client.follow_poses(False)

    def _settle(self, step: MoveStep, label: str, start: float) -> None:
        """Wait until the controller's pose estimate holds within tolerance for SETTLE_HOLD_S of sim time (what a
        user at the robot sees: the robot's own view), and the ground truth has a sample since; record the
        ground truth's error (the judged figure) and the estimate's."""
        opts, client = self.options, self.client
        client.send_move(step.pose)
        client.spin_until(lambda: client.move_result() is not None, opts.step_timeout_s,
                          f"the move to {step.name} to end")
        result = cast(MoveResult, client.move_result())
        if result.outcome != "SUCCEEDED":
            raise StepFailed(f"the move to {step.name} ended {result.outcome}: {result.message}")
        held = HeldFor(SETTLE_HOLD_S)

        def settled():
            pose = client.pose_estimate()
            if pose is None or client.clock is None or client.clock < start + 0.1 or client.ground_truth() is None:
                return False
            err = pose - step.pose
            ok = np.abs(err[:3]).max() < opts.settle_tolerance_m and np.abs(err[3:]).max() < opts.settle_tolerance_rad
            return held.update(bool(ok), client.clock)

        client.spin_until(settled, opts.step_timeout_s, f"the platform to settle at {step.name}")
        truth = cast(np.ndarray, client.ground_truth())
        err = truth - step.pose
        believed = cast(np.ndarray, client.pose_estimate()) - step.pose
        fracture = fracture_residual(truth, step.pose, self.fracture_site).record()
        self.record.moves.append({
            "name": step.name, "target": step.pose.tolist(), "time": client.clock,
            "pose_error_m": float(np.abs(err[:3]).max()), "pose_error_deg": float(np.degrees(np.abs(err[3:]).max())),
            "estimate_error_m": float(np.abs(believed[:3]).max()),
            "estimate_error_deg": float(np.degrees(np.abs(believed[3:]).max())),
            "outcome": result.outcome, "peak_force_n": result.peak_force_n, "move_duration_s": result.duration_s,
            **fracture,
        })
        opts.progress(f"{label}: settled at {step.name} in {cast(float, client.clock) - start:.2f} s sim; "
                      f"ground-truth error {np.abs(err[:3]).max() * 1e6:.3f} um, "
                      f"{np.degrees(np.abs(err[3:]).max()):.5f} deg; the controller's estimate "
                      f"{np.abs(believed[:3]).max() * 1e6:.3f} um, {np.degrees(np.abs(believed[3:]).max()):.5f} deg; "
                      f"at the fracture site {fracture['fracture_displacement_mm']:.3f} mm, angulation "
                      f"{fracture['fracture_angulation_deg']:.4f} deg, rotation "
                      f"{fracture['fracture_rotation_deg']:.4f} deg")

    def _guarded(self, step: MoveStep, label: str, start: float) -> None:
        """A move the force guard must stop: its goal must end GUARD_STOPPED (the struts at rest short of the
        target); then the platform must be at rest (SETTLE_HOLD_S of sim time still)."""
        opts, client = self.options, self.client
        client.send_move(step.pose)
        client.spin_until(lambda: client.move_result() is not None, opts.step_timeout_s,
                          "the force guard to stop the move")
        result = cast(MoveResult, client.move_result())
        if result.outcome == "SUCCEEDED":
            raise StepFailed(f"the force guard did not stop the move to {np.round(step.pose, 5).tolist()}: the "
                             "platform reached the target")
        if result.outcome != "GUARD_STOPPED":
            raise StepFailed(f"the guarded move to {np.round(step.pose, 5).tolist()} ended {result.outcome}: "
                             f"{result.message}")
        still = StillFor(SETTLE_HOLD_S)

        def at_rest():
            pose = client.ground_truth()
            return pose is not None and still.update(pose, cast(float, client.clock))

        client.spin_until(at_rest, opts.step_timeout_s, "the platform to come to rest after the guard stop")
        held = cast(np.ndarray, still.anchor)  # at rest: where it came to rest
        guard = client.guard_status()
        record = {"target": step.pose.tolist(), "time": client.clock,
                  "guard": guard.record() if guard is not None else {}, "stopped_pose": held.tolist(),
                  "short_of_target_m": float(np.linalg.norm(step.pose[:3] - held[:3])),
                  "peak_force_n": result.peak_force_n, "peak_moment_nm": result.peak_moment_nm}
        message = result.message
        self.record.guard_stops.append(record)
        opts.progress(f"{label}: the force guard stopped the move as expected: {message}; "
                      f"held {record['short_of_target_m'] * 1e3:.2f} mm short of the target")

    # -- vibration -----------------------------------------------------------------------------------------
    def identify(self, step: VibrateStep, label: str) -> None:
        """Identify the vibration units here at the vibration's frequency (the planner then plans with the
        file, which is kept in the run's folder); a refused or rejected identification fails the step."""
        frequency = float(step.parameters["frequency_hz"])
        number = len(self.record.identifications) + 1
        path = Path(self.options.out_dir).resolve() / f"vibration_identification_{number}.yaml"
        self.options.progress(f"{label}: identifying the vibration units at {frequency:g} Hz")
        end = self.client.identify_units([frequency], str(path), IDENTIFICATION_TIMEOUT_S / max(
            self.options.real_time_factor, 0.05))
        self.record.identifications.append({"label": label, "frequency_hz": frequency, "outcome": end.outcome,
                                            "message": end.message, "path": end.path, "problems": end.problems})
        if end.outcome != "SUCCEEDED":
            raise StepFailed(f"identification of the vibration units ({end.outcome}): {end.message}")
        self.identified = True
        self.options.progress(f"{label}: identified: {end.message}")

    def reuse_identification(self, step: VibrateStep, label: str) -> bool:
        """Whether the identification the run was given (``identification_file``, the planner's from its start)
        holds for this vibration: the pose of the last move (within the feed-forward's tolerances) and the
        frequency. Once this run identified, the planner plans with the run's own file instead."""
        path = self.options.identification_file
        if path is None or self.identified or not self.record.moves:
            return False
        frequency = float(step.parameters["frequency_hz"])
        why_not = identification_misses(load_identification(path), np.asarray(self.record.moves[-1]["target"]),
                                        frequency)
        if why_not:
            self.options.progress(f"{label}: {path} does not hold here ({why_not}); identifying the units")
            return False
        self.record.identifications.append({"label": label, "frequency_hz": frequency, "outcome": "REUSED",
                                            "message": f"reused {path}", "path": str(path), "problems": []})
        self.options.progress(f"{label}: reusing the identification {path} (it holds at this pose and frequency)")
        return True

    def vibrate(self, step: VibrateStep, label: str) -> None:
        """Identify the vibration units here (or reuse the run's identification where it holds), then run the
        vibration (``_vibrate``). A vibration on a reused identification that failed because the file proved
        stale (its closed loop could not hold the vibration) runs once more on a fresh identification: the
        failed attempt stays in the record."""
        opts, client = self.options, self.client
        reused = opts.vibration_control != "off" and self.reuse_identification(step, label)
        if opts.vibration_control != "off" and not reused:
            self.identify(step, label)
        try:
            self._vibrate(step, label)
        except StepFailed as exc:
            if not (reused and self.record.vibrations and self.record.vibrations[-1].get("stale_identification")):
                raise
            opts.progress(f"{label}: {exc}; identifying the vibration units here and vibrating again")
            client.spin_until(lambda: client.vibration_status is not None and client.vibration_status.state in (
                "idle", "stopped"), 30 / max(opts.real_time_factor, 0.05), "the units to come to rest")
            self.identify(step, label)
            self._vibrate(step, label)

    def _vibrate(self, step: VibrateStep, label: str) -> None:
        """Send the planner's vibrate goal and follow the emulator's vibration/status until the vibration is
        over; a refusal, an outcome other than SUCCEEDED or a vibration shorter than planned fails the step. The
        record keeps the settings and the plan the planner ran, which the summary judges against; a closed loop
        that found its identification stale (``stale_identification``) is said with it, and after a vibration
        that ran the units are identified again (the next vibration's file)."""
        opts, client = self.options, self.client
        start = client.clock  # before the goal: a lower bound of its t0 (the summary finds the windows from it)
        started = client.start_vibration(step.parameters)
        if started.plan is None:
            raise StepFailed(f"vibration start refused ({started.outcome}): {started.message}")
        plan = started.plan
        ran = dict(step.parameters, t0_s=plan["t0_s"], pose=plan["pose"], plan=plan)
        t0 = float(plan["t0_s"])
        ramp, duration = float(plan["ramp_s"]), float(plan["duration_s"])
        opts.progress(f"{label}: vibrating: started: {plan['frequency_hz']:g} Hz, platform amplitude "
                      f"{plan['amplitude_m'] * 1e6:.3f} um ({plan['acceleration_g']:.3f} g) along "
                      f"{np.round(plan['direction_base'], 6).tolist()} (base frame), t0 = {t0:.6f} s, ramp {ramp} s, "
                      f"duration {duration} s; gains k = {np.round(plan['gains'], 6).tolist()}; leg amplitudes um = "
                      f"{np.round(np.asarray(plan['leg_amplitudes_m']) * 1e6, 3).tolist()}")
        record: dict[str, Any] = {"parameters": ran, "start_time": start, "t0": t0}
        self.record.vibrations.append(record)
        rtf = max(opts.real_time_factor, 0.05)

        def failed() -> str | None:
            report, ended = client.vibration_status, client.vibration_result()
            if ended is not None and ended.outcome != "SUCCEEDED":
                return f"the planner ended the vibration ({ended.outcome}): {ended.message}"
            if report is not None and report.state in ("estopped", "stopped") and report.since >= t0 - 1e-6:
                return f"the vibration units {report.message}"
            if report is not None and report.event == "refused" and report.event_stamp is not None and \
                    abs(report.event_stamp - t0) < 1e-6:
                return f"the hardware emulator {report.event_text}"
            return None

        def fail(reason: str):
            ended = client.vibration_result()
            correction = 0.0 if ended is None else ended.demand_correction
            stale = stale_identification(correction, SineControlLimits())
            if stale:  # why the loop could not hold the vibration: say so with the failure
                record["demand_correction"], record["stale_identification"] = correction, stale
                reason = f"{reason} ({stale})"
            record["failure"] = reason
            raise StepFailed(reason)

        def watch(until: float, what: str) -> None:
            client.spin_until(lambda: failed() is not None or (client.clock is not None and client.clock >= until),
                              (until - cast(float, client.clock)) / rtf + 60, what)
            if reason := failed():
                fail(reason)

        watch(t0 + ramp, "the vibration to begin")
        # the emulator reports at 10 Hz of wall time: faster than real time the newest report may predate t0, so
        # wait for one from t0 on and look for the start among the state changes seen (a short ramp-in can fall
        # between two reports)
        client.spin_until(lambda: failed() is not None or (client.vibration_status is not None and
                                                            client.vibration_status.time >= t0), 10.0,
                          "a vibration report from t0 on")
        report = client.vibration_status
        began = any(state in ("ramping_in", "running") and since >= t0 - 0.01
                    for state, since, _reason in client.status_history)
        if report is None or not began:
            fail(f"the vibration did not begin at t0 = {t0:.3f} s: the emulator reports "
                 f"{report.message if report else 'nothing (no vibration/status)'}")
        watch(t0 + duration, "the vibration to finish")
        client.spin_until(lambda: failed() is not None or (client.vibration_status is not None and
                                                            client.vibration_status.state in ("idle", "stopped")),
                          30 / rtf, "the units to come to rest")
        if reason := failed():
            fail(reason)
        client.spin_until(lambda: client.vibration_result() is not None, 30 / rtf,
                          "the planner's result of the vibration")
        if reason := failed():
            fail(reason)
        result = cast(VibrationEnd, client.vibration_result())
        record["outcome"] = result.outcome
        record["planner_active_s"], record["cycles_delivered"] = result.active_s, result.cycles_delivered
        record["loop_corrections"] = result.loop_corrections
        record["stop_time"] = client.clock
        ended = client.vibration_status.since
        record["status_active_s"] = ended - t0
        loop = f"; the closed loop sent {result.loop_corrections} corrections" if result.loop_corrections else ""
        opts.progress(f"{label}: vibration done: the emulator reports the units active from t0 = {t0:.3f} s to "
                      f"{ended:.3f} s ({ended - t0:.3f} s of the planned {duration:.3f} s){loop}")
        client.wait_sim(SETTLE_AFTER_VIBRATION_S, "the platform to settle after the vibration")
        if ended < t0 + duration - 0.05:
            fail(f"the vibration ended {t0 + duration - ended:.3f} s early: {client.vibration_status.message}")
        record["demand_correction"] = result.demand_correction
        stale = stale_identification(result.demand_correction, SineControlLimits())
        if stale and opts.vibration_control == "closed_loop":  # the dose was corrected; what follows needs a new one
            record["stale_identification"] = stale
            opts.progress(f"{label}: {stale}; identifying the vibration units again")
            self.identify(step, label)
