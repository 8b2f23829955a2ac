"""Collision world: the robot's Coal geometry plus the scene's obstacles and object.

Single queries go through Coal's naive broadphase manager (via Pinocchio), batches
through Pinocchio's parallel pool of dynamic AABB tree managers; both measured faster
than Pinocchio's pair loop on the Panda (see ``benchmarks/bench_validity.py``).
Each thread gets its own Pinocchio ``Data``,
``GeometryData`` and manager, so one world can serve several threads.
"""

from __future__ import annotations

import os
import threading
import warnings
import weakref
from dataclasses import dataclass
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from openup_ompl.motion_bound import self_pair_factors
from openup_ompl.scene import Problem, Shape

# Coal's naive manager (AABB test on every pair, then the narrow phase) measured fastest
# for single configurations of robots with a few dozen geometries
# (``benchmarks/bench_validity.py``). Batches go through the dynamic AABB tree pool, the
# only pool Pinocchio binds.
_Manager: Any = pin.BroadPhaseManager_NaiveCollisionManager
_ManagerPool: Any = pin.BroadPhaseManagerPool_DynamicAABBTreeCollisionManager
#: Smallest batch sent to the thread pool (see :meth:`CollisionWorld.batch_in_collision`).
PARALLEL_MIN_STATES = 32


def _without_warm_start(
    geometry_data: pin.GeometryData, distances: bool = True
) -> pin.GeometryData:
    """Turn off GJK's cached initial guess in every collision request, and in every
    distance request unless ``distances`` is false (data that never computes distances
    need not pay for the loop over its requests).

    With it on (Pinocchio's default), a query's answer can depend on the queries before
    it (a penetration reported free, a distance that changes when asked twice); turning it
    off costs a few per cent.
    """
    requests = list(geometry_data.collisionRequests)
    if distances:
        requests += geometry_data.distanceRequests
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        for request in requests:
            request.enable_cached_gjk_guess = False
            request.gjk_initial_guess = coal.GJKInitialGuess.DefaultGuess
    return geometry_data


def self_margins(problem: Problem, geometry_model: pin.GeometryModel, padding: float) -> np.ndarray:
    """Security margin [m] of each collision pair of a world padded by ``padding``: for a
    self-collision pair that arm joints move relative to each other, its factor of
    :func:`~openup_ompl.motion_bound.self_pair_factors` (at most 2) times the padding; 0
    for the rest.

    Environment shapes are grown by the padding, so a checked state keeps every robot
    point ``padding`` away from them; two robot points close in on each other by at most
    the sum of their moves, so self-collision pairs keep up to twice the padding, and a
    motion check covers self-collision between its states as it covers the environment.
    Pairs inside the hand (moved relative to each other only by the fingers) keep 0.

    Args:
        problem: The loaded scene (its robot's motion bounds).
        geometry_model: The world's geometry model and its collision pairs.
        padding: The world's padding [m].

    Returns:
        One margin [m] per collision pair of ``geometry_model``.
    """
    margins = np.zeros(len(geometry_model.collisionPairs))
    if padding <= 0.0:
        return margins
    robot = problem.robot
    # The robot's own pairs come first (build_collision_model copies its model), the same
    # for every world of the robot: computed once per robot.
    factors = _FACTORS.get(robot)
    if factors is None:
        factors = _FACTORS[robot] = self_pair_factors(robot, robot.collision_model)
    margins[: factors.size] = padding * factors
    return margins


#: Self-collision factors per robot (see :func:`self_margins`).
_FACTORS: weakref.WeakKeyDictionary[Any, np.ndarray] = weakref.WeakKeyDictionary()


def _with_margins(geometry_data: pin.GeometryData, margins: np.ndarray) -> pin.GeometryData:
    """Set each collision pair's security margin (see :func:`self_margins`)."""
    for request, margin in zip(geometry_data.collisionRequests, margins.tolist(), strict=True):
        request.security_margin = margin
    return geometry_data


