"""The coupled check of single arm states: forward kinematics, the normalised distance
``d`` to the grasp (Algorithm 1), the hand from the law (Algorithm 3), then Coal.

:class:`StateChecker` also sets the law's hands on batches of states (the states a motion
check places), bounding ``d`` where that spares forward kinematics.
"""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl import native as _native
from openup_ompl._model import selector
from openup_ompl._toml import is_finite, is_integer
from openup_ompl.collision import PARALLEL_MIN_STATES, CollisionWorld, ThreadContext
from openup_ompl.exceptions import ConfigError, InvalidProblem
from openup_ompl.hand_law import HandLaw, NormalizedDistance, palm_distance
from openup_ompl.ik import MAX_POSITION_TOLERANCE
from openup_ompl.scene import Problem

#: Forward kinematics for ``d`` at every this many states of a motion; the states between
#: are bounded from these (see :meth:`StateChecker._law_distances`).
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
#: :meth:`~openup_ompl.validity.CoupledChecker.check_motion`).
COARSE_LEVELS = 3
#: The most doublings accepted (the widest margin is ``padding * 2**levels``).
COARSE_LEVELS_MAX = 16
#: The least distance [m] of the start's palm from the grasp pose (Algorithm 1's
#: denominator): the loosest goal position tolerance, within which the start is already
#: at the grasp.
MIN_START_DISTANCE = MAX_POSITION_TOLERANCE
#: The least palm travel [m] over which the law may change the hand (``mga`` times the
#: start's distance). The checks that certify the fingers' motion near the grasp grow as
#: its inverse (see the results page on speed).
MIN_LAW_TRAVEL = 0.0025
#: A state is checked forward kinematics first (for ``d``, then the collision query) when
#: the last state checked had ``d <= NEAR_HINT * mga``; else the query goes first, with the
#: plateau's hand (``StateChecker._check_state``). Chosen on the suites' solves: a
#: planner's states come in runs near or far from the grasp, and the margin above ``mga``
#: spares most of the double queries at the runs' starts.
NEAR_HINT = 2.0
#: Collision-free arm states remembered, with their ``d``, at most (see
#: :meth:`StateChecker.is_valid`): a tree's vertex is checked when it is grown and is an
#: end of the motions checked later.
KNOWN_VALID_MAX = 50_000


