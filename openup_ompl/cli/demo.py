"""``openup-ompl demo``: plan the default scene; write its plan and pictures."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from openup_ompl.cli._common import (
    add_planning_options,
    dir_out,
    out_path,
    plan_scene,
    print_shown,
    summary,
)
from openup_ompl.exceptions import MissingExtra

HELP = "plan the default scene; write its plan and pictures"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The planning options, ``--out`` (a directory) and ``--scene``.

    Args:
        parser: The command's parser, given its options.
    """
    add_planning_options(parser, 5.0)
    parser.add_argument(
        "--out", type=out_path, default=Path("openup-demo"), help="output directory"
    )
    parser.add_argument(
        "--scene",
        type=Path,
        default=None,
        help="scene TOML (default: scenes/lwa3_sdh_can.toml, the paper's robot, whose SDH"
        " hand opens by centimetres; scenes/panda_can.toml: the Panda's, by millimetres)",
    )


def run(args: argparse.Namespace) -> int:
    """Plan, save ``plan.json`` and draw it (without pictures if ``viz`` is missing).

    Args:
        args: The parsed command line.

    Returns:
        The exit status.
    """
    from openup_ompl.scene import demo_scene_path

    dir_out(args.out)
    _, plan = plan_scene(args, args.scene or demo_scene_path())
    print(summary(plan))
    out: Path = args.out
    path = plan.save(out / "plan.json")
    print(f"plan written to {path}")
    try:
        print_shown(path, out)
    except MissingExtra as error:
        print(f"no pictures: {error}", file=sys.stderr)
    return 0
