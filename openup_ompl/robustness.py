"""The paper's experiment: plan with the perceived object pose, execute against the true one.

For each uncertainty ``u`` and planning seed, one plan is made with the nominal object
pose (what perception reported). That plan is then executed against the true object,
displaced by an error ``delta`` along the world x and y axes (both signs) and optionally
turned by ``yaw`` about its own z axis. In the shipped ``lwa3_sdh`` scene the world x
axis is the approach direction and y the lateral one, the axes of the paper's Fig. 1.

A trial succeeds when

1. the arm and hand touch neither the true object nor any obstacle at any row of the
   plan (the plan's rows are at the checker's resolution, the hand set by the law), and
2. closing the fingers at the end of the plan (:mod:`~openup_ompl.grasp`) holds the true
   object in force closure.

Runs go through the :mod:`~openup_ompl.executor`: one task per ``(u, seed)`` plans once
and executes every perturbation; each task process rebuilds its problem from the scene
file. A planning failure makes every trial of its task a failure (not a collision).

Outputs (:func:`run_robustness`): ``robustness.csv`` (one row per ``(u, dx, dy, yaw)``
cell), ``robustness.md`` (tables), ``robustness.png`` (success rate against error, one
line per ``u``) and ``trials.json`` (every trial), formatted by
:mod:`~openup_ompl.robustness_report`; ``grasps.png`` (the paper's Fig. 1) drawn by
:mod:`~openup_ompl.viz.grasps` from :func:`figure_trials`.
"""

from __future__ import annotations

import json
import math
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from openup_ompl import _toml
from openup_ompl._io import make_dir
from openup_ompl._resources import data_dir
from openup_ompl.exceptions import ConfigError, InvalidProblem, MissingExtra, PlanningFailed
from openup_ompl.executor import (
    SEED_LIMIT,
    Task,
    check_seeds,
    load_records,
    run_tasks,
    settings_digest,
)
from openup_ompl.grasp import check_torsion
from openup_ompl.plan import Plan
from openup_ompl.planning import GraspPlanningSetup
from openup_ompl.planning_options import PlanningOptions, check_planner, check_time_limit
from openup_ompl.robustness_report import markdown_tables, plot_robustness, write_csv
from openup_ompl.robustness_trial import (
    check_scene,
    displaced,
    execute,
    plan_nominal,
    robustness_run,
)
from openup_ompl.scene import Problem, Shape, load_scene
from openup_ompl.viz.grasps import write_grasp_figure

__all__ = [
    "CSV_COLUMNS",
    "EXECUTIONS",
    "MAX_DELTA",
    "MAX_SEEDS",
    "PHYSICS_COLUMNS",
    "SEED_LIMIT",
    "RobustnessOptions",
    "RobustnessResult",
    "check_scene",
    "check_seeds",
    "default_robustness_scene",
    "displaced",
    "execute",
    "figure_trials",
    "make_tasks",
    "markdown_tables",
    "perturbations",
    "plan_nominal",
    "plot_robustness",
    "robustness_run",
    "run_robustness",
    "summarize",
]

#: The columns of ``robustness.csv``, in order.
CSV_COLUMNS = (
    "u",
    "dx",
    "dy",
    "yaw",
    "trials",
    "successes",
    "success_rate",
    "collisions",
    "force_closure",
)
#: The columns a physics sweep adds (``--execute physics``): trials where the hand touched
#: the object before closing, and the median object displacement before closing [mm].
PHYSICS_COLUMNS = ("touched", "moved_mm")
#: How trials are executed: ``kinematic`` (the default) or ``physics`` (MuJoCo).
EXECUTIONS = ("kinematic", "physics")
#: Largest pose error [m] accepted: beyond it the "error" is a different scene.
MAX_DELTA = 0.25
#: Most plans per ``u`` accepted (``seeds``): 10 give the shipped tables, and every plan is
#: a process of up to ``time_limit`` seconds.
MAX_SEEDS = 10_000


def default_robustness_scene() -> Path:
    """The paper's robot taking a can from the side.

    Returns:
        The path of ``scenes/lwa3_sdh_can.toml``.
    """
    return data_dir("scenes") / "lwa3_sdh_can.toml"


