"""The simulation loop's one step and what it watches: contacts, the object's height, the
kept frames, and MuJoCo's instability warnings (:class:`Monitor`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from openup_ompl.exceptions import SimulationDiverged
from openup_ompl.physics.world import NEIGHBOUR, OBJECT, OBSTACLE, ROBOT, World

__all__ = ["UNSTABLE", "Monitor", "transform"]

#: MuJoCo's warnings (``mjtWarning`` names) that it reset an unstable state, and what
#: each says.
UNSTABLE = (
    ("mjWARN_BADQPOS", "huge or non-finite position"),
    ("mjWARN_BADQVEL", "huge or non-finite velocity"),
    ("mjWARN_BADQACC", "bad acceleration"),
)


def transform(sim: Any, body: int) -> np.ndarray:
    """The ``(4, 4)`` world transform of a body."""
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
    ) -> None:
        self.world, self.sim, self.ctrl = world, sim, ctrl
        self.dt = float(world.model.opt.timestep)
        self.floor, self.goal, self.start_distance = floor, goal, start_distance
        self.period, self.messages = frame_period, messages
        self.phase = "settle"
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

    @property
    def time(self) -> float:
        """Simulated time [s]."""
        return self.steps * self.dt

    def step(self) -> None:
        """One simulation step at :attr:`ctrl`, then the watch."""
        import mujoco

        world, sim = self.world, self.sim
        sim.ctrl[world.actuator] = self.ctrl
        mujoco.mj_step(world.model, sim)
        self.steps += 1
        height = sim.qpos[world.object_qpos + 2]
        if self.sunk is None and height < self.floor:
            self.sunk = self.phase
        if self.phase in ("lift", "hold") and height > self.top:
            self.top = float(height)
        if sim.ncon:
            self._contacts()
        if self.period and self.steps % self.period == 0:
            self._keep()

    def run_for(self, seconds: float) -> None:
        """Step for ``seconds`` [s] of simulated time at constant targets."""
        for _ in range(round(seconds / self.dt)):
            self.step()

    def _contacts(self) -> None:
        """Record the step's contacts: penetrations, and each first touch."""
        sim, kinds = self.sim, self.world.geom_kind
        pairs = kinds[sim.contact.geom[: sim.ncon]]
        depth = -sim.contact.dist[: sim.ncon]
        pressed = ((pairs == OBJECT) & (pairs[:, ::-1] == OBSTACLE)).any(axis=1)
        if pressed.any():
            deepest = float(depth[pressed].max())
            if deepest > self.pressed:
                self.pressed, self.pressed_phase = deepest, self.phase
        gripped = ((pairs == OBJECT) & (pairs[:, ::-1] == ROBOT)).any(axis=1)
        if gripped.any():
            self.gripped = max(self.gripped, float(depth[gripped].max()))
        for i in np.flatnonzero((pairs == ROBOT).any(axis=1)):
            g = sim.contact.geom[i]
            robot_first = kinds[g[0]] == ROBOT
            other = int(g[1] if robot_first else g[0])
            self._touch(self.world.geom_link[int(g[0] if robot_first else g[1])], other)

    def _touch(self, link: str, other: int) -> None:
        """A robot ``link`` touches geom ``other``: note the first touch of its kind."""
        kind, name = self.world.geom_kind[other], self.world.geom_link[other]
        time, phase = self.time, self.phase
        if kind == OBJECT:
            if phase in ("settle", "reach"):
                self.touched = True
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
