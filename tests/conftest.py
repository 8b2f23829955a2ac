"""Shared fixtures: the shipped Panda, its robot file's text and scene-file writers."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

import openup_ompl as ou


@pytest.fixture(scope="session")
def panda() -> ou.Robot:
    """The shipped Panda, loaded once per session (tests must not mutate it)."""
    return ou.load_robot("panda")


@pytest.fixture(scope="session")
def panda_toml() -> str:
    """The text of the shipped robots/panda.toml, to copy and edit."""
    return ou.available_robots()["panda"].read_text()


@pytest.fixture(scope="session")
def default_scene_text() -> str:
    """The text of the default scene, scenes/panda_can.toml."""
    return ou.default_scene_path().read_text()


@pytest.fixture(scope="session")
def empty_scene_text() -> str:
    """A scene with no obstacles and no object: the Panda at home and a grasp pose."""
    return 'robot = "panda"\n[grasp]\npose = [0.6, 0.0, 0.19, 1.0, 0.0, 0.0, 0.0]\n'


@pytest.fixture
def write_file(tmp_path: Path) -> Callable[[str, str], Path]:
    """Write ``text`` to ``tmp_path / name`` and return the path."""

    def write(name: str, text: str) -> Path:
        path = tmp_path / name
        path.write_text(text)
        return path

    return write
