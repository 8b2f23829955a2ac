"""The approach a plan's trials share (``PhysicsOptions.shared_approach``): simulated once,
each trial takes over where its hand may first reach its object (:class:`SharedApproach`).

The plan's approach (settle, reach, close) runs once in the trials' own world with the
object at its nominal pose (:attr:`SharedApproach.run`), as far as the hand stays off the
object, the neighbours and the fixed obstacles. Until a robot part comes near the object,
nothing a trial varies touches the robot: MuJoCo solves each constraint island on its own,
so the arm's and the hand's motion are every trial's to the last bit, and so are the
neighbours'. The object meanwhile rests on its support; a trial whose object stands
elsewhere on the same flat face, or turned about the vertical through its start (``yaw``,
when its own z axis is vertical), takes the nominal object's rest moved so. That move is
exact physics (on a flat face the rest does not depend on where the object stands or
which way it faces) but not exact arithmetic: the object differs from an unshared run's
by rounding (below a micrometre), so a record's numbers may differ from the unshared
run's, and a verdict that rounding decides may differ (none of the 146 fixed trials does
today; one of them turns with a 1e-10 m shift of its start). The nominal trial is the
unshared run bit for bit.

A trial uses the shared run up to its *handover*: the last checkpoint (every
:data:`STRIDE` steps) before which no robot geom that can touch the object may have
reached it (or a neighbour), the object no neighbour
(:mod:`~openup_ompl.physics.clearance`: bounding spheres at every step, then MuJoCo's
distance at each checkpoint beyond what each geom moves until the next), and before the
shared run's robot touched anything (its watch sensors). From the handover on the trial is
simulated as without sharing. Not shared (the trial runs whole): an object turned about
anything but the vertical or standing at another height, one that rests on anything but
the top face of one fixed box (its footprint within the face) or a horizontal plane, or
that would stand within :data:`MOVE` of another fixed obstacle; and nothing past the step
at which the shared object moved more than :data:`MOVE`, or a stretch in which MuJoCo
warned.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from openup_ompl.physics import clearance
from openup_ompl.physics.phases import Closing

if TYPE_CHECKING:
    from openup_ompl.physics.monitor import Monitor
    from openup_ompl.physics.rollout import Rollout

__all__ = ["BLOCK", "MOVE", "STRIDE", "Handover", "SharedApproach"]

#: Steps between the checkpoints a trial can take over at.
STRIDE = 16
#: Steps the shared run goes further by when a trial needs more.
BLOCK = 16 * STRIDE
#: How far [m] any point of the resting object may move while trials share: its
#: clearance from the other fixed obstacles is judged with this travel.
MOVE = 1e-3


class _Track:
    """A simulation run in stretches of at most :data:`STRIDE` steps: every state and
    sensor row, and the solver's warm start at each stretch's end, kept.

    Attributes:
        states: ``states[t]``: the full physics state after ``t`` steps.
        sensors: ``sensors[t]``: the sensors of step ``t - 1`` (its contacts at
            ``t - 1``); row 0 zeros.
        warm: The warm start after ``t`` steps, at each checkpoint ``t``.
        count: How many of :attr:`states` are filled.
    """

    def __init__(self, model: Any, data: Any, steps: int) -> None:
        import mujoco
        from mujoco import rollout

        self.model, self.data = model, data
        self.runner = rollout.Rollout(nthread=0)
        size = mujoco.mj_stateSize(model, int(mujoco.mjtState.mjSTATE_FULLPHYSICS))
        self.states = np.empty((steps + 1, size))
        self.sensors = np.zeros((steps + 1, model.nsensordata))
        mujoco.mj_getState(model, data, self.states[0], int(mujoco.mjtState.mjSTATE_FULLPHYSICS))
        self.warm = {0: data.qacc_warmstart.copy()}
        self.count = 1

    def extend(self, controls: np.ndarray) -> bool:
        """Run ``controls`` (one ``ctrl`` row per step, at most :data:`STRIDE`) from the
        last state; False (nothing kept) if MuJoCo warned."""
        import mujoco

        t, n = self.count - 1, len(controls)
        self.runner.rollout(
            [self.model], [self.data], self.states[t][None], controls[None],
            control_spec=int(mujoco.mjtState.mjSTATE_CTRL), skip_checks=True, nstep=n,
            initial_warmstart=self.warm[t][None], state=self.states[None, t + 1 : t + 1 + n],
            sensordata=self.sensors[None, t + 1 : t + 1 + n],
        )  # fmt: skip
        if any(self.data.warning.number):
            return False
        self.warm[t + n] = self.data.qacc_warmstart.copy()
        self.count += n
        return True


class SharedApproach:
    """The settle, the reach and the close of one :class:`~openup_ompl.physics.rollout.
    Rollout`, simulated once, in blocks of :data:`BLOCK` steps as far as its trials
    need (module docstring).

    Args:
        rollout: The rollout whose trials share it.

    Attributes:
        rows: The targets of every shared step (plan joint order).
        limit: No trial takes over later than this step: the shared run's robot touches
            the object, a neighbour or a fixed obstacle in the stretch after it, or
            MuJoCo warned there.
        support: The object's support (found after the first block), or ``None``: the
            trials cannot share.
    """

    def __init__(self, rollout: Rollout) -> None:
        import mujoco

        from openup_ompl.physics.targets import displaced_pose
        from openup_ompl.physics.world import FIXED_ROBOT, NEIGHBOUR, OBJECT, OBSTACLE, ROBOT

        world, options = rollout.world, rollout.options
        model, dt = world.model, float(world.model.opt.timestep)
        reach = rollout.reach_targets
        ctrl = np.array(reach.targets[reach.steps - 1])
        closing = Closing(world, ctrl[world.hand], rollout.closed, rollout.close_rates)
        self.rows = np.concatenate([
            np.tile(rollout.path[0], (round(options.settle / dt), 1)),
            reach.commands[: reach.steps],
            closing.rows(ctrl, dt),
        ])  # fmt: skip
        steps = len(self.rows)
        self.controls = np.zeros((steps, model.nu))
        self.controls[:, world.actuator] = self.rows
        self.world, self.qpos = world, 1 + np.arange(model.nq)
        self.nominal = displaced_pose(world.object_shape.pose, 0.0, 0.0, 0.0)
        self.limit = steps

        # The whole world, the object at its nominal pose.
        data = mujoco.MjData(model)
        data.qpos[world.qpos] = rollout.path[0]
        data.qpos[world.object_qpos : world.object_qpos + 7] = self.nominal
        for address, start in zip(world.neighbour_qpos, world.neighbour_start, strict=True):
            data.qpos[address : address + 7] = start
        data.ctrl[world.actuator] = rollout.path[0]
        mujoco.mj_forward(model, data)
        self.run = _Track(model, data, steps)
        self.kinematics = mujoco.MjData(model)

        # Geoms: the robot's that can touch the object or a neighbour; the object's; the
        # neighbours'. Their bounding radii with margins [m].
        kinds = world.geom_kind
        self.objects = np.flatnonzero(kinds == OBJECT)
        self.neighbours = np.flatnonzero(kinds == NEIGHBOUR)
        obj = self.objects[0]
        meets = (model.geom_contype & model.geom_conaffinity[obj]) | (
            model.geom_contype[obj] & model.geom_conaffinity
        )
        self.geoms = np.flatnonzero((kinds == ROBOT) & (meets != 0))
        bound = model.geom_rbound + model.geom_margin
        self.r_geoms, self.r_objects = bound[self.geoms], bound[self.objects]
        self.r_neighbours = bound[self.neighbours]
        self.fixed = np.flatnonzero(np.isin(kinds, (OBSTACLE, FIXED_ROBOT)))
        # The object's and the neighbours' bodies (the object first) and their radii [m].
        self.bodies = np.array([world.object_body, *world.neighbour_body], dtype=np.intp)
        self.r_bodies = np.array([clearance.body_radius(model, b) for b in self.bodies])
        index = {int(b): i for i, b in enumerate(self.bodies)}
        self.owner = np.array([index[int(b)] for b in model.geom_bodyid[self.neighbours]],
                              dtype=np.intp)  # each neighbour geom's body, in bodies  # fmt: skip
        self.centres = np.empty((steps + 1, len(self.geoms), 3))
        self.axes = np.empty((steps + 1, len(self.geoms), 9))
        self.neighbour_centres = np.empty((steps + 1, len(self.neighbours), 3))
        self.object_centres = np.empty((steps + 1, len(self.objects), 3))
        self.body_centres = np.empty((steps + 1, len(self.bodies), 3))
        self.body_axes = np.empty((steps + 1, len(self.bodies), 9))
        self.robot_apart = np.empty(steps + 1, dtype=bool)  # from every neighbour
        self._motions: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._kinematics(0, 1)
        # How far the object reaches sideways, at its start (the kinematics just made).
        self.footprint = clearance.footprint(model, self.kinematics, world.object_body)
        self._extend()
        self.support = clearance.support(model, self.run.states[self.run.count - 1])

    def _kinematics(self, first: int, stop: int) -> None:
        """The geoms' placements at the shared run's states ``first .. stop - 1``."""
        import mujoco

        model, data = self.world.model, self.kinematics
        for t in range(first, stop):
            data.qpos[:] = self.run.states[t][self.qpos]
            mujoco.mj_kinematics(model, data)
            self.centres[t] = data.geom_xpos[self.geoms]
            self.axes[t] = data.geom_xmat[self.geoms]
            self.neighbour_centres[t] = data.geom_xpos[self.neighbours]
            self.object_centres[t] = data.geom_xpos[self.objects]
            self.body_centres[t] = data.xpos[self.bodies]
            self.body_axes[t] = data.xmat[self.bodies]
        self.robot_apart[first:stop] = clearance.spheres_apart(
            self.centres[first:stop], self.r_geoms,
            self.neighbour_centres[first:stop], self.r_neighbours,
        )  # fmt: skip

    def _extend(self) -> bool:
        """Run the shared simulation up to :data:`BLOCK` steps further; False if it is at
        :attr:`limit` already."""
        first = self.run.count
        if first - 1 >= self.limit:
            return False
        done = first - 1
        while done < min(first - 1 + BLOCK, self.limit):
            controls = self.controls[done : done + STRIDE]
            if not self.run.extend(controls):
                self.limit = done  # nothing from the failed stretch on
                break
            done += len(controls)
        stop = self.run.count
        self._kinematics(first, stop)
        watch = self.world.watch
        touching = [*watch.touching, *watch.gripped]
        hit = (self.run.sensors[first:stop, touching] > 0).any(axis=1)
        if hit.any():  # sensors row t: the contacts at state t - 1
            at = first - 1 + int(np.argmax(hit))
            self.limit = min(self.limit, at - at % STRIDE)
        states = [0, *range(first, stop)]  # the object's travel from its start
        moved = (
            clearance.travel(
                self.body_centres[states, :1], self.body_axes[states, :1], self.r_bodies[:1]
            )[1:, 0]
            > MOVE
        )
        if moved.any():  # no longer resting where it was
            at = first + int(np.argmax(moved))
            self.limit = min(self.limit, at - at % STRIDE)
        return stop > first

    def _motion(self, first: int, stop: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """How far [m] each robot geom, object geom and neighbour geom may move from
        ``first`` until ``stop`` (cached)."""
        if first not in self._motions:
            robot = clearance.travel(
                self.centres[first:stop], self.axes[first:stop], self.r_geoms
            ).max(axis=0)
            bodies = clearance.travel(
                self.body_centres[first:stop], self.body_axes[first:stop], self.r_bodies
            ).max(axis=0)
            objects = np.full(len(self.objects), bodies[0])
            self._motions[first] = (robot, objects, bodies[self.owner])
        return self._motions[first]

    def handover(self, start: np.ndarray) -> Handover | None:
        """Where a trial whose object starts at ``start`` takes over.

        Args:
            start: The object's start ``qpos`` (position, scalar-first quaternion).

        Returns:
            The trial's handover, or ``None`` (the trial runs whole).
        """
        move = clearance.Move.between(self.nominal, start)
        if move is None:
            return None
        if self.support is None or not self.support.holds(move.shift, self.footprint + MOVE):
            return None
        if not self._clear_of_fixed(move):
            return None
        # Bounding spheres at every state, as far as they stay apart.
        t = 0
        while True:
            stop = self.run.count
            objects = move.points(self.object_centres[t:stop])
            apart = self.robot_apart[t:stop] & clearance.spheres_apart(
                self.centres[t:stop], self.r_geoms, objects, self.r_objects,
            ) & clearance.spheres_apart(
                objects, self.r_objects, self.neighbour_centres[t:stop], self.r_neighbours,
            )  # fmt: skip
            if not apart.all():
                t += int(np.argmin(apart))
                break
            t = stop
            if not self._extend():
                t = stop - 1
                break
        checkpoint = min(t - t % STRIDE, self.limit)
        # MuJoCo's distances from there, a stretch at a time.
        while checkpoint < self.limit:
            following = min(checkpoint + STRIDE, len(self.rows))
            if self.run.count <= following and not self._extend():
                break
            if following > self.limit or not self._apart(checkpoint, following, move):
                break
            checkpoint = following
        return Handover(self, checkpoint, move) if checkpoint > 0 else None

    def _place(self, t: int, move: clearance.Move) -> None:
        """Kinematics of the shared run's state ``t`` with its object moved by ``move``."""
        import mujoco

        data, q = self.kinematics, self.world.object_qpos
        data.qpos[:] = self.run.states[t][self.qpos]
        data.qpos[q : q + 3] = move.points(data.qpos[q : q + 3])
        data.qpos[q + 3 : q + 7] = move.quats(data.qpos[None, q + 3 : q + 7])[0]
        mujoco.mj_kinematics(self.world.model, data)

    def _clear_of_fixed(self, move: clearance.Move) -> bool:
        """Whether the object, moved by ``move`` and by up to :data:`MOVE` more, stays
        clear of every fixed obstacle but its support (MuJoCo's distance at the start)."""
        assert self.support is not None
        world, data = self.world, self.kinematics
        self._place(0, move)
        others = [int(g) for g in self.fixed if g != self.support.geom]
        pairs = [(int(o), g) for o in self.objects for g in others]
        travel = {**{int(o): MOVE for o in self.objects}, **{g: 0.0 for g in others}}
        return clearance.exactly_apart(world.model, data, pairs, travel)

    def _apart(self, first: int, stop: int, move: clearance.Move) -> bool:
        """Whether no robot geom can touch the object (moved by ``move``) or a neighbour,
        and the object no neighbour, at the states ``first .. stop - 1``."""
        t_robot, t_objects, t_neighbours = self._motion(first, stop)
        robot, objects = self.centres[first], move.points(self.object_centres[first])
        neighbours = self.neighbour_centres[first]
        pairs: list[tuple[int, int]] = []
        travel: dict[int, float] = {}
        for a, ra, ta, ga, b, rb, tb, gb in (
            (robot, self.r_geoms, t_robot, self.geoms,
             objects, self.r_objects, t_objects, self.objects),
            (robot, self.r_geoms, t_robot, self.geoms,
             neighbours, self.r_neighbours, t_neighbours, self.neighbours),
            (objects, self.r_objects, t_objects, self.objects,
             neighbours, self.r_neighbours, t_neighbours, self.neighbours),
        ):  # fmt: skip
            if not len(ga) or not len(gb):
                continue
            gaps = np.linalg.norm(a[:, None] - b[None], axis=2) - ra[:, None] - rb
            for i, j in np.argwhere(gaps <= ta[:, None] + tb):
                pairs.append((int(ga[i]), int(gb[j])))
                travel[int(ga[i])], travel[int(gb[j])] = float(ta[i]), float(tb[j])
        if not pairs:
            return True
        self._place(first, move)
        return clearance.exactly_apart(self.world.model, self.kinematics, pairs, travel)


