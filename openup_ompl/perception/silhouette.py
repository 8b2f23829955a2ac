"""The view's free space, where the fitted object may not project
(:class:`Silhouette`; used by :func:`~openup_ompl.perception.fit.fit_superquadric`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from openup_ompl.perception.superquadric import _angles

__all__ = ["DEPTH_MARGIN", "Silhouette"]

#: How far [m] a fitted surface may come before the depth its pixel measured (the
#: sensor's noise and the pixel's footprint on a slanted surface: centimetres would
#: still be caught).
DEPTH_MARGIN = 0.01


@dataclass(frozen=True)
class Silhouette:
    """Free space seen by the camera: where the object may not project.

    A depth camera also sees past the object: a pixel that saw the table or the wall
    behind says the object is not in front of it. Without this a partial view leaves the
    unseen side free (a can's visible front half fits an ellipse reaching centimetres
    behind it equally well). Each surface sample of the superquadric that projects onto
    such a pixel adds a residual: its image distance to the allowed region (the object's
    pixels and pixels of occluders in front of it) beyond one pixel (the object's edge lies
    somewhere between its last pixel centre and the next), in metres at its depth.

    The camera cannot see through the table the object stands on: a sample below the
    table's top hides behind it, and a view from above let the fitted can grow through
    the table, or float above it (the top face seen, the bottom hidden). With the
    ``support``'s height each sample below it adds its depth below it, and one residual,
    weighted as all the points together, holds the lowest sample on it: the object stands
    on its support.

    A ray that measured a surface also says the space before it is free: a sample nearer
    the camera than the depth its pixel measured (on the object or an occluder), by more
    than :data:`DEPTH_MARGIN`, adds the difference (an occluder's pixels otherwise leave
    the fit free to grow towards the camera, through the occluder: README, Perception).

    Attributes:
        distance: ``(H, W)`` pixel distance to the allowed region (0 inside it).
        position: Camera position [m], world frame.
        rotation: Camera frame (x right, y down, z forward) in the world frame.
        intrinsics: ``(fx, fy, cx, cy)`` [px].
        samples: Surface sample angles (:func:`~openup_ompl.perception.superquadric._angles`).
        support: Height [m, world z] of the surface the object stands on (None: unknown).
        depth: ``(H, W)`` depth [m] measured at the allowed pixels (-inf elsewhere: no
            bound); None: no depth bound.
        max_incidence: The sensor's grazing limit [deg]: a face seen beyond it gives no
            point (a point on it is another face's, put across their edge by the noise).
    """

    distance: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    intrinsics: tuple[float, float, float, float]
    samples: np.ndarray
    support: float | None = None
    depth: np.ndarray | None = None
    max_incidence: float = 90.0  # [deg]

    @classmethod
    def from_view(
        cls,
        object_mask: np.ndarray,
        occluder_mask: np.ndarray,
        position: np.ndarray,
        rotation: np.ndarray,
        intrinsics: tuple[float, float, float, float],
        samples: tuple[int, int] = (10, 20),
        support: float | None = None,
        depth: np.ndarray | None = None,
        max_incidence: float = 90.0,
    ) -> Silhouette:
        """The free space of one view.

        Args:
            object_mask: ``(H, W)`` the object's pixels.
            occluder_mask: ``(H, W)`` pixels whose hit is in front of the object (where it
                may hide) or that measured nothing.
            position, rotation: The camera's pose, world frame ([m]; ``(3, 3)``, world from
                camera).
            intrinsics: ``(fx, fy, cx, cy)`` [pixels].
            samples: Numbers of latitudes and longitudes of the surface samples.
            support: Height [m, world z] of the surface under the object, or ``None``.
            depth: ``(H, W)`` measured depth [m] (NaN: none), or ``None``.
            max_incidence: The sensor's grazing limit [deg].
        Returns:
            Its pixel distances to the allowed region, camera, samples, support, depth bound.
        """
        from scipy.ndimage import distance_transform_edt

        allowed = object_mask | occluder_mask
        distance = distance_transform_edt(~allowed)
        free = None
        if depth is not None:
            free = np.where(allowed & np.isfinite(depth), depth, -np.inf)
        return cls(
            np.asarray(distance, dtype=float),
            position,
            rotation,
            intrinsics,
            _angles(*samples),
            support,
            free,
            max_incidence,
        )

    def excess(self, world: np.ndarray) -> np.ndarray:
        """Each world point's image distance beyond the allowed region, plus its depth
        below the :attr:`support`.

        Args:
            world: Points [m], world frame, shape ``(..., 3)``.

        Returns:
            The excess [m] (image distance scaled to the point's depth), shape ``(...)``.
        """
        from scipy.ndimage import map_coordinates

        fx, fy, cx, cy = self.intrinsics
        shape = world.shape[:-1]
        camera = (world.reshape(-1, 3) - self.position) @ self.rotation
        z = np.maximum(camera[:, 2], 1e-3)
        column = fx * camera[:, 0] / z + cx - 0.5
        row = fy * camera[:, 1] / z + cy - 0.5
        pixels = map_coordinates(self.distance, [row, column], order=1, mode="nearest")
        excess = (np.maximum(pixels - 1.0, 0.0) * z / fx).reshape(shape)
        if self.depth is not None:
            height, width = self.depth.shape
            r = np.clip(np.round(row).astype(int), 0, height - 1)
            c = np.clip(np.round(column).astype(int), 0, width - 1)
            inside = (row > -0.5) & (row < height - 0.5) & (column > -0.5) & (column < width - 0.5)
            before = np.where(inside, self.depth[r, c] - DEPTH_MARGIN - camera[:, 2], 0.0)
            excess = excess + np.maximum(before, 0.0).reshape(shape)
        if self.support is None:
            return excess
        return excess + np.maximum(self.support - world[..., 2], 0.0)
