"""Command line: ``openup-ompl plan``, ``demo``, ``robustness``, ``benchmark`` and more.

Bad input ends with one line on stderr and exit status 2; a planner that finds no
solution ends with its OMPL status on stderr and exit status 1. No plan file is written
unless it holds a valid plan.
"""

from __future__ import annotations

import argparse
import math
import os
import secrets
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from openup_ompl._io import check_dir
from openup_ompl.exceptions import ConfigError, MissingExtra, OpenUpError, PlanningFailed


def _parsed(text: str, kind: type, ok: Callable[[float], bool], expected: str) -> Any:
    """``kind(text)`` if it parses and ``ok`` accepts it, else an argparse error naming both."""
    try:
        value = kind(text)
    except ValueError:
        value = None
    if value is None or not (math.isfinite(value) and ok(value)):
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
    return value


def _time_limit(text: str) -> float:
    """A time limit [s], checked by ``planning.check_time_limit`` (``(0, TIME_LIMIT_MAX]``:
    OMPL's clock overflows beyond it); else an argparse error saying what it expects."""
    from openup_ompl.planning import check_time_limit

    try:
        value = float(text)
    except ValueError:
        value = math.nan  # refused below with the same message
    try:
        return check_time_limit(value)
    except ConfigError as error:
        raise argparse.ArgumentTypeError(f"expected {error.expected}, got {text!r}") from None


def _unit_float(text: str) -> float:
    return float(_parsed(text, float, lambda v: 0.0 <= v <= 1.0, "a number in [0, 1]"))


def _seed(text: str) -> int:
    return int(_parsed(text, int, lambda v: 0 <= v < 2**31, "an integer seed in [0, 2^31)"))


def _count(text: str) -> int:
    """A positive integer (runs, seeds, trials, workers); each command's options bound it
    further."""
    return int(_parsed(text, int, lambda v: v >= 1, "a positive integer"))


def _scheduler(text: str) -> str:
    """A Dask scheduler address, ``[scheme://]host:port``, checked with Dask's own parser
    (``executor.check_scheduler``; when Dask is installed: without it the run says the
    extra is missing)."""
    from openup_ompl.executor import check_scheduler

    try:
        return check_scheduler(text)
    except ConfigError as error:
        raise argparse.ArgumentTypeError(f"expected {error.expected}, got {text!r}") from None


def _planner(text: str) -> str:
    """A planner name, lowered; an unknown or refused one is an argparse error that says
    why (``planning.check_planner``: ``prm`` deadlocks on a Python goal region, ...)."""
    from openup_ompl.planning import check_planner

    try:
        return check_planner(text)
    except ConfigError as error:
        raise argparse.ArgumentTypeError(f"expected {error.expected}, got {text!r}") from None


class _Formatter(argparse.HelpFormatter):
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


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", _Formatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")


