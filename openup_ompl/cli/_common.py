"""What the commands share: argument validators, the parser class and its help
formatter, the checks of ``--out`` made before any work, and the planning options of
``plan`` and ``demo``."""

from __future__ import annotations

import argparse
import math
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from openup_ompl._io import check_dir
from openup_ompl.exceptions import ConfigError

if TYPE_CHECKING:
    from openup_ompl.plan import Plan
    from openup_ompl.planning import GraspPlanningSetup


def parsed(text: str, kind: type, ok: Callable[[float], bool], expected: str) -> Any:
    """``kind(text)`` if it parses and ``ok`` accepts it, else an argparse error naming both."""
    try:
        value = kind(text)
    except ValueError:
        value = None
    if value is None or not (math.isfinite(value) and ok(value)):
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
    return value


def _checked(check: Callable[[Any], Any], value: Any, text: str) -> Any:
    """``check(value)``, its ConfigError turned into an argparse error quoting ``text``."""
    try:
        return check(value)
    except ConfigError as error:
        raise argparse.ArgumentTypeError(f"expected {error.expected}, got {text!r}") from None


def time_limit(text: str) -> float:
    """A time limit [s], checked by ``planning.check_time_limit`` (``(0, TIME_LIMIT_MAX]``:
    OMPL's clock overflows beyond it); else an argparse error saying what it expects."""
    from openup_ompl.planning import check_time_limit

    try:
        value = float(text)
    except ValueError:
        value = math.nan  # refused by the check with the same message
    return float(_checked(check_time_limit, value, text))


def unit_float(text: str) -> float:
    """A number in [0, 1] (the uncertainty ``u``)."""
    return float(parsed(text, float, lambda v: 0.0 <= v <= 1.0, "a number in [0, 1]"))


def seed(text: str) -> int:
    """A seed in [0, 2^31)."""
    return int(parsed(text, int, lambda v: 0 <= v < 2**31, "an integer seed in [0, 2^31)"))


def count(text: str) -> int:
    """A positive integer (runs, seeds, trials, workers); each command's options bound it
    further."""
    return int(parsed(text, int, lambda v: v >= 1, "a positive integer"))


def scheduler(text: str) -> str:
    """A Dask scheduler address, ``[scheme://]host:port``, checked with Dask's own parser
    (``executor.check_scheduler``; when Dask is installed: without it the run says the
    extra is missing)."""
    from openup_ompl.executor import check_scheduler

    return str(_checked(check_scheduler, text, text))


def planner(text: str) -> str:
    """A planner name, lowered; an unknown or refused one is an argparse error that says
    why (``planning.check_planner``: ``prm`` deadlocks on a Python goal region, ...)."""
    from openup_ompl.planning import check_planner

    return str(_checked(check_planner, text, text))


def out_path(text: str) -> Path:
    """An ``--out`` path: not empty (``Path("")`` would silently be the current
    directory)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected a path, got {text!r}")
    return Path(text)


class Formatter(argparse.HelpFormatter):
    """Help that shows each option's default, unless its text already says it or there
    is none to show."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if (
            "(default" in text
            or not action.option_strings
            or default in (None, False, argparse.SUPPRESS)
        ):
            return text
        shown = " ".join(str(x) for x in default) if isinstance(default, list) else default
        return f"{text} (default: {shown})"


