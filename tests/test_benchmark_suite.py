"""The problem suite and the benchmark runner: OMPL logs, database with extra columns."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest
from ompl import util as ompl_util

import openup_ompl as oo
from openup_ompl.__main__ import main
from openup_ompl.benchmark import (
    EXTRA_COLUMNS,
    default_problems,
    default_problems_dir,
    find_problems,
    make_tasks,
    problem_id,
    run_benchmark,
)
from openup_ompl.exceptions import ConfigError

ompl_util.setLogLevel(ompl_util.LOG_ERROR)

SUITE = sorted(default_problems_dir().glob("*.toml"))
#: One suite per robot: every directory of ``benchmarks/problems``.
SUITE_DIRS = default_problems()
ALL_SCENES = [p for d in SUITE_DIRS for p in sorted(d.glob("*.toml"))]
EIGHT_SCENES = {
    "table_pick",
    "table_under_pick",
    "shelf_small",
    "shelf_tall",
    "box",
    "cage",
    "clutter",
    "narrow_passage",
}


def test_every_robot_has_a_suite() -> None:
    """The Panda, UR5 + Allegro and LWA3 + SDH suites are all there."""
    assert {"panda", "ur5_allegro", "lwa3_sdh"} <= {d.name for d in SUITE_DIRS}


@pytest.mark.parametrize("suite", SUITE_DIRS, ids=[d.name for d in SUITE_DIRS])
def test_suite_has_the_eight_scenes(suite: Path) -> None:
    """Every robot's suite holds the eight MotionBenchMaker-style scenes."""
    assert {p.stem for p in suite.glob("*.toml")} >= EIGHT_SCENES


@pytest.mark.parametrize("path", ALL_SCENES, ids=[f"{p.parent.name}/{p.stem}" for p in ALL_SCENES])
def test_suite_problem_loads_with_reachable_grasp(path: Path) -> None:
    """Every suite scene loads, its start is free and its grasp has a free IK solution."""
    problem = oo.load_scene(path)
    assert problem.robot.name == path.parent.name, path
    assert problem.object is not None, path
    setup = oo.GraspPlanningSetup(problem)
    assert setup.goal.solutions, path.name
    assert setup.checker.is_valid(setup.goal.solutions[0])


def test_suites_of_all_robots_make_distinct_problems() -> None:
    """The suites share scene names; their problems are named <robot>.<scene>, one each."""
    problems = find_problems(SUITE_DIRS)
    names = [problem_id(p) for p in problems]
    assert len(problems) == len(ALL_SCENES) == len(set(names))
    assert {"panda.cage", "lwa3_sdh.cage", "ur5_allegro.cage"} <= set(names)
    keys = [t.key for t in make_tasks(problems, ["ikbirrt"], runs=1, time_limit=1.0)]
    assert len(set(keys)) == len(problems)


def test_a_rerun_reuses_a_run_only_with_the_same_time_and_files(tmp_path: Path) -> None:
    """The task keys (the shards a rerun into the same folder reuses) change with the time
    limit, the first seed and the problem file's contents: a finished run of another time
    limit or seed, or of the scene before an edit, is not taken for this one."""
    problem = tmp_path / "table_pick.toml"
    problem.write_text((default_problems_dir() / "table_pick.toml").read_text())

    def key(time_limit: float = 1.0, seed: int = 1) -> str:
        return make_tasks([problem], ["ikbirrt"], runs=1, time_limit=time_limit, seed=seed)[0].key

    first = key()
    assert key() == first and key(2.0) != first and key(seed=100) != first
    problem.write_text(problem.read_text().replace("u = 0.3", "u = 0.31"))
    assert key() != first


