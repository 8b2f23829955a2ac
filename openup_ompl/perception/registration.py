"""A mesh object's pose from its cloud: the known convex hull registered onto the points.

A superquadric cannot take a bottle's shape (a body, a shoulder, a neck): fitted to one,
its centre sits centimetres off the bottle's (README, Perception).
The scene names the mesh, so its pose is refined by least squares of each point's signed
distance to the hull (``max_i (n_i . q - d_i)`` over the hull's face planes, ``q`` the
point in the mesh's frame: exact inside and on the faces, a lower bound beyond an edge),
from the superquadric's estimate and its equivalent flips, with the resting on the
support as for the superquadric. Its covariance is the Gauss-Newton one over the
directions the shape can show: turns about an axis of revolution move no surface and are
left out (zero variance: the grasp of a round object does not care about them).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

__all__ = ["Registration", "register_hull"]


@dataclass(frozen=True)
class Registration:
    """The hull's registered pose and its covariance.

    Attributes:
        placement: The mesh frame's pose in the world.
        covariance: ``(6, 6)`` covariance of the position [m] and a small world-frame
            rotation [rad] (in that order).
        residual_rms: The points' residuals' standard deviation [m].
        cost: Half the sum of squared residuals at the optimum.
    """

    placement: pin.SE3
    covariance: np.ndarray
    residual_rms: float
    cost: float


def _planes(vertices: np.ndarray) -> np.ndarray:
    """The hull's face planes ``(m, 4)``: unit outward normal and offset (``n . q <= d``
    inside), in the mesh's frame."""
    from scipy.spatial import ConvexHull

    equations = ConvexHull(vertices).equations  # n . q + c <= 0 inside
    return np.column_stack([equations[:, :3], -equations[:, 3]])


def _moved(x: np.ndarray, start: pin.SE3) -> tuple[np.ndarray, np.ndarray]:
    """The rotation and position of parameters ``x`` (a position change and a world-frame
    rotation vector) applied to ``start``."""
    rotation = pin.exp3(x[3:6]) @ start.rotation
    return rotation, start.translation + x[:3]


def _residuals(
    x: np.ndarray,
    start: pin.SE3,
    points: np.ndarray,
    planes: np.ndarray,
    vertices: np.ndarray,
    weights: np.ndarray | None,
    support: float | None,
) -> np.ndarray:
    rotation, position = _moved(x, start)
    local = (points - position) @ rotation
    distance = (local @ planes[:, :3].T - planes[:, 3]).max(axis=1)
    if weights is not None:
        distance = distance * weights
    if support is None:
        return distance
    lowest = float((vertices @ rotation.T)[:, 2].min() + position[2])
    return np.append(distance, (lowest - support) * math.sqrt(points.shape[0]))


def _jacobian(x: np.ndarray, *args: object) -> np.ndarray:
    steps = np.array([1e-6] * 3 + [1e-5] * 3)
    columns = []
    for k in range(6):
        step = np.zeros(6)
        step[k] = steps[k]
        forward = _residuals(x + step, *args)  # type: ignore[arg-type]
        backward = _residuals(x - step, *args)  # type: ignore[arg-type]
        columns.append((forward - backward) / (2 * steps[k]))
    return np.column_stack(columns)


def register_hull(
    points: np.ndarray,
    vertices: np.ndarray,
    starts: list[pin.SE3],
    symmetry_axes: Callable[[np.ndarray], np.ndarray],
    noise: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    support: float | None = None,
) -> Registration:
    """Register the hull of ``vertices`` (mesh frame [m]) onto ``points`` (world [m]).

    Args:
        points: The object's measured points.
        vertices: The mesh's hull vertices in its own frame.
        starts: Candidate poses of the mesh frame; each is refined, the lowest cost wins.
        symmetry_axes: ``axes(rotation) -> (k, 3)`` world axes of the shape's rotations
            that move no surface (:meth:`~openup_ompl.perception.nominal.Nominal.symmetry_axes`).
        noise: ``noise(points, normals) -> sigma`` [m] for weights (as the superquadric
            fit's); None: unweighted.
        support: Height [m] of the surface the object stands on (None: unknown).

    Returns:
        The best start's registered pose, with its covariance.
    """
    from scipy.optimize import least_squares

    planes = _planes(vertices)
    best = None
    for start in starts:
        args: tuple[Any, ...] = (start, points, planes, vertices, None, support)
        result = least_squares(_residuals, np.zeros(6), args=args, method="lm", max_nfev=400)
        if best is None or result.cost < best[0].cost:
            best = (result, start)
    assert best is not None
    result, start = best
    rotation, position = _moved(result.x, start)
    placement = pin.SE3(rotation, position)
    weights = None
    if noise is not None:
        local = (points - position) @ rotation
        face = np.argmax(local @ planes[:, :3].T - planes[:, 3], axis=1)
        sigma = noise(points, planes[face, :3] @ rotation.T)
        weights = float(np.mean(sigma)) / sigma
        args = (placement, points, planes, vertices, weights, support)
        refined = least_squares(_residuals, np.zeros(6), args=args, method="lm", max_nfev=400)
        rotation, position = _moved(refined.x, placement)
        placement = pin.SE3(rotation, position)
    args = (placement, points, planes, vertices, weights, support)
    residuals = _residuals(np.zeros(6), *args)
    jacobian = _jacobian(np.zeros(6), *args)
    n = points.shape[0]
    variance = float(residuals[:n] @ residuals[:n] / max(n - 6, 1))
    # The directions the shape shows: the position and the turns off its symmetry axes.
    axes = symmetry_axes(rotation)
    turns = np.eye(3) - axes.T @ axes if axes.size else np.eye(3)
    values, vectors = np.linalg.eigh(turns)
    basis = np.zeros((6, 3 + int(np.sum(values > 0.5))))
    basis[:3, :3] = np.eye(3)
    basis[3:, 3:] = vectors[:, values > 0.5]
    reduced = jacobian @ basis
    information = reduced.T @ reduced
    covariance = basis @ np.linalg.pinv(information, rcond=1e-12) @ basis.T * variance
    unweighted = residuals[:n] / weights if weights is not None else residuals[:n]
    return Registration(
        placement,
        covariance,
        float(np.sqrt(unweighted @ unweighted / max(n - 6, 1))),
        float(0.5 * residuals @ residuals),
    )
