"""The suite's headroom as ratios to its floors, measured side by side in one run.

Each round measures, one after the other on a quiet machine:
- the suite: the main job vibrating at real time (benchmarks/suite_cpu.py's measurement: CPU of every process
  over a window of the vibration);
- the messaging floor: the suite's topology moving the same bytes with no computation (benchmarks/dds_floor.py);
- the physics floor: MuJoCo stepping the emulator's model at 2 kHz in C (benchmarks/physics_floor.py), in cores:
  2,000 steps/s over its raw rate;
- the emulator node alone at its maximum speed (benchmarks/emulator.py), against that raw rate.

The floors vary ~1.6x from run to run, so the rounds alternate (at least 3) and the verdict is on medians:
required suite <= 3x (messaging + physics floors), goal <= 1.5x; goal: the emulator's maximum real-time factor
>= 0.8x MuJoCo's raw rate on the same model; required: every main job passes its bounds.

    .venv/bin/python benchmarks/headroom.py [--rounds 3] [--plant ideal] [--json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from dds_floor import measure_floor  # noqa: E402 - benchmarks/ is not a package
from emulator import measure_max_speed  # noqa: E402
from physics_floor import PHYSICS_HZ, emulator_for, raw_rate  # noqa: E402
from suite_cpu import measure_suite  # noqa: E402

REQUIRED_RATIO, GOAL_RATIO, RTF_SHARE_GOAL = 3.0, 1.5, 0.8


def measure_round(index: int, args, tmp: Path) -> dict:
    """One round: the suite, the messaging floor, the physics floor, the emulator at its maximum speed."""
    suite = measure_suite(args.vibration, args.window, tmp / f"run_{index}", plant=args.plant)
    messaging = measure_floor(args.floor_seconds)
    raw = raw_rate(emulator_for(args.plant), args.physics_seconds)
    emulator = measure_max_speed(args.emulator_seconds, tmp, args.plant)
    return {"suite_cores": suite["total_cores"], "suite_per_process": suite["cores"],
            "main_job_exit_code": suite["exit_code"], "messaging_floor_cores": sum(messaging.values()),
            "physics_raw_steps_per_s": raw, "physics_floor_cores": PHYSICS_HZ / raw,
            "emulator_max_rtf": emulator["real_time_factor_achieved"], "raw_rtf": raw / PHYSICS_HZ}


def judge(rounds: list[dict]) -> dict:
    """Medians over the rounds, the ratios and the verdicts [(figure, required?, met?)]."""
    med = {key: statistics.median(r[key] for r in rounds) for key in
           ("suite_cores", "messaging_floor_cores", "physics_floor_cores", "emulator_max_rtf", "raw_rtf")}
    floors = med["messaging_floor_cores"] + med["physics_floor_cores"]
    ratio = med["suite_cores"] / floors
    rtf_share = med["emulator_max_rtf"] / med["raw_rtf"]
    codes = [r["main_job_exit_code"] for r in rounds]
    verdicts = [
        (f"suite {med['suite_cores']:.3f} cores = {ratio:.2f}x its floors ({floors:.3f} cores) <= {REQUIRED_RATIO:g}x",
         True, ratio <= REQUIRED_RATIO),
        (f"every main job passed its bounds (exit codes {codes})", True, all(c == 0 for c in codes)),
        (f"suite {ratio:.2f}x its floors <= {GOAL_RATIO:g}x (goal)", False, ratio <= GOAL_RATIO),
        (f"emulator max real-time factor {med['emulator_max_rtf']:.2f} = {rtf_share:.2f}x MuJoCo's raw "
         f"{med['raw_rtf']:.1f} >= {RTF_SHARE_GOAL:g}x (goal)", False, rtf_share >= RTF_SHARE_GOAL),
    ]
    return {"medians": med, "floors_cores": floors, "ratio": ratio, "emulator_rtf_share": rtf_share,
            "verdicts": verdicts}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds (at least 3)")
    parser.add_argument("--plant", default="ideal", help="the plant of the suite and the floors (the main job's "
                        "default: ideal)")
    parser.add_argument("--vibration", type=float, default=20.0, help="the main job's vibration, s")
    parser.add_argument("--window", type=float, default=12.0, help="the suite's CPU window in the vibration, s")
    parser.add_argument("--floor-seconds", type=float, default=10.0, help="the messaging floor's window, s")
    parser.add_argument("--physics-seconds", type=float, default=5.0, help="MuJoCo's raw rate, s of physics")
    parser.add_argument("--emulator-seconds", type=float, default=5.0, help="the emulator at its maximum, s")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    if args.rounds < 3:
        parser.error("--rounds must be at least 3 (the verdict is on medians of alternating runs)")
    with tempfile.TemporaryDirectory() as tmp:
        rounds = []
        for index in range(args.rounds):
            rounds.append(measure_round(index, args, Path(tmp)))
            if not args.json:
                r = rounds[-1]
                print(f"round {index + 1}: suite {r['suite_cores']:.3f} cores "
                      f"(main job exit {r['main_job_exit_code']}), "
                      f"messaging floor {r['messaging_floor_cores']:.3f}, physics floor {r['physics_floor_cores']:.4f} "
                      f"({r['physics_raw_steps_per_s']:.0f} steps/s), emulator max {r['emulator_max_rtf']:.2f}x real "
                      f"time", flush=True)
    result = judge(rounds)
    ok = all(met for _, required, met in result["verdicts"] if required)
    if args.json:
        result["verdicts"] = [{"figure": f, "required": r, "met": m} for f, r, m in result["verdicts"]]
        print(json.dumps({"plant": args.plant, "rounds": rounds, **result}, indent=2))
        return 0 if ok else 1
    med = result["medians"]
    print(f"Medians of {args.rounds} rounds ({args.plant} plant): suite {med['suite_cores']:.3f} cores, "
          f"messaging floor {med['messaging_floor_cores']:.3f}, physics floor {med['physics_floor_cores']:.4f}; "
          f"suite / floors {result['ratio']:.2f}x")
    print("Suite per process, median cores:")
    for name in sorted(rounds[0]["suite_per_process"], key=lambda n: -rounds[0]["suite_per_process"][n]):
        values = [r["suite_per_process"].get(name, 0.0) for r in rounds]
        print(f"  {name:<22}{statistics.median(values):7.3f}")
    print("Verdict (exit code 0 when every required figure is met; goals are reported, not required):")
    for figure, required, met in result["verdicts"]:
        print(f"  {'ok  ' if met else ('FAIL' if required else 'miss')}  {figure}")
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
