"""Scene files (see the file formats): robot, start, grasp pose, hand law, object and
obstacles. Every table rejects keys it does not know, naming the nearest valid one."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from openup_ompl import _toml
from openup_ompl._io import resolved
from openup_ompl._resources import data_dir
from openup_ompl.exceptions import ConfigError
from openup_ompl.hand_law import TABLE_FIELDS, HandLaw
from openup_ompl.meshes import convex_geometry, hull_points
from openup_ompl.robot import Robot, find_robot_file, load_robot

SHAPES = ("box", "cylinder", "sphere", "mesh")
#: The dimensions each shape takes ([m]; a mesh's file and its uniform scale).
SHAPE_KEYS = {
    "box": ("size",),
    "cylinder": ("radius", "length"),
    "sphere": ("radius",),
    "mesh": ("file", "scale"),
}
#: The keys of a scene file's top level and of its ``[grasp]`` table.
#: ``[camera]`` is the simulated depth camera's (:mod:`openup_ompl.perception`, which
#: validates it when it looks).
SCENE_KEYS = ("robot", "start", "grasp", "hand", "object", "obstacles", "camera")
GRASP_KEYS = ("pose",)
#: The hand-law fields a scene's ``[hand]`` may override (the fixed preshape is a planning
#: option, not part of a scene).
SCENE_LAW_FIELDS = tuple(name for name in TABLE_FIELDS if name != "fixed")
#: The lightest object [kg] physics accepts (MuJoCo refuses a body lighter than its
#: ``mjMINVAL`` while compiling, blaming the model).
MIN_MASS = 1e-6
#: The object's mass [kg] and Coulomb friction when the scene gives none (physics only).
OBJECT_MASS = 0.1
OBJECT_FRICTION = 0.6
#: The thinnest radius or length of a cylinder or sphere accepted [m].
MIN_EXTENT = 1e-6


def _box_size(value: Any, where: str) -> np.ndarray:
    """A box's full side lengths [m]: three in ``(0, MAX_EXTENT]``, or a ConfigError."""
    size = _toml.vector(value, where, 3)
    if np.any(size <= 0) or np.any(size > _toml.MAX_EXTENT):
        raise ConfigError(
            where, _toml.shown(value), f"three positive lengths [m], at most {_toml.MAX_EXTENT:g}"
        )
    return size


def _extent(value: Any, where: str) -> float:
    """A cylinder's or sphere's radius or length [m] in ``[MIN_EXTENT, MAX_EXTENT]``."""
    return _toml.number(value, where, low=MIN_EXTENT, high=_toml.MAX_EXTENT)


def _mesh_file(value: Any, where: str) -> Path:
    """A mesh's file path (checked to exist when its hull is read)."""
    return Path(_toml.string(str(value) if isinstance(value, Path) else value, where)).expanduser()


def _scale(value: Any, where: str) -> float:
    """A mesh's uniform scale: a number in ``(0, 1e3]``."""
    return _toml.number(value, where, low=MIN_EXTENT, high=1e3)


_DIMENSION_CHECKS = {
    "size": _box_size,
    "radius": _extent,
    "length": _extent,
    "file": _mesh_file,
    "scale": _scale,
}


