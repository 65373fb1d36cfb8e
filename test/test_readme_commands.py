"""Every command in the ```bash blocks of the README and the docs pages (docs/*.md), run exactly as written
(engineering standard: a documented command that nobody runs is a documented command that is wrong).

The lines run in a copy of the checkout (so ``runs/``, ``report/`` ... land there), in a bash that has
sourced ``tools/venv.sh`` -- what the README tells a user to do -- with this test's ROS domain. ``ros2``
is test/ros2_shim.py (ros2cli is not on PyPI): ``topic pub/echo``, ``service call``, ``param set`` and
``run`` over real DDS. What needs a ROS install that this machine cannot have (``ros2 launch``, ``ros2
bag``) is listed in NEEDS_A_ROS_INSTALL with the test that covers it instead; anything else unclassified
fails test_every_readme_command_is_run_here, so a new command in the README or a docs page needs a runner
here. Blocks are looked up by the heading they stand under (the section's heading is kept when a section
moves between the README and a docs page).
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from stewart_vibration.runtime.processes import claim_ros_domain

pytestmark = [pytest.mark.integration, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = [README, *sorted((ROOT / "docs").glob("*.md"))]  # the README first: its first block is the main job
COPY_IGNORE = shutil.ignore_patterns(".git", ".venv", ".mypy_cache", "runs", "build", "install", "log", "__pycache__",
                                     "*.egg-info", ".pytest_cache", ".ruff_cache", "paper_figures", "report", "dyn")
# Lines this machine cannot run (launch and rosbag2 are not on PyPI), each with the test that checks what it
# relies on.
NEEDS_A_ROS_INSTALL = {
    "ros2 launch stewart_vibration stewart_vibration.launch.py real_time_factor:=1.0":
        "test_launch_file.py runs generate_launch_description; test_dds_loopback.py checks its DDS profile",
    "ros2 launch stewart_vibration stewart_vibration.launch.py ui:=true":
        "test_launch_file.py (optional nodes); the planning_ui executable runs from the colcon install in "
        "test_ros_install_block_as_written",
    "ros2 bag info runs/latest": "test_mcap_bag_directory.py opens the run folder with rosbags' rosbag2 reader",
    "ros2 bag play runs/latest": "test_mcap_bag_directory.py (reader) and test_mcap_replay_clock.py (/clock)",
}
KINDS = [  # (kind, pattern on the line without its comment)
    ("ci", r"\./tools/test$"),
    ("keep_running", r"\./tools/main .*--keep-running"),
    ("main", r"\./tools/main( |$)"),
    ("ros_install", r"ros2 (launch|bag) "),
    ("ros2_run", r"ros2 run "),
    ("ros2", r"ros2 (topic|service|param|action) "),
    ("colcon", r"colcon build "),
    ("pip", r"pip install "),
    ("suite_cli", r"stewart-vibration (topic-rate|calibrate) "),  # need the running suite: run with the UI commands
    ("cli", r"stewart-vibration "),
    ("python", r"python -m "),
]


def strip_comment(line: str) -> str:
    return shlex.join(shlex.split(line, comments=True))


def readme_blocks(lang: str) -> list[tuple[str, list[str]]]:
    """(section heading, commands) of every ```lang block of the README, then of each docs page (a page's
    blocks before its first heading have the heading ""); continuation lines joined, comments kept. A line
    starting with # inside another fenced block (a shell comment) is not a heading."""
    blocks = []
    for doc in DOCS:
        heading, block, other_fence = "", None, False
        for line in doc.read_text().splitlines():
            if block is not None:
                if line.strip() == "```":
                    blocks.append((heading, block))
                    block = None
                else:
                    block.append(line)
            elif other_fence:
                other_fence = line.strip() != "```"
            elif line.strip() == f"```{lang}":
                block = []
            elif line.strip().startswith("```"):
                other_fence = True
            elif line.startswith("#"):
                heading = line.lstrip("# ").strip()
    result = []
    for heading, lines in blocks:
        if lang != "bash":
            result.append((heading, lines))
            continue
        commands, pending = [], ""
        for line in lines:
            pending += line.rstrip()
            if pending.endswith("\\"):
                pending = pending[:-1]
                continue
            if pending.strip() and not pending.lstrip().startswith("#"):
                commands.append(pending.strip())
            pending = ""
        result.append((heading, commands))
    return result


