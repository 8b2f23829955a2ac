"""The hand law against the classical fixed preshape, from a benchmark's ``summary.json``.

Reads the output of ``openup-ompl benchmark --fixed-hand`` (both hands ran the same seeds
side by side in one sweep) and prints, per robot and planner, the median solve time of
each hand over the robot's suite and their ratio, then the median over the problem x
planner cells of the per-cell ratio of medians, and the cells above the issue's 1.2x.
``--table`` also prints the README's per-problem table (both hands side by side).

    python benchmarks/law_vs_fixed.py openup-benchmark/summary.json
"""

from __future__ import annotations

import argparse
import json
import sqlite3
from collections import defaultdict
from pathlib import Path

import numpy as np

TARGET = 1.2


def _suite_medians(database: Path) -> dict[tuple[str, str, str], float]:
    """Median OMPL ``time`` over every run of a robot's suite, per planner and hand."""
    times: dict[tuple[str, str, str], list[float]] = defaultdict(list)
    with sqlite3.connect(database) as db:
        rows = db.execute(
            "SELECT runs.problem, plannerConfigs.name, runs.hand, runs.time FROM runs "
            "JOIN plannerConfigs ON runs.plannerid = plannerConfigs.id"
        ).fetchall()
    for problem, planner, hand, time in rows:
        robot = problem.split(".")[0]
        name = planner.split("_fixed_w")[0].replace("geometric_", "").lower()
        times[(robot, name, hand)].append(float(time))
    return {key: float(np.median(value)) for key, value in times.items()}


def _per_problem_table(rows: list[dict]) -> None:
    by_cell = {(r["problem"], r["planner"], r["hand"]): r for r in rows}
    print()
    print(
        "| problem | planner | success | median [ms] | p95 [ms] | path length [rad] "
        "| fixed-`w` success | fixed-`w` median [ms] | law / fixed median |"
    )
    print("|:--|:--|--:|--:|--:|--:|--:|--:|--:|")
    for problem, planner in sorted({(r["problem"], r["planner"]) for r in rows}):
        law = by_cell.get((problem, planner, "law"))
        fixed = by_cell.get((problem, planner, "fixed"))
        if law is None or fixed is None:
            continue
        print(
            f"| {problem} | {planner} | {law['success']:.0%} | {law['median_time'] * 1e3:.0f} "
            f"| {law['p95_time'] * 1e3:.0f} | {law['length']:.2f} | {fixed['success']:.0%} "
            f"| {fixed['median_time'] * 1e3:.0f} "
            f"| {law['median_time'] / fixed['median_time']:.2f} |".replace("%", " %")
        )
    print()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("summary", type=Path, help="summary.json of a --fixed-hand benchmark")
    parser.add_argument("--table", action="store_true", help="also print the per-problem table")
    args = parser.parse_args()
    if not args.summary.is_file():
        parser.error(f"no such file: {args.summary}")
    rows = json.loads(args.summary.read_text())["rows"]
    cells: dict[tuple[str, str], dict[str, float]] = defaultdict(dict)
    for row in rows:
        cells[(row["problem"], row["planner"])][row["hand"]] = row["median_time"]
    ratios = {
        key: hands["law"] / hands["fixed"]
        for key, hands in sorted(cells.items())
        if {"law", "fixed"} <= hands.keys()
    }
    if not ratios:
        raise SystemExit(f"{args.summary}: no cell ran both hands (run with --fixed-hand)")

    database = args.summary.with_name("benchmark.db")
    if database.exists():
        medians = _suite_medians(database)
        print("| robot | planner | law median [ms] | fixed-w median [ms] | law / fixed |")
        print("|:--|:--|--:|--:|--:|")
        for robot, planner in sorted({(r, p) for r, p, _ in medians}):
            law = medians.get((robot, planner, "law"))
            fixed = medians.get((robot, planner, "fixed"))
            if law is not None and fixed is not None:
                print(
                    f"| `{robot}` | `{planner}` | {law * 1e3:.0f} | {fixed * 1e3:.0f} "
                    f"| {law / fixed:.2f} |"
                )
        print()
    values = np.array(list(ratios.values()))
    print(
        f"per-cell law / fixed median: median {np.median(values):.2f} over {values.size} cells "
        f"(range {values.min():.2f}-{values.max():.2f}); "
        f"{int(np.sum(values <= TARGET))}/{values.size} cells at most {TARGET}x"
    )
    if args.table:
        _per_problem_table(rows)
    by_planner: dict[str, list[float]] = defaultdict(list)
    for (problem, planner), ratio in ratios.items():
        by_planner[f"{problem.split('.')[0]} {planner}"].append(ratio)
    for name, values_ in sorted(by_planner.items()):
        print(f"  {name}: median of cell ratios {np.median(values_):.2f}")


if __name__ == "__main__":
    main()
