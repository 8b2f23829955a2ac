"""Property-based tests (Hypothesis) of every file reader (scene, perceived scene, robot,
plan, execution) and of the command line's numeric flags.

A random mutation of a valid file (a value replaced, nudged or removed, a key added, the
text cut or corrupted) is either read as written or refused with a typed error
(:class:`~openup_ompl.exceptions.OpenUpError`) naming the bad key or value: never a
traceback, a hang, or a result that differs silently from the file. The quick tier
draws :data:`QUICK_EXAMPLES` inputs per file, the slow one :data:`MANY_EXAMPLES` per
reader (shared among its files); both are derandomized (the same inputs on every run).
"""

from __future__ import annotations

import contextlib
import json
import math
import re
import signal
import types
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import openup_ompl as oo
from openup_ompl.exceptions import ConfigError, OpenUpError
from openup_ompl.physics.record import ExecutionRecord, read_execution, write_execution
from openup_ompl.plan import PlanFile
from openup_ompl.robot_file import RobotSpec, find_robot_file

QUICK_EXAMPLES = 40
MANY_EXAMPLES = 2000
TIERS = [
    pytest.param(QUICK_EXAMPLES, id="quick"),
    pytest.param(MANY_EXAMPLES, id="many", marks=pytest.mark.slow),
]
#: Longest a single read may take before it counts as a hang [s]: reads take milliseconds.
HANG_S = 60
ROOT = Path(__file__).resolve().parent.parent
ROBOTS = ("panda", "lwa3_sdh", "ur5_allegro")


