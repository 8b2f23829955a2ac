"""Bad input on the command line: exit status 2, one stderr line naming the bad value, no
traceback; and the outcomes that are not errors (an unseen object, seed 0) say so plainly.

Each test fails before any long planning: tiny sweeps, or errors raised before planning.
"""

from __future__ import annotations

import csv
import importlib.util
import json
import subprocess
from pathlib import Path

import pytest
from test_cli import assert_one_error_line, run_cli

import openup_ompl as ou
from openup_ompl.benchmark import summarize
from openup_ompl.exceptions import ConfigError
from openup_ompl.robustness import RobustnessOptions

pytestmark = pytest.mark.slow  # subprocesses

SCENE = str(ou.default_scene_path())
PANDA_SRDF = 'srdf = "example-robot-data://panda_description/srdf/panda.srdf"'
PANDA_URDF = 'urdf = "example-robot-data://panda_description/urdf/panda.urdf"'


def assert_bad_input(result: subprocess.CompletedProcess[str], *named: str) -> None:
    """Exit status 2, exactly one stderr line, no traceback, every ``named`` text in it."""
    assert result.returncode == 2, (result.stdout, result.stderr)
    assert_one_error_line(result)
    for text in named:
        assert text in result.stderr, result.stderr


@pytest.fixture
def robot_with(tmp_path, panda_toml):
    """A copy of the Panda's robot file whose SRDF (or URDF) line is replaced, and a copy
    of the default scene that uses it."""

    def write(old: str, new: str, name: str, text: str) -> tuple[Path, Path]:
        (tmp_path / name).write_text(text)
        robot = tmp_path / "robot.toml"
        robot.write_text(panda_toml.replace(old, new.format(name=name)))
        scene = tmp_path / "scene.toml"
        scene.write_text(Path(SCENE).read_text().replace('robot = "panda"', 'robot = "robot.toml"'))
        return robot, scene

    return write


MALFORMED = {
    "garbage": '<robot name="x"><disable_collisions link1=',
    "empty": "",
    "not xml": "not xml at all {",
    "wrong root": "<foo/>",
    "no link2": '<robot name="x"><disable_collisions link1="panda_link1"/></robot>',
}


@pytest.mark.parametrize("text", MALFORMED.values(), ids=MALFORMED.keys())
@pytest.mark.parametrize("command", ["plan", "law"])
def test_malformed_srdf_is_one_error_line(tmp_path, robot_with, command, text):
    """A malformed SRDF, in ``plan`` or ``law --robot``, names the robot file and the SRDF."""
    robot, scene = robot_with(PANDA_SRDF, 'srdf = "{name}"', "bad.srdf", text)
    args = ["plan", str(scene)] if command == "plan" else ["law", "--robot", str(robot)]
    result = run_cli(*args, "--out", str(tmp_path / "out.png"), cwd=tmp_path)
    assert_bad_input(result, "robot.toml: srdf", "bad.srdf")


def test_srdf_with_a_wrong_extension_is_one_error_line(tmp_path, robot_with):
    """An SRDF path not ending in .srdf (pinocchio reads no other) is refused by name."""
    robot, _ = robot_with(PANDA_SRDF, 'srdf = "{name}"', "pairs.xml", '<robot name="x"/>')
    result = run_cli("law", "--robot", str(robot), "--out", "law.png", cwd=tmp_path)
    assert_bad_input(result, "robot.toml: srdf", "pairs.xml", ".srdf")


@pytest.mark.parametrize("text", ["", '<robot name="x"><link name='], ids=["empty", "garbage"])
def test_broken_urdf_prints_no_urdfdom_lines(tmp_path, robot_with, text):
    """A URDF that is not XML is refused before urdfdom parses it: one line, ours."""
    robot, _ = robot_with(PANDA_URDF, 'urdf = "{name}"', "bad.urdf", text)
    result = run_cli("law", "--robot", str(robot), "--out", "law.png", cwd=tmp_path)
    assert_bad_input(result, "robot.toml: urdf", "bad.urdf")


def test_invalid_urdf_is_one_line_with_urdfdom_reasons(tmp_path, robot_with):
    """A URDF that is XML but not a valid URDF (a revolute joint without limits): urdfdom's
    own lines on stderr are folded into the one error line, reasons kept."""
    text = (
        '<robot name="x"><link name="a"/><link name="b"/><joint name="j" type="revolute">'
        '<parent link="a"/><child link="b"/></joint></robot>'
    )
    robot, _ = robot_with(PANDA_URDF, 'urdf = "{name}"', "bad.urdf", text)
    result = run_cli("law", "--robot", str(robot), "--out", "law.png", cwd=tmp_path)
    assert_bad_input(result, "robot.toml: urdf", "bad.urdf", "does not specify limits")
    assert "at line" not in result.stderr  # urdfdom's source-line trailers are left out


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["plan", "binary.toml"], "scene file"),
        (["law", "--scene", "binary.toml"], "scene file"),
        (["law", "--robot", "binary.toml"], "robot file"),
        (["show", "binary.json"], "plan file"),
    ],
    ids=["plan", "law --scene", "law --robot", "show"],
)
def test_a_file_that_is_not_text_is_one_line(tmp_path, args, named):
    """A scene, robot or plan file that is not UTF-8 text is refused like a malformed one,
    not with a UnicodeDecodeError traceback."""
    for name in ("binary.toml", "binary.json"):
        (tmp_path / name).write_bytes(bytes(range(256)))
    assert_bad_input(run_cli(*args, cwd=tmp_path), named, "binary.")


