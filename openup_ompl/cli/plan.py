"""``openup-ompl plan SCENE.toml``: plan a scene file and write the plan file."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from openup_ompl.cli._common import add_planning_options, file_out, out_path, plan_scene, summary

HELP = "plan a scene file and write the plan file"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The scene, the planning options and ``--out``.

    Args:
        parser: The command's parser, given its options.
    """
    parser.add_argument("scene", type=Path, help="scene TOML (README, Files: Scene)")
    add_planning_options(parser, 5.0)
    parser.add_argument("--out", type=out_path, default=None, help="plan JSON to write")


def run(args: argparse.Namespace) -> int:
    """Plan; print the summary and where the plan went. Returns the exit status (0).

    Args:
        args: The parsed command line.

    Returns:
        The exit status.
    """
    file_out(args.out)
    _, plan = plan_scene(args, args.scene)
    print(summary(plan))
    if args.out is not None:
        print(f"plan written to {plan.save(args.out)}")
    else:
        print("openup-ompl: no --out given: the plan was not saved", file=sys.stderr)
    return 0
