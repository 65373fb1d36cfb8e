"""The fast tier (``./tools/test --fast``): every test that starts no ROS node process and is not marked slow,
and nothing else; CI runs the whole suite (test_readme_commands checks that .ci/run runs ``./tools/test``)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # it collects the suite three times

ROOT = Path(__file__).resolve().parents[1]


def collected(command: list[str]) -> set[str]:
    env = dict(os.environ, STEWART_VENV=sys.prefix, STEWART_VENV_NO_INSTALL="1")
    result = subprocess.run(command + ["--collect-only", "-q"], cwd=ROOT, env=env, text=True, timeout=300,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    assert result.returncode == 0, result.stdout[-3000:]
    return {line for line in result.stdout.splitlines() if line.startswith("test/") and "::" in line}


def test_the_fast_tier_is_every_test_without_nodes_and_not_slow():
    pytest_cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider"]
    fast = collected(["bash", "tools/test", "--fast"])
    everything = collected(pytest_cmd)
    left_out = collected(pytest_cmd + ["-m", "integration or slow"])
    assert len(fast) > 1000 and fast == everything - left_out
    assert not any("test_test_tiers.py" in test for test in fast)
