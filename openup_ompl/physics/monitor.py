"""The simulation loop's one step and what it watches: contacts, the object's height, the
kept frames, and MuJoCo's instability warnings (:class:`Monitor`)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from openup_ompl.exceptions import SimulationDiverged
from openup_ompl.physics.chunks import CHUNK, Chunks, rest_flags
from openup_ompl.physics.world import NEIGHBOUR, OBJECT, OBSTACLE, ROBOT, World

if TYPE_CHECKING:
    from openup_ompl.physics.approach import Handover

__all__ = ["UNSTABLE", "Monitor", "transform"]

#: MuJoCo's warnings (``mjtWarning`` names) that it reset an unstable state, and what
#: each says.
UNSTABLE = (
    ("mjWARN_BADQPOS", "huge or non-finite position"),
    ("mjWARN_BADQVEL", "huge or non-finite velocity"),
    ("mjWARN_BADQACC", "bad acceleration"),
)


#: Classes of a contacting geom pair (:func:`_pair_classes`): none of interest, the
#: object on a fixed obstacle, a robot link on the object, on a fixed obstacle, on a
#: neighbour.
OTHER, PRESSED, GRIPPED, HIT, NUDGED = 0, 1, 2, 3, 4
#: Steps between the hold's rest checks (early end), how many in a row must find the
#: object and the neighbours at rest, and the speeds below which they are [m/s, rad/s].
REST_PERIOD = 25
REST_CHECKS = 4
REST_SPEED = 1e-3
REST_SPIN = 1e-2


def _pair_classes(kinds: np.ndarray) -> np.ndarray:
    """The class of every ordered geom pair ``(a, b)``, flattened at ``a * ngeom + b``."""
    first, second = kinds[:, None], kinds[None, :]

    def either(a: int, b: int) -> np.ndarray:
        return ((first == a) & (second == b)) | ((first == b) & (second == a))

    table = np.full((kinds.size, kinds.size), OTHER, dtype=np.int8)
    table[either(OBJECT, OBSTACLE)] = PRESSED
    table[either(OBJECT, ROBOT)] = GRIPPED
    table[either(ROBOT, OBSTACLE)] = HIT
    table[either(ROBOT, NEIGHBOUR)] = NUDGED
    return table.ravel()


def transform(sim: Any, body: int) -> np.ndarray:
    """The world transform of a body.

    Args:
        sim: The MuJoCo data (``mujoco.MjData``), kinematics up to date.
        body: The body's index.

    Returns:
        Its homogeneous transform [m], world frame, shape ``(4, 4)``.
    """
    t = np.eye(4)
    t[:3, :3] = sim.xmat[body].reshape(3, 3)
    t[:3, 3] = sim.xpos[body]
    return t


class Monitor:
    """Steps the simulation with the actuator targets :attr:`ctrl` and records, per step,
    what the verdict needs (first touches, the deepest penetrations, the object's height).

    Args:
        world: The physics world.
        sim: Its ``mujoco.MjData``, at the start state.
        ctrl: Actuator targets (plan joint order), changed in place by the phases.
        floor: A height [m] below any pose of the object resting on its support.
        goal: The grasp pose's position [m] (Algorithm 1's ``d`` at the first touch).
        start_distance: The plan's start palm distance [m] (0: ``d`` not computed).
        frame_period: Steps between kept frames, or 0 for none.
        messages: MuJoCo's warnings collected while it runs.
        early_end: End the rollout once its verdict is certain (:attr:`ended`).

    Attributes:
        phase: The running phase's name.
        steps: Steps taken.
        touched: The hand touched the object during the settle or the reach.
        first: First hand-object contact ``{"link", "time_s", "d", "phase"}`` or ``None``.
        obstacles: First contact of each (robot link, fixed obstacle) pair.
        neighbours: First robot contact of each movable obstacle, by name.
        pressed: Deepest object-obstacle penetration [m]; ``pressed_phase`` its phase.
        gripped: Deepest robot-object penetration [m].
        sunk: The phase in which the object went below ``floor``, or ``None``.
        top: The object's highest z [m] over the lift and hold.
        kept: The frames ``{"q", "object", "phase", "neighbours"}``.
        touch_step: The step at which :attr:`touched` became true, or ``None``.
        ended: Why and when the rollout ended early ``{"reason", "phase", "time_s"}``,
            or ``None``: once set, the phases stop stepping.
    """

    def __init__(
        self,
        world: World,
        sim: Any,
        ctrl: np.ndarray,
        floor: float,
        goal: np.ndarray,
        start_distance: float,
        frame_period: int,
        messages: list[str],
        early_end: bool = False,
    ) -> None:
        self.world, self.sim, self.ctrl = world, sim, ctrl
        self.dt = float(world.model.opt.timestep)
        self.floor, self.goal, self.start_distance = floor, goal, start_distance
        self.period, self.messages = frame_period, messages
        self.phase = "settle"
        self.phase_start = 0  # the step count when the phase began
        self.steps = 0
        self.touched = False
        self.first: dict[str, Any] | None = None
        self.obstacles: dict[tuple[str, str], dict[str, Any]] = {}
        self.neighbours: dict[str, dict[str, Any]] = {}
        self.pressed = 0.0
        self.pressed_phase: str | None = None
        self.gripped = 0.0
        self.sunk: str | None = None
        self.top = -math.inf
        self.kept: dict[str, Any] = {"q": [], "object": [], "phase": [], "neighbours": {}}
        self.touch_step: int | None = None
        self.ended: dict[str, Any] | None = None
        self.early_end = early_end
        import mujoco

        model = world.model
        self._ngeom = int(model.ngeom)
        self._classes = _pair_classes(world.geom_kind)
        self._seen = np.zeros(self._ngeom * self._ngeom, dtype=bool)
        self._in_order = bool(np.array_equal(world.actuator, np.arange(model.nu)))
        self._rest_checks = 0
        # Views into the simulation's arrays (fixed for its lifetime) and MuJoCo's step.
        self._sim_ctrl, self._qpos, self._sensors = sim.ctrl, sim.qpos, sim.sensordata
        self._height = world.object_qpos + 2
        self._mj_step = mujoco.mj_step
        watch = world.watch
        self._pressed = watch.pressed
        # Stretches of steps inside MuJoCo (none with frames to keep), and the step count
        # until which the monitor steps one step at a time.
        self.chunks: Chunks | None = Chunks(self) if not frame_period else None
        self.slow_until = 0
        self.gripped_sensors = watch.gripped
        self.touching_sensors = watch.touching
        # The shared approach's steps this rollout replays
        # (:mod:`~openup_ompl.physics.approach`).
        self.handover: Handover | None = None

    @property
    def time(self) -> float:
        """Simulated time [s]."""
        return self.steps * self.dt

    def step(self, targets: np.ndarray | None = None) -> None:
        """One simulation step, then the watch: the object's height, and the contacts
        through the watch's sensors (:mod:`~openup_ompl.physics.watch`); MuJoCo's contact
        list is read one contact at a time only on steps where a robot link touches a
        fixed obstacle or a neighbour, or touches the object while a first touch may
        still be recorded.

        Args:
            targets: The actuator targets (plan joint order); ``None``: :attr:`ctrl`.
        """
        world, sim = self.world, self.sim
        if targets is None:
            targets = self.ctrl
        if self._in_order:
            self._sim_ctrl[:] = targets
        else:
            sim.ctrl[world.actuator] = targets
        self._mj_step(world.model, sim)
        self.steps += 1
        height = self._qpos[self._height]
        if self.sunk is None and height < self.floor:
            self.sunk = self.phase
        if height > self.top and self.phase in ("lift", "hold"):
            self.top = float(height)
        sensors = self._sensors.tolist()
        if sensors[self._pressed]:
            # The deepest penetration: -min(dist) is max(-dist) to the last bit.
            deepest = -sensors[self._pressed + 1]
            if deepest > self.pressed:
                self.pressed, self.pressed_phase = deepest, self.phase
        look = False
        for i in self.gripped_sensors:
            if sensors[i]:
                look = look or self.pending()
                self.gripped = max(self.gripped, -sensors[i + 1])
        for i in self.touching_sensors:
            look = look or sensors[i] > 0
        if look:
            self._contacts(sim.ncon)
        if self.period and self.steps % self.period == 0:
            self._keep()
        if self.early_end and self.phase == "hold" and self.steps % REST_PERIOD == 0:
            self._check_rest()

    def pending(self) -> bool:
        """A touch of the object may still be recorded: the first, or the first of the
        settle and the reach."""
        return self.first is None or (not self.touched and self.phase in ("settle", "reach"))

    def drive(self, rows: np.ndarray, log: np.ndarray | None = None) -> int:
        """Step once per row of actuator targets, fewer if the rollout ends; :attr:`ctrl`
        ends at the last row driven. Stretches run inside MuJoCo
        (:class:`~openup_ompl.physics.chunks.Chunks`), one step at a time where contacts
        must be read one by one: the same steps either way, to the last bit.

        Args:
            rows: The targets of each step (plan joint order), shape ``(steps, n)``.
            log: If given, ``log[k]`` gets the whole ``qpos`` after step ``k``.

        Returns:
            The steps taken.
        """
        done, total = 0, len(rows)
        while done < total and self.ended is None:
            if self.handover is not None:  # the steps a shared approach ran
                done += self.handover.replay(self, rows[done:], log, done)
                continue
            if self.chunks is not None and self.steps >= self.slow_until:
                done += self.chunks.run(self, rows[done : done + CHUNK], log, done)
                continue
            end = total if self.chunks is None else min(total, done + self.slow_until - self.steps)
            for row in rows[done:end]:
                if self.ended is not None:
                    break
                self.step(row)
                if log is not None:
                    log[done] = self._qpos
                done += 1
        if done:
            self.ctrl[:] = rows[done - 1]
        return done

    def run_for(self, seconds: float) -> None:
        """Step at constant targets (less if the rollout ends early).

        Args:
            seconds: Simulated time [s]; rounded to whole timesteps.
        """
        steps = round(seconds / self.dt)
        if steps and self.ended is None:
            self.drive(np.tile(self.ctrl, (steps, 1)))

    def watch_steps(self, heights: np.ndarray, sensors: np.ndarray) -> None:
        """The watch of steps that MuJoCo ran (:mod:`~openup_ompl.physics.chunks`), none of
        whose contacts needs reading one by one: what :meth:`step` does, array by array.

        Args:
            heights: The object's height [m] after each step.
            sensors: The sensor values of each step.
        """
        if not len(heights):
            return
        self.steps += len(heights)
        if self.sunk is None and (heights < self.floor).any():
            self.sunk = self.phase
        if self.phase in ("lift", "hold"):
            self.top = max(self.top, float(heights.max()))
        found = sensors[:, self._pressed] > 0
        if found.any():
            deepest = float((-sensors[found, self._pressed + 1]).max())
            if deepest > self.pressed:
                self.pressed, self.pressed_phase = deepest, self.phase
        for i in self.gripped_sensors:
            found = sensors[:, i] > 0
            if found.any():
                self.gripped = max(self.gripped, float((-sensors[found, i + 1]).max()))

    def rest_checks(self, states: np.ndarray, sensors: np.ndarray, qvel: int) -> int | None:
        """The hold's rest checks (:meth:`_check_rest`) over steps that MuJoCo ran, from
        their states and sensors; sets :attr:`ended` at the check that ends the rollout.

        Args:
            states: MuJoCo's full physics state after each step (time first).
            sensors: The sensor values of each step.
            qvel: Where ``qvel`` starts in a state.

        Returns:
            The index of the step the rollout ends at, or ``None``.
        """
        if not (self.early_end and self.phase == "hold"):
            return None
        world = self.world
        steps = self.steps + 1 + np.arange(len(states))
        checked = np.flatnonzero(steps % REST_PERIOD == 0)
        still = rest_flags(states[checked], sensors[checked], qvel,
                           [world.object_dof, *world.neighbour_dof], self.gripped_sensors,
                           REST_SPEED, REST_SPIN)  # fmt: skip
        for k, rests in zip(checked, still, strict=True):
            self._rest_checks = self._rest_checks + 1 if rests else 0
            if self._rest_checks >= REST_CHECKS:
                self.ended = {"reason": "object left the hand, at rest", "phase": self.phase,
                              "time_s": int(steps[k]) * self.dt}  # fmt: skip
                return int(k)
        return None

    def _contacts(self, ncon: int) -> None:
        """Record the step's contacts: penetrations, and each first touch. A geom pair's
        class comes from one table lookup; only contacts that can still add a first touch
        are looked at one by one (in MuJoCo's order, as every one was before)."""
        contact = self.sim.contact
        geom = contact.geom
        ids = geom[:, 0] * self._ngeom + geom[:, 1]
        classes = self._classes[ids]
        count = np.bincount(classes, minlength=5)
        if count[0] == ncon:
            return
        if count[PRESSED]:
            # The deepest penetration: -min(dist) is max(-dist) to the last bit.
            deepest = -float(contact.dist[classes == PRESSED].min())
            if deepest > self.pressed:
                self.pressed, self.pressed_phase = deepest, self.phase
        pending = self.pending()
        gripped = None
        if count[GRIPPED]:
            gripped = classes == GRIPPED
            self.gripped = max(self.gripped, -float(contact.dist[gripped].min()))
        if count[HIT] + count[NUDGED]:
            relevant = (classes >= HIT) & ~self._seen[ids]
            if pending and gripped is not None:
                relevant |= gripped
        elif pending and gripped is not None:
            relevant = gripped
        else:
            return
        kinds, links = self.world.geom_kind, self.world.geom_link
        for i in np.flatnonzero(relevant):
            g = geom[i]
            robot_first = kinds[g[0]] == ROBOT
            other = int(g[1] if robot_first else g[0])
            self._touch(links[int(g[0] if robot_first else g[1])], other)
            if classes[i] >= HIT:
                self._seen[ids[i]] = True

    def _touch(self, link: str, other: int) -> None:
        """A robot ``link`` touches geom ``other``: note the first touch of its kind."""
        kind, name = self.world.geom_kind[other], self.world.geom_link[other]
        time, phase = self.time, self.phase
        if kind == OBJECT:
            if phase in ("settle", "reach") and not self.touched:
                self.touched, self.touch_step = True, self.steps
            if self.first is None:
                palm = self.sim.xpos[self.world.palm_body]
                d = (
                    float(np.linalg.norm(palm - self.goal)) / self.start_distance
                    if self.start_distance > 0
                    else None
                )
                self.first = {"link": link, "time_s": time, "d": d, "phase": phase}
        elif kind == NEIGHBOUR:
            if name not in self.neighbours:
                self.neighbours[name] = {"link": link, "time_s": time, "phase": phase}
        elif kind == OBSTACLE:
            key = (link, name)
            if key not in self.obstacles:
                self.obstacles[key] = {
                    "link": link, "obstacle": name, "time_s": time, "phase": phase
                }  # fmt: skip
                if self.early_end and not self.world.neighbours and self.ended is None:
                    # The first failure cause in order: nothing later changes the verdict
                    # (with neighbours, their disturbance is still to come).
                    self.ended = {"reason": "obstacle contact", "phase": phase, "time_s": time}

    def _check_rest(self) -> None:
        """During the hold: no robot link touches the object, and the object and every
        neighbour are at rest (:data:`REST_SPEED`) for :data:`REST_CHECKS` checks in a
        row. The robot holds still at the top, so nothing moves again: the verdict
        (``dropped`` or ``no contact``, or a cause before them) is certain."""
        sim, world = self.sim, self.world
        bodies = [world.object_dof, *world.neighbour_dof]
        still = bool(rest_flags(sim.qvel[None], sim.sensordata[None], 0, bodies,
                                self.gripped_sensors, REST_SPEED, REST_SPIN)[0])  # fmt: skip
        self._rest_checks = self._rest_checks + 1 if still else 0
        if self._rest_checks >= REST_CHECKS:
            self.ended = {"reason": "object left the hand, at rest", "phase": self.phase,
                          "time_s": self.time}  # fmt: skip

    def _keep(self) -> None:
        """Keep a frame: the joints, the object's pose and every neighbour's."""
        world, sim, kept = self.world, self.sim, self.kept
        kept["q"].append(sim.qpos[world.qpos].tolist())
        p = sim.qpos[world.object_qpos : world.object_qpos + 7]
        kept["object"].append([*p[:3], p[4], p[5], p[6], p[3]])
        kept["phase"].append(self.phase)
        for shape, body in zip(world.neighbours, world.neighbour_body, strict=True):
            q = sim.xquat[body]
            pose = [*sim.xpos[body].tolist(), float(q[1]), float(q[2]), float(q[3]), float(q[0])]
            kept["neighbours"].setdefault(shape.name, []).append(pose)

    def check_stable(self) -> None:
        """Raise :class:`SimulationDiverged` if MuJoCo reset an unstable state or the
        state is not finite."""
        import mujoco

        sim = self.sim
        for warning, what in UNSTABLE:
            if sim.warning[getattr(mujoco.mjtWarning, warning)].number:
                detail = f"{what}, state reset" + "".join(f": {m}" for m in self.messages[-1:])
                raise SimulationDiverged(self.phase, self.time, detail)
        if not np.all(np.isfinite(sim.qpos)):
            raise SimulationDiverged(self.phase, self.time, "non-finite state")
