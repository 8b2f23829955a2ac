"""Benchmark a problem suite on OMPL's own tooling.

Every run (problem x planner x hand configuration x repetition) is one task of the
:mod:`~openup_ompl.executor`: a fresh process loads the scene file, builds a
:class:`~openup_ompl.planning.GraspPlanningSetup` and runs ``ompl.tools.Benchmark`` once
with one planner, so each run writes a genuine OMPL benchmark log. The logs are turned
into an SQLite database by OMPL's own ``ompl_benchmark_statistics`` (Planner Arena reads
it), then the per-run counters OMPL does not know about are added as extra columns of the
``runs`` table (:data:`EXTRA_COLUMNS`). PNG plots of solve time and success per problem
and planner are drawn with matplotlib (the ``viz`` extra).

Hand configurations: ``law`` is the paper's hand law; ``fixed`` is the classical fixed
preshape, the hand frozen at ``w`` for the whole reach. In the database the fixed runs'
planner is named ``<planner>_fixed_w``.

OMPL's planners are given the goal region's pregrasp states
(:attr:`~openup_ompl.planning.PlanningOptions.pregrasp`): their paths, as OMPL logs them,
end there, so their ``solution length`` leaves out the certified straight approach
(``pregrasp`` metres of palm motion) that :meth:`GraspPlanningSetup.solve
<openup_ompl.planning.GraspPlanningSetup.solve>` appends; IKBiRRT's paths include its retreat.
"""

from __future__ import annotations

import json
import math
import sqlite3
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from ompl import tools as ot

from openup_ompl import _toml
from openup_ompl._io import json_safe
from openup_ompl._resources import data_dir
from openup_ompl.benchmark_report import plot_results, summarize
from openup_ompl.exceptions import ConfigError, InvalidProblem, MissingExtra, OpenUpError
from openup_ompl.executor import Task, check_seeds, load_records, run_tasks, settings_digest
from openup_ompl.planning import GraspPlanningSetup
from openup_ompl.planning_options import PlanningOptions, check_planner, check_time_limit
from openup_ompl.scene import load_scene

__all__ = [
    "EXTRA_COLUMNS",
    "HANDS",
    "MAX_RUNS",
    "PROBLEMS_ROOT",
    "BenchmarkResult",
    "benchmark_run",
    "build_database",
    "default_problems",
    "default_problems_dir",
    "find_problems",
    "make_tasks",
    "plot_results",
    "problem_id",
    "run_benchmark",
    "summarize",
]

#: Hand configurations: the law, and the classical fixed preshape (hand frozen at w).
HANDS: tuple[str, ...] = ("law", "fixed")
#: Most runs per problem, planner and hand accepted (each a process of up to the time
#: limit): the bound of the robustness sweep's seeds.
MAX_RUNS = 10_000
#: Columns added to the database's ``runs`` table, with their SQL types.
EXTRA_COLUMNS: dict[str, str] = {
    "run_key": "TEXT",
    "problem": "TEXT",
    "hand": "TEXT",
    "seed": "INTEGER",
    "ik_calls": "INTEGER",
    "state_checks": "INTEGER",
    "motion_checks": "INTEGER",
    "final_aperture": "REAL",
}


#: The shipped problem suites, one directory per robot (``benchmarks/problems`` of the
#: source tree, package data in a wheel).
PROBLEMS_ROOT = data_dir("problems")


def default_problems_dir(robot: str = "panda") -> Path:
    """The shipped suite of ``robot``: ``benchmarks/problems/<robot>``.

    Args:
        robot: A shipped robot's name.

    Returns:
        The directory.
    """
    return PROBLEMS_ROOT / robot


def default_problems() -> list[Path]:
    """Every robot's suite: the directories under :data:`PROBLEMS_ROOT`.

    Returns:
        The suite directories, sorted.
    """
    return sorted(path for path in PROBLEMS_ROOT.iterdir() if path.is_dir())


