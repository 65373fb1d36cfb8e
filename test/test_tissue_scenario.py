"""The tissue scenario as a user runs it: ``./tools/main --scenario config/scenario_tissue.yaml``.

A module of its own: test_tissue_dds.py keeps a second suite of nodes up for its whole module (a module
fixture), and this run beside it measured the guard on a machine with two suites sharing two cores
(estimates 0.2-1.6 s behind the states, CI).
"""

from __future__ import annotations

from pathlib import Path

import pytest

pytestmark = pytest.mark.integration


@pytest.mark.slow
def test_tissue_scenario_runs_within_its_bounds(tmp_path, ros_domain):
    """./tools/main --scenario config/scenario_tissue.yaml as a user runs it: every step done (the guarded move
    stopped by the guard), every figure within its bounds, the tissue figures and the report's plot there."""
    from test_main_job import passing_summary

    out = tmp_path / "run"
    scenario = Path(__file__).resolve().parents[1] / "stewart_vibration" / "config" / "scenario_tissue.yaml"
    summary, stdout = passing_summary(out, ros_domain, "--scenario", str(scenario), "--duration", "1.2")
    tissue = summary["tissue"]
    assert tissue["moves_holds"]["relative_force"] <= 0.02 and tissue["vibration"]["rms_force_error_n"] <= 1.0
    (trip,) = [t for t in tissue["guard"] if t["limit"] != "estimates"]  # besides any pause while estimates lagged
    assert trip["limit"] == "force" and trip["overshoot"] <= 0.10
    assert all(t["peak_applied_force_n"] <= 1.1 * 200 for t in tissue["guard"])  # pauses included
    (stop,) = summary["guard_stops"]
    assert stop["short_of_target_m"] > 1e-3
    assert "force guard tripped" in stdout and "soft tissue" in stdout
    assert (Path(summary["report_dir"]) / "tissue_wrench.png").is_file()
