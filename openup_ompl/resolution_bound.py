"""The certified-resolution bound of one checker: how far any robot point may move along a
straight arm motion, the hand following the law, and so how densely a motion's states
must be checked (the bounds themselves are derived in :mod:`openup_ompl.motion_bound`).

A motion check places states no more than the resolution apart in this bound and checks
them against obstacles padded by half of it: every point then stays within the padding
of a checked position, which makes the check of the whole motion exact.
"""

from __future__ import annotations

import math

import numpy as np

from openup_ompl.hand_law import HandLaw
from openup_ompl.motion_bound import (
    arm_weights,
    body_bounds,
    distance_rates,
    hand_rate,
    local_rate_terms,
    local_reach,
)
from openup_ompl.robot import Robot

#: Default motion-check resolution [m]: the largest distance any point of the robot may
#: move between two consecutive checked states of a motion (bounded as in
#: :mod:`openup_ompl.motion_bound`). Obstacles and object are padded by half of it, which
#: makes the check of a whole motion exact for the unpadded scene.
DEFAULT_RESOLUTION = 0.006
#: The coarsest motion-check resolution accepted [m]: beyond it the checks, and the
#: default padding of half of it, stop describing the scene.
RESOLUTION_MAX = 0.1
#: The finest motion-check resolution accepted [m]: a tenth of a millimetre, 60 times
#: finer than the default (a far finer one makes a motion check allocate without bound).
RESOLUTION_MIN = 1e-4
#: The arm's share of a motion's bound is never tightened below this fraction of its
#: global bound: self-collision margins rely on it
#: (:func:`~openup_ompl.motion_bound.self_pair_factors`).
ARM_TIGHTEN_FLOOR = 0.5


class ResolutionBound:
    """The displacement bound of straight arm motions for one robot and hand law.

    Args:
        robot: The robot.
        law: The hand law its fingers follow.
        start_distance: The start palm's distance from the grasp [m] (Algorithm 1's
            denominator).

    Attributes:
        plateau_weights: Weights ``W`` [m per joint unit] with the hand still (motions on
            the law's plateau).
        distance_rates: How fast ``d`` may change per joint unit (its Lipschitz bound).
        hand_rate: The fingers' displacement [m] per unit of ``d`` (0 for a fixed hand).
        motion_weights: ``W`` with the fingers' motion under the law included.
        local_terms: The palm's speed terms of
            :func:`~openup_ompl.motion_bound.local_rate_terms` (``None`` for a fixed
            hand).
        bodies: The arm bodies' bounds (:func:`~openup_ompl.motion_bound.body_bounds`).
        arm_joint_ids: Pinocchio joint indices of the arm joints.
    """

    def __init__(self, robot: Robot, law: HandLaw, start_distance: float) -> None:
        model = robot.model
        self._mga = law.mga
        self._inv_start = 1.0 / start_distance
        self.plateau_weights = arm_weights(robot)
        self.distance_rates = distance_rates(robot, law, start_distance)
        # Fingers' displacement per unit of d (none for a fixed hand); with the rates of d
        # it gives the fingers' share of the bound.
        self.hand_rate = (
            0.0
            if law.fixed is not None
            else hand_rate(robot, [model.getJointId(n) for n in robot.hand_joints], law)
        )
        self.motion_weights = self.plateau_weights + self.hand_rate * self.distance_rates
        self.local_terms = None if law.fixed is not None else local_rate_terms(robot, law)
        self.arm_joint_ids = [model.getJointId(n) for n in robot.spec.arm_joints]
        self.bodies = body_bounds(robot)

    def on_plateau(self, da: float, db: float, spread: float) -> bool:
        """Whether ``d`` stays above ``mga`` all along a motion whose ends have ``d`` =
        ``da`` and ``db`` and along which ``d`` changes by at most ``spread`` per unit of
        ``t``: ``d >= (da + db - spread) / 2`` everywhere on it.

        Args:
            da, db: ``d`` at the motion's ends (unitless).
            spread: Bound on the change of ``d`` per unit of ``t`` (unitless).

        Returns:
            ``True`` if the hand is certainly on the law's plateau all along.
        """
        return 0.5 * (da + db - spread) > self._mga

    def local_spread(
        self, abs_delta: np.ndarray, spread: float, palm_a: list[float], palm_b: list[float]
    ) -> float:
        """How much ``d`` can change per unit of ``t`` along a motion with ``abs_delta =
        |b - a|`` whose palm is at ``palm_a`` and ``palm_b`` [m, world frame] at its ends:
        at most ``spread`` (the global bound), tightened by the palm's displacement between
        the ends plus half a bound of its acceleration
        (:func:`~openup_ompl.motion_bound.local_rate_terms`). Near the grasp a short
        motion moves the palm nearly straight, and the fingers' share shrinks with it.

        Args:
            abs_delta: ``|b - a|`` [rad], shape ``(dof,)``.
            spread: The global bound on the change of ``d`` per unit of ``t`` (unitless).
            palm_a, palm_b: The palm's positions [m, world frame] at ``a`` and ``b``.

        Returns:
            The tightened bound on the change of ``d`` per unit of ``t`` (unitless).
        """
        if self.local_terms is None:
            return spread
        second, rotation = self.local_terms
        turn = float(rotation @ abs_delta)
        taylor = math.dist(palm_a, palm_b)
        taylor += 0.5 * float(abs_delta @ second @ abs_delta)
        return min(spread, (taylor + turn) * self._inv_start)

    def tightened_arm(
        self, frames_a: np.ndarray, frames_b: np.ndarray, curvature: np.ndarray, arm: float
    ) -> float:
        """The arm's share of a motion's bound, tightened from ``arm`` (the global bound)
        by the arm joints' placements at its two ends (``(dof, 4, 4)`` homogeneous
        matrices) and the bodies' ``curvature``
        (:func:`~openup_ompl.motion_bound.local_reach`), never below
        :data:`ARM_TIGHTEN_FLOOR` times ``arm``.

        Args:
            frames_a, frames_b: Arm joints' placements at the motion's ends, world frame,
                shape ``(dof, 4, 4)``, in ``spec.arm_joints`` order.
            curvature: The bodies' curvature terms
                (:func:`~openup_ompl.motion_bound.body_curvature`).
            arm: The arm's global share of the bound [m per unit of ``t``].

        Returns:
            The tightened share [m per unit of ``t``].
        """
        assert self.bodies is not None
        local = local_reach(self.bodies, frames_a, frames_b, curvature)
        return min(arm, max(local, ARM_TIGHTEN_FLOOR * arm))

    def segment_count(self, delta: np.ndarray, resolution: float, weights: np.ndarray) -> int:
        """Number of steps a motion of joint displacement ``delta`` is cut into so that no
        robot point moves more than ``resolution`` [m] between checked states, in the
        bound of ``weights``.

        Args:
            delta: Joint displacement ``b - a`` [rad], shape ``(dof,)``.
            resolution: Largest move of a robot point per step [m].
            weights: Per-joint weights [m/rad], shape ``(dof,)``.

        Returns:
            The number of steps (at least 1).
        """
        return max(1, math.ceil(float(np.abs(delta) @ weights) / resolution))
