"""Robot model: a robot TOML (CONTRACT §1) loaded into Pinocchio and Coal.

The arm joints are OMPL's state space; the hand joints follow the hand law. Both map
into Pinocchio's configuration vector ``q`` through :attr:`Robot.arm_idx` and
:attr:`Robot.hand_idx`.
"""

from __future__ import annotations

import hashlib
import os
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from openup_ompl import _toml
from openup_ompl._io import write_atomic
from openup_ompl._resources import data_dir, erd_share_dir, resolve_path
from openup_ompl.exceptions import ConfigError, FrameNotFound, JointNotFound, RobotNotFound
from openup_ompl.hand_law import HandLaw

#: Tolerance [rad or m] when checking a configuration against joint limits.
LIMIT_TOLERANCE = 1e-9


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
        srdf=None
        if srdf is None
        else resolve_path(_toml.string(srdf, f"{where}: mount.srdf"), base, f"{where}: mount.srdf"),
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
        mga: Normalised distance of maximum grip aperture, in (0, 1].
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
        """Read and validate a robot TOML file (CONTRACT §1)."""
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
            srdf=None
            if srdf is None
            else resolve_path(_toml.string(srdf, f"{where}: srdf"), path.parent, f"{where}: srdf"),
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
                low=1e-9,
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
    """Shipped robot files by name."""
    return {path.stem: path for path in sorted(data_dir("robots").glob("*.toml"))}


def find_robot_file(name_or_path: str | Path, relative_to: Path | None = None) -> Path:
    """A shipped robot name (``"panda"``) or a path to a robot TOML."""
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