@dataclass
class ThreadContext:
    """One thread's scratch data for collision checks.

    Attributes:
        data: Pinocchio data of the robot's model.
        geometry_data: Pinocchio/Coal geometry data of the world's geometry model.
        manager: Coal's broadphase manager over that geometry.
        q: A full configuration [rad or m], written before each check.
        hand: A buffer for the hand joint values [rad or m] the law computes.
        palm: The palm frame's position [m, world frame] in ``data.oMf``, a view that
            each ``pin.updateFramePlacement`` of the palm frame updates in place (read
            without a copy through Pinocchio's binding); ``None`` where the binding
            returns copies (see :func:`live_translation`).
    """

    data: pin.Data
    geometry_data: pin.GeometryData
    manager: Any
    q: np.ndarray
    hand: np.ndarray
    palm: np.ndarray | None = None


def live_translation(model: pin.Model, data: pin.Data, frame: int) -> np.ndarray | None:
    """A view of ``data.oMf[frame].translation`` [m] that Pinocchio's frame updates write
    through, or ``None`` if the binding gives a copy (checked by writing through it).

    The view shares ``data``'s memory: keep ``data`` alive as long as the view.

    Args:
        model: The robot's Pinocchio model.
        data: Its data (the view's owner).
        frame: A frame index of ``model``.
    """
    view = data.oMf[frame].translation
    view[0] = np.nan
    live = bool(np.isnan(data.oMf[frame].translation[0]))
    pin.forwardKinematics(model, data, pin.neutral(model))
    pin.updateFramePlacement(model, data, frame)
    return view if live else None


#: Name prefix of the scene's geometries (obstacles and object) in a collision model.
ENVIRONMENT_PREFIX = "env/"


def build_collision_model(
    problem: Problem, environment: list[Shape] | None = None, padding: float = 0.0
) -> pin.GeometryModel:
    """Robot geometry plus the environment shapes, with the pairs to test.

    Pairs: the robot's self-collision pairs (already pruned by its SRDF) and every robot
    geometry against every environment shape. Environment shapes never test each other.
    Each environment shape is grown by ``padding`` [m] plus the robot's own
    ``spec.padding`` on every side (the robot's is never halved). Self-collision pairs get
    their margins from the world (:func:`self_margins`), not from the geometry.

    Args:
        problem: The loaded scene (robot, obstacles, object).
        environment: The shapes to collide with (default: the obstacles and the object).
        padding: Growth of every environment shape [m].

    Returns:
        The Pinocchio geometry model with its collision pairs.
    """
    robot = problem.robot
    model = robot.collision_model.copy()
    n_robot = model.ngeoms
    shapes = problem.environment if environment is None else environment
    padding = padding + robot.spec.padding
    for shape in shapes:
        geometry = pin.GeometryObject(
            f"{ENVIRONMENT_PREFIX}{shape.name}", 0, 0, shape.placement, shape.geometry(padding)
        )
        model.addGeometryObject(geometry)
    for env in range(n_robot, model.ngeoms):
        for link in range(n_robot):
            model.addCollisionPair(pin.CollisionPair(link, env))
    return model


