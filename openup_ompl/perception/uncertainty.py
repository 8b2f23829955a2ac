"""From the fit's pose covariance to the hand law's ``u``, per robot, from its geometry."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from openup_ompl import _toml
from openup_ompl._model import moved_by
from openup_ompl.exceptions import ConfigError
from openup_ompl.scene import Problem

__all__ = [
    "COVERAGE",
    "arrival_fraction",
    "clearance_per_u",
    "closing_direction",
    "lateral_sigma",
    "u_from_covariance",
]

#: Standard deviations of pose error the extra opening must cover (2: about 95 % of a
#: one-dimensional Gaussian error).
COVERAGE = 2.0


def _hand_extent(problem: Problem, hand: np.ndarray) -> np.ndarray:
    """Extent [m] of the hand's collision geometry along the palm frame's x, y, z axes
    (the arm at its start; the hand's shape in the palm frame does not depend on it)."""
    corners = _hand_corners(problem, hand)
    return np.ptp(corners, axis=0) if corners.size else np.zeros(3)


def _hand_corners(problem: Problem, hand: np.ndarray) -> np.ndarray:
    """The corners [m] of the boxes around the hand's moving links, in the palm frame."""
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
    return np.concatenate(corners) if corners else np.zeros((0, 3))


def _opening(problem: Problem) -> tuple[float, np.ndarray, np.ndarray]:
    """The clearance per side per unit of ``u`` [m], the palm-frame axis it opens along
    (the hand's closing direction), from the hand's extents at ``u = 0`` and ``u = 1``,
    and those extents [m] at ``u = 0`` (along the palm's x, y, z)."""
    law = problem.hand_law
    approach = np.abs(np.asarray(problem.robot.spec.approach, dtype=float))
    across = np.flatnonzero(approach < 0.9)  # the palm axes across the approach direction
    grown = _hand_extent(problem, law.with_options(u=1.0)(law.mga))
    base = _hand_extent(problem, law.with_options(u=0.0)(law.mga))
    growth = (grown - base)[across]
    if not growth.size:
        return 0.0, np.zeros(3), base
    axis = np.zeros(3)
    axis[across[int(np.argmax(growth))]] = 1.0
    return float(max(np.max(growth) / 2, 0.0)), axis, base


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
    return _opening(problem)[0]


def closing_direction(problem: Problem) -> np.ndarray:
    """The world unit vector along which the hand opens with ``u`` at the grasp (the palm
    axis across the approach whose extent grows most from ``u = 0`` to ``u = 1``); zeros
    for a hand that does not open with ``u``.

    Args:
        problem: The scene (robot, grasp pose, law).

    Returns:
        A unit vector ``(3,)`` in the world frame, or zeros.
    """
    axis = _opening(problem)[1]
    return np.asarray(pin.XYZQUATToSE3(problem.grasp_pose).rotation @ axis)


def _finger_reach(problem: Problem) -> float:
    """How far [m] the fingers reach from the palm frame along the approach (at ``u = 0``):
    their tips, where a grasp's contacts lie at most."""
    law = problem.hand_law
    corners = _hand_corners(problem, law.with_options(u=0.0)(law.mga))
    approach = np.asarray(problem.robot.spec.approach, dtype=float)
    return float(np.max(corners @ approach)) if corners.size else 0.0


def _grasp_approach(problem: Problem) -> np.ndarray:
    """The unit direction (world frame) the palm moves in to reach the grasp."""
    grasp = pin.XYZQUATToSE3(problem.grasp_pose)
    approach = grasp.rotation @ np.asarray(problem.robot.spec.approach, dtype=float)
    return np.asarray(approach / np.linalg.norm(approach))


def arrival_fraction(problem: Problem, sizes: np.ndarray | None = None) -> float:
    """The share of the law's extra opening left when the fingertips reach the object.

    Algorithm 3 opens the hand most at ``d = mga`` and closes it linearly to ``c`` at the
    grasp, so the clearance one unit of ``u`` buys at a distance ``d < mga`` is ``k u d /
    mga`` (:func:`clearance_per_u` gives ``k``). What the opening must clear is the
    object where the fingertips first pass it: on a straight final approach the fingertips
    reach the object's near extent (along the approach) when the palm is ``s = r - t``
    from the grasp, with ``r`` the fingers' reach from the palm (:func:`_finger_reach`)
    and ``t`` the object's near extent from the grasp position, both along the approach;
    there ``d = s / D0`` (``D0`` the start's palm distance, Algorithm 1's denominator) and
    the share left is ``min(1, d / mga)``. A law that arrives open (``open_arrival``)
    keeps its whole extra opening: 1.

    Args:
        problem: The scene at the estimate (robot, grasp, law, object).
        sizes: The object's half-extents [m] along its axes (default: the scene shape's).

    Returns:
        The share, in ``(0, 1]`` (unitless).

    Raises:
        ConfigError: The problem has no object.
    """
    shape = problem.object
    if shape is None:
        raise ConfigError("scene: object", None, "an [object] the hand closes on")
    law = problem.hand_law
    if law.open_arrival:
        return 1.0
    from openup_ompl.hand_law import NormalizedDistance
    from openup_ompl.perception.nominal import nominal_of

    nominal = nominal_of(shape)
    half = np.asarray(sizes, dtype=float) if sizes is not None else nominal.half
    placement = pin.XYZQUATToSE3(shape.pose)
    grasp = problem.grasp
    approach = _grasp_approach(problem)
    near = (placement.act(nominal.centre) - grasp.translation) @ approach
    near -= float(np.abs(placement.rotation.T @ approach) @ half)
    depth = _finger_reach(problem) - near  # palm travel [m] with the tips past the near side
    robot = problem.robot
    start = robot.palm_placement(robot.model.createData(), robot.full_q(problem.start, law(1.0)))
    distance = NormalizedDistance(grasp, start, law.distance, law.rotation_weight)
    # At least 1 % of mga: a grasp whose tips do not reach the object still opens a little.
    d = max(depth / distance.start_distance, 0.01 * law.mga)
    return float(min(d / law.mga, 1.0))


def _finger_half_width(problem: Problem) -> float:
    """Half the hand's extent [m] across both its closing direction and the approach
    (a finger pad's half-width for a parallel gripper)."""
    _, axis, extents = _opening(problem)
    approach = np.abs(np.asarray(problem.robot.spec.approach, dtype=float)) >= 0.9
    side = ~approach & (axis == 0)
    return float(extents[side].max() / 2) if side.any() else 0.0


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
    cross_covariance: np.ndarray | None = None,
) -> float:
    """The pose error's standard deviation [m] that the hand's opening must absorb: the
    error of the object's surface along the grasp's closing direction, at the contacts.

    The error of a point ``r`` from the object's centre (world frame) is ``dp + dtheta x r``;
    along the closing direction ``n`` it is ``g . (dp, dtheta)`` with ``g = (n, r x n)``,
    whose variance is ``g^T Sigma g`` (``Sigma`` the pose's 6 x 6 covariance). The contacts
    are taken where the fingers meet the object: the fingertips' position at the grasp
    (the palm's plus the fingers' reach along the approach) relative to the object,
    clipped to the object's extents, and moved
    along the direction across both the closing direction and the approach to either
    edge of the fingers there (half the hand's extent that way, at most the object's: a
    turn about the approach moves a box's face under the finger's edges); the largest
    variance is taken. An error along the approach is absorbed by the reach itself, and a
    turn about a symmetry axis of the shape moves no surface: the estimate's covariance
    carries none (:func:`~openup_ompl.perception.perceive.without_turns`); a
    covariance given here without it has it removed. The grasp's closing direction is the
    hand's (:func:`closing_direction`); the object's pose is the problem's.

    Args:
        position_covariance: ``(3, 3)`` [m^2], world frame.
        rotation_covariance: ``(3, 3)`` [rad^2] of a small world-frame rotation.
        problem: The scene at the estimate (object and grasp).
        sizes: The object's half-extents [m] along its axes (default: the scene shape's).
        cross_covariance: ``(3, 3)`` covariance between the position and the rotation
            (default zero).

    Returns:
        The standard deviation [m].
    """
    shape = problem.object
    if shape is None:
        raise ConfigError("scene: object", None, "an [object] whose pose was estimated")
    covariance = np.zeros((6, 6))
    covariance[:3, :3] = _covariance_matrix("position_covariance", position_covariance)
    covariance[3:, 3:] = _covariance_matrix("rotation_covariance", rotation_covariance)
    if cross_covariance is not None:
        covariance[:3, 3:] = np.asarray(cross_covariance, dtype=float)
        covariance[3:, :3] = covariance[:3, 3:].T
    from openup_ompl.perception.nominal import nominal_of

    nominal = nominal_of(shape)
    placement = pin.XYZQUATToSE3(shape.pose)
    axes = nominal.symmetry_axes(placement.rotation)
    keep = np.eye(6)
    if axes.size:
        keep[3:, 3:] -= axes.T @ axes
    covariance = keep @ covariance @ keep.T
    closing = closing_direction(problem)
    if not np.any(closing):
        # A hand that does not open: the largest error across the approach, for the record.
        return _across_approach(covariance[:3, :3], problem)
    half = np.asarray(sizes, dtype=float) if sizes is not None else nominal.half
    return math.sqrt(max(0.0, max(_closing_variances(covariance, problem, closing, half))))


