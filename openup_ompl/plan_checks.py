"""The checks of a plan file's path against the plan's own robot model and hand law:
rows of finite numbers within the joint limits, leaving from the start and ending at the
grasp pose, the hand on the law at every row.

:class:`~openup_ompl.plan.PlanFile` applies them to every plan it reads; they need the
URDF's model only, not the scene or robot TOML the plan was made from.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl.exceptions import ConfigError
from openup_ompl.hand_law import HandLaw, palm_distance
from openup_ompl.ik import MAX_POSITION_TOLERANCE, MAX_ROTATION_TOLERANCE

#: Slack [rad or m] a plan file's path may have beyond a joint limit (the planner's rows
#: lie within the limits; this only absorbs rounding).
LIMIT_TOLERANCE = 1e-6

#: How far [m] the palm may be from a plan's grasp pose at the path's last row: a plan
#: ends where IK put the palm (within ``IKOptions.position_tolerance``, 1e-5 m by
#: default; :class:`~openup_ompl.ik.IKOptions` refuses more than this).
GRASP_POSITION_TOLERANCE = MAX_POSITION_TOLERANCE
#: The same for the palm's rotation [rad].
GRASP_ROTATION_TOLERANCE = MAX_ROTATION_TOLERANCE


def number_rows(value: Any, where: str, width: int) -> np.ndarray:
    """Check a table of numbers.

    Args:
        value: A non-empty list (or 2-D numeric array) of rows of ``width`` finite numbers.
        where: The name errors give ``value``.
        width: The length every row must have.

    Returns:
        ``value`` as a float array, shape ``(N, width)``.

    Raises:
        ConfigError: Not such a list, naming the first bad row or value
            (``where[i]`` or ``where[i][j]``).
    """
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "fiu" and value.ndim == 2 and value.shape[1] == width:
            array = value.astype(float)
            if array.size and np.isfinite(array).all():
                return array
        value = value.tolist()  # checked below, naming the bad row or value
    if not (isinstance(value, list) and value):
        raise ConfigError(where, value, f"a non-empty list of rows of {width} numbers")
    for i, row in enumerate(value):
        if not (isinstance(row, list) and len(row) == width):
            raise ConfigError(f"{where}[{i}]", row, f"a row of {width} numbers")
        for j, x in enumerate(row):
            if type(x) not in (int, float):
                raise ConfigError(f"{where}[{i}][{j}]", x, "a number")
    array = np.array(value, dtype=float)
    bad = np.argwhere(~np.isfinite(array))
    if bad.size:
        i, j = bad[0]
        raise ConfigError(f"{where}[{i}][{j}]", float(array[i, j]), "a finite number")
    return array


def path_within_limits(value: Any, where: str, model: pin.Model) -> np.ndarray:
    """Check a plan's ``path``: rows of ``model.nq`` finite joint values within the joint
    limits (:data:`LIMIT_TOLERANCE`).

    Args:
        value: The path, rows of joint values [rad; m for prismatic joints].
        where: The name errors give ``value``.
        model: The robot's Pinocchio model.

    Returns:
        The path as a float array, shape ``(N, nq)``.

    Raises:
        ConfigError: A bad row or value, naming the row, the joint and its limits.
    """
    path = number_rows(value, where, model.nq)
    columns = [model.names[i] for i in range(1, model.njoints) for _ in range(model.joints[i].nq)]
    low, high = model.lowerPositionLimit, model.upperPositionLimit
    outside = np.argwhere((path < low - LIMIT_TOLERANCE) | (path > high + LIMIT_TOLERANCE))
    if outside.size:
        i, j = outside[0]
        raise ConfigError(
            f"{where}[{i}][{j}]",
            float(path[i, j]),
            f"{columns[j]} within its limits [{low[j]:.6g}, {high[j]:.6g}]",
        )
    return path


def check_ends(
    path: np.ndarray,
    start: np.ndarray | None,
    arm_idx: np.ndarray,
    model: pin.Model,
    palm_frame_id: int,
    grasp_pose: np.ndarray,
    where: str,
) -> None:
    """A plan's path must leave from its ``start`` (when the file names one) and end with
    the palm at its grasp pose: a path edited, reversed or cut short would otherwise be
    drawn and executed as the plan for that grasp.

    Args:
        path: Full configurations [rad; m for prismatic joints], shape ``(N, nq)``.
        start: The arm's start configuration [rad], shape ``(dof,)``, or ``None``.
        arm_idx: Indices of the arm joints in ``q``.
        model: The robot's Pinocchio model.
        palm_frame_id: Pinocchio frame index of the palm.
        grasp_pose: The palm's grasp pose in the world frame, ``(x, y, z, qx, qy, qz, qw)``
            [m, unit quaternion].
        where: Prefix of error locations.

    Raises:
        ConfigError: ``path[0]``'s arm is not ``start`` (within :data:`LIMIT_TOLERANCE`),
            or the last row's palm is not at ``grasp_pose`` (within
            :data:`GRASP_POSITION_TOLERANCE` and :data:`GRASP_ROTATION_TOLERANCE`).
    """
    if start is not None and np.max(np.abs(path[0, arm_idx] - start)) > LIMIT_TOLERANCE:
        raise ConfigError(
            f"{where}path[0]",
            np.round(path[0, arm_idx], 6).tolist(),
            f"the arm at the plan's start {np.round(start, 6).tolist()}",
        )
    data = model.createData()
    pin.framesForwardKinematics(model, data, path[-1])
    error = data.oMf[palm_frame_id].actInv(pin.XYZQUATToSE3(grasp_pose))
    distance = float(np.linalg.norm(error.translation))
    angle = float(np.linalg.norm(pin.log3(error.rotation)))
    if distance > GRASP_POSITION_TOLERANCE or angle > GRASP_ROTATION_TOLERANCE:
        raise ConfigError(
            f"{where}path[{len(path) - 1}]",
            f"the palm {distance * 1e3:.1f} mm and {angle:.3f} rad from grasp_pose",
            f"the last row at the grasp pose (within {GRASP_POSITION_TOLERANCE * 1e3:g} mm "
            f"and {GRASP_ROTATION_TOLERANCE:g} rad)",
        )


#: How far [rad or m] a path row's hand joint may be from the hand law's value there
#: (rounding: the planner writes the law's value itself).
HAND_TOLERANCE = 1e-6
#: The least palm-to-grasp distance [m] at a plan's start: the planner refuses a start
#: closer to its grasp (:data:`~openup_ompl.validity.MIN_START_DISTANCE`), and the law's
#: normalised distance divides by it.
MIN_START_PALM_DISTANCE = MAX_POSITION_TOLERANCE


def check_hand(
    path: np.ndarray,
    law: HandLaw,
    start_distance: float | None,
    model: pin.Model,
    hand_idx: np.ndarray,
    hand_joints: tuple[str, ...],
    palm_frame_id: int,
    grasp_pose: np.ndarray,
    where: str,
) -> None:
    """Every row's hand joints must hold what the file's law gives for that row's arm
    (as :meth:`~openup_ompl.planning.GraspPlanningSetup.densify` wrote them): a file whose
    ``hand_joints`` are reordered, or whose hand columns were edited, would otherwise be
    drawn and executed as a plan of that law.

    ``d`` at a row is the palm's distance to ``grasp_pose`` (the law's kind of distance)
    over ``start_distance`` (``None``: the palm's at ``path[0]``, the start). The last
    row may be :data:`GRASP_POSITION_TOLERANCE` (and :data:`GRASP_ROTATION_TOLERANCE`)
    from the grasp pose, so the grasp pose may be that far from the one the plan was made
    for: a row's hand may be anything the law gives over the span of ``d`` that allows,
    plus :data:`HAND_TOLERANCE`.

    Args:
        path: Full configurations [rad; m for prismatic joints], shape ``(N, nq)``.
        law: The file's hand law.
        start_distance: The start palm's distance from the grasp [m] (the law's kind of
            distance), or ``None``: the one at ``path[0]``.
        model: The robot's Pinocchio model.
        hand_idx: Indices of the hand joints in ``q``.
        hand_joints: The hand joints' names, in the law's order.
        palm_frame_id: Pinocchio frame index of the palm.
        grasp_pose: The palm's grasp pose in the world frame, ``(x, y, z, qx, qy, qz, qw)``
            [m, unit quaternion].
        where: Prefix of error locations.

    Raises:
        ConfigError: A row's hand is not the law's, or (``start_distance`` ``None``)
            ``path[0]``'s palm is closer than :data:`MIN_START_PALM_DISTANCE` to the grasp.
    """
    hands = path[:, hand_idx]
    if law.fixed_clipped is not None:
        low = high = np.broadcast_to(law.fixed_clipped, hands.shape)
    else:
        grasp = pin.XYZQUATToSE3(grasp_pose)
        rotation_t = grasp.rotation.T if law.distance == "weighted" else None
        slack = GRASP_POSITION_TOLERANCE
        if rotation_t is not None:
            slack += law.rotation_weight * GRASP_ROTATION_TOLERANCE
        data = model.createData()
        raw = np.empty(len(path))
        for i, q in enumerate(path):
            pin.forwardKinematics(model, data, q)
            placement = pin.updateFramePlacement(model, data, palm_frame_id)
            raw[i] = palm_distance(placement, grasp.translation, rotation_t, law.rotation_weight)
        if start_distance is None:
            start_distance = float(raw[0])
            if start_distance < MIN_START_PALM_DISTANCE:
                raise ConfigError(
                    f"{where}path[0]",
                    f"the palm {start_distance * 1e3:.3g} mm from grasp_pose",
                    f"a start at least {MIN_START_PALM_DISTANCE * 1e3:g} mm from it (the"
                    " hand law's distance is normalised by it)",
                )
        # The law is affine in d on each side of mga, then clipped: over [d0, d1] each
        # joint's extremes lie at d0, d1 or mga.
        d = raw / start_distance
        d0 = np.maximum(d - slack / start_distance, 0.0)
        d1 = d + slack / start_distance
        ends = law.columns(np.concatenate([d0, d1, np.clip(law.mga, d0, d1)]))
        ends = ends.T.reshape(3, len(path), -1)
        low, high = ends.min(axis=0), ends.max(axis=0)
    bad = np.argwhere((hands < low - HAND_TOLERANCE) | (hands > high + HAND_TOLERANCE))
    if bad.size:
        i, j = (int(k) for k in bad[0])
        column = int(hand_idx[j])
        span = (
            f"{low[i, j]:.6g}"
            if high[i, j] - low[i, j] <= HAND_TOLERANCE
            else f"in [{low[i, j]:.6g}, {high[i, j]:.6g}]"
        )
        raise ConfigError(
            f"{where}path[{i}][{column}]",
            float(path[i, column]),
            f"{hand_joints[j]} at {span}, as the file's hand_law gives for the row's arm"
            " (robot.hand_joints in the law's order)",
        )