class CollisionWorld:
    """Answers "is this full configuration ``q`` in collision?" for one problem.

    Args:
        problem: Robot, obstacles and object.
        num_threads: Threads for batched queries (default: the machine's cores).
        environment: Shapes to collide with instead of ``problem.environment``.
        padding: Margin [m] grown around every environment shape.
    """

    def __init__(
        self,
        problem: Problem,
        num_threads: int | None = None,
        environment: list[Shape] | None = None,
        padding: float = 0.0,
    ) -> None:
        self.problem = problem
        self.padding = float(padding)
        self.model = problem.robot.model
        self.geometry_model = build_collision_model(problem, environment, self.padding)
        #: Each collision pair's security margin (:func:`self_margins`).
        self.margins = self_margins(problem, self.geometry_model, self.padding)
        names = [g.name for g in self.geometry_model.geometryObjects]
        self._environment_pairs = [
            k
            for k, pair in enumerate(self.geometry_model.collisionPairs)
            if names[pair.second].startswith(ENVIRONMENT_PREFIX)
        ]
        self.num_threads = max(1, num_threads or len(os.sched_getaffinity(0)))
        self._local = threading.local()
        self._pool: Any = None
        self._pool_lock = threading.Lock()

    def context(self) -> ThreadContext:
        """This thread's Pinocchio and Coal scratch data (created on first use).

        Returns:
            The calling thread's :class:`ThreadContext`.
        """
        try:
            return self._local.context  # type: ignore[no-any-return]
        except AttributeError:
            data = self.model.createData()
            geometry_data = _with_margins(
                _without_warm_start(self.geometry_model.createData(), distances=False),
                self.margins,
            )
            manager = _Manager(self.model, self.geometry_model, geometry_data)
            robot = self.problem.robot
            context = ThreadContext(
                data,
                geometry_data,
                manager,
                robot.neutral(),
                np.empty(robot.hand_idx.size),
                live_translation(self.model, data, robot.palm_frame_id),
            )
            self._local.context = context
            return context

    def in_collision(self, q: np.ndarray) -> bool:
        """Whether the full configuration ``q`` collides (self, obstacles or object).

        Args:
            q: Full configuration [rad or m], Pinocchio's ``q`` order.

        Returns:
            True if any tested pair collides (with its margin).
        """
        context = self.context()
        return bool(pin.computeCollisions(self.model, context.data, context.manager, q, True))

    def batch_in_collision(self, qs: np.ndarray, stop_at_first: bool = True) -> np.ndarray:
        """Collision flags for the columns of ``qs`` (shape ``(nq, N)``).

        With ``stop_at_first`` the batch stops at the first colliding configuration: the
        flags are then only meaningful as "some configuration collides". Batches of at
        least :data:`PARALLEL_MIN_STATES` go to Pinocchio's thread pool; smaller ones, and
        every batch of a one-thread world, are checked one by one in this thread: waking
        the pool's sleeping threads costs more than a small batch's single checks
        (``benchmarks/bench_speed.py``).

        Args:
            qs: Full configurations [rad or m] as columns, ``(nq, N)``.
            stop_at_first: Stop at the first colliding configuration.

        Returns:
            ``(N,)`` booleans, True where a configuration collides.
        """
        n = qs.shape[1]
        if self.num_threads == 1 or n < PARALLEL_MIN_STATES:
            flags = np.zeros(n, dtype=bool)
            context = self.context()
            model, data, manager = self.model, context.data, context.manager
            collides = pin.computeCollisions
            for i in range(n):
                if collides(model, data, manager, qs[:, i], True):
                    flags[i] = True
                    if stop_at_first:
                        break
            return flags
        with self._pool_lock:
            if self._pool is None:
                self._pool = _ManagerPool(self.model, self.geometry_model, self.num_threads)
                for geometry_data in self._pool.getGeometryDatas():
                    _with_margins(_without_warm_start(geometry_data, distances=False), self.margins)
            return np.asarray(
                pin.computeCollisionsInParallel(
                    self.num_threads, self._pool, qs, True, stop_at_first
                ),
                dtype=bool,
            )

    def colliding_pairs(self, q: np.ndarray) -> list[tuple[str, str]]:
        """Names of the geometry pairs in collision at ``q``, each with its margin (the
        padding, and between the robot's own links :func:`self_margins`), as
        :meth:`in_collision` checks them: for error messages.

        Args:
            q: Full configuration [rad or m].

        Returns:
            ``(geometry, geometry)`` name pairs, empty when ``q`` is free.
        """
        data = self.model.createData()
        geometry_data = _with_margins(
            _without_warm_start(self.geometry_model.createData(), distances=False), self.margins
        )
        pin.computeCollisions(self.model, data, self.geometry_model, geometry_data, q, False)
        names = [g.name for g in self.geometry_model.geometryObjects]
        return [
            (names[pair.first], names[pair.second])
            for pair, result in zip(
                self.geometry_model.collisionPairs, geometry_data.collisionResults, strict=True
            )
            if result.isCollision()
        ]

    def touches_environment(self, q: np.ndarray) -> bool:
        """Whether ``q`` collides with an obstacle or the object (self-collision aside).

        Args:
            q: Full configuration [rad or m].

        Returns:
            True if a robot geometry touches an environment shape.
        """
        context = self.context()
        geometry_data = context.geometry_data
        pin.computeCollisions(
            self.model, context.data, self.geometry_model, geometry_data, q, False
        )
        results = geometry_data.collisionResults
        return any(results[k].isCollision() for k in self._environment_pairs)
