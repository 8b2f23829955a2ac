"""Planning with the compiled check on and off, side by side: the same problems and
seeds solved by ``GraspPlanningSetup(problem, native=...)`` with ``"off"`` (the Python
check) and ``"on"`` (:mod:`openup_ompl.native`: single states and the motion check's
small batches compiled), alternately. IKBiRRT with a seed is deterministic and the two
checks give the same verdicts, so each pair must return the same path bit for bit (the
script fails otherwise) and check the same number of states; the ratio is the paired
solve times' (thread CPU time), its median over the pairs per suite.

Run (about 1 min, after ``openup-ompl build-native``)::

    python benchmarks/native/solve_native.py
    python benchmarks/native/solve_native.py --robots panda --count 8 --seeds 3
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from ompl import util as ou

import openup_ompl
from openup_ompl._resources import data_dir

ROBOTS = ("panda", "lwa3_sdh", "ur5_allegro")


def solve(problem: openup_ompl.Problem, mode: str, args: argparse.Namespace, seed: int):
    """One solve with ``native=mode``: its plan, thread CPU seconds and states checked."""
    setup = openup_ompl.GraspPlanningSetup(problem, native=mode)
    started = time.thread_time()
    plan = setup.solve(args.time, "ikbirrt", seed)
    return plan, time.thread_time() - started, setup.checker.states_checked


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", nargs="+", default=list(ROBOTS), choices=ROBOTS)
    parser.add_argument("--count", type=int, default=4, help="problems per suite (4)")
    parser.add_argument("--seeds", type=int, default=2, help="seeds per problem (2)")
    parser.add_argument("--time", type=float, default=10.0, help="time limit [s] (10)")
    args = parser.parse_args()
    ou.setLogLevel(ou.LOG_ERROR)
    print("| robot | solves | ms per solve, Python | ms, compiled | Python / compiled (median) |")
    print("|:--|--:|--:|--:|--:|")
    for robot in args.robots:
        files = sorted((data_dir("problems") / robot).glob("*.toml"))[: args.count]
        times: dict[str, list[float]] = {"off": [], "on": []}
        for k, path in enumerate(files):
            problem = openup_ompl.load_scene(path)
            for seed in range(args.seeds):
                order = ("off", "on") if (k + seed) % 2 == 0 else ("on", "off")
                out = {mode: solve(problem, mode, args, seed) for mode in order}
                (p_off, t_off, n_off), (p_on, t_on, n_on) = out["off"], out["on"]
                if not np.array_equal(p_off.path, p_on.path) or n_off != n_on:
                    raise SystemExit(f"{path.stem} seed {seed}: the paths or counts differ")
                times["off"].append(t_off)
                times["on"].append(t_on)
        ratio = float(np.median(np.divide(times["off"], times["on"])))
        print(
            f"| `{robot}` | {len(times['on'])} | {1e3 * np.median(times['off']):.1f} | "
            f"{1e3 * np.median(times['on']):.1f} | {ratio:.2f} |"
        )


if __name__ == "__main__":
    main()
