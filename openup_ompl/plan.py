"""Plans: the result of a solve, and the plan file (README, Files: Plan).

The file's schema is one table, :data:`PLAN_FIELDS`: each key's writer (from a
:class:`Plan`) beside its reader (into a :class:`PlanFile`). :mod:`~openup_ompl.plan_checks`
checks a path against its own robot and law.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl import _toml
from openup_ompl._io import json_with_rows, read_json, write_atomic
from openup_ompl._model import frame_id, q_indices
from openup_ompl.exceptions import ConfigError, FrameNotFound
from openup_ompl.hand_law import HandLaw
from openup_ompl.plan_checks import (
    GRASP_POSITION_TOLERANCE,
    GRASP_ROTATION_TOLERANCE,
    HAND_TOLERANCE,
    LIMIT_TOLERANCE,
    MIN_START_PALM_DISTANCE,
    check_ends,
    check_hand,
    number_rows,
    path_within_limits,
)
from openup_ompl.scene import Problem, Shape, check_unique_names
from openup_ompl.urdf import urdf_model

__all__ = [
    "GRASP_POSITION_TOLERANCE",
    "GRASP_ROTATION_TOLERANCE",
    "HAND_TOLERANCE",
    "LIMIT_TOLERANCE",
    "MIN_START_PALM_DISTANCE",
    "PLAN_FIELDS",
    "PLAN_FORMAT",
    "Plan",
    "PlanFile",
    "number_rows",
    "read_plan",
]

PLAN_FORMAT = "openup-plan/1"


@dataclass(eq=False)
class Plan:
    """A collision-free reach-to-grasp plan.

    Attributes:
        path: ``(N, nq)`` full configurations (arm and hand) in Pinocchio's ``q`` order,
            no robot point moving more than the checker's resolution between rows (the
            arm motion between them checked exactly), the hand set by the law at every
            row. Row 0 is the start; the last row puts the palm on the grasp pose.
        waypoints: ``(M, dof)`` the planner's arm waypoints (simplified), which ``path`` joins.
        status: OMPL's planner status, as text.
        planner: Planner name.
        seed: Seed of the run.
        solve_time_s: Planning time [s] (simplification excluded).
        problem: The problem solved.
        law: The hand law the plan follows.
        start_palm_distance: Palm-to-grasp distance at the start [m] (D's denominator).
        stats: Counters of the run (validity checks, IK calls, ...).
    """

    path: np.ndarray
    waypoints: np.ndarray
    status: str
    planner: str
    seed: int | None
    solve_time_s: float
    problem: Problem
    law: HandLaw
    start_palm_distance: float
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def arm_path(self) -> np.ndarray:
        """``(N, dof)`` arm joint values of :attr:`path`."""
        return self.path[:, self.problem.robot.arm_idx]

    @property
    def hand_path(self) -> np.ndarray:
        """``(N, hand dof)`` hand joint values of :attr:`path`."""
        return self.path[:, self.problem.robot.hand_idx]

    def to_dict(self) -> dict[str, Any]:
        """The plan file's contents (README, Files: Plan).

        Returns:
            Its keys in :data:`PLAN_FIELDS` order, JSON values (lengths [m], angles [rad]).
        """
        return {spec.key: spec.write(self) for spec in PLAN_FIELDS}

    def save(self, path: str | Path) -> Path:
        """Write the plan file (JSON, README, Files: Plan), atomically.

        Args:
            path: The file to write (a :class:`~openup_ompl.exceptions.ConfigError` if a directory).
        Returns:
            ``path``, as a ``Path``.
        """
        if not isinstance(path, (str, os.PathLike)) or Path(path).is_dir():
            raise ConfigError("plan file", path, "a path to a file to write")
        path = Path(path)
        if not np.all(np.isfinite(self.path)):
            raise ConfigError("plan path", "non-finite values", "a finite path")
        return write_atomic(path, json_with_rows(self.to_dict(), ("path", "waypoints")))


def read_plan(path: str | Path) -> dict[str, Any]:
    """Read a plan file and check it whole (:meth:`PlanFile.read`, as ``show`` does).

    Args:
        path: The plan file (JSON).
    Returns:
        Its contents, as :meth:`Plan.to_dict` gives them.
    Raises:
        ConfigError: What :meth:`PlanFile.read` raises.
    """
    return PlanFile.read(path).contents


# -- the plan file's schema: each key's writer beside its reader --------------------


@dataclass(frozen=True)
class _Robot:
    """A plan file's ``robot`` table, read: the URDF's model and the joint groups."""

    urdf: str
    model: pin.Model
    package_dirs: tuple[str, ...]
    palm_frame_id: int
    arm_joints: tuple[str, ...]
    hand_joints: tuple[str, ...]
    arm_idx: np.ndarray
    hand_idx: np.ndarray


#: What a reader is given: the value, its location for errors, the keys read before it.
Reader = Callable[[Any, str, dict[str, Any]], Any]


@dataclass(frozen=True)
class PlanField:
    """One top-level key of the plan file.

    Attributes:
        key: The key.
        write: Its value in the file of a :class:`Plan` (JSON types).
        read: Its value checked and typed, from the file's value, ``where + key`` and the
            keys read before it; ``None``: kept in :attr:`PlanFile.contents` only.
        required: Whether a file must hold it.
    """

    key: str
    write: Callable[[Plan], Any]
    read: Reader | None = None
    required: bool = False


def _table(value: Any, where: str, expected: str) -> dict[str, Any]:
    """``value`` if it is a table, else a ConfigError naming ``where``."""
    if not isinstance(value, dict):
        raise ConfigError(where, value, expected)
    return value


def _urdf_model(urdf: str, where: str = "robot.urdf") -> pin.Model:
    if not Path(urdf).is_file():
        raise ConfigError(where, urdf, "an existing URDF file")
    return urdf_model(urdf, where)


def _write_robot(plan: Plan) -> dict[str, Any]:
    robot = plan.problem.robot
    spec = robot.spec
    return {
        "name": spec.name,
        "file": str(spec.path),
        "urdf": str(robot.urdf),
        "srdf": None if robot.srdf is None else str(robot.srdf),
        "package_dirs": list(robot.package_dirs),
        "palm_frame": spec.palm_frame,
        "joint_names": robot.joint_names,
        "arm_joints": list(spec.arm_joints),
        "hand_joints": list(robot.hand_joints),
    }


def _read_robot(value: Any, where: str, _: dict[str, Any]) -> _Robot:
    """The ``robot`` table: a loadable URDF whose joints and palm frame it names."""
    robot = _table(value, where, "a table with urdf, joint_names, palm_frame, ...")
    at = f"{where}."
    urdf = _toml.string(_toml.require(robot, "urdf", where), f"{at}urdf")
    model = _urdf_model(urdf, f"{at}urdf")
    names = [model.names[i] for i in range(1, model.njoints) if model.joints[i].nq > 0]
    if _toml.require(robot, "joint_names", where) != names:
        raise ConfigError(f"{at}joint_names", robot["joint_names"], f"{names} (the URDF's)")
    groups: dict[str, tuple[str, ...]] = {}
    for key in ("arm_joints", "hand_joints"):
        groups[key] = tuple(_toml.string_list(_toml.require(robot, key, where), f"{at}{key}"))
        for joint in groups[key]:
            if joint not in names:
                raise ConfigError(f"{at}{key}", joint, f"one of robot.joint_names {names}")
    shared = sorted(set(groups["arm_joints"]) & set(groups["hand_joints"]))
    if shared:
        raise ConfigError(f"{at}hand_joints", shared[0], "a joint not in robot.arm_joints")
    package_dirs = robot.get("package_dirs") or []
    if not (isinstance(package_dirs, list) and all(isinstance(d, str) for d in package_dirs)):
        raise ConfigError(f"{at}package_dirs", package_dirs, "a list of directories")
    palm = _toml.string(_toml.require(robot, "palm_frame", where), f"{at}palm_frame")
    try:
        palm_frame_id = frame_id(model, palm)
    except FrameNotFound:
        raise ConfigError(f"{at}palm_frame", palm, f"a frame of {urdf}") from None
    return _Robot(
        urdf=urdf,
        model=model,
        package_dirs=tuple(package_dirs),
        palm_frame_id=palm_frame_id,
        arm_joints=groups["arm_joints"],
        hand_joints=groups["hand_joints"],
        arm_idx=q_indices(model, groups["arm_joints"]),
        hand_idx=q_indices(model, groups["hand_joints"]),
    )


def _write_scene(plan: Plan) -> dict[str, Any]:
    scene_object = plan.problem.object
    return {
        "object": None if scene_object is None else scene_object.to_table(),
        "obstacles": [shape.to_table() for shape in plan.problem.obstacles],
    }


def _read_scene(
    value: Any, where: str, _: dict[str, Any]
) -> tuple[tuple[Shape, ...], Shape | None]:
    """The ``scene`` table: its obstacles and its object (or ``None``), named uniquely."""
    scene = _table(value, where, "a table with the object and obstacles")
    raw_obstacles = scene.get("obstacles") or []
    if not isinstance(raw_obstacles, list):
        raise ConfigError(f"{where}.obstacles", raw_obstacles, "a list of shape tables")
    obstacles = tuple(
        Shape.from_table(table, f"{where}.obstacles[{i}]") for i, table in enumerate(raw_obstacles)
    )
    raw_object = scene.get("object")
    shape = None
    if raw_object is not None:
        shape = Shape.from_table(raw_object, f"{where}.object", is_object=True)
    check_unique_names(obstacles, shape, f"{where}: obstacle name")
    return obstacles, shape


def _write_law(plan: Plan) -> dict[str, Any]:
    return {**plan.law.to_dict(), "start_palm_distance": plan.start_palm_distance}


def _read_law(value: Any, where: str, read: dict[str, Any]) -> tuple[HandLaw, float | None]:
    """The ``hand_law`` table: the law, the start's palm distance [m] (or ``None``)."""
    table = _table(value, where, "a table with c, b, w, u, mga")
    robot: _Robot = read["robot"]
    law = HandLaw.from_table(
        table,
        robot.model.lowerPositionLimit[robot.hand_idx],
        robot.model.upperPositionLimit[robot.hand_idx],
        where,
        ignore=("start_palm_distance",),
    )
    start_distance = None
    if table.get("start_palm_distance") is not None:
        start_distance = _toml.number(
            table["start_palm_distance"],
            f"{where}.start_palm_distance",
            low=MIN_START_PALM_DISTANCE,
        )
    return law, start_distance


def _read_seed(value: Any, where: str, _: dict[str, Any]) -> int | None:
    if value is not None and (isinstance(value, bool) or not isinstance(value, (int, np.integer))):
        raise ConfigError(where, value, "an integer or null")
    return None if value is None else int(value)


#: The plan file's top-level keys, in the order they are written.
PLAN_FIELDS: tuple[PlanField, ...] = (
    PlanField("format", lambda plan: PLAN_FORMAT),
    PlanField("status", lambda plan: plan.status, lambda v, at, _: _toml.string(v, at)),
    PlanField("planner", lambda plan: plan.planner, lambda v, at, _: _toml.string(v, at)),
    PlanField("seed", lambda plan: plan.seed, _read_seed),
    PlanField(
        "solve_time_s",
        lambda plan: plan.solve_time_s,
        lambda v, at, _: _toml.number(v, at, low=0.0),
    ),
    PlanField("robot", _write_robot, _read_robot, required=True),
    PlanField("scene", _write_scene, _read_scene, required=True),
    PlanField(
        "start",
        lambda plan: plan.problem.start.tolist(),
        lambda v, at, read: _toml.vector(v, at, len(read["robot"].arm_joints)),
    ),
    PlanField(
        "grasp_pose",
        lambda plan: plan.problem.grasp_pose.tolist(),
        lambda v, at, _: _toml.pose(v, at),
        required=True,
    ),
    PlanField("hand_law", _write_law, _read_law, required=True),
    PlanField("waypoints", lambda plan: plan.waypoints.tolist()),
    PlanField("stats", lambda plan: plan.stats),
    PlanField(
        "path",
        lambda plan: plan.path.tolist(),
        lambda v, at, read: path_within_limits(v, at, read["robot"].model),
        required=True,
    ),
)


def _read_fields(data: dict[str, Any], where: str) -> dict[str, Any]:
    """The readable keys of :data:`PLAN_FIELDS`, read (optional, absent: ``None``)."""
    read: dict[str, Any] = {}
    for spec in PLAN_FIELDS:
        if spec.read is None:
            continue
        if spec.key in data:
            read[spec.key] = spec.read(data[spec.key], f"{where}{spec.key}", read)
        elif spec.required:
            raise ConfigError(f"{where}{spec.key}", None, "a value (the key is missing)")
        else:
            read[spec.key] = None
    return read


@dataclass(frozen=True, eq=False)
class PlanFile:
    """A plan as a plan file holds it, typed and checked: robot, law, shapes, path. Read
    from the file and the URDF it names alone (:meth:`read`: no scene or robot TOML
    needed to replay or draw it), or made from a :class:`Plan` (:meth:`from_plan`).

    Attributes:
        name: A short name for titles (the plan file's stem).
        planner: The planner's name.
        seed: Seed of the run, or ``None``.
        status: OMPL's planner status, as text.
        urdf: The URDF of the whole robot.
        package_dirs: Directories resolving its ``package://`` mesh URIs.
        model: Pinocchio model built from :attr:`urdf`.
        hand_joints: Hand joint names, in the law's order.
        hand_idx: Indices in ``q`` of the hand joints, in the law's order.
        palm_frame_id: Pinocchio frame index of the palm frame.
        law: The hand law the plan followed (limits from :attr:`model`).
        grasp_pose: Palm frame target ``[x, y, z, qx, qy, qz, qw]`` (world frame).
        path: ``(N, nq)`` full configurations.
        obstacles: The scene's obstacles.
        object: The object to grasp, or ``None``.
        contents: The file's contents as read (JSON types), for physics and execution records.
    """

    name: str
    planner: str
    seed: int | None
    status: str
    urdf: Path
    package_dirs: tuple[str, ...]
    model: pin.Model
    hand_joints: tuple[str, ...]
    hand_idx: np.ndarray
    palm_frame_id: int
    law: HandLaw
    grasp_pose: np.ndarray
    path: np.ndarray
    obstacles: tuple[Shape, ...]
    object: Shape | None
    contents: dict[str, Any] = field(repr=False)

    @classmethod
    def read(cls, path: str | Path) -> PlanFile:
        """Read a plan file, check it (:meth:`from_dict`) and load its robot's model.

        Args:
            path: The plan file (JSON).
        Returns:
            The plan file, named after the file's stem.
        Raises:
            ConfigError: The file is not a readable ``openup-plan/1`` file, or what
                :meth:`from_dict` raises, located at ``<file name>: <key>``.
        """
        data = read_json(path, PLAN_FORMAT, "plan file")
        path = Path(path)
        return cls.from_dict(data, path.stem, where=f"{path.name}: ")

    @classmethod
    def from_dict(cls, data: dict[str, Any], name: str = "plan", where: str = "") -> PlanFile:
        """Check a plan file's contents (as :meth:`Plan.to_dict` gives them), load its
        robot's model: the one check of every reader (``show``, ``execute``, physics).

        Args:
            data: The contents.
            name: A short name for titles.
            where: Prefix of error locations (e.g. ``"plan.json: "``).
        Returns:
            The plan file (:attr:`contents` is ``data`` itself).
        Raises:
            ConfigError: At ``where + key``, a key missing or a bad value: a robot table
                naming joints or a frame its URDF lacks, an unloadable URDF, a bad law,
                shape or grasp pose, a path row of the wrong width, non-finite or beyond a
                limit by over :data:`LIMIT_TOLERANCE`, a path not from ``start`` or not
                ending at ``grasp_pose`` (:data:`GRASP_POSITION_TOLERANCE`,
                :data:`GRASP_ROTATION_TOLERANCE`), a hand off the law
                (:data:`HAND_TOLERANCE`), ``start_palm_distance`` under the minimum.
        """
        if not isinstance(data, dict):
            raise ConfigError(where.rstrip(": .") or "plan", data, "a plan (a JSON object)")
        read = _read_fields(data, where)
        robot: _Robot = read["robot"]
        law, start_distance = read["hand_law"]
        obstacles, shape = read["scene"]
        path, grasp_pose = read["path"], read["grasp_pose"]
        model, palm = robot.model, robot.palm_frame_id
        check_ends(path, read["start"], robot.arm_idx, model, palm, grasp_pose, where)
        check_hand(
            path,
            law,
            start_distance,
            model,
            robot.hand_idx,
            robot.hand_joints,
            palm,
            grasp_pose,
            where,
        )
        return cls(
            name=name,
            planner=data.get("planner", "plan"),
            seed=read["seed"],
            status=data.get("status", ""),
            urdf=Path(robot.urdf),
            package_dirs=robot.package_dirs,
            model=model,
            hand_joints=robot.hand_joints,
            hand_idx=robot.hand_idx,
            palm_frame_id=palm,
            law=law,
            grasp_pose=grasp_pose,
            path=path,
            obstacles=obstacles,
            object=shape,
            contents=data,
        )

    @classmethod
    def from_plan(cls, plan: Plan, name: str = "plan") -> PlanFile:
        """What the plan file of ``plan`` would hold, without writing and re-reading it:
        its law, shapes and path as they are; the model built from the robot's URDF.

        Args:
            plan: A plan; ``name``: a short name for titles.
        Returns:
            The plan file, :attr:`contents` as :meth:`Plan.to_dict` gives them.
        """
        robot = plan.problem.robot
        model = _urdf_model(str(robot.urdf))
        hand_idx = q_indices(model, tuple(robot.hand_joints))
        return cls(
            name=name,
            planner=plan.planner,
            seed=plan.seed,
            status=plan.status,
            urdf=Path(str(robot.urdf)),
            package_dirs=tuple(str(p) for p in robot.package_dirs),
            model=model,
            hand_joints=tuple(robot.hand_joints),
            hand_idx=hand_idx,
            palm_frame_id=frame_id(model, robot.spec.palm_frame),
            law=plan.law,
            grasp_pose=plan.problem.grasp_pose,
            path=plan.path,
            obstacles=tuple(plan.problem.obstacles),
            object=plan.problem.object,
            contents=plan.to_dict(),
        )

    @property
    def grasp(self) -> pin.SE3:
        """Grasp pose of the palm frame as a Pinocchio ``SE3`` (world frame)."""
        return pin.XYZQUATToSE3(self.grasp_pose)