def problem_id(path: Path) -> str:
    """``<robot>.<scene>``: the problem's name in task keys, the database and the tables
    (the suites of different robots use the same scene names).

    Args:
        path: The scene file (``.../<robot>/<scene>.toml``).

    Returns:
        The id.
    """
    robot = _toml.read_toml(Path(path), "scene file").get("robot", "")
    return f"{Path(str(robot)).stem}.{Path(path).stem}"


def find_problems(paths: Sequence[str | Path]) -> list[Path]:
    """Scene files from directories (their ``*.toml``, sorted) and files.

    Args:
        paths: Scene files and directories of them.

    Returns:
        The scene files, in order, each once.

    Raises:
        ConfigError: A path that does not exist, no scene file at all, or two scenes of
            the same :func:`problem_id`.
    """
    found: list[Path] = []
    for entry in paths:
        path = Path(entry)
        if path.is_dir():
            found.extend(sorted(path.glob("*.toml")))
        elif path.is_file():
            found.append(path)
        else:
            raise ConfigError("problems", str(path), "an existing scene file or directory")
    if not found:
        raise ConfigError("problems", [str(p) for p in paths], "at least one scene TOML")
    names = [problem_id(p) for p in found]
    if len(set(names)) != len(names):
        raise ConfigError("problems", names, "scenes with distinct <robot>.<scene> names")
    return found


def _planner_names(planners: Sequence[str]) -> list[str]:
    if not planners:
        raise ConfigError("planners", list(planners), "at least one planner")
    return [check_planner(p) for p in planners]


def make_tasks(
    problems: Sequence[Path],
    planners: Sequence[str],
    runs: int,
    time_limit: float,
    *,
    hands: Sequence[str] = ("law",),
    seed: int = 1,
) -> list[Task]:
    """The sweep: one task per problem x planner x hand x run.

    Run ``i`` has seed ``seed + i`` for every problem, planner and hand, so the
    configurations are compared on the same seeds. The keys carry a digest of the time
    limit, the first seed and the problem's files (:func:`~openup_ompl.executor.settings_digest`).

    Args:
        problems: Scene files.
        planners: Planner names.
        runs: Runs per problem, planner and hand.
        time_limit: Time limit per run [s].
        hands: ``"law"`` and/or ``"fixed"``.
        seed: Seed of run 0.

    Returns:
        The tasks, each with its key and arguments.

    Raises:
        ConfigError: Unknown planner or hand, ``runs`` outside ``[1, MAX_RUNS]``, seeds
            outside ``[0, 2^31)``, a bad time limit, or what
            :func:`~openup_ompl.scene.load_scene` raises for a problem file.
    """
    names = _planner_names(planners)
    check_seeds(seed, runs, MAX_RUNS, "runs")
    seed, runs = int(seed), int(runs)  # numpy integers accepted; task files hold ints
    check_time_limit(time_limit, "time")
    for hand in hands:
        if hand not in HANDS:
            raise ConfigError("hand", hand, f"one of {list(HANDS)}")
    tasks = []
    for problem in problems:
        ident, path = problem_id(Path(problem)), str(Path(problem).resolve())
        # A rerun into the same shards reuses a run only with the same time limit, first
        # seed, and scene, robot and URDF files.
        digest = settings_digest(
            {"time_limit": float(time_limit), "seed": seed}, load_scene(problem).source_files()
        )
        for name in names:
            for hand in hands:
                for i in range(runs):
                    tasks.append(
                        Task(
                            key=f"{ident}-{name}-{hand}-{i:04d}-{digest}",
                            function="openup_ompl.benchmark:benchmark_run",
                            kwargs={
                                "problem": path,
                                "planner": name,
                                "hand": hand,
                                "time_limit": float(time_limit),
                            },
                            seed=seed + i,
                        )
                    )
    return tasks


