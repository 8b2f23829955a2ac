"""Mesh objects: reading an OBJ or STL file into the points of its convex hull, and the
generated meshes shipped under ``scenes/meshes/``.

A mesh shape is planned for and simulated as the convex hull of its vertices: Coal checks
it as a ``Convex`` and MuJoCo collides with a mesh geom's hull, so the planner and the
physics see the same solid. The depth camera sees the same hull (MuJoCo's ray cast hits
the mesh geom). A concave object (a mug's handle loop) is therefore simplified to its hull.

The shipped meshes are generated here (:func:`write_shipped_meshes`), not downloaded:
solids of revolution of stated profiles and one irregular pebble, in metres, their origin
at the centre of their bounding box, their axis along z.
"""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path

import coal
import numpy as np
from scipy.spatial import ConvexHull, QhullError

from openup_ompl._io import MAX_FILE_BYTES
from openup_ompl.exceptions import ConfigError

__all__ = [
    "MESH_SUFFIXES",
    "SHIPPED_MESHES",
    "convex_geometry",
    "hull_points",
    "revolution_mesh",
    "write_obj",
    "write_shipped_meshes",
]

#: The file kinds a mesh shape may name (read by Coal's assimp loader).
MESH_SUFFIXES = (".obj", ".stl")
#: The thinnest hull accepted [m]: flatter vertex sets have no solid hull.
MIN_THICKNESS = 1e-4


def revolution_mesh(profile: np.ndarray, segments: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """The surface swept by a ``(k, 2)`` profile of ``(radius, z)`` points [m] about z.

    Args:
        profile: ``(radius, z)`` rows from bottom to top; ends at radius 0 close the
            surface.
        segments: Vertices per ring.

    Returns:
        ``(vertices (n, 3) [m], triangles (m, 3) vertex indices)``.
    """
    angles = np.linspace(0.0, 2 * math.pi, segments, endpoint=False)
    r, z = profile[:, :1], profile[:, 1:]
    rings = np.stack(
        [r * np.cos(angles), r * np.sin(angles), np.repeat(z, segments, axis=1)], axis=-1
    )
    k = len(profile)
    vertices = rings.reshape(-1, 3)
    i, j = np.meshgrid(np.arange(k - 1), np.arange(segments), indexing="ij")
    a = (i * segments + j).ravel()
    b = (i * segments + (j + 1) % segments).ravel()
    c, d = b + segments, a + segments
    return vertices, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


@lru_cache(maxsize=64)
def _loaded(path: str, scale: float) -> np.ndarray:
    try:
        model = coal.MeshLoader().load(path, np.full(3, scale))
    except Exception as error:  # assimp's reasons arrive as RuntimeError or ValueError
        raise ConfigError("mesh file", path, f"a readable OBJ or STL mesh ({error})") from None
    points = np.array([model.vertex(i) for i in range(model.num_vertices)], dtype=float)
    points.setflags(write=False)
    return points


def hull_points(path: str | Path, scale: float = 1.0, where: str = "mesh") -> np.ndarray:
    """The vertices [m] of the convex hull of a mesh file, scaled, in the file's frame.

    Args:
        path: An ``.obj`` or ``.stl`` file.
        scale: Uniform scale applied to the file's coordinates (a file in millimetres
            takes ``0.001``).
        where: Where the mesh is named, for errors.

    Returns:
        ``(n, 3)`` hull vertices [m] (read-only; cached per file and scale).

    Raises:
        ConfigError: The file is not an OBJ/STL file, cannot be read, or its vertices
            have no solid hull (fewer than 4, or flatter than :data:`MIN_THICKNESS`).
    """
    path = Path(path)
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise ConfigError(f"{where}.file", str(path), f"a mesh file ending in {MESH_SUFFIXES}")
    if not path.is_file():
        raise ConfigError(f"{where}.file", str(path), "an existing regular OBJ or STL file")
    if path.stat().st_size > MAX_FILE_BYTES:
        raise ConfigError(f"{where}.file", str(path), f"a mesh of at most {MAX_FILE_BYTES} bytes")
    points = _loaded(str(path.resolve()), float(scale))
    try:
        hull = ConvexHull(points) if len(points) >= 4 else None
    except QhullError:
        hull = None
    if hull is None or _thickness(points[hull.vertices], hull) < MIN_THICKNESS:
        raise ConfigError(
            f"{where}.file", str(path), f"a mesh whose hull is solid (>= {MIN_THICKNESS} m thick)"
        )
    vertices = points[hull.vertices]
    vertices.setflags(write=False)
    return vertices


def _thickness(points: np.ndarray, hull: ConvexHull) -> float:
    """The hull's smallest width over its face normals [m]."""
    normals = hull.equations[:, :3]
    spans = points @ normals.T
    return float(np.min(spans.max(axis=0) - spans.min(axis=0)))


def convex_geometry(points: np.ndarray, padding: float = 0.0) -> coal.ConvexBase:
    """A Coal ``Convex`` of hull vertices [m], grown by ``padding`` [m] on every side (its
    swept-sphere radius: exactly the Minkowski sum with a ball).

    Args:
        points: Hull vertices ``(n, 3)`` [m] (:func:`hull_points`).
        padding: Growth [m] on every side.

    Returns:
        The Coal convex shape.
    """
    vector = coal.StdVec_Vec3s()
    vector.extend(list(np.asarray(points, dtype=float)))
    geometry = coal.Convex.convexHull(vector, False, None)
    if padding > 0:
        geometry.setSweptSphereRadius(float(padding))
    return geometry


def write_obj(path: Path, vertices: np.ndarray, triangles: np.ndarray, comment: str) -> Path:
    """Write a Wavefront OBJ file (vertices [m], 1-based triangle indices).

    Args:
        path: The file to write.
        vertices: ``(n, 3)`` vertex positions [m].
        triangles: ``(m, 3)`` 0-based vertex indices.
        comment: A first line, written as an OBJ comment.

    Returns:
        ``path``.
    """
    lines = [f"# {comment}"]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in triangles]
    path.write_text("\n".join(lines) + "\n")
    return path


