"""Property-based tests (Hypothesis) of the command line's numeric flags: any text given
to ``--time``, ``--u``, ``--seed``, ``--runs``, ``--noise``, ... is either taken as the
number it spells or refused in one line (exit 2), never a traceback, a hang or a value
silently changed (clamped, rounded, not finite)."""

from __future__ import annotations

import argparse
import contextlib
import io
import math
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from openup_ompl.__main__ import build_parser, main

QUICK_EXAMPLES = 15
MANY_EXAMPLES = 50  # per flag (42 flags: 2,100 inputs)
TIERS = [
    pytest.param(QUICK_EXAMPLES, id="quick"),
    pytest.param(MANY_EXAMPLES, id="many", marks=pytest.mark.slow),
]
ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "scenes" / "panda_can.toml"


def _is_numeric(action: argparse.Action) -> bool:
    """Whether an option takes numbers: its type turns ``"1"`` into a number."""
    if action.type is None or not action.option_strings:
        return False
    try:
        return type(action.type("1")) in (int, float)  # type: ignore[operator]
    except (argparse.ArgumentTypeError, ValueError, TypeError):
        return False


PARSER = build_parser()
COMMANDS = next(a for a in PARSER._actions if isinstance(a, argparse._SubParsersAction))


def _numeric_flags() -> list[tuple[str, str]]:
    """Every ``(command, flag)`` of the parser whose flag takes numbers."""
    return [
        (name, action.option_strings[-1])
        for name, sub in sorted(COMMANDS.choices.items())
        for action in sub._actions
        if _is_numeric(action)
    ]


FLAGS = _numeric_flags()


def _subparser(command: str) -> argparse.ArgumentParser:
    return COMMANDS.choices[command]  # type: ignore[no-any-return]


def _argv(command: str, flag: str, text: str, out: Path) -> tuple[list[str], argparse.Action]:
    """A command line of ``command`` with ``text`` given to ``flag`` (its other values
    valid) and a scene, a plan and ``--out`` wherever they are needed."""
    sub = _subparser(command)
    action = next(a for a in sub._actions if flag in a.option_strings)
    argv = [command]
    for positional in (a for a in sub._actions if not a.option_strings and a.dest != "help"):
        argv.append(str(out / "plan.json") if positional.dest == "plan" else str(SCENE))
    if any("--out" in a.option_strings for a in sub._actions) and flag != "--out":
        argv += ["--out", str(out / "out")]
    if isinstance(action.nargs, int) and action.nargs > 1:
        argv += [flag, text, *["0"] * (action.nargs - 1)]
    else:
        argv.append(f"{flag}={text}")
    return argv, action


def _texts() -> st.SearchStrategy[str]:
    return st.one_of(
        st.floats(allow_nan=True, allow_infinity=True).map(repr),
        st.integers(min_value=-(2**70), max_value=2**70).map(str),
        st.floats(min_value=-2.0, max_value=2.0).map(lambda x: f"{x:.3g}"),
        st.sampled_from(
            [
                "nan",
                "-nan",
                "inf",
                "-inf",
                "Infinity",
                "1e400",
                "-0",
                "0x10",
                "1_000",
                " 5",
                "5 ",
                "\uff15",
                "1e-320",
                "",
                "0.5.5",
                "--",
                "1.0",
                "2147483648",
                "0",
            ]
        ),  # fmt: skip
        st.text(max_size=6),
    )


def _parse(argv: list[str]) -> tuple[Any, int | None, str]:
    """The parsed arguments, or the exit status and stderr of a refusal."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            return PARSER.parse_args(argv), None, ""
        except SystemExit as stop:
            return None, int(stop.code or 0), err.getvalue()


def _spelled(text: str, kind: type) -> float | None:
    """The number ``text`` spells for Python's ``int`` or ``float``, else ``None``."""
    try:
        return kind(text)  # type: ignore[no-any-return]
    except (ValueError, OverflowError):
        return None


@pytest.mark.parametrize("examples", TIERS)
@pytest.mark.parametrize(("command", "flag"), FLAGS)
def test_numeric_flags_take_the_number_typed_or_refuse_in_one_line(
    command: str, flag: str, examples: int, tmp_path: Path
) -> None:
    """Any text given to a numeric flag is the number it spells or one line of refusal
    (exit 2); a non-finite number a flag's parser lets through is refused by the command
    in one line naming it (exit 2), before any work."""

    def check(text: str) -> None:
        argv, action = _argv(command, flag, text, tmp_path)
        args, status, err = _parse(argv)
        if args is None:
            lines = [line for line in err.splitlines() if line.strip()]
            assert status == 2, (argv, status, err)
            assert len(lines) == 1 and "Traceback" not in err, err
            assert flag.lstrip("-") in lines[0] or repr(text) in lines[0], lines[0]
            return
        value = getattr(args, action.dest)
        value = value[0] if isinstance(value, (list, tuple)) else value
        kind = int if isinstance(value, int) else float
        assert type(value) is kind, (text, value)
        assert value == _spelled(text, kind) or (isinstance(value, float) and math.isnan(value)), (
            text,
            value,
        )
        if not math.isfinite(value):
            err_text = io.StringIO()
            with contextlib.redirect_stderr(err_text):
                status = main(argv)
            lines = [line for line in err_text.getvalue().splitlines() if line.strip()]
            assert status == 2, (argv, status, err_text.getvalue())
            assert len(lines) == 1 and str(value) in lines[0], lines

    settings(
        max_examples=examples,
        derandomize=True,
        deadline=None,
        database=None,
        suppress_health_check=[HealthCheck.too_slow],
    )(given(_texts())(check))()


def test_every_command_with_numbers_is_covered() -> None:
    """The flags found include those of planning, sweeps, physics and perception."""
    found = set(FLAGS)
    for pair in [("plan", "--time"), ("plan", "--u"), ("plan", "--seed"),
                 ("robustness", "--delta"), ("execute", "--object-offset"),
                 ("perceive", "--noise"), ("closed-loop", "--distance")]:  # fmt: skip
        assert pair in found, pair


@pytest.mark.parametrize(
    "argv",
    [
        ["plan", str(SCENE), "--seed=--"],
        ["plan", str(SCENE), "--time=--"],
        ["robustness", "--u=--"],
        ["closed-loop", "--noise=--"],
    ],
)
def test_a_flag_given_only_the_separator_is_refused(argv: list[str]) -> None:
    """``--flag=--`` (which argparse reads as no value at all: ``--seed=--`` was a
    traceback, ``--u=--`` the default sweep) is refused in one line naming the flag."""
    args, status, err = _parse(argv)
    assert args is None and status == 2
    assert err.count("\n") == 1 and argv[-1].split("=")[0] in err, err