def kind_of(command: str) -> str | None:
    bare = strip_comment(command)
    for kind, pattern in KINDS:
        if re.match(pattern, bare):
            return kind
    return None


def commands_of(kind: str) -> list[str]:
    return [c for _, commands in readme_blocks("bash") for c in commands if kind_of(c) == kind]


def test_every_readme_command_is_run_here():
    commands = [c for _, cs in readme_blocks("bash") for c in cs]
    assert len(commands) > 20
    unclassified = [c for c in commands if kind_of(c) is None]
    assert not unclassified, f"README / docs commands no test runs: {unclassified}"
    ros_install = {strip_comment(c) for c in commands_of("ros_install")}
    assert ros_install == set(NEEDS_A_ROS_INSTALL), "NEEDS_A_ROS_INSTALL is out of date with the README and docs"
    for covered_by in NEEDS_A_ROS_INSTALL.values():
        for name in re.findall(r"test_\w+\.py", covered_by):
            assert (ROOT / "test" / name).is_file(), name


def test_the_readme_test_command_is_what_ci_runs():
    """``./tools/test`` cannot run inside itself; .ci/run runs it, as written, on a clean checkout."""
    assert [strip_comment(c) for c in commands_of("ci")] == ["./tools/test"]
    assert "\n./tools/test\n" in (ROOT / ".ci" / "run").read_text()


