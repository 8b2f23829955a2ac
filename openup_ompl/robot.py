"""Robot model: a robot file (see the file formats) loaded into Pinocchio and Coal.

The arm joints are OMPL's state space; the hand joints follow the hand law. Both map
into Pinocchio's configuration vector ``q`` through :attr:`Robot.arm_idx` and
:attr:`Robot.hand_idx`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl import _toml
from openup_ompl._model import frame_id
from openup_ompl._mount import mount_hand
from openup_ompl._resources import erd_share_dir
from openup_ompl.exceptions import ConfigError, JointNotFound
from openup_ompl.hand_law import REFERENCE_TOLERANCE, HandLaw
from openup_ompl.robot_file import (
    MimicSpec,
    MountSpec,
    RobotSpec,
    available_robots,
    find_robot_file,
)
from openup_ompl.urdf import (
    _build,
    _convex_hulls,
    _resolve_chains,
    cache_dir,
    remove_srdf_pairs,
    urdf_mimic,
)

#: Also importable from here (their old home): the file format, the cache, frame lookup.
__all__ = [
    "LIMIT_TOLERANCE",
    "MimicSpec",
    "MountSpec",
    "Robot",
    "RobotSpec",
    "available_robots",
    "cache_dir",
    "find_robot_file",
    "frame_id",
    "load_robot",
]

#: Tolerance [rad or m] when checking a configuration against joint limits.
LIMIT_TOLERANCE = 1e-9


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
        self._check_palm_frame()
        self._check_held_joints()
        self.check_arm(self.spec.home, f"{self.spec.path.name}: home")
        self._check_hand_references()

    def _palm_chain(self) -> list[str]:
        """The joints that move the palm frame, from the palm towards the root."""
        chain = []
        joint = self.model.frames[self.palm_frame_id].parentJoint
        while joint != 0:
            chain.append(self.model.names[joint])
            joint = self.model.parents[joint]
        return chain

    def _check_palm_frame(self) -> None:
        """The palm frame must be moved by an arm joint and by no hand joint: IK and the
        law's palm distance place it with the arm alone, the rest of ``q`` neutral (a
        palm the arm does not move made every grasp "out of reach after 200 IK
        restarts")."""
        chain = self._palm_chain()
        where = f"{self.spec.path.name}: palm_frame"
        if not set(chain) & set(self.spec.arm_joints):
            moved_by = f"moved only by {chain}" if chain else "fixed to the world"
            raise ConfigError(
                where,
                self.spec.palm_frame,
                f"a frame moved by at least one of arm_joints (this one is {moved_by})",
            )
        by_hand = [name for name in chain if name in self.hand_joints]
        if by_hand:
            raise ConfigError(
                where,
                self.spec.palm_frame,
                f"a frame no hand joint moves (this one is moved by {by_hand[0]})",
            )

    def _check_held_joints(self) -> None:
        """A joint in neither ``arm_joints`` nor ``hand_joints`` (nor a mimic follower) is
        held at its neutral value: refuse it when that lies outside its limits (every plan
        would then be refused by ``show`` and ``execute``). The message gives the remedy:
        ``arm_joints`` for a joint that moves the palm, else ``hand_joints`` or a
        ``[mimic]`` entry of multiplier 0 holding it at its offset."""
        listed = {*self.spec.arm_joints, *self.hand_joints}
        neutral = pin.neutral(self.model)
        low, high = self.model.lowerPositionLimit, self.model.upperPositionLimit
        for j in range(1, self.model.njoints):
            name, joint = self.model.names[j], self.model.joints[j]
            if name in listed or joint.nq != 1:
                continue
            i = joint.idx_q
            if low[i] - LIMIT_TOLERANCE <= neutral[i] <= high[i] + LIMIT_TOLERANCE:
                continue
            if name in self._palm_chain():
                remedy = "list it in arm_joints (it moves the palm frame)"
            else:
                remedy = (
                    f'list it in hand_joints, or hold it with a [mimic] entry "{name}" ='
                    f' {{ joint = "{self.spec.hand_joints[0]}", multiplier = 0.0,'
                    f" offset = <a value in [{low[i]:.6g}, {high[i]:.6g}]> }}"
                )
            raise ConfigError(
                f"{self.spec.path.name}: joint {name}",
                float(neutral[i]),
                f"a value within its limits [{low[i]:.6g}, {high[i]:.6g}] for a joint in"
                f" neither arm_joints nor hand_joints, held at {neutral[i]:g}: {remedy}",
            )

    def _check_hand_references(self) -> None:
        """The robot file's ``c``, ``b``, ``w`` and ``closed`` within the hand joints'
        limits: checked here, where the limits are known, so that the message names the
        robot file and the joints at fault rather than a scene that did not set them."""
        where = f"{self.spec.path.name}: hand"
        for key in ("c", "b", "w"):
            self.check_hand(getattr(self.spec, key), f"{where}.{key}")
        if self.spec.closed is not None:
            self.check_hand(self.spec.closed, f"{where}.closed", followers=False)

    def check_hand(self, driven: np.ndarray, what: str, *, followers: bool = True) -> None:
        """Check driven hand values against the joints' limits (to
        :data:`~openup_ompl.hand_law.REFERENCE_TOLERANCE`), and, if ``followers``, the mimic
        followers they set.

        Args:
            driven: Driven hand joint values [rad or m].
            what: How to name them in an error (e.g. ``"hand.c"``).
            followers: Also check the mimic followers they set.

        Raises:
            ConfigError: Naming ``what``, the driven values and every joint outside its
                limits (a follower with its mimic relation).
        """
        n = self.n_driven
        values = self.expand_hand(driven) if followers else np.asarray(driven, dtype=float)
        low = self.model.lowerPositionLimit[self.hand_idx][: values.size]
        high = self.model.upperPositionLimit[self.hand_idx][: values.size]
        outside = (values < low - REFERENCE_TOLERANCE) | (values > high + REFERENCE_TOLERANCE)
        faults = []
        for k in np.flatnonzero(outside):
            joint = self.hand_joints[k]
            if k >= n:
                m = self.mimic[k - n]
                source = "[mimic]" if m in self.spec.mimic else "the URDF's <mimic>"
                joint += f" (set by {source} to {m.multiplier:g} * {m.leader} + {m.offset:g})"
            faults.append(f"{joint} = {values[k]:.6g} outside [{low[k]:.6g}, {high[k]:.6g}]")
        if faults:
            raise ConfigError(
                what,
                np.asarray(driven, dtype=float).tolist(),
                f"values within the hand joints' limits ({'; '.join(faults)})",
            )

    @property
    def n_driven(self) -> int:
        """Number of driven hand joints (the length of ``c``, ``b``, ``w``)."""
        return len(self.spec.hand_joints)

    def expand_hand(self, driven: np.ndarray) -> np.ndarray:
        """Driven hand values (last axis, ``spec.hand_joints`` order) with the followers
        appended (:attr:`hand_joints` order): ``q_f = multiplier * q_leader + offset``.

        Args:
            driven: Driven hand joint values [rad or m], last axis ``spec.hand_joints``.

        Returns:
            The values of every hand joint [rad or m], followers last.
        """
        driven = np.asarray(driven, dtype=float)
        if driven.ndim == 0 or driven.shape[-1] != self.n_driven:
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
        """The robot's name (the robot file's ``name``)."""
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
        """Pinocchio's neutral configuration (joints outside arm and hand stay there).

        Returns:
            The neutral ``q`` [rad or m], ``(nq,)``.
        """
        return pin.neutral(self.model)

    def full_q(self, arm: np.ndarray, hand: np.ndarray) -> np.ndarray:
        """The full configuration ``q`` from arm joint values and hand joint values: the
        driven ones (:attr:`n_driven`, the followers computed) or all of
        :attr:`hand_joints` (followers included, as given).

        Args:
            arm: Arm joint values [rad or m].
            hand: Driven or all hand joint values [rad or m].

        Returns:
            The full configuration ``(nq,)`` in Pinocchio's order.

        Raises:
            ConfigError: ``arm`` or ``hand`` of another length.
        """
        arm = np.asarray(arm, dtype=float)
        if arm.shape != self.arm_idx.shape:
            raise ConfigError("arm", arm.tolist(), f"{self.arm_idx.size} arm joint values")
        hand = np.asarray(hand, dtype=float)
        if hand.shape not in ((self.n_driven,), self.hand_idx.shape):
            raise ConfigError(
                "hand",
                hand.tolist(),
                f"{self.n_driven} driven hand joint values or {self.hand_idx.size} with the "
                "followers",
            )
        q = self.neutral()
        q[self.arm_idx] = arm
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

        Args:
            table: Field name -> value overriding the robot's ``[hand]``.
            where: Prefix of error locations.
            **overrides: Further fields (e.g. ``u=0.3``).

        Returns:
            The law, with ``c``, ``b``, ``w`` over every hand joint.

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
        if table is not None and not isinstance(table, Mapping):
            raise ConfigError(where, table, "a [hand] table (field name -> value)")
        changes = {**(table or {}), **overrides}
        for key in ("c", "b", "w"):
            value = changes.get(key)
            if value is None or isinstance(value, str):
                continue
            try:
                size = np.size(value)  # type: ignore[arg-type]
            except ValueError:  # ragged
                raise ConfigError(f"{where}.{key}", value, "a list of numbers") from None
            if size == self.n_driven:
                try:
                    numbers = np.asarray(value, dtype=float)
                except (TypeError, ValueError):
                    raise ConfigError(f"{where}.{key}", value, "a list of numbers") from None
                self.check_hand(numbers, f"{where}.{key}")
                changes[key] = self.expand_hand(numbers)
            elif size != self.hand_idx.size:
                raise ConfigError(
                    f"{where}.{key}", value, f"{self.n_driven} values, one per driven hand joint"
                )
        fields.update({k: v for k, v in changes.items() if v is not None})
        lower = self.model.lowerPositionLimit[self.hand_idx]
        upper = self.model.upperPositionLimit[self.hand_idx]
        return HandLaw.from_table(fields, lower, upper, where)

    def check_arm(self, arm: np.ndarray, what: str) -> np.ndarray:
        """Validate an arm configuration: right length, finite, inside the joint limits.

        Args:
            arm: Arm joint values [rad or m].
            what: How to name them in an error.

        Returns:
            ``arm`` as a float array ``(dof,)``.

        Raises:
            ConfigError: Naming ``what`` (and the joint beyond its limits).
        """
        n = self.arm_idx.size
        values = _toml.floats(arm)
        if values is None or values.shape != (n,) or not np.all(np.isfinite(values)):
            raise ConfigError(what, _toml.shown(arm), f"{n} finite arm joint values [rad]")
        arm = values
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
        """World placement of the palm frame at ``q`` (writes into ``data``).

        Args:
            data: Pinocchio data of this robot's model (scratch).
            q: Full configuration [rad or m].

        Returns:
            The palm frame's placement (world frame, metres).
        """
        pin.forwardKinematics(self.model, data, q)
        return pin.updateFramePlacement(self.model, data, self.palm_frame_id)


