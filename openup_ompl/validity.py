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

from openup_ompl._model import selector
from openup_ompl._toml import is_finite, is_integer, is_number
from openup_ompl.collision import CollisionWorld, ThreadContext
from openup_ompl.exceptions import ConfigError, InvalidProblem
from openup_ompl.hand_law import HandLaw, NormalizedDistance, palm_distance
from openup_ompl.ik import MAX_POSITION_TOLERANCE
from openup_ompl.motion_bound import (
    arm_weights,
    body_bounds,
    body_curvature,
    distance_rates,
    hand_rate,
    local_rate_terms,
    local_reach,
)
from openup_ompl.scene import Problem

#: Default motion-check resolution [m]: the largest distance any point of the robot may
#: move between two consecutive checked states of a motion (bounded as in
#: :mod:`openup_ompl.motion_bound`). Obstacles and object are padded by half of it, which
#: makes the check of a whole motion exact for the unpadded scene.
DEFAULT_RESOLUTION = 0.006
#: The coarsest motion-check resolution accepted [m]: beyond it the checks, and the
#: default padding of half of it, stop describing the scene.
RESOLUTION_MAX = 0.1
#: The finest motion-check resolution accepted [m]: a tenth of a millimetre, 60 times
#: finer than the default (at 1e-12 m a motion check tried to allocate 80 GiB).
RESOLUTION_MIN = 1e-4
#: Forward kinematics for ``d`` at every this many states of a motion; the states between
#: are bounded from these (see :meth:`CoupledChecker._law_distances`).
ANCHOR_STRIDE = 8

#: Halvings of the padding available where the full margin is not: a state counts as
#: collision-free down to a clearance of ``padding / 2**REFINE_LEVELS`` (0.375 mm by
#: default), and motions through thinner margins are cut finer to stay exact.
REFINE_LEVELS = 3
#: Doublings of the padding tried first: a motion's first states are ``2**COARSE_LEVELS``
#: times farther apart than the resolution, checked against obstacles padded
#: ``2**COARSE_LEVELS`` times more (48 mm apart, 24 mm of padding by default), which is as
#: exact and settles a motion far from every obstacle with an eighth of the states; the
#: margins between are used where the robot passes closer (see
#: :meth:`CoupledChecker.check_motion`).
COARSE_LEVELS = 3
#: The most doublings accepted (the widest margin is ``padding * 2**levels``).
COARSE_LEVELS_MAX = 16
#: A motion's displacement bound is tightened from its two ends' placements
#: (:func:`~openup_ompl.motion_bound.local_reach`, about 25 us) when the global weights'
#: bound spans more than this many of the first round's intervals, or when the first round
#: leaves intervals that need at least ``LOCAL_REACH_MIN_STATES`` more states: below
#: these, reading the placements costs more than the states it would spare.
LOCAL_REACH_MIN_INTERVALS = 8
LOCAL_REACH_MIN_STATES = 8
#: The arm's share of a motion's bound is never tightened below this fraction of its
#: global bound: self-collision margins rely on it
#: (:func:`~openup_ompl.motion_bound.self_pair_factors`).
ARM_TIGHTEN_FLOOR = 0.5
#: A motion whose first round has at least this many states (a long one: most are a path
#: simplifier's shortcuts, most of which collide) is first probed at every
#: ``PROBE_STRIDE``-th of them against the finest margin (:meth:`CoupledChecker.check_motion`).
PROBE_MIN_STATES = 24
PROBE_STRIDE = 8
#: The least distance [m] of the start's palm from the grasp pose (Algorithm 1's
#: denominator): the loosest goal position tolerance, within which the start is already
#: at the grasp.
MIN_START_DISTANCE = MAX_POSITION_TOLERANCE
#: The least palm travel [m] over which the law may change the hand (``mga`` times the
#: start's distance). The checks that certify the fingers' motion near the grasp grow as
#: its inverse: on the LWA3, 2.5 mm (1 cm from the grasp, ``mga`` 0.25) cost 39,000 plan
#: rows and 1.2 s, 0.25 mm 383,000 rows and 23 s, and 1e-8 m never ended.
MIN_LAW_TRAVEL = 0.0025
#: Accepted motions remembered by :attr:`CoupledChecker.certified` at most.
CERTIFIED_MAX = 200_000
#: Collision-free arm states remembered, with their ``d``, at most (see
#: :meth:`CoupledChecker.is_valid`): a tree's vertex is checked when it is grown and is an
#: end of the motions checked later.
KNOWN_VALID_MAX = 50_000


