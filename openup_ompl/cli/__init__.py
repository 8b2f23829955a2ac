"""The ``openup-ompl`` command line, one module per command.

Each command lives in one module that exposes, side by side:

- ``add_arguments(parser)``: fills the command's ``argparse`` sub-parser;
- ``run(args) -> int``: the handler, which returns the exit status (0 success, 1 a
  planning failure or a failed execution) and raises a typed error
  (:class:`~openup_ompl.exceptions.OpenUpError`) on bad input, which :func:`main` turns
  into one line on stderr and exit status 2;
- optionally ``HELP``, the command's one-line help (else its docstring's first line).

A module may instead expose ``add_parser(subparsers) -> parser``, which adds its own
sub-parser (``subparsers.add_parser("study", help=...)``), fills it and returns it; its
handler is the ``handler`` it sets (``parser.set_defaults(handler=...)``), else its ``run``.

The parser is built from the table :data:`~openup_ompl.cli.commands.COMMANDS`:
registering a command is one line there, ``Command("name", "package.module")``, wherever
the module lives (the perception commands' handlers are in
:mod:`openup_ompl.perception.cli`; a subpackage's ``study/cli.py`` is registered as
``Command("study", "openup_ompl.study.cli", optional=True)``). Import heavy dependencies
inside ``run``, not at module level: ``--help`` imports every command module.

``openup_ompl.__main__`` only dispatches to :func:`run`.
"""

from __future__ import annotations

from openup_ompl.cli._main import build_parser, main, run

__all__ = ["build_parser", "main", "run"]