def load_robot(name_or_path: str | Path = "panda") -> Robot:
    """Load a robot by shipped name (``"panda"``) or from the path of a robot TOML.

    A robot with a ``[mount]`` is composed with ``pinocchio.appendModel``: the hand's
    model and geometry fixed to the arm's ``mount.frame`` at ``mount.pose``. Its
    collision pairs are every pair of geometries on different joints, minus the arm's
    and the hand's SRDF pairs, the pair (the arm link holding ``mount.frame``, the
    hand's root link) and ``mount.disable_collisions``. A merged URDF with the same
    kinematics is written to :func:`cache_dir` for plan files.

    Args:
        name_or_path: A shipped robot's name or a robot TOML's path.

    Returns:
        The loaded :class:`Robot` (Pinocchio model and geometry, spec).

    Raises:
        RobotNotFound: No robot of that name and no such file.
        ConfigError: The file holds a bad value (named in the message), or its URDF or
            SRDF is not one pinocchio can load.
        JointNotFound, FrameNotFound: The file names a joint or frame the URDF lacks.
    """
    spec = RobotSpec.from_file(find_robot_file(name_or_path))
    srdf = spec.srdf
    package_dirs = [str(erd_share_dir()), str(spec.urdf.parent), str(spec.urdf.parent.parent)]
    model, collision, urdf_root = _build(spec.urdf, package_dirs, f"{spec.path.name}: urdf")
    urdf = spec.urdf
    if spec.mount is not None:
        model, collision, urdf, urdf_root, srdf = mount_hand(
            spec, spec.mount, model, collision, urdf_root, package_dirs
        )
    else:
        if spec.convex:
            _convex_hulls(model, collision, spec.path.name)
        collision.addAllCollisionPairs()
        if spec.srdf is not None:
            remove_srdf_pairs(model, collision, spec.srdf, f"{spec.path.name}: srdf")
    mimic = _resolve_chains(urdf_mimic(urdf_root), spec.hand_joints)
    return Robot(
        spec=spec,
        model=model,
        collision_model=collision,
        package_dirs=package_dirs,
        urdf=urdf,
        srdf=srdf,
        urdf_mimic=mimic,
    )