@dataclass(eq=False)
class Robot:
    """A robot loaded into Pinocchio (kinematics) and Coal (collision geometry).

    Attributes:
        spec: The robot file's contents.
        model: Pinocchio kinematic model.
        collision_model: Robot collision geometries (meshes as convex hulls if
            ``spec.convex``), with self-collision pairs pruned by the SRDF.
        package_dirs: Directories used to resolve ``package://`` mesh URIs.
        urdf: The URDF describing the whole robot: ``spec.urdf``, or for a robot with a
            ``[mount]`` the merged URDF the loader wrote (what plan files name).
        urdf_mimic: Followers from the URDF's ``<mimic>`` tags (joints not listed in the
            robot file whose leader chain ends at a driven hand joint).
        srdf: The SRDF of the self-collision pairs left out: ``spec.srdf``, or for a robot
            with a ``[mount]`` the merged SRDF the loader wrote (arm and hand SRDFs, the
            mount adjacency, ``mount.disable_collisions``).
        arm_idx: Indices in ``q`` of the arm joints, in ``spec.arm_joints`` order.
        hand_idx: Indices in ``q`` of the hand joints: the driven ones in
            ``spec.hand_joints`` order, then the mimic followers in :attr:`mimic` order.
        hand_joints: Names of the joints of :attr:`hand_idx`.
        mimic: Every follower (the ``[mimic]`` table, then URDF tags).
        arm_v_idx: Indices in the velocity vector ``v`` (Jacobian columns) of the arm joints.
        palm_frame_id: Pinocchio frame index of the palm frame.
    """

    spec: RobotSpec
    model: pin.Model
    collision_model: pin.GeometryModel
    package_dirs: list[str]
    urdf: Path | None = None
    srdf: Path | None = None
    urdf_mimic: tuple[MimicSpec, ...] = ()
    arm_idx: np.ndarray = field(init=False)
    hand_idx: np.ndarray = field(init=False)
    hand_joints: tuple[str, ...] = field(init=False)
    mimic: tuple[MimicSpec, ...] = field(init=False)
    arm_v_idx: np.ndarray = field(init=False)
    palm_frame_id: int = field(init=False)

    def __post_init__(self) -> None:
        if self.urdf is None:
            self.urdf = self.spec.urdf
            self.srdf = self.spec.srdf
        listed = set(self.spec.arm_joints) | set(self.spec.hand_joints)
        followers = {m.joint: m for m in self.urdf_mimic if m.joint not in listed}
        followers.update({m.joint: m for m in self.spec.mimic})
        self.mimic = tuple(followers.values())
        for mimic in self.mimic:
            if not self.model.existJointName(mimic.leader):
                raise JointNotFound(mimic.leader, list(self.model.names)[1:])
        self.hand_joints = (*self.spec.hand_joints, *(m.joint for m in self.mimic))
        self.arm_idx = self._joint_indices(self.spec.arm_joints)
        self.hand_idx = self._joint_indices(self.hand_joints)
        driven = list(self.spec.hand_joints)
        self._leader = np.array([driven.index(m.leader) for m in self.mimic], dtype=np.intp)
        self._multiplier = np.array([m.multiplier for m in self.mimic], dtype=float)
        self._offset = np.array([m.offset for m in self.mimic], dtype=float)
        self.arm_v_idx = np.array(
            [self.model.joints[self.model.getJointId(n)].idx_v for n in self.spec.arm_joints],
            dtype=np.intp,
        )
        self.palm_frame_id = frame_id(self.model, self.spec.palm_frame)
        self.check_arm(self.spec.home, "home")

    @property
    def n_driven(self) -> int:
        """Number of driven hand joints (the length of ``c``, ``b``, ``w``)."""
        return len(self.spec.hand_joints)

    def expand_hand(self, driven: np.ndarray) -> np.ndarray:
        """Driven hand values (last axis, ``spec.hand_joints`` order) with the followers
        appended (:attr:`hand_joints` order): ``q_f = multiplier * q_leader + offset``."""
        driven = np.asarray(driven, dtype=float)
        if driven.shape[-1] != self.n_driven:
            raise ConfigError(
                "hand configuration", driven.tolist(), f"{self.n_driven} driven hand joint values"
            )
        followers = driven[..., self._leader] * self._multiplier + self._offset
        return np.concatenate([driven, followers], axis=-1)

    def _joint_indices(self, names: tuple[str, ...]) -> np.ndarray:
        indices = []
        for name in names:
            if not self.model.existJointName(name):
                raise JointNotFound(name, list(self.model.names)[1:])
            joint = self.model.joints[self.model.getJointId(name)]
            if joint.nq != 1 or joint.nv != 1:
                raise ConfigError(
                    f"{self.spec.path.name}: joint {name}",
                    joint.shortname(),
                    "a one-degree-of-freedom revolute or prismatic joint",
                )
            indices.append(joint.idx_q)
        return np.array(indices, dtype=np.intp)

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def arm_lower(self) -> np.ndarray:
        """Arm joint lower limits [rad or m]."""
        return self.model.lowerPositionLimit[self.arm_idx].copy()

    @property
    def arm_upper(self) -> np.ndarray:
        """Arm joint upper limits [rad or m]."""
        return self.model.upperPositionLimit[self.arm_idx].copy()

    @property
    def joint_names(self) -> list[str]:
        """Every joint with a configuration, in Pinocchio's ``q`` order."""
        joints = sorted(
            (self.model.joints[i].idx_q, self.model.names[i])
            for i in range(1, self.model.njoints)
            if self.model.joints[i].nq > 0
        )
        return [name for _, name in joints]

    def neutral(self) -> np.ndarray:
        """Pinocchio's neutral configuration (joints outside arm and hand stay there)."""
        return pin.neutral(self.model)

    def full_q(self, arm: np.ndarray, hand: np.ndarray) -> np.ndarray:
        """The full configuration ``q`` from arm and hand joint values."""
        q = self.neutral()
        q[self.arm_idx] = arm
        hand = np.asarray(hand, dtype=float)
        q[self.hand_idx] = self.expand_hand(hand) if hand.size == self.n_driven else hand
        return q

    def hand_law(
        self,
        table: Mapping[str, Any] | None = None,
        *,
        where: str = "hand",
        **overrides: object,
    ) -> HandLaw:
        """The robot's hand law (its ``[hand]`` table) with fields overridden by ``table``
        (e.g. a scene's ``[hand]``) and then by ``overrides``; ``None`` values are ignored.

        ``c``, ``b``, ``w`` (and overrides of them given for the driven joints only) are
        expanded to the mimic followers: Algorithm 3 is an affine combination of them with
        weights summing to one, so a follower set by the law stays ``multiplier * leader +
        offset`` (up to clipping on each joint's own limits).

        Raises:
            ConfigError: An unknown field or a bad value, located at ``where.key``.
        """
        fields: dict[str, Any] = {
            "c": self.expand_hand(self.spec.c),
            "b": self.expand_hand(self.spec.b),
            "w": self.expand_hand(self.spec.w),
            "u": self.spec.u,
            "mga": self.spec.mga,
        }
        changes = {**(table or {}), **overrides}
        for key in ("c", "b", "w"):
            value = changes.get(key)
            if value is None or isinstance(value, str):
                continue
            size = np.size(value)  # type: ignore[arg-type]
            if size == self.n_driven:
                changes[key] = self.expand_hand(np.asarray(value, dtype=float))
            elif size != self.hand_idx.size:
                raise ConfigError(
                    f"{where}.{key}", value, f"{self.n_driven} values, one per driven hand joint"
                )
        fields.update({k: v for k, v in changes.items() if v is not None})
        lower = self.model.lowerPositionLimit[self.hand_idx]
        upper = self.model.upperPositionLimit[self.hand_idx]
        return HandLaw.from_table(fields, lower, upper, where)

    def check_arm(self, arm: np.ndarray, what: str) -> np.ndarray:
        """Validate an arm configuration: right length, finite, inside the joint limits."""
        arm = np.asarray(arm, dtype=float)
        n = self.arm_idx.size
        if arm.shape != (n,) or not np.all(np.isfinite(arm)):
            raise ConfigError(what, arm.tolist(), f"{n} finite arm joint values [rad]")
        low, high = self.arm_lower, self.arm_upper
        outside = (arm < low - LIMIT_TOLERANCE) | (arm > high + LIMIT_TOLERANCE)
        if np.any(outside):
            i = int(np.flatnonzero(outside)[0])
            raise ConfigError(
                f"{what}: joint {self.spec.arm_joints[i]}",
                float(arm[i]),
                f"a value within its limits [{low[i]:.4g}, {high[i]:.4g}]",
            )
        return arm

    def palm_placement(self, data: pin.Data, q: np.ndarray) -> pin.SE3:
        """World placement of the palm frame at ``q`` (writes into ``data``)."""
        pin.forwardKinematics(self.model, data, q)
        return pin.updateFramePlacement(self.model, data, self.palm_frame_id)


