"""IKBiRRT: a bidirectional RRT whose goal tree is rooted at IK solutions of the grasp.

A start tree grows from the start state(s) and a goal tree from inverse-kinematics
solutions of the grasp pose, new goal roots being sampled during planning with
probability ``p_sample_goal`` (Berenson et al., "Manipulation planning on constraint
manifolds", 2009). Both trees grow with the paper's Algorithm 2 (``Extend``): from the
nearest vertex, step toward the target, add each collision-free step as a vertex, stop at
the first collision. Every step is checked with the hand set by the law at the checker's
resolution. The trees swap roles after every iteration.

Each new goal root first grows a straight retreat: the palm backs away from the grasp
against the robot's approach direction (``approach`` in the robot file) in steps of
``retreat_step``, up to ``retreat``, each step checked with the law, stopping at the
first collision. Near the grasp the law's hand is close to ``c``, millimetres from the
object, so a random extension from a root almost always drives a finger into the object;
the retreat is the one motion that leaves it (the classical pregrasp-and-approach), and
the goal tree then grows from its end. ``retreat = 0`` gives the plain IKBiRRT.

With ``aim_new_roots`` (the default), the first growth after a new goal root aims the
start tree at that root's retreat end instead of at a uniform sample, and the goal tree
then extends toward what the start tree reached, as after any growth. On an open scene
this straight reach to the pregrasp is the whole plan; where it is blocked the trees grow
on from wherever it stopped. Without it the first plan of an open scene runs through a
uniform sample of the joint space, on average more than twice as long.

With ``lazy`` (the default) the trees grow with their vertices checked and their edges
not: a step is added when the state it reaches is collision-free. When the trees meet, the
edges of the path through them are checked (the full motion check, as the eager planner
checks every step), and an edge that collides is cut from its tree with everything grown
beyond it before the trees grow on. Most edges of the trees never lie on a path; checking
them is most of an eager planner's work. The returned path is made of checked motions
only, exactly as without ``lazy``; ``lazy = False`` checks every step as it is grown
(Algorithm 2 as the paper states it). Retreat steps are always checked as they are grown.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np
from ompl import base as ob
from ompl import geometric as og

from openup_ompl._toml import is_finite, is_integer, is_number
from openup_ompl.exceptions import ConfigError
from openup_ompl.goal import GraspGoal, IKGoalRegion, check_retreat


@dataclass(frozen=True)
class IKBiRRTOptions:
    """IKBiRRT settings.

    Attributes:
        max_step: Length of one ``Step`` of Algorithm 2 [rad, Euclidean norm over the arm
            joints]; each step is collision-checked at the checker's finer resolution.
        p_sample_goal: Probability per iteration of sampling a new IK root for the goal
            tree instead of growing the trees.
        goal_restarts: IK restarts per goal-sampling iteration.
        retreat: Length [m] of the straight palm retreat grown from each new goal root
            (0: none; at most :data:`~openup_ompl.goal.MAX_RETREAT`).
        retreat_step: Palm displacement [m] of one retreat step (one goal-tree vertex),
            at least :data:`~openup_ompl.goal.MIN_RETREAT_STEP`.
        seed: Seed of the planner's random generator (``None``: fresh entropy).
        lazy: Check the trees' edges only when they lie on a path between the trees (see
            the module docstring); ``False`` checks every step as it is grown.
        aim_new_roots: Aim the first growth after each new goal root at its retreat end
            (see the module docstring); ``False`` grows toward uniform samples only.
    """

    max_step: float = 0.3  # [rad]
    p_sample_goal: float = 0.1
    goal_restarts: int = 1
    retreat: float = 0.1  # [m]
    retreat_step: float = 0.025  # [m]
    seed: int | None = None
    lazy: bool = True
    aim_new_roots: bool = True

    def __post_init__(self) -> None:
        if not (is_finite(self.max_step) and self.max_step > 0):
            raise ConfigError("IKBiRRTOptions.max_step", self.max_step, "a positive step [rad]")
        if not (is_number(self.p_sample_goal) and 0.0 <= self.p_sample_goal <= 1.0):
            raise ConfigError(
                "IKBiRRTOptions.p_sample_goal", self.p_sample_goal, "a probability in [0, 1]"
            )
        if not (is_integer(self.goal_restarts) and self.goal_restarts >= 1):
            raise ConfigError("IKBiRRTOptions.goal_restarts", self.goal_restarts, "an integer >= 1")
        names = ("IKBiRRTOptions.retreat", "IKBiRRTOptions.retreat_step", "IKBiRRTOptions.max_step")
        check_retreat(self.retreat, self.retreat_step, self.max_step, names)
        if self.seed is not None and not (
            isinstance(self.seed, (int, np.integer))
            and not isinstance(self.seed, (bool, np.bool_))
            and self.seed >= 0
        ):
            raise ConfigError("IKBiRRTOptions.seed", self.seed, "None or an integer >= 0")
        for name in ("lazy", "aim_new_roots"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"IKBiRRTOptions.{name}", getattr(self, name), "true or false")


class _Extend(Enum):
    REACHED = "reached"
    ADVANCED = "advanced"
    TRAPPED = "trapped"


class _Tree:
    """Vertices in one array (numpy nearest neighbour), each with its parent index, whether
    the edge from its parent is checked, and whether it was cut off (a lazy edge on its
    way from the root collided)."""

    def __init__(self, dof: int, capacity: int = 1024) -> None:
        self.nodes = np.empty((capacity, dof))
        self.parents = np.empty(capacity, dtype=np.intp)
        self.checked = np.empty(capacity, dtype=bool)
        self.dead = np.empty(capacity, dtype=bool)
        self.size = 0
        self.cut = 0

    def add(self, q: np.ndarray, parent: int, checked: bool = True) -> int:
        if self.size == self.nodes.shape[0]:
            self.nodes = np.concatenate([self.nodes, np.empty_like(self.nodes)])
            self.parents = np.concatenate([self.parents, np.empty_like(self.parents)])
            self.checked = np.concatenate([self.checked, np.empty_like(self.checked)])
            self.dead = np.concatenate([self.dead, np.empty_like(self.dead)])
        self.nodes[self.size] = q
        self.parents[self.size] = parent
        self.checked[self.size] = checked
        self.dead[self.size] = False
        self.size += 1
        return self.size - 1

    def nearest(self, q: np.ndarray) -> int:
        diff = self.nodes[: self.size] - q
        distance = np.einsum("ij,ij->i", diff, diff)
        if self.cut:
            distance[self.dead[: self.size]] = np.inf
        return int(np.argmin(distance))

    def branch(self, index: int) -> list[int]:
        """Vertex indices from the root to ``index``."""
        out = []
        while index >= 0:
            out.append(index)
            index = int(self.parents[index])
        return out[::-1]

    def cut_off(self, index: int) -> None:
        """Cut vertex ``index`` and everything grown beyond it out of the tree (children
        always come after their parents)."""
        dead, parents = self.dead, self.parents
        dead[index] = True
        for i in range(index + 1, self.size):
            if not dead[i] and parents[i] >= 0 and dead[parents[i]]:
                dead[i] = True
        self.cut = int(np.sum(dead[: self.size]))


class IKBiRRT(ob.Planner):
    """Bidirectional RRT with IK-sampled goal roots (an ``ob.Planner``).

    The problem's goal must be an :class:`~openup_ompl.goal.IKGoalRegion`: the planner
    draws IK roots from it and uses its coupled checker for every state and motion (the
    same checks as the space information's validity checker and motion validator, without
    the OMPL round trip). Repeatable: the same seed gives the same path, and ``clear()``
    between runs (as ``SimpleSetup`` and ``ompl.tools.Benchmark`` do) starts afresh while
    the random generator continues, so benchmark runs differ.

    Args:
        si: OMPL space information over the arm joints.
        options: Planner settings.
        name: Planner name reported to OMPL.

    Attributes:
        iterations: Iterations of the last solve.
        goal_roots: Goal-tree roots of the last solve.
        retreat_vertices: Goal-tree vertices of the last solve grown by retreats.
        lazy_cuts: Lazy edges of the last solve found colliding on a path between the
            trees (each cut from its tree).
        cut_vertices: Vertices of the last solve cut off with them.
    """

    def __init__(
        self,
        si: ob.SpaceInformation,
        options: IKBiRRTOptions | None = None,
        name: str = "IKBiRRT",
    ) -> None:
        super().__init__(si, name)
        self.options = options or IKBiRRTOptions()
        self._si = si
        self._rng = np.random.default_rng(self.options.seed)
        self.iterations = 0
        self.goal_roots = 0
        self.retreat_vertices = 0
        self.lazy_cuts = 0
        self.cut_vertices = 0
        self.start_tree_size = 0
        self.goal_tree_size = 0

    def set_seed(self, seed: int | None) -> None:
        """Restart the planner's random generator from ``seed``.

        Args:
            seed: The generator's seed (``None``: drawn from the operating system).
        """
        self._rng = np.random.default_rng(seed)

    def clear(self) -> None:
        super().clear()
        self.iterations = 0
        self.goal_roots = 0
        self.retreat_vertices = 0
        self.lazy_cuts = 0
        self.cut_vertices = 0

    def setup(self) -> None:
        super().setup()

    def solve(self, ptc: ob.PlannerTerminationCondition) -> ob.PlannerStatus:
        """OMPL's solve: grow the start and goal trees until they connect or ``ptc`` ends.

        Args:
            ptc: OMPL's termination condition (a time limit, or a caller's condition).

        Returns:
            OMPL's status: ``EXACT_SOLUTION`` (the path added to the problem definition),
            ``TIMEOUT``, or ``INVALID_START`` / ``INVALID_GOAL``.
        """
        pdef = self.getProblemDefinition()
        goal_region = pdef.getGoal()
        if not isinstance(goal_region, IKGoalRegion):
            return ob.PlannerStatus(ob.PlannerStatus.INVALID_GOAL)
        goal = goal_region.goal
        checker = goal.checker
        dof = checker.robot.arm_idx.size
        lower, upper = checker.robot.arm_lower, checker.robot.arm_upper

        start_tree, goal_tree = _Tree(dof), _Tree(dof)
        inputs = ob.PlannerInputStates()
        inputs.use(pdef)
        state = inputs.nextStart()
        while state is not None:
            arm = np.array(state[0:dof])
            if checker.is_valid(arm):
                start_tree.add(arm, -1)
            state = inputs.nextStart()
        if start_tree.size == 0:
            return ob.PlannerStatus(ob.PlannerStatus.INVALID_START)

        # At least one goal root before growing: a fresh IK sample, else one found earlier.
        approach = None  # the newest root's retreat end, not yet aimed at
        while goal_tree.size == 0 and not ptc():
            root = goal.sample(max_restarts=self.options.goal_restarts)
            if root is None and goal.solutions:
                root = goal.solutions[int(self._rng.integers(len(goal.solutions)))]
            if root is not None:
                approach = self._retreat(goal, goal_tree, goal_tree.add(root, -1))
        if goal_tree.size == 0:
            return ob.PlannerStatus(ob.PlannerStatus.TIMEOUT)

        trees = (start_tree, goal_tree)
        status = ob.PlannerStatus(ob.PlannerStatus.TIMEOUT)
        while not ptc():
            self.iterations += 1
            if self._rng.random() < self.options.p_sample_goal:
                root = goal.sample(max_restarts=self.options.goal_restarts)
                if root is not None:
                    approach = self._retreat(goal, goal_tree, goal_tree.add(root, -1))
                continue
            grow, other = trees
            if approach is not None and self.options.aim_new_roots:
                # A new root is first aimed at straight from the start tree: on an open
                # scene that is the whole plan.
                grow, other = start_tree, goal_tree
                target = goal_tree.nodes[approach].copy()
                approach = None
            else:
                target = self._rng.uniform(lower, upper)
            result, new = self._extend(checker, grow, target, ptc)
            if result is not _Extend.TRAPPED:
                result, met = self._extend(checker, other, grow.nodes[new], ptc)
                if result is _Extend.REACHED:
                    ends = (new, met) if grow is start_tree else (met, new)
                    path = self._connect(checker, start_tree, goal_tree, *ends)
                    if path is not None:
                        self._add_solution(pdef, path)
                        status = ob.PlannerStatus(ob.PlannerStatus.EXACT_SOLUTION)
                        break
            trees = (other, grow)
        self.goal_roots = int(np.sum(goal_tree.parents[: goal_tree.size] < 0))
        self.start_tree_size = start_tree.size
        self.goal_tree_size = goal_tree.size
        self.cut_vertices = start_tree.cut + goal_tree.cut
        return status

    def _connect(
        self, checker: object, start_tree: _Tree, goal_tree: _Tree, start: int, goal: int
    ) -> list[np.ndarray] | None:
        """The path from the start tree's root through its vertex ``start`` (the same state
        as the goal tree's ``goal``) to the goal tree's root, once every edge on it is
        checked; ``None`` if one collides (that edge and what grew beyond it are cut)."""
        branches = ((start_tree, start_tree.branch(start)), (goal_tree, goal_tree.branch(goal)))
        for tree, branch in branches:
            for parent, child in zip(branch[:-1], branch[1:], strict=True):
                if tree.checked[child]:
                    continue
                if not checker.check_motion(tree.nodes[parent], tree.nodes[child]):  # type: ignore[attr-defined]
                    tree.cut_off(child)
                    self.lazy_cuts += 1
                    return None
                tree.checked[child] = True
        (_, to_start), (_, to_goal) = branches
        return [start_tree.nodes[i].copy() for i in to_start] + [
            goal_tree.nodes[i].copy() for i in to_goal[::-1][1:]
        ]

    def _retreat(self, goal: GraspGoal, tree: _Tree, root: int) -> int:
        """Grow the straight palm retreat from the goal root ``root`` (see the module
        docstring and :meth:`GraspGoal.retreat`). Returns the index of its last vertex (the
        root itself when no step was free)."""
        options = self.options
        chain = goal.retreat(
            tree.nodes[root].copy(), options.retreat, options.retreat_step, options.max_step
        )
        index = root
        for q in chain[1:]:
            index = tree.add(q, index)
        self.retreat_vertices += len(chain) - 1
        return index

    def _extend(
        self, checker: object, tree: _Tree, target: np.ndarray, ptc: ob.PlannerTerminationCondition
    ) -> tuple[_Extend, int]:
        """Algorithm 2: step from the nearest vertex toward ``target``, adding every
        collision-free step, until the target is reached or a step collides."""
        index = tree.nearest(target)
        q = tree.nodes[index].copy()
        advanced = False
        step = self.options.max_step
        lazy = self.options.lazy
        while True:
            delta = target - q
            distance = math.sqrt(float(delta @ delta))
            reached = distance <= step
            nxt = target.copy() if reached else q + delta * (step / distance)
            # Lazy: the state now, the edge when it lies on a path (see _connect).
            free = checker.is_valid(nxt) if lazy else checker.check_motion(q, nxt)  # type: ignore[attr-defined]
            if not free:
                return (_Extend.ADVANCED if advanced else _Extend.TRAPPED), index
            index = tree.add(nxt, index, checked=not lazy)
            advanced = True
            if reached:
                return _Extend.REACHED, index
            if ptc():
                return _Extend.ADVANCED, index
            q = nxt

    def _add_solution(self, pdef: ob.ProblemDefinition, path: list[np.ndarray]) -> None:
        si = self._si
        solution = og.PathGeometric(si)
        scratch = si.allocState()
        for arm in path:
            scratch[0 : arm.size] = arm.tolist()
            solution.append(scratch)
        pdef.addSolutionPath(solution, False, 0.0, self.getName())
