"""The object's pose in the scene shape's frame, from the superquadric fit (and, for a
mesh, its hull registered onto the cloud), with the covariances of its position and
rotation."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from openup_ompl.perception.covariance import Outline, SuperquadricFit
from openup_ompl.perception.nominal import Nominal, nominal_of
from openup_ompl.perception.registration import register_hull
from openup_ompl.perception.superquadric import ROTATION
from openup_ompl.scene import Shape

__all__ = ["estimate", "estimated_pose", "symmetric_turn"]


#: The largest ratio of a superquadric's ``a1``, ``a2`` that still reads as a round
#: section about its z (:func:`_cylinder_axis`).
ROUND_SECTION = 1.25
#: The weight of the scene's axis in :func:`_cylinder_axis` against the half-sizes' log
#: ratios: a tie-breaker, small against the log ratio of a can's long and short sides.
AXIS_PRIOR = 0.2


def estimate(
    fit: SuperquadricFit,
    shape: Shape,
    points: np.ndarray,
    weights: Callable[[np.ndarray, np.ndarray], np.ndarray] | None,
    support: float | None,
    size_sigma: float = 0.0,
    outline: Outline | None = None,
    covariance: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The object's pose and its covariance: the superquadric's for a primitive, with a
    turn about a symmetry axis of the shape held (it moves no surface), or a mesh's hull
    registered from it (:mod:`~openup_ompl.perception.registration`).

    Args:
        fit: The superquadric fitted to the object's points.
        shape: The scene's shape of the object (its kind, dimensions and nominal pose).
        points: The object's measured points [m], world frame, shape ``(n, 3)``.
        weights: ``noise(points, normals) -> sigma`` [m] weighting a mesh's registration;
            ``None``: unweighted.
        support: Height [m] of the surface the object stands on (``None``: unknown).
        size_sigma: How well the scene's dimensions are known [m] (see
            :meth:`~openup_ompl.perception.covariance.SuperquadricFit.pose_covariance`;
            0: the superquadric's sizes free).
        outline: The view's edges, for a primitive's covariance (see
            :meth:`~openup_ompl.perception.covariance.SuperquadricFit.pose_covariance`).
        covariance: The sensor noise's covariance at each point, for a mesh's
            registration (:func:`~openup_ompl.perception.registration.register_hull`).

    Returns:
        ``(pose, covariance)``: the pose ``[x, y, z, qx, qy, qz, qw]`` [m, unit
        quaternion] of the shape's frame in the world, and the ``(6, 6)`` covariance of
        its position [m] and a small world-frame rotation [rad].
    """
    pose, fixed = _fitted_pose(fit, shape)
    if shape.shape != "mesh":
        return pose, fit.pose_covariance(fixed, size_sigma, _size_groups(fixed), outline)
    from openup_ompl.meshes import hull_points

    assert shape.file is not None
    nominal = nominal_of(shape)
    start = pin.XYZQUATToSE3(pose)
    flips = [np.eye(3)]
    if nominal.symmetry == "axis":  # end over end: a bottle upside down
        flips.append(np.asarray(pin.exp3(np.pi * np.eye(3)[(nominal.axis + 1) % 3])))
    elif nominal.symmetry == "none":
        flips += [np.asarray(pin.exp3(np.pi * axis)) for axis in np.eye(3)]
    starts = [pin.SE3(start.rotation @ flip, start.translation) for flip in flips]
    vertices = np.asarray(hull_points(shape.file, shape.scale or 1.0), dtype=float)
    axes = nominal.symmetry_axes
    registered = register_hull(points, vertices, starts, axes, weights, support, covariance)
    placement = registered.placement
    if nominal.symmetry != "none":
        # The turn about the axis is not measured: keep the scene's (the grasp moves with it).
        reference = pin.XYZQUATToSE3(shape.pose).rotation
        rotation = symmetric_turn(placement.rotation[:, nominal.axis], reference, nominal)
        centre = placement.act(nominal.centre)
        placement = pin.SE3(rotation, centre - rotation @ nominal.centre)
    return np.asarray(pin.SE3ToXYZQUAT(placement), dtype=float), registered.covariance


