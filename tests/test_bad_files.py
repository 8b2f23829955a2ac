"""Bad plan files and execution files: each is refused with a ConfigError naming the file
and the key, by every reader (``show``, ``execute``, the Python API), and on the command
line with exit status 2 and one line on stderr.

A valid plan is written once (one short solve) and a valid execution once (one rollout);
each case mutates their JSON.
"""

from __future__ import annotations

import copy
import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

import openup_ompl as ou
from openup_ompl.__main__ import main
from openup_ompl.exceptions import ConfigError
from openup_ompl.plan import GRASP_POSITION_TOLERANCE, LIMIT_TOLERANCE, PlanFile, read_plan

Mutation = Callable[[dict[str, Any]], None]


def _set(*keys: str | int, value: Any) -> Mutation:
    """A mutation setting ``data[k0][k1]...`` to ``value``."""

    def mutate(data: dict[str, Any]) -> None:
        for key in keys[:-1]:
            data = data[key]
        data[keys[-1]] = value

    return mutate


def _drop(*keys: str) -> Mutation:
    """A mutation deleting ``data[k0][k1]...``."""

    def mutate(data: dict[str, Any]) -> None:
        for key in keys[:-1]:
            data = data[key]
        del data[keys[-1]]

    return mutate


def _every_row(column: int, value: float) -> Mutation:
    def mutate(data: dict[str, Any]) -> None:
        for row in data["path"]:
            row[column] = value

    return mutate


def _shared_joint(data: dict[str, Any]) -> None:
    data["robot"]["hand_joints"] = [data["robot"]["arm_joints"][0]]


def _ragged_row(data: dict[str, Any]) -> None:
    data["path"][5].pop()


#: Case -> (mutation of a valid plan, the key its error names).
BAD_PLANS: dict[str, tuple[Mutation, str]] = {
    "string in a path row": (_set("path", 5, 0, value="x"), "path[5][0]"),
    "ragged path row": (_ragged_row, "path[5]"),
    "NaN in a path row": (_set("path", 5, 0, value=float("nan")), "path[5][0]"),
    "empty path": (_set("path", value=[]), "path"),
    "path not a list": (_set("path", value=None), "path"),
    "joint beyond its limit": (_every_row(0, 5.0), "path[0][0]"),
    "robot a string": (_set("robot", value="panda"), "robot"),
    "missing URDF": (_set("robot", "urdf", value="/no/such.urdf"), "robot.urdf"),
    "bad joint names": (_set("robot", "joint_names", value=["a", "b"]), "robot.joint_names"),
    "unknown arm joint": (_set("robot", "arm_joints", value=["nope"]), "robot.arm_joints"),
    "arm joint in the hand": (_shared_joint, "robot.hand_joints"),
    "unknown palm frame": (_set("robot", "palm_frame", value="nope"), "robot.palm_frame"),
    "package_dirs a string": (_set("robot", "package_dirs", value="x"), "robot.package_dirs"),
    "scene a string": (_set("scene", value="x"), "scene"),
    "scene missing": (_drop("scene"), "scene"),
    "obstacles a string": (_set("scene", "obstacles", value="x"), "scene.obstacles"),
    "negative object radius": (_set("scene", "object", "radius", value=-1), "scene.object.radius"),
    # MuJoCo's compiler refused the repeated body name with a traceback (exit 1).
    "obstacle named like the object": (
        lambda data: data["scene"]["obstacles"].append(
            {**data["scene"]["obstacles"][0], "name": data["scene"]["object"]["name"]}
        ),
        "scene: obstacle name",
    ),
    "law u NaN": (_set("hand_law", "u", value=float("nan")), "hand_law.u"),
    "law mga 0": (_set("hand_law", "mga", value=0.0), "hand_law.mga"),
    "law missing": (_drop("hand_law"), "hand_law"),
    "negative start distance": (
        _set("hand_law", "start_palm_distance", value=-1.0),
        "hand_law.start_palm_distance",
    ),
    "grasp pose NaN": (_set("grasp_pose", value=[float("nan")] * 7), "grasp_pose"),
    "grasp pose short": (_set("grasp_pose", value=[0.0] * 3), "grasp_pose"),
    "seed a string": (_set("seed", value="x"), "seed"),
    "start short": (_set("start", value=[0.0]), "start"),
    # A path that does not leave from its start or does not end at its grasp pose.
    "path reversed": (lambda data: data["path"].reverse(), "path[0]"),
    "path cut short": (lambda data: data.__setitem__("path", data["path"][:3]), "path[2]"),
    "start elsewhere": (_set("start", value=[0.0] * 7), "path[0]"),
}