@dataclass(frozen=True)
class RobustnessOptions:
    """The sweep's settings.

    Attributes:
        us: Uncertainties ``u`` in [0, 1] to plan with.
        deltas: Position errors [m], each applied along +x, -x, +y and -y (0: once).
        yaws: Rotations [rad] of the object about its own z axis, combined with every
            position error.
        seeds: Planning seeds per ``u`` (trials per cell).
        first_seed: Seed of the first plan (plan ``i`` uses ``first_seed + i``).
        planner: Planner name (:data:`~openup_ompl.planning.PLANNERS`).
        time_limit: Planning time limit [s].
        friction: Coulomb coefficient of the force-closure test.
        open_arrival: Plan with the law that reaches the grasp opened by ``u`` (an
            extension, :func:`~openup_ompl.hand_law.open_hand`) instead of Algorithm 3.
        torsion: Soft-finger torsional friction [m] of the grasp test; ``None``: the
            robot file's ``[hand].torsion`` (0, point contacts, if it has none).
        execute: ``"kinematic"`` (welded object, force closure) or ``"physics"`` (each
            trial a MuJoCo rollout, :mod:`openup_ompl.physics.sweep`).
        shared_approach: Physics only: a plan's trials share its approach
            (``PhysicsOptions.shared_approach``; faster, equal up to rounding).
    """

    us: tuple[float, ...] = (0.0, 0.1, 0.3, 0.5, 1.0)
    deltas: tuple[float, ...] = (0.0, 0.005, 0.01, 0.015, 0.02, 0.03)  # [m]
    yaws: tuple[float, ...] = (0.0,)  # [rad]
    seeds: int = 10
    first_seed: int = 1
    planner: str = "ikbirrt"
    time_limit: float = 5.0  # [s]
    friction: float = 0.5
    open_arrival: bool = False
    torsion: float | None = None
    execute: str = "kinematic"
    shared_approach: bool = False

    def __post_init__(self) -> None:
        def values(name: str, raw: Sequence[float], ok: Any, expected: str) -> tuple[float, ...]:
            try:
                if isinstance(raw, (str, bytes)) or any(isinstance(x, bool) for x in raw):
                    raise TypeError
                items = tuple(float(x) for x in raw)
            except (TypeError, ValueError):
                raise ConfigError(name, raw, f"a list of numbers: {expected}") from None
            if not items:
                raise ConfigError(name, list(raw), f"at least one value: {expected}")
            for x in items:
                if not (math.isfinite(x) and ok(x)):
                    raise ConfigError(name, x, expected)
            if len(set(items)) != len(items):
                raise ConfigError(name, list(items), "distinct values")
            return items

        object.__setattr__(
            self, "us", values("u", self.us, lambda x: 0 <= x <= 1, "values in [0, 1]")
        )
        object.__setattr__(
            self,
            "deltas",
            values(
                "delta",
                self.deltas,
                lambda x: 0 <= x <= MAX_DELTA,
                f"errors in [0, {MAX_DELTA}] m (each is applied with both signs)",
            ),
        )
        object.__setattr__(
            self,
            "yaws",
            values("yaw", self.yaws, lambda x: abs(x) <= math.pi, "angles in [-pi, pi] rad"),
        )
        check_seeds(self.first_seed, self.seeds, MAX_SEEDS, "seeds")
        for name in ("first_seed", "seeds"):  # numpy integers accepted, stored as int
            object.__setattr__(self, name, int(getattr(self, name)))
        check_planner(self.planner)
        check_time_limit(self.time_limit, "time")
        friction = self.friction
        if not (_toml.is_finite(friction) and friction >= 0):
            raise ConfigError("friction", friction, "a coefficient >= 0")
        if not isinstance(self.open_arrival, bool):
            raise ConfigError("open_arrival", self.open_arrival, "true or false")
        if self.execute not in EXECUTIONS:
            raise ConfigError("execute", self.execute, f"one of {list(EXECUTIONS)}")
        if self.shared_approach not in (False, True) or (
            self.shared_approach and self.execute != "physics"
        ):
            raise ConfigError(
                "shared_approach", self.shared_approach, "True or False (True with physics only)"
            )
        if self.torsion is not None:
            check_torsion(self.torsion)

    def planning(self, u: float) -> PlanningOptions:
        """How each plan of the sweep is made: at ``u``, simplified.

        Args:
            u: The hand law's closing parameter ``u`` (unitless, in ``[0, 1]``).

        Returns:
            The planning options of the sweep's plans at ``u``.
        """
        return PlanningOptions(
            u=u,
            open_arrival=self.open_arrival,
            planner=self.planner,
            time_limit=self.time_limit,
            simplify=True,
        )


def perturbations(
    deltas: Sequence[float], yaws: Sequence[float] = (0.0,)
) -> list[tuple[float, float, float]]:
    """The ``(dx, dy, yaw)`` cells: each ``delta`` along +x, -x, +y, -y (0 once), times
    every ``yaw``.

    Args:
        deltas: Object position errors [m] (``0`` gives the nominal cell once).
        yaws: Object yaw errors [rad] about the world z axis.

    Returns:
        The cells ``(dx [m], dy [m], yaw [rad])`` in the world frame, yaw-major.
    """
    cells: list[tuple[float, float, float]] = []
    for yaw in yaws:
        for delta in deltas:
            if delta == 0:
                cells.append((0.0, 0.0, float(yaw)))
            else:
                d = float(delta)
                cells += [(d, 0.0, yaw), (-d, 0.0, yaw), (0.0, d, yaw), (0.0, -d, yaw)]
    return cells


