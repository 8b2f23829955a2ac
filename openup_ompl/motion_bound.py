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


def joint_reach(robot: Robot, joint_id: int) -> float:
    """Upper bound [m] on the distance from a joint's origin to any robot point it moves."""
    model = robot.model
    subtree = set(model.subtrees[joint_id])
    reach = 0.0
    for geometry in robot.collision_model.geometryObjects:
        if geometry.parentJoint not in subtree:
            continue
        shape = geometry.geometry
        shape.computeLocalAABB()
        extent = (
            float(np.linalg.norm(geometry.placement.translation))
            + float(np.linalg.norm(shape.aabb_center))
            + float(shape.aabb_radius)
        )
        reach = max(
            reach,
            _chain_length(model, joint_id, geometry.parentJoint)
            + _travel(model, geometry.parentJoint)
            + extent,
        )
    return reach


def joint_weight(robot: Robot, joint_id: int) -> float:
    """Displacement [m] of the farthest moved point per unit of this joint's motion."""
    return 1.0 if is_prismatic(robot.model.joints[joint_id]) else joint_reach(robot, joint_id)


def distance_rates(robot: Robot, law: HandLaw, start_distance: float) -> np.ndarray:
    """Per-arm-joint Lipschitz constants of Algorithm 1's ``d`` [1 per joint unit]:
    ``|d(q) - d(q')| <= sum_i |q_i - q'_i| * rate_i`` for any two arm configurations.

    Args:
        robot: The robot.
        law: The hand law (its distance kind and rotation weight).
        start_distance: Algorithm 1's denominator [m].
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
    the palm moves per radian of that joint."""
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


def local_rate_terms(
    robot: Robot, law: HandLaw
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """What :meth:`~openup_ompl.validity.CoupledChecker.check_motion` needs to bound how
    fast ``d`` changes along one motion more tightly than :func:`distance_rates` (``None``
    for an arm with a prismatic joint, where the global rates are used).

    Two bounds of the palm's speed along a straight motion ``q(t) = a + t (b - a)``,
    ``t`` in [0, 1], for revolute joints (the axis ``w_i`` of joint ``i`` through its
    origin ``o_i``; the palm at ``p``):

    - per joint: joint ``i`` moves the palm by at most ``|p - o_i|`` per radian, and
      along the motion ``|p - o_i|`` grows at most by what the joints between ``i`` and the
      palm move the palm relative to joint ``i``: ``sum_j chain[i, j] |b_j - a_j|``;
    - second order: ``d2p/dq_i dq_j = w_i x (w_j x (p - o_j))`` for ``i`` before ``j``
      in the chain, of norm at most ``j``'s :func:`palm_reach`, so
      ``|p''(t)| <= K = |b - a|^T second |b - a|``; with Taylor's remainder the palm's
      speed is at most ``|p(b) - p(a)| + 1.5 K`` all along.

    Returns:
        ``chain`` and ``second`` (arm joints x arm joints) [m per joint unit] and the
        rotation term of :func:`distance_rates` (before the division by the start
        distance).
    """
    model = robot.model
    arm_ids = [model.getJointId(name) for name in robot.spec.arm_joints]
    if any(is_prismatic(model.joints[j]) for j in arm_ids):
        return None
    reach = palm_reach(robot)
    n = len(arm_ids)
    chain = np.zeros((n, n))
    second = np.zeros((n, n))
    for i, joint in enumerate(arm_ids):
        below = set(model.subtrees[joint])
        for j, other in enumerate(arm_ids):
            if other in below and other != joint:
                chain[i, j] = reach[j]
            if reach[i] > 0 and reach[j] > 0:
                # The later joint of the two in the chain (both move the palm, so one
                # lies below the other).
                later = j if other in below else i
                second[i, j] = reach[later]
    return chain, second, _rotation_rates(robot, law)


def arm_weights(robot: Robot) -> np.ndarray:
    """Per-arm-joint weights [m per joint unit] of the bound with the hand still: enough
    wherever the law's hand does not move (a fixed hand, or ``d`` above ``mga``)."""
    model = robot.model
    return np.array([joint_weight(robot, model.getJointId(n)) for n in robot.spec.arm_joints])


def hand_rate(robot: Robot, hand_ids: list[int], law: HandLaw) -> float:
    """Bound [m per unit of ``d``] on how far any robot point moves through the fingers'
    own motion under the law.

    A point moves only with the hand joints on its own chain, so the bound is the largest
    sum of ``|slope_j| * W_j`` along one chain (one finger), not the sum over the whole
    hand: each finger of a multi-finger hand is a separate chain from the palm.
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
