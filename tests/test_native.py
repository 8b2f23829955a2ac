"""The optional compiled coupled check: the fallback when it is not built or built against
other versions, its build's typed errors, and (slow: it compiles, about 20 s and 2 GB)
its verdicts, ``d`` and counts against the Python check's on every shipped robot."""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace

import coal
import numpy as np
import pinocchio as pin
import pytest

import openup_ompl as oo
from openup_ompl import native
from openup_ompl._resources import data_dir
from openup_ompl.cli import main
from openup_ompl.validity import CoupledChecker

ROBOTS = ("panda", "lwa3_sdh", "ur5_allegro")


@pytest.fixture(autouse=True)
def no_build(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty folder of builds, whatever this machine has built."""
    folder = tmp_path / "native"
    monkeypatch.setenv(native.DIR_VARIABLE, str(folder))
    return folder


@pytest.fixture(scope="module")
def problem() -> oo.Problem:
    return oo.load_scene(oo.default_scene_path())


def _states(problem: oo.Problem, count: int, seed: int) -> np.ndarray:
    robot = problem.robot
    rng = np.random.default_rng(seed)
    return rng.uniform(robot.arm_lower, robot.arm_upper, (count, robot.arm_idx.size))


def test_without_a_build_the_checker_is_the_python_one(problem: oo.Problem) -> None:
    """Nothing built: ``"auto"`` runs the Python check, state for state as ``"off"``."""
    auto, off = CoupledChecker(problem), CoupledChecker(problem, native="off")
    assert (auto.native, off.native) == (False, False)
    for arm in _states(problem, 100, 0):
        assert auto._check_state(arm) == off._check_state(arm)
    assert auto.states_checked == off.states_checked == 100


def test_on_without_a_build_raises_naming_the_command(problem: oo.Problem) -> None:
    """``native="on"`` with nothing built is a NativeUnavailable saying how to build it."""
    with pytest.raises(oo.NativeUnavailable, match="openup-ompl build-native"):
        CoupledChecker(problem, native="on")
    with pytest.raises(oo.NativeUnavailable):
        oo.GraspPlanningSetup(problem, native="on")


@pytest.mark.parametrize("mode", ["yes", None, True, ""])
def test_a_bad_mode_is_a_config_error(problem: oo.Problem, mode: object) -> None:
    """A ``native`` that is not auto/on/off is a ConfigError naming it, in both places."""
    with pytest.raises(oo.ConfigError, match="native"):
        CoupledChecker(problem, native=mode)  # type: ignore[arg-type]
    with pytest.raises(oo.ConfigError, match="native"):
        oo.PlanningOptions(native=mode)  # type: ignore[arg-type]


def _fake_build(built_with: dict[str, str], monkeypatch: pytest.MonkeyPatch) -> None:
    """Make :func:`native.load` find a module recording ``built_with``."""
    module = SimpleNamespace(built_with=built_with)
    monkeypatch.setitem(native._MODULES, native.binary_path(), module)


def test_a_version_mismatch_is_refused(
    problem: oo.Problem, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A module recording another pinocchio is never used: ``"auto"`` falls back to
    Python, ``"on"`` and ``load`` raise NativeUnavailable naming both versions."""
    _fake_build({"pinocchio": "0.0.1", "coal": coal.__version__}, monkeypatch)
    with pytest.raises(oo.NativeUnavailable, match="0.0.1") as error:
        native.load()
    assert pin.__version__ in str(error.value)
    assert CoupledChecker(problem).native is False
    with pytest.raises(oo.NativeUnavailable, match="built against"):
        CoupledChecker(problem, native="on")
    usable, line = native.status()
    assert not usable and "0.0.1" in line


def test_a_module_recording_no_versions_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    """A module without ``built_with`` is refused too (never assumed to match)."""
    monkeypatch.setitem(native._MODULES, native.binary_path(), SimpleNamespace())
    with pytest.raises(oo.NativeUnavailable, match="None"):
        native.load()


def test_the_weighted_distance_keeps_the_python_check(problem: oo.Problem) -> None:
    """The compiled ``d`` is not exact with the weighted distance: ``"auto"`` keeps
    Python (whatever is built), ``"on"`` refuses it before looking for a build."""
    law = problem.hand_law.with_options(distance="weighted")
    assert native.inexact_reason(law) is not None
    assert native.inexact_reason(law.with_options(fixed=law.high)) is None
    assert native.inexact_reason(problem.hand_law) is None
    with pytest.raises(oo.NativeUnavailable, match="weighted"):
        CoupledChecker(problem, law, native="on")


def test_the_build_path_follows_the_versions() -> None:
    """Another pinocchio (or coal) version gives another build folder: a pin upgrade
    never finds the old binary."""
    before = native.binary_path()
    assert "pin" + pin.__version__ in before.parent.name
    versions = pin.__version__, coal.__version__
    try:
        for module in (pin, coal):
            native.build_key.cache_clear()
            module.__version__ = "99.0.0"
            assert native.binary_path() != before
            pin.__version__, coal.__version__ = versions
    finally:
        pin.__version__, coal.__version__ = versions
        native.build_key.cache_clear()
    assert native.binary_path() == before


def test_the_build_refuses_a_missing_compiler(no_build: Path) -> None:
    """No compiler: a NativeBuildError at the 'compiler' step, nothing written."""
    with pytest.raises(oo.NativeBuildError, match="compiler") as error:
        native.build(no_build, compiler="/nonexistent/c++", log=lambda line: None)
    assert error.value.step == "compiler"
    assert not no_build.exists()


def test_the_build_refuses_a_folder_without_eigen(no_build: Path, tmp_path: Path) -> None:
    """An Eigen folder without Eigen/Core: a NativeBuildError at the 'eigen' step."""
    with pytest.raises(oo.NativeBuildError, match="Eigen/Core") as error:
        native.build(no_build, eigen=tmp_path, log=lambda line: None)
    assert error.value.step == "eigen"


def test_a_failed_compile_leaves_no_module(no_build: Path, tmp_path: Path) -> None:
    """A compiler that fails: a NativeBuildError at the 'compile' step naming its exit
    status, and no module left behind for a later load to find."""
    (tmp_path / "Eigen").mkdir()
    (tmp_path / "Eigen" / "Core").write_text("")
    with pytest.raises(oo.NativeBuildError) as error:
        native.build(no_build, compiler="false", eigen=tmp_path, log=lambda line: None)
    if error.value.step == "headers":
        pytest.skip("pin is not installed from its PyPI wheels here")
    assert error.value.step == "compile" and "status 1" in str(error.value)
    assert not native.binary_path(no_build).exists()
    assert not list(no_build.rglob("*.so"))


def test_the_status_command_says_it_is_not_built(capsys: pytest.CaptureFixture[str]) -> None:
    """``openup-ompl build-native --status`` exits 1 and names the command when nothing
    is built for the versions in use."""
    assert main(["build-native", "--status"]) == 1
    assert "openup-ompl build-native" in capsys.readouterr().out


# -- slow: a real build --------------------------------------------------------------------


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """The compiled check built into a fresh folder (this module's only build); skipped
    without a compiler or PyPI (for Eigen's headers), except in CI (``CI`` set)."""
    folder = tmp_path_factory.mktemp("native-build")
    lines: list[str] = []
    try:
        path = native.build(folder, log=lines.append)
    except oo.NativeBuildError as error:
        if error.step in ("compiler", "eigen") and not os.environ.get("CI"):
            pytest.skip(f"cannot build here: {error}")
        raise
    assert path == native.binary_path(folder) and path.is_file()
    assert lines[-1] == f"built: {path}"
    yield folder


@pytest.fixture
def with_build(built: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv(native.DIR_VARIABLE, str(built))
    return built


def _near_grasp(checker: CoupledChecker, grasp_arm: np.ndarray, count: int, seed: int):
    """``count`` arm states with ``d <= mga`` around ``grasp_arm`` (Gaussian steps)."""
    robot, rng, found, sigma = checker.robot, np.random.default_rng(seed), [], 0.2
    while len(found) < count:
        arm = grasp_arm + rng.normal(scale=sigma, size=grasp_arm.size)
        arm = np.clip(arm, robot.arm_lower, robot.arm_upper)
        if checker.normalized_distance(arm) <= checker.law.mga:
            found.append(arm)
        sigma = max(sigma * 0.99, 0.01)
    return np.array(found)


@pytest.mark.slow
def test_the_build_loads_and_is_reused(with_build: Path) -> None:
    """A build loads, records the running versions, and is not built again."""
    module = native.load()
    assert module.built_with["pinocchio"] == pin.__version__
    assert module.built_with["coal"] == coal.__version__
    lines: list[str] = []
    native.build(with_build, log=lines.append)
    assert lines[0].startswith("already built")
    assert native.status()[0]


@pytest.mark.slow
@pytest.mark.parametrize("robot", ROBOTS)
def test_compiled_verdicts_and_d_equal_python(with_build: Path, robot: str) -> None:
    """On 200 uniform and 200 near-grasp states per robot, the compiled check gives the
    Python check's verdicts, ``d`` bit for bit, counts and batches' hands; so do motion
    checks."""
    problem = oo.load_scene(data_dir("scenes") / f"{robot}_can.toml")
    setup = oo.GraspPlanningSetup(problem, native="off")
    python, compiled = setup.checker, CoupledChecker(problem, native="on")
    assert compiled.native and not python.native
    near = _near_grasp(python, setup.goal.ensure_solution(), 200, 1)
    arms = np.concatenate([_states(problem, 200, 0), near])
    python.forget()
    python.states_checked = 0  # the setup's own checks
    expected = [python._check_state(arm) for arm in arms]
    assert [compiled._check_state(arm) for arm in arms] == expected
    assert sum(free for free, _ in expected) > 20
    assert sum(d <= problem.hand_law.mga for _, d in expected) >= 200
    assert compiled.states_checked == python.states_checked
    again = [python._check_state(arm) for arm in arms]  # the free ones remembered
    assert [compiled._check_state(arm) for arm in arms] == again == expected
    assert compiled.states_checked == python.states_checked < 2 * len(arms)
    distances = [python.normalized_distance(arm) for arm in arms]
    assert [compiled.normalized_distance(arm) for arm in arms] == distances
    for rows in (arms[190:230], arms[200:206], arms[300:340]):  # the batches' hands
        assert np.array_equal(compiled.coupled_qs(rows), python.coupled_qs(rows))
    free = arms[[k for k, (ok, _) in enumerate(expected) if ok]]
    pairs = [(free[k], free[(k * 7 + 3) % len(free)]) for k in range(60)]
    motions = [python.check_motion(a, b) for a, b in pairs]
    assert [compiled.check_motion(a, b) for a, b in pairs] == motions
    assert compiled.states_checked == python.states_checked
    assert compiled.certified == python.certified


@pytest.mark.slow
def test_compiled_fixed_hand_equals_python(with_build: Path, problem: oo.Problem) -> None:
    """With a fixed hand the compiled check gives Python's verdicts and ``d = inf``."""
    law = problem.hand_law.with_options(fixed=problem.hand_law.w)
    python = CoupledChecker(problem, law, native="off")
    compiled = CoupledChecker(problem, law, native="on")
    arms = _states(problem, 200, 2)
    assert [compiled._check_state(a) for a in arms] == [python._check_state(a) for a in arms]
    assert compiled._check_state(arms[0])[1] == np.inf


@pytest.mark.slow
def test_each_thread_gets_its_own_compiled_context(with_build: Path, problem: oo.Problem) -> None:
    """One checker used from two threads at once gives each state its one-thread verdict."""
    python = CoupledChecker(problem, native="off")
    compiled = CoupledChecker(problem, native="on")
    arms = [arm.tolist() for arm in _states(problem, 400, 3)]
    expected = [python.is_valid(arm) for arm in arms]
    results: dict[int, list[bool]] = {}
    checks: dict[int, object] = {}

    def run(index: int) -> None:
        results[index] = [compiled.is_valid(arm) for arm in arms]
        checks[index] = compiled._compiled_checks()[-1]

    threads = [threading.Thread(target=run, args=(k,)) for k in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert results == {0: expected, 1: expected}
    assert checks[0] is not checks[1]