class CoupledChecker:
    """The numpy-level coupled check shared by the OMPL validity checker, the motion
    validator, inverse kinematics and the planners.

    Args:
        problem: Robot, scene and grasp.
        law: The hand law (``problem.hand_law`` if omitted).
        world: A collision world to reuse (built from ``problem`` if omitted).
        resolution: Motion-check resolution [m] (see :data:`DEFAULT_RESOLUTION`), in
            ``[RESOLUTION_MIN, RESOLUTION_MAX]``.
        padding: Margin [m] added around obstacles and object, and between the robot's
            own links (a pair's margin is up to twice it: see
            :func:`~openup_ompl.collision.self_margins`); ``None`` gives
            ``resolution / 2``, the margin that makes motion checks exact. Where a state
            lacks that margin, halved margins (:data:`REFINE_LEVELS`) are tried and the
            motion around it is cut finer; ``0`` turns the guarantee off.
        coarse_levels: Doublings of the padding and of the spacing of the first pass
            over a motion (:data:`COARSE_LEVELS`); ``0`` checks every motion at
            ``resolution`` directly.

    Raises:
        ConfigError: A bad resolution, padding or number of coarse levels.
        InvalidProblem: A start too close to the grasp for the law
            (:data:`MIN_START_DISTANCE`, :data:`MIN_LAW_TRAVEL`), refused before any
            check is built on that distance.

    Attributes:
        paddings: The margins [m] of the levels, widest first: the coarse pass's
            (:data:`COARSE_LEVELS`), the base ``padding``, then its halvings.
        coarse_resolution: Spacing [m] of the coarse pass's states.
        states_checked: States checked so far (single and batched; a free state
            :meth:`is_valid` remembers is not checked, nor counted, again).
        motions_checked: Motions checked so far.
        certified: Motions :meth:`check_motion` accepted, as ``(a, b)`` byte keys, so that
            a path made of them need not be checked again (:meth:`is_certified`); kept up
            to :data:`CERTIFIED_MAX` motions, then restarted.
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
        if not (is_number(resolution) and RESOLUTION_MIN <= resolution <= RESOLUTION_MAX):
            raise ConfigError(
                "resolution", resolution, f"a length in [{RESOLUTION_MIN:g}, {RESOLUTION_MAX:g}] m"
            )
        padding = resolution / 2 if padding is None else padding
        if not (is_finite(padding) and padding >= 0):
            raise ConfigError("padding", padding, "a distance >= 0 [m]")
        if not (is_integer(coarse_levels) and 0 <= coarse_levels <= COARSE_LEVELS_MAX):
            raise ConfigError(
                "coarse_levels", coarse_levels, f"an integer in [0, {COARSE_LEVELS_MAX}]"
            )
        self.problem = problem
        self.robot = problem.robot
        self.law = problem.hand_law if law is None else law
        start_q = self.robot.full_q(problem.start, self.law(1.0))
        start_placement = self.robot.palm_placement(self.robot.model.createData(), start_q)
        _check_reach(problem.grasp, start_placement, self.law)
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
        self._pads = np.asarray(self.paddings)
        self.coarse_resolution = self.resolution * 2.0**self._coarse
        self._model = self.robot.model
        self._palm = self.robot.palm_frame_id
        self.goal_distance = NormalizedDistance(
            problem.grasp, start_placement, self.law.distance, self.law.rotation_weight
        )
        self._arm_idx = self.robot.arm_idx
        self._hand_idx = self.robot.hand_idx
        self._arm_sel = selector(self._arm_idx)
        self._hand_sel = selector(self._hand_idx)
        self._translation_only = self.law.distance == "translation"
        self._goal = problem.grasp.translation.tolist()
        self._inv_start = 1.0 / self.goal_distance.start_distance
        start_distance = self.goal_distance.start_distance
        self.plateau_weights = arm_weights(self.robot)
        self.distance_rates = distance_rates(self.robot, self.law, start_distance)
        model = self._model
        # Fingers' displacement per unit of d (none for a fixed hand); with the rates of d
        # it gives the fingers' share of the bound.
        self._hand_rate = (
            0.0
            if self.law.fixed is not None
            else hand_rate(
                self.robot, [model.getJointId(n) for n in self.robot.hand_joints], self.law
            )
        )
        self.motion_weights = self.plateau_weights + self._hand_rate * self.distance_rates
        self._local_terms = (
            None if self.law.fixed is not None else local_rate_terms(self.robot, self.law)
        )
        self._arm_joint_ids = [model.getJointId(n) for n in self.robot.spec.arm_joints]
        self._bodies = body_bounds(self.robot)
        self.states_checked = 0
        self.motions_checked = 0
        self.certified: set[bytes] = set()
        self._known_valid: dict[bytes, float] = {}

    # -- single states ----------------------------------------------------------------
    def normalized_distance(self, arm: np.ndarray) -> float:
        """Normalised palm-to-grasp distance ``d`` (Algorithm 1) of an arm configuration."""
        context = self.world.context()
        context.q[self._arm_sel] = arm
        return self._palm_distance(context.data, context.q)

    def _palm_point(self, arm: np.ndarray) -> list[float]:
        """The palm's position [m] at an arm configuration."""
        context = self.world.context()
        context.q[self._arm_sel] = arm
        return self.robot.palm_placement(context.data, context.q).translation.tolist()

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
        the finest margin, ``paddings[-1]``).

        An arm configuration given as a float64 array and found free is remembered (up to
        :data:`KNOWN_VALID_MAX`, then forgotten at once), and not checked again: the
        motions checked later from or to it (:meth:`check_motion`) read its ``d`` and its
        verdict back.
        """
        return self._check_state(arm)[0]

    def _check_state(self, arm: object) -> tuple[bool, float]:
        """:meth:`is_valid`, and ``d`` there (``inf`` for a fixed hand)."""
        key = arm.tobytes() if type(arm) is np.ndarray and arm.dtype == np.float64 else None
        if key is not None:
            d = self._known_valid.get(key)
            if d is not None:
                return True, d
        self.states_checked += 1
        context = self.finest_world.context()
        d = self._fill(context, arm)
        free = not pin.computeCollisions(
            self._model, context.data, context.manager, context.q, True
        )
        if free and key is not None:
            if len(self._known_valid) >= KNOWN_VALID_MAX:
                self._known_valid.clear()
            self._known_valid[key] = d
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
        return self.plateau_weights if self._on_plateau(da, db, spread) else self.motion_weights

    def _on_plateau(self, da: float, db: float, spread: float) -> bool:
        """Whether ``d`` stays above ``mga`` all along a motion whose ends have ``d`` =
        ``da`` and ``db`` and along which ``d`` changes by at most ``spread`` per unit of
        ``t``: ``d >= (da + db - spread) / 2`` everywhere on it."""
        return 0.5 * (da + db - spread) > self.law.mga

    def _motion_spread(
        self, a: np.ndarray, b: np.ndarray, abs_delta: np.ndarray, spread: float | None = None
    ) -> float:
        """How much ``d`` can change per unit of ``t`` along the motion ``a -> b`` with
        ``abs_delta = |b - a|``: at most ``spread``, the global bound
        :attr:`distance_rates` ``@ abs_delta`` (computed if not given).

        The palm's speed bound of :func:`~openup_ompl.motion_bound.local_rate_terms`: its
        displacement between the motion's ends plus half a bound of its acceleration. Near
        the grasp a short motion moves the palm nearly straight: a 25 mm step of the LWA3's
        retreat is bounded at 47 mm of palm motion instead of 180 mm, and the fingers'
        share of its displacement bound shrinks with it.
        """
        if spread is None:
            spread = float(self.distance_rates @ abs_delta)
        if self._local_terms is None:
            return spread
        second, rotation = self._local_terms
        turn = float(rotation @ abs_delta)
        taylor = math.dist(self._palm_point(a), self._palm_point(b))
        taylor += 0.5 * float(abs_delta @ second @ abs_delta)
        return min(spread, (taylor + turn) * self._inv_start)

    def _local_reach(
        self, a: np.ndarray, b: np.ndarray, curvature: np.ndarray, arm: float
    ) -> float:
        """The arm's share of the displacement bound of the motion ``a -> b``, tightened
        from ``arm`` (the global bound) by the arm joints' placements at its two ends and
        the bodies' ``curvature`` (:func:`~openup_ompl.motion_bound.local_reach`), never below
        :data:`ARM_TIGHTEN_FLOOR` times ``arm``; computed in the finest world's context
        (whose next check recomputes it)."""
        assert self._bodies is not None
        ids = self._arm_joint_ids
        context = self.finest_world.context()
        q, data, model = context.q, context.data, self._model
        frames = []
        for end in (a, b):
            q[self._arm_sel] = end
            pin.forwardKinematics(model, data, q)
            placements = data.oMi.tolist()  # one call, not one per joint
            frames.append(np.array([placements[j].homogeneous for j in ids]))
        local = local_reach(self._bodies, frames[0], frames[1], curvature)
        return min(arm, max(local, ARM_TIGHTEN_FLOOR * arm))

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

    def _set_hands(
        self, qs: np.ndarray, path: np.ndarray, ends: tuple[float, float] | None = None
    ) -> np.ndarray | None:
        """Write the law's hands into the columns of ``qs``, ``d`` bounded along ``path``;
        return the lower bounds of ``d`` used (see :meth:`_law_distances`; ``None`` for a
        fixed hand)."""
        law = self.law
        if law.fixed_clipped is not None:
            qs[self._hand_sel, :] = law.fixed_clipped[:, None]
            return None
        d = self._law_distances(qs, path, ends)
        if d.min() <= law.mga:
            qs[self._hand_sel, :] = law.columns(d)
        else:  # all on the plateau
            qs[self._hand_sel, :] = law.high[:, None]
        return d

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
        """``d`` for the columns of ``qs``, or a lower bound of it above ``mga`` where the
        hand is certainly on the law's plateau.

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
        if ends is None:
            first = distance(data, qs[:, 0])
            ends = (first, distance(data, qs[:, -1]) if n > 1 else first)
        if n <= ANCHOR_STRIDE + 2:
            # A motion's few states: plain Python is faster than numpy's calls.
            d0, d1 = ends
            steps = path.tolist()
            total = steps[-1]
            out = [d0]
            for k in range(1, n - 1):
                low = max(d0 - steps[k], d1 - (total - steps[k]))
                out.append(distance(data, qs[:, k]) if low <= mga else low)
            if n > 1:
                out.append(d1)
            return np.array(out)
        d = np.empty(n)
        d[0], d[-1] = ends
        bound = np.maximum(d[0] - path, d[-1] - (path[-1] - path))
        d[1:-1] = bound[1:-1]
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
            d[rest] = bound
            need = rest[bound <= mga]
        for k in need.tolist():
            d[k] = distance(data, qs[:, k])
        return d

    def check_motion(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether the straight arm motion ``a -> b`` is collision-free with the coupled hand.

        ``b`` is checked first (the finest margin). Then states of the motion are placed
        where they are needed, each with the widest of the margins :attr:`paddings` it
        keeps: a point of the robot that moves no more than ``m_i + m_j`` between two
        checked states of margins ``m_i`` and ``m_j`` stays within one margin of one of
        them, so the interval between them is collision-free. The first round places
        states :attr:`coarse_resolution` apart against the widest margin: a motion far
        from every obstacle is settled by them. Each further round cuts the intervals
        still uncovered at the spacing their thinner end's margin covers, and checks the
        new states from that margin on; a state that collides even with the finest margin
        refuses the motion. Each round's states of one margin go to Coal in one batch
        (:meth:`~openup_ompl.collision.CollisionWorld.batch_in_collision`). A long
        motion's first round (:data:`PROBE_MIN_STATES` states or more) is probed first:
        one state in :data:`PROBE_STRIDE` against the finest margin, up to the first that
        collides, which refuses it as its full round would.

        The displacement bound is the arm's share plus the fingers'. The arm's is the
        global weights' (:attr:`plateau_weights`), or, once the motion needs more than the
        first round or is long, the smaller bound from its two ends' placements
        (:func:`~openup_ompl.motion_bound.local_reach`). The fingers' is counted only over
        the intervals where ``d`` may reach ``mga`` (from the lower bounds of ``d`` at
        their two states and how fast ``d`` changes along the motion): elsewhere the
        hand is on the law's plateau and still.
        """
        self.motions_checked += 1
        free, db = self._check_state(b)
        if not free:
            return False
        mga = self.law.mga
        delta = b - a
        abs_delta = np.abs(delta)
        spread = float(self.distance_rates @ abs_delta)  # d changes by at most [per unit t]
        # The fingers may move where d may reach mga along the motion (see weights()).
        # d(a) >= d(b) - spread, so d(b) - spread > mga keeps the hand on the plateau all
        # along without forward kinematics at a.
        ends = (math.inf, math.inf)
        fingers_move = self.law.fixed is None and db - spread <= mga
        if fingers_move:
            da = self._known_valid.get(a.tobytes())
            ends = (self.normalized_distance(a) if da is None else da, db)
            fingers_move = not self._on_plateau(*ends, spread)
        if fingers_move and self._local_terms is not None:
            # Bound d along this motion from its ends, tighter than the global rates.
            spread = self._motion_spread(a, b, abs_delta, spread)
            fingers_move = not self._on_plateau(*ends, spread)
        plateau = not fingers_move
        # No robot point moves farther [m] per unit of t than the arm's share, plus the
        # fingers' (through d) where d may be at or below mga.
        arm = float(abs_delta @ self.plateau_weights)
        fingers = self._hand_rate * spread if fingers_move else 0.0
        # The part of the motion where d may reach mga (from the ends and the spread).
        window = 1.0
        if fingers > 0.0:
            window -= (max(ends[0] - mga, 0.0) + max(ends[1] - mga, 0.0)) / spread
            window = min(max(window, 0.0), 1.0)
        pads = self._pads
        # The arm's share tightened from the motion's ends (local_reach) at once for a long
        # motion, else only if the first pass does not settle it; only where it may pay:
        # its curvature term, known without forward kinematics, stays under
        # ARM_TIGHTEN_FLOOR times the global bound.
        tighten = False
        if self._bodies is not None:
            curvature = body_curvature(self._bodies, abs_delta)
            tighten = 0.5 * float(curvature.max()) < ARM_TIGHTEN_FLOOR * arm
        if tighten and arm + fingers * window > LOCAL_REACH_MIN_INTERVALS * 2.0 * pads[0]:
            arm = self._local_reach(a, b, curvature, arm)
            tighten = False
        if pads[-1] <= 0.0:  # no padding: plain resolution checks, no guarantee
            n = max(1, math.ceil((arm + fingers) / self.resolution))
            qs, _ = self._states(a, delta, np.arange(n + 1) / n, ends, spread, plateau)
            self.states_checked += n + 1
            return not np.any(self.finest_world.batch_in_collision(qs))
        # The first round counts the fingers where they move at an end; elsewhere the
        # rounds after it cut the intervals where d comes near mga.
        first = arm + (fingers * window if min(ends) <= mga else 0.0)
        n = max(1, math.ceil(first / (2.0 * pads[0])))
        t = np.arange(n + 1) / n
        qs, low = self._states(a, delta, t, ends, spread, plateau)
        if n + 1 >= PROBE_MIN_STATES and self._probe_collides(qs):
            return False
        levels = self._margins(qs, np.zeros(n + 1, dtype=np.intp))
        if levels is None:
            return False
        while True:
            margin = pads[levels]
            dt = np.diff(t)
            if fingers > 0.0 and low is not None:
                # The fingers stay on the plateau over an interval whose ends' lower bounds
                # of d keep d above mga all along it.
                moving = low[:-1] + low[1:] - spread * dt <= 2.0 * mga
                gap = dt * (arm + fingers * moving)
            else:
                gap = dt * arm
            open_ = np.flatnonzero(gap > (margin[:-1] + margin[1:]) * (1.0 - 1e-12))
            if open_.size == 0:
                self._certified(a, b)
                return True
            # Cut each uncovered interval at the spacing its thinner end's margin covers.
            thinner = np.maximum(levels[open_], levels[open_ + 1])
            pieces = np.maximum(np.ceil(gap[open_] / (2.0 * pads[thinner]) - 1e-9), 2)
            pieces = pieces.astype(np.intp)
            if tighten:
                tighten = False
                if int(pieces.sum()) - pieces.size >= LOCAL_REACH_MIN_STATES:
                    arm = self._local_reach(a, b, curvature, arm)
                    continue
            owner = np.repeat(np.arange(open_.size), pieces - 1)
            first = np.cumsum(pieces - 1) - (pieces - 1)
            rank = np.arange(owner.size) - first[owner] + 1
            new_t = t[open_][owner] + rank * (dt[open_] / pieces)[owner]
            new_qs, new_low = self._states(a, delta, new_t, ends, spread, plateau)
            new_levels = self._margins(new_qs, thinner[owner])
            if new_levels is None:
                return False
            order = np.argsort(np.concatenate([t, new_t]), kind="stable")
            t = np.concatenate([t, new_t])[order]
            levels = np.concatenate([levels, new_levels])[order]
            if low is not None and new_low is not None:
                low = np.concatenate([low, new_low])[order]

    def forget(self) -> None:
        """Forget the free states :meth:`is_valid` remembers and the motions
        :attr:`certified` holds: the next checks of them are done again (to time cold
        checks, or after the checker's scene was changed in place)."""
        self._known_valid.clear()
        self.certified.clear()

    def _certified(self, a: np.ndarray, b: np.ndarray) -> None:
        if len(self.certified) >= CERTIFIED_MAX:
            self.certified.clear()
        self.certified.add(a.tobytes() + b.tobytes())

    def is_certified(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether :meth:`check_motion` accepted the motion ``a -> b`` or ``b -> a`` (the
        same bit-exact arm configurations) since :attr:`certified` last restarted."""
        a = np.ascontiguousarray(a, dtype=float)
        b = np.ascontiguousarray(b, dtype=float)
        keys = self.certified
        return a.tobytes() + b.tobytes() in keys or b.tobytes() + a.tobytes() in keys

    def _states(
        self,
        a: np.ndarray,
        delta: np.ndarray,
        t: np.ndarray,
        ends: tuple[float, float],
        spread: float | None = None,
        plateau: bool = False,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Full configurations ``(nq, len(t))`` at ``a + t * delta`` (``t`` in [0, 1]), the
        hand from the law; ``ends`` are ``d`` at ``t = 0`` and ``t = 1``, ``spread`` how
        much ``d`` changes at most per unit of ``t`` (default :attr:`distance_rates`
        ``@ |delta|``). Also the lower bounds of ``d`` the hands were set from (exact
        where ``d <= mga``; ``None`` for a fixed hand). ``plateau`` says that ``d`` is
        known to stay above ``mga`` all along: every hand is the law's plateau, and no
        bound of ``d`` is computed (``None`` is returned for them)."""
        law = self.law
        if plateau or law.fixed_clipped is not None:
            qs = self._arm_qs(a + t[:, None] * delta)
            hand = law.high if law.fixed_clipped is None else law.fixed_clipped
            qs[self._hand_sel, :] = hand[:, None]
            return qs, None
        if spread is None:
            spread = float(self.distance_rates @ np.abs(delta))
        # The hands of _set_hands, which bounds d from the motion's two ends: bracket the
        # states with them where t does not hold them.
        bracket = not (t[0] == 0.0 and t[-1] == 1.0)
        at = np.concatenate([[0.0], t, [1.0]]) if bracket else t
        qs = self._arm_qs(a + at[:, None] * delta)
        low = self._set_hands(qs, at * spread, ends)
        if not bracket:
            return qs, low
        return qs[:, 1:-1], None if low is None else low[1:-1]

    def _probe_collides(self, qs: np.ndarray) -> bool:
        """Whether one of every :data:`PROBE_STRIDE` columns of ``qs`` (a long motion's
        first round) collides with the finest margin, checked one by one up to the first
        that does. Such a state refuses the motion as :meth:`_margins` would (it collides
        with every wider margin too), so the verdict is the same; a refused motion then
        costs a few states instead of its whole first round."""
        probe = np.asfortranarray(qs[:, PROBE_STRIDE // 2 :: PROBE_STRIDE])
        self.states_checked += probe.shape[1]
        return bool(np.any(self.finest_world.batch_in_collision(probe)))

    def _margins(self, qs: np.ndarray, first: np.ndarray) -> np.ndarray | None:
        """For each column of ``qs``, the index of the widest margin, from ``first`` on
        (per column), at which it is collision-free; ``None`` if one collides even with the
        finest margin (tried at once for the states that lose their ``first`` margin, so
        that a colliding motion costs little)."""
        self.states_checked += qs.shape[1]
        levels = first.copy()
        finest = len(self._worlds) - 1
        pending = np.arange(qs.shape[1])
        tried_finest = False
        while pending.size:
            level = int(levels[pending].min())
            batch = pending[levels[pending] == level]
            states = qs if batch.size == qs.shape[1] else np.asfortranarray(qs[:, batch])
            flags = self._worlds[level].batch_in_collision(states, stop_at_first=False)
            hit = batch[flags]
            if hit.size and level == finest:
                return None
            if hit.size and not tried_finest:
                tried_finest = True
                if np.any(self.finest_world.batch_in_collision(np.asfortranarray(qs[:, hit]))):
                    return None
            levels[hit] += 1
            pending = pending[levels[pending] != level]
        return levels


def _check_reach(grasp: pin.SE3, start_placement: pin.SE3, law: HandLaw) -> None:
    """Refuse a start palm (at ``start_placement``) too close to ``grasp`` for the law:
    within :data:`MIN_START_DISTANCE`, or, for a law that moves the hand, one whose
    ``mga`` times that distance is under :data:`MIN_LAW_TRAVEL`."""
    rotation_t = grasp.rotation.T if law.distance == "weighted" else None
    reach = palm_distance(start_placement, grasp.translation, rotation_t, law.rotation_weight)
    if reach < MIN_START_DISTANCE:
        raise InvalidProblem(
            f"start is already at the grasp pose: its palm is {reach:.3g} m from it "
            f"(the hand law's {law.distance} distance), under {MIN_START_DISTANCE:g} m"
        )
    if law.fixed is None and law.mga * reach < MIN_LAW_TRAVEL:
        raise InvalidProblem(
            f"the hand law would move the fingers over {law.mga * reach * 1e3:.3g} mm of "
            f"the reach (mga {law.mga:g} times the start's {reach:.3g} m from the grasp), "
            f"under {MIN_LAW_TRAVEL * 1e3:g} mm: the checks near the grasp grow as its "
            "inverse; start farther from the grasp, raise mga or fix the hand"
        )


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