class StateChecker:
    """Single states, the hand set by the law, checked at the margins of the motion check.

    Args:
        problem: Robot, scene and grasp.
        law: The hand law (``problem.hand_law`` if omitted).
        world: A collision world to reuse (built from ``problem`` if omitted).
        padding: Margin [m] added around obstacles and object, and between the robot's
            own links (see :func:`~openup_ompl.collision.self_margins`); halvings of it
            (:data:`REFINE_LEVELS`) are the finer margins.
        coarse_levels: Doublings of the padding tried first (:data:`COARSE_LEVELS`).
        native: The compiled check (:mod:`openup_ompl.native`) for single states, ``d`` and
            the batches checked in the calling thread: ``"auto"`` if it is built for the
            versions in use and exact for the law, ``"on"`` always (else
            :class:`~openup_ompl.exceptions.NativeUnavailable`), ``"off"`` never. The
            verdicts, ``d``, the remembered free states and the counts are the same.

    Raises:
        ConfigError: A bad padding, number of coarse levels or ``native``.
        NativeUnavailable: ``native="on"`` and the compiled check cannot be used.
        InvalidProblem: A start too close to the grasp for the law
            (:data:`MIN_START_DISTANCE`, :data:`MIN_LAW_TRAVEL`).

    Attributes:
        paddings: The margins [m] of the levels, widest first: the coarse pass's
            (:data:`COARSE_LEVELS`), the base ``padding``, then its halvings.
        finest_world: The world of the finest margin, ``paddings[-1]``.
        goal_distance: Algorithm 1's normalised distance to the grasp.
        states_checked: States checked so far (a free state :meth:`is_valid` remembers is
            not checked, nor counted, again).
        native: Whether the compiled check is in use (see the ``native`` argument).
    """

    def __init__(
        self,
        problem: Problem,
        law: HandLaw | None,
        world: CollisionWorld | None,
        padding: float,
        coarse_levels: int,
        native: str = "auto",
    ) -> None:
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
        self._model = self.robot.model
        self._palm = self.robot.palm_frame_id
        self.goal_distance = NormalizedDistance(
            problem.grasp, start_placement, self.law.distance, self.law.rotation_weight
        )
        self._arm_sel = selector(self.robot.arm_idx)
        self._hand_sel = selector(self.robot.hand_idx)
        self._translation_only = self.law.distance == "translation"
        self._goal = problem.grasp.translation.tolist()
        self._inv_start = 1.0 / self.goal_distance.start_distance
        self.states_checked = 0
        self._known_valid: dict[bytes, float] = {}
        # Whether the last state checked lay near the grasp (NEAR_HINT; only a hint).
        self._near = False
        self._near_limit = NEAR_HINT * self.law.mga
        self._compiled: Any = _native.resolve(native, self.law)  # and each thread's checks:
        self._compiled_local = threading.local()
        self.native = self._compiled is not None

    def normalized_distance(self, arm: np.ndarray) -> float:
        """Normalised palm-to-grasp distance ``d`` (Algorithm 1) of an arm configuration.

        Args:
            arm: Arm configuration [rad], shape ``(dof,)``.

        Returns:
            ``d`` (unitless; 1 at the start, 0 at the grasp pose).
        """
        context = self.world.context()
        context.q[self._arm_sel] = arm
        return self._palm_distance(context, context.q)

    def _palm_point(self, arm: np.ndarray) -> list[float]:
        """The palm's position [m, world frame] at an arm configuration."""
        context = self.world.context()
        context.q[self._arm_sel] = arm
        return self.robot.palm_placement(context.data, context.q).translation.tolist()

    def coupled_q(self, arm: np.ndarray) -> np.ndarray:
        """Full configuration for an arm configuration, the hand set by the law.

        Args:
            arm: Arm configuration [rad], shape ``(dof,)``.

        Returns:
            A new Pinocchio configuration, shape ``(nq,)``.
        """
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
        d = self._palm_distance(context, q)
        self._set_hand(context, d)
        return d

    def _set_hand(self, context: ThreadContext, d: float) -> None:
        """Write the law's hand at ``d`` into ``context.q``."""
        law = self.law
        if d > law.mga:
            context.q[self._hand_sel] = law.high
            return
        hand = context.hand
        np.multiply(law.low_slope, d, out=hand)
        np.add(hand, law.arrival, out=hand)
        if law.clip_low:
            np.clip(hand, law.lower, law.upper, out=hand)
        context.q[self._hand_sel] = hand

    def is_valid(self, arm: object) -> bool:
        """Whether the arm configuration, hand set by the law, is collision-free (with
        the finest margin, ``paddings[-1]``).

        An arm configuration given as a float64 array and found free is remembered (up to
        :data:`KNOWN_VALID_MAX`, then forgotten at once), and not checked again: the
        motions checked later from or to it read its ``d`` and its verdict back.

        Args:
            arm: Arm configuration [rad], any sequence of ``dof`` floats.

        Returns:
            ``True`` if it is collision-free.
        """
        return self._check_state(arm)[0]

    def _check_state(self, arm: object) -> tuple[bool, float]:
        """:meth:`is_valid`, and ``d`` there (``inf`` for a fixed hand).

        ``d`` needs the palm's placement, and the collision query computes forward
        kinematics anyway. Away from the grasp (the hand on the law's plateau, as at
        almost every state a planner samples) the state is queried with the plateau hand
        first and ``d`` read from the placements the query left: the coupled check then
        costs one forward kinematics, as a fixed hand's does. Where ``d <= mga`` the hand
        was wrong: it is set from ``d`` and the state queried again. When the last state
        checked had ``d <= NEAR_HINT * mga`` (:data:`NEAR_HINT`), the planner is likely
        near the grasp: forward kinematics for ``d`` go first, then the one query. Either
        way the verdict is the query of the state with the law's hand (a query does not
        depend on the ones before it: no GJK warm start).
        """
        key = arm.tobytes() if type(arm) is np.ndarray and arm.dtype == np.float64 else None
        if key is not None:
            d = self._known_valid.get(key)
            if d is not None:
                return True, d
        self.states_checked += 1
        context = self.finest_world.context()
        model, data, manager, q = self._model, context.data, context.manager, context.q
        law = self.law
        collides = None
        if self._compiled is not None:  # the same query, d bit for bit (openup_ompl.native)
            collides, d = self._compiled_state(arm, key is not None)
        elif law.fixed_clipped is not None or self._near:  # forward kinematics for d first
            d = self._fill(context, arm)
            self._near = d <= self._near_limit
        else:  # the plateau's hand first, d from the placements the query leaves
            q[self._arm_sel] = arm
            q[self._hand_sel] = law.high
            collides = pin.computeCollisions(model, data, manager, q, True)
            palm = context.palm
            if palm is not None and self._translation_only:  # _placed_distance, inlined
                pin.updateFramePlacement(model, data, self._palm)
                d = math.dist(palm.tolist(), self._goal) * self._inv_start
            else:
                d = self._placed_distance(context)
            self._near = d <= self._near_limit
            if d <= law.mga:
                self._set_hand(context, d)
                collides = None
        if collides is None:
            collides = pin.computeCollisions(model, data, manager, q, True)
        free = not collides
        if free and key is not None:
            if len(self._known_valid) >= KNOWN_VALID_MAX:
                self._known_valid.clear()
            self._known_valid[key] = d
        return free, d

    def _compiled_state(self, arm: Any, array: bool) -> tuple[bool, float]:
        """``(collides, d)`` of the arm state (a float64 array if ``array``), compiled."""
        try:
            check = self._compiled_local.finest
        except AttributeError:
            check = self._compiled_checks()[-1]
        return not check.is_valid(arm.tolist() if array else arm), check.distance

    def _compiled_checks(self) -> list[Any]:
        """This thread's compiled checks, one per world of :attr:`paddings` (on this
        thread's contexts; created on first use)."""
        try:
            return self._compiled_local.checks  # type: ignore[no-any-return]
        except AttributeError:
            checks = [_native.compiled_check(self._compiled, self, w) for w in self._worlds]
            self._compiled_local.checks = checks
            self._compiled_local.finest = checks[-1]
            return checks

    def _batch_collides(self, level: int, qs: np.ndarray, stop_at_first: bool = True) -> np.ndarray:
        """Flags of the columns of ``qs`` colliding in the world of ``paddings[level]``:
        :meth:`~openup_ompl.collision.CollisionWorld.batch_in_collision`, its batches checked
        in this thread through the compiled loop when in use (the same query, flags)."""
        world = self._worlds[level]
        serial = world.num_threads == 1 or qs.shape[1] < PARALLEL_MIN_STATES
        if self._compiled is None or not serial:
            return world.batch_in_collision(qs, stop_at_first)
        flags = self._compiled_checks()[level].collides_columns(qs, stop_at_first)
        return np.array(flags, dtype=bool)

    def is_valid_with_hand(self, arm: np.ndarray, hand: np.ndarray) -> bool:
        """Whether the arm configuration with the given hand is collision-free.

        Args:
            arm: Arm configuration [rad], shape ``(dof,)``.
            hand: Hand joint values [rad; m for prismatic joints] in the robot's hand
                order, shape ``(hand dof,)``.

        Returns:
            ``True`` if it is collision-free with the finest margin.
        """
        self.states_checked += 1
        return not self.finest_world.in_collision(self.robot.full_q(arm, hand))

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

    def _palm_distance(self, context: ThreadContext, q: np.ndarray) -> float:
        """``d`` at the full configuration ``q`` (forward kinematics in ``context``)."""
        if self.native and self._translation_only:  # the compiled d, bit for bit
            return self._compiled_checks()[-1].distance_q(q)  # type: ignore[no-any-return]
        pin.forwardKinematics(self._model, context.data, q)
        return self._placed_distance(context)

    def _placed_distance(self, context: ThreadContext) -> float:
        """``d`` from the joint placements in ``context.data`` (the last forward
        kinematics there)."""
        placement = pin.updateFramePlacement(self._model, context.data, self._palm)
        if not self._translation_only:
            return self.goal_distance(placement)
        palm = context.palm
        point = placement.translation.tolist() if palm is None else palm.tolist()
        return math.dist(point, self._goal) * self._inv_start

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
        context = self.world.context()
        distance = self._palm_distance
        mga = self.law.mga
        if ends is None:
            first = distance(context, qs[:, 0])
            ends = (first, distance(context, qs[:, -1]) if n > 1 else first)
        if n <= ANCHOR_STRIDE + 2:
            # A motion's few states: plain Python is faster than numpy's calls.
            d0, d1 = ends
            steps = path.tolist()
            total = steps[-1]
            out = [d0]
            for k in range(1, n - 1):
                low = max(d0 - steps[k], d1 - (total - steps[k]))
                out.append(distance(context, qs[:, k]) if low <= mga else low)
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
                d[k] = distance(context, qs[:, k])
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
            d[k] = distance(context, qs[:, k])
        return d

    def _states(
        self,
        a: np.ndarray,
        delta: np.ndarray,
        t: np.ndarray,
        ends: tuple[float, float],
        spread: float,
        plateau: bool = False,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Full configurations ``(nq, len(t))`` at ``a + t * delta`` (``t`` in [0, 1]), the
        hand from the law; ``ends`` are ``d`` at ``t = 0`` and ``t = 1``, ``spread`` how
        much ``d`` changes at most per unit of ``t``. Also the lower bounds of ``d`` the
        hands were set from (exact where ``d <= mga``; ``None`` for a fixed hand).
        ``plateau`` says that ``d`` is known to stay above ``mga`` all along: every hand is
        the law's plateau, and no bound of ``d`` is computed (``None`` is returned for
        them)."""
        law = self.law
        if plateau or law.fixed_clipped is not None:
            qs = self._arm_qs(a + t[:, None] * delta)
            hand = law.high if law.fixed_clipped is None else law.fixed_clipped
            qs[self._hand_sel, :] = hand[:, None]
            return qs, None
        # The hands of _set_hands, which bounds d from the motion's two ends: bracket the
        # states with them where t does not hold them.
        bracket = not (t[0] == 0.0 and t[-1] == 1.0)
        at = np.concatenate([[0.0], t, [1.0]]) if bracket else t
        qs = self._arm_qs(a + at[:, None] * delta)
        low = self._set_hands(qs, at * spread, ends)
        if not bracket:
            return qs, low
        return qs[:, 1:-1], None if low is None else low[1:-1]

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
            flags = self._batch_collides(level, states, stop_at_first=False)
            hit = batch[flags]
            if hit.size and level == finest:
                return None
            if hit.size and not tried_finest:
                tried_finest = True
                if np.any(self._batch_collides(-1, np.asfortranarray(qs[:, hit]))):
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
