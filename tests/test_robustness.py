"""The paper's experiment (``openup-ompl robustness``): perturbations, the sweep's
outputs and their consistency, and typed refusals of bad input."""

from __future__ import annotations

import csv
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from test_cli import assert_one_error_line, run_cli

import openup_ompl as oo
from openup_ompl.exceptions import ConfigError, InvalidProblem
from openup_ompl.robustness import (
    CSV_COLUMNS,
    RobustnessOptions,
    check_scene,
    default_robustness_scene,
    displaced,
    make_tasks,
    perturbations,
    run_robustness,
)

pytestmark = pytest.mark.slow  # subprocesses, sweeps or OMPL benchmark runs

SMALL = RobustnessOptions(us=(0.0, 0.3), deltas=(0.0, 0.02), seeds=2, time_limit=5.0)


@pytest.fixture(scope="module")
def small_sweep(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    """2 u x 2 delta x 2 seeds on the paper's robot, run once through the executor."""
    out = tmp_path_factory.mktemp("robustness")
    return out, run_robustness(None, SMALL, out, workers=2, quiet=True)


def test_small_sweep_writes_consistent_counts(small_sweep) -> None:  # type: ignore[no-untyped-def]
    """The CSV has the documented columns and one row per (u, dx, dy, yaw) cell; its
    counts are consistent with each other and with every trial in trials.json."""
    out, result = small_sweep
    with (out / "robustness.csv").open() as handle:
        reader = csv.DictReader(handle)
        assert tuple(reader.fieldnames or ()) == CSV_COLUMNS
        rows = list(reader)
    cells = {(float(r["u"]), float(r["dx"]), float(r["dy"]), float(r["yaw"])) for r in rows}
    expected = {(u, dx, dy, yaw) for u in SMALL.us for dx, dy, yaw in perturbations(SMALL.deltas)}
    assert cells == expected and len(rows) == len(expected) == 10
    trials = json.loads((out / "trials.json").read_text())
    assert len(trials) == len(SMALL.us) * SMALL.seeds
    for row in rows:
        n, ok = int(row["trials"]), int(row["successes"])
        collisions, closure = int(row["collisions"]), int(row["force_closure"])
        assert n == SMALL.seeds
        assert 0 <= ok <= min(closure, n - collisions)
        assert float(row["success_rate"]) == pytest.approx(ok / n, abs=1e-4)
        key = (float(row["u"]), float(row["dx"]), float(row["dy"]))
        mine = [
            t
            for record in trials
            if record["u"] == key[0]
            for t in record["trials"]
            if (t["dx"], t["dy"]) == key[1:]
        ]
        assert len(mine) == n
        assert sum(t["success"] for t in mine) == ok
        assert sum(t["collision"] for t in mine) == collisions
        assert all(t["success"] == (not t["collision"] and t["force_closure"]) for t in mine)
    assert (out / "robustness.md").read_text().count("/") >= 10
    assert result.plot is not None and result.plot.stat().st_size > 10_000
    assert result.grasps == out / "grasps.png" and result.grasps.stat().st_size > 20_000


def test_nominal_pose_succeeds_and_large_side_errors_collide(small_sweep) -> None:  # type: ignore[no-untyped-def]
    """With no error every plan grasps the can in force closure; a 2 cm error towards a
    finger (+y or -y) makes a finger touch the can along the plan."""
    _, result = small_sweep
    for row in result.rows:
        if row["dx"] == row["dy"] == 0:
            assert row["successes"] == row["trials"]
        if row["dy"] != 0:
            assert row["collisions"] == row["trials"]
    for record in result.records:
        assert record["planned"]
        for trial in record["trials"]:
            if trial["collision"]:
                assert any("env/can" in pair for pair in trial["pairs"])


def test_rerun_reuses_every_shard(small_sweep, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """Running the same sweep again into the same directory plans nothing and gives the
    same rows; other settings get other task keys."""
    out, result = small_sweep
    again = run_robustness(None, SMALL, out, workers=2, quiet=True)
    assert again.rows == result.rows
    keys = {t.key for t in make_tasks(default_robustness_scene(), SMALL)}
    other = RobustnessOptions(us=SMALL.us, deltas=(0.0, 0.01), seeds=2)
    assert keys.isdisjoint(t.key for t in make_tasks(default_robustness_scene(), other))


def test_an_edited_scene_robot_or_urdf_gets_other_task_keys(tmp_path: Path) -> None:
    """Task keys carry the contents of the scene, robot and URDF files, not only the
    scene's path: the same files give the same keys, and each edit (the can's radius,
    the robot's padding, a URDF joint limit) gives keys no earlier run used."""
    problem = oo.load_scene(default_robustness_scene())
    spec = problem.robot.spec
    shutil.copytree(spec.urdf.parent, tmp_path / spec.urdf.parent.name)
    robot = tmp_path / spec.path.name
    robot.write_text(spec.path.read_text())
    scene = tmp_path / "scene.toml"
    text = default_robustness_scene().read_text()
    scene.write_text(text.replace('robot = "lwa3_sdh"', f'robot = "{robot.name}"'))
    urdf = tmp_path / spec.urdf.parent.name / spec.urdf.name

    def keys() -> set[str]:
        return {task.key for task in make_tasks(scene, SMALL)}

    seen = [keys()]
    assert keys() == seen[0]
    edits = [
        (scene, "radius = 0.033", "radius = 0.034"),
        (robot, "\nhome = ", "\npadding = 0.001\nhome = "),
        (urdf, 'upper="3.14159"', 'upper="3.0"'),
    ]
    for path, old, new in edits:
        before = path.read_text()
        assert old in before, path
        path.write_text(before.replace(old, new, 1))
        seen.append(keys())
    for i, earlier in enumerate(seen):
        for later in seen[i + 1 :]:
            assert earlier.isdisjoint(later)


def test_open_c_scene_of_the_readme_loads() -> None:
    """The README's scene with c opened to c + 0.3 (w - c) loads for the experiment."""
    path = Path(__file__).resolve().parent.parent / "benchmarks" / "robustness"
    problem = check_scene(path / "lwa3_sdh_can_open_c.toml")
    spec = problem.robot.spec
    expected = problem.robot.expand_hand(spec.c + 0.3 * (spec.w - spec.c))
    np.testing.assert_allclose(problem.hand_law.c, expected, atol=1e-4)


def test_perturbations_and_displacement() -> None:
    """Each error appears along +x, -x, +y, -y (zero once) for every yaw; the true
    object moves by exactly (dx, dy) and turns about its own z axis."""
    cells = perturbations([0.0, 0.01, 0.02], yaws=[0.0, 0.5])
    assert len(cells) == 2 * (1 + 4 * 2) and len(set(cells)) == len(cells)
    assert (0.01, 0.0, 0.5) in cells and (0.0, -0.02, 0.0) in cells
    problem = oo.load_scene(default_robustness_scene())
    moved = displaced(problem, 0.01, -0.02, 0.5)
    assert problem.object is not None and moved.object is not None
    before, after = problem.object.placement, moved.object.placement
    np.testing.assert_allclose(after.translation - before.translation, [0.01, -0.02, 0.0])
    np.testing.assert_allclose(after.rotation[:, 2], before.rotation[:, 2], atol=1e-12)
    angle = math.acos(np.clip(after.rotation[:, 0] @ before.rotation[:, 0], -1, 1))
    assert angle == pytest.approx(0.5)
    assert moved.object.raw["pose"] == pytest.approx(list(moved.object.pose))
    assert problem.object.pose[0] == pytest.approx(0.75)  # the nominal scene is untouched


@pytest.mark.parametrize(
    ("field", "value", "named"),
    [
        ("deltas", (0.0, -0.01), "delta"),
        ("deltas", (0.5,), "delta"),
        ("deltas", (math.nan,), "delta"),
        ("us", (1.5,), "u"),
        ("us", (), "u"),
        ("yaws", (4.0,), "yaw"),
        ("seeds", 0, "seeds"),
        ("planner", "nope", "planner"),
        ("friction", -1.0, "friction"),
        ("friction", "x", "friction"),
        ("us", "abc", "u"),
        ("us", 0.3, "u"),
        ("open_arrival", "no", "open_arrival"),  # a non-empty string is truthy
    ],
)
def test_bad_options_raise_config_error(field: str, value: object, named: str) -> None:
    """Negative, absurd or non-finite errors and other bad settings raise ConfigError
    naming the setting."""
    with pytest.raises(ConfigError, match=named):
        RobustnessOptions(**{field: value})  # type: ignore[arg-type]


def test_scene_without_object_is_refused(tmp_path: Path, empty_scene_text: str) -> None:
    """A scene with nothing to grasp raises InvalidProblem before any run starts; the
    command line prints one line and exits 2 (so does a negative error)."""
    scene = tmp_path / "empty.toml"
    scene.write_text(empty_scene_text)
    with pytest.raises(InvalidProblem, match="object"):
        run_robustness(scene, SMALL, tmp_path / "out", quiet=True)
    assert not (tmp_path / "out" / "shards").exists()
    result = run_cli("robustness", "--scene", str(scene), cwd=tmp_path)
    assert_one_error_line(result)
    assert result.returncode == 2 and "object" in result.stderr
    result = run_cli("robustness", "--delta", "0", "-0.01", cwd=tmp_path)
    assert_one_error_line(result)
    assert result.returncode == 2 and "delta" in result.stderr


def test_tables_say_when_they_pool_several_yaws():
    """With more than one yaw swept, both tables say the yaws are pooled (the CSV keeps
    them apart); with one, they say nothing of it."""
    from openup_ompl.robustness_report import markdown_tables

    row = {"u": 0.3, "dx": 0.01, "dy": 0.0, "trials": 1, "successes": 1}
    one = markdown_tables([{**row, "yaw": 0.0}])
    two = markdown_tables([{**row, "yaw": 0.0}, {**row, "yaw": 0.1, "successes": 0}])
    assert "yaws" not in one
    assert two.count("yaws 0, 0.1 rad pooled") == 2 and "| 0.3 | 1/2 |" in two
