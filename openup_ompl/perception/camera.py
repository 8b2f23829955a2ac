"""A simulated pinhole depth camera that ray-casts the scene with MuJoCo.

The camera frame follows OpenCV (``z`` forward, ``x`` right, ``y`` down). One ray per pixel
centre is cast with ``mujoco.mj_multiRay`` against the scene's MuJoCo model
(:func:`~openup_ompl.physics.shapes.scene_spec`): hit distance, geom and normal. The noise
(:mod:`~openup_ompl.perception.noise`) is applied apart: one cast serves many noisy views.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from openup_ompl import _toml
from openup_ompl.exceptions import ConfigError, InvalidProblem
from openup_ompl.scene import Problem

__all__ = ["CameraOptions", "DepthCamera", "DepthView"]


#: The keys that place the camera on an orbit around the object (without ``position``).
ORBIT_KEYS = ("distance", "elevation", "azimuth")


#: The surface under the object's measured points is its support
#: (:meth:`DepthCamera.support_under`) when it lies at most this far [m] above their
#: lowest one (the sensor's noise reaches millimetres) ...
SUPPORT_TOLERANCE = 0.01
#: ... and at most this far [m] below it: a wall may hide an object's lowest centimetres;
#: an object held higher above a surface is not standing on it.
SUPPORT_GAP = 0.05
#: A pixel just below the object's lowest one in an image column that sees a surface this
#: much [m] deeper than that object pixel sees under the object: a gap, where a standing
#: object's base meets the table (the table in front of it is nearer, not deeper): set
#: between the depths a can held 1.5 cm up and one held 3 cm up give.
GAP_DEPTH = 0.025


#: The focal lengths accepted [px]. An explicit ``fx`` of 1e-300 px overflowed the rays'
#: directions (numpy warnings on stderr); the field of view's own range, (0, 180) deg,
#: gives 0.004 px (179 deg, 1 px wide) to millions.
FOCAL_RANGE = (1e-3, 1e9)
#: The farthest principal point accepted from the image's corner [px]: 25 times the widest
#: image (1e308 px overflowed the rays as an ``fx`` of 1e-300 px did).
PRINCIPAL_MAX = 1e5


@dataclass(frozen=True)
class CameraOptions:
    """Pose, intrinsics and resolution of the depth camera.

    The pose is explicit (``position``, ``target``) or, by default, from the object:
    ``distance`` from its centre, towards the robot's base (world origin) or at ``azimuth``,
    raised by ``elevation``, looking at the centre. ``fov`` sets the focal length if no ``fx``.

    Attributes:
        width: Image width [px].
        height: Image height [px].
        fov: Horizontal field of view [deg] (57: the Kinect v1's), used when ``fx`` is None.
        fx: Focal length along x [px] (None: from ``fov``).
        fy: Focal length along y [px] (None: ``fx``, square pixels).
        cx: Principal point x [px] (None: the image centre).
        cy: Principal point y [px] (None: the image centre).
        distance: Camera to object centre [m] (default pose only).
        elevation: Angle [deg] of the line of sight above the horizontal (default pose).
        azimuth: Direction [deg] from the object to the camera about world z (None: the base's).
        position: Explicit camera position ``[x, y, z]`` [m] in the world frame.
        target: Explicit point [m] the optical axis passes through (None: object centre).
        max_range: Rays longer than this [m] return nothing (the sensor's far limit).
    """

    width: int = 160  # [px]
    height: int = 120  # [px]
    fov: float = 57.0  # [deg]
    fx: float | None = None  # [px]
    fy: float | None = None  # [px]
    cx: float | None = None  # [px]
    cy: float | None = None  # [px]
    distance: float = 0.8  # [m]
    elevation: float = 40.0  # [deg]
    azimuth: float | None = None  # [deg]
    position: tuple[float, float, float] | None = None  # [m]
    target: tuple[float, float, float] | None = None  # [m]
    max_range: float = 4.0  # [m]

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            if not (_toml.is_integer(value) and 1 <= value <= 4096):
                raise ConfigError(
                    f"camera.{name}", value, "an integer number of pixels in [1, 4096]"
                )
            object.__setattr__(self, name, int(value))  # numpy integers stored as int
        positive = {"fov": self.fov, "distance": self.distance, "max_range": self.max_range}
        for name in ("fx", "fy"):
            if getattr(self, name) is not None:
                positive[name] = getattr(self, name)
        for name, value in positive.items():
            if not (_toml.is_finite(value) and value > 0):
                raise ConfigError(f"camera.{name}", value, "a positive finite number")
        if not self.fov < 180:
            raise ConfigError("camera.fov", self.fov, "a field of view in (0, 180) deg")
        low, high = FOCAL_RANGE
        for name in ("fx", "fy"):
            value = getattr(self, name)
            if value is not None and not low <= value <= high:
                raise ConfigError(
                    f"camera.{name}", value, f"a focal length in [{low:g}, {high:g}] px"
                )
        if not self.distance <= _toml.MAX_EXTENT:
            raise ConfigError(
                "camera.distance", self.distance, f"a distance of at most {_toml.MAX_EXTENT:g} m"
            )
        for name in ("cx", "cy", "azimuth"):
            value = getattr(self, name)
            if value is not None and not (_toml.is_finite(value)):
                raise ConfigError(f"camera.{name}", value, "a finite number")
        for name in ("cx", "cy"):
            value = getattr(self, name)
            if value is not None and not abs(value) <= PRINCIPAL_MAX:
                raise ConfigError(
                    f"camera.{name}", value, f"a principal point within {PRINCIPAL_MAX:g} px"
                )
        if not (_toml.is_number(self.elevation) and -90 < self.elevation < 90):
            raise ConfigError("camera.elevation", self.elevation, "an angle in (-90, 90) deg")
        for name in ("position", "target"):
            value = getattr(self, name)
            if value is not None and not (
                len(value) == 3
                and all(_toml.is_finite(x) and abs(x) <= _toml.MAX_EXTENT for x in value)
            ):
                raise ConfigError(
                    f"camera.{name}",
                    value,
                    f"[x, y, z], finite, in metres, each within {_toml.MAX_EXTENT:g} m of the"
                    " origin",
                )

    @classmethod
    def from_table(cls, table: Mapping[str, Any], where: str = "camera") -> CameraOptions:
        """Options from a ``[camera]`` table or ``--camera KEY=VALUE`` pairs (attribute names).

        Args:
            table: Key -> value (``width``, ``height``, ``fov``, ``distance``, ...).
            where: Prefix of error locations.
        Returns:
            The options, checked.
        """
        _toml.check_keys(table, {f.name for f in fields(cls)}, where)
        orbit = sorted(set(table) & set(ORBIT_KEYS))
        if "position" in table and orbit:
            # An explicit position leaves nothing for these to set: they would be ignored.
            raise ConfigError(
                f"{where}.{orbit[0]}",
                table[orbit[0]],
                "no distance, elevation or azimuth"
                " with an explicit position (the position sets the view)",
            )
        values: dict[str, Any] = {}
        for key, value in table.items():
            if key in ("position", "target"):
                value = tuple(float(x) for x in _toml.vector(value, f"{where}.{key}", 3))
            values[key] = value
        return cls(**values)

    def intrinsics(self) -> tuple[float, float, float, float]:
        """``(fx, fy, cx, cy)`` [px].

        Returns:
            The focal lengths and principal point ``(fx, fy, cx, cy)`` [px].
        """
        fx = (
            self.fx
            if self.fx is not None
            else self.width / 2 / math.tan(math.radians(self.fov) / 2)
        )
        fy = self.fy if self.fy is not None else fx
        cx = self.cx if self.cx is not None else self.width / 2
        cy = self.cy if self.cy is not None else self.height / 2
        return float(fx), float(fy), float(cx), float(cy)

    def look_at(self, problem: Problem) -> tuple[np.ndarray, np.ndarray]:
        """The camera's position and target [m] in the world frame for ``problem``.

        Args:
            problem: The scene (its object, robot base and grasp).
        Returns:
            ``(position, target)``, each ``(3,)`` [m].
        """
        if self.target is not None:
            target = np.array(self.target, dtype=float)
        elif problem.object is not None:
            target = np.asarray(problem.object.pose[:3], dtype=float)
        else:
            raise InvalidProblem("the camera needs a target: the scene has no [object]")
        if self.position is not None:
            position = np.array(self.position, dtype=float)
        else:
            if self.azimuth is not None:
                azimuth = math.radians(self.azimuth)
            else:
                azimuth = math.atan2(-target[1], -target[0])  # towards the robot's base
            elevation = math.radians(self.elevation)
            direction = np.array(
                [
                    math.cos(elevation) * math.cos(azimuth),
                    math.cos(elevation) * math.sin(azimuth),
                    math.sin(elevation),
                ]
            )
            position = target + self.distance * direction
        if np.linalg.norm(target - position) < 1e-6:
            raise ConfigError("camera.position", position.tolist(), "a point away from the target")
        if problem.object is not None:
            # A camera inside the object sees it from within (a wrong fit, reported as a
            # good one): it must stand outside the object's bounding sphere.
            geometry = problem.object.geometry()
            geometry.computeLocalAABB()
            centre = problem.object.placement.act(np.asarray(geometry.aabb_center))
            radius = float(geometry.aabb_radius)
            if np.linalg.norm(position - centre) <= radius:
                where, value = (
                    ("camera.position", position.tolist())
                    if self.position is not None
                    else ("camera.distance", self.distance)
                )
                raise ConfigError(
                    where,
                    value,
                    f"a camera outside the object (farther than {radius:.3g} m from its centre)",
                )
        return position, target


def camera_of_scene(problem: Problem, overrides: Mapping[str, Any] | None = None) -> CameraOptions:
    """The camera of the problem's scene file (its ``[camera]`` table; the defaults for
    a problem without one, or built in code), with ``overrides`` (the same keys) on top.

    Args:
        problem: The scene (read again from its file, if it has one).
        overrides: ``[camera]`` keys and values (distances [m], angles [deg]), or ``None``.
    Returns:
        The camera's options, checked.
    Raises:
        ConfigError: A ``[camera]`` that is not a table, or a bad key or value.
    """
    table: Any = {}
    if problem.path is not None:
        table = _toml.read_toml(problem.path, "scene file").get("camera", {})
        if not isinstance(table, dict):
            raise ConfigError(f"{problem.path.name}: camera", table, "a [camera] table")
    overrides = dict(overrides or {})
    if "position" in overrides:  # the override's explicit view replaces the scene's orbit
        table = {k: v for k, v in table.items() if k not in ORBIT_KEYS}
    elif set(overrides) & set(ORBIT_KEYS):  # and an orbit the scene's position
        table = {k: v for k, v in table.items() if k not in ("position", "target")}
    return CameraOptions.from_table({**table, **overrides})


def camera_rotation(position: np.ndarray, target: np.ndarray) -> np.ndarray:
    """World rotation of the camera frame (columns: x right, y down, z forward).

    Args:
        position, target: The camera's position and the point it looks at [m], world frame.
    Returns:
        The rotation (world from camera), ``(3, 3)``; image up is world +z (+x looking along z).
    """
    forward = (target - position) / np.linalg.norm(target - position)
    up = np.array([0.0, 0.0, 1.0])
    if abs(float(forward @ up)) > 0.999:  # looking straight up or down: image up is +x
        up = np.array([1.0, 0.0, 0.0])
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    return np.column_stack([right, down, forward])


@dataclass(frozen=True)
class DepthView:
    """One noise-free ray cast: every pixel's hit, in the world and camera frames.

    Attributes:
        position: Camera position [m], world frame.
        rotation: Camera frame in the world frame (columns x right, y down, z forward).
        rays: Unit ray directions, camera frame, ``(H * W, 3)``, row-major pixels.
        distance: Hit distance along each ray [m]; NaN where nothing was hit.
        geom: Hit geom id (-1: none).
        normal: Surface normal at the hit, world frame (zeros: none).
        object_geoms: Geom ids of the object.
        width: Image width [px].
        height: Image height [px].
        focal: ``fx`` [px] (the lateral noise's pixel scale).
    """

    position: np.ndarray
    rotation: np.ndarray
    rays: np.ndarray
    distance: np.ndarray
    geom: np.ndarray
    normal: np.ndarray
    object_geoms: np.ndarray
    width: int
    height: int
    focal: float

    @property
    def hit(self) -> np.ndarray:
        """Pixels whose ray hit the scene."""
        return self.geom >= 0

    @property
    def on_object(self) -> np.ndarray:
        """Pixels whose ray hit the object: the segmentation rule, an idealisation (a
        perfect instance label from the renderer, as a trained segmenter approximates)."""
        return np.isin(self.geom, self.object_geoms)

    @property
    def depth(self) -> np.ndarray:
        """Depth ``z`` [m] along the optical axis (NaN: no hit)."""
        return self.distance * self.rays[:, 2]

    @property
    def incidence(self) -> np.ndarray:
        """Angle [rad] between each ray and the surface normal it hit (NaN: no hit)."""
        world_rays = self.rays @ self.rotation.T
        cosine = np.abs(np.einsum("ij,ij->i", world_rays, self.normal))
        angle = np.arccos(np.clip(cosine, 0.0, 1.0))
        return np.where(self.hit, angle, np.nan)

    def camera_points(self) -> np.ndarray:
        """Hit points in the camera frame [m] (NaN rows: no hit).

        Returns:
            ``(height * width, 3)`` points [m].
        """
        return self.rays * self.distance[:, None]


class DepthCamera:
    """Ray-casts one scene from one camera: the MuJoCo model is compiled once.

    Args:
        problem: The scene (its obstacles and object are cast; the robot is not).
        options: Camera pose and intrinsics.
    """

    def __init__(self, problem: Problem, options: CameraOptions | None = None) -> None:
        import mujoco

        from openup_ompl.physics.shapes import scene_spec

        if problem.object is None:
            raise InvalidProblem("the scene has no [object] to look at")
        self.problem = problem
        self.options = options or CameraOptions()
        self.position, self.target = self.options.look_at(problem)
        self.rotation = camera_rotation(self.position, self.target)
        self.model = scene_spec(problem).compile()
        self.data = mujoco.MjData(self.model)
        mujoco.mj_kinematics(self.model, self.data)
        self._object_body = self.model.body("object").id
        self.object_geoms = np.flatnonzero(self.model.geom_bodyid == self._object_body)
        fx, fy, cx, cy = self.options.intrinsics()
        width, height = self.options.width, self.options.height
        u, v = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
        rays = np.column_stack([((u - cx) / fx).ravel(), ((v - cy) / fy).ravel(), np.ones(u.size)])
        self.rays = rays / np.linalg.norm(rays, axis=1, keepdims=True)
        self._world_rays = np.ascontiguousarray((self.rays @ self.rotation.T).ravel())
        self._focal = fx
        n = self.rays.shape[0]
        self._geom = np.empty(n, dtype=np.int32)
        self._dist = np.empty(n, dtype=float)
        self._normal = np.empty(3 * n, dtype=float)

    def looking_from(self, options: CameraOptions) -> DepthCamera:
        """The same scene (its compiled model shared) seen through other ``options`` of
        the same intrinsics and resolution: many candidate views without recompiling.

        Returns:
            A camera at ``options``' pose (a new one, compiled again, if they differ).
        """
        if (options.width, options.height, options.intrinsics()) != (
            self.options.width,
            self.options.height,
            self.options.intrinsics(),
        ):
            return DepthCamera(self.problem, options)
        moved = copy.copy(self)
        moved.options = options
        moved.position, moved.target = options.look_at(self.problem)
        moved.rotation = camera_rotation(moved.position, moved.target)
        moved._world_rays = np.ascontiguousarray((self.rays @ moved.rotation.T).ravel())
        return moved

    def render(self) -> DepthView:
        """Cast every pixel's ray (MuJoCo ``mj_multiRay``, static geoms included).

        Returns:
            The view (:class:`DepthView`): per pixel the hit distance [m], geom and normal.
        """
        import mujoco

        n = self.rays.shape[0]
        mujoco.mj_multiRay(
            self.model,
            self.data,
            self.position,
            self._world_rays,
            None,
            True,
            -1,
            self._geom,
            self._dist,
            self._normal,
            n,
            self.options.max_range,
        )
        geom = self._geom.copy()
        distance = np.where(geom >= 0, self._dist, np.nan)
        normal = self._normal.reshape(n, 3).copy()
        return DepthView(
            position=self.position.copy(),
            rotation=self.rotation.copy(),
            rays=self.rays,
            distance=distance,
            geom=geom,
            normal=normal,
            object_geoms=self.object_geoms,
            width=self.options.width,
            height=self.options.height,
            focal=self._focal,
        )

    def support_under(self, points: np.ndarray, view: DepthView | None = None) -> float | None:
        """Height [m] of the surface the object stands on, from its measured ``points``:
        rays cast straight down past the object from their top, at their centre and four x
        and y extremes, all hit it within :data:`SUPPORT_TOLERANCE` of each other (a flat
        surface under the whole visible footprint). ``None`` when they do not, the surface
        is not within :data:`SUPPORT_TOLERANCE` above and :data:`SUPPORT_GAP` below the
        points' lowest, or the ``view`` sees a gap under the object in most image columns
        (:func:`gap_under`: held above it, or on a stand the rays miss).

        Args:
            points: The object's measured points ``(n, 3)`` [m], world frame.
            view: The view they came from (for the gap test); ``None`` skips it.
        Returns:
            The surface's height [m], or ``None``.
        """
        import mujoco

        if view is not None and gap_under(view) > 0.5:
            return None
        points = np.asarray(points, dtype=float)
        top = float(points[:, 2].max())
        feet = [points[:, :2].mean(axis=0)]
        for axis in (0, 1):
            feet += [points[np.argmin(points[:, axis]), :2], points[np.argmax(points[:, axis]), :2]]
        geom = np.array([-1], dtype=np.int32)
        down = np.array([0.0, 0.0, -1.0])
        heights = []
        for foot in feet:
            start = np.array([foot[0], foot[1], top])
            distance = mujoco.mj_ray(
                self.model, self.data, start, down, None, 1, self._object_body, geom
            )
            if geom[0] < 0:
                return None
            heights.append(top - distance)
        height = float(max(heights))
        if height - min(heights) > SUPPORT_TOLERANCE:
            return None
        lowest = float(points[:, 2].min())
        return height if -SUPPORT_GAP <= height - lowest <= SUPPORT_TOLERANCE else None


def gap_under(view: DepthView) -> float:
    """The share of the object's image columns where the pixel just below its lowest object
    pixel sees a surface over :data:`GAP_DEPTH` deeper: space seen under the object (0 for
    an object on the table, whose base meets the nearer table in front; columns whose next
    pixel is off the image, unmeasured or nearer, such as a wall in front, say nothing).

    Returns:
        The share, in ``[0, 1]`` (0 when no pixel sees the object).
    """
    on_object = view.on_object.reshape(view.height, view.width)
    depth = view.depth.reshape(view.height, view.width)
    columns = np.flatnonzero(on_object.any(axis=0))
    if columns.size == 0:
        return 0.0
    rows = view.height - 1 - np.argmax(on_object[::-1, columns], axis=0)  # lowest object pixel
    below = rows + 1
    inside = below < view.height
    cols, rows, below = columns[inside], rows[inside], below[inside]
    deeper = depth[below, cols] > depth[rows, cols] + GAP_DEPTH  # NaN (no hit) compares False
    return float(np.count_nonzero(deeper & ~on_object[below, cols]) / columns.size)
