"""The emulator's strut-command acceptance (emulation.safety_controller / strut_acceptance): how long it takes to
accept a command, and how long the physics lock is held for it.

- a typical 10 s move: the kinematics node's minimum-jerk plan (500 points, one per 20 ms) to a pose 20 mm /
  12 deg from home, accepted from rest;
- a replan of the running move 5 s in, from its moving state: short (200 points: checked and committed under the
  lock, as the force guard's stops) and long (1000 points: checked outside, the commit re-checks the departure
  segment under the lock);
- a maximal command: MAX_TRAJECTORY_POINTS points (a slow 200 s creep with a 1 Hz wobble), from rest;
- a refused one: +45/-30/+45/-30/+45/-30 mm, legal per strut (refused at the joint limit).

Each is timed as a whole (best and median of --repeats) and for its time under the caller's lock (the snapshot
and the commit: what physics waits for). The commands a 10 Hz sender can push are bounded by the whole time
(it runs on the executor thread, outside the lock).

Run: .venv/bin/python benchmarks/strut_acceptance.py [--repeats 7] [--json]
"""

from __future__ import annotations

import argparse
import json
import threading
import time

import numpy as np

from stewart_vibration import inverse_kinematics, load_robot
from stewart_vibration.emulation.command_size import MAX_TRAJECTORY_POINTS
from stewart_vibration.emulation.safety_controller import SafetyController
from stewart_vibration.errors import StewartError
from stewart_vibration.motion.profiles import minimum_jerk
from stewart_vibration.robot import LEG_NAMES

DT = 1 / 2000


class TimedLock:
    """A lock that adds up how long it was held (s)."""

    def __init__(self):
        self._lock = threading.Lock()
        self.held = 0.0
        self._since = 0.0

    def __enter__(self):
        self._lock.acquire()
        self._since = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.held += time.perf_counter() - self._since
        self._lock.release()


def ten_second_move(robot):
    start = inverse_kinematics(robot, robot.home_pose)
    goal = inverse_kinematics(robot, robot.home_pose + np.array([0.012, -0.008, 0.014, 0.12, -0.1, 0.15]))
    times = np.linspace(0.02, 10.0, 500)
    return (0.0, times, *minimum_jerk(start, goal, 10.0, times)), start


def maximal_command(robot):
    start = inverse_kinematics(robot, robot.home_pose)
    times = np.linspace(0.02, 200.0, MAX_TRAJECTORY_POINTS)
    pos, vel, acc = minimum_jerk(start, start + 0.004, 200.0, times)
    wobble = 2e-4 * np.sin(2 * np.pi * times)[:, None] * np.sin(np.pi * times / 200.0)[:, None] ** 2
    rate = 2e-4 * 2 * np.pi * np.cos(2 * np.pi * times)[:, None] * np.sin(np.pi * times / 200.0)[:, None] ** 2
    return (0.0, times, pos + wobble * np.array([1, -1, 1, -1, 1, -1]), vel + rate * np.array([1, -1, 1, -1, 1, -1]),
            None), start


def refused_command(robot):
    start = inverse_kinematics(robot, robot.home_pose)
    goal = start + np.array([0.045, -0.03] * 3)
    times = np.linspace(0.0469, 4.6875, 100)
    return (0.0, times, *minimum_jerk(start, goal, 4.6875, times)), start


def replanned_move(ctl, now, points):
    """A 10 s minimum-jerk move of ``points`` points from the state commanded at ``now`` toward another pose, its
    first point 0.5 s later, as a replanning controller would send it (positions only: cubic from the moving
    state)."""
    robot = ctl.robot
    current = ctl.struts.sample([now])[0][0]
    goal = inverse_kinematics(robot, robot.home_pose + np.array([-0.01, 0.01, 0.008, -0.1, 0.08, -0.1]))
    times = np.linspace(0.5, 10.0, points)
    return (0.0, times, minimum_jerk(current, goal, 10.0, times)[0], None, None)


def measure(robot, command, repeats, running=None, refused=False):
    """(total s, locked s) per repeat: a fresh controller (with ``running`` commanded first and run 5 s in;
    ``command`` is then the number of points of the replanned move); the command must be refused exactly when
    ``refused``."""
    totals, locked = [], []
    points = command
    for _ in range(repeats):
        ctl = SafetyController(robot, DT)
        now = 0.0
        if running is not None:
            ctl.command_struts(0.0, LEG_NAMES, *running)
            now = 5.0
            command = replanned_move(ctl, now, points)
        lock = TimedLock()
        ticks = iter([now, now + 0.002])  # the commit happens a block later: the departure moves on

        def clock(ticks=ticks, later=now + 0.002):
            return next(ticks, later)

        began = time.perf_counter()
        try:
            ctl.command_struts(now, LEG_NAMES, *command, lock=lock, clock=clock)
            outcome = False
        except StewartError:
            outcome = True
        totals.append(time.perf_counter() - began)
        locked.append(lock.held)
        if outcome != refused:
            raise RuntimeError(f"the command was {'refused' if outcome else 'accepted'}: not the case to time")
    return totals, locked


def summary(values):
    ms = np.array(values) * 1e3
    return {"best_ms": float(ms.min()), "median_ms": float(np.median(ms)), "worst_ms": float(ms.max())}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    robot = load_robot()
    move, _ = ten_second_move(robot)
    cases = {
        "10 s move from rest (500 points)": measure(robot, move, args.repeats),
        "a 200-point replan of a running move (checked under the lock)": measure(robot, 200, args.repeats,
                                                                                 running=move),
        "a 1000-point replan of a running move (departure re-checked)": measure(robot, 1000, args.repeats,
                                                                                running=move),
        f"maximal command ({MAX_TRAJECTORY_POINTS} points, 200 s)": measure(robot, maximal_command(robot)[0],
                                                                              max(2, args.repeats // 3)),
        "refused +45/-30 mm command": measure(robot, refused_command(robot)[0], args.repeats, refused=True),
    }
    results = {name: {"total": summary(t), "locked": summary(lk)} for name, (t, lk) in cases.items()}
    if args.json:
        print(json.dumps(results, indent=2))
        return 0
    print("strut command acceptance (SafetyController.command_struts; locked = snapshot + commit)")
    for name, r in results.items():
        t, lk = r["total"], r["locked"]
        print(f"  {name}: {t['median_ms']:.1f} ms median (best {t['best_ms']:.1f}, worst {t['worst_ms']:.1f}); "
              f"under the lock {lk['median_ms']:.2f} ms median (worst {lk['worst_ms']:.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
