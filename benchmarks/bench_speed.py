"""Speed over the problem suites: solve time, the law's price, the whole call, the command.

For every shipped robot's problem suite (``benchmarks/problems/<robot>/``) it solves each
problem with ``ikbirrt`` and ``rrtconnect`` (+ ``IKGoalRegion``, whose pregrasp states it
is given: ``PlanningOptions.pregrasp``), each with the hand law
and with the classical fixed preshape (hand frozen at ``w``), side by side in one process:
seed by seed, problem by problem, the four variants in an order that rotates from problem
to problem. It reports, per robot, planner and hand:

- solved runs, median and 95th percentile of the solve time (``Plan.solve_time_s``, what
  OMPL's ``solve`` took; a failed run counts as the time limit);
- the whole call: the median over runs of ``GraspPlanningSetup.solve()``'s wall time
  (densification of the path and the final check included) divided by its solve time;
- median state checks and IK calls per run (counts: the same for a seed on any machine);

then the law's price (law / fixed-``w`` suite medians, the median over problems of the
per-problem ratio of medians, and the geometric mean over runs of the ratio of the law's run
to the fixed hand's with the same problem and seed, split into the ratio of motions
checked, the search's size with the hand's shape, and of state checks per motion, the law's
own work; ``--fixed w b`` adds the fixed ``b`` preshape beside ``w``),
the targets of the speed issue against what was measured,
the ``openup-ompl plan`` command from process start to plan written (median of
``--cli-runs`` fresh processes on each robot's demo scene, with the import of the package
alone beside it), and ``tests/recheck.py`` over every ``--recheck-every``-th plan.

Run (about 4 min with the defaults on 2 idle cores)::

    python benchmarks/bench_speed.py
    python benchmarks/bench_speed.py --robots panda --seeds 10 --json speed.json
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from ompl import util as ou

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

import openup_ompl as oo  # noqa: E402
from openup_ompl._resources import data_dir  # noqa: E402
from openup_ompl.benchmark import default_problems_dir  # noqa: E402
from openup_ompl.planning import check_planner  # noqa: E402

#: The classical fixed preshapes the law is compared with by default (``--fixed``).
FIXED = ("w",)
#: The issue's targets: suite median [ms] of ikbirrt with the law, per robot.
MEDIAN_TARGET_MS = {"panda": 15.0, "ur5_allegro": 100.0, "lwa3_sdh": 60.0}
P95_TARGET_MS = {"panda": 100.0}
PRICE_TARGET = {"ikbirrt": 1.2, "rrtconnect": 1.3}
WALL_TARGET = 1.5


def hands_of(fixed: list[str]) -> list[str]:
    """The compared hands: ``"law"`` and ``"fixed <preshape>"`` for each of ``fixed``."""
    return ["law"] + [f"fixed {preshape}" for preshape in fixed]


def preshape_of(hand: str) -> str | None:
    """The fixed preshape of a hand of :func:`hands_of` (``None`` for the law)."""
    return None if hand == "law" else hand.split()[1]


def run_suites(
    robots: list[str],
    planners: list[str],
    seeds: int,
    time_limit: float,
    recheck_every: int,
    fixed: list[str],
    options: oo.PlanningOptions | None = None,
    first_seed: int = 1,
) -> tuple[list[dict[str, Any]], list[Any]]:
    """Every run's record, and the plans kept for the re-check (``options``: the setups'
    planning options, the fixed hand aside; ``None``: the package's defaults)."""
    hands = hands_of(fixed)
    setups: dict[tuple[str, str], oo.GraspPlanningSetup] = {}
    for robot in robots:
        for path in sorted(default_problems_dir(robot).glob("*.toml")):
            problem = oo.load_scene(path)
            for hand in hands:
                setups[(f"{robot}.{path.stem}", hand)] = oo.GraspPlanningSetup(
                    problem, options, fixed_hand=preshape_of(hand)
                )
    variants = [(hand, planner) for hand in hands for planner in planners]
    problems = sorted({name for name, _ in setups})
    runs: list[dict[str, Any]] = []
    kept: list[Any] = []
    total = seeds * len(problems) * len(variants)
    started = time.perf_counter()
    for done_seeds, seed in enumerate(range(first_seed, first_seed + seeds), start=1):
        for k, name in enumerate(problems):
            shift = (seed + k) % len(variants)
            for hand, planner in variants[shift:] + variants[:shift]:
                setup = setups[(name, hand)]
                begun = time.perf_counter()
                try:
                    plan = setup.solve(time_limit, planner=planner, seed=seed)
                except oo.PlanningFailed:
                    plan = None
                wall = time.perf_counter() - begun
                runs.append(
                    {
                        "robot": name.split(".")[0],
                        "problem": name,
                        "hand": hand,
                        "planner": planner,
                        "seed": seed,
                        "solved": plan is not None,
                        "solve_s": plan.solve_time_s if plan else time_limit,
                        "wall_s": wall,
                        "state_checks": plan.stats["state_checks"] if plan else None,
                        "motion_checks": plan.stats["motion_checks"] if plan else None,
                        "ik_calls": plan.stats["ik_calls"] if plan else None,
                    }
                )
                if plan is not None and len(runs) % recheck_every == 0:
                    kept.append(plan)
        done = done_seeds * len(problems) * len(variants)
        print(
            f"  seed {seed} ({done_seeds}/{seeds}): {done}/{total} runs, "
            f"{time.perf_counter() - started:.0f} s",
            file=sys.stderr,
        )
    return runs, kept