def _centred(vertices: np.ndarray) -> np.ndarray:
    return vertices - (vertices.min(axis=0) + vertices.max(axis=0)) / 2


def _bottle() -> np.ndarray:
    """A 0.2 m bottle: a 33 mm radius body, a shoulder, a 13 mm neck."""
    return np.array(
        [[0, 0], [0.030, 0], [0.033, 0.006], [0.033, 0.120], [0.028, 0.140],
         [0.018, 0.155], [0.013, 0.165], [0.013, 0.195], [0.014, 0.2], [0, 0.2]],
        dtype=float,
    )  # fmt: skip


def _vase() -> np.ndarray:
    """A 0.16 m vase: a 45 mm belly narrowing to a 28 mm mouth."""
    z = np.linspace(0.0, 0.16, 17)
    radius = 0.028 + 0.017 * np.sin(np.pi * z / 0.16) ** 1.5
    return np.concatenate([[[0.0, 0.0]], np.stack([radius, z], 1), [[0.0, 0.16]]])


def _cup() -> np.ndarray:
    """A 0.1 m tapered cup: 30 mm radius at the foot, 40 mm at the rim."""
    return np.array([[0, 0], [0.030, 0], [0.040, 0.1], [0, 0.1]], dtype=float)


def _pebble(seed: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """An irregular convex pebble about 70 x 55 x 45 mm (a squashed, jittered sphere)."""
    rng = np.random.default_rng(seed)
    directions = rng.normal(size=(160, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    radii = 1.0 + 0.12 * rng.uniform(-1, 1, size=160)
    points = directions * radii[:, None] * np.array([0.035, 0.0275, 0.0225])
    hull = ConvexHull(points)
    return points, hull.simplices


#: The generated meshes: ``name -> description``.
SHIPPED_MESHES = {
    "bottle": "0.2 m bottle, 33 mm body radius, 13 mm neck",
    "vase": "0.16 m vase, 45 mm belly, 28 mm mouth",
    "cup": "0.1 m tapered cup, 30-40 mm radius",
    "pebble": "irregular convex pebble, about 70 x 55 x 45 mm",
}


def write_shipped_meshes(folder: Path) -> list[Path]:
    """Generate the shipped meshes (:data:`SHIPPED_MESHES`) as OBJ files in ``folder``.

    Args:
        folder: Where to write them (created if missing).

    Returns:
        The written files.
    """
    folder.mkdir(parents=True, exist_ok=True)
    solids = {
        "bottle": revolution_mesh(_bottle()),
        "vase": revolution_mesh(_vase()),
        "cup": revolution_mesh(_cup()),
        "pebble": _pebble(),
    }
    written = []
    for name, (vertices, triangles) in solids.items():
        comment = f"openup-ompl generated mesh '{name}': {SHIPPED_MESHES[name]} [m]"
        written.append(write_obj(folder / f"{name}.obj", _centred(vertices), triangles, comment))
    return written


if __name__ == "__main__":  # regenerate: python -m openup_ompl.meshes scenes/meshes
    import sys

    for file in write_shipped_meshes(Path(sys.argv[1] if len(sys.argv) > 1 else "meshes")):
        print(file)