def make_tasks(
    scene: str | Path, options: RobustnessOptions, problem: Problem | None = None
) -> list[Task]:
    """One task per ``(u, seed)``; the key carries a digest of every setting and of the
    contents of the files the plans are made from (:meth:`Problem.source_files
    <openup_ompl.scene.Problem.source_files>`), so that a rerun with other settings, or
    after one of those files was edited, never reuses a shard
    (:func:`~openup_ompl.executor.settings_digest`).

    Args:
        scene: The scene file.
        options: The sweep.
        problem: ``scene`` already loaded (it is loaded here otherwise).

    Returns:
        The tasks, ``u``-major then seed, for :func:`~openup_ompl.executor.run_tasks`.

    Raises:
        ConfigError, RobotNotFound: What :func:`~openup_ompl.scene.load_scene` raises
            for ``scene`` (a missing file, a bad value, an unknown robot).
    """
    problem = load_scene(scene) if problem is None else problem
    path = str(problem.path)
    cells = perturbations(options.deltas, options.yaws)
    shared = {
        "scene": path,
        "planner": options.planner.lower(),
        "time_limit": float(options.time_limit),
        "perturbations": [list(cell) for cell in cells],
        "friction": float(options.friction),
        "open_arrival": bool(options.open_arrival),
        "torsion": options.torsion,
    }
    function = "openup_ompl.robustness_trial:robustness_run"
    if options.execute == "physics":
        shared["execute"] = "physics"
        function = "openup_ompl.physics.sweep:physics_run"
        if options.shared_approach:  # a setting of its own shards
            shared["shared_approach"] = True
    # The files' bytes, not only the scene's path (the task processes read the files
    # again, by path, so the contents stay out of their arguments).
    digest = settings_digest(shared, problem.source_files())
    tasks = []
    for u in options.us:
        for i in range(options.seeds):
            seed = options.first_seed + i
            tasks.append(
                Task(
                    key=f"u{u:g}-seed{seed}-{digest}",
                    function=function,
                    kwargs={**shared, "u": float(u)},
                    seed=seed,
                )
            )
    return tasks


