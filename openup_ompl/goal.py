"""Goal region of a grasp: the arm configurations that put the palm on the grasp pose.

:class:`IKGoalRegion` is an ``ob.GoalSampleableRegion``: any OMPL planner that accepts
sampleable goals (RRTConnect, BITstar, ...) samples goal states from it, each one a fresh
inverse-kinematics solution computed during planning. A solution counts only if it is
collision-free with the hand at ``open_hand(0)`` (the close preshape ``c``, or ``c + (w - c) u``
with the open-arrival variant).
"""

from __future__ import annotations

import math

import numpy as np
from ompl import base as ob

from openup_ompl.exceptions import UnreachableGrasp
from openup_ompl.hand_law import ROTATION_WEIGHT, palm_distance
from openup_ompl.ik import IKSolver
from openup_ompl.validity import CoupledChecker

#: Default goal threshold on that distance [m]: a goal state is within 1 mm and 0.01 rad.
GOAL_THRESHOLD = 1e-3


class GraspGoal:
    """The numpy-level goal: IK sampling, the solutions found, the task-space distance.

    Args:
        checker: The coupled check (its problem gives robot, grasp pose and law).
        ik: The IK solver of the grasp pose.
        rng: Random generator for restarts (owned by the run).

    Attributes:
        solutions: Collision-free IK solutions found so far (arm configurations).
        ik_calls: IK restarts run.
        rejected: IK solutions rejected for collision.
    """

    def __init__(self, checker: CoupledChecker, ik: IKSolver, rng: np.random.Generator) -> None:
        self.checker = checker
        self.ik = ik
        self.rng = rng
        self.solutions: list[np.ndarray] = []
        self.rejected = 0
        self.last_rejected: np.ndarray | None = None
        self._hand_at_goal = checker.law(0.0)
        self._data = checker.robot.model.createData()
        self._q = checker.robot.neutral()
        self._target = checker.problem.grasp
        self._target_position = self._target.translation.copy()
        self._target_rotation_t = self._target.rotation.T.copy()

    @property
    def ik_calls(self) -> int:
        return self.ik.calls

    def sample(self, max_restarts: int | None = None) -> np.ndarray | None:
        """A new collision-free IK solution (random restarts), or ``None``."""
        restarts = max_restarts or self.ik.options.max_restarts
        for _ in range(restarts):
            arm = self.ik.refine(self.ik.random_arm(self.rng))
            if arm is None:
                continue
            if self.checker.is_valid_with_hand(arm, self._hand_at_goal):
                self.solutions.append(arm)
                return arm
            self.rejected += 1
            self.last_rejected = arm
        return None

    def ensure_solution(self, max_restarts: int = 200) -> np.ndarray:
        """At least one collision-free solution, or :class:`UnreachableGrasp`."""
        if self.solutions:
            return self.solutions[0]
        calls_before = self.ik.calls
        rejected_before = self.rejected
        solution = self.sample(max_restarts)
        if solution is None:
            pairs: list[tuple[str, str]] = []
            if self.rejected > rejected_before and self.last_rejected is not None:
                q = self.checker.robot.full_q(self.last_rejected, self._hand_at_goal)
                pairs = self.checker.finest_world.colliding_pairs(q)
            raise UnreachableGrasp(
                self.checker.problem.grasp_pose.tolist(),
                self.ik.calls - calls_before,
                self.rejected - rejected_before,
                self.checker.paddings[-1],
                pairs,
            )
        return solution

    def task_error(self, arm: np.ndarray) -> float:
        """Task-space distance to the grasp [m]: position error plus
        :data:`ROTATION_WEIGHT` times the rotation error."""
        q = self._q
        q[self.checker.robot.arm_idx] = arm
        placement = self.checker.robot.palm_placement(self._data, q)
        return palm_distance(
            placement, self._target_position, self._target_rotation_t, ROTATION_WEIGHT
        )

    distance = task_error  # the old name ("distance" also meant the normalised d)


class IKGoalRegion(ob.GoalSampleableRegion):
    """OMPL goal region of the grasp pose, sampled by inverse kinematics during planning.

    ``sampleGoal`` runs IK with random restarts and returns a new collision-free
    solution; when a call's restarts all fail it returns one found earlier, so every
    sampled state is a true goal. One solution is found at construction: an unreachable
    grasp raises :class:`UnreachableGrasp` before any planner runs. ``distanceGoal`` is the
    task-space distance (see :meth:`GraspGoal.distance`), the threshold
    :data:`GOAL_THRESHOLD`.

    Args:
        si: OMPL space information over the arm joints.
        goal: The numpy-level goal.
        max_samples: ``maxSampleCount()``: how many goal samples a planner may draw.
    """

    def __init__(self, si: ob.SpaceInformation, goal: GraspGoal, max_samples: int = 10_000) -> None:
        super().__init__(si)
        self.goal = goal
        self.max_samples = int(max_samples)
        self.setThreshold(GOAL_THRESHOLD)
        self._n = goal.checker.robot.arm_idx.size
        goal.ensure_solution()

    def sampleGoal(self, state: ob.State) -> None:  # noqa: N802 - OMPL's name
        arm = self.goal.sample(max_restarts=5)
        if arm is None:
            solutions = self.goal.solutions
            arm = solutions[int(self.goal.rng.integers(len(solutions)))]
        state[0 : self._n] = arm.tolist()

    def maxSampleCount(self) -> int:  # noqa: N802 - OMPL's name
        return self.max_samples

    def couldSample(self) -> bool:  # noqa: N802 - OMPL's name
        return True

    def distanceGoal(self, state: ob.State) -> float:  # noqa: N802 - OMPL's name
        value = self.goal.task_error(np.array(state[0 : self._n]))
        return value if math.isfinite(value) else math.inf