def benchmark_run(
    seed: int, problem: str, planner: str, hand: str, time_limit: float
) -> dict[str, Any]:
    """One run through ``ompl.tools.Benchmark`` (inside a task process).

    Args:
        seed: The run's seed (OMPL's generator and ours).
        problem: The scene file's path.
        planner: A planner name of :data:`~openup_ompl.planning.PLANNERS`.
        hand: ``"law"`` or ``"fixed"`` (the hand frozen at ``w``).
        time_limit: The run's time limit [s].

    Returns:
        The record: OMPL's log text (``log``), OMPL's run properties (``time``,
        ``solved``, ``length``, ...), and the extra counters of :data:`EXTRA_COLUMNS`.
    """
    name = problem_id(Path(problem))
    record: dict[str, Any] = {"problem": name, "planner": planner, "hand": hand, "seed": seed}
    try:
        options = PlanningOptions(fixed_hand="w" if hand == "fixed" else None)
        setup = GraspPlanningSetup(load_scene(problem), options)
    except InvalidProblem as error:
        # A setup that cannot start is a failed run with no OMPL log.
        return {**record, "error": str(error), "solved": False, "time": time_limit}
    instance = setup.make_planner(planner, seed)
    if hand == "fixed":
        instance.setName(f"{instance.getName()}_fixed_w")
    setup.reseed(seed)
    checker, ik = setup.checker, setup.ik
    before = (checker.states_checked, checker.motions_checked, ik.calls)
    bench = ot.Benchmark(setup.simple_setup, name)
    bench.addPlanner(instance)
    request = ot.Request()
    request.maxTime = float(time_limit)
    request.runCount = 1
    request.displayProgress = False
    request.saveConsoleOutput = False
    bench.benchmark(request)
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "run.log"
        bench.saveResultsToFile(str(log))
        record["log"] = log.read_text()
    experiment = bench.getRecordedExperimentData()
    props = experiment.planners[0].runs[0].to_dict()
    record["planner_name"] = experiment.planners[0].name
    record["time"] = float(props.get("time REAL", math.nan))
    record["solved"] = str(props.get("solved BOOLEAN", "0")) in ("1", "True", "true")
    length = props.get("solution length REAL")
    record["length"] = float(length) if length not in (None, "") else None
    record["ik_calls"] = ik.calls - before[2]
    record["state_checks"] = checker.states_checked - before[0]
    record["motion_checks"] = checker.motions_checked - before[1]
    record["final_aperture"] = None
    ss = setup.simple_setup
    if record["solved"] and ss.haveExactSolutionPath():
        dof = setup.problem.robot.arm_idx.size
        last = ss.getSolutionPath().getStates()[-1]
        arm = np.array([last[i] for i in range(dof)])
        approach = setup.goal_region.approach(arm)
        if approach.shape[0]:  # a pregrasp state: the hand at the grasp is at its end
            arm = approach[-1]
        q = checker.coupled_q(arm)
        # Sum of the hand joints (for the Panda, the gap between the fingers [m]).
        record["final_aperture"] = float(np.sum(q[setup.problem.robot.hand_idx]))
    return record


_STATISTICS = "import sys; from ompl.ompl_benchmark_statistics import main; sys.exit(main())"


def build_database(records: Sequence[dict[str, Any]], out: Path) -> Path:
    """Write the OMPL logs, build ``benchmark.db`` with ``ompl_benchmark_statistics``
    and add :data:`EXTRA_COLUMNS` to its ``runs`` table.

    Args:
        records: The runs' records (:func:`benchmark_run`).
        out: The output directory.

    Returns:
        The database's path (``out/benchmark.db``).

    Raises:
        InvalidProblem: No run has a log: no problem could be set up (each named with
            why).
        OpenUpError: ``ompl_benchmark_statistics`` failed.
    """
    out = Path(out)
    logged = [r for r in records if r.get("log")]
    if not logged:
        failed = {r["problem"]: r.get("error", "no OMPL log") for r in records}
        raise InvalidProblem(
            "no problem could be set up, so there is no OMPL log to benchmark: "
            + "; ".join(f"{problem}: {why}" for problem, why in failed.items())
        )
    logs_dir = out / "logs"
    logs_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for record in logged:
        path = logs_dir / f"{record['key']}.log"
        path.write_text(record["log"])
        paths.append(str(path))
    db = out / "benchmark.db"
    db.unlink(missing_ok=True)
    done = subprocess.run(
        # OMPL's console script ``ompl_benchmark_statistics``, run by this interpreter.
        [sys.executable, "-c", _STATISTICS, "-d", str(db), "-v", *paths],
        capture_output=True,
        text=True,
    )
    if done.returncode != 0 or not db.exists():
        raise OpenUpError(f"ompl_benchmark_statistics failed: {done.stderr.strip()[-400:]}")
    with sqlite3.connect(db) as conn:
        # The logs were read in this order into a fresh database: experiment i+1 is log i.
        ids = [row[0] for row in conn.execute("SELECT id FROM experiments ORDER BY id")]
        if len(ids) != len(logged):
            raise OpenUpError(f"{len(ids)} experiments in the database for {len(logged)} logs")
        for column, kind in EXTRA_COLUMNS.items():
            conn.execute(f"ALTER TABLE runs ADD COLUMN {column} {kind}")
        sets = ", ".join(f"{c} = ?" for c in EXTRA_COLUMNS)
        for experiment, record in zip(ids, logged, strict=True):
            values = [record.get(c if c != "run_key" else "key") for c in EXTRA_COLUMNS]
            conn.execute(f"UPDATE runs SET {sets} WHERE experimentid = ?", [*values, experiment])
    return db


