"""Soak: plan many problems and re-check every plan independently (issue 37).

Problems come from three kinds of source, for the three robots:

- ``scene``: the hand-written scenes (``scenes/*.toml``, the problem suites
  ``benchmarks/problems/<robot>/*.toml``, the tests' Panda scenes), each planned again
  with another seed per instance;
- ``family``: the study's generated scenes (:mod:`openup_ompl.study.families`, every kind,
  for the robots that have families), one new instance per index;
- ``perturbed``: the UR5-Allegro's hand-written scenes with the object and its grasp
  moved together (``PERTURB_XY`` [m], ``PERTURB_YAW`` [rad]), as perception would
  report them.

Every instance is planned with every planner of ``--planners`` at every ``u`` of ``--us``
(seed: the instance index + 1), and every plan's file contents are re-checked by the
tests' independent checker (``tests/recheck.py``: rebuilt from the plan's URDF, SRDF,
shapes and law alone; each segment re-interpolated at ``--recheck-step`` rad of joint
motion, finer than the planner's motion check; all of a plan's states checked in one
batch through Coal's broad phase). A plan is *valid* when no re-checked state collides,
its hand is the law's at every row (1e-9), it leaves from the start and ends at the
grasp (1 mm, 0.01 rad).

Runs go through :mod:`openup_ompl.executor`: one task per block of ``--block``
consecutive instances of one source (a task process starts in about a second; its
re-check builds each robot's model once), one shard per task in ``OUT/shards``; a rerun
skips finished tasks (a larger ``--plans`` keeps every whole block and redoes the last,
partial block of each source). ``OUT/soak.json`` sums up every plan's record;
``OUT/soak.md`` is the results-page section: the command, the counts per robot, source,
planner and ``u``, the unsolved and invalid plans, and where this run's time went
(seconds per plan of each phase, plans per second per worker).

Usage (from the repository root)::

    python benchmarks/soak.py --plans 10000 --out soak --workers 2
    python benchmarks/soak.py --plans 200 --out soak-check
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import json
import math
import os
import shlex
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

import openup_ompl as oo
from openup_ompl._resources import data_dir
from openup_ompl.benchmark import default_problems_dir
from openup_ompl.exceptions import ConfigError, InvalidProblem, OpenUpError, PlanningFailed
from openup_ompl.executor import Task, load_records, run_tasks, settings_digest
from openup_ompl.planning_options import check_planner, check_time_limit

ROOT = Path(__file__).resolve().parent.parent
ROBOTS = ("panda", "lwa3_sdh", "ur5_allegro")
PLANNERS = ("ikbirrt", "rrtconnect", "bitstar", "kpiece1")
US = (0.0, 0.3, 1.0)
#: Object (and grasp) displacement of a ``perturbed`` instance [m], each axis in +-.
PERTURB_XY = 0.03
#: Its yaw about the object's own z [rad], in +-.
PERTURB_YAW = 0.25
#: Joint motion [rad, Euclidean] between re-checked states: 1.5 mrad, a few mm of palm
#: motion at most, finer than the planner's 6 mm certified resolution.
RECHECK_STEP = 0.0015


def _recheck_module() -> Any:
    """``tests/recheck.py``, loaded by path (the tests are not a package)."""
    if "recheck" in sys.modules:
        return sys.modules["recheck"]
    spec = importlib.util.spec_from_file_location("recheck", ROOT / "tests" / "recheck.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["recheck"] = module  # its dataclass looks its module up there
    spec.loader.exec_module(module)
    return module


# -- the problems ------------------------------------------------------------------------


def hand_written(robot: str) -> list[Path]:
    """The hand-written scenes of ``robot``: the shipped ones and its problem suite (and
    the tests' scenes for the Panda)."""
    scenes = sorted(data_dir("scenes").glob(f"{robot}_*.toml"))
    scenes += sorted(default_problems_dir(robot).glob("*.toml"))
    if robot == "panda":
        scenes += sorted((ROOT / "tests" / "scenes").glob("*.toml"))
    return scenes


def _interleaved(lists: list[list[dict[str, Any]]]) -> list[dict[str, Any]]:
    """The lists' items taken in turn (the first of each, then the second, ...)."""
    out = []
    for k in range(max(map(len, lists), default=0)):
        out += [items[k] for items in lists if k < len(items)]
    return out


def generators(robots: tuple[str, ...] = ROBOTS) -> list[dict[str, Any]]:
    """The problem sources, interleaved by robot and kind (a short soak covers them all):
    one per hand-written scene, study family and perturbed scene."""
    from openup_ompl.study.families import KINDS
    from openup_ompl.study.families import ROBOTS as FAMILY_ROBOTS

    per_robot = []
    for robot in robots:
        scenes = [
            {"kind": "scene", "robot": robot, "name": f"{robot}-{p.stem}", "path": str(p)}
            for p in hand_written(robot)
        ]
        if robot in FAMILY_ROBOTS:
            made = [{"kind": "family", "robot": robot, "name": f"{robot}-{k}"} for k in KINDS]
        else:
            made = [
                {**scene, "kind": "perturbed", "name": f"{scene['name']}-perturbed"}
                for scene in scenes
            ]
        per_robot.append(_interleaved([made, scenes]))
    return _interleaved(per_robot)


def instance(source: dict[str, Any], index: int, mesh_dir: Path) -> oo.Problem:
    """Instance ``index`` of a problem source (the same for the same index).

    Raises:
        ConfigError, InvalidProblem: A generated instance that cannot be posed.
    """
    from openup_ompl.study.families import Family, instance_problem, template_scene

    if source["kind"] == "scene":
        return oo.load_scene(source["path"])
    rng = np.random.default_rng([index, sum(source["name"].encode())])
    if source["kind"] == "family":
        family = Family(source["name"], source["robot"], source["name"].split("-", 1)[1])
        return instance_problem(family, rng, template_scene(family), mesh_dir)
    from openup_ompl.perception.perceive import at_estimate
    from openup_ompl.robustness_trial import displaced
    from openup_ompl.scene import check_object_clear

    problem = oo.load_scene(source["path"])
    if problem.object is None:
        return problem
    dx, dy = rng.uniform(-PERTURB_XY, PERTURB_XY, 2)
    yaw = rng.uniform(-PERTURB_YAW, PERTURB_YAW)
    moved = displaced(problem, dx, dy, yaw)
    assert moved.object is not None
    moved = at_estimate(problem, moved.object.pose)
    check_object_clear(moved.obstacles, moved.object, f"{source['name']}{index}")
    return moved


# -- one task: the plans of one instance ---------------------------------------------------


def _recheck(plan: oo.Plan, recheck: Any, step: float) -> dict[str, Any]:
    """The independent re-check of ``plan``'s file contents."""
    started = time.perf_counter()
    data = json.loads(json.dumps(plan.to_dict()))
    result = recheck.recheck_plan(data, finer=1, resolution=step)
    valid = (
        result.colliding == []
        and result.hand_error < 1e-9
        and result.start_error < 1e-9
        and result.position_error <= 1e-3
        and result.rotation_error <= 1e-2
    )
    return {
        "valid": bool(valid),
        "states": result.states,
        "colliding": result.colliding,
        "hand_error": result.hand_error,
        "position_error": result.position_error,
        "rotation_error": result.rotation_error,
        "start_error": result.start_error,
        "recheck_s": time.perf_counter() - started,
    }


def soak_instance(
    source: dict[str, Any],
    index: int,
    planners: list[str],
    us: list[float],
    time_limit: float,
    recheck_step: float,
    mesh_dir: str,
) -> dict[str, Any]:
    """Plan instance ``index`` of ``source`` with every planner and ``u`` (seed
    ``index + 1``), re-check each plan; the record also holds where the time went [s]:
    posing the instance (``scene_s``), setting up (``setup_s``), planning, re-checking."""
    started = time.perf_counter()
    recheck = _recheck_module()
    base = {"robot": source["robot"], "source": source["kind"], "name": source["name"]}
    try:
        problem = instance(source, index, Path(mesh_dir))
    except (ConfigError, InvalidProblem) as error:
        return {**base, "index": index, "refused": str(error), "plans": []}
    scene_s = time.perf_counter() - started
    setup_s = 0.0
    plans = []
    for u in us:
        set_up = time.perf_counter()
        try:
            setup = oo.GraspPlanningSetup(problem, u=u)
        except OpenUpError as error:  # the problem cannot be posed (start, grasp)
            refused = f"{type(error).__name__}: {error}"
            plans += [
                {"planner": p, "u": u, "status": "refused", "error": refused} for p in planners
            ]
            continue
        finally:
            setup_s += time.perf_counter() - set_up
        for planner in planners:
            row: dict[str, Any] = {"planner": planner, "u": u, "seed": index + 1}
            solving = time.perf_counter()
            try:
                plan = setup.solve(time_limit=time_limit, planner=planner, seed=index + 1)
            except PlanningFailed as error:
                plan = None
                row.update(status="unsolved", error=str(error))
            row["solve_s"] = time.perf_counter() - solving
            if plan is not None:
                check = _recheck(plan, recheck, recheck_step)
                status = "valid" if check["valid"] else "invalid"
                row.update(status=status, rows=int(plan.path.shape[0]), **check)
                row["solve_time_s"] = plan.solve_time_s
            plans.append(row)
    wall = time.perf_counter() - started
    return {
        **base,
        "index": index,
        "refused": None,
        "plans": plans,
        "wall_s": wall,
        "scene_s": scene_s,
        "setup_s": setup_s,
    }


def soak_block(
    seed: int, source: dict[str, Any], first: int, count: int, **settings: Any
) -> dict[str, Any]:
    """Instances ``first, ..., first + count - 1`` of ``source``, one after the other in
    this process (an executor task: ``seed`` seeds OMPL once, before the first; the
    robot models of the re-check are built once). Keyword arguments: those of
    :func:`soak_instance`."""
    started = time.perf_counter()
    instances = [soak_instance(source, index, **settings) for index in range(first, first + count)]
    return {"instances": instances, "wall_s": time.perf_counter() - started}


# -- the sweep -----------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class SoakOptions:
    """The soak's settings.

    Attributes:
        plans: Plans to make at least (rounded up to whole instances).
        planners: Planner names.
        us: Uncertainties ``u``.
        time_limit: Planning time per plan [s].
        recheck_step: Joint motion [rad] between re-checked states.
        robots: Robots to soak.
        block: Instances of one source per task process (a process starts in about
            1.5 s, imports and robot models included; a killed task loses its block).
    """

    plans: int = 10_000
    planners: tuple[str, ...] = PLANNERS
    us: tuple[float, ...] = US
    time_limit: float = 5.0  # [s]
    recheck_step: float = RECHECK_STEP  # [rad]
    robots: tuple[str, ...] = ROBOTS
    block: int = 4

    def __post_init__(self) -> None:
        if not (isinstance(self.plans, int) and self.plans >= 1):
            raise ConfigError("plans", self.plans, "a positive integer")
        for name in self.planners:
            check_planner(name)
        for u in self.us:
            if not (isinstance(u, (int, float)) and 0.0 <= u <= 1.0):
                raise ConfigError("u", u, "a number in [0, 1]")
        check_time_limit(self.time_limit)
        if not (math.isfinite(self.recheck_step) and 0 < self.recheck_step <= 0.015):
            raise ConfigError("recheck_step", self.recheck_step, "a step in (0, 0.015] rad")
        for robot in self.robots:
            if robot not in ROBOTS:
                raise ConfigError("robot", robot, f"one of {list(ROBOTS)}")
        if not (isinstance(self.block, int) and self.block >= 1):
            raise ConfigError("block", self.block, "a positive integer")


def make_tasks(options: SoakOptions, mesh_dir: Path) -> list[Task]:
    """Enough instances for ``options.plans`` plans, taken round-robin over the sources
    (instance ``k`` is index ``k // S`` of source ``k % S``, so that a short soak covers
    every robot and source); one task per block of ``options.block`` consecutive indices
    of a source, the first blocks of every source first. A larger ``--plans`` keeps the
    whole blocks (their keys) and redoes the last, partial one of a source."""
    sources = generators(options.robots)
    per_instance = len(options.planners) * len(options.us)
    count = math.ceil(options.plans / per_instance)
    shared = {
        "planners": list(options.planners),
        "us": list(options.us),
        "time_limit": float(options.time_limit),
        "recheck_step": float(options.recheck_step),
        "mesh_dir": str(mesh_dir),
    }
    files = sorted({p for s in sources for p in oo.load_scene(_template(s)).source_files()})
    digest = settings_digest(shared, [*files, ROOT / "tests" / "recheck.py"])
    indices = [len(range(s, count, len(sources))) for s in range(len(sources))]
    tasks = []
    for first in range(0, max(indices, default=0), options.block):
        for source, n in zip(sources, indices, strict=True):
            if first >= n:
                continue
            size = min(options.block, n - first)
            tasks.append(
                Task(
                    key=f"{source['kind']}-{source['name']}-{first}-{size}-{digest}",
                    function="benchmarks.soak:soak_block",
                    kwargs={**shared, "source": source, "first": first, "count": size},
                    seed=first + 1,
                )
            )
    return tasks


def _template(source: dict[str, Any]) -> Path:
    if "path" in source:
        return Path(source["path"])
    from openup_ompl.study.families import ROBOTS as FAMILY_ROBOTS

    return data_dir("scenes") / FAMILY_ROBOTS[source["robot"]]


STATUSES = ("valid", "invalid", "unsolved", "refused")
#: The columns of a plan's record that :func:`summarize` times [s], in order.
PHASES = ("scene_s", "setup_s", "solve_s", "recheck_s")


def summarize(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Counts of plans by status, overall and per robot, source, planner and ``u``; the
    invalid plans; where the task processes' time went [s].

    Args:
        records: The tasks' records (:func:`soak_block`).

    Returns:
        A JSON-able dict: ``plans``, ``counts`` (by status), ``groups`` (by ``"robot
        panda"``, ``"source family"``, ``"planner bitstar"``, ``"u 0.3"``), ``unsolved``
        (by robot, source and planner), ``invalid`` (their rows), ``states_rechecked``,
        ``time_s`` (summed over the instances: each phase of :data:`PHASES`, ``instance``
        their whole wall time, ``task`` the task functions' wall time).
    """
    total: Counter[str] = Counter()
    groups: dict[str, Counter[str]] = {}
    unsolved: Counter[str] = Counter()
    invalid = []
    time_s = dict.fromkeys([*PHASES, "instance"], 0.0)
    instances = [record for task in records for record in task["instances"]]
    for record in instances:
        time_s["instance"] += record.get("wall_s", 0.0)
        time_s["scene_s"] += record.get("scene_s", 0.0)
        time_s["setup_s"] += record.get("setup_s", 0.0)
        for row in record["plans"]:
            total[row["status"]] += 1
            time_s["solve_s"] += row.get("solve_s", 0.0)
            time_s["recheck_s"] += row.get("recheck_s", 0.0)
            keys = (
                f"robot {record['robot']}",
                f"source {record['source']}",
                f"planner {row['planner']}",
                f"u {row['u']:g}",
            )
            for key in keys:
                groups.setdefault(key, Counter())[row["status"]] += 1
            if row["status"] == "unsolved":
                unsolved[f"{record['robot']} {record['source']} {row['planner']}"] += 1
            if row["status"] == "invalid":
                invalid.append({k: record[k] for k in ("robot", "name", "index")} | row)
    return {
        "instances": len(instances),
        "refused_instances": sum(record["refused"] is not None for record in instances),
        "plans": sum(total.values()),
        "counts": dict(total),
        "groups": {key: dict(groups[key]) for key in sorted(groups, key=_group_order)},
        "unsolved": dict(sorted(unsolved.items())),
        "invalid": invalid,
        "states_rechecked": sum(
            row.get("states", 0) for record in instances for row in record["plans"]
        ),
        "time_s": {**time_s, "task": sum(task.get("wall_s", 0.0) for task in records)},
    }


def _group_order(key: str) -> tuple[int, str]:
    kind, _, name = key.partition(" ")
    return ["robot", "source", "planner", "u"].index(kind), name


def _row(name: str, counts: dict[str, int]) -> str:
    return f"| {name} | " + " | ".join(str(counts.get(s, 0)) for s in STATUSES) + " |"


def markdown(summary: dict[str, Any], options: SoakOptions, command: str) -> str:
    """The summary as a results-page section: the command, the settings, one table of
    counts (all, then per robot, source, planner, ``u``), the unsolved and invalid plans,
    and where the time went.

    Args:
        summary: :func:`summarize`'s, with ``run`` (:func:`timing`) when tasks ran now.
        options: The soak's settings.
        command: The command line that made it.

    Returns:
        Markdown text.
    """
    lines = [
        f"`{command}`: {summary['plans']} plans of {summary['instances']} instances "
        f"({summary['refused_instances']} instances refused as posed); planners "
        f"{', '.join(options.planners)}; u in {', '.join(f'{u:g}' for u in options.us)}; "
        f"{options.time_limit:g} s per plan; each plan re-checked every "
        f"{options.recheck_step:g} rad of joint motion ({summary['states_rechecked']:,} "
        "states in all).",
        "",
        "| plans | " + " | ".join(STATUSES) + " |",
        "|---|" + "---:|" * len(STATUSES),
        _row("all", summary["counts"]),
        *(_row(key, counts) for key, counts in summary["groups"].items()),
        "",
    ]
    if summary["unsolved"]:
        listed = ", ".join(f"{key} {n}" for key, n in summary["unsolved"].items())
        lines.append(
            f"Unsolved within {options.time_limit:g} s (robot, source, planner): {listed}."
        )
    if summary["invalid"]:
        lines.append(f"Invalid plans ({len(summary['invalid'])}):")
        lines += [
            f"- {row['robot']} {row['name']} #{row['index']}, {row['planner']} u = {row['u']:g}: "
            f"colliding segments {row['colliding'][:10]}, hand error {row['hand_error']:.2g}, "
            f"position error {row['position_error']:.2g} m, rotation error "
            f"{row['rotation_error']:.2g} rad, start error {row['start_error']:.2g} rad"
            for row in summary["invalid"]
        ]
    else:
        lines.append("Invalid plans: none.")
    if "run" in summary:
        lines += ["", timing_text(summary["run"])]
    return "\n".join(lines) + "\n"


def timing(ran: list[dict[str, Any]], wall: float, workers: int) -> dict[str, Any]:
    """Where this run's time went: the tasks it ran (``ran``, their records) took ``wall``
    seconds on ``workers`` processes.

    Returns:
        ``plans``, ``wall_s``, ``workers``, ``plans_per_s_per_worker`` and ``per_plan_s``:
        seconds per plan of each phase of :data:`PHASES`, ``other`` (the rest of the
        instances' time: results, files) and ``outside`` (the workers' time outside the
        task functions: process start-up, imports, waiting at the end).
    """
    part = summarize(ran)
    plans = max(part["plans"], 1)
    spent = part["time_s"]
    per_plan = {phase: spent[phase] / plans for phase in PHASES}
    per_plan["other"] = (spent["task"] - sum(spent[phase] for phase in PHASES)) / plans
    per_plan["outside"] = (wall * workers - spent["task"]) / plans
    return {
        "plans": part["plans"],
        "wall_s": wall,
        "workers": workers,
        "plans_per_s_per_worker": part["plans"] / (wall * workers),
        "per_plan_s": per_plan,
    }


def timing_text(run: dict[str, Any]) -> str:
    """One paragraph on :func:`timing`'s figures."""
    names = {
        "scene_s": "posing the instance",
        "setup_s": "setting up",
        "solve_s": "planning",
        "recheck_s": "re-checking",
        "other": "the rest of the task",
        "outside": "process start-up and idle workers",
    }
    parts = ", ".join(f"{names[k]} {v:.3f}" for k, v in run["per_plan_s"].items())
    return (
        f"This run: {run['plans']} plans in {run['wall_s']:.0f} s on {run['workers']} "
        f"worker(s), {run['plans_per_s_per_worker']:.3f} plans per second per worker; "
        f"seconds per plan: {parts}."
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--plans", type=int, default=10_000, help="plans to make at least")
    parser.add_argument("--planners", nargs="+", default=list(PLANNERS))
    parser.add_argument("--us", type=float, nargs="+", default=list(US))
    parser.add_argument("--robots", nargs="+", default=list(ROBOTS))
    parser.add_argument("--time", type=float, default=5.0, help="time limit per plan [s]")
    parser.add_argument("--recheck-step", type=float, default=RECHECK_STEP, help="[rad]")
    parser.add_argument("--block", type=int, default=4, help="instances per task process")
    parser.add_argument("--workers", type=int, default=1, help="task processes at a time")
    parser.add_argument("--scheduler", default=None, help="Dask scheduler address")
    parser.add_argument("--out", type=Path, default=Path("soak"))
    parser.add_argument("--quiet", action="store_true")
    args = parser.parse_args(argv)
    try:
        options = SoakOptions(
            plans=args.plans,
            planners=tuple(args.planners),
            us=tuple(args.us),
            time_limit=args.time,
            recheck_step=args.recheck_step,
            robots=tuple(args.robots),
            block=args.block,
        )
    except ConfigError as error:
        print(f"soak: error: {error}", file=sys.stderr)
        return 2
    out = args.out.resolve()
    mesh_dir = out / "meshes"
    mesh_dir.mkdir(parents=True, exist_ok=True)
    # The task processes import this script as ``benchmarks.soak``.
    paths = [str(ROOT), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    os.environ["PYTHONPATH"] = os.pathsep.join(dict.fromkeys(paths))
    tasks = make_tasks(options, mesh_dir)
    started = time.perf_counter()
    ran = run_tasks(
        tasks, out / "shards", workers=args.workers, scheduler=args.scheduler, quiet=args.quiet
    )
    wall = time.perf_counter() - started
    summary = summarize(load_records(tasks, out / "shards"))
    if ran and args.scheduler is None:
        now = load_records([task for task in tasks if task.key in set(ran)], out / "shards")
        summary["run"] = timing(now, wall, args.workers)
    command = shlex.join(
        ["python", "benchmarks/soak.py", *(sys.argv[1:] if argv is None else argv)]
    )
    summary["command"] = command
    (out / "soak.json").write_text(json.dumps(summary, indent=1) + "\n")
    text = markdown(summary, options, command)
    (out / "soak.md").write_text(text)
    print(text, end="")
    return 1 if summary["counts"].get("invalid", 0) else 0


if __name__ == "__main__":
    sys.exit(main())
