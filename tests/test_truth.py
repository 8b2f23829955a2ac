"""Executing a perceived plan against the true object (issue 35): ``execute PLAN --truth
SCENE.toml`` and ``execute_plan(plan, truth=scene)``."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

import openup_ompl as ou
from openup_ompl.cli import main
from openup_ompl.exceptions import ConfigError
from openup_ompl.plan import PlanFile
from openup_ompl.truth import with_true_object

ERROR = 0.02  # [m] the estimate's error along world x


@pytest.fixture(scope="module")
def scenes(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The true scene (the Panda's can) and an estimate of it: the can and its grasp pose
    ``ERROR`` further along x, as a perceived.toml would hold them."""
    true = ou.default_scene_path()
    text = true.read_text()
    text = text.replace("pose = [0.6, 0.0, 0.19,", f"pose = [{0.6 + ERROR:g}, 0.0, 0.19,")
    text = text.replace("pose = [0.6, 0.0, 0.06,", f"pose = [{0.6 + ERROR:g}, 0.0, 0.06,")
    estimate = tmp_path_factory.mktemp("perceived") / "perceived.toml"
    estimate.write_text(text)
    return true, estimate


@pytest.fixture(scope="module")
def plan(scenes: tuple[Path, Path]) -> ou.Plan:
    """A plan made for the estimate (seed 1)."""
    return ou.GraspPlanningSetup(ou.load_scene(scenes[1])).solve(seed=1)


def test_the_true_object_replaces_the_plans_and_nothing_else(plan, scenes, tmp_path):
    """In memory and in a plan file, only the object changes (to the true one); the path,
    the law and the obstacles stay the plan's, and the plan itself is unchanged."""
    truth = ou.load_scene(scenes[0])
    assert truth.object is not None and plan.problem.object is not None
    moved = with_true_object(plan, truth)
    assert moved.problem.object is truth.object
    assert plan.problem.object.to_table()["pose"][0] == pytest.approx(0.6 + ERROR)
    assert moved.path is plan.path and moved.problem.obstacles == plan.problem.obstacles
    read = PlanFile.read(plan.save(tmp_path / "plan.json"))
    moved_file = with_true_object(read, truth.object)
    assert moved_file.object is truth.object
    assert moved_file.contents["scene"]["object"] == truth.object.to_table()
    assert read.contents["scene"]["object"]["pose"][0] == pytest.approx(0.6 + ERROR)
    np.testing.assert_array_equal(moved_file.path, read.path)


def test_a_truth_of_another_robot_or_without_an_object_is_refused(plan):
    """The true scene must be of the plan's robot and hold an object."""
    with pytest.raises(ConfigError, match="truth.robot"):
        with_true_object(plan, ou.load_scene(ou.demo_scene_path()))
    empty = ou.load_scene(ou.default_scene_path())
    with pytest.raises(ConfigError, match="truth.object"):
        with_true_object(plan, dataclasses.replace(empty, object=None))


def test_execute_truth_runs_against_the_true_pose(plan, scenes, tmp_path):
    """``execute --truth`` builds its world with the can where it truly is (the record's
    source and first frame say so), as an offset of minus the error does; without it the
    can stands at the estimate."""
    path = plan.save(tmp_path / "plan.json")
    runs = {
        "estimate": [],
        "truth": ["--truth", str(scenes[0])],
        "offset": ["--object-offset", str(-ERROR), "0", "0"],
    }
    records = {}
    for name, extra in runs.items():
        out = tmp_path / name
        assert main(["execute", str(path), "--out", str(out), *extra]) in (0, 1)
        records[name] = json.loads((out / "execution.json").read_text())
    start_x = {name: record["frames"]["object"][0][0] for name, record in records.items()}
    assert start_x["estimate"] == pytest.approx(0.6 + ERROR, abs=2e-3)
    assert start_x["truth"] == pytest.approx(0.6, abs=2e-3)
    assert start_x["offset"] == pytest.approx(0.6, abs=2e-3)
    assert records["truth"]["source"]["scene"]["object"]["pose"][0] == 0.6
    assert records["truth"]["success"] == records["offset"]["success"]
    assert records["truth"]["cause"] == records["offset"]["cause"]


def test_execute_plan_takes_the_truth(plan, scenes, tmp_path):
    """The API: ``execute_plan(plan, truth=scene)`` executes against the true object, the
    plan in memory as its file (the same record)."""
    from openup_ompl.physics import execute_plan

    truth = ou.load_scene(scenes[0])
    assert truth.object is not None
    records = [
        execute_plan(source, truth=truth).to_dict()
        for source in (plan, plan.save(tmp_path / "plan.json"))
    ]
    for record in records:
        assert record["source"]["scene"]["object"] == truth.object.to_table()
    assert json.dumps(records[0]) == json.dumps(records[1])


def test_execute_truth_of_another_robot_is_one_line(plan, tmp_path, capsys):
    """A true scene of another robot exits 2 in one line naming it."""
    path = plan.save(tmp_path / "plan.json")
    assert main(["execute", str(path), "--truth", str(ou.demo_scene_path())]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and "truth.robot" in lines[0]
    assert not (tmp_path / "execution.json").exists()
