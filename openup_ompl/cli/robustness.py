"""``openup-ompl robustness``: the paper's experiment, plan at the nominal object pose and
execute against displaced ones."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from openup_ompl.cli._common import (
    add_executor_options,
    count,
    dir_out,
    out_path,
    planner,
    seed,
    time_limit,
    unit_float,
)

HELP = (
    "the paper's experiment: plan at the nominal object pose, execute against"
    " displaced ones, close the fingers, test force closure"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The sweep (u, displacements, yaws, seeds), the judge and where the tasks run.

    Args:
        parser: The command's parser, given its options.
    """
    parser.add_argument(
        "--scene", type=Path, default=None, help="scene TOML (default: scenes/lwa3_sdh_can.toml)"
    )
    parser.add_argument(
        "--u",
        type=unit_float,
        nargs="+",
        default=None,
        help="values of u (default: 0 0.1 0.3 0.5 1)",
    )
    parser.add_argument(
        "--delta",
        type=float,
        nargs="+",
        default=None,
        help="object position errors [m], each along +x, -x, +y, -y"
        " (default: 0 0.005 0.01 0.015 0.02 0.03)",
    )
    parser.add_argument(
        "--yaw",
        type=float,
        nargs="+",
        default=None,
        help="object rotations about its own z axis [rad] (default: 0)",
    )
    parser.add_argument("--seeds", type=count, default=10, help="plans per u (trials per cell)")
    parser.add_argument("--seed", type=seed, default=1, help="seed of plan 0 (plan i: seed + i)")
    parser.add_argument(
        "--planner", default="ikbirrt", type=planner, metavar="NAME", help="planner name"
    )
    parser.add_argument("--time", type=time_limit, default=5.0, help="time limit per plan [s]")
    parser.add_argument(
        "--friction", type=float, default=0.5, help="Coulomb coefficient of the grasp test"
    )
    parser.add_argument(
        "--torsion",
        type=float,
        default=None,
        help="soft-finger torsional friction [m] of the grasp test (default: the robot's,"
        " else 0: point contacts)",
    )
    parser.add_argument(
        "--open-arrival",
        action="store_true",
        help="plan with the extension that reaches the grasp opened by u",
    )
    parser.add_argument(
        "--execute",
        choices=("kinematic", "physics"),
        default="kinematic",
        help="judge each trial kinematically (welded object, force closure; the default)"
        " or in physics (MuJoCo: the object free, close, lift, hold)",
    )
    parser.add_argument(
        "--shared-approach",
        action="store_true",
        help="physics: a plan's trials share the robot's approach up to where each hand may"
        " first reach its object (faster; the object's rest equal up to rounding)",
    )
    parser.add_argument(
        "--out", type=out_path, default=Path("openup-robustness"), help="output directory"
    )
    add_executor_options(parser)
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")


def run(args: argparse.Namespace) -> int:
    """Run the sweep; print its tables and where its files are. Returns 0.

    Args:
        args: The parsed command line.

    Returns:
        The exit status.
    """
    from openup_ompl.robustness import RobustnessOptions, markdown_tables, run_robustness

    dir_out(args.out)
    created = not args.out.exists()
    given = {"us": args.u, "deltas": args.delta, "yaws": args.yaw}
    sweep: dict[str, Any] = {key: tuple(value) for key, value in given.items() if value}
    options = RobustnessOptions(
        **sweep,
        seeds=args.seeds,
        first_seed=args.seed,
        planner=args.planner,
        time_limit=args.time,
        friction=args.friction,
        open_arrival=args.open_arrival,
        torsion=args.torsion,
        execute=args.execute,
        shared_approach=args.shared_approach,
    )
    try:
        result = run_robustness(
            args.scene,
            options,
            args.out,
            workers=args.workers,
            scheduler=args.scheduler,
            quiet=args.quiet,
        )
    except BaseException:
        if created and args.out.is_dir() and not any(args.out.iterdir()):
            args.out.rmdir()  # a run that ended before any trial leaves no empty --out
        raise
    print(markdown_tables(result.rows), end="")
    print(f"table written to {result.csv} and {result.markdown}")
    if result.plot is not None:
        print(f"plot written to {result.plot}")
    if result.grasps is not None:
        print(f"grasps of one plan written to {result.grasps}")
    print(f"every trial in {result.trials}")
    return 0