def frame_id(model: pin.Model, name: str) -> int:
    """Index of the frame ``name``; the BODY frame when several frames share the name
    (e.g. a link and a joint both called ``gripperStator``)."""
    matches = [f for f in model.frames if f.name == name]
    if not matches:
        raise FrameNotFound(name, [f.name for f in model.frames])
    if len(matches) > 1 and any(f.type == pin.FrameType.BODY for f in matches):
        return int(model.getFrameId(name, pin.FrameType.BODY))
    return int(model.getFrameId(name, matches[0].type))


def _convex_hulls(geometry_model: pin.GeometryModel) -> None:
    """Replace every mesh by its convex hull (qhull): conservative, about 2x faster."""
    for geometry in geometry_model.geometryObjects:
        shape = geometry.geometry
        if isinstance(shape, coal.BVHModelBase):
            shape.buildConvexHull(True, "Qt")
            geometry.geometry = shape.convex


def cache_dir() -> Path:
    """Where the loader writes merged URDFs: ``$OPENUP_OMPL_CACHE``, else
    ``$XDG_CACHE_HOME/openup-ompl``, else ``~/.cache/openup-ompl``."""
    if os.environ.get("OPENUP_OMPL_CACHE"):
        return Path(os.environ["OPENUP_OMPL_CACHE"]).expanduser()
    root = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(root).expanduser() / "openup-ompl"


