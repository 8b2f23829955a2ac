"""Goal region of a grasp: the arm configurations that put the palm on the grasp pose.

:class:`IKGoalRegion` is an ``ob.GoalSampleableRegion``: any OMPL planner that accepts
sampleable goals (RRTConnect, BITstar, ...) samples goal states from it, each one a fresh
inverse-kinematics solution computed during planning. A solution counts only if it is
collision-free with the hand at ``open_hand(0)`` (the close preshape ``c``, or ``c + (w - c) u``
with the open-arrival variant). With ``pregrasp > 0`` the samples are pregrasp states
instead: each solution backed off along a certified straight retreat, whose approach
completes the plan.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np
from ompl import base as ob

from openup_ompl import _toml
from openup_ompl.exceptions import ConfigError, UnreachableGrasp
from openup_ompl.hand_law import ROTATION_WEIGHT, palm_distance
from openup_ompl.ik import IKSolver
from openup_ompl.validity import CoupledChecker

#: Default goal threshold on that distance [m]: a goal state is within 1 mm and 0.01 rad.
GOAL_THRESHOLD = 1e-3
#: Palm displacement [m] of one step of a pregrasp retreat (IKBiRRT's ``retreat_step``).
PREGRASP_STEP = 0.025
#: The shortest retreat step accepted [m] (here and for IKBiRRT's retreat): each step is
#: an IK solve and a motion check, and a retreat of 0.1 m in micrometre steps would not
#: end.
MIN_RETREAT_STEP = 1e-3
#: The longest retreat (and pregrasp distance) accepted [m]: past a metre the palm has
#: left the grasp's neighbourhood, and a retreat is no longer an approach.
MAX_RETREAT = 1.0


def check_retreat(
    length: float,
    step: float,
    max_joint_step: float,
    names: tuple[str, str, str] = ("length", "step", "max_joint_step"),
) -> tuple[float, float, float]:
    """A retreat's length, palm step and joint-step bound, checked.

    Args:
        length: The retreat's length [m], in ``[0, MAX_RETREAT]``.
        step: The palm's step [m], at least :data:`MIN_RETREAT_STEP`.
        max_joint_step: The largest arm motion per step [rad, Euclidean norm], positive.
        names: The names the three values are refused under.

    Returns:
        ``(length, step, max_joint_step)`` as floats.

    Raises:
        ConfigError: Naming the bad one by its entry of ``names``.
    """
    if not (_toml.is_finite(length) and 0 <= length <= MAX_RETREAT):
        raise ConfigError(names[0], length, f"a retreat length in [0, {MAX_RETREAT:g}] m")
    if not (_toml.is_finite(step) and step >= MIN_RETREAT_STEP):
        raise ConfigError(names[1], step, f"a finite step >= {MIN_RETREAT_STEP:g} m")
    if not (_toml.is_finite(max_joint_step) and max_joint_step > 0):
        raise ConfigError(names[2], max_joint_step, "a positive step [rad]")
    return float(length), float(step), float(max_joint_step)


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
        """IK solves run so far (the solver's count of calls)."""
        return self.ik.calls

    def sample(self, max_restarts: int | None = None) -> np.ndarray | None:
        """A new collision-free IK solution of the grasp pose.

        Args:
            max_restarts: Random restarts at most (an integer >= 1; ``None``: the IK
                options').

        Returns:
            The arm's joint values [rad or m] of a solution collision-free with the law's
            hand at the grasp (added to :attr:`solutions`), or ``None`` if the restarts
            found none.

        Raises:
            ConfigError: ``max_restarts`` is not an integer >= 1 (or ``None``).
        """
        if max_restarts is not None and not (_toml.is_integer(max_restarts) and max_restarts >= 1):
            raise ConfigError("max_restarts", max_restarts, "an integer >= 1 or None")
        restarts = self.ik.options.max_restarts if max_restarts is None else max_restarts
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
        """At least one collision-free solution of the grasp pose, before any planning.

        Args:
            max_restarts: Random restarts allowed to find the first one.

        Returns:
            The first solution's arm joint values [rad or m].

        Raises:
            UnreachableGrasp: No solution, or none free of collisions (with the counts).
        """
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

    def retreat(
        self, root: np.ndarray, length: float, step: float, max_joint_step: float
    ) -> list[np.ndarray]:
        """The straight palm retreat from the grasp configuration ``root``: the palm backs
        away against the robot's approach direction (``approach`` in the robot file), each
        motion checked with the law. A step that collides, that IK cannot reach, or that
        moves the arm more than ``max_joint_step`` (near a singularity) ends it.

        Args:
            root: The grasp configuration's arm joint values [rad or m].
            length: The retreat's length [m], in ``[0, MAX_RETREAT]``.
            step: The palm's step [m], at least :data:`MIN_RETREAT_STEP`.
            max_joint_step: The largest arm motion per step [rad, Euclidean norm].

        Returns:
            The configurations from ``root`` (first) to the retreat's end (last); only
            ``root`` when no step was free. Read backwards, a certified straight approach.

        Raises:
            ConfigError: ``length`` not in ``[0, MAX_RETREAT]``, ``step`` below
                :data:`MIN_RETREAT_STEP` or not finite, ``max_joint_step`` not positive.
        """
        length, step, max_joint_step = check_retreat(length, step, max_joint_step)
        offset = -step * self.checker.robot.spec.approach
        chain = [root]
        q = root
        for _ in range(math.ceil(length / step - 1e-9)):
            nxt = self.ik.palm_step(q, offset)
            if nxt is None or float(np.linalg.norm(nxt - q)) > max_joint_step:
                break
            if not self.checker.check_motion(q, nxt):
                break
            chain.append(nxt)
            q = nxt
        return chain

    def task_error(self, arm: np.ndarray) -> float:
        """Task-space distance of an arm configuration's palm to the grasp pose.

        Args:
            arm: The arm's joint values [rad or m].

        Returns:
            The position error [m] plus :data:`ROTATION_WEIGHT` [m/rad] times the rotation
            error [rad].
        """
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
    task-space distance (see :meth:`GraspGoal.task_error`), the threshold
    :data:`GOAL_THRESHOLD`.

    **Pregrasp goals** (``pregrasp > 0``): each IK solution is backed off first, the palm
    retreating straight against the approach direction by up to ``pregrasp`` metres
    (:meth:`GraspGoal.retreat`, every step checked with the law), and ``sampleGoal``
    returns the retreat's end: the classical pregrasp-and-approach that IKBiRRT's goal tree
    grows too. Near the grasp the law holds the fingers millimetres from the object, and a
    planner's random extensions from a grasp configuration almost all collide; from the
    pregrasp they do not. A retreat cut short by an obstacle or the object ends pressed
    against it, no freer than the grasp: the grasp configuration itself is then the
    sample. The goal is the grasp configurations *and* the pregrasp states sampled so far
    (``distanceGoal`` is 0 on those), and a path a planner returns ends at the grasp only
    once :meth:`approach` of its last state is appended (a certified straight motion;
    :meth:`GraspPlanningSetup.solve <openup_ompl.planning.GraspPlanningSetup.solve>` does
    it).

    Args:
        si: OMPL space information over the arm joints.
        goal: The numpy-level goal.
        max_samples: ``maxSampleCount()``: how many goal samples a planner may draw (fewer
            once :attr:`deadline` has passed).
        pregrasp: Length [m] of the retreat from each sampled grasp configuration (0: the
            grasp configurations themselves are the samples).
        pregrasp_step: Palm displacement [m] of one retreat step.
        max_joint_step: Arm motion [rad, Euclidean norm] one retreat step may not exceed.

    Raises:
        ConfigError: A ``pregrasp`` outside ``[0, MAX_RETREAT]``, a ``pregrasp_step`` under
            :data:`MIN_RETREAT_STEP`, a non-positive ``max_joint_step``, or
            ``max_samples`` not an integer in [1, 2^31).
        UnreachableGrasp: No collision-free IK solution of the grasp pose was found.
    """

    def __init__(
        self,
        si: ob.SpaceInformation,
        goal: GraspGoal,
        max_samples: int = 10_000,
        pregrasp: float = 0.0,
        pregrasp_step: float = PREGRASP_STEP,
        max_joint_step: float = 0.3,
    ) -> None:
        pregrasp, pregrasp_step, max_joint_step = check_retreat(
            pregrasp, pregrasp_step, max_joint_step, ("pregrasp", "pregrasp_step", "max_joint_step")
        )
        if not (_toml.is_integer(max_samples) and 1 <= max_samples < 2**31):
            raise ConfigError("max_samples", max_samples, "an integer in [1, 2^31)")
        super().__init__(si)
        self.goal = goal
        self.max_samples = max_samples
        self.pregrasp = pregrasp
        self.pregrasp_step = pregrasp_step
        self.max_joint_step = max_joint_step
        self.setThreshold(GOAL_THRESHOLD)
        self._n = goal.checker.robot.arm_idx.size
        # Pregrasp state (bytes) -> its retreat, grasp first; grasp state (bytes) -> same.
        self._retreats: dict[bytes, list[np.ndarray]] = {}
        #: Goals drawn by planners, and the checker's motion count at the last draw.
        self.draws = 0
        self.motions_at_draw = 0
        self._deadline: float | None = None
        self._draws_before = 0
        goal.ensure_solution()

    def sampleGoal(self, state: ob.State) -> None:  # noqa: N802 - OMPL's name
        """OMPL's goal sampling: writes a new goal into ``state``.

        A new IK solution of the grasp (five restarts; else one already found), backed off
        to its pregrasp state when the region has a ``pregrasp`` length.

        Args:
            state: The OMPL state to fill with the arm's joint values [rad or m].
        """
        self.draws += 1
        self.motions_at_draw = self.goal.checker.motions_checked
        arm = self.goal.sample(max_restarts=5)
        if arm is None:
            solutions = self.goal.solutions
            arm = solutions[int(self.goal.rng.integers(len(solutions)))]
        if self.pregrasp > 0:
            arm = self._pregrasp_of(arm)
        state[0 : self._n] = arm.tolist()

    def _pregrasp_of(self, grasp: np.ndarray) -> np.ndarray:
        chain = self._retreats.get(grasp.tobytes())
        if chain is None:
            chain = self.goal.retreat(grasp, self.pregrasp, self.pregrasp_step, self.max_joint_step)
            steps = math.ceil(self.pregrasp / self.pregrasp_step - 1e-9)
            if len(chain) - 1 < steps and self._blocked_by_scene(chain[-1]):
                chain = chain[:1]
            self._retreats[grasp.tobytes()] = chain
            self._retreats[chain[-1].tobytes()] = chain
        return chain[-1]

    def _blocked_by_scene(self, arm: np.ndarray) -> bool:
        """Whether the palm's next step back from ``arm`` runs into an obstacle or the
        object: a retreat stopped there ends pressed against the scene, no freer than the
        grasp itself (a retreat stopped by the robot's own links, by IK or by a joint-space
        jump is not)."""
        checker = self.goal.checker
        nxt = self.goal.ik.palm_step(arm, -self.pregrasp_step * checker.robot.spec.approach)
        return nxt is not None and checker.finest_world.touches_environment(checker.coupled_q(nxt))

    def _arm_values(self, arm: ob.State | np.ndarray | Sequence[float]) -> np.ndarray:
        """The arm joint values of an OMPL state over the arm joints, or of a sequence."""
        if isinstance(arm, ob.State):
            return np.array(arm[0 : self._n], dtype=float)
        return np.asarray(arm, dtype=float)

    def _retreat_to(self, arm: ob.State | np.ndarray | Sequence[float]) -> list[np.ndarray] | None:
        """The retreat that ends at ``arm`` (bit for bit) if it is a sampled pregrasp."""
        key = self._arm_values(arm).tobytes()
        chain = self._retreats.get(key)
        return (
            chain if chain is not None and len(chain) > 1 and chain[-1].tobytes() == key else None
        )

    def is_pregrasp(self, arm: ob.State | np.ndarray | Sequence[float]) -> bool:
        """Whether ``arm`` (an OMPL state or the arm joint values [rad or m], bit for bit)
        is a pregrasp state this region sampled.

        Args:
            arm: An OMPL state of the arm's space, or the arm joint values [rad or m].

        Returns:
            True if the region sampled ``arm`` as the end of a retreat.
        """
        return self._retreat_to(arm) is not None

    def approach(self, arm: ob.State | np.ndarray | Sequence[float]) -> np.ndarray:
        """The certified straight approach from a sampled pregrasp state to its grasp
        configuration.

        Args:
            arm: The pregrasp state: an OMPL state of :attr:`goal`'s arm space (e.g. a
                path's last state) or its arm joint values [rad or m], bit for bit as
                sampled.

        Returns:
            ``(k, dof)`` arm configurations, ``arm`` itself left out, the grasp last;
            empty (``(0, dof)``) when ``arm`` is not a pregrasp state of this region.
        """
        chain = self._retreat_to(arm)
        return np.empty((0, self._n)) if chain is None else np.array(chain[-2::-1])

    def forget(self) -> None:
        """Drop the pregrasp states sampled so far (a new run samples its own)."""
        self._retreats.clear()

    @property
    def deadline(self) -> float | None:
        """A ``time.perf_counter()`` value past which no more goals are offered than the
        run has drawn since it was set (at least one: BITstar cannot start without a
        goal). BITstar and FMT draw ``maxSampleCount()`` goals up front without looking
        at the time, an IK solve each, far past a planning time limit.
        :meth:`GraspPlanningSetup.solve <openup_ompl.planning.GraspPlanningSetup.solve>`
        sets it to its time limit and clears it after."""
        return self._deadline

    @deadline.setter
    def deadline(self, value: float | None) -> None:
        self._deadline = value
        self._draws_before = self.draws  # a planner counts its own draws from 0

    def maxSampleCount(self) -> int:  # noqa: N802 - OMPL's name
        """OMPL's bound on the goals a planner may draw.

        Returns:
            ``max_samples``; past the :attr:`deadline`, only the goals drawn so far (at
            least one).
        """
        if self._deadline is not None and time.perf_counter() >= self._deadline:
            return min(max(1, self.draws - self._draws_before), self.max_samples)
        return self.max_samples

    def couldSample(self) -> bool:  # noqa: N802 - OMPL's name
        """OMPL's question whether more goals may come.

        Returns:
            Always True: IK can always be tried again.
        """
        return True

    def distanceGoal(self, state: ob.State) -> float:  # noqa: N802 - OMPL's name
        """OMPL's distance of a state to the goal.

        Args:
            state: An OMPL state of the arm's space.

        Returns:
            0 on a pregrasp state this region sampled, else the palm's task-space error to
            the grasp [m] (:meth:`GraspGoal.task_error`; infinite if not finite).
        """
        arm = np.array(state[0 : self._n])
        if self._retreats and self.is_pregrasp(arm):
            return 0.0
        value = self.goal.task_error(arm)
        return value if math.isfinite(value) else math.inf
