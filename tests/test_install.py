"""The package works installed from a wheel, run from another directory (no source tree)."""

from __future__ import annotations

import importlib.util
import json
import os
import site
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

pytestmark = pytest.mark.slow  # builds a wheel, installs it into a venv, runs the CLI


def _run(args: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=900)


def _venv_seeing_this_environment(venv: Path) -> Path:
    """A new venv that imports what the running interpreter imports, and its python.

    ``--system-site-packages`` shows the new venv its base interpreter's site-packages;
    run from inside a venv, that base is the venv's own base Python, without the venv's
    packages (ompl, pinocchio, ...). The running environment's site-packages are then
    added by a ``.pth`` file, after the new venv's own (so the installed wheel wins)."""
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True)
    python = venv / "bin" / "python"
    if sys.prefix != sys.base_prefix:
        purelib = subprocess.run(
            [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        lines = [f"import site; site.addsitedir({path!r})" for path in site.getsitepackages()]
        (Path(purelib) / "_outer_environment.pth").write_text("\n".join(lines) + "\n")
    return python


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, dict[str, str]]:
    """A venv (seeing the system's dependencies) with the package pip-installed from this
    checkout; its python, a work directory outside the source tree, and an environment
    without PYTHONPATH."""
    base = tmp_path_factory.mktemp("wheel")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["OPENUP_OMPL_CACHE"] = str(base / "cache")
    python = _venv_seeing_this_environment(base / "venv")
    isolation = [] if importlib.util.find_spec("hatchling") is None else ["--no-build-isolation"]
    done = _run(
        [str(python), "-m", "pip", "install", "-q", "--no-deps", *isolation, str(ROOT)],
        base,
        env,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    work = base / "work"
    work.mkdir()
    return python, work, env


def test_installed_package_is_the_wheel(installed: tuple[Path, Path, dict[str, str]]) -> None:
    """The venv imports the installed copy, not the source tree, and finds its data."""
    python, work, env = installed
    code = (
        "import openup_ompl as o, openup_ompl.benchmark as b;"
        "print(o.__file__); print(b.PROBLEMS_ROOT); print(o.default_scene_path())"
    )
    done = _run([str(python), "-c", code], work, env)
    assert done.returncode == 0, done.stderr[-3000:]
    module, problems, scene = done.stdout.split()[-3:]
    for path in (module, problems, scene):
        assert str(ROOT) not in path and "site-packages" in path
    assert Path(scene).is_file() and Path(problems).is_dir()


def test_installed_cli_plans_benchmarks_and_sweeps(
    installed: tuple[Path, Path, dict[str, str]],
) -> None:
    """From another directory: `plan`, `benchmark --runs 1` on the shipped suites and
    `robustness --seeds 1` all work and write their outputs."""
    python, work, env = installed
    cli = [str(python), "-m", "openup_ompl"]
    scene = "import openup_ompl; print(openup_ompl.default_scene_path())"
    path = _run([str(python), "-c", scene], work, env).stdout.split()[-1]
    done = _run([*cli, "plan", path, "--seed", "1", "--out", "plan.json"], work, env)
    assert done.returncode == 0, done.stderr[-3000:]
    assert json.loads((work / "plan.json").read_text())["format"] == "openup-plan/1"
    done = _run(
        [*cli, "benchmark", "--runs", "1", "--planners", "ikbirrt", "--out", "bench", "--quiet"],
        work,
        env,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    rows = json.loads((work / "bench" / "summary.json").read_text())["rows"]
    assert {row["problem"].split(".")[0] for row in rows} == {"lwa3_sdh", "panda", "ur5_allegro"}
    done = _run(
        [*cli, "robustness", "--seeds", "1", "--u", "0.3", "--delta", "0", "--out", "rob",
         "--quiet"],
        work,
        env,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert (work / "rob" / "robustness.csv").read_text().count("\n") == 2
