"""Execute a plan in physics: reach, close, squeeze, lift, hold; judge the grasp.

Phases (:mod:`~openup_ompl.physics.phases`, each a stretch of position-actuator targets,
:mod:`~openup_ompl.physics.world`):

1. **settle**: the object rests where it really is (the plan's pose plus the offset).
2. **reach**: the plan's rows, timed under the URDF velocity limits
   (:func:`~openup_ompl.physics.trajectory.time_path`), the hand following the law as
   planned. The object is free: a finger that brushes it pushes it.
3. **close**: the hand joints' targets move towards the robot's closed configuration
   (its ``[hand].closed`` and ``closing_speed`` when the robot file is found, else the
   limit on ``c``'s side of ``w``); each joint stops where the object stops it.
4. **squeeze**: the targets stay there ``close_settle`` seconds; each joint presses with
   its force limit.
5. **lift**: the palm goes straight up by ``lift_height`` (world z) with its orientation
   held: differential IK on MuJoCo's own Jacobian, from the plan's last row.
6. **hold**: ``hold`` seconds at the top.

Success (DexGraspBench's criterion, :mod:`~openup_ompl.physics.verdict`): no robot link
touched a fixed obstacle, the object rose with the palm (at least ``lifted_fraction`` of
the lift), and at the end of the hold it sits within ``success_distance`` and
``success_angle`` of where it sat in the palm frame at the end of the squeeze.
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
from openup_ompl.exceptions import ConfigError
from openup_ompl.executor import check_generator_seed
from openup_ompl.physics.approach import SharedApproach
from openup_ompl.physics.inputs import PlanInput
from openup_ompl.physics.monitor import UNSTABLE, Monitor, transform
from openup_ompl.physics.options import PHASE_MAX, PhysicsOptions
from openup_ompl.physics.phases import (
    PHASE_ORDER,
    Closing,
    Lift,
    LiftTargets,
    Reach,
    ReachTargets,
    hold,
    settle,
)
from openup_ompl.physics.record import ExecutionRecord
from openup_ompl.physics.reuse import cached_world
from openup_ompl.physics.targets import (
    closed_configuration,
    closed_targets,
    displaced_pose,
    lift_rows,
)
from openup_ompl.physics.trajectory import time_path
from openup_ompl.physics.verdict import (
    DROPPED_RISE,
    Outcome,
    disturbance,
    final_contacts,
    judge,
    pose_change,
)
from openup_ompl.plan import Plan, PlanFile
from openup_ompl.scene import Problem, Shape
from openup_ompl.truth import with_true_object

__all__ = [
    "DROPPED_RISE",
    "UNSTABLE",
    "PlanInput",
    "Rollout",
    "check_offset",
    "closed_targets",
    "execute_plan",
    "lift_rows",
]

#: The largest object displacement [m] along x or y a rollout takes: beyond the reach of
#: every shipped arm (MuJoCo resets a state with a huge position).
OFFSET_MAX = 1.0


def check_offset(offset: Sequence[float]) -> tuple[float, float, float]:
    """Check an object offset.

    Args:
        offset: ``(dx, dy, yaw)`` [m, m, rad]: the object's displacement along the world x
            and y axes and its turn about its own z axis.

    Returns:
        ``(dx, dy, yaw)`` as floats.

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