def _size_groups(fixed: list[int]) -> list[list[int]]:
    """The superquadric's half-sizes that err together, from the rotations held about the
    shape's symmetry axes (:func:`_fitted_pose`): the two radii about an axis of
    revolution, a ball's three."""
    if len(fixed) == 3:
        return [[0, 1, 2]]
    if len(fixed) == 1:
        column = fixed[0] - ROTATION.start
        return [[k for k in range(3) if k != column], [column]]
    return [[0], [1], [2]]


def estimated_pose(fit: SuperquadricFit, nominal: Shape) -> np.ndarray:
    """The fitted pose in the frame of the scene's shape.

    The superquadric's frame is one of several equivalent ones: a box's axes may be
    permuted and flipped, a solid of revolution's (a cylinder's, a round mesh's) axis
    flipped and its turn about the axis is unobservable, a sphere's orientation is. Among
    the equivalent orientations the one closest to the scene's nominal orientation is
    returned (harmless: they describe the same solid). A box's (or another mesh's) axes
    are matched to the scene's extents by the fitted half-sizes' order. The fitted centre
    is the centre of the shape's bounding box
    (:class:`~openup_ompl.perception.nominal.Nominal`), which a mesh's file may place away
    from its origin.

    Args:
        fit: The superquadric fitted to the object's points.
        nominal: The scene's shape of the object.

    Returns:
        The pose ``[x, y, z, qx, qy, qz, qw]`` [m, unit quaternion] of the shape's frame
        in the world.
    """
    return _fitted_pose(fit, nominal)[0]


def _fitted_pose(fit: SuperquadricFit, nominal: Shape) -> tuple[np.ndarray, list[int]]:
    """:func:`estimated_pose`, and the superquadric's rotation parameters (indices in
    :data:`~openup_ompl.perception.superquadric.PARAMETERS`) about the shape's symmetry
    axes."""
    sq = fit.superquadric
    rotation = sq.rotation
    shape = nominal_of(nominal)
    reference = pin.XYZQUATToSE3(nominal.pose).rotation
    if shape.symmetry == "axis":
        k = shape.axis
        column = _cylinder_axis(
            sq.sizes, sq.exponents, shape.radius, float(shape.half[k]), rotation.T @ reference[:, k]
        )
        rotation = symmetric_turn(rotation[:, column], reference, shape)
        fixed = [ROTATION.start + column]
    elif shape.symmetry == "all":
        rotation = reference
        fixed = list(range(ROTATION.start, ROTATION.stop))
    else:
        fixed = []
        sizes = sq.sizes
        if sq.exponents[1] > DIAMOND:
            # A diamond section: its axes are the box's diagonals, its half-sides a1 a2 /
            # sqrt(a1^2 + a2^2) (a square box seen across a corner fits one).
            side = sizes[0] * sizes[1] / math.hypot(sizes[0], sizes[1])
            sizes = np.array([side, side, sizes[2]])
            rotation = rotation @ np.asarray(pin.exp3(np.array([0.0, 0.0, math.pi / 4])))
        rotation = _box_rotation(sizes, rotation, shape.half, reference)
    position = sq.position - rotation @ shape.centre
    return np.asarray(pin.SE3ToXYZQUAT(pin.SE3(rotation, position)), dtype=float), fixed


#: A superquadric cross-section exponent ``e2`` above this is a diamond: a box's section
#: turned by 45 degrees about its z (``e2 = 2`` is exactly one).
DIAMOND = 1.5
#: Two half-sizes within this ratio are interchangeable when a box's (or another
#: shape's) axes are matched to the fit's: a square section's two sides.
SAME_SIZE = 1.15


