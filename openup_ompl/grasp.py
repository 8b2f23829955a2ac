"""Closing the hand at the goal (the paper's step 3), and judging the grasp it makes.

:class:`HandCloser` closes every finger from the plan's last hand configuration towards
the robot's closed configuration (``[hand].closed``) until it touches the object; a
finger that misses the object closes fully. Contact is located with Coal distance
queries through Pinocchio's geometry model, by conservative advancement: each step moves
the fingers by no more than the smallest finger-object distance allows under the
displacement bound of :mod:`~openup_ompl.motion_bound`, so no step passes through a
surface; a step that would still penetrate (steps have a floor, so that sliding contacts
converge) is bisected until the finger is within ``tolerance`` of the surface.

Which joints stop is GraspIt's ``autoGrasp`` rule: when a link touches, the hand joints
that move it (its own and every hand joint above it on its finger) stop, and the joints
below it keep closing (a proximal link's contact lets the distal joint wrap on). Each
moving joint advances by the same fraction of its joint range per unit of progress,
scaled by the robot file's ``[hand].closing_speed`` (a hand whose distal joints close
slower wraps its proximal links on first). Fingers also
stop on obstacles (the table); those contacts are reported apart and do not enter the
grasp test. Self-collision between fingers is not checked while closing.

The grasp test (force closure, enclosure) is :mod:`~openup_ompl.grasp_quality`, re-exported
here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from openup_ompl._toml import is_integer, is_number
from openup_ompl.collision import ENVIRONMENT_PREFIX, _without_warm_start
from openup_ompl.exceptions import ConfigError, InvalidProblem
from openup_ompl.grasp_quality import (
    DEFAULT_FRICTION,
    MAX_TORSION,
    check_torsion,
    contact_wrenches,
    enclosed,
    force_closure,
    positively_spans,
)
from openup_ompl.meshes import hull_points
from openup_ompl.motion_bound import joint_weight
from openup_ompl.scene import Problem, Shape

__all__ = [
    "DEFAULT_FRICTION",
    "MAX_TORSION",
    "ClosingOptions",
    "Contact",
    "GraspResult",
    "HandCloser",
    "check_torsion",
    "close_hand",
    "closed_configuration",
    "contact_wrenches",
    "enclosed",
    "force_closure",
    "object_axis",
    "positively_spans",
]


@dataclass(frozen=True)
class ClosingOptions:
    """How the fingers close.

    Attributes:
        tolerance: A finger stops once it is within this distance [m] of a surface
            (and never inside it).
        min_step: Smallest step, as a fraction of each joint's range: sliding contacts,
            for which conservative advancement alone would crawl, still converge.
        max_steps: Rounds of distance queries after which the closing stops (counted
            with the bisection's, checked between steps: the step under way, and its
            bisection, may add a few).
    """

    tolerance: float = 0.5e-3  # [m]
    min_step: float = 2e-3  # [fraction of the joint range]
    max_steps: int = 2000

    def __post_init__(self) -> None:
        if not (is_number(self.tolerance) and 1e-6 <= self.tolerance <= 0.01):
            raise ConfigError("ClosingOptions.tolerance", self.tolerance, "1e-6 to 0.01 m")
        if not (is_number(self.min_step) and 0 < self.min_step <= 0.1):
            raise ConfigError("ClosingOptions.min_step", self.min_step, "in (0, 0.1]")
        if not (is_integer(self.max_steps) and self.max_steps >= 1):
            raise ConfigError("ClosingOptions.max_steps", self.max_steps, "at least 1")


@dataclass(frozen=True)
class Contact:
    """A finger link touching a shape, at the end of closing.

    Attributes:
        link: The finger link (the geometry's parent frame).
        geometry: The collision geometry that touches.
        shape: The scene shape it touches.
        point: The contact point on the shape's surface, world frame [m].
        normal: Unit normal, world frame, from the finger into the shape: the direction
            the finger pushes.
        distance: Finger-to-surface distance [m] (0 to ``tolerance``; negative if the
            finger already penetrated before closing).
    """

    link: str
    geometry: str
    shape: str
    point: np.ndarray
    normal: np.ndarray
    distance: float


@dataclass(frozen=True)
class GraspResult:
    """The hand after closing.

    Attributes:
        q: Full configuration after closing.
        hand: Driven hand joint values after closing (``spec.hand_joints`` order).
        contacts: Finger contacts on the object.
        obstacle_contacts: Finger contacts on obstacles (they stop a finger too).
        closed_fully: Driven hand joints that reached their closed value.
        steps: Rounds of distance queries used.
    """

    q: np.ndarray
    hand: np.ndarray
    contacts: tuple[Contact, ...]
    obstacle_contacts: tuple[Contact, ...] = ()
    closed_fully: tuple[str, ...] = ()
    steps: int = 0

    @property
    def points(self) -> np.ndarray:
        """Object contact points ``(K, 3)``, world frame [m]."""
        return np.array([c.point for c in self.contacts]).reshape(-1, 3)

    @property
    def normals(self) -> np.ndarray:
        """Object contact normals ``(K, 3)``, into the object."""
        return np.array([c.normal for c in self.contacts]).reshape(-1, 3)

    @property
    def fingers(self) -> set[str]:
        """The links touching the object."""
        return {c.link for c in self.contacts}


def closed_configuration(problem: Problem) -> np.ndarray:
    """The driven hand configuration the fingers close towards.

    The robot file's ``[hand].closed``, or else for each joint the limit on ``c``'s side
    of ``w`` (the Panda's fingers close to 0, the Allegro's flex to their upper limits);
    a joint with ``c == w`` keeps its value.

    Args:
        problem: The loaded scene (its robot's hand and law).

    Returns:
        The driven hand joints' targets [rad or m].
    """
    robot = problem.robot
    n = robot.n_driven
    if n == 0:
        raise InvalidProblem(f"robot {robot.name!r} has no hand joints to close")
    limits = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    lower, upper = (x[robot.hand_idx[:n]] for x in limits)
    if robot.spec.closed is not None:
        return np.clip(robot.spec.closed, lower, upper)
    return closing_limits(problem.hand_law.c[:n], problem.hand_law.w[:n], lower, upper)


def closing_limits(
    c: np.ndarray, w: np.ndarray, lower: np.ndarray, upper: np.ndarray
) -> np.ndarray:
    """Each hand joint's limit on ``c``'s side of ``w`` (where it closes to when the robot
    file gives no ``[hand].closed``).

    Args:
        c, w: The hand law's close preshape and widest open configuration [rad or m],
            shape ``(hand dof,)``.
        lower, upper: The hand joints' limits [rad or m], shape ``(hand dof,)``.

    Returns:
        The limits [rad or m], shape ``(hand dof,)``; NaN for a joint with ``c == w``,
        which does not close.
    """
    return np.where(c < w, lower, np.where(c > w, upper, np.nan))


@dataclass
class _Finger:
    """A hand geometry and the driven joints that move it."""

    geometry: int
    link: str
    movers: np.ndarray  # driven hand joint indices
    rates: np.ndarray  # [m per unit of closing progress], one per mover
    pairs: list[int] = field(default_factory=list)


class HandCloser:
    """Closes the hand of one problem onto its object (see the module docstring).

    Args:
        problem: Robot, object and obstacles (the object where it really is).
        options: Closing settings.

    Raises:
        InvalidProblem: The scene has no object, or the robot no hand joints.
    """

    def __init__(self, problem: Problem, options: ClosingOptions | None = None) -> None:
        if problem.object is None:
            raise InvalidProblem("the scene has no [object] to close the hand on")
        self.problem = problem
        self.options = options or ClosingOptions()
        robot = problem.robot
        self.closed = closed_configuration(problem)
        n = robot.n_driven
        model = robot.model
        limits = model.upperPositionLimit - model.lowerPositionLimit
        self._speed = limits[robot.hand_idx[:n]]
        if robot.spec.closing_speed is not None:
            self._speed = self._speed * robot.spec.closing_speed
        driven_of = {model.getJointId(name): i for i, name in enumerate(robot.spec.hand_joints)}
        multiplier = {model.getJointId(name): 1.0 for name in robot.spec.hand_joints}
        for mimic in robot.mimic:
            joint = model.getJointId(mimic.joint)
            driven_of[joint] = robot.spec.hand_joints.index(mimic.leader)
            multiplier[joint] = abs(mimic.multiplier)

        self.geometry_model = robot.collision_model.copy()
        n_robot = self.geometry_model.ngeoms
        shapes = [problem.object, *problem.obstacles]
        self._shapes: list[Shape] = shapes
        for shape in shapes:
            self.geometry_model.addGeometryObject(
                pin.GeometryObject(
                    f"{ENVIRONMENT_PREFIX}{shape.name}", 0, 0, shape.placement, shape.geometry()
                )
            )
        self._fingers: list[_Finger] = []
        for index in range(n_robot):
            geometry = self.geometry_model.geometryObjects[index]
            movers, rates = [], []
            joint = geometry.parentJoint
            while joint != 0:
                if joint in driven_of:
                    movers.append(driven_of[joint])
                    rates.append(multiplier[joint] * joint_weight(robot, joint))
                joint = model.parents[joint]
            if not movers:
                continue
            finger = _Finger(
                index, model.frames[geometry.parentFrame].name, np.array(movers), np.array(rates)
            )
            for s in range(len(shapes)):
                finger.pairs.append(len(self.geometry_model.collisionPairs))
                self.geometry_model.addCollisionPair(pin.CollisionPair(index, n_robot + s))
            self._fingers.append(finger)
        self._data = model.createData()
        self._geometry_data = _without_warm_start(self.geometry_model.createData())
        self._rounds = 0  # distance-query rounds of the current closing

    def _distances(self, q: np.ndarray, fingers: list[_Finger]) -> np.ndarray:
        """Signed distance [m] of each finger to each shape, ``(len(fingers), shapes)``."""
        self._rounds += 1
        robot = self.problem.robot
        pin.updateGeometryPlacements(
            robot.model, self._data, self.geometry_model, self._geometry_data, q
        )
        out = np.empty((len(fingers), len(self._shapes)))
        for i, finger in enumerate(fingers):
            for s, pair in enumerate(finger.pairs):
                result = pin.computeDistance(self.geometry_model, self._geometry_data, pair)
                out[i, s] = result.min_distance
        return out

    def _contact(self, finger: _Finger, shape: int) -> Contact:
        result = self._geometry_data.distanceResults[finger.pairs[shape]]
        normal = np.array(result.normal, dtype=float)
        normal /= max(float(np.linalg.norm(normal)), 1e-12)
        return Contact(
            link=finger.link,
            geometry=self.geometry_model.geometryObjects[finger.geometry].name,
            shape=self._shapes[shape].name,
            point=np.array(result.getNearestPoint2(), dtype=float),
            normal=normal,
            distance=float(result.min_distance),
        )

    def close(self, q: np.ndarray) -> GraspResult:
        """Close the fingers from the full configuration ``q`` (arm and hand fixed there).

        Args:
            q: The full configuration (arm and hand) [rad or m], Pinocchio's ``q`` order.

        Returns:
            The hand after closing: configuration, contacts on the object and on
            obstacles, and the joints that closed fully.
        """
        robot = self.problem.robot
        n = robot.n_driven
        tolerance = self.options.tolerance
        q = np.array(q, dtype=float)
        if q.shape != (robot.model.nq,):
            raise ConfigError("close: q", q.shape, f"a full configuration of {robot.model.nq}")
        if not np.all(np.isfinite(q)):
            raise ConfigError("close: q", q.tolist(), "finite joint values")
        hand = q[robot.hand_idx[:n]].copy()
        target = np.where(np.isnan(self.closed), hand, self.closed)
        direction = np.sign(target - hand) * self._speed  # per unit of progress
        active = direction != 0
        touching: dict[tuple[int, int], Contact] = {}
        moving = [f for f in self._fingers if active[f.movers].any()]

        def at(values: np.ndarray) -> np.ndarray:
            q[robot.hand_idx] = robot.expand_hand(values)
            return q

        self._rounds = 0
        # Distances at the current hand, one row per moving finger; Coal's results of the
        # last query are those of this hand, so contacts are read from them.
        distances = self._distances(at(hand), moving)
        while moving and self._rounds < self.options.max_steps:
            hit = distances <= tolerance
            if hit.any():
                for i, s in zip(*np.nonzero(hit), strict=True):
                    touching[(moving[i].geometry, int(s))] = self._contact(moving[i], int(s))
                    active[moving[i].movers] = False
            else:
                remaining = np.abs(target - hand) / self._speed
                room = float(remaining[active].min())
                rates = np.array(
                    [np.sum(f.rates * active[f.movers] * self._speed[f.movers]) for f in moving]
                )
                clearance = distances.min(axis=1)
                step = max(
                    float(np.min(clearance / np.maximum(rates, 1e-12))), self.options.min_step
                )
                step = min(step, room)
                proposal = self._advance(hand, target, direction, active, step)
                distances = self._distances(at(proposal), moving)
                if (distances <= 0).any():
                    proposal, distances = self._bisect(
                        hand, target, direction, active, step, moving, at
                    )
                hand = proposal
                active &= ~np.isclose(hand, target, rtol=0, atol=1e-12)
            keep = [i for i, f in enumerate(moving) if active[f.movers].any()]
            moving = [moving[i] for i in keep]
            distances = distances[keep]
        at(hand)
        return GraspResult(
            q=q.copy(),
            hand=hand.copy(),
            contacts=tuple(c for (_, s), c in touching.items() if s == 0),
            obstacle_contacts=tuple(c for (_, s), c in touching.items() if s > 0),
            closed_fully=tuple(
                name
                for name, value, goal, moves in zip(
                    robot.spec.hand_joints, hand, target, direction != 0, strict=True
                )
                if moves and abs(value - goal) <= 1e-9
            ),
            steps=self._rounds,
        )

    @staticmethod
    def _advance(
        hand: np.ndarray, target: np.ndarray, direction: np.ndarray, active: np.ndarray, step: float
    ) -> np.ndarray:
        moved = hand + direction * active * step
        return np.where(direction > 0, np.minimum(moved, target), np.maximum(moved, target))

    def _bisect(
        self,
        hand: np.ndarray,
        target: np.ndarray,
        direction: np.ndarray,
        active: np.ndarray,
        step: float,
        moving: list[_Finger],
        at: Callable[[np.ndarray], np.ndarray],
    ) -> tuple[np.ndarray, np.ndarray]:
        """The step in ``(0, step)`` after which the nearest finger is within
        ``tolerance`` of a surface and none is inside one: the hand there and its
        distances, Coal's last query being the one at that hand."""
        low, high = 0.0, step
        best, best_distances, last_is_best = hand, None, False
        for _ in range(60):
            middle = 0.5 * (low + high)
            proposal = self._advance(hand, target, direction, active, middle)
            distances = self._distances(at(proposal), moving)
            if (distances <= 0).any():
                high = middle
                last_is_best = False
            else:
                low, best, best_distances, last_is_best = middle, proposal, distances, True
                if (distances <= self.options.tolerance).any():
                    break
        if not last_is_best or best_distances is None:
            best_distances = self._distances(at(best), moving)
        return best, best_distances


def close_hand(
    problem: Problem, q: np.ndarray, options: ClosingOptions | None = None
) -> GraspResult:
    """Close the hand of ``problem``'s robot at the full configuration ``q`` onto its
    object (see :class:`HandCloser`).

    Args:
        problem: The loaded scene (robot, object, obstacles).
        q: The full configuration [rad or m] (a plan's last row).
        options: Closing tolerance and steps (default :class:`ClosingOptions`).

    Returns:
        The hand after closing (:class:`GraspResult`): configuration, contacts, the
        joints that closed fully.
    """
    return HandCloser(problem, options).close(q)


def object_axis(shape: Shape) -> np.ndarray | None:
    """The object's long axis in the world frame: a cylinder's z, a box's longest side,
    a mesh's longest bounding-box side (in its file's frame); ``None`` for a sphere.

    Args:
        shape: The object.

    Returns:
        A unit vector ``(3,)`` in the world frame, or ``None``.
    """
    rotation = shape.placement.rotation
    if shape.shape == "cylinder":
        return np.array(rotation[:, 2])
    if shape.shape == "box":
        assert shape.size is not None
        return np.array(rotation[:, int(np.argmax(shape.size))])
    if shape.shape == "mesh":
        assert shape.file is not None and shape.scale is not None
        points = hull_points(shape.file, shape.scale)
        return np.array(rotation[:, int(np.argmax(np.ptp(points, axis=0)))])
    return None
