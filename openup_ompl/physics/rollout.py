"""Execute a plan in physics: reach, close, lift, hold; judge the grasp.

Phases (each a stretch of position-actuator targets, :mod:`~openup_ompl.physics.world`):

1. **settle**: the object rests where it really is (the plan's pose plus the offset).
2. **reach**: the plan's rows, timed under the URDF velocity limits
   (:func:`~openup_ompl.physics.trajectory.time_path`), the hand following the law as
   planned. The object is free: a finger that brushes it pushes it.
3. **close**: the hand joints' targets move towards the robot's closed configuration
   (its ``[hand].closed`` and ``closing_speed`` when the plan's robot file is found, else
   the limit on ``c``'s side of ``w``) and stay there; each joint stops where the object
   stops it and presses with its force limit (the squeeze).
4. **lift**: the palm goes straight up by ``lift_height`` (world z) with its orientation
   held: differential IK on MuJoCo's own Jacobian, from the plan's last row.
5. **hold**: ``hold`` seconds at the top.

Success (DexGraspBench's criterion): no robot link touched an obstacle, the object rose
with the palm (at least ``lifted_fraction`` of the lift), and at the end of the hold it
sits within ``success_distance`` and ``success_angle`` of where it sat in the palm frame
at the end of closing.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from openup_ompl._toml import is_number
from openup_ompl.exceptions import ConfigError, OpenUpError, SimulationDiverged
from openup_ompl.executor import check_generator_seed
from openup_ompl.grasp import closing_limits
from openup_ompl.physics.options import PHASE_MAX, PhysicsOptions
from openup_ompl.physics.record import ExecutionRecord
from openup_ompl.physics.trajectory import time_path
from openup_ompl.physics.world import NEIGHBOUR, OBJECT, OBSTACLE, ROBOT, World, build_world
from openup_ompl.plan import Plan, PlanFile

__all__ = ["Rollout", "check_offset", "closed_targets", "execute_plan", "lift_rows"]


#: The largest object displacement [m] along x or y a rollout takes: beyond the reach of
#: every shipped arm (MuJoCo resets a state with a huge position, and a run at
#: ``dx = 1e10`` read "held" before this bound).
OFFSET_MAX = 1.0
#: An object whose highest rise over the lift and hold exceeds this [m] and that no link
#: touches at the end was ``dropped`` (it rose, then left the hand), else ``no contact``.
DROPPED_RISE = 0.01


#: MuJoCo's warnings (``mjtWarning`` names) that it reset an unstable state, and what
#: each says.
UNSTABLE = (
    ("mjWARN_BADQPOS", "huge or non-finite position"),
    ("mjWARN_BADQVEL", "huge or non-finite velocity"),
    ("mjWARN_BADQACC", "bad acceleration"),
)


def check_offset(offset: Sequence[float]) -> tuple[float, float, float]:
    """``(dx, dy, yaw)`` as floats.

    Raises:
        ConfigError: Not three finite numbers (metres, metres, radians), ``dx`` or
            ``dy`` beyond :data:`OFFSET_MAX`, or ``yaw`` outside ``[-pi, pi]``.
    """
    try:
        if isinstance(offset, (str, bytes)) or not all(is_number(x) for x in offset):
            raise TypeError  # a string or a bool is not a displacement
        values = tuple(float(x) for x in offset)
    except (TypeError, ValueError):
        raise ConfigError("object offset", offset, "three numbers DX DY YAW [m, m, rad]") from None
    if len(values) != 3:
        raise ConfigError("object offset", list(offset), "three numbers DX DY YAW [m, m, rad]")
    for name, value in zip(("dx", "dy", "yaw"), values, strict=True):
        if not math.isfinite(value):
            raise ConfigError(f"object offset {name}", value, "a finite number")
        if name != "yaw" and abs(value) > OFFSET_MAX:
            raise ConfigError(
                f"object offset {name}", value, f"a displacement within +-{OFFSET_MAX:g} m"
            )
        if name == "yaw" and abs(value) > math.pi:  # as the robustness sweep's yaws
            raise ConfigError(f"object offset {name}", value, "an angle in [-pi, pi] rad")
    return values  # type: ignore[return-value]


def closed_targets(data: dict[str, Any], world: World) -> tuple[np.ndarray, np.ndarray, str]:
    """The closed configuration and closing speed of every hand joint (plan order of
    ``hand_joints``), and where they came from (``"robot file"`` or ``"c/w"``)."""
    from openup_ompl.robot import RobotSpec, find_robot_file

    hand = world.hand
    law = data.get("hand_law") or {}
    c = np.asarray(law.get("c", []), dtype=float)
    w = np.asarray(law.get("w", []), dtype=float)
    low, high = world.lower[hand], world.upper[hand]
    if c.shape != (hand.size,) or w.shape != (hand.size,):
        raise ConfigError("plan hand_law c/w", law.get("c"), f"{hand.size} hand joint values")
    closed = closing_limits(c, w, low, high)
    closed = np.where(np.isnan(closed), c, closed)  # a joint with c == w holds c
    speed = np.ones(hand.size)
    source = "c/w"
    robot = data.get("robot") or {}
    try:
        spec = RobotSpec.from_file(find_robot_file(str(robot.get("name"))))
    except OpenUpError:  # a robot this package does not know: c/w it is
        spec = None
    names = list(robot.get("hand_joints") or [])
    if spec is not None and list(spec.hand_joints) == names[: len(spec.hand_joints)]:
        n = len(spec.hand_joints)
        if spec.closed is not None:
            closed[:n] = spec.closed
            source = "robot file"
        if spec.closing_speed is not None:
            speed[:n] = spec.closing_speed
    closed = np.clip(closed, low, high)
    return closed, speed, source


def lift_rows(world: World, q: np.ndarray, height: float, step: float = 0.005) -> np.ndarray:
    """Arm and hand configurations (plan joint order) raising the palm by ``height`` [m]
    along world z, orientation held, one row per ``step`` [m] (hand unchanged).

    Damped least squares on MuJoCo's body Jacobian of the palm link (the same kinematics
    the simulation runs), each row refined from the previous one.
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