def _box_rotation(
    sizes: np.ndarray, rotation: np.ndarray, half: np.ndarray, reference: np.ndarray
) -> np.ndarray:
    """The fitted frame's axes matched to a shape of ``half`` extents, nearest the
    ``reference`` orientation: the axes permuted so that the fitted half-sizes best match
    the nominal ones (by log ratio; any permutation within :data:`SAME_SIZE` of the best
    counts as a match: the noise orders a square section's equal sides at random), and
    flipped; of those proper rotations, the nearest the reference."""
    costs = {
        order: sum(abs(math.log(sizes[order[j]] / half[j])) for j in range(3))
        for order in itertools.permutations(range(3))
    }
    best_cost = min(costs.values())
    best, best_angle = rotation, np.inf
    for order, cost in costs.items():
        if cost > best_cost + 2 * math.log(SAME_SIZE):
            continue
        permuted = rotation[:, list(order)]
        for signs in itertools.product((1.0, -1.0), repeat=3):
            candidate = permuted * np.array(signs)
            if np.linalg.det(candidate) < 0:
                continue
            angle = float(np.linalg.norm(pin.log3(reference.T @ candidate)))
            if angle < best_angle:
                best, best_angle = candidate, angle
    return np.asarray(best)


def symmetric_turn(axis: np.ndarray, reference: np.ndarray, shape: Nominal) -> np.ndarray:
    """The orientation of a solid of revolution whose axis lies along ``axis`` (world,
    either sign), nearest the ``reference`` orientation: its turn about the axis, which
    moves no surface, is the reference's (a sphere's whole orientation is).

    Args:
        axis: The axis's direction, world frame, shape ``(3,)`` (unit, either sign).
        reference: The nominal orientation (world from shape), shape ``(3, 3)``.
        shape: The shape's symmetry (:func:`~openup_ompl.perception.nominal.nominal_of`).

    Returns:
        The orientation (world from shape), shape ``(3, 3)``.
    """
    if shape.symmetry == "all":
        return np.asarray(reference, dtype=float)
    k = shape.axis
    axis = axis * np.sign(axis @ reference[:, k] or 1.0)
    return np.asarray(_rotation_between(reference[:, k], axis) @ reference)


def _cylinder_axis(
    sizes: np.ndarray,
    exponents: np.ndarray,
    radius: float,
    half_length: float,
    nominal_axis: np.ndarray,
) -> int:
    """Which of the superquadric's axes is the cylinder's. Its own z when it is shaped as
    a cylinder about z (a round section, ``e2`` >= 0.5, between flat ends, ``e1`` <= 0.5,
    and ``a1``, ``a2`` within :data:`ROUND_SECTION` of each other). Otherwise the axis
    whose half-size, with the other two as radii, is the nearest to the nominal cylinder's
    (by ratio): the fit starts from every principal axis of the cloud, and a superquadric
    lying across an upright can fits a partial view about as well as one along it. A can
    as long as it is wide leaves the sizes no say: :data:`AXIS_PRIOR` times the sine of
    each axis's angle to the scene's ``nominal_axis`` (in the superquadric's frame) then
    decides."""
    e1, e2 = exponents
    if e2 >= 0.5 and e1 <= 0.5 and max(sizes[:2]) <= ROUND_SECTION * min(sizes[:2]):
        return 2
    mismatch = [
        abs(math.log(sizes[k] / half_length))
        + sum(abs(math.log(sizes[j] / radius)) for j in range(3) if j != k)
        + AXIS_PRIOR * math.sqrt(max(0.0, 1.0 - float(nominal_axis[k]) ** 2))
        for k in range(3)
    ]
    return int(np.argmin(mismatch))


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector ``a`` onto unit vector ``b``."""
    axis = np.cross(a, b)
    sine, cosine = float(np.linalg.norm(axis)), float(a @ b)
    if sine < 1e-12:
        return np.eye(3)  # parallel (antiparallel is excluded by the sign choice)
    return np.asarray(pin.exp3(axis / sine * math.atan2(sine, cosine)))
