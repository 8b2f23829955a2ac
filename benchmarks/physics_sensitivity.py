"""How many physics verdicts of the fixed trial sets a rounding-sized change of the object's
start moves: the noise floor of "the same verdicts".

Every trial of ``tests/data/physics_trials.json`` (the throughput set, 126 trials) and
``tests/data/physics_regression.json`` (20) is executed with its object started ``eps``
further along the world x axis (added to the trial's offset) and its verdict (success and
cause) compared with the recorded one, for each ``eps``. A verdict that a shift of
10^-9 m changes is decided by rounding: no change of the simulation's arithmetic (another
MuJoCo build, another order of the same sums) can be required to keep it. Settings as the
sweep's (``PhysicsOptions(early_end=True)``, whose verdicts are the full rollout's).

Run (about 3 minutes on one core with the defaults)::

    python benchmarks/physics_sensitivity.py
    python benchmarks/physics_sensitivity.py --eps 1e-12 1e-9 1e-7 --json sensitivity.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402
import physics_regression as regression  # noqa: E402

from openup_ompl.physics import PhysicsOptions, Rollout  # noqa: E402
from openup_ompl.study.stats import wilson_interval  # noqa: E402


def changed(eps: float) -> tuple[int, list[dict[str, object]]]:
    """Run both sets with the object shifted by ``eps`` [m] along x; returns the trial
    count and the trials whose verdict differs from the recorded one."""
    total, moved = 0, []
    for path in (regression.TRIALS, regression.DATA):
        for case in regression.load(path):
            rollout = Rollout(regression.plan_contents(case), PhysicsOptions(early_end=True))
            for trial in case["trials"]:
                offset = list(trial["offset"])
                offset[0] += eps
                record = rollout.run(offset, frames=False)
                total += 1
                if (record.success, record.cause) != (trial["success"], trial["cause"]):
                    moved.append({
                        "set": path.stem, "scene": case["scene"], "seed": case["seed"],
                        "offset": trial["offset"], "recorded": trial["cause"] or "held",
                        "now": record.cause or "held",
                    })  # fmt: skip
    return total, moved


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--eps", type=float, nargs="+", default=[1e-12, 1e-9, 1e-7],
                        help="start shifts along x [m]")  # fmt: skip
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args()
    results = []
    for eps in args.eps:
        started = time.perf_counter()
        total, moved = changed(eps)
        low, high = wilson_interval(len(moved), total)
        results.append({"eps_m": eps, "trials": total, "changed": len(moved),
                        "wilson95": [low, high], "trials_changed": moved})  # fmt: skip
        print(f"shift {eps:g} m: {len(moved)} of {total} verdicts changed "
              f"({100 * len(moved) / total:.1f} %, 95 % CI {100 * low:.1f}-{100 * high:.1f} %; "
              f"{time.perf_counter() - started:.0f} s)", flush=True)  # fmt: skip
        for trial in moved:
            print(f"  {trial['scene']} seed {trial['seed']} at {trial['offset']}: "
                  f"{trial['recorded']} -> {trial['now']}")  # fmt: skip
    print(_common.machine_line(_common.machine_info()))
    if args.json:
        args.json.write_text(json.dumps({"machine": _common.machine_info(),
                                         "results": results}, indent=1) + "\n")  # fmt: skip


if __name__ == "__main__":
    main()