def _write_cached(text: str, stem: str, suffix: str) -> Path:
    """Write ``text`` to the cache under a content-hashed name (atomic, reused)."""
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    path = cache_dir() / f"{stem}-{digest}{suffix}"
    if not path.is_file():
        write_atomic(path, text)
    return path


def _urdf_tree(path: Path, where: str) -> ET.Element:
    try:
        return ET.parse(path).getroot()
    except (OSError, ET.ParseError) as error:
        raise ConfigError(where, str(path), f"a readable URDF ({error})") from None


def _urdf_mimic(root: ET.Element) -> tuple[MimicSpec, ...]:
    """The ``<mimic>`` tags of a URDF, as follower specs."""
    specs = []
    for joint in root.iter("joint"):
        tag = joint.find("mimic")
        if tag is not None and joint.get("name") and tag.get("joint"):
            specs.append(
                MimicSpec(
                    joint=str(joint.get("name")),
                    leader=str(tag.get("joint")),
                    multiplier=float(tag.get("multiplier", 1.0)),
                    offset=float(tag.get("offset", 0.0)),
                )
            )
    return tuple(specs)


def _resolve_chains(mimic: tuple[MimicSpec, ...], driven: tuple[str, ...]) -> tuple[MimicSpec, ...]:
    """URDF followers whose leader chain ends at a driven joint, composed to that joint."""
    by_joint = {m.joint: m for m in mimic}
    resolved = []
    for spec in mimic:
        leader, mult, off, seen = spec.leader, spec.multiplier, spec.offset, {spec.joint}
        while leader not in driven and leader in by_joint and leader not in seen:
            seen.add(leader)
            up = by_joint[leader]
            leader, mult, off = up.leader, mult * up.multiplier, mult * up.offset + off
        if leader in driven:
            resolved.append(MimicSpec(spec.joint, leader, mult, off))
    return tuple(resolved)


def _absolute_meshes(root: ET.Element, urdf: Path, package_dirs: list[str]) -> None:
    """Rewrite ``package://`` and relative mesh file names as absolute paths."""
    for mesh in root.iter("mesh"):
        name = mesh.get("filename", "")
        if name.startswith("package://"):
            rest = name[len("package://") :]
            for base in package_dirs:
                if (Path(base) / rest).is_file():
                    mesh.set("filename", str((Path(base) / rest).resolve()))
                    break
        elif name.startswith("file://"):
            mesh.set("filename", name[len("file://") :])
        elif name and not Path(name).is_absolute():
            mesh.set("filename", str((urdf.parent / name).resolve()))


def _prefix_names(root: ET.Element, prefix: str) -> None:
    """Prefix every link and joint name (and the references to them) of a URDF or SRDF."""
    if not prefix:
        return
    for element in root.iter():
        if element.tag in ("link", "joint") and element.get("name"):
            element.set("name", prefix + str(element.get("name")))
        if element.tag in ("parent", "child") and element.get("link"):
            element.set("link", prefix + str(element.get("link")))
        if element.tag == "mimic" and element.get("joint"):
            element.set("joint", prefix + str(element.get("joint")))
        if element.tag == "disable_collisions":
            for key in ("link1", "link2"):
                element.set(key, prefix + str(element.get(key)))


def _root_link(root: ET.Element) -> str:
    children = {c.get("link") for c in root.iter("child")}
    links = [
        str(link.get("name")) for link in root.findall("link") if link.get("name") not in children
    ]
    return links[0]


