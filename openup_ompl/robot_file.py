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
from openup_ompl._io import resolved
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


#: Shapes a contact pad may take, and the size keys of each.
PAD_SHAPES = {"box": ("size",), "capsule": ("radius", "length"), "sphere": ("radius",)}
#: The largest pad extent [m] (a finger pad, not a table).
PAD_MAX = 0.2


@dataclass(frozen=True)
class PadSpec:
    """A contact pad: physics-only contact geometry on a robot link (``[[physics.pads]]``).

    In the physics world a pad meets the object and the movable obstacles; the link's URDF
    collision geometries that contain the pad's centre meet only the fixed obstacles
    there (planning keeps the URDF's geometry throughout).

    Attributes:
        link: The link (a URDF link name) the pad is fixed to.
        shape: ``"box"``, ``"capsule"`` or ``"sphere"``.
        pose: ``[x, y, z, qx, qy, qz, qw]`` of its centre in the link frame.
        size: A box's full sides [m].
        radius: A capsule's or sphere's radius [m].
        length: A capsule's cylinder length [m] along its local z.
        friction: Sliding friction of the pad's contacts (``None``: the object's rules).
        timeconst: Contact time constant [s] (MuJoCo ``solref[0]``; ``None``: the
            object's).
        solimp: MuJoCo ``solimp`` of its contacts (``None``: the object's).
    """

    link: str
    shape: str
    pose: np.ndarray
    size: np.ndarray | None = None
    radius: float | None = None
    length: float | None = None
    friction: float | None = None
    timeconst: float | None = None
    solimp: tuple[float, ...] | None = None


def _pad_spec(raw: Any, where: str) -> PadSpec:
    if not isinstance(raw, dict):
        raise ConfigError(where, raw, "a pad table { link, shape, pose, size or radius, ... }")
    shape = _toml.string(_toml.require(raw, "shape", where), f"{where}.shape")
    if shape not in PAD_SHAPES:
        raise ConfigError(f"{where}.shape", shape, f"one of {sorted(PAD_SHAPES)}")
    keys = PAD_SHAPES[shape]
    _toml.check_keys(
        raw, {"link", "shape", "pose", "friction", "timeconst", "solimp", *keys}, where
    )
    dims: dict[str, Any] = {}
    if "size" in keys:
        size = _toml.vector(_toml.require(raw, "size", where), f"{where}.size", 3)
        if np.any(size <= 0) or np.any(size > PAD_MAX):
            raise ConfigError(f"{where}.size", size.tolist(), f"sides in (0, {PAD_MAX:g}] m")
        dims["size"] = size
    for key in ("radius", "length"):
        if key in keys:
            dims[key] = _toml.number(_toml.require(raw, key, where), f"{where}.{key}",
                                     low=1e-4, high=PAD_MAX)  # fmt: skip
    solimp = raw.get("solimp")
    if solimp is not None:
        values = _toml.vector(solimp, f"{where}.solimp")
        if not (len(values) in (3, 5) and 0 < values[0] <= values[1] < 1 and values[2] > 0):
            raise ConfigError(f"{where}.solimp", solimp, "[d0, dwidth, width (, mid, power)],"
                              " 0 < d0 <= dwidth < 1, width > 0 [m]")  # fmt: skip
        solimp = tuple(float(v) for v in values)
    return PadSpec(
        link=_toml.string(_toml.require(raw, "link", where), f"{where}.link"),
        shape=shape,
        pose=_toml.pose(_toml.require(raw, "pose", where), f"{where}.pose"),
        friction=None if raw.get("friction") is None
        else _toml.number(raw["friction"], f"{where}.friction", low=0.0, high=10.0),
        timeconst=None if raw.get("timeconst") is None
        else _toml.number(raw["timeconst"], f"{where}.timeconst", low=1e-4, high=1.0),
        solimp=solimp,
        **dims,
    )  # fmt: skip


def _physics(raw: Any, where: str) -> tuple[PadSpec, ...]:
    """The ``[physics]`` table: its ``pads``."""
    if not isinstance(raw, dict):
        raise ConfigError(f"{where}: physics", raw, "a [physics] table")
    _toml.check_keys(raw, {"pads"}, f"{where}: physics")
    pads = raw.get("pads", [])
    if not isinstance(pads, list):
        raise ConfigError(f"{where}: physics.pads", pads, "a list of pad tables")
    return tuple(_pad_spec(p, f"{where}: physics.pads[{i}]") for i, p in enumerate(pads))


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
        pads: Physics-only contact pads (``[physics] pads``), or none: the URDF's
            collision geometry makes every contact in physics too.
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
    pads: tuple[PadSpec, ...] = ()

    @classmethod
    def from_file(cls, path: Path) -> RobotSpec:
        """Read and validate a robot TOML file (see the file formats).

        Args:
            path: The robot TOML file.

        Returns:
            The validated spec (not yet loaded into Pinocchio).
        """
        path = resolved(path, "robot file")
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
            "hand_joints", "home", "convex", "padding", "hand", "mount", "mimic", "physics",
        }  # fmt: skip
        _toml.check_keys(raw, known, f"{where}: ")
        hand_keys = {"c", "b", "w", "mga", "u", "closed", "closing_speed", "torsion"}
        _toml.check_keys(table, hand_keys, f"{where}: hand")
        srdf = raw.get("srdf")
        convex = raw.get("convex", True)
        if not isinstance(convex, bool):
            raise ConfigError(f"{where}: convex", convex, "true or false")
        description = raw.get("description", "")
        if not isinstance(description, str):
            raise ConfigError(f"{where}: description", description, "a string")
        return cls(
            name=_toml.string(_toml.require(raw, "name", where), f"{where}: name"),
            description=description,
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
            pads=_physics(raw["physics"], where) if "physics" in raw else (),
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
