"""The command line (CONTRACT §6), run as ``python -m openup_ompl`` in a subprocess."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import openup_ompl as ou

pytestmark = pytest.mark.slow  # subprocesses, sweeps or OMPL benchmark runs

SCENE = str(ou.default_scene_path())


def run_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """Run ``python -m openup_ompl ARGS`` in ``cwd`` and capture its output."""
    return subprocess.run(
        [sys.executable, "-m", "openup_ompl", *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=cwd,
    )


def assert_one_error_line(result: subprocess.CompletedProcess[str]) -> None:
    """Non-zero exit with exactly one non-empty line on stderr, no traceback, no leaks."""
    assert result.returncode != 0, result.stdout
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].strip()
    assert "Traceback" not in result.stderr
    assert "leaked" not in result.stderr


BAD_ARGS = {
    "missing scene": (["plan", "no_such_scene.toml"], "no_such_scene.toml"),
    "u above 1": (["plan", SCENE, "--u", "2"], "--u"),
    "unknown planner": (["plan", SCENE, "--planner", "nope"], "nope"),
    "refused planner says why": (["robustness", "--planner", "prm"], "deadlocks"),
    "negative time": (["plan", SCENE, "--time", "-1"], "--time"),
    "no command": ([], "command"),
}


@pytest.mark.parametrize(("args", "named"), BAD_ARGS.values(), ids=BAD_ARGS.keys())
def test_bad_arguments_exit_with_one_error_line(tmp_path, args, named):
    """Bad arguments exit non-zero with one stderr line naming what is wrong."""
    result = run_cli(*args, cwd=tmp_path)
    assert_one_error_line(result)
    assert named in result.stderr


@pytest.mark.parametrize(
    ("old", "new", "named"),
    [
        ("u = 0.3", "u = ", "broken.toml"),  # a TOML syntax error names the file
        ('robot = "panda"', 'robot = "r2d2"', "r2d2"),  # an unknown robot is named
    ],
)
def test_bad_scene_exits_with_one_error_line(tmp_path, default_scene_text, old, new, named):
    """A malformed scene exits non-zero with one line naming the fault; no plan written."""
    scene = tmp_path / "broken.toml"
    scene.write_text(default_scene_text.replace(old, new))
    result = run_cli("plan", str(scene), "--out", str(tmp_path / "plan.json"), cwd=tmp_path)
    assert_one_error_line(result)
    assert named in result.stderr
    assert not list(tmp_path.glob("*.json"))


@pytest.fixture(scope="module")
def planned(tmp_path_factory) -> tuple[subprocess.CompletedProcess[str], dict]:
    """One `plan` run on the default scene, seed 3, written to a new subdirectory."""
    cwd = tmp_path_factory.mktemp("plan")
    result = run_cli("plan", SCENE, "--seed", "3", "--out", "tmp/plan.json", cwd=cwd)
    assert result.returncode == 0, result.stderr
    return result, json.loads((cwd / "tmp" / "plan.json").read_text())


def test_plan_exits_zero_quietly(planned):
    """`plan` on the default scene exits 0 with nothing on stderr (no nanobind leak notes)."""
    result, _ = planned
    assert result.stderr == ""
    assert "plan written to" in result.stdout


def test_plan_file_has_full_rows_starting_at_the_start(planned, panda):
    """The plan file's rows are full q's (len(joint_names)) and the first row is the start."""
    _, data = planned
    assert data["format"] == "openup-plan/1"
    assert data["seed"] == 3
    names = data["robot"]["joint_names"]
    assert names == panda.joint_names
    path = np.array(data["path"])
    assert path.ndim == 2 and path.shape[0] >= 2 and path.shape[1] == len(names)
    start = ou.load_scene(SCENE, robot=panda).start
    np.testing.assert_allclose(path[0, panda.arm_idx], start, atol=1e-12)


def test_plan_file_hand_follows_the_law_at_the_ends(planned, panda):
    """The hand is the law's plateau at the start (d = 1) and c at the grasp (d ~ 0)."""
    _, data = planned
    path = np.array(data["path"])
    law = ou.load_scene(SCENE, robot=panda).hand_law
    np.testing.assert_allclose(path[0, panda.hand_idx], law(1.0), atol=1e-12)
    np.testing.assert_allclose(path[-1, panda.hand_idx], law.c, atol=1e-3)


