"""From the fit's pose covariance to the hand law's ``u``, per robot, from its geometry."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from openup_ompl import _toml
from openup_ompl._model import moved_by
from openup_ompl.exceptions import ConfigError
from openup_ompl.scene import Problem

__all__ = ["COVERAGE", "clearance_per_u", "lateral_sigma", "u_from_covariance"]

#: Standard deviations of pose error the extra opening must cover (2: about 95 % of a
#: one-dimensional Gaussian error).
COVERAGE = 2.0


def _hand_extent(problem: Problem, hand: np.ndarray) -> np.ndarray:
    """Extent [m] of the hand's collision geometry along the palm frame's x, y, z axes
    (the arm at its start; the hand's shape in the palm frame does not depend on it)."""
    robot = problem.robot
    model = robot.model
    data = model.createData()
    q = robot.full_q(problem.start, hand)
    pin.forwardKinematics(model, data, q)
    palm = pin.updateFramePlacement(model, data, robot.palm_frame_id)
    fingers = moved_by(model, robot.collision_model, robot.hand_joints)
    corners = []
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)
    for geometry, finger in zip(robot.collision_model.geometryObjects, fingers, strict=True):
        if not finger:
            continue
        shape = geometry.geometry
        shape.computeLocalAABB()
        box = shape.aabb_local
        centre = (np.asarray(box.max_) + np.asarray(box.min_)) / 2
        half = (np.asarray(box.max_) - np.asarray(box.min_)) / 2
        placement = palm.actInv(data.oMi[geometry.parentJoint] * geometry.placement)
        local = centre + signs * half
        corners.append(local @ placement.rotation.T + placement.translation)
    if not corners:
        return np.zeros(3)
    points = np.concatenate(corners)
    return np.ptp(points, axis=0)


def clearance_per_u(problem: Problem) -> float:
    """The extra clearance [m] per side that one unit of ``u`` buys at maximum aperture.

    Algorithm 3 opens the hand most at ``d = mga``, to ``b + (w - c) u`` (clipped to the
    joint limits). The hand's extent across the approach axis is measured by forward
    kinematics of its collision geometry (boxes around each link, in the palm frame) at
    ``u = 0`` and ``u = 1``; half the largest growth is what each side of the object
    gains: ``k = max_axis (extent(u=1) - extent(u=0)) / 2``.

    Args:
        problem: The scene (robot, grasp pose, law).

    Returns:
        ``k`` [m per unit of ``u``], ``>= 0``.
    """
    law = problem.hand_law
    approach = np.abs(np.asarray(problem.robot.spec.approach, dtype=float))
    across = approach < 0.9  # the palm axes across the approach direction
    grown = _hand_extent(problem, law.with_options(u=1.0)(law.mga))
    base = _hand_extent(problem, law.with_options(u=0.0)(law.mga))
    growth = (grown - base)[across]
    return float(max(np.max(growth) / 2, 0.0)) if growth.size else 0.0


def _covariance_matrix(name: str, value: np.ndarray) -> np.ndarray:
    """``value`` as a 3 x 3 covariance: finite, symmetric, positive semi-definite (to a
    rounding tolerance), else :class:`ConfigError` naming ``name``."""
    expected = "a finite, symmetric, positive semi-definite 3 x 3 matrix"
    matrix = _toml.floats(value)
    if matrix is None:
        raise ConfigError(name, value, expected)
    ok = matrix.shape == (3, 3) and bool(np.all(np.isfinite(matrix)))
    if ok:
        scale = max(float(np.abs(matrix).max()), 1e-300)
        ok = bool(np.allclose(matrix, matrix.T, rtol=0, atol=1e-9 * scale))
        ok = ok and float(np.linalg.eigvalsh(0.5 * (matrix + matrix.T)).min()) >= -1e-9 * scale
    if not ok:
        shown = matrix.tolist() if matrix.size <= 9 else f"an array of shape {matrix.shape}"
        raise ConfigError(name, shown, expected)
    return matrix


