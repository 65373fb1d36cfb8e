"""Values in the suite's params file reach the nodes as the bring-up starts them (the old
`hardware_emulator:` keys never matched /stewart/hardware_emulator, so only use_sim_time applied)."""

from __future__ import annotations

import pytest
import yaml
from rcl_interfaces.srv import GetParameters

from stewart_vibration.install import default_config_dir
from stewart_vibration.nodes.suite_runner import RunOptions, SuiteRunner
from stewart_vibration.runtime.suite import SUITE_PARAMS_FILE

pytestmark = pytest.mark.integration

CHANGED = {  # (node, parameter): a value unlike its default
    ("kinematics", "speed_scale"): 0.37,
    ("hardware_emulator", "watchdog_s"): 0.7,
    ("vibration_planner", "lookahead_s"): 2.5,
    ("leg_force_estimator", "rms_window_s"): 2.0,
    ("mcap_recorder", "flush_period_s"): 0.4,
}


def test_params_file_values_reach_every_node(tmp_path, ros_domain):
    tree = yaml.safe_load((default_config_dir() / SUITE_PARAMS_FILE).read_text())
    for (node, name), value in CHANGED.items():
        # the shipped block of that node, whatever its key (a key that does not match the node fails here)
        key = next((k for k in tree if k.rstrip("/").split("/")[-1] == node), f"/**/{node}")
        tree.setdefault(key, {"ros__parameters": {}})["ros__parameters"][name] = value
    params = tmp_path / "suite_params.yaml"
    params.write_text(yaml.safe_dump(tree))
    runner = SuiteRunner(RunOptions(domain_id=ros_domain, out_dir=tmp_path / "run", params_file=params,
                                    progress=lambda *_: None))
    try:
        runner.start()
        runner.wait_ready()
        for (node, name), value in CHANGED.items():
            response = runner.call(GetParameters, f"{node}/get_parameters", GetParameters.Request(names=[name]))
            assert response.values[0].double_value == pytest.approx(value), (node, name)
        sim = runner.call(GetParameters, "kinematics/get_parameters", GetParameters.Request(names=["use_sim_time"]))
        assert sim.values[0].bool_value  # the /** block applies too
    finally:
        runner.stop()