def _cell(runs: list[dict[str, Any]]) -> dict[str, Any]:
    solve = [r["solve_s"] for r in runs]
    solved = [r for r in runs if r["solved"]]
    return {
        "runs": len(runs),
        "solved": len(solved),
        "median_ms": 1e3 * _common.median(solve),
        "p95_ms": 1e3 * _common.percentile(solve, 95),
        "wall_ratio": _common.median([r["wall_s"] / r["solve_s"] for r in solved]),
        "state_checks": _common.median([r["state_checks"] for r in solved]),
        "ik_calls": _common.median([r["ik_calls"] for r in solved]),
    }


def _geomean_of_logs(logs: list[float]) -> float:
    return math.exp(sum(logs) / len(logs)) if logs else math.nan


def summarize(
    runs: list[dict[str, Any]], robots: list[str], planners: list[str], fixed: list[str]
) -> dict:
    hands = hands_of(fixed)
    cells = {}
    prices = {}
    for robot in robots:
        for planner in planners:
            for hand in hands:
                chosen = [
                    r
                    for r in runs
                    if (r["robot"], r["planner"], r["hand"]) == (robot, planner, hand)
                ]
                cells[(robot, planner, hand)] = _cell(chosen)
            problems = sorted({r["problem"] for r in runs if r["robot"] == robot})
            medians = {
                (problem, hand): _common.median(
                    [
                        r["solve_s"]
                        for r in runs
                        if (r["problem"], r["planner"], r["hand"]) == (problem, planner, hand)
                    ]
                )
                for problem in problems
                for hand in hands
            }
            law = cells[(robot, planner, "law")]
            times = {
                (r["problem"], r["seed"], r["hand"]): r["solve_s"]
                for r in runs
                if (r["robot"], r["planner"]) == (robot, planner)
            }
            solved = {
                (r["problem"], r["seed"], r["hand"]): r
                for r in runs
                if (r["robot"], r["planner"]) == (robot, planner) and r["solved"]
            }
            for hand in hands[1:]:
                per_problem = [medians[(p, "law")] / medians[(p, hand)] for p in problems]
                # The same problem and seed with either hand: ikbirrt then grows the same
                # trees wherever the two hands agree, so the ratio is the law's own work.
                paired = [
                    math.log(time / times[(problem, seed, hand)])
                    for (problem, seed, kind), time in times.items()
                    if kind == "law"
                ]
                # The paired price split in two, over the pairs both hands solved: how many
                # motions the search checked (the hand's shape: how hard the scene is with
                # it), and how many states each motion cost (the law's own work: the
                # fingers' motion widens every motion's displacement bound).
                both = [
                    (run, solved[(problem, seed, hand)])
                    for (problem, seed, kind), run in solved.items()
                    if kind == "law"
                    and (problem, seed, hand) in solved
                    and run["motion_checks"]
                    and solved[(problem, seed, hand)]["motion_checks"]
                ]
                motions = [math.log(a["motion_checks"] / b["motion_checks"]) for a, b in both]
                per_motion = [
                    math.log(
                        (a["state_checks"] / a["motion_checks"])
                        / (b["state_checks"] / b["motion_checks"])
                    )
                    for a, b in both
                ]
                prices[(robot, planner, hand)] = {
                    "suite": law["median_ms"] / cells[(robot, planner, hand)]["median_ms"],
                    "per_problem_median": _common.median(per_problem),
                    "per_problem_max": max(per_problem),
                    "paired_geomean": math.exp(sum(paired) / len(paired)),
                    "motions_geomean": _geomean_of_logs(motions),
                    "checks_per_motion_geomean": _geomean_of_logs(per_motion),
                }
    return {"cells": cells, "prices": prices}


