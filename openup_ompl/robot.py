"""Robot model: a robot TOML (CONTRACT §1) loaded into Pinocchio and Coal.

The arm joints are OMPL's state space; the hand joints follow the hand law. Both map
into Pinocchio's configuration vector ``q`` through :attr:`Robot.arm_idx` and
:attr:`Robot.hand_idx`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin

from openup_ompl import _toml
from openup_ompl._resources import data_dir, erd_share_dir, resolve_path
from openup_ompl.exceptions import ConfigError, FrameNotFound, JointNotFound, RobotNotFound
from openup_ompl.hand_law import HandLaw

#: Tolerance [rad or m] when checking a configuration against joint limits.
LIMIT_TOLERANCE = 1e-9


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
        arm_joints: OMPL's state space, in this order.
        hand_joints: Joints set by the hand law, in the order of ``c``, ``b``, ``w``.
        home: Arm configuration [rad] used when a scene gives no start.
        c: Close preshape (hand-joint order).
        b: Base open configuration.
        w: Widest opening.
        mga: Normalised distance of maximum grip aperture, in (0, 1].
        u: Default pose uncertainty in [0, 1].
        convex: Replace collision meshes by their convex hulls (faster, conservative).
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
            arm_joints=tuple(arm),
            hand_joints=tuple(hand),
            home=_toml.vector(_toml.require(raw, "home", where), f"{where}: home", len(arm)),
            c=_toml.vector(_toml.require(table, "c", f"{where}: hand"), f"{where}: hand.c", n),
            b=_toml.vector(_toml.require(table, "b", f"{where}: hand"), f"{where}: hand.b", n),
            w=_toml.vector(_toml.require(table, "w", f"{where}: hand"), f"{where}: hand.w", n),
            mga=_toml.number(
                _toml.require(table, "mga", f"{where}: hand"),
                f"{where}: hand.mga",
                low=1e-9,
                high=1.0,
            ),
            u=_toml.number(table.get("u", 0.0), f"{where}: hand.u", low=0.0, high=1.0),
            convex=convex,
        )


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
        arm_idx: Indices in ``q`` of the arm joints, in ``spec.arm_joints`` order.
        hand_idx: Indices in ``q`` of the hand joints, in ``spec.hand_joints`` order.
        arm_v_idx: Indices in the velocity vector ``v`` (Jacobian columns) of the arm joints.
        palm_frame_id: Pinocchio frame index of the palm frame.
    """

    spec: RobotSpec
    model: pin.Model
    collision_model: pin.GeometryModel
    package_dirs: list[str]
    arm_idx: np.ndarray = field(init=False)
    hand_idx: np.ndarray = field(init=False)
    arm_v_idx: np.ndarray = field(init=False)
    palm_frame_id: int = field(init=False)

    def __post_init__(self) -> None:
        self.arm_idx = self._joint_indices(self.spec.arm_joints)
        self.hand_idx = self._joint_indices(self.spec.hand_joints)
        self.arm_v_idx = np.array(
            [self.model.joints[self.model.getJointId(n)].idx_v for n in self.spec.arm_joints],
            dtype=np.intp,
        )
        if not self.model.existFrame(self.spec.palm_frame):
            raise FrameNotFound(self.spec.palm_frame, [f.name for f in self.model.frames])
        self.palm_frame_id = self.model.getFrameId(self.spec.palm_frame)
        self.check_arm(self.spec.home, "home")

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
        q[self.hand_idx] = hand
        return q

    def hand_law(self, **overrides: object) -> HandLaw:
        """The robot's hand law (its ``[hand]`` table), with fields overridden."""
        fields: dict[str, object] = {
            "c": self.spec.c,
            "b": self.spec.b,
            "w": self.spec.w,
            "u": self.spec.u,
            "mga": self.spec.mga,
            "lower": self.model.lowerPositionLimit[self.hand_idx],
            "upper": self.model.upperPositionLimit[self.hand_idx],
        }
        fields.update({k: v for k, v in overrides.items() if v is not None})
        return HandLaw(**fields)  # type: ignore[arg-type]

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


def _convex_hulls(geometry_model: pin.GeometryModel) -> None:
    """Replace every mesh by its convex hull (qhull): conservative, about 2x faster."""
    for geometry in geometry_model.geometryObjects:
        shape = geometry.geometry
        if isinstance(shape, coal.BVHModelBase):
            shape.buildConvexHull(True, "Qt")
            geometry.geometry = shape.convex


def load_robot(name_or_path: str | Path = "panda") -> Robot:
    """Load a robot by shipped name (``"panda"``) or from the path of a robot TOML.

    Raises:
        RobotNotFound: No robot of that name and no such file.
        ConfigError: The file holds a bad value (named in the message).
        JointNotFound, FrameNotFound: The file names a joint or frame the URDF lacks.
    """
    spec = RobotSpec.from_file(find_robot_file(name_or_path))
    package_dirs = [str(erd_share_dir()), str(spec.urdf.parent), str(spec.urdf.parent.parent)]
    try:
        model = pin.buildModelFromUrdf(str(spec.urdf))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            collision = pin.buildGeomFromUrdf(
                model, str(spec.urdf), pin.COLLISION, package_dirs=package_dirs
            )
    except (RuntimeError, ValueError) as error:
        raise ConfigError(
            f"{spec.path.name}: urdf", str(spec.urdf), f"a loadable URDF ({error})"
        ) from None
    if spec.convex:
        _convex_hulls(collision)
    collision.addAllCollisionPairs()
    if spec.srdf is not None:
        pin.removeCollisionPairs(model, collision, str(spec.srdf))
    return Robot(spec=spec, model=model, collision_model=collision, package_dirs=package_dirs)