def _merged_urdf(
    spec: RobotSpec, mount: MountSpec, arm_model: pin.Model, package_dirs: list[str]
) -> tuple[Path, Path, Path | None]:
    """Write the merged URDF (and the prefixed hand URDF/SRDF) to the cache.

    Returns:
        The merged URDF, the hand URDF to load, the hand SRDF to apply.
    """
    where = f"{spec.path.name}: mount"
    arm = _urdf_tree(spec.urdf, f"{spec.path.name}: urdf")
    hand = _urdf_tree(mount.urdf, f"{where}.urdf")
    _prefix_names(hand, mount.prefix)
    hand_urdf, hand_srdf = mount.urdf, mount.srdf
    if mount.prefix:
        hand_abs = ET.fromstring(ET.tostring(hand))
        _absolute_meshes(hand_abs, mount.urdf, [*package_dirs, str(mount.urdf.parent)])
        hand_urdf = _write_cached(ET.tostring(hand_abs, encoding="unicode"), "hand", ".urdf")
        if mount.srdf is not None:
            srdf = _urdf_tree(mount.srdf, f"{where}.srdf")
            _prefix_names(srdf, mount.prefix)
            hand_srdf = _write_cached(ET.tostring(srdf, encoding="unicode"), "hand", ".srdf")
    _absolute_meshes(arm, spec.urdf, package_dirs)
    _absolute_meshes(hand, mount.urdf, [*package_dirs, str(mount.urdf.parent)])
    arm_names = {e.get("name") for e in arm if e.tag in ("link", "joint")}
    clash = sorted(
        str(e.get("name"))
        for e in hand
        if e.tag in ("link", "joint") and e.get("name") in arm_names
    )
    if clash:
        raise ConfigError(f"{where}.prefix", mount.prefix, f"a prefix making {clash[0]!r} unique")
    # The link the hand is fixed to: the frame itself if a link, else a joint's child link.
    parent_frame = arm_model.frames[frame_id(arm_model, mount.frame)]
    links = {e.get("name") for e in arm.findall("link")}
    if mount.frame in links:
        parent_link = mount.frame
    else:
        joint = next(j for j in arm.findall("joint") if j.get("name") == parent_frame.name)
        parent_link = str(joint.find("child").get("link"))  # type: ignore[union-attr]
    placement = pin.XYZQUATToSE3(mount.pose)
    rpy = pin.rpy.matrixToRpy(placement.rotation)
    fixed = ET.SubElement(arm, "joint", {"name": f"{mount.prefix}openup_mount", "type": "fixed"})
    ET.SubElement(fixed, "parent", {"link": parent_link})
    ET.SubElement(fixed, "child", {"link": _root_link(hand)})
    ET.SubElement(
        fixed,
        "origin",
        {
            "xyz": " ".join(repr(float(x)) for x in placement.translation),
            "rpy": " ".join(repr(float(x)) for x in rpy),
        },
    )
    materials = {e.get("name") for e in arm.findall("material")}
    for element in hand:
        if element.tag in ("link", "joint") or (
            element.tag == "material" and element.get("name") not in materials
        ):
            arm.append(element)
    arm.set("name", spec.name)
    merged = _write_cached(ET.tostring(arm, encoding="unicode"), spec.name, ".urdf")
    return merged, hand_urdf, hand_srdf


def _build(urdf: Path, package_dirs: list[str], where: str) -> tuple[pin.Model, pin.GeometryModel]:
    try:
        model = pin.buildModelFromUrdf(str(urdf))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            collision = pin.buildGeomFromUrdf(
                model, str(urdf), pin.COLLISION, package_dirs=package_dirs
            )
    except (RuntimeError, ValueError) as error:
        raise ConfigError(where, str(urdf), f"a loadable URDF ({error})") from None
    return model, collision