def test_plan_file_status_is_exact_solution(planned):
    """The plan file's status reads "exact solution" as in CONTRACT §4."""
    _, data = planned
    assert data["status"] == "exact solution"


def test_same_seed_gives_the_same_rrtconnect_path(tmp_path):
    """Two rrtconnect runs with one seed write identical paths (OMPL's RNG is seeded)."""
    paths = []
    for run in ("a", "b"):
        out = tmp_path / f"{run}.json"
        args = ("plan", SCENE, "--seed", "7", "--planner", "rrtconnect", "--out", str(out))
        result = run_cli(*args, cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        paths.append(json.loads(out.read_text())["path"])
    assert paths[0] == paths[1]


def test_demo_writes_its_plan(tmp_path):
    """`demo --out DIR --seed 1` writes DIR/plan.json, a plan of the demo scene (the
    paper's robot)."""
    from openup_ompl.scene import demo_scene_path

    result = run_cli("demo", "--out", "demo", "--seed", "1", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    data = json.loads((tmp_path / "demo" / "plan.json").read_text())
    assert data["format"] == "openup-plan/1"
    assert data["robot"]["name"] == "lwa3_sdh"
    assert data["grasp_pose"] == ou.load_scene(demo_scene_path()).grasp_pose.tolist()
    assert len(data["path"]) >= 2


def test_plan_to_a_directory_fails_before_planning(tmp_path):
    """`plan --out DIR` exits 2 with one line naming --out, and leaves no file behind."""
    (tmp_path / "out").mkdir()
    result = run_cli("plan", SCENE, "--out", "out", cwd=tmp_path)
    assert_one_error_line(result)
    assert result.returncode == 2 and "--out" in result.stderr
    assert "plan written" not in result.stdout  # refused before planning
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["out"]


def test_demo_into_a_file_fails_before_planning(tmp_path):
    """`demo --out FILE` (an existing file) exits 2 with one line, before planning."""
    (tmp_path / "taken").write_text("x")
    result = run_cli("demo", "--out", "taken", cwd=tmp_path)
    assert_one_error_line(result)
    assert result.returncode == 2 and "taken" in result.stderr
    assert result.stdout == ""


def test_plan_without_out_says_the_plan_was_not_saved(tmp_path):
    """`plan` without --out plans, exits 0 and says on stderr that nothing was saved."""
    result = run_cli("plan", SCENE, "--seed", "1", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "not saved" in result.stderr
    assert not list(tmp_path.iterdir())


def test_help_shows_no_markup_and_the_defaults(tmp_path):
    """The top-level help has no RST markup; a command's help shows its defaults."""
    top = run_cli("--help", cwd=tmp_path).stdout
    assert "``" not in top and "robustness" in top
    assert "(default: 5.0)" in run_cli("plan", "--help", cwd=tmp_path).stdout


def test_summary_line_counts_restarts() -> None:
    """The command's one-line summary names the restarts of a restarted rrtconnect run
    (none said when there were none, and none for a planner that is not restarted)."""
    from openup_ompl.cli._common import summary as _summary

    setup = ou.GraspPlanningSetup(ou.load_scene(ou.default_scene_path()))
    plan = setup.solve(planner="rrtconnect", seed=1)
    assert plan.stats["restarts"] == 0 and "restart" not in _summary(plan)
    plan.stats["restarts"] = 1
    assert _summary(plan).endswith("states, 1 restart)")
    plan.stats["restarts"] = 3
    assert _summary(plan).endswith("states, 3 restarts)")
    assert "restarts" not in setup.solve(planner="ikbirrt", seed=1).stats