@pytest.mark.parametrize(
    "args",
    [
        ["execute", "plan.json"],
        ["show", "plan.json"],
        ["perceive", SCENE],
        ["closed-loop", "--trials", "1"],
    ],
    ids=["execute", "show", "perceive", "closed-loop"],
)
def test_an_output_directory_that_is_a_file_is_refused_first(tmp_path, args):
    """--out naming an existing file is refused before any work, naming --out (it was an
    OSError after the rollout, the fit or the whole sweep)."""
    (tmp_path / "afile").write_text("")
    assert_bad_input(run_cli(*args, "--out", "afile", cwd=tmp_path), "--out", "afile")


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux's /proc")
@pytest.mark.parametrize(
    "args",
    [
        ["plan", SCENE],
        ["demo"],
        ["execute", "plan.json"],
        ["perceive", SCENE],
        ["closed-loop", "--trials", "1"],
    ],
    ids=["plan", "demo", "execute", "perceive", "closed-loop"],
)
def test_an_output_path_that_cannot_be_written_is_refused_first(tmp_path, args):
    """--out in a directory that takes no file (/proc, even for root) is refused before
    any work, naming --out (``plan`` planned, then failed on its temporary file)."""
    result = run_cli(*args, "--out", "/proc/openup-out", cwd=tmp_path)
    assert_bad_input(result, "--out", "/proc/openup-out", "writable directory")
    assert "solution" not in result.stdout


def test_an_empty_output_path_is_refused(tmp_path):
    """``--out ''`` is refused as it was given, not as the current directory '.'."""
    result = run_cli("plan", SCENE, "--out", "", cwd=tmp_path)
    assert_bad_input(result, "--out", "expected a path, got ''")
    assert not list(tmp_path.iterdir())


def test_law_refuses_an_unsupported_format(tmp_path):
    """``law --out x.txt`` names --out and the formats matplotlib can write."""
    result = run_cli("law", "--out", "x.txt", cwd=tmp_path)
    assert_bad_input(result, "--out", "x.txt", ".png", ".pdf", ".svg")
    assert not list(tmp_path.iterdir())


def test_law_refuses_a_directory(tmp_path):
    """``law --out DIR`` is refused rather than written beside it as DIR.png."""
    (tmp_path / "adir").mkdir()
    result = run_cli("law", "--out", "adir", cwd=tmp_path)
    assert_bad_input(result, "--out", "adir", "directory")
    assert not (tmp_path / "adir.png").exists()