@dataclass(frozen=True)
class Shape:
    """A box, cylinder, sphere or mesh placed in the world frame.

    Attributes:
        name: Unique name (used for its Coal geometry).
        shape: ``"box"``, ``"cylinder"``, ``"sphere"`` or ``"mesh"`` (the convex hull of
            an OBJ or STL file's vertices, for planning, physics and the camera alike).
        pose: ``[x, y, z, qx, qy, qz, qw]`` of its centre in the world frame.
        size: Box full side lengths [m] (x, y, z).
        radius: Cylinder or sphere radius [m].
        length: Cylinder length [m] along its local z.
        file: A mesh's OBJ or STL file (absolute once read).
        scale: A mesh's uniform scale (file units to metres; 1.0 when the file is in m).
        mass: Mass [kg]: the object's, or a movable obstacle's (both free bodies in
            physics).
        friction: Coulomb friction coefficient in physics (``None``: the simulator's
            default; the object's default is :data:`OBJECT_FRICTION`).
        movable: An obstacle that physics simulates as a free body (a neighbour the hand
            may push or tip); planning treats it as fixed, as every obstacle.
        raw: The table as written in the scene file (``{}`` for a shape built in code;
            plan files hold :meth:`to_table`, not this).
    """

    name: str
    shape: str
    pose: np.ndarray
    size: np.ndarray | None = None
    radius: float | None = None
    length: float | None = None
    file: Path | None = None
    scale: float | None = None
    mass: float | None = None
    friction: float | None = None
    movable: bool = False
    raw: dict[str, Any] = field(default_factory=dict, compare=False)

    @classmethod
    def from_table(
        cls, table: Any, where: str, *, is_object: bool = False, base: Path | None = None
    ) -> Shape:
        """Read a scene's ``[object]`` (``is_object``) or ``[[obstacles]]`` table.

        Args:
            table: The TOML (or plan file JSON) table.
            where: Where it was read, for errors (``"scene.toml: obstacles[2]"``).
            is_object: The object's table: it takes ``mass`` and ``friction`` with their
                defaults; an obstacle takes them only when ``movable = true``.
            base: The folder a mesh's relative ``file`` is read from (the scene file's;
                the working directory when ``None``).

        Returns:
            The shape, its fields checked.

        Raises:
            ConfigError: Naming ``where`` and the key at fault.
        """
        if not isinstance(table, dict):
            raise ConfigError(where, table, "a table with name, shape, pose and dimensions")
        shape = _toml.require(table, "shape", where)
        if shape not in SHAPES:
            raise ConfigError(f"{where}.shape", shape, f"one of {SHAPES}")
        movable = table.get("movable", False)
        if is_object and "movable" in table:
            raise ConfigError(f"{where}.movable", movable, "no movable key: the object is free")
        if not isinstance(movable, bool):
            raise ConfigError(f"{where}.movable", movable, "true or false")
        known = {"name", "shape", "pose", "mass", "friction", "movable", *SHAPE_KEYS[shape]}
        _toml.check_keys(table, known, where)
        physics: dict[str, Any] = {"movable": movable}
        if is_object or movable:
            physics["mass"] = _toml.number(
                table.get("mass", OBJECT_MASS), f"{where}.mass", low=MIN_MASS
            )
        elif "mass" in table:
            raise ConfigError(
                f"{where}.mass", table["mass"], "no mass: a fixed obstacle (movable = true)"
            )
        if "friction" in table or is_object:
            physics["friction"] = _toml.number(
                table.get("friction", OBJECT_FRICTION), f"{where}.friction", low=0.0
            )
        name = _toml.string(_toml.require(table, "name", where), f"{where}.name")
        pose = _toml.pose(_toml.require(table, "pose", where), f"{where}.pose")
        dims: dict[str, Any] = {
            key: _DIMENSION_CHECKS[key](_toml.require(table, key, where), f"{where}.{key}")
            for key in SHAPE_KEYS[shape]
            if key != "scale"
        }
        if shape == "mesh":
            if base is not None and not dims["file"].is_absolute():
                dims["file"] = base / dims["file"]
            dims["scale"] = _scale(table.get("scale", 1.0), f"{where}.scale")
            hull_points(dims["file"], dims["scale"], where)
        return cls(name, shape, pose, **dims, **physics, raw=dict(table))

    def __post_init__(self) -> None:
        """Check a shape built in code (or by ``dataclasses.replace``) as :meth:`from_table`
        checks a file's: a known shape with its dimensions only, each within
        ``[MIN_EXTENT, MAX_EXTENT]`` (a negative box was dropped from collision checks
        without a word), a pose with a unit quaternion (normalised), a mass of at least
        :data:`MIN_MASS` and a friction >= 0 when given. Arrays, lists and tuples are
        stored as float arrays, numbers as floats.

        Raises:
            ConfigError: Naming the shape and the field (``shape 'wall'.size``).
        """
        name = _toml.string(self.name, "shape.name")
        where = f"shape {name!r}"
        if not (isinstance(self.shape, str) and self.shape in SHAPES):
            raise ConfigError(f"{where}.shape", self.shape, f"one of {SHAPES}")
        if not isinstance(self.raw, dict):
            raise ConfigError(f"{where}.raw", self.raw, "a dict (the scene file's table)")
        checked: dict[str, Any] = {"pose": _toml.pose(_toml.shown(self.pose), f"{where}.pose")}
        keys = SHAPE_KEYS[self.shape]
        for key, check in _DIMENSION_CHECKS.items():
            value = getattr(self, key)
            if key in keys:
                checked[key] = check(value, f"{where}.{key}")
            elif value is not None:
                raise ConfigError(
                    f"{where}.{key}", _toml.shown(value), f"None: a {self.shape} has {keys}"
                )
        if self.shape == "mesh":
            checked["file"] = resolved(checked["file"], f"{where}.file")
            hull_points(checked["file"], checked["scale"], where)
        if not isinstance(self.movable, bool):
            raise ConfigError(f"{where}.movable", self.movable, "True or False")
        if self.mass is not None:
            checked["mass"] = _toml.number(self.mass, f"{where}.mass", low=MIN_MASS)
        if self.friction is not None:
            checked["friction"] = _toml.number(self.friction, f"{where}.friction", low=0.0)
        for key, value in checked.items():  # frozen: set as the dataclass's own __init__ does
            object.__setattr__(self, key, value)

    def at(self, pose: np.ndarray) -> Shape:
        """The same shape at ``pose`` ``[x, y, z, qx, qy, qz, qw]`` (its :attr:`raw` table
        moved along): the object displaced, or where perception estimates it.

        Args:
            pose: ``[x, y, z, qx, qy, qz, qw]`` [m], world frame.

        Returns:
            A new shape, equal but for its pose.
        """
        pose = np.asarray(pose, dtype=float)
        raw = {**self.raw, "pose": pose.tolist()}
        return dataclasses.replace(self, pose=pose, raw=raw)

    def to_table(self) -> dict[str, Any]:
        """The shape as a scene file's table, written from its fields (JSON and TOML
        types): what a plan file holds, read back by :meth:`from_table` into an equal
        shape. Not :attr:`raw`, which a shape changed in code (``dataclasses.replace``)
        or built there does not update or have.

        Returns:
            Key -> value (lists for arrays, the mesh file as a string).
        """
        table: dict[str, Any] = {"name": self.name, "shape": self.shape}
        table["pose"] = np.asarray(self.pose, dtype=float).tolist()
        for key in (*SHAPE_KEYS[self.shape], "mass", "friction"):
            value = getattr(self, key)
            if isinstance(value, Path):
                table[key] = str(value)
            elif value is not None:
                table[key] = np.asarray(value, dtype=float).tolist()
        if self.movable:
            table["movable"] = True
        return table

    @property
    def placement(self) -> pin.SE3:
        """World placement of the shape's centre."""
        return pin.XYZQUATToSE3(self.pose)

    def geometry(self, padding: float = 0.0) -> coal.CollisionGeometry:
        """The Coal collision geometry of this shape, centred at its origin, grown by
        ``padding`` [m] on every side (a superset of the shape's Minkowski sum with a
        ball of that radius).

        Args:
            padding: Growth on every side [m], finite and ``>= 0``.

        Returns:
            The Coal geometry (a box, cylinder, sphere or convex hull).

        Raises:
            ConfigError: ``padding`` negative or not finite (a shrunk shape would hide
                contacts).
        """
        if not (_toml.is_finite(padding) and padding >= 0):
            raise ConfigError("padding", padding, "a distance >= 0 [m]")
        if self.shape == "box":
            assert self.size is not None
            return coal.Box(*(float(x) + 2 * padding for x in self.size))
        if self.shape == "mesh":
            assert self.file is not None and self.scale is not None
            return convex_geometry(hull_points(self.file, self.scale), padding)
        assert self.radius is not None
        if self.shape == "sphere":
            return coal.Sphere(self.radius + padding)
        assert self.length is not None
        return coal.Cylinder(self.radius + padding, self.length + 2 * padding)


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