def _share(examples: int, files: int) -> int:
    """Inputs per file when a reader's ``examples`` are shared among ``files`` files (the
    quick tier's count stays per file)."""
    return examples if examples <= QUICK_EXAMPLES else -(-examples // files)


def _run(check: Callable[..., None], strategy: st.SearchStrategy[Any], examples: int) -> None:
    """Run ``check`` on ``examples`` derandomized draws of ``strategy``."""
    configured = settings(
        max_examples=examples,
        derandomize=True,
        deadline=None,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )
    configured(given(strategy)(check))()


class Hang(Exception):
    """A read took longer than :data:`HANG_S`."""


@contextlib.contextmanager
def _hang_guard() -> Iterator[None]:
    def alarm(signum: int, frame: Any) -> None:
        raise Hang(f"no answer in {HANG_S} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(HANG_S)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


# -- mutations of a document (a TOML or JSON file's contents) --------------------------

Key = str | int


@dataclass(frozen=True)
class Mutation:
    """One change to a document: ``kind`` is ``replace`` (``value`` at ``path``),
    ``delete`` (the key at ``path``), ``add`` (the new key ``value[0]`` with value
    ``value[1]`` in the table at ``path``), or ``text`` (``value`` a function of the
    file's text)."""

    kind: str
    path: tuple[Key, ...]
    value: Any = None


def _nodes(doc: Any, path: tuple[Key, ...] = ()) -> Iterator[tuple[tuple[Key, ...], Any]]:
    """Every node of ``doc`` with its path; of a long list only its ends and middle (a
    plan's path has thousands of rows alike)."""
    yield path, doc
    if isinstance(doc, dict):
        for key, value in doc.items():
            yield from _nodes(value, (*path, key))
    elif isinstance(doc, list):
        n = len(doc)
        indices = range(n) if n <= 6 else sorted({0, 1, n // 2, n - 2, n - 1})
        for i in indices:
            yield from _nodes(doc[i], (*path, i))


def _leaf_values(toml: bool) -> st.SearchStrategy[Any]:
    leaves = st.one_of(
        st.booleans(),
        st.integers(min_value=-(2**70), max_value=2**70),
        st.floats(allow_nan=True, allow_infinity=True),
        st.sampled_from([0, 1, -1, 0.0, -0.0, 1e-320, 1e308, -1e308, 2**31, 2**63, 0.5]),
        st.text(max_size=10),
        st.sampled_from(["", "panda", "box", "mesh", "sphere", "c", "w", "/dev/zero", ".."]),
    )
    if not toml:
        leaves = st.one_of(leaves, st.none())
    return st.recursive(
        leaves,
        lambda inner: st.one_of(
            st.lists(inner, max_size=8), st.dictionaries(st.text(max_size=6), inner, max_size=3)
        ),
        max_leaves=10,
    )


def _nudged(value: Any) -> st.SearchStrategy[Any]:
    """``value`` slightly or greatly changed, of the same shape where it is a number or
    a list of numbers."""
    steps = st.sampled_from([1e-12, -1e-9, 1e-6, -1e-4, 0.01, -0.1, 1.0, -3.0, 100.0, 1e9])
    if isinstance(value, bool):
        return st.just(not value)
    if isinstance(value, int):
        return st.sampled_from([value + 1, value - 1, -value, value * 1000, 2**40])
    if isinstance(value, float):
        return steps.map(lambda e: value + e * max(1.0, abs(value)))
    if isinstance(value, list) and value:
        return st.one_of(
            st.just(value[:-1]),
            st.just([*value, value[-1]]),
            st.tuples(st.integers(0, len(value) - 1), steps).map(
                lambda ie: [
                    x + ie[1] if i == ie[0] and type(x) in (int, float) else x
                    for i, x in enumerate(value)
                ]
            ),
        )
    return st.nothing()


@st.composite
def mutations(draw: st.DrawFn, doc: dict[str, Any], toml: bool) -> Mutation:
    """A mutation of ``doc`` (module docstring)."""
    nodes = list(_nodes(doc))
    kind = draw(st.sampled_from(["replace", "replace", "nudge", "delete", "add", "text"]))
    if kind == "text":
        positions = st.integers(0, 10**6)
        edit = draw(
            st.one_of(
                positions.map(lambda k: ("cut", k, "")),
                st.tuples(st.just("insert"), positions, st.text(min_size=1, max_size=3)),
                st.tuples(st.just("swap"), positions, st.text(min_size=1, max_size=1)),
            )
        )
        return Mutation("text", (), edit)
    if kind == "add":
        tables = [path for path, node in nodes if isinstance(node, dict)]
        path = draw(st.sampled_from(tables))
        key = draw(st.text(min_size=1, max_size=8))
        return Mutation("add", path, (key, draw(_leaf_values(toml))))
    path, node = draw(st.sampled_from(nodes[1:]))
    if kind == "delete":
        return Mutation("delete", path)
    if kind == "nudge":
        nudged = _nudged(node)
        if not nudged.is_empty:
            return Mutation("replace", path, draw(nudged))
    return Mutation("replace", path, draw(_leaf_values(toml)))


def _apply(doc: Any, mutation: Mutation) -> Any:
    """A copy of ``doc`` with ``mutation`` applied (not a ``text`` one)."""
    doc = json.loads(json.dumps(doc))
    *parents, last = mutation.path or (None,)
    node = doc
    for key in parents:
        node = node[key]
    if mutation.kind == "add":
        target = node[last] if mutation.path else doc
        key, value = mutation.value
        if key in target:
            key += "_x"
        target[key] = value
    elif mutation.kind == "delete":
        del node[last]
    else:
        node[last] = mutation.value
    return doc


def _edited_text(text: str, edit: tuple[str, int, str]) -> str:
    how, at, piece = edit
    at %= len(text) + 1
    if how == "cut":
        return text[:at]
    if how == "insert":
        return text[:at] + piece + text[at:]
    return text[:at] + piece + text[at + 1 :]


def _lookup(doc: Any, path: tuple[Key, ...]) -> Any:
    for key in path:
        if (isinstance(doc, dict) and isinstance(key, str) and key in doc) or (
            isinstance(doc, list) and isinstance(key, int) and -len(doc) <= key < len(doc)
        ):
            doc = doc[key]
        else:
            raise KeyError(path)
    return doc


# -- TOML and JSON text of a document ----------------------------------------------------


def _toml_string(text: str) -> str:
    """A TOML basic string (JSON's escapes, but every character a TOML string may hold
    raw kept raw, and DEL escaped)."""
    escaped = (c if c not in '"\\' and 0x20 <= ord(c) != 0x7F else f"\\u{ord(c):04x}" for c in text)
    return '"' + "".join(escaped) + '"'


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return (
            "nan"
            if math.isnan(value)
            else repr(value)
            if math.isfinite(value)
            else ("inf" if value > 0 else "-inf")
        )
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(x) for x in value) + "]"
    items = (f"{_toml_string(k)} = {_toml_value(v)}" for k, v in value.items())
    return "{" + ", ".join(items) + "}"


def toml_text(doc: dict[str, Any]) -> str:
    """``doc`` as TOML: one ``key = value`` line per top-level key, tables inline."""
    return "".join(f"{_toml_string(k)} = {_toml_value(v)}\n" for k, v in doc.items())


# -- the property -----------------------------------------------------------------------


def _strings(doc: Any) -> Iterator[str]:
    """Every key and string value of ``doc``."""
    if isinstance(doc, dict):
        for key, value in doc.items():
            yield str(key)
            yield from _strings(value)
    elif isinstance(doc, list):
        for value in doc:
            yield from _strings(value)
    elif isinstance(doc, str):
        yield doc


def _names_a_place(error: OpenUpError, docs: tuple[Any, ...], mutation: Mutation) -> bool:
    """Whether the error points into the file: a :class:`ConfigError` located at a key
    of the file (or the key added), any other error naming one of its keys or values (a
    robot, joint or frame name)."""
    known = {word for doc in docs for word in _strings(doc) if len(word) >= 2}
    if mutation.kind == "add":
        known.add(str(mutation.value[0]))
    if isinstance(error, ConfigError):
        tokens = re.split(r"[.\[\]: ]+", error.where)
        return any(token in known for token in tokens) or any(
            word in error.where for word in known if len(word) >= 3
        )
    return any(word in str(error) for word in known)


def _as_written(path: tuple[Key, ...], value: Any) -> Any:
    """What a reader makes of ``value`` at ``path`` when it accepts it: a pose's
    quaternion normalised (the readers accept a norm within 1e-3 of 1)."""
    if "pose" in path or path[-1:] == ("grasp_pose",):
        array = np.asarray(value, dtype=float)
        if array.shape == (7,):
            return np.r_[array[:3], array[3:] / np.linalg.norm(array[3:])]
    return value


def _is_numbers(value: Any) -> bool:
    """Whether ``value`` is a number or a (nested) list of numbers, not booleans."""
    if isinstance(value, np.ndarray):
        return value.dtype.kind in "fiu"
    if isinstance(value, list):
        return bool(value) and all(_is_numbers(x) for x in value)
    return type(value) in (int, float)


def check_reader(
    doc: dict[str, Any],
    mutation: Mutation,
    *,
    file: Path,
    dump: Callable[[dict[str, Any]], str],
    read: Callable[[Path], Any],
    view: Callable[[Any], dict[tuple[Key, ...], Any]],
) -> None:
    """The property of every reader (module docstring)."""
    if mutation.kind == "text":
        mutated = None
        text = _edited_text(dump(doc), mutation.value)
    else:
        mutated = _apply(doc, mutation)
        text = dump(mutated)
    file.write_text(text, encoding="utf-8")
    try:
        with _hang_guard():
            result = read(file)
    except OpenUpError as error:
        if mutation.kind != "text":
            assert _names_a_place(error, (doc, mutated), mutation), (mutation, str(error))
        if isinstance(error, ConfigError):
            assert error.where, error
        return
    if mutated is None:
        return
    for path, got in view(result).items():
        try:
            written = _as_written(path, _lookup(mutated, path))
        except KeyError:
            continue  # an optional key the mutation removed
        if _is_numbers(written):
            numbers = np.asarray(written, dtype=float)
            shown = np.asarray(got, dtype=float)
            assert shown.shape == numbers.shape, (path, got, written, mutation)
            assert np.allclose(shown, numbers, rtol=1e-12, atol=0, equal_nan=True), (
                path,
                got,
                written,
                mutation,
            )
        else:
            assert got == written, (path, got, written, mutation)


# -- scene files (hand-written and perceived) ----------------------------------------------


def _absolute_files(table: dict[str, Any], base: Path) -> dict[str, Any]:
    """``table`` with a relative ``file`` (a mesh) made absolute, so that the mutated copy
    written elsewhere reads the same mesh."""
    if isinstance(table.get("file"), str) and not Path(table["file"]).is_absolute():
        return {**table, "file": str((base / table["file"]).resolve())}
    return table


def _scene_doc(path: Path) -> dict[str, Any]:
    import tomllib

    doc = tomllib.loads(path.read_text())
    if "object" in doc:
        doc["object"] = _absolute_files(doc["object"], path.parent)
    doc["obstacles"] = [_absolute_files(t, path.parent) for t in doc.get("obstacles", [])]
    return doc


def _scene_view(problem: oo.Problem) -> dict[tuple[Key, ...], Any]:
    view: dict[tuple[Key, ...], Any] = {
        ("start",): problem.start,
        ("grasp", "pose"): problem.grasp_pose,
    }
    law = problem.hand_law.to_dict()
    view |= {("hand", key): value for key, value in law.items()}
    shapes = [("object", problem.object)] if problem.object is not None else []
    shapes += [(("obstacles", i), s) for i, s in enumerate(problem.obstacles)]  # type: ignore[misc]
    for where, shape in shapes:
        prefix = where if isinstance(where, tuple) else (where,)
        for key, value in shape.to_table().items():
            if key != "file":
                view[(*prefix, key)] = value
    return view


SCENES = {
    "panda_can": ROOT / "scenes" / "panda_can.toml",
    "lwa3_sdh_can": ROOT / "scenes" / "lwa3_sdh_can.toml",
    "ur5_allegro_can": ROOT / "scenes" / "ur5_allegro_can.toml",
    "panda_bottle": ROOT / "scenes" / "panda_bottle.toml",
}


@pytest.fixture(scope="module")
def robots() -> dict[str, oo.Robot]:
    """The three shipped robots, loaded once."""
    return {name: oo.load_robot(name) for name in ROBOTS}


def _scene_reader(robots: dict[str, oo.Robot], robot: str) -> Callable[[Path], oo.Problem]:
    return lambda path: oo.load_scene(path, robot=robots[robot])


@pytest.mark.parametrize("examples", TIERS)
@pytest.mark.parametrize("scene", sorted(SCENES))
def test_mutated_scene_files_are_read_as_written_or_refused(
    scene: str, examples: int, robots: dict[str, oo.Robot], tmp_path: Path
) -> None:
    """A mutated scene file is read as written or refused with a typed error naming it."""
    doc = _scene_doc(SCENES[scene])
    read = _scene_reader(robots, doc["robot"])

    def check(mutation: Mutation) -> None:
        check_reader(
            doc,
            mutation,
            file=tmp_path / f"{scene}.toml",
            dump=toml_text,
            read=read,
            view=_scene_view,
        )

    # The slow tier's inputs are per reader: shared among the shipped scene files.
    _run(check, mutations(doc, toml=True), _share(examples, len(SCENES)))


def _perceived_doc(tmp: Path, robots: dict[str, oo.Robot]) -> dict[str, Any]:
    """A ``perceived.toml`` as ``openup-ompl perceive`` writes it (its writer, with a
    stand-in fit)."""

    from openup_ompl.perception.perceive import perceived_toml

    problem = oo.load_scene(SCENES["lwa3_sdh_can"], robot=robots["lwa3_sdh"])
    assert problem.object is not None
    pose = problem.object.pose + np.array([0.004, -0.003, 0.0, 0, 0, 0, 0])
    quadric = types.SimpleNamespace(sizes=np.array([0.03, 0.03, 0.06]), exponents=np.ones(2))
    fit = types.SimpleNamespace(points=812, superquadric=quadric, mean_residual=0.0011)
    perception = types.SimpleNamespace(pose=pose, u=0.42, fit=fit)
    text = perceived_toml(problem, perception)  # type: ignore[arg-type]
    path = tmp / "perceived.toml"
    path.write_text(text)
    return _scene_doc(path) | {"_text": text}


@pytest.mark.parametrize("examples", TIERS)
def test_mutated_perceived_scenes_are_read_as_written_or_refused(
    examples: int, robots: dict[str, oo.Robot], tmp_path: Path
) -> None:
    """A mutated ``perceived.toml`` is read as written or refused with a typed error; as
    written it reads at the estimate with the measured ``u``."""
    doc = _perceived_doc(tmp_path, robots)
    text = doc.pop("_text")
    read = _scene_reader(robots, "lwa3_sdh")
    problem = read(tmp_path / "perceived.toml")
    assert problem.hand_law.u == pytest.approx(0.42)
    assert text.startswith("# Perceived")

    def check(mutation: Mutation) -> None:
        check_reader(
            doc,
            mutation,
            file=tmp_path / "mutated.toml",
            dump=toml_text,
            read=read,
            view=_scene_view,
        )

    _run(check, mutations(doc, toml=True), examples)


# -- robot files -----------------------------------------------------------------------


def _robot_view(robot: oo.Robot) -> dict[tuple[Key, ...], Any]:
    spec = robot.spec
    view: dict[tuple[Key, ...], Any] = {
        (key,): getattr(spec, key)
        for key in ("name", "description", "palm_frame", "home", "convex")
    }
    view[("arm_joints",)] = list(spec.arm_joints)
    view[("hand_joints",)] = list(spec.hand_joints)
    for key in ("c", "b", "w", "mga", "u"):
        view[("hand", key)] = getattr(spec, key)
    return view


@pytest.mark.parametrize("examples", TIERS)
@pytest.mark.parametrize("name", ROBOTS)
def test_mutated_robot_files_are_read_as_written_or_refused(
    name: str, examples: int, tmp_path: Path
) -> None:
    """A mutated robot file is loaded as written or refused with a typed error naming it."""
    import tomllib

    source = find_robot_file(name)
    doc = tomllib.loads(source.read_text())
    spec = RobotSpec.from_file(source)
    doc["urdf"] = str(spec.urdf)  # resolved: the copy is written elsewhere
    if spec.srdf is not None:
        doc["srdf"] = str(spec.srdf)
    if spec.mount is not None:
        doc["mount"]["urdf"] = str(spec.mount.urdf)
        if doc["mount"].get("srdf"):
            doc["mount"]["srdf"] = str(spec.mount.srdf)

    def check(mutation: Mutation) -> None:
        check_reader(
            doc,
            mutation,
            file=tmp_path / f"{name}.toml",
            dump=toml_text,
            read=oo.load_robot,
            view=_robot_view,
        )

    _run(check, mutations(doc, toml=True), _share(examples, len(ROBOTS)))


# -- plan files --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def plan_doc(robots: dict[str, oo.Robot]) -> dict[str, Any]:
    """A plan file's contents: the Panda's can, seed 1."""
    problem = oo.load_scene(SCENES["panda_can"], robot=robots["panda"])
    plan = oo.GraspPlanningSetup(problem).solve(5.0, "ikbirrt", 1)
    return json.loads(json.dumps(plan.to_dict()))


def _plan_view(plan: PlanFile) -> dict[tuple[Key, ...], Any]:
    view: dict[tuple[Key, ...], Any] = {
        ("grasp_pose",): plan.grasp_pose,
        ("path",): plan.path,
        ("robot", "hand_joints"): list(plan.hand_joints),
    }
    if plan.seed is not None:
        view[("seed",)] = plan.seed
    law = plan.law.to_dict()
    view |= {("hand_law", key): value for key, value in law.items()}
    return view


@pytest.mark.parametrize("examples", TIERS)
def test_mutated_plan_files_are_read_as_written_or_refused(
    examples: int, plan_doc: dict[str, Any], tmp_path: Path
) -> None:
    """A mutated plan file is read as written or refused with a typed error naming it."""

    def check(mutation: Mutation) -> None:
        check_reader(
            plan_doc,
            mutation,
            file=tmp_path / "plan.json",
            dump=lambda doc: json.dumps(doc, indent=1),
            read=PlanFile.read,
            view=_plan_view,
        )

    _run(check, mutations(plan_doc, toml=False), examples)


# -- execution files ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def execution_doc(plan_doc: dict[str, Any], tmp_path_factory: pytest.TempPathFactory) -> Any:
    """An ``execution.json`` with its frames, as ``openup-ompl execute`` writes it, of
    the plan of :func:`plan_doc` (the rollout itself stood in for)."""
    rows = plan_doc["path"]
    pose = plan_doc["scene"]["object"]["pose"]
    phases = ["settle", "reach", "close", "lift", "hold"]
    record = ExecutionRecord(
        success=True,
        cause=None,
        verdict="held",
        offset={"dx": 0.0, "dy": 0.01, "yaw": 0.0},
        seed=1,
        touched=False,
        moved_before_closing={"mm": 0.0, "deg": 0.0},
        first_contact={"link": "panda_leftfinger", "time_s": 1.2, "d": 0.01, "phase": "close"},
        obstacle_contacts=[],
        tracking={"reach_arm": 0.001, "reach_hand": 0.0, "lift_arm": 0.002},
        final_contacts=[{"link": "panda_leftfinger", "with": "can"}],
        lift={"palm_mm": 100.0, "object_mm": 99.0, "object_peak_mm": 99.5},
        in_hand={"mm": 0.5, "deg": 0.2},
        penetration={"object_obstacle_mm": 0.0, "robot_object_mm": 0.3},
        phases={p: 0.5 for p in phases},
        plan={"robot": "panda", "planner": "IKBiRRT", "seed": 1, "u": 0.3, "rows": len(rows)},
        options={},
        steps=1000,
        frames={
            "period_s": 0.02,
            "joint_names": plan_doc["robot"]["joint_names"],
            "q": [rows[0], rows[len(rows) // 2], rows[-1], rows[-1], rows[-1]],
            "object": [pose] * 5,
            "phase": phases,
        },
        source=plan_doc,
    )
    return json.loads(write_execution(record, tmp_path_factory.mktemp("execution")).read_text())


def _read_and_show(path: Path) -> dict[str, Any]:
    """What ``openup-ompl show`` does with an execution file before drawing."""
    from openup_ompl.viz.rollout import _loaded, key_frames

    data = read_execution(path)
    if data.get("frames") is not None:
        _loaded(data, f"{path.name}: ")
        key_frames(data)
    return data


@pytest.mark.parametrize("examples", TIERS)
def test_mutated_execution_files_are_read_as_written_or_refused(
    examples: int, execution_doc: dict[str, Any], tmp_path: Path
) -> None:
    """A mutated ``execution.json`` is read (and prepared for drawing) as written or
    refused with a typed error naming it."""

    def check(mutation: Mutation) -> None:
        check_reader(
            execution_doc,
            mutation,
            file=tmp_path / "execution.json",
            dump=lambda doc: json.dumps(doc, indent=1),
            read=_read_and_show,
            view=lambda data: {(key,): data[key] for key in ("success", "seed", "offset")},
        )

    _run(check, mutations(execution_doc, toml=False), examples)


# -- what the properties found, each kept as a test -------------------------------------


def test_a_robot_description_that_is_not_text_is_refused(panda_toml: str, tmp_path: Path) -> None:
    """``description = false`` was read as the text "False"; it is refused, named."""
    path = tmp_path / "panda.toml"
    path.write_text(re.sub(r"^description = .*$", "description = false", panda_toml, flags=re.M))
    with pytest.raises(ConfigError, match="description"):
        RobotSpec.from_file(path)
