"""Every script of examples/ runs with no arguments from a directory outside the source
tree, exits 0 and writes what its docstring promises."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
# What each script writes in its working directory; the slow ones plan and simulate.
WRITES = {
    "plan_and_save.py": ["plan.json"],
    "own_simple_setup.py": [],
    "ompl_benchmark.py": ["panda_can.log"],
    "execute_displaced.py": ["execution.json"],
    "perceive_plan_execute.py": [],
    "own_robot_hand_law.py": ["hand_law.png"],
}
SLOW = {"ompl_benchmark.py", "execute_displaced.py", "perceive_plan_execute.py"}


def test_every_example_is_listed() -> None:
    """A new example gets a row here, so that the suite runs it."""
    assert sorted(p.name for p in EXAMPLES.glob("*.py")) == sorted(WRITES)


@pytest.mark.parametrize(
    "name",
    [pytest.param(n, marks=pytest.mark.slow) if n in SLOW else n for n in sorted(WRITES)],
)
def test_example_runs_from_a_temporary_directory(name: str, tmp_path: Path) -> None:
    """The script runs as a user would run it, from another directory, and writes its files."""
    env = dict(os.environ, MPLBACKEND="Agg", OPENUP_OMPL_CACHE=str(tmp_path / "cache"))
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / name)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip(), "the example printed nothing"
    for written in WRITES[name]:
        assert (tmp_path / written).is_file(), f"{name} did not write {written}"
