"""The parser built from :data:`~openup_ompl.cli.commands.COMMANDS`, and the entry points
:func:`main` and :func:`run`."""

from __future__ import annotations

import argparse
import importlib
import os
import secrets
import sys
from collections.abc import Sequence
from types import ModuleType
from typing import Any

from openup_ompl.cli._common import Parser
from openup_ompl.cli.commands import COMMANDS, Command
from openup_ompl.exceptions import OpenUpError, PlanningFailed

__all__ = ["build_parser", "main", "run"]


def _module(command: Command) -> ModuleType | None:
    """The module of a command, or ``None`` for an optional one that is not there."""
    try:
        return importlib.import_module(command.module)
    except ModuleNotFoundError as error:
        if command.optional and error.name is not None and command.module.startswith(error.name):
            return None
        raise


def _help(module: ModuleType) -> str:
    """A command's one-line help: its module's ``HELP``, else its docstring's first line."""
    text = getattr(module, "HELP", None) or (module.__doc__ or "").strip().split("\n")[0]
    return str(text)


def build_parser() -> argparse.ArgumentParser:
    """The ``openup-ompl`` parser: one sub-parser per row of the command table, each
    filled by its module's ``add_arguments`` and dispatching to its ``run``.

    Returns:
        The parser; ``parse_args`` gives a namespace whose ``handler`` runs the command.
    """
    parser = Parser(
        prog="openup-ompl",
        description="Reach-to-grasp planning under object-pose uncertainty on OMPL: the hand"
        " opens with the uncertainty u (Open Up!).",
        epilog="Run 'openup-ompl COMMAND --help' for a command's options. Bad input exits"
        " with status 2 and one line on stderr, a planning failure with status 1.",
    )
    commands = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for command in COMMANDS:
        module = _module(command)
        if module is not None:
            _add_command(commands, command.name, module)
    return parser


def _add_command(commands: Any, name: str, module: ModuleType) -> None:
    """Add one command's sub-parser: by the module's own ``add_parser(subparsers)`` if
    it has one, else named ``name`` and filled by its ``add_arguments``; its handler is
    the ``handler`` the module set, else its ``run``."""
    if hasattr(module, "add_parser"):
        sub = module.add_parser(commands)
    else:
        sub = commands.add_parser(name, help=_help(module))
        module.add_arguments(sub)
    if sub.get_default("handler") is None:
        sub.set_defaults(handler=module.run)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status.

    Each subcommand sets ``handler`` (``args -> exit status``); commands that plan take
    ``--seed``, which seeds OMPL's process-wide generator before any OMPL object exists.

    Args:
        argv: The arguments (default: ``sys.argv[1:]``).

    Returns:
        0 on success, 1 on a planning failure (or a failed execution), 2 on bad input
        (one line on stderr), 130 when interrupted.
    """
    args = build_parser().parse_args(argv)
    from ompl import util as ompl_util

    from openup_ompl.executor import seed_ompl

    if hasattr(args, "seed"):
        if args.seed is None:
            args.seed = secrets.randbelow(2**31)
        # OMPL's generator can only be seeded before any OMPL object exists.
        seed_ompl(args.seed)
    ompl_util.setLogLevel(ompl_util.LOG_ERROR)
    try:
        return int(args.handler(args))
    except PlanningFailed as error:
        print(f"openup-ompl: planning failed: {error}", file=sys.stderr)
        return 1
    except (OpenUpError, OSError) as error:
        print(f"openup-ompl: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("openup-ompl: interrupted", file=sys.stderr)
        return 130


def run() -> None:
    """Console entry point: exit without interpreter teardown, which would make the
    nanobind bindings print reference-leak notes after the one line we promise."""
    status = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)
