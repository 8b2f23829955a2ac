"""``openup-ompl perceive SCENE.toml``: the parser's side; the handler is
:func:`openup_ompl.perception.cli.perceive_command`."""

from __future__ import annotations

import argparse
from pathlib import Path

from openup_ompl.cli._common import dir_out, out_path, seed

HELP = (
    "simulated depth view of the scene's object, superquadric fit, covariance;"
    " writes DIR/perceived.toml with the estimated pose and u"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The scene, the camera, the noise, the seed and ``--out``.

    Args:
        parser: The command's parser, given its options.
    """
    parser.add_argument("scene", type=Path, help="scene TOML (may hold a [camera] table)")
    parser.add_argument(
        "--camera",
        nargs="+",
        default=None,
        metavar="KEY=VALUE",
        help="'auto' (default: the scene's [camera] view if it sees the object, else the"
        " best of a ring of views around it, printed), optionally followed by, or else,"
        " camera options over the scene's [camera] (e.g. distance=0.9 elevation=50"
        " width=320 height=240 position=[1,0,0.8]: that view, refused if it cannot see"
        " the object)",
    )
    parser.add_argument(
        "--noise", type=float, default=1.0, help="sensor noise scale (1: Kinect v1, 0: none)"
    )
    parser.add_argument("--seed", type=seed, default=1, help="seed of the sensor noise")
    parser.add_argument("--out", type=out_path, required=True, help="output directory")
    from openup_ompl.perception.cli import add_error_arguments

    add_error_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Check ``--out``, then hand over to the perception package's handler.

    Args:
        args: The parsed command line.

    Returns:
        The exit status.
    """
    from openup_ompl.perception.cli import perceive_command

    dir_out(args.out)
    return perceive_command(args)