def _plain(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` with NumPy values as plain JSON types (a plan's ``to_dict`` may hold them)."""

    def convert(value: Any) -> Any:
        return value.tolist() if hasattr(value, "tolist") else str(value)

    result: dict[str, Any] = json.loads(json.dumps(data, default=convert))
    return result


class Rollout:
    """One plan in one physics world; :meth:`run` executes it against an offset object.

    Building the world (a few milliseconds) and the lift's IK happen once, so a sweep
    runs every offset of a plan through one :class:`Rollout`.

    Args:
        plan: The plan (:meth:`~openup_ompl.GraspPlanningSetup.solve`'s, taken as it is:
            its problem's robot and scene), as read
            (:meth:`~openup_ompl.plan.PlanFile.read`), or a plan file's contents (checked
            here as ``show`` checks them).
        options: Physics settings.
        scene_object: The object the world holds instead of the plan's (a :class:`Plan`
            only: the truth a plan made for an estimate is judged against).

    Raises:
        ConfigError: A plan file's contents that fail their check
            (:meth:`~openup_ompl.plan.PlanFile.from_dict`), a plan without an object, or a
            plan MuJoCo cannot build.
    """

    def __init__(
        self,
        plan: Plan | PlanFile | dict[str, Any],
        options: PhysicsOptions | None = None,
        *,
        scene_object: Shape | None = None,
    ) -> None:
        import mujoco

        if options is not None and not isinstance(options, PhysicsOptions):
            raise ConfigError("options", options, "PhysicsOptions or None")
        if isinstance(plan, Plan):
            source = PlanInput.from_plan(plan, scene_object)
        else:
            if scene_object is not None:
                raise ConfigError("scene_object", scene_object.name, "None for a plan file")
            if not isinstance(plan, PlanFile):
                plan = PlanFile.from_dict(plan, where="plan ")
            source = PlanInput.from_file(plan)
        self.source = source
        self.options = options = options or PhysicsOptions()
        self.world = world = cached_world(source.robot, source.obstacles, source.object, options)
        self.path = source.path
        self.timed = time_path(self.path, world.velocity_limit, options.speed, options.acceleration)
        if self.timed.duration > PHASE_MAX:
            raise ConfigError(
                "PhysicsOptions.speed and acceleration",
                (options.speed, options.acceleration),
                f"a reach of at most {PHASE_MAX:g} s (this plan's takes "
                f"{self.timed.duration:.3g} s)",
            )
        self.closed, self.closing_speed, self.closed_source = closed_configuration(
            source.c, source.w, world, source.spec, source.robot.hand_joints
        )
        # Speed of each hand joint's target while the hand closes [rad/s or m/s].
        self.close_rates = self.closing_speed * np.where(
            world.prismatic[world.hand], options.finger_close_speed, options.close_speed
        )
        close_time = Closing(world, self.path[-1][world.hand], self.closed, self.close_rates)
        if close_time.duration > PHASE_MAX:
            raise ConfigError(
                "PhysicsOptions.close_speed and finger_close_speed",
                (options.close_speed, options.finger_close_speed),
                f"a closing of at most {PHASE_MAX:g} s (this plan's takes"
                f" {close_time.duration:.3g} s)",
            )
        self.lift = lift_rows(world, self.path[-1], options.lift_height)
        self.sim = mujoco.MjData(world.model)
        model = world.model
        # kv / kp of each joint's actuator [s]: the velocity feed-forward's lead.
        gains = model.actuator_gainprm[world.actuator, 0]
        self.lead = -model.actuator_biasprm[world.actuator, 2] / gains
        self.goal = source.grasp_pose[:3]
        self.start_distance = source.start_palm_distance
        dt = float(model.opt.timestep)
        self.reach_targets = ReachTargets(self.timed, self.lead, dt)
        lift_steps = max(1, math.ceil(options.lift_height / options.lift_speed / dt))
        self.lift_targets = LiftTargets(self.lift, world.arm, self.lead[world.arm], lift_steps, dt)
        self._shared: SharedApproach | None = None  # made at the first trial that shares

    def run(
        self, offset: Sequence[float] = (0.0, 0.0, 0.0), seed: int = 0, frames: bool = True
    ) -> ExecutionRecord:
        """Execute the plan with the object displaced.

        MuJoCo's warnings are caught while it runs (no ``MUJOCO_LOG.TXT`` in the working
        directory): those of a state it reset raise :class:`SimulationDiverged` with their
        text; the others are printed on stderr after the run, one line each.

        Args:
            offset: ``(dx, dy, yaw)`` [m, m, rad] (:func:`check_offset`).
            seed: Seed of the object's jitter (``PhysicsOptions.object_jitter``).
            frames: Keep the sampled rollout (and the plan's contents) for the viewer.

        Returns:
            The execution record: the verdict, its cause and what the rollout measured.

        Raises:
            ConfigError: A bad offset or seed.
            SimulationDiverged: MuJoCo went unstable.
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

    def _start(self, dx: float, dy: float, seed: int, yaw: float) -> tuple[np.ndarray, float]:
        """Reset the simulation: the object at its true pose, the robot at the first row.
        Returns the jitter drawn and the height below which the object has fallen."""
        import mujoco

        world, model, sim = self.world, self.world.model, self.sim
        if self.options.object_jitter > 0:
            jitter = np.random.default_rng(seed).normal(0.0, self.options.object_jitter, 2)
        else:
            jitter = np.zeros(2)
        mujoco.mj_resetData(model, sim)
        true_pose = displaced_pose(
            world.object_shape.pose, dx + float(jitter[0]), dy + float(jitter[1]), yaw
        )
        sim.qpos[world.object_qpos : world.object_qpos + 7] = true_pose
        for address, start in zip(world.neighbour_qpos, world.neighbour_start, strict=True):
            sim.qpos[address : address + 7] = start
        sim.qpos[world.qpos] = self.path[0]
        sim.ctrl[world.actuator] = self.path[0]
        mujoco.mj_forward(model, sim)
        # Lower than any pose resting on its support allows: the object went through it.
        floor = float(true_pose[2]) - float(model.geom_rbound[world.object_geom]) - 0.01
        return jitter, floor

    def _run(
        self, dx: float, dy: float, yaw: float, seed: int, frames: bool, messages: list[str]
    ) -> ExecutionRecord:
        """:meth:`run` with its offset checked; ``messages`` collects MuJoCo's warnings."""
        options, world, sim = self.options, self.world, self.sim
        jitter, floor = self._start(dx, dy, seed, yaw)
        handover = None
        if options.shared_approach and not frames:
            if self._shared is None:
                self._shared = SharedApproach(self)
            start = sim.qpos[world.object_qpos : world.object_qpos + 7].copy()
            handover = self._shared.handover(start)
        period = max(1, round(options.frame_period / world.model.opt.timestep))
        monitor = Monitor(world, sim, np.array(self.path[0]), floor, self.goal,
                          self.start_distance, period if frames else 0, messages,
                          early_end=options.early_end)  # fmt: skip
        monitor.handover = handover
        phases: dict[str, float] = {}
        phases["settle"] = settle(monitor, options.settle)
        monitor.check_stable()
        settled = transform(sim, world.object_body)
        neighbours_settled = [transform(sim, body) for body in world.neighbour_body]
        reach = Reach(self.reach_targets)
        phases["reach"] = reach.run(monitor)
        monitor.check_stable()
        moved_m, moved_rad = pose_change(settled, transform(sim, world.object_body))
        closing = Closing(world, monitor.ctrl[world.hand], self.closed, self.close_rates)
        phases["close"] = closing.close(monitor)
        monitor.check_stable()
        phases["squeeze"] = closing.squeeze(monitor, options.close_settle)
        monitor.check_stable()
        palm_closed = transform(sim, world.palm_body)
        in_palm_closed = np.linalg.inv(palm_closed) @ transform(sim, world.object_body)
        palm_z0 = float(sim.xpos[world.palm_body][2])
        object_z0 = float(sim.xpos[world.object_body][2])
        object_qpos_z0 = float(sim.qpos[world.object_qpos + 2])
        lift = Lift(self.lift_targets)
        phases["lift"] = lift.run(monitor)
        monitor.check_stable()
        phases["hold"] = hold(monitor, options.hold)
        monitor.check_stable()
        if monitor.ended is not None:  # the phases after the one it ended in never ran
            last = PHASE_ORDER.index(monitor.ended["phase"])
            phases = {k: v for k, v in phases.items() if PHASE_ORDER.index(k) <= last}

        in_palm_end = np.linalg.inv(transform(sim, world.palm_body)) @ transform(
            sim, world.object_body
        )
        drift_m, drift_rad = pose_change(in_palm_closed, in_palm_end)
        object_rise = float(sim.xpos[world.object_body][2]) - object_z0
        final, holding = final_contacts(sim, world)
        outcome = Outcome(
            object_rise=object_rise,
            # Its highest rise: one that fell back to the table was still dropped.
            peak_rise=max(object_rise, monitor.top - object_qpos_z0),
            palm_rise=float(sim.xpos[world.palm_body][2]) - palm_z0,
            drift_m=drift_m,
            drift_rad=drift_rad,
            holding=holding,
        )
        cause, verdict = judge(monitor, outcome, options, world.object_shape.name)
        neighbours = [
            disturbance(shape.name, start, transform(sim, body), options,
                        monitor.neighbours.get(shape.name))
            for shape, start, body in zip(
                world.neighbours, neighbours_settled, world.neighbour_body, strict=True
            )
        ]  # fmt: skip
        return self._record(
            monitor=monitor, cause=cause, verdict=verdict, outcome=outcome, phases=phases,
            offset=(dx, dy, yaw), jitter=jitter, seed=seed, frames=frames,
            moved=(moved_m, moved_rad), final=final, neighbours=neighbours,
            tracking={"reach_arm": reach.arm_error, "reach_hand": reach.hand_error,
                      "lift_arm": lift.arm_error},
        )  # fmt: skip

    def _record(
        self,
        *,
        monitor: Monitor,
        cause: str | None,
        verdict: str,
        outcome: Outcome,
        phases: dict[str, float],
        offset: tuple[float, float, float],
        jitter: np.ndarray,
        seed: int,
        frames: bool,
        moved: tuple[float, float],
        final: set[tuple[str, str]],
        neighbours: list[dict[str, Any]],
        tracking: dict[str, float],
    ) -> ExecutionRecord:
        """The execution record of a finished rollout."""
        source, world = self.source, self.world
        dx, dy, yaw = offset
        return ExecutionRecord(
            success=cause is None,
            cause=cause,
            verdict=verdict,
            offset={"dx": dx, "dy": dy, "yaw": yaw},
            jitter={"dx": float(jitter[0]), "dy": float(jitter[1])},
            seed=int(seed),
            touched=bool(monitor.touched),
            moved_before_closing={"mm": moved[0] * 1e3, "deg": math.degrees(moved[1])},
            first_contact=monitor.first,
            obstacle_contacts=sorted(monitor.obstacles.values(), key=lambda c: c["time_s"]),
            tracking=tracking,
            final_contacts=[{"link": a, "with": b} for a, b in sorted(final)],
            lift={
                "palm_mm": outcome.palm_rise * 1e3,
                "object_mm": outcome.object_rise * 1e3,
                "object_peak_mm": outcome.peak_rise * 1e3,
            },
            in_hand={"mm": outcome.drift_m * 1e3, "deg": math.degrees(outcome.drift_rad)},
            penetration={
                "object_obstacle_mm": monitor.pressed * 1e3,
                "robot_object_mm": monitor.gripped * 1e3,
            },
            phases=phases,
            plan={
                "robot": source.robot.name,
                "planner": source.planner,
                "seed": source.seed,
                "u": source.u,
                "rows": int(self.path.shape[0]),
                "closed": self.closed.tolist(),
                "closed_from": self.closed_source,
            },
            options=dataclasses.asdict(self.options),
            steps=int(monitor.steps),
            ended_early=monitor.ended,
            neighbours=neighbours,
            neighbour_moved=any(n["moved"] for n in neighbours),
            neighbour_tipped=any(n["tipped"] for n in neighbours),
            neighbour_touched=any(n["touched"] is not None for n in neighbours),
            frames={"period_s": monitor.period * monitor.dt, "joint_names": world.joint_names,
                    **monitor.kept} if frames else None,
            source=_plain(source.contents()) if frames else None,
        )  # fmt: skip


def execute_plan(
    plan: str | Path | Plan | PlanFile | dict[str, Any],
    offset: Sequence[float] = (0.0, 0.0, 0.0),
    *,
    seed: int = 0,
    options: PhysicsOptions | None = None,
    frames: bool = True,
    truth: Problem | Shape | None = None,
) -> ExecutionRecord:
    """Execute a plan file (or a plan, the plan read, or its contents) in physics with the
    object displaced by ``offset = (dx, dy, yaw)`` [m, m, rad] (module docstring);
    ``seed`` draws the object's jitter (``PhysicsOptions.object_jitter``). ``truth``, a
    scene or a shape, puts the true object in place of the plan's
    (:func:`~openup_ompl.truth.with_true_object`): a perceived plan against the true pose,
    ``offset`` then displacing the true object. The path is not re-validated against its
    scene here (``openup-ompl execute`` does it first:
    :func:`~openup_ompl.revalidate.revalidate_plan`).

    Args:
        plan: A plan file's path, a :class:`~openup_ompl.plan.Plan`, a
            :class:`~openup_ompl.plan.PlanFile` or a plan file's contents.
        offset: ``(dx, dy, yaw)`` [m, m, rad] (:func:`check_offset`).
        seed: Seed of the object's jitter.
        options: The physics settings (default
            :class:`~openup_ompl.physics.options.PhysicsOptions`).
        frames: Keep the sampled rollout for the viewer.
        truth: The true scene or object, or ``None`` (the plan's object).

    Returns:
        The execution record.

    Raises:
        ConfigError: A non-finite offset; a file that is not ``openup-plan/1`` or fails
            the check ``show`` applies (:meth:`~openup_ompl.plan.PlanFile.read`: a
            missing URDF, a path row beyond a joint limit, a bad law, ...); a plan
            without an object; a ``truth`` without one or of another robot.
        SimulationDiverged: MuJoCo went unstable (then no verdict is given).
    """
    check_offset(offset)
    if isinstance(plan, (str, os.PathLike)):
        path = Path(plan)
        plan = PlanFile.read(path)
        if plan.object is None and truth is None:
            raise ConfigError(f"{path.name}: scene.object", None, "an object to grasp")
    if truth is not None:
        if not isinstance(plan, (Plan, PlanFile)):
            plan = PlanFile.from_dict(plan, where="plan: ")
        plan = with_true_object(plan, truth)
    return Rollout(plan, options).run(offset, seed=seed, frames=frames)