#: Case -> (mutation of a valid execution file, the key its error names).
BAD_EXECUTIONS: dict[str, tuple[Mutation, str]] = {
    "period 0": (_set("frames", "period_s", value=0), "frames.period_s"),
    "period negative": (_set("frames", "period_s", value=-1.0), "frames.period_s"),
    "period NaN": (_set("frames", "period_s", value=float("nan")), "frames.period_s"),
    "verdict missing": (_drop("verdict"), "verdict"),
    "steps missing": (_drop("steps"), "steps"),
    "frames a string": (_set("frames", value="x"), "frames"),
    "lift a string": (_set("lift", value="x"), "lift"),
    "q empty": (_set("frames", "q", value=[]), "frames.q"),
    "q ragged": (_set("frames", "q", 3, value=[0.0]), "frames.q[3]"),
    "q NaN": (_set("frames", "q", 3, 0, value=float("nan")), "frames.q[3][0]"),
    "q holds a string": (_set("frames", "q", 3, 0, value="x"), "frames.q[3][0]"),
    "object empty": (_set("frames", "object", value=[]), "frames.object"),
    "object short": (_set("frames", "object", value=[[0, 0, 0, 0, 0, 0, 1]] * 3), "frames.object"),
    "object not a unit quaternion": (
        _set("frames", "object", 0, value=[0.0] * 7),
        "frames.object[0]",
    ),
    "unknown phase": (_set("frames", "phase", 0, value="zzz"), "frames.phase[0]"),
    "offset a string": (_set("offset", "dx", value="x"), "offset.dx"),
    "first contact in no phase": (
        _set("first_contact", value={"link": "l", "time_s": 0.1, "d": 0.5, "phase": "zzz"}),
        "first_contact.phase",
    ),
}

#: Faults found when the viewer loads the executed plan (``source``).
BAD_SOURCES: dict[str, tuple[Mutation, str]] = {
    "source a string": (_set("source", value="x"), "source"),
    "source missing": (_drop("source"), "source"),
    "source URDF missing": (_set("source", "robot", "urdf", value="/no.urdf"), "source.robot.urdf"),
    "source path beyond a limit": (_set("source", "path", 0, 0, value=5.0), "source.path[0][0]"),
    "frames of other joints": (
        lambda data: data["frames"]["joint_names"].reverse(),
        "frames.joint_names",
    ),
}


@pytest.fixture(scope="module")
def plan_data(tmp_path_factory) -> dict[str, Any]:
    """A valid plan file's contents: the Panda demo scene planned once (seed 1)."""
    setup = ou.GraspPlanningSetup(ou.load_scene(ou.default_scene_path()))
    plan = setup.solve(time_limit=5.0, planner="ikbirrt", seed=1)
    path = plan.save(tmp_path_factory.mktemp("plan") / "plan.json")
    return json.loads(path.read_text())


@pytest.fixture(scope="module")
def execution_data(plan_data, tmp_path_factory) -> dict[str, Any]:
    """A valid execution file's contents: the plan executed once, with its frames."""
    pytest.importorskip("mujoco")
    from openup_ompl.physics import execute_plan, write_execution

    record = execute_plan(plan_data)
    path = write_execution(record, tmp_path_factory.mktemp("execution"))
    return json.loads(path.read_text())


def _write(tmp_path: Path, data: dict[str, Any], mutate: Mutation | None = None) -> Path:
    data = copy.deepcopy(data)
    if mutate is not None:
        mutate(data)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    return path


