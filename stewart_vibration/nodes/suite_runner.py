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
from ..runtime.scenario import Scenario
from ..runtime.steps import RunOptions, RunRecord, ScenarioSteps, StepFailed
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
        cast(SuiteClient, self.client).wait_ready(self.options.progress)

    def run(self, scenario: Scenario) -> RunRecord:
        return ScenarioSteps(cast(SuiteClient, self.client), self.options, self.record).run(scenario)

    def call(self, srv_type, name: str, request, timeout: float = 30.0):
        return cast(SuiteClient, self.client).call(srv_type, name, request, timeout)

    def log_lines(self, node: str, marker: str) -> list[str]:
        return self.processes.log_lines(node, marker)

    def recent_problems(self, per_node: int = 5) -> list[str]:
        return self.processes.recent_problems(per_node)

    def supervise(self, respawn: set[str]) -> None:
        self.processes.supervise(respawn, idle=cast(SuiteClient, self.client).spin_once)

    def stop(self) -> None:
        """Stop the recorder (finishes the MCAP), then every process; close the client."""
        path = None
        if self.client is not None:
            answer = self.client.stop_recorder(self.options.progress)
            path = Path(answer) if answer else None
        self.processes.stop()
        if self.client is not None:
            self.client.close()
            self.client = None
        if path is None or not path.exists():
            files = sorted(glob.glob(str(Path(self.options.out_dir) / "*.mcap")), key=os.path.getmtime)
            path = Path(files[-1]) if files else None
        self.record.mcap_path = path
