"""Where planning's time goes: the share of ``GraspPlanningSetup.solve`` spent in single
state checks (which the compiled check replaces) and in motion checks (whose serial
batches' query loop it replaces, not the states' placement and hands), under cProfile;
with the Python check (``--native off``, the default) or the compiled one (``on``).

Run (about 10 s)::

    python benchmarks/native/solve_profile.py
    python benchmarks/native/solve_profile.py --problems benchmarks/problems/ur5_allegro --seeds 2
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time
from pathlib import Path

from ompl import util as ou

import openup_ompl
from openup_ompl._resources import data_dir

#: The functions reported: (module file name, function name) -> label.
FUNCTIONS = {
    ("state_check.py", "_check_state"): "single states (`StateChecker._check_state`)",
    ("validity.py", "check_motion"): "motions (`CoupledChecker.check_motion`)",
    ("state_check.py", "_batch_collides"): "  batches (`_batch_collides`, the re-check's too)",
    ("state_check.py", "_set_hands"): "  the batches' hands (`_set_hands`)",
    ("collision.py", "batch_in_collision"): "`CollisionWorld.batch_in_collision` (all callers)",
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--problems", type=Path, default=data_dir("problems") / "panda", help="a suite folder"
    )
    parser.add_argument("--count", type=int, default=4, help="problems of the suite (4)")
    parser.add_argument("--seeds", type=int, default=2, help="seeds per problem (2)")
    parser.add_argument("--time", type=float, default=5.0, help="time limit [s] (5)")
    parser.add_argument("--planner", default="ikbirrt", help="planner (ikbirrt)")
    parser.add_argument("--native", choices=["off", "on"], default="off", help="(off)")
    args = parser.parse_args()
    ou.setLogLevel(ou.LOG_ERROR)
    files = sorted(args.problems.glob("*.toml"))[: args.count]
    profile = cProfile.Profile(time.process_time)
    solves = 0
    for path in files:
        problem = openup_ompl.load_scene(path)
        for seed in range(args.seeds):
            setup = openup_ompl.GraspPlanningSetup(problem, native=args.native)
            profile.enable()
            setup.solve(args.time, args.planner, seed)
            profile.disable()
            solves += 1
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
    total = max(ct for (_, _, name), (_, _, _, ct, _) in stats.items() if name == "solve")
    print(f"{solves} solves ({args.planner}) of {', '.join(p.stem for p in files)}: ")
    print(f"{1e3 * total:.0f} ms of CPU time in solve")
    for (file_name, function), label in FUNCTIONS.items():
        entries = [
            (calls, ct)
            for (path, _, name), (_, calls, _, ct, _) in stats.items()
            if name == function and path.endswith(file_name)
        ]
        calls, cumulative = sum(c for c, _ in entries), sum(t for _, t in entries)
        print(f"- {label}: {calls} calls, {1e3 * cumulative:.1f} ms ({cumulative / total:.0%})")


if __name__ == "__main__":
    main()