def _contacts(problem: Problem, closing: np.ndarray, half: np.ndarray) -> list[np.ndarray]:
    """Points (world, from the object's centre) where the fingers meet the object."""
    assert problem.object is not None
    from openup_ompl.perception.nominal import nominal_of

    placement = pin.XYZQUATToSE3(problem.object.pose)
    centre = placement.act(nominal_of(problem.object).centre)
    approach = _grasp_approach(problem)
    tips = np.asarray(problem.grasp_pose[:3], dtype=float) + _finger_reach(problem) * approach
    local = placement.rotation.T @ (tips - centre)
    reach = placement.rotation @ np.clip(local, -half, half)
    reach = reach - (reach @ closing) * closing
    side = np.cross(closing, approach)
    if np.linalg.norm(side) < 1e-9:
        return [reach]
    side /= np.linalg.norm(side)
    extent = float(np.abs(placement.rotation.T @ side) @ half)  # the box's support along it
    extent = min(extent, _finger_half_width(problem))
    return [reach, reach + extent * side, reach - extent * side]


def _closing_variances(
    covariance: np.ndarray, problem: Problem, closing: np.ndarray, half: np.ndarray
) -> list[float]:
    """The error variance [m^2] along ``closing`` at each contact (:func:`_contacts`)."""
    variances = []
    for lever in _contacts(problem, closing, half):
        g = np.concatenate([closing, np.cross(lever, closing)])
        variances.append(float(g @ covariance @ g))
    return variances


