"""Stretches of steps run inside MuJoCo (``mujoco.rollout``) with the watch applied to
them afterwards, array by array (:class:`Chunks`).

A stretch of :data:`CHUNK` steps with its targets known in advance runs in one call, from
the simulation's state and solver warm start (the state MuJoCo continues from bit for bit);
MuJoCo returns each step's state and sensors. The steps before the first one whose
contact list must be read one contact at a time (a robot link on an obstacle or a
neighbour, a touch of the object that may be its first; :mod:`~openup_ompl.physics.watch`)
are then watched from those arrays: the object's height, the deepest penetrations, the
hold's rest checks. From that step on, the stretch runs again from its start up to it,
and the :class:`~openup_ompl.physics.monitor.Monitor` steps on one step at a time for
:data:`SLOW` steps. A warning of MuJoCo (which would stop the call and clear its
counters) sends the stretch, and the rest of the rollout, back to single steps.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from openup_ompl.physics.monitor import Monitor

__all__ = ["CHUNK", "SLOW", "Chunks", "rest_flags"]

#: Steps per call to MuJoCo.
CHUNK = 128
#: Steps taken one at a time after a step whose contacts were read one by one.
SLOW = 64


class Chunks:
    """Runs a monitor's targets in stretches (module docstring).

    Args:
        monitor: The rollout's monitor (its world and simulation).
    """

    def __init__(self, monitor: Monitor) -> None:
        import mujoco
        from mujoco import rollout

        self.model, self.sim = monitor.world.model, monitor.sim
        self.spec = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
        self.control_spec = int(mujoco.mjtState.mjSTATE_CTRL)
        size = mujoco.mj_stateSize(self.model, self.spec)
        self.start = np.empty((1, size))
        self.warm = np.empty((1, self.model.nv))
        self.states = np.empty((1, CHUNK, size))
        self.sensors = np.empty((1, CHUNK, self.model.nsensordata))
        self.controls = np.zeros((1, CHUNK, self.model.nu))
        self.runner = rollout.Rollout(nthread=0)
        # Where qpos and qvel sit in a state (time first).
        self.qpos = 1 + np.arange(self.model.nq)
        self.qvel = 1 + self.model.nq
        self.height = 1 + monitor.world.object_qpos + 2  # the object's z
        self.actuator = monitor.world.actuator

    def _call(self, steps: int) -> None:
        """Run ``steps`` of :attr:`controls` from :attr:`start` and :attr:`warm`."""
        self.runner.rollout(
            [self.model], [self.sim], self.start, self.controls[:, :steps],
            control_spec=self.control_spec, skip_checks=True, nstep=steps,
            initial_warmstart=self.warm, state=self.states[:, :steps],
            sensordata=self.sensors[:, :steps],
        )  # fmt: skip

    def run(self, monitor: Monitor, rows: np.ndarray, log: np.ndarray | None, at: int) -> int:
        """Run up to :data:`CHUNK` rows of targets.

        Args:
            monitor: The rollout's monitor.
            rows: The targets (plan joint order), at most :data:`CHUNK` rows.
            log: If given, ``log[at + k]`` gets the whole ``qpos`` after step ``k``.
            at: The index in ``log`` of the first row.

        Returns:
            The steps taken (0: MuJoCo warned; the monitor goes on one step at a time).
        """
        import mujoco

        sim, n = self.sim, len(rows)
        if any(sim.warning.number):
            monitor.chunks = None
            return 0
        mujoco.mj_getState(self.model, sim, self.start[0], self.spec)
        self.warm[0] = sim.qacc_warmstart
        controls = self.controls[0]
        controls[:n, self.actuator] = rows
        messages = len(monitor.messages)
        self._call(n)
        if any(sim.warning.number):  # back to where it was, then single steps
            del monitor.messages[messages:]
            sim.warning.number[:] = 0
            mujoco.mj_setState(self.model, sim, self.start[0], self.spec)
            sim.qacc_warmstart[:] = self.warm[0]
            monitor.chunks = None
            return 0
        states, sensors = self.states[0, :n], self.sensors[0, :n]
        look = np.zeros(n, dtype=bool)
        for i in monitor.touching_sensors:
            look |= sensors[:, i] > 0
        if monitor.pending():
            for i in monitor.gripped_sensors:
                look |= sensors[:, i] > 0
        first = int(np.argmax(look)) if look.any() else n
        ended = monitor.rest_checks(states[:first], sensors[:first], self.qvel)
        taken = first if ended is None else ended + 1
        monitor.watch_steps(states[:taken, self.height], sensors[:taken])
        if log is not None:
            log[at : at + taken] = states[:taken, self.qpos]
        if taken == n:
            return n
        if taken:  # again from the start, up to the step to stop at or to look at
            self._call(taken)
        else:
            mujoco.mj_setState(self.model, sim, self.start[0], self.spec)
            sim.qacc_warmstart[:] = self.warm[0]
        if ended is not None:
            return taken
        monitor.step(rows[taken])
        if log is not None:
            log[at + taken] = sim.qpos
        monitor.slow_until = monitor.steps + SLOW
        return taken + 1


def rest_flags(
    states: np.ndarray,
    sensors: np.ndarray,
    qvel: int,
    bodies: list[int],
    gripped: tuple[int, ...],
    speed: float,
    spin: float,
) -> np.ndarray:
    """Per step, the rest test of the hold's early end: no robot part touches the object,
    and every body rests.

    Args:
        states: MuJoCo's full physics state after each step, shape ``(steps, size)``.
        sensors: The sensor values of each step.
        qvel: Where ``qvel`` starts in a state.
        bodies: ``qvel`` addresses of the free joints that must rest.
        gripped: Sensor indices of the robot's contacts with the object.
        speed: Linear speed [m/s] each component stays below.
        spin: Angular speed [rad/s] each component stays below.

    Returns:
        One flag per step.
    """
    still = np.ones(len(states), dtype=bool)
    for i in gripped:
        still &= sensors[:, i] == 0
    for d in bodies:
        velocity = np.abs(states[:, qvel + d : qvel + d + 6])
        still &= (velocity[:, :3].max(axis=1) < speed) & (velocity[:, 3:].max(axis=1) < spin)
    return still
