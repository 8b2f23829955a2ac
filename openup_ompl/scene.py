"""Scene files (see the file formats): robot, start, grasp pose, hand law, object and
obstacles. Every table rejects keys it does not know, naming the nearest valid one."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin

from openup_ompl import _toml
from openup_ompl._io import resolved
from openup_ompl._resources import data_dir
from openup_ompl.exceptions import ConfigError
from openup_ompl.hand_law import TABLE_FIELDS, HandLaw
from openup_ompl.robot import Robot, find_robot_file, load_robot
from openup_ompl.shape import (
    MIN_EXTENT,
    MIN_MASS,
    OBJECT_FRICTION,
    OBJECT_MASS,
    SHAPE_KEYS,
    SHAPES,
    Shape,
)

__all__ = [
    "GRASP_KEYS",
    "MIN_EXTENT",
    "MIN_MASS",
    "OBJECT_FRICTION",
    "OBJECT_MASS",
    "SCENE_KEYS",
    "SCENE_LAW_FIELDS",
    "SHAPES",
    "SHAPE_KEYS",
    "Problem",
    "Shape",
    "check_object_clear",
    "check_unique_names",
    "default_scene_path",
    "demo_scene_path",
    "load_scene",
]

#: The keys of a scene file's top level and of its ``[grasp]`` table.
#: ``[camera]`` is the simulated depth camera's (:mod:`openup_ompl.perception`, which
#: validates it when it looks).
SCENE_KEYS = ("robot", "start", "grasp", "hand", "object", "obstacles", "camera")
GRASP_KEYS = ("pose",)
#: The hand-law fields a scene's ``[hand]`` may override (the fixed preshape is a planning
#: option, not part of a scene).
SCENE_LAW_FIELDS = tuple(name for name in TABLE_FIELDS if name != "fixed")


@dataclass(eq=False)
class Problem:
    """A reach-to-grasp problem: everything a planner needs, loaded and validated.

    Attributes:
        robot: The loaded robot.
        start: Start arm configuration [rad].
        grasp_pose: Palm frame target ``[x, y, z, qx, qy, qz, qw]`` in the world frame.
        hand_law: The hand law with the scene's overrides applied.
        obstacles: Fixed obstacles.
        object: The object to grasp (collides like an obstacle), or ``None``.
        path: The scene file, if loaded from one.
    """

    robot: Robot
    start: np.ndarray
    grasp_pose: np.ndarray
    hand_law: HandLaw
    obstacles: list[Shape]
    object: Shape | None = None
    path: Path | None = None

    def __post_init__(self) -> None:
        """Check what a problem built in code (or by ``dataclasses.replace``) holds, as
        :func:`load_scene` checks a file: a start of finite arm joint values (its joint
        limits are the setup's check: :class:`~openup_ompl.exceptions.InvalidProblem`),
        a grasp pose with a unit quaternion (normalised), a hand law of the robot's hand,
        a list (or tuple, stored as a list) of :class:`Shape` obstacles and an optional
        :class:`Shape` object, all named apart (:func:`check_unique_names`).

        Raises:
            ConfigError: Naming the field (``problem.start``, ``problem.obstacles[2]``, ...).
        """
        if not isinstance(self.robot, Robot):
            raise ConfigError("problem.robot", self.robot, "a Robot (load_robot)")
        n = self.robot.arm_idx.size
        start = _toml.floats(self.start)
        if start is None or start.shape != (n,) or not np.all(np.isfinite(start)):
            shown = _toml.shown(self.start)
            raise ConfigError("problem.start", shown, f"{n} finite arm joint values")
        self.start = start
        self.grasp_pose = _toml.pose(self.grasp_pose, "problem.grasp_pose")
        law = self.hand_law
        if not isinstance(law, HandLaw):
            raise ConfigError("problem.hand_law", law, "a HandLaw (robot.hand_law())")
        hand = self.robot.hand_idx.size
        if law.c.shape != (hand,):
            raise ConfigError(
                "problem.hand_law", law.c.tolist(), f"a law of the robot's {hand} hand joints"
            )
        if not isinstance(self.obstacles, (list, tuple)):
            raise ConfigError("problem.obstacles", self.obstacles, "a list of Shapes ([] for none)")
        for i, shape in enumerate(self.obstacles):
            if not isinstance(shape, Shape):
                raise ConfigError(f"problem.obstacles[{i}]", shape, "a Shape")
            if shape.mass is not None and not shape.movable:  # as a scene file's
                raise ConfigError(
                    f"problem.obstacles[{i}].mass", shape.mass, "None: a fixed obstacle"
                )
        self.obstacles = list(self.obstacles)
        if self.object is not None and not isinstance(self.object, Shape):
            raise ConfigError("problem.object", self.object, "None or a Shape")
        if self.object is not None and self.object.movable:
            raise ConfigError("problem.object.movable", True, "False: the object is free")
        check_unique_names(self.obstacles, self.object, "problem: obstacle name")

    def source_files(self) -> list[Path]:
        """The files the problem was read from: its scene file (if any), the robot file,
        and the URDF and SRDF files it names (its mounted hand's too). Not the meshes a
        URDF references: finding them means resolving its package URIs, and the shipped
        robots' come from an installed package (example-robot-data) or are primitives.

        Returns:
            Their paths.
        """
        spec = self.robot.spec
        files = [self.path, spec.path, spec.urdf, spec.srdf]
        if spec.mount is not None:
            files += [spec.mount.urdf, spec.mount.srdf]
        return [Path(file) for file in files if file is not None]

    @property
    def grasp(self) -> pin.SE3:
        """Grasp pose of the palm frame as a Pinocchio ``SE3`` (world frame)."""
        return pin.XYZQUATToSE3(self.grasp_pose)

    @property
    def environment(self) -> list[Shape]:
        """Everything the robot must not touch: the obstacles and the object."""
        return [*self.obstacles, *([self.object] if self.object is not None else [])]


def default_scene_path() -> Path:
    """The Panda reaching a can past a wall: the scene of the documentation's examples.

    Returns:
        The path of the shipped ``panda_can.toml``.
    """
    return data_dir("scenes") / "panda_can.toml"


def demo_scene_path() -> Path:
    """The scene ``openup-ompl demo`` plans: the paper's robot (an LWA3-class arm with an
    SDH-class hand) taking a can from the side, its fingers opening by centimetres (the
    Panda's open by millimetres).

    Returns:
        The path of the shipped ``lwa3_sdh_can.toml``.
    """
    return data_dir("scenes") / "lwa3_sdh_can.toml"


def check_unique_names(obstacles: Sequence[Shape], obj: Shape | None, where: str) -> None:
    """Refuse a scene where two shapes (the object included) share a name: collision pairs,
    physics bodies and contact reports are named after them.

    Args:
        obstacles: The scene's obstacles.
        obj: The object, if any.
        where: The scene file, for the message.

    Raises:
        ConfigError: Naming ``where`` and the first repeated name.
    """
    names = [shape.name for shape in obstacles] + ([obj.name] if obj else [])
    duplicate = next((n for n in names if names.count(n) > 1), None)
    if duplicate is not None:
        raise ConfigError(where, duplicate, "names unique within the scene")


#: Radius [m] of the probe at an object's centre in :func:`check_object_clear`.
_CENTRE_PROBE = 1e-6


def check_object_clear(obstacles: Sequence[Shape], obj: Shape | None, where: str) -> None:
    """Refuse an object whose centre lies inside an obstacle (a can placed in the wall,
    or sunk below its table's top: a typed pose, planned for as written). An object may
    overlap an obstacle otherwise: a resting object touches its table, and a perceived
    estimate (``perceived.toml``) tilted by a degree dips a corner of its base up to a
    centimetre into it, which planning must accept.

    Args:
        obstacles: The scene's obstacles.
        obj: The object, if any.
        where: The scene file, for the message.

    Raises:
        ConfigError: Naming ``where``, the object's pose, the obstacle and how deep the
            centre lies in it.
    """
    if obj is None:
        return
    probe = coal.Sphere(_CENTRE_PROBE)
    centre = coal.Transform3s(np.eye(3), obj.placement.translation)
    for shape in obstacles:
        request, result = coal.DistanceRequest(), coal.DistanceResult()
        placement = coal.Transform3s(shape.placement.rotation, shape.placement.translation)
        depth = -coal.distance(probe, centre, shape.geometry(), placement, request, result)
        if depth > 0:
            raise ConfigError(
                where,
                obj.pose.tolist(),
                f"an object whose centre lies outside every obstacle (it is"
                f" {depth * 1e3:.3g} mm inside {shape.name!r})",
            )


def load_scene(path: str | Path, robot: Robot | None = None) -> Problem:
    """Load a scene TOML (see the file formats) into a :class:`Problem`.

    Args:
        path: The scene file.
        robot: An already loaded robot to use instead of loading the scene's ``robot``
            again (it must be the same robot file).

    Returns:
        The problem: robot, start, grasp pose, law, obstacles and object.

    Raises:
        ConfigError: A missing key or bad value, named with its file and key; an object
            whose centre lies inside an obstacle (:func:`check_object_clear`).
        RobotNotFound, JointNotFound, FrameNotFound: From loading the robot.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise ConfigError("scene file", path, "a path to a scene TOML")
    path = resolved(path, "scene file")
    raw = _toml.read_toml(path, "scene file")
    where = path.name
    _toml.check_keys(raw, SCENE_KEYS, f"{where}: ")
    robot_name = _toml.string(_toml.require(raw, "robot", where), f"{where}: robot")
    robot_file = find_robot_file(robot_name, relative_to=path.parent)
    if robot is None:
        robot = load_robot(robot_file)
    elif not isinstance(robot, Robot):
        raise ConfigError("robot", robot, "None or a loaded Robot (load_robot)")
    elif robot.spec.path != robot_file:
        raise ConfigError(f"{where}: robot", robot_name, f"the robot passed in ({robot.spec.path})")
    start = robot.spec.home
    if "start" in raw:
        start = _toml.vector(raw["start"], f"{where}: start", robot.arm_idx.size)
    start = robot.check_arm(start, f"{where}: start")
    grasp = _toml.require(raw, "grasp", where)
    if not isinstance(grasp, dict):
        raise ConfigError(f"{where}: grasp", grasp, "a [grasp] table with a pose")
    _toml.check_keys(grasp, GRASP_KEYS, f"{where}: grasp")
    grasp_pose = _toml.pose(_toml.require(grasp, "pose", f"{where}: grasp"), f"{where}: grasp.pose")
    hand = raw.get("hand", {})
    if not isinstance(hand, dict):
        raise ConfigError(f"{where}: hand", hand, "a [hand] table")
    _toml.check_keys(hand, SCENE_LAW_FIELDS, f"{where}: hand")
    for key in ("c", "b", "w"):  # read as a robot file's are (no bool, NaN or nested list)
        if key in hand:
            _toml.vector(hand[key], f"{where}: hand.{key}")
    law = robot.hand_law(hand, where=f"{where}: hand")
    obstacles_raw = raw.get("obstacles", [])
    if not isinstance(obstacles_raw, list):
        raise ConfigError(f"{where}: obstacles", obstacles_raw, "an array of [[obstacles]] tables")
    obstacles = [
        Shape.from_table(t, f"{where}: obstacles[{i}]", base=path.parent)
        for i, t in enumerate(obstacles_raw)
    ]
    obj = (
        Shape.from_table(raw["object"], f"{where}: object", is_object=True, base=path.parent)
        if "object" in raw
        else None
    )
    check_unique_names(obstacles, obj, f"{where}: obstacle name")
    check_object_clear(obstacles, obj, f"{where}: object.pose")
    return Problem(robot, start, grasp_pose, law, obstacles, obj, path)
