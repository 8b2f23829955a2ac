"""The execution record: what one physics rollout found, and its file ``execution.json``.

The reader sits beside the writer. The record holds no wall-clock time, so the same plan,
offset, seed and options give the same file byte for byte.
"""

from __future__ import annotations

import dataclasses
import json
import types
import typing
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from openup_ompl import _toml
from openup_ompl._io import json_safe, read_bytes, read_json, write_atomic
from openup_ompl.exceptions import ConfigError
from openup_ompl.plan_checks import number_rows

__all__ = [
    "EXECUTION_FORMAT",
    "PHASES",
    "ExecutionRecord",
    "check_execution",
    "is_execution",
    "read_execution",
    "write_execution",
]

EXECUTION_FORMAT = "openup-execution/1"

#: The rollout's phases, in order (:mod:`~openup_ompl.physics.rollout`).
PHASES = ("settle", "reach", "close", "squeeze", "lift", "hold")


@dataclass
class ExecutionRecord:
    """One rollout (``execution.json``). Lengths in the units their names give, frames in
    the world frame unless named otherwise.

    Attributes:
        success: The grasp held (see :attr:`cause` otherwise).
        cause: Why it failed, first that applies: ``"obstacle contact"`` (a robot link
            touched an obstacle), ``"jammed"`` (the object pressed into an obstacle deeper
            than ``max_penetration``), ``"fell"`` (the object went lower than any pose
            resting on its support: off the table), ``"no contact"`` (the hand holds
            nothing at the end), ``"dropped"`` (lifted, then lost), ``"not lifted"``,
            ``"slipped"`` (moved in the hand beyond the thresholds); ``None`` if held.
        verdict: One line for people.
        offset: The object's pose error asked for, ``{"dx": m, "dy": m, "yaw": rad}``,
            against the plan's nominal pose (world x, y; about the object's own z).
        jitter: The random horizontal shift ``{"dx": m, "dy": m}`` drawn on top of
            :attr:`offset` (``PhysicsOptions.object_jitter``; zero without it): the
            object's true error is ``offset + jitter``.
        seed: The run's seed.
        touched: The hand touched the object before closing.
        moved_before_closing: The object's displacement from its true pose by the end of
            the reach: ``{"mm": ..., "deg": ...}``.
        first_contact: First hand-object contact ``{"link", "time_s", "d", "phase"}``
            (``d``: Algorithm 1's normalised palm distance there), or ``None``.
        obstacle_contacts: Every robot link-obstacle pair that touched:
            ``{"link", "obstacle", "time_s", "phase"}`` at its first contact.
        tracking: Largest joint tracking error [rad or m] ``{"reach_arm", "reach_hand",
            "lift_arm"}``.
        final_contacts: Contacts at the end: ``{"link", "with"}`` pairs, sorted.
        lift: ``{"palm_mm", "object_mm", "object_peak_mm"}``: rise of the palm and of the
            object over the lift and hold, and the object's highest rise during them.
        in_hand: Motion of the object in the palm frame from the end of closing to the
            end of the hold: ``{"mm", "deg"}``.
        penetration: Deepest contact penetration [mm] ``{"object_obstacle_mm",
            "robot_object_mm"}``: MuJoCo's contacts are soft; beyond
            ``PhysicsOptions.max_penetration`` between object and obstacle the trial is
            ``"jammed"`` (the hand forced the object into the scene).
        phases: Duration of each phase [s]: ``settle, reach, close, squeeze, lift,
            hold`` (files written before the squeeze was its own phase count it in
            ``close``).
        plan: What was executed: ``{"robot", "planner", "seed", "u", "rows"}``.
        options: The :class:`~openup_ompl.physics.options.PhysicsOptions` used.
        steps: Simulation steps.
        ended_early: ``None``, or why and when the rollout ended once its verdict was
            certain (``PhysicsOptions.early_end``): ``{"reason", "phase", "time_s"}``;
            the phases after that one are absent from :attr:`phases`, and the numbers are
            those at that time.
        neighbours: Per movable obstacle (``movable = true``: a free body in physics), in
            the scene's order, how the rollout disturbed it from its pose at the end of
            the settle to the end of the rollout: ``{"name", "moved_mm"`` (its centre's
            displacement), ``"tilt_deg"`` (the turn of its up axis, its own z),
            ``"moved"`` (beyond ``PhysicsOptions.neighbour_moved_distance``, 2 cm),
            ``"tipped"`` (beyond ``neighbour_tipped_angle``, 45 deg), ``"touched"`` (the
            first robot contact ``{"link", "time_s", "phase"}`` or ``None``)``}``.
            A robot link touching a neighbour does not fail the trial (it is no
            ``obstacle contact``); these fields report it.
        neighbour_moved: Some neighbour was moved.
        neighbour_tipped: Some neighbour was tipped.
        neighbour_touched: The robot touched some neighbour.
        frames: Sampled rollout for the viewer: ``{"period_s", "joint_names", "q",
            "object", "phase", "neighbours"}`` (``object``: ``[x, y, z, qx, qy, qz, qw]``
            rows; ``neighbours``: such rows per movable obstacle's name), or ``None`` when
            not kept (sweeps).
        source: The executed plan file's contents, kept with the frames so that the file
            replays alone (``openup-ompl show``); ``None`` without frames.
    """

    success: bool
    cause: str | None
    verdict: str
    offset: dict[str, float]
    seed: int
    touched: bool
    moved_before_closing: dict[str, float]
    first_contact: dict[str, Any] | None
    obstacle_contacts: list[dict[str, Any]]
    tracking: dict[str, float]
    final_contacts: list[dict[str, str]]
    lift: dict[str, float]
    in_hand: dict[str, float]
    penetration: dict[str, float]
    phases: dict[str, float]
    plan: dict[str, Any]
    options: dict[str, Any]
    steps: int
    frames: dict[str, Any] | None = field(default=None, repr=False)
    source: dict[str, Any] | None = field(default=None, repr=False)
    jitter: dict[str, float] = field(default_factory=lambda: {"dx": 0.0, "dy": 0.0})
    neighbours: list[dict[str, Any]] = field(default_factory=list)
    neighbour_moved: bool = False
    neighbour_tipped: bool = False
    neighbour_touched: bool = False
    ended_early: dict[str, Any] | None = None

    def to_dict(self, frames: bool = True) -> dict[str, Any]:
        """The file's contents (``frames=False``: without the rollout frames).

        Args:
            frames: Include the rollout's frames (every 20 ms).

        Returns:
            The ``openup-execution/1`` contents, JSON-ready (see the file formats).
        """
        data = {"format": EXECUTION_FORMAT, **asdict(self)}
        if not frames:
            data.pop("frames")
            data.pop("source")
        return json_safe(data, digits=9)