def _merged_srdf(
    spec: RobotSpec, mount: MountSpec, hand_srdf: Path | None, pairs: list[tuple[str, str]]
) -> Path:
    """Write one SRDF holding the arm's and the hand's disabled pairs plus ``pairs``."""
    merged = ET.Element("robot", {"name": spec.name})
    for srdf, where in ((spec.srdf, "srdf"), (hand_srdf, "mount.srdf")):
        if srdf is not None:
            root = _urdf_tree(srdf, f"{spec.path.name}: {where}")
            merged.extend(root.iter("disable_collisions"))
    for a, b in pairs:
        ET.SubElement(merged, "disable_collisions", {"link1": a, "link2": b, "reason": "Never"})
    return _write_cached(ET.tostring(merged, encoding="unicode"), spec.name, ".srdf")


def load_robot(name_or_path: str | Path = "panda") -> Robot:
    """Load a robot by shipped name (``"panda"``) or from the path of a robot TOML.

    A robot with a ``[mount]`` is composed with ``pinocchio.appendModel``: the hand's
    model and geometry fixed to the arm's ``mount.frame`` at ``mount.pose``. Its
    collision pairs are every pair of geometries on different joints, minus the arm's
    and the hand's SRDF pairs, the pair (the arm link holding ``mount.frame``, the
    hand's root link) and ``mount.disable_collisions``. A merged URDF with the same
    kinematics is written to :func:`cache_dir` for plan files.

    Raises:
        RobotNotFound: No robot of that name and no such file.
        ConfigError: The file holds a bad value (named in the message).
        JointNotFound, FrameNotFound: The file names a joint or frame the URDF lacks.
    """
    spec = RobotSpec.from_file(find_robot_file(name_or_path))
    srdf = spec.srdf
    package_dirs = [str(erd_share_dir()), str(spec.urdf.parent), str(spec.urdf.parent.parent)]
    model, collision = _build(spec.urdf, package_dirs, f"{spec.path.name}: urdf")
    urdf = spec.urdf
    mount = spec.mount
    if mount is not None:
        for extra in (mount.urdf.parent, mount.urdf.parent.parent):
            if str(extra) not in package_dirs:
                package_dirs.append(str(extra))
        if not any(f.name == mount.frame for f in model.frames):
            raise FrameNotFound(mount.frame, [f.name for f in model.frames])
        urdf, hand_urdf, hand_srdf = _merged_urdf(spec, mount, model, package_dirs)
        hand_model, hand_collision = _build(
            hand_urdf, package_dirs, f"{spec.path.name}: mount.urdf"
        )
        hand_root = hand_model.frames[1].name
        mount_id = frame_id(model, mount.frame)
        body = model.frames[mount_id]
        while body.type != pin.FrameType.BODY and body.parentFrame != 0:
            body = model.frames[body.parentFrame]
        model, collision = pin.appendModel(
            model, hand_model, collision, hand_collision, mount_id, pin.XYZQUATToSE3(mount.pose)
        )
        collision.removeAllCollisionPairs()
        if spec.convex:
            _convex_hulls(collision)
        collision.addAllCollisionPairs()
        frames = {f.name for f in model.frames}
        for pair in mount.disable_collisions:
            for name in pair:
                if name not in frames:
                    raise FrameNotFound(name, sorted(frames))
        srdf = _merged_srdf(
            spec, mount, hand_srdf, [(body.name, hand_root), *mount.disable_collisions]
        )
        pin.removeCollisionPairs(model, collision, str(srdf))
    else:
        if spec.convex:
            _convex_hulls(collision)
        collision.addAllCollisionPairs()
        if spec.srdf is not None:
            pin.removeCollisionPairs(model, collision, str(spec.srdf))
    mimic = _resolve_chains(
        _urdf_mimic(_urdf_tree(urdf, f"{spec.path.name}: urdf")), spec.hand_joints
    )
    return Robot(
        spec=spec,
        model=model,
        collision_model=collision,
        package_dirs=package_dirs,
        urdf=urdf,
        srdf=srdf,
        urdf_mimic=mimic,
    )
