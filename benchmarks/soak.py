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
motion, finer than the planner's motion check). A plan is *valid* when no re-checked
state collides, its hand is the law's at every row (1e-9), it leaves from the start and
ends at the grasp (1 mm, 0.01 rad).

Runs go through :mod:`openup_ompl.executor`: one task per instance (its plans), one
shard per task in ``OUT/shards``; a rerun (a larger ``--plans`` too) skips finished
tasks. ``OUT/soak.json`` holds every plan's record summed up, ``OUT/soak.md`` the table.

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
    seed: int,
    source: dict[str, Any],
    index: int,
    planners: list[str],
    us: list[float],
    time_limit: float,
    recheck_step: float,
    mesh_dir: str,
) -> dict[str, Any]:
    """Plan instance ``index`` of ``source`` with every planner and ``u``, re-check each
    plan (an executor task; ``seed`` seeds OMPL, the plans use ``index + 1``)."""
    started = time.perf_counter()
    recheck = _recheck_module()
    base = {"robot": source["robot"], "source": source["kind"], "name": source["name"]}
    try:
        problem = instance(source, index, Path(mesh_dir))
    except (ConfigError, InvalidProblem) as error:
        return {**base, "index": index, "refused": str(error), "plans": []}
    plans = []
    for u in us:
        try:
            setup = oo.GraspPlanningSetup(problem, u=u)
        except OpenUpError as error:  # the problem cannot be posed (start, grasp)
            refused = f"{type(error).__name__}: {error}"
            plans += [
                {"planner": p, "u": u, "status": "refused", "error": refused} for p in planners
            ]
            continue
        for planner in planners:
            row: dict[str, Any] = {"planner": planner, "u": u, "seed": index + 1}
            try:
                plan = setup.solve(time_limit=time_limit, planner=planner, seed=index + 1)
            except PlanningFailed as error:
                row.update(status="unsolved", error=str(error))
            else:
                check = _recheck(plan, recheck, recheck_step)
                status = "valid" if check["valid"] else "invalid"
                row.update(status=status, rows=int(plan.path.shape[0]), **check)
                row["solve_time_s"] = plan.solve_time_s
            plans.append(row)
    wall = time.perf_counter() - started
    return {**base, "index": index, "refused": None, "plans": plans, "wall_s": wall}


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
    """

    plans: int = 10_000
    planners: tuple[str, ...] = PLANNERS
    us: tuple[float, ...] = US
    time_limit: float = 5.0  # [s]
    recheck_step: float = RECHECK_STEP  # [rad]
    robots: tuple[str, ...] = ROBOTS

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


def make_tasks(options: SoakOptions, mesh_dir: Path) -> list[Task]:
    """One task per instance, round-robin over the sources (so that a short soak covers
    every robot and source), enough for ``options.plans`` plans."""
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
    tasks = []
    for k in range(count):
        source = sources[k % len(sources)]
        index = k // len(sources)
        tasks.append(
            Task(
                key=f"{source['kind']}-{source['name']}-{index}-{digest}",
                function="benchmarks.soak:soak_instance",
                kwargs={**shared, "source": source, "index": index},
                seed=index + 1,
            )
        )
    return tasks


def _template(source: dict[str, Any]) -> Path:
    if "path" in source:
        return Path(source["path"])
    from openup_ompl.study.families import ROBOTS as FAMILY_ROBOTS

    return data_dir("scenes") / FAMILY_ROBOTS[source["robot"]]


def summarize(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Counts of plans by status, overall and per robot, source and planner."""
    total: Counter[str] = Counter()
    groups: dict[str, Counter[str]] = {}
    invalid = []
    refused_instances = 0
    for record in records:
        refused_instances += record["refused"] is not None
        for row in record["plans"]:
            total[row["status"]] += 1
            for key in (record["robot"], record["source"], row["planner"]):
                groups.setdefault(key, Counter())[row["status"]] += 1
            if row["status"] == "invalid":
                invalid.append({k: record[k] for k in ("robot", "name", "index")} | row)
    return {
        "instances": len(records),
        "refused_instances": refused_instances,
        "plans": sum(total.values()),
        "counts": dict(total),
        "groups": {key: dict(counter) for key, counter in sorted(groups.items())},
        "invalid": invalid,
        "states_rechecked": sum(
            row.get("states", 0) for record in records for row in record["plans"]
        ),
        "task_wall_s": sum(record.get("wall_s", 0.0) for record in records),
    }


def markdown(summary: dict[str, Any], options: SoakOptions) -> str:
    """The summary as a results-page table."""
    statuses = ("valid", "invalid", "unsolved", "refused")
    lines = [
        f"{summary['plans']} plans of {summary['instances']} instances "
        f"({summary['refused_instances']} instances refused as posed); planners "
        f"{', '.join(options.planners)}; u in {list(options.us)}; "
        f"{options.time_limit:g} s per plan; re-checked every {options.recheck_step:g} rad "
        f"({summary['states_rechecked']} states).",
        "",
        "| group | " + " | ".join(statuses) + " |",
        "|---|" + "---:|" * len(statuses),
        "| all | " + " | ".join(str(summary["counts"].get(s, 0)) for s in statuses) + " |",
    ]
    for key, counts in summary["groups"].items():
        lines.append(f"| {key} | " + " | ".join(str(counts.get(s, 0)) for s in statuses) + " |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--plans", type=int, default=10_000, help="plans to make at least")
    parser.add_argument("--planners", nargs="+", default=list(PLANNERS))
    parser.add_argument("--us", type=float, nargs="+", default=list(US))
    parser.add_argument("--robots", nargs="+", default=list(ROBOTS))
    parser.add_argument("--time", type=float, default=5.0, help="time limit per plan [s]")
    parser.add_argument("--recheck-step", type=float, default=RECHECK_STEP, help="[rad]")
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
    run_tasks(
        tasks, out / "shards", workers=args.workers, scheduler=args.scheduler, quiet=args.quiet
    )
    wall = time.perf_counter() - started
    summary = summarize(load_records(tasks, out / "shards"))
    summary["wall_s_this_run"] = wall
    (out / "soak.json").write_text(json.dumps(summary, indent=1) + "\n")
    (out / "soak.md").write_text(markdown(summary, options))
    print(markdown(summary, options), end="")
    return 1 if summary["counts"].get("invalid", 0) else 0


if __name__ == "__main__":
    sys.exit(main())