def write_execution(record: ExecutionRecord, out_dir: str | Path) -> Path:
    """Write ``out_dir/execution.json``; returns its path.

    Args:
        record: The rollout's record.
        out_dir: The directory to write into.

    Returns:
        The path of ``execution.json``.
    """
    text = json.dumps(record.to_dict(), indent=1, allow_nan=False) + "\n"
    return write_atomic(Path(out_dir) / "execution.json", text)


def is_execution(path: str | Path) -> bool:
    """Whether ``path`` is a JSON object of the execution format's family (any version,
    any layout: for the command line to pick its reader, whose errors then name the
    version it expects). A file :func:`~openup_ompl._io.read_bytes` refuses (a device,
    one too large) is not one: the plan reader then says why.

    Args:
        path: The file to look at.

    Returns:
        True if its ``format`` names the execution family.
    """
    try:
        data = json.loads(read_bytes(path, "execution file"))
    except (OSError, ValueError, RecursionError):  # ConfigError is a ValueError
        return False
    family = EXECUTION_FORMAT.split("/")[0] + "/"
    return isinstance(data, dict) and str(data.get("format", "")).startswith(family)


def read_execution(path: str | Path) -> dict[str, Any]:
    """Read an ``execution.json`` and check it (:func:`check_execution`).

    Args:
        path: The ``execution.json`` file.

    Returns:
        Its checked contents.

    Raises:
        ConfigError: Not a readable execution file, or a key missing or holding a bad
            value, located at ``<file name>: <key>``.
    """
    path = Path(path)
    data = read_json(path, EXECUTION_FORMAT, "execution file")
    check_execution(data, f"{path.name}: ")
    return data


