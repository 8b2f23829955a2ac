"""``openup-ompl study``: the paired study of families x error sources x policies."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

__all__ = ["add_parser", "study_command"]


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``study`` to the command line's subparsers (:mod:`openup_ompl.cli`).

    Args:
        subparsers: The command line's subparsers action.

    Returns:
        The ``study`` parser.
    """
    from openup_ompl.cli._common import (
        add_executor_options,
        count,
        out_path,
        planner,
        seed,
        time_limit,
    )
    from openup_ompl.study.errors import DEFAULT_ERRORS
    from openup_ompl.study.families import KINDS, ROBOTS
    from openup_ompl.study.policies import DEFAULT_POLICIES

    study = subparsers.add_parser(
        "study",
        help="where does opening the hand pay? paired trials of scene families, error"
        " sources and policies, executed in physics",
    )
    study.add_argument(
        "--family",
        nargs="+",
        default=None,
        metavar="NAME",
        help=f"families '<robot>-<kind>', a kind for every robot or 'all' (robots"
        f" {list(ROBOTS)}, kinds {list(KINDS)}; default: all, or none with --scene)",
    )
    study.add_argument(
        "--scene", type=Path, default=None, help="a scene file as a family (only the error drawn)"
    )
    study.add_argument(
        "--error",
        nargs="+",
        default=list(DEFAULT_ERRORS),
        metavar="SOURCE",
        help="error sources: pose-<sigma>cm, perceived[-<noise scale>]",
    )
    study.add_argument(
        "--policies", nargs="+", default=list(DEFAULT_POLICIES), metavar="POLICY",
        help="u values in [0, 1] and/or covariance, diameter, residual, capped, adaptive",
    )  # fmt: skip
    study.add_argument("--trials", type=count, default=20, help="paired trials per cell")
    study.add_argument("--chunk", type=count, default=10, help="trials per task (shard file)")
    study.add_argument("--seed", type=seed, default=1, help="the study's seed")
    study.add_argument(
        "--planner", type=planner, default="ikbirrt", metavar="NAME",
        help="planner name",
    )  # fmt: skip
    study.add_argument("--time", type=time_limit, default=5.0, help="time limit per plan [s]")
    study.add_argument("--out", type=out_path, required=True, help="output directory")
    add_executor_options(study)
    study.add_argument("--quiet", action="store_true", help="no progress on stderr")
    study.set_defaults(handler=study_command)
    return study


def study_command(args: argparse.Namespace) -> int:
    """Run the study and print each cell's successes per policy and where its outputs are.

    Args:
        args: The parsed command line.

    Returns:
        The exit status, 0.
    """
    from openup_ompl.cli._common import dir_out
    from openup_ompl.study.families import parse_families
    from openup_ompl.study.run import StudyOptions
    from openup_ompl.study.sweep import run_study

    dir_out(args.out)
    families = parse_families(args.family, args.scene)
    options = StudyOptions(
        tuple(families),
        errors=tuple(args.error),
        policies=tuple(args.policies),
        trials=args.trials,
        seed=args.seed,
        planner=args.planner,
        time_limit=args.time,
        chunk=args.chunk,
    )
    result = run_study(
        options, args.out, workers=args.workers, scheduler=args.scheduler, quiet=args.quiet
    )
    cells: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for row in result.rows:
        cells.setdefault((row["family"], row["error"]), []).append(row)
    for (family, error), rows in cells.items():
        shown = ", ".join(f"{r['policy']} {r['successes']}/{r['trials']}" for r in rows)
        print(f"{family} {error}: {shown}")
    print(f"wrote {result.map_csv}, {result.pairs_csv}", end="")
    print(f", {result.figure}" if result.figure else "", file=sys.stdout)
    return 0
