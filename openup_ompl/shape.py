"""Scene shapes: the object and obstacles of a scene file (box, cylinder, sphere or convex
mesh), checked as a file's tables are, with their Coal collision geometry."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from openup_ompl import _toml
from openup_ompl._io import resolved
from openup_ompl.exceptions import ConfigError
from openup_ompl.meshes import convex_geometry, hull_points

SHAPES = ("box", "cylinder", "sphere", "mesh")
#: The dimensions each shape takes ([m]; a mesh's file and its uniform scale).
SHAPE_KEYS = {
    "box": ("size",),
    "cylinder": ("radius", "length"),
    "sphere": ("radius",),
    "mesh": ("file", "scale"),
}
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
