"""``execute --true-scene``: a plan made for a perceived object, executed against the
object where another scene file (the true one) has it."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

import openup_ompl as oo
from openup_ompl.cli.execute import true_offset
from openup_ompl.exceptions import ConfigError

SCENE = Path(oo.default_scene_path())
OBJECT_POSE = "pose = [0.6, 0.0, 0.06, 0.0, 0.0, 0.0, 1.0]"


def _moved(tmp: Path, dx: float, dy: float, yaw: float, name: str = "scene.toml") -> Path:
    """The default scene with its can moved by ``dx, dy`` [m] and turned by ``yaw`` [rad]."""
    text = SCENE.read_text()
    assert text.count(OBJECT_POSE) == 1
    pose = [0.6 + dx, dy, 0.06, 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)]
    path = tmp / name
    path.write_text(text.replace(OBJECT_POSE, f"pose = {pose}"))
    return path


def test_true_offset_is_the_true_planar_pose_relative_to_the_plan(tmp_path: Path) -> None:
    """The offset is the true object's x, y [m] and yaw [rad] relative to the planned one."""
    planned = oo.load_scene(SCENE).object
    assert planned is not None
    offset = true_offset(planned, _moved(tmp_path, 0.01, -0.02, 0.3))
    assert offset == pytest.approx((0.01, -0.02, 0.3), abs=1e-9)


def test_true_scene_of_another_object_is_refused(tmp_path: Path) -> None:
    """A scene whose object is another (by name) is refused, naming its object."""
    planned = oo.load_scene(SCENE).object
    assert planned is not None
    other = tmp_path / "other.toml"
    other.write_text(SCENE.read_text().replace('name = "can"', 'name = "cup"', 1))
    with pytest.raises(ConfigError, match="other.toml: object"):
        true_offset(planned, other)


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "openup_ompl", *args], capture_output=True, text=True, timeout=300
    )


def test_execute_runs_against_the_true_scene(tmp_path: Path) -> None:
    """``execute --true-scene`` records the true scene's offset in execution.json, and
    refuses ``--object-offset`` beside it (exit 2)."""
    plan = oo.GraspPlanningSetup(oo.load_scene(SCENE)).solve(seed=1).save(tmp_path / "plan.json")
    truth = _moved(tmp_path, 0.0, 0.01, 0.0)
    done = _cli("execute", str(plan), "--true-scene", str(truth), "--out", str(tmp_path))
    assert done.returncode in (0, 1), done.stderr
    offset = json.loads((tmp_path / "execution.json").read_text())["offset"]
    assert offset == pytest.approx({"dx": 0.0, "dy": 0.01, "yaw": 0.0}, abs=1e-9)
    both = _cli("execute", str(plan), "--true-scene", str(truth), "--object-offset", "0", "0", "0")
    assert both.returncode == 2 and "not allowed with" in both.stderr