def summarize(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Count the trials' outcomes per cell.

    Args:
        records: One record per ``(u, seed)``, as the tasks return them.

    Returns:
        One row per ``(u, dx, dy, yaw)`` cell (``dx, dy`` [m], ``yaw`` [rad]) with the
        :data:`CSV_COLUMNS` (and :data:`PHYSICS_COLUMNS` for physics trials), in sweep
        order.
    """
    cells: dict[tuple[float, float, float, float], dict[str, Any]] = {}
    for record in records:
        for trial in record["trials"]:
            key = (record["u"], trial["dx"], trial["dy"], trial["yaw"])
            row = cells.setdefault(
                key,
                dict(zip(CSV_COLUMNS[:4], key, strict=True))
                | {"trials": 0, "successes": 0, "collisions": 0, "force_closure": 0},
            )
            row["trials"] += 1
            row["successes"] += int(trial["success"])
            row["collisions"] += int(trial["collision"])
            row["force_closure"] += int(bool(trial.get("force_closure")))
            if "touched" in trial:
                row.setdefault("touched", 0)
                row["touched"] += int(trial["touched"])
                moved = trial.get("moved_before_closing")
                row.setdefault("moved", []).extend([moved["mm"]] if moved else [])
    rows = []
    for row in cells.values():
        row["success_rate"] = row["successes"] / row["trials"]
        columns = {column: row[column] for column in CSV_COLUMNS}
        if "touched" in row:
            # Physics: no force-closure test; the median of the planned trials' moves.
            columns["force_closure"] = ""
            moved = row["moved"]
            columns |= {"touched": row["touched"], "moved_mm": np.median(moved) if moved else ""}
        rows.append(columns)
    return rows


@dataclass(frozen=True)
class RobustnessResult:
    """What :func:`run_robustness` wrote and found.

    Attributes:
        csv: ``robustness.csv``.
        markdown: ``robustness.md``.
        plot: ``robustness.png``, or ``None`` without matplotlib.
        grasps: ``grasps.png`` (the paper's Fig. 1: one plan's grasp, open and closed,
            at each error direction), or ``None`` without matplotlib or when its plan
            failed.
        trials: ``trials.json`` (every record).
        rows: The CSV rows.
        records: One record per ``(u, seed)``.
    """

    csv: Path
    markdown: Path
    plot: Path | None
    trials: Path
    rows: list[dict[str, Any]]
    records: list[dict[str, Any]]
    grasps: Path | None = None


def run_robustness(
    scene: str | Path | None = None,
    options: RobustnessOptions | None = None,
    out: str | Path = "openup-robustness",
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    quiet: bool = False,
) -> RobustnessResult:
    """Run the experiment (skipping finished tasks) and write its outputs to ``out``.

    Args:
        scene: Scene file (default :func:`default_robustness_scene`).
        options: The sweep (default :class:`RobustnessOptions`).
        out: Output directory.
        workers: Local task processes at a time (default: the usable cores).
        scheduler: Dask scheduler address; ``None`` runs locally.
        quiet: No progress on stderr.

    Returns:
        The files written and the rows and records found.

    Raises:
        InvalidProblem: The scene has no object, or its robot no hand to close.
        ConfigError: Bad options, arguments of another type, or ``out`` a file.
        SweepFailed: Some task failed on every attempt.
    """
    if scene is not None and not isinstance(scene, (str, os.PathLike)):
        raise ConfigError("scene", scene, "a scene file's path or None")
    if options is not None and not isinstance(options, RobustnessOptions):
        raise ConfigError("options", options, "RobustnessOptions or None")
    if not isinstance(out, (str, os.PathLike)):
        raise ConfigError("out", out, "an output directory's path")
    scene = Path(scene) if scene is not None else default_robustness_scene()
    options = options or RobustnessOptions()
    problem = check_scene(scene)
    out = make_dir(Path(out))
    tasks = make_tasks(scene, options, problem)
    run_tasks(tasks, out / "shards", workers=workers, scheduler=scheduler, quiet=quiet)
    records = load_records(tasks, out / "shards")
    rows = summarize(records)
    trials = out / "trials.json"
    trials.write_text(json.dumps(records, indent=1) + "\n")
    physics = options.execute == "physics"
    csv_path = write_csv(
        rows, out / "robustness.csv", (*CSV_COLUMNS, *(PHYSICS_COLUMNS if physics else ()))
    )
    markdown = out / "robustness.md"
    law = "open-arrival variant" if options.open_arrival else "Algorithm 3"
    torsion = problem.robot.spec.torsion if options.torsion is None else options.torsion
    contacts = f", soft fingers {torsion * 1e3:g} mm" if torsion > 0 else ""
    judge = (
        "executed in physics (MuJoCo)" if physics else f"friction {options.friction:g}{contacts}"
    )
    title = (
        f"{problem.robot.name}, {scene.name}, {law}: {options.seeds} plans per u "
        f"({options.planner}, {options.time_limit:g} s), {judge}"
    )
    markdown.write_text(
        f"# Robustness to object pose errors\n\n{title}\n\n" + markdown_tables(rows)
    )

    plot: Path | None
    try:
        plot = plot_robustness(rows, out / "robustness.png", title=title)
    except MissingExtra as error:
        print(f"no plot: {error}", file=sys.stderr)
        plot = None
    grasps = None
    if options.execute != "kinematic":
        # A kinematic run's Fig. 1 left in ``out`` would sit beside other trials' results.
        (out / "grasps.png").unlink(missing_ok=True)
    elif plot is not None:
        figure = figure_trials(problem, options, torsion)
        if figure is not None:
            grasps = write_grasp_figure(figure[0], figure[1], out / "grasps.png")
    return RobustnessResult(csv_path, markdown, plot, trials, rows, records, grasps)


def figure_trials(
    problem: Problem, options: RobustnessOptions, torsion: float
) -> tuple[Plan, list[tuple[dict[str, Any], np.ndarray, Shape]]] | None:
    """The paper's Fig. 1 experiment for one plan: ``u = 0.3`` (or the middle ``u``), the
    first seed, executed at the nominal pose and at the largest error up to 2 cm in each
    direction.

    Args:
        problem: The sweep's scene, loaded.
        options: The sweep.
        torsion: Soft-finger torsional friction lever [m] (``0``: point contacts).

    Returns:
        The plan and, per error, ``(trial, closed hand q, true object)``; ``None`` when
        planning failed (the reason on stderr).
    """
    u = 0.3 if 0.3 in options.us else sorted(options.us)[len(options.us) // 2]
    moved = [d for d in options.deltas if 0 < d <= 0.02] or [d for d in options.deltas if d > 0]
    cells = perturbations([0.0, *([max(moved)] if moved else [])])
    try:
        setup = GraspPlanningSetup(problem, options.planning(u))
        plan = setup.solve(seed=options.first_seed)
    except (PlanningFailed, InvalidProblem) as error:
        print(f"no grasp figure: {error}", file=sys.stderr)
        return None
    columns = []
    for dx, dy, yaw in cells:
        trial, grasp = execute(setup, plan, dx, dy, yaw, friction=options.friction, torsion=torsion)
        true = displaced(problem, dx, dy, yaw).object
        assert true is not None
        columns.append((trial, grasp.q, true))
    return plan, columns
