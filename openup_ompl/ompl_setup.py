"""The OMPL side of a grasp planning setup: the arm's state space, a ``og.SimpleSetup``
wired to the coupled checks, and its start state.

:class:`~openup_ompl.planning.GraspPlanningSetup` builds its setup from these; they hold
no planning logic of their own.
"""

from __future__ import annotations

import math

import numpy as np
from ompl import base as ob
from ompl import geometric as og

from openup_ompl.exceptions import ConfigError, InvalidProblem
from openup_ompl.robot import Robot
from openup_ompl.scene import Problem
from openup_ompl.validity import CoupledChecker, CoupledMotionValidator, CoupledValidityChecker


def arm_state_space(robot: Robot) -> ob.RealVectorStateSpace:
    """OMPL's state space of a robot's arm joints, bounded by their limits.

    Args:
        robot: The robot.

    Returns:
        A ``RealVectorStateSpace`` of dimension ``dof``, one axis per arm joint [rad].
    """
    dof = robot.arm_idx.size
    space = ob.RealVectorStateSpace(dof)
    bounds = ob.RealVectorBounds(dof)
    for i, (low, high) in enumerate(zip(robot.arm_lower, robot.arm_upper, strict=True)):
        bounds.setLow(i, float(low))
        bounds.setHigh(i, float(high))
    space.setBounds(bounds)
    return space


def coupled_simple_setup(
    space: ob.RealVectorStateSpace, checker: CoupledChecker
) -> tuple[og.SimpleSetup, CoupledValidityChecker, CoupledMotionValidator]:
    """A ``og.SimpleSetup`` on ``space`` whose states and motions ``checker`` checks, with
    a path-length objective that any solution satisfies.

    Args:
        space: The arm's state space (:func:`arm_state_space`).
        checker: The coupled check of states and motions.

    Returns:
        ``(simple_setup, validity_checker, motion_validator)``.
    """
    simple_setup = og.SimpleSetup(space)
    si = simple_setup.getSpaceInformation()
    validity_checker = CoupledValidityChecker(si, checker)
    motion_validator = CoupledMotionValidator(si, checker)
    simple_setup.setStateValidityChecker(validity_checker)
    si.setMotionValidator(motion_validator)
    # Path length, satisfied by any solution: the optimising planners (RRT*, BIT*,
    # FMT*, ...) return their first exact solution instead of refining until the
    # time limit; the others ignore it.
    objective = ob.PathLengthOptimizationObjective(si)
    objective.setCostThreshold(ob.Cost(math.inf))
    simple_setup.setOptimizationObjective(objective)
    # Only OMPL's own interpolation reads this fraction (our validator has its own bound).
    step = checker.resolution / float(np.max(checker.motion_weights))
    si.setStateValidityCheckingResolution(min(1.0, step / space.getMaximumExtent()))
    return simple_setup, validity_checker, motion_validator


def set_start(simple_setup: og.SimpleSetup, problem: Problem, checker: CoupledChecker) -> None:
    """Set ``problem.start`` as the start state of ``simple_setup``.

    Args:
        simple_setup: The setup (:func:`coupled_simple_setup`).
        problem: The problem whose start arm configuration [rad] is set.
        checker: The coupled checker the start is checked with.

    Raises:
        InvalidProblem: The start is outside the joint limits, or collides (the pairs
            named).
    """
    robot = problem.robot
    try:
        robot.check_arm(problem.start, "start")
    except ConfigError as error:  # a joint beyond its limits: no plan can leave from it
        raise InvalidProblem(f"start configuration outside the joint limits: {error}") from None
    if not checker.is_valid(problem.start):
        pairs = checker.finest_world.colliding_pairs(checker.coupled_q(problem.start))
        raise InvalidProblem(
            f"start configuration {problem.start.tolist()} is in collision: {pairs}"
        )
    start = simple_setup.getSpaceInformation().allocState()
    start[0 : robot.arm_idx.size] = problem.start.tolist()
    simple_setup.setStartState(start)
