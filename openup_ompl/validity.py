"""Coupled validity: every arm state is checked with the hand set by the hand law.

The arm joints are OMPL's state space; the fingers follow. For an arm configuration the
checker computes the palm placement (forward kinematics), the normalised distance ``d``
to the grasp pose (Algorithm 1), the hand from the law (Algorithm 3), and checks the full
configuration for self, obstacle and object collision with Coal.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from ompl import base as ob

from openup_ompl.collision import CollisionWorld, ThreadContext
from openup_ompl.exceptions import ConfigError
from openup_ompl.hand_law import HandLaw, NormalizedDistance
from openup_ompl.motion_bound import arm_weights, distance_rates, motion_weights
from openup_ompl.scene import Problem

#: Default motion-check resolution [m]: the largest distance any point of the robot may
#: move between two consecutive checked states of a motion (bounded as in
#: :mod:`openup_ompl.motion_bound`). Obstacles and object are padded by half of it, which
#: makes the check of a whole motion exact for the unpadded scene.
DEFAULT_RESOLUTION = 0.006
#: Forward kinematics for ``d`` at every this many states of a motion; the states between
#: are bounded from these (see :meth:`CoupledChecker._law_distances`).
ANCHOR_STRIDE = 8

#: Halvings of the padding available where the full margin is not: a state counts as
#: collision-free down to a clearance of ``padding / 2**REFINE_LEVELS`` (0.375 mm by
#: default), and motions through thinner margins are cut finer to stay exact.
REFINE_LEVELS = 3
#: Doublings of the padding tried first: a motion is first checked at states
#: ``2**COARSE_LEVELS`` times farther apart against obstacles padded ``2**COARSE_LEVELS``
#: times more (24 mm apart, 12 mm of padding by default), which is as exact and settles a
#: motion far from every obstacle with a quarter of the states.
COARSE_LEVELS = 2


class CoupledChecker:
    """The numpy-level coupled check shared by the OMPL validity checker, the motion
    validator, inverse kinematics and the planners.

    Args:
        problem: Robot, scene and grasp.
        law: The hand law (``problem.hand_law`` if omitted).
        world: A collision world to reuse (built from ``problem`` if omitted).
        resolution: Motion-check resolution [m] (see :data:`DEFAULT_RESOLUTION`).
        padding: Margin [m] added around obstacles and object; ``None`` gives
            ``resolution / 2``, the margin that makes motion checks exact. Where a state
            lacks that margin, halved margins (:data:`REFINE_LEVELS`) are tried and the
            motion around it is cut finer; ``0`` turns the guarantee off.
        coarse_levels: Doublings of the padding and of the spacing of the first pass
            over a motion (:data:`COARSE_LEVELS`); ``0`` checks every motion at
            ``resolution`` directly.

    Attributes:
        paddings: The margins [m] of the levels, widest first: the coarse pass's
            (:data:`COARSE_LEVELS`), the base ``padding``, then its halvings.
        coarse_resolution: Spacing [m] of the coarse pass's states.
        states_checked: States checked so far (single and batched).
        motions_checked: Motions checked so far.
        motion_weights: Weights ``W`` [m per joint unit] of the displacement bound
            (:mod:`~openup_ompl.motion_bound`), the fingers' motion under the law included.
        plateau_weights: The same with the hand still, for motions that stay on the law's
            plateau (:meth:`weights`).
    """

    def __init__(
        self,
        problem: Problem,
        law: HandLaw | None = None,
        world: CollisionWorld | None = None,
        resolution: float = DEFAULT_RESOLUTION,
        padding: float | None = None,
        coarse_levels: int = COARSE_LEVELS,
    ) -> None:
        if not (math.isfinite(resolution) and resolution > 0):
            raise ConfigError("resolution", resolution, "a positive distance [m]")
        padding = resolution / 2 if padding is None else padding
        if not (math.isfinite(padding) and padding >= 0):
            raise ConfigError("padding", padding, "a distance >= 0 [m]")
        if not (isinstance(coarse_levels, int) and coarse_levels >= 0):
            raise ConfigError("coarse_levels", coarse_levels, "an integer >= 0")
        self.problem = problem
        self.robot = problem.robot
        self.law = problem.hand_law if law is None else law
        self.world = CollisionWorld(problem, padding=padding) if world is None else world
        self.resolution = float(resolution)
        # No coarse pass without padding: it would not make a motion check exact.
        self._coarse = coarse_levels if self.world.padding > 0 else 0
        self.paddings = [
            self.world.padding * 2.0**level for level in range(self._coarse, -REFINE_LEVELS - 1, -1)
        ]
        self._worlds = [
            self.world
            if level == self._coarse
            else CollisionWorld(problem, num_threads=self.world.num_threads, padding=pad)
            for level, pad in enumerate(self.paddings)
        ]
        self.finest_world = self._worlds[-1]
        self.coarse_resolution = self.resolution * 2.0**self._coarse
        self._model = self.robot.model
        self._palm = self.robot.palm_frame_id
        start_q = self.robot.full_q(problem.start, self.law(1.0))
        self.goal_distance = NormalizedDistance(
            problem.grasp,
            self.robot.palm_placement(self._model.createData(), start_q),
            self.law.distance,
            self.law.rotation_weight,
        )
        self._arm_idx = self.robot.arm_idx
        self._hand_idx = self.robot.hand_idx
        self._arm_sel = _selector(self._arm_idx)
        self._hand_sel = _selector(self._hand_idx)
        self._translation_only = self.law.distance == "translation"
        self._goal = problem.grasp.translation.tolist()
        self._inv_start = 1.0 / self.goal_distance.start_distance
        start_distance = self.goal_distance.start_distance
        self.motion_weights = motion_weights(self.robot, self.law, start_distance)
        self.plateau_weights = arm_weights(self.robot)
        self.distance_rates = distance_rates(self.robot, self.law, start_distance)
        self.states_checked = 0
        self.motions_checked = 0

    # -- single states ----------------------------------------------------------------
    def normalized_distance(self, arm: np.ndarray) -> float:
        """Normalised palm-to-grasp distance ``d`` (Algorithm 1) of an arm configuration."""
        context = self.world.context()
        context.q[self._arm_sel] = arm
        return self._palm_distance(context.data, context.q)

    def coupled_q(self, arm: np.ndarray) -> np.ndarray:
        """Full configuration for an arm configuration, the hand set by the law (a copy)."""
        context = self.world.context()
        self._fill(context, arm)
        return context.q.copy()

    #: Old names (``distance`` and ``full_q`` each meant two things in the package).
    distance = normalized_distance
    full_q = coupled_q

    def _fill(self, context: ThreadContext, arm: object) -> float:
        """Write arm (any sequence of floats) and law-driven hand into ``context.q``;
        return ``d`` (``inf`` for a fixed hand, which needs none).

        This is the hot path of every check: it allocates no array and makes as few
        Python-level calls as the law allows (measured in ``benchmarks/bench_validity.py``).
        """
        q = context.q
        q[self._arm_sel] = arm
        law = self.law
        if law.fixed_clipped is not None:
            q[self._hand_sel] = law.fixed_clipped
            return math.inf
        d = self._palm_distance(context.data, q)
        if d > law.mga:
            q[self._hand_sel] = law.high
        else:
            hand = context.hand
            np.multiply(law.low_slope, d, out=hand)
            np.add(hand, law.arrival, out=hand)
            if law.clip_low:
                np.clip(hand, law.lower, law.upper, out=hand)
            q[self._hand_sel] = hand
        return d

    def is_valid(self, arm: object) -> bool:
        """Whether the arm configuration, hand set by the law, is collision-free (with
        the finest margin, ``paddings[-1]``)."""
        return self._check_state(arm)[0]

    def _check_state(self, arm: object) -> tuple[bool, float]:
        """:meth:`is_valid`, and ``d`` there (``inf`` for a fixed hand)."""
        self.states_checked += 1
        context = self.finest_world.context()
        d = self._fill(context, arm)
        free = not pin.computeCollisions(
            self._model, context.data, context.manager, context.q, True
        )
        return free, d

    def is_valid_with_hand(self, arm: np.ndarray, hand: np.ndarray) -> bool:
        """Whether the arm configuration with the given hand is collision-free."""
        self.states_checked += 1
        return not self.finest_world.in_collision(self.robot.full_q(arm, hand))

    # -- motions --------------------------------------------------------------------------
    def weights(
        self, a: np.ndarray, b: np.ndarray, ends: tuple[float, float] | None = None
    ) -> np.ndarray:
        """Weights of the displacement bound for the motion ``a -> b``: without the
        fingers' term where ``d`` provably stays above ``mga`` all along (the hand is then
        on the law's plateau and does not move), else :attr:`motion_weights`.

        Along the motion ``d >= (d(a) + d(b) - rates . |b - a|) / 2``, from the Lipschitz
        bound of ``d`` (:attr:`distance_rates`) at both ends; ``ends`` gives
        ``(d(a), d(b))`` when they are known.
        """
        if self.law.fixed is not None:
            return self.motion_weights
        da, db = (
            (self.normalized_distance(a), self.normalized_distance(b)) if ends is None else ends
        )
        spread = float(self.distance_rates @ np.abs(b - a))
        if 0.5 * (da + db - spread) > self.law.mga:
            return self.plateau_weights
        return self.motion_weights

    def segment_count(
        self,
        a: np.ndarray,
        b: np.ndarray,
        resolution: float | None = None,
        weights: np.ndarray | None = None,
    ) -> int:
        """Number of steps the motion ``a -> b`` is cut into so that no robot point moves
        more than ``resolution`` (default :attr:`resolution`) between checked states, in
        the bound of ``weights`` (default :attr:`motion_weights`)."""
        step = self.resolution if resolution is None else resolution
        w = self.motion_weights if weights is None else weights
        return max(1, math.ceil(float(np.abs(b - a) @ w) / step))

    def interpolate(
        self,
        a: np.ndarray,
        b: np.ndarray,
        resolution: float | None = None,
        weights: np.ndarray | None = None,
    ) -> np.ndarray:
        """Arm states along ``a -> b`` no robot point ``resolution`` (default
        :attr:`resolution`) apart in the bound of ``weights`` (default
        :attr:`motion_weights`), excluding ``a``, including ``b``: ``(n, dof)``."""
        n = self.segment_count(a, b, resolution, weights)
        t = np.arange(1, n + 1, dtype=float)[:, None] / n
        return a + t * (b - a)

    def coupled_qs(self, arms: np.ndarray) -> np.ndarray:
        """Full configurations, hand from the law, for arm states ``(n, dof)``: ``(nq, n)``."""
        arms = np.atleast_2d(arms)
        qs = self._arm_qs(arms)
        steps = self.distance_rates @ np.abs(np.diff(arms, axis=0)).T
        self._set_hands(qs, np.concatenate([[0.0], np.cumsum(steps)]))
        return qs

    full_qs = coupled_qs  # the old name

    def _motion_qs(
        self,
        a: np.ndarray,
        b: np.ndarray,
        spacing: float,
        weights: np.ndarray,
        ends: tuple[float, float],
    ) -> tuple[np.ndarray, np.ndarray]:
        """The states of the motion ``a -> b`` at ``spacing`` [m] in the bound of
        ``weights`` (:meth:`interpolate`), ``a`` included, and their full configurations:
        ``(n, dof)`` and ``(nq, n)``. ``ends`` are ``d(a)`` and ``d(b)``."""
        arms = np.concatenate([a[None, :], self.interpolate(a, b, spacing, weights)])
        qs = self._arm_qs(arms)
        n = arms.shape[0]
        step = float(self.distance_rates @ np.abs(b - a)) / (n - 1)
        self._set_hands(qs, step * np.arange(n), ends)
        return arms, qs

    def _set_hands(
        self, qs: np.ndarray, path: np.ndarray, ends: tuple[float, float] | None = None
    ) -> None:
        """Write the law's hands into the columns of ``qs``, ``d`` bounded along ``path``
        (see :meth:`_law_distances`)."""
        law = self.law
        if law.fixed_clipped is not None:
            qs[self._hand_sel, :] = law.fixed_clipped[:, None]
            return
        d = self._law_distances(qs, path, ends)
        if np.any(d <= law.mga):
            qs[self._hand_sel, :] = law.batch(d).T
        else:  # all on the plateau
            qs[self._hand_sel, :] = law.high[:, None]

    def _arm_qs(self, arms: np.ndarray) -> np.ndarray:
        """``(nq, n)`` configurations with the arm joints of ``arms``, the rest neutral."""
        qs = np.empty((self._model.nq, arms.shape[0]), order="F")
        qs[:] = self.robot.neutral()[:, None]
        qs[self._arm_sel, :] = arms.T
        return qs

    def _palm_distance(self, data: pin.Data, q: np.ndarray) -> float:
        pin.forwardKinematics(self._model, data, q)
        placement = pin.updateFramePlacement(self._model, data, self._palm)
        if self._translation_only:
            return math.dist(placement.translation.tolist(), self._goal) * self._inv_start
        return self.goal_distance(placement)

    def _law_distances(
        self, qs: np.ndarray, path: np.ndarray, ends: tuple[float, float] | None = None
    ) -> np.ndarray:
        """``d`` for the columns of ``qs``, or a value above ``mga`` where the hand is
        certainly on the law's plateau.

        Only ``d <= mga`` changes the hand. ``d`` is Lipschitz in the arm joints
        (:func:`~openup_ompl.motion_bound.distance_rates`), so along the states
        ``|d_i - d_j| <= |path_i - path_j|``, ``path`` being the cumulative
        ``rates . |q_k - q_(k-1)|``. The two ends (given as ``ends`` or from forward
        kinematics) bound every state; those whose bound may reach ``mga`` get forward
        kinematics at every :data:`ANCHOR_STRIDE`-th of them, which bound the states
        between two anchors; the states still unsettled get their own. Far from the
        grasp this costs the two ends; near it, one forward kinematics per state.
        """
        n = qs.shape[1]
        data = self.world.context().data
        distance = self._palm_distance
        mga = self.law.mga
        d = np.full(n, mga + 1.0)
        if ends is None:
            d[0] = distance(data, qs[:, 0])
            d[-1] = distance(data, qs[:, -1]) if n > 1 else d[0]
        else:
            d[0], d[-1] = ends
        if n <= 2:
            return d
        bound = np.maximum(d[0] - path, d[-1] - (path[-1] - path))
        need = np.flatnonzero(bound[1:-1] <= mga) + 1
        if need.size > ANCHOR_STRIDE:
            anchors = need[::ANCHOR_STRIDE]
            for k in anchors.tolist():
                d[k] = distance(data, qs[:, k])
            known = np.concatenate([[0], anchors, [n - 1]])
            rest = need[np.arange(need.size) % ANCHOR_STRIDE != 0]
            right = np.searchsorted(known, rest)
            left, right = known[right - 1], known[right]
            bound = np.maximum(
                d[left] - (path[rest] - path[left]), d[right] - (path[right] - path[rest])
            )
            need = rest[bound <= mga]
        for k in need.tolist():
            d[k] = distance(data, qs[:, k])
        return d

    def check_motion(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether the straight arm motion ``a -> b`` is collision-free with the coupled hand.

        ``b`` is checked first. Then the coarse pass: states :attr:`coarse_resolution`
        apart, in one parallel batch against the widest padding, settle a motion far from
        every obstacle (all free), or one through an obstacle (a state collides even with
        the finest margin). Otherwise ``a``, the intermediate states at :attr:`resolution`
        and ``b`` go to the base padding in one batch: every state keeps that margin
        (free), or one collides with the finest (not free), or some keep only a thinner
        margin and the intervals next to them are cut finer until each is covered
        (:meth:`_certify`). On one thread the batches loop over their states
        (:meth:`~openup_ompl.collision.CollisionWorld.batch_in_collision`).
        """
        self.motions_checked += 1
        free, db = self._check_state(b)
        if not free:
            return False
        ends = (
            (math.inf, math.inf)
            if self.law.fixed is not None
            else (self.normalized_distance(a), db)
        )
        weights = self.weights(a, b, ends)
        if self._coarse:
            arms, qs = self._motion_qs(a, b, self.coarse_resolution, weights, ends)
            self.states_checked += arms.shape[0]
            if not np.any(self._worlds[0].batch_in_collision(qs)):
                return self._certify(
                    arms, np.zeros(arms.shape[0], dtype=int), weights, self.coarse_resolution
                )
            if np.any(self.finest_world.batch_in_collision(qs)):
                return False
        base = self._coarse
        arms, qs = self._motion_qs(a, b, self.resolution, weights, ends)
        self.states_checked += arms.shape[0]
        if not np.any(self._worlds[base].batch_in_collision(qs)):
            return self._certify(arms, np.full(arms.shape[0], base), weights, self.resolution)
        if np.any(self.finest_world.batch_in_collision(qs)):
            return False
        flags = self._worlds[base].batch_in_collision(qs, stop_at_first=False)
        levels = np.full(arms.shape[0], base)
        for i in np.flatnonzero(flags):
            level = self._level(qs[:, i], base + 1)
            if level is None:
                return False
            levels[i] = level
        return self._certify(arms, levels, weights)

    def _level(self, q: np.ndarray, first: int = 0) -> int | None:
        """Index of the widest margin, from level ``first`` on, at which ``q`` is
        collision-free, or ``None``."""
        for level in range(first, len(self._worlds)):
            if not self._worlds[level].in_collision(q):
                return level
        return None

    def _certify(
        self,
        arms: np.ndarray,
        levels: np.ndarray,
        weights: np.ndarray,
        spacing: float | None = None,
    ) -> bool:
        """Whether the polyline through ``arms`` is collision-free, given each state's
        margin level, in the displacement bound of ``weights``.

        An interval is covered when no robot point moves more than twice the thinner of
        its two end margins along it: every point then stays within one margin of a
        checked position. Uncovered intervals are split at their middle, the new state
        checked, until covered or a state collides even with the finest margin. Given
        ``spacing``, the most any point moves along one interval (known when ``arms``
        were interpolated at it), the intervals are covered at once if it is at most
        twice the thinnest margin.
        """
        pads = np.asarray(self.paddings)
        if pads[-1] <= 0.0:  # no padding: plain resolution checks, no guarantee
            return True
        if spacing is not None and spacing <= 2 * pads[int(np.max(levels))]:
            return True
        reach = np.abs(np.diff(arms, axis=0)) @ weights
        margin = pads[np.maximum(levels[:-1], levels[1:])]
        stack = [
            (arms[i], int(levels[i]), arms[i + 1], int(levels[i + 1]))
            for i in np.flatnonzero(reach > 2 * margin)
        ]
        while stack:
            start, start_level, end, end_level = stack.pop()
            if float(np.abs(end - start) @ weights) <= 2 * pads[max(start_level, end_level)]:
                continue
            middle = 0.5 * (start + end)
            self.states_checked += 1
            level = self._level(self.coupled_q(middle), min(start_level, end_level))
            if level is None:
                return False
            stack.append((start, start_level, middle, level))
            stack.append((middle, level, end, end_level))
        return True


