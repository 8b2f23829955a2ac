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
    offsets: np.ndarray | None = None,
) -> np.ndarray:
    rotation, position = _moved(x, start)
    distance = _hull_distance(points, rotation, position, planes)
    if offsets is not None:
        distance = distance - offsets
    if weights is not None:
        distance = distance * weights
    if support is None:
        return distance
    lowest = float((vertices @ rotation.T)[:, 2].min() + position[2])
    return np.append(distance, (lowest - support) * math.sqrt(points.shape[0]))


def _hull_distance(
    points: np.ndarray, rotation: np.ndarray, position: np.ndarray, planes: np.ndarray
) -> np.ndarray:
    """The world points' signed distances [m] to the hull placed at ``rotation``,
    ``position`` (exact inside and on the faces, a lower bound beyond an edge)."""
    return np.asarray(_hull_distances(points, rotation, position, planes).max(axis=1))


def _hull_distances(
    points: np.ndarray, rotation: np.ndarray, position: np.ndarray, planes: np.ndarray
) -> np.ndarray:
    """Each world point's signed distance [m] to each face plane of the placed hull."""
    return np.asarray(((points - position) @ rotation) @ planes[:, :3].T - planes[:, 3])


def _expected_offsets(
    points: np.ndarray, placement: pin.SE3, planes: np.ndarray, covariances: np.ndarray
) -> np.ndarray:
    """Each point's expected distance to the placed hull under the sensor noise less its
    distance, ``E[d(p + n)] - d(p)`` [m], ``n ~ N(0, Sigma_i)``, by the unscented transform
    (the six points ``p +- sqrt(3)`` times each principal axis of ``Sigma_i``, equally
    weighted: exact for a quadratic ``d``). The distance to a convex hull is convex: a
    noisy point lies outside it on average (by ``tr(H Sigma) / 2`` on a smooth surface of
    curvature ``H``), and least squares on ``d`` moved the rigid bottle towards the camera
    by 1.0 mm at noise 4 (0.35 at noise 2) against a sigma of 0.4."""
    values, vectors = np.linalg.eigh(covariances)
    axes = vectors * np.sqrt(3.0 * np.maximum(values, 0.0))[:, None, :]
    steps = np.concatenate([axes, -axes], axis=2).transpose(0, 2, 1)  # (n, 6, 3)
    shifted = (points[:, None, :] + steps).reshape(-1, 3)
    rotation, position = placement.rotation, placement.translation
    spread = _hull_distance(shifted, rotation, position, planes).reshape(-1, 6).mean(axis=1)
    return np.asarray(spread - _hull_distance(points, rotation, position, planes))


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
    covariance: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
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
        covariance: ``covariance(points, normals) -> (n, 3, 3)`` [m^2], the sensor noise's
            covariance (world frame; :func:`~openup_ompl.perception.noise.noise_covariance`):
            the pose is refined once more with each point's distance less its expected
            excess under the noise (:func:`_expected_offsets`); None: as they are.

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
    weights = offsets = None
    face = np.argmax(_hull_distances(points, rotation, position, planes), axis=1)
    normals = planes[face, :3] @ rotation.T  # world frame
    if noise is not None:
        sigma = noise(points, normals)
        weights = float(np.mean(sigma)) / sigma
    if covariance is not None:
        offsets = _expected_offsets(points, placement, planes, covariance(points, normals))
    if weights is not None or offsets is not None:
        args = (placement, points, planes, vertices, weights, support, offsets)
        refined = least_squares(_residuals, np.zeros(6), args=args, method="lm", max_nfev=400)
        rotation, position = _moved(refined.x, placement)
        placement = pin.SE3(rotation, position)
    args = (placement, points, planes, vertices, weights, support, offsets)
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
    spread = basis @ np.linalg.pinv(information, rcond=1e-12) @ basis.T * variance
    unweighted = residuals[:n] / weights if weights is not None else residuals[:n]
    return Registration(
        placement,
        spread,
        float(np.sqrt(unweighted @ unweighted / max(n - 6, 1))),
        float(0.5 * residuals @ residuals),
    )