def time_command(scene: Path, runs: int) -> dict[str, float]:
    """Median wall time [s] of ``openup-ompl plan`` in a fresh process, start to plan
    written, and of ``import openup_ompl`` alone."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    plan_times, import_times = [], []
    with tempfile.TemporaryDirectory() as directory:
        out = Path(directory) / "plan.json"
        command = [sys.executable, "-m", "openup_ompl", "plan", str(scene)]
        for run in range(runs):
            begun = time.perf_counter()
            subprocess.run(
                [*command, "--seed", str(run + 1), "--out", str(out)],
                check=True,
                capture_output=True,
                env=env,
            )
            plan_times.append(time.perf_counter() - begun)
            begun = time.perf_counter()
            subprocess.run([sys.executable, "-c", "import openup_ompl"], check=True, env=env)
            import_times.append(time.perf_counter() - begun)
    return {"plan_s": _common.median(plan_times), "import_s": _common.median(import_times)}


def prefilter_floor(robot: str, states: int = 2000) -> dict[str, float]:
    """What a link-sphere prefilter in Python would pay per state at the least [us]:
    Pinocchio's forward kinematics and reading every joint's placement (the spheres'
    centres need them), against the exact check it would spare (``in_collision``: forward
    kinematics, Coal's broadphase and narrow phase), on the same states of a suite
    problem's plans."""
    import pinocchio as pin

    setup = oo.GraspPlanningSetup(oo.load_scene(default_problems_dir(robot) / "table_pick.toml"))
    qs = np.concatenate([setup.solve(seed=seed).path for seed in range(1, 4)])[:states]
    model = setup.problem.robot.model
    data = model.createData()
    joints = range(1, model.njoints)
    world = setup.checker.finest_world
    begun = time.perf_counter()
    for q in qs:
        pin.forwardKinematics(model, data, q)
        placements = [data.oMi[j].homogeneous for j in joints]
    fk = (time.perf_counter() - begun) / len(qs) * 1e6
    begun = time.perf_counter()
    for q in qs:
        world.in_collision(q)
    exact = (time.perf_counter() - begun) / len(qs) * 1e6
    del placements
    return {"fk_and_placements_us": fk, "exact_check_us": exact}


def _target(value: float, limit: float) -> str:
    return f"{value:.3g} ({'met' if value <= limit else 'not met'}, target ≤ {limit:g})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", nargs="+", default=["panda", "lwa3_sdh", "ur5_allegro"])
    parser.add_argument("--planners", nargs="+", default=["ikbirrt", "rrtconnect"])
    parser.add_argument("--seeds", type=int, default=5, help="seeds per problem (default 5)")
    parser.add_argument(
        "--first-seed", type=int, default=1, help="seeds run from this one (default 1)"
    )
    parser.add_argument("--time", type=float, default=5.0, help="seconds per solve (5)")
    parser.add_argument("--recheck-every", type=int, default=5, help="re-check every Nth plan")
    parser.add_argument("--cli-runs", type=int, default=3, help="fresh processes per robot")
    parser.add_argument(
        "--fixed",
        nargs="+",
        default=list(FIXED),
        choices=["c", "b", "w"],
        help="fixed preshapes to compare the law with (default w; the targets are for w)",
    )
    parser.add_argument(
        "--pregrasp",
        type=float,
        default=oo.PlanningOptions.pregrasp,
        help="the goal region's pregrasp distance [m] for rrtconnect (default: the package's, "
        "%(default)s)",
    )
    parser.add_argument("--continuous", action="store_true", help="the law without the jump at mga")
    parser.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    args = parser.parse_args()
    if (
        args.seeds < 1
        or args.first_seed < 1
        or args.time <= 0
        or args.recheck_every < 1
        or args.cli_runs < 0
    ):
        parser.error(
            "--seeds, --first-seed, --recheck-every must be >= 1, --time > 0, --cli-runs >= 0"
        )
    for robot in args.robots:
        if robot not in MEDIAN_TARGET_MS:
            parser.error(f"--robots: {robot!r} is not one of {sorted(MEDIAN_TARGET_MS)}")
    for planner in args.planners:
        check_planner(planner)
    try:
        options = oo.PlanningOptions(
            pregrasp=args.pregrasp, continuous=True if args.continuous else None
        )
    except oo.ConfigError as error:
        parser.error(str(error))
    ou.RNG.setSeed(1)
    ou.setLogLevel(ou.LogLevel.LOG_NONE)
    info = _common.machine_info()

    runs, kept = run_suites(
        args.robots,
        args.planners,
        args.seeds,
        args.time,
        args.recheck_every,
        args.fixed,
        options,
        args.first_seed,
    )
    summary = summarize(runs, args.robots, args.planners, args.fixed)
    checked, passed = _common.recheck_plans(kept)
    floors = {robot: prefilter_floor(robot) for robot in args.robots}
    commands = {
        robot: time_command(sorted(data_dir("scenes").glob(f"{robot}_*.toml"))[0], args.cli_runs)
        for robot in args.robots
        if args.cli_runs
    }

    print(_common.machine_line(info))
    print()
    print(
        f"Each robot's suite, {args.seeds} seeds per problem (from {args.first_seed}), "
        f"{args.time:g} s limit; "
        "median / p95 over all runs (failed = the limit); wall / solve: "
        "`GraspPlanningSetup.solve()` over its solve time, median of the runs."
    )
    print()
    rows = []
    for (robot, planner, hand), cell in summary["cells"].items():
        rows.append(
            [
                robot,
                planner,
                "law" if hand == "law" else f"fixed `{preshape_of(hand)}`",
                f"{cell['solved']}/{cell['runs']}",
                f"{cell['median_ms']:.1f}",
                f"{cell['p95_ms']:.0f}",
                f"{cell['wall_ratio']:.2f}",
                f"{cell['state_checks']:.0f}",
                f"{cell['ik_calls']:.0f}",
            ]
        )
    print(
        _common.markdown_table(
            [
                "robot",
                "planner",
                "hand",
                "solved",
                "median [ms]",
                "p95 [ms]",
                "wall / solve",
                "state checks",
                "IK calls",
            ],
            rows,
            left=3,
        )
    )
    print()
    rows = [
        [
            robot,
            planner,
            f"`{preshape_of(hand)}`",
            f"{price['suite']:.2f}",
            f"{price['per_problem_median']:.2f}",
            f"{price['per_problem_max']:.2f}",
            f"{price['paired_geomean']:.2f}",
            f"{price['motions_geomean']:.2f}",
            f"{price['checks_per_motion_geomean']:.2f}",
            f"≤ {PRICE_TARGET.get(planner, 1.2):g}" if preshape_of(hand) == "w" else "",
        ]
        for (robot, planner, hand), price in summary["prices"].items()
    ]
    print(
        _common.markdown_table(
            [
                "robot",
                "planner",
                "against",
                "law / fixed, suite medians",
                "per problem, median",
                "per problem, max",
                "per run, same seed (geometric mean)",
                "of which motions",
                "of which checks / motion",
                "target",
            ],
            rows,
            left=3,
        )
    )
    print()
    print("Targets:")
    for robot in args.robots:
        cell = summary["cells"].get((robot, "ikbirrt", "law"))
        if cell is None:
            continue
        median = _target(cell["median_ms"], MEDIAN_TARGET_MS[robot])
        line = f"- {robot}, ikbirrt with the law: median {median} ms"
        if robot in P95_TARGET_MS:
            line += f", p95 {_target(cell['p95_ms'], P95_TARGET_MS[robot])} ms"
        line += f", solved {cell['solved']}/{cell['runs']}"
        print(line)
    walls = [c["wall_ratio"] for c in summary["cells"].values()]
    print(f"- solve() wall / solve time, worst cell: {_target(max(walls), WALL_TARGET)}")
    for robot, timing in commands.items():
        print(
            f"- `openup-ompl plan` on {robot}'s demo scene, process start to plan written: "
            f"{timing['plan_s']:.2f} s median of {args.cli_runs} (of which "
            f"`import openup_ompl` alone {timing['import_s']:.2f} s)"
        )
    for robot, floor in floors.items():
        print(
            f"- prefilter floor, {robot}: forward kinematics + every joint placement "
            f"{floor['fk_and_placements_us']:.1f} us/state against the exact check "
            f"{floor['exact_check_us']:.1f} us/state it would spare"
        )
    print(f"recheck: {passed}/{checked} plans pass tests/recheck.py")
    _common.write_json(
        args.json,
        {
            "machine": info,
            "args": vars(args),
            "runs": runs,
            "cells": [
                {"robot": k[0], "planner": k[1], "hand": k[2], **v}
                for k, v in summary["cells"].items()
            ],
            "prices": [
                {"robot": k[0], "planner": k[1], "against": k[2], **v}
                for k, v in summary["prices"].items()
            ],
            "commands": commands,
            "prefilter_floor": floors,
            "recheck": {"checked": checked, "passed": passed},
        },
    )
    if passed != checked:
        sys.exit(f"{checked - passed} plans failed the re-check")


if __name__ == "__main__":
    main()
