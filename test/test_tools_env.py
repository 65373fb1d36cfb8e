"""`source tools/env.sh` sets up a user's interactive shell without changing its options (issue 15): a
failing command afterwards must not close the terminal, and the suite's executables are on PATH."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration  # starts a shell

REPO = Path(__file__).resolve().parents[1]


def test_sourcing_env_keeps_the_shell_options_and_sets_up_the_tools():
    script = f"""
    set +euo pipefail
    before="$-"
    source "{REPO}/tools/env.sh"
    after="$-"
    false
    echo "survived a failing command"
    echo "options before=$before after=$after"
    command -v stewart-vibration
    command -v hardware_emulator_node
    echo "AMENT_PREFIX_PATH=$AMENT_PREFIX_PATH"
    """
    out = subprocess.run(["bash", "-c", script], capture_output=True, text=True, timeout=600).stdout
    assert "survived a failing command" in out
    line = next(x for x in out.splitlines() if x.startswith("options before="))
    before, after = (part.split("=")[1] for part in line.split()[1:])
    assert before == after, line
    assert "/lib/stewart_vibration/stewart-vibration" in out and "hardware_emulator_node" in out
    assert ".venv" in next(x for x in out.splitlines() if x.startswith("AMENT_PREFIX_PATH="))