def _across_approach(position_covariance: np.ndarray, problem: Problem) -> float:
    """The largest standard deviation [m] of the position across the grasp's approach."""
    approach = _grasp_approach(problem)
    projector = np.eye(3) - np.outer(approach, approach)
    return math.sqrt(
        max(0.0, float(np.max(np.linalg.eigvalsh(projector @ position_covariance @ projector))))
    )


def u_from_covariance(
    position_covariance: np.ndarray,
    rotation_covariance: np.ndarray,
    problem: Problem,
    *,
    sizes: np.ndarray | None = None,
    coverage: float = COVERAGE,
    cross_covariance: np.ndarray | None = None,
    at_arrival: bool = False,
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

    ``at_arrival=True`` asks for the cover where the fingertips first pass the object
    rather than at the maximum aperture: the law has closed the hand to a share ``f`` of
    its extra opening there (:func:`arrival_fraction`), so ``k`` becomes ``f k``.

    Args:
        position_covariance: ``(3, 3)`` [m^2], world frame.
        rotation_covariance: ``(3, 3)`` [rad^2] of a small world-frame rotation.
        problem: The scene at the estimate (robot, grasp, law, object).
        sizes: The object's half-extents [m] (default: the scene shape's).
        coverage: Standard deviations to cover.
        cross_covariance: ``(3, 3)`` position-rotation covariance (default zero).
        at_arrival: Cover the error where the fingertips reach the object.

    Returns:
        ``u`` in [0, 1].
    """
    if not isinstance(at_arrival, (bool, np.bool_)):
        raise ConfigError("at_arrival", at_arrival, "true or false")
    if not (math.isfinite(coverage) and coverage > 0):
        raise ConfigError("coverage", coverage, "a positive number of standard deviations")
    sigma = lateral_sigma(
        position_covariance, rotation_covariance, problem, sizes, cross_covariance
    )
    k = clearance_per_u(problem)
    if sigma == 0:
        return 0.0
    if at_arrival:
        k *= arrival_fraction(problem, sizes)
    if k <= 0:
        return 1.0
    return float(min(max(coverage * sigma / k, 0.0), 1.0))
