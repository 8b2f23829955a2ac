"""``openup-ompl robots``: list the available robots."""

from __future__ import annotations

import argparse

HELP = "list the available robots: arm DOF, hand joints, description"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """No options.

    Args:
        parser: The command's parser (left as it is).
    """


def run(args: argparse.Namespace) -> int:
    """Print one row per shipped robot; returns 0.

    Args:
        args: The parsed command line.

    Returns:
        The exit status.
    """
    from openup_ompl.robot import available_robots, load_robot

    rows = [("name", "arm", "hand (driven+followers)", "description")]
    for name in available_robots():
        robot = load_robot(name)
        hand = f"{robot.hand_idx.size} ({robot.n_driven}+{len(robot.mimic)})"
        rows.append((name, str(robot.arm_idx.size), hand, robot.spec.description))
    widths = [max(len(row[i]) for row in rows) for i in range(3)]
    for row in rows:
        cells = [cell.ljust(width) for cell, width in zip(row[:3], widths, strict=True)]
        print("  ".join([*cells, row[3]]))
    return 0