class Parser(argparse.ArgumentParser):
    """An argument parser with :class:`Formatter` whose errors are one line (exit 2)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", Formatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")

    def _get_values(self, action: argparse.Action, arg_strings: list[str]) -> Any:
        # ``--flag=--`` reaches an option as ["--"], which argparse strips to no value at
        # all: ``--seed=--`` became ``[]`` (a traceback), ``--u=--`` the default sweep.
        if action.option_strings and arg_strings == ["--"] and action.nargs != 0:
            self.error(f"argument {'/'.join(action.option_strings)}: expected a value, got '--'")
        return super()._get_values(action, arg_strings)


def _writable(path: Path, nearest: Path) -> None:
    """Refuse ``path`` when its nearest existing directory ``nearest`` takes no new file
    (tried with a temporary file, removed at once: permission bits say nothing to root or
    of a read-only or virtual file system)."""
    try:
        with tempfile.TemporaryFile(dir=nearest):
            pass
    except OSError as error:
        raise ConfigError(
            "--out",
            str(path),
            f"a path in a writable directory (creating a file in {nearest}: {error.strerror})",
        ) from None


def file_out(path: Path | None) -> None:
    """Refuse, before any work, an output file that cannot be written.

    Raises:
        ConfigError: ``path`` is a directory, or its parent is a file or not writable.
    """
    if path is None:
        return
    if path.is_dir():
        raise ConfigError("--out", str(path), "a file to write (this is a directory)")
    parent = next((p for p in path.absolute().parents if p.exists()), None)
    if parent is not None and not parent.is_dir():
        raise ConfigError("--out", str(path), f"a path whose parent is a directory ({parent})")
    if parent is not None:
        _writable(path, parent)


def dir_out(path: Path) -> None:
    """Refuse, before any work, an output directory that is an existing file or that
    cannot be written.

    Raises:
        ConfigError: Naming ``--out``.
    """
    check_dir(path, "--out")
    nearest = next((p for p in (path.absolute(), *path.absolute().parents) if p.exists()), None)
    if nearest is not None:
        _writable(path, nearest)


def add_executor_options(parser: argparse.ArgumentParser) -> None:
    """``--workers`` and ``--scheduler``: where a sweep's tasks run (local processes or a
    Dask cluster; :mod:`openup_ompl.executor`).

    Args:
        parser: The command's parser.
    """
    parser.add_argument(
        "--workers",
        type=count,
        default=None,
        help="local task processes at a time (default: the usable cores)",
    )
    parser.add_argument(
        "--scheduler", type=scheduler, default=None, help="Dask scheduler address (tcp://host:port)"
    )


def add_planning_options(sub: argparse.ArgumentParser, default_time: float) -> None:
    """The options of a command that plans one scene (``plan``, ``demo``)."""
    from openup_ompl.planning import PLANNERS

    sub.add_argument(
        "--u",
        type=unit_float,
        default=None,
        help="pose uncertainty in [0, 1] (default: the scene's)",
    )
    sub.add_argument(
        "--planner",
        default="ikbirrt",
        type=planner,
        metavar="NAME",
        help=f"one of {', '.join(PLANNERS)}",
    )
    sub.add_argument(
        "--time", type=time_limit, default=default_time, help="planning time limit [s]"
    )
    sub.add_argument(
        "--seed",
        type=seed,
        default=None,
        help="random seed (default: drawn, and written in the plan)",
    )
    sub.add_argument("--no-simplify", action="store_true", help="keep the planner's raw path")
    sub.add_argument(
        "--continuous", action="store_true", help="use the hand law without the jump at mga"
    )
    sub.add_argument(
        "--open-arrival",
        action="store_true",
        help="extension: the hand reaches the grasp opened by u, at c + (w - c) u",
    )


def add_validate_option(parser: argparse.ArgumentParser) -> None:
    """``--no-validate``: use a plan without re-validating it (``execute``, ``show``)."""
    parser.add_argument(
        "--no-validate",
        action="store_true",
        help="for experts: use the plan without re-validating it against its scene (joint"
        " limits, the hand on the law, steps within the motion check's resolution, every"
        " motion collision-free); a plan that fails it is otherwise refused (exit 2)",
    )


def plan_scene(args: argparse.Namespace, scene: Path) -> tuple[GraspPlanningSetup, Plan]:
    """Plan ``scene`` with the options of :func:`add_planning_options`.

    Raises:
        PlanningFailed: No solution within the time limit.
        ConfigError: A bad scene file, its ``[camera]`` table included (refused as
            ``perceive`` refuses it, though planning does not use it).
    """
    from openup_ompl.perception.camera import camera_of_scene
    from openup_ompl.planning import GraspPlanningSetup, PlanningOptions
    from openup_ompl.scene import load_scene

    options = PlanningOptions(
        u=args.u,
        continuous=True if args.continuous else None,
        open_arrival=True if args.open_arrival else None,
        planner=args.planner,
        time_limit=args.time,
        simplify=not args.no_simplify,
    )
    problem = load_scene(scene)
    camera_of_scene(problem)
    setup = GraspPlanningSetup(problem, options)
    return setup, setup.solve(seed=args.seed)


def summary(plan: Plan) -> str:
    """The one-line summary of a solve that ``plan`` and ``demo`` print."""
    restarts = plan.stats.get("restarts", 0)
    restarted = f", {restarts} restart{'s' * (restarts != 1)}" if restarts else ""
    return (
        f"{plan.status.lower()} by {plan.planner} in {plan.solve_time_s * 1e3:.0f} ms "
        f"(seed {plan.seed}, u = {plan.law.u:g}, {plan.waypoints.shape[0]} waypoints, "
        f"{plan.path.shape[0]} states{restarted})"
    )


def print_shown(plan: Path, out: Path | None) -> None:
    """Write a plan's pictures (``viz.show``) and say where they are."""
    from openup_ompl.viz import show

    shown = show(plan, out)
    print(f"animation written to {shown.html} (open it in a browser)")
    print(f"storyboard written to {shown.storyboard}")
    print(f"hand law figure written to {shown.hand_law}")
