"""Issue 37's hostile inputs that fell short, each now refused in one line (the tampered
plan is tests/test_revalidate.py's)."""

from __future__ import annotations

from pathlib import Path

import pytest

import openup_ompl as ou
import openup_ompl.executor as executor
from openup_ompl.cli import main
from openup_ompl.exceptions import ConfigError


def _one_line(capsys: pytest.CaptureFixture[str]) -> str:
    """The one line the command printed on stderr (no traceback)."""
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.fixture()
def loop(tmp_path: Path) -> Path:
    """A scene path that is a symbolic link to itself."""
    path = tmp_path / "loop.toml"
    path.symlink_to(path)
    return path


def test_a_scene_that_is_a_symlink_loop_is_a_config_error(loop):
    """``load_scene`` refuses a symlink loop with a ConfigError naming the path."""
    with pytest.raises(ConfigError, match="loop of symbolic links") as refused:
        ou.load_scene(loop)
    assert refused.value.value == str(loop)


@pytest.mark.parametrize("command", [["plan"], ["perceive", "--out", "perceived"]])
def test_commands_refuse_a_symlink_loop_in_one_line(loop, tmp_path, capsys, command):
    """``plan`` and ``perceive`` of a symlink loop exit 2 with one line naming it."""
    args = [
        command[0],
        str(loop),
        *[str(tmp_path / a) if a == "perceived" else a for a in command[1:]],
    ]
    assert main(args) == 2
    line = _one_line(capsys)
    assert "loop.toml" in line and "loop of symbolic links" in line


def test_plan_refuses_an_unknown_camera_key_as_perceive_does(
    write_file, default_scene_text, tmp_path, capsys
):
    """A ``[camera]`` key that is not the camera's is refused by ``plan`` with the line
    ``perceive`` gives (planning does not use the camera, but the file is wrong)."""
    scene = write_file(
        "scene.toml",
        default_scene_text.replace("elevation = 60.0", "elevation = 60.0\nelevaton = 50"),
    )
    lines = []
    for args in (["plan", str(scene)], ["perceive", str(scene), "--out", str(tmp_path / "p")]):
        assert main(args) == 2
        lines.append(_one_line(capsys))
    assert "camera.elevaton" in lines[0] and "did you mean 'elevation'" in lines[0]
    assert lines[0] == lines[1]


def test_an_unreachable_scheduler_leaves_no_empty_directory(tmp_path, monkeypatch, capsys):
    """``robustness --scheduler`` at an address nobody answers exits 2 in one line and
    leaves neither an empty ``shards/`` in an existing ``--out`` nor a new empty ``--out``."""
    monkeypatch.setattr(executor, "CONNECT_TIMEOUT", 1.0)  # [s] no one answers at port 9
    sweep = ["--seeds", "1", "--u", "0", "--delta", "0", "--scheduler", "tcp://127.0.0.1:9"]
    existing = tmp_path / "existing"
    existing.mkdir()
    for out in (existing, tmp_path / "new"):
        assert main(["robustness", *sweep, "--out", str(out)]) == 2
        assert "127.0.0.1:9" in _one_line(capsys)
        assert not (out / "shards").exists()
    assert existing.is_dir() and not (tmp_path / "new").exists()
