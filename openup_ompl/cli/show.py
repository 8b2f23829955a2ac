"""``openup-ompl show PLAN.json``: a plan's pictures (after re-validating it against its
scene), or an execution's."""

from __future__ import annotations

import argparse
from pathlib import Path

from openup_ompl.cli._common import add_validate_option, dir_out, out_path, print_shown

HELP = (
    "write a plan's pictures: HTML animation, storyboard, hand law figure (or an"
    " execution's: the rollout animated, a reach / close / lift storyboard)"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The plan (or execution) file, ``--out`` and ``--no-validate``.

    Args:
        parser: The command's parser, given its options.
    """
    parser.add_argument(
        "plan", type=Path, help="plan JSON (README, Files: Plan), or an execution.json"
    )
    parser.add_argument(
        "--out", type=out_path, default=None, help="output directory (default: the plan's)"
    )
    add_validate_option(parser)


def run(args: argparse.Namespace) -> int:
    """Draw the file; returns 0.

    Args:
        args: The parsed command line.

    Returns:
        The exit status.

    Raises:
        ConfigError: A bad file or ``--out``.
        PlanRejected: The plan fails its re-validation.
    """
    from openup_ompl.physics.record import is_execution

    if args.out is not None:
        dir_out(args.out)
    if is_execution(args.plan):
        from openup_ompl.viz.rollout import show_execution

        shown = show_execution(args.plan, args.out)
        print(f"rollout animation written to {shown.html} (open it in a browser)")
        print(f"rollout storyboard written to {shown.storyboard}")
        return 0
    if not args.no_validate:
        from openup_ompl.plan import PlanFile
        from openup_ompl.revalidate import revalidate_plan

        revalidate_plan(PlanFile.read(args.plan), where=f"{args.plan.name}: ")
    print_shown(args.plan, args.out)
    return 0
