"""Planning time and success: planners, and the hand law against a fixed preshape.

For every (hand, planner) variant, ``GraspPlanningSetup.solve`` runs once per seed with a
time limit; the variants are interleaved per seed (order rotated every seed) so that a
noisy machine slows them alike. Hands: the law (``GraspPlanningSetup(problem)``) and the
classical fixed preshape baseline (``GraspPlanningSetup(problem, fixed_hand="w")``), which
may make the problem infeasible (reported as such). A failed solve
(``PlanningFailed``) counts as a failure with time = the time limit in the percentiles.

Reported per variant: success rate, median and 95th-percentile solve time, paired ratio
to the reference variant (the first one: median over seeds of this variant's time /
the reference's time on the same seed), and means over successful runs of waypoints,
joint-space path length (sum of the norms of the steps of ``plan.arm_path``), and
``plan.stats`` (state checks, IK calls).

The planner name ``ikbirrt-plain`` is IKBiRRT without the goal tree's retreat
(``IKBiRRTOptions(retreat=0)``), and ``rrtconnect-plain`` OMPL's RRTConnect given the grasp
configurations instead of the goal region's pregrasp states (``pregrasp=0``), to measure
what the retreat and the pregrasp buy side by side.

Run (about 20 s on 2 idle cores; at worst seeds x variants x time limit)::

    python benchmarks/bench_planning.py
    python benchmarks/bench_planning.py --seeds 20 --time-limit 5 \
        --planners ikbirrt rrtconnect --fixed-hand w --json bench_planning.json
    python benchmarks/bench_planning.py --scene benchmarks/problems/panda/shelf_small.toml \
        --planners ikbirrt ikbirrt-plain --seeds 10
    python benchmarks/bench_planning.py --planners rrtconnect rrtconnect-plain --seeds 20
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from ompl import util as ou

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

import openup_ompl  # noqa: E402

#: Bench-only planner name: IKBiRRT without the goal tree's retreat.
PLAIN = "ikbirrt-plain"
#: Bench-only planner name: RRTConnect given grasp configurations, not pregrasp states.
RRTCONNECT_PLAIN = "rrtconnect-plain"


def build_setups(
    problem: openup_ompl.Problem, fixed_hand: str | None, batch_threads: int | None
) -> dict[str, openup_ompl.GraspPlanningSetup | str]:
    """Hand mode -> setup, or the reason it is infeasible."""
    modes: dict[str, dict[str, Any]] = {"law": {}}
    if fixed_hand is not None:
        modes[f"fixed {fixed_hand}"] = {"fixed_hand": fixed_hand}
    setups: dict[str, openup_ompl.GraspPlanningSetup | str] = {}
    for mode, kwargs in modes.items():
        try:
            setup = openup_ompl.GraspPlanningSetup(problem, **kwargs)
        except (openup_ompl.UnreachableGrasp, openup_ompl.InvalidProblem) as error:
            setups[mode] = f"infeasible: {type(error).__name__}: {error}"
            continue
        if batch_threads is not None:
            # Diagnostic knob: the world builds its parallel pool lazily, on the first
            # batched query (none has run yet), with this many threads.
            setup.checker.world.num_threads = batch_threads
        setups[mode] = setup
    return setups


def path_length(arm_path: np.ndarray) -> float:
    """Joint-space length [rad]: sum of the norms of consecutive differences."""
    return float(np.linalg.norm(np.diff(arm_path, axis=0), axis=1).sum())


def run_once(
    setup: openup_ompl.GraspPlanningSetup, planner: str, seed: int, time_limit: float
) -> dict[str, Any]:
    checks_before = setup.checker.states_checked
    ik_before = setup.ik.calls
    started = time.perf_counter()
    instance: str | openup_ompl.IKBiRRT = planner
    if planner == PLAIN:
        options = openup_ompl.IKBiRRTOptions(retreat=0.0)
        instance = openup_ompl.IKBiRRT(setup.space_information, options)
    pregrasp = setup.goal_region.pregrasp
    if planner == RRTCONNECT_PLAIN:
        instance = "rrtconnect"
        setup.goal_region.pregrasp = 0.0
    try:
        plan = setup.solve(time_limit=time_limit, planner=instance, seed=seed)
    except openup_ompl.PlanningFailed as error:
        return {
            "success": False,
            "time_s": time_limit,
            "wall_s": time.perf_counter() - started,
            "error": str(error),
            "state_checks": setup.checker.states_checked - checks_before,
            "ik_calls": setup.ik.calls - ik_before,
        }
    finally:
        setup.goal_region.pregrasp = pregrasp
    return {
        "success": True,
        "time_s": plan.solve_time_s,
        "wall_s": time.perf_counter() - started,
        "waypoints": int(plan.waypoints.shape[0]),
        "path_length": path_length(plan.arm_path),
        "state_checks": int(plan.stats["state_checks"]),
        "ik_calls": int(plan.stats["ik_calls"]),
        "motion_checks": int(plan.stats.get("motion_checks", 0)),
    }


def summarize(runs: list[dict[str, Any]], reference: list[dict[str, Any]] | None) -> dict:
    times = [r["time_s"] for r in runs]
    ok = [r for r in runs if r["success"]]

    def mean(key: str) -> float:
        return float(np.mean([r[key] for r in ok])) if ok else float("nan")

    paired = float("nan")
    if reference is not None:
        by_seed = {r["seed"]: r["time_s"] for r in reference}
        ratios = [r["time_s"] / by_seed[r["seed"]] for r in runs if r["seed"] in by_seed]
        paired = _common.median(ratios)
    return {
        "runs": len(runs),
        "successes": len(ok),
        "success_rate": len(ok) / len(runs) if runs else float("nan"),
        "median_s": _common.median(times),
        "p95_s": _common.percentile(times, 95),
        "median_s_successful": _common.median([r["time_s"] for r in ok]),
        "paired_ratio_to_reference": paired,
        "mean_waypoints": mean("waypoints"),
        "mean_path_length": mean("path_length"),
        "mean_state_checks": mean("state_checks"),
        "mean_ik_calls": mean("ik_calls"),
    }


def fmt(value: float, spec: str) -> str:
    return "-" if math.isnan(value) else format(value, spec)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--scene", default=None, help="scene TOML (default: scenes/panda_can.toml, the Panda's can)"
    )
    parser.add_argument(
        "--planners",
        nargs="+",
        default=["ikbirrt", "rrtconnect"],
        help=f"planner names, from {list(openup_ompl.PLANNERS)}, {PLAIN} and {RRTCONNECT_PLAIN}",
    )
    parser.add_argument("--seeds", type=int, default=20, help="seeds per variant (default 20)")
    parser.add_argument("--first-seed", type=int, default=0, help="first seed (default 0)")
    parser.add_argument("--time-limit", type=float, default=5.0, help="seconds per solve (5)")
    parser.add_argument(
        "--fixed-hand",
        default="w",
        help="baseline preshape held for the whole reach: c, b or w (default w), "
        "or 'none' for no baseline",
    )
    parser.add_argument(
        "--ompl-seed",
        type=int,
        default=1,
        help="ompl.util.RNG.setSeed before any OMPL object (OMPL's planners draw from it)",
    )
    parser.add_argument(
        "--batch-threads",
        type=int,
        default=None,
        help="threads of the batched motion checks (default: the package's, all cores)",
    )
    parser.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    args = parser.parse_args()
    if args.seeds < 1 or not args.time_limit > 0:
        parser.error("--seeds must be >= 1 and --time-limit > 0")
    names = (*openup_ompl.PLANNERS, PLAIN, RRTCONNECT_PLAIN)
    unknown = [p for p in args.planners if p.lower() not in names]
    if unknown:
        parser.error(f"unknown planners {unknown}: expected some of {list(openup_ompl.PLANNERS)}")
    fixed_hand = None if args.fixed_hand.lower() == "none" else args.fixed_hand
    if fixed_hand not in (None, "c", "b", "w"):
        parser.error(f"--fixed-hand: got {args.fixed_hand!r}, expected c, b, w or none")

    ou.RNG.setSeed(args.ompl_seed)
    ou.setLogLevel(ou.LOG_ERROR)
    info = _common.machine_info()
    scene = args.scene or openup_ompl.default_scene_path()
    problem = openup_ompl.load_scene(scene)
    setups = build_setups(problem, fixed_hand, args.batch_threads)

    variants = [(mode, planner) for mode in setups for planner in args.planners]
    runnable = [v for v in variants if not isinstance(setups[v[0]], str)]
    runs: dict[tuple[str, str], list[dict[str, Any]]] = {v: [] for v in variants}
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    total = len(runnable) * len(seeds)
    done = 0
    started = time.perf_counter()
    for k, seed in enumerate(seeds):
        order = runnable[k % len(runnable) :] + runnable[: k % len(runnable)] if runnable else []
        for mode, planner in order:
            setup = setups[mode]
            assert not isinstance(setup, str)
            result = run_once(setup, planner, seed, args.time_limit)
            result.update(seed=seed, hand=mode, planner=planner)
            runs[(mode, planner)].append(result)
            done += 1
            outcome = (
                f"ok {result['time_s']:.3f} s, {result['waypoints']} waypoints"
                if result["success"]
                else f"FAILED ({result['error']})"
            )
            print(
                f"[{done}/{total}] {mode:>8} {planner:<12} seed {seed:>3}: {outcome}",
                file=sys.stderr,
                flush=True,
            )
    elapsed = time.perf_counter() - started

    reference = runs[runnable[0]] if runnable else None
    summary = {}
    rows = []
    for mode, planner in variants:
        setup = setups[mode]
        if isinstance(setup, str):
            summary[f"{mode}/{planner}"] = {"infeasible": setup}
            rows.append([mode, planner, "infeasible", *["-"] * 7])
            continue
        s = summarize(runs[(mode, planner)], reference)
        summary[f"{mode}/{planner}"] = s
        rows.append(
            [
                mode,
                planner,
                f"{s['successes']}/{s['runs']}",
                fmt(s["median_s"], ".3f"),
                fmt(s["p95_s"], ".3f"),
                fmt(s["paired_ratio_to_reference"], ".2f"),
                fmt(s["mean_waypoints"], ".1f"),
                fmt(s["mean_path_length"], ".2f"),
                fmt(s["mean_state_checks"], ",.0f"),
                fmt(s["mean_ik_calls"], ".1f"),
            ]
        )
    ref_name = "/".join(runnable[0]) if runnable else "-"
    threads = {
        mode: setup.checker.world.num_threads
        for mode, setup in setups.items()
        if not isinstance(setup, str)
    }
    thread_text = "/".join(str(n) for n in sorted(set(threads.values()))) or "-"
    out = [
        "## Planning: solve time and success",
        "",
        _common.machine_line(info),
        "",
        f"Scene `{Path(scene).name}`, {len(seeds)} seeds ({seeds[0]}..{seeds[-1]}), time limit "
        f"{args.time_limit:g} s, variants interleaved per seed, OMPL RNG seed {args.ompl_seed}, "
        f"batched motion checks on {thread_text} thread(s). A failure "
        "counts as the time limit. Ratio: median over seeds of time / time of "
        f"`{ref_name}` on the same seed. Waypoints, path length (joint space, rad), state "
        f"checks and IK calls: means over successful runs. Total {elapsed:.0f} s.",
        "",
        _common.markdown_table(
            [
                "hand",
                "planner",
                "success",
                "median s",
                "p95 s",
                "ratio",
                "waypoints",
                "length rad",
                "state checks",
                "IK calls",
            ],
            rows,
            left=2,
        ),
    ]
    for mode, setup in setups.items():
        if isinstance(setup, str):
            out += ["", f"`{mode}`: {setup}"]
    print("\n".join(out))
    _common.write_json(
        args.json,
        {
            "benchmark": "bench_planning",
            "machine": info,
            "scene": str(scene),
            "args": {k: v for k, v in vars(args).items() if k != "json"},
            "reference": ref_name,
            "summary": summary,
            "runs": [r for v in variants for r in runs[v]],
            "elapsed_s": elapsed,
        },
    )


if __name__ == "__main__":
    main()
