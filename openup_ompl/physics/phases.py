"""The phases of a rollout, in order: settle, reach, close, squeeze, lift, hold.

Each phase drives the :class:`~openup_ompl.physics.monitor.Monitor`'s actuator targets
for its stretch of simulated time and returns that duration [s]; the reach and the lift
keep their own tracking errors.
"""

from __future__ import annotations

import math

import numpy as np

from openup_ompl.physics.monitor import Monitor
from openup_ompl.physics.trajectory import Timed
from openup_ompl.physics.world import World

__all__ = ["PHASE_ORDER", "Closing", "Lift", "Reach", "hold", "settle"]

#: The phases' names, in order.
PHASE_ORDER = ("settle", "reach", "close", "squeeze", "lift", "hold")
#: Time [s] the reach holds the plan's last row after the timed path ends.
REACH_TAIL = 0.1


def settle(monitor: Monitor, seconds: float) -> float:
    """The object rests where it really is, the robot at the plan's first row."""
    monitor.phase = "settle"
    monitor.run_for(seconds)
    return seconds


class Reach:
    """The plan's rows as timed (:func:`~openup_ompl.physics.trajectory.time_path`), with
    velocity feed-forward through the targets.

    Attributes:
        arm_error: Largest arm tracking error [rad or m].
        hand_error: Largest hand tracking error before the hand touched the object.
    """

    def __init__(self, timed: Timed, lead: np.ndarray) -> None:
        self.timed, self.lead = timed, lead
        self.arm_error = 0.0
        self.hand_error = 0.0

    def run(self, monitor: Monitor) -> float:
        """Drive the targets along the timed path; returns the duration [s]."""
        monitor.phase = "reach"
        world, sim, ctrl, dt = monitor.world, monitor.sim, monitor.ctrl, monitor.dt
        steps = math.ceil(self.timed.duration / dt) + round(REACH_TAIL / dt)
        desired = np.empty_like(ctrl)
        ahead = np.empty_like(ctrl)
        arm, hand = world.arm, world.hand
        for k in range(steps):
            self.timed.at((k + 1) * dt, desired)
            self.timed.at((k + 2) * dt, ahead)
            # Velocity feed-forward through the target: kp (q* + kv/kp v* - q) - kv v
            # = kp (q* - q) + kv (v* - v), no lag of kv v / kp behind a moving target.
            np.multiply(ahead - desired, self.lead / dt, out=ctrl)
            ctrl += desired
            monitor.step()
            error = np.abs(sim.qpos[world.qpos] - desired)
            self.arm_error = max(self.arm_error, float(error[arm].max()))
            if hand.size and not monitor.touched:
                self.hand_error = max(self.hand_error, float(error[hand].max()))
        ctrl[:] = desired
        return steps * dt


class Closing:
    """The hand's targets move from where the reach left them towards ``closed`` at
    ``rates`` [rad/s or m/s] (:meth:`close`), then stay there while each joint presses
    with its force limit (:meth:`squeeze`). Mimic followers follow their leaders.

    Args:
        world: The physics world.
        start: The hand's targets at the end of the reach.
        closed: The closed configuration of each hand joint.
        rates: Speed of each hand joint's target [rad/s or m/s].
    """

    def __init__(
        self, world: World, start: np.ndarray, closed: np.ndarray, rates: np.ndarray
    ) -> None:
        self.world = world
        self.start = start.copy()
        self.rates = rates
        self.span = np.abs(closed - self.start)
        self.direction = np.sign(closed - self.start)
        self.duration = float(np.max(self.span / rates)) if world.hand.size else 0.0

    def _targets(self, ctrl: np.ndarray, travel: np.ndarray) -> None:
        ctrl[self.world.hand] = self.start + self.direction * travel
        for follower, leader, multiplier, off in self.world.mimic:
            ctrl[follower] = multiplier * ctrl[leader] + off

    def close(self, monitor: Monitor) -> float:
        """Move the targets to the closed configuration; returns the duration [s]."""
        monitor.phase = "close"
        steps = math.ceil(self.duration / monitor.dt)
        for k in range(steps):
            self._targets(monitor.ctrl, np.minimum(self.span, self.rates * (k + 1) * monitor.dt))
            monitor.step()
        return steps * monitor.dt

    def squeeze(self, monitor: Monitor, seconds: float) -> float:
        """Hold the closed targets for ``seconds`` [s]: each joint presses on what
        stopped it. Returns the duration [s]."""
        monitor.phase = "squeeze"
        steps = round(seconds / monitor.dt)
        for _ in range(steps):
            self._targets(monitor.ctrl, self.span)
            monitor.step()
        return steps * monitor.dt


class Lift:
    """The palm straight up along the lift's IK rows (equal palm rises) at a smoothstep in
    time, starting and stopping at rest, with velocity feed-forward; the hand's targets
    held.

    Args:
        rows: The lift's configurations (:func:`~openup_ompl.physics.targets.lift_rows`).
        arm: Indices of the arm joints.
        lead: ``kv / kp`` of the arm joints' actuators [s].
        steps: Simulation steps of the lift.

    Attributes:
        arm_error: Largest arm tracking error [rad or m].
    """

    def __init__(self, rows: np.ndarray, arm: np.ndarray, lead: np.ndarray, steps: int) -> None:
        self.rows, self.arm, self.lead, self.steps = rows, arm, lead, steps
        self.arm_error = 0.0

    def at(self, k: int) -> np.ndarray:
        """Arm target at lift step ``k``."""
        last = len(self.rows) - 1
        s = min(1.0, k / self.steps)
        x = s * s * (3 - 2 * s) * last
        i = min(int(x), max(last - 1, 0))
        a = min(1.0, x - i)
        j = min(i + 1, last)
        return self.rows[i, self.arm] + a * (self.rows[j, self.arm] - self.rows[i, self.arm])

    def run(self, monitor: Monitor) -> float:
        """Drive the arm up; returns the duration [s]. The targets end at the top."""
        monitor.phase = "lift"
        world, sim, ctrl, dt = monitor.world, monitor.sim, monitor.ctrl, monitor.dt
        for k in range(self.steps):
            target, following = self.at(k + 1), self.at(k + 2)
            ctrl[self.arm] = target + self.lead * (following - target) / dt
            monitor.step()
            error = np.abs(sim.qpos[world.qpos[self.arm]] - target)
            self.arm_error = max(self.arm_error, float(error.max()))
        ctrl[self.arm] = self.at(self.steps)
        return self.steps * dt


def hold(monitor: Monitor, seconds: float) -> float:
    """The targets stay at the top for ``seconds`` [s]."""
    monitor.phase = "hold"
    monitor.run_for(seconds)
    return seconds
