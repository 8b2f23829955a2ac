"""The execution record: what one physics rollout found, and its file ``execution.json``.

The reader sits beside the writer. The record holds no wall-clock time, so the same plan,
offset, seed and options give the same file byte for byte.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from openup_ompl._io import read_json, write_atomic

__all__ = [
    "EXECUTION_FORMAT",
    "ExecutionRecord",
    "is_execution",
    "read_execution",
    "write_execution",
]

EXECUTION_FORMAT = "openup-execution/1"


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
        offset: The object's true pose error ``{"dx": m, "dy": m, "yaw": rad}`` against the
            plan's nominal pose (world x, y; about the object's own z).
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
        lift: ``{"palm_mm", "object_mm"}``: rise of the palm and of the object over the
            lift and hold.
        in_hand: Motion of the object in the palm frame from the end of closing to the
            end of the hold: ``{"mm", "deg"}``.
        penetration: Deepest contact penetration [mm] ``{"object_obstacle_mm",
            "robot_object_mm"}``: MuJoCo's contacts are soft; beyond
            ``PhysicsOptions.max_penetration`` between object and obstacle the trial is
            ``"jammed"`` (the hand forced the object into the scene).
        phases: Duration of each phase [s]: ``settle, reach, close, lift, hold``.
        plan: What was executed: ``{"robot", "planner", "seed", "u", "rows"}``.
        options: The :class:`~openup_ompl.physics.options.PhysicsOptions` used.
        steps: Simulation steps.
        frames: Sampled rollout for the viewer: ``{"period_s", "joint_names", "q",
            "object", "phase"}`` (``object``: ``[x, y, z, qx, qy, qz, qw]`` rows), or
            ``None`` when not kept (sweeps).
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

    def to_dict(self, frames: bool = True) -> dict[str, Any]:
        """The file's contents (``frames=False``: without the rollout frames)."""
        data = {"format": EXECUTION_FORMAT, **asdict(self)}
        if not frames:
            data.pop("frames")
            data.pop("source")
        return _rounded(data)


def _rounded(value: Any) -> Any:
    """Floats to 9 significant digits: the file reads well and stays deterministic."""
    if isinstance(value, float):
        return float(f"{value:.9g}") if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_rounded(v) for v in value]
    return value


def write_execution(record: ExecutionRecord, out_dir: str | Path) -> Path:
    """Write ``out_dir/execution.json``; returns its path."""
    text = json.dumps(record.to_dict(), indent=1, allow_nan=False) + "\n"
    return write_atomic(Path(out_dir) / "execution.json", text)


def is_execution(path: str | Path) -> bool:
    """Whether ``path`` is a JSON file of the execution format (a cheap look, for the
    command line to pick its reader)."""
    try:
        with Path(path).open() as handle:
            head = handle.read(4096)
    except OSError:
        return False
    return f'"format": "{EXECUTION_FORMAT}"' in head


def read_execution(path: str | Path) -> dict[str, Any]:
    """Read an ``execution.json`` and check its format.

    Raises:
        ConfigError: Not a readable execution file.
    """
    return read_json(path, EXECUTION_FORMAT, "execution file")
