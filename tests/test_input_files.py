"""Bad input files and options found by an audit: each is refused with a ConfigError that
names the value and its file (one line and exit status 2 on the command line), never a
crash, a memory blow-up, a numpy warning or a silently wrong result; and every file the
package writes or ships still reads.
"""

from __future__ import annotations

import copy
import dataclasses
import importlib.util
import json
import os
import warnings
from pathlib import Path
from typing import Any

import coal
import numpy as np
import pytest

import openup_ompl as ou
from openup_ompl import _io
from openup_ompl.__main__ import main
from openup_ompl.exceptions import ConfigError
from openup_ompl.perception.camera import CameraOptions, DepthCamera, camera_of_scene
from openup_ompl.physics.record import is_execution, read_execution
from openup_ompl.plan import MIN_START_PALM_DISTANCE, PlanFile, read_plan
from openup_ompl.scene import demo_scene_path

ROOT = Path(__file__).resolve().parents[1]
HAS_DASK = importlib.util.find_spec("distributed") is not None


def _one_error_line(capsys: pytest.CaptureFixture[str]) -> str:
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def _dump(tmp_path: Path, data: dict[str, Any], name: str = "bad.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return path


# -- 1. a plan's hand columns follow its law --------------------------------------------


@pytest.fixture(scope="module")
def lwa3_plan(tmp_path_factory) -> dict[str, Any]:
    """A plan file's contents on the paper's robot (its hand's joints differ from each
    other, unlike the Panda's two fingers), planned once (seed 1)."""
    plan = ou.GraspPlanningSetup(ou.load_scene(demo_scene_path())).solve(time_limit=10, seed=1)
    return json.loads(plan.save(tmp_path_factory.mktemp("plan") / "plan.json").read_text())


def test_plan_with_reordered_hand_joints_is_refused(lwa3_plan, tmp_path, capsys):
    """hand_joints reversed (the law's c/b/w mapped onto other joints) is refused naming a
    row and a hand joint, by the reader and by ``show`` (it was drawn and executed)."""
    data = copy.deepcopy(lwa3_plan)
    data["robot"]["hand_joints"].reverse()
    path = _dump(tmp_path, data)
    with pytest.raises(ConfigError) as caught:
        PlanFile.read(path)
    assert caught.value.where.startswith("bad.json: path[")
    assert any(joint in caught.value.expected for joint in data["robot"]["hand_joints"])
    assert main(["show", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "bad.json: path[" in _one_error_line(capsys)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("row", [0, 1000, -1])
def test_plan_with_a_hand_value_off_its_law_names_the_row_and_joint(lwa3_plan, tmp_path, row):
    """One hand value moved by 0.1 rad is refused, naming that row, column and joint."""
    data = copy.deepcopy(lwa3_plan)
    names, hand = data["robot"]["joint_names"], data["robot"]["hand_joints"]
    column = names.index(hand[1])
    row = row % len(data["path"])
    data["path"][row][column] += 0.1
    with pytest.raises(ConfigError) as caught:
        read_plan(_dump(tmp_path, data))
    assert caught.value.where == f"bad.json: path[{row}][{column}]"
    assert hand[1] in caught.value.expected


@pytest.mark.parametrize(
    ("scene", "changes"),
    [
        ("lwa3_sdh_can", {"fixed_hand": "w"}),
        ("lwa3_sdh_can", {"open_arrival": True}),
        ("lwa3_sdh_can", {"continuous": True, "u": 1.0}),
        ("lwa3_sdh_can", {"distance": "weighted"}),
        ("lwa3_sdh_can", {"planner": "rrtconnect", "simplify": True}),
        ("ur5_allegro_can", {}),
        ("panda_can", {"u": 0.0}),
    ],
    ids=["fixed", "open_arrival", "continuous", "weighted", "rrtconnect", "allegro", "panda"],
)
def test_every_plan_the_package_writes_reads_back(tmp_path, scene, changes):
    """Plans of every law variant and fixed hand, by ikbirrt and rrtconnect (a review
    read back plans of rrt, rrtstar, bitstar and kpiece1 too), read back through the hand
    check, with and without their start_palm_distance (then the palm's at path[0])."""
    problem = ou.load_scene(ROOT / "scenes" / f"{scene}.toml")
    changes = dict(changes)
    if "distance" in changes:
        law = problem.hand_law.with_options(distance=changes.pop("distance"))
        problem = dataclasses.replace(problem, hand_law=law)
    planner = changes.pop("planner", "ikbirrt")
    simplify = changes.pop("simplify", False)
    setup = ou.GraspPlanningSetup(problem, **changes)
    plan = setup.solve(time_limit=10, planner=planner, seed=2, simplify=simplify)
    path = plan.save(tmp_path / "plan.json")
    np.testing.assert_array_equal(PlanFile.read(path).path, plan.path)
    data = json.loads(path.read_text())
    del data["hand_law"]["start_palm_distance"]
    np.testing.assert_array_equal(PlanFile.read(_dump(tmp_path, data)).path, plan.path)


def test_start_palm_distance_under_the_planners_floor_is_refused(lwa3_plan, tmp_path):
    """A start_palm_distance of 0 (the law's d divides by it) is refused, naming it."""
    data = copy.deepcopy(lwa3_plan)
    data["hand_law"]["start_palm_distance"] = 0.0
    with pytest.raises(ConfigError, match=f">= {MIN_START_PALM_DISTANCE}") as caught:
        read_plan(_dump(tmp_path, data))
    assert caught.value.where == "bad.json: hand_law.start_palm_distance"


# -- 2. files that are not regular, or too large -----------------------------------------


def _load_scene(path: Path) -> Any:
    return ou.load_scene(path)


READERS = {
    "scene": (_load_scene, "scene file"),
    "plan": (read_plan, "plan file"),
    "execution": (read_execution, "execution file"),
}


@pytest.fixture
def special_files(tmp_path) -> dict[str, tuple[Path, str]]:
    """Files no reader should read whole: a device, a directory, a named pipe (opening it
    would wait for a writer) and a sparse file one byte over the cap."""
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    big = tmp_path / "big.json"
    with open(big, "wb") as stream:
        stream.truncate(_io.MAX_FILE_BYTES + 1)
    return {
        "device": (Path("/dev/zero"), "a character device"),
        "directory": (tmp_path, "a directory"),
        "pipe": (fifo, "a named pipe"),
        "too large": (big, f"it holds {_io.MAX_FILE_BYTES + 1:,} bytes"),
    }


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
@pytest.mark.parametrize("kind", ["device", "directory", "pipe", "too large"])
@pytest.mark.parametrize("reader", READERS)
def test_a_file_that_is_not_regular_or_too_large_is_refused_unread(special_files, reader, kind):
    """Every reader refuses it with a ConfigError naming the path and why (``plan
    /dev/zero`` grew to 23 GB before it was killed)."""
    read, what = READERS[reader]
    path, why = special_files[kind]
    with pytest.raises(ConfigError) as caught:
        read(path)
    assert caught.value.where == what
    assert caught.value.value == str(path)
    assert why in caught.value.expected and "256 MiB" in caught.value.expected
    assert not is_execution(path)


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="needs Linux's /proc")
def test_reading_stops_one_byte_past_the_cap(monkeypatch):
    """A regular file whose size the system does not report (/proc: 0 bytes) is read up to
    one byte past the cap, then refused."""
    monkeypatch.setattr(_io, "MAX_FILE_BYTES", 64)
    with pytest.raises(ConfigError, match="it holds 65 bytes or more"):
        _io.read_json("/proc/self/maps", "openup-plan/1", "plan file")


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
@pytest.mark.parametrize("command", ["plan", "show", "execute"])
def test_dev_zero_on_the_command_line_is_one_line(capsys, command):
    """``plan /dev/zero`` (and ``show``, ``execute``) exits 2 with one line naming it."""
    assert main([command, "/dev/zero"]) == 2
    line = _one_error_line(capsys)
    assert line.startswith("openup-ompl: error: ") and "'/dev/zero'" in line


# -- 3. the rollout viewer reads what the execution check lets through ---------------------


@pytest.fixture(scope="module")
def execution_data(tmp_path_factory) -> dict[str, Any]:
    """A valid execution file's contents: the Panda demo plan executed once."""
    pytest.importorskip("mujoco")
    from openup_ompl.physics import execute_plan, write_execution

    plan = ou.GraspPlanningSetup(ou.load_scene(ou.default_scene_path())).solve(seed=1)
    path = write_execution(execute_plan(plan), tmp_path_factory.mktemp("execution"))
    return json.loads(path.read_text())


def test_first_contact_without_d_is_shown(execution_data, tmp_path, capsys):
    """A first contact during the reach without its optional ``d`` is drawn with
    ``d = ?`` (it was a KeyError)."""
    pytest.importorskip("matplotlib")
    pytest.importorskip("meshcat")
    data = copy.deepcopy(execution_data)
    data["first_contact"] = {"link": "panda_hand", "time_s": 1.0, "phase": "reach"}
    path = _dump(tmp_path, data, "execution.json")
    read_execution(path)  # passes the check
    assert main(["show", str(path), "--out", str(tmp_path / "out")]) == 0
    assert (tmp_path / "out" / "execution_storyboard.png").is_file()
    from openup_ompl.viz.rollout import key_frames

    assert any("d = ?" in title for _, title in key_frames(data))


def test_execution_whose_plan_has_no_object_is_refused(execution_data, tmp_path, capsys):
    """``source.scene.object = null`` is refused naming it (it was a StopIteration)."""
    pytest.importorskip("matplotlib")
    pytest.importorskip("meshcat")
    data = copy.deepcopy(execution_data)
    data["source"]["scene"]["object"] = None
    path = _dump(tmp_path, data, "execution.json")
    read_execution(path)  # passes the check
    assert main(["show", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "execution.json: source.scene.object: got None" in _one_error_line(capsys)
    assert not (tmp_path / "out").exists()


# -- 4. scheduler addresses --------------------------------------------------------------


@pytest.mark.skipif(not HAS_DASK, reason="the distributed extra is missing")
def test_scheduler_without_a_port_is_a_config_error(tmp_path):
    """run_tasks with ``bogus`` (Dask takes no default port) is a ConfigError naming the
    address, before any connection (it was Dask's raw ValueError)."""
    from openup_ompl.executor import Task, check_scheduler, run_tasks

    task = Task("t", "openup_ompl.executor:selfcheck_task")
    with pytest.raises(ConfigError, match="missing port") as caught:
        run_tasks([task], tmp_path / "shards", scheduler="bogus", quiet=True)
    assert (caught.value.where, caught.value.value) == ("scheduler", "bogus")
    assert check_scheduler("tcp://127.0.0.1:8786") == "tcp://127.0.0.1:8786"
    for bad in ("", "tcp://host", "zzz://host:1", "tcp://host:0"):
        with pytest.raises(ConfigError):
            check_scheduler(bad)


@pytest.mark.skipif(not HAS_DASK, reason="the distributed extra is missing")
@pytest.mark.parametrize("command", ["robustness", "benchmark"])
def test_scheduler_without_a_port_on_the_command_line_is_one_line(tmp_path, capsys, command):
    """``--scheduler bogus`` exits 2 with one line naming the option and the address."""
    with pytest.raises(SystemExit) as caught:
        main([command, "--scheduler", "bogus", "--out", str(tmp_path / "out")])
    assert caught.value.code == 2
    line = _one_error_line(capsys)
    assert "--scheduler" in line and "'bogus'" in line
    assert not (tmp_path / "out").exists()


# -- 5. a scene's [hand] lists are read as a robot file's ---------------------------------


@pytest.mark.parametrize(
    "value", ["[0.035, nan]", "[[0.035], [0.035]]", "[false, false]", "[0.035, false]"]
)
def test_scene_hand_list_must_be_finite_numbers(write_file, default_scene_text, value):
    """NaN, nested lists and booleans in ``[hand] c`` are refused naming the file and key,
    with the list as written (not a numpy array dump; booleans were read as 0.0)."""
    text = default_scene_text.replace("c = [0.035, 0.035]", f"c = {value}")
    with pytest.raises(ConfigError) as caught:
        ou.load_scene(write_file("scene.toml", text))
    assert caught.value.where == "scene.toml: hand.c"
    assert "array(" not in str(caught.value)
    assert isinstance(caught.value.value, list)


# -- 6. magnitudes that overflowed into numpy warnings ------------------------------------


def test_huge_grasp_quaternion_is_refused_without_a_warning(write_file, default_scene_text):
    """A quaternion component of 1e300 is refused before its norm overflows."""
    text = default_scene_text.replace(
        "pose = [0.6, 0.0, 0.19, 1.0, 0.0, 0.0, 0.0]", "pose = [0.6, 0.0, 0.19, 1e300, 0, 0, 0]"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ConfigError, match="unit quaternion") as caught:
            ou.load_scene(write_file("scene.toml", text))
    assert caught.value.where == "scene.toml: grasp.pose"


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("fx", 1e-300),
        ("fy", 1e300),
        ("cx", 1e308),
        ("cy", -1e308),
        ("position", [1e300, 0.0, 1.0]),
        ("target", [0.0, 0.0, -1e300]),
        ("distance", 1e300),
    ],
)
def test_camera_magnitudes_are_bounded(write_file, default_scene_text, key, value):
    """A scene's [camera] with a focal length, principal point or position that overflowed
    the rays (numpy warnings on stderr) is refused, naming the key."""
    text = default_scene_text.replace("elevation = 60.0", "")
    text += f"{key} = {json.dumps(value)}\n"
    problem = ou.load_scene(write_file("scene.toml", text))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ConfigError) as caught:
            camera_of_scene(problem)
    assert caught.value.where == f"camera.{key}"


def test_camera_at_its_bounds_casts_without_warnings(panda):
    """The extreme intrinsics accepted build their rays without a numpy warning."""
    pytest.importorskip("mujoco")
    problem = ou.load_scene(ou.default_scene_path(), robot=panda)
    options = CameraOptions(width=64, height=48, fx=1e-3, fy=1e9, cx=1e5, cy=-1e5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        camera = DepthCamera(problem, options)
    assert np.all(np.isfinite(camera.rays))


# -- 7. law --u ---------------------------------------------------------------------------


def test_law_refuses_duplicate_u(tmp_path, capsys):
    """``law --u 0 0`` is refused as ``robustness --u 0 0`` is, writing nothing."""
    assert main(["law", "--u", "0", "0", "--out", str(tmp_path / "law.png")]) == 2
    assert (
        _one_error_line(capsys) == "openup-ompl: error: u: got [0.0, 0.0], expected distinct values"
    )
    assert not (tmp_path / "law.png").exists()


# -- 8. an object sunk into an obstacle ----------------------------------------------------


SCENE_FILES = sorted(
    {
        *ROOT.glob("scenes/*.toml"),
        *ROOT.glob("benchmarks/problems/**/*.toml"),
        *ROOT.glob("benchmarks/heldout/**/*.toml"),
        *ROOT.glob("benchmarks/unseen/**/*.toml"),
        *ROOT.glob("benchmarks/robustness/*.toml"),
    }
)


def test_every_shipped_and_benchmark_scene_loads():
    """Every shipped and benchmark scene loads: no object's centre lies inside an
    obstacle."""
    assert len(SCENE_FILES) >= 35
    for path in SCENE_FILES:
        assert ou.load_scene(path).path == path.resolve()


@pytest.mark.parametrize(
    ("pose", "obstacle", "depth"),
    [
        ("[0.6, 0.0, -0.005, 0.0, 0.0, 0.0, 1.0]", "table", "5 mm"),
        ("[0.45, 0.0, 0.11, 0.0, 0.0, 0.0, 1.0]", "wall", "20 mm"),
    ],
    ids=["sunk below the table's top", "inside the wall"],
)
def test_object_centred_in_an_obstacle_is_refused(
    write_file, default_scene_text, pose, obstacle, depth
):
    """A can whose centre is 5 mm below the table's top (or inside the wall) is refused
    naming the object's pose, the obstacle and the depth (it was planned for as
    written)."""
    text = default_scene_text.replace(
        "pose = [0.6, 0.0, 0.06, 0.0, 0.0, 0.0, 1.0]", f"pose = {pose}"
    )
    with pytest.raises(ConfigError) as caught:
        ou.load_scene(write_file("scene.toml", text))
    assert caught.value.where == "scene.toml: object.pose"
    assert repr(obstacle) in caught.value.expected and depth in caught.value.expected


def test_a_perceived_estimate_dipping_into_its_table_plans(tmp_path):
    """``perceive`` then ``plan``: an estimate that sinks the can's base into the table (the
    estimate of the LWA3's can at noise 4, tilted 0.05 rad more about the world's x axis and
    5 mm lower, as a noisier fit may give) loads and plans (a check of any overlap beyond
    2 mm refused it)."""
    import re

    import pinocchio as pin

    from openup_ompl.__main__ import main

    out = tmp_path / "p"
    scene = str(ROOT / "scenes" / "lwa3_sdh_can.toml")
    assert main(["perceive", scene, "--noise", "4", "--seed", "2", "--out", str(out)]) == 0
    perceived = out / "perceived.toml"
    estimate = ou.load_scene(perceived).object
    assert estimate is not None
    placement = pin.XYZQUATToSE3(np.array(estimate.pose, dtype=float))
    placement.rotation = pin.rpy.rpyToMatrix(0.05, 0.0, 0.0) @ placement.rotation
    placement.translation = placement.translation - np.array([0.0, 0.0, 0.005])
    shown = ", ".join(f"{v:.9f}" for v in pin.SE3ToXYZQUAT(placement))
    head, tail = perceived.read_text().split("[object]", 1)
    tail = re.sub(r"^pose = \[[^\]]*\]", f"pose = [{shown}]", tail, count=1, flags=re.M)
    perceived.write_text(head + "[object]" + tail)
    problem = ou.load_scene(perceived)
    assert problem.object is not None
    table = next(shape for shape in problem.obstacles if shape.name == "table")
    placements = [
        coal.Transform3s(shape.placement.rotation, shape.placement.translation)
        for shape in (problem.object, table)
    ]
    gap = coal.distance(
        problem.object.geometry(),
        placements[0],
        table.geometry(),
        placements[1],
        coal.DistanceRequest(),
        coal.DistanceResult(),
    )
    assert gap < -0.002  # a corner of its base dips more than 2 mm into the table
    assert main(["plan", str(perceived), "--out", str(tmp_path / "plan.json")]) == 0