def _cli_error(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    """Run the command line in this process; assert exit status 2 and one stderr line."""
    assert main(list(args)) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def _execute(path: Path) -> None:
    from openup_ompl.physics import execute_plan

    execute_plan(path)


@pytest.mark.parametrize("reader", [PlanFile.read, read_plan, _execute])
@pytest.mark.parametrize("case", BAD_PLANS)
def test_bad_plan_is_refused_naming_file_and_key(plan_data, tmp_path, case, reader):
    """Every reader (show's, read_plan, execute's) refuses the file with a ConfigError
    located at ``bad.json: <key>``."""
    mutate, key = BAD_PLANS[case]
    with pytest.raises(ConfigError) as caught:
        reader(_write(tmp_path, plan_data, mutate))
    assert caught.value.where == f"bad.json: {key}"


@pytest.mark.parametrize("command", ["show", "execute"])
@pytest.mark.parametrize("case", BAD_PLANS)
def test_bad_plan_exits_2_with_one_line(plan_data, tmp_path, capsys, case, command):
    """``show`` and ``execute`` exit 2 with one line naming the key, writing nothing."""
    mutate, key = BAD_PLANS[case]
    path = _write(tmp_path, plan_data, mutate)
    line = _cli_error(capsys, command, str(path), "--out", str(tmp_path / "out"))
    assert f"bad.json: {key}: got " in line
    assert not (tmp_path / "out").exists()


def test_plan_naming_an_invalid_urdf_is_one_line(plan_data, tmp_path, capfd):
    """A plan whose URDF urdfdom refuses (a revolute joint without limits): one line, with
    urdfdom's reason in it, and none of urdfdom's own lines on file descriptor 2."""
    urdf = tmp_path / "bad.urdf"
    urdf.write_text(
        '<robot name="x"><link name="a"/><link name="b"/><joint name="j" type="revolute">'
        '<parent link="a"/><child link="b"/></joint></robot>'
    )
    path = _write(tmp_path, plan_data, _set("robot", "urdf", value=str(urdf)))
    assert main(["show", str(path), "--out", str(tmp_path / "out")]) == 2
    lines = capfd.readouterr().err.splitlines()
    assert len(lines) == 1, lines
    assert "bad.json: robot.urdf" in lines[0] and "does not specify limits" in lines[0]


def test_plan_contents_are_checked_by_the_rollout(plan_data):
    """A plan's contents given to the physics rollout get the same check."""
    from openup_ompl.physics import Rollout

    data = copy.deepcopy(plan_data)
    _every_row(0, 5.0)(data)
    with pytest.raises(ConfigError, match="panda_joint1 within its limits") as caught:
        Rollout(data)
    assert caught.value.where == "plan path[0][0]"


def test_deeply_nested_plan_file_is_a_config_error(tmp_path):
    """JSON nested past Python's recursion limit is refused like malformed JSON (it was a
    RecursionError)."""
    path = tmp_path / "deep.json"
    path.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(ConfigError, match="deep.json"):
        read_plan(path)


def test_valid_plan_loads(plan_data, tmp_path):
    """The plan as written loads, through every reader, with its path as written."""
    path = _write(tmp_path, plan_data)
    plan = PlanFile.read(path)
    assert plan.path.tolist() == plan_data["path"]
    assert read_plan(path) == plan_data


def test_row_at_a_limit_within_the_tolerance_loads(plan_data, tmp_path):
    """A joint value beyond its limit by less than LIMIT_TOLERANCE is accepted (rounding)."""
    upper = float(PlanFile.read(_write(tmp_path, plan_data)).model.upperPositionLimit[0])
    beyond = upper + LIMIT_TOLERANCE / 2
    plan = PlanFile.read(_write(tmp_path, plan_data, _set("path", 5, 0, value=beyond)))
    assert plan.path[5, 0] == beyond


@pytest.mark.parametrize(
    ("shift", "refused"), [(0.5 * GRASP_POSITION_TOLERANCE, False), (0.05, True)]
)
def test_plan_must_end_at_its_grasp_pose(plan_data, tmp_path, shift, refused):
    """A grasp pose moved away from the path's last row (by more than
    GRASP_POSITION_TOLERANCE) is refused, naming the last row and the distance; within it,
    the plan loads."""
    data = copy.deepcopy(plan_data)
    data["grasp_pose"][2] += shift
    path = _write(tmp_path, data)
    if not refused:
        assert PlanFile.read(path).grasp_pose[2] == data["grasp_pose"][2]
        return
    last = len(data["path"]) - 1
    with pytest.raises(ConfigError, match=rf"path\[{last}\]: got 'the palm 50.0 mm and 0.000 rad"):
        PlanFile.read(path)


@pytest.mark.parametrize("case", BAD_EXECUTIONS)
def test_bad_execution_is_refused_naming_file_and_key(execution_data, tmp_path, case):
    """read_execution refuses the file with a ConfigError located at ``bad.json: <key>``."""
    from openup_ompl.physics import read_execution

    mutate, key = BAD_EXECUTIONS[case]
    with pytest.raises(ConfigError) as caught:
        read_execution(_write(tmp_path, execution_data, mutate))
    assert caught.value.where == f"bad.json: {key}"


@pytest.mark.parametrize("case", {**BAD_EXECUTIONS, **BAD_SOURCES})
def test_bad_execution_show_exits_2_with_one_line(execution_data, tmp_path, capsys, case):
    """``show EXECUTION.json`` exits 2 with one line naming the key, writing nothing."""
    pytest.importorskip("matplotlib")
    pytest.importorskip("meshcat")
    mutate, key = {**BAD_EXECUTIONS, **BAD_SOURCES}[case]
    path = _write(tmp_path, execution_data, mutate)
    line = _cli_error(capsys, "show", str(path), "--out", str(tmp_path / "out"))
    assert f"bad.json: {key}: got " in line
    assert not (tmp_path / "out").exists()


def test_valid_execution_loads(execution_data, tmp_path):
    """The execution as written loads, its executed plan loads, and its key frames are
    the start and the end of every phase after the settle."""
    from openup_ompl.physics import read_execution
    from openup_ompl.viz.rollout import key_frames

    data = read_execution(_write(tmp_path, execution_data))
    assert data == execution_data
    plan = PlanFile.from_dict(data["source"])
    assert plan.model.nq == len(data["frames"]["joint_names"])
    titles = [title for _, title in key_frames(data)]
    assert titles[0] == "start" and titles[-1] == "end of hold"


@pytest.mark.slow
@pytest.mark.parametrize(
    ("command", "case"), [("execute", "joint beyond its limit"), ("show", "period 0")]
)
def test_bad_file_in_a_subprocess_prints_one_line(
    plan_data, execution_data, tmp_path, command, case
):
    """In its own process (no test harness around stderr) the command prints exactly one
    line, no traceback, and exits 2."""
    mutate, key = {**BAD_PLANS, **BAD_EXECUTIONS}[case]
    data = plan_data if command == "execute" else execution_data
    path = _write(tmp_path, data, mutate)
    result = subprocess.run(
        [sys.executable, "-m", "openup_ompl", command, str(path), "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2, result.stdout
    assert result.stderr.splitlines() == [result.stderr.strip()]
    assert f"bad.json: {key}: got " in result.stderr