#: What a JSON value of each Python type is called in errors.
_JSON_NAMES = {
    bool: "true or false",
    int: "an integer",
    str: "a string",
    dict: "an object",
    list: "a list",
    type(None): "null",
}


def _json_types(hint: Any) -> tuple[type, ...]:
    """The JSON value types (``dict``, ``list``, ``str``, ...) a field's hint allows."""
    union = typing.get_origin(hint) in (typing.Union, types.UnionType)
    return tuple(typing.get_origin(a) or a for a in (typing.get_args(hint) if union else (hint,)))


def check_execution(data: dict[str, Any], where: str = "") -> None:
    """Check an execution file's contents: every field of :class:`ExecutionRecord`
    (``frames`` and ``source`` may be absent) with its JSON type, and the values the viewer
    reads (``offset``, ``first_contact``, ``frames``). ``source`` is checked where it is
    replayed (:meth:`~openup_ompl.plan.PlanFile.from_dict`).

    Args:
        data: The file's parsed contents.
        where: Prefix of error locations (the file name and ``": "``).

    Raises:
        ConfigError: A key missing or holding a bad value, located at ``where + key``.
    """
    hints = typing.get_type_hints(ExecutionRecord)
    for spec in dataclasses.fields(ExecutionRecord):
        if spec.name not in data:
            if spec.default is dataclasses.MISSING:
                raise ConfigError(f"{where}{spec.name}", None, "a value (the key is missing)")
            continue
        value, allowed = data[spec.name], _json_types(hints[spec.name])
        if not isinstance(value, allowed) or (isinstance(value, bool) and bool not in allowed):
            expected = " or ".join(_JSON_NAMES[t] for t in allowed)
            raise ConfigError(f"{where}{spec.name}", value, expected)
    offset = data["offset"]
    for key in ("dx", "dy", "yaw"):
        _toml.number(_toml.require(offset, key, f"{where}offset"), f"{where}offset.{key}")
    for key in ("dx", "dy") if "jitter" in data else ():
        _toml.number(_toml.require(data["jitter"], key, f"{where}jitter"), f"{where}jitter.{key}")
    first = data["first_contact"]
    if first is not None:
        at = f"{where}first_contact"
        _toml.string(_toml.require(first, "link", at), f"{at}.link")
        _toml.number(_toml.require(first, "time_s", at), f"{at}.time_s", low=0.0)
        if first.get("d") is not None:
            _toml.number(first["d"], f"{at}.d", low=0.0)
        _phase(_toml.require(first, "phase", at), f"{at}.phase")
    if data.get("frames") is not None:
        _check_frames(data["frames"], f"{where}frames")


def _phase(value: Any, where: str) -> None:
    if value not in PHASES:
        raise ConfigError(where, value, f"one of {list(PHASES)}")


def _check_frames(frames: dict[str, Any], where: str) -> None:
    """The sampled rollout: a period > 0, one configuration of ``joint_names``, one object
    pose (a unit quaternion) and one phase per frame."""
    period = _toml.number(_toml.require(frames, "period_s", where), f"{where}.period_s")
    if period <= 0.0:
        raise ConfigError(f"{where}.period_s", period, "a period > 0 [s]")
    names = _toml.string_list(_toml.require(frames, "joint_names", where), f"{where}.joint_names")
    q = number_rows(_toml.require(frames, "q", where), f"{where}.q", len(names))
    poses = number_rows(_toml.require(frames, "object", where), f"{where}.object", 7)
    phases = _toml.require(frames, "phase", where)
    per_frame = f"one per row of frames.q ({len(q)})"
    if len(poses) != len(q):
        raise ConfigError(f"{where}.object", f"{len(poses)} rows", per_frame)
    if not isinstance(phases, list) or len(phases) != len(q):
        shown = f"{len(phases)} entries" if isinstance(phases, list) else phases
        raise ConfigError(f"{where}.phase", shown, per_frame)
    norms = np.linalg.norm(poses[:, 3:], axis=1)
    bad = np.flatnonzero(np.abs(norms - 1.0) > 1e-3)
    if bad.size:
        k = int(bad[0])
        expected = "[x, y, z, qx, qy, qz, qw] with a unit quaternion"
        raise ConfigError(f"{where}.object[{k}]", poses[k].tolist(), expected)
    for k, phase in enumerate(phases):
        _phase(phase, f"{where}.phase[{k}]")