def _displaced_pose(pose: np.ndarray, dx: float, dy: float, yaw: float) -> np.ndarray:
    """``[x, y, z, qw, qx, qy, qz]`` (MuJoCo's free-joint order) of a scene pose moved by
    ``(dx, dy)`` in the world and turned by ``yaw`` about its own z axis."""
    import mujoco

    from openup_ompl.physics.shapes import mujoco_quat

    turn = np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
    quat = np.zeros(4)
    mujoco.mju_mulQuat(quat, mujoco_quat(pose), turn)
    return np.concatenate([np.asarray(pose[:3], dtype=float) + [dx, dy, 0.0], quat])


def _plain(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` with NumPy values as plain JSON types (a plan's ``to_dict`` may hold them)."""

    def convert(value: Any) -> Any:
        return value.tolist() if hasattr(value, "tolist") else str(value)

    result: dict[str, Any] = json.loads(json.dumps(data, default=convert))
    return result


def _pose_change(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Translation [m] and rotation angle [rad] between two ``(4, 4)`` transforms."""
    delta = np.linalg.inv(a) @ b
    cos = (np.trace(delta[:3, :3]) - 1) / 2
    return float(np.linalg.norm(delta[:3, 3])), float(math.acos(min(1.0, max(-1.0, cos))))


def _body_transform(sim: Any, body: int) -> np.ndarray:
    """The ``(4, 4)`` world transform of a body."""
    t = np.eye(4)
    t[:3, :3] = sim.xmat[body].reshape(3, 3)
    t[:3, 3] = sim.xpos[body]
    return t


def _disturbance(
    name: str,
    start: np.ndarray,
    end: np.ndarray,
    options: PhysicsOptions,
    touched: dict[str, Any] | None,
) -> dict[str, Any]:
    """How a neighbour moved between two world transforms: its displacement, the turn of
    its up axis (its own z) and the thresholds' verdicts."""
    moved = float(np.linalg.norm(end[:3, 3] - start[:3, 3]))
    cos = float(np.dot(start[:3, 2], end[:3, 2]))
    tilt = math.acos(min(1.0, max(-1.0, cos)))
    return {
        "name": name,
        "moved_mm": moved * 1e3,
        "tilt_deg": math.degrees(tilt),
        "moved": moved > options.neighbour_moved_distance,
        "tipped": tilt > options.neighbour_tipped_angle,
        "touched": touched,
    }


class Rollout:
    """One plan in one physics world; :meth:`run` executes it against an offset object.

    Building the world (a few milliseconds) and the lift's IK happen once, so a sweep
    runs every offset of a plan through one :class:`Rollout`.

    Args:
        plan: The plan (:meth:`~openup_ompl.GraspPlanningSetup.solve`'s), as read
            (:meth:`~openup_ompl.plan.PlanFile.read`), or a plan file's contents (checked
            here as ``show`` checks them).
        options: Physics settings.

    Raises:
        ConfigError: A plan file's contents that fail their check
            (:meth:`~openup_ompl.plan.PlanFile.from_dict`), a plan without an object, or a
            plan MuJoCo cannot build.
    """

    def __init__(
        self, plan: Plan | PlanFile | dict[str, Any], options: PhysicsOptions | None = None
    ) -> None:
        import mujoco

        if isinstance(plan, Plan):
            plan = PlanFile.from_plan(plan)
        elif not isinstance(plan, PlanFile):
            plan = PlanFile.from_dict(plan, where="plan ")
        if options is not None and not isinstance(options, PhysicsOptions):
            raise ConfigError("options", options, "PhysicsOptions or None")
        self.plan = plan
        self.options = options or PhysicsOptions()
        self.data = data = plan.contents
        self.world = build_world(data, self.options)
        self.path = plan.path
        self.timed = time_path(
            self.path, self.world.velocity_limit, self.options.speed, self.options.acceleration
        )
        if self.timed.duration > PHASE_MAX:
            raise ConfigError(
                "PhysicsOptions.speed and acceleration",
                (self.options.speed, self.options.acceleration),
                f"a reach of at most {PHASE_MAX:g} s (this plan's takes "
                f"{self.timed.duration:.3g} s)",
            )
        self.closed, self.closing_speed, self.closed_source = closed_targets(data, self.world)
        # Speed of each hand joint's target while the hand closes [rad/s or m/s].
        world = self.world
        self.close_rates = self.closing_speed * np.where(
            world.prismatic[world.hand], self.options.finger_close_speed, self.options.close_speed
        )
        close_time = self._close_time(self.path[-1][self.world.hand])
        if close_time > PHASE_MAX:
            raise ConfigError(
                "PhysicsOptions.close_speed and finger_close_speed",
                (self.options.close_speed, self.options.finger_close_speed),
                f"a closing of at most {PHASE_MAX:g} s (this plan's takes {close_time:.3g} s)",
            )
        self.lift = lift_rows(self.world, self.path[-1], self.options.lift_height)
        self.sim = mujoco.MjData(self.world.model)
        model = self.world.model
        # kv / kp of each joint's actuator [s]: the velocity feed-forward's lead.
        gains = model.actuator_gainprm[self.world.actuator, 0]
        self.lead = -model.actuator_biasprm[self.world.actuator, 2] / gains
        self.goal = plan.grasp_pose[:3]
        self.start_distance = float(data["hand_law"].get("start_palm_distance") or 0.0)

    def _close_time(self, start: np.ndarray) -> float:
        """Time [s] the hand's targets take from ``start`` to the closed configuration."""
        if not self.world.hand.size:
            return 0.0
        return float(np.max(np.abs(self.closed - start) / self.close_rates))

    def run(
        self, offset: Sequence[float] = (0.0, 0.0, 0.0), seed: int = 0, frames: bool = True
    ) -> ExecutionRecord:
        """Execute the plan with the object displaced by ``offset`` = ``(dx, dy, yaw)``
        [m, m, rad]; ``frames`` keeps the sampled rollout for the viewer.

        MuJoCo's warnings are caught while it runs (no ``MUJOCO_LOG.TXT`` in the working
        directory): those of a state it reset raise :class:`SimulationDiverged` with their
        text; the others are printed on stderr after the run, one line each.
        """
        import mujoco

        dx, dy, yaw = check_offset(offset)
        check_generator_seed(seed)
        messages: list[str] = []
        previous = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(messages.append)
        try:
            record = self._run(dx, dy, yaw, seed, frames, messages)
        finally:
            mujoco.set_mju_user_warning(previous)
        for message in messages:
            print(f"MuJoCo warning: {message}", file=sys.stderr)
        return record

    def _run(
        self, dx: float, dy: float, yaw: float, seed: int, frames: bool, messages: list[str]
    ) -> ExecutionRecord:
        """:meth:`run` with its offset checked; ``messages`` collects MuJoCo's warnings."""
        import mujoco

        options, world, model, sim = self.options, self.world, self.world.model, self.sim
        if options.object_jitter > 0:
            jitter = np.random.default_rng(seed).normal(0.0, options.object_jitter, 2)
        else:
            jitter = np.zeros(2)
        mujoco.mj_resetData(model, sim)
        true_pose = _displaced_pose(
            world.object_shape.pose, dx + float(jitter[0]), dy + float(jitter[1]), yaw
        )
        sim.qpos[world.object_qpos : world.object_qpos + 7] = true_pose
        sim.qpos[world.qpos] = self.path[0]
        ctrl = np.array(self.path[0])
        sim.ctrl[world.actuator] = ctrl
        mujoco.mj_forward(model, sim)

        dt = model.opt.timestep
        # Lower than any pose resting on its support allows: the object went through it.
        floor = float(true_pose[2]) - float(model.geom_rbound[world.object_geom]) - 0.01
        hand, arm = world.hand, world.arm
        kinds, links = world.geom_kind, world.geom_link
        period = max(1, round(options.frame_period / dt))
        kept: dict[str, Any] = {"q": [], "object": [], "phase": [], "neighbours": {}}
        neighbour_names = [shape.name for shape in world.neighbours]
        state: dict[str, Any] = {
            "step": 0,
            "first": None,
            "obstacles": {},
            "phase": "settle",
            "touched": False,
            "pressed": 0.0,
            "sunk": None,
            "pressed_phase": None,
            "gripped": 0.0,
            "top": -math.inf,  # the object's highest z [m] over the lift and hold
            "neighbours": {},  # shape name -> its first robot contact
        }
        tracking = {"reach_arm": 0.0, "reach_hand": 0.0, "lift_arm": 0.0}

        def object_transform() -> np.ndarray:
            t = np.eye(4)
            t[:3, :3] = sim.xmat[world.object_body].reshape(3, 3)
            t[:3, 3] = sim.xpos[world.object_body]
            return t

        def palm_transform() -> np.ndarray:
            t = np.eye(4)
            t[:3, :3] = sim.xmat[world.palm_body].reshape(3, 3)
            t[:3, 3] = sim.xpos[world.palm_body]
            return t

        def step() -> None:
            sim.ctrl[world.actuator] = ctrl
            mujoco.mj_step(model, sim)
            state["step"] += 1
            height = sim.qpos[world.object_qpos + 2]
            if state["sunk"] is None and height < floor:
                state["sunk"] = state["phase"]
            if state["phase"] in ("lift", "hold") and height > state["top"]:
                state["top"] = float(height)
            time = state["step"] * dt
            if sim.ncon:
                pairs = kinds[sim.contact.geom[: sim.ncon]]
                depth = -sim.contact.dist[: sim.ncon]
                pressed = ((pairs == OBJECT) & (pairs[:, ::-1] == OBSTACLE)).any(axis=1)
                if pressed.any():
                    deepest = float(depth[pressed].max())
                    if deepest > state["pressed"]:
                        state["pressed"], state["pressed_phase"] = deepest, state["phase"]
                gripped = ((pairs == OBJECT) & (pairs[:, ::-1] == ROBOT)).any(axis=1)
                if gripped.any():
                    state["gripped"] = max(state["gripped"], float(depth[gripped].max()))
                for i in np.flatnonzero((pairs == ROBOT).any(axis=1)):
                    g = sim.contact.geom[i]
                    other = int(g[1] if kinds[g[0]] == ROBOT else g[0])
                    link = links[int(g[0] if kinds[g[0]] == ROBOT else g[1])]
                    if kinds[other] == OBJECT:
                        if state["phase"] in ("settle", "reach"):
                            state["touched"] = True
                        if state["first"] is None:
                            palm = sim.xpos[world.palm_body]
                            d = (
                                float(np.linalg.norm(palm - self.goal)) / self.start_distance
                                if self.start_distance > 0
                                else None
                            )
                            state["first"] = {
                                "link": link,
                                "time_s": time,
                                "d": d,
                                "phase": state["phase"],
                            }
                    elif kinds[other] == NEIGHBOUR:
                        if links[other] not in state["neighbours"]:
                            state["neighbours"][links[other]] = {
                                "link": link, "time_s": time, "phase": state["phase"]
                            }  # fmt: skip
                    elif kinds[other] == OBSTACLE:
                        key = (link, links[other])
                        if key not in state["obstacles"]:
                            state["obstacles"][key] = {
                                "link": link,
                                "obstacle": links[other],
                                "time_s": time,
                                "phase": state["phase"],
                            }
            if frames and state["step"] % period == 0:
                kept["q"].append(sim.qpos[world.qpos].tolist())
                p = sim.qpos[world.object_qpos : world.object_qpos + 7]
                kept["object"].append([*p[:3], p[4], p[5], p[6], p[3]])
                kept["phase"].append(state["phase"])
                for name, body in zip(neighbour_names, world.neighbour_body, strict=True):
                    p = sim.xpos[body].tolist() + sim.xquat[body].tolist()
                    kept["neighbours"].setdefault(name, []).append([*p[:3], *p[4:], p[3]])

        def check_stable() -> None:
            for warning, what in UNSTABLE:
                if sim.warning[getattr(mujoco.mjtWarning, warning)].number:
                    detail = f"{what}, state reset" + "".join(f": {m}" for m in messages[-1:])
                    raise SimulationDiverged(state["phase"], state["step"] * dt, detail)
            if not np.all(np.isfinite(sim.qpos)):
                raise SimulationDiverged(state["phase"], state["step"] * dt, "non-finite state")

        def run_for(seconds: float) -> None:
            for _ in range(round(seconds / dt)):
                step()

        phases: dict[str, float] = {}
        phases["settle"] = options.settle
        run_for(options.settle)
        check_stable()
        settled = object_transform()
        neighbours_settled = [_body_transform(sim, b) for b in world.neighbour_body]

        state["phase"] = "reach"
        reach_steps = math.ceil(self.timed.duration / dt) + round(0.1 / dt)
        lead = self.lead
        desired = np.empty_like(ctrl)
        ahead = np.empty_like(ctrl)
        for k in range(reach_steps):
            self.timed.at((k + 1) * dt, desired)
            self.timed.at((k + 2) * dt, ahead)
            # Velocity feed-forward through the target: kp (q* + kv/kp v* - q) - kv v
            # = kp (q* - q) + kv (v* - v), no lag of kv v / kp behind a moving target.
            np.multiply(ahead - desired, lead / dt, out=ctrl)
            ctrl += desired
            step()
            error = np.abs(sim.qpos[world.qpos] - desired)
            tracking["reach_arm"] = max(tracking["reach_arm"], float(error[arm].max()))
            if hand.size and not state["touched"]:
                tracking["reach_hand"] = max(tracking["reach_hand"], float(error[hand].max()))
        ctrl[:] = desired
        phases["reach"] = reach_steps * dt
        check_stable()
        moved_m, moved_rad = _pose_change(settled, object_transform())

        state["phase"] = "close"
        start = ctrl[hand].copy()
        rates = self.close_rates
        span = np.abs(self.closed - start)
        close_time = self._close_time(start)
        close_steps = math.ceil(close_time / dt) + round(options.close_settle / dt)
        direction = np.sign(self.closed - start)
        for k in range(close_steps):
            travel = np.minimum(span, rates * (k + 1) * dt)
            ctrl[hand] = start + direction * travel
            for follower, leader, multiplier, off in world.mimic:
                ctrl[follower] = multiplier * ctrl[leader] + off
            step()
        phases["close"] = close_steps * dt
        check_stable()
        in_palm_closed = np.linalg.inv(palm_transform()) @ object_transform()
        palm_z0 = float(sim.xpos[world.palm_body][2])
        object_z0 = float(sim.xpos[world.object_body][2])
        object_qpos_z0 = float(sim.qpos[world.object_qpos + 2])

        state["phase"] = "lift"
        lift_rows_ = self.lift.copy()
        lift_rows_[:, hand] = ctrl[hand]
        lift_time = options.lift_height / options.lift_speed
        lift_steps = max(1, math.ceil(lift_time / dt))
        lift_lead = lead[arm]
        last = len(lift_rows_) - 1

        def lift_at(k: int) -> np.ndarray:
            """Arm target at lift step ``k``: the IK rows (equal palm rises) at a
            smoothstep in time, starting and stopping at rest."""
            s = min(1.0, k / lift_steps)
            x = s * s * (3 - 2 * s) * last
            i = min(int(x), max(last - 1, 0))
            a = min(1.0, x - i)
            j = min(i + 1, last)
            return lift_rows_[i, arm] + a * (lift_rows_[j, arm] - lift_rows_[i, arm])

        for k in range(lift_steps):
            target, following = lift_at(k + 1), lift_at(k + 2)
            ctrl[arm] = target + lift_lead * (following - target) / dt
            step()
            error = np.abs(sim.qpos[world.qpos[arm]] - target)
            tracking["lift_arm"] = max(tracking["lift_arm"], float(error.max()))
        phases["lift"] = lift_steps * dt
        check_stable()

        ctrl[arm] = lift_at(lift_steps)
        state["phase"] = "hold"
        run_for(options.hold)
        phases["hold"] = options.hold
        check_stable()

        in_palm_end = np.linalg.inv(palm_transform()) @ object_transform()
        drift_m, drift_rad = _pose_change(in_palm_closed, in_palm_end)
        palm_rise = float(sim.xpos[world.palm_body][2]) - palm_z0
        object_rise = float(sim.xpos[world.object_body][2]) - object_z0
        # Its highest rise: one that fell back to the table was still dropped.
        peak_rise = max(object_rise, state["top"] - object_qpos_z0)
        final = set()
        holding = False
        for i in range(sim.ncon):
            g = sim.contact.geom[i]
            a, b = int(g[0]), int(g[1])
            if kinds[b] == ROBOT:
                a, b = b, a
            if kinds[a] == ROBOT and kinds[b] in (OBJECT, OBSTACLE, NEIGHBOUR):
                final.add((links[a], links[b]))
                holding |= kinds[b] == OBJECT
            elif {int(kinds[a]), int(kinds[b])} == {OBJECT, OBSTACLE}:
                final.add(
                    (
                        links[a] if kinds[a] == OBJECT else links[b],
                        links[b] if kinds[a] == OBJECT else links[a],
                    )
                )
        obstacle_contacts = sorted(state["obstacles"].values(), key=lambda c: c["time_s"])
        lifted = object_rise >= options.lifted_fraction * options.lift_height

        cause: str | None = None
        if obstacle_contacts:
            cause = "obstacle contact"
        elif state["pressed"] > options.max_penetration:
            cause = "jammed"
        elif state["sunk"] is not None:
            cause = "fell"
        elif not holding:
            cause = "dropped" if peak_rise > DROPPED_RISE else "no contact"
        elif not lifted:
            cause = "not lifted"
        elif drift_m > options.success_distance or drift_rad > options.success_angle:
            cause = "slipped"
        name = world.object_shape.name
        if cause is None:
            verdict = (
                f"held: {name} lifted {object_rise * 1e3:.0f} mm, moved {drift_m * 1e3:.1f} mm /"
                f" {math.degrees(drift_rad):.1f} deg in the hand over the hold"
            )
        elif cause == "jammed" and state["pressed_phase"] == "settle":
            # Before the robot moves: the object was placed overlapping an obstacle (an
            # offset into a wall, say), not pushed there by the hand.
            verdict = (
                f"failed (jammed): {name} lay {state['pressed'] * 1e3:.0f} mm inside an"
                " obstacle during the settle, before the robot moved (placed there)"
            )
        elif cause == "jammed":
            verdict = (
                f"failed (jammed): the hand forced {name} {state['pressed'] * 1e3:.0f} mm into"
                f" an obstacle during the {state['pressed_phase']} (a real arm would stall;"
                " MuJoCo's soft contact gave way)"
            )
        elif cause == "fell":
            verdict = (
                f"failed (fell): {name} dropped below any pose resting on its support during"
                f" the {state['sunk']} (off the table or through it)"
            )
        elif cause == "obstacle contact":
            first = obstacle_contacts[0]
            verdict = (
                f"failed (obstacle contact): {first['link']} hit {first['obstacle']} at"
                f" {first['time_s']:.2f} s ({first['phase']})"
            )
        else:
            verdict = (
                f"failed ({cause}): {name} rose {object_rise * 1e3:.0f} mm of the palm's"
                f" {palm_rise * 1e3:.0f} mm, moved {drift_m * 1e3:.0f} mm /"
                f" {math.degrees(drift_rad):.0f} deg in the hand"
            )
        law = self.data.get("hand_law") or {}
        robot = self.data.get("robot") or {}
        neighbours = [
            _disturbance(shape.name, start, _body_transform(sim, body), options,
                         state["neighbours"].get(shape.name))
            for shape, start, body in zip(
                world.neighbours, neighbours_settled, world.neighbour_body, strict=True
            )
        ]  # fmt: skip
        return ExecutionRecord(
            success=cause is None,
            cause=cause,
            verdict=verdict,
            offset={"dx": dx, "dy": dy, "yaw": yaw},
            jitter={"dx": float(jitter[0]), "dy": float(jitter[1])},
            seed=int(seed),
            touched=bool(state["touched"]),
            moved_before_closing={"mm": moved_m * 1e3, "deg": math.degrees(moved_rad)},
            first_contact=state["first"],
            obstacle_contacts=obstacle_contacts,
            tracking=tracking,
            final_contacts=[{"link": a, "with": b} for a, b in sorted(final)],
            lift={
                "palm_mm": palm_rise * 1e3,
                "object_mm": object_rise * 1e3,
                "object_peak_mm": peak_rise * 1e3,
            },
            in_hand={"mm": drift_m * 1e3, "deg": math.degrees(drift_rad)},
            penetration={
                "object_obstacle_mm": state["pressed"] * 1e3,
                "robot_object_mm": state["gripped"] * 1e3,
            },
            phases=phases,
            plan={
                "robot": robot.get("name"),
                "planner": self.data.get("planner"),
                "seed": self.data.get("seed"),
                "u": law.get("u"),
                "rows": int(self.path.shape[0]),
                "closed": self.closed.tolist(),
                "closed_from": self.closed_source,
            },
            options=dataclasses.asdict(options),
            steps=int(state["step"]),
            neighbours=neighbours,
            neighbour_moved=any(n["moved"] for n in neighbours),
            neighbour_tipped=any(n["tipped"] for n in neighbours),
            neighbour_touched=any(n["touched"] is not None for n in neighbours),
            frames={
                "period_s": period * dt,
                "joint_names": world.joint_names,
                **kept,
            }
            if frames
            else None,
            source=_plain(self.data) if frames else None,
        )


def execute_plan(
    plan: str | Path | Plan | PlanFile | dict[str, Any],
    offset: Sequence[float] = (0.0, 0.0, 0.0),
    *,
    seed: int = 0,
    options: PhysicsOptions | None = None,
    frames: bool = True,
) -> ExecutionRecord:
    """Execute a plan file (or a plan, the plan read, or its contents) in physics with the
    object displaced by ``offset = (dx, dy, yaw)`` [m, m, rad] (module docstring);
    ``seed`` draws the object's jitter (``PhysicsOptions.object_jitter``).

    Raises:
        ConfigError: A non-finite offset; a file that is not ``openup-plan/1`` or fails
            the check ``show`` applies (:meth:`~openup_ompl.plan.PlanFile.read`: a
            missing URDF, a path row beyond a joint limit, a bad law, ...); a plan
            without an object.
        SimulationDiverged: MuJoCo went unstable (then no verdict is given).
    """
    check_offset(offset)
    if isinstance(plan, (str, os.PathLike)):
        path = Path(plan)
        plan = PlanFile.read(path)
        if plan.object is None:
            raise ConfigError(f"{path.name}: scene.object", None, "an object to grasp")
    return Rollout(plan, options).run(offset, seed=seed, frames=frames)
