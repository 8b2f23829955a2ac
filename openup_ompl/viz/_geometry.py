"""Triangle meshes of Coal geometries and scene shapes, for drawing.

Meshes come from what Coal loaded (``BVHModel`` triangles, ``Convex`` polygons); the
primitives Coal keeps analytic (box, sphere, cylinder, capsule, cone) are tessellated here,
with faces cut to at most ``max_edge`` so that a painter's-algorithm renderer (matplotlib)
sorts them against small robot triangles correctly.
"""

from __future__ import annotations

import math

import coal
import numpy as np
import pinocchio as pin
from scipy.spatial import ConvexHull

from openup_ompl.meshes import hull_points, revolution_mesh
from openup_ompl.scene import Shape

#: ``(vertices (n, 3) [m], triangles (m, 3) vertex indices)``, in the geometry's frame.
Mesh = tuple[np.ndarray, np.ndarray]


def _grid(corner: np.ndarray, du: np.ndarray, dv: np.ndarray, nu: int, nv: int) -> Mesh:
    """A parallelogram ``corner + s du + t dv`` cut into ``2 nu nv`` triangles."""
    s, t = np.meshgrid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1), indexing="ij")
    vertices = corner + s.reshape(-1, 1) * du + t.reshape(-1, 1) * dv
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = (i * (nv + 1) + j).ravel()
    b, c, d = a + nv + 1, a + nv + 2, a + 1
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return vertices, faces


def _merge(meshes: list[Mesh]) -> Mesh:
    vertices, faces, offset = [], [], 0
    for v, f in meshes:
        vertices.append(v)
        faces.append(f + offset)
        offset += len(v)
    return np.concatenate(vertices), np.concatenate(faces)


def box_mesh(size: np.ndarray, max_edge: float = 0.05) -> Mesh:
    """A box of full side lengths ``size`` [m] centred at the origin."""
    half = np.asarray(size, dtype=float) / 2
    faces = []
    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        du, dv = np.zeros(3), np.zeros(3)
        du[u], dv[v] = 2 * half[u], 2 * half[v]
        nu, nv = (max(1, math.ceil(2 * half[k] / max_edge)) for k in (u, v))
        for sign in (-1.0, 1.0):
            corner = -half.copy()
            corner[axis] = sign * half[axis]
            vertices, tris = _grid(corner, du, dv, nu, nv)
            faces.append((vertices, tris if sign > 0 else tris[:, ::-1]))
    return _merge(faces)


def _cylinder_profile(radius: float, half: float, max_edge: float) -> np.ndarray:
    n = max(1, math.ceil(2 * half / max_edge))
    side = np.stack([np.full(n + 1, radius), np.linspace(-half, half, n + 1)], 1)
    return np.concatenate([[[0.0, -half]], side, [[0.0, half]]])


def _arc_profile(radius: float, centre: float, start: float, stop: float) -> np.ndarray:
    """``(radius, z)`` points of a circle arc about ``z = centre``, angles from the -z pole."""
    t = np.linspace(start, stop, 1 + math.ceil(16 * (stop - start) / math.pi))
    return np.stack([radius * np.sin(t), centre - radius * np.cos(t)], 1)


def shape_mesh(shape: Shape, max_edge: float = 0.05) -> Mesh:
    """Mesh of a scene shape, in its own frame (place it with ``shape.placement``)."""
    if shape.shape == "box":
        assert shape.size is not None
        return box_mesh(shape.size, max_edge)
    if shape.shape == "mesh":  # drawn as what is planned and simulated: its convex hull
        assert shape.file is not None and shape.scale is not None
        points = np.array(hull_points(shape.file, shape.scale))
        return points, ConvexHull(points).simplices
    assert shape.radius is not None
    if shape.shape == "sphere":
        return revolution_mesh(_arc_profile(shape.radius, 0.0, 0.0, math.pi))
    assert shape.length is not None
    return revolution_mesh(_cylinder_profile(shape.radius, shape.length / 2, max_edge))


def coal_mesh(geometry: coal.CollisionGeometry, max_edge: float = 0.05) -> Mesh | None:
    """Mesh of a Coal geometry in its own frame, or ``None`` for a kind not drawn here
    (planes, height fields, octrees)."""
    if isinstance(geometry, coal.BVHModelBase):
        tris = [geometry.tri_indices(k) for k in range(geometry.num_tris)]
        faces = np.array([[t[0], t[1], t[2]] for t in tris], dtype=np.intp).reshape(-1, 3)
        return np.asarray(geometry.vertices(), dtype=float), faces
    if isinstance(geometry, coal.ConvexBase):
        polygons = [geometry.polygons(k) for k in range(geometry.num_polygons)]
        faces = np.array([[p[0], p[1], p[2]] for p in polygons], dtype=np.intp).reshape(-1, 3)
        return np.asarray(geometry.points(), dtype=float), faces
    if isinstance(geometry, coal.Box):
        return box_mesh(2 * np.asarray(geometry.halfSide), max_edge)
    if isinstance(geometry, coal.Sphere):
        return revolution_mesh(_arc_profile(geometry.radius, 0.0, 0.0, math.pi))
    if isinstance(geometry, coal.Cylinder):
        return revolution_mesh(_cylinder_profile(geometry.radius, geometry.halfLength, max_edge))
    if isinstance(geometry, coal.Capsule):
        r, h = geometry.radius, geometry.halfLength
        profile = np.concatenate(
            [
                _arc_profile(r, -h, 0.0, math.pi / 2),
                _arc_profile(r, h, math.pi / 2, math.pi),
            ]
        )
        return revolution_mesh(profile)
    if isinstance(geometry, coal.Cone):
        r, h = geometry.radius, geometry.halfLength
        return revolution_mesh(np.array([[0.0, -h], [r, -h], [0.0, h]]))
    return None


def placed(mesh: Mesh, placement: pin.SE3) -> Mesh:
    """The mesh with its vertices moved by ``placement``."""
    vertices, faces = mesh
    return vertices @ placement.rotation.T + placement.translation, faces


def decimate(mesh: Mesh, cell: float) -> Mesh:
    """A coarser mesh by vertex clustering: vertices in one ``cell``-sized [m] grid cube
    merge into their mean, and triangles that collapse are dropped. Keeps the silhouette
    to within about ``cell``; meant for drawing, not for collision checking."""
    vertices, faces = mesh
    if len(faces) == 0:
        return mesh
    keys = np.floor(vertices / cell).astype(np.int64)
    _, cluster = np.unique(keys, axis=0, return_inverse=True)
    cluster = cluster.ravel()
    counts = np.bincount(cluster)
    sums = np.stack([np.bincount(cluster, weights=vertices[:, k]) for k in range(3)], 1)
    merged = sums / counts[:, None]
    faces = cluster[faces]
    alive = (
        (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    )
    faces = faces[alive]
    _, first = np.unique(np.sort(faces, axis=1), axis=0, return_index=True)
    return merged, faces[np.sort(first)]
