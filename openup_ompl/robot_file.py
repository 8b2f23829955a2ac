"""Robot files (see the file formats): the TOML format read into a :class:`RobotSpec`.

Only reading and checking: loading the URDF is :mod:`openup_ompl.urdf`, the loaded model
:mod:`openup_ompl.robot`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from openup_ompl import _toml
from openup_ompl._resources import data_dir, resolve_path
from openup_ompl.exceptions import ConfigError, RobotNotFound
from openup_ompl.hand_law import MGA_MIN


@dataclass(frozen=True)
class MimicSpec:
    """A follower joint driven by a hand joint: ``q_f = multiplier * q_leader + offset``.

    Attributes:
        joint: The follower joint (not in ``arm_joints`` nor ``hand_joints``).
        leader: The driven hand joint it follows (one of ``hand_joints``).
        multiplier: Ratio of follower to leader motion.
        offset: Follower value [rad or m] when the leader is at zero.
    """

    joint: str
    leader: str
    multiplier: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class MountSpec:
    """A second URDF (the hand) fixed to a frame of the robot's URDF (the arm).

    Attributes:
        urdf: Resolved hand URDF.
        srdf: Resolved hand SRDF (self-collision pruning), or ``None``.
        frame: Frame of the arm model the hand is fixed to.
        pose: The hand URDF's root frame in ``frame``: ``[x, y, z, qx, qy, qz, qw]``.
        prefix: Added to the hand's joint, link and geometry names.
        disable_collisions: Extra link pairs never checked for collision.
    """

    urdf: Path
    srdf: Path | None
    frame: str
    pose: np.ndarray
    prefix: str = ""
    disable_collisions: tuple[tuple[str, str], ...] = ()


def _srdf_path(raw: Any, base: Path, where: str) -> Path | None:
    """An SRDF path resolved against ``base``, or ``None``: pinocchio reads an SRDF only
    from a file named ``*.srdf``."""
    if raw is None:
        return None
    path = resolve_path(_toml.string(raw, where), base, where)
    if path.suffix != ".srdf":
        raise ConfigError(where, raw, "an SRDF file, its name ending in .srdf")
    return path


def _mount_spec(raw: Any, where: str, base: Path) -> MountSpec:
    if not isinstance(raw, dict):
        raise ConfigError(f"{where}: mount", raw, "a [mount] table")
    known = {"urdf", "srdf", "frame", "pose", "prefix", "disable_collisions"}
    _toml.check_keys(raw, known, f"{where}: mount")
    srdf = raw.get("srdf")
    prefix = raw.get("prefix", "")
    if not isinstance(prefix, str):
        raise ConfigError(f"{where}: mount.prefix", prefix, "a string")
    pairs = raw.get("disable_collisions", [])
    ok = isinstance(pairs, list) and all(
        isinstance(p, list) and len(p) == 2 and all(isinstance(x, str) for x in p) for p in pairs
    )
    if not ok:
        raise ConfigError(
            f"{where}: mount.disable_collisions", pairs, "a list of [link, link] name pairs"
        )
    return MountSpec(
        urdf=resolve_path(
            _toml.string(_toml.require(raw, "urdf", f"{where}: mount"), f"{where}: mount.urdf"),
            base,
            f"{where}: mount.urdf",
        ),
        srdf=_srdf_path(srdf, base, f"{where}: mount.srdf"),
        frame=_toml.string(_toml.require(raw, "frame", f"{where}: mount"), f"{where}: mount.frame"),
        pose=_toml.pose(_toml.require(raw, "pose", f"{where}: mount"), f"{where}: mount.pose"),
        prefix=prefix,
        disable_collisions=tuple((a, b) for a, b in pairs),
    )


def _mimic_specs(raw: Any, where: str, arm: list[str], hand: list[str]) -> tuple[MimicSpec, ...]:
    if not isinstance(raw, dict):
        raise ConfigError(f"{where}: mimic", raw, "a [mimic] table of follower = {joint = ...}")
    specs = []
    for follower, entry in raw.items():
        key = f"{where}: mimic.{follower}"
        if follower in arm or follower in hand:
            raise ConfigError(key, follower, "a follower not listed in arm_joints or hand_joints")
        if not isinstance(entry, dict):
            raise ConfigError(key, entry, "{ joint = LEADER, multiplier = M, offset = O }")
        _toml.check_keys(entry, {"joint", "multiplier", "offset"}, key)
        leader = _toml.string(_toml.require(entry, "joint", key), f"{key}.joint")
        if leader not in hand:
            raise ConfigError(f"{key}.joint", leader, f"a driven hand joint, one of {hand}")
        specs.append(
            MimicSpec(
                joint=follower,
                leader=leader,
                multiplier=_toml.number(entry.get("multiplier", 1.0), f"{key}.multiplier"),
                offset=_toml.number(entry.get("offset", 0.0), f"{key}.offset"),
            )
        )
    return tuple(specs)


@dataclass(frozen=True)
class RobotSpec:
    """The contents of a robot TOML file, validated but not yet loaded into Pinocchio.

    Attributes:
        name: Robot name.
        description: One line for listings.
        path: The TOML file.
        urdf: Resolved URDF path.
        srdf: Resolved SRDF path, or ``None`` (no self-collision pruning).
        palm_frame: Frame whose world pose is the grasp pose.
        approach: Unit vector, in the palm frame, of the direction the palm moves in
            to reach the grasp (towards the object); IKBiRRT's goal tree retreats
            against it (:attr:`~openup_ompl.planners.ikbirrt.IKBiRRTOptions.retreat`).
            Default: the palm frame's ``z`` axis.
        arm_joints: OMPL's state space, in this order.
        hand_joints: Joints set by the hand law, in the order of ``c``, ``b``, ``w``.
        home: Arm configuration [rad] used when a scene gives no start.
        c: Close preshape (hand-joint order).
        b: Base open configuration.
        w: Widest opening.
        mga: Normalised distance of maximum grip aperture, in [MGA_MIN, 1] (0.01).
        u: Default pose uncertainty in [0, 1].
        closed: The configuration each hand joint closes towards when grasping
            (:mod:`~openup_ompl.grasp`), or ``None``: the joint limit on ``c``'s side of
            ``w`` (a joint with ``c == w`` stays).
        closing_speed: Relative closing speed of each hand joint, in fractions of its
            joint range per unit of closing progress (default: 1 for every joint).
        torsion: Soft-finger torsional friction [m] of the fingers' pads for the grasp
            test (:func:`~openup_ompl.grasp.force_closure`); 0: point contacts.
        convex: Replace collision meshes by their convex hulls (faster, conservative).
        padding: Extra clearance [m] the robot keeps from obstacles and object (not
            applied to self-collision).
        mount: A hand URDF fixed to a frame of ``urdf``, or ``None``.
        mimic: Follower joints of the ``[mimic]`` table (URDF ``<mimic>`` tags are added
            when the robot is loaded).
    """

    name: str
    description: str
    path: Path
    urdf: Path
    srdf: Path | None
    palm_frame: str
    arm_joints: tuple[str, ...]
    hand_joints: tuple[str, ...]
    home: np.ndarray
    c: np.ndarray
    b: np.ndarray
    w: np.ndarray
    mga: float
    u: float = 0.0
    convex: bool = True
    padding: float = 0.0
    mount: MountSpec | None = None
    mimic: tuple[MimicSpec, ...] = ()
    closed: np.ndarray | None = None
    closing_speed: np.ndarray | None = None
    torsion: float = 0.0
    approach: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))

    @classmethod
    def from_file(cls, path: Path) -> RobotSpec:
        """Read and validate a robot TOML file (see the file formats).

        Args:
            path: The robot TOML file.

        Returns:
            The validated spec (not yet loaded into Pinocchio).
        """
        path = Path(path).resolve()
        raw = _toml.read_toml(path, "robot file")
        where = path.name
        arm = _toml.string_list(_toml.require(raw, "arm_joints", where), f"{where}: arm_joints")
        hand = _toml.string_list(_toml.require(raw, "hand_joints", where), f"{where}: hand_joints")
        if set(arm) & set(hand):
            raise ConfigError(f"{where}: hand_joints", hand, "joints not also in arm_joints")
        table = _toml.require(raw, "hand", where)
        if not isinstance(table, dict):
            raise ConfigError(f"{where}: hand", table, "a [hand] table")
        n = len(hand)
        known = {
            "name", "description", "urdf", "srdf", "palm_frame", "approach", "arm_joints",
            "hand_joints", "home", "convex", "padding", "hand", "mount", "mimic",
        }  # fmt: skip
        _toml.check_keys(raw, known, f"{where}: ")
        hand_keys = {"c", "b", "w", "mga", "u", "closed", "closing_speed", "torsion"}
        _toml.check_keys(table, hand_keys, f"{where}: hand")
        srdf = raw.get("srdf")
        convex = raw.get("convex", True)
        if not isinstance(convex, bool):
            raise ConfigError(f"{where}: convex", convex, "true or false")
        return cls(
            name=_toml.string(_toml.require(raw, "name", where), f"{where}: name"),
            description=str(raw.get("description", "")),
            path=path,
            urdf=resolve_path(
                _toml.string(_toml.require(raw, "urdf", where), f"{where}: urdf"),
                path.parent,
                f"{where}: urdf",
            ),
            srdf=_srdf_path(srdf, path.parent, f"{where}: srdf"),
            palm_frame=_toml.string(
                _toml.require(raw, "palm_frame", where), f"{where}: palm_frame"
            ),
            approach=_unit_vector(raw.get("approach", [0.0, 0.0, 1.0]), f"{where}: approach"),
            arm_joints=tuple(arm),
            hand_joints=tuple(hand),
            home=_toml.vector(_toml.require(raw, "home", where), f"{where}: home", len(arm)),
            **{
                key: _toml.vector(
                    _toml.require(table, key, f"{where}: hand"),
                    f"{where}: hand.{key} (one value per hand joint)",
                    n,
                )
                for key in ("c", "b", "w")
            },
            mga=_toml.number(
                _toml.require(table, "mga", f"{where}: hand"),
                f"{where}: hand.mga",
                low=MGA_MIN,
                high=1.0,
            ),
            u=_toml.number(table.get("u", 0.0), f"{where}: hand.u", low=0.0, high=1.0),
            convex=convex,
            padding=_toml.number(raw.get("padding", 0.0), f"{where}: padding", low=0.0),
            mount=None if "mount" not in raw else _mount_spec(raw["mount"], where, path.parent),
            mimic=_mimic_specs(raw.get("mimic", {}), where, arm, hand),
            closed=None
            if "closed" not in table
            else _toml.vector(
                table["closed"], f"{where}: hand.closed (one value per hand joint)", n
            ),
            closing_speed=None
            if "closing_speed" not in table
            else _closing_speed(table["closing_speed"], f"{where}: hand.closing_speed", n),
            torsion=_toml.number(
                table.get("torsion", 0.0), f"{where}: hand.torsion", low=0.0, high=0.1
            ),
        )


def _unit_vector(raw: Any, where: str) -> np.ndarray:
    vector = _toml.vector(raw, where, 3)
    norm = float(np.linalg.norm(vector))
    if not norm > 1e-9:
        raise ConfigError(where, vector.tolist(), "a non-zero 3-vector (the palm's approach)")
    return vector / norm


def _closing_speed(raw: Any, where: str, n: int) -> np.ndarray:
    speed = _toml.vector(raw, f"{where} (one value per hand joint)", n)
    if np.any(speed <= 0) or np.any(speed > 1):
        raise ConfigError(where, raw, "relative speeds in (0, 1]")
    return speed


def available_robots() -> dict[str, Path]:
    """Shipped robot files by name.

    Returns:
        Robot name -> robot TOML path, for every shipped robot.
    """
    return {path.stem: path for path in sorted(data_dir("robots").glob("*.toml"))}


def find_robot_file(name_or_path: str | Path, relative_to: Path | None = None) -> Path:
    """A shipped robot name (``"panda"``) or a path to a robot TOML.

    Args:
        name_or_path: A shipped robot's name or a path to a robot TOML.
        relative_to: The directory a relative path is read from (a scene file's).

    Returns:
        The robot TOML's path.
    """
    text = str(name_or_path)
    robots = available_robots()
    if text in robots:
        return robots[text]
    path = Path(text).expanduser()
    if relative_to is not None and not path.is_absolute():
        path = relative_to / path
    if path.suffix == ".toml" and path.is_file():
        return path.resolve()
    raise RobotNotFound(text, list(robots))