class Workspace:
    """A copy of the checkout; commands run in bash after ``source tools/venv.sh`` (the README's setup)."""

    def __init__(self, path: Path, domain: int, shim_bin: Path):
        self.path, self.domain = path, domain
        env = {k: v for k, v in os.environ.items() if not k.startswith(("FASTRTPS_", "FASTDDS_", "ROS_"))}
        # the copy borrows this venv: it must not re-point the venv's editable install at itself
        env.update(STEWART_VENV=sys.prefix, STEWART_VENV_NO_INSTALL="1", ROS_DOMAIN_ID=str(domain),
                   ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", PATH=f"{shim_bin}:{env['PATH']}", PYTHONUNBUFFERED="1")
        self.env = env

    def script(self, command: str, setup: str = "") -> list[str]:
        return ["bash", "-c", f"set -e; source tools/venv.sh; {setup}\n{command}"]

    def run(self, command: str, timeout: float = 300, setup: str = "") -> subprocess.CompletedProcess:
        return subprocess.run(self.script(command, setup), cwd=self.path, env=self.env, timeout=timeout,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)

    def start(self, command: str, setup: str = "") -> LineReader:
        proc = subprocess.Popen(self.script(command, setup), cwd=self.path, env=self.env, start_new_session=True,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        return LineReader(proc)


class LineReader:
    """A started command whose output is collected by a thread (so waiting on a line cannot block)."""

    def __init__(self, proc: subprocess.Popen):
        self.proc, self.lines = proc, []
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self):
        for line in self.proc.stdout:
            self.lines.append(line)

    @property
    def text(self) -> str:
        return "".join(self.lines)

    def wait_for(self, pattern: str, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if re.search(pattern, self.text, re.MULTILINE):
                return True
            if self.proc.poll() is not None:
                self._thread.join(timeout=5)
                return bool(re.search(pattern, self.text, re.MULTILINE))
            time.sleep(0.1)
        return False

    def interrupt(self, timeout: float = 180) -> int:
        """SIGINT to the command's process group (Ctrl-C), then its exit code."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
        try:
            code = self.proc.wait(timeout=timeout)
        finally:
            if self.proc.poll() is None:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
        self._thread.join(timeout=5)
        return code


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    # bring the venv up to date for this checkout first (the copy may not install into it)
    setup = subprocess.run(["bash", "-c", "source tools/env.sh"], cwd=ROOT, text=True, timeout=600,
                           env=dict(os.environ, STEWART_VENV=sys.prefix), stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT)
    assert setup.returncode == 0, setup.stdout
    path = tmp_path_factory.mktemp("readme") / "stewart_vibration"
    shutil.copytree(ROOT, path, ignore=COPY_IGNORE, symlinks=True)
    shim_bin = path.parent / "shim_bin"
    shim_bin.mkdir()
    shim = shim_bin / "ros2"
    shim.write_text(f"#!{sys.executable}\nimport sys\nsys.path.insert(0, {str(ROOT / 'test')!r})\n"
                    "from ros2_shim import main\nsys.exit(main(sys.argv[1:]))\n")
    shim.chmod(0o755)
    domain, lock = claim_ros_domain()
    yield Workspace(path, domain, shim_bin)
    lock.close()


@pytest.fixture(scope="module")
def main_job_run(workspace):
    """The README's first command, ``./tools/main``: the other commands read the run it leaves."""
    (first,) = [c for c in readme_blocks("bash")[0][1] if kind_of(c) == "main"]
    result = workspace.run(first, timeout=600)
    return first, result


def test_main_job_as_written(workspace, main_job_run):
    command, result = main_job_run
    assert result.returncode == 0, result.stdout[-4000:]
    assert "=== run summary ===" in result.stdout
    latest = workspace.path / "runs" / "latest"
    assert (latest / "summary.json").is_file() and (latest / "metadata.yaml").is_file()
    assert list(latest.glob("run_*.mcap"))


def test_main_job_options_as_written(workspace, main_job_run):
    paper = ROOT / "stewart_vibration" / "config" / "scenario_paper.yaml"
    (workspace.path / "my_scenario.yaml").write_text(paper.read_text())
    others = [c for c in commands_of("main") if c != main_job_run[0]]
    assert others
    for command in others:
        result = workspace.run(command, timeout=600)
        assert result.returncode == 0, f"{command}\n{result.stdout[-4000:]}"


def test_keep_running_serves_the_ui_commands(workspace, main_job_run):
    """``--keep-running``: the nodes stay up; the planning-UI commands (docs/planning-ui.md, "Driving it from a
    planning UI") and the ones the run prints work against them from another shell (exported as printed);
    Ctrl-C stops it with 130."""
    commands = commands_of("keep_running")
    assert commands
    ui_block = [c for heading, cs in readme_blocks("bash") if "planning UI" in heading for c in cs]
    assert ui_block
    for command in commands:
        suite = workspace.start(command)
        try:
            assert suite.wait_for(r"^Nodes are running", timeout=300), suite.text[-4000:]
            printed = printed_commands(suite.text)
            assert printed and f"export ROS_DOMAIN_ID={workspace.domain}" in suite.text
            if command == commands[0]:
                for line in ui_block + printed:
                    run_ui_command(workspace, line)
        finally:
            # after Ctrl-C the run summarises and reports everything recorded: the UI block's calibration makes
            # this session ~60 MB of MCAP, whose report alone took 110 s on a quiet machine (the report's own
            # limit in the main job is 600 s)
            code = suite.interrupt(timeout=600)
        assert code == 130, f"{command} exited {code}\n{suite.text[-4000:]}"


def printed_commands(output: str) -> list[str]:
    """The ``ros2 ...`` lines the run prints under 'In another shell:' (continuations joined)."""
    block = output.split("In another shell:", 1)[1].split("\n\n", 1)[0]
    return [c for c in " ".join(block.split("\\\n")).splitlines() if c.strip().startswith("ros2 ")]


def run_ui_command(workspace: Workspace, command: str) -> None:
    command = command.strip()
    if strip_comment(command).startswith("ros2 topic echo"):
        echo = workspace.start(command)
        try:
            assert echo.wait_for(r"^---$", timeout=60), f"{command}: nothing received\n{echo.text[-2000:]}"
        finally:
            echo.interrupt()
        return
    calibrate = strip_comment(command).startswith("stewart-vibration calibrate")
    result = workspace.run(command, timeout=900 if calibrate else 120)
    assert result.returncode == 0, f"{command}\n{result.stdout[-3000:]}"
    if calibrate:  # the robot file it names loads as a calibrated robot
        from stewart_vibration.kinematics.robot_config import load_robot

        assert "calibrate: SUCCEEDED" in result.stdout, result.stdout[-3000:]
        path = re.search(r"^robot file: (\S+)", result.stdout, re.M)
        assert path and load_robot(path.group(1)).calibrated, result.stdout[-3000:]
    # ros2cli exits 0 on a refusal too: what happened is in what it prints, as a user reads it
    if "param set" in command:
        assert "Set parameter successful" in result.stdout, result.stdout[-3000:]
    if "service call" in command:
        assert "response:" in result.stdout, result.stdout[-3000:]
        answer = result.stdout.split("response:", 1)[1]
        assert "success=False" not in answer, f"{command}\n{answer[-3000:]}"
        if "Outcome(" in answer:  # a typed answer: SUCCEEDED (1)
            assert "Outcome(code=1," in answer, f"{command}\n{answer[-3000:]}"
        if "std_srvs/srv/Trigger" in command:
            assert "success=True" in answer, f"{command}\n{answer[-3000:]}"
    if "action send_goal" in command:  # the vibration ran: its typed result and the goal's final status
        assert "Goal finished with status: SUCCEEDED" in result.stdout and "Feedback:" in result.stdout, \
            result.stdout[-3000:]
    if "emergency_stop" in command:  # the reset that follows in the block needs time to move home
        time.sleep(1.0)


def test_ros_install_block_as_written(workspace):
    """colcon build + source, then each ``ros2 run`` line starts its node from the install (Ctrl-C ends it)."""
    lines = [c for heading, cs in readme_blocks("bash") if "colcon" in heading for c in cs]
    (build,) = [c for c in lines if kind_of(c) == "colcon"]
    for command in [c for c in lines if kind_of(c) == "pip"]:
        result = workspace.run(command, timeout=300)
        assert result.returncode == 0, f"{command}\n{result.stdout[-3000:]}"
    result = workspace.run(build, timeout=600, setup="set +u")
    assert result.returncode == 0, result.stdout[-4000:]
    assert (workspace.path / "install" / "stewart_vibration" / "share" / "stewart_vibration" / "config").is_dir()
    runs = commands_of("ros2_run")  # this block's and the other sections' (planning_ui ...)
    assert set(c for c in lines if kind_of(c) == "ros2_run") < set(runs)
    for command in runs:
        node = workspace.start(command, setup="source install/local_setup.bash")
        try:
            executable = shlex.split(command)[3]
            ready = node.wait_for(r"(ready|active|recording|listening|serving|planning UI at)", timeout=60)
            assert node.proc.poll() is None, f"{command} exited\n{node.text[-3000:]}"
            assert ready, f"{executable} never said it was ready\n{node.text[-3000:]}"
            assert "/install/stewart_vibration/" in node_command_line(node.proc.pid)
        finally:
            code = node.interrupt()
        assert code in (0, 130, -signal.SIGINT), f"{command} exited {code} on Ctrl-C\n{node.text[-3000:]}"
        assert "Traceback" not in node.text, node.text[-3000:]


def node_command_line(bash_pid: int) -> str:
    """Command lines of ``bash_pid``'s process group (the executed node runs from the colcon install)."""
    lines = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if os.getpgid(int(entry.name)) == bash_pid:
                    lines.append((entry / "cmdline").read_bytes().replace(b"\0", b" ").decode())
            except (OSError, ProcessLookupError):
                continue
    return "\n".join(lines)


def test_replay_and_cli_blocks_as_written(workspace, main_job_run):
    """``stewart-vibration ...`` and ``python -m ...`` lines, on the run the main job left in runs/latest (the
    tests before may have started other runs or a recorder of their own, each a newer runs/latest: the link is
    put back on the main job's run, as it was when the main job ended)."""
    assert main_job_run[1].returncode == 0
    point_latest_at_the_main_job_run(workspace, main_job_run[1].stdout)
    commands = commands_of("cli") + commands_of("python")
    assert len(commands) >= 8
    for command in commands:
        result = workspace.run(command, timeout=600)
        assert result.returncode == 0, f"{command}\n{result.stdout[-4000:]}"
        assert "Traceback" not in result.stdout, f"{command}\n{result.stdout[-4000:]}"


def point_latest_at_the_main_job_run(workspace: Workspace, output: str) -> None:
    """Point runs/latest back at the run folder the main job's ``output`` names (its "report:" line)."""
    match = re.search(r"^report: runs/([^/\s]+)/report$", output, re.MULTILINE)
    assert match, output[-2000:]
    runs = workspace.path / "runs"
    assert (runs / match.group(1) / "summary.json").is_file()
    temporary = runs / ".latest.test"
    temporary.unlink(missing_ok=True)
    temporary.symlink_to(match.group(1))
    os.replace(temporary, runs / "latest")


def test_python_block_as_written(workspace):
    (code,) = [lines for heading, lines in readme_blocks("python")]
    result = subprocess.run([sys.executable, "-c", "\n".join(code)], cwd=workspace.path, timeout=120,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert result.returncode == 0, result.stdout
