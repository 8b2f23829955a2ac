"""Whether one view shows the whole object, and its free space for the fit: the checks
:func:`~openup_ompl.perception.perceive.perceive` refuses a view by."""

from __future__ import annotations

import math

import numpy as np

from openup_ompl.exceptions import ObjectCutOff, ObjectNotVisible, ObjectOccluded, TooFewPoints
from openup_ompl.perception.camera import CameraOptions, DepthCamera, DepthView
from openup_ompl.perception.fit import Silhouette
from openup_ompl.perception.noise import NoiseOptions, PointCloud
from openup_ompl.perception.superquadric import N_PARAMETERS
from openup_ompl.scene import Problem

__all__ = [
    "HIDDEN_SHARE",
    "bounded_outline",
    "checked_view",
    "occluded_outline",
    "silhouette_of",
]


def silhouette_of(
    view: DepthView, noise: NoiseOptions, camera: CameraOptions, support: float | None = None
) -> Silhouette:
    """The view's free space: the object's pixels, pixels without a measurement (dropped
    or no hit: unknown) and pixels whose hit lies in front of the object are allowed;
    nothing below the ``support``'s height [m] (:meth:`DepthCamera.support_under`), nor
    before the depth a pixel measured.

    Args:
        view: The rendered view (true depths, per pixel).
        noise: The sensor noise model (its grazing-incidence limit).
        camera: The camera options (their intrinsics).
        support: Height [m, world z] of the surface under the object, or ``None``.

    Returns:
        The view's free space for the fit.
    """
    valid = _valid(view, noise)
    shape = (view.height, view.width)
    return Silhouette.from_view(
        (view.on_object & valid).reshape(shape),
        (_occluder(view, noise) | ~valid).reshape(shape),
        view.position,
        view.rotation,
        camera.intrinsics(),
        support=support,
        depth=np.where(valid, view.depth, np.nan).reshape(shape),
        max_incidence=noise.max_incidence,
    )


def _valid(view: DepthView, noise: NoiseOptions) -> np.ndarray:
    """The pixels measured (a hit, not at grazing incidence)."""
    return np.asarray(view.hit & (view.incidence <= math.radians(noise.max_incidence)))


def _occluder(view: DepthView, noise: NoiseOptions) -> np.ndarray:
    """The measured pixels off the object nearer than its nearest point: what may hide
    part of it."""
    valid = _valid(view, noise)
    on_object = view.on_object & valid
    front = np.nanmin(view.depth[on_object]) if on_object.any() else np.inf
    return np.asarray(valid & ~view.on_object & (view.depth < front))


#: Image sides and the step (row, column) to the pixel beyond each.
_SIDES = {"top": (-1, 0), "bottom": (1, 0), "left": (0, -1), "right": (0, 1)}


def occluded_outline(view: DepthView, noise: NoiseOptions) -> dict[str, tuple[int, int]]:
    """Per image side, the object's outline pixels on it whose next pixel beyond is an
    occluder (a measured surface nearer than the object's nearest point), and all its
    outline pixels on it: ``{side: (hidden, outline)}``. The table in front of a standing
    object's base lies behind its nearest point and hides nothing.

    Args:
        view: The rendered view.
        noise: The sensor noise model (its grazing-incidence limit).

    Returns:
        ``{side: (hidden, outline)}`` pixel counts, sides ``top, bottom, left, right``.
    """
    shape = (view.height, view.width)
    on_object = view.on_object.reshape(shape)
    occluder = _occluder(view, noise).reshape(shape)
    counts = {}
    for side, (dr, dc) in _SIDES.items():
        # beyond[r, c]: the pixel (r + dr, c + dc), False off the image.
        inside = np.zeros(shape, dtype=bool)
        hidden = np.zeros(shape, dtype=bool)
        rows = slice(max(-dr, 0), shape[0] - max(dr, 0))
        cols = slice(max(-dc, 0), shape[1] - max(dc, 0))
        beyond_rows = slice(max(dr, 0), shape[0] + min(dr, 0))
        beyond_cols = slice(max(dc, 0), shape[1] + min(dc, 0))
        inside[rows, cols] = on_object[beyond_rows, beyond_cols]
        hidden[rows, cols] = occluder[beyond_rows, beyond_cols]
        outline = on_object & ~inside
        counts[side] = (int(np.count_nonzero(outline & hidden)), int(np.count_nonzero(outline)))
    return counts


