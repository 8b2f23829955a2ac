"""The table of commands: each row a command's name and the module that defines it
(see :mod:`openup_ompl.cli` for what such a module exposes)."""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["COMMANDS", "Command"]


class Command(NamedTuple):
    """One row of :data:`COMMANDS`.

    Attributes:
        name: The command's name (``openup-ompl NAME``).
        module: The module exposing ``add_arguments(parser)`` and ``run(args) -> int``.
        optional: Leave the command out when ``module`` itself does not exist (a
            subpackage not installed yet), instead of failing.
    """

    name: str
    module: str
    optional: bool = False


#: Every command, in the order ``openup-ompl --help`` lists them.
COMMANDS: tuple[Command, ...] = (
    Command("plan", "openup_ompl.cli.plan"),
    Command("demo", "openup_ompl.cli.demo"),
    Command("show", "openup_ompl.cli.show"),
    Command("law", "openup_ompl.cli.law"),
    Command("robots", "openup_ompl.cli.robots"),
    Command("benchmark", "openup_ompl.cli.benchmark"),
    Command("execute", "openup_ompl.cli.execute"),
    Command("robustness", "openup_ompl.cli.robustness"),
    Command("perceive", "openup_ompl.cli.perceive"),
    Command("closed-loop", "openup_ompl.cli.closed_loop"),
    Command("build-native", "openup_ompl.cli.build_native"),
    Command("study", "openup_ompl.study.cli", optional=True),
)
