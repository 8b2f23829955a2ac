"""``openup-ompl benchmark``: a problem suite through ``ompl.tools.Benchmark``."""

from __future__ import annotations

import argparse
from pathlib import Path

from openup_ompl.cli._common import add_executor_options, count, dir_out, out_path, seed, time_limit

HELP = "run a problem suite through ompl.tools.Benchmark; OMPL logs, database, plots"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Problems, planners, runs, time, output and where the tasks run.

    Args:
        parser: The command's parser, given its options.
    """
    from openup_ompl.planning import PLANNERS

    parser.add_argument(
        "--problems",
        type=Path,
        nargs="+",
        default=None,
        help="scene files or directories (default: every robot's suite, benchmarks/problems/*)",
    )
    parser.add_argument(
        "--planners",
        nargs="+",
        default=["ikbirrt", "rrtconnect"],
        metavar="NAME",
        help=f"one or more of {', '.join(PLANNERS)}",
    )
    parser.add_argument("--runs", type=count, default=10, help="runs per problem, planner and hand")
    parser.add_argument("--time", type=time_limit, default=5.0, help="time limit per run [s]")
    parser.add_argument(
        "--fixed-hand", action="store_true", help="also run the fixed preshape (hand frozen at w)"
    )
    parser.add_argument(
        "--out", type=out_path, default=Path("openup-benchmark"), help="output directory"
    )
    add_executor_options(parser)
    parser.add_argument("--seed", type=seed, default=1, help="seed of run 0 (run i: seed + i)")
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")


def run(args: argparse.Namespace) -> int:
    """Run the benchmark, then print the table and where the outputs are; returns 0.

    Args:
        args: The parsed command line.

    Returns:
        The exit status.
    """
    from openup_ompl.benchmark import default_problems, run_benchmark
    from openup_ompl.benchmark_report import markdown_table

    dir_out(args.out)
    problems = args.problems or default_problems()
    result = run_benchmark(
        problems,
        args.planners,
        args.out,
        runs=args.runs,
        time_limit=args.time,
        fixed_hand=args.fixed_hand,
        workers=args.workers,
        scheduler=args.scheduler,
        seed=args.seed,
        quiet=args.quiet,
    )
    print(markdown_table(result.rows))
    print(f"OMPL logs in {result.logs}")
    print(f"database (Planner Arena) written to {result.database}")
    print(f"summary written to {result.summary}")
    for plot in result.plots:
        print(f"plot written to {plot}")
    return 0
