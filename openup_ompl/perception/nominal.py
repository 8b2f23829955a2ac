"""What perception knows of the object's shape from the scene: its extents, its centre
and its symmetry, for a box, a cylinder, a sphere or a mesh alike.

A fitted superquadric's frame is one of several equivalent ones (its axes may be permuted
and flipped; about an axis of revolution its turn is arbitrary). Reading the estimate in
the scene shape's frame, and saying which rotation errors move no surface of it (those the
grasp does not care about), needs the shape's symmetry. Primitives state theirs; a mesh's
is measured on its convex hull (the solid the camera, the planner and the physics all
see): it is a solid of revolution about one of its file's axes when its hull's support
function does not change as a direction turns about that axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from openup_ompl.scene import Shape

__all__ = ["SYMMETRIES", "Nominal", "nominal_of"]

#: ``"none"``: no continuous symmetry; ``"axis"``: a solid of revolution about
#: :attr:`Nominal.axis`; ``"all"``: a ball (every rotation about its centre).
SYMMETRIES = ("none", "axis", "all")
#: A mesh's hull is round about an axis when its support function varies by at most this
#: share of its largest half-extent as a direction turns about the axis (a 32-sided
#: polygon of revolution varies by 0.5 %).
ROUND_TOLERANCE = 0.02


@dataclass(frozen=True)
class Nominal:
    """The scene shape as perception reads it, in the shape's own frame.

    Attributes:
        half: Half-extents [m] along the shape's local x, y, z (of its bounding box).
        centre: Its bounding box's centre [m] in its local frame (0 but for a mesh whose
            file's origin is elsewhere): where a fitted superquadric's centre lies.
        symmetry: One of :data:`SYMMETRIES`.
        axis: The local axis (0, 1, 2) of revolution (``symmetry == "axis"``).
    """

    half: np.ndarray
    centre: np.ndarray
    symmetry: str = "none"
    axis: int = 2

    @property
    def radius(self) -> float:
        """The largest half-extent across the axis of revolution [m]."""
        return float(max(self.half[j] for j in range(3) if j != self.axis))

    def symmetry_axes(self, rotation: np.ndarray) -> np.ndarray:
        """World unit vectors about which a rotation moves no surface of the shape.

        Args:
            rotation: The shape's orientation (world from shape), shape ``(3, 3)``.

        Returns:
            The axes as rows, shape ``(k, 3)``: none, the axis of revolution, or all three.
        """
        if self.symmetry == "all":
            return np.eye(3)
        if self.symmetry == "axis":
            return np.asarray(rotation, dtype=float)[:, self.axis][None, :].copy()
        return np.zeros((0, 3))


def nominal_of(shape: Shape) -> Nominal:
    """The scene shape's :class:`Nominal` (a mesh's from its convex hull).

    Args:
        shape: A scene shape (box, cylinder, sphere or mesh).

    Returns:
        Its half-extents [m], centre [m, shape frame] and symmetry.

    Raises:
        ConfigError: A mesh file that cannot be read (as when the scene was loaded).
    """
    if shape.shape == "box":
        assert shape.size is not None
        return Nominal(np.asarray(shape.size, dtype=float) / 2, np.zeros(3))
    if shape.shape == "cylinder":
        assert shape.radius is not None and shape.length is not None
        half = np.array([shape.radius, shape.radius, shape.length / 2])
        return Nominal(half, np.zeros(3), "axis", 2)
    if shape.shape == "sphere":
        assert shape.radius is not None
        return Nominal(np.full(3, float(shape.radius)), np.zeros(3), "all")
    from openup_ompl.meshes import hull_points

    assert shape.file is not None
    points = np.asarray(hull_points(shape.file, shape.scale or 1.0), dtype=float)
    low, high = points.min(axis=0), points.max(axis=0)
    half, centre = (high - low) / 2, (high + low) / 2
    round_axes = [k for k in range(3) if _is_round(points - centre, k, float(half.max()))]
    if len(round_axes) >= 2:
        return Nominal(half, centre, "all")
    if round_axes:
        return Nominal(half, centre, "axis", round_axes[0])
    return Nominal(half, centre)


def _is_round(points: np.ndarray, axis: int, size: float) -> bool:
    """Whether the hull of ``points`` (centred) is a solid of revolution about local
    ``axis``: its support function ``max_p p . d`` stays within :data:`ROUND_TOLERANCE` of
    ``size`` as ``d`` turns about the axis, at every tilt from it."""
    others = [j for j in range(3) if j != axis]
    turns = np.linspace(0.0, 2 * math.pi, 72, endpoint=False)
    for tilt in np.radians([30.0, 60.0, 90.0, 120.0, 150.0]):
        directions = np.zeros((turns.size, 3))
        directions[:, axis] = math.cos(tilt)
        directions[:, others[0]] = math.sin(tilt) * np.cos(turns)
        directions[:, others[1]] = math.sin(tilt) * np.sin(turns)
        support = (points @ directions.T).max(axis=0)
        if float(np.ptp(support)) > ROUND_TOLERANCE * size:
            return False
    return True
