"""What follows a solve: the planner's waypoints made a full path (the arm at the
checker's resolution, the hand from the law at every row), and that path checked again
before it becomes a :class:`~openup_ompl.plan.Plan`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from openup_ompl.exceptions import ConfigError, VerifyFailed
from openup_ompl.goal import GOAL_THRESHOLD
from openup_ompl.plan_checks import number_rows
from openup_ompl.robot import LIMIT_TOLERANCE
from openup_ompl.scene import Problem
from openup_ompl.validity import CoupledChecker


def densify(checker: CoupledChecker, waypoints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Full configurations along ``waypoints`` at the checker's resolution, the hand from
    the law at every row; and for each row the index of the motion it ends on.

    Args:
        checker: The coupled checker the waypoints were planned with.
        waypoints: Arm configurations [rad], shape ``(M, dof)``.

    Returns:
        ``(path, segment)``: full configurations [rad; m for prismatic joints], shape
        ``(N, nq)``, and for each row the index of its motion, shape ``(N,)`` (0 for the
        start row).
    """
    arms = [waypoints[:1]]
    segment = [np.zeros(1, dtype=np.intp)]
    for i, (a, b) in enumerate(zip(waypoints[:-1], waypoints[1:], strict=True)):
        arms.append(checker.interpolate(a, b, weights=checker.weights(a, b)))
        segment.append(np.full(arms[-1].shape[0], i, dtype=np.intp))
    path = checker.coupled_qs(np.concatenate(arms)).T.copy()
    return path, np.concatenate(segment)


def rows_to_verify(
    checker: CoupledChecker, waypoints: np.ndarray, segment: np.ndarray
) -> np.ndarray:
    """The rows of a densified path (:func:`densify`) to check again: every waypoint row
    and every row of a motion the checker did not certify (rows inside certified motions
    need no second check).

    Args:
        checker: The coupled checker that checked the motions.
        waypoints: Arm configurations [rad], shape ``(M, dof)``.
        segment: Each densified row's motion index, from :func:`densify`, shape ``(N,)``.

    Returns:
        Sorted row indices into the densified path.
    """
    certified = np.array(
        [checker.is_certified(a, b) for a, b in zip(waypoints[:-1], waypoints[1:], strict=True)]
    )
    waypoint_row = np.r_[segment[1:] != segment[:-1], True]  # each motion's last row
    waypoint_row[0] = True  # the start
    return np.flatnonzero(waypoint_row | ~certified[segment])


def verify_path(
    problem: Problem,
    checker: CoupledChecker,
    task_error: Callable[[np.ndarray], float],
    path: np.ndarray,
    rows: np.ndarray | None = None,
) -> None:
    """Refuse a path that is not a valid plan of ``problem``: it must start at the start,
    end on the grasp pose within the goal threshold (``task_error`` of the last arm
    state), keep every arm and hand joint within its limits
    (:data:`~openup_ompl.robot.LIMIT_TOLERANCE`) at every row, and collide nowhere in
    the checker's finest world (at ``rows`` only, if given). Whether the hand follows the
    law is not checked.

    Args:
        problem: The problem the path was planned for.
        checker: Its coupled checker.
        task_error: The palm's task-space distance to the grasp pose [m, rotation
            weighted] of an arm configuration (:meth:`~openup_ompl.goal.GraspGoal.task_error`).
        path: Full configurations [rad; m for prismatic joints], shape ``(N, nq)``.
        rows: Indices of the rows to check for collision (``None``: all).

    Raises:
        ConfigError: ``path`` is not a non-empty array of rows of ``nq`` finite numbers,
            or ``rows`` holds an index outside it.
        VerifyFailed: With the reason; never expected from a correct planner.
    """
    robot = problem.robot
    path = number_rows(path, "path", robot.model.nq)
    if rows is not None:
        rows = np.asarray(rows)
        if rows.dtype.kind not in "iu" or np.any((rows < 0) | (rows >= len(path))):
            expected = f"indices of path rows in [0, {len(path)})"
            raise ConfigError("rows", rows.tolist(), expected)
    arms = path[:, robot.arm_idx]
    if not np.allclose(arms[0], problem.start, atol=1e-9):
        raise VerifyFailed("the path does not start at the start")
    distance = task_error(arms[-1])
    if distance > GOAL_THRESHOLD:
        raise VerifyFailed(f"the path ends {distance:.2e} m from the grasp pose")
    # Every row, whatever ``rows``: the test is a few array operations, and a joint
    # past its limit can still be collision-free (the Panda's first joint at 10 rad).
    columns = np.r_[robot.arm_idx, robot.hand_idx]
    low = robot.model.lowerPositionLimit[columns]
    high = robot.model.upperPositionLimit[columns]
    values = path[:, columns]
    outside = np.argwhere((values < low - LIMIT_TOLERANCE) | (values > high + LIMIT_TOLERANCE))
    if outside.size:
        i, j = (int(k) for k in outside[0])
        joint = [*robot.spec.arm_joints, *robot.hand_joints][j]
        raise VerifyFailed(
            f"path row {i}: joint {joint} at {values[i, j]:.6g}, outside its limits "
            f"[{low[j]:.6g}, {high[j]:.6g}]"
        )
    rows = np.arange(path.shape[0]) if rows is None else np.asarray(rows, dtype=np.intp)
    flags = checker.finest_world.batch_in_collision(np.asfortranarray(path[rows].T), False)
    if np.any(flags):
        raise VerifyFailed(f"path row {int(rows[np.flatnonzero(flags)[0]])} collides")