@dataclass(frozen=True)
class BenchmarkResult:
    """Where a benchmark wrote its outputs, and its summary rows.

    Attributes:
        database: ``benchmark.db`` (OMPL's schema, plus the extra ``runs`` columns).
        logs: The directory of OMPL's log files.
        summary: ``summary.json``.
        plots: The PNG plots written (empty without matplotlib or with ``plots=False``).
        rows: The summary rows (:func:`summarize`).
        records: Every run's record.
    """

    database: Path
    logs: Path
    summary: Path
    plots: list[Path]
    rows: list[dict[str, Any]]
    records: list[dict[str, Any]]


def run_benchmark(
    problems: Sequence[str | Path],
    planners: Sequence[str],
    out: str | Path,
    *,
    runs: int = 10,
    time_limit: float = 5.0,
    fixed_hand: bool = False,
    workers: int | None = None,
    scheduler: str | None = None,
    seed: int = 1,
    plots: bool = True,
    quiet: bool = False,
) -> BenchmarkResult:
    """Run the sweep (skipping finished runs), merge it into the database, summarise.

    Args:
        problems: Scene files or directories of them.
        planners: Names from :data:`~openup_ompl.planning.PLANNERS`.
        out: Output directory (shards, logs, ``benchmark.db``, ``summary.json``, plots).
        runs: Runs per problem, planner and hand.
        time_limit: Time limit per run [s].
        fixed_hand: Also run the fixed preshape (hand frozen at ``w``).
        workers: Local task processes at a time (default: the usable cores).
        scheduler: Dask scheduler address; ``None`` runs locally.
        seed: Seed of run 0 (run ``i`` uses ``seed + i``).
        plots: Draw the PNG plots (skipped with a note when matplotlib is missing).
        quiet: No progress on stderr.

    Returns:
        The summary rows, the database's path and the plots written
        (:class:`BenchmarkResult`).

    Raises:
        ConfigError: What :func:`find_problems` and :func:`make_tasks` raise, or a scene
            file that does not load (:func:`~openup_ompl.scene.load_scene`), before any
            run.
    """
    out = Path(out)
    hands = ("law", "fixed") if fixed_hand else ("law",)
    found = find_problems(problems)
    # make_tasks loads every scene (its files key the runs): a bad scene is one error
    # here, not a failed task per run.
    tasks = make_tasks(found, planners, runs, time_limit, hands=hands, seed=seed)
    run_tasks(tasks, out / "shards", workers=workers, scheduler=scheduler, quiet=quiet)
    records = load_records(tasks, out / "shards")
    db = build_database(records, out)
    rows = summarize(records)
    summary = out / "summary.json"
    summary.write_text(json.dumps({"rows": json_safe(rows)}, indent=1, default=str) + "\n")
    drawn: list[Path] = []
    if plots:
        try:
            drawn = plot_results(rows, out)
        except MissingExtra as error:
            print(f"no plots: {error}", file=sys.stderr)
    return BenchmarkResult(db, out / "logs", summary, drawn, rows, records)