def bounded_outline(view: DepthView, noise: NoiseOptions) -> int:
    """The object's outline pixels whose next pixel beyond (on any image side) measured a
    surface behind the object's nearest point: where the view bounds the object (an
    occluder's pixel hides it, a pixel without a measurement, such as a table seen at
    grazing incidence, says nothing).

    Args:
        view: The rendered view.
        noise: The sensor noise model (its grazing-incidence limit).

    Returns:
        The number of such pixels.
    """
    shape = (view.height, view.width)
    on_object = view.on_object.reshape(shape)
    valid = _valid(view, noise)
    front = np.nanmin(view.depth[view.on_object & valid]) if (view.on_object & valid).any() else 0
    behind = (valid & ~view.on_object & (view.depth >= front)).reshape(shape)
    bounded = np.zeros(shape, dtype=bool)
    for dr, dc in _SIDES.values():
        rows = slice(max(-dr, 0), shape[0] - max(dr, 0))
        cols = slice(max(-dc, 0), shape[1] - max(dc, 0))
        beyond_rows = slice(max(dr, 0), shape[0] + min(dr, 0))
        beyond_cols = slice(max(dc, 0), shape[1] + min(dc, 0))
        step = np.zeros(shape, dtype=bool)
        step[rows, cols] = behind[beyond_rows, beyond_cols]
        bounded |= step
    return int(np.count_nonzero(on_object & bounded))


#: An image side is hidden when more than this share of the object's outline on it lies
#: next to an occluder (:func:`occluded_outline`).
HIDDEN_SHARE = 0.5


def checked_view(
    problem: Problem,
    cam: DepthCamera,
    view: DepthView,
    cloud: PointCloud,
    noise: NoiseOptions,
    silhouette: bool,
) -> float | None:
    """Refuse a view that does not show the whole object (see
    :func:`~openup_ompl.perception.perceive.perceive`'s ``Raises``).

    Args:
        problem: The scene; its object is where it truly is.
        cam: The camera that rendered the view.
        view: The rendered view.
        cloud: The noisy point cloud measured from it.
        noise: The sensor noise model.
        silhouette: Whether the fit uses the view's free space.

    Returns:
        The height [m, world z] of the surface the object stands on (``None``: unknown,
        or ``silhouette`` off).

    Raises:
        PerceptionError: As :func:`~openup_ompl.perception.perceive.perceive` lists
            (object not visible, too few points, cut off, occluded).
    """
    assert problem.object is not None
    if cloud.points.shape[0] == 0:
        raise ObjectNotVisible(
            cam.position.tolist(),
            cam.target.tolist(),
            problem.object.name,
            int(view.hit.sum()),
            cloud.dropped,
        )
    if cloud.points.shape[0] < 2 * N_PARAMETERS:
        raise TooFewPoints(cloud.points.shape[0], 2 * N_PARAMETERS)
    on_object = view.on_object.reshape(view.height, view.width)
    border = {
        "top": on_object[0],
        "bottom": on_object[-1],
        "left": on_object[:, 0],
        "right": on_object[:, -1],
    }
    sides = [side for side, pixels in border.items() if pixels.any()]
    if sides:
        # The corner pixels lie on two sides: count each pixel once.
        edge = on_object.copy()
        edge[1:-1, 1:-1] = False
        raise ObjectCutOff(int(edge.sum()), sides)
    support = cam.support_under(cloud.points, view) if silhouette else None
    hidden = {
        side: count
        for side, (count, outline) in occluded_outline(view, noise).items()
        if count > HIDDEN_SHARE * outline and not (side == "bottom" and support is not None)
    }
    if hidden:
        raise ObjectOccluded(sum(hidden.values()), list(hidden))
    return support
