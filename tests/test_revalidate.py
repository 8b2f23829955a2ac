"""Re-validation of a plan against its scene before ``execute`` and ``show`` use it
(issue 37): a tampered or stale plan is refused in one line naming its first bad state."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import openup_ompl as ou
from openup_ompl.cli import main
from openup_ompl.exceptions import ConfigError, PlanRejected
from openup_ompl.plan import PlanFile
from openup_ompl.revalidate import revalidate_plan

SCENE = ou.default_scene_path()  # the Panda's can past a wall


@pytest.fixture(scope="module")
def plan() -> ou.Plan:
    """A plan of the Panda's can scene (seed 1)."""
    return ou.GraspPlanningSetup(ou.load_scene(SCENE)).solve(seed=1)


@pytest.fixture()
def plan_file(plan: ou.Plan, tmp_path: Path) -> Path:
    """That plan, saved."""
    return plan.save(tmp_path / "plan.json")


def _tampered(plan_file: Path) -> tuple[Path, int]:
    """The plan with 20 consecutive path states' arm jumped elsewhere (shoulder to 1.5 rad,
    elbow to -0.3 rad), as issue 37's hostile input; and the first of those rows."""
    data = json.loads(plan_file.read_text())
    names, arm = data["robot"]["joint_names"], data["robot"]["arm_joints"]
    first = len(data["path"]) // 3
    for row in data["path"][first : first + 20]:
        row[names.index(arm[1])], row[names.index(arm[3])] = 1.5, -0.3
    path = plan_file.with_name("tampered.json")
    path.write_text(json.dumps(data))
    return path, first


def _one_line(capsys: pytest.CaptureFixture[str]) -> str:
    """The one line the command printed on stderr."""
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def test_a_plan_revalidates_from_memory_and_from_its_file(plan: ou.Plan, plan_file: Path):
    """A fresh plan passes, in memory and read back, every row and motion checked at the
    planner's recorded resolution, no step beyond it."""
    for source in (plan, PlanFile.read(plan_file)):
        checked = revalidate_plan(source)
        assert checked.states == plan.path.shape[0] == checked.motions + 1
        assert checked.resolution == plan.stats["resolution"]
        assert 0 < checked.largest_step <= checked.resolution * (1 + 1e-6)


@pytest.mark.parametrize("command", ["execute", "show"])
def test_a_tampered_plan_is_refused_in_one_line(plan_file, tmp_path, capsys, command):
    """``execute`` and ``show`` refuse the tampered plan (exit 2) in one line naming its
    first jumped row, and write nothing."""
    tampered, first = _tampered(plan_file)
    out = tmp_path / "out"
    assert main([command, str(tampered), "--out", str(out)]) == 2
    line = _one_line(capsys)
    assert f"tampered.json: path[{first}]: a robot point may move" in line
    assert not out.exists() or not any(out.iterdir())


def test_no_validate_hands_the_tampered_plan_over(plan_file, monkeypatch):
    """``--no-validate`` skips the re-validation: the tampered plan reaches execution."""
    import openup_ompl.physics

    reached = []

    def fake_execute(plan: Any, *args: Any, **kwargs: Any) -> None:
        reached.append(plan)
        raise KeyboardInterrupt  # stops the command once the plan got here

    monkeypatch.setattr(openup_ompl.physics, "execute_plan", fake_execute)
    tampered, _ = _tampered(plan_file)
    assert main(["execute", str(tampered), "--no-validate"]) == 130
    assert len(reached) == 1


def test_a_valid_plan_executes_exactly_as_before(plan_file, tmp_path):
    """A valid plan passes and runs as the unchecked call runs it: the same record."""
    from openup_ompl.physics import execute_plan

    assert main(["execute", str(plan_file), "--out", str(tmp_path / "cli"), "--seed", "3"]) == 0
    written = json.loads((tmp_path / "cli" / "execution.json").read_text())
    direct = execute_plan(plan_file, seed=3).to_dict()
    assert json.loads(json.dumps(direct)) == written


def test_a_stale_plan_whose_scene_gained_an_obstacle_is_refused(plan_file):
    """A box put across the path's middle in the plan's scene: refused at the first
    motion into it, in path order."""
    data = json.loads(plan_file.read_text())
    plan = PlanFile.from_dict(data)
    middle = len(plan.path) // 2
    q = plan.path[middle]
    robot = ou.load_robot("panda")
    palm = robot.palm_placement(robot.model.createData(), q).translation
    box = {"name": "new_box", "shape": "box", "size": [0.04] * 3, "pose": [*palm, 0, 0, 0, 1]}
    data["scene"]["obstacles"].append(box)
    with pytest.raises(PlanRejected, match="collides") as refused:
        revalidate_plan(PlanFile.from_dict(data), where="plan.json: ")
    assert 0 < refused.value.row <= middle
    assert refused.value.where == f"plan.json: path[{refused.value.row}]"


def test_a_joint_beyond_its_limit_or_a_hand_off_the_law_is_named(plan: ou.Plan):
    """A plan in memory with one row's elbow beyond its limit, or one row's hand moved, is
    refused at that row, naming the joint or the hand's error."""
    robot = plan.problem.robot
    row = len(plan.path) // 2
    beyond = plan.path.copy()
    elbow = robot.arm_idx[3]
    beyond[row, elbow] = robot.model.upperPositionLimit[elbow] + 0.1
    with pytest.raises(PlanRejected, match=robot.joint_names[elbow]) as refused:
        revalidate_plan(dataclasses.replace(plan, path=beyond))
    assert refused.value.row == row
    off_law = plan.path.copy()
    off_law[row + 1, robot.hand_idx] -= 0.001
    with pytest.raises(PlanRejected, match="from the law's") as refused:
        revalidate_plan(dataclasses.replace(plan, path=off_law))
    assert refused.value.row == row + 1


def test_a_plan_of_an_unknown_robot_is_refused_naming_it(plan_file):
    """A plan whose robot this installation cannot load is a ConfigError naming
    robot.name, not a traceback."""
    data = json.loads(plan_file.read_text())
    data["robot"]["name"], data["robot"]["file"] = "no_such_robot", "/nowhere/robot.toml"
    with pytest.raises(ConfigError, match="robot.name"):
        revalidate_plan(PlanFile.from_dict(data))


def test_a_bad_recorded_resolution_is_a_config_error(plan_file):
    """A plan whose stats hold a resolution that is not a length is refused naming it."""
    data = json.loads(plan_file.read_text())
    data["stats"]["resolution"] = "fine"
    with pytest.raises(ConfigError, match="stats.resolution"):
        revalidate_plan(PlanFile.from_dict(data))
    assert np.isfinite(json.loads(plan_file.read_text())["stats"]["resolution"])
