"""What compiling the motion check's serial batches would save: the batches planning
sends to ``CollisionWorld.batch_in_collision`` (recorded while ``GraspPlanningSetup.solve``
runs), replayed through it and through a compiled loop over the same columns
(``CoupledCheck.collides_columns``, the same query per state), side by side.

Only the batches of fewer than ``collision.PARALLEL_MIN_STATES`` states are replayed: the
larger ones go to Pinocchio's thread pool, already compiled. Every flag of the compiled
loop is compared with the Python one's (the script fails on a difference).

Run (about 30 s, after ``openup-ompl build-native``)::

    python benchmarks/native/batch_replay.py
"""

from __future__ import annotations

import argparse
import gc
import time
from typing import Any

import numpy as np
from ompl import util as ou

import openup_ompl
from openup_ompl import native
from openup_ompl._resources import data_dir
from openup_ompl.collision import PARALLEL_MIN_STATES, CollisionWorld

ROBOTS = ("panda", "lwa3_sdh", "ur5_allegro")


def record(problem: openup_ompl.Problem, seeds: int, limit: float) -> tuple[Any, list[Any]]:
    """Solve ``problem`` for each seed; return the last setup and the serial batches its
    motion checks sent, as ``(world, qs, stop_at_first)``."""
    calls: list[Any] = []
    original = CollisionWorld.batch_in_collision

    def spy(self: CollisionWorld, qs: np.ndarray, stop_at_first: bool = True) -> np.ndarray:
        if qs.shape[1] < PARALLEL_MIN_STATES:
            calls.append((self, np.array(qs, order="F"), stop_at_first))
        return original(self, qs, stop_at_first)

    CollisionWorld.batch_in_collision = spy  # type: ignore[method-assign]
    try:
        for seed in range(seeds):
            setup = openup_ompl.GraspPlanningSetup(problem, native="off")
            setup.solve(limit, "ikbirrt", seed)
    finally:
        CollisionWorld.batch_in_collision = original  # type: ignore[method-assign]
    return setup, calls


def replay(problem: openup_ompl.Problem, args: argparse.Namespace) -> dict[str, float]:
    setup, calls = record(problem, args.seeds, args.time)
    checker = setup.checker
    natives = {}
    module = native.load()
    for world, _, _ in calls:
        if id(world) not in natives:
            natives[id(world)] = native.compiled_check(module, checker, world)
    for world, qs, stop in calls:
        expected = world.batch_in_collision(qs, stop).tolist()
        got = natives[id(world)].collides_columns(qs, stop)
        if got != expected:
            raise SystemExit(f"{problem.robot.name}: compiled flags differ on a batch")
    states = sum(qs.shape[1] for _, qs, _ in calls)
    times: dict[str, list[float]] = {"python": [], "compiled": []}
    gc.disable()
    try:
        for r in range(args.rounds + 1):
            for name in ("python", "compiled") if r % 2 else ("compiled", "python"):
                started = time.thread_time()
                for world, qs, stop in calls:
                    if name == "python":
                        world.batch_in_collision(qs, stop)
                    else:
                        natives[id(world)].collides_columns(qs, stop)
                if r:
                    times[name].append(time.thread_time() - started)
    finally:
        gc.enable()
    py, compiled = np.median(times["python"]), np.median(times["compiled"])
    return {
        "batches": len(calls),
        "states": states,
        "python_us_per_state": 1e6 * py / states,
        "compiled_us_per_state": 1e6 * compiled / states,
        "ratio": float(np.median(np.divide(times["python"], times["compiled"]))),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", nargs="+", default=list(ROBOTS), choices=ROBOTS)
    parser.add_argument("--seeds", type=int, default=3, help="solves per robot (3)")
    parser.add_argument("--time", type=float, default=5.0, help="time limit [s] (5)")
    parser.add_argument("--rounds", type=int, default=7, help="timed rounds (7)")
    args = parser.parse_args()
    ou.setLogLevel(ou.LOG_ERROR)
    print("| robot | serial batches | states | µs/state, Python | µs/state, compiled | ratio |")
    print("|:--|--:|--:|--:|--:|--:|")
    for robot in args.robots:
        problem = openup_ompl.load_scene(data_dir("scenes") / f"{robot}_can.toml")
        out = replay(problem, args)
        print(
            f"| `{robot}` | {out['batches']} | {out['states']} | "
            f"{out['python_us_per_state']:.2f} | {out['compiled_us_per_state']:.2f} | "
            f"{out['ratio']:.2f} |"
        )


if __name__ == "__main__":
    main()