def _selector(indices: np.ndarray) -> slice | np.ndarray:
    """A slice equal to a run of consecutive indices (faster assignment), else the indices."""
    if indices.size and np.all(np.diff(indices) == 1):
        return slice(int(indices[0]), int(indices[-1]) + 1)
    return indices


class CoupledValidityChecker(ob.StateValidityChecker):
    """OMPL state validity checker: arm state -> FK -> ``d`` -> hand law -> Coal collision.

    Args:
        si: OMPL space information over the arm joints (``RealVectorStateSpace``).
        checker: The coupled check to run.
    """

    def __init__(self, si: ob.SpaceInformation, checker: CoupledChecker) -> None:
        super().__init__(si)
        self.checker = checker
        self._n = checker.robot.arm_idx.size

    def isValid(self, state: ob.State) -> bool:  # noqa: N802 - OMPL's name
        return self.checker.is_valid(state[0 : self._n])


class CoupledMotionValidator(ob.MotionValidator):
    """OMPL motion validator: the arm interpolated at the checker's resolution, the hand
    following the law at every intermediate state, all states checked in one batch.

    Only ``checkMotion(s1, s2)`` is available from Python (OMPL's last-valid overload is
    not bound). ``s1`` is assumed valid; ``s2`` is checked.
    """

    def __init__(self, si: ob.SpaceInformation, checker: CoupledChecker) -> None:
        super().__init__(si)
        self.checker = checker
        self._n = checker.robot.arm_idx.size

    def checkMotion(self, s1: ob.State, s2: ob.State) -> bool:  # noqa: N802 - OMPL's name
        n = self._n
        return self.checker.check_motion(np.array(s1[0:n]), np.array(s2[0:n]))