def lateral_sigma(
    position_covariance: np.ndarray,
    rotation_covariance: np.ndarray,
    problem: Problem,
    sizes: np.ndarray | None = None,
) -> float:
    """The pose error's standard deviation [m] that the hand must absorb.

    The position covariance is projected on the plane across the grasp's approach axis
    (an error along the approach is absorbed by the reach itself) and, for a cylinder,
    across its axis too (the hand slides along it); its largest standard deviation is
    taken. A box's yaw about the world z axis adds ``sigma_yaw`` times its half diagonal
    in the horizontal plane (a cylinder's or sphere's yaw moves no surface).

    Args:
        position_covariance: The estimate's position covariance (3 x 3) [m²].
        rotation_covariance: Its rotation covariance (3 x 3) [rad²].
        problem: The scene (the object's shape and the grasp's approach axis).
        sizes: The fitted half-sizes [m] (default: the scene object's).

    Returns:
        The standard deviation [m].
    """
    shape = problem.object
    if shape is None:
        raise ConfigError("scene: object", None, "an [object] whose pose was estimated")
    position_covariance = _covariance_matrix("position_covariance", position_covariance)
    rotation_covariance = _covariance_matrix("rotation_covariance", rotation_covariance)
    grasp = pin.XYZQUATToSE3(problem.grasp_pose)
    approach = grasp.rotation @ np.asarray(problem.robot.spec.approach, dtype=float)
    removed = [approach / np.linalg.norm(approach)]
    if shape.shape == "cylinder":
        axis = pin.XYZQUATToSE3(shape.pose).rotation[:, 2]
        axis = axis - (axis @ removed[0]) * removed[0]
        if np.linalg.norm(axis) > 1e-6:
            removed.append(axis / np.linalg.norm(axis))
    projector = np.eye(3)
    for direction in removed:
        projector -= np.outer(direction, direction)
    variance = float(np.max(np.linalg.eigvalsh(projector @ position_covariance @ projector)))
    if shape.shape == "box":
        half = np.asarray(sizes if sizes is not None else np.asarray(shape.size) / 2)
        radius = float(np.hypot(*np.sort(half)[1:]))  # the two largest half-sides
        yaw_variance = float(rotation_covariance[2, 2])
        variance += yaw_variance * radius**2
    return math.sqrt(max(variance, 0.0))


def u_from_covariance(
    position_covariance: np.ndarray,
    rotation_covariance: np.ndarray,
    problem: Problem,
    *,
    sizes: np.ndarray | None = None,
    coverage: float = COVERAGE,
) -> float:
    """The hand law's ``u`` that covers ``coverage`` standard deviations of pose error.

    Derivation: at maximum aperture the law opens the hand to ``b + (w - c) u``, so each
    side of the object gains ``k u`` metres of clearance (:func:`clearance_per_u`, from the
    robot's forward kinematics). A lateral pose error ``e`` is absorbed while ``|e| <= k
    u``; with ``e`` Gaussian of standard deviation ``sigma`` (:func:`lateral_sigma`),
    covering ``coverage`` sigmas needs ``k u >= coverage sigma``, hence

        u = clip(coverage * sigma / k, 0, 1).

    ``u = 1`` when the hand cannot cover that error (or ``k = 0``: a hand that does not
    open with ``u``) and the error is not zero.

    Args:
        position_covariance: The estimate's position covariance (3 x 3) [m²].
        rotation_covariance: Its rotation covariance (3 x 3) [rad²].
        problem: The scene (robot, grasp, law, object).
        sizes: The fitted half-sizes [m] (default: the scene object's).
        coverage: Standard deviations to cover.

    Returns:
        ``u`` in [0, 1].
    """
    if not (math.isfinite(coverage) and coverage > 0):
        raise ConfigError("coverage", coverage, "a positive number of standard deviations")
    sigma = lateral_sigma(position_covariance, rotation_covariance, problem, sizes)
    k = clearance_per_u(problem)
    if sigma == 0:
        return 0.0
    if k <= 0:
        return 1.0
    return float(min(max(coverage * sigma / k, 0.0), 1.0))