class Handover:
    """A trial's share of the approach: the steps ``0 .. end - 1`` are replayed from the
    shared run, and the trial's simulation is set to the merged state at step ``end``.

    Attributes:
        end: The handover step.
    """

    def __init__(self, shared: SharedApproach, end: int, move: clearance.Move) -> None:
        self.shared, self.end, self.move, self.world = shared, end, move, shared.world

    def _states(self, first: int, stop: int) -> np.ndarray:
        """The trial's full physics states after ``first .. stop - 1`` steps: the shared
        run's, its object moved by the trial's offset (position and orientation; the
        linear velocity turned, the angular one is in the object's own frame)."""
        states = self.shared.run.states[first:stop].copy()
        q = 1 + self.world.object_qpos
        v = 1 + self.world.model.nq + self.world.object_dof
        states[:, q : q + 3] = self.move.points(states[:, q : q + 3])
        states[:, q + 3 : q + 7] = self.move.quats(states[:, q + 3 : q + 7])
        states[:, v : v + 3] = self.move.vectors(states[:, v : v + 3])
        return states

    def replay(self, monitor: Monitor, rows: np.ndarray, log: np.ndarray | None, at: int) -> int:
        """Replay up to the handover from ``monitor.steps``: the watch's numbers, the log,
        and at the end the simulation's state.

        Args:
            monitor: The trial's monitor.
            rows: The targets the phase drives from here (plan joint order).
            log: If given, ``log[at + k]`` gets the whole ``qpos`` after step ``k``.
            at: The index in ``log`` of the first row.

        Returns:
            The steps replayed.
        """
        import mujoco

        shared, world = self.shared, self.world
        first = monitor.steps
        n = min(len(rows), self.end - first)
        if not np.array_equal(rows[:n], shared.rows[first : first + n]):
            raise RuntimeError("the shared approach's targets differ from the trial's")
        states = self._states(first, first + n + 1)  # the start's, then after each step
        sensors = shared.run.sensors[first + 1 : first + n + 1]
        monitor.watch_steps(states[1:, 1 + world.object_qpos + 2], sensors)
        if log is not None:
            log[at : at + n] = states[1:, shared.qpos]
        model, sim, spec = world.model, monitor.sim, int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
        # As after MuJoCo's step: the kinematics of the state before, the state after.
        mujoco.mj_setState(model, sim, states[-2], spec)
        mujoco.mj_kinematics(model, sim)
        mujoco.mj_setState(model, sim, states[-1], spec)
        if first + n == self.end:
            warm = shared.run.warm[self.end].copy()
            d = world.object_dof
            warm[d : d + 3] = self.move.vectors(warm[d : d + 3])
            sim.qacc_warmstart[:] = warm
            monitor.handover = None
        return n
