"""Scene shapes as MuJoCo geoms: the one translation of a :class:`~openup_ompl.scene.Shape`
into an ``mujoco.MjSpec``, shared by the physics world and the simulated camera.

MuJoCo sizes are half-sizes (a box's half sides, a cylinder's radius and half length) and
its quaternions are scalar first; scene poses are scalar last (``pinocchio.XYZQUATToSE3``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from openup_ompl.meshes import hull_points

if TYPE_CHECKING:
    import mujoco

    from openup_ompl.scene import Problem, Shape

__all__ = ["add_free_body", "add_scene", "add_shape", "mujoco_quat", "scene_spec"]


def mujoco_quat(pose: Sequence[float] | np.ndarray) -> np.ndarray:
    """``[qw, qx, qy, qz]`` of a ``[x, y, z, qx, qy, qz, qw]`` pose.

    Args:
        pose: ``[x, y, z, qx, qy, qz, qw]`` [m].

    Returns:
        The unit quaternion, scalar first (MuJoCo's order).
    """
    q = np.asarray(pose, dtype=float)[3:7]
    return np.array([q[3], q[0], q[1], q[2]])


def _geom_type_and_size(shape: Shape) -> tuple[Any, list[float]]:
    import mujoco

    if shape.shape == "mesh":
        return mujoco.mjtGeom.mjGEOM_MESH, [0.0, 0.0, 0.0]
    if shape.shape == "box":
        assert shape.size is not None
        return mujoco.mjtGeom.mjGEOM_BOX, [float(x) / 2 for x in shape.size]
    assert shape.radius is not None
    if shape.shape == "sphere":
        return mujoco.mjtGeom.mjGEOM_SPHERE, [shape.radius, 0.0, 0.0]
    assert shape.length is not None
    return mujoco.mjtGeom.mjGEOM_CYLINDER, [shape.radius, shape.length / 2, 0.0]


def add_shape(
    body: mujoco.MjsBody,
    shape: Shape,
    *,
    local: bool = False,
    spec: mujoco.MjSpec | None = None,
    **attributes: Any,
) -> mujoco.MjsGeom:
    """Add ``shape`` as a geom of ``body`` (named as the shape).

    Args:
        body: The spec body that holds it (``spec.worldbody`` for a static shape).
        shape: The scene shape.
        local: Place the geom at the body's origin (the body carries the pose, as a free
            object's body does) instead of at the shape's world pose.
        spec: The spec that owns ``body``: a mesh shape's vertices become a mesh asset
            of it (named ``"<shape>_mesh"``; MuJoCo collides with its convex hull).
        attributes: Further geom attributes (``friction``, ``mass``, ``rgba``, ...).

    Returns:
        The new geom.

    Raises:
        ValueError: A mesh shape without ``spec``.
    """
    geom_type, size = _geom_type_and_size(shape)
    pose = np.asarray(shape.pose, dtype=float)
    placement = {} if local else {"pos": pose[:3].tolist(), "quat": mujoco_quat(pose).tolist()}
    if shape.shape == "mesh":
        if spec is None:
            raise ValueError(f"mesh shape {shape.name!r} needs the spec to hold its vertices")
        assert shape.file is not None and shape.scale is not None
        mesh = spec.add_mesh(name=f"{shape.name}_mesh")
        mesh.uservert = hull_points(shape.file, shape.scale).ravel().tolist()
        attributes = {"meshname": mesh.name, **attributes}
    return body.add_geom(name=shape.name, type=geom_type, size=size, **placement, **attributes)


def scene_spec(problem: Problem, *, free_object: bool = False) -> mujoco.MjSpec:
    """A spec of the scene alone: every obstacle a static geom of the world body, and the
    object a geom of its own body ``"object"`` (with a free joint if ``free_object``).

    The object's mass and friction are the scene's (``[object] mass``, ``friction``); an
    obstacle's friction is its own ``friction`` key, else MuJoCo's default.

    Args:
        problem: The scene.
        free_object: Give the object a free joint.

    Returns:
        The MuJoCo spec (not compiled).
    """
    import mujoco

    spec = mujoco.MjSpec()
    add_scene(spec, problem.obstacles, problem.object, free_object=free_object)
    return spec


def add_scene(
    spec: mujoco.MjSpec,
    obstacles: Sequence[Shape],
    scene_object: Shape | None,
    *,
    free_object: bool = False,
    **object_attributes: Any,
) -> mujoco.MjsBody | None:
    """Add a scene's obstacles (static geoms of the world body) and its object (a geom of
    the body ``"object"``, free if ``free_object``) to ``spec``; returns the object's
    body. ``object_attributes`` override the object geom's (``friction``, ``mass``,
    ``condim``, ...).

    Args:
        spec: The MuJoCo spec to add to.
        obstacles: The scene's obstacles (static geoms).
        scene_object: The object, if any.
        free_object: Give the object a free joint (physics) rather than fixing it
            (the camera).
        **object_attributes: MuJoCo geom attributes of the object.

    Returns:
        The object's body, or ``None`` without an object.
    """
    for obstacle in obstacles:
        add_shape(spec.worldbody, obstacle, spec=spec, **_contact(obstacle))
    if scene_object is None:
        return None
    if not free_object:
        return _add_body(spec, scene_object, "object", **object_attributes)
    return add_free_body(spec, scene_object, "object", **object_attributes)


def add_free_body(
    spec: mujoco.MjSpec, shape: Shape, name: str, **attributes: Any
) -> mujoco.MjsBody:
    """Add ``shape`` as the geom of a free body ``name`` (a free joint of that name) at
    the shape's pose, with its ``mass`` and ``friction``; ``attributes`` override the
    geom's. Returns the body.

    Args:
        spec: The MuJoCo spec to add to.
        shape: The shape (its pose, ``mass`` [kg] and ``friction``).
        name: The body's and its free joint's name.
        **attributes: MuJoCo geom attributes overriding the shape's.

    Returns:
        The new body.
    """
    body = _add_body(spec, shape, name, **attributes)
    body.add_freejoint(name=name)
    return body


def _add_body(spec: mujoco.MjSpec, shape: Shape, name: str, **attributes: Any) -> mujoco.MjsBody:
    """``shape`` as the geom of a body ``name`` of the world body, at the shape's pose."""
    pose = np.asarray(shape.pose, dtype=float)
    body = spec.worldbody.add_body(
        name=name, pos=pose[:3].tolist(), quat=mujoco_quat(pose).tolist()
    )
    add_shape(
        body, shape, local=True, spec=spec, **{"mass": shape.mass, **_contact(shape), **attributes}
    )
    return body


def _contact(shape: Shape) -> dict[str, Any]:
    if shape.friction is None:
        return {}
    # MuJoCo's friction: sliding, torsional, rolling (its defaults for the last two).
    return {"friction": [shape.friction, 0.005, 0.0001]}
