"""`source tools/env.sh` sets up a user's interactive shell without changing its options: a
failing command afterwards must not close the terminal, and the suite's executables are on PATH."""

from __future__ import annotations

import os
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


def test_the_interfaces_build_says_what_it_needs_when_the_machine_has_no_compiler(tmp_path):
    """Without cmake or a compiler the set-up stops with one line naming the fix, before colcon runs."""
    script = f"""
    source "{REPO}/tools/env.sh" >/dev/null 2>&1 || exit 3
    PATH="{tmp_path}" _stewart_interfaces "{REPO}" "{tmp_path / 'venv'}"
    echo "status=$?"
    """
    proc = subprocess.run(["bash", "-c", script], capture_output=True, text=True, timeout=600)
    assert "status=1" in proc.stdout, proc.stdout + proc.stderr
    assert "needs cmake and a C and C++ compiler" in proc.stderr and "apt-get install -y g++ cmake" in proc.stderr
    assert not (tmp_path / "venv" / ".interfaces.sha").exists()


def test_the_venv_has_the_interfaces_package_and_colcon_finds_the_venv():
    """After `source tools/env.sh`: the suite's actions import, ament knows the package (what `ros2 interface`
    reads), and CMAKE_PREFIX_PATH holds the venv (an ament_cmake build finds the ROS packages there)."""
    script = f"""
    source "{REPO}/tools/env.sh" >/dev/null 2>&1 || exit 3
    echo "CMAKE_PREFIX_PATH=$CMAKE_PREFIX_PATH"
    python -c "
from ament_index_python.packages import get_package_share_directory
from stewart_vibration_interfaces.action import MoveToPose, Vibrate
print('share', get_package_share_directory('stewart_vibration_interfaces'))
print('goal', Vibrate.Goal().frame == '', MoveToPose.Result().outcome.code == MoveToPose.Result().outcome.UNDEFINED)
"
    """
    out = subprocess.run(["bash", "-c", script], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    assert ".venv" in next(x for x in out.stdout.splitlines() if x.startswith("CMAKE_PREFIX_PATH="))
    share = next(x for x in out.stdout.splitlines() if x.startswith("share "))
    assert (Path(share.split(" ", 1)[1]) / "action" / "Vibrate.action").is_file()
    assert "goal True True" in out.stdout


def test_the_venv_registers_the_package_as_ros2_run_and_launch_look_it_up():
    """After `source tools/env.sh` the ament index knows stewart_vibration (the lookup ros2cli's run, pkg and
    launch verbs do): its prefix holds lib/stewart_vibration/<node executables> and its share folder the
    package.xml, the launch file and the config; the test shim's `ros2 run` goes through the same lookup and
    says "Package ... not found" like ros2cli for a package the index does not know."""
    script = f"""
    source "{REPO}/tools/env.sh" >/dev/null 2>&1 || exit 3
    python -c "
from ament_index_python.packages import get_package_prefix, get_package_share_directory
print('prefix', get_package_prefix('stewart_vibration'))
print('share', get_package_share_directory('stewart_vibration'))
"
    python "{REPO}/test/ros2_shim.py" run no_such_package some_node; echo "status=$?"
    python "{REPO}/test/ros2_shim.py" run stewart_vibration stewart-vibration --help | head -1
    """
    out = subprocess.run(["bash", "-c", script], capture_output=True, text=True, timeout=600)
    lines = out.stdout.splitlines()
    prefix = Path(next(x for x in lines if x.startswith("prefix ")).split(" ", 1)[1])
    share = Path(next(x for x in lines if x.startswith("share ")).split(" ", 1)[1])
    for exe in ("hardware_emulator_node", "kinematics_node", "vibration_planner_node", "leg_force_estimator_node",
                "mcap_recorder", "mcap_replay", "planning_ui", "foxglove_bridge"):
        assert (prefix / "lib" / "stewart_vibration" / exe).is_file(), exe
    assert (share / "package.xml").is_file() and (share / "launch" / "stewart_vibration.launch.py").is_file()
    assert (share / "config" / "suite_params.yaml").is_file()
    # ros2 launch PACKAGE FILE looks the file up by os.walk of the share folder (it does not enter linked folders)
    found = [Path(root) / name for root, _, files in os.walk(share) for name in files]
    assert [f.name for f in found].count("stewart_vibration.launch.py") == 1, found
    assert "Package 'no_such_package' not found" in out.stderr and "status=1" in out.stdout
    assert any(x.startswith("usage: stewart-vibration") for x in lines), out.stdout + out.stderr


def test_activating_the_venv_alone_puts_the_executables_on_path():
    """The usual Python habit, `. .venv/bin/activate`, without tools/env.sh: stewart-vibration and the node
    executables are found (bin/ links to lib/stewart_vibration/, set up by the first tools/env.sh)."""
    script = f"""
    source "{REPO}/tools/env.sh" >/dev/null 2>&1 || exit 3
    env -i HOME="$HOME" PATH=/usr/bin:/bin bash -c '. "{REPO}/.venv/bin/activate" && command -v stewart-vibration \
        && command -v kinematics_node && stewart-vibration --help | head -1'
    """
    out = subprocess.run(["bash", "-c", script], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "/.venv/bin/stewart-vibration" in out.stdout and "/.venv/bin/kinematics_node" in out.stdout
    assert "usage: stewart-vibration" in out.stdout


def test_the_executables_land_where_ros2_run_and_path_look_whichever_layout_pip_chose(tmp_path):
    """An older pip installs the editable package's executables in lib/stewart_vibration (setup.cfg), a recent
    one (PEP 660 editable wheels) in bin/: after the link step each is in both, and a real file is never
    replaced by a link."""
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    (venv / "lib" / "stewart_vibration").mkdir(parents=True)
    (venv / "bin" / "in_bin").write_text("#!/bin/sh\necho bin\n")
    (venv / "lib" / "stewart_vibration" / "in_lib").write_text("#!/bin/sh\necho lib\n")
    script = f"""
    source "{REPO}/tools/env.sh" >/dev/null 2>&1 || exit 3
    _stewart_link_executables "{venv}" in_bin in_lib missing || exit 4
    """
    out = subprocess.run(["bash", "-c", script], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    lib, bin_ = venv / "lib" / "stewart_vibration", venv / "bin"
    assert (lib / "in_bin").is_symlink() and (lib / "in_bin").resolve() == (bin_ / "in_bin")
    assert (bin_ / "in_lib").is_symlink() and (bin_ / "in_lib").resolve() == (lib / "in_lib")
    assert not (bin_ / "in_bin").is_symlink() and not (lib / "in_lib").is_symlink()
    assert not (lib / "missing").exists() and not (bin_ / "missing").exists()
