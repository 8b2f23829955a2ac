"""The command line as a package: the parser built from the command table, one module per
command, a command added by one row (in process, quick)."""

from __future__ import annotations

import argparse
import ast
import sys
import types
from pathlib import Path

import pytest

import openup_ompl.cli._main as cli_main
from openup_ompl.cli import build_parser, main
from openup_ompl.cli.commands import COMMANDS, Command

CLI = Path(cli_main.__file__).parent


def _choices(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The sub-parsers of ``parser``, by command name."""
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def test_every_command_of_the_table_is_a_subcommand_with_a_handler() -> None:
    """Each row of the table whose module exists is a sub-command that dispatches to a
    handler, in the table's order."""
    choices = _choices(build_parser())
    present = [c.name for c in COMMANDS if not c.optional or c.name in choices]
    assert list(choices) == present
    assert {"plan", "demo", "execute", "perceive", "robustness"} <= set(choices)
    for name, sub in choices.items():
        assert callable(sub.get_default("handler")), name


def _fake(name: str, module: types.ModuleType, monkeypatch: pytest.MonkeyPatch) -> None:
    """Register ``module`` as command ``name`` by one row appended to the table."""
    monkeypatch.setitem(sys.modules, module.__name__, module)
    monkeypatch.setattr(cli_main, "COMMANDS", (*COMMANDS, Command(name, module.__name__)))


def test_a_module_with_add_parser_is_registered_by_one_row(monkeypatch, capsys) -> None:
    """A module exposing ``add_parser(subparsers)`` (which sets its own handler) becomes a
    command by one row of the table; its handler's status is the exit status."""
    module = types.ModuleType("fake_study_cli")

    def handler(args: argparse.Namespace) -> int:
        print(f"trials {args.trials}")
        return 1

    def add_parser(subparsers):  # type: ignore[no-untyped-def]
        sub = subparsers.add_parser("fake-study", help="a study")
        sub.add_argument("--trials", type=int, default=3)
        sub.set_defaults(handler=handler)
        return sub

    module.add_parser = add_parser  # type: ignore[attr-defined]
    _fake("fake-study", module, monkeypatch)
    assert main(["fake-study", "--trials", "7"]) == 1
    assert capsys.readouterr().out == "trials 7\n"


def test_a_module_with_add_arguments_and_run_is_registered(monkeypatch, capsys) -> None:
    """A module exposing ``add_arguments`` and ``run`` becomes a command whose help is its
    ``HELP``; a typed error it raises is one line on stderr and exit status 2."""
    from openup_ompl.exceptions import ConfigError

    module = types.ModuleType("fake_cli")
    module.HELP = "does a fake thing"  # type: ignore[attr-defined]
    module.add_arguments = lambda parser: parser.add_argument("--n", type=int)  # type: ignore[attr-defined]

    def run(args: argparse.Namespace) -> int:
        raise ConfigError("--n", args.n, "an even number")

    module.run = run  # type: ignore[attr-defined]
    _fake("fake", module, monkeypatch)
    assert "does a fake thing" in build_parser().format_help()
    assert main(["fake", "--n", "3"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "--n" in err[0] and "an even number" in err[0]


def test_an_optional_command_without_its_module_is_left_out(monkeypatch) -> None:
    """An optional row whose module is not installed is left out; a required one is an
    error."""
    extra = Command("ghost", "openup_ompl.no_such_subpackage.cli", optional=True)
    monkeypatch.setattr(cli_main, "COMMANDS", (*COMMANDS, extra))
    assert "ghost" not in _choices(build_parser())
    monkeypatch.setattr(cli_main, "COMMANDS", (*COMMANDS, extra._replace(optional=False)))
    with pytest.raises(ModuleNotFoundError):
        build_parser()


def test_cli_modules_and_functions_are_small() -> None:
    """No module of the CLI package over 500 lines, no function over 100 (issue 39), and
    ``__main__`` only dispatches (it defines no function and adds no argument)."""
    for path in CLI.glob("*.py"):
        text = path.read_text()
        assert text.count("\n") <= 500, path.name
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef):
                length = (node.end_lineno or node.lineno) - node.lineno + 1
                assert length <= 100, f"{path.name}: {node.name} has {length} lines"
    dispatch = ast.parse((CLI.parent / "__main__.py").read_text())
    assert not any(isinstance(n, ast.FunctionDef) for n in ast.walk(dispatch))
    assert "add_argument" not in ast.unparse(dispatch)
