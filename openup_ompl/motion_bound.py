"""How far any point of the robot can move along a straight arm motion.

For a straight joint-space motion ``a -> b``, no point of the robot moves farther than
``sum_i |b_i - a_i| * W_i`` [m]: a revolute joint turning by ``dq`` moves a point at most
``dq`` times its distance to the joint origin, a prismatic joint moves it by ``dq``, and
the moves add up along the chain (triangle inequality). ``W_i`` bounds that distance over
every configuration from the URDF's link offsets, prismatic travel and each collision
geometry's bounding sphere. The hand follows the law, so the finger joints move too: by
at most ``|slope|`` times the change of ``d``, itself bounded through the palm's own move,
and a point moves only with the finger joints of its own chain (:func:`hand_rate`).

Checking states no more than ``resolution`` apart in this bound, against obstacles padded
by ``resolution / 2``, proves the whole motion collision-free with the unpadded
obstacles (each point stays within ``resolution / 2`` of a checked position).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from openup_ompl._model import is_prismatic
from openup_ompl.hand_law import HandLaw
from openup_ompl.robot import Robot


def _travel(model: pin.Model, joint_id: int) -> float:
    """Largest offset [m] a prismatic joint can add (0 for revolute joints)."""
    joint = model.joints[joint_id]
    if not is_prismatic(joint):
        return 0.0
    q = joint.idx_q
    return float(max(abs(model.lowerPositionLimit[q]), abs(model.upperPositionLimit[q])))


def _chain_length(model: pin.Model, ancestor: int, joint_id: int) -> float:
    """Upper bound [m] on the distance from ``ancestor``'s origin to ``joint_id``'s origin."""
    length = 0.0
    while joint_id != ancestor:
        length += float(np.linalg.norm(model.jointPlacements[joint_id].translation))
        length += _travel(model, joint_id)
        joint_id = model.parents[joint_id]
    return length


def _geometry_reach(robot: Robot, joint_id: int, geometry: pin.GeometryObject) -> float:
    """Upper bound [m] on the distance from a joint's origin to any point of one geometry
    below it, over every configuration."""
    model = robot.model
    shape = geometry.geometry
    shape.computeLocalAABB()
    extent = (
        float(np.linalg.norm(geometry.placement.translation))
        + float(np.linalg.norm(shape.aabb_center))
        + float(shape.aabb_radius)
    )
    return (
        _chain_length(model, joint_id, geometry.parentJoint)
        + _travel(model, geometry.parentJoint)
        + extent
    )


def joint_reach(robot: Robot, joint_id: int) -> float:
    """Upper bound [m] on the distance from a joint's origin to any robot point it moves.

    Args:
        robot: The loaded robot.
        joint_id: A Pinocchio joint index.

    Returns:
        The bound [m].
    """
    subtree = set(robot.model.subtrees[joint_id])
    return max(
        (
            _geometry_reach(robot, joint_id, geometry)
            for geometry in robot.collision_model.geometryObjects
            if geometry.parentJoint in subtree
        ),
        default=0.0,
    )


def joint_weight(robot: Robot, joint_id: int) -> float:
    """Displacement [m] of the farthest moved point per unit of this joint's motion.

    Args:
        robot: The loaded robot.
        joint_id: A Pinocchio joint index.

    Returns:
        The weight [m per rad, or m per m for a prismatic joint].
    """
    return 1.0 if is_prismatic(robot.model.joints[joint_id]) else joint_reach(robot, joint_id)


def distance_rates(robot: Robot, law: HandLaw, start_distance: float) -> np.ndarray:
    """Per-arm-joint Lipschitz constants of Algorithm 1's ``d`` [1 per joint unit]:
    ``|d(q) - d(q')| <= sum_i |q_i - q'_i| * rate_i`` for any two arm configurations.

    Args:
        robot: The robot.
        law: The hand law (its distance kind and rotation weight).
        start_distance: Algorithm 1's denominator [m].

    Returns:
        ``(dof,)`` rates [1 per rad or per m], arm joint order.
    """
    return (palm_reach(robot) + _rotation_rates(robot, law)) / start_distance


def _rotation_rates(robot: Robot, law: HandLaw) -> np.ndarray:
    """With the weighted distance, each revolute arm joint also turns the palm by at most
    one radian per radian: ``rotation_weight`` per revolute joint, else 0."""
    model = robot.model
    rotation = law.rotation_weight if law.distance == "weighted" else 0.0
    arm_ids = [model.getJointId(name) for name in robot.spec.arm_joints]
    return np.array([0.0 if is_prismatic(model.joints[j]) else rotation for j in arm_ids])


def palm_reach(robot: Robot) -> np.ndarray:
    """Per arm joint, an upper bound [m] on the distance from its origin to the palm frame's
    origin over every configuration (0 for a joint that does not move the palm): how far
    the palm moves per radian of that joint.

    Args:
        robot: The loaded robot.

    Returns:
        ``(dof,)`` bounds [m], arm joint order.
    """
    model = robot.model
    arm_ids = [model.getJointId(name) for name in robot.spec.arm_joints]
    palm = model.frames[robot.palm_frame_id]
    palm_offset = float(np.linalg.norm(palm.placement.translation))
    return np.array(
        [
            _chain_length(model, j, palm.parentJoint) + palm_offset
            if palm.parentJoint in set(model.subtrees[j])
            else 0.0
            for j in arm_ids
        ]
    )


def local_rate_terms(robot: Robot, law: HandLaw) -> tuple[np.ndarray, np.ndarray] | None:
    """What :meth:`~openup_ompl.validity.CoupledChecker.check_motion` needs to bound how
    fast ``d`` changes along one motion more tightly than :func:`distance_rates` (``None``
    for an arm with a prismatic joint, where the global rates are used).

    Along a straight motion ``q(t) = a + t (b - a)``, ``t`` in [0, 1], of revolute joints
    (the axis ``w_i`` of joint ``i`` through its origin ``o_i``; the palm at ``p``),
    ``d2p/dq_i dq_j = w_i x (w_j x (p - o_j))`` for ``i`` before ``j`` in the chain, of
    norm at most ``j``'s :func:`palm_reach`, so ``|p''(t)| <= K = |b - a|^T second
    |b - a|``. Then ``p'(t)`` differs from the mean velocity ``p(b) - p(a)`` by at most
    ``K / 2`` (``|p'(t) - p'(s)| <= K |t - s|``, averaged over ``s`` in [0, 1]): the
    palm's speed is at most ``|p(b) - p(a)| + K / 2`` all along.

    Args:
        robot: The loaded robot.
        law: The hand law (its distance kind and rotation weight).

    Returns:
        ``second`` (arm joints x arm joints) [m per joint unit squared] and the rotation
        term of :func:`distance_rates` (before the division by the start distance).
    """
    model = robot.model
    arm_ids = [model.getJointId(name) for name in robot.spec.arm_joints]
    if any(is_prismatic(model.joints[j]) for j in arm_ids):
        return None
    second = _second_derivatives(model, arm_ids, palm_reach(robot)[:, None])[0]
    return second, _rotation_rates(robot, law)


def _second_derivatives(model: pin.Model, arm_ids: list[int], reach: np.ndarray) -> np.ndarray:
    """``(m, n, n)`` bounds of ``|d2x/dq_i dq_j|`` for points ``x`` of ``m`` groups, from
    ``reach`` ``(n, m)``: each arm joint's distance to the group's points (0 where it does
    not move them). The bound is the later joint's reach when both joints move the group
    (one then lies below the other in the chain), else 0."""
    n, m = reach.shape
    second = np.zeros((m, n, n))
    for i, joint in enumerate(arm_ids):
        below = set(model.subtrees[joint])
        for j, other in enumerate(arm_ids):
            later = j if other in below else i
            second[:, i, j] = np.where((reach[i] > 0) & (reach[j] > 0), reach[later], 0.0)
    return second


def arm_weights(robot: Robot) -> np.ndarray:
    """Per-arm-joint weights [m per joint unit] of the bound with the hand still: enough
    wherever the law's hand does not move (a fixed hand, or ``d`` above ``mga``).

    Args:
        robot: The loaded robot.

    Returns:
        ``(dof,)`` weights [m per rad or per m], arm joint order.
    """
    model = robot.model
    return np.array([joint_weight(robot, model.getJointId(n)) for n in robot.spec.arm_joints])


def hand_rate(robot: Robot, hand_ids: list[int], law: HandLaw) -> float:
    """Bound [m per unit of ``d``] on how far any robot point moves through the fingers'
    own motion under the law.

    A point moves only with the hand joints on its own chain, so the bound is the largest
    sum of ``|slope_j| * W_j`` along one chain (one finger), not the sum over the whole
    hand: each finger of a multi-finger hand is a separate chain from the palm.

    Args:
        robot: The loaded robot.
        hand_ids: Pinocchio joint indices of the hand joints.
        law: The hand law (its slopes in ``d``).

    Returns:
        The bound [m per unit of ``d``].
    """
    model = robot.model
    terms = dict(
        zip(
            hand_ids,
            np.abs(law.low_slope) * [joint_weight(robot, j) for j in hand_ids],
            strict=True,
        )
    )
    chains = []
    for joint_id in hand_ids:
        total = 0.0
        while joint_id != 0:
            total += float(terms.get(joint_id, 0.0))
            joint_id = model.parents[joint_id]
        chains.append(total)
    return max(chains, default=0.0)


@dataclass(frozen=True)
class BodyBounds:
    """What :func:`local_reach` needs to bound, for one straight motion, how far any robot
    point moves through the arm's motion: one sphere per arm joint that carries geometry,
    fixed in that joint's frame, enclosing every point that moves rigidly with it; a hand
    on the last joint is enclosed in every finger configuration (the fingers' own motion
    is bounded apart, through ``d``).

    Attributes:
        arm_index: For each body ``k``, the index (in ``spec.arm_joints``) of its joint.
        centers: Sphere centres in their joint's frame, ``(m, 3)`` [m].
        radii: Sphere radii, ``(m,)`` [m].
        second: ``(m, n * n)``: ``|d2x/dq_i dq_j| <= second[k, i * n + j]`` [m] for a point
            ``x`` of body ``k``: the distance from the later of joints ``i`` and ``j`` in
            the chain to any point of the body, over every configuration (0 unless both
            move it).
    """

    arm_index: np.ndarray
    centers: np.ndarray
    radii: np.ndarray
    second: np.ndarray


def body_bounds(robot: Robot) -> BodyBounds | None:
    """The spheres and constants of :func:`local_reach` for a robot (``None`` for an arm
    with a prismatic joint, which the second-order bound below does not cover).

    Each collision geometry belongs to its nearest arm-joint ancestor ``A`` (geometry that
    no arm joint moves is left out). Its points lie, from a point ``y`` fixed in ``A``'s
    frame, within ``|y - c| + e``: ``c`` the centre of its local box and ``e`` the box's
    radius for geometry on ``A`` itself; for geometry under further (finger) joints, ``c``
    the origin of the first of them and ``e`` the chain length to the geometry's joint
    plus the geometry's extent, whatever the fingers do.

    Args:
        robot: The loaded robot.

    Returns:
        The bodies' spheres and second-derivative constants, or ``None``.
    """
    model = robot.model
    arm_ids = [model.getJointId(name) for name in robot.spec.arm_joints]
    if any(is_prismatic(model.joints[j]) for j in arm_ids):
        return None
    arm_set = set(arm_ids)
    members: dict[int, list[tuple[np.ndarray, float]]] = {}
    for geometry in robot.collision_model.geometryObjects:
        path = []  # joints from the geometry's up to its nearest arm joint
        joint = geometry.parentJoint
        while joint != 0 and joint not in arm_set:
            path.append(joint)
            joint = model.parents[joint]
        if joint == 0:
            continue  # no arm joint moves it
        shape = geometry.geometry
        shape.computeLocalAABB()
        if not path:
            anchor = geometry.placement.act(np.asarray(shape.aabb_center))
            extent = float(shape.aabb_radius)
        else:
            first = path[-1]
            anchor = np.asarray(model.jointPlacements[first].translation)
            extent = _geometry_reach(robot, first, geometry) + _travel(model, first)
        members.setdefault(joint, []).append((np.asarray(anchor, dtype=float), extent))
    bodies = [j for j in arm_ids if j in members]
    if not bodies:
        return None
    n, m = len(arm_ids), len(bodies)
    centers = np.zeros((m, 3))
    radii = np.zeros(m)
    far = np.zeros(m)  # from the body joint's origin
    for k, joint in enumerate(bodies):
        anchors = np.array([a for a, _ in members[joint]])
        extents = np.array([e for _, e in members[joint]])
        center = 0.5 * (anchors.min(axis=0) + anchors.max(axis=0))
        centers[k] = center
        radii[k] = float(np.max(np.linalg.norm(anchors - center, axis=1) + extents))
        far[k] = float(np.max(np.linalg.norm(anchors, axis=1) + extents))
    # reach[j, k]: distance from arm joint j's origin to any point of body k (0 if j does
    # not move k).
    reach = np.zeros((n, m))
    for j, joint in enumerate(arm_ids):
        below = set(model.subtrees[joint])
        for k, body in enumerate(bodies):
            if body in below:
                reach[j, k] = _chain_length(model, joint, body) + far[k]
    second = _second_derivatives(model, arm_ids, reach)
    index = {joint: i for i, joint in enumerate(arm_ids)}
    return BodyBounds(
        arm_index=np.array([index[b] for b in bodies]),
        centers=centers,
        radii=radii,
        second=second.reshape(m, n * n),
    )


def body_curvature(bounds: BodyBounds, abs_delta: np.ndarray) -> np.ndarray:
    """Per body, the bound ``K`` of ``|x''(t)|`` for its points along a straight motion with
    ``abs_delta = |b - a|`` (see :func:`local_reach`), ``(m,)`` [m].

    Args:
        bounds: The robot's :func:`body_bounds`.
        abs_delta: ``|b - a|`` per arm joint [rad].

    Returns:
        ``(m,)`` bounds ``K`` [m], one per body.
    """
    return bounds.second @ np.outer(abs_delta, abs_delta).ravel()


def local_reach(
    bounds: BodyBounds, frames_a: np.ndarray, frames_b: np.ndarray, curvature: np.ndarray
) -> float:
    """Bound [m] on how far any robot point moves through the arm along the straight motion
    ``q(t) = a + t (b - a)``, ``t`` in [0, 1], per unit of ``t``, from the arm joints'
    placements at both ends (``frames_a``, ``frames_b``: ``(n, 4, 4)`` homogeneous, in
    ``spec.arm_joints`` order) and each body's :func:`body_curvature`. The fingers' own
    motion under the law is not included.

    A point ``x`` of body ``k`` (fixed in its joint's frame) has ``|x''(t)| <= K``, the
    quadratic form of ``second[k]`` in ``|b - a|`` (``d2x/dq_i dq_j = w_i x (w_j x (x -
    o_j))`` for ``i`` before ``j`` in the chain), so its velocity differs from its mean
    ``x(1) - x(0)`` by at most ``K / 2`` anywhere; ``|x(1) - x(0)|`` is at most the
    sphere centre's displacement plus the radius times ``2 sin(angle / 2)``, ``angle``
    the body's rotation between the ends. The
    largest over the bodies bounds every point. A short coordinated motion (a palm
    retreat) moves the robot far less than the global weights' sum over the joints says;
    for long motions the global bound is the smaller and the caller keeps it.

    Args:
        bounds: The robot's :func:`body_bounds`.
        frames_a: The arm joints' placements at ``a``, ``(n, 4, 4)``.
        frames_b: The same at ``b``.
        curvature: :func:`body_curvature` of the motion, ``(m,)`` [m].

    Returns:
        The bound [m per unit of ``t``].
    """
    index = bounds.arm_index
    frames_a, frames_b = frames_a[index], frames_b[index]
    turn = frames_b[:, :3, :3] - frames_a[:, :3, :3]
    moved = (turn @ bounds.centers[:, :, None])[:, :, 0] + (frames_b[:, :3, 3] - frames_a[:, :3, 3])
    # A point at r from the centre moves by |(R_b - R_a) r| <= 2 sin(angle / 2) |r| more,
    # and the Frobenius norm of R_b - R_a is sqrt(2) times 2 sin(angle / 2).
    spin = np.sqrt((turn * turn).sum(axis=(1, 2)) * 0.5)
    speed = np.sqrt((moved * moved).sum(axis=1)) + bounds.radii * spin + 0.5 * curvature
    return float(speed.max())


def self_pair_factors(robot: Robot, geometry_model: pin.GeometryModel) -> np.ndarray:
    """Per collision pair, how many times a world's padding its self-collision margin must
    be for a motion check to cover self-collision between its states (0 for pairs against
    the environment, and for pairs inside the hand, whose margins are not kept).

    Two points of the robot close in on each other at most by the sum of their moves, so
    twice the padding always suffices. Only the joints between the two geometries move
    them relative to each other: joint ``j`` at ``R_j`` per radian (its distance to the
    geometry it moves), against the global weight ``W_j`` the motion check's bound counts
    for it. With ``kappa = max_j R_j / W_j`` over the arm joints between them, their
    relative speed is at most ``kappa`` times the arm's global bound, plus the fingers'
    share where finger joints lie between them; the motion check never tightens the arm's
    share below half its global bound, so ``2 kappa`` (at least 1 with fingers between)
    suffices too. Neighbouring links of one wrist, a few centimetres apart in every
    configuration, then keep a fraction of the padding instead of twice it.

    Args:
        robot: The loaded robot.
        geometry_model: A world's geometry model and its collision pairs.

    Returns:
        ``(pairs,)`` factors in [0, 2], collision pair order.
    """
    model = robot.model
    arm = [model.getJointId(name) for name in robot.spec.arm_joints]
    arm_set = set(arm)
    weights = dict(zip(arm, arm_weights(robot).tolist(), strict=True))
    hand = {model.getJointId(name) for name in robot.spec.hand_joints}
    n_robot = robot.collision_model.ngeoms
    objects = geometry_model.geometryObjects
    chains = [set(model.supports[g.parentJoint]) - {0} for g in objects[:n_robot]]
    reach: dict[tuple[int, int], float] = {}  # (joint, geometry) -> _geometry_reach

    factors = np.zeros(len(geometry_model.collisionPairs))
    for k, pair in enumerate(geometry_model.collisionPairs):
        if pair.first >= n_robot or pair.second >= n_robot:
            continue
        between = chains[pair.first] ^ chains[pair.second]
        moving = between & arm_set
        if not moving:
            continue  # inside the hand
        kappa = 0.0
        for joint in moving:
            if is_prismatic(model.joints[joint]):
                kappa = max(kappa, 1.0)  # moves every point below it as much as its weight
                continue
            moved = pair.first if joint in chains[pair.first] else pair.second
            if (joint, moved) not in reach:
                reach[(joint, moved)] = _geometry_reach(robot, joint, objects[moved])
            kappa = max(kappa, reach[(joint, moved)] / weights[joint])
        floor = 1.0 if between & hand else 0.0
        factors[k] = min(2.0, max(2.0 * kappa, floor))
    return factors
