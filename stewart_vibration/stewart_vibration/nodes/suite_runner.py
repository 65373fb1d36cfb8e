"""Bring-up of the whole suite in the pip world (what `stewart-vibration run` does).

Starts every node as its own process on sim time in one namespace and ROS domain (``runtime.bringup``),
waits until each is ready (topics flowing, services up: no fixed sleeps; ``suite_client``), runs a
scenario (move, vibrate, return: ``runtime.steps``), stops the recorder so the MCAP is finished, stops
every process (SIGINT, then SIGTERM/SIGKILL), and keeps the MCAP path and the event times for the summary.
"""

from __future__ import annotations

import glob
import os
from pathlib import Path
from typing import cast

from ..runtime.bringup import SuiteProcesses
from ..runtime.rest_check import RestCheck
from ..runtime.run_options import RunOptions, RunRecord
from ..runtime.scenario import Scenario
from ..runtime.steps import SETTLE_HOLD_S, ScenarioSteps
from ..runtime.suite_interface import StepFailed
from .suite_client import SuiteClient

__all__ = ["RunOptions", "RunRecord", "StepFailed", "SuiteRunner"]


class SuiteRunner:
    """The run's processes, its ROS client and the scenario's steps, started and stopped together."""

    def __init__(self, options: RunOptions):
        self.options = options
        self.record = RunRecord()
        self.processes = SuiteProcesses(options, self.record)
        self.client: SuiteClient | None = None

    def start(self) -> None:
        self.processes.start()
        opts = self.options
        self.client = SuiteClient(opts.namespace, opts.domain_id, opts.real_time_factor, self.processes.dead,
                                  self.record.log_dir)

    # wait_ready, run, call and supervise come after start, which creates the client
    def wait_ready(self) -> None:
        """Wait until every node works; the recording is judged complete from the moment the recorder records
        the states (``recording_span``)."""
        client = cast(SuiteClient, self.client)
        try:
            client.wait_ready(self.options.progress)
        finally:
            self.record.recording_span[0] = client.recorder_ready_clock

    def run(self, scenario: Scenario) -> RunRecord:
        return ScenarioSteps(cast(SuiteClient, self.client), self.options, self.record).run(scenario)

    def call(self, srv_type, name: str, request, timeout: float = 30.0):
        return cast(SuiteClient, self.client).call(srv_type, name, request, timeout)

    def log_lines(self, node: str, marker: str) -> list[str]:
        return self.processes.log_lines(node, marker)

    def recent_problems(self, per_node: int = 5) -> list[str]:
        return self.processes.recent_problems(per_node)

    def supervise(self, respawn: set[str]) -> None:
        """--keep-running: restart nodes that exit (``SuiteProcesses.supervise``); a recorder write failure is
        said at once and fails the run (the user's session goes on)."""
        client = cast(SuiteClient, self.client)

        def idle() -> None:
            client.spin_once()
            if client.recording_failed():
                client.stopping = True  # said once
                self.options.progress(f"the recorder stopped recording: {client.recorder_fault}")
                self.record.failures.append(f"the recording failed: {client.recorder_fault}")

        self.processes.supervise(respawn, idle=idle, now=lambda: client.clock)

    def bring_to_rest(self, timeout_s: float = 60.0) -> None:
        """After a failed step: start nothing more, stop the vibration (the planner's ramp-out) and wait until its
        goal has ended, the units are idle and the platform's ground truth holds still (a move under way ends at
        its target), so the nodes are stopped with the robot at rest. Says so, or why it could not confirm it."""
        client, progress = self.client, self.options.progress
        if client is None:
            return
        progress("stopping the scenario safely: no further moves, the vibration ramps out, waiting for the robot "
                 "to come to rest")
        client.stopping = True
        try:
            # the goal, not the units' status: a vibration still waiting for its t0 has idle units
            if client.stop_vibration():
                progress("the vibration is cancelled: the units ramp out")
            client.follow_poses(True)
            rest = RestCheck(SETTLE_HOLD_S)

            def at_rest() -> bool:
                status = client.vibration_status
                return rest.update(client.vibration_goal_open(), None if status is None else status.state,
                                   client.ground_truth(), client.clock)

            client.spin_until(at_rest, timeout_s, "the robot to come to rest")
            progress("the robot is at rest (vibration units idle, platform still)")
        except (StepFailed, RuntimeError) as exc:
            progress(f"could not confirm the robot at rest: {exc}")
        finally:
            client.follow_poses(False)

    def stop(self) -> None:
        """Stop the recorder (finishes the MCAP), then every process; close the client."""
        path = None
        if self.client is not None:
            self.record.recording_span[1] = self.client.clock
            answer = self.client.stop_recorder(self.options.progress)
            path = Path(answer) if answer else None
        self.processes.stop()
        if self.client is not None:
            if self.client.recorder_fault is not None:  # also when the recorder could not log its counts
                self.record.failures.append(f"the recording failed: {self.client.recorder_fault}")
            self.client.close()
            self.client = None
        if path is None or not path.exists():
            files = sorted(glob.glob(str(Path(self.options.out_dir) / "*.mcap")), key=os.path.getmtime)
            path = Path(files[-1]) if files else None
        self.record.mcap_path = path