def _out_path(text: str) -> Path:
    """An ``--out`` path: not empty (``Path("")`` would silently be the current
    directory)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected a path, got {text!r}")
    return Path(text)


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


def _file_out(path: Path | None) -> None:
    """Refuse, before any work, an output file that cannot be written."""
    if path is None:
        return
    if path.is_dir():
        raise ConfigError("--out", str(path), "a file to write (this is a directory)")
    parent = next((p for p in path.absolute().parents if p.exists()), None)
    if parent is not None and not parent.is_dir():
        raise ConfigError("--out", str(path), f"a path whose parent is a directory ({parent})")
    if parent is not None:
        _writable(path, parent)


def _dir_out(path: Path) -> None:
    """Refuse, before any work, an output directory that is an existing file or that
    cannot be written."""
    check_dir(path, "--out")
    nearest = next((p for p in (path.absolute(), *path.absolute().parents) if p.exists()), None)
    if nearest is not None:
        _writable(path, nearest)


def build_parser() -> argparse.ArgumentParser:
    from openup_ompl.planning import PLANNERS

    parser = _Parser(
        prog="openup-ompl",
        description="Reach-to-grasp planning under object-pose uncertainty on OMPL: the hand"
        " opens with the uncertainty u (Open Up!).",
        epilog="Run 'openup-ompl COMMAND --help' for a command's options. Bad input exits"
        " with status 2 and one line on stderr, a planning failure with status 1.",
    )
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    def planning_options(sub: argparse.ArgumentParser, default_time: float) -> None:
        sub.add_argument(
            "--u",
            type=_unit_float,
            default=None,
            help="pose uncertainty in [0, 1] (default: the scene's)",
        )
        sub.add_argument(
            "--planner",
            default="ikbirrt",
            type=_planner,
            metavar="NAME",
            help=f"one of {', '.join(PLANNERS)}",
        )
        sub.add_argument(
            "--time", type=_time_limit, default=default_time, help="planning time limit [s]"
        )
        sub.add_argument(
            "--seed",
            type=_seed,
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

    plan = commands.add_parser("plan", help="plan a scene file and write the plan file")
    plan.add_argument("scene", type=Path, help="scene TOML (README, Files: Scene)")
    planning_options(plan, 5.0)
    plan.add_argument("--out", type=_out_path, default=None, help="plan JSON to write")
    plan.set_defaults(handler=_plan_command)

    demo = commands.add_parser("demo", help="plan the default scene; write its plan and pictures")
    planning_options(demo, 5.0)
    demo.add_argument("--out", type=_out_path, default=Path("openup-demo"), help="output directory")
    demo.add_argument(
        "--scene",
        type=Path,
        default=None,
        help="scene TOML (default: scenes/lwa3_sdh_can.toml, the paper's robot, whose SDH"
        " hand opens by centimetres; scenes/panda_can.toml: the Panda's, by millimetres)",
    )
    demo.set_defaults(handler=_demo_command)

    show = commands.add_parser(
        "show",
        help="write a plan's pictures: HTML animation, storyboard, hand law figure (or an"
        " execution's: the rollout animated, a reach / close / lift storyboard)",
    )
    show.add_argument(
        "plan", type=Path, help="plan JSON (README, Files: Plan), or an execution.json"
    )
    show.add_argument(
        "--out", type=_out_path, default=None, help="output directory (default: the plan's)"
    )
    show.set_defaults(handler=_show_command)

    law = commands.add_parser("law", help="plot the hand law alone for several u (Fig. 3)")
    source = law.add_mutually_exclusive_group()
    source.add_argument("--robot", default=None, help="robot name or TOML (default: panda)")
    source.add_argument(
        "--scene", type=Path, default=None, help="scene TOML: its robot and [hand] overrides"
    )
    law.add_argument(
        "--u", type=_unit_float, nargs="+", default=[0.0, 0.3, 1.0], help="values of u in [0, 1]"
    )
    law.add_argument("--continuous", action="store_true", help="the law without the jump at mga")
    law.add_argument(
        "--open-arrival", action="store_true", help="the law that reaches the grasp opened by u"
    )
    law.add_argument(
        "--out",
        type=_out_path,
        default=None,
        help="image file: PNG, PDF, SVG, ... by its suffix, PNG without one"
        " (default: <robot>_hand_law.png)",
    )
    law.set_defaults(handler=_law_command)

    robots = commands.add_parser(
        "robots", help="list the available robots: arm DOF, hand joints, description"
    )
    robots.set_defaults(handler=_robots_command)

    bench = commands.add_parser(
        "benchmark",
        help="run a problem suite through ompl.tools.Benchmark; OMPL logs, database, plots",
    )
    bench.add_argument(
        "--problems",
        type=Path,
        nargs="+",
        default=None,
        help="scene files or directories (default: every robot's suite, benchmarks/problems/*)",
    )
    bench.add_argument(
        "--planners",
        nargs="+",
        default=["ikbirrt", "rrtconnect"],
        metavar="NAME",
        help=f"one or more of {', '.join(PLANNERS)}",
    )
    bench.add_argument("--runs", type=_count, default=10, help="runs per problem, planner and hand")
    bench.add_argument("--time", type=_time_limit, default=5.0, help="time limit per run [s]")
    bench.add_argument(
        "--fixed-hand", action="store_true", help="also run the fixed preshape (hand frozen at w)"
    )
    bench.add_argument(
        "--out", type=_out_path, default=Path("openup-benchmark"), help="output directory"
    )
    bench.add_argument(
        "--workers",
        type=_count,
        default=None,
        help="local task processes at a time (default: the usable cores)",
    )
    bench.add_argument(
        "--scheduler",
        type=_scheduler,
        default=None,
        help="Dask scheduler address (tcp://host:port)",
    )
    bench.add_argument("--seed", type=_seed, default=1, help="seed of run 0 (run i: seed + i)")
    bench.add_argument("--quiet", action="store_true", help="no progress on stderr")
    bench.set_defaults(handler=_benchmark_command)

    execute = commands.add_parser(
        "execute",
        help="run a plan in physics (MuJoCo): reach with the object free, close, lift 10 cm,"
        " hold; exit 0 held, 1 failed",
    )
    execute.add_argument("plan", type=Path, help="plan JSON (README, Files: Plan)")
    execute.add_argument(
        "--object-offset",
        type=float,
        nargs=3,
        default=(0.0, 0.0, 0.0),
        metavar=("DX", "DY", "YAW"),
        help="true object pose error: world x, y [m] and yaw about its own z [rad]",
    )
    execute.add_argument(
        "--out", type=_out_path, default=None, help="output directory (default: the plan's)"
    )
    execute.add_argument(
        "--seed", type=_seed, default=1, help="run seed (draws PhysicsOptions.object_jitter)"
    )
    execute.set_defaults(handler=_execute_command)

    robust = commands.add_parser(
        "robustness",
        help="the paper's experiment: plan at the nominal object pose, execute against"
        " displaced ones, close the fingers, test force closure",
    )
    robust.add_argument(
        "--scene", type=Path, default=None, help="scene TOML (default: scenes/lwa3_sdh_can.toml)"
    )
    robust.add_argument(
        "--u",
        type=_unit_float,
        nargs="+",
        default=None,
        help="values of u (default: 0 0.1 0.3 0.5 1)",
    )
    robust.add_argument(
        "--delta",
        type=float,
        nargs="+",
        default=None,
        help="object position errors [m], each along +x, -x, +y, -y"
        " (default: 0 0.005 0.01 0.015 0.02 0.03)",
    )
    robust.add_argument(
        "--yaw",
        type=float,
        nargs="+",
        default=None,
        help="object rotations about its own z axis [rad] (default: 0)",
    )
    robust.add_argument("--seeds", type=_count, default=10, help="plans per u (trials per cell)")
    robust.add_argument("--seed", type=_seed, default=1, help="seed of plan 0 (plan i: seed + i)")
    robust.add_argument(
        "--planner", default="ikbirrt", type=_planner, metavar="NAME", help="planner name"
    )
    robust.add_argument("--time", type=_time_limit, default=5.0, help="time limit per plan [s]")
    robust.add_argument(
        "--friction", type=float, default=0.5, help="Coulomb coefficient of the grasp test"
    )
    robust.add_argument(
        "--torsion",
        type=float,
        default=None,
        help="soft-finger torsional friction [m] of the grasp test (default: the robot's,"
        " else 0: point contacts)",
    )
    robust.add_argument(
        "--open-arrival",
        action="store_true",
        help="plan with the extension that reaches the grasp opened by u",
    )
    robust.add_argument(
        "--execute",
        choices=("kinematic", "physics"),
        default="kinematic",
        help="judge each trial kinematically (welded object, force closure; the default)"
        " or in physics (MuJoCo: the object free, close, lift, hold)",
    )
    robust.add_argument(
        "--out", type=_out_path, default=Path("openup-robustness"), help="output directory"
    )
    robust.add_argument(
        "--workers",
        type=_count,
        default=None,
        help="local task processes at a time (default: the usable cores)",
    )
    robust.add_argument(
        "--scheduler",
        type=_scheduler,
        default=None,
        help="Dask scheduler address (tcp://host:port)",
    )
    robust.add_argument("--quiet", action="store_true", help="no progress on stderr")
    robust.set_defaults(handler=_robustness_command)

    perceive = commands.add_parser(
        "perceive",
        help="simulated depth view of the scene's object, superquadric fit, covariance;"
        " writes DIR/perceived.toml with the estimated pose and u",
    )
    perceive.add_argument("scene", type=Path, help="scene TOML (may hold a [camera] table)")
    perceive.add_argument(
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
    perceive.add_argument(
        "--noise", type=float, default=1.0, help="sensor noise scale (1: Kinect v1, 0: none)"
    )
    perceive.add_argument("--seed", type=_seed, default=1, help="seed of the sensor noise")
    perceive.add_argument("--out", type=_out_path, required=True, help="output directory")
    from openup_ompl.perception.cli import add_error_arguments

    add_error_arguments(perceive)
    perceive.set_defaults(handler=_perceive_command)

    loop = commands.add_parser(
        "closed-loop",
        help="perceive -> plan at the estimate with each policy's u -> execute against the"
        " true pose (kinematically or in physics), over noise scales and camera distances",
    )
    loop.add_argument(
        "--execute",
        choices=("kinematic", "physics"),
        default="kinematic",
        help="how a plan is judged against the true pose: the kinematic re-check and force"
        " closure, or a MuJoCo rollout that closes, lifts and holds (default: kinematic)",
    )
    loop.add_argument(
        "--scene", type=Path, default=None, help="scene TOML (default: scenes/lwa3_sdh_can.toml)"
    )
    loop.add_argument(
        "--policies",
        nargs="+",
        default=["0", "0.3", "1", "covariance"],
        help="fixed u values and/or 'covariance' (default: 0 0.3 1 covariance)",
    )
    loop.add_argument(
        "--camera",
        nargs="+",
        default=None,
        metavar="KEY=VALUE",
        help="camera options over the scene's [camera] (distance is swept by --distance)",
    )
    loop.add_argument(
        "--noise",
        type=float,
        nargs="+",
        default=[1.0, 2.0, 4.0],
        help="sensor noise scales (1: Kinect v1, 0: none)",
    )
    loop.add_argument("--distance", type=float, nargs="+", default=[0.6, 1.0], help="[m]")
    loop.add_argument("--trials", type=_count, default=10, help="views per noise and distance")
    loop.add_argument("--seed", type=_seed, default=1, help="seed of trial 0")
    loop.add_argument(
        "--planner", default="ikbirrt", type=_planner, metavar="NAME", help="planner name"
    )
    loop.add_argument("--time", type=_time_limit, default=5.0, help="time limit per plan [s]")
    loop.add_argument(
        "--out", type=_out_path, default=Path("openup-closed-loop"), help="output directory"
    )
    loop.add_argument("--quiet", action="store_true", help="no progress on stderr")
    add_error_arguments(loop)
    loop.set_defaults(handler=_closed_loop_command)
    return parser


def _closed_loop_command(args: argparse.Namespace) -> int:
    from openup_ompl.perception.cli import closed_loop_command

    _dir_out(args.out)
    return closed_loop_command(args)


def _perceive_command(args: argparse.Namespace) -> int:
    from openup_ompl.perception.cli import perceive_command

    _dir_out(args.out)
    return perceive_command(args)


def _robustness_command(args: argparse.Namespace) -> int:
    from openup_ompl.robustness import RobustnessOptions, markdown_tables, run_robustness

    _dir_out(args.out)
    given = {"us": args.u, "deltas": args.delta, "yaws": args.yaw}
    sweep: dict[str, Any] = {key: tuple(value) for key, value in given.items() if value}
    options = RobustnessOptions(
        **sweep,
        seeds=args.seeds,
        first_seed=args.seed,
        planner=args.planner,
        time_limit=args.time,
        friction=args.friction,
        open_arrival=args.open_arrival,
        torsion=args.torsion,
        execute=args.execute,
    )
    result = run_robustness(
        args.scene,
        options,
        args.out,
        workers=args.workers,
        scheduler=args.scheduler,
        quiet=args.quiet,
    )
    print(markdown_tables(result.rows), end="")
    print(f"table written to {result.csv} and {result.markdown}")
    if result.plot is not None:
        print(f"plot written to {result.plot}")
    if result.grasps is not None:
        print(f"grasps of one plan written to {result.grasps}")
    print(f"every trial in {result.trials}")
    return 0


def _execute_command(args: argparse.Namespace) -> int:
    from openup_ompl.physics import execute_plan, write_execution

    if args.out is not None:
        _dir_out(args.out)
    record = execute_plan(args.plan, args.object_offset, seed=args.seed)
    path = write_execution(record, args.out if args.out is not None else args.plan.parent)
    print(f"{record.verdict} (execution written to {path})")
    return 0 if record.success else 1


def _benchmark_command(args: argparse.Namespace) -> int:
    """Run the benchmark, then print the table and where the outputs are."""
    from openup_ompl.benchmark import default_problems, markdown_table, run_benchmark

    _dir_out(args.out)
    problems = args.problems or default_problems()
    result = run_benchmark(
        problems,
        args.planners,
        args.out,
        runs=args.runs,
        time_limit=args.time,
        fixed_hand=args.fixed_hand,
        workers=args.workers,
        scheduler=args.scheduler,
        seed=args.seed,
        quiet=args.quiet,
    )
    print(markdown_table(result.rows))
    print(f"OMPL logs in {result.logs}")
    print(f"database (Planner Arena) written to {result.database}")
    print(f"summary written to {result.summary}")
    for plot in result.plots:
        print(f"plot written to {plot}")
    return 0


def _plan(args: argparse.Namespace, scene: Path):  # type: ignore[no-untyped-def]
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
    setup = GraspPlanningSetup(load_scene(scene), options)
    return setup, setup.solve(seed=args.seed)


def _summary(plan) -> str:  # type: ignore[no-untyped-def]
    restarts = plan.stats.get("restarts", 0)
    restarted = f", {restarts} restart{'s' * (restarts != 1)}" if restarts else ""
    return (
        f"{plan.status.lower()} by {plan.planner} in {plan.solve_time_s * 1e3:.0f} ms "
        f"(seed {plan.seed}, u = {plan.law.u:g}, {plan.waypoints.shape[0]} waypoints, "
        f"{plan.path.shape[0]} states{restarted})"
    )


def _plan_command(args: argparse.Namespace) -> int:
    _file_out(args.out)
    _, plan = _plan(args, args.scene)
    print(_summary(plan))
    if args.out is not None:
        print(f"plan written to {plan.save(args.out)}")
    else:
        print("openup-ompl: no --out given: the plan was not saved", file=sys.stderr)
    return 0


def _demo_command(args: argparse.Namespace) -> int:
    from openup_ompl.scene import demo_scene_path

    _dir_out(args.out)
    _, plan = _plan(args, args.scene or demo_scene_path())
    print(_summary(plan))
    out: Path = args.out
    path = plan.save(out / "plan.json")
    print(f"plan written to {path}")
    try:
        _print_shown(path, out)
    except MissingExtra as error:
        print(f"no pictures: {error}", file=sys.stderr)
    return 0


def _print_shown(plan: Path, out: Path | None) -> None:
    from openup_ompl.viz import show

    shown = show(plan, out)
    print(f"animation written to {shown.html} (open it in a browser)")
    print(f"storyboard written to {shown.storyboard}")
    print(f"hand law figure written to {shown.hand_law}")


def _show_command(args: argparse.Namespace) -> int:
    from openup_ompl.physics.record import is_execution

    if args.out is not None:
        _dir_out(args.out)
    if is_execution(args.plan):
        from openup_ompl.viz.rollout import show_execution

        shown = show_execution(args.plan, args.out)
        print(f"rollout animation written to {shown.html} (open it in a browser)")
        print(f"rollout storyboard written to {shown.storyboard}")
        return 0
    _print_shown(args.plan, args.out)
    return 0


def _law_command(args: argparse.Namespace) -> int:
    from openup_ompl.robot import load_robot
    from openup_ompl.scene import load_scene
    from openup_ompl.viz._scene import prismatic_joints
    from openup_ompl.viz.law import figure_path, plot_law

    if len(set(args.u)) != len(args.u):  # as robustness refuses them (RobustnessOptions)
        raise ConfigError("u", list(args.u), "distinct values")
    _file_out(args.out)
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


def _robots_command(args: argparse.Namespace) -> int:
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


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status.

    Each subcommand sets ``handler`` (``args -> exit status``); commands that plan take
    ``--seed``, which seeds OMPL's process-wide generator before any OMPL object exists.
    """
    args = build_parser().parse_args(argv)
    from ompl import util as ompl_util

    from openup_ompl.executor import seed_ompl

    if hasattr(args, "seed"):
        if args.seed is None:
            args.seed = secrets.randbelow(2**31)
        # OMPL's planners draw from one process-wide generator that can only be seeded
        # before any OMPL object exists: do it first, so that the same seed gives the same
        # plan.
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


if __name__ == "__main__":
    run()
