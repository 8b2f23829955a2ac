"""Per-robot cost: the coupled state check and the median solve time, in one run.

For every shipped robot with a demo scene (``scenes/<robot>_*.toml``, the Panda's
``panda_can.toml`` included): the cost [us] of ``CoupledChecker.is_valid`` (arm state ->
FK -> hand law -> Coal, the hand set by the law) on random arm states within the joint
limits, median over interleaved rounds; and the median solve time [s] of ``ikbirrt`` and
``rrtconnect`` (+ ``IKGoalRegion``) over N seeds, with the success count. The robots'
geometry and pair counts are listed beside, since the check cost scales with them.

Run (about 15 s with the defaults on 2 cores)::

    python benchmarks/bench_robots.py
    python benchmarks/bench_robots.py --seeds 20 --states 2000 --json bench_robots.json
"""

from __future__ import annotations

import argparse
import gc
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from ompl import util as ou

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

import openup_ompl  # noqa: E402
from openup_ompl._resources import data_dir  # noqa: E402

PLANNERS = ("ikbirrt", "rrtconnect")


def demo_scenes() -> dict[str, Path]:
    """The first demo scene of each shipped robot that has one."""
    scenes = {}
    for name in openup_ompl.available_robots():
        found = sorted(data_dir("scenes").glob(f"{name}_*.toml"))
        if found:
            scenes[name] = found[0]
    return scenes


def state_cost(setups: dict[str, Any], states: int, rounds: int) -> dict[str, float]:
    """Median over rounds of the per-state ``is_valid`` time [us], robots interleaved."""
    rng = np.random.default_rng(0)
    samples = {}
    for name, setup in setups.items():
        robot = setup.problem.robot
        samples[name] = rng.uniform(robot.arm_lower, robot.arm_upper, (states, robot.arm_idx.size))
    times: dict[str, list[float]] = {name: [] for name in setups}
    gc.disable()
    try:
        for r in range(rounds):
            order = list(setups)
            order = order[r % len(order) :] + order[: r % len(order)]
            for name in order:
                checker = setups[name].checker
                checker.forget()  # every state checked, not read back from the last round
                start = time.perf_counter()
                for arm in samples[name]:
                    checker.is_valid(arm)
                times[name].append((time.perf_counter() - start) / states * 1e6)
    finally:
        gc.enable()
    return {name: _common.median(values) for name, values in times.items()}


def solve_times(
    setup: Any, planner: str, seeds: int, time_limit: float, label: str, quiet: bool
) -> dict[str, Any]:
    """Solve times [s] over seeds (failures count at the time limit)."""
    times, solved = [], 0
    for seed in range(seeds):
        if not quiet:
            print(f"\r{label} {planner}: seed {seed + 1}/{seeds}", end="", file=sys.stderr)
        start = time.perf_counter()
        try:
            setup.solve(time_limit=time_limit, planner=planner, seed=seed)
            solved += 1
        except openup_ompl.PlanningFailed:
            pass
        times.append(time.perf_counter() - start)
    if not quiet:
        print(file=sys.stderr)
    return {"solved": solved, "seeds": seeds, "median_s": _common.median(times)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=10, help="seeds per planner (default 10)")
    parser.add_argument("--time-limit", type=float, default=10.0, help="seconds per solve (10)")
    parser.add_argument("--states", type=int, default=1000, help="states per round (1000)")
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds (5)")
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    parser.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    args = parser.parse_args()
    quiet = args.quiet or not sys.stderr.isatty()
    ou.setLogLevel(ou.LOG_ERROR)

    info = _common.machine_info()
    scenes = demo_scenes()
    setups = {
        name: openup_ompl.GraspPlanningSetup(openup_ompl.load_scene(path))
        for name, path in scenes.items()
    }
    cost = state_cost(setups, args.states, args.rounds)
    results: dict[str, Any] = {}
    for name, setup in setups.items():
        robot = setup.problem.robot
        results[name] = {
            "scene": scenes[name].name,
            "arm_dof": int(robot.arm_idx.size),
            "hand_joints": int(robot.hand_idx.size),
            "geometries": int(robot.collision_model.ngeoms),
            "self_pairs": len(robot.collision_model.collisionPairs),
            "state_check_us": cost[name],
            **{
                planner: solve_times(setup, planner, args.seeds, args.time_limit, name, quiet)
                for planner in PLANNERS
            },
        }
    panda = results.get("panda", {}).get("state_check_us")
    rows = []
    for name, r in results.items():
        ratio = f"{r['state_check_us'] / panda:.2f}" if panda else "-"
        rows.append(
            [
                name,
                r["scene"],
                r["arm_dof"],
                r["hand_joints"],
                f"{r['geometries']} / {r['self_pairs']}",
                f"{r['state_check_us']:.1f}",
                ratio,
                *(
                    f"{1e3 * r[p]['median_s']:.1f} ({r[p]['solved']}/{r[p]['seeds']})"
                    for p in PLANNERS
                ),
            ]
        )
    print(_common.machine_line(info))
    print()
    print(
        _common.markdown_table(
            [
                "robot",
                "scene",
                "arm DOF",
                "hand joints",
                "geoms / self pairs",
                "state check [us]",
                "x Panda",
                *(f"{p} median [ms] (solved)" for p in PLANNERS),
            ],
            rows,
            left=2,
        )
    )
    _common.write_json(args.json, {"machine": info, "args": vars(args), "results": results})


if __name__ == "__main__":
    main()
