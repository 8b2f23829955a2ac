"""``openup-ompl closed-loop``: the parser's side; the handler is
:func:`openup_ompl.perception.cli.closed_loop_command`."""

from __future__ import annotations

import argparse
from pathlib import Path

from openup_ompl.cli._common import count, dir_out, out_path, planner, seed, time_limit

HELP = (
    "perceive -> plan at the estimate with each policy's u -> execute against the"
    " true pose (kinematically or in physics), over noise scales and camera distances"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The judge, the scene, the policies, the camera, noises, distances and trials.

    Args:
        parser: The command's parser, given its options.
    """
    parser.add_argument(
        "--execute",
        choices=("kinematic", "physics"),
        default="kinematic",
        help="how a plan is judged against the true pose: the kinematic re-check and force"
        " closure, or a MuJoCo rollout that closes, lifts and holds (default: kinematic)",
    )
    parser.add_argument(
        "--scene", type=Path, default=None, help="scene TOML (default: scenes/lwa3_sdh_can.toml)"
    )
    parser.add_argument(
        "--policies",
        nargs="+",
        default=["0", "0.3", "1", "covariance"],
        help="fixed u values and/or 'covariance' (default: 0 0.3 1 covariance)",
    )
    parser.add_argument(
        "--camera",
        nargs="+",
        default=None,
        metavar="KEY=VALUE",
        help="camera options over the scene's [camera] (distance is swept by --distance)",
    )
    parser.add_argument(
        "--noise",
        type=float,
        nargs="+",
        default=[1.0, 2.0, 4.0],
        help="sensor noise scales (1: Kinect v1, 0: none)",
    )
    parser.add_argument("--distance", type=float, nargs="+", default=[0.6, 1.0], help="[m]")
    parser.add_argument("--trials", type=count, default=10, help="views per noise and distance")
    parser.add_argument("--seed", type=seed, default=1, help="seed of trial 0")
    parser.add_argument(
        "--planner", default="ikbirrt", type=planner, metavar="NAME", help="planner name"
    )
    parser.add_argument("--time", type=time_limit, default=5.0, help="time limit per plan [s]")
    parser.add_argument(
        "--out", type=out_path, default=Path("openup-closed-loop"), help="output directory"
    )
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    from openup_ompl.perception.cli import add_error_arguments

    add_error_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Check ``--out``, then hand over to the perception package's handler.

    Args:
        args: The parsed command line.

    Returns:
        The exit status.
    """
    from openup_ompl.perception.cli import closed_loop_command

    dir_out(args.out)
    return closed_loop_command(args)