def test_law_reports_the_file_it_wrote(tmp_path):
    """A name without a suffix is written as NAME.png, and that is the path printed."""
    result = run_cli("law", "--out", "figure", "--u", "0.3", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().endswith("figure.png")
    assert (tmp_path / "figure.png").is_file()


@pytest.mark.skipif(
    importlib.util.find_spec("distributed") is None, reason="the distributed extra is missing"
)
@pytest.mark.parametrize("command", ["robustness", "benchmark"])
def test_bad_scheduler_address_names_the_option(tmp_path, command):
    """A scheduler address with a port that is not a number names --scheduler."""
    result = run_cli(command, "--scheduler", "foo:bar", "--out", "out", cwd=tmp_path)
    assert_bad_input(result, "--scheduler", "foo:bar")
    assert not (tmp_path / "out").exists()


def test_benchmark_with_no_problem_set_up_says_so(tmp_path, default_scene_text):
    """A suite whose only problem cannot be set up (grasp out of reach) names it and why,
    instead of failing on an empty database."""
    scene = tmp_path / "far.toml"
    scene.write_text(
        default_scene_text.replace("pose = [0.6, 0.0, 0.19, 1.0", "pose = [5.6, 0.0, 0.19, 1.0")
    )
    result = run_cli(
        "benchmark", "--problems", str(scene), "--runs", "1", "--time", "0.5",
        "--planners", "ikbirrt", "--out", "bench", "--quiet", cwd=tmp_path,
    )  # fmt: skip
    assert_bad_input(result, "no problem could be set up", "panda.far", "out of reach")


def test_benchmark_refuses_a_bad_scene_before_any_run(tmp_path):
    """A scene among the problems that does not load is one line naming its file and key,
    before any run (it was one failed task per run, reported after their retries)."""
    (tmp_path / "bad.toml").write_text('robot = "panda"\nstart = [0, 0, 0, 0, 0, 0]\n')
    result = run_cli(
        "benchmark", "--problems", SCENE, "bad.toml", "--runs", "2", "--out", "b", cwd=tmp_path
    )
    assert_bad_input(result, "bad.toml: start", "7 finite numbers")
    assert "failed" not in result.stderr
    assert not (tmp_path / "b" / "shards").exists()


def test_benchmark_planner_names_are_checked_like_plans(tmp_path):
    """``benchmark --planners`` goes through the same check as ``plan --planner``: any
    case accepted, a refused planner named with why, before any run."""
    result = run_cli(
        "benchmark", "--planners", "RRTConnect", "prm", "--problems", SCENE, "--out", "b",
        cwd=tmp_path,
    )  # fmt: skip
    assert_bad_input(result, "planner", "'prm'", "deadlocks")
    assert not (tmp_path / "b" / "shards").exists()


def test_summary_rows_of_unsolved_runs_are_valid_json():
    """A cell with no solved run has no mean length: ``None`` (JSON null), never NaN."""
    record = {"problem": "panda.x", "planner": "rrt", "hand": "law", "time": 0.5, "solved": False}
    rows = summarize([record])
    assert rows[0]["length"] is None
    json.dumps({"rows": rows}, allow_nan=False)


SEED_ARGS = {
    "last robustness seed past 2^31": (
        ["robustness", "--seed", "2147483647", "--seeds", "2"],
        ["seed + seeds - 1", "2147483648"],
    ),
    "huge --seeds": (["robustness", "--seeds", "100000000000"], ["seeds", "100000000000"]),
    "zero --seeds": (["robustness", "--seeds", "0"], ["--seeds", "'0'"]),
    "huge --trials": (["closed-loop", "--trials", "20000"], ["trials", "20000"]),
    "last closed-loop seed past 2^31": (
        ["closed-loop", "--seed", "2147483000", "--trials", "1000"],
        ["seed + trials - 1", "2147483999"],
    ),
    "negative --runs": (["benchmark", "--runs", "-3"], ["--runs", "'-3'"]),
    "huge --runs": (["benchmark", "--runs", "99999999999"], ["runs", "99999999999"]),
    "last benchmark seed past 2^31": (
        ["benchmark", "--seed", "2147483647", "--runs", "2"],
        ["seed + runs - 1", "2147483648"],
    ),
}


@pytest.mark.parametrize(("args", "named"), SEED_ARGS.values(), ids=SEED_ARGS.keys())
def test_seed_counts_name_the_option_at_fault(tmp_path, args, named):
    """--seeds, --trials and --runs are positive and bounded; the sum with --seed is named
    as a sum, with its value."""
    result = run_cli(*args, "--out", "out", cwd=tmp_path)
    assert_bad_input(result, *named)


@pytest.mark.parametrize("command", ["plan", "benchmark", "robustness", "closed-loop"])
def test_time_limit_is_bounded(tmp_path, command):
    """--time above planning.TIME_LIMIT_MAX (where OMPL's clock overflows) is refused by
    the parser of every command that plans, before any run."""
    args = [command, SCENE] if command == "plan" else [command]
    result = run_cli(*args, "--time", "1e7", "--out", "out", cwd=tmp_path)
    assert_bad_input(result, "--time", "'1e7'", "1e+06")


def test_the_largest_seed_is_accepted():
    """Seed 2^31 - 1 with one plan is in range (the last seed is the first)."""
    options = RobustnessOptions(first_seed=2**31 - 1, seeds=1)
    assert options.first_seed == 2**31 - 1
    with pytest.raises(ConfigError, match="seed \\+ seeds - 1"):
        RobustnessOptions(first_seed=2**31 - 1, seeds=2)


def test_unseen_object_is_counted_as_not_seen(tmp_path):
    """A camera below the table never sees the object: the trials are "not seen" (not
    planning failures), a fixed policy keeps its u, and stderr stays clean."""
    result = run_cli(
        "closed-loop", "--camera", "elevation=-80", "--trials", "1", "--noise", "1",
        "--distance", "0.6", "--policies", "0.3", "covariance", "--out", "loop", "--quiet",
        cwd=tmp_path,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    assert "nan" not in result.stdout
    assert "(mean u 0.300, 1 not seen)" in result.stdout
    with (tmp_path / "loop" / "closed_loop.csv").open(newline="") as handle:
        rows = {row["policy"]: row for row in csv.DictReader(handle)}
    assert rows["0.3"]["not_seen"] == "1" and rows["0.3"]["planning_failures"] == "0"
    assert rows["0.3"]["mean_u"] == "0.3000" and rows["covariance"]["mean_u"] == ""
    json.loads(
        (tmp_path / "loop" / "closed_loop_trials.json").read_text(),
        parse_constant=lambda name: pytest.fail(f"{name} in the trials JSON"),
    )


def test_seed_zero_plans_without_an_ompl_warning(tmp_path):
    """Seed 0 is given to OMPL as 1 (what OMPL does itself), without its warning."""
    result = run_cli("plan", SCENE, "--seed", "0", "--out", "plan.json", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    assert json.loads((tmp_path / "plan.json").read_text())["seed"] == 0
