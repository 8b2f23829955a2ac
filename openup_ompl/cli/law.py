"""``openup-ompl law``: plot the hand law alone for several u (the paper's Fig. 3)."""

from __future__ import annotations

import argparse
from pathlib import Path

from openup_ompl.cli._common import file_out, out_path, unit_float
from openup_ompl.exceptions import ConfigError

HELP = "plot the hand law alone for several u (Fig. 3)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """A robot or a scene, the values of u, the law's variants and ``--out``.

    Args:
        parser: The command's parser, given its options.
    """
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--robot", default=None, help="robot name or TOML (default: panda)")
    source.add_argument(
        "--scene", type=Path, default=None, help="scene TOML: its robot and [hand] overrides"
    )
    parser.add_argument(
        "--u", type=unit_float, nargs="+", default=[0.0, 0.3, 1.0], help="values of u in [0, 1]"
    )
    parser.add_argument("--continuous", action="store_true", help="the law without the jump at mga")
    parser.add_argument(
        "--open-arrival", action="store_true", help="the law that reaches the grasp opened by u"
    )
    parser.add_argument(
        "--out",
        type=out_path,
        default=None,
        help="image file: PNG, PDF, SVG, ... by its suffix, PNG without one"
        " (default: <robot>_hand_law.png)",
    )


def run(args: argparse.Namespace) -> int:
    """Draw the law; returns 0.

    Args:
        args: The parsed command line.

    Returns:
        The exit status.

    Raises:
        ConfigError: Repeated values of u, or a bad ``--out``.
    """
    from openup_ompl.robot import load_robot
    from openup_ompl.scene import load_scene
    from openup_ompl.viz._scene import prismatic_joints
    from openup_ompl.viz.law import figure_path, plot_law

    if len(set(args.u)) != len(args.u):  # as robustness refuses them (RobustnessOptions)
        raise ConfigError("u", list(args.u), "distinct values")
    file_out(args.out)
    out = None if args.out is None else figure_path(args.out, "--out")
    if args.scene is not None:
        problem = load_scene(args.scene)
        robot, law = problem.robot, problem.hand_law
        what = f"{robot.name} in {args.scene.name}"
    else:
        robot = load_robot(args.robot or "panda")
        law, what = robot.hand_law(), robot.name
    law = law.with_options(continuous=True) if args.continuous else law
    law = law.with_options(open_arrival=True) if args.open_arrival else law
    joints = list(robot.hand_joints)
    figure = plot_law(
        law,
        out or Path(f"{robot.name}_hand_law.png"),
        us=args.u,
        joint_names=joints,
        prismatic=prismatic_joints(robot.model, joints).tolist(),
        title=f"hand law of {what} (Algorithm 3), mga = {law.mga:g}"
        + (", continuous" if law.continuous else "")
        + (", open arrival" if law.open_arrival else ""),
    )
    print(f"hand law figure written to {figure}")
    return 0
