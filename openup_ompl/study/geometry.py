"""Geometry the study's families and policies share: shape distances, and the hand's
finger geometry swept along the final approach (:class:`HandSweep`)."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin

from openup_ompl._model import moved_by
from openup_ompl.grasp import closed_configuration
from openup_ompl.scene import Problem, Shape

__all__ = ["SUPPORT", "HandSweep", "shape_distance"]

#: The name of the surface objects stand on: resting on it is not a collision.
SUPPORT = "table"


def _transform(placement: pin.SE3) -> coal.Transform3s:
    return coal.Transform3s(placement.rotation, placement.translation)


def shape_distance(a: Shape, b: Shape) -> float:
    """Signed distance between two scene shapes (Coal).

    Args:
        a, b: Scene shapes at their poses (world frame).

    Returns:
        The distance [m]; negative: they overlap.
    """
    request, result = coal.DistanceRequest(), coal.DistanceResult()
    return float(
        coal.distance(
            a.geometry(), _transform(a.placement), b.geometry(), _transform(b.placement),
            request, result,
        )
    )  # fmt: skip


class HandSweep:
    """The fingers' collision geometry along the last part of a straight approach.

    The coupled planner opens the hand with Algorithm 3 as the palm nears the grasp;
    here the palm is placed on the grasp's approach line at ``d`` in ``[0, mga]`` (the
    stretch where the hand is widest and nearest the object: ``d * start distance``
    back from the grasp, at most ``max_back``), the fingers at the law's opening for
    ``u``, and each finger geometry is checked against the obstacles other than the
    support. The planner's path need not be straight; this is the prediction a policy
    can afford before planning.

    Args:
        problem: The problem as planned (its object where it is believed to be).
        samples: Values of ``d`` checked in ``[0, mga]``.
        max_back: Farthest the palm is placed behind the grasp [m].
    """

    def __init__(self, problem: Problem, samples: int = 8, max_back: float = 0.15) -> None:
        robot = problem.robot
        self.problem = problem
        self.model = robot.model
        self.data = robot.model.createData()
        self.fingers = [
            g
            for g, moved in zip(
                robot.collision_model.geometryObjects,
                moved_by(robot.model, robot.collision_model, robot.hand_joints),
                strict=True,
            )
            if moved
        ]
        grasp = problem.grasp
        approach = grasp.rotation @ np.asarray(robot.spec.approach, dtype=float)
        approach /= np.linalg.norm(approach)
        start = self._palm(problem.start, problem.hand_law.c)
        distance = float(np.linalg.norm(start.translation - grasp.translation))
        law = problem.hand_law
        self.steps = [
            (d, pin.SE3(grasp.rotation, grasp.translation - approach * min(d * distance, max_back)))
            for d in np.linspace(0.0, law.mga, samples)
        ]
        self.obstacles = [s for s in problem.obstacles if s.name != SUPPORT]

    def _palm(self, arm: np.ndarray, hand: np.ndarray) -> pin.SE3:
        q = self.problem.robot.full_q(arm, hand)
        return self.problem.robot.palm_placement(self.data, q)

    def _finger_placements(self, hand: np.ndarray) -> list[pin.SE3]:
        """Each finger geometry's placement in the palm frame at hand joints ``hand``."""
        palm = self._palm(self.problem.start, hand)
        return [palm.actInv(self.data.oMi[g.parentJoint] * g.placement) for g in self.fingers]

    def clearance(self, u: float) -> np.ndarray:
        """Per approach step, the smallest signed distance from a finger to an obstacle
        other than the support.

        Args:
            u: The hand law's ``u`` (unitless, in ``[0, 1]``).

        Returns:
            Distances [m], one per step, shape ``(samples,)`` (negative: they overlap;
            ``inf``: no obstacle).
        """
        law = self.problem.hand_law.with_options(u=float(u))
        out = np.full(len(self.steps), np.inf)
        request = coal.DistanceRequest()
        shapes = [(s.geometry(), _transform(s.placement)) for s in self.obstacles]
        for k, (d, palm) in enumerate(self.steps):
            for finger, local in zip(self.fingers, self._finger_placements(law(d)), strict=True):
                world = _transform(palm * local)
                for geometry, where in shapes:
                    result = coal.DistanceResult()
                    gap = coal.distance(finger.geometry, world, geometry, where, request, result)
                    out[k] = min(out[k], gap)
        return out

    def approach_clear(self) -> bool:
        """Whether the fingers at ``u = 0`` touch no obstacle anywhere on the approach.

        Returns:
            ``True`` if every step's clearance is positive.
        """
        return bool(np.all(self.clearance(0.0) > 0.0))

    def _baseline_hands(self, yielded: bool = False) -> list[tuple[pin.SE3, np.ndarray]]:
        """Palm placements and hand joints of the ``u = 0`` hand: along the approach (the
        law's opening), then at the grasp closing from ``c`` to the closed configuration
        with nothing in the way (farther than the object lets them go); ``yielded`` adds
        the hand at the grasp opened to its joint limits on ``w``'s side (a finger the
        squeezed object pushes back to its limit, as the LWA3-SDH's thumb is in physics)."""
        law = self.problem.hand_law.with_options(u=0.0)
        rows = [(palm, law(d)) for d, palm in self.steps]
        c = np.asarray(law.c, dtype=float)
        closed = closed_configuration(self.problem)
        target = c.copy()
        target[: closed.size] = np.where(np.isnan(closed), c[: closed.size], closed)
        grasp = self.steps[0][1]
        rows += [(grasp, c + s * (target - c)) for s in np.linspace(0.0, 1.0, 6)[1:]]
        if yielded:
            robot = self.problem.robot
            limits = self.model.lowerPositionLimit, self.model.upperPositionLimit
            n = robot.n_driven
            lower, upper = (x[robot.hand_idx[:n]] for x in limits)
            w = np.asarray(law.w, dtype=float)
            limit = np.where(w[:n] < c[:n], lower, np.where(w[:n] > c[:n], upper, c[:n]))
            # Joints pushed open to their limit, the others anywhere from c to closed.
            back = w[:n] < c[:n]
            for others in (c, target, limit):
                hand = c.copy()
                hand[:n] = np.where(back, limit, others[:n])
                rows.append((grasp, hand))
        return rows

    def reach(
        self, centre: np.ndarray, directions: list[np.ndarray], yielded: bool = False
    ) -> np.ndarray:
        """How far [m] the ``u = 0`` hand's fingers (:meth:`_baseline_hands`) reach from
        ``centre`` along each world unit vector of ``directions`` (signed: the largest
        projection, 0 if none is positive).

        Args:
            centre: The point reached from [m], world frame, shape ``(3,)``.
            directions: World unit vectors.
            yielded: Include the hand pushed open to its limits
                (:meth:`_baseline_hands`).

        Returns:
            The reach [m] along each direction, shape ``(len(directions),)``.
        """
        signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
        axes = np.array(directions, dtype=float)
        reach = np.zeros(len(axes))
        for palm, hand in self._baseline_hands(yielded):
            for finger, local in zip(self.fingers, self._finger_placements(hand), strict=True):
                shape = finger.geometry
                shape.computeLocalAABB()
                low, high = np.asarray(shape.aabb_local.min_), np.asarray(shape.aabb_local.max_)
                corners = (low + high) / 2 + signs * (high - low) / 2
                world = palm * local
                points = corners @ world.rotation.T + world.translation
                reach = np.maximum(reach, np.max((points - centre) @ axes.T, axis=0))
        return reach

    def largest_safe_u(self, margin: float = 0.005, tolerance: float = 0.02) -> float:
        """The largest ``u`` in ``[0, 1]`` whose swept fingers come no closer than
        ``margin`` [m] to an obstacle at any step, or no closer than ``u = 0``'s already
        do there (bisection to ``tolerance``; the opening grows with ``u``).

        Args:
            margin: Clearance [m] kept from every obstacle.
            tolerance: Bisection width on ``u`` (unitless).

        Returns:
            ``u`` in ``[0, 1]`` (1 when every ``u`` is safe).
        """
        floor = np.minimum(self.clearance(0.0), margin) - 1e-6

        def safe(u: float) -> bool:
            return bool(np.all(self.clearance(u) >= floor))

        if safe(1.0):
            return 1.0
        low, high = 0.0, 1.0
        while high - low > tolerance:
            middle = (low + high) / 2
            low, high = (middle, high) if safe(middle) else (low, middle)
        return low
