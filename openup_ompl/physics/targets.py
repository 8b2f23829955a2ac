"""Where a rollout sends the robot besides the plan's rows: the hand's closed
configuration, the lift's arm rows, and the object's displaced start pose."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from openup_ompl.exceptions import ConfigError
from openup_ompl.grasp import closing_limits
from openup_ompl.physics.robot_table import robot_spec
from openup_ompl.physics.world import World

if TYPE_CHECKING:
    from openup_ompl.robot_file import RobotSpec

__all__ = ["closed_configuration", "closed_targets", "displaced_pose", "lift_rows", "robot_spec"]


def closed_configuration(
    c: np.ndarray,
    w: np.ndarray,
    world: World,
    spec: RobotSpec | None,
    hand_joints: tuple[str, ...] | list[str],
) -> tuple[np.ndarray, np.ndarray, str]:
    """The closed configuration and closing speed of every hand joint (``hand_joints``
    order) and where they came from: the robot file's ``[hand].closed`` and
    ``closing_speed`` (``"robot file"``, when ``spec``'s hand joints lead
    ``hand_joints``), else each joint's limit on ``c``'s side of ``w`` (``"c/w"``).

    Args:
        c, w: The hand law's close preshape and widest open configuration [rad or m],
            shape ``(hand dof,)``.
        world: The physics world.
        spec: The robot file's spec, or ``None``.
        hand_joints: The plan's hand joint names, in order.

    Returns:
        ``(closed [rad or m], speed [rad/s or m/s], source)``, the first two of shape
        ``(hand dof,)``; ``closed`` is within the joint limits.

    Raises:
        ConfigError: ``c`` or ``w`` without one value per hand joint.
    """
    hand = world.hand
    c = np.asarray(c, dtype=float)
    w = np.asarray(w, dtype=float)
    low, high = world.lower[hand], world.upper[hand]
    if c.shape != (hand.size,) or w.shape != (hand.size,):
        raise ConfigError("plan hand_law c/w", c.tolist(), f"{hand.size} hand joint values")
    closed = closing_limits(c, w, low, high)
    closed = np.where(np.isnan(closed), c, closed)  # a joint with c == w holds c
    speed = np.ones(hand.size)
    source = "c/w"
    names = list(hand_joints)
    if spec is not None and list(spec.hand_joints) == names[: len(spec.hand_joints)]:
        n = len(spec.hand_joints)
        if spec.closed is not None:
            closed[:n] = spec.closed
            source = "robot file"
        if spec.closing_speed is not None:
            speed[:n] = spec.closing_speed
    closed = np.clip(closed, low, high)
    return closed, speed, source


def closed_targets(data: dict[str, Any], world: World) -> tuple[np.ndarray, np.ndarray, str]:
    """:func:`closed_configuration` of a plan file's contents (its law's ``c`` and ``w``,
    the robot file found by its robot's name).

    Args:
        data: A plan file's contents.
        world: The physics world built from it.

    Returns:
        As :func:`closed_configuration`.

    Raises:
        ConfigError: The law's ``c`` or ``w`` is not one number per hand joint.
    """
    law = data.get("hand_law") or {}
    robot = data.get("robot") or {}
    c, w = law.get("c", []), law.get("w", [])
    try:
        c, w = np.asarray(c, dtype=float), np.asarray(w, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError("plan hand_law c/w", c, f"{world.hand.size} hand joint values") from None
    spec = robot_spec(str(robot.get("name")))
    return closed_configuration(c, w, world, spec, list(robot.get("hand_joints") or []))


def lift_rows(world: World, q: np.ndarray, height: float, step: float = 0.005) -> np.ndarray:
    """Arm and hand configurations (plan joint order) raising the palm by ``height`` [m]
    along world z, orientation held, one row per ``step`` [m] (hand unchanged).

    Damped least squares on MuJoCo's body Jacobian of the palm link (the same kinematics
    the simulation runs), each row refined from the previous one.

    Args:
        world: The physics world.
        q: The configuration the lift starts from (plan joint order) [rad or m].
        height: The palm's rise [m].
        step: The rise between rows [m].

    Returns:
        Configurations, shape ``(count + 1, len(q))`` with ``count = ceil(height / step)``;
        row 0 is ``q``.
    """
    import mujoco

    model = world.model
    scratch = mujoco.MjData(model)
    qpos_arm = world.qpos[world.arm]
    dof_arm = world.dof[world.arm]
    scratch.qpos[world.qpos] = q
    mujoco.mj_kinematics(model, scratch)
    start = scratch.xpos[world.palm_body].copy()
    target_quat = scratch.xquat[world.palm_body].copy()
    jacp = np.zeros((3, model.nv))
    jacr = np.zeros((3, model.nv))
    rot = np.zeros(3)
    current = np.zeros(4)
    low, high = world.lower[world.arm], world.upper[world.arm]
    count = max(1, math.ceil(height / step))
    rows = [np.array(q, dtype=float)]
    for k in range(1, count + 1):
        goal = start + np.array([0.0, 0.0, height * k / count])
        for _ in range(50):
            mujoco.mj_kinematics(model, scratch)
            mujoco.mj_comPos(model, scratch)
            current[:] = scratch.xquat[world.palm_body]
            mujoco.mju_subQuat(rot, target_quat, current)
            rot_world = scratch.xmat[world.palm_body].reshape(3, 3) @ rot
            error = np.concatenate([goal - scratch.xpos[world.palm_body], rot_world])
            if np.linalg.norm(error[:3]) < 1e-6 and np.linalg.norm(error[3:]) < 1e-5:
                break
            mujoco.mj_jacBody(model, scratch, jacp, jacr, world.palm_body)
            jac = np.vstack([jacp[:, dof_arm], jacr[:, dof_arm]])
            dq = jac.T @ np.linalg.solve(jac @ jac.T + 1e-6 * np.eye(6), error)
            scratch.qpos[qpos_arm] = np.clip(scratch.qpos[qpos_arm] + dq, low, high)
        row = rows[-1].copy()
        row[world.arm] = scratch.qpos[qpos_arm]
        rows.append(row)
    return np.array(rows)


def displaced_pose(pose: np.ndarray, dx: float, dy: float, yaw: float) -> np.ndarray:
    """``[x, y, z, qw, qx, qy, qz]`` (MuJoCo's free-joint order) of a scene pose moved by
    ``(dx, dy)`` in the world and turned by ``yaw`` about its own z axis.

    Args:
        pose: The scene pose ``[x, y, z, qx, qy, qz, qw]`` [m, unit quaternion], world
            frame.
        dx, dy: Position error [m] along the world x and y axes.
        yaw: Rotation error [rad] about the pose's own z axis.

    Returns:
        The displaced pose, shape ``(7,)``, in MuJoCo's order.
    """
    import mujoco

    from openup_ompl.physics.shapes import mujoco_quat

    turn = np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
    quat = np.zeros(4)
    mujoco.mju_mulQuat(quat, mujoco_quat(pose), turn)
    return np.concatenate([np.asarray(pose[:3], dtype=float) + [dx, dy, 0.0], quat])