@pytest.mark.slow
def test_two_problem_benchmark_database(tmp_path: Path) -> None:
    """2 problems x 2 planners x 2 runs give 8 runs rows with the extra columns filled."""
    problems = [default_problems_dir() / "table_pick.toml", default_problems_dir() / "clutter.toml"]
    result = run_benchmark(
        problems,
        ["ikbirrt", "rrtconnect"],
        tmp_path,
        runs=2,
        time_limit=5.0,
        workers=2,
        quiet=True,
        plots=False,
    )
    assert len(list(result.logs.glob("*.log"))) == 8
    with sqlite3.connect(result.database) as conn:
        columns = [row[1] for row in conn.execute("PRAGMA table_info(runs)")]
        assert set(EXTRA_COLUMNS) <= set(columns)
        assert {"time", "solved", "solution_length"} <= set(columns)
        rows = conn.execute(
            "SELECT run_key, problem, hand, seed, ik_calls, state_checks, final_aperture, "
            "solved, plannerConfigs.name FROM runs "
            "JOIN plannerConfigs ON plannerConfigs.id = runs.plannerid"
        ).fetchall()
        experiments = {r[0] for r in conn.execute("SELECT name FROM experiments")}
    # run_key: the task's key, problem-planner-hand-run and a digest of the settings.
    assert sorted(r[0].rsplit("-", 1)[0] for r in rows) == sorted(
        f"{p}-{n}-law-{i:04d}"
        for p in ("panda.table_pick", "panda.clutter")
        for n in ("ikbirrt", "rrtconnect")
        for i in range(2)
    )
    assert experiments == {"panda.table_pick", "panda.clutter"}
    assert {r[8] for r in rows} == {"geometric_IKBiRRT", "geometric_RRTConnect"}
    for key, problem, hand, seed, ik_calls, checks, aperture, solved, _ in rows:
        assert key.startswith(problem) and hand == "law" and seed in (1, 2)
        assert ik_calls > 0 and checks > 0
        if solved:  # the law closes the hand to c at the grasp: 2 x 0.03 or 2 x 0.035 m
            expected = 0.06 if problem == "panda.table_pick" else 0.07
            assert aperture == pytest.approx(expected, abs=1e-4)
    assert {r["problem"] for r in result.rows} == {"panda.table_pick", "panda.clutter"}


@pytest.mark.slow
def test_fixed_hand_configuration_is_a_separate_planner(tmp_path: Path) -> None:
    """--fixed-hand adds runs named <planner>_fixed_w whose hand stays at w."""
    result = run_benchmark(
        [default_problems_dir() / "table_pick.toml"],
        ["rrtconnect"],
        tmp_path,
        runs=1,
        fixed_hand=True,
        workers=2,
        quiet=True,
        plots=False,
    )
    with sqlite3.connect(result.database) as conn:
        rows = dict(
            conn.execute(
                "SELECT plannerConfigs.name, final_aperture FROM runs "
                "JOIN plannerConfigs ON plannerConfigs.id = runs.plannerid"
            ).fetchall()
        )
    assert set(rows) == {"geometric_RRTConnect", "geometric_RRTConnect_fixed_w"}
    assert rows["geometric_RRTConnect_fixed_w"] == pytest.approx(0.08, abs=1e-4)


@pytest.mark.parametrize(
    "kwargs",
    [{"planners": ["nosuch"]}, {"runs": 0}, {"runs": -3}, {"time_limit": 0.0}],
)
def test_bad_benchmark_input_raises_config_error(kwargs: dict) -> None:
    """An unknown planner, runs <= 0 or a bad time limit is a ConfigError."""
    args = {"planners": ["ikbirrt"], "runs": 1, "time_limit": 1.0, **kwargs}
    with pytest.raises(ConfigError):
        make_tasks(SUITE[:1], args["planners"], args["runs"], args["time_limit"])


def test_missing_problem_dir_raises_config_error(tmp_path: Path) -> None:
    """A problems path that does not exist, or holds no scene, is a ConfigError."""
    with pytest.raises(ConfigError, match="nowhere"):
        find_problems([tmp_path / "nowhere"])
    with pytest.raises(ConfigError):
        find_problems([tmp_path])


def test_cli_bad_benchmark_input_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """openup-ompl benchmark with an unknown planner exits 2 with one line naming it."""
    status = main(["benchmark", "--planners", "nosuch", "--out", str(tmp_path), "--quiet"])
    assert status == 2
    assert "nosuch" in capsys.readouterr().err
