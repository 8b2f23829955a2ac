"""Coupled validity: every arm state is checked with the hand set by the hand law.

The arm joints are OMPL's state space; the fingers follow. Three units make the check:
single states (:mod:`openup_ompl.state_check`: forward kinematics, the normalised distance
``d`` to the grasp pose of Algorithm 1, the hand from Algorithm 3, Coal), a motion's
certified-resolution bound (:mod:`openup_ompl.resolution_bound`), and here the motion check
that places states by that bound, with the OMPL classes over it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from ompl import base as ob

from openup_ompl._toml import is_number
from openup_ompl.collision import CollisionWorld
from openup_ompl.exceptions import ConfigError
from openup_ompl.hand_law import HandLaw
from openup_ompl.motion_bound import body_curvature
from openup_ompl.resolution_bound import (
    ARM_TIGHTEN_FLOOR,
    DEFAULT_RESOLUTION,
    RESOLUTION_MAX,
    RESOLUTION_MIN,
    ResolutionBound,
)
from openup_ompl.scene import Problem
from openup_ompl.state_check import (
    ANCHOR_STRIDE,
    COARSE_LEVELS,
    COARSE_LEVELS_MAX,
    KNOWN_VALID_MAX,
    MIN_LAW_TRAVEL,
    MIN_START_DISTANCE,
    REFINE_LEVELS,
    StateChecker,
)

__all__ = [
    "ANCHOR_STRIDE",
    "ARM_TIGHTEN_FLOOR",
    "CERTIFIED_MAX",
    "COARSE_LEVELS",
    "COARSE_LEVELS_MAX",
    "DEFAULT_RESOLUTION",
    "KNOWN_VALID_MAX",
    "LOCAL_REACH_MIN_INTERVALS",
    "LOCAL_REACH_MIN_STATES",
    "MIN_LAW_TRAVEL",
    "MIN_START_DISTANCE",
    "PROBE_MIN_STATES",
    "PROBE_STRIDE",
    "REFINE_LEVELS",
    "RESOLUTION_MAX",
    "RESOLUTION_MIN",
    "CoupledChecker",
    "CoupledMotionValidator",
    "CoupledValidityChecker",
]

#: Past this many first-round intervals of the global weights' bound, or ``LOCAL_REACH_MIN_STATES``
#: states more after the first round, a motion's bound is tightened from its ends' placements
#: (:func:`~openup_ompl.motion_bound.local_reach`); below, reading them costs more than the states
#: it spares.
LOCAL_REACH_MIN_INTERVALS = 8
LOCAL_REACH_MIN_STATES = 8
#: A motion whose first round has at least this many states (a long one: most are a path
#: simplifier's shortcuts, most of which collide) is first probed at every
#: ``PROBE_STRIDE``-th of them against the finest margin (:meth:`CoupledChecker.check_motion`).
PROBE_MIN_STATES = 24
PROBE_STRIDE = 8
#: Accepted motions remembered by :attr:`CoupledChecker.certified` at most.
CERTIFIED_MAX = 200_000


@dataclass
class _MotionBound:
    """One motion's displacement bound, as :meth:`CoupledChecker.check_motion` uses it.

    Attributes:
        delta: ``b - a`` (joint units).
        ends: ``d`` at ``a`` and ``b`` (``inf`` where not needed).
        spread: How much ``d`` changes at most per unit of ``t``.
        plateau: Whether the hand provably stays on the law's plateau.
        arm: The arm's share [m per unit of t] (tightened in place).
        fingers: The fingers' share [m per unit of t] where they may move.
        window: The fraction of the motion where ``d`` may reach ``mga``.
        tighten: Whether the arm's share may still be tightened from the ends.
        curvature: The bodies' curvature terms (for the tightening).
    """

    delta: np.ndarray
    ends: tuple[float, float]
    spread: float
    plateau: bool
    arm: float
    fingers: float
    window: float
    tighten: bool
    curvature: np.ndarray | None


class CoupledChecker(StateChecker):
    """The numpy-level coupled check shared by the OMPL validity checker, the motion
    validator, inverse kinematics and the planners.

    Args:
        problem: Robot, scene and grasp.
        law: The hand law (``problem.hand_law`` if omitted).
        world: A collision world to reuse (built from ``problem`` if omitted).
        resolution: Motion-check resolution [m] (see :data:`DEFAULT_RESOLUTION`), in
            ``[RESOLUTION_MIN, RESOLUTION_MAX]``.
        padding: Margin [m] added around obstacles and object, and between the robot's own
            links (a pair's is up to twice it: :func:`~openup_ompl.collision.self_margins`);
            ``None`` gives ``resolution / 2``, which makes motion checks exact. A state
            lacking it tries halved margins (:data:`REFINE_LEVELS`), the motion around it
            cut finer; ``0`` turns the guarantee off.
        coarse_levels: Doublings of the padding and of the first pass's spacing
            (:data:`COARSE_LEVELS`); ``0`` checks every motion at ``resolution`` directly.
        native: The compiled check (see :class:`~openup_ompl.state_check.StateChecker`).

    Raises:
        ConfigError: A bad resolution, padding, number of coarse levels or ``native``.
        NativeUnavailable: ``native="on"`` and the compiled check is unavailable.
        InvalidProblem: A start too close to the grasp for the law (:data:`MIN_START_DISTANCE`,
            :data:`MIN_LAW_TRAVEL`), before any check uses it.

    Attributes:
        paddings: The margins [m] of the levels, widest first: the coarse pass's
            (:data:`COARSE_LEVELS`), the base ``padding``, then its halvings.
        coarse_resolution: Spacing [m] of the coarse pass's states.
        bound: The certified-resolution bound of motions
            (:class:`~openup_ompl.resolution_bound.ResolutionBound`).
        states_checked: States checked so far (single and batched; a free state
            :meth:`is_valid` remembers is not checked, nor counted, again).
        motions_checked: Motions checked so far.
        certified: Motions :meth:`check_motion` accepted, as ``(a, b)`` byte keys for
            :meth:`is_certified`; up to :data:`CERTIFIED_MAX`, then restarted.
        motion_weights: Weights ``W`` [m per joint unit] of the displacement bound
            (:mod:`~openup_ompl.motion_bound`), the fingers' motion under the law included.
        plateau_weights: The same with the hand still (motions on the plateau, :meth:`weights`).
        distance_rates: How fast ``d`` may change per joint unit.
    """

    def __init__(
        self,
        problem: Problem,
        law: HandLaw | None = None,
        world: CollisionWorld | None = None,
        resolution: float = DEFAULT_RESOLUTION,
        padding: float | None = None,
        coarse_levels: int = COARSE_LEVELS,
        native: str = "auto",
    ) -> None:
        if not (is_number(resolution) and RESOLUTION_MIN <= resolution <= RESOLUTION_MAX):
            raise ConfigError(
                "resolution", resolution, f"a length in [{RESOLUTION_MIN:g}, {RESOLUTION_MAX:g}] m"
            )
        padding = resolution / 2 if padding is None else padding
        super().__init__(problem, law, world, padding, coarse_levels, native)
        self.resolution = float(resolution)
        self.coarse_resolution = self.resolution * 2.0**self._coarse
        self.bound = ResolutionBound(self.robot, self.law, self.goal_distance.start_distance)
        self.plateau_weights = self.bound.plateau_weights
        self.distance_rates = self.bound.distance_rates
        self.motion_weights = self.bound.motion_weights
        self.motions_checked = 0
        self.certified: set[bytes] = set()

    # -- the bound of one motion ------------------------------------------------------
    def weights(
        self, a: np.ndarray, b: np.ndarray, ends: tuple[float, float] | None = None
    ) -> np.ndarray:
        """The displacement bound's weights for the motion ``a -> b``: without the fingers'
        term where ``d`` provably stays above ``mga`` all along (the hand on the plateau,
        still), from ``d >= (d(a) + d(b) - rates . |b - a|) / 2`` (:attr:`distance_rates`).

        Args:
            a, b: Arm configurations [rad], shape ``(dof,)``.
            ends: ``(d(a), d(b))`` [unitless] when known; computed otherwise.
        Returns:
            :attr:`plateau_weights` or :attr:`motion_weights` [m/rad], shape ``(dof,)``.
        """
        if self.law.fixed is not None:
            return self.motion_weights
        da, db = (
            (self.normalized_distance(a), self.normalized_distance(b)) if ends is None else ends
        )
        spread = float(self.distance_rates @ np.abs(b - a))
        plateau = self.bound.on_plateau(da, db, spread)
        return self.plateau_weights if plateau else self.motion_weights

    def _motion_spread(
        self, a: np.ndarray, b: np.ndarray, abs_delta: np.ndarray, spread: float | None = None
    ) -> float:
        """How much ``d`` can change per unit of ``t`` along ``a -> b`` (``abs_delta = |b - a|``):
        at most ``spread`` (:attr:`distance_rates` ``@ abs_delta`` if not given), tightened from the
        palm's ends (:meth:`~openup_ompl.resolution_bound.ResolutionBound.local_spread`)."""
        if spread is None:
            spread = float(self.distance_rates @ abs_delta)
        if self.bound.local_terms is None:
            return spread
        return self.bound.local_spread(abs_delta, spread, self._palm_point(a), self._palm_point(b))

    def _local_reach(
        self, a: np.ndarray, b: np.ndarray, curvature: np.ndarray, arm: float
    ) -> float:
        """The arm's share of the bound of ``a -> b`` tightened from its ends' placements
        (:meth:`~openup_ompl.resolution_bound.ResolutionBound.tightened_arm`), in the finest
        context."""
        ids = self.bound.arm_joint_ids
        context = self.finest_world.context()
        q, data, model = context.q, context.data, self._model
        frames = []
        for end in (a, b):
            q[self._arm_sel] = end
            pin.forwardKinematics(model, data, q)
            placements = data.oMi.tolist()  # one call, not one per joint
            frames.append(np.array([placements[j].homogeneous for j in ids]))
        return self.bound.tightened_arm(frames[0], frames[1], curvature, arm)

    def segment_count(
        self,
        a: np.ndarray,
        b: np.ndarray,
        resolution: float | None = None,
        weights: np.ndarray | None = None,
    ) -> int:
        """Number of steps (at least 1) the motion ``a -> b`` is cut into so that no robot
        point moves more than ``resolution`` between checked states, in the bound of ``weights``.

        Args:
            a, b: Arm configurations [rad], shape ``(dof,)``.
            resolution: Largest move of a robot point per step [m]; default :attr:`resolution`.
            weights: Per-joint weights [m/rad]; default :attr:`motion_weights`.
        Returns:
            The number of steps.
        """
        step = self.resolution if resolution is None else resolution
        w = self.motion_weights if weights is None else weights
        return self.bound.segment_count(b - a, step, w)

    def interpolate(
        self,
        a: np.ndarray,
        b: np.ndarray,
        resolution: float | None = None,
        weights: np.ndarray | None = None,
    ) -> np.ndarray:
        """Arm states along ``a -> b``: no robot point moves more than ``resolution`` between two.

        Args:
            a, b, resolution, weights: As for :meth:`segment_count`.
        Returns:
            ``(n, dof)`` arm states [rad], ``a`` excluded, ``b`` last.
        """
        n = self.segment_count(a, b, resolution, weights)
        t = np.arange(1, n + 1, dtype=float)[:, None] / n
        return a + t * (b - a)

    def coupled_qs(self, arms: np.ndarray) -> np.ndarray:
        """Full configurations of arm states, the hand set by the law.

        Args:
            arms: Arm configurations [rad], shape ``(n, dof)`` (or ``(dof,)``).
        Returns:
            ``(nq, n)`` configurations (joint units), one per column.
        """
        arms = np.atleast_2d(arms)
        qs = self._arm_qs(arms)
        steps = self.distance_rates @ np.abs(np.diff(arms, axis=0)).T
        self._set_hands(qs, np.concatenate([[0.0], np.cumsum(steps)]))
        return qs

    full_qs = coupled_qs  # the old name

    def _motion_bound(self, a: np.ndarray, b: np.ndarray, db: float) -> _MotionBound:
        """The displacement bound of ``a -> b`` (``d(b) = db``): the arm's share from the
        global weights, tightened at once for a long motion; the fingers' only where ``d``
        may reach ``mga`` (from ``d`` at the ends and how fast it changes along it)."""
        mga = self.law.mga
        delta = b - a
        abs_delta = np.abs(delta)
        spread = float(self.distance_rates @ abs_delta)  # d changes by at most [per unit t]
        # d(a) >= d(b) - spread, so d(b) - spread > mga keeps the hand on the plateau all
        # along without forward kinematics at a.
        ends = (math.inf, math.inf)
        fingers_move = self.law.fixed is None and db - spread <= mga
        if fingers_move:
            da = self._known_valid.get(a.tobytes())
            ends = (self.normalized_distance(a) if da is None else da, db)
            fingers_move = not self.bound.on_plateau(*ends, spread)
        if fingers_move and self.bound.local_terms is not None:
            spread = self._motion_spread(a, b, abs_delta, spread)
            fingers_move = not self.bound.on_plateau(*ends, spread)
        arm = float(abs_delta @ self.plateau_weights)
        fingers = self.bound.hand_rate * spread if fingers_move else 0.0
        window = 1.0
        if fingers > 0.0:
            window -= (max(ends[0] - mga, 0.0) + max(ends[1] - mga, 0.0)) / spread
            window = min(max(window, 0.0), 1.0)
        # Tightening pays only while the bodies' curvature term, known without forward
        # kinematics, stays under ARM_TIGHTEN_FLOOR times the global bound.
        tighten, curvature = False, None
        if self.bound.bodies is not None:
            curvature = body_curvature(self.bound.bodies, abs_delta)
            tighten = 0.5 * float(curvature.max()) < ARM_TIGHTEN_FLOOR * arm
        if tighten and arm + fingers * window > LOCAL_REACH_MIN_INTERVALS * 2.0 * self._pads[0]:
            assert curvature is not None
            arm = self._local_reach(a, b, curvature, arm)
            tighten = False
        return _MotionBound(
            delta, ends, spread, not fingers_move, arm, fingers, window, tighten, curvature
        )

    # -- motions ----------------------------------------------------------------------
    def check_motion(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Check the straight arm motion ``a -> b`` with the coupled hand.

        ``b`` is checked first (the finest margin). Then states are placed where needed, each with
        the widest margin of :attr:`paddings` it keeps: a robot point that moves no more than ``m_i
        + m_j`` between checked states of margins ``m_i`` and ``m_j`` stays within one margin of one
        of them, so the interval between them is free. The first round places states
        :attr:`coarse_resolution` apart against the widest margin (settling a motion far from every
        obstacle); each further round cuts the intervals still uncovered at the spacing their
        thinner end's margin covers and checks the new states from that margin on; a state colliding
        even with the finest margin refuses the motion. A round's states of one margin go to Coal in
        one batch. A long first round (:data:`PROBE_MIN_STATES` states) is probed first: one state
        in :data:`PROBE_STRIDE` against the finest margin, up to the first that collides.

        The displacement bound is the arm's share (:attr:`plateau_weights`' bound, or, past the
        first round or for a long motion, the smaller one from its ends' placements:
        :func:`~openup_ompl.motion_bound.local_reach`) plus the fingers', counted only over
        intervals where ``d`` may reach ``mga`` (from the lower bounds of ``d`` at their ends
        and how fast ``d`` changes): elsewhere the hand is on the law's plateau, still.

        Args:
            a, b: Arm configurations [rad], shape ``(dof,)``; ``a`` is assumed valid.
        Returns:
            ``True`` when the motion is free (then :attr:`certified`).
        """
        self.motions_checked += 1
        free, db = self._check_state(b)
        if not free:
            return False
        bound = self._motion_bound(a, b, db)
        if self._pads[-1] <= 0.0:  # no padding: plain resolution checks, no guarantee
            n = max(1, math.ceil((bound.arm + bound.fingers) / self.resolution))
            qs, _ = self._states(
                a, bound.delta, np.arange(n + 1) / n, bound.ends, bound.spread, bound.plateau
            )
            self.states_checked += n + 1
            return not np.any(self._batch_collides(-1, qs))
        # The first round counts the fingers where they move at an end; elsewhere the
        # rounds after it cut the intervals where d comes near mga.
        moving = bound.fingers * bound.window if min(bound.ends) <= self.law.mga else 0.0
        n = max(1, math.ceil((bound.arm + moving) / (2.0 * self._pads[0])))
        t = np.arange(n + 1) / n
        qs, low = self._states(a, bound.delta, t, bound.ends, bound.spread, bound.plateau)
        if n + 1 >= PROBE_MIN_STATES and self._probe_collides(qs):
            return False
        levels = self._margins(qs, np.zeros(n + 1, dtype=np.intp))
        if levels is None or not self._refine(a, b, bound, t, levels, low):
            return False
        self._certified(a, b)
        return True

    def _refine(
        self,
        a: np.ndarray,
        b: np.ndarray,
        bound: _MotionBound,
        t: np.ndarray,
        levels: np.ndarray,
        low: np.ndarray | None,
    ) -> bool:
        """Cut the uncovered intervals of the checked states at ``t`` (margin indices ``levels``,
        lower bounds of ``d`` ``low``), round after round, until all are covered (``True``) or a
        state collides with the finest margin (``False``)."""
        pads, mga = self._pads, self.law.mga
        while True:
            margin = pads[levels]
            dt = np.diff(t)
            if bound.fingers > 0.0 and low is not None:
                # The fingers stay on the plateau over an interval whose ends' lower bounds
                # of d keep d above mga all along it.
                moving = low[:-1] + low[1:] - bound.spread * dt <= 2.0 * mga
                gap = dt * (bound.arm + bound.fingers * moving)
            else:
                gap = dt * bound.arm
            open_ = np.flatnonzero(gap > (margin[:-1] + margin[1:]) * (1.0 - 1e-12))
            if open_.size == 0:
                return True
            # Cut each uncovered interval at the spacing its thinner end's margin covers.
            thinner = np.maximum(levels[open_], levels[open_ + 1])
            pieces = np.maximum(np.ceil(gap[open_] / (2.0 * pads[thinner]) - 1e-9), 2)
            pieces = pieces.astype(np.intp)
            if bound.tighten:
                bound.tighten = False
                if int(pieces.sum()) - pieces.size >= LOCAL_REACH_MIN_STATES:
                    assert bound.curvature is not None
                    bound.arm = self._local_reach(a, b, bound.curvature, bound.arm)
                    continue
            owner = np.repeat(np.arange(open_.size), pieces - 1)
            first = np.cumsum(pieces - 1) - (pieces - 1)
            rank = np.arange(owner.size) - first[owner] + 1
            new_t = t[open_][owner] + rank * (dt[open_] / pieces)[owner]
            new_qs, new_low = self._states(
                a, bound.delta, new_t, bound.ends, bound.spread, bound.plateau
            )
            new_levels = self._margins(new_qs, thinner[owner])
            if new_levels is None:
                return False
            order = np.argsort(np.concatenate([t, new_t]), kind="stable")
            t = np.concatenate([t, new_t])[order]
            levels = np.concatenate([levels, new_levels])[order]
            if low is not None and new_low is not None:
                low = np.concatenate([low, new_low])[order]

    def forget(self) -> None:
        """Forget the free states :meth:`is_valid` remembers and :attr:`certified`: their next
        checks are done again (to time cold checks, or after the scene changed in place)."""
        self._known_valid.clear()
        self.certified.clear()

    def _certified(self, a: np.ndarray, b: np.ndarray) -> None:
        if len(self.certified) >= CERTIFIED_MAX:
            self.certified.clear()
        self.certified.add(a.tobytes() + b.tobytes())

    def is_certified(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether :meth:`check_motion` accepted the motion ``a -> b`` or ``b -> a`` (the
        same bit-exact arm configurations) since :attr:`certified` last restarted.

        Args:
            a, b: Arm configurations [rad], shape ``(dof,)``.
        Returns:
            ``True`` when it was accepted.
        """
        a = np.ascontiguousarray(a, dtype=float)
        b = np.ascontiguousarray(b, dtype=float)
        keys = self.certified
        return a.tobytes() + b.tobytes() in keys or b.tobytes() + a.tobytes() in keys

    def _probe_collides(self, qs: np.ndarray) -> bool:
        """Whether one of every :data:`PROBE_STRIDE` columns of ``qs`` (a long first round)
        collides with the finest margin: it refuses the motion as :meth:`_margins` would (it
        collides with every wider margin too), for a few states instead of the whole round."""
        probe = np.asfortranarray(qs[:, PROBE_STRIDE // 2 :: PROBE_STRIDE])
        self.states_checked += probe.shape[1]
        return bool(np.any(self._batch_collides(-1, probe)))


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
        """OMPL's state check: :meth:`~openup_ompl.state_check.StateChecker.is_valid` of the arm.

        Returns:
            Whether it is collision-free, the hand set by the law.
        """
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
        """OMPL's motion check: :meth:`CoupledChecker.check_motion` of the arm states.

        Returns:
            Whether the motion ``s1 -> s2`` is collision-free with the coupled hand.
        """
        n = self._n
        return self.checker.check_motion(np.array(s1[0:n]), np.array(s2[0:n]))
